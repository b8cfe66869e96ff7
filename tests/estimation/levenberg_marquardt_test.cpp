// Levenberg–Marquardt: known minima (Rosenbrock, exponential fit), bounds with KKT signs, fixed
// parameters, Huber loss against outliers, callback trace and abort, failure handling, the QR
// fallback on an ill-conditioned problem, and validation errors that name the option.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include <Eigen/QR>

#include "nlid/estimation.hpp"
#include "test_problems.hpp"

using Catch::Matchers::Contains;
using nlid::AutoDiffProblem;
using nlid::LmOptions;
using nlid::LmStatus;

namespace {

// ∂F/∂θ of F = ½‖r‖² at θ, from the problem's own Jacobian.
template <class P>
Eigen::VectorXd gradient(const P& p, const typename P::Parameters& th) {
  Eigen::VectorXd r(p.num_residuals());
  typename P::Jacobian J(p.num_residuals(), p.num_parameters());
  REQUIRE(p.evaluate(th, r, &J));
  return J.transpose() * r;
}

}  // namespace

TEST_CASE("Rosenbrock, static parameter count: minimum (1, 1) to 1e-8", "[estimation][lm]") {
  AutoDiffProblem problem(nlid_test::Rosenbrock<2>{});
  Eigen::Vector2d x(-1.2, 1.0);
  const auto s = nlid::solve_least_squares(problem, x);
  INFO(s.message());
  CHECK(s.converged());
  CHECK(std::abs(x[0] - 1.0) < 1e-8);
  CHECK(std::abs(x[1] - 1.0) < 1e-8);
  CHECK(s.final_cost < 1e-20);
  CHECK(s.initial_cost == Approx(0.5 * (4.4 * 4.4 + 2.2 * 2.2)));
  CHECK(s.iterations > 3);  // a real nonlinear solve, not a lucky first step
  CHECK(s.jacobian_evaluations == s.accepted_steps + 1);
  CHECK(s.residual_evaluations == s.iterations + s.jacobian_evaluations);
  CHECK(s.seconds >= 0);
}

TEST_CASE("Rosenbrock, dynamic parameter count and without Jacobian scaling", "[estimation][lm]") {
  AutoDiffProblem problem(nlid_test::Rosenbrock<nlid::Dynamic>{});
  Eigen::VectorXd x(2);
  x << -1.2, 1.0;
  const auto s = nlid::solve_least_squares(problem, x);
  INFO(s.message());
  CHECK(s.converged());
  CHECK((x - Eigen::Vector2d(1, 1)).cwiseAbs().maxCoeff() < 1e-8);

  LmOptions o;
  o.scaling = nlid::LmScaling::levenberg;
  Eigen::VectorXd x2(2);
  x2 << -1.2, 1.0;
  const auto s2 = nlid::solve_least_squares(problem, x2, o);
  INFO(s2.message());
  CHECK(s2.converged());
  CHECK((x2 - Eigen::Vector2d(1, 1)).cwiseAbs().maxCoeff() < 1e-8);

  // Extended Rosenbrock, n = 10: the chunked Dual path (chunks of 8 + 2) inside a real solve.
  AutoDiffProblem ext(nlid_test::ExtendedRosenbrock{});
  Eigen::VectorXd z(10);
  for (int i = 0; i < 10; ++i) z[i] = i % 2 == 0 ? -1.2 : 1.0;
  const auto s3 = nlid::solve_least_squares(ext, z);
  INFO(s3.message());
  CHECK(s3.converged());
  CHECK((z.array() - 1.0).abs().maxCoeff() < 1e-8);
}

TEST_CASE("exponential fit y = a exp(bt) + c recovers noise-free parameters to 1e-9",
          "[estimation][lm]") {
  AutoDiffProblem problem(nlid_test::ExpFit<3>(2.0, -1.3, 0.5));
  Eigen::Vector3d th(1.0, -0.5, 0.0);
  const auto s = nlid::solve_least_squares(problem, th);
  INFO(s.message());
  CHECK(s.converged());
  CHECK(std::abs(th[0] - 2.0) < 1e-9);
  CHECK(std::abs(th[1] + 1.3) < 1e-9);
  CHECK(std::abs(th[2] - 0.5) < 1e-9);
  CHECK_THAT(s.message(), Contains("converged") && Contains("Jacobian evaluations"));

  // The same through central differences: fewer digits, same answer.
  nlid::NumericDiffProblem nproblem(nlid_test::ExpFit<3>(2.0, -1.3, 0.5));
  Eigen::Vector3d th2(1.0, -0.5, 0.0);
  const auto s2 = nlid::solve_least_squares(nproblem, th2);
  CHECK(s2.converged());
  CHECK((th2 - Eigen::Vector3d(2.0, -1.3, 0.5)).cwiseAbs().maxCoeff() < 1e-6);
}

TEST_CASE("an active upper bound: solution on the bound with the KKT sign", "[estimation][lm]") {
  using P = AutoDiffProblem<nlid_test::ExpFit<3>>;
  P problem(nlid_test::ExpFit<3>(2.0, -1.3, 0.5));
  LmOptions o;
  const double inf = std::numeric_limits<double>::infinity();
  o.upper_bounds = Eigen::Vector3d(1.5, inf, inf);
  // With a on the wrong value the residuals stay large, and Gauss–Newton converges only
  // linearly (JᵀJ misses Σ rᵢ∇²rᵢ): switch the cost-change test off so the gradient test decides.
  o.function_tolerance = 0;
  Eigen::Vector3d th(1.0, -0.5, 0.0);
  const auto s = nlid::solve_least_squares(problem, th, o);
  INFO(s.message());
  CHECK(s.converged());
  CHECK(th[0] == 1.5);  // exactly on the bound
  const Eigen::VectorXd g = gradient(problem, th);
  // At an upper bound the cost must not decrease inward: ∂F/∂a ≤ 0 (strictly, here), and the
  // free parameters are stationary.
  CHECK(g[0] < -1e-3);
  CHECK(std::abs(g[1]) < 1e-8);
  CHECK(std::abs(g[2]) < 1e-8);
  CHECK(s.final_gradient_norm < 1e-8);
}

