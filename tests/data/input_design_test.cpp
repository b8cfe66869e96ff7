// Input design: known answers (PRBS period, balance and autocorrelation; multisine lines and
// levels; Gaussian moments; APRBS holds and range cover), band limits measured on the spectrum,
// seed reproducibility, and bad arguments named.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdint>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "nlid/data/input_design.hpp"

namespace {

// |DFT|² at line k of x (one whole period).
double line_power(const Eigen::VectorXd& x, Eigen::Index k) {
  std::complex<double> acc = 0.0;
  const auto n = static_cast<double>(x.size());
  for (Eigen::Index t = 0; t < x.size(); ++t)
    acc += x[t] * std::polar(1.0, -2.0 * std::numbers::pi * static_cast<double>(k * t % x.size()) / n);
  return std::norm(acc);
}

// Fraction of the power (mean removed) at frequencies above `edge` (fraction of Nyquist), from
// the DFT of the whole record.
double power_above(Eigen::VectorXd x, double edge) {
  x.array() -= x.mean();
  double above = 0.0, total = 0.0;
  const Eigen::Index n = x.size();
  for (Eigen::Index k = 1; k <= n / 2; ++k) {
    const double p = line_power(x, k);
    total += p;
    if (2.0 * static_cast<double>(k) / static_cast<double>(n) > edge) above += p;
  }
  return above / total;
}

}  // namespace

TEST_CASE("PRBS registers have the maximal period for every length", "[data][input_design]") {
  for (int bits = 2; bits <= nlid::prbs_max_bits; ++bits) {
    const std::uint32_t start = (std::uint32_t{1} << bits) - 1u;
    std::uint32_t s = nlid::prbs_next_state(bits, start);  // the checked entry point once,
    long long period = 1;                                   // then the kernel prbs() runs
    while (s != start && period <= (1ll << bits)) {
      s = nlid::detail::prbs_step(bits, s);
      ++period;
    }
    INFO("bits = " << bits);
    CHECK(period == (1ll << bits) - 1);
  }
}

TEST_CASE("PRBS: levels, hold, balance and two-valued autocorrelation", "[data][input_design]") {
  const int bits = 7, chips = 127;
  const Eigen::VectorXd u = nlid::prbs(bits, 2, {0.5, 2.0}, 3);
  REQUIRE(u.size() == 2 * chips * 3);
  CHECK(u.head(chips * 3) == u.tail(chips * 3));  // periodic
  for (Eigen::Index k = 0; k < u.size(); k += 3) {
    CHECK((u[k] == 0.5 || u[k] == 2.0));
    CHECK(u[k + 1] == u[k]);
    CHECK(u[k + 2] == u[k]);
  }
  const Eigen::VectorXd p = nlid::prbs(bits);  // ±1, hold 1
  CHECK((p.array() > 0).count() == 64);         // 2^(bits-1) high chips per period
  CHECK((p.array() < 0).count() == 63);
  // Circular autocorrelation of a maximum-length sequence: N at lag 0, −1 at every other lag.
  for (int lag = 0; lag < chips; ++lag) {
    double r = 0.0;
    for (int t = 0; t < chips; ++t) r += p[t] * p[(t + lag) % chips];
    CHECK(r == (lag == 0 ? 127.0 : -1.0));
  }
}

TEST_CASE("Multisine: only the chosen lines, flat amplitude, exact levels", "[data][input_design]") {
  nlid::MultisineOptions o;
  o.band = {0.0, 0.5};
  o.levels = {-2.0, 3.0};
  o.periods = 2;
  const Eigen::Index n = 256;
  const std::vector<Eigen::Index> lines = nlid::multisine_lines(n, o);
  REQUIRE(lines.size() == 64u);  // 1 … 64: 0.5 of Nyquist is line 64 of a 256-sample period
  CHECK(lines.front() == 1);
  CHECK(lines.back() == 64);
  const Eigen::VectorXd u = nlid::multisine(n, o);
  REQUIRE(u.size() == 2 * n);
  CHECK(u.head(n) == u.tail(n));
  CHECK(u.minCoeff() == Approx(-2.0).margin(1e-12));
  CHECK(u.maxCoeff() == Approx(3.0).margin(1e-12));
  const Eigen::VectorXd one = u.head(n);
  const double p1 = line_power(one, 1);
  for (Eigen::Index k = 1; k < n / 2; ++k) {
    const double p = line_power(one, k);
    if (k <= 64) CHECK(p == Approx(p1).epsilon(1e-9));
    else CHECK(p < 1e-12 * p1);
  }
  // Schroeder's phases keep the crest factor low: max |u − mean| / rms, about 1.7 for a flat
  // spectrum (a single cosine: 1.41); all lines in phase would give √(2·64) ≈ 11.
  const Eigen::ArrayXd c = one.array() - one.mean();
  const double crest = c.abs().maxCoeff() / std::sqrt(c.square().mean());
  CHECK(crest < 2.0);
}

