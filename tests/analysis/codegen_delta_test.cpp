// Single-precision C of linear blocks with poles close to z = 1 (docs/codegen.md, "Linear blocks
// with poles close to z = 1"): the delta-operator form (codegen/delta_form.hpp) against nlid's
// double simulation and against the direct (polynomial) form on the same model. Poles 0.999 and
// 0.998 give F(1) = 2e-6, where rounding the f coefficients to float moves the static gain by
// percent; the delta form must track nlid closely and the direct form must be at least ten times
// worse — so the test fails if the delta path silently falls back to the direct form. Also: the
// initial state tables (equilibrium) and an explicit state (NAME_set_state with
// generated_c_state) map nlid's state correctly, and double code ignores the option. ARX models
// (two inputs and an offset over the same slow A) are one multi-input delta block.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "nlid/codegen/any_model.hpp"
#include "nlid/codegen/delta_form.hpp"
#include "nlid/codegen/hammerstein_wiener.hpp"
#include "nlid/codegen/linear.hpp"
#include "nlid/codegen/series.hpp"
#include "nlid/models/transfer_function_block.hpp"
#include "nlid/nonlinearities/saturation.hpp"
#include "nlid/nonlinearities/unit_gain.hpp"

#include "../support/generated_c.hpp"

namespace {

using Slow = nlid::TransferFunctionBlock<2, 2, 1>;
using SlowHw = nlid::HammersteinWiener<nlid::UnitGain, Slow, nlid::Saturation>;

constexpr double ts = 0.001;

// B = [3e-6 1e-6] (delay 1), F = (1 - 0.999 q^-1)(1 - 0.998 q^-1): F(1) = 2e-6, gain 2;
// output saturation [-20, 20] (not reached: its branches are traced, the error is the block's).
SlowHw slow_hw() {
  SlowHw m(nlid::UnitGain{}, Slow{}, nlid::Saturation{}, ts);
  Eigen::VectorXd th(6);
  th << 3e-6, 1e-6, -1.997, 0.997002, -20.0, 20.0;
  m.set_parameters(th);
  return m;
}

// A unit step, and random steps (levels in [-3, 3] held 300 .. 1500 samples), N = 6000.
Eigen::MatrixXd step_input(double level) { return Eigen::MatrixXd::Constant(6000, 1, level); }
Eigen::MatrixXd random_steps(unsigned seed = 7) {
  std::mt19937 gen(seed);
  std::uniform_real_distribution<double> level(-3.0, 3.0);
  std::uniform_int_distribution<int> hold(300, 1500);
  Eigen::MatrixXd u(6000, 1);
  for (Eigen::Index t = 0; t < u.rows();) {
    const double v = level(gen);
    for (int k = hold(gen); k > 0 && t < u.rows(); --k) u(t++, 0) = v;
  }
  return u;
}

nlid::Experiment experiment(const Eigen::MatrixXd& u) { return nlid::Experiment(u, Eigen::MatrixXd::Zero(u.rows(), 1), ts); }

// max |a - b| / max |b|.
double rel_error(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  REQUIRE(a.size() == b.size());
  return (a - b).cwiseAbs().maxCoeff() / b.cwiseAbs().maxCoeff();
}

// Single-precision code of `m` in `form`, started at the equilibrium for `u0` if given.
template <class Model>
nlid::GeneratedCode single_code(const Model& m, const std::string& name, nlid::codegen::LinearForm form,
                                std::optional<Eigen::VectorXd> u0 = std::nullopt) {
  nlid::CodegenOptions o;
  o.name = name;
  o.precision = nlid::codegen::Precision::single_precision;
  o.linear_form = form;
  o.equilibrium_input = std::move(u0);
  return nlid::generate_c(m, o);
}

// The float code in delta form tracks nlid's double run `ref` on `u`; the direct form is at least
// ten times worse (and visibly wrong), so a silent fallback to the direct form fails.
void check_delta_beats_direct(const nlid::GeneratedCode& delta, const nlid::GeneratedCode& direct,
                              const Eigen::MatrixXd& u, const Eigen::VectorXd& ref, const std::string& tag) {
  const double err_delta = rel_error(nlid_test::run_generated_c(delta, u, tag, true), ref);
  const double err_direct = rel_error(nlid_test::run_generated_c(direct, u, tag + "_direct", true), ref);
  INFO("input " << tag << ": delta form " << err_delta << ", direct form " << err_direct
                << " (max |y_C - y_nlid| / max |y_nlid|)");
  CHECK(err_delta <= 1e-5);
  CHECK(err_direct >= 10.0 * err_delta);
  CHECK(err_direct > 1e-3);
}

// Double code is the direct form whatever `automatic`/`direct` says; asking for delta is refused.
template <class Model>
void check_double_code_is_direct(const Model& m, const std::string& name) {
  nlid::CodegenOptions o;
  o.name = name;
  const std::string automatic = nlid::generate_c(m, o).source;
  o.linear_form = nlid::codegen::LinearForm::direct;
  CHECK(nlid::generate_c(m, o).source == automatic);
  o.linear_form = nlid::codegen::LinearForm::delta;
  CHECK_THROWS_AS(nlid::generate_c(m, o), nlid::Error);
}

// Outputs of the generated code started with NAME_set_state(x) instead of NAME_init.
Eigen::VectorXd run_from_state(const nlid::GeneratedCode& g, const Eigen::MatrixXd& u, const Eigen::VectorXd& x,
                               const std::string& tag) {
  const std::filesystem::path dir = nlid_test::scratch_dir() / ("c_" + tag);
  std::filesystem::create_directories(dir);
  g.write(dir.string());
  const std::string n = g.name;
  std::string xs;
  char b[48];
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    std::snprintf(b, sizeof b, "%s(%s)%.9g", i ? ", " : "", (n + "_real").c_str(), x(i));
    xs += b;
  }
  std::ofstream(dir / "driver.c") << "#include <stdio.h>\n#include \"" << n << ".h\"\n"
                                  << "int main(int argc, char** argv) {\n  " << n << "_real u[" << u.cols() << "], y[1];\n  const " << n
                                  << "_real x[] = {" << xs << "};\n  double v;\n  int i = 0;\n  " << n << "_state s;\n"
                                  << "  FILE* in = argc > 1 ? fopen(argv[1], \"r\") : NULL;\n  if (!in) return 2;\n  " << n
                                  << "_init(&s);\n  " << n << "_set_state(&s, x);\n"
                                  << "  while (fscanf(in, \"%lf\", &v) == 1) {\n    u[i++] = (" << n << "_real)v;\n"
                                  << "    if (i < " << u.cols() << ") continue;\n    i = 0;\n    " << n
                                  << "_step(&s, u, y);\n    printf(\"%.17g\\n\", (double)y[0]);\n  }\n  fclose(in);\n  return 0;\n}\n";
  {
    std::ofstream in(dir / "u.txt");
    for (Eigen::Index t = 0; t < u.rows(); ++t)
      for (Eigen::Index j = 0; j < u.cols(); ++j) {
        std::snprintf(b, sizeof b, "%.17g\n", u(t, j));
        in << b;
      }
  }
  nlid_test::compile_and_run_driver(dir, n, true);
  std::ifstream out(dir / "y.txt");
  std::vector<double> ys;
  for (double v; out >> v;) ys.push_back(v);
  return Eigen::Map<Eigen::VectorXd>(ys.data(), static_cast<Eigen::Index>(ys.size()));
}

}  // namespace

