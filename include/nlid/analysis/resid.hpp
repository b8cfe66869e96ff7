#pragma once
/// @file
/// Residual analysis (the toolbox's `resid`): is what the model leaves unexplained white, and
/// independent of the input?
///
/// A model is validated by its residuals ε(t) = y(t) − ŷ(t) (Ljung 1999, Sec. 16.6, "residual
/// analysis"). Two properties say the model has captured all the structure the data can show:
///
///  1. whiteness — ε(t) is uncorrelated with its own past. Otherwise the model has missed
///     dynamics (or the noise model is wrong): there is still something to predict.
///  2. independence — ε(t) is uncorrelated with past (and, for feedback, future) inputs.
///     Otherwise part of the input's effect has not been explained: the dynamics are wrong.
///
/// Estimates (Ljung 1999, eqs. 16.70–16.77), N samples, lags τ = 0 … M (τ = −M … M for the
/// cross test):
///
///     R̂_ε(τ)  = 1/N Σ_t ε(t) ε(t − τ),         r_ε(τ)  = R̂_ε(τ) / R̂_ε(0),
///     R̂_εu(τ) = 1/N Σ_t ε(t) u(t − τ),         r_εu(τ) = R̂_εu(τ) / √(R̂_ε(0) R̂_u(0)),
///
/// with ε and u taken about their means. Confidence bounds at level `confidence` (99 % by
/// default, as the toolbox plots), with z = Φ⁻¹((1 + confidence)/2) (z = 2.576 for 99 %):
///
///     whiteness:     |r_ε(τ)| ≤ z / √N                      (τ ≥ 1; √N r_ε(τ) → N(0, 1))
///     independence:  |r_εu(τ)| ≤ z √P / (√N √(R̂_ε(0) R̂_u(0))),  P = Σ_{k=−M}^{M} R̂_ε(k) R̂_u(k)
///
/// (eq. 16.76: under independence √N R̂_εu(τ) → N(0, P); for a white ε, P = R̂_ε(0) R̂_u(0) and
/// the bound reduces to z/√N as well).
///
/// The per-lag bands are marginal: each says where one lag's estimate falls with probability
/// `confidence` under the null hypothesis. Neighbouring lags are not independent — for the
/// cross test they are strongly correlated whenever the input is coloured (a step-like input
/// moves all r_εu(τ) of nearby τ together) — so several lags may leave the band together.
///
/// Verdict. Each lag outside its band is listed, but with 25 lags about one in four white
/// residual sequences has *some* lag outside a 99 % band by chance, so the pass/fail decision
/// uses two joint tests at level α = 1 − confidence:
///  - a χ² statistic Q against the χ²(K) quantile (Wilson–Hilferty approximation of the quantile,
///    exact for K ≤ 2), which catches many small correlations. For the whiteness test the lag
///    estimates are asymptotically independent and Q = N Σ_τ r_ε(τ)² (Ljung 1999 eq. 16.72,
///    Box–Pierce), K = M. For the cross test they are not, and Σ (r/σ)² would have the right mean
///    but a much larger spread for a coloured input (with an amplitude-modulated step input,
///    N = 2000, M = 25: 20 % false rejections at the 99 % level). It uses their full covariance
///    instead, Q = R̂ᵀ V⁺ R̂ over the vector R̂ of R̂_εu(τ), τ = −M … M (Ljung 1999, Sec. 16.6, for
///    a white ε; Bartlett's formula for two independent series otherwise): conditional on the
///    input, and with the sums over exactly the samples each lag uses,
///        Cov(R̂_εu(τ_i), R̂_εu(τ_j)) = 1/N² Σ_{|k|≤M} w_k R̂_ε(k) Σ_t u(t − τ_i) u(t − k − τ_j),
///    with the Bartlett lag window w_k = 1 − |k|/(M + 1), which keeps V positive semidefinite.
///    For a white ε this is the exact covariance (Q is exactly χ² for Gaussian ε); a coloured ε
///    enters through R̂_ε(k) up to lag M. An input that does not excite all 2M + 1 lag directions
///    (a sinusoid, a multisine of few lines) makes V singular or nearly so: V⁺ is the pseudo-inverse over the
///    eigenvalues above 10⁻¹⁰ of the largest, and K is their count (`degrees_of_freedom`);
///  - the largest |r(τ)|/σ_τ against the Bonferroni bound z_{1−α/(2K)}, which catches one large one
///    (valid, if conservative, for correlated lags).
/// A test fails if either rejects; "correlated at lags 1, 2" names the lags outside the band.
///
/// Which residuals. By default the one-step prediction errors, as the toolbox's `resid`: for a
/// nonlinear ARX or ARX model `predict(e, 1)` (the first n₀ samples, copied from the data, are
/// skipped — also behind an `AnyModel`, which forwards `history_length()`);
/// for an output-error structure (Hammerstein–Wiener, grey box, OE) prediction equals simulation,
/// so the simulation residuals are used. `ResidOptions::source` selects simulation residuals
/// explicitly. Multi-experiment data are pooled: the sums run within each experiment (no lag
/// crosses a boundary) and are divided by the total sample count.
///
/// Charts. `resid_chart_svg` draws r(τ) as stems with the confidence band shaded, for the HTML
/// report (io/svg_chart.hpp; the chart needs only core/, so this analysis header may use it).

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/core/initial_condition.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/data/experiment.hpp"
#include "nlid/io/svg_chart.hpp"

