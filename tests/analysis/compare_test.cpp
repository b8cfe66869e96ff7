// compare(): fit per experiment and output for any SimulationModel, tables, located errors.
#include <catch2/catch.hpp>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "nlid/analysis/compare.hpp"
#include "nlid/linear/arx.hpp"
#include "nlid/linear/output_error.hpp"
#include "nlid/linear/state_space.hpp"
#include "../support/decimal_comma_locale.hpp"

namespace {
// A toy model: output = gain * input (one column per input), for testing compare itself.
struct Gain {
  double g = 1.0;
  Eigen::MatrixXd simulate(const nlid::Experiment& e, nlid::InitialCondition) const { return g * e.u(); }
};
// A model that returns the wrong shape.
struct Broken {
  Eigen::MatrixXd simulate(const nlid::Experiment& e, nlid::InitialCondition) const {
    return Eigen::MatrixXd::Zero(e.size() + 1, 1);
  }
};
// Diverges on the experiment named "unstable" (at sample 7), fails otherwise on "broken".
struct SometimesDiverging {
  Eigen::MatrixXd simulate(const nlid::Experiment& e, nlid::InitialCondition) const {
    if (e.name() == "unstable") throw nlid::DivergenceError("simulation of 'unstable' diverges", 7);
    if (e.name() == "broken") throw nlid::Error("the model cannot read this record");
    return 2.0 * e.u();
  }
};
// Returns inf/NaN from sample 4 on (a model that lets an unstable simulation overflow).
struct Overflowing {
  Eigen::MatrixXd simulate(const nlid::Experiment& e, nlid::InitialCondition) const {
    Eigen::MatrixXd y = e.u();
    y.bottomRows(y.rows() - 4).setConstant(std::numeric_limits<double>::quiet_NaN());
    y(4, 0) = std::numeric_limits<double>::infinity();
    return y;
  }
};
struct NotAModel {
  int simulate(int) const { return 0; }
};
static_assert(nlid::SimulationModel<Gain>);
static_assert(nlid::SimulationModel<nlid::Arx>);
static_assert(nlid::SimulationModel<nlid::OutputError>);
static_assert(nlid::SimulationModel<nlid::StateSpace>);
static_assert(!nlid::SimulationModel<NotAModel>);
static_assert(!nlid::SimulationModel<double>);

Eigen::MatrixXd ramp(int n, double scale) {
  Eigen::MatrixXd x(n, 1);
  for (int k = 0; k < n; ++k) x(k, 0) = scale * k;
  return x;
}
}  // namespace

TEST_CASE("compare scores each experiment with the normalised fit", "[analysis][compare]") {
  // y = 2u; model with gain 2 is perfect, gain 1 gives a known fit.
  const nlid::Experiment a(ramp(10, 1.0), ramp(10, 2.0), 0.1, "a");
  const nlid::Experiment b(ramp(20, -1.0), ramp(20, -2.0), 0.1, "b");
  const nlid::Dataset data{a, b};
  const nlid::CompareResult perfect = nlid::compare(Gain{2.0}, data);
  CHECK(perfect.fit(0, 0) == Approx(100.0));
  CHECK(perfect.fit(1, 0) == Approx(100.0));
  const nlid::CompareResult half = nlid::compare(Gain{1.0}, data, nlid::InitialCondition::estimate);
  const Eigen::VectorXd y = a.y().col(0);
  const double expect = 100.0 * (1.0 - (y - 0.5 * y).norm() / (y.array() - y.mean()).matrix().norm());
  CHECK(half.fit_of(0) == Approx(expect));
  CHECK(half.experiment_names == std::vector<std::string>{"a", "b"});
  REQUIRE(half.simulated.size() == 2);
  CHECK((half.simulated[1] - b.u()).norm() == 0.0);
  const std::string t = half.table();
  CHECK(t.find("initial condition 'estimate'") != std::string::npos);
  CHECK(t.find("a ") != std::string::npos);
  CHECK_THROWS_WITH(half.fit_of(5), Catch::Contains("out of range"));
}

TEST_CASE("compare handles several outputs and unnamed experiments", "[analysis][compare]") {
  Eigen::MatrixXd u(10, 2), y(10, 2);
  u << ramp(10, 1.0), ramp(10, -3.0);
  y = u;
  y.col(1) *= 0.5;
  const nlid::CompareResult r = nlid::compare(Gain{1.0}, nlid::Dataset{nlid::Experiment(u, y, 1.0)});
  CHECK(r.fit.rows() == 1);
  CHECK(r.fit.cols() == 2);
  CHECK(r.fit(0, 0) == Approx(100.0));
  CHECK(r.fit(0, 1) < 100.0);
  CHECK(r.experiment_names[0] == "experiment 0");
  CHECK(r.output_names == std::vector<std::string>{"y1", "y2"});
  nlid::FitTable table;
  table.add("gain", r);
  CHECK(table.str().find("experiment 0/y2") != std::string::npos);
}