TEST_CASE("Taylor shift about z = 1 and the delta coefficients of a block", "[codegen][delta]") {
  // z^2 - 1.997 z + 0.997002 = d^2 + 0.003 d + 2e-6 (d = z - 1).
  const std::vector<double> a = nlid::codegen::taylor_shift_at_one({1.0, -1.997, 0.997002});
  REQUIRE(a.size() == 3);
  CHECK(a[0] == 1.0);
  CHECK(a[1] == Approx(0.003).epsilon(1e-12));
  CHECK(a[2] == Approx(2e-6).epsilon(1e-9));
  // 2 z^3 + 0 z^2 - 1 z + 5 = 2 d^3 + 6 d^2 + 5 d + 6.
  CHECK(nlid::codegen::taylor_shift_at_one({2.0, 0.0, -1.0, 5.0}) == std::vector<double>{2.0, 6.0, 5.0, 6.0});
  // The delta state is the Taylor shift of nlid's TDF-II registers: e1 = s1, e2 = s1 + s2.
  const SlowHw m = slow_hw();
  const nlid::codegen::DeltaBlock d = nlid::codegen::delta_block(m.linear_block(), m.linear_parameters());
  CHECK(d.n == 2);
  CHECK(d.c[2] == Approx(4e-6).epsilon(1e-9));  // B(1)
  CHECK(d.a[2] == Approx(2e-6).epsilon(1e-9));  // F(1)
  const Eigen::VectorXd e = d.state_from_tdf2(Eigen::Vector2d(1.5, -0.25));
  CHECK(e(0) == 1.5);
  CHECK(e(1) == 1.25);
}

TEST_CASE("float code of a slow Hammerstein-Wiener block: the delta form tracks nlid, the direct form does not",
          "[codegen][delta]") {
  using nlid::codegen::LinearForm;
  const SlowHw m = slow_hw();
  const nlid::GeneratedCode delta = single_code(m, "slowhw", LinearForm::automatic);
  const nlid::GeneratedCode direct = single_code(m, "slowhw_direct", LinearForm::direct);
  CHECK(delta.source != direct.source);
  CHECK(delta.header.find("delta-operator form") != std::string::npos);
  CHECK(nlid_test::c_code_only(delta.source + delta.header).find("double") == std::string::npos);
  CHECK(single_code(m, "slowhw", LinearForm::delta).source == delta.source);  // automatic = delta in float
  int k = 0;
  for (const Eigen::MatrixXd& u : {step_input(1.0), random_steps()})
    check_delta_beats_direct(delta, direct, u, m.simulate(experiment(u), nlid::InitialCondition::zero).col(0),
                             "delta_hw" + std::to_string(k++));
  // Double code: `automatic` is the direct form, the same text as before the option existed.
  check_double_code_is_direct(m, "slowhw_double");
}

