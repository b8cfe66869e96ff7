#pragma once
/// @file
/// `Stepper<Model>`: a model run one sample at a time — the form a controller, an observer or a
/// hardware-in-the-loop rig needs, where the next input is not known before the current output.
///
///     nlid::Stepper run(model);              // Nlarx, HammersteinWiener or Series, at rest
///     run.reset(x0);                         // or from a state (layout of the model's x0)
///     for (;;) { const double y = run.step(u); … }
///
///     nlid::Stepper plant(greybox, ts, x0);  // GreyBox: sample time and initial state
///     const auto& y = plant.step(u);         // outputs y(t); the state moves on to t + 1
///
/// Contract:
/// - `step(u(t))` returns y(t) and advances the state to t + 1: N steps from a state give
///   exactly (bit for bit) the numbers of the model's batch `simulate` over those N samples from
///   that state, so a loop validated offline runs unchanged online. (Grey box: when the sub-step
///   count does not depend on the run — see `Stepper<GreyBox<P>>`.)
/// - The stepper holds its own copy of the model taken at construction: setting new parameters
///   on the model later does not change a running stepper (make a new one).
/// - `state()` is the state after the last step in the layout of the model's x0, so a run can
///   be stopped and resumed, or continued by a batch `simulate` from that state. A stepper is a
///   value: copy it to branch several scenarios from one point.
/// - `step` and `reset` allocate nothing, with static sizes and with the Dynamic twins alike
///   (sizes are fixed when the stepper is built; tests/nomalloc); construction, copies and
///   `state()` allocate. (Exception: a run-time grey-box physics whose sub-step count depends on
///   the run — see `Stepper<GreyBox<P>>`.)
/// - A non-finite input, or an output or state that leaves the finite numbers, throws
///   (`nlid::Error` / `nlid::DivergenceError` naming the sample counted from the last reset);
///   the state is then left as it was before that step. (A grey box whose state diverges inside
///   an interval has already returned that sample's y(t): it refuses the next step.)

#include <cmath>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <type_traits>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/models/greybox.hpp"
#include "nlid/models/greybox_simulate.hpp"
#include "nlid/models/hammerstein_wiener.hpp"
#include "nlid/models/integrators.hpp"
#include "nlid/models/nlarx.hpp"
#include "nlid/models/series.hpp"
#include "nlid/nonlinearities/detail/bound_map.hpp"
#include "nlid/regressors/history.hpp"
#include "nlid/regressors/lag_window.hpp"

namespace nlid {

namespace detail {
template <class>
inline constexpr bool stepper_unsupported = false;

// Refuses a non-finite input sample, naming the channel and the sample.
inline void check_step_input(double u, int channel, std::int64_t k) {
  if (std::isfinite(u)) return;
  throw Error("Stepper: input " + std::to_string(channel) + " is " + format_g(u) + " at sample " + std::to_string(k) +
                  "; a simulation cannot run through it (the state is kept as it was before this sample)",
              at_parameter("u"));
}
}  // namespace detail

/// A model run one sample at a time (see the file comment). Defined for `Nlarx`,
/// `HammersteinWiener`, `Series` (block chains) and `GreyBox`.
template <class Model>
class Stepper {
  static_assert(detail::stepper_unsupported<Model>,
                "nlid::Stepper runs Nlarx, HammersteinWiener, Series and GreyBox models (a model file: load it as its "
                "run-time type, e.g. load_model<nlid::DynamicNlarx>, not as an AnyModel); a linear model (Arx, "
                "OutputError, StateSpace) is stepped by its own simulate over one sample from a state");
};

// ---- nonlinear ARX ---------------------------------------------------------------------------

/// Nonlinear ARX run sample by sample. State: the lag window [y(t−1) … y(t−Ly),
/// u₁(t−1) … u₁(t−Lu), u₂(t−1) …] (`Nlarx::state_dimension()` values, the model's x0 layout).
template <class R, class F>
class Stepper<Nlarx<R, F>> {
 public:
  /// The model type.
  using Model = Nlarx<R, F>;

