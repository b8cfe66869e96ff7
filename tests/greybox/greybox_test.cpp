// GreyBox<Physics>: parameter table, simulation against closed-form steady states, scalar
// genericity (double/float/Dual), exact sensitivities vs central finite differences, initial
// conditions, and every user-caused failure reported with what and where.
#include <catch2/catch.hpp>

#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>

#include "nlid/data/preprocess.hpp"
#include "nlid/models/equilibrium.hpp"
#include "nlid/models/greybox.hpp"
#include "nlid/models/greybox_estimate.hpp"
#include "nlid/models/greybox_problem.hpp"
#include "nlid/models/physics/catalogue.hpp"
#include "../support/sanitizer.hpp"
#include "../support/unrated_pendulum.hpp"
#include "test_data.hpp"

using nlid::Dataset;
using nlid::Experiment;
using nlid::GreyBox;
using nlid::InitialCondition;
namespace physics = nlid::physics;

namespace {

// The study's throttle in degrees: c, k, K, b, lower_stop, upper_stop, rest.
Eigen::VectorXd throttle_truth() {
  Eigen::VectorXd p(7);
  p << 30.0, 400.0, 1e5, 400.0 * 140.0, 15.0, 90.0, 0.0;
  return p;
}

// Max relative difference between an exact Jacobian and central differences of the residuals.
template <class Problem>
double jacobian_error(const Problem& pb, const Eigen::VectorXd& theta, double rel_step = 1e-6) {
  const Eigen::Index m = pb.num_residuals();
  const int n = pb.num_parameters();
  Eigen::VectorXd r(m), rp(m), rm(m);
  Eigen::MatrixXd J(m, n);
  REQUIRE(pb.evaluate(theta, r, &J));
  double worst = 0.0;
  for (int i = 0; i < n; ++i) {
    const double h = rel_step * std::max(1.0, std::abs(theta[i]));
    Eigen::VectorXd tp = theta, tm = theta;
    tp[i] += h;
    tm[i] -= h;
    REQUIRE(pb.evaluate(tp, rp, nullptr));
    REQUIRE(pb.evaluate(tm, rm, nullptr));
    const Eigen::VectorXd fd = (rp - rm) / (2.0 * h);
    const double scale = std::max(fd.norm(), J.col(i).norm());
    if (scale > 1e-9) worst = std::max(worst, (fd - J.col(i)).norm() / scale);
  }
  return worst;
}

// A stiff lag (k = 1000 1/s) whose spectral_radius says "unknown" (-1), NaN or +inf.
template <int Mode>
struct DeclaredRadius {
  static constexpr int num_states = 1, num_inputs = 1, num_outputs = 1, num_params = 1;
  std::array<nlid::ParameterInfo, 1> parameter_info() const {
    return {{{"k", "", "", 1000.0, 0.0, std::numeric_limits<double>::infinity()}}};
  }
  double spectral_radius(const double* p) const {
    if (Mode == 0) return -1.0;
    if (Mode == 1) return std::numeric_limits<double>::quiet_NaN() * p[0];
    return std::numeric_limits<double>::infinity();
  }
  template <class T>
  void derivative(const T* x, const T* u, const T* p, T* dx) const { dx[0] = -p[0] * (x[0] - u[0]); }
  template <class T>
  void output(const T* x, const T*, const T*, T* y) const { y[0] = x[0]; }
};

// Torricelli's law for a tank draining through an orifice: x' = -k sqrt(x) + b u.
struct TorricelliTank {
  static constexpr int num_states = 1, num_inputs = 1, num_outputs = 1, num_params = 2;
  std::array<nlid::ParameterInfo, 2> parameter_info() const {
    return {{{"k", "", "", 0.5, 0.0, INFINITY}, {"b", "", "", 1.0, -INFINITY, INFINITY}}};
  }
  template <class T>
  void derivative(const T* x, const T* u, const T* p, T* dx) const {
    using std::sqrt;
    dx[0] = -p[0] * sqrt(x[0]) + p[1] * u[0];
  }
  template <class T>
  void output(const T* x, const T*, const T*, T* y) const { y[0] = x[0]; }
};

// dx/dt = −a x + b₁ u₁ + b₂ u₂ with unequal gains, so swapped inputs give another output.
struct TwoInputMix {
  static constexpr int num_states = 1, num_inputs = 2, num_outputs = 1, num_params = 3;
  std::array<nlid::ParameterInfo, 3> parameter_info() const {
    return {{{"a", "1/s", "", 2.0, 0.0, INFINITY}, {"b1", "", "", 3.0, -INFINITY, INFINITY},
             {"b2", "", "", -1.0, -INFINITY, INFINITY}}};
  }
  template <class T>
  void derivative(const T* x, const T* u, const T* p, T* dx) const { dx[0] = -p[0] * x[0] + p[1] * u[0] + p[2] * u[1]; }
  template <class T>
  void output(const T* x, const T*, const T*, T* y) const { y[0] = x[0]; }
};

}  // namespace

TEST_CASE("Parameter table: names, values, bounds, ranges, fixed flags", "[greybox]") {
  GreyBox<physics::Throttle> m;
  CHECK(m.num_parameters() == 7);
  CHECK(m.parameter_names() ==
        std::vector<std::string>{"c", "k", "K", "b", "lower_stop", "upper_stop", "rest"});
  m.set_parameter("K", 2e5);
  CHECK(m.parameter("K") == 2e5);
  CHECK(m.parameters()[2] == 2e5);
  m.fix("rest");
  CHECK(m.is_fixed("rest"));
  CHECK(m.fixed_flags()[6]);
  m.fix("rest", false);
  CHECK_FALSE(m.is_fixed("rest"));
  m.set_bounds("b", 0.0, 1e6);
  CHECK(m.parameter_info()[3].lower == 0.0);
  m.set_range("c", 1.0, 100.0, true);
  CHECK(m.parameter_info()[0].log_scale);
  CHECK(m.state_info()[0].name == "y");
  CHECK(m.name() == "throttle");
}

TEST_CASE("Parameter errors name the parameter and list the known ones", "[greybox][errors]") {
  GreyBox<physics::Throttle> m;
  try {
    (void)m.parameter("damping");
    FAIL("no throw");
  } catch (const nlid::Error& e) {
    CHECK_THAT(e.what(), Catch::Contains("unknown parameter 'damping'") &&
                             Catch::Contains("c, k, K, b, lower_stop, upper_stop, rest"));
    CHECK(e.where().parameter == "damping");
  }
  try {
    m.set_parameter("c", -1.0);
    FAIL("no throw");
  } catch (const nlid::Error& e) {
    CHECK_THAT(e.what(), Catch::Contains("value -1 of 'c' is outside its bounds [0, inf]"));
    CHECK(e.where().parameter == "c");
  }
  Eigen::VectorXd p = m.parameters();
  p[1] = std::nan("");
  CHECK_THROWS_WITH(m.set_parameters(p), Catch::Contains("'k' is not finite"));
  CHECK(std::isfinite(m.parameter("k")));  // nothing changed
  CHECK_THROWS_WITH(m.set_bounds("K", 1.0, 10.0), Catch::Contains("outside the new bounds"));
  CHECK_THROWS_WITH(m.set_range("K", 0.0, 10.0, true), Catch::Contains("must be positive"));
  nlid::IntegratorOptions o;
  o.stability_target = 10.0;
  CHECK_THROWS_WITH(m.set_integrator(o), Catch::Contains("stability_target"));
}

