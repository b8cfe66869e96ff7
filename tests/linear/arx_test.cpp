// ARX: known-answer recovery (SISO, MISO, multi-experiment), prediction, simulation initial
// conditions, state-space conversion, and located errors for bad input.
#include <catch2/catch.hpp>

#include <cmath>
#include <limits>
#include <locale>
#include <sstream>
#include <string>
#include <vector>

#include "../support/error_of.hpp"
#include "linear_test_util.hpp"
#include "nlid/analysis/fit.hpp"
#include "nlid/linear/arx.hpp"
#include "nlid/linear/order_selection.hpp"
#include "nlid/linear/output_error.hpp"

using nlid::Arx;
using nlid::Experiment;
using nlid::InitialCondition;

namespace {
Eigen::VectorXd vec(std::initializer_list<double> v) {
  Eigen::VectorXd x(static_cast<Eigen::Index>(v.size()));
  Eigen::Index k = 0;
  for (double d : v) x(k++) = d;
  return x;
}
// A(q) = 1 - 1.5 q^-1 + 0.7 q^-2 (poles 0.75 +/- 0.37i), B(q) = q^-1 (1 + 0.5 q^-1), c = 0.3.
Arx siso_truth(double c = 0.0) { return Arx(vec({-1.5, 0.7}), {vec({1.0, 0.5})}, {1}, 0.1, c); }
}  // namespace

TEST_CASE("ARX recovers a SISO system exactly from noise-free data", "[linear][arx]") {
  const Arx truth = siso_truth();
  const Experiment e = nlid_test::arx_data(truth, nlid_test::white_noise(400, 1, 1), 0.0, 0);
  const Arx m = nlid::arx(e, {2, 2, 1});
  CHECK((m.parameters() - truth.parameters()).cwiseAbs().maxCoeff() < 1e-8);
  CHECK(m.report().fit_percent == Approx(100.0));
  CHECK(m.report().num_samples == 398);  // rows t = 2 ... 399
  CHECK(m.report().num_parameters == 4);
  CHECK(m.ts() == 0.1);
  CHECK((m.a_polynomial() - vec({1.0, -1.5, 0.7})).norm() < 1e-8);
  CHECK((m.b_polynomial() - vec({0.0, 1.0, 0.5})).norm() < 1e-8);
}

TEST_CASE("ARX with offset recovers the constant", "[linear][arx]") {
  const Arx truth = siso_truth(0.3);
  const Experiment e = nlid_test::arx_data(truth, nlid_test::random_steps(300, 1, 2), 0.0, 0);
  const Arx m = nlid::arx(e, {2, 2, 1}, {.offset = true});
  REQUIRE(m.has_offset());
  CHECK(std::abs(m.offset() - 0.3) < 1e-8);
  CHECK((m.parameters() - truth.parameters()).cwiseAbs().maxCoeff() < 1e-8);
  CHECK(m.parameter_names() == std::vector<std::string>{"a1", "a2", "b1", "b2", "c"});
  // Without the offset term the same data cannot be fitted exactly.
  const Arx biased = nlid::arx(e, {2, 2, 1});
  CHECK(biased.report().loss > 1e-6);
}

TEST_CASE("ARX recovers a two-input system with its own nb and nk per input", "[linear][arx]") {
  const Arx truth(vec({-0.9, 0.2}), {vec({0.5, -0.3, 0.1}), vec({2.0})}, {0, 3}, 0.05);
  const Experiment e = nlid_test::arx_data(truth, nlid_test::white_noise(500, 2, 5), 0.0, 0);
  const nlid::ArxOrders o(2, {3, 1}, {0, 3});
  CHECK(o.str() == "[2 [3 1] [0 3]]");
  const Arx m = nlid::arx(e, o);
  CHECK((m.parameters() - truth.parameters()).cwiseAbs().maxCoeff() < 1e-8);
  CHECK(m.nk(1) == 3);
  CHECK(m.nb(0) == 3);
  CHECK(m.parameter_names()[2] == "b1_0");
  CHECK(m.parameter_names()[5] == "b2_3");
  CHECK((m.b_polynomial(1) - vec({0, 0, 0, 2.0})).norm() < 1e-8);
}

