// HammersteinWiener: the block equations, scalar genericity, Jacobian vs finite differences,
// fixed vs Dynamic twin, initial conditions, initialisation from polynomials, bad input.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>

#include "nlid/linear/output_error.hpp"
#include "nlid/linear/polynomial.hpp"
#include "nlid/models/hammerstein_wiener.hpp"
#include "nlid/nonlinearities/piecewise_linear.hpp"
#include "nlid/nonlinearities/saturation.hpp"
#include "nlid/nonlinearities/unit_gain.hpp"
#include "test_inputs.hpp"

using nlid::Dynamic;

namespace {
using Wiener = nlid::HammersteinWiener<nlid::UnitGain, nlid::TransferFunctionBlock<2, 2, 1>, nlid::Saturation>;
using Hw = nlid::HammersteinWiener<nlid::PwLinear<3>, nlid::TransferFunctionBlock<2, 2, 1>, nlid::Saturation>;

Eigen::VectorXd wiener_theta() {
  Eigen::VectorXd th(6);
  th << 0.5, 0.25, -1.5, 0.7, -1.0, 2.0;  // b1 b2 f1 f2 lower upper
  return th;
}
Eigen::MatrixXd inputs(int n) {
  Eigen::MatrixXd u(n, 1);
  for (int t = 0; t < n; ++t) u(t, 0) = 0.6 * std::sin(0.03 * t) + (t / 50 % 2 ? 0.5 : -0.4);
  return u;
}
// Reference: filter through B/F, then clamp (the textbook Wiener model).
Eigen::VectorXd wiener_reference(const Eigen::MatrixXd& u, const Eigen::VectorXd& th) {
  Eigen::VectorXd b(3), f(3);
  b << 0, th(0), th(1);
  f << 1, th(2), th(3);
  const Eigen::VectorXd x = nlid::filter(b, f, Eigen::VectorXd(u.col(0)));
  return x.cwiseMax(th(4)).cwiseMin(th(5));
}
template <class T>
std::span<const T> cspan(const std::vector<T>& v) { return {v.data(), v.size()}; }

struct FakeOe {  // anything with toolbox polynomials, as OutputError has them
  Eigen::VectorXd b_polynomial() const { return Eigen::Vector3d(0, 0.5, 0.25); }
  Eigen::VectorXd f_polynomial() const { return Eigen::Vector3d(1, -1.5, 0.7); }
};
}  // namespace

TEST_CASE("HW sizes and structure concepts", "[models][hw]") {
  static_assert(Wiener::num_params == 6);
  static_assert(Hw::num_params == 12);
  static_assert(nlid::ModelStructure<Wiener> && nlid::Model<Wiener>);
  Hw m;
  CHECK(m.linear_offset() == 6);
  CHECK(m.output_offset() == 10);
  CHECK(m.state_dimension() == 2);
  CHECK(m.parameter_names()[6] == "linear:b1");
}

TEST_CASE("Wiener simulation equals filter-then-clamp", "[models][hw]") {
  Wiener m;
  m.set_parameters(wiener_theta());
  const Eigen::MatrixXd u = inputs(500);
  const nlid::Experiment e(u, Eigen::VectorXd::Zero(500), 1.0, "w");
  const Eigen::MatrixXd y = m.simulate(e, nlid::InitialCondition::zero);
  const Eigen::VectorXd ref = wiener_reference(u, wiener_theta());
  CHECK((y.col(0) - ref).cwiseAbs().maxCoeff() < 1e-12);
  CHECK(ref.maxCoeff() == 2.0);  // the test signal does reach the saturation
  CHECK(ref.minCoeff() == -1.0);
  const Eigen::MatrixXd sig = m.signals(u, nlid::detail::as_const_span(m.parameters()), {});
  CHECK(sig.col(0) == u.col(0));  // unit gain input
  CHECK((sig.col(2) - ref).cwiseAbs().maxCoeff() < 1e-12);
}

