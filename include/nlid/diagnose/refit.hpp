#pragma once
/// @file
/// Refitting an augmented model by simulation error, and scoring it on data.
///
/// Criterion (Ljung 1999, sec. 7.2, eq. 7.12 with the simulation predictor of sec. 4.5):
///
///     V(θ, x₀⁽¹⁾ … x₀⁽ᴱ⁾) = ½ Σ_e Σ_k (ŷ_e(k | θ, x₀⁽ᵉ⁾) − y_e(k))²,
///
/// over the free parameters θ_f of the augmented model (baseline and effects; fixed entries of
/// the parameter table stay put) and, with `InitialCondition::estimate`, one baseline initial
/// state per experiment. Levenberg–Marquardt with bounds (estimation/levenberg_marquardt.hpp)
/// solves it; the Jacobian is exact, by forward AD through the simulator on Dual<double, 8>.
///
/// Jacobian structure. Experiment e's residuals depend on θ_f and on x₀⁽ᵉ⁾ only, so its block
/// is simulated with the columns [θ_f, x₀⁽ᵉ⁾] seeded, 8 at a time; every other x₀ column of that
/// block is zero. A throttle baseline with one effect (8 + 2 columns) costs two Dual runs per
/// experiment per Jacobian.
///
/// Scoring. A model is judged by its free-run simulation: on estimation data from the fitted
/// x₀, on validation data from an x₀ fitted to that record with θ held (the toolbox's
/// `compare(…, 'InitialCondition', 'estimate')`), so the start-up transient of an unknown
/// initial state is not charged to the model's physics.
///
/// Threads. `evaluate` is const and works on local storage only: one problem may be evaluated
/// from several threads (the diagnosis refits candidates in parallel).

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "nlid/analysis/fit.hpp"
#include "nlid/core/error.hpp"
#include "nlid/core/initial_condition.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/diagnose/augmented.hpp"
#include "nlid/estimation/levenberg_marquardt.hpp"

namespace nlid {

/// Simulation-error problem of an augmented model on a data set (see the file comment).
/// Satisfies `LeastSquaresProblem` with `num_params = Dynamic`. Unknowns z = [θ_f; x₀⁽¹⁾; …].
/// The model and data set must outlive the problem.
template <Physics P>
class AugmentedProblem {
 public:
  /// Parameter count known at run time only.
  static constexpr int num_params = Dynamic;

  /// Problem for `model` on `data`; `estimate_x0` adds one initial state per experiment as
  /// unknowns (otherwise x₀ = `fixed_x0[e]`, or zero when that is empty). Throws `nlid::Error`
  /// naming the experiment on a channel mismatch.
  AugmentedProblem(const AugmentedModel<P>& model, const Dataset& data, bool estimate_x0,
                   std::vector<Eigen::VectorXd> fixed_x0 = {})
      : model_(&model), data_(&data), estimate_x0_(estimate_x0), fixed_x0_(std::move(fixed_x0)) {
    require(data.size() > 0, "refit: empty data set");
    for (std::size_t e = 0; e < data.size(); ++e) model.check_experiment(data[e], static_cast<long>(e));
    const std::vector<ParameterInfo> info = model.parameter_info();
    for (std::size_t i = 0; i < info.size(); ++i)
      if (!info[i].fixed) free_.push_back(static_cast<int>(i));
    nx_ = model.state_dimension();
    m_ = 0;
    for (const Experiment& x : data) m_ += x.size();
    if (!estimate_x0_ && fixed_x0_.empty())
      fixed_x0_.assign(data.size(), Eigen::VectorXd::Zero(nx_));
    require(estimate_x0_ || fixed_x0_.size() == data.size(),
            "refit: " + std::to_string(fixed_x0_.size()) + " initial states for " +
                std::to_string(data.size()) + " experiments");
  }

  /// Free model parameters plus estimated initial states.
  [[nodiscard]] int num_parameters() const {
    return static_cast<int>(free_.size()) + (estimate_x0_ ? nx_ * static_cast<int>(data_->size()) : 0);
  }
  /// Total samples of all experiments.
  [[nodiscard]] Eigen::Index num_residuals() const { return m_; }
  /// Indices (into θ) of the free model parameters, in z order.
  [[nodiscard]] const std::vector<int>& free_parameters() const { return free_; }

