#pragma once
/// @file
/// `PwLinear<Breakpoints>`: a one-dimensional piecewise-linear map through n breakpoints
/// (toolbox `pwlinear` / idPiecewiseLinear), the workhorse input and output block of
/// Hammerstein–Wiener models (`nlhw2` of the throttle study uses it on both sides).
///
/// Math. Breakpoints (x₀, y₀), …, (x_{n−1}, y_{n−1}) with x₀ < x₁ < … < x_{n−1}. Between two
/// breakpoints g interpolates linearly; beyond the ends it extrapolates the first and last
/// segments (so an input outside the estimation range gets a sensible, not a constant, answer):
///
///     g(x) = yₖ + (y_{k+1} − yₖ)(x − xₖ)/(x_{k+1} − xₖ),   k = segment containing x
///                                                          (k = 0 below x₀, n−2 above x_{n−1}).
///
/// Parametrisation that keeps the breakpoints sorted. Breakpoint positions are estimated, and an
/// unconstrained optimiser must never make them cross (crossing would make g discontinuous and
/// the segment slopes infinite). θ therefore holds the first position and the logarithms of the
/// gaps,
///
///     θ = [x₀, γ₁, …, γ_{n−1}, y₀, …, y_{n−1}],     xₖ = x_{k−1} + exp(γₖ),
///
/// so every θ ∈ R²ⁿ gives strictly increasing positions, and the map is smooth in θ away from
/// the breakpoints. Fixing the first n parameters (LmOptions::fixed) keeps the positions where
/// they are and estimates only the values, which is a linear problem. `theta_from_breakpoints`
/// and `breakpoints` convert between θ and the (x, y) table.
///
/// Extreme log-gaps. exp(γₖ) overflows above γₖ ≈ 709.78 (88.7 in float): the segment then
/// reaches beyond every finite x and its slope is computed as Δy·exp(−γₖ), so values and
/// derivatives stay finite and right. A γₖ so small that the slope Δy/exp(γₖ) is not a finite
/// number (exp underflows below about −745, or the quotient overflows) has no representable
/// value or derivative on that segment: evaluating g there throws `nlid::Error` naming
/// "log_gap[k]"; the other segments evaluate normally.
///
/// Initialisation (deterministic, no random restarts):
/// 1. positions: given to the constructor, or chosen by forward selection of hinge functions
///    max(0, x − c) over candidate knots c at quantiles of x and on a uniform grid (orthogonal
///    least squares, Chen et al. 1991): span{1, x, hinges at c₁…c_{n−2}} is exactly the set of
///    piecewise-linear maps with breakpoints {min x, c₁, …, c_{n−2}, max x}, so the greedy picks
///    the knots where the data bend. A data set that bends in fewer places gets its remaining
///    breakpoints in the middle of the widest gaps;
/// 2. values: linear least squares on the "hat function" basis of the interpolant, plus a tiny
///    penalty on slope changes that only decides values the data leave undetermined (a segment
///    without samples, e.g. a step input that takes few levels) — they become the linear
///    interpolation of their neighbours instead of arbitrary numbers.

#include <algorithm>
#include <array>
#include <cmath>
#include <span>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/core/sizes.hpp"
#include "nlid/nonlinearities/detail/common.hpp"
#include "nlid/nonlinearities/detail/forward_selection.hpp"

namespace nlid {

/// Piecewise-linear map of one input through n breakpoints, θ = [x₀, γ₁…γ_{n−1}, y₀…y_{n−1}]
/// with xₖ = x_{k−1} + exp(γₖ); p = 2n.
/// Invariant: n ≥ 2 and equals Breakpoints when fixed; given initial positions (if any) are
/// finite and strictly increasing.
template <int Breakpoints>
  requires(Breakpoints == Dynamic || Breakpoints >= 2)
class PwLinear {
 public:
  /// m = 1.
  static constexpr int num_inputs = 1;
  /// p = 2n (or Dynamic).
  static constexpr int num_params = size_product(2, Breakpoints);

