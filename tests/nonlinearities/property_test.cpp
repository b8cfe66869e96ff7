// One generic property suite over every nonlinearity type (Sophus/manif style): sizes and
// names agree, forward-AD derivatives in θ and in x match central finite differences, fixed and
// dynamic duals agree, float evaluation tracks double, and initialize is deterministic.
#include <catch2/catch.hpp>

#include <cmath>
#include <random>
#include <span>
#include <type_traits>
#include <vector>

#include "nlid/nonlinearities.hpp"

namespace {

using nlid::Dynamic;

template <class F>
F make() {
  if constexpr (std::is_same_v<F, nlid::LinearMap<Dynamic>>) {
    return F(3);
  } else if constexpr (std::is_same_v<F, nlid::SigmoidNet<Dynamic, Dynamic>>) {
    return F(2, 3);
  } else if constexpr (std::is_same_v<F, nlid::WaveletNet<Dynamic, Dynamic>>) {
    return F(2, 2);
  } else if constexpr (std::is_same_v<F, nlid::PwLinear<Dynamic>>) {
    return F(4);
  } else if constexpr (std::is_same_v<F, nlid::Poly1d<Dynamic>>) {
    return F(3);
  } else if constexpr (std::is_same_v<F, nlid::TreePartition<Dynamic, Dynamic>>) {
    return F(2, 2);
  } else {
    return F{};
  }
}

// Data each type can fit: a smooth surface for the networks, the map's own shape for the
// piecewise 1-D maps (so initialize produces representative parameters).
template <class F>
void make_data(const F& f, Eigen::MatrixXd& X, Eigen::VectorXd& y) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  const int m = f.input_dimension();
  X.resize(240, m);
  y.resize(240);
  for (Eigen::Index i = 0; i < X.rows(); ++i) {
    for (int j = 0; j < m; ++j) X(i, j) = u(rng);
    const double x0 = X(i, 0);
    if constexpr (std::is_same_v<F, nlid::Saturation>) {
      y(i) = std::clamp(x0, -1.0, 1.2);
    } else if constexpr (std::is_same_v<F, nlid::DeadZone>) {
      y(i) = x0 < -0.5 ? x0 + 0.5 : (x0 > 0.7 ? x0 - 0.7 : 0.0);
    } else {
      y(i) = std::sin(1.3 * x0) + 0.3 * X(i, m - 1) * X(i, m - 1) + 0.2 * x0;
    }
  }
}

// Points where the map has kinks (derivatives are one-sided there): breakpoints and limits.
template <class F>
std::vector<double> kinks(const F& f, const std::vector<double>& th) {
  if constexpr (std::is_same_v<F, nlid::Saturation> || std::is_same_v<F, nlid::DeadZone>) {
    return {th[0], th[1]};
  } else if constexpr (std::is_same_v<F, nlid::PwLinear<5>> || std::is_same_v<F, nlid::PwLinear<Dynamic>>) {
    return f.breakpoints(th).first;
  } else {
    (void)f;
    (void)th;
    return {};
  }
}

template <class F>
struct Setup {
  F f = make<F>();
  std::vector<double> theta;
  std::vector<std::vector<double>> points;

  Setup() {
    Eigen::MatrixXd X;
    Eigen::VectorXd y;
    make_data(f, X, y);
    theta.assign(static_cast<std::size_t>(f.num_parameters()), 0.0);
    f.initialize(X, y, theta);
    // Move θ off the least-squares point so no derivative vanishes by optimality.
    for (std::size_t i = 0; i < theta.size(); ++i) theta[i] += 0.01 * static_cast<double>(static_cast<int>(i % 3) - 1);
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> u(-1.8, 1.8);
    const auto kk = kinks(f, theta);
    while (points.size() < 6) {
      std::vector<double> x(static_cast<std::size_t>(f.input_dimension()));
      for (auto& v : x) v = u(rng);
      bool near = false;
      for (double k : kk) near = near || std::abs(x[0] - k) < 1e-3;
      if (!near) points.push_back(x);
    }
  }

  double value(const std::vector<double>& x, const std::vector<double>& th) const {
    return f(std::span<const double>(x), std::span<const double>(th));
  }
};

}  // namespace

