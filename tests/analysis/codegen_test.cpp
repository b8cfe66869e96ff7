// Generated C code: the tracer (literals, folding, branch exploration, limits), and the real
// test of the feature — generated C for an nlarx with a custom regressor + sigmoid net, a
// Hammerstein-Wiener with piecewise-linear input and saturated output, and the throttle grey box
// is compiled with the system C compiler (-std=c99 -Wall -Wextra -pedantic -Werror), run on the
// throttle data (data3 at 100 Hz) and must match nlid's own simulation to 1e-12 relative; their
// single-precision versions must contain no double and stay within float rounding of it.
#include <catch2/catch.hpp>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

// Before the custom regressor's lambda (nlid::max on TraceScalar). The three generators this file
// uses, not the umbrella: it also holds the run-time, series, linear and diagnosis generators.
#include "nlid/codegen/greybox.hpp"
#include "nlid/codegen/hammerstein_wiener.hpp"
#include "nlid/codegen/nlarx.hpp"
#include "nlid/data/csv.hpp"
#include "nlid/data/resample.hpp"
#include "nlid/models/physics/throttle.hpp"
#include "nlid/models/transfer_function_block.hpp"
#include "nlid/nonlinearities/dead_zone.hpp"
#include "nlid/nonlinearities/piecewise_linear.hpp"
#include "nlid/nonlinearities/polynomial.hpp"
#include "nlid/nonlinearities/wavelet_network.hpp"
#include "nlid/nonlinearities/saturation.hpp"
#include "nlid/nonlinearities/sigmoid_network.hpp"
#include "nlid/regressors.hpp"

#include "../support/decimal_comma_locale.hpp"
#include "../support/generated_c.hpp"


namespace {

nlid::Experiment throttle(int k) {
  const nlid::Experiment e =
      nlid::read_csv(std::string(NLID_TEST_DATA_DIR) + "/throttle/data" + std::to_string(k) + ".csv");
  nlid::Experiment d = nlid::decimate(e, 10);
  d.set_name("data" + std::to_string(k));
  return d;
}

auto spring() {
  return nlid::custom_regressor<nlid::OutputLag<1>>(
      "max(y1(t-1),90)+min(y1(t-1),15)-105",
      [](auto y1) { return nlid::max(y1, 90.0) + nlid::min(y1, 15.0) - 105.0; });
}

// Equilibrium starts of physics with no input and with two: NAME_init's comment names every input.
struct Decay {
  static constexpr int num_states = 1, num_inputs = 0, num_outputs = 1, num_params = 1;
  std::array<nlid::ParameterInfo, 1> parameter_info() const { return {{{"a", "", "", 2.0, 0.0, INFINITY}}}; }
  template <class T>
  void derivative(const T* x, const T*, const T* p, T* dx) const { dx[0] = -p[0] * x[0]; }
  template <class T>
  void output(const T* x, const T*, const T*, T* y) const { y[0] = x[0]; }
};

struct TwoInputLag {
  static constexpr int num_states = 1, num_inputs = 2, num_outputs = 1, num_params = 1;
  std::array<nlid::ParameterInfo, 1> parameter_info() const { return {{{"a", "", "", 2.0, 0.0, INFINITY}}}; }
  template <class T>
  void derivative(const T* x, const T* u, const T* p, T* dx) const { dx[0] = -p[0] * (x[0] - u[0] - u[1]); }
  template <class T>
  void output(const T* x, const T*, const T*, T* y) const { y[0] = x[0]; }
};

using nlid_test::check_single_precision;
using nlid_test::max_relative_error;
using nlid_test::run_generated_c;
}  // namespace

TEST_CASE("C literals read back to the same double", "[codegen]") {
  for (double v : {0.1, -2.5e-300, 1.0 / 3.0, 90.0, -0.0, 6.02214076e23}) {
    std::string s = nlid::codegen::c_literal(v);
    if (s.front() == '(') s = s.substr(1, s.size() - 2);
    CHECK(std::strtod(s.c_str(), nullptr) == v);
  }
  CHECK(nlid::codegen::c_literal(90.0) == "90.0");
  CHECK(nlid::codegen::c_literal(-1.5) == "(-1.5)");
  CHECK(nlid::codegen::c_literal(std::numeric_limits<double>::infinity()) == "HUGE_VAL");
}

