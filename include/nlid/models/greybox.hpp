#pragma once
/// @file
/// `GreyBox<Physics>`: a grey-box model — physics written once, parameters from data.
///
/// A grey-box model (Ljung 1999, Sec. 4.5, eq. 4.62; Bohlin 2006, ch. 2) is the continuous-time
/// state-space model
///
///     ẋ = f(x, u, p),   y = g(x, u, p),   x(t₀) = x₀,
///
/// whose structure f, g is physics (see `Physics` in greybox_concepts.hpp) and whose named
/// parameters p (with units, bounds and fixed flags) are estimated from sampled data by
/// minimising the simulation error (greybox_problem.hpp, greybox_estimate.hpp). This class holds
/// the physics, the parameter table and the integrator settings, and simulates:
///
///     GreyBox<physics::Throttle> model;
///     model.initialize(data);                                  // scale parameters from the data
///     auto fit = estimate(model, data);                         // multi-start simulation error
///     Eigen::MatrixXd yhat = model.simulate(data3, InitialCondition::estimate);
///     std::cout << model.describe();
///
/// Simulation holds each input sample over its interval (zero-order hold) and integrates with the
/// method and sub-step rule of `IntegratorOptions` (integrators.hpp). Initial conditions
/// (`InitialCondition`, core/initial_condition.hpp):
///   - `zero`: x₀ = 0;
///   - `equilibrium`: x₀ = x̄ with f(x̄, u₀, p) = 0 for the first input sample held;
///   - `estimate`: x₀ minimises the simulation error over the first samples of the record
///     (parameters fixed; `set_initial_state_window`, default 2000 samples, 0 = all), the
///     grey-box counterpart of the toolbox's `findstates`;
///   - `measured` does not apply to a state-space model and is rejected with an `nlid::Error`.
///
/// The same class serves compile-time physics (`GreyBox<physics::Throttle>`: fixed-size vectors,
/// no heap use per sample, one Dual pass per experiment for the Jacobian) and physics chosen at
/// run time (`DynamicGreyBox = GreyBox<AnyPhysics>`, greybox_dynamic.hpp).
///
/// Parameter table invariants: one entry per physics parameter, names unique, lower ≤ value ≤
/// upper. Setters check these and throw `nlid::Error` naming the parameter. The physics'
/// relations between values (its optional `check_parameters`, e.g. the throttle's lower_stop <
/// upper_stop) are checked by the constructor, `set_parameters`, `update_parameters`,
/// `initialize`, `simulate` and `estimate`, but not by `set_parameter`, which sets one value at
/// a time.

#include <algorithm>
#include <cmath>
#include <concepts>
#include <cstdio>
#include <limits>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/core/initial_condition.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/data/experiment.hpp"
#include "nlid/estimation/detail/covariance_check.hpp"
#include "nlid/estimation/levenberg_marquardt.hpp"
#include "nlid/models/greybox_concepts.hpp"
#include "nlid/models/greybox_problem.hpp"
#include "nlid/models/greybox_simulate.hpp"
#include "nlid/models/integrators.hpp"

namespace nlid {

namespace detail {
template <class P>
concept HasStateInfo = requires(const P& p) {
  { p.state_info() } -> InfoList<StateInfo>;
};
template <class P>
concept HasPhysicsName = requires(const P& p) {
  { p.name() } -> std::convertible_to<std::string>;
};
template <class P>
concept HasEquation = requires(const P& p) {
  { p.equation() } -> std::convertible_to<std::string>;
};
template <class P>
concept HasInitializeHook = requires(const P& p, const Dataset& d, std::span<ParameterInfo> s) {
  p.initialize(d, s);
};

}  // namespace detail

/// A grey-box model of physics P (see the file comment).
template <Physics P>
class GreyBox {
 public:
  using physics_type = P;                                         ///< the physics functor
  static constexpr int num_states = P::num_states;                ///< n_x (or Dynamic)
  static constexpr int num_inputs = P::num_inputs;                ///< n_u (or Dynamic)
  static constexpr int num_outputs = P::num_outputs;              ///< n_y (or Dynamic)
  static constexpr int num_params = P::num_params;                ///< n_p (or Dynamic)
  using StateVector = Eigen::Matrix<double, num_states, 1>;       ///< x
  using ParameterVector = Eigen::Matrix<double, num_params, 1>;   ///< p

  /// Model with a default-constructed physics and its default parameter values.
  GreyBox()
    requires std::default_initializable<P>
      : GreyBox(P{}) {}