TEST_CASE("Crossed throttle stops are refused, naming both stops and their values", "[greybox][errors]") {
  GreyBox<physics::Throttle> m;  // stops 0 and 1
  const Eigen::VectorXd p0 = m.parameters();
  const auto refused = [](auto&& fn, const std::string& what, const std::string& values) {
    try {
      fn();
      FAIL("no nlid::Error for crossed stops");
    } catch (const nlid::Error& e) {
      INFO(e.what());
      CHECK(e.where().parameter == "lower_stop");
      CHECK_THAT(e.what(), Catch::Contains("grey-box model 'throttle', " + what) && Catch::Contains(values) &&
                               Catch::Contains("must be below"));
    }
  };
  Eigen::VectorXd p = p0;
  p[4] = 0.9;
  p[5] = 0.1;
  refused([&] { m.set_parameters(p); }, "set_parameters", "lower_stop = 0.9 must be below upper_stop = 0.1 (crossed");
  CHECK(m.parameters() == p0);  // nothing changed
  refused([&] { m.update_parameters(p); }, "update_parameters", "lower_stop = 0.9");
  p[4] = p[5] = 0.5;
  refused([&] { m.set_parameters(p); }, "set_parameters", "lower_stop = 0.5 must be below upper_stop = 0.5 (equal");
  // A file is read one value at a time, so set_parameter lets a crossing pass; a simulation
  // refuses it, and setting the other stop repairs it.
  const Eigen::MatrixXd u = Eigen::MatrixXd::Zero(5, 1);
  m.set_parameter("lower_stop", 15.0);
  refused([&] { (void)m.simulate(u, 0.01, Eigen::Vector2d::Zero()); }, "simulate",
          "lower_stop = 15 must be below upper_stop = 1");
  m.set_parameter("upper_stop", 90.0);
  CHECK(m.simulate(u, 0.01, Eigen::Vector2d(20.0, 0.0)).allFinite());
  // In estimation a trial step to crossed stops is not evaluable (rejected, like a divergence).
  const Dataset d(Experiment(Eigen::MatrixXd::Zero(20, 1), Eigen::MatrixXd::Constant(20, 1, 20.0), 0.01));
  const nlid::GreyBoxProblem<physics::Throttle> problem(m.physics(), m.integrator(), d, InitialCondition::zero);
  Eigen::VectorXd th = m.parameters();
  Eigen::VectorXd r(problem.num_residuals());
  CHECK(problem.evaluate(th, r, nullptr));
  th[4] = 95.0;
  CHECK_FALSE(problem.evaluate(th, r, nullptr));
}

namespace {
// One-parameter lag whose parameter table the test writes.
struct TableLag {
  static constexpr int num_states = 1, num_inputs = 1, num_outputs = 1, num_params = 1;
  nlid::ParameterInfo info;
  std::array<nlid::ParameterInfo, 1> parameter_info() const { return {{info}}; }
  template <class T>
  void derivative(const T* x, const T* u, const T* p, T* dx) const {
    dx[0] = u[0] - p[0] * x[0];
  }
  template <class T>
  void output(const T* x, const T*, const T*, T* y) const {
    y[0] = x[0];
  }
};
}  // namespace

TEST_CASE("A physics' parameter table is checked when the model is built", "[greybox][errors]") {
  const double inf = std::numeric_limits<double>::infinity();
  const auto refused = [](const nlid::ParameterInfo& q, const std::string& text) {
    try {
      GreyBox<TableLag> m(TableLag{q});
      FAIL("no throw");
    } catch (const nlid::Error& e) {
      CHECK_THAT(e.what(), Catch::Contains(text));
      CHECK(e.where().parameter == "a");
    }
  };
  refused({"a", "1/s", "", inf, 0.0, inf}, "default value inf of 'a' is not finite");
  refused({"a", "1/s", "", 1.0, 0.0, inf, 5.0, 0.5}, "range [5, 0.5] of 'a' must satisfy lower <= upper");
  refused({"a", "1/s", "", 1.0, std::nan(""), inf}, "bounds [nan, inf] of 'a' must satisfy lower <= upper");
  CHECK_NOTHROW(GreyBox<TableLag>(TableLag{{"a", "1/s", "", 1.0, 0.0, inf}}));  // NaN range: the bounds
}

TEST_CASE("Sample times and tolerances are checked by name", "[greybox][errors]") {
  GreyBox<physics::Throttle> m;
  for (const double ts : {0.0, -0.01, std::nan(""), std::numeric_limits<double>::infinity()}) {
    try {
      (void)m.substeps(ts);
      FAIL("no throw for ts = " << ts);
    } catch (const nlid::Error& e) {
      CHECK_THAT(e.what(), Catch::Contains("sample time must be positive and finite"));
      CHECK(e.where().parameter == "ts");
    }
  }
  CHECK(m.substeps(0.01) == 2);  // h sqrt(k + K) = 1.005
  nlid::IntegratorOptions o;
  CHECK(nlid::substeps_for(std::nan(""), 100.0, o) == o.max_substeps);  // not an undefined cast
  o.absolute_tolerance = 0.0;
  try {
    m.set_integrator(o);
    FAIL("no throw");
  } catch (const nlid::Error& e) {
    CHECK_THAT(e.what(), Catch::Contains("absolute_tolerance"));
    CHECK(e.where().parameter == "absolute_tolerance");
  }
}

TEST_CASE("Throttle steady states follow the equation, free and on the stops", "[greybox]") {
  GreyBox<physics::Throttle> m;
  m.set_parameters(throttle_truth());
  const double ts = 0.01;
  const Eigen::MatrixXd u = nlid_test::steps({0.3, 0.9, -0.2}, 200, 600);
  const Eigen::MatrixXd y = m.simulate(u, ts, Eigen::Vector2d(15.0, 0.0));
  // Free range: k y = b u  ->  y = 140 u.
  CHECK(y(199, 0) == Approx(42.0).epsilon(1e-4));
  // Upper stop: (k + K) y = b u + K·90 (penetration small, smoothing width 0.075°).
  const double up = (56000.0 * 0.9 + 1e5 * 90.0) / (1e5 + 400.0);
  CHECK(y(399, 0) == Approx(up).margin(0.06));
  // Lower stop with the spring's preload and a negative command.
  const double lo = (56000.0 * -0.2 + 1e5 * 15.0) / (1e5 + 400.0);
  CHECK(y(599, 0) == Approx(lo).margin(0.06));
  // With contact_smoothing = 0 the study's exact max/min is used.
  physics::Throttle exact;
  exact.contact_smoothing = 0.0;
  GreyBox<physics::Throttle> me(exact);
  me.set_parameters(throttle_truth());
  const Eigen::MatrixXd ye = me.simulate(u, ts, Eigen::Vector2d(15.0, 0.0));
  CHECK(ye(399, 0) == Approx(up).epsilon(1e-6));
  CHECK(ye(599, 0) == Approx(lo).epsilon(1e-6));
}

