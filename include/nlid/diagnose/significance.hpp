#pragma once
/// @file
/// When does an added effect count? The three tests of the diagnosis, and the noise-floor gate.
///
/// Setting. The current model M₀ and an augmented model M₁ (one more effect, Δp more
/// parameters) are both fitted on the *estimation* data; both are then simulated on the
/// *validation* data, with residuals ε₀ = y − ŷ₀, ε₁ = y − ŷ₁, sums of squares V₀, V₁, and
/// difference of predictions δ = ŷ₁ − ŷ₀ (so ε₁ = ε₀ − δ). N is the number of validation samples,
/// σ the noise floor and γ its variance inflation (noise_floor.hpp), N_eff = N/γ.
///
/// 1. Statistical significance (noise test). If M₁ explained nothing real on the validation
///    record, its gain D = V₀ − V₁ = 2 ε₀ᵀδ − ‖δ‖² would come from the noise alone: with ε₀ = m + n,
///    the noise term 2nᵀδ has standard deviation 2σ√γ‖δ‖ (for white noise; γ widens it for
///    correlated noise). The test statistic
///
///        z = D / (2 σ √γ ‖δ‖)
///
///    is compared with the normal upper quantile z_{α/K}, K the number of candidates tried in the
///    round (Bonferroni, so the chance of any false detection per round is at most α). This is
///    the likelihood-ratio test of the two fixed predictors under Gaussian noise of known level
///    (Ljung 1999, sec. 16.4 on comparing model structures with validation data; the
///    Diebold–Mariano idea of testing the *loss difference* on fresh data, J. Bus. Econ. Stat. 13,
///    1995, with the noise variance known instead of estimated).
///
/// 2. Relevance relative to the excess above the noise floor. The residual energy that physics
///    can still explain is the excess E = V₀ − Nσ². A candidate must remove a fraction
///
///        ρ = D / E ≥ η     (η = 0.1 by default)
///
///    of it. On real records the residual always holds some structure no catalogue effect
///    describes (a slightly wrong sensor curve, a thermal drift); a candidate that nibbles 2 % of
///    that is statistically "significant" on long records but is not the missing physics.
///
/// 3. Information criterion with a parameter penalty, on validation data:
///
///        score = N_eff ln(V₀/V₁) − Δp ln N_eff   > 0,
///
///    Schwarz's BIC difference (Schwarz 1978, Ann. Stat. 6; Ljung 1999, eq. 16.33) evaluated on
///    the validation record with the effective sample count. It is also the ranking key of the
///    candidate table: gain in log-likelihood minus the price of the added parameters.
///
/// A candidate is *significant* when all three hold. The noise-floor gate decides before any
/// candidate is tried: if the validation residual is consistent with the noise floor,
///
///        V₀ / (N σ²) ≤ 1 + m_σ + z_{α} √(2γ/N),
///
///    (the χ² upper bound for N_eff degrees of freedom, plus a margin m_σ = 0.05 for the
///    uncertainty of σ itself), nothing is missing and nothing is added.

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/diagnose/locate.hpp"

namespace nlid {

/// Thresholds of the significance tests (see the file comment).
struct SignificanceOptions {
  /// Family-wise probability of a false detection per search round (noise test, Bonferroni).
  double alpha = 0.01;
  /// Smallest share of the excess residual energy a candidate must remove (relevance η).
  double relevance = 0.10;
  /// Relative uncertainty allowed for σ² in the noise-floor gate (m_σ).
  double floor_margin = 0.05;
};

/// Validation statistics of one candidate against the current model.
struct CandidateStatistics {
  double gain = 0.0;        ///< D = V₀ − V₁ (validation)
  double z = 0.0;           ///< noise-test statistic z = D / (2σ√γ‖δ‖)
  double z_critical = 0.0;  ///< z_{α/K}
  double relevance = 0.0;   ///< ρ = D / (V₀ − Nσ²)  (−∞ … 1; NaN-free)
  double score = -std::numeric_limits<double>::infinity();  ///< N_eff ln(V₀/V₁) − Δp ln N_eff
  bool significant = false; ///< all three tests passed
};

/// Outcome of the noise-floor gate.
struct FloorConsistency {
  double ratio = 0.0;      ///< V₀ / (N σ²)
  double bound = 0.0;      ///< 1 + m_σ + z_α √(2γ/N)
  bool consistent = false; ///< ratio ≤ bound: the residual is explained by noise
};

/// The noise-floor gate on validation residual energy `v0` over `n` samples.
inline FloorConsistency floor_consistency(double v0, Eigen::Index n, double sigma, double inflation,
                                          const SignificanceOptions& o = {}) {
  require(sigma > 0.0 && n > 0, "floor consistency: need a positive noise floor and samples");
  FloorConsistency f;
  const double nn = static_cast<double>(n);
  f.ratio = v0 / (nn * sigma * sigma);
  f.bound = 1.0 + o.floor_margin + normal_upper_quantile(o.alpha) * std::sqrt(2.0 * std::max(1.0, inflation) / nn);
  f.consistent = f.ratio <= f.bound;
  return f;
}

/// Statistics of a candidate (file comment): `v0`, `v1` validation sums of squares of the
/// current and augmented model, `delta_norm` = ‖ŷ₁ − ŷ₀‖ on validation data, `n` validation
/// samples, `added_params` Δp, `tried` K candidates in the round.
inline CandidateStatistics candidate_statistics(double v0, double v1, double delta_norm, Eigen::Index n,
                                                double sigma, double inflation, int added_params, int tried,
                                                const SignificanceOptions& o = {}) {
  require(sigma > 0.0 && n > 0, "candidate statistics: need a positive noise floor and samples");
  CandidateStatistics s;
  const double gamma = std::max(1.0, inflation);
  const double nn = static_cast<double>(n), neff = nn / gamma;
  s.z_critical = normal_upper_quantile(o.alpha / std::max(1, tried));
  if (!(std::isfinite(v0) && std::isfinite(v1)) || v1 <= 0.0) return s;
  s.gain = v0 - v1;
  s.z = delta_norm > 0.0 ? s.gain / (2.0 * sigma * std::sqrt(gamma) * delta_norm) : 0.0;
  const double excess = v0 - nn * sigma * sigma;
  s.relevance = excess > 0.0 ? s.gain / excess : (s.gain > 0.0 ? 0.0 : -1.0);
  s.score = neff * std::log(v0 / v1) - static_cast<double>(added_params) * std::log(neff);
  s.significant = s.z > s.z_critical && s.relevance >= o.relevance && s.score > 0.0 && s.gain > 0.0;
  return s;
}

}  // namespace nlid