TEST_CASE("HW on double, float and Dual, Jacobian vs central differences", "[models][hw]") {
  Hw m(nlid::PwLinear<3>{}, nlid::TransferFunctionBlock<2, 2, 1>{}, nlid::Saturation{});
  Eigen::VectorXd th(12);
  // pwlinear x0 = -1, gaps e^0 = 1: breakpoints -1, 0, 1 with values -0.8, 0, 1.3 (a kinked gain)
  th << -1.0, 0.0, 0.0, -0.8, 0.0, 1.3, 0.5, 0.25, -1.5, 0.7, -1.0, 2.0;
  const Eigen::MatrixXd u = inputs(300);
  const int n = 300;
  std::vector<double> thv(th.data(), th.data() + 12), y(n);
  REQUIRE(m.simulate<double>(u, cspan(thv), {}, y));
  using D = nlid::Dual<double, 14>;
  std::vector<D> thd(12), x0d(2), yd(n);
  for (int i = 0; i < 12; ++i) thd[i] = D::variable(th(i), i);
  x0d[0] = D::variable(0.0, 12);
  x0d[1] = D::variable(0.0, 13);
  REQUIRE(m.simulate<D>(u, cspan(thd), cspan(x0d), yd));
  for (int t = 0; t < n; ++t) CHECK(yd[t].a == y[t]);
  std::vector<float> thf(thv.begin(), thv.end()), yf(n);
  REQUIRE(m.simulate<float>(u, cspan(thf), {}, yf));
  for (int t = 0; t < n; ++t) CHECK(yf[t] == Approx(y[t]).margin(1e-4));

  const double h = 1e-7;
  for (int i = 0; i < 14; ++i) {
    std::vector<double> tp = thv, tm = thv, xp(2, 0.0), xm(2, 0.0), yp(n), ym(n);
    if (i < 12) {
      tp[i] += h;
      tm[i] -= h;
    } else {
      xp[i - 12] += h;
      xm[i - 12] -= h;
    }
    REQUIRE(m.simulate<double>(u, cspan(tp), cspan(xp), yp));
    REQUIRE(m.simulate<double>(u, cspan(tm), cspan(xm), ym));
    int mismatches = 0;
    for (int t = 0; t < n; ++t) {
      const double fd = (yp[t] - ym[t]) / (2 * h);
      if (std::abs(yd[t].v[i] - fd) > 1e-5 * (1 + std::abs(fd))) ++mismatches;
    }
    CHECK(mismatches == 0);
  }
}

TEST_CASE("fixed and Dynamic HW variants simulate identically", "[models][hw]") {
  Hw fixed;
  Eigen::VectorXd th(12);
  th << -1.0, 0.0, 0.0, -0.8, 0.0, 1.3, 0.5, 0.25, -1.5, 0.7, -1.0, 2.0;
  fixed.set_parameters(th);
  nlid::HammersteinWiener<nlid::PwLinear<Dynamic>, nlid::TransferFunctionBlock<Dynamic, Dynamic, Dynamic>, nlid::Saturation>
      dyn(nlid::PwLinear<Dynamic>(3), nlid::TransferFunctionBlock<Dynamic, Dynamic, Dynamic>(2, 2, 1), nlid::Saturation{});
  static_assert(decltype(dyn)::num_params == Dynamic);
  dyn.set_parameters(th);
  const nlid::Experiment e(inputs(400), Eigen::VectorXd::Zero(400), 1.0);
  for (auto ic : {nlid::InitialCondition::zero, nlid::InitialCondition::equilibrium})
    CHECK((fixed.simulate(e, ic) - dyn.simulate(e, ic)).cwiseAbs().maxCoeff() < 1e-12);
}

TEST_CASE("HW initial conditions: equilibrium holds still, measured is refused", "[models][hw]") {
  Wiener m;
  m.set_parameters(wiener_theta());
  const nlid::Experiment e(Eigen::MatrixXd::Constant(60, 1, 0.1), Eigen::VectorXd::Zero(60), 1.0, "flat");
  const Eigen::MatrixXd y = m.simulate(e, nlid::InitialCondition::equilibrium);
  CHECK((y.array() - 0.1 * 0.75 / 0.2).abs().maxCoeff() < 1e-12);
  CHECK_THROWS_WITH(m.simulate(e, nlid::InitialCondition::measured),
                    Catch::Contains("use zero, equilibrium or estimate") && Catch::Contains("parameter 'initial'"));
}

