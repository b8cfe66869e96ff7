// Known-answer tests of grey-box estimation: records simulated from each catalogue model with
// known parameters (plus noise) are fitted from the models' *default* guesses — only the data-
// driven initialisation and multi-start stand between the defaults and the answer.
#include <catch2/catch.hpp>

#include <array>
#include <cmath>
#include <numbers>

#include "nlid/models/greybox_estimate.hpp"
#include "nlid/models/simulation_band.hpp"
#include "nlid/models/physics/catalogue.hpp"
#include "../support/error_of.hpp"
#include "test_data.hpp"

using nlid::Dataset;
using nlid::GreyBox;
using nlid::InitialCondition;
namespace physics = nlid::physics;

namespace {

nlid::GreyBoxEstimateOptions quick(int candidates, int starts) {
  nlid::GreyBoxEstimateOptions o;
  o.multi_start.num_candidates = candidates;
  o.multi_start.num_starts = starts;
  return o;
}

// Two throttle records (steps through both stops) in the units of `scale` (1 = degrees).
Dataset throttle_data(double scale) {
  GreyBox<physics::Throttle> truth;
  Eigen::VectorXd p(7);
  p << 30.0, 400.0, 1e5, 56000.0 * scale, 15.0 * scale, 90.0 * scale, 0.0;
  truth.set_parameters(p);
  const double ts = 0.01;
  Dataset d;
  d.add(nlid_test::simulated(truth, nlid_test::steps({0.0, 0.35, 0.8, 0.2, -0.2, 0.6}, 80, 480), ts,
                             Eigen::Vector2d(15.0 * scale, 0.0), 0.2 * scale, 11, "steps"));
  d.add(nlid_test::simulated(truth, nlid_test::steps({0.45, 0.9, 0.1, 0.5, -0.1}, 60, 420), ts,
                             Eigen::Vector2d(15.0 * scale, 0.0), 0.2 * scale, 12, "pulses"));
  return d;
}

}  // namespace

TEST_CASE("Throttle: multi-start recovers c, k, K, b and the stops from default guesses",
          "[greybox][estimate]") {
  const Dataset d = throttle_data(1.0);
  GreyBox<physics::Throttle> m;  // defaults: travel 0..1, c = 20, k = 100, K = 1e4, b = 100
  const nlid::GreyBoxEstimate r = estimate(m, d);
  INFO(r.report());
  // Tolerances: 0.2 deg noise on 900 samples; K is only seen during brief contacts.
  CHECK(m.parameter("c") == Approx(30.0).epsilon(0.03));
  CHECK(m.parameter("k") == Approx(400.0).epsilon(0.03));
  CHECK(m.parameter("b") == Approx(56000.0).epsilon(0.03));
  CHECK(m.parameter("K") == Approx(1e5).epsilon(0.3));
  CHECK(m.parameter("lower_stop") == Approx(15.0).margin(0.2));
  CHECK(m.parameter("upper_stop") == Approx(90.0).margin(0.2));
  CHECK(m.parameter("rest") == Approx(0.0).margin(1.0));
  CHECK(r.fit.minCoeff() > 99.0);
  // Independent starts agree on the optimum: the evidence multi-start exists for.
  CHECK(r.multi_start.num_within_tolerance >= 2);
  CHECK(r.multi_start.starts.size() == 6u);
  CHECK(r.initial_states.size() == 2u);
  CHECK(r.initial_states[0][0] == Approx(15.0).margin(0.5));
  CHECK_THAT(r.report(), Catch::Contains("upper_stop") && Catch::Contains("fit steps"));
}

TEST_CASE("Throttle in radians: the catalogue does not assume the study's units",
          "[greybox][estimate]") {
  const double rad = std::numbers::pi / 180.0;
  const Dataset d = throttle_data(rad);
  GreyBox<physics::Throttle> m;
  const nlid::GreyBoxEstimate r = estimate(m, d, quick(16, 4));
  INFO(r.report());
  CHECK(m.parameter("c") == Approx(30.0).epsilon(0.03));
  CHECK(m.parameter("k") == Approx(400.0).epsilon(0.03));
  CHECK(m.parameter("b") == Approx(56000.0 * rad).epsilon(0.03));
  CHECK(m.parameter("lower_stop") == Approx(15.0 * rad).margin(0.2 * rad));
  CHECK(m.parameter("upper_stop") == Approx(90.0 * rad).margin(0.2 * rad));
  CHECK(r.fit.minCoeff() > 99.0);
}

