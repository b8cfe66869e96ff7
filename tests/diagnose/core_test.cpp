// Building blocks of the diagnosis: noise floor, locator, significance tests, effect catalogue,
// augmented model (simulation, exact Jacobian) and refit — each against a known answer.
#include <catch2/catch.hpp>

#include <array>
#include <cmath>
#include <random>
#include <string>

#include "nlid/diagnose.hpp"
#include "nlid/models/physics/first_order.hpp"
#include "nlid/models/physics/mass_spring_damper.hpp"
#include "nlid/models/physics/throttle.hpp"
#include "synth.hpp"
#include "../support/unrated_pendulum.hpp"

using namespace nlid;

namespace {

Eigen::VectorXd noisy_sine(Eigen::Index n, double sigma, unsigned seed, double quantum = 0.0) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> nd(0.0, sigma);
  Eigen::VectorXd y(n);
  for (Eigen::Index k = 0; k < n; ++k) {
    double v = 10.0 * std::sin(0.002 * static_cast<double>(k)) + nd(rng);
    if (quantum > 0) v = quantum * std::round(v / quantum);
    y(k) = v;
  }
  return y;
}

std::string message_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

DataScales msd_scales(double ts) { return diag_test::unit_scales(ts, 1.1); }

}  // namespace

TEST_CASE("noise floor: differences recover sigma of white noise on a smooth signal", "[diagnose][noise]") {
  for (double sigma : {0.01, 0.2}) {
    const Eigen::VectorXd y = noisy_sine(20000, sigma, 7u);
    const NoiseFloor f = estimate_noise_floor(y);
    CHECK(f.sigma == Approx(sigma).epsilon(0.04));
  }
  // Steps (a few huge differences) do not inflate the robust estimate.
  Eigen::VectorXd y = noisy_sine(20000, 0.05, 3u);
  for (Eigen::Index k = 0; k < y.size(); ++k) y(k) += 20.0 * static_cast<double>((k / 1000) % 2);
  CHECK(estimate_noise_floor(y).sigma == Approx(0.05).epsilon(0.05));
}

TEST_CASE("noise floor: quantisation is detected and floors sigma at q/sqrt(12)", "[diagnose][noise]") {
  const Eigen::VectorXd y = noisy_sine(5000, 0.01, 5u, 0.1);
  CHECK(detect_quantisation(y) == Approx(0.1).epsilon(1e-9));
  CHECK(estimate_noise_floor(y).sigma >= 0.1 / std::sqrt(12.0) - 1e-12);
  CHECK(detect_quantisation(noisy_sine(5000, 0.01, 5u)) == 0.0);
}

TEST_CASE("noise floor: raw-rate estimate carried through decimation matches the decimated noise", "[diagnose][noise]") {
  const double sigma = 0.2;
  Dataset d;
  Eigen::MatrixXd u = Eigen::MatrixXd::Zero(40000, 1);
  Eigen::MatrixXd y(40000, 1);
  y.col(0) = noisy_sine(40000, sigma, 11u);
  d.add(Experiment(u, y, 0.001, "raw"));
  const NoiseFloor f = estimate_noise_floor(d, 0, 10);
  CHECK(f.raw_sigma == Approx(sigma).epsilon(0.04));
  // Reference: pure noise decimated by the same filter.
  Eigen::MatrixXd n(40000, 1);
  std::mt19937 rng(99u);
  std::normal_distribution<double> nd(0.0, sigma);
  for (Eigen::Index k = 0; k < n.rows(); ++k) n(k, 0) = nd(rng);
  const Experiment dec = decimate(Experiment(u, n, 0.001), 10);
  const double ref = std::sqrt(dec.y().col(0).array().square().mean());
  CHECK(f.sigma == Approx(ref).epsilon(0.06));
  CHECK(f.inflation >= 1.0);
  // A given raw-rate sigma is carried through the same filter (nlid-diagnose --noise): the same
  // floor and inflation as the estimate from that sigma, not sigma itself with inflation 1.
  const NoiseFloor g = noise_floor_from_sigma(f.raw_sigma, 10);
  CHECK(g.sigma == f.sigma);
  CHECK(g.inflation == f.inflation);
  CHECK(g.inflation > 1.0);
  CHECK(g.decimation == 10);
  const NoiseFloor h = noise_floor_from_sigma(0.3);
  CHECK(h.sigma == 0.3);
  CHECK(h.inflation == 1.0);
  CHECK_THAT(message_of([&] { (void)noise_floor_from_sigma(0.0, 10); }), Catch::Contains("must be positive and finite"));
}

