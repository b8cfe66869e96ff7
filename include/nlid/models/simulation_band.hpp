#pragma once
/// @file
/// `simulation_band(model, data, uncertainty)`: the standard deviation of a model's simulated
/// output that the uncertainty of its parameters implies — the toolbox's `[y, y_sd] = sim(...)` —
/// and the question a control engineer asks of a validation plot next: is the error between
/// simulation and record what the parameters' uncertainty allows, or is it something else?
///
/// To first order, ŷ(θ̂ + δ) = ŷ(θ̂) + J δ with J = ∂ŷ/∂θ of the free run, so
/// Var ŷ(t) = J(t) Σ J(t)ᵀ with Σ the parameters' covariance (`parameter_uncertainty`: by default
/// allowing for correlated residuals). J comes from one forward-AD pass of the simulation on the
/// given input (the data's outputs are not needed for it; they are used only for the error
/// statistics). Σ holds the strong correlations of simulation-error estimates (the throttle's
/// c, k, b: 0.98–0.998): the diagonal alone would overstate the band many times, which is why
/// the whole `ParameterUncertainty` is passed and not the standard deviations a model file keeps.
///
/// What the band is not: it is the spread of the *model's* output over parameter values the
/// estimation data allow, with the initial state held as chosen; it contains neither the
/// measurement noise nor anything the model's structure leaves out. So on validation data an
/// error many times the band says the parameters are not the problem — the noise or the
/// structure is — and `nlid::diagnose` (grey boxes) tells which physics is missing. Directions of
/// θ the estimation data could not determine (`ParameterUncertainty::unidentifiable`) carry no
/// variance in Σ (its pseudo-inverse); the band therefore reports how much a 1 % move along each
/// changes the output on these data, which a new input can make large.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <Eigen/SVD>

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/core/initial_condition.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/estimation/autodiff.hpp"
#include "nlid/estimation/uncertainty.hpp"
#include "nlid/models/detail/estimation_segment.hpp"
#include "nlid/models/detail/initial_state.hpp"
#include "nlid/models/detail/simulation_residuals.hpp"
#include "nlid/models/greybox.hpp"
#include "nlid/models/greybox_problem.hpp"
#include "nlid/models/hammerstein_wiener.hpp"
#include "nlid/models/nlarx.hpp"

namespace nlid {

/// Settings of `simulation_band`.
struct SimulationBandOptions {
  /// How each experiment's simulation starts (held, not varied with θ). Unset: grey boxes
  /// `estimate`, Nlarx `measured`, Hammerstein–Wiener `zero` — what `compare` would be asked for.
  std::optional<InitialCondition> initial_condition;
  /// Half-width of the band, in standard deviations, for `within_band` (the share of measured
  /// samples inside ŷ ± k σ).
  double band_sigmas = 2.0;
};

/// Simulated output with its standard deviation from the parameters' covariance, per experiment,
/// with the measured error set against it (file comment).
struct SimulationBand {
  std::vector<std::string> experiment_names;
  std::vector<std::string> output_names;
  std::vector<Eigen::MatrixXd> y;       ///< simulated output, N_e × n_y per experiment
  std::vector<Eigen::MatrixXd> stddev;  ///< 1σ of `y` (0 where measured past outputs are used)
  /// Per experiment × output: rms and largest σ over the simulated samples.
  Eigen::MatrixXd rms_stddev, max_stddev;
  /// Per experiment × output, over samples with a finite measured output: rms of ŷ − y, and the
  /// share (0…1) of those samples with |ŷ − y| ≤ band_sigmas · σ. NaN where nothing was measured.
  Eigen::MatrixXd rms_error, within_band;
  /// Per experiment × output, to first order in the free parameters (δ = ∂θ, measured in the
  /// covariance's metric √(δᵀΣ⁻¹δ), "sigmas"; directions without variance are not moved, as in
  /// the band): `reachable_share`, the share (0…1) of the error's square sum that the best change
  /// of any size removes on this record — what the parameters can do at all; the rest is the
  /// model's structure or noise; `shift_sigmas`, the size of the smallest change that removes
  /// 90 % of that reachable part; `plausible_share`, the share removed by the best change within
  /// `plausible_radius()` sigmas (at least 90 % of the reachable part exactly when the shift is
  /// within the radius). NaN where fewer samples than parameters were measured, and the shares
  /// where the error is zero (nothing to explain; the shift is 0).
  Eigen::MatrixXd reachable_share, shift_sigmas, plausible_share;
  /// The best change within the radius per experiment: n_p × n_y (column j for output j; 0 for
  /// fixed parameters and where the shares are NaN), in the parameters' units.
  std::vector<Eigen::MatrixXd> parameter_change;
  std::vector<std::string> parameter_names;  ///< the model's
  Eigen::VectorXd parameter_stddev;          ///< √diag Σ of the model's parameters
  /// Per unidentifiable direction of the uncertainty (same order): the largest |Δŷ| on these
  /// data for the 1 % move that direction is scaled to. Not contained in `stddev`.
  std::vector<double> unidentifiable_change;
  double band_sigmas = 2.0;
  int free_parameters = 0;  ///< k: the free parameters the changes are taken over
  std::string caveat;  ///< carried over from the uncertainty

