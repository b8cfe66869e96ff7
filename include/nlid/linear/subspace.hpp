#pragma once
/// @file
/// Subspace identification of state-space models: PO-MOESP.
///
/// nlid uses the past-output MOESP algorithm of Verhaegen (1994) ("Identification of the
/// deterministic part of MIMO state space models given in innovations form from input-output
/// data", Automatica 30(1):61–74; also Verhaegen & Verdult 2007, "Filtering and System
/// Identification", §9.6, and Katayama 2005, §10.6). MOESP was chosen over N4SID because its
/// A, C step needs one LQ factorisation and one SVD, and the B, D step can then minimise the
/// *simulation* error directly — the focus the study asks for.
///
/// Notation: m inputs, p outputs, n states, s block rows ("horizon", s > n). For each
/// experiment, block Hankel matrices with j = N − 2s + 1 columns hold the past (samples
/// k … k+s−1) and future (k+s … k+2s−1) windows:
///
///     U_p, U_f ∈ R^{sm × j},   Y_p, Y_f ∈ R^{sp × j},   Z_p = [U_p; Y_p]
///
/// (columns of several experiments are placed side by side; no window crosses a boundary).
/// 1. LQ factorisation [U_f; Z_p; Y_f] = L Qᵀ, L lower block triangular.
/// 2. SVD of L₃₂ (block of L for Y_f rows and Z_p columns) = U Σ Vᵀ. Z_p is an instrument
///    uncorrelated with the future noise, so the column space of L₃₂ is that of the extended
///    observability matrix Γ_s = [C; CA; …; CA^{s−1}] (Verhaegen 1994, Thm. 3). The singular
///    values σ₁ ≥ σ₂ ≥ … indicate the order: a gap after σₙ (`subspace_singular_values`).
/// 3. Γ̂ = U₁ Σ₁^{1/2} (first n columns), C = first p rows of Γ̂, A from the shift invariance
///    Γ̂_{1:s−1} A = Γ̂_{2:s} by least squares.
/// 4. With A and C fixed the output is linear in B, D, the offset y₀ and each experiment's
///    x(0): y(t) = C Aᵗ x(0) + Σ_{τ<t} C A^{t−1−τ} B u(τ) + D u(t) + y₀. These are found by one
///    linear least-squares fit of the simulated to the measured output (QR).
/// Channels are scaled to unit RMS before steps 1–3 so the SVD weighs every channel equally; A
/// is unaffected and C is scaled back. Means are removed per experiment only when an offset is
/// estimated: a constant in the data is not a free response of a stable system and would show
/// up as one extra singular value (a state at z = 1); with `offset` the constant is taken out
/// first and y₀ is fitted in step 4.
/// If the estimated A is unstable (noise, too high an order) and `enforce_stability` is set, its
/// unstable eigenvalues λ are reflected to 1/λ̄ before step 4.

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <Eigen/QR>
#include <Eigen/SVD>

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/core/sizes.hpp"
#include "nlid/core/initial_condition.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/linear/detail/checks.hpp"
#include "nlid/linear/detail/least_squares.hpp"
#include "nlid/linear/report.hpp"
#include "nlid/linear/state_space.hpp"

