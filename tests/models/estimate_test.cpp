// Estimation of Nlarx and Hammerstein-Wiener models: known-answer recovery from the library's own
// initialisation, multi-experiment data with estimated initial states, solver options, bad input.
#include <catch2/catch.hpp>

#include <cmath>
#include <limits>
#include <random>
#include <utility>

#include "nlid/data/csv.hpp"
#include "nlid/data/resample.hpp"
#include "nlid/models/estimate.hpp"
#include "nlid/linear/polynomial.hpp"
#include "nlid/nonlinearities/linear.hpp"
#include "nlid/nonlinearities/piecewise_linear.hpp"
#include "nlid/nonlinearities/saturation.hpp"
#include "nlid/nonlinearities/sigmoid_network.hpp"
#include "nlid/nonlinearities/unit_gain.hpp"
#include "nlid/regressors.hpp"
#include "test_inputs.hpp"

using nlid_test::random_steps;

namespace {

using Wiener = nlid::HammersteinWiener<nlid::UnitGain, nlid::TransferFunctionBlock<2, 2, 1>, nlid::Saturation>;

Eigen::VectorXd wiener_truth() {
  Eigen::VectorXd th(6);
  th << 0.1, 0.06, -1.5, 0.7, -0.8, 1.0;  // b1 b2 f1 f2 lower upper; static gain 0.8
  return th;
}

nlid::Experiment simulate_truth(const Wiener& truth, const Eigen::MatrixXd& u, const std::string& name) {
  Eigen::VectorXd y(u.rows());
  REQUIRE(truth.simulate<double>(u, nlid::detail::as_const_span(truth.parameters()), {}, nlid::detail::as_span(y)));
  return nlid::Experiment(u, y, 0.01, name);
}
}  // namespace

TEST_CASE("Wiener [2 2 1] + saturation: B, F and the limits are recovered", "[models][estimate]") {
  Wiener truth;
  truth.set_parameters(wiener_truth());
  const nlid::Dataset data{simulate_truth(truth, random_steps(800, -2.0, 2.0, 1), "a"),
                           simulate_truth(truth, random_steps(600, -2.0, 2.0, 2), "b")};
  // Both limits must actually be active in the data, else they are not identifiable.
  CHECK(data[0].y().maxCoeff() == Approx(1.0));
  CHECK(data[0].y().minCoeff() == Approx(-0.8));

  const Wiener est = nlid::estimate(Wiener{}, data);  // library's own initialisation, zero IC
  const Eigen::VectorXd err = est.parameters() - wiener_truth();
  INFO(est.describe());
  CHECK(err.cwiseAbs().maxCoeff() < 1e-6);  // noise-free data: recovery to solver tolerance
  CHECK(est.report().fit_percent[0] > 99.999);
  CHECK(est.ts() == 0.01);
  CHECK_THAT(est.describe(), Catch::Contains("estimated with simulation focus"));

  // The same records with u in units 1e10 larger and y in units 1e10 smaller: the same model in
  // those units. (The linear block's least-squares start once judged the input columns zero
  // beside the output columns, 1e20 apart, and started from B = 0.)
  const double ku = 1e-10, ky = 1e10;
  nlid::Dataset scaled;
  for (const nlid::Experiment& e : data) scaled.add(nlid::Experiment(ku * e.u(), ky * e.y(), e.ts(), e.name()));
  const Wiener est2 = nlid::estimate(Wiener{}, scaled);
  Eigen::VectorXd want = wiener_truth();
  want.head(2) *= ky / ku;
  want.tail(2) *= ky;
  INFO(est2.describe());
  CHECK(((est2.parameters() - want).array() / want.array()).abs().maxCoeff() < 1e-6);
  CHECK(est2.report().fit_percent[0] > 99.999);
  // The data-driven start itself (no iterations) is the same start in those units.
  nlid::EstimateOptions start_only;
  start_only.linear_iterations = 0;
  start_only.solver.max_iterations = 0;
  const Eigen::VectorXd s1 = nlid::estimate(Wiener{}, data, start_only).parameters();
  Eigen::VectorXd s2 = nlid::estimate(Wiener{}, scaled, start_only).parameters();
  s2.head(2) *= ku / ky;
  s2.tail(2) /= ky;
  CAPTURE(s1.transpose(), s2.transpose());
  CHECK(s1.cwiseAbs().head(2).minCoeff() > 1e-3);
  CHECK((s2 - s1).cwiseAbs().maxCoeff() < 1e-9 * s1.cwiseAbs().maxCoeff());
}

TEST_CASE("HW started from a given linear block with initialize = false", "[models][estimate]") {
  Wiener truth;
  truth.set_parameters(wiener_truth());
  const nlid::Dataset data{simulate_truth(truth, random_steps(600, -2.0, 2.0, 3), "c")};
  Wiener start;
  Eigen::VectorXd th(6);
  th << 0.12, 0.05, -1.45, 0.66, -0.7, 0.9;  // e.g. an earlier OE model plus the stops' guess
  start.set_parameters(th);
  nlid::EstimateOptions o;
  o.initialize = false;
  int calls = 0;
  o.solver.callback = [&calls](const nlid::IterationReport&) { ++calls; return true; };
  const Wiener est = nlid::estimate(start, data, o);
  CHECK((est.parameters() - wiener_truth()).cwiseAbs().maxCoeff() < 1e-6);
  CHECK(calls > 1);
}

