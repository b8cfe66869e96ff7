// Expression regressors: values, Dual derivatives vs central differences, errors with column,
// run-time regressor lists equal to compile-time sets.
#include <catch2/catch.hpp>

#include <cmath>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "nlid/ad/dual.hpp"
#include "nlid/regressors/custom.hpp"
#include "nlid/regressors/expression.hpp"
#include "nlid/regressors/lagged.hpp"
#include "nlid/regressors/regressor_set.hpp"

using nlid::Expression;

namespace {

double eval(const std::string& text, std::vector<double> v) {
  const Expression e = Expression::parse(text);
  return e.evaluate_values<double>(v);
}

// The column an expression error reports (-1 if none was thrown).
long error_column(const std::string& text, std::string* message = nullptr) {
  try {
    (void)Expression::parse(text);
  } catch (const nlid::Error& e) {
    if (message != nullptr) *message = e.what();
    return e.where().column;
  }
  return -1;
}

}  // namespace

TEST_CASE("expression: values of operators, precedence and functions") {
  CHECK(eval("1+2*3", {}) == 7.0);
  CHECK(eval("(1+2)*3", {}) == 9.0);
  CHECK(eval("-2^2", {}) == -4.0);  // ^ binds tighter than unary minus (MATLAB)
  CHECK(eval("2^3^2", {}) == 512.0);  // right associative
  CHECK(eval("2^-1", {}) == 0.5);
  CHECK(eval("8/4/2", {}) == 1.0);  // left associative
  CHECK(eval("10-4-3", {}) == 3.0);
  CHECK(eval("1.5e2 + .5", {}) == 150.5);
  CHECK(eval("abs(-3)+sqrt(16)+exp(0)+log(1)", {}) == 8.0);
  CHECK(eval("sign(-2)+sign(0)+sign(5)", {}) == 0.0);
  CHECK(eval("min(3,4)+max(3,4)+pow(2,10)", {}) == 3.0 + 4.0 + 1024.0);
  CHECK(eval("tanh(0)+sin(0)+cos(0)", {}) == 1.0);
  CHECK(eval("--3", {}) == 3.0);
  CHECK(eval(" + 3 ", {}) == 3.0);
}

TEST_CASE("expression: the study's hard-stop regressor reads y1(t-1) and matches the lambda bit for bit") {
  const Expression e = Expression::parse("max(y1(t-1),90)+min(y1(t-1),15)-105");
  REQUIRE(e.signals().size() == 1);
  CHECK(e.signals()[0].is_output);
  CHECK(e.signals()[0].lag == 1);
  CHECK(e.output_lag() == 1);
  CHECK(e.input_lag() == 0);
  CHECK(e.num_input_channels() == 0);
  const auto lambda = [](auto y) { return nlid::max(y, 90.0) + nlid::min(y, 15.0) - 105.0; };
  for (double y : {-20.0, 0.0, 15.0, 15.000000001, 47.3, 89.9999, 90.0, 93.7, 1e6}) {
    std::vector<double> v{y};
    CHECK(e.evaluate_values<double>(v) == lambda(y));
  }
  CHECK(eval("max(y1(t-1),90)+min(y1(t-1),15)-105", {50.0}) == 0.0);
  CHECK(eval("max(y1(t-1),90)+min(y1(t-1),15)-105", {95.0}) == 5.0);
  CHECK(eval("max(y1(t-1),90)+min(y1(t-1),15)-105", {10.0}) == -5.0);
}

TEST_CASE("expression: signals, channel names and lags") {
  const Expression e = Expression::parse("u2(t-3)*y1(t-2) + u1(t) + y1(t-2)");
  REQUIRE(e.signals().size() == 3);  // y1(t-2) appears twice but is one signal
  CHECK(e.output_lag() == 2);
  CHECK(e.input_lag() == 3);
  CHECK(e.num_input_channels() == 2);
  std::vector<double> v{2.0, 3.0, 5.0};  // u2(t-3), y1(t-2), u1(t)
  CHECK(e.evaluate_values<double>(v) == 2.0 * 3.0 + 5.0 + 3.0);

  const Expression named = Expression::parse("angle(t-1) * command(t)", {"command"}, "angle");
  REQUIRE(named.signals().size() == 2);
  CHECK(named.signals()[0].is_output);
  CHECK(!named.signals()[1].is_output);
  CHECK(named.signals()[1].channel == 0);
  CHECK(Expression::parse("y1( t - 4 )").output_lag() == 4);
  CHECK(Expression::parse("y1(t-1)").is_signal());
  CHECK(!Expression::parse("y1(t-1)*2").is_signal());
}

