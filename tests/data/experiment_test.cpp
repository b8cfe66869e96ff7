// Experiment and Dataset: construction checks, channel metadata, missing-data policies, merge.
#include "nlid/data/experiment.hpp"

#include <catch2/catch.hpp>

#include "../support/error_of.hpp"
#include <cmath>
#include <limits>
#include <string>

#include "nlid/data/dataset.hpp"

namespace {

using Catch::Matchers::Contains;
const double kNaN = std::numeric_limits<double>::quiet_NaN();

// Builds a one-input, one-output experiment of n zero samples with sample time ts.
nlid::Experiment zeros(Eigen::Index n, double ts) {
  return {Eigen::MatrixXd::Zero(n, 1), Eigen::MatrixXd::Zero(n, 1), ts};
}

nlid::Experiment ramp(Eigen::Index n, double ts, int nu = 1, int ny = 1, std::string name = {}) {
  Eigen::MatrixXd u(n, nu), y(n, ny);
  for (Eigen::Index k = 0; k < n; ++k) {
    for (int c = 0; c < nu; ++c) u(k, c) = static_cast<double>(k + c);
    for (int c = 0; c < ny; ++c) y(k, c) = 2.0 * static_cast<double>(k) - c;
  }
  return {u, y, ts, std::move(name)};
}

using nlid_test::error_of;

}  // namespace

TEST_CASE("Experiment stores samples, sample time and default channel names", "[data]") {
  const nlid::Experiment e = ramp(5, 0.01, 2, 1, "run");
  CHECK(e.size() == 5);
  CHECK(e.num_inputs() == 2);
  CHECK(e.num_outputs() == 1);
  CHECK(e.ts() == 0.01);
  CHECK(e.t0() == 0.0);
  CHECK(e.name() == "run");
  CHECK(e.input_names() == std::vector<std::string>{"u1", "u2"});
  CHECK(e.output_names() == std::vector<std::string>{"y"});
  CHECK(e.input_units() == std::vector<std::string>{"", ""});
  CHECK(e.u()(3, 1) == 4.0);
  CHECK(e.y()(4, 0) == 8.0);
  CHECK_FALSE(e.has_missing());
}

TEST_CASE("Experiment time vector is t0 + k ts without accumulated rounding", "[data]") {
  nlid::Experiment e = ramp(100001, 1e-3);
  e.set_t0(2.5);
  const Eigen::VectorXd t = e.time();
  CHECK(t(0) == 2.5);
  CHECK(t(100000) == 2.5 + 100000 * 1e-3);
  CHECK(e.t_end() == t(100000));
}

TEST_CASE("Experiment setters validate", "[data]") {
  nlid::Experiment e = ramp(4, 0.1, 1, 2);
  e.set_output_names({"angle", "rate"});
  e.set_output_units({"deg", "deg/s"});
  e.set_input_units({"V"});
  CHECK(e.output_names()[1] == "rate");
  CHECK(e.output_units()[0] == "deg");
  const auto err = error_of([&] { e.set_output_names({"only one"}); });
  CHECK_THAT(err.what(), Contains("expected 2, got 1"));
  CHECK(err.where().parameter == "output_names");
  CHECK_THROWS_WITH(e.set_ts(0.0), Contains("positive and finite"));
  CHECK_THROWS_WITH(e.set_ts(-1.0), Contains("-1"));
  CHECK_THROWS_AS(e.set_ts(std::numeric_limits<double>::infinity()), nlid::Error);
  CHECK_THROWS_AS(e.set_t0(kNaN), nlid::Error);
  e.set_name("renamed");
  CHECK(e.name() == "renamed");
}

TEST_CASE("Experiment constructor rejects inconsistent data", "[data]") {
  SECTION("row counts differ") {
    const auto err = error_of([] {
      (void)nlid::Experiment(Eigen::MatrixXd::Zero(4, 1), Eigen::MatrixXd::Zero(5, 1), 1.0);
    });
    CHECK_THAT(err.what(), Contains("u has 4 rows, y has 5"));
  }
  SECTION("non-positive sample time") {
    CHECK_THROWS_WITH(zeros(4, 0.0), Contains("sample time must be positive"));
    CHECK_THROWS_WITH(zeros(4, -0.5), Contains("got -0.5"));
    CHECK_THROWS_AS(zeros(4, kNaN), nlid::Error);
  }
  SECTION("NaN sample names channel and sample") {
    Eigen::MatrixXd y = Eigen::MatrixXd::Zero(6, 2);
    y(3, 1) = kNaN;
    const auto err =
        error_of([&] { (void)nlid::Experiment(Eigen::MatrixXd::Zero(6, 1), y, 1.0, "rig"); });
    CHECK_THAT(err.what(), Contains("experiment 'rig'"));
    CHECK_THAT(err.what(), Contains("sample index 3"));
    CHECK(err.where().row == 4);
    CHECK(err.where().column == 2);
    CHECK(err.where().column_name == "y2");
  }
}

