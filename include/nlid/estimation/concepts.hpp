#pragma once
/// @file
/// Concepts of the estimation layer: what a least-squares problem and a residual functor are.
///
/// Every estimator in nlid (prediction-error ARX/OE, nonlinear ARX, Hammerstein–Wiener, grey
/// box) reduces to the same nonlinear least-squares problem (Ljung 1999, sec. 7.2, eq. 7.11;
/// sec. 10.2 for its numerical solution):
///
///     θ̂ = arg min_θ  F(θ),   F(θ) = ½ Σᵢ ρ(rᵢ(θ)²),   r ∈ Rᵐ, θ ∈ Rⁿ,
///
/// where rᵢ are prediction or simulation errors and ρ is a loss (ρ(s) = s: ordinary least
/// squares; see `robust_loss.hpp`). A solver needs r and its Jacobian J = ∂r/∂θ (m × n). Two
/// shapes of user code provide them:
///
/// 1. `LeastSquaresProblem` — the solver's interface: evaluates r and, on request, J:
///
///        static constexpr int num_params;          // n, or nlid::Dynamic
///        int num_parameters() const;               // n at run time
///        Eigen::Index num_residuals() const;       // m (the data length: always run time)
///        bool evaluate(const Eigen::Matrix<double, num_params, 1>& theta, Eigen::VectorXd& r,
///                      Eigen::Matrix<double, Eigen::Dynamic, num_params>* J) const;
///
///    `r` arrives sized m and `J` is null (no Jacobian wanted) or sized m × n. `evaluate` returns
///    false if the model cannot be evaluated at θ (a diverging simulation, a log of a negative
///    number): the solver then rejects the step instead of propagating NaN.
///
/// 2. `ResidualFunctor` — the model author's interface, Ceres-style: residuals only, written
///    once as a template over the scalar so that `AutoDiffProblem` can evaluate it on `double`
///    (residuals) and on `Dual` (residuals and exact Jacobian in one pass):
///
///        static constexpr int num_params;          // n, or nlid::Dynamic
///        int num_parameters() const;
///        Eigen::Index num_residuals() const;
///        template <class T> bool residuals(std::span<const T> theta, std::span<T> r) const;
///
/// Sizes follow the Ceres lesson (issue #833): the parameter count may be static (then the
/// solver's workspace is fixed-size and allocation-free), the residual count never is.

#include <concepts>
#include <span>

#include <Eigen/Core>

#include "nlid/ad/dual.hpp"
#include "nlid/core/sizes.hpp"

namespace nlid {

/// Parameter vector of a problem with `P` parameters (`P` may be `Dynamic`).
template <int P>
using ParameterVector = Eigen::Matrix<double, P, 1>;

/// Jacobian of m residuals with respect to `P` parameters: m × P, column-major, m at run time.
template <int P>
using JacobianMatrix = Eigen::Matrix<double, Eigen::Dynamic, P>;

/// Number of derivatives carried per pass by `AutoDiffProblem` when the parameter count is
/// `Dynamic`: parameters are differentiated in chunks of this many with a fixed-size `Dual`.
inline constexpr int default_ad_chunk_size = 8;

namespace detail {

/// `T::num_params` exists, is an int constant, and is a valid size (≥ 1 or Dynamic).
template <class T>
concept HasParamCount = requires {
  { T::num_params } -> std::convertible_to<int>;
} && (T::num_params == Dynamic || T::num_params >= 1);

/// The dual type a residual functor is checked (and by default evaluated) with.
template <class F>
using FunctorDual = Dual<double, F::num_params == Dynamic ? default_ad_chunk_size : F::num_params>;

}  // namespace detail

/// A nonlinear least-squares problem as the solver sees it (see the file comment for the
/// contract). Satisfied by `AutoDiffProblem<F>`, `NumericDiffProblem<F>`, `FunctionProblem<P, Fn>`,
/// `StackedProblem<Pb>` and any user type with analytic Jacobians and the same members.
template <class P>
concept LeastSquaresProblem =
    detail::HasParamCount<P> &&
    requires(const P& p, const ParameterVector<P::num_params>& theta, Eigen::VectorXd& r,
             JacobianMatrix<P::num_params>* J) {
      { p.num_parameters() } -> std::convertible_to<int>;
      { p.num_residuals() } -> std::convertible_to<Eigen::Index>;
      { p.evaluate(theta, r, J) } -> std::convertible_to<bool>;
    };

/// Residuals written once over the scalar type, evaluable on `double` and on `Dual`.
/// Satisfied by any type with `num_params`, `num_parameters()`, `num_residuals()` and a member
/// template `residuals(std::span<const T>, std::span<T>)` callable with T = double and with the
/// dual type `AutoDiffProblem` will use (e.g. every nlid model's prediction-error functor).
template <class F>
concept ResidualFunctor =
    detail::HasParamCount<F> &&
    requires(const F& f, std::span<const double> theta, std::span<double> r,
             std::span<const detail::FunctorDual<F>> theta_d,
             std::span<detail::FunctorDual<F>> r_d) {
      { f.num_parameters() } -> std::convertible_to<int>;
      { f.num_residuals() } -> std::convertible_to<Eigen::Index>;
      { f.residuals(theta, r) } -> std::convertible_to<bool>;
      { f.residuals(theta_d, r_d) } -> std::convertible_to<bool>;
    };

}  // namespace nlid
