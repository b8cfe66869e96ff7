#pragma once
/// @file
/// Grey-box physics chosen at run time: `RuntimePhysics` (type-erased interface), `AnyPhysics`
/// (value handle), the catalogue registry `make_physics("throttle")`, and
/// `DynamicGreyBox = GreyBox<AnyPhysics>`.
///
/// Why a second path. `GreyBox<physics::Throttle>` is fastest (fixed sizes, no allocation per
/// sample, one Dual pass per experiment), but its physics is fixed when the program is compiled.
/// Missing-physics diagnosis must build models while it runs: a baseline picked by name, then
/// augmented by effects (friction, backlash, dead zone, dead time …) chosen from the data. So a
/// physics can also be an object behind a virtual interface with run-time sizes and parameter
/// tables. Sensitivities then use the fixed chunk type `RuntimeDual = Dual<double, 8>`: one
/// virtual call serves 8 Jacobian columns, and the interface needs exactly two evaluation
/// overloads (double and RuntimeDual) instead of a template, which virtual functions cannot be.
///
/// Writing a runtime physics. Derive from `RuntimePhysicsBase<Derived>` and write the equations
/// once as member templates `compute_derivative<T>` / `compute_output<T>`; the base implements
/// the virtual overloads from them (CRTP) for T = double, RuntimeDual and TraceScalar (the code
/// generator's tracer, so a run-time model can be exported as C) — so write them with operations
/// on T only, never converting a T to double:
///
///     struct Augmented : RuntimePhysicsBase<Augmented> {
///       AnyPhysics base;                                   // e.g. make_physics("throttle")
///       template <class T> void compute_derivative(const T* x, const T* u, const T* p, T* dx) const {
///         base.derivative(x, u, p, dx);                    // baseline physics
///         dx[1] -= p[base.num_parameters()] * tanh(x[1] / T(0.01));   // + Coulomb friction
///       }
///       …                                                  // sizes, parameter_info(), output
///     };
///
/// Exactness. A compile-time catalogue physics wrapped at run time performs the same floating-
/// point operations in the same order, so `DynamicGreyBox` simulations equal `GreyBox<P>` ones to
/// the last bit (tested to 1e−12), and their Jacobians agree to rounding.
///
/// The registry is process-wide and thread-safe; `register_physics` adds user physics under a
/// new name (a name can be registered once).

#include <algorithm>
#include <concepts>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

#include "nlid/codegen/trace_scalar.hpp"
#include "nlid/core/error.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/models/greybox.hpp"
#include "nlid/models/greybox_concepts.hpp"
#include "nlid/models/greybox_simulate.hpp"
#include "nlid/models/physics/catalogue.hpp"

namespace nlid {

/// Type-erased grey-box physics with run-time sizes (see the file comment). Implementations must
/// be immutable after construction: one object is shared by copies of a model and evaluated from
/// several threads at once (multi-start).
class RuntimePhysics {
 public:
  virtual ~RuntimePhysics() = default;