TEST_CASE("Simulation is generic over double, float and Dual", "[greybox]") {
  GreyBox<physics::Throttle> m;
  m.set_parameters(throttle_truth());
  const double ts = 0.01;
  const Eigen::MatrixXd u = nlid_test::steps({0.3, 0.9, -0.2, 0.5}, 60, 240);
  const Eigen::MatrixXd yd = m.simulate(u, ts, Eigen::Vector2d(15.0, 0.0));
  const int sub = m.substeps(ts);
  CHECK(sub == 4);  // sqrt(k + K) ts = 3.17 -> 4 sub-steps at h·rho <= 1
  {
    Eigen::Matrix<float, 7, 1> p = m.parameters().cast<float>();
    float x[2] = {15.0f, 0.0f};
    Eigen::VectorXf yf(u.rows());
    const auto got = m.simulate_with<float>(u, ts, p.data(), x, sub,
                                            [&](Eigen::Index k, const float* y) { yf[k] = y[0]; });
    REQUIRE(got == u.rows());
    CHECK((yf.cast<double>() - yd.col(0)).cwiseAbs().maxCoeff() < 2e-2);
  }
  {
    using D = nlid::Dual<double, 9>;
    Eigen::Matrix<D, 7, 1> p;
    for (int i = 0; i < 7; ++i) p[i] = D::variable(m.parameters()[i], i);
    D x[2] = {D::variable(15.0, 7), D::variable(0.0, 8)};
    double worst = 0.0;
    m.simulate_with<D>(u, ts, p.data(), x, sub, [&](Eigen::Index k, const D* y) {
      worst = std::max(worst, std::abs(y[0].a - yd(k, 0)));
    });
    CHECK(worst == 0.0);  // same operations, same rounding
  }
}

namespace {

// Outputs and call counts of one experiment's simulation, filled by its per-sample callback.
struct Trace {
  explicit Trace(Eigen::Index n) : y(Eigen::VectorXd::Constant(n, -1.0)), calls(Eigen::VectorXi::Zero(n)) {}
  auto sink() {
    return [this](Eigen::Index k, const double* yk) {
      y[k] = yk[0];
      ++calls[k];
    };
  }
  Eigen::VectorXd y;
  Eigen::VectorXi calls;
};

// Runs `ua` and `ub` in lockstep and alone; every number and every callback must agree.
void check_pair_equals_singles(const nlid::IntegratorOptions& opt, const Eigen::MatrixXd& ua,
                               const Eigen::MatrixXd& ub) {
  const physics::Throttle phys;
  const Eigen::VectorXd p = throttle_truth();
  const int sub = 4;
  Trace pa(ua.rows()), pb(ub.rows()), sa(ua.rows()), sb(ub.rows());
  double xa[2] = {15.0, 0.0}, xb[2] = {60.0, -5.0}, ya[2] = {15.0, 0.0}, yb[2] = {60.0, -5.0};
  const auto got = nlid::simulate_physics_pair(phys, opt, sub, ua, ub, 0.01, p.data(), xa, xb, pa.sink(), pb.sink());
  const auto ga = nlid::simulate_physics<double>(phys, opt, sub, ua, 0.01, p.data(), ya, sa.sink());
  const auto gb = nlid::simulate_physics<double>(phys, opt, sub, ub, 0.01, p.data(), yb, sb.sink());
  CHECK(got[0] == ga);
  CHECK(got[1] == gb);
  CHECK((pa.y - sa.y).cwiseAbs().maxCoeff() == 0.0);
  CHECK((pb.y - sb.y).cwiseAbs().maxCoeff() == 0.0);
  CHECK(pa.calls == sa.calls);
  CHECK(pb.calls == sb.calls);
  CHECK(pa.calls.maxCoeff() == 1);
  CHECK(xa[0] == ya[0]);
  CHECK(xa[1] == ya[1]);
  CHECK(xb[0] == yb[0]);
  CHECK(xb[1] == yb[1]);
}

}  // namespace

TEST_CASE("Two experiments in lockstep give exactly the numbers of two single runs", "[greybox]") {
  const Eigen::MatrixXd longer = nlid_test::steps({0.3, 0.9, -0.2, 0.5}, 60, 240);
  const Eigen::MatrixXd shorter = nlid_test::steps({0.8, 0.1, 0.6}, 35, 170);
  nlid::IntegratorOptions opt;
  SECTION("RK4, the longer record first or second") {
    check_pair_equals_singles(opt, longer, shorter);
    check_pair_equals_singles(opt, shorter, longer);
    check_pair_equals_singles(opt, longer, longer);
  }
  SECTION("Euler") {
    opt.method = nlid::IntegratorMethod::euler;
    check_pair_equals_singles(opt, longer, shorter);
  }
  SECTION("Dormand-Prince (each record its own steps: run one after the other)") {
    opt.method = nlid::IntegratorMethod::dormand_prince;
    check_pair_equals_singles(opt, shorter, longer);
  }
  SECTION("records of one and two samples") {
    check_pair_equals_singles(opt, longer.topRows(1), longer.topRows(2));
    check_pair_equals_singles(opt, longer.topRows(2), shorter);
  }
  SECTION("a record that diverges stops where it stops alone; the other runs to its end") {
    Eigen::MatrixXd wild = shorter;
    wild(77, 0) = 1e305;  // b·u overflows: the state leaves the finite numbers in interval 77
    check_pair_equals_singles(opt, longer, wild);
    check_pair_equals_singles(opt, wild, longer);
    opt.method = nlid::IntegratorMethod::euler;
    check_pair_equals_singles(opt, wild, longer);
  }
}

namespace {

// Three throttle records of different lengths (240, 170, 200 samples): the first two are
// evaluated in lockstep, the third alone.
Dataset three_records(const GreyBox<physics::Throttle>& m, double ts) {
  Dataset d;
  d.add(nlid_test::simulated(m, nlid_test::steps({0.3, 0.9, -0.2, 0.5}, 60, 240), ts, Eigen::Vector2d(15.0, 0.0), 0.3, 1, "a"));
  d.add(nlid_test::simulated(m, nlid_test::steps({0.8, 0.1, 0.6}, 35, 170), ts, Eigen::Vector2d(15.0, 0.0), 0.3, 2, "b"));
  d.add(nlid_test::simulated(m, nlid_test::steps({0.5, 0.2}, 40, 200), ts, Eigen::Vector2d(15.0, 0.0), 0.3, 3, "c"));
  return d;
}

// The first record of `d`, then its second with an input of 1e305 at sample 50, which makes the
// simulation diverge there.
Dataset with_wild_second(const Dataset& d) {
  Dataset bad;
  bad.add(d[0]);
  Eigen::MatrixXd u = d[1].u();
  u(50, 0) = 1e305;
  bad.add(Experiment(u, d[1].y(), d[1].ts(), "wild"));
  return bad;
}

}  // namespace

