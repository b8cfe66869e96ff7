// Polynomials in q^-1: filtering (double, float, Dual), roots, reflection, formatting.
#include <catch2/catch.hpp>

#include <algorithm>
#include <complex>

#include "linear_test_util.hpp"
#include "nlid/ad/dual.hpp"
#include "nlid/linear/polynomial.hpp"

namespace {
Eigen::VectorXd vec(std::initializer_list<double> v) {
  Eigen::VectorXd x(static_cast<Eigen::Index>(v.size()));
  Eigen::Index k = 0;
  for (double d : v) x(k++) = d;
  return x;
}
}  // namespace

TEST_CASE("filter runs the difference equation from rest", "[linear][polynomial]") {
  const Eigen::VectorXd a = vec({2.0, -3.0, 1.4});  // a0 != 1 is normalised
  const Eigen::VectorXd b = vec({0.0, 1.0, 0.5});
  const Eigen::VectorXd x = nlid_test::white_noise(50, 1, 3);
  const Eigen::VectorXd y = nlid::filter(b, a, x);
  // Hand recursion: 2 y(t) = x(t-1) + 0.5 x(t-2) + 3 y(t-1) - 1.4 y(t-2).
  Eigen::VectorXd r = Eigen::VectorXd::Zero(50);
  for (int t = 0; t < 50; ++t) {
    double acc = 0;
    if (t >= 1) acc += x(t - 1) + 3.0 * r(t - 1);
    if (t >= 2) acc += 0.5 * x(t - 2) - 1.4 * r(t - 2);
    r(t) = acc / 2.0;
  }
  CHECK((y - r).cwiseAbs().maxCoeff() < 1e-12);
  const Eigen::VectorXf yf = nlid::filter(b.cast<float>(), a.cast<float>(), x.cast<float>());
  CHECK((yf.cast<double>() - r).cwiseAbs().maxCoeff() < 1e-4 * r.cwiseAbs().maxCoeff());
  CHECK_THROWS_WITH(nlid::filter(b, vec({0.0, 1.0}), x), Catch::Contains("a0 is zero"));
}

TEST_CASE("filter with Dual coefficients matches central differences", "[linear][polynomial]") {
  using D = nlid::Dual<double, 3>;
  const Eigen::VectorXd x = nlid_test::white_noise(40, 1, 4);
  const double th[3] = {0.8, -1.2, 0.5};  // b0, a1, a2
  Eigen::Matrix<D, Eigen::Dynamic, 1> b(1), a(3);
  b(0) = D::variable(th[0], 0);
  a(0) = D(1.0);
  a(1) = D::variable(th[1], 1);
  a(2) = D::variable(th[2], 2);
  const auto y = nlid::filter(b, a, x);
  auto plain = [&](int k, double h) {
    double p[3] = {th[0], th[1], th[2]};
    p[k] += h;
    return nlid::filter(vec({p[0]}), vec({1.0, p[1], p[2]}), x);
  };
  for (int k = 0; k < 3; ++k) {
    const double h = 1e-6;
    const Eigen::VectorXd fd = (plain(k, h) - plain(k, -h)) / (2 * h);
    for (Eigen::Index t = 0; t < x.size(); ++t)
      CHECK(y(t).v(k) == Approx(fd(t)).margin(1e-6 * std::max(1.0, std::abs(fd(t)))));
  }
}