TEST_CASE("generated C is the same under a locale with decimal commas", "[codegen]") {
  // snprintf follows LC_NUMERIC: a program that had set de_DE got "0,5" in its generated C, which
  // in an initialiser list compiles to two other numbers.
  using Block = nlid::TransferFunctionBlock<2, 2, 1>;
  using Model = nlid::HammersteinWiener<nlid::PwLinear<3>, Block, nlid::Saturation>;
  Model m(nlid::PwLinear<3>{}, Block{}, nlid::Saturation{}, 0.01);
  Eigen::VectorXd th = Eigen::VectorXd::LinSpaced(m.num_parameters(), 0.125, 0.875);
  m.set_parameters(th);
  nlid::CodegenOptions o;
  o.name = "hw_locale";
  const nlid::GeneratedCode in_c = nlid::generate_c(m, o);
  o.precision = nlid::codegen::Precision::single_precision;
  const nlid::GeneratedCode single_in_c = nlid::generate_c(m, o);
  const nlid_test::DecimalCommaLocale comma;
  if (nlid_test::DecimalCommaLocale::required()) REQUIRE(comma.active());
  if (!comma.active()) {
    WARN("no locale with decimal commas installed: not checked");
    return;
  }
  CHECK(nlid::codegen::c_literal(0.5) == "0.5");
  CHECK(nlid::detail::format_g(-1.25e-7, 3) == "-1.25e-07");
  const nlid::GeneratedCode g = nlid::generate_c(m, o);
  CHECK(g.source == single_in_c.source);
  o.precision = nlid::codegen::Precision::double_precision;
  const nlid::GeneratedCode d = nlid::generate_c(m, o);
  CHECK(d.source == in_c.source);
  CHECK(d.header == in_c.header);
}

TEST_CASE("single-precision C literals and names read back to the nearest float", "[codegen]") {
  const nlid::codegen::PrecisionScope single(nlid::codegen::Precision::single_precision);
  for (double v : {0.1, 1.0 / 3.0, 90.0, -0.0, 6.02214076e23, 1e-40}) {
    std::string s = nlid::codegen::c_literal(v);
    if (s.front() == '(') s = s.substr(1, s.size() - 2);
    REQUIRE(s.back() == 'f');
    s.pop_back();
    CHECK(std::strtof(s.c_str(), nullptr) == static_cast<float>(v));
  }
  CHECK(nlid::codegen::c_literal(90.0) == "90.0f");
  CHECK(nlid::codegen::c_literal(-1.5) == "(-1.5f)");
  CHECK(nlid::codegen::c_literal(1e300) == "HUGE_VALF");  // beyond float's range
  CHECK(nlid::codegen::c_literal(-1e300) == "(-HUGE_VALF)");
  CHECK(nlid::codegen::c_literal(0x1.fffffep127) == "3.40282347e+38f");  // FLT_MAX itself
  CHECK(nlid::codegen::c_literal(0x1.ffffffp127) == "HUGE_VALF");        // rounds to infinity
  CHECK(nlid::codegen::c_real() == "float");
  CHECK(nlid::codegen::c_math("log1p") == "log1pf");
  {
    const nlid::codegen::PrecisionScope inner(nlid::codegen::Precision::double_precision);
    CHECK(nlid::codegen::c_literal(0.1) == "0.10000000000000001");
  }
  CHECK(nlid::codegen::c_literal(0.1) == "0.100000001f");  // the scope restored single
}

