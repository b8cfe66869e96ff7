#pragma once
/// @file
/// Step and impulse responses (the toolbox's `step` and `impulse`): from rest for any model, and
/// about an operating point for the nonlinear models, whose response depends on where and how
/// far they are pushed.
///
///     y = step_response(model, 100);              // unit step on input 0 at t = 0, from rest
///     y = step_response(model, op, delta, 100);   // from the equilibrium op (nlid::equilibrium),
///                                                 // input op.u + delta from t = 0
///     h = impulse_response(linear, 100);          // the toolbox's impulse: pulse of area 1
///     g = impulse_response(linear, 100, 0, ImpulseScaling::unit_pulse);   // g(k), impulseest's
///
/// From rest: zero initial state and zero input before t = 0, u_j(t) = amplitude for t ≥ 0 —
/// for a linear model the toolbox's discrete step response (y(0) is the feed-through term; a
/// delay nk shows as nk leading zeros). A linear model's estimated output offset is not part of
/// its step or impulse response (the toolbox's responses show the dynamics G(q) alone), so it is
/// removed (also behind an AnyModel); a nonlinear model's output at rest is part of its
/// response and stays. About an
/// operating point: the model starts at the
/// equilibrium x̄ of ū = op.u and sees ū + δ from t = 0, so y(0) = ȳ (plus any feed-through of
/// δ) and the response settles at the equilibrium of ū + δ, if there is one; the result is the
/// output itself, not y − ȳ. Run through `Stepper`, so it is the batch simulation's numbers.
///
/// Impulse: only for linear models (a nonlinear model's response to a pulse of height 1/Ts
/// says little; use `step_response` about an operating point or `linearize`). The toolbox's
/// discrete `impulse` applies a pulse of area 1 — height 1/Ts for one sample — so it shows
/// g(k)/Ts, which tends to the continuous impulse response as Ts → 0; `unit_pulse` gives the
/// Markov parameters g(k) themselves (u(0) = 1), the coefficients `impulseest` estimates.

#include <cmath>
#include <concepts>
#include <span>
#include <string>
#include <type_traits>

#include <Eigen/Core>

#include "nlid/analysis/concepts.hpp"
#include "nlid/core/error.hpp"
#include "nlid/core/initial_condition.hpp"
#include "nlid/data/experiment.hpp"
#include "nlid/linear/concepts.hpp"
#include "nlid/models/equilibrium.hpp"
#include "nlid/models/stepper.hpp"

