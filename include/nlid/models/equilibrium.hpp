#pragma once
/// @file
/// Equilibria (operating points) of every model kind for a constant input, and the input that
/// holds a wanted output: the initial states of a simulation that starts "at rest", and the
/// points about which `linearize` (analysis/linearize.hpp) works.
///
/// An equilibrium for the constant input ū is a state x̄ that the model maps to itself
/// (Khalil, "Nonlinear Systems", 3rd ed., 2002, Sec. 1.2; for sampled models x̄ = Φ(x̄, ū)):
///
///     nonlinear ARX      ȳ = F(φ(ȳ, …, ȳ, ū, …, ū)),     x̄ = [ȳ … ȳ, ū … ū]     (lag window)
///     Hammerstein–Wiener w̄ = f(ū), x̄ = B(1)/F(1)·w̄,  s̄ = the block's steady state, ȳ = h(x̄)
///     grey box           f(x̄, ū, p) = 0,  ȳ = g(x̄, ū, p)
///
/// The models already start a simulation from the equilibrium of their *first input sample*
/// (`InitialCondition::equilibrium`); these helpers add what that cannot do: any ū, the output
/// at the equilibrium, and the inverse problem — the ū whose equilibrium output is a wanted ȳ
/// (e.g. "the throttle held at 45°"), solved by a safeguarded secant method on the scalar map
/// ū ↦ ȳ(ū) (single-input, single-output models).
///
/// The solvers are the models' own (Newton with backtracking, `Nlarx::equilibrium_output`,
/// `TransferFunctionBlock::equilibrium_state`, `physics_equilibrium`), so these helpers agree
/// with the models' simulation start exactly. Failures (no steady state: an oscillating or
/// integrating model, F(1) = 0) throw `nlid::Error` saying which input was held.

#include <cmath>
#include <limits>
#include <span>
#include <string>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/models/detail/model_common.hpp"
#include "nlid/models/greybox.hpp"
#include "nlid/models/hammerstein_wiener.hpp"
#include "nlid/models/nlarx.hpp"