  /// Model of the given physics; parameters start at the physics' defaults. Throws
  /// `nlid::Error` if the physics' metadata is inconsistent (count, duplicate or empty names,
  /// default outside its bounds).
  explicit GreyBox(P physics) : physics_(std::move(physics)) {
    const auto info = physics_.parameter_info();
    const int np = detail::physics_params(physics_);
    require(static_cast<int>(info.size()) == np,
            "physics declares " + std::to_string(np) + " parameters but describes " +
                std::to_string(info.size()));
    for (std::size_t i = 0; i < info.size(); ++i) {
      const ParameterInfo& q = info[i];
      require(!q.name.empty(), "parameter " + std::to_string(i) + " has no name");
      for (std::size_t j = 0; j < i; ++j) {
        require(info[j].name != q.name, "duplicate parameter name '" + q.name + "'",
                at_parameter(q.name));
      }
      require(!std::isnan(q.lower) && !std::isnan(q.upper) && q.lower <= q.upper,
              "bounds [" + detail::format_g(q.lower) + ", " + detail::format_g(q.upper) + "] of '" + q.name +
                  "' must satisfy lower <= upper",
              at_parameter(q.name));
      // An infinite default passes an infinite bound, then every simulation is NaN.
      require(std::isfinite(q.value), "default value " + detail::format_g(q.value) + " of '" + q.name + "' is not finite",
              at_parameter(q.name));
      require(q.lower <= q.value && q.value <= q.upper,
              "default value " + detail::format_g(q.value) + " of '" + q.name +
                  "' is outside its bounds",
              at_parameter(q.name));
      // NaN ends mean "the bounds"; multi-start would silently never sample an inverted range.
      require(!(q.range_lower > q.range_upper),
              "range [" + detail::format_g(q.range_lower) + ", " + detail::format_g(q.range_upper) + "] of '" +
                  q.name + "' must satisfy lower <= upper",
              at_parameter(q.name));
      params_.push_back(q);
    }
    user_set_.assign(params_.size(), false);
    check_relations(parameters(), "default values");
    const int nx = detail::physics_states(physics_);
    if constexpr (detail::HasStateInfo<P>) {
      const auto si = physics_.state_info();
      for (std::size_t i = 0; i < si.size(); ++i) states_.push_back(si[i]);
    }
    if (static_cast<int>(states_.size()) != nx) {
      states_.clear();
      for (int i = 0; i < nx; ++i) states_.push_back(StateInfo{"x" + std::to_string(i + 1), "", ""});
    }
  }

  // ---- structure -------------------------------------------------------------------------------

  /// The physics.
  [[nodiscard]] const P& physics() const { return physics_; }
  /// Catalogue name of the physics ("custom" if it has none).
  [[nodiscard]] std::string name() const {
    if constexpr (detail::HasPhysicsName<P>) {
      return physics_.name();
    } else {
      return "custom";
    }
  }
  /// n_x.
  [[nodiscard]] int state_dimension() const { return detail::physics_states(physics_); }
  /// n_u.
  [[nodiscard]] int input_dimension() const { return detail::physics_inputs(physics_); }
  /// n_y.
  [[nodiscard]] int output_dimension() const { return detail::physics_outputs(physics_); }
  /// n_p.
  [[nodiscard]] int num_parameters() const { return static_cast<int>(params_.size()); }
  /// State names and units.
  [[nodiscard]] const std::vector<StateInfo>& state_info() const { return states_; }

  // ---- parameters ------------------------------------------------------------------------------