  /// A stepper of (a copy of) `model`, at rest: every past output and input zero.
  explicit Stepper(const Model& model)
      : model_(model), past_(model_.output_lag()), lu_(model_.input_lag()), nu_(model_.num_inputs()) {
    if constexpr (R::num_regressors == Dynamic) phi_.resize(model_.regressors().size());
    // Rows 0 … Lu−1: u(t−Lu) … u(t−1); row Lu: the current sample, written by `step`.
    window_.resize(lu_ + 1, nu_);
    reset();
  }

  /// Back to rest: every past output and input zero.
  void reset() {
    past_.fill(0.0);
    window_.setZero();
    k_ = 0;
  }

  /// Starts from the lag window `x0` (`state_dimension()` values, the layout of the model's x0:
  /// `Nlarx::initial_state`, `measured_state`, `held_state`, or an earlier `state()`).
  /// Throws `nlid::Error` naming "x0" if its size differs or a value is not finite.
  void reset(const Eigen::Ref<const Eigen::VectorXd>& x0) {
    // Tested before a message is built: a reset inside a control loop must not allocate either.
    if (x0.size() != model_.state_dimension()) {
      throw Error("Stepper: initial state has " + std::to_string(x0.size()) + " values, the model's lag window has " +
                      std::to_string(model_.state_dimension()),
                  at_parameter("x0"));
    }
    if (!x0.allFinite()) throw Error("Stepper: initial state is not finite", at_parameter("x0"));
    const int ly = model_.output_lag();
    past_.fill(0.0);
    for (int k = ly; k >= 1; --k) past_.push(x0(k - 1));  // lag 1 pushed last
    window_.setZero();
    for (int c = 0; c < nu_; ++c)
      for (int k = 1; k <= lu_; ++k) window_(lu_ - k, c) = x0(ly + c * lu_ + k - 1);
    k_ = 0;
  }

  /// y(t) for the input sample u(t) (one value per input channel); advances to t + 1.
  double step(std::span<const double> u) {
    // Tested before a message is built: a step must not allocate.
    if (static_cast<int>(u.size()) != nu_) {
      throw Error("Stepper: " + std::to_string(u.size()) + " input value(s) given, the model reads " +
                      std::to_string(nu_),
                  at_parameter("u"));
    }
    for (int c = 0; c < nu_; ++c) {
      detail::check_step_input(u[static_cast<std::size_t>(c)], c, k_);
      window_(lu_, c) = u[static_cast<std::size_t>(c)];
    }
    // The batch simulation's window over a record whose current row is row Lu of ours: the
    // same regressor values, hence the same output to the last bit.
    SimulationWindow<double, R::max_output_lag> w(window_, past_, std::span<const double>{}, lu_);
    w.set_time(lu_);
    const std::span<double> phi(phi_.data(), static_cast<std::size_t>(phi_.size()));
    model_.regressors().evaluate(w, phi);
    const double y = model_.evaluate(std::span<const double>(phi_.data(), phi.size()),
                                     std::span<const double>(model_.parameters().data(),
                                                             static_cast<std::size_t>(model_.num_parameters())));
    if (!std::isfinite(y)) {
      throw DivergenceError("Stepper: the output of the nonlinear ARX model is not finite at sample " +
                                std::to_string(k_) + " (the state is kept as it was before this sample)",
                            static_cast<long>(k_));
    }
    past_.push(y);
    for (int i = 0; i < lu_; ++i) window_.row(i) = window_.row(i + 1);
    ++k_;
    return y;
  }
  /// Single-input models: y(t) for u(t).
  double step(double u) { return step(std::span<const double>(&u, 1)); }

  /// The lag window after the last step, in the layout of the model's x0.
  [[nodiscard]] Eigen::VectorXd state() const {
    const int ly = model_.output_lag();
    Eigen::VectorXd x(model_.state_dimension());
    for (int k = 1; k <= ly; ++k) x(k - 1) = past_(k);
    for (int c = 0; c < nu_; ++c)
      for (int k = 1; k <= lu_; ++k) x(ly + c * lu_ + k - 1) = window_(lu_ - k, c);
    return x;
  }
  /// Steps taken since the last reset.
  [[nodiscard]] std::int64_t samples() const { return k_; }
  /// The stepper's copy of the model.
  [[nodiscard]] const Model& model() const { return model_; }

