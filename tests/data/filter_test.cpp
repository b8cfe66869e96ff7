// Anti-alias filters and zero-phase filtering: the design against the closed-form magnitude, and
// the stated decimation specs measured with sinusoids.
#include "nlid/data/filter.hpp"

#include <Eigen/QR>
#include <catch2/catch.hpp>
#include <chrono>
#include <cmath>
#include <numbers>

#include "nlid/ad/dual.hpp"
#include "nlid/data/csv.hpp"
#include "nlid/data/resample.hpp"

#include "../support/sanitizer.hpp"

namespace {

using Catch::Matchers::Contains;
using std::numbers::pi;

double chebyshev_t(int n, double x) {
  return std::abs(x) <= 1.0 ? std::cos(n * std::acos(x)) : std::cosh(n * std::acosh(std::abs(x)));
}

// Least-squares amplitude and phase of a sinusoid of frequency w (rad/sample) in x[k0, k1).
struct Sine {
  double amplitude, phase;
};
Sine fit_sine(const Eigen::VectorXd& x, double w, Eigen::Index k0, Eigen::Index k1) {
  Eigen::MatrixXd a(k1 - k0, 2);
  for (Eigen::Index k = k0; k < k1; ++k) {
    a(k - k0, 0) = std::sin(w * static_cast<double>(k));
    a(k - k0, 1) = std::cos(w * static_cast<double>(k));
  }
  const Eigen::Vector2d c = a.colPivHouseholderQr().solve(x.segment(k0, k1 - k0));
  return {std::hypot(c(0), c(1)), std::atan2(c(1), c(0))};
}

Eigen::VectorXd sine(Eigen::Index n, double w, double phase = 0.3) {
  Eigen::VectorXd x(n);
  for (Eigen::Index k = 0; k < n; ++k) x(k) = std::sin(w * static_cast<double>(k) + phase);
  return x;
}

// Value at the first (or last) sample of the least-squares line through x.
double edge_level(const Eigen::VectorXd& x, bool at_end) {
  const auto n = static_cast<double>(x.size());
  const Eigen::VectorXd k = Eigen::VectorXd::LinSpaced(x.size(), 0.0, n - 1);
  const double km = k.mean(), xm = x.mean();
  const double slope = (k.array() - km).matrix().dot((x.array() - xm).matrix()) /
                       (k.array() - km).matrix().squaredNorm();
  return xm + slope * ((at_end ? n - 1 : 0.0) - km);
}

}  // namespace

TEST_CASE("Chebyshev I design matches the closed-form magnitude", "[data][filter]") {
  for (int order : {1, 3, 4, 8, 11}) {
    for (double cutoff : {0.8, 0.3, 0.08, 0.008}) {
      const double rp = 0.05;
      const nlid::SosFilter f = nlid::chebyshev1_lowpass(order, rp, cutoff);
      CHECK(f.order() == order);
      CHECK(f.dc_gain() == Approx(1.0).epsilon(1e-13));
      const double eps2 = std::pow(10.0, rp / 10.0) - 1.0;
      const double wc = std::tan(pi * cutoff / 2.0);
      const double dc = order % 2 == 0 ? 1.0 + eps2 : 1.0;  // DC normalisation of even orders
      for (double frac : {0.0, 0.2, 0.5, 0.9, 1.0, 1.1, 1.25, 2.0, 5.0}) {
        const double w = std::min(pi * cutoff * frac, pi * 0.999);
        const double x = std::tan(w / 2.0) / wc;
        const double expect = dc / (1.0 + eps2 * chebyshev_t(order, x) * chebyshev_t(order, x));
        INFO("order " << order << " cutoff " << cutoff << " frac " << frac);
        CHECK(f.zero_phase_gain(w) == Approx(expect).epsilon(1e-8).margin(1e-14));
      }
    }
  }
}

TEST_CASE("Butterworth design matches the closed-form magnitude", "[data][filter]") {
  for (int order : {2, 5}) {
    const nlid::SosFilter f = nlid::butterworth_lowpass(order, 0.25);
    const double wc = std::tan(pi * 0.25 / 2.0);
    for (double w : {0.0, 0.1, pi * 0.25, 1.5, 3.0}) {
      const double x = std::tan(w / 2.0) / wc;
      CHECK(f.zero_phase_gain(w) == Approx(1.0 / (1.0 + std::pow(x, 2 * order))).epsilon(1e-10));
    }
    CHECK(std::abs(f.response(pi * 0.25)) == Approx(std::sqrt(0.5)).epsilon(1e-10));
  }
}

