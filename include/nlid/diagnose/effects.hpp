#pragma once
/// @file
/// The effect catalogue: physical phenomena a grey-box baseline may have left out, each a
/// composable augmentation with physically meaningful parameters.
///
/// Structure. A baseline is the grey-box model ẋ = f(x, u, p), y = g(x, u, p) (greybox_concepts.hpp).
/// An effect acts at one of three sites:
///
///   input        u  →  u_e = A(u)           before the physics (actuator, driver, transport)
///   mechanical   v̇  =  f_v(x, u_e, p) + a_e(q, v)   in the acceleration equation
///   output       y_e = S(y)                 between the physics and the sensor reading
///
/// Mechanical effects need a position state q and a velocity state v with q̇ = v. They are found
/// by probing f, not by trusting names (augmented.hpp, `find_mechanical_roles`). Forces are written
/// per inertia — as accelerations, in units of the output per s² — because grey-box catalogue
/// models are normalised by the inertia (the throttle study's model is): a friction force F_c
/// on a valve of inertia J appears as F_c/J. Non-mechanical baselines (first_order, two_tank)
/// receive only the input and output effects; the others are reported "not applicable".
///
/// | name              | site       | law (v = q̇; one-sided variants named upper/lower)            | parameters                |
/// | ----------------- | ---------- | ------------------------------------------------------------- | ------------------------- |
/// | coulomb_friction  | mechanical | a = −F_c s, Dahl:  ds/dq = (1 − s·sgn q̇)/δ                   | F_c  [{y}/s²]             |
/// | viscous_friction  | mechanical | a = −c_v v                                                    | c_v  [1/s]                |
/// | quadratic_drag    | mechanical | a = −c_q v|v|                                                 | c_q  [1/{y}]              |
/// | cubic_stiffness   | mechanical | a = −k₃ (q − q_c)³                                           | k₃ [1/({y}²s²)], q_c [{y}] |
/// | hard_stop         | mechanical | a = −K_s max(q − q_s, 0)   (lower: +K_s max(q_s − q, 0))      | q_s [{y}], K_s [1/s²]     |
/// | preload           | mechanical | a = −P tanh((q − q_p)/w)   (a force step of height 2P at q_p) | P [{y}/s²], q_p [{y}]     |
/// | backlash          | mechanical | y_e = play_β(y): z ← min(max(z, y − β/2), y + β/2)            | β    [{y}]                |
/// | input_deadzone    | input      | u_e = u − clamp(u, −d, d)                                     | d    [{u}]                |
/// | input_saturation  | input      | u_e = min(u, u_max)        (lower: max(u, u_min))             | u_max or u_min [{u}]      |
/// | output_saturation | output     | y_e = min(y, y_max)        (lower: max(y, y_min))             | y_max or y_min [{y}]      |
/// | dead_time         | input      | u_e(t) = u(t − τ)                                             | τ    [s]                  |
/// | actuator_lag      | input      | T_a u̇_e = u − u_e                                            | T_a  [s]                  |
/// | input_offset      | input      | u_e = u + δ_u                                                 | δ_u  [{u}]                |
/// | output_offset     | output     | y_e = y + δ_y                                                 | δ_y  [{y}]                |
///
/// Smoothing, only as much as the optimiser needs, with every constant taken from the data:
///
/// - Coulomb friction is the Dahl model (Dahl 1968, Aerospace Corp. TR-0158(3107-18)-1; Olsson,
///   Åström, Canudas de Wit et al. 1998, Eur. J. Control 4, eq. 9): the friction state s ∈ [−1, 1]
///   follows the *displacement*, s(q + Δq) = σ + (s − σ) e^{−|Δq|/δ} with σ = sgn Δq, which the
///   simulator applies exactly after every integration sub-step. At rest s is frozen, so a stuck
///   valve stays stuck (no creep, unlike tanh(v/ε) smoothing, which lets a spring-loaded body
///   drift ε·F/F_c per second and needs ε so small that the ODE becomes stiff); in sliding
///   s → sgn v and the force is the classical F_c. The presliding displacement δ = 10⁻³ × the
///   position range; the bristle stiffness F_c/δ enters the sub-step rule.
/// - The preload step is a tanh of width w = 0.005 × the position range (its slope P/w enters the
///   sub-step rule).
/// - Dead-zone, saturations and stops are piecewise linear (their kinks are crossed by many
///   samples, which is all Levenberg–Marquardt needs).
/// - Dead time is fractional: τ = (m + α)T_s gives the sample-and-hold input
///   u_e(k) = (1 − α) u(k − m) + α u(k − m − 1), differentiable in τ between whole samples.
///
/// Scale-dependent parameters (positions, levels, offsets, forces) are initialised from the data
/// (`DataScales`), never from the units of one study; each candidate carries a few starting
/// points for its refit (`EffectCandidate::starts`).

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/models/greybox_concepts.hpp"

