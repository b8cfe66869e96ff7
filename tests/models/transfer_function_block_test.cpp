// TransferFunctionBlock: TDF-II stepping equals the difference equation, steady state,
// polynomials round trip, Dynamic twin, scalar genericity, bad orders.
#include <catch2/catch.hpp>

#include <cmath>

#include "nlid/linear/polynomial.hpp"
#include "nlid/models/transfer_function_block.hpp"

using nlid::Dynamic;

namespace {
Eigen::VectorXd excitation(int n) {
  Eigen::VectorXd w(n);
  for (int t = 0; t < n; ++t) w(t) = std::sin(0.2 * t) + (t % 17 < 8 ? 1.0 : -0.5);
  return w;
}
template <class Block>
Eigen::VectorXd run(const Block& b, const Eigen::VectorXd& theta, const Eigen::VectorXd& w) {
  Eigen::VectorXd x(w.size());
  b.template simulate<double>({w.data(), static_cast<std::size_t>(w.size())},
                              {theta.data(), static_cast<std::size_t>(theta.size())}, {},
                              {x.data(), static_cast<std::size_t>(x.size())});
  return x;
}
}  // namespace

TEST_CASE("TDF-II block equals the difference equation B(q)/F(q) w(t-nk)", "[models][linear_block]") {
  const Eigen::VectorXd w = excitation(200);
  SECTION("[2 2 1]") {
    nlid::TransferFunctionBlock<2, 2, 1> b;
    static_assert(decltype(b)::num_params == 4 && decltype(b)::num_states == 2);
    Eigen::VectorXd theta(4);
    theta << 0.5, 0.25, -1.5, 0.7;
    const auto [B, F] = b.polynomials({theta.data(), 4});
    CHECK(B.size() == 3);
    CHECK(B(0) == 0.0);
    const Eigen::VectorXd ref = nlid::filter(B, F, w);
    CHECK((run(b, theta, w) - ref).cwiseAbs().maxCoeff() < 1e-12);
  }
  SECTION("[3 3 0] with direct feed-through") {
    nlid::TransferFunctionBlock<3, 3, 0> b;
    Eigen::VectorXd theta(6);
    theta << 0.2, -0.1, 0.05, -1.2, 0.5, -0.06;
    const auto [B, F] = b.polynomials({theta.data(), 6});
    CHECK((run(b, theta, w) - nlid::filter(B, F, w)).cwiseAbs().maxCoeff() < 1e-12);
  }
  SECTION("[1 2 4]: delay longer than the denominator") {
    nlid::TransferFunctionBlock<1, 2, 4> b;
    static_assert(decltype(b)::num_states == 4);
    Eigen::VectorXd theta(3);
    theta << 0.3, -0.9, 0.2;
    const auto [B, F] = b.polynomials({theta.data(), 3});
    CHECK((run(b, theta, w) - nlid::filter(B, F, w)).cwiseAbs().maxCoeff() < 1e-12);
  }
}

TEST_CASE("equilibrium state keeps the block at its static gain", "[models][linear_block]") {
  nlid::TransferFunctionBlock<2, 2, 1> b;
  Eigen::VectorXd theta(4);
  theta << 0.5, 0.25, -1.5, 0.7;
  const std::span<const double> th(theta.data(), 4);
  Eigen::Vector2d s;
  REQUIRE(b.equilibrium_state(2.0, th, std::span<double>(s.data(), 2)));
  const double gain = b.dc_gain(th);
  CHECK(gain == Approx(0.75 / 0.2));
  for (int t = 0; t < 50; ++t) CHECK(b.step(std::span<double>(s.data(), 2), 2.0, th) == Approx(2.0 * gain).epsilon(1e-12));
  // An integrator (F(1) = 0) has no steady state.
  Eigen::VectorXd integ(3);
  integ << 1.0, -1.0, 0.0;
  nlid::TransferFunctionBlock<1, 2, 0> bi;
  Eigen::Vector2d si = Eigen::Vector2d::Constant(7.0);
  CHECK_FALSE(bi.equilibrium_state(1.0, std::span<const double>(integ.data(), 3), std::span<double>(si.data(), 2)));
  CHECK(si(0) == 7.0);
}