TEST_CASE("Mass-spring-damper in millimetres", "[greybox][estimate]") {
  GreyBox<physics::MassSpringDamper> truth;
  truth.set_parameters(Eigen::Vector4d(8.0, 150.0, 3000.0, 40.0));  // rest 40 mm, 20 mm per unit
  const Dataset d(nlid_test::simulated(truth, nlid_test::steps({0.0, 1.0, -0.5, 0.5}, 60, 360), 0.01,
                                       Eigen::Vector2d(40.0, 0.0), 0.05, 21, "msd"));
  GreyBox<physics::MassSpringDamper> m;
  const auto r = estimate(m, d, quick(8, 2));
  INFO(r.report());
  CHECK(m.parameter("c") == Approx(8.0).epsilon(0.02));
  CHECK(m.parameter("k") == Approx(150.0).epsilon(0.02));
  CHECK(m.parameter("b") == Approx(3000.0).epsilon(0.02));
  CHECK(m.parameter("rest") == Approx(40.0).margin(0.05));
}

TEST_CASE("Regularization is given in the parameters' own units: a strong pull acts like fixing",
          "[greybox][estimate]") {
  // The solver works on scaled parameters; a weight or nominal left unscaled would pull k to
  // 170 times its scale instead of to 170.
  GreyBox<physics::MassSpringDamper> truth;
  truth.set_parameters(Eigen::Vector4d(8.0, 150.0, 3000.0, 40.0));
  const Dataset d(nlid_test::simulated(truth, nlid_test::steps({0.0, 1.0, -0.5, 0.5}, 60, 360), 0.01,
                                       Eigen::Vector2d(40.0, 0.0), 0.05, 21, "msd"));
  GreyBox<physics::MassSpringDamper> held;
  held.set_parameter("k", 170.0);
  held.fix("k");
  (void)estimate(held, d, quick(8, 2));

  GreyBox<physics::MassSpringDamper> pulled;
  auto o = quick(8, 2);
  o.multi_start.lm.regularization.lambda = 1e8;
  o.multi_start.lm.regularization.weights = Eigen::Vector4d(0.0, 1.0, 0.0, 0.0);
  o.multi_start.lm.regularization.nominal = Eigen::Vector4d(0.0, 170.0, 0.0, 0.0);
  const auto r = estimate(pulled, d, o);
  INFO(r.report());
  CHECK(pulled.parameter("k") == Approx(170.0).epsilon(1e-5));
  for (const char* p : {"c", "b", "rest"}) {
    INFO(p);
    CHECK(pulled.parameter(p) == Approx(held.parameter(p)).epsilon(1e-3));
  }
  // A weak pull leaves the data in charge.
  GreyBox<physics::MassSpringDamper> weak;
  o.multi_start.lm.regularization.lambda = 1e-9;
  (void)estimate(weak, d, o);
  CHECK(weak.parameter("k") == Approx(150.0).epsilon(0.02));
  // Without a nominal the pull is towards the start (the physical guess), not towards zero as
  // in black-box ridge regression: k stays at its start of 170 (it went to 0 before).
  GreyBox<physics::MassSpringDamper> from_guess;
  from_guess.set_parameters(Eigen::Vector4d(8.0, 170.0, 3000.0, 40.0));
  auto g = o;
  g.initialize_from_data = false;
  g.multi_start.lm.regularization.lambda = 1e8;
  g.multi_start.lm.regularization.nominal.resize(0);
  (void)estimate(from_guess, d, g);
  CHECK(from_guess.parameter("k") == Approx(170.0).epsilon(1e-5));
  CHECK(from_guess.parameter("b") == Approx(held.parameter("b")).epsilon(1e-3));
  // Sizes are the model's parameters, not the solver's (which include initial states).
  o.multi_start.lm.regularization.weights = Eigen::VectorXd::Ones(6);
  CHECK_THROWS_WITH(estimate(weak, d, o), Catch::Contains("regularization.weights has 6 entries; the model has 4 parameters"));
}