TEST_CASE("FitTable lists models against experiments", "[analysis][compare]") {
  const nlid::Experiment a(ramp(10, 1.0), ramp(10, 2.0), 0.1, "data3lin");
  const nlid::Experiment b(ramp(10, 1.0), ramp(10, 2.0), 0.1, "data2lin");
  nlid::FitTable table;
  table.add("perfect", nlid::compare(Gain{2.0}, nlid::Dataset{a, b}));
  table.add("half", nlid::compare(Gain{1.0}, nlid::Dataset{b}));
  const std::string s = table.str();
  CHECK(s.find("data3lin") < s.find("data2lin"));
  CHECK(s.find("100.0 %") != std::string::npos);
  // "half" was not compared on data3lin: its cell shows "-".
  const std::string half_row = s.substr(s.find("half"));
  CHECK(half_row.find(" - ") != std::string::npos);
}

TEST_CASE("compare reports located errors", "[analysis][compare]") {
  const nlid::Experiment ok(ramp(10, 1.0), ramp(10, 2.0), 0.1, "ok");
  const nlid::Experiment flat(ramp(10, 1.0), Eigen::MatrixXd::Constant(10, 1, 15.0), 0.1, "flat");
  try {
    (void)nlid::compare(Gain{1.0}, nlid::Dataset{ok, flat});
    FAIL("constant output accepted");
  } catch (const nlid::Error& e) {
    CHECK(std::string(e.what()).find("'flat'") != std::string::npos);
    CHECK(std::string(e.what()).find("constant") != std::string::npos);
    CHECK(e.where().experiment == 1);
  }
  CHECK_THROWS_WITH(nlid::compare(Broken{}, nlid::Dataset{ok}), Catch::Contains("11 x 1 output for experiment 0 ('ok') with 10 samples"));
  CHECK_THROWS_WITH(nlid::compare(Gain{}, nlid::Dataset{}), Catch::Contains("empty"));
}

TEST_CASE("compare works on a linear model end to end", "[analysis][compare]") {
  Eigen::VectorXd a(1), b(1);
  a << -0.9;
  b << 0.5;
  const nlid::Arx m(a, {b}, {1}, 0.1);
  Eigen::MatrixXd u(200, 1);
  for (int k = 0; k < 200; ++k) u(k, 0) = (k / 20) % 2 ? 1.0 : -1.0;
  const nlid::Experiment blank(u, Eigen::MatrixXd::Zero(200, 1), 0.1);
  const nlid::Experiment e(u, m.simulate(blank), 0.1, "sim");
  CHECK(nlid::compare(m, nlid::Dataset{e}).fit(0, 0) == Approx(100.0));
  CHECK(nlid::compare(m.to_state_space(), nlid::Dataset{e}).fit(0, 0) == Approx(100.0));
}

TEST_CASE("compare_prediction scores k-step-ahead predictions", "[analysis][compare]") {
  // ARX y(t) = 0.9 y(t-1) + 0.5 u(t-1) + e(t) with noise: the one-step predictor beats the free
  // run, a long horizon approaches it, and every fit is that of the model's own predict(e, k).
  Eigen::VectorXd a(1), b(1);
  a << -0.9;
  b << 0.5;
  const nlid::Arx m(a, {b}, {1}, 0.1);
  Eigen::MatrixXd u(400, 1), y(400, 1);
  unsigned state = 12345u;
  auto noise = [&] {
    state = state * 1664525u + 1013904223u;
    return (static_cast<double>(state >> 8) / 16777216.0 - 0.5) * 0.6;
  };
  for (int t = 0; t < 400; ++t) {
    u(t, 0) = (t / 25) % 2 ? 1.0 : -1.0;
    y(t, 0) = (t > 0 ? 0.9 * y(t - 1, 0) + 0.5 * u(t - 1, 0) : 0.0) + noise();
  }
  const nlid::Dataset d{nlid::Experiment(u, y, 0.1, "noisy")};
  double last = 101.0;
  for (const int k : {1, 2, 5, 20}) {
    const nlid::CompareResult r = nlid::compare_prediction(m, d, k);
    CHECK(r.horizon == k);
    CHECK(r.fit(0, 0) == nlid::fit_percent(y, m.predict(d[0], k))(0));
    CHECK(r.simulated.at(0) == m.predict(d[0], k));
    CHECK(r.fit(0, 0) < last);  // a longer horizon predicts worse on this record
    last = r.fit(0, 0);
  }
  CHECK(nlid::compare_prediction(m, d, 1).fit(0, 0) > nlid::compare(m, d, nlid::InitialCondition::estimate).fit(0, 0) + 5.0);
  CHECK_THAT(nlid::compare_prediction(m, d, 5).table(), Catch::Contains("Fit (%) of the 5-step-ahead predicted output"));
  CHECK_THROWS_WITH(nlid::compare_prediction(m, d, 0), Catch::Contains("the horizon k must be >= 1, got 0"));
  // In a FitTable beside the free run, the prediction row says its horizon.
  nlid::FitTable t;
  t.add("arx", nlid::compare(m, d, nlid::InitialCondition::estimate));
  t.add("arx", nlid::compare_prediction(m, d, 1));
  CHECK_THAT(t.str(), Catch::Contains("\narx (k = 1) |") && Catch::Contains("\narx         |"));
  const nlid::CompareResult far = nlid::compare_prediction(m, d, nlid::infinite_horizon);
  t.add("arx", far);
  CHECK_THAT(t.str(), Catch::Contains("\narx (k = inf) |"));
  CHECK_THAT(far.table(), Catch::Contains("predicted infinitely many steps ahead"));
}

