// Offsets, means, trends, time windows and resampling, each with a known answer, plus the
// Dataset overloads and their error locations.
#include "nlid/data/preprocess.hpp"

#include <catch2/catch.hpp>

#include "../support/error_of.hpp"
#include <cmath>
#include <limits>
#include <numbers>

namespace {

using Catch::Matchers::Contains;

using nlid_test::error_of;

// u = [k, 2] , y = [a + b t + s(t)] with s a zero-mean wiggle orthogonal to 1 and t.
nlid::Experiment trended(double a, double b, double ts = 0.1, Eigen::Index n = 201,
                         double t0 = 3.0) {
  Eigen::MatrixXd u(n, 2), y(n, 1);
  for (Eigen::Index k = 0; k < n; ++k) {
    const double t = t0 + static_cast<double>(k) * ts;
    u(k, 0) = static_cast<double>(k);
    u(k, 1) = 2.0;
    y(k, 0) = a + b * t;
  }
  nlid::Experiment e(u, y, ts, "trended");
  e.set_t0(t0);
  return e;
}

}  // namespace

TEST_CASE("remove_offset subtracts the given constants", "[data][preprocess]") {
  const nlid::Experiment e = trended(15.0, 0.0);
  const nlid::Experiment r =
      nlid::remove_offset(e, Eigen::Vector2d(1.0, 2.0), Eigen::VectorXd::Constant(1, 15.0));
  CHECK((r.y().array() == 0.0).all());  // exact: constant offsets add no rounding from t
  CHECK((r.u().col(1).array() == 0.0).all());
  CHECK(r.u()(5, 0) == 4.0);
  CHECK(r.t0() == e.t0());
  CHECK(r.input_names() == e.input_names());
  CHECK_THAT(r.notes().back(), Contains("removed trend"));
  const nlid::Experiment s = nlid::remove_offset(e, 0.0, 15.0);
  CHECK(s.y() == r.y());
  CHECK(s.u() == e.u());

  const auto err = error_of(
      [&] { (void)nlid::remove_offset(e, Eigen::VectorXd::Zero(1), Eigen::VectorXd::Zero(1)); });
  CHECK_THAT(err.what(), Contains("input_offset has 1 entries but the experiment has 2 channels"));
  CHECK(err.where().parameter == "input_offset");
}

TEST_CASE("remove_mean and mean_trend", "[data][preprocess]") {
  const nlid::Experiment e = trended(1.0, 2.0);
  const nlid::Trend t = nlid::mean_trend(e);
  CHECK(t.input_offset(0) == Approx(100.0));
  CHECK(t.input_offset(1) == 2.0);
  CHECK(t.output_offset(0) == Approx(1.0 + 2.0 * (3.0 + 10.0)));
  const nlid::Experiment r = nlid::remove_mean(e);
  CHECK(r.y().mean() == Approx(0.0).margin(1e-12));
  CHECK(r.u().colwise().mean().cwiseAbs().maxCoeff() < 1e-12);
  // add_trend undoes remove_trend.
  const nlid::Experiment back = nlid::add_trend(r, t);
  CHECK((back.y() - e.y()).cwiseAbs().maxCoeff() < 1e-12);
}

TEST_CASE("detrend removes a least-squares line, linear_trend recovers it", "[data][preprocess]") {
  const nlid::Experiment e = trended(-4.0, 0.75);
  const nlid::Trend t = nlid::linear_trend(e);
  CHECK(t.output_slope(0) == Approx(0.75).epsilon(1e-12));
  CHECK(t.output_offset(0) == Approx(-4.0 + 0.75 * t.t_ref).epsilon(1e-12));
  CHECK(t.input_slope(0) == Approx(10.0).epsilon(1e-12));  // u = k = (t − t0)/ts
  CHECK(t.input_slope(1) == Approx(0.0).margin(1e-12));
  const nlid::Experiment d = nlid::detrend(e);
  CHECK(d.y().cwiseAbs().maxCoeff() < 1e-10);

  // Line plus an oscillation: the residual is the oscillation minus its own LS line, hence
  // orthogonal to 1 and t.
  nlid::Experiment w = e;
  for (Eigen::Index k = 0; k < w.size(); ++k) w.y()(k, 0) += std::sin(0.3 * static_cast<double>(k));
  const nlid::Experiment dw = nlid::detrend(w);
  const Eigen::VectorXd time = dw.time();
  CHECK(dw.y().col(0).sum() == Approx(0.0).margin(1e-9));
  CHECK(dw.y().col(0).dot(time) == Approx(0.0).margin(1e-8));

  const nlid::Experiment one(Eigen::MatrixXd::Zero(1, 1), Eigen::MatrixXd::Zero(1, 1), 1.0);
  CHECK_THROWS_WITH(nlid::detrend(one), Contains("needs at least 2 sample(s)"));
}