namespace nlid {

/// Which residuals `resid` analyses.
enum class ResidualSource {
  automatic,   ///< one-step prediction errors if the model predicts, else simulation errors
  prediction,  ///< one-step prediction errors (model must have `predict(e, 1)`)
  simulation,  ///< free-run simulation errors from `ResidOptions::initial_condition`
};

/// Settings of the residual analysis.
struct ResidOptions {
  /// Largest lag M (toolbox default 25).
  int max_lag = 25;
  /// Confidence level of the bounds and of the verdict, in (0, 1).
  double confidence = 0.99;
  /// Which residuals (see the file comment).
  ResidualSource source = ResidualSource::automatic;
  /// Initial condition of simulation residuals.
  InitialCondition initial_condition = InitialCondition::zero;
  /// Output channel analysed.
  int output = 0;
};

/// One correlation test: r(τ) over lags with its confidence band and verdict.
struct CorrelationTest {
  std::string name;            ///< "autocorrelation of e" or "cross-correlation u1 -> e"
  std::string input;           ///< input channel name of a cross test (empty for the whiteness test)
  std::vector<int> lags;       ///< τ values (0 … M, or −M … M)
  std::vector<double> value;   ///< r(τ), normalised correlation
  std::vector<double> bound;   ///< half-width of the band at each lag (0 at τ = 0 of the autocorrelation)
  std::vector<int> outside;    ///< lags with |r(τ)| > bound(τ) (τ = 0 of the autocorrelation excluded)
  double statistic = 0.0;      ///< joint χ² statistic Q over the tested lags (see the file comment)
  int degrees_of_freedom = 0;  ///< K of the χ²(K) reference distribution of Q
  double statistic_limit = 0;  ///< χ²(K) quantile at the confidence level
  double max_normalised = 0;   ///< largest |r(τ)|/σ_τ over the tested lags
  double max_limit = 0;        ///< Bonferroni bound on it
  double confidence = 0.99;    ///< level of the band and of the joint tests
  bool passed = true;          ///< both joint tests accept (see file comment)

