// The structured simulation Jacobian of Hammerstein-Wiener models
// (models/detail/hw_sensitivity.hpp) against forward AD through the whole chain
// (AutoDiffProblem<SimulationResiduals>) and central finite differences, and estimation through
// either Jacobian reaching the same model.
#include <catch2/catch.hpp>

#include <cmath>
#include <random>

#include "nlid/analysis/fit.hpp"
#include "jacobian_checks.hpp"
#include "nlid/models/estimate.hpp"
#include "nlid/models/hammerstein_wiener.hpp"
#include "nlid/nonlinearities/piecewise_linear.hpp"
#include "nlid/nonlinearities/saturation.hpp"

namespace {

using Hw = nlid::HammersteinWiener<nlid::PwLinear<5>, nlid::TransferFunctionBlock<3, 3, 0>, nlid::PwLinear<4>>;

Eigen::MatrixXd test_input(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> level(-1.0, 1.0);
  Eigen::MatrixXd u(n, 1);
  double v = 0.0;
  for (int t = 0; t < n; ++t) {
    if (t % 13 == 0) v = level(rng);
    u(t, 0) = v + 0.1 * std::sin(0.05 * t);
  }
  return u;
}

// A stable model with every breakpoint inside the signals' range, so every parameter matters.
Hw make_model() {
  Hw m;
  Eigen::VectorXd th(Hw::num_params);
  th << -0.8, std::log(0.4), std::log(0.4), std::log(0.4), std::log(0.4),  // input breakpoints
      -0.6, -0.35, 0.0, 0.5, 0.7,                                        // input values
      0.2, 0.1, 0.05, -0.9, 0.2, -0.02,                                  // B/F (poles inside)
      -1.0, std::log(0.7), std::log(0.7), std::log(0.7),                 // output breakpoints
      -0.9, -0.4, 0.3, 0.6;                                              // output values
  m.set_parameters(th);
  return m;
}

std::vector<nlid::detail::EstimationSegment> segments(const std::vector<Eigen::MatrixXd>& u,
                                                      const std::vector<Eigen::VectorXd>& y) {
  std::vector<nlid::detail::EstimationSegment> segs(u.size());
  for (std::size_t i = 0; i < u.size(); ++i) {
    segs[i].u = &u[i];
    segs[i].y = y[i];
  }
  return segs;
}

using nlid_test::rel_diff;

}  // namespace

TEST_CASE("structured Hammerstein-Wiener Jacobian equals forward AD and finite differences", "[models][sensitivity]") {
  constexpr int P = Hw::num_params;
  STATIC_REQUIRE(nlid::detail::HasStructuredHwJacobian<Hw>);
  const Hw m = make_model();
  std::vector<Eigen::MatrixXd> u{test_input(400, 1), test_input(300, 2)};
  std::vector<Eigen::VectorXd> y(2);
  for (std::size_t i = 0; i < 2; ++i) {
    y[i] = m.simulate(nlid::Experiment(u[i], Eigen::MatrixXd::Zero(u[i].rows(), 1), 0.01), nlid::InitialCondition::zero).col(0);
    for (Eigen::Index t = 0; t < y[i].size(); ++t) y[i](t) += 0.05 * std::sin(0.3 * t);  // not an exact fit
  }
  Eigen::Matrix<double, P, 1> th = m.parameters();
  th(2) += 0.1;    // a breakpoint spacing of the input map
  th(11) -= 0.03;  // b1
  th(21) += 0.05;  // an output value
  const auto segs = segments(u, y);
  nlid::detail::HwSimulationProblem<Hw, P> fast(m, segs, nlid::InitialCondition::zero, 1e6);
  nlid::AutoDiffProblem<nlid::detail::SimulationResiduals<Hw, P>> ad(
      nlid::detail::SimulationResiduals<Hw, P>(m, segs, {}, nlid::InitialCondition::zero, 1e6));
  REQUIRE(fast.num_residuals() == 700);
  REQUIRE(ad.num_residuals() == 700);
  const Eigen::Index n = fast.num_residuals();
  Eigen::VectorXd r1(n), r2(n), r3(n);
  nlid::JacobianMatrix<P> J1(n, P), J2(n, P);
  REQUIRE(fast.evaluate(th, r1, &J1));
  REQUIRE(ad.evaluate(th, r2, &J2));
  REQUIRE(fast.evaluate(th, r3, nullptr));

  SECTION("forward AD through the whole chain") {
    CHECK(rel_diff(r1, r2) < 1e-14);
    CHECK(rel_diff(r1, r3) < 1e-14);
    CHECK(rel_diff(J2, J1) < 1e-12);
    // Every column is exercised (breakpoints inside the signal ranges): none is all zero.
    for (int c = 0; c < P; ++c) {
      CAPTURE(c);
      CHECK(J1.col(c).cwiseAbs().maxCoeff() > 1e-4);
    }
  }

  SECTION("central finite differences") {
    // Piecewise-linear maps: a sample within h of a kink has a one-sided derivative, hence the
    // looser bound on the largest difference over all samples.
    nlid_test::check_central_differences(fast, th, J1, 1e-4);
  }

  SECTION("a fixed initial state of the linear block") {
    auto with_x0 = segs;
    for (auto& s : with_x0) s.x0 = Eigen::Vector3d(0.3, -0.1, 0.05);
    nlid::detail::HwSimulationProblem<Hw, P> f2(m, with_x0, nlid::InitialCondition::measured, 1e6);
    nlid::AutoDiffProblem<nlid::detail::SimulationResiduals<Hw, P>> a2(
        nlid::detail::SimulationResiduals<Hw, P>(m, with_x0, {}, nlid::InitialCondition::measured, 1e6));
    REQUIRE(f2.evaluate(th, r1, &J1));
    REQUIRE(a2.evaluate(th, r2, &J2));
    CHECK(rel_diff(r1, r2) < 1e-14);
    CHECK(rel_diff(J2, J1) < 1e-12);
    CHECK(rel_diff(r1, r3) > 1e-4);  // the state mattered
  }

  SECTION("unsupported initial conditions are refused by name") {
    CHECK_THROWS_WITH((nlid::detail::HwSimulationProblem<Hw, P>(m, segs, nlid::InitialCondition::estimate, 1e6)),
                      Catch::Contains("initial_condition"));
  }

  SECTION("a diverging simulation is reported, not returned as numbers") {
    Eigen::Matrix<double, P, 1> unstable = th;
    unstable(13) = -2.5;  // f1: a pole outside the unit circle
    CHECK_FALSE(fast.evaluate(unstable, r1, &J1));
  }
}

