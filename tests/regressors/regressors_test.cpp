// Regressor layer: names (getreg), values, history requirements, Dynamic twin, AD, bad input.
#include <catch2/catch.hpp>

#include <cmath>

#include "nlid/regressors.hpp"

using nlid::Dynamic;

namespace {
// The study's hard-spring regressor.
auto spring() {
  return nlid::custom_regressor<nlid::OutputLag<1>>(
      "max(y1(t-1),90)+min(y1(t-1),15)-105",
      [](auto y1) { return nlid::max(y1, 90.0) + nlid::min(y1, 15.0) - 105.0; });
}

Eigen::MatrixXd test_inputs(int n) {
  Eigen::MatrixXd u(n, 2);
  for (int t = 0; t < n; ++t) {
    u(t, 0) = std::sin(0.3 * t) + 0.1 * t;
    u(t, 1) = std::cos(0.7 * t);
  }
  return u;
}
Eigen::VectorXd test_outputs(int n) {
  Eigen::VectorXd y(n);
  for (int t = 0; t < n; ++t) y(t) = 50.0 + 45.0 * std::sin(0.11 * t);
  return y;
}
}  // namespace

TEST_CASE("standard regressors carry the toolbox's names and sizes", "[regressors]") {
  using R = nlid::LaggedRegressors<2, 1, 0>;
  static_assert(R::num_regressors == 3 && R::max_output_lag == 2 && R::max_input_lag == 0);
  static_assert(nlid::Regressor<R>);
  R r;
  CHECK(nlid::regressor_names(r) == std::vector<std::string>{"y1(t-1)", "y1(t-2)", "u1(t)"});
  CHECK(nlid::history_length(r) == 2);

  using R2 = nlid::LaggedRegressors<3, 3, 2>;
  static_assert(R2::num_regressors == 6 && R2::max_input_lag == 4);
  CHECK(R2{}.names({"cmd"}, "angle") ==
        std::vector<std::string>{"angle(t-1)", "angle(t-2)", "angle(t-3)", "cmd(t-2)", "cmd(t-3)",
                                 "cmd(t-4)"});
}

TEST_CASE("regressors read the right samples of measured data", "[regressors]") {
  const Eigen::MatrixXd u = test_inputs(30);
  const Eigen::VectorXd y = test_outputs(30);
  nlid::RegressorSet regs{nlid::OutputLags<2>{}, nlid::InputLags<2, 1, 0>{},
                          nlid::InputLags<1, 0, 1>{}, spring()};
  static_assert(decltype(regs)::num_regressors == 6);
  static_assert(decltype(regs)::max_output_lag == 2 && decltype(regs)::max_input_lag == 2);
  CHECK(regs.num_input_channels() == 2);
  CHECK(nlid::regressor_names(regs) ==
        std::vector<std::string>{"y1(t-1)", "y1(t-2)", "u1(t-1)", "u1(t-2)", "u2(t)",
                                 "max(y1(t-1),90)+min(y1(t-1),15)-105"});
  const Eigen::MatrixXd x = nlid::regressor_matrix(regs, u, y);
  REQUIRE(x.rows() == 28);
  REQUIRE(x.cols() == 6);
  for (int i = 0; i < 28; ++i) {
    const int t = i + 2;
    CHECK(x(i, 0) == y(t - 1));
    CHECK(x(i, 1) == y(t - 2));
    CHECK(x(i, 2) == u(t - 1, 0));
    CHECK(x(i, 3) == u(t - 2, 0));
    CHECK(x(i, 4) == u(t, 1));
    CHECK(x(i, 5) == std::max(y(t - 1), 90.0) + std::min(y(t - 1), 15.0) - 105.0);
  }
}

