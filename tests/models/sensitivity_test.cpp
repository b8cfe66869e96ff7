// The structured simulation Jacobian of Nlarx (models/detail/nlarx_sensitivity.hpp) against
// the two references it must agree with: forward AD through the recursion
// (AutoDiffProblem<SimulationResiduals>) and central finite differences; SigmoidNet's analytic
// gradient against its Dual derivative; and estimation through either Jacobian reaching the
// same model.
#include <catch2/catch.hpp>

#include <cmath>
#include <random>

#include "jacobian_checks.hpp"
#include "nlid/models/estimate.hpp"
#include "nlid/nonlinearities/linear.hpp"
#include "nlid/nonlinearities/sigmoid_network.hpp"
#include "nlid/regressors.hpp"

namespace {

using Net = nlid::SigmoidNet<6, 5>;
using Nlarx5 = nlid::Nlarx<nlid::LaggedRegressors<3, 3, 0>, Net>;

Eigen::MatrixXd test_input(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> level(-1.0, 1.0);
  Eigen::MatrixXd u(n, 1);
  double v = 0.0;
  for (int t = 0; t < n; ++t) {
    if (t % 17 == 0) v = level(rng);
    u(t, 0) = v + 0.2 * std::sin(0.07 * t);
  }
  return u;
}

// A stable nlarx5-shaped model with every parameter nonzero and a non-trivial normalisation
// (so 1/s enters ∂F/∂φ).
Nlarx5 make_model(unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> d(-0.5, 0.5);
  Net net;
  Eigen::VectorXd r(6), s(6);
  r << 0.1, 0.1, 0.1, 0.05, 0.05, 0.05;
  s << 0.8, 0.8, 0.8, 0.6, 0.6, 0.6;
  net.set_normalization(r, s);
  Nlarx5 m(nlid::LaggedRegressors<3, 3, 0>{}, net);
  Eigen::VectorXd th(Nlarx5::num_params);
  for (Eigen::Index i = 0; i < th.size(); ++i) th(i) = d(rng);
  th.head(3) << 0.5, 0.15, 0.05;  // L on the past outputs (scaled by 1/s): a stable linear part
  for (int k = 0; k < 5; ++k) {
    th(net.offset_b() + 6 * k) *= 0.3;  // gentle feedback through the units
    th(net.offset_a() + k) *= 0.5;
  }
  m.set_parameters(th);
  return m;
}

std::vector<nlid::detail::EstimationSegment> segments(const std::vector<Eigen::MatrixXd>& u,
                                                      const std::vector<Eigen::VectorXd>& y, nlid::InitialCondition ic,
                                                      const Nlarx5& m) {
  std::vector<nlid::detail::EstimationSegment> segs(u.size());
  for (std::size_t i = 0; i < u.size(); ++i) {
    segs[i].u = &u[i];
    segs[i].y = y[i];
    if (ic == nlid::InitialCondition::measured) {
      segs[i].start = m.history_length();
      segs[i].x0 = m.measured_state(u[i], y[i], m.history_length());
    } else if (ic == nlid::InitialCondition::estimate) {
      segs[i].x0 = m.held_state(y[i](0), u[i].row(0));
      segs[i].free_offset = 3 * static_cast<int>(i);
    }
  }
  return segs;
}

using nlid_test::rel_diff;

}  // namespace