TEST_CASE("noise floor: bad input is reported", "[diagnose][noise][errors]") {
  Dataset d;
  d.add(Experiment(Eigen::MatrixXd::Zero(20, 1), Eigen::MatrixXd::Zero(20, 1), 0.1));
  CHECK_THAT(message_of([&] { (void)estimate_noise_floor(d, 3); }), Catch::Contains("output index 3 out of range"));
  CHECK_THAT(message_of([&] { (void)estimate_noise_floor(Eigen::VectorXd::Zero(5)); }), Catch::Contains("need at least"));
}

TEST_CASE("locate: an injected error burst is found as an interval with its energy share", "[diagnose][locate]") {
  const double sigma = 0.1;
  Dataset d;
  std::mt19937 rng(1u);
  std::normal_distribution<double> nd(0.0, sigma);
  const Eigen::Index n = 4000;
  Eigen::MatrixXd u(n, 1), y(n, 1);
  Eigen::VectorXd sim(n);
  for (Eigen::Index k = 0; k < n; ++k) {
    u(k, 0) = static_cast<double>(k % 500 < 250);
    sim(k) = 5.0 * std::sin(0.01 * static_cast<double>(k));
    y(k, 0) = sim(k) + nd(rng) + ((k >= 2000 && k < 2200) ? 1.0 : 0.0);
  }
  d.add(Experiment(u, y, 0.01, "burst"));
  NoiseFloor f;
  f.sigma = sigma;
  const Mismatch m = locate_mismatch(d, {sim}, f);
  REQUIRE(m.intervals.size() == 1);
  CHECK(m.intervals[0].t0 == Approx(20.0).margin(0.3));
  CHECK(m.intervals[0].t1 == Approx(22.0).margin(0.3));
  CHECK(m.intervals[0].energy_share == Approx(202.0 / 240.0).epsilon(0.05));  // burst + its noise of the total
  // Regions: energy shares of each variable's bins add up to 1.
  double ysum = 0, rsum = 0, usum = 0;
  for (const MismatchRegion& r : m.regions) (r.variable == "y" ? ysum : r.variable == "u" ? usum : rsum) += r.energy_share;
  CHECK(ysum == Approx(1.0));
  CHECK(rsum == Approx(1.0));
  CHECK(usum == Approx(1.0));
  // Pure noise: nothing located.
  Dataset d0;
  Eigen::MatrixXd y0(n, 1);
  for (Eigen::Index k = 0; k < n; ++k) y0(k, 0) = sim(k) + nd(rng);
  d0.add(Experiment(u, y0, 0.01));
  CHECK(locate_mismatch(d0, {sim}, f).intervals.empty());
  CHECK_THAT(message_of([&] { (void)locate_mismatch(d0, {sim.head(10)}, f); }), Catch::Contains("simulated output has 10 samples"));
}

TEST_CASE("significance: gate and candidate tests", "[diagnose][significance]") {
  // A residual at the floor is consistent; 20 % above is not (N = 10^4).
  CHECK(floor_consistency(1.0e4 * 0.01, 10000, 0.1, 1.0).consistent);
  CHECK_FALSE(floor_consistency(1.2e4 * 0.01, 10000, 0.1, 1.0).consistent);
  // A candidate removing half the excess with a clear change is significant...
  const double v0 = 2.0 * 1e4 * 0.01, v1 = 1.5 * 1e4 * 0.01;
  CandidateStatistics s = candidate_statistics(v0, v1, std::sqrt(v0 - v1), 10000, 0.1, 1.0, 1, 14);
  CHECK(s.significant);
  CHECK(s.relevance == Approx(0.5));
  // ... one that removes 2 % of the excess is not relevant, and one that gains nothing fails.
  s = candidate_statistics(v0, v0 - 0.02 * (v0 - 100.0), 1.0, 10000, 0.1, 1.0, 1, 14);
  CHECK_FALSE(s.significant);
  CHECK(s.relevance < 0.1);
  CHECK_FALSE(candidate_statistics(v0, v0, 0.0, 10000, 0.1, 1.0, 1, 14).significant);
}