TEST_CASE("float code in delta form starts from nlid's equilibrium and from an explicit state", "[codegen][delta]") {
  using nlid::codegen::LinearForm;
  const SlowHw m = slow_hw();
  Eigen::MatrixXd u = random_steps();
  u.topRows(200).setConstant(2.5);
  const nlid::Experiment e = experiment(u);
  // Equilibrium for u0 = 2.5 (y = 5): NAME_x0 is the delta state of nlid's steady state.
  const nlid::GeneratedCode eq = single_code(m, "slowhw_eq", LinearForm::automatic, Eigen::VectorXd::Constant(1, 2.5));
  const Eigen::VectorXd ref_eq = m.simulate(e, nlid::InitialCondition::equilibrium).col(0);
  const Eigen::VectorXd y_eq = nlid_test::run_generated_c(eq, u, "delta_hw_eq", true);
  REQUIRE(y_eq.size() == ref_eq.size());
  INFO("equilibrium start: first outputs " << y_eq(0) << " vs nlid " << ref_eq(0));
  CHECK(std::abs(ref_eq(0) - 5.0) < 1e-9);
  for (int t = 0; t < 200; ++t) CHECK(std::abs(y_eq(t) - ref_eq(t)) <= 4e-7 * std::abs(ref_eq(t)));
  CHECK(rel_error(y_eq, ref_eq) <= 1e-4);

  // An explicit state: where nlid's block is after 1500 samples of a ramp (both registers away
  // from any steady state), passed through generated_c_state to NAME_set_state.
  std::vector<double> s(2, 0.0);
  const std::vector<double> th(m.linear_parameters().begin(), m.linear_parameters().end());
  for (int t = 0; t < 1500; ++t)
    (void)m.linear_block().step(std::span<double>(s), 0.004 * t, std::span<const double>(th));
  const Eigen::VectorXd x = Eigen::Map<const Eigen::VectorXd>(s.data(), 2);
  nlid::CodegenOptions o;
  o.precision = nlid::codegen::Precision::single_precision;
  const Eigen::VectorXd xc = nlid::generated_c_state(m, x, o);
  CHECK(xc(0) == x(0));
  CHECK(xc(1) == x(0) + x(1));
  o.linear_form = LinearForm::direct;
  CHECK(nlid::generated_c_state(m, x, o) == x);  // the direct form's state is nlid's
  Eigen::VectorXd ref_x(u.rows());
  const std::span<const double> theta(m.parameters().data(), static_cast<std::size_t>(m.parameters().size()));
  REQUIRE(m.simulate<double>(u, theta, std::span<const double>(x.data(), 2),
                             std::span<double>(ref_x.data(), static_cast<std::size_t>(ref_x.size()))));
  const Eigen::VectorXd y_x = run_from_state(single_code(m, "slowhw_x", LinearForm::automatic), u, xc, "delta_hw_x");
  REQUIRE(y_x.size() == ref_x.size());
  INFO("explicit state " << x.transpose() << ": first outputs " << y_x(0) << ", " << y_x(1) << " vs nlid " << ref_x(0)
                         << ", " << ref_x(1));
  for (int t = 0; t < 20; ++t) CHECK(std::abs(y_x(t) - ref_x(t)) <= 4e-7 * std::abs(ref_x(t)));
  CHECK(rel_error(y_x, ref_x) <= 1e-4);
}