TEST_CASE("HW estimation gives the same model whatever units the data are in", "[models][estimate]") {
  // Data from a Hammerstein–Wiener system whose input map (tanh) PwLinear<4> can only
  // approximate, so the solve ends at a compromise that depends on the path: a path that
  // depended on the units would show in the fit.
  using Hw = nlid::HammersteinWiener<nlid::PwLinear<4>, nlid::TransferFunctionBlock<2, 2, 1>, nlid::Saturation>;
  const Eigen::MatrixXd u = random_steps(700, -2.0, 2.0, 5);
  Eigen::VectorXd w = u.col(0).array().tanh();
  Eigen::VectorXd b(3), f(3);
  b << 0, 0.3, 0.15;
  f << 1, -1.2, 0.4;
  const Eigen::VectorXd y = nlid::filter(b, f, w).cwiseMax(-1.5).cwiseMin(1.8);
  auto fit_in_units = [&](double ku, double ky, nlid::LmScaling scaling,
                          nlid::InitialCondition ic = nlid::InitialCondition::zero) {
    const nlid::Dataset data{nlid::Experiment(Eigen::MatrixXd(ku * u), Eigen::VectorXd(ky * y), 0.01, "e")};
    nlid::EstimateOptions o;
    o.solver.scaling = scaling;
    o.initial_condition = ic;
    const Hw est = nlid::estimate(Hw{}, data, o);
    INFO(est.report().status);
    return est.report().fit_percent[0];
  };
  const double reference = fit_in_units(1.0, 1.0, nlid::LmScaling::automatic);
  CHECK(reference > 90.0);
  // (y ×1e-9: gradients far below the parameters' last digits, where θ − (θ − g) rounds to 0.)
  for (const auto& [ku, ky] : {std::pair{1000.0, 1.0}, std::pair{1.0, 1e-3}, std::pair{1.0, 1e6}, std::pair{1e-4, 1e5},
                               std::pair{1.0, 1e-9}}) {
    CAPTURE(ku, ky);
    CHECK(fit_in_units(ku, ky, nlid::LmScaling::automatic) == Approx(reference).margin(0.01));
  }
  // Uniform damping without the parameters' units (explicit levenberg): the units change the path.
  CHECK(std::abs(fit_in_units(1.0, 1e6, nlid::LmScaling::levenberg) - reference) > 0.1);
  // Estimated initial states are unknowns of the solve too, with the block's (y's) units.
  const double with_x0 = fit_in_units(1.0, 1.0, nlid::LmScaling::automatic, nlid::InitialCondition::estimate);
  CHECK(with_x0 > 90.0);
  CHECK(fit_in_units(1e3, 1e-3, nlid::LmScaling::automatic, nlid::InitialCondition::estimate) ==
        Approx(with_x0).margin(0.01));
}

TEST_CASE("sigmoid-net NARX: the estimated model fits fresh noise-free data > 99 %", "[models][estimate]") {
  using Net = nlid::SigmoidNet<3, 3>;
  using Model = nlid::Nlarx<nlid::LaggedRegressors<2, 1, 0>, Net>;
  Net net;
  net.set_normalization(Eigen::Vector3d::Zero(), Eigen::Vector3d::Ones());
  Model truth(nlid::LaggedRegressors<2, 1, 0>{}, net, 0.1);
  Eigen::VectorXd th(Model::num_params);  // [L(3), d, a(3), b(3x3), c(3)]
  th << 0.5, 0.2, 0.3, 0.1, 1.0, -0.8, 0.5, 0.3, 0.0, 1.5, 0.0, 0.4, -1.0, 0.5, 0.2, 2.0, 0.0, 0.5, -0.3;
  truth.set_parameters(th);
  auto make = [&](unsigned seed, const std::string& name) {
    const Eigen::MatrixXd u = random_steps(700, -1.5, 1.5, seed);
    const nlid::Experiment e0(u, Eigen::VectorXd::Zero(700), 0.1, name);
    return nlid::Experiment(u, truth.simulate(e0), 0.1, name);
  };
  const nlid::Dataset train{make(11, "train")};
  const nlid::Experiment valid = make(12, "valid");

  nlid::EstimateOptions o;
  o.solver.max_iterations = 150;  // the unit directions converge slowly (flat valleys)
  const Model est = nlid::estimate(Model{}, train, o);
  const Eigen::MatrixXd sim = est.simulate(valid, nlid::InitialCondition::zero);
  const double fit = nlid::fit_percent(valid.y().col(0), sim.col(0));
  INFO(est.describe());
  CHECK(fit > 99.0);
  CHECK(est.report().fit_percent.size() == 1);
  CHECK(est.regressor_names() == std::vector<std::string>{"y(t-1)", "y(t-2)", "u(t)"});  // the data's channel names
}