TEST_CASE("ARX on multi-experiment data builds regressors per experiment", "[linear][arx]") {
  const Arx truth = siso_truth();
  // Two records of one system that start from different (nonzero) past states: the second is
  // cut from the middle of a longer run.
  const Experiment e1 = nlid_test::arx_data(truth, nlid_test::white_noise(300, 1, 7), 0.0, 0, "e1");
  const Experiment long_run = nlid_test::arx_data(truth, nlid_test::white_noise(600, 1, 8), 0.0, 0);
  const Experiment e2(long_run.u().bottomRows(250), long_run.y().bottomRows(250), 0.1, "e2");
  const nlid::Dataset data{e1, e2};
  const Arx m = nlid::arx(data, {2, 2, 1});
  CHECK((m.parameters() - truth.parameters()).cwiseAbs().maxCoeff() < 1e-8);
  CHECK(m.report().num_experiments == 2);
  CHECK(m.report().num_samples == (300 - 2) + (250 - 2));
  // Gluing the records end to end creates rows that straddle the seam: no longer exact.
  Eigen::MatrixXd u(550, 1), y(550, 1);
  u << e1.u(), e2.u();
  y << e1.y(), e2.y();
  const Arx glued = nlid::arx(Experiment(u, y, 0.1), {2, 2, 1});
  CHECK((glued.parameters() - truth.parameters()).cwiseAbs().maxCoeff() > 1e-4);
}

TEST_CASE("ARX on noisy data: estimates within their standard deviations", "[linear][arx]") {
  const Arx truth = siso_truth();
  const Experiment e = nlid_test::arx_data(truth, nlid_test::white_noise(4000, 1, 11), 0.2, 12);
  const Arx m = nlid::arx(e, {2, 2, 1});
  const Eigen::VectorXd err = m.parameters() - truth.parameters();
  const Eigen::VectorXd sd = m.parameter_stddev();
  for (Eigen::Index k = 0; k < err.size(); ++k) {
    CHECK(sd(k) > 0.0);
    CHECK(sd(k) < 0.05);
    CHECK(std::abs(err(k)) < 4.0 * sd(k));
  }
  CHECK(m.report().loss == Approx(0.04).epsilon(0.1));  // V estimates the noise variance 0.2^2
}

TEST_CASE("ARX parameter standard deviations: set, and refused when malformed", "[linear][arx][errors]") {
  Arx a = siso_truth();
  const std::vector<std::string> names = a.parameter_names();
  Eigen::VectorXd sd = Eigen::VectorXd::LinSpaced(a.num_parameters(), 0.0, 0.3);
  a.set_parameter_stddev(sd);
  CHECK(a.parameter_stddev() == sd);
  CHECK_THROWS_WITH(a.set_parameter_stddev(Eigen::VectorXd::Zero(a.num_parameters() + 1)),
                    Catch::Contains("Arx: " + std::to_string(a.num_parameters() + 1) + " standard deviations for " +
                                    std::to_string(a.num_parameters()) + " parameters"));
  Eigen::VectorXd bad = sd;
  bad(1) = std::numeric_limits<double>::quiet_NaN();
  CHECK_THROWS_WITH(a.set_parameter_stddev(bad),
                    Catch::Contains("Arx: the standard deviation of " + names[1] + " (entry 1) must be finite and >= 0"));
  bad = sd;
  bad(0) = -1e-3;
  CHECK_THROWS_WITH(a.set_parameter_stddev(bad), Catch::Contains("of " + names[0] + " (entry 0)"));
  CHECK(a.parameter_stddev() == sd);  // a refused vector leaves the old one
  bad = sd;
  bad(2) = std::numeric_limits<double>::infinity();  // "not identifiable": accepted and said so
  a.set_parameter_stddev(bad);
  CHECK(a.describe().find("(not identifiable)") != std::string::npos);
}