TEST_CASE("filter design rejects invalid arguments", "[data][filter]") {
  CHECK_THROWS_WITH(nlid::chebyshev1_lowpass(0, 0.05, 0.5), Contains("order must be in 1..40"));
  CHECK_THROWS_WITH(nlid::chebyshev1_lowpass(8, 0.05, 1.0), Contains("cutoff must lie strictly"));
  CHECK_THROWS_WITH(nlid::chebyshev1_lowpass(8, 0.0, 0.5), Contains("ripple"));
  CHECK_THROWS_WITH(nlid::butterworth_lowpass(4, -0.1), Contains("cutoff"));
  // Below 1e-6 the poles round onto the unit circle: the cut-off is named, not "section 0".
  try {
    (void)nlid::butterworth_lowpass(8, 1e-17);
    FAIL("a cut-off of 1e-17 was accepted");
  } catch (const nlid::Error& e) {
    CHECK(e.where().parameter == "cutoff");
    CHECK_THAT(e.what(), Contains("cutoff 1e-17") && Contains("below 1e-06"));
  }
  CHECK_THROWS_WITH(nlid::chebyshev1_lowpass(8, 0.05, 5e-7), Contains("below 1e-06"));
  CHECK(nlid::chebyshev1_lowpass(8, 0.05, 1e-6).order() == 8);
  // decimate and resample name their own argument.
  const nlid::Experiment long_rec(Eigen::MatrixXd::Zero(1000002, 1), Eigen::MatrixXd::Zero(1000002, 1), 1.0);
  try {
    (void)nlid::decimate(long_rec, 1000001);
    FAIL("decimation by 1000001 in one step was accepted");
  } catch (const nlid::Error& e) {
    CHECK(e.where().parameter == "factor");
    CHECK_THAT(e.what(), Contains("decimate in stages"));
  }
  try {
    (void)nlid::resample(long_rec, 1000000.5);
    FAIL("resampling by 1000000.5 in one step was accepted");
  } catch (const nlid::Error& e) {
    CHECK(e.where().parameter == "new_ts");
    CHECK_THAT(e.what(), Contains("in stages"));
  }
  nlid::Biquad unstable;
  unstable.a1 = -2.5;
  unstable.a2 = 1.2;
  CHECK_THROWS_WITH(nlid::SosFilter({unstable}), Contains("unstable"));
}

TEST_CASE("filtfilt is zero-phase with gain |H|^2", "[data][filter]") {
  const int r = 10;
  const nlid::SosFilter f = nlid::chebyshev1_lowpass(8, 0.05, 0.8 / r);
  const Eigen::Index n = 6000;
  for (double frac : {0.05, 0.3, 0.6, 0.8}) {  // fraction of the new Nyquist frequency
    const double w = frac * pi / r;
    const Eigen::VectorXd x = sine(n, w);
    const Eigen::VectorXd y = nlid::filtfilt(f, x);
    const Sine s = fit_sine(y, w, 1500, 4500);
    const Sine s0 = fit_sine(x, w, 1500, 4500);
    INFO("frequency " << frac << " x new Nyquist");
    CHECK(s.amplitude == Approx(f.zero_phase_gain(w)).epsilon(1e-7));
    CHECK(std::abs(s.phase - s0.phase) < 1e-7);  // zero phase
    // Stated pass band: gain within [0, +0.1] dB.
    CHECK(20 * std::log10(s.amplitude) > -1e-6);
    CHECK(20 * std::log10(s.amplitude) < 0.1 + 1e-6);
    // Away from the edges the output is g·x sample by sample.
    CHECK((y.segment(1500, 3000) - f.zero_phase_gain(w) * x.segment(1500, 3000))
              .cwiseAbs()
              .maxCoeff() < 1e-6);
  }
}