TEST_CASE("tracing: folding, parameters, branch exploration and limits", "[codegen]") {
  using nlid::TraceScalar;
  // Literals fold, parameters stay named, signals produce SSA lines.
  const auto f = nlid::codegen::trace_paths([] {
    const TraceScalar x = TraceScalar::signal("u[0]");
    const TraceScalar p = TraceScalar::parameter("m_p[0]", 2.0);
    const TraceScalar c = TraceScalar(3.0) * TraceScalar(0.5);
    return std::vector<TraceScalar>{x * p + c};
  });
  CHECK(f.paths == 1);
  const std::string code = nlid::codegen::emit_c(f, {"y[0]"});
  CHECK(code.find("u[0] * m_p[0]") != std::string::npos);
  CHECK(code.find("+ 1.5") != std::string::npos);
  // A saturation branches twice on its signal: three paths, nested if/else.
  nlid::Saturation sat;
  const std::vector<double> lim{15.0, 90.0};
  const auto g = nlid::codegen::trace_paths([&] {
    const TraceScalar x = TraceScalar::signal("u[0]");
    const auto th = nlid::codegen::parameters("m", lim);
    return std::vector<TraceScalar>{sat(std::span<const TraceScalar>(&x, 1), std::span<const TraceScalar>(th))};
  });
  CHECK(g.paths == 3);
  const std::string sc = nlid::codegen::emit_c(g, {"y[0]"});
  CHECK(sc.find("if (u[0] < m_p[0])") != std::string::npos);
  CHECK(sc.find("y[0] = m_p[1];") != std::string::npos);
  // Comparing parameters only is decided at generation time (no branch in the code).
  const auto h = nlid::codegen::trace_paths([] {
    const TraceScalar a = TraceScalar::parameter("m_p[0]", 1.0), b = TraceScalar::parameter("m_p[1]", 2.0);
    return std::vector<TraceScalar>{a < b ? a : b};
  });
  CHECK(h.paths == 1);
  // Too many paths: an error, not exponential code.
  nlid::codegen::TraceLimits lim8;
  lim8.max_paths = 8;
  CHECK_THROWS_WITH(nlid::codegen::trace_paths(
                        [] {
                          TraceScalar acc = 0.0;
                          for (int i = 0; i < 5; ++i) {
                            const TraceScalar x = TraceScalar::signal("u[" + std::to_string(i) + "]");
                            acc += x > TraceScalar(0.0) ? x : -x;
                          }
                          return std::vector<TraceScalar>{acc};
                        },
                        lim8),
                    Catch::Contains("more than 8 paths"));
  // A traced signal used outside a trace is an error.
  CHECK_THROWS_WITH(TraceScalar::signal("u[0]") + 1.0, Catch::Contains("outside a trace"));
}

TEST_CASE("tracing: each math function emits its own C function, two-argument ones in argument order", "[codegen]") {
  using nlid::TraceScalar;
  const auto f = nlid::codegen::trace_paths([] {
    const TraceScalar a = TraceScalar::signal("u[0]"), b = TraceScalar::signal("u[1]");
    return std::vector<TraceScalar>{nlid::atan2(a, b), nlid::hypot(a, b), nlid::pow(a, b), nlid::cbrt(a),
                                    nlid::sqrt(a), nlid::expm1(a), nlid::log1p(a), nlid::log10(a),
                                    nlid::erf(a), nlid::tanh(a), nlid::fabs(a)};
  });
  const std::string code =
      nlid::codegen::emit_c(f, {"y[0]", "y[1]", "y[2]", "y[3]", "y[4]", "y[5]", "y[6]", "y[7]", "y[8]", "y[9]", "y[10]"});
  INFO(code);
  for (const char* call : {"atan2(u[0], u[1])", "hypot(u[0], u[1])", "pow(u[0], u[1])", "cbrt(u[0])", "sqrt(u[0])",
                           "expm1(u[0])", "log1p(u[0])", "log10(u[0])", "erf(u[0])", "tanh(u[0])", "fabs(u[0])"}) {
    CAPTURE(call);
    CHECK(code.find(call) != std::string::npos);
  }
  // On literals the same functions fold to the C library's values.
  CHECK(nlid::atan2(TraceScalar(1.0), TraceScalar(-2.0)).value() == std::atan2(1.0, -2.0));
  CHECK(nlid::cbrt(TraceScalar(-27.0)).value() == std::cbrt(-27.0));
  CHECK(nlid::cbrt(TraceScalar(-27.0)).value() == Approx(-3.0).epsilon(1e-15));
}