TEST_CASE("an active lower bound, a start outside the box is projected", "[estimation][lm]") {
  using P = AutoDiffProblem<nlid_test::Rosenbrock<2>>;
  P problem(nlid_test::Rosenbrock<2>{});
  LmOptions o;
  o.lower_bounds = Eigen::Vector2d(1.5, -std::numeric_limits<double>::infinity());
  Eigen::Vector2d x(-1.2, 1.0);  // x₁ = −1.2 < 1.5: projected to 1.5
  const auto s = nlid::solve_least_squares(problem, x, o);
  INFO(s.message());
  CHECK(s.converged());
  CHECK(s.projected_parameters == 1);
  CHECK_THAT(s.message(), Contains("projected onto bounds"));
  CHECK(x[0] == 1.5);
  CHECK(x[1] == Approx(2.25).epsilon(1e-10));
  const Eigen::VectorXd g = gradient(problem, x);
  CHECK(g[0] == Approx(0.5));  // ∂F/∂x₁ = −(1 − x₁) = 0.5 ≥ 0 at a lower bound
  CHECK(std::abs(g[1]) < 1e-8);
}

TEST_CASE("a fixed parameter stays exactly unchanged", "[estimation][lm]") {
  using P = AutoDiffProblem<nlid_test::ExpFit<3>>;
  P problem(nlid_test::ExpFit<3>(2.0, -1.3, 0.5));
  LmOptions o;
  o.fixed = {false, false, true};
  o.function_tolerance = 0;  // large residual: let the gradient test decide (see above)
  const double c0 = 0.4000000000000000222;  // deliberately wrong offset, held
  Eigen::Vector3d th(1.0, -0.5, c0);
  const auto s = nlid::solve_least_squares(problem, th, o);
  INFO(s.message());
  CHECK(s.converged());
  CHECK(th[2] == c0);  // bit-for-bit
  const Eigen::VectorXd g = gradient(problem, th);
  CHECK(std::abs(g[0]) < 1e-8);  // the free parameters are optimal given c
  CHECK(std::abs(g[1]) < 1e-8);
  CHECK(std::abs(g[2]) > 1e-3);  // c itself is not at its optimum, proving it was held
  CHECK(std::abs(th[0] - 2.0) > 1e-3);

  o.fixed = {true, true, true};
  Eigen::Vector3d all(1.0, -0.5, 0.0);
  const auto s2 = nlid::solve_least_squares(problem, all, o);
  CHECK(s2.status == LmStatus::all_parameters_fixed);
  CHECK(s2.iterations == 0);
  CHECK(all == Eigen::Vector3d(1.0, -0.5, 0.0));
  CHECK(s2.final_cost == Approx(s2.initial_cost));
}

TEST_CASE("Huber loss recovers the line despite gross outliers, squared loss does not",
          "[estimation][lm][robust]") {
  // 10 % of the samples carry a +5 error.
  AutoDiffProblem problem(nlid_test::LineWithOutliers(1.0, 2.0, 100, 10, 5.0));
  Eigen::Vector2d ls(0.0, 0.0), hub(0.0, 0.0);
  const auto s_ls = nlid::solve_least_squares(problem, ls);
  LmOptions o;
  o.loss = nlid::RobustLoss::huber(0.05);
  o.function_tolerance = 0;  // IRLS converges linearly; let the gradient test decide
  const auto s_h = nlid::solve_least_squares(problem, hub, o);
  INFO(s_ls.message() << "\n" << s_h.message());
  CHECK(s_ls.converged());
  CHECK(s_h.converged());
  CHECK(std::abs(ls[0] - 1.0) > 0.3);  // least squares is dragged up by the outliers
  CHECK(std::abs(hub[0] - 1.0) < 0.02);
  CHECK(std::abs(hub[1] - 2.0) < 0.03);
  // At the Huber solution the true gradient Σ ρ'(r²) r ∇r vanishes.
  Eigen::VectorXd r(100);
  nlid::JacobianMatrix<2> J(100, 2);
  REQUIRE(problem.evaluate(hub, r, &J));
  Eigen::Vector2d g = Eigen::Vector2d::Zero();
  for (int i = 0; i < 100; ++i) {
    g += nlid::evaluate_loss(o.loss, r[i] * r[i]).rho1 * r[i] * J.row(i).transpose();
  }
  CHECK(g.cwiseAbs().maxCoeff() < 1e-8);
  // The reported cost is ½ Σ ρ(r²), not ½‖r‖².
  CHECK(s_h.final_cost == Approx(nlid::robust_cost(o.loss, r)).epsilon(1e-12));
  CHECK(s_h.final_cost < 0.5 * r.squaredNorm());
}

TEST_CASE("callback: trace of costs is monotone over accepted steps, abort stops at once",
          "[estimation][lm]") {
  AutoDiffProblem problem(nlid_test::Rosenbrock<2>{});
  std::vector<nlid::IterationReport> trace;
  LmOptions o;
  o.initial_lambda = 1e-8;  // provoke rejected steps early on
  o.callback = [&](const nlid::IterationReport& r) {
    trace.push_back(r);
    return true;
  };
  Eigen::Vector2d x(-1.2, 1.0);
  const auto s = nlid::solve_least_squares(problem, x, o);
  REQUIRE(trace.size() == static_cast<std::size_t>(s.iterations + 1));
  CHECK(trace.front().iteration == 0);
  CHECK(trace.front().step_accepted);
  CHECK(trace.front().cost == Approx(s.initial_cost));
  int rejected = 0;
  for (std::size_t i = 1; i < trace.size(); ++i) {
    CHECK(trace[i].iteration == static_cast<int>(i));
    if (trace[i].step_accepted) {
      CHECK(trace[i].cost < trace[i - 1].cost);
    } else {
      ++rejected;
      CHECK(trace[i].cost == trace[i - 1].cost);  // a rejected step leaves θ and F alone
      CHECK(trace[i].lambda > trace[i - 1].lambda);
    }
    CHECK(trace[i].step_norm > 0);
  }
  CHECK(rejected > 0);
  CHECK(trace.back().cost == Approx(s.final_cost));

  // Abort after the third attempt: θ is the last accepted point, status user_abort.
  Eigen::Vector2d last_accepted(-1.2, 1.0);
  int calls = 0;
  o.callback = [&](const nlid::IterationReport& r) { return ++calls < 4 || r.iteration < 0; };
  Eigen::Vector2d y(-1.2, 1.0);
  const auto sa = nlid::solve_least_squares(problem, y, o);
  CHECK(sa.status == LmStatus::user_abort);
  CHECK_FALSE(sa.converged());
  CHECK(sa.iterations == 3);
  CHECK(sa.final_cost == Approx(trace[3].cost));
  CHECK(0.5 * (std::pow(10 * (y[1] - y[0] * y[0]), 2) + std::pow(1 - y[0], 2)) ==
        Approx(sa.final_cost));

  // Aborting on the start report: no iterations at all.
  o.callback = [](const nlid::IterationReport&) { return false; };
  Eigen::Vector2d z(-1.2, 1.0);
  const auto s0 = nlid::solve_least_squares(problem, z, o);
  CHECK(s0.status == LmStatus::user_abort);
  CHECK(s0.iterations == 0);
  CHECK(z == Eigen::Vector2d(-1.2, 1.0));
}

