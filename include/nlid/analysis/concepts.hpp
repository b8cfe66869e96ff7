#pragma once
/// @file
/// What the analysis layer asks of a model.
///
/// Comparing a model with measurements (Ljung 1999, §16.6, "model validation by simulation")
/// needs nothing but the model's free-run output ŷ for the inputs of a recorded experiment,
/// started from a stated initial condition. Any model that provides that one member can be
/// compared, whatever its structure (linear, NLARX, Hammerstein–Wiener, grey box). Comparing
/// k-step-ahead predictions needs the model's predictor instead.

#include <concepts>

#include <Eigen/Core>

#include "nlid/core/initial_condition.hpp"
#include "nlid/data/experiment.hpp"

namespace nlid {

/// A model that simulates an experiment: `Eigen::MatrixXd simulate(const Experiment&,
/// InitialCondition) const` returning the N x ny free-run output.
/// Satisfied by `Arx`, `OutputError`, `StateSpace`, `Nlarx`, `HammersteinWiener` and `GreyBox`.
template <class M>
concept SimulationModel = requires(const M& m, const Experiment& e, InitialCondition ic) {
  { m.simulate(e, ic) } -> std::convertible_to<Eigen::MatrixXd>;
};

/// A model that predicts k samples ahead from measured data: `Eigen::MatrixXd predict(const
/// Experiment&, int k) const` returning ŷ(t | t − k), N x ny (`compare_prediction`).
/// Satisfied by `Arx`, `OutputError`, `StateSpace`, `Nlarx`, `HammersteinWiener` and `AnyModel`.
template <class M>
concept KStepPredictor = requires(const M& m, const Experiment& e, int k) {
  { m.predict(e, k) } -> std::convertible_to<Eigen::MatrixXd>;
};

}  // namespace nlid
