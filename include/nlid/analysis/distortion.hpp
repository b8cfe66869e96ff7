#pragma once
/// @file
/// Nonlinear distortion analysis of a periodic experiment: is a linear model enough, and if
/// not, is the nonlinearity even or odd — measured before any model is estimated.
///
/// Method (Pintelon & Schoukens, "System Identification: A Frequency Domain Approach", 2nd ed.,
/// 2012, ch. 3 and 4; Schoukens, Pintelon & Rolain, "Mastering System Identification in 100
/// Exercises", 2012). Excite the system with a multisine that leaves some lines of its band
/// empty (`multisine` with `MultisineLines::odd` or `random_odd`, data/input_design.hpp), record
/// P ≥ 2 steady-state periods, and take the DFT of each period at every line k = 1 … period/2 − 1:
///
///   - a linear system's output has power only at the excited lines;
///   - an even nonlinearity (x², …) mixes pairs of odd lines into *even* lines;
///   - an odd nonlinearity (x³, …) mixes triples of odd lines into *odd* lines, so it shows on the
///     odd lines a random-odd multisine leaves out;
///   - noise shows everywhere, and its level is measured separately from the spread of Y_p(k)
///     over the periods p (distortion repeats every period; noise does not).
///
/// Levels are mean powers over lines in the excited band (from the lowest to the highest excited
/// line) of the period-averaged spectrum Ȳ(k) = (1/P) Σ_p Y_p(k), Y_p(k) = Σ_t y_p(t) e^{−2πikt/N};
/// the noise level is the mean over the same lines of var(Ȳ(k)) = Σ_p |Y_p(k) − Ȳ(k)|² / (P(P−1)),
/// the expectation of |Ȳ(k)|² at a line that carries noise only (for a noise-free record, the
/// DFT's rounding floor takes its place: `noise_floor`; it scales with the whole output's power,
/// DC included, so the rounding of a constant or offset output is not read as distortion). A
/// detection-line level more than `threshold_db` (default 6 dB, a factor 4 in power) above the
/// noise level is reported as distortion. Only a kind of distortion whose lines the input leaves
/// empty can be measured (`even_measurable`, `odd_measurable`): an odd multisine excites every
/// odd line, so it shows even distortion but hides odd distortion under the excited lines; "a
/// linear model can explain these data" is said only when both kinds were measured and neither
/// found. The frequency response at the excited lines, Ȳ(k)/Ū(k), is the best linear
/// approximation of the system for this input class (for a linear system, its transfer function).
///
/// Cost: period²/2 multiply-adds per period (direct DFT with exact integer angles).

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/data/detail/dft_table.hpp"
#include "nlid/data/experiment.hpp"

namespace nlid {

/// Result of `distortion_analysis` (see the file comment).
struct DistortionAnalysis {
  Eigen::Index period = 0;  ///< samples per period
  int periods = 0;          ///< periods analysed (after the skipped ones)
  double ts = 0.0;          ///< sample time (s)
  std::vector<Eigen::Index> excited;     ///< excited lines (input power above −40 dB of its peak)
  std::vector<Eigen::Index> even_lines;  ///< empty even lines inside the excited band
  std::vector<Eigen::Index> odd_lines;   ///< empty odd lines inside the excited band
  Eigen::VectorXcd frf;                  ///< Ȳ/Ū at the excited lines (best linear approximation)
  /// The powers and levels below are those of y / output_scale, the largest |y| of the record:
  /// in the output's own units they would overflow for outputs beyond about 1e150 (multiply by
  /// output_scale² where they do not). The dB values are ratios and need no unit.
  double output_scale = 1.0;
  Eigen::VectorXd output_power;          ///< |Ȳ(k)|², k = 0 … period/2
  Eigen::VectorXd noise_power;           ///< var(Ȳ(k)) from the spread over periods, k = 0 … period/2
  double excited_level = std::numeric_limits<double>::quiet_NaN();  ///< mean |Ȳ|² at excited lines
  double even_level = std::numeric_limits<double>::quiet_NaN();     ///< … at empty even lines
  double odd_level = std::numeric_limits<double>::quiet_NaN();      ///< … at empty odd lines
  double noise_level = std::numeric_limits<double>::quiet_NaN();    ///< mean var(Ȳ) over the band
  double threshold_db = 6.0;  ///< detection threshold above the noise level

