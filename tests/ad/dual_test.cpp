// Dual numbers: every overload's derivative against its analytic formula and against central
// finite differences, for fixed N, Dynamic N and float; edge cases where naive rules give NaN;
// aliasing in compound assignment; mixing with plain numbers; nested duals.
#include <catch2/catch.hpp>

#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "nlid/ad.hpp"

using nlid::Dual;
using nlid::DynamicDual;

namespace {

constexpr double pi = 3.14159265358979323846;

// A dual with value a and gradient (g0, g1): exercises the chain rule on a non-unit seed.
template <class D>
D make_dual(typename D::Scalar a, typename D::Scalar g0, typename D::Scalar g1) {
  D d;
  d.a = a;
  d.v.resize(2);
  d.v << g0, g1;
  return d;
}

struct UnaryCase {
  std::string name;
  std::function<double(double)> f;                // on double
  std::function<Dual<double, 2>(Dual<double, 2>)> f2;  // fixed N
  std::function<DynamicDual<double>(DynamicDual<double>)> fd;  // Dynamic
  std::function<Dual<float, 2>(Dual<float, 2>)> ff;  // float
  std::function<double(double)> df;               // analytic derivative
  std::vector<double> points;
};

#define NLID_UNARY(fn, deriv, ...)                                                  \
  UnaryCase {                                                                       \
    #fn, [](double x) { return nlid::fn(x); },                                      \
        [](Dual<double, 2> x) { return nlid::fn(x); },                              \
        [](DynamicDual<double> x) { return nlid::fn(x); },                          \
        [](Dual<float, 2> x) { return nlid::fn(x); }, []([[maybe_unused]] double x) { return deriv; }, \
    { __VA_ARGS__ }                                                                 \
  }

std::vector<UnaryCase> unary_cases() {
  return {
      NLID_UNARY(abs, x < 0 ? -1.0 : 1.0, -1.7, 0.4, 3.0),
      NLID_UNARY(exp, std::exp(x), -2.0, 0.0, 1.3),
      NLID_UNARY(exp2, std::log(2.0) * std::exp2(x), -1.5, 0.2, 2.0),
      NLID_UNARY(expm1, std::exp(x), -1.0, 1e-3, 0.8),
      NLID_UNARY(log, 1.0 / x, 0.3, 1.0, 7.5),
      NLID_UNARY(log10, 1.0 / (x * std::log(10.0)), 0.3, 2.0, 40.0),
      NLID_UNARY(log2, 1.0 / (x * std::log(2.0)), 0.3, 2.0, 40.0),
      NLID_UNARY(log1p, 1.0 / (1.0 + x), -0.5, 1e-3, 3.0),
      NLID_UNARY(sqrt, 0.5 / std::sqrt(x), 0.01, 2.0, 9.0),
      NLID_UNARY(cbrt, 1.0 / (3.0 * std::cbrt(x) * std::cbrt(x)), -8.0, 0.5, 27.0),
      NLID_UNARY(sin, std::cos(x), -2.0, 0.0, 1.0),
      NLID_UNARY(cos, -std::sin(x), -2.0, 0.3, 1.0),
      NLID_UNARY(tan, 1.0 / (std::cos(x) * std::cos(x)), -1.2, 0.0, 1.0),
      NLID_UNARY(asin, 1.0 / std::sqrt(1.0 - x * x), -0.9, 0.0, 0.7),
      NLID_UNARY(acos, -1.0 / std::sqrt(1.0 - x * x), -0.9, 0.0, 0.7),
      NLID_UNARY(atan, 1.0 / (1.0 + x * x), -3.0, 0.0, 2.0),
      NLID_UNARY(sinh, std::cosh(x), -2.0, 0.0, 1.5),
      NLID_UNARY(cosh, std::sinh(x), -2.0, 0.1, 1.5),
      NLID_UNARY(tanh, 1.0 - std::tanh(x) * std::tanh(x), -2.0, 0.0, 0.7),
      NLID_UNARY(erf, 2.0 / std::sqrt(pi) * std::exp(-x * x), -1.5, 0.0, 0.6),
      NLID_UNARY(square, 2.0 * x, -3.0, 0.0, 1.5),
      NLID_UNARY(floor, 0.0, -2.5, 0.4, 3.7),
      NLID_UNARY(ceil, 0.0, -2.5, 0.4, 3.7),
      NLID_UNARY(round, 0.0, -2.3, 0.4, 3.7),
      NLID_UNARY(trunc, 0.0, -2.3, 0.4, 3.7),
  };
}

double central_difference(const std::function<double(double)>& f, double x) {
  const double h = 1e-6 * std::max(1.0, std::abs(x));
  return (f(x + h) - f(x - h)) / (2 * h);
}

}  // namespace

