// Known values of every nonlinearity at hand-computed points, parameter names and describe().
#include <catch2/catch.hpp>

#include <cmath>
#include <functional>
#include <limits>
#include <span>
#include <vector>

#include "nlid/nonlinearities.hpp"

namespace {

template <class F>
double eval(const F& f, std::vector<double> x, const std::vector<double>& th) {
  return f(std::span<const double>(x), std::span<const double>(th));
}

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

}  // namespace

TEST_CASE("UnitGain is the identity without parameters", "[nonlinearities][values]") {
  nlid::UnitGain f;
  CHECK(eval(f, {2.5}, {}) == 2.5);
  CHECK(eval(f, {-7.0}, {}) == -7.0);
  CHECK(f.parameter_names().empty());
  CHECK(contains(f.describe({}), "g(x) = x"));
}

TEST_CASE("LinearMap evaluates x'L + d", "[nonlinearities][values]") {
  nlid::LinearMap<2> f;
  const std::vector<double> th{2.0, -1.0, 0.5};
  CHECK(eval(f, {3.0, 4.0}, th) == Approx(2.5).epsilon(1e-15));
  CHECK(f.parameter_names() == std::vector<std::string>{"L[0]", "L[1]", "d"});
  const std::string d = f.describe(th, {"y(t-1)", "u(t)"});
  CHECK(contains(d, "2·y(t-1) - 1·u(t) + 0.5"));
}

TEST_CASE("SigmoidNet evaluates the toolbox formula", "[nonlinearities][values]") {
  nlid::SigmoidNet<2, 1> f;
  // θ = [L0 L1 d a0 b00 b01 c0]; r = 0, s = 1 before initialize.
  const std::vector<double> th{1, 2, 0.5, 3, 1, -1, 0.2};
  // z'L = 0.3 + 0.2, unit argument 0.3 - 0.1 + 0.2 = 0.4, σ(0.4) = 0.598687660112452.
  CHECK(eval(f, {0.3, 0.1}, th) == Approx(2.7960629803373562).epsilon(1e-14));

  // With normalisation r = [1 2], s = [2 4]: x = [2 6] gives z = [0.5 1].
  f.set_normalization(Eigen::Vector2d(1, 2), Eigen::Vector2d(2, 4));
  CHECK(eval(f, {2.0, 6.0}, th) == Approx(4.276672449565023).epsilon(1e-14));

  CHECK(f.parameter_names() == std::vector<std::string>{"L[0]", "L[1]", "d", "a[0]", "b[0][0]", "b[0][1]", "c[0]"});
  const std::string d = f.describe(th);
  CHECK(contains(d, "sigma(t) = 1/(1+exp(-t))"));
  CHECK(contains(d, "per unit of x"));
  CHECK(contains(d, "[1, -1]"));

  // Without the linear term: θ = [d a0 b00 b01 c0].
  nlid::SigmoidNet<2, 1, false> g;
  const std::vector<double> tg{0.5, 3, 1, -1, 0.2};
  CHECK(eval(g, {0.3, 0.1}, tg) == Approx(0.5 + 3 * 0.598687660112452).epsilon(1e-13));
  CHECK(g.parameter_names().front() == "d");
}

TEST_CASE("SigmoidNet is stable far into both tails", "[nonlinearities][values]") {
  nlid::SigmoidNet<1, 1, false> f;
  const std::vector<double> th{0, 1, 1, 0};  // g = σ(x)
  CHECK(eval(f, {-800.0}, th) == 0.0);
  CHECK(eval(f, {800.0}, th) == 1.0);
  using D = nlid::Dual<double, 4>;
  std::vector<D> x{D(-800.0)};
  std::vector<D> t;
  for (int i = 0; i < 4; ++i) t.push_back(D::variable(th[static_cast<std::size_t>(i)], i));
  const D g = f(std::span<const D>(x), std::span<const D>(t));
  CHECK(std::isfinite(g.a));
  CHECK(g.v.allFinite());
}