TEST_CASE("Least squares marks undetermined parameters, keeps the determined ones' variance", "[linear][arx]") {
  // Columns 1 and 2 are equal: only their sum is determined. Column 0 is orthogonal to both, so
  // its variance must be what a fit without the duplicate gives, not 0 and not +inf.
  const Eigen::MatrixXd x = nlid_test::white_noise(50, 2, 81);
  Eigen::MatrixXd phi(50, 3);
  phi << x.col(0), x.col(1), x.col(1);
  Eigen::MatrixXd reduced(50, 2);
  reduced << x.col(0), x.col(1);
  const Eigen::VectorXd y = nlid_test::white_noise(50, 1, 82).col(0);
  const nlid::detail::LeastSquaresSolution full = nlid::detail::solve_least_squares_qr(reduced, y);
  const nlid::detail::LeastSquaresSolution dup = nlid::detail::solve_least_squares_qr(phi, y);
  CHECK(dup.rank == 2);
  CHECK(dup.unscaled_variance(0) == Approx(full.unscaled_variance(0)).epsilon(1e-10));
  CHECK(std::isinf(dup.unscaled_variance(1)));
  CHECK(std::isinf(dup.unscaled_variance(2)));
  const Eigen::VectorXd sd = nlid::detail::stddev_from_variance(0.0, dup.unscaled_variance);
  CHECK(sd(0) == 0.0);
  CHECK(std::isinf(sd(1)));  // not NaN from 0 * inf
}

TEST_CASE("ARX one-step prediction of noise-free data equals the measurement", "[linear][arx]") {
  const Arx truth = siso_truth(0.3);
  const Experiment e = nlid_test::arx_data(truth, nlid_test::white_noise(200, 1, 21), 0.0, 0);
  CHECK((truth.predict(e, 1) - e.y()).cwiseAbs().maxCoeff() < 1e-12);
  CHECK((truth.predict(e, 7) - e.y()).cwiseAbs().maxCoeff() < 1e-10);
}

TEST_CASE("ARX k-step prediction runs the model k steps from measured data", "[linear][arx]") {
  const Arx truth = siso_truth();
  const Experiment e = nlid_test::arx_data(truth, nlid_test::white_noise(120, 1, 31), 0.5, 32);
  const int k = 4;
  const Eigen::MatrixXd p = truth.predict(e, k);
  const int n = 2;
  CHECK((p.topRows(n) - e.y().topRows(n)).norm() == 0.0);  // measured past data
  // Independent route: simulate (measured past) a window ending at t that starts n samples
  // before t - k + 1; its last value is y(t | t - k).
  for (Eigen::Index t = 10; t < 120; t += 9) {
    const Eigen::Index s = t - k + 1 - n;
    const Experiment w(e.u().middleRows(s, n + k), e.y().middleRows(s, n + k), 0.1);
    const Eigen::MatrixXd sim = truth.simulate(w, InitialCondition::measured);
    CHECK(p(t, 0) == Approx(sim(n + k - 1, 0)).epsilon(1e-12));
  }
  // The one-step predictor is phi(t)' theta.
  const Eigen::MatrixXd p1 = truth.predict(e, 1);
  const auto& y = e.y();
  const auto& u = e.u();
  for (Eigen::Index t = 2; t < 120; ++t)
    CHECK(p1(t, 0) == Approx(1.5 * y(t - 1, 0) - 0.7 * y(t - 2, 0) + u(t - 1, 0) + 0.5 * u(t - 2, 0)));
  // An infinite horizon is the simulation from measured past data; so is k >= N.
  CHECK((truth.predict(e, nlid::infinite_horizon) - truth.simulate(e, InitialCondition::measured)).norm() == 0.0);
  CHECK((truth.predict(e, 500) - truth.simulate(e, InitialCondition::measured)).norm() == 0.0);
  // Prediction gets worse with the horizon on noisy data.
  CHECK(nlid::fit_percent(e.y().col(0), truth.predict(e, 1).col(0)) >
        nlid::fit_percent(e.y().col(0), truth.predict(e, 10).col(0)));
}