TEST_CASE("roots, poly_from_roots and reflection", "[linear][polynomial]") {
  // (1 - 0.5 q^-1)(1 - 2 q^-1) = 1 - 2.5 q^-1 + q^-2: roots 0.5 and 2.
  const Eigen::VectorXd p = vec({1.0, -2.5, 1.0});
  Eigen::VectorXcd r = nlid::roots(p);
  std::vector<double> mags{std::abs(r(0)), std::abs(r(1))};
  std::sort(mags.begin(), mags.end());
  CHECK(mags[0] == Approx(0.5));
  CHECK(mags[1] == Approx(2.0));
  CHECK((nlid::poly_from_roots(r) - p).norm() < 1e-12);
  CHECK_FALSE(nlid::is_stable_polynomial(p));
  const Eigen::VectorXd q = nlid::reflect_unstable(p);  // 2 -> 0.5: (1 - 0.5 q^-1)^2
  CHECK((q - vec({1.0, -1.0, 0.25})).norm() < 1e-12);
  CHECK(nlid::is_stable_polynomial(q));
  // Reflection keeps the magnitude response up to one constant factor.
  const Eigen::VectorXd w = Eigen::VectorXd::LinSpaced(7, 0.1, 3.0);
  const Eigen::VectorXcd g1 = nlid::frequency_response(vec({1.0}), p, w, 1.0);
  const Eigen::VectorXcd g2 = nlid::frequency_response(vec({1.0}), q, w, 1.0);
  const double ratio = std::abs(g1(0)) / std::abs(g2(0));
  for (Eigen::Index k = 1; k < w.size(); ++k) CHECK(std::abs(g1(k)) / std::abs(g2(k)) == Approx(ratio));
  // Complex pair and leading delay zeros.
  const Eigen::VectorXcd rc = nlid::roots(vec({0.0, 0.0, 1.0, -1.6, 0.89}));  // 0.8 +/- 0.5i
  REQUIRE(rc.size() == 2);
  CHECK(std::abs(rc(0)) == Approx(std::sqrt(0.89)));
  CHECK(nlid::spectral_radius(vec({1.0, -1.6, 0.89})) == Approx(std::sqrt(0.89)));
}

TEST_CASE("convolve, evaluate and frequency response", "[linear][polynomial]") {
  CHECK((nlid::convolve(vec({1, 1}), vec({1, -1})) - vec({1, 0, -1})).norm() == 0.0);
  const Eigen::VectorXd b = vec({0.0, 0.3}), a = vec({1.0, -0.7});
  const Eigen::VectorXcd g = nlid::frequency_response(b, a, vec({0.0}), 0.01);
  CHECK(g(0).real() == Approx(1.0));  // B(1)/A(1) = 0.3/0.3
  CHECK(std::abs(g(0).imag()) < 1e-14);
  // At Nyquist z = -1: -0.3 / 1.7.
  const Eigen::VectorXcd gn = nlid::frequency_response(b, a, vec({M_PI / 0.01}), 0.01);
  CHECK(gn(0).real() == Approx(-0.3 / 1.7));
}

TEST_CASE("format_polynomial writes the toolbox form", "[linear][polynomial]") {
  CHECK(nlid::format_polynomial(vec({1.0, -1.5, 0.7})) == "1 - 1.5 q^-1 + 0.7 q^-2");
  CHECK(nlid::format_polynomial(vec({0.0, 0.25})) == "0.25 q^-1");
  CHECK(nlid::format_polynomial(vec({0.0, 0.0})) == "0");
  CHECK(nlid::format_polynomial(vec({1.0, 1.0})) == "1 + q^-1");
  const Eigen::VectorXd sd = vec({0.0, 0.01});
  CHECK(nlid::format_polynomial(vec({1.0, -0.5}), 4, "q", &sd) == "1 - 0.5 (+/- 0.01) q^-1");
  Eigen::VectorXcd r(3);
  r << std::complex<double>(0.5, 0.25), std::complex<double>(0.5, -0.25), 0.1;
  CHECK(nlid::format_roots(r) == "0.5 +/- 0.25i, 0.1");
}

TEST_CASE("format_number: the toolbox's 4 significant digits by default", "[linear][polynomial]") {
  CHECK(nlid::format_number(1.523456) == "1.523");
  CHECK(nlid::format_number(1.523456, 6) == "1.52346");
  CHECK(nlid::format_number(-0.000123456) == "-0.0001235");
}