TEST_CASE("max_iterations stops an unfinished solve", "[estimation][lm]") {
  AutoDiffProblem problem(nlid_test::Rosenbrock<2>{});
  LmOptions o;
  o.max_iterations = 3;
  Eigen::Vector2d x(-1.2, 1.0);
  const auto s = nlid::solve_least_squares(problem, x, o);
  CHECK(s.status == LmStatus::max_iterations_reached);
  CHECK(s.iterations == 3);
  CHECK_FALSE(s.converged());
  CHECK(s.final_cost < s.initial_cost);
  CHECK_THAT(s.message(), Contains("max_iterations_reached") && Contains("not converged"));
  o.max_iterations = 0;
  Eigen::Vector2d x0(-1.2, 1.0);
  const auto s0 = nlid::solve_least_squares(problem, x0, o);
  CHECK(s0.status == LmStatus::max_iterations_reached);
  CHECK(s0.iterations == 0);
  CHECK(x0 == Eigen::Vector2d(-1.2, 1.0));
}

namespace {
// min (log θ − log 3)²: the Gauss–Newton step from θ = 20 overshoots below 0, where log is not
// defined; evaluate() reports false there and the solver must back off.
struct LogFit {
  static constexpr int num_params = 1;
  int num_parameters() const { return 1; }
  Eigen::Index num_residuals() const { return 1; }
  template <class T>
  bool residuals(std::span<const T> th, std::span<T> r) const {
    using std::log;
    if (!(th[0] > 0)) return false;
    r[0] = log(th[0]) - std::log(3.0);
    return true;
  }
};
}  // namespace

TEST_CASE("steps into a region where evaluate() fails are rejected, not propagated",
          "[estimation][lm]") {
  AutoDiffProblem problem(LogFit{});
  Eigen::Matrix<double, 1, 1> th(20.0);
  LmOptions o;
  o.initial_lambda = 1e-12;
  int rejected = 0;
  o.callback = [&](const nlid::IterationReport& r) {
    rejected += r.step_accepted ? 0 : 1;
    return true;
  };
  const auto s = nlid::solve_least_squares(problem, th, o);
  INFO(s.message());
  CHECK(s.converged());
  CHECK(th[0] == Approx(3.0).epsilon(1e-10));
  CHECK(rejected >= 1);

  // Not evaluable at the start: an error that says so.
  Eigen::Matrix<double, 1, 1> bad(-1.0);
  CHECK_THROWS_WITH(nlid::solve_least_squares(problem, bad),
                    Contains("cannot be evaluated at the initial parameters") &&
                        Contains("evaluate() returned false"));
}

namespace {
// r = e^θ − 2.2 from θ = 0: the Gauss–Newton step (≈ 1.2) overshoots the minimum ln 2.2 ≈ 0.79,
// so the first step decreases the cost by only ~13 % of the model's prediction.
struct ExpOvershoot {
  static constexpr int num_params = 1;
  int num_parameters() const { return 1; }
  Eigen::Index num_residuals() const { return 1; }
  template <class T>
  bool residuals(std::span<const T> th, std::span<T> r) const {
    using std::exp;
    r[0] = exp(th[0]) - 2.2;
    return true;
  }
};
}  // namespace

TEST_CASE("LM damping follows the gain ratio: known first steps, accepted at a small gain, nu doubling",
          "[estimation][lm]") {
  // One parameter, J(0) = 1 so the scale D = 1: the damped step from θ = 0 is δ = 1.2 / (1 + λ₀),
  // the model decrease m(0) − m(δ) = 1.2δ − δ²/2, and the gain ratio ϱ ≈ 0.135 — small but above
  // the acceptance threshold 1e-3, so the step is taken and λ is scaled by
  // max(1/3, 1 − (2ϱ − 1)³) (Nielsen's update).
  AutoDiffProblem problem(ExpOvershoot{});
  std::vector<nlid::IterationReport> trace;
  LmOptions o;
  o.callback = [&](const nlid::IterationReport& r) {
    trace.push_back(r);
    return true;
  };
  Eigen::Matrix<double, 1, 1> th(0.0);
  const auto s = nlid::solve_least_squares(problem, th, o);
  INFO(s.message());
  CHECK(s.converged());
  CHECK(th[0] == Approx(std::log(2.2)).epsilon(1e-10));
  REQUIRE(trace.size() >= 2);
  const double l0 = o.initial_lambda;
  const double delta = 1.2 / (1.0 + l0);
  const double predicted = 1.2 * delta - 0.5 * delta * delta;
  const double new_cost = 0.5 * std::pow(std::exp(delta) - 2.2, 2);
  const double gain = (0.72 - new_cost) / predicted;
  REQUIRE(gain > 0.1);
  REQUIRE(gain < 0.2);
  CHECK(trace[0].lambda == l0);
  CHECK(trace[0].cost == Approx(0.72));
  CHECK(trace[1].step_accepted);
  CHECK(trace[1].step_norm == Approx(delta).epsilon(1e-12));
  CHECK(trace[1].cost == Approx(new_cost).epsilon(1e-12));
  // The report carries the damping after the attempt (the one the next step uses).
  const double t = 2.0 * gain - 1.0;
  CHECK(trace[1].lambda == Approx(l0 * std::max(1.0 / 3.0, 1.0 - t * t * t)).epsilon(1e-9));

  // Rejected steps multiply λ by ν = 2, 4, 8, …: from θ = 20 the undamped step of LogFit lands
  // below 0, where evaluate() fails, for many attempts in a row.
  AutoDiffProblem logfit(LogFit{});
  trace.clear();
  o.initial_lambda = 1e-12;
  Eigen::Matrix<double, 1, 1> th2(20.0);
  const auto s2 = nlid::solve_least_squares(logfit, th2, o);
  INFO(s2.message());
  CHECK(s2.converged());
  REQUIRE(trace.size() >= 4);
  for (int i = 1; i <= 3; ++i) CHECK_FALSE(trace[static_cast<std::size_t>(i)].step_accepted);
  CHECK(trace[1].lambda == Approx(2e-12));
  CHECK(trace[2].lambda == Approx(8e-12));
  CHECK(trace[3].lambda == Approx(64e-12));
}

