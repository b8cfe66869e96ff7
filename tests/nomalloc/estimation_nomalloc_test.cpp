// Proof that the estimation hot paths allocate nothing on the heap for a static parameter count:
// AutoDiffProblem::evaluate (residuals and Jacobian) and whole Levenberg–Marquardt solves
// (plain, bounded + fixed, Huber, and the QR fallback), with Eigen's heap switched off.
//
// EIGEN_RUNTIME_NO_MALLOC turns every Eigen heap allocation into an eigen_assert failure; that
// needs assertions enabled, so NDEBUG is undone here, and a canary (in a forked child) proves
// the trap is armed — otherwise these tests would pass vacuously in a Release build.
#undef NDEBUG
#include <catch2/catch.hpp>

#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <cstdio>
#include <limits>

#include "../estimation/test_problems.hpp"
#include "nlid/estimation.hpp"

#ifndef EIGEN_RUNTIME_NO_MALLOC
#error "tests/nomalloc must be compiled with EIGEN_RUNTIME_NO_MALLOC"
#endif

namespace {

// RAII: heap forbidden inside the scope.
struct NoHeap {
  NoHeap() { Eigen::internal::set_is_malloc_allowed(false); }
  ~NoHeap() { Eigen::internal::set_is_malloc_allowed(true); }
  NoHeap(const NoHeap&) = delete;
  NoHeap& operator=(const NoHeap&) = delete;
};

}  // namespace

TEST_CASE("canary: a forbidden Eigen allocation really aborts", "[nomalloc][estimation]") {
  const pid_t pid = fork();
  REQUIRE(pid >= 0);
  if (pid == 0) {
    // Default abort behaviour and no output in the child (Catch's own handler would report it).
    std::signal(SIGABRT, SIG_DFL);
    std::freopen("/dev/null", "w", stderr);
    std::freopen("/dev/null", "w", stdout);
    Eigen::internal::set_is_malloc_allowed(false);
    Eigen::VectorXd v(1000);  // must trip the assertion
    v.setZero();
    _exit(v.size() == 1000 ? 0 : 1);  // reached only if the trap is not armed
  }
  int status = 0;
  waitpid(pid, &status, 0);
  INFO("child status " << status);
  CHECK(WIFSIGNALED(status));
  CHECK(WTERMSIG(status) == SIGABRT);
}

TEST_CASE("AutoDiffProblem::evaluate allocates nothing for a static parameter count",
          "[nomalloc][estimation]") {
  nlid::AutoDiffProblem problem(nlid_test::ExpFit<3>(2.0, -1.3, 0.5, 200));
  const Eigen::Vector3d th(1.0, -0.5, 0.2);
  Eigen::VectorXd r(200);
  nlid::JacobianMatrix<3> J(200, 3);
  bool ok = false;
  {
    NoHeap guard;
    ok = problem.evaluate(th, r, &J) && problem.evaluate(th, r, nullptr);
  }
  CHECK(ok);
  CHECK(J(10, 0) == Approx(std::exp(-0.5 * problem.functor().t[10])));
}

TEST_CASE("Levenberg-Marquardt iterations allocate nothing (static P)", "[nomalloc][estimation]") {
  using P = nlid::AutoDiffProblem<nlid_test::ExpFit<3>>;
  P problem(nlid_test::ExpFit<3>(2.0, -1.3, 0.5, 200));
  int calls = 0;
  nlid::LmOptions o;
  o.callback = [&calls](const nlid::IterationReport&) { return ++calls > 0; };
  nlid::LevenbergMarquardt<P> lm(o);
  lm.setup(problem);  // every buffer is allocated here
  Eigen::Vector3d th(1.0, -0.5, 0.0);
  nlid::LmSummary s;
  {
    NoHeap guard;
    s = lm.solve(problem, th);
  }
  CHECK(s.converged());
  CHECK(s.iterations >= 4);
  CHECK(calls == s.iterations + 1);
  CHECK((th - Eigen::Vector3d(2.0, -1.3, 0.5)).cwiseAbs().maxCoeff() < 1e-9);
}

