// Generated C for the linear input/output models (codegen/linear.hpp): a two-input ARX and a
// two-input output-error model, with offsets and delays including nk = 0, are generated,
// compiled with the system C compiler (warnings are errors) and run; the outputs must equal
// `simulate` to 1e-12 relative from zero and from an equilibrium. A kind that is not generated
// (state space) is refused by name through the run-time entry point.
#include <catch2/catch.hpp>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "nlid/codegen/any_model.hpp"
#include "nlid/codegen/linear.hpp"
#include "nlid/linear/state_space.hpp"

#include "../support/scratch_dir.hpp"

namespace fs = std::filesystem;
using namespace nlid;

namespace {

// Two inputs per line in u.txt; the driver prints y per sample.
Eigen::VectorXd run_two_input(const GeneratedCode& g, const Eigen::MatrixXd& u, const std::string& tag) {
  const fs::path dir = nlid_test::scratch_dir() / ("lin_" + tag);
  fs::create_directories(dir);
  g.write(dir.string());
  const std::string n = g.name;
  std::ofstream(dir / "driver.c") << "#include <stdio.h>\n#include \"" << n << ".h\"\n"
                                  << "int main(int argc, char** argv) {\n  double u[2], y[1];\n  " << n << "_state s;\n"
                                  << "  FILE* in = argc > 1 ? fopen(argv[1], \"r\") : NULL;\n  if (!in) return 2;\n  " << n
                                  << "_init(&s);\n  while (fscanf(in, \"%lf %lf\", &u[0], &u[1]) == 2) {\n    " << n
                                  << "_step(&s, u, y);\n    printf(\"%.17g\\n\", y[0]);\n  }\n  fclose(in);\n  return 0;\n}\n";
  {
    std::ofstream in(dir / "u.txt");
    char b[80];
    for (Eigen::Index t = 0; t < u.rows(); ++t) {
      std::snprintf(b, sizeof b, "%.17g %.17g\n", u(t, 0), u(t, 1));
      in << b;
    }
  }
  const std::string exe = (dir / "driver").string();
  const std::string cmd = "cc -std=c99 -O2 -ffp-contract=off -Wall -Wextra -pedantic -Werror -o " + exe + " " +
                          (dir / "driver.c").string() + " " + (dir / (n + ".c")).string() + " -lm > " +
                          (dir / "cc.log").string() + " 2>&1";
  if (std::system(cmd.c_str()) != 0) {
    std::ifstream log(dir / "cc.log");
    std::stringstream ss;
    ss << log.rdbuf();
    FAIL("generated code does not compile:\n" << ss.str());
  }
  REQUIRE(std::system((exe + " " + (dir / "u.txt").string() + " > " + (dir / "y.txt").string()).c_str()) == 0);
  std::ifstream out(dir / "y.txt");
  std::vector<double> ys;
  for (double v; out >> v;) ys.push_back(v);
  return Eigen::Map<Eigen::VectorXd>(ys.data(), static_cast<Eigen::Index>(ys.size()));
}

Eigen::MatrixXd two_inputs(int n) {
  Eigen::MatrixXd u(n, 2);
  for (int k = 0; k < n; ++k) {
    u(k, 0) = (k / 37) % 2 ? 0.8 : -0.3 + 0.1 * std::sin(0.07 * k);
    u(k, 1) = std::cos(0.021 * k) + ((k / 53) % 3 == 0 ? 0.5 : 0.0);
  }
  return u;
}

double max_relative_error(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  return (a - b).cwiseAbs().maxCoeff() / std::max(1.0, b.cwiseAbs().maxCoeff());
}

template <class M>
void check_model(const M& model, const std::string& tag) {
  const Eigen::MatrixXd u = two_inputs(600);
  const Experiment e(u, Eigen::MatrixXd::Zero(u.rows(), 1), 0.05, "two");
  CodegenOptions o;
  o.name = "lin";
  const Eigen::VectorXd yc = run_two_input(generate_c(model, o), u, tag);
  const Eigen::VectorXd yn = model.simulate(e, InitialCondition::zero).col(0);
  REQUIRE(yc.size() == yn.size());
  CHECK(max_relative_error(yc, yn) <= 1e-12);
  o.name = "lin_eq";
  o.equilibrium_input = Eigen::Vector2d(u(0, 0), u(0, 1));
  const Eigen::VectorXd yce = run_two_input(generate_c(model, o), u, tag + "eq");
  const Eigen::VectorXd yne = model.simulate(e, InitialCondition::equilibrium).col(0);
  CHECK(max_relative_error(yce, yne) <= 1e-12);
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

TEST_CASE("codegen: a state-space model is refused by kind", "[analysis][codegen]") {
  const StateSpace ss(Eigen::MatrixXd::Constant(1, 1, 0.9), Eigen::MatrixXd::Constant(1, 1, 0.1),
                      Eigen::MatrixXd::Constant(1, 1, 1.0), Eigen::MatrixXd::Zero(1, 1), 0.05);
  try {
    (void)generate_c(AnyModel(ss));
    FAIL("a state-space model was generated");
  } catch (const Error& err) {
    CHECK_THAT(err.what(), Catch::Contains("models of kind 'state_space' are not generated") &&
                               Catch::Contains("arx, output_error"));
  }
}