  /// rms error / rms σ of experiment e, output j (NaN without measurements, ∞ for a zero band).
  [[nodiscard]] double error_ratio(Eigen::Index e, Eigen::Index j) const {
    const double s = rms_stddev(e, j), r = rms_error(e, j);
    if (!std::isfinite(r)) return std::numeric_limits<double>::quiet_NaN();
    return s > 0.0 ? r / s : std::numeric_limits<double>::infinity();
  }

  /// Table of the band against the error per experiment and output, one verdict per row, and
  /// the unidentifiable directions' effect.
  [[nodiscard]] std::string report() const {
    auto num = [](double v) { return std::isnan(v) ? std::string("-") : detail::format_g(v, 4); };
    auto pct = [&](double v) { return std::isnan(v) ? std::string("-") : num(100.0 * v) + " %"; };
    char line[320];
    std::string s = "Simulation band (1 sigma of the simulated output from the parameters' covariance)\n";
    std::snprintf(line, sizeof line, "%-12s %-7s %10s %10s %10s %8s %9s %10s %9s %10s\n", "experiment", "output",
                  "rms sigma", "max sigma", "rms error", "err/sig", "in band", "reachable", "shift", "near");
    s += line;
    std::string verdicts;
    for (Eigen::Index e = 0; e < rms_stddev.rows(); ++e) {
      for (Eigen::Index j = 0; j < rms_stddev.cols(); ++j) {
        std::snprintf(line, sizeof line, "%-12s %-7s %10s %10s %10s %8s %9s %10s %9s %10s\n",
                      experiment_names[static_cast<std::size_t>(e)].c_str(),
                      output_names[static_cast<std::size_t>(j)].c_str(), num(rms_stddev(e, j)).c_str(),
                      num(max_stddev(e, j)).c_str(), num(rms_error(e, j)).c_str(), num(error_ratio(e, j)).c_str(),
                      pct(within_band(e, j)).c_str(), pct(reachable_share(e, j)).c_str(),
                      num(shift_sigmas(e, j)).c_str(),
                      pct(plausible_share(e, j)).c_str());
        s += line;
        verdicts += verdict(e, j);
      }
    }
    s += "(in band: measured samples within +-" + num(band_sigmas) +
         " sigma; reachable: share of the error's square sum the best parameter change removes, first order; "
         "shift: the smallest change removing 90 % of that, in sigmas; near: the share a change of at most " +
         num(plausible_radius()) + " sigma removes)\n";
    s += verdicts;
    // The three combinations that matter most on these data, then the largest of the rest.
    std::vector<std::size_t> order(unidentifiable_change.size());
    for (std::size_t d = 0; d < order.size(); ++d) order[d] = d;
    std::stable_sort(order.begin(), order.end(),
                     [&](std::size_t a, std::size_t b) { return unidentifiable_change[a] > unidentifiable_change[b]; });
    for (std::size_t q = 0; q < std::min<std::size_t>(3, order.size()); ++q) {
      s += "  unidentifiable combination " + std::to_string(order[q] + 1) +
           " (1 % move): changes the output by up to " + num(unidentifiable_change[order[q]]) +
           " on these data; not in the band\n";
    }
    if (order.size() > 3) {
      s += "  ... and " + std::to_string(order.size() - 3) + " more unidentifiable combinations, each changing it by at most " +
           num(unidentifiable_change[order[3]]) + "\n";
    }
    if (!caveat.empty()) s += "  note: " + caveat + "\n";
    return s;
  }

