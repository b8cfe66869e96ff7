// step_response: known discrete step responses of linear models from rest, and nonlinear models
// pushed from an operating point to the equilibrium of the new input.
#include <catch2/catch.hpp>

#include <cmath>

#include "nlid/analysis/step_response.hpp"
#include "nlid/linear/arx.hpp"
#include "nlid/linear/output_error.hpp"
#include "nlid/linear/state_space.hpp"
#include "nlid/models/any_model.hpp"
#include "nlid/models/equilibrium.hpp"
#include "nlid/models/physics/catalogue.hpp"
#include "nlid/nonlinearities/sigmoid_network.hpp"
#include "nlid/regressors.hpp"

namespace {
Eigen::VectorXd vec1(double v) { return Eigen::VectorXd::Constant(1, v); }
}  // namespace

TEST_CASE("step_response of linear models from rest is the known discrete step", "[analysis][step]") {
  // y(t) = 0.8 y(t-1) + 0.5 u(t-1): y(0) = 0, y(t) = 0.5 (1 - 0.8^t) / 0.2.
  const nlid::Arx arx(vec1(-0.8), {vec1(0.5)}, {1}, 0.1);
  const Eigen::MatrixXd y = nlid::step_response(arx, 40);
  REQUIRE(y.rows() == 40);
  for (int t = 0; t < 40; ++t) CHECK(y(t, 0) == Approx(2.5 * (1.0 - std::pow(0.8, t))).margin(1e-12));
  CHECK(nlid::step_response(arx.to_state_space(), 40).isApprox(y, 1e-12));
  CHECK(nlid::step_response(arx, 40, 0, -2.0).isApprox(-2.0 * y, 1e-14));
  // Feed-through and a delay: x = (1 + 0.5 q^-1) / (1 - 0.5 q^-1) u(t - 2): two leading zeros,
  // then 1, 2, 2.5, 2.75, ... towards B(1)/F(1) = 3.
  const nlid::OutputError oe({Eigen::Vector2d(1.0, 0.5)}, {vec1(-0.5)}, {2}, 1.0);
  const Eigen::MatrixXd yo = nlid::step_response(oe, 30);
  CHECK(yo(0, 0) == 0.0);
  CHECK(yo(1, 0) == 0.0);
  CHECK(yo(2, 0) == Approx(1.0));
  CHECK(yo(3, 0) == Approx(2.0));
  CHECK(yo(4, 0) == Approx(2.5));
  CHECK(yo(29, 0) == Approx(3.0).epsilon(1e-6));
  // Two inputs, two outputs: the column of the input stepped, y(0) = D.
  Eigen::Matrix2d a, b, c, d;
  a << 0.5, 0.0, 0.0, 0.25;
  b << 1.0, 0.0, 0.0, 2.0;
  c << 1.0, 0.0, 0.0, 1.0;
  d << 0.0, 0.3, 0.0, 0.0;
  const nlid::StateSpace ss(a, b, c, d, 1.0);
  const Eigen::MatrixXd y2 = nlid::step_response(ss, 50, 1);
  CHECK(y2(0, 0) == Approx(0.3));
  CHECK(y2(0, 1) == 0.0);
  CHECK(y2(49, 1) == Approx(2.0 / 0.75).epsilon(1e-9));
  CHECK(y2(49, 0) == Approx(0.3));
  CHECK_THROWS_WITH(nlid::step_response(ss, 50, 2), Catch::Contains("input 2 out of range, the model has 2 input(s)"));
  CHECK_THROWS_WITH(nlid::step_response(ss, 0), Catch::Contains("number of samples must be >= 1, got 0"));
}

