// nlid-codegen end to end, as a user deploying a model: nlid-fit saves a model, nlid-codegen
// writes C for it, the C is compiled with the system compiler (warnings are errors) and run on a
// recording's input; its outputs must equal nlid-sim's on the same file to 1e-12 relative (the
// generated code performs nlid's operations in nlid's order). Every model family the tool
// generates goes through this, from the zero state and from an equilibrium; the errors it
// promises (a grey box without --ts, bad options) are checked.
// Also here: the channel names and --decimate that make nlid-fit → nlid-sim work for every family.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "../support/c_text.hpp"
#include "nlid/core/atomic_file.hpp"
#include "nlid/io/json.hpp"
#include "nlid/io/json_eigen.hpp"
#include "tool_runner.hpp"

namespace fs = std::filesystem;
using tool_test::q;
using tool_test::fit;
using tool_test::sim;
using tool_test::codegen;
using tool_test::Run;
using tool_test::slurp;
using tool_test::work_dir;
using tool_test::write_record;
using tool_test::csv_column;

namespace {

// Compiles DIR/NAME.c with a driver that steps the model over the inputs in u.txt (one per
// line) from NAME_init and prints the outputs; returns them. The driver uses NAME_real, so it
// serves double and single-precision code; single precision is compiled with
// -Wdouble-promotion -Wfloat-conversion as errors, which a stray double operation would trip.
std::vector<double> run_generated(const fs::path& dir, const std::string& name, const std::vector<double>& u,
                                  bool single = false) {
  {
    std::ofstream f(dir / "u.txt");
    f.precision(17);
    for (double v : u) f << v << "\n";
  }
  {
    std::ofstream d(dir / (name + "_driver.c"));
    d << "#include <stdio.h>\n#include \"" << name << ".h\"\n"
      << "int main(int argc, char** argv) {\n"
      << "  " << name << "_state s;\n  " << name << "_real u[1], y[1];\n  double v;\n  FILE* f = fopen(argv[1], \"r\");\n"
      << "  (void)argc;\n  if (!f) return 1;\n  " << name << "_init(&s);\n"
      << "  while (fscanf(f, \"%lf\", &v) == 1) {\n    u[0] = (" << name << "_real)v;\n    " << name << "_step(&s, u, y);\n"
      << "    printf(\"%.17g\\n\", (double)y[0]);\n  }\n  fclose(f);\n  return 0;\n}\n";
  }
  const std::string exe = (dir / (name + "_run")).string();
  // -ffp-contract=off: the bitwise agreement needs the same roundings as nlid (docs/codegen.md).
  const std::string cmd = std::string("cc -std=c99 -O2 -ffp-contract=off -Wall -Wextra -pedantic -Werror ") +
                          (single ? "-Wdouble-promotion -Wfloat-conversion " : "") + "-o \"" + exe + "\" \"" +
                          (dir / (name + "_driver.c")).string() + "\" \"" + (dir / (name + ".c")).string() + "\" -lm 2>\"" +
                          (dir / "cc.txt").string() + "\"";
  if (std::system(cmd.c_str()) != 0) FAIL("generated code does not compile:\n" << slurp(dir / "cc.txt"));
  REQUIRE(std::system(("\"" + exe + "\" \"" + (dir / "u.txt").string() + "\" > \"" + (dir / "y.txt").string() + "\"").c_str()) == 0);
  std::vector<double> y;
  std::ifstream f(dir / "y.txt");
  for (double v; f >> v;) y.push_back(v);
  return y;
}

double max_relative_gap(const std::vector<double>& a, const std::vector<double>& b) {
  double gap = 0, scale = 1;
  for (std::size_t k = 0; k < std::min(a.size(), b.size()); ++k) {
    gap = std::max(gap, std::abs(a[k] - b[k]));
    scale = std::max(scale, std::abs(b[k]));
  }
  return gap / scale;
}

// <math.h> for a bare-metal target, which has no C library: C99's declarations, double and float,
// as newlib's and every other libm's read. A function the generated code calls but this list
// lacks fails the compile (implicit declaration, -Werror), naming it.
const char* const bare_metal_math_h = R"(#ifndef NLID_TEST_BARE_METAL_MATH_H
#define NLID_TEST_BARE_METAL_MATH_H
#define HUGE_VAL (__builtin_huge_val())
#define HUGE_VALF (__builtin_huge_valf())
#define INFINITY (__builtin_inff())
#define NAN (__builtin_nanf(""))
#define isfinite(x) __builtin_isfinite(x)
#define isinf(x) __builtin_isinf(x)
#define isnan(x) __builtin_isnan(x)
#define signbit(x) __builtin_signbit(x)
#define NLID_MATH_1(n) double n(double); float n##f(float);
#define NLID_MATH_2(n) double n(double, double); float n##f(float, float);
NLID_MATH_1(acos) NLID_MATH_1(asin) NLID_MATH_1(atan) NLID_MATH_2(atan2) NLID_MATH_1(cos) NLID_MATH_1(sin)
NLID_MATH_1(tan) NLID_MATH_1(acosh) NLID_MATH_1(asinh) NLID_MATH_1(atanh) NLID_MATH_1(cosh) NLID_MATH_1(sinh)
NLID_MATH_1(tanh) NLID_MATH_1(exp) NLID_MATH_1(exp2) NLID_MATH_1(expm1) NLID_MATH_1(log) NLID_MATH_1(log10)
NLID_MATH_1(log1p) NLID_MATH_1(log2) NLID_MATH_1(logb) NLID_MATH_1(cbrt) NLID_MATH_1(fabs) NLID_MATH_2(hypot)
NLID_MATH_2(pow) NLID_MATH_1(sqrt) NLID_MATH_1(erf) NLID_MATH_1(erfc) NLID_MATH_1(lgamma) NLID_MATH_1(tgamma)
NLID_MATH_1(ceil) NLID_MATH_1(floor) NLID_MATH_1(nearbyint) NLID_MATH_1(rint) NLID_MATH_1(round)
NLID_MATH_1(trunc) NLID_MATH_2(fmod) NLID_MATH_2(remainder) NLID_MATH_2(copysign) NLID_MATH_2(nextafter)
NLID_MATH_2(fdim) NLID_MATH_2(fmax) NLID_MATH_2(fmin)
double fma(double, double, double); float fmaf(float, float, float);
double ldexp(double, int); float ldexpf(float, int);
#undef NLID_MATH_1
#undef NLID_MATH_2
#endif
)";