TEST_CASE("every unary overload: derivative = analytic = central difference", "[ad][dual]") {
  for (const auto& c : unary_cases()) {
    for (double x : c.points) {
      INFO(c.name << " at x = " << x);
      const double d_exact = c.df(x);
      // Finite differences agree with the analytic rule (checks the test table itself).
      CHECK(central_difference(c.f, x) == Approx(d_exact).margin(1e-7).epsilon(1e-6));

      const auto r2 = c.f2(make_dual<Dual<double, 2>>(x, 1.0, -0.5));
      CHECK(r2.a == Approx(c.f(x)).epsilon(1e-15));
      CHECK(r2.v[0] == Approx(d_exact).epsilon(1e-13).margin(1e-15));
      CHECK(r2.v[1] == Approx(-0.5 * d_exact).epsilon(1e-13).margin(1e-15));

      const auto rd = c.fd(make_dual<DynamicDual<double>>(x, 1.0, -0.5));
      CHECK(rd.a == Approx(c.f(x)).epsilon(1e-15));
      if (d_exact == 0.0 && rd.v.size() == 0) continue;  // constant result: empty gradient is 0
      REQUIRE(rd.v.size() == 2);
      CHECK(rd.v[0] == Approx(d_exact).epsilon(1e-13).margin(1e-15));
      CHECK(rd.v[1] == Approx(-0.5 * d_exact).epsilon(1e-13).margin(1e-15));

      const auto rf = c.ff(make_dual<Dual<float, 2>>(static_cast<float>(x), 1.0f, -0.5f));
      CHECK(rf.a == Approx(c.f(x)).epsilon(1e-5).margin(1e-6));
      CHECK(rf.v[0] == Approx(d_exact).epsilon(1e-4).margin(1e-5));
    }
  }
}

TEST_CASE("arithmetic: product, quotient and scalar mixing", "[ad][dual]") {
  using D = Dual<double, 2>;
  const D x = D::variable(1.5, 0);
  const D y = D::variable(-0.8, 1);
  const D p = x * y;
  CHECK(p.a == Approx(-1.2));
  CHECK(p.v[0] == Approx(-0.8));  // ∂(xy)/∂x = y
  CHECK(p.v[1] == Approx(1.5));   // ∂(xy)/∂y = x
  const D q = x / y;
  CHECK(q.v[0] == Approx(1.0 / -0.8));
  CHECK(q.v[1] == Approx(-1.5 / (0.8 * 0.8)));
  const D s = 3.0 / x;  // (3/x)' = -3/x²
  CHECK(s.v[0] == Approx(-3.0 / (1.5 * 1.5)));
  const D t = 1 - 2 * x + x / 4 - 1.0;  // integer constants convert
  CHECK(t.a == Approx(-2.0 * 1.5 + 1.5 / 4));
  CHECK(t.v[0] == Approx(-2.0 + 0.25));
  CHECK(t.v[1] == 0.0);
  CHECK(x > 1);
  CHECK(0 < x);
  CHECK(y <= -0.8);
  CHECK(x != y);
  CHECK(x == 1.5);
}