TEST_CASE("the estimation trend is applied to validation data as is", "[data][preprocess]") {
  const nlid::Experiment est = trended(15.0, 0.0);
  const nlid::Experiment val = trended(16.0, 0.0);  // a real 1° offset difference
  const nlid::Experiment v = nlid::remove_trend(val, nlid::mean_trend(est));
  CHECK(v.y().mean() == Approx(1.0));  // not hidden by removing val's own mean
  const nlid::Dataset d{est, val};
  const nlid::Trend pooled = nlid::mean_trend(d);
  CHECK(pooled.output_offset(0) == Approx(15.5));
  const nlid::Dataset dr = nlid::remove_trend(d, pooled);
  CHECK(dr[0].y().mean() == Approx(-0.5));
  CHECK(nlid::add_trend(dr, pooled)[1].y().mean() == Approx(16.0));
}

TEST_CASE("select keeps a time window with its original times", "[data][preprocess]") {
  const nlid::Experiment e = trended(0.0, 1.0, 0.1, 101, 0.0);  // t = 0 … 10
  const nlid::Experiment s = nlid::select(e, 0.5, 1.0);
  REQUIRE(s.size() == 6);  // 0.5, 0.6, …, 1.0 (rounding in k·ts is tolerated)
  CHECK(s.t0() == Approx(0.5));
  CHECK(s.u()(0, 0) == 5.0);
  CHECK(s.u()(5, 0) == 10.0);
  CHECK(s.ts() == e.ts());
  CHECK_THAT(s.notes().back(), Contains("selected time window [0.5, 1]"));
  CHECK(nlid::select(e, 0.0, 10.0).size() == 101);
  CHECK(nlid::select(e, 0.55, 0.65).size() == 1);

  CHECK_THROWS_WITH(nlid::select(e, 2.0, 1.0), Contains("not a finite, ordered interval"));
  CHECK_THROWS_WITH(nlid::select(e, 5.0, 12.0), Contains("reaches outside the record [0, 10]"));
  CHECK(error_of([&] { (void)nlid::select(e, -1.0, 2.0); }).where().parameter == "t_begin");
  CHECK_THROWS_WITH(nlid::select(e, 0.51, 0.59), Contains("contains no sample"));
  CHECK_THROWS_AS(nlid::select(e, std::nan(""), 1.0), nlid::Error);

  const nlid::Experiment ss = nlid::select_samples(e, 10, 3);
  CHECK(ss.t0() == Approx(1.0));
  CHECK(ss.u()(2, 0) == 12.0);
  CHECK_THROWS_WITH(nlid::select_samples(e, 100, 2), Contains("outside the record of 101 samples"));
  CHECK_THROWS_AS(nlid::select_samples(e, 0, 0), nlid::Error);
}

TEST_CASE("resampling and decimation refuse requests that leave no record", "[data][preprocess][errors]") {
  const nlid::Experiment e = trended(1.0, 0.1, 0.1, 100);
  // A sample time so short that the count overflows (it aborted inside Eigen before).
  CHECK_THROWS_WITH(nlid::resample(e, 1e-300), Contains("more than 2^31 - 1"));
  // A factor that leaves one sample, mostly the filter's start-up (it returned NaN or -8.5 for
  // a record between 1 and 11).
  CHECK_THROWS_WITH(nlid::decimate(e, 1000), Contains("needs more than 1000 samples"));
  CHECK_THROWS_WITH(nlid::decimate(e, 100), Contains("the record has 100"));
  CHECK(nlid::decimate(e, 50).size() == 2);
  // A non-integer ratio that leaves one sample is refused like the integer one (it returned a
  // 1-sample record).
  const nlid::Error short_out = error_of([&] { (void)nlid::resample(e, 100.5 * e.ts()); });
  CHECK_THAT(short_out.what(), Contains("would leave 1 sample") && Contains("at least two out"));
  CHECK(short_out.where().parameter == "new_ts");
  CHECK(nlid::resample(e, 49.5 * e.ts()).size() == 3);
  // Absurd counts: the message names them without overflowing.
  CHECK_THROWS_WITH(nlid::select_samples(e, 1, std::numeric_limits<Eigen::Index>::max()),
                    Contains("from index 1 is empty or outside the record of 100 samples"));
}

