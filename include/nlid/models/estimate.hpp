#pragma once
/// @file
/// Estimation of `Nlarx` and `HammersteinWiener` models from (multi-experiment) data.
///
/// Criterion (Ljung 1999, sec. 7.2, eq. 7.11, with a loss ρ from `RobustLoss`):
///
///     θ̂ = arg min ½ Σ_e Σ_t ρ(ε_e(t, θ)²),
///
///   prediction focus:  ε(t) = y(t) − ŷ(t | t−1; θ)       (one-step errors; regression-like),
///   simulation focus:  ε(t) = y(t) − ŷ_s(t; θ, x0_e)     (free-run errors; the study's measure).
///
/// Residuals of several experiments are stacked; every experiment has its own initial
/// condition (zero, measured past, or estimated: then its x0 joins θ as extra parameters, as
/// the toolbox does for `nlhw1`). Jacobians are exact. Forward AD (`AutoDiffProblem`) is the
/// general route: for simulation focus the duals run through the whole recursion (Ljung 1999,
/// eq. 10.43). An Nlarx model whose nonlinearity has an analytic gradient (SigmoidNet) takes the
/// structured route of models/detail/nlarx_sensitivity.hpp instead: the same Jacobian from one
/// local gradient per sample and the output-lag recursion, several times faster
/// (`EstimateOptions::structured_jacobian`).
/// A diverging simulation (non-finite or beyond 10³·max|y|) makes `evaluate` return false, so
/// the Levenberg–Marquardt step is rejected instead of poisoning the fit.
///
/// Initialisation without luck (deterministic, data-driven; Sjöberg et al. 1995, sec. 7):
/// - Nlarx: the regressor matrix Φ of the measured data (all experiments) and F.initialize(Φ, y),
///   i.e. a regression; then a prediction-focus refinement; then, for simulation focus, the
///   free-run refinement. If the refined predictor diverges in free run, the regression start
///   is tried; if both diverge, an `nlid::Error` names the experiment.
/// - HammersteinWiener: f ≈ identity on the input range (f.initialize(u, u)); the linear block
///   by ARX least squares on (f(u), y) with an offset term, stabilised (unstable poles
///   reflected), refined as an output-error model with offset; h initialised against the linear
///   block's simulated output (h.initialize(x_sim, y)); then the joint refinement of all θ.
///   `initialize = false` starts from the model's current parameters instead — e.g. after
///   `set_linear_block(oe_model)`.

#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/QR>

#include "nlid/analysis/fit.hpp"
#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/core/initial_condition.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/estimation/autodiff.hpp"
#include "nlid/estimation/levenberg_marquardt.hpp"
#include "nlid/linear/detail/least_squares.hpp"
#include "nlid/linear/polynomial.hpp"
#include "nlid/models/detail/estimation_segment.hpp"
#include "nlid/models/detail/initial_state.hpp"
#include "nlid/models/detail/hw_sensitivity.hpp"
#include "nlid/models/detail/nlarx_sensitivity.hpp"
#include "nlid/models/detail/simulation_residuals.hpp"
#include "nlid/models/detail/model_common.hpp"
#include "nlid/models/hammerstein_wiener.hpp"
#include "nlid/models/nlarx.hpp"
#include "nlid/nonlinearities/concepts.hpp"

namespace nlid {

/// Which error the estimator minimises.
enum class Focus {
  prediction,  ///< one-step prediction errors (fast; the model may drift in free run)
  simulation,  ///< free-run simulation errors (what the fit % measures)
};

/// Options of `estimate`.
struct EstimateOptions {
  /// Prediction or simulation focus. Hammerstein–Wiener models (output-error structure) are
  /// always estimated by simulation error; the field is ignored for them.
  Focus focus = Focus::prediction;
  /// Initial condition of each experiment's simulation during simulation-focus estimation.
  /// Unset: `measured` for Nlarx, `zero` for Hammerstein–Wiener. `estimate` adds each
  /// experiment's initial state to the parameters.
  std::optional<InitialCondition> initial_condition;
  /// Data-driven initialisation (see file comment); false: start from the model's parameters.
  bool initialize = true;
  /// Nlarx with simulation focus: iterations of the prediction-focus refinement run first.
  int prediction_iterations = 20;
  /// Hammerstein–Wiener: iterations of the output-error refinement of the linear block during
  /// initialisation.
  int linear_iterations = 50;
  /// Nlarx: number of data-driven starts compared by estimation cost (used when `initialize` is
  /// true and the nonlinearity offers alternative starts, i.e. has
  /// `initialize(X, y, theta, int start)`; SigmoidNet does). Every start runs the prediction
  /// stage and `start_iterations` iterations of the main criterion; the start with the lowest
  /// cost then gets the rest of `solver.max_iterations`, so the main stage of the returned model
  /// never exceeds `solver.max_iterations` in total. 1: the single default start.
  int starts = 1;
  /// Nlarx with `starts` > 1: iterations of the main criterion each start runs before they are
  /// compared (counted against `solver.max_iterations` for the winner).
  int start_iterations = 30;
  /// Nlarx with simulation focus: Jacobian of the free-run errors by the structured sensitivity
  /// recursion (Ljung 1999, eq. 10.43) with the nonlinearity's analytic gradient, when it has
  /// one (`DifferentiableNonlinearity`, e.g. SigmoidNet) and the output lag is static. The
  /// same Jacobian as forward AD through the recursion, to rounding, at a fraction of the cost
  /// (docs/performance.md). HammersteinWiener with static block sizes and a zero initial state:
  /// duals over the input map and linear block only, the output map's chain rule applied per
  /// sample (models/detail/hw_sensitivity.hpp). false: always forward AD.
  bool structured_jacobian = true;
  /// Solver options of the main stage: `max_iterations`, `loss` (robust), `callback`,
  /// `lower_bounds`/`upper_bounds`/`fixed` and `regularization` (sized to the model's
  /// parameters; entries for estimated initial states are added automatically — free, not
  /// penalised), tolerances. `regularization` applies to the prediction stage too. A `fixed`
  /// parameter keeps the value the model has on entry, also when `initialize` is true (the
  /// data-driven start then sets only the free ones).
  LmOptions solver;
  /// Nlarx: receives one line as each stage begins ("start 2 of 4: prediction stage …"), so
  /// that a `solver.callback` printing costs can be read: the prediction stage's costs are of
  /// one-step errors, far below the free-run costs that follow. Empty: silent.
  std::function<void(const std::string&)> progress;
};

namespace detail {

/// One-step prediction residuals of an Nlarx model over several experiments.
template <class M>
class PredictionResiduals {
 public:
  /// The model's static parameter count.
  static constexpr int num_params = M::num_params;

