#pragma once
/// @file
/// Input signals for identification experiments (the toolbox's `idinput`, plus the amplitude-
/// modulated steps that nonlinear models need).
///
/// Why these five. A linear model needs power at every frequency of interest; a nonlinear one
/// also needs every *amplitude* of interest (Nelles, "Nonlinear System Identification", 2001,
/// sec. 19.7: a binary signal shows a nonlinear model two points of its static map). So:
///
/// - `prbs`: maximum-length pseudo-random binary sequence. Over whole periods its spectrum is
///   flat at the chip rate and its circular autocorrelation two-valued, the classic linear test
///   signal. Binary: useless for the shape of a nonlinearity.
/// - `random_binary`, `random_gaussian`: band-limited noise, then its sign (binary) or scaled
///   (Gaussian: `levels` are mean ∓ one standard deviation, the toolbox's convention).
/// - `multisine`: a sum of cosines on the DFT grid of one period, flat amplitude spectrum, phases
///   by Schroeder's rule (low crest factor) or at random. Lines can be restricted to odd ones or
///   to "random odd" ones (Pintelon & Schoukens, "System Identification: A Frequency Domain
///   Approach", 2nd ed., 2012, sec. 3.4): the unexcited lines of a periodic steady state then
///   show the nonlinear distortion directly (even lines: even-order, left-out odd lines: odd-order).
/// - `random_steps`: amplitude-modulated random steps (APRBS): hold times drawn in
///   [min_hold, max_hold], one amplitude per equal slice of the level range in random order, so
///   the whole range is visited and every step can settle.
///
/// Reproducibility. Every random signal is a function of its seed alone, on every platform: the
/// generator is `std::mt19937_64` (its output is fixed by the C++ standard) and the uniform and
/// normal variates are computed here (the standard distributions are implementation-defined).
///
/// Frequencies are fractions of the Nyquist frequency (1 = half the sampling rate), as in
/// `butterworth_lowpass`. Band-limiting of noise is a zero-phase Butterworth filter of order 8
/// (`filtfilt`: attenuation −6 dB at the band edge, 16th-order roll-off outside); a band starting
/// above 0 subtracts the low-pass at its lower edge.

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/data/detail/dft_table.hpp"
#include "nlid/data/detail/per_experiment.hpp"
#include "nlid/data/filter.hpp"

