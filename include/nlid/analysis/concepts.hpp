#pragma once
/// @file
/// What the analysis layer asks of a model.
///
/// Comparing a model with measurements (Ljung 1999, §16.6, "model validation by simulation")
/// needs nothing but the model's free-run output ŷ for the inputs of a recorded experiment,
/// started from a stated initial condition. Any model that provides that one member can be
/// compared, whatever its structure (linear, NLARX, Hammerstein–Wiener, grey box).

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

}  // namespace nlid