TEST_CASE("a solve that never moves from its start is reported as stalled, not converged",
          "[estimation][lm]") {
  // r = θ − 1 with a Jacobian that lies (huge and of the wrong sign, as exploding simulation
  // sensitivities do): every damped step goes the wrong way and is rejected until it is tiny.
  auto problem = nlid::make_problem<1>(1, 1, [](const auto& th, Eigen::VectorXd& r, auto* J) {
    r[0] = th[0] - 1.0;
    if (J) (*J)(0, 0) = -1e8;
    return true;
  });
  Eigen::Matrix<double, 1, 1> th(0.0);
  const auto s = nlid::solve_least_squares(problem, th);
  INFO(s.message());
  CHECK(s.status == LmStatus::parameter_tolerance_reached);
  CHECK(s.accepted_steps == 0);
  CHECK(s.stalled_at_start());
  CHECK_FALSE(s.converged());
  CHECK(th[0] == 0.0);
  CHECK_THAT(s.message(), Contains("stalled") && !Contains("(converged)"));
  // The same stop after progress is a convergence: r = θ − 1 with the true Jacobian converges.
  auto honest = nlid::make_problem<1>(1, 1, [](const auto& t, Eigen::VectorXd& r, auto* J) {
    r[0] = (t[0] - 1.0) * (t[0] - 1.0) * (t[0] - 1.0);
    if (J) (*J)(0, 0) = 3.0 * (t[0] - 1.0) * (t[0] - 1.0);
    return true;
  });
  Eigen::Matrix<double, 1, 1> t2(0.0);
  const auto s2 = nlid::solve_least_squares(honest, t2);
  INFO(s2.message());
  CHECK(s2.accepted_steps > 0);
  CHECK(s2.converged());
  CHECK_FALSE(s2.stalled_at_start());
}

TEST_CASE("a start that is already the least-squares optimum is converged, not stalled",
          "[estimation][lm]") {
  // nlid-fit warned "did not converge (stalled)" for a linear ARX spec: its start is the exact
  // least-squares solution, so the first tiny step is rejected on rounding alone. Whether
  // rounding accepts or rejects that step depends on the data; of these linear fits some do
  // each, and every one must end converged, the rejected ones with the new label.
  int rejected = 0;
  for (int variant = 0; variant < 24; ++variant) {
    const int m = 400;
    Eigen::MatrixXd X(m, 3);
    Eigen::VectorXd y(m);
    for (int i = 0; i < m; ++i) {
      X(i, 0) = std::sin(0.37 * i + variant);
      X(i, 1) = std::cos(1.3 * i) * 17.0;
      X(i, 2) = 1.0;
      y(i) = 0.3 * X(i, 0) - 0.05 * X(i, 1) + 15.0 + 0.1 * std::sin(7.1 * i * i + 0.3 * variant);
    }
    auto problem = nlid::make_problem<3>(3, m, [&](const auto& th, Eigen::VectorXd& r, auto* J) {
      r = X * th - y;
      if (J) *J = X;
      return true;
    });
    Eigen::Vector3d th = X.colPivHouseholderQr().solve(y);
    const Eigen::Vector3d start = th;
    const auto s = nlid::solve_least_squares(problem, th);
    INFO("variant " << variant << ": " << s.message());
    CHECK(s.converged());
    CHECK_FALSE(s.stalled_at_start());
    CHECK((th - start).norm() < 1e-12);
    if (s.accepted_steps == 0) {
      ++rejected;
      CHECK(s.status == LmStatus::function_tolerance_reached);
      CHECK_THAT(s.message(), Contains("start is optimal"));
    }
  }
  CHECK(rejected > 0);  // the path under test was taken
}

TEST_CASE("a non-finite Jacobian at an accepted point stops with a named parameter",
          "[estimation][lm]") {
  // r = θ² − 0.01 with an analytic Jacobian that (wrongly) turns NaN below θ = 0.5.
  auto problem = nlid::make_problem<1>(1, 1, [](const auto& th, Eigen::VectorXd& r, auto* J) {
    r[0] = th[0] * th[0] - 0.01;
    if (J) (*J)(0, 0) = th[0] < 0.5 ? std::numeric_limits<double>::quiet_NaN() : 2 * th[0];
    return true;
  });
  Eigen::Matrix<double, 1, 1> th(2.0);
  LmOptions o;
  o.parameter_names = {"gain"};
  const auto s = nlid::solve_least_squares(problem, th, o);
  CHECK(s.status == LmStatus::jacobian_not_finite);
  CHECK_FALSE(s.converged());
  CHECK(th[0] < 0.5);  // θ is the accepted point where it happened
  CHECK_THAT(s.detail, Contains("'gain'") && Contains("r[0]"));
  CHECK_THAT(s.message(), Contains("jacobian_not_finite"));
  // NaN residuals at the start are an error naming the residual.
  auto nan_problem = nlid::make_problem<1>(1, 2, [](const auto&, Eigen::VectorXd& r, auto* J) {
    r << 1.0, std::numeric_limits<double>::quiet_NaN();
    if (J) J->setOnes();
    return true;
  });
  Eigen::Matrix<double, 1, 1> t2(1.0);
  CHECK_THROWS_WITH(nlid::solve_least_squares(nan_problem, t2), Contains("residual 1 is nan"));
}