  /// n = Breakpoints, positions estimated from data.
  PwLinear()
    requires(Breakpoints != Dynamic)
  = default;
  /// n breakpoints (≥ 2, must equal Breakpoints when fixed), positions estimated from data.
  /// Throws naming "breakpoints".
  explicit PwLinear(int breakpoints)
      : n_(detail::checked_size(breakpoints, Breakpoints, 2, "breakpoints", "PwLinear")) {}
  /// Breakpoints at the given positions; `initialize` keeps them and fits the values.
  /// Throws naming "breakpoints" (and the offending index) if they are not strictly increasing
  /// or not finite, or their count contradicts Breakpoints.
  explicit PwLinear(std::vector<double> positions)
      : n_(detail::checked_size(static_cast<int>(positions.size()), Breakpoints, 2, "breakpoints",
                                "PwLinear")) {
    for (std::size_t k = 0; k < positions.size(); ++k) {
      if (!std::isfinite(positions[k])) {
        throw Error("PwLinear: breakpoint " + std::to_string(k) + " is not finite",
                    at_parameter("breakpoints"));
      }
      if (k > 0 && !(positions[k] > positions[k - 1])) {
        throw Error("PwLinear: breakpoints must be strictly increasing, but breakpoint " +
                        std::to_string(k) + " (" + detail::format_g(positions[k]) +
                        ") is not greater than breakpoint " + std::to_string(k - 1) + " (" +
                        detail::format_g(positions[k - 1]) + ")",
                    at_parameter("breakpoints"));
      }
    }
    given_ = std::move(positions);
  }

  /// Number of breakpoints n.
  [[nodiscard]] int num_breakpoints() const { return n_; }
  /// Initial positions given to the constructor (empty if they are estimated).
  [[nodiscard]] const std::vector<double>& given_positions() const { return given_; }
  /// Number of inputs (1).
  [[nodiscard]] int input_dimension() const { return 1; }
  /// Number of parameters 2n.
  [[nodiscard]] int num_parameters() const { return 2 * n_; }

  /// Interpolates (extrapolates beyond the ends). Throws if a span has the wrong length, or
  /// naming "log_gap[k]" if x falls on a segment whose slope is not a finite number.
  template <class T>
  [[nodiscard]] T operator()(std::span<const T> x, std::span<const T> theta) const {
    using std::exp;
    if (x.size() != 1) detail::check_size(x.size(), 1, "x", "PwLinear");
    if (static_cast<int>(theta.size()) != 2 * n_) detail::check_size(theta.size(), 2 * n_, "theta", "PwLinear");
    const auto n = static_cast<std::size_t>(n_);
    const T& xv = x[0];
    T xk = theta[0];
    // Walk the segments until x lies left of the segment's right end; the last segment also
    // takes everything beyond it (extrapolation), the first everything before x₀.
    for (std::size_t k = 0; k + 1 < n; ++k) {
      const T gap = exp(theta[1 + k]);
      const T xn = xk + gap;
      if (xv < xn || k + 2 == n) {
        const T slope = segment_slope(theta, k, gap);
        return segment_value(theta, k, slope, xk, xv);
      }
      xk = xn;
    }
    return theta[n];  // unreachable: n ≥ 2
  }

  /// The θ-only part of g for one θ: breakpoint positions xₖ and segment slopes, with a view of
  /// the values yₖ in θ. Built once per simulation by `prepare`, so the n − 1 exponentials of
  /// the positions are not recomputed at every sample (on a 46-wide Dual each is 47 exps' worth
  /// of work; see docs/performance.md, nlhw2).
  template <class T>
  struct Prepared {
    /// Storage of n (or n − 1) scalars: on the stack for a fixed n.
    using Values = std::conditional_t<Breakpoints == Dynamic, std::vector<T>, std::array<T, (Breakpoints > 0 ? Breakpoints : 1)>>;
    Values x{};                  ///< breakpoint positions x₀ < … < x_{n−1}
    Values slope{};              ///< slope of segment k (k < n − 1)
    std::span<const T> values;  ///< y₀ … y_{n−1} (a view of θ)
    std::span<const T> log_gaps;  ///< γ₁ … γ_{n−1} (a view of θ, for the error of a refused segment)
    /// False if some slope is not a finite number: only then does `evaluate_prepared` test the
    /// segment it lands on (a test per sample cost nlhw2's simulation 30 %).
    bool all_slopes_finite = true;
  };