TEST_CASE("HW equilibrium of an integrating block: at rest for a zero input, refused otherwise", "[models][hw]") {
  // x(t) = x(t-1) + u(t): F(1) = 0. It used to start a 0.5 input from rest without a word and
  // ramp 0.5, 1, 1.5, ... as if that were the steady state; Nlarx refuses the same request.
  nlid::HammersteinWiener<nlid::UnitGain, nlid::TransferFunctionBlock<1, 1, 0>, nlid::UnitGain> m;
  m.set_parameters(Eigen::Vector2d(1.0, -1.0));
  const nlid::Experiment held(Eigen::MatrixXd::Constant(5, 1, 0.5), Eigen::VectorXd::Zero(5), 1.0, "held");
  const auto err = [&] {
    try {
      (void)m.simulate(held, nlid::InitialCondition::equilibrium);
    } catch (const nlid::DivergenceError& x) {
      return std::string(x.what()) + " @" + x.where().parameter;
    }
    return std::string("no error");
  }();
  CHECK_THAT(err, Catch::Contains("experiment 'held': no steady state for the held input u = 0.5") &&
                      Catch::Contains("integrates") && Catch::Contains("@initial"));
  Eigen::MatrixXd u = Eigen::MatrixXd::Zero(5, 1);
  u(3, 0) = 1.0;
  const nlid::Experiment rest(u, Eigen::VectorXd::Zero(5), 1.0, "rest");
  CHECK(m.simulate(rest, nlid::InitialCondition::equilibrium).col(0) == Eigen::Vector<double, 5>(0, 0, 0, 1, 1));
  CHECK(m.simulate(held, nlid::InitialCondition::zero)(4, 0) == 2.5);  // the other starts still work
}

TEST_CASE("the linear block is set from an earlier linear model's polynomials", "[models][hw]") {
  Wiener m;
  m.set_linear_block(FakeOe{});
  const auto lin = m.linear_parameters();
  CHECK(std::vector<double>(lin.begin(), lin.end()) == std::vector<double>{0.5, 0.25, -1.5, 0.7});
  Eigen::VectorXd bad(2);
  bad << 1.0, 2.0;
  CHECK_THROWS_WITH(m.set_linear_polynomials(bad, Eigen::Vector2d(1, 0.5)), Catch::Contains("parameter 'F'"));
}

TEST_CASE("the linear block is set from an estimated OutputError model", "[models][hw]") {
  // A known B/F system: oe() recovers it from noise-free data, and the block takes its numbers
  // (OutputError::f() omits F's leading 1, so the block reads f_polynomial()).
  const nlid::Dataset d(nlid_test::known_bf_record(400, 0.07, 17, 0.5, "bf"));
  const nlid::OutputError oe = nlid::oe(d, {2, 2, 1});
  Wiener m;
  m.set_linear_block(oe);
  const auto lin = m.linear_parameters();
  const std::vector<double> want{0.5, 0.25, -1.5, 0.7};
  REQUIRE(lin.size() == want.size());
  for (std::size_t i = 0; i < want.size(); ++i) CHECK(lin[i] == Approx(want[i]).margin(1e-6));
  const nlid::OutputError wrong = nlid::oe(d, {3, 2, 1});
  CHECK_THROWS_WITH(m.set_linear_block(wrong), Catch::Contains("parameter 'B'"));
}

TEST_CASE("HW rejects data it cannot simulate, naming the experiment", "[models][hw]") {
  Wiener m(nlid::UnitGain{}, nlid::TransferFunctionBlock<2, 2, 1>{}, nlid::Saturation{}, 0.01);
  m.set_parameters(wiener_theta());
  Eigen::MatrixXd u2 = Eigen::MatrixXd::Ones(30, 2);
  CHECK_THROWS_WITH(m.simulate(nlid::Experiment(u2, Eigen::VectorXd::Zero(30), 0.01, "two")),
                    Catch::Contains("experiment 'two' has 2 input(s) but the Hammerstein-Wiener model reads 1"));
  CHECK_THROWS_WITH(m.simulate(nlid::Experiment(inputs(30), Eigen::MatrixXd::Zero(30, 2), 0.01, "mimo")),
                    Catch::Contains("experiment 'mimo' has 2 outputs"));
  CHECK_THAT(m.describe(), Catch::Contains("B(q) = 0.5 q^-1 + 0.25 q^-2") && Catch::Contains("saturation"));
}

TEST_CASE("estimated HW initial state recovers the true block state", "[models][hw]") {
  Wiener m;
  m.set_parameters(wiener_theta());
  const Eigen::MatrixXd u = 0.3 * inputs(300);  // stays inside the saturation at the start
  Eigen::VectorXd y(300);
  const Eigen::Vector2d s_true(0.4, -0.3);
  REQUIRE(m.simulate<double>(u, nlid::detail::as_const_span(m.parameters()), nlid::detail::as_const_span(s_true),
                             nlid::detail::as_span(y)));
  const nlid::Experiment e(u, y, 1.0, "state");
  const Eigen::VectorXd s = m.initial_state(e, nlid::InitialCondition::estimate);
  CHECK(s(0) == Approx(0.4).margin(1e-7));
  CHECK(s(1) == Approx(-0.3).margin(1e-7));
  CHECK((m.predict(e, 5).col(0) - y).cwiseAbs().maxCoeff() < 1e-7);
}