TEST_CASE("ARX simulation initial conditions", "[linear][arx]") {
  const Arx truth = siso_truth(0.3);
  const Experiment run = nlid_test::arx_data(truth, nlid_test::white_noise(500, 1, 41), 0.0, 0);
  // A record that starts mid-run: unknown, nonzero past.
  const Experiment e(run.u().bottomRows(300), run.y().bottomRows(300), 0.1);
  const Eigen::MatrixXd zero = truth.simulate(e, InitialCondition::zero);
  const Eigen::MatrixXd est = truth.simulate(e, InitialCondition::estimate);
  const Eigen::MatrixXd meas = truth.simulate(e, InitialCondition::measured);
  CHECK((est - e.y()).cwiseAbs().maxCoeff() < 1e-9);
  CHECK((meas - e.y()).cwiseAbs().maxCoeff() < 1e-9);
  CHECK((zero - e.y()).cwiseAbs().maxCoeff() > 0.1);  // transient of the wrong start
  // Equilibrium: a constant input from rest at the matching steady state stays put.
  const Eigen::MatrixXd uc = Eigen::MatrixXd::Constant(50, 1, 2.0);
  const Experiment c(uc, Eigen::MatrixXd::Zero(50, 1), 0.1);
  const Eigen::MatrixXd eq = truth.simulate(c, InitialCondition::equilibrium);
  const double yss = (2.0 * 1.5 + 0.3) / (1 - 1.5 + 0.7);
  CHECK((eq.array() - yss).abs().maxCoeff() < 1e-9);
  CHECK(truth.dc_gain() == Approx(1.5 / 0.2));
}

TEST_CASE("ARX and OE refuse an estimated initial state whose free response overflows", "[linear][arx][errors]") {
  // A pole at 1.5: 1/A's impulse response passes 1e150 after about 850 samples, and the fitted
  // initial state, then the whole simulation, came back NaN without a word.
  const Arx unstable(vec({-1.5}), {vec({1.0})}, {0}, 0.1);
  const Experiment e(nlid_test::white_noise(2000, 1, 95), nlid_test::white_noise(2000, 1, 96), 0.1);
  CHECK_THROWS_WITH(unstable.simulate(e, InitialCondition::estimate),
                    Catch::Contains("Arx::simulate: InitialCondition::estimate needs the free response of 1/A(q)") &&
                        Catch::Contains("A(q) is unstable (a pole at |z| = 1.5)"));
  const Experiment s(e.u().topRows(100), e.y().topRows(100), 0.1);
  CHECK(unstable.simulate(s, InitialCondition::estimate).allFinite());
  const nlid::OutputError oe({vec({1.0}), vec({0.5})}, {vec({-0.5}), vec({-1.5})}, {0, 0}, 0.1);
  const Experiment two(nlid_test::white_noise(2000, 2, 97), nlid_test::white_noise(2000, 1, 98), 0.1);
  CHECK_THROWS_WITH(oe.simulate(two, InitialCondition::estimate),
                    Catch::Contains("free response of 1/F2(q)") && Catch::Contains("|z| = 1.5"));
}

TEST_CASE("ARX converts to state space with the same input-output behaviour", "[linear][arx]") {
  const Arx truth(vec({-0.9, 0.2}), {vec({0.5, -0.3, 0.1}), vec({2.0})}, {0, 3}, 0.05);
  const nlid::StateSpace ss = truth.to_state_space();
  CHECK(ss.order() == 3);
  const Experiment e(nlid_test::white_noise(100, 2, 51), Eigen::MatrixXd::Zero(100, 1), 0.05);
  CHECK((ss.simulate(e, InitialCondition::zero) - truth.simulate(e, InitialCondition::zero)).cwiseAbs().maxCoeff() < 1e-12);
  const Eigen::VectorXd w = Eigen::VectorXd::LinSpaced(9, 0.5, 60.0);
  for (int i = 0; i < 2; ++i)
    CHECK((ss.frequency_response(w, 0, i) - truth.frequency_response(w, i)).cwiseAbs().maxCoeff() < 1e-10);
  const nlid::TransferFunction tf = truth.to_transfer_function(1);
  CHECK((tf.numerator - vec({0, 0, 0, 2.0})).norm() == 0.0);
}

