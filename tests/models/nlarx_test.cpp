// Nlarx: simulation/prediction semantics, scalar genericity (double/float/Dual), Jacobian through
// the recursion vs finite differences, fixed vs Dynamic twin, initial conditions, bad input.
#include <catch2/catch.hpp>

#include <cmath>
#include <limits>
#include <span>
#include <string>

#include "nlid/analysis/compare.hpp"
#include "nlid/models/nlarx.hpp"
#include "nlid/nonlinearities/linear.hpp"
#include "nlid/regressors.hpp"
#include "nlid/regressors/expression.hpp"

using nlid::Dynamic;

namespace {
// y(t) = a1 y(t-1) + a2 y(t-2) + b u(t) + c·tanh(y(t-1))·u(t) + d: nonlinear in the past output,
// so the Jacobian of the free run is a genuine recursion.
auto coupling() {
  return nlid::custom_regressor<nlid::OutputLag<1>, nlid::InputLag<0>>(
      "tanh(y1(t-1))*u1(t)", [](auto y1, auto u) { using nlid::tanh; using std::tanh; return tanh(y1) * u; });
}
using Regs = nlid::RegressorSet<nlid::LaggedRegressors<2, 1, 0>, decltype(coupling())>;
using Model = nlid::Nlarx<Regs, nlid::LinearMap<4>>;

Model make_model() {
  Model m(Regs(nlid::LaggedRegressors<2, 1, 0>{}, coupling()), nlid::LinearMap<4>{}, 0.01);
  Eigen::VectorXd theta(5);
  theta << 1.2, -0.4, 0.3, 0.15, 0.05;
  m.set_parameters(theta);
  return m;
}

Eigen::MatrixXd inputs(int n) {
  Eigen::MatrixXd u(n, 1);
  for (int t = 0; t < n; ++t) u(t, 0) = std::sin(0.05 * t) + (t / 40 % 2 ? 0.8 : -0.3);
  return u;
}

// Plain re-implementation of the model equation, used as the reference.
Eigen::VectorXd reference(const Eigen::MatrixXd& u, const Eigen::VectorXd& th, double ym1, double ym2) {
  Eigen::VectorXd y(u.rows());
  double y1 = ym1, y2 = ym2;
  for (int t = 0; t < u.rows(); ++t) {
    const double yt = th(0) * y1 + th(1) * y2 + th(2) * u(t, 0) + th(3) * std::tanh(y1) * u(t, 0) + th(4);
    y(t) = yt;
    y2 = y1;
    y1 = yt;
  }
  return y;
}

template <class T>
std::span<const T> cspan(const std::vector<T>& v) { return {v.data(), v.size()}; }
}  // namespace

TEST_CASE("Nlarx static sizes and structure", "[models][nlarx]") {
  static_assert(Model::num_params == 5 && Model::num_regressors == 4);
  static_assert(nlid::ModelStructure<Model>);
  static_assert(nlid::Model<Model>);
  const Model m = make_model();
  CHECK(m.state_dimension() == 2);  // y(t-1), y(t-2); u(t) needs no past
  CHECK(m.history_length() == 2);
  CHECK(m.regressor_names() ==
        std::vector<std::string>{"y1(t-1)", "y1(t-2)", "u1(t)", "tanh(y1(t-1))*u1(t)"});
}

TEST_CASE("free-run simulation equals the model equation from zero and from a given past", "[models][nlarx]") {
  const Model m = make_model();
  const Eigen::MatrixXd u = inputs(300);
  const Eigen::VectorXd th = m.parameters();
  Eigen::VectorXd y(300);
  REQUIRE(m.simulate<double>(u, nlid::detail::as_const_span(th), {}, nlid::detail::as_span(y)));
  CHECK((y - reference(u, th, 0, 0)).cwiseAbs().maxCoeff() < 1e-12);
  const Eigen::Vector2d x0(0.7, -0.2);  // y(-1), y(-2)
  REQUIRE(m.simulate<double>(u, nlid::detail::as_const_span(th), nlid::detail::as_const_span(x0), nlid::detail::as_span(y)));
  CHECK((y - reference(u, th, 0.7, -0.2)).cwiseAbs().maxCoeff() < 1e-12);
}

