// Simulation bands: σ of the simulated output equals √(J Σ Jᵀ) with J taken by finite differences
// (grey box, Nlarx, Hammerstein–Wiener), the band of estimated models matches the spread of
// their simulations over Monte Carlo records, the reachable share and the shift read a known
// parameter change back, and bad input is named.
#include <catch2/catch.hpp>

#include <cmath>
#include <limits>
#include <random>

#include "../greybox/test_data.hpp"
#include "../support/scratch_dir.hpp"
#include "nlid/io/model_file.hpp"
#include "nlid/models/any_model_band.hpp"
#include "nlid/models/greybox_estimate.hpp"
#include "nlid/models/physics/first_order.hpp"
#include "nlid/models/simulation_band.hpp"
#include "nlid/nonlinearities/linear.hpp"
#include "nlid/nonlinearities/saturation.hpp"
#include "nlid/nonlinearities/unit_gain.hpp"
#include "nlid/regressors.hpp"
#include "test_inputs.hpp"

using Catch::Matchers::Contains;

namespace {

using Lag = nlid::GreyBox<nlid::physics::FirstOrder>;
using Arx = nlid::Nlarx<nlid::LaggedRegressors<2, 1, 0>, nlid::LinearMap<3>>;
using Wiener = nlid::HammersteinWiener<nlid::UnitGain, nlid::TransferFunctionBlock<2, 2, 1>, nlid::Saturation>;

// A hand-made uncertainty at θ: covariance A Aᵀ (scaled to θ), all parameters free.
nlid::ParameterUncertainty made_uncertainty(const Eigen::VectorXd& theta, std::vector<std::string> names,
                                            double rel, unsigned seed) {
  const Eigen::Index n = theta.size();
  std::mt19937 gen(seed);
  std::normal_distribution<double> nd(0.0, 1.0);
  Eigen::MatrixXd A(n, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    for (Eigen::Index j = 0; j < n; ++j) A(i, j) = nd(gen) * rel * std::max(0.1, std::abs(theta[i]));
  }
  nlid::ParameterUncertainty u;
  u.names = std::move(names);
  u.theta = theta;
  u.covariance = A * A.transpose() / static_cast<double>(n);
  u.stddev = u.covariance.diagonal().cwiseSqrt();
  u.free.assign(static_cast<std::size_t>(n), true);
  u.at_bound.assign(static_cast<std::size_t>(n), false);
  return u;
}

// Central-difference Jacobian of `sim(θ)` (an N-vector) at θ.
template <class Sim>
Eigen::MatrixXd fd_jacobian(Sim&& sim, const Eigen::VectorXd& theta) {
  const Eigen::VectorXd y0 = sim(theta);
  Eigen::MatrixXd J(y0.size(), theta.size());
  for (Eigen::Index i = 0; i < theta.size(); ++i) {
    const double h = 1e-6 * std::max(1.0, std::abs(theta[i]));
    Eigen::VectorXd tp = theta, tm = theta;
    tp[i] += h;
    tm[i] -= h;
    J.col(i) = (sim(tp) - sim(tm)) / (2.0 * h);
  }
  return J;
}

void check_band_against(const nlid::SimulationBand& b, const Eigen::MatrixXd& J, const Eigen::MatrixXd& cov) {
  const Eigen::VectorXd var = (J * cov).cwiseProduct(J).rowwise().sum();
  REQUIRE(b.stddev[0].rows() == var.size());
  double worst = 0.0;
  for (Eigen::Index k = 0; k < var.size(); ++k) {
    worst = std::max(worst, std::abs(b.stddev[0](k, 0) - std::sqrt(var[k])) / (1e-3 + std::sqrt(var[k])));
  }
  INFO("largest relative difference " << worst);
  CHECK(worst < 1e-5);
  CHECK(var.maxCoeff() > 0.0);
}

std::vector<std::string> lag_names() { return {"tau", "gain", "offset"}; }

}  // namespace

