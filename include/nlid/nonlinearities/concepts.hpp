#pragma once
/// @file
/// The `Nonlinearity` concept: a static map g: Rᵐ → R with parameters θ ∈ Rᵖ.
///
/// Nonlinear black-box models are compositions of a few building blocks (Sjöberg et al.,
/// "Nonlinear black-box modeling in system identification: a unified overview", Automatica 31(12),
/// 1995, Sec. 3; Ljung, "System Identification", 2nd ed., 1999, Sec. 5.4):
///
///     y(t) = g(φ(t), θ)                      nonlinear ARX: φ = regressors, g = nonlinearity
///     w = f(u),  x = B/F w,  y = h(x)        Hammerstein–Wiener: f, h are nonlinearities, m = 1
///
/// Most g are *basis-function expansions* (Sjöberg 1995, eq. (8)): a linear part plus a weighted
/// sum of units κ(βₖ(φ − γₖ)) of one mother function κ (sigmoid, wavelet, hinge, ...).
///
/// Division of state. A nonlinearity *object* holds the structure: input dimension, number of
/// units, and whatever `initialize` learns about the data that is not a parameter (the regressor
/// mean and scale used for normalisation, candidate breakpoints). The parameter vector θ lives
/// outside, in the caller's storage, so one object evaluates on `double` (simulation), `float`
/// (deployment) and `Dual` (Jacobians by forward AD) without copies.
///
/// Contract (see docs/architecture.md, "nonlinearities"):
///
///     static constexpr int num_inputs;   // m, or nlid::Dynamic
///     static constexpr int num_params;   // p, or nlid::Dynamic
///     int input_dimension() const;       // m at run time
///     int num_parameters() const;        // p at run time
///     template <class T> T operator()(std::span<const T> x, std::span<const T> theta) const;
///     void initialize(const Eigen::MatrixXd& X, const Eigen::VectorXd& y, std::span<double> theta);
///     std::vector<std::string> parameter_names() const;        // size p, e.g. "L[0]", "a[2]"
///     std::string describe(std::span<const double> theta) const;
///
/// Guarantees of every nlid nonlinearity (the generic property suite checks them):
/// - `operator()` is a pure function of (x, θ); it throws `nlid::Error` if a span has the wrong
///   length, and with fixed sizes it allocates nothing;
/// - it is differentiable in x and θ wherever the map is (piecewise maps: away from kinks), and
///   `Dual` evaluation gives exactly those derivatives;
/// - `initialize` is deterministic (same data → same θ, no random starts), fits the data by
///   (linear) least squares with any nonlinear unit parameters chosen from the data, and throws
///   `nlid::Error` naming `X`, `y` or `theta` (and the row/column of a non-finite cell) on bad input.

#include <concepts>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "nlid/ad/dual.hpp"
#include "nlid/core/sizes.hpp"

namespace nlid {

namespace detail {

/// The static sizes are present, are ints, and are valid (positive or Dynamic; p may be 0).
template <class F>
concept HasNonlinearitySizes = requires {
  { F::num_inputs } -> std::convertible_to<int>;
  { F::num_params } -> std::convertible_to<int>;
} && (F::num_inputs == Dynamic || F::num_inputs >= 1) && (F::num_params == Dynamic || F::num_params >= 0);

/// `f(x, θ)` is callable with spans of scalar T and returns T.
template <class F, class T>
concept EvaluatesOn = requires(const F& f, std::span<const T> x, std::span<const T> theta) {
  { f(x, theta) } -> std::same_as<T>;
};

/// `part.parameter_scales(in, out, s)` where the component has it (the unit of each of its
/// parameters for signals in units `in` → `out`; PwLinear, TransferFunctionBlock, …), else false
/// with `s` untouched: one detection for the type-erased map and for the estimator.
template <class Part>
bool parameter_scales_of(const Part& part, double in, double out, std::span<double> s) {
  if constexpr (requires { part.parameter_scales(in, out, s); }) {
    return static_cast<bool>(part.parameter_scales(in, out, s));
  } else {
    return false;
  }
}

}  // namespace detail

/// A static map g: Rᵐ → R with external parameters θ (see the file comment for the contract).
/// Satisfied by UnitGain, LinearMap<M>, SigmoidNet<M, Units, LinearTerm>,
/// WaveletNet<M, Units, LinearTerm>, PwLinear<Breakpoints>, Saturation, DeadZone, Poly1d<Degree>,
/// TreePartition<M, Depth>,
/// and any user type with the same members that evaluates on double and Dual.
template <class F>
concept Nonlinearity =
    std::copy_constructible<F> && detail::HasNonlinearitySizes<F> &&
    detail::EvaluatesOn<F, double> && detail::EvaluatesOn<F, Dual<double, 1>> &&
    requires(const F& cf, F& f, const Eigen::MatrixXd& X, const Eigen::VectorXd& y,
             std::span<double> theta, std::span<const double> ctheta) {
      { cf.input_dimension() } -> std::convertible_to<int>;
      { cf.num_parameters() } -> std::convertible_to<int>;
      f.initialize(X, y, theta);
      { cf.parameter_names() } -> std::same_as<std::vector<std::string>>;
      { cf.describe(ctheta) } -> std::convertible_to<std::string>;
    };

/// A nonlinearity that also gives its exact gradient for plain numbers:
///     double gradient(x, θ, g_θ, g_x)   returns g(x; θ), writes ∂g/∂θ (p) and ∂g/∂x (m).
/// Optional: estimation uses it for the structured simulation Jacobian of Nlarx (one gradient
/// per sample instead of dual arithmetic through the whole network). Satisfied by SigmoidNet.
template <class F>
concept DifferentiableNonlinearity =
    Nonlinearity<F> && requires(const F& f, std::span<const double> x, std::span<const double> theta,
                                std::span<double> g_theta, std::span<double> g_x) {
      { f.gradient(x, theta, g_theta, g_x) } -> std::same_as<double>;
    };

/// A nonlinearity of one input (m = 1): the input and output blocks of a Hammerstein–Wiener
/// model. A `Dynamic`-input type qualifies too; its `input_dimension()` must then be 1 at run
/// time, which the model checks on construction.
/// Satisfied by UnitGain, PwLinear<B>, Saturation, DeadZone, Poly1d<D>, LinearMap<1>,
/// SigmoidNet<1, U, L>, WaveletNet<1, U, L> and the Dynamic-input twins.
template <class F>
concept ScalarNonlinearity = Nonlinearity<F> && (F::num_inputs == 1 || F::num_inputs == Dynamic);

}  // namespace nlid