// q = x/y with x = n·t, y = d·s at t = s = 1: ∂q/∂t = n/d, ∂q/∂s = −n/d. The old rule scaled by
// 1/d and (n/d)/d: for d = 1e-200 that is ∞ (and ∞·0 = NaN in the component y does not move),
// for d = 1e300 it underflows to 0, for a subnormal d the reciprocal itself is ∞.
template <class D>
void check_quotient_by_extreme_divisor(double n, double d) {
  INFO("n = " << n << ", d = " << d);
  const double dq = n / d;
  // Central difference in s of n/(d·s): relative steps keep every value an ordinary number.
  const double h = 1e-6;
  const double fd = (n / (d * (1 + h)) - n / (d * (1 - h))) / (2 * h);
  CHECK(fd == Approx(-dq).epsilon(1e-6));
  const D x = make_dual<D>(n, n, 0.0), y = make_dual<D>(d, 0.0, d);
  D assigned = x;
  assigned /= y;
  for (const D& q : {x / y, assigned}) {
    CHECK(q.a == dq);
    CHECK(q.v[0] == Approx(dq).epsilon(1e-14));
    CHECK(q.v[1] == Approx(-dq).epsilon(1e-14));
  }
  // A plain numerator or denominator: n/y, x/d.
  const D r = n / y;
  CHECK(r.v[0] == 0.0);
  CHECK(r.v[1] == Approx(-dq).epsilon(1e-14));
  D over_scalar = x;
  over_scalar /= d;
  for (const D& w : {x / d, over_scalar}) {
    CHECK(w.v[0] == Approx(dq).epsilon(1e-14));
    CHECK(w.v[1] == 0.0);
  }
}

TEST_CASE("quotients by tiny and huge divisors keep the derivatives the quotient rule gives", "[ad][dual]") {
  for (const auto& [n, d] : {std::pair{2.0, 1e-200}, std::pair{2.0, 1e-300}, std::pair{1e-100, 1e-310},
                             std::pair{2.0, 1e300}, std::pair{1e300, 1e307}, std::pair{-3.0, 0.25}}) {
    check_quotient_by_extreme_divisor<Dual<double, 2>>(n, d);
    check_quotient_by_extreme_divisor<DynamicDual<double>>(n, d);
  }
}

TEST_CASE("compound assignment with itself (aliasing) is correct", "[ad][dual]") {
  using D = Dual<double, 2>;
  D x = D::variable(3.0, 0);
  x *= x;  // x²: value 9, derivative 6
  CHECK(x.a == 9.0);
  CHECK(x.v[0] == 6.0);
  D y = D::variable(3.0, 1);
  const D& same_y = y;  // aliasing is the point; a name keeps clang's self-assignment warning quiet
  y /= same_y;
  CHECK(y.a == 1.0);
  CHECK(y.v[1] == 0.0);
  D z = D::variable(3.0, 0);
  const D& same_z = z;
  z -= same_z;
  CHECK(z.a == 0.0);
  CHECK(z.v[0] == 0.0);
  D w = D::variable(3.0, 0);
  w += w;
  CHECK(w.a == 6.0);
  CHECK(w.v[0] == 2.0);
  DynamicDual<double> u = DynamicDual<double>::variable(2.0, 1, 3);
  u *= u;
  CHECK(u.v[1] == 4.0);
}