 private:
  Model model_;
  History<double, R::max_output_lag> past_;
  int lu_, nu_;
  Eigen::MatrixXd window_;
  Eigen::Matrix<double, R::num_regressors, 1> phi_;
  std::int64_t k_ = 0;
};

// ---- Hammerstein–Wiener and block chains ----------------------------------------------------

namespace detail {

// What the block-state steppers share (Hammerstein–Wiener, chains): a state made of linear-block
// states, stepped in a scratch copy that is swapped in only when the output and the state are
// finite — behind a saturating output map an unstable block would run off to inf unseen.
template <int NS>
class BlockStateStepper {
 public:
  /// Every linear block back to rest.
  void reset() {
    s_.setZero();
    k_ = 0;
  }
  /// Starts from the block state `x0` (the model's x0 layout). Throws `nlid::Error` naming "x0"
  /// if its size differs or a value is not finite.
  void reset(const Eigen::Ref<const Eigen::VectorXd>& x0) {
    // Tested before a message is built: a reset inside a control loop must not allocate.
    if (x0.size() != s_.size()) {
      throw Error("Stepper: initial state has " + std::to_string(x0.size()) + " values, " + states_of_ + " " +
                      std::to_string(s_.size()) + " states",
                  at_parameter("x0"));
    }
    if (!x0.allFinite()) throw Error("Stepper: initial state is not finite", at_parameter("x0"));
    s_ = x0;
    k_ = 0;
  }
  /// The block state after the last step (the model's x0 layout).
  [[nodiscard]] Eigen::VectorXd state() const { return s_; }
  /// Steps taken since the last reset.
  [[nodiscard]] std::int64_t samples() const { return k_; }

 protected:
  using State = Eigen::Matrix<double, NS, 1>;
  // `states_of`: "the linear block has"; `owner`: "Hammerstein-Wiener model" (for messages).
  BlockStateStepper(Eigen::Index n, const char* states_of, const char* state_noun, const char* owner)
      : states_of_(states_of), state_noun_(state_noun), owner_(owner) {
    if constexpr (NS == Dynamic) {
      s_.resize(n);
      next_.resize(n);
    }
    reset();
  }
  // The one input of a span, for the signature the other steppers share.
  static double single(std::span<const double> u) {
    if (u.size() != 1) {
      throw Error("Stepper: " + std::to_string(u.size()) + " input values given, the model reads 1", at_parameter("u"));
    }
    return u[0];
  }
  // Starts a step: refuses a non-finite input; the step then works on next_.
  std::span<double> begin(double u) {
    check_step_input(u, 0, k_);
    next_ = s_;  // same size: no allocation, also Dynamic
    return {next_.data(), static_cast<std::size_t>(next_.size())};
  }
  // Ends a step that gave y: keeps the new state if it and y are finite, else throws.
  double commit(double y) {
    if (!std::isfinite(y) || !values_finite(next_)) {
      throw DivergenceError("Stepper: the " + std::string(std::isfinite(y) ? state_noun_ : "output") + " of the " +
                                owner_ + " is not finite at sample " + std::to_string(k_) +
                                " (the state is kept as it was before this sample)",
                            static_cast<long>(k_));
    }
    s_.swap(next_);
    ++k_;
    return y;
  }

 private:
  State s_, next_;
  std::int64_t k_ = 0;
  const char* states_of_;
  const char* state_noun_;
  const char* owner_;
};

}  // namespace detail

/// Hammerstein–Wiener model run sample by sample. State: the linear block's n states
/// (`state_dimension()`, the model's x0 layout; `TransferFunctionBlock`): `reset(x0)` from the
/// model's `initial_state` or `equilibrium_state`.
template <class In, class L, class Out>
class Stepper<HammersteinWiener<In, L, Out>> : public detail::BlockStateStepper<L::num_states> {
  using Base = detail::BlockStateStepper<L::num_states>;

