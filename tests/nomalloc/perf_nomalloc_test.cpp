// Performance-path proofs of "no heap allocation" (issue 5): batched simulation on
// Batch<double, W> (nlarx5 and the grey-box throttle), and per-iteration freedom from heap of a
// fixed-size simulation-focus Levenberg–Marquardt solve of the nlhw2 structure (pwlinear(10) →
// B/F [3 3 0] → pwlinear(10)). The Nlarx counterpart, with a counting operator new, is in
// models_nomalloc_test.cpp (this executable may hold only one operator new replacement, so these
// proofs arm Eigen's EIGEN_RUNTIME_NO_MALLOC trap, with NDEBUG undone so that it fires).
#undef NDEBUG
#include <catch2/catch.hpp>

#include <array>
#include <cmath>
#include <span>
#include <vector>

#include "nlid/core/batch.hpp"
#include "nlid/estimation/autodiff.hpp"
#include "nlid/estimation/levenberg_marquardt.hpp"
#include "nlid/models/estimate.hpp"
#include "nlid/models/greybox_simulate.hpp"
#include "nlid/models/hammerstein_wiener.hpp"
#include "nlid/models/nlarx.hpp"
#include "nlid/models/transfer_function_block.hpp"
#include "nlid/nonlinearities/piecewise_linear.hpp"
#include "nlid/nonlinearities/sigmoid_network.hpp"
#include "nlid/regressors/lagged.hpp"

#include "../support/study_throttle.hpp"

#ifndef EIGEN_RUNTIME_NO_MALLOC
#error "tests/nomalloc must be compiled with EIGEN_RUNTIME_NO_MALLOC"
#endif

namespace {

struct EigenHeapOff {
  EigenHeapOff() { Eigen::internal::set_is_malloc_allowed(false); }
  ~EigenHeapOff() { Eigen::internal::set_is_malloc_allowed(true); }
  EigenHeapOff(const EigenHeapOff&) = delete;
  EigenHeapOff& operator=(const EigenHeapOff&) = delete;
};

Eigen::MatrixXd input(int n) {
  Eigen::MatrixXd u(n, 1);
  for (int t = 0; t < n; ++t) u(t, 0) = (t / 40) % 2 == 0 ? 0.9 : 0.2;
  return u;
}

using nlid_test::StudyThrottle;  // tests/support/study_throttle.hpp

}  // namespace

TEST_CASE("batched nlarx5 simulation allocates nothing", "[nomalloc][batch]") {
  using B = nlid::Batch<double, 8>;
  nlid::Nlarx<nlid::LaggedRegressors<3, 3, 0>, nlid::SigmoidNet<6, 5>> m;
  constexpr int P = nlid::SigmoidNet<6, 5>::num_params;
  std::array<B, P> th;
  for (int i = 0; i < P; ++i)
    for (int w = 0; w < 8; ++w) th[static_cast<std::size_t>(i)][w] = (i < 3 ? 0.3 : 0.01) * (1.0 + 0.01 * w);
  const Eigen::MatrixXd u = input(400);
  std::vector<B> y(400);
  bool ok = false;
  {
    EigenHeapOff guard;
    ok = m.simulate(u, std::span<const B>(th), std::span<const B>(), std::span<B>(y));
  }
  REQUIRE(ok);
  CHECK(std::isfinite(static_cast<double>(y.back())));
}

TEST_CASE("batched nlarx5 simulation on the CPU's widest registers allocates nothing", "[nomalloc][batch]") {
  // The run-time dispatch of core/batch.hpp (AVX2/AVX-512 code in a baseline build) needs the
  // model to keep no Batch in Eigen's heap blocks, which are aligned for the build's registers
  // only: this is the proof for the fixed-size nlarx5 that simulate_batched relies on.
  nlid::Nlarx<nlid::LaggedRegressors<3, 3, 0>, nlid::SigmoidNet<6, 5>> m;
  constexpr int P = nlid::SigmoidNet<6, 5>::num_params;
  const Eigen::MatrixXd u = input(400);
  bool ok = false, finite = false;
  std::size_t used = 0;
  nlid::with_register_bytes([&]<std::size_t R>() {
    using B = nlid::Batch<double, 8, R>;
    std::array<B, P> th;
    for (int i = 0; i < P; ++i)
      for (int w = 0; w < 8; ++w) th[static_cast<std::size_t>(i)][w] = (i < 3 ? 0.3 : 0.01) * (1.0 + 0.01 * w);
    std::vector<B> y(400);
    {
      EigenHeapOff guard;
      ok = m.simulate(u, std::span<const B>(th), std::span<const B>(), std::span<B>(y));
    }
    finite = nlid::isfinite(y.back());
    used = R;
  });
  REQUIRE(ok);
  CHECK(finite);
  CHECK(used == nlid::cpu_register_bytes());
}

