#pragma once
/// @file
/// cos and sin of 2πm/N, m = 0 … N−1: the one table behind every DFT-grid computation of nlid
/// (multisine synthesis, distortion analysis). Line k at sample t uses entry (k·t) mod N, an exact
/// integer, so long periods have no phase drift (internal).

#include <Eigen/Core>
#include <cmath>
#include <numbers>

namespace nlid::detail {

/// cos(2πm/N) and sin(2πm/N) for m = 0 … N−1.
struct DftTable {
  Eigen::VectorXd cos, sin;

  explicit DftTable(Eigen::Index n) : cos(n), sin(n) {
    for (Eigen::Index m = 0; m < n; ++m) {
      const double a = 2.0 * std::numbers::pi * static_cast<double>(m) / static_cast<double>(n);
      cos[m] = std::cos(a);
      sin[m] = std::sin(a);
    }
  }
};

}  // namespace nlid::detail
