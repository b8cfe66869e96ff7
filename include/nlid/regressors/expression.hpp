#pragma once
/// @file
/// Custom regressors written as text: a small expression language, its parser and an evaluator
/// templated on the scalar, plus `RegressorList`, the regressor set chosen at run time.
///
/// Why text. A custom regressor written as a C++ lambda (regressors/custom.hpp) is fastest, but it
/// cannot be stored in a model file, typed on a command line or chosen by a program while it runs.
/// The toolbox stores custom regressors as strings for the same reason, e.g. the study's hard-stop
/// regressor (Ljung 1999, sec. 5.4, "semi-physical regressors")
///
///     max(y1(t-1),90)+min(y1(t-1),15)-105 .
///
/// Grammar (whitespace is ignored between tokens):
///
///     expr    := term   (('+' | '-') term)*
///     term    := unary  (('*' | '/') unary)*
///     unary   := ('-' | '+') unary | power
///     power   := primary ('^' unary)?            right associative: 2^3^2 = 2^9
///     primary := number | '(' expr ')' | function '(' expr (',' expr)* ')' | signal '(' time ')'
///     time    := 't' | 't' '-' integer           y1(t-1) = y(t−1), u2(t) = u₂(t)
///
/// As in MATLAB, `^` binds tighter than unary minus: −2^2 = −4. Numbers are decimal with an
/// optional fraction and exponent (1, 0.5, 2.5e-3). Signals are `y1` (the output; lag ≥ 1) and
/// `u1`, `u2`, … (inputs; lag ≥ 0), or the channel names given to the parser. Functions:
/// abs sqrt exp log tanh sin cos sign (one argument), min max pow (two arguments).
///
/// Evaluation. `parse` compiles the text once to a postfix program (reverse Polish notation) and
/// records which lagged signals it reads; `evaluate(window)` runs that program on a value stack of
/// at most `Expression::max_stack` entries held in a `std::array` — on doubles, floats or dual
/// numbers alike, without heap use. On duals the derivative of every operation is the one of
/// nlid's AD layer (kinks of abs/min/max/sign: one-sided, sign' = 0), so an expression gives the
/// same numbers, bit for bit, as the lambda `[](auto y) { return max(y, 90.0) + … ; }`.
///
/// Errors. A bad expression throws `nlid::Error` whose message quotes the text, points at the
/// 1-based column of the offending token and says what was expected, e.g.
///
///     nlid: unknown function or signal 'maxx' at column 1 of 'maxx(y1(t-1),90)' (functions: …)
///
/// and whose `Location::column` holds that column.

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstddef>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "nlid/ad/dual.hpp"
#include "nlid/core/error.hpp"
#include "nlid/core/sizes.hpp"
#include "nlid/core/utf8.hpp"
#include "nlid/regressors/concepts.hpp"

namespace nlid {

/// One lagged signal read by an expression: the output y(t−lag) or the input u_channel(t−lag).
struct SignalRef {
  bool is_output = false;  ///< true: the output y; false: input `channel`
  int channel = 0;         ///< 0-based input channel (0 for the output)
  int lag = 0;             ///< samples back (≥ 1 for the output, ≥ 0 for inputs)
  /// Two references are equal if they read the same sample of the same signal.
  friend bool operator==(const SignalRef&, const SignalRef&) = default;
};

/// A parsed expression of lagged signals (see the file comment for the language).
/// Invariant: the program is a valid postfix sequence whose stack never exceeds `max_stack`.
class Expression {
 public:
  /// Deepest value stack an expression may need (nesting limit; keeps evaluation heap-free).
  static constexpr int max_stack = 32;

  /// Operations of the postfix program.
  enum class Op : unsigned char {
    number, signal, neg, add, sub, mul, div, pow, abs, sqrt, exp, log, tanh, sin, cos, sign, min, max
  };
  /// One instruction: an operation, its constant (number) or signal index (signal).
  struct Node {
    Op op = Op::number;  ///< what to do
    double value = 0.0;  ///< the constant of `number`
    int index = 0;       ///< index into `signals()` of `signal`
  };

  /// Empty expression (evaluates to nothing; `parse` builds real ones).
  Expression() = default;

  /// Parses `text`. Signals may be written `y1`/`u<k>` or with the given channel names
  /// (`input_names[c]` for input c, `output_name` for the output). Throws `nlid::Error` with the
  /// column of the bad token.
  [[nodiscard]] static Expression parse(std::string_view text,
                                        const std::vector<std::string>& input_names = {},
                                        const std::string& output_name = "y1");

