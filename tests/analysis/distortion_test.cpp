// Nonlinear distortion analysis: known answers from theory on a Wiener system excited by a
// random-odd multisine — a linear system shows nothing on the empty lines and its frequency
// response is recovered; a square term shows on the even lines only, a cube on the odd ones.
#include "nlid/analysis/distortion.hpp"

#include <catch2/catch.hpp>
#include <cmath>
#include <complex>
#include <string>
#include <utility>

#include "nlid/data/input_design.hpp"

namespace {

constexpr Eigen::Index kPeriod = 512;

// x(t) = 0.9 x(t-1) + 0.1 u(t); y = x + a2 x² + a3 x³ + noise (σ = 1e-3), 1 + 4 periods.
nlid::Experiment wiener(double a2, double a3,
                        nlid::MultisineLines lines = nlid::MultisineLines::random_odd,
                        double sigma = 1e-3) {
  nlid::MultisineOptions o;
  o.band = {0.0, 0.3};
  o.lines = lines;
  o.periods = 5;
  o.seed = 2;
  o.phases = nlid::MultisinePhases::random;
  const Eigen::VectorXd u = nlid::multisine(kPeriod, o);
  const Eigen::VectorXd noise = sigma > 0 ? nlid::random_gaussian(u.size(), {}, {-sigma, sigma}, 17)
                                          : Eigen::VectorXd::Zero(u.size());
  Eigen::VectorXd y(u.size());
  double x = 0.0;
  for (Eigen::Index t = 0; t < u.size(); ++t) {
    x = 0.9 * x + 0.1 * u[t];
    y[t] = x + a2 * x * x + a3 * x * x * x + noise[t];
  }
  return nlid::Experiment(u, y, 0.01, "wiener");
}

}  // namespace

TEST_CASE("Distortion analysis: a linear system shows no distortion and its FRF",
          "[analysis][distortion]") {
  const nlid::DistortionAnalysis d = nlid::distortion_analysis(wiener(0.0, 0.0), kPeriod);
  CHECK(d.periods == 4);
  // Band 0.3 of Nyquist: lines 1 … 76; odd ones 1 … 75 (38), one of each 4 left out (9 groups).
  CHECK(d.excited.size() == 29u);
  CHECK(d.odd_lines.size() == 9u);
  CHECK(d.even_lines.size() == 37u);  // 2 … 74 between the first and the last excited line
  CHECK_FALSE(d.even_detected());
  CHECK_FALSE(d.odd_detected());
  CHECK(std::abs(d.even_db()) < 3.0);  // noise only: the level of the noise, 0 dB
  CHECK(std::abs(d.odd_db()) < 3.0);
  CHECK(d.snr_db() > 30.0);
  double worst = 0.0;
  for (std::size_t i = 0; i < d.excited.size(); ++i) {
    const double w =
        2.0 * std::numbers::pi * static_cast<double>(d.excited[i]) / static_cast<double>(kPeriod);
    const std::complex<double> g = 0.1 / (1.0 - 0.9 * std::polar(1.0, -w));
    worst = std::max(worst, std::abs(d.frf[static_cast<Eigen::Index>(i)] - g) / std::abs(g));
  }
  CHECK(worst < 0.02);
  CHECK(d.frequency(d.excited.front()) ==
        Approx(static_cast<double>(d.excited.front()) / (kPeriod * 0.01)));
  CHECK_THAT(
      d.report(),
      Catch::Contains("no distortion above the noise: a linear model can explain these data"));
}

TEST_CASE("Distortion analysis: a square term shows on the even lines, a cube on the odd ones",
          "[analysis][distortion]") {
  const nlid::DistortionAnalysis even = nlid::distortion_analysis(wiener(0.5, 0.0), kPeriod);
  CHECK(even.even_detected());
  CHECK(even.even_db() > 20.0);
  CHECK_FALSE(even.odd_detected());
  const nlid::DistortionAnalysis odd = nlid::distortion_analysis(wiener(0.0, 0.5), kPeriod);
  CHECK(odd.odd_detected());
  CHECK(odd.odd_db() > 20.0);
  CHECK_FALSE(odd.even_detected());
  CHECK_THAT(odd.report(), Catch::Contains("odd distortion:") && Catch::Contains("present") &&
                               Catch::Contains("a nonlinear structure is warranted"));
  // All lines excited: nothing to detect with, and the report says what to use instead.
  const nlid::DistortionAnalysis full =
      nlid::distortion_analysis(wiener(0.5, 0.5, nlid::MultisineLines::all), kPeriod);
  CHECK(full.even_lines.empty());
  CHECK(full.odd_lines.empty());
  CHECK_FALSE(full.even_detected());
  CHECK_THAT(full.report(),
             Catch::Contains("no empty even lines in the band (use odd or random-odd lines)"));
}