TEST_CASE("SigmoidNet::gradient equals the Dual derivative and the value of operator()", "[models][sensitivity]") {
  const Nlarx5 m = make_model(3);
  const Net& net = m.nonlinearity();
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> d(-2.0, 2.0);
  constexpr int P = Net::num_params;
  using D = nlid::Dual<double, P + 6>;
  for (int trial = 0; trial < 20; ++trial) {
    Eigen::VectorXd x(6), th = m.parameters();
    for (int j = 0; j < 6; ++j) x(j) = d(rng);
    th(net.offset_c()) += 8.0 * d(rng);  // units deep in saturation on both sides
    std::array<D, P> thd;
    std::array<D, 6> xd;
    for (int i = 0; i < P; ++i) thd[static_cast<std::size_t>(i)] = D::variable(th(i), i);
    for (int j = 0; j < 6; ++j) xd[static_cast<std::size_t>(j)] = D::variable(x(j), P + j);
    const D g = net(std::span<const D>(xd), std::span<const D>(thd));
    Eigen::VectorXd gt(P), gx(6);
    const double v = net.gradient(nlid::detail::as_const_span(x), nlid::detail::as_const_span(th),
                                  nlid::detail::as_span(gt), nlid::detail::as_span(gx));
    CHECK(v == net(nlid::detail::as_const_span(x), nlid::detail::as_const_span(th)));  // bitwise
    CHECK(rel_diff(g.v.head(P), gt) < 1e-13);
    CHECK(rel_diff(g.v.tail(6), gx) < 1e-13);
  }
  // The Dynamic twin has the same gradient.
  nlid::SigmoidNet<nlid::Dynamic, nlid::Dynamic> dyn(6, 5);
  dyn.set_normalization(net.center(), net.scale());
  Eigen::VectorXd x = Eigen::VectorXd::LinSpaced(6, -1.0, 1.0), gt1(P), gx1(6), gt2(P), gx2(6);
  const auto th = nlid::detail::as_const_span(m.parameters());
  // (The fixed twin evaluates its units' logistic functions in SIMD lanes and sums in another
  // order: equal to a few ulp, not bitwise.)
  const double v1 = net.gradient(nlid::detail::as_const_span(x), th, nlid::detail::as_span(gt1), nlid::detail::as_span(gx1));
  const double v2 = dyn.gradient(nlid::detail::as_const_span(x), th, nlid::detail::as_span(gt2), nlid::detail::as_span(gx2));
  CHECK(std::abs(v1 - v2) <= 1e-14 * (1.0 + std::abs(v2)));
  CHECK(v2 == dyn(nlid::detail::as_const_span(x), th));
  CHECK(rel_diff(gt1, gt2) < 1e-14);
  CHECK(rel_diff(gx1, gx2) < 1e-14);
  // Wrong lengths are named.
  Eigen::VectorXd short_g(P - 1);
  CHECK_THROWS_WITH(net.gradient(nlid::detail::as_const_span(x), th, nlid::detail::as_span(short_g), nlid::detail::as_span(gx1)),
                    Catch::Contains("g_theta"));
}

