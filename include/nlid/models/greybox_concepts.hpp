#pragma once
/// @file
/// The `Physics` concept: how a user writes the physics of a grey-box model once, as a functor.
///
/// A grey-box model is a state-space model whose *structure* comes from physics and whose
/// *parameters* come from data (Ljung 1999, Sec. 4.5 "physically parametrized models", eq. 4.62;
/// Bohlin, "Practical Grey-box Process Identification", Springer 2006, ch. 2):
///
///     ẋ(t) = f(x(t), u(t), p),      y(t) = g(x(t), u(t), p),      x(t₀) = x₀,
///
/// with n_x states x, n_u inputs u, n_y outputs y and n_p named physical parameters p. The input
/// is known only at the samples and held constant in between (zero-order hold, the way a digital
/// controller or a logged command drives a plant).
///
/// The physics functor. A type P satisfies `Physics` if it provides
///
///     static constexpr int num_states, num_inputs, num_outputs, num_params;   // or nlid::Dynamic
///     ParamList parameter_info() const;     // std::array<ParameterInfo, num_params> (or vector)
///     template <class T> void derivative(const T* x, const T* u, const T* p, T* dx) const;  // f
///     template <class T> void output(const T* x, const T* u, const T* p, T* y) const;       // g
///
/// `derivative` and `output` are written once over a scalar T and are evaluated on `double`
/// (simulation), `float` (deployment) and `Dual<double, N>` (exact sensitivities for estimation).
/// Inside them call the nlid math functions unqualified or as `nlid::max`, `nlid::min`,
/// `nlid::sqrt` … (they handle all three scalar types) and write constants as `T(2.5)`.
/// Raw pointers rather than Eigen vectors keep the functor independent of storage: the same
/// code runs on stack arrays, Eigen fixed vectors and the chunked buffers of the runtime model.
///
/// Optional members (detected; each has a sensible default):
///
///     StateList state_info() const;                       // names/units of x (default x1, x2, …)
///     std::string name() const;                           // catalogue name (default "custom")
///     std::string equation() const;                       // for describe()
///     double spectral_radius(const double* p) const;      // bound on |eig ∂f/∂x|, drives sub-steps
///     void initialize(const Dataset&, std::span<ParameterInfo>) const;  // data-driven start
///     bool initial_state(const double* y0, const double* u0, const double* p, double* x0) const;
///     void check_parameters(const double* p) const;       // throws if the values contradict each other
///
/// `check_parameters` states what per-parameter bounds cannot: a relation between parameters
/// (the throttle's lower_stop < upper_stop). It throws `nlid::Error` naming the parameters and
/// their values; `GreyBox` calls it where a whole set of values is set or used (see its file
/// comment), and estimation rejects trial steps that violate it and checks its start and result
/// (greybox_estimate.hpp).
///
/// A physics with `Dynamic` sizes (the runtime models of greybox_dynamic.hpp) reports them through
/// `state_dimension()`, `input_dimension()`, `output_dimension()` and `num_parameters()`, and
/// need only evaluate on `double` and `Dual<double, 8>` (the chunk width used for dynamic sizes).
///
/// Parameter metadata (`ParameterInfo`) carries what a control engineer expects to see and set
/// per parameter: name, unit, meaning, default value, hard bounds, the typical range that
/// multi-start explores (log-spaced for positive scale parameters), and whether it is fixed.
/// Units may use the placeholders `{y}` and `{u}`, replaced by the data's output and input units
/// in `describe()`: catalogue models do not assume the units of any particular study.

#include <array>
#include <cmath>
#include <concepts>
#include <cstddef>
#include <limits>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "nlid/ad/dual.hpp"
#include "nlid/core/error.hpp"
#include "nlid/core/sizes.hpp"