TEST_CASE("WaveletNet evaluates scaling and wavelet terms", "[nonlinearities][values]") {
  nlid::WaveletNet<1, 1> f;
  // θ = [L d a w b c]: ρ = 1.5²·(0.6 − 0.2)² = 0.36; g = 0.3 + 1 + (2 + 3(1 − 0.36)) e^(−0.18).
  const std::vector<double> th{0.5, 1, 2, 3, 1.5, 0.2};
  CHECK(eval(f, {0.6}, th) == Approx(4.574259228732187).epsilon(1e-14));

  nlid::WaveletNet<2, 1> g;
  // L = [1 −1], d = 0.5, a = 2, w = −1, b = 2, c = [0.1 0.2], x = [0.3 0.5]; m = 2.
  const std::vector<double> tg{1, -1, 0.5, 2, -1, 2, 0.1, 0.2};
  CHECK(eval(g, {0.3, 0.5}, tg) == Approx(0.7009468246178545).epsilon(1e-14));
  CHECK(g.parameter_names() ==
        std::vector<std::string>{"L[0]", "L[1]", "d", "a[0]", "w[0]", "b[0]", "c[0][0]", "c[0][1]"});
  CHECK(contains(g.describe(tg), "(m - rho_k)"));
}

TEST_CASE("PwLinear interpolates and extrapolates the end segments", "[nonlinearities][values]") {
  nlid::PwLinear<3> f;
  std::vector<double> th(6);
  const std::vector<double> xs{0, 1, 3}, ys{0, 2, 3};
  f.theta_from_breakpoints(xs, ys, th);
  CHECK(th[0] == 0.0);
  CHECK(th[1] == Approx(0.0).margin(1e-15));        // log(1)
  CHECK(th[2] == Approx(std::log(2.0)).epsilon(1e-15));
  CHECK(eval(f, {0.5}, th) == Approx(1.0).epsilon(1e-15));
  CHECK(eval(f, {2.0}, th) == Approx(2.5).epsilon(1e-15));
  CHECK(eval(f, {-1.0}, th) == Approx(-2.0).epsilon(1e-15));  // first slope 2
  CHECK(eval(f, {5.0}, th) == Approx(4.0).epsilon(1e-15));    // last slope 0.5
  CHECK(eval(f, {1.0}, th) == Approx(2.0).epsilon(1e-15));    // at a breakpoint
  const auto [bx, by] = f.breakpoints(th);
  CHECK(bx[2] == Approx(3.0).epsilon(1e-15));
  CHECK(by[1] == 2.0);
  CHECK(f.parameter_names() == std::vector<std::string>{"x[0]", "log_gap[1]", "log_gap[2]", "y[0]", "y[1]", "y[2]"});
  const std::string d = f.describe(th);
  CHECK(contains(d, "(3, 3)"));
  CHECK(contains(d, "slope to next: 0.5"));
}