TEST_CASE("generated C of an nlarx with a custom regressor and a sigmoid net matches nlid to 1e-12", "[codegen]") {
  using Regs = nlid::RegressorSet<nlid::LaggedRegressors<2, 1, 0>, decltype(spring())>;
  using Model = nlid::Nlarx<Regs, nlid::SigmoidNet<4, 5>>;
  const nlid::Experiment e1 = throttle(1), e3 = throttle(3);
  Model m(Regs(nlid::LaggedRegressors<2, 1, 0>{}, spring()), nlid::SigmoidNet<4, 5>{}, e1.ts());
  const Eigen::MatrixXd X = m.regressor_values(e1);
  Eigen::VectorXd theta(m.num_parameters());
  m.nonlinearity().initialize(X, e1.y().col(0).tail(X.rows()), std::span<double>(theta.data(), theta.size()));
  m.set_parameters(theta);
  const Eigen::VectorXd ref = m.simulate(e3, nlid::InitialCondition::zero).col(0);
  nlid::CodegenOptions o;
  o.name = "nlarx_sig";
  const nlid::GeneratedCode g = nlid::generate_c(m, o);
  CHECK(g.source.find("nlid_logistic") != std::string::npos);
  CHECK(g.source.find(">= 90.0 ?") != std::string::npos);  // the custom regressor's max
  CHECK(g.header.find("#define NLARX_SIG_NUM_STATES 2") != std::string::npos);
  const Eigen::VectorXd yc = run_generated_c(g, e3.u(), "nlarx");
  REQUIRE(yc.size() == ref.size());
  CHECK(max_relative_error(yc, ref) <= 1e-12);
  // This free run is sensitive: nlid's own double simulation moves by 4.7e-4 of its range when
  // the parameters change by float's relative rounding (6e-8), so float code cannot be closer.
  check_single_precision(m, o, e3.u(), ref, 2e-3);
}

TEST_CASE("generated C of a Hammerstein-Wiener with pwlinear input and saturated output matches nlid", "[codegen]") {
  using Block = nlid::TransferFunctionBlock<3, 3, 0>;
  using Model = nlid::HammersteinWiener<nlid::PwLinear<4>, Block, nlid::Saturation>;
  const nlid::Experiment e3 = throttle(3);
  Model m(nlid::PwLinear<4>{}, Block{}, nlid::Saturation{}, e3.ts());
  Eigen::VectorXd th(16);
  std::vector<double> pw(8);
  const std::vector<double> bx{-0.5, 0.0, 0.3, 1.0}, by{-5.0, 3.0, 20.0, 40.0};
  m.input_nonlinearity().theta_from_breakpoints(bx, by, pw);
  for (int i = 0; i < 8; ++i) th(i) = pw[static_cast<std::size_t>(i)];
  // B = [0.02 0.01 0.005], F from poles 0.9, 0.8, 0.5 (DC gain 3.5); saturation [15, 90].
  th.segment(8, 6) << 0.02, 0.01, 0.005, -2.2, 1.57, -0.36;
  th.tail(2) << 15.0, 90.0;
  m.set_parameters(th);
  const Eigen::VectorXd ref = m.simulate(e3, nlid::InitialCondition::zero).col(0);
  REQUIRE(ref.maxCoeff() == 90.0);  // the run exercises the upper limit ...
  REQUIRE(ref.minCoeff() == 15.0);  // ... and the lower one
  nlid::CodegenOptions o;
  o.name = "nlhw";
  const nlid::GeneratedCode g = nlid::generate_c(m, o);
  // pwlinear: 4 paths (3 segments; the C++ tests x < x_end before "|| last segment", so the last
  // segment is reached by both outcomes of that test), saturation: 3 regions.
  CHECK(g.paths == 4 * 3);
  // The coefficients belong to the model's sample time: relabelling them is refused, repeating it
  // is not.
  nlid::CodegenOptions relabelled = o;
  relabelled.ts = 2 * e3.ts();
  CHECK_THROWS_WITH(nlid::generate_c(m, relabelled), Catch::Contains("estimated at sample time 0.01 s") &&
                                                         Catch::Contains("cannot run at CodegenOptions::ts = 0.02"));
  relabelled.ts = e3.ts();
  CHECK(nlid::generate_c(m, relabelled).source == g.source);
  const Eigen::VectorXd yc = run_generated_c(g, e3.u(), "hw");
  REQUIRE(yc.size() == ref.size());
  CHECK(max_relative_error(yc, ref) <= 1e-12);
  check_single_precision(m, o, e3.u(), ref, 1e-4);
}