TEST_CASE("effects: catalogue names, sites and applicability", "[diagnose][effects]") {
  const std::vector<std::string> names{"coulomb_friction", "viscous_friction", "quadratic_drag", "cubic_stiffness",
                                       "hard_stop", "preload", "backlash", "input_deadzone", "input_saturation",
                                       "output_saturation", "dead_time", "actuator_lag", "input_offset", "output_offset"};
  REQUIRE(all_effect_kinds().size() == names.size());
  for (std::size_t i = 0; i < names.size(); ++i) {
    CHECK(effect_name(all_effect_kinds()[i]) == names[i]);
    CHECK(effect_kind(names[i]) == all_effect_kinds()[i]);
  }
  CHECK_THAT(message_of([] { (void)effect_kind("stiction"); }),
             Catch::Contains("unknown effect 'stiction'") && Catch::Contains("coulomb_friction"));
  // first_order has no position/velocity pair: friction is not applicable, offsets are.
  const physics::FirstOrder fo;
  AugmentedModel<physics::FirstOrder> m(fo, diag_test::table(fo, {}), 0.01);
  CHECK_FALSE(m.roles().mechanical);
  CHECK_FALSE(effect_not_applicable_reason(EffectKind::coulomb_friction, false).empty());
  CHECK(effect_not_applicable_reason(EffectKind::input_offset, false).empty());
  const DataScales s = msd_scales(0.01);
  CHECK_THAT(message_of([&] { m.add_effect(diag_test::effect(EffectKind::coulomb_friction, {1.0}, s)); }),
             Catch::Contains("not applicable"));
  m.add_effect(diag_test::effect(EffectKind::output_offset, {0.5}, s));
  CHECK_THAT(message_of([&] { m.add_effect(diag_test::effect(EffectKind::output_offset, {0.5}, s)); }),
             Catch::Contains("already part of the model"));
  // The mass-spring-damper is found mechanical by probing, output = position.
  const physics::MassSpringDamper msd;
  AugmentedModel<physics::MassSpringDamper> mm(msd, diag_test::table(msd, {}), 0.01);
  CHECK(mm.roles().mechanical);
  CHECK(mm.roles().position == 0);
  CHECK(mm.roles().velocity == 1);
  CHECK(mm.roles().output_is_position);
}

TEST_CASE("augmented model: effects act as their laws say", "[diagnose][augmented]") {
  const physics::FirstOrder fo;
  const DataScales s = msd_scales(0.01);
  AugmentedModel<physics::FirstOrder> base(fo, diag_test::table(fo, {{"tau", 0.1}, {"gain", 2.0}}), 0.01);
  Eigen::MatrixXd u = Eigen::MatrixXd::Constant(400, 1, 1.0);
  u.topRows(10).setZero();
  const Experiment e(u, Eigen::MatrixXd::Zero(400, 1), 0.01);
  const Eigen::VectorXd x0 = Eigen::VectorXd::Zero(1);
  // Steady state gain*u = 2; output offset adds, input offset shifts by gain*offset.
  CHECK(base.simulate(e, x0)(399, 0) == Approx(2.0).epsilon(1e-6));
  CHECK(base.with_effect(diag_test::effect(EffectKind::output_offset, {0.3}, s)).simulate(e, x0)(399, 0) == Approx(2.3).epsilon(1e-6));
  CHECK(base.with_effect(diag_test::effect(EffectKind::input_offset, {0.25}, s)).simulate(e, x0)(399, 0) == Approx(2.5).epsilon(1e-6));
  CHECK(base.with_effect(diag_test::effect(EffectKind::input_saturation, {0.5}, s, "upper")).simulate(e, x0)(399, 0) == Approx(1.0).epsilon(1e-6));
  CHECK(base.with_effect(diag_test::effect(EffectKind::output_saturation, {1.5}, s, "upper")).simulate(e, x0)(399, 0) == Approx(1.5).epsilon(1e-9));
  CHECK(base.with_effect(diag_test::effect(EffectKind::input_deadzone, {0.4}, s)).simulate(e, x0)(399, 0) == Approx(1.2).epsilon(1e-6));
  // Dead time of 5 samples: the output stays at zero for 5 samples longer.
  const Eigen::MatrixXd yd = base.with_effect(diag_test::effect(EffectKind::dead_time, {0.05}, s)).simulate(e, x0);
  const Eigen::MatrixXd y0 = base.simulate(e, x0);
  CHECK(y0(11, 0) > 0.01);
  CHECK(yd(16, 0) == Approx(y0(11, 0)).epsilon(1e-9));
  CHECK(yd(15, 0) == Approx(0.0).margin(1e-12));
}

