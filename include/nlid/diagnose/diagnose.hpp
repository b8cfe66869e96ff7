#pragma once
/// @file
/// `diagnose`: when simulation and recordings differ, locate the mismatch, name the physics that
/// was left out, model it, and show the fit improve.
///
/// Input: a grey-box baseline (a catalogue physics by name, any `Physics` type, or an already
/// estimated `GreyBox<P>`), estimation records and validation records. Steps:
///
///  1. Preprocess and noise floor. With `decimate` = r > 1 the records are raw: the noise floor
///     is estimated at the raw rate and carried through the same anti-alias filter
///     (noise_floor.hpp), then the records are decimated.
///  2. Baseline. Parameters start from the catalogue's data-driven defaults and are estimated by
///     multi-start simulation error (models/greybox_estimate.hpp), so no guesses are needed; the
///     fit is then polished in the augmented-model simulator so that "before" and "after" are
///     judged by the same numerics.
///  3. Locate. The baseline is simulated on estimation and validation records; intervals and
///     operating regions where the residual exceeds the noise floor are reported with their
///     share of the residual energy (locate.hpp).
///  4. Name and model. Greedy search over the effect catalogue: screen, refit by simulation
///     error, score on validation data with the noise test, the relevance test and a BIC penalty
///     (candidates/search.hpp, significance.hpp). It stops when no candidate improves the fit
///     significantly — on data where nothing is missing it adds nothing.
///  5. Show. Fits before/after per experiment, per candidate and per added effect, located
///     mismatch after the repair, and a plain-language explanation (explain.hpp). report.hpp
///     writes the JSON and the self-contained HTML report.
///
/// The repaired model (`Diagnosis::model`) is an `AugmentedModel<P>` with named parameters and
/// units: it simulates experiments like any nlid model and can be kept and used.
///
/// Limits. One input and one output per record (the catalogue's input and output effects act on
/// those); output-error (simulation) criterion, so process noise counts as excess residual;
/// effects outside the catalogue are reported as "residual above the floor, no catalogue effect
/// explains it" rather than forced into a wrong name.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/core/initial_condition.hpp"
#include "nlid/core/sample_time.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/data/resample.hpp"
#include "nlid/diagnose/augmented.hpp"
#include "nlid/diagnose/candidates/search.hpp"
#include "nlid/diagnose/effects.hpp"
#include "nlid/diagnose/locate.hpp"
#include "nlid/diagnose/noise_floor.hpp"
#include "nlid/diagnose/refit.hpp"
#include "nlid/diagnose/significance.hpp"
#include "nlid/models/greybox.hpp"
#include "nlid/models/greybox_dynamic.hpp"
#include "nlid/models/greybox_estimate.hpp"
#include "nlid/models/physics/catalogue.hpp"

