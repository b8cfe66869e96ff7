// Proof that fixed-size model evaluation allocates nothing: Nlarx and Hammerstein-Wiener
// free-run simulation and one-step prediction on double and on Dual (the Jacobian pass), and a
// whole simulation-focus residual + Jacobian evaluation (one estimator iteration's model work).
// nlid-unity: separate (replaces the global operator new, which must be at global scope)
//
// Two traps are armed together: Eigen's EIGEN_RUNTIME_NO_MALLOC assertion (NDEBUG undone so it
// fires) and a counting replacement of the global operator new, which also sees std::vector,
// std::string and std::function allocations that Eigen's trap cannot.
#undef NDEBUG
#include <catch2/catch.hpp>

#include <atomic>
#include <cstdlib>
#include <limits>
#include <new>
#include <string>

#include "nlid/core/format.hpp"
#include "nlid/data/detail/csv_parse.hpp"
#include "nlid/models/estimate.hpp"
#include "nlid/models/greybox.hpp"
#include "nlid/models/greybox_dynamic.hpp"
#include "nlid/models/hammerstein_wiener.hpp"
#include "nlid/models/nlarx.hpp"
#include "nlid/models/physics/catalogue.hpp"
#include "nlid/models/series.hpp"
#include "nlid/models/stepper.hpp"
#include "nlid/nonlinearities/linear.hpp"
#include "nlid/nonlinearities/piecewise_linear.hpp"
#include "nlid/nonlinearities/polynomial.hpp"
#include "nlid/nonlinearities/sigmoid_network.hpp"
#include "nlid/regressors.hpp"
#include "nlid/regressors/expression.hpp"

#include "../support/block_models.hpp"

#ifndef EIGEN_RUNTIME_NO_MALLOC
#error "tests/nomalloc must be compiled with EIGEN_RUNTIME_NO_MALLOC"
#endif

// ---- counting global operator new (the only replacement in this executable) -------------------
namespace {
std::atomic<long> g_new_calls{0};
}  // namespace
[[gnu::noinline]] void* operator new(std::size_t n) {
  g_new_calls.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(n == 0 ? 1 : n)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) { return operator new(n); }
// new and delete are kept out of line: inlined, GCC 12 pairs malloc/free with the replaced
// operators at the call site and reports a mismatched allocation (-Wmismatched-new-delete).
[[gnu::noinline]] void operator delete(void* p) noexcept { std::free(p); }
[[gnu::noinline]] void operator delete[](void* p) noexcept { std::free(p); }
[[gnu::noinline]] void operator delete(void* p, std::size_t) noexcept { std::free(p); }
[[gnu::noinline]] void operator delete[](void* p, std::size_t) noexcept { std::free(p); }

namespace {
// RAII: Eigen's heap forbidden and operator new counted inside the scope.
class NoHeap {
 public:
  NoHeap() : start_(g_new_calls.load()) { Eigen::internal::set_is_malloc_allowed(false); }
  ~NoHeap() { Eigen::internal::set_is_malloc_allowed(true); }
  NoHeap(const NoHeap&) = delete;
  NoHeap& operator=(const NoHeap&) = delete;
  [[nodiscard]] long new_calls() const { return g_new_calls.load() - start_; }

 private:
  long start_;
};

Eigen::MatrixXd test_input(int n) {
  Eigen::MatrixXd u(n, 1);
  for (int t = 0; t < n; ++t) u(t, 0) = 0.5 + 0.4 * std::sin(0.05 * t) + (t / 30 % 2 ? 0.3 : 0.0);
  return u;
}

using Net = nlid::SigmoidNet<6, 5>;
using Nlarx5 = nlid::Nlarx<nlid::LaggedRegressors<3, 3, 0>, Net>;  // the study's nlarx5 structure

Nlarx5 make_nlarx5() {
  Net net;
  net.set_normalization(Eigen::VectorXd::Constant(6, 0.5), Eigen::VectorXd::Constant(6, 1.0));
  Nlarx5 m(nlid::LaggedRegressors<3, 3, 0>{}, net);
  Eigen::VectorXd th = Eigen::VectorXd::Constant(Nlarx5::num_params, 0.01);
  th.head(3) << 0.6, 0.1, 0.05;  // stable linear part
  m.set_parameters(th);
  return m;
}
}  // namespace

TEST_CASE("counting trap sees std allocations", "[nomalloc][models]") {
  NoHeap guard;
  // Kept in a volatile pointer: a compiler may elide a new/delete pair whose pointer never
  // escapes (clang does), and then this canary would see nothing.
  static std::vector<int>* volatile v = nullptr;
  v = new std::vector<int>(10);
  delete v;
  CHECK(guard.new_calls() == 2);
}