TEST_CASE("Grey-box band: sigma = sqrt(J Sigma J') with J by finite differences, x0 held", "[models][band]") {
  Lag model;
  model.set_parameters(Eigen::Vector3d(12.0, 35.0, 21.0));
  const Eigen::MatrixXd u = nlid_test::steps({0.0, 1.0, 0.4, 0.8}, 25, 200);
  const nlid::Dataset data(nlid_test::simulated(model, u, 1.0, Eigen::VectorXd::Constant(1, 25.0), 0.3, 3u, "oven"));
  const nlid::ParameterUncertainty unc = made_uncertainty(model.parameters(), lag_names(), 0.02, 1u);
  const nlid::SimulationBand b = nlid::simulation_band(model, data, unc);
  // Default initial condition: estimated on the record with the parameters held.
  const Eigen::VectorXd x0 = model.initial_state(data[0], nlid::InitialCondition::estimate);
  CHECK((b.y[0] - model.simulate(data[0], x0)).cwiseAbs().maxCoeff() < 1e-12);
  const Eigen::MatrixXd J = fd_jacobian(
      [&](const Eigen::VectorXd& th) {
        Lag m = model;
        m.set_parameters(th);
        return Eigen::VectorXd(m.simulate(data[0], x0).col(0));
      },
      model.parameters());
  check_band_against(b, J, unc.covariance);
  CHECK(b.rms_stddev(0, 0) > 0.0);
  CHECK(b.max_stddev(0, 0) >= b.rms_stddev(0, 0));
  CHECK(b.experiment_names == std::vector<std::string>{"oven"});

  // A record shorter than the unknowns of an estimation (3 samples; 3 parameters and a state):
  // the band estimates nothing, so it still has one.
  const nlid::Experiment short_run(u.topRows(3), data[0].y().topRows(3), 1.0, "short");
  const nlid::SimulationBand bs = nlid::simulation_band(model, nlid::Dataset(short_run), unc);
  REQUIRE(bs.stddev[0].rows() == 3);
  CHECK(bs.stddev[0].allFinite());
  CHECK(bs.stddev[0](2, 0) > 0.0);

  // A zero start instead: the band follows the other trajectory.
  nlid::SimulationBandOptions o;
  o.initial_condition = nlid::InitialCondition::zero;
  const nlid::SimulationBand bz = nlid::simulation_band(model, data, unc, o);
  CHECK((bz.y[0] - model.simulate(data[0], Eigen::VectorXd::Zero(1))).cwiseAbs().maxCoeff() < 1e-12);
}

TEST_CASE("Nlarx and Hammerstein-Wiener bands: sqrt(J Sigma J') of the free run", "[models][band]") {
  SECTION("Nlarx, measured initial past: the first n0 samples are the record's, sigma 0") {
    Arx model;
    model.set_parameters(Eigen::Vector4d(1.3, -0.45, 0.2, 0.7));
    const Eigen::MatrixXd u = nlid_test::random_steps(300, -3.0, 3.0, 4u);
    Eigen::VectorXd y = Eigen::VectorXd::Zero(300);
    for (int t = 2; t < 300; ++t) y[t] = 1.3 * y[t - 1] - 0.45 * y[t - 2] + 0.2 * u(t, 0) + 0.7;
    const nlid::Dataset data(nlid::Experiment(u, y, 1.0, "arx"));
    const nlid::ParameterUncertainty unc = made_uncertainty(model.parameters(), model.parameter_names(), 0.01, 2u);
    const nlid::SimulationBand b = nlid::simulation_band(model, data, unc);
    CHECK((b.y[0] - model.simulate(data[0], nlid::InitialCondition::measured)).cwiseAbs().maxCoeff() < 1e-12);
    CHECK(b.stddev[0](0, 0) == 0.0);
    CHECK(b.stddev[0](1, 0) == 0.0);
    const Eigen::MatrixXd J = fd_jacobian(
        [&](const Eigen::VectorXd& th) {
          Arx m = model;
          m.set_parameters(th);
          return Eigen::VectorXd(m.simulate(data[0], nlid::InitialCondition::measured).col(0));
        },
        model.parameters());
    check_band_against(b, J, unc.covariance);
    // The record is the model's own output: nothing to explain.
    CHECK(b.rms_error(0, 0) < 1e-9);
  }
  SECTION("Wiener with a saturation, zero initial state") {
    Wiener model;
    Eigen::VectorXd th(6);
    th << 0.1, 0.06, -1.5, 0.7, -0.8, 1.0;
    model.set_parameters(th);
    const Eigen::MatrixXd u = nlid_test::random_steps(400, -2.0, 2.0, 5u);
    const nlid::Dataset data(nlid::Experiment(u, Eigen::VectorXd::Zero(400), 0.01, "w"));
    const nlid::ParameterUncertainty unc = made_uncertainty(th, model.parameter_names(), 0.01, 3u);
    const nlid::SimulationBand b = nlid::simulation_band(model, data, unc);
    CHECK((b.y[0] - model.simulate(data[0], nlid::InitialCondition::zero)).cwiseAbs().maxCoeff() < 1e-12);
    const Eigen::MatrixXd J = fd_jacobian(
        [&](const Eigen::VectorXd& t) {
          Wiener m = model;
          m.set_parameters(t);
          return Eigen::VectorXd(m.simulate(data[0], nlid::InitialCondition::zero).col(0));
        },
        th);
    check_band_against(b, J, unc.covariance);
  }
}