  /// The level the others are compared with: the measured noise, or — for a noise-free record
  /// (simulated data) — `rounding_floor()`.
  [[nodiscard]] double noise_floor() const { return std::max(noise_level, rounding_floor()); }
  /// What double rounding leaves on a line of the DFT, with a wide margin: 10⁻²⁴ of the output's
  /// total power Σ|Ȳ(k)|², k = 0 … period/2 (measured: 10⁻³³ to 10⁻³² of it for periods of 512 to
  /// 8192 samples). Rounding comes from all of the output, not from the excited lines alone: a
  /// floor relative to the excited level put the rounding of a constant or strongly offset
  /// output 240 dB "above the noise" and reported it as distortion.
  [[nodiscard]] double rounding_floor() const {
    const double total = output_power.sum();
    return std::isfinite(total) ? 1e-24 * total : 0.0;
  }
  /// True when the record has no measurable noise and levels are relative to the rounding floor.
  [[nodiscard]] bool noise_free() const { return !(noise_level > rounding_floor()); }

  /// Frequency of line k in Hz.
  [[nodiscard]] double frequency(Eigen::Index k) const {
    return static_cast<double>(k) / (static_cast<double>(period) * ts);
  }
  /// Level above the noise, in dB (NaN without such lines).
  [[nodiscard]] double even_db() const { return db(even_level); }
  [[nodiscard]] double odd_db() const { return db(odd_level); }
  /// Level of the excited output relative to the noise, in dB (the experiment's SNR).
  [[nodiscard]] double snr_db() const { return db(excited_level); }
  /// Even / odd distortion above the threshold (false without detection lines).
  [[nodiscard]] bool even_detected() const { return even_db() > threshold_db; }
  [[nodiscard]] bool odd_detected() const { return odd_db() > threshold_db; }
  /// True when the input leaves empty even / odd lines in its band, so that this kind of
  /// distortion can be measured at all. An odd multisine (every odd line excited) has no empty
  /// odd lines: odd distortion falls on excited lines, where it cannot be told from the linear
  /// response — "not detected" then says nothing; a random-odd multisine measures both.
  [[nodiscard]] bool even_measurable() const { return !even_lines.empty(); }
  [[nodiscard]] bool odd_measurable() const { return !odd_lines.empty(); }

  /// True when the excited output stands above the noise by more than the threshold: only then
  /// does "no distortion detected" say something about the system.
  /// An output without power at the excited lines responds to nothing: no verdict, and no dB
  /// level against a zero floor. A noise-free record is held to the same test against the
  /// rounding floor: a constant output has nothing but rounding on its excited lines.
  [[nodiscard]] bool conclusive() const { return excited_level > 0.0 && snr_db() > threshold_db; }

