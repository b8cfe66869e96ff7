// Stepper: models run one sample at a time give the batch simulation's numbers bit for bit, keep
// their state across chunks and copies, and refuse bad samples without losing their state.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <numbers>
#include <span>
#include <vector>

#include "nlid/models/greybox.hpp"
#include "nlid/models/hammerstein_wiener.hpp"
#include "nlid/models/nlarx.hpp"
#include "nlid/models/physics/catalogue.hpp"
#include "nlid/models/series.hpp"
#include "nlid/models/stepper.hpp"
#include "nlid/models/transfer_function_block.hpp"
#include "nlid/nonlinearities/linear.hpp"
#include "nlid/nonlinearities/piecewise_linear.hpp"
#include "nlid/nonlinearities/polynomial.hpp"
#include "nlid/nonlinearities/saturation.hpp"
#include "nlid/nonlinearities/unit_gain.hpp"
#include "nlid/nonlinearities/sigmoid_network.hpp"
#include "nlid/regressors.hpp"
#include "nlid/regressors/expression.hpp"
#include "../support/block_models.hpp"
#include "../support/unrated_pendulum.hpp"

namespace {

Eigen::MatrixXd stepper_input(int n, int channels = 1) {
  Eigen::MatrixXd u(n, channels);
  for (int t = 0; t < n; ++t)
    for (int c = 0; c < channels; ++c) u(t, c) = 0.5 + 0.4 * std::sin(0.05 * t + c) + ((t / (30 + 7 * c)) % 2 ? 0.3 : 0.0);
  return u;
}

using Net = nlid::SigmoidNet<6, 5>;
using Nlarx5 = nlid::Nlarx<nlid::LaggedRegressors<3, 3, 0>, Net>;

Nlarx5 stepper_nlarx5() {
  Net net;
  net.set_normalization(Eigen::VectorXd::Constant(6, 0.5), Eigen::VectorXd::Constant(6, 1.0));
  Nlarx5 m(nlid::LaggedRegressors<3, 3, 0>{}, net);
  Eigen::VectorXd th(Nlarx5::num_params);
  for (int i = 0; i < th.size(); ++i) th(i) = 0.05 * std::sin(1.7 * i + 0.3);
  th.head(3) << 0.6, 0.1, 0.05;  // a stable linear part
  m.set_parameters(th);
  return m;
}

// The batch core's free run from x0 (empty: zero).
template <class M>
Eigen::VectorXd batch(const M& m, const Eigen::MatrixXd& u, const Eigen::VectorXd& x0 = {}) {
  Eigen::VectorXd y(u.rows());
  REQUIRE(m.template simulate<double>(u, std::span<const double>(m.parameters().data(), static_cast<std::size_t>(m.parameters().size())),
                                      std::span<const double>(x0.data(), static_cast<std::size_t>(x0.size())),
                                      std::span<double>(y.data(), static_cast<std::size_t>(y.size()))));
  return y;
}

template <class S>
Eigen::VectorXd stepped(S& run, const Eigen::MatrixXd& u) {
  Eigen::VectorXd y(u.rows());
  for (Eigen::Index t = 0; t < u.rows(); ++t) {
    const Eigen::RowVectorXd ut = u.row(t);
    y(t) = run.step(std::span<const double>(ut.data(), static_cast<std::size_t>(ut.size())));
  }
  return y;
}

}  // namespace

