// StateSpace: simulation, initial states, transfer functions, frequency response, errors.
#include <catch2/catch.hpp>

#include <cmath>

#include "linear_test_util.hpp"
#include "nlid/linear/state_space.hpp"

using nlid::Experiment;
using nlid::InitialCondition;
using nlid::StateSpace;

namespace {
// Two states (poles 0.8 +/- 0.2i), two inputs, one output, with feed-through from input 2.
StateSpace mimo() {
  Eigen::MatrixXd a(2, 2), b(2, 2), c(1, 2), d(1, 2);
  a << 0.8, 0.2, -0.2, 0.8;
  b << 1.0, 0.0, 0.5, 1.0;
  c << 1.0, -0.5;
  d << 0.0, 0.3;
  return StateSpace(a, b, c, d, 0.01);
}
}  // namespace

TEST_CASE("StateSpace simulates the state equations", "[linear][state_space]") {
  const StateSpace m = mimo();
  const Eigen::MatrixXd u = nlid_test::white_noise(60, 2, 1);
  Eigen::VectorXd x0(2);
  x0 << 1.0, -2.0;
  const Eigen::MatrixXd y = m.simulate(u, x0);
  Eigen::VectorXd x = x0;
  for (Eigen::Index t = 0; t < 60; ++t) {
    const double yt = (m.c() * x + m.d() * u.row(t).transpose())(0);
    CHECK(y(t, 0) == Approx(yt).epsilon(1e-13));
    x = m.a() * x + m.b() * u.row(t).transpose();
  }
  CHECK(m.order() == 2);
  CHECK(m.num_inputs() == 2);
  CHECK(m.num_outputs() == 1);
  CHECK(m.is_stable());
}

TEST_CASE("StateSpace initial-state policies", "[linear][state_space]") {
  StateSpace m = mimo();
  m.set_offset(Eigen::VectorXd::Constant(1, 4.0));
  const Eigen::MatrixXd u = nlid_test::white_noise(200, 2, 2);
  Eigen::VectorXd x0(2);
  x0 << 3.0, -1.0;
  const Experiment e(u, m.simulate(u, x0), 0.01);
  CHECK((m.initial_state(e, InitialCondition::estimate) - x0).norm() < 1e-10);
  CHECK((m.simulate(e, InitialCondition::estimate) - e.y()).cwiseAbs().maxCoeff() < 1e-10);
  CHECK((m.predict(e, 3) - e.y()).cwiseAbs().maxCoeff() < 1e-10);
  CHECK((m.simulate(e, InitialCondition::zero) - e.y()).cwiseAbs().maxCoeff() > 0.5);
  // Equilibrium: constant input, output stays at the static gain plus offset.
  const Eigen::MatrixXd uc = Eigen::MatrixXd::Constant(30, 2, 1.5);
  const Experiment c(uc, Eigen::MatrixXd::Zero(30, 1), 0.01);
  const Eigen::MatrixXd yeq = m.simulate(c, InitialCondition::equilibrium);
  const double yss = (m.dc_gain() * Eigen::Vector2d(1.5, 1.5))(0) + 4.0;
  CHECK((yeq.array() - yss).abs().maxCoeff() < 1e-10);
  CHECK_THROWS_WITH(m.simulate(e, InitialCondition::measured), Catch::Contains("use InitialCondition::estimate"));
}

