// Generated C for the linear input/output models (codegen/linear.hpp): a two-input ARX and a
// two-input output-error model, with offsets and delays including nk = 0, are generated,
// compiled with the system C compiler (warnings are errors) and run; the outputs must equal
// `simulate` to 1e-12 relative from zero and from an equilibrium. (A kind that is not generated,
// state space, is refused by name: tests/tools/nlid_codegen_test.cpp, through nlid-codegen.)
#include <catch2/catch.hpp>

#include <cmath>
#include <string>

#include "nlid/codegen/linear.hpp"

#include "../support/generated_c.hpp"

using namespace nlid;

namespace {

Eigen::MatrixXd two_inputs(int n) {
  Eigen::MatrixXd u(n, 2);
  for (int k = 0; k < n; ++k) {
    u(k, 0) = (k / 37) % 2 ? 0.8 : -0.3 + 0.1 * std::sin(0.07 * k);
    u(k, 1) = std::cos(0.021 * k) + ((k / 53) % 3 == 0 ? 0.5 : 0.0);
  }
  return u;
}

template <class M>
void check_model(const M& model, const std::string& tag) {
  const Eigen::MatrixXd u = two_inputs(600);
  const Experiment e(u, Eigen::MatrixXd::Zero(u.rows(), 1), 0.05, "two");
  CodegenOptions o;
  o.name = "lin";
  const Eigen::VectorXd yc = nlid_test::run_generated_c(generate_c(model, o), u, tag);
  const Eigen::VectorXd yn = model.simulate(e, InitialCondition::zero).col(0);
  REQUIRE(yc.size() == yn.size());
  CHECK(nlid_test::max_relative_error(yc, yn) <= 1e-12);
  o.name = "lin_eq";
  o.equilibrium_input = Eigen::Vector2d(u(0, 0), u(0, 1));
  const Eigen::VectorXd yce = nlid_test::run_generated_c(generate_c(model, o), u, tag + "eq");
  const Eigen::VectorXd yne = model.simulate(e, InitialCondition::equilibrium).col(0);
  CHECK(nlid_test::max_relative_error(yce, yne) <= 1e-12);
  CHECK(std::abs(yne(0) - yn(0)) > 1e-3);  // the equilibrium start differs from rest
}

}  // namespace

TEST_CASE("codegen: ARX and output-error models reproduce simulate to 1e-12", "[analysis][codegen]") {
  SECTION("ARX [2 (3 2) (1 0)] with offset") {
    const Arx arx(Eigen::Vector2d(-1.2, 0.45), {Eigen::Vector3d(0.3, 0.2, -0.05), Eigen::Vector2d(0.1, 0.15)}, {1, 0}, 0.05,
                  0.7);
    check_model(arx, "arx");
  }
  SECTION("OE [(2 1) (2 2) (1 0)] with offset") {
    const OutputError oe({Eigen::Vector2d(0.3, 0.2), Eigen::VectorXd::Constant(1, 0.4)},
                         {Eigen::Vector2d(-1.1, 0.3), Eigen::Vector2d(-0.6, 0.08)}, {1, 0}, 0.05, -0.25);
    check_model(oe, "oe");
  }
}