  /// The text as given to `parse`.
  [[nodiscard]] const std::string& text() const { return text_; }
  /// The postfix program.
  [[nodiscard]] const std::vector<Node>& program() const { return program_; }
  /// Distinct lagged signals read, in order of first appearance.
  [[nodiscard]] const std::vector<SignalRef>& signals() const { return signals_; }
  /// True if the expression is exactly one lagged signal (e.g. "y1(t-2)").
  [[nodiscard]] bool is_signal() const { return program_.size() == 1 && program_[0].op == Op::signal; }
  /// Largest output lag read (0 if none).
  [[nodiscard]] int output_lag() const {
    int m = 0;
    for (const auto& s : signals_) m = s.is_output && s.lag > m ? s.lag : m;
    return m;
  }
  /// Largest input lag read (0 if none).
  [[nodiscard]] int input_lag() const {
    int m = 0;
    for (const auto& s : signals_) m = !s.is_output && s.lag > m ? s.lag : m;
    return m;
  }
  /// 1 + the highest input channel read (0 if only the output is read).
  [[nodiscard]] int num_input_channels() const {
    int m = 0;
    for (const auto& s : signals_) m = !s.is_output && s.channel + 1 > m ? s.channel + 1 : m;
    return m;
  }

  /// Value at the window's current time, on the window's scalar (double, float, Dual).
  template <LagWindow W>
  [[nodiscard]] typename W::Scalar evaluate(const W& w) const {
    using T = typename W::Scalar;
    return run<T>([&w](const SignalRef& s) -> T {
      return s.is_output ? T(w.y(s.lag)) : T(w.u(s.channel, s.lag));
    });
  }

  /// Value for given signal values: `values[i]` is the value of `signals()[i]`.
  template <class T>
  [[nodiscard]] T evaluate_values(std::span<const T> values) const {
    require(values.size() == signals_.size(),
            "expression '" + text_ + "' reads " + std::to_string(signals_.size()) + " signals, got " +
                std::to_string(values.size()) + " values",
            at_parameter("values"));
    return run<T>([&](const SignalRef& s) -> T {
      for (std::size_t i = 0; i < signals_.size(); ++i)
        if (signals_[i] == s) return values[i];
      return T(0);
    });
  }

  /// Longest C text `to_c` writes (characters): sign() writes its operand twice, so nested signs
  /// double the text; past this length `to_c` refuses rather than allocating gigabytes.
  static constexpr std::size_t max_c_size = std::size_t{1} << 20;

  /// The expression as C99 source (fmax, fmin, pow, fabs, …; fully parenthesised), each signal
  /// spelled by `signal_name(ref)`: what a code generator emits for a custom regressor. Throws
  /// `nlid::Error` if the text would exceed `max_c_size` (sign() nested about 15 deep).
  /// C's fmax / fmin differ from nlid::max / min (x >= y ? x : y, as `evaluate` computes) where
  /// an operand is NaN — fmax(1, NaN) is 1, max(1, NaN) NaN — or both are zeros of opposite
  /// sign: the ternary form would write both operands twice, doubling the text per nested
  /// min/max. For those values the C differs from `evaluate` (nlid's own code generator traces
  /// `evaluate` and does match it).
  template <class NameFn>
  [[nodiscard]] std::string to_c(NameFn&& signal_name) const {
    std::vector<std::string> st;
    for (const Node& n : program_) {
      switch (n.op) {
        case Op::number: st.push_back(c_number(n.value)); break;
        case Op::signal: st.push_back(signal_name(signals_[static_cast<std::size_t>(n.index)])); break;
        case Op::neg: st.back() = "(-" + st.back() + ")"; break;
        case Op::abs: case Op::sqrt: case Op::exp: case Op::log: case Op::tanh: case Op::sin:
        case Op::cos: st.back() = std::string(c_function(n.op)) + "(" + st.back() + ")"; break;
        case Op::sign:
          // C99 has no sign function that gives 0 at 0 and at NaN, as run() does, so the operand
          // is written twice and each nested sign() doubles the text: 40 nested signs in 300
          // bytes of expression asked for 40 GiB. Refuse a text past max_c_size instead.
          require(2 * st.back().size() + 40 <= max_c_size,
                  "expression '" + text_ + "': its C form would exceed " + std::to_string(max_c_size) +
                      " characters (each nested sign() writes its argument twice); split it into several regressors",
                  at_parameter("expression"));
          st.back() = "((" + st.back() + ") > 0 ? 1.0 : ((" + st.back() + ") < 0 ? -1.0 : 0.0))";
          break;
        default: {
          std::string b = std::move(st.back());
          st.pop_back();
          std::string& a = st.back();
          if (n.op == Op::pow || n.op == Op::min || n.op == Op::max) {
            a = std::string(c_function(n.op)) + "(" + a + ", " + b + ")";
          } else {
            const char* o = n.op == Op::add ? " + " : n.op == Op::sub ? " - " : n.op == Op::mul ? " * " : " / ";
            a = "(" + a + o + b + ")";
          }
        }
      }
    }
    return st.empty() ? std::string("0.0") : st.back();
  }

