#pragma once
/// @file
/// Jacobians by central finite differences, and a Jacobian checker.
///
/// Central differences approximate column k of J = ∂r/∂θ by
///
///     J_k ≈ (r(θ + h_k e_k) − r(θ − h_k e_k)) / (2 h_k),   h_k = η · max(|θ_k|, 1),
///
/// with truncation error O(h²)·‖r'''‖ and rounding error O(ε‖r‖/h); η = ε^{1/3} ≈ 6·10⁻⁶
/// balances the two (Nocedal & Wright, "Numerical Optimization", 2nd ed., 2006, sec. 8.1,
/// eq. 8.7), giving about 2/3 of the digits of r. Costs 2n residual evaluations.
///
/// Uses: `NumericDiffProblem<F>` for functors that cannot run on `Dual` (a black-box
/// simulator) or to cross-check `AutoDiffProblem`; `check_jacobian` to validate a hand-written
/// analytic Jacobian of any `LeastSquaresProblem` (like Ceres' GradientChecker).

#include <algorithm>
#include <cmath>
#include <limits>
#include <span>
#include <string>
#include <utility>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/estimation/concepts.hpp"

namespace nlid {

/// Default relative step η = ε^{1/3} of central differences.
inline constexpr double default_relative_step = 6.055454452393343e-06;  // ε^{1/3}, ε = 2^-52

namespace detail {
inline void check_relative_step(double eta) {
  if (!(std::isfinite(eta) && eta > 0 && eta < 1)) {
    throw Error("relative finite-difference step must be in (0, 1), got " + format_g(eta),
                at_parameter("relative_step"));
  }
}
}  // namespace detail

/// Adapts a residual functor into a `LeastSquaresProblem` whose Jacobian is computed by central
/// differences of the `double` residuals. Scratch vectors are per thread (sized in the
/// constructor for the constructing thread), so `evaluate` is const, thread-safe if the functor
/// is, and allocation-free in steady state.
template <ResidualFunctor F>
class NumericDiffProblem {
 public:
  static constexpr int num_params = F::num_params;   ///< static parameter count (or Dynamic)
  using Parameters = ParameterVector<num_params>;    ///< θ
  using Jacobian = JacobianMatrix<num_params>;       ///< J

  /// Wraps the functor; `relative_step` is η above. Throws `nlid::Error` on a bad step or sizes.
  explicit NumericDiffProblem(F functor, double relative_step = default_relative_step)
      : f_(std::move(functor)), eta_(relative_step) {
    detail::check_relative_step(eta_);
    const int n = f_.num_parameters();
    if (n < 1 || (num_params != Dynamic && n != num_params)) {
      throw Error("NumericDiffProblem: functor reports " + std::to_string(n) +
                      " parameters but its static num_params is " + std::to_string(num_params),
                  at_parameter("num_parameters"));
    }
    if (f_.num_residuals() < 1) {
      throw Error("NumericDiffProblem: functor reports no residuals", at_parameter("num_residuals"));
    }
    scratch(n, f_.num_residuals());
  }

  /// n.
  int num_parameters() const { return f_.num_parameters(); }
  /// m.
  Eigen::Index num_residuals() const { return f_.num_residuals(); }
  /// The wrapped functor.
  const F& functor() const { return f_; }

  /// r(θ) and, if requested, the central-difference Jacobian. False if any evaluation fails.
  bool evaluate(const Parameters& theta, Eigen::VectorXd& r, Jacobian* J) const {
    const int n = num_parameters();
    const Eigen::Index m = num_residuals();
    if (theta.size() != n || r.size() != m || (J && (J->rows() != m || J->cols() != n))) {
      throw Error("NumericDiffProblem::evaluate: argument sizes do not match the problem (" +
                      std::to_string(n) + " parameters, " + std::to_string(m) + " residuals)",
                  at_parameter("theta"));
    }
    if (!call(theta, r)) return false;
    if (J == nullptr) return true;
    Scratch& w = scratch(n, m);
    Parameters& th = w.theta;
    th = theta;
    for (int k = 0; k < n; ++k) {
      const double h = eta_ * std::max(std::abs(theta[k]), 1.0);
      th[k] = theta[k] + h;
      const double hp = th[k] - theta[k];  // the step actually representable
      if (!call(th, w.r_plus)) return false;
      th[k] = theta[k] - h;
      const double hm = theta[k] - th[k];
      if (!call(th, w.r_minus)) return false;
      th[k] = theta[k];
      J->col(k) = (w.r_plus - w.r_minus) / (hp + hm);
    }
    return true;
  }

