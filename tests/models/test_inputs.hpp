#pragma once
// Inputs shared by the model-estimation tests.
#include <random>

#include <Eigen/Core>

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

}  // namespace nlid_test