namespace nlid {

/// Settings of `diagnose`.
struct DiagnoseOptions {
  /// Decimation factor r ≥ 1: the records are raw and are decimated by r (anti-alias filtered)
  /// after the noise floor was estimated at the raw rate.
  int decimate = 1;
  /// Anti-alias filter of the decimation.
  DecimateOptions decimate_options;
  /// `estimate` (initial states fitted per record) or `zero`.
  InitialCondition initial_condition = InitialCondition::estimate;
  /// Estimate the baseline parameters (multi-start) first; false: use them as given.
  bool fit_baseline = true;
  /// Levenberg–Marquardt runs of the baseline multi-start (from the best screened candidates).
  int starts = 6;
  /// Candidates screened by the baseline multi-start (0 = 4 × starts).
  int start_candidates = 0;
  /// Effect names to try (empty = the whole catalogue). Unknown names throw.
  std::vector<std::string> effects;
  /// Largest number of effects added.
  int max_effects = 3;
  /// Worker threads (0 = hardware concurrency, at most 8).
  int threads = 0;
  /// Screening and refit effort of the effect search.
  int screen_iterations = 10;
  /// Levenberg–Marquardt steps of the converging refits.
  int refine_iterations = 50;
  /// Candidates refitted to convergence per round.
  int refine_top = 3;
  /// Thresholds of the significance tests.
  SignificanceOptions significance;
  /// Settings of the mismatch locator.
  LocateOptions locate;
  /// Noise floor to use instead of estimating one (`sigma` > 0 enables it).
  NoiseFloor noise;
  /// Minimum samples per experiment after decimation.
  Eigen::Index min_samples = 50;
  /// Progress lines (stderr in the command-line tool); may be empty.
  std::function<void(const std::string&)> progress;
};

/// One effect the diagnosis added, with its effect on the fit.
struct FoundEffect {
  Effect effect;                  ///< kind, variant, fitted parameters (values, units)
  int round = 0;                  ///< search round that added it
  Eigen::VectorXd fit_val_before; ///< validation fit % per experiment before adding it
  Eigen::VectorXd fit_val_after;  ///< … after (all parameters re-estimated)
  Eigen::VectorXd fit_est_after;  ///< estimation fit % after
  CandidateStatistics stats;      ///< its validation tests
};

/// Everything a diagnosis found (see the file comment).
template <Physics P>
struct Diagnosis {
  /// A diagnosis of `fitted` that found nothing yet (baseline = repaired model = `fitted`).
  explicit Diagnosis(AugmentedModel<P> fitted) : baseline(fitted), model(std::move(fitted)) {}

  std::string baseline_name;            ///< catalogue or physics name
  AugmentedModel<P> baseline;           ///< fitted baseline
  AugmentedModel<P> model;              ///< repaired model (baseline + found effects, re-estimated)
  Dataset estimation;                   ///< estimation records as analysed (after decimation)
  Dataset validation;                   ///< validation records as analysed
  NoiseFloor noise;                     ///< noise floor used
  std::vector<Eigen::VectorXd> baseline_x0;  ///< baseline initial states on estimation records
  std::vector<Eigen::VectorXd> model_x0;     ///< repaired model's initial states there
  Evaluation baseline_est;              ///< baseline on estimation data
  Evaluation baseline_val;              ///< baseline on validation data
  Evaluation final_est;                 ///< repaired model on estimation data
  Evaluation final_val;                 ///< repaired model on validation data
  Mismatch mismatch;                    ///< baseline mismatch located on validation data
  Mismatch mismatch_estimation;         ///< baseline mismatch located on estimation data
  Mismatch mismatch_after;              ///< repaired model's mismatch on validation data
  FloorConsistency floor_before;        ///< noise-floor gate of the baseline (validation)
  FloorConsistency floor_after;         ///< noise-floor gate of the repaired model
  std::vector<SearchRound> rounds;      ///< every search round with its candidate table
  std::vector<FoundEffect> effects;     ///< effects added, in order
  /// Effects the search added but the final joint re-estimation made inactive (e.g. a dead time
  /// driven to 0): the validation simulation did not change without them, so they were removed
  /// and are not named as missing physics.
  std::vector<FoundEffect> inert;
  std::vector<std::string> not_applicable;  ///< catalogue effects that cannot apply, with reason
  std::string stop_reason;              ///< why the search ended
  SearchStop stop = SearchStop::none_significant;  ///< the same as a value
  int max_effects = 0;                  ///< the search's limit (DiagnoseOptions::max_effects)
  std::vector<std::string> effects_asked;  ///< DiagnoseOptions::effects (empty: the whole catalogue)
  DataScales scales;                    ///< data scales of the repaired model
  std::string baseline_report;          ///< multi-start summary of the baseline fit
  std::string explanation;              ///< what was missing, where, how large, fit gain
  double seconds = 0.0;                 ///< wall-clock time
};

/// Diagnoses `baseline` (its parameter table is the starting point, or the answer when
/// `fit_baseline` is false) on estimation records `est` and validation records `val`. Throws
/// `nlid::Error` for unusable data (no records, channel mismatch, too short after decimation,
/// constant output) or options (unknown effect name, bad factor).
template <Physics P>
Diagnosis<P> diagnose(GreyBox<P> baseline, const Dataset& est, const Dataset& val,
                      const DiagnoseOptions& options = {});

/// Diagnoses the catalogue baseline registered under `name` (models/greybox_dynamic.hpp).
/// Throws `nlid::Error` listing the known baselines if the name is unknown.
inline Diagnosis<AnyPhysics> diagnose(std::string_view name, const Dataset& est, const Dataset& val,
                                      const DiagnoseOptions& options = {}) {
  return diagnose(GreyBox<AnyPhysics>(make_physics(name)), est, val, options);
}

/// Calls `f(GreyBox<P>{})` with the compile-time type P of the catalogue baseline `name`
/// (throttle, mass_spring_damper, rigid_body, first_order, two_tank: fixed-size simulation and
/// one-pass sensitivities, several times faster than the runtime path), or `f(make_greybox(name))`
/// for a physics registered at run time. Every call of `f` must return the same type. Throws
/// `nlid::Error` listing the known names if `name` is unknown.
template <class F>
decltype(auto) with_baseline(std::string_view name, F&& f) {
  if (name == "throttle") return f(GreyBox<physics::Throttle>());
  if (name == "mass_spring_damper") return f(GreyBox<physics::MassSpringDamper>());
  if (name == "rigid_body") return f(GreyBox<physics::RigidBody>());
  if (name == "first_order") return f(GreyBox<physics::FirstOrder>());
  if (name == "two_tank") return f(GreyBox<physics::TwoTank>());
  return f(make_greybox(name));
}

/// Plain-language explanation of a diagnosis (defined in explain.hpp, included below).
template <Physics P>
std::string explain(const Diagnosis<P>& d);

}  // namespace nlid