TEST_CASE("simulation on double, float and Dual gives the same values", "[models][nlarx]") {
  const Model m = make_model();
  const Eigen::MatrixXd u = inputs(200);
  const Eigen::VectorXd th = m.parameters();
  Eigen::VectorXd y(200);
  REQUIRE(m.simulate<double>(u, nlid::detail::as_const_span(th), {}, nlid::detail::as_span(y)));

  using D = nlid::Dual<double, 5>;
  std::vector<D> thd(5), yd(200);
  for (int i = 0; i < 5; ++i) thd[i] = D::variable(th(i), i);
  REQUIRE(m.simulate<D>(u, cspan(thd), {}, yd));
  for (int t = 0; t < 200; ++t) CHECK(yd[t].a == y(t));  // bit-identical values

  std::vector<float> thf(th.data(), th.data() + 5), yf(200);
  REQUIRE(m.simulate<float>(u, cspan(thf), {}, yf));
  for (int t = 0; t < 200; ++t) CHECK(yf[t] == Approx(y(t)).margin(1e-3));
}

TEST_CASE("Dual Jacobian of the simulation matches central finite differences", "[models][nlarx]") {
  const Model m = make_model();
  const Eigen::MatrixXd u = inputs(250);
  const Eigen::VectorXd th = m.parameters();
  using D = nlid::Dual<double, 7>;  // 5 parameters + 2 initial outputs
  std::vector<D> thd(5), x0d(2), yd(250);
  for (int i = 0; i < 5; ++i) thd[i] = D::variable(th(i), i);
  x0d[0] = D::variable(0.4, 5);
  x0d[1] = D::variable(0.1, 6);
  REQUIRE(m.simulate<D>(u, cspan(thd), cspan(x0d), yd));
  const double h = 1e-6;
  for (int i = 0; i < 7; ++i) {
    Eigen::VectorXd tp = th, tm = th;
    Eigen::Vector2d xp(0.4, 0.1), xm(0.4, 0.1);
    if (i < 5) {
      tp(i) += h;
      tm(i) -= h;
    } else {
      xp(i - 5) += h;
      xm(i - 5) -= h;
    }
    const Eigen::VectorXd fd = (reference(u, tp, xp(0), xp(1)) - reference(u, tm, xm(0), xm(1))) / (2 * h);
    double worst = 0;
    for (int t = 0; t < 250; ++t) worst = std::max(worst, std::abs(yd[t].v[i] - fd(t)) / (1.0 + std::abs(fd(t))));
    CHECK(worst < 1e-6);
  }
}

TEST_CASE("fixed and Dynamic variants of the same model simulate identically", "[models][nlarx]") {
  const Model fixed = make_model();
  using DynRegs = nlid::RegressorSet<nlid::LaggedRegressors<Dynamic, Dynamic, Dynamic>, decltype(coupling())>;
  nlid::Nlarx<DynRegs, nlid::LinearMap<Dynamic>> dyn(
      DynRegs(nlid::LaggedRegressors<Dynamic, Dynamic, Dynamic>(2, 1, 0), coupling()), nlid::LinearMap<Dynamic>(4), 0.01);
  static_assert(decltype(dyn)::num_params == Dynamic);
  dyn.set_parameters(fixed.parameters());
  const Eigen::MatrixXd u = inputs(400);
  const nlid::Experiment e(u, reference(u, fixed.parameters(), 0, 0), 0.01, "ref");
  for (auto ic : {nlid::InitialCondition::zero, nlid::InitialCondition::measured, nlid::InitialCondition::equilibrium}) {
    CHECK((fixed.simulate(e, ic) - dyn.simulate(e, ic)).cwiseAbs().maxCoeff() < 1e-12);
  }
  CHECK((fixed.predict(e, 1) - dyn.predict(e, 1)).cwiseAbs().maxCoeff() < 1e-12);
}