TEST_CASE("number text appended to a reserved buffer allocates nothing", "[nomalloc][models]") {
  // The CSV writers (write_csv, nlid-sim, nlid-input) write up to 17 significant digits per
  // number; as a returned std::string such a text is longer than the inline buffer, so
  // `text += format_g(v, 17)` cost one heap allocation per number.
  std::string text;
  text.reserve(4096);
  const double values[] = {1.0 / 3.0, -std::numeric_limits<double>::max(), 6.02214076e23, -0.0,
                           std::numeric_limits<double>::denorm_min(), 2.5};
  NoHeap guard;
  for (const double v : values) {
    nlid::detail::append_g(text, v, 17);
    text += ',';
    nlid::detail::append_double(text, v);
    text += '\n';
  }
  CHECK(guard.new_calls() == 0);
  CHECK(text.starts_with("0.33333333333333331,0.3333333333333333\n-1.7976931348623157e+308,"));
}

TEST_CASE("Nlarx [3 3 0] + sigmoidnet: simulate and predict allocate nothing", "[nomalloc][models]") {
  const Nlarx5 m = make_nlarx5();
  const Eigen::MatrixXd u = test_input(500);
  Eigen::VectorXd y(500), yp(497), x0 = Eigen::VectorXd::Constant(m.state_dimension(), 0.2);
  const Eigen::VectorXd& th = m.parameters();
  using D = nlid::Dual<double, Nlarx5::num_params>;
  Eigen::Matrix<D, Nlarx5::num_params, 1> thd;
  for (int i = 0; i < Nlarx5::num_params; ++i) thd(i) = D::variable(th(i), i);
  Eigen::Matrix<D, Eigen::Dynamic, 1> yd(500);
  const std::span<const D> thds(thd.data(), Nlarx5::num_params);
  bool ok = true;
  {
    NoHeap guard;
    ok = ok && m.simulate<double>(u, nlid::detail::as_const_span(th), {}, nlid::detail::as_span(y));
    ok = ok && m.simulate<double>(u, nlid::detail::as_const_span(th), nlid::detail::as_const_span(x0), nlid::detail::as_span(y));
    ok = ok && m.predict<double>(u, y, nlid::detail::as_const_span(th), nlid::detail::as_span(yp));
    ok = ok && m.simulate<D>(u, thds, {}, std::span<D>(yd.data(), 500));
    CHECK(guard.new_calls() == 0);
  }
  CHECK(ok);
  CHECK(yd(499).a == y(499));
}

TEST_CASE("Nlarx with the hard-spring custom regressor allocates nothing", "[nomalloc][models]") {
  auto spring = nlid::custom_regressor<nlid::OutputLag<1>>(
      "", [](auto y1) { return nlid::max(y1, 90.0) + nlid::min(y1, 15.0) - 105.0; });
  nlid::RegressorSet regs{nlid::LaggedRegressors<2, 1, 0>{}, spring};
  nlid::Nlarx m(regs, nlid::LinearMap<4>{});
  Eigen::VectorXd th(5);
  th << 1.2, -0.3, 2.0, -0.5, 1.5;
  m.set_parameters(th);
  const Eigen::MatrixXd u = test_input(400);
  Eigen::VectorXd y(400);
  NoHeap guard;
  CHECK(m.simulate<double>(u, nlid::detail::as_const_span(th), {}, nlid::detail::as_span(y)));
  CHECK(guard.new_calls() == 0);
}

TEST_CASE("Hammerstein-Wiener pwlinear/[3 3 0]/pwlinear allocates nothing", "[nomalloc][models]") {
  using Hw = nlid::HammersteinWiener<nlid::PwLinear<4>, nlid::TransferFunctionBlock<3, 3, 0>, nlid::PwLinear<4>>;
  Hw m;
  const Eigen::VectorXd th = nlid_test::pwlinear_hw_theta();
  m.set_parameters(th);
  const Eigen::MatrixXd u = test_input(500);
  Eigen::VectorXd y(500);
  using D = nlid::Dual<double, Hw::num_params>;
  Eigen::Matrix<D, Hw::num_params, 1> thd;
  for (int i = 0; i < Hw::num_params; ++i) thd(i) = D::variable(th(i), i);
  Eigen::Matrix<D, Eigen::Dynamic, 1> yd(500);
  bool ok = true;
  {
    NoHeap guard;
    ok = ok && m.simulate<double>(u, nlid::detail::as_const_span(th), {}, nlid::detail::as_span(y));
    ok = ok && m.simulate<D>(u, std::span<const D>(thd.data(), Hw::num_params), {}, std::span<D>(yd.data(), 500));
    CHECK(guard.new_calls() == 0);
  }
  CHECK(ok);
}

