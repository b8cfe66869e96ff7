#pragma once
/// @file
/// The noise floor: how small a simulation residual can get when nothing is missing.
///
/// Why. A diagnosis must tell "the model misses physics" from "the model is as good as the
/// sensor allows". With output-error models (simulation from the input alone) the residual of a
/// *correct* model is the measurement noise n(t) (Ljung 1999, sec. 4.3, eq. 4.113 with
/// H(q) = 1), so the noise level σ is the floor below which no missing effect can be seen, and the
/// excess Σ ε² − N σ² is what physics still has to explain.
///
/// Estimate. σ is read from the data itself, without a model, from high-order differences. For a
/// smooth signal s and white noise n of variance σ², the d-th difference
///
///     Δᵈ y(k) = Σ_{j=0..d} (−1)ʲ C(d, j) y(k − j)        has   var Δᵈ n = C(2d, d) σ²,
///
/// (C(2,1) = 2, C(4,2) = 6, C(6,3) = 20), while Δᵈ s ≈ hᵈ s⁽ᵈ⁾ is negligible when the sample time
/// h is short compared with the signal's time scales (von Neumann 1941, Ann. Math. Stat. 12, the
/// "mean square successive difference"; Gasser, Sroka & Jennen-Steinmetz 1986, Biometrika 73,
/// eq. 2 for the pseudo-residual form). Steps and contacts make a few differences huge, so the
/// scale is robust: start from the median absolute deviation (MAD·1.4826 estimates σ for
/// Gaussian data; Hampel 1974), then iterate a trimmed RMS that drops |Δ| > c·σ̂ with c = 3.5 and
/// corrects for the trimmed Gaussian tail,
///
///     σ̂² = mean_{|Δ| ≤ cσ̂}(Δ²) / (C(2d,d) · κ(c)),   κ(c) = 1 − 2cφ(c)/(2Φ(c) − 1),
///
/// which unlike the bare MAD is not itself quantised when the data are (a position sensor with a
/// 0.1° step makes Δᵈ y a multiple of 0.1°, and its median jumps by whole steps).
///
/// Quantisation. If the raw values lie on a grid of step q, the rounding error is (nearly)
/// uniform with variance q²/12 (Widrow & Kollár 2008, "Quantization Noise", eq. 4.9); it is part of
/// the floor, and σ̂ is never reported below q/√12.
///
/// Preprocessing. Decimation low-passes the data (resample.hpp), which removes most of the
/// broadband noise and colours what is left, so differences of the *decimated* record
/// under-estimate its noise (by ~12 % for d = 1 and the default filter) and successive residuals
/// are correlated. When the raw record is at hand, the floor is therefore estimated at the raw
/// rate (where sensor noise is white) and carried through the very same `decimate` call by
/// Monte Carlo: a white sequence of known variance is decimated and its variance ratio g and
/// autocorrelation ρ_k are measured, giving σ_dec = σ_raw √g and the variance inflation of a
/// windowed mean square, 1 + 2 Σ_k ρ_k² (for Gaussian noise cov(n_i², n_j²) = 2 ρ² σ⁴), which the
/// locator and the significance tests use as an effective-sample-size correction.
///
/// Limits (documented, not hidden): process disturbances that enter before the dynamics are
/// smooth and are *not* noise by this definition; they show up as excess residual. A diagnosis
/// then reports the excess but, because every candidate must improve *validation* fit
/// significantly, it does not invent an effect for it.

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/data/resample.hpp"