TEST_CASE("structured simulation Jacobian equals forward AD through the recursion", "[models][sensitivity]") {
  const Nlarx5 m = make_model(5);
  std::vector<Eigen::MatrixXd> u{test_input(400, 1), test_input(300, 2)};
  std::vector<Eigen::VectorXd> y(2);
  for (std::size_t i = 0; i < 2; ++i) {
    y[i] = m.simulate(nlid::Experiment(u[i], Eigen::MatrixXd::Zero(u[i].rows(), 1), 0.01)).col(0);
    for (Eigen::Index t = 0; t < y[i].size(); ++t) y[i](t) += 0.05 * std::sin(0.3 * t);  // not an exact fit
  }
  Eigen::VectorXd theta = m.parameters();
  theta(0) += 0.02;
  theta(Net{}.offset_c() + 1) -= 0.1;

  SECTION("zero and measured initial conditions, static parameter count") {
    for (auto ic : {nlid::InitialCondition::zero, nlid::InitialCondition::measured}) {
      CAPTURE(nlid::to_string(ic));
      const auto segs = segments(u, y, ic, m);
      constexpr int P = Nlarx5::num_params;
      nlid::detail::NlarxSimulationProblem<Nlarx5, P> fast(m, segs, {}, ic, 1e6);
      nlid::AutoDiffProblem<nlid::detail::SimulationResiduals<Nlarx5, P>> ad(
          nlid::detail::SimulationResiduals<Nlarx5, P>(m, segs, {}, ic, 1e6));
      REQUIRE(fast.num_residuals() == ad.num_residuals());
      const Eigen::Index n = fast.num_residuals();
      Eigen::VectorXd r1(n), r2(n), r3(n);
      nlid::JacobianMatrix<P> J1(n, P), J2(n, P);
      const Eigen::Matrix<double, P, 1> th = theta;
      REQUIRE(fast.evaluate(th, r1, &J1));
      REQUIRE(ad.evaluate(th, r2, &J2));
      REQUIRE(fast.evaluate(th, r3, nullptr));
      CHECK(rel_diff(r1, r2) < 1e-13);  // the same simulation (Duals take the scalar logistic)
      CHECK(rel_diff(r1, r3) == 0.0);  // with and without the Jacobian: bitwise
      CHECK(rel_diff(J2, J1) < 1e-11);
      CHECK(J1.cwiseAbs().maxCoeff() > 1e-3);  // a real Jacobian, not zeros
    }
  }

  SECTION("estimated initial states (Dynamic count): columns of the past outputs too") {
    const auto segs = segments(u, y, nlid::InitialCondition::estimate, m);
    const std::vector<int> free{0, 1, 2};
    nlid::detail::NlarxSimulationProblem<Nlarx5, nlid::Dynamic> fast(m, segs, free, nlid::InitialCondition::estimate, 1e6);
    nlid::AutoDiffProblem<nlid::detail::SimulationResiduals<Nlarx5, nlid::Dynamic>> ad(
        nlid::detail::SimulationResiduals<Nlarx5, nlid::Dynamic>(m, segs, free, nlid::InitialCondition::estimate, 1e6));
    const int np = Nlarx5::num_params + 6;
    REQUIRE(fast.num_parameters() == np);
    Eigen::VectorXd th(np);
    th.head(Nlarx5::num_params) = theta;
    th.tail(6) << y[0](0) + 0.1, y[0](0), y[0](0) - 0.05, y[1](0), y[1](0) + 0.2, y[1](0);
    const Eigen::Index n = fast.num_residuals();
    Eigen::VectorXd r1(n), r2(n);
    Eigen::MatrixXd J1(n, np), J2(n, np);
    REQUIRE(fast.evaluate(th, r1, &J1));
    REQUIRE(ad.evaluate(th, r2, &J2));
    CHECK(rel_diff(r1, r2) < 1e-13);
    CHECK(rel_diff(J2, J1) < 1e-11);
    // Experiment 0's residuals do not depend on experiment 1's initial state, and vice versa.
    CHECK(J1.block(0, Nlarx5::num_params + 3, 400, 3).cwiseAbs().maxCoeff() == 0.0);
    CHECK(J1.block(400, Nlarx5::num_params, 300, 3).cwiseAbs().maxCoeff() == 0.0);
    CHECK(J1.block(0, Nlarx5::num_params, 400, 3).cwiseAbs().maxCoeff() > 1e-3);
  }

  SECTION("central finite differences") {
    const auto segs = segments(u, y, nlid::InitialCondition::measured, m);
    constexpr int P = Nlarx5::num_params;
    nlid::detail::NlarxSimulationProblem<Nlarx5, P> fast(m, segs, {}, nlid::InitialCondition::measured, 1e6);
    const Eigen::Index n = fast.num_residuals();
    Eigen::VectorXd r(n);
    nlid::JacobianMatrix<P> J(n, P);
    const Eigen::Matrix<double, P, 1> th = theta;
    REQUIRE(fast.evaluate(th, r, &J));
    nlid_test::check_central_differences(fast, th, J, 1e-6);
  }
}