TEST_CASE("multi-start NARX: starts compared by estimation cost, the cheapest continued", "[models][estimate]") {
  using Model = nlid::Nlarx<nlid::LaggedRegressors<2, 1, 0>, nlid::SigmoidNet<3, 2>>;
  // A plant with a sign-like (steep) nonlinearity in the velocity: friction-like.
  const Eigen::MatrixXd u = random_steps(800, -1.0, 1.0, 21);
  Eigen::VectorXd y = Eigen::VectorXd::Zero(800);
  for (Eigen::Index t = 2; t < 800; ++t) {
    const double v = y(t - 1) - y(t - 2);
    y(t) = 1.5 * y(t - 1) - 0.6 * y(t - 2) + 0.2 * u(t, 0) - 0.02 * std::tanh(50.0 * v);
  }
  const nlid::Dataset train{nlid::Experiment(u, y, 0.1, "train")};
  nlid::EstimateOptions o;
  o.focus = nlid::Focus::simulation;
  o.solver.max_iterations = 40;
  const Model one = nlid::estimate(Model{}, train, o);
  CHECK(one.report().start_costs.empty());
  CHECK(one.report().chosen_start == -1);
  o.starts = 3;
  o.start_iterations = 10;
  std::vector<std::string> stages;
  o.progress = [&stages](const std::string& s) { stages.push_back(s); };
  const Model multi = nlid::estimate(Model{}, train, o);
  const auto& costs = multi.report().start_costs;
  REQUIRE(costs.size() == 3);
  const int k = multi.report().chosen_start;
  REQUIRE(k >= 0);
  // Each stage is announced, so costs printed by a callback can be told apart: per start a
  // prediction stage (one-step costs) and a simulation stage, then the chosen start continues.
  REQUIRE(stages.size() == 7);
  CHECK(stages[0] == "start 1 of 3: prediction stage (one-step errors, the free run's start)");
  CHECK(stages[1] == "start 1 of 3: simulation stage (free-run errors)");
  CHECK(stages[5] == "start 3 of 3: simulation stage (free-run errors)");
  CHECK_THAT(stages[6], Catch::Contains("start " + std::to_string(k + 1) + " has the lowest cost") &&
                            Catch::Contains("continues for 30 iteration(s)"));
  for (double c : costs) CHECK(costs[static_cast<std::size_t>(k)] <= c);
  CHECK(multi.report().final_cost <= costs[static_cast<std::size_t>(k)]);  // the continuation only improves
  CHECK(multi.describe().find("3 data-driven starts") != std::string::npos);
  // Start 0 of a SigmoidNet is its default initialisation.
  nlid::SigmoidNet<3, 2> a, b;
  const Eigen::MatrixXd X = Eigen::MatrixXd::Random(200, 3);
  const Eigen::VectorXd yy = X.rowwise().sum().array().tanh();
  Eigen::VectorXd ta(a.num_parameters()), tb(b.num_parameters());
  a.initialize(X, yy, nlid::detail::as_span(ta));
  b.initialize(X, yy, nlid::detail::as_span(tb), 0);
  CHECK(ta == tb);
  CHECK_THROWS_AS(b.initialize(X, yy, nlid::detail::as_span(tb), -1), nlid::Error);
}

TEST_CASE("multi-experiment simulation focus with estimated initial states", "[models][estimate]") {
  using Model = nlid::Nlarx<nlid::LaggedRegressors<2, 1, 0>, nlid::LinearMap<3>>;
  Model truth;
  Eigen::VectorXd th(4);
  th << 1.3, -0.45, 0.2, 0.7;  // ARX with offset, static gain 0.2/0.15
  truth.set_parameters(th);
  std::vector<nlid::Experiment> exps;
  const Eigen::Vector2d x0s[2] = {{8.0, 7.5}, {-2.0, -1.0}};
  for (int i = 0; i < 2; ++i) {
    const Eigen::MatrixXd u = random_steps(300, -3.0, 3.0, 20 + i);
    Eigen::VectorXd y(300);
    REQUIRE(truth.simulate<double>(u, nlid::detail::as_const_span(th), nlid::detail::as_const_span(x0s[i]),
                                   nlid::detail::as_span(y)));
    exps.emplace_back(u, y, 1.0, "e" + std::to_string(i));
  }
  nlid::EstimateOptions o;
  o.focus = nlid::Focus::simulation;
  o.initial_condition = nlid::InitialCondition::estimate;
  const Model est = nlid::estimate(Model{}, nlid::Dataset(exps), o);
  CHECK((est.parameters() - th).cwiseAbs().maxCoeff() < 1e-6);
  REQUIRE(est.report().initial_states.size() == 2);
  for (int i = 0; i < 2; ++i) CHECK((est.report().initial_states[i] - x0s[i]).cwiseAbs().maxCoeff() < 1e-5);
  CHECK(est.report().fit_percent[1] > 99.9999);
}