namespace nlid {

/// Options of `moesp` (and of the subspace start of `ssest`).
struct SubspaceOptions {
  int horizon = 0;             ///< block rows s (> n); 0 = automatic, max(2n + 2, 10)
  bool feedthrough = false;    ///< estimate D (toolbox default: D = 0, a delay of ≥ 1 sample)
  bool offset = false;         ///< estimate the output offset y₀
  InitialCondition initial_state = InitialCondition::estimate;  ///< zero or estimate x(0)
  bool enforce_stability = true;  ///< reflect unstable eigenvalues of A into the unit circle
};

namespace detail {

struct MoespSvd {
  Eigen::MatrixXd u;        // left singular vectors of L32 (sp x k)
  Eigen::VectorXd sigma;    // singular values
  Eigen::VectorXd u_scale;  // channel scales used
  Eigen::VectorXd y_scale;
  int horizon = 0;
};

inline void check_subspace_data(const Dataset& data, const std::string& who, bool remove_means) {
  require(data.size() > 0, who + ": the data set is empty", at_parameter("data"));
  require(data.num_outputs() >= 1, who + ": the data have no output", at_parameter("data"));
  for (std::size_t e = 0; e < data.size(); ++e) {
    check_linear_experiment(data[e], data.num_inputs(), data.num_outputs(), 0.0, static_cast<long>(e),
                     who, true);
    data[e].require_estimable_scale(who, static_cast<long>(e));
  }
  // A constant output has no response to identify; left to the solver, its all-zero Hankel
  // matrix gave a NaN A and a message about instability. With the means removed per record
  // (`offset`), a level held within every record is constant too. Empty records are left to the
  // length checks.
  for (int j = 0; j < data.num_outputs(); ++j) {
    bool constant = true, any = false;
    double level = 0.0;
    for (const Experiment& e : data) {
      if (e.size() == 0) continue;
      const double first = e.y()(0, j);
      if (!any || remove_means) level = first;
      any = true;
      constant = constant && (e.y().col(j).array() == level).all();
    }
    if (!any || !constant) continue;
    Location where;
    where.column_name = data[0].output_names().at(static_cast<std::size_t>(j));
    throw Error(who + ": output '" + where.column_name + "' is " +
                    (remove_means && data.size() > 1 ? std::string("constant within every experiment (offset removes "
                                                                   "each experiment's mean)")
                                                     : detail::format_g(level, 6) + " in every sample of every experiment") +
                    ": no response to identify",
                where);
  }
}

inline int choose_horizon(const Dataset& data, int n, int requested, const std::string& who) {
  const int m = data.num_inputs(), p = data.num_outputs();
  auto columns = [&](int s) {
    Eigen::Index j = 0;
    for (const auto& e : data) j += std::max<Eigen::Index>(0, e.size() - 2 * s + 1);
    return j;
  };
  if (requested > 0) {
    require(requested * p > n,
            who + ": horizon s = " + std::to_string(requested) + " too small for order " +
                std::to_string(n) + " (need s * outputs > n)",
            at_parameter("horizon"));
    return requested;
  }
  int s = std::max(2 * n + 2, 10);
  const int s_min = n / p + 1;
  while (s > s_min && columns(s) < 2 * s * (m + p)) --s;
  return s;
}

// `automatic_for_order` > 0: s was chosen by `choose_horizon` for that order, not by the user,
// which a refusal must say (the user never set the number it names).
inline MoespSvd moesp_svd(const Dataset& data, int s, bool remove_means, const std::string& who,
                          int automatic_for_order = 0) {
  const int m = data.num_inputs(), p = data.num_outputs();
  // Channel scales: pooled RMS over all experiments (after per-experiment means if removed).
  auto centre = [&](const Eigen::MatrixXd& x) -> Eigen::MatrixXd {
    if (!remove_means) return x;
    return x.rowwise() - x.colwise().mean();
  };
  MoespSvd out;
  out.horizon = s;
  out.u_scale = Eigen::VectorXd::Ones(m);
  out.y_scale = Eigen::VectorXd::Ones(p);
  Eigen::Index total = 0, cols = 0;
  Eigen::VectorXd su = Eigen::VectorXd::Zero(m), sy = Eigen::VectorXd::Zero(p);
  for (std::size_t e = 0; e < data.size(); ++e) {
    const Experiment& ex = data[e];
    if (ex.size() < 2 * s) {
      std::string why;
      if (automatic_for_order > 0)
        why = " (horizon " + std::to_string(s) + " was chosen automatically for order " +
              std::to_string(automatic_for_order) + "; SubspaceOptions::horizon <= " +
              std::to_string(ex.size() / 2) + " would let this experiment in, or leave it out)";
      throw Error(who + ": " + linear_experiment_label(ex, static_cast<long>(e)) + " has " +
                      std::to_string(ex.size()) + " samples, fewer than 2 x horizon = " +
                      std::to_string(2 * s) + " needed for the Hankel matrices" + why,
                  at_experiment(static_cast<long>(e)));
    }
    su += centre(ex.u()).colwise().squaredNorm().transpose();
    sy += centre(ex.y()).colwise().squaredNorm().transpose();
    total += ex.size();
    cols += ex.size() - 2 * s + 1;
  }
  for (int i = 0; i < m; ++i)
    if (su(i) > 0) out.u_scale(i) = std::sqrt(su(i) / static_cast<double>(total));
  for (int i = 0; i < p; ++i)
    if (sy(i) > 0) out.y_scale(i) = std::sqrt(sy(i) / static_cast<double>(total));
  const Eigen::Index rows = 2 * s * (m + p);
  require(cols >= rows,
          who + ": " + std::to_string(cols) + " Hankel columns for " + std::to_string(rows) +
              " rows with horizon " + std::to_string(s) + "; more data or a smaller horizon needed",
          at_parameter("horizon"));
  // Wᵀ (columns x rows), row blocks in the order [U_f; U_p; Y_p; Y_f].
  Eigen::MatrixXd wt(cols, rows);
  Eigen::Index c0 = 0;
  for (const Experiment& ex : data) {
    const Eigen::MatrixXd u = centre(ex.u()) * out.u_scale.cwiseInverse().asDiagonal();
    const Eigen::MatrixXd y = centre(ex.y()) * out.y_scale.cwiseInverse().asDiagonal();
    const Eigen::Index j = ex.size() - 2 * s + 1;
    for (Eigen::Index k = 0; k < j; ++k) {
      auto row = wt.row(c0 + k);
      for (int i = 0; i < s; ++i) {
        row.segment(i * m, m) = u.row(k + s + i);                          // U_f
        row.segment(s * m + i * m, m) = u.row(k + i);                      // U_p
        row.segment(2 * s * m + i * p, p) = y.row(k + i);                  // Y_p
        row.segment(2 * s * m + s * p + i * p, p) = y.row(k + s + i);      // Y_f
      }
    }
    c0 += j;
  }
  Eigen::HouseholderQR<Eigen::MatrixXd> qr(wt);
  const Eigen::MatrixXd l =
      qr.matrixQR().topRows(rows).triangularView<Eigen::Upper>().toDenseMatrix().transpose();
  const Eigen::MatrixXd l32 = l.block(s * m + s * (m + p), s * m, s * p, s * (m + p));
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(l32, Eigen::ComputeThinU);
  out.u = svd.matrixU();
  out.sigma = svd.singularValues();
  return out;
}

// Reflects eigenvalues of A outside the unit circle to 1/λ̄ (and pulls any on it to 0.999),
// leaving the others. A diagonalisable A keeps its eigenvectors. A defective one (or one whose
// eigenvectors are numerically singular) goes through its real Schur form A = U T Uᵀ instead:
// scaling a diagonal block of the quasi-triangular T scales just that block's eigenvalues, so
// the result is stable in every case rather than the unstable A handed back.
inline Eigen::MatrixXd stabilize_matrix(const Eigen::MatrixXd& a) {
  if (a.rows() == 0) return a;
  Eigen::EigenSolver<Eigen::MatrixXd> es(a);
  Eigen::VectorXcd lambda = es.eigenvalues();
  bool changed = false;
  for (Eigen::Index k = 0; k < lambda.size(); ++k)
    if (const double r = std::abs(lambda(k)); r >= 1.0) {
      lambda(k) = r > 1.0 ? 1.0 / std::conj(lambda(k)) : lambda(k) * (0.999 / r);
      changed = true;
    }
  if (!changed) return a;
  const Eigen::MatrixXcd v = es.eigenvectors();
  Eigen::FullPivLU<Eigen::MatrixXcd> lu(v);
  if (lu.isInvertible() && lu.rcond() > 1e-8) return (v * lambda.asDiagonal() * lu.inverse()).real();
  const Eigen::RealSchur<Eigen::MatrixXd> schur(a);
  Eigen::MatrixXd t = schur.matrixT();
  const Eigen::Index n = t.rows();
  for (Eigen::Index k = 0; k < n;) {
    const Eigen::Index size = k + 1 < n && t(k + 1, k) != 0.0 ? 2 : 1;
    const double r = size == 1 ? std::abs(t(k, k))
                               : std::sqrt(std::abs(t.block(k, k, 2, 2).determinant()));
    // Scaling the block by c scales its eigenvalues by c: 1/r² maps λ to λ/|λ|² = 1/λ̄.
    if (r >= 1.0) t.block(k, k, size, size) *= r > 1.0 ? 1.0 / (r * r) : 0.999 / r;
    k += size;
  }
  return schur.matrixU() * t * schur.matrixU().transpose();
}

// Response columns of the output to each free linear parameter of the model (B, D, y₀, x(0) per
// experiment), stacked over experiments; then one QR least-squares fit.
struct BdFit {
  Eigen::MatrixXd b, d;
  Eigen::VectorXd offset;
  std::vector<Eigen::VectorXd> x0;
  double ssr = 0;
  std::vector<double> fit;  // per output
  Eigen::Index rows = 0;
  int params = 0;
};

inline BdFit fit_b_d(const Dataset& data, const Eigen::MatrixXd& a, const Eigen::MatrixXd& c,
                     const SubspaceOptions& opt, const std::string& who) {
  const int n = static_cast<int>(a.rows());
  const int m = data.num_inputs(), p = data.num_outputs();
  const int ne = static_cast<int>(data.size());
  const bool est_x0 = opt.initial_state == InitialCondition::estimate;
  const int nb = n * m, nd = opt.feedthrough ? p * m : 0, no = opt.offset ? p : 0;
  const int nx = est_x0 ? n * ne : 0;
  const int params = nb + nd + no + nx;
  const Eigen::Index rows = data.total_samples() * p;
  Eigen::MatrixXd phi = Eigen::MatrixXd::Zero(rows, params);
  Eigen::VectorXd y(rows);
  Eigen::Index r0 = 0;
  for (int e = 0; e < ne; ++e) {
    const Experiment& ex = data[static_cast<std::size_t>(e)];
    const Eigen::Index N = ex.size();
    for (Eigen::Index t = 0; t < N; ++t) y.segment(r0 + t * p, p) = ex.y().row(t).transpose();
    // B: per input j, X(t+1) = A X(t) + I u_j(t); column (i, j) of the output is C X(t) e_i.
    for (int j = 0; j < m; ++j) {
      Eigen::MatrixXd x = Eigen::MatrixXd::Zero(n, n), xn(n, n);
      for (Eigen::Index t = 0; t < N; ++t) {
        const Eigen::MatrixXd cx = c * x;  // p x n
        for (int i = 0; i < n; ++i) phi.block(r0 + t * p, j * n + i, p, 1) = cx.col(i);
        xn.noalias() = a * x;
        xn.diagonal().array() += ex.u()(t, j);
        x.swap(xn);
        // Unlike an x(0) column, a B column cannot be cut short (every later output depends on
        // it): past 1e150 its squares overflow and B, then the whole model, would come out NaN.
        if (!(x.cwiseAbs().maxCoeff() <= 1e150)) {
          const double radius = Eigen::EigenSolver<Eigen::MatrixXd>(a, false).eigenvalues().cwiseAbs().maxCoeff();
          throw Error(who + ": the estimated A is unstable (an eigenvalue at |z| = " + detail::format_g(radius, 6) +
                          ") and its response overflows within the " + std::to_string(N) +
                          " samples of " + linear_experiment_label(ex, e) +
                          "; set SubspaceOptions::enforce_stability or choose a lower order",
                      at_parameter("enforce_stability"));
        }
      }
    }
    for (Eigen::Index t = 0; t < N; ++t) {
      for (int j = 0; j < m && opt.feedthrough; ++j)
        for (int i = 0; i < p; ++i) phi(r0 + t * p + i, nb + j * p + i) = ex.u()(t, j);
      for (int i = 0; i < no; ++i) phi(r0 + t * p + i, nb + nd + i) = 1.0;
    }
    if (est_x0) {
      Eigen::MatrixXd cat = c;
      for (Eigen::Index t = 0; t < N; ++t) {
        if (cat.cwiseAbs().maxCoeff() > 1e150) break;  // unstable A: later rows carry nothing usable
        phi.block(r0 + t * p, nb + nd + no + e * n, p, n) = cat;
        cat = cat * a;
      }
    }
    r0 += N * p;
  }
  const LeastSquaresSolution sol = solve_least_squares_qr(phi, y);
  BdFit f;
  f.b.resize(n, m);
  for (int j = 0; j < m; ++j) f.b.col(j) = sol.theta.segment(j * n, n);
  f.d = Eigen::MatrixXd::Zero(p, m);
  if (opt.feedthrough)
    for (int j = 0; j < m; ++j) f.d.col(j) = sol.theta.segment(nb + j * p, p);
  f.offset = opt.offset ? Eigen::VectorXd(sol.theta.segment(nb + nd, p)) : Eigen::VectorXd::Zero(p);
  for (int e = 0; e < ne; ++e)
    f.x0.push_back(est_x0 ? Eigen::VectorXd(sol.theta.segment(nb + nd + no + e * n, n))
                          : Eigen::VectorXd::Zero(n));
  f.ssr = sol.residual_norm * sol.residual_norm;
  f.fit = fit_percent_per_output(y, phi * sol.theta - y, p);
  f.rows = rows;
  f.params = params;
  return f;
}

}  // namespace detail

/// Singular values of the PO-MOESP matrix L₃₂ for horizon `s` (largest first): a clear drop
/// after the n-th value suggests order n (the toolbox's n4sid order plot). `remove_means` as
/// with `SubspaceOptions::offset`. Throws like `moesp`.
inline Eigen::VectorXd subspace_singular_values(const Dataset& data, int horizon,
                                                bool remove_means = false) {
  detail::check_subspace_data(data, "subspace_singular_values", remove_means);
  require(horizon >= 1, "subspace_singular_values: horizon must be >= 1",
          at_parameter("horizon"));
  return detail::moesp_svd(data, horizon, remove_means, "subspace_singular_values").sigma;
}

namespace detail {

// `who` names the function the user called in every message: ssest starts here too, and its
// users should not read about a function they never called.
inline StateSpace moesp_as(const Dataset& data, int order, const SubspaceOptions& options,
                           const std::string& who) {
  detail::check_subspace_data(data, who, options.offset);
  require(order >= 1, who + ": order must be >= 1, got " + std::to_string(order),
          at_parameter("order"));
  require(order <= max_model_order,
          who + ": order " + std::to_string(order) + " is beyond the largest order " +
              std::to_string(max_model_order),
          at_parameter("order"));
  require(options.horizon >= 0 && options.horizon <= max_model_order,
          who + ": horizon must be 0 (automatic) or 1 ... " + std::to_string(max_model_order) +
              ", got " + std::to_string(options.horizon),
          at_parameter("horizon"));
  require(options.initial_state == InitialCondition::zero ||
              options.initial_state == InitialCondition::estimate,
          who + ": initial_state must be InitialCondition::zero or ::estimate",
          at_parameter("initial_state"));
  const int p = data.num_outputs();
  const int s = detail::choose_horizon(data, order, options.horizon, who);
  const detail::MoespSvd svd =
      detail::moesp_svd(data, s, options.offset, who, options.horizon > 0 ? 0 : order);
  require(order < s * p && order <= svd.sigma.size(),
          who + ": order " + std::to_string(order) + " too large for horizon " +
              std::to_string(s) + " (need order < horizon x outputs)",
          at_parameter("order"));
  const Eigen::MatrixXd gamma =
      svd.u.leftCols(order) * svd.sigma.head(order).cwiseSqrt().asDiagonal();
  Eigen::MatrixXd c = svd.y_scale.asDiagonal() * gamma.topRows(p);
  const Eigen::Index sh = (s - 1) * p;
  Eigen::MatrixXd a = gamma.topRows(sh).colPivHouseholderQr().solve(gamma.bottomRows(sh));
  // Not an unstable A (the message further on) but none: say so before B and D are fitted to it.
  require(a.allFinite() && c.allFinite(),
          who + ": the subspace step gave a non-finite A or C for order " + std::to_string(order) +
              " (the data's response has fewer directions than that" +
              (order > 1 ? std::string("); choose a lower order") : std::string(": is the output moved by the input?)")),
          at_parameter("order"));
  if (options.enforce_stability) a = detail::stabilize_matrix(a);
  const detail::BdFit fit = detail::fit_b_d(data, a, c, options, who);
  StateSpace model(a, fit.b, c, fit.d, data.ts());
  model.set_offset(fit.offset);
  LinearEstimationReport r;
  r.method = "PO-MOESP subspace (horizon " + std::to_string(s) +
             "), B, D, x0 by least squares on the simulation error";
  r.focus = "simulation";
  r.num_experiments = static_cast<int>(data.size());
  r.num_samples = fit.rows;
  r.num_parameters = order * p + fit.params;  // identifiable: C (n p, A up to similarity) + B, D, y0, x0
  r.loss = fit.ssr / static_cast<double>(fit.rows);
  r.set_fit(fit.fit);
  model.set_report(r);
  model.set_input_names(data[0].input_names());
  model.set_output_names(data[0].output_names());
  return model;
}

}  // namespace detail

/// Estimates an n-state model by PO-MOESP (see file comment) on single- or multi-experiment
/// data. Throws `nlid::Error` for n < 1, an order the horizon cannot resolve, an experiment
/// shorter than 2·horizon (naming it), or missing samples.
inline StateSpace moesp(const Dataset& data, int order, const SubspaceOptions& options = {}) {
  return detail::moesp_as(data, order, options, "moesp");
}

}  // namespace nlid