TEST_CASE("augmented model: a record at another sample time is refused, naming it", "[diagnose][augmented][errors]") {
  const physics::FirstOrder fo;
  AugmentedModel<physics::FirstOrder> m(fo, diag_test::table(fo, {{"tau", 0.1}, {"gain", 2.0}}), 0.01);
  const Eigen::MatrixXd u = Eigen::MatrixXd::Constant(50, 1, 1.0);
  const Experiment fast(u, Eigen::MatrixXd::Zero(50, 1), 0.001, "raw");
  const std::string msg = message_of([&] { (void)m.simulate(fast, Eigen::VectorXd::Zero(1)); });
  CHECK_THAT(msg, Catch::Contains("experiment 'raw' has sample time 0.001") && Catch::Contains("model's is 0.01"));
  // The same samples at the model's rate simulate.
  CHECK(m.simulate(Experiment(u, Eigen::MatrixXd::Zero(50, 1), 0.01), Eigen::VectorXd::Zero(1)).rows() == 50);
}

TEST_CASE("augmented model: the baseline physics' relations are checked (throttle stops crossed)",
          "[diagnose][augmented][errors]") {
  const physics::Throttle th;
  CHECK_THROWS_WITH((AugmentedModel<physics::Throttle>(th, diag_test::table(th, {{"lower_stop", 2.0}}), 0.01)),
                    Catch::Contains("the baseline's values") && Catch::Contains("must be below upper_stop"));
  AugmentedModel<physics::Throttle> m(th, diag_test::table(th, {}), 0.01);
  Eigen::VectorXd p = m.parameters();
  const std::vector<ParameterInfo> info = m.parameter_info();
  for (std::size_t i = 0; i < info.size(); ++i)
    if (info[i].name == "lower_stop") p[static_cast<Eigen::Index>(i)] = 2.0;
  CHECK_THROWS_WITH(m.set_parameters(p), Catch::Contains("set_parameters") && Catch::Contains("must be below upper_stop"));
  CHECK(m.parameters() != p);  // nothing was changed
}

TEST_CASE("augmented model: exact Jacobian equals central finite differences", "[diagnose][augmented][jacobian]") {
  const physics::MassSpringDamper msd;
  const double ts = 0.01;
  const DataScales s = msd_scales(ts);
  AugmentedModel<physics::MassSpringDamper> m(msd, diag_test::table(msd, {{"c", 8.0}, {"k", 100.0}, {"b", 100.0}}), ts);
  m.add_effect(diag_test::effect(EffectKind::cubic_stiffness, {30.0, 0.05}, s));
  m.add_effect(diag_test::effect(EffectKind::quadratic_drag, {0.05}, s));
  m.add_effect(diag_test::effect(EffectKind::dead_time, {0.023}, s));
  m.add_effect(diag_test::effect(EffectKind::actuator_lag, {0.02}, s));
  m.add_effect(diag_test::effect(EffectKind::preload, {5.0, 0.1}, s));
  m.add_effect(diag_test::effect(EffectKind::output_offset, {0.1}, s));
  const Eigen::MatrixXd u = diag_test::random_steps(300, -1.0, 1.0, 20, 60, 3u);
  Dataset d;
  d.add(Experiment(u, Eigen::MatrixXd::Zero(300, 1), ts, "a"));
  const AugmentedProblem<physics::MassSpringDamper> pb(m, d, true);
  std::vector<Eigen::VectorXd> x0{Eigen::Vector2d(0.2, -0.5)};
  const Eigen::VectorXd z = pb.pack(m.parameters(), x0);
  Eigen::VectorXd r(pb.num_residuals()), rp(r), rm(r);
  Eigen::MatrixXd J(pb.num_residuals(), pb.num_parameters());
  REQUIRE(pb.evaluate(z, r, &J));
  for (int j = 0; j < pb.num_parameters(); ++j) {
    const double h = 1e-6 * std::max(1.0, std::abs(z(j)));
    Eigen::VectorXd zp = z, zm = z;
    zp(j) += h;
    zm(j) -= h;
    REQUIRE(pb.evaluate(zp, rp, nullptr));
    REQUIRE(pb.evaluate(zm, rm, nullptr));
    const Eigen::VectorXd fd = (rp - rm) / (2 * h);
    INFO("column " << j << " (" << pb.names()[static_cast<std::size_t>(j)] << ")");
    CHECK((J.col(j) - fd).norm() <= 1e-5 * std::max(1.0, fd.norm()));
  }
}