TEST_CASE("Hammerstein input saturation: the limits are found from the library's own start", "[models][estimate]") {
  // The input map starts as the identity; a saturation with its limits at the input's extremes
  // would clamp nothing and get no gradient, so its limits must start inside the data.
  using H = nlid::HammersteinWiener<nlid::Saturation, nlid::TransferFunctionBlock<2, 1, 1>, nlid::UnitGain>;
  H truth;
  Eigen::VectorXd p(5);
  p << -1.0, 1.2, 0.5, 0.3, -0.7;  // lower upper | b1 b2 | f1
  truth.set_parameters(p);
  const Eigen::MatrixXd u = random_steps(1000, -2.0, 2.0, 21);
  REQUIRE((u.array() < -1.0).count() > 50);
  REQUIRE((u.array() > 1.2).count() > 50);
  Eigen::VectorXd y(1000);
  REQUIRE(truth.simulate<double>(u, nlid::detail::as_const_span(p), {}, nlid::detail::as_span(y)));
  const H est = nlid::estimate(H{}, nlid::Dataset{nlid::Experiment(u, y, 1.0, "e")});
  INFO(est.report().status);
  CHECK((est.parameters() - p).cwiseAbs().maxCoeff() < 1e-6);
  CHECK(est.report().fit_percent[0] > 99.999);
}

TEST_CASE("fixed parameters keep the caller's values when the start is data-driven", "[models][estimate]") {
  SECTION("Hammerstein-Wiener: b1, b2 held at the values set") {
    Wiener truth;
    truth.set_parameters(wiener_truth());
    const nlid::Dataset data{simulate_truth(truth, random_steps(600, -2.0, 2.0, 7), "f")};
    Wiener start;
    Eigen::VectorXd th = Eigen::VectorXd::Zero(6);
    th(0) = wiener_truth()(0);
    th(1) = wiener_truth()(1);
    start.set_parameters(th);
    nlid::EstimateOptions o;  // initialize = true: the data-driven start sets the other four
    o.solver.fixed = {true, true, false, false, false, false};
    const Wiener est = nlid::estimate(start, data, o);
    CHECK(est.parameters()(0) == wiener_truth()(0));
    CHECK(est.parameters()(1) == wiener_truth()(1));
    CHECK((est.parameters() - wiener_truth()).cwiseAbs().maxCoeff() < 1e-6);
  }
  SECTION("nonlinear ARX: L[0] held at 0.3 while the rest is fitted") {
    using Model = nlid::Nlarx<nlid::LaggedRegressors<2, 1, 0>, nlid::LinearMap<3>>;
    Model truth;
    Eigen::VectorXd th(4);
    th << 1.3, -0.45, 0.2, 0.7;
    truth.set_parameters(th);
    const Eigen::MatrixXd u = random_steps(300, -3.0, 3.0, 9);
    Eigen::VectorXd y(300);
    REQUIRE(truth.simulate<double>(u, nlid::detail::as_const_span(th), nlid::detail::as_const_span(Eigen::Vector2d(0.0, 0.0)),
                                   nlid::detail::as_span(y)));
    Model start;
    Eigen::VectorXd th0 = Eigen::VectorXd::Zero(4);
    th0(0) = 0.3;
    start.set_parameters(th0);
    nlid::EstimateOptions o;
    o.focus = nlid::Focus::prediction;
    o.solver.fixed = {true, false, false, false};
    const Model est = nlid::estimate(start, nlid::Dataset{nlid::Experiment(u, y, 1.0, "g")}, o);
    CHECK(est.parameters()(0) == 0.3);
    CHECK(std::abs(est.parameters()(1) + 0.45) > 0.01);  // the others compensate as they can
  }
}

TEST_CASE("EstimateOptions counts that mean nothing are refused, naming the option", "[models][estimate][errors]") {
  Wiener truth;
  truth.set_parameters(wiener_truth());
  const nlid::Dataset data{simulate_truth(truth, random_steps(300, -2.0, 2.0, 8), "h")};
  using Model = nlid::Nlarx<nlid::LaggedRegressors<2, 1, 0>, nlid::LinearMap<3>>;
  auto refused = [&](auto set, const char* name) {
    nlid::EstimateOptions o;
    o.focus = nlid::Focus::simulation;
    set(o);
    CHECK_THROWS_WITH(nlid::estimate(Model{}, data, o), Catch::Contains(std::string("EstimateOptions::") + name));
    CHECK_THROWS_WITH(nlid::estimate(Wiener{}, data, o), Catch::Contains(std::string("EstimateOptions::") + name));
  };
  refused([](nlid::EstimateOptions& o) { o.prediction_iterations = -1; }, "prediction_iterations");
  refused([](nlid::EstimateOptions& o) { o.linear_iterations = -2; }, "linear_iterations");
  refused([](nlid::EstimateOptions& o) { o.starts = 0; }, "starts");
  refused([](nlid::EstimateOptions& o) { o.start_iterations = -1; }, "start_iterations");
}

