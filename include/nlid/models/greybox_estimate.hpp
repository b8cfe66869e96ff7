#pragma once
/// @file
/// `estimate(GreyBox<P>&, const Dataset&)`: grey-box estimation by simulation error, with
/// data-driven starting values, multi-start, and a per-experiment fit report.
///
/// What happens (each step is the answer to a way such estimations go wrong in practice):
///
///  1. Scale. Unless the model was initialised already, `GreyBox::initialize(data)` reads
///     levels, stop positions, gains and time constants off the data (greybox_init.hpp), so the
///     search starts in the right decade whatever the units of the record.
///  2. Unknowns. θ = [p; x₀⁽¹⁾; …; x₀⁽ᴱ⁾] (greybox_problem.hpp): the physical parameters with their
///     bounds and fixed flags, and one initial state per experiment (policy
///     `InitialCondition::estimate`, the default; `zero` and `equilibrium` are also accepted).
///  3. Search. Multi-start Levenberg–Marquardt (estimation/multi_start.hpp): quasi-random
///     candidates over each parameter's range — log-spaced for positive scale parameters — are
///     screened by cost; the best are refined in parallel; the lowest cost wins. The summary
///     reports how many starts agree with the best (within 1 %): the evidence that the optimum is
///     not an accident of the starting point.
///  4. Result. The model's parameters are updated, the initial states stored, and the fit
///     100·(1 − ‖y − ŷ‖/‖y − ȳ‖) of the free-run simulation is reported per experiment and output
///     (Ljung 1999, Sec. 16.6; the measure of the throttle study).
///
/// Criterion weights: each output's residuals are divided by that output's standard deviation,
/// so the reported cost is dimensionless (½ Σ normalised squared errors).

#include <chrono>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/core/initial_condition.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/estimation/levenberg_marquardt.hpp"
#include "nlid/estimation/multi_start.hpp"
#include "nlid/estimation/uncertainty.hpp"
#include "nlid/models/greybox.hpp"
#include "nlid/models/greybox_problem.hpp"

namespace nlid {

/// Settings of grey-box estimation.
struct GreyBoxEstimateOptions {
  /// How each experiment's simulation starts: `estimate` (x₀ per experiment is an unknown),
  /// `zero`, or `equilibrium` (for the first input sample, differentiated exactly).
  InitialCondition initial_condition = InitialCondition::estimate;
  /// Run `GreyBox::initialize(data)` first if the model has not been initialised yet.
  bool initialize_from_data = true;
  /// Multi-start settings. `num_starts = 1, num_candidates = 1` is a single LM run from the
  /// model's current values. The search box, log spacing, bounds, fixed flags, parameter names
  /// and the candidate hook are filled in from the model; set only counts, threads, tolerances
  /// and `lm.max_iterations` / tolerances / `lm.regularization` here (the last sized to the
  /// model's parameters and in their own units; initial states are not penalised). An empty
  /// `regularization.nominal` is the model's values at the start of the estimation — the
  /// physical guess, after `initialize` — not zero as for black-box models: pulling a stiffness
  /// of 10⁵ towards 0 means nothing physically. Give zeros explicitly for a pull towards zero.
  MultiStartOptions multi_start = default_multi_start();

  /// Defaults: 24 candidates screened, 6 refined, LM up to 100 iterations.
  static MultiStartOptions default_multi_start() {
    MultiStartOptions o;
    o.num_candidates = 24;
    o.num_starts = 6;
    o.lm.max_iterations = 100;
    o.lm.function_tolerance = 1e-9;
    return o;
  }
};

/// Outcome of grey-box estimation.
struct GreyBoxEstimate {
  Eigen::VectorXd parameters;                 ///< estimated physical parameters (also in the model)
  std::vector<std::string> parameter_names;   ///< their names
  std::vector<Eigen::VectorXd> initial_states;  ///< x₀ per experiment (as used)
  Eigen::MatrixXd fit;                        ///< fit % per experiment (row) and output (column)
  std::vector<std::string> experiment_names;  ///< row labels of `fit`
  double cost = 0.0;                          ///< final cost ½ Σ (w_j ε)²
  LmSummary summary;                          ///< LM summary of the winning start
  MultiStartSummary multi_start;              ///< all starts
  double seconds = 0.0;                       ///< wall-clock time including initialisation
  /// Standard deviations and correlations of all unknowns (parameters first, then the initial
  /// states), from the residuals of the estimate (estimation/uncertainty.hpp); `report()` lists
  /// the physical parameters with ±1σ.
  ParameterUncertainty uncertainty;

