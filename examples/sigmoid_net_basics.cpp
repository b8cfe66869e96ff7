// A sigmoid network as a static map: fit it to a valve-like curve by its deterministic
// initialisation, read the equation, and get dg/dx and dg/dθ from one Dual evaluation.
#include <algorithm>
#include <cmath>
#include <iostream>
#include <span>
#include <vector>

#include "nlid/ad/dual.hpp"
#include "nlid/nonlinearities/evaluate.hpp"
#include "nlid/nonlinearities/sigmoid_network.hpp"

int main() {
  // Opening angle vs command: a spring-loaded valve resting at 15°, stopping at 90°.
  Eigen::MatrixXd X(200, 1);
  Eigen::VectorXd y(200);
  for (int i = 0; i < 200; ++i) {
    X(i, 0) = -0.2 + 1.4 * i / 199.0;
    y(i) = std::clamp(15.0 + 90.0 * X(i, 0), 15.0, 90.0);
  }
  nlid::SigmoidNet<1, 4> g;  // one input, four units, with linear term
  std::vector<double> theta(nlid::SigmoidNet<1, 4>::num_params);
  g.initialize(X, y, theta);  // no random start: same data, same theta
  std::cout << g.describe(theta, {"u"}) << "R^2 = " << nlid::r_squared(g, X, y, theta) << "\n";

  // Seed x as derivative 0 and every parameter after it: one pass gives the whole gradient.
  using D = nlid::Dual<double, 1 + nlid::SigmoidNet<1, 4>::num_params>;
  const std::vector<D> x{D::variable(0.5, 0)};
  std::vector<D> th;
  for (std::size_t i = 0; i < theta.size(); ++i) th.push_back(D::variable(theta[i], static_cast<int>(i) + 1));
  const D out = g(std::span<const D>(x), std::span<const D>(th));
  std::cout << "g(0.5) = " << out.a << ", dg/du = " << out.v(0) << ", dg/dd = " << out.v(1 + g.offset_d()) << "\n";
}