 public:
  /// The model type.
  using Model = HammersteinWiener<In, L, Out>;

  /// A stepper of (a copy of) `model`, with the linear block at rest.
  explicit Stepper(const Model& model)
      : Base(model.state_dimension(), "the linear block has", "linear block's state", "Hammerstein-Wiener model"),
        model_(model) {
    bind();
  }
  /// Copies re-bind the maps to their own copy of θ (the maps' prepared tables view it).
  Stepper(const Stepper& o) : Base(o), model_(o.model_) { bind(); }
  /// See the copy constructor.
  Stepper& operator=(const Stepper& o) {
    if (this != &o) {
      Base::operator=(o);
      model_ = o.model_;
      bind();
    }
    return *this;
  }
  ~Stepper() = default;

  /// y(t) for u(t); advances the linear block to t + 1.
  double step(double u) {
    const std::span<double> s = this->begin(u);
    const double w = (*f_)(u);
    const double x = model_.linear_block().step(s, w, theta_l_);
    return this->commit((*h_)(x));
  }
  /// The one-input form of the span signature the other steppers share.
  double step(std::span<const double> u) { return step(Base::single(u)); }

  /// The stepper's copy of the model.
  [[nodiscard]] const Model& model() const { return model_; }

 private:
  using InMap = detail::BoundScalarMap<In, double>;
  using OutMap = detail::BoundScalarMap<Out, double>;

  // The maps' θ-only work (PwLinear's breakpoint table) done once, as the batch simulation does.
  void bind() {
    const std::span<const double> theta(model_.parameters().data(), static_cast<std::size_t>(model_.num_parameters()));
    const auto of = static_cast<std::size_t>(model_.linear_offset());
    const auto oh = static_cast<std::size_t>(model_.output_offset());
    theta_l_ = theta.subspan(of, oh - of);
    f_.emplace(model_.input_nonlinearity(), theta.first(of));
    h_.emplace(model_.output_nonlinearity(), theta.subspan(oh));
  }

  Model model_;
  std::span<const double> theta_l_;
  std::optional<InMap> f_;
  std::optional<OutMap> h_;
};

/// A block chain (`Series`: Hammerstein, Wiener, Wiener–Hammerstein, …) run sample by sample.
/// State: the stacked states of its linear blocks (`state_dimension()`, the model's x0 layout).
template <SeriesBlock... Blocks>
class Stepper<Series<Blocks...>> : public detail::BlockStateStepper<Series<Blocks...>::num_states> {
  using Base = detail::BlockStateStepper<Series<Blocks...>::num_states>;

 public:
  /// The model type.
  using Model = Series<Blocks...>;

  /// A stepper of (a copy of) `model`, every linear block at rest.
  explicit Stepper(const Model& model)
      : Base(model.state_dimension(), "the chain's linear blocks have", "block state", "block chain"),
        model_(model) {}

  /// y(t) for u(t); advances every linear block to t + 1 (the operations of the batch loop).
  double step(double u) {
    const std::span<double> s = this->begin(u);
    return this->commit(model_.step(s, u, std::span<const double>(model_.parameters().data(),
                                                                 static_cast<std::size_t>(model_.num_parameters()))));
  }
  /// The one-input form of the span signature the other steppers share.
  double step(std::span<const double> u) { return step(Base::single(u)); }

  /// The stepper's copy of the model.
  [[nodiscard]] const Model& model() const { return model_; }

