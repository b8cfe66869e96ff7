#pragma once
/// @file
/// What every linear model of nlid provides.
///
/// A linear time-invariant model maps inputs to outputs by a rational transfer operator,
///
///     y(t) = G(q) u(t) + H(q) e(t)          (Ljung 1999, eq. 4.4)
///
/// with G the input dynamics and H the disturbance model (H = 1/A for ARX, H = 1 for OE and for
/// the output-error state-space model). Two uses of such a model recur in the study:
/// - simulation: ŷ(t) = G(q) u(t) from the input alone (the mission's quality measure), and
/// - k-step prediction: ŷ(t | t − k), using measured outputs up to t − k (Ljung 1999, §3.2).
///   For H = 1 the predictor ignores measured outputs, so every k gives the simulation.
///
/// The concept below names that common interface so analysis code (compare, order search, the
/// Hammerstein–Wiener initialisation) can be written once for `Arx`, `OutputError` and
/// `StateSpace`.

#include <concepts>
#include <limits>
#include <string>

#include <Eigen/Core>

#include "nlid/core/initial_condition.hpp"
#include "nlid/data/experiment.hpp"

namespace nlid {

/// Prediction horizon meaning "infinitely many steps ahead", i.e. pure simulation:
/// `model.predict(e, infinite_horizon)` is the free-run output started from measured past data.
inline constexpr int infinite_horizon = std::numeric_limits<int>::max();

/// A discrete-time linear model that simulates, predicts and describes itself.
/// Satisfied by `Arx`, `OutputError` and `StateSpace`.
template <class M>
concept LinearModel = requires(const M& m, const Experiment& e, InitialCondition ic, int k,
                               const Eigen::VectorXd& w) {
  { m.simulate(e, ic) } -> std::convertible_to<Eigen::MatrixXd>;
  { m.predict(e, k) } -> std::convertible_to<Eigen::MatrixXd>;
  { m.describe() } -> std::convertible_to<std::string>;
  { m.ts() } -> std::convertible_to<double>;
  { m.num_inputs() } -> std::convertible_to<int>;
  { m.num_outputs() } -> std::convertible_to<int>;
  { m.poles() } -> std::convertible_to<Eigen::VectorXcd>;
  { m.frequency_response(w) } -> std::convertible_to<Eigen::VectorXcd>;
};

}  // namespace nlid