  /// Positions and slopes of θ (see `Prepared`). Throws `nlid::Error` if θ has the wrong length.
  /// (A segment whose slope is not a finite number is refused only when `evaluate_prepared` is
  /// asked for a value on it, as `operator()` does.)
  template <class T>
  [[nodiscard]] Prepared<T> prepare(std::span<const T> theta) const {
    using std::exp;
    using std::isfinite;
    if (static_cast<int>(theta.size()) != 2 * n_) detail::check_size(theta.size(), 2 * n_, "theta", "PwLinear");
    const auto n = static_cast<std::size_t>(n_);
    Prepared<T> p;
    if constexpr (Breakpoints == Dynamic) {
      p.x.resize(n);
      p.slope.resize(n);
    }
    p.values = theta.subspan(n);
    // The same operations in the same order as operator(), so both give bitwise the same g.
    T xk = theta[0];
    p.x[0] = xk;
    for (std::size_t k = 0; k + 1 < n; ++k) {
      const T gap = exp(theta[1 + k]);
      const T xn = xk + gap;
      p.slope[k] = segment_slope(theta, k, gap);
      if (!isfinite(p.slope[k])) p.all_slopes_finite = false;
      p.x[k + 1] = xn;
      xk = xn;
    }
    p.log_gaps = theta.subspan(1, n - 1);
    return p;
  }

  /// g(x) from a `prepare`d θ; equal to `operator()` with that θ (and refusing what it refuses).
  template <class T>
  [[nodiscard]] T evaluate_prepared(const Prepared<T>& p, const T& xv) const {
    // The check of a refused segment stays out of the search loop: inside it, even behind the
    // flag, it cost nlhw2's simulation 30 % (docs/performance.md).
    if (!p.all_slopes_finite) [[unlikely]] return evaluate_prepared_checked(p, xv);
    const auto n = static_cast<std::size_t>(n_);
    for (std::size_t k = 0; k + 1 < n; ++k) {
      if (xv < p.x[k + 1] || k + 2 == n) return p.values[k] + p.slope[k] * (xv - p.x[k]);
    }
    return p.values[0];  // unreachable: n ≥ 2
  }

  /// Breakpoint positions (given, or by hinge forward selection) and least-squares values.
  void initialize(const Eigen::MatrixXd& X, const Eigen::VectorXd& y, std::span<double> theta) {
    detail::check_init_data(X, y, theta.size(), 1, 2 * n_, 2, "PwLinear");
    const Eigen::VectorXd x = X.col(0);
    std::vector<double> pos = given_.empty() ? select_positions(x, y) : given_;
    const Eigen::VectorXd values = fit_values(x, y, pos);
    std::vector<double> vals(values.data(), values.data() + values.size());
    theta_from_breakpoints(pos, vals, theta);
  }

  /// Writes θ for breakpoints (x, y); x finite and strictly increasing, y finite. Throws naming
  /// "breakpoints" or "values" (θ is left unchanged then).
  void theta_from_breakpoints(std::span<const double> xs, std::span<const double> ys,
                              std::span<double> theta) const {
    detail::check_size(xs.size(), n_, "breakpoints", "PwLinear");
    detail::check_size(ys.size(), n_, "values", "PwLinear");
    detail::check_size(theta.size(), 2 * n_, "theta", "PwLinear");
    for (std::size_t k = 0; k < xs.size(); ++k) {
      if (!std::isfinite(xs[k])) {
        throw Error("PwLinear: breakpoint " + std::to_string(k) + " is not finite", at_parameter("breakpoints"));
      }
      if (!std::isfinite(ys[k])) {
        throw Error("PwLinear: value " + std::to_string(k) + " is not finite", at_parameter("values"));
      }
      if (k > 0 && !(xs[k] > xs[k - 1])) {
        throw Error("PwLinear: breakpoints must be strictly increasing at index " + std::to_string(k),
                    at_parameter("breakpoints"));
      }
      // Finite neighbours can still be more than DBL_MAX apart; θ would hold log(∞).
      if (k > 0 && !std::isfinite(xs[k] - xs[k - 1])) {
        throw Error("PwLinear: the gap between breakpoints " + std::to_string(k - 1) + " and " + std::to_string(k) +
                        " is not a finite number",
                    at_parameter("breakpoints"));
      }
    }
    theta[0] = xs[0];
    for (std::size_t k = 1; k < xs.size(); ++k) theta[k] = std::log(xs[k] - xs[k - 1]);
    for (std::size_t k = 0; k < ys.size(); ++k) theta[xs.size() + k] = ys[k];
  }