TEST_CASE("Distortion analysis: an odd multisine cannot measure odd distortion, and says so",
          "[analysis][distortion]") {
  // Every odd line excited: a cube's distortion falls on excited lines. The old report read
  // "not detected" there and concluded "a linear model can explain these data".
  const nlid::DistortionAnalysis d =
      nlid::distortion_analysis(wiener(0.0, 0.5, nlid::MultisineLines::odd), kPeriod);
  CHECK(d.even_measurable());
  CHECK_FALSE(d.odd_measurable());
  CHECK(d.odd_lines.empty());
  CHECK_FALSE(d.odd_detected());
  CHECK_FALSE(d.even_detected());
  const std::string r = d.report();
  CHECK_THAT(r, !Catch::Contains("a linear model can explain"));
  CHECK_THAT(r, Catch::Contains("odd distortion: not measurable, no empty odd lines in the band (use random-odd lines)"));
  CHECK_THAT(r, Catch::Contains("no even distortion above the noise, but odd distortion cannot be measured with this "
                                "input: no verdict on linearity"));
  // The same system on random-odd lines: both measurable, the cube is found.
  const nlid::DistortionAnalysis ro = nlid::distortion_analysis(wiener(0.0, 0.5), kPeriod);
  CHECK(ro.even_measurable());
  CHECK(ro.odd_measurable());
  CHECK(ro.odd_detected());
  // All lines excited: neither kind measurable, no verdict.
  const nlid::DistortionAnalysis full =
      nlid::distortion_analysis(wiener(0.0, 0.0, nlid::MultisineLines::all), kPeriod);
  CHECK_FALSE(full.even_measurable());
  CHECK_FALSE(full.odd_measurable());
  CHECK_THAT(full.report(), Catch::Contains("neither kind of distortion can be measured") &&
                                !Catch::Contains("a linear model can explain"));
}

TEST_CASE("Distortion analysis of a noise-free (simulated) record compares with the rounding floor",
          "[analysis][distortion]") {
  // No noise: the spread between periods is zero, and "0 dB above the noise" would hide any
  // distortion; the levels are taken against the DFT's rounding floor instead.
  const nlid::DistortionAnalysis odd =
      nlid::distortion_analysis(wiener(0.0, 0.05, nlid::MultisineLines::random_odd, 0.0), kPeriod);
  CHECK(odd.noise_free());
  CHECK(odd.odd_detected());
  CHECK_FALSE(odd.even_detected());
  CHECK_THAT(odd.report(), Catch::Contains("no measurable noise"));
  const nlid::DistortionAnalysis lin =
      nlid::distortion_analysis(wiener(0.0, 0.0, nlid::MultisineLines::random_odd, 0.0), kPeriod);
  CHECK(lin.noise_free());
  CHECK_FALSE(lin.odd_detected());
  CHECK_FALSE(lin.even_detected());
  CHECK(lin.snr_db() > 200.0);
}