  // ---- Implementation details below ----------------------------------------------------------
 private:
  friend class ExpressionParser;

  template <class T, class Fetch>
  T run(Fetch&& fetch) const {
    using std::abs, std::sqrt, std::exp, std::log, std::tanh, std::sin, std::cos, std::pow;
    if (is_signal()) return fetch(signals_[static_cast<std::size_t>(program_[0].index)]);
    std::array<T, static_cast<std::size_t>(max_stack)> st{};
    std::size_t top = 0;  // number of values on the stack
    for (const Node& n : program_) {
      switch (n.op) {
        case Op::number: st[top++] = T(n.value); break;
        case Op::signal: st[top++] = fetch(signals_[static_cast<std::size_t>(n.index)]); break;
        case Op::neg: st[top - 1] = -st[top - 1]; break;
        case Op::abs: st[top - 1] = abs(st[top - 1]); break;
        case Op::sqrt: st[top - 1] = sqrt(st[top - 1]); break;
        case Op::exp: st[top - 1] = exp(st[top - 1]); break;
        case Op::log: st[top - 1] = log(st[top - 1]); break;
        case Op::tanh: st[top - 1] = tanh(st[top - 1]); break;
        case Op::sin: st[top - 1] = sin(st[top - 1]); break;
        case Op::cos: st[top - 1] = cos(st[top - 1]); break;
        case Op::sign: {
          // Piecewise constant: derivative zero everywhere (and at 0 the value 0, as MATLAB's sign).
          const auto v = value_of(st[top - 1]);
          st[top - 1] = T(v > 0 ? 1.0 : (v < 0 ? -1.0 : 0.0));
          break;
        }
        default: {
          --top;
          T& a = st[top - 1];
          const T& b = st[top];
          switch (n.op) {
            case Op::add: a = a + b; break;
            case Op::sub: a = a - b; break;
            case Op::mul: a = a * b; break;
            case Op::div: a = a / b; break;
            // Unqualified, so that overloads declared after this header (the code generator's
            // TraceScalar) are found by argument-dependent lookup when run<T> is instantiated: a
            // qualified nlid::min saw only the overloads declared before it, and a program that
            // included this header before nlid/codegen could not generate C for these models.
            case Op::min: a = min(a, b); break;
            case Op::max: a = max(a, b); break;
            case Op::pow: a = power(a, b); break;
            default: break;
          }
        }
      }
    }
    return st[0];
  }

  // x^y. A constant integer exponent is the common case (x^2, x^3) and keeps a negative base
  // meaningful on duals; a general exponent uses pow(T, T).
  template <class T>
  static T power(const T& x, const T& y) {
    using std::pow;
    if constexpr (is_dual_v<T>) {
      bool constant = true;
      for (Eigen::Index k = 0; k < y.v.size(); ++k) constant = constant && y.v[k] == 0;
      if (constant) return pow(x, y.a);
      return pow(x, y);
    } else {
      return static_cast<T>(pow(x, y));
    }
  }

  static std::string c_number(double v) {
    char buf[40];
    auto r = std::to_chars(buf, buf + sizeof buf, v);
    std::string s(buf, r.ptr);
    if (s.find_first_of(".en") == std::string::npos) s += ".0";
    return v < 0 ? "(" + s + ")" : s;
  }
  static const char* c_function(Op op) {
    switch (op) {
      case Op::abs: return "fabs";
      case Op::sqrt: return "sqrt";
      case Op::exp: return "exp";
      case Op::log: return "log";
      case Op::tanh: return "tanh";
      case Op::sin: return "sin";
      case Op::cos: return "cos";
      case Op::pow: return "pow";
      case Op::min: return "fmin";
      case Op::max: return "fmax";
      default: return "?";
    }
  }

  std::string text_;
  std::vector<Node> program_;
  std::vector<SignalRef> signals_;
};

/// Recursive-descent parser of the expression language (used through `Expression::parse`).
class ExpressionParser {
 public:
  /// Parser over `text` with the given channel names.
  ExpressionParser(std::string_view text, const std::vector<std::string>& input_names,
                   const std::string& output_name)
      : s_(text), inputs_(input_names), output_(output_name) {}

