// Runs generated C code the way a user deploys it: writes NAME.h/NAME.c and a driver that
// steps the model from NAME_init over the input rows, compiles both with the system C compiler
// (warnings are errors; -ffp-contract=off for nlid's roundings, docs/codegen.md) and returns the
// outputs. Shared by the code-generation tests. The driver works in NAME_real, so it runs
// double and single-precision code alike; single precision is compiled with
// -Wdouble-promotion -Wfloat-conversion as errors, which any double operation left in it trips.
#pragma once

#include <catch2/catch.hpp>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "c_text.hpp"
#include "nlid/codegen/emitter.hpp"
#include "scratch_dir.hpp"

namespace nlid_test {

/// Compiles `dir`/driver.c with `dir`/NAME.c (warnings are errors; single precision also with
/// -Wdouble-promotion -Wfloat-conversion) and runs it on `dir`/u.txt into `dir`/y.txt.
inline void compile_and_run_driver(const std::filesystem::path& dir, const std::string& n, bool single) {
  const std::string exe = (dir / "driver").string();
  const std::string cmd = std::string("cc -std=c99 -O2 -ffp-contract=off -Wall -Wextra -pedantic -Werror ") +
                          (single ? "-Wdouble-promotion -Wfloat-conversion " : "") + "-o \"" + exe + "\" \"" +
                          (dir / "driver.c").string() + "\" \"" + (dir / (n + ".c")).string() + "\" -lm > \"" +
                          (dir / "cc.log").string() + "\" 2>&1";
  if (std::system(cmd.c_str()) != 0) {
    std::ifstream log(dir / "cc.log");
    std::stringstream ss;
    ss << log.rdbuf();
    FAIL("generated code does not compile:\n" << ss.str());
  }
  REQUIRE(std::system(("\"" + exe + "\" \"" + (dir / "u.txt").string() + "\" > \"" + (dir / "y.txt").string() + "\"").c_str()) == 0);
}

/// Outputs (first output channel) of the generated model on the inputs `u` (N × n_u).
inline Eigen::VectorXd run_generated_c(const nlid::GeneratedCode& g, const Eigen::MatrixXd& u, const std::string& tag,
                                       bool single = false) {
  const std::filesystem::path dir = scratch_dir() / ("c_" + tag);
  std::filesystem::create_directories(dir);
  g.write(dir.string());
  const std::string n = g.name, nu = std::to_string(std::max<Eigen::Index>(u.cols(), 1));
  std::ofstream(dir / "driver.c") << "#include <stdio.h>\n#include \"" << n << ".h\"\n"
                                  << "int main(int argc, char** argv) {\n  " << n << "_real u[" << nu << "], y["
                                  << nlid::codegen::macro(n) << "_NUM_OUTPUTS];\n  double v;\n  int i;\n  " << n << "_state s;\n"
                                  << "  FILE* in = argc > 1 ? fopen(argv[1], \"r\") : NULL;\n  if (!in) return 2;\n  " << n
                                  << "_init(&s);\n  for (;;) {\n    for (i = 0; i < " << nu
                                  << "; ++i) {\n      if (fscanf(in, \"%lf\", &v) != 1) goto done;\n      u[i] = (" << n << "_real)v;\n    }\n    " << n
                                  << "_step(&s, u, y);\n    printf(\"%.17g\\n\", (double)y[0]);\n  }\ndone:\n  fclose(in);\n  return 0;\n}\n";
  {
    std::ofstream in(dir / "u.txt");
    char b[40];
    for (Eigen::Index t = 0; t < u.rows(); ++t)
      for (Eigen::Index j = 0; j < u.cols(); ++j) {
        std::snprintf(b, sizeof b, "%.17g\n", u(t, j));
        in << b;
      }
  }
  compile_and_run_driver(dir, n, single);
  std::ifstream out(dir / "y.txt");
  std::vector<double> ys;
  for (double v; out >> v;) ys.push_back(v);
  return Eigen::Map<Eigen::VectorXd>(ys.data(), static_cast<Eigen::Index>(ys.size()));
}

/// max |a − b| / max(1, max |b|).
inline double max_relative_error(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  return (a - b).cwiseAbs().maxCoeff() / std::max(1.0, b.cwiseAbs().maxCoeff());
}

/// Single-precision code of `m` (options `o`, name suffixed "_f32"): no double anywhere,
/// `NAME_real` is float, and its run on `u` is float rounding of nlid's double simulation `ref`
/// — within `tol` relative to max(1, max |ref|), but not bitwise equal.
template <class Model>
void check_single_precision(const Model& m, nlid::CodegenOptions o, const Eigen::MatrixXd& u, const Eigen::VectorXd& ref,
                            double tol) {
  o.name += "_f32";
  o.precision = nlid::codegen::Precision::single_precision;
  const nlid::GeneratedCode g = generate_c(m, o);
  CHECK(c_code_only(g.source + g.header).find("double") == std::string::npos);
  CHECK(g.header.find("typedef float " + o.name + "_real;") != std::string::npos);
  const Eigen::VectorXd yc = run_generated_c(g, u, o.name, true);
  REQUIRE(yc.size() == ref.size());
  const double gap = max_relative_error(yc, ref);
  INFO("single precision: max |y_C - y_nlid| / max(1, max |y_nlid|) = " << gap);
  CHECK(gap <= tol);
  CHECK(gap > 0.0);
}

}  // namespace nlid_test
