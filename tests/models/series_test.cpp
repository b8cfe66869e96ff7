// Series<Blocks...>: block equations against filter/map references, the HammersteinWiener
// equivalence, scalar genericity with the Jacobian against central differences, fixed vs Dynamic
// twins, initial conditions, the BLA split helpers, known-answer estimation (Wiener-Hammerstein,
// Hammerstein) and bad input with message checks.
#include <catch2/catch.hpp>

#include <cmath>
#include <limits>
#include <random>
#include <string>

#include "nlid/analysis/fit.hpp"
#include "nlid/linear/output_error.hpp"
#include "nlid/linear/polynomial.hpp"
#include "nlid/models/hammerstein_wiener.hpp"
#include "nlid/models/series.hpp"
#include "nlid/models/series_estimate.hpp"
#include "nlid/nonlinearities/linear.hpp"
#include "nlid/nonlinearities/piecewise_linear.hpp"
#include "nlid/nonlinearities/polynomial.hpp"
#include "nlid/nonlinearities/saturation.hpp"
#include "nlid/nonlinearities/unit_gain.hpp"
#include "test_inputs.hpp"
#include "../support/block_models.hpp"

using nlid::Dynamic;

namespace {
using Tf220 = nlid::TransferFunctionBlock<2, 2, 1>;
using Tf210 = nlid::TransferFunctionBlock<2, 1, 0>;
using TfD = nlid::TransferFunctionBlock<Dynamic, Dynamic, Dynamic>;
using Wh = nlid::WienerHammerstein<Tf220, nlid::Poly1d<3>, Tf210>;
using WhD = nlid::WienerHammerstein<TfD, nlid::Poly1d<Dynamic>, TfD>;

// Truth of the known-answer tests (tests/support/block_models.hpp).
using nlid_test::wiener_hammerstein_theta;

Eigen::MatrixXd gaussian_input(int n, unsigned seed, double sd = 0.4) {
  std::mt19937 gen(seed);
  std::normal_distribution<double> nd(0.0, sd);
  Eigen::MatrixXd u(n, 1);
  for (int t = 0; t < n; ++t) u(t, 0) = nd(gen);
  return u;
}

// Reference: filter, polynomial, filter (the textbook Wiener-Hammerstein model).
Eigen::VectorXd wh_reference(const Eigen::MatrixXd& u, const Eigen::VectorXd& th) {
  Eigen::VectorXd b1(3), f1(3), b2(2), f2(2);
  b1 << 0, th(0), th(1);
  f1 << 1, th(2), th(3);
  b2 << th(8), th(9);
  f2 << 1, th(10);
  const Eigen::VectorXd x = nlid::filter(b1, f1, Eigen::VectorXd(u.col(0)));
  Eigen::VectorXd v(x.size());
  for (Eigen::Index t = 0; t < x.size(); ++t) v(t) = th(4) + x(t) * (th(5) + x(t) * (th(6) + x(t) * th(7)));
  return nlid::filter(b2, f2, v);
}

nlid::Experiment simulate_truth(const Eigen::MatrixXd& u, double ts = 0.01) {
  return nlid::Experiment(u, wh_reference(u, wiener_hammerstein_theta()), ts, "wh");
}

template <class T>
std::span<const T> cspan(const std::vector<T>& v) {
  return {v.data(), v.size()};
}
}  // namespace

TEST_CASE("a series delaying its input by every record's length is refused before initialisation", "[models][series]") {
  // Found by tests/fuzz/spec_fuzz.cpp (wh:nb=4,nf=2,nk=40960:poly1d:8:nb=4,nf=3,nk=6 fitted to 60
  // samples): the estimation ran in full although no output sample depends on the input.
  const nlid::Dataset sixty(simulate_truth(gaussian_input(60, 3)));
  const WhD late(TfD(2, 2, 30), nlid::Poly1d<Dynamic>(3), TfD(2, 1, 30));
  CHECK_THROWS_WITH(nlid::estimate(late, sixty),
                    Catch::Contains("Wiener-Hammerstein model delays its input by 60 samples") &&
                        Catch::Contains("no output sample depends on the input"));
  WhD late_copy = late;
  CHECK_THROWS_WITH(nlid::initialize_series(late_copy, sixty), Catch::Contains("delays its input by 60 samples"));
  nlid::SeriesEstimateOptions one;
  one.solver.max_iterations = 1;
  CHECK_NOTHROW(nlid::estimate(WhD(TfD(2, 2, 30), nlid::Poly1d<Dynamic>(3), TfD(2, 1, 29)), sixty, one));
}