TEST_CASE("Band of estimated grey boxes matches the spread of their simulations over Monte Carlo records",
          "[models][band]") {
  Lag truth;
  truth.set_parameters(Eigen::Vector3d(12.0, 35.0, 21.0));
  const Eigen::MatrixXd u = nlid_test::steps({0.0, 1.0, 0.4, 0.8}, 25, 200);
  // Validation input the estimation never saw, from a zero start.
  const Eigen::MatrixXd uv = nlid_test::steps({0.2, 0.9, 0.1, 0.6, 1.2}, 17, 160);
  const nlid::Dataset val(nlid::Experiment(uv, Eigen::VectorXd::Zero(160), 1.0, "val"));
  nlid::SimulationBandOptions o;
  o.initial_condition = nlid::InitialCondition::zero;
  const int replicates = 60;
  Eigen::MatrixXd sims(replicates, 160), bands(replicates, 160);
  nlid::GreyBoxEstimateOptions eo;
  eo.multi_start.num_candidates = 1;
  eo.multi_start.num_starts = 1;
  for (int k = 0; k < replicates; ++k) {
    const nlid::Dataset d(nlid_test::simulated(truth, u, 1.0, Eigen::VectorXd::Constant(1, 21.0), 0.5,
                                               300u + static_cast<unsigned>(k), "oven"));
    Lag m = truth;
    const nlid::GreyBoxEstimate r = nlid::estimate(m, d, eo);
    const nlid::SimulationBand b = nlid::simulation_band(m, val, r.uncertainty, o);
    sims.row(k) = b.y[0].col(0).transpose();
    bands.row(k) = b.stddev[0].col(0).transpose();
  }
  const Eigen::RowVectorXd mean = sims.colwise().mean();
  const Eigen::RowVectorXd spread =
      ((sims.rowwise() - mean).array().square().colwise().sum() / (replicates - 1)).sqrt();
  const Eigen::RowVectorXd predicted = bands.colwise().mean();
  // Over the record (after the first sample, where both are 0): 60 replicates know the spread to
  // about ±9 %, the correlated-residual formula adds its own scatter.
  const double ratio = predicted.tail(159).norm() / spread.tail(159).norm();
  INFO("predicted / empirical rms sigma: " << ratio);
  CHECK(ratio == Approx(1.0).margin(0.2));
  // And sample by sample, where the band moves with the input.
  for (Eigen::Index k : {20, 60, 100, 150}) {
    INFO("sample " << k << ": predicted " << predicted[k] << ", empirical " << spread[k]);
    CHECK(predicted[k] / spread[k] == Approx(1.0).margin(0.3));
  }
}

TEST_CASE("A grey box's stored covariance gives the band of its estimate's uncertainty", "[models][band]") {
  Lag m;
  m.set_parameters(Eigen::Vector3d(12.0, 35.0, 21.0));
  const Eigen::MatrixXd u = nlid_test::steps({0.0, 1.0, 0.4, 0.8}, 25, 200);
  const nlid::Dataset d(nlid_test::simulated(m, u, 1.0, Eigen::VectorXd::Constant(1, 21.0), 0.5, 11u, "oven"));
  nlid::GreyBoxEstimateOptions eo;
  eo.multi_start.num_candidates = 1;
  eo.multi_start.num_starts = 1;
  const nlid::GreyBoxEstimate r = nlid::estimate(m, d, eo);
  REQUIRE(m.parameter_covariance().rows() == 3);
  const nlid::Dataset val(nlid::Experiment(nlid_test::steps({0.2, 0.9}, 30, 120), Eigen::VectorXd::Zero(120), 1.0, "v"));
  nlid::SimulationBandOptions o;
  o.initial_condition = nlid::InitialCondition::zero;
  const nlid::SimulationBand from_estimate = nlid::simulation_band(m, val, r.uncertainty, o);
  const nlid::SimulationBand from_model = nlid::simulation_band(m, val, o);
  CHECK((from_model.stddev[0] - from_estimate.stddev[0]).cwiseAbs().maxCoeff() <=
        1e-12 * from_estimate.stddev[0].maxCoeff());
  CHECK(from_model.stddev[0].maxCoeff() > 0.0);
  // A parameter fixed since the estimation keeps its variance in the band but is not moved to
  // explain an error.
  Lag held = m;
  held.fix("offset");
  const nlid::SimulationBand fixed_band = nlid::simulation_band(held, val, o);
  CHECK(fixed_band.free_parameters == 2);
  CHECK(fixed_band.stddev[0] == from_model.stddev[0]);
  // Stale after a change of value: refused, not silently wrong.
  m.set_parameter("tau", 13.0);
  CHECK_THROWS_WITH(nlid::simulation_band(m, val, o), Contains("carries no parameter covariance"));
}