TEST_CASE("decimate: pass band kept, stop band attenuated by at least 45 dB", "[data][filter]") {
  const double ts = 1e-3;  // 1 kHz, as the throttle data
  const Eigen::Index n = 20000;
  for (int r : {2, 5, 10, 20}) {
    const double fs_new_nyq = 0.5 / (ts * r);  // Hz
    // Pass band: 0.1 … 0.8 of the new Nyquist frequency.
    for (double frac : {0.1, 0.5, 0.8}) {
      const double w = 2 * pi * frac * fs_new_nyq * ts;
      const nlid::Experiment e(sine(n, w), sine(n, w, 1.0), ts);
      const nlid::Experiment d = nlid::decimate(e, r);
      const Sine s = fit_sine(d.y().col(0), w * r, d.size() / 4, 3 * d.size() / 4);
      const Sine s0 = fit_sine(sine(n, w, 1.0), w, n / 4, 3 * n / 4);
      INFO("r " << r << " pass frac " << frac);
      CHECK(20 * std::log10(s.amplitude) > -1e-6);
      CHECK(20 * std::log10(s.amplitude) < 0.1 + 1e-6);
      CHECK(std::abs(s.phase - s0.phase) < 1e-6);
    }
    // Stop band: at and above the new Nyquist frequency.
    for (double frac : {1.0, 1.2, 2.0, 5.0, 0.98 * r}) {
      const double w = 2 * pi * frac * fs_new_nyq * ts;
      const nlid::Experiment e(sine(n, w), sine(n, w), ts);
      const nlid::Experiment d = nlid::decimate(e, r);
      // The decimated sinusoid aliases; measure its RMS over the interior instead of fitting.
      const Eigen::Index m = d.size();
      const double rms = std::sqrt(d.y().col(0).segment(m / 4, m / 2).squaredNorm() / (m / 2));
      const double atten_db = -20 * std::log10(rms * std::sqrt(2.0));
      INFO("r " << r << " stop frac " << frac << " attenuation " << atten_db << " dB");
      CHECK(atten_db >= 45.0);
    }
  }
}

TEST_CASE("decimate keeps constants exactly and ramps to rounding, edges included",
          "[data][filter]") {
  const Eigen::Index n = 5003;
  nlid::Experiment c(Eigen::MatrixXd::Constant(n, 1, -0.25), Eigen::MatrixXd::Constant(n, 1, 15.0),
                     1e-3);
  const nlid::Experiment dc = nlid::decimate(c, 10);
  REQUIRE(dc.size() == 501);  // ceil(5003 / 10): samples 0, 10, …, 5000
  CHECK((dc.y().array() == 15.0).all());
  CHECK((dc.u().array() == -0.25).all());
  CHECK(dc.ts() == Approx(0.01).epsilon(1e-15));
  CHECK(dc.t0() == c.t0());

  // A zero-phase filter with DC gain 1 has a flat zero-phase response at DC (|H|² is even in ω),
  // so a ramp passes unchanged; the odd edge reflection continues it exactly.
  Eigen::MatrixXd ramp(n, 1);
  for (Eigen::Index k = 0; k < n; ++k) ramp(k, 0) = 3.0 + 0.002 * static_cast<double>(k);
  const nlid::Experiment dr = nlid::decimate(nlid::Experiment(ramp, ramp, 1e-3), 10);
  for (Eigen::Index k = 0; k < dr.size(); ++k)
    CHECK(dr.y()(k, 0) == Approx(ramp(10 * k, 0)).margin(1e-9));
}

TEST_CASE("decimate the throttle data to 100 Hz without edge overshoot", "[data][filter]") {
  for (int i = 1; i <= 5; ++i) {
    const std::string path =
        std::string(NLID_TEST_DATA_DIR) + "/throttle/data" + std::to_string(i) + ".csv";
    const nlid::Experiment raw = nlid::read_csv(path);
    const nlid::Experiment d = nlid::decimate(raw, 10);
    INFO(path);
    // 20001 samples at t = 0, 0.001, …, 20 become 2001 samples at t = 0, 0.01, …, 20.
    CHECK(d.size() == 2001);
    CHECK(d.ts() == Approx(0.01).epsilon(1e-15));
    CHECK(d.t0() == 0.0);
    CHECK(d.t_end() == Approx(20.0));
    CHECK(d.y().minCoeff() >= raw.y().minCoeff() - 1.0);
    CHECK(d.y().maxCoeff() <= raw.y().maxCoeff() + 1.0);
    // Edges: the first and last outputs follow the local trend (data5 ends in the middle of a
    // rising step, so the reference is a least-squares line through the last 20 ms).
    CHECK(std::abs(d.y()(0, 0) - edge_level(raw.y().col(0).head(20), false)) < 0.5);
    CHECK(std::abs(d.y()(d.size() - 1, 0) - edge_level(raw.y().col(0).tail(20), true)) < 0.5);
    CHECK_THAT(d.notes().back(), Contains("decimated by 10"));
  }
}