TEST_CASE("Experiment allows zero-channel sides and empty records", "[data]") {
  const nlid::Experiment ts(Eigen::MatrixXd(10, 0), Eigen::MatrixXd::Ones(10, 1), 0.5);
  CHECK(ts.num_inputs() == 0);
  CHECK(ts.size() == 10);
  const nlid::Experiment empty;
  CHECK(empty.size() == 0);
  CHECK(empty.empty());
  CHECK(empty.time().size() == 0);
}

TEST_CASE("NonFinitePolicy::keep and ::interpolate", "[data]") {
  Eigen::MatrixXd u = Eigen::MatrixXd::Zero(8, 1);
  Eigen::VectorXd y(8);
  y << 0, 1, kNaN, kNaN, 4, 5, std::numeric_limits<double>::infinity(), 7;
  SECTION("keep") {
    const nlid::Experiment e(u, y, 1.0, "k", nlid::NonFinitePolicy::keep);
    CHECK(e.has_missing());
    CHECK(std::isnan(e.y()(2, 0)));
    CHECK_THROWS_WITH(e.validate(), Contains("non-finite output sample"));
    CHECK_NOTHROW(e.validate(true));
  }
  SECTION("interpolate fills interior gaps linearly and notes them") {
    const nlid::Experiment e(u, y, 1.0, "i", nlid::NonFinitePolicy::interpolate);
    CHECK_FALSE(e.has_missing());
    CHECK(e.y()(2, 0) == Approx(2.0));
    CHECK(e.y()(3, 0) == Approx(3.0));
    CHECK(e.y()(6, 0) == Approx(6.0));
    REQUIRE(e.notes().size() == 1);
    CHECK_THAT(e.notes()[0], Contains("filled 3 missing sample(s) of 'y'"));
    CHECK_THAT(e.notes()[0], Contains("2..3, 6"));
  }
  SECTION("interpolate refuses long gaps and gaps at the ends") {
    CHECK_THROWS_WITH(
        nlid::Experiment(u, y, 1.0, "", nlid::NonFinitePolicy::interpolate, 1),
        Contains("gap of 2 missing samples (samples 2..3) is longer than the allowed 1"));
    Eigen::VectorXd y2 = y;
    y2(0) = kNaN;
    CHECK_THROWS_WITH(nlid::Experiment(u, y2, 1.0, "", nlid::NonFinitePolicy::interpolate),
                      Contains("start of the record"));
    Eigen::VectorXd y3 = Eigen::VectorXd::Zero(8);
    y3(7) = kNaN;
    CHECK_THROWS_WITH(nlid::Experiment(u, y3, 1.0, "", nlid::NonFinitePolicy::interpolate),
                      Contains("end of the record"));
  }
}

TEST_CASE("Experiment errors show a name with control characters escaped, not cut at a NUL byte", "[data][errors]") {
  Eigen::MatrixXd u = Eigen::MatrixXd::Zero(6, 1);
  Eigen::VectorXd y = Eigen::VectorXd::Zero(6);
  y(0) = kNaN;
  const std::string name("run\0a", 5);  // a NUL byte would end what() early and lose the location
  nlid::Experiment e(u, y, 1.0, name, nlid::NonFinitePolicy::keep);
  e.set_output_names({std::string("ang\0le", 6)});
  try {
    e.validate();
    FAIL("a missing sample was accepted");
  } catch (const nlid::Error& err) {
    const std::string what = err.what();
    CHECK_THAT(what, Contains("experiment 'run\\x00a'"));
    CHECK_THAT(what, Contains("'ang\\x00le'"));  // the location's column name
    CHECK_THAT(what, Contains("row 1"));          // after the names: nothing was cut
  }
}