// The symbols DIR/NAME.c needs from libraries when compiled for a Cortex-M4F (single-precision
// FPU only) by clang's ARM back end: double arithmetic there is a call of the soft-float
// routines __aeabi_dadd, __aeabi_dmul, ... (binutils' nm reads the ARM object). A cross
// toolchain with newlib (gcc-arm-none-eabi) would do the same, at 800 MB of install in every CI
// run. Empty optional without clang.
std::optional<std::string> cortex_m4f_imports(const fs::path& dir, const std::string& name) {
  if (std::system("command -v clang >/dev/null 2>&1 && command -v nm >/dev/null 2>&1") != 0) return std::nullopt;
  const fs::path include = dir / "bare_metal_include";
  fs::create_directories(include);
  nlid::write_file_atomically((include / "math.h").string(), bare_metal_math_h);
  const std::string obj = (dir / (name + "_m4.o")).string();
  const std::string cmd = "clang --target=arm-none-eabi -mcpu=cortex-m4 -mthumb -mfpu=fpv4-sp-d16 -mfloat-abi=hard "
                          "-ffreestanding -std=c99 -O2 -Wall -Wextra -pedantic -Werror -I\"" + include.string() +
                          "\" -c -o \"" + obj + "\" \"" + (dir / (name + ".c")).string() + "\" 2>\"" +
                          (dir / "arm.txt").string() + "\"";
  if (std::system(cmd.c_str()) != 0) FAIL("generated code does not compile for Cortex-M4F:\n" << slurp(dir / "arm.txt"));
  REQUIRE(std::system(("nm -u \"" + obj + "\" > \"" + (dir / "imports.txt").string() + "\"").c_str()) == 0);
  return slurp(dir / "imports.txt");
}

// The values of NAME_x0 in a generated source ("static const double NAME_x0[n] = {a, (-b)};").
std::vector<double> x0_values(const std::string& source, const std::string& name) {
  const std::size_t at = source.find(name + "_x0[");
  REQUIRE(at != std::string::npos);
  const std::size_t open = source.find('{', at), close = source.find('}', at);
  REQUIRE(open < close);
  std::vector<double> v;
  std::string item;
  std::stringstream list(source.substr(open + 1, close - open - 1));
  while (std::getline(list, item, ',')) {
    std::erase_if(item, [](char c) { return c == '(' || c == ')'; });  // negative literals are parenthesized
    v.push_back(std::strtod(item.c_str(), nullptr));
  }
  return v;
}

// "a,b,c" with 17 significant digits (read back exactly).
std::string number_list(const std::vector<double>& v) {
  std::string s;
  char b[40];
  for (std::size_t i = 0; i < v.size(); ++i) {
    std::snprintf(b, sizeof b, "%s%.17g", i ? "," : "", v[i]);
    s += b;
  }
  return s;
}

bool pure_ascii(const std::string& s) {
  return std::all_of(s.begin(), s.end(), [](char c) { return static_cast<unsigned char>(c) < 0x80; });
}

}  // namespace