  /// Parses the whole text; throws `nlid::Error` at the first bad token.
  Expression run() {
    e_.text_ = std::string(s_);
    skip();
    if (p_ >= s_.size()) fail(p_, "empty expression; expected e.g. 'max(y1(t-1),90)'");
    expr();
    skip();
    if (p_ < s_.size()) fail(p_, "unexpected '" + char_at(p_) + "' after a complete expression");
    // Stack depth of the postfix program.
    int depth = 0, most = 0;
    for (const auto& n : e_.program_) {
      using Op = Expression::Op;
      if (n.op == Op::number || n.op == Op::signal) ++depth;
      else if (n.op == Op::add || n.op == Op::sub || n.op == Op::mul || n.op == Op::div ||
               n.op == Op::pow || n.op == Op::min || n.op == Op::max) --depth;
      most = depth > most ? depth : most;
    }
    if (most > Expression::max_stack) {
      fail(0, "expression needs a value stack of " + std::to_string(most) + " (more than " +
                  std::to_string(Expression::max_stack) + "); split it into several regressors");
    }
    return std::move(e_);
  }

 private:
  using Op = Expression::Op;

  void expr() {
    term();
    for (;;) {
      skip();
      if (peek('+')) { ++p_; term(); emit(Op::add); }
      else if (peek('-')) { ++p_; term(); emit(Op::sub); }
      else return;
    }
  }
  void term() {
    unary();
    for (;;) {
      skip();
      if (peek('*')) { ++p_; unary(); emit(Op::mul); }
      else if (peek('/')) { ++p_; unary(); emit(Op::div); }
      else return;
    }
  }
  void unary() {
    // Every nesting (parenthesis, function argument, sign, exponent) passes through here; a
    // bound keeps a hostile or mistyped text (thousands of '(') from overflowing the C++ stack
    // of this recursive parser, which no value-stack check can prevent: "((((1))))" needs one slot.
    if (++nesting_ > max_nesting) {
      fail(p_, "expression nests deeper than " + std::to_string(max_nesting) +
                   " levels (parentheses, function calls, signs, powers); split it into several regressors");
    }
    skip();
    if (peek('-')) { ++p_; unary(); emit(Op::neg); }
    else if (peek('+')) { ++p_; unary(); }
    else power();
    --nesting_;
  }
  void power() {
    primary();
    skip();
    if (peek('^')) {
      ++p_;
      unary();  // right associative, and 2^-1 is allowed
      emit(Op::pow);
    }
  }
  void primary() {
    skip();
    if (p_ >= s_.size()) fail(p_, "unexpected end of expression; expected a number, signal, function or '('");
    const char c = s_[p_];
    if (c == '(') {
      ++p_;
      expr();
      expect(')', "')' to close the '(' ");
      return;
    }
    if ((c >= '0' && c <= '9') || c == '.') { number(); return; }
    if (is_name_start(c)) { name(); return; }
    fail(p_, "unexpected '" + char_at(p_) + "'; expected a number, signal, function or '('");
  }
  void number() {
    const std::size_t start = p_;
    while (p_ < s_.size() && ((s_[p_] >= '0' && s_[p_] <= '9') || s_[p_] == '.')) ++p_;
    if (p_ < s_.size() && (s_[p_] == 'e' || s_[p_] == 'E')) {
      std::size_t q = p_ + 1;
      if (q < s_.size() && (s_[q] == '+' || s_[q] == '-')) ++q;
      if (q < s_.size() && s_[q] >= '0' && s_[q] <= '9') {
        p_ = q;
        while (p_ < s_.size() && s_[p_] >= '0' && s_[p_] <= '9') ++p_;
      }
    }
    double v = 0;
    const auto r = std::from_chars(s_.data() + start, s_.data() + p_, v);
    if (r.ec != std::errc() || r.ptr != s_.data() + p_ || !std::isfinite(v)) {
      fail(start, "bad number '" + std::string(s_.substr(start, p_ - start)) + "'");
    }
    Expression::Node n;
    n.op = Op::number;
    n.value = v;
    e_.program_.push_back(n);
  }
  void name() {
    const std::size_t start = p_;
    while (p_ < s_.size() && is_name_char(s_[p_])) ++p_;
    const std::string id(s_.substr(start, p_ - start));
    skip();
    const bool call = peek('(');
    // Functions first, then channel names.
    struct Fn { const char* name; Op op; int args; };
    static constexpr std::array<Fn, 11> fns{{{"abs", Op::abs, 1}, {"sqrt", Op::sqrt, 1}, {"exp", Op::exp, 1},
                                             {"log", Op::log, 1}, {"tanh", Op::tanh, 1}, {"sin", Op::sin, 1},
                                             {"cos", Op::cos, 1}, {"sign", Op::sign, 1}, {"min", Op::min, 2},
                                             {"max", Op::max, 2}, {"pow", Op::pow, 2}}};
    for (const Fn& f : fns) {
      if (id != f.name) continue;
      if (!call) fail(start, "function '" + id + "' needs its arguments in parentheses, e.g. " + id + "(y1(t-1)" + (f.args == 2 ? ",0)" : ")"));
      ++p_;
      int args = 0;
      skip();
      if (!peek(')')) {
        for (;;) {
          expr();
          ++args;
          skip();
          if (peek(',')) { ++p_; continue; }
          break;
        }
      }
      if (args != f.args) {
        fail(start, "function '" + id + "' takes " + std::to_string(f.args) + " argument" +
                        (f.args == 1 ? "" : "s") + ", got " + std::to_string(args));
      }
      expect(')', "')' to close the arguments of '" + id + "' ");
      Expression::Node n;
      n.op = f.op;
      e_.program_.push_back(n);
      return;
    }
    SignalRef ref;
    if (!resolve(id, ref)) {
      std::string known;
      for (const Fn& f : fns) known += std::string(known.empty() ? "" : ", ") + f.name;
      std::string sig = output_ == "y1" ? std::string("y1, u1, u2, ...") : output_ + ", y1, u1, u2, ...";
      for (const auto& n : inputs_) sig += ", " + n;
      fail(start, "unknown function or signal '" + id + "' (functions: " + known + "; signals: " + sig + ")");
    }
    if (!call) fail(start, "signal '" + id + "' needs a time argument, e.g. " + id + "(t-1)");
    ++p_;
    skip();
    const std::size_t tpos = p_;
    if (!(p_ < s_.size() && s_[p_] == 't' && (p_ + 1 >= s_.size() || !is_name_char(s_[p_ + 1])))) {
      fail(tpos, "expected the time 't' or 't-<lag>' inside " + id + "(...)");
    }
    ++p_;
    skip();
    int lag = 0;
    if (peek('-')) {
      ++p_;
      skip();
      const std::size_t lpos = p_;
      while (p_ < s_.size() && s_[p_] >= '0' && s_[p_] <= '9') ++p_;
      if (p_ == lpos) fail(lpos, "expected an integer lag after 't-' in " + id + "(...)");
      const auto r = std::from_chars(s_.data() + lpos, s_.data() + p_, lag);
      if (r.ec != std::errc() || lag > 100000) fail(lpos, "lag is too large");
      skip();
    } else if (peek('+')) {
      fail(p_, "future samples (t+k) cannot be regressors; use t or t-<lag>");
    }
    if (ref.is_output && lag < 1) {
      fail(tpos, "'" + id + "(t)' is the output being predicted; an output regressor must look back at least one "
                 "sample, e.g. " + id + "(t-1)");
    }
    expect(')', "')' to close " + id + "(t...) ");
    ref.lag = lag;
    int index = -1;
    for (std::size_t i = 0; i < e_.signals_.size(); ++i)
      if (e_.signals_[i] == ref) index = static_cast<int>(i);
    if (index < 0) {
      index = static_cast<int>(e_.signals_.size());
      e_.signals_.push_back(ref);
    }
    Expression::Node n;
    n.op = Op::signal;
    n.index = index;
    e_.program_.push_back(n);
  }