  /// The breakpoint table (positions, values) encoded by θ.
  [[nodiscard]] std::pair<std::vector<double>, std::vector<double>> breakpoints(
      std::span<const double> theta) const {
    detail::check_size(theta.size(), 2 * n_, "theta", "PwLinear");
    const auto n = static_cast<std::size_t>(n_);
    std::vector<double> xs(n), ys(n);
    xs[0] = theta[0];
    for (std::size_t k = 1; k < n; ++k) xs[k] = xs[k - 1] + std::exp(theta[k]);
    for (std::size_t k = 0; k < n; ++k) ys[k] = theta[n + k];
    return {xs, ys};
  }

  /// The unit of each parameter when x is measured in units of size `in` and g(x) in units of
  /// size `out` (estimation uses them to damp steps alike whatever units the data are in).
  /// The log-gaps are unitless: a change of units shifts them.
  bool parameter_scales(double in, double out, std::span<double> s) const {
    s[0] = in;
    for (int k = 1; k < n_; ++k) s[static_cast<std::size_t>(k)] = 1.0;
    for (int k = 0; k < n_; ++k) s[static_cast<std::size_t>(n_ + k)] = out;
    return true;
  }

  /// "x[0]", "log_gap[1]" … "log_gap[n−1]", "y[0]" … "y[n−1]".
  [[nodiscard]] std::vector<std::string> parameter_names() const {
    std::vector<std::string> s{"x[0]"};
    for (int k = 1; k < n_; ++k) s.push_back("log_gap[" + std::to_string(k) + "]");
    for (int k = 0; k < n_; ++k) s.push_back("y[" + std::to_string(k) + "]");
    return s;
  }

  /// The breakpoint table with the slope of each segment.
  [[nodiscard]] std::string describe(std::span<const double> theta) const {
    const auto [xs, ys] = breakpoints(theta);
    std::string s = "piecewise linear (" + std::to_string(n_) +
                    " breakpoints, linear extrapolation beyond the ends): g(x) through\n";
    for (std::size_t k = 0; k < xs.size(); ++k) {
      if (!std::isfinite(xs[k])) {
        // exp(log_gap) overflowed on the way here (see the file comment): the previous segment
        // reaches beyond every finite x, so this breakpoint and those after it are never met.
        s += "  (beyond every finite x, " + detail::format_g(ys[k]) + ")   not reached: log_gap[" + std::to_string(k) +
             "] or an earlier one overflows exp\n";
        continue;
      }
      s += "  (" + detail::format_g(xs[k]) + ", " + detail::format_g(ys[k]) + ")";
      if (k + 1 < xs.size()) {
        const double gap = xs[k + 1] - xs[k];
        // Δy·exp(−γ) where the gap overflows, as the evaluation computes it.
        const double slope = std::isfinite(gap) ? (ys[k + 1] - ys[k]) / gap : (ys[k + 1] - ys[k]) * std::exp(-theta[k + 1]);
        s += "   slope to next: " + detail::format_g(slope);
      }
      s += "\n";
    }
    return s;
  }

  // ---- Implementation details below ----------------------------------------------------------
 private:
  // Slope (y_{k+1} − y_k)/exp(γ_{k+1}) of segment k, given gap = exp(γ_{k+1}). Above
  // γ = ln(DBL_MAX) ≈ 709.78 the gap overflows to +∞: the value Δy/∞ = 0 would still be right,
  // but on a Dual the quotient's derivative is (Δy'·∞ − Δy·∞·γ')/∞² = NaN, and estimation would
  // stop at "Jacobian not finite" although the model is fine (segment k then reaches beyond every
  // finite x; the next positions are +∞ and never selected). There the same slope is
  // Δy·exp(−γ), finite with finite derivatives. Below the threshold the division is kept, so
  // every ordinary θ gives bitwise the values it always gave (and the C code generated from it,
  // where γ is a known parameter and the test is decided at generation time, is unchanged).
  template <class T>
  static T segment_slope(std::span<const T> theta, std::size_t k, const T& gap) {
    using std::exp;
    using std::isfinite;
    const auto n = theta.size() / 2;
    if (isfinite(gap)) return (theta[n + k + 1] - theta[n + k]) / gap;
    return (theta[n + k + 1] - theta[n + k]) * exp(-theta[1 + k]);
  }