  /// The parameter table (names, units, values, bounds, ranges, fixed flags).
  [[nodiscard]] const std::vector<ParameterInfo>& parameter_info() const { return params_; }
  /// Parameter names in order.
  [[nodiscard]] std::vector<std::string> parameter_names() const {
    std::vector<std::string> n;
    for (const auto& q : params_) n.push_back(q.name);
    return n;
  }
  /// Current parameter values.
  [[nodiscard]] ParameterVector parameters() const {
    ParameterVector p(num_parameters());
    for (int i = 0; i < num_parameters(); ++i) p[i] = params_[static_cast<std::size_t>(i)].value;
    return p;
  }
  /// Sets all parameter values. Throws `nlid::Error` naming the first parameter that is not
  /// finite or lies outside its bounds, or the values that violate a relation of the physics
  /// (`check_parameters`), or on a size mismatch; nothing is changed then.
  void set_parameters(const Eigen::Ref<const Eigen::VectorXd>& p) {
    require(p.size() == num_parameters(), "expected " + std::to_string(num_parameters()) +
                                              " parameter values, got " + std::to_string(p.size()));
    for (int i = 0; i < num_parameters(); ++i) check_value(params_[static_cast<std::size_t>(i)], p[i]);
    check_relations(p, "set_parameters");
    for (int i = 0; i < num_parameters(); ++i) {
      params_[static_cast<std::size_t>(i)].value = p[i];
      user_set_[static_cast<std::size_t>(i)] = true;
    }
    clear_uncertainty();  // deviations belong to the values they were computed for
  }
  /// Index of a parameter by name; throws `nlid::Error` listing the known names.
  [[nodiscard]] int parameter_index(std::string_view name) const {
    for (std::size_t i = 0; i < params_.size(); ++i) {
      if (params_[i].name == name) return static_cast<int>(i);
    }
    std::string known;
    for (const auto& q : params_) known += (known.empty() ? "" : ", ") + q.name;
    throw Error("unknown parameter '" + std::string(name) + "' of grey-box model '" + this->name() +
                    "'; known parameters: " + known,
                at_parameter(std::string(name)));
  }
  /// Value of a named parameter.
  [[nodiscard]] double parameter(std::string_view name) const {
    return params_[static_cast<std::size_t>(parameter_index(name))].value;
  }
  /// Sets a named parameter; throws `nlid::Error` naming it if the value is outside its bounds.
  /// The physics' relations between values are not checked here: values set one at a time
  /// (as a model file is read) pass through combinations such as a lower stop of 15 above the
  /// default upper stop 1; `set_parameters`, `initialize`, `simulate` and `estimate` check them.
  void set_parameter(std::string_view name, double value) {
    const auto i = static_cast<std::size_t>(parameter_index(name));
    check_value(params_[i], value);
    params_[i].value = value;
    user_set_[i] = true;
    clear_uncertainty();
  }
  /// Sets hard bounds of a named parameter (lower ≤ value ≤ upper must hold afterwards).
  void set_bounds(std::string_view name, double lower, double upper) {
    const auto i = static_cast<std::size_t>(parameter_index(name));
    ParameterInfo& q = params_[i];
    require(!(lower > upper) && !std::isnan(lower) && !std::isnan(upper),
            "bounds of '" + q.name + "' must satisfy lower <= upper", at_parameter(q.name));
    require(lower <= q.value && q.value <= upper,
            "current value " + detail::format_g(q.value) + " of '" + q.name +
                "' lies outside the new bounds [" + detail::format_g(lower) + ", " +
                detail::format_g(upper) + "]; set the value first",
            at_parameter(q.name));
    q.lower = lower;
    q.upper = upper;
  }
  /// Sets the range multi-start explores for a named parameter (log-spaced if `log_scale` and
  /// the range is positive).
  void set_range(std::string_view name, double lower, double upper, bool log_scale = false) {
    const auto i = static_cast<std::size_t>(parameter_index(name));
    ParameterInfo& q = params_[i];
    require(std::isfinite(lower) && std::isfinite(upper) && lower <= upper,
            "range of '" + q.name + "' must be finite with lower <= upper", at_parameter(q.name));
    require(!log_scale || lower > 0.0, "log-spaced range of '" + q.name + "' must be positive",
            at_parameter(q.name));
    q.range_lower = lower;
    q.range_upper = upper;
    q.log_scale = log_scale;
    user_set_[i] = true;
  }
  /// Holds a named parameter at its value during estimation (or frees it with `false`); the
  /// data-driven `initialize` leaves a fixed parameter's value alone too.
  void fix(std::string_view name, bool fixed = true) {
    params_[static_cast<std::size_t>(parameter_index(name))].fixed = fixed;
  }
  /// True if the named parameter is fixed.
  [[nodiscard]] bool is_fixed(std::string_view name) const {
    return params_[static_cast<std::size_t>(parameter_index(name))].fixed;
  }
  /// Fixed flags in parameter order.
  [[nodiscard]] std::vector<bool> fixed_flags() const {
    std::vector<bool> f;
    for (const auto& q : params_) f.push_back(q.fixed);
    return f;
  }
  /// Replaces values (and ranges) from an estimation or another table, keeping bounds checks.
  /// Used by `estimate`; unlike `set_parameters` it does not mark values as user-set.
  void update_parameters(const Eigen::Ref<const Eigen::VectorXd>& p) {
    require(p.size() == num_parameters(), "parameter count mismatch");
    for (int i = 0; i < num_parameters(); ++i) check_value(params_[static_cast<std::size_t>(i)], p[i]);
    check_relations(p, "update_parameters");
    for (int i = 0; i < num_parameters(); ++i) params_[static_cast<std::size_t>(i)].value = p[i];
    clear_uncertainty();
  }

  /// Standard deviations of the parameter values (1σ; 0 for a fixed parameter, +∞ for one the
  /// data did not determine, NaN for one the estimation left on a bound, where there is none),
  /// as the last estimation left them (`GreyBoxEstimate::uncertainty`); empty when unknown.
  /// Kept in model files; cleared when a value changes.
  [[nodiscard]] const Eigen::VectorXd& parameter_stddev() const { return stddev_; }
  /// Sets the standard deviations (n_p entries, each >= 0, +inf or NaN for on its bound; empty
  /// clears them). Throws `nlid::Error` naming the parameter of a negative entry, or on a size
  /// mismatch.
  void set_parameter_stddev(Eigen::VectorXd sd) {
    require(sd.size() == 0 || sd.size() == num_parameters(),
            "grey-box model '" + name() + "': " + std::to_string(sd.size()) + " standard deviations for " +
                std::to_string(num_parameters()) + " parameters",
            at_parameter("stddev"));
    for (Eigen::Index i = 0; i < sd.size(); ++i) {
      const std::string& q = params_[static_cast<std::size_t>(i)].name;
      require(sd[i] >= 0.0 || std::isnan(sd[i]),
              "grey-box model '" + name() + "': the standard deviation of " + q + " must be >= 0 (or inf, or nan for on its bound), got " +
                  detail::format_g(sd[i]),
              at_parameter(q));
    }
    stddev_ = std::move(sd);
  }

  /// Covariance of the parameter values (n_p × n_p; zero rows for fixed parameters), as the
  /// last estimation left it (`GreyBoxEstimate::uncertainty.covariance`); empty when unknown.
  /// What `simulation_band(model, data)` propagates: the deviations alone would miss the strong
  /// correlations of simulation-error estimates. Kept in model files; cleared when a value changes.
  [[nodiscard]] const Eigen::MatrixXd& parameter_covariance() const { return covariance_; }
  /// Sets the covariance (n_p × n_p, finite, symmetric, non-negative diagonal; empty clears it).
  /// Throws `nlid::Error` saying which condition fails, naming the parameter where one does.
  void set_parameter_covariance(Eigen::MatrixXd c) {
    const Eigen::Index n = num_parameters();
    require(c.size() == 0 || (c.rows() == n && c.cols() == n),
            "grey-box model '" + name() + "': a " + std::to_string(c.rows()) + "x" + std::to_string(c.cols()) +
                " parameter covariance for " + std::to_string(n) + " parameters",
            at_parameter("covariance"));
    if (c.size() > 0) {
      detail::check_covariance("grey-box model '" + name() + "': ", parameter_names(), c);
    }
    covariance_ = std::move(c);
  }