namespace nlid {

/// The phenomena of the catalogue (see the table in the file comment).
enum class EffectKind {
  coulomb_friction,
  viscous_friction,
  quadratic_drag,
  cubic_stiffness,
  hard_stop,
  preload,
  backlash,
  input_deadzone,
  input_saturation,
  output_saturation,
  dead_time,
  actuator_lag,
  input_offset,
  output_offset,
};

/// Number of effect kinds.
inline constexpr int num_effect_kinds = 14;

/// Where an effect acts on the baseline.
enum class EffectSite {
  input,       ///< transforms the input before the physics
  mechanical,  ///< adds to the acceleration of a position/velocity pair (or plays the output)
  output,      ///< transforms the output after the physics
};

/// Catalogue name of an effect kind, e.g. "coulomb_friction".
inline const char* effect_name(EffectKind k) {
  switch (k) {
    case EffectKind::coulomb_friction: return "coulomb_friction";
    case EffectKind::viscous_friction: return "viscous_friction";
    case EffectKind::quadratic_drag: return "quadratic_drag";
    case EffectKind::cubic_stiffness: return "cubic_stiffness";
    case EffectKind::hard_stop: return "hard_stop";
    case EffectKind::preload: return "preload";
    case EffectKind::backlash: return "backlash";
    case EffectKind::input_deadzone: return "input_deadzone";
    case EffectKind::input_saturation: return "input_saturation";
    case EffectKind::output_saturation: return "output_saturation";
    case EffectKind::dead_time: return "dead_time";
    case EffectKind::actuator_lag: return "actuator_lag";
    case EffectKind::input_offset: return "input_offset";
    case EffectKind::output_offset: return "output_offset";
  }
  return "unknown";
}

/// All effect kinds in catalogue order.
inline std::vector<EffectKind> all_effect_kinds() {
  std::vector<EffectKind> v;
  for (int i = 0; i < num_effect_kinds; ++i) v.push_back(static_cast<EffectKind>(i));
  return v;
}

/// Effect kind by catalogue name; throws `nlid::Error` listing the known names.
inline EffectKind effect_kind(std::string_view name) {
  for (EffectKind k : all_effect_kinds())
    if (name == effect_name(k)) return k;
  std::string known;
  for (EffectKind k : all_effect_kinds()) known += std::string(known.empty() ? "" : ", ") + effect_name(k);
  throw Error("unknown effect '" + std::string(name) + "'; known effects: " + known,
              at_parameter("effect"));
}

/// Site of an effect kind.
inline EffectSite effect_site(EffectKind k) {
  switch (k) {
    case EffectKind::input_deadzone:
    case EffectKind::input_saturation:
    case EffectKind::dead_time:
    case EffectKind::actuator_lag:
    case EffectKind::input_offset: return EffectSite::input;
    case EffectKind::output_saturation:
    case EffectKind::output_offset: return EffectSite::output;
    default: return EffectSite::mechanical;
  }
}

/// One-line physical description of an effect kind, for reports and explanations.
inline const char* effect_description(EffectKind k) {
  switch (k) {
    case EffectKind::coulomb_friction:
      return "dry (Coulomb) friction: a constant force opposing motion that also holds the body "
             "at rest, leaving a hysteresis band between up- and down-going moves";
    case EffectKind::viscous_friction:
      return "viscous friction: a force proportional to speed";
    case EffectKind::quadratic_drag:
      return "quadratic (aerodynamic/hydraulic) drag: a force growing with the square of speed";
    case EffectKind::cubic_stiffness:
      return "cubic (hardening or softening) stiffness: the spring force grows with the cube of "
             "the deflection";
    case EffectKind::hard_stop:
      return "a hard stop: a stiff contact that ends the travel at a position";
    case EffectKind::preload:
      return "a preload: a force step at a position (a preloaded spring pair or detent)";
    case EffectKind::backlash:
      return "backlash: play between the drive and the measured position, so the reading stalls "
             "when the motion reverses";
    case EffectKind::input_deadzone:
      return "an input dead zone: small commands produce no drive";
    case EffectKind::input_saturation:
      return "input saturation: the drive cannot exceed a limit";
    case EffectKind::output_saturation:
      return "output saturation: the sensor reading is clipped at a limit";
    case EffectKind::dead_time:
      return "dead time: the response starts a fixed time after the command";
    case EffectKind::actuator_lag:
      return "actuator lag: the drive follows the command through a first-order lag";
    case EffectKind::input_offset:
      return "an input offset: the drive sees the command plus a constant bias";
    case EffectKind::output_offset:
      return "an output (sensor) offset: the reading is shifted by a constant";
  }
  return "";
}

/// One effect in a model: its kind, one-sided variant, parameters and data-derived shape
/// constants. Invariant: `params` has the count and order listed in the file comment.
struct Effect {
  EffectKind kind = EffectKind::coulomb_friction;  ///< the phenomenon
  /// "upper" or "lower" for hard_stop, input_saturation and output_saturation; empty otherwise.
  std::string variant;
  /// Estimated parameters, with names (unique within the effect), units, values and bounds.
  std::vector<ParameterInfo> params;
  /// Shape constant, not estimated: presliding displacement δ (coulomb_friction), transition
  /// width w (preload) or the travel L that bounds the cubic's stiffness in the sub-step rule
  /// (cubic_stiffness), in output units; 0 for other effects.
  double width = 0.0;
  /// Typical speed (output units/s) used to bound the stiffness of quadratic drag.
  double speed = 0.0;