TEST_CASE("series sizes, aliases, roles and names", "[models][series]") {
  static_assert(Wh::num_params == 11 && Wh::num_states == 3 && Wh::num_blocks == 3);
  static_assert(WhD::num_params == Dynamic && WhD::num_states == Dynamic);
  static_assert(nlid::ModelStructure<Wh> && nlid::Model<Wh> && nlid::ModelStructure<WhD>);
  static_assert(std::is_same_v<nlid::Hammerstein<nlid::Poly1d<2>, Tf210>, nlid::Series<nlid::Poly1d<2>, Tf210>>);
  static_assert(Wh::is_linear<0> && !Wh::is_linear<1> && Wh::is_linear<2>);
  static_assert(nlid::SeriesBlock<Tf220> && nlid::SeriesBlock<nlid::Saturation> && !nlid::SeriesBlock<double>);
  Wh m;
  CHECK(Wh::pattern() == "LNL");
  CHECK(Wh::kind() == "Wiener-Hammerstein");
  CHECK(nlid::Wiener<Tf210, nlid::Saturation>::kind() == "Wiener");
  CHECK(nlid::Hammerstein<nlid::Poly1d<2>, Tf210>::kind() == "Hammerstein");
  CHECK(m.parameter_offset(1) == 4);
  CHECK(m.parameter_offset(2) == 8);
  CHECK(m.state_offset(2) == 2);
  CHECK(m.state_dimension() == 3);
  const auto names = m.parameter_names();
  REQUIRE(names.size() == 11);
  CHECK(names[0] == "linear1:b1");
  CHECK(names[4] == "static:c[0]");
  CHECK(names[10] == "linear2:f1");
  CHECK(m.describe().find("Wiener-Hammerstein model (y1 = G2(q) [g1(G1(q) u1)])") != std::string::npos);
}

TEST_CASE("Wiener-Hammerstein simulation equals filter, polynomial, filter", "[models][series]") {
  Wh m;
  m.set_parameters(wiener_hammerstein_theta());
  const Eigen::MatrixXd u = gaussian_input(400, 1);
  const Eigen::VectorXd ref = wh_reference(u, wiener_hammerstein_theta());
  std::vector<double> y(400);
  REQUIRE(m.simulate<double>(u, nlid::detail::as_const_span(m.parameters()), {}, std::span<double>(y)));
  for (int t = 0; t < 400; ++t) REQUIRE(y[static_cast<std::size_t>(t)] == Approx(ref(t)).margin(1e-12));
  // The intermediate signals: column k is block k's output.
  const Eigen::MatrixXd sig = m.signals(u, nlid::detail::as_const_span(m.parameters()), {});
  CHECK(sig.cols() == 3);
  CHECK((sig.col(2) - ref).cwiseAbs().maxCoeff() < 1e-12);
}

TEST_CASE("an N-L-N series is the HammersteinWiener model", "[models][series]") {
  using S = nlid::HammersteinWienerSeries<nlid::PwLinear<3>, Tf220, nlid::Saturation>;
  using H = nlid::HammersteinWiener<nlid::PwLinear<3>, Tf220, nlid::Saturation>;
  static_assert(S::num_params == H::num_params);
  S s;
  H h;
  Eigen::VectorXd th(12);
  th << -1, 0, 0, -1, 0, 1.5, 0.5, 0.25, -1.5, 0.7, -1, 2;
  s.set_parameters(th);
  h.set_parameters(th);
  const Eigen::MatrixXd u = gaussian_input(300, 2, 1.0);
  std::vector<double> ys(300), yh(300);
  s.simulate<double>(u, nlid::detail::as_const_span(th), {}, std::span<double>(ys));
  h.simulate<double>(u, nlid::detail::as_const_span(th), {}, std::span<double>(yh));
  CHECK(ys == yh);
  CHECK(s.parameter_names() == h.parameter_names());
  CHECK(s.linear_offset() == h.linear_offset());
  CHECK(s.output_offset() == h.output_offset());
  CHECK(s.state_dimension() == h.state_dimension());
  const auto xs = s.equilibrium_state<double>(0.4, nlid::detail::as_const_span(th));
  const auto xh = h.equilibrium_state<double>(0.4, nlid::detail::as_const_span(th));
  CHECK((xs - xh).norm() < 1e-14);
  // The HammersteinWiener accessors exist on the series too.
  CHECK(s.linear_parameters().size() == 4);
  CHECK(s.input_parameters().size() == 6);
  CHECK(s.output_parameters()[1] == 2.0);
  Eigen::VectorXd b(3), f(3);
  b << 0, 0.2, 0.1;
  f << 1, -0.5, 0.1;
  s.set_linear_polynomials(b, f);
  CHECK(s.linear_parameters()[0] == 0.2);
  CHECK(s.linear_parameters()[3] == 0.1);
}

