#pragma once
/// @file
/// Parameter uncertainty of a least-squares estimate: standard deviations, correlations, and the
/// combinations of parameters the data cannot tell apart.
///
/// Near the optimum θ̂ the estimate is asymptotically Gaussian with covariance (Ljung 1999,
/// sec. 9.2–9.3)
///
///     P = H⁻¹ S H⁻¹,   H = JᵀJ,   S = Σ_τ Σ_t ψ(t) e(t) e(t−τ) ψ(t−τ)ᵀ,
///
/// ψ(t)ᵀ being J's row of residual e(t). White residuals collapse S to σ²H and P to σ²(JᵀJ)⁻¹,
/// the formula most tools print. Simulation-error (output-error) fits rarely leave white
/// residuals: what a model misses is a slow error, correlated over many samples, and the white
/// formula then understates the spread of θ̂ — several times over on real records. So the
/// default estimates S from the residuals themselves (Newey & West 1987: the lag sums weighted
/// by Bartlett's window 1 − τ/(M+1), which keeps S positive semi-definite), with M from
/// Andrews' (1991) AR(1) plug-in rule unless a lag is given, after prewhitening the scores
/// (Andrews & Monahan 1992) and undoing each residual's shrinkage by its leverage (HC2). Both standard deviations are
/// returned; their ratio says how far from white the residuals are.
///
/// Identifiability. H is formed from the column-normalised Jacobian (every column scaled to
/// unit norm, so units and magnitudes do not matter) and eigen-decomposed. Eigenvalues below
/// `rank_tolerance`·λ_max are directions the data do not determine: they are reported as
/// parameter combinations ("c +1 % together with b −1 % leaves the residuals unchanged"), the
/// parameters taking part get an infinite standard deviation, and the others come from the
/// pseudo-inverse, which is what they are determined to once that combination is pinned.
///
/// Limits the report states: the formula is local (a parameter resting on a bound is treated as
/// fixed); with a robust loss or a regularisation it describes the data term under squared loss.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <Eigen/SVD>

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/estimation/concepts.hpp"
#include "nlid/estimation/detail/covariance_check.hpp"
#include "nlid/estimation/levenberg_marquardt.hpp"

namespace nlid {

/// A run of residual rows that form one time series: rows offset, offset + stride, …
/// (`length` of them). Lag sums of the correlated-residual covariance stay inside a series: one
/// per experiment and output (the grey-box problem lays experiment e's output j at
/// offset_e + j with stride n_y).
struct ResidualSeries {
  Eigen::Index offset = 0;
  Eigen::Index length = 0;
  Eigen::Index stride = 1;
};

/// What the covariance assumes of the residuals.
enum class ResidualModel {
  white,      ///< independent, equal variance: P = σ²(JᵀJ)⁻¹
  correlated  ///< correlated in time (Newey–West lag window): P = H⁻¹SH⁻¹
};

/// Settings of `parameter_uncertainty`.
struct UncertaintyOptions {
  /// Which covariance `stddev` and `covariance` hold (the white one is always returned too).
  ResidualModel residuals = ResidualModel::correlated;
  /// Time series of the residual vector; empty: all rows, in order, are one series.
  std::vector<ResidualSeries> series;
  /// Bartlett window length M (lags 1…M) of the correlated covariance; −1: Andrews' rule.
  int max_lag = -1;
  /// Prewhiten the scores with a VAR(1) fit before the lag window (Andrews & Monahan 1992).
  bool prewhiten = true;
  /// Parameters held fixed in the estimation (size 0 or n).
  std::vector<bool> fixed;
  /// Bounds of the estimation (size 0 or n); a parameter on its bound is treated as fixed.
  Eigen::VectorXd lower_bounds, upper_bounds;
  /// Parameter names for the report and error messages (size 0 or n).
  std::vector<std::string> names;
  /// Eigenvalues of the normalised JᵀJ below this fraction of the largest are unidentifiable
  /// directions (1e-10: singular values 10⁵ apart).
  double rank_tolerance = 1e-10;
  /// Caveat printed by `report()` (e.g. "robust loss" or "regularised"); empty: none.
  std::string caveat;
};

/// Standard deviations, covariance and identifiability of an estimate.
struct ParameterUncertainty {
  std::vector<std::string> names;  ///< parameter names ("theta[i]" if none were given)
  Eigen::VectorXd theta;           ///< the estimate the uncertainty is about
  ResidualModel residuals = ResidualModel::correlated;  ///< what `stddev`/`covariance` assume
  Eigen::VectorXd stddev;          ///< 1σ per parameter: 0 if fixed, +∞ if not identifiable
  Eigen::VectorXd stddev_white;    ///< 1σ from the white-residual formula σ²(JᵀJ)⁻¹
  /// n × n; rows/columns of fixed and on-bound parameters zero. For an unidentifiable parameter
  /// they hold the pseudo-inverse's (finite) values while its `stddev` is +∞: use `stddev`.
  Eigen::MatrixXd covariance;
  Eigen::MatrixXd correlation;     ///< n × n; NaN where a standard deviation is 0 or ∞
  std::vector<bool> free;          ///< estimated and off its bounds
  std::vector<bool> at_bound;      ///< estimated but resting on a bound (treated as fixed)
  double noise_variance = 0.0;     ///< σ² = Σe²/(N − k)
  Eigen::Index observations = 0;   ///< N: residual rows that carry data
  Eigen::Index degrees_of_freedom = 0;  ///< N − k, k = number of free parameters
  int rank = 0;                    ///< identifiable directions among the k free parameters
  int max_lag = 0;                 ///< Bartlett window length M used (0 for white)
  double lag1_correlation = 0.0;   ///< pooled lag-1 autocorrelation of the residuals
  /// Unidentifiable directions: changes of θ (parameter units) that leave the residuals
  /// unchanged to first order, scaled so the largest relative change |Δθᵢ/θᵢ| is 1 %.
  std::vector<Eigen::VectorXd> unidentifiable;
  std::string caveat;              ///< from the options
  /// Rebuilt from a stored covariance (`uncertainty_from_covariance`): no residuals or data
  /// behind it here, so `observations` is 0 and the white-formula deviations are NaN.
  bool stored = false;