TEST_CASE("Rigid body with friction and input offset", "[greybox][estimate]") {
  GreyBox<physics::RigidBody> truth;
  truth.set_parameters(Eigen::Vector3d(2.0, 50.0, 0.1));
  const Dataset d(nlid_test::simulated(truth, nlid_test::steps({0.6, -0.4, 0.3, -0.1}, 50, 400), 0.01,
                                       Eigen::Vector2d(100.0, 0.0), 0.02, 31, "cart"));
  GreyBox<physics::RigidBody> m;
  const auto r = estimate(m, d, quick(8, 2));
  INFO(r.report());
  CHECK(m.parameter("c") == Approx(2.0).epsilon(0.02));
  CHECK(m.parameter("b") == Approx(50.0).epsilon(0.02));
  CHECK(m.parameter("u_offset") == Approx(0.1).margin(0.002));
  CHECK(r.initial_states[0][0] == Approx(100.0).margin(0.05));
}

TEST_CASE("First-order lag (thermal) in degrees Celsius", "[greybox][estimate]") {
  GreyBox<physics::FirstOrder> truth;
  truth.set_parameters(Eigen::Vector3d(12.0, 35.0, 21.0));  // τ = 12 s, 35 °C per unit, 21 °C ambient
  const Dataset d(nlid_test::simulated(truth, nlid_test::steps({0.0, 1.0, 0.4, 0.8}, 60, 300), 1.0,
                                       Eigen::VectorXd::Constant(1, 21.0), 0.1, 41, "oven"));
  GreyBox<physics::FirstOrder> m;
  const auto r = estimate(m, d, quick(8, 2));
  INFO(r.report());
  CHECK(m.parameter("tau") == Approx(12.0).epsilon(0.02));
  CHECK(m.parameter("gain") == Approx(35.0).epsilon(0.01));
  CHECK(m.parameter("offset") == Approx(21.0).margin(0.1));
}

TEST_CASE("Two tanks (Torricelli) with a pump", "[greybox][estimate]") {
  GreyBox<physics::TwoTank> truth;
  truth.set_parameters(Eigen::Vector4d(0.5, 0.3, 0.4, 0.0));
  const Dataset d(nlid_test::simulated(truth, nlid_test::steps({1.0, 2.0, 0.5, 1.5}, 100, 400), 0.5,
                                       Eigen::Vector2d(2.8, 1.6), 0.005, 51, "tanks"));
  GreyBox<physics::TwoTank> m;
  CHECK(m.is_fixed("offset"));  // a level sensor reads 0 at an empty tank unless freed
  const auto r = estimate(m, d, quick(8, 3));
  INFO(r.report());
  CHECK(m.parameter("b") == Approx(0.5).epsilon(0.03));
  CHECK(m.parameter("a1") == Approx(0.3).epsilon(0.03));
  CHECK(m.parameter("a2") == Approx(0.4).epsilon(0.03));
  CHECK(m.parameter("offset") == 0.0);
}

TEST_CASE("Fixed parameters stay bit-for-bit, zero and equilibrium starts work", "[greybox][estimate]") {
  GreyBox<physics::MassSpringDamper> truth;
  truth.set_parameters(Eigen::Vector4d(8.0, 150.0, 300.0, 0.0));
  const Dataset d(nlid_test::simulated(truth, nlid_test::steps({0.0, 1.0, 0.5}, 60, 240), 0.01,
                                       Eigen::Vector2d(0.0, 0.0), 0.01, 61, "msd"));
  SECTION("zero") {
    GreyBox<physics::MassSpringDamper> m;
    m.set_parameter("rest", 0.0);
    m.fix("rest");
    auto o = quick(4, 1);
    o.initial_condition = InitialCondition::zero;
    const auto r = estimate(m, d, o);
    CHECK(m.parameter("rest") == 0.0);
    CHECK(m.parameter("k") == Approx(150.0).epsilon(0.01));
    CHECK(r.initial_states[0].isZero());
  }
  SECTION("equilibrium") {
    GreyBox<physics::MassSpringDamper> m;
    auto o = quick(4, 1);
    o.initial_condition = InitialCondition::equilibrium;
    const auto r = estimate(m, d, o);
    CHECK(m.parameter("k") == Approx(150.0).epsilon(0.01));
    CHECK(r.initial_states[0][0] == Approx(0.0).margin(0.01));
  }
  SECTION("measured is rejected") {
    GreyBox<physics::MassSpringDamper> m;
    auto o = quick(4, 1);
    o.initial_condition = InitialCondition::measured;
    CHECK_THROWS_WITH(estimate(m, d, o), Catch::Contains("InitialCondition::measured"));
  }
}