TEST_CASE("nlid-codegen: C from nlid-fit's model files reproduces nlid-sim for every generated family",
          "[tools][codegen]") {
  const fs::path est = write_record("cg_est", 1200, 71u, 1), val = write_record("cg_val", 600, 72u, 1);
  const std::vector<double> u = csv_column(val, 1);
  struct Case {
    const char* name;
    const char* spec;
    const char* codegen_options;
  };
  // Small structures and few iterations: the point is the code, not the fit. treepartition
  // branches on the regressors (its leaf choice becomes if/else on signals); the grey box is
  // continuous and needs --ts.
  const Case cases[] = {
      {"cg_sigmoid", "nlarx:na=2,nb=2,nk=1:sigmoidnet:units=3", ""},
      {"cg_tree", "nlarx:na=1,nb=1,nk=1:treepartition:depth=2", ""},
      {"cg_hw", "hw:nb=2,nf=2,nk=1:in=pwlinear:4:out=saturation", ""},
      {"cg_wh", "wh:nb=2,nf=1,nk=1:poly1d:3:nb=1,nf=1,nk=0", ""},
      {"cg_grey", "greybox:first_order", "--ts 0.01"},
      {"cg_arx", "linear:arx:na=2,nb=2,nk=1", ""},
      {"cg_oe", "linear:oe:nb=2,nf=2,nk=1", ""},
  };
  for (const Case& c : cases) {
    DYNAMIC_SECTION(c.spec) {
      const fs::path dir = work_dir() / c.name;
      fs::create_directories(dir);
      const fs::path model = dir / (std::string(c.name) + ".json");
      const Run f = fit("--model " + std::string(c.spec) + " --est " + q(est) + " --iterations 4 --save " + q(model));
      INFO(f.err);
      REQUIRE(f.code == 0);

      // From the zero state: nlid-sim --x0 zero.
      const Run g = codegen("--model " + q(model) + " --out " + q(dir) + " " + c.codegen_options);
      INFO(g.err);
      REQUIRE(g.code == 0);
      CHECK_THAT(g.out, Catch::Contains(std::string(c.name) + ".c"));
      const std::string header = slurp(dir / (std::string(c.name) + ".h")), source = slurp(dir / (std::string(c.name) + ".c"));
      CHECK(pure_ascii(header));
      CHECK(pure_ascii(source));
      const fs::path simulated = dir / "sim.csv";
      const Run s = sim("--model " + q(model) + " --input " + q(val) + " --out " + q(simulated));
      INFO(s.err);
      REQUIRE(s.code == 0);
      const std::vector<double> y_nlid = csv_column(simulated, 1);
      const std::vector<double> y_c = run_generated(dir, c.name, u);
      REQUIRE(y_c.size() == y_nlid.size());
      CHECK(max_relative_gap(y_c, y_nlid) <= 1e-12);

      // From the equilibrium of the record's first input: nlid-sim --x0 equilibrium. (That input,
      // 0.995, lies beyond the estimation record's inputs, so nlid-codegen needs the switch.)
      char u0[64];
      std::snprintf(u0, sizeof u0, "%.17g", u[0]);
      const Run ge = codegen("--model " + q(model) + " --out " + q(dir) + " --name eq_model --x0 equilibrium --u0 " + u0 +
                             " --allow-extrapolation " + c.codegen_options);
      INFO(ge.err);
      REQUIRE(ge.code == 0);
      const Run se = sim("--model " + q(model) + " --input " + q(val) + " --x0 equilibrium --out " + q(simulated));
      INFO(se.err);
      REQUIRE(se.code == 0);
      const std::vector<double> ye_nlid = csv_column(simulated, 1), ye_c = run_generated(dir, "eq_model", u);
      REQUIRE(ye_c.size() == ye_nlid.size());
      CHECK(max_relative_gap(ye_c, ye_nlid) <= 1e-12);
      // Started in equilibrium, the first output is the steady output, not the zero-state one.
      CHECK(std::abs(ye_c[0] - y_c[0]) > 1e-6);

      // --x0 X1,X2,..: that equilibrium's state in nlid's layout (double code keeps it: read back
      // from eq_model.c) is the same start, so the same NAME_x0 and the same run; in single
      // precision it is mapped as --x0 equilibrium maps its own (the delta state of linear blocks).
      const std::vector<double> x_eq = x0_values(slurp(dir / "eq_model.c"), "eq_model");
      const Run gx = codegen("--model " + q(model) + " --out " + q(dir) + " --name x_model --x0 " + number_list(x_eq) + " " +
                             c.codegen_options);
      INFO(gx.err);
      REQUIRE(gx.code == 0);
      CHECK(x0_values(slurp(dir / "x_model.c"), "x_model") == x_eq);
      CHECK(run_generated(dir, "x_model", u) == ye_c);
      REQUIRE(codegen("--model " + q(model) + " --out " + q(dir) + " --name xs_model --precision single --x0 " +
                      number_list(x_eq) + " " + c.codegen_options).code == 0);
      REQUIRE(codegen("--model " + q(model) + " --out " + q(dir) + " --name es_model --precision single --x0 equilibrium --u0 " +
                      u0 + " --allow-extrapolation " + c.codegen_options).code == 0);
      CHECK(x0_values(slurp(dir / "xs_model.c"), "xs_model") == x0_values(slurp(dir / "es_model.c"), "es_model"));
      std::vector<double> x_short(x_eq.begin(), x_eq.end() - 1);
      x_short.push_back(0.0);
      x_short.push_back(0.0);  // one value too many
      const Run bad = codegen("--model " + q(model) + " --out " + q(dir) + " --name x_bad --x0 " + number_list(x_short) + " " +
                              c.codegen_options);
      CHECK(bad.code == 1);
      CHECK_THAT(bad.err, Catch::Contains("has " + std::to_string(x_short.size()) + " values, the model's state has " +
                                          std::to_string(x_eq.size())) &&
                              Catch::Contains("parameter '--x0'"));

      // Single precision: no double in the code, float rounding of the same model.
      const Run gs = codegen("--model " + q(model) + " --out " + q(dir) + " --name sp_model --precision single " +
                             c.codegen_options);
      INFO(gs.err);
      REQUIRE(gs.code == 0);
      CHECK_THAT(gs.err, Catch::Contains("single precision"));
      const std::string sp_code = nlid_test::c_code_only(slurp(dir / "sp_model.c") + slurp(dir / "sp_model.h"));
      CHECK(sp_code.find("double") == std::string::npos);
      CHECK(sp_code.find("float") != std::string::npos);
      const std::vector<double> ys_c = run_generated(dir, "sp_model", u, true);
      REQUIRE(ys_c.size() == y_nlid.size());
      const double gap = max_relative_gap(ys_c, y_nlid);
      INFO("single precision: max |y_C - y_nlid| / max(1, max |y_nlid|) = " << gap);
      // Float keeps about 7 digits and a free run amplifies rounding by its own sensitivity:
      // measured 1.6e-7 ... 1.5e-6 here (the barely estimated output-error model 1.8e-7 in delta
      // form, 1.3e-4 in the direct form it had before).
      CHECK(gap <= 1e-3);
      CHECK(gap > 0.0);  // float rounding shows: the code did compute in float
      // Linear blocks of HW, series, ARX and output-error models are in delta-operator form in
      // single precision; --linear-form direct keeps the polynomial form (the same model within
      // float rounding).
      const bool block_model = std::string(c.name) == "cg_hw" || std::string(c.name) == "cg_wh" ||
                               std::string(c.name) == "cg_arx" || std::string(c.name) == "cg_oe";
      CHECK((slurp(dir / "sp_model.h").find("delta-operator form") != std::string::npos) == block_model);
      const Run gd = codegen("--model " + q(model) + " --out " + q(dir) + " --name sp_direct --precision single " +
                             "--linear-form direct " + c.codegen_options);
      INFO(gd.err);
      REQUIRE(gd.code == 0);
      CHECK(slurp(dir / "sp_direct.h").find("delta-operator form") == std::string::npos);
      const std::vector<double> yd_c = run_generated(dir, "sp_direct", u, true);
      REQUIRE(yd_c.size() == y_nlid.size());
      CHECK(max_relative_gap(yd_c, y_nlid) <= 1e-3);
      // On a float-only FPU the double code calls soft-float routines, the float code none.
      if (const auto sp = cortex_m4f_imports(dir, "sp_model")) {
        const auto dp = cortex_m4f_imports(dir, c.name);
        INFO("Cortex-M4F imports, double: " << *dp << "\nsingle: " << *sp);
        CHECK(dp->find("__aeabi_d") != std::string::npos);
        CHECK(sp->find("__aeabi_d") == std::string::npos);
      } else {
        WARN("clang or nm not installed (scripts/deps installs clang): Cortex-M4F check skipped");
      }
    }
  }
}