TEST_CASE("Experiment::validate catches changes made through the mutable accessors", "[data]") {
  nlid::Experiment e = ramp(5, 1.0);
  e.u().conservativeResize(4, 1);
  CHECK_THROWS_WITH(e.validate(), Contains("u has 4 rows, y has 5"));
  nlid::Experiment f = ramp(5, 1.0);
  f.y().conservativeResize(5, 2);
  CHECK_THROWS_WITH(f.validate(), Contains("output matrix has 2 columns but 1 output names"));
}

TEST_CASE("require_estimable_scale refuses mis-scaled channels, naming channel and sample", "[data][errors]") {
  nlid::Experiment e = ramp(6, 1.0, 2, 1, "run1");
  CHECK_NOTHROW(e.require_estimable_scale("arx", 0));
  // Channels in any physical unit pass, and so do all-zero ones (the estimators judge those).
  e.u().col(1) *= 1e-90;
  e.y() *= 1e90;
  e.u().col(0).setZero();
  CHECK_NOTHROW(e.require_estimable_scale());
  e.y()(3, 0) = std::numeric_limits<double>::quiet_NaN();  // missing samples are other checks' business
  CHECK_NOTHROW(e.require_estimable_scale());

  nlid::Experiment big = ramp(6, 1.0, 1, 1, "run1");
  big.y()(4, 0) = -3e201;
  const nlid::Error a = error_of([&] { big.require_estimable_scale("arx", 2); });
  CHECK_THAT(std::string(a.what()), Contains("arx: experiment 'run1', output 'y': a sample of magnitude 3e+201 at sample index 4 is beyond 1e100"));
  CHECK_THAT(std::string(a.what()), Contains("rescale"));
  CHECK(a.where().experiment == 2);
  CHECK(a.where().row == -1);  // a sample index is no file row after decimation

  nlid::Experiment tiny = ramp(6, 1.0);
  tiny.u() *= 1e-250;
  const nlid::Error b = error_of([&] { tiny.require_estimable_scale("", 1); });
  CHECK_THAT(std::string(b.what()), Contains("experiment 1, input 'u': the largest magnitude is 5e-250 (sample index 5), below 1e-100"));
  CHECK(b.where().experiment == 1);
}

TEST_CASE("Dataset checks sample time and channel counts, naming the experiment", "[data]") {
  nlid::Dataset d{ramp(10, 0.01, 1, 1, "a"), ramp(20, 0.01, 1, 1, "b")};
  CHECK(d.size() == 2);
  CHECK(d.ts() == 0.01);
  CHECK(d.num_inputs() == 1);
  CHECK(d.num_outputs() == 1);
  CHECK(d.total_samples() == 30);
  CHECK(d.names() == std::vector<std::string>{"a", "b"});
  CHECK(d[1].name() == "b");

  // ts equal within the relative 1e-6 tolerance is accepted: two records of a jittering logger
  // whose sample times read_csv took from their end points differ by about 1e-8 ...
  CHECK_NOTHROW(d.add(ramp(5, 0.01 * (1 + 1.5e-8))));
  CHECK_NOTHROW(d.add(ramp(5, 0.01 * (1 - 9e-7))));
  // ... a larger difference is not, and the message names index and record.
  auto err = error_of([&] { d.add(ramp(5, 0.01 * (1 + 2e-6), 1, 1, "drift")); });
  CHECK_THAT(err.what(), Contains("experiment 'drift' has sample time 0.01000002 but the data set has 0.01 (relative difference 2e-06)"));
  // Nearly equal rates read from one logger's jittering stamps: the hint names the remedy.
  CHECK_THAT(err.what(), Contains("if both were logged at one rate, set that sample time"));
  err = error_of([&] { d.add(ramp(5, 0.02, 1, 1, "slow")); });
  CHECK(err.where().experiment == 4);
  CHECK_THAT(err.what(), Contains("experiment 'slow' has sample time 0.02"));
  CHECK_THAT(err.what(), Contains("experiment 4"));
  err = error_of([&] { d.add(ramp(5, 0.01, 2, 1)); });
  CHECK_THAT(err.what(), Contains("has 2 inputs and 1 outputs but the data set has 1 inputs"));
  err = error_of([&] { d.add(ramp(5, 0.01, 1, 3)); });
  CHECK_THAT(err.what(), Contains("3 outputs"));
  CHECK(d.size() == 4);  // failed adds leave the set unchanged

  err = error_of([&] { (void)d[7]; });
  CHECK_THAT(err.what(), Contains("index 7 out of range"));

  const nlid::Dataset empty;
  CHECK(empty.total_samples() == 0);
  CHECK_THROWS_WITH(empty.ts(), Contains("empty data set"));
}