TEST_CASE("expression: evaluation on float and on a lag window") {
  const Expression e = Expression::parse("y1(t-1)^2 - 3*u1(t-1)");
  std::vector<float> vf{2.0f, 1.0f};
  CHECK(e.evaluate_values<float>(vf) == Approx(1.0f));

  Eigen::MatrixXd u(4, 1);
  u << 1, 2, 3, 4;
  Eigen::VectorXd y(4);
  y << 10, 20, 30, 40;
  nlid::MeasuredWindow<double> w(u, y);
  w.set_time(2);
  CHECK(e.evaluate(w) == 20.0 * 20.0 - 3.0 * 2.0);
}

TEST_CASE("expression: Dual derivatives equal central finite differences") {
  using D = nlid::Dual<double, 2>;
  const std::vector<std::string> texts{
      "max(y1(t-1),90)+min(y1(t-1),15)-105", "y1(t-1)^3 - 2*u1(t)/y1(t-1)", "tanh(0.3*y1(t-1)) * exp(-u1(t)^2)",
      "sqrt(abs(y1(t-1))) + log(2 + sin(u1(t))) + cos(y1(t-1)*u1(t))", "pow(y1(t-1), u1(t)) + sign(u1(t))*3",
      "(y1(t-1) - u1(t)) / (1 + y1(t-1)^2)"};
  const std::vector<std::vector<double>> points{{1.3, 0.4}, {95.0, 0.7}, {7.0, -0.2}, {2.2, 1.1}};
  for (const auto& text : texts) {
    const Expression e = Expression::parse(text);
    for (auto p : points) {
      if (e.signals().size() != 2) p.resize(e.signals().size());
      // signals() order is the order of first appearance; the tests above use y1 first.
      std::vector<D> dv;
      for (std::size_t i = 0; i < p.size(); ++i) dv.push_back(D::variable(p[i], static_cast<int>(i), 2));
      const D r = e.evaluate_values<D>(dv);
      CHECK(r.a == e.evaluate_values<double>(p));
      for (std::size_t i = 0; i < p.size(); ++i) {
        const double h = 1e-5 * std::max(1.0, std::abs(p[i]));
        auto pp = p, pm = p;
        pp[i] += h;
        pm[i] -= h;
        const double fd = (e.evaluate_values<double>(pp) - e.evaluate_values<double>(pm)) / (2 * h);
        // Central differences carry rounding error ~ eps·|f|/h on top of the O(h²) truncation.
        const double rounding = 8 * 2.2e-16 * (1.0 + std::abs(r.a)) / h;
        INFO(text << " at signal " << i);
        CHECK(r.v[static_cast<Eigen::Index>(i)] == Approx(fd).epsilon(1e-6).margin(rounding + 1e-8));
      }
    }
  }
}