TEST_CASE("nlid-codegen: a kind it does not generate, a grey box without --ts, another sample time and bad options are reported",
          "[tools][codegen]") {
  const fs::path est = write_record("cg_bad_est", 800, 73u, 1);
  const fs::path dir = work_dir() / "cg_bad";
  fs::create_directories(dir);
  const fs::path grey = dir / "grey.json", nlarx = dir / "lin.json";
  REQUIRE(fit("--model greybox:first_order --est " + q(est) + " --iterations 2 --save " + q(grey)).code == 0);
  REQUIRE(fit("--model nlarx:na=1,nb=1,nk=1:linear --est " + q(est) + " --save " + q(nlarx)).code == 0);
  // A kind that is not generated: a state-space model file (nlid-fit does not write one).
  const fs::path ss = dir / "ss.json";
  std::ofstream(ss) << R"json({"format": "nlid-model", "version": 1, "kind": "state_space", "ts": 0.01,
 "initial_condition": "zero", "created": "2026-11-25T00:00:00Z", "generator": "test", "description": "",
 "inputs": [{"name": "u", "unit": ""}], "outputs": [{"name": "y", "unit": ""}],
 "structure": {"A": [[0.9]], "B": [[0.1]], "C": [[1.0]], "D": [[0.0]], "offset": [0.0]},
 "parameters": {"names": ["A(1,1)", "B(1,1)", "C(1,1)", "D(1,1)"], "values": [0.9, 0.1, 1.0, 0.0]},
 "report": {"method": "", "focus": "", "num_experiments": 0, "num_samples": 0, "num_parameters": 4, "loss": 0,
            "fit_percent": 0, "iterations": 0, "solver_message": ""}})json";
  Run r = codegen("--model " + q(ss) + " --out " + q(dir));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("models of kind 'state_space' are not generated") &&
                        Catch::Contains("arx, output_error"));
  r = codegen("--model " + q(grey) + " --out " + q(dir));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("grey-box model is continuous") && Catch::Contains("--ts"));
  r = codegen("--model " + q(nlarx) + " --out " + q(dir) + " --ts 0.02");
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("--ts 0.02 s differs from the model's sample time 0.01 s"));
  // A name that is no C identifier is a command-line error, refused before the model is read.
  r = codegen("--model " + q(nlarx) + " --out " + q(dir) + " --name 9lives");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--name: name '9lives' is not a C identifier"));
  r = codegen("--model " + q(dir / "nope.json") + " --out " + q(dir) + " --name my-model");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("name 'my-model' is not a C identifier") && !Catch::Contains("nope.json"));
  // A name equal to a C standard header's would write DIR/math.h, shadowing <math.h>: refused up
  // front, also as the default name of a model file called math.json (C compares case-sensitively).
  r = codegen("--model " + q(nlarx) + " --out " + q(dir) + " --name stdio");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("name 'stdio' is the name of the C standard header <stdio.h>"));
  CHECK_FALSE(fs::exists(dir / "stdio.h"));
  fs::copy_file(nlarx, dir / "math.json", fs::copy_options::overwrite_existing);
  r = codegen("--model " + q(dir / "math.json") + " --out " + q(dir));
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("the default --name 'math' (from the model file's name") &&
                        Catch::Contains("<math.h>") && Catch::Contains("give another --name"));
  CHECK_FALSE(fs::exists(dir / "math.h"));
  r = codegen("--model " + q(dir / "math.json") + " --out " + q(dir) + " --name Math");
  CHECK(r.code == 0);
  CHECK(fs::exists(dir / "Math.h"));
  // A sub-step count too small for the grey box's stiffness at this sample time names the tool's
  // option, not the library's CodegenOptions field.
  r = codegen("--model " + q(grey) + " --out " + q(dir) + " --ts 2 --substeps 1");
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("--substeps 1 gives an unstable integrator step") &&
                        Catch::Contains("[at parameter '--substeps']") && !Catch::Contains("CodegenOptions"));
  r = codegen("--model " + q(nlarx) + " --out " + q(dir / "missing"));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("output directory") && Catch::Contains("does not exist"));
  r = codegen("--model " + q(nlarx) + " --out " + q(dir) + " --u0 0.5");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--u0 sets the input of --x0 equilibrium"));
  r = codegen("--model " + q(nlarx) + " --out " + q(dir) + " --x0 steady");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--x0 must be zero, equilibrium or a state X1,X2,.."));
  r = codegen("--model " + q(nlarx) + " --out " + q(dir) + " --x0 0.5,,1");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--x0 needs finite numbers separated by commas, got '0.5,,1' (an empty item)"));
  r = codegen("--model " + q(nlarx) + " --out " + q(dir) + " --x0 equilibrium --u0 0.5,x");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--u0 needs finite numbers separated by commas") && Catch::Contains("item 2: 'x'"));
  r = codegen("--model " + q(nlarx) + " --out " + q(dir) + " --x0 equilibrium --u0 0.1,0.2");
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("--u0 has 2 values, the model") && Catch::Contains("has 1 input (give one value"));
  r = codegen("--model " + q(nlarx) + " --out " + q(dir) + " --precision half");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--precision must be double or single, got 'half'"));
  r = codegen("--model " + q(nlarx) + " --out " + q(dir) + " --precision single --linear-form cascade");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--linear-form must be auto, direct or delta, got 'cascade'"));
  r = codegen("--model " + q(nlarx) + " --out " + q(dir) + " --linear-form delta");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--linear-form delta is for --precision single"));
  r = codegen("--model " + q(nlarx) + " --out " + q(dir) + " --substeps 0");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--substeps needs an integer from 1"));
  r = codegen("--model " + q(dir / "nope.json") + " --out " + q(dir));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("nope.json"));
  // The default name comes from the file's stem, made a C identifier.
  fs::copy_file(nlarx, dir / "throttle-v2.json", fs::copy_options::overwrite_existing);
  r = codegen("--model " + q(dir / "throttle-v2.json") + " --out " + q(dir));
  CHECK(r.code == 0);
  CHECK(fs::exists(dir / "throttle_v2.c"));
  CHECK_THAT(slurp(dir / "throttle_v2.h"), Catch::Contains("int throttle_v2_step(throttle_v2_state* s"));
}

