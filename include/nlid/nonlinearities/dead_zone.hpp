#pragma once
/// @file
/// `DeadZone`: zero output on the interval [lower, upper], unit slope outside (toolbox
/// `deadzone` / idDeadZone) — backlash-free stiction, a valve that does not move until the
/// command passes a threshold, a sensor insensitive near zero.
///
/// Math. θ = [lower, upper]:
///
///     g(x) = x − lower   for x < lower,
///            0           for lower ≤ x ≤ upper,
///            x − upper   for x > upper.
///
/// ∂g/∂x = 1 outside and 0 inside; ∂g/∂lower = −1 below, ∂g/∂upper = −1 above. At the two kinks
/// forward AD returns the derivative of the branch taken. If an optimiser makes the limits
/// cross, the map uses [min(θ), max(θ)] (continuous in θ; `describe` reports it).
///
/// Initialisation. Initial limits given to the constructor are used as they are. Otherwise the
/// limits come from the exact least-squares scan of detail/limit_scan.hpp: the samples below ℓ
/// change the sum of squares by Σ (yᵢ − xᵢ + ℓ)² − yᵢ². If the best limits would cross, both
/// are set to their midpoint (a zone of zero width: the data show no dead zone).

#include <cmath>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/nonlinearities/detail/common.hpp"
#include "nlid/nonlinearities/detail/limit_scan.hpp"

namespace nlid {

/// Dead zone with zero interval [lower, upper], θ = [lower, upper].
/// Invariant: initial limits, when set, are finite with lower ≤ upper.
class DeadZone {
 public:
  /// m = 1.
  static constexpr int num_inputs = 1;
  /// p = 2: lower, upper.
  static constexpr int num_params = 2;

  /// Limits are learned from data by `initialize`.
  DeadZone() = default;
  /// Starts from the given zero interval. Throws naming "lower" if lower > upper or a limit is
  /// not finite.
  DeadZone(double lower, double upper) { set_initial_limits(lower, upper); }

  /// Sets the zero interval `initialize` will use instead of estimating it.
  void set_initial_limits(double lower, double upper) {
    if (!std::isfinite(lower) || !std::isfinite(upper)) {
      throw Error("DeadZone: limits must be finite", at_parameter(std::isfinite(lower) ? "upper" : "lower"));
    }
    if (lower > upper) {
      throw Error("DeadZone: lower limit " + detail::format_g(lower) + " exceeds upper limit " +
                      detail::format_g(upper),
                  at_parameter("lower"));
    }
    initial_ = std::make_pair(lower, upper);
  }
  /// The initial zero interval, if given.
  [[nodiscard]] std::optional<std::pair<double, double>> initial_limits() const { return initial_; }

  /// Number of inputs (1).
  [[nodiscard]] int input_dimension() const { return 1; }
  /// Number of parameters (2).
  [[nodiscard]] int num_parameters() const { return 2; }

  /// Dead-zone map with limits [min(θ), max(θ)]. Throws if a span has the wrong length.
  template <class T>
  [[nodiscard]] T operator()(std::span<const T> x, std::span<const T> theta) const {
    if (x.size() != 1) detail::check_size(x.size(), 1, "x", "DeadZone");
    if (theta.size() != 2) detail::check_size(theta.size(), 2, "theta", "DeadZone");
    const bool crossed = theta[1] < theta[0];
    const T& lo = crossed ? theta[1] : theta[0];
    const T& hi = crossed ? theta[0] : theta[1];
    // Ordered so that a NaN input falls through to x − lo and stays NaN: a free run whose
    // regressor went non-finite must be seen as diverged, not continue from an invented 0.
    if (x[0] > hi) return x[0] - hi;
    if (x[0] >= lo) return detail::cast_to<T>(0.0);
    return x[0] - lo;
  }

  /// Initial limits if given, else the exact least-squares limits for (X, y); X is N × 1.
  void initialize(const Eigen::MatrixXd& X, const Eigen::VectorXd& y, std::span<double> theta) {
    detail::check_init_data(X, y, theta.size(), 1, 2, initial_ ? 0 : 1, "DeadZone");
    if (initial_) {
      theta[0] = initial_->first;
      theta[1] = initial_->second;
      return;
    }
    const auto n = static_cast<std::size_t>(X.rows());
    const auto idx = detail::sort_permutation(X.data(), n);
    std::vector<double> xs(n), a(n), b(n);
    for (std::size_t i = 0; i < n; ++i) {
      const auto r = static_cast<Eigen::Index>(idx[i]);
      xs[i] = X(r, 0);
      a[i] = y(r) - X(r, 0);  // (y − (x − ℓ))² = (a + ℓ)²
      b[i] = y(r) * y(r);     // error of the zero branch
    }
    double lo = detail::scan_lower_limit(xs, a, b).limit;
    double hi = detail::scan_upper_limit(xs, a, b).limit;
    if (lo > hi) lo = hi = 0.5 * (lo + hi);
    theta[0] = lo;
    theta[1] = hi;
  }

  /// The unit of each parameter when x is measured in units of size `in` and g(x) in units of
  /// size `out` (estimation uses them to damp steps alike whatever units the data are in).
  bool parameter_scales(double in, double /*out*/, std::span<double> s) const {
    s[0] = s[1] = in;
    return true;
  }

  /// "lower", "upper".
  [[nodiscard]] std::vector<std::string> parameter_names() const { return {"lower", "upper"}; }

  /// The equation with the zero interval.
  [[nodiscard]] std::string describe(std::span<const double> theta) const {
    detail::check_size(theta.size(), 2, "theta", "DeadZone");
    const double lo = std::min(theta[0], theta[1]);
    const double hi = std::max(theta[0], theta[1]);
    std::string s = "dead zone: g(x) = x - (" + detail::format_g(lo) + ") for x < " + detail::format_g(lo) +
                    ", 0 for " + detail::format_g(lo) + " <= x <= " + detail::format_g(hi) +
                    ", x - (" + detail::format_g(hi) + ") for x > " + detail::format_g(hi) + "\n";
    if (theta[1] < theta[0]) s += "  note: lower > upper in theta; the limits are used swapped\n";
    return s;
  }

 private:
  std::optional<std::pair<double, double>> initial_;
};

}  // namespace nlid