  /// The lags outside the band, runs of consecutive lags compressed: "1..12, 15, -25..-3".
  [[nodiscard]] std::string lags_text() const {
    std::string s;
    for (std::size_t i = 0; i < outside.size();) {
      std::size_t j = i;
      while (j + 1 < outside.size() && outside[j + 1] == outside[j] + 1) ++j;
      s += (s.empty() ? "" : ", ") + std::to_string(outside[i]);
      if (j > i) s += (j == i + 1 ? ", " : "..") + std::to_string(outside[j]);
      i = j + 1;
    }
    return s;
  }
  /// "passed", or "correlated at lags 1..12, 15" (or "correlated" if no single lag leaves its band).
  [[nodiscard]] std::string verdict() const {
    if (passed) return "passed";
    if (outside.empty()) return "correlated (jointly; no single lag outside the band)";
    return "correlated at lag" + std::string(outside.size() > 1 ? "s " : " ") + lags_text();
  }
};

/// Outcome of `resid`: the whiteness test and one independence test per input.
struct ResidAnalysis {
  CorrelationTest whiteness;              ///< autocorrelation of ε, lags 0 … M
  std::vector<CorrelationTest> inputs;    ///< cross-correlation ε–u_c, lags −M … M
  Eigen::Index num_samples = 0;           ///< N used (pooled over experiments)
  double confidence = 0.99;               ///< level of bounds and verdicts
  double residual_rms = 0.0;              ///< √(R̂_ε(0)), same unit as y
  std::string source = "given residuals";  ///< "one-step prediction", "simulation" or "given residuals"

  /// True if the residuals pass the whiteness test.
  [[nodiscard]] bool white() const { return whiteness.passed; }
  /// True if the residuals pass the independence test for every input.
  [[nodiscard]] bool independent() const {
    return std::all_of(inputs.begin(), inputs.end(), [](const CorrelationTest& t) { return t.passed; });
  }
  /// One-paragraph verdict, e.g. "residuals (one-step prediction, N = 3998, 99 % confidence): white;
  /// independent of u1".
  [[nodiscard]] std::string verdict() const {
    std::string s = "residuals (" + source + ", N = " + std::to_string(num_samples) + ", " +
                    detail::format_g(100.0 * confidence) + " % confidence, rms " + detail::format_g(residual_rms, 4) +
                    "): ";
    s += white() ? "white" : "not white (" + whiteness.verdict() + ")";
    for (const auto& t : inputs) {
      s += t.passed ? "; independent of " + t.input
                    : "; correlated with " + t.input + (t.outside.empty() ? " (jointly)" : " (lags " + t.lags_text() + ")");
    }
    return s;
  }
  /// Verdict plus a table of the lags outside their band.
  [[nodiscard]] std::string report() const {
    std::string s = verdict() + "\n";
    auto line = [&s](const CorrelationTest& t) {
      s += "  " + detail::left_aligned(t.name, 32) + " Q = " + detail::format_g(t.statistic, 4) + " (limit " +
           detail::format_g(t.statistic_limit, 4) + "), max |r|/sigma = " + detail::format_g(t.max_normalised, 3) +
           " (limit " + detail::format_g(t.max_limit, 3) + "): " + t.verdict() + "\n";
    };
    line(whiteness);
    for (const auto& t : inputs) line(t);
    return s;
  }
};

namespace detail {

/// Standard normal quantile Φ⁻¹(p), by bisection on erfc (exact to rounding; called rarely).
inline double normal_quantile(double p) {
  require(p > 0.0 && p < 1.0, "normal quantile needs 0 < p < 1", at_parameter("confidence"));
  double lo = -40.0, hi = 40.0;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    if (0.5 * std::erfc(-mid / std::sqrt(2.0)) < p) lo = mid; else hi = mid;
  }
  return 0.5 * (lo + hi);
}

/// χ²(k) quantile: exact for k = 1, 2; the Wilson–Hilferty cube approximation (relative error
/// < 1 % for k ≥ 3) otherwise.
inline double chi_square_quantile(double p, int k) {
  if (k == 1) {
    const double z1 = normal_quantile(0.5 * (1.0 + p));
    return z1 * z1;
  }
  if (k == 2) return -2.0 * std::log1p(-p);
  const double z = normal_quantile(p);
  const double a = 2.0 / (9.0 * k);
  const double c = 1.0 - a + z * std::sqrt(a);
  return k * c * c * c;
}

/// Pooled (1/N) Σ a(t) b(t − τ) over segments; a and b are lists of equal-length columns.
inline double pooled_lag_product(const std::vector<Eigen::VectorXd>& a, const std::vector<Eigen::VectorXd>& b,
                                 int tau, Eigen::Index n_total) {
  double s = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const Eigen::Index n = a[i].size();
    if (tau >= 0) {
      for (Eigen::Index t = tau; t < n; ++t) s += a[i](t) * b[i](t - tau);
    } else {
      for (Eigen::Index t = 0; t < n + tau; ++t) s += a[i](t) * b[i](t - tau);
    }
  }
  return s / static_cast<double>(n_total);
}