TEST_CASE("Reachable share and shift read a known parameter change back", "[models][band]") {
  Lag model;
  model.set_parameters(Eigen::Vector3d(12.0, 35.0, 21.0));
  const Eigen::MatrixXd u = nlid_test::steps({0.0, 1.0, 0.4, 0.8}, 25, 200);
  const Eigen::VectorXd x0 = Eigen::VectorXd::Constant(1, 21.0);
  const nlid::ParameterUncertainty unc = made_uncertainty(model.parameters(), lag_names(), 0.01, 7u);
  nlid::SimulationBandOptions o;
  o.initial_condition = nlid::InitialCondition::equilibrium;  // the same x0 for every record below

  // The record is the model with θ + δ: a parameter change removes it all, and its size is
  // √(δᵀΣ⁻¹δ).
  auto record_at = [&](const Eigen::Vector3d& delta) {
    Lag shifted = model;
    shifted.set_parameters(model.parameters() + delta);
    return nlid::Experiment(u, shifted.simulate(u, 1.0, x0), 1.0, "shifted");
  };
  const Eigen::MatrixXd L = unc.covariance.llt().matrixL();
  const Eigen::Vector3d small = 0.5 * L * Eigen::Vector3d(1.0, -0.5, 0.8);
  const double expected = std::sqrt(small.dot(unc.covariance.ldlt().solve(small)));
  const nlid::SimulationBand near = nlid::simulation_band(model, nlid::Dataset(record_at(small)), unc, o);
  INFO(near.report());
  CHECK(near.reachable_share(0, 0) > 0.99);
  // The smallest change removing 90 % is not larger than the true one.
  CHECK(near.shift_sigmas(0, 0) <= expected * 1.01);
  CHECK(near.shift_sigmas(0, 0) > 0.2 * expected);
  CHECK(near.plausible_share(0, 0) > 0.99);
  CHECK_THAT(near.verdict(0, 0), Contains("consistent with the parameters' uncertainty"));

  const Eigen::Vector3d big = 40.0 * small;
  const nlid::SimulationBand far = nlid::simulation_band(model, nlid::Dataset(record_at(big)), unc, o);
  INFO(far.report());
  CHECK(far.reachable_share(0, 0) > 0.9);
  CHECK(far.shift_sigmas(0, 0) > far.plausible_radius());
  CHECK(far.shift_sigmas(0, 0) <= 40.0 * expected * 1.05);
  CHECK(far.plausible_share(0, 0) < 0.9 * far.reachable_share(0, 0));
  CHECK_THAT(far.verdict(0, 0), Contains("as if they differed") && Contains("pulled most: "));
  // The change within the radius solves the trust-region problem min ‖e − J δ‖, √(δᵀΣ⁻¹δ) ≤ r:
  // it lies on the boundary, the removed share is its own, and (KKT) in whitened coordinates
  // z = L⁻¹δ the gradient Lᵀ Jᵀ (e − J δ) is parallel to z.
  const Eigen::Vector3d dz = far.parameter_change[0].col(0);
  CHECK(std::sqrt(dz.dot(unc.covariance.ldlt().solve(dz))) == Approx(far.plausible_radius()).epsilon(1e-6));
  const Eigen::Vector3d z = L.triangularView<Eigen::Lower>().solve(dz);
  const Eigen::MatrixXd Jfd = fd_jacobian(
      [&](const Eigen::VectorXd& th) {
        Lag m = model;
        m.set_parameters(th);
        return Eigen::VectorXd(m.simulate(u, 1.0, x0).col(0));
      },
      model.parameters());
  const Eigen::VectorXd e = (record_at(big).y() - model.simulate(u, 1.0, x0)).col(0);
  const Eigen::VectorXd left = e - Jfd * dz;
  CHECK(1.0 - left.squaredNorm() / e.squaredNorm() == Approx(far.plausible_share(0, 0)).epsilon(1e-4));
  const Eigen::Vector3d g = L.transpose() * (Jfd.transpose() * left);
  CHECK(g.normalized().dot(z.normalized()) > 0.9999);
  CHECK(dz.dot(big) > 0.0);

  // An alternating error no first-order lag can produce: out of reach.
  Eigen::MatrixXd y = model.simulate(u, 1.0, x0);
  for (Eigen::Index k = 0; k < y.rows(); ++k) y(k, 0) += (k % 2 == 0 ? 0.3 : -0.3);
  const nlid::SimulationBand out = nlid::simulation_band(model, nlid::Dataset(nlid::Experiment(u, y, 1.0, "odd")), unc, o);
  INFO(out.report());
  CHECK(out.reachable_share(0, 0) < 0.05);
  CHECK_THAT(out.verdict(0, 0), Contains("outside what they can reach"));
  CHECK_THAT(out.report(), Contains("odd") && Contains("reachable"));
}

