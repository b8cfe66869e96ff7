// Linearisation: exact AD matrices vs central finite differences (Nlarx with a custom regressor,
// Hammerstein-Wiener with curved maps, grey-box throttle discrete and continuous); linear
// nonlinearities give exactly the known linear model (poles, frequency response); equilibria
// and the input for a wanted output; bad input.
#include <catch2/catch.hpp>

#include <cmath>
#include <complex>

#include "nlid/analysis/linearize.hpp"
#include "nlid/models/equilibrium.hpp"
#include "nlid/models/physics/throttle.hpp"
#include "nlid/models/transfer_function_block.hpp"
#include "nlid/nonlinearities/linear.hpp"
#include "nlid/nonlinearities/polynomial.hpp"
#include "nlid/nonlinearities/saturation.hpp"
#include "nlid/nonlinearities/unit_gain.hpp"
#include "nlid/regressors.hpp"

namespace {
using cd = std::complex<double>;

template <class M>
concept LinearizesAtEquilibrium = requires(const M& m, const Eigen::VectorXd& u) { nlid::linearize_at_equilibrium(m, u); };
template <class M>
concept LinearizesAtEquilibriumWithTs = requires(const M& m, const Eigen::VectorXd& u) {
  nlid::linearize_at_equilibrium(m, u, 0.01);
};

// Central differences of map(x, u) -> [y; x_next] w.r.t. [x; u].
template <class Map>
Eigen::MatrixXd fd_jacobian(const Eigen::VectorXd& z0, int nout, Map map, double h = 1e-6) {
  Eigen::MatrixXd J(nout, z0.size());
  for (Eigen::Index j = 0; j < z0.size(); ++j) {
    Eigen::VectorXd zp = z0, zm = z0;
    const double s = h * (1.0 + std::abs(z0(j)));
    zp(j) += s;
    zm(j) -= s;
    J.col(j) = (map(zp) - map(zm)) / (2 * s);
  }
  return J;
}

Eigen::MatrixXd stacked(const nlid::StateSpace& ss) {
  const auto nx = ss.order(), nu = ss.num_inputs(), ny = ss.num_outputs();
  Eigen::MatrixXd J(ny + nx, nx + nu);
  J << ss.c(), ss.d(), ss.a(), ss.b();
  return J;
}

// Discrete frequency response of the state-space model at e^{iw}.
cd freq(const nlid::StateSpace& ss, double w) {
  const Eigen::Index n = ss.order();
  const cd z = std::polar(1.0, w);
  const Eigen::MatrixXcd M = z * Eigen::MatrixXcd::Identity(n, n) - ss.a().cast<cd>();
  const Eigen::VectorXcd x = M.fullPivLu().solve(ss.b().col(0).cast<cd>());
  return (ss.c().row(0).cast<cd>() * x)(0) + ss.d()(0, 0);
}

// Matrix exponential by scaling and squaring with a Taylor series (small matrices only).
Eigen::MatrixXd expm(const Eigen::MatrixXd& A) {
  int s = 0;
  double nrm = A.cwiseAbs().rowwise().sum().maxCoeff();
  while (nrm > 0.1) { nrm /= 2; ++s; }
  const Eigen::MatrixXd B = A / std::pow(2.0, s);
  Eigen::MatrixXd E = Eigen::MatrixXd::Identity(A.rows(), A.cols()), term = E;
  for (int k = 1; k < 25; ++k) { term = term * B / k; E += term; }
  for (int i = 0; i < s; ++i) E = E * E;
  return E;
}

auto coupling() {
  return nlid::custom_regressor<nlid::OutputLag<1>, nlid::InputLag<1>>(
      "tanh(y1(t-1))*u1(t-1)", [](auto y1, auto u) { using std::tanh; return tanh(y1) * u; });
}
}  // namespace