TEST_CASE("decimate options and errors", "[data][filter]") {
  Eigen::MatrixXd step = Eigen::MatrixXd::Zero(1000, 1);
  step.bottomRows(500).setOnes();
  const nlid::Experiment e(step, step, 1e-3, "step");
  nlid::DecimateOptions o;
  o.filter_inputs = false;
  const nlid::Experiment d = nlid::decimate(e, 10, o);
  CHECK(((d.u().array() == 0.0) || (d.u().array() == 1.0)).all());  // held input sampled as is
  CHECK(d.y().maxCoeff() > 1.0);  // filtered output rings (Gibbs) at the step
  CHECK(nlid::decimate(e, 1).y() == e.y());

  CHECK_THROWS_WITH(nlid::decimate(e, 0), Contains("factor must be >= 1, got 0"));
  o.cutoff = 1.5;
  CHECK_THROWS_WITH(nlid::decimate(e, 2, o), Contains("cutoff"));
  nlid::Experiment gap(step, step, 1e-3, "gap", nlid::NonFinitePolicy::keep);
  gap.y()(3, 0) = std::nan("");
  CHECK_THROWS_WITH(nlid::decimate(gap, 2), Contains("experiment 'gap': non-finite output sample"));
  const auto err = [&] {
    try {
      (void)nlid::decimate(nlid::Dataset{e, gap}, 2);
    } catch (const nlid::Error& x) {
      return x;
    }
    return nlid::Error("none");
  }();
  CHECK(err.where().experiment == 1);
}

TEST_CASE("decimating 1e5 samples takes milliseconds", "[data][filter]") {
  const Eigen::Index n = 100000;
  const nlid::Experiment e(Eigen::MatrixXd::Random(n, 1), Eigen::MatrixXd::Random(n, 1), 1e-3);
  nlid::Experiment d = nlid::decimate(e, 10);  // first call pays page faults; time the second
  const auto t0 = std::chrono::steady_clock::now();
  d = nlid::decimate(e, 10);
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  WARN("decimate 1e5 samples x 2 channels: " << ms << " ms");
  CHECK(d.size() == 10000);
#if defined(NDEBUG) && !NLID_TEST_ASAN
  CHECK(ms < 200.0);  // ~3 ms in Release; an O(N²) slip would take seconds
#else
  CHECK(ms < 2000.0);  // unoptimised or sanitizer builds (~100 ms with ASan)
#endif
}

TEST_CASE("filtfilt is generic over the scalar: float and Dual", "[data][filter]") {
  const nlid::SosFilter f = nlid::chebyshev1_lowpass(8, 0.05, 0.1);
  const Eigen::VectorXd x = sine(800, 0.05) + 0.2 * sine(800, 2.0);
  const Eigen::VectorXd yd = nlid::filtfilt(f, x);
  const Eigen::VectorXf yf = nlid::filtfilt(f, x.cast<float>());
  CHECK((yf.cast<double>() - yd).cwiseAbs().maxCoeff() < 1e-4);

  // Filtering is linear, so the derivative of filtfilt(a·x) with respect to a is filtfilt(x).
  using D = nlid::Dual<double, 1>;
  Eigen::Matrix<D, Eigen::Dynamic, 1> xa(x.size());
  const D a = D::variable(2.0, 0);
  for (Eigen::Index k = 0; k < x.size(); ++k) xa(k) = a * x(k);
  const auto ya = nlid::filtfilt(f, xa);
  double worst = 0.0;
  for (Eigen::Index k = 0; k < x.size(); ++k) {
    worst = std::max(worst, std::abs(ya(k, 0).a - 2.0 * yd(k)) + std::abs(ya(k, 0).v(0) - yd(k)));
  }
  CHECK(worst < 1e-12);
}

// FilterScalar: what the filter kernels accept (and refuse) at compile time.
static_assert(nlid::FilterScalar<double>);
static_assert(nlid::FilterScalar<float>);
static_assert(nlid::FilterScalar<nlid::Dual<double, 3>>);
static_assert(nlid::FilterScalar<nlid::DynamicDual<double>>);
static_assert(!nlid::FilterScalar<std::string>);  // no product
static_assert(!nlid::FilterScalar<int*>);         // not constructible from double
static_assert(!nlid::FilterScalar<int>);          // would truncate the coefficients
template <class M>
concept CanFiltfilt = requires(const nlid::SosFilter& f, const M& m) {
  nlid::filtfilt(f, m);
};
static_assert(CanFiltfilt<Eigen::MatrixXd>);
static_assert(CanFiltfilt<Eigen::VectorXf>);
static_assert(!CanFiltfilt<Eigen::MatrixXi>);  // rejected at the interface, not deep inside