TEST_CASE("Dataset iterates in order and converts from a single Experiment", "[data]") {
  const nlid::Dataset one = ramp(3, 1.0, 1, 1, "solo");
  REQUIRE(one.size() == 1);
  CHECK(one[0].name() == "solo");
  nlid::Dataset many(std::vector<nlid::Experiment>{ramp(1, 1.0), ramp(2, 1.0), ramp(3, 1.0)});
  Eigen::Index expect = 1;
  for (const auto& e : many) CHECK(e.size() == expect++);
  for (auto& e : many) e.set_name("x");
  CHECK(many[2].name() == "x");
}

TEST_CASE("merge concatenates data sets and validates the result", "[data]") {
  const nlid::Dataset a{ramp(10, 0.01, 1, 1, "a1"), ramp(11, 0.01, 1, 1, "a2")};
  const nlid::Dataset b = ramp(12, 0.01, 1, 1, "b1");
  const nlid::Dataset m = nlid::merge(a, b);
  REQUIRE(m.size() == 3);
  CHECK(m.names() == std::vector<std::string>{"a1", "a2", "b1"});
  CHECK(m.total_samples() == 33);
  CHECK(m[2].y() == b[0].y());
  const auto err = error_of([&] { (void)nlid::merge(a, ramp(12, 0.001, 1, 1, "fast")); });
  CHECK(err.where().experiment == 2);
  CHECK_THAT(err.what(), Contains("'fast' has sample time 0.001"));
}

TEST_CASE("Dataset refuses records whose channels carry different names at one position", "[data][errors]") {
  nlid::Experiment a = ramp(10, 0.01, 2, 1, "a");
  a.set_input_names({"cmd", "load"});
  nlid::Experiment b = ramp(10, 0.01, 2, 1, "b");
  b.set_input_names({"load", "cmd"});
  auto err = error_of([&] { (void)nlid::Dataset{a, b}; });
  CHECK_THAT(err.what(), Contains("experiment 'b' has input 1 named 'load' but the data set's input 1 is 'cmd'"));
  CHECK(err.where().experiment == 1);
  CHECK(err.where().column == 1);
  CHECK(err.where().column_name == "load");
  err = error_of([&] { (void)nlid::merge(nlid::Dataset{a}, nlid::Dataset{b}); });
  CHECK(err.where().experiment == 1);
  nlid::Experiment c = ramp(10, 0.01, 2, 1, "c");
  c.set_output_names({"angle"});
  nlid::Experiment d = ramp(10, 0.01, 2, 1, "d");
  d.set_output_names({"rate"});
  CHECK_THROWS_WITH(nlid::Dataset({c, d}), Contains("output 1 named 'rate'"));
  // Default names (u1, u2; y) and empty ones name nothing in particular: they merge with any.
  nlid::Experiment e = ramp(10, 0.01, 2, 1, "e");
  e.set_input_names({"", "load"});
  const nlid::Dataset ok{a, ramp(10, 0.01, 2, 1, "plain"), e, a};
  CHECK(ok.size() == 4);
  // ... but a default name at another position is a reordering: a CSV with columns u1, u2 read
  // once as {u1, u2} and once as {u2, u1} was fitted as one system with the inputs swapped.
  nlid::Experiment f = ramp(10, 0.01, 2, 1, "f");
  f.set_input_names({"u1", "u2"});
  nlid::Experiment g = ramp(10, 0.01, 2, 1, "g");
  g.set_input_names({"u2", "u1"});
  CHECK_THROWS_WITH(nlid::Dataset({f, g}), Contains("experiment 'g' has input 1 named 'u2' but the data set's input 1 is 'u1'"));
  CHECK_THROWS_WITH(nlid::Dataset({g, f}), Contains("has input 1 named 'u1' but the data set's input 1 is 'u2'"));
  CHECK_THROWS_WITH(nlid::Dataset({g, a}), Contains("has input 1 named 'cmd' but the data set's input 1 is 'u2'"));
  CHECK(nlid::Dataset({f, a}).size() == 2);  // u1, u2 in their own places name nothing
}
