// ssest: sensitivity Jacobian vs central differences, refinement never worse than the subspace
// start, noise-free exactness, known-answer poles/frequency response on noisy data.
#include <catch2/catch.hpp>

#include <cmath>

#include "linear_test_util.hpp"
#include "nlid/linear/ssest.hpp"

using nlid::Experiment;
using nlid::InitialCondition;
using nlid::StateSpace;

namespace {
StateSpace siso2() {
  Eigen::MatrixXd a(2, 2), b(2, 1), c(1, 2);
  a << 1.6, 1.0, -0.68, 0.0;  // poles 0.8 +/- 0.2i
  b << 0.5, 0.3;
  c << 1.0, 0.0;
  return StateSpace(a, b, c, Eigen::MatrixXd::Zero(1, 1), 0.01);
}
}  // namespace

TEST_CASE("ssest sensitivity Jacobian matches central differences", "[linear][ssest]") {
  Eigen::MatrixXd u1 = nlid_test::white_noise(40, 2, 1), u2 = nlid_test::white_noise(30, 2, 2);
  const nlid::Dataset data{Experiment(u1, nlid_test::white_noise(40, 2, 3), 1.0, "a"),
                           Experiment(u2, nlid_test::white_noise(30, 2, 4), 1.0, "b")};
  const nlid::detail::StateSpacePemProblem p(data, 2, true, true, true);
  CHECK(p.num_parameters() == 4 + 4 + 4 + 4 + 2 + 2 * 2);
  Eigen::VectorXd th(p.num_parameters());
  for (Eigen::Index k = 0; k < th.size(); ++k) th(k) = 0.1 * std::sin(1.0 + 3.0 * static_cast<double>(k));
  th.head(4) << 0.5, -0.2, 0.3, 0.6;  // A, column-major, stable
  Eigen::VectorXd r(p.num_residuals()), rp(p.num_residuals()), rm(p.num_residuals());
  Eigen::MatrixXd J(p.num_residuals(), p.num_parameters());
  REQUIRE(p.evaluate(th, r, &J));
  for (Eigen::Index k = 0; k < th.size(); ++k) {
    const double h = 1e-6;
    Eigen::VectorXd tp = th, tm = th;
    tp(k) += h;
    tm(k) -= h;
    REQUIRE(p.evaluate(tp, rp, nullptr));
    REQUIRE(p.evaluate(tm, rm, nullptr));
    const Eigen::VectorXd fd = (rp - rm) / (2 * h);
    CHECK((J.col(k) - fd).cwiseAbs().maxCoeff() < 1e-6 * std::max(1.0, fd.cwiseAbs().maxCoeff()));
  }
  Eigen::VectorXd bad = th;
  bad.head(4) << 1.2, 0.0, 0.0, 0.5;  // eigenvalue 1.2
  CHECK_FALSE(p.evaluate(bad, r, nullptr));
  // pack / unpack round trip.
  const StateSpace s = p.unpack(th);
  std::vector<Eigen::VectorXd> x0{th.segment(18, 2), th.segment(20, 2)};
  CHECK((p.pack(s, x0) - th).norm() == 0.0);
}

TEST_CASE("ssest keeps an exact subspace estimate exact", "[linear][ssest]") {
  const StateSpace truth = siso2();
  const Eigen::MatrixXd u = nlid_test::random_steps(600, 1, 5, 4);
  Eigen::VectorXd x0(2);
  x0 << 1.0, -0.5;
  const Experiment e(u, truth.simulate(u, x0), 0.01);
  const StateSpace m = nlid::ssest(e, 2);
  const Eigen::VectorXd w = Eigen::VectorXd::LinSpaced(9, 1.0, 300.0);
  CHECK((m.frequency_response(w) - truth.frequency_response(w)).cwiseAbs().maxCoeff() < 1e-8);
  CHECK(m.report().fit_percent > 99.9999);
  CHECK(m.report().num_parameters == 2 * 2 + 2);  // n(m + p) + x0
}

TEST_CASE("ssest on noisy data: refinement improves the simulation fit", "[linear][ssest]") {
  // Coloured output noise (a slow drift) biases the subspace step; the refinement minimises the
  // simulation error directly and must not be worse than its start.
  const StateSpace truth = siso2();
  const Eigen::MatrixXd u = nlid_test::random_steps(3000, 1, 7, 4);
  const Eigen::MatrixXd y0 = truth.simulate(u, Eigen::VectorXd::Zero(2));
  const double sd = 0.1 * std::sqrt((y0.array() - y0.mean()).square().mean());
  const Eigen::VectorXd v = nlid::filter(Eigen::VectorXd::Ones(1), (Eigen::VectorXd(2) << 1.0, -0.9).finished(),
                                         nlid_test::white_noise(3000, 1, 8, sd * std::sqrt(1 - 0.81)).col(0));
  const Experiment e(u, y0 + v, 0.01);
  nlid::SsestOptions opt;
  opt.refine = false;
  const StateSpace start = nlid::ssest(e, 2, opt);
  const StateSpace m = nlid::ssest(e, 2);
  CHECK(m.report().loss <= start.report().loss * (1 + 1e-12));
  CHECK(m.is_stable());
  CHECK(m.report().solver_message.find("Levenberg-Marquardt") != std::string::npos);
  const Eigen::VectorXd w = Eigen::VectorXd::LinSpaced(30, 0.5, 0.5 * M_PI / 0.01);
  const Eigen::VectorXcd g = truth.frequency_response(w), gh = m.frequency_response(w);
  CHECK(((gh - g).cwiseAbs().array() / g.cwiseAbs().array()).maxCoeff() < 0.05);
  CHECK(m.dc_gain()(0, 0) == Approx(truth.dc_gain()(0, 0)).epsilon(0.03));
}