TEST_CASE("An estimate held on a bound is inside the bounds, not one rounding below", "[greybox][estimate]") {
  GreyBox<physics::FirstOrder> truth;
  truth.set_parameters(Eigen::Vector3d(0.5, 2.0, 1.0));
  const Dataset d(nlid_test::simulated(truth, nlid_test::steps({0.0, 1.0, 0.3}, 50, 300), 0.02,
                                       Eigen::VectorXd::Constant(1, 1.0), 0.01, 3, "lag"));
  // The optimum tau = 0.5 lies below the lower bound, so the solver stops on it. The solver works
  // in units of the start value 7, and this bound does not survive the round trip (lower / 7) * 7.
  const double lower = 0.9179;
  REQUIRE(lower / 7.0 * 7.0 < lower);
  GreyBox<physics::FirstOrder> m;
  m.set_parameter("tau", 7.0);
  m.set_bounds("tau", lower, 100.0);
  nlid::GreyBoxEstimate r;
  REQUIRE_NOTHROW(r = estimate(m, d, quick(1, 1)));
  CHECK(m.parameter("tau") == lower);
  CHECK(r.parameters[0] == lower);
  for (const nlid::StartResult& s : r.multi_start.starts) CHECK(s.theta[0] >= lower);
}

TEST_CASE("A parameter estimated onto its bound has no standard deviation on the model, not a zero one",
          "[greybox][estimate][uncertainty]") {
  GreyBox<physics::FirstOrder> truth;
  truth.set_parameters(Eigen::Vector3d(0.5, 2.0, 1.0));
  const Dataset d(nlid_test::simulated(truth, nlid_test::steps({0.0, 1.0, 0.3}, 50, 300), 0.02,
                                       Eigen::VectorXd::Constant(1, 1.0), 0.01, 3, "lag"));
  GreyBox<physics::FirstOrder> m;
  m.set_parameter("tau", 2.0);
  m.set_bounds("tau", 1.0, 100.0);  // the optimum 0.5 lies below
  const nlid::GreyBoxEstimate r = estimate(m, d, quick(1, 1));
  REQUIRE(m.parameter("tau") == 1.0);
  REQUIRE(r.uncertainty.at_bound[0]);
  CHECK_THAT(r.report(), Catch::Contains("on its bound: no standard deviation"));
  REQUIRE(m.parameter_stddev().size() == 3);
  CHECK(std::isnan(m.parameter_stddev()[0]));
  CHECK(m.parameter_stddev()[1] > 0.0);
  INFO(m.describe());
  CHECK_THAT(m.describe(), Catch::Contains("estimated, on its lower bound") && !Catch::Contains("+- 0 ") &&
                               Catch::Contains("estimated +- "));
  // The band from what the model carries (as for a loaded model) takes tau as held, like the
  // band from the estimate's own uncertainty.
  const nlid::SimulationBand stored = nlid::simulation_band(m, d);
  const nlid::SimulationBand fresh = nlid::simulation_band(m, d, r.uncertainty);
  REQUIRE(stored.rms_stddev.allFinite());
  CHECK(stored.rms_stddev.isApprox(fresh.rms_stddev, 1e-6));
  const nlid::ParameterUncertainty u = nlid::uncertainty_from_covariance(
      m.parameter_names(), m.parameters(), m.parameter_covariance(), m.parameter_stddev(), m.fixed_flags());
  CHECK(u.at_bound[0]);
  CHECK_FALSE(u.free[0]);
  CHECK(u.stddev[0] == 0.0);
  CHECK_THAT(u.report(), Catch::Contains("on its bound: no standard deviation"));
}