  /// Packs θ and initial states into z.
  [[nodiscard]] Eigen::VectorXd pack(const Eigen::VectorXd& theta, const std::vector<Eigen::VectorXd>& x0) const {
    Eigen::VectorXd z(num_parameters());
    for (std::size_t i = 0; i < free_.size(); ++i) z(static_cast<Eigen::Index>(i)) = theta(free_[i]);
    if (estimate_x0_) {
      for (std::size_t e = 0; e < data_->size(); ++e)
        z.segment(static_cast<Eigen::Index>(free_.size()) + static_cast<Eigen::Index>(e) * nx_, nx_) = x0.at(e);
    }
    return z;
  }
  /// θ from z (fixed entries from `theta_ref`).
  [[nodiscard]] Eigen::VectorXd theta_of(const Eigen::VectorXd& z, const Eigen::VectorXd& theta_ref) const {
    Eigen::VectorXd th = theta_ref;
    for (std::size_t i = 0; i < free_.size(); ++i) th(free_[i]) = z(static_cast<Eigen::Index>(i));
    return th;
  }
  /// Initial state of experiment e under z.
  [[nodiscard]] Eigen::VectorXd x0_of(const Eigen::VectorXd& z, std::size_t e) const {
    if (!estimate_x0_) return fixed_x0_.at(e);
    return z.segment(static_cast<Eigen::Index>(free_.size()) + static_cast<Eigen::Index>(e) * nx_, nx_);
  }
  /// Bounds of z (model bounds; initial states unbounded).
  void bounds(Eigen::VectorXd& lower, Eigen::VectorXd& upper) const {
    const int n = num_parameters();
    lower = Eigen::VectorXd::Constant(n, -std::numeric_limits<double>::infinity());
    upper = Eigen::VectorXd::Constant(n, std::numeric_limits<double>::infinity());
    const std::vector<ParameterInfo> info = model_->parameter_info();
    for (std::size_t i = 0; i < free_.size(); ++i) {
      lower(static_cast<Eigen::Index>(i)) = info[static_cast<std::size_t>(free_[i])].lower;
      upper(static_cast<Eigen::Index>(i)) = info[static_cast<std::size_t>(free_[i])].upper;
    }
  }
  /// Names of z's entries (for solver messages).
  [[nodiscard]] std::vector<std::string> names() const {
    std::vector<std::string> s;
    const std::vector<ParameterInfo> info = model_->parameter_info();
    for (int i : free_) s.push_back(info[static_cast<std::size_t>(i)].name);
    if (estimate_x0_)
      for (std::size_t e = 0; e < data_->size(); ++e)
        for (int i = 0; i < nx_; ++i) s.push_back("x0[" + std::to_string(e) + "][" + std::to_string(i) + "]");
    return s;
  }

  /// r = ŷ − y over all experiments; J = ∂r/∂z (see the file comment). False if a simulation
  /// diverged or produced non-finite values.
  bool evaluate(const Eigen::VectorXd& z, Eigen::VectorXd& r, Eigen::MatrixXd* J) const {
    const Eigen::VectorXd theta = theta_of(z, model_->parameters());
    // A trial step that crosses the physics' relations (stops swapped) is rejected, as in the
    // grey-box estimator; θ starts with the baseline's values.
    if (!physics_parameters_consistent(model_->physics(), theta.data())) return false;
    if (J) J->setZero();
    Eigen::Index row = 0;
    const int nf = static_cast<int>(free_.size());
    for (std::size_t e = 0; e < data_->size(); ++e) {
      const Experiment& x = (*data_)[e];
      const Eigen::Index n = x.size();
      const Eigen::VectorXd x0 = x0_of(z, e);
      if (!J) {
        Eigen::VectorXd yh(n);
        if (model_->template simulate<double>(x.u(), theta.data(), x0.data(), yh.data()) < n) return false;
        r.segment(row, n) = yh - x.y().col(0);
      } else {
        const int ncol = nf + (estimate_x0_ ? nx_ : 0);
        bool ok;
        // One pass of a 16-wide dual beats two 8-wide passes (the value part is computed once);
        // runtime physics evaluate on RuntimeDual only.
        if constexpr (detail::EvaluatesPhysicsOn<P, Dual<double, 16>>) {
          ok = ncol > RuntimeDual::num_derivatives
                   ? jacobian_block<Dual<double, 16>>(x, theta, x0, e, row, r, *J)
                   : jacobian_block<RuntimeDual>(x, theta, x0, e, row, r, *J);
        } else {
          ok = jacobian_block<RuntimeDual>(x, theta, x0, e, row, r, *J);
        }
        if (!ok) return false;
      }
      row += n;
    }
    return r.allFinite() && (!J || J->allFinite());
  }