  /// Views the model; owns the segments.
  PredictionResiduals(const M& model, std::vector<EstimationSegment> segments)
      : model_(&model), segs_(std::move(segments)) {
    for (const auto& s : segs_) m_ += s.y.size() - model_->history_length();
  }
  /// The model's parameters.
  [[nodiscard]] int num_parameters() const { return model_->num_parameters(); }
  /// Σ (N − n₀).
  [[nodiscard]] Eigen::Index num_residuals() const { return m_; }

  /// r = ŷ(t|t−1) − y(t), stacked; false if a prediction is not finite.
  template <class T>
  bool residuals(std::span<const T> theta, std::span<T> r) const {
    const Eigen::Index n0 = model_->history_length();
    std::size_t off = 0;
    for (const auto& s : segs_) {
      const Eigen::Index len = s.y.size() - n0;
      const std::span<T> ri = r.subspan(off, static_cast<std::size_t>(len));
      if (!model_->predict(*s.u, s.y, theta, ri)) return false;
      for (Eigen::Index t = 0; t < len; ++t) ri[static_cast<std::size_t>(t)] -= s.y(n0 + t);
      off += static_cast<std::size_t>(len);
    }
    return true;
  }

 private:
  const M* model_;
  std::vector<EstimationSegment> segs_;
  Eigen::Index m_ = 0;
};

/// Output-error residuals of a linear block with an output offset c: x(t) + c − y(t), the
/// block started in steady state for w(0). θ = [θ_L, c].
template <class L>
class LinearStageResiduals {
 public:
  /// Run-time parameter count.
  static constexpr int num_params = Dynamic;

  /// `w`, `y`: per experiment.
  LinearStageResiduals(const L& block, std::vector<Eigen::VectorXd> w, std::vector<Eigen::VectorXd> y, double limit)
      : lin_(&block), w_(std::move(w)), y_(std::move(y)), limit_(limit) {
    for (const auto& v : y_) m_ += v.size();
  }
  /// θ_L and the offset.
  [[nodiscard]] int num_parameters() const { return lin_->num_parameters() + 1; }
  /// All samples.
  [[nodiscard]] Eigen::Index num_residuals() const { return m_; }

  /// r = B/F w + c − y; false on divergence.
  template <class T>
  bool residuals(std::span<const T> theta, std::span<T> r) const {
    const std::span<const T> th = theta.first(static_cast<std::size_t>(lin_->num_parameters()));
    const T& c = theta[static_cast<std::size_t>(lin_->num_parameters())];
    std::vector<T> s(static_cast<std::size_t>(lin_->num_states_runtime()));
    std::size_t off = 0;
    for (std::size_t e = 0; e < w_.size(); ++e) {
      const T w0(w_[e](0));
      if (!lin_->equilibrium_state(w0, th, std::span<T>(s))) std::fill(s.begin(), s.end(), T(0));
      for (Eigen::Index t = 0; t < w_[e].size(); ++t) {
        const T x = lin_->step(std::span<T>(s), T(w_[e](t)), th) + c;
        if (!is_finite_scalar(x) || std::abs(static_cast<double>(value_of(x))) > limit_) return false;
        r[off++] = x - y_[e](t);
      }
    }
    return true;
  }

