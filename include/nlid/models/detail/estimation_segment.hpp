#pragma once
/// @file
/// One experiment as the estimation residual problems see it, and the per-thread scratch they
/// share (used by models/estimate.hpp and models/detail/nlarx_sensitivity.hpp).

#include <vector>

#include <Eigen/Core>

namespace nlid::detail {

/// One experiment as the residual functors see it.
struct EstimationSegment {
  const Eigen::MatrixXd* u = nullptr;  ///< N×nu inputs (viewing the data set)
  Eigen::VectorXd y;                   ///< N outputs
  Eigen::Index start = 0;              ///< first simulated sample (n₀ for a measured past)
  Eigen::VectorXd x0;                  ///< initial state (or its base when estimated)
  int free_offset = -1;                ///< index in θ of its first estimated x0 entry (−1: none)
};

/// Scratch vector of scalar T, one per thread and type; capacity only grows.
template <class T>
std::vector<T>& initial_state_scratch() {
  thread_local std::vector<T> buffer;
  return buffer;
}

}  // namespace nlid::detail
