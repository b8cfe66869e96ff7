#pragma once
/// @file
/// `AugmentedModel<P>`: a grey-box baseline physics P with effects from the catalogue
/// (effects.hpp) composed around it — the model a diagnosis refits, scores and returns.
///
/// Composition. With baseline ẋ = f(x, u, p), y = g(x, u, p) (greybox_concepts.hpp) and effects
/// split by site, one sample interval [t_k, t_{k+1}) of the augmented model is
///
///     u_e(k)  = A(u; k)                   input chain: dead_time → input_offset →
///                                         input_deadzone → input_saturation (upper, lower)
///     ẋ       = f(x, w, p) + e_v·a_e(q, v, s)   (w = u_e, or the actuator_lag state
///     ẇ       = (u_e − w)/T_a                    when that effect is present)
///     ŷ(k)    = S(g(x(t_k), w, p); k)     output chain: backlash play → output_saturation →
///                                         output_offset
///
/// where e_v selects the velocity state and a_e sums the mechanical effects (viscous, drag,
/// cubic stiffness, stops, preload, Coulomb). The order of each chain is the physical signal
/// path (transport delay before the driver's bias, dead zone and limit; the sensor's play before
/// its clipping and offset), fixed so that a model reads the same whichever order the search
/// found its effects in.
///
/// Integration. Each sample interval is split into n sub-steps of classical RK4 on the
/// continuous states [x; w] with the input held (zero-order hold, as `simulate_physics` in
/// greybox_simulate.hpp). n follows the sub-step rule of integrators.hpp,
/// n = ⌈T_s ρ / s⌉, with ρ the baseline's spectral-radius bound plus the stiffness each effect
/// adds: c_v, 2c_q·3V (drag at three times the typical speed V), √(3|k₃|)·L (cubic, L the
/// travel), √K_s (stop), √(|P|/w) (preload slope), √(F_c/δ) (Dahl presliding stiffness) and
/// 1/T_a (lag). The Dahl friction state and the play state are updated exactly between
/// sub-steps / samples (effects.hpp), so they add no stiffness of their own.
///
/// Parameters. θ = [p; θ_effect₁; θ_effect₂; …] in the order effects were added; names in the
/// combined table are "<effect>.<parameter>" (e.g. "coulomb_friction.Fc"), so they never clash
/// with a baseline name. Initial state x₀ is the baseline's (n_x values); the effect states start
/// from the first sample: w(0) = u_e(0) (actuator at rest), s(0) = 0 (no friction memory), play
/// centred on the first reading, dead-time history filled with u(0).
///
/// Scalars. Everything is templated on T ∈ {double, Dual<double, 8>} (the scalars every
/// `Physics` evaluates on); a Dual run gives the exact sensitivities of the *discrete* map that
/// produced the double run (same sub-step count, same branches), which the refit uses.
///
/// Structural roles. `find_mechanical_roles` probes f at random states: a pair (q, v) with
/// f_q(x, u, p) = x_v identically is a position/velocity pair, and v's derivative is the
/// acceleration equation. No names or units are trusted.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "nlid/ad/dual.hpp"
#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/core/initial_condition.hpp"
#include "nlid/core/sample_time.hpp"
#include "nlid/core/sizes.hpp"
#include "nlid/data/experiment.hpp"
#include "nlid/diagnose/effects.hpp"
#include "nlid/estimation/levenberg_marquardt.hpp"
#include "nlid/estimation/problem.hpp"
#include "nlid/models/greybox_concepts.hpp"
#include "nlid/models/greybox_simulate.hpp"
#include "nlid/models/integrators.hpp"

namespace nlid {

/// Position/velocity roles of a baseline's states (mechanical effects need them).
struct MechanicalRoles {
  bool mechanical = false;  ///< a pair with q̇ = v was found
  int position = -1;        ///< index of q in x
  int velocity = -1;        ///< index of v in x
  bool output_is_position = false;  ///< g(x) = q (then output levels are positions)
};

/// Probes `phys` at parameters `p` for a position/velocity pair (see the file comment).
template <Physics P>
MechanicalRoles find_mechanical_roles(const P& phys, std::span<const double> p);

/// A baseline physics with catalogue effects composed around it (see the file comment).
/// Single-input single-output effects: input effects act on input 0, output effects on
/// output 0. Invariants: parameter values lie within their bounds; at most one effect of each
/// (kind, variant); mechanical effects only on a mechanical baseline.
template <Physics P>
class AugmentedModel {
 public:
  using physics_type = P;  ///< the baseline physics

  /// The baseline alone, with parameter table `base` (values, bounds, fixed flags; size n_p) and
  /// sample time `ts`. Mechanical roles are probed at the table's values. Throws `nlid::Error` if
  /// the table's size differs from the physics' parameter count or `ts` is not positive.
  AugmentedModel(P physics, std::vector<ParameterInfo> base, double ts);

  /// Adds an effect (its parameter values are the starting values). Throws `nlid::Error` if it
  /// is not applicable (mechanical effect, non-mechanical baseline), already present, or its
  /// parameter count is wrong.
  void add_effect(Effect effect);
  /// A copy with one more effect.
  [[nodiscard]] AugmentedModel with_effect(Effect effect) const {
    AugmentedModel m = *this;
    m.add_effect(std::move(effect));
    return m;
  }

