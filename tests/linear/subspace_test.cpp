// PO-MOESP subspace identification: exact recovery from noise-free data (MIMO, multi-experiment,
// feed-through), consistency on noisy data, order indication, and errors.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <complex>
#include <vector>

#include "linear_test_util.hpp"
#include "nlid/linear/ssest.hpp"
#include "nlid/linear/subspace.hpp"
#include "../support/error_of.hpp"

using nlid::Experiment;
using nlid::InitialCondition;
using nlid::StateSpace;

namespace {
StateSpace three_state(bool feedthrough = false) {
  Eigen::MatrixXd a(3, 3), b(3, 2), c(2, 3), d = Eigen::MatrixXd::Zero(2, 2);
  a << 0.8, 0.2, 0.0, -0.2, 0.8, 0.0, 0.0, 0.0, 0.5;
  b << 1, 0, 0, 1, 1, 1;
  c << 1, 0, 1, 0, 1, 0;
  if (feedthrough) d << 0.5, 0.0, 0.0, -0.25;
  return StateSpace(a, b, c, d, 1.0);
}

// Sorted pole magnitudes and angles, for comparing pole sets independent of order.
std::vector<std::pair<double, double>> pole_set(const Eigen::VectorXcd& p) {
  std::vector<std::pair<double, double>> v;
  for (Eigen::Index k = 0; k < p.size(); ++k) v.emplace_back(std::abs(p(k)), std::abs(std::arg(p(k))));
  std::sort(v.begin(), v.end());
  return v;
}

double max_pole_error(const StateSpace& m, const StateSpace& truth) {
  const auto a = pole_set(m.poles()), b = pole_set(truth.poles());
  double e = 0;
  for (std::size_t k = 0; k < a.size(); ++k)
    e = std::max({e, std::abs(a[k].first - b[k].first), std::abs(a[k].second - b[k].second)});
  return e;
}
}  // namespace

TEST_CASE("MOESP recovers a MIMO system from noise-free data", "[linear][subspace]") {
  const StateSpace truth = three_state();
  const Eigen::MatrixXd u = nlid_test::white_noise(800, 2, 1);
  Eigen::VectorXd x0(3);
  x0 << 1, 2, 3;
  const Experiment e(u, truth.simulate(u, x0), 1.0);
  const StateSpace m = nlid::moesp(e, 3);
  CHECK(max_pole_error(m, truth) < 1e-8);
  const Eigen::VectorXd w = Eigen::VectorXd::LinSpaced(13, 0.01, 3.1);
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 2; ++j)
      CHECK((m.frequency_response(w, i, j) - truth.frequency_response(w, i, j)).cwiseAbs().maxCoeff() < 1e-8);
  CHECK((m.simulate(e, InitialCondition::estimate) - e.y()).cwiseAbs().maxCoeff() < 1e-8);
  CHECK(m.report().fit_percent > 99.9999);
  CHECK(m.report().focus == "simulation");
  // The singular values drop by many decades after the third.
  const Eigen::VectorXd sv = nlid::subspace_singular_values(e, 6);
  CHECK(sv(2) / sv(0) > 1e-3);
  CHECK(sv(3) / sv(0) < 1e-10);
}

TEST_CASE("MOESP on multi-experiment data with feed-through", "[linear][subspace]") {
  const StateSpace truth = three_state(true);
  const Eigen::MatrixXd u1 = nlid_test::random_steps(500, 2, 2, 3), u2 = nlid_test::white_noise(400, 2, 3);
  Eigen::VectorXd x1(3), x2(3);
  x1 << 0, 0, 0;
  x2 << -2, 1, 0.5;
  const nlid::Dataset data{Experiment(u1, truth.simulate(u1, x1), 1.0, "a"),
                           Experiment(u2, truth.simulate(u2, x2), 1.0, "b")};
  nlid::SubspaceOptions opt;
  opt.feedthrough = true;
  const StateSpace m = nlid::moesp(data, 3, opt);
  CHECK(max_pole_error(m, truth) < 1e-8);
  CHECK((m.d() - truth.d()).cwiseAbs().maxCoeff() < 1e-8);
  CHECK((m.dc_gain() - truth.dc_gain()).cwiseAbs().maxCoeff() < 1e-8);
  CHECK(m.report().num_experiments == 2);
}

TEST_CASE("MOESP on noisy SISO data: poles and static gain within tolerance", "[linear][subspace]") {
  // y = B/F u + e with F = 1 - 1.6 q^-1 + 0.68 q^-2; output SNR about 20 dB.
  Eigen::MatrixXd a(2, 2), b(2, 1), c(1, 2);
  a << 1.6, 1.0, -0.68, 0.0;  // observer form of F
  b << 0.5, 0.3;
  c << 1.0, 0.0;
  const StateSpace truth(a, b, c, Eigen::MatrixXd::Zero(1, 1), 0.01);
  const Eigen::MatrixXd u = nlid_test::random_steps(3000, 1, 5, 4);
  const Eigen::MatrixXd y0 = truth.simulate(u, Eigen::VectorXd::Zero(2));
  const double sd = 0.1 * std::sqrt((y0.array() - y0.mean()).square().mean());
  const Experiment e(u, y0 + nlid_test::white_noise(3000, 1, 6, sd), 0.01);
  const StateSpace m = nlid::moesp(e, 2);
  CHECK(max_pole_error(m, truth) < 0.02);
  CHECK(m.dc_gain()(0, 0) == Approx(truth.dc_gain()(0, 0)).epsilon(0.03));
  CHECK(m.report().fit_percent > 85.0);  // 20 dB noise caps the fit near 90 %
}