  // ---- integrator ------------------------------------------------------------------------------

  /// Integrator settings.
  [[nodiscard]] const IntegratorOptions& integrator() const { return integrator_; }
  /// Sets the integrator; throws `nlid::Error` naming an invalid option.
  void set_integrator(const IntegratorOptions& o) {
    validate(o);
    integrator_ = o;
  }
  /// Sub-steps per sample the rule gives at the current parameters for sample time `ts`, judged
  /// at the zero state and input: the count of every run for a physics with a
  /// `spectral_radius`; for one without, a run's count also depends on the states it reaches —
  /// `substeps(u, ts, x0)` gives it. Throws `nlid::Error` naming "ts" unless ts is positive and
  /// finite, or naming "spectral_radius" if the physics returns +inf.
  [[nodiscard]] int substeps(double ts) const {
    require(ts > 0.0 && std::isfinite(ts), "sample time must be positive and finite, got " + detail::format_g(ts),
            at_parameter("ts"));
    const ParameterVector p = parameters();
    const StateVector x = StateVector::Zero(state_dimension());
    const Eigen::VectorXd u = Eigen::VectorXd::Zero(input_dimension());
    return substeps_for(ts, physics_spectral_radius(physics_, p.data(), x.data(), u.data()),
                        integrator_);
  }
  /// Sub-steps per sample of `simulate(u, ts, x0)`: for a physics without a `spectral_radius`
  /// the rule with the largest Gershgorin bound of ∂f/∂x along that run (`physics_substeps`).
  [[nodiscard]] int substeps(const Eigen::MatrixXd& u, double ts, const StateVector& x0) const {
    require(ts > 0.0 && std::isfinite(ts), "sample time must be positive and finite, got " + detail::format_g(ts),
            at_parameter("ts"));
    require(u.cols() == input_dimension(), "input has " + std::to_string(u.cols()) + " columns, the model takes " +
                                               std::to_string(input_dimension()),
            at_parameter("u"));
    require(x0.size() == state_dimension(), "initial state has " + std::to_string(x0.size()) +
                                                " entries, the model has " + std::to_string(state_dimension()) +
                                                " states",
            at_parameter("x0"));
    const ParameterVector p = parameters();
    return physics_substeps(physics_, integrator_, p.data(), x0.data(), u, ts);
  }

  // ---- data-driven initialisation --------------------------------------------------------------

  /// Sets starting values and multi-start ranges of scale-dependent parameters from the data
  /// (physics' `initialize` hook) and records the data's units for `describe`. Values the user
  /// set explicitly (`set_parameter`, `set_parameters`, `set_range`) and fixed parameters (`fix`,
  /// or fixed in the physics' table) are kept. Throws
  /// `nlid::Error` if the data's channel counts do not match the physics.
  void initialize(const Dataset& data) {
    require(data.size() > 0, "initialize: empty data set");
    check_channels(data);
    const Experiment& e0 = data[0];
    if constexpr (detail::HasInitializeHook<P>) {
      const std::vector<ParameterInfo> before = params_;
      std::vector<ParameterInfo> table = params_;
      physics_.initialize(data, std::span<ParameterInfo>(table));
      for (std::size_t i = 0; i < params_.size(); ++i) {
        // A fixed parameter is held at its value, default or not: the data must not move it
        // before the estimator holds it there.
        if (user_set_[i] || params_[i].fixed) continue;
        ParameterInfo& q = params_[i];
        const ParameterInfo& t = table[i];
        if (!std::isfinite(t.value)) continue;
        q.value = std::clamp(t.value, q.lower, q.upper);
        if (std::isfinite(t.range_lower) && std::isfinite(t.range_upper) && t.range_lower <= t.range_upper) {
          q.range_lower = std::max(t.range_lower, q.lower);
          q.range_upper = std::min(t.range_upper, q.upper);
          // The data suggest values the bounds forbid: no range inside them, so the start stays
          // at the bound-clamped value rather than leaving an inverted range in the table.
          if (q.range_lower > q.range_upper) q.range_lower = q.range_upper = q.value;
          q.log_scale = t.log_scale && q.range_lower > 0.0;
        }
      }
      // Values the data suggest, combined with values the user set, can contradict each other.
      try {
        check_relations(parameters(), "initialize from the data (values set by the user are kept)");
      } catch (const Error&) {
        params_ = before;
        throw;
      }
    }
    // Only now, so that a refused initialisation leaves the model as it was.
    if (!e0.output_units().empty()) y_unit_ = e0.output_units()[0];
    if (!e0.input_units().empty()) u_unit_ = e0.input_units()[0];
    // The data's channel names, so that a saved model simulates the same columns of a new file.
    if (static_cast<int>(e0.input_names().size()) == input_dimension()) input_names_ = e0.input_names();
    if (static_cast<int>(e0.output_names().size()) == output_dimension()) output_names_ = e0.output_names();
    initialized_ = true;
  }
  /// True once `initialize` has run (estimate calls it automatically otherwise).
  [[nodiscard]] bool initialized() const { return initialized_; }

  // ---- simulation ------------------------------------------------------------------------------