TEST_CASE("Stepper: nonlinear ARX steps equal the batch simulation bit for bit", "[models][stepper]") {
  const Nlarx5 m = stepper_nlarx5();
  const Eigen::MatrixXd u = stepper_input(400);
  nlid::Stepper run(m);
  STATIC_REQUIRE(std::is_same_v<decltype(run), nlid::Stepper<Nlarx5>>);
  CHECK(stepped(run, u) == batch(m, u));
  CHECK(run.samples() == 400);

  // From a measured lag window, in two chunks: the state after the first chunk continues it.
  const Eigen::VectorXd y_ref = batch(m, u);
  const Eigen::VectorXd x0 = m.measured_state(u, y_ref, 50);
  const Eigen::MatrixXd tail = u.bottomRows(350);
  const Eigen::VectorXd whole = batch(m, tail, x0);
  run.reset(x0);
  const Eigen::VectorXd first = stepped(run, tail.topRows(120));
  CHECK(first == whole.head(120));
  const Eigen::VectorXd x120 = run.state();
  CHECK(batch(m, tail.bottomRows(230), x120) == whole.tail(230));
  // A copy is a branch: both continue alike and independently.
  nlid::Stepper branch = run;
  CHECK(stepped(branch, tail.bottomRows(230)) == whole.tail(230));
  CHECK(run.state() == x120);
  CHECK(stepped(run, tail.bottomRows(230)) == whole.tail(230));
  // The stepper keeps its own copy of the model.
  Nlarx5 changed = m;
  nlid::Stepper run2(changed);
  changed.set_parameters(Eigen::VectorXd::Zero(Nlarx5::num_params));
  CHECK(stepped(run2, u) == batch(m, u));
}

TEST_CASE("Stepper: multi-input nonlinear ARX with a long dead time and a custom regressor", "[models][stepper]") {
  nlid::RegressorList list;
  list.add_output_lags(2).add_input_lags(2, 20, 0).add_input_lags(1, 3, 1).add_custom("y1(t-1)*u2(t-3)");
  nlid::Nlarx<nlid::RegressorList, nlid::LinearMap<nlid::Dynamic>> m(list, nlid::LinearMap<nlid::Dynamic>(6));
  Eigen::VectorXd th(m.num_parameters());
  th << 0.5, 0.2, 0.3, -0.1, 0.4, 0.05, 0.01;
  m.set_parameters(th);
  const Eigen::MatrixXd u = stepper_input(300, 2);
  Eigen::VectorXd x0(m.state_dimension());
  for (int i = 0; i < x0.size(); ++i) x0(i) = 0.01 * i - 0.1;
  nlid::Stepper run(m);
  run.reset(x0);
  CHECK(stepped(run, u) == batch(m, u, x0));
  CHECK(batch(m, u.topRows(100), x0) == batch(m, u, x0).head(100));
  run.reset(x0);
  (void)stepped(run, u.topRows(100));
  CHECK(batch(m, u.bottomRows(200), run.state()) == batch(m, u, x0).tail(200));
}

TEST_CASE("Stepper: Hammerstein-Wiener steps equal the batch simulation, copies stand alone", "[models][stepper]") {
  using Hw = nlid::HammersteinWiener<nlid::PwLinear<4>, nlid::TransferFunctionBlock<3, 3, 20>, nlid::PwLinear<4>>;
  Hw m;
  const Eigen::VectorXd th = nlid_test::pwlinear_hw_theta();
  m.set_parameters(th);
  const Eigen::MatrixXd u = stepper_input(300);
  const Eigen::VectorXd x0 = m.equilibrium_state<double>(u(0, 0), std::span<const double>(th.data(), Hw::num_params));
  const Eigen::VectorXd whole = batch(m, u, x0);
  auto run = std::make_unique<nlid::Stepper<Hw>>(m);
  run->reset(x0);
  for (int t = 0; t < 100; ++t) REQUIRE(run->step(u(t, 0)) == whole(t));
  // The copy's breakpoint tables view its own parameters: it outlives the original.
  nlid::Stepper<Hw> copy = *run;
  run.reset();
  CHECK(stepped(copy, u.bottomRows(200)) == whole.tail(200));
  CHECK(batch(m, u.bottomRows(200), nlid::Stepper<Hw>(copy).state()) != whole.tail(200));  // moved on
  nlid::Stepper<Hw> again(m);
  again.reset(x0);
  (void)stepped(again, u.topRows(100));
  CHECK(batch(m, u.bottomRows(200), again.state()) == whole.tail(200));
}

