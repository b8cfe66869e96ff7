#pragma once
/// @file
/// State-space estimation with simulation focus: PO-MOESP start, prediction-error refinement.
///
/// `ssest(data, n)` first estimates an n-state model by PO-MOESP (subspace.hpp) and then
/// minimises the simulation error
///
///     V(θ) = ½ Σₑ Σₜ ‖ŷₑ(t | θ) − yₑ(t)‖²,   x(t+1) = A x + B u,  ŷ = C x + D u + y₀
///
/// over all entries θ = [vec A, vec B, vec C, (vec D), (y₀), (x₀ per experiment)] with
/// Levenberg–Marquardt (Ljung 1999, §10.2; the toolbox's `ssest` with a zero disturbance model,
/// i.e. "simulation focus"). The Jacobian comes from the sensitivity recursions
///
///     S(t+1) = A S(t) + ∂(A x + B u)/∂θ |explicit,   ∂ŷ/∂θ = C S(t) + ∂(C x + D u + y₀)/∂θ |explicit
///
/// with S = ∂x/∂θ and S(0) = ∂x₀/∂θ (Ljung 1999, eq. 10.55 in state-space form).
///
/// Parametrisation. All entries of A, B, C, D are free ("full parametrisation"). Any similarity
/// transform T gives the same input-output behaviour, so V is flat along n² directions; the
/// damping of Levenberg–Marquardt keeps those components of the step small (McKelvey, Helmersson
/// & Ribarits 2004 analyse this for data-driven local coordinates). The number of *identifiable*
/// parameters n(m + p) (+ pm for D, + p for y₀, + n per experiment for x₀) is what the report
/// counts. Each evaluation checks that A is strictly stable and reports the point as not
/// evaluable otherwise, so the result stays stable.

#include <cmath>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>

#include "nlid/core/error.hpp"
#include "nlid/core/initial_condition.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/estimation/levenberg_marquardt.hpp"
#include "nlid/linear/report.hpp"
#include "nlid/linear/state_space.hpp"
#include "nlid/linear/subspace.hpp"

namespace nlid {

/// Options of `ssest`.
struct SsestOptions {
  /// Start (PO-MOESP) options; `feedthrough`, `offset` and `initial_state` also define which
  /// parameters the refinement estimates.
  SubspaceOptions subspace;
  bool refine = true;  ///< run the prediction-error refinement
  LmOptions lm;        ///< options of the refinement
};

// ---- Implementation details below ------------------------------------------------------------
namespace detail {

// Simulation-error problem of a fully parametrised state-space model (see file comment). Holds a
// reference to the data: it lives only inside `ssest`. θ layout: vec A, vec B, vec C (column-
// major), then vec D, y₀ and x₀ per experiment if estimated.
class StateSpacePemProblem {
 public:
  static constexpr int num_params = Dynamic;

  StateSpacePemProblem(const Dataset& data, int n, bool feedthrough, bool offset, bool est_x0)
      : data_(data), n_(n), m_(data.num_inputs()), p_(data.num_outputs()),
        feedthrough_(feedthrough), offset_(offset), est_x0_(est_x0) {
    na_ = n * n;
    nb_ = n * m_;
    nc_ = p_ * n;
    nd_ = feedthrough ? p_ * m_ : 0;
    no_ = offset ? p_ : 0;
    nmodel_ = na_ + nb_ + nc_ + nd_ + no_;
    total_ = nmodel_ + (est_x0 ? n * static_cast<int>(data.size()) : 0);
    rows_ = data.total_samples() * p_;
  }

  [[nodiscard]] int num_parameters() const { return total_; }
  [[nodiscard]] Eigen::Index num_residuals() const { return rows_; }

  [[nodiscard]] Eigen::VectorXd pack(const StateSpace& s, const std::vector<Eigen::VectorXd>& x0) const {
    Eigen::VectorXd th = Eigen::VectorXd::Zero(total_);
    th.segment(0, na_) = s.a().reshaped();
    th.segment(na_, nb_) = s.b().reshaped();
    th.segment(na_ + nb_, nc_) = s.c().reshaped();
    if (feedthrough_) th.segment(na_ + nb_ + nc_, nd_) = s.d().reshaped();
    if (offset_) th.segment(na_ + nb_ + nc_ + nd_, no_) = s.offset();
    if (est_x0_)
      for (std::size_t e = 0; e < x0.size(); ++e) th.segment(nmodel_ + static_cast<int>(e) * n_, n_) = x0[e];
    return th;
  }