TEST_CASE("Dataset overloads act per experiment and name the failing one", "[data][preprocess]") {
  const nlid::Dataset d{trended(1.0, 0.0, 0.1, 50), trended(2.0, 0.0, 0.1, 30)};
  const nlid::Dataset m = nlid::remove_mean(d);
  CHECK(m.size() == 2);
  CHECK(m[1].y().cwiseAbs().maxCoeff() < 1e-12);
  CHECK(nlid::detrend(d)[0].y().cwiseAbs().maxCoeff() < 1e-12);
  CHECK(nlid::remove_offset(d, 0.0, 1.0)[1].y()(0, 0) == 1.0);
  CHECK(nlid::remove_offset(d, Eigen::Vector2d(0, 0), Eigen::VectorXd::Constant(1, 2.0))[1].y()(
            0, 0) == 0.0);
  CHECK(nlid::decimate(d, 2)[1].size() == 15);
  // The window [3, 6] fits the first record (3 … 7.9) but not the second (3 … 5.9).
  CHECK(nlid::select(d, 3.0, 5.0).total_samples() == 42);
  const auto err = error_of([&] { (void)nlid::select(d, 3.0, 6.0); });
  CHECK(err.where().experiment == 1);
  CHECK_THAT(err.what(), Contains("experiment 1"));
  CHECK_THAT(err.what(), Contains("reaches outside the record"));
  // By index: samples 20 … 34 exist in the first record (50 samples), not in the second (30).
  const nlid::Dataset s = nlid::select_samples(d, 5, 10);
  CHECK(s.total_samples() == 20);
  CHECK(s[1].y()(0, 0) == d[1].y()(5, 0));
  CHECK(s[1].t0() == Approx(d[1].t0() + 5 * d[1].ts()));
  const auto err2 = error_of([&] { (void)nlid::select_samples(d, 20, 15); });
  CHECK(err2.where().experiment == 1);
  CHECK_THAT(err2.what(), Contains("outside the record of 30 samples"));
}

TEST_CASE("resample to an integer multiple equals decimate", "[data][resample]") {
  nlid::Experiment e = trended(0.0, 1.0, 1e-3, 3000);
  for (Eigen::Index k = 0; k < e.size(); ++k)
    e.y()(k, 0) += std::sin(0.01 * static_cast<double>(k));
  const nlid::Experiment r = nlid::resample(e, 5e-3);
  const nlid::Experiment d = nlid::decimate(e, 5);
  CHECK(r.y() == d.y());
  CHECK(r.ts() == 5e-3);
}