TEST_CASE("Values set by the user survive data-driven initialisation", "[greybox][estimate]") {
  const Dataset d = throttle_data(1.0);
  GreyBox<physics::Throttle> m;
  m.set_parameter("upper_stop", 91.0);
  m.initialize(d);
  CHECK(m.parameter("upper_stop") == 91.0);
  CHECK(m.parameter("lower_stop") == Approx(15.0).margin(0.3));  // read off the data
  CHECK(m.parameter("b") > 1000.0);                              // rescaled from the default 100
  CHECK(m.initialized());
}

TEST_CASE("A held input tells the throttle's initialisation nothing about the gain b", "[greybox][estimate]") {
  // The recorded angles with the command held at 0.3 (or at 3e-13, far below any absolute
  // floor): b was range / 1e-12 = 1.9e15 (and 1.9e27), from a floor in absolute units.
  Dataset d;
  for (nlid::Experiment e : throttle_data(1.0)) {
    e.u().setConstant(0.3);
    d.add(std::move(e));
  }
  GreyBox<physics::Throttle> m;
  const double b0 = m.parameter("b");
  m.initialize(d);
  CHECK(m.parameter("b") == b0);
  CHECK(m.parameters().allFinite());
  // Held, with the rounding of a command stored to 6 significant digits (3.7e10 before).
  Dataset rounded;
  for (nlid::Experiment e : d) {
    for (Eigen::Index t = 0; t < e.size(); ++t) e.u()(t, 0) += (t % 3 - 1) * 5e-7;
    rounded.add(std::move(e));
  }
  GreyBox<physics::Throttle> r;
  r.initialize(rounded);
  CHECK(r.parameter("b") == b0);
  Dataset tiny;
  for (nlid::Experiment e : throttle_data(1.0)) {
    e.u() *= 1e-12;
    tiny.add(std::move(e));
  }
  GreyBox<physics::Throttle> t;
  t.initialize(tiny);
  CHECK(t.parameter("b") > 1e14);  // an input in tiny units that moves still scales b: 1e12 x degrees
}

TEST_CASE("A fixed parameter keeps its value through data-driven initialisation, default value included",
          "[greybox][estimate]") {
  const Dataset d = throttle_data(1.0);
  GreyBox<physics::Throttle> free_rest;
  free_rest.initialize(d);
  REQUIRE(free_rest.parameter("rest") != 0.0);  // the data would move it
  GreyBox<physics::Throttle> m;
  m.fix("rest");  // known: the default 0
  m.initialize(d);
  CHECK(m.parameter("rest") == 0.0);
  CHECK(m.is_fixed("rest"));
  CHECK(m.parameter("lower_stop") == Approx(15.0).margin(0.3));  // the free ones are still read off the data
  GreyBox<physics::Throttle> held;
  held.fix("rest");
  (void)estimate(held, d, quick(1, 1));
  CHECK(held.parameter("rest") == 0.0);
}

TEST_CASE("Estimation refuses crossed throttle stops at its start, saying what and where", "[greybox][estimate]") {
  const Dataset d = throttle_data(1.0);
  GreyBox<physics::Throttle> m;
  m.set_parameter("lower_stop", 95.0);  // a value the user set, above the stop the data show
  try {
    (void)estimate(m, d, quick(1, 1));
    FAIL("no nlid::Error for crossed stops");
  } catch (const nlid::Error& e) {
    INFO(e.what());
    CHECK(e.where().parameter == "lower_stop");
    CHECK_THAT(e.what(), Catch::Contains("initialize from the data") && Catch::Contains("lower_stop = 95 must be below upper_stop = 9"));
  }
  CHECK(m.parameter("upper_stop") == 1.0);  // the refused initialisation changed nothing
  nlid::GreyBoxEstimateOptions o = quick(1, 1);
  o.initialize_from_data = false;
  try {
    (void)estimate(m, d, o);
    FAIL("no nlid::Error for crossed stops");
  } catch (const nlid::Error& e) {
    INFO(e.what());
    CHECK(e.where().parameter == "lower_stop");
    CHECK_THAT(e.what(), Catch::Contains("grey-box estimation: the start: throttle: lower_stop = 95 must be below upper_stop = 1"));
  }
}