TEST_CASE("one-step prediction is F on measured regressors, long horizons give the simulation", "[models][nlarx]") {
  const Model m = make_model();
  const Eigen::MatrixXd u = inputs(300);
  Eigen::VectorXd y = reference(u, m.parameters(), 0, 0);
  for (int t = 0; t < 300; ++t) y(t) += 0.05 * std::sin(1.3 * t);  // the data are not the model
  const nlid::Experiment e(u, y, 0.01, "noisy");
  const Eigen::MatrixXd p1 = m.predict(e, 1);
  const Eigen::MatrixXd x = m.regressor_values(e);
  for (int t = 2; t < 300; ++t) {
    const Eigen::VectorXd th = m.parameters();
    CHECK(p1(t, 0) == Approx(x.row(t - 2).dot(th.head(4)) + th(4)).epsilon(1e-12));
  }
  CHECK(p1(0, 0) == y(0));
  const Eigen::MatrixXd sim = m.simulate(e, nlid::InitialCondition::measured);
  const Eigen::MatrixXd pinf = m.predict(e, 1000);
  CHECK((sim - pinf).cwiseAbs().maxCoeff() < 1e-12);
  // k = 3: ŷ(t|t-3) = model run 3 steps from the measured past at t-3.
  const Eigen::MatrixXd p3 = m.predict(e, 3);
  const int t = 150;
  Eigen::VectorXd buf(3);
  const Eigen::VectorXd x0 = m.measured_state(u, y, t - 2);
  REQUIRE(m.simulate<double>(u.middleRows(t - 2, 3), nlid::detail::as_const_span(m.parameters()),
                             nlid::detail::as_const_span(x0), nlid::detail::as_span(buf)));
  CHECK(p3(t, 0) == buf(2));
}

TEST_CASE("measured_state holds the past outputs and inputs in lag order, and continues the prediction", "[models][nlarx]") {
  // Orders [2 2 1]: regressors y(t-1), y(t-2), u(t-1), u(t-2), so the state holds two past
  // outputs and two past inputs (the test model above has no input state).
  using Lagged = nlid::Nlarx<nlid::LaggedRegressors<2, 2, 1>, nlid::LinearMap<4>>;
  Lagged m(nlid::LaggedRegressors<2, 2, 1>{}, nlid::LinearMap<4>{}, 0.01);
  Eigen::VectorXd theta(5);
  theta << 0.9, -0.3, 0.5, 0.2, 0.1;
  m.set_parameters(theta);
  REQUIRE(m.state_dimension() == 4);
  Eigen::MatrixXd u(12, 1);
  Eigen::VectorXd y(12);
  for (int k = 0; k < 12; ++k) {
    u(k, 0) = 10.0 * k;
    y(k) = k;
  }
  const Eigen::VectorXd x5 = m.measured_state(u, y, 5);
  CHECK(x5 == Eigen::Vector4d(4.0, 3.0, 40.0, 30.0));  // y(4), y(3), u(4), u(3)
  // One step from the measured state at t is the one-step prediction at t.
  const nlid::Experiment e(u, y, 0.01, "ramps");
  const Eigen::MatrixXd p1 = m.predict(e, 1);
  for (int t = 2; t < 12; ++t) {
    const Eigen::VectorXd x0 = m.measured_state(u, y, t);
    double yt = 0;
    REQUIRE(m.simulate<double>(u.middleRows(t, 1), nlid::detail::as_const_span(m.parameters()),
                               nlid::detail::as_const_span(x0), std::span<double>(&yt, 1)));
    CAPTURE(t);
    CHECK(yt == Approx(0.9 * y(t - 1) - 0.3 * y(t - 2) + 0.5 * u(t - 1, 0) + 0.2 * u(t - 2, 0) + 0.1).epsilon(1e-14));
    CHECK(yt == Approx(p1(t, 0)).epsilon(1e-14));
  }
}

TEST_CASE("equilibrium initial condition starts the model at rest", "[models][nlarx]") {
  const Model m = make_model();
  Eigen::MatrixXd u = Eigen::MatrixXd::Constant(100, 1, 0.5);
  const nlid::Experiment e(u, Eigen::VectorXd::Constant(100, 1.0), 0.01);
  const Eigen::MatrixXd y = m.simulate(e, nlid::InitialCondition::equilibrium);
  CHECK((y.array() - y(0, 0)).abs().maxCoeff() < 1e-9);
  const Eigen::VectorXd th = m.parameters();
  const double ys = y(0, 0);
  CHECK(ys == Approx(th(0) * ys + th(1) * ys + th(2) * 0.5 + th(3) * std::tanh(ys) * 0.5 + th(4)).epsilon(1e-10));
}