TEST_CASE("float code of a Wiener-Hammerstein chain writes each linear block in delta form", "[codegen][delta]") {
  using nlid::codegen::LinearForm;
  using Fast = nlid::TransferFunctionBlock<1, 1, 0>;
  nlid::WienerHammerstein<Slow, nlid::Saturation, Fast> m(Slow{}, nlid::Saturation{}, Fast{}, ts);
  Eigen::VectorXd th(8);
  th << 3e-6, 1e-6, -1.997, 0.997002,  // the slow block of the HW test (gain 2)
      -20.0, 20.0,                      // saturation, not reached
      0.25, -0.5;                       // 0.25 / (1 - 0.5 q^-1): gain 0.5
  m.set_parameters(th);
  const Eigen::MatrixXd u = random_steps();
  const Eigen::VectorXd ref = m.simulate(experiment(u), nlid::InitialCondition::zero).col(0);
  const nlid::GeneratedCode delta = single_code(m, "slowwh", LinearForm::automatic);
  CHECK(delta.header.find("delta-operator form") != std::string::npos);
  check_delta_beats_direct(delta, single_code(m, "slowwh_direct", LinearForm::direct), u, ref, "delta_wh");

  // Equilibrium for u0 = -1.5 (stacked states of both blocks transformed).
  Eigen::MatrixXd ue = u;
  ue.topRows(300).setConstant(-1.5);
  const Eigen::VectorXd ref_eq = m.simulate(experiment(ue), nlid::InitialCondition::equilibrium).col(0);
  const Eigen::VectorXd y_eq = nlid_test::run_generated_c(
      single_code(m, "slowwh_eq", LinearForm::automatic, Eigen::VectorXd::Constant(1, -1.5)), ue, "delta_wh_eq", true);
  REQUIRE(y_eq.size() == ref_eq.size());
  CHECK(std::abs(ref_eq(0) + 1.5) < 1e-9);
  for (int t = 0; t < 300; ++t) CHECK(std::abs(y_eq(t) - ref_eq(t)) <= 4e-7 * std::abs(ref_eq(t)));
  CHECK(rel_error(y_eq, ref_eq) <= 1e-4);
}

TEST_CASE("float code of a slow output-error model writes its block in delta form", "[codegen][delta]") {
  using nlid::codegen::LinearForm;
  // The slow block of the HW test as an output-error model with offset 0.5.
  const nlid::OutputError m({Eigen::Vector2d(3e-6, 1e-6)}, {Eigen::Vector2d(-1.997, 0.997002)}, {1}, ts, 0.5);
  Eigen::MatrixXd u = random_steps();
  const nlid::Experiment e = experiment(u);
  const Eigen::VectorXd ref = m.simulate(e, nlid::InitialCondition::zero).col(0);
  const nlid::GeneratedCode delta = single_code(m, "slowoe", LinearForm::automatic);
  CHECK(delta.header.find("delta-operator form") != std::string::npos);
  CHECK(delta.header.find("#define SLOWOE_NUM_STATES 2") != std::string::npos);  // n = max(nf, nk + nb - 1)
  check_delta_beats_direct(delta, single_code(m, "slowoe_direct", LinearForm::direct), u, ref, "delta_oe");

  u.topRows(300).setConstant(2.0);
  const Eigen::VectorXd ref_eq = m.simulate(experiment(u), nlid::InitialCondition::equilibrium).col(0);
  const Eigen::VectorXd y_eq = nlid_test::run_generated_c(
      single_code(m, "slowoe_eq", LinearForm::automatic, Eigen::VectorXd::Constant(1, 2.0)), u, "delta_oe_eq", true);
  REQUIRE(y_eq.size() == ref_eq.size());
  CHECK(std::abs(ref_eq(0) - 4.5) < 1e-9);  // offset 0.5 + gain 2 * 2
  for (int t = 0; t < 300; ++t) CHECK(std::abs(y_eq(t) - ref_eq(t)) <= 4e-7 * std::abs(ref_eq(t)));
  CHECK(rel_error(y_eq, ref_eq) <= 1e-5);
}

namespace {

// A(q) = (1 - 0.999 q^-1)(1 - 0.998 q^-1), A(1) = 2e-6; B1 = [3e-6 1e-6] with delay 1 (gain 2),
// B2 = 0.5e-6 (1 + q^-1 + q^-2 + q^-3) without delay (gain 1, direct feedthrough, 3 past
// inputs: n = 3 > na), offset c = 1e-6 (0.5 at steady state).
nlid::Arx slow_arx() {
  return nlid::Arx(Eigen::Vector2d(-1.997, 0.997002), {Eigen::Vector2d(3e-6, 1e-6), Eigen::Vector4d::Constant(0.5e-6)},
                   {1, 0}, ts, 1e-6);
}

// Two inputs of random steps (independent levels and switching times).
Eigen::MatrixXd random_steps2() {
  Eigen::MatrixXd u(6000, 2);
  u.col(0) = random_steps(7);
  u.col(1) = random_steps(11);
  return u;
}

}  // namespace