TEST_CASE("ill-conditioned Jacobian: the QR fallback keeps full accuracy", "[estimation][lm]") {
  // r = y − (a + b) t − 1e-7 b t² with nearly collinear columns: cond(J) ≈ 1e8, so the normal
  // equations (cond ≈ 1e16) cannot be trusted while QR on J can.
  const int m = 40;
  Eigen::VectorXd t(m), y(m);
  for (int i = 0; i < m; ++i) {
    t[i] = 1.0 + static_cast<double>(i) / m;
    y[i] = (1.0 + 2.0) * t[i] + 1e-7 * 2.0 * t[i] * t[i];
  }
  auto problem = nlid::make_problem<2>(2, m, [&](const Eigen::Vector2d& th, Eigen::VectorXd& r,
                                                 nlid::JacobianMatrix<2>* J) {
    r = y - (th[0] + th[1]) * t - 1e-7 * th[1] * t.cwiseProduct(t);
    if (J) {
      J->col(0) = -t;
      J->col(1) = -t - 1e-7 * t.cwiseProduct(t);
    }
    return true;
  });
  LmOptions o;
  o.initial_lambda = 1e-20;  // essentially Gauss–Newton from the start
  // The gradient along the ill-determined direction a − b is ~σ_min² ≈ 1e-14 times the error:
  // only the step-size test can tell when that direction has converged.
  o.gradient_tolerance = 0;
  o.function_tolerance = 0;
  Eigen::Vector2d th(0.0, 0.0);
  const auto s = nlid::solve_least_squares(problem, th, o);
  INFO(s.message());
  CHECK(s.qr_fallbacks > 0);
  CHECK_THAT(s.message(), Contains("QR fallback"));
  // Attainable: data rounding (1e-15) / σ_min (2e-7) ≈ 1e-8; the normal equations alone would
  // lose all digits of a − b (cond² ε ≈ 1).
  CHECK(std::abs(th[0] - 1.0) < 1e-7);
  CHECK(std::abs(th[1] - 2.0) < 1e-7);
  CHECK(s.final_cost < 1e-20);
}

TEST_CASE("stacked problems share parameters across experiments", "[estimation][lm]") {
  using P = AutoDiffProblem<nlid_test::ExpFit<3>>;
  std::vector<P> parts{P(nlid_test::ExpFit<3>(2.0, -1.3, 0.5, 30)),
                       P(nlid_test::ExpFit<3>(2.0, -1.3, 0.5, 17))};
  nlid::StackedProblem<P> stacked(std::move(parts));
  CHECK(stacked.num_residuals() == 47);
  CHECK(stacked.offset(1) == 30);
  CHECK(stacked.size() == 2);
  Eigen::Vector3d th(1.0, -0.5, 0.0);
  const auto s = nlid::solve_least_squares(stacked, th);
  CHECK(s.converged());
  CHECK((th - Eigen::Vector3d(2.0, -1.3, 0.5)).cwiseAbs().maxCoeff() < 1e-9);
  // The stacked Jacobian is the parts' Jacobians on top of each other.
  Eigen::VectorXd r(47);
  nlid::JacobianMatrix<3> J(47, 3);
  REQUIRE(stacked.evaluate(th, r, &J));
  Eigen::VectorXd r1(17);
  nlid::JacobianMatrix<3> J1(17, 3);
  REQUIRE(stacked.part(1).evaluate(th, r1, &J1));
  CHECK(J.bottomRows(17) == J1);
  CHECK_THROWS_WITH(nlid::StackedProblem<P>(std::vector<P>{}), Contains("no parts"));
}