TEST_CASE("nlid-codegen: an equilibrium start outside the estimation data's range is refused with --u0 and the range named",
          "[tools][codegen]") {
  // Before, --x0 equilibrium --u0 50 for a sigmoid-network model fitted on inputs in [-1, 1]
  // wrote the network's linear extrapolation as the initial state (for the throttle study's
  // nlarx5 at u0 = 5: a steady 950 deg for a valve that stops at 90), without a word.
  const fs::path est = write_record("ex_est", 1200, 81u, 1);
  const fs::path dir = work_dir() / "ex";
  fs::create_directories(dir);
  const fs::path model = dir / "ex.json";
  const Run f = fit("--model nlarx:na=2,nb=2,nk=1:sigmoidnet:units=3 --est " + q(est) + " --iterations 4 --save " + q(model));
  INFO(f.err);
  REQUIRE(f.code == 0);
  const nlid::Json file = nlid::read_json(model.string());
  REQUIRE(file.view().contains("data_range"));
  const Eigen::VectorXd in_range = file.view().at("data_range").at("inputs").at(0).get<Eigen::VectorXd>();
  REQUIRE(in_range.size() == 2);
  CHECK(in_range(0) >= -1.0);
  CHECK(in_range(0) < -0.5);
  CHECK(in_range(1) <= 1.0);
  CHECK(in_range(1) > 0.5);

  Run r = codegen("--model " + q(model) + " --out " + q(dir) + " --x0 equilibrium --u0 50");
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("--u0 50 is outside the input range of the estimation data recorded in") &&
                        Catch::Contains("(u: -0.") && Catch::Contains("its steady state there: y = ") &&
                        Catch::Contains("--allow-extrapolation") && Catch::Contains("parameter '--u0'"));
  CHECK_FALSE(fs::exists(dir / "ex.c"));
  CHECK_FALSE(fs::exists(dir / "ex.h"));
  // Below the range as well; and the switch generates it with a warning.
  r = codegen("--model " + q(model) + " --out " + q(dir) + " --x0 equilibrium --u0 -3");
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("--u0 -3 is outside the input range"));
  r = codegen("--model " + q(model) + " --out " + q(dir) + " --x0 equilibrium --u0 50 --allow-extrapolation");
  INFO(r.err);
  CHECK(r.code == 0);
  CHECK_THAT(r.err, Catch::Contains("warning: --u0 50 is outside the input range"));
  CHECK(fs::exists(dir / "ex.c"));
  // A switch given twice means the same (not "given twice; it takes one value").
  r = codegen("--model " + q(model) + " --out " + q(dir) + " --x0 equilibrium --u0 50 --allow-extrapolation --allow-extrapolation");
  CHECK(r.code == 0);
  // Inside the range: no warning, no note.
  r = codegen("--model " + q(model) + " --out " + q(dir) + " --x0 equilibrium --u0 0.5");
  CHECK(r.code == 0);
  CHECK(r.err.find("warning") == std::string::npos);
  CHECK(r.err.find("note") == std::string::npos);
  // The header names the range, for the caller to check or clamp the inputs against; in
  // single precision as float literals (a driver clamping a float input with them compiles
  // under -Wdouble-promotion -Wfloat-conversion -Werror).
  const std::string header = slurp(dir / "ex.h");
  CHECK_THAT(header, Catch::Contains("#define EX_INPUT0_MIN ") && Catch::Contains("#define EX_INPUT0_MAX ") &&
                         Catch::Contains("#define EX_OUTPUT0_MIN ") && Catch::Contains("#define EX_OUTPUT0_MAX "));
  {
    const std::size_t at = header.find("#define EX_INPUT0_MAX ") + std::string("#define EX_INPUT0_MAX ").size();
    CHECK(std::strtod(header.c_str() + at, nullptr) == in_range(1));
  }
  r = codegen("--model " + q(model) + " --out " + q(dir) + " --name ex_f --precision single");
  REQUIRE(r.code == 0);
  CHECK_THAT(slurp(dir / "ex_f.h"), Catch::Contains("#define EX_F_INPUT0_MIN ") && Catch::Contains("f /* u */"));
  std::ofstream(dir / "clamp.c") << "#include \"ex_f.h\"\n"
                                 << "ex_f_real clamp(ex_f_real u) {\n"
                                 << "  return u < EX_F_INPUT0_MIN ? EX_F_INPUT0_MIN : (u > EX_F_INPUT0_MAX ? EX_F_INPUT0_MAX : u);\n}\n";
  const std::string cc = "cc -std=c99 -Wall -Wextra -pedantic -Werror -Wdouble-promotion -Wfloat-conversion -c -o \"" +
                         (dir / "clamp.o").string() + "\" \"" + (dir / "clamp.c").string() + "\" 2>\"" +
                         (dir / "clamp.txt").string() + "\"";
  if (std::system(cc.c_str()) != 0) FAIL("a float driver using the range macros does not compile:\n" << slurp(dir / "clamp.txt"));
  // Without --u0 the default 0 is checked too; the message says it was the default. (A model
  // fitted on inputs that stay above 0.5: the same record shifted up by 1.5.)
  {
    const fs::path shifted = dir / "shifted.csv";
    std::ifstream in(est);
    std::ofstream out(shifted);
    std::string line;
    std::getline(in, line);
    out << line << "\n";
    while (std::getline(in, line)) {
      std::stringstream cells(line);
      std::string t, uu, yy;
      std::getline(cells, t, ',');
      std::getline(cells, uu, ',');
      std::getline(cells, yy, ',');
      out << t << "," << std::stod(uu) + 1.5 << "," << yy << "\n";
    }
    out.close();
    const fs::path up = dir / "up.json";
    REQUIRE(fit("--model nlarx:na=1,nb=1,nk=1:linear --est " + q(shifted) + " --save " + q(up)).code == 0);
    r = codegen("--model " + q(up) + " --out " + q(dir) + " --x0 equilibrium");
    CHECK(r.code == 1);
    CHECK_THAT(r.err, Catch::Contains("--u0 0 (the default) is outside the input range"));
  }
  // The switch only goes with an equilibrium start.
  r = codegen("--model " + q(model) + " --out " + q(dir) + " --allow-extrapolation");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--allow-extrapolation permits an equilibrium start"));

  // Inside the input range, a steady output far outside the recorded outputs (here: a range
  // edited to [100, 101]) is refused too.
  nlid::Json edited = nlid::read_json(model.string());
  edited["data_range"]["outputs"] = nlid::Json::array({nlid::Json::array({100.0, 101.0})});
  const fs::path narrow = dir / "narrow.json";
  nlid::write_file_atomically(narrow.string(), edited.dump(2));
  r = codegen("--model " + q(narrow) + " --out " + q(dir) + " --x0 equilibrium --u0 0.5");
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("the equilibrium for --u0 0.5 has the output y = ") &&
                        Catch::Contains("far outside the output range of the estimation data") &&
                        Catch::Contains("(100 to 101)"));

  // A file without the range (written before nlid kept it): generated, with a note saying
  // that --u0 was not checked.
  nlid::Json old = nlid::read_json(model.string());
  REQUIRE(old.erase("data_range"));
  const fs::path unranged = dir / "unranged.json";
  nlid::write_file_atomically(unranged.string(), old.dump(2));
  r = codegen("--model " + q(unranged) + " --out " + q(dir) + " --x0 equilibrium --u0 50");
  CHECK(r.code == 0);
  CHECK_THAT(r.err, Catch::Contains("note: ") && Catch::Contains("records no range of its estimation data") &&
                        Catch::Contains("--u0 50 is not checked"));
}