TEST_CASE("regularized prediction focus is the ridge estimate of the regressors", "[models][estimate]") {
  // A linear-in-θ NARX (LinearMap): the prediction-focus criterion is linear least squares in
  // θ = [L1 L2 d] over the rows φ(t) = [y(t-1) u(t-1) 1], t = 1 … N-1, so the regularized
  // estimate has a closed form.
  using Model = nlid::Nlarx<nlid::LaggedRegressors<1, 1, 1>, nlid::LinearMap<2>>;
  const int n = 120;
  const Eigen::MatrixXd u = random_steps(n, -1.0, 1.0, 9);
  std::mt19937 gen(4);
  std::normal_distribution<double> noise(0.0, 0.3);
  Eigen::VectorXd y(n);
  y(0) = 0.0;
  for (int t = 1; t < n; ++t) y(t) = 0.7 * y(t - 1) + 0.5 * u(t - 1, 0) + 0.2 + noise(gen);
  const nlid::Dataset data(nlid::Experiment(u, y, 1.0, "noisy"));
  Eigen::MatrixXd phi(n - 1, 3);
  for (int t = 1; t < n; ++t) phi.row(t - 1) << y(t - 1), u(t - 1, 0), 1.0;
  const Eigen::VectorXd target = y.tail(n - 1);

  nlid::EstimateOptions o;
  o.focus = nlid::Focus::prediction;
  o.solver.function_tolerance = 0;
  o.solver.gradient_tolerance = 1e-12;
  const Model plain = nlid::estimate(Model{}, data, o);
  const Eigen::VectorXd ls = (phi.transpose() * phi).ldlt().solve(phi.transpose() * target);
  CHECK((plain.parameters() - ls).cwiseAbs().maxCoeff() < 1e-6);  // the rows are the criterion's

  const double lambda = 30.0;
  const Eigen::Vector3d w(1.0, 4.0, 0.0), nominal(0.2, 0.0, 0.0);  // the offset is free
  o.solver.regularization.lambda = lambda;
  o.solver.regularization.weights = w;
  o.solver.regularization.nominal = nominal;
  const Model ridge = nlid::estimate(Model{}, data, o);
  const Eigen::VectorXd want = (phi.transpose() * phi + lambda * Eigen::MatrixXd(w.asDiagonal()))
                                   .ldlt()
                                   .solve(phi.transpose() * target + lambda * w.cwiseProduct(nominal));
  INFO("plain " << plain.parameters().transpose() << ", ridge " << ridge.parameters().transpose() << ", want "
                << want.transpose());
  CHECK((want - ls).cwiseAbs().maxCoeff() > 0.05);  // the penalty moves the estimate
  CHECK((ridge.parameters() - want).cwiseAbs().maxCoeff() < 1e-6);  // the cost resolves θ to ≈ 1e-8

  o.solver.regularization.weights = Eigen::Vector2d(1.0, 1.0);
  CHECK_THROWS_WITH(nlid::estimate(Model{}, data, o),
                    Catch::Contains("regularization.weights has 2 entries; the model has 3 parameters"));
}

TEST_CASE("regularization leaves estimated initial states free", "[models][estimate]") {
  // Simulation focus with initial states appended to θ: a strong pull of the model's
  // parameters towards the truth must not pull the states towards zero.
  using Model = nlid::Nlarx<nlid::LaggedRegressors<2, 1, 0>, nlid::LinearMap<3>>;
  Model truth;
  Eigen::VectorXd th(4);
  th << 1.3, -0.45, 0.2, 0.7;
  truth.set_parameters(th);
  const Eigen::Vector2d x0(8.0, 7.5);
  const Eigen::MatrixXd u = random_steps(300, -3.0, 3.0, 20);
  Eigen::VectorXd y(300);
  REQUIRE(truth.simulate<double>(u, nlid::detail::as_const_span(th), nlid::detail::as_const_span(x0),
                                 nlid::detail::as_span(y)));
  nlid::EstimateOptions o;
  o.focus = nlid::Focus::simulation;
  o.initial_condition = nlid::InitialCondition::estimate;
  o.solver.regularization.lambda = 1e6;
  o.solver.regularization.nominal = th;
  const Model est = nlid::estimate(Model{}, nlid::Dataset(nlid::Experiment(u, y, 1.0, "e")), o);
  CHECK((est.parameters() - th).cwiseAbs().maxCoeff() < 1e-6);
  REQUIRE(est.report().initial_states.size() == 1);
  CHECK((est.report().initial_states[0] - x0).cwiseAbs().maxCoeff() < 1e-4);
}