TEST_CASE("Reach in closed form: identity covariance, orthonormal sensitivities", "[models][band]") {
  // A = Q (orthonormal columns), Σ = I: z = δ, the trust-region path runs straight along c = Qᵀe,
  // a change of size r removes 2r‖c‖ − r², and 90 % of ‖c‖² needs r = (1 − √0.1)‖c‖.
  std::mt19937 gen(5);
  std::normal_distribution<double> nd(0.0, 1.0);
  Eigen::MatrixXd X(50, 4);
  for (Eigen::Index i = 0; i < X.size(); ++i) X.data()[i] = nd(gen);
  const Eigen::HouseholderQR<Eigen::MatrixXd> qr(X);
  const Eigen::MatrixXd Q = qr.householderQ() * Eigen::MatrixXd::Identity(50, 4);
  const Eigen::MatrixXd A = Q.leftCols(3);
  const Eigen::Vector3d z(3.0, -4.0, 12.0);  // ‖z‖ = 13
  const Eigen::VectorXd err = A * z + 5.0 * Q.col(3);
  const double total = err.squaredNorm();  // 169 + 25
  const nlid::detail::ErrorReach r = nlid::detail::error_reach(A, err, Eigen::Matrix3d::Identity(), 4.0);
  CHECK(r.reachable == Approx(169.0 / total).epsilon(1e-10));
  CHECK(r.shift == Approx((1.0 - std::sqrt(0.1)) * 13.0).epsilon(1e-8));
  CHECK(r.plausible == Approx((2.0 * 4.0 * 13.0 - 16.0) / total).epsilon(1e-8));
  CHECK((r.delta - z * (4.0 / 13.0)).norm() < 1e-8);
  // A radius beyond the need: the whole reachable part, the change itself.
  const nlid::detail::ErrorReach all = nlid::detail::error_reach(A, err, Eigen::Matrix3d::Identity(), 20.0);
  CHECK(all.plausible == Approx(169.0 / total).epsilon(1e-10));
  CHECK((all.delta - z).norm() < 1e-8);
  // A zero-variance direction is not moved (as the band does not move it).
  Eigen::Matrix3d pinned = Eigen::Matrix3d::Identity();
  pinned(2, 2) = 0.0;
  const nlid::detail::ErrorReach two = nlid::detail::error_reach(A, err, pinned, 20.0);
  CHECK(two.reachable == Approx(25.0 / total).epsilon(1e-10));
  CHECK(two.delta[2] == 0.0);
}

