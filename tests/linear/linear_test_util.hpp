// Shared helpers of the linear-model tests: reproducible inputs and data from known systems.
#pragma once

#include <algorithm>
#include <cmath>
#include <random>

#include <Eigen/Core>
#include <catch2/catch.hpp>

#include "nlid/data/experiment.hpp"
#include "nlid/linear/arx.hpp"
#include "nlid/linear/polynomial.hpp"
#include "nlid/linear/report.hpp"

namespace nlid_test {

// N x m white Gaussian input (unit variance), reproducible from `seed`.
inline Eigen::MatrixXd white_noise(Eigen::Index n, Eigen::Index m, unsigned seed, double sd = 1.0) {
  std::mt19937 gen(seed);
  std::normal_distribution<double> dist(0.0, sd);
  Eigen::MatrixXd x(n, m);
  for (Eigen::Index j = 0; j < m; ++j)
    for (Eigen::Index k = 0; k < n; ++k) x(k, j) = dist(gen);
  return x;
}

// Adds to each output column white noise as large as that column's own variation (its RMS
// about its mean), seeds `seed`, `seed + 1`, ...: every channel's fit is then near 29 %.
inline void add_noise_of_signal_size(Eigen::MatrixXd& y, unsigned seed) {
  for (Eigen::Index i = 0; i < y.cols(); ++i) {
    const double sd = std::sqrt((y.col(i).array() - y.col(i).mean()).square().mean());
    y.col(i) += white_noise(y.rows(), 1, seed + static_cast<unsigned>(i), sd).col(0);
  }
}

// A two-output report of data from add_noise_of_signal_size: each output's fit near 29 % (far
// from the ~99 % of one mean over both outputs stacked), the scalar the worse of the two.
inline void check_fits_of_noisy_outputs(const nlid::LinearEstimationReport& r) {
  REQUIRE(r.fit_per_output.size() == 2);
  for (double f : r.fit_per_output) {
    CHECK(f > 15.0);
    CHECK(f < 45.0);
  }
  CHECK(r.fit_percent == std::min(r.fit_per_output[0], r.fit_per_output[1]));
}

// N x m random binary (+-1) input held for `hold` samples: rich in low frequencies, like the
// step tests of the study.
inline Eigen::MatrixXd random_steps(Eigen::Index n, Eigen::Index m, unsigned seed, int hold = 5) {
  std::mt19937 gen(seed);
  std::bernoulli_distribution coin(0.5);
  Eigen::MatrixXd x(n, m);
  for (Eigen::Index j = 0; j < m; ++j) {
    double v = 1.0;
    for (Eigen::Index k = 0; k < n; ++k) {
      if (k % hold == 0) v = coin(gen) ? 1.0 : -1.0;
      x(k, j) = v;
    }
  }
  return x;
}

// Output of `truth` (zero initial conditions) plus ARX equation noise e/A, e ~ N(0, sd^2).
inline nlid::Experiment arx_data(const nlid::Arx& truth, const Eigen::MatrixXd& u, double sd,
                                 unsigned seed, const std::string& name = "sim") {
  const nlid::Experiment blank(u, Eigen::MatrixXd::Zero(u.rows(), 1), truth.ts(), name);
  Eigen::MatrixXd y = truth.simulate(blank, nlid::InitialCondition::zero);
  if (sd > 0) {
    const Eigen::VectorXd e = white_noise(u.rows(), 1, seed, sd);
    y.col(0) += nlid::filter(Eigen::VectorXd::Ones(1), truth.a_polynomial(), e);
  }
  return nlid::Experiment(u, y, truth.ts(), name);
}

}  // namespace nlid_test
