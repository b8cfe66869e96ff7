// Runtime-chosen physics: the registry, exact equality with the compile-time models, and the
// extension path the missing-physics diagnosis relies on (a baseline wrapped with an effect).
#include <catch2/catch.hpp>

#include <cmath>
#include <limits>
#include <memory>

#include "nlid/models/greybox_dynamic.hpp"
#include "nlid/models/greybox_estimate.hpp"
#include "test_data.hpp"
#include "../support/with_coulomb.hpp"

using nlid::Dataset;
using nlid::GreyBox;
using nlid::InitialCondition;
namespace physics = nlid::physics;

namespace {

using nlid_test::WithCoulomb;

template <class Static>
void check_runtime_equals_static(const char* name, const Eigen::VectorXd& p, const Eigen::MatrixXd& u,
                                 double ts, const Eigen::VectorXd& x0) {
  INFO(name);
  GreyBox<Static> s;
  s.set_parameters(p);
  nlid::DynamicGreyBox d = nlid::make_greybox(name);
  d.set_parameters(p);
  CHECK(d.name() == name);
  CHECK(d.parameter_names() == s.parameter_names());
  const Eigen::MatrixXd ys = s.simulate(u, ts, x0), yd = d.simulate(u, ts, x0);
  CHECK((ys - yd).cwiseAbs().maxCoeff() <= 1e-12 * (1.0 + ys.cwiseAbs().maxCoeff()));
  // Jacobians: one Dual<double, n_p + n_x> pass vs chunks of Dual<double, 8>.
  const Dataset data(nlid::Experiment(u, ys, ts, "sim"));
  nlid::GreyBoxProblem<Static> ps(s.physics(), s.integrator(), data, InitialCondition::estimate);
  nlid::GreyBoxProblem<nlid::AnyPhysics> pd(d.physics(), d.integrator(), data, InitialCondition::estimate);
  REQUIRE(ps.num_parameters() == pd.num_parameters());
  Eigen::VectorXd th(ps.num_parameters());
  th << p * 0.97, x0;
  Eigen::VectorXd rs(ps.num_residuals()), rd(pd.num_residuals());
  Eigen::MatrixXd Js(rs.size(), th.size()), Jd(rd.size(), th.size());
  REQUIRE(ps.evaluate(th, rs, &Js));
  REQUIRE(pd.evaluate(th, rd, &Jd));
  CHECK((rs - rd).cwiseAbs().maxCoeff() <= 1e-12);
  CHECK((Js - Jd).cwiseAbs().maxCoeff() <= 1e-12 * (1.0 + Js.cwiseAbs().maxCoeff()));
}

// A stiff first-order system written by hand, without spectral_radius.
class Stiff final : public nlid::RuntimePhysicsBase<Stiff> {
 public:
  std::string name() const override { return "stiff"; }
  int state_dimension() const override { return 1; }
  int input_dimension() const override { return 1; }
  int output_dimension() const override { return 1; }
  int num_parameters() const override { return 1; }
  std::vector<nlid::ParameterInfo> parameter_info() const override {
    return {{"a", "1/s", "pole", 1000.0, 0.0, 1e9}};
  }
  template <class T>
  void compute_derivative(const T* x, const T* u, const T* p, T* dx) const {
    dx[0] = p[0] * (u[0] - x[0]);
  }
  template <class T>
  void compute_output(const T* x, const T*, const T*, T* y) const {
    y[0] = x[0];
  }
};

}  // namespace

TEST_CASE("The registry knows the catalogue by name", "[greybox][dynamic]") {
  const auto names = nlid::physics_names();
  for (const char* n : {"throttle", "mass_spring_damper", "rigid_body", "first_order", "two_tank"}) {
    CHECK(std::find(names.begin(), names.end(), n) != names.end());
  }
  const nlid::AnyPhysics p = nlid::make_physics("throttle");
  CHECK(p.num_parameters() == 7);
  CHECK(p.state_dimension() == 2);
  CHECK(p.parameter_info()[5].name == "upper_stop");
}