TEST_CASE("ARX describe prints A(q) and B(q) like the toolbox", "[linear][arx]") {
  const Experiment e = nlid_test::arx_data(siso_truth(), nlid_test::white_noise(300, 1, 61), 0.0, 0);
  const std::string d = nlid::arx(e, {2, 2, 1}).describe();
  CHECK(d.find("orders [na nb nk] = [2 2 1]") != std::string::npos);
  CHECK(d.find("A(q)y(t) = B(q)u(t) + e(t)") != std::string::npos);
  CHECK(d.find("A(q) = 1 - 1.5") != std::string::npos);
  CHECK(d.find("q^-2") != std::string::npos);
  CHECK(d.find("B(q) = 1 (+/- ") != std::string::npos);
  CHECK(d.find("Poles: 0.75 +/- 0.3708i") != std::string::npos);
  CHECK(d.find("Sample time: 0.1 s") != std::string::npos);
}

namespace {
// A numeric punctuation as a German program might install globally: decimal comma, '.' between
// groups of three digits.
struct ArxTestCommaGrouping : std::numpunct<char> {
  char do_decimal_point() const override { return ','; }
  char do_thousands_sep() const override { return '.'; }
  std::string do_grouping() const override { return "\3"; }
};
}  // namespace

TEST_CASE("ARX and state-space text does not follow the program's global C++ locale", "[linear][arx]") {
  // The text went through std::ostringstream, which takes the global locale: after
  // std::locale::global(de_DE) the report read "1.998 samples" and the matrices "0,75".
  const Experiment e = nlid_test::arx_data(siso_truth(), nlid_test::white_noise(2000, 1, 62), 0.0, 0);
  const nlid::Arx m = nlid::arx(e, {2, 2, 1});
  const std::string arx_text = m.describe();
  const std::string ss_text = m.to_state_space().describe();
  REQUIRE_THAT(arx_text, Catch::Contains("1998 samples"));
  const std::locale saved = std::locale::global(std::locale(std::locale::classic(), new ArxTestCommaGrouping));
  const std::string arx_local = m.describe();
  const std::string ss_local = m.to_state_space().describe();
  std::ostringstream probe;  // the locale is in effect: a stream made now groups digits
  probe << 1998;
  std::locale::global(saved);
  CHECK(probe.str() == "1.998");
  CHECK(arx_local == arx_text);
  CHECK(ss_local == ss_text);
}

TEST_CASE("ARX and OE describe name the degree instead of factoring a huge A or F", "[linear][arx]") {
  // Found by tests/fuzz/spec_fuzz.cpp: describe() of linear:arx:na=54096 (a valid order) built
  // the 54096 x 54096 companion matrix of A, 23 GB, to list the poles.
  Eigen::VectorXd a_high = Eigen::VectorXd::Zero(600);
  a_high(0) = -0.5;
  const Arx arx_high(a_high, {vec({1.0})}, {1}, 0.1);
  CHECK_THAT(arx_high.describe(), Catch::Contains("Poles: not listed (degree 600, above 500)"));
  CHECK(arx_high.poles().size() == 600);  // asked for explicitly, they are still computed
  CHECK_THAT(Arx(vec({-0.5}), {vec({1.0})}, {1}, 0.1).describe(), Catch::Contains("Poles: 0.5\n"));
  const nlid::OutputError oe_high({vec({1.0})}, {a_high}, {0}, 0.1);
  CHECK_THAT(oe_high.describe(), Catch::Contains("Poles: not listed (degree 600, above 500)"));
  CHECK_THAT(nlid::OutputError({vec({1.0})}, {vec({-0.5})}, {0}, 0.1).describe(), Catch::Contains("Poles: 0.5\n"));
}

