#pragma once
/// @file
/// Many parameter sets of one grey-box model at once: Monte-Carlo runs from an estimate's
/// uncertainty, sensitivity sweeps, robustness checks of a physics model before it goes on
/// hardware.
///
///     Eigen::MatrixXd thetas = ...;                      // n_p × K, column k = parameter set k
///     Eigen::MatrixXd y = nlid::simulate_batched<8>(model, data3.u(), data3.ts(), thetas, x0s);
///     // y: N × K, column k = the free run of parameter set k from x0s.col(k)
///
/// Why batched. One free run of an ODE is a chain of dependent RK4 stages: the core waits on
/// latency most cycles. W runs in the lanes of a `Batch<double, W, R>` (core/batch.hpp) advance
/// together, one vector instruction per operation for all lanes, on the widest vector registers
/// of the CPU (chosen at run time, also in a program built for baseline x86-64). The throttle
/// physics runs at 6.7× one trajectory at W = 8 and 10× at W = 16 (docs/performance.md).
///
/// Semantics. Lane k computes what `GreyBox::simulate(u, ts, x0s.col(k))` computes with the
/// parameters of column k, with two differences a Monte-Carlo user should know:
///   - sub-steps: a batch integrates with the *largest* sub-step count its lanes need by the
///     model's rule (`substeps_for` at each lane's parameters), so a lane whose own rule asks for
///     fewer sub-steps is integrated more finely than its single run (the same discrete model as
///     `simulate` when the counts agree; tested);
///   - rounding: the wide-register code may fuse multiply-adds, so lanes agree with single runs
///     to rounding (about 1e-12 relative), not bit for bit.
/// A run that diverges (a non-finite state or output) stops its batch: from that sample on the
/// whole batch's columns are NaN (the runs before it are kept). The physics must be written
/// without branches on values (nlid's `max`/`min`, `select`), as the catalogue's are; a branch
/// on a batched comparison does not compile (core/batch.hpp). Fixed-step methods only (RK4,
/// Euler): with Dormand–Prince each run would choose its own steps.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <limits>
#include <string>

#include <Eigen/Core>

#include "nlid/core/batch.hpp"
#include "nlid/core/error.hpp"
#include "nlid/models/greybox.hpp"
#include "nlid/models/greybox_concepts.hpp"
#include "nlid/models/greybox_simulate.hpp"
#include "nlid/models/integrators.hpp"

namespace nlid {

/// Free runs of K parameter sets of a grey-box model with static sizes on the input record `u`
/// (N × n_u) at sample time `ts`, W runs at a time (see the file comment). `thetas` is n_p × K
/// (the parameters in the model's order, `GreyBox::parameter_names()`); `x0s` is n_x × K, or
/// empty for every run from the zero state; `output` picks the output channel returned.
/// Returns N × K. `register_bytes` as in `with_register_bytes` (0: the CPU's widest).
/// Throws `nlid::Error` naming the argument for mismatched sizes, a non-positive sample time,
/// non-finite inputs or parameters, an output index out of range, or the adaptive method.
template <int W, StaticPhysics P>
  requires detail::EvaluatesPhysicsOn<P, Batch<double, W>>
Eigen::MatrixXd simulate_batched(const GreyBox<P>& model, const Eigen::MatrixXd& u, double ts,
                                 const Eigen::Ref<const Eigen::MatrixXd>& thetas,
                                 const Eigen::Ref<const Eigen::MatrixXd>& x0s = Eigen::MatrixXd(), int output = 0,
                                 std::size_t register_bytes = 0) {
  constexpr int NP = P::num_params, NX = P::num_states, NU = P::num_inputs, NY = P::num_outputs;
  const Eigen::Index k_runs = thetas.cols(), n = u.rows();
  require(u.cols() == NU, "input has " + std::to_string(u.cols()) + " column(s), the model takes " + std::to_string(NU),
          at_parameter("u"));
  require(thetas.rows() == NP,
          "thetas has " + std::to_string(thetas.rows()) + " rows, the model has " + std::to_string(NP) + " parameters",
          at_parameter("thetas"));
  require(x0s.cols() == 0 || (x0s.cols() == k_runs && x0s.rows() == NX),
          "x0s is " + std::to_string(x0s.rows()) + " x " + std::to_string(x0s.cols()) + ", expected " +
              std::to_string(NX) + " x " + std::to_string(k_runs) + " (states x parameter sets) or empty",
          at_parameter("x0s"));
  require(ts > 0.0 && std::isfinite(ts), "sample time must be positive and finite", at_parameter("ts"));
  require(output >= 0 && output < NY,
          "output " + std::to_string(output) + " out of range: the model has " + std::to_string(NY) + " output(s)",
          at_parameter("output"));
  require(u.allFinite(), "input contains non-finite samples; a simulation cannot run through them", at_parameter("u"));
  require(thetas.allFinite(), "thetas contains non-finite values", at_parameter("thetas"));
  require(x0s.allFinite(), "x0s contains non-finite values", at_parameter("x0s"));
  const IntegratorOptions& opt = model.integrator();
  require(opt.method != IntegratorMethod::dormand_prince,
          "batched runs need a fixed-step method (rk4 or euler): with dormand_prince every run would choose its own "
          "steps",
          at_parameter("integrator"));
  const P& phys = model.physics();
  Eigen::MatrixXd out(n, k_runs);
  // Sub-steps of each run by the model's rule, at its own parameters and initial state (for a
  // physics without spectral_radius, over its own trajectory: one double pass per run).
  const auto run_substeps = [&](Eigen::Index k) {
    const Eigen::Matrix<double, NP, 1> p = thetas.col(k);
    Eigen::Matrix<double, NX, 1> x = x0s.cols() > 0 ? Eigen::Matrix<double, NX, 1>(x0s.col(k))
                                                     : Eigen::Matrix<double, NX, 1>::Zero();
    return physics_substeps(phys, opt, p.data(), x.data(), u, ts);
  };
  with_register_bytes(
      [&]<std::size_t R>() {
        using B = Batch<double, W, R>;
        for (Eigen::Index k0 = 0; k0 < k_runs; k0 += W) {
          // A last incomplete batch repeats its first run in the spare lanes.
          const auto run_of = [&](int w) { return k0 + w < k_runs ? k0 + w : k0; };
          std::array<B, NP> p;
          std::array<B, NX> x;
          int sub = 1;
          for (int w = 0; w < W; ++w) {
            const Eigen::Index k = run_of(w);
            for (int j = 0; j < NP; ++j) p[static_cast<std::size_t>(j)][w] = thetas(j, k);
            for (int i = 0; i < NX; ++i) x[static_cast<std::size_t>(i)][w] = x0s.cols() > 0 ? x0s(i, k) : 0.0;
            if (k0 + w < k_runs) sub = std::max(sub, run_substeps(k));
          }
          const Eigen::Index got = simulate_physics<B>(phys, opt, sub, u, ts, p.data(), x.data(),
                                                       [&](Eigen::Index t, const B* y) {
                                                         for (int w = 0; w < W && k0 + w < k_runs; ++w)
                                                           out(t, k0 + w) = y[output][w];
                                                       });
          for (int w = 0; w < W && k0 + w < k_runs; ++w)
            out.col(k0 + w).tail(n - got).setConstant(std::numeric_limits<double>::quiet_NaN());
        }
      },
      register_bytes);
  return out;
}

}  // namespace nlid