  /// Catalogue or user name, e.g. "throttle".
  [[nodiscard]] virtual std::string name() const = 0;
  /// Equation for reports (may be empty).
  [[nodiscard]] virtual std::string equation() const { return {}; }
  /// n_x.
  [[nodiscard]] virtual int state_dimension() const = 0;
  /// n_u.
  [[nodiscard]] virtual int input_dimension() const = 0;
  /// n_y.
  [[nodiscard]] virtual int output_dimension() const = 0;
  /// n_p.
  [[nodiscard]] virtual int num_parameters() const = 0;
  /// n_p parameter descriptions with default values, bounds and ranges.
  [[nodiscard]] virtual std::vector<ParameterInfo> parameter_info() const = 0;
  /// n_x state descriptions (default: x1, x2, …).
  [[nodiscard]] virtual std::vector<StateInfo> state_info() const {
    std::vector<StateInfo> s;
    for (int i = 0; i < state_dimension(); ++i) s.push_back({"x" + std::to_string(i + 1), "", ""});
    return s;
  }
  /// ẋ = f(x, u, p) on doubles.
  virtual void derivative(const double* x, const double* u, const double* p, double* dx) const = 0;
  /// ẋ = f(x, u, p) on RuntimeDual (8 derivative directions).
  virtual void derivative(const RuntimeDual* x, const RuntimeDual* u, const RuntimeDual* p,
                          RuntimeDual* dx) const = 0;
  /// y = g(x, u, p) on doubles.
  virtual void output(const double* x, const double* u, const double* p, double* y) const = 0;
  /// y = g(x, u, p) on RuntimeDual.
  virtual void output(const RuntimeDual* x, const RuntimeDual* u, const RuntimeDual* p,
                      RuntimeDual* y) const = 0;
  /// f on the code generator's tracer (codegen/trace_scalar.hpp), so that a model built at run
  /// time — loaded from a file, or composed by a diagnosis — can be exported as C like a
  /// compile-time one. Default: this physics cannot be traced (an `nlid::Error` from codegen).
  virtual void derivative(const TraceScalar* x, const TraceScalar* u, const TraceScalar* p, TraceScalar* dx) const {
    (void)x, (void)u, (void)p, (void)dx;
    throw Error("codegen: grey-box physics '" + name() + "' cannot be traced (it does not implement the TraceScalar overloads); "
                "derive it from RuntimePhysicsBase or generate code from its compile-time type",
                at_parameter("physics"));
  }
  /// g on the tracer (see `derivative`).
  virtual void output(const TraceScalar* x, const TraceScalar* u, const TraceScalar* p, TraceScalar* y) const {
    (void)x, (void)u, (void)p, (void)y;
    throw Error("codegen: grey-box physics '" + name() + "' cannot be traced (it does not implement the TraceScalar overloads); "
                "derive it from RuntimePhysicsBase or generate code from its compile-time type",
                at_parameter("physics"));
  }
  /// Upper bound on |eig ∂f/∂x| for the sub-step rule; negative = unknown (then the Gershgorin
  /// bound at the initial state is used), 0 = no stiffness (only the sub-step floor applies).
  [[nodiscard]] virtual double spectral_radius(const double* /*p*/) const { return -1.0; }
  /// Data-driven starting values and ranges (default: keep the defaults).
  virtual void initialize(const Dataset& /*data*/, std::span<ParameterInfo> /*params*/) const {}
  /// Initial-state guess from the first sample; false = no guess (equilibrium is tried).
  virtual bool initial_state(const double* /*y0*/, const double* /*u0*/, const double* /*p*/,
                             double* /*x0*/) const {
    return false;
  }
  /// Relations between parameter values (greybox_concepts.hpp): throws `nlid::Error` if p
  /// violates one (default: none).
  virtual void check_parameters(const double* /*p*/) const {}
};

/// CRTP helper: implements the six evaluation overloads of `RuntimePhysics` from the member
/// templates `Derived::compute_derivative<T>` and `Derived::compute_output<T>`.
template <class Derived>
class RuntimePhysicsBase : public RuntimePhysics {
 public:
  /// Forwards to `Derived::compute_derivative<double>`.
  void derivative(const double* x, const double* u, const double* p, double* dx) const override {
    self().compute_derivative(x, u, p, dx);
  }
  /// Forwards to `Derived::compute_derivative<RuntimeDual>`.
  void derivative(const RuntimeDual* x, const RuntimeDual* u, const RuntimeDual* p,
                  RuntimeDual* dx) const override {
    self().compute_derivative(x, u, p, dx);
  }
  /// Forwards to `Derived::compute_output<double>`.
  void output(const double* x, const double* u, const double* p, double* y) const override {
    self().compute_output(x, u, p, y);
  }
  /// Forwards to `Derived::compute_output<RuntimeDual>`.
  void output(const RuntimeDual* x, const RuntimeDual* u, const RuntimeDual* p,
              RuntimeDual* y) const override {
    self().compute_output(x, u, p, y);
  }
  void derivative(const TraceScalar* x, const TraceScalar* u, const TraceScalar* p, TraceScalar* dx) const override {
    self().compute_derivative(x, u, p, dx);
  }
  void output(const TraceScalar* x, const TraceScalar* u, const TraceScalar* p, TraceScalar* y) const override {
    self().compute_output(x, u, p, y);
  }

 private:
  const Derived& self() const { return static_cast<const Derived&>(*this); }
};

/// Wraps a compile-time `Physics` (e.g. a catalogue type) as a `RuntimePhysics`.
template <StaticPhysics P>
class PhysicsAdapter final : public RuntimePhysicsBase<PhysicsAdapter<P>> {
 public:
  /// Wraps a copy of `physics`.
  explicit PhysicsAdapter(P physics = {}) : p_(std::move(physics)) {}