  bool resolve(const std::string& id, SignalRef& ref) const {
    if (id == output_ || id == "y1") {
      ref.is_output = true;
      ref.channel = 0;
      return true;
    }
    for (std::size_t c = 0; c < inputs_.size(); ++c) {
      if (id == inputs_[c]) {
        ref.is_output = false;
        ref.channel = static_cast<int>(c);
        return true;
      }
    }
    if (id.size() >= 2 && id[0] == 'u' && id[1] >= '1' && id[1] <= '9') {
      int k = 0;
      const auto r = std::from_chars(id.data() + 1, id.data() + id.size(), k);
      if (r.ec == std::errc() && r.ptr == id.data() + id.size() && k >= 1 && k <= 1000) {
        ref.is_output = false;
        ref.channel = k - 1;
        return true;
      }
    }
    return false;
  }

  static bool is_name_start(char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_' || (static_cast<unsigned char>(c) >= 0x80);
  }
  static bool is_name_char(char c) { return is_name_start(c) || (c >= '0' && c <= '9'); }
  bool peek(char c) const { return p_ < s_.size() && s_[p_] == c; }
  void skip() {
    while (p_ < s_.size() && (s_[p_] == ' ' || s_[p_] == '\t' || s_[p_] == '\n' || s_[p_] == '\r')) ++p_;
  }
  void expect(char c, const std::string& what) {
    skip();
    if (!peek(c)) {
      fail(p_, "expected " + what + (p_ < s_.size() ? "but found '" + char_at(p_) + "'" : "but the expression ended"));
    }
    ++p_;
  }
  void emit(Op op) {
    Expression::Node n;
    n.op = op;
    e_.program_.push_back(n);
  }
  // The character at pos as a message quotes it: its whole UTF-8 sequence (the first byte of
  // "é" alone made the message malformed UTF-8), else the one byte, which Error shows as \xHH
  // (a malformed byte or a control character, as anywhere in a message).
  std::string char_at(std::size_t pos) const {
    return std::string(s_.substr(pos, std::max<std::size_t>(1, detail::utf8_sequence_length(s_, pos))));
  }
  // 1-based column in code points (UTF-8 continuation bytes do not count), as an editor shows it.
  long column(std::size_t pos) const {
    long col = 1;
    for (std::size_t i = 0; i < pos && i < s_.size(); ++i)
      if ((static_cast<unsigned char>(s_[i]) & 0xC0) != 0x80) ++col;
    return col;
  }
  [[noreturn]] void fail(std::size_t pos, const std::string& what) const {
    Location where;
    where.column = column(pos);
    where.parameter = "expression";
    throw Error(what + " at column " + std::to_string(where.column) + " of '" + std::string(s_) + "'", where);
  }