TEST_CASE("StateSpace transfer function matches the frequency response", "[linear][state_space]") {
  const StateSpace m = mimo();
  const Eigen::VectorXd w = Eigen::VectorXd::LinSpaced(11, 0.1, 300.0);
  for (int i = 0; i < 2; ++i) {
    const nlid::TransferFunction tf = m.to_transfer_function(0, i);
    CHECK(tf.denominator.size() == 3);
    CHECK(tf.denominator(0) == Approx(1.0));
    CHECK((tf.frequency_response(w) - m.frequency_response(w, 0, i)).cwiseAbs().maxCoeff() < 1e-12);
  }
  // Input 1 by hand: C (zI - A)^-1 B1 with det = z^2 - 1.6 z + 0.68.
  const nlid::TransferFunction tf = m.to_transfer_function(0, 0);
  Eigen::VectorXd den(3);
  den << 1.0, -1.6, 0.68;
  CHECK((tf.denominator - den).norm() < 1e-12);
  // Numerator: z-form C adj(zI - A) B1 = 0.75 z - 0.4 -> q^-1 form [0, 0.75, -0.4].
  Eigen::VectorXd num(3);
  num << 0.0, 0.75, -0.4;
  CHECK((tf.numerator - num).norm() < 1e-12);
  CHECK(m.dc_gain()(0, 0) == Approx(0.35 / 0.08));
  CHECK(m.dc_gain()(0, 1) == Approx(m.to_transfer_function(0, 1).numerator.sum() / den.sum()));
}

TEST_CASE("StateSpace rejects inconsistent matrices and data", "[linear][state_space]") {
  const Eigen::MatrixXd a = Eigen::MatrixXd::Identity(2, 2) * 0.5;
  CHECK_THROWS_WITH(StateSpace(a, Eigen::MatrixXd::Ones(3, 1), Eigen::MatrixXd::Ones(1, 2), Eigen::MatrixXd::Zero(1, 1), 1.0),
                    Catch::Contains("B must have 2 rows"));
  CHECK_THROWS_WITH(StateSpace(a, Eigen::MatrixXd::Ones(2, 1), Eigen::MatrixXd::Ones(1, 3), Eigen::MatrixXd::Zero(1, 1), 1.0),
                    Catch::Contains("C must have 2 columns"));
  CHECK_THROWS_WITH(StateSpace(a, Eigen::MatrixXd::Ones(2, 1), Eigen::MatrixXd::Ones(1, 2), Eigen::MatrixXd::Zero(2, 1), 1.0),
                    Catch::Contains("D must be 1 x 1"));
  CHECK_THROWS_WITH(StateSpace(a, Eigen::MatrixXd::Ones(2, 1), Eigen::MatrixXd::Ones(1, 2), Eigen::MatrixXd::Zero(1, 1), 0.0),
                    Catch::Contains("sample time"));
  const StateSpace m = mimo();
  const Experiment one_input(Eigen::MatrixXd::Ones(10, 1), Eigen::MatrixXd::Ones(10, 1), 0.01, "narrow");
  CHECK_THROWS_WITH(m.simulate(one_input), Catch::Contains("model has 2 input(s) but experiment 'narrow' has 1"));
  CHECK_THROWS_WITH(m.frequency_response(Eigen::VectorXd::Ones(1), 0, 5), Catch::Contains("input index 5"));
  Eigen::MatrixXd integ(1, 1);
  integ << 1.0;
  const StateSpace i(integ, Eigen::MatrixXd::Ones(1, 1), Eigen::MatrixXd::Ones(1, 1), Eigen::MatrixXd::Zero(1, 1), 1.0);
  CHECK_THROWS_WITH(i.dc_gain(), Catch::Contains("integrator"));
  const Experiment c(Eigen::MatrixXd::Ones(5, 1), Eigen::MatrixXd::Zero(5, 1), 1.0);
  CHECK_THROWS_WITH(i.simulate(c, InitialCondition::equilibrium), Catch::Contains("no equilibrium"));
}

TEST_CASE("StateSpace describe lists matrices and poles", "[linear][state_space]") {
  const std::string d = mimo().describe();
  CHECK(d.find("2 state(s), 2 input(s), 1 output(s)") != std::string::npos);
  CHECK(d.find("Poles: 0.8 +/- 0.2i") != std::string::npos);
  CHECK(d.find("x(t+Ts) = A x(t) + B u(t)") != std::string::npos);
}