 private:
  Model model_;
};

// ---- grey box --------------------------------------------------------------------------------

/// Grey-box model run sample by sample with zero-order hold. State: the physics' n_x states.
///
/// Sub-steps (fixed-step methods): the count is fixed at construction when it does not depend on
/// the run — `IntegratorOptions::substeps` set, or a physics with a `spectral_radius` — and then
/// the steps equal `GreyBox::simulate` bit for bit. Otherwise (the count follows the stiffest
/// state a run reaches, `physics_substeps`) a batch simulation takes the largest count of its
/// whole record from the first sample on, which a sample-by-sample run cannot know in advance:
/// the stepper starts at the count of its initial state and raises it as stiffer states are
/// reached. Its numbers then differ from the batch run's by the integrator's error, not more;
/// set `IntegratorOptions::substeps` (e.g. to `GreyBox::substeps(u, ts, x0)` of a representative
/// record) where online and offline runs must agree exactly — and for a run-time physics, whose
/// stiffness is then judged at every step from a Jacobian that allocates. The adaptive method
/// carries its step size from sample to sample, as the batch simulation does.
template <class P>
class Stepper<GreyBox<P>> {
 public:
  /// The model type.
  using Model = GreyBox<P>;
  /// Output vector y(t).
  using OutputVector = Eigen::Matrix<double, P::num_outputs, 1>;

  /// A stepper of (a copy of) `model` at sample time `ts` from the state `x0`. Throws
  /// `nlid::Error` naming "ts" or "x0" if ts is not positive and finite or x0 has the wrong size
  /// or is not finite.
  Stepper(const Model& model, double ts, const Eigen::Ref<const Eigen::VectorXd>& x0)
      : model_(model), p_(model_.parameters()), ts_(ts) {
    require(ts > 0.0 && std::isfinite(ts), "Stepper: sample time must be positive and finite, got " + detail::format_g(ts),
            at_parameter("ts"));
    const int nu = model_.input_dimension();
    if constexpr (P::num_inputs == Dynamic) uk_.resize(nu);
    if constexpr (P::num_outputs == Dynamic) y_.resize(model_.output_dimension());
    if constexpr (P::num_states == Dynamic) {
      x_.resize(model_.state_dimension());
      next_.resize(model_.state_dimension());
    }
    rk4_.reserve(model_.state_dimension());
    euler_.reserve(model_.state_dimension());
    dopri_.reserve(model_.state_dimension());
    model_.check_relations(p_, "Stepper");  // what simulate refuses, the stepper refuses
    fixed_count_ = model_.integrator().substeps > 0 || physics_stiffness_known(model_.physics(), p_.data());
    reset(x0);
    if (fixed_count_) {
      // The batch run's own rule with its own arguments: one count for every state, so it is
      // judged once here (it allocates for a run-time physics; reset and step must not).
      fixed_substeps_ = physics_substeps(model_.physics(), model_.integrator(), p_.data(), x_.data(),
                                         Eigen::MatrixXd(0, model_.input_dimension()), ts_);
      substeps_ = fixed_substeps_;
    }
  }

  /// Starts again from the state `x0` (n_x values). Throws `nlid::Error` naming "x0" if its size
  /// differs or a value is not finite.
  void reset(const Eigen::Ref<const Eigen::VectorXd>& x0) {
    if (x0.size() != model_.state_dimension()) {
      throw Error("Stepper: initial state has " + std::to_string(x0.size()) + " entries, grey-box model '" +
                      model_.name() + "' has " + std::to_string(model_.state_dimension()) + " states",
                  at_parameter("x0"));
    }
    if (!x0.allFinite()) {
      throw Error("Stepper: initial state of grey-box model '" + model_.name() + "' is not finite",
                  at_parameter("x0"));
    }
    x_ = x0;
    h_try_ = 0.0;
    k_ = 0;
    diverged_ = false;
    worst_ = -1.0;  // the count is judged again from this state
    substeps_ = fixed_count_ ? fixed_substeps_ : model_.integrator().min_substeps;
  }