TEST_CASE("Residuals alone equal the residuals of the Jacobian pass, bit for bit", "[greybox]") {
  // Three records of different lengths: the first two in lockstep, the third alone.
  GreyBox<physics::Throttle> m;
  m.set_parameters(throttle_truth());
  const double ts = 0.01;
  const Dataset d = three_records(m, ts);
  Eigen::VectorXd p = throttle_truth();
  p[0] *= 1.3;  // away from the truth, so the residuals are not noise alone
  for (const InitialCondition ic : {InitialCondition::zero, InitialCondition::estimate, InitialCondition::equilibrium}) {
    nlid::GreyBoxProblem<physics::Throttle> pb(m.physics(), m.integrator(), d, ic);
    Eigen::VectorXd theta(pb.num_parameters());
    theta.head(7) = p;
    pb.refresh_initial_states(theta);
    Eigen::VectorXd r(pb.num_residuals()), rj(pb.num_residuals());
    Eigen::MatrixXd J(pb.num_residuals(), pb.num_parameters());
    REQUIRE(pb.evaluate(theta, r, nullptr));
    REQUIRE(pb.evaluate(theta, rj, &J));
    INFO("initial condition " << static_cast<int>(ic));
    CHECK(r.norm() > 1.0);
    if (ic == InitialCondition::equilibrium) {
      // The Jacobian pass starts from x̄ − (∂f/∂x)⁻¹ f(x̄) (the sensitivity step): x̄ moved by
      // the equilibrium solver's residual, ~1e-11, not by a different simulation.
      CHECK((r - rj).cwiseAbs().maxCoeff() <= 1e-9 * r.cwiseAbs().maxCoeff());
    } else {
      CHECK((r - rj).cwiseAbs().maxCoeff() == 0.0);
    }
  }
  SECTION("one diverging record fails the evaluation") {
    const Dataset bad = with_wild_second(d);
    nlid::GreyBoxProblem<physics::Throttle> pb(m.physics(), m.integrator(), bad, InitialCondition::zero);
    Eigen::VectorXd r(pb.num_residuals());
    CHECK_FALSE(pb.evaluate(p, r, nullptr));
  }
}

TEST_CASE("Jacobian passes in lockstep pairs equal the passes one after the other, bit for bit",
          "[greybox][jacobian]") {
  GreyBox<physics::Throttle> m;
  m.set_parameters(throttle_truth());
  const double ts = 0.01;
  // Three records of different lengths: the first two paired, the third alone.
  const Dataset d = three_records(m, ts);
  Eigen::VectorXd p = throttle_truth();
  p[0] *= 1.3;
  for (const InitialCondition ic : {InitialCondition::zero, InitialCondition::estimate, InitialCondition::equilibrium}) {
    INFO("initial condition " << static_cast<int>(ic));
    nlid::GreyBoxProblem<physics::Throttle> pb(m.physics(), m.integrator(), d, ic);
    Eigen::VectorXd theta(pb.num_parameters());
    theta.head(7) = p;
    pb.refresh_initial_states(theta);
    if (ic == InitialCondition::estimate) theta.tail(6) += Eigen::VectorXd::LinSpaced(6, 0.5, 3.0);
    nlid_test::check_lockstep_jacobians(pb, theta);
  }
  SECTION("a fixed parameter") {
    std::vector<bool> fixed(7, false);
    fixed[2] = true;
    nlid::GreyBoxProblem<physics::Throttle> pb(m.physics(), m.integrator(), d, InitialCondition::estimate, fixed);
    Eigen::VectorXd theta(pb.num_parameters());
    theta.head(7) = p;
    pb.refresh_initial_states(theta);
    nlid_test::check_lockstep_jacobians(pb, theta);
  }
  SECTION("initial states only") {
    nlid::GreyBoxProblem<physics::Throttle> pb(m.physics(), m.integrator(), d, InitialCondition::estimate, {},
                                               true, p);
    Eigen::VectorXd theta(pb.num_parameters());
    pb.refresh_initial_states(theta);
    nlid_test::check_lockstep_jacobians(pb, theta);
  }
  SECTION("a record that diverges fails both ways") {
    const Dataset bad = with_wild_second(d);
    nlid::GreyBoxProblem<physics::Throttle> pb(m.physics(), m.integrator(), bad, InitialCondition::zero);
    nlid_test::check_lockstep_jacobians(pb, p, false);
  }
}

namespace {

// ẋ = −a·x³ + b·u, y = x. No `spectral_radius`: the sub-step rule takes the Gershgorin bound
// 3·a·x₀² at each record's own initial state, so two records can need different sub-step counts.
struct CubicDecay {
  static constexpr int num_states = 1, num_inputs = 1, num_outputs = 1, num_params = 2;
  std::array<nlid::ParameterInfo, 2> parameter_info() const {
    return {{{"a", "", "cubic decay", 2.0}, {"b", "", "input gain", 1.0}}};
  }
  template <class T>
  void derivative(const T* x, const T* u, const T* p, T* dx) const {
    dx[0] = -p[0] * x[0] * x[0] * x[0] + p[1] * u[0];
  }
  template <class T>
  void output(const T* x, const T*, const T*, T* y) const {
    y[0] = x[0];
  }
};

}  // namespace

TEST_CASE("Records needing different sub-steps are evaluated one after the other, same numbers",
          "[greybox]") {
  const double ts = 0.1;
  Eigen::MatrixXd u = nlid_test::steps({0.5, 1.5, 0.2}, 15, 60);
  Eigen::VectorXd y = Eigen::VectorXd::LinSpaced(60, 1.0, 0.6);
  Dataset d;
  d.add(Experiment(u, y, ts, "slow"));
  d.add(Experiment(u.topRows(45), y.head(45), ts, "fast"));
  nlid::GreyBoxProblem<CubicDecay> pb(CubicDecay{}, nlid::IntegratorOptions{}, d, InitialCondition::estimate);
  Eigen::VectorXd theta(4);
  theta << 2.0, 1.0, 1.0, 3.0;  // a, b, x0 of "slow", x0 of "fast"
  REQUIRE(pb.substeps(0, theta.data(), &theta[2]) == 1);
  REQUIRE(pb.substeps(1, theta.data(), &theta[3]) == 6);
  Eigen::VectorXd r(pb.num_residuals()), rj(pb.num_residuals());
  Eigen::MatrixXd J(pb.num_residuals(), 4);
  REQUIRE(pb.evaluate(theta, r, nullptr));
  REQUIRE(pb.evaluate(theta, rj, &J));
  CHECK(r.norm() > 1.0);
  CHECK((r - rj).cwiseAbs().maxCoeff() == 0.0);
  nlid_test::check_lockstep_jacobians(pb, theta);  // the pair falls back to one after the other
}