TEST_CASE("Stepper: a Wiener-Hammerstein chain steps as its batch simulation", "[models][stepper]") {
  using Wh = nlid::WienerHammerstein<nlid::TransferFunctionBlock<2, 2, 1>, nlid::Poly1d<3>,
                                     nlid::TransferFunctionBlock<2, 1, 0>>;
  Wh m;
  const Eigen::VectorXd th = nlid_test::wiener_hammerstein_theta();
  m.set_parameters(th);
  const Eigen::MatrixXd u = stepper_input(300) * 0.5;
  const Eigen::VectorXd x0 = m.equilibrium_state<double>(u(0, 0), std::span<const double>(th.data(), 11));
  const Eigen::VectorXd whole = batch(m, u, x0);
  nlid::Stepper run(m);
  STATIC_REQUIRE(std::is_same_v<decltype(run), nlid::Stepper<Wh>>);
  run.reset(x0);
  CHECK(stepped(run, u.topRows(120)) == whole.head(120));
  CHECK(batch(m, u.bottomRows(180), run.state()) == whole.tail(180));
  CHECK(stepped(run, u.bottomRows(180)) == whole.tail(180));
  CHECK_THROWS_WITH(run.reset(Eigen::VectorXd::Zero(2)), Catch::Contains("the chain's linear blocks have 3 states"));
}

TEST_CASE("Stepper: a bad sample is refused and the state kept", "[models][stepper][errors]") {
  const Nlarx5 m = stepper_nlarx5();
  const Eigen::MatrixXd u = stepper_input(100);
  nlid::Stepper run(m);
  (void)stepped(run, u.topRows(40));
  const Eigen::VectorXd x40 = run.state();
  CHECK_THROWS_WITH(run.step(std::numeric_limits<double>::quiet_NaN()),
                    Catch::Contains("input 0 is nan at sample 40") && Catch::Contains("state is kept"));
  CHECK(run.state() == x40);
  CHECK(run.samples() == 40);
  CHECK(stepped(run, u.bottomRows(60)) == batch(m, u).tail(60));
  const double two[] = {0.1, 0.2};
  CHECK_THROWS_WITH(run.step(std::span<const double>(two, 2)), Catch::Contains("2 input value(s) given, the model reads 1"));
  CHECK_THROWS_WITH(run.reset(Eigen::VectorXd::Zero(3)),
                    Catch::Contains("initial state has 3 values, the model's lag window has 5"));
  Eigen::VectorXd bad = Eigen::VectorXd::Zero(5);  // y(t-1..t-3), u(t-1..t-2)
  bad(2) = std::numeric_limits<double>::infinity();
  CHECK_THROWS_WITH(run.reset(bad), Catch::Contains("initial state is not finite"));

  // An output that leaves the finite numbers: DivergenceError naming the sample.
  Nlarx5 wild = m;
  Eigen::VectorXd th = m.parameters();
  th.head(3) << 1e200, 1e200, 1e200;
  wild.set_parameters(th);
  nlid::Stepper w(wild);
  w.reset(Eigen::VectorXd::Constant(5, 1.0));
  long at = -1;
  try {
    for (int t = 0; t < 10; ++t) (void)w.step(1.0);
  } catch (const nlid::DivergenceError& e) {
    at = e.sample();
    CHECK_THAT(e.what(), Catch::Contains("not finite at sample"));
  }
  CHECK(at >= 0);
  CHECK(w.samples() == at);
}

