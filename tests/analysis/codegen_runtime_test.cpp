// Generated C for models built at run time: a user's run-time physics (derived from
// RuntimePhysicsBase, so it evaluates on TraceScalar as on double and Dual) inside
// GreyBox<AnyPhysics> is exported, compiled and run to 1e-12 of GreyBox::simulate; a run-time
// physics that implements only the double/Dual overloads is refused by name.
#include <catch2/catch.hpp>

#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "nlid/codegen/greybox.hpp"
#include "nlid/models/greybox_dynamic.hpp"

#include "../support/generated_c.hpp"
#include "../support/with_coulomb.hpp"

using namespace nlid;

namespace {

// A run-time physics written against the virtual interface only (no TraceScalar overloads).
class DoubleOnly final : public RuntimePhysics {
 public:
  std::string name() const override { return "double_only"; }
  int state_dimension() const override { return 1; }
  int input_dimension() const override { return 1; }
  int output_dimension() const override { return 1; }
  int num_parameters() const override { return 1; }
  std::vector<ParameterInfo> parameter_info() const override {
    return {{"a", "1/s", "rate", 1.0, 0.0, 10.0, 0.1, 10.0, false, false}};
  }
  void derivative(const double* x, const double* u, const double* p, double* dx) const override { dx[0] = p[0] * (u[0] - x[0]); }
  void derivative(const RuntimeDual* x, const RuntimeDual* u, const RuntimeDual* p, RuntimeDual* dx) const override {
    dx[0] = p[0] * (u[0] - x[0]);
  }
  void output(const double* x, const double*, const double*, double* y) const override { y[0] = x[0]; }
  void output(const RuntimeDual* x, const RuntimeDual*, const RuntimeDual*, RuntimeDual* y) const override { y[0] = x[0]; }
  using RuntimePhysics::derivative;
  using RuntimePhysics::output;
};

Eigen::MatrixXd steps(int n) {
  Eigen::MatrixXd u(n, 1);
  for (int k = 0; k < n; ++k) u(k, 0) = (k / 60) % 2 ? 1.0 : -0.5;
  return u;
}

}  // namespace

TEST_CASE("codegen: a user's run-time physics in GreyBox<AnyPhysics> is exported exactly", "[analysis][codegen]") {
  const DynamicGreyBox model(AnyPhysics(std::make_shared<const nlid_test::WithCoulomb>(make_physics("mass_spring_damper"))));
  const Eigen::MatrixXd u = steps(800);
  const double ts = 0.01;
  CodegenOptions o;
  o.name = "user_grey";
  o.ts = ts;
  const GeneratedCode g = generate_c(model, o);
  CHECK(g.source.find("tanh(") != std::string::npos);
  const Eigen::VectorXd yc = nlid_test::run_generated_c(g, u, "user_grey");
  const Eigen::VectorXd yn = model.simulate(u, ts, Eigen::VectorXd::Zero(model.state_dimension())).col(0);
  REQUIRE(yc.size() == yn.size());
  CHECK(nlid_test::max_relative_error(yc, yn) <= 1e-12);
  // The friction acts: without it the trajectory differs.
  const DynamicGreyBox bare(make_physics("mass_spring_damper"));
  CHECK(nlid_test::max_relative_error(bare.simulate(u, ts, Eigen::VectorXd::Zero(2)).col(0), yn) > 1e-3);
}

TEST_CASE("codegen: a run-time physics without TraceScalar overloads is refused by name", "[analysis][codegen]") {
  const DynamicGreyBox model(AnyPhysics(std::make_shared<const DoubleOnly>()));
  CodegenOptions o;
  o.ts = 0.01;
  try {
    (void)generate_c(model, o);
    FAIL("an untraceable physics was generated");
  } catch (const Error& err) {
    CHECK_THAT(err.what(), Catch::Contains("grey-box physics 'double_only' cannot be traced") &&
                               Catch::Contains("RuntimePhysicsBase"));
  }
}
