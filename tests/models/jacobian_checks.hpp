#pragma once
// Checks shared by the structured-Jacobian tests (sensitivity_test.cpp, hw_sensitivity_test.cpp).
#include <catch2/catch.hpp>

#include <cmath>

#include <Eigen/Core>

namespace nlid_test {

// max |a − b| relative to 1 + max |a|.
template <class A, class B>
double rel_diff(const A& a, const B& b) {
  return (a - b).cwiseAbs().maxCoeff() / (1.0 + a.cwiseAbs().maxCoeff());
}

// Every column of `J` (the problem's Jacobian at θ) against central differences of its residuals
// with step 10⁻⁶(1 + |θ_c|): rel_diff below `tol`.
template <class Problem, class Theta, class Jacobian>
void check_central_differences(const Problem& problem, const Theta& theta, const Jacobian& J, double tol) {
  const Eigen::Index n = problem.num_residuals();
  Eigen::VectorXd rp(n), rm(n);
  for (int c = 0; c < theta.size(); ++c) {
    const double h = 1e-6 * (1.0 + std::abs(theta(c)));
    Theta tp = theta, tm = theta;
    tp(c) += h;
    tm(c) -= h;
    REQUIRE(problem.evaluate(tp, rp, nullptr));
    REQUIRE(problem.evaluate(tm, rm, nullptr));
    const Eigen::VectorXd fd = (rp - rm) / (2.0 * h);
    CAPTURE(c);
    CHECK(rel_diff(fd, J.col(c)) < tol);
  }
}

}  // namespace nlid_test