TEST_CASE("Odd and random-odd multisines leave the detection lines empty", "[data][input_design]") {
  nlid::MultisineOptions o;
  o.band = {0.0, 1.0};
  o.lines = nlid::MultisineLines::odd;
  const Eigen::Index n = 200;
  const std::vector<Eigen::Index> odd = nlid::multisine_lines(n, o);
  CHECK(odd.size() == 50u);  // 1, 3, …, 99
  CHECK(std::all_of(odd.begin(), odd.end(), [](Eigen::Index k) { return k % 2 == 1; }));
  o.lines = nlid::MultisineLines::random_odd;
  o.seed = 7;
  const std::vector<Eigen::Index> ro = nlid::multisine_lines(n, o);
  // 12 full groups of 4 odd lines lose one each; the last 2 lines form a short group, kept.
  CHECK(ro.size() == 50u - 12u);
  for (std::size_t g = 0; g < 12; ++g) {
    const Eigen::Index first = static_cast<Eigen::Index>(8 * g + 1);
    const auto in_group = std::count_if(ro.begin(), ro.end(), [&](Eigen::Index k) { return k >= first && k < first + 8; });
    CHECK(in_group == 3);
  }
  const Eigen::VectorXd u = nlid::multisine(n, o);
  const double p1 = line_power(u, ro.front());
  for (Eigen::Index k = 1; k < n / 2; ++k) {
    const bool excited = std::find(ro.begin(), ro.end(), k) != ro.end();
    if (excited) CHECK(line_power(u, k) == Approx(p1).epsilon(1e-9));
    else CHECK(line_power(u, k) < 1e-12 * p1);
  }
  o.seed = 8;
  CHECK(nlid::multisine_lines(n, o) != ro);  // the detection lines follow the seed
}

TEST_CASE("Band-limited noise: Gaussian moments, binary levels, power inside the band", "[data][input_design]") {
  const Eigen::Index n = 2048;
  const Eigen::VectorXd g = nlid::random_gaussian(n, {0.0, 0.2}, {1.0, 5.0}, 3);
  CHECK(g.mean() == Approx(3.0).epsilon(1e-12));
  CHECK(std::sqrt((g.array() - g.mean()).square().mean()) == Approx(2.0).epsilon(1e-12));
  CHECK(power_above(g, 0.3) < 0.01);
  CHECK(power_above(nlid::random_gaussian(n, {}, {}, 3), 0.3) > 0.6);  // white: ~70 % above 0.3
  // A band starting above zero removes the low frequencies too.
  Eigen::VectorXd bp = nlid::random_gaussian(n, {0.4, 0.6}, {}, 4);
  CHECK(power_above(bp, 0.8) < 0.01);
  CHECK(power_above(bp, 0.2) > 0.99);
  const Eigen::VectorXd b = nlid::random_binary(n, {0.0, 0.1}, {0.0, 10.0}, 5);
  CHECK(((b.array() == 0.0) || (b.array() == 10.0)).all());
  CHECK((b.array() == 10.0).count() > n / 3);
  CHECK((b.array() == 0.0).count() > n / 3);
  // Sign changes are far rarer than for white noise: the band is a tenth of Nyquist.
  Eigen::Index changes = 0;
  for (Eigen::Index k = 1; k < n; ++k) changes += b[k] != b[k - 1] ? 1 : 0;
  CHECK(changes < n / 10);
}