  static constexpr int max_nesting = 200;

  std::string_view s_;
  const std::vector<std::string>& inputs_;
  const std::string& output_;
  std::size_t p_ = 0;
  int nesting_ = 0;
  Expression e_;
};

inline Expression Expression::parse(std::string_view text, const std::vector<std::string>& input_names,
                                    const std::string& output_name) {
  return ExpressionParser(text, input_names, output_name).run();
}

namespace detail {

/// Throws `nlid::Error` if `e`'s text, read with these channel names, names other signals than
/// `e` reads: "u2(t-1)^2" written for the second input reads the first once the inputs are named
/// {u2, u1}, so its printed name and a model file saved under those names would describe another
/// model.
inline void check_expression_names(const Expression& e, const std::vector<std::string>& input_names,
                                   const std::string& output_name) {
  bool same = false;
  try {
    same = Expression::parse(e.text(), input_names, output_name).signals() == e.signals();
  } catch (const Error&) {
    same = false;
  }
  if (same) return;
  std::string list;
  for (std::size_t c = 0; c < input_names.size(); ++c) list += (c ? ", " : "") + input_names[c];
  throw Error("custom regressor '" + e.text() + "' reads other channels than its text names under the input names {" +
                  list + "} (output '" + output_name + "'); rename the channels (u<k> means input k only where no "
                  "channel carries that name) or write the regressor with the channel names",
              at_parameter("input_names"));
}

}  // namespace detail

/// One custom regressor given as an expression: a `Regressor` whose lags are known at run time.
/// Satisfies `Regressor` (sizes `Dynamic`); getreg prints the expression text.
class ExpressionRegressor {
 public:
  /// One regressor.
  static constexpr int num_regressors = 1;
  /// Lags are known at run time only.
  static constexpr int max_output_lag = Dynamic;
  /// Lags are known at run time only.
  static constexpr int max_input_lag = Dynamic;

  /// From a parsed expression.
  explicit ExpressionRegressor(Expression e) : e_(std::move(e)) {}
  /// Parses `text` (throws `nlid::Error` with the column of a bad token).
  explicit ExpressionRegressor(std::string_view text, const std::vector<std::string>& input_names = {},
                               const std::string& output_name = "y1")
      : e_(Expression::parse(text, input_names, output_name)) {}

  /// The expression.
  [[nodiscard]] const Expression& expression() const { return e_; }
  /// One regressor.
  [[nodiscard]] int size() const { return 1; }
  /// Output history needed.
  [[nodiscard]] int output_lag() const { return e_.output_lag(); }
  /// Input history needed.
  [[nodiscard]] int input_lag() const { return e_.input_lag(); }
  /// 1 + the highest input channel read.
  [[nodiscard]] int num_input_channels() const { return e_.num_input_channels(); }
  /// out[0] = expression at the window's time.
  template <LagWindow W>
  void evaluate(const W& w, std::span<typename W::Scalar> out) const {
    out[0] = e_.evaluate(w);
  }
  /// The expression text.
  [[nodiscard]] std::vector<std::string> names(const std::vector<std::string>& /*input_names*/,
                                               const std::string& /*output_name*/) const {
    return {e_.text()};
  }
  /// Throws if the text, read with these channel names, would name other signals than it reads
  /// (see `RegressorList::check_channel_names`).
  void check_channel_names(const std::vector<std::string>& input_names, const std::string& output_name) const {
    detail::check_expression_names(e_, input_names, output_name);
  }

