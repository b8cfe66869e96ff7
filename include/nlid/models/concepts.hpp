#pragma once
/// @file
/// Concepts of the model layer: linear blocks, model structures and user-level models.
///
/// nlid separates a model into two views, following Ljung (1999, sec. 4.5: "model structure"
/// M(θ) versus "model" M(θ*)):
///
/// - the *structure* is a map θ ↦ predictor. Its scalar-generic members
///   `simulate<T>(u, θ, x0, ŷ)` and `predict<T>(u, y, θ, ŷ)` run on `double`, `float` and
///   `Dual`, so the same code produces a simulation and, with dual θ, its exact Jacobian
///   ∂ŷ(t)/∂θ propagated through the recursion (the sensitivity equations of Ljung 1999,
///   eq. 10.43, evaluated by forward AD instead of by hand);
/// - the *model* is a structure with one θ, a sample time and channel names, which simulates
///   and predicts `Experiment`s, prints itself, and is what analysis (compare, residuals) uses.
///
/// In nlid both views live in one class (`Nlarx`, `HammersteinWiener`): the class holds the
/// structure and the estimated θ, the templated members take θ explicitly.
///
/// Initial state x0 of a structure (`state_dimension()` values; an empty span means zero):
/// - Nlarx: the lag window before t = 0, [y(−1) … y(−Ly), u₁(−1) … u₁(−Lu), u₂(−1) …];
/// - HammersteinWiener: the state of the linear block (transposed direct form II).

#include <concepts>
#include <span>
#include <string>

#include <Eigen/Core>

#include "nlid/ad/dual.hpp"
#include "nlid/core/initial_condition.hpp"
#include "nlid/data/experiment.hpp"

namespace nlid {

/// A linear single-input single-output block x = B(q)/F(q) w(t−nk) with external parameters
/// and an explicit state, stepped one sample at a time on any scalar.
///
/// Required: `num_params`, `num_states` (static, or `Dynamic`); `num_parameters()`,
/// `num_states_runtime()`; `T step(std::span<T> s, const T& w, std::span<const T> θ)` returning
/// x(t) and advancing s to t + 1; `equilibrium_state(w0, θ, s)`; `parameter_names()`;
/// `describe(θ)`.
/// Satisfied by `TransferFunctionBlock<Nb, Nf, Nk>` (and its Dynamic twin).
template <class L>
concept LinearBlock =
    requires {
      { L::num_params } -> std::convertible_to<int>;
      { L::num_states } -> std::convertible_to<int>;
    } &&
    requires(const L& l, std::span<double> s, std::span<const double> theta, double w,
             std::span<Dual<double, 1>> sd, std::span<const Dual<double, 1>> thetad,
             Dual<double, 1> wd) {
      { l.num_parameters() } -> std::convertible_to<int>;
      { l.num_states_runtime() } -> std::convertible_to<int>;
      { l.step(s, w, theta) } -> std::same_as<double>;
      { l.step(sd, wd, thetad) } -> std::same_as<Dual<double, 1>>;
      l.equilibrium_state(w, theta, s);
      { l.parameter_names() } -> std::same_as<std::vector<std::string>>;
      { l.describe(theta) } -> std::convertible_to<std::string>;
    };

/// A model structure whose free-run simulation is generic over the scalar: the shape every
/// estimator of the models layer works on.
/// Satisfied by `Nlarx<R, F>` and `HammersteinWiener<In, L, Out>`.
template <class M>
concept ModelStructure =
    requires { { M::num_params } -> std::convertible_to<int>; } &&
    requires(const M& m, const Eigen::MatrixXd& u, std::span<const double> theta,
             std::span<double> y, std::span<const Dual<double, 1>> thetad,
             std::span<Dual<double, 1>> yd) {
      { m.num_parameters() } -> std::convertible_to<int>;
      { m.state_dimension() } -> std::convertible_to<int>;
      { m.simulate(u, theta, std::span<const double>{}, y) } -> std::same_as<bool>;
      { m.simulate(u, thetad, std::span<const Dual<double, 1>>{}, yd) } -> std::same_as<bool>;
    };

/// A user-level model: simulates and predicts experiments, reports its parameters and itself.
/// This is all `analysis/compare.hpp` and the diagnosis layer need.
/// Satisfied by `Nlarx`, `HammersteinWiener`, `Series` and the linear models. Grey boxes are
/// continuous-time and have no noise model (no `predict`, no `ts`): they satisfy
/// `SimulationModel` (analysis/concepts.hpp), which is what `compare` needs.
template <class M>
concept Model = requires(const M& m, const Experiment& e, InitialCondition ic, int k) {
  { m.simulate(e, ic) } -> std::convertible_to<Eigen::MatrixXd>;
  { m.predict(e, k) } -> std::convertible_to<Eigen::MatrixXd>;
  { m.ts() } -> std::convertible_to<double>;
  { m.describe() } -> std::convertible_to<std::string>;
};

}  // namespace nlid
