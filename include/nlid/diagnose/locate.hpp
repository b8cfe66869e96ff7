#pragma once
/// @file
/// Locating a model mismatch: *when* (time intervals per experiment) and *where in the operating
/// range* (bins over output level, output rate and its sign, input level) the simulation
/// residual rises above the noise floor.
///
/// Notation. For experiment e with samples k = 0…N_e−1, measured output y, simulated output ŷ
/// (free run from the input alone) and residual ε = y − ŷ; σ is the noise floor
/// (noise_floor.hpp) and γ its variance inflation (1 for white noise).
///
/// Time intervals. The local mean square over a centred window of W samples,
///
///     m(k) = (1/W) Σ_{|j| ≤ W/2} ε(k + j)²,
///
/// is, where the model is right, a mean of squared noise: W m / σ² ≈ χ²_ν with ν = W/γ degrees
/// of freedom. A window is flagged when m(k) exceeds the (1 − α/M) quantile of σ² χ²_ν / ν,
/// where M = Σ N_e / W is the number of independent windows (Bonferroni), so the chance of one
/// false interval in the whole data set is at most α. The quantile uses the Wilson–Hilferty
/// approximation χ²_ν,p ≈ ν (1 − 2/(9ν) + z_p √(2/(9ν)))³ (Johnson, Kotz & Balakrishnan 1994,
/// "Continuous Univariate Distributions" vol. 1, eq. 18.24). Flagged windows are joined into
/// intervals when they overlap or lie less than W apart. Each interval reports its share of the
/// residual energy of the data set, Σ_interval ε² / Σ_all ε², and its RMS relative to σ.
///
/// Operating regions. Each sample is also placed in bins of
///   - the output level y (equal-width bins between the data's extremes),
///   - the output rate ẏ: "fast negative", "slow negative", "at rest", "slow positive",
///     "fast positive" — the rest band is ±r₀ with r₀ the larger of 4× the noise of the rate
///     estimate and 2 % of the 95th percentile of |ẏ|; slow/fast split at the median |ẏ| of the
///     moving samples. ẏ comes from a quadratic Savitzky–Golay derivative over 7 samples
///     (Savitzky & Golay 1964, Anal. Chem. 36, Table III), so sensor noise does not scatter
///     samples out of the rest band;
///   - the input level u (equal-width bins).
/// A region reports its share of the residual energy next to its share of the samples; a ratio
/// well above one says the mismatch concentrates there (Coulomb friction, for instance, shows at
/// rest and at reversals; a missing drag at high speed; a missing stop near one end of travel).
/// The *excess* share (energy above the noise floor, Σ ε² − n σ², clipped at 0) separates a
/// region that is merely busy from one that is badly modelled.

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/diagnose/noise_floor.hpp"