TEST_CASE("Stepper: grey box equals simulate with a fixed sub-step count, RK4 and adaptive", "[models][stepper][greybox]") {
  nlid::GreyBox<nlid::physics::Throttle> m;
  Eigen::VectorXd p(7);
  p << 30.0, 400.0, 1e5, 400.0 * 140.0, 15.0, 90.0, 0.0;
  m.set_parameters(p);
  const double ts = 0.01;
  Eigen::MatrixXd u(400, 1);
  for (int t = 0; t < 400; ++t) u(t, 0) = (t / 50) % 2 ? 0.9 : -0.2;  // into both stops
  const Eigen::Vector2d x0(15.0, 0.0);
  for (const auto method : {nlid::IntegratorMethod::rk4, nlid::IntegratorMethod::dormand_prince}) {
    nlid::IntegratorOptions o = m.integrator();
    o.method = method;
    m.set_integrator(o);
    const Eigen::MatrixXd whole = m.simulate(u, ts, x0);
    nlid::Stepper run(m, ts, x0);
    STATIC_REQUIRE(std::is_same_v<decltype(run), nlid::Stepper<nlid::GreyBox<nlid::physics::Throttle>>>);
    if (method == nlid::IntegratorMethod::rk4) CHECK(run.substeps() == m.substeps(ts));
    Eigen::VectorXd y(400);
    for (int t = 0; t < 400; ++t) y(t) = run.step(u(t, 0))[0];
    CHECK(y == whole.col(0));
    // Resumed by a batch run from the stepper's state after 150 samples: the same tail.
    run.reset(x0);
    for (int t = 0; t < 150; ++t) (void)run.step(u(t, 0));
    const Eigen::MatrixXd rest = m.simulate(u.bottomRows(250), ts, run.state());
    if (method == nlid::IntegratorMethod::rk4) {
      CHECK(rest.col(0) == whole.col(0).tail(250));
    } else {
      // The adaptive run restarts its step-size search there: within its tolerance.
      CHECK((rest.col(0) - whole.col(0).tail(250)).cwiseAbs().maxCoeff() < 1e-4);
    }
  }
  CHECK_THROWS_WITH(nlid::Stepper(m, 0.0, x0), Catch::Contains("sample time must be positive"));
  CHECK_THROWS_WITH(nlid::Stepper(m, ts, Eigen::Vector3d::Zero()), Catch::Contains("initial state has 3 entries"));
}

TEST_CASE("Stepper: grey box without a spectral radius raises its sub-steps as it goes", "[models][stepper][greybox]") {
  // Released horizontal the pendulum is soft (|df/dx| ~ 1): one RK4 step per 0.2 s sample; at
  // the bottom of its swing it needs more. A batch run takes the whole record's count from the
  // first sample; a sample-by-sample run cannot know it, so it follows the states it reaches.
  nlid::GreyBox<nlid_test::UnratedPendulum> m;
  const double ts = 0.2;
  const Eigen::MatrixXd u = Eigen::MatrixXd::Zero(100, 1);
  const Eigen::Vector2d x0(std::numbers::pi / 2, 0.0);
  nlid::Stepper run(m, ts, x0);
  Eigen::VectorXd y(100);
  for (int t = 0; t < 100; ++t) y(t) = run.step(u(t, 0))[0];
  CHECK(run.substeps() == m.substeps(u, ts, x0));  // the batch count, reached during the run
  const Eigen::MatrixXd whole = m.simulate(u, ts, x0);
  CHECK((y - whole.col(0)).cwiseAbs().maxCoeff() < 0.05);  // integrator error, not a different model
  // With a fixed count both agree exactly.
  nlid::IntegratorOptions o = m.integrator();
  o.substeps = 4;
  m.set_integrator(o);
  nlid::Stepper fixed(m, ts, x0);
  for (int t = 0; t < 100; ++t) y(t) = fixed.step(u(t, 0))[0];
  CHECK(y == m.simulate(u, ts, x0).col(0));
}