TEST_CASE("linear step and impulse responses leave out an estimated output offset", "[analysis][step]") {
  // A y = B u + c: the offset moves the output at rest, not the response (the toolbox's step).
  const nlid::Arx plain(vec1(-0.8), {vec1(0.5)}, {1}, 0.1);
  const nlid::Arx with_c(vec1(-0.8), {vec1(0.5)}, {1}, 0.1, 0.7);
  REQUIRE(with_c.has_offset());
  const Eigen::MatrixXd y = nlid::step_response(plain, 60);
  CHECK((nlid::step_response(with_c, 60) - y).cwiseAbs().maxCoeff() < 1e-12);
  CHECK((nlid::step_response(with_c.to_state_space(), 60) - y).cwiseAbs().maxCoeff() < 1e-12);
  CHECK((nlid::impulse_response(with_c, 60) - nlid::impulse_response(plain, 60)).cwiseAbs().maxCoeff() < 1e-12);
  const nlid::OutputError oe({Eigen::Vector2d(1.0, 0.5)}, {vec1(-0.5)}, {2}, 1.0, -3.0);
  REQUIRE(oe.has_offset());
  CHECK(nlid::step_response(oe, 30)(29, 0) == Approx(3.0).epsilon(1e-6));
  // Behind an AnyModel (a model file's linear model): the same responses.
  const nlid::AnyModel any(with_c);
  CHECK((nlid::step_response(any, 60) - y).cwiseAbs().maxCoeff() < 1e-12);
  CHECK((nlid::impulse_response(any, 60) - nlid::impulse_response(plain, 60)).cwiseAbs().maxCoeff() < 1e-12);
  // Unstable, with an offset: the step overflows to inf as without one, not to inf - inf = NaN.
  const nlid::Arx unstable(vec1(-1.5), {vec1(1.0)}, {1}, 1.0, 0.7);
  const Eigen::MatrixXd yu = nlid::step_response(unstable, 3000);
  CHECK(std::isinf(yu(2999, 0)));
  CHECK_FALSE(yu.array().isNaN().any());
}

TEST_CASE("impulse_response: Markov parameters, the toolbox's unit-area pulse, sum is the step",
          "[analysis][impulse]") {
  // y(t) = 0.8 y(t-1) + 0.5 u(t-1): g(0) = 0, g(k) = 0.5 * 0.8^(k-1).
  const nlid::Arx arx(vec1(-0.8), {vec1(0.5)}, {1}, 0.1);
  const Eigen::MatrixXd g = nlid::impulse_response(arx, 40, 0, nlid::ImpulseScaling::unit_pulse);
  REQUIRE(g.rows() == 40);
  REQUIRE(g.cols() == 1);
  CHECK(g(0, 0) == 0.0);
  for (int k = 1; k < 40; ++k) CHECK(g(k, 0) == Approx(0.5 * std::pow(0.8, k - 1)).margin(1e-14));
  // The toolbox's impulse: a pulse of height 1/Ts = 10 for one sample.
  const Eigen::MatrixXd h = nlid::impulse_response(arx, 40);
  CHECK((h - g / 0.1).cwiseAbs().maxCoeff() < 1e-12);
  // Superposition: the running sum of g is the step response.
  const Eigen::MatrixXd s = nlid::step_response(arx, 40);
  double sum = 0.0;
  for (int k = 0; k < 40; ++k) {
    sum += g(k, 0);
    CHECK(s(k, 0) == Approx(sum).margin(1e-12));
  }
  // Two inputs, two outputs: g(0) is D's column, g(k) = C A^(k-1) B's column.
  Eigen::Matrix2d a, b, c, d;
  a << 0.5, 0.1, 0.0, 0.25;
  b << 1.0, 0.0, 0.0, 2.0;
  c << 1.0, 0.0, 0.5, 1.0;
  d << 0.0, 0.3, 0.0, 0.0;
  const nlid::StateSpace ss(a, b, c, d, 0.5);
  const Eigen::MatrixXd g2 = nlid::impulse_response(ss, 6, 1, nlid::ImpulseScaling::unit_pulse);
  CHECK(g2.row(0).transpose().isApprox(d.col(1)));
  Eigen::Matrix2d ak = Eigen::Matrix2d::Identity();
  for (int k = 1; k < 6; ++k) {
    const Eigen::Vector2d want = c * ak * b.col(1);
    CHECK((g2.row(k).transpose() - want).cwiseAbs().maxCoeff() < 1e-14);
    ak = ak * a;
  }
  CHECK((nlid::impulse_response(ss, 6, 1) - g2 / 0.5).cwiseAbs().maxCoeff() < 1e-14);
  CHECK_THROWS_WITH(nlid::impulse_response(ss, 6, 2), Catch::Contains("impulse_response: input 2 out of range"));
  CHECK_THROWS_WITH(nlid::impulse_response(ss, 0), Catch::Contains("number of samples must be >= 1, got 0"));
}

