// Output-error models: Jacobian vs finite differences, known-answer recovery (noise-free exact,
// noisy within statistically justified tolerances), initial conditions, MISO, and errors.
#include <catch2/catch.hpp>

#include <cmath>
#include <limits>

#include "linear_test_util.hpp"
#include "nlid/linear/output_error.hpp"

using nlid::Experiment;
using nlid::InitialCondition;
using nlid::OutputError;

namespace {
Eigen::VectorXd vec(std::initializer_list<double> v) {
  Eigen::VectorXd x(static_cast<Eigen::Index>(v.size()));
  Eigen::Index k = 0;
  for (double d : v) x(k++) = d;
  return x;
}
// B = 0.5 + 0.3 q^-1, F = 1 - 1.6 q^-1 + 0.68 q^-2 (poles 0.8 +/- 0.2i), nk = 0: an OE [2 2 0].
OutputError truth_220(double c = 0.0) { return OutputError({vec({0.5, 0.3})}, {vec({-1.6, 0.68})}, {0}, 0.01, c); }

Experiment oe_data(const OutputError& m, const Eigen::MatrixXd& u, double snr_sd, unsigned seed,
                   const std::string& name = "sim") {
  const Experiment blank(u, Eigen::MatrixXd::Zero(u.rows(), 1), m.ts(), name);
  Eigen::MatrixXd y = m.simulate(blank, InitialCondition::zero);
  if (snr_sd > 0) {
    const double sd = snr_sd * std::sqrt((y.array() - y.mean()).square().mean());
    y += nlid_test::white_noise(u.rows(), 1, seed, sd);
  }
  return Experiment(u, y, m.ts(), name);
}
}  // namespace

TEST_CASE("OE analytic Jacobian matches central differences", "[linear][oe]") {
  const Experiment e1 = oe_data(truth_220(), nlid_test::white_noise(80, 1, 1), 0.1, 2, "a");
  const Experiment e2 = oe_data(truth_220(), nlid_test::white_noise(60, 1, 3), 0.1, 4, "b");
  const nlid::Dataset data{e1, e2};
  for (bool est_ic : {false, true}) {
    const nlid::detail::OePemProblem p(data, {2, 2, 1}, true, est_ic);
    Eigen::VectorXd th = Eigen::VectorXd::Zero(p.num_parameters());
    th.head(5) << 0.4, 0.2, -1.5, 0.6, 0.7;  // b0 b1 f1 f2 c
    for (Eigen::Index k = 5; k < th.size(); ++k) th(k) = 0.1 * static_cast<double>(k);
    Eigen::VectorXd r(p.num_residuals()), rp(p.num_residuals()), rm(p.num_residuals());
    Eigen::MatrixXd J(p.num_residuals(), p.num_parameters());
    REQUIRE(p.evaluate(th, r, &J));
    for (Eigen::Index k = 0; k < th.size(); ++k) {
      const double h = 1e-6;
      Eigen::VectorXd tp = th, tm = th;
      tp(k) += h;
      tm(k) -= h;
      REQUIRE(p.evaluate(tp, rp, nullptr));
      REQUIRE(p.evaluate(tm, rm, nullptr));
      const Eigen::VectorXd fd = (rp - rm) / (2 * h);
      CHECK((J.col(k) - fd).cwiseAbs().maxCoeff() < 1e-6 * std::max(1.0, fd.cwiseAbs().maxCoeff()));
    }
    // Outside the stability region the problem reports "not evaluable" so LM rejects the step.
    Eigen::VectorXd bad = th;
    bad(2) = -2.1;
    bad(3) = 1.2;
    CHECK_FALSE(p.evaluate(bad, r, nullptr));
  }
}

TEST_CASE("OE recovers B/F exactly from noise-free data", "[linear][oe]") {
  const OutputError truth = truth_220();
  const Experiment e = oe_data(truth, nlid_test::random_steps(600, 1, 5, 4), 0.0, 0);
  const OutputError m = nlid::oe(e, {2, 2, 0});
  CHECK((m.parameters() - truth.parameters()).cwiseAbs().maxCoeff() < 1e-8);
  CHECK(m.report().fit_percent > 99.999999);
  CHECK(m.is_stable());
  CHECK((m.f_polynomial() - vec({1.0, -1.6, 0.68})).norm() < 1e-8);
  CHECK(m.b(0).size() == 2);
  CHECK(m.f(0).size() == 2);
  CHECK(m.parameter_names() == std::vector<std::string>{"b0", "b1", "f1", "f2"});
}

