// User errors raise nlid::Error naming the parameter (and the cell) at fault.
#include <catch2/catch.hpp>

#include <cmath>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include "nlid/nonlinearities.hpp"

namespace {

using nlid::Dynamic;

// Runs f, requires an nlid::Error whose parameter is `param` and whose text contains `text`.
template <class Fn>
void require_error(Fn&& fn, const std::string& param, const std::string& text) {
  try {
    fn();
    FAIL("no nlid::Error thrown (expected one about '" << param << "')");
  } catch (const nlid::Error& e) {
    INFO(e.what());
    CHECK(e.where().parameter == param);
    CHECK(std::string(e.what()).find(text) != std::string::npos);
  }
}

}  // namespace

TEST_CASE("bad structure arguments name the parameter", "[nonlinearities][errors]") {
  require_error([] { nlid::SigmoidNet<Dynamic, Dynamic> f(2, 0); }, "units", "units must be at least 1, got 0");
  require_error([] { nlid::WaveletNet<2, Dynamic> f(2, -1); }, "units", "units must be at least 1");
  require_error([] { nlid::SigmoidNet<2, Dynamic> f(3, 4); }, "m", "m = 3 contradicts the compile-time value 2");
  require_error([] { nlid::LinearMap<Dynamic> f(0); }, "m", "at least 1");
  require_error([] { nlid::Poly1d<Dynamic> f(0); }, "degree", "degree must be at least 1");
  require_error([] { nlid::PwLinear<Dynamic> f(1); }, "breakpoints", "at least 2");
  require_error([] { nlid::PwLinear<Dynamic> f(std::vector<double>{0, 2, 1}); }, "breakpoints",
                "breakpoint 2 (1) is not greater than breakpoint 1 (2)");
  require_error([] { nlid::PwLinear<3> f(std::vector<double>{0, 1}); }, "breakpoints",
                "breakpoints = 2 contradicts the compile-time value 3");
  require_error([] { nlid::PwLinear<Dynamic> f(std::vector<double>{0, std::nan(""), 1}); }, "breakpoints",
                "breakpoint 1 is not finite");
  require_error([] { nlid::TreePartition<Dynamic, Dynamic> f(2, 0); }, "depth", "depth must be at least 1");
  require_error([] { nlid::TreePartition<Dynamic, Dynamic> f(2, 13); }, "depth", "at most 12");
  require_error([] { nlid::TreePartition<2, 2> f; (void)f.split_threshold(3); }, "node", "node 3 does not exist");
  // A NaN direction or threshold, or a −∞ threshold, used to be stored: NaN routes every x left,
  // −∞ every x right, and describe() printed "not split" for both.
  require_error([] { nlid::TreePartition<2, 2> f; f.set_split(1, Eigen::Vector2d(1, std::nan("")), 0.5); }, "direction",
                "split direction of node 1 is not finite");
  require_error([] { nlid::TreePartition<2, 2> f; f.set_split(0, Eigen::Vector2d(1, 0), std::nan("")); }, "threshold",
                "must be a number or +inf");
  require_error([] { nlid::TreePartition<2, 2> f; f.set_split(0, Eigen::Vector2d(1, 0), -std::numeric_limits<double>::infinity()); },
                "threshold", "must be a number or +inf");
  require_error([] { nlid::Saturation f(90, 15); }, "lower", "lower limit 90 exceeds upper limit 15");
  require_error([] { nlid::DeadZone f(1, -1); }, "lower", "lower limit 1 exceeds upper limit -1");
  require_error([] { nlid::Saturation f(0, std::numeric_limits<double>::infinity()); }, "upper", "finite");
}

