// Sample-time changes: ZOH c2d/d2c known answers, exact conversion of linear dynamics checked by
// simulation at common instants, delay rescaling and the nk = 0 warning.
#include <catch2/catch.hpp>

#include <cmath>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "nlid/models/sample_time.hpp"

using namespace nlid;

namespace {

// Piecewise-constant input on the coarse grid (ts), sampled on the fine grid (ts / r): a ZOH
// conversion must then give the same output at every coarse instant.
Experiment steps(double ts, int n, int r = 1) {
  Eigen::MatrixXd u(n * r, 1);
  for (int k = 0; k < n; ++k) u.block(k * r, 0, r, 1).setConstant(std::sin(0.37 * k) + (k / 25 % 2 ? 0.8 : -0.3));
  return Experiment(u, Eigen::MatrixXd::Zero(n * r, 1), ts / r, "steps");
}

bool has_warning(const SampleTimeReport& r, const std::string& text) {
  for (const auto& w : r.warnings)
    if (w.find(text) != std::string::npos) return true;
  return false;
}

}  // namespace

TEST_CASE("c2d / d2c: first-order known answer and round trip") {
  // ẋ = −2x + 3u, y = x: Φ = e^{−2h}, Γ = 1.5 (1 − e^{−2h}).
  const ContinuousStateSpace c{Eigen::MatrixXd::Constant(1, 1, -2.0), Eigen::MatrixXd::Constant(1, 1, 3.0),
                               Eigen::MatrixXd::Ones(1, 1), Eigen::MatrixXd::Zero(1, 1)};
  const StateSpace d = c2d(c, 0.1);
  CHECK(d.a()(0, 0) == Approx(std::exp(-0.2)).epsilon(1e-14));
  CHECK(d.b()(0, 0) == Approx(1.5 * (1 - std::exp(-0.2))).epsilon(1e-13));
  CHECK(d.ts() == 0.1);
  const ContinuousStateSpace back = d2c(d);
  CHECK(back.a(0, 0) == Approx(-2.0).epsilon(1e-12));
  CHECK(back.b(0, 0) == Approx(3.0).epsilon(1e-12));

  // Second order with complex poles: d2c(c2d(sys)) = sys.
  Eigen::MatrixXd A(2, 2), B(2, 1), C(1, 2), D(1, 1);
  A << 0, 1, -30, -6;
  B << 0, 2500;
  C << 1, 0;
  D << 0;
  const ContinuousStateSpace c2{A, B, C, D};
  const ContinuousStateSpace r2 = d2c(c2d(c2, 0.01));
  CHECK((r2.a - A).norm() <= 1e-9 * A.norm());
  CHECK((r2.b - B).norm() <= 1e-9 * B.norm());

  // A pole on the negative real axis has no continuous equivalent.
  const StateSpace neg(Eigen::MatrixXd::Constant(1, 1, -0.5), Eigen::MatrixXd::Ones(1, 1), Eigen::MatrixXd::Ones(1, 1),
                       Eigen::MatrixXd::Zero(1, 1), 0.1);
  CHECK_THROWS_WITH(d2c(neg), Catch::Contains("negative real axis") && Catch::Contains("z = -0.5"));
  CHECK_THROWS_WITH(c2d(c, 0.0), Catch::Contains("new sample time must be positive"));
}