TEST_CASE("Exact sensitivities equal central finite differences", "[greybox][jacobian]") {
  const double ts = 0.01;
  SECTION("throttle, two experiments, estimated initial states, through both stops") {
    GreyBox<physics::Throttle> m;
    m.set_parameters(throttle_truth());
    Dataset d;
    d.add(nlid_test::simulated(m, nlid_test::steps({0.3, 0.9, -0.2}, 50, 150), ts,
                               Eigen::Vector2d(20.0, 0.0), 0.1, 1, "a"));
    d.add(nlid_test::simulated(m, nlid_test::steps({0.6, 0.1}, 40, 120), ts,
                               Eigen::Vector2d(30.0, 5.0), 0.1, 2, "b"));
    nlid::GreyBoxProblem<physics::Throttle> pb(m.physics(), m.integrator(), d,
                                               InitialCondition::estimate);
    REQUIRE(pb.num_parameters() == 11);
    Eigen::VectorXd th(11);
    th << 25.0, 350.0, 8e4, 5e4, 16.0, 88.0, 2.0, 21.0, 1.0, 29.0, 4.0;
    CHECK(jacobian_error(pb, th) < 1e-5);
  }
  SECTION("two-tank, square roots, nonzero initial levels") {
    GreyBox<physics::TwoTank> m;
    m.set_parameters(Eigen::Vector4d(0.5, 0.3, 0.4, 0.0));
    m.fix("offset", false);
    Dataset d(nlid_test::simulated(m, nlid_test::steps({1.0, 2.0, 0.5}, 100, 300), 0.5,
                                   Eigen::Vector2d(2.0, 1.0), 0.01, 3, "tank"));
    nlid::GreyBoxProblem<physics::TwoTank> pb(m.physics(), m.integrator(), d,
                                              InitialCondition::estimate, m.fixed_flags());
    Eigen::VectorXd th(6);
    th << 0.45, 0.35, 0.38, 0.05, 2.2, 0.9;
    CHECK(jacobian_error(pb, th) < 1e-6);
  }
  SECTION("mass-spring-damper from equilibrium: implicit-function sensitivities") {
    GreyBox<physics::MassSpringDamper> m;
    Dataset d(nlid_test::simulated(m, nlid_test::steps({0.5, 1.5, 1.0}, 60, 180), ts,
                                   Eigen::Vector2d(0.5, 0.0), 0.01, 4, "msd"));
    nlid::GreyBoxProblem<physics::MassSpringDamper> pb(m.physics(), m.integrator(), d,
                                                       InitialCondition::equilibrium);
    REQUIRE(pb.num_parameters() == 4);
    CHECK(jacobian_error(pb, Eigen::Vector4d(15.0, 120.0, 90.0, 0.1)) < 1e-6);
  }
  SECTION("adaptive Dormand-Prince: derivative of the same discrete map") {
    GreyBox<physics::FirstOrder> m;
    nlid::IntegratorOptions o;
    o.method = nlid::IntegratorMethod::dormand_prince;
    o.relative_tolerance = 1e-10;
    o.absolute_tolerance = 1e-12;
    m.set_integrator(o);
    Dataset d(nlid_test::simulated(m, nlid_test::steps({0.0, 1.0, -0.5}, 30, 90), 0.1,
                                   Eigen::VectorXd::Constant(1, 0.2), 0.01, 5, "lag"));
    nlid::GreyBoxProblem<physics::FirstOrder> pb(m.physics(), m.integrator(), d,
                                                 InitialCondition::estimate);
    CHECK(jacobian_error(pb, Eigen::Vector4d(0.8, 1.2, 0.1, 0.3), 1e-5) < 1e-5);
  }
}

TEST_CASE("Fixed parameters get zero Jacobian columns", "[greybox][jacobian]") {
  GreyBox<physics::FirstOrder> m;
  m.fix("offset");
  Dataset d(nlid_test::simulated(m, nlid_test::steps({0.0, 1.0}, 20, 80), 0.1,
                                 Eigen::VectorXd::Constant(1, 0.0), 0.0, 6, "lag"));
  nlid::GreyBoxProblem<physics::FirstOrder> pb(m.physics(), m.integrator(), d,
                                               InitialCondition::zero, m.fixed_flags());
  Eigen::VectorXd r(pb.num_residuals());
  Eigen::MatrixXd J(pb.num_residuals(), 3);
  REQUIRE(pb.evaluate(Eigen::Vector3d(1.0, 1.0, 0.0), r, &J));
  CHECK(J.col(2).norm() == 0.0);
  CHECK(J.col(0).norm() > 0.0);
  CHECK(pb.fixed_mask() == std::vector<bool>{false, false, true});
}

TEST_CASE("Initial conditions: zero, equilibrium, estimated, measured is rejected", "[greybox]") {
  GreyBox<physics::MassSpringDamper> m;
  m.set_parameters(Eigen::Vector4d(12.0, 100.0, 80.0, 0.25));
  const double ts = 0.01;
  // Equilibrium for u = 0.5: y = rest + b u / k, at rest.
  const auto xe = m.equilibrium(Eigen::VectorXd::Constant(1, 0.5));
  CHECK(xe[0] == Approx(0.25 + 80.0 * 0.5 / 100.0).epsilon(1e-12));
  CHECK(xe[1] == Approx(0.0).margin(1e-12));
  // A record started away from rest: the estimated x0 is recovered.
  const Eigen::Vector2d x0(1.3, -4.0);
  const Experiment e =
      nlid_test::simulated(m, nlid_test::steps({0.5, 1.0}, 50, 200), ts, x0, 0.0, 7, "msd");
  const auto x0e = m.initial_state(e, InitialCondition::estimate);
  CHECK(x0e[0] == Approx(1.3).epsilon(1e-6));
  CHECK(x0e[1] == Approx(-4.0).epsilon(1e-5));
  CHECK((m.simulate(e, InitialCondition::estimate) - e.y()).cwiseAbs().maxCoeff() < 1e-6);
  CHECK(m.initial_state(e, InitialCondition::zero).isZero());
  CHECK(m.initial_state(e, InitialCondition::equilibrium)[0] == Approx(0.25 + 0.4).epsilon(1e-12));
  CHECK_THROWS_WITH(m.simulate(e, InitialCondition::measured),
                    Catch::Contains("InitialCondition::measured applies to regression models"));
}

TEST_CASE("An initial-state window shorter than the states need is widened", "[greybox]") {
  GreyBox<physics::MassSpringDamper> m;
  m.set_parameters(Eigen::Vector4d(12.0, 100.0, 80.0, 0.25));
  const Experiment e =
      nlid_test::simulated(m, nlid_test::steps({0.5, 1.0}, 50, 200), 0.01, Eigen::Vector2d(1.3, -4.0), 0.0, 7, "msd");
  m.set_initial_state_window(1);  // one sample cannot fix position and velocity
  Eigen::Vector2d x0;
  REQUIRE_NOTHROW(x0 = m.initial_state(e, InitialCondition::estimate));
  CHECK(x0[0] == Approx(1.3).epsilon(1e-6));
  CHECK(x0[1] == Approx(-4.0).epsilon(1e-4));
}

TEST_CASE("A guess picks one of several equilibria: the pendulum hanging or upright", "[greybox]") {
  GreyBox<nlid_test::UnratedPendulum> m;
  const Eigen::VectorXd u0 = Eigen::VectorXd::Zero(1);
  CHECK(m.equilibrium(u0)(0) == 0.0);
  const Eigen::Vector2d upright = m.equilibrium(u0, Eigen::Vector2d(3.0, 0.0));
  CHECK(upright(0) == Approx(std::numbers::pi).epsilon(1e-12));
  CHECK(upright(1) == Approx(0.0).margin(1e-12));
  const nlid::OperatingPoint op = nlid::equilibrium(m, u0, Eigen::Vector2d(-3.0, 0.0));
  CHECK(op.x(0) == Approx(-std::numbers::pi).epsilon(1e-12));
  CHECK(op.y(0) == op.x(0));
  CHECK(nlid::equilibrium(m, u0).x(0) == 0.0);
  CHECK_THROWS_WITH(m.equilibrium(u0, Eigen::Vector3d::Zero()), Catch::Contains("the guess must have 2 entries, got 3"));
  CHECK_THROWS_WITH(m.equilibrium(u0, Eigen::Vector2d(std::nan(""), 0.0)), Catch::Contains("the guess is not finite"));
}