TEST_CASE("ARX rejects bad orders and data with located messages", "[linear][arx]") {
  const Experiment e = nlid_test::arx_data(siso_truth(), nlid_test::white_noise(100, 1, 71), 0.0, 0, "good");
  SECTION("negative orders") {
    CHECK_THROWS_WITH(nlid::arx(e, {-1, 2, 1}), Catch::Contains("na must be >= 0"));
    CHECK_THROWS_WITH(nlid::arx(e, {2, -2, 1}), Catch::Contains("nb must be >= 0"));
    CHECK_THROWS_WITH(nlid::arx(e, {2, 2, -1}), Catch::Contains("nk must be >= 0"));
    try {
      (void)nlid::arx(e, {2, 2, -1});
    } catch (const nlid::Error& err) {
      CHECK(err.where().parameter == "nk");
    }
  }
  SECTION("no parameters") { CHECK_THROWS_WITH(nlid::arx(e, {0, 0, 0}), Catch::Contains("no parameter")); }
  SECTION("data too short names the experiment") {
    const Experiment s(e.u().topRows(2), e.y().topRows(2), 0.1, "short");
    try {
      (void)nlid::arx(nlid::Dataset{e, s}, {2, 2, 1});
      FAIL("short experiment accepted");
    } catch (const nlid::Error& err) {
      CHECK(std::string(err.what()).find("experiment 1 ('short') has 2 samples") != std::string::npos);
      CHECK(err.where().experiment == 1);
    }
  }
  SECTION("mismatched channel counts") {
    CHECK_THROWS_WITH(nlid::arx(e, nlid::ArxOrders(2, {1, 1}, {0, 0})),
                      Catch::Contains("for 2 input(s) but the data have 1"));
    CHECK_THROWS_WITH(nlid::arx(e, nlid::ArxOrders(2, {1, 1}, {0})), Catch::Contains("nb has 2 entries but nk has 1"));
    const Experiment two_out(e.u(), Eigen::MatrixXd::Random(100, 2), 0.1);
    CHECK_THROWS_WITH(nlid::arx(two_out, {2, 2, 1}), Catch::Contains("data have 2"));
    const Experiment two_in(Eigen::MatrixXd::Random(100, 2), e.y(), 0.1, "two");
    CHECK_THROWS_WITH(siso_truth().simulate(two_in), Catch::Contains("model has 1 input(s) but experiment 'two' has 2"));
  }
  SECTION("mis-scaled channels: the channel, not a rank deficiency") {
    // The squares of 1e200 overflowed and arx reported "rank 1 < 4 parameters".
    const Experiment big(e.u(), 1e200 * e.y(), 0.1, "big");
    const nlid::Error a = nlid_test::error_of([&] { (void)nlid::arx(nlid::Dataset{e, big}, {2, 2, 1}); });
    CHECK_THAT(std::string(a.what()), Catch::Contains("arx: experiment 'big', output 'y'") && Catch::Contains("beyond 1e100"));
    CHECK(a.where().experiment == 1);
    const Experiment tiny(1e-200 * e.u(), e.y(), 0.1, "tiny");
    CHECK_THROWS_WITH(nlid::arx(tiny, {2, 2, 1}), Catch::Contains("input 'u'") && Catch::Contains("below 1e-100"));
    CHECK_THROWS_WITH(nlid::arx_order_selection(nlid::Dataset{big}), Catch::Contains("beyond 1e100"));
    CHECK_THROWS_WITH(nlid::arx_order_selection(nlid::Dataset{e}, nlid::Dataset{big}),
                      Catch::Contains("arx_order_selection (validation data): experiment 'big'") && Catch::Contains("beyond 1e100"));
  }
  SECTION("not persistently exciting") {
    const Experiment c(Eigen::MatrixXd::Constant(100, 1, 1.0), e.y(), 0.1);
    CHECK_THROWS_WITH(nlid::arx(c, {2, 2, 1}), Catch::Contains("rank"));
  }
  SECTION("missing samples") {
    Eigen::MatrixXd y = e.y();
    y(40, 0) = std::nan("");
    const Experiment m(e.u(), y, 0.1, "gappy", nlid::NonFinitePolicy::keep);
    CHECK_THROWS_WITH(nlid::arx(m, {2, 2, 1}), Catch::Contains("missing") && Catch::Contains("index 40"));
  }
  SECTION("prediction horizon and sample time") {
    CHECK_THROWS_WITH(siso_truth().predict(e, 0), Catch::Contains("k must be >= 1"));
    const Experiment other(e.u(), e.y(), 0.01, "fast");
    CHECK_THROWS_WITH(siso_truth().simulate(other), Catch::Contains("sample time"));
  }
  SECTION("as many regression rows as parameters") {
    // [1 2 1]: 3 parameters, largest lag 2, so N samples give N - 2 rows.
    const Experiment s(e.u().topRows(4), e.y().topRows(4), 0.1, "four");
    CHECK_THROWS_WITH(nlid::arx(s, {1, 2, 1}), Catch::Contains("2 regression rows for 3 parameters"));
    // Exactly as many rows as parameters would fit exactly: refused too, not 100 % and sd 0.
    const Experiment t(e.u().topRows(5), e.y().topRows(5), 0.1, "five");
    CHECK_THROWS_WITH(nlid::arx(t, {1, 2, 1}), Catch::Contains("3 regression rows for 3 parameters"));
    CHECK(nlid::arx(Experiment(e.u().topRows(6), e.y().topRows(6), 0.1), {1, 2, 1}).report().num_samples == 4);
  }
  SECTION("empty data set") { CHECK_THROWS_WITH(nlid::arx(nlid::Dataset{}, {2, 2, 1}), Catch::Contains("empty")); }
}