// Output outliers also enter an ARX model's regressors y(t-1), so one-step (prediction-focus)
// errors are not robust to them whatever the loss; free-run errors are, since the simulation never
// reads the measured output. Hence simulation focus here.
TEST_CASE("Huber loss resists outliers that pull least squares off", "[models][estimate]") {
  using Model = nlid::Nlarx<nlid::LaggedRegressors<1, 1, 1>, nlid::LinearMap<2>>;
  Model truth;
  Eigen::Vector3d th(0.8, 0.5, 0.0);
  truth.set_parameters(th);
  const Eigen::MatrixXd u = random_steps(400, -1.0, 1.0, 5);
  nlid::Experiment e(u, Eigen::VectorXd::Zero(400), 1.0, "out");
  Eigen::VectorXd y = truth.simulate(e).col(0);
  for (int t = 13; t < 400; t += 37) y(t) += 25.0;  // spikes: sensor glitches
  e.y().col(0) = y;
  nlid::EstimateOptions o;
  o.focus = nlid::Focus::simulation;
  o.initial_condition = nlid::InitialCondition::zero;
  const Model ls = nlid::estimate(Model{}, nlid::Dataset{e}, o);
  o.solver.loss.kind = nlid::RobustLoss::Kind::huber;
  o.solver.loss.delta = 0.1;
  o.solver.max_iterations = 200;
  const Model hub = nlid::estimate(Model{}, nlid::Dataset{e}, o);
  const double err_ls = (ls.parameters() - th).norm(), err_hub = (hub.parameters() - th).norm();
  CHECK(err_hub < 0.1 * err_ls);
  CHECK(err_hub < 0.02);
}

TEST_CASE("an input held constant in the estimation data does not move the estimated model", "[models][estimate]") {
  // y ignores u2, which is held at 0.1 (its mean is not exactly 0.1). Before, the rounding
  // noise x - mean was fitted with weights up to 1e16, and moving u2 by 0.1 moved the
  // simulated output by 1e11.
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> level(-1, 1);
  const int n = 600;
  Eigen::MatrixXd u(n, 2);
  Eigen::VectorXd y(n);
  for (int t = 0; t < n; ++t) {
    u(t, 0) = level(rng);
    u(t, 1) = 0.1;
    y(t) = (t ? 0.5 * y(t - 1) : 0.0) + std::tanh(2.0 * u(t, 0));
  }
  using Regs = nlid::RegressorSet<nlid::LaggedRegressors<1, 1, 0>, nlid::InputLags<1, 0, 1>>;
  const nlid::Experiment e(u, y, 1.0);
  const auto m = nlid::estimate(nlid::Nlarx<Regs, nlid::SigmoidNet<3, 4>>{}, nlid::Dataset{e});
  CHECK(m.parameters().cwiseAbs().maxCoeff() < 1e3);
  Eigen::MatrixXd u2 = u;
  u2.col(1).setConstant(0.2);
  const nlid::Experiment moved(u2, y, 1.0);
  const Eigen::MatrixXd s1 = m.simulate(e, nlid::InitialCondition::measured);
  CHECK((m.simulate(moved, nlid::InitialCondition::measured) - s1).cwiseAbs().maxCoeff() == 0.0);
  CHECK(nlid::fit_percent(y, s1.col(0)) > 99.0);
}

TEST_CASE("estimation refuses bad data, naming the experiment", "[models][estimate]") {
  using Model = nlid::Nlarx<nlid::LaggedRegressors<4, 2, 1>, nlid::LinearMap<6>>;
  const nlid::Experiment ok(random_steps(50, -1, 1, 7), Eigen::VectorXd::Zero(50), 1.0, "long");
  const nlid::Experiment tiny(random_steps(4, -1, 1, 8), Eigen::VectorXd::Zero(4), 1.0, "tiny");
  CHECK_THROWS_WITH(nlid::estimate(Model{}, nlid::Dataset{ok, tiny}),
                    Catch::Contains("experiment 'tiny' has 4 samples") && Catch::Contains("experiment 1"));
  CHECK_THROWS_WITH(nlid::estimate(Model{}, nlid::Dataset{}), Catch::Contains("no experiments"));
  using TwoInputs = nlid::Nlarx<nlid::RegressorSet<nlid::OutputLags<1>, nlid::InputLags<1, 0, 0>, nlid::InputLags<1, 0, 1>>,
                                nlid::LinearMap<3>>;
  CHECK_THROWS_WITH(nlid::estimate(TwoInputs{}, nlid::Dataset{ok}),
                    Catch::Contains("experiment 'long' has 1 input(s) but the nonlinear ARX model reads 2") &&
                        Catch::Contains("experiment 0"));
  nlid::EstimateOptions o;
  o.focus = nlid::Focus::simulation;
  o.initial_condition = nlid::InitialCondition::equilibrium;
  CHECK_THROWS_WITH(nlid::estimate(Model{}, nlid::Dataset{ok}, o), Catch::Contains("use zero, measured or estimate"));
  o.initial_condition = nlid::InitialCondition::measured;
  CHECK_THROWS_WITH(nlid::estimate(Wiener{}, nlid::Dataset{ok}, o), Catch::Contains("not defined for a Hammerstein-Wiener"));
  nlid::EstimateOptions bad_fixed;
  bad_fixed.solver.fixed = {true, false};
  CHECK_THROWS_WITH(nlid::estimate(Model{}, nlid::Dataset{ok}, bad_fixed),
                    Catch::Contains("fixed has 2 entries; the model has 7 parameters"));
  // Mis-scaled data are named before the overflowing squares surface as an invalid
  // normalisation (sigmoid net) or a non-finite value in a nonlinearity's data (saturation).
  const nlid::Experiment big(random_steps(50, -1, 1, 7), 1e200 * random_steps(50, -1, 1, 9), 1.0, "big");
  CHECK_THROWS_WITH(nlid::estimate(Model{}, nlid::Dataset{ok, big}),
                    Catch::Contains("nonlinear ARX estimation: experiment 'big', output 'y'") && Catch::Contains("beyond 1e100"));
  CHECK_THROWS_WITH(nlid::estimate(Wiener{}, nlid::Dataset{big}),
                    Catch::Contains("Hammerstein-Wiener estimation: experiment 'big'") && Catch::Contains("beyond 1e100"));
}