  // y_k + slope·(x − x_k) on segment k. A slope that is not a finite number comes from a gap
  // too small for it (γ below about −709 + ln|Δy|: exp(γ) underflows, or Δy/exp(γ) overflows):
  // the breakpoints k and k + 1 coincide in double precision, and the value (∞·0 = NaN at
  // x = x_k, 0/0 when Δy = 0) and its derivative (∞) cannot be represented — an error naming the
  // log-gap, instead of a NaN or an infinity in the simulation. (Only for finite θ entries.)
  template <class T>
  T segment_value(std::span<const T> theta, std::size_t k, const T& slope, const T& xk, const T& xv) const {
    using std::isfinite;
    const auto n = theta.size() / 2;
    if (!isfinite(slope)) [[unlikely]] refuse_slope(k, theta[n + k + 1] - theta[n + k], theta[1 + k]);
    return theta[n + k] + slope * (xv - xk);
  }

  // The number under a double, float, Dual or traced scalar (for messages only).
  template <class T>
  static double plain_value(const T& v) {
    if constexpr (std::is_arithmetic_v<T>) {
      return static_cast<double>(v);
    } else if constexpr (requires { v.value(); }) {
      return static_cast<double>(v.value());  // codegen's TraceScalar: a known parameter's value
    } else {
      return static_cast<double>(value_of(v));
    }
  }

  // evaluate_prepared where some slope is not a finite number: refuses the segment x lands on if
  // it is one of those.
  template <class T>
  [[gnu::noinline]] T evaluate_prepared_checked(const Prepared<T>& p, const T& xv) const {
    using std::isfinite;
    const auto n = static_cast<std::size_t>(n_);
    for (std::size_t k = 0; k + 1 < n; ++k) {
      if (xv < p.x[k + 1] || k + 2 == n) {
        if (!isfinite(p.slope[k])) refuse_slope(k, p.values[k + 1] - p.values[k], p.log_gaps[k]);
        return p.values[k] + p.slope[k] * (xv - p.x[k]);
      }
    }
    return p.values[0];  // unreachable: n ≥ 2
  }

  // Throws the error of a segment whose slope is not finite although Δy and γ are: the gap is
  // the culprit. (Non-finite entries of θ are passed through as before: NaN in, NaN out.) Cold
  // and out of line, so its message building does not weigh on the loops that call it.
  template <class T>
  [[gnu::cold, gnu::noinline]] static void refuse_slope(std::size_t k, const T& dy, const T& log_gap) {
    const double g = plain_value(log_gap), d = plain_value(dy);
    if (!std::isfinite(g) || !std::isfinite(d)) return;
    const std::string gap_name = "log_gap[" + std::to_string(k + 1) + "]";
    throw Error("PwLinear: the slope of segment " + std::to_string(k) + ", (y[" + std::to_string(k + 1) + "] - y[" +
                    std::to_string(k) + "]) / exp(" + gap_name + ") = " + detail::format_g(d) + " / exp(" +
                    detail::format_g(g) + "), is not a finite number: " + gap_name + " = " + detail::format_g(g) +
                    " puts breakpoints " + std::to_string(k) + " and " + std::to_string(k + 1) +
                    " closer together than the slope between them can be represented",
                at_parameter(gap_name));
  }