 private:
  const L* lin_;
  std::vector<Eigen::VectorXd> w_, y_;
  double limit_;
  Eigen::Index m_ = 0;
};

/// Runs LM on an `AutoDiffProblem` of `functor` with static count P, θ as VectorXd.
template <int P, class Functor>
LmSummary solve_functor(Functor functor, Eigen::VectorXd& theta, const LmOptions& options) {
  AutoDiffProblem<Functor> problem(std::move(functor));
  Eigen::Matrix<double, P, 1> th = theta;
  const LmSummary s = solve_least_squares(problem, th, options);
  theta = th;
  return s;
}

/// Runs LM on a `LeastSquaresProblem` with static count P, θ as VectorXd.
template <int P, class Problem>
LmSummary solve_problem(const Problem& problem, Eigen::VectorXd& theta, const LmOptions& options) {
  Eigen::Matrix<double, P, 1> th = theta;
  const LmSummary s = solve_least_squares(problem, th, options);
  theta = th;
  return s;
}

/// Solver options extended by `extra` free parameters (initial states): no bounds, not fixed,
/// unit `state_scale` where parameter units are given. Throws `nlid::Error` if bounds/fixed are
/// not sized to the model's `np` parameters.
inline LmOptions extend_options(LmOptions o, int np, int extra, const std::vector<std::string>& names,
                                double state_scale = 1.0) {
  auto check = [np](Eigen::Index n, const char* what) {
    require(n == 0 || n == np,
            std::string(what) + " has " + std::to_string(n) + " entries; the model has " + std::to_string(np) +
                " parameters",
            at_parameter(what));
  };
  check(o.lower_bounds.size(), "lower_bounds");
  check(o.upper_bounds.size(), "upper_bounds");
  check(static_cast<Eigen::Index>(o.fixed.size()), "fixed");
  check(o.regularization.weights.size(), "regularization.weights");
  check(o.regularization.nominal.size(), "regularization.nominal");
  check(o.parameter_scale.size(), "parameter_scale");
  if (o.parameter_scale.size() > 0) {
    o.parameter_scale.conservativeResize(np + extra);
    o.parameter_scale.tail(extra).setConstant(state_scale);
  }
  // Appended unknowns (initial states) are not penalised: weight 0.
  if (extra > 0 && o.regularization.lambda > 0) {
    if (o.regularization.weights.size() == 0) o.regularization.weights = Eigen::VectorXd::Ones(np);
    o.regularization.weights.conservativeResize(np + extra);
    o.regularization.weights.tail(extra).setZero();
  }
  if (o.regularization.nominal.size() > 0) {
    o.regularization.nominal.conservativeResize(np + extra);
    o.regularization.nominal.tail(extra).setZero();
  }
  const double inf = std::numeric_limits<double>::infinity();
  if (o.lower_bounds.size() > 0) {
    o.lower_bounds.conservativeResize(np + extra);
    o.lower_bounds.tail(extra).setConstant(-inf);
  }
  if (o.upper_bounds.size() > 0) {
    o.upper_bounds.conservativeResize(np + extra);
    o.upper_bounds.tail(extra).setConstant(inf);
  }
  if (!o.fixed.empty()) o.fixed.resize(static_cast<std::size_t>(np + extra), false);
  if (o.parameter_names.empty()) o.parameter_names = names;
  return o;
}

/// Refuses EstimateOptions counts that mean nothing (negative iterations, no start), naming the
/// option; the solver's own options are checked by the solver.
inline void check_estimate_options(const EstimateOptions& o) {
  auto at_least = [](int v, int lo, const char* name) {
    require(v >= lo, std::string("EstimateOptions::") + name + " must be >= " + std::to_string(lo) + ", got " +
                         std::to_string(v),
            at_parameter(name));
  };
  at_least(o.prediction_iterations, 0, "prediction_iterations");
  at_least(o.linear_iterations, 0, "linear_iterations");
  at_least(o.starts, 1, "starts");
  at_least(o.start_iterations, 0, "start_iterations");
}

/// Puts the parameters marked `fixed` back to the values `entry` had: a data-driven start must
/// not replace what the caller holds.
inline void hold_fixed(const std::vector<bool>& fixed, const Eigen::VectorXd& entry, Eigen::VectorXd& theta) {
  if (static_cast<Eigen::Index>(fixed.size()) != theta.size() || entry.size() != theta.size()) return;
  for (Eigen::Index k = 0; k < theta.size(); ++k)
    if (fixed[static_cast<std::size_t>(k)]) theta[k] = entry[k];
}

/// Seconds since `t0`.
inline double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// Fit (%) of one estimation experiment for the report: −∞ for a diverged simulation, NaN where
/// the normalised fit is undefined because the measured output is constant (a rest record may
/// be part of the estimation data; the estimate must not be lost for its report line, and
/// `describe()` prints "undefined"), else `fit_percent`.
inline double estimation_fit(const Eigen::VectorXd& y, const Eigen::VectorXd& yhat, bool ok) {
  if (!ok) return -std::numeric_limits<double>::infinity();
  const double mean = y.mean();
  if (negligible_spread((y.array() - mean).square().sum(), mean, y.size())) return std::numeric_limits<double>::quiet_NaN();
  return fit_percent(y, yhat);
}

/// Entries of x0 that estimation frees: Nlarx the Ly past outputs, HW every block state.
template <class M>
std::vector<int> model_free_states(const M& model) {
  std::vector<int> free;
  if constexpr (requires { model.output_lag(); }) {
    for (int k = 0; k < model.output_lag(); ++k) free.push_back(k);
  } else {
    for (int k = 0; k < model.state_dimension(); ++k) free.push_back(k);
  }
  return free;
}

/// Appends each experiment's estimated initial-state entries (those `model_free_states` frees,
/// read from the segments' x0) to θ (holding the model's parameters on entry) and their names,
/// and sets each segment's `free_offset`; returns the freed entries. One layout of the unknowns
/// for the simulation stage and for `parameter_uncertainty`.
template <class M>
std::vector<int> append_initial_states(const M& model, std::vector<EstimationSegment>& segs, Eigen::VectorXd& theta,
                                       std::vector<std::string>& names) {
  const auto np = theta.size();
  std::vector<int> free = model_free_states(model);
  theta.conservativeResize(np + static_cast<Eigen::Index>(free.size() * segs.size()));
  int off = 0;
  for (std::size_t e = 0; e < segs.size(); ++e) {
    segs[e].free_offset = off;
    for (std::size_t k = 0; k < free.size(); ++k) {
      theta(np + off + static_cast<Eigen::Index>(k)) = segs[e].x0(free[k]);
      names.push_back("x0[" + std::to_string(e) + "][" + std::to_string(free[k]) + "]");
    }
    off += static_cast<int>(free.size());
  }
  return free;
}

/// Main simulation-focus stage shared by both model kinds: builds the functor, extends θ by the
/// estimated initial states, solves, and writes the states back into the segments.
template <class M>
LmSummary simulation_stage(const M& model, std::vector<EstimationSegment>& segs, InitialCondition ic,
                           Eigen::VectorXd& theta, const LmOptions& solver, double limit,
                           bool structured_jacobian = true, double state_scale = 1.0) {
  const int np = model.num_parameters();
  std::vector<int> free;
  std::vector<std::string> names = model.parameter_names();
  Eigen::VectorXd full = theta;
  if (ic == InitialCondition::estimate) free = append_initial_states(model, segs, full, names);
  const LmOptions o = extend_options(solver, np, static_cast<int>(full.size()) - np, names, state_scale);
  LmSummary summary;
  bool done = false;
  if constexpr (HasStructuredSimulationJacobian<M>) {
    if (structured_jacobian && ic != InitialCondition::equilibrium) {
      if (ic == InitialCondition::estimate || M::num_params == Dynamic) {
        summary = solve_problem<Dynamic>(NlarxSimulationProblem<M, Dynamic>(model, segs, free, ic, limit), full, o);
      } else {
        summary = solve_problem<M::num_params>(NlarxSimulationProblem<M, M::num_params>(model, segs, free, ic, limit), full, o);
      }
      done = true;
    }
  }
  if constexpr (HasStructuredHwJacobian<M>) {
    if (structured_jacobian && ic == InitialCondition::zero) {
      summary = solve_problem<M::num_params>(HwSimulationProblem<M, M::num_params>(model, segs, ic, limit), full, o);
      done = true;
    }
  }
  if (!done) {
    if (ic == InitialCondition::estimate || M::num_params == Dynamic) {
      summary = solve_functor<Dynamic>(SimulationResiduals<M, Dynamic>(model, segs, free, ic, limit), full, o);
    } else {
      summary = solve_functor<M::num_params>(SimulationResiduals<M, M::num_params>(model, segs, free, ic, limit), full, o);
    }
  }
  theta = full.head(np);
  if (ic == InitialCondition::estimate) {
    for (auto& s : segs)
      for (std::size_t k = 0; k < free.size(); ++k) s.x0(free[k]) = full(np + s.free_offset + static_cast<Eigen::Index>(k));
  }
  // "Stalled at the start" alone leaves the user guessing. A gradient out of all proportion to
  // the cost (the study's nlarx2: 1.6e22 against 7461) means the free run's output changes with
  // θ faster than any step can follow — the recursion amplifies a parameter change without bound
  // (confirmed there by finite differences: a change of 1e-10 moves the output by 0.2°) — not
  // that the start is a minimum.
  if (summary.stalled_at_start() && summary.detail.empty() && std::isfinite(summary.final_gradient_norm)) {
    const double size = std::max(1.0, full.cwiseAbs().maxCoeff());
    if (summary.final_gradient_norm * size > 1e8 * std::max(summary.final_cost, 1e-300)) {
      summary.detail = "The simulation error's gradient (" + format_g(summary.final_gradient_norm, 3) +
                       ") is out of all proportion to its cost (" + format_g(summary.final_cost, 4) +
                       "): the free-run output changes with the parameters faster than any step can follow "
                       "(a recursion that amplifies parameter changes, e.g. ringing or switching at a limit "
                       "such as a stop), so simulation focus cannot improve this model; the start was kept (for a "
                       "nonlinear ARX model, its prediction-focus estimate).";
    }
  }
  return summary;
}

/// Simulates one segment with θ (double) and its x0; false if it diverges.
template <class M>
bool simulate_segment(const M& model, const EstimationSegment& s, const Eigen::VectorXd& theta, InitialCondition ic,
                      Eigen::VectorXd& yhat, double limit = std::numeric_limits<double>::infinity()) {
  const Eigen::Index len = s.y.size() - s.start;
  yhat.resize(s.y.size());
  yhat.head(s.start) = s.y.head(s.start);
  Eigen::VectorXd x0 = s.x0;
  if (ic == InitialCondition::equilibrium) {
    if constexpr (requires { model.template equilibrium_state<double>(0.0, as_const_span(theta)); }) {
      x0 = model.template equilibrium_state<double>((*s.u)(0, 0), as_const_span(theta));
    }
  }
  return model.simulate(s.u->bottomRows(len), as_const_span(theta), as_const_span(x0),
                        std::span<double>(yhat.data() + s.start, static_cast<std::size_t>(len)), limit);
}

/// ARX least squares with offset for a transfer-function block: y(t) = −Σ fᵢ y(t−i) +
/// Σ bⱼ w(t−nk−j+1) + c over all experiments; F stabilised by reflecting unstable poles.
template <class L>
void arx_initialize(const L& lin, const std::vector<Eigen::VectorXd>& w, const std::vector<Eigen::VectorXd>& y,
                    std::span<double> theta_l) {
  const int nb = lin.nb(), nf = lin.nf(), nk = lin.nk();
  const int n0 = std::max(nf, nk + nb - 1);
  Eigen::Index rows = 0;
  for (const auto& v : y) rows += std::max<Eigen::Index>(0, v.size() - n0);
  require(rows > nb + nf + 1, "too few samples to initialise the linear block", at_parameter("data"));
  Eigen::MatrixXd a(rows, nb + nf + 1);
  Eigen::VectorXd b(rows);
  Eigen::Index i = 0;
  for (std::size_t e = 0; e < y.size(); ++e) {
    for (Eigen::Index t = n0; t < y[e].size(); ++t, ++i) {
      for (int j = 0; j < nb; ++j) a(i, j) = w[e](t - nk - j);
      for (int k = 1; k <= nf; ++k) a(i, nb + k - 1) = -y[e](t - k);
      a(i, nb + nf) = 1.0;
      b(i) = y[e](t);
    }
  }
  // Columns in the data's units (lagged w, lagged y, 1) can lie further apart than a plain QR's
  // rank tolerance (1e14: the w columns were judged zero and B came out 0): equilibrated solve.
  const Eigen::VectorXd sol = solve_equilibrated(std::move(a), b);
  Eigen::VectorXd f(nf + 1);
  f(0) = 1.0;
  f.tail(nf) = sol.segment(nb, nf);
  if (nf > 0 && !is_stable_polynomial(f)) f = reflect_unstable(f);
  for (int j = 0; j < nb; ++j) theta_l[static_cast<std::size_t>(j)] = sol(j);
  for (int k = 0; k < nf; ++k) theta_l[static_cast<std::size_t>(nb + k)] = f(k + 1);
}

/// Checks the data set, adopts its sample time and channel names.
template <class M>
void adopt_data(M& model, const Dataset& data, int history, const char* kind) {
  require(data.size() > 0, "the estimation data set has no experiments", at_parameter("data"));
  if (model.ts() == 0.0) model.set_ts(data.ts());
  for (std::size_t i = 0; i < data.size(); ++i) {
    check_experiment(data[i], static_cast<long>(i), model.num_inputs(), history, model.ts(), kind);
    require_complete(data[i], static_cast<long>(i));
    data[i].require_estimable_scale(std::string(kind) + " estimation", static_cast<long>(i));
  }
}

}  // namespace detail

/// Estimates a nonlinear ARX model on `data` (one or more experiments; residuals stacked).
/// `model` supplies the structure (and the starting θ when `options.initialize` is false).
/// Returns the model with estimated θ, sample time, channel names and `report()` (the argument
/// is a copy and stays as it was: `m = estimate(m, data)`; a grey box is estimated in place).
/// Throws `nlid::Error` naming the experiment for data that do not fit the model, or when a
/// simulation-focus estimation cannot start because every start diverges.
template <Regressor R, Nonlinearity F>
[[nodiscard]] Nlarx<R, F> estimate(Nlarx<R, F> model, const Dataset& data, const EstimateOptions& options = {}) {
  using M = Nlarx<R, F>;
  const auto t0 = std::chrono::steady_clock::now();
  detail::check_estimate_options(options);
  detail::adopt_data(model, data, model.history_length(), "nonlinear ARX");
  detail::require_enough_samples("nonlinear ARX",
                                 model.num_parameters() - detail::count_fixed(options.solver.fixed, model.num_parameters()),
                                 data, model.history_length());
  model.set_channel_names(data[0].input_names(), data[0].output_names().empty() ? "y1" : data[0].output_names()[0]);
  const InitialCondition ic = options.initial_condition.value_or(InitialCondition::measured);
  if (options.focus == Focus::simulation) {
    require(ic != InitialCondition::equilibrium,
            "equilibrium initial conditions are not supported during Nlarx estimation; use zero, measured or estimate",
            at_parameter("initial_condition"));
  }
  const int n0 = model.history_length();
  std::vector<detail::EstimationSegment> segs(data.size());
  Eigen::VectorXd y_all(data.total_samples());
  {
    Eigen::Index k = 0;
    for (std::size_t i = 0; i < data.size(); ++i) {
      segs[i].u = &data[i].u();
      segs[i].y = data[i].y().col(0);
      y_all.segment(k, segs[i].y.size()) = segs[i].y;
      k += segs[i].y.size();
    }
  }
  const double limit = detail::divergence_limit(y_all);

  Eigen::VectorXd theta = model.parameters();
  const Eigen::VectorXd theta_entry = theta;
  Eigen::MatrixXd x;
  Eigen::VectorXd yr;
  if (options.initialize) {
    Eigen::Index rows = 0;
    for (const auto& s : segs) rows += s.y.size() - n0;
    x.resize(rows, model.regressors().size());
    yr.resize(rows);
    Eigen::Index k = 0;
    for (std::size_t i = 0; i < segs.size(); ++i) {
      const Eigen::Index len = segs[i].y.size() - n0;
      x.middleRows(k, len) = regressor_matrix(model.regressors(), *segs[i].u, segs[i].y, detail::experiment_location(static_cast<long>(i)));
      yr.segment(k, len) = segs[i].y.tail(len);
      k += len;
    }
    model.nonlinearity().initialize(x, yr, detail::as_span(theta));
    detail::hold_fixed(options.solver.fixed, theta_entry, theta);
  }

  EstimationReport report;
  LmSummary summary;
  int iterations = 0;
  // One start: the prediction stage from `th` (the whole estimation for prediction focus), then
  // for simulation focus the free-run stage with `main_iterations`; `fallback` is the start to
  // use if the refined predictor diverges in free run. Updates th, segs, summary, iterations.
  std::string start_label;  // "start k of n: " while several starts run
  auto say = [&](const std::string& what) {
    if (options.progress) options.progress(start_label + what);
  };
  auto run_start = [&](Eigen::VectorXd& th, const Eigen::VectorXd& fallback, int main_iterations) {
    if (options.focus == Focus::prediction || options.initialize) {
      say(options.focus == Focus::simulation ? "prediction stage (one-step errors, the free run's start)"
                                             : "prediction stage");
      LmOptions o = detail::extend_options(options.solver, model.num_parameters(), 0, model.parameter_names());
      if (options.focus == Focus::simulation) o.max_iterations = std::min(o.max_iterations, options.prediction_iterations);
      else o.max_iterations = main_iterations;
      summary = detail::solve_functor<M::num_params>(detail::PredictionResiduals<M>(model, segs), th, o);
      iterations += summary.iterations;
    }
    if (options.focus != Focus::simulation) return;
    // Per-experiment start; fall back to the regression start if the refined predictor diverges.
    auto starts_ok = [&](const Eigen::VectorXd& t, long* bad) {
      for (std::size_t i = 0; i < segs.size(); ++i) {
        auto& s = segs[i];
        s.start = ic == InitialCondition::measured ? n0 : 0;
        if (ic == InitialCondition::measured) {
          s.x0 = model.measured_state(*s.u, s.y, n0);
        } else if (ic == InitialCondition::estimate) {
          s.x0 = model.held_state(s.y(0), s.u->row(0));
        } else {
          s.x0.resize(0);
        }
        Eigen::VectorXd yh;
        if (!detail::simulate_segment(model, s, t, ic, yh, limit)) {
          *bad = static_cast<long>(i);
          return false;
        }
      }
      return true;
    };
    long bad = -1;
    if (!starts_ok(th, &bad)) {
      th = fallback;
      if (!starts_ok(th, &bad)) {
        throw Error("simulation-focus estimation cannot start: the initial model's simulation of " +
                        detail::experiment_label(data[static_cast<std::size_t>(bad)], bad) +
                        " diverges (try prediction focus, other orders or fewer units)",
                    detail::experiment_location(bad));
      }
    }
    LmOptions o = options.solver;
    o.max_iterations = main_iterations;
    say("simulation stage (free-run errors)");
    summary = detail::simulation_stage(model, segs, ic, th, o, limit, options.structured_jacobian);
    iterations += summary.iterations;
  };

  bool multi = false;
  if constexpr (requires(F& f, const Eigen::MatrixXd& X, const Eigen::VectorXd& Y, std::span<double> t) { f.initialize(X, Y, t, 1); }) {
    multi = options.initialize && options.starts > 1;
  }
  if (!multi) {
    const Eigen::VectorXd theta_regression = theta;
    run_start(theta, theta_regression, options.solver.max_iterations);
  } else {
    if constexpr (requires(F& f, const Eigen::MatrixXd& X, const Eigen::VectorXd& Y, std::span<double> t) { f.initialize(X, Y, t, 1); }) {
      // Several data-driven starts, each refined by `start_iterations` of the main criterion;
      // the lowest cost wins and continues (Sjöberg et al. 1995, sec. 7: the criterion, not luck,
      // decides between local minima). Deterministic: start k is the nonlinearity's variant k.
      const int pilot = std::min(std::max(options.start_iterations, 0), options.solver.max_iterations);
      double best_cost = std::numeric_limits<double>::infinity();
      Eigen::VectorXd best_theta;
      std::vector<detail::EstimationSegment> best_segs;
      int best_iterations = 0;
      LmSummary best_summary;
      std::optional<Error> first_error;
      std::vector<double> start_costs;
      int chosen = -1;
      for (int k = 0; k < options.starts; ++k) {
        start_costs.push_back(std::numeric_limits<double>::infinity());
        Eigen::VectorXd th = theta;
        if (k > 0) {
          model.nonlinearity().initialize(x, yr, detail::as_span(th), k);
          detail::hold_fixed(options.solver.fixed, theta_entry, th);
        }
        start_label = "start " + std::to_string(k + 1) + " of " + std::to_string(options.starts) + ": ";
        const Eigen::VectorXd th0 = th;
        iterations = 0;
        try {
          run_start(th, th0, pilot);
        } catch (const Error& e) {  // this start cannot run; others may
          if (!first_error) first_error = e;
          continue;
        }
        if (std::isfinite(summary.final_cost)) start_costs.back() = summary.final_cost;
        if (std::isfinite(summary.final_cost) && summary.final_cost < best_cost) {
          chosen = k;
          best_cost = summary.final_cost;
          best_theta = th;
          best_segs = segs;
          best_iterations = iterations;
          best_summary = summary;
        }
      }
      if (!std::isfinite(best_cost)) {
        if (first_error) throw *first_error;
        throw Error("no start of the estimation gave a finite cost", at_parameter("starts"));
      }
      theta = best_theta;
      segs = std::move(best_segs);
      iterations = best_iterations;
      summary = best_summary;
      const int rest = options.solver.max_iterations - pilot;
      start_label.clear();
      if (rest > 0)
        say("start " + std::to_string(chosen + 1) + " has the lowest cost (" + detail::format_g(best_cost, 4) +
            "): it continues for " + std::to_string(rest) + " iteration(s)");
      if (rest > 0) {
        LmOptions o = detail::extend_options(options.solver, model.num_parameters(), 0, model.parameter_names());
        o.max_iterations = rest;
        if (options.focus == Focus::simulation) {
          LmOptions so = options.solver;
          so.max_iterations = rest;
          const LmSummary cont = detail::simulation_stage(model, segs, ic, theta, so, limit, options.structured_jacobian);
          const double c0 = summary.initial_cost;
          summary = cont;
          summary.initial_cost = c0;
          iterations += cont.iterations;
        } else {
          const LmSummary cont = detail::solve_functor<M::num_params>(detail::PredictionResiduals<M>(model, segs), theta, o);
          const double c0 = summary.initial_cost;
          summary = cont;
          summary.initial_cost = c0;
          iterations += cont.iterations;
        }
      }
      report.start_costs = std::move(start_costs);
      report.chosen_start = chosen;
    }
  }
  model.set_parameters(theta);

  report.estimated = true;
  report.focus = options.focus == Focus::simulation ? "simulation" : "prediction";
  const InitialCondition fit_ic = options.focus == Focus::simulation ? ic : InitialCondition::measured;
  report.initial_condition = to_string(fit_ic);
  report.iterations = iterations;
  report.initial_cost = summary.initial_cost;
  report.final_cost = summary.final_cost;
  report.status = summary.message();
  for (std::size_t i = 0; i < segs.size(); ++i) {
    auto& s = segs[i];
    if (options.focus == Focus::prediction) {
      s.start = n0;
      s.x0 = model.measured_state(*s.u, s.y, n0);
    }
    Eigen::VectorXd yh;
    const bool ok = detail::simulate_segment(model, s, theta, fit_ic, yh);
    report.data_names.push_back(data[i].name());
    report.fit_percent.push_back(detail::estimation_fit(s.y, yh, ok));
    if (fit_ic == InitialCondition::estimate) report.initial_states.push_back(s.x0);
  }
  report.seconds = detail::seconds_since(t0);
  model.set_report(std::move(report));
  return model;
}

namespace detail {

// RMS of a signal as its unit of size (1 for an all-zero or non-finite one).
inline double signal_unit(const Eigen::VectorXd& v) {
  const double r = v.size() ? std::sqrt(v.squaredNorm() / static_cast<double>(v.size())) : 0.0;
  return std::isfinite(r) && r > 0 ? r : 1.0;
}

// Each parameter's unit in a Hammerstein–Wiener model initialised as `estimate` does it: f maps u
// to a signal in u's units (it starts as the identity), the block maps that to one in y's units
// (its first fit is to y), h maps that to y. Empty if a component does not know its units.
template <class Model>
Eigen::VectorXd hw_parameter_scales(const Model& model, const Eigen::VectorXd& u, const Eigen::VectorXd& y) {
  const double su = signal_unit(u), sy = signal_unit(y);
  const auto pf = static_cast<std::size_t>(model.input_nonlinearity().num_parameters());
  const auto pl = static_cast<std::size_t>(model.linear_block().num_parameters());
  const auto ph = static_cast<std::size_t>(model.output_nonlinearity().num_parameters());
  Eigen::VectorXd s = Eigen::VectorXd::Ones(static_cast<Eigen::Index>(pf + pl + ph));
  const std::span<double> all(s.data(), pf + pl + ph);
  if (!parameter_scales_of(model.input_nonlinearity(), su, su, all.subspan(0, pf)) ||
      !parameter_scales_of(model.linear_block(), su, sy, all.subspan(pf, pl)) ||
      !parameter_scales_of(model.output_nonlinearity(), sy, sy, all.subspan(pf + pl, ph)))
    return {};
  return s;
}

}  // namespace detail

/// Estimates a Hammerstein–Wiener model on `data` by simulation error (see file comment for
/// the initialisation). Returns the model with θ, sample time, channel names and `report()`.
/// Throws `nlid::Error` naming the experiment for data that do not fit the model, and for
/// `InitialCondition::measured` (not defined for a block state).
template <ScalarNonlinearity In, LinearBlock L, ScalarNonlinearity Out>
[[nodiscard]] HammersteinWiener<In, L, Out> estimate(HammersteinWiener<In, L, Out> model, const Dataset& data,
                                       const EstimateOptions& options = {}) {
  const auto t0 = std::chrono::steady_clock::now();
  detail::check_estimate_options(options);
  detail::adopt_data(model, data, 0, "Hammerstein-Wiener");
  detail::require_enough_samples("Hammerstein-Wiener",
                                 model.num_parameters() - detail::count_fixed(options.solver.fixed, model.num_parameters()),
                                 data, 0);
  detail::require_input_reaches_output("Hammerstein-Wiener", detail::block_input_delay(model.linear_block()), data);
  model.set_channel_names(data[0].input_names().empty() ? "u1" : data[0].input_names()[0],
                          data[0].output_names().empty() ? "y1" : data[0].output_names()[0]);
  const InitialCondition ic = options.initial_condition.value_or(InitialCondition::zero);
  require(ic != InitialCondition::measured,
          "InitialCondition::measured is not defined for a Hammerstein-Wiener model; use zero, equilibrium or estimate",
          at_parameter("initial_condition"));
  std::vector<detail::EstimationSegment> segs(data.size());
  Eigen::VectorXd y_all(data.total_samples()), u_all(data.total_samples());
  {
    Eigen::Index k = 0;
    for (std::size_t i = 0; i < data.size(); ++i) {
      segs[i].u = &data[i].u();
      segs[i].y = data[i].y().col(0);
      y_all.segment(k, segs[i].y.size()) = segs[i].y;
      u_all.segment(k, segs[i].y.size()) = data[i].u().col(0);
      k += segs[i].y.size();
    }
  }
  const double limit = detail::divergence_limit(y_all);
  Eigen::VectorXd theta = model.parameters();
  const Eigen::VectorXd theta_entry = theta;
  const auto pf = static_cast<std::size_t>(model.input_nonlinearity().num_parameters());
  const auto pl = static_cast<std::size_t>(model.linear_block().num_parameters());
  const auto ph = static_cast<std::size_t>(model.output_nonlinearity().num_parameters());
  const std::span<double> th_f(theta.data(), pf), th_l(theta.data() + pf, pl), th_h(theta.data() + pf + pl, ph);
  int iterations = 0;

  if (options.initialize) {
    // f ≈ identity on the input range: the linear block then sees (a scaled copy of) u.
    model.input_nonlinearity().initialize(Eigen::MatrixXd(u_all), u_all, th_f);
    std::vector<Eigen::VectorXd> w(segs.size()), ys(segs.size());
    for (std::size_t i = 0; i < segs.size(); ++i) {
      w[i].resize(segs[i].y.size());
      for (Eigen::Index t = 0; t < w[i].size(); ++t) {
        const double ut = (*segs[i].u)(t, 0);
        w[i](t) = model.input_nonlinearity()(std::span<const double>(&ut, 1), std::span<const double>(th_f));
      }
      ys[i] = segs[i].y;
    }
    const auto& lin = model.linear_block();
    if constexpr (requires { lin.nb(); lin.nf(); lin.nk(); }) detail::arx_initialize(lin, w, ys, th_l);
    // Output-error refinement of the linear block (with an offset the output map will absorb).
    Eigen::VectorXd lt(static_cast<Eigen::Index>(pl) + 1);
    for (std::size_t j = 0; j < pl; ++j) lt(static_cast<Eigen::Index>(j)) = th_l[j];
    // Offset start: the mean output minus the block's mean steady-state response.
    double gain = 0.0;
    if constexpr (requires { lin.dc_gain(std::span<const double>(th_l)); }) gain = lin.dc_gain(std::span<const double>(th_l));
    double w_sum = 0.0;
    for (const auto& v : w) w_sum += v.sum();
    lt(static_cast<Eigen::Index>(pl)) = y_all.mean() - gain * w_sum / static_cast<double>(y_all.size());
    detail::LinearStageResiduals<L> lf(lin, w, ys, limit);
    Eigen::VectorXd r(lf.num_residuals());
    if (options.linear_iterations > 0 && lf.residuals(detail::as_const_span(lt), detail::as_span(r))) {
      LmOptions o;
      o.max_iterations = options.linear_iterations;
      iterations += detail::solve_functor<Dynamic>(std::move(lf), lt, o).iterations;
      for (std::size_t j = 0; j < pl; ++j) th_l[j] = lt(static_cast<Eigen::Index>(j));
    }
    // h against the linear block's simulated output, started as the estimation will start.
    Eigen::VectorXd x_all(y_all.size());
    Eigen::Index k = 0;
    for (std::size_t i = 0; i < segs.size(); ++i) {
      std::vector<double> s(static_cast<std::size_t>(lin.num_states_runtime()), 0.0);
      if (ic != InitialCondition::zero) lin.equilibrium_state(w[i](0), std::span<const double>(th_l), std::span<double>(s));
      for (Eigen::Index t = 0; t < w[i].size(); ++t) x_all(k++) = lin.step(std::span<double>(s), w[i](t), std::span<const double>(th_l));
    }
    model.output_nonlinearity().initialize(Eigen::MatrixXd(x_all), y_all, th_h);
    detail::hold_fixed(options.solver.fixed, theta_entry, theta);
  }

  for (auto& s : segs) {
    s.start = 0;
    if (ic == InitialCondition::estimate) {
      s.x0 = model.template equilibrium_state<double>((*s.u)(0, 0), detail::as_const_span(theta));
    } else {
      s.x0.resize(0);
    }
  }
  for (std::size_t i = 0; i < segs.size(); ++i) {
    Eigen::VectorXd yh;
    if (!detail::simulate_segment(model, segs[i], theta, ic, yh, limit)) {
      throw Error("Hammerstein-Wiener estimation cannot start: the initial model's simulation of " +
                      detail::experiment_label(data[i], static_cast<long>(i)) + " diverges",
                  detail::experiment_location(static_cast<long>(i)));
    }
  }
  // Uniform (Levenberg) damping by default: the maps' parameters in sparsely visited parts of the
  // signal range have small Jacobian columns, and a unit-invariant scaling lets them take the
  // large steps the data barely determine; uniform damping keeps them near their data-driven
  // start. Lower final costs in fewer iterations on every Hammerstein-Wiener problem measured
  // (docs/estimation.md).
  // Uniform damping compares parameters in their own units, so it is applied to θ_k/s_k with s_k
  // the unit each parameter has in the data's units (a breakpoint in input units, a value in
  // output units): the same data in degrees or radians, volts or millivolts, then give the
  // same model. Maps that do not know their units (the networks) leave θ unscaled.
  LmOptions solver = options.solver;
  if (solver.scaling == LmScaling::automatic) {
    solver.scaling = LmScaling::levenberg;
    if (solver.parameter_scale.size() == 0) solver.parameter_scale = detail::hw_parameter_scales(model, u_all, y_all);
  }
  // The block's states are in y's units like its output (see hw_parameter_scales).
  const LmSummary summary = detail::simulation_stage(model, segs, ic, theta, solver, limit, options.structured_jacobian,
                                                     detail::signal_unit(y_all));
  iterations += summary.iterations;
  model.set_parameters(theta);

  EstimationReport report;
  report.estimated = true;
  report.focus = "simulation";
  report.initial_condition = to_string(ic);
  report.iterations = iterations;
  report.initial_cost = summary.initial_cost;
  report.final_cost = summary.final_cost;
  report.status = summary.message();
  for (std::size_t i = 0; i < segs.size(); ++i) {
    Eigen::VectorXd yh;
    const bool ok = detail::simulate_segment(model, segs[i], theta, ic, yh);
    report.data_names.push_back(data[i].name());
    report.fit_percent.push_back(detail::estimation_fit(segs[i].y, yh, ok));
    if (ic == InitialCondition::estimate) report.initial_states.push_back(segs[i].x0);
  }
  report.seconds = detail::seconds_since(t0);
  model.set_report(std::move(report));
  return model;
}

}  // namespace nlid