TEST_CASE("float code of a slow two-input ARX model with offset: one delta block tracks nlid", "[codegen][delta]") {
  using nlid::codegen::LinearForm;
  const nlid::Arx m = slow_arx();
  // One block of n = 3 states, the first h = na = 2 in delta form: numerators per input (their
  // coefficients of q^-0 .. q^-2) and the offset's c*binomial(2, k); B2's q^-3 coefficient is in
  // the third register, which has no feedback and stays as it is.
  nlid::CodegenOptions so;
  so.precision = nlid::codegen::Precision::single_precision;
  const auto db = nlid::codegen::detail::arx_delta_block(m, so);
  REQUIRE(db);
  CHECK(db->n == 3);
  CHECK(db->h == 2);
  REQUIRE(db->c.size() == 3);
  REQUIRE(db->a.size() == 3);
  CHECK(db->a[2] == Approx(2e-6).epsilon(1e-9));       // A(1)
  CHECK(db->c[0][2] == Approx(4e-6).epsilon(1e-9));    // B1(1): B1 lies within the delta part
  CHECK(db->c[1][2] == Approx(1.5e-6).epsilon(1e-9));  // b2,0 + b2,1 + b2,2
  CHECK(db->c[1][0] == 0.5e-6);                        // feedthrough b2,0
  CHECK(db->c[2] == std::vector<double>{1e-6, 2e-6, 1e-6});
  CHECK(db->tail == std::vector<std::vector<double>>{{0.0}, {0.5e-6}, {0.0}});

  const nlid::GeneratedCode delta = single_code(m, "slowarx", LinearForm::automatic);
  const nlid::GeneratedCode direct = single_code(m, "slowarx_direct", LinearForm::direct);
  CHECK(delta.header.find("delta-operator form") != std::string::npos);
  CHECK(delta.header.find("#define SLOWARX_NUM_STATES 3") != std::string::npos);
  CHECK(direct.header.find("delta-operator form") == std::string::npos);
  CHECK(nlid_test::c_code_only(delta.source + delta.header).find("double") == std::string::npos);
  CHECK(single_code(m, "slowarx", LinearForm::delta).source == delta.source);  // automatic = delta in float
  const Eigen::MatrixXd u = random_steps2();
  const Eigen::VectorXd ref = m.simulate(experiment(u), nlid::InitialCondition::zero).col(0);
  check_delta_beats_direct(delta, direct, u, ref, "delta_arx");
  check_double_code_is_direct(m, "slowarx_double");

  // No feedback (na = 0): the direct form in single precision too.
  const nlid::Arx fir(Eigen::VectorXd(0), {Eigen::Vector2d(0.5, 0.25)}, {1}, ts);
  CHECK(single_code(fir, "fir", LinearForm::automatic).source == single_code(fir, "fir", LinearForm::direct).source);
}

TEST_CASE("float code of a slow ARX model in delta form starts from nlid's equilibrium and from past samples",
          "[codegen][delta]") {
  using nlid::codegen::LinearForm;
  const nlid::Arx m = slow_arx();
  Eigen::MatrixXd u = random_steps2();
  u.topRows(300).col(0).setConstant(2.5);
  u.topRows(300).col(1).setConstant(-1.0);
  // Equilibrium for u0 = (2.5, -1): y = 2*2.5 - 1 + 0.5 = 4.5.
  const Eigen::VectorXd ref_eq = m.simulate(experiment(u), nlid::InitialCondition::equilibrium).col(0);
  const Eigen::VectorXd y_eq =
      nlid_test::run_generated_c(single_code(m, "slowarx_eq", LinearForm::automatic, Eigen::Vector2d(2.5, -1.0)), u,
                                 "delta_arx_eq", true);
  REQUIRE(y_eq.size() == ref_eq.size());
  INFO("equilibrium start: first outputs " << y_eq(0) << " vs nlid " << ref_eq(0) << ", max rel. error "
                                           << rel_error(y_eq, ref_eq));
  CHECK(std::abs(ref_eq(0) - 4.5) < 1e-9);
  // A start finite in double but beyond float's range would be written as HUGE_VALF and refused
  // by every step: generation refuses it instead.
  CHECK_THROWS_WITH(single_code(m, "slowarx_huge", LinearForm::direct, Eigen::Vector2d(1e300, 0.0)),
                    Catch::Contains("initial state x0[") && Catch::Contains("beyond float's range"));
  for (int t = 0; t < 300; ++t) CHECK(std::abs(y_eq(t) - ref_eq(t)) <= 4e-7 * std::abs(ref_eq(t)));
  CHECK(rel_error(y_eq, ref_eq) <= 1e-5);

  // Past samples after 1500 samples of ramps: x = [y(t-1) y(t-2), u1(t-1) u1(t-2), u2(t-1) .. u2(t-3)]
  // at t = 1500, mapped by generated_c_state; the C run from there against the rest of nlid's run.
  const Eigen::Index t0 = 1500;
  Eigen::MatrixXd uu(t0 + u.rows(), 2);
  for (Eigen::Index t = 0; t < t0; ++t) uu.row(t) << 0.004 * static_cast<double>(t), -0.002 * static_cast<double>(t);
  uu.bottomRows(u.rows()) = u;
  const Eigen::VectorXd yy = m.simulate(experiment(uu), nlid::InitialCondition::zero).col(0);
  Eigen::VectorXd x(7);
  x << yy(t0 - 1), yy(t0 - 2), uu(t0 - 1, 0), uu(t0 - 2, 0), uu(t0 - 1, 1), uu(t0 - 2, 1), uu(t0 - 3, 1);
  nlid::CodegenOptions o;
  o.precision = nlid::codegen::Precision::single_precision;
  const Eigen::VectorXd xc = nlid::generated_c_state(m, x, o);
  REQUIRE(xc.size() == 3);
  o.linear_form = LinearForm::direct;
  CHECK(nlid::generated_c_state(m, x, o) == x);  // the direct form's state is the past samples
  CHECK_THROWS_AS(nlid::generated_c_state(m, x.head(6), o), nlid::Error);
  const Eigen::VectorXd ref_x = yy.tail(u.rows());
  const Eigen::VectorXd y_x = run_from_state(single_code(m, "slowarx_x", LinearForm::automatic), u, xc, "delta_arx_x");
  REQUIRE(y_x.size() == ref_x.size());
  INFO("past samples " << x.transpose() << " -> delta state " << xc.transpose() << ": first outputs " << y_x(0) << ", "
                       << y_x(1) << " vs nlid " << ref_x(0) << ", " << ref_x(1));
  for (int t = 0; t < 20; ++t) CHECK(std::abs(y_x(t) - ref_x(t)) <= 4e-7 * std::abs(ref_x(t)));
  CHECK(rel_error(y_x, ref_x) <= 1e-5);
}

