// Integrators: order of accuracy (odeint style: halve h, the error falls by 2^p), stability of the
// sub-step rule on a stiff contact spring, exact Dual sensitivities, float states, option checks.
#include <catch2/catch.hpp>

#include <cmath>
#include <type_traits>

#include "nlid/models/integrators.hpp"

namespace {

using V2 = Eigen::Vector2d;

// Harmonic oscillator x'' = -w^2 x, x(0) = 1, x'(0) = 0: exact x(t) = cos(w t).
struct Oscillator {
  double w = 2.0;
  template <class S>
  void operator()(const S& x, S& dx) const {
    dx[0] = x[1];
    dx[1] = -w * w * x[0];
  }
};

template <class Stepper>
double global_error(int n, double t_end = 2.0) {
  Oscillator f;
  Stepper s;
  V2 x(1.0, 0.0);
  for (int i = 0; i < n; ++i) s.step(f, x, t_end / n);
  return std::abs(x[0] - std::cos(f.w * t_end));
}

double dopri_fixed_error(int n, double t_end = 2.0) {
  Oscillator f;
  nlid::DormandPrinceStepper<V2> s;
  V2 x(1.0, 0.0), err;
  for (int i = 0; i < n; ++i) s.step(f, x, t_end / n, err);
  return std::abs(x[0] - std::cos(f.w * t_end));
}

}  // namespace

TEST_CASE("RK4 global error falls by 2^4 when h is halved", "[greybox][integrators]") {
  const double e1 = global_error<nlid::Rk4Stepper<V2>>(40);
  const double e2 = global_error<nlid::Rk4Stepper<V2>>(80);
  const double e3 = global_error<nlid::Rk4Stepper<V2>>(160);
  CHECK(e1 / e2 == Approx(16.0).epsilon(0.1));
  CHECK(e2 / e3 == Approx(16.0).epsilon(0.05));
  CHECK(std::log2(e1 / e3) / 2.0 == Approx(4.0).margin(0.1));
}

TEST_CASE("Euler global error falls by 2 when h is halved", "[greybox][integrators]") {
  const double e1 = global_error<nlid::EulerStepper<V2>>(2000);
  const double e2 = global_error<nlid::EulerStepper<V2>>(4000);
  CHECK(e1 / e2 == Approx(2.0).epsilon(0.05));
}

TEST_CASE("Dormand-Prince propagated solution is fifth order", "[greybox][integrators]") {
  const double e1 = dopri_fixed_error(20);
  const double e2 = dopri_fixed_error(40);
  CHECK(std::log2(e1 / e2) == Approx(5.0).margin(0.3));
}

TEST_CASE("Dormand-Prince step's embedded error estimate is the fourth-order solution's local error", "[greybox][integrators]") {
  // err = y5 − y4, so y4 = x − err; y5 is an order more accurate, so y4's true local error is
  // ≈ −err, and both fall by 2^5 when h is halved (local error of a 4th-order method: O(h^5)).
  Oscillator f;
  auto one_step = [&](double h, double& true_y4_error) {
    nlid::DormandPrinceStepper<V2> s;
    V2 x(1.0, 0.0), err;
    s.step(f, x, h, err);
    const V2 exact(std::cos(f.w * h), -f.w * std::sin(f.w * h));
    true_y4_error = ((x - err) - exact).norm();
    CHECK((x - exact).norm() < 0.25 * err.norm());  // the propagated 5th-order solution is better
    return err.norm();
  };
  double t1 = 0, t2 = 0;
  const double e1 = one_step(0.2, t1);
  const double e2 = one_step(0.1, t2);
  CHECK(e1 == Approx(t1).epsilon(0.1));
  CHECK(e2 == Approx(t2).epsilon(0.1));
  CHECK(std::log2(e1 / e2) == Approx(5.0).margin(0.3));
}

TEST_CASE("Dormand-Prince adaptive error follows the tolerance", "[greybox][integrators]") {
  Oscillator f;
  for (double tol : {1e-4, 1e-7, 1e-10}) {
    nlid::DormandPrinceStepper<V2> s;
    nlid::IntegratorOptions o;
    o.relative_tolerance = tol;
    o.absolute_tolerance = tol;
    V2 x(1.0, 0.0);
    double h_try = 0.0;
    // Ten sample intervals of 0.2 s, the step size carried across them as in a simulation.
    for (int k = 0; k < 10; ++k) REQUIRE(s.integrate(f, x, 0.2, h_try, o));
    const double err = std::abs(x[0] - std::cos(f.w * 2.0));
    CHECK(err < 50 * tol);
    CHECK(err > 1e-3 * tol);  // the controller does not waste work far beyond the request
  }
}

TEST_CASE("Sub-step rule keeps RK4 stable on a stiff contact spring", "[greybox][integrators]") {
  // Contact phase of a hard stop: x'' = -K x - c x', K = 1e6 1/s^2, spectral radius ~ 1000 1/s.
  const double K = 1e6, c = 5.0, h = 0.01;
  auto f = [&](const V2& x, V2& dx) {
    dx[0] = x[1];
    dx[1] = -K * x[0] - c * x[1];
  };
  nlid::IntegratorOptions o;
  const double rho = std::max(c, std::sqrt(K));
  const int n = nlid::substeps_for(h, rho, o);
  CHECK(n == 10);
  nlid::Rk4Stepper<V2> s;
  V2 x(1e-3, 0.0);
  for (int k = 0; k < 100; ++k) REQUIRE(s.integrate(f, x, h, n));
  // Energy ½Kx² + ½v² decays with the damping; it must not grow.
  const double e0 = 0.5 * K * 1e-6;
  const double e1 = 0.5 * K * x[0] * x[0] + 0.5 * x[1] * x[1];
  CHECK(e1 < e0);
  // One step per sample (h rho = 10) leaves RK4's stability region: the state blows up.
  V2 y(1e-3, 0.0);
  bool finite = true;
  for (int k = 0; k < 100 && finite; ++k) finite = s.integrate(f, y, h, 1) && y.norm() < 1e3;
  CHECK_FALSE(finite);
}