TEST_CASE("a Hammerstein-Wiener delay as long as every record is refused before initialisation", "[models][estimate]") {
  // The series estimator ran in full on such data (found by tests/fuzz/spec_fuzz.cpp, wh with
  // nk = 40960 on 60 samples); Hammerstein-Wiener estimation stopped in its initialisation with
  // "too few samples to initialise the linear block". Both now say what is wrong.
  using TfLongDelay = nlid::TransferFunctionBlock<nlid::Dynamic, nlid::Dynamic, nlid::Dynamic>;
  using HwLongDelay = nlid::HammersteinWiener<nlid::UnitGain, TfLongDelay, nlid::Saturation>;
  const Eigen::MatrixXd u = random_steps(40, -1, 1, 5);
  Eigen::VectorXd y(40);
  for (int t = 0; t < 40; ++t) y(t) = std::tanh(u(t, 0));
  const nlid::Dataset d{nlid::Experiment(u, y, 1.0, "short")};
  const HwLongDelay late(nlid::UnitGain{}, TfLongDelay(1, 1, 40), nlid::Saturation{});
  CHECK_THROWS_WITH(nlid::estimate(late, d),
                    Catch::Contains("Hammerstein-Wiener model delays its input by 40 samples") &&
                        Catch::Contains("longest estimation record (40 samples)"));
}

TEST_CASE("more free parameters than residuals is refused before initialisation", "[models][estimate]") {
  // 20 samples, [2 2 1] lags: 18 residuals. A 3-unit network with linear term has 4 + 1 + 3·6 = 23
  // parameters; 2 units have 17.
  using Net3 = nlid::Nlarx<nlid::LaggedRegressors<2, 2, 1>, nlid::SigmoidNet<4, 3>>;
  using Net2 = nlid::Nlarx<nlid::LaggedRegressors<2, 2, 1>, nlid::SigmoidNet<4, 2>>;
  const Eigen::MatrixXd u = random_steps(20, -1, 1, 11);
  Eigen::VectorXd y(20);
  for (int t = 0; t < 20; ++t) y(t) = std::tanh(u(t, 0)) + 0.1 * t;
  const nlid::Dataset d{nlid::Experiment(u, y, 1.0, "short")};
  CHECK_THROWS_WITH(nlid::estimate(Net3{}, d),
                    Catch::Contains("nonlinear ARX model has 23 free parameters but the estimation data give only "
                                    "18 residuals (20 samples in 1 experiment, less 2 of lag history in each)"));
  CHECK_NOTHROW(nlid::estimate(Net2{}, d));
  // Fixed parameters are not free: holding 5 of the 23 brings the count to the 18 residuals.
  nlid::EstimateOptions o;
  o.solver.fixed.assign(23, false);
  for (int k = 0; k < 5; ++k) o.solver.fixed[static_cast<std::size_t>(k)] = true;
  CHECK_NOTHROW(nlid::estimate(Net3{}, d, o));
  // A run-time unit count that would take hours to initialise fails at once.
  using Net = nlid::SigmoidNet<nlid::Dynamic, nlid::Dynamic>;
  using Dyn = nlid::Nlarx<nlid::LaggedRegressors<2, 2, 1>, Net>;
  CHECK_THROWS_WITH(nlid::estimate(Dyn(nlid::LaggedRegressors<2, 2, 1>{}, Net(4, 100000)), d),
                    Catch::Contains("600005 free parameters") && Catch::Contains("use more data or a smaller model"));
  // Hammerstein-Wiener: 6 parameters on 5 samples.
  const nlid::Dataset five{nlid::Experiment(u.topRows(5), y.head(5), 1.0, "five")};
  CHECK_THROWS_WITH(nlid::estimate(Wiener{}, five),
                    Catch::Contains("Hammerstein-Wiener model has 6 free parameters but the estimation data give only 5 "
                                    "residuals (5 samples in 1 experiment)"));
}

