#pragma once
/// @file
/// Digital low-pass filters for anti-aliasing, and zero-phase (forward-backward) filtering.
///
/// Design. A Chebyshev type I low-pass of order n, pass-band ripple R_p dB and ripple-band edge
/// ω_c (rad/sample) has the squared magnitude (Oppenheim & Schafer, "Discrete-Time Signal
/// Processing", 3rd ed., sec. 7.3 and App. B; Parks & Burrus, "Digital Filter Design", ch. 7)
///
///     |H(e^{jω})|² = 1 / (1 + ε² T_n²(Ω/Ω_c)),   ε² = 10^{R_p/10} − 1,   Ω = tan(ω/2),
///
/// with T_n the Chebyshev polynomial. Its analog poles, scaled to Ω_c, are
///
///     p_k = Ω_c (−sinh(a) sin θ_k + j cosh(a) cos θ_k),   a = asinh(1/ε)/n,   θ_k = (2k−1)π/(2n),
///
/// mapped to z by the bilinear transform z = (1 + s)/(1 − s) (the tan pre-warp above makes the band
/// edge land exactly on ω_c). The low-pass zeros at s = ∞ land on z = −1. A Butterworth filter is
/// the same construction with sinh(a) = cosh(a) = 1 (maximally flat, no ripple).
///
/// Realisation. Conjugate pole pairs become second-order sections ("biquads"), cascaded from the
/// pole farthest from the unit circle to the nearest. A single high-order polynomial would lose all
/// accuracy for narrow bands (MATLAB `decimate` warns above factor 13 for that reason); sections
/// stay accurate for factors in the hundreds. Each section is scaled to DC gain exactly 1, so the
/// even-order Chebyshev filter's pass band lies in [0, +R_p] dB rather than [−R_p, 0] dB: a
/// constant signal (the throttle's 15° rest angle) passes unchanged.
///
/// Zero phase. `filtfilt` runs the cascade forward, then backward over the reversed result, so the
/// total response is |H(e^{jω})|² with zero phase (Gustafsson 1996, IEEE Trans. Signal Processing
/// 44(4), "Determining the initial states in forward-backward filtering"): ripple and attenuation
/// in dB double, and no delay is introduced between input and output channels. Edges are handled by
/// odd reflection, x(−k) = 2x(0) − x(k), over the filter's settling length, with each section
/// started in its steady state, so a record that starts at rest starts without a transient.

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <complex>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/data/concepts.hpp"

namespace nlid {

/// One second-order section, normalised so a0 = 1:
/// H(z) = (b0 + b1 z⁻¹ + b2 z⁻²) / (1 + a1 z⁻¹ + a2 z⁻²). A first-order section has b2 = a2 = 0.
struct Biquad {
  double b0 = 1, b1 = 0, b2 = 0;  ///< numerator
  double a1 = 0, a2 = 0;          ///< denominator (a0 = 1)

  /// Frequency response H(e^{jω}), ω in rad/sample.
  [[nodiscard]] std::complex<double> response(double omega) const {
    const std::complex<double> z1 = std::polar(1.0, -omega);  // z⁻¹
    const std::complex<double> z2 = z1 * z1;
    return (b0 + b1 * z1 + b2 * z2) / (1.0 + a1 * z1 + a2 * z2);
  }
  /// H(1): the gain for a constant input.
  [[nodiscard]] double dc_gain() const { return (b0 + b1 + b2) / (1.0 + a1 + a2); }
  /// Largest pole magnitude (< 1 for a stable section).
  [[nodiscard]] double pole_radius() const {
    const double disc = a1 * a1 - 4.0 * a2;
    if (disc < 0.0) return std::sqrt(a2);  // complex pair: |p|² = a2
    const double s = std::sqrt(disc);
    return std::max(std::abs(-a1 + s), std::abs(-a1 - s)) / 2.0;
  }
};

/// A cascade of second-order sections. Invariant: every section is stable (pole radius < 1).
class SosFilter {
 public:
  /// Identity filter (no sections).
  SosFilter() = default;
  /// Takes the sections in the order they are applied; throws if one is unstable.
  explicit SosFilter(std::vector<Biquad> sections) : sections_(std::move(sections)) {
    for (std::size_t i = 0; i < sections_.size(); ++i) {
      if (!(sections_[i].pole_radius() < 1.0)) {
        throw Error("filter section " + std::to_string(i) + " is unstable (pole radius >= 1)",
                    at_parameter("sections"));
      }
    }
  }
  /// The sections, in application order.
  [[nodiscard]] const std::vector<Biquad>& sections() const { return sections_; }
  /// Filter order (number of poles).
  [[nodiscard]] int order() const {
    int n = 0;
    for (const auto& s : sections_) n += s.a2 != 0.0 ? 2 : (s.a1 != 0.0 ? 1 : 0);
    return n;
  }
  /// H(e^{jω}) of the cascade (single pass), ω in rad/sample ∈ [0, π].
  [[nodiscard]] std::complex<double> response(double omega) const {
    std::complex<double> h = 1.0;
    for (const auto& s : sections_) h *= s.response(omega);
    return h;
  }
  /// Gain of the zero-phase (forward-backward) filter: |H(e^{jω})|².
  [[nodiscard]] double zero_phase_gain(double omega) const { return std::norm(response(omega)); }
  /// Gain for a constant input.
  [[nodiscard]] double dc_gain() const {
    double g = 1.0;
    for (const auto& s : sections_) g *= s.dc_gain();
    return g;
  }
  /// Number of samples after which the slowest mode has decayed below `decay` (relative): the
  /// length of the edge reflection used by `filtfilt`.
  [[nodiscard]] Eigen::Index settling_samples(double decay = 1e-9) const {
    double r = 0.0;
    for (const auto& s : sections_) r = std::max(r, s.pole_radius());
    if (r <= 0.0) return 1;
    return static_cast<Eigen::Index>(std::ceil(std::log(decay) / std::log(r))) + 1;
  }

