// libFuzzer harness for the custom-regressor expression language (regressors/expression.hpp):
// `Expression::parse` with the default channel names and with named channels, then everything
// the header promises of a parsed expression.
//
// Contract checked here:
// - bad text throws nlid::Error naming the parameter "expression", with a 1-based column inside
//   the text (at most one past its end, counted in code points) that the message repeats, and a
//   message that is UTF-8 when the text is; any other exception, a sanitizer report or a hang
//   is a defect;
// - a parsed expression keeps its text, its program is a valid postfix sequence whose stack
//   never exceeds `max_stack`, every signal it lists is read, lags are within the language's
//   bounds (output lag >= 1, input lag >= 0, both <= 100000; input channels u1 ... u1000 or the
//   given names) and output_lag / input_lag / num_input_channels agree with `signals()`;
// - evaluation on a lag window, on given signal values, on float and on duals runs (a value
//   may be non-finite: log(0), 1/0 are legal); the window and the values give the same double,
//   bit for bit, and the dual's value part is the double's;
// - parsing text() again gives the same evaluation;
// - `to_c` returns C text of a size proportional to the expression (up to max_c_size with
//   nested sign(), past which it throws nlid::Error), and that C, evaluated, gives the
//   expression's value wherever that is finite and no fmax / fmin met a NaN or zeros of both
//   signs (there C's fmax / fmin and nlid::max / min differ, as to_c documents);
// - as a custom regressor of a RegressorList and of a nonlinear ARX model it reports the lags
//   of the expression, its regressor column equals the expression evaluated on the data, and a
//   simulation either runs or throws nlid::Error.
//
// Seeds: tests/fuzz/seeds/expression/; dictionary: tests/fuzz/expression.dict.
#include <bit>
#include <charconv>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <span>
#include <string>
#include <string_view>
#include <typeinfo>
#include <vector>

#include <Eigen/Core>

#include "nlid/ad/dual.hpp"
#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/core/utf8.hpp"
#include "nlid/data/experiment.hpp"
#include "nlid/models/nlarx.hpp"
#include "nlid/nonlinearities/linear.hpp"
#include "nlid/regressors/expression.hpp"

namespace {

[[noreturn]] void expr_fuzz_defect(const std::string& what, std::string_view text) {
  std::fprintf(stderr, "expression_fuzz: DEFECT: %s\n  text: '%.*s'\n", what.c_str(), static_cast<int>(text.size()),
               text.data());
  std::fflush(stderr);
  std::abort();
}

bool expr_fuzz_same(double a, double b) {
  return (std::isnan(a) && std::isnan(b)) || std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b);
}

// A deterministic history: y(t-k) and u_c(t-k) for any lag and channel, moderate values.
template <class T>
struct ExprFuzzWindow {
  using Scalar = T;
  static double yv(int lag) { return 0.75 * std::cos(0.7 * lag) + 0.1; }
  static double uv(int channel, int lag) { return std::sin(0.3 * lag + 0.9 * channel) - 0.2; }
  T y(int lag) const { return T(yv(lag)); }
  T u(int channel, int lag) const { return T(uv(channel, lag)); }
};

// Evaluates the C text `to_c` writes (signals named s<index>), as C would: fmax, fmin, fabs,
// pow, ... of <math.h>, the conditional operator of sign(). Throws std::runtime_error (reported
// as a defect) on text it cannot read: to_c must write only this.
class ExprFuzzC {
 public:
  ExprFuzzC(std::string_view c, std::span<const double> signals) : s_(c), sig_(signals) {}
  double run() {
    const double v = cond();
    if (p_ != s_.size()) bad("trailing text");
    return v;
  }