  /// Free-run simulation of an experiment from the given initial condition; N × n_y outputs.
  /// Throws `nlid::Error` on a channel mismatch, an inapplicable initial condition, a missing
  /// equilibrium, or a diverging simulation (naming the sample and suggesting a remedy).
  [[nodiscard]] Eigen::MatrixXd simulate(const Experiment& e,
                                         InitialCondition ic = InitialCondition::estimate) const {
    check_channels(e, -1);
    const StateVector x0 = initial_state(e, ic);
    return simulate(e, x0);
  }

  /// Free-run simulation of an experiment from the initial state `x0`.
  [[nodiscard]] Eigen::MatrixXd simulate(const Experiment& e,
                                         const Eigen::Ref<const Eigen::VectorXd>& x0) const {
    check_channels(e, -1);
    return simulate(e.u(), e.ts(), x0, e.name());
  }

  /// Free-run simulation of the N × n_u input matrix `u` at sample time `ts` from `x0`.
  [[nodiscard]] Eigen::MatrixXd simulate(const Eigen::MatrixXd& u, double ts,
                                         const Eigen::Ref<const Eigen::VectorXd>& x0,
                                         const std::string& label = {}) const {
    require(u.cols() == input_dimension(), "input has " + std::to_string(u.cols()) +
                                               " column(s), the model takes " +
                                               std::to_string(input_dimension()));
    require(x0.size() == state_dimension(), "initial state has " + std::to_string(x0.size()) +
                                                " entries, the model has " +
                                                std::to_string(state_dimension()) + " states");
    require(ts > 0.0 && std::isfinite(ts), "sample time must be positive and finite",
            at_parameter("ts"));
    require(u.allFinite(), "input contains non-finite samples; a simulation cannot run through them");
    require(x0.allFinite(), "initial state of grey-box model '" + name() + "' is not finite", at_parameter("x0"));
    const ParameterVector p = parameters();
    check_relations(p, "simulate");
    StateVector x = x0;
    Eigen::MatrixXd y(u.rows(), output_dimension());
    double rho = 0.0;
    const int sub = physics_substeps(physics_, integrator_, p.data(), x.data(), u, ts, &rho);
    const Eigen::Index got = simulate_physics<double>(
        physics_, integrator_, sub, u, ts, p.data(), x.data(), [&](Eigen::Index k, const double* yk) {
          for (Eigen::Index j = 0; j < y.cols(); ++j) y(k, j) = yk[j];
        });
    if (got != u.rows()) {
      const std::string head = "simulation of grey-box model '" + name() + "'" +
                               (label.empty() ? std::string() : " on '" + label + "'") + " diverged at sample " +
                               std::to_string(got) + " (t = " + detail::format_g(static_cast<double>(got) * ts) +
                               " s after start)";
      // The adaptive method takes no sub-step count: it fails when its step budget runs out (a
      // stiff model needs many steps per sample) or its step shrinks to nothing, and the remedy
      // is the budget, not the fixed-step options.
      if (integrator_.method == IntegratorMethod::dormand_prince) {
        throw DivergenceError(head + " with the adaptive Dormand-Prince method: a sample interval needed more than "
                                     "IntegratorOptions::max_adaptive_steps = " +
                                  std::to_string(integrator_.max_adaptive_steps) +
                                  " steps, or the state left the finite numbers; check the parameters, or raise "
                                  "IntegratorOptions::max_adaptive_steps",
                              static_cast<long>(got));
      }
      const std::string undefined = undefined_physics_note(u, ts, x0, p, sub, got);
      if (!undefined.empty()) throw DivergenceError(head + undefined, static_cast<long>(got));
      throw DivergenceError(head + " with " + std::to_string(sub) + " sub-step(s) per sample" +
                                capped_substeps_note(ts, rho, sub) +
                                "; check the parameters, or raise "
                                "IntegratorOptions::substeps / min_substeps, or use the adaptive method",
                            static_cast<long>(got));
    }
    return y;
  }

  /// Why a fixed-step run may have diverged although the physics is fine: the automatic rule
  /// wanted more sub-steps than its ceiling, and the capped step is beyond the method's
  /// stability limit (h·ρ ≈ 2.78 for RK4, 2 for Euler). Empty otherwise.
  [[nodiscard]] std::string capped_substeps_note(double ts, double rho, int sub) const {
    const double need = unstable_capped_substeps(ts, rho, sub, integrator_);
    if (need == 0.0) return {};
    return " (the sample time " + detail::format_g(ts) + " s is too long for the model's stiffness, spectral radius " +
           detail::format_g(rho) + " 1/s: a stable step needs " + detail::format_g(need) +
           " sub-steps, more than IntegratorOptions::max_substeps = " + std::to_string(integrator_.max_substeps) + ")";
  }

  /// Generic simulation core on scalar T (double, float, Dual): see `simulate_physics`.
  /// `p` holds n_p values, `x` the n_x initial states (overwritten with the state *at* the last
  /// sample, x(N−1): the interval after it is not integrated, so a chunked run would repeat that
  /// sample — `Stepper` carries the state from one sample to the next); returns the number of
  /// samples delivered to `on_sample(k, const T* y)`.
  template <class T, class OnSample>
  Eigen::Index simulate_with(const Eigen::MatrixXd& u, double ts, const T* p, T* x, int substeps,
                             OnSample&& on_sample) const {
    return simulate_physics<T>(physics_, integrator_, substeps, u, ts, p, x,
                               std::forward<OnSample>(on_sample));
  }