TEST_CASE("Band: unidentifiable directions, missing outputs and bad input", "[models][band]") {
  Lag model;
  model.set_parameters(Eigen::Vector3d(12.0, 35.0, 21.0));
  const Eigen::MatrixXd u = nlid_test::steps({0.0, 1.0, 0.4, 0.8}, 25, 120);
  Eigen::MatrixXd y = model.simulate(u, 1.0, Eigen::VectorXd::Constant(1, 21.0));
  const nlid::Dataset data(nlid::Experiment(u, y, 1.0, "rec"));
  nlid::SimulationBandOptions o;
  o.initial_condition = nlid::InitialCondition::zero;

  SECTION("the output change of a 1 % move along an unidentifiable direction") {
    nlid::ParameterUncertainty unc = made_uncertainty(model.parameters(), lag_names(), 0.01, 4u);
    unc.unidentifiable.push_back(Eigen::Vector3d(0.12, -0.35, 0.0));
    const nlid::SimulationBand b = nlid::simulation_band(model, data, unc, o);
    const Eigen::MatrixXd J = fd_jacobian(
        [&](const Eigen::VectorXd& th) {
          Lag m = model;
          m.set_parameters(th);
          return Eigen::VectorXd(m.simulate(u, 1.0, Eigen::VectorXd::Zero(1)).col(0));
        },
        model.parameters());
    const double expected = (J * unc.unidentifiable[0]).cwiseAbs().maxCoeff();
    REQUIRE(b.unidentifiable_change.size() == 1);
    CHECK(b.unidentifiable_change[0] == Approx(expected).epsilon(1e-5));
    CHECK_THAT(b.report(), Contains("unidentifiable combination 1"));
  }
  SECTION("fixed parameters carry no variance and are not moved to explain the error") {
    nlid::ParameterUncertainty unc = made_uncertainty(model.parameters(), lag_names(), 0.01, 4u);
    unc.covariance.row(2).setZero();
    unc.covariance.col(2).setZero();
    unc.free[2] = false;
    Eigen::MatrixXd y2 = y;
    y2.array() += 0.5;  // an offset only the fixed parameter could produce exactly
    const nlid::SimulationBand b =
        nlid::simulation_band(model, nlid::Dataset(nlid::Experiment(u, y2, 1.0, "rec")), unc, o);
    CHECK(b.free_parameters == 2);
    CHECK(b.reachable_share(0, 0) < 0.999);
  }
  SECTION("no free parameters: the whole error is the model's") {
    nlid::ParameterUncertainty unc = made_uncertainty(model.parameters(), lag_names(), 0.01, 4u);
    unc.covariance.setZero();
    unc.free.assign(3, false);
    Eigen::MatrixXd y2 = y;
    y2.array() += 0.5;
    const nlid::SimulationBand b =
        nlid::simulation_band(model, nlid::Dataset(nlid::Experiment(u, y2, 1.0, "rec")), unc, o);
    CHECK(b.free_parameters == 0);
    CHECK(b.rms_stddev(0, 0) == 0.0);
    CHECK_THAT(b.verdict(0, 0), Contains("no free parameters"));
  }
  SECTION("missing measured outputs: the band is computed, the error statistics skip them") {
    Eigen::MatrixXd ym = y;
    ym.setConstant(std::numeric_limits<double>::quiet_NaN());
    const nlid::ParameterUncertainty unc = made_uncertainty(model.parameters(), lag_names(), 0.01, 4u);
    const nlid::SimulationBand b =
        nlid::simulation_band(model, nlid::Dataset(nlid::Experiment(u, ym, 1.0, "blind", nlid::NonFinitePolicy::keep)), unc, o);
    CHECK(b.rms_stddev(0, 0) > 0.0);
    CHECK(b.stddev[0].allFinite());
    CHECK(std::isnan(b.rms_error(0, 0)));
    CHECK(std::isnan(b.within_band(0, 0)));
    CHECK(b.verdict(0, 0).empty());
    CHECK_THAT(b.report(), Contains("blind"));
  }
  SECTION("bad input is named") {
    nlid::ParameterUncertainty unc = made_uncertainty(model.parameters(), lag_names(), 0.01, 4u);
    Lag moved = model;
    moved.set_parameters(Eigen::Vector3d(12.5, 35.0, 21.0));
    CHECK_THROWS_WITH(nlid::simulation_band(moved, data, unc), Contains("'tau'") && Contains("recompute"));
    nlid::ParameterUncertainty other = unc;
    other.names[1] = "K";
    CHECK_THROWS_WITH(nlid::simulation_band(model, data, other), Contains("'gain'") && Contains("'K'"));
    nlid::ParameterUncertainty small = unc;
    small.covariance = Eigen::Matrix2d::Identity();
    CHECK_THROWS_WITH(nlid::simulation_band(model, data, small), Contains("covariance"));
    nlid::ParameterUncertainty nan = unc;
    nan.covariance(0, 0) = std::numeric_limits<double>::quiet_NaN();
    CHECK_THROWS_WITH(nlid::simulation_band(model, data, nan), Contains("not finite"));
    nlid::SimulationBandOptions bad;
    bad.band_sigmas = 0.0;
    CHECK_THROWS_WITH(nlid::simulation_band(model, data, unc, bad), Contains("band_sigmas"));
    CHECK_THROWS_WITH(nlid::simulation_band(model, nlid::Dataset{}, unc), Contains("no experiments"));
    Eigen::MatrixXd ub = u;
    ub(7, 0) = std::numeric_limits<double>::quiet_NaN();
    CHECK_THROWS_WITH(nlid::simulation_band(model, nlid::Dataset(nlid::Experiment(ub, y, 1.0, "gap", nlid::NonFinitePolicy::keep)), unc, o),
                      Contains("gap") && Contains("sample 7"));
    const nlid::Dataset two_inputs(nlid::Experiment(Eigen::MatrixXd::Zero(40, 2), Eigen::VectorXd::Zero(40), 1.0, "wide"));
    CHECK_THROWS(nlid::simulation_band(model, two_inputs, unc));
  }
}