  /// A few lines for a person: levels, what they mean for the choice of model.
  [[nodiscard]] std::string report() const {
    char buf[256];
    std::string s;
    s += "Distortion analysis: " + std::to_string(periods) + " periods of " + std::to_string(period) + " samples, " +
         std::to_string(excited.size()) + " excited lines (" +
         detail::format_g(excited.empty() ? 0.0 : frequency(excited.front()), 4) + " to " +
         detail::format_g(excited.empty() ? 0.0 : frequency(excited.back()), 4) + " Hz), ";
    if (excited_level > 0.0) {
      s += "output " + detail::format_f(snr_db(), 1) + " dB above the noise\n";
    } else {
      s += "no output at the excited lines\n";
    }
    if (noise_free()) s += "  no measurable noise (a simulated record?): levels are relative to the DFT's rounding floor\n";
    const auto line = [&](const char* what, const std::vector<Eigen::Index>& lines, double level_db, bool detected) {
      if (lines.empty()) {
        // Even lines are left empty by odd and random-odd multisines, odd lines only by random-odd ones.
        std::snprintf(buf, sizeof buf,
                      "  %s distortion: not measurable, no empty %s lines in the band (use %s lines)\n", what, what,
                      what[0] == 'e' ? "odd or random-odd" : "random-odd");
      } else if (!std::isfinite(level_db)) {
        std::snprintf(buf, sizeof buf, "  %s distortion: no level on %zu lines (no output to compare it with)\n", what,
                      lines.size());
      } else {
        std::snprintf(buf, sizeof buf, "  %s distortion: %s dB above the noise on %zu lines: %s\n", what,
                      detail::format_f(level_db, 1).c_str(), lines.size(), detected ? "present" : "not detected");
      }
      s += buf;
    };
    line("even", even_lines, even_db(), even_detected());
    line("odd", odd_lines, odd_db(), odd_detected());
    if (!(excited_level > 0.0)) {
      s += "  no conclusion: the output has no power at the excited lines (constant, or not a response to this input)\n";
    } else if (!conclusive() && noise_free() && snr_db() <= 20.0) {
      s += "  no conclusion: the output at the excited lines is at the DFT's rounding floor (constant, or not a "
           "response to this input)\n";
    } else if (!conclusive() && noise_free()) {
      // Clearly a response, but not as far above rounding as the threshold asks: in a noise-free
      // record the threshold is the reason, not the output (the rounding floor lies 240 dB under
      // the output's whole power, DC included).
      s += "  no conclusion: the output at the excited lines is " + detail::format_f(snr_db(), 1) +
           " dB above the DFT's rounding floor, not more than the threshold of " + detail::format_f(threshold_db, 1) +
           " dB; a noise-free record is compared with rounding: lower the threshold\n";
    } else if (!conclusive()) {
      s += "  no conclusion: the output at the excited lines is only " + detail::format_f(snr_db(), 1) +
           " dB above the noise (needs more than " + detail::format_f(threshold_db, 1) +
           " dB): too noisy, or not a response to this input\n";
    } else if (even_detected() || odd_detected()) {
      s += "  a linear model leaves this distortion unexplained; a nonlinear structure is warranted\n";
    } else if (even_measurable() && odd_measurable()) {
      s += "  no distortion above the noise: a linear model can explain these data\n";
    } else if (even_measurable() || odd_measurable()) {
      // Only one kind was measured: the other may be there, hidden on excited lines.
      std::snprintf(buf, sizeof buf,
                    "  no %s distortion above the noise, but %s distortion cannot be measured with this input: no "
                    "verdict on linearity (excite with random-odd lines to measure both)\n",
                    even_measurable() ? "even" : "odd", even_measurable() ? "odd" : "even");
      s += buf;
    } else {
      s += "  neither kind of distortion can be measured with this input: no verdict on linearity (excite with "
           "random-odd lines)\n";
    }
    return s;
  }

