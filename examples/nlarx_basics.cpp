// Nonlinear ARX in a few lines: a valve with hard stops, identified with the study's physical
// "hard spring" regressor and a linear map, then simulated on fresh data.
#include <algorithm>
#include <cmath>
#include <iostream>

#include "nlid/analysis/fit.hpp"
#include "nlid/models/estimate.hpp"
#include "nlid/nonlinearities/linear.hpp"
#include "nlid/regressors.hpp"

// A toy valve: first-order lag towards 15 + 100 u, pushed back hard beyond the stops 15 and 90.
nlid::Experiment valve(double phase) {
  Eigen::MatrixXd u(600, 1);
  Eigen::VectorXd y(600);
  double x = 15;
  for (int t = 0; t < 600; ++t) {
    u(t, 0) = 0.45 + 0.5 * std::sin(0.021 * t + phase) * std::cos(0.0037 * t);
    const double stop = std::max(x, 90.0) + std::min(x, 15.0) - 105.0;
    x = 0.9 * x + 0.1 * (15 + 100 * u(t, 0)) - 0.6 * stop;
    y(t) = x;
  }
  return nlid::Experiment(u, y, 0.01, "valve");
}

int main() {
  // Regressors y(t-1), y(t-2), u(t) and the custom max(y(t-1),90)+min(y(t-1),15)-105; generic
  // lambda so that it runs on double (simulation) and Dual (Jacobian) alike.
  const auto spring = nlid::custom_regressor<nlid::OutputLag<1>>(
      "max(y(t-1),90)+min(y(t-1),15)-105", [](auto y) { return nlid::max(y, 90.0) + nlid::min(y, 15.0) - 105.0; });
  nlid::Nlarx model(nlid::RegressorSet{nlid::LaggedRegressors<2, 1, 0>{}, spring}, nlid::LinearMap<4>{});

  nlid::EstimateOptions options;
  options.focus = nlid::Focus::simulation;  // minimise the free-run error, not the one-step error
  model = nlid::estimate(model, nlid::Dataset{valve(0.0)}, options);
  std::cout << model.describe();

  const nlid::Experiment fresh = valve(1.3);
  const Eigen::MatrixXd sim = model.simulate(fresh, nlid::InitialCondition::estimate);
  std::cout << "validation fit: " << nlid::fit_percent(fresh.y().col(0), sim.col(0)) << " %\n";
}