TEST_CASE("Nlarx band: a missing input or measured past is named, not called a divergence", "[models][band]") {
  Arx model;
  model.set_parameters(Eigen::Vector4d(0.5, -0.1, 0.2, 0.7));
  const Eigen::MatrixXd u = nlid_test::random_steps(100, -1.0, 1.0, 6u);
  const Eigen::VectorXd y =
      model.simulate(nlid::Experiment(u, Eigen::VectorXd::Zero(100), 1.0), nlid::InitialCondition::zero).col(0);
  const nlid::ParameterUncertainty unc = made_uncertainty(model.parameters(), model.parameter_names(), 0.01, 8u);
  Eigen::MatrixXd ub = u;
  ub(40, 0) = std::numeric_limits<double>::quiet_NaN();
  const nlid::Dataset gap(nlid::Experiment(ub, y, 1.0, "gap", nlid::NonFinitePolicy::keep));
  CHECK_THROWS_WITH(nlid::simulation_band(model, gap, unc),
                    Contains("gap") && Contains("sample 40") && Contains("input") && !Contains("diverges"));
  // The measured initial past (the first n0 = 2 samples) has a missing output.
  Eigen::VectorXd yb = y;
  yb[1] = std::numeric_limits<double>::quiet_NaN();
  const nlid::Dataset past(nlid::Experiment(u, yb, 1.0, "past", nlid::NonFinitePolicy::keep));
  CHECK_THROWS_WITH(nlid::simulation_band(model, past, unc),
                    Contains("past") && Contains("sample 1") && Contains("output") && !Contains("diverges"));
  // A missing output later on only leaves that sample out of the error statistics.
  yb[1] = y[1];
  yb[60] = std::numeric_limits<double>::quiet_NaN();
  const nlid::SimulationBand b =
      nlid::simulation_band(model, nlid::Dataset(nlid::Experiment(u, yb, 1.0, "late", nlid::NonFinitePolicy::keep)), unc);
  CHECK(b.stddev[0].allFinite());
  CHECK(b.rms_error(0, 0) < 1e-9);
}

TEST_CASE("Band: a record the model reproduces exactly has no error to explain, not one out of reach",
          "[models][band]") {
  Lag model;
  model.set_parameters(Eigen::Vector3d(12.0, 35.0, 21.0));
  const Eigen::MatrixXd u = nlid_test::steps({0.0, 1.0, 0.4, 0.8}, 25, 120);
  const nlid::ParameterUncertainty unc = made_uncertainty(model.parameters(), lag_names(), 0.01, 9u);
  nlid::SimulationBandOptions o;
  o.initial_condition = nlid::InitialCondition::zero;
  const Eigen::MatrixXd y = model.simulate(u, 1.0, Eigen::VectorXd::Zero(1));
  const nlid::SimulationBand b = nlid::simulation_band(model, nlid::Dataset(nlid::Experiment(u, y, 1.0, "own")), unc, o);
  REQUIRE(b.rms_error(0, 0) == 0.0);
  CHECK(std::isnan(b.reachable_share(0, 0)));
  CHECK(std::isnan(b.plausible_share(0, 0)));
  CHECK(b.shift_sigmas(0, 0) == 0.0);
  CHECK_THAT(b.report(), !Contains("outside what they can reach"));
}

// Without an uncertainty argument: grey boxes (their own covariance) and AnyModel (its file's);
// a typed Nlarx does not turn into an AnyModel to fail at run time.
template <class M>
constexpr bool band_without_uncertainty = requires(const M& m, const nlid::Dataset& d) { nlid::simulation_band(m, d); };
static_assert(band_without_uncertainty<Lag>);
static_assert(band_without_uncertainty<nlid::AnyModel>);
static_assert(!band_without_uncertainty<Arx>);
static_assert(!band_without_uncertainty<Wiener>);