TEST_CASE("Steppers of fixed-size models allocate nothing per step or reset", "[nomalloc][models][stepper]") {
  // The real-time loop: step after step, a reset from a state, stepping on. Construction (which
  // copies the model) is outside the traps.
  const Nlarx5 m = make_nlarx5();
  using Hw = nlid::HammersteinWiener<nlid::PwLinear<4>, nlid::TransferFunctionBlock<3, 3, 2>, nlid::PwLinear<4>>;
  Hw hw;
  hw.set_parameters(nlid_test::pwlinear_hw_theta());
  nlid::GreyBox<nlid::physics::Throttle> gb;
  Eigen::VectorXd p(7);
  p << 30.0, 400.0, 1e5, 400.0 * 140.0, 15.0, 90.0, 0.0;
  gb.set_parameters(p);
  const Eigen::MatrixXd u = test_input(500);
  const Eigen::Matrix<double, 5, 1> x_nlarx = Eigen::Matrix<double, 5, 1>::Constant(0.4);
  const Eigen::Matrix<double, 4, 1> x_hw = Eigen::Matrix<double, 4, 1>::Constant(0.1);
  const Eigen::Vector2d x_gb(15.0, 0.0);
  using Wh = nlid::WienerHammerstein<nlid::TransferFunctionBlock<2, 2, 1>, nlid::Poly1d<3>,
                                     nlid::TransferFunctionBlock<2, 1, 0>>;
  Wh wh;
  wh.set_parameters(nlid_test::wiener_hammerstein_theta());
  const Eigen::Vector3d x_wh = Eigen::Vector3d::Constant(0.05);
  nlid::Stepper a(m);
  nlid::Stepper b(hw);
  nlid::Stepper c(gb, 0.01, x_gb);
  nlid::Stepper d(wh);
  double sum = 0.0;
  {
    NoHeap guard;
    for (Eigen::Index t = 0; t < u.rows(); ++t) {
      const double ut = u(t, 0);
      if (t == 250) {
        a.reset(x_nlarx);
        b.reset(x_hw);
        c.reset(x_gb);
        d.reset(x_wh);
      }
      sum += a.step(ut) + b.step(ut) + c.step(ut)[0] + a.step(std::span<const double>(&ut, 1)) + d.step(0.5 * ut);
    }
    CHECK(guard.new_calls() == 0);
  }
  CHECK(std::isfinite(sum));
  CHECK(a.samples() == 500);
}

TEST_CASE("Steppers of the Dynamic twins allocate nothing per step either", "[nomalloc][models][stepper]") {
  // Orders, units and physics chosen at run time (what a loaded model file is): the sizes are
  // set when the stepper is built, so stepping reuses its buffers.
  nlid::RegressorList list;
  list.add_output_lags(3).add_input_lags(3, 0, 0).add_custom("max(y1(t-1),90)+min(y1(t-1),15)-105");
  using DynNet = nlid::SigmoidNet<nlid::Dynamic, nlid::Dynamic>;
  nlid::Nlarx<nlid::RegressorList, DynNet> m(list, DynNet(7, 5));
  Eigen::VectorXd th = Eigen::VectorXd::Constant(m.num_parameters(), 0.01);
  th.head(3) << 0.5, 0.1, 0.05;
  m.set_parameters(th);
  using Pw = nlid::PwLinear<nlid::Dynamic>;
  using Tf = nlid::TransferFunctionBlock<nlid::Dynamic, nlid::Dynamic, nlid::Dynamic>;
  nlid::HammersteinWiener<Pw, Tf, Pw> hw(Pw(4), Tf(3, 3, 2), Pw(4));
  hw.set_parameters(nlid_test::pwlinear_hw_theta());
  const nlid::DynamicGreyBox gb(nlid::make_physics("throttle"));
  Eigen::VectorXd x0 = Eigen::VectorXd::Zero(gb.state_dimension());
  x0(0) = 15.0;
  nlid::Stepper a(m);
  nlid::Stepper b(hw);
  nlid::Stepper c(gb, 0.01, x0);
  const Eigen::MatrixXd u = test_input(300);
  double sum = 0.0;
  const Eigen::VectorXd xa = Eigen::VectorXd::Constant(m.state_dimension(), 0.2);
  const Eigen::VectorXd xb = Eigen::VectorXd::Constant(hw.state_dimension(), 0.1);
  {
    NoHeap guard;
    for (Eigen::Index t = 0; t < u.rows(); ++t) {
      if (t == 150) {
        a.reset(xa);
        b.reset(xb);
        c.reset(x0);
      }
      sum += a.step(u(t, 0)) + b.step(u(t, 0)) + c.step(u(t, 0))[0];
    }
    CHECK(guard.new_calls() == 0);
  }
  CHECK(std::isfinite(sum));
}