TEST_CASE("missing samples are refused by name, a constant rest record is estimated, its fit undefined",
          "[models][estimate]") {
  using Net = nlid::Nlarx<nlid::LaggedRegressors<2, 2, 0>, nlid::SigmoidNet<4, 2>>;
  const Eigen::MatrixXd u = random_steps(300, -1, 1, 12);
  Eigen::VectorXd y(300);
  double s = 0.0;
  for (int t = 0; t < 300; ++t) y(t) = s = 0.8 * s + 0.2 * std::tanh(2.0 * u(t, 0));
  const nlid::Experiment good(u, y, 0.01, "steps");
  Eigen::VectorXd y_gap = y;
  y_gap(120) = std::numeric_limits<double>::quiet_NaN();
  const nlid::Experiment gap(u, y_gap, 0.01, "gap", nlid::NonFinitePolicy::keep);
  try {
    (void)nlid::estimate(Net{}, nlid::Dataset{good, gap});
    FAIL("no throw");
  } catch (const nlid::Error& e) {
    // Before: "SigmoidNet: non-finite value in y [at row 118]", a row of the regression matrix.
    CHECK_THAT(e.what(), Catch::Contains("experiment 'gap' has a missing output sample: 'y' is NaN at sample 120") &&
                             Catch::Contains("fill_missing()"));
    CHECK(e.where().experiment == 1);
    CHECK(e.where().row == 121);
  }
  Eigen::MatrixXd u_gap = u;
  u_gap(7, 0) = -std::numeric_limits<double>::infinity();
  CHECK_THROWS_WITH(nlid::estimate(Wiener{}, nlid::Dataset{nlid::Experiment(u_gap, y, 0.01, "", nlid::NonFinitePolicy::keep)}),
                    Catch::Contains("experiment 0 has a missing input sample: 'u' is -Inf at sample 7"));
  // A rest record (constant output) next to an informative one: the estimate is kept, and the
  // report says the rest record's fit is undefined instead of throwing after the solve.
  const nlid::Experiment rest(Eigen::MatrixXd::Zero(100, 1), Eigen::VectorXd::Zero(100), 0.01, "rest");
  const Net est = nlid::estimate(Net{}, nlid::Dataset{good, rest});
  REQUIRE(est.report().fit_percent.size() == 2);
  CHECK(est.report().fit_percent[0] > 90.0);
  CHECK(std::isnan(est.report().fit_percent[1]));
  CHECK_THAT(est.describe(), Catch::Contains("fit to rest (simulation): undefined (constant measured output)"));
  const Wiener hw = nlid::estimate(Wiener{}, nlid::Dataset{good, rest});
  CHECK(std::isnan(hw.report().fit_percent[1]));
}

TEST_CASE("simulation focus that cannot start says which experiment diverges", "[models][estimate]") {
  using Model = nlid::Nlarx<nlid::LaggedRegressors<1, 1, 0>, nlid::LinearMap<2>>;
  // An integrating-like system with a drift the one-step predictor fits but free run cannot follow
  // stably: start from an explicitly unstable model with initialize = false.
  Model start;
  start.set_parameters(Eigen::Vector3d(1.5, 1.0, 0.0));
  const nlid::Experiment e(random_steps(3000, -1, 1, 9), Eigen::VectorXd::Ones(3000), 1.0, "drift");
  nlid::EstimateOptions o;
  o.focus = nlid::Focus::simulation;
  o.initialize = false;
  CHECK_THROWS_WITH(nlid::estimate(start, nlid::Dataset{e}, o),
                    Catch::Contains("cannot start") && Catch::Contains("experiment 'drift'"));
}

TEST_CASE("simulation focus that cannot move from an over-sensitive start says why", "[models][estimate]") {
  // The study's nlarx2 (docs/guide.md §3): its prediction-focus model's free run changes by 0.2°
  // for a parameter change of 1e-10, so the simulation stage stalls at once with a gradient of
  // ~1e22. The report must say that, not only "stalled".
  const auto load = [](int i) {
    nlid::Experiment e = nlid::decimate(
        nlid::read_csv(std::string(NLID_TEST_DATA_DIR) + "/throttle/data" + std::to_string(i) + ".csv"), 10);
    e.set_name("data" + std::to_string(i));
    return e;
  };
  const nlid::Dataset est{load(1), load(2)};
  auto spring = nlid::custom_regressor<nlid::OutputLag<1>>(
      "max(y1(t-1),90)+min(y1(t-1),15)-105", [](auto y) { return nlid::max(y, 90.0) + nlid::min(y, 15.0) - 105.0; });
  nlid::RegressorSet with_spring{nlid::LaggedRegressors<2, 1, 0>{}, spring};
  nlid::EstimateOptions sim;
  sim.focus = nlid::Focus::simulation;
  const auto nlarx2 = nlid::estimate(nlid::Nlarx(with_spring, nlid::LinearMap<4>{}), est, sim);
  INFO(nlarx2.report().status);
  CHECK_THAT(nlarx2.report().status, Catch::Contains("stalled") && Catch::Contains("out of all proportion"));
  // A simulation stage that does move (nlarx1, no stop regressor) carries no such note.
  const auto nlarx1 = nlid::estimate(nlid::Nlarx<nlid::LaggedRegressors<2, 1, 0>, nlid::LinearMap<3>>{}, est, sim);
  INFO(nlarx1.report().status);
  CHECK_THAT(nlarx1.report().status, !Catch::Contains("out of all proportion"));
}