/// Fills the bands and joint tests of `t` given the per-lag standard deviations σ_τ (tested lags
/// only). The χ² statistic is Σ (r/σ)² with K = tested lags unless `joint` gives it (Q, K).
inline void finish_test(CorrelationTest& t, const std::vector<double>& sigma, const std::vector<bool>& tested,
                        double confidence, double z, const std::pair<double, int>* joint = nullptr) {
  int k = 0;
  for (std::size_t i = 0; i < t.value.size(); ++i) {
    t.bound[i] = tested[i] ? z * sigma[i] : 0.0;
    if (!tested[i]) continue;
    ++k;
    const double q = t.value[i] / sigma[i];
    t.statistic += q * q;
    t.max_normalised = std::max(t.max_normalised, std::abs(q));
    if (std::abs(t.value[i]) > t.bound[i]) t.outside.push_back(t.lags[i]);
  }
  const double alpha = 1.0 - confidence;
  t.confidence = confidence;
  t.degrees_of_freedom = k;
  if (joint != nullptr) {
    t.statistic = joint->first;
    t.degrees_of_freedom = joint->second;
  }
  t.statistic_limit = chi_square_quantile(confidence, std::max(t.degrees_of_freedom, 1));
  t.max_limit = normal_quantile(1.0 - alpha / (2.0 * std::max(k, 1)));
  t.passed = t.statistic <= t.statistic_limit && t.max_normalised <= t.max_limit;
}

