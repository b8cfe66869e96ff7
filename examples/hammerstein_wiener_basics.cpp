// A Wiener model (linear dynamics, then a saturation) recovered from noisy data: the estimator
// starts from its own data-driven initialisation, the result reads as B/F polynomials and limits,
// and each parameter comes with its standard deviation.
#include <iostream>
#include <random>

#include "nlid/models/estimate.hpp"
#include "nlid/models/uncertainty.hpp"
#include "nlid/nonlinearities/saturation.hpp"
#include "nlid/nonlinearities/unit_gain.hpp"

int main() {
  using Wiener = nlid::HammersteinWiener<nlid::UnitGain, nlid::TransferFunctionBlock<2, 2, 1>, nlid::Saturation>;
  Wiener truth;
  Eigen::VectorXd th(6);
  th << 0.1, 0.06, -1.5, 0.7, -0.8, 1.0;  // b1 b2 | f1 f2 | lower upper
  truth.set_parameters(th);

  // Random steps, long enough for the linear block to settle and for both limits to be hit.
  std::mt19937 gen(7);
  std::uniform_real_distribution<double> level(-2, 2);
  Eigen::MatrixXd u(1000, 1);
  for (int t = 0; t < 1000; ++t) u(t, 0) = t % 25 == 0 ? level(gen) : u(t - 1, 0);
  const nlid::Experiment e0(u, Eigen::VectorXd::Zero(1000), 0.01, "steps");
  Eigen::VectorXd y = truth.simulate(e0);
  std::normal_distribution<double> noise(0.0, 0.01);
  for (Eigen::Index t = 0; t < y.size(); ++t) y[t] += noise(gen);
  const nlid::Dataset data{nlid::Experiment(u, y, 0.01, "steps")};

  const Wiener est = nlid::estimate(Wiener{}, data);  // zero initial state
  std::cout << est.describe();
  // How well the data determine each parameter: errors beyond 3 sigma would be suspect.
  const nlid::ParameterUncertainty unc = nlid::parameter_uncertainty(est, data);
  std::cout << unc.report();
  for (int i = 0; i < 6; ++i) {
    std::cout << "  " << unc.names[static_cast<std::size_t>(i)] << ": error " << est.parameters()[i] - th[i] << " = "
              << (est.parameters()[i] - th[i]) / unc.stddev[i] << " sigma\n";
  }
}
