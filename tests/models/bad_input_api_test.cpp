// Bad input to the models' public API, as found by a review that probed it: each case must end
// in an nlid::Error saying what and where — not uninitialised output, a std::out_of_range, or a
// missing sample reported as the model's divergence.
#include <catch2/catch.hpp>

#include <cmath>
#include <limits>
#include <vector>

#include "nlid/models/equilibrium.hpp"
#include "nlid/models/greybox.hpp"
#include "nlid/models/hammerstein_wiener.hpp"
#include "nlid/models/nlarx.hpp"
#include "nlid/models/physics/throttle.hpp"
#include "nlid/models/series.hpp"
#include "nlid/nonlinearities/linear.hpp"
#include "nlid/nonlinearities/polynomial.hpp"
#include "nlid/nonlinearities/saturation.hpp"
#include "nlid/nonlinearities/unit_gain.hpp"
#include "nlid/regressors.hpp"

namespace {
using Lin = nlid::Nlarx<nlid::LaggedRegressors<2, 1, 0>, nlid::LinearMap<3>>;

nlid::Experiment record(int n, double nan_u_at = -1, double nan_y_at = -1) {
  Eigen::MatrixXd u(n, 1), y(n, 1);
  for (int k = 0; k < n; ++k) {
    u(k, 0) = std::sin(0.3 * k);
    y(k, 0) = 1.0 + 0.5 * std::cos(0.2 * k);
  }
  if (nan_u_at >= 0) u(static_cast<Eigen::Index>(nan_u_at), 0) = std::nan("");
  if (nan_y_at >= 0) y(static_cast<Eigen::Index>(nan_y_at), 0) = std::nan("");
  return nlid::Experiment(u, y, 0.1, "rec", nlid::NonFinitePolicy::keep);
}
}  // namespace

TEST_CASE("Nlarx prediction and simulation name a missing sample or an overflow, never return unwritten rows",
          "[models][errors]") {
  Lin m;
  m.set_parameters(Eigen::VectorXd::Constant(4, 0.3));
  // A missing output sample: one-step prediction reads it (it returned NaN then unwritten zeros).
  CHECK_THROWS_WITH(m.predict(record(50, -1, 20), 1),
                    Catch::Contains("missing (non-finite) output sample at sample index 20"));
  // A missing input sample: named as such, not as the model diverging.
  CHECK_THROWS_WITH(m.simulate(record(50, 10)), Catch::Contains("missing (non-finite) input sample at sample index 10") &&
                                                   !Catch::Contains("diverges"));
  // Finite data, a model whose prediction overflows: the sample is named.
  Lin big;
  big.set_parameters(Eigen::VectorXd::Constant(4, 1e300));
  nlid::Experiment e = record(50);
  e.y() *= 1e10;
  try {
    (void)big.predict(e, 1);
    FAIL("no error");
  } catch (const nlid::DivergenceError& d) {
    CHECK(d.sample() == 2);
    CHECK_THAT(d.what(), Catch::Contains("one-step prediction of experiment 'rec' is not finite at sample 2"));
  }
  // The complete record still predicts, and every row is written.
  const Eigen::MatrixXd ok = m.predict(record(50), 1);
  CHECK(ok.allFinite());
}

TEST_CASE("Nlarx starts that read outputs name a missing output sample, a missing y(0) only drops the equilibrium guess",
          "[models][errors]") {
  Lin m;
  m.set_parameters((Eigen::VectorXd(4) << 0.5, -0.1, 0.4, 0.2).finished());
  // measured reads y(0), y(1): a gap there was a "divergence" at sample 2.
  CHECK_THROWS_WITH(m.simulate(record(50, -1, 1), nlid::InitialCondition::measured),
                    Catch::Contains("missing (non-finite) output at sample 1") && Catch::Contains("measured start") && !Catch::Contains("diverges"));
  // estimate fits x0 to every output: a gap anywhere is named, not a solver failure at 'theta'.
  CHECK_THROWS_WITH(m.simulate(record(50, -1, 30), nlid::InitialCondition::estimate),
                    Catch::Contains("missing (non-finite) output sample at sample index 30"));
  // equilibrium only takes y(0) as Newton's first guess: without it the default guess serves.
  const Eigen::MatrixXd with = m.simulate(record(50), nlid::InitialCondition::equilibrium);
  const Eigen::MatrixXd without = m.simulate(record(50, -1, 0), nlid::InitialCondition::equilibrium);
  CHECK(without.allFinite());
  CHECK((with - without).cwiseAbs().maxCoeff() < 1e-9);  // a linear map has one steady state
  // Hammerstein-Wiener and series models estimating their start need the outputs too.
  nlid::HammersteinWiener<nlid::UnitGain, nlid::TransferFunctionBlock<2, 2, 1>, nlid::Saturation> hw;
  CHECK_THROWS_WITH(hw.initial_state(record(40, -1, 12), nlid::InitialCondition::estimate),
                    Catch::Contains("missing (non-finite) output sample at sample index 12"));
}