TEST_CASE("a simulation-focus residual + Jacobian evaluation allocates nothing", "[nomalloc][models]") {
  const Nlarx5 m = make_nlarx5();
  const Eigen::MatrixXd u = test_input(300);
  Eigen::VectorXd y(300);
  REQUIRE(m.simulate<double>(u, nlid::detail::as_const_span(m.parameters()), {}, nlid::detail::as_span(y)));
  std::vector<nlid::detail::EstimationSegment> segs(1);
  segs[0].u = &u;
  segs[0].y = y;
  using F = nlid::detail::SimulationResiduals<Nlarx5, Nlarx5::num_params>;
  nlid::AutoDiffProblem<F> problem(F(m, segs, {}, nlid::InitialCondition::zero, 1e6));
  const Nlarx5::Parameters theta = m.parameters();
  Eigen::VectorXd r(300);
  Eigen::Matrix<double, Eigen::Dynamic, Nlarx5::num_params> J(300, Nlarx5::num_params);
  bool ok = false;
  {
    NoHeap guard;
    ok = problem.evaluate(theta, r, &J);
    CHECK(guard.new_calls() == 0);
  }
  REQUIRE(ok);
  CHECK(r.cwiseAbs().maxCoeff() < 1e-12);  // the data are the model's own simulation
}

namespace {

// One experiment of the model's own noise-free output, started from the measured past as
// `estimate` does. `u` and `y` are viewed/copied by the segment: they must outlive it.
std::vector<nlid::detail::EstimationSegment> measured_segment(const Nlarx5& truth, const Eigen::MatrixXd& u, Eigen::VectorXd& y) {
  y.resize(u.rows());
  REQUIRE(truth.simulate<double>(u, nlid::detail::as_const_span(truth.parameters()), {}, nlid::detail::as_span(y)));
  std::vector<nlid::detail::EstimationSegment> segs(1);
  segs[0].u = &u;
  segs[0].y = y;
  segs[0].start = truth.history_length();
  segs[0].x0 = truth.measured_state(u, y, truth.history_length());
  return segs;
}

// Solves `problem` from `theta` (off the truth, so real steps are taken) with both heap traps
// armed, counting operator new between iterations: after set-up (workspace, per-thread
// scratch, which the caller has grown) no iteration may allocate, and the solve must converge.
template <class P, class Theta>
void check_iterations_allocate_nothing(const P& problem, Theta theta) {
  int iterations = 0;
  long news_in_iterations = 0;
  long last = -1;
  nlid::LmOptions o;
  o.max_iterations = 8;
  o.callback = [&](const nlid::IterationReport&) {
    const long now = g_new_calls.load();
    if (last >= 0) news_in_iterations += now - last;
    last = now;
    ++iterations;
    return true;
  };
  nlid::LevenbergMarquardt<P> lm(o);
  lm.setup(problem);
  nlid::LmSummary s;
  {
    NoHeap guard;
    s = lm.solve(problem, theta);
  }
  INFO(s.message());
  CHECK(iterations >= 3);
  CHECK(news_in_iterations == 0);
  CHECK(s.final_cost < 1e-3 * s.initial_cost);
}

Nlarx5::Parameters off_truth(const Nlarx5& truth) {
  Nlarx5::Parameters theta = truth.parameters();
  theta.head(3) += Eigen::Vector3d(0.02, -0.01, 0.01);
  return theta;
}

}  // namespace