TEST_CASE("Random steps (APRBS): hold times, one amplitude per slice of the range", "[data][input_design]") {
  const Eigen::Index n = 5000;
  const Eigen::VectorXd u = nlid::random_steps(n, 20, 80, {15.0, 90.0}, 11);
  REQUIRE(u.size() == n);
  std::vector<Eigen::Index> holds;
  std::vector<double> amps;
  for (Eigen::Index k = 0; k < n;) {
    Eigen::Index e = k;
    while (e < n && u[e] == u[k]) ++e;
    holds.push_back(e - k);
    amps.push_back(u[k]);
    k = e;
  }
  for (std::size_t i = 0; i + 1 < holds.size(); ++i) {
    CHECK(holds[i] >= 20);
    CHECK(holds[i] <= 80);
  }
  CHECK(holds.back() <= 80);
  // m steps: the sorted amplitudes lie one in each m-th of [15, 90].
  std::sort(amps.begin(), amps.end());
  const double w = 75.0 / static_cast<double>(amps.size());
  for (std::size_t i = 0; i < amps.size(); ++i) {
    CHECK(amps[i] >= 15.0 + w * static_cast<double>(i));
    CHECK(amps[i] <= 15.0 + w * static_cast<double>(i + 1));
  }
}

TEST_CASE("Designed inputs depend on the seed alone", "[data][input_design]") {
  CHECK(nlid::random_gaussian(500, {0.0, 0.5}, {}, 9) == nlid::random_gaussian(500, {0.0, 0.5}, {}, 9));
  CHECK(nlid::random_gaussian(500, {0.0, 0.5}, {}, 9) != nlid::random_gaussian(500, {0.0, 0.5}, {}, 10));
  CHECK(nlid::random_steps(300, 5, 9, {}, 2) == nlid::random_steps(300, 5, 9, {}, 2));
  CHECK(nlid::random_steps(300, 5, 9, {}, 2) != nlid::random_steps(300, 5, 9, {}, 3));
  nlid::MultisineOptions o;
  o.phases = nlid::MultisinePhases::random;
  o.seed = 4;
  const Eigen::VectorXd a = nlid::multisine(100, o);
  CHECK(a == nlid::multisine(100, o));
  o.seed = 5;
  CHECK(a != nlid::multisine(100, o));
  // Pinned values: std::mt19937_64 is fixed by the standard and the variates are computed by
  // nlid, so these are the same on every platform; a change here changes every user's signal.
  std::mt19937_64 g(1);
  CHECK(nlid::detail::uniform01(g) == 0.13387664401253263);
  CHECK(nlid::detail::standard_normal(g) == Approx(-0.51633441868505159).epsilon(1e-14));
}

TEST_CASE("Input design refuses bad arguments, naming them", "[data][input_design][errors]") {
  using Catch::Contains;
  CHECK_THROWS_WITH(nlid::prbs(1), Contains("bits must be in 2 ... 24"));
  CHECK_THROWS_WITH(nlid::prbs(25), Contains("bits must be in 2 ... 24"));
  CHECK_THROWS_WITH(nlid::prbs(5, 0), Contains("periods must be >= 1"));
  CHECK_THROWS_WITH(nlid::prbs(5, 1, {}, 0), Contains("hold must be >= 1"));
  CHECK_THROWS_WITH(nlid::prbs(5, 1, {1.0, 1.0}), Contains("low < high"));
  CHECK_THROWS_WITH(nlid::prbs(5, 1, {0.0, NAN}), Contains("levels must be finite"));
  // Levels whose span overflows: refused by every generator, not written as inf/NaN.
  CHECK_THROWS_WITH(nlid::random_steps(100, 5, 10, {-1e308, 1e308}), Contains("finite span") && Contains("-1e+308"));
  nlid::MultisineOptions wide;
  wide.levels = {-1e308, 1e308};
  CHECK_THROWS_WITH(nlid::multisine(64, wide), Contains("finite span"));
  CHECK_THROWS_WITH(nlid::random_gaussian(100, {}, {-1e308, 1e308}), Contains("finite span"));
  CHECK_THROWS_WITH(nlid::random_gaussian(1000, {}, {-8e307, 8e307}), Contains("tails are not finite"));
  CHECK(nlid::random_gaussian(1000, {}, {-1e300, 1e300}).allFinite());
  CHECK_THROWS_WITH(nlid::prbs(24, 200), Contains("more than 2^31"));
  CHECK_THROWS_WITH(nlid::random_binary(0), Contains("at least 1 sample"));
  CHECK_THROWS_WITH(nlid::random_binary(100, {0.5, 0.5}), Contains("0 <= low < high <= 1"));
  CHECK_THROWS_WITH(nlid::random_gaussian(100, {0.0, 1.5}), Contains("band must satisfy"));
  CHECK_THROWS_WITH(nlid::random_gaussian(1), Contains("at least 2 samples"));
  nlid::MultisineOptions o;
  o.band = {0.0, 0.01};
  CHECK_THROWS_WITH(nlid::multisine(50, o), Contains("no DFT line of a 50-sample period lies in the band"));
  o.band = {};
  CHECK_THROWS_WITH(nlid::multisine(3, o), Contains("period must be >= 4"));
  o.periods = 0;
  CHECK_THROWS_WITH(nlid::multisine(64, o), Contains("periods must be >= 1"));
  CHECK_THROWS_WITH(nlid::random_steps(100, 0, 5), Contains("min_hold must be >= 1"));
  CHECK_THROWS_WITH(nlid::random_steps(100, 6, 5), Contains("max_hold (5) must be >= min_hold (6)"));
  try {
    (void)nlid::random_steps(100, 6, 5);
    FAIL("random_steps accepted max_hold < min_hold");
  } catch (const nlid::Error& e) {
    CHECK(e.where().parameter == "max_hold");
  }
}

