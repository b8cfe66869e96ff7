#pragma once
// Shared helpers of the grey-box tests: reproducible step-sequence inputs and simulated records.
#include <random>
#include <string>
#include <vector>

#include <catch2/catch.hpp>
#include <Eigen/Core>

#include "nlid/data/dataset.hpp"
#include "nlid/models/greybox.hpp"
#include "nlid/models/greybox_problem.hpp"

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

// Residuals and Jacobian with the experiments' passes paired in lockstep and one after the
// other; they must agree bit for bit (and both fail together for a diverging record).
template <class P>
void check_lockstep_jacobians(nlid::GreyBoxProblem<P> pb, const Eigen::VectorXd& theta, bool ok = true) {
  Eigen::VectorXd r1(pb.num_residuals()), r2(pb.num_residuals());
  Eigen::MatrixXd J1(pb.num_residuals(), pb.num_parameters()), J2(pb.num_residuals(), pb.num_parameters());
  r1.setConstant(7.0);
  r2.setConstant(-7.0);
  pb.set_lockstep_jacobians(true);
  REQUIRE(pb.lockstep_jacobians());
  REQUIRE(pb.evaluate(theta, r1, &J1) == ok);
  pb.set_lockstep_jacobians(false);
  REQUIRE(pb.evaluate(theta, r2, &J2) == ok);
  if (!ok) return;
  CHECK((r1 - r2).cwiseAbs().maxCoeff() == 0.0);
  CHECK((J1 - J2).cwiseAbs().maxCoeff() == 0.0);
  // Every free column is reached by some experiment (a seeding slip would leave one zero).
  const std::vector<bool> fixed = pb.fixed_mask();
  for (int c = 0; c < pb.num_parameters(); ++c) {
    INFO("column " << c);
    CHECK((J1.col(c).cwiseAbs().maxCoeff() > 0.0) == !fixed[static_cast<std::size_t>(c)]);
  }
}

}  // namespace nlid_test