TEST_CASE("an equilibrium start that does not exist names the whole held input", "[models][nlarx]") {
  // y(t) = y(t-1) + 0.5 u1(t) + 0.5 u2(t): an integrator, no steady state unless u1 + u2 = 0.
  using TwoInputs = nlid::Nlarx<nlid::RegressorSet<nlid::OutputLags<1>, nlid::InputLags<1, 0, 0>, nlid::InputLags<1, 0, 1>>,
                                nlid::LinearMap<3>>;
  TwoInputs m;
  m.set_parameters(Eigen::Vector4d(1.0, 0.5, 0.5, 0.0));
  Eigen::MatrixXd u(20, 2);
  u.col(0).setZero();
  u.col(1).setConstant(0.7);
  const nlid::Experiment e(u, Eigen::VectorXd::Zero(20), 0.01);
  // The message gave u = 0 (the first channel only).
  CHECK_THROWS_WITH(m.simulate(e, nlid::InitialCondition::equilibrium),
                    Catch::Contains("no steady state found for the held input u = (0, 0.7)"));
}

TEST_CASE("channel names under which a custom regressor's text would read other channels are refused", "[models][nlarx]") {
  // "u2(t-1)^2" was written for input 2. Inputs named {u2, u1} (a CSV with columns u1, u2 read in
  // the other order) would make its text name input 1: describe() and a saved file (loaded by
  // name) described another model than the one estimated.
  nlid::RegressorList list;
  list.add_output_lags(1).add_input_lags(1, 0, 0).add_input_lags(1, 0, 1).add_custom("u2(t-1)^2");
  nlid::Nlarx<nlid::RegressorList, nlid::LinearMap<nlid::Dynamic>> m(list, nlid::LinearMap<nlid::Dynamic>(4));
  CHECK_THROWS_WITH(m.set_channel_names({"u2", "u1"}, "y1"),
                    Catch::Contains("custom regressor 'u2(t-1)^2' reads other channels than its text names under the input "
                                    "names {u2, u1}"));
  CHECK((m.input_names() != std::vector<std::string>{"u2", "u1"}));  // unchanged
  m.set_channel_names({"u1", "u2"}, "y1");
  m.set_channel_names({"flow", "temp"}, "level");  // no channel is called u2: u2 is input 2
  // A record carrying the model's channel names in another order would run it on swapped inputs.
  Eigen::MatrixXd u(20, 2);
  u.setOnes();
  nlid::Experiment swapped(u, Eigen::VectorXd::Zero(20), 1.0, "swapped");
  swapped.set_input_names({"temp", "flow"});
  CHECK_THROWS_WITH(m.simulate(swapped, nlid::InitialCondition::zero),
                    Catch::Contains("experiment 'swapped' has the inputs {temp, flow} but the model reads {flow, temp}"));
  CHECK_THROWS_WITH(m.predict(swapped, 1), Catch::Contains("reorder them (select_channels)"));
  swapped.set_input_names({"flow", "temp"});
  CHECK(m.simulate(swapped, nlid::InitialCondition::zero).rows() == 20);
  // A regressor written with the channel names follows them.
  nlid::RegressorList named;
  named.add_output_lags(1).add_custom("temp(t-1)*flow(t)", {"flow", "temp"});
  nlid::Nlarx<nlid::RegressorList, nlid::LinearMap<nlid::Dynamic>> n(named, nlid::LinearMap<nlid::Dynamic>(2));
  n.set_channel_names({"flow", "temp"}, "y1");
  CHECK_THROWS_WITH(n.set_channel_names({"temp", "flow"}, "y1"), Catch::Contains("'temp(t-1)*flow(t)'"));
  // The compile-time set with a text regressor checks the same way; estimation names the data's
  // channels first, so data read as {u2, u1} are refused before any fit.
  using Set = nlid::RegressorSet<nlid::LaggedRegressors<1, 1, 0>, nlid::InputLags<1, 0, 1>, nlid::ExpressionRegressor>;
  nlid::Nlarx<Set, nlid::LinearMap<4>> s(Set{{}, {}, nlid::ExpressionRegressor("u2(t-1)^2")}, nlid::LinearMap<4>{});
  CHECK_THROWS_WITH(s.set_channel_names({"u2", "u1"}, "y1"), Catch::Contains("'u2(t-1)^2'"));
}