TEST_CASE("invalid options throw errors that name the option and the parameter",
          "[estimation][lm][errors]") {
  AutoDiffProblem problem(nlid_test::ExpFit<3>(2.0, -1.3, 0.5));
  const Eigen::Vector3d start(1.0, -0.5, 0.0);
  auto expect = [&](const LmOptions& o, const std::string& what, const std::string& where) {
    Eigen::Vector3d th = start;
    try {
      nlid::solve_least_squares(problem, th, o);
      FAIL("no error for: " << what);
    } catch (const nlid::Error& e) {
      INFO(e.what());
      CHECK_THAT(std::string(e.what()), Contains(what));
      CHECK(e.where().parameter == where);
      CHECK(th == start);  // θ untouched on a validation error
    }
  };
  LmOptions o;
  o.lower_bounds = Eigen::VectorXd::Zero(2);
  expect(o, "lower_bounds has 2 entries, the problem has 3 parameters", "lower_bounds");
  o = {};
  o.upper_bounds = Eigen::VectorXd::Zero(4);
  expect(o, "upper_bounds has 4 entries", "upper_bounds");
  o = {};
  o.lower_bounds = Eigen::Vector3d(0, 2, 0);
  o.upper_bounds = Eigen::Vector3d(1, 1, 1);
  expect(o, "lower bound 2 exceeds upper bound 1 for parameter 'theta[1]' (index 1)", "theta[1]");
  o.parameter_names = {"a", "b", "c"};
  expect(o, "for parameter 'b'", "b");
  o = {};
  o.lower_bounds = Eigen::Vector3d(0, std::nan(""), 0);
  expect(o, "lower_bounds is nan", "theta[1]");
  o = {};
  o.fixed = {true};
  expect(o, "fixed has 1 entries", "fixed");
  o = {};
  o.parameter_names = {"a"};
  expect(o, "parameter_names has 1 entries", "parameter_names");
  o = {};
  o.max_iterations = -1;
  expect(o, "max_iterations must be >= 0", "max_iterations");
  o = {};
  o.function_tolerance = -1e-3;
  expect(o, "function_tolerance must be finite and >= 0", "function_tolerance");
  o = {};
  o.gradient_tolerance = std::numeric_limits<double>::quiet_NaN();
  expect(o, "gradient_tolerance", "gradient_tolerance");
  o = {};
  o.parameter_tolerance = std::numeric_limits<double>::infinity();
  expect(o, "parameter_tolerance", "parameter_tolerance");
  o = {};
  o.scaling = static_cast<nlid::LmScaling>(7);
  expect(o, "LmOptions::scaling is not an LmScaling value (got 7)", "scaling");
  o = {};
  o.initial_lambda = 0;
  expect(o, "initial_lambda must be finite and > 0", "initial_lambda");
  o = {};
  o.loss = nlid::RobustLoss::huber(-1.0);
  expect(o, "Huber loss threshold delta must be finite and > 0", "loss.delta");
  o = {};
  o.fixed = {false, true, false};
  o.upper_bounds = Eigen::Vector3d(10, -1.0, 10);
  expect(o, "parameter 'theta[1]' is fixed at -0.5 which lies outside its bounds [-inf, -1]",
         "theta[1]");

  // Bad initial values.
  Eigen::Vector3d nan_start(1.0, std::numeric_limits<double>::quiet_NaN(), 0.0);
  CHECK_THROWS_WITH(nlid::solve_least_squares(problem, nan_start),
                    Contains("initial value of parameter 'theta[1]' is not finite"));
  AutoDiffProblem dyn(nlid_test::Rosenbrock<nlid::Dynamic>{});
  Eigen::VectorXd wrong(3);
  wrong.setZero();
  CHECK_THROWS_WITH(nlid::solve_least_squares(dyn, wrong),
                    Contains("theta has 3 entries, the problem has 2 parameters"));
}

TEST_CASE("a solver object is reusable and re-validates changed options", "[estimation][lm]") {
  using P = AutoDiffProblem<nlid_test::ExpFit<3>>;
  P problem(nlid_test::ExpFit<3>(2.0, -1.3, 0.5));
  nlid::LevenbergMarquardt<P> lm;
  lm.setup(problem);
  for (int k = 0; k < 3; ++k) {
    Eigen::Vector3d th(1.0 + k, -0.5, 0.0);
    const auto s = lm.solve(problem, th);
    CHECK(s.converged());
    CHECK((th - Eigen::Vector3d(2.0, -1.3, 0.5)).cwiseAbs().maxCoeff() < 1e-9);
  }
  LmOptions bad;
  bad.initial_lambda = -1;
  lm.set_options(bad);
  Eigen::Vector3d th(1.0, -0.5, 0.0);
  CHECK_THROWS_WITH(lm.solve(problem, th), Contains("initial_lambda"));
  CHECK(std::string(nlid::to_string(LmStatus::gradient_tolerance_reached)) ==
        "gradient_tolerance_reached");
}

namespace {
// Rosenbrock with the second parameter in units a thousand times smaller (x₁ = 1000·z): the
// same problem, written in other units.
struct RosenbrockInOtherUnits {
  static constexpr int num_params = 2;
  int num_parameters() const { return 2; }
  Eigen::Index num_residuals() const { return 2; }
  template <class T>
  bool residuals(std::span<const T> x, std::span<T> r) const {
    r[0] = 10.0 * (1000.0 * x[1] - x[0] * x[0]);
    r[1] = 1.0 - x[0];
    return true;
  }
};

std::vector<double> cost_history(const auto& problem, Eigen::Vector2d x, nlid::LmScaling scaling, nlid::LmSummary& s,
                                 const Eigen::VectorXd& parameter_scale = {}) {
  std::vector<double> costs;
  LmOptions o;
  o.scaling = scaling;
  o.parameter_scale = parameter_scale;
  o.callback = [&](const nlid::IterationReport& r) {
    costs.push_back(r.cost);
    return true;
  };
  s = nlid::solve_least_squares(problem, x, o);
  return costs;
}
}  // namespace

TEST_CASE("LmScaling: the column scalings are invariant to parameter units, all three converge", "[estimation][lm]") {
  AutoDiffProblem plain(nlid_test::Rosenbrock<2>{});
  AutoDiffProblem other(RosenbrockInOtherUnits{});
  std::vector<double> running_max_costs;
  for (auto scaling : {nlid::LmScaling::running_max, nlid::LmScaling::current}) {
    CAPTURE(static_cast<int>(scaling));
    nlid::LmSummary s1, s2;
    const auto c1 = cost_history(plain, Eigen::Vector2d(-1.2, 1.0), scaling, s1);
    const auto c2 = cost_history(other, Eigen::Vector2d(-1.2, 1e-3), scaling, s2);
    CHECK(s1.converged());
    CHECK(s2.converged());
    // The same iterates in other units: the same costs, step for step.
    REQUIRE(c1.size() == c2.size());
    for (std::size_t k = 0; k < c1.size(); ++k) CHECK(c2[k] == Approx(c1[k]).epsilon(1e-8).margin(1e-20));
    if (scaling == nlid::LmScaling::running_max) {
      running_max_costs = c1;
    } else {
      CHECK(c1 != running_max_costs);  // the option changes the path
    }
  }
  // automatic is running_max outside estimate(): the same iterates.
  nlid::LmSummary sa;
  CHECK(cost_history(plain, Eigen::Vector2d(-1.2, 1.0), nlid::LmScaling::automatic, sa) == running_max_costs);
  // Levenberg damping is not unit-invariant, but converges on both.
  for (const bool units : {false, true}) {
    nlid::LmSummary s;
    Eigen::Vector2d x(-1.2, units ? 1e-3 : 1.0);
    LmOptions o;
    o.scaling = nlid::LmScaling::levenberg;
    o.max_iterations = 500;
    s = units ? nlid::solve_least_squares(other, x, o) : nlid::solve_least_squares(plain, x, o);
    INFO(s.message());
    CHECK(s.converged());
    CHECK(x[0] == Approx(1.0).epsilon(1e-7));
    CHECK(x[1] * (units ? 1000.0 : 1.0) == Approx(1.0).epsilon(1e-7));
  }
}