TEST_CASE("series on double, float and Dual, Jacobian vs central differences", "[models][series]") {
  Wh m;
  const Eigen::VectorXd th = wiener_hammerstein_theta();
  const Eigen::MatrixXd u = gaussian_input(120, 3);
  std::vector<double> y(120);
  REQUIRE(m.simulate<double>(u, nlid::detail::as_const_span(th), {}, std::span<double>(y)));
  std::vector<float> thf(th.data(), th.data() + th.size()), yf(120);
  REQUIRE(m.simulate<float>(u, cspan(thf), {}, std::span<float>(yf)));
  for (int t = 0; t < 120; ++t) CHECK(yf[static_cast<std::size_t>(t)] == Approx(y[static_cast<std::size_t>(t)]).margin(1e-4));
  using D = nlid::Dual<double, 11>;
  std::vector<D> thd(11), yd(120);
  for (int i = 0; i < 11; ++i) thd[static_cast<std::size_t>(i)] = D::variable(th(i), i);
  REQUIRE(m.simulate<D>(u, cspan(thd), {}, std::span<D>(yd)));
  for (int i = 0; i < 11; ++i) {
    const double h = 1e-6;
    Eigen::VectorXd tp = th, tm = th;
    tp(i) += h;
    tm(i) -= h;
    std::vector<double> yp(120), ym(120);
    m.simulate<double>(u, nlid::detail::as_const_span(tp), {}, std::span<double>(yp));
    m.simulate<double>(u, nlid::detail::as_const_span(tm), {}, std::span<double>(ym));
    for (int t = 0; t < 120; t += 7) {
      const double fd = (yp[static_cast<std::size_t>(t)] - ym[static_cast<std::size_t>(t)]) / (2 * h);
      REQUIRE(yd[static_cast<std::size_t>(t)].v(i) == Approx(fd).margin(1e-6).epsilon(1e-5));
    }
  }
}

TEST_CASE("fixed and Dynamic series simulate identically", "[models][series]") {
  Wh m;
  m.set_parameters(wiener_hammerstein_theta());
  WhD d(TfD(2, 2, 1), nlid::Poly1d<Dynamic>(3), TfD(2, 1, 0));
  d.set_parameters(wiener_hammerstein_theta());
  REQUIRE(d.state_dimension() == 3);
  const Eigen::MatrixXd u = gaussian_input(500, 4);
  const nlid::Experiment e(u, Eigen::MatrixXd::Zero(500, 1), 0.01);
  const Eigen::MatrixXd ym = m.simulate(e), yd = d.simulate(e);
  CHECK((ym - yd).cwiseAbs().maxCoeff() <= 1e-12);
  const Eigen::MatrixXd em = m.simulate(e, nlid::InitialCondition::equilibrium);
  const Eigen::MatrixXd ed = d.simulate(e, nlid::InitialCondition::equilibrium);
  CHECK((em - ed).cwiseAbs().maxCoeff() <= 1e-12);
}