 private:
  Expression e_;
};

/// A custom regressor from its toolbox-style text, e.g.
/// `custom_regressor("max(y1(t-1),90)+min(y1(t-1),15)-105")`. Throws `nlid::Error` with the
/// column of a bad token.
[[nodiscard]] inline ExpressionRegressor custom_regressor(std::string_view text,
                                                          const std::vector<std::string>& input_names = {},
                                                          const std::string& output_name = "y1") {
  return ExpressionRegressor(text, input_names, output_name);
}

/// Regressors chosen at run time: blocks of output lags, input lags (any channel) and custom
/// expressions, in order — the `Regressor` of run-time nonlinear ARX models (models read from
/// files, command-line specifications). Gives the same values and names as the equivalent
/// compile-time `RegressorSet` of `OutputLags`, `InputLags` and custom regressors.
/// Satisfies `Regressor` (all sizes `Dynamic`).
class RegressorList {
 public:
  /// Count known at run time.
  static constexpr int num_regressors = Dynamic;
  /// Known at run time.
  static constexpr int max_output_lag = Dynamic;
  /// Known at run time.
  static constexpr int max_input_lag = Dynamic;

  /// What a block holds.
  enum class Kind { output_lags, input_lags, custom };
  /// One block: y(t−1) … y(t−na); or u_c(t−nk) … u_c(t−nk−nb+1); or one expression.
  struct Block {
    Kind kind = Kind::output_lags;  ///< which kind of block
    int na = 0;                     ///< output lags (output_lags)
    int nb = 0;                     ///< number of input lags (input_lags)
    int nk = 0;                     ///< input delay (input_lags)
    int channel = 0;                ///< 0-based input channel (input_lags)
    Expression expression;          ///< the custom regressor (custom)
  };

  /// No regressors.
  RegressorList() = default;

  /// The standard single-input set of orders [na nb nk] (as `LaggedRegressors`).
  [[nodiscard]] static RegressorList lagged(int na, int nb, int nk) {
    RegressorList r;
    r.add_output_lags(na);
    r.add_input_lags(nb, nk, 0);
    return r;
  }
  /// The standard multi-input set: na output lags, then nb[c] lags of input c from delay nk[c].
  [[nodiscard]] static RegressorList lagged(int na, const std::vector<int>& nb, const std::vector<int>& nk) {
    require(nb.size() == nk.size(), "lagged regressors: " + std::to_string(nb.size()) + " nb orders but " +
                                        std::to_string(nk.size()) + " delays nk",
            at_parameter("nk"));
    RegressorList r;
    r.add_output_lags(na);
    for (std::size_t c = 0; c < nb.size(); ++c) r.add_input_lags(nb[c], nk[c], static_cast<int>(c));
    return r;
  }

  /// Appends y(t−1) … y(t−na). Throws naming "na" if na < 0.
  RegressorList& add_output_lags(int na) {
    require(na >= 0, "model order na must be >= 0, got " + std::to_string(na), at_parameter("na"));
    require(na <= max_model_order,
            "model order na must be <= " + std::to_string(max_model_order) + " (the largest model order), got " +
                std::to_string(na),
            at_parameter("na"));
    Block b;
    b.kind = Kind::output_lags;
    b.na = na;
    return add(std::move(b));
  }
  /// Appends u_c(t−nk) … u_c(t−nk−nb+1). Throws naming "nb", "nk" or "channel".
  RegressorList& add_input_lags(int nb, int nk, int channel = 0) {
    require(nb >= 0, "model order nb must be >= 0, got " + std::to_string(nb), at_parameter("nb"));
    require(nb <= max_model_order,
            "model order nb must be <= " + std::to_string(max_model_order) + " (the largest model order), got " +
                std::to_string(nb),
            at_parameter("nb"));
    require(nk >= 0, "model order nk must be >= 0, got " + std::to_string(nk), at_parameter("nk"));
    require(nk <= max_model_order,
            "model order nk must be <= " + std::to_string(max_model_order) + " (the largest model order), got " +
                std::to_string(nk),
            at_parameter("nk"));
    require(channel >= 0, "input channel must be >= 0, got " + std::to_string(channel), at_parameter("channel"));
    Block b;
    b.kind = Kind::input_lags;
    b.nb = nb;
    b.nk = nk;
    b.channel = channel;
    return add(std::move(b));
  }
  /// Appends a custom regressor. Throws naming "expression" for an empty (default-constructed)
  /// one, which would be a regressor named "" that always reads 0.
  RegressorList& add_custom(Expression e) {
    require(!e.program().empty(), "custom regressor: the expression is empty (build it with Expression::parse)",
            at_parameter("expression"));
    Block b;
    b.kind = Kind::custom;
    b.expression = std::move(e);
    return add(std::move(b));
  }
  /// Appends a custom regressor from text (throws with the column of a bad token).
  RegressorList& add_custom(std::string_view text, const std::vector<std::string>& input_names = {},
                            const std::string& output_name = "y1") {
    return add_custom(Expression::parse(text, input_names, output_name));
  }