TEST_CASE("generated C of a wavelet-network nlarx and a dead-zone/polynomial HW matches nlid", "[codegen]") {
  const nlid::Experiment e1 = throttle(1), e3 = throttle(3);
  using Wn = nlid::Nlarx<nlid::LaggedRegressors<2, 2, 1>, nlid::WaveletNet<4, 3>>;
  Wn w(nlid::LaggedRegressors<2, 2, 1>{}, nlid::WaveletNet<4, 3>{}, e1.ts());
  const Eigen::MatrixXd X = w.regressor_values(e1);
  Eigen::VectorXd theta(w.num_parameters());
  w.nonlinearity().initialize(X, e1.y().col(0).tail(X.rows()), std::span<double>(theta.data(), theta.size()));
  w.set_parameters(theta);
  const Eigen::VectorXd ref_w = w.predict(e3, 1).col(0);  // one-step: bounded whatever the free run does
  nlid::CodegenOptions o;
  o.name = "wavenet";
  const nlid::GeneratedCode gw = nlid::generate_c(w, o);
  CHECK(gw.paths == 1);  // radial units: no branches
  // The generated step is the free run; compare it with nlid's free run where that is finite.
  Eigen::VectorXd sim(e3.size());
  const bool finite = w.simulate<double>(e3.u(), nlid::detail::as_const_span(w.parameters()), {}, nlid::detail::as_span(sim));
  REQUIRE(finite);
  const Eigen::VectorXd yw = run_generated_c(gw, e3.u(), "wavenet");
  REQUIRE(yw.size() == sim.size());
  CHECK(max_relative_error(yw, sim) <= 1e-12);
  (void)ref_w;

  using Block = nlid::TransferFunctionBlock<2, 2, 1>;
  using Hw = nlid::HammersteinWiener<nlid::DeadZone, Block, nlid::Poly1d<3>>;
  Hw m(nlid::DeadZone{}, Block{}, nlid::Poly1d<3>{}, e3.ts());
  Eigen::VectorXd th(10);
  th << 0.1, 0.3,                // dead zone [0.1, 0.3]
      0.5, 0.2, -1.3, 0.42,      // B, F (stable)
      15.0, 30.0, 2.0, -0.5;     // h(x) = 15 + 30x + 2x^2 - 0.5x^3
  m.set_parameters(th);
  const Eigen::VectorXd ref = m.simulate(e3, nlid::InitialCondition::zero).col(0);
  o.name = "dzpoly";
  const nlid::GeneratedCode g = nlid::generate_c(m, o);
  CHECK(g.paths == 3);
  const Eigen::VectorXd yc = run_generated_c(g, e3.u(), "dzpoly");
  REQUIRE(yc.size() == ref.size());
  CHECK(max_relative_error(yc, ref) <= 1e-12);
}

TEST_CASE("generated C of the throttle grey box (RK4, smoothed stops) matches nlid from an equilibrium", "[codegen]") {
  const nlid::Experiment e3 = throttle(3);
  nlid::GreyBox<nlid::physics::Throttle> g;
  Eigen::VectorXd p(7);
  p << 30.0, 400.0, 4e4, 64000.0, 15.0, 90.0, 10.0;
  g.set_parameters(p);
  const Eigen::VectorXd ref = g.simulate(e3, nlid::InitialCondition::equilibrium).col(0);
  REQUIRE(ref.maxCoeff() > 90.0);  // reaches the upper stop: contact branches are exercised
  nlid::CodegenOptions o;
  o.name = "throttle_model";
  o.ts = e3.ts();
  o.equilibrium_input = e3.u().row(0).transpose();
  const nlid::GeneratedCode code = nlid::generate_c(g, o);
  CHECK(code.source.find("#define THROTTLE_MODEL_SUBSTEPS " + std::to_string(g.substeps(e3.ts()))) != std::string::npos);
  CHECK(code.source.find("log1p") != std::string::npos);  // the smoothed contact
  const Eigen::VectorXd yc = run_generated_c(code, e3.u(), "greybox");
  REQUIRE(yc.size() == ref.size());
  CHECK(max_relative_error(yc, ref) <= 1e-12);
  check_single_precision(g, o, e3.u(), ref, 1e-4);
}

TEST_CASE("grey-box code from an equilibrium names every held input, and none for a physics without inputs",
          "[codegen]") {
  nlid::CodegenOptions o;
  o.name = "decay";
  o.ts = 0.1;
  o.equilibrium_input = Eigen::VectorXd(0);  // the only input vector of a physics without inputs
  const nlid::GeneratedCode none = nlid::generate_c(nlid::GreyBox<Decay>(), o);
  CHECK(none.header.find("the equilibrium with no input") != std::string::npos);
  o.equilibrium_input = Eigen::VectorXd::Zero(1);
  CHECK_THROWS_WITH(nlid::generate_c(nlid::GreyBox<Decay>(), o), Catch::Contains("takes 0 input(s)"));

  o.name = "lag2";
  o.equilibrium_input = Eigen::Vector2d(1.0, 2.0);
  const nlid::GeneratedCode two = nlid::generate_c(nlid::GreyBox<TwoInputLag>(), o);
  CHECK(two.header.find("the equilibrium for u held at [1, 2]") != std::string::npos);
  CHECK(two.source.find("the equilibrium for u held at [1, 2]") != std::string::npos);
}