TEST_CASE("LmScaling::levenberg with parameter_scale: uniform damping in θ/s, the same iterates in any units",
          "[estimation][lm]") {
  AutoDiffProblem plain(nlid_test::Rosenbrock<2>{});
  AutoDiffProblem other(RosenbrockInOtherUnits{});
  nlid::LmSummary s1, s2, s3;
  const auto c1 = cost_history(plain, Eigen::Vector2d(-1.2, 1.0), nlid::LmScaling::levenberg, s1);
  const auto c2 = cost_history(other, Eigen::Vector2d(-1.2, 1e-3), nlid::LmScaling::levenberg, s2,
                               Eigen::Vector2d(1.0, 1e-3));
  CHECK(s1.converged());
  CHECK(s2.converged());
  CHECK(s1.message().find("parameter_tolerance") == s2.message().find("parameter_tolerance"));
  REQUIRE(c1.size() == c2.size());
  for (std::size_t k = 0; k < c1.size(); ++k) CHECK(c2[k] == Approx(c1[k]).epsilon(1e-8).margin(1e-20));
  // Without the scales the other units take another path (what the scales are for).
  const auto c3 = cost_history(other, Eigen::Vector2d(-1.2, 1e-3), nlid::LmScaling::levenberg, s3);
  CHECK(c3.size() != c1.size());

  // A scale that is not a positive number is refused, naming the parameter.
  LmOptions o;
  o.parameter_scale = Eigen::Vector2d(1.0, 0.0);
  o.parameter_names = {"gain", "tau"};
  Eigen::Vector2d x(-1.2, 1.0);
  CHECK_THROWS_WITH(nlid::solve_least_squares(plain, x, o),
                    Catch::Contains("parameter_scale") && Catch::Contains("'tau'"));
  o.parameter_scale = Eigen::Vector3d(1.0, 1.0, 1.0);
  CHECK_THROWS_WITH(nlid::solve_least_squares(plain, x, o), Catch::Contains("parameter_scale has 3 entries"));
}

TEST_CASE("data in tiny units: the gradient test is relative to the start's gradient, the fit is the same",
          "[estimation][lm]") {
  // y = a exp(bt) + c in units 10⁻¹² of the usual ones: every gradient is 10⁻¹² of the usual,
  // below the absolute 10⁻¹⁰ test at the start already (the solve stopped there before).
  nlid_test::ExpFit<3> usual(2.0, -1.5, 0.5), tiny(2e-12, -1.5, 0.5e-12);
  AutoDiffProblem pu(usual), pt(tiny);
  Eigen::Vector3d xu(1.0, -1.0, 0.0), xt(1e-12, -1.0, 0.0);
  const nlid::LmSummary su = nlid::solve_least_squares(pu, xu, LmOptions{});
  const nlid::LmSummary st = nlid::solve_least_squares(pt, xt, LmOptions{});
  INFO(st.message());
  CHECK(st.converged());
  CHECK(st.iterations > 3);
  CHECK(xt[0] == Approx(2e-12).epsilon(1e-6));
  CHECK(xt[1] == Approx(-1.5).epsilon(1e-6));
  CHECK(xt[1] == Approx(xu[1]).epsilon(1e-6));
  CHECK(su.converged());
}

namespace {

// r = y − Xθ with a well-conditioned X (3 columns), and the ridge answer of
// min ½‖y − Xθ‖² + ½λ Σ w_k(θ_k − θ̄_k)²: (XᵀX + λW)θ = Xᵀy + λWθ̄.
struct RidgeCase {
  Eigen::MatrixXd X;
  Eigen::VectorXd y;
  RidgeCase() : X(30, 3), y(30) {
    for (int i = 0; i < 30; ++i) {
      const double t = 0.1 * i;
      X(i, 0) = 1.0;
      X(i, 1) = std::sin(t);
      X(i, 2) = t * t / 9.0;
      y[i] = 0.5 - 2.0 * X(i, 1) + 3.0 * X(i, 2) + 0.05 * std::cos(7.0 * t);
    }
  }
  Eigen::VectorXd ridge(double lambda, const Eigen::VectorXd& w, const Eigen::VectorXd& nominal) const {
    const Eigen::MatrixXd A = X.transpose() * X + lambda * Eigen::MatrixXd(w.asDiagonal());
    const Eigen::VectorXd b = X.transpose() * y + lambda * w.cwiseProduct(nominal);
    return A.ldlt().solve(b);
  }
  template <int P>
  auto problem() const {
    return nlid::make_problem<P>(3, 30, [this](const auto& th, Eigen::VectorXd& r, auto* J) {
      r = y - X * Eigen::VectorXd(th);
      if (J) *J = -X;
      return true;
    });
  }
};

}  // namespace