  /// The blocks in order.
  [[nodiscard]] const std::vector<Block>& blocks() const { return blocks_; }
  /// Number of regressors.
  [[nodiscard]] int size() const { return static_cast<int>(terms_.size()); }
  /// Output history needed.
  [[nodiscard]] int output_lag() const { return output_lag_; }
  /// Input history needed.
  [[nodiscard]] int input_lag() const { return input_lag_; }
  /// 1 + the highest input channel read.
  [[nodiscard]] int num_input_channels() const { return channels_; }

  /// Every regressor at the window's time, in order.
  template <LagWindow W>
  void evaluate(const W& w, std::span<typename W::Scalar> out) const {
    using T = typename W::Scalar;
    for (std::size_t i = 0; i < terms_.size(); ++i) {
      const Term& t = terms_[i];
      if (t.expression < 0) {
        out[i] = t.signal.is_output ? T(w.y(t.signal.lag)) : T(w.u(t.signal.channel, t.signal.lag));
      } else {
        out[i] = blocks_[static_cast<std::size_t>(t.expression)].expression.evaluate(w);
      }
    }
  }

  /// Throws `nlid::Error` if a custom regressor's text, read with these channel names, would
  /// name other signals than it reads: "u2(t-1)^2" written for the second input reads the first
  /// once the inputs are named {u2, u1}, so its name (describe, getreg) and a model file saved
  /// under those names would describe another model. Every other naming passes.
  void check_channel_names(const std::vector<std::string>& input_names, const std::string& output_name) const {
    for (const Block& b : blocks_)
      if (b.kind == Kind::custom) detail::check_expression_names(b.expression, input_names, output_name);
  }

  /// getreg names: "y1(t-1)", "u1(t)" with the given channel names; custom ones as written.
  [[nodiscard]] std::vector<std::string> names(const std::vector<std::string>& input_names,
                                               const std::string& output_name) const {
    std::vector<std::string> n;
    for (const Term& t : terms_) {
      if (t.expression >= 0) {
        n.push_back(blocks_[static_cast<std::size_t>(t.expression)].expression.text());
      } else if (t.signal.is_output) {
        n.push_back(detail::lag_name(output_name, t.signal.lag));
      } else {
        n.push_back(detail::lag_name(detail::input_name(input_names, t.signal.channel), t.signal.lag));
      }
    }
    return n;
  }

  // ---- Implementation details below ----------------------------------------------------------
 private:
  struct Term {
    SignalRef signal;     // a plain lagged signal, or
    int expression = -1;  // index of the custom block
  };

  RegressorList& add(Block b) {
    const auto index = static_cast<int>(blocks_.size());
    switch (b.kind) {
      case Kind::output_lags:
        for (int k = 1; k <= b.na; ++k) terms_.push_back(Term{SignalRef{true, 0, k}, -1});
        output_lag_ = std::max(output_lag_, b.na);
        break;
      case Kind::input_lags:
        for (int k = 0; k < b.nb; ++k) terms_.push_back(Term{SignalRef{false, b.channel, b.nk + k}, -1});
        // A channel counts as read even with nb = 0, as `InputLags` does.
        channels_ = std::max(channels_, b.channel + 1);
        if (b.nb > 0) input_lag_ = std::max(input_lag_, b.nk + b.nb - 1);
        break;
      case Kind::custom:
        terms_.push_back(Term{SignalRef{}, index});
        output_lag_ = std::max(output_lag_, b.expression.output_lag());
        input_lag_ = std::max(input_lag_, b.expression.input_lag());
        channels_ = std::max(channels_, b.expression.num_input_channels());
        break;
    }
    blocks_.push_back(std::move(b));
    return *this;
  }

  std::vector<Block> blocks_;
  std::vector<Term> terms_;
  int output_lag_ = 0;
  int input_lag_ = 0;
  int channels_ = 0;
};

}  // namespace nlid