TEST_CASE("Distortion analysis refuses records it cannot analyse, naming the parameter",
          "[analysis][distortion][errors]") {
  const nlid::Experiment e = wiener(0.0, 0.0);
  CHECK_THROWS_WITH(nlid::distortion_analysis(e, 4), Catch::Contains("period must be >= 8"));
  CHECK_THROWS_WITH(
      nlid::distortion_analysis(e, kPeriod, 4),
      Catch::Contains("hold 5 whole period(s) of 512; after skipping 4 at least 2 must remain"));
  CHECK_THROWS_WITH(nlid::distortion_analysis(e, kPeriod, -1),
                    Catch::Contains("skip_periods must be >= 0"));
  // At or below the noise level every noise line would count as distortion.
  CHECK_THROWS_WITH(nlid::distortion_analysis(e, kPeriod, 1, -5.0),
                    Catch::Contains("threshold_db must be a finite level above the noise") &&
                        Catch::Contains("got -5.0"));
  CHECK_THROWS_WITH(nlid::distortion_analysis(e, kPeriod, 1, 0.0), Catch::Contains("threshold_db"));
  const nlid::Experiment flat(Eigen::VectorXd::Constant(2048, 0.3), Eigen::VectorXd::Zero(2048),
                              0.01);
  CHECK_THROWS_WITH(nlid::distortion_analysis(flat, kPeriod),
                    Catch::Contains("no power at any line"));
  try {
    (void)nlid::distortion_analysis(e, 2000);
  } catch (const nlid::Error& err) {
    CHECK(err.where().parameter == "period");
  }
  // An input that does not repeat with the given period: a wrong period (one sample short) or
  // a non-periodic excitation. Analysed anyway, the input's own change between periods would
  // read as "noise" and the verdict would be the confident "a linear model can explain these data".
  CHECK_THROWS_WITH(nlid::distortion_analysis(e, kPeriod - 1), Catch::Contains("the input does not repeat every 511 samples"));
  const Eigen::VectorXd noise_u = nlid::random_gaussian(4 * kPeriod, {0.0, 0.5}, {-1.0, 1.0}, 5);
  const nlid::Experiment random_input(noise_u, 0.5 * noise_u, 0.01);
  CHECK_THROWS_WITH(nlid::distortion_analysis(random_input, kPeriod), Catch::Contains("needs a periodic input"));
  // A periodic input with a little measurement noise (-40 dB) is still analysed.
  nlid::Experiment noisy_u = wiener(0.0, 0.0);
  noisy_u.u().col(0) += nlid::random_gaussian(noisy_u.size(), {}, {-0.003, 0.003}, 9);
  CHECK_NOTHROW(nlid::distortion_analysis(noisy_u, kPeriod));
}

TEST_CASE("Distortion analysis: an output buried in noise gives no verdict, not 'linear'", "[analysis][distortion]") {
  // σ = 10 against an output of about 0.1: nothing above the noise on any line.
  const nlid::DistortionAnalysis d = nlid::distortion_analysis(wiener(0.5, 0.5, nlid::MultisineLines::random_odd, 10.0), kPeriod);
  CHECK_FALSE(d.conclusive());
  CHECK_THAT(d.report(), Catch::Contains("no conclusion") && !Catch::Contains("a linear model can explain"));
  CHECK(nlid::distortion_analysis(wiener(0.0, 0.0), kPeriod).conclusive());
}

TEST_CASE("Distortion analysis: huge and tiny finite records give the same levels as ordinary ones",
          "[analysis][distortion]") {
  // Powers are sums of squares: unscaled, an output near 1e301 overflowed to inf (NaN dB and a
  // "linear" verdict), an input near 1e301 read as one without power.
  const nlid::Experiment base = wiener(0.5, 0.0);
  const nlid::DistortionAnalysis ref = nlid::distortion_analysis(base, kPeriod);
  REQUIRE(ref.even_detected());
  for (const auto& [ku, ky] : {std::pair{1.0, 7e300}, std::pair{7e300, 1.0}, std::pair{1e300, 1e-300}, std::pair{1e-300, 1.0}}) {
    INFO("input x " << ku << ", output x " << ky);
    const nlid::Experiment e(base.u() * ku, base.y() * ky, base.ts(), "scaled");
    const nlid::DistortionAnalysis d = nlid::distortion_analysis(e, kPeriod);
    CHECK(d.excited == ref.excited);
    CHECK(d.snr_db() == Approx(ref.snr_db()).epsilon(1e-9));
    CHECK(d.even_db() == Approx(ref.even_db()).epsilon(1e-9));
    CHECK(d.odd_db() == Approx(ref.odd_db()).epsilon(1e-9));
    CHECK(d.even_detected());
    CHECK_FALSE(d.odd_detected());
    // The frequency response in the record's units, where it is a double (1e-600 is not).
    if (ky / ku > 1e-290 && ky / ku < 1e290) {
      const std::complex<double> g = d.frf[0] / (ky / ku), g0 = ref.frf[0];
      CHECK(std::abs(g - g0) <= 1e-9 * std::abs(g0));
    }
    CHECK(d.report().find("nan") == std::string::npos);
  }
}