TEST_CASE("A failed estimation leaves the model as it was, not even initialised", "[greybox][estimate][errors]") {
  Dataset d;
  for (nlid::Experiment e : throttle_data(1.0)) {
    e.set_input_names({"command"});
    e.set_output_names({"angle"});
    d.add(std::move(e));
  }
  GreyBox<physics::Throttle> m;
  const Eigen::VectorXd p0 = m.parameters();
  const std::string text0 = m.describe();
  // An option refused after the data initialisation had run (it moved b from 100 to 5.6e4).
  nlid::GreyBoxEstimateOptions o = quick(1, 1);
  o.multi_start.lm.regularization.lambda = 1.0;
  o.multi_start.lm.regularization.weights = Eigen::VectorXd::Ones(3);
  CHECK_THROWS_WITH(estimate(m, d, o), Catch::Contains("regularization.weights has 3 entries; the model has 7 parameters"));
  CHECK(m.parameters() == p0);
  CHECK_FALSE(m.initialized());
  CHECK(m.describe() == text0);
  CHECK(m.input_names() != std::vector<std::string>{"command"});
  // A refused data initialisation (crossed stops) takes no channel names from the data either.
  m.set_parameter("lower_stop", 95.0);
  CHECK_THROWS(m.initialize(d));
  CHECK(m.input_names() != std::vector<std::string>{"command"});
  CHECK_FALSE(m.initialized());
  // And the estimate that succeeds commits everything.
  GreyBox<physics::Throttle> ok;
  (void)estimate(ok, d, quick(1, 1));
  CHECK(ok.initialized());
  CHECK(ok.input_names() == std::vector<std::string>{"command"});
  CHECK(ok.parameters() != p0);
}

namespace {
// dx/dt = -a x + b log(u): not defined for u <= 0, so one bad input sample makes every start fail.
struct LogInputPlant {
  static constexpr int num_states = 1, num_inputs = 1, num_outputs = 1, num_params = 2;
  std::array<nlid::ParameterInfo, 2> parameter_info() const {
    return {{{"a", "1/s", "pole", 5.0, 0.0, INFINITY, 0.5, 50.0, true, false},
             {"b", "1/s", "gain", 1.0, -INFINITY, INFINITY, 0.2, 5.0, false, false}}};
  }
  template <class T>
  void derivative(const T* x, const T* u, const T* p, T* dx) const {
    using std::log;
    dx[0] = -p[0] * x[0] + p[1] * log(u[0]);
  }
  template <class T>
  void output(const T* x, const T*, const T*, T* y) const {
    y[0] = x[0];
  }
};
}  // namespace