/// Joint statistic of the cross test (file comment): Q = Sᵀ V⁺ S, S(τ) = Σ_t ε(t) u(t − τ)
/// (= N R̂_εu(τ)), V = Σ_{|k|≤M} c(|k|) Σ_t a_t a_{t−k}ᵀ its covariance under independence given
/// u, where a_t(τ) = u(t − τ) where lag τ uses sample t and 0 elsewhere; c(k) = w_k R̂_ε(k).
/// Returns (Q, rank of V). `s` holds S(τ) for τ = −m … m; `uc` the centred input per experiment.
template <int = 0>
std::pair<double, int> cross_joint_statistic(const Eigen::VectorXd& s, const std::vector<Eigen::VectorXd>& uc,
                                             const std::vector<double>& c, int m) {
  const int kk = 2 * m + 1, dmax = 3 * m, edge = 3 * m + 1;
  Eigen::MatrixXd v = Eigen::MatrixXd::Zero(kk, kk);
  for (const Eigen::VectorXd& u : uc) {
    const Eigen::Index n = u.size();
    // Lag sums Σ_{s=lo}^{hi−1} u(s) u(s − d) in O(1): the full sum minus head and tail partial
    // sums (the ranges differ from the full one by at most 3M samples at either end).
    const bool fast = n > dmax + 2 * edge;
    std::vector<double> full, head, tail;  // [d * (edge + 1) + j]
    if (fast) {
      full.assign(static_cast<std::size_t>(dmax + 1), 0.0);
      head.assign(static_cast<std::size_t>((dmax + 1) * (edge + 1)), 0.0);
      tail = head;
      for (int d = 0; d <= dmax; ++d) {
        double f = 0.0;
        for (Eigen::Index t = d; t < n; ++t) f += u(t) * u(t - d);
        full[static_cast<std::size_t>(d)] = f;
        const std::size_t o = static_cast<std::size_t>(d) * static_cast<std::size_t>(edge + 1);
        for (int j = 1; j <= edge; ++j) {
          const std::size_t i = o + static_cast<std::size_t>(j);
          head[i] = head[i - 1] + u(d + j - 1) * u(j - 1);
          tail[i] = tail[i - 1] + u(n - j) * u(n - j - d);
        }
      }
    }
    const auto lag_sum = [&](Eigen::Index d, Eigen::Index lo, Eigen::Index hi) {
      if (d < 0) {  // Σ u(s) u(s + |d|) = Σ_{s'} u(s' − |d|) u(s'), s' = s + |d|
        lo -= d;
        hi -= d;
        d = -d;
      }
      lo = std::max(lo, d);
      hi = std::min(hi, n);
      if (hi <= lo) return 0.0;
      const Eigen::Index a = lo - d, b = n - hi;
      if (fast && a <= edge && b <= edge) {
        const std::size_t o = static_cast<std::size_t>(d) * static_cast<std::size_t>(edge + 1);
        return full[static_cast<std::size_t>(d)] - head[o + static_cast<std::size_t>(a)] -
               tail[o + static_cast<std::size_t>(b)];
      }
      double r = 0.0;
      for (Eigen::Index t = lo; t < hi; ++t) r += u(t) * u(t - d);
      return r;
    };
    for (int i = 0; i < kk; ++i) {
      const Eigen::Index ti = i - m;
      for (int j = i; j < kk; ++j) {
        const Eigen::Index tj = j - m;
        double acc = 0.0;
        for (int k = -m; k <= m; ++k) {
          const double ck = c[static_cast<std::size_t>(std::abs(k))];
          if (ck == 0.0) continue;
          // t uses lag τ_i (0 ≤ t − τ_i < n) and t − k uses lag τ_j; sum over s = t − τ_i.
          const Eigen::Index tlo = std::max(std::max<Eigen::Index>(0, ti), k + std::max<Eigen::Index>(0, tj));
          const Eigen::Index thi = std::min(std::min(n, n + ti), k + std::min(n, n + tj));
          acc += ck * lag_sum(k + tj - ti, tlo - ti, thi - ti);
        }
        v(i, j) += acc;
      }
    }
  }
  v.triangularView<Eigen::StrictlyLower>() = v.transpose().triangularView<Eigen::StrictlyLower>();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(v);
  const Eigen::VectorXd& lambda = es.eigenvalues();
  const double top = lambda.maxCoeff();
  double q = 0.0;
  int rank = 0;
  if (top > 0.0) {
    const Eigen::VectorXd proj = es.eigenvectors().transpose() * s;
    for (int l = 0; l < kk; ++l) {
      if (!(lambda(l) > 1e-10 * top)) continue;
      q += proj(l) * proj(l) / lambda(l);
      ++rank;
    }
  }
  return {q, rank};
}

}  // namespace detail