TEST_CASE("polynomials round trip, with and without the delay's zeros", "[models][linear_block]") {
  nlid::TransferFunctionBlock<2, 2, 1> b;
  Eigen::Vector4d theta(0.5, 0.25, -1.5, 0.7), back;
  const auto [B, F] = b.polynomials({theta.data(), 4});
  b.set_from_polynomials(B, F, {back.data(), 4});
  CHECK(back == theta);
  b.set_from_polynomials(B.tail(2), F, {back.data(), 4});
  CHECK(back == theta);
  Eigen::VectorXd bad_b(3);
  bad_b << 0.1, 0.5, 0.25;
  CHECK_THROWS_WITH(b.set_from_polynomials(bad_b, F, {back.data(), 4}),
                    Catch::Contains("first nk = 1 coefficients must be zero") && Catch::Contains("parameter 'B'"));
  Eigen::VectorXd bad_f(3);
  bad_f << 2.0, -1.5, 0.7;
  CHECK_THROWS_WITH(b.set_from_polynomials(B, bad_f, {back.data(), 4}), Catch::Contains("monic"));
  CHECK(b.parameter_names() == std::vector<std::string>{"b1", "b2", "f1", "f2"});
  const std::string d = b.describe({theta.data(), 4});
  CHECK_THAT(d, Catch::Contains("B(q) = 0.5 q^-1 + 0.25 q^-2") && Catch::Contains("F(q) = 1 - 1.5 q^-1 + 0.7 q^-2"));
}

TEST_CASE("A linear block's describe names the degree instead of factoring a huge F", "[models][linear_block]") {
  // Found by tests/fuzz/spec_fuzz.cpp: describe() factored F through its companion matrix, nf²
  // doubles (nf = 10^5 is a valid order: 80 GB), to list the poles.
  const nlid::TransferFunctionBlock<Dynamic, Dynamic, Dynamic> high(1, 600, 0);
  std::vector<double> theta_high(601, 0.0);
  theta_high[1] = -0.5;
  CHECK_THAT(high.describe(theta_high), Catch::Contains("poles: not listed (degree 600, above 500)"));
  const nlid::TransferFunctionBlock<Dynamic, Dynamic, Dynamic> low(1, 1, 0);
  const std::vector<double> theta_low{1.0, -0.5};
  CHECK_THAT(low.describe(theta_low), Catch::Contains("poles: 0.5\n"));
}

TEST_CASE("Dynamic twin and float/Dual scalars give the same output", "[models][linear_block]") {
  const Eigen::VectorXd w = excitation(100);
  Eigen::VectorXd theta(5);
  theta << 0.2, -0.1, 0.05, -1.2, 0.5;
  nlid::TransferFunctionBlock<3, 2, 1> fixed;
  nlid::TransferFunctionBlock<Dynamic, Dynamic, Dynamic> dyn(3, 2, 1);
  static_assert(decltype(dyn)::num_states == Dynamic);
  CHECK(dyn.num_states_runtime() == 3);
  CHECK((run(fixed, theta, w) - run(dyn, theta, w)).cwiseAbs().maxCoeff() < 1e-12);

  // float
  Eigen::VectorXf wf = w.cast<float>(), thf = theta.cast<float>(), xf(w.size());
  fixed.simulate<float>({wf.data(), 100}, {thf.data(), 5}, {}, {xf.data(), 100});
  CHECK((xf.cast<double>() - run(fixed, theta, w)).cwiseAbs().maxCoeff() < 1e-4);

  // Dual: derivative with respect to b1 equals the response to w filtered by 1/F (times q^-nk).
  using D = nlid::Dual<double, 5>;
  std::vector<D> th(5), wd(100), xd(100);
  for (int i = 0; i < 5; ++i) th[i] = D::variable(theta(i), i);
  for (int t = 0; t < 100; ++t) wd[t] = D(w(t));
  fixed.simulate<D>(wd, th, {}, xd);
  const double h = 1e-6;
  for (int i = 0; i < 5; ++i) {
    Eigen::VectorXd tp = theta, tm = theta;
    tp(i) += h;
    tm(i) -= h;
    const Eigen::VectorXd fd = (run(fixed, tp, w) - run(fixed, tm, w)) / (2 * h);
    for (int t = 0; t < 100; ++t) CHECK(xd[t].v[i] == Approx(fd(t)).margin(1e-6));
  }
}

TEST_CASE("bad linear block orders name the order", "[models][linear_block]") {
  CHECK_THROWS_WITH((nlid::TransferFunctionBlock<Dynamic, Dynamic, Dynamic>(0, 2, 1)),
                    Catch::Contains("nb must be >= 1") && Catch::Contains("parameter 'nb'"));
  CHECK_THROWS_WITH((nlid::TransferFunctionBlock<2, Dynamic, 1>(2, -1, 1)), Catch::Contains("parameter 'nf'"));
  CHECK_THROWS_WITH((nlid::TransferFunctionBlock<2, 2, Dynamic>(2, 2, -3)), Catch::Contains("nk must be >= 0"));
}