  [[nodiscard]] StateSpace unpack(const Eigen::VectorXd& th) const {
    const Eigen::MatrixXd a = th.segment(0, na_).reshaped(n_, n_);
    const Eigen::MatrixXd b = th.segment(na_, nb_).reshaped(n_, m_);
    const Eigen::MatrixXd c = th.segment(na_ + nb_, nc_).reshaped(p_, n_);
    const Eigen::MatrixXd d = feedthrough_ ? Eigen::MatrixXd(th.segment(na_ + nb_ + nc_, nd_).reshaped(p_, m_))
                                           : Eigen::MatrixXd::Zero(p_, m_);
    StateSpace s(a, b, c, d, data_.ts());
    if (offset_) s.set_offset(th.segment(na_ + nb_ + nc_ + nd_, no_));
    return s;
  }

  bool evaluate(const Eigen::VectorXd& th, Eigen::VectorXd& r, Eigen::MatrixXd* J) const {
    if (!th.allFinite()) return false;
    const Eigen::MatrixXd a = th.segment(0, na_).reshaped(n_, n_);
    const Eigen::MatrixXd b = th.segment(na_, nb_).reshaped(n_, m_);
    const Eigen::MatrixXd c = th.segment(na_ + nb_, nc_).reshaped(p_, n_);
    Eigen::MatrixXd d = Eigen::MatrixXd::Zero(p_, m_);
    if (feedthrough_) d = th.segment(na_ + nb_ + nc_, nd_).reshaped(p_, m_);
    Eigen::VectorXd y0 = Eigen::VectorXd::Zero(p_);
    if (offset_) y0 = th.segment(na_ + nb_ + nc_ + nd_, no_);
    // An unstable A makes the simulation diverge: not evaluable, LM backs off.
    if (n_ > 0) {
      const Eigen::VectorXcd ev = Eigen::EigenSolver<Eigen::MatrixXd>(a, false).eigenvalues();
      for (Eigen::Index k = 0; k < ev.size(); ++k)
        if (!(std::abs(ev(k)) < 1.0)) return false;
    }
    if (J) J->setZero();
    const int ns = na_ + nb_ + n_;  // columns of S: A, B, and this experiment's x0
    Eigen::MatrixXd S(n_, ns), Sn(n_, ns);
    Eigen::VectorXd x(n_), xn(n_);
    Eigen::Index row = 0;
    for (std::size_t e = 0; e < data_.size(); ++e) {
      const Experiment& ex = data_[e];
      const int kx0 = nmodel_ + static_cast<int>(e) * n_;
      x = est_x0_ ? Eigen::VectorXd(th.segment(kx0, n_)) : Eigen::VectorXd::Zero(n_);
      S.setZero();
      if (est_x0_) S.rightCols(n_).setIdentity();
      for (Eigen::Index t = 0; t < ex.size(); ++t) {
        const auto u = ex.u().row(t).transpose();
        r.segment(row, p_) = c * x + d * u + y0 - ex.y().row(t).transpose();
        if (J) {
          auto Jr = J->middleRows(row, p_);
          const Eigen::MatrixXd cs = c * S;  // p x ns
          Jr.leftCols(na_ + nb_) = cs.leftCols(na_ + nb_);
          if (est_x0_) Jr.middleCols(kx0, n_) = cs.rightCols(n_);
          for (int j = 0; j < n_; ++j)  // C(i, j): column na+nb + i + j p
            for (int i = 0; i < p_; ++i) Jr(i, na_ + nb_ + i + j * p_) = x(j);
          for (int j = 0; j < m_ && feedthrough_; ++j)
            for (int i = 0; i < p_; ++i) Jr(i, na_ + nb_ + nc_ + i + j * p_) = u(j);
          for (int i = 0; i < no_; ++i) Jr(i, na_ + nb_ + nc_ + nd_ + i) = 1.0;
          // S(t+1) = A S(t) + explicit terms: A(i,j) -> e_i x_j, B(i,j) -> e_i u_j.
          Sn.noalias() = a * S;
          for (int j = 0; j < n_; ++j)
            for (int i = 0; i < n_; ++i) Sn(i, i + j * n_) += x(j);
          for (int j = 0; j < m_; ++j)
            for (int i = 0; i < n_; ++i) Sn(i, na_ + i + j * n_) += u(j);
          S.swap(Sn);
        }
        xn.noalias() = a * x + b * u;
        x.swap(xn);
        row += p_;
      }
    }
    return r.allFinite();
  }