 private:
  [[noreturn]] void bad(const char* what) const {
    throw std::runtime_error(std::string("to_c text unreadable (") + what + ") at byte " + std::to_string(p_));
  }
  void skip() {
    while (p_ < s_.size() && s_[p_] == ' ') ++p_;
  }
  bool eat(char c) {
    skip();
    if (p_ < s_.size() && s_[p_] == c) {
      ++p_;
      return true;
    }
    return false;
  }
  void need(char c) {
    if (!eat(c)) bad("expected a character");
  }
  double cond() {
    const double c = compare();
    if (!eat('?')) return c;
    const double a = cond();
    need(':');
    const double b = cond();
    return c != 0 ? a : b;
  }
  double compare() {
    const double a = sum();
    if (eat('>')) return a > sum() ? 1.0 : 0.0;
    if (eat('<')) return a < sum() ? 1.0 : 0.0;
    return a;
  }
  double sum() {
    double a = product();
    for (;;) {
      if (eat('+')) a = a + product();
      else if (eat('-')) a = a - product();
      else return a;
    }
  }
  double product() {
    double a = unary();
    for (;;) {
      if (eat('*')) a = a * unary();
      else if (eat('/')) a = a / unary();
      else return a;
    }
  }
  double unary() {
    if (eat('-')) return -unary();
    return primary();
  }
  double primary() {
    skip();
    if (eat('(')) {
      const double v = cond();
      need(')');
      return v;
    }
    if (p_ >= s_.size()) bad("unexpected end");
    const char c = s_[p_];
    if ((c >= '0' && c <= '9') || c == '.') {
      double v = 0;
      const auto r = std::from_chars(s_.data() + p_, s_.data() + s_.size(), v);
      if (r.ec != std::errc()) bad("number");
      p_ = static_cast<std::size_t>(r.ptr - s_.data());
      return v;
    }
    const std::size_t start = p_;
    while (p_ < s_.size() && ((s_[p_] >= 'a' && s_[p_] <= 'z') || (s_[p_] >= '0' && s_[p_] <= '9'))) ++p_;
    const std::string_view id = s_.substr(start, p_ - start);
    if (id.size() >= 2 && id[0] == 's' && id[1] >= '0' && id[1] <= '9') {
      std::size_t k = 0;
      std::from_chars(id.data() + 1, id.data() + id.size(), k);
      if (k >= sig_.size()) bad("signal index");
      return sig_[k];
    }
    need('(');
    const double a = cond();
    double b = 0;
    const bool two = id == "pow" || id == "fmin" || id == "fmax";
    if (two) {
      need(',');
      b = cond();
    }
    need(')');
    if (id == "fabs") return std::fabs(a);
    if (id == "sqrt") return std::sqrt(a);
    if (id == "exp") return std::exp(a);
    if (id == "log") return std::log(a);
    if (id == "tanh") return std::tanh(a);
    if (id == "sin") return std::sin(a);
    if (id == "cos") return std::cos(a);
    if (id == "pow") return std::pow(a, b);
    if (id == "fmin" || id == "fmax") {
      // Where C's fmin / fmax and nlid::min / max differ (Expression::to_c): a NaN operand, or
      // zeros of both signs. The value is then not compared.
      if (std::isnan(a) || std::isnan(b) || (a == b && std::signbit(a) != std::signbit(b))) nan_minmax = true;
      return id == "fmin" ? std::fmin(a, b) : std::fmax(a, b);
    }
    bad("unknown function");
  }

  std::string_view s_;
  std::span<const double> sig_;
  std::size_t p_ = 0;

 public:
  bool nan_minmax = false;  ///< an fmin / fmax met a NaN or zeros of both signs
};

long expr_fuzz_code_points(std::string_view s) {
  long n = 0;
  for (char c : s) n += (static_cast<unsigned char>(c) & 0xC0) != 0x80;
  return n;
}

// The custom regressor inside a RegressorList and a nonlinear ARX model.
void expr_fuzz_as_regressor(const nlid::Expression& e, std::string_view text, double value) {
  nlid::RegressorList r;
  r.add_output_lags(1);
  r.add_input_lags(1, 0, 0);
  r.add_custom(e);
  if (r.size() != 3 || r.output_lag() != std::max(1, e.output_lag()) || r.input_lag() != e.input_lag() ||
      r.num_input_channels() != std::max(1, e.num_input_channels())) {
    expr_fuzz_defect("RegressorList lags or size differ from the expression's", text);
  }
  std::vector<double> out(3);
  r.evaluate(ExprFuzzWindow<double>{}, std::span<double>(out));
  if (!expr_fuzz_same(out[2], value)) expr_fuzz_defect("RegressorList value differs from the expression's", text);
  if (r.names({}, "y1").at(2) != e.text()) expr_fuzz_defect("custom regressor name is not its text", text);
  const nlid::ExpressionRegressor er(e);
  if (er.output_lag() != e.output_lag() || er.input_lag() != e.input_lag()) {
    expr_fuzz_defect("ExpressionRegressor lags differ", text);
  }

  // A short record: only for expressions whose history and channels fit it.
  const int n = 40, nu = std::max(1, e.num_input_channels());
  if (e.output_lag() > 20 || e.input_lag() > 20 || nu > 6) return;
  Eigen::MatrixXd u(n, nu), y(n, 1);
  for (int k = 0; k < n; ++k) {
    for (int c = 0; c < nu; ++c) u(k, c) = ExprFuzzWindow<double>::uv(c, -k);
    y(k, 0) = ExprFuzzWindow<double>::yv(-k);
  }
  const nlid::Experiment ex(u, y, 0.1, "fuzz");
  nlid::Nlarx<nlid::RegressorList, nlid::LinearMap<nlid::Dynamic>> m(r, nlid::LinearMap<nlid::Dynamic>(r.size()), 0.1);
  Eigen::VectorXd th(m.num_parameters());
  th << 0.5, 0.2, 0.1, 0.05;
  m.set_parameters(th);
  const Eigen::MatrixXd X = m.regressor_values(ex);
  const int n0 = m.history_length();
  if (X.rows() != n - n0 || X.cols() != 3) expr_fuzz_defect("regressor matrix has the wrong shape", text);
  std::vector<double> vals(e.signals().size());
  for (Eigen::Index i = 0; i < X.rows(); ++i) {
    const int t = n0 + static_cast<int>(i);
    for (std::size_t j = 0; j < vals.size(); ++j) {
      const nlid::SignalRef& s = e.signals()[j];
      vals[j] = s.is_output ? y(t - s.lag, 0) : u(t - s.lag, s.channel);
    }
    if (!expr_fuzz_same(X(i, 2), e.evaluate_values<double>(vals))) {
      expr_fuzz_defect("regressor column differs from the expression on the data at row " + std::to_string(i), text);
    }
  }
  try {
    const Eigen::MatrixXd ys = m.simulate(ex);
    if (ys.rows() != n || ys.cols() != 1 || !ys.allFinite()) expr_fuzz_defect("simulation shape or value", text);
  } catch (const nlid::Error&) {
    // A diverging simulation (DivergenceError) is an accepted outcome.
  }
}