TEST_CASE("refit: recovers a known effect parameter from noisy data", "[diagnose][refit]") {
  const physics::MassSpringDamper msd;
  const double ts = 0.01;
  const DataScales s = msd_scales(ts);
  const auto tab = diag_test::table(msd, {{"c", 8.0}, {"k", 100.0}, {"b", 100.0}});
  AugmentedModel<physics::MassSpringDamper> truth(msd, tab, ts / 4);
  truth.add_effect(diag_test::effect(EffectKind::cubic_stiffness, {40.0, 0.0}, s));
  const Eigen::MatrixXd u = diag_test::random_steps(1500, -1.0, 1.0, 40, 120, 9u);
  Dataset d;
  d.add(diag_test::synthesize(truth, u, ts, Eigen::Vector2d(0.0, 0.0), 0.005, 1u, "est", 4));
  AugmentedModel<physics::MassSpringDamper> m(msd, tab, ts);
  m.add_effect(diag_test::effect(EffectKind::cubic_stiffness, {0.0, 0.2}, s));
  const RefitResult r = refit(m, d, m.parameters(), {});
  REQUIRE(r.ok);
  CHECK(r.theta(4) == Approx(40.0).epsilon(0.05));
  CHECK(r.theta(1) == Approx(100.0).epsilon(0.02));
  // Data in absurd units are the caller's error, named - not a start that failed to simulate.
  nlid::Experiment big = d[0];
  big.y() *= 1e200;
  CHECK_THROWS_WITH(refit(m, Dataset{big}, m.parameters(), {}), Catch::Contains("refit: experiment 'est', output") &&
                                                                     Catch::Contains("beyond 1e100"));
}

TEST_CASE("augmented model: without a spectral radius the sub-steps cover the stiffest state of the run",
          "[diagnose][augmented]") {
  const nlid_test::UnratedPendulum pend;
  const double ts = 0.2;
  AugmentedModel<nlid_test::UnratedPendulum> m(pend, diag_test::table(pend, {}), ts);
  const Eigen::MatrixXd u = Eigen::MatrixXd::Zero(100, 1);
  const Eigen::Vector2d x0(1.5, 0.0);
  const Eigen::VectorXd theta = m.parameters();
  CHECK(m.substeps(theta.data(), x0.data(), u.row(0).data()) == 1);  // at the start
  CHECK(m.substeps(theta.data(), x0.data(), u) == 3);                // along the swing
  // The free run takes the run's count: it agrees with the plain grey box (same rule, same
  // RK4) and is close to a finely sub-stepped reference.
  const Experiment e(u, Eigen::MatrixXd::Zero(100, 1), ts);
  const Eigen::MatrixXd y = m.simulate(e, x0);
  GreyBox<nlid_test::UnratedPendulum> g;
  CHECK((y - g.simulate(u, ts, x0)).cwiseAbs().maxCoeff() < 1e-12);
  IntegratorOptions fine;
  fine.substeps = 400;
  g.set_integrator(fine);
  CHECK((y - g.simulate(u, ts, x0)).cwiseAbs().maxCoeff() < 5e-4);
}