TEST_CASE("PwLinear stays finite and exact where a log-gap's exp overflows", "[nonlinearities][values]") {
  // exp(γ) overflows above γ ≈ 709.78. The segment then reaches beyond every finite x, with slope
  // Δy·e^(−γ): tiny but not zero, and its derivatives finite (Δy/∞ gave NaN ones on a Dual).
  using D = nlid::Dual<double, 7>;  // θ (6) and x
  const nlid::PwLinear<3> f;
  const auto check = [&f](const std::vector<double>& th, double x, double g, const std::vector<double>& dg) {
    CAPTURE(x);
    const double v = eval(f, {x}, th);
    CHECK(v == Approx(g).epsilon(1e-14));
    const auto p = f.prepare(std::span<const double>(th));
    CHECK(f.evaluate_prepared(p, x) == v);
    std::vector<D> thd(6);
    for (int i = 0; i < 6; ++i) thd[static_cast<std::size_t>(i)] = D::variable(th[static_cast<std::size_t>(i)], i);
    const D xd = D::variable(x, 6);
    const D vd = f(std::span<const D>(&xd, 1), std::span<const D>(thd));
    const D vp = f.evaluate_prepared(f.prepare(std::span<const D>(thd)), xd);
    CHECK(vd.a == v);
    CHECK(vp.a == v);
    REQUIRE(vd.v.allFinite());
    CHECK((vp.v - vd.v).cwiseAbs().maxCoeff() == 0.0);
    for (int i = 0; i < 7; ++i) {
      CAPTURE(i);
      CHECK(vd.v[i] == Approx(dg[static_cast<std::size_t>(i)]).epsilon(1e-9).margin(1e-300));
    }
  };
  // First gap e^710 = ∞ in double: y0 + (y1 − y0)(x − x0)e^(−710), checked against long double.
  const double e710 = static_cast<double>(std::exp(-710.0L));  // 4.47e-309, subnormal
  const std::vector<double> th1{0.0, 710.0, 0.0, 1.0, 3.0, 4.0};
  const double x = 1e300, t = x * e710;  // position within the segment, 4.5e-9
  // dg/d[x0, γ1, γ2, y0, y1, y2, x]
  check(th1, x, 1.0 + 2.0 * t, {-2.0 * e710, -2.0 * t, 0.0, 1.0 - t, t, 0.0, 2.0 * e710});
  CHECK(eval(f, {x}, th1) - 1.0 == Approx(2.0 * t).epsilon(1e-6));  // not the flat 1 of Δy/∞
  check(th1, -5.0, 1.0, {-2.0 * e710, 0.0, 0.0, 1.0, 0.0, 0.0, 2.0 * e710});
  // Last gap e^1000 beyond x1 = 1: the end segment is flat to double precision, derivatives 0.
  const std::vector<double> th2{0.0, 0.0, 1000.0, 1.0, 3.0, 4.0};
  check(th2, 5.0, 3.0, {0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0});
  check(th2, 0.5, 2.0, {-2.0, -1.0, 0.0, 0.5, 0.5, 0.0, 2.0});  // the ordinary first segment
  // describe() prints the first table's slope as the evaluation computes it (Δy·e^(−γ), not
  // Δy/∞ = 0) and the breakpoint beyond reach as such (it printed inf positions, nan slopes).
  const std::string d1 = f.describe(std::span<const double>(th1));
  CHECK_THAT(d1, Catch::Contains("slope to next: 8.9") && Catch::Contains("not reached: log_gap[1]"));
  CHECK_THAT(d1, !Catch::Contains("nan") && !Catch::Contains("inf,"));
  // Float: exp(100) overflows float's range already.
  const std::vector<float> thf{0.0f, 0.0f, 100.0f, 1.0f, 3.0f, 4.0f};
  const float xf = 5.0f;
  CHECK(f(std::span<const float>(&xf, 1), std::span<const float>(thf)) == 3.0f);
}

TEST_CASE("PwLinear refuses a segment whose gap is too small for its slope, naming the log-gap",
          "[nonlinearities][values]") {
  // e^(−800) underflows to 0: breakpoints 1 and 2 coincide, and beyond them the last segment's
  // slope Δy/0 is infinite (the value was ±∞, at x = x1 or with Δy = 0 NaN). The other segments
  // are still evaluated normally.
  const nlid::PwLinear<3> f;
  using D = nlid::Dual<double, 6>;
  for (const double y2 : {4.0, 3.0}) {  // Δy = 1, and Δy = 0 (0/0)
    CAPTURE(y2);
    const std::vector<double> th{0.0, 0.0, -800.0, 1.0, 3.0, y2};
    std::vector<D> thd(th.begin(), th.end());
    CHECK(eval(f, {0.5}, th) == 2.0);
    for (const double x : {1.0, 5.0}) {
      CAPTURE(x);
      const auto p = f.prepare(std::span<const double>(th));
      const auto pd = f.prepare(std::span<const D>(thd));
      const D xd(x);
      for (const auto& call : std::vector<std::function<void()>>{
               [&] { (void)eval(f, {x}, th); }, [&] { (void)f.evaluate_prepared(p, x); },
               [&] { (void)f(std::span<const D>(&xd, 1), std::span<const D>(thd)); },
               [&] { (void)f.evaluate_prepared(pd, xd); }}) {
        try {
          call();
          FAIL("no nlid::Error for log_gap[2] = -800");
        } catch (const nlid::Error& e) {
          CHECK(e.where().parameter == "log_gap[2]");
          CHECK(contains(e.what(), "log_gap[2] = -800 puts breakpoints 1 and 2 closer together"));
        }
      }
    }
  }
}

TEST_CASE("Saturation clamps to [lower, upper]", "[nonlinearities][values]") {
  nlid::Saturation f;
  const std::vector<double> th{15, 90};
  CHECK(eval(f, {10.0}, th) == 15.0);
  CHECK(eval(f, {50.0}, th) == 50.0);
  CHECK(eval(f, {100.0}, th) == 90.0);
  // Crossed limits are used in order (continuous in θ).
  CHECK(eval(f, {100.0}, {90, 15}) == 90.0);
  CHECK(eval(f, {0.0}, {90, 15}) == 15.0);
  CHECK(contains(f.describe(th), "min(max(x, 15), 90)"));
  CHECK(contains(f.describe(std::vector<double>{90, 15}), "swapped"));
  CHECK(f.parameter_names() == std::vector<std::string>{"lower", "upper"});
}