TEST_CASE("OE on noisy data (SNR 20 dB, 5000 samples) within stated tolerances", "[linear][oe]") {
  // Tolerances: the asymptotic standard deviations at this SNR are about 0.1-0.3 % for f1, f2
  // and 1-3 % for b0, b1 (strongly correlated; their frequency response is far better
  // determined). We require every coefficient within 4 reported sigmas, F within 1 %, and the
  // frequency response within 2 % (relative, over the band up to half Nyquist).
  const OutputError truth = truth_220();
  const Experiment e = oe_data(truth, nlid_test::random_steps(5000, 1, 5, 4), 0.1, 6);
  const OutputError m = nlid::oe(e, {2, 2, 0});
  const Eigen::VectorXd err = m.parameters() - truth.parameters();
  const Eigen::VectorXd sd = m.parameter_stddev();
  for (Eigen::Index k = 0; k < err.size(); ++k) {
    CHECK(sd(k) > 0.0);
    CHECK(std::abs(err(k)) < 4.0 * sd(k));
  }
  CHECK(std::abs(err(2)) < 0.01 * 1.6);
  CHECK(std::abs(err(3)) < 0.01 * 0.68);
  const Eigen::VectorXd w = Eigen::VectorXd::LinSpaced(40, 0.5, 0.5 * M_PI / 0.01);
  const Eigen::VectorXcd g = truth.frequency_response(w), gh = m.frequency_response(w);
  CHECK(((gh - g).cwiseAbs().array() / g.cwiseAbs().array()).maxCoeff() < 0.02);
  CHECK(m.dc_gain() == Approx(truth.dc_gain()).epsilon(0.02));
  CHECK(m.report().fit_percent > 88.0);  // 20 dB of white noise leaves about 90 %
  CHECK(m.report().solver_message.find("converged") != std::string::npos);
  // An ARX fit of the same orders is biased on OE data: its poles are visibly off.
  const nlid::Arx a = nlid::arx(e, {2, 2, 0});
  CHECK((a.a() - truth.f(0)).cwiseAbs().maxCoeff() > 5.0 * sd(2));
}

TEST_CASE("OE with estimated initial state and offset", "[linear][oe]") {
  const OutputError truth = truth_220(15.0);
  const Experiment run = oe_data(truth, nlid_test::random_steps(900, 1, 7, 5), 0.0, 0);
  const Experiment e(run.u().bottomRows(500), run.y().bottomRows(500), 0.01, "mid");
  nlid::OeOptions opt;
  opt.offset = true;
  opt.initial_state = InitialCondition::estimate;
  const OutputError m = nlid::oe(e, {2, 2, 0}, opt);
  CHECK((m.parameters() - truth.parameters()).cwiseAbs().maxCoeff() < 1e-6);
  CHECK(m.offset() == Approx(15.0).epsilon(1e-8));
  CHECK((m.simulate(e, InitialCondition::estimate) - e.y()).cwiseAbs().maxCoeff() < 1e-6);
  CHECK((m.simulate(e, InitialCondition::measured) - e.y()).cwiseAbs().maxCoeff() < 1e-6);
  CHECK((m.predict(e, 1) - e.y()).cwiseAbs().maxCoeff() < 1e-6);
  CHECK((m.simulate(e, InitialCondition::zero) - e.y()).cwiseAbs().maxCoeff() > 0.01);
  // Zero initial conditions on the same data cannot be exact.
  opt.initial_state = InitialCondition::zero;
  CHECK(nlid::oe(e, {2, 2, 0}, opt).report().loss > 1e-8);
}