TEST_CASE("An emptying tank: equilibrium where df/dx is infinite at the zero guess", "[greybox]") {
  // x' = -k sqrt(x) + b u: the searches start at x = 0, where df/dx = -inf. Newton stopped there
  // and reported "no equilibrium" for u = 0.3, whose equilibrium is (b u / k)^2 = 0.36; the
  // estimated start of a record, seeded from that equilibrium, failed on the model's own output.
  GreyBox<TorricelliTank> m;
  const Eigen::VectorXd u0 = Eigen::VectorXd::Constant(1, 0.3);
  CHECK(m.equilibrium(u0)(0) == Approx(0.36).epsilon(1e-10));
  Eigen::MatrixXd u(300, 1);
  for (int t = 0; t < 300; ++t) u(t, 0) = 0.3 + 0.1 * std::sin(0.05 * t);
  const Eigen::MatrixXd y = m.simulate(u, 0.1, Eigen::VectorXd::Constant(1, 0.1));
  const Experiment e(u, y, 0.1, "tank");
  CHECK(m.initial_state(e, InitialCondition::equilibrium)(0) == Approx(0.36).epsilon(1e-10));
  CHECK(m.initial_state(e, InitialCondition::estimate)(0) == Approx(0.1).epsilon(1e-6));
  CHECK((m.simulate(e, InitialCondition::estimate) - y).cwiseAbs().maxCoeff() < 1e-6);
  // A record draining to the equilibrium x = 0 of u = 0 starts its search at that kink: the
  // failure is named as the initial state's, not as "the initial parameters".
  const Eigen::MatrixXd u_drain = Eigen::MatrixXd::Zero(10, 1);
  const Experiment drain(u_drain, m.simulate(u_drain, 0.1, Eigen::VectorXd::Constant(1, 1.0)), 0.1, "drain");
  CHECK_THROWS_WITH(m.simulate(drain, InitialCondition::estimate),
                    Catch::Contains("estimating the initial state of grey-box model") &&
                        Catch::Contains("on 'drain' (its unknowns theta[i] are the states, from [0])") &&
                        Catch::Contains("initial_state hook"));
}

TEST_CASE("A free body under a net force has no equilibrium: reported, not guessed", "[greybox][errors]") {
  GreyBox<physics::RigidBody> m;  // c = 1, b = 1, u_offset = 0
  CHECK_NOTHROW(m.equilibrium(Eigen::VectorXd::Constant(1, 0.0)));
  CHECK_THROWS_WITH(m.equilibrium(Eigen::VectorXd::Constant(1, 0.5)),
                    Catch::Contains("has no equilibrium"));
}

TEST_CASE("An equilibrium start is the one estimation uses where there are many", "[greybox]") {
  // A free body at u = u_offset rests anywhere: every position is an equilibrium. Estimation
  // starts the record where it was measured; a simulation of the same record must too, or
  // compare() after estimate() would report another fit than the estimate did.
  GreyBox<physics::RigidBody> m;  // c = 1, b = 1, u_offset = 0
  Eigen::MatrixXd u = Eigen::MatrixXd::Zero(100, 1);
  u.bottomRows(50).setConstant(0.5);
  const Experiment e = nlid_test::simulated(m, u, 0.02, Eigen::Vector2d(3.0, 0.0), 0.0, 1, "body");
  const Dataset d(e);
  const nlid::GreyBoxProblem<physics::RigidBody> pb(m.physics(), m.integrator(), d, InitialCondition::equilibrium);
  Eigen::Vector2d x_problem;
  REQUIRE(pb.initial_state(Eigen::VectorXd(m.parameters()), 0, x_problem.data()));
  CHECK(x_problem[0] == Approx(3.0).epsilon(1e-12));
  const Eigen::Vector2d x_model = m.initial_state(e, InitialCondition::equilibrium);
  CHECK(x_model[0] == x_problem[0]);
  CHECK(x_model[1] == x_problem[1]);
  CHECK((m.simulate(e, InitialCondition::equilibrium) - e.y()).cwiseAbs().maxCoeff() < 1e-12);
  // Without a record there is no measured start: the search begins at the zero state.
  CHECK(m.equilibrium(Eigen::VectorXd::Constant(1, 0.0))[0] == 0.0);
}

TEST_CASE("Data errors say what and where", "[greybox][errors]") {
  GreyBox<physics::Throttle> m;
  const double ts = 0.01;
  SECTION("channel count names the experiment") {
    Dataset d;
    d.add(Experiment(Eigen::MatrixXd::Zero(10, 2), Eigen::MatrixXd::Zero(10, 1), ts, "two"));
    try {
      nlid::GreyBoxProblem<physics::Throttle> pb(m.physics(), m.integrator(), d,
                                                 InitialCondition::estimate);
      FAIL("no throw");
    } catch (const nlid::Error& e) {
      CHECK_THAT(e.what(), Catch::Contains("experiment 0 ('two') has 2 input(s), the physics takes 1"));
      CHECK(e.where().experiment == 0);
    }
    CHECK_THROWS_WITH(m.initialize(d), Catch::Contains("experiment 0 ('two') has 2 input(s)"));
    CHECK_THROWS_WITH(m.simulate(d[0], Eigen::Vector2d(0.0, 0.0)),
                      Catch::Contains("('two') has 2 input(s)"));
  }
  SECTION("too short") {
    Dataset d(Experiment(Eigen::MatrixXd::Zero(1, 1), Eigen::MatrixXd::Zero(1, 1), ts, "one"));
    CHECK_THROWS_WITH((nlid::GreyBoxProblem<physics::Throttle>(m.physics(), m.integrator(), d,
                                                               InitialCondition::zero)),
                      Catch::Contains("experiment 0 ('one') has 1 sample(s)") &&
                          Catch::Contains("data too short"));
    Dataset d2(Experiment(Eigen::MatrixXd::Zero(4, 1), Eigen::MatrixXd::Zero(4, 1), ts, "four"));
    CHECK_THROWS_WITH((nlid::GreyBoxProblem<physics::Throttle>(m.physics(), m.integrator(), d2,
                                                               InitialCondition::estimate)),
                      Catch::Contains("grey-box estimation: the data are too short: 4 residual(s) for 9 free "
                                      "unknown(s) (the parameters not fixed, and the initial states of every "
                                      "experiment)"));
  }
  SECTION("missing input names the sample") {
    Eigen::MatrixXd u = Eigen::MatrixXd::Zero(20, 1), y = Eigen::MatrixXd::Zero(20, 1);
    u(7, 0) = std::numeric_limits<double>::quiet_NaN();
    Dataset d(Experiment(u, y, ts, "gap", nlid::NonFinitePolicy::keep));
    try {
      nlid::GreyBoxProblem<physics::Throttle> pb(m.physics(), m.integrator(), d,
                                                 InitialCondition::zero);
      FAIL("no throw");
    } catch (const nlid::Error& e) {
      CHECK_THAT(e.what(), Catch::Contains("input 0 is not finite at sample 7"));
      CHECK(e.where().row == 8);
      CHECK(e.where().experiment == 0);
    }
  }
  SECTION("a diverging simulation is an error naming the sample, not a NaN") {
    m.set_parameters(throttle_truth());
    m.set_parameter("K", 1e7);
    nlid::IntegratorOptions o;
    o.substeps = 1;  // h·sqrt(K) = 32: far outside RK4's stability region in contact
    m.set_integrator(o);
    const Eigen::MatrixXd u = nlid_test::steps({0.9}, 100, 100);
    CHECK_THROWS_WITH(m.simulate(u, ts, Eigen::Vector2d(15.0, 0.0)),
                      Catch::Contains("diverged at sample") && Catch::Contains("substeps"));
  }
}