TEST_CASE("The runtime throttle refuses crossed stops like the compile-time one", "[greybox][dynamic][errors]") {
  nlid::DynamicGreyBox d = nlid::make_greybox("throttle");
  Eigen::VectorXd p = d.parameters();
  p[4] = 2.0;
  CHECK_THROWS_WITH(d.set_parameters(p), Catch::Contains("lower_stop = 2 must be below upper_stop = 1"));
  p[5] = 3.0;
  CHECK_NOTHROW(d.set_parameters(p));
}

TEST_CASE("Unknown physics names are reported with the known ones", "[greybox][dynamic][errors]") {
  try {
    (void)nlid::make_physics("trottle");
    FAIL("no throw");
  } catch (const nlid::Error& e) {
    CHECK_THAT(e.what(), Catch::Contains("unknown physics 'trottle'; known physics: first_order, "
                                         "mass_spring_damper, rigid_body, throttle, two_tank"));
    CHECK_THAT(e.what(), Catch::Contains("parameter 'physics'"));  // the argument, not the typo
  }
  CHECK_THROWS_WITH(nlid::AnyPhysics(nullptr), Catch::Contains("null physics"));
  CHECK_THROWS_WITH(nlid::register_physics("throttle", [] {
                      return std::make_shared<const nlid::PhysicsAdapter<physics::Throttle>>();
                    }),
                    Catch::Contains("already registered"));
}

TEST_CASE("Runtime-chosen models equal compile-time models to 1e-12", "[greybox][dynamic]") {
  const Eigen::MatrixXd u = nlid_test::steps({0.3, 0.9, -0.2, 0.6}, 40, 160);
  Eigen::VectorXd p7(7), p4(4), p3(3), pt(4);
  p7 << 30.0, 400.0, 1e5, 56000.0, 15.0, 90.0, 0.0;
  check_runtime_equals_static<physics::Throttle>("throttle", p7, u, 0.01, Eigen::Vector2d(20.0, 1.0));
  p4 << 8.0, 150.0, 300.0, 0.2;
  check_runtime_equals_static<physics::MassSpringDamper>("mass_spring_damper", p4, u, 0.01,
                                                         Eigen::Vector2d(0.1, 0.0));
  p3 << 2.0, 5.0, 0.1;
  check_runtime_equals_static<physics::RigidBody>("rigid_body", p3, u, 0.01, Eigen::Vector2d(1.0, 0.5));
  check_runtime_equals_static<physics::FirstOrder>("first_order", Eigen::Vector3d(0.5, 2.0, 1.0), u,
                                                   0.05, Eigen::VectorXd::Constant(1, 0.3));
  pt << 0.5, 0.3, 0.4, 0.0;
  check_runtime_equals_static<physics::TwoTank>("two_tank", pt, u.cwiseAbs() * 2.0, 0.5,
                                                Eigen::Vector2d(1.0, 0.8));
}

TEST_CASE("Runtime physics: Jacobian passes in lockstep pairs, in chunks of 8 columns, bit for bit",
          "[greybox][dynamic][jacobian]") {
  // 7 parameters + 2 initial states = 9 columns: two chunk passes of RuntimeDual per pair.
  nlid::DynamicGreyBox d = nlid::make_greybox("throttle");
  Eigen::VectorXd p7(7);
  p7 << 30.0, 400.0, 1e5, 56000.0, 15.0, 90.0, 0.0;
  d.set_parameters(p7);
  Dataset data;
  const Eigen::MatrixXd ua = nlid_test::steps({0.3, 0.9, -0.2, 0.6}, 40, 160);
  const Eigen::MatrixXd ub = nlid_test::steps({0.7, 0.1}, 30, 130);
  data.add(nlid::Experiment(ua, d.simulate(ua, 0.01, Eigen::Vector2d(20.0, 1.0)), 0.01, "a"));
  data.add(nlid::Experiment(ub, d.simulate(ub, 0.01, Eigen::Vector2d(40.0, 0.0)), 0.01, "b"));
  nlid::GreyBoxProblem<nlid::AnyPhysics> pb(d.physics(), d.integrator(), data, InitialCondition::estimate);
  Eigen::VectorXd th(pb.num_parameters());
  th << p7 * 0.97, 21.0, 0.5, 38.0, 0.2;
  nlid_test::check_lockstep_jacobians(pb, th);
}