 private:
  [[nodiscard]] double db(double level) const {
    const double floor = noise_floor();
    if (!std::isfinite(level) || !(floor > 0.0)) return std::numeric_limits<double>::quiet_NaN();
    return 10.0 * std::log10(std::max(level, 1e-300) / floor);
  }
};

/// Analyses input 0 and output 0 of `e`, which holds whole periods of `period` samples of a
/// periodic input (the first `skip_periods` are skipped as the transient; samples after the last
/// whole period are ignored). Needs at least 2 analysed periods (for the noise level). Throws
/// `nlid::Error` naming the parameter for a bad period count, and for an input without excited
/// lines.
[[nodiscard]] inline DistortionAnalysis distortion_analysis(const Experiment& e, Eigen::Index period,
                                                            int skip_periods = 1, double threshold_db = 6.0) {
  e.validate(true);
  require(e.num_inputs() >= 1 && e.num_outputs() >= 1, "distortion analysis needs an input and an output",
          at_parameter("experiment"));
  require(period >= 8, "distortion analysis: the period must be >= 8 samples, got " + std::to_string(period),
          at_parameter("period"));
  require(skip_periods >= 0, "distortion analysis: skip_periods must be >= 0", at_parameter("skip_periods"));
  // A level at or below the noise (0 dB or less) would call every noise line distortion.
  require(std::isfinite(threshold_db) && threshold_db > 0.0,
          "distortion analysis: threshold_db must be a finite level above the noise (> 0 dB), got " +
              detail::format_f(threshold_db, 1),
          at_parameter("threshold_db"));
  const Eigen::Index whole = e.size() / period;
  const Eigen::Index p = whole - skip_periods;
  require(p >= 2,
          "distortion analysis: " + std::to_string(e.size()) + " samples hold " + std::to_string(whole) +
              " whole period(s) of " + std::to_string(period) + "; after skipping " + std::to_string(skip_periods) +
              " at least 2 must remain (the noise level is their spread)",
          // The record's fault if it holds fewer than 2 periods, the skip's if it took them.
          at_parameter(whole >= 2 && skip_periods > 0 ? "skip_periods" : "period"));
  require(e.u().col(0).allFinite() && e.y().col(0).allFinite(), "distortion analysis: the record has non-finite samples",
          at_parameter("experiment"));
  // Powers are sums of squares: of samples near 1e300 they overflow (inf/inf = NaN dB, an input
  // "without power"), of samples near 1e-300 they underflow. Divided by the largest magnitude
  // every sum stays within a period's length of 1, for any finite record.
  const auto scale_of = [](const auto& v) {
    const double m = v.cwiseAbs().maxCoeff();
    return m > 0.0 ? m : 1.0;
  };
  const double u_scale = scale_of(e.u().col(0)), y_scale = scale_of(e.y().col(0));
  const Eigen::VectorXd u = e.u().col(0) / u_scale;
  const Eigen::VectorXd y = e.y().col(0) / y_scale;

  // The method rests on the input repeating: on a record that is not periodic with this
  // period (a wrong period, a non-periodic excitation) the "noise" is the input's own change
  // between periods and every verdict would be meaningless. A measured input may carry some
  // noise; a spread of a tenth of its variation means it does not repeat.
  {
    Eigen::VectorXd mean_period = Eigen::VectorXd::Zero(period);
    for (Eigen::Index q = 0; q < p; ++q) mean_period += u.segment((skip_periods + q) * period, period);
    mean_period /= static_cast<double>(p);
    double spread = 0.0;
    for (Eigen::Index q = 0; q < p; ++q)
      spread += (u.segment((skip_periods + q) * period, period) - mean_period).squaredNorm();
    spread = std::sqrt(spread / static_cast<double>(p * period));
    const double variation = std::sqrt((mean_period.array() - mean_period.mean()).square().mean());
    if (variation > 0.0 && spread > 0.1 * variation) {
      throw Error("distortion analysis: the input does not repeat every " + std::to_string(period) +
                      " samples (its periods differ from their mean by " +
                      detail::format_g(100.0 * spread / variation, 3) + " %" +
                      " of the input's variation, RMS); the analysis needs a periodic input: give its period, and skip "
                      "the periods before the steady state",
                  at_parameter("period"));
    }
  }

  DistortionAnalysis r;
  r.period = period;
  r.periods = static_cast<int>(p);
  r.ts = e.ts();
  r.threshold_db = threshold_db;
  r.output_scale = y_scale;
  const Eigen::Index nk = period / 2 + 1;  // lines 0 … period/2
  const detail::DftTable tab(period);
  const Eigen::VectorXd &c = tab.cos, &s = tab.sin;
  // Y_p(k) for every analysed period; Ū averaged directly.
  std::vector<Eigen::VectorXcd> yp(static_cast<std::size_t>(p));
  Eigen::VectorXcd ubar = Eigen::VectorXcd::Zero(nk);
  for (Eigen::Index q = 0; q < p; ++q) {
    const Eigen::Index off = (skip_periods + q) * period;
    Eigen::VectorXcd& Y = yp[static_cast<std::size_t>(q)];
    Y = Eigen::VectorXcd::Zero(nk);
    for (Eigen::Index k = 0; k < nk; ++k) {
      double yr = 0, yi = 0, ur = 0, ui = 0;
      Eigen::Index m = 0;
      for (Eigen::Index t = 0; t < period; ++t) {
        yr += y[off + t] * c[m];
        yi -= y[off + t] * s[m];
        ur += u[off + t] * c[m];
        ui -= u[off + t] * s[m];
        m += k;
        if (m >= period) m -= period;
      }
      Y[k] = {yr, yi};
      ubar[k] += std::complex<double>(ur, ui) / static_cast<double>(p);
    }
  }
  Eigen::VectorXcd ybar = Eigen::VectorXcd::Zero(nk);
  for (const auto& Y : yp) ybar += Y / static_cast<double>(p);
  r.output_power = ybar.cwiseAbs2();
  r.noise_power = Eigen::VectorXd::Zero(nk);
  for (const auto& Y : yp) r.noise_power += (Y - ybar).cwiseAbs2();
  r.noise_power /= static_cast<double>(p * (p - 1));

  // Excited lines: input power within 40 dB of its peak (DC and, for even periods, Nyquist out).
  const Eigen::Index top = period % 2 == 0 ? nk - 2 : nk - 1;
  double peak = 0.0, energy = 0.0;
  for (Eigen::Index k = 1; k <= top; ++k) peak = std::max(peak, std::norm(ubar[k]));
  for (Eigen::Index k = 0; k < nk; ++k) energy += std::norm(ubar[k]);
  // Rounding leaves ~(N·ε)² of a constant input at every line: relative to the whole spectrum.
  require(peak > 1e-12 * energy, "distortion analysis: the input has no power at any line of the period (a constant input?)",
          at_parameter("experiment"));
  for (Eigen::Index k = 1; k <= top; ++k)
    if (std::norm(ubar[k]) > 1e-4 * peak) r.excited.push_back(k);
  r.frf.resize(static_cast<Eigen::Index>(r.excited.size()));
  double exc = 0, noise = 0, even = 0, odd = 0;
  for (std::size_t i = 0; i < r.excited.size(); ++i) {
    const Eigen::Index k = r.excited[i];
    r.frf[static_cast<Eigen::Index>(i)] = ybar[k] / ubar[k] * (y_scale / u_scale);
    exc += r.output_power[k];
  }
  std::size_t j = 0;
  for (Eigen::Index k = r.excited.front(); k <= r.excited.back(); ++k) {
    noise += r.noise_power[k];
    while (j < r.excited.size() && r.excited[j] < k) ++j;
    if (j < r.excited.size() && r.excited[j] == k) continue;
    if (k % 2 == 0) {
      r.even_lines.push_back(k);
      even += r.output_power[k];
    } else {
      r.odd_lines.push_back(k);
      odd += r.output_power[k];
    }
  }
  r.excited_level = exc / static_cast<double>(r.excited.size());
  r.noise_level = noise / static_cast<double>(r.excited.back() - r.excited.front() + 1);
  if (!r.even_lines.empty()) r.even_level = even / static_cast<double>(r.even_lines.size());
  if (!r.odd_lines.empty()) r.odd_level = odd / static_cast<double>(r.odd_lines.size());
  return r;
}

}  // namespace nlid