TEST_CASE("hard-spring custom regressor: values and one-sided slopes on duals", "[regressors]") {
  auto s = spring();
  static_assert(decltype(s)::max_output_lag == 1 && decltype(s)::max_input_lag == 0);
  using D = nlid::Dual<double, 1>;
  struct W {
    using Scalar = D;
    D value;
    D y(int) const { return value; }
    D u(int, int) const { return D(0.0); }
  };
  const double ys[] = {10.0, 50.0, 95.0};
  const double values[] = {-5.0, 0.0, 5.0};
  const double slopes[] = {1.0, 0.0, 1.0};
  for (int i = 0; i < 3; ++i) {
    D out[1];
    s.evaluate(W{D::variable(ys[i], 0)}, std::span<D>(out, 1));
    CHECK(out[0].a == Approx(values[i]));
    CHECK(out[0].v[0] == slopes[i]);
  }
}

TEST_CASE("custom regressor default name lists its arguments", "[regressors]") {
  auto c = nlid::custom_regressor<nlid::OutputLag<1>, nlid::InputLag<2, 1>>(
      "", [](auto y, auto u) { return y * u; });
  static_assert(decltype(c)::max_input_lag == 2);
  CHECK(c.num_input_channels() == 2);
  CHECK(c.names({"a", "b"}, "out") == std::vector<std::string>{"f(out(t-1),b(t-2))"});
}

TEST_CASE("a regressor function must be generic over the scalar", "[regressors]") {
  auto generic = [](auto y) { return y * y; };
  auto double_only = [](double y) { return y * y; };
  static_assert(nlid::RegressorFunction<decltype(generic), 1>);
  static_assert(!nlid::RegressorFunction<decltype(double_only), 1>);
  static_assert(!nlid::RegressorFunction<decltype(generic), 2>);
  // A result that merely converts to the dual is a constant there: the derivative would be lost.
  auto returns_double = [](auto y) -> double { return nlid::value_of(y) * 2.0; };
  auto double_only_inside = [](auto y) { return std::floor(nlid::value_of(y)); };
  static_assert(!nlid::RegressorFunction<decltype(returns_double), 1>);
  static_assert(!nlid::RegressorFunction<decltype(double_only_inside), 1>);
  // Piecewise constant, written to return the argument's type; a reference to it is that type too.
  auto piecewise_constant = [](auto y) { return decltype(y)(std::floor(nlid::value_of(y))); };
  auto by_reference = [](const auto& y) -> const auto& { return y; };
  static_assert(nlid::RegressorFunction<decltype(piecewise_constant), 1>);
  static_assert(nlid::RegressorFunction<decltype(by_reference), 1>);
  // On a float this function returns double (float · double): float results are converted by
  // evaluate, not checked by the concept, as before.
  const auto c = nlid::custom_regressor<nlid::OutputLag<1>>("", [](auto y) { return y * 2.0 - 190.0; });
  const std::vector<float> past{100.0f, 0.0f};
  struct FloatWindow {
    using Scalar = float;
    const std::vector<float>* y_;
    float y(int lag) const { return (*y_)[static_cast<std::size_t>(lag - 1)]; }
    float u(int, int) const { return 0.0f; }
  };
  float out = 0.0f;
  c.evaluate(FloatWindow{&past}, std::span<float>(&out, 1));
  CHECK(out == 10.0f);
  // The study's hard-stop regressor with integer or double limits compiles on every scalar
  // (nlid::max(float, double) and nlid::max(double, int) did not).
  const auto stops = nlid::custom_regressor<nlid::OutputLag<1>>(
      "", [](auto y) { return nlid::max(y, 90.0) + nlid::min(y, 15) - 105; });
  stops.evaluate(FloatWindow{&past}, std::span<float>(&out, 1));
  CHECK(out == 10.0f);  // 100 + 15 - 105
}

TEST_CASE("history ring buffer keeps the last L values in lag order", "[regressors]") {
  nlid::History<double, 3> h;
  nlid::History<double, Dynamic> hd(3);
  for (int k = 1; k <= 5; ++k) {
    h.push(k);
    hd.push(k);
  }
  CHECK(h(1) == 5.0);
  CHECK(h(2) == 4.0);
  CHECK(h(3) == 3.0);
  CHECK(hd(1) == 5.0);
  CHECK(hd(3) == 3.0);
  nlid::History<double, 0> empty;
  empty.push(1.0);  // no history needed: nothing is stored, nothing breaks
  CHECK(empty.length() == 0);
  CHECK_THROWS_WITH((nlid::History<double, 3>(2)), Catch::Contains("compile-time length 3"));
}