TEST_CASE("Distortion analysis: a zero output gives no verdict and no NaN level", "[analysis][distortion]") {
  // Every level is 0 against a floor of 0: the report printed "nan dB" and "a linear model can
  // explain these data".
  const nlid::Experiment base = wiener(0.0, 0.0);
  const nlid::Experiment e(base.u(), Eigen::VectorXd::Zero(base.size()), base.ts(), "flat");
  const nlid::DistortionAnalysis d = nlid::distortion_analysis(e, kPeriod);
  CHECK_FALSE(d.conclusive());
  const std::string r = d.report();
  CHECK(r.find("nan") == std::string::npos);
  CHECK_THAT(r, Catch::Contains("no conclusion: the output has no power at the excited lines"));
  CHECK(r.find("a linear model can explain") == std::string::npos);
}

TEST_CASE("Distortion analysis: a constant or offset noise-free output is not read as distortion",
          "[analysis][distortion]") {
  // The rounding floor was 1e-24 of the excited level: a constant output has nothing but
  // rounding on its excited lines, so that rounding stood 240 dB "above the noise" on the
  // detection lines too, and the report said "present" and "a nonlinear structure is warranted".
  const nlid::Experiment base = wiener(0.0, 0.0, nlid::MultisineLines::random_odd, 0.0);
  for (const double level : {1.0, 3.7, -250.0, 1e-5}) {
    INFO("constant output " << level);
    const nlid::Experiment e(base.u(), Eigen::VectorXd::Constant(base.size(), level), base.ts(), "constant");
    const nlid::DistortionAnalysis d = nlid::distortion_analysis(e, kPeriod);
    CHECK(d.noise_free());
    CHECK_FALSE(d.even_detected());
    CHECK_FALSE(d.odd_detected());
    CHECK_FALSE(d.conclusive());
    const std::string r = d.report();
    CHECK_THAT(r, Catch::Contains("no conclusion: the output at the excited lines is at the DFT's rounding floor"));
    CHECK_THAT(r, !Catch::Contains("present") && !Catch::Contains("nonlinear structure") &&
                      !Catch::Contains("a linear model can explain"));
  }
  // A response far above rounding with a threshold beyond it: the threshold is the reason, not
  // "at the DFT's rounding floor (constant, or not a response to this input)".
  {
    const nlid::DistortionAnalysis d = nlid::distortion_analysis(base, kPeriod, 1, 300.0);
    CHECK(d.noise_free());
    CHECK_FALSE(d.conclusive());
    CHECK(d.snr_db() > 100.0);
    CHECK_THAT(d.report(), Catch::Contains("dB above the DFT's rounding floor, not more than the threshold of 300.0 dB") &&
                               Catch::Contains("lower the threshold") && !Catch::Contains("constant, or not a response"));
  }
  // An offset adds rounding in proportion to its own power: a linear response on top of a large
  // offset stays linear, and a cube on top of it is still found.
  for (const double offset : {100.0, 1e4}) {
    INFO("offset " << offset);
    const nlid::Experiment lin(base.u(), base.y().array() + offset, base.ts(), "offset linear");
    const nlid::DistortionAnalysis d = nlid::distortion_analysis(lin, kPeriod);
    CHECK(d.conclusive());
    CHECK_FALSE(d.even_detected());
    CHECK_FALSE(d.odd_detected());
    CHECK_THAT(d.report(), Catch::Contains("a linear model can explain these data"));
    const nlid::Experiment cube = wiener(0.0, 0.05, nlid::MultisineLines::random_odd, 0.0);
    const nlid::DistortionAnalysis c =
        nlid::distortion_analysis(nlid::Experiment(cube.u(), cube.y().array() + offset, cube.ts(), "offset cube"), kPeriod);
    CHECK(c.conclusive());
    CHECK(c.odd_detected());
    CHECK_FALSE(c.even_detected());
  }
}