TEST_CASE("with_sample_time: output-error model, exact at the common instants, delays scale") {
  // Throttle-like linear part at 10 ms: B/F [2 2 2].
  const OutputError oe({Eigen::Vector2d(0.12, 0.09)}, {Eigen::Vector2d(-1.6, 0.68)}, {2}, 0.01, 15.0);
  SampleTimeReport rep;
  const OutputError fast = with_sample_time(oe, 0.005, &rep);
  CHECK(fast.ts() == 0.005);
  CHECK(fast.nk(0) == 3);  // one sample of the sampled plant + 10 ms of dead time = 2 samples
  CHECK(rep.exact);
  CHECK(rep.old_ts == 0.01);
  CHECK(rep.warnings.empty());
  CHECK(fast.dc_gain(0) == Approx(oe.dc_gain(0)).epsilon(1e-10));
  const Experiment coarse = steps(0.01, 200), fine = steps(0.01, 200, 2);
  const Eigen::MatrixXd y1 = oe.simulate(coarse, InitialCondition::zero);
  const Eigen::MatrixXd y2 = fast.simulate(fine, InitialCondition::zero);
  double worst = 0;
  for (int k = 0; k < 200; ++k) worst = std::max(worst, std::abs(y1(k, 0) - y2(2 * k, 0)));
  CHECK(worst <= 1e-9 * (1 + y1.cwiseAbs().maxCoeff()));
  // Back to 10 ms gives the original polynomials.
  const OutputError back = with_sample_time(fast, 0.01);
  CHECK((back.f(0) - oe.f(0)).cwiseAbs().maxCoeff() <= 1e-9);
  CHECK(back.b(0).head(2).isApprox(oe.b(0), 1e-8));
  CHECK(back.nk(0) == 2);

  // A delay that is not a whole number of new samples is rounded, with a warning.
  SampleTimeReport r3;
  const OutputError slow = with_sample_time(oe, 0.03, &r3);
  CHECK(slow.nk(0) == 1);
  CHECK(!r3.exact);
  CHECK(has_warning(r3, "is not a whole number of samples"));
}

TEST_CASE("with_sample_time: nk = 1 is the sampled plant's own sample, not dead time (known answer)") {
  // K a/(s + a) without dead time, sampled with a ZOH at h: q^-1 K(1 - e^{-ah}) / (1 - e^{-ah} q^-1),
  // i.e. nb = nf = 1, nk = 1 (Astrom & Wittenmark sec. 2.3). At any other rate it is the same
  // formula with that h and nk = 1 again; its step response is K(1 - e^{-a t}) at every sample.
  const double K = 2.0, a = 3.0;
  const auto sampled = [&](double h) {
    return OutputError({Eigen::VectorXd::Constant(1, K * (1 - std::exp(-a * h)))},
                       {Eigen::VectorXd::Constant(1, -std::exp(-a * h))}, {1}, h, 0.0);
  };
  for (const double h : {0.05, 0.2, 0.0125}) {
    INFO("new sample time " << h);
    SampleTimeReport rep;
    const OutputError conv = with_sample_time(sampled(0.1), h, &rep);
    CHECK(rep.exact);
    CHECK(conv.nk(0) == 1);
    REQUIRE(conv.b(0).size() == 1);
    CHECK(conv.b(0)(0) == Approx(K * (1 - std::exp(-a * h))).epsilon(1e-9));
    CHECK(conv.f(0)(0) == Approx(-std::exp(-a * h)).epsilon(1e-9));
    const Experiment step(Eigen::MatrixXd::Ones(12, 1), Eigen::VectorXd::Zero(12), h);
    const Eigen::MatrixXd y = conv.simulate(step, InitialCondition::zero);
    for (int k = 0; k < 12; ++k) CHECK(y(k, 0) == Approx(K * (1 - std::exp(-a * h * k))).margin(1e-9));
    // Faster than the old rate, the smallest delay keeps the study's caution.
    CHECK(has_warning(rep, "estimate the delay again") == (h < 0.1));
    CHECK(has_warning(rep, "input delay nk = 1: beyond the one sample that sampling itself takes, the input acts "
                           "within one sample of 0.1 s"));
  }
  // The same through the linear block of a Hammerstein-Wiener model and through ARX.
  DynamicHammersteinWiener hw(AnyNonlinearity(UnitGain{}), TransferFunctionBlock<Dynamic, Dynamic, Dynamic>(1, 1, 1),
                              AnyNonlinearity(UnitGain{}), 0.1);
  hw.set_parameters(Eigen::Vector2d(K * (1 - std::exp(-a * 0.1)), -std::exp(-a * 0.1)));
  const auto hw2 = with_sample_time(hw, 0.05);
  CHECK(hw2.linear_block().nk() == 1);
  CHECK(hw2.linear_block().nb() == 1);
  const Experiment step(Eigen::MatrixXd::Ones(8, 1), Eigen::VectorXd::Zero(8), 0.05);
  const Eigen::MatrixXd yh = hw2.simulate(step, InitialCondition::zero);
  for (int k = 0; k < 8; ++k) CHECK(yh(k, 0) == Approx(K * (1 - std::exp(-a * 0.05 * k))).margin(1e-9));
  const Arx arx(Eigen::VectorXd::Constant(1, -std::exp(-a * 0.1)), {Eigen::VectorXd::Constant(1, K * (1 - std::exp(-a * 0.1)))},
                {3}, 0.1);  // and 0.2 s of dead time
  const Arx arx2 = with_sample_time(arx, 0.05);
  CHECK(arx2.nk(0) == 5);  // 1 + 0.2 s / 0.05 s
  const Eigen::MatrixXd ya = arx2.simulate(step, InitialCondition::zero);
  for (int k = 0; k < 8; ++k) CHECK(ya(k, 0) == Approx(k < 4 ? 0.0 : K * (1 - std::exp(-a * 0.05 * (k - 4)))).margin(1e-9));
}