TEST_CASE("Nlarx with a linear map linearises to exactly its ARX model", "[analysis][linearize]") {
  using Model = nlid::Nlarx<nlid::LaggedRegressors<2, 2, 1>, nlid::LinearMap<4>>;
  Model m(nlid::LaggedRegressors<2, 2, 1>{}, nlid::LinearMap<4>{}, 0.01);
  Eigen::VectorXd th(5);
  th << 1.5, -0.7, 0.4, 0.25, 3.0;  // y = 1.5y1 - 0.7y2 + 0.4u(t-1) + 0.25u(t-2) + 3
  m.set_parameters(th);
  const nlid::Linearization L = nlid::linearize_at_equilibrium(m, Eigen::VectorXd::Constant(1, 2.0));
  CHECK(L.at_equilibrium());
  // Equilibrium: y = (0.65·2 + 3)/(1 − 0.8) = 21.5.
  CHECK(L.point.y(0) == Approx(21.5).epsilon(1e-10));
  REQUIRE(L.discrete.order() == 4);
  CHECK(L.state_names == std::vector<std::string>{"y1(t-1)", "y1(t-2)", "u1(t-1)", "u1(t-2)"});
  CHECK(L.discrete.d()(0, 0) == 0.0);
  for (double w : {0.01, 0.3, 1.0, 2.5}) {
    const cd zi = std::polar(1.0, -w);
    const cd h = (0.4 * zi + 0.25 * zi * zi) / (1.0 - 1.5 * zi + 0.7 * zi * zi);
    CHECK(std::abs(freq(L.discrete, w) - h) < 1e-12 * std::abs(h));
  }
  // Poles: roots of z^2 - 1.5z + 0.7 plus two at the origin (the input lag states).
  const Eigen::VectorXcd p = L.discrete.poles();
  int at_root = 0, at_zero = 0;
  const cd r1(0.75, std::sqrt(0.7 - 0.75 * 0.75));
  for (Eigen::Index i = 0; i < p.size(); ++i) {
    if (std::abs(p(i)) < 1e-10) ++at_zero;
    if (std::abs(p(i) - r1) < 1e-10 || std::abs(p(i) - std::conj(r1)) < 1e-10) ++at_root;
  }
  CHECK(at_root == 2);
  CHECK(at_zero == 2);
}

TEST_CASE("Nlarx with a custom regressor: AD Jacobian equals central differences", "[analysis][linearize]") {
  using Regs = nlid::RegressorSet<nlid::LaggedRegressors<2, 1, 0>, decltype(coupling())>;
  using Model = nlid::Nlarx<Regs, nlid::LinearMap<4>>;
  Model m(Regs(nlid::LaggedRegressors<2, 1, 0>{}, coupling()), nlid::LinearMap<4>{}, 0.05);
  Eigen::VectorXd th(5);
  th << 1.1, -0.35, 0.3, 0.4, 0.05;
  m.set_parameters(th);
  REQUIRE(m.state_dimension() == 3);  // y(t-1), y(t-2), u(t-1)
  const Eigen::Vector3d x0(0.6, 0.2, -0.4);
  const Eigen::VectorXd u0 = Eigen::VectorXd::Constant(1, 0.7);
  const nlid::Linearization L = nlid::linearize(m, x0, u0);
  CHECK_FALSE(L.at_equilibrium());
  auto map = [&](const Eigen::VectorXd& z) {
    Eigen::VectorXd out(4);
    std::vector<double> th_v(th.data(), th.data() + th.size());
    out(0) = nlid::detail::nlarx_step<double>(m, z.data(), z.data() + 3, std::span<const double>(th_v), out.data() + 1);
    return out;
  };
  Eigen::VectorXd z(4);
  z << x0, u0;
  const Eigen::MatrixXd Jfd = fd_jacobian(z, 4, map);
  CHECK((stacked(L.discrete) - Jfd).cwiseAbs().maxCoeff() < 1e-8);
  // y0 is the model's one-step output, the drift its state update.
  CHECK(L.point.y(0) == Approx(map(z)(0)).epsilon(1e-15));
  // Known entries: dy/dy(t-1) = 1.1 + 0.4 u(t-1) (1 - tanh^2 y(t-1)); dy/du(t) = 0.3.
  CHECK(L.discrete.c()(0, 0) == Approx(1.1 + 0.4 * -0.4 * (1 - std::pow(std::tanh(0.6), 2))).epsilon(1e-14));
  CHECK(L.discrete.d()(0, 0) == Approx(0.3).epsilon(1e-14));
  CHECK(L.discrete.b()(2, 0) == 1.0);  // u(t) becomes u(t-1)
}

TEST_CASE("Hammerstein-Wiener with unit gains linearises to exactly B/F", "[analysis][linearize]") {
  using Block = nlid::TransferFunctionBlock<2, 2, 1>;
  using Model = nlid::HammersteinWiener<nlid::UnitGain, Block, nlid::UnitGain>;
  Model m(nlid::UnitGain{}, Block{}, nlid::UnitGain{}, 0.01);
  Eigen::VectorXd th(4);
  th << 0.3, 0.15, -1.2, 0.5;  // B = 0.3 + 0.15 q^-1, F = 1 - 1.2 q^-1 + 0.5 q^-2, nk = 1
  m.set_parameters(th);
  const nlid::Linearization L = nlid::linearize_at_equilibrium(m, Eigen::VectorXd::Constant(1, 1.0));
  CHECK(L.at_equilibrium());
  CHECK(L.point.y(0) == Approx(0.45 / 0.3).epsilon(1e-12));
  for (double w : {0.02, 0.5, 1.7, 3.0}) {
    const cd zi = std::polar(1.0, -w);
    const cd h = zi * (0.3 + 0.15 * zi) / (1.0 - 1.2 * zi + 0.5 * zi * zi);
    CHECK(std::abs(freq(L.discrete, w) - h) < 1e-12 * std::abs(h));
  }
}