 private:
  // Residuals and Jacobian block of experiment e, columns [θ_f, x₀⁽ᵉ⁾] seeded W at a time.
  template <class D>
  bool jacobian_block(const Experiment& x, const Eigen::VectorXd& theta, const Eigen::VectorXd& x0,
                      std::size_t e, Eigen::Index row, Eigen::VectorXd& r, Eigen::MatrixXd& J) const {
    constexpr int W = D::num_derivatives;
    const Eigen::Index n = x.size();
    const int nf = static_cast<int>(free_.size());
    const int ncol = nf + (estimate_x0_ ? nx_ : 0);
    std::vector<D> thd(static_cast<std::size_t>(theta.size())), xd(static_cast<std::size_t>(nx_)),
        yd(static_cast<std::size_t>(n));
    for (int c0 = 0; c0 < std::max(ncol, 1); c0 += W) {
      for (Eigen::Index i = 0; i < theta.size(); ++i) thd[static_cast<std::size_t>(i)] = D(theta(i));
      for (int i = 0; i < nx_; ++i) xd[static_cast<std::size_t>(i)] = D(x0(i));
      for (int c = c0; c < std::min(ncol, c0 + W); ++c) {
        if (c < nf) {
          const int k = free_[static_cast<std::size_t>(c)];
          thd[static_cast<std::size_t>(k)] = D::variable(theta(k), c - c0);
        } else {
          xd[static_cast<std::size_t>(c - nf)] = D::variable(x0(c - nf), c - c0);
        }
      }
      if (model_->template simulate<D>(x.u(), thd.data(), xd.data(), yd.data()) < n) return false;
      for (Eigen::Index k = 0; k < n; ++k) {
        const D& v = yd[static_cast<std::size_t>(k)];
        if (c0 == 0) r(row + k) = v.a - x.y()(k, 0);
        for (int c = c0; c < std::min(ncol, c0 + W); ++c) {
          const Eigen::Index col = c < nf ? c : nf + static_cast<Eigen::Index>(e) * nx_ + (c - nf);
          J(row + k, col) = v.v[c - c0];
        }
      }
    }
    return true;
  }