  /// The baseline physics.
  [[nodiscard]] const P& physics() const { return phys_; }
  /// Structural roles of the baseline states.
  [[nodiscard]] const MechanicalRoles& roles() const { return roles_; }
  /// Effects in the order they were added (parameter values current).
  [[nodiscard]] const std::vector<Effect>& effects() const { return effects_; }
  /// Baseline parameter table (values current).
  [[nodiscard]] const std::vector<ParameterInfo>& baseline_parameters() const { return base_; }
  /// Sample time the model was built for.
  [[nodiscard]] double ts() const { return ts_; }
  /// Number of baseline states n_x (the length of an initial state x₀).
  [[nodiscard]] int state_dimension() const { return detail::physics_states(phys_); }
  /// Total parameter count (baseline + effects).
  [[nodiscard]] int num_parameters() const { return static_cast<int>(base_.size()) + num_effect_params_; }
  /// Offset of effect i's parameters in θ.
  [[nodiscard]] int effect_offset(std::size_t i) const { return offsets_.at(i); }

  /// Combined parameter table: baseline names, then "<effect>.<name>" (see the file comment).
  [[nodiscard]] std::vector<ParameterInfo> parameter_info() const;
  /// Current θ.
  [[nodiscard]] Eigen::VectorXd parameters() const;
  /// Sets θ; throws `nlid::Error` naming the first value that is not finite or out of bounds.
  void set_parameters(const Eigen::Ref<const Eigen::VectorXd>& theta);
  /// Units substituted for "{y}" and "{u}" in reports.
  void set_units(std::string output_unit, std::string input_unit) {
    y_unit_ = std::move(output_unit);
    u_unit_ = std::move(input_unit);
  }
  /// Input channel names (the data's, one per physics input; empty if unknown).
  [[nodiscard]] const std::vector<std::string>& input_names() const { return input_names_; }
  /// Output channel names (one; empty if unknown).
  [[nodiscard]] const std::vector<std::string>& output_names() const { return output_names_; }
  /// Sets the channel names (from the estimation data or a model file). Throws `nlid::Error`
  /// naming "input_names"/"output_names" if a non-empty list has the wrong length.
  void set_channel_names(std::vector<std::string> inputs, std::vector<std::string> outputs) {
    require(inputs.empty() || static_cast<int>(inputs.size()) == detail::physics_inputs(phys_),
            "augmented model: " + std::to_string(inputs.size()) + " input names for " +
                std::to_string(detail::physics_inputs(phys_)) + " input(s)",
            at_parameter("input_names"));
    require(outputs.size() <= 1, "augmented model: one output name (or none)", at_parameter("output_names"));
    input_names_ = std::move(inputs);
    output_names_ = std::move(outputs);
  }
  /// Output unit ("" if unknown).
  [[nodiscard]] const std::string& output_unit() const { return y_unit_; }
  /// Input unit ("" if unknown).
  [[nodiscard]] const std::string& input_unit() const { return u_unit_; }
  /// Integrator settings (RK4 with the automatic sub-step rule by default; only `rk4` is
  /// supported, because the Dahl and play updates are placed between fixed sub-steps).
  [[nodiscard]] const IntegratorOptions& integrator() const { return integ_; }
  /// Sets the integrator settings; throws `nlid::Error` for an invalid option or a non-RK4 method.
  void set_integrator(const IntegratorOptions& o) {
    validate(o);
    require(o.method == IntegratorMethod::rk4,
            "augmented models integrate with rk4 only (friction and play states are updated "
            "between fixed sub-steps)",
            at_parameter("method"));
    integ_ = o;
  }

  /// Sub-steps per sample at parameter values `theta` judged at the start (see the file
  /// comment); a run's own count, for a baseline physics without `spectral_radius`, also covers
  /// the states the run reaches: `substeps(theta, x0, u)`.
  [[nodiscard]] int substeps(const double* theta, const double* x0, const double* u0) const {
    return substeps_for(ts_, stiffness(theta, x0, u0), integ_);
  }
  /// Sub-steps per sample of `simulate` over the inputs u (N × n_u): the count at the start, and
  /// for a baseline physics that does not know its spectral radius the largest Gershgorin bound
  /// of its ∂f/∂x along a run at that count (plus each effect's rate), as `physics_substeps` for
  /// a plain grey box — a bound at the start alone can be far below the stiffest state.
  [[nodiscard]] int substeps(const double* theta, const double* x0, const Eigen::MatrixXd& u) const;
  /// The stiffness estimate ρ [1/s] behind `substeps`: the physics' spectral radius at (x0, u0)
  /// (or a Gershgorin bound of its Jacobian) plus each effect's own rate.
  [[nodiscard]] double stiffness(const double* theta, const double* x0, const double* u0) const;
  /// The effects' part of `stiffness`: the sum of each effect's own rate (state-independent).
  [[nodiscard]] double effects_rate(const double* theta) const;

  // ---- one sample, piece by piece ----------------------------------------------------------
  // `simulate` is built from these members; the C generator (codegen/augmented.hpp) traces
  // them, so the generated step performs the same operations in the same order.