TEST_CASE("a custom regressor nonlinear in past outputs enters the sensitivity through its derivative",
          "[models][sensitivity]") {
  // y(t−1)² as a regressor: ∂φ/∂ŷ(t−1) = 2ŷ(t−1), which a plain lag selection would miss.
  auto square = nlid::custom_regressor<nlid::OutputLag<1>>("", [](auto y1) { return y1 * y1; });
  nlid::RegressorSet regs{nlid::LaggedRegressors<2, 2, 1>{}, square};
  using Model = nlid::Nlarx<decltype(regs), nlid::SigmoidNet<5, 2>>;
  Model m(regs, nlid::SigmoidNet<5, 2>{});
  Eigen::VectorXd th = Eigen::VectorXd::Constant(Model::num_params, 0.05);
  th.head(5) << 0.4, 0.1, 0.5, 0.2, -0.1;
  m.set_parameters(th);
  const Eigen::MatrixXd u = test_input(300, 9);
  Eigen::VectorXd y(300);
  REQUIRE(m.simulate<double>(u, nlid::detail::as_const_span(th), {}, nlid::detail::as_span(y)));
  y.array() += 0.01;
  std::vector<nlid::detail::EstimationSegment> segs(1);
  segs[0].u = &u;
  segs[0].y = y;
  constexpr int P = Model::num_params;
  nlid::detail::NlarxSimulationProblem<Model, P> fast(m, segs, {}, nlid::InitialCondition::zero, 1e6);
  nlid::AutoDiffProblem<nlid::detail::SimulationResiduals<Model, P>> ad(
      nlid::detail::SimulationResiduals<Model, P>(m, segs, {}, nlid::InitialCondition::zero, 1e6));
  Eigen::VectorXd r1(300), r2(300);
  nlid::JacobianMatrix<P> J1(300, P), J2(300, P);
  const Eigen::Matrix<double, P, 1> t = th;
  REQUIRE(fast.evaluate(t, r1, &J1));
  REQUIRE(ad.evaluate(t, r2, &J2));
  CHECK(rel_diff(r1, r2) < 1e-13);
  CHECK(rel_diff(J2, J1) < 1e-11);
}

TEST_CASE("estimation through the structured Jacobian reaches the forward-AD result", "[models][sensitivity]") {
  const Nlarx5 truth = make_model(7);
  nlid::Dataset data;
  for (unsigned e = 0; e < 2; ++e) {
    const Eigen::MatrixXd u = test_input(500, 20 + e);
    const Eigen::MatrixXd y = truth.simulate(nlid::Experiment(u, Eigen::MatrixXd::Zero(500, 1), 0.01));
    data.add(nlid::Experiment(u, y, 0.01));
  }
  nlid::EstimateOptions o;
  o.focus = nlid::Focus::simulation;
  o.solver.max_iterations = 15;
  const Nlarx5 a = nlid::estimate(Nlarx5{}, data, o);
  o.structured_jacobian = false;
  const Nlarx5 b = nlid::estimate(Nlarx5{}, data, o);
  INFO("structured " << a.report().final_cost << ", AD " << b.report().final_cost);
  CHECK(a.report().iterations == b.report().iterations);
  CHECK(std::abs(a.report().final_cost - b.report().final_cost) <= 1e-6 * (1.0 + b.report().final_cost));
  CHECK(a.report().final_cost < 0.5 * a.report().initial_cost);
  CHECK(a.report().fit_percent[0] > 95.0);
}

TEST_CASE("the structured Jacobian refuses an equilibrium initial condition", "[models][sensitivity]") {
  const Nlarx5 m = make_model(1);
  const Eigen::MatrixXd u = test_input(50, 1);
  std::vector<nlid::detail::EstimationSegment> segs(1);
  segs[0].u = &u;
  segs[0].y = Eigen::VectorXd::Zero(50);
  using Pb = nlid::detail::NlarxSimulationProblem<Nlarx5, Nlarx5::num_params>;
  CHECK_THROWS_WITH(Pb(m, segs, {}, nlid::InitialCondition::equilibrium, 1e6), Catch::Contains("initial conditions"));
  CHECK_THROWS_WITH(Pb(m, segs, {4}, nlid::InitialCondition::estimate, 1e6), Catch::Contains("not a past output"));
}
