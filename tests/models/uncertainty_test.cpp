// Parameter uncertainty of Nlarx and Hammerstein–Wiener models: the prediction-focus covariance
// of a linear-in-parameters NARX against σ²(XᵀX)⁻¹, a Wiener system's B, F and saturation limits
// within a few standard deviations of the truth, estimated initial states counted as unknowns,
// and errors that say what is missing.
#include <catch2/catch.hpp>

#include <cmath>
#include <random>

#include "nlid/models/estimate.hpp"
#include "nlid/models/uncertainty.hpp"
#include "nlid/nonlinearities/linear.hpp"
#include "nlid/nonlinearities/saturation.hpp"
#include "nlid/nonlinearities/unit_gain.hpp"
#include "nlid/regressors.hpp"
#include "test_inputs.hpp"

using Catch::Matchers::Contains;

using nlid_test::random_steps;

namespace {


using Arx = nlid::Nlarx<nlid::LaggedRegressors<2, 1, 0>, nlid::LinearMap<3>>;

// y(t) = 1.3 y(t−1) − 0.45 y(t−2) + 0.2 u(t) + 0.7 + e(t), e white (equation error).
nlid::Experiment arx_record(int n, unsigned seed, double noise) {
  const Eigen::MatrixXd u = random_steps(n, -3.0, 3.0, seed);
  std::mt19937 gen(seed + 100);
  std::normal_distribution<double> nd(0.0, noise);
  Eigen::VectorXd y = Eigen::VectorXd::Zero(n);
  for (int t = 2; t < n; ++t) y[t] = 1.3 * y[t - 1] - 0.45 * y[t - 2] + 0.2 * u(t, 0) + 0.7 + nd(gen);
  return nlid::Experiment(u, y, 1.0, "arx" + std::to_string(seed));
}

using Wiener = nlid::HammersteinWiener<nlid::UnitGain, nlid::TransferFunctionBlock<2, 2, 1>, nlid::Saturation>;

}  // namespace

TEST_CASE("Nlarx, prediction focus: the covariance of a linear-in-parameters model is sigma^2 (X'X)^-1",
          "[models][uncertainty]") {
  const nlid::Dataset data{arx_record(400, 1, 0.1), arx_record(300, 2, 0.1)};
  const Arx est = nlid::estimate(Arx{}, data);
  nlid::ModelUncertaintyOptions o;
  o.uncertainty.residuals = nlid::ResidualModel::white;
  const nlid::ParameterUncertainty u = nlid::parameter_uncertainty(est, data, o);

  // The regression written out: rows t = 2 … N−1 of each record, X = [y(t−1) y(t−2) u(t) 1].
  Eigen::MatrixXd X(398 + 298, 4);
  Eigen::VectorXd Y(398 + 298);
  Eigen::Index row = 0;
  for (const auto& e : data) {
    for (Eigen::Index t = 2; t < e.size(); ++t, ++row) {
      X.row(row) << e.y()(t - 1, 0), e.y()(t - 2, 0), e.u()(t, 0), 1.0;
      Y[row] = e.y()(t, 0);
    }
  }
  const Eigen::VectorXd r = X * est.parameters() - Y;
  const Eigen::MatrixXd P = r.squaredNorm() / (696.0 - 4.0) * (X.transpose() * X).inverse();
  REQUIRE(u.theta.size() == 4);
  CHECK(u.names == est.parameter_names());
  CHECK(u.observations == 696);
  CHECK((u.covariance - P).cwiseAbs().maxCoeff() < 1e-9 * P.cwiseAbs().maxCoeff());
  // The truth within 4 σ.
  const Eigen::Vector4d truth(1.3, -0.45, 0.2, 0.7);
  for (int i = 0; i < 4; ++i) CHECK(std::abs(est.parameters()[i] - truth[i]) < 4.0 * u.stddev[i]);
  // White equation error: the correlated formula agrees with the white one.
  const nlid::ParameterUncertainty c = nlid::parameter_uncertainty(est, data);
  CHECK(c.residuals == nlid::ResidualModel::correlated);
  for (int i = 0; i < 4; ++i) CHECK(c.stddev[i] / u.stddev[i] == Approx(1.0).margin(0.25));
  // Mis-scaled data are named, as in the estimators.
  nlid::Experiment big = data[0];
  big.u() *= 1e-250;
  CHECK_THROWS_WITH(nlid::parameter_uncertainty(est, nlid::Dataset{big}),
                    Catch::Contains("parameter_uncertainty: experiment") && Catch::Contains("below 1e-100"));
}