/// Residual analysis of given residual sequences: `residuals[i]` (N_i samples) and the inputs
/// `inputs[i]` (N_i × n_u) of the same experiments; `input_names` names the columns (default
/// "u1", …). Throws `nlid::Error` on mismatched lengths, non-finite values, too few samples
/// (N ≤ 2M) or a constant residual.
inline ResidAnalysis resid(const std::vector<Eigen::VectorXd>& residuals, const std::vector<Eigen::MatrixXd>& inputs,
                           const ResidOptions& options = {}, std::vector<std::string> input_names = {}) {
  require(options.max_lag >= 1, "resid: max_lag must be >= 1, got " + std::to_string(options.max_lag),
          at_parameter("max_lag"));
  require(options.confidence > 0.0 && options.confidence < 1.0,
          "resid: confidence must be in (0, 1), got " + detail::format_f(options.confidence, 6),
          at_parameter("confidence"));
  require(!residuals.empty() && residuals.size() == inputs.size(),
          "resid: need one input matrix per residual sequence (got " + std::to_string(residuals.size()) +
              " residual sequences and " + std::to_string(inputs.size()) + " input matrices)",
          at_parameter("inputs"));
  const Eigen::Index nu = inputs[0].cols();
  Eigen::Index n_total = 0;
  for (std::size_t i = 0; i < residuals.size(); ++i) {
    require(inputs[i].rows() == residuals[i].size() && inputs[i].cols() == nu,
            "resid: experiment " + std::to_string(i) + " has " + std::to_string(residuals[i].size()) +
                " residuals but an input of " + std::to_string(inputs[i].rows()) + " x " +
                std::to_string(inputs[i].cols()),
            at_experiment(static_cast<long>(i)));
    for (Eigen::Index t = 0; t < residuals[i].size(); ++t) {
      require(std::isfinite(residuals[i](t)),
              "resid: residual of experiment " + std::to_string(i) + " is not finite at sample " + std::to_string(t) +
                  " (the model diverged or the data have gaps)",
              at_experiment(static_cast<long>(i)));
    }
    require(inputs[i].allFinite(), "resid: input of experiment " + std::to_string(i) + " has non-finite samples",
            at_experiment(static_cast<long>(i)));
    n_total += residuals[i].size();
  }
  const int m = options.max_lag;
  require(n_total > 2 * m, "resid: " + std::to_string(n_total) + " samples are too few for lags up to " +
                               std::to_string(m) + " (need more than " + std::to_string(2 * m) + ")",
          at_parameter("max_lag"));
  // Centre per pooled mean: a constant offset is not "correlation" but a bias (shown by rms).
  double e_mean = 0.0;
  for (const auto& e : residuals) e_mean += e.sum();
  e_mean /= static_cast<double>(n_total);
  std::vector<Eigen::VectorXd> ec;
  for (const auto& e : residuals) ec.push_back(e.array() - e_mean);

  ResidAnalysis out;
  out.num_samples = n_total;
  out.confidence = options.confidence;
  const double z = detail::normal_quantile(0.5 * (1.0 + options.confidence));
  std::vector<double> re(static_cast<std::size_t>(m + 1));
  for (int tau = 0; tau <= m; ++tau) re[static_cast<std::size_t>(tau)] = detail::pooled_lag_product(ec, ec, tau, n_total);
  const double r0 = re[0];
  require(r0 > 0.0, "resid: the residuals are constant (zero variance); nothing to test",
          at_parameter("residuals"));
  double raw_ms = 0.0;
  for (const auto& e : residuals) raw_ms += e.squaredNorm();
  out.residual_rms = std::sqrt(raw_ms / static_cast<double>(n_total));
  const double sn = std::sqrt(static_cast<double>(n_total));

  CorrelationTest& w = out.whiteness;
  w.name = "autocorrelation of e";
  std::vector<double> sigma;
  std::vector<bool> tested;
  for (int tau = 0; tau <= m; ++tau) {
    w.lags.push_back(tau);
    w.value.push_back(re[static_cast<std::size_t>(tau)] / r0);
    w.bound.push_back(0.0);
    sigma.push_back(1.0 / sn);
    tested.push_back(tau >= 1);
  }
  detail::finish_test(w, sigma, tested, options.confidence, z);

  for (Eigen::Index c = 0; c < nu; ++c) {
    std::vector<Eigen::VectorXd> uc;
    double u_mean = 0.0;
    for (const auto& u : inputs) u_mean += u.col(c).sum();
    u_mean /= static_cast<double>(n_total);
    for (const auto& u : inputs) uc.push_back(u.col(c).array() - u_mean);
    std::vector<double> ru(static_cast<std::size_t>(m + 1));
    for (int tau = 0; tau <= m; ++tau) ru[static_cast<std::size_t>(tau)] = detail::pooled_lag_product(uc, uc, tau, n_total);
    const std::string name = c < static_cast<Eigen::Index>(input_names.size()) && !input_names[static_cast<std::size_t>(c)].empty()
                                 ? input_names[static_cast<std::size_t>(c)]
                                 : "u" + std::to_string(c + 1);
    CorrelationTest t;
    t.name = "cross-correlation " + name + " -> e";
    t.input = name;
    if (!(ru[0] > 0.0)) {
      // A constant input cannot be correlated with anything: nothing to test, reported as passed.
      t.passed = true;
      t.confidence = options.confidence;
      out.inputs.push_back(t);
      continue;
    }
    // P = Σ_{|k|≤M} R̂_ε(k) R̂_u(k) (both even functions); never below the white-residual value's
    // floor of 0 — a negative estimate (short data) falls back to R̂_ε(0)R̂_u(0).
    double p = re[0] * ru[0];
    for (int k = 1; k <= m; ++k) p += 2.0 * re[static_cast<std::size_t>(k)] * ru[static_cast<std::size_t>(k)];
    if (!(p > 0.0)) p = re[0] * ru[0];
    const double norm = std::sqrt(re[0] * ru[0]);
    const double s_tau = std::sqrt(p) / (sn * norm);
    sigma.assign(static_cast<std::size_t>(2 * m + 1), s_tau);
    tested.assign(static_cast<std::size_t>(2 * m + 1), true);
    Eigen::VectorXd sums(2 * m + 1);
    for (int tau = -m; tau <= m; ++tau) {
      const double r_eu = detail::pooled_lag_product(ec, uc, tau, n_total);
      sums(tau + m) = r_eu * static_cast<double>(n_total);
      t.lags.push_back(tau);
      t.value.push_back(r_eu / norm);
      t.bound.push_back(0.0);
    }
    // Joint test with the full covariance of the lags (file comment), Bartlett-windowed R̂_ε.
    std::vector<double> cw(static_cast<std::size_t>(m + 1));
    for (int k = 0; k <= m; ++k)
      cw[static_cast<std::size_t>(k)] = (1.0 - k / (m + 1.0)) * re[static_cast<std::size_t>(k)];
    const std::pair<double, int> joint = detail::cross_joint_statistic(sums, uc, cw, m);
    detail::finish_test(t, sigma, tested, options.confidence, z, &joint);
    out.inputs.push_back(std::move(t));
  }
  return out;
}