  /// Relative standard deviation of parameter i in % (∞ if θᵢ = 0 and σᵢ > 0).
  [[nodiscard]] double relative_percent(Eigen::Index i) const {
    if (stddev[i] == 0.0) return 0.0;
    return theta[i] != 0.0 ? 100.0 * stddev[i] / std::abs(theta[i]) : std::numeric_limits<double>::infinity();
  }

  /// Readable account: one line per parameter (`count` first ones; −1: all) with ±1σ and the
  /// white-formula value, the unidentifiable combinations, and pairs correlated beyond 0.95.
  [[nodiscard]] std::string report(int count = -1) const {
    auto num = [](double v) { return detail::format_g(v, 4); };
    const Eigen::Index n = count < 0 ? theta.size() : std::min<Eigen::Index>(count, theta.size());
    std::string s = "Parameter uncertainty (1 sigma; ";
    if (stored) {
      const auto nfree = std::count(free.begin(), free.end(), true);
      s += "from a stored covariance; " + std::to_string(theta.size()) + " unknowns, " + std::to_string(nfree) + " free";
      if (rank < nfree) s += ", " + std::to_string(nfree - rank) + " of them undetermined";
      s += ")\n";
    } else {
      s += residuals == ResidualModel::white
               ? std::string("white residuals")
               : "correlated residuals: prewhitened Newey-West, " + std::to_string(max_lag) + (max_lag == 1 ? " lag" : " lags");
      s += "; N = " + std::to_string(observations) + ", " + std::to_string(theta.size()) +
           " unknowns, rank " + std::to_string(rank) + "; residual lag-1 correlation " +
           num(lag1_correlation) + ")\n";
    }
    std::size_t width = 0;
    for (Eigen::Index i = 0; i < n; ++i) width = std::max(width, names[static_cast<std::size_t>(i)].size());
    for (Eigen::Index i = 0; i < n; ++i) {
      const auto iu = static_cast<std::size_t>(i);
      std::string line = "  " + detail::left_aligned(names[iu], width) + " = " + num(theta[i]);
      if (at_bound[iu]) {
        line += "  (on its bound: no standard deviation)";
      } else if (!free[iu]) {
        line += "  (fixed)";
      } else if (!std::isfinite(stddev[i])) {
        line += " +- inf  (not identifiable, see below)";
      } else {
        line += " +- " + num(stddev[i]) + " (" + num(relative_percent(i)) + " %)";
        if (residuals == ResidualModel::correlated && i < stddev_white.size() && std::isfinite(stddev_white[i]))
          line += "   white formula: +- " + num(stddev_white[i]);
      }
      s += line + "\n";
    }
    // At most five directions, each by its five largest relative changes: an over-parametrised
    // network can have dozens, each touching most parameters a little.
    constexpr std::size_t max_directions = 5;
    constexpr std::size_t max_terms = 5;
    for (std::size_t dir = 0; dir < unidentifiable.size() && dir < max_directions; ++dir) {
      const Eigen::VectorXd& v = unidentifiable[dir];
      auto size_of = [&](Eigen::Index i) { return theta[i] != 0.0 ? std::abs(v[i] / theta[i]) : std::abs(v[i]); };
      std::vector<Eigen::Index> order;
      for (Eigen::Index i = 0; i < v.size(); ++i) {
        if (v[i] != 0.0 && (theta[i] == 0.0 || 100.0 * size_of(i) >= 0.01)) order.push_back(i);
      }
      std::stable_sort(order.begin(), order.end(), [&](Eigen::Index a, Eigen::Index b) { return size_of(a) > size_of(b); });
      std::string combo;
      for (std::size_t t = 0; t < order.size() && t < max_terms; ++t) {
        const Eigen::Index i = order[t];
        const double rel = theta[i] != 0.0 ? 100.0 * v[i] / std::abs(theta[i]) : 0.0;
        if (!combo.empty()) combo += " with ";
        combo += names[static_cast<std::size_t>(i)] + " " +
                 (theta[i] != 0.0 ? (rel >= 0 ? "+" : "") + num(rel) + " %" : (v[i] >= 0 ? "+" : "") + num(v[i]));
      }
      if (order.size() > max_terms) {
        const std::size_t more = order.size() - max_terms;
        combo += " (and " + std::to_string(more) + (more == 1 ? " smaller change)" : " smaller changes)");
      }
      s += "  not identifiable from these data: " + combo + " leaves the residuals unchanged\n";
    }
    if (unidentifiable.size() > max_directions) {
      const std::size_t more = unidentifiable.size() - max_directions;
      s += "  ... and " + std::to_string(more) + (more == 1 ? " more undetermined direction" : " more undetermined directions") +
           " (ParameterUncertainty::unidentifiable)\n";
    }
    for (Eigen::Index i = 0; i < n; ++i) {
      for (Eigen::Index j = i + 1; j < n; ++j) {
        if (std::abs(correlation(i, j)) > 0.95) {
          s += "  strongly correlated: " + names[static_cast<std::size_t>(i)] + " and " +
               names[static_cast<std::size_t>(j)] + " (" + num(correlation(i, j)) + ")\n";
        }
      }
    }
    if (!caveat.empty()) s += "  note: " + caveat + "\n";
    return s;
  }
};

namespace detail {

// Rows of one residual series.
inline Eigen::Index series_row(const ResidualSeries& s, Eigen::Index t) { return s.offset + t * s.stride; }

// Andrews' (1991) bandwidth for Bartlett's window from AR(1) fits to each score column:
// M = 1.1447 (α L)^{1/3}, α = Σ 4ρ²σ⁴/((1−ρ)⁶(1+ρ)²) / Σ σ⁴/(1−ρ)⁴ (σ²: innovation variance).
// ρ is clipped to ±0.97: nearer to 1 the rule asks for windows as long as the record, where the
// lag sums of scores that add to zero at the optimum (the normal equations) collapse towards 0.
inline int andrews_lag(const Eigen::MatrixXd& G, const std::vector<ResidualSeries>& series, double typical_length,
                       Eigen::Index longest) {
  double num = 0.0, den = 0.0;
  for (Eigen::Index a = 0; a < G.cols(); ++a) {
    double sxy = 0.0, sxx = 0.0;
    for (const ResidualSeries& s : series) {
      for (Eigen::Index t = 1; t < s.length; ++t) {
        sxy += G(series_row(s, t), a) * G(series_row(s, t - 1), a);
        sxx += G(series_row(s, t - 1), a) * G(series_row(s, t - 1), a);
      }
    }
    if (!(sxx > 0.0)) continue;
    const double rho = std::clamp(sxy / sxx, -0.97, 0.97);
    double e2 = 0.0, cnt = 0.0;
    for (const ResidualSeries& s : series) {
      for (Eigen::Index t = 1; t < s.length; ++t) {
        const double v = G(series_row(s, t), a) - rho * G(series_row(s, t - 1), a);
        e2 += v * v;
        cnt += 1.0;
      }
    }
    const double s2 = e2 / cnt;
    num += 4.0 * rho * rho * s2 * s2 / (std::pow(1.0 - rho, 6) * (1.0 + rho) * (1.0 + rho));
    den += s2 * s2 / std::pow(1.0 - rho, 4);
  }
  if (!(den > 0.0)) return 0;
  const double alpha = num / den;
  const double m = 1.1447 * std::cbrt(alpha * typical_length);
  // At most a quarter of the longest series: longer windows see too few lag products. (Not the
  // shortest: one short record beside long ones would cut everybody's window; a short series
  // simply contributes the lags it has.)
  return static_cast<int>(std::clamp(std::ceil(m), 0.0, std::max(0.0, static_cast<double>(longest / 4))));
}

}  // namespace detail

/// The caveat an estimation's settings put on its uncertainty (empty for plain least squares).
inline std::string uncertainty_caveat(const LmOptions& lm) {
  std::string c;
  if (lm.loss.kind != RobustLoss::Kind::squared) c = "estimated with a robust loss";
  if (lm.regularization.lambda > 0.0) c += std::string(c.empty() ? "" : " and ") + "regularised";
  if (!c.empty()) c += "; the standard deviations describe the squared-error data term alone";
  return c;
}

/// Uncertainty of the estimate `theta` of `problem` (see the file comment). Evaluates the
/// residuals and Jacobian once. Throws `nlid::Error` on inconsistent sizes, a θ at which the
/// problem cannot be evaluated or whose Jacobian is not finite (naming the parameter), a series
/// outside the residual vector, or fewer data rows than free parameters.
template <LeastSquaresProblem Pb>
ParameterUncertainty parameter_uncertainty(const Pb& problem, const Eigen::VectorXd& theta,
                                           const UncertaintyOptions& options = {}) {
  const char* who = "parameter_uncertainty: ";
  const int n = problem.num_parameters();
  const Eigen::Index m = problem.num_residuals();
  require(theta.size() == n, std::string(who) + "theta has " + std::to_string(theta.size()) +
                                 " entries; the problem has " + std::to_string(n) + " parameters",
          at_parameter("theta"));
  auto check_size = [&](Eigen::Index size, const char* what) {
    require(size == 0 || size == n, std::string(who) + what + " has " + std::to_string(size) +
                                        " entries; the problem has " + std::to_string(n) + " parameters",
            at_parameter(what));
  };
  check_size(static_cast<Eigen::Index>(options.fixed.size()), "fixed");
  check_size(static_cast<Eigen::Index>(options.names.size()), "names");
  check_size(options.lower_bounds.size(), "lower_bounds");
  check_size(options.upper_bounds.size(), "upper_bounds");
  require(options.rank_tolerance > 0.0 && options.rank_tolerance < 1.0,
          std::string(who) + "rank_tolerance must be in (0, 1), got " + detail::format_f(options.rank_tolerance, 6),
          at_parameter("rank_tolerance"));
  require(options.max_lag >= -1, std::string(who) + "max_lag must be >= 0, or -1 for automatic; got " +
                                     std::to_string(options.max_lag),
          at_parameter("max_lag"));

  ParameterUncertainty out;
  out.residuals = options.residuals;
  out.caveat = options.caveat;
  out.theta = theta;
  for (int i = 0; i < n; ++i) {
    out.names.push_back(options.names.empty() ? "theta[" + std::to_string(i) + "]"
                                              : options.names[static_cast<std::size_t>(i)]);
    require(std::isfinite(theta[i]), std::string(who) + "parameter " + out.names.back() + " is not finite",
            at_parameter(out.names.back()));
    // A NaN bound compares false and would silently make an on-bound parameter free.
    const double lo = options.lower_bounds.size() ? options.lower_bounds[i] : -std::numeric_limits<double>::infinity();
    const double hi = options.upper_bounds.size() ? options.upper_bounds[i] : std::numeric_limits<double>::infinity();
    require(!std::isnan(lo) && !std::isnan(hi) && lo <= hi,
            std::string(who) + "the bounds [" + detail::format_g(lo) + ", " + detail::format_g(hi) + "] of parameter " +
                out.names.back() + " are not an interval",
            at_parameter(out.names.back()));
  }

  std::vector<ResidualSeries> series = options.series;
  if (series.empty()) series.push_back({0, m, 1});
  Eigen::Index total_length = 0, longest = 0;
  std::vector<unsigned char> covered(static_cast<std::size_t>(m), 0);
  for (std::size_t k = 0; k < series.size(); ++k) {
    const ResidualSeries& s = series[k];
    const bool ok = s.length >= 1 && s.stride >= 1 && s.offset >= 0 && s.offset + (s.length - 1) * s.stride < m;
    require(ok, std::string(who) + "residual series " + std::to_string(k) + " (offset " + std::to_string(s.offset) +
                    ", length " + std::to_string(s.length) + ", stride " + std::to_string(s.stride) +
                    ") is empty or reaches outside the " + std::to_string(m) + " residuals",
            at_parameter("series"));
    total_length += s.length;
    longest = std::max(longest, s.length);
    // Each row in exactly one series: an overlap would count its lag products twice, and a row
    // outside every series would be neither prewhitened nor windowed.
    for (Eigen::Index t = 0; t < s.length; ++t) {
      unsigned char& c = covered[static_cast<std::size_t>(detail::series_row(s, t))];
      require(c == 0, std::string(who) + "residual row " + std::to_string(detail::series_row(s, t)) +
                          " is in two series (the second is series " + std::to_string(k) + ")",
              at_parameter("series"));
      c = 1;
    }
  }
  // The length of the series a sample belongs to, on average (Σ L² / Σ L): the T of Andrews'
  // rule. Equal records give their length; a short record beside long ones hardly matters.
  double typical_length = 0.0;
  for (const ResidualSeries& s : series) typical_length += static_cast<double>(s.length) * static_cast<double>(s.length);
  typical_length /= static_cast<double>(total_length);
  for (Eigen::Index row = 0; row < m; ++row) {
    require(covered[static_cast<std::size_t>(row)] != 0,
            std::string(who) + "residual row " + std::to_string(row) + " is in no series; the series must cover all " +
                std::to_string(m) + " residuals",
            at_parameter("series"));
  }

  const ParameterVector<Pb::num_params> th = theta;
  Eigen::VectorXd r(m);
  JacobianMatrix<Pb::num_params> Jfull(m, n);
  require(problem.evaluate(th, r, &Jfull), std::string(who) + "the problem cannot be evaluated at theta",
          at_parameter("theta"));
  for (int i = 0; i < n; ++i) {
    require(Jfull.col(i).allFinite(), std::string(who) + "the Jacobian column of " + out.names[static_cast<std::size_t>(i)] +
                                          " is not finite",
            at_parameter(out.names[static_cast<std::size_t>(i)]));
  }
  require(r.allFinite(), std::string(who) + "the residuals at theta are not finite", at_parameter("theta"));

  // Free parameters: estimated and off their bounds.
  out.free.assign(static_cast<std::size_t>(n), true);
  out.at_bound.assign(static_cast<std::size_t>(n), false);
  std::vector<int> idx;
  for (int i = 0; i < n; ++i) {
    const auto iu = static_cast<std::size_t>(i);
    if (!options.fixed.empty() && options.fixed[iu]) out.free[iu] = false;
    const double tol = 1e-12 * std::max(1.0, std::abs(theta[i]));
    const bool lo = options.lower_bounds.size() == n && theta[i] <= options.lower_bounds[i] + tol;
    const bool hi = options.upper_bounds.size() == n && theta[i] >= options.upper_bounds[i] - tol;
    if (out.free[iu] && (lo || hi)) {
      out.free[iu] = false;
      out.at_bound[iu] = true;
    }
    if (out.free[iu]) idx.push_back(i);
  }
  const auto k = static_cast<Eigen::Index>(idx.size());

  // Rows that carry data (a missing measurement gives a zero residual and a zero Jacobian row).
  Eigen::MatrixXd J(m, k);
  for (Eigen::Index c = 0; c < k; ++c) J.col(c) = Jfull.col(idx[static_cast<std::size_t>(c)]);
  for (Eigen::Index row = 0; row < m; ++row) {
    if (r[row] != 0.0 || (k > 0 && J.row(row).cwiseAbs().maxCoeff() > 0.0)) ++out.observations;
  }
  out.degrees_of_freedom = out.observations - k;
  out.covariance = Eigen::MatrixXd::Zero(n, n);
  out.stddev = Eigen::VectorXd::Zero(n);
  out.stddev_white = Eigen::VectorXd::Zero(n);
  out.correlation = Eigen::MatrixXd::Constant(n, n, std::numeric_limits<double>::quiet_NaN());
  if (k == 0) {  // nothing estimated: nothing uncertain, whatever the data
    out.noise_variance = out.degrees_of_freedom > 0 ? r.squaredNorm() / static_cast<double>(out.degrees_of_freedom) : 0.0;
    return out;
  }
  require(out.degrees_of_freedom > 0, std::string(who) + std::to_string(out.observations) +
                                          " data rows for " + std::to_string(k) +
                                          " free parameters: no degrees of freedom left for the noise level");
  out.noise_variance = r.squaredNorm() / static_cast<double>(out.degrees_of_freedom);

  // Pooled lag-1 autocorrelation of the residuals over the series.
  {
    double sxy = 0.0, sxx = 0.0;
    for (const ResidualSeries& s : series) {
      for (Eigen::Index t = 0; t < s.length; ++t) {
        const double e = r[detail::series_row(s, t)];
        sxx += e * e;
        if (t > 0) sxy += e * r[detail::series_row(s, t - 1)];
      }
    }
    out.lag1_correlation = sxx > 0.0 ? sxy / sxx : 0.0;
  }


  // Column-normalised Jacobian Ĵ = J D⁻¹; a column without effect is its own null direction.
  Eigen::VectorXd d = J.colwise().norm().transpose();
  Eigen::VectorXd dinv(k);
  for (Eigen::Index c = 0; c < k; ++c) dinv[c] = d[c] > 0.0 ? 1.0 / d[c] : 0.0;
  const Eigen::MatrixXd Jn = J * dinv.asDiagonal();
  const Eigen::MatrixXd H = Jn.transpose() * Jn;
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(H);
  const double lmax = std::max(eig.eigenvalues().maxCoeff(), 0.0);
  Eigen::MatrixXd Hpinv = Eigen::MatrixXd::Zero(k, k);
  // Share of each parameter's unit vector in the undetermined subspace.
  Eigen::VectorXd null_share = Eigen::VectorXd::Zero(k);
  for (Eigen::Index j = 0; j < k; ++j) {
    const double lam = eig.eigenvalues()[j];
    const Eigen::VectorXd v = eig.eigenvectors().col(j);
    if (lmax > 0.0 && lam > options.rank_tolerance * lmax) {
      Hpinv.noalias() += v * v.transpose() / lam;
      ++out.rank;
      continue;
    }
    // δθ = D⁻¹ v changes no residual to first order; scale so the largest |Δθᵢ/θᵢ| is 1 %.
    Eigen::VectorXd delta = Eigen::VectorXd::Zero(n);
    double big = 0.0;
    for (Eigen::Index c = 0; c < k; ++c) {
      const int i = idx[static_cast<std::size_t>(c)];
      const double vi = d[c] > 0.0 ? v[c] / d[c] : v[c];
      delta[i] = vi;
      null_share[c] += v[c] * v[c];
      big = std::max(big, theta[i] != 0.0 ? std::abs(vi / theta[i]) : std::abs(vi));
    }
    if (big > 0.0) delta *= 0.01 / big;
    // Round the tiny shares off so the report names only the parameters involved.
    for (Eigen::Index c = 0; c < k; ++c) {
      if (std::abs(v[c]) <= 1e-3) delta[idx[static_cast<std::size_t>(c)]] = 0.0;
    }
    out.unidentifiable.push_back(delta);
  }
  // A parameter is not identifiable if more than 1 % of its squared unit vector lies in the
  // undetermined subspace (a 10 % component): moving along those directions moves it freely.
  // Below that, the pseudo-inverse's value is its deviation with the undetermined combinations
  // pinned — the case of parameters that only graze a nearly degenerate direction, e.g. the
  // linear block of a Hammerstein–Wiener model whose estimated initial states include a mode
  // that decays within a sample.
  std::vector<bool> undetermined(static_cast<std::size_t>(k), false);
  for (Eigen::Index c = 0; c < k; ++c) undetermined[static_cast<std::size_t>(c)] = d[c] == 0.0 || null_share[c] > 0.01;

  // White: σ² D⁻¹ H⁺ D⁻¹.
  const Eigen::MatrixXd Pw = out.noise_variance * dinv.asDiagonal() * Hpinv * dinv.asDiagonal();
  Eigen::MatrixXd P = Pw;
  if (options.residuals == ResidualModel::correlated) {
    // Scores ĝ(t) = Ĵ(t)ᵀ e(t); S = Σ_t ĝĝᵀ + Σ_{τ=1..M} w_τ Σ_t (ĝ(t)ĝ(t−τ)ᵀ + ĝ(t−τ)ĝ(t)ᵀ).
    // Leverage (MacKinnon & White 1985, "HC2"): a residual that parameters can fit on their own
    // — the first samples of a record whose initial state is estimated — comes out shrunk by
    // √(1 − h_t), h_t = ψ̂(t)ᵀH⁺ψ̂(t), and would make those parameters look exact; divide it back.
    const Eigen::VectorXd h = ((Jn * Hpinv).cwiseProduct(Jn)).rowwise().sum();
    Eigen::VectorXd rs(m);
    for (Eigen::Index t = 0; t < m; ++t) rs[t] = r[t] / std::sqrt(std::max(1.0 - h[t], 1e-6));
    Eigen::MatrixXd G = rs.asDiagonal() * Jn;
    // Prewhitening (Andrews & Monahan 1992): a VAR(1) fit ĝ(t) ≈ A ĝ(t−1) takes the slow part
    // out of the scores, the window estimates what is left, and (I − A)⁻¹ puts the slow part back.
    // A window alone underestimates S badly when the scores are strongly correlated.
    Eigen::MatrixXd recolor = Eigen::MatrixXd::Identity(k, k);
    if (options.prewhiten) {
      Eigen::MatrixXd Sxx = Eigen::MatrixXd::Zero(k, k), Sxy = Eigen::MatrixXd::Zero(k, k);
      for (const ResidualSeries& s : series) {
        for (Eigen::Index t = 1; t < s.length; ++t) {
          const auto prev = G.row(detail::series_row(s, t - 1));
          Sxx.noalias() += prev.transpose() * prev;
          Sxy.noalias() += prev.transpose() * G.row(detail::series_row(s, t));
        }
      }
      // A = (Sxx⁻¹ Sxy)ᵀ, its singular values held below 0.97 so that I − A stays invertible.
      Eigen::MatrixXd A = Sxx.completeOrthogonalDecomposition().solve(Sxy).transpose();
      Eigen::JacobiSVD<Eigen::MatrixXd> svd(A, Eigen::ComputeFullU | Eigen::ComputeFullV);
      Eigen::VectorXd sv = svd.singularValues().cwiseMin(0.97);
      A = svd.matrixU() * sv.asDiagonal() * svd.matrixV().transpose();
      // The first score of each series stays as it is (Andrews & Monahan drop it): for short
      // series a slight overestimate of S, never an underestimate.
      Eigen::MatrixXd V = G;
      for (const ResidualSeries& s : series) {
        for (Eigen::Index t = s.length - 1; t >= 1; --t) {
          V.row(detail::series_row(s, t)) -= G.row(detail::series_row(s, t - 1)) * A.transpose();
        }
      }
      G = std::move(V);
      recolor = (Eigen::MatrixXd::Identity(k, k) - A).inverse();
    }
    // A given lag beyond the longest series has no lag products to add; the report states the
    // lag actually used.
    out.max_lag = options.max_lag >= 0 ? static_cast<int>(std::min<Eigen::Index>(options.max_lag, longest - 1))
                                       : detail::andrews_lag(G, series, typical_length, longest);
    Eigen::MatrixXd S = G.transpose() * G;
    for (const ResidualSeries& s : series) {
      Eigen::MatrixXd Gs(s.length, k);
      for (Eigen::Index t = 0; t < s.length; ++t) Gs.row(t) = G.row(detail::series_row(s, t));
      for (int tau = 1; tau <= out.max_lag && tau < s.length; ++tau) {
        const double w = 1.0 - static_cast<double>(tau) / (out.max_lag + 1.0);
        const Eigen::MatrixXd A = Gs.bottomRows(s.length - tau).transpose() * Gs.topRows(s.length - tau);
        S.noalias() += w * (A + A.transpose());
      }
    }
    // No N/(N − k) on top: the leverage division is already the degrees-of-freedom correction
    // (E[e_t²/(1 − h_t)] = σ² for white residuals; Σh_t = k), and both would inflate S by N/(N − k).
    S = recolor * S * recolor.transpose();
    P = dinv.asDiagonal() * (Hpinv * S * Hpinv) * dinv.asDiagonal();
  }

  for (Eigen::Index a = 0; a < k; ++a) {
    const int i = idx[static_cast<std::size_t>(a)];
    // The mean of P and Pᵀ, variances not below 0: the products above leave rounding asymmetries
    // (about 1e-9 relative) that a reader checking a stored covariance must not have to forgive.
    for (Eigen::Index b = 0; b < k; ++b) out.covariance(i, idx[static_cast<std::size_t>(b)]) = 0.5 * (P(a, b) + P(b, a));
    out.covariance(i, i) = std::max(out.covariance(i, i), 0.0);
    const bool none = undetermined[static_cast<std::size_t>(a)];
    out.stddev[i] = none ? std::numeric_limits<double>::infinity() : std::sqrt(std::max(P(a, a), 0.0));
    out.stddev_white[i] = none ? std::numeric_limits<double>::infinity() : std::sqrt(std::max(Pw(a, a), 0.0));
  }
  for (Eigen::Index a = 0; a < k; ++a) {
    const int i = idx[static_cast<std::size_t>(a)];
    for (Eigen::Index b = 0; b < k; ++b) {
      const int j = idx[static_cast<std::size_t>(b)];
      const double si = out.stddev[i], sj = out.stddev[j];
      if (si > 0.0 && sj > 0.0 && std::isfinite(si) && std::isfinite(sj)) {
        out.correlation(i, j) = out.covariance(i, j) / (si * sj);
      }
    }
  }
  return out;
}

/// The uncertainty a stored covariance describes: what a model file keeps of an estimate
/// (`"uncertainty": {"covariance", "stddev"}`; a grey box's `parameters.covariance`) turned back into the form `simulation_band`
/// takes. `stddev` (size 0 or n) keeps the deviations as estimated, +∞ for a parameter the data
/// left undetermined (its covariance row holds the pseudo-inverse's finite values), NaN for one
/// estimated onto a bound (`at_bound`, σ 0 in the result); empty: the diagonal's square roots.
/// A parameter with zero variance or flagged in `fixed` (size 0 or n) is
/// not free. What the residuals and the data were is not stored: `observations` is 0, the
/// white-formula deviations are NaN, and `unidentifiable` is empty (an undetermined parameter is
/// named in `caveat` instead). Throws `nlid::Error` naming the parameter for sizes that do not
/// match, a non-finite, asymmetric or negative-variance covariance, or a negative deviation.
[[nodiscard]] inline ParameterUncertainty uncertainty_from_covariance(std::vector<std::string> names, Eigen::VectorXd theta,
                                                                      Eigen::MatrixXd covariance, Eigen::VectorXd stddev = {},
                                                                      const std::vector<bool>& fixed = {}) {
  const Eigen::Index n = theta.size();
  require(n > 0, "stored uncertainty: no parameters", at_parameter("theta"));
  require(names.empty() || names.size() == static_cast<std::size_t>(n),
          "stored uncertainty: " + std::to_string(names.size()) + " names for " + std::to_string(n) + " parameters",
          at_parameter("names"));
  if (names.empty())
    for (Eigen::Index i = 0; i < n; ++i) names.push_back("theta[" + std::to_string(i) + "]");
  require(covariance.rows() == n && covariance.cols() == n,
          "stored uncertainty: a " + std::to_string(covariance.rows()) + "x" + std::to_string(covariance.cols()) +
              " covariance for " + std::to_string(n) + " parameters",
          at_parameter("covariance"));
  require(stddev.size() == 0 || stddev.size() == n,
          "stored uncertainty: " + std::to_string(stddev.size()) + " standard deviations for " + std::to_string(n) +
              " parameters",
          at_parameter("stddev"));
  require(fixed.empty() || fixed.size() == static_cast<std::size_t>(n),
          "stored uncertainty: " + std::to_string(fixed.size()) + " fixed flags for " + std::to_string(n) + " parameters",
          at_parameter("fixed"));
  for (Eigen::Index i = 0; i < n; ++i) {
    const std::string& q = names[static_cast<std::size_t>(i)];
    require(std::isfinite(theta[i]), "stored uncertainty: the value of " + q + " is not finite", at_parameter(q));
  }
  detail::check_covariance("stored uncertainty: ", names, covariance);
  for (Eigen::Index i = 0; i < stddev.size(); ++i) {
    const std::string& q = names[static_cast<std::size_t>(i)];
    require(stddev[i] >= 0.0 || std::isnan(stddev[i]),
            "stored uncertainty: the standard deviation of " + q + " must be >= 0 (or inf, or nan for on its bound), got " +
                detail::format_g(stddev[i]),
            at_parameter(q));
  }
  ParameterUncertainty u;
  u.stored = true;
  u.names = std::move(names);
  u.theta = std::move(theta);
  u.covariance = std::move(covariance);
  u.stddev = stddev.size() > 0 ? std::move(stddev) : Eigen::VectorXd(u.covariance.diagonal().cwiseSqrt());
  u.stddev_white = Eigen::VectorXd::Constant(n, std::numeric_limits<double>::quiet_NaN());
  u.correlation = Eigen::MatrixXd::Constant(n, n, std::numeric_limits<double>::quiet_NaN());
  u.free.resize(static_cast<std::size_t>(n));
  u.at_bound.assign(static_cast<std::size_t>(n), false);
  // NaN is how a grey box keeps "on its bound" (GreyBox::parameter_stddev); back in the form
  // `parameter_uncertainty` gives it: σ 0, flagged, so the report says so and no band uses it.
  for (Eigen::Index i = 0; i < n; ++i) {
    if (std::isnan(u.stddev[i])) {
      u.stddev[i] = 0.0;
      u.at_bound[static_cast<std::size_t>(i)] = true;
    }
  }
  std::string undetermined;
  for (Eigen::Index i = 0; i < n; ++i) {
    const auto iu = static_cast<std::size_t>(i);
    // A parameter fixed since the estimation keeps its variance in Σ but is not moved.
    u.free[iu] = u.covariance(i, i) > 0.0 && !(iu < fixed.size() && fixed[iu]) && !u.at_bound[iu];
    if (u.free[iu] && std::isfinite(u.stddev[i])) ++u.rank;
    if (std::isinf(u.stddev[i])) undetermined += (undetermined.empty() ? "" : ", ") + u.names[iu];
    for (Eigen::Index j = 0; j < n; ++j) {
      const double si = u.stddev[i], sj = u.stddev[j];
      if (si > 0.0 && sj > 0.0 && std::isfinite(si) && std::isfinite(sj)) u.correlation(i, j) = u.covariance(i, j) / (si * sj);
    }
  }
  if (!undetermined.empty()) {
    u.caveat = "not determined by the estimation data (the covariance holds their pseudo-inverse variance, not the "
               "combinations the data left open): " + undetermined;
  }
  return u;
}

}  // namespace nlid