  /// Whole samples m of the dead time at parameter values `theta` (0 without a dead time):
  /// u_e(k) interpolates between u(k − m) and u(k − m − 1).
  [[nodiscard]] int dead_time_samples(const double* theta) const;
  /// True if the input chain has a dead time.
  [[nodiscard]] bool has_dead_time() const {
    return std::any_of(input_chain_.begin(), input_chain_.end(),
                       [&](int i) { return effects_[static_cast<std::size_t>(i)].kind == EffectKind::dead_time; });
  }
  /// True if the actuator-lag state w follows the chain output (else w stays 0 and the physics
  /// reads the chain output directly).
  [[nodiscard]] bool has_actuator_lag() const { return lag_ >= 0; }
  /// True if the Dahl friction state is carried (Coulomb friction).
  [[nodiscard]] bool has_coulomb_friction() const { return coulomb_ >= 0; }
  /// The input chain u_e(k) from the raw input u(k) and the delayed samples u(k − m),
  /// u(k − m − 1) (`m = dead_time_samples`; before the record starts they are u(0)).
  template <class T>
  [[nodiscard]] T input_chain(const T* theta, const T& u_k, const T& u_km, const T& u_km1, int m) const;
  /// [ẋ; ẇ] at s = [x; w] with the chain output `u_static` held and Dahl state `fric`; `uin`
  /// is the physics' input vector (entries 1… set by the caller, entry 0 set here).
  template <class T>
  void augmented_derivative(const T* s, const T& u_static, const T& fric, const T* theta, T* uin, T* ds) const;
  /// ŷ(k) at the state X = [x; w]: the physics output (entry 0) through the output chain. `play`
  /// is the backlash state; on the `first` sample it starts at the physics output. `uin` and
  /// `yb` are scratch of the physics' input and output sizes (uin entries 1… set by the caller).
  template <class T>
  [[nodiscard]] T output_at(const T* X, const T& u_static, const T* theta, T* uin, T* yb, T& play, bool first) const;
  /// The Dahl friction state after a sub-step that moved the position by `dq` (exact update,
  /// effects.hpp); unchanged for dq = 0.
  template <class T>
  [[nodiscard]] T friction_after(const T& fric, const T& dq) const;

  /// Core free-run simulation on scalar T (double or Dual<double, 8>): inputs `u` (N × n_u),
  /// parameters `theta` (num_parameters()), baseline initial state `x0` (n_x); writes N outputs
  /// (output 0) to `y`. Returns the number of samples delivered (N, or fewer if the simulation
  /// left the finite numbers).
  /// If `states` is not null it receives the N × n_x baseline states, row k (row-major) at t_k.
  template <class T>
  Eigen::Index simulate(const Eigen::MatrixXd& u, const T* theta, const T* x0, T* y,
                        T* states = nullptr) const;
  /// `simulate` with a given sub-step count (≥ 1).
  template <class T>
  Eigen::Index simulate_with_substeps(const Eigen::MatrixXd& u, const T* theta, const T* x0, T* y, T* states,
                                      int sub) const;

  /// Free run of an experiment from `x0` at the current parameters: N × 1 outputs. Throws
  /// `nlid::Error` on a channel mismatch or a diverging simulation (naming the sample).
  [[nodiscard]] Eigen::MatrixXd simulate(const Experiment& e, const Eigen::VectorXd& x0) const;
  /// Free run under an initial-condition policy: `zero`, `equilibrium` (baseline equilibrium for
  /// the first input), or `estimate` (x₀ fitted to the record, see `estimate_initial_state`).
  /// `measured` does not apply to a state-space model and throws.
  [[nodiscard]] Eigen::MatrixXd simulate(const Experiment& e, InitialCondition ic) const;
  /// k-step prediction. An output-error model has no noise model, so its predictor is the
  /// simulation itself (Ljung 1999, eq. 4.113 with H = 1): returns `simulate(e, estimate)`.
  [[nodiscard]] Eigen::MatrixXd predict(const Experiment& e, int /*k*/) const {
    return simulate(e, InitialCondition::estimate);
  }
  /// Initial-state guess for a record: the physics' `initial_state` hook if it has one, else the
  /// baseline equilibrium for the first input, else zero.
  [[nodiscard]] Eigen::VectorXd initial_state_guess(const Experiment& e) const;
  /// Initial state that minimises the simulation error of the record at the current parameters
  /// (Levenberg–Marquardt over x₀ only, from `initial_state_guess`).
  [[nodiscard]] Eigen::VectorXd estimate_initial_state(const Experiment& e, int max_iterations = 20) const;

  /// Equation, effects with their laws, and every parameter with unit and value.
  [[nodiscard]] std::string describe() const;

  /// Checks that an experiment can be simulated (one output, the physics' input count, at least
  /// two samples); throws naming experiment `index`.
  void check_experiment(const Experiment& e, long index = -1) const;

 private:
  void rebuild_layout();

