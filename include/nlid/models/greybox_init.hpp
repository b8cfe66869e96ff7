#pragma once
/// @file
/// Data-driven starting values for grey-box parameters.
///
/// Why. A simulation-error criterion is non-convex in physical parameters: started far from the
/// optimum (a stiffness off by two decades, a stop at the wrong end of the travel), the
/// Levenberg–Marquardt iteration settles in a poor local minimum. The throttle study needed trial
/// and error for its starting guesses. nlid instead reads the scale-dependent parameters off the
/// data (levels, stop positions, gains, time constants), so a record in radians or millimetres
/// starts as well as one in degrees, and multi-start then explores a range around that point.
///
/// Tools (each robust to noise, quantisation and missing samples; non-finite samples are skipped):
///
/// - `quantile`: order statistics of a pooled channel (levels and ranges without outliers).
/// - `detect_stop`: is an output pinned at one end of its travel while the input keeps moving?
///   Then that end is a mechanical stop (or a saturation), and its level is the stop position.
/// - `fit_first_order`, `fit_second_order`: least-squares ARX fits (Ljung 1999, Sec. 4.2, eq. 4.7
///   and Sec. 7.3, eq. 7.34) on the samples inside a level band, converted to the continuous-time
///   parameters of a first-order lag τẏ = −y + K u + y₀ or an oscillator
///   ÿ + c ẏ + k (y − y₀) = b u. Discrete poles z map to continuous ones by s = ln(z)/T_s (exact
///   for a zero-order-hold sampled system), so
///
///       real poles:     c = −(s₁ + s₂),   k = s₁ s₂
///       complex pair:   c = −2 ln|z| / T_s,   k = (ln²|z| + arg²z) / T_s²
///
///   and the static gain and level follow from the ARX steady state, ȳ = (B(1) ū + d) / A(1).
///   Equation-error fits are biased by output noise (Ljung 1999, Sec. 8.3); they are starting
///   values for the simulation-error fit, not the answer.

#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>
#include <vector>

#include <Eigen/Core>
#include <Eigen/QR>

#include "nlid/core/error.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/models/greybox_concepts.hpp"