TEST_CASE("Hammerstein-Wiener with curved maps: AD equals finite differences, gains scale", "[analysis][linearize]") {
  using Block = nlid::TransferFunctionBlock<2, 2, 0>;
  using Model = nlid::HammersteinWiener<nlid::Poly1d<3>, Block, nlid::Saturation>;
  Model m(nlid::Poly1d<3>{}, Block{}, nlid::Saturation{}, 0.02);
  Eigen::VectorXd th(10);
  th << 0.1, 1.0, 0.5, 0.2,  // f(u) = 0.1 + u + 0.5u^2 + 0.2u^3
      0.4, 0.2, -0.9, 0.2,   // B, F
      -5.0, 5.0;             // saturation limits
  m.set_parameters(th);
  const Eigen::Vector2d x0(0.3, -0.1);
  const Eigen::VectorXd u0 = Eigen::VectorXd::Constant(1, 0.8);
  const nlid::Linearization L = nlid::linearize(m, x0, u0);
  auto map = [&](const Eigen::VectorXd& z) {
    Eigen::VectorXd out(3);
    std::vector<double> s(z.data(), z.data() + 2);
    const double uu = z(2);
    const double w = m.input_nonlinearity()(std::span<const double>(&uu, 1), m.input_parameters());
    const double xl = m.linear_block().step(std::span<double>(s), w, m.linear_parameters());
    out(0) = m.output_nonlinearity()(std::span<const double>(&xl, 1), m.output_parameters());
    out(1) = s[0];
    out(2) = s[1];
    return out;
  };
  Eigen::VectorXd z(3);
  z << x0, u0;
  CHECK((stacked(L.discrete) - fd_jacobian(z, 3, map)).cwiseAbs().maxCoeff() < 1e-7);
  // D = h'(x) * b1 * f'(u0) with h' = 1 inside the limits.
  CHECK(L.discrete.d()(0, 0) == Approx(0.4 * (1.0 + 2 * 0.5 * 0.8 + 3 * 0.2 * 0.64)).epsilon(1e-13));
}

TEST_CASE("grey-box throttle: discrete and continuous linearisation at an equilibrium", "[analysis][linearize]") {
  nlid::GreyBox<nlid::physics::Throttle> g;
  Eigen::VectorXd p(7);
  p << 20.0, 100.0, 1e4, 7000.0, 15.0, 90.0, 10.0;  // y_eq = 10 + 70 u between the stops
  g.set_parameters(p);
  const double ts = 0.01;
  const nlid::OperatingPoint op = nlid::equilibrium_for_output(g, 45.0, 0.3);
  CHECK(op.u(0) == Approx(0.5).epsilon(1e-8));
  CHECK(op.x(0) == Approx(45.0).epsilon(1e-9));
  const nlid::Linearization L = nlid::linearize(g, op.x, op.u, ts);
  REQUIRE(L.continuous);
  CHECK(L.at_equilibrium());
  CHECK(L.state_names == std::vector<std::string>{"y", "v"});
  // Between the stops the contact term is negligible: A_c = [[0, 1], [-k, -c]], B_c = [0; b].
  const auto& c = *L.continuous;
  CHECK(c.a(0, 0) == 0.0);
  CHECK(c.a(0, 1) == 1.0);
  CHECK(c.a(1, 0) == Approx(-100.0).epsilon(1e-9));
  CHECK(c.a(1, 1) == Approx(-20.0).epsilon(1e-12));
  CHECK(c.b(1, 0) == Approx(7000.0).epsilon(1e-12));
  CHECK(c.c(0, 0) == 1.0);
  // Discrete = derivative of one RK4 sample: FD of that map, and ≈ exp(A_c ts) (RK4 accuracy).
  const Eigen::VectorXd pv = g.parameters();
  const int sub = g.substeps(ts);
  auto map = [&](const Eigen::VectorXd& z) {
    Eigen::VectorXd out(3);
    g.physics().output(z.data(), z.data() + 2, pv.data(), out.data());
    Eigen::VectorXd x = z.head(2);
    nlid::detail::greybox_sample<double>(g, pv.data(), z.data() + 2, x, ts, sub);
    out(1) = x(0);  // element-wise: GCC 12 misreports a packet store into tail(2)
    out(2) = x(1);
    return out;
  };
  Eigen::VectorXd z(3);
  z << op.x, op.u;
  CHECK((stacked(L.discrete) - fd_jacobian(z, 3, map, 1e-5)).cwiseAbs().maxCoeff() < 1e-5);
  CHECK((L.discrete.a() - expm(c.a * ts)).cwiseAbs().maxCoeff() < 1e-6);
  // Static gain dy/du = b/k = 70 °/unit, continuous and discrete alike.
  CHECK(L.discrete.dc_gain()(0, 0) == Approx(70.0).epsilon(1e-8));
  CHECK(L.describe().find("continuous poles") != std::string::npos);
}