#define NLID_ALL_NONLINEARITIES                                                                      \
  nlid::UnitGain, nlid::LinearMap<3>, nlid::LinearMap<Dynamic>, (nlid::SigmoidNet<2, 3>),            \
      (nlid::SigmoidNet<3, 2, false>), (nlid::SigmoidNet<Dynamic, Dynamic>), (nlid::WaveletNet<2, 3>), \
      (nlid::WaveletNet<1, 2, false>), (nlid::WaveletNet<Dynamic, Dynamic>), nlid::PwLinear<5>,     \
      nlid::PwLinear<Dynamic>, nlid::Saturation, nlid::DeadZone, nlid::Poly1d<3>, nlid::Poly1d<Dynamic>,           \
      (nlid::TreePartition<2, 2>), (nlid::TreePartition<Dynamic, Dynamic>)

TEMPLATE_TEST_CASE("nonlinearity sizes, names and describe agree", "[nonlinearities][property]",
                   NLID_ALL_NONLINEARITIES) {
  Setup<TestType> s;
  const auto& f = s.f;
  if constexpr (TestType::num_params != Dynamic) CHECK(f.num_parameters() == TestType::num_params);
  if constexpr (TestType::num_inputs != Dynamic) CHECK(f.input_dimension() == TestType::num_inputs);
  const auto names = f.parameter_names();
  REQUIRE(static_cast<int>(names.size()) == f.num_parameters());
  for (std::size_t i = 0; i < names.size(); ++i) {
    for (std::size_t j = i + 1; j < names.size(); ++j) CHECK(names[i] != names[j]);
  }
  CHECK(!f.describe(s.theta).empty());
  for (double t : s.theta) CHECK(std::isfinite(t));
}

TEMPLATE_TEST_CASE("dual derivatives in theta match central differences", "[nonlinearities][property]",
                   NLID_ALL_NONLINEARITIES) {
  Setup<TestType> s;
  const int p = s.f.num_parameters();
  using D = nlid::DynamicDual<double>;
  for (const auto& x : s.points) {
    std::vector<D> xd(x.begin(), x.end());
    std::vector<D> td;
    for (int i = 0; i < p; ++i) td.push_back(D::variable(s.theta[static_cast<std::size_t>(i)], i, p));
    const D g = s.f(std::span<const D>(xd), std::span<const D>(td));
    CHECK(g.a == Approx(s.value(x, s.theta)).epsilon(1e-14).margin(1e-14));
    for (int i = 0; i < p; ++i) {
      auto tp = s.theta, tm = s.theta;
      const double h = 1e-6 * (1.0 + std::abs(s.theta[static_cast<std::size_t>(i)]));
      tp[static_cast<std::size_t>(i)] += h;
      tm[static_cast<std::size_t>(i)] -= h;
      const double fd = (s.value(x, tp) - s.value(x, tm)) / (2 * h);
      const double ad = g.v.size() ? g.v(i) : 0.0;
      INFO("parameter " << s.f.parameter_names()[static_cast<std::size_t>(i)]);
      CHECK(ad == Approx(fd).epsilon(1e-6).margin(1e-7));
    }
    // The fixed-size dual (the estimator's fast path) agrees with the dynamic one exactly.
    if constexpr (TestType::num_params != Dynamic && TestType::num_params > 0) {
      constexpr int P = TestType::num_params;
      using DF = nlid::Dual<double, P>;
      std::vector<DF> xf(x.begin(), x.end());
      std::vector<DF> tf;
      for (int i = 0; i < P; ++i) tf.push_back(DF::variable(s.theta[static_cast<std::size_t>(i)], i));
      const DF gf = s.f(std::span<const DF>(xf), std::span<const DF>(tf));
      CHECK(gf.a == g.a);
      for (int i = 0; i < P; ++i) CHECK(gf.v(i) == Approx(g.v.size() ? g.v(i) : 0.0).epsilon(1e-14).margin(1e-15));
    }
  }
}

TEMPLATE_TEST_CASE("dual derivatives in x match central differences", "[nonlinearities][property]",
                   NLID_ALL_NONLINEARITIES) {
  Setup<TestType> s;
  const int m = s.f.input_dimension();
  using D = nlid::DynamicDual<double>;
  const std::vector<D> td(s.theta.begin(), s.theta.end());
  for (const auto& x : s.points) {
    std::vector<D> xd;
    for (int j = 0; j < m; ++j) xd.push_back(D::variable(x[static_cast<std::size_t>(j)], j, m));
    const D g = s.f(std::span<const D>(xd), std::span<const D>(td));
    for (int j = 0; j < m; ++j) {
      auto xp = x, xm = x;
      const double h = 1e-6;
      xp[static_cast<std::size_t>(j)] += h;
      xm[static_cast<std::size_t>(j)] -= h;
      const double fd = (s.value(xp, s.theta) - s.value(xm, s.theta)) / (2 * h);
      const double ad = g.v.size() ? g.v(j) : 0.0;
      CHECK(ad == Approx(fd).epsilon(1e-6).margin(1e-7));
    }
  }
}

