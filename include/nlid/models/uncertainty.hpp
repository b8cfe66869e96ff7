#pragma once
/// @file
/// `parameter_uncertainty(model, data)`: standard deviations, correlations and unidentifiable
/// combinations of an estimated nonlinear ARX or Hammerstein–Wiener model's parameters, from the
/// criterion it was estimated by (estimation/uncertainty.hpp explains the formulas).
///
/// The criterion is read from the model's estimation report — prediction or simulation focus,
/// and the initial condition (estimated initial states are taken from the report and counted as
/// unknowns, as they were during estimation) — unless the options say otherwise, so the same
/// call also answers "how well would these (other) data determine the model". Computed on
/// request rather than inside `estimate()`: cheap (one Jacobian pass plus the lag sums: 32 ms
/// for the study's nlarx5, whose estimation takes 0.6 s; 8 ms for nlhw1), but for network
/// nonlinearities mostly a statement about the parametrisation (below).
///
/// What to expect: the linear parts and the saturation limits of a Hammerstein–Wiener model are
/// usually well determined; the units of a sigmoid or wavelet network are not individually
/// identifiable (swapping two units, or trading a unit's weight against its slope, leaves the
/// output unchanged nearly everywhere), so their rows say "not identifiable" or show large
/// deviations — a statement about the parametrisation, not about the fit.

#include <limits>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/core/initial_condition.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/estimation/autodiff.hpp"
#include "nlid/estimation/uncertainty.hpp"
#include "nlid/models/detail/estimation_segment.hpp"
#include "nlid/models/detail/simulation_residuals.hpp"
#include "nlid/models/estimate.hpp"
#include "nlid/models/hammerstein_wiener.hpp"
#include "nlid/models/nlarx.hpp"