namespace nlid {

/// Settings of the noise-floor estimate.
struct NoiseFloorOptions {
  /// Order d of the differences (1…4). 2 cancels constant slopes (ramps) as well as levels and
  /// keeps the noise gain C(2d, d) = 6 moderate; 1 is preferable on already low-passed data.
  int difference_order = 2;
  /// Trimming threshold c of the robust RMS, in units of the current scale estimate.
  double trim = 3.5;
  /// Length of the white sequence used to propagate the floor through decimation.
  Eigen::Index monte_carlo_samples = 40000;
  /// Largest lag of the autocorrelation used for the variance inflation.
  int max_lag = 40;
};

/// The measurement-noise level of one output, as seen by a simulation residual.
struct NoiseFloor {
  double sigma = 0.0;         ///< noise standard deviation in the analysed (preprocessed) data
  double raw_sigma = 0.0;     ///< noise standard deviation at the raw sample rate
  double quantisation = 0.0;  ///< detected quantisation step of the raw output (0: none found)
  /// Variance inflation of a windowed mean of squared noise, 1 + 2 Σ ρ_k² (1 for white noise):
  /// a window of W samples carries W / inflation independent samples' worth of information.
  double inflation = 1.0;
  int decimation = 1;           ///< decimation factor the floor was propagated through
  Eigen::Index samples = 0;     ///< differences the estimate is based on
  std::string method;           ///< one line: how σ was obtained (for reports)
};

/// Robust standard deviation of white noise in `x` from its `order`-th differences (see the file
/// comment). Non-finite samples break the difference chain and are skipped. Returns 0 if fewer
/// than 8 differences exist or `x` is exactly constant.
inline double difference_noise_sigma(const Eigen::Ref<const Eigen::VectorXd>& x, int order = 2,
                                     double trim = 3.5, Eigen::Index* used = nullptr);

/// Detects a quantisation grid of the values of `x`: returns the step q if at least 99 % of the
/// finite values lie within 1e-6·q of multiples of q (offset allowed), else 0. The candidate q
/// is the most common smallest positive gap between sorted distinct values.
inline double detect_quantisation(const Eigen::Ref<const Eigen::VectorXd>& x);

/// Noise floor of output `output` from the given records, pooled over experiments. With
/// `decimation` > 1 the records are raw data that will be decimated by that factor with
/// `decimate_options` before modelling; the floor is estimated at the raw rate and propagated
/// through the same filter (see the file comment). Throws `nlid::Error` if the output index is
/// out of range or the records hold too few samples for an estimate.
inline NoiseFloor estimate_noise_floor(const Dataset& data, int output = 0, int decimation = 1,
                                       const DecimateOptions& decimate_options = {},
                                       const NoiseFloorOptions& options = {});

/// Noise floor of a single residual or signal at its own rate (no preprocessing to undo), with
/// the difference order of `options`. Throws if fewer than 8 usable differences exist.
inline NoiseFloor estimate_noise_floor(const Eigen::Ref<const Eigen::VectorXd>& signal,
                                       const NoiseFloorOptions& options = {});

/// The noise floor of records whose raw-rate noise standard deviation is known (a sensor's data
/// sheet; simulated records, which have no noise to estimate), carried through decimation by
/// `decimation` exactly as an estimated floor is: σ after the filter and the variance inflation
/// of its correlated samples. `source` starts `NoiseFloor::method` (where σ came from). Throws
/// unless `raw_sigma` is positive and finite.
inline NoiseFloor noise_floor_from_sigma(double raw_sigma, int decimation = 1, const DecimateOptions& decimate_options = {},
                                         const NoiseFloorOptions& options = {}, const std::string& source = "given");

// ------------------------------------------------------------------------------------------
// Implementation details below.
// ------------------------------------------------------------------------------------------

namespace detail {

// Sets f.sigma and f.inflation from f.raw_sigma for records decimated by `decimation`.
inline void propagate_through_decimation(NoiseFloor& f, int decimation, const DecimateOptions& decimate_options,
                                         const NoiseFloorOptions& options);

inline double binomial(int n, int k) {
  double c = 1.0;
  for (int i = 1; i <= k; ++i) c = c * static_cast<double>(n - k + i) / static_cast<double>(i);
  return c;
}

// Median of a vector (partially sorts a copy).
inline double median_of(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const std::size_t m = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(m), v.end());
  double med = v[m];
  if (v.size() % 2 == 0) {
    const double lo = *std::max_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(m));
    med = 0.5 * (med + lo);
  }
  return med;
}

// Variance kept by a Gaussian truncated to |z| ≤ c: 1 − 2cφ(c)/(2Φ(c) − 1).
inline double truncated_gaussian_variance(double c) {
  const double pi = 3.14159265358979323846;
  const double phi = std::exp(-0.5 * c * c) / std::sqrt(2.0 * pi);
  const double mass = std::erf(c / std::sqrt(2.0));
  return 1.0 - 2.0 * c * phi / mass;
}

// All order-d differences of x along runs of finite samples.
inline std::vector<double> differences(const Eigen::Ref<const Eigen::VectorXd>& x, int d) {
  std::vector<double> out;
  out.reserve(static_cast<std::size_t>(std::max<Eigen::Index>(0, x.size() - d)));
  std::vector<double> w(static_cast<std::size_t>(d + 1));
  for (int j = 0; j <= d; ++j) w[static_cast<std::size_t>(j)] = ((j % 2) ? -1.0 : 1.0) * binomial(d, j);
  for (Eigen::Index k = d; k < x.size(); ++k) {
    double s = 0.0;
    bool finite = true;
    for (int j = 0; j <= d && finite; ++j) {
      const double v = x(k - j);
      finite = std::isfinite(v);
      s += w[static_cast<std::size_t>(j)] * v;
    }
    if (finite) out.push_back(s);
  }
  return out;
}