TEST_CASE("grey-box throttle at a stop: contact stiffness enters A", "[analysis][linearize]") {
  nlid::GreyBox<nlid::physics::Throttle> g;
  Eigen::VectorXd p(7);
  p << 20.0, 100.0, 1e4, 7000.0, 15.0, 90.0, 10.0;
  g.set_parameters(p);
  // u = 3 drives y past 90: k(y − 10) + K(y − 90) = 21000 → y ≈ 91.3, 17 contact widths deep
  const nlid::Linearization L = nlid::linearize_at_equilibrium(g, Eigen::VectorXd::Constant(1, 3.0), 0.01);
  CHECK(L.point.y(0) == Approx(922000.0 / 10100.0).epsilon(1e-6));
  // Without the sample time the call itself is refused (it compiled into the sampled models'
  // template and failed deep inside it).
  static_assert(!LinearizesAtEquilibrium<decltype(g)>);
  static_assert(LinearizesAtEquilibriumWithTs<decltype(g)>);
  CHECK(L.continuous->a(1, 0) == Approx(-(100.0 + 1e4)).epsilon(1e-6));
}

TEST_CASE("trajectory states and equilibria agree with the models' own simulation", "[analysis][linearize]") {
  using Block = nlid::TransferFunctionBlock<2, 2, 0>;
  using Model = nlid::HammersteinWiener<nlid::UnitGain, Block, nlid::UnitGain>;
  Model m(nlid::UnitGain{}, Block{}, nlid::UnitGain{}, 0.01);
  Eigen::VectorXd th(4);
  th << 0.5, 0.1, -1.1, 0.3;
  m.set_parameters(th);
  Eigen::MatrixXd u(50, 1);
  for (int t = 0; t < 50; ++t) u(t, 0) = std::sin(0.2 * t);
  const nlid::Experiment e(u, Eigen::VectorXd::Zero(50), 0.01, "sine");
  const Eigen::VectorXd s = nlid::trajectory_state(m, e, 20);
  const nlid::Linearization L = nlid::linearize(m, s, e.u().row(20).transpose());
  CHECK(L.point.y(0) == Approx(m.simulate(e)(20, 0)).epsilon(1e-12));
  // Equilibrium of the HW: held simulation stays put.
  const nlid::OperatingPoint op = nlid::equilibrium(m, Eigen::VectorXd::Constant(1, 0.4));
  CHECK(op.y(0) == Approx(0.4 * 0.6 / 0.2).epsilon(1e-12));
}

TEST_CASE("Linearization::describe prints the static gain of every output", "[analysis][linearize]") {
  // x(t+1) = 0.5 x + u, y1 = x, y2 = 3x: gains 2 and 6 (only the first was printed).
  nlid::Linearization L;
  L.discrete = nlid::StateSpace(Eigen::MatrixXd::Constant(1, 1, 0.5), Eigen::MatrixXd::Ones(1, 1),
                                (Eigen::MatrixXd(2, 1) << 1.0, 3.0).finished(), Eigen::MatrixXd::Zero(2, 1), 0.1);
  L.point = {Eigen::VectorXd::Zero(1), Eigen::VectorXd::Zero(1), Eigen::VectorXd::Zero(2)};
  const std::string d = L.describe();
  CHECK_THAT(d, Catch::Contains("static gain dy/du (one row per output, one column per input):\n    y1: [2]\n    y2: [6]\n"));
  L.discrete = nlid::StateSpace(Eigen::MatrixXd::Constant(1, 1, 0.5), Eigen::MatrixXd::Ones(1, 1),
                                Eigen::MatrixXd::Ones(1, 1), Eigen::MatrixXd::Zero(1, 1), 0.1);
  L.point.y = Eigen::VectorXd::Zero(1);
  CHECK_THAT(L.describe(), Catch::Contains("static gain dy/du: [2]\n"));
}