TEST_CASE("output-error code starts from past samples: generated_c_state, initial_state and AnyModel", "[codegen][delta]") {
  using nlid::codegen::LinearForm;
  // Input 1: the slow block (delta form in float); input 2: an FIR block (no feedback, kept as
  // past inputs in both forms). Offset 0.5.
  const Eigen::VectorXd b1 = Eigen::Vector2d(3e-6, 1e-6), f1 = Eigen::Vector2d(-1.997, 0.997002);
  const nlid::OutputError m({b1, Eigen::Vector2d(0.25, 0.25)}, {f1, Eigen::VectorXd()}, {1, 1}, ts, 0.5);
  const Eigen::MatrixXd u = random_steps2();
  // Ramps for t0 samples, then the random steps: nlid's run over both, and the past samples at t0.
  const Eigen::Index t0 = 1500;
  Eigen::MatrixXd uu(t0 + u.rows(), 2);
  for (Eigen::Index t = 0; t < t0; ++t) uu.row(t) << 0.004 * static_cast<double>(t), -0.002 * static_cast<double>(t);
  uu.bottomRows(u.rows()) = u;
  const Eigen::VectorXd yy = m.simulate(experiment(uu), nlid::InitialCondition::zero).col(0);
  const nlid::OutputError block1({b1}, {f1}, {1}, ts, 0.0);  // w1 alone
  const Eigen::VectorXd w1 = block1.simulate(experiment(uu.col(0)), nlid::InitialCondition::zero).col(0);
  Eigen::VectorXd x(6);  // [u1(t-1) u1(t-2) w1(t-1) w1(t-2), u2(t-1) u2(t-2)]
  x << uu(t0 - 1, 0), uu(t0 - 2, 0), w1(t0 - 1), w1(t0 - 2), uu(t0 - 1, 1), uu(t0 - 2, 1);
  const Eigen::VectorXd ref = yy.tail(u.rows());

  // Double code keeps the past samples: from them it continues nlid's run to the last bits.
  nlid::CodegenOptions od;
  od.name = "oe2_x_double";
  od.initial_state = x;
  CHECK(nlid::generated_c_state(m, x, od) == x);
  const Eigen::VectorXd y_double = nlid_test::run_generated_c(nlid::generate_c(m, od), u, "oe2_x_double", false);
  REQUIRE(y_double.size() == ref.size());
  CHECK(nlid_test::max_relative_error(y_double, ref) <= 1e-12);

  // Float code: block 1 holds its delta state, block 2 its past inputs.
  nlid::CodegenOptions o;
  o.precision = nlid::codegen::Precision::single_precision;
  const Eigen::VectorXd xc = nlid::generated_c_state(m, x, o);
  REQUIRE(xc.size() == 4);
  CHECK(xc.tail(2) == x.tail(2));
  const Eigen::VectorXd y_x = run_from_state(single_code(m, "oe2_x", LinearForm::automatic), u, xc, "delta_oe2_x");
  REQUIRE(y_x.size() == ref.size());
  INFO("past samples " << x.transpose() << " -> " << xc.transpose() << ": first outputs " << y_x(0) << ", " << y_x(1)
                       << " vs nlid " << ref(0) << ", " << ref(1));
  for (int t = 0; t < 20; ++t) CHECK(std::abs(y_x(t) - ref(t)) <= 4e-7 * std::abs(ref(t)));
  CHECK(rel_error(y_x, ref) <= 1e-5);
  // The same start written into NAME_x0 (CodegenOptions::initial_state).
  o.name = "oe2_x0";
  o.initial_state = x;
  const Eigen::VectorXd y_init = nlid_test::run_generated_c(nlid::generate_c(m, o), u, "delta_oe2_x0", true);
  REQUIRE(y_init.size() == ref.size());
  CHECK(rel_error(y_init, y_x) <= 1e-6);

  // Through a run-time handle, as for a model loaded from a file.
  const nlid::AnyModel any(m);
  CHECK(nlid::generated_c_state(any, x, o) == xc);
  CHECK_THROWS_WITH(nlid::generated_c_state(any, x.head(5), o), Catch::Contains("has 6 (past inputs and block outputs)"));
  CHECK_THROWS_WITH(nlid::generated_c_state(nlid::AnyModel(), x, o), Catch::Contains("empty"));

  // Refusals: a state of the wrong size; a state and an equilibrium at once.
  o.initial_state = x.head(5);
  CHECK_THROWS_WITH(nlid::generate_c(m, o), Catch::Contains("initial_state has 5 values, the model's state has 6"));
  o.initial_state = x;
  o.equilibrium_input = Eigen::Vector2d(0.0, 0.0);
  CHECK_THROWS_WITH(nlid::generate_c(m, o), Catch::Contains("both set"));
}