TEST_CASE("Dynamic twin gives identical regressors", "[regressors]") {
  const Eigen::MatrixXd u = test_inputs(40);
  const Eigen::VectorXd y = test_outputs(40);
  nlid::LaggedRegressors<3, 2, 1> fixed;
  nlid::LaggedRegressors<Dynamic, Dynamic, Dynamic> dyn(3, 2, 1);
  static_assert(decltype(dyn)::num_regressors == Dynamic);
  CHECK(dyn.size() == 5);
  CHECK(nlid::regressor_names(dyn) == nlid::regressor_names(fixed));
  CHECK(nlid::regressor_matrix(dyn, u, y) == nlid::regressor_matrix(fixed, u, y));
}

TEST_CASE("bad orders and bad data are reported with what and where", "[regressors]") {
  CHECK_THROWS_WITH((nlid::LaggedRegressors<Dynamic, Dynamic, Dynamic>(2, -1, 0)),
                    Catch::Contains("model order nb must be >= 0") && Catch::Contains("parameter 'nb'"));
  CHECK_THROWS_WITH((nlid::LaggedRegressors<2, Dynamic, 0>(3, 1, 0)),
                    Catch::Contains("na = 3 differs from its compile-time value 2"));
  // Orders beyond the largest model order are refused as RegressorList refuses them; two
  // accepted huge orders made input_lag() = nk + nb − 1 overflow int (negative history).
  CHECK_THROWS_WITH((nlid::InputLags<Dynamic, Dynamic>(2000000000, 2000000000)),
                    Catch::Contains("model order nb must be <= 100000") && Catch::Contains("parameter 'nb'"));
  CHECK_THROWS_WITH((nlid::LaggedRegressors<Dynamic, Dynamic, Dynamic>(1, 1, nlid::max_model_order + 1)),
                    Catch::Contains("parameter 'nk'"));
  CHECK_THROWS_WITH((nlid::OutputLags<Dynamic>(nlid::max_model_order + 1)), Catch::Contains("parameter 'na'"));
  CHECK(nlid::InputLags<Dynamic, Dynamic>(nlid::max_model_order, nlid::max_model_order).input_lag() ==
        2 * nlid::max_model_order - 1);
  nlid::LaggedRegressors<4, 2, 0> r;
  const Eigen::MatrixXd u = test_inputs(4);
  const Eigen::VectorXd y = test_outputs(4);
  CHECK_THROWS_WITH(nlid::regressor_matrix(r, u.leftCols(1), y, nlid::at_experiment(2)),
                    Catch::Contains("not more than the 4 needed by the regressor lags") &&
                        Catch::Contains("experiment 2"));
  nlid::RegressorSet two{nlid::InputLags<1, 0, 1>{}};
  CHECK_THROWS_WITH(nlid::regressor_matrix(two, test_inputs(10).leftCols(1), test_outputs(10)),
                    Catch::Contains("read 2 input channel(s) but the data have 1"));
}

TEST_CASE("simulation window serves the initial input window before t = 0", "[regressors]") {
  Eigen::MatrixXd u(3, 1);
  u << 1, 2, 3;
  nlid::History<double, 2> h;
  h.push(-2.0);  // y(-2)
  h.push(-1.0);  // y(-1)
  const double u_past[] = {-10.0, -20.0};  // u(-1), u(-2)
  nlid::SimulationWindow<double, 2> w(u, h, std::span<const double>(u_past, 2), 2);
  w.set_time(0);
  CHECK(w.y(1) == -1.0);
  CHECK(w.y(2) == -2.0);
  CHECK(w.u(0, 0) == 1.0);
  CHECK(w.u(0, 1) == -10.0);
  CHECK(w.u(0, 2) == -20.0);
  w.set_time(1);
  CHECK(w.u(0, 1) == 1.0);
  CHECK(w.u(0, 2) == -10.0);
  nlid::SimulationWindow<double, 2> zero(u, h, {}, 2);
  zero.set_time(0);
  CHECK(zero.u(0, 2) == 0.0);
}