namespace nlid {

/// Which side of an experiment a channel index refers to.
enum class Channel {
  input,   ///< column of `Experiment::u()`
  output,  ///< column of `Experiment::y()`
};

/// All finite samples of one channel, pooled over the experiments of a data set.
inline Eigen::VectorXd pooled(const Dataset& data, Channel side, int column) {
  Eigen::Index n = 0;
  for (const Experiment& e : data) n += e.size();
  Eigen::VectorXd v(n);
  Eigen::Index m = 0;
  for (const Experiment& e : data) {
    const Eigen::MatrixXd& s = side == Channel::input ? e.u() : e.y();
    require(column >= 0 && column < s.cols(), "channel index out of range");
    for (Eigen::Index k = 0; k < s.rows(); ++k) {
      const double x = s(k, column);
      if (std::isfinite(x)) v(m++) = x;
    }
  }
  v.conservativeResize(m);
  return v;
}

/// The q-quantile (0 ≤ q ≤ 1) of the values, linearly interpolated between order statistics.
/// Takes its argument by value because it partially sorts it. Throws on an empty vector.
inline double quantile(Eigen::VectorXd v, double q) {
  require(v.size() > 0, "quantile of an empty signal");
  q = std::clamp(q, 0.0, 1.0);
  const double pos = q * static_cast<double>(v.size() - 1);
  const auto lo = static_cast<Eigen::Index>(std::floor(pos));
  const Eigen::Index hi = std::min<Eigen::Index>(lo + 1, v.size() - 1);
  double* b = v.data();
  std::nth_element(b, b + lo, b + v.size());
  const double a = b[lo];
  if (hi == lo) return a;
  const double c = *std::min_element(b + lo + 1, b + v.size());
  return a + (pos - static_cast<double>(lo)) * (c - a);
}

/// Result of `detect_stop`.
struct StopEstimate {
  bool contacted = false;  ///< the output rests at that end while the input varies
  double position = 0.0;   ///< stop level (median of the pinned samples), or a level just beyond
                           ///< the data when not contacted, so the stop term stays inactive
  double fraction = 0.0;   ///< share of samples found pinned
};

/// Looks for a mechanical stop at the upper (`upper = true`) or lower end of output `output`.
/// A stop is reported when at least `min_fraction` of the samples lie within 3 % of the output
/// range of that end *and* the input over those samples spreads over at least 5 % of its range
/// (a system merely sitting at its lowest commanded level has a constant input there).
inline StopEstimate detect_stop(const Dataset& data, int input, int output, bool upper,
                                double min_fraction = 0.02) {
  StopEstimate s;
  const Eigen::VectorXd y = pooled(data, Channel::output, output);
  if (y.size() < 10) return s;
  const double lo = quantile(y, 0.005), hi = quantile(y, 0.995);
  const double range = hi - lo;
  s.position = upper ? hi + 0.5 * range : lo - 0.5 * range;
  if (!(range > 0.0)) return s;
  const double band = 0.03 * range;
  std::vector<double> ys, us;
  double umin = std::numeric_limits<double>::infinity(), umax = -umin;
  for (const Experiment& e : data) {
    for (Eigen::Index k = 0; k < e.size(); ++k) {
      const double yk = e.y()(k, output);
      const double uk = input >= 0 && input < e.num_inputs() ? e.u()(k, input) : 0.0;
      if (!std::isfinite(yk) || !std::isfinite(uk)) continue;
      umin = std::min(umin, uk);
      umax = std::max(umax, uk);
      if (upper ? yk >= hi - band : yk <= lo + band) {
        ys.push_back(yk);
        us.push_back(uk);
      }
    }
  }
  s.fraction = static_cast<double>(ys.size()) / static_cast<double>(y.size());
  if (s.fraction < min_fraction || ys.size() < 5) return s;
  const Eigen::VectorXd uv = Eigen::Map<Eigen::VectorXd>(us.data(), static_cast<Eigen::Index>(us.size()));
  const double spread = quantile(uv, 0.95) - quantile(uv, 0.05);
  if (!(umax > umin) || spread < 0.05 * (umax - umin)) return s;
  s.contacted = true;
  s.position = quantile(Eigen::Map<Eigen::VectorXd>(ys.data(), static_cast<Eigen::Index>(ys.size())), 0.5);
  return s;
}

/// Continuous-time linear response read off the data by an ARX fit (see the file comment).
struct LinearResponse {
  bool ok = false;       ///< false: too few samples in the band, or unstable/unphysical poles
  double c = 0.0;        ///< damping 1/s (second order), or 1/τ (first order)
  double k = 0.0;        ///< stiffness 1/s² (second order; 0 for first order)
  double tau = 0.0;      ///< time constant s (first order; 2/c for second order)
  double gain = 0.0;     ///< static gain dy/du at steady state
  double offset = 0.0;   ///< steady-state output at u = 0
  Eigen::Index samples = 0;  ///< regression rows used
};

namespace detail {
// Least-squares ARX fit y_t = Σ a_i y_{t−i} + Σ b_i u_{t−i} + d over rows whose outputs y_t …
// y_{t−na} all lie in [y_min, y_max]; returns [a_1..a_na, b_1..b_na, d] or an empty vector.
inline Eigen::VectorXd arx_band_fit(const Dataset& data, int input, int output, int na, double y_min,
                                    double y_max, Eigen::Index& rows_used) {
  const int nth = 2 * na + 1;
  Eigen::MatrixXd ata = Eigen::MatrixXd::Zero(nth, nth);
  Eigen::VectorXd atb = Eigen::VectorXd::Zero(nth);
  Eigen::VectorXd phi(nth);
  rows_used = 0;
  for (const Experiment& e : data) {
    const bool has_u = input >= 0 && input < e.num_inputs();
    for (Eigen::Index t = na; t < e.size(); ++t) {
      bool use = true;
      for (int i = 0; i <= na && use; ++i) {
        const double yv = e.y()(t - i, output);
        use = std::isfinite(yv) && yv >= y_min && yv <= y_max;
      }
      if (!use) continue;
      for (int i = 1; i <= na; ++i) {
        phi(i - 1) = e.y()(t - i, output);
        phi(na + i - 1) = has_u ? e.u()(t - i, input) : 0.0;
      }
      phi(nth - 1) = 1.0;
      if (!phi.allFinite()) continue;
      ata.noalias() += phi * phi.transpose();
      atb.noalias() += phi * e.y()(t, output);
      ++rows_used;
    }
  }
  if (rows_used < 4 * nth) return {};
  // Column-pivoting QR copes with an input that is constant over the band (rank deficiency).
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(ata);
  if (qr.rank() < nth) return {};
  return qr.solve(atb);
}
}  // namespace detail

/// First-order fit τẏ = −y + gain·u + offset on samples with output in [y_min, y_max].
inline LinearResponse fit_first_order(const Dataset& data, int input, int output,
                                      double y_min = -std::numeric_limits<double>::infinity(),
                                      double y_max = std::numeric_limits<double>::infinity()) {
  LinearResponse r;
  if (data.size() == 0) return r;
  const double ts = data.ts();
  const Eigen::VectorXd th = detail::arx_band_fit(data, input, output, 1, y_min, y_max, r.samples);
  if (th.size() == 0) return r;
  const double a = th(0), b = th(1), d = th(2);
  if (!(a > 0.0 && a < 1.0)) return r;
  r.tau = -ts / std::log(a);
  r.c = 1.0 / r.tau;
  r.gain = b / (1.0 - a);
  r.offset = d / (1.0 - a);
  r.ok = std::isfinite(r.tau) && std::isfinite(r.gain) && std::isfinite(r.offset);
  return r;
}

/// Second-order fit ÿ + c ẏ + k (y − offset) = k·gain·u on samples with output in [y_min, y_max].
inline LinearResponse fit_second_order(const Dataset& data, int input, int output,
                                       double y_min = -std::numeric_limits<double>::infinity(),
                                       double y_max = std::numeric_limits<double>::infinity()) {
  LinearResponse r;
  if (data.size() == 0) return r;
  const double ts = data.ts();
  const Eigen::VectorXd th = detail::arx_band_fit(data, input, output, 2, y_min, y_max, r.samples);
  if (th.size() == 0) return r;
  const double a1 = th(0), a2 = th(1), b1 = th(2), b2 = th(3), d = th(4);
  const double a_at_1 = 1.0 - a1 - a2;  // A(1): zero for a pole at z = 1 (no static gain)
  if (!(a_at_1 > 1e-9)) return r;
  // Poles: roots of z² − a1 z − a2.
  const std::complex<double> disc = std::sqrt(std::complex<double>(a1 * a1 + 4.0 * a2, 0.0));
  const std::complex<double> z1 = 0.5 * (a1 + disc), z2 = 0.5 * (a1 - disc);
  if (std::abs(z1) >= 1.0 || std::abs(z2) >= 1.0 || std::abs(z1) == 0.0 || std::abs(z2) == 0.0) return r;
  if (disc.imag() == 0.0 && (z1.real() <= 0.0 || z2.real() <= 0.0)) return r;  // no continuous twin
  const std::complex<double> s1 = std::log(z1) / ts, s2 = std::log(z2) / ts;
  r.c = -(s1 + s2).real();
  r.k = (s1 * s2).real();
  r.tau = r.c > 0.0 ? 2.0 / r.c : 0.0;
  r.gain = (b1 + b2) / a_at_1;
  r.offset = d / a_at_1;
  r.ok = r.c > 0.0 && r.k > 0.0 && std::isfinite(r.gain) && std::isfinite(r.offset);
  return r;
}

/// Sets a parameter's starting value and its multi-start range (ends in either order); the range
/// is log-spaced only if asked for and entirely positive. For use in `Physics::initialize`.
inline void set_start(ParameterInfo& p, double value, double range_a, double range_b, bool log_scale) {
  p.value = value;
  p.range_lower = std::min(range_a, range_b);
  p.range_upper = std::max(range_a, range_b);
  p.log_scale = log_scale && p.range_lower > 0.0;
}

}  // namespace nlid