TEST_CASE("nlid-fit -> nlid-sim: every family keeps the data's channel names, and --decimate matches nlid-fit's",
          "[tools][sim]") {
  // Before, grey-box and output-error files named their channels u1/y1 whatever the data said,
  // so nlid-sim looked for a column 'u1' that the recording does not have.
  const fs::path est = write_record("names_est", 800, 74u, 1, true, "angle");
  const fs::path dir = work_dir() / "names";
  fs::create_directories(dir);
  for (const char* spec : {"greybox:first_order", "linear:oe:nb=1,nf=1,nk=1", "linear:arx:na=1,nb=1,nk=1"}) {
    INFO(spec);
    const fs::path model = dir / "m.json";
    const Run f = fit("--model " + std::string(spec) + " --est " + q(est) + " --output angle --iterations 2 --save " + q(model));
    INFO(f.err);
    REQUIRE(f.code == 0);
    const std::string text = slurp(model);
    CHECK_THAT(text, Catch::Contains("\"name\": \"u\"") && Catch::Contains("\"name\": \"angle\""));
    const Run s = sim("--model " + q(model) + " --input " + q(est) + " --out " + q(dir / "y.csv"));
    INFO(s.err);
    CHECK(s.code == 0);
  }

  // A 1 kHz record fitted at 100 Hz (nlid-fit --decimate 10) runs in nlid-sim on the same raw
  // file with --decimate 10; without it the message names the option.
  const fs::path raw = write_record("raw_1k", 6000, 75u, 10, true, "y", 0.001);
  const fs::path model = dir / "dec.json";
  REQUIRE(fit("--model nlarx:na=1,nb=1,nk=1:linear --est " + q(raw) + " --decimate 10 --save " + q(model)).code == 0);
  Run s = sim("--model " + q(model) + " --input " + q(raw) + " --out " + q(dir / "dec.csv"));
  CHECK(s.code == 1);
  CHECK_THAT(s.err, Catch::Contains("sample-time mismatch") && Catch::Contains("use --decimate 10"));
  // A file already at the model's rate, decimated anyway: the hint was "resample the data".
  const fs::path at_rate = write_record("at_100", 600, 76u, 1, true, "y", 0.01);
  s = sim("--model " + q(model) + " --input " + q(at_rate) + " --decimate 10 --out " + q(dir / "dec.csv"));
  CHECK(s.code == 1);
  CHECK_THAT(s.err, Catch::Contains("decimated by 10") && Catch::Contains("the file already has the model's sample time: drop --decimate"));
  s = sim("--model " + q(model) + " --input " + q(at_rate) + " --decimate 5 --out " + q(dir / "dec.csv"));
  CHECK_THAT(s.err, Catch::Contains("drop --decimate"));
  s = sim("--model " + q(model) + " --input " + q(raw) + " --decimate 5 --out " + q(dir / "dec.csv"));
  CHECK_THAT(s.err, Catch::Contains("use --decimate 10"));
  s = sim("--model " + q(model) + " --input " + q(raw) + " --decimate 10 --out " + q(dir / "dec.csv"));
  INFO(s.err);
  REQUIRE(s.code == 0);
  const std::vector<double> t = csv_column(dir / "dec.csv", 0);
  REQUIRE(t.size() == 600);
  CHECK(t[1] - t[0] == Approx(0.01));
  s = sim("--model " + q(model) + " --input " + q(raw) + " --decimate 0 --out " + q(dir / "dec.csv"));
  CHECK(s.code == 2);
  CHECK_THAT(s.err, Catch::Contains("--decimate needs an integer from 1"));
}