TEST_CASE("A runtime model estimates like its compile-time twin", "[greybox][dynamic][estimate]") {
  GreyBox<physics::MassSpringDamper> truth;
  truth.set_parameters(Eigen::Vector4d(8.0, 150.0, 3000.0, 40.0));
  const Dataset d(nlid_test::simulated(truth, nlid_test::steps({0.0, 1.0, -0.5, 0.5}, 60, 360), 0.01,
                                       Eigen::Vector2d(40.0, 0.0), 0.05, 21, "msd"));
  nlid::GreyBoxEstimateOptions o;
  o.multi_start.num_candidates = 8;
  o.multi_start.num_starts = 2;
  GreyBox<physics::MassSpringDamper> s;
  nlid::DynamicGreyBox r = nlid::make_greybox("mass_spring_damper");
  const auto es = estimate(s, d, o);
  const auto er = estimate(r, d, o);
  for (int i = 0; i < 4; ++i) CHECK(er.parameters[i] == Approx(es.parameters[i]).epsilon(1e-8));
  CHECK(er.fit(0, 0) == Approx(es.fit(0, 0)).epsilon(1e-8));
}

TEST_CASE("Augmenting a runtime baseline with an effect: Coulomb friction recovered",
          "[greybox][dynamic][estimate]") {
  const auto make = [] {
    return nlid::DynamicGreyBox(nlid::AnyPhysics(
        std::make_shared<const WithCoulomb>(nlid::make_physics("mass_spring_damper"))));
  };
  nlid::DynamicGreyBox truth = make();
  CHECK(truth.name() == "mass_spring_damper+coulomb_friction");
  Eigen::VectorXd p(5);
  p << 8.0, 150.0, 3000.0, 40.0, 60.0;  // Fc = 60 mm/s²
  truth.set_parameters(p);
  const Dataset d(nlid_test::simulated(truth, nlid_test::steps({0.0, 1.0, -0.5, 0.5, 0.2}, 60, 480),
                                       0.01, Eigen::Vector2d(40.0, 0.0), 0.05, 71, "msd+fc"));
  nlid::DynamicGreyBox m = make();
  nlid::GreyBoxEstimateOptions o;
  o.multi_start.num_candidates = 16;
  o.multi_start.num_starts = 4;
  const auto r = estimate(m, d, o);
  INFO(r.report());
  CHECK(m.parameter("Fc") == Approx(60.0).epsilon(0.03));
  CHECK(m.parameter("k") == Approx(150.0).epsilon(0.02));
  CHECK(r.fit(0, 0) > 99.0);
  // The augmentation is registrable by name like the catalogue.
  nlid::register_physics("test_msd_coulomb", [] {
    return std::make_shared<const WithCoulomb>(nlid::make_physics("mass_spring_damper"));
  });
  CHECK(nlid::make_greybox("test_msd_coulomb").num_parameters() == 5);
}

TEST_CASE("Runtime physics without a stiffness bound: Gershgorin sets the sub-steps",
          "[greybox][dynamic]") {
  nlid::DynamicGreyBox m{nlid::AnyPhysics(std::make_shared<const Stiff>())};
  CHECK(m.substeps(0.01) == 10);  // |∂f/∂x| = 1000 1/s, h = 10 ms
  const Eigen::MatrixXd y = m.simulate(nlid_test::steps({1.0}, 50, 50), 0.01, Eigen::VectorXd::Zero(1));
  CHECK(y(49, 0) == Approx(1.0).epsilon(1e-9));
}