TEST_CASE("trajectory_state of an Nlarx needs a sample inside the experiment", "[analysis][linearize]") {
  // The lag window exists at t = N, but the documented next step, linearize(model, x,
  // e.u().row(t)), would read past the input's end: t = N is refused like the other models do.
  using Model = nlid::Nlarx<nlid::LaggedRegressors<2, 1, 0>, nlid::LinearMap<3>>;
  const Model m(nlid::LaggedRegressors<2, 1, 0>{}, nlid::LinearMap<3>{}, 0.01);
  Eigen::MatrixXd u(10, 1);
  for (int t = 0; t < 10; ++t) u(t, 0) = 0.1 * t;
  const nlid::Experiment e(u, Eigen::VectorXd::LinSpaced(10, 0.0, 1.0), 0.01, "ramp");
  const Eigen::VectorXd x = nlid::trajectory_state(m, e, 9);
  CHECK(nlid::linearize(m, x, e.u().row(9).transpose()).point.x == x);
  CHECK_THROWS_WITH(nlid::trajectory_state(m, e, 10), Catch::Contains("sample 10 is outside the experiment (10 samples)"));
  CHECK_THROWS_WITH(nlid::trajectory_state(m, e, -1), Catch::Contains("sample -1 is outside the experiment"));
}

TEST_CASE("linearize rejects bad input with located messages", "[analysis][linearize]") {
  using Model = nlid::Nlarx<nlid::LaggedRegressors<2, 1, 0>, nlid::LinearMap<3>>;
  Model m(nlid::LaggedRegressors<2, 1, 0>{}, nlid::LinearMap<3>{});
  CHECK_THROWS_WITH(nlid::linearize(m, Eigen::VectorXd::Zero(3), Eigen::VectorXd::Zero(1)),
                    Catch::Contains("the state has 2 entries"));
  CHECK_THROWS_WITH(nlid::linearize(m, Eigen::VectorXd::Zero(2), Eigen::VectorXd::Zero(1)),
                    Catch::Contains("has no sample time"));
  nlid::GreyBox<nlid::physics::Throttle> g;
  CHECK_THROWS_WITH(nlid::linearize(g, Eigen::VectorXd::Zero(2), Eigen::VectorXd::Zero(2), 0.01),
                    Catch::Contains("takes 1 input(s), got 2"));
  // A NaN in the input was reported as "not differentiable", at parameter 'x0'.
  try {
    (void)nlid::linearize(g, Eigen::Vector2d(20.0, 0.0), Eigen::VectorXd::Constant(1, std::nan("")), 0.01);
    FAIL("accepted");
  } catch (const nlid::Error& e) {
    CHECK(e.where().parameter == "u0");
    CHECK_THAT(e.message(), Catch::Contains("input u0[0] is not finite"));
  }
  CHECK_THROWS_WITH(nlid::linearize(g, Eigen::Vector2d(std::nan(""), 0.0), Eigen::VectorXd::Zero(1), 0.01),
                    Catch::Contains("state entry x0[0] is not finite"));
  // A saturated output cannot reach 5: the inverse problem reports the closest value.
  // (two F coefficients: GCC 12 gives a false -Warray-bounds for a one-state block's step)
  using Hw = nlid::HammersteinWiener<nlid::UnitGain, nlid::TransferFunctionBlock<1, 2, 0>, nlid::Saturation>;
  Hw hw(nlid::UnitGain{}, nlid::TransferFunctionBlock<1, 2, 0>{}, nlid::Saturation{}, 0.1);
  Eigen::VectorXd th(5);
  th << 0.5, -0.5, 0.0, 0.0, 1.0;
  hw.set_parameters(th);
  CHECK(nlid::equilibrium_for_output(hw, 0.25, 0.0).u(0) == Approx(0.25).epsilon(1e-9));
  CHECK_THROWS_WITH(nlid::equilibrium_for_output(hw, 5.0, 0.3), Catch::Contains("no constant input found"));
  // A two-input model: said up front (it read "the model reads 2 input(s), got 1 value(s)").
  using TwoInputs = nlid::Nlarx<nlid::RegressorSet<nlid::OutputLags<1>, nlid::InputLags<1, 0, 0>, nlid::InputLags<1, 0, 1>>,
                                nlid::LinearMap<3>>;
  TwoInputs two;
  two.set_parameters(Eigen::Vector4d(0.5, 0.2, 0.3, 0.0));
  CHECK_THROWS_WITH(nlid::equilibrium_for_output(two, 1.0, 0.3),
                    Catch::Contains("the model reads 2 inputs; this search varies one input"));
}