TEST_CASE("linear models refuse a record whose channels carry their names in another order", "[linear][errors]") {
  // Models read channels by position: a record read as {temp, flow} ran a {flow, temp} model on
  // swapped inputs without a word (found by a multi-input review).
  Eigen::MatrixXd u(40, 2);
  for (Eigen::Index k = 0; k < 40; ++k) u.row(k) << std::sin(0.3 * static_cast<double>(k)), (k / 7) % 2;
  Experiment e(u, Eigen::VectorXd::Zero(40), 1.0, "rec");
  Arx arx(vec({-0.5}), {vec({1.0}), vec({0.5})}, {1, 1}, 1.0);
  arx.set_input_names({"flow", "temp"});
  e.set_input_names({"temp", "flow"});
  CHECK_THROWS_WITH(arx.simulate(e), Catch::Contains("Arx::simulate: experiment 'rec' has the inputs {temp, flow} but the model "
                                                     "reads {flow, temp} in that order"));
  CHECK_THROWS_WITH(arx.predict(e, 1), Catch::Contains("Arx::predict") && Catch::Contains("reorder them (select_channels)"));
  nlid::OutputError oe({vec({1.0}), vec({0.5})}, {vec({-0.5}), vec({-0.5})}, {1, 1}, 1.0);
  oe.set_input_names({"flow", "temp"});
  CHECK_THROWS_WITH(oe.simulate(e), Catch::Contains("OutputError::simulate") && Catch::Contains("{temp, flow}"));
  // Other names, defaults or the same order pass: only a reordering is certain to be a mistake.
  e.set_input_names({"a", "b"});
  CHECK(arx.simulate(e).rows() == 40);
  e.set_input_names({"flow", "temp"});
  CHECK(oe.simulate(e).rows() == 40);
  // Default names count too: a model estimated on a CSV's u1, u2, run on the file read as {u2, u1}.
  Arx plain(vec({-0.5}), {vec({1.0}), vec({0.5})}, {1, 1}, 1.0);
  plain.set_input_names({"u1", "u2"});
  e.set_input_names({"u2", "u1"});
  CHECK_THROWS_WITH(plain.simulate(e), Catch::Contains("has the inputs {u2, u1} but the model reads {u1, u2}"));
  // A model built by hand has no names: nothing to compare.
  const Arx unnamed(vec({-0.5}), {vec({1.0}), vec({0.5})}, {1, 1}, 1.0);
  CHECK(unnamed.simulate(e).rows() == 40);
  // Two outputs of a state-space model, swapped.
  nlid::StateSpace ss(Eigen::MatrixXd::Identity(2, 2) * 0.5, Eigen::MatrixXd::Identity(2, 2), Eigen::MatrixXd::Identity(2, 2),
                      Eigen::MatrixXd::Zero(2, 2), 1.0);
  ss.set_output_names({"level", "pressure"});
  Experiment two(u, Eigen::MatrixXd::Zero(40, 2), 1.0, "two");
  two.set_output_names({"pressure", "level"});
  CHECK_THROWS_WITH(ss.simulate(two), Catch::Contains("has the outputs {pressure, level} but the model reads {level, pressure}"));
}