TEST_CASE("MOESP offset option", "[linear][subspace]") {
  const StateSpace base = three_state();
  StateSpace truth = base;
  truth.set_offset(Eigen::Vector2d(15.0, -3.0));
  const Eigen::MatrixXd u = nlid_test::white_noise(1500, 2, 9);
  const Experiment e(u, truth.simulate(u, Eigen::VectorXd::Zero(3)), 1.0);
  nlid::SubspaceOptions opt;
  opt.offset = true;
  const StateSpace m = nlid::moesp(e, 3, opt);
  CHECK((m.offset() - truth.offset()).cwiseAbs().maxCoeff() < 0.05);
  CHECK(max_pole_error(m, truth) < 0.01);
  CHECK(m.report().fit_percent > 99.0);
}

TEST_CASE("MOESP reports the fit of each output against that output's own mean", "[linear][subspace]") {
  // y1 sits near 100, y2 near 0, and both carry noise as large as their dynamic part. A fit that
  // measured the errors against the mean of both outputs stacked would read about 99 %.
  StateSpace truth = three_state();
  truth.set_offset(Eigen::Vector2d(100.0, 0.0));
  const Eigen::MatrixXd u = nlid_test::white_noise(2000, 2, 21);
  Eigen::MatrixXd y = truth.simulate(u, Eigen::VectorXd::Zero(3));
  nlid_test::add_noise_of_signal_size(y, 22u);
  nlid::SubspaceOptions opt;
  opt.offset = true;
  const StateSpace m = nlid::moesp(Experiment(u, y, 1.0), 3, opt);
  const nlid::LinearEstimationReport& r = m.report();
  nlid_test::check_fits_of_noisy_outputs(r);  // noise of the signal's size: ‖e‖/‖y − ȳ‖ ≈ 1/√2
  CHECK(r.str().find("per output: y1 ") != std::string::npos);
}

TEST_CASE("MOESP rejects bad orders and short data", "[linear][subspace]") {
  const StateSpace truth = three_state();
  const Eigen::MatrixXd u = nlid_test::white_noise(200, 2, 4);
  const Experiment e(u, truth.simulate(u, Eigen::VectorXd::Zero(3)), 1.0, "ok");
  CHECK_THROWS_WITH(nlid::moesp(e, 0), Catch::StartsWith("nlid: moesp: order must be >= 1"));
  const Experiment s(u.topRows(12), truth.simulate(u.topRows(12), Eigen::VectorXd::Zero(3)), 1.0, "tiny");
  try {
    (void)nlid::moesp(nlid::Dataset{e, s}, 3);
    FAIL("short experiment accepted");
  } catch (const nlid::Error& err) {
    CHECK(std::string(err.what()).find("experiment 1 ('tiny') has 12 samples") != std::string::npos);
    // The user never set the horizon the message names: say where it came from and what fits.
    CHECK(std::string(err.what()).find("horizon 10 was chosen automatically for order 3; "
                                       "SubspaceOptions::horizon <= 6 would let this experiment in") !=
          std::string::npos);
    CHECK(err.where().experiment == 1);
  }
  // 2n + 2 must not overflow int before a check sees it.
  CHECK_THROWS_WITH(nlid::moesp(e, 2000000000), Catch::Contains("order 2000000000 is beyond the largest order"));
  nlid::SubspaceOptions opt;
  opt.horizon = 2;
  CHECK_THROWS_WITH(nlid::moesp(e, 5, opt), Catch::Contains("horizon"));
  opt.horizon = 0;
  opt.initial_state = InitialCondition::measured;
  CHECK_THROWS_WITH(nlid::moesp(e, 3, opt), Catch::Contains("initial_state"));
  // A mis-scaled channel is named (its squares overflow in the block Hankel products).
  const Experiment big(1e150 * u, e.y(), 1.0, "big");
  CHECK_THROWS_WITH(nlid::moesp(nlid::Dataset{e, big}, 3), Catch::Contains("experiment 'big', input 'u1'") && Catch::Contains("beyond 1e100"));
  // A constant output (here all zero) is named, not reported as an unstable A at |z| = -nan.
  Experiment flat(u, Eigen::MatrixXd::Zero(200, 2), 1.0, "flat");
  flat.set_output_names({"speed", "angle"});
  const nlid::Error z = nlid_test::error_of([&] { (void)nlid::moesp(flat, 2); });
  CHECK_THAT(z.what(), Catch::Contains("moesp: output 'speed' is 0 in every sample of every experiment"));
  CHECK(z.where().column_name == "speed");
  CHECK_THROWS_WITH(nlid::ssest(flat, 2), Catch::Contains("output 'speed' is 0 in every sample"));
  // One output constant, the other not: that output is named; a constant in one record only is data.
  Experiment half = e;
  half.y().col(1).setConstant(15.0);
  CHECK_THROWS_WITH(nlid::moesp(half, 2), Catch::Contains("output 'y2' is 15 in every sample"));
  Experiment rest = e;
  rest.y().col(1).setConstant(15.0);
  CHECK_NOTHROW(nlid::moesp(nlid::Dataset{e, rest}, 3));
  // With offset, each record's mean is removed: levels held within every record are constant.
  Experiment at3 = e, at5 = e;
  at3.y().setConstant(3.0);
  at5.y().setConstant(5.0);
  nlid::SubspaceOptions with_offset;
  with_offset.offset = true;
  CHECK_THROWS_WITH(nlid::moesp(nlid::Dataset{at3, at5}, 1, with_offset),
                    Catch::Contains("output 'y1' is constant within every experiment (offset removes each experiment's mean)"));
  CHECK_NOTHROW(nlid::moesp(nlid::Dataset{at3, at5}, 1));  // without offset the step between them is data
  // An empty first record is the length check's to report (the constant check read its row 0).
  const Experiment empty(Eigen::MatrixXd(0, 2), Eigen::MatrixXd(0, 2), 1.0, "empty");
  CHECK_THROWS_WITH(nlid::moesp(nlid::Dataset{empty, e}, 3), Catch::Contains("experiment 0 ('empty') has 0 samples"));
}