TEST_CASE("When no start can be simulated, estimation names the experiment and the sample", "[greybox][estimate][errors]") {
  Eigen::MatrixXd u = Eigen::MatrixXd::Constant(200, 1, 2.0);
  u.bottomRows(100).setConstant(3.0);
  GreyBox<LogInputPlant> truth;
  const Eigen::MatrixXd y = truth.simulate(u, 0.01, Eigen::VectorXd::Zero(1));
  Eigen::MatrixXd u_bad = u;
  u_bad(150, 0) = -1.0;  // log(-1)
  const Dataset d{nlid::Experiment(u, y, 0.01, "ok"), nlid::Experiment(u_bad, y, 0.01, "neg")};
  GreyBox<LogInputPlant> m;
  const nlid::Error e = nlid_test::error_of([&] { (void)estimate(m, d, quick(4, 2)); });
  // Was: "multi-start: the problem cannot be evaluated at the initial guess nor at any of 4
  // candidates; check the model, data and search ranges", with no location.
  CHECK_THAT(e.what(), Catch::Contains("grey-box estimation: no start can be simulated; at the starting values") &&
                           Catch::Contains("on 'neg'") && Catch::Contains("at sample 151"));
  // The physics is not defined there; more sub-steps would not help, and the message says so.
  CHECK_THAT(e.what(), Catch::Contains("the physics' derivative is not finite at the state of sample 150 and its input "
                                       "(u = -1): the model is not defined there"));
  CHECK_THAT(e.what(), !Catch::Contains("sub-step"));
  CHECK(e.where().experiment == 1);
  CHECK_FALSE(m.initialized());
  // From an equilibrium start too (the steady state exists; the record fails later).
  nlid::GreyBoxEstimateOptions eq = quick(4, 2);
  eq.initial_condition = InitialCondition::equilibrium;
  const nlid::Error e_eq = nlid_test::error_of([&] { (void)estimate(m, d, eq); });
  CHECK_THAT(e_eq.what(), Catch::Contains("no start can be simulated") && Catch::Contains("at sample 151"));
  CHECK(e_eq.where().experiment == 1);
  // A refused option is reported as itself, bad data or not.
  nlid::GreyBoxEstimateOptions zero_starts = quick(4, 2);
  zero_starts.multi_start.num_starts = 0;
  CHECK_THROWS_WITH(estimate(m, d, zero_starts), Catch::Contains("num_starts must be >= 1"));
  // Without the bad sample the same estimation runs.
  const Dataset good{nlid::Experiment(u, y, 0.01, "ok")};
  CHECK(estimate(m, good, quick(4, 2)).fit(0, 0) > 99.0);
}

TEST_CASE("Estimation and uncertainty name a mis-scaled record instead of failing every start", "[greybox][estimate][errors]") {
  // Degrees written as 1e200 made every start's simulation overflow: "the problem cannot be
  // evaluated at the initial guess nor at any of 24 candidates; check the model, data ...".
  Dataset d = throttle_data(1.0);
  Dataset bad;
  bad.add(d[0]);
  nlid::Experiment big = d[1];
  big.y() *= 1e200;
  bad.add(big);
  GreyBox<physics::Throttle> m;
  const nlid::Error e = nlid_test::error_of([&] { (void)estimate(m, bad, quick(1, 1)); });
  CHECK_THAT(e.what(), Catch::Contains("grey-box estimation: experiment 'pulses', output 'y'") &&
                           Catch::Contains("beyond 1e100") && Catch::Contains("rescale"));
  CHECK(e.where().experiment == 1);
  CHECK_THROWS_WITH(nlid::parameter_uncertainty(m, bad), Catch::Contains("parameter_uncertainty: experiment 'pulses'"));
}

TEST_CASE("Data that point outside a parameter's bounds leave no inverted range", "[greybox][estimate]") {
  const Dataset d = throttle_data(1.0);
  GreyBox<physics::Throttle> m;
  m.set_bounds("b", 0.0, 1000.0);  // the records need b = 56000
  m.initialize(d);
  const nlid::ParameterInfo& b = m.parameter_info()[3];
  CHECK(b.value == 1000.0);
  CHECK(b.range_lower <= b.range_upper);
  CHECK(b.range_upper <= 1000.0);
}