 private:
  const Dataset& data_;
  int n_, m_, p_;
  bool feedthrough_, offset_, est_x0_;
  int na_ = 0, nb_ = 0, nc_ = 0, nd_ = 0, no_ = 0, nmodel_ = 0, total_ = 0;
  Eigen::Index rows_ = 0;
};

}  // namespace detail

/// Estimates an n-state model with simulation focus: PO-MOESP start, then Levenberg–Marquardt on
/// the simulation error (see file comment). Throws like `moesp`, naming `ssest`.
inline StateSpace ssest(const Dataset& data, int order, const SsestOptions& options = {}) {
  StateSpace start = detail::moesp_as(data, order, options.subspace, "ssest");
  if (!start.is_stable() && options.subspace.enforce_stability) {
    // moesp reflected the unstable eigenvalues already; this catches one left on the circle by
    // rounding.
    StateSpace s(detail::stabilize_matrix(start.a()), start.b(), start.c(), start.d(), start.ts());
    s.set_offset(start.offset());
    s.set_report(start.report());
    s.set_input_names(start.input_names());
    s.set_output_names(start.output_names());
    start = s;
  }
  if (!options.refine) return start;
  // The refinement searches the stable models only (every evaluation rejects an unstable A), so
  // it cannot start from an unstable one; stabilising it here would silently undo the option.
  require(start.is_stable(),
          "ssest: the subspace start has an unstable A and SubspaceOptions::enforce_stability is "
          "off; the refinement needs a stable start (turn enforce_stability on, or set refine = "
          "false to keep the unstable subspace model)",
          at_parameter("enforce_stability"));
  const SubspaceOptions& so = options.subspace;
  const bool est_x0 = so.initial_state == InitialCondition::estimate;
  detail::StateSpacePemProblem problem(data, order, so.feedthrough, so.offset, est_x0);
  std::vector<Eigen::VectorXd> x0;
  for (const auto& e : data)
    x0.push_back(est_x0 ? start.initial_state(e, InitialCondition::estimate)
                        : Eigen::VectorXd::Zero(order));
  Eigen::VectorXd theta = problem.pack(start, x0);
  const LmSummary summary = solve_least_squares(problem, theta, options.lm);
  StateSpace model = problem.unpack(theta);
  model.set_input_names(start.input_names());
  model.set_output_names(start.output_names());
  Eigen::VectorXd r(problem.num_residuals());
  require(problem.evaluate(theta, r, nullptr),
          "ssest: the refined model cannot be simulated (unstable A)", at_parameter("order"));
  const int p = data.num_outputs(), m = data.num_inputs();
  Eigen::VectorXd yall(r.size());
  Eigen::Index row = 0;
  for (const auto& e : data) {
    yall.segment(row, e.y().size()) = e.y().transpose().reshaped();  // sample by sample, as r
    row += e.y().size();
  }
  LinearEstimationReport rep;
  rep.method = "PO-MOESP start + prediction-error minimisation (Levenberg-Marquardt), " +
               std::string(est_x0 ? "initial states estimated" : "zero initial states");
  rep.focus = "simulation";
  rep.num_experiments = static_cast<int>(data.size());
  rep.num_samples = r.size();
  rep.num_parameters = order * (m + p) + (so.feedthrough ? p * m : 0) + (so.offset ? p : 0) +
                       (est_x0 ? order * static_cast<int>(data.size()) : 0);
  rep.loss = r.squaredNorm() / static_cast<double>(r.size());
  rep.set_fit(fit_percent_per_output(yall, r, p));
  rep.iterations = summary.iterations;
  rep.solver_message = summary.message();
  model.set_report(rep);
  return model;
}

}  // namespace nlid