TEST_CASE("substeps_for: fixed count, unknown radius, floor and ceiling", "[greybox][integrators]") {
  nlid::IntegratorOptions o;
  CHECK(nlid::substeps_for(0.01, 0.0, o) == 1);
  CHECK(nlid::substeps_for(0.01, std::nan(""), o) == 1);
  CHECK(nlid::substeps_for(0.01, 250.0, o) == 3);
  o.min_substeps = 4;
  CHECK(nlid::substeps_for(0.01, 250.0, o) == 4);
  o.max_substeps = 50;
  CHECK(nlid::substeps_for(0.01, 1e9, o) == 50);
  o.substeps = 7;
  CHECK(nlid::substeps_for(0.01, 1e9, o) == 7);
}

TEST_CASE("Dual state through RK4 and DOPRI5 gives d x(T)/d w", "[greybox][integrators]") {
  using D = nlid::Dual<double, 1>;
  using V2D = Eigen::Matrix<D, 2, 1>;
  auto run = [](auto w, auto& stepper, auto adaptive_tag) {
    constexpr bool adaptive = decltype(adaptive_tag)::value;
    using S = std::remove_cvref_t<decltype(w)>;
    using St = Eigen::Matrix<S, 2, 1>;
    auto f = [&](const St& x, St& dx) {
      dx[0] = x[1];
      dx[1] = -(w * w) * x[0];
    };
    St x;
    x << S(1.0), S(0.0);
    nlid::IntegratorOptions o;
    o.relative_tolerance = 1e-9;
    o.absolute_tolerance = 1e-12;
    double h_try = 0.0;
    for (int k = 0; k < 20; ++k) {
      if constexpr (adaptive) {
        stepper.integrate(f, x, 0.1, h_try, o);
      } else {
        stepper.integrate(f, x, 0.1, 5);
        (void)h_try;
        (void)o;
      }
    }
    return x[0];
  };
  const double w0 = 1.7, dw = 1e-6;
  {
    nlid::Rk4Stepper<V2D> sd;
    nlid::Rk4Stepper<V2> s1, s2;
    const D r = run(D::variable(w0, 0), sd, std::false_type{});
    const double fd = (run(w0 + dw, s1, std::false_type{}) - run(w0 - dw, s2, std::false_type{})) / (2 * dw);
    CHECK(r.v[0] == Approx(fd).epsilon(1e-7));
    // and matches the exact sensitivity d cos(w t)/dw = -t sin(w t) to the integration error
    CHECK(r.v[0] == Approx(-2.0 * std::sin(w0 * 2.0)).epsilon(1e-4));
  }
  {
    nlid::DormandPrinceStepper<V2D> sd;
    const D r = run(D::variable(w0, 0), sd, std::true_type{});
    CHECK(r.v[0] == Approx(-2.0 * std::sin(w0 * 2.0)).epsilon(1e-6));
  }
}

TEST_CASE("Integrators run on float and dynamic-size states", "[greybox][integrators]") {
  using V2f = Eigen::Vector2f;
  auto f = [](const V2f& x, V2f& dx) {
    dx[0] = x[1];
    dx[1] = -4.0f * x[0];
  };
  nlid::Rk4Stepper<V2f> s;
  V2f x(1.0f, 0.0f);
  REQUIRE(s.integrate(f, x, 2.0, 100));
  CHECK(x[0] == Approx(std::cos(4.0)).margin(1e-4));

  Eigen::VectorXd xd(2);
  xd << 1.0, 0.0;
  auto fd = [](const Eigen::VectorXd& y, Eigen::VectorXd& dy) {
    dy[0] = y[1];
    dy[1] = -4.0 * y[0];
  };
  nlid::Rk4Stepper<Eigen::VectorXd> sd;
  REQUIRE(sd.integrate(fd, xd, 2.0, 100));
  CHECK(xd[0] == Approx(std::cos(4.0)).margin(1e-6));
}

TEST_CASE("Adaptive integrator reports a blow-up instead of returning garbage", "[greybox][integrators]") {
  auto f = [](const Eigen::Matrix<double, 1, 1>& x, Eigen::Matrix<double, 1, 1>& dx) {
    dx[0] = x[0] * x[0];  // finite-time blow-up at t = 1 for x(0) = 1
  };
  nlid::DormandPrinceStepper<Eigen::Matrix<double, 1, 1>> s;
  nlid::IntegratorOptions o;
  o.max_adaptive_steps = 10000;
  Eigen::Matrix<double, 1, 1> x;
  x << 1.0;
  double h_try = 0.0;
  CHECK_FALSE(s.integrate(f, x, 2.0, h_try, o));
}

TEST_CASE("Integrator options are validated with the option named", "[greybox][integrators]") {
  nlid::IntegratorOptions o;
  CHECK_NOTHROW(nlid::validate(o));
  o.stability_target = 3.0;
  CHECK_THROWS_WITH(nlid::validate(o), Catch::Contains("stability_target"));
  o = {};
  o.max_substeps = 0;
  CHECK_THROWS_WITH(nlid::validate(o), Catch::Contains("max_substeps"));
  o = {};
  o.substeps = -1;
  CHECK_THROWS_WITH(nlid::validate(o), Catch::Contains("substeps"));
}