  /// Causal filtering in place, each section started in the steady state of its first input
  /// sample (so a signal that starts at a constant level produces no start-up transient).
  /// `Scalar` may be double, float, or any type with field arithmetic (e.g. `nlid::Dual`).
  template <FilterScalar Scalar>
  void filter_in_place(Scalar* x, Eigen::Index n, Eigen::Index stride = 1) const {
    if (n <= 0) return;
    // Sections run in groups of up to `group` per sample: each section's recursion is a serial
    // dependency chain, and interleaving independent chains lets the CPU overlap them.
    constexpr std::size_t group = 4;
    Scalar v = x[0];  // first input of the current section (steady state: scaled by DC gains)
    for (std::size_t g0 = 0; g0 < sections_.size(); g0 += group) {
      const std::size_t m = std::min(group, sections_.size() - g0);
      Scalar b0[group], b1[group], b2[group], a1[group], a2[group], z1[group], z2[group];
      for (std::size_t i = 0; i < m; ++i) {
        const Biquad& s = sections_[g0 + i];
        b0[i] = Scalar(s.b0), b1[i] = Scalar(s.b1), b2[i] = Scalar(s.b2);
        a1[i] = Scalar(s.a1), a2[i] = Scalar(s.a2);
        const Scalar gain(s.dc_gain());
        // Transposed direct form II in the steady state of a constant input v:
        // z1 = (g − b0)v, z2 = (b2 − a2 g)v.
        z1[i] = (gain - b0[i]) * v;
        z2[i] = (b2[i] - a2[i] * gain) * v;
        v = gain * v;
      }
      for (Eigen::Index k = 0; k < n; ++k) {
        Scalar& xk = x[k * stride];
        Scalar in = xk;
        for (std::size_t i = 0; i < m; ++i) {
          const Scalar out = b0[i] * in + z1[i];
          z1[i] = b1[i] * in - a1[i] * out + z2[i];
          z2[i] = b2[i] * in - a2[i] * out;
          in = out;
        }
        xk = in;
      }
    }
  }