// The hand-written gradient (used by Nlarx's structured simulation Jacobian) against forward AD
// of operator(), for every type that has one.
TEMPLATE_TEST_CASE("analytic gradient equals the dual derivatives in theta and x", "[nonlinearities][property]",
                   (nlid::SigmoidNet<2, 3>), (nlid::SigmoidNet<3, 2, false>), (nlid::SigmoidNet<Dynamic, Dynamic>)) {
  Setup<TestType> s;
  const int p = s.f.num_parameters();
  const int m = s.f.input_dimension();
  using D = nlid::DynamicDual<double>;
  for (const auto& x : s.points) {
    std::vector<D> td, xd;
    for (int i = 0; i < p; ++i) td.push_back(D::variable(s.theta[static_cast<std::size_t>(i)], i, p + m));
    for (int j = 0; j < m; ++j) xd.push_back(D::variable(x[static_cast<std::size_t>(j)], p + j, p + m));
    const D g = s.f(std::span<const D>(xd), std::span<const D>(td));
    std::vector<double> g_theta(static_cast<std::size_t>(p)), g_x(static_cast<std::size_t>(m));
    const double v = s.f.gradient(std::span<const double>(x), std::span<const double>(s.theta), std::span<double>(g_theta),
                                  std::span<double>(g_x));
    CHECK(v == s.value(x, s.theta));  // bitwise operator()'s value
    for (int i = 0; i < p; ++i) {
      INFO("parameter " << s.f.parameter_names()[static_cast<std::size_t>(i)]);
      CHECK(g_theta[static_cast<std::size_t>(i)] == Approx(g.v(i)).epsilon(1e-12).margin(1e-14));
    }
    for (int j = 0; j < m; ++j) {
      INFO("input " << j);
      CHECK(g_x[static_cast<std::size_t>(j)] == Approx(g.v(p + j)).epsilon(1e-12).margin(1e-14));
    }
  }
}

TEMPLATE_TEST_CASE("float evaluation tracks double", "[nonlinearities][property]", NLID_ALL_NONLINEARITIES) {
  Setup<TestType> s;
  const std::vector<float> tf(s.theta.begin(), s.theta.end());
  for (const auto& x : s.points) {
    const std::vector<float> xf(x.begin(), x.end());
    const float g = s.f(std::span<const float>(xf), std::span<const float>(tf));
    const double ref = s.value(x, s.theta);
    CHECK(static_cast<double>(g) == Approx(ref).epsilon(2e-4).margin(2e-4));
  }
}

TEMPLATE_TEST_CASE("initialize is deterministic", "[nonlinearities][property]", NLID_ALL_NONLINEARITIES) {
  Eigen::MatrixXd X;
  Eigen::VectorXd y;
  auto f1 = make<TestType>();
  make_data(f1, X, y);
  auto f2 = f1;
  std::vector<double> t1(static_cast<std::size_t>(f1.num_parameters())), t2(t1.size());
  f1.initialize(X, y, t1);
  f2.initialize(X, y, t2);
  CHECK(t1 == t2);
  // Re-initialising the same object on the same data reproduces θ too.
  std::vector<double> t3(t1.size());
  f1.initialize(X, y, t3);
  CHECK(t1 == t3);
}

TEMPLATE_TEST_CASE("a NaN input stays NaN and a far input gives no NaN", "[nonlinearities][property]",
                   NLID_ALL_NONLINEARITIES) {
  // A free run treats a non-finite output as divergence; a map that turned NaN into a number
  // (DeadZone did: both comparisons false, so 0) let a broken simulation continue from invented
  // values. Far from the data a map must extrapolate, not read inf·0 (WaveletNet did at 1e155).
  Setup<TestType> s;
  const auto m = static_cast<std::size_t>(s.f.input_dimension());
  CHECK(std::isnan(s.value(std::vector<double>(m, std::nan("")), s.theta)));
  for (const double far : {1e200, -1e200, 1e300}) {
    CAPTURE(far);
    CHECK_FALSE(std::isnan(s.value(std::vector<double>(m, far), s.theta)));
  }
  using D = nlid::Dual<double, 1>;
  std::vector<D> xd(m, D::variable(std::nan(""), 0));
  std::vector<D> td(s.theta.begin(), s.theta.end());
  CHECK(std::isnan(s.f(std::span<const D>(xd), std::span<const D>(td)).a));
}