// Robust RMS (MAD start, trimmed-RMS iterations) of zero-mean samples.
inline double robust_rms(const std::vector<double>& v, double trim) {
  if (v.empty()) return 0.0;
  std::vector<double> a(v.size());
  for (std::size_t i = 0; i < v.size(); ++i) a[i] = std::abs(v[i]);
  double s = 1.482602218505602 * median_of(a);
  if (!(s > 0.0)) {
    // More than half the differences are exactly zero (coarse quantisation, long flat stretches):
    // start from the plain RMS instead, the trimming below still rejects steps.
    double ss = 0.0;
    for (double x : v) ss += x * x;
    s = std::sqrt(ss / static_cast<double>(v.size()));
    if (!(s > 0.0)) return 0.0;
  }
  const double kappa = truncated_gaussian_variance(trim);
  for (int it = 0; it < 20; ++it) {
    double ss = 0.0;
    std::size_t n = 0;
    for (double x : v) {
      if (std::abs(x) <= trim * s) {
        ss += x * x;
        ++n;
      }
    }
    if (n < 4) break;
    const double s_new = std::sqrt(ss / static_cast<double>(n) / kappa);
    const bool done = std::abs(s_new - s) <= 1e-6 * s;
    s = s_new;
    if (done) break;
  }
  return s;
}

}  // namespace detail

inline double difference_noise_sigma(const Eigen::Ref<const Eigen::VectorXd>& x, int order,
                                     double trim, Eigen::Index* used) {
  require(order >= 1 && order <= 4, "difference order must be 1..4, got " + std::to_string(order),
          at_parameter("difference_order"));
  require(trim >= 1.5, "trim must be >= 1.5 (robust scale would discard good samples)",
          at_parameter("trim"));
  const std::vector<double> d = detail::differences(x, order);
  if (used) *used = static_cast<Eigen::Index>(d.size());
  if (d.size() < 8) return 0.0;
  return detail::robust_rms(d, trim) / std::sqrt(detail::binomial(2 * order, order));
}

inline double detect_quantisation(const Eigen::Ref<const Eigen::VectorXd>& x) {
  std::vector<double> v;
  v.reserve(static_cast<std::size_t>(x.size()));
  for (Eigen::Index i = 0; i < x.size(); ++i)
    if (std::isfinite(x(i))) v.push_back(x(i));
  if (v.size() < 16) return 0.0;
  std::sort(v.begin(), v.end());
  v.erase(std::unique(v.begin(), v.end()), v.end());
  if (v.size() < 3) return 0.0;
  // Gaps between neighbouring distinct values; on a grid the smallest ones are (multiples of) q.
  std::vector<double> gaps(v.size() - 1);
  for (std::size_t i = 0; i + 1 < v.size(); ++i) gaps[i] = v[i + 1] - v[i];
  const double smallest = *std::min_element(gaps.begin(), gaps.end());
  if (!(smallest > 0.0)) return 0.0;
  // Take the median of the gaps below 1.5 × the smallest: robust to the last-digit rounding of a
  // CSV writer (0.1 stored as 0.0999999…).
  std::vector<double> small;
  for (double g : gaps)
    if (g < 1.5 * smallest) small.push_back(g);
  const double q = detail::median_of(small);
  const double scale = std::max(std::abs(v.front()), std::abs(v.back()));
  if (!(q > 1e-12 * std::max(1.0, scale))) return 0.0;
  // Check the grid on all samples (not only distinct values) with a tolerance that covers the
  // decimal rounding of the file.
  const double origin = v.front();
  const double tol = 1e-6 * q + 1e-12 * scale;
  Eigen::Index on = 0, n = 0;
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    if (!std::isfinite(x(i))) continue;
    ++n;
    const double r = (x(i) - origin) / q;
    if (std::abs(r - std::round(r)) * q <= tol) ++on;
  }
  return (static_cast<double>(on) >= 0.99 * static_cast<double>(n)) ? q : 0.0;
}

inline NoiseFloor estimate_noise_floor(const Eigen::Ref<const Eigen::VectorXd>& signal,
                                       const NoiseFloorOptions& options) {
  NoiseFloor f;
  Eigen::Index used = 0;
  f.raw_sigma = difference_noise_sigma(signal, options.difference_order, options.trim, &used);
  require(used >= 8, "noise floor: need at least " + std::to_string(8 + options.difference_order) +
                         " finite samples, got " + std::to_string(signal.size()));
  f.quantisation = detect_quantisation(signal);
  f.raw_sigma = std::max(f.raw_sigma, f.quantisation / std::sqrt(12.0));
  f.sigma = f.raw_sigma;
  f.samples = used;
  f.method = "robust RMS of order-" + std::to_string(options.difference_order) + " differences";
  return f;
}

