// The study's linear section on the shipped throttle recordings, as a regression test: the
// numbers examples/linear_study.cpp prints (and docs/linear.md quotes) must keep their meaning.
// Bounds are loose enough for other compilers and BLAS-free Eigen versions, tight enough that a
// broken estimator, a wrong offset or a linear model that suddenly "explains" the stops fails.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <string>

#include "nlid/analysis/compare.hpp"
#include "nlid/data.hpp"
#include "nlid/linear.hpp"

namespace {
nlid::Experiment throttle(int k) {
  nlid::Experiment e = nlid::decimate(
      nlid::read_csv(std::string(NLID_TEST_DATA_DIR) + "/throttle/data" + std::to_string(k) + ".csv"),
      10);
  e = nlid::remove_offset(e, 0.0, 15.0);  // the 15 degree rest angle
  e.set_name("data" + std::to_string(k) + "lin");
  return e;
}
}  // namespace

TEST_CASE("throttle linear study: fits on data3lin and failure on data2", "[linear][study]") {
  const nlid::Experiment data3lin = throttle(3), data2lin = throttle(2);
  REQUIRE(data3lin.ts() == Approx(0.01));
  REQUIRE(data3lin.size() == 2001);
  const nlid::Dataset both{data3lin, data2lin};
  const auto ic = nlid::InitialCondition::estimate;

  const nlid::Arx arx210 = nlid::arx(data3lin, {2, 1, 0});
  const nlid::Arx arx211 = nlid::arx(data3lin, {2, 1, 1});
  nlid::OeOptions oo;
  oo.initial_state = ic;
  const nlid::OutputError oe220 = nlid::oe(data3lin, {2, 2, 0}, oo);
  const nlid::StateSpace ss2 = nlid::ssest(data3lin, 2);

  // A damped second-order response: two stable poles, positive static gain.
  for (const auto& p : {arx210.poles(), arx211.poles()}) {
    REQUIRE(p.size() == 2);
    CHECK(p.cwiseAbs().maxCoeff() < 1.0);
    CHECK(p.cwiseAbs().minCoeff() > 0.8);
  }
  CHECK(arx210.dc_gain() > 0.0);
  CHECK(oe220.is_stable());
  CHECK(ss2.is_stable());

  const auto f_arx210 = nlid::compare(arx210, both, ic), f_arx211 = nlid::compare(arx211, both, ic);
  const auto f_oe = nlid::compare(oe220, both, ic), f_ss = nlid::compare(ss2, both, ic);
  // Estimation data: simulation-focus models fit well, ARX (prediction focus) less so.
  CHECK(f_oe.fit_of(0) > 85.0);
  CHECK(f_ss.fit_of(0) > 85.0);
  CHECK(f_arx210.fit_of(0) > 70.0);
  CHECK(f_arx211.fit_of(0) > 70.0);
  CHECK(f_oe.fit_of(0) > f_arx210.fit_of(0) + 5.0);
  // OE and the 2-state model minimise the same criterion over the same model class.
  CHECK(std::abs(f_oe.fit_of(0) - f_ss.fit_of(0)) < 2.0);
  // data2 (pulses against the stops): every linear model fails visibly ...
  for (const auto* r : {&f_arx210, &f_arx211, &f_oe, &f_ss}) {
    CHECK(r->fit_of(1) < 60.0);
    CHECK(r->fit_of(1) < r->fit_of(0) - 25.0);
  }
  // ... because its simulation runs through the stops (below 15 and above 90 degrees).
  const Eigen::VectorXd sim = f_ss.simulated[1].col(0).array() + 15.0;
  CHECK(sim.maxCoeff() > 100.0);
  CHECK(sim.minCoeff() < 0.0);
  CHECK(data2lin.y().maxCoeff() + 15.0 < 92.0);
  CHECK(data2lin.y().minCoeff() + 15.0 > 13.0);
}

TEST_CASE("throttle linear study: two poles suffice in the ARX order search", "[linear][study]") {
  const nlid::Experiment data3lin = throttle(3);
  const nlid::OrderSelection sel = nlid::arx_order_selection(data3lin);
  double loss1 = 1e300, loss2 = 1e300, best = 1e300;
  for (const auto& c : sel.candidates) {
    if (!c.valid) continue;
    if (c.orders.na == 1) loss1 = std::min(loss1, c.loss);
    if (c.orders.na == 2) loss2 = std::min(loss2, c.loss);
    best = std::min(best, c.loss);
  }
  CHECK(loss1 / loss2 > 4.0);  // the second pole removes most of the loss
  CHECK(loss2 / best < 2.0);   // further orders add little
  // [2 1 0] and the study's pick [2 1 1] are within 2 % of each other in loss.
  double l210 = 0, l211 = 0;
  for (const auto& c : sel.candidates) {
    if (c.orders.str() == "[2 1 0]") l210 = c.loss;
    if (c.orders.str() == "[2 1 1]") l211 = c.loss;
  }
  REQUIRE(l210 > 0);
  REQUIRE(l211 > 0);
  CHECK(std::abs(l211 - l210) / l210 < 0.02);
}

TEST_CASE("throttle: OE [2 2 0] on data1lin+data2lin simulates no worse than ARX [2 2 0]", "[linear][oe][study]") {
  // ARX [2 2 0] is a point of the OE [2 2 0] model class, and OE minimises exactly the
  // simulation error. The Steiglitz-McBride iterates on this nonlinear plant drift to a pole at
  // z = 1 (start: sum of squared errors 4.7e6); the refinement then stopped at 8.2e5, fits
  // 55 / 39 %, worse than the ARX model simulated (5.2e5; 61 / 55 %). The start is now the best iterate, the first being ARX.
  const nlid::Dataset d{throttle(1), throttle(2)};
  const nlid::OutputError m = nlid::oe(d, {2, 2, 0});
  const nlid::Arx a = nlid::arx(d, {2, 2, 0});
  const nlid::OutputError as_oe({a.b_polynomial(0)}, {Eigen::VectorXd(a.a_polynomial().tail(2))}, {0}, a.ts());
  double c_oe = 0.0, c_arx = 0.0;
  for (const auto& e : d) {
    c_oe += (m.simulate(e, nlid::InitialCondition::zero) - e.y()).squaredNorm();
    c_arx += (as_oe.simulate(e, nlid::InitialCondition::zero) - e.y()).squaredNorm();
  }
  INFO(m.describe());
  CHECK(m.is_stable());
  CHECK(c_oe <= c_arx);
  CHECK(c_oe < 0.85 * c_arx);  // measured: 4.17e5 against 5.22e5
}