  /// y(t) for the input sample u(t) (n_u values); advances the state to t + 1. Throws
  /// `nlid::DivergenceError` if y(t) is not finite, or — at the next step, once y(t) has been
  /// returned — if the state left the finite numbers during the interval.
  const OutputVector& step(std::span<const double> u) {
    const int nu = model_.input_dimension();
    if (static_cast<int>(u.size()) != nu) {
      throw Error("Stepper: " + std::to_string(u.size()) + " input value(s) given, grey-box model '" +
                      model_.name() + "' takes " + std::to_string(nu),
                  at_parameter("u"));
    }
    if (diverged_) {
      const std::string how = model_.integrator().method == IntegratorMethod::dormand_prince
                                  ? "with the adaptive Dormand-Prince method (IntegratorOptions::max_adaptive_steps = " +
                                        std::to_string(model_.integrator().max_adaptive_steps) + ")"
                                  : "with " + std::to_string(substeps_) + " sub-step(s) per sample";
      throw DivergenceError("Stepper: simulation of grey-box model '" + model_.name() + "' diverged at sample " +
                                std::to_string(k_) + " " + how + "; reset it from a finite state",
                            static_cast<long>(k_));
    }
    for (int j = 0; j < nu; ++j) {
      detail::check_step_input(u[static_cast<std::size_t>(j)], j, k_);
      uk_[j] = u[static_cast<std::size_t>(j)];
    }
    const P& phys = model_.physics();
    phys.output(x_.data(), uk_.data(), p_.data(), y_.data());
    if (!detail::values_finite(y_)) {
      throw DivergenceError("Stepper: output of grey-box model '" + model_.name() + "' is not finite at sample " +
                                std::to_string(k_),
                            static_cast<long>(k_));
    }
    const IntegratorOptions& o = model_.integrator();
    if (!fixed_count_ && o.method != IntegratorMethod::dormand_prince) {
      // The batch rule's bound at this sample's state and input, kept as a running maximum.
      const double r = detail::gershgorin_bound(phys, x_.data(), uk_.data(), p_.data());
      if (r > worst_) {
        worst_ = r;
        substeps_ = substeps_for(ts_, worst_, o);
      }
    }
    auto f = [&](const State& s, State& ds) { phys.derivative(s.data(), uk_.data(), p_.data(), ds.data()); };
    next_ = x_;  // same size: no allocation, also for a run-time physics
    double h = h_try_;
    bool ok = true;
    if (o.method == IntegratorMethod::dormand_prince) {
      ok = dopri_.integrate(f, next_, ts_, h, o);
    } else {
      ok = detail::fixed_step_interval(o.method, rk4_, euler_, f, next_, ts_, std::max(1, substeps_));
    }
    ++k_;
    if (!ok) {
      diverged_ = true;  // y(t) is still valid; the next sample cannot be delivered
    } else {
      x_.swap(next_);
      h_try_ = h;
    }
    return y_;
  }
  /// Single-input models: y(t) for u(t).
  const OutputVector& step(double u) { return step(std::span<const double>(&u, 1)); }

  /// The state after the last step (x(t + 1)), n_x values. After a divergence (the step that
  /// returned y(t) could not integrate on), the last finite state x(t).
  [[nodiscard]] Eigen::VectorXd state() const { return x_; }
  /// Sub-steps per sample the fixed-step methods use now.
  [[nodiscard]] int substeps() const { return substeps_; }
  /// Steps taken since the last reset.
  [[nodiscard]] std::int64_t samples() const { return k_; }
  /// The stepper's copy of the model.
  [[nodiscard]] const Model& model() const { return model_; }

 private:
  using State = Eigen::Matrix<double, P::num_states, 1>;

  Model model_;
  typename Model::ParameterVector p_;
  double ts_;
  State x_, next_;
  // The integrators' stage buffers, kept so that a run-time state size allocates them once.
  Rk4Stepper<State> rk4_;
  EulerStepper<State> euler_;
  DormandPrinceStepper<State> dopri_;
  Eigen::Matrix<double, P::num_inputs, 1> uk_;
  OutputVector y_;
  bool fixed_count_ = false;
  int fixed_substeps_ = 1;
  int substeps_ = 1;
  double worst_ = -1.0;
  double h_try_ = 0.0;
  bool diverged_ = false;
  std::int64_t k_ = 0;
};

/// Deduction guide: `Stepper run(nlarx_or_hw_model)`.
template <class Model>
Stepper(const Model&) -> Stepper<Model>;
/// Deduction guide: `Stepper run(greybox, ts, x0)`.
template <class P, class X>
Stepper(const GreyBox<P>&, double, const X&) -> Stepper<GreyBox<P>>;

}  // namespace nlid
