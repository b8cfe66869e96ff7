// Grey-box hot paths under EIGEN_RUNTIME_NO_MALLOC: a fixed-size physics simulates, and the
// simulation-error problem evaluates residuals and its exact Jacobian, without one heap
// allocation per sample or per evaluation (all buffers belong to the caller or the stack).
#include <catch2/catch.hpp>

#include <array>

#include "nlid/models/greybox.hpp"
#include "nlid/models/greybox_problem.hpp"
#include "nlid/models/physics/catalogue.hpp"
#include "../support/unrated_pendulum.hpp"

namespace {
struct MallocGuard {
  MallocGuard() { Eigen::internal::set_is_malloc_allowed(false); }
  ~MallocGuard() { Eigen::internal::set_is_malloc_allowed(true); }
};
}  // namespace

TEST_CASE("Grey-box simulation and Jacobian allocate nothing", "[nomalloc][greybox]") {
  using nlid::physics::Throttle;
  nlid::GreyBox<Throttle> m;
  Eigen::Matrix<double, 7, 1> p;
  p << 30.0, 400.0, 1e5, 56000.0, 15.0, 90.0, 0.0;
  m.set_parameters(p);
  const double ts = 0.01;
  const int n = 400;
  Eigen::MatrixXd u(n, 1);
  for (int k = 0; k < n; ++k) u(k, 0) = (k / 50) % 3 == 0 ? 0.9 : ((k / 50) % 3 == 1 ? -0.2 : 0.4);
  const Eigen::MatrixXd y = m.simulate(u, ts, Eigen::Vector2d(15.0, 0.0));
  const nlid::Dataset data(nlid::Experiment(u, y, ts, "sim"));
  const nlid::GreyBoxProblem<Throttle> pb(m.physics(), m.integrator(), data,
                                          nlid::InitialCondition::estimate);
  // Two records of unequal length: residual-only evaluation runs them in lockstep
  // (simulate_physics_pair), then the longer one's tail alone.
  const Eigen::MatrixXd u2 = u.topRows(250);
  const nlid::Dataset data2{nlid::Experiment(u, y, ts, "sim"),
                            nlid::Experiment(u2, m.simulate(u2, ts, Eigen::Vector2d(15.0, 0.0)), ts, "short")};
  const nlid::GreyBoxProblem<Throttle> pb2(m.physics(), m.integrator(), data2, nlid::InitialCondition::zero);
  Eigen::VectorXd r2(pb2.num_residuals());
  const Eigen::VectorXd p_dyn = p;  // evaluate takes a VectorXd: convert before the guard
  Eigen::VectorXd theta(9);
  theta << p, 15.0, 0.0;
  Eigen::VectorXd r(pb.num_residuals());
  Eigen::MatrixXd J(pb.num_residuals(), 9);
  const int sub = m.substeps(ts);
  nlid::IntegratorOptions adaptive;
  adaptive.method = nlid::IntegratorMethod::dormand_prince;

  bool ok_r = false, ok_j = false, ok_pair = false;
  Eigen::Index got_d = 0, got_dual = 0, got_dp = 0;
  std::array<Eigen::Index, 2> got_pair{};
  double sum = 0.0;
  {
    MallocGuard guard;
    double x[2] = {15.0, 0.0};
    got_d = nlid::simulate_physics<double>(m.physics(), m.integrator(), sub, u, ts, p.data(), x,
                                           [&](Eigen::Index, const double* yk) { sum += yk[0]; });
    using D = nlid::Dual<double, 9>;
    Eigen::Matrix<D, 7, 1> pd;
    for (int i = 0; i < 7; ++i) pd[i] = D::variable(p[i], i);
    D xd[2] = {D::variable(15.0, 7), D::variable(0.0, 8)};
    got_dual = nlid::simulate_physics<D>(m.physics(), m.integrator(), sub, u, ts, pd.data(), xd,
                                         [&](Eigen::Index, const D* yk) { sum += yk[0].v[0]; });
    double xa[2] = {15.0, 0.0};
    got_dp = nlid::simulate_physics<double>(m.physics(), adaptive, sub, u, ts, p.data(), xa,
                                            [&](Eigen::Index, const double* yk) { sum += yk[0]; });
    ok_r = pb.evaluate(theta, r, nullptr);
    ok_j = pb.evaluate(theta, r, &J);
    double xb[2] = {15.0, 0.0}, xc[2] = {15.0, 0.0};
    got_pair = nlid::simulate_physics_pair(m.physics(), m.integrator(), sub, u, u2, ts, p.data(), xb, xc,
                                           [&](Eigen::Index, const double* yk) { sum += yk[0]; },
                                           [&](Eigen::Index, const double* yk) { sum += yk[0]; });
    ok_pair = pb2.evaluate(p_dyn, r2, nullptr);
  }
  CHECK(got_pair[0] == n);
  CHECK(got_pair[1] == 250);
  CHECK(ok_pair);
  CHECK(r2.norm() > 1.0);  // started from zero, not from the records' 15 degrees
  CHECK(got_d == n);
  CHECK(got_dual == n);
  CHECK(got_dp == n);
  CHECK(ok_r);
  CHECK(ok_j);
  CHECK(std::isfinite(sum));
  CHECK(r.cwiseAbs().maxCoeff() < 1e-9);  // exact parameters and initial state: zero residual
  CHECK(J.allFinite());
}

// nlid_test::UnratedPendulum has no spectral_radius: the sub-step rule takes the Gershgorin
// bound along each run (physics_substeps), a double pass with a Jacobian per sample — on the
// stack too.
TEST_CASE("The sub-step rule along a run allocates nothing for a fixed-size physics", "[nomalloc][greybox]") {
  nlid::GreyBox<nlid_test::UnratedPendulum> m;
  const double ts = 0.2;
  const Eigen::MatrixXd u = Eigen::MatrixXd::Zero(300, 1);
  const Eigen::Vector2d x0(1.5, 0.0);
  const nlid::Dataset data(nlid::Experiment(u, m.simulate(u, ts, x0), ts, "swing"));
  const nlid::GreyBoxProblem<nlid_test::UnratedPendulum> pb(m.physics(), m.integrator(), data, nlid::InitialCondition::estimate);
  Eigen::VectorXd theta(5);
  theta << m.parameters(), x0;
  Eigen::VectorXd r(pb.num_residuals());
  Eigen::MatrixXd J(pb.num_residuals(), 5);
  const Eigen::VectorXd p = m.parameters();
  int sub = 0;
  bool ok_r = false, ok_j = false;
  {
    MallocGuard guard;
    sub = nlid::physics_substeps(m.physics(), m.integrator(), p.data(), x0.data(), u, ts);
    ok_r = pb.evaluate(theta, r, nullptr);
    ok_j = pb.evaluate(theta, r, &J);
  }
  CHECK(sub == 3);  // 1 at the start (horizontal), 3 at the bottom of the swing
  CHECK(ok_r);
  CHECK(ok_j);
  CHECK(r.cwiseAbs().maxCoeff() < 1e-12);
  CHECK(J.allFinite());
}