void expr_fuzz_parsed(const nlid::Expression& e, std::string_view text, const std::vector<std::string>& names,
                      const std::string& output) {
  using Op = nlid::Expression::Op;
  if (e.text() != text) expr_fuzz_defect("text() is not the parsed text", text);
  const auto& prog = e.program();
  const auto& sig = e.signals();
  if (prog.empty()) expr_fuzz_defect("empty program", text);
  int depth = 0;
  std::vector<bool> used(sig.size(), false);
  for (const auto& nd : prog) {
    switch (nd.op) {
      case Op::number:
        if (!std::isfinite(nd.value) || nd.value < 0) expr_fuzz_defect("a number constant is negative or not finite", text);
        ++depth;
        break;
      case Op::signal:
        if (nd.index < 0 || static_cast<std::size_t>(nd.index) >= sig.size()) expr_fuzz_defect("signal index", text);
        used[static_cast<std::size_t>(nd.index)] = true;
        ++depth;
        break;
      case Op::add: case Op::sub: case Op::mul: case Op::div: case Op::pow: case Op::min: case Op::max:
        if (depth < 2) expr_fuzz_defect("binary operation on fewer than two values", text);
        --depth;
        break;
      default:
        if (depth < 1) expr_fuzz_defect("unary operation on an empty stack", text);
    }
    if (depth > nlid::Expression::max_stack) expr_fuzz_defect("stack deeper than max_stack", text);
  }
  if (depth != 1) expr_fuzz_defect("program leaves " + std::to_string(depth) + " values", text);
  int ylag = 0, ulag = 0, channels = 0;
  for (std::size_t i = 0; i < sig.size(); ++i) {
    const nlid::SignalRef& s = sig[i];
    if (!used[i]) expr_fuzz_defect("a listed signal is never read", text);
    for (std::size_t j = 0; j < i; ++j)
      if (sig[j] == s) expr_fuzz_defect("a signal is listed twice", text);
    if (s.is_output ? (s.lag < 1 || s.channel != 0) : s.lag < 0) expr_fuzz_defect("lag below its bound", text);
    if (s.lag > 100000) expr_fuzz_defect("lag above 100000", text);
    if (!s.is_output && (s.channel < 0 || s.channel >= std::max<int>(1000, static_cast<int>(names.size())))) {
      expr_fuzz_defect("input channel out of range", text);
    }
    if (s.is_output) ylag = std::max(ylag, s.lag);
    else {
      ulag = std::max(ulag, s.lag);
      channels = std::max(channels, s.channel + 1);
    }
  }
  if (e.output_lag() != ylag || e.input_lag() != ulag || e.num_input_channels() != channels) {
    expr_fuzz_defect("output_lag / input_lag / num_input_channels disagree with signals()", text);
  }
  if (e.is_signal() != (prog.size() == 1 && prog[0].op == Op::signal)) expr_fuzz_defect("is_signal", text);

  // Evaluation.
  const double v = e.evaluate(ExprFuzzWindow<double>{});
  std::vector<double> vals(sig.size());
  for (std::size_t i = 0; i < sig.size(); ++i)
    vals[i] = sig[i].is_output ? ExprFuzzWindow<double>::yv(sig[i].lag) : ExprFuzzWindow<double>::uv(sig[i].channel, sig[i].lag);
  if (!expr_fuzz_same(v, e.evaluate_values<double>(vals))) expr_fuzz_defect("window and values evaluations differ", text);
  (void)e.evaluate(ExprFuzzWindow<float>{});
  using D = nlid::Dual<double, 2>;
  const D dv = e.evaluate(ExprFuzzWindow<D>{});
  if (!expr_fuzz_same(dv.a, v)) {
    expr_fuzz_defect("dual value " + nlid::detail::format_g(dv.a, 17) + " differs from the double value " +
                         nlid::detail::format_g(v, 17),
                     text);
  }

  // The text parses again to the same evaluation.
  const nlid::Expression again = nlid::Expression::parse(e.text(), names, output);
  if (!expr_fuzz_same(again.evaluate(ExprFuzzWindow<double>{}), v)) expr_fuzz_defect("parse(text()) evaluates differently", text);

  // C text: proportional to the expression (sign() writes its operand twice, so nested signs
  // may double it up to max_c_size, past which to_c throws), and the same value where that is
  // finite and no fmin / fmax met a NaN.
  bool has_sign = false;
  for (const auto& nd : prog) has_sign = has_sign || nd.op == Op::sign;
  std::string c;
  try {
    c = e.to_c([&](const nlid::SignalRef& s) {
      for (std::size_t i = 0; i < sig.size(); ++i)
        if (sig[i] == s) return "s" + std::to_string(i);
      return std::string("s_unknown");
    });
  } catch (const nlid::Error& err) {
    if (!has_sign) expr_fuzz_defect(std::string("to_c refused an expression without sign(): ") + err.what(), text);
    expr_fuzz_as_regressor(e, text, v);
    return;
  }
  if (c.empty()) expr_fuzz_defect("to_c wrote nothing", text);
  if (c.size() > (has_sign ? nlid::Expression::max_c_size : 64 * text.size() + 64)) {
    expr_fuzz_defect("to_c wrote " + std::to_string(c.size()) + " bytes for " + std::to_string(text.size()), text);
  }
  double cv = 0;
  ExprFuzzC creader(c, vals);
  try {
    cv = creader.run();
  } catch (const std::runtime_error& err) {
    expr_fuzz_defect(std::string(err.what()) + " in '" + c + "'", text);
  }
  if (std::isfinite(v) && !creader.nan_minmax && cv != v) {
    expr_fuzz_defect("C text '" + c + "' gives " + nlid::detail::format_g(cv, 17) + ", the expression " +
                         nlid::detail::format_g(v, 17),
                     text);
  }

  expr_fuzz_as_regressor(e, text, v);
}