namespace detail {
template <class M>
concept OneStepPredictor = requires(const M& m, const Experiment& e) {
  { m.predict(e, 1) } -> std::convertible_to<Eigen::MatrixXd>;
};
template <class M>
concept HasHistoryLength = requires(const M& m) {
  { m.history_length() } -> std::convertible_to<int>;
};
template <class M>
concept ExperimentSimulator = requires(const M& m, const Experiment& e, InitialCondition ic) {
  { m.simulate(e, ic) } -> std::convertible_to<Eigen::MatrixXd>;
};
/// Leading samples the model's predictor (and measured-start simulation) copies from the data:
/// `history_length()` (nonlinear ARX, AnyModel), an ARX model's largest lag (recognised by its
/// `orders().max_lag()` and `na()`), else 0.
template <class M>
int copied_samples(const M& m) {
  if constexpr (HasHistoryLength<M>) {
    return m.history_length();
  } else if constexpr (requires { { m.orders().max_lag() } -> std::convertible_to<int>; m.na(); }) {
    return m.orders().max_lag();
  } else {
    return 0;
  }
}
/// True if the model predicts one step ahead: it has `predict(e, 1)` and, for a type-erased
/// model (AnyModel), the held model has a predictor of its own (`has_predictor()`).
template <class M>
bool predicts(const M& m) {
  if constexpr (!OneStepPredictor<M>) {
    (void)m;
    return false;
  } else if constexpr (requires { { m.has_predictor() } -> std::convertible_to<bool>; }) {
    return m.has_predictor();
  } else {
    return true;
  }
}
}  // namespace detail

/// Residual analysis of a model on data (file comment): any model with
/// `simulate(const Experiment&, InitialCondition)`; `predict(e, 1)` is used when present (for an
/// `AnyModel`, when the held model has a predictor: a grey box behind an AnyModel takes the
/// simulation path with `ResidOptions::initial_condition`, as it does unwrapped).
/// Throws `nlid::Error` naming the experiment on bad data or a diverging model.
template <class M>
  requires detail::ExperimentSimulator<M>