  [[nodiscard]] std::string name() const override {
    if constexpr (detail::HasPhysicsName<P>) {
      return p_.name();
    } else {
      return "custom";
    }
  }
  [[nodiscard]] std::string equation() const override {
    if constexpr (detail::HasEquation<P>) {
      return p_.equation();
    } else {
      return {};
    }
  }
  [[nodiscard]] int state_dimension() const override { return P::num_states; }
  [[nodiscard]] int input_dimension() const override { return P::num_inputs; }
  [[nodiscard]] int output_dimension() const override { return P::num_outputs; }
  [[nodiscard]] int num_parameters() const override { return P::num_params; }
  [[nodiscard]] std::vector<ParameterInfo> parameter_info() const override {
    const auto a = p_.parameter_info();
    return std::vector<ParameterInfo>(a.begin(), a.end());
  }
  [[nodiscard]] std::vector<StateInfo> state_info() const override {
    if constexpr (detail::HasStateInfo<P>) {
      const auto a = p_.state_info();
      return std::vector<StateInfo>(a.begin(), a.end());
    } else {
      return RuntimePhysics::state_info();
    }
  }
  [[nodiscard]] double spectral_radius(const double* p) const override {
    if constexpr (detail::HasSpectralRadius<P>) {
      return p_.spectral_radius(p);
    } else {
      (void)p;
      return -1.0;
    }
  }
  void initialize(const Dataset& data, std::span<ParameterInfo> params) const override {
    if constexpr (detail::HasInitializeHook<P>) {
      p_.initialize(data, params);
    } else {
      (void)data;
      (void)params;
    }
  }
  bool initial_state(const double* y0, const double* u0, const double* p, double* x0) const override {
    if constexpr (detail::HasInitialStateHook<P>) {
      return p_.initial_state(y0, u0, p, x0);
    } else {
      (void)y0, (void)u0, (void)p, (void)x0;
      return false;
    }
  }
  void check_parameters(const double* p) const override { physics_check_parameters(p_, p); }

  /// The wrapped physics' f.
  template <class T>
  void compute_derivative(const T* x, const T* u, const T* p, T* dx) const {
    p_.derivative(x, u, p, dx);
  }
  /// The wrapped physics' g.
  template <class T>
  void compute_output(const T* x, const T* u, const T* p, T* y) const {
    p_.output(x, u, p, y);
  }
  /// The wrapped physics.
  [[nodiscard]] const P& physics() const { return p_; }

 private:
  P p_;
};

/// Value handle of a `RuntimePhysics`: satisfies `Physics` with `Dynamic` sizes, so
/// `GreyBox<AnyPhysics>` (= `DynamicGreyBox`) is a grey-box model whose physics is chosen at run
/// time. Copies share the (immutable) implementation.
class AnyPhysics {
 public:
  static constexpr int num_states = Dynamic;   ///< run time: `state_dimension()`
  static constexpr int num_inputs = Dynamic;   ///< run time: `input_dimension()`
  static constexpr int num_outputs = Dynamic;  ///< run time: `output_dimension()`
  static constexpr int num_params = Dynamic;   ///< run time: `num_parameters()`

  /// Holds `impl`; throws `nlid::Error` if it is null.
  explicit AnyPhysics(std::shared_ptr<const RuntimePhysics> impl) : impl_(std::move(impl)) {
    require(impl_ != nullptr, "AnyPhysics: null physics");
  }
  /// Wraps a compile-time physics.
  template <StaticPhysics P>
  static AnyPhysics from(P physics) {
    return AnyPhysics(std::make_shared<const PhysicsAdapter<P>>(std::move(physics)));
  }

  /// The implementation.
  [[nodiscard]] const RuntimePhysics& runtime() const { return *impl_; }
  /// Shared pointer to the implementation (for wrapping in augmentations).
  [[nodiscard]] const std::shared_ptr<const RuntimePhysics>& pointer() const { return impl_; }