TEST_CASE("with_sample_time: nb > nf with a delay (a fractional dead time) converts inexactly, with a warning") {
  // q^-1 (b1 + b2 q^-1)/(1 + f1 q^-1): the ZOH model of a first-order plant behind part of a
  // sample of dead time; no rational model converts that exactly.
  const OutputError oe({Eigen::Vector2d(0.3, 0.2)}, {Eigen::VectorXd::Constant(1, -0.6)}, {1}, 0.1);
  SampleTimeReport rep;
  const OutputError half = with_sample_time(oe, 0.05, &rep);
  CHECK_FALSE(rep.exact);
  CHECK(has_warning(rep, "a fraction of a sample of dead time"));
  CHECK(half.nk(0) == 2);  // the old reading: feed-through behind 0.1 s
  // Still exact for inputs held over the old samples.
  const Experiment coarse = steps(0.1, 80), fine = steps(0.1, 80, 2);
  const Eigen::MatrixXd y1 = oe.simulate(coarse, InitialCondition::zero), y2 = half.simulate(fine, InitialCondition::zero);
  for (int k = 0; k < 80; ++k) CHECK(y2(2 * k, 0) == Approx(y1(k, 0)).margin(1e-9));
}

TEST_CASE("with_sample_time: nk = 0 keeps the feed-through and warns, as the study cautions") {
  const OutputError oe({Eigen::Vector2d(0.1, 0.05)}, {Eigen::Vector2d(-1.2, 0.4)}, {0}, 0.01);
  SampleTimeReport rep;
  const OutputError fast = with_sample_time(oe, 0.001, &rep);
  CHECK(fast.nk(0) == 0);
  REQUIRE(rep.warnings.size() == 1);
  CHECK_THAT(rep.warnings[0], Catch::Contains("nk = 0") && Catch::Contains("estimate the delay again"));
}