TEST_CASE("expression: errors name the column of the bad token") {
  std::string msg;
  CHECK(error_column("maxx(y1(t-1),90)", &msg) == 1);
  CHECK_THAT(msg, Catch::Contains("unknown function or signal 'maxx'") && Catch::Contains("column 1"));
  // The default output name is y1: the list of signals names it once.
  CHECK_THAT(msg, Catch::Contains("signals: y1, u1, u2, ...") && !Catch::Contains("y1, y1"));
  CHECK(error_column("max(y1(t-1),90) + foo(t-1)", &msg) == 19);
  CHECK_THAT(msg, Catch::Contains("'foo'"));
  CHECK(error_column("1 + * 2", &msg) == 5);
  CHECK_THAT(msg, Catch::Contains("unexpected '*'"));
  CHECK(error_column("max(y1(t-1))", &msg) == 1);
  CHECK_THAT(msg, Catch::Contains("takes 2 arguments, got 1"));
  CHECK(error_column("y1(t)", &msg) == 4);
  CHECK_THAT(msg, Catch::Contains("output being predicted"));
  CHECK(error_column("u1(t+1)", &msg) == 5);
  CHECK_THAT(msg, Catch::Contains("future"));
  CHECK(error_column("y1", &msg) == 1);
  CHECK_THAT(msg, Catch::Contains("needs a time argument"));
  CHECK(error_column("(1 + 2", &msg) == 7);
  CHECK_THAT(msg, Catch::Contains("')'"));
  CHECK(error_column("1 2", &msg) == 3);
  CHECK(error_column("", &msg) == 1);
  CHECK_THAT(msg, Catch::Contains("empty expression"));
  CHECK(error_column("y1(s-1)", &msg) == 4);
  CHECK(error_column("y1(t-)", &msg) == 6);
  CHECK(error_column("2 $ 3", &msg) == 3);
  // Nesting deeper than the evaluation stack is refused at parse time, not at run time.
  std::string deep = "1";
  for (int i = 0; i < 40; ++i) deep = "(" + deep + "+1)";
  std::string right = "0";
  for (int i = 0; i < 40; ++i) right = "y1(t-1)*(" + right + ")";
  CHECK(error_column(right, &msg) >= 1);
  CHECK_THAT(msg, Catch::Contains("value stack"));
  CHECK(error_column(deep) == -1);  // left-nested sums need only two slots
}

TEST_CASE("expression: errors quote a whole non-ASCII character, a malformed byte in hex") {
  // Found by tests/fuzz/expression_fuzz.cpp: the message quoted the first byte of "é" alone,
  // which made it malformed UTF-8 (shown as a replacement character, if at all).
  std::string msg;
  CHECK(error_column("1 \xC3\xA9", &msg) == 3);
  CHECK_THAT(msg, Catch::Contains("unexpected '\xC3\xA9' after a complete expression"));
  CHECK(error_column("max(1,2\xE2\x82\xAC)", &msg) == 8);
  CHECK_THAT(msg, Catch::Contains("but found '\xE2\x82\xAC'"));
  CHECK(error_column("1 \xFF", &msg) == 3);
  CHECK_THAT(msg, Catch::Contains("unexpected '\\xFF'"));
  // A control character is escaped too (a NUL byte ended the message there).
  CHECK(error_column(std::string("1 \0", 3), &msg) == 3);
  CHECK_THAT(msg, Catch::Contains("unexpected '\\x00'"));
  CHECK(msg.find('\0') == std::string::npos);
}

TEST_CASE("expression: deep nesting is an error with a column, not a stack overflow") {
  // A recursive-descent parser recurses once per '(' or sign; without a bound these texts
  // overflowed the C++ stack (a crash) before the value-stack check could run.
  std::string msg;
  const std::string parens = std::string(100000, '(') + "1" + std::string(100000, ')');
  CHECK(error_column(parens, &msg) == 201);
  CHECK_THAT(msg, Catch::Contains("nests deeper than 200 levels"));
  CHECK(error_column(std::string(100000, '-') + "y1(t-1)", &msg) == 201);
  CHECK_THAT(msg, Catch::Contains("nests deeper"));
  CHECK(error_column("2^" + std::string(100000, '+') + "2", &msg) >= 1);
  CHECK_THAT(msg, Catch::Contains("nests deeper"));
  // Nesting within the bound still parses and evaluates.
  const std::string ok = std::string(150, '(') + "y1(t-1)" + std::string(150, ')');
  CHECK(eval(ok, {2.5}) == 2.5);
  CHECK(eval(std::string(150, '-') + "3", {}) == 3.0);
}

TEST_CASE("expression: C code for generated models") {
  const Expression e = Expression::parse("max(y1(t-1),90)+min(y1(t-1),15)-105");
  const std::string c = e.to_c([](const nlid::SignalRef& s) { return "y_" + std::to_string(s.lag); });
  CHECK(c == "((fmax(y_1, 90.0) + fmin(y_1, 15.0)) - 105.0)");
  CHECK(Expression::parse("-u1(t)^2").to_c([](const nlid::SignalRef&) { return std::string("u"); }) ==
        "(-pow(u, 2.0))");
}