  const AugmentedModel<P>* model_;
  const Dataset* data_;
  bool estimate_x0_;
  std::vector<Eigen::VectorXd> fixed_x0_;
  std::vector<int> free_;
  int nx_ = 0;
  Eigen::Index m_ = 0;
};

/// Settings of `refit`.
struct RefitOptions {
  int max_iterations = 60;            ///< Levenberg–Marquardt step attempts per start
  double function_tolerance = 1e-8;   ///< relative cost decrease that ends a run
  /// `estimate` (x₀ per experiment is an unknown) or `zero`.
  InitialCondition initial_condition = InitialCondition::estimate;
  /// Keep the given initial states instead of estimating them (a cheaper screening refit: the
  /// Jacobian then has only the model's columns).
  bool hold_initial_states = false;
};

/// Outcome of `refit`.
struct RefitResult {
  bool ok = false;                       ///< a finite cost was reached
  Eigen::VectorXd theta;                 ///< parameters (all, fixed ones unchanged)
  std::vector<Eigen::VectorXd> x0;       ///< initial state per experiment
  double sse = std::numeric_limits<double>::infinity();  ///< Σ (ŷ − y)² at the result
  LmSummary summary;                     ///< solver summary of the run that won
  std::string error;                     ///< why it failed (if !ok)
};

/// Refits `model` on `data` from parameter vector `theta0` and initial states `x0_start` (one
/// per experiment; empty = each experiment's `initial_state_guess`). Never throws for a start
/// that cannot be simulated: the result is then `ok == false` with the reason.
template <Physics P>
RefitResult refit(const AugmentedModel<P>& model, const Dataset& data, const Eigen::VectorXd& theta0,
                  std::vector<Eigen::VectorXd> x0_start, const RefitOptions& options = {});

/// Free-run scoring of a model on a data set (see the file comment).
struct Evaluation {
  bool ok = false;                        ///< every experiment simulated to the end
  std::vector<Eigen::VectorXd> yhat;      ///< simulated output per experiment
  std::vector<Eigen::VectorXd> x0;        ///< initial state used per experiment
  Eigen::VectorXd fit;                    ///< fit % per experiment
  Eigen::VectorXd sse;                    ///< Σ (y − ŷ)² per experiment
  /// Σ over experiments of `sse`.
  [[nodiscard]] double total_sse() const { return sse.size() ? sse.sum() : std::numeric_limits<double>::infinity(); }
};

/// Simulates every experiment of `data` with `model`'s current parameters from the given
/// initial states (`x0` non-empty) or from states estimated per record (`x0` empty and
/// `ic == estimate`) or zero (`ic == zero`), and scores it.
template <Physics P>
Evaluation evaluate_model(const AugmentedModel<P>& model, const Dataset& data,
                          const std::vector<Eigen::VectorXd>& x0 = {},
                          InitialCondition ic = InitialCondition::estimate);

// ------------------------------------------------------------------------------------------
// Implementation details below.
// ------------------------------------------------------------------------------------------

template <Physics P>
RefitResult refit(const AugmentedModel<P>& model, const Dataset& data, const Eigen::VectorXd& theta0,
                  std::vector<Eigen::VectorXd> x0_start, const RefitOptions& options) {
  RefitResult out;
  // Bad data are the caller's error, not a start that failed: thrown, not returned.
  data.require_estimable_scale("refit");
  const bool guess = options.initial_condition == InitialCondition::estimate;
  const bool est = guess && !options.hold_initial_states;
  if (x0_start.empty()) {
    for (const Experiment& x : data)
      x0_start.push_back(guess ? model.initial_state_guess(x) : Eigen::VectorXd::Zero(model.state_dimension()));
  }
  try {
    AugmentedModel<P> m = model;
    m.set_parameters(theta0);
    const AugmentedProblem<P> problem(m, data, est, est ? std::vector<Eigen::VectorXd>{} : x0_start);
    Eigen::VectorXd z = problem.pack(theta0, x0_start);
    LmOptions o;
    o.max_iterations = options.max_iterations;
    o.function_tolerance = options.function_tolerance;
    o.parameter_tolerance = 1e-10;
    problem.bounds(o.lower_bounds, o.upper_bounds);
    o.parameter_names = problem.names();
    // A start on a bound is legal; one outside is projected by the solver.
    out.summary = solve_least_squares(problem, z, o);
    out.theta = problem.theta_of(z, theta0);
    for (std::size_t e = 0; e < data.size(); ++e) out.x0.push_back(problem.x0_of(z, e));
    out.sse = 2.0 * out.summary.final_cost;
    out.ok = std::isfinite(out.sse);
    if (!out.ok) out.error = "non-finite cost";
  } catch (const Error& err) {
    out.ok = false;
    out.error = err.what();
  }
  return out;
}

template <Physics P>
Evaluation evaluate_model(const AugmentedModel<P>& model, const Dataset& data,
                          const std::vector<Eigen::VectorXd>& x0, InitialCondition ic) {
  Evaluation ev;
  ev.fit = Eigen::VectorXd::Constant(static_cast<Eigen::Index>(data.size()), -std::numeric_limits<double>::infinity());
  ev.sse = Eigen::VectorXd::Constant(static_cast<Eigen::Index>(data.size()), std::numeric_limits<double>::infinity());
  ev.ok = true;
  const Eigen::VectorXd th = model.parameters();
  for (std::size_t e = 0; e < data.size(); ++e) {
    const Experiment& x = data[e];
    model.check_experiment(x, static_cast<long>(e));
    Eigen::VectorXd s0;
    if (!x0.empty()) s0 = x0.at(e);
    else if (ic == InitialCondition::zero) s0 = Eigen::VectorXd::Zero(model.state_dimension());
    else s0 = model.estimate_initial_state(x);
    Eigen::VectorXd yh = Eigen::VectorXd::Constant(x.size(), std::numeric_limits<double>::quiet_NaN());
    const Eigen::Index got = model.template simulate<double>(x.u(), th.data(), s0.data(), yh.data());
    ev.x0.push_back(s0);
    if (got < x.size()) {
      ev.ok = false;
      ev.yhat.push_back(yh);
      continue;
    }
    ev.sse(static_cast<Eigen::Index>(e)) = (x.y().col(0) - yh).squaredNorm();
    ev.fit(static_cast<Eigen::Index>(e)) = fit_percent(Eigen::VectorXd(x.y().col(0)), yh);
    ev.yhat.push_back(std::move(yh));
  }
  return ev;
}

}  // namespace nlid
