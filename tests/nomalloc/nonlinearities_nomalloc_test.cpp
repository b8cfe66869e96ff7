// Fixed-size nonlinearities evaluate without touching the heap, on double and on the
// fixed-size Dual used for Jacobians (this executable is built with EIGEN_RUNTIME_NO_MALLOC, so
// any Eigen allocation inside the guarded region aborts the test).
#include <catch2/catch.hpp>

#include <array>
#include <cmath>
#include <span>
#include <vector>

#include "nlid/nonlinearities.hpp"

namespace {

// Initialises on a small data set (heap allowed), then evaluates value and gradient with the
// heap switched off; the results are compared with the double evaluation afterwards.
template <class F>
void check_no_heap(F f) {
  constexpr int M = F::num_inputs;
  constexpr int P = F::num_params;
  Eigen::MatrixXd X(64, M);
  Eigen::VectorXd y(64);
  for (int i = 0; i < 64; ++i) {
    for (int j = 0; j < M; ++j) X(i, j) = std::sin(0.37 * i + j) * 2.0;
    y(i) = std::tanh(X(i, 0)) + 0.1 * X(i, M - 1);
  }
  std::array<double, static_cast<std::size_t>(P)> theta{};
  f.initialize(X, y, theta);

  using D = nlid::Dual<double, P>;
  std::array<D, static_cast<std::size_t>(P)> td;
  for (int i = 0; i < P; ++i) td[static_cast<std::size_t>(i)] = D::variable(theta[static_cast<std::size_t>(i)], i);
  std::array<double, static_cast<std::size_t>(M)> x{};
  std::array<D, static_cast<std::size_t>(M)> xd;
  double sum = 0;
  D dsum;
  Eigen::internal::set_is_malloc_allowed(false);
  for (int i = 0; i < 64; ++i) {
    for (int j = 0; j < M; ++j) {
      x[static_cast<std::size_t>(j)] = X(i, j);
      xd[static_cast<std::size_t>(j)] = D(X(i, j));
    }
    sum += f(std::span<const double>(x), std::span<const double>(theta));
    dsum += f(std::span<const D>(xd), std::span<const D>(td));
  }
  Eigen::internal::set_is_malloc_allowed(true);
  CHECK(std::isfinite(sum));
  CHECK(dsum.a == Approx(sum).epsilon(1e-12));
  CHECK(dsum.v.allFinite());
  CHECK(dsum.v.norm() > 0);
}

}  // namespace

TEST_CASE("fixed-size nonlinearities evaluate without heap allocation", "[nomalloc][nonlinearities]") {
  check_no_heap(nlid::LinearMap<3>{});
  check_no_heap(nlid::SigmoidNet<3, 5>{});
  check_no_heap(nlid::SigmoidNet<6, 5, false>{});
  check_no_heap(nlid::WaveletNet<2, 4>{});
  check_no_heap(nlid::PwLinear<10>{});
  check_no_heap(nlid::Saturation{});
  check_no_heap(nlid::DeadZone{});
  check_no_heap(nlid::Poly1d<3>{});
  check_no_heap(nlid::TreePartition<3, 2>{});
}