TEST_CASE("expression: C code of deeply nested sign() is refused, not allocated") {
  // Found by tests/fuzz/expression_fuzz.cpp: sign() writes its operand twice, so the C text
  // doubled per nested sign — 40 of them (a 300-byte expression) asked for 40 GiB.
  const auto name_expr_c = [](const nlid::SignalRef&) { return std::string("y"); };
  std::string nested = "y1(t-1)";
  for (int i = 0; i < 20; ++i) nested = "sign(" + nested + ")";
  const Expression deep = Expression::parse(nested);
  CHECK(deep.evaluate_values<double>(std::vector<double>{-2.0}) == -1.0);  // evaluation is unaffected
  try {
    (void)deep.to_c(name_expr_c);
    FAIL("to_c wrote the C text of 20 nested signs");
  } catch (const nlid::Error& e) {
    CHECK_THAT(e.what(), Catch::Contains("sign()") && Catch::Contains("split it"));
  }
  // A few nested signs still have their C form.
  CHECK(Expression::parse("sign(sign(y1(t-1)))").to_c(name_expr_c) ==
        "((((y) > 0 ? 1.0 : ((y) < 0 ? -1.0 : 0.0))) > 0 ? 1.0 : ((((y) > 0 ? 1.0 : ((y) < 0 ? -1.0 : 0.0))) < 0 "
        "? -1.0 : 0.0))");
}

TEST_CASE("custom_regressor(text) and RegressorList equal the compile-time regressors") {
  const auto spring_text = nlid::custom_regressor("max(y1(t-1),90)+min(y1(t-1),15)-105");
  const auto spring_fn = nlid::custom_regressor<nlid::OutputLag<1>>(
      "max(y1(t-1),90)+min(y1(t-1),15)-105",
      [](auto y1) { return nlid::max(y1, 90.0) + nlid::min(y1, 15.0) - 105.0; });
  nlid::RegressorSet typed{nlid::LaggedRegressors<2, 1, 0>{}, spring_fn};
  nlid::RegressorSet mixed{nlid::LaggedRegressors<2, 1, 0>{}, spring_text};
  nlid::RegressorList list = nlid::RegressorList::lagged(2, 1, 0);
  list.add_custom("max(y1(t-1),90)+min(y1(t-1),15)-105");
  static_assert(nlid::Regressor<nlid::ExpressionRegressor>);
  static_assert(nlid::Regressor<nlid::RegressorList>);

  CHECK(list.size() == 4);
  CHECK(list.output_lag() == 2);
  CHECK(list.input_lag() == 0);
  CHECK(list.num_input_channels() == 1);
  CHECK(list.names({"u1"}, "y1") == typed.names({"u1"}, "y1"));
  CHECK(mixed.names({"u1"}, "y1") == typed.names({"u1"}, "y1"));

  Eigen::MatrixXd u = Eigen::VectorXd::LinSpaced(50, -1.0, 1.0);
  Eigen::VectorXd y = Eigen::VectorXd::LinSpaced(50, 0.0, 120.0);
  const Eigen::MatrixXd a = nlid::regressor_matrix(typed, u, y);
  CHECK((nlid::regressor_matrix(list, u, y).array() == a.array()).all());
  CHECK((nlid::regressor_matrix(mixed, u, y).array() == a.array()).all());

  // Multi-input lists, with names from the caller.
  const nlid::RegressorList miso = nlid::RegressorList::lagged(1, {2, 1}, {0, 3});
  CHECK(miso.names({"throttle", "load"}, "speed") ==
        std::vector<std::string>{"speed(t-1)", "throttle(t)", "throttle(t-1)", "load(t-3)"});
  CHECK(miso.input_lag() == 3);
  CHECK(miso.num_input_channels() == 2);
  CHECK_THROWS_WITH(nlid::RegressorList().add_output_lags(-1), Catch::Contains("na must be >= 0"));
  // A default-constructed Expression used to become a silent regressor named "" that reads 0.
  CHECK_THROWS_WITH(nlid::RegressorList().add_custom(Expression{}),
                    Catch::Contains("expression is empty") && Catch::Contains("parameter 'expression'"));
  CHECK_THROWS_WITH(nlid::RegressorList::lagged(1, {1, 2}, {0}), Catch::Contains("2 nb orders but 1 delays"));
}