TEST_CASE("step_response about an operating point settles at the new equilibrium", "[analysis][step]") {
  using Net = nlid::SigmoidNet<4, 3>;
  Net net;
  net.set_normalization(Eigen::VectorXd::Constant(4, 0.0), Eigen::VectorXd::Constant(4, 1.0));
  nlid::Nlarx<nlid::LaggedRegressors<2, 2, 1>, Net> m(nlid::LaggedRegressors<2, 2, 1>{}, net);
  Eigen::VectorXd th(m.num_parameters());
  for (int i = 0; i < th.size(); ++i) th(i) = 0.2 * std::sin(2.3 * i + 0.4);
  th.head(4) << 0.5, 0.2, 0.4, 0.1;  // a stable linear part
  m.set_parameters(th);
  const nlid::OperatingPoint op = nlid::equilibrium(m, vec1(0.3));
  const Eigen::MatrixXd rest = nlid::step_response(m, op, vec1(0.0), 50);
  CHECK((rest.array() - op.y(0)).abs().maxCoeff() < 1e-9);  // held input: it stays
  const Eigen::MatrixXd y = nlid::step_response(m, op, vec1(0.4), 300);
  CHECK(y(0, 0) == Approx(op.y(0)).margin(1e-12));  // nk = 1: the step shows from t = 1
  CHECK(y(299, 0) == Approx(nlid::equilibrium(m, vec1(0.7)).y(0)).epsilon(1e-8));
  // The batch simulation from the same state, same numbers.
  Eigen::VectorXd yb(300);
  const Eigen::MatrixXd u = Eigen::MatrixXd::Constant(300, 1, 0.7);
  REQUIRE(m.simulate<double>(u, std::span<const double>(th.data(), static_cast<std::size_t>(th.size())),
                             std::span<const double>(op.x.data(), static_cast<std::size_t>(op.x.size())),
                             std::span<double>(yb.data(), 300)));
  CHECK(y.col(0) == yb);
  CHECK_THROWS_WITH(nlid::step_response(m, op, Eigen::Vector2d(0.1, 0.1), 10),
                    Catch::Contains("one finite value per input (1), got 2"));
  // A nonlinear model behind an AnyModel has no impulse response (a pulse of 1/Ts says little).
  CHECK_THROWS_WITH(nlid::impulse_response(nlid::AnyModel(m), 10), Catch::Contains("impulse_response: the model is not linear"));

  // The throttle grey box between two held commands: from the rest of 0.3 to that of 0.5.
  nlid::GreyBox<nlid::physics::Throttle> g;
  Eigen::VectorXd p(7);
  p << 30.0, 400.0, 1e5, 400.0 * 140.0, 15.0, 90.0, 0.0;
  g.set_parameters(p);
  const nlid::OperatingPoint gop = nlid::equilibrium(g, vec1(0.3));
  const Eigen::MatrixXd yg = nlid::step_response(g, 0.01, gop, vec1(0.2), 400);
  CHECK(yg(0, 0) == Approx(gop.y(0)));
  CHECK(yg(399, 0) == Approx(nlid::equilibrium(g, vec1(0.5)).y(0)).epsilon(1e-6));
}
