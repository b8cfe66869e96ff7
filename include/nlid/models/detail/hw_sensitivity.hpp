#pragma once
/// @file
/// Structured Jacobian of a Hammerstein–Wiener model's free-run simulation errors.
///
/// Forward AD through the whole chain (`AutoDiffProblem<SimulationResiduals>`) carries all
/// p = p_f + p_L + p_h derivatives through every operation of all three blocks. The chain
/// ŷ(t) = h(x(t); θ_h), x = L(θ_L) w, w(t) = f(u(t); θ_f) has less coupling than that:
///
///     ∂ŷ/∂(θ_f, θ_L) = h'(x(t)) · ∂x(t)/∂(θ_f, θ_L),     ∂ŷ/∂θ_h = ∂h/∂θ_h (x(t)),
///
/// and x(t) does not depend on θ_h at all. So one pass carries p_f + p_L derivatives through
/// the input map and the linear block (duals of that width), and the output map is evaluated on
/// a dual of width p_h + 1 (its own parameters and its input x). For the study's nlhw2 (10-point
/// piecewise-linear maps, B/F [3 3 0]) that is 26 and 21 lanes instead of 46 everywhere.
///
/// The residual values are those of `SimulationResiduals` (the problem holds one; the
/// residual-only path is its `residuals`), and the Jacobian equals the forward-AD one to
/// rounding (tests/models/sensitivity_test.cpp). Initial conditions: zero or a fixed x0 of the
/// linear block; estimated or equilibrium initial states take the forward-AD route. With static
/// sizes every buffer is on the stack: a fixed-size evaluation allocates nothing (tests/nomalloc).

#include <algorithm>
#include <array>
#include <cmath>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "nlid/ad/dual.hpp"
#include "nlid/core/error.hpp"
#include "nlid/core/initial_condition.hpp"
#include "nlid/core/sizes.hpp"
#include "nlid/models/detail/estimation_segment.hpp"
#include "nlid/models/detail/model_common.hpp"
#include "nlid/models/detail/simulation_residuals.hpp"
#include "nlid/nonlinearities/detail/bound_map.hpp"

namespace nlid::detail {

/// A Hammerstein–Wiener type whose simulation Jacobian `HwSimulationProblem` can build: every
/// block with a compile-time parameter count and a compile-time state count (the dual widths
/// and the stack buffers).
template <class M>
concept HasStructuredHwJacobian = requires {
  typename M::InputMap;
  typename M::Linear;
  typename M::OutputMap;
} && M::InputMap::num_params != Dynamic && M::Linear::num_params != Dynamic &&
    M::OutputMap::num_params != Dynamic && M::Linear::num_states != Dynamic;

/// Free-run residuals of a Hammerstein–Wiener model with the structured Jacobian (file
/// comment): a `LeastSquaresProblem` with the θ layout of the model (no estimated states).
template <class M, int P>
  requires HasStructuredHwJacobian<M>
class HwSimulationProblem {
 public:
  /// Static parameter count (the model's).
  static constexpr int num_params = P;

  HwSimulationProblem(const M& model, std::vector<EstimationSegment> segments, InitialCondition ic, double limit)
      : res_(model, std::move(segments), {}, ic, limit) {
    require(ic == InitialCondition::zero || ic == InitialCondition::measured,
            "the structured Hammerstein-Wiener Jacobian supports zero and given initial states",
            at_parameter("initial_condition"));
  }

  /// The model's parameters.
  [[nodiscard]] int num_parameters() const { return res_.num_parameters(); }
  /// Σ over experiments of the simulated samples.
  [[nodiscard]] Eigen::Index num_residuals() const { return res_.num_residuals(); }