  std::vector<double> select_positions(const Eigen::VectorXd& x, const Eigen::VectorXd& y) const {
    const double xmin = x.minCoeff();
    const double xmax = x.maxCoeff();
    if (!(xmax > xmin)) {
      throw Error("PwLinear: column 1 of X is constant (" + detail::format_g(xmin) +
                      "); breakpoints cannot be placed — give them to the constructor",
                  at_parameter("X"));
    }
    const double range = xmax - xmin;
    const int interior = n_ - 2;
    std::vector<double> knots;
    if (interior > 0) {
      const auto rows = detail::subsample_rows(x.size(), 4000);
      const auto nr = static_cast<Eigen::Index>(rows.size());
      Eigen::VectorXd xs(nr), ys(nr);
      for (Eigen::Index i = 0; i < nr; ++i) {
        xs(i) = x(rows[static_cast<std::size_t>(i)]);
        ys(i) = y(rows[static_cast<std::size_t>(i)]);
      }
      // Candidate knots: quantiles (dense where data are) and a uniform grid (covers sparse
      // regions), strictly inside the range and distinct.
      const auto sorted = detail::sorted_copy(xs);
      std::vector<double> cand;
      constexpr int kQuantiles = 64, kGrid = 32;
      for (int i = 0; i < kQuantiles; ++i) cand.push_back(detail::quantile_sorted(sorted, (i + 0.5) / kQuantiles));
      for (int i = 1; i < kGrid; ++i) cand.push_back(xmin + range * i / kGrid);
      std::sort(cand.begin(), cand.end());
      std::vector<double> uniq;
      for (double c : cand) {
        if (c <= xmin + 1e-6 * range || c >= xmax - 1e-6 * range) continue;
        if (!uniq.empty() && c - uniq.back() <= 1e-6 * range) continue;
        uniq.push_back(c);
      }
      Eigen::MatrixXd H(nr, static_cast<Eigen::Index>(uniq.size()));
      for (std::size_t j = 0; j < uniq.size(); ++j) {
        H.col(static_cast<Eigen::Index>(j)) = (xs.array() - uniq[j]).max(0.0).matrix();
      }
      const double sst = (ys.array() - ys.mean()).square().sum();
      std::vector<int> chosen;
      {
        detail::ForwardSelector sel(ys, H, 1);
        sel.add_fixed(Eigen::VectorXd::Ones(nr));
        sel.add_fixed(xs);
        while (static_cast<int>(chosen.size()) < interior) {
          double explained = 0;
          const int j = sel.select(explained);
          if (j < 0 || !(explained > 1e-12 * sst)) break;
          chosen.push_back(j);
        }
      }
      // Exchange refinement: greedy steps are myopic (the best single hinge for a two-bend
      // target sits between the bends), so each knot in turn is re-chosen as the best candidate
      // given all the others. The residual never grows, so the sweeps terminate.
      for (int sweep = 0; sweep < 10 && chosen.size() > 1; ++sweep) {
        bool changed = false;
        for (std::size_t i = 0; i < chosen.size(); ++i) {
          detail::ForwardSelector sel(ys, H, 1);
          sel.add_fixed(Eigen::VectorXd::Ones(nr));
          sel.add_fixed(xs);
          for (std::size_t k = 0; k < chosen.size(); ++k) {
            if (k != i) sel.add_fixed(H.col(chosen[k]));
          }
          const double current = sel.explained_by(chosen[i]);
          double best = 0;
          const int j = sel.select(best);
          if (j >= 0 && j != chosen[i] && best > current + 1e-9 * sst) {
            chosen[i] = j;
            changed = true;
          }
        }
        if (!changed) break;
      }
      for (int j : chosen) knots.push_back(uniq[static_cast<std::size_t>(j)]);
      std::sort(knots.begin(), knots.end());
      refine_knots(xs, ys, xmin, xmax, knots);
    }
    std::vector<double> pos{xmin, xmax};
    pos.insert(pos.end(), knots.begin(), knots.end());
    std::sort(pos.begin(), pos.end());
    // Breakpoints the data do not ask for: halve the widest gap, repeatedly.
    while (static_cast<int>(pos.size()) < n_) {
      std::size_t w = 0;
      for (std::size_t k = 1; k + 1 < pos.size(); ++k) {
        if (pos[k + 1] - pos[k] > pos[w + 1] - pos[w]) w = k;
      }
      pos.insert(pos.begin() + static_cast<std::ptrdiff_t>(w + 1), 0.5 * (pos[w] + pos[w + 1]));
    }
    return pos;
  }

  // Residual sum of squares of the best continuous piecewise-linear fit with the given interior
  // knots (span{1, x, max(0, x − c)}), by normal equations — only used to compare knot sets.
  static double hinge_rss(const Eigen::VectorXd& x, const Eigen::VectorXd& y, const std::vector<double>& knots) {
    const auto n = static_cast<Eigen::Index>(knots.size()) + 2;
    Eigen::MatrixXd A(x.size(), n);
    A.col(0).setOnes();
    A.col(1) = x;
    for (std::size_t k = 0; k < knots.size(); ++k) {
      A.col(static_cast<Eigen::Index>(k) + 2) = (x.array() - knots[k]).max(0.0).matrix();
    }
    return (y - A * detail::least_squares(A, y)).squaredNorm();
  }