TEST_CASE("A record naming the model's channels in another order is refused", "[greybox][errors]") {
  // The physics reads u[0] as the first column whatever its name: {heater, fan} fed to a model
  // estimated on {fan, heater} ran (and re-fitted) the equations on swapped inputs.
  GreyBox<TwoInputMix> m;
  Eigen::MatrixXd u(200, 2);
  for (Eigen::Index t = 0; t < u.rows(); ++t) {
    u(t, 0) = (t / 40) % 2 ? 1.0 : 0.0;
    u(t, 1) = (t / 25) % 2 ? -0.5 : 0.5;
  }
  Experiment e(u, m.simulate(u, 0.1, Eigen::VectorXd::Zero(1)), 0.1, "bench");
  e.set_input_names({"fan", "heater"});
  e.set_output_names({"temp"});
  m.initialize(Dataset(e));
  REQUIRE(m.input_names() == std::vector<std::string>{"fan", "heater"});
  const Eigen::MatrixXd y = m.simulate(e, Eigen::VectorXd::Zero(1));
  Eigen::MatrixXd u_swapped(u.rows(), 2);
  u_swapped << u.col(1), u.col(0);
  Experiment swapped(u_swapped, e.y(), 0.1, "swapped");
  swapped.set_input_names({"heater", "fan"});
  swapped.set_output_names({"temp"});
  CHECK_THROWS_WITH(m.simulate(swapped, Eigen::VectorXd::Zero(1)),
                    Catch::Contains("experiment ('swapped') has the inputs {heater, fan} but the model reads "
                                    "{fan, heater} in that order"));
  try {
    nlid::estimate(m, Dataset(swapped));
    FAIL("no throw");
  } catch (const nlid::Error& err) {
    CHECK_THAT(err.what(), Catch::Contains("experiment 0 ('swapped') has the inputs {heater, fan}") &&
                               Catch::Contains("reorder them (select_channels)"));
    CHECK(err.where().experiment == 0);
  }
  // Reordered, it is the same record: the same simulation, bit for bit.
  CHECK(m.simulate(nlid::select_channels(swapped, {"fan", "heater"}, {"temp"}), Eigen::VectorXd::Zero(1)) == y);
  // Other names are other channels: matched by position, as before.
  swapped.set_input_names({"a", "b"});
  CHECK_NOTHROW(m.simulate(swapped, Eigen::VectorXd::Zero(1)));
}

TEST_CASE("Missing outputs are skipped, not invented", "[greybox]") {
  GreyBox<physics::FirstOrder> m;
  Experiment e = nlid_test::simulated(m, nlid_test::steps({0.0, 1.0}, 20, 60), 0.1,
                                      Eigen::VectorXd::Constant(1, 0.0), 0.0, 8, "lag");
  Eigen::MatrixXd y = e.y();
  y(30, 0) = std::numeric_limits<double>::quiet_NaN();
  Dataset d(Experiment(e.u(), y, 0.1, "lag", nlid::NonFinitePolicy::keep));
  nlid::GreyBoxProblem<physics::FirstOrder> pb(m.physics(), m.integrator(), d, InitialCondition::zero);
  Eigen::VectorXd r(pb.num_residuals());
  Eigen::MatrixXd J(pb.num_residuals(), 3);
  REQUIRE(pb.evaluate(m.parameters(), r, &J));
  CHECK(r[30] == 0.0);
  CHECK(J.row(30).norm() == 0.0);
  CHECK(r.allFinite());
  CHECK(r.norm() < 1e-12);
}

TEST_CASE("describe lists parameters with values and the data's units", "[greybox]") {
  GreyBox<physics::Throttle> m;
  m.set_units("deg", "V");
  const std::string s = m.describe();
  CHECK_THAT(s, Catch::Contains("Grey-box model 'throttle'") && Catch::Contains("max(y, upper_stop)"));
  CHECK_THAT(s, Catch::Contains("upper_stop") && Catch::Contains("deg/(V*s^2)") &&
                    Catch::Contains("hard-stop contact stiffness"));
  CHECK_THAT(s, Catch::Contains("y (deg), v (deg/s)"));
  m.fix("rest");
  CHECK_THAT(m.describe(), Catch::Contains("fixed"));
}

TEST_CASE("Long records: 1e5 samples simulate and differentiate in bounded time", "[greybox][large]") {
  // The instrumented -O0 build runs the same code path on a shorter record (10⁵ samples took 32 s
  // there, 2·10⁴ took 24 s).
  const int n = NLID_TEST_ASAN ? 10000 : 100000;
  GreyBox<physics::Throttle> m;
  m.set_parameters(throttle_truth());
  const double ts = 0.01;
  const Eigen::MatrixXd u = nlid_test::steps({0.3, 0.9, -0.2, 0.5, 0.1}, 137, n);
  const auto t0 = std::chrono::steady_clock::now();
  const Experiment e = nlid_test::simulated(m, u, ts, Eigen::Vector2d(15.0, 0.0), 0.1, 9, "long");
  const double t_sim = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  Dataset d(e);
  nlid::GreyBoxProblem<physics::Throttle> pb(m.physics(), m.integrator(), d,
                                             InitialCondition::estimate);
  Eigen::VectorXd th(9);
  th << m.parameters(), 15.0, 0.0;
  Eigen::VectorXd r(pb.num_residuals());
  Eigen::MatrixXd J(pb.num_residuals(), 9);
  const auto t1 = std::chrono::steady_clock::now();
  REQUIRE(pb.evaluate(th, r, &J));
  const double t_jac = std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
  CHECK(J.allFinite());
  CHECK(r.cwiseAbs().maxCoeff() < 1.0);  // noise 0.1 deg over a std of ~28 deg
  const auto x0 = m.initial_state(e, InitialCondition::estimate);
  CHECK(x0[0] == Approx(15.0).margin(0.2));
  // Generous bounds: they catch an accidental O(N²) or per-sample allocation storm, not noise.
  CHECK(t_sim < 5.0);
  CHECK(t_jac < 20.0);
}