TEST_CASE("batched grey-box throttle simulation (RK4) allocates nothing", "[nomalloc][batch]") {
  using B = nlid::Batch<double, 4>;
  const Eigen::MatrixXd u = input(300);
  std::array<B, 4> p{B(20.0), B(100.0), B(1e4), B(9000.0)};
  for (int w = 0; w < 4; ++w) p[0][w] += w;
  B x[2] = {B(15.0), B(0.0)};
  B last;
  Eigen::Index n = 0;
  {
    EigenHeapOff guard;
    n = nlid::simulate_physics<B>(StudyThrottle{}, nlid::IntegratorOptions{}, 3, u, 0.01, p.data(), x,
                                  [&](Eigen::Index, const B* v) { last = v[0]; });
  }
  CHECK(n == 300);
  CHECK(nlid::isfinite(last));
}

TEST_CASE("fixed-size nlhw2 simulation-focus estimation allocates nothing per iteration", "[nomalloc][batch]") {
  using Hw = nlid::HammersteinWiener<nlid::PwLinear<10>, nlid::TransferFunctionBlock<3, 3, 0>, nlid::PwLinear<10>>;
  Hw truth;
  Eigen::VectorXd th(Hw::num_params);
  th(0) = -0.05;
  for (int k = 1; k < 10; ++k) th(k) = std::log(0.12);
  for (int k = 0; k < 10; ++k) th(10 + k) = (-0.05 + 0.12 * k) * (1.0 + 0.2 * k / 9.0);
  th.segment(20, 6) << 0.04, 0.03, 0.03, -1.2, 0.5, -0.06;  // poles inside the unit circle
  th(26) = -0.5;
  for (int k = 1; k < 10; ++k) th(26 + k) = std::log(0.25);
  for (int k = 0; k < 10; ++k) th(36 + k) = 15.0 + 7.0 * k + 0.5 * k * k;
  truth.set_parameters(th);
  const Eigen::MatrixXd u = input(300);
  Eigen::VectorXd y(300);
  REQUIRE(truth.simulate<double>(u, nlid::detail::as_const_span(truth.parameters()), {}, nlid::detail::as_span(y)));
  std::vector<nlid::detail::EstimationSegment> segs(1);
  segs[0].u = &u;
  segs[0].y = y;
  using F = nlid::detail::SimulationResiduals<Hw, Hw::num_params>;
  using Problem = nlid::AutoDiffProblem<F>;
  Problem problem(F(truth, segs, {}, nlid::InitialCondition::zero, 1e6));
  int iterations = 0;
  nlid::LmOptions o;
  o.max_iterations = 6;
  o.callback = [&](const nlid::IterationReport&) {
    ++iterations;
    return true;
  };
  nlid::LevenbergMarquardt<Problem> lm(o);
  lm.setup(problem);
  Hw::Parameters theta = truth.parameters();
  theta.segment(36, 10) *= 1.01;  // output values off the truth: real steps are taken
  {
    Eigen::VectorXd r(problem.num_residuals());
    nlid::JacobianMatrix<Hw::num_params> J(problem.num_residuals(), Hw::num_params);
    REQUIRE(problem.evaluate(theta, r, &J));  // grows the per-thread scratch once
  }
  nlid::LmSummary s;
  {
    EigenHeapOff guard;
    s = lm.solve(problem, theta);
  }
  INFO(s.message());
  CHECK(iterations >= 2);
  CHECK(s.final_cost < 1e-2 * s.initial_cost);
}