inline NoiseFloor estimate_noise_floor(const Dataset& data, int output, int decimation,
                                       const DecimateOptions& decimate_options,
                                       const NoiseFloorOptions& options) {
  require(data.size() > 0, "noise floor: no experiments");
  require(output >= 0 && output < data.num_outputs(),
          "noise floor: output index " + std::to_string(output) + " out of range (data has " +
              std::to_string(data.num_outputs()) + " outputs)",
          at_parameter("output"));
  require(decimation >= 1, "noise floor: decimation factor must be >= 1", at_parameter("decimation"));
  // Pool the differences of all experiments (never across the seam between two records).
  std::vector<double> diffs;
  std::vector<double> qs;
  for (std::size_t e = 0; e < data.size(); ++e) {
    const Eigen::VectorXd y = data[e].y().col(output);
    const std::vector<double> d = detail::differences(y, options.difference_order);
    diffs.insert(diffs.end(), d.begin(), d.end());
    qs.push_back(detect_quantisation(y));
  }
  require(diffs.size() >= 8,
          "noise floor: the records hold only " + std::to_string(diffs.size()) +
              " usable differences; need at least 8");
  NoiseFloor f;
  f.samples = static_cast<Eigen::Index>(diffs.size());
  f.raw_sigma = detail::robust_rms(diffs, options.trim) /
                std::sqrt(detail::binomial(2 * options.difference_order, options.difference_order));
  // A grid counts only if every record shows the same one.
  f.quantisation = qs.front();
  for (double q : qs)
    if (!(std::abs(q - f.quantisation) <= 1e-9 * std::max(1.0, std::abs(q)))) f.quantisation = 0.0;
  f.raw_sigma = std::max(f.raw_sigma, f.quantisation / std::sqrt(12.0));
  f.method = "robust RMS of order-" + std::to_string(options.difference_order) +
             " differences of the raw output";
  detail::propagate_through_decimation(f, decimation, decimate_options, options);
  return f;
}

inline NoiseFloor noise_floor_from_sigma(double raw_sigma, int decimation, const DecimateOptions& decimate_options,
                                         const NoiseFloorOptions& options, const std::string& source) {
  require(raw_sigma > 0.0 && std::isfinite(raw_sigma),
          "noise floor: the given standard deviation must be positive and finite, got " + detail::format_g(raw_sigma),
          at_parameter("raw_sigma"));
  require(decimation >= 1, "noise floor: decimation factor must be >= 1", at_parameter("decimation"));
  NoiseFloor f;
  f.raw_sigma = raw_sigma;
  f.method = source;
  detail::propagate_through_decimation(f, decimation, decimate_options, options);
  return f;
}

namespace detail {

inline void propagate_through_decimation(NoiseFloor& f, int decimation, const DecimateOptions& decimate_options,
                                         const NoiseFloorOptions& options) {
  f.decimation = decimation;
  if (decimation == 1) {
    f.sigma = f.raw_sigma;
    return;
  }
  // Propagate through the same anti-alias filter by Monte Carlo (fixed seed: reproducible).
  const Eigen::Index n = std::max<Eigen::Index>(options.monte_carlo_samples, 200 * decimation);
  std::mt19937_64 rng(20240611u);
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::MatrixXd w(n, 1);
  for (Eigen::Index k = 0; k < n; ++k) w(k, 0) = g(rng);
  const Experiment raw(Eigen::MatrixXd::Zero(n, 0), w, 1.0);
  const Experiment dec = decimate(raw, decimation, decimate_options);
  const Eigen::VectorXd z = dec.y().col(0);
  // Ignore the edges, where the reflection of filtfilt changes the statistics.
  const Eigen::Index edge = std::min<Eigen::Index>(z.size() / 10, 50);
  const Eigen::VectorXd zc = z.segment(edge, z.size() - 2 * edge);
  const double var = zc.squaredNorm() / static_cast<double>(zc.size());
  f.sigma = f.raw_sigma * std::sqrt(var);
  double infl = 1.0;
  for (int lag = 1; lag <= options.max_lag && lag < zc.size() / 4; ++lag) {
    const double r = zc.head(zc.size() - lag).dot(zc.tail(zc.size() - lag)) /
                     (static_cast<double>(zc.size() - lag) * var);
    infl += 2.0 * r * r;
  }
  f.inflation = infl;
  f.method += ", propagated through decimation by " + std::to_string(decimation) +
              " (variance gain " + detail::format_f(var, 6) + ")";
}

}  // namespace detail

}  // namespace nlid