TEST_CASE("Sub-steps of a fixed-step method: a known answer for Euler and RK4 on a first-order lag",
          "[greybox][integrators]") {
  // tau*y' = -(y - offset) + gain*u, u = 1: with h = ts/n each sub-step multiplies the distance to
  // the rest value y* = offset + gain by (1 - h/tau) for Euler and by the degree-4 Taylor
  // polynomial of exp(-h/tau) for RK4, so y(k) = y* + (y0 - y*)·q^(n·k) exactly (to rounding).
  GreyBox<nlid::physics::FirstOrder> m;
  m.set_parameters(Eigen::Vector3d(0.5, 2.0, 1.0));
  const double ts = 0.1, ystar = 3.0, y0 = 1.0;
  const Eigen::MatrixXd u = Eigen::MatrixXd::Ones(30, 1);
  for (const auto method : {nlid::IntegratorMethod::euler, nlid::IntegratorMethod::rk4}) {
    for (const int n : {1, 4}) {
      nlid::IntegratorOptions o;
      o.method = method;
      o.substeps = n;
      m.set_integrator(o);
      const double z = -(ts / n) / 0.5;
      const double q = method == nlid::IntegratorMethod::euler ? 1.0 + z : 1.0 + z + z * z / 2 + z * z * z / 6 + z * z * z * z / 24;
      const Eigen::MatrixXd y = m.simulate(u, ts, Eigen::VectorXd::Constant(1, y0));
      INFO((method == nlid::IntegratorMethod::euler ? "euler" : "rk4") << ", " << n << " sub-steps");
      for (int k = 0; k < 30; ++k) CHECK(y(k, 0) == Approx(ystar + (y0 - ystar) * std::pow(q, n * k)).epsilon(1e-12));
    }
  }
}

TEST_CASE("A NaN spectral radius falls back to the Gershgorin bound, +inf is refused by name",
          "[greybox][integrators]") {
  const double ts = 0.01;  // h*rho = 10: one RK4 step per sample explodes
  const Eigen::MatrixXd u = Eigen::MatrixXd::Ones(100, 1);
  const GreyBox<DeclaredRadius<0>> unknown;
  const GreyBox<DeclaredRadius<1>> nan;
  REQUIRE(unknown.substeps(ts) == 10);
  CHECK(nan.substeps(ts) == unknown.substeps(ts));
  const Eigen::MatrixXd y = nan.simulate(u, ts, Eigen::VectorXd::Zero(1));
  CHECK(y(99, 0) == Approx(1.0));

  const GreyBox<DeclaredRadius<2>> inf;
  try {
    (void)inf.simulate(u, ts, Eigen::VectorXd::Zero(1));
    FAIL("no nlid::Error for an infinite spectral radius");
  } catch (const nlid::Error& e) {
    INFO(e.what());
    CHECK(e.where().parameter == "spectral_radius");
    CHECK_THAT(e.what(), Catch::Contains("spectral_radius(p) is +inf"));
  }
  CHECK_THROWS_WITH(inf.substeps(ts), Catch::Contains("spectral_radius"));
  // In estimation such a trial point is rejected like a diverging one, not ended with a throw.
  const Dataset d(Experiment(u, Eigen::MatrixXd::Ones(100, 1), ts));
  const nlid::GreyBoxProblem<DeclaredRadius<2>> problem(inf.physics(), inf.integrator(), d, InitialCondition::zero);
  Eigen::VectorXd r(problem.num_residuals());
  CHECK_FALSE(problem.evaluate(inf.parameters(), r, nullptr));
}

TEST_CASE("Without a spectral radius the sub-step count covers the stiffest state of the run, not only its start",
          "[greybox][integrators]") {
  // Released from horizontal the Gershgorin bound is 1 (one RK4 step per 0.2 s sample); at the
  // bottom of the swing it is 10.5 (three). Judged at the start only, the run took 1 step per
  // sample and ended 6e-3 rad from the true swing, 70 times the error of three.
  GreyBox<nlid_test::UnratedPendulum> m;
  const double ts = 0.2;
  const Eigen::MatrixXd u = Eigen::MatrixXd::Zero(100, 1);
  const Eigen::Vector2d x0(std::numbers::pi / 2, 0.0);
  CHECK(m.substeps(u, ts, x0) == 3);
  CHECK(m.substeps(u.topRows(1), ts, x0) == 1);  // a one-sample run never leaves the start
  const Eigen::MatrixXd y = m.simulate(u, ts, x0);
  nlid::IntegratorOptions fine;
  fine.substeps = 400;
  GreyBox<nlid_test::UnratedPendulum> ref = m;
  ref.set_integrator(fine);
  const Eigen::MatrixXd y_ref = ref.simulate(u, ts, x0);
  const double err = (y - y_ref).cwiseAbs().maxCoeff();
  CHECK(err < 5e-4);
  // The count at the start alone (what the rule gave before): visibly wrong.
  nlid::IntegratorOptions start_only;
  start_only.substeps = 1;
  GreyBox<nlid_test::UnratedPendulum> coarse = m;
  coarse.set_integrator(start_only);
  CHECK((coarse.simulate(u, ts, x0) - y_ref).cwiseAbs().maxCoeff() > 3.0 * err);
  // Estimation takes the same count as simulation: its residuals at the true parameters are
  // those of `simulate`.
  const Dataset d(Experiment(u, y, ts));
  const nlid::GreyBoxProblem<nlid_test::UnratedPendulum> problem(m.physics(), m.integrator(), d, InitialCondition::estimate);
  Eigen::VectorXd theta(problem.num_parameters());
  theta << m.parameters(), x0;
  CHECK(problem.substeps(0, theta.data(), x0.data()) == 3);
  Eigen::VectorXd r(problem.num_residuals());
  REQUIRE(problem.evaluate(theta, r, nullptr));
  CHECK(r.cwiseAbs().maxCoeff() < 1e-12);
}

TEST_CASE("An adaptive run out of its step budget names max_adaptive_steps, not the fixed-step options",
          "[greybox][integrators]") {
  GreyBox<DeclaredRadius<0>> m;
  m.set_parameter("k", 1e6);  // stiff: Dormand-Prince needs thousands of steps per 10 ms sample
  nlid::IntegratorOptions o;
  o.method = nlid::IntegratorMethod::dormand_prince;
  o.max_adaptive_steps = 50;
  m.set_integrator(o);
  const Eigen::MatrixXd u = Eigen::MatrixXd::Ones(10, 1);
  try {
    (void)m.simulate(u, 0.01, Eigen::VectorXd::Zero(1));
    FAIL("no nlid::DivergenceError for an exhausted step budget");
  } catch (const nlid::DivergenceError& e) {
    INFO(e.what());
    CHECK_THAT(e.what(), Catch::Contains("diverged at sample 1") && Catch::Contains("adaptive Dormand-Prince") &&
                             Catch::Contains("IntegratorOptions::max_adaptive_steps = 50") &&
                             !Catch::Contains("sub-step") && !Catch::Contains("min_substeps"));
  }
  o.max_adaptive_steps = 100000;
  m.set_integrator(o);
  CHECK(m.simulate(u, 0.01, Eigen::VectorXd::Zero(1))(9, 0) == Approx(1.0));
}