TEST_CASE("bad initialisation data name X, y or theta and the cell", "[nonlinearities][errors]") {
  nlid::SigmoidNet<2, 3> f;
  std::vector<double> th(static_cast<std::size_t>(f.num_parameters()));
  const Eigen::MatrixXd X3 = Eigen::MatrixXd::Random(20, 3);
  const Eigen::VectorXd y = Eigen::VectorXd::Random(20);
  require_error([&] { f.initialize(X3, y, th); }, "X", "X has 3 columns, expected 2");
  const Eigen::MatrixXd X = Eigen::MatrixXd::Random(20, 2);
  require_error([&] { f.initialize(X, Eigen::VectorXd::Random(19), th); }, "y", "X has 20 rows but y has 19");
  std::vector<double> short_th(3);
  require_error([&] { f.initialize(X, y, short_th); }, "theta", "theta has 3 entries, expected 15");

  Eigen::MatrixXd Xn = X;
  Xn(6, 1) = std::nan("");
  try {
    f.initialize(Xn, y, th);
    FAIL("no error for NaN");
  } catch (const nlid::Error& e) {
    CHECK(e.where().row == 7);
    CHECK(e.where().column == 2);
    CHECK(std::string(e.what()).find("non-finite value in X") != std::string::npos);
  }
  Eigen::VectorXd yn = y;
  yn(3) = std::numeric_limits<double>::infinity();
  nlid::Saturation s;
  std::vector<double> ts(2);
  try {
    s.initialize(X.leftCols(1), yn, ts);
    FAIL("no error for inf");
  } catch (const nlid::Error& e) {
    CHECK(e.where().parameter == "y");
    CHECK(e.where().row == 4);
  }

  nlid::PwLinear<4> p;
  std::vector<double> tp(8);
  require_error([&] { p.initialize(Eigen::MatrixXd::Constant(10, 1, 2.0), Eigen::VectorXd::Ones(10), tp); }, "X",
                "column 1 of X is constant");
  nlid::Poly1d<5> q;
  std::vector<double> tq(6);
  require_error([&] { q.initialize(Eigen::MatrixXd::Random(4, 1), Eigen::VectorXd::Random(4), tq); }, "X",
                "at least 6 samples, got 4");
}

TEST_CASE("bad evaluation arguments name x or theta", "[nonlinearities][errors]") {
  nlid::SigmoidNet<2, 3> f;
  std::vector<double> th(static_cast<std::size_t>(f.num_parameters()));
  const std::vector<double> x3{1, 2, 3}, x2{1, 2};
  require_error([&] { (void)f(std::span<const double>(x3), std::span<const double>(th)); }, "x",
                "x has 3 entries, expected 2");
  require_error([&] { (void)f(std::span<const double>(x2), std::span<const double>(th).first(4)); }, "theta",
                "theta has 4 entries, expected 15");
  nlid::Saturation s;
  require_error([&] { (void)s(std::span<const double>(x2), std::span<const double>(x2)); }, "x",
                "Saturation: x has 2 entries, expected 1");
  require_error([&] { (void)nlid::evaluate_rows(f, Eigen::MatrixXd::Ones(3, 4), th); }, "X", "4 columns, expected 2");
  require_error([&] { (void)f.describe(th, {"a", "b", "c"}); }, "input_names", "3 input names given for 2 inputs");
  require_error([&] { f.set_normalization(Eigen::Vector2d(0, 0), Eigen::Vector2d(1, -1)); }, "normalization",
                "positive finite scale");
  nlid::PwLinear<3> p;
  std::vector<double> tp(6);
  require_error([&] { p.theta_from_breakpoints(std::vector<double>{0, 0, 1}, std::vector<double>{1, 2, 3}, tp); },
                "breakpoints", "strictly increasing at index 1");
  // Non-finite positions or values used to be written into θ as inf/NaN without a word (a NaN
  // first position was reported as "not strictly increasing at index 1").
  const double inf = std::numeric_limits<double>::infinity();
  require_error([&] { p.theta_from_breakpoints(std::vector<double>{0, 1, inf}, std::vector<double>{1, 2, 3}, tp); },
                "breakpoints", "breakpoint 2 is not finite");
  require_error([&] { p.theta_from_breakpoints(std::vector<double>{std::nan(""), 1, 2}, std::vector<double>{1, 2, 3}, tp); },
                "breakpoints", "breakpoint 0 is not finite");
  require_error([&] { p.theta_from_breakpoints(std::vector<double>{0, 1, 2}, std::vector<double>{1, std::nan(""), 3}, tp); },
                "values", "value 1 is not finite");
  require_error([&] { p.theta_from_breakpoints(std::vector<double>{-1e308, 1e308, 1.5e308}, std::vector<double>{1, 2, 3}, tp); },
                "breakpoints", "gap between breakpoints 0 and 1");
  for (double t : tp) CHECK(t == 0.0);  // θ untouched by a refused table
}