  /// Initial state for an experiment under an initial-condition policy (file comment).
  [[nodiscard]] StateVector initial_state(const Experiment& e, InitialCondition ic) const {
    check_channels(e, -1);
    const int nx = state_dimension();
    switch (ic) {
      case InitialCondition::zero:
        return StateVector::Zero(nx);
      case InitialCondition::equilibrium: {
        require(e.size() > 0, "equilibrium start needs at least one input sample");
        // Searched from the record's own start, as estimation does (GreyBoxProblem): where the
        // equilibrium is not unique, both then pick the same one.
        const ParameterVector p = parameters();
        const Eigen::VectorXd y0 = e.y().row(0).transpose(), u0 = e.u().row(0).transpose();
        StateVector x(nx);
        physics_initial_guess(physics_, y0.data(), u0.data(), p.data(), x.data());
        return equilibrium_from(x, u0, e.name());
      }
      case InitialCondition::measured:
        throw Error("InitialCondition::measured applies to regression models (past outputs); a "
                    "grey-box model starts from a state: use estimate, zero or equilibrium");
      case InitialCondition::estimate:
        break;
    }
    return estimate_initial_state(e);
  }

  /// Equilibrium state for the input `u` held constant: f(x̄, u, p) = 0 (Newton from the zero
  /// state; `InitialCondition::equilibrium` starts from the record's first sample instead).
  /// Throws `nlid::Error` if there is none (e.g. a free body under a net force).
  [[nodiscard]] StateVector equilibrium(const Eigen::Ref<const Eigen::VectorXd>& u,
                                        const std::string& label = {}) const {
    return equilibrium(u, StateVector::Zero(state_dimension()), label);
  }
  /// As above, Newton started from `x_guess` (n_x values): where there are several equilibria (a
  /// pendulum hanging or upright, a tank's levels) the guess selects which one the search
  /// converges to (usually the nearest; a step along f where ∂f/∂x is not finite may move further).
  [[nodiscard]] StateVector equilibrium(const Eigen::Ref<const Eigen::VectorXd>& u,
                                        const Eigen::Ref<const Eigen::VectorXd>& x_guess,
                                        const std::string& label = {}) const {
    require(u.size() == input_dimension(), "equilibrium: input has " + std::to_string(u.size()) +
                                               " entries, the model takes " +
                                               std::to_string(input_dimension()));
    require(x_guess.size() == state_dimension(),
            "equilibrium: the guess must have " + std::to_string(state_dimension()) + " entries, got " +
                std::to_string(x_guess.size()),
            at_parameter("x_guess"));
    require(x_guess.allFinite(), "equilibrium: the guess is not finite", at_parameter("x_guess"));
    return equilibrium_from(StateVector(x_guess), u, label);
  }

  /// Number of leading samples `InitialCondition::estimate` fits x₀ to in `simulate` and
  /// `initial_state` (0 = the whole record). Default 2000: x₀ of a stable system only shapes the
  /// start of a record, and a long record (10⁵ samples) then costs no more than a short one.
  void set_initial_state_window(Eigen::Index samples) {
    require(samples >= 0, "initial-state window must be >= 0 (0 = whole record)",
            at_parameter("initial_state_window"));
    initial_state_window_ = samples;
  }
  /// See `set_initial_state_window`.
  [[nodiscard]] Eigen::Index initial_state_window() const { return initial_state_window_; }

  /// Initial states estimated per experiment by the last `estimate` (empty before).
  [[nodiscard]] const std::vector<Eigen::VectorXd>& estimated_initial_states() const {
    return initial_states_;
  }
  /// Stores per-experiment initial states (used by `estimate`).
  void set_estimated_initial_states(std::vector<Eigen::VectorXd> x0) { initial_states_ = std::move(x0); }

  // ---- reporting -------------------------------------------------------------------------------

  /// Input channel names (those of the estimation data; empty until `initialize` or
  /// `set_channel_names`).
  [[nodiscard]] const std::vector<std::string>& input_names() const { return input_names_; }
  /// Output channel names (see `input_names`).
  [[nodiscard]] const std::vector<std::string>& output_names() const { return output_names_; }
  /// Sets the channel names (a model file's "inputs"/"outputs"). Throws `nlid::Error` naming
  /// "input_names"/"output_names" if a non-empty list does not have one name per channel.
  void set_channel_names(std::vector<std::string> inputs, std::vector<std::string> outputs) {
    require(inputs.empty() || static_cast<int>(inputs.size()) == input_dimension(),
            "grey-box model '" + name() + "' has " + std::to_string(input_dimension()) + " input(s), got " +
                std::to_string(inputs.size()) + " names",
            at_parameter("input_names"));
    require(outputs.empty() || static_cast<int>(outputs.size()) == output_dimension(),
            "grey-box model '" + name() + "' has " + std::to_string(output_dimension()) + " output(s), got " +
                std::to_string(outputs.size()) + " names",
            at_parameter("output_names"));
    input_names_ = std::move(inputs);
    output_names_ = std::move(outputs);
  }

  /// Units used by `describe` for "{y}" and "{u}" (set by `initialize` from the data).
  void set_units(std::string output_unit, std::string input_unit) {
    y_unit_ = std::move(output_unit);
    u_unit_ = std::move(input_unit);
  }