TEST_CASE("Input design refuses signals longer than 2^31 samples before allocating them",
          "[data][input_design][errors]") {
  using Catch::Contains;
  const auto parameter_of = [](auto&& make) {
    try {
      (void)make();
    } catch (const nlid::Error& e) {
      return e.where().parameter;
    }
    FAIL("expected nlid::Error");
    return std::string();
  };
  // (2^24 - 1) * 2^20 * 2^20 wraps around in 64 bits; the wrapped product passed the old check.
  CHECK_THROWS_WITH(nlid::prbs(24, 1 << 20, {}, 1 << 20), Contains("more than 2^31 samples"));
  CHECK(parameter_of([] { return nlid::prbs(24, 1 << 20, {}, 1 << 20); }) == "periods");
  CHECK(parameter_of([] { return nlid::prbs(20, 1000, {}, 1000); }) == "hold");
  CHECK(parameter_of([] { return nlid::prbs(2, 2147483647, {}, 2147483647); }) == "periods");
  CHECK(nlid::prbs(10, 3, {}, 2).size() == 1023 * 3 * 2);
  nlid::MultisineOptions o;
  CHECK_THROWS_WITH(nlid::multisine(Eigen::Index{1} << 40, o), Contains("more than 2^31"));
  CHECK(parameter_of([&] { return nlid::multisine(Eigen::Index{1} << 40, o); }) == "period");
  CHECK(parameter_of([&] { return nlid::multisine_lines(Eigen::Index{1} << 40, o); }) == "period");
  o.periods = 1 << 30;
  CHECK_THROWS_WITH(nlid::multisine(1024, o), Contains("more than 2^31 samples"));
  CHECK(parameter_of([&] { return nlid::multisine(1024, o); }) == "periods");
  CHECK(parameter_of([] { return nlid::random_steps(Eigen::Index{1} << 40, 1, 5); }) == "n");
  CHECK(parameter_of([] { return nlid::random_binary(Eigen::Index{1} << 40); }) == "n");
  // A band edge too narrow for the band-limiting filter is the band's fault, not a filter section's.
  CHECK(parameter_of([] { return nlid::random_binary(1000, {1e-17, 1.0}); }) == "band");
  CHECK_THROWS_WITH(nlid::random_binary(1000, {1e-17, 1.0}), Contains("band edge 1e-17"));
  CHECK(parameter_of([] { return nlid::random_gaussian(1000, {0.0, 1e-9}); }) == "band");
}

TEST_CASE("Random binary: a band too narrow for the length is refused, not written as a constant", "[data][input_design][errors]") {
  // Band 0 … 0.001 of Nyquist on 100 samples: the noise drifts without changing sign.
  try {
    (void)nlid::random_binary(100, {0.0, 0.001});
    FAIL("random_binary gave a constant signal for a band far narrower than 1/n");
  } catch (const nlid::Error& e) {
    CHECK_THAT(e.message(), Catch::Contains("band [0, 0.001]") && Catch::Contains("too narrow for 100 samples"));
    CHECK(e.where().parameter == "band");
  }
  // Long enough for the same band: both levels, as before.
  const Eigen::VectorXd u = nlid::random_binary(100000, {0.0, 0.001});
  CHECK(u.minCoeff() == -1.0);
  CHECK(u.maxCoeff() == 1.0);
}