namespace nlid {

/// Amplitudes of a designed input: the two values of a binary signal; mean − σ and mean + σ of a
/// Gaussian one; the minimum and maximum of a multisine or of random steps.
struct InputLevels {
  double low = -1.0;
  double high = 1.0;
};

/// Excited band as fractions of the Nyquist frequency, 0 ≤ low < high ≤ 1.
struct InputBand {
  double low = 0.0;
  double high = 1.0;
};

/// Which DFT lines of the band a multisine excites.
enum class MultisineLines {
  all,         ///< every line in the band
  odd,         ///< odd lines only (even-order distortion lands on the empty even lines)
  random_odd,  ///< odd lines, one of every 4 consecutive ones left out at random (detection lines)
};

/// Phases of a multisine's cosines.
enum class MultisinePhases {
  schroeder,  ///< φ_j = −π j (j − 1)/K for the j-th of K lines: deterministic, crest factor ≈ 1.7
  random,     ///< uniform in [0, 2π) from the seed
};

/// Options of `multisine`.
struct MultisineOptions {
  InputBand band;                                       ///< excited band (fractions of Nyquist)
  InputLevels levels;                                   ///< minimum and maximum of the signal
  int periods = 1;                                      ///< repetitions of the period, ≥ 1
  MultisineLines lines = MultisineLines::all;           ///< which lines of the band
  MultisinePhases phases = MultisinePhases::schroeder;  ///< phase rule
  std::uint64_t seed = 1;                               ///< for random phases and random-odd lines
};

namespace detail {

inline void check_levels(const InputLevels& l) {
  // The span too: the generators scale by high − low, which overflows for levels near ±1e308.
  require(std::isfinite(l.low) && std::isfinite(l.high) && l.low < l.high && std::isfinite(l.high - l.low),
          "input design: levels must be finite with low < high and a finite span high - low, got [" +
              detail::format_g(l.low, 10) +
              ", " + detail::format_g(l.high, 10) + "]",
          at_parameter("levels"));
}

inline void check_band(const InputBand& b) {
  require(b.low >= 0.0 && b.high <= 1.0 && b.low < b.high,
          "input design: band must satisfy 0 <= low < high <= 1 (fractions of the Nyquist frequency), got [" +
              detail::format_f(b.low, 6) + ", " + detail::format_f(b.high, 6) + "]",
          at_parameter("band"));
}

// Largest signal the generators produce (16 GiB of doubles). Without a cap a mistyped length
// ends in std::bad_alloc, or in an index that wraps, instead of an error naming the argument.
inline constexpr long long input_max_samples = 1ll << 31;

inline void check_length(Eigen::Index n) {
  require(n >= 1, "input design: the signal needs at least 1 sample, got " + std::to_string(n), at_parameter("n"));
  require(n <= input_max_samples,
          "input design: " + std::to_string(n) + " samples is more than 2^31; generate a shorter signal",
          at_parameter("n"));
}

// Uniform in [0, 1) with 53 random bits (the standard's uniform_real_distribution is not
// specified bit for bit).
inline double uniform01(std::mt19937_64& g) { return static_cast<double>(g() >> 11) * 0x1.0p-53; }

// Standard normal by Box–Muller; one variate per call (the second is discarded for simplicity).
inline double standard_normal(std::mt19937_64& g) {
  const double u1 = 1.0 - uniform01(g);  // (0, 1]: log is finite
  const double u2 = uniform01(g);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
}

// White Gaussian noise limited to `band` (see the file comment).
inline Eigen::VectorXd band_noise(Eigen::Index n, const InputBand& band, std::uint64_t seed) {
  constexpr int order = 8;
  // The caller chose a band, not a filter: a too narrow edge is reported as the band's, and
  // before any noise is drawn.
  const auto lowpass = [&](double edge) {
    if (edge <= 0.0 || edge >= 1.0) return SosFilter();  // that side of the band is open
    try {
      return butterworth_lowpass(order, edge);
    } catch (const Error& err) {
      throw Error("input design: band edge " + format_g(edge, 6) + ": " + err.message(), at_parameter("band"));
    }
  };
  const SosFilter upper = lowpass(band.high), lower = lowpass(band.low);
  std::mt19937_64 g(seed);
  Eigen::VectorXd e(n);
  for (Eigen::Index k = 0; k < n; ++k) e[k] = standard_normal(g);
  if (band.high < 1.0) e = filtfilt(upper, e);
  if (band.low > 0.0) e -= filtfilt(lower, e);
  return e;
}

// Fibonacci-LFSR feedback masks whose sequences have the maximal period 2^n − 1 (n = 2 … 24):
// new bit = parity(state & mask), state = (state << 1 | bit) mod 2^n. Each was checked by running
// the register through its whole period (tests/data/input_design_test.cpp repeats that check).
inline constexpr std::uint32_t prbs_masks[] = {0x0,      0x0,     0x3,      0x5,      0x9,      0x12,
                                               0x21,     0x41,    0xc3,     0x108,    0x204,    0x402,
                                               0x883,    0x1013,  0x2803,   0x4001,   0x8805,   0x10004,
                                               0x20040,  0x40013, 0x80004,  0x100002, 0x200001, 0x400010,
                                               0x800043};

}  // namespace detail

/// Largest register length `prbs` accepts (period 2^24 − 1 = 16 777 215 chips).
inline constexpr int prbs_max_bits = 24;

namespace detail {
inline void check_prbs_bits(int bits) {
  if (bits < 2 || bits > prbs_max_bits)
    throw Error("prbs: bits must be in 2 ... " + std::to_string(prbs_max_bits) + ", got " + std::to_string(bits),
                at_parameter("bits"));
}
inline std::uint32_t prbs_step(int bits, std::uint32_t state) {
  const std::uint32_t fb = static_cast<std::uint32_t>(std::popcount(state & prbs_masks[bits]) & 1);
  return ((state << 1) | fb) & ((std::uint32_t{1} << bits) - 1u);
}
}  // namespace detail

/// One step of the maximum-length register of `bits` bits (2 … 24) used by `prbs`: returns the
/// next state. Starting from any nonzero state it returns there after exactly 2^bits − 1 steps.
inline std::uint32_t prbs_next_state(int bits, std::uint32_t state) {
  detail::check_prbs_bits(bits);
  return detail::prbs_step(bits, state);
}

/// Maximum-length PRBS: `periods` periods of 2^bits − 1 chips, each chip held for `hold` samples
/// (the spectrum then follows sinc²(π f·hold/f_s): first null at f_s/hold, i.e. 2/hold of the
/// Nyquist frequency, half power at ≈ 0.44 f_s/hold). The register starts with all bits set; a chip is
/// `levels.high` when the register's newest bit is 1. Per period: 2^(bits−1) high chips and
/// 2^(bits−1) − 1 low ones.
[[nodiscard]] inline Eigen::VectorXd prbs(int bits, int periods = 1, InputLevels levels = {}, int hold = 1) {
  detail::check_prbs_bits(bits);
  require(periods >= 1, "prbs: periods must be >= 1, got " + std::to_string(periods), at_parameter("periods"));
  require(hold >= 1, "prbs: hold must be >= 1 sample, got " + std::to_string(hold), at_parameter("hold"));
  detail::check_levels(levels);
  const long long chips = (1ll << bits) - 1;
  // Each factor is checked against what is left of the cap before it is multiplied in: the
  // plain product of three large arguments wraps around and would pass a check made afterwards.
  const long long cap = detail::input_max_samples;
  const auto too_long = [&](const char* parameter) {
    return Error("prbs: " + std::to_string(chips) + " chips x " + std::to_string(periods) + " periods x " +
                     std::to_string(hold) + " samples per chip is more than 2^31 samples; use fewer bits, periods or hold",
                 at_parameter(parameter));
  };
  if (periods > cap / chips) throw too_long("periods");
  if (hold > cap / (chips * periods)) throw too_long("hold");
  const long long n = chips * periods * hold;
  Eigen::VectorXd u(static_cast<Eigen::Index>(n));
  std::uint32_t s = (std::uint32_t{1} << bits) - 1u;
  Eigen::Index k = 0;
  for (long long c = 0; c < chips * periods; ++c) {
    s = detail::prbs_step(bits, s);
    const double v = (s & 1u) ? levels.high : levels.low;
    for (int h = 0; h < hold; ++h) u[k++] = v;
  }
  return u;
}

/// Random binary signal of `n` samples: the sign of band-limited Gaussian noise, mapped to the two
/// levels (zero counts as high).
[[nodiscard]] inline Eigen::VectorXd random_binary(Eigen::Index n, InputBand band = {}, InputLevels levels = {},
                                                   std::uint64_t seed = 1) {
  detail::check_length(n);
  detail::check_band(band);
  detail::check_levels(levels);
  Eigen::VectorXd e = detail::band_noise(n, band, seed);
  for (Eigen::Index k = 0; k < n; ++k) e[k] = e[k] >= 0.0 ? levels.high : levels.low;
  // A band much narrower than 1/n leaves noise that drifts without changing sign: a constant
  // "excitation" is refused, as random_gaussian refuses a band with no power left.
  require(n < 2 || (e.array() != e[0]).any(),
          "random_binary: the band [" + detail::format_g(band.low, 6) + ", " + detail::format_g(band.high, 6) +
              "] (fractions of Nyquist) is too narrow for " + std::to_string(n) +
              " samples: the signal would stay at one level; widen the band or generate more samples",
          at_parameter("band"));
  return e;
}

/// Band-limited Gaussian noise of `n` samples with sample mean (low + high)/2 and sample standard
/// deviation (high − low)/2 exactly.
[[nodiscard]] inline Eigen::VectorXd random_gaussian(Eigen::Index n, InputBand band = {}, InputLevels levels = {},
                                                     std::uint64_t seed = 1) {
  detail::check_length(n);
  detail::check_band(band);
  detail::check_levels(levels);
  require(n >= 2, "random_gaussian: needs at least 2 samples for a standard deviation", at_parameter("n"));
  Eigen::VectorXd e = detail::band_noise(n, band, seed);
  e.array() -= e.mean();
  const double sd = std::sqrt(e.squaredNorm() / static_cast<double>(n));
  require(sd > 0.0, "random_gaussian: the band is too narrow for " + std::to_string(n) + " samples (no power left)",
          at_parameter("band"));
  Eigen::VectorXd out = (e * ((levels.high - levels.low) / (2.0 * sd))).array() + 0.5 * (levels.low + levels.high);
  // Gaussian tails reach several deviations past the levels: near the largest doubles they overflow.
  require(out.allFinite(), "random_gaussian: levels this large overflow: the signal's tails are not finite",
          at_parameter("levels"));
  return out;
}

/// DFT lines (k of f = k/period cycles per sample) a multisine of this period and these options
/// excites: k in [⌈low·period/2⌉, ⌊high·period/2⌋], without DC and the Nyquist line, then thinned
/// by `lines`. Throws if none is left.
[[nodiscard]] inline std::vector<Eigen::Index> multisine_lines(Eigen::Index period, const MultisineOptions& o) {
  require(period >= 4, "multisine: the period must be >= 4 samples, got " + std::to_string(period),
          at_parameter("period"));
  require(period <= detail::input_max_samples,
          "multisine: the period of " + std::to_string(period) + " samples is more than 2^31; use a shorter period",
          at_parameter("period"));
  detail::check_band(o.band);
  const double half = 0.5 * static_cast<double>(period);
  Eigen::Index lo = static_cast<Eigen::Index>(std::ceil(o.band.low * half - 1e-9));
  Eigen::Index hi = static_cast<Eigen::Index>(std::floor(o.band.high * half + 1e-9));
  lo = std::max<Eigen::Index>(lo, 1);
  if (2 * hi >= period) hi = (period - 1) / 2;  // the Nyquist line is not excited
  std::vector<Eigen::Index> k;
  std::mt19937_64 g(o.seed ^ 0x9e3779b97f4a7c15ull);  // its own stream: phases do not shift the choice
  for (Eigen::Index j = lo; j <= hi; ++j) {
    if (o.lines != MultisineLines::all && j % 2 == 0) continue;
    k.push_back(j);
  }
  if (o.lines == MultisineLines::random_odd) {
    std::vector<Eigen::Index> kept;
    for (std::size_t b = 0; b < k.size(); b += 4) {
      const std::size_t m = std::min<std::size_t>(4, k.size() - b);
      const std::size_t drop = m == 4 ? static_cast<std::size_t>(detail::uniform01(g) * 4.0) : m;
      for (std::size_t i = 0; i < m; ++i)
        if (i != drop) kept.push_back(k[b + i]);
    }
    k = std::move(kept);
  }
  require(!k.empty(),
          "multisine: no DFT line of a " + std::to_string(period) + "-sample period lies in the band [" +
              detail::format_f(o.band.low, 6) + ", " + detail::format_f(o.band.high, 6) +
              "] (lines are 2/period apart in fractions of Nyquist); widen the band or lengthen the period",
          at_parameter("band"));
  return k;
}

/// Multisine: `o.periods` repetitions of one period of `period` samples,
/// u(t) = Σ_j cos(2π k_j t/period + φ_j) over the lines of `multisine_lines`, equal amplitudes,
/// scaled so that its minimum and maximum over a period are `o.levels`. Whole periods are what
/// make the spectrum exact (no leakage): discard the first period as a transient and analyse the
/// rest. Cost: period × lines operations.
[[nodiscard]] inline Eigen::VectorXd multisine(Eigen::Index period, const MultisineOptions& o = {}) {
  detail::check_levels(o.levels);
  require(o.periods >= 1, "multisine: periods must be >= 1, got " + std::to_string(o.periods), at_parameter("periods"));
  const std::vector<Eigen::Index> k = multisine_lines(period, o);  // also caps the period
  require(o.periods <= detail::input_max_samples / period,
          "multisine: " + std::to_string(o.periods) + " periods of " + std::to_string(period) +
              " samples is more than 2^31 samples; use fewer periods or a shorter period",
          at_parameter("periods"));
  const auto nl = static_cast<double>(k.size());
  std::vector<double> phi(k.size());
  std::mt19937_64 g(o.seed);
  for (std::size_t j = 0; j < k.size(); ++j) {
    const double jj = static_cast<double>(j + 1);
    phi[j] = o.phases == MultisinePhases::schroeder ? -std::numbers::pi * jj * (jj - 1.0) / nl
                                                    : 2.0 * std::numbers::pi * detail::uniform01(g);
  }
  const detail::DftTable tab(period);  // entry m = (k·t) mod period: exact integer angles
  const Eigen::VectorXd &c = tab.cos, &s = tab.sin;
  Eigen::VectorXd one = Eigen::VectorXd::Zero(period);
  for (std::size_t j = 0; j < k.size(); ++j) {
    const double cp = std::cos(phi[j]), sp = std::sin(phi[j]);
    Eigen::Index m = 0;
    for (Eigen::Index t = 0; t < period; ++t) {
      one[t] += c[m] * cp - s[m] * sp;  // cos(a + φ)
      m += k[j];
      if (m >= period) m -= period;
    }
  }
  const double mn = one.minCoeff(), mx = one.maxCoeff();
  one = ((one.array() - mn) * ((o.levels.high - o.levels.low) / (mx - mn)) + o.levels.low).matrix();
  Eigen::VectorXd u(period * o.periods);
  for (int p = 0; p < o.periods; ++p) u.segment(p * period, period) = one;
  return u;
}

/// Amplitude-modulated random steps (APRBS) of `n` samples: hold times drawn uniformly in
/// [min_hold, max_hold] samples (the last step is cut at n), and one amplitude per step drawn in
/// its own equal slice of [levels.low, levels.high], the slices in random order — so m steps
/// cover the range with one amplitude in each m-th of it, whatever the seed.
[[nodiscard]] inline Eigen::VectorXd random_steps(Eigen::Index n, Eigen::Index min_hold, Eigen::Index max_hold,
                                                  InputLevels levels = {}, std::uint64_t seed = 1) {
  detail::check_length(n);
  detail::check_levels(levels);
  require(min_hold >= 1, "random_steps: min_hold must be >= 1 sample, got " + std::to_string(min_hold),
          at_parameter("min_hold"));
  require(max_hold >= min_hold,
          "random_steps: max_hold (" + std::to_string(max_hold) + ") must be >= min_hold (" + std::to_string(min_hold) + ")",
          at_parameter("max_hold"));
  std::mt19937_64 g(seed);
  std::vector<Eigen::Index> holds;
  for (Eigen::Index total = 0; total < n;) {
    const auto span = static_cast<double>(max_hold - min_hold + 1);
    const Eigen::Index h = min_hold + std::min<Eigen::Index>(static_cast<Eigen::Index>(detail::uniform01(g) * span),
                                                             max_hold - min_hold);
    holds.push_back(std::min(h, n - total));
    total += h;
  }
  const std::size_t m = holds.size();
  std::vector<std::size_t> slice(m);
  for (std::size_t i = 0; i < m; ++i) slice[i] = i;
  for (std::size_t i = m; i > 1; --i) {  // Fisher–Yates with our own variates
    const auto j = std::min(static_cast<std::size_t>(detail::uniform01(g) * static_cast<double>(i)), i - 1);
    std::swap(slice[i - 1], slice[j]);
  }
  Eigen::VectorXd u(n);
  Eigen::Index k = 0;
  const double width = (levels.high - levels.low) / static_cast<double>(m);
  for (std::size_t i = 0; i < m; ++i) {
    const double a = levels.low + width * (static_cast<double>(slice[i]) + detail::uniform01(g));
    u.segment(k, holds[i]).setConstant(a);
    k += holds[i];
  }
  return u;
}

}  // namespace nlid
