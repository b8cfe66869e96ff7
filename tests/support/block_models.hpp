#pragma once
// Parameter vectors of the block-oriented test models, shared by the simulation, stepping and
// allocation tests so that they all exercise one definition.

#include <Eigen/Core>

namespace nlid_test {

// The 4-breakpoint pwlinear → B/F [3 3 nk] → pwlinear Hammerstein–Wiener model. The block is
// stable: the poles of F = 1 − 0.9 q⁻¹ + 0.2 q⁻² − 0.02 q⁻³ are 0.63 and a pair of modulus 0.18.
inline Eigen::VectorXd pwlinear_hw_theta() {
  Eigen::VectorXd th(22);
  th << 0.0, -0.5, -0.5, -0.5, 0.0, 0.5, 1.0, 1.6,  // input breakpoints and values
      0.2, 0.1, 0.05, -0.9, 0.2, -0.02,             // linear block: b1..b3, f1..f3
      0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 2.0, 3.0;       // output breakpoints and values
  return th;
}

// The Wiener–Hammerstein chain [2 2 1] → cubic → [2 1 0]: G1 = (0.5 q⁻¹ + 0.3 q⁻²)/(1 − 1.2 q⁻¹ +
// 0.5 q⁻²), N(x) = 0.05 + x + 0.1 x² − 0.15 x³ (mostly odd, like a real amplifier),
// G2 = (1 + 0.4 q⁻¹)/(1 − 0.6 q⁻¹).
inline Eigen::VectorXd wiener_hammerstein_theta() {
  Eigen::VectorXd th(11);
  th << 0.5, 0.3, -1.2, 0.5, 0.05, 1.0, 0.1, -0.15, 1.0, 0.4, -0.6;
  return th;
}

}  // namespace nlid_test
