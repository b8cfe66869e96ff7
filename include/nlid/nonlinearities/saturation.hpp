#pragma once
/// @file
/// `Saturation`: g(x) = clamp(x, lower, upper) — the linear interval [lower, upper] with hard
/// limits outside (toolbox `saturation` / idSaturation).
///
/// Math. θ = [lower, upper]:
///
///     g(x) = lower   for x < lower,
///            x       for lower ≤ x ≤ upper,
///            upper   for x > upper.
///
/// ∂g/∂x = 1 inside the interval and 0 outside; ∂g/∂lower = 1 below, ∂g/∂upper = 1 above. The
/// map is not differentiable at the two kinks; forward AD returns the one-sided derivative of the
/// branch taken, as any gradient method for such models must (Ljung 1999, Sec. 5.5, block
/// nonlinearities).
///
/// Typical use: the output block of a Wiener or Hammerstein–Wiener model of a valve that rests at
/// a stop and travels to another (`nlhw1` of the throttle study: limits ≈ [15°, 90°]).
///
/// Ordering. While an optimiser moves θ the two limits may cross; the map then uses
/// [min(θ), max(θ)], which is continuous in θ (both orders agree at lower = upper), so no step
/// produces a discontinuity or a NaN. `describe` reports crossed limits.
///
/// Initialisation. With initial limits given to the constructor (prior knowledge such as the
/// mechanical stops) `initialize` uses them. Otherwise each limit is placed by the exact
/// least-squares scan of detail/limit_scan.hpp: the samples beyond a lower limit ℓ change the sum
/// of squares by Σ (yᵢ − ℓ)² − (yᵢ − xᵢ)², minimised globally over ℓ. A side with no saturated
/// samples gets its limit 1 % of the x range inside the data's extreme x: nearly inactive on the
/// data, but with a gradient (a limit at the extreme clamps nothing, its derivative is zero on
/// every sample and no optimiser could move it — e.g. the input map of a Hammerstein model,
/// initialised as the identity, never found a saturation the data held). Data no saturation
/// explains (limits that would cross) give the best constant, lower = upper = mean(y).

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

/// Hard saturation g(x) = clamp(x, lower, upper), θ = [lower, upper].
/// Invariant: initial limits, when set, are finite with lower ≤ upper.
class Saturation {
 public:
  /// m = 1.
  static constexpr int num_inputs = 1;
  /// p = 2: lower, upper.
  static constexpr int num_params = 2;

  /// Limits are learned from data by `initialize`.
  Saturation() = default;
  /// Starts from the given limits (e.g. the mechanical stops). Throws naming "lower" if
  /// lower > upper or a limit is not finite.
  Saturation(double lower, double upper) { set_initial_limits(lower, upper); }

  /// Sets the limits `initialize` will use instead of estimating them from data.
  void set_initial_limits(double lower, double upper) {
    if (!std::isfinite(lower) || !std::isfinite(upper)) {
      throw Error("Saturation: limits must be finite", at_parameter(std::isfinite(lower) ? "upper" : "lower"));
    }
    if (lower > upper) {
      throw Error("Saturation: lower limit " + detail::format_g(lower) + " exceeds upper limit " +
                      detail::format_g(upper),
                  at_parameter("lower"));
    }
    initial_ = std::make_pair(lower, upper);
  }
  /// The initial limits, if given.
  [[nodiscard]] std::optional<std::pair<double, double>> initial_limits() const { return initial_; }

  /// Number of inputs (1).
  [[nodiscard]] int input_dimension() const { return 1; }
  /// Number of parameters (2).
  [[nodiscard]] int num_parameters() const { return 2; }

  /// clamp(x, min(θ), max(θ)). Throws `nlid::Error` if a span has the wrong length.
  template <class T>
  [[nodiscard]] T operator()(std::span<const T> x, std::span<const T> theta) const {
    if (x.size() != 1) detail::check_size(x.size(), 1, "x", "Saturation");
    if (theta.size() != 2) detail::check_size(theta.size(), 2, "theta", "Saturation");
    const bool crossed = theta[1] < theta[0];
    const T& lo = crossed ? theta[1] : theta[0];
    const T& hi = crossed ? theta[0] : theta[1];
    if (x[0] < lo) return lo;
    if (x[0] > hi) return hi;
    return x[0];
  }

  /// Initial limits if given, else the exact least-squares limits for (X, y); X is N × 1.
  void initialize(const Eigen::MatrixXd& X, const Eigen::VectorXd& y, std::span<double> theta) {
    detail::check_init_data(X, y, theta.size(), 1, 2, initial_ ? 0 : 1, "Saturation");
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
      a[i] = -y(r);                                         // (y − ℓ)² = (a + ℓ)²
      b[i] = (y(r) - X(r, 0)) * (y(r) - X(r, 0));           // the identity's own error
    }
    const detail::LimitFit lf = detail::scan_lower_limit(xs, a, b), hf = detail::scan_upper_limit(xs, a, b);
    double lo = lf.limit, hi = hf.limit;
    if (lo > hi) {
      // Data no saturation explains: the best a saturation can do is the constant mean(y); any
      // other pair of collapsed limits is a worse constant.
      lo = hi = y.mean();
    } else if (n > 1 && xs.back() > xs.front()) {
      // A limit at the data's extreme clamps no sample and has no gradient there: an optimiser
      // could never move it in to where the data (seen through other blocks) want it. 1 % of the
      // range inside, it clamps the outermost samples a little and can move either way.
      const double inset = 0.01 * (xs.back() - xs.front());
      if (lf.active == 0) lo = xs.front() + inset;
      if (hf.active == 0) hi = xs.back() - inset;
      if (lo > hi) lo = hi = 0.5 * (xs.front() + xs.back());
    }
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

  /// The equation with the limits, e.g. "g(x) = min(max(x, 15), 90)".
  [[nodiscard]] std::string describe(std::span<const double> theta) const {
    detail::check_size(theta.size(), 2, "theta", "Saturation");
    const double lo = std::min(theta[0], theta[1]);
    const double hi = std::max(theta[0], theta[1]);
    std::string s = "saturation: g(x) = min(max(x, " + detail::format_g(lo) + "), " +
                    detail::format_g(hi) + ")   [linear interval " + detail::format_g(lo) +
                    " <= x <= " + detail::format_g(hi) + "]\n";
    if (theta[1] < theta[0]) s += "  note: lower > upper in theta; the limits are used swapped\n";
    return s;
  }

 private:
  std::optional<std::pair<double, double>> initial_;
};

}  // namespace nlid