TEST_CASE("Hammerstein-Wiener code starts from a given block state (CodegenOptions::initial_state)", "[codegen][delta]") {
  const SlowHw m = slow_hw();
  const Eigen::MatrixXd u = random_steps();
  const Eigen::Vector2d x(1.5e-3, -1.4985e-3);  // registers of a block in motion
  Eigen::VectorXd ref(u.rows());
  const Eigen::VectorXd theta = m.parameters();
  REQUIRE(m.simulate<double>(u, std::span<const double>(theta.data(), static_cast<std::size_t>(theta.size())),
                             std::span<const double>(x.data(), 2), std::span<double>(ref.data(), static_cast<std::size_t>(ref.size()))));
  nlid::CodegenOptions o;
  o.name = "slowhw_given";
  o.initial_state = x;
  const Eigen::VectorXd y_double = nlid_test::run_generated_c(nlid::generate_c(m, o), u, "hw_given_double", false);
  CHECK(nlid_test::max_relative_error(y_double, ref) <= 1e-12);
  o.name = "slowhw_given_f";
  o.precision = nlid::codegen::Precision::single_precision;
  const Eigen::VectorXd y_float = nlid_test::run_generated_c(nlid::generate_c(m, o), u, "hw_given_float", true);
  CHECK(rel_error(y_float, ref) <= 1e-4);
  CHECK(std::abs(ref(0)) > 1e-3);  // the given state shows in the output
  o.initial_state = Eigen::Vector3d::Zero();
  CHECK_THROWS_WITH(nlid::generate_c(m, o), Catch::Contains("initial_state has 3 values") &&
                                                Catch::Contains("the linear block's registers"));
  o.initial_state = Eigen::Vector2d(std::nan(""), 0.0);
  CHECK_THROWS_WITH(nlid::generate_c(m, o), Catch::Contains("initial_state[0]") && Catch::Contains("not finite"));
}