  /// One line on experiment e, output j: whether the parameters' uncertainty accounts for the
  /// error (empty without measurements or without an error).
  [[nodiscard]] std::string verdict(Eigen::Index e, Eigen::Index j) const {
    const double reach = reachable_share(e, j), near = plausible_share(e, j);
    if (std::isnan(rms_error(e, j)) || std::isnan(reach)) return {};
    auto num = [](double v) { return detail::format_g(v, 3); };
    const std::string who = "  " + experiment_names[static_cast<std::size_t>(e)] +
                            (rms_stddev.cols() > 1 ? " " + output_names[static_cast<std::size_t>(j)] : "") + ": ";
    const std::string radius = num(plausible_radius()) + " sigma";
    if (reach < 0.5) {
      if (free_parameters == 0) return who + "no free parameters: the whole error is the model's (structure, or noise)\n";
      return who + "no change of the parameters removes more than " + num(100.0 * reach) +
             " % of the error: it lies outside what they can reach (the model's structure, or noise)\n";
    }
    std::string s = who;
    if (near >= 0.9 * reach) {
      s += "a change within " + radius + " removes " + num(100.0 * near) +
           " % of the error: that much is consistent with the parameters' uncertainty";
    } else {
      s += "the parameters could remove " + num(100.0 * reach) + " % of the error, but within " + radius +
           " of the estimate only " + num(100.0 * near) + " %: this record behaves as if they differed (pulled most: " +
           largest_changes(e, j) + ")";
    }
    if (reach < 0.9) s += "; the other " + num(100.0 * (1.0 - reach)) + " % is out of their reach (structure, or noise)";
    return s + "\n";
  }