TEST_CASE("nlid-diagnose --save -> nlid-sim and nlid-codegen: the repaired model runs and deploys",
          "[tools][codegen][diagnose]") {
  // A first-order lag with a concealed dead time of 4 samples: the diagnosis adds dead_time;
  // the saved model keeps the data's channel names, nlid-sim runs it on the raw file, and its C
  // (dead-time history in the state) reproduces nlid-sim from the zero state.
  const fs::path est = write_record("dg_est", 1500, 11u, 4), val = write_record("dg_val", 1500, 12u, 4);
  const fs::path dir = work_dir() / "dg";
  fs::create_directories(dir);
  const fs::path model = dir / "repaired.json";
  const Run d = tool_test::diagnose("--baseline first_order --est " + q(est) + " --val " + q(val) +
                                                         " --starts 2 --threads 2 --quiet --save " + q(model));
  INFO(d.err);
  REQUIRE(d.code == 0);
  CHECK_THAT(d.out, Catch::Contains("added dead_time"));
  const std::string text = slurp(model);
  CHECK_THAT(text, Catch::Contains("\"kind\": \"augmented_greybox\"") && Catch::Contains("\"effect\": \"dead_time\"") &&
                       Catch::Contains("\"name\": \"u\""));
  CHECK_THAT(text, Catch::Contains("\"data_range\""));  // where it was fitted: nlid-codegen checks --u0 against it

  const fs::path simulated = dir / "sim.csv";
  const Run s = sim("--model " + q(model) + " --input " + q(val) + " --out " + q(simulated));
  INFO(s.err);
  REQUIRE(s.code == 0);
  const std::vector<double> y_nlid = csv_column(simulated, 1), y = csv_column(val, 2);
  // The repaired model follows the record (noise 0.01 on a range of about 4) after the start-up.
  double worst = 0;
  for (std::size_t k = 200; k < y.size(); ++k) worst = std::max(worst, std::abs(y[k] - y_nlid[k]));
  CHECK(worst < 0.1);

  const Run g = codegen("--model " + q(model) + " --out " + q(dir) + " --name repaired");
  INFO(g.err);
  REQUIRE(g.code == 0);
  const std::string source = slurp(dir / "repaired.c");
  CHECK_THAT(source, Catch::Contains("REPAIRED_DELAY_SAMPLES"));
  CHECK(pure_ascii(source));
  const std::vector<double> y_c = run_generated(dir, "repaired", csv_column(val, 1));
  REQUIRE(y_c.size() == y_nlid.size());
  CHECK(max_relative_gap(y_c, y_nlid) <= 1e-12);
}

TEST_CASE("nlid-diagnose --save records the data range as the estimation saw it like nlid-fit does", "[tools][diagnose]") {
  // With --decimate the models are fitted on the filtered, decimated record, whose range differs
  // from the raw file's (the anti-alias filter rings at steps); both tools record that one.
  const fs::path est = write_record("dr_est", 1600, 13u, 4), val = write_record("dr_val", 1600, 14u, 4);
  const fs::path dir = work_dir() / "dr";
  fs::create_directories(dir);
  const Run d = tool_test::diagnose("--baseline first_order --est " + q(est) + " --val " + q(val) +
                                    " --decimate 4 --starts 1 --max-effects 1 --threads 2 --quiet --save " + q(dir / "rep.json"));
  INFO(d.err);
  REQUIRE(d.code == 0);
  const Run f = fit("--model linear:arx:na=1,nb=1,nk=1 --est " + q(est) + " --decimate 4 --save " + q(dir / "arx.json"));
  REQUIRE(f.code == 0);
  auto range = [](const fs::path& p, const char* which) {
    return nlid::read_json(p.string()).view().at("data_range").at(which).at(0).get<Eigen::VectorXd>();
  };
  const Eigen::VectorXd ri = range(dir / "rep.json", "inputs"), fi = range(dir / "arx.json", "inputs");
  const Eigen::VectorXd ro = range(dir / "rep.json", "outputs"), fo = range(dir / "arx.json", "outputs");
  REQUIRE(ri.size() == 2);
  CHECK(ri(0) == fi(0));
  CHECK(ri(1) == fi(1));
  CHECK(ro(0) == fo(0));
  CHECK(ro(1) == fo(1));
  // Not the raw file's range: the filtered steps overshoot it.
  const std::vector<double> raw = csv_column(est, 1);
  const auto [lo, hi] = std::minmax_element(raw.begin(), raw.end());
  CHECK((ri(0) < *lo || ri(1) > *hi));
}