  // Continuous refinement of each knot by golden-section search between its neighbours (the
  // candidate grid only places knots to within its spacing). Each accepted move lowers the RSS.
  static void refine_knots(const Eigen::VectorXd& xs, const Eigen::VectorXd& ys, double xmin, double xmax,
                           std::vector<double>& knots) {
    const auto rows = detail::subsample_rows(xs.size(), 1000);
    Eigen::VectorXd x(static_cast<Eigen::Index>(rows.size())), y(x.size());
    for (std::size_t i = 0; i < rows.size(); ++i) {
      x(static_cast<Eigen::Index>(i)) = xs(rows[i]);
      y(static_cast<Eigen::Index>(i)) = ys(rows[i]);
    }
    const double range = xmax - xmin;
    const double gr = 0.5 * (std::sqrt(5.0) - 1.0);
    for (int sweep = 0; sweep < 2; ++sweep) {
      for (std::size_t i = 0; i < knots.size(); ++i) {
        const double lo_nb = i == 0 ? xmin : knots[i - 1];
        const double hi_nb = i + 1 == knots.size() ? xmax : knots[i + 1];
        // Search the middle half of each neighbouring gap, so knots stay apart.
        double a = knots[i] - 0.5 * (knots[i] - lo_nb), b = knots[i] + 0.5 * (hi_nb - knots[i]);
        if (!(b - a > 1e-9 * range)) continue;
        auto cost = [&](double c) {
          auto k = knots;
          k[i] = c;
          return hinge_rss(x, y, k);
        };
        const double best0 = cost(knots[i]);
        double c1 = b - gr * (b - a), c2 = a + gr * (b - a);
        double f1 = cost(c1), f2 = cost(c2);
        for (int it = 0; it < 30 && b - a > 1e-7 * range; ++it) {
          if (f1 <= f2) {
            b = c2; c2 = c1; f2 = f1; c1 = b - gr * (b - a); f1 = cost(c1);
          } else {
            a = c1; c1 = c2; f1 = f2; c2 = a + gr * (b - a); f2 = cost(c2);
          }
        }
        const double c = f1 <= f2 ? c1 : c2;
        if (std::min(f1, f2) < best0) knots[i] = c;
      }
    }
  }

  Eigen::VectorXd fit_values(const Eigen::VectorXd& x, const Eigen::VectorXd& y,
                             const std::vector<double>& pos) const {
    const auto n = static_cast<Eigen::Index>(pos.size());
    const Eigen::Index N = x.size();
    const Eigen::Index penalties = n - 2;
    Eigen::MatrixXd A = Eigen::MatrixXd::Zero(N + penalties, n);
    Eigen::VectorXd b = Eigen::VectorXd::Zero(N + penalties);
    for (Eigen::Index i = 0; i < N; ++i) {
      Eigen::Index k = 0;
      while (k + 2 < n && x(i) >= pos[static_cast<std::size_t>(k + 1)]) ++k;
      const double x0 = pos[static_cast<std::size_t>(k)], x1 = pos[static_cast<std::size_t>(k + 1)];
      const double t = (x(i) - x0) / (x1 - x0);
      A(i, k) = 1 - t;
      A(i, k + 1) = t;
      b(i) = y(i);
    }
    // Second-difference (slope change) penalty, in units of y, weighted so that it matters only
    // where the data determine nothing.
    const double hbar = (pos.back() - pos.front()) / static_cast<double>(n - 1);
    const double w = 1e-7 * std::sqrt(static_cast<double>(N));
    for (Eigen::Index k = 1; k + 1 < n; ++k) {
      const double hl = pos[static_cast<std::size_t>(k)] - pos[static_cast<std::size_t>(k - 1)];
      const double hr = pos[static_cast<std::size_t>(k + 1)] - pos[static_cast<std::size_t>(k)];
      const Eigen::Index r = N + k - 1;
      A(r, k - 1) = w * hbar / hl;
      A(r, k) = -w * hbar * (1 / hl + 1 / hr);
      A(r, k + 1) = w * hbar / hr;
    }
    return detail::least_squares(A, b);
  }

  int n_ = Breakpoints;
  std::vector<double> given_;
};

}  // namespace nlid