TEST_CASE("binary functions: both partial derivatives vs central differences", "[ad][dual]") {
  using D = Dual<double, 2>;
  struct Case {
    const char* name;
    std::function<double(double, double)> f;
    std::function<D(D, D)> fd;
    double x, y;
  };
  const std::vector<Case> cases = {
      {"atan2", [](double a, double b) { return std::atan2(a, b); },
       [](D a, D b) { return nlid::atan2(a, b); }, 0.7, -1.3},
      {"atan2 q3", [](double a, double b) { return std::atan2(a, b); },
       [](D a, D b) { return nlid::atan2(a, b); }, -0.7, -1.3},
      {"hypot", [](double a, double b) { return std::hypot(a, b); },
       [](D a, D b) { return nlid::hypot(a, b); }, 3.0, -4.0},
      {"pow", [](double a, double b) { return std::pow(a, b); },
       [](D a, D b) { return nlid::pow(a, b); }, 1.7, 2.3},
      {"pow small base", [](double a, double b) { return std::pow(a, b); },
       [](D a, D b) { return nlid::pow(a, b); }, 0.2, -1.5},
      {"max", [](double a, double b) { return std::max(a, b); },
       [](D a, D b) { return nlid::max(a, b); }, 0.3, 1.2},
      {"min", [](double a, double b) { return std::min(a, b); },
       [](D a, D b) { return nlid::min(a, b); }, 0.3, 1.2},
      {"product", [](double a, double b) { return a * b; }, [](D a, D b) { return a * b; }, 2.0,
       -3.0},
      {"quotient", [](double a, double b) { return a / b; }, [](D a, D b) { return a / b; }, 2.0,
       -3.0},
  };
  for (const auto& c : cases) {
    INFO(c.name);
    const D r = c.fd(D::variable(c.x, 0), D::variable(c.y, 1));
    const double h = 1e-6;
    const double dx = (c.f(c.x + h, c.y) - c.f(c.x - h, c.y)) / (2 * h);
    const double dy = (c.f(c.x, c.y + h) - c.f(c.x, c.y - h)) / (2 * h);
    CHECK(r.a == Approx(c.f(c.x, c.y)));
    CHECK(r.v[0] == Approx(dx).epsilon(1e-7).margin(1e-9));
    CHECK(r.v[1] == Approx(dy).epsilon(1e-7).margin(1e-9));
  }
  // Analytic spot checks of the two-argument rules.
  const D a = D::variable(3.0, 0), b = D::variable(4.0, 1);
  const D h = nlid::hypot(a, b);
  CHECK(h.v[0] == Approx(3.0 / 5.0));
  CHECK(h.v[1] == Approx(4.0 / 5.0));
  const D t = nlid::atan2(a, b);  // ∂/∂y = x/(x²+y²) with y = a, x = b
  CHECK(t.v[0] == Approx(4.0 / 25.0));
  CHECK(t.v[1] == Approx(-3.0 / 25.0));
}

TEST_CASE("power and min/max with plain scalars", "[ad][dual]") {
  using D = Dual<double, 1>;
  const D x = D::variable(2.0, 0);
  CHECK(nlid::pow(x, 3).v[0] == Approx(12.0));      // 3x²
  CHECK(nlid::pow(x, 0.5).v[0] == Approx(0.5 / std::sqrt(2.0)));
  CHECK(nlid::pow(x, 0).v[0] == 0.0);
  CHECK(nlid::pow(3.0, x).v[0] == Approx(9.0 * std::log(3.0)));  // 3^x ln 3
  CHECK(nlid::pow(0.0, x).v[0] == 0.0);
  CHECK(nlid::max(x, 1.0).v[0] == 1.0);
  CHECK(nlid::max(x, 5).v[0] == 0.0);
  CHECK(nlid::max(5.0, x).a == 5.0);
  CHECK(nlid::min(x, 1).a == 1.0);
  CHECK(nlid::min(x, 1).v[0] == 0.0);
  CHECK(nlid::min(1.0, x).v[0] == 0.0);
  CHECK(nlid::min(9.0, x).v[0] == 1.0);
  // Plain-number versions, so generic code is uniform.
  CHECK(nlid::max(2.0, 3.0) == 3.0);
  CHECK(nlid::min(2.0f, 3.0f) == 2.0f);
  // Mixed plain types, as a regressor `max(y, 90)` written once meets them on double and float.
  CHECK(nlid::max(91.5, 90) == 91.5);
  CHECK(nlid::max(2.5f, 90.0) == 90.0);
  CHECK(nlid::min(2.5f, 15.0) == 2.5);
  CHECK(nlid::min(20, 15.5) == 15.5);
  static_assert(std::is_same_v<decltype(nlid::max(2.5f, 90.0)), double>);
  static_assert(std::is_same_v<decltype(nlid::min(1, 2.0f)), float>);
  CHECK(nlid::square(3.0) == 9.0);
}

