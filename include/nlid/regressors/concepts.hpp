#pragma once
/// @file
/// Concepts of the regressor layer: what a lag window offers and what a regressor must provide.
///
/// A nonlinear ARX model (Ljung 1999, sec. 5.2, eq. 5.46; Sjöberg et al. 1995, sec. 4) predicts
///
///     ŷ(t) = F(φ(t)),   φ(t) = [φ₁(t) … φ_m(t)]ᵀ,
///
/// where every regressor φᵢ(t) is a function of the past outputs y(t−1), y(t−2), … and of the
/// current and past inputs u_c(t), u_c(t−1), …  The *lag window* at time t is exactly that
/// information: `w.y(k)` = y(t−k) for k ≥ 1 and `w.u(c, k)` = u_c(t−k) for k ≥ 0. In one-step
/// prediction the window reads measured outputs; in free-run simulation it reads the model's own
/// past outputs from a ring buffer. A regressor never knows which: that is what lets one model
/// definition serve both prediction focus and simulation focus.
///
/// The window is templated on the scalar `T` (double, float or `Dual`): a regressor is evaluated
/// on duals when the Jacobian of a simulation is propagated through the recursion, so every
/// regressor must be generic over the scalar.
///
/// Notation used throughout: outputs are single-channel (MISO models, as in the toolbox's
/// one-output nonlinear ARX); inputs are numbered c = 0 … nu−1 in code and named "u1" … in text.

#include <concepts>
#include <span>
#include <string>
#include <vector>

#include "nlid/ad/dual.hpp"
#include "nlid/core/sizes.hpp"

namespace nlid {

namespace detail {
/// A minimal window, used only to check concepts (never defined, never instantiated).
template <class T>
struct LagWindowArchetype {
  using Scalar = T;
  T y(int lag) const;
  T u(int channel, int lag) const;
};
/// A dual type used to prove that regressors are generic over the scalar.
using ArchetypeDual = Dual<double, 2>;
}  // namespace detail

/// The samples visible at time t: `y(k)` = y(t−k) for k ≥ 1, `u(c, k)` = u_c(t−k) for k ≥ 0.
/// Satisfied by `MeasuredWindow<T>` (prediction) and `SimulationWindow<T, L>` (free run).
template <class W>
concept LagWindow = requires(const W& w, int lag, int channel) {
  typename W::Scalar;
  { w.y(lag) } -> std::convertible_to<typename W::Scalar>;
  { w.u(channel, lag) } -> std::convertible_to<typename W::Scalar>;
};

/// A block of regressors: sizes known at compile time where possible, evaluated on any scalar.
///
/// Static members: `num_regressors` (count, or `Dynamic`), `max_output_lag` and `max_input_lag`
/// (the history the block needs, or `Dynamic`). Run-time twins: `size()`, `output_lag()`,
/// `input_lag()`; `num_input_channels()` is 1 + the highest input channel read (0 if none).
/// `evaluate(w, out)` writes `size()` values; `names(input_names, output_name)` returns one
/// printable name per regressor (the toolbox's getreg).
///
/// Satisfied by `OutputLags`, `InputLags`, `LaggedRegressors`, `CustomRegressor` and
/// `RegressorSet` (so sets nest).
template <class R>
concept Regressor =
    requires {
      { R::num_regressors } -> std::convertible_to<int>;
      { R::max_output_lag } -> std::convertible_to<int>;
      { R::max_input_lag } -> std::convertible_to<int>;
    } &&
    requires(const R& r, std::span<double> out, std::span<detail::ArchetypeDual> out_dual,
             const detail::LagWindowArchetype<double>& w,
             const detail::LagWindowArchetype<detail::ArchetypeDual>& w_dual,
             const std::vector<std::string>& input_names, const std::string& output_name) {
      { r.size() } -> std::same_as<int>;
      { r.output_lag() } -> std::same_as<int>;
      { r.input_lag() } -> std::same_as<int>;
      { r.num_input_channels() } -> std::same_as<int>;
      r.evaluate(w, out);
      r.evaluate(w_dual, out_dual);
      { r.names(input_names, output_name) } -> std::same_as<std::vector<std::string>>;
    };

/// Default channel names of the toolbox: "u1", "u2", … for inputs and "y1" for the output.
inline std::vector<std::string> default_input_names(int num_inputs) {
  std::vector<std::string> n;
  for (int c = 0; c < num_inputs; ++c) n.push_back("u" + std::to_string(c + 1));
  return n;
}

/// The printable names of a regressor block with the default channel names ("y1", "u1", …).
template <Regressor R>
std::vector<std::string> regressor_names(const R& r) {
  return r.names(default_input_names(r.num_input_channels()), "y1");
}

namespace detail {
/// Largest of static sizes; `Dynamic` if any is dynamic. A lag of 0 means "no history".
template <class... Ints>
constexpr int size_max(Ints... n) {
  const bool dyn = ((n == Dynamic) || ...);
  int m = 0;
  ((m = n > m ? n : m), ...);
  return dyn ? Dynamic : m;
}

/// "y1(t-2)", "u1(t)": the toolbox's spelling of one lagged signal.
inline std::string lag_name(const std::string& signal, int lag) {
  return lag == 0 ? signal + "(t)" : signal + "(t-" + std::to_string(lag) + ")";
}

/// Name of input channel c, falling back to "u<c+1>" when the caller gave fewer names.
inline std::string input_name(const std::vector<std::string>& names, int channel) {
  if (channel < static_cast<int>(names.size()) && !names[channel].empty()) return names[channel];
  return "u" + std::to_string(channel + 1);
}
}  // namespace detail

}  // namespace nlid