  /// The (at most three) parameters the change of experiment e, output j moves most, relative to
  /// their standard deviations: "name +Δ (n sigma), …".
  [[nodiscard]] std::string largest_changes(Eigen::Index e, Eigen::Index j) const {
    const Eigen::VectorXd d = parameter_change[static_cast<std::size_t>(e)].col(j);
    std::vector<std::pair<double, Eigen::Index>> order;
    for (Eigen::Index i = 0; i < d.size(); ++i) {
      if (d[i] != 0.0 && parameter_stddev[i] > 0.0) order.emplace_back(std::abs(d[i]) / parameter_stddev[i], i);
    }
    std::sort(order.begin(), order.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
    std::string s;
    for (std::size_t q = 0; q < std::min<std::size_t>(3, order.size()); ++q) {
      const Eigen::Index i = order[q].second;
      s += (q > 0 ? ", " : "") + parameter_names[static_cast<std::size_t>(i)] + " " +
           detail::with_plus(detail::format_g(d[i], 3)) + " (" + detail::format_g(order[q].first, 3) + " sigma)";
    }
    return s;
  }

  /// Size (sigmas) of a parameter change still called plausible: 3 + √k, k free parameters (a
  /// draw from the k-dimensional Gaussian of the covariance has size about √k).
  [[nodiscard]] double plausible_radius() const { return 3.0 + std::sqrt(static_cast<double>(free_parameters)); }
};

namespace detail {

// The model's np parameters must be those the uncertainty was computed at.
inline void check_band_parameters(const ParameterUncertainty& u, const Eigen::VectorXd& p,
                                  const std::vector<std::string>& names) {
  const Eigen::Index np = p.size();
  require(u.theta.size() >= np && u.covariance.rows() == u.theta.size() && u.covariance.cols() == u.theta.size(),
          "simulation_band: the uncertainty covers " + std::to_string(u.theta.size()) + " unknowns with a " +
              std::to_string(u.covariance.rows()) + "x" + std::to_string(u.covariance.cols()) +
              " covariance; the model has " + std::to_string(np) +
              " parameters (compute it with parameter_uncertainty on this model)",
          at_parameter("uncertainty"));
  for (Eigen::Index i = 0; i < np; ++i) {
    const std::string name = static_cast<std::size_t>(i) < names.size() ? names[static_cast<std::size_t>(i)]
                                                                        : "theta[" + std::to_string(i) + "]";
    if (static_cast<std::size_t>(i) < u.names.size()) {
      require(u.names[static_cast<std::size_t>(i)] == name,
              "simulation_band: parameter " + std::to_string(i) + " is '" + name + "' in the model but '" +
                  u.names[static_cast<std::size_t>(i)] + "' in the uncertainty (another model's?)",
              at_parameter(name));
    }
    const double a = p[i], b = u.theta[i];
    require(std::abs(a - b) <= 1e-9 * std::max({1.0, std::abs(a), std::abs(b)}),
            "simulation_band: parameter '" + name + "' is " + detail::format_f(a, 6) +
                " in the model but the uncertainty was computed at " + detail::format_f(b, 6) +
                " (recompute parameter_uncertainty after changing the model)",
            at_parameter(name));
  }
}

struct ErrorReach {
  double reachable = 0.0, plausible = 0.0, shift = 0.0;
  Eigen::VectorXd delta;  // the change within the radius, in the parameters' units
};

// In whitened coordinates δ = L z (Σ_f = L Lᵀ over the directions the covariance gives variance;
// the others are not moved, as the band does not move them): the share of ‖err‖² that the best z
// removes (reachable), the size ‖z‖ of the smallest z removing 90 % of that (shift, in sigmas), and the share
// removed by the best z with ‖z‖ ≤ radius (plausible; a trust-region solve by bisection on the
// Levenberg parameter).
inline ErrorReach error_reach(const Eigen::MatrixXd& A, const Eigen::VectorXd& err, const Eigen::MatrixXd& sf,
                              double radius) {
  ErrorReach out;
  out.delta = Eigen::VectorXd::Zero(A.cols());
  const double total = err.squaredNorm();
  if (total == 0.0) {
    // No error: a share of it is 0/0, and "out of reach" (share 0) would be a false verdict.
    out.reachable = out.plausible = std::numeric_limits<double>::quiet_NaN();
    return out;
  }
  if (A.cols() == 0) return out;
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(sf);
  const double top = es.eigenvalues().cwiseAbs().maxCoeff();
  std::vector<Eigen::Index> keep;
  for (Eigen::Index q = 0; q < sf.rows(); ++q) {
    if (es.eigenvalues()[q] > 1e-12 * top) keep.push_back(q);
  }
  if (keep.empty()) return out;
  Eigen::MatrixXd L(sf.rows(), static_cast<Eigen::Index>(keep.size()));
  for (std::size_t q = 0; q < keep.size(); ++q) {
    L.col(static_cast<Eigen::Index>(q)) = es.eigenvectors().col(keep[q]) * std::sqrt(es.eigenvalues()[keep[q]]);
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(A * L, Eigen::ComputeThinU | Eigen::ComputeThinV);
  const Eigen::VectorXd& sv = svd.singularValues();
  const Eigen::VectorXd c = svd.matrixU().transpose() * err;
  Eigen::Index m = 0;
  while (m < sv.size() && sv[m] > 1e-10 * sv[0]) ++m;
  if (m == 0) return out;
  const Eigen::VectorXd sm = sv.head(m), cm = c.head(m);
  out.reachable = std::clamp(cm.squaredNorm() / total, 0.0, 1.0);
  // z(μ) = V diag(sᵢ/(sᵢ² + μ)) Uᵀe; ‖z(μ)‖ and the share it removes, Σcᵢ² − Σ(cᵢμ/(sᵢ² + μ))²,
  // both fall with μ, and ‖z(μ)‖ ≤ s₀‖c‖/μ.
  auto coefficients = [&](double mu) {
    return Eigen::VectorXd(sm.cwiseProduct(cm).cwiseQuotient((sm.array().square() + mu).matrix()));
  };
  auto removed = [&](double mu) {
    return cm.squaredNorm() - (cm.array() * mu / (sm.array().square() + mu)).matrix().squaredNorm();
  };
  // Shift: the smallest change removing 90 % of what is reachable. (The least-norm change removing
  // all of it is dominated by directions the record barely senses, whose tiny singular values
  // make it arbitrarily large.)
  {
    double lo = 0.0, hi = 1e8 * sm[0] * sm[0];
    const double target = 0.9 * cm.squaredNorm();
    for (int it = 0; it < 200; ++it) {
      const double mid = 0.5 * (lo + hi);
      (removed(mid) >= target ? lo : hi) = mid;
    }
    out.shift = coefficients(lo).norm();
  }
  double mu = 0.0;
  if (cm.cwiseQuotient(sm).norm() > radius) {
    double lo = 0.0, hi = sm[0] * cm.norm() / radius;
    for (int it = 0; it < 200; ++it) {
      const double mid = 0.5 * (lo + hi);
      (coefficients(mid).norm() > radius ? lo : hi) = mid;
    }
    mu = hi;
  }
  const Eigen::VectorXd w = coefficients(mu);
  const double left = total - cm.squaredNorm() + (cm - sm.cwiseProduct(w)).squaredNorm();
  out.plausible = std::clamp(1.0 - left / total, 0.0, 1.0);
  out.delta = L * (svd.matrixV().leftCols(m) * w);
  return out;
}

// Fills band entries of experiment e from ŷ (N × ny), its parameter Jacobian rows (sample-major,
// rows [row0, row0 + N·ny), columns = the model's np parameters), the measured outputs and the
// first sample the simulation covers.
inline void fill_band_experiment(SimulationBand& b, std::size_t e, const Eigen::MatrixXd& yhat,
                                 const Eigen::Ref<const Eigen::MatrixXd>& Jp, const ParameterUncertainty& u,
                                 const Eigen::MatrixXd& ymeas, Eigen::Index first) {
  const Eigen::Index np = Jp.cols(), n = yhat.rows(), ny = yhat.cols();
  const Eigen::MatrixXd sigma = u.covariance.topLeftCorner(np, np);
  const Eigen::MatrixXd js = Jp * sigma;
  Eigen::MatrixXd sd = Eigen::MatrixXd::Zero(n, ny);
  for (Eigen::Index k = first; k < n; ++k) {
    for (Eigen::Index j = 0; j < ny; ++j) {
      const Eigen::Index row = (k - first) * ny + j;
      sd(k, j) = std::sqrt(std::max(0.0, js.row(row).dot(Jp.row(row))));
    }
  }
  const auto ee = static_cast<Eigen::Index>(e);
  // The free parameters a change may move, and their covariance block (the same for every output).
  std::vector<Eigen::Index> cols;
  for (Eigen::Index i = 0; i < np; ++i) {
    if (u.free[static_cast<std::size_t>(i)]) cols.push_back(i);
  }
  const auto nc = static_cast<Eigen::Index>(cols.size());
  Eigen::MatrixXd sf(nc, nc);
  for (Eigen::Index a = 0; a < nc; ++a) {
    for (Eigen::Index c = 0; c < nc; ++c) sf(a, c) = sigma(cols[static_cast<std::size_t>(a)], cols[static_cast<std::size_t>(c)]);
  }
  for (Eigen::Index j = 0; j < ny; ++j) {
    double s2 = 0.0, smax = 0.0, e2 = 0.0;
    Eigen::Index count = 0, measured = 0, inside = 0;
    for (Eigen::Index k = first; k < n; ++k) {
      s2 += sd(k, j) * sd(k, j);
      smax = std::max(smax, sd(k, j));
      ++count;
      const double ym = ymeas(k, j);
      if (!std::isfinite(ym)) continue;
      const double err = yhat(k, j) - ym;
      e2 += err * err;
      ++measured;
      if (std::abs(err) <= b.band_sigmas * sd(k, j)) ++inside;
    }
    const double nan = std::numeric_limits<double>::quiet_NaN();
    // What a change of the free parameters can do about this output's error on this record.
    if (measured > np) {
      std::vector<Eigen::Index> rows;
      for (Eigen::Index k = first; k < n; ++k) {
        if (std::isfinite(ymeas(k, j))) rows.push_back((k - first) * ny + j);
      }
      const auto nr = static_cast<Eigen::Index>(rows.size());
      Eigen::MatrixXd A(nr, nc);
      Eigen::VectorXd err(nr);
      for (Eigen::Index q = 0; q < nr; ++q) {
        const Eigen::Index row = rows[static_cast<std::size_t>(q)];
        err[q] = ymeas(first + row / ny, j) - yhat(first + row / ny, j);
        for (Eigen::Index c = 0; c < nc; ++c) A(q, c) = Jp(row, cols[static_cast<std::size_t>(c)]);
      }
      const ErrorReach r = error_reach(A, err, sf, b.plausible_radius());
      b.reachable_share(ee, j) = r.reachable;
      b.plausible_share(ee, j) = r.plausible;
      b.shift_sigmas(ee, j) = r.shift;
      for (Eigen::Index c = 0; c < nc; ++c) b.parameter_change[e](cols[static_cast<std::size_t>(c)], j) = r.delta[c];
    } else {
      b.reachable_share(ee, j) = b.plausible_share(ee, j) = b.shift_sigmas(ee, j) =
          std::numeric_limits<double>::quiet_NaN();
    }
    b.rms_stddev(ee, j) = count > 0 ? std::sqrt(s2 / static_cast<double>(count)) : 0.0;
    b.max_stddev(ee, j) = smax;
    b.rms_error(ee, j) = measured > 0 ? std::sqrt(e2 / static_cast<double>(measured)) : nan;
    b.within_band(ee, j) = measured > 0 ? static_cast<double>(inside) / static_cast<double>(measured) : nan;
  }
  for (std::size_t d = 0; d < u.unidentifiable.size(); ++d) {
    const Eigen::VectorXd dy = Jp * u.unidentifiable[d].head(np);
    const double m = dy.size() > 0 ? dy.cwiseAbs().maxCoeff() : 0.0;
    b.unidentifiable_change[d] = std::max(b.unidentifiable_change[d], m);
  }
  b.y[e] = yhat;
  b.stddev[e] = std::move(sd);
}

inline SimulationBand start_band(const Dataset& data, int ny, std::vector<std::string> outputs,
                                 const ParameterUncertainty& u, const SimulationBandOptions& o, int np,
                                 std::vector<std::string> names) {
  require(data.size() > 0, "simulation_band: the data set has no experiments", at_parameter("data"));
  require(std::isfinite(o.band_sigmas) && o.band_sigmas > 0.0,
          "simulation_band: band_sigmas must be positive, got " + detail::format_f(o.band_sigmas, 6),
          at_parameter("band_sigmas"));
  for (std::size_t i = 0; i < u.unidentifiable.size(); ++i) {
    require(u.unidentifiable[i].size() == u.theta.size(),
            "simulation_band: unidentifiable direction " + std::to_string(i) + " has " +
                std::to_string(u.unidentifiable[i].size()) + " entries, the uncertainty " +
                std::to_string(u.theta.size()),
            at_parameter("uncertainty"));
  }
  require(u.covariance.allFinite(), "simulation_band: the uncertainty's covariance is not finite",
          at_parameter("uncertainty"));
  SimulationBand b;
  b.band_sigmas = o.band_sigmas;
  b.caveat = u.caveat;
  require(u.free.size() == static_cast<std::size_t>(u.theta.size()),
          "simulation_band: the uncertainty has " + std::to_string(u.free.size()) + " free flags for " +
              std::to_string(u.theta.size()) + " unknowns",
          at_parameter("uncertainty"));
  b.parameter_names = std::move(names);
  b.parameter_stddev = u.covariance.topLeftCorner(np, np).diagonal().cwiseMax(0.0).cwiseSqrt();
  b.free_parameters = static_cast<int>(std::count(u.free.begin(), u.free.begin() + np, true));
  const auto ne = static_cast<Eigen::Index>(data.size());
  for (std::size_t e = 0; e < data.size(); ++e) {
    b.experiment_names.push_back(data[e].name().empty() ? "experiment " + std::to_string(e) : data[e].name());
  }
  // The model's output names, else the first record's, else y1, y2, …
  outputs.resize(static_cast<std::size_t>(ny));
  const std::vector<std::string>& recorded = data[0].output_names();
  for (int j = 0; j < ny; ++j) {
    auto& name = outputs[static_cast<std::size_t>(j)];
    if (name.empty() && static_cast<std::size_t>(j) < recorded.size()) name = recorded[static_cast<std::size_t>(j)];
    if (name.empty()) name = "y" + std::to_string(j + 1);
  }
  b.output_names = std::move(outputs);
  b.y.resize(data.size());
  b.parameter_change.assign(data.size(), Eigen::MatrixXd::Zero(np, ny));
  b.stddev.resize(data.size());
  b.rms_stddev = b.max_stddev = Eigen::MatrixXd::Zero(ne, ny);
  b.rms_error = b.within_band = Eigen::MatrixXd::Zero(ne, ny);
  b.reachable_share = b.plausible_share = b.shift_sigmas = Eigen::MatrixXd::Zero(ne, ny);
  b.unidentifiable_change.assign(u.unidentifiable.size(), 0.0);
  return b;
}

// Nlarx and Hammerstein–Wiener models: one forward-AD pass of the free run per experiment from
// the held x0, on zero "measurements" so the residuals are ŷ itself.
template <class M>
SimulationBand regression_band(const M& model, const Dataset& data, const ParameterUncertainty& u,
                               InitialCondition ic, const SimulationBandOptions& o, int history, const char* kind) {
  const int np = model.num_parameters();
  check_band_parameters(u, model.parameters(), model.parameter_names());
  SimulationBand b = start_band(data, 1, {}, u, o, np, model.parameter_names());
  for (std::size_t e = 0; e < data.size(); ++e) {
    const Experiment& ex = data[e];
    check_experiment(ex, static_cast<long>(e), model.num_inputs(), history, model.ts(), kind);
    const Eigen::VectorXd x0 = model.initial_state(ex, ic, static_cast<long>(e));
    const Eigen::Index first = ic == InitialCondition::measured ? history : 0;
    // A missing sample the run reads would end it as a "divergence" without saying where: name
    // it (inputs of the simulated samples, and inputs or outputs of a measured initial past).
    auto missing = [&](bool output, Eigen::Index k, Eigen::Index c, const std::string& why) {
      const auto [name, where] = sample_location(ex, static_cast<long>(e), output, c, k);
      throw Error("simulation_band: " + b.experiment_names[e] + ": " + (output ? "output" : "input") + " '" + name +
                      "' is not finite at sample " + std::to_string(k) + "; " + why,
                  where);
    };
    for (Eigen::Index k = first; k < ex.size(); ++k) {
      for (Eigen::Index c = 0; c < ex.u().cols(); ++c) {
        if (!std::isfinite(ex.u()(k, c))) {
          missing(false, k, c, "a simulation cannot run through missing inputs (interpolate or cut the record)");
        }
      }
    }
    if (!x0.allFinite() && ic == InitialCondition::measured) {
      for (Eigen::Index k = 0; k < first; ++k) {
        const std::string why = "the simulation starts from the measured first " + std::to_string(first) +
                                " samples (InitialCondition::measured; use estimate, or cut the record)";
        if (!std::isfinite(ex.y()(k, 0))) missing(true, k, 0, why);
        for (Eigen::Index c = 0; c < ex.u().cols(); ++c) {
          if (!std::isfinite(ex.u()(k, c))) missing(false, k, c, why);
        }
      }
    }
    std::vector<EstimationSegment> segs(1);
    segs[0].u = &ex.u();
    segs[0].y = Eigen::VectorXd::Zero(ex.size());
    segs[0].start = first;
    segs[0].x0 = x0;
    Eigen::VectorXd finite = ex.y().col(0);
    for (Eigen::Index k = 0; k < finite.size(); ++k) {
      if (!std::isfinite(finite[k])) finite[k] = 0.0;
    }
    // x0 is given in full (zero policy with a stored x0 means "use it as it is").
    const AutoDiffProblem<SimulationResiduals<M, Dynamic>> problem(SimulationResiduals<M, Dynamic>(
        model, std::move(segs), {}, InitialCondition::zero, divergence_limit(finite)));
    Eigen::VectorXd r(problem.num_residuals());
    Eigen::MatrixXd J(problem.num_residuals(), np);
    if (!problem.evaluate(model.parameters(), r, &J)) {
      throw DivergenceError("simulation_band: the simulation of " + b.experiment_names[e] + " diverges",
                            -1, at_experiment(static_cast<long>(e)));
    }
    Eigen::MatrixXd yhat(ex.size(), 1);
    yhat.topRows(first) = ex.y().topRows(first);
    yhat.bottomRows(ex.size() - first) = r;
    fill_band_experiment(b, e, yhat, J, u, ex.y(), first);
  }
  return b;
}

}  // namespace detail

/// Band of a grey-box model's simulation on `data` from the parameters' uncertainty `u` (from
/// `estimate(...).uncertainty` or `parameter_uncertainty(model, estimation_data)`, computed at the
/// model's current values). Initial states are held at those of `options.initial_condition`
/// (default: estimated on each record with the parameters fixed). Throws `nlid::Error` if `u`
/// belongs to other parameter values or another model, for data that do not fit the physics, or
/// if a simulation diverges.
template <Physics P>
SimulationBand simulation_band(const GreyBox<P>& model, const Dataset& data, const ParameterUncertainty& u,
                               const SimulationBandOptions& options = {}) {
  const int np = model.num_parameters(), nx = model.state_dimension(), ny = model.output_dimension();
  std::vector<std::string> names;
  for (const auto& q : model.parameter_info()) names.push_back(q.name);
  detail::check_band_parameters(u, model.parameters(), names);
  SimulationBand b = detail::start_band(data, ny, model.output_names(), u, options, np, names);
  model.check_channels(data);
  const InitialCondition ic = options.initial_condition.value_or(InitialCondition::estimate);
  // The same records with zero outputs: the problem's residuals are then ŷ itself (weights 1),
  // and its Jacobian ∂ŷ/∂θ covers every sample, measured or not. Initial states enter as fixed
  // unknowns of an `estimate` problem.
  Dataset zero;
  for (std::size_t e = 0; e < data.size(); ++e) {
    Experiment z = data[e];
    z.y().setZero();
    zero.add(std::move(z));
  }
  // Constructed first: it checks every record (channels, length, finite inputs) by name.
  // For evaluation: a record may be shorter than the unknowns, which are held here, not estimated.
  const GreyBoxProblem<P> problem =
      GreyBoxProblem<P>::for_evaluation(model.physics(), model.integrator(), zero, InitialCondition::estimate);
  Eigen::VectorXd theta(problem.num_parameters());
  theta.head(np) = model.parameters();
  for (std::size_t e = 0; e < data.size(); ++e) {
    theta.segment(problem.state_column(e), nx) = model.initial_state(data[e], ic);
  }
  Eigen::VectorXd r(problem.num_residuals());
  Eigen::MatrixXd J(problem.num_residuals(), problem.num_parameters());
  if (!problem.evaluate(theta, r, &J)) {
    throw DivergenceError("simulation_band: the simulation of grey-box model '" + model.name() +
                              "' diverges on these data at its current parameters",
                          -1, at_parameter("data"));
  }
  for (std::size_t e = 0; e < data.size(); ++e) {
    const Eigen::Index off = problem.residual_offset(e), n = data[e].size();
    Eigen::MatrixXd yhat(n, ny);
    for (Eigen::Index k = 0; k < n; ++k) {
      for (int j = 0; j < ny; ++j) yhat(k, j) = r[off + k * ny + j];
    }
    detail::fill_band_experiment(b, e, yhat, J.block(off, 0, n * ny, np), u, data[e].y(), 0);
  }
  return b;
}

/// Band of a grey-box model's simulation from the covariance it carries
/// (`GreyBox::parameter_covariance`: set by `estimate`, kept in model files) — for a model loaded
/// from a file. Unidentifiable combinations are not stored, so `unidentifiable_change` is empty;
/// a parameter the estimation left undetermined (σ = ∞) is named in the caveat. Throws
/// `nlid::Error` if the model carries no covariance, and as the overload above.
template <Physics P>
SimulationBand simulation_band(const GreyBox<P>& model, const Dataset& data, const SimulationBandOptions& options = {}) {
  const Eigen::Index np = model.num_parameters();
  require(model.parameter_covariance().rows() == np && np > 0,
          "simulation_band: grey-box model '" + model.name() +
              "' carries no parameter covariance (estimate it, or load a model file written after an estimation)",
          at_parameter("covariance"));
  std::vector<std::string> names;
  for (const auto& q : model.parameter_info()) names.push_back(q.name);
  const Eigen::VectorXd sd = model.parameter_stddev().size() == np ? model.parameter_stddev() : Eigen::VectorXd();
  const ParameterUncertainty u =
      uncertainty_from_covariance(std::move(names), model.parameters(), model.parameter_covariance(), sd, model.fixed_flags());
  return simulation_band(model, data, u, options);
}

/// Band of a nonlinear ARX model's free-run simulation on `data` (initial condition default:
/// `measured`; its first n₀ samples are the record's own, σ = 0). Throws as the grey-box overload.
template <Regressor R, Nonlinearity F>
SimulationBand simulation_band(const Nlarx<R, F>& model, const Dataset& data, const ParameterUncertainty& u,
                               const SimulationBandOptions& options = {}) {
  return detail::regression_band(model, data, u, options.initial_condition.value_or(InitialCondition::measured),
                                 options, model.history_length(), "nonlinear ARX");
}

/// Band of a Hammerstein–Wiener model's simulation on `data` (initial condition default: `zero`).
/// Throws as the grey-box overload.
template <ScalarNonlinearity In, LinearBlock L, ScalarNonlinearity Out>
SimulationBand simulation_band(const HammersteinWiener<In, L, Out>& model, const Dataset& data,
                               const ParameterUncertainty& u, const SimulationBandOptions& options = {}) {
  return detail::regression_band(model, data, u, options.initial_condition.value_or(InitialCondition::zero), options,
                                 0, "Hammerstein-Wiener");
}

}  // namespace nlid
