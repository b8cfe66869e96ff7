#pragma once
// One parameter vector for the 4-breakpoint pwlinear → B/F [3 3 nk] → pwlinear Hammerstein–Wiener
// models of the tests (simulation, stepping, allocation proofs). The block is stable: the poles
// of F = 1 − 0.9 q⁻¹ + 0.2 q⁻² − 0.02 q⁻³ are 0.63 and a pair of modulus 0.18.

#include <Eigen/Core>

namespace nlid_test {

inline Eigen::VectorXd pwlinear_hw_theta() {
  Eigen::VectorXd th(22);
  th << 0.0, -0.5, -0.5, -0.5, 0.0, 0.5, 1.0, 1.6,  // input breakpoints and values
      0.2, 0.1, 0.05, -0.9, 0.2, -0.02,             // linear block: b1..b3, f1..f3
      0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 2.0, 3.0;       // output breakpoints and values
  return th;
}

}  // namespace nlid_test
