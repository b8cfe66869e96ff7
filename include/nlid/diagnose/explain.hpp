#pragma once
/// @file
/// The explanation of a diagnosis, in the words a control engineer would use: what was missing,
/// where it showed, how large it is, and what it gains.
///
/// Sizes are translated into quantities one can check on the rig:
///
/// - Coulomb friction F_c (per inertia) against a return spring of stiffness k (per inertia)
///   holds the body F_c/k away from the frictionless equilibrium, so up- and down-going steps to
///   the same command settle 2F_c/k apart (the hysteresis band of a staircase test);
/// - a preload P is a force step of height 2P, i.e. a jump of 2P/k in the static curve;
/// - cubic stiffness is compared with the linear spring force at the end of the travel,
///   |k₃|(L/2)³ versus k·L/2;
/// - drag and viscous friction are compared with the acceleration scale at the typical speed V;
/// - dead zones, offsets and limits are given in input/output units and as a share of the range;
/// - dead time and lags in seconds and in samples.
///
/// "Where" comes from the located mismatch of the baseline on validation data (locate.hpp): the
/// operating region with the highest concentration of excess residual energy, and the time
/// intervals above the noise floor. "How well" is the validation fit per experiment before and
/// after, and the final residual relative to the noise floor.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/format.hpp"
#include "nlid/diagnose/diagnose.hpp"
#include "nlid/diagnose/effects.hpp"
#include "nlid/diagnose/locate.hpp"