ResidAnalysis resid(const M& model, const Dataset& data, const ResidOptions& options = {}) {
  require(data.size() > 0, "resid: the data set is empty", at_parameter("data"));
  require(options.output >= 0 && options.output < data.num_outputs(),
          "resid: output " + std::to_string(options.output) + " does not exist (the data have " +
              std::to_string(data.num_outputs()) + ")",
          at_parameter("output"));
  const bool use_prediction = detail::predicts(model) && options.source != ResidualSource::simulation;
  require(use_prediction || options.source != ResidualSource::prediction,
          "resid: the model has no one-step predictor (predict(e, 1)); use ResidualSource::simulation",
          at_parameter("source"));
  std::vector<Eigen::VectorXd> eps;
  std::vector<Eigen::MatrixXd> us;
  for (std::size_t i = 0; i < data.size(); ++i) {
    const Experiment& e = data[i];
    Eigen::MatrixXd yhat;
    Eigen::Index skip = 0;
    // The samples predict (or a measured start) copies from the data have exact-zero
    // residuals: skipped.
    if (use_prediction) {
      if constexpr (detail::OneStepPredictor<M>) yhat = model.predict(e, 1);
      skip = detail::copied_samples(model);
    } else {
      yhat = model.simulate(e, options.initial_condition);
      if (options.initial_condition == InitialCondition::measured) skip = detail::copied_samples(model);
    }
    skip = std::min<Eigen::Index>(skip, e.size());
    require(yhat.rows() == e.size() && yhat.cols() > options.output,
            "resid: the model returned " + std::to_string(yhat.rows()) + " x " + std::to_string(yhat.cols()) +
                " outputs for experiment '" + e.name() + "' of " + std::to_string(e.size()) + " samples",
            at_experiment(static_cast<long>(i)));
    const Eigen::Index n = e.size() - skip;
    eps.push_back(e.y().col(options.output).tail(n) - yhat.col(options.output).tail(n));
    // Checked here, not by the residual-level resid: residual k is data sample k + skip.
    for (Eigen::Index t = 0; t < n; ++t) {
      require(std::isfinite(eps.back()(t)),
              "resid: residual of experiment " + std::to_string(i) + " is not finite at sample " +
                  std::to_string(t + skip) + " (the model diverged or the data have gaps)",
              at_experiment(static_cast<long>(i)));
    }
    us.push_back(e.u().bottomRows(n));
  }
  ResidAnalysis r = resid(eps, us, options, data[0].input_names());
  r.source = use_prediction ? "one-step prediction" : "simulation";
  return r;
}

/// As above for one experiment.
template <class M>
  requires detail::ExperimentSimulator<M>
ResidAnalysis resid(const M& model, const Experiment& e, const ResidOptions& options = {}) {
  return resid(model, Dataset(e), options);
}

/// SVG stem chart of one correlation test: r(τ) as stems from 0, the confidence band shaded
/// (labelled with the test's own level, `CorrelationTest::confidence`), lags outside the band
/// listed in the title. For `HtmlReport` (io/html_report.hpp).
inline std::string resid_chart_svg(const CorrelationTest& t) {
  LineChart chart(t.name + (t.passed ? "  (passed)" : "  (" + t.verdict() + ")"));
  chart.x_label("lag (samples)").y_label("correlation");
  std::vector<double> x, y;
  for (std::size_t i = 0; i < t.lags.size(); ++i) {
    // Stems as separate segments: NaN breaks the polyline between lags.
    x.insert(x.end(), {double(t.lags[i]), double(t.lags[i]), double(t.lags[i])});
    y.insert(y.end(), {0.0, t.value[i], std::numeric_limits<double>::quiet_NaN()});
  }
  chart.line("r(tau)", x, y, "#1f77b4");
  double b = 0.0;
  for (std::size_t i = 0; i < t.bound.size(); ++i) b = std::max(b, t.bound[i]);
  if (b > 0.0) chart.band(-b, b, detail::format_g(100.0 * t.confidence) + " % confidence");
  double top = 1.5 * b;
  for (double v : t.value) top = std::max(top, 1.1 * std::abs(v));
  if (!(top > 0.0)) top = 1.0;
  chart.y_limits(-top, top);
  chart.decimate(false);
  return chart.svg();
}

}  // namespace nlid
