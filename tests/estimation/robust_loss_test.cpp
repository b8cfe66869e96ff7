// Robust losses: values and derivatives of ρ against the definitions and finite differences,
// continuity at the threshold, robust scale, validation.
#include <catch2/catch.hpp>

#include <cmath>

#include "nlid/estimation/robust_loss.hpp"

using Catch::Matchers::Contains;
using nlid::RobustLoss;

TEST_CASE("Huber ρ: quadratic inside δ, linear outside, C¹ at the threshold",
          "[estimation][robust]") {
  const RobustLoss h = RobustLoss::huber(0.5);
  // Inside: ρ(s) = s.
  CHECK(nlid::evaluate_loss(h, 0.09).rho == Approx(0.09));
  CHECK(nlid::evaluate_loss(h, 0.09).rho1 == 1.0);
  // Outside: ρ = 2δ|r| − δ²: for r = 3, 2·0.5·3 − 0.25 = 2.75.
  const auto v = nlid::evaluate_loss(h, 9.0);
  CHECK(v.rho == Approx(2.75));
  CHECK(v.rho1 == Approx(0.5 / 3.0));
  CHECK(v.rho2 == Approx(-0.25 / 27.0));
  // Continuity of ρ and ρ' at s = δ².
  const auto lo = nlid::evaluate_loss(h, 0.25 - 1e-12), hi = nlid::evaluate_loss(h, 0.25 + 1e-12);
  CHECK(lo.rho == Approx(hi.rho).margin(1e-11));
  CHECK(lo.rho1 == Approx(hi.rho1).margin(1e-10));
  // ρ' and ρ'' against central differences of ρ (outside).
  for (double s : {0.3, 1.0, 7.0}) {
    const double d = 1e-6;
    const double fd1 = (nlid::evaluate_loss(h, s + d).rho - nlid::evaluate_loss(h, s - d).rho) / (2 * d);
    const double fd2 = (nlid::evaluate_loss(h, s + d).rho1 - nlid::evaluate_loss(h, s - d).rho1) / (2 * d);
    CHECK(nlid::evaluate_loss(h, s).rho1 == Approx(fd1).epsilon(1e-7));
    CHECK(nlid::evaluate_loss(h, s).rho2 == Approx(fd2).epsilon(1e-6));
  }
  // Squared loss is ρ(s) = s everywhere.
  const auto q = nlid::evaluate_loss(RobustLoss::squared(), 9.0);
  CHECK(q.rho == 9.0);
  CHECK(q.rho1 == 1.0);
  CHECK(q.rho2 == 0.0);
}

TEST_CASE("robust cost and IRLS weights", "[estimation][robust]") {
  Eigen::VectorXd r(3);
  r << 0.1, -2.0, 4.0;
  CHECK(nlid::robust_cost(RobustLoss::squared(), r) == Approx(0.5 * (0.01 + 4 + 16)));
  const RobustLoss h = RobustLoss::huber(1.0);
  CHECK(nlid::robust_cost(h, r) == Approx(0.5 * (0.01 + 3.0 + 7.0)));
  Eigen::VectorXd w(3);
  nlid::robust_weights(h, r, w);
  CHECK(w[0] == 1.0);
  CHECK(w[1] == Approx(std::sqrt(0.5)));
  CHECK(w[2] == Approx(std::sqrt(0.25)));
  // The weighted gradient term wᵢ² rᵢ equals dρ(rᵢ²)/drᵢ / 2: Huber's ψ clipped at ±δ.
  CHECK(w[1] * w[1] * r[1] == Approx(-1.0));
  CHECK(w[2] * w[2] * r[2] == Approx(1.0));
}

TEST_CASE("robust_scale is 1.4826 times the median absolute deviation, even and odd lengths",
          "[estimation][robust]") {
  // Even length: median 1.5 (mean of the middle pair), deviations 1.5 0.5 0.5 8.5, MAD 1.
  Eigen::VectorXd even(4);
  even << 10.0, 0.0, 2.0, 1.0;
  CHECK(nlid::robust_scale(even) == Approx(1.482602218505602));
  // Odd length: median 2, deviations 2 1 0 8 9, MAD 2.
  Eigen::VectorXd odd(5);
  odd << 11.0, 0.0, 2.0, 10.0, 1.0;
  CHECK(nlid::robust_scale(odd) == Approx(2.0 * 1.482602218505602));
}

TEST_CASE("robust_scale ignores outliers, validation names the field", "[estimation][robust]") {
  Eigen::VectorXd r(101);
  for (int i = 0; i < 101; ++i) r[i] = 0.2 * std::sin(0.37 * i * i);
  const double s0 = nlid::robust_scale(r);
  for (int i = 0; i < 101; i += 10) r[i] = 1e3;  // 11 gross outliers
  const double s1 = nlid::robust_scale(r);
  CHECK(s0 > 0.05);
  CHECK(s1 == Approx(s0).epsilon(0.3));  // barely moved, unlike the standard deviation
  Eigen::VectorXd e(0);
  CHECK_THROWS_WITH(nlid::robust_scale(e), Contains("empty"));
  r[5] = std::nan("");
  CHECK_THROWS_WITH(nlid::robust_scale(r), Contains("residual 5 is not finite"));
  try {
    nlid::validate(RobustLoss::huber(0.0));
    FAIL("no error");
  } catch (const nlid::Error& err) {
    CHECK(err.where().parameter == "loss.delta");
  }
  CHECK_NOTHROW(nlid::validate(RobustLoss{RobustLoss::Kind::squared, -1.0}));  // δ unused
}
