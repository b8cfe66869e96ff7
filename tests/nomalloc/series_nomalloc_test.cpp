// Proof that a fixed-size Series (Wiener-Hammerstein [4 3 0] / poly1d(5) / [4 3 0]) simulates
// without heap allocation, on double and on Dual (the Jacobian pass of the estimator).
//
// Eigen's EIGEN_RUNTIME_NO_MALLOC trap is armed (NDEBUG undone so its assertion fires). The
// counting operator new of this executable lives in models_nomalloc_test.cpp and is not visible
// here; the series simulation loop uses no std container, so the Eigen trap covers it (the
// per-block state is one fixed-size Eigen vector and the per-block parameters are spans).
#undef NDEBUG
#include <catch2/catch.hpp>

#include <cmath>

#include "nlid/models/series.hpp"
#include "nlid/nonlinearities/piecewise_linear.hpp"
#include "nlid/nonlinearities/polynomial.hpp"

#ifndef EIGEN_RUNTIME_NO_MALLOC
#error "tests/nomalloc must be compiled with EIGEN_RUNTIME_NO_MALLOC"
#endif

namespace {
using Wh = nlid::WienerHammerstein<nlid::TransferFunctionBlock<4, 3, 0>, nlid::Poly1d<5>,
                                   nlid::TransferFunctionBlock<4, 3, 0>>;
using Hammer = nlid::Hammerstein<nlid::PwLinear<4>, nlid::TransferFunctionBlock<2, 2, 1>>;

Eigen::MatrixXd series_input(int n) {
  Eigen::MatrixXd u(n, 1);
  for (int t = 0; t < n; ++t) u(t, 0) = 0.4 * std::sin(0.07 * t) + (t / 40 % 2 ? 0.3 : -0.2);
  return u;
}
}  // namespace

TEST_CASE("fixed-size Wiener-Hammerstein series: simulate on double and Dual allocates nothing",
          "[nomalloc][series]") {
  static_assert(Wh::num_params == 20 && Wh::num_states == 6);
  Wh m;
  Eigen::VectorXd th(Wh::num_params);
  th << 0.2, 0.1, 0.05, 0.01, -0.9, 0.2, -0.02,  // G1
      0.0, 1.0, 0.1, -0.2, 0.01, 0.005,        // g
      0.3, -0.1, 0.05, 0.0, -0.5, 0.1, 0.0;    // G2
  m.set_parameters(th);
  const Eigen::MatrixXd u = series_input(600);
  Eigen::VectorXd y(600);
  using D = nlid::Dual<double, Wh::num_params>;
  Eigen::Matrix<D, Wh::num_params, 1> thd;
  for (int i = 0; i < Wh::num_params; ++i) thd(i) = D::variable(th(i), i);
  Eigen::Matrix<D, Eigen::Dynamic, 1> yd(600);
  Eigen::Matrix<double, 6, 1> x0;
  x0 << 0.1, 0.0, -0.1, 0.2, 0.0, 0.05;
  bool ok = true;
  Eigen::internal::set_is_malloc_allowed(false);
  ok = ok && m.simulate<double>(u, nlid::detail::as_const_span(th), {}, nlid::detail::as_span(y));
  ok = ok && m.simulate<double>(u, nlid::detail::as_const_span(th), std::span<const double>(x0.data(), 6),
                                nlid::detail::as_span(y));
  ok = ok && m.simulate<D>(u, std::span<const D>(thd.data(), Wh::num_params), {}, std::span<D>(yd.data(), 600));
  Eigen::internal::set_is_malloc_allowed(true);
  CHECK(ok);
  CHECK(std::isfinite(y(599)));
  CHECK(yd(599).v.allFinite());
}

TEST_CASE("fixed-size Hammerstein series (pwlinear, [2 2 1]) allocates nothing", "[nomalloc][series]") {
  Hammer m;
  Eigen::VectorXd th(Hammer::num_params);
  th << -1.0, 0.0, 0.0, 0.0, -1.0, -0.2, 0.3, 1.2,  // breakpoints and values
      0.5, 0.25, -1.5, 0.7;                          // linear block
  m.set_parameters(th);
  const Eigen::MatrixXd u = series_input(400);
  Eigen::VectorXd y(400);
  Eigen::internal::set_is_malloc_allowed(false);
  const bool ok = m.simulate<double>(u, nlid::detail::as_const_span(th), {}, nlid::detail::as_span(y));
  Eigen::internal::set_is_malloc_allowed(true);
  CHECK(ok);
}