TEST_CASE("abs of a dual at -0 is +0 with the right-hand slope, as std::abs", "[ad][dual]") {
  // Found by tests/fuzz/expression_fuzz.cpp ("abs(0 / u1(t))" with u1(t) < 0): abs returned the
  // dual itself at -0, sign bit and all, so 1/abs(x) was -inf where the double gives +inf.
  using D = Dual<double, 1>;
  const D z = nlid::abs(D::variable(-0.0, 0));
  CHECK(!std::signbit(z.a));
  CHECK(z.v[0] == 1.0);  // the right-hand slope at the kink, as at +0
  CHECK(1.0 / z.a == std::numeric_limits<double>::infinity());
  CHECK(!std::signbit(nlid::abs(Dual<float, 2>(-0.0f)).a));
  // Nested duals: the inner value loses its sign bit, its derivatives are kept.
  using DD = Dual<D, 1>;
  DD nested;
  nested.a = D::variable(-0.0, 0);
  nested.v[0] = D(2.0);
  const DD an = nlid::abs(nested);
  CHECK(!std::signbit(an.a.a));
  CHECK(an.a.v[0] == 1.0);
  CHECK(an.v[0].a == 2.0);
}

TEST_CASE("infinite slopes do not poison unrelated gradient components", "[ad][dual]") {
  using D = Dual<double, 2>;
  // sqrt at 0 seeded only in component 0: component 1 must stay exactly 0, not ∞·0 = NaN.
  const D s = nlid::sqrt(D::variable(0.0, 0));
  CHECK(s.a == 0.0);
  CHECK(std::isinf(s.v[0]));
  CHECK(s.v[1] == 0.0);
  const D c = nlid::cbrt(D::variable(0.0, 1));
  CHECK(c.v[0] == 0.0);
  const D as = nlid::asin(D::variable(1.0, 0));
  CHECK(as.v[1] == 0.0);
  // A negative base with a constant exponent (no derivative in the exponent) stays finite.
  D base = D::variable(-2.0, 0);
  D expo(3.0);
  const D p = nlid::pow(base, expo);
  CHECK(p.a == Approx(-8.0));
  CHECK(p.v[0] == Approx(12.0));
  CHECK(nlid::isfinite(p));
  // pow(0, y) with y moving: x^y log x → 0 as x → 0⁺ (y > 0).
  const D z = nlid::pow(D(0.0), D::variable(2.0, 1));
  CHECK(z.v[1] == 0.0);
  // hypot at the origin: subgradient 0 rather than 0/0.
  const D h = nlid::hypot(D::variable(0.0, 0), D::variable(0.0, 1));
  CHECK(h.v.isZero());
}

TEST_CASE("isfinite, isnan, isinf inspect value and derivatives", "[ad][dual]") {
  using D = Dual<double, 2>;
  D x = D::variable(1.0, 0);
  CHECK(nlid::isfinite(x));
  CHECK_FALSE(nlid::isnan(x));
  x.v[1] = std::numeric_limits<double>::quiet_NaN();
  CHECK_FALSE(nlid::isfinite(x));
  CHECK(nlid::isnan(x));
  CHECK_FALSE(nlid::isinf(x));
  CHECK(nlid::isinf(D(std::numeric_limits<double>::infinity())));
  CHECK(nlid::value_of(x) == 1.0);
  // Nested: value_of reaches the innermost value.
  Dual<Dual<double, 1>, 1> nn(Dual<double, 1>(4.0));
  CHECK(nlid::value_of(nn) == 4.0);
}