TEST_CASE("float code of a block with a long input delay keeps the delay as plain registers", "[codegen][delta]") {
  // The slow block of slow_hw() behind 20 samples of delay: n = nk + nb - 1 = 21 states, of
  // which only nf = 2 carry feedback. In delta form over all 21, the delay's poles at z = 0
  // became binomial coefficients up to C(21, 10) ~ 3.5e5 that cancel in float, and the step
  // diverged (ARX nk = 25: outputs of 1e32). The delta part now covers the 2 feedback states.
  using nlid::codegen::LinearForm;
  using Delayed = nlid::TransferFunctionBlock<2, 2, 20>;
  using DelayedHw = nlid::HammersteinWiener<nlid::UnitGain, Delayed, nlid::Saturation>;
  DelayedHw m(nlid::UnitGain{}, Delayed{}, nlid::Saturation{}, ts);
  Eigen::VectorXd th(6);
  th << 3e-6, 1e-6, -1.997, 0.997002, -20.0, 20.0;
  m.set_parameters(th);
  const nlid::codegen::DeltaBlock d = nlid::codegen::delta_block(m.linear_block(), m.linear_parameters());
  CHECK(d.n == 21);
  CHECK(d.h == 2);
  CHECK(d.c == std::vector<double>{0.0, 0.0, 0.0});  // B's coefficients all sit in the delay
  REQUIRE(d.tail.size() == 19);
  CHECK(d.tail[17] == 3e-6);  // beta_20 = b1
  CHECK(d.tail[18] == 1e-6);  // beta_21 = b2
  for (int i = 0; i < 17; ++i) CHECK(d.tail[static_cast<std::size_t>(i)] == 0.0);
  // The state map: Taylor shift on the two feedback registers, the delay registers as they are.
  Eigen::VectorXd s = Eigen::VectorXd::LinSpaced(21, 1.0, 21.0);
  const Eigen::VectorXd e = d.state_from_tdf2(s);
  CHECK(e(0) == 1.0);
  CHECK(e(1) == 3.0);
  CHECK(e.tail(19) == s.tail(19));
  CHECK_THAT(d.describe(), Catch::Contains("e_3 .. e_21 are the input delay's registers"));

  const nlid::GeneratedCode delta = single_code(m, "delayhw", LinearForm::automatic);
  const nlid::GeneratedCode direct = single_code(m, "delayhw_direct", LinearForm::direct);
  CHECK(delta.header.find("delta-operator form") != std::string::npos);
  const Eigen::MatrixXd u = random_steps();
  check_delta_beats_direct(delta, direct, u, m.simulate(experiment(u), nlid::InitialCondition::zero).col(0),
                           "delay_hw");

  // From the equilibrium for u0 = 2.5, and from the registers after 1500 samples of a ramp
  // (the delay line then holds 20 different inputs).
  Eigen::MatrixXd ue = u;
  ue.topRows(200).setConstant(2.5);
  const Eigen::VectorXd ref_eq = m.simulate(experiment(ue), nlid::InitialCondition::equilibrium).col(0);
  const Eigen::VectorXd y_eq = nlid_test::run_generated_c(
      single_code(m, "delayhw_eq", LinearForm::automatic, Eigen::VectorXd::Constant(1, 2.5)), ue, "delay_hw_eq", true);
  REQUIRE(y_eq.size() == ref_eq.size());
  for (int t = 0; t < 200; ++t) CHECK(std::abs(y_eq(t) - ref_eq(t)) <= 4e-7 * std::abs(ref_eq(t)));
  CHECK(rel_error(y_eq, ref_eq) <= 1e-5);
  std::vector<double> reg(21, 0.0);
  const std::vector<double> lt(m.linear_parameters().begin(), m.linear_parameters().end());
  for (int t = 0; t < 1500; ++t)
    (void)m.linear_block().step(std::span<double>(reg), 0.004 * t, std::span<const double>(lt));
  const Eigen::VectorXd x = Eigen::Map<const Eigen::VectorXd>(reg.data(), 21);
  nlid::CodegenOptions o;
  o.precision = nlid::codegen::Precision::single_precision;
  const Eigen::VectorXd xc = nlid::generated_c_state(m, x, o);
  Eigen::VectorXd ref_x(u.rows());
  const std::span<const double> theta(m.parameters().data(), static_cast<std::size_t>(m.parameters().size()));
  REQUIRE(m.simulate<double>(u, theta, std::span<const double>(x.data(), 21),
                             std::span<double>(ref_x.data(), static_cast<std::size_t>(ref_x.size()))));
  const Eigen::VectorXd y_x = run_from_state(single_code(m, "delayhw_x", LinearForm::automatic), u, xc, "delay_hw_x");
  REQUIRE(y_x.size() == ref_x.size());
  for (int t = 0; t < 40; ++t) CHECK(std::abs(y_x(t) - ref_x(t)) <= 4e-7 * std::abs(ref_x(t)));
  CHECK(rel_error(y_x, ref_x) <= 1e-5);
}

TEST_CASE("float code of an ARX model with nk = 25 tracks nlid", "[codegen][delta]") {
  // The reviewer's case: na = 2, nb = 2, nk = 25, slow A; 26 states in delta form diverged.
  using nlid::codegen::LinearForm;
  const nlid::Arx m(Eigen::Vector2d(-1.997, 0.997002), {Eigen::Vector2d(3e-6, 1e-6)}, {25}, ts, 1e-6);
  nlid::CodegenOptions so;
  so.precision = nlid::codegen::Precision::single_precision;
  const auto db = nlid::codegen::detail::arx_delta_block(m, so);
  REQUIRE(db);
  CHECK(db->n == 26);
  CHECK(db->h == 2);
  const nlid::GeneratedCode delta = single_code(m, "delayarx", LinearForm::automatic);
  const nlid::GeneratedCode direct = single_code(m, "delayarx_direct", LinearForm::direct);
  const Eigen::MatrixXd u = random_steps();
  check_delta_beats_direct(delta, direct, u, m.simulate(experiment(u), nlid::InitialCondition::zero).col(0),
                           "delay_arx");
  Eigen::MatrixXd ue = u;
  ue.topRows(300).setConstant(2.5);
  const Eigen::VectorXd ref_eq = m.simulate(experiment(ue), nlid::InitialCondition::equilibrium).col(0);
  const Eigen::VectorXd y_eq = nlid_test::run_generated_c(
      single_code(m, "delayarx_eq", LinearForm::automatic, Eigen::VectorXd::Constant(1, 2.5)), ue, "delay_arx_eq", true);
  REQUIRE(y_eq.size() == ref_eq.size());
  CHECK(rel_error(y_eq, ref_eq) <= 1e-5);
}