 private:
  std::vector<Biquad> sections_;
};

// ---- Implementation details below (until the end of namespace detail) ------------------
/// Smallest low-pass edge (fraction of the Nyquist frequency) the designs accept. A section's
/// pole pair is stored as a1 = −2 Re z, a2 = |z|², both near 1 for a narrow band, and (Im z)² is
/// what is left of a1²/4 − a2: about (π·cutoff/2)² against rounding of 2^−52. At 1e-6 the poles
/// are still right to about 1e-4; well below, they fall onto the unit circle and the filter is
/// unstable or meaningless (a section "unstable" at 1e-16).
inline constexpr double min_lowpass_cutoff = 1e-6;

namespace detail {

inline void check_lowpass_args(int order, double cutoff) {
  if (order < 1 || order > 40) {
    throw Error("filter order must be in 1..40, got " + std::to_string(order),
                at_parameter("order"));
  }
  if (!(cutoff > 0.0 && cutoff < 1.0)) {
    throw Error(
        "cutoff must lie strictly between 0 and 1 (fraction of the Nyquist frequency), "
        "got " +
            detail::format_f(cutoff, 6),
        at_parameter("cutoff"));
  }
  if (cutoff < min_lowpass_cutoff) {
    throw Error("cutoff " + format_g(cutoff, 6) +
                    " (fraction of the Nyquist frequency) is below 1e-06: the poles of so narrow a "
                    "low-pass round onto the unit circle in double precision; filter in stages "
                    "(e.g. decimate twice) instead",
                at_parameter("cutoff"));
  }
}

/// Poles −σ_k + jω_k (σ = sinh(a) sin θ, ω = cosh(a) cos θ) → biquads with zeros at z = −1.
inline SosFilter lowpass_from_prototype(int order, double cutoff, double sh, double ch) {
  const double w = std::tan(std::numbers::pi * cutoff / 2.0);  // pre-warped band edge
  std::vector<std::pair<double, Biquad>> secs;                 // (pole radius, section)
  for (int k = 1; k <= order / 2; ++k) {
    const double theta = (2.0 * k - 1.0) * std::numbers::pi / (2.0 * order);
    const std::complex<double> p(-w * sh * std::sin(theta), w * ch * std::cos(theta));
    const std::complex<double> z = (1.0 + p) / (1.0 - p);
    Biquad b;
    b.a1 = -2.0 * z.real();
    b.a2 = std::norm(z);
    const double k4 = (1.0 + b.a1 + b.a2) / 4.0;  // DC gain 1: numerator k(1 + z⁻¹)²
    b.b0 = k4;
    b.b1 = 2.0 * k4;
    b.b2 = k4;
    secs.emplace_back(std::abs(z), b);
  }
  if (order % 2 == 1) {
    const double p = -w * sh;
    const double z = (1.0 + p) / (1.0 - p);
    Biquad b;
    b.a1 = -z;
    b.b0 = b.b1 = (1.0 - z) / 2.0;
    secs.emplace_back(std::abs(z), b);
  }
  std::sort(secs.begin(), secs.end(),
            [](const auto& l, const auto& r) { return l.first < r.first; });
  std::vector<Biquad> out;
  for (auto& s : secs) out.push_back(s.second);
  return SosFilter(std::move(out));
}

}  // namespace detail

/// Chebyshev type I low-pass: `order` poles, pass band [0, cutoff·π] rad/sample with ripple
/// `ripple_db` (gain within [0, +ripple_db] dB for an even order, [−ripple_db, 0] dB for an odd
/// one, whose DC is a ripple peak; DC gain exactly 1 either way), monotone stop band.
/// `cutoff` is the ripple-band edge as a fraction of the Nyquist frequency, in (0, 1).
inline SosFilter chebyshev1_lowpass(int order, double ripple_db, double cutoff) {
  detail::check_lowpass_args(order, cutoff);
  if (!(ripple_db > 0.0 && ripple_db <= 10.0)) {
    throw Error("pass-band ripple must be in (0, 10] dB, got " + detail::format_f(ripple_db, 6),
                at_parameter("ripple_db"));
  }
  const double eps = std::sqrt(std::pow(10.0, ripple_db / 10.0) - 1.0);
  const double a = std::asinh(1.0 / eps) / order;
  return detail::lowpass_from_prototype(order, cutoff, std::sinh(a), std::cosh(a));
}

/// Butterworth low-pass: maximally flat, −3.01 dB (single pass) at `cutoff`·π rad/sample.
inline SosFilter butterworth_lowpass(int order, double cutoff) {
  detail::check_lowpass_args(order, cutoff);
  return detail::lowpass_from_prototype(order, cutoff, 1.0, 1.0);
}

/// Zero-phase filtering of every column of `x` (forward, then backward; see the file comment).
/// Returns a matrix of the same size. A constant column is returned bit-exactly: the first sample
/// is subtracted before filtering and added back afterwards, and a zero signal stays zero.
template <class Derived>
requires FilterScalar<typename Derived::Scalar>
[[nodiscard]] Eigen::Matrix<typename Derived::Scalar, Eigen::Dynamic, Eigen::Dynamic> filtfilt(
    const SosFilter& filter, const Eigen::MatrixBase<Derived>& x) {
  using Scalar = typename Derived::Scalar;
  const Eigen::Index n = x.rows();
  Eigen::Matrix<Scalar, Eigen::Dynamic, Eigen::Dynamic> out(n, x.cols());
  if (n == 0) return out;
  const Eigen::Index pad = std::min<Eigen::Index>(n - 1, filter.settling_samples());
  std::vector<Scalar> buf(static_cast<std::size_t>(n + 2 * pad));
  for (Eigen::Index c = 0; c < x.cols(); ++c) {
    const Scalar first = x(0, c);
    const Scalar last = x(n - 1, c);
    // Odd reflection keeps value and slope continuous at both ends, relative to `first`.
    for (Eigen::Index k = 0; k < pad; ++k) {
      buf[static_cast<std::size_t>(k)] = (first - x(pad - k, c));
      buf[static_cast<std::size_t>(pad + n + k)] = (last - first) + (last - x(n - 2 - k, c));
    }
    for (Eigen::Index k = 0; k < n; ++k) buf[static_cast<std::size_t>(pad + k)] = x(k, c) - first;
    const auto len = static_cast<Eigen::Index>(buf.size());
    filter.filter_in_place(buf.data(), len);
    filter.filter_in_place(buf.data() + (len - 1), len, -1);  // backward pass, in place
    for (Eigen::Index k = 0; k < n; ++k) out(k, c) = buf[static_cast<std::size_t>(pad + k)] + first;
  }
  return out;
}

}  // namespace nlid