TEST_CASE("nlid-codegen: --u0 gives each input of a two-input model its own value", "[tools][codegen]") {
  // A two-input ARX model file (the tools fit one input; a C++ program saves more):
  // y(t) = 0.5 y(t-1) + u1(t-1) + 2 u2(t-1), steady state y = 2 (u1 + 2 u2).
  const fs::path dir = work_dir() / "cg_two_inputs";
  fs::create_directories(dir);
  const fs::path model = dir / "arx2.json";
  std::ofstream(model) << R"json({"format": "nlid-model", "version": 1, "kind": "arx", "ts": 0.01,
 "initial_condition": "zero", "created": "2026-11-27T00:00:00Z", "generator": "test", "description": "",
 "inputs": [{"name": "cmd", "unit": ""}, {"name": "load", "unit": ""}], "outputs": [{"name": "y", "unit": ""}],
 "structure": {"a": [-0.5], "b": [[1.0], [2.0]], "nk": [1, 1], "offset": 0.0}})json";
  Run r = codegen("--model " + q(model) + " --out " + q(dir) + " --x0 equilibrium --u0 0.2,-0.3");
  INFO(r.err);
  REQUIRE(r.code == 0);
  // State [y(t-1), u1(t-1), u2(t-1)] at the steady state for u = (0.2, -0.3): y = 2 (0.2 - 0.6).
  const std::vector<double> x = x0_values(slurp(dir / "arx2.c"), "arx2");
  REQUIRE(x.size() == 3);
  CHECK(std::abs(x[0] - (-0.8)) < 1e-15);
  CHECK(x[1] == 0.2);
  CHECK(x[2] == -0.3);
  // One value holds both inputs.
  REQUIRE(codegen("--model " + q(model) + " --out " + q(dir) + " --name arx2_one --x0 equilibrium --u0 0.1").code == 0);
  const std::vector<double> x1 = x0_values(slurp(dir / "arx2_one.c"), "arx2_one");
  REQUIRE(x1.size() == 3);
  CHECK(std::abs(x1[0] - 0.6) < 1e-15);
  CHECK(x1[1] == 0.1);
  CHECK(x1[2] == 0.1);
  r = codegen("--model " + q(model) + " --out " + q(dir) + " --x0 equilibrium --u0 0.1,0.2,0.3");
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("--u0 has 3 values, the model") && Catch::Contains("has 2 inputs"));
}

TEST_CASE("nlid-codegen: channel names holding comment markers compile under -Werror", "[tools][codegen]") {
  // The names go into C comments: "*/" was defused, "/*" was not, and -Wcomment failed the build.
  const fs::path dir = work_dir() / "cg_comment_names";
  fs::create_directories(dir);
  const fs::path rec = write_record("cg_marks", 400, 51u, 0);
  {
    std::string text = slurp(rec);
    text.replace(0, text.find('\n'), "t,u/*V,y*/ /* x");
    std::ofstream(rec) << text;
  }
  const fs::path model = dir / "model.json";
  const Run f = fit("--model linear:arx:na=1,nb=1,nk=1 --est " + q(rec) + " --input 'u/*V' --output 'y*/ /* x' --save " +
                    q(model));
  INFO(f.err);
  REQUIRE(f.code == 0);
  const Run g = codegen("--model " + q(model) + " --out " + q(dir) + " --name marks");
  INFO(g.err);
  REQUIRE(g.code == 0);
  CHECK_THAT(slurp(dir / "marks.c") + slurp(dir / "marks.h"), Catch::Contains("u/ *V"));
  CHECK(run_generated(dir, "marks", {1, 2, 0}).size() == 3u);
}

TEST_CASE("nlid-codegen: an unstable linear model is generated with a warning naming its pole", "[tools][codegen]") {
  const fs::path dir = work_dir() / "cg_poles";
  fs::create_directories(dir);
  // y(t) = a y(t-1) + u(t-1): unstable for a = 1.5, stable for a = 0.5.
  const auto arx = [&](const std::string& file, double a) {
    const fs::path p = dir / file;
    std::ofstream(p) << R"json({"format": "nlid-model", "version": 1, "kind": "arx", "ts": 0.01,
 "created": "2026-11-29T00:00:00Z", "generator": "test", "description": "",
 "inputs": [{"name": "u", "unit": ""}], "outputs": [{"name": "y", "unit": ""}], "initial_condition": "zero",
 "structure": {"a": [)json" << -a << R"json(], "b": [[1]], "nk": [1], "offset": 0},
 "parameters": {"names": ["a1", "b1"], "values": [)json" << -a << R"json(, 1]},
 "report": {"method": "", "focus": "", "num_experiments": 0, "num_samples": 0, "num_parameters": 2, "loss": 0,
            "fit_percent": 0, "iterations": 0, "solver_message": ""}})json";
    return p;
  };
  Run r = codegen("--model " + q(arx("grows.json", 1.5)) + " --out " + q(dir));
  INFO(r.err);
  CHECK(r.code == 0);
  CHECK_THAT(r.err, Catch::Contains("nlid-codegen: warning:") && Catch::Contains("grows.json is unstable") &&
                        Catch::Contains("magnitude 1.5 > 1"));
  CHECK(fs::exists(dir / "grows.c"));
  r = codegen("--model " + q(arx("settles.json", 0.5)) + " --out " + q(dir));
  CHECK(r.code == 0);
  CHECK_THAT(r.err, !Catch::Contains("warning"));
}

TEST_CASE("nlid-codegen --x0 equilibrium works for a nonlinear ARX model with a long lag window", "[tools][codegen]") {
  // The equilibrium was probed on an 8-sample record: a model with nk = 20 (21 samples of lags)
  // was refused ("8 samples, not more than the 21 needed"), though nlid-sim starts it there.
  const fs::path est = write_record("lag_est", 1000, 83u, 20);
  const fs::path dir = work_dir() / "lag";
  fs::create_directories(dir);
  const fs::path model = dir / "lag.json";
  const Run f = fit("--model nlarx:na=2,nb=2,nk=20:sigmoidnet:units=2 --est " + q(est) + " --iterations 3 --save " +
                    q(model));
  INFO(f.err);
  REQUIRE(f.code == 0);
  const Run r = codegen("--model " + q(model) + " --out " + q(dir) + " --x0 equilibrium --u0 0.3");
  INFO(r.err);
  CHECK(r.code == 0);
  CHECK(fs::exists(dir / "lag.c"));
  CHECK_THAT(slurp(dir / "lag.h"), Catch::Contains("equilibrium"));
}