TEST_CASE("AnyModel band: the uncertainty a model file keeps gives the typed model's band", "[models][band]") {
  const auto path = [](const std::string& name) { return (nlid_test::scratch_dir() / name).string(); };
  auto same = [](const nlid::SimulationBand& a, const nlid::SimulationBand& b) {
    REQUIRE(a.stddev[0].rows() == b.stddev[0].rows());
    CHECK((a.stddev[0] - b.stddev[0]).cwiseAbs().maxCoeff() <= 1e-12 * b.stddev[0].maxCoeff());
    CHECK((a.y[0] - b.y[0]).cwiseAbs().maxCoeff() <= 1e-12 * (1.0 + b.y[0].cwiseAbs().maxCoeff()));
    CHECK(b.stddev[0].maxCoeff() > 0.0);
  };
  nlid::SimulationBandOptions o;
  o.initial_condition = nlid::InitialCondition::zero;
  const Eigen::MatrixXd u = nlid_test::random_steps(200, -1.0, 1.0, 12u);
  const nlid::Dataset data(nlid::Experiment(u, Eigen::VectorXd::Zero(200), 0.01, "run"));

  SECTION("nonlinear ARX") {
    Arx model(nlid::LaggedRegressors<2, 1, 0>{}, nlid::LinearMap<3>{}, 0.01);
    model.set_parameters(Eigen::Vector4d(1.3, -0.45, 0.2, 0.7));
    nlid::ModelFileInfo info;
    info.uncertainty = made_uncertainty(model.parameters(), model.parameter_names(), 0.01, 13u);
    nlid::save_model(path("band_any_arx.json"), model, info);
    const nlid::AnyModel any = nlid::load_model(path("band_any_arx.json"));
    same(nlid::simulation_band(any, data, o), nlid::simulation_band(model, data, *info.uncertainty, o));
    // Default: the initial condition the AnyModel simulates from.
    nlid::SimulationBandOptions by_default;
    by_default.initial_condition = any.initial_condition();
    same(nlid::simulation_band(any, data), nlid::simulation_band(model, data, *info.uncertainty, by_default));
    // Changed values: no covariance any more, and the band says so.
    nlid::AnyModel moved = any;
    Eigen::VectorXd th = moved.parameters();
    th[3] += 0.1;
    moved.set_parameters(th);
    CHECK_THROWS_WITH(nlid::simulation_band(moved, data, o), Contains("carries no parameter covariance"));
  }
  SECTION("Hammerstein-Wiener") {
    Wiener model;
    Eigen::VectorXd th(6);
    th << 0.1, 0.06, -1.5, 0.7, -0.8, 1.0;
    model.set_parameters(th);
    model.set_ts(0.01);
    nlid::ModelFileInfo info;
    info.uncertainty = made_uncertainty(th, model.parameter_names(), 0.01, 14u);
    nlid::save_model(path("band_any_hw.json"), model, info);
    same(nlid::simulation_band(nlid::load_model(path("band_any_hw.json")), data, o),
         nlid::simulation_band(model, data, *info.uncertainty, o));
  }
  SECTION("grey box: its own covariance") {
    Lag model;
    model.set_parameters(Eigen::Vector3d(12.0, 35.0, 21.0));
    const nlid::ParameterUncertainty unc = made_uncertainty(model.parameters(), lag_names(), 0.02, 15u);
    model.set_parameter_covariance(unc.covariance);
    nlid::save_model(path("band_any_lag.json"), model);
    const nlid::Dataset oven(nlid::Experiment(nlid_test::steps({0.0, 1.0, 0.4}, 25, 150), Eigen::VectorXd::Zero(150), 1.0, "oven"));
    same(nlid::simulation_band(nlid::load_model(path("band_any_lag.json")), oven, o), nlid::simulation_band(model, oven, unc, o));
  }
  SECTION("kinds without a band, and models without a covariance, are refused") {
    Arx model(nlid::LaggedRegressors<2, 1, 0>{}, nlid::LinearMap<3>{}, 0.01);
    model.set_parameters(Eigen::Vector4d(1.3, -0.45, 0.2, 0.7));
    nlid::save_model(path("band_any_none.json"), model);
    CHECK_THROWS_WITH(nlid::simulation_band(nlid::load_model(path("band_any_none.json")), data, o),
                      Contains("this nlarx model carries no parameter covariance"));
    // A compile-time type held by an AnyModel: no stored uncertainty to find; the typed call is the way.
    CHECK_THROWS_WITH(nlid::simulation_band(nlid::AnyModel(model), data, o),
                      Contains("has no simulation band") && Contains("compile-time model"));
  }
}