TEST_CASE("regularization: the solution is the ridge estimate towards the nominal, with the penalty in the cost",
          "[estimation][lm]") {
  const RidgeCase c;
  const double lambda = 4.0;
  const Eigen::Vector3d w(0.0, 1.0, 2.5), nominal(9.0, -1.0, 1.0);  // the intercept is not penalised
  const Eigen::VectorXd want = c.ridge(lambda, w, nominal);
  const Eigen::VectorXd plain = c.X.colPivHouseholderQr().solve(c.y);
  REQUIRE((want - plain).norm() > 0.1);  // the penalty matters here

  LmOptions o;
  o.regularization.lambda = lambda;
  o.regularization.weights = w;
  o.regularization.nominal = nominal;
  o.gradient_tolerance = 1e-13;  // run to the minimum, not to a small relative decrease
  o.function_tolerance = 0;
  Eigen::Vector3d th = Eigen::Vector3d::Zero();  // fixed size
  const auto s = nlid::solve_least_squares(c.problem<3>(), th, o);
  INFO(s.message());
  // Attainable: a cost of ≈ 5 resolves decreases down to ≈ 1e-15, i.e. θ to ≈ √(1e-15) ≈ 3e-8;
  // 1e-6 leaves room for other compilers' roundings and is 1e5 times below the penalty's effect.
  CHECK((th - want).norm() < 1e-6);
  const double expected_cost = 0.5 * (c.y - c.X * want).squaredNorm() +
                               0.5 * lambda * (w.array() * (want - nominal).array().square()).sum();
  CHECK(std::abs(s.final_cost - expected_cost) < 1e-10 * expected_cost);
  CHECK(std::abs(s.initial_cost - (0.5 * c.y.squaredNorm() + 0.5 * lambda * (w.array() * nominal.array().square()).sum())) < 1e-9);

  Eigen::VectorXd thd = Eigen::VectorXd::Zero(3);  // Dynamic: the same answer
  const auto sd = nlid::solve_least_squares(c.problem<nlid::Dynamic>(), thd, o);
  INFO(sd.message());
  CHECK((thd - want).norm() < 1e-6);

  // Defaults: weights all 1, nominal zero.
  LmOptions d;
  d.regularization.lambda = lambda;
  d.gradient_tolerance = 1e-13;
  d.function_tolerance = 0;
  th.setZero();
  (void)nlid::solve_least_squares(c.problem<3>(), th, d);
  CHECK((th - c.ridge(lambda, Eigen::Vector3d::Ones(), Eigen::Vector3d::Zero())).norm() < 1e-6);
  // lambda 0 is off whatever the weights: the plain least-squares answer.
  d.regularization.lambda = 0.0;
  d.regularization.weights = w;
  th.setZero();
  (void)nlid::solve_least_squares(c.problem<3>(), th, d);
  CHECK((th - plain).norm() < 1e-6);
}

TEST_CASE("regularization: the QR fallback solves the regularized step", "[estimation][lm]") {
  // The ill-conditioned problem above (cond(J) ≈ 1e8) with b pulled towards 3: along the
  // ill-determined direction the data's curvature (≈ 2e-12) and λ_R = 1e-12 are comparable, so
  // the answer moves far from (1, 2), and only a step that carries the penalty rows through
  // the QR reaches it. Reference: Householder QR of the stacked system [J; √λ_R e_b].
  const int m = 40;
  Eigen::VectorXd t(m), y(m);
  for (int i = 0; i < m; ++i) {
    t[i] = 1.0 + static_cast<double>(i) / m;
    y[i] = (1.0 + 2.0) * t[i] + 1e-7 * 2.0 * t[i] * t[i];
  }
  Eigen::MatrixXd J(m, 2);
  J.col(0) = t;
  J.col(1) = t + 1e-7 * t.cwiseProduct(t);
  auto problem = nlid::make_problem<2>(2, m, [&](const Eigen::Vector2d& th, Eigen::VectorXd& r,
                                                 nlid::JacobianMatrix<2>* Jp) {
    r = y - J * th;
    if (Jp) *Jp = -J;
    return true;
  });
  const double lr = 1e-12, nominal_b = 3.0;
  Eigen::MatrixXd Js(m + 1, 2);
  Js.topRows(m) = J;
  Js.row(m) << 0.0, std::sqrt(lr);
  Eigen::VectorXd ys(m + 1);
  ys.head(m) = y;
  ys[m] = std::sqrt(lr) * nominal_b;
  const Eigen::Vector2d want = Js.householderQr().solve(ys);
  REQUIRE(std::abs(want[1] - 2.0) > 0.05);

  LmOptions o;
  o.initial_lambda = 1e-20;
  o.gradient_tolerance = 0;
  o.function_tolerance = 0;
  o.regularization.lambda = lr;
  o.regularization.weights = Eigen::Vector2d(0.0, 1.0);
  o.regularization.nominal = Eigen::Vector2d(0.0, nominal_b);
  Eigen::Vector2d th(0.0, 0.0);
  const auto s = nlid::solve_least_squares(problem, th, o);
  INFO(s.message());
  CHECK(s.qr_fallbacks > 0);
  // Attainable: at the optimum F ≈ 3e-14 with residuals ≈ 1e-7, so rounding blurs F by ≈ 1e-21;
  // along the weak direction (curvature ≈ 3e-12) that hides parameter changes up to
  // √(2·1e-21 / 3e-12) ≈ 3e-5 (builds differ within that: 2e-6 with one compiler's roundings).
  // Without the penalty rows the fallback would head for (1, 2), |Δb| > 0.05 away.
  CHECK(std::abs(th[0] - want[0]) < 1e-4);
  CHECK(std::abs(th[1] - want[1]) < 1e-4);
}

TEST_CASE("regularization: bad settings are refused naming the option and the parameter", "[estimation][lm][errors]") {
  const RidgeCase c;
  const auto fails = [&](auto edit) {
    LmOptions o;
    o.parameter_names = {"c", "gain", "curv"};
    edit(o);
    Eigen::Vector3d th = Eigen::Vector3d::Zero();
    try {
      (void)nlid::solve_least_squares(c.problem<3>(), th, o);
    } catch (const nlid::Error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  CHECK_THAT(fails([](LmOptions& o) { o.regularization.lambda = -1.0; }),
             Contains("regularization.lambda must be finite and >= 0, got -1"));
  CHECK_THAT(fails([](LmOptions& o) { o.regularization.lambda = std::numeric_limits<double>::infinity(); }),
             Contains("regularization.lambda must be finite"));
  CHECK_THAT(fails([](LmOptions& o) { o.regularization.weights = Eigen::Vector2d(1, 1); }),
             Contains("regularization.weights has 2 entries, the problem has 3 parameters"));
  CHECK_THAT(fails([](LmOptions& o) { o.regularization.weights = Eigen::Vector3d(1, -2, 1); }),
             Contains("regularization.weights is -2 for parameter 'gain' (index 1)"));
  CHECK_THAT(fails([](LmOptions& o) { o.regularization.nominal = Eigen::Vector3d(1, 1, std::nan("")); }),
             Contains("regularization.nominal is nan for parameter 'curv' (index 2)"));
}