namespace nlid {

/// Settings of `parameter_uncertainty(model, data)`.
struct ModelUncertaintyOptions {
  /// Nlarx: the criterion; unset: the focus of the model's estimation report (prediction if the
  /// model was not estimated). Hammerstein–Wiener models are always taken by simulation error.
  std::optional<Focus> focus;
  /// Initial condition of the simulations; unset: the one of the report (Nlarx: measured if
  /// none, Hammerstein–Wiener: zero). `estimate` needs the report's estimated initial states.
  std::optional<InitialCondition> initial_condition;
  /// Formula settings. `fixed`, `lower_bounds` and `upper_bounds` may be sized to the model's
  /// parameters (as in `EstimateOptions::solver`); names and residual series are filled in.
  UncertaintyOptions uncertainty;
};

namespace detail {

inline InitialCondition initial_condition_from_report(const std::string& s, InitialCondition fallback) {
  if (s == "zero") return InitialCondition::zero;
  if (s == "estimate") return InitialCondition::estimate;
  if (s == "equilibrium") return InitialCondition::equilibrium;
  if (s == "measured") return InitialCondition::measured;
  return fallback;
}

// Extends bounds and fixed flags sized to the model's np parameters by `extra` free unknowns.
inline void extend_uncertainty_options(UncertaintyOptions& o, int np, int extra) {
  const auto check = [np](Eigen::Index size, const char* what) {
    require(size == 0 || size == np,
            std::string("parameter_uncertainty: ") + what + " has " + std::to_string(size) +
                " entries; the model has " + std::to_string(np) + " parameters",
            at_parameter(what));
  };
  check(static_cast<Eigen::Index>(o.fixed.size()), "fixed");
  check(o.lower_bounds.size(), "lower_bounds");
  check(o.upper_bounds.size(), "upper_bounds");
  const double inf = std::numeric_limits<double>::infinity();
  if (!o.fixed.empty()) o.fixed.resize(static_cast<std::size_t>(np + extra), false);
  if (o.lower_bounds.size() > 0) {
    o.lower_bounds.conservativeResize(np + extra);
    o.lower_bounds.tail(extra).setConstant(-inf);
  }
  if (o.upper_bounds.size() > 0) {
    o.upper_bounds.conservativeResize(np + extra);
    o.upper_bounds.tail(extra).setConstant(inf);
  }
}

// The free-run criterion of `model` on `segs` (start and x0 prepared), with each experiment's
// estimated initial state appended to θ when ic is `estimate`.
template <class M>
ParameterUncertainty simulation_uncertainty(const M& model, std::vector<EstimationSegment> segs, InitialCondition ic,
                                            UncertaintyOptions o) {
  const int np = model.num_parameters();
  std::vector<int> free;
  std::vector<std::string> names = model.parameter_names();
  Eigen::VectorXd theta = model.parameters();
  if (ic == InitialCondition::estimate) free = append_initial_states(model, segs, theta, names);
  extend_uncertainty_options(o, np, static_cast<int>(theta.size()) - np);
  o.names = names;
  o.series.clear();
  Eigen::Index off = 0;
  for (const auto& s : segs) {
    o.series.push_back({off, s.y.size() - s.start, 1});
    off += s.y.size() - s.start;
  }
  Eigen::VectorXd y_all(off);
  off = 0;
  for (const auto& s : segs) {
    y_all.segment(off, s.y.size() - s.start) = s.y.tail(s.y.size() - s.start);
    off += s.y.size() - s.start;
  }
  const AutoDiffProblem<SimulationResiduals<M, Dynamic>> problem(
      SimulationResiduals<M, Dynamic>(model, std::move(segs), std::move(free), ic, divergence_limit(y_all)));
  return parameter_uncertainty(problem, theta, o);
}

// Experiments as estimation segments (inputs viewed, outputs copied); checks them against the model.
template <class M>
std::vector<EstimationSegment> uncertainty_segments(const M& model, const Dataset& data, int history, const char* kind) {
  require(data.size() > 0, "parameter_uncertainty: the data set has no experiments", at_parameter("data"));
  std::vector<EstimationSegment> segs(data.size());
  for (std::size_t i = 0; i < data.size(); ++i) {
    check_experiment(data[i], static_cast<long>(i), model.num_inputs(), history, model.ts(), kind);
    require_complete(data[i], static_cast<long>(i));
    data[i].require_estimable_scale("parameter_uncertainty", static_cast<long>(i));
    segs[i].u = &data[i].u();
    segs[i].y = data[i].y().col(0);
  }
  return segs;
}

// The report's estimated initial state of each experiment, checked against the data.
template <class M>
void take_report_initial_states(const M& model, std::vector<EstimationSegment>& segs, Eigen::Index size) {
  const auto& x0 = model.report().initial_states;
  require(x0.size() == segs.size(),
          "parameter_uncertainty: initial condition 'estimate' needs the estimated initial state of each of the " +
              std::to_string(segs.size()) + " experiments; the model's report has " + std::to_string(x0.size()) +
              " (estimate the model on these data, or choose another initial condition)",
          at_parameter("initial_condition"));
  for (std::size_t e = 0; e < segs.size(); ++e) {
    require(x0[e].size() == size,
            "parameter_uncertainty: the report's initial state of experiment " + std::to_string(e) + " has " +
                std::to_string(x0[e].size()) + " entries; the model's state has " + std::to_string(size),
            at_experiment(static_cast<long>(e)));
    segs[e].x0 = x0[e];
  }
}

}  // namespace detail

/// Uncertainty of a nonlinear ARX model's parameters on `data` (the estimation data, normally).
/// Throws `nlid::Error` for data that do not fit the model, an `estimate` initial condition
/// without the report's initial states, or a criterion that cannot be evaluated.
template <Regressor R, Nonlinearity F>
ParameterUncertainty parameter_uncertainty(const Nlarx<R, F>& model, const Dataset& data,
                                           const ModelUncertaintyOptions& options = {}) {
  using M = Nlarx<R, F>;
  const int n0 = model.history_length();
  std::vector<detail::EstimationSegment> segs = detail::uncertainty_segments(model, data, n0, "nonlinear ARX");
  const EstimationReport& rep = model.report();
  const Focus focus = options.focus.value_or(rep.estimated && rep.focus == "simulation" ? Focus::simulation
                                                                                        : Focus::prediction);
  if (focus == Focus::prediction) {
    UncertaintyOptions o = options.uncertainty;
    detail::extend_uncertainty_options(o, model.num_parameters(), 0);
    o.names = model.parameter_names();
    o.series.clear();
    Eigen::Index off = 0;
    for (const auto& s : segs) {
      o.series.push_back({off, s.y.size() - n0, 1});
      off += s.y.size() - n0;
    }
    const AutoDiffProblem<detail::PredictionResiduals<M>> problem(detail::PredictionResiduals<M>(model, std::move(segs)));
    return parameter_uncertainty(problem, model.parameters(), o);
  }
  const InitialCondition ic = options.initial_condition.value_or(
      detail::initial_condition_from_report(rep.initial_condition, InitialCondition::measured));
  require(ic != InitialCondition::equilibrium,
          "parameter_uncertainty: equilibrium initial conditions are not supported for Nlarx; use zero, measured or estimate",
          at_parameter("initial_condition"));
  if (ic == InitialCondition::estimate) {
    detail::take_report_initial_states(model, segs, model.held_state(segs[0].y(0), segs[0].u->row(0)).size());
  }
  for (auto& s : segs) {
    s.start = ic == InitialCondition::measured ? n0 : 0;
    if (ic == InitialCondition::measured) s.x0 = model.measured_state(*s.u, s.y, n0);
    if (ic == InitialCondition::zero) s.x0.resize(0);
  }
  return detail::simulation_uncertainty(model, std::move(segs), ic, options.uncertainty);
}

/// Uncertainty of a Hammerstein–Wiener model's parameters on `data` (simulation error, the
/// criterion it is estimated by). Throws as the Nlarx overload.
template <ScalarNonlinearity In, LinearBlock L, ScalarNonlinearity Out>
ParameterUncertainty parameter_uncertainty(const HammersteinWiener<In, L, Out>& model, const Dataset& data,
                                           const ModelUncertaintyOptions& options = {}) {
  std::vector<detail::EstimationSegment> segs = detail::uncertainty_segments(model, data, 0, "Hammerstein-Wiener");
  const InitialCondition ic = options.initial_condition.value_or(
      detail::initial_condition_from_report(model.report().initial_condition, InitialCondition::zero));
  require(ic != InitialCondition::measured,
          "parameter_uncertainty: InitialCondition::measured is not defined for a Hammerstein-Wiener model",
          at_parameter("initial_condition"));
  if (ic == InitialCondition::estimate) {
    detail::take_report_initial_states(model, segs, model.state_dimension());
  }
  for (auto& s : segs) {
    s.start = 0;
    if (ic != InitialCondition::estimate) s.x0.resize(0);
  }
  return detail::simulation_uncertainty(model, std::move(segs), ic, options.uncertainty);
}

}  // namespace nlid