namespace nlid {

/// A model `step_response` can drive from rest: it simulates an experiment and says its channel
/// counts and sample time (0: none set).
template <class M>
concept StepResponseModel = SimulationModel<M> && requires(const M& m) {
  { m.num_inputs() } -> std::convertible_to<int>;
  { m.num_outputs() } -> std::convertible_to<int>;
  { m.ts() } -> std::convertible_to<double>;
};

namespace detail {
// A model that says whether what it holds is linear (AnyModel).
template <class M>
concept SaysIfLinear = requires(const M& m) {
  { m.is_linear() } -> std::convertible_to<bool>;
};

// True for the linear models, also behind an AnyModel.
template <class M>
bool is_linear_model(const M& m) {
  if constexpr (LinearModel<M>) {
    (void)m;
    return true;
  } else if constexpr (SaysIfLinear<M>) {
    return m.is_linear();
  } else {
    (void)m;
    return false;
  }
}

// Free run of `u` from rest; for a linear model less its run at zero input, which is the
// response to an estimated output offset alone (superposition). Where the run overflows (an
// unstable model) its inf stays, rather than inf − inf = NaN.
template <StepResponseModel M>
Eigen::MatrixXd response_from_rest(const M& model, const Eigen::MatrixXd& u, const char* name) {
  const double ts = model.ts() > 0.0 ? model.ts() : 1.0;
  const Eigen::MatrixXd no_y = Eigen::MatrixXd::Zero(u.rows(), model.num_outputs());
  Eigen::MatrixXd y = model.simulate(Experiment(u, no_y, ts, name), InitialCondition::zero);
  if (is_linear_model(model)) {
    const Eigen::MatrixXd rest =
        model.simulate(Experiment(Eigen::MatrixXd::Zero(u.rows(), u.cols()), no_y, ts, "rest"), InitialCondition::zero);
    for (Eigen::Index i = 0; i < y.size(); ++i)
      if (std::isfinite(rest.data()[i])) y.data()[i] -= rest.data()[i];
  }
  return y;
}

inline void check_sample_count(const char* who, Eigen::Index n) {
  require(n >= 1, std::string(who) + ": the number of samples must be >= 1, got " + std::to_string(n),
          at_parameter("n"));
}

template <class M>
void check_response_arguments(const char* who, const M& model, Eigen::Index n, int input) {
  check_sample_count(who, n);
  require(input >= 0 && input < model.num_inputs(),
          std::string(who) + ": input " + std::to_string(input) + " out of range, the model has " +
              std::to_string(model.num_inputs()) + " input(s)",
          at_parameter("input"));
}
}  // namespace detail

/// Response (n × n_y) to a step of height `amplitude` on input `input` at t = 0, from rest (see
/// the file comment). Throws `nlid::Error` naming "n", "input" or "amplitude" on a bad argument;
/// a model that cannot run at rest (no zero start) passes its own error through.
template <StepResponseModel M>
[[nodiscard]] Eigen::MatrixXd step_response(const M& model, Eigen::Index n, int input = 0, double amplitude = 1.0) {
  detail::check_response_arguments("step_response", model, n, input);
  require(std::isfinite(amplitude), "step_response: the step height must be finite", at_parameter("amplitude"));
  Eigen::MatrixXd u = Eigen::MatrixXd::Zero(n, model.num_inputs());
  u.col(input).setConstant(amplitude);
  return detail::response_from_rest(model, u, "step");
}

/// How `impulse_response` scales its pulse (see the file comment).
enum class ImpulseScaling {
  unit_area,   ///< u(0) = 1/Ts: the toolbox's `impulse`, g(k)/Ts
  unit_pulse,  ///< u(0) = 1: the Markov parameters g(k)
};

/// Response (n × n_y) of a linear model (also one held by an `AnyModel`) to a pulse on input
/// `input` at t = 0, from rest, scaled by `scaling` (default: the toolbox's `impulse`). Throws
/// `nlid::Error` naming "n" or "input", or "model" for an AnyModel that holds a nonlinear model.
template <StepResponseModel M>
  requires LinearModel<M> || detail::SaysIfLinear<M>
[[nodiscard]] Eigen::MatrixXd impulse_response(const M& model, Eigen::Index n, int input = 0,
                                               ImpulseScaling scaling = ImpulseScaling::unit_area) {
  require(detail::is_linear_model(model),
          "impulse_response: the model is not linear; use step_response about an operating point, or linearize",
          at_parameter("model"));
  detail::check_response_arguments("impulse_response", model, n, input);
  Eigen::MatrixXd u = Eigen::MatrixXd::Zero(n, model.num_inputs());
  u(0, input) = scaling == ImpulseScaling::unit_area ? 1.0 / model.ts() : 1.0;
  return detail::response_from_rest(model, u, "impulse");
}

namespace detail {
template <class S>
Eigen::MatrixXd step_from(S& run, const OperatingPoint& op, const Eigen::VectorXd& delta, Eigen::Index n,
                          int ny) {
  check_sample_count("step_response", n);
  require(delta.size() == op.u.size() && delta.allFinite(),
          "step_response: the step must have one finite value per input (" + std::to_string(op.u.size()) + "), got " +
              std::to_string(delta.size()),
          at_parameter("delta"));
  run.reset(op.x);
  const Eigen::VectorXd u = op.u + delta;
  const std::span<const double> us(u.data(), static_cast<std::size_t>(u.size()));
  Eigen::MatrixXd y(n, ny);
  for (Eigen::Index t = 0; t < n; ++t) {
    if constexpr (std::is_same_v<std::decay_t<decltype(run.step(us))>, double>) {
      y(t, 0) = run.step(us);
    } else {
      y.row(t) = run.step(us).transpose();
    }
  }
  return y;
}
}  // namespace detail

/// Response (n × 1) of a nonlinear ARX model started at the operating point `op` (its lag
/// window, `nlid::equilibrium(model, u)`) to the input op.u + `delta` from t = 0.
template <class R, class F>
[[nodiscard]] Eigen::MatrixXd step_response(const Nlarx<R, F>& model, const OperatingPoint& op,
                                            const Eigen::VectorXd& delta, Eigen::Index n) {
  Stepper run(model);
  return detail::step_from(run, op, delta, n, 1);
}

/// Response (n × 1) of a Hammerstein–Wiener model started at the operating point `op` (its
/// block's steady state) to the input op.u + `delta` from t = 0.
template <class In, class L, class Out>
[[nodiscard]] Eigen::MatrixXd step_response(const HammersteinWiener<In, L, Out>& model, const OperatingPoint& op,
                                            const Eigen::VectorXd& delta, Eigen::Index n) {
  Stepper run(model);
  return detail::step_from(run, op, delta, n, 1);
}

/// Response (n × n_y) of a grey-box model sampled at `ts`, started at the operating point `op`
/// (its physics' state), to the input op.u + `delta` from t = 0 (zero-order hold).
template <class P>
[[nodiscard]] Eigen::MatrixXd step_response(const GreyBox<P>& model, double ts, const OperatingPoint& op,
                                            const Eigen::VectorXd& delta, Eigen::Index n) {
  Stepper run(model, ts, op.x);
  return detail::step_from(run, op, delta, n, model.output_dimension());
}

}  // namespace nlid