  P phys_;
  std::vector<ParameterInfo> base_;
  std::vector<Effect> effects_;
  std::vector<int> offsets_;
  int num_effect_params_ = 0;
  MechanicalRoles roles_;
  double ts_ = 1.0;
  IntegratorOptions integ_;
  std::string y_unit_, u_unit_;
  std::vector<std::string> input_names_, output_names_;
  // Indices into effects_ by site, in the fixed chain order.
  std::vector<int> input_chain_, mech_, output_chain_;
  std::vector<char> upper_;  // per effect: the one-sided variant is "upper" (no string compare per sample)
  int lag_ = -1, coulomb_ = -1;
};

// ------------------------------------------------------------------------------------------
// Implementation details below.
// ------------------------------------------------------------------------------------------

template <Physics P>
MechanicalRoles find_mechanical_roles(const P& phys, std::span<const double> p) {
  MechanicalRoles r;
  const int nx = detail::physics_states(phys), nu = detail::physics_inputs(phys),
            ny = detail::physics_outputs(phys);
  std::mt19937 rng(12345u);
  std::normal_distribution<double> g(0.0, 1.0);
  constexpr int probes = 4;
  std::vector<std::vector<double>> xs, dxs, ys;
  for (int t = 0; t < probes; ++t) {
    std::vector<double> x(static_cast<std::size_t>(nx)), u(static_cast<std::size_t>(std::max(nu, 1))),
        dx(static_cast<std::size_t>(nx)), y(static_cast<std::size_t>(ny));
    for (double& v : x) v = 0.5 + g(rng);
    for (double& v : u) v = g(rng);
    phys.derivative(x.data(), u.data(), p.data(), dx.data());
    phys.output(x.data(), u.data(), p.data(), y.data());
    xs.push_back(x);
    dxs.push_back(dx);
    ys.push_back(y);
  }
  auto same = [](double a, double b) { return std::abs(a - b) <= 1e-12 * (1.0 + std::abs(b)); };
  for (int i = 0; i < nx && !r.mechanical; ++i) {
    for (int j = 0; j < nx; ++j) {
      if (i == j) continue;
      bool all = true;
      for (int t = 0; t < probes && all; ++t)
        all = same(dxs[static_cast<std::size_t>(t)][static_cast<std::size_t>(i)],
                   xs[static_cast<std::size_t>(t)][static_cast<std::size_t>(j)]);
      if (all) {
        r.mechanical = true;
        r.position = i;
        r.velocity = j;
        break;
      }
    }
  }
  if (r.mechanical) {
    bool all = true;
    for (int t = 0; t < probes && all; ++t)
      all = same(ys[static_cast<std::size_t>(t)][0],
                 xs[static_cast<std::size_t>(t)][static_cast<std::size_t>(r.position)]);
    r.output_is_position = all;
  }
  return r;
}

template <Physics P>
AugmentedModel<P>::AugmentedModel(P physics, std::vector<ParameterInfo> base, double ts)
    : phys_(std::move(physics)), base_(std::move(base)), ts_(ts) {
  require(static_cast<int>(base_.size()) == detail::physics_params(phys_),
          "augmented model: parameter table has " + std::to_string(base_.size()) +
              " entries but the physics has " + std::to_string(detail::physics_params(phys_)));
  require(ts > 0.0 && std::isfinite(ts), "augmented model: sample time must be positive",
          at_parameter("ts"));
  std::vector<double> p;
  for (const ParameterInfo& q : base_) p.push_back(q.value);
  physics_check_parameters(phys_, p.data(), "augmented model: the baseline's values");
  roles_ = find_mechanical_roles(phys_, std::span<const double>(p));
  rebuild_layout();
}

template <Physics P>
void AugmentedModel<P>::rebuild_layout() {
  offsets_.clear();
  int off = static_cast<int>(base_.size());
  num_effect_params_ = 0;
  for (const Effect& e : effects_) {
    offsets_.push_back(off);
    off += static_cast<int>(e.params.size());
    num_effect_params_ += static_cast<int>(e.params.size());
  }
  input_chain_.clear();
  mech_.clear();
  output_chain_.clear();
  lag_ = coulomb_ = -1;
  upper_.clear();
  for (const Effect& e : effects_) upper_.push_back(e.variant == "upper" ? 1 : 0);
  auto find = [&](EffectKind k, const char* variant) {
    for (std::size_t i = 0; i < effects_.size(); ++i)
      if (effects_[i].kind == k && effects_[i].variant == variant) return static_cast<int>(i);
    return -1;
  };
  auto push = [](std::vector<int>& v, int i) {
    if (i >= 0) v.push_back(i);
  };
  push(input_chain_, find(EffectKind::dead_time, ""));
  push(input_chain_, find(EffectKind::input_offset, ""));
  push(input_chain_, find(EffectKind::input_deadzone, ""));
  push(input_chain_, find(EffectKind::input_saturation, "upper"));
  push(input_chain_, find(EffectKind::input_saturation, "lower"));
  lag_ = find(EffectKind::actuator_lag, "");
  push(output_chain_, find(EffectKind::backlash, ""));
  push(output_chain_, find(EffectKind::output_saturation, "upper"));
  push(output_chain_, find(EffectKind::output_saturation, "lower"));
  push(output_chain_, find(EffectKind::output_offset, ""));
  for (std::size_t i = 0; i < effects_.size(); ++i) {
    const EffectKind k = effects_[i].kind;
    if (effect_site(k) == EffectSite::mechanical && k != EffectKind::backlash)
      mech_.push_back(static_cast<int>(i));
    if (k == EffectKind::coulomb_friction) coulomb_ = static_cast<int>(i);
  }
}

namespace detail {
inline std::size_t expected_effect_params(EffectKind k) {
  switch (k) {
    case EffectKind::hard_stop:
    case EffectKind::cubic_stiffness:
    case EffectKind::preload: return 2;
    default: return 1;
  }
}
}  // namespace detail

template <Physics P>
void AugmentedModel<P>::add_effect(Effect effect) {
  const std::string why = effect_not_applicable_reason(effect.kind, roles_.mechanical);
  require(why.empty(), "effect " + effect.label() + " " + why, at_parameter(effect.name()));
  for (const Effect& e : effects_)
    require(!(e.kind == effect.kind && e.variant == effect.variant),
            "effect " + effect.label() + " is already part of the model", at_parameter(effect.name()));
  require(effect.params.size() == detail::expected_effect_params(effect.kind),
          "effect " + effect.label() + " needs " +
              std::to_string(detail::expected_effect_params(effect.kind)) + " parameter(s), got " +
              std::to_string(effect.params.size()),
          at_parameter(effect.name()));
  const bool one_sided = effect.kind == EffectKind::hard_stop ||
                         effect.kind == EffectKind::input_saturation ||
                         effect.kind == EffectKind::output_saturation;
  require(one_sided ? (effect.variant == "upper" || effect.variant == "lower") : effect.variant.empty(),
          "effect " + effect.label() + ": variant must be " +
              (one_sided ? std::string("'upper' or 'lower'") : std::string("empty")),
          at_parameter(effect.name()));
  for (ParameterInfo& q : effect.params) {
    require(std::isfinite(q.value) && q.value >= q.lower && q.value <= q.upper,
            "effect " + effect.label() + ": parameter '" + q.name + "' = " + detail::format_f(q.value, 6) +
                " is not finite or outside its bounds",
            at_parameter(effect.name() + "." + q.name));
  }
  if (effect.kind == EffectKind::dead_time) {
    // τ / ts is a count of samples (a delay line in the simulation and in generated C): every value
    // the bounds allow must be one, 0 … max_model_order like any delay. A negative τ read before the
    // record's start, 1e300 s overflowed the int count, 1e6 s generated 500 MB of C.
    const ParameterInfo& q = effect.params.front();
    require(q.lower >= 0.0 && q.upper / ts_ <= static_cast<double>(max_model_order),
            "effect " + effect.label() + ": the bounds of '" + q.name + "' must lie in [0, " +
                detail::format_g(max_model_order * ts_) + "] s (0 … " + std::to_string(max_model_order) +
                " samples of " + detail::format_g(ts_) + " s), got [" + detail::format_g(q.lower) + ", " +
                detail::format_g(q.upper) + "]",
            at_parameter(effect.name() + "." + q.name));
  }
  const bool needs_width = effect.kind == EffectKind::coulomb_friction || effect.kind == EffectKind::preload ||
                           effect.kind == EffectKind::cubic_stiffness;
  require(!needs_width || effect.width > 0.0,
          "effect " + effect.label() + ": shape width must be positive", at_parameter(effect.name()));
  effects_.push_back(std::move(effect));
  rebuild_layout();
}

template <Physics P>
std::vector<ParameterInfo> AugmentedModel<P>::parameter_info() const {
  std::vector<ParameterInfo> out = base_;
  for (const Effect& e : effects_) {
    for (ParameterInfo q : e.params) {
      q.name = e.name() + (e.variant.empty() ? "" : "_" + e.variant) + "." + q.name;
      out.push_back(std::move(q));
    }
  }
  return out;
}

template <Physics P>
Eigen::VectorXd AugmentedModel<P>::parameters() const {
  Eigen::VectorXd th(num_parameters());
  Eigen::Index i = 0;
  for (const ParameterInfo& q : base_) th(i++) = q.value;
  for (const Effect& e : effects_)
    for (const ParameterInfo& q : e.params) th(i++) = q.value;
  return th;
}

template <Physics P>
void AugmentedModel<P>::set_parameters(const Eigen::Ref<const Eigen::VectorXd>& theta) {
  require(theta.size() == num_parameters(),
          "augmented model: " + std::to_string(theta.size()) + " parameter values for " +
              std::to_string(num_parameters()) + " parameters");
  const std::vector<ParameterInfo> info = parameter_info();
  for (Eigen::Index i = 0; i < theta.size(); ++i) {
    const ParameterInfo& q = info[static_cast<std::size_t>(i)];
    require(std::isfinite(theta(i)) && theta(i) >= q.lower && theta(i) <= q.upper,
            "augmented model: value " + detail::format_f(theta(i), 6) + " is not finite or outside [" +
                detail::format_f(q.lower, 6) + ", " + detail::format_f(q.upper, 6) + "]",
            at_parameter(q.name));
  }
  // θ starts with the baseline's values, in the physics' order.
  physics_check_parameters(phys_, theta.data(), "augmented model: set_parameters");
  Eigen::Index i = 0;
  for (ParameterInfo& q : base_) q.value = theta(i++);
  for (Effect& e : effects_)
    for (ParameterInfo& q : e.params) q.value = theta(i++);
}

template <Physics P>
double AugmentedModel<P>::stiffness(const double* theta, const double* x0, const double* u0) const {
  // The physics' own bound, or (it does not know its stiffness) the Gershgorin bound of ∂f/∂x
  // at the start.
  return physics_spectral_radius(phys_, theta, x0, u0) + effects_rate(theta);
}

template <Physics P>
double AugmentedModel<P>::effects_rate(const double* theta) const {
  double rho = 0.0;
  for (std::size_t i = 0; i < effects_.size(); ++i) {
    const Effect& e = effects_[i];
    const double* q = theta + offsets_[i];
    switch (e.kind) {
      case EffectKind::coulomb_friction: rho += std::sqrt(std::abs(q[0]) / e.width); break;
      case EffectKind::viscous_friction: rho += std::abs(q[0]); break;
      case EffectKind::quadratic_drag: rho += 6.0 * std::abs(q[0]) * e.speed; break;
      case EffectKind::cubic_stiffness: rho += std::sqrt(3.0 * std::abs(q[0])) * e.width; break;
      case EffectKind::hard_stop: rho += std::sqrt(std::abs(q[1])); break;
      case EffectKind::preload: rho += std::sqrt(std::abs(q[0]) / e.width); break;
      case EffectKind::actuator_lag: rho += 1.0 / std::max(std::abs(q[0]), 1e-12); break;
      default: break;
    }
  }
  return rho;
}

template <Physics P>
template <class T>
Eigen::Index AugmentedModel<P>::simulate(const Eigen::MatrixXd& u, const T* theta, const T* x0, T* y,
                                         T* states) const {
  if (u.rows() == 0) return 0;
  // Sub-steps from the value parts (identical for double and Dual runs).
  const int nx = detail::physics_states(phys_);
  std::vector<double> thv(static_cast<std::size_t>(num_parameters())), x0v(static_cast<std::size_t>(nx));
  for (int i = 0; i < num_parameters(); ++i) thv[static_cast<std::size_t>(i)] = static_cast<double>(value_of(theta[i]));
  for (int i = 0; i < nx; ++i) x0v[static_cast<std::size_t>(i)] = static_cast<double>(value_of(x0[i]));
  return simulate_with_substeps(u, theta, x0, y, states, substeps(thv.data(), x0v.data(), u));
}

template <Physics P>
int AugmentedModel<P>::substeps(const double* theta, const double* x0, const Eigen::MatrixXd& u) const {
  const int nx = detail::physics_states(phys_), nu = detail::physics_inputs(phys_);
  std::vector<double> u0(static_cast<std::size_t>(std::max(nu, 1)), 0.0);
  for (int j = 0; j < nu && u.rows() > 0; ++j) u0[static_cast<std::size_t>(j)] = u(0, j);
  const int sub = std::max(1, substeps(theta, x0, u0.data()));
  if (physics_stiffness_known(phys_, theta) || integ_.substeps > 0 || u.rows() < 2) return sub;
  // The baseline does not know its stiffness: run once at the start's count and take the
  // stiffest baseline state met (the effects' rates do not depend on the state).
  const Eigen::Index n = u.rows();
  std::vector<double> y(static_cast<std::size_t>(n)), states(static_cast<std::size_t>(n * nx));
  const Eigen::Index got = simulate_with_substeps<double>(u, theta, x0, y.data(), states.data(), sub);
  double worst = 0.0;
  for (Eigen::Index k = 0; k < got; ++k) {
    for (int j = 0; j < nu; ++j) u0[static_cast<std::size_t>(j)] = u(k, j);
    worst = std::max(worst, detail::gershgorin_bound(phys_, states.data() + k * nx, u0.data(), theta));
  }
  return std::max(sub, substeps_for(ts_, worst + effects_rate(theta), integ_));
}

template <Physics P>
template <class T>
Eigen::Index AugmentedModel<P>::simulate_with_substeps(const Eigen::MatrixXd& u, const T* theta, const T* x0, T* y,
                                                       T* states, int sub) const {
  // Continuous state [x; w]: fixed-size (stack, no heap) for a static physics. The actuator
  // state w is always carried (ẇ = 0 without the lag effect) so the size never changes.
  constexpr int NC = P::num_states == Dynamic ? Eigen::Dynamic : P::num_states + 1;
  using State = Eigen::Matrix<T, NC, 1>;
  const int nx = detail::physics_states(phys_), nu = detail::physics_inputs(phys_),
            ny = detail::physics_outputs(phys_);
  const Eigen::Index n = u.rows();
  if (n == 0) return 0;
  const int nc = nx + 1;
  std::vector<double> thv(static_cast<std::size_t>(num_parameters()));
  for (int i = 0; i < num_parameters(); ++i) thv[static_cast<std::size_t>(i)] = static_cast<double>(value_of(theta[i]));
  sub = std::max(1, sub);
  const double hs = ts_ / sub;
  const int m = dead_time_samples(thv.data());

  // Input chain value of sample k (before the actuator lag).
  auto input_at = [&](Eigen::Index k) -> T {
    const Eigen::Index k1 = std::max<Eigen::Index>(0, k - m), k2 = std::max<Eigen::Index>(0, k - m - 1);
    return input_chain(theta, T(u(k, 0)), T(u(k1, 0)), T(u(k2, 0)), m);
  };

  std::vector<T> uin(static_cast<std::size_t>(std::max(nu, 1)));
  std::vector<T> yb(static_cast<std::size_t>(ny));
  T u_static = T(0);   // chain output held over the interval
  T fric = T(0);       // Dahl state s ∈ [−1, 1]
  State X(nc);
  for (int i = 0; i < nx; ++i) X[i] = x0[i];
  X[nx] = has_actuator_lag() ? input_at(0) : T(0);
  const int qi = roles_.position;

  auto rhs = [&](const State& s, State& ds) { augmented_derivative(s.data(), u_static, fric, theta, uin.data(), ds.data()); };

  Rk4Stepper<State> rk4;
  T z = T(0);  // play state
  for (Eigen::Index k = 0; k < n; ++k) {
    u_static = input_at(k);
    for (int j = 1; j < nu; ++j) uin[static_cast<std::size_t>(j)] = T(u(k, j));
    const T yk = output_at(X.data(), u_static, theta, uin.data(), yb.data(), z, k == 0);
    if (!std::isfinite(static_cast<double>(value_of(yk)))) return k;
    y[k] = yk;
    if (states)
      for (int i = 0; i < nx; ++i) states[k * nx + i] = X[i];
    if (k + 1 == n) break;
    for (int s = 0; s < sub; ++s) {
      const T q_before = has_coulomb_friction() ? X[qi] : T(0);
      rk4.step(rhs, X, hs);
      if (has_coulomb_friction()) fric = friction_after(fric, T(X[qi] - q_before));
    }
    if (!detail::values_finite(X)) return k + 1;
  }
  return n;
}

template <Physics P>
int AugmentedModel<P>::dead_time_samples(const double* theta) const {
  for (int i : input_chain_) {
    const Effect& e = effects_[static_cast<std::size_t>(i)];
    if (e.kind == EffectKind::dead_time)
      return static_cast<int>(std::floor(theta[offsets_[static_cast<std::size_t>(i)]] / ts_));
  }
  return 0;
}

template <Physics P>
template <class T>
T AugmentedModel<P>::input_chain(const T* theta, const T& u_k, const T& u_km, const T& u_km1, int m) const {
  using std::max;
  using std::min;
  T v = u_k;
  for (int i : input_chain_) {
    const Effect& e = effects_[static_cast<std::size_t>(i)];
    const T* q = theta + offsets_[static_cast<std::size_t>(i)];
    switch (e.kind) {
      case EffectKind::dead_time: {
        const T d = q[0] / T(ts_);
        const T alpha = d - T(static_cast<double>(m));
        v = (T(1) - alpha) * u_km + alpha * u_km1;
        break;
      }
      case EffectKind::input_offset: v = v + q[0]; break;
      case EffectKind::input_deadzone: v = v - min(max(v, T(-q[0])), q[0]); break;
      case EffectKind::input_saturation:
        v = upper_[static_cast<std::size_t>(i)] ? min(v, q[0]) : max(v, q[0]);
        break;
      default: break;
    }
  }
  return v;
}

template <Physics P>
template <class T>
void AugmentedModel<P>::augmented_derivative(const T* s, const T& u_static, const T& fric, const T* theta, T* uin,
                                             T* ds) const {
  using std::abs;
  using std::max;
  using std::tanh;
  const int nx = detail::physics_states(phys_);
  const bool has_lag = lag_ >= 0;
  // Input seen by the physics: the lag state, or the held chain output.
  uin[0] = has_lag ? s[nx] : u_static;
  phys_.derivative(s, uin, theta, ds);  // baseline parameters come first in θ
  if (!mech_.empty()) {
    const T& q = s[roles_.position];
    const T& v = s[roles_.velocity];
    T a = T(0);
    for (int i : mech_) {
      const Effect& e = effects_[static_cast<std::size_t>(i)];
      const T* c = theta + offsets_[static_cast<std::size_t>(i)];
      switch (e.kind) {
        case EffectKind::coulomb_friction: a -= c[0] * fric; break;
        case EffectKind::viscous_friction: a -= c[0] * v; break;
        case EffectKind::quadratic_drag: a -= c[0] * v * abs(v); break;
        case EffectKind::cubic_stiffness: {
          const T d = q - c[1];
          a -= c[0] * d * d * d;
          break;
        }
        case EffectKind::hard_stop:
          if (upper_[static_cast<std::size_t>(i)]) a -= c[1] * max(q - c[0], T(0));
          else a += c[1] * max(c[0] - q, T(0));
          break;
        case EffectKind::preload: a -= c[0] * tanh((q - c[1]) / T(e.width)); break;
        default: break;
      }
    }
    ds[roles_.velocity] += a;
  }
  ds[nx] = has_lag ? T((u_static - s[nx]) / theta[offsets_[static_cast<std::size_t>(lag_)]]) : T(0);
}

template <Physics P>
template <class T>
T AugmentedModel<P>::output_at(const T* X, const T& u_static, const T* theta, T* uin, T* yb, T& play, bool first) const {
  using std::max;
  using std::min;
  const int nx = detail::physics_states(phys_);
  uin[0] = lag_ >= 0 ? X[nx] : u_static;
  phys_.output(X, uin, theta, yb);
  T yk = yb[0];
  for (int i : output_chain_) {
    const Effect& e = effects_[static_cast<std::size_t>(i)];
    const T* c = theta + offsets_[static_cast<std::size_t>(i)];
    switch (e.kind) {
      case EffectKind::backlash: {
        const T half = T(0.5) * c[0];
        if (first) play = yk;
        play = min(max(play, yk - half), yk + half);
        yk = play;
        break;
      }
      case EffectKind::output_saturation:
        yk = upper_[static_cast<std::size_t>(i)] ? min(yk, c[0]) : max(yk, c[0]);
        break;
      case EffectKind::output_offset: yk = yk + c[0]; break;
      default: break;
    }
  }
  return yk;
}

template <Physics P>
template <class T>
T AugmentedModel<P>::friction_after(const T& fric, const T& dq) const {
  using std::abs;
  using std::exp;
  const double delta = coulomb_ >= 0 ? effects_[static_cast<std::size_t>(coulomb_)].width : 1.0;
  // Compared on the value part: for double and Dual a double, for the code generator's tracer
  // the traced value itself, so the generated code branches on the signal.
  const auto dqv = value_of(dq);
  if (dqv != 0.0) {
    const double sg = dqv > 0.0 ? 1.0 : -1.0;
    return T(sg) + (fric - T(sg)) * exp(-abs(dq) / T(delta));
  }
  return fric;
}

template <Physics P>
void AugmentedModel<P>::check_experiment(const Experiment& e, long index) const {
  Location where;
  where.experiment = index;
  const std::string who = e.name().empty() ? (index >= 0 ? "experiment " + std::to_string(index) : "experiment")
                                           : "experiment '" + e.name() + "'";
  require(e.num_outputs() == 1,
          who + " has " + std::to_string(e.num_outputs()) +
              " outputs; the diagnosis models one output (select it first)",
          where);
  require(e.num_inputs() == detail::physics_inputs(phys_),
          who + " has " + std::to_string(e.num_inputs()) + " input(s) but the physics reads " +
              std::to_string(detail::physics_inputs(phys_)),
          where);
  require(e.size() >= 2, who + " has fewer than 2 samples", where);
  e.validate(true);  // u() and y() are mutable: a record resized through one would be read past its end
  // The simulation steps by the model's own sample time: a record at another rate would run on
  // a stretched time axis and still look plausible.
  require(same_sample_time(e.ts(), ts_),
          who + " has sample time " + detail::format_g(e.ts(), 10) + " s but the model's is " + detail::format_g(ts_, 10) +
              " s (resample the data, e.g. decimate it as for the estimation)",
          where);
}

template <Physics P>
Eigen::MatrixXd AugmentedModel<P>::simulate(const Experiment& e, const Eigen::VectorXd& x0) const {
  check_experiment(e);
  require(x0.size() == state_dimension(),
          "augmented model: initial state has " + std::to_string(x0.size()) + " entries, expected " +
              std::to_string(state_dimension()),
          at_parameter("x0"));
  const Eigen::VectorXd th = parameters();
  Eigen::VectorXd y(e.size());
  const Eigen::Index got = simulate<double>(e.u(), th.data(), x0.data(), y.data());
  if (got < e.size()) {
    Location where;
    where.row = static_cast<long>(got) + 1;
    throw DivergenceError("simulation diverged at sample " + std::to_string(got) +
                              " (non-finite state); check the parameter values or reduce the sample time",
                          static_cast<long>(got), where);
  }
  return y;
}

template <Physics P>
Eigen::VectorXd AugmentedModel<P>::initial_state_guess(const Experiment& e) const {
  const int nx = state_dimension();
  Eigen::VectorXd x0 = Eigen::VectorXd::Zero(nx);
  std::vector<double> p;
  for (const ParameterInfo& q : base_) p.push_back(q.value);
  const Eigen::RowVectorXd u0 = e.u().row(0);
  const double y0 = e.y()(0, 0);
  if constexpr (detail::HasInitialStateHook<P>) {
    if (phys_.initial_state(&y0, u0.data(), p.data(), x0.data()) && x0.allFinite()) return x0;
    x0.setZero();
  }
  const EquilibriumResult eq = physics_equilibrium(phys_, u0.data(), p.data(), x0.data());
  if (!eq.converged || !x0.allFinite()) x0.setZero();
  return x0;
}

template <Physics P>
Eigen::VectorXd AugmentedModel<P>::estimate_initial_state(const Experiment& e, int max_iterations) const {
  check_experiment(e);
  const int nx = state_dimension();
  const Eigen::VectorXd th = parameters();
  const Eigen::VectorXd ym = e.y().col(0);
  const Eigen::Index n = e.size();
  using D = RuntimeDual;
  auto fn = [&](const Eigen::VectorXd& x0, Eigen::VectorXd& r, Eigen::MatrixXd* J) -> bool {
    if (!J) {
      Eigen::VectorXd yh(n);
      if (simulate<double>(e.u(), th.data(), x0.data(), yh.data()) < n) return false;
      r = yh - ym;
      return r.allFinite();
    }
    std::vector<D> thd(static_cast<std::size_t>(th.size())), yd(static_cast<std::size_t>(n));
    for (Eigen::Index i = 0; i < th.size(); ++i) thd[static_cast<std::size_t>(i)] = D(th(i));
    std::vector<D> xd(static_cast<std::size_t>(nx));
    for (int c0 = 0; c0 < nx; c0 += D::num_derivatives) {
      for (int i = 0; i < nx; ++i)
        xd[static_cast<std::size_t>(i)] = (i >= c0 && i < c0 + D::num_derivatives) ? D::variable(x0(i), i - c0) : D(x0(i));
      if (simulate<D>(e.u(), thd.data(), xd.data(), yd.data()) < n) return false;
      for (Eigen::Index k = 0; k < n; ++k) {
        const D& v = yd[static_cast<std::size_t>(k)];
        if (c0 == 0) r(k) = v.a - ym(k);
        for (int i = c0; i < std::min(nx, c0 + D::num_derivatives); ++i) (*J)(k, i) = v.v[i - c0];
      }
    }
    return r.allFinite() && J->allFinite();
  };
  const auto problem = make_problem<Dynamic>(nx, n, fn);
  Eigen::VectorXd x0 = initial_state_guess(e);
  LmOptions o;
  o.max_iterations = max_iterations;
  o.function_tolerance = 1e-8;
  Eigen::VectorXd r(n);
  if (!fn(x0, r, nullptr)) return x0;  // the guess cannot be simulated: keep it (caller reports)
  try {
    solve_least_squares(problem, x0, o);
  } catch (const Error&) {
    return initial_state_guess(e);
  }
  return x0;
}

template <Physics P>
Eigen::MatrixXd AugmentedModel<P>::simulate(const Experiment& e, InitialCondition ic) const {
  check_experiment(e);
  switch (ic) {
    case InitialCondition::zero: return simulate(e, Eigen::VectorXd::Zero(state_dimension()));
    case InitialCondition::equilibrium: {
      Eigen::VectorXd x0 = initial_state_guess(e);
      std::vector<double> p;
      for (const ParameterInfo& q : base_) p.push_back(q.value);
      const Eigen::RowVectorXd u0 = e.u().row(0);
      const EquilibriumResult eq = physics_equilibrium(phys_, u0.data(), p.data(), x0.data());
      require(eq.converged, "no equilibrium of the baseline for the first input sample",
              at_parameter("initial_condition"));
      return simulate(e, x0);
    }
    case InitialCondition::estimate: return simulate(e, estimate_initial_state(e));
    case InitialCondition::measured: break;
  }
  throw Error("initial condition 'measured' does not apply to a state-space model; use estimate, "
              "zero or equilibrium",
              at_parameter("initial_condition"));
}

template <Physics P>
std::string AugmentedModel<P>::describe() const {
  auto unit = [&](const std::string& s) { return detail::substitute_units(s, y_unit_, u_unit_); };
  auto num = [](double v) { return detail::format_g(v, 6); };
  std::string s = "Augmented grey-box model (sample time " + num(ts_) + " s)\n";
  std::string bname = "custom";
  if constexpr (requires(const P& q) { { q.name() } -> std::convertible_to<std::string>; }) bname = phys_.name();
  s += "  baseline: " + bname;
  if constexpr (requires(const P& q) { { q.equation() } -> std::convertible_to<std::string>; })
    s += ":  " + std::string(phys_.equation());
  s += "\n";
  if (effects_.empty()) s += "  effects: none\n";
  for (const Effect& e : effects_) {
    s += "  + " + e.label() + ": " + effect_description(e.kind) + "\n";
  }
  s += "  parameters:\n";
  for (const ParameterInfo& q : parameter_info()) {
    s += "    " + detail::left_aligned(q.name, 28) + " = " + detail::left_aligned(num(q.value), 14) + " " +
         detail::left_aligned(unit(q.unit), 14) + (q.fixed ? " (fixed)" : "") + "\n";
  }
  return s;
}

}  // namespace nlid