TEST_CASE("codegen refuses a name that would write a header shadowing a C standard header", "[codegen]") {
  for (const char* h : {"assert", "complex", "ctype", "errno", "fenv", "float", "inttypes", "iso646", "limits", "locale",
                        "math", "setjmp", "signal", "stdarg", "stdbool", "stddef", "stdint", "stdio", "stdlib", "string",
                        "tgmath", "time", "wchar", "wctype"}) {
    INFO(h);
    CHECK_THROWS_WITH(nlid::codegen::check_name(h),
                      Catch::Contains("is the name of the C standard header <" + std::string(h) + ".h>") &&
                          Catch::Contains("choose another name"));
  }
  // Header names are case-sensitive in C; a prefix or suffix is another file.
  for (const char* ok : {"Math", "MATH", "math_model", "my_stdio", "timer"}) CHECK_NOTHROW(nlid::codegen::check_name(ok));
  nlid::GreyBox<nlid::physics::Throttle> g;
  nlid::CodegenOptions o;
  o.name = "math";
  o.ts = 0.01;
  CHECK_THROWS_WITH(nlid::generate_c(g, o), Catch::Contains("<math.h>"));
}

TEST_CASE("codegen refuses a grey box whose values break the physics' relations (stops crossed by set_parameter)",
          "[codegen]") {
  nlid::GreyBox<nlid::physics::Throttle> g;
  nlid::CodegenOptions o;
  o.name = "valve";
  o.ts = 0.01;
  REQUIRE_NOTHROW(nlid::generate_c(g, o));
  g.set_parameter("lower_stop", g.parameter("upper_stop") + 1.0);  // one value at a time: not checked here
  CHECK_THROWS_WITH(nlid::generate_c(g, o), Catch::Contains("code generation for grey-box model") &&
                                                Catch::Contains("must be below upper_stop"));
}

TEST_CASE("codegen rejects bad names, missing sample times and the adaptive integrator", "[codegen]") {
  nlid::GreyBox<nlid::physics::Throttle> g;
  nlid::CodegenOptions o;
  o.name = "2fast";
  o.ts = 0.01;
  CHECK_THROWS_WITH(nlid::generate_c(g, o), Catch::Contains("is not a C identifier"));
  o.name = "ok";
  o.ts = 0.0;
  CHECK_THROWS_WITH(nlid::generate_c(g, o), Catch::Contains("set CodegenOptions::ts"));
  o.ts = 0.01;
  nlid::IntegratorOptions io;
  io.method = nlid::IntegratorMethod::dormand_prince;
  g.set_integrator(io);
  CHECK_THROWS_WITH(nlid::generate_c(g, o), Catch::Contains("Dormand-Prince"));
  const nlid::GeneratedCode none{};
  CHECK_THROWS_WITH(none.write("/nonexistent/dir"), Catch::Contains("does not exist"));
  // A sample time so long that the automatic rule hits its sub-step ceiling with a step beyond
  // RK4's stability limit (ρ ≈ 100 1/s at the default stop stiffness; 100 s needs 10⁴ sub-steps):
  // the generated code would blow up on the target, so generation refuses, saying what to do.
  g.set_integrator(nlid::IntegratorOptions{});
  o.ts = 100.0;
  CHECK_THROWS_WITH(nlid::generate_c(g, o), Catch::Contains("needs 1") && Catch::Contains("more than the ceiling of 2000") &&
                                                Catch::Contains("CodegenOptions::substeps"));
  o.substeps = 20000;  // the user's explicit choice stands when it is stable
  CHECK_NOTHROW(nlid::generate_c(g, o));
  o.substeps = 1000;  // h·ρ/n ≈ 10 > 2.78: an explicit count RK4 cannot keep stable is refused too
  CHECK_THROWS_WITH(nlid::generate_c(g, o), Catch::Contains("CodegenOptions::substeps = 1000 gives an unstable") &&
                                                Catch::Contains("needs at least 3"));
  o.substeps = 0;
  // The library's own simulation names the same cause when it diverges there.
  // (a command that drives the valve onto its upper stop, where the contact stiffness acts)
  const nlid::Experiment slow(Eigen::MatrixXd::Constant(5, 1, 2.0), Eigen::MatrixXd::Zero(5, 1), 100.0);
  CHECK_THROWS_WITH(g.simulate(slow, nlid::InitialCondition::zero),
                    Catch::Contains("too long for the model's stiffness") && Catch::Contains("max_substeps = 2000"));
}