// A whole simulation-focus Levenberg-Marquardt solve of the study's nlarx5 structure, started
// from the measured past as `estimate` does: after the set-up (workspace, per-thread scratch)
// every iteration — residuals, Jacobian through the recursion, step — runs without heap.
TEST_CASE("fixed-size simulation-focus estimation allocates nothing per iteration", "[nomalloc][models]") {
  const Nlarx5 truth = make_nlarx5();
  const Eigen::MatrixXd u = test_input(250);
  Eigen::VectorXd y;
  using F = nlid::detail::SimulationResiduals<Nlarx5, Nlarx5::num_params>;
  using P = nlid::AutoDiffProblem<F>;
  const P problem(F(truth, measured_segment(truth, u, y), {}, nlid::InitialCondition::measured, 1e6));
  const Nlarx5::Parameters theta = off_truth(truth);
  {
    Eigen::VectorXd r(problem.num_residuals());
    nlid::JacobianMatrix<Nlarx5::num_params> J(problem.num_residuals(), Nlarx5::num_params);
    // Grows the per-thread x0 scratch once per scalar type (Dual for the Jacobian pass, double
    // for the residual-only evaluations of trial steps): one-time setup, not per iteration.
    REQUIRE(problem.evaluate(theta, r, &J));
    REQUIRE(problem.evaluate(theta, r, nullptr));
  }
  check_iterations_allocate_nothing(problem, theta);
}

// The route estimate() takes for this structure: the structured simulation Jacobian
// (models/detail/nlarx_sensitivity.hpp) keeps its sensitivity ring, gradients and regressor
// duals on the stack, so its evaluations and a whole solve allocate nothing after set-up.
TEST_CASE("structured simulation Jacobian: evaluation and LM iterations allocate nothing", "[nomalloc][models]") {
  const Nlarx5 truth = make_nlarx5();
  const Eigen::MatrixXd u = test_input(250);
  Eigen::VectorXd y;
  using P = nlid::detail::NlarxSimulationProblem<Nlarx5, Nlarx5::num_params>;
  STATIC_REQUIRE(nlid::detail::HasStructuredSimulationJacobian<Nlarx5>);
  const P problem(truth, measured_segment(truth, u, y), {}, nlid::InitialCondition::measured, 1e6);
  const Nlarx5::Parameters theta = off_truth(truth);
  Eigen::VectorXd r(problem.num_residuals());
  nlid::JacobianMatrix<Nlarx5::num_params> J(problem.num_residuals(), Nlarx5::num_params);
  REQUIRE(problem.evaluate(theta, r, nullptr));  // grows the per-thread x0 scratch once
  {
    NoHeap guard;
    CHECK(problem.evaluate(theta, r, &J));
    CHECK(problem.evaluate(theta, r, nullptr));
    CHECK(guard.new_calls() == 0);
  }
  check_iterations_allocate_nothing(problem, theta);
}

// The route estimate() takes for the study's nlhw2 shape (static blocks, zero initial state):
// the structured Hammerstein-Wiener Jacobian (models/detail/hw_sensitivity.hpp) keeps its duals,
// breakpoint tables and block state on the stack.
TEST_CASE("structured Hammerstein-Wiener Jacobian: evaluation and LM iterations allocate nothing", "[nomalloc][models]") {
  using Hw = nlid::HammersteinWiener<nlid::PwLinear<4>, nlid::TransferFunctionBlock<3, 3, 0>, nlid::PwLinear<4>>;
  STATIC_REQUIRE(nlid::detail::HasStructuredHwJacobian<Hw>);
  Hw truth;
  Eigen::VectorXd th(Hw::num_params);
  th << -0.8, -0.5, -0.5, -0.5, -0.5, 0.0, 0.5, 0.8,  // input breakpoints and values
      0.2, 0.1, 0.05, -0.9, 0.2, -0.02,                // linear block
      -1.0, 0.0, 0.0, 0.0, -0.6, 0.0, 0.6, 0.9;        // output breakpoints and values
  truth.set_parameters(th);
  const Eigen::MatrixXd u = test_input(300);
  Eigen::VectorXd y(300);
  REQUIRE(truth.simulate<double>(u, nlid::detail::as_const_span(th), {}, nlid::detail::as_span(y)));
  std::vector<nlid::detail::EstimationSegment> segs(1);
  segs[0].u = &u;
  segs[0].y = y;
  using P = nlid::detail::HwSimulationProblem<Hw, Hw::num_params>;
  const P problem(truth, segs, nlid::InitialCondition::zero, 1e6);
  Hw::Parameters theta = th;
  theta.segment(8, 3) += Eigen::Vector3d(0.02, -0.01, 0.01);  // off the truth: real steps
  Eigen::VectorXd r(problem.num_residuals());
  nlid::JacobianMatrix<Hw::num_params> J(problem.num_residuals(), Hw::num_params);
  REQUIRE(problem.evaluate(theta, r, nullptr));  // grows the per-thread x0 scratch once
  {
    NoHeap guard;
    CHECK(problem.evaluate(theta, r, &J));
    CHECK(problem.evaluate(theta, r, nullptr));
    CHECK(guard.new_calls() == 0);
  }
  check_iterations_allocate_nothing(problem, theta);
}