TEST_CASE("dynamic duals mix constants (empty gradient) with variables", "[ad][dual]") {
  using D = DynamicDual<double>;
  const D x = D::variable(2.0, 1, 3);
  const D c(5.0);  // constant: empty gradient
  CHECK(c.v.size() == 0);
  const D r = c * x + c - x / c + nlid::atan2(c, x) + nlid::hypot(c, x) + nlid::pow(c, x);
  REQUIRE(r.v.size() == 3);
  const double dr = 5.0 + 0.0 - 1.0 / 5.0 + (-5.0 / (4.0 + 25.0)) + 2.0 / std::sqrt(29.0) +
                    std::pow(5.0, 2.0) * std::log(5.0);
  CHECK(r.v[1] == Approx(dr));
  CHECK(r.v[0] == 0.0);
  CHECK(r.v[2] == 0.0);
  const D cc = c * c + nlid::exp(c);  // constant stays constant (and allocation-free)
  CHECK(cc.v.size() == 0);
  CHECK(cc.a == Approx(25.0 + std::exp(5.0)));
}

TEST_CASE("nested duals give second derivatives", "[ad][dual]") {
  // f(x) = x³ sin x: f'' = 6x sin x + 6x² cos x − x³ sin x.
  using Inner = Dual<double, 1>;
  using Outer = Dual<Inner, 1>;
  const double x0 = 0.7;
  Outer x;
  x.a = Inner::variable(x0, 0);
  x.v[0] = Inner(1.0);
  const Outer f = x * x * x * nlid::sin(x);
  const double d1 = 3 * x0 * x0 * std::sin(x0) + x0 * x0 * x0 * std::cos(x0);
  const double d2 = 6 * x0 * std::sin(x0) + 6 * x0 * x0 * std::cos(x0) - x0 * x0 * x0 * std::sin(x0);
  CHECK(f.a.a == Approx(x0 * x0 * x0 * std::sin(x0)));
  CHECK(f.v[0].a == Approx(d1));
  CHECK(f.a.v[0] == Approx(d1));
  CHECK(f.v[0].v[0] == Approx(d2));
  // Functions of nested duals compile and propagate through both levels.
  const Outer g = nlid::exp(x) + nlid::tanh(x) * 2.0 + nlid::sqrt(x);
  CHECK(g.v[0].v[0] == Approx(std::exp(x0) +
                               2.0 * (-2.0 * std::tanh(x0) * (1 - std::tanh(x0) * std::tanh(x0))) -
                               0.25 * std::pow(x0, -1.5)));
}

TEST_CASE("numeric_limits and NumTraits of a dual are those of its value type", "[ad][dual]") {
  using D = Dual<double, 3>;
  CHECK(std::numeric_limits<D>::is_specialized);
  CHECK(std::numeric_limits<D>::epsilon().a == std::numeric_limits<double>::epsilon());
  CHECK(std::isinf(std::numeric_limits<D>::infinity().a));
  CHECK(std::numeric_limits<D>::max().a == std::numeric_limits<double>::max());
  CHECK(std::numeric_limits<D>::lowest().a == std::numeric_limits<double>::lowest());
  CHECK(std::isnan(std::numeric_limits<D>::quiet_NaN().a));
  CHECK(std::numeric_limits<D>::digits == std::numeric_limits<double>::digits);
  CHECK(Eigen::NumTraits<D>::epsilon().a == std::numeric_limits<double>::epsilon());
  CHECK(std::isinf(Eigen::NumTraits<D>::infinity().a));
  CHECK(Eigen::NumTraits<Dual<float, 2>>::digits10() == std::numeric_limits<float>::digits10);
}