TEST_CASE("bounded, fixed and Huber solves allocate nothing (static P)", "[nomalloc][estimation]") {
  using P = nlid::AutoDiffProblem<nlid_test::ExpFit<3>>;
  P problem(nlid_test::ExpFit<3>(2.0, -1.3, 0.5, 200, /*outlier=*/30.0));
  nlid::LmOptions o;
  const double inf = std::numeric_limits<double>::infinity();
  o.upper_bounds = Eigen::Vector3d(1.8, inf, inf);
  o.fixed = {false, false, false};
  o.loss = nlid::RobustLoss::huber(0.1);
  nlid::LevenbergMarquardt<P> lm(o);
  lm.setup(problem);
  Eigen::Vector3d th(1.0, -0.5, 0.0);
  nlid::LmSummary s;
  {
    NoHeap guard;
    s = lm.solve(problem, th);
  }
  CHECK(s.converged());
  CHECK(th[0] == 1.8);
}

namespace {

// y = 3t + 2e-7 t², fitted as (a + b)t + c·b t²: with c = 1e-7 the two columns are nearly
// collinear (cond(J) ≈ 1e8, the LDLT path gives way to the QR fallback); with c = 1 they are not.
struct NearlyCollinear {
  static constexpr int m = 40;
  Eigen::VectorXd t{m}, y{m}, t2{m};
  NearlyCollinear() {
    for (int i = 0; i < m; ++i) {
      t[i] = 1.0 + static_cast<double>(i) / m;
      t2[i] = t[i] * t[i];
      y[i] = 3.0 * t[i] + 2e-7 * t2[i];
    }
  }
  auto problem(double c) const {
    return nlid::make_problem<2>(2, m, [this, c](const Eigen::Vector2d& th, Eigen::VectorXd& r,
                                                 nlid::JacobianMatrix<2>* J) {
      r = y - (th[0] + th[1]) * t - (c * th[1]) * t2;
      if (J) {
        J->col(0) = -t;
        J->col(1) = -t - c * t2;
      }
      return true;
    });
  }
};

}  // namespace

TEST_CASE("the QR fallback allocates nothing (static P)", "[nomalloc][estimation]") {
  const NearlyCollinear data;
  auto problem = data.problem(1e-7);
  nlid::LmOptions o;
  o.initial_lambda = 1e-20;
  nlid::LevenbergMarquardt<decltype(problem)> lm(o);
  lm.setup(problem);
  Eigen::Vector2d th(0.0, 0.0);
  nlid::LmSummary s;
  {
    NoHeap guard;
    s = lm.solve(problem, th);
  }
  CHECK(s.qr_fallbacks > 0);
  CHECK(s.final_cost < 1e-20);
}

TEST_CASE("regularized solves allocate nothing, with the normal equations or the QR fallback (static P)",
          "[nomalloc][estimation]") {
  const NearlyCollinear data;
  for (const double c : {1e-7, 1.0}) {
    auto problem = data.problem(c);
    nlid::LmOptions o;
    o.initial_lambda = 1e-20;
    o.regularization.lambda = 1e-12;
    o.regularization.weights = Eigen::Vector2d(0.0, 1.0);
    o.regularization.nominal = Eigen::Vector2d(0.0, 3.0);
    nlid::LevenbergMarquardt<decltype(problem)> lm(o);
    lm.setup(problem);
    Eigen::Vector2d th(0.0, 0.0);
    nlid::LmSummary s;
    {
      NoHeap guard;
      s = lm.solve(problem, th);
    }
    INFO("c = " << c << ": " << s.message());
    CHECK(s.accepted_steps > 0);
    CHECK((s.qr_fallbacks > 0) == (c < 1e-3));
  }
}