TEST_CASE("series initial conditions: equilibrium holds still, estimate recovers, measured is refused",
          "[models][series]") {
  Wh m;
  m.set_parameters(wiener_hammerstein_theta());
  const nlid::Experiment still(Eigen::MatrixXd::Constant(50, 1, 0.7), Eigen::MatrixXd::Zero(50, 1), 0.01);
  const Eigen::MatrixXd y = m.simulate(still, nlid::InitialCondition::equilibrium);
  CHECK((y.array() - y(0, 0)).abs().maxCoeff() < 1e-12);
  CHECK(std::abs(y(0, 0)) > 0.1);  // not trivially zero
  // A record that starts from a non-rest state: the estimated x0 reproduces it.
  const Eigen::MatrixXd u = gaussian_input(300, 5);
  Eigen::VectorXd x0(3);
  x0 << 0.3, -0.2, 0.5;
  std::vector<double> yt(300);
  m.simulate<double>(u, nlid::detail::as_const_span(m.parameters()), nlid::detail::as_const_span(x0), std::span<double>(yt));
  const nlid::Experiment rec(u, Eigen::Map<Eigen::MatrixXd>(yt.data(), 300, 1), 0.01);
  const Eigen::VectorXd xe = m.initial_state(rec, nlid::InitialCondition::estimate);
  CHECK((xe - x0).norm() < 1e-6);
  try {
    (void)m.simulate(rec, nlid::InitialCondition::measured);
    FAIL("measured must be refused");
  } catch (const nlid::Error& err) {
    CHECK(std::string(err.what()).find("Wiener-Hammerstein model's state is internal") != std::string::npos);
  }
}

TEST_CASE("root grouping and split enumeration keep conjugate pairs together", "[models][series]") {
  Eigen::VectorXcd r(5);
  r << std::complex<double>(0.6, 0.3), 0.5, std::complex<double>(0.6, -0.3), std::complex<double>(-0.2, 0.1),
      std::complex<double>(-0.2, -0.1);
  const auto g = nlid::detail::group_roots(r);
  REQUIRE(g.size() == 3);
  CHECK(g[0].size == 2);
  CHECK(g[1].size == 1);
  // Capacities 2 and 3 hold 5 roots exactly: pair+real | pair, real+pair | pair, pair | pair+real …
  const auto a = nlid::detail::assign_groups(g, {2, 3}, 1000);
  int exact = 0, halved = 0;
  for (const auto& s : a) {
    bool whole = true;
    for (int v : s) {
      whole = whole && v >= 0;
      halved += v <= -2 ? 1 : 0;
    }
    if (whole) ++exact;
    std::vector<int> room{2, 3};
    for (std::size_t k = 0; k < s.size(); ++k) {
      if (s[k] >= 0) room[static_cast<std::size_t>(s[k])] -= g[k].size;
      if (s[k] <= -2) room[static_cast<std::size_t>(-2 - s[k])] -= 1;
    }
    CHECK(room[0] >= 0);
    CHECK(room[1] >= 0);
  }
  CHECK(exact == 2);  // {A}|{real, B} and {B}|{real, A}: the only splits that keep every root whole
  CHECK(halved > 0);  // {real, |A|}|{B} is offered too: a close pair may stand for two real poles
  const Eigen::VectorXd p = nlid::detail::polynomial_of(g, a.front(), 0, 3);
  CHECK(p(0) == 1.0);
}

TEST_CASE("known Wiener-Hammerstein system recovered from its data (> 99.9 % validation fit)",
          "[models][series][estimate]") {
  const nlid::Experiment est = simulate_truth(gaussian_input(3000, 11));
  const nlid::Experiment val = simulate_truth(gaussian_input(2000, 12));
  nlid::SeriesEstimateOptions o;
  o.solver.max_iterations = 100;
  std::vector<std::string> stages;
  o.progress = [&](const std::string& s) { stages.push_back(s); };
  const Wh m = nlid::estimate(Wh{}, nlid::Dataset(est), o);
  const Eigen::MatrixXd yv = m.simulate(val);
  const double fit = nlid::fit_percent(Eigen::VectorXd(val.y().col(0)), Eigen::VectorXd(yv.col(0)));
  INFO(m.describe());
  CHECK(fit > 99.9);
  REQUIRE(stages.size() >= 2);
  CHECK(stages[0].find("best linear approximation [nb nf nk] = [3 3 1]") != std::string::npos);
  CHECK(m.report().estimated);
  CHECK(m.report().status.find("initialisation: BLA fit") != std::string::npos);
  CHECK(m.ts() == 0.01);
  // The split put the complex pair into G1 and the real pole into G2, as in the truth.
  const auto [b2, f2] = m.block_polynomials<2>();
  CHECK(f2(1) == Approx(-0.6).margin(1e-3));
}