  [[nodiscard]] std::string name() const { return impl_->name(); }                 ///< name
  [[nodiscard]] std::string equation() const { return impl_->equation(); }         ///< equation
  [[nodiscard]] int state_dimension() const { return impl_->state_dimension(); }   ///< n_x
  [[nodiscard]] int input_dimension() const { return impl_->input_dimension(); }   ///< n_u
  [[nodiscard]] int output_dimension() const { return impl_->output_dimension(); } ///< n_y
  [[nodiscard]] int num_parameters() const { return impl_->num_parameters(); }     ///< n_p
  /// Parameter descriptions.
  [[nodiscard]] std::vector<ParameterInfo> parameter_info() const { return impl_->parameter_info(); }
  /// State descriptions.
  [[nodiscard]] std::vector<StateInfo> state_info() const { return impl_->state_info(); }
  /// Stiffness bound (negative = unknown; see `RuntimePhysics::spectral_radius`).
  [[nodiscard]] double spectral_radius(const double* p) const { return impl_->spectral_radius(p); }
  /// Data-driven initialisation.
  void initialize(const Dataset& data, std::span<ParameterInfo> params) const {
    impl_->initialize(data, params);
  }
  /// Initial-state guess.
  bool initial_state(const double* y0, const double* u0, const double* p, double* x0) const {
    return impl_->initial_state(y0, u0, p, x0);
  }
  /// Relations between parameter values; throws `nlid::Error` if p violates one.
  void check_parameters(const double* p) const { impl_->check_parameters(p); }
  /// f on double or RuntimeDual (the only scalars a virtual interface can offer).
  template <class T>
    requires(std::same_as<T, double> || std::same_as<T, RuntimeDual> || std::same_as<T, TraceScalar>)
  void derivative(const T* x, const T* u, const T* p, T* dx) const {
    impl_->derivative(x, u, p, dx);
  }
  /// g on double or RuntimeDual.
  template <class T>
    requires(std::same_as<T, double> || std::same_as<T, RuntimeDual> || std::same_as<T, TraceScalar>)
  void output(const T* x, const T* u, const T* p, T* y) const {
    impl_->output(x, u, p, y);
  }

 private:
  std::shared_ptr<const RuntimePhysics> impl_;
};

/// A grey-box model whose physics is chosen at run time.
using DynamicGreyBox = GreyBox<AnyPhysics>;

/// Makes a fresh runtime physics.
using PhysicsFactory = std::function<std::shared_ptr<const RuntimePhysics>()>;

namespace detail {
struct PhysicsRegistry {
  std::mutex mutex;
  std::map<std::string, PhysicsFactory, std::less<>> factories;
};
// One registry per process (an inline function's static is unique across translation units),
// filled with the catalogue on first use.
inline PhysicsRegistry& physics_registry() {
  static PhysicsRegistry reg;
  static std::once_flag filled;
  std::call_once(filled, [] {
    auto add = []<class P>(P) {
      reg.factories.emplace(P{}.name(), [] { return std::make_shared<const PhysicsAdapter<P>>(); });
    };
    add(physics::Throttle{});
    add(physics::MassSpringDamper{});
    add(physics::RigidBody{});
    add(physics::FirstOrder{});
    add(physics::TwoTank{});
  });
  return reg;
}
}  // namespace detail

/// Names of every registered physics, sorted ("first_order", "mass_spring_damper", …).
inline std::vector<std::string> physics_names() {
  auto& reg = detail::physics_registry();
  std::lock_guard<std::mutex> lock(reg.mutex);
  std::vector<std::string> names;
  for (const auto& [n, f] : reg.factories) names.push_back(n);
  return names;
}

/// Registers a user physics under `name`. Throws `nlid::Error` if the name is empty, taken, or
/// the factory is empty.
inline void register_physics(const std::string& name, PhysicsFactory factory) {
  require(!name.empty(), "register_physics: empty name");
  require(static_cast<bool>(factory), "register_physics: empty factory for '" + name + "'");
  auto& reg = detail::physics_registry();
  std::lock_guard<std::mutex> lock(reg.mutex);
  require(reg.factories.find(name) == reg.factories.end(),
          "register_physics: a physics named '" + name + "' is already registered",
          at_parameter(name));
  reg.factories.emplace(name, std::move(factory));
}

/// The physics registered under `name` (the catalogue: throttle, mass_spring_damper, rigid_body,
/// first_order, two_tank). Throws `nlid::Error` listing the known names if there is none.
inline AnyPhysics make_physics(std::string_view name) {
  auto& reg = detail::physics_registry();
  PhysicsFactory f;
  {
    std::lock_guard<std::mutex> lock(reg.mutex);
    const auto it = reg.factories.find(name);
    if (it != reg.factories.end()) f = it->second;
  }
  if (!f) {
    std::string known;
    for (const std::string& n : physics_names()) known += (known.empty() ? "" : ", ") + n;
    throw Error("unknown physics '" + std::string(name) + "'; known physics: " + known,
                at_parameter("physics"));
  }
  auto impl = f();
  require(impl != nullptr, "physics factory for '" + std::string(name) + "' returned null");
  return AnyPhysics(std::move(impl));
}

/// A grey-box model of the physics registered under `name` (see `make_physics`).
inline DynamicGreyBox make_greybox(std::string_view name) { return DynamicGreyBox(make_physics(name)); }

}  // namespace nlid