  /// r = ŷ_s − y stacked, and with `J` the m × n Jacobian; false if a simulation diverges.
  bool evaluate(const Eigen::Matrix<double, P, 1>& theta, Eigen::VectorXd& r,
                Eigen::Matrix<double, Eigen::Dynamic, P>* J) const {
    const std::span<const double> th(theta.data(), static_cast<std::size_t>(theta.size()));
    if (!J) return res_.residuals(th, std::span<double>(r.data(), static_cast<std::size_t>(r.size())));
    return res_.stacked_with_sensitivity(th, r, [&](const EstimationSegment& s, std::span<const double> x0, Eigen::Index off) {
      return simulate_with_sensitivity(s, th, x0, r, off, *J);
    });
  }

 private:
  using In = typename M::InputMap;
  using L = typename M::Linear;
  using Out = typename M::OutputMap;
  static constexpr int kPf = In::num_params, kPl = L::num_params, kPh = Out::num_params;
  static constexpr int kW1 = kPf + kPl > 0 ? kPf + kPl : 1;  // input map + linear block
  static constexpr int kW2 = kPh + 1;                        // output map + its input
  static constexpr int kNx = L::num_states > 0 ? L::num_states : 1;
  using D1 = Dual<double, kW1>;
  using D2 = Dual<double, kW2>;

  bool simulate_with_sensitivity(const EstimationSegment& s, std::span<const double> th,
                                 std::span<const double> x0, Eigen::VectorXd& r, Eigen::Index off,
                                 Eigen::Matrix<double, Eigen::Dynamic, P>& J) const {
    const M& model = res_.model();
    const int nx = model.state_dimension();
    const Eigen::Index len = s.y.size() - s.start;
    const auto u = s.u->bottomRows(len);

    // θ_f and θ_L seeded as lanes 0 … p_f + p_L − 1 of D1; θ_h as lanes 0 … p_h − 1 of D2.
    std::array<D1, (kPf > 0 ? kPf : 1)> thf{};
    std::array<D1, (kPl > 0 ? kPl : 1)> thl{};
    std::array<D2, (kPh > 0 ? kPh : 1)> thh{};
    for (int k = 0; k < kPf; ++k) thf[static_cast<std::size_t>(k)] = D1::variable(th[static_cast<std::size_t>(k)], k);
    for (int k = 0; k < kPl; ++k)
      thl[static_cast<std::size_t>(k)] = D1::variable(th[static_cast<std::size_t>(kPf + k)], kPf + k);
    for (int k = 0; k < kPh; ++k)
      thh[static_cast<std::size_t>(k)] = D2::variable(th[static_cast<std::size_t>(kPf + kPl + k)], k);
    const BoundScalarMap<In, D1> f(model.input_nonlinearity(), std::span<const D1>(thf.data(), kPf));
    const BoundScalarMap<Out, D2> h(model.output_nonlinearity(), std::span<const D2>(thh.data(), kPh));
    const std::span<const D1> thl_span(thl.data(), kPl);

    std::array<D1, kNx> state{};
    for (int i = 0; i < nx; ++i) state[static_cast<std::size_t>(i)] = D1(x0.empty() ? 0.0 : x0[static_cast<std::size_t>(i)]);
    const std::span<D1> ss(state.data(), static_cast<std::size_t>(nx));
    const L& lin = model.linear_block();
    for (Eigen::Index t = 0; t < len; ++t) {
      const D1 w = f(D1(u(t, 0)));
      const D1 x = lin.step(ss, w, thl_span);
      const D2 yt = h(D2::variable(x.a, kPh));
      if (!std::isfinite(yt.a) || std::abs(yt.a) > res_.limit()) return false;
      r(off + t) = yt.a;
      const double dh_dx = yt.v[kPh];
      for (int c = 0; c < kPf + kPl; ++c) J(off + t, c) = dh_dx * x.v[c];
      for (int c = 0; c < kPh; ++c) J(off + t, kPf + kPl + c) = yt.v[c];
    }
    return true;
  }

  SimulationResiduals<M, P> res_;  // residuals and initial states, shared with forward AD
};

}  // namespace nlid::detail