  /// Human-readable account: equation, states, and every parameter with value, unit, bounds and
  /// status (estimated / fixed, with ±1σ when known), plus the integrator.
  [[nodiscard]] std::string describe() const {
    std::string s = "Grey-box model '" + name() + "'";
    if constexpr (detail::HasEquation<P>) s += ": " + physics_.equation();
    s += "\n  states:";
    for (std::size_t i = 0; i < states_.size(); ++i) {
      const StateInfo& st = states_[i];
      s += (i == 0 ? " " : ", ") + st.name;
      if (!st.unit.empty()) s += " (" + detail::substitute_units(st.unit, y_unit_, u_unit_) + ")";
    }
    s += "\n  parameters:\n";
    std::size_t w = 4;
    for (const auto& q : params_) w = std::max(w, q.name.size());
    for (const auto& q : params_) {
      std::string line = "    " + q.name + std::string(w - q.name.size() + 2, ' ');
      std::string val = detail::format_g(q.value);
      line += val + std::string(val.size() < 14 ? 14 - val.size() : 1, ' ');
      std::string unit = detail::substitute_units(q.unit, y_unit_, u_unit_);
      line += unit + std::string(unit.size() < 18 ? 18 - unit.size() : 1, ' ');
      line += q.fixed ? "fixed" : "estimated";
      if (stddev_.size() == num_parameters() && !q.fixed) {
        const double sd = stddev_[&q - params_.data()];
        if (std::isnan(sd)) {
          // Where the estimate stopped on a bound the linearisation does not hold: no σ, and a
          // ± 0 would claim the value exactly known.
          const double tol = 1e-12 * std::max(1.0, std::abs(q.value));  // as the uncertainty's on-bound test
          line += q.value <= q.lower + tol   ? ", on its lower bound"
                  : q.value >= q.upper - tol ? ", on its upper bound"
                                             : ", on a bound (no standard deviation)";
        } else {
          line += std::isfinite(sd) ? " +- " + detail::format_g(sd) : std::string(" +- inf (not identifiable)");
        }
      }
      if (std::isfinite(q.lower) || std::isfinite(q.upper)) {
        line += "  bounds [" + detail::format_g(q.lower) + ", " + detail::format_g(q.upper) + "]";
      }
      if (!q.description.empty()) line += "  -- " + q.description;
      s += line + "\n";
    }
    const char* method = integrator_.method == IntegratorMethod::rk4     ? "rk4"
                         : integrator_.method == IntegratorMethod::euler ? "euler"
                                                                         : "dormand_prince";
    s += "  integrator: " + std::string(method);
    if (integrator_.method == IntegratorMethod::dormand_prince) {
      s += " (rtol " + detail::format_g(integrator_.relative_tolerance) + ", atol " +
           detail::format_g(integrator_.absolute_tolerance) + ")";
    } else if (integrator_.substeps > 0) {
      s += ", " + std::to_string(integrator_.substeps) + " sub-steps per sample";
    } else {
      s += ", automatic sub-steps (h*rho <= " + detail::format_g(integrator_.stability_target) + ")";
    }
    s += "; input held between samples (zero-order hold)\n";
    return s;
  }

  /// Checks an experiment's channel counts and, where it names its channels as the model does, their
  /// order; throws naming experiment `index` (if ≥ 0).
  void check_channels(const Experiment& e, long index) const {
    const Location where = index >= 0 ? at_experiment(index) : Location{};
    // "experiment 2 ('data3')", as much of it as is known.
    const std::string who = "experiment" + (index >= 0 ? " " + std::to_string(index) : std::string()) +
                            (e.name().empty() ? std::string() : " ('" + e.name() + "')");
    e.validate(true);  // u() and y() are mutable: a record resized through one would be read past its end
    require(e.num_inputs() == input_dimension(),
            who + " has " + std::to_string(e.num_inputs()) + " input(s), grey-box model '" + name() +
                "' takes " + std::to_string(input_dimension()),
            where);
    require(e.num_outputs() == output_dimension(),
            who + " has " + std::to_string(e.num_outputs()) + " output(s), grey-box model '" +
                name() + "' gives " + std::to_string(output_dimension()),
            where);
    // The physics reads its inputs and outputs by position: a record carrying the model's channel
    // names in another order would run (or fit) the equations on swapped signals.
    detail::check_channel_order(e.input_names(), input_names_, "input", who, where);
    detail::check_channel_order(e.output_names(), output_names_, "output", who, where);
  }
  /// Checks every experiment of a data set.
  void check_channels(const Dataset& d) const {
    for (std::size_t i = 0; i < d.size(); ++i) check_channels(d[i], static_cast<long>(i));
  }

  // ---- Implementation details below ----------------------------------------------------------