TEST_CASE("MOESP refuses an unstable A whose response overflows, instead of NaN", "[linear][subspace][errors]") {
  // The B columns of the B, D fit are A's responses to unit inputs; with |λ| = 1.5 they pass
  // 1e150 after about 850 samples and the fit would return NaN for B.
  Eigen::MatrixXd a(1, 1), c(1, 1);
  a << 1.5;
  c << 1.0;
  const Eigen::MatrixXd u = nlid_test::white_noise(1000, 1, 91);
  const Experiment e(u, nlid_test::white_noise(1000, 1, 92), 1.0, "long");
  nlid::SubspaceOptions opt;
  opt.initial_state = InitialCondition::zero;
  CHECK_THROWS_WITH(nlid::detail::fit_b_d(e, a, c, opt, "moesp"),
                    Catch::Contains("moesp: the estimated A is unstable (an eigenvalue at |z| = 1.5)") &&
                        Catch::Contains("1000 samples of experiment 0 ('long')"));
  // A short record stays finite and is fitted.
  const Experiment s(u.topRows(100), e.y().topRows(100), 1.0);
  CHECK(nlid::detail::fit_b_d(s, a, c, opt, "moesp").b.allFinite());
}

TEST_CASE("stabilize_matrix also stabilises a defective A", "[linear][subspace]") {
  // A Jordan block at 1.1 has one eigenvector, so the eigenvector matrix is (numerically)
  // singular; the result must still be stable with the reflected eigenvalues. (This checks the
  // contract; Eigen's nearly singular eigenvectors happen to give the same answer, so it does not
  // reproduce the exactly singular case that used to return A unchanged.)
  Eigen::MatrixXd a(3, 3);
  a << 1.1, 1.0, 0.0, 0.0, 1.1, 0.0, 0.0, 0.0, 0.5;
  const Eigen::MatrixXd s = nlid::detail::stabilize_matrix(a);
  const Eigen::VectorXd mag = Eigen::EigenSolver<Eigen::MatrixXd>(s, false).eigenvalues().cwiseAbs();
  std::vector<double> m(mag.data(), mag.data() + mag.size());
  std::sort(m.begin(), m.end());
  CHECK(m[0] == Approx(0.5).epsilon(1e-6));
  CHECK(m[1] == Approx(1.0 / 1.1).epsilon(1e-6));
  CHECK(m[2] == Approx(1.0 / 1.1).epsilon(1e-6));
  // A complex unstable pair in a defective-free matrix: reflected to 1/conj(λ), the stable one kept.
  Eigen::MatrixXd b(3, 3);
  b << 1.0, -0.6, 0.0, 0.6, 1.0, 0.0, 0.0, 0.0, -0.3;  // 1 +/- 0.6i (|λ| = 1.166), -0.3
  const Eigen::VectorXcd ev = Eigen::EigenSolver<Eigen::MatrixXd>(nlid::detail::stabilize_matrix(b), false).eigenvalues();
  const double r = std::abs(std::complex<double>(1.0, 0.6));
  int reflected = 0;
  for (Eigen::Index k = 0; k < ev.size(); ++k)
    if (std::abs(std::abs(ev(k)) - 1.0 / r) < 1e-9) ++reflected;
  CHECK(reflected == 2);
}
