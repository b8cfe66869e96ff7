// fit_percent: the study's quality measure, checked against hand-computed values.
#include <catch2/catch.hpp>

#include <cmath>
#include <limits>

#include "nlid/analysis/fit.hpp"

TEST_CASE("fit_percent known values", "[analysis][fit]") {
  Eigen::VectorXd y(4);
  y << 1, 2, 3, 4;  // mean 2.5, ||y - mean|| = sqrt(5)
  SECTION("perfect model scores 100") { CHECK(nlid::fit_percent(y, y) == Approx(100.0)); }
  SECTION("the mean scores 0") {
    const Eigen::VectorXd m = Eigen::VectorXd::Constant(4, 2.5);
    CHECK(nlid::fit_percent(y, m) == Approx(0.0).margin(1e-12));
  }
  SECTION("hand-computed value") {
    Eigen::VectorXd h(4);
    h << 1, 2, 3, 5;  // error norm 1
    CHECK(nlid::fit_percent(y, h) == Approx(100.0 * (1.0 - 1.0 / std::sqrt(5.0))));
  }
  SECTION("worse than the mean is negative") {
    const Eigen::VectorXd h = -y;
    CHECK(nlid::fit_percent(y, h) < 0.0);
  }
  SECTION("float vectors") {
    const Eigen::VectorXf yf = y.cast<float>();
    Eigen::VectorXf hf = yf;
    hf(3) = 5.0f;
    CHECK(nlid::fit_percent(yf, hf) == Approx(100.0 * (1.0 - 1.0 / std::sqrt(5.0))).epsilon(1e-6));
  }
}

TEST_CASE("fit_percent per output column", "[analysis][fit]") {
  Eigen::MatrixXd y(4, 2), h(4, 2);
  y << 1, 10, 2, 20, 3, 30, 4, 40;
  h = y;
  h(3, 0) = 5;     // column 0: error 1 of spread sqrt(5)
  h.col(1) *= 0.0;  // column 1: all zero
  const Eigen::VectorXd f = nlid::fit_percent(y, h);
  REQUIRE(f.size() == 2);
  CHECK(f(0) == Approx(100.0 * (1.0 - 1.0 / std::sqrt(5.0))));
  CHECK(f(1) == Approx(100.0 * (1.0 - y.col(1).norm() / std::sqrt(500.0))));
  // One-column matrix still gives a vector (the result type follows the argument's shape).
  const Eigen::MatrixXd y1 = y.leftCols(1);
  CHECK(nlid::fit_percent(y1, y1).size() == 1);
}

TEST_CASE("fit_percent rejects bad input with a located message", "[analysis][fit]") {
  Eigen::VectorXd y(3), h(2);
  y << 1, 2, 3;
  h << 1, 2;
  CHECK_THROWS_WITH(nlid::fit_percent(y, h), Catch::Contains("3 samples") && Catch::Contains("2"));
  const Eigen::VectorXd c = Eigen::VectorXd::Constant(3, 15.0);
  CHECK_THROWS_WITH(nlid::fit_percent(c, c), Catch::Contains("constant"));
  Eigen::MatrixXd ym(3, 2), hm(3, 2);
  ym << 1, 5, 2, 5, 3, 5;
  hm = ym;
  try {
    (void)nlid::fit_percent(ym, hm);
    FAIL("constant column accepted");
  } catch (const nlid::Error& e) {
    CHECK(std::string(e.what()).find("column 2") != std::string::npos);
    CHECK(e.where().column == 2);
  }
  CHECK_THROWS_WITH(nlid::fit_percent(ym, Eigen::MatrixXd(ym.leftCols(1))), Catch::Contains("3 x 2"));
  Eigen::VectorXd bad = y;
  bad(1) = std::numeric_limits<double>::quiet_NaN();
  CHECK_THROWS_WITH(nlid::fit_percent(bad, y), Catch::Contains("not finite at sample 1"));
  CHECK_THROWS_WITH(nlid::fit_percent(Eigen::VectorXd(), Eigen::VectorXd()), Catch::Contains("empty"));
}

TEST_CASE("fit_percent of a diverged model is -inf, never NaN", "[analysis][fit]") {
  Eigen::VectorXd y(3), h(3);
  y << 1, 2, 3;
  h << 1, std::numeric_limits<double>::infinity(), std::numeric_limits<double>::quiet_NaN();
  const double f = nlid::fit_percent(y, h);
  CHECK(std::isinf(f));
  CHECK(f < 0);
}

TEST_CASE("fit_percent does not depend on the units of the signal", "[analysis][fit]") {
  // A floor of 1 in the "constant output" test made every output with a spread below 1e-12
  // (picoamperes in amperes) undefined: fit_percent threw "measured output is constant".
  Eigen::VectorXd y(4), h(4);
  y << 1, 2, 3, 4;
  h << 1, 2, 3, 5;
  const double ref = nlid::fit_percent(y, h);
  // 1e±200 and 1e300: the squares over- or underflowed ("measured output is constant" below,
  // NaN or -inf above) until the sums ran on y / max|y|.
  for (const double unit : {1e-13, 1e-30, 1e30, 1e-200, 1e200, 1e300, 1e-300}) {
    CAPTURE(unit);
    CHECK(nlid::fit_percent(Eigen::VectorXd(unit * y), Eigen::VectorXd(unit * h)) == Approx(ref).epsilon(1e-12));
  }
  // Still constant: an offset with rounding noise in its last digits, and exact zeros.
  Eigen::VectorXd c = Eigen::VectorXd::Constant(4, 0.1);
  c(2) = std::nextafter(0.1, 1.0);
  CHECK_THROWS_WITH(nlid::fit_percent(c, y), Catch::Contains("is constant"));
  CHECK_THROWS_WITH(nlid::fit_percent(Eigen::VectorXd::Zero(4), y), Catch::Contains("is constant"));
}
