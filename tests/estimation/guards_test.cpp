// Guards of the estimation layer found in review: a gradient that overflows to NaN is not a
// converged gradient, a large fixed parameter does not loosen the step test of the free ones,
// multi-start validates the solver's options before it samples with them, and bad arguments of
// the helpers are named.
#include <catch2/catch.hpp>

#include <atomic>
#include <cmath>
#include <limits>
#include <span>
#include <string>

#include "nlid/estimation.hpp"
#include "nlid/estimation/multi_start.hpp"
#include "test_problems.hpp"

using Catch::Matchers::Contains;
using nlid::LmOptions;
using nlid::LmStatus;

namespace {

// The error `fn` throws; fails the test if it throws none or another type.
template <class Fn>
nlid::Error error_of(Fn&& fn) {
  try {
    fn();
  } catch (const nlid::Error& e) {
    return e;
  }
  FAIL("no nlid::Error thrown");
  return nlid::Error("unreachable");
}

// A functor that reports a negative residual count.
struct NoResiduals {
  static constexpr int num_params = 1;
  int num_parameters() const { return 1; }
  Eigen::Index num_residuals() const { return -1; }
  template <class T>
  bool residuals(std::span<const T>, std::span<T>) const {
    return true;
  }
};

}  // namespace

TEST_CASE("a gradient that overflows to NaN is never reported as converged", "[estimation][lm]") {
  // Finite residuals (cost 2.5e300) and a finite Jacobian, but Jᵀr = 1e350 − 2e350 = inf − inf:
  // the projected-gradient test must not read the NaN as zero.
  auto problem = nlid::make_problem<1>(1, 2, [](const auto& th, Eigen::VectorXd& r, auto* J) {
    r << 1e150 + 1e200 * th[0], 2e150 - 1e200 * th[0];
    if (J) (*J) << 1e200, -1e200;
    return true;
  });
  Eigen::Matrix<double, 1, 1> th(0.0);
  const auto s = nlid::solve_least_squares(problem, th);
  INFO(s.message());
  CHECK(std::isfinite(s.initial_cost));
  CHECK(s.status != LmStatus::gradient_tolerance_reached);
  CHECK_FALSE(s.converged());
  CHECK(std::isnan(s.final_gradient_norm));
}

TEST_CASE("a large fixed parameter does not loosen the step test of the free ones", "[estimation][lm]") {
  // Rosenbrock in (x0, x1) with a third, fixed parameter of 1e9 the residuals ignore: with ‖θ‖
  // taken over all parameters the step test would accept any step below 10 as "converged".
  auto problem = nlid::make_problem<3>(3, 2, [](const auto& x, Eigen::VectorXd& r, auto* J) {
    r << 10.0 * (x[1] - x[0] * x[0]), 1.0 - x[0];
    if (J) {
      *J << -20.0 * x[0], 10.0, 0.0, -1.0, 0.0, 0.0;
    }
    return true;
  });
  Eigen::Vector3d x(-1.2, 1.0, 1e9);
  LmOptions o;
  o.fixed = {false, false, true};
  const auto s = nlid::solve_least_squares(problem, x, o);
  INFO(s.message());
  CHECK(s.converged());
  CHECK(std::abs(x[0] - 1.0) < 1e-6);
  CHECK(std::abs(x[1] - 1.0) < 1e-6);
  CHECK(x[2] == 1e9);
}