TEST_CASE("estimation through the structured or the forward-AD Jacobian reaches the same model",
          "[models][sensitivity]") {
  const Hw truth = make_model();
  const nlid::Dataset data{nlid::Experiment(test_input(600, 7), Eigen::MatrixXd::Zero(600, 1), 0.01),
                           nlid::Experiment(test_input(400, 8), Eigen::MatrixXd::Zero(400, 1), 0.01)};
  nlid::Dataset measured;
  for (const auto& e : data) measured.add(nlid::Experiment(e.u(), truth.simulate(e, nlid::InitialCondition::zero), 0.01));
  nlid::EstimateOptions o;
  o.initial_condition = nlid::InitialCondition::zero;
  o.solver.max_iterations = 40;
  const Hw a = nlid::estimate(Hw{}, measured, o);
  o.structured_jacobian = false;
  const Hw b = nlid::estimate(Hw{}, measured, o);
  INFO(a.report().status << " / " << b.report().status);
  CHECK(a.report().final_cost == Approx(b.report().final_cost).epsilon(1e-6));
  CHECK(a.report().iterations == b.report().iterations);
  for (const auto& e : measured) {
    const Eigen::VectorXd ya = a.simulate(e, nlid::InitialCondition::zero).col(0);
    CHECK(nlid::fit_percent(e.y().col(0), ya) > 95.0);
  }
}

TEST_CASE("Hammerstein-Wiener estimation damps uniformly (LmScaling::levenberg) unless told otherwise",
          "[models][sensitivity]") {
  const Hw truth = make_model();
  nlid::Dataset measured;
  for (unsigned seed : {3u, 4u}) {
    const nlid::Experiment e(test_input(500, seed), Eigen::MatrixXd::Zero(500, 1), 0.01);
    Eigen::MatrixXd y = truth.simulate(e, nlid::InitialCondition::zero);
    for (Eigen::Index t = 0; t < y.rows(); ++t) y(t, 0) += 0.02 * std::sin(0.7 * t);  // a misfit floor
    measured.add(nlid::Experiment(e.u(), y, 0.01));
  }
  auto cost_with = [&](nlid::LmScaling scaling, const Eigen::VectorXd& parameter_scale = {}) {
    nlid::EstimateOptions o;
    o.initial_condition = nlid::InitialCondition::zero;
    o.solver.max_iterations = 15;
    o.solver.scaling = scaling;
    o.solver.parameter_scale = parameter_scale;
    return nlid::estimate(Hw{}, measured, o).report().final_cost;
  };
  // Each parameter in its own units: those of the input (RMS) for f, of the output for h.
  Eigen::VectorXd u_all(1000), y_all(1000);
  u_all << measured[0].u().col(0), measured[1].u().col(0);
  y_all << measured[0].y().col(0), measured[1].y().col(0);
  const Eigen::VectorXd scales = nlid::detail::hw_parameter_scales(Hw{}, u_all, y_all);
  REQUIRE(scales.size() == Hw{}.num_parameters());
  const double automatic = cost_with(nlid::LmScaling::automatic);
  CHECK(automatic == cost_with(nlid::LmScaling::levenberg, scales));  // the same solve, bit for bit
  CHECK(automatic != cost_with(nlid::LmScaling::levenberg));
  CHECK(automatic != cost_with(nlid::LmScaling::running_max));
}