  /// Human-readable report: parameters with ±1σ, fit per experiment, multi-start agreement.
  [[nodiscard]] std::string report() const {
    auto num = [](double v) { return detail::format_g(v); };
    std::string s = "Grey-box estimation: cost " + num(cost) + ", " + num(seconds) + " s\n";
    if (uncertainty.theta.size() >= parameters.size() && parameters.size() > 0) {
      s += uncertainty.report(static_cast<int>(parameters.size()));
    } else {
      for (Eigen::Index i = 0; i < parameters.size(); ++i) {
        s += "  " + parameter_names[static_cast<std::size_t>(i)] + " = " + num(parameters[i]) + "\n";
      }
      if (!uncertainty.caveat.empty()) s += "  (" + uncertainty.caveat + ")\n";
    }
    for (Eigen::Index e = 0; e < fit.rows(); ++e) {
      s += "  fit " + experiment_names[static_cast<std::size_t>(e)] + ":";
      for (Eigen::Index j = 0; j < fit.cols(); ++j) s += " " + num(fit(e, j)) + " %";
      s += "\n";
    }
    s += multi_start.report();
    s += summary.message() + "\n";
    return s;
  }
};

namespace detail {

/// A parameter's own magnitude, the unit of the estimator's scaled coordinates (and of the model
/// specs' relative `lambda=`): |value|, else the width of its search range (its bounds where no
/// range is given), else 1.
inline double parameter_magnitude(const ParameterInfo& q) {
  if (q.value != 0.0) return std::abs(q.value);
  const double lo = std::isfinite(q.range_lower) ? q.range_lower : q.lower;
  const double hi = std::isfinite(q.range_upper) ? q.range_upper : q.upper;
  const double width = hi - lo;
  return std::isfinite(width) && width > 0.0 ? width : 1.0;
}
// Fit % of one output column, skipping samples where the measurement is missing (NaN).
inline double fit_percent_skipping_missing(const Eigen::MatrixXd& y, const Eigen::MatrixXd& yhat,
                                           Eigen::Index j) {
  double mean = 0.0, n = 0.0;
  for (Eigen::Index k = 0; k < y.rows(); ++k) {
    if (std::isfinite(y(k, j))) {
      mean += y(k, j);
      n += 1.0;
    }
  }
  if (n < 2.0) return std::numeric_limits<double>::quiet_NaN();
  mean /= n;
  double e2 = 0.0, v2 = 0.0;
  for (Eigen::Index k = 0; k < y.rows(); ++k) {
    if (!std::isfinite(y(k, j))) continue;
    e2 += (y(k, j) - yhat(k, j)) * (y(k, j) - yhat(k, j));
    v2 += (y(k, j) - mean) * (y(k, j) - mean);
  }
  if (!(v2 > 0.0)) return std::numeric_limits<double>::quiet_NaN();
  if (!std::isfinite(e2)) return -std::numeric_limits<double>::infinity();
  return 100.0 * (1.0 - std::sqrt(e2 / v2));
}
// The problem in scaled unknowns θ̃ = θ / s. Levenberg–Marquardt's damping is scale-invariant
// with Jacobian scaling, but its step-size stopping test is not: with b ≈ 10⁵ and c ≈ 30 in one
// vector, a relative step of 10⁻⁸ in ‖θ‖ would be a large step in c. Scaling every unknown to
// order one makes all tolerances mean "relative to the parameter's own size".
template <class Pb>
class ScaledProblem {
 public:
  static constexpr int num_params = Dynamic;
  ScaledProblem(const Pb& inner, Eigen::VectorXd scale) : inner_(&inner), scale_(std::move(scale)) {}
  int num_parameters() const { return inner_->num_parameters(); }
  Eigen::Index num_residuals() const { return inner_->num_residuals(); }
  bool evaluate(const Eigen::VectorXd& ts, Eigen::VectorXd& r, Eigen::MatrixXd* J) const {
    const Eigen::VectorXd th = ts.cwiseProduct(scale_);
    if (!inner_->evaluate(th, r, J)) return false;
    if (J) *J = *J * scale_.asDiagonal();
    return true;
  }
  const Eigen::VectorXd& scale() const { return scale_; }