void expr_fuzz_one(std::string_view text, const std::vector<std::string>& names, const std::string& output) {
  nlid::Expression e;
  try {
    e = nlid::Expression::parse(text, names, output);
  } catch (const nlid::Error& err) {
    const long col = err.where().column;
    if (col < 1 || col > expr_fuzz_code_points(text) + 1) {
      expr_fuzz_defect("error column " + std::to_string(col) + " outside the text: " + err.what(), text);
    }
    if (err.where().parameter != "expression") expr_fuzz_defect("error does not name the expression", text);
    if (err.message().find("at column " + std::to_string(col)) == std::string::npos) {
      expr_fuzz_defect(std::string("error message does not give its column: ") + err.what(), text);
    }
    // A message about well-formed text is well-formed: it quotes characters, not bytes of them.
    if (nlid::first_invalid_utf8(text) == std::string_view::npos &&
        nlid::first_invalid_utf8(err.message()) != std::string::npos) {
      expr_fuzz_defect(std::string("error message about UTF-8 text is not UTF-8: ") + err.what(), text);
    }
    return;
  }
  expr_fuzz_parsed(e, text, names, output);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  static const std::vector<std::string> none;
  static const std::vector<std::string> named{"speed", "torque"};
  try {
    expr_fuzz_one(text, none, "y1");
    expr_fuzz_one(text, named, "angle");
  } catch (const nlid::Error& err) {
    expr_fuzz_defect(std::string("nlid::Error after a successful parse: ") + err.what(), text);
  } catch (const std::exception& err) {
    expr_fuzz_defect(std::string(typeid(err).name()) + ": " + err.what(), text);
  }
  return 0;
}