namespace nlid {

/// Settings of `locate_mismatch`.
struct LocateOptions {
  /// Window length W in samples; 0 = automatic, max(5, N_e / 200) for each experiment.
  int window = 0;
  /// Probability of at least one false interval in the whole data set when nothing is wrong.
  double false_alarm = 0.01;
  /// Number of equal-width bins for the output and input levels.
  int level_bins = 5;
  /// Largest number of intervals reported (the most energetic are kept).
  int max_intervals = 40;
};

/// One time interval of one experiment where the residual exceeds the noise floor.
struct MismatchInterval {
  int experiment = 0;        ///< 0-based index in the data set passed to `locate_mismatch`
  std::string name;          ///< experiment name (may be empty)
  double t0 = 0.0;           ///< start time (experiment's clock)
  double t1 = 0.0;           ///< end time
  double energy_share = 0;   ///< Σ ε² inside / Σ ε² of the whole data set
  double rms_ratio = 0;      ///< RMS of ε inside, divided by σ
};

/// One bin of an operating variable with its share of the residual energy.
struct MismatchRegion {
  std::string variable;      ///< "y" (output level), "dy/dt" (output rate) or "u" (input level)
  std::string label;         ///< e.g. "at rest", "fast positive", "level 3 of 5"
  double lo = 0.0;           ///< lower edge (data units; rate in units per time unit)
  double hi = 0.0;           ///< upper edge
  double energy_share = 0;   ///< Σ ε² in the bin / Σ ε² total
  double excess_share = 0;   ///< Σ max(ε² − σ², ·) in the bin / total excess (0 if no excess)
  double sample_share = 0;   ///< samples in the bin / total samples
  /// energy_share / sample_share: > 1 where the mismatch concentrates.
  [[nodiscard]] double concentration() const {
    return sample_share > 0.0 ? energy_share / sample_share : 0.0;
  }
};

/// Result of `locate_mismatch`.
struct Mismatch {
  double noise_sigma = 0.0;      ///< the floor σ used
  double residual_rms = 0.0;     ///< RMS of ε over all samples
  /// (Σ ε² − N σ²) / Σ ε²: share of the residual energy above the noise floor (may be < 0 when
  /// the residual is at or below the floor).
  double excess_share = 0.0;
  double threshold_ratio = 0.0;  ///< flagging threshold on m(k)/σ² (for reports)
  double flagged_time_share = 0.0;    ///< share of samples inside intervals
  double flagged_energy_share = 0.0;  ///< share of residual energy inside intervals
  std::vector<MismatchInterval> intervals;  ///< by experiment, then time
  std::vector<MismatchRegion> regions;      ///< y bins, then dy/dt bins, then u bins
};

/// Locates where the residual y − ŷ of output `output` exceeds the noise floor. `simulated[e]` is
/// the model's simulated output of experiment e (length N_e). Throws `nlid::Error` naming the
/// experiment if a length differs or a value is not finite, and if `noise.sigma` is not positive.
/// Throws `nlid::Error` naming the first setting of `o` out of range; `prefix` goes before the
/// parameter's name ("locate." where the options are a member of `DiagnoseOptions`).
inline void check_locate_options(const LocateOptions& o, const std::string& prefix = {}) {
  require(o.max_intervals >= 0, "locate: max_intervals must be >= 0, got " + std::to_string(o.max_intervals),
          at_parameter(prefix + "max_intervals"));
  require(o.window >= 0, "locate: window must be >= 0 (0 = automatic), got " + std::to_string(o.window),
          at_parameter(prefix + "window"));
  require(o.level_bins >= 1 && o.level_bins <= 50, "locate: level_bins must be 1..50",
          at_parameter(prefix + "level_bins"));
  require(o.false_alarm > 0.0 && o.false_alarm < 0.5, "locate: false_alarm must lie in (0, 0.5)",
          at_parameter(prefix + "false_alarm"));
}

inline Mismatch locate_mismatch(const Dataset& data, const std::vector<Eigen::VectorXd>& simulated,
                                const NoiseFloor& noise, const LocateOptions& options = {},
                                int output = 0);

/// Output rate by a 7-point quadratic Savitzky–Golay derivative (3-point and one-sided
/// differences near the ends). Used for the rate regions and by the effect catalogue.
inline Eigen::VectorXd smoothed_rate(const Eigen::Ref<const Eigen::VectorXd>& y, double ts);

/// Upper p-quantile of σ²χ²_ν/ν, i.e. the value a mean of ν squared unit-variance Gaussian
/// samples exceeds with probability p (Wilson–Hilferty; p in (0, 0.5)).
inline double chi_square_mean_quantile(double nu, double p);

/// Standard normal upper quantile z with P(Z > z) = p, for p in (0, 0.5] (Acklam's rational
/// approximation refined by one Newton step; relative error below 1e-12).
inline double normal_upper_quantile(double p);

// ------------------------------------------------------------------------------------------
// Implementation details below.
// ------------------------------------------------------------------------------------------

inline double normal_upper_quantile(double p) {
  require(p > 0.0 && p < 1.0, "normal quantile: probability must lie in (0, 1)");
  // Acklam's algorithm for the lower quantile of 1 − p, then a Newton step on erfc.
  const double q = 1.0 - p;
  static constexpr double a[] = {-3.969683028665376e+01, 2.209460984245205e+02,
                                 -2.759285104469687e+02, 1.383577518672690e+02,
                                 -3.066479806614716e+01, 2.506628277459239e+00};
  static constexpr double b[] = {-5.447609879822406e+01, 1.615858368580409e+02,
                                 -1.556989798598866e+02, 6.680131188771972e+01,
                                 -1.328068155288572e+01};
  static constexpr double c[] = {-7.784894002430293e-03, -3.223964580411365e-01,
                                 -2.400758277161838e+00, -2.549732539343734e+00,
                                 4.374664141464968e+00, 2.938163982698783e+00};
  static constexpr double d[] = {7.784695709041462e-03, 3.224671290700398e-01,
                                 2.445134137142996e+00, 3.754408661907416e+00};
  double x;
  const double plow = 0.02425;
  if (q < plow) {
    const double r = std::sqrt(-2.0 * std::log(q));
    x = (((((c[0] * r + c[1]) * r + c[2]) * r + c[3]) * r + c[4]) * r + c[5]) /
        ((((d[0] * r + d[1]) * r + d[2]) * r + d[3]) * r + 1.0);
  } else if (q <= 1.0 - plow) {
    const double r = q - 0.5, s = r * r;
    x = (((((a[0] * s + a[1]) * s + a[2]) * s + a[3]) * s + a[4]) * s + a[5]) * r /
        (((((b[0] * s + b[1]) * s + b[2]) * s + b[3]) * s + b[4]) * s + 1.0);
  } else {
    const double r = std::sqrt(-2.0 * std::log(p));
    x = -(((((c[0] * r + c[1]) * r + c[2]) * r + c[3]) * r + c[4]) * r + c[5]) /
        ((((d[0] * r + d[1]) * r + d[2]) * r + d[3]) * r + 1.0);
  }
  // Newton refinement on the upper tail P(Z > x) = ½ erfc(x/√2).
  const double pi = 3.14159265358979323846;
  const double e = 0.5 * std::erfc(x / std::sqrt(2.0)) - p;
  const double dens = std::exp(-0.5 * x * x) / std::sqrt(2.0 * pi);
  if (dens > 0.0) x += e / dens;
  return x;
}

inline double chi_square_mean_quantile(double nu, double p) {
  require(nu > 0.0, "chi-square quantile: degrees of freedom must be positive");
  const double z = normal_upper_quantile(p);
  const double h = 2.0 / (9.0 * nu);
  const double base = 1.0 - h + z * std::sqrt(h);
  return std::max(0.0, base * base * base);
}

inline Eigen::VectorXd smoothed_rate(const Eigen::Ref<const Eigen::VectorXd>& y, double ts) {
  const Eigen::Index n = y.size();
  Eigen::VectorXd r = Eigen::VectorXd::Zero(n);
  if (n < 2) return r;
  for (Eigen::Index k = 0; k < n; ++k) {
    if (k >= 3 && k + 3 < n) {
      // Quadratic SG derivative: Σ j y(k+j) / Σ j², j = −3..3, Σ j² = 28.
      r(k) = (3.0 * (y(k + 3) - y(k - 3)) + 2.0 * (y(k + 2) - y(k - 2)) + (y(k + 1) - y(k - 1))) /
             (28.0 * ts);
    } else if (k >= 1 && k + 1 < n) {
      r(k) = (y(k + 1) - y(k - 1)) / (2.0 * ts);
    } else if (k == 0) {
      r(k) = (y(1) - y(0)) / ts;
    } else {
      r(k) = (y(k) - y(k - 1)) / ts;
    }
  }
  return r;
}

namespace detail {

// Equal-width bin index of x in [lo, hi] with nb bins (clamped).
inline int level_bin(double x, double lo, double hi, int nb) {
  if (!(hi > lo)) return 0;
  const int b = static_cast<int>(std::floor((x - lo) / (hi - lo) * nb));
  return std::clamp(b, 0, nb - 1);
}

}  // namespace detail

inline Mismatch locate_mismatch(const Dataset& data, const std::vector<Eigen::VectorXd>& simulated,
                                const NoiseFloor& noise, const LocateOptions& options,
                                int output) {
  require(noise.sigma > 0.0 && std::isfinite(noise.sigma),
          "locate: noise floor must be positive and finite", at_parameter("noise.sigma"));
  require(simulated.size() == data.size(),
          "locate: " + std::to_string(simulated.size()) + " simulated outputs for " +
              std::to_string(data.size()) + " experiments");
  require(output >= 0 && output < data.num_outputs(), "locate: output index out of range",
          at_parameter("output"));
  check_locate_options(options);
  Mismatch m;
  m.noise_sigma = noise.sigma;
  const double s2 = noise.sigma * noise.sigma;
  const double gamma = std::max(1.0, noise.inflation);

  // Residuals, totals and checks.
  std::vector<Eigen::VectorXd> eps(data.size());
  double total = 0.0;
  Eigen::Index n_total = 0;
  for (std::size_t e = 0; e < data.size(); ++e) {
    const Experiment& x = data[e];
    require(simulated[e].size() == x.size(),
            "locate: simulated output has " + std::to_string(simulated[e].size()) +
                " samples but the experiment has " + std::to_string(x.size()),
            at_experiment(static_cast<long>(e)));
    eps[e] = x.y().col(output) - simulated[e];
    require(eps[e].allFinite(), "locate: residual is not finite (diverged simulation?)",
            at_experiment(static_cast<long>(e)));
    total += eps[e].squaredNorm();
    n_total += x.size();
  }
  require(n_total > 0, "locate: the data set has no samples");
  m.residual_rms = std::sqrt(total / static_cast<double>(n_total));
  m.excess_share = total > 0.0 ? (total - static_cast<double>(n_total) * s2) / total : 0.0;
  const double total_safe = total > 0.0 ? total : 1.0;

  // ---- time intervals ----
  Eigen::Index flagged_samples = 0;
  double flagged_energy = 0.0;
  std::vector<MismatchInterval> found;
  for (std::size_t e = 0; e < data.size(); ++e) {
    const Experiment& x = data[e];
    const Eigen::Index n = x.size();
    const int w = options.window > 0 ? options.window
                                     : static_cast<int>(std::max<Eigen::Index>(5, n / 200));
    if (n < w) continue;
    const double windows = std::max(1.0, static_cast<double>(n_total) / w);
    const double thr = chi_square_mean_quantile(static_cast<double>(w) / gamma,
                                                options.false_alarm / windows);
    m.threshold_ratio = std::max(m.threshold_ratio, thr);
    // Prefix sums of ε² give each window's mean in O(1).
    Eigen::VectorXd cs(n + 1);
    cs(0) = 0.0;
    for (Eigen::Index k = 0; k < n; ++k) cs(k + 1) = cs(k) + eps[e](k) * eps[e](k);
    std::vector<char> mark(static_cast<std::size_t>(n), 0);
    for (Eigen::Index a = 0; a + w <= n; ++a) {
      const double ms = (cs(a + w) - cs(a)) / w;
      if (ms > thr * s2)
        for (Eigen::Index k = a; k < a + w; ++k) mark[static_cast<std::size_t>(k)] = 1;
    }
    // Join marked runs closer than W.
    Eigen::Index k = 0;
    while (k < n) {
      if (!mark[static_cast<std::size_t>(k)]) {
        ++k;
        continue;
      }
      Eigen::Index a = k, b = k;
      Eigen::Index j = k;
      while (j < n) {
        if (mark[static_cast<std::size_t>(j)]) {
          b = j;
          ++j;
        } else if (j - b <= w) {
          ++j;
        } else {
          break;
        }
      }
      k = b + 1;
      MismatchInterval iv;
      iv.experiment = static_cast<int>(e);
      iv.name = x.name();
      iv.t0 = x.t0() + static_cast<double>(a) * x.ts();
      iv.t1 = x.t0() + static_cast<double>(b) * x.ts();
      const double en = cs(b + 1) - cs(a);
      iv.energy_share = en / total_safe;
      iv.rms_ratio = std::sqrt(en / static_cast<double>(b - a + 1)) / noise.sigma;
      flagged_samples += b - a + 1;
      flagged_energy += en;
      found.push_back(iv);
    }
  }
  if (static_cast<int>(found.size()) > options.max_intervals) {
    std::sort(found.begin(), found.end(), [](const MismatchInterval& p, const MismatchInterval& q) {
      return p.energy_share > q.energy_share;
    });
    found.resize(static_cast<std::size_t>(options.max_intervals));
    std::sort(found.begin(), found.end(), [](const MismatchInterval& p, const MismatchInterval& q) {
      return p.experiment != q.experiment ? p.experiment < q.experiment : p.t0 < q.t0;
    });
  }
  m.intervals = std::move(found);
  m.flagged_time_share = static_cast<double>(flagged_samples) / static_cast<double>(n_total);
  m.flagged_energy_share = flagged_energy / total_safe;

  // ---- operating regions ----
  double ylo = INFINITY, yhi = -INFINITY, ulo = INFINITY, uhi = -INFINITY;
  const bool has_u = data.num_inputs() > 0;
  std::vector<Eigen::VectorXd> rates(data.size());
  std::vector<double> abs_rate;
  abs_rate.reserve(static_cast<std::size_t>(n_total));
  for (std::size_t e = 0; e < data.size(); ++e) {
    const Experiment& x = data[e];
    ylo = std::min(ylo, x.y().col(output).minCoeff());
    yhi = std::max(yhi, x.y().col(output).maxCoeff());
    if (has_u && x.size() > 0) {
      ulo = std::min(ulo, x.u().col(0).minCoeff());
      uhi = std::max(uhi, x.u().col(0).maxCoeff());
    }
    rates[e] = smoothed_rate(x.y().col(output), x.ts());
    for (Eigen::Index k = 0; k < rates[e].size(); ++k) abs_rate.push_back(std::abs(rates[e](k)));
  }
  const double ts = data.ts();
  const double rate_noise = noise.sigma / (ts * std::sqrt(28.0)) * std::sqrt(gamma);
  std::vector<double> sorted_rate = abs_rate;
  std::sort(sorted_rate.begin(), sorted_rate.end());
  const double r95 = sorted_rate.empty()
                         ? 0.0
                         : sorted_rate[static_cast<std::size_t>(0.95 * (sorted_rate.size() - 1))];
  const double r0 = std::max(4.0 * rate_noise, 0.02 * r95);
  std::vector<double> moving;
  for (double r : abs_rate)
    if (r > r0) moving.push_back(r);
  const double r1 = moving.empty() ? 2.0 * r0 : std::max(detail::median_of(moving), 1.01 * r0);
  const double rmax = sorted_rate.empty() ? r1 : std::max(sorted_rate.back(), r1);

  const int nb = options.level_bins;
  std::vector<double> ey(static_cast<std::size_t>(nb), 0.0), xy(ey), ny(ey);
  std::vector<double> eu(ey), xu(ey), nu(ey);
  std::vector<double> er(5, 0.0), xr(5, 0.0), nr(5, 0.0);
  double excess_total = 0.0;
  for (std::size_t e = 0; e < data.size(); ++e) {
    const Experiment& x = data[e];
    for (Eigen::Index k = 0; k < x.size(); ++k) {
      const double q = eps[e](k) * eps[e](k);
      const double ex = std::max(0.0, q - s2);
      excess_total += ex;
      const auto by = static_cast<std::size_t>(detail::level_bin(x.y()(k, output), ylo, yhi, nb));
      ey[by] += q;
      xy[by] += ex;
      ny[by] += 1;
      if (has_u) {
        const auto bu = static_cast<std::size_t>(detail::level_bin(x.u()(k, 0), ulo, uhi, nb));
        eu[bu] += q;
        xu[bu] += ex;
        nu[bu] += 1;
      }
      const double r = rates[e](k);
      std::size_t br = 2;
      if (r <= -r1) br = 0;
      else if (r <= -r0) br = 1;
      else if (r < r0) br = 2;
      else if (r < r1) br = 3;
      else br = 4;
      er[br] += q;
      xr[br] += ex;
      nr[br] += 1;
    }
  }
  const double nt = static_cast<double>(n_total);
  auto add = [&](const std::string& var, const std::string& label, double lo, double hi, double en,
                 double ex, double cnt) {
    if (cnt <= 0) return;
    MismatchRegion r;
    r.variable = var;
    r.label = label;
    r.lo = lo;
    r.hi = hi;
    r.energy_share = en / total_safe;
    r.excess_share = excess_total > 0.0 ? ex / excess_total : 0.0;
    r.sample_share = cnt / nt;
    m.regions.push_back(r);
  };
  for (int b = 0; b < nb; ++b) {
    const double lo = ylo + (yhi - ylo) * b / nb, hi = ylo + (yhi - ylo) * (b + 1) / nb;
    add("y", "level " + std::to_string(b + 1) + " of " + std::to_string(nb), lo, hi,
        ey[static_cast<std::size_t>(b)], xy[static_cast<std::size_t>(b)],
        ny[static_cast<std::size_t>(b)]);
  }
  const char* rate_labels[5] = {"fast negative", "slow negative", "at rest", "slow positive",
                                "fast positive"};
  const double edges[6] = {-rmax, -r1, -r0, r0, r1, rmax};
  for (int b = 0; b < 5; ++b)
    add("dy/dt", rate_labels[b], edges[b], edges[b + 1], er[static_cast<std::size_t>(b)],
        xr[static_cast<std::size_t>(b)], nr[static_cast<std::size_t>(b)]);
  if (has_u) {
    for (int b = 0; b < nb; ++b) {
      const double lo = ulo + (uhi - ulo) * b / nb, hi = ulo + (uhi - ulo) * (b + 1) / nb;
      add("u", "level " + std::to_string(b + 1) + " of " + std::to_string(nb), lo, hi,
          eu[static_cast<std::size_t>(b)], xu[static_cast<std::size_t>(b)],
          nu[static_cast<std::size_t>(b)]);
    }
  }
  return m;
}

}  // namespace nlid