TEST_CASE("Stepper: an unstable block behind a saturating output map is caught by its state", "[models][stepper][errors]") {
  // x(t) = 1.5 x(t-1) + u(t-1) runs off to inf while y = saturation(x) stays at its limit: the
  // stepper must stop at the state, as the contract says, not deliver y = 1 from an inf state.
  using Hw = nlid::HammersteinWiener<nlid::UnitGain, nlid::TransferFunctionBlock<1, 1, 1>, nlid::Saturation>;
  Hw m;
  Eigen::VectorXd th(m.num_parameters());
  th << 1.0, -1.5, -1.0, 1.0;  // b1, f1, then the saturation's lower and upper limits
  m.set_parameters(th);
  nlid::Stepper run(m);
  long at = -1;
  double largest = 0.0;
  try {
    for (int t = 0; t < 5000; ++t) largest = std::max(largest, std::abs(run.step(1.0)));
  } catch (const nlid::DivergenceError& e) {
    at = e.sample();
    CHECK_THAT(e.what(), Catch::Contains("linear block's state") && Catch::Contains("not finite at sample"));
  }
  REQUIRE(at > 1000);  // 1.5^t overflows near t = 1750
  CHECK(largest == 1.0);  // the output never showed it
  CHECK(run.samples() == at);
  CHECK(run.state().allFinite());
  run.reset(run.state());  // resumable from the last finite state
}

TEST_CASE("Stepper: grey-box parameters simulate refuses are refused", "[models][stepper][greybox][errors]") {
  nlid::GreyBox<nlid::physics::Throttle> m;
  m.set_parameter("upper_stop", 20.0);
  m.set_parameter("lower_stop", 30.0);  // crossed, one at a time
  CHECK_THROWS_WITH(m.simulate(Eigen::MatrixXd::Zero(5, 1), 0.01, Eigen::Vector2d(25.0, 0.0)),
                    Catch::Contains("must be below upper_stop"));
  CHECK_THROWS_WITH(nlid::Stepper(m, 0.01, Eigen::Vector2d(25.0, 0.0)),
                    Catch::Contains("Stepper") && Catch::Contains("must be below upper_stop"));
}

TEST_CASE("Stepper: a diverging grey box delivers its last valid output, then refuses", "[models][stepper][greybox][errors]") {
  nlid::GreyBox<nlid::physics::Throttle> m;
  Eigen::VectorXd p(7);
  p << 30.0, 400.0, 1e7, 400.0 * 140.0, 15.0, 90.0, 0.0;
  m.set_parameters(p);
  nlid::IntegratorOptions o;
  o.substeps = 1;  // h·sqrt(K) = 32: far outside RK4's stability region in contact
  m.set_integrator(o);
  const double ts = 0.01;
  nlid::Stepper run(m, ts, Eigen::Vector2d(15.0, 0.0));
  long at = -1;
  try {
    for (int t = 0; t < 100; ++t) {
      const double y = run.step(0.9)[0];
      REQUIRE(std::isfinite(y));
    }
  } catch (const nlid::DivergenceError& e) {
    at = e.sample();
    CHECK_THAT(e.what(), Catch::Contains("diverged at sample") && Catch::Contains("reset it from a finite state"));
  }
  REQUIRE(at > 0);
  // The batch simulation reports the same sample.
  try {
    (void)m.simulate(Eigen::MatrixXd::Constant(100, 1, 0.9), ts, Eigen::Vector2d(15.0, 0.0));
    FAIL("no throw");
  } catch (const nlid::DivergenceError& e) {
    CHECK(e.sample() == at);
  }
  // samples() counts the outputs delivered; state() is the last finite state, x(at - 1).
  CHECK(run.samples() == at);
  CHECK(run.state().allFinite());
  CHECK_THROWS_WITH(run.step(std::numeric_limits<double>::infinity()),
                    Catch::Contains("diverged at sample") && Catch::Contains("1 sub-step(s) per sample"));
  run.reset(Eigen::Vector2d(15.0, 0.0));
  CHECK_THROWS_WITH(run.step(std::numeric_limits<double>::infinity()), Catch::Contains("input 0 is inf at sample 0"));
}