TEST_CASE("Nlarx: a start that cannot be formed or a k-step prediction that blows up is a DivergenceError",
          "[models][errors]") {
  // y(t) = 1.5 y(t-1) + ...: no stable steady state, and any start away from it explodes.
  Lin m;
  m.set_parameters((Eigen::VectorXd(4) << 1.5, 0.0, 1.0, 0.0).finished());
  nlid::Experiment e = record(2000);  // 1.5^t overflows a double after about 1750 samples
  e.u().setConstant(1.0);
  for (const auto ic : {nlid::InitialCondition::estimate, nlid::InitialCondition::zero}) {
    try {
      (void)m.simulate(e, ic);
      FAIL("no error");
    } catch (const nlid::DivergenceError& d) {
      CHECK(d.sample() >= 0);
    }
  }
  Lin big;
  big.set_parameters(Eigen::VectorXd::Constant(4, 1e300));
  nlid::Experiment f = record(50);
  f.y() *= 1e10;
  try {
    (void)big.predict(f, 3);
    FAIL("no error");
  } catch (const nlid::DivergenceError& d) {
    CHECK_THAT(d.what(), Catch::Contains("k-step prediction of experiment 'rec' diverges at sample"));
    CHECK(d.sample() >= 2);
  }
}

TEST_CASE("Hammerstein-Wiener and series simulations name a missing input sample", "[models][errors]") {
  nlid::HammersteinWiener<nlid::UnitGain, nlid::TransferFunctionBlock<2, 2, 1>, nlid::Saturation> hw;
  CHECK_THROWS_WITH(hw.simulate(record(40, 7)), Catch::Contains("missing (non-finite) input sample at sample index 7"));
  nlid::Wiener<nlid::TransferFunctionBlock<2, 2, 1>, nlid::Poly1d<2>> w;
  CHECK_THROWS_WITH(w.simulate(record(40, 5)), Catch::Contains("missing (non-finite) input sample at sample index 5"));
}

TEST_CASE("Series block setters refuse a bad index and non-finite values with nlid::Error", "[models][errors]") {
  using S = nlid::Hammerstein<nlid::Poly1d<2>, nlid::TransferFunctionBlock<2, 1, 0>>;
  S s;
  const std::vector<double> v(3, 0.1);
  CHECK_THROWS_AS(s.set_block_parameters(7, v), nlid::Error);
  CHECK_THROWS_WITH(s.set_block_parameters(7, v), Catch::Contains("block 7 is out of range: the chain has 2 block(s)"));
  CHECK_THROWS_AS(s.block_parameters(2), nlid::Error);
  CHECK_THROWS_AS(s.block_num_parameters(2), nlid::Error);
  CHECK(s.parameter_offset(2) == s.num_parameters());  // k = K is the end of θ
  CHECK_THROWS_AS(s.parameter_offset(3), nlid::Error);
  const std::vector<double> bad = {0.1, std::nan(""), 0.2};
  CHECK_THROWS_WITH(s.set_block_parameters(0, bad), Catch::Contains("parameter 1 is not finite"));
  Eigen::VectorXd b(2), f(2);
  b << std::nan(""), 1.0;
  f << 1.0, -0.5;
  CHECK_THROWS_WITH(s.set_block_polynomials<1>(b, f), Catch::Contains("B has a non-finite coefficient"));
  nlid::HammersteinWiener<nlid::UnitGain, nlid::TransferFunctionBlock<2, 1, 0>, nlid::UnitGain> hw;
  CHECK_THROWS_WITH(hw.set_linear_polynomials(b, f), Catch::Contains("B has a non-finite coefficient"));
}

TEST_CASE("Grey-box equilibrium and simulation name a non-finite input or initial state", "[models][errors]") {
  nlid::GreyBox<nlid::physics::Throttle> g;
  CHECK_THROWS_WITH(nlid::equilibrium(g, Eigen::VectorXd::Constant(1, std::nan(""))),
                    Catch::Contains("held input must be finite"));
  CHECK_THROWS_WITH(g.simulate(Eigen::MatrixXd::Zero(5, 1), 0.01, Eigen::Vector2d(std::nan(""), 0.0)),
                    Catch::Contains("initial state of grey-box model") && Catch::Contains("is not finite"));
}