namespace nlid {

/// Metadata and current setting of one physical parameter of a grey-box model.
/// Invariant (checked by GreyBox): lower ≤ value ≤ upper, range_lower ≤ range_upper.
struct ParameterInfo {
  std::string name;         ///< identifier, unique within a model (e.g. "c", "upper_stop")
  std::string unit;         ///< unit; "{y}" / "{u}" stand for the output / input unit
  std::string description;  ///< one line: what the parameter means physically
  double value = 0.0;       ///< default or current value
  double lower = -std::numeric_limits<double>::infinity();  ///< hard lower bound (physics)
  double upper = std::numeric_limits<double>::infinity();   ///< hard upper bound
  /// Typical range explored by multi-start; NaN means "use the bounds" (then they must be finite
  /// for the parameter to be sampled; otherwise it keeps its value in every start).
  double range_lower = std::numeric_limits<double>::quiet_NaN();
  double range_upper = std::numeric_limits<double>::quiet_NaN();  ///< see `range_lower`
  /// A positive scale parameter (stiffness, time constant, gain magnitude): multi-start spaces
  /// its starts logarithmically, so 1, 10, 100 are as likely as 10, 20, 30.
  bool log_scale = false;
  bool fixed = false;  ///< held at `value` during estimation
};

/// Name and unit of one state, for reports.
struct StateInfo {
  std::string name;         ///< e.g. "y", "v"
  std::string unit;         ///< may use "{y}" / "{u}" placeholders
  std::string description;  ///< one line
};

namespace detail {

/// A sized list of `ParameterInfo` (std::array for static physics, std::vector for runtime).
template <class L, class Info>
concept InfoList = requires(const L& l, std::size_t i) {
  { l.size() } -> std::convertible_to<std::size_t>;
  { l[i] } -> std::convertible_to<const Info&>;
};

/// The four static sizes exist and are positive (parameters may be 0) or Dynamic.
template <class P>
concept HasPhysicsSizes = requires {
  { P::num_states } -> std::convertible_to<int>;
  { P::num_inputs } -> std::convertible_to<int>;
  { P::num_outputs } -> std::convertible_to<int>;
  { P::num_params } -> std::convertible_to<int>;
} && (P::num_states == Dynamic || P::num_states >= 1) &&
    (P::num_inputs == Dynamic || P::num_inputs >= 0) &&
    (P::num_outputs == Dynamic || P::num_outputs >= 1) &&
    (P::num_params == Dynamic || P::num_params >= 0);

/// A physics with any Dynamic size must report its sizes at run time.
template <class P>
concept HasRuntimeSizes = requires(const P& p) {
  { p.state_dimension() } -> std::convertible_to<int>;
  { p.input_dimension() } -> std::convertible_to<int>;
  { p.output_dimension() } -> std::convertible_to<int>;
  { p.num_parameters() } -> std::convertible_to<int>;
};

/// f and g evaluate on scalar T through raw pointers.
template <class P, class T>
concept EvaluatesPhysicsOn = requires(const P& p, const T* x, const T* u, const T* th, T* out) {
  p.derivative(x, u, th, out);
  p.output(x, u, th, out);
};

}  // namespace detail

/// The scalar used for sensitivities of physics with runtime sizes: derivatives are seeded in
/// chunks of 8 parameters (one virtual call serves 8 Jacobian columns).
using RuntimeDual = Dual<double, 8>;

/// The physics of a grey-box model (see the file comment for the full contract).
/// Satisfied by the catalogue types `physics::Throttle`, `physics::MassSpringDamper`,
/// `physics::RigidBody`, `physics::FirstOrder`, `physics::TwoTank`, by the runtime handle
/// `AnyPhysics`, and by any user functor with the same members.
template <class P>
concept Physics =
    std::copy_constructible<P> && detail::HasPhysicsSizes<P> &&
    (!(P::num_states == Dynamic || P::num_inputs == Dynamic || P::num_outputs == Dynamic ||
       P::num_params == Dynamic) ||
     detail::HasRuntimeSizes<P>) &&
    detail::EvaluatesPhysicsOn<P, double> && detail::EvaluatesPhysicsOn<P, RuntimeDual> &&
    requires(const P& p) {
      { p.parameter_info() } -> detail::InfoList<ParameterInfo>;
    };

/// A physics whose sizes are all fixed at compile time: simulation and sensitivities then run on
/// stack-allocated fixed-size vectors and allocate nothing per sample.
/// Satisfied by the catalogue types and user functors with four static sizes.
template <class P>
concept StaticPhysics = Physics<P> && P::num_states != Dynamic && P::num_inputs != Dynamic &&
                        P::num_outputs != Dynamic && P::num_params != Dynamic;

namespace detail {

template <class P>
int physics_states(const P& p) {
  if constexpr (P::num_states != Dynamic) {
    (void)p;
    return P::num_states;
  } else {
    return p.state_dimension();
  }
}
template <class P>
int physics_inputs(const P& p) {
  if constexpr (P::num_inputs != Dynamic) {
    (void)p;
    return P::num_inputs;
  } else {
    return p.input_dimension();
  }
}
template <class P>
int physics_outputs(const P& p) {
  if constexpr (P::num_outputs != Dynamic) {
    (void)p;
    return P::num_outputs;
  } else {
    return p.output_dimension();
  }
}
template <class P>
int physics_params(const P& p) {
  if constexpr (P::num_params != Dynamic) {
    (void)p;
    return P::num_params;
  } else {
    return p.num_parameters();
  }
}

/// Replaces "{y}" and "{u}" in a unit string by the given units ("[y]"/"[u]" when unknown).
inline std::string substitute_units(std::string unit, std::string_view y_unit,
                                    std::string_view u_unit) {
  auto repl = [&unit](std::string_view key, std::string_view with) {
    std::size_t pos = 0;
    while ((pos = unit.find(key, pos)) != std::string::npos) {
      unit.replace(pos, key.size(), with);
      pos += with.size();
    }
  };
  const std::string yu = y_unit.empty() ? std::string("[y]") : std::string(y_unit);
  const std::string uu = u_unit.empty() ? std::string("[u]") : std::string(u_unit);
  repl("{y}", yu);
  repl("{u}", uu);
  return unit;
}

}  // namespace detail

}  // namespace nlid