namespace nlid {

/// One sentence on the size of an effect in checkable terms (see the file comment). `y_unit`
/// and `u_unit` replace "{y}" and "{u}" (empty: written as "[y]", "[u]").
inline std::string effect_magnitude(const Effect& e, const DataScales& s, const std::string& y_unit,
                                    const std::string& u_unit);

/// Where the mismatch concentrates, e.g. "at rest (|dy/dt| small: 46 % of the excess residual
/// energy in 22 % of the samples)"; empty if no region stands out.
inline std::string mismatch_location(const Mismatch& m, const std::string& y_unit, const std::string& u_unit);

// ------------------------------------------------------------------------------------------
// Implementation details below.
// ------------------------------------------------------------------------------------------

namespace detail {

inline std::string g3(double v) { return format_g(v, 3); }

inline std::string pct(double v) { return format_f(100.0 * v, 0) + " %"; }

inline std::string fits_text(const Eigen::VectorXd& f) {
  std::string s;
  for (Eigen::Index i = 0; i < f.size(); ++i) {
    s += (i ? "/" : "") + format_f(f(i), 1);
  }
  return s + " %";
}

inline std::string gains_text(const Eigen::VectorXd& before, const Eigen::VectorXd& after) {
  std::string s;
  for (Eigen::Index i = 0; i < before.size() && i < after.size(); ++i) {
    s += (i ? "/" : "") + with_plus(format_f(after(i) - before(i), 1));
  }
  return s + " points";
}

inline std::string with_units(const std::string& unit, const std::string& yu, const std::string& uu) {
  return substitute_units(unit, yu, uu);
}

}  // namespace detail

inline std::string effect_magnitude(const Effect& e, const DataScales& s, const std::string& yu,
                                    const std::string& uu) {
  using detail::g3;
  using detail::pct;
  const std::string Y = yu.empty() ? "[y]" : yu, U = uu.empty() ? "[u]" : uu;
  const double L = s.q_range();
  auto param = [&](std::size_t i) { return e.params.at(i).value; };
  auto named = [&](std::size_t i) {
    return e.params.at(i).name + " = " + g3(param(i)) + " " + detail::with_units(e.params.at(i).unit, yu, uu);
  };
  switch (e.kind) {
    case EffectKind::coulomb_friction:
      if (s.stiffness > 0.0) {
        const double dq = param(0) / s.stiffness;
        return named(0) + ", equivalent to " + g3(dq) + " " + Y + " of spring deflection: up- and down-going "
               "moves to the same command settle about " + g3(2.0 * dq) + " " + Y + " apart (" +
               pct(2.0 * dq / L) + " of the travel)";
      }
      return named(0) + " (" + pct(param(0) / std::max(s.accel, 1e-300)) + " of the typical acceleration)";
    case EffectKind::viscous_friction:
      return named(0) + ": at the typical speed " + g3(s.speed) + " " + Y + "/s it decelerates by " +
             g3(param(0) * s.speed) + " " + Y + "/s^2 (" + pct(param(0) * s.speed / std::max(s.accel, 1e-300)) +
             " of the typical acceleration)";
    case EffectKind::quadratic_drag:
      return named(0) + ": at the typical speed " + g3(s.speed) + " " + Y + "/s the drag is " +
             g3(param(0) * s.speed * s.speed) + " " + Y + "/s^2 (" +
             pct(param(0) * s.speed * s.speed / std::max(s.accel, 1e-300)) + " of the typical acceleration)";
    case EffectKind::cubic_stiffness: {
      const double h = 0.5 * L, f3 = std::abs(param(0)) * h * h * h;
      std::string t = named(0) + (param(0) > 0 ? " (hardening)" : " (softening)") + ": at the ends of the travel "
                      "it adds " + g3(f3) + " " + Y + "/s^2";
      if (s.stiffness > 0.0) t += ", " + pct(f3 / (s.stiffness * h)) + " of the linear spring force there";
      return t;
    }
    case EffectKind::hard_stop:
      return "a " + e.variant + " stop at " + g3(param(0)) + " " + Y + " with contact stiffness " + g3(param(1)) +
             " 1/s^2";
    case EffectKind::preload: {
      std::string t = "a force step of height " + g3(2.0 * std::abs(param(0))) + " " + Y + "/s^2 at " +
                      g3(param(1)) + " " + Y;
      if (s.stiffness > 0.0) t += " (a jump of " + g3(2.0 * std::abs(param(0)) / s.stiffness) + " " + Y + " in the static curve)";
      return t;
    }
    case EffectKind::backlash:
      return "a play of " + g3(param(0)) + " " + Y + " (" + pct(param(0) / L) + " of the travel)";
    case EffectKind::input_deadzone:
      // Noun phrases: the explanation reads "... with <magnitude>".
      return "a dead band of +/-" + g3(param(0)) + " " + U + " around zero, in which commands produce no drive (" +
             pct(param(0) / s.u_range()) + " of the input range)";
    case EffectKind::input_saturation:
      return "a limit at " + g3(param(0)) + " " + U + std::string(e.variant == "upper" ? " (commands above it" : " (commands below it") +
             " are clipped)";
    case EffectKind::output_saturation:
      return "a limit at " + g3(param(0)) + " " + Y + std::string(e.variant == "upper" ? " (readings above it" : " (readings below it") +
             " are clipped)";
    case EffectKind::dead_time:
      return "tau = " + g3(param(0)) + " s (" + g3(param(0) / s.ts) + " samples)";
    case EffectKind::actuator_lag:
      return "T = " + g3(param(0)) + " s (" + g3(param(0) / s.ts) + " samples)";
    case EffectKind::input_offset:
      return "a bias of " + g3(param(0)) + " " + U + " (" + pct(std::abs(param(0)) / s.u_range()) + " of the input range)";
    case EffectKind::output_offset:
      return "an offset of " + g3(param(0)) + " " + Y + " (" + pct(std::abs(param(0)) / s.y_range()) +
             " of the output range)";
  }
  return {};
}

inline std::string mismatch_location(const Mismatch& m, const std::string& yu, const std::string& uu) {
  const MismatchRegion* best = nullptr;
  double best_c = 1.3;  // a region must hold 30 % more than its share of samples to "stand out"
  for (const MismatchRegion& r : m.regions) {
    if (r.excess_share < 0.2 || r.sample_share <= 0.0) continue;
    const double c = r.excess_share / r.sample_share;
    if (c > best_c) {
      best_c = c;
      best = &r;
    }
  }
  if (!best) return {};
  const std::string Y = yu.empty() ? "[y]" : yu, U = uu.empty() ? "[u]" : uu;
  std::string where;
  if (best->variable == "dy/dt") {
    if (best->label == "at rest") where = "at rest and at reversals (|dy/dt| < " + detail::g3(best->hi) + " " + Y + "/s)";
    else where = "while moving " + best->label + " (dy/dt from " + detail::g3(best->lo) + " to " + detail::g3(best->hi) + " " + Y + "/s)";
  } else if (best->variable == "y") {
    where = "at output levels " + detail::g3(best->lo) + " to " + detail::g3(best->hi) + " " + Y;
  } else {
    where = "for inputs " + detail::g3(best->lo) + " to " + detail::g3(best->hi) + " " + U;
  }
  return where + ": " + detail::pct(best->excess_share) + " of the excess residual energy in " +
         detail::pct(best->sample_share) + " of the samples";
}

template <Physics P>
std::string explain(const Diagnosis<P>& d) {
  using detail::g3;
  const std::string yu = d.model.output_unit(), uu = d.model.input_unit();
  const std::string Y = yu.empty() ? "[y]" : yu;
  std::string s;
  const double ratio0 = std::sqrt(std::max(0.0, d.floor_before.ratio));
  const double ratio1 = std::sqrt(std::max(0.0, d.floor_after.ratio));
  s += "The baseline '" + d.baseline_name + "' model reaches a validation fit of " +
       detail::fits_text(d.baseline_val.fit) + "; its residual RMS is " + g3(ratio0) + " times the noise floor (sigma = " +
       g3(d.noise.sigma) + " " + Y + ").";
  if (d.floor_before.consistent) {
    s += " That is consistent with measurement noise alone: nothing is missing, and no effect was added.";
    return s;
  }
  const std::string where = mismatch_location(d.mismatch, yu, uu);
  if (!where.empty()) s += " The mismatch is largest " + where + ".";
  if (!d.mismatch.intervals.empty()) {
    s += " It exceeds the noise floor in " + std::to_string(d.mismatch.intervals.size()) + " time interval(s) covering " +
         detail::pct(d.mismatch.flagged_time_share) + " of the validation time and " +
         detail::pct(d.mismatch.flagged_energy_share) + " of its residual energy.";
  }
  int refits = 0;
  for (const SearchRound& r : d.rounds) refits += r.note.empty() ? 0 : 1;
  if (refits > 0) {
    s += " Part of it was a poorly converged baseline fit: a candidate effect led the optimiser out of a local "
         "minimum, but the baseline re-fitted from there did as well without it, so the re-fitted baseline was kept"
         " (no effect credited for that gain).";
  }
  for (const FoundEffect& f : d.inert) {
    s += " " + f.effect.label() + ", added in round " + std::to_string(f.round) +
         ", was made inactive by the later joint re-estimation (" + effect_magnitude(f.effect, d.scales, yu, uu) +
         ": the validation simulation is the same without it), so it was removed and is not named as missing physics.";
  }
  if (d.effects.empty()) {
    if (refits > 0 && d.floor_after.consistent) {
      s += " After that re-fit the residual is consistent with the noise floor (validation fit " +
           detail::fits_text(d.final_val.fit) + "): nothing is missing, and no effect was added.";
      return s;
    }
    const std::string kept = refits > 0 ? "no effect was added" : "the baseline is kept unchanged";
    switch (d.stop) {
      case SearchStop::effect_limit:
        s += " No catalogue effect was tried (max_effects = " + std::to_string(d.max_effects) + "), so " + kept + ".";
        return s;
      case SearchStop::catalogue_exhausted:
        if (!d.effects_asked.empty()) {
          std::string list;
          for (const std::string& n : d.effects_asked) list += (list.empty() ? "" : ", ") + n;
          s += " None of the effects asked for (" + list + ") applies to this baseline (see not_applicable), so " +
               kept + "; the rest of the catalogue was not tried.";
          return s;
        }
        s += " No catalogue effect applies to this baseline (see not_applicable), so " + kept + ".";
        return s;
      case SearchStop::repeated_refits:
        s += " The search stopped after repeated re-fits of the baseline without a new effect, so " + kept +
             "; the residual is still above the noise floor.";
        return s;
      default:
        break;
    }
    s += " None of the catalogue effects explains a significant part of it";
    // Only candidates refitted to convergence can be accepted (chosen by estimation cost, so that
    // the validation data judge but do not choose): quote the best of those, and say so when a
    // candidate that was not refitted scored higher on its short screening fit.
    const CandidateResult* screened = nullptr;
    if (!d.rounds.empty()) {
      const std::vector<CandidateResult>& cands = d.rounds.back().candidates;
      const auto refined = std::find_if(cands.begin(), cands.end(), [](const CandidateResult& c) { return c.ok && c.refined; });
      if (refined != cands.end())
        s += " (best refitted candidate " + refined->effect.label() + " removes " +
             detail::pct(std::max(0.0, refined->stats.relevance)) + " of the excess)";
      const auto first = std::find_if(cands.begin(), refined, [](const CandidateResult& c) {
        return c.ok && !c.refined && c.stats.significant;
      });
      if (first != refined) screened = &*first;
    }
    s += ", so " + kept + "; what is missing lies outside the catalogue (or is a disturbance rather than physics).";
    if (screened != nullptr)
      s += " " + screened->effect.label() + " passed the validation tests with its short screening fit, removing " +
           detail::pct(std::max(0.0, screened->stats.relevance)) +
           " of the excess, but its estimation cost was not among the lowest, so it was not refitted to "
           "convergence and could not be added; try it alone (nlid-diagnose --effects " + screened->effect.name() +
           ", DiagnoseOptions::effects) or raise refine_top (--refine-top).";
    return s;
  }
  s += " The missing physics is ";
  for (std::size_t i = 0; i < d.effects.size(); ++i) {
    const FoundEffect& f = d.effects[i];
    if (i) s += i + 1 == d.effects.size() ? ", and " : "; ";
    s += f.effect.name() + (f.effect.variant.empty() ? "" : " (" + f.effect.variant + ")") + " — " +
         effect_description(f.effect.kind) + " — with " + effect_magnitude(f.effect, d.scales, yu, uu);
  }
  s += ". Re-estimated by simulation error together with the baseline parameters, the model reaches " +
       detail::fits_text(d.final_val.fit) + " on the validation data (" +
       detail::gains_text(d.baseline_val.fit, d.final_val.fit) + ").";
  if (d.floor_after.consistent) {
    s += " The remaining residual is consistent with the noise floor.";
  } else {
    switch (d.stop) {
      case SearchStop::effect_limit:
        s += " The search stopped at its limit of " + std::to_string(d.max_effects) +
             " effect(s) (max_effects), so more may be missing";
        break;
      case SearchStop::catalogue_exhausted:
        s += d.effects_asked.empty() ? " Every applicable catalogue effect is now in the model"
                                     : " Every applicable effect asked for is now in the model (the rest of the "
                                       "catalogue was not tried)";
        break;
      case SearchStop::repeated_refits:
        s += " The search stopped after repeated re-fits without a new effect";
        break;
      default:
        s += " No further catalogue effect improved the validation fit significantly";
        break;
    }
    s += "; the remaining residual RMS is " + g3(ratio1) + " times the noise floor.";
  }
  return s;
}

}  // namespace nlid