  /// Catalogue name, e.g. "hard_stop".
  [[nodiscard]] std::string name() const { return effect_name(kind); }
  /// Name with the variant, e.g. "hard_stop (upper)".
  [[nodiscard]] std::string label() const {
    return variant.empty() ? name() : name() + " (" + variant + ")";
  }
  /// Value of a named parameter; throws `nlid::Error` naming it if unknown.
  [[nodiscard]] double value(std::string_view pname) const {
    for (const ParameterInfo& p : params)
      if (p.name == pname) return p.value;
    throw Error("effect " + label() + " has no parameter '" + std::string(pname) + "'",
                at_parameter(std::string(pname)));
  }
};

/// Scales read off the data and the fitted baseline, used to place effect parameters without
/// assuming units. All are in the data's own units.
struct DataScales {
  double ts = 1.0;          ///< sample time
  double y_lo = 0.0;        ///< 0.5 % quantile of the measured output
  double y_hi = 1.0;        ///< 99.5 % quantile of the measured output
  double y_min = 0.0;       ///< smallest measured output
  double y_max = 1.0;       ///< largest measured output
  double u_lo = 0.0;        ///< 0.5 % quantile of the input
  double u_hi = 1.0;        ///< 99.5 % quantile of the input
  double u_abs = 1.0;       ///< largest |u|
  double q_lo = 0.0;        ///< 0.5 % quantile of the simulated position (mechanical baselines)
  double q_hi = 1.0;        ///< 99.5 % quantile of the simulated position
  double q_mid = 0.5;       ///< median of the simulated position
  double speed = 1.0;       ///< 95 % quantile of |simulated velocity|
  double accel = 1.0;       ///< 95 % quantile of |simulated acceleration|
  double stiffness = 0.0;   ///< median |∂v̇/∂q| of the baseline along the trajectory (1/s²)
  double rest_position = std::numeric_limits<double>::quiet_NaN();  ///< q at equilibrium, u = 0
  /// Position range q_hi − q_lo, never zero.
  [[nodiscard]] double q_range() const { return std::max(q_hi - q_lo, 1e-9 * std::max(1.0, std::abs(q_hi))); }
  /// Output range y_hi − y_lo, never zero.
  [[nodiscard]] double y_range() const { return std::max(y_hi - y_lo, 1e-9 * std::max(1.0, std::abs(y_hi))); }
  /// Input range u_hi − u_lo, never zero.
  [[nodiscard]] double u_range() const { return std::max(u_hi - u_lo, 1e-9 * std::max(1.0, u_abs)); }
  /// Force (acceleration) scale: the spring force over 10 % of the travel when there is a spring,
  /// else 10 % of the typical acceleration.
  [[nodiscard]] double force() const {
    const double f = stiffness > 0.0 ? 0.1 * stiffness * q_range() : 0.1 * accel;
    return f > 0.0 ? f : 1.0;
  }
};

/// A candidate effect ready for a refit: the effect with its parameter table and several
/// starting points (one vector of parameter values each; the refit keeps the best).
struct EffectCandidate {
  Effect effect;                          ///< the effect (parameter values = first start)
  std::vector<Eigen::VectorXd> starts;    ///< starting values of `effect.params`
};

/// Why an effect kind cannot be tried on a baseline ("" if it can).
inline std::string effect_not_applicable_reason(EffectKind k, bool mechanical) {
  if (effect_site(k) == EffectSite::mechanical && !mechanical)
    return "not applicable: the baseline has no position/velocity state pair (q' = v)";
  return {};
}

/// The candidate(s) of one effect kind for a baseline with the given scales (one per variant).
/// Starting values are multiples of the data scales (see the file comment).
inline std::vector<EffectCandidate> make_effect_candidates(EffectKind k, const DataScales& s);

// ------------------------------------------------------------------------------------------
// Implementation details below.
// ------------------------------------------------------------------------------------------

namespace detail {

inline ParameterInfo effect_param(std::string name, std::string unit, std::string description,
                                  double value, double lower, double upper, bool log_scale = false) {
  ParameterInfo p;
  p.name = std::move(name);
  p.unit = std::move(unit);
  p.description = std::move(description);
  p.value = std::clamp(value, lower, upper);
  p.lower = lower;
  p.upper = upper;
  p.log_scale = log_scale;
  return p;
}

inline Eigen::VectorXd vec(std::initializer_list<double> v) {
  Eigen::VectorXd x(static_cast<Eigen::Index>(v.size()));
  Eigen::Index i = 0;
  for (double d : v) x(i++) = d;
  return x;
}

}  // namespace detail

inline std::vector<EffectCandidate> make_effect_candidates(EffectKind k, const DataScales& s) {
  constexpr double inf = std::numeric_limits<double>::infinity();
  const double L = s.q_range(), F = s.force();
  const double V = std::max(s.speed, 1e-9 * L / s.ts);
  std::vector<EffectCandidate> out;
  auto one = [&](Effect e, std::vector<Eigen::VectorXd> starts) {
    for (std::size_t i = 0; i < e.params.size(); ++i) e.params[i].value = starts.front()(static_cast<Eigen::Index>(i));
    out.push_back({std::move(e), std::move(starts)});
  };
  Effect e;
  e.kind = k;
  using detail::effect_param;
  using detail::vec;
  switch (k) {
    case EffectKind::coulomb_friction:
      e.width = 1e-3 * L;
      e.params = {effect_param("Fc", "{y}/s^2", "Coulomb friction force / inertia", 0, 0, inf, true)};
      one(e, {vec({0.0}), vec({0.3 * F})});
      break;
    case EffectKind::viscous_friction:
      e.params = {effect_param("cv", "1/s", "viscous friction coefficient / inertia", 0, 0, inf, true)};
      one(e, {vec({0.0})});  // linear in c_v: one start suffices
      break;
    case EffectKind::quadratic_drag:
      e.speed = V;
      e.params = {effect_param("cq", "1/{y}", "quadratic drag coefficient / inertia", 0, 0, inf, true)};
      one(e, {vec({0.0}), vec({0.3 * s.accel / (V * V)})});  // zero and a visible drag
      break;
    case EffectKind::cubic_stiffness: {
      // The centre q_c is estimated: a hardening spring is cubic about its own free position,
      // which need not be the middle of the recorded travel. Starts: at the rest position (where
      // a return spring is unloaded) if the baseline has one inside the travel, else mid-travel.
      e.width = L;
      const double h = 0.5 * L;
      const bool rest_inside = std::isfinite(s.rest_position) && s.rest_position > s.q_lo - 0.1 * L &&
                               s.rest_position < s.q_hi + 0.1 * L;
      const double qc = rest_inside ? s.rest_position : 0.5 * (s.q_lo + s.q_hi);
      e.params = {effect_param("k3", "1/({y}^2*s^2)", "cubic stiffness / inertia", 0, -inf, inf),
                  effect_param("centre", "{y}", "position about which the spring is cubic", qc, -inf, inf)};
      const double k3 = 3.0 * F / (h * h * h);
      one(e, {vec({0.0, qc}), vec({k3, qc}), vec({k3, 0.5 * (s.q_lo + s.q_hi)}), vec({-0.3 * k3, qc})});
      break;
    }
    case EffectKind::hard_stop: {
      const double K = s.stiffness > 0.0 ? 20.0 * s.stiffness : 20.0 * s.accel / L;
      for (int side = 0; side < 2; ++side) {
        Effect h = e;
        const bool upper = side == 0;
        h.variant = upper ? "upper" : "lower";
        h.params = {effect_param("position", "{y}", std::string(upper ? "upper" : "lower") + " stop position", 0, -inf, inf),
                    effect_param("K", "1/s^2", "contact stiffness / inertia", K, 0, inf, true)};
        const double edge = upper ? s.y_max : s.y_min;
        const double in = upper ? s.q_hi - 0.05 * L : s.q_lo + 0.05 * L;
        one(h, {vec({edge, K}), vec({in, K})});
      }
      break;
    }
    case EffectKind::preload: {
      e.width = 5e-3 * L;
      e.params = {effect_param("P", "{y}/s^2", "preload force step (half height) / inertia", 0, -inf, inf),
                  effect_param("position", "{y}", "position of the force step", s.q_mid, -inf, inf)};
      // A zero-height start (never worse than the baseline), then visible steps at the rest
      // position (where preloaded return springs sit) and across the travel.
      std::vector<Eigen::VectorXd> st{vec({0.0, s.q_mid})};
      const bool rest_inside = std::isfinite(s.rest_position) && s.rest_position > s.q_lo - 0.1 * L &&
                               s.rest_position < s.q_hi + 0.1 * L;
      st.push_back(vec({0.3 * F, rest_inside ? s.rest_position : s.q_mid}));
      for (double f : {0.25, 0.75}) st.push_back(vec({0.3 * F, s.q_lo + f * L}));
      one(e, st);
      break;
    }
    case EffectKind::backlash:
      e.params = {effect_param("width", "{y}", "total play (dead band) between drive and reading", 0, 0, inf, true)};
      one(e, {vec({0.0}), vec({0.02 * L})});
      break;
    case EffectKind::input_deadzone:
      e.params = {effect_param("d", "{u}", "dead-zone half width around zero command", 0, 0, inf, true)};
      one(e, {vec({0.0}), vec({0.05 * s.u_abs})});
      break;
    case EffectKind::input_saturation:
      for (int side = 0; side < 2; ++side) {
        Effect h = e;
        const bool upper = side == 0;
        h.variant = upper ? "upper" : "lower";
        h.params = {effect_param(upper ? "u_max" : "u_min", "{u}",
                                 std::string(upper ? "upper" : "lower") + " input limit", 0, -inf, inf)};
        const double R = s.u_range();
        if (upper)
          one(h, {vec({s.u_hi - 0.15 * R}), vec({s.u_hi - 0.4 * R})});
        else
          one(h, {vec({s.u_lo + 0.15 * R}), vec({s.u_lo + 0.4 * R})});
      }
      break;
    case EffectKind::output_saturation:
      for (int side = 0; side < 2; ++side) {
        Effect h = e;
        const bool upper = side == 0;
        h.variant = upper ? "upper" : "lower";
        h.params = {effect_param(upper ? "y_max" : "y_min", "{y}",
                                 std::string(upper ? "upper" : "lower") + " output (sensor) limit", 0, -inf, inf)};
        const double R = s.y_range();
        if (upper)
          one(h, {vec({s.y_max}), vec({s.y_hi - 0.1 * R})});
        else
          one(h, {vec({s.y_min}), vec({s.y_lo + 0.1 * R})});
      }
      break;
    case EffectKind::dead_time:
      e.params = {effect_param("tau", "s", "dead time", 0, 0, 50.0 * s.ts)};
      one(e, {vec({1.5 * s.ts}), vec({4.0 * s.ts})});
      break;
    case EffectKind::actuator_lag:
      e.params = {effect_param("T", "s", "actuator time constant", 0, 0.05 * s.ts, inf, true)};
      one(e, {vec({1.5 * s.ts}), vec({5.0 * s.ts})});
      break;
    case EffectKind::input_offset:
      e.params = {effect_param("offset", "{u}", "bias added to the command", 0, -inf, inf)};
      one(e, {vec({0.0})});
      break;
    case EffectKind::output_offset:
      e.params = {effect_param("offset", "{y}", "sensor offset added to the reading", 0, -inf, inf)};
      one(e, {vec({0.0})});
      break;
  }
  return out;
}

}  // namespace nlid