 private:
  bool call(const Parameters& th, Eigen::VectorXd& out) const {
    return f_.residuals(std::span<const double>(th.data(), static_cast<std::size_t>(th.size())),
                        std::span<double>(out.data(), static_cast<std::size_t>(out.size())));
  }
  struct Scratch {
    Parameters theta;
    Eigen::VectorXd r_plus, r_minus;
  };
  // Per-thread buffers (one set per functor type), resized only when the sizes change.
  static Scratch& scratch(int n, Eigen::Index m) {
    thread_local Scratch s;
    if (s.theta.size() != n) s.theta.resize(n);
    if (s.r_plus.size() != m) {
      s.r_plus.resize(m);
      s.r_minus.resize(m);
    }
    return s;
  }

  F f_;
  double eta_;
};

/// Central-difference Jacobian of any `LeastSquaresProblem` at θ (its own Jacobian is not used).
/// `J` is resized to m × n. Returns false if an evaluation fails.
template <LeastSquaresProblem P>
bool numeric_jacobian(const P& problem, const ParameterVector<P::num_params>& theta,
                      JacobianMatrix<P::num_params>& J,
                      double relative_step = default_relative_step) {
  detail::check_relative_step(relative_step);
  const int n = problem.num_parameters();
  const Eigen::Index m = problem.num_residuals();
  if (theta.size() != n) {
    throw Error("numeric_jacobian: theta has " + std::to_string(theta.size()) +
                    " entries, the problem has " + std::to_string(n) + " parameters",
                at_parameter("theta"));
  }
  J.resize(m, n);
  Eigen::VectorXd rp(m), rm(m);
  ParameterVector<P::num_params> th = theta;
  for (int k = 0; k < n; ++k) {
    const double h = relative_step * std::max(std::abs(theta[k]), 1.0);
    th[k] = theta[k] + h;
    const double hp = th[k] - theta[k];
    if (!problem.evaluate(th, rp, nullptr)) return false;
    th[k] = theta[k] - h;
    const double hm = theta[k] - th[k];
    if (!problem.evaluate(th, rm, nullptr)) return false;
    th[k] = theta[k];
    J.col(k) = (rp - rm) / (hp + hm);
  }
  return true;
}

/// Outcome of `check_jacobian`: the worst disagreement between the problem's Jacobian and
/// central differences, measured as |J − J_fd| / max(1, |J_fd|) entry-wise.
struct JacobianCheck {
  double max_error = 0;   ///< largest mixed absolute/relative error
  Eigen::Index row = -1;  ///< residual index of the worst entry
  int column = -1;        ///< parameter index of the worst entry
  bool ok = false;        ///< max_error ≤ tolerance
};

/// Compares the problem's own Jacobian at θ with central differences. Throws `nlid::Error` if
/// the problem cannot be evaluated at θ or θ has the wrong size (the error names the parameter
/// vector), or if `tolerance` is negative or not finite (a check that could never pass).
template <LeastSquaresProblem P>
JacobianCheck check_jacobian(const P& problem, const ParameterVector<P::num_params>& theta,
                             double tolerance = 1e-6) {
  if (!(std::isfinite(tolerance) && tolerance >= 0)) {
    throw Error("check_jacobian: tolerance must be finite and >= 0, got " + detail::format_g(tolerance),
                at_parameter("tolerance"));
  }
  const int n = problem.num_parameters();
  const Eigen::Index m = problem.num_residuals();
  if (theta.size() != n) {
    throw Error("check_jacobian: theta has " + std::to_string(theta.size()) + " entries, the problem has " +
                    std::to_string(n) + " parameters",
                at_parameter("theta"));
  }
  Eigen::VectorXd r(m);
  JacobianMatrix<P::num_params> J(m, n), Jfd;
  if (!problem.evaluate(theta, r, &J) || !numeric_jacobian(problem, theta, Jfd)) {
    throw Error("check_jacobian: the problem cannot be evaluated at the given parameters",
                at_parameter("theta"));
  }
  JacobianCheck c;
  for (int k = 0; k < n; ++k) {
    for (Eigen::Index i = 0; i < m; ++i) {
      const double e = std::abs(J(i, k) - Jfd(i, k)) / std::max(1.0, std::abs(Jfd(i, k)));
      if (!(e <= c.max_error)) {  // also catches NaN
        c.max_error = std::isnan(e) ? std::numeric_limits<double>::infinity() : e;
        c.row = i;
        c.column = k;
      }
    }
  }
  c.ok = c.max_error <= tolerance;
  return c;
}

}  // namespace nlid