TEST_CASE("OE with two inputs, each with its own F", "[linear][oe]") {
  const OutputError truth({vec({0.5, 0.3}), vec({1.0})}, {vec({-1.6, 0.68}), vec({-0.5})}, {0, 2}, 0.01);
  Eigen::MatrixXd u(800, 2);
  u << nlid_test::random_steps(800, 1, 8, 4), nlid_test::white_noise(800, 1, 9);
  const Experiment e = oe_data(truth, u, 0.0, 0);
  const OutputError m = nlid::oe(e, nlid::OeOrders({2, 1}, {2, 1}, {0, 2}));
  CHECK((m.parameters() - truth.parameters()).cwiseAbs().maxCoeff() < 1e-6);
  CHECK(m.parameter_names()[2] == "b2_2");
  CHECK(m.parameter_names()[3] == "f1_1");
  CHECK(m.poles().size() == 3);
  // The block-diagonal state-space form simulates identically.
  const nlid::StateSpace ss = m.to_state_space();
  CHECK(ss.order() == 4);  // block orders max(nf, nk + nb - 1) = 2 and 2
  CHECK((ss.simulate(e, InitialCondition::zero) - m.simulate(e, InitialCondition::zero)).cwiseAbs().maxCoeff() < 1e-10);
}

TEST_CASE("OE standard deviations survive collinear initial-condition terms", "[linear][oe]") {
  // Two FIR blocks with estimated initial conditions: both blocks' free responses are the same
  // unit impulses, so their γ columns coincide and the full Jacobian is rank deficient. That
  // must not wipe out the B standard deviations (they were all 0, printed without +/-).
  Eigen::MatrixXd u(600, 2);
  u << nlid_test::white_noise(600, 1, 31), nlid_test::white_noise(600, 1, 32);
  const OutputError truth({vec({0.5, 0.3}), vec({-0.4, 0.2})}, {vec({}), vec({})}, {1, 1}, 0.01);
  Experiment e = oe_data(truth, u, 0.1, 33);
  nlid::OeOptions opt;
  opt.initial_state = InitialCondition::estimate;
  const OutputError m = nlid::oe(e, nlid::OeOrders({2, 2}, {0, 0}, {1, 1}), opt);
  const Eigen::VectorXd sd = m.parameter_stddev();
  REQUIRE(sd.size() == 4);
  for (Eigen::Index k = 0; k < sd.size(); ++k) {
    CHECK(std::isfinite(sd(k)));
    CHECK(sd(k) > 0.0);
    CHECK(std::abs(m.parameters()(k) - truth.parameters()(k)) < 5.0 * sd(k));
  }
  CHECK(m.describe().find("B1(q) = 0.") != std::string::npos);
  CHECK(m.describe().find(" (+/- ") != std::string::npos);
}

TEST_CASE("OE counts the initial-condition terms among the parameters", "[linear][oe][errors]") {
  // [2 2 2] with estimated initial conditions: 4 B/F + 3 γ per experiment. Three experiments of
  // 4 samples are 12 residuals for 13 parameters: an exact "100 %" fit if accepted.
  nlid::Dataset d, longer;
  for (unsigned k = 0; k < 3; ++k) {
    const Experiment x = oe_data(truth_220(), nlid_test::white_noise(6, 1, 40 + k), 0.1, 50 + k);
    d.add(Experiment(x.u().topRows(4), x.y().topRows(4), x.ts()));
    longer.add(x);
  }
  nlid::OeOptions opt;
  opt.initial_state = InitialCondition::estimate;
  CHECK_THROWS_WITH(nlid::oe(d, {2, 2, 2}, opt),
                    Catch::Contains("12 samples for 13 parameters (4 model + 9 initial-condition)"));
  CHECK(nlid::oe(longer, {2, 2, 2}, opt).report().num_parameters == 13);
}