TEST_CASE("bad data are reported naming the experiment", "[models][nlarx]") {
  const Model m = make_model();
  const nlid::Experiment short_data(inputs(2), Eigen::VectorXd::Zero(2), 0.01, "tiny");
  // Starts that read the record's past need more samples than the lags ...
  CHECK_THROWS_WITH(m.simulate(short_data, nlid::InitialCondition::measured),
                    Catch::Contains("experiment 'tiny' has 2 samples") && Catch::Contains("needed by the model's lags"));
  CHECK_THROWS_WITH(m.simulate(short_data, nlid::InitialCondition::estimate), Catch::Contains("needed by the model's lags"));
  // ... a free run from rest or equilibrium reads none (it was refused the same way): its first
  // samples are those of a longer run.
  const nlid::Experiment longer(inputs(40), Eigen::VectorXd::Zero(40), 0.01);
  for (const auto ic : {nlid::InitialCondition::zero, nlid::InitialCondition::equilibrium}) {
    const Eigen::MatrixXd a = m.simulate(short_data, ic), b = m.simulate(longer, ic);
    REQUIRE(a.rows() == 2);
    CHECK(a(0, 0) == b(0, 0));
    CHECK(a(1, 0) == b(1, 0));
  }
  const nlid::Experiment empty(inputs(0), Eigen::VectorXd::Zero(0), 0.01, "empty");
  CHECK_THROWS_WITH(m.simulate(empty), Catch::Contains("experiment 'empty' has no samples"));
  Eigen::MatrixXd u2(50, 2);
  u2.setOnes();
  const nlid::Experiment two_inputs(u2, Eigen::VectorXd::Zero(50), 0.01, "wide");
  CHECK_THROWS_WITH(m.simulate(two_inputs), Catch::Contains("experiment 'wide' has 2 input(s) but the nonlinear ARX model reads 1"));
  const nlid::Experiment wrong_ts(inputs(50), Eigen::VectorXd::Zero(50), 0.001, "fast");
  CHECK_THROWS_WITH(m.simulate(wrong_ts), Catch::Contains("sample time 0.001") && Catch::Contains("'fast'"));
  CHECK_THROWS_WITH(m.predict(wrong_ts, 0), Catch::Contains("horizon k must be >= 1"));
  Model unstable = make_model();
  Eigen::VectorXd th = unstable.parameters();
  th(0) = 3.0;  // pole far outside the unit circle
  unstable.set_parameters(th);
  const nlid::Experiment long_data(inputs(3000), Eigen::VectorXd::Zero(3000), 0.01, "long");
  CHECK_THROWS_WITH(unstable.simulate(long_data), Catch::Contains("simulation of experiment 'long' diverges"));
  // A DivergenceError (so that compare reports the model as diverged) at the first bad sample.
  try {
    (void)unstable.simulate(long_data);
    FAIL("diverging simulation returned");
  } catch (const nlid::DivergenceError& d) {
    CHECK(d.sample() > 100);
    CHECK_THAT(d.what(), Catch::Contains("not finite at sample " + std::to_string(d.sample()) + ")"));
  }
  const nlid::CompareResult cr = nlid::compare(unstable, nlid::Dataset{long_data});
  CHECK(cr.fit_of(0) == -std::numeric_limits<double>::infinity());
  CHECK_THROWS_WITH(unstable.set_parameters(Eigen::VectorXd::Zero(3)), Catch::Contains("has 3 values, the model has 5"));
}

TEST_CASE("a nonlinearity of the wrong size is rejected at construction", "[models][nlarx]") {
  using DynModel = nlid::Nlarx<nlid::LaggedRegressors<2, 1, 0>, nlid::LinearMap<Dynamic>>;
  CHECK_THROWS_WITH(DynModel(nlid::LaggedRegressors<2, 1, 0>{}, nlid::LinearMap<Dynamic>(5)),
                    Catch::Contains("takes 5 inputs but the regressor set has 3"));
}

TEST_CASE("describe lists regressors, the equation and the parameters", "[models][nlarx]") {
  Model m = make_model();
  m.set_channel_names({"cmd"}, "angle");
  const std::string d = m.describe();
  CHECK_THAT(d, Catch::Contains("angle(t-1)") && Catch::Contains("cmd(t)") && Catch::Contains("L[3] = 0.15") &&
                    Catch::Contains("not estimated"));
}

TEST_CASE("estimated initial condition recovers the true past outputs", "[models][nlarx]") {
  const Model m = make_model();
  const Eigen::MatrixXd u = inputs(200);
  const nlid::Experiment e(u, reference(u, m.parameters(), 0.7, -0.2), 0.01, "x0");
  const Eigen::VectorXd x0 = m.initial_state(e, nlid::InitialCondition::estimate);
  CHECK(x0(0) == Approx(0.7).margin(1e-7));
  CHECK(x0(1) == Approx(-0.2).margin(1e-7));
  CHECK((m.simulate(e, nlid::InitialCondition::estimate) - e.y()).cwiseAbs().maxCoeff() < 1e-7);
}