namespace {

// Steps generated code over `u` (one input per line, "nan"/"inf" allowed) and returns, per
// sample, NAME_step's return value and y[0].
struct CheckedRun {
  std::vector<int> status;
  std::vector<double> y;
};
CheckedRun run_checked(const nlid::GeneratedCode& g, const std::vector<double>& u, const std::string& tag, bool single) {
  const std::filesystem::path dir = nlid_test::scratch_dir() / ("checked_" + tag);
  std::filesystem::create_directories(dir);
  g.write(dir.string());
  const std::string n = g.name;
  std::ofstream(dir / "driver.c") << "#include <stdio.h>\n#include \"" << n << ".h\"\n"
                                  << "int main(int argc, char** argv) {\n  " << n << "_real u[1], y[1];\n  double v;\n  "
                                  << n << "_state s;\n  FILE* in = argc > 1 ? fopen(argv[1], \"r\") : NULL;\n"
                                  << "  if (!in) return 2;\n  " << n << "_init(&s);\n"
                                  << "  while (fscanf(in, \"%lf\", &v) == 1) {\n    int r;\n    u[0] = (" << n << "_real)v;\n"
                                  << "    r = " << n << "_step(&s, u, y);\n    printf(\"%d %.17g\\n\", r, (double)y[0]);\n  }\n"
                                  << "  fclose(in);\n  return 0;\n}\n";
  {
    std::ofstream in(dir / "u.txt");
    for (double v : u) {
      char b[40];
      std::snprintf(b, sizeof b, "%.17g\n", v);
      in << b;
    }
  }
  nlid_test::compile_and_run_driver(dir, n, single);
  CheckedRun r;
  std::ifstream out(dir / "y.txt");
  std::string line;
  while (std::getline(out, line)) {
    std::istringstream l(line);
    int st = -1;
    std::string yv;
    l >> st >> yv;
    r.status.push_back(st);
    r.y.push_back(std::strtod(yv.c_str(), nullptr));
  }
  return r;
}

}  // namespace

