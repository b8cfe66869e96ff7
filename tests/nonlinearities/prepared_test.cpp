// PwLinear's prepared evaluation (breakpoint positions and slopes computed once per θ, used by
// block models through detail::BoundScalarMap) must give exactly operator()'s value, on double
// and on Dual, below, inside and beyond the breakpoints, for the fixed and the Dynamic twin.
#include <catch2/catch.hpp>

#include <random>

#include "nlid/nonlinearities/detail/bound_map.hpp"
#include "nlid/nonlinearities/piecewise_linear.hpp"
#include "nlid/nonlinearities/saturation.hpp"

namespace {
std::span<const double> cspan(const Eigen::VectorXd& v) { return {v.data(), static_cast<std::size_t>(v.size())}; }

template <class F>
void check_prepared(const F& f, const Eigen::VectorXd& theta) {
  using D = nlid::Dual<double, 20>;
  std::vector<D> thd(static_cast<std::size_t>(theta.size()));
  for (Eigen::Index i = 0; i < theta.size(); ++i) thd[static_cast<std::size_t>(i)] = D::variable(theta(i), static_cast<int>(i));
  const std::span<const double> th(theta.data(), static_cast<std::size_t>(theta.size()));
  const auto p = f.prepare(th);
  const auto pd = f.prepare(std::span<const D>(thd));
  const nlid::detail::BoundScalarMap<F, double> bound(f, th);
  for (double x = -3.0; x <= 3.0; x += 0.013) {
    CAPTURE(x);
    const double g = f(std::span<const double>(&x, 1), th);
    CHECK(f.evaluate_prepared(p, x) == g);
    CHECK(bound(x) == g);
    const D xd = D::variable(x, 19);
    const D gd = f(std::span<const D>(&xd, 1), std::span<const D>(thd));
    const D gp = f.evaluate_prepared(pd, xd);
    CHECK(gp.a == gd.a);
    CHECK((gp.v - gd.v).cwiseAbs().maxCoeff() == 0.0);
  }
}
}  // namespace

TEST_CASE("PwLinear prepared evaluation equals operator() on double and Dual", "[nonlinearities][pwlinear]") {
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> d(-1.0, 1.0);
  Eigen::VectorXd theta(20);
  theta(0) = -2.0;
  for (int k = 1; k < 10; ++k) theta(k) = std::log(0.3 + 0.2 * (d(rng) + 1.0));
  for (int k = 10; k < 20; ++k) theta(k) = d(rng);
  check_prepared(nlid::PwLinear<10>{}, theta);
  check_prepared(nlid::PwLinear<nlid::Dynamic>(10), theta);
  // Two breakpoints: one segment, extrapolated both ways.
  Eigen::VectorXd t2(4);
  t2 << -0.5, 0.0, 1.0, 3.0;
  check_prepared(nlid::PwLinear<2>{}, t2);
}

TEST_CASE("BoundScalarMap falls back to operator() for maps without prepare", "[nonlinearities][pwlinear]") {
  STATIC_REQUIRE(nlid::detail::PreparedEvaluation<nlid::PwLinear<10>, double>);
  STATIC_REQUIRE_FALSE(nlid::detail::PreparedEvaluation<nlid::Saturation, double>);
  const nlid::Saturation sat;
  Eigen::VectorXd th(2);  // a VectorXd: cspan() of a Vector2d would view a temporary copy
  th << 15.0, 90.0;
  const nlid::detail::BoundScalarMap<nlid::Saturation, double> bound(sat, cspan(th));
  for (double x : {0.0, 15.0, 50.0, 90.0, 120.0}) CHECK(bound(x) == sat(std::span<const double>(&x, 1), cspan(th)));
}

TEST_CASE("PwLinear::prepare refuses a wrong-length theta", "[nonlinearities][pwlinear]") {
  const Eigen::VectorXd th = Eigen::VectorXd::Zero(7);
  CHECK_THROWS_WITH(nlid::PwLinear<4>{}.prepare(cspan(th)), Catch::Contains("theta"));
}
