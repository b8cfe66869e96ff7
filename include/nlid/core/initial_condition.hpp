#pragma once
/// @file
/// How a free-run simulation starts. The study uses all three: zero (nlhw2), estimated from the
/// measured data (nlhw1, grey box), and equilibrium for a constant input (deployment).

namespace nlid {

/// Initial-condition policy of a simulation.
enum class InitialCondition {
  zero,         ///< all states / past samples zero (past outputs: the model's zero-input response)
  estimate,     ///< chosen to fit the first samples of the measured output (least squares)
  equilibrium,  ///< steady state for the first input sample held constant
  measured,     ///< past outputs taken from the measured data (regression models; "past data")
};

}  // namespace nlid