TEST_CASE("resample: spline up-sampling and filtered down-sampling", "[data][resample]") {
  const double ts = 1e-3;
  const Eigen::Index n = 4001;
  auto signal = [](double t, double f) { return std::sin(2 * std::numbers::pi * f * t + 0.4); };
  auto make = [&](double f) {
    Eigen::MatrixXd y(n, 1);
    for (Eigen::Index k = 0; k < n; ++k) y(k, 0) = signal(static_cast<double>(k) * ts, f);
    return nlid::Experiment(y, y, ts);
  };

  SECTION("up-sampling a smooth signal by 2.5 is accurate to O(h^4)") {
    const nlid::Experiment e = make(10.0);  // 100 samples per period
    const nlid::Experiment r = nlid::resample(e, ts / 2.5);
    CHECK(r.size() == 10001);
    CHECK(r.t_end() == Approx(e.t_end()));
    double worst = 0.0;
    for (Eigen::Index k = 0; k < r.size(); ++k) {
      worst =
          std::max(worst, std::abs(r.y()(k, 0) - signal(static_cast<double>(k) * r.ts(), 10.0)));
    }
    CHECK(worst < 1e-6);  // including the ends (not-a-knot)
    CHECK_THAT(r.notes().back(), Contains("(interpolation)"));
  }
  SECTION("down-sampling 1 kHz to 400 Hz keeps the pass band and removes the stop band") {
    const nlid::Experiment pass = nlid::resample(make(20.0), 2.5e-3);  // new Nyquist 200 Hz
    CHECK(pass.size() == 1601);
    double worst = 0.0;
    for (Eigen::Index k = 400; k < 1200; ++k) {
      worst =
          std::max(worst, std::abs(pass.y()(k, 0) - signal(static_cast<double>(k) * 2.5e-3, 20.0)));
    }
    CHECK(worst < 0.012);  // ripple 0.1 dB = 1.2 %
    const nlid::Experiment stop = nlid::resample(make(300.0), 2.5e-3);
    CHECK(stop.y().middleRows(400, 800).cwiseAbs().maxCoeff() < 0.01);  // ≥ 40 dB
  }
  SECTION("hold keeps a piecewise-constant input on its levels") {
    Eigen::MatrixXd u(n, 1);
    for (Eigen::Index k = 0; k < n; ++k) u(k, 0) = (k / 700) % 2 == 0 ? 0.2 : 0.9;
    nlid::ResampleOptions o;
    o.inputs = nlid::Interpolation::hold;
    const nlid::Experiment e(u, u, ts);
    for (double new_ts : {0.4e-3, 2.5e-3}) {
      const nlid::Experiment r = nlid::resample(e, new_ts, o);
      CHECK(((r.u().array() == 0.2) || (r.u().array() == 0.9)).all());
      CHECK(r.y().maxCoeff() > 0.9);  // the spline / filtered output is not held
    }
    o.inputs = nlid::Interpolation::linear;
    const nlid::Experiment lin = nlid::resample(e, 0.5e-3, o);
    CHECK(lin.u()(1399, 0) == Approx(0.55));  // half-way between samples 699 (0.2) and 700 (0.9)
  }
  SECTION("errors") {
    const nlid::Experiment e = make(1.0);
    CHECK_THROWS_WITH(nlid::resample(e, 0.0), Contains("new sample time must be positive"));
    CHECK_THROWS_WITH(nlid::resample(e, -1.0), Contains("got -1"));
  }
}

TEST_CASE("select_channels picks channels by name, in the order given", "[data][preprocess]") {
  nlid::Experiment e(Eigen::MatrixXd::Random(6, 2), Eigen::MatrixXd::Random(6, 3), 0.5, "mimo");
  e.set_input_names({"volt", "load"});
  e.set_output_names({"angle", "rate", "current"});
  e.set_output_units({"deg", "deg/s", "A"});
  e.set_t0(1.0);
  const nlid::Experiment s = nlid::select_channels(e, {"load"}, {"current", "angle"});
  CHECK(s.u().col(0) == e.u().col(1));
  CHECK(s.y().col(0) == e.y().col(2));
  CHECK(s.y().col(1) == e.y().col(0));
  CHECK(s.output_units() == std::vector<std::string>{"A", "deg"});
  CHECK(s.t0() == 1.0);
  CHECK(s.notes().size() == e.notes().size() + 1);
  CHECK_THAT(s.notes().back(), Contains("selected channels: inputs 'load'; outputs 'current', 'angle'"));
  CHECK(nlid::select_channels(e, {}, {"rate"}).num_inputs() == 0);
  CHECK_THROWS_WITH(
      nlid::select_channels(e, {"volt"}, {"speed"}),
      Contains("no output channel named 'speed'; available: 'angle', 'rate', 'current'"));
  const auto err = error_of([&] { (void)nlid::select_channels(nlid::Dataset{e, e}, {"x"}, {}); });
  CHECK(err.where().experiment == 0);
  // Integer offsets pick the scalar overload (Eigen's vector constructors are explicit).
  CHECK(nlid::remove_offset(s, 0, 1).y()(0, 0) == s.y()(0, 0) - 1.0);
}