TEST_CASE("with_sample_time: ARX deterministic part, state space, Hammerstein-Wiener, nonlinear ARX") {
  const Experiment coarse = steps(0.01, 150), fine = steps(0.01, 150, 4);
  auto agree = [&](const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
    double worst = 0;
    for (Eigen::Index k = 0; k < a.rows(); ++k) worst = std::max(worst, std::abs(a(k, 0) - b(4 * k, 0)));
    return worst <= 1e-8 * (1 + a.cwiseAbs().maxCoeff());
  };
  const Arx arx(Eigen::Vector2d(-1.5, 0.7), {Eigen::Vector2d(0.3, 0.1)}, {1}, 0.01);
  SampleTimeReport ra;
  const Arx arx4 = with_sample_time(arx, 0.0025, &ra);
  CHECK(arx4.nk(0) == 1);
  CHECK(has_warning(ra, "noise model"));
  CHECK(agree(arx.simulate(coarse, InitialCondition::zero), arx4.simulate(fine, InitialCondition::zero)));
  // The offset c is an equilibrium term (A(1) y0 = c): kept as the same static offset, so runs
  // that start in equilibrium agree (a start from y = 0 would add a transient no ARX can share).
  const Arx arxc(Eigen::Vector2d(-1.5, 0.7), {Eigen::Vector2d(0.3, 0.1)}, {1}, 0.01, 2.0);
  const Arx arxc4 = with_sample_time(arxc, 0.0025);
  CHECK(arxc4.offset() / arxc4.a_polynomial().sum() == Approx(2.0 / 0.2).epsilon(1e-9));
  CHECK(agree(arxc.simulate(coarse, InitialCondition::equilibrium), arxc4.simulate(fine, InitialCondition::equilibrium)));

  Eigen::MatrixXd A(2, 2), B(2, 1), C(1, 2), D(1, 1);
  A << 0.9, 0.2, -0.1, 0.7;
  B << 0.3, 1.0;
  C << 1.0, 0.5;
  D << 0.1;
  StateSpace ss(A, B, C, D, 0.01);
  ss.set_input_names({"command"});
  ss.set_output_names({"angle"});
  const StateSpace ss4 = with_sample_time(ss, 0.0025);
  CHECK(ss4.input_names() == ss.input_names());
  CHECK(ss4.output_names() == ss.output_names());
  CHECK(agree(ss.simulate(coarse, InitialCondition::zero), ss4.simulate(fine, InitialCondition::zero)));

  DynamicHammersteinWiener hw(AnyNonlinearity(Poly1d<Dynamic>(2)), TransferFunctionBlock<Dynamic, Dynamic, Dynamic>(2, 2, 1),
                              AnyNonlinearity(Saturation(-1.0, 1.0)), 0.01);
  Eigen::VectorXd th(hw.num_parameters());
  th << 0.0, 1.0, 0.3, 0.2, 0.1, -1.3, 0.45, -0.8, 0.8;
  hw.set_parameters(th);
  SampleTimeReport rh;
  const auto hw4 = with_sample_time(hw, 0.0025, &rh);
  CHECK(hw4.linear_block().nk() == 1);
  CHECK(rh.exact);
  CHECK(agree(hw.simulate(coarse, InitialCondition::zero), hw4.simulate(fine, InitialCondition::zero)));

  DynamicNlarx nl(RegressorList::lagged(2, 2, 1).add_custom("y1(t-1)^2"), AnyNonlinearity(LinearMap<Dynamic>(5)), 0.01);
  SampleTimeReport rn;
  const DynamicNlarx nl2 = with_sample_time(nl, 0.005, &rn);
  CHECK(!rn.exact);
  CHECK(has_warning(rn, "re-estimate"));
  CHECK(has_warning(rn, "custom regressors keep their lags"));
  CHECK(nl2.regressor_names() ==
        std::vector<std::string>{"y1(t-1)", "y1(t-2)", "u1(t-1)", "u1(t-2)", "y1(t-1)^2"});  // nk = 1: no dead time
  CHECK(nl2.ts() == 0.005);

  // Through AnyModel.
  SampleTimeReport rany;
  const AnyModel any = with_sample_time(AnyModel(arx), 0.005, &rany);
  CHECK(any.ts() == 0.005);
  CHECK(any.kind() == "arx");
  // The parameters' uncertainty belongs to the old rate: not carried over (the Nlarx keeps θ and
  // its names, so nothing else would catch it).
  AnyModel held(nl);
  held.info().uncertainty = uncertainty_from_covariance(nl.parameter_names(), nl.parameters(),
                                                        Eigen::MatrixXd::Identity(nl.num_parameters(), nl.num_parameters()));
  held.info().description = "kept";
  const AnyModel moved = with_sample_time(held, 0.005);
  CHECK_FALSE(moved.info().uncertainty.has_value());
  CHECK(moved.info().description == "kept");
}