TEST_CASE("Uncertainty of the throttle estimate: the truth lies within a few sigma, names and units",
          "[greybox][estimate][uncertainty]") {
  const Dataset d = throttle_data(1.0);
  GreyBox<physics::Throttle> m;
  // The claims are about the optimum, not about reaching it (the multi-start test above does
  // that): one start near the truth, so the instrumented build (-O0, ASan) does not spend three
  // minutes on six starts from the defaults.
  Eigen::VectorXd start(7);
  start << 27.0, 370.0, 8e4, 52000.0, 15.5, 89.5, 0.0;
  m.set_parameters(start);
  m.fix("rest");
  const nlid::GreyBoxEstimate r = estimate(m, d, quick(1, 1));
  const nlid::ParameterUncertainty& u = r.uncertainty;
  INFO(r.report());
  // 7 parameters then x₀ = (y, v) of each of the two records.
  REQUIRE(u.theta.size() == 11);
  CHECK(u.names[0] == "c");
  CHECK(u.names[7] == "x0[0].y");
  CHECK(u.rank == 10);
  CHECK(u.stddev[6] == 0.0);  // rest: fixed
  const std::vector<std::pair<const char*, double>> truth = {
      {"c", 30.0}, {"k", 400.0}, {"K", 1e5}, {"b", 56000.0}, {"lower_stop", 15.0}, {"upper_stop", 90.0}};
  for (const auto& [name, value] : truth) {
    const auto i = m.parameter_index(name);
    INFO(name << " = " << u.theta[i] << " +- " << u.stddev[i]);
    CHECK(u.theta[i] == m.parameter(name));
    CHECK(u.stddev[i] > 0.0);
    CHECK(std::abs(u.theta[i] - value) < 4.0 * u.stddev[i]);
    CHECK(u.relative_percent(i) < 5.0);
  }
  // White measurement noise: the two formulas agree to within the window's own scatter.
  CHECK(std::abs(u.lag1_correlation) < 0.1);
  CHECK(u.stddev[0] / u.stddev_white[0] == Approx(1.0).margin(0.3));
  CHECK_THAT(r.report(), Catch::Contains("c          = ") && Catch::Contains("+- ") &&
                             Catch::Contains("rest       = 0  (fixed)") && !Catch::Contains("x0[0].y"));

  // Afterwards, from the model alone: the same numbers to the solvers' tolerances (initial
  // states re-fitted with the parameters held land where estimation left them) ...
  const nlid::ParameterUncertainty again = nlid::parameter_uncertainty(m, d);
  for (int i = 0; i < 11; ++i) CHECK(again.stddev[i] == Approx(u.stddev[i]).epsilon(1e-3));
  // ... also for a copy that has the parameters but no stored initial states.
  GreyBox<physics::Throttle> copy;
  copy.set_parameters(m.parameters());
  copy.fix("rest");
  const nlid::ParameterUncertainty fresh = nlid::parameter_uncertainty(copy, d);
  for (int i = 0; i < 6; ++i) CHECK(fresh.stddev[i] == Approx(u.stddev[i]).epsilon(1e-3));
  // Another initial condition: no state unknowns.
  nlid::GreyBoxUncertaintyOptions zero;
  zero.initial_condition = InitialCondition::zero;
  CHECK(nlid::parameter_uncertainty(m, d, zero).theta.size() == 7);
  // Data the physics cannot read are named.
  const Dataset wide(nlid::Experiment(Eigen::MatrixXd::Zero(40, 2), Eigen::VectorXd::Zero(40), 0.01, "wide"));
  CHECK_THROWS_WITH(nlid::parameter_uncertainty(m, wide), Catch::Contains("wide"));
}

TEST_CASE("Uncertainty of a grey-box estimate matches the spread over Monte Carlo records",
          "[greybox][estimate][uncertainty]") {
  // First-order lag, white noise: 60 records, each estimated from the truth with one LM run.
  GreyBox<physics::FirstOrder> truth;
  truth.set_parameters(Eigen::Vector3d(12.0, 35.0, 21.0));
  const Eigen::MatrixXd u = nlid_test::steps({0.0, 1.0, 0.4, 0.8}, 25, 200);
  const int replicates = 60;
  Eigen::MatrixXd est(replicates, 3), sd(replicates, 3);
  for (int k = 0; k < replicates; ++k) {
    const Dataset d(nlid_test::simulated(truth, u, 1.0, Eigen::VectorXd::Constant(1, 21.0), 0.5,
                                         100u + static_cast<unsigned>(k), "oven"));
    GreyBox<physics::FirstOrder> m = truth;
    const auto r = estimate(m, d, quick(1, 1));
    est.row(k) = r.parameters.transpose();
    sd.row(k) = r.uncertainty.stddev.head(3).transpose();
  }
  const Eigen::RowVector3d mean = est.colwise().mean();
  const Eigen::RowVector3d spread =
      ((est.rowwise() - mean).array().square().colwise().sum() / (replicates - 1)).sqrt();
  for (int i = 0; i < 3; ++i) {
    INFO("parameter " << i << ": spread " << spread[i] << ", predicted " << sd.col(i).mean());
    // 60 replicates: the spread itself is known to about ±9 %.
    CHECK(sd.col(i).mean() / spread[i] == Approx(1.0).margin(0.3));
  }
}