TEST_CASE("generated step refuses a non-finite input and keeps its state so that one bad sample does not poison it",
          "[codegen]") {
  // Before, a single NaN input (a failed sensor read) entered the lag window / filter registers
  // / integrator state and every later output was NaN until the caller re-initialised. Now
  // NAME_step returns 1 for that sample and leaves the state as it was: the run with the bad
  // samples inserted equals the clean run on every good sample, bit for bit.
  const nlid::Experiment e3 = throttle(3);
  const int n = 400;
  std::vector<double> clean(e3.u().col(0).data(), e3.u().col(0).data() + n);
  std::vector<double> bad;
  std::vector<bool> inserted;
  for (int t = 0; t < n; ++t) {
    if (t == 150 || t == 250 || t == 260) {
      bad.push_back(t == 150 ? std::numeric_limits<double>::quiet_NaN()
                             : (t == 250 ? std::numeric_limits<double>::infinity() : -std::numeric_limits<double>::infinity()));
      inserted.push_back(true);
    }
    bad.push_back(clean[static_cast<std::size_t>(t)]);
    inserted.push_back(false);
  }
  // Three kinds of state: a lag window (nlarx), filter registers (Hammerstein-Wiener), an
  // integrated physical state (grey box, whose output y = g(x) stays finite on a NaN input).
  using Model = nlid::Nlarx<nlid::LaggedRegressors<2, 2, 0>, nlid::SigmoidNet<4, 3>>;
  Model nl(nlid::LaggedRegressors<2, 2, 0>{}, nlid::SigmoidNet<4, 3>{}, e3.ts());
  {
    const Eigen::MatrixXd X = nl.regressor_values(e3);
    Eigen::VectorXd theta(nl.num_parameters());
    nl.nonlinearity().initialize(X, e3.y().col(0).tail(X.rows()), std::span<double>(theta.data(), theta.size()));
    nl.set_parameters(theta);
  }
  using Block = nlid::TransferFunctionBlock<2, 2, 0>;
  nlid::HammersteinWiener<nlid::PwLinear<3>, Block, nlid::Saturation> hw(nlid::PwLinear<3>{}, Block{}, nlid::Saturation{},
                                                                        e3.ts());
  {
    Eigen::VectorXd th(hw.num_parameters());
    std::vector<double> pw(6);
    const std::vector<double> bx{-0.5, 0.2, 1.0}, by{-5.0, 10.0, 40.0};
    hw.input_nonlinearity().theta_from_breakpoints(bx, by, pw);
    for (int i = 0; i < 6; ++i) th(i) = pw[static_cast<std::size_t>(i)];
    th.segment(6, 4) << 0.05, 0.02, -1.5, 0.56;
    th.tail(2) << 15.0, 90.0;
    hw.set_parameters(th);
  }
  nlid::GreyBox<nlid::physics::Throttle> grey;
  {
    Eigen::VectorXd p(7);
    p << 30.0, 400.0, 4e4, 64000.0, 15.0, 90.0, 10.0;
    grey.set_parameters(p);
  }
  for (const bool single : {false, true}) {
    nlid::CodegenOptions o;
    o.ts = e3.ts();
    o.equilibrium_input = Eigen::VectorXd::Constant(1, clean[0]);
    if (single) o.precision = nlid::codegen::Precision::single_precision;
    const std::string p = single ? "_f" : "";
    o.name = "guard_nlarx" + p;
    const nlid::GeneratedCode g1 = nlid::generate_c(nl, o);
    o.name = "guard_hw" + p;
    const nlid::GeneratedCode g2 = nlid::generate_c(hw, o);
    o.name = "guard_grey" + p;
    const nlid::GeneratedCode g3 = nlid::generate_c(grey, o);
    for (const nlid::GeneratedCode* g : {&g1, &g2, &g3}) {
      INFO(g->name);
      CHECK(g->header.find("int " + g->name + "_step(") != std::string::npos);
      const CheckedRun ok = run_checked(*g, clean, g->name + "_clean", single);
      const CheckedRun r = run_checked(*g, bad, g->name + "_bad", single);
      REQUIRE(ok.y.size() == clean.size());
      REQUIRE(r.y.size() == bad.size());
      for (int s : ok.status) CHECK(s == 0);
      std::size_t k = 0;
      int refused = 0;
      for (std::size_t t = 0; t < bad.size(); ++t) {
        if (inserted[t]) {
          CHECK(r.status[t] == 1);
          refused += r.status[t];
          continue;
        }
        INFO("sample " << k);
        REQUIRE(r.status[t] == 0);
        REQUIRE(r.y[t] == ok.y[k]);  // same state as without the bad samples
        ++k;
      }
      CHECK(refused == 3);
    }
  }
}

TEST_CASE("codegen: user text in C comments cannot close them", "[codegen]") {
  // Channel names, parameter names and equations come from users' files into /* ... */.
  CHECK(nlid::codegen::comment_text("valve */ angle") == "valve * / angle");
  CHECK(nlid::codegen::comment_text("a*/*/b") == "a* / * /b");  // and no "/*" left to open one
  CHECK(nlid::codegen::comment_text("no terminator / * here") == "no terminator / * here");
  CHECK(nlid::codegen::comment_block("x */ y").find("x * / y") != std::string::npos);
}

TEST_CASE("C comments: user text cannot open or close a comment", "[codegen]") {
  // "*/" would end the comment; "/*" inside one is legal C, but -Wcomment warns of it, and
  // a -Werror build of the generated code failed on a channel named "u/*V".
  for (const std::string t : {"u/*V", "a*/b", "/*/", "*/*", "x /**/ y", "/**", "//* c"}) {
    INFO(t);
    const std::string c = nlid::codegen::comment_text(t);
    CHECK(c.find("/*") == std::string::npos);
    CHECK(c.find("*/") == std::string::npos);
    const std::string block = nlid::codegen::comment_block(t + "\n" + t);
    CHECK(block.find("/*", 1) == std::string::npos);           // only the block's own opener
    CHECK(block.find("*/") == block.size() - 3);               // only its own closer, " */\n"
  }
  CHECK(nlid::codegen::comment_text("u/*V") == "u/ *V");
  CHECK(nlid::codegen::comment_text("plain text") == "plain text");
}