#include "nlid/diagnose/explain.hpp"

namespace nlid {

// ------------------------------------------------------------------------------------------
// Implementation details below.
// ------------------------------------------------------------------------------------------

namespace detail {

inline void check_diagnosis_data(const Dataset& d, const char* role, Eigen::Index min_samples, int factor) {
  require(d.size() > 0, std::string("no ") + role + " records given");
  for (std::size_t e = 0; e < d.size(); ++e) {
    const Experiment& x = d[e];
    const std::string who = std::string(role) + " record " +
                            (x.name().empty() ? std::to_string(e) : "'" + x.name() + "'");
    Location where = at_experiment(static_cast<long>(e));
    where.file = x.name();
    require(x.num_outputs() == 1,
            who + " has " + std::to_string(x.num_outputs()) + " outputs; the diagnosis needs exactly one",
            where);
    require(x.num_inputs() >= 1, who + " has no input channel", where);
    const Eigen::Index after = factor > 1 ? (x.size() - 1) / factor + 1 : x.size();
    require(after >= min_samples,
            who + " is too short: " + std::to_string(x.size()) + " samples" +
                (factor > 1 ? " (" + std::to_string(after) + " after decimation by " + std::to_string(factor) + ")" : "") +
                "; the diagnosis needs at least " + std::to_string(min_samples),
            where);
    const double span = x.y().col(0).maxCoeff() - x.y().col(0).minCoeff();
    require(span > 0.0, who + ": the output is constant, there is nothing to model", where);
    x.require_estimable_scale(std::string("diagnosis, ") + role + " record", static_cast<long>(e));
  }
}

/// Moves every effect of `model` (listed in the same order in `found`) that no longer changes
/// the validation simulation into `inert`, removing it from the model; returns their labels. An
/// effect accepted in an early round can be driven to its identity by the later joint
/// re-estimations (a dead time of 0): naming it as the missing physics would then be wrong.
template <Physics P>
std::vector<std::string> remove_inert_effects(AugmentedModel<P>& model, std::vector<FoundEffect>& found,
                                              std::vector<FoundEffect>& inert, const Dataset& val, InitialCondition ic) {
  std::vector<std::string> removed;
  if (found.size() != model.effects().size()) return removed;
  const double sse = evaluate_model(model, val, {}, ic).total_sse();
  if (!std::isfinite(sse)) return removed;
  for (std::size_t i = found.size(); i-- > 0;) {
    AugmentedModel<P> without(model.physics(), model.baseline_parameters(), model.ts());
    without.set_units(model.output_unit(), model.input_unit());
    if (!model.input_names().empty()) without.set_channel_names(model.input_names(), model.output_names());
    for (std::size_t j = 0; j < model.effects().size(); ++j)
      if (j != i) without.add_effect(model.effects()[j]);
    const Evaluation e = evaluate_model(without, val, {}, ic);
    if (!(e.ok && std::abs(e.total_sse() - sse) <= 1e-9 * sse)) continue;
    removed.push_back(found[i].effect.label());
    inert.insert(inert.begin(), found[i]);
    found.erase(found.begin() + static_cast<std::ptrdiff_t>(i));
    model = std::move(without);
  }
  return removed;
}

}  // namespace detail

template <Physics P>
Diagnosis<P> diagnose(GreyBox<P> baseline, const Dataset& est_in, const Dataset& val_in,
                      const DiagnoseOptions& options) {
  const auto t_start = std::chrono::steady_clock::now();
  auto say = [&](const std::string& s) {
    if (options.progress) options.progress(s);
  };
  require(options.decimate >= 1, "decimation factor must be >= 1, got " + std::to_string(options.decimate),
          at_parameter("decimate"));
  require(options.starts >= 1, "starts must be >= 1", at_parameter("starts"));
  require(options.max_effects >= 0, "max_effects must be >= 0", at_parameter("max_effects"));
  // Settings checked by the search and the locator are checked here too, before the baseline fit.
  check_search_effort(options.screen_iterations, options.refine_iterations, options.refine_top);
  require(options.start_candidates >= 0, "start_candidates must be >= 0 (0 = 4 x starts), got " +
                                             std::to_string(options.start_candidates),
          at_parameter("start_candidates"));
  require(options.min_samples >= 1, "min_samples must be >= 1, got " + std::to_string(options.min_samples),
          at_parameter("min_samples"));
  const SignificanceOptions& sig = options.significance;
  require(sig.alpha > 0.0 && sig.alpha < 1.0,
          "significance.alpha (false-detection probability) must lie in (0, 1), got " + detail::format_g(sig.alpha),
          at_parameter("significance.alpha"));
  require(sig.relevance >= 0.0 && sig.relevance <= 1.0,
          "significance.relevance (share of the excess a candidate must remove) must lie in [0, 1], got " +
              detail::format_g(sig.relevance),
          at_parameter("significance.relevance"));
  require(sig.floor_margin >= 0.0 && std::isfinite(sig.floor_margin),
          "significance.floor_margin must be finite and >= 0, got " + detail::format_g(sig.floor_margin),
          at_parameter("significance.floor_margin"));
  check_locate_options(options.locate, "locate.");
  require(!(options.noise.sigma > 0.0) || std::isfinite(options.noise.sigma),
          "noise.sigma must be finite (or 0 to estimate the noise floor), got " + detail::format_g(options.noise.sigma),
          at_parameter("noise.sigma"));
  require(options.initial_condition == InitialCondition::estimate ||
              options.initial_condition == InitialCondition::zero,
          "the diagnosis supports initial conditions 'estimate' and 'zero'", at_parameter("x0"));
  std::vector<EffectKind> kinds;
  for (const std::string& n : options.effects) kinds.push_back(effect_kind(n));
  detail::check_diagnosis_data(est_in, "estimation", options.min_samples, options.decimate);
  detail::check_diagnosis_data(val_in, "validation", options.min_samples, options.decimate);
  const auto record_name = [](const Dataset& d) {
    return d[0].name().empty() ? std::string("the first") : "'" + d[0].name() + "'";
  };
  require(val_in.ts() > 0 && same_sample_time(val_in.ts(), est_in.ts()),
          "estimation and validation records have different sample times (" + detail::format_g(est_in.ts(), 10) +
              " s for estimation record " + record_name(est_in) + ", " + detail::format_g(val_in.ts(), 10) +
              " s for validation record " + record_name(val_in) + ")",
          at_parameter("val"));
  require(est_in.num_inputs() == val_in.num_inputs(),
          "estimation and validation records have different input counts");
  // Effects are tested on validation records that no parameter was fitted to; a record in both
  // sets would let an effect fitted to its noise pass the test.
  for (std::size_t v = 0; v < val_in.size(); ++v) {
    for (std::size_t e = 0; e < est_in.size(); ++e) {
      const Experiment& a = val_in[v];
      const Experiment& b = est_in[e];
      if (a.size() != b.size() || a.u() != b.u() || a.y() != b.y()) continue;
      Location where = at_experiment(static_cast<long>(v));
      where.file = a.name();
      throw Error("validation record " + (a.name().empty() ? std::to_string(v) : "'" + a.name() + "'") +
                      " is the same data as estimation record " +
                      (b.name().empty() ? std::to_string(e) : "'" + b.name() + "'") +
                      "; the diagnosis tests each effect on validation records that no parameter was fitted to",
                  where);
    }
  }
  baseline.check_channels(est_in);
  baseline.check_channels(val_in);

  // 1. Noise floor and preprocessing.
  NoiseFloor noise = options.noise;
  if (!(noise.sigma > 0.0)) {
    say("estimating the noise floor" + std::string(options.decimate > 1 ? " at the raw rate" : ""));
    noise = estimate_noise_floor(merge(est_in, val_in), 0, options.decimate, options.decimate_options);
  }
  require(noise.sigma > 0.0 && std::isfinite(noise.sigma),
          "the noise floor could not be estimated (the output looks noise-free); pass one in "
          "DiagnoseOptions::noise",
          at_parameter("noise"));
  const Dataset est = options.decimate > 1 ? decimate(est_in, options.decimate, options.decimate_options) : est_in;
  const Dataset val = options.decimate > 1 ? decimate(val_in, options.decimate, options.decimate_options) : val_in;

  // 2. Baseline.
  std::string report;
  std::vector<Eigen::VectorXd> x0;
  if (options.fit_baseline) {
    say("estimating the baseline (" + std::to_string(options.starts) + " multi-start runs)");
    GreyBoxEstimateOptions go;
    go.initial_condition = options.initial_condition;
    go.multi_start.num_starts = options.starts;
    go.multi_start.num_candidates = options.start_candidates > 0 ? options.start_candidates : 4 * options.starts;
    go.multi_start.num_threads = options.threads;
    const GreyBoxEstimate ge = estimate(baseline, est, go);
    report = ge.multi_start.report();
    x0 = ge.initial_states;
  } else if (!baseline.initialized()) {
    baseline.set_units(est[0].output_units().empty() ? std::string() : est[0].output_units()[0],
                       est[0].input_units().empty() ? std::string() : est[0].input_units()[0]);
  }
  AugmentedModel<P> base(baseline.physics(), baseline.parameter_info(), est.ts());
  base.set_units(est[0].output_units().empty() ? std::string() : est[0].output_units()[0],
                 est[0].input_units().empty() ? std::string() : est[0].input_units()[0]);
  if (static_cast<int>(est[0].input_names().size()) == detail::physics_inputs(baseline.physics()) &&
      est[0].output_names().size() == 1)
    base.set_channel_names(est[0].input_names(), est[0].output_names());
  {
    // Polish in the augmented simulator so "before" and "after" share numerics and optimality.
    // A baseline used as given keeps its parameters: only its initial states are estimated.
    RefitOptions ro;
    ro.max_iterations = options.refine_iterations;
    ro.function_tolerance = 1e-8;
    ro.initial_condition = options.initial_condition;
    const auto held = [&] {
      std::vector<ParameterInfo> table = baseline.parameter_info();
      for (ParameterInfo& q : table) q.fixed = true;
      return AugmentedModel<P>(baseline.physics(), std::move(table), est.ts());
    };
    const RefitResult r = options.fit_baseline ? refit(base, est, base.parameters(), x0, ro)
                                               : refit(held(), est, base.parameters(), x0, ro);
    if (r.ok) {
      base.set_parameters(r.theta);
      x0 = r.x0;
    } else if (x0.empty()) {
      throw Error("the baseline cannot be simulated on the estimation records: " + r.error);
    }
  }

  Diagnosis<P> d(base);
  d.estimation = est;
  d.validation = val;
  d.noise = noise;
  d.baseline_x0 = x0;
  d.model_x0 = x0;
  if constexpr (requires(const P& q) { { q.name() } -> std::convertible_to<std::string>; })
    d.baseline_name = baseline.physics().name();
  else
    d.baseline_name = "custom";
  d.baseline_report = report;
  const InitialCondition ic = options.initial_condition;
  d.baseline_est = evaluate_model(base, est, x0, ic);
  d.baseline_val = evaluate_model(base, val, {}, ic);
  require(d.baseline_est.ok && d.baseline_val.ok,
          "the fitted baseline diverges on " + std::string(d.baseline_est.ok ? "validation" : "estimation") +
              " data; check the records and the baseline");
  say("baseline fit: estimation " + detail::format_fits(d.baseline_est.fit) + " %, validation " +
      detail::format_fits(d.baseline_val.fit) + " %");

  // 3. Locate.
  d.mismatch = locate_mismatch(val, d.baseline_val.yhat, noise, options.locate);
  d.mismatch_estimation = locate_mismatch(est, d.baseline_est.yhat, noise, options.locate);
  Eigen::Index n_val = 0;
  for (const Experiment& x : val) n_val += x.size();
  d.floor_before = floor_consistency(d.baseline_val.total_sse(), n_val, noise.sigma, noise.inflation,
                                     options.significance);

  // 4. Search.
  SearchOptions so;
  so.kinds = kinds;
  so.max_effects = options.max_effects;
  so.screen_iterations = options.screen_iterations;
  so.refine_iterations = options.refine_iterations;
  so.refine_top = options.refine_top;
  so.threads = options.threads;
  so.initial_condition = ic;
  so.significance = options.significance;
  so.progress = options.progress;
  SearchResult<P> sr = search_effects(base, x0, est, val, noise, so);
  d.model = sr.model;
  d.model_x0 = sr.x0_est;
  d.rounds = sr.rounds;
  d.not_applicable = sr.not_applicable;
  d.stop_reason = sr.stop_reason;
  d.stop = sr.stop;
  d.max_effects = options.max_effects;
  d.effects_asked = options.effects;
  for (const SearchRound& r : d.rounds) {
    if (r.accepted < 0) continue;
    const CandidateResult& c = r.candidates[static_cast<std::size_t>(r.accepted)];
    FoundEffect f;
    f.effect = c.effect;
    f.round = r.round;
    f.fit_val_before = r.fit_val_before;
    f.fit_val_after = c.fit_val;
    f.fit_est_after = c.fit_est;
    f.stats = c.stats;
    d.effects.push_back(std::move(f));
  }
  // The effects' parameter values as re-estimated together in the final model.
  for (std::size_t i = 0; i < d.effects.size() && i < d.model.effects().size(); ++i)
    d.effects[i].effect = d.model.effects()[i];
  for (const std::string& label : detail::remove_inert_effects(d.model, d.effects, d.inert, val, ic))
    say("removed " + label + ": the joint re-estimation made it inactive");

  // 5. Show.
  d.final_est = evaluate_model(d.model, est, d.model_x0, ic);
  d.final_val = evaluate_model(d.model, val, {}, ic);
  d.mismatch_after = locate_mismatch(val, d.final_val.yhat, noise, options.locate);
  d.floor_after = floor_consistency(d.final_val.total_sse(), n_val, noise.sigma, noise.inflation,
                                    options.significance);
  d.scales = data_scales(d.model, est, d.model_x0);
  d.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  d.explanation = explain(d);
  return d;
}

}  // namespace nlid