TEST_CASE("a diverging simulation is a result of compare, other errors are not", "[analysis][compare]") {
  const nlid::Experiment a(ramp(10, 1.0), ramp(10, 2.0), 0.1, "a");
  const nlid::Experiment unstable(ramp(10, 1.0), ramp(10, 2.0), 0.1, "unstable");
  const nlid::CompareResult r = nlid::compare(SometimesDiverging{}, nlid::Dataset{a, unstable});
  CHECK(r.fit_of(0) == Approx(100.0));
  CHECK(r.fit_of(1) == -std::numeric_limits<double>::infinity());
  REQUIRE(r.simulated.size() == 2);
  CHECK(r.simulated[0].rows() == 10);
  CHECK(r.simulated[1].size() == 0);
  CHECK(r.diverged_at == std::vector<long>{-1, 7});
  CHECK_THAT(r.table(), Catch::Contains("diverged") && Catch::Contains("(diverged at sample 7)"));
  nlid::FitTable t;
  t.add("m", r);
  CHECK_THAT(t.str(), Catch::Contains("100.0 %") && Catch::Contains("diverged"));
  // Models that do not throw: a non-finite output is a divergence from its first such row.
  const nlid::CompareResult o = nlid::compare(Overflowing{}, nlid::Dataset{a});
  CHECK(o.fit_of(0) == -std::numeric_limits<double>::infinity());
  CHECK(o.diverged_at == std::vector<long>{4});
  REQUIRE(o.simulated.size() == 1);
  CHECK(o.simulated[0].size() == 0);
  CHECK_THAT(o.table(), Catch::Contains("(diverged at sample 4)"));
  // An unstable ARX, y(t) = 1e60 y(t-1) + u(t-1), overflows to inf (then NaN) within 10 samples.
  const nlid::Arx unstable_arx(Eigen::VectorXd::Constant(1, -1e60), {Eigen::VectorXd::Ones(1)}, {1}, 0.1);
  const nlid::CompareResult ua = nlid::compare(unstable_arx, nlid::Dataset{a});
  CHECK(ua.fit_of(0) == -std::numeric_limits<double>::infinity());
  CHECK(ua.diverged_at[0] > 0);
  CHECK(ua.diverged_at[0] < 10);
  CHECK(ua.simulated[0].size() == 0);
  const nlid::Experiment broken(ramp(10, 1.0), ramp(10, 2.0), 0.1, "broken");
  CHECK_THROWS_WITH(nlid::compare(SometimesDiverging{}, nlid::Dataset{a, broken}), Catch::Contains("cannot read this record"));
}

TEST_CASE("compare's table and the FitTable read the same under a decimal-comma locale", "[analysis][compare][locale]") {
  const nlid::Experiment a(ramp(10, 1.0), ramp(10, 2.0), 0.1, "a");
  const nlid::Experiment b(ramp(20, -1.0), ramp(20, -2.0), 0.1, "b");
  const nlid::CompareResult r = nlid::compare(Gain{1.3}, nlid::Dataset{a, b});
  nlid::FitTable fits;
  fits.add("gain", r);
  const std::string table = r.table(), fit_table = fits.str();
  REQUIRE(table.find('.') != std::string::npos);  // the fits, with two decimals
  REQUIRE(fit_table.find('.') != std::string::npos);
  const nlid_test::DecimalCommaLocale comma;
  if (nlid_test::DecimalCommaLocale::required()) REQUIRE(comma.active());
  if (!comma.active()) {
    WARN("no locale with decimal commas installed: not checked");
    return;
  }
  CHECK(r.table() == table);
  CHECK(fits.str() == fit_table);
}