TEST_CASE("OE describe and conversions", "[linear][oe]") {
  const OutputError m = truth_220(2.0);
  const std::string d = m.describe();
  CHECK(d.find("orders [nb nf nk] = [2 2 0]") != std::string::npos);
  CHECK(d.find("y(t) = [B(q)/F(q)]u(t) + c + e(t)") != std::string::npos);
  CHECK(d.find("F(q) = 1 - 1.6 q^-1 + 0.68 q^-2") != std::string::npos);
  CHECK(m.dc_gain() == Approx(0.8 / 0.08));
  const Experiment c(Eigen::MatrixXd::Constant(40, 1, 1.0), Eigen::MatrixXd::Zero(40, 1), 0.01);
  CHECK((m.simulate(c, InitialCondition::equilibrium).array() - 12.0).abs().maxCoeff() < 1e-9);
  const Eigen::VectorXd w = Eigen::VectorXd::LinSpaced(5, 1.0, 200.0);
  CHECK((m.to_state_space().frequency_response(w) - m.frequency_response(w)).cwiseAbs().maxCoeff() < 1e-10);
}

TEST_CASE("OE rejects bad orders and data with located messages", "[linear][oe]") {
  const Experiment e = oe_data(truth_220(), nlid_test::white_noise(100, 1, 10), 0.0, 0, "good");
  CHECK_THROWS_WITH(nlid::oe(e, {0, 2, 0}), Catch::Contains("nb must be >= 1"));
  CHECK_THROWS_WITH(nlid::oe(e, {2, -1, 0}), Catch::Contains("nf must be >= 0"));
  CHECK_THROWS_WITH(nlid::oe(e, {2, 2, -3}), Catch::Contains("nk must be >= 0"));
  CHECK_THROWS_WITH(nlid::oe(e, nlid::OeOrders({2, 2}, {2, 2}, {0, 0})), Catch::Contains("for 2 input(s) but the data have 1"));
  const Experiment s(e.u().topRows(2), e.y().topRows(2), 0.01, "stub");
  try {
    (void)nlid::oe(nlid::Dataset{e, s}, {2, 2, 0});
    FAIL("short experiment accepted");
  } catch (const nlid::Error& err) {
    CHECK(std::string(err.what()).find("experiment 1 ('stub') has 2 samples") != std::string::npos);
    CHECK(err.where().experiment == 1);
  }
  nlid::OeOptions opt;
  opt.initial_state = InitialCondition::equilibrium;
  CHECK_THROWS_WITH(nlid::oe(e, {2, 2, 0}, opt), Catch::Contains("initial_state"));
  // Mis-scaled data: named, where the overflowing squares read "rank 2 < 4 parameters".
  const Experiment big(e.u(), 1e200 * e.y(), 0.01, "big");
  CHECK_THROWS_WITH(nlid::oe(big, {2, 2, 0}), Catch::Contains("oe: experiment 'big', output 'y'") && Catch::Contains("beyond 1e100"));
  const OutputError two({vec({1.0}), vec({1.0})}, {vec({-0.5}), vec({-0.5})}, {0, 0}, 0.01);
  const Experiment e2(Eigen::MatrixXd::Random(20, 2), Eigen::MatrixXd::Random(20, 1), 0.01);
  CHECK_THROWS_WITH(two.simulate(e2, InitialCondition::measured), Catch::Contains("one input only"));
}

TEST_CASE("OE parameter standard deviations: set, and refused when malformed", "[linear][oe][errors]") {
  OutputError o = truth_220();
  const Eigen::VectorXd sdo = Eigen::VectorXd::Constant(o.num_parameters(), 0.5);
  o.set_parameter_stddev(sdo);
  CHECK(o.parameter_stddev() == sdo);
  Eigen::VectorXd bado = sdo;
  bado(3) = std::numeric_limits<double>::quiet_NaN();
  CHECK_THROWS_WITH(o.set_parameter_stddev(bado),
                    Catch::Contains("OutputError: the standard deviation of " + o.parameter_names()[3] + " (entry 3)"));
  // +inf is how an estimate says "the data do not determine this parameter".
  Eigen::VectorXd inf = sdo;
  inf(3) = std::numeric_limits<double>::infinity();
  o.set_parameter_stddev(inf);
  CHECK(o.describe().find("(not identifiable)") != std::string::npos);
  CHECK(o.describe().find("inf") == std::string::npos);
  CHECK_THROWS_WITH(o.set_parameter_stddev(Eigen::VectorXd::Zero(1)), Catch::Contains("OutputError: 1 standard deviations"));
}