 private:
  /// Why a run failed when the physics itself is not defined there (the log of a negative
  /// command): replays the run to the last sample delivered and evaluates the physics at that
  /// state and input. Empty when it is finite there (a step too long, an unstable model), so the
  /// sub-step advice is given only where it can help.
  [[nodiscard]] std::string undefined_physics_note(const Eigen::MatrixXd& u, double ts,
                                                   const Eigen::Ref<const Eigen::VectorXd>& x0,
                                                   const ParameterVector& p, int sub, Eigen::Index got) const {
    StateVector x = x0;
    const Eigen::Index k = got > 0 ? got - 1 : 0;
    if (got > 0) {
      const auto ignore = [](Eigen::Index, const double*) {};
      const Eigen::MatrixXd head = u.topRows(got);
      if (simulate_physics<double>(physics_, integrator_, sub, head, ts, p.data(), x.data(), ignore) != got) return {};
    }
    const Eigen::VectorXd uk = u.row(k).transpose();
    std::string us;
    for (Eigen::Index j = 0; j < uk.size(); ++j) us += (j > 0 ? ", " : "") + detail::format_g(uk[j]);
    if (got == 0) {
      Eigen::VectorXd y0(output_dimension());
      physics_.output(x.data(), uk.data(), p.data(), y0.data());
      if (y0.allFinite()) return {};
      return ": the physics' output is not finite at the initial state and the input of sample 0 (u = " + us +
             "): the model is not defined there; check the input and the initial state";
    }
    StateVector dx = x;
    physics_.derivative(x.data(), uk.data(), p.data(), dx.data());
    if (dx.allFinite()) return {};
    return ": the physics' derivative is not finite at the state of sample " + std::to_string(k) +
           " and its input (u = " + us + "): the model is not defined there; check the input or the model's domain";
  }

  template <class>
  friend class Stepper;  // checks the relations as simulate does

  // The physics' relations between the values p (`check_parameters`); `what` says which
  // operation set them.
  void check_relations(const Eigen::Ref<const Eigen::VectorXd>& p, const std::string& what) const {
    const Eigen::VectorXd v = p;
    physics_check_parameters(physics_, v.data(), "grey-box model '" + name() + "', " + what);
  }

  static void check_value(const ParameterInfo& q, double v) {
    require(std::isfinite(v), "value of '" + q.name + "' is not finite", at_parameter(q.name));
    require(q.lower <= v && v <= q.upper,
            "value " + detail::format_g(v) + " of '" + q.name + "' is outside its bounds [" +
                detail::format_g(q.lower) + ", " + detail::format_g(q.upper) + "]",
            at_parameter(q.name));
  }

  // Shared by `equilibrium` and the per-record start, so both fail with the same message.
  StateVector equilibrium_from(StateVector x, const Eigen::Ref<const Eigen::VectorXd>& u,
                               const std::string& label) const {
    const ParameterVector p = parameters();
    const Eigen::VectorXd uv = u;
    const EquilibriumResult res = physics_equilibrium(physics_, uv.data(), p.data(), x.data());
    if (!res.converged) {
      throw Error("grey-box model '" + name() + "' has no equilibrium for the input held at its " +
                  (label.empty() ? std::string("given") : "first ('" + label + "')") +
                  " value (|f(x)| stays at " + detail::format_g(res.residual) +
                  "); use InitialCondition::estimate or zero");
    }
    return x;
  }

  // x₀ minimising the simulation error over the first `initial_state_window_` samples of this
  // record with the parameters held (findstates on a prefix).
  StateVector estimate_initial_state(const Experiment& e) const {
    // A window too short to determine x₀ (one sample, or fewer outputs than states) is widened:
    // the record, not the window, is then what a too-short error is about.
    const int ny = output_dimension();
    const Eigen::Index needed = std::max<Eigen::Index>(2, (state_dimension() + ny - 1) / ny);
    const Eigen::Index n = initial_state_window_ > 0
                               ? std::min<Eigen::Index>(e.size(), std::max(initial_state_window_, needed))
                               : e.size();
    Dataset d(n == e.size() ? e
                            : Experiment(e.u().topRows(n), e.y().topRows(n), e.ts(), e.name(),
                                         NonFinitePolicy::keep));
    GreyBoxProblem<P> problem(physics_, integrator_, d, InitialCondition::estimate, {}, true,
                              Eigen::VectorXd(parameters()));
    Eigen::VectorXd theta(problem.num_parameters());
    problem.refresh_initial_states(theta);
    LmOptions lm;
    lm.max_iterations = 50;
    // A guess that cannot be simulated (diverging from a bad state) falls back to zero.
    Eigen::VectorXd r(problem.num_residuals());
    if (!problem.evaluate(theta, r, nullptr)) theta.setZero();
    if (!problem.evaluate(theta, r, nullptr)) {
      throw Error("simulation of grey-box model '" + name() + "' on '" + e.name() +
                  "' diverges from every initial-state guess; check the parameters or raise "
                  "IntegratorOptions::substeps");
    }
    try {
      solve_least_squares(problem, theta, lm);
    } catch (const Error& err) {
      // The solver speaks of "parameters" theta[i]; here they are the record's initial states.
      std::string start;
      for (Eigen::Index i = 0; i < theta.size(); ++i) start += (i ? ", " : "") + detail::format_g(theta[i]);
      throw Error("estimating the initial state of grey-box model '" + name() + "' on '" + e.name() +
                      "' (its unknowns theta[i] are the states, from [" + start + "]): " + err.message() +
                      "; give the physics an initial_state hook, or start from InitialCondition::zero or an x0",
                  err.where());
    }
    return StateVector(theta);
  }

  P physics_;
  std::vector<ParameterInfo> params_;
  std::vector<bool> user_set_;
  std::vector<StateInfo> states_;
  IntegratorOptions integrator_;
  bool initialized_ = false;
  std::string y_unit_, u_unit_;
  std::vector<std::string> input_names_, output_names_;
  std::vector<Eigen::VectorXd> initial_states_;
  Eigen::VectorXd stddev_;
  Eigen::MatrixXd covariance_;

  void clear_uncertainty() {
    stddev_.resize(0);
    covariance_.resize(0, 0);
  }
  Eigen::Index initial_state_window_ = 2000;
};

}  // namespace nlid