TEST_CASE("known Hammerstein system recovered with a Dynamic structure", "[models][series][estimate]") {
  using H = nlid::Hammerstein<nlid::Poly1d<Dynamic>, TfD>;
  H truth(nlid::Poly1d<Dynamic>(3), TfD(2, 2, 0));
  Eigen::VectorXd th(8);
  th << 0.1, 1.0, 0.4, -0.3, 0.3, 0.15, -1.1, 0.4;  // f(u) = 0.1 + u + 0.4u² − 0.3u³; G = (0.3 + 0.15q⁻¹)/(1 − 1.1q⁻¹ + 0.4q⁻²)
  truth.set_parameters(th);
  auto make = [&](unsigned seed) {
    const Eigen::MatrixXd u = gaussian_input(2000, seed, 0.8);
    std::vector<double> y(2000);
    truth.simulate<double>(u, nlid::detail::as_const_span(th), {}, std::span<double>(y));
    return nlid::Experiment(u, Eigen::Map<Eigen::MatrixXd>(y.data(), 2000, 1), 1.0);
  };
  const nlid::Experiment est = make(21), val = make(22);
  nlid::SeriesEstimateOptions o;
  o.solver.max_iterations = 100;
  const H m = nlid::estimate(H(nlid::Poly1d<Dynamic>(3), TfD(2, 2, 0)), nlid::Dataset(est), o);
  const Eigen::MatrixXd yv = m.simulate(val);
  CHECK(nlid::fit_percent(Eigen::VectorXd(val.y().col(0)), Eigen::VectorXd(yv.col(0))) > 99.9);
}

TEST_CASE("unit-slope static blocks get their scale from the data: Wiener and Hammerstein with a saturation",
          "[models][series][estimate]") {
  // The throttle's shape: a positive input (a motor command, 0 … 1) and an output in degrees
  // between hard stops. A saturation has slope 1, so the linear block must carry the whole gain
  // (DC gain 100 here). Scaled to unit RMS as for a network, the saturation saw a signal the
  // size of u against a target in the tens: its least-squares limits collapsed to one value, a
  // constant model the solver could not leave (fit below 0 %).
  using W = nlid::Wiener<Tf220, nlid::Saturation>;
  W truth;
  Eigen::VectorXd th(6);
  th << 20.0, 10.0, -1.2, 0.5, 15.0, 90.0;  // G = (20 q⁻¹ + 10 q⁻²)/(1 − 1.2 q⁻¹ + 0.5 q⁻²), stops 15 and 90
  truth.set_parameters(th);
  auto make = [&](const auto& model, const Eigen::VectorXd& theta, unsigned seed, double mean, double sd) {
    Eigen::MatrixXd u = gaussian_input(3000, seed, sd);
    u.array() += mean;
    std::vector<double> y(3000);
    model.template simulate<double>(u, nlid::detail::as_const_span(theta), {}, std::span<double>(y));
    return nlid::Experiment(u, Eigen::Map<Eigen::MatrixXd>(y.data(), 3000, 1), 0.01);
  };
  nlid::SeriesEstimateOptions o;
  o.solver.max_iterations = 60;
  {
    const nlid::Experiment est = make(truth, th, 31, 0.5, 0.35), val = make(truth, th, 32, 0.5, 0.35);
    const W m = nlid::estimate(W{}, nlid::Dataset(est), o);
    INFO(m.describe());
    CHECK(nlid::fit_percent(Eigen::VectorXd(val.y().col(0)), Eigen::VectorXd(m.simulate(val).col(0))) > 99.0);
    const Eigen::VectorXd p = m.parameters();
    CHECK(std::min(p(4), p(5)) == Approx(15.0).margin(0.5));
    CHECK(std::max(p(4), p(5)) == Approx(90.0).margin(0.5));
  }
  {
    // Hammerstein: the gain goes to the linear block after the saturation.
    using H = nlid::Hammerstein<nlid::Saturation, Tf220>;
    H htruth;
    Eigen::VectorXd hth(6);
    hth << 0.2, 0.8, 20.0, 10.0, -1.2, 0.5;  // saturation [0.2, 0.8], then G
    htruth.set_parameters(hth);
    const nlid::Experiment est = make(htruth, hth, 33, 0.5, 0.35), val = make(htruth, hth, 34, 0.5, 0.35);
    const H m = nlid::estimate(H{}, nlid::Dataset(est), o);
    INFO(m.describe());
    CHECK(nlid::fit_percent(Eigen::VectorXd(val.y().col(0)), Eigen::VectorXd(m.simulate(val).col(0))) > 99.0);
  }
}

