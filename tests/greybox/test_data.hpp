#pragma once
// Shared helpers of the grey-box tests: reproducible step-sequence inputs and simulated records.
#include <random>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "nlid/data/dataset.hpp"
#include "nlid/models/greybox.hpp"

namespace nlid_test {

// Piecewise-constant input: `levels` held for `hold` samples each, cycled to length n.
inline Eigen::MatrixXd steps(const std::vector<double>& levels, int hold, int n) {
  Eigen::MatrixXd u(n, 1);
  for (int k = 0; k < n; ++k) u(k, 0) = levels[static_cast<std::size_t>((k / hold) % static_cast<int>(levels.size()))];
  return u;
}

// Simulates `model` from x0 on u and adds Gaussian noise of standard deviation `noise`.
template <class Model>
nlid::Experiment simulated(const Model& model, const Eigen::MatrixXd& u, double ts,
                           const Eigen::VectorXd& x0, double noise, unsigned seed,
                           std::string name) {
  Eigen::MatrixXd y = model.simulate(u, ts, x0);
  std::mt19937 rng(seed);
  std::normal_distribution<double> nd(0.0, 1.0);
  for (Eigen::Index k = 0; k < y.rows(); ++k) y(k, 0) += noise * nd(rng);
  return nlid::Experiment(u, y, ts, std::move(name));
}

}  // namespace nlid_test