 private:
  const Pb* inner_;
  Eigen::VectorXd scale_;
};

// Uncertainty of θ = [p; x₀…] of `problem` in the model's own units: the model's names, bounds
// and fixed flags (initial states free and unbounded), one residual series per experiment and
// output (rows are sample-major: output j of experiment e starts at its offset + j, stride n_y).
template <Physics P>
ParameterUncertainty greybox_uncertainty(const GreyBox<P>& model, const GreyBoxProblem<P>& problem, const Dataset& data,
                                         const Eigen::VectorXd& theta, UncertaintyOptions uo) {
  const int n = problem.num_parameters(), np = model.num_parameters(), nx = model.state_dimension();
  const double inf = std::numeric_limits<double>::infinity();
  uo.fixed = problem.fixed_mask();
  uo.lower_bounds = Eigen::VectorXd::Constant(n, -inf);
  uo.upper_bounds = Eigen::VectorXd::Constant(n, inf);
  uo.names.clear();
  for (int i = 0; i < np; ++i) {
    const ParameterInfo& q = model.parameter_info()[static_cast<std::size_t>(i)];
    uo.lower_bounds[i] = q.lower;
    uo.upper_bounds[i] = q.upper;
    uo.names.push_back(q.name);
  }
  for (std::size_t e = 0; e < data.size() && problem.state_column(e) >= 0; ++e) {
    for (int i = 0; i < nx; ++i) {
      uo.names.push_back("x0[" + std::to_string(e) + "]." + model.state_info()[static_cast<std::size_t>(i)].name);
    }
  }
  const int ny = model.output_dimension();
  uo.series.clear();
  for (std::size_t e = 0; e < data.size(); ++e) {
    for (int j = 0; j < ny; ++j) {
      uo.series.push_back({problem.residual_offset(e) + j, static_cast<Eigen::Index>(data[e].size()), ny});
    }
  }
  return parameter_uncertainty(problem, theta, uo);
}

}  // namespace detail

/// Settings of `parameter_uncertainty(GreyBox, data)`.
struct GreyBoxUncertaintyOptions {
  /// How each experiment's simulation starts. `estimate`: x₀ per experiment is an unknown, first
  /// fitted to these data with the parameters held (starting from the model's stored states
  /// when there is one per experiment), as estimation would have left it.
  InitialCondition initial_condition = InitialCondition::estimate;
  /// Formula settings (names, series, bounds and fixed flags are filled in from the model).
  UncertaintyOptions uncertainty;
};

/// Uncertainty of a grey-box model's parameters on `data` at its current values — e.g. of a model
/// loaded from a file, or "how well would this other record determine the parameters". (An
/// estimation reports the same in `GreyBoxEstimate::uncertainty`.) Throws `nlid::Error` for data
/// that do not fit the physics, an inapplicable initial condition, or a model that cannot be
/// simulated on the data.
template <Physics P>
ParameterUncertainty parameter_uncertainty(const GreyBox<P>& model, const Dataset& data,
                                           const GreyBoxUncertaintyOptions& options = {}) {
  require(data.size() > 0, "parameter_uncertainty: empty data set", at_parameter("data"));
  model.check_channels(data);
  data.require_estimable_scale("parameter_uncertainty");
  const int np = model.num_parameters(), nx = model.state_dimension();
  const GreyBoxProblem<P> problem(model.physics(), model.integrator(), data, options.initial_condition,
                                  model.fixed_flags());
  Eigen::VectorXd theta(problem.num_parameters());
  theta.head(np) = model.parameters();
  if (options.initial_condition == InitialCondition::estimate) {
    // Initial states fitted with the parameters held: the residuals the formula assumes are
    // those at an optimum.
    const GreyBoxProblem<P> states(model.physics(), model.integrator(), data, InitialCondition::estimate, {}, true,
                                   model.parameters());
    Eigen::VectorXd x(states.num_parameters());
    const auto& stored = model.estimated_initial_states();
    bool have = stored.size() == data.size();
    for (const auto& x0 : stored) have = have && x0.size() == nx;
    if (have) {
      for (std::size_t e = 0; e < data.size(); ++e) x.segment(states.state_column(e), nx) = stored[e];
    } else {
      states.refresh_initial_states(x);
    }
    LmOptions lm;
    lm.max_iterations = 50;
    solve_least_squares(states, x, lm);
    theta.tail(x.size()) = x;
  }
  return detail::greybox_uncertainty(model, problem, data, theta, options.uncertainty);
}

namespace detail {
// The estimation proper; works on the model it is given, which it changes as it goes (the data
// initialisation first), so the public `estimate` hands it a copy.
template <Physics P>
GreyBoxEstimate estimate_in_place(GreyBox<P>& model, const Dataset& data, const GreyBoxEstimateOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  require(data.size() > 0, "grey-box estimation: empty data set");
  model.check_channels(data);
  data.require_estimable_scale("grey-box estimation");
  if (options.initialize_from_data && !model.initialized()) model.initialize(data);

  const GreyBoxProblem<P> problem(model.physics(), model.integrator(), data,
                                  options.initial_condition, model.fixed_flags());
  const int np = model.num_parameters(), n = problem.num_parameters();
  const int nx = model.state_dimension();
  const double inf = std::numeric_limits<double>::infinity();
  const double nan = std::numeric_limits<double>::quiet_NaN();

  // θ₀ = current parameters + initial-state guesses. The model's values satisfy the physics'
  // relations (its setters check them); checked here again so that an estimation never starts
  // from a meaningless model. Multi-start candidates that violate them (the throttle's stop
  // ranges can overlap) and LM trial steps there are rejected by GreyBoxProblem::evaluate.
  Eigen::VectorXd theta(n);
  theta.head(np) = model.parameters();
  physics_check_parameters(model.physics(), theta.data(), "grey-box estimation: the start");
  problem.refresh_initial_states(theta);

  MultiStartOptions ms = options.multi_start;
  ms.lm.lower_bounds = Eigen::VectorXd::Constant(n, -inf);
  ms.lm.upper_bounds = Eigen::VectorXd::Constant(n, inf);
  ms.range_lower = Eigen::VectorXd::Constant(n, nan);
  ms.range_upper = Eigen::VectorXd::Constant(n, nan);
  ms.log_scale.assign(static_cast<std::size_t>(n), false);
  ms.lm.parameter_names.clear();
  const auto& info = model.parameter_info();
  for (int i = 0; i < np; ++i) {
    const ParameterInfo& q = info[static_cast<std::size_t>(i)];
    ms.lm.lower_bounds[i] = q.lower;
    ms.lm.upper_bounds[i] = q.upper;
    ms.range_lower[i] = std::isfinite(q.range_lower) ? q.range_lower : q.lower;
    ms.range_upper[i] = std::isfinite(q.range_upper) ? q.range_upper : q.upper;
    ms.log_scale[static_cast<std::size_t>(i)] = q.log_scale && ms.range_lower[i] > 0.0;
    ms.lm.parameter_names.push_back(q.name);
  }
  for (std::size_t e = 0; e < data.size(); ++e) {
    for (int i = 0; i < nx && problem.state_column(e) >= 0; ++i) {
      ms.lm.parameter_names.push_back("x0[" + std::to_string(e) + "]." +
                                      model.state_info()[static_cast<std::size_t>(i)].name);
    }
  }
  ms.lm.fixed = problem.fixed_mask();

  // Scales: a parameter's own magnitude (detail::parameter_magnitude); an initial state's largest
  // guessed magnitude over the experiments (at least 1).
  Eigen::VectorXd scale = Eigen::VectorXd::Ones(n);
  for (int i = 0; i < np; ++i) scale[i] = detail::parameter_magnitude(info[static_cast<std::size_t>(i)]);
  if (problem.state_column(0) >= 0) {
    for (int i = 0; i < nx; ++i) {
      double mag = 1.0;
      for (std::size_t e = 0; e < data.size(); ++e) mag = std::max(mag, std::abs(theta[problem.state_column(e) + i]));
      for (std::size_t e = 0; e < data.size(); ++e) scale[problem.state_column(e) + i] = mag;
    }
  }
  const detail::ScaledProblem<GreyBoxProblem<P>> scaled(problem, scale);
  auto to_scaled = [&scale](Eigen::VectorXd& v) {
    for (Eigen::Index i = 0; i < v.size(); ++i) {
      if (std::isfinite(v[i])) v[i] /= scale[i];
    }
  };
  // Regularization is given for the model's parameters in their own units; the solver works in
  // scaled ones (θ = s·ϑ): λR(θ − θ̄)² = λRs²(ϑ − θ̄/s)². Initial states are not penalised.
  LmRegularization& reg = ms.lm.regularization;
  if (reg.lambda > 0.0 || reg.weights.size() > 0 || reg.nominal.size() > 0) {
    const auto check = [np](Eigen::Index size, const char* what) {
      require(size == 0 || size == np,
              std::string("grey-box estimation: ") + what + " has " + std::to_string(size) +
                  " entries; the model has " + std::to_string(np) + " parameters",
              at_parameter(what));
    };
    check(reg.weights.size(), "regularization.weights");
    check(reg.nominal.size(), "regularization.nominal");
    Eigen::VectorXd w = Eigen::VectorXd::Zero(n), nominal = Eigen::VectorXd::Zero(n);
    w.head(np) = reg.weights.size() == np ? reg.weights : Eigen::VectorXd::Ones(np);
    nominal.head(np) = reg.nominal.size() == np ? reg.nominal : theta.head(np);
    reg.weights = w.cwiseProduct(scale).cwiseProduct(scale);
    reg.nominal = nominal.cwiseQuotient(scale);
  }
  to_scaled(ms.lm.lower_bounds);
  to_scaled(ms.lm.upper_bounds);
  to_scaled(ms.range_lower);
  to_scaled(ms.range_upper);
  ms.prepare = [&problem, &scale](Eigen::VectorXd& th) {
    Eigen::VectorXd t = th.cwiseProduct(scale);
    problem.refresh_initial_states(t);
    th = t.cwiseQuotient(scale);
  };
  const Eigen::VectorXd start = theta;  // in the model's units, initial-state guesses included
  theta = theta.cwiseQuotient(scale);

  GreyBoxEstimate out;
  try {
    out.multi_start = multi_start(scaled, theta, ms);
  } catch (const UnevaluableStartsError&) {
    // Every start failed, and the solver can only say "evaluate() returned false". With an
    // equilibrium start the usual cause is structural (a model with an integrator, such as a
    // rigid body's position, has no steady state under a non-zero input): the model's own
    // equilibrium search at the starting values says so in its words.
    if (options.initial_condition == InitialCondition::equilibrium) {
      const Eigen::VectorXd p = model.parameters();
      for (std::size_t e = 0; e < data.size(); ++e) {
        // The problem's own test of the start, the one its evaluations failed on.
        if (data[e].size() == 0 || problem.equilibrium_start_usable(e, p.data())) continue;
        Location where = at_parameter("initial_condition");
        where.experiment = static_cast<long>(e);
        try {
          (void)model.equilibrium(data[e].u().row(0).transpose(), data[e].name());
        } catch (const Error& why) {
          throw Error("grey-box estimation from an equilibrium start: " + why.message() +
                          " (at the starting parameter values; a model that integrates its input has no steady "
                          "state under a non-zero input)",
                      where);
        }
        // A steady state exists but is not unique (∂f/∂x singular: any position of a rigid body
        // at rest is one), so it has no derivative with respect to the parameters.
        throw Error("grey-box estimation from an equilibrium start: the steady state of '" + model.name() +
                        "' for the first input of " +
                        (data[e].name().empty() ? "experiment " + std::to_string(e) : "'" + data[e].name() + "'") +
                        " is not unique (df/dx is singular there: the model integrates, e.g. a rigid body's "
                        "position, so a whole family of states is at rest) and the start cannot follow the "
                        "parameters; use InitialCondition::estimate or zero",
                    where);
      }
    }
    // The model's own simulation from the start each experiment began at names the experiment
    // and sample where it fails. (A refused option is another error and passes as it is.)
    for (std::size_t e = 0; e < data.size(); ++e) {
      try {
        if (problem.state_column(e) >= 0) {
          (void)model.simulate(data[e], Eigen::VectorXd(start.segment(problem.state_column(e), nx)));
        } else {
          (void)model.simulate(data[e], options.initial_condition);
        }
      } catch (const Error& why) {
        Location where = why.where();
        if (where.experiment < 0) where.experiment = static_cast<long>(e);
        throw Error("grey-box estimation: no start can be simulated; at the starting values: " + why.message(),
                    where);
      }
    }
    throw;
  }
  // The solver held a parameter on its bound in scaled units: (lower / s) · s can come back one
  // rounding below lower, and the model would then refuse its own estimate as out of bounds.
  const auto unscale = [&](const Eigen::VectorXd& v) {
    Eigen::VectorXd t = v.cwiseProduct(scale);
    for (int i = 0; i < np; ++i) {
      const ParameterInfo& q = info[static_cast<std::size_t>(i)];
      t[i] = std::clamp(t[i], q.lower, q.upper);
    }
    return t;
  };
  theta = unscale(theta);
  for (StartResult& sr : out.multi_start.starts) {
    sr.start = unscale(sr.start);
    sr.theta = unscale(sr.theta);
  }
  const StartResult& best = out.multi_start.best_start();
  out.summary = best.summary;
  out.cost = best.cost;

  physics_check_parameters(model.physics(), theta.data(),
                           "grey-box estimation: the result (start " + std::to_string(out.multi_start.best + 1) + ")");
  model.update_parameters(theta.head(np));
  out.parameters = theta.head(np);
  out.parameter_names = model.parameter_names();

  // Initial states as used, and the free-run fit per experiment.
  out.fit.resize(static_cast<Eigen::Index>(data.size()), model.output_dimension());
  for (std::size_t e = 0; e < data.size(); ++e) {
    Eigen::VectorXd x0(nx);
    if (!problem.initial_state(theta, e, x0.data())) {
      throw Error("grey-box estimation: no equilibrium at the estimated parameters for experiment " +
                      std::to_string(e),
                  at_experiment(static_cast<long>(e)));
    }
    out.initial_states.push_back(x0);
    const Eigen::MatrixXd yhat = model.simulate(data[e], x0);
    for (int j = 0; j < model.output_dimension(); ++j) {
      out.fit(static_cast<Eigen::Index>(e), j) = detail::fit_percent_skipping_missing(data[e].y(), yhat, j);
    }
    out.experiment_names.push_back(data[e].name().empty() ? "experiment " + std::to_string(e)
                                                          : data[e].name());
  }
  model.set_estimated_initial_states(out.initial_states);

  // The estimate stands even where its uncertainty cannot be computed; the report says why.
  UncertaintyOptions uo;
  uo.caveat = uncertainty_caveat(options.multi_start.lm);
  try {
    out.uncertainty = detail::greybox_uncertainty(model, problem, data, theta, uo);
    // The uncertainty's 0 for an on-bound parameter would read, on the model alone, as exactly
    // known: the model keeps NaN there ("on its bound: no standard deviation").
    Eigen::VectorXd sd = out.uncertainty.stddev.head(np);
    for (Eigen::Index i = 0; i < np; ++i)
      if (out.uncertainty.at_bound[static_cast<std::size_t>(i)]) sd[i] = std::numeric_limits<double>::quiet_NaN();
    model.set_parameter_stddev(std::move(sd));
    // Symmetric, and no rounding-negative variance, so storing it cannot fail.
    const Eigen::MatrixXd c = out.uncertainty.covariance.topLeftCorner(np, np);
    Eigen::MatrixXd sym = 0.5 * (c + c.transpose());
    sym.diagonal() = sym.diagonal().cwiseMax(0.0);
    model.set_parameter_covariance(std::move(sym));
  } catch (const Error& err) {
    out.uncertainty.caveat = std::string("no uncertainty: ") + err.what();
  }
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}
}  // namespace detail

/// Estimates the free parameters of `model` (and initial states) from `data` by simulation
/// error; updates the model and returns the report. Throws `nlid::Error` on a channel mismatch,
/// too little data, an inapplicable initial condition, a bad option, or if no start can be
/// simulated — and then leaves `model` as it was (not even initialised from the data).
template <Physics P>
GreyBoxEstimate estimate(GreyBox<P>& model, const Dataset& data, const GreyBoxEstimateOptions& options = {}) {
  GreyBox<P> work = model;
  GreyBoxEstimate out = detail::estimate_in_place(work, data, options);
  model = std::move(work);
  return out;
}

}  // namespace nlid