TEST_CASE("DeadZone is zero inside and unit-slope outside", "[nonlinearities][values]") {
  nlid::DeadZone f;
  const std::vector<double> th{-1, 2};
  CHECK(eval(f, {-3.0}, th) == -2.0);
  CHECK(eval(f, {0.0}, th) == 0.0);
  CHECK(eval(f, {2.0}, th) == 0.0);
  CHECK(eval(f, {5.0}, th) == 3.0);
  CHECK(contains(f.describe(th), "0 for -1 <= x <= 2"));
}

TEST_CASE("Poly1d evaluates ascending coefficients by Horner", "[nonlinearities][values]") {
  nlid::Poly1d<2> f;
  const std::vector<double> th{1, -2, 3};  // 1 − 2x + 3x²
  CHECK(eval(f, {2.0}, th) == 9.0);
  CHECK(eval(f, {-1.0}, th) == 6.0);
  CHECK(f.parameter_names() == std::vector<std::string>{"c[0]", "c[1]", "c[2]"});
  CHECK(contains(f.describe(th), "3·x^2 - 2·x + 1"));
  nlid::Poly1d<nlid::Dynamic> g(4);
  CHECK(g.num_parameters() == 5);
  CHECK(eval(g, {2.0}, {0, 0, 0, 0, 1}) == 16.0);
}

TEST_CASE("TreePartition routes x to its leaf's affine model", "[nonlinearities][values]") {
  nlid::TreePartition<1, 1> f;
  f.set_split(0, Eigen::VectorXd::Ones(1), 0.5);  // right if z > 0.5 (r = 0, s = 1)
  const std::vector<double> th{2, 1, -1, 3};       // leaf 0: 2z + 1, leaf 1: −z + 3
  CHECK(eval(f, {0.2}, th) == Approx(1.4).epsilon(1e-15));
  CHECK(eval(f, {1.0}, th) == Approx(2.0).epsilon(1e-15));
  const double x = 1.0;
  CHECK(f.leaf_of(std::span<const double>(&x, 1)) == 1);
  CHECK(f.parameter_names() == std::vector<std::string>{"L[0][0]", "d[0]", "L[1][0]", "d[1]"});
  const std::string d = f.describe(th);
  CHECK(contains(d, "0: 1*z(x) > 0.5"));
  CHECK(contains(d, "1: L = [-1], d = 3"));
}

TEST_CASE("WaveletNet far from its centres is its linear part, with finite derivatives",
          "[nonlinearities][values]") {
  nlid::WaveletNet<1, 1> f;
  const std::vector<double> th{0.5, 0.1, 1, 0.3, 1, 0};  // L d a w b c
  CHECK(eval(f, {1e20}, th) == 0.5e20);
  CHECK(eval(f, {1e200}, th) == 0.5e200);
  CHECK(eval(f, {-1e300}, th) == -0.5e300);
  nlid::WaveletNet<1, 1, false> g;  // no linear term: the offset alone
  const std::vector<double> tg{0.1, 1, 0.3, 1, 0};
  CHECK(eval(g, {1e200}, tg) == 0.1);
  CHECK(eval(g, {std::numeric_limits<double>::infinity()}, tg) == 0.1);
  using D = nlid::Dual<double, 5>;
  std::vector<D> x{D(1e200)};
  std::vector<D> t;
  for (int i = 0; i < 5; ++i) t.push_back(D::variable(tg[static_cast<std::size_t>(i)], i));
  const D v = g(std::span<const D>(x), std::span<const D>(t));
  CHECK(v.a == 0.1);
  CHECK(v.v.allFinite());
  CHECK(v.v(0) == 1.0);
}

TEST_CASE("DeadZone passes a NaN input on as NaN", "[nonlinearities][values]") {
  const nlid::DeadZone f;
  CHECK(std::isnan(eval(f, {std::nan("")}, {-1, 2})));
  CHECK(std::isnan(eval(f, {std::nan("")}, {2, -1})));  // crossed limits as well
}