namespace nlid {

/// An operating point: state, input and output of a model held at rest.
struct OperatingPoint {
  Eigen::VectorXd x;  ///< state (the model's x0 layout)
  Eigen::VectorXd u;  ///< input, one value per channel
  Eigen::VectorXd y;  ///< output at (x, u)
};

/// Equilibrium of a nonlinear ARX model for the constant input `u0` (one value per input
/// channel); `y_guess` starts Newton's method (NaN: 0). State layout: `Nlarx::state_dimension`.
template <class R, class F>
OperatingPoint equilibrium(const Nlarx<R, F>& model, const Eigen::VectorXd& u0,
                           double y_guess = std::numeric_limits<double>::quiet_NaN()) {
  require(u0.size() == model.num_inputs(),
          "equilibrium: the model reads " + std::to_string(model.num_inputs()) + " input(s), got " +
              std::to_string(u0.size()) + " value(s)",
          at_parameter("u0"));
  require(u0.allFinite(), "equilibrium: the held input must be finite", at_parameter("u0"));
  const Eigen::RowVectorXd ur = u0.transpose();
  const double y = model.equilibrium_output(ur, detail::as_const_span(model.parameters()),
                                            std::isfinite(y_guess) ? y_guess : 0.0);
  OperatingPoint op;
  op.x = model.template held_state<double>(y, ur);
  op.u = u0;
  op.y = Eigen::VectorXd::Constant(1, y);
  return op;
}

/// Equilibrium of a Hammerstein–Wiener model for the constant input `u0` (one value). Throws if
/// the linear block has no steady state (F(1) = 0, an integrator).
template <class In, class L, class Out>
OperatingPoint equilibrium(const HammersteinWiener<In, L, Out>& model, const Eigen::VectorXd& u0) {
  require(u0.size() == 1, "equilibrium: a Hammerstein-Wiener model has one input, got " + std::to_string(u0.size()),
          at_parameter("u0"));
  require(std::isfinite(u0(0)), "equilibrium: the held input must be finite", at_parameter("u0"));
  const auto th = detail::as_const_span(model.parameters());
  // F(1) = 1 + Σ f_i: zero means an integrating block with no steady state.
  const auto thl = model.linear_parameters();
  const auto& lin = model.linear_block();
  const auto [bpoly, fpoly] = lin.polynomials(thl);
  require(std::abs(fpoly.sum()) > 1e-12,
          "equilibrium: the linear block integrates (F(1) = 0), so no input holds it at rest",
          at_parameter("u0"));
  OperatingPoint op;
  op.x = model.template equilibrium_state<double>(u0(0), th);
  op.u = u0;
  Eigen::VectorXd y(1);
  const Eigen::MatrixXd u1 = Eigen::MatrixXd::Constant(1, 1, u0(0));
  require(model.template simulate<double>(u1, th, detail::as_const_span(op.x), detail::as_span(y)),
          "equilibrium: the output nonlinearity is not finite at the steady state", at_parameter("u0"));
  op.y = y;
  return op;
}

/// Equilibrium of a grey-box model for the constant input `u0` (n_u values): f(x̄, ū, p) = 0,
/// Newton from `x_guess` (empty: the zero state; with several equilibria, the guess picks one).
/// Throws (from `GreyBox::equilibrium`) if Newton's method finds none.
template <class P>
OperatingPoint equilibrium(const GreyBox<P>& model, const Eigen::VectorXd& u0,
                           const Eigen::VectorXd& x_guess = {}) {
  require(u0.size() == model.input_dimension(),
          "equilibrium: the model takes " + std::to_string(model.input_dimension()) + " input(s), got " +
              std::to_string(u0.size()),
          at_parameter("u0"));
  require(u0.allFinite(), "equilibrium: the held input must be finite", at_parameter("u0"));
  OperatingPoint op;
  op.x = x_guess.size() == 0 ? model.equilibrium(u0) : model.equilibrium(u0, x_guess);
  op.u = u0;
  const auto p = model.parameters();
  op.y.resize(model.output_dimension());
  model.physics().output(op.x.data(), op.u.data(), p.data(), op.y.data());
  return op;
}

/// The constant input (single-input, single-output models) whose equilibrium output is
/// `y_target`, by a secant method from `u_guess` and `u_guess + du` with step halving when the
/// residual grows (steady-state maps with saturations are monotone but kinked). Throws
/// `nlid::Error` if no input within 60 iterations reaches |ȳ − y_target| ≤ tol·(1 + |y_target|).
template <class M>
OperatingPoint equilibrium_for_output(const M& model, double y_target, double u_guess, double du = 0.1,
                                      double tol = 1e-9) {
  require(std::isfinite(y_target) && std::isfinite(u_guess) && du != 0.0 && std::isfinite(du),
          "equilibrium_for_output: target, guess and step must be finite (step non-zero)", at_parameter("y_target"));
  // One input to search for: with several, the equilibrium's own count check would blame a
  // vector the caller never passed.
  int inputs = 1;
  if constexpr (requires { model.num_inputs(); }) inputs = static_cast<int>(model.num_inputs());
  else if constexpr (requires { model.input_dimension(); }) inputs = static_cast<int>(model.input_dimension());
  require(inputs == 1,
          "equilibrium_for_output: the model reads " + std::to_string(inputs) +
              " inputs; this search varies one input (use equilibrium(model, u0) with every input given)",
          at_parameter("model"));
  auto g = [&](double u, OperatingPoint& op) {
    op = equilibrium(model, Eigen::VectorXd::Constant(1, u));
    require(op.y.size() >= 1, "equilibrium_for_output: the model has no output", at_parameter("model"));
    return op.y(0) - y_target;
  };
  OperatingPoint op0, op1;
  double u0 = u_guess, u1 = u_guess + du;
  double g0 = g(u0, op0), g1 = g(u1, op1);
  const double eps = tol * (1.0 + std::abs(y_target));
  for (int it = 0; it < 60; ++it) {
    if (std::abs(g1) <= eps) return op1;
    if (std::abs(g0) <= eps) return op0;
    const double slope = (g1 - g0) / (u1 - u0);
    if (!(std::abs(slope) > 0.0) || !std::isfinite(slope)) break;
    double step = -g1 / slope;
    OperatingPoint op2;
    double u2 = u1 + step, g2 = g(u2, op2);
    // Halve a step that makes things worse (a kink of a saturating steady-state map).
    for (int h = 0; h < 30 && !(std::abs(g2) < std::abs(g1)); ++h) {
      step *= 0.5;
      u2 = u1 + step;
      g2 = g(u2, op2);
    }
    if (!(std::abs(g2) < std::abs(g1))) break;
    u0 = u1; g0 = g1; op0 = op1;
    u1 = u2; g1 = g2; op1 = op2;
  }
  throw Error("equilibrium_for_output: no constant input found whose steady output is " + detail::format_g(y_target) +
                  " (closest: " + detail::format_g(y_target + g1) + " at u = " + detail::format_g(u1) +
                  "); the target may lie outside the model's steady-state range",
              at_parameter("y_target"));
}

}  // namespace nlid
