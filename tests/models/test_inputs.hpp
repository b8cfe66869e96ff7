#pragma once
// Inputs shared by the model-estimation tests.
#include <cmath>
#include <random>
#include <string>

#include <Eigen/Core>

#include "nlid/data/experiment.hpp"

namespace nlid_test {

// Random steps (held for 5..40 samples) in [lo, hi]: rich in amplitude and frequency.
inline Eigen::MatrixXd random_steps(int n, double lo, double hi, unsigned seed) {
  std::mt19937 gen(seed);
  std::uniform_real_distribution<double> level(lo, hi);
  std::uniform_int_distribution<int> hold(5, 40);
  Eigen::MatrixXd u(n, 1);
  int t = 0;
  while (t < n) {
    const double v = level(gen);
    for (int k = hold(gen); k > 0 && t < n; --k) u(t++, 0) = v;
  }
  return u;
}

// n noise-free samples of the known output-error system B = 0.5 q^-1 + 0.25 q^-2,
// F = 1 - 1.5 q^-1 + 0.7 q^-2 from rest (samples before the record are zero), driven by a sine
// plus a square wave of half-period `hold` samples; ts = 1.
inline nlid::Experiment known_bf_record(int n, double w, int hold, double square, const std::string& name) {
  Eigen::MatrixXd u(n, 1);
  for (int k = 0; k < n; ++k) u(k, 0) = std::sin(w * k) + ((k / hold) % 2 == 0 ? square : -square);
  Eigen::VectorXd y = Eigen::VectorXd::Zero(n);
  const auto at = [](const auto& v, int k) { return k >= 0 ? v(k) : 0.0; };
  const Eigen::VectorXd u0 = u.col(0);
  for (int k = 1; k < n; ++k)
    y[k] = 1.5 * at(y, k - 1) - 0.7 * at(y, k - 2) + 0.5 * at(u0, k - 1) + 0.25 * at(u0, k - 2);
  return nlid::Experiment(u, y, 1.0, name);
}

}  // namespace nlid_test