TEST_CASE("series rejects bad input with located messages", "[models][series]") {
  Wh m;
  auto message = [](auto&& f) {
    try {
      f();
    } catch (const nlid::Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  CHECK(message([&] { m.set_parameters(Eigen::VectorXd::Zero(3)); }).find("parameter vector has 3 values, the model has 11") !=
        std::string::npos);
  CHECK(message([&] { m.set_block_parameters(1, std::vector<double>(2)); }).find("block 1 (static) has 4 parameters, got 2") !=
        std::string::npos);
  const nlid::Experiment two(Eigen::MatrixXd::Zero(20, 2), Eigen::MatrixXd::Zero(20, 1), 0.01, "two");
  CHECK(message([&] { (void)m.simulate(two); }).find("experiment 'two' has 2 input(s) but the Wiener-Hammerstein model reads 1") !=
        std::string::npos);
  Wh timed;
  timed.set_ts(0.1);
  const nlid::Experiment fast(Eigen::MatrixXd::Zero(20, 1), Eigen::MatrixXd::Zero(20, 1), 0.01, "fast");
  CHECK(message([&] { (void)timed.simulate(fast); }).find("sample time 0.01 s but the model's is 0.1 s") !=
        std::string::npos);
  using Wide = nlid::Series<Tf210, nlid::LinearMap<Dynamic>>;
  CHECK(message([&] { Wide w(Tf210{}, nlid::LinearMap<Dynamic>(2)); }).find("the output nonlinearity must have one input, it has 2") !=
        std::string::npos);
  nlid::SeriesEstimateOptions o;
  o.initial_condition = nlid::InitialCondition::measured;
  CHECK(message([&] { (void)nlid::estimate(Wh{}, nlid::Dataset(simulate_truth(gaussian_input(200, 9))), o); })
            .find("measured is not defined for a Wiener-Hammerstein model") != std::string::npos);
  // 11 parameters on 10 samples: refused by estimate and by initialize_series alone.
  const nlid::Dataset ten(simulate_truth(gaussian_input(10, 4)));
  CHECK(message([&] { (void)nlid::estimate(Wh{}, ten); })
            .find("Wiener-Hammerstein model has 11 free parameters but the estimation data give only 10 residuals") !=
        std::string::npos);
  Wh w;
  CHECK(message([&] { (void)nlid::initialize_series(w, ten); }).find("11 free parameters") != std::string::npos);
  // Parameters held by solver.fixed are not estimated: with two of them fixed, 9 free parameters
  // fit on 10 samples in both (initialize_series counted all 11 and refused what estimate accepts).
  nlid::SeriesEstimateOptions held;
  held.solver.fixed.assign(11, false);
  held.solver.fixed[0] = held.solver.fixed[1] = true;
  CHECK(message([&] { (void)nlid::initialize_series(w, ten, held); }).find("free parameters") == std::string::npos);
  nlid::Experiment gap = simulate_truth(gaussian_input(200, 5));
  Eigen::MatrixXd yg = gap.y();
  yg(42, 0) = std::numeric_limits<double>::quiet_NaN();
  const nlid::Experiment with_gap(gap.u(), yg, gap.ts(), "gap", nlid::NonFinitePolicy::keep);
  CHECK(message([&] { (void)nlid::estimate(Wh{}, nlid::Dataset(with_gap)); })
            .find("experiment 'gap' has a missing output sample: 'y' is NaN at sample 42") != std::string::npos);
}

TEST_CASE("Series: the only linear block is set from an estimated OutputError model", "[models][series]") {
  // oe() on noise-free data of B = 0.5 q^-1 + 0.25 q^-2, F = 1 - 1.5 q^-1 + 0.7 q^-2; the block
  // reads the toolbox polynomials (OutputError::f() leaves out F's leading 1).
  const nlid::OutputError oe = nlid::oe(nlid::Dataset(nlid_test::known_bf_record(400, 0.05, 13, 0.4, "bf")), {2, 2, 1});
  nlid::Hammerstein<nlid::Poly1d<2>, Tf220> m;
  m.set_linear_block(oe);
  const auto lin = m.block_parameters(1);
  const std::vector<double> want{0.5, 0.25, -1.5, 0.7};
  REQUIRE(lin.size() == want.size());
  for (std::size_t i = 0; i < want.size(); ++i) CHECK(lin[i] == Approx(want[i]).margin(1e-6));
}