TEST_CASE("Nlarx, simulation focus with estimated initial states: the states are unknowns too",
          "[models][uncertainty]") {
  const nlid::Dataset data{arx_record(300, 3, 0.05), arx_record(300, 4, 0.05)};
  nlid::EstimateOptions eo;
  eo.focus = nlid::Focus::simulation;
  eo.initial_condition = nlid::InitialCondition::estimate;
  const Arx est = nlid::estimate(Arx{}, data, eo);
  const nlid::ParameterUncertainty u = nlid::parameter_uncertainty(est, data);
  REQUIRE(u.theta.size() == 4 + 2 * 2);  // θ, then y(−1), y(−2) of each record
  CHECK(u.names[4] == "x0[0][0]");
  CHECK(u.rank == 8);
  CHECK(u.observations == 600);
  for (int i = 0; i < 8; ++i) CHECK((std::isfinite(u.stddev[i]) && u.stddev[i] > 0.0));
  // Equation error seen through the simulation: strongly correlated residuals.
  CHECK(u.lag1_correlation > 0.5);
  CHECK(u.stddev[0] > 1.5 * u.stddev_white[0]);

  // Asked with another criterion than the report's: prediction, no states.
  nlid::ModelUncertaintyOptions pred;
  pred.focus = nlid::Focus::prediction;
  CHECK(nlid::parameter_uncertainty(est, data, pred).theta.size() == 4);

  // Initial condition 'estimate' for a model whose report has no states.
  nlid::ModelUncertaintyOptions bad;
  bad.focus = nlid::Focus::simulation;
  bad.initial_condition = nlid::InitialCondition::estimate;
  CHECK_THROWS_WITH(nlid::parameter_uncertainty(Arx{}, data, bad),
                    Contains("needs the estimated initial state of each of the 2 experiments; the model's report has 0"));
  bad.initial_condition = nlid::InitialCondition::equilibrium;
  CHECK_THROWS_WITH(nlid::parameter_uncertainty(est, data, bad), Contains("equilibrium initial conditions are not supported"));
  bad.initial_condition.reset();
  bad.uncertainty.fixed = {true};
  CHECK_THROWS_WITH(nlid::parameter_uncertainty(est, data, bad), Contains("fixed has 1 entries; the model has 4 parameters"));
}

TEST_CASE("Wiener + saturation: B, F and both limits within a few sigma of the truth", "[models][uncertainty]") {
  Wiener truth;
  Eigen::VectorXd th(6);
  th << 0.1, 0.06, -1.5, 0.7, -0.8, 1.0;  // b1 b2 f1 f2 lower upper
  truth.set_parameters(th);
  std::mt19937 gen(9);
  std::normal_distribution<double> nd(0.0, 0.02);
  std::vector<nlid::Experiment> exps;
  for (unsigned s = 1; s <= 2; ++s) {
    const Eigen::MatrixXd u = random_steps(700, -2.0, 2.0, s);
    Eigen::VectorXd y(u.rows());
    REQUIRE(truth.simulate<double>(u, nlid::detail::as_const_span(th), {}, nlid::detail::as_span(y)));
    for (Eigen::Index t = 0; t < y.size(); ++t) y[t] += nd(gen);
    exps.emplace_back(u, y, 0.01, "w" + std::to_string(s));
  }
  const nlid::Dataset data(exps);
  const Wiener est = nlid::estimate(Wiener{}, data);
  const nlid::ParameterUncertainty u = nlid::parameter_uncertainty(est, data);
  INFO(u.report());
  REQUIRE(u.theta.size() == 6);
  CHECK(u.rank == 6);
  CHECK(std::abs(u.lag1_correlation) < 0.1);  // white measurement noise, right structure
  for (int i = 0; i < 6; ++i) {
    INFO(u.names[static_cast<std::size_t>(i)]);
    CHECK(u.stddev[i] > 0.0);
    CHECK(std::abs(est.parameters()[i] - th[i]) < 4.0 * u.stddev[i]);
  }
  // The limits are seen directly at every saturated sample: far better determined than B.
  CHECK(u.relative_percent(5) < u.relative_percent(0));
  CHECK_THAT(u.report(), Contains(est.parameter_names()[0]) && Contains("+- "));

  // Data that do not fit the model are named.
  const nlid::Dataset two_inputs(nlid::Experiment(Eigen::MatrixXd::Zero(50, 2), Eigen::VectorXd::Zero(50), 0.01, "wide"));
  CHECK_THROWS_WITH(nlid::parameter_uncertainty(est, two_inputs), Contains("experiment 'wide' has 2 input(s)"));
}
