#pragma once
/// @file
/// `TraceScalar`: a scalar that records the arithmetic done on it as C code — how nlid turns a
/// model written once in generic C++ (custom regressors, nonlinearities, grey-box physics) into
/// dependency-free C.
///
/// Idea (operator-overloading code generation; the same trick as the "taping" of operator-
/// overloading AD tools, Griewank & Walther, "Evaluating Derivatives", 2nd ed., 2008, Sec. 6.1):
/// every component of an nlid model is a template on its scalar T, because it must run on
/// `double` and on `Dual`. Run it on a `TraceScalar` instead and each +, −, ·, /, exp, max, …
/// appends one line of static single assignment C to a *tape*:
///
///     const double t7 = (s->x[0] - 45.3) * 0.0212;     // z = (x − r)·(1/s) of a sigmoid net
///     const double t8 = nlid_logistic(t7 * P[4] + P[9]);
///
/// A traced value is one of three kinds:
///  - a *literal* (a constant of the code, e.g. a normalisation centre): printed with 17
///    significant digits, so it reads back to the same double; operations on literals alone are
///    folded at generation time (same IEEE operation, same result);
///  - a *parameter* (`P[3]`): named in the code, its value known while tracing;
///  - a *signal* (an input, a state, and everything computed from them): value unknown.
///
/// Branches. Generic code branches on values (`if (x < lower)` in a saturation, the softplus
/// cases of a smoothed hard stop). A comparison whose operands are all known (literals and
/// parameters) is decided at generation time. A comparison involving a signal cannot be, so the
/// tracer *explores both outcomes*: `trace_paths` re-runs the function with every sequence of
/// outcomes (depth-first), and the recorded paths form a decision tree that is emitted as nested
/// `if (…) { … } else { … }` with the same conditions as the C++ (saturation: 3 paths, smoothed
/// stop: 3 per stop, piecewise-linear map with n breakpoints: n). A limit on the number of
/// paths (`TraceLimits`) turns a combinatorial explosion into an `nlid::Error`.
///
/// Exactness. The generated code performs the same IEEE operations in the same order as nlid's
/// C++ (no re-association, no algebraic simplification, `x >= y ? x : y` for max as in
/// `nlid::max`), so with the same libm it reproduces nlid's simulation to the last bit or
/// within a few ulps — the codegen test demands 1e-12 relative.
///
/// Not supported (clear errors rather than wrong code): converting a traced signal to double
/// (there is no conversion operator, so such code does not compile). Run-time physics
/// (`AnyPhysics`) has `TraceScalar` overloads of its virtual functions for this reason.

#include <cctype>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <memory>
#include <set>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "nlid/ad/dual.hpp"
#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/nonlinearities/detail/common.hpp"

namespace nlid {

namespace codegen {

/// Floating-point type of the generated C. `single_precision` is for targets whose FPU has no
/// double arithmetic (Cortex-M4F/M33, many PLC runtimes), where every `double` operation would be
/// a software routine: the code then holds no double at all — float variables, `f` literals, the
/// `f` functions of <math.h> (expf, …) — and computes nlid's model in float rounding instead of
/// reproducing nlid's double bits.
enum class Precision { double_precision, single_precision };

/// The precision generation is running in (one per thread; `PrecisionScope` sets it).
inline Precision& current_precision() {
  thread_local Precision p = Precision::double_precision;
  return p;
}

/// Sets `current_precision()` for its lifetime (each `generate_c` holds one).
class PrecisionScope {
 public:
  explicit PrecisionScope(Precision p) : previous_(current_precision()) { current_precision() = p; }
  ~PrecisionScope() { current_precision() = previous_; }
  PrecisionScope(const PrecisionScope&) = delete;
  PrecisionScope& operator=(const PrecisionScope&) = delete;

 private:
  Precision previous_;
};

/// True while generating single-precision C.
inline bool single_precision() { return current_precision() == Precision::single_precision; }

/// The C type of real values: "double" or "float".
inline std::string c_real() { return single_precision() ? "float" : "double"; }

/// The <math.h> function `fn` for the current precision ("exp" or "expf").
inline std::string c_math(const std::string& fn) { return single_precision() ? fn + "f" : fn; }

/// True if `v` rounds to infinity as a float: at or past the midpoint between FLT_MAX and 2^128
/// (the conversion of such a double is undefined behaviour in C++).
inline bool beyond_float_range(double v) { return std::abs(v) >= 0x1.ffffffp127; }

/// A C99 literal of the current precision. Double: reads back to exactly `v` (17 significant
/// digits). Single: `v` rounded to the nearest float, 9 significant digits and an `f` suffix
/// (reads back to that float). HUGE_VAL(F)/NAN for the non-finite values (and for doubles
/// beyond float's range in single precision); negative values parenthesised.
inline std::string c_literal(double v) {
  const bool single = single_precision();
  if (std::isnan(v)) return "NAN";
  // Beyond float's range the literal is spelt as an infinity.
  const bool overflow = single && beyond_float_range(v);
  const double shown = overflow ? std::copysign(std::numeric_limits<double>::infinity(), v)
                       : single ? static_cast<double>(static_cast<float>(v))
                                : v;
  if (std::isinf(shown)) {
    const char* huge = single ? "HUGE_VALF" : "HUGE_VAL";
    return shown > 0 ? std::string(huge) : "(-" + std::string(huge) + ")";
  }
  // Not snprintf: it follows LC_NUMERIC, and "0,5" in an initialiser list is two numbers.
  std::string s = nlid::detail::format_g(shown, single ? 9 : 17);
  if (s.find_first_of(".e") == std::string::npos) s += ".0";
  if (single) s += "f";
  return shown < 0 || (shown == 0 && std::signbit(shown)) ? "(" + s + ")" : s;
}

/// Bounds on tracing: more paths than this is reported as an error (a branchy function of many
/// signals would generate exponential code).
struct TraceLimits {
  int max_paths = 4096;       ///< decision-tree leaves
  int max_lines = 2000000;    ///< total SSA lines over all paths
};

/// The record of one run of a traced function: SSA lines, decisions, C helpers used.
class Tape {
 public:
  /// One event: a line "const double tN = rhs;" or a decision on a C condition.
  struct Event {
    bool is_decision = false;  ///< false: an SSA line
    std::string text;          ///< the line's right-hand side, or the condition
    int temp = -1;             ///< temp number of a line
    bool outcome = false;      ///< outcome of a decision
  };

  /// A tape whose first decisions follow `script` (true/false); later ones take `true`.
  explicit Tape(std::vector<bool> script = {}) : script_(std::move(script)) {}

  /// Appends an SSA line and returns the temp's name.
  std::string emit(std::string rhs) {
    Event e;
    e.text = std::move(rhs);
    e.temp = next_temp_++;
    events_.push_back(std::move(e));
    return temp_name(events_.back().temp);
  }
  /// Decides a condition on a signal: the scripted outcome, or `true` beyond the script.
  bool decide(std::string condition) {
    const bool outcome = decisions_ < script_.size() ? script_[decisions_] : true;
    ++decisions_;
    Event e;
    e.is_decision = true;
    e.text = std::move(condition);
    e.outcome = outcome;
    events_.push_back(std::move(e));
    return outcome;
  }
  /// Marks a C helper function (e.g. "nlid_logistic") as needed by the generated code.
  void use_helper(const std::string& name) { helpers_.insert(name); }

  /// Events in order.
  [[nodiscard]] const std::vector<Event>& events() const { return events_; }
  /// Helpers used.
  [[nodiscard]] const std::set<std::string>& helpers() const { return helpers_; }
  /// Name of temp number n.
  static std::string temp_name(int n) { return "t" + std::to_string(n); }

  /// The tape that traced operations append to (one per thread; null outside a trace).
  static Tape*& active() {
    thread_local Tape* tape = nullptr;
    return tape;
  }

 private:
  std::vector<bool> script_;
  std::size_t decisions_ = 0;
  int next_temp_ = 0;
  std::vector<Event> events_;
  std::set<std::string> helpers_;
};

}  // namespace codegen

/// Scalar that records operations as C code (file comment). Generic nlid code runs on it the
/// way it runs on `double` or `Dual`.
class TraceScalar {
 public:
  /// Literal 0 (spelled in the current precision).
  TraceScalar() : TraceScalar(0.0) {}
  /// A literal constant (implicit, as `T(0.5)` and mixed arithmetic with doubles need).
  TraceScalar(double v) : ref_(codegen::c_literal(v)), value_(v), kind_(Kind::literal) {}  // NOLINT
  /// Arithmetic constants of other types (`T(2)`).
  template <class I>
    requires(std::is_arithmetic_v<I> && !std::is_same_v<I, double>)
  TraceScalar(I v) : TraceScalar(static_cast<double>(v)) {}  // NOLINT

  /// A signal: C expression `c_name` (e.g. "u[0]", "s->x[2]") whose value is unknown.
  static TraceScalar signal(std::string c_name) { return TraceScalar(std::move(c_name), 0.0, Kind::signal); }
  /// A parameter: C expression `c_name` (e.g. "P[3]") with known value `value`.
  static TraceScalar parameter(std::string c_name, double value) {
    return TraceScalar(std::move(c_name), value, Kind::parameter);
  }

  /// The C expression naming this value (a literal, a variable or a temp).
  [[nodiscard]] const std::string& expr() const { return ref_; }
  /// True unless the value depends on a signal.
  [[nodiscard]] bool known() const { return kind_ != Kind::signal; }
  /// True for a literal constant.
  [[nodiscard]] bool is_literal() const { return kind_ == Kind::literal; }
  /// The value (meaningful only if `known()`).
  [[nodiscard]] double value() const { return value_; }

  TraceScalar& operator+=(const TraceScalar& o) { return *this = *this + o; }
  TraceScalar& operator-=(const TraceScalar& o) { return *this = *this - o; }
  TraceScalar& operator*=(const TraceScalar& o) { return *this = *this * o; }
  TraceScalar& operator/=(const TraceScalar& o) { return *this = *this / o; }

  /// Sum (C `a + b`).
  friend TraceScalar operator+(const TraceScalar& a, const TraceScalar& b) {
    return binary(a, b, "+", a.value_ + b.value_);
  }
  /// Difference.
  friend TraceScalar operator-(const TraceScalar& a, const TraceScalar& b) {
    return binary(a, b, "-", a.value_ - b.value_);
  }
  /// Product.
  friend TraceScalar operator*(const TraceScalar& a, const TraceScalar& b) {
    return binary(a, b, "*", a.value_ * b.value_);
  }
  /// Quotient.
  friend TraceScalar operator/(const TraceScalar& a, const TraceScalar& b) {
    return binary(a, b, "/", a.value_ / b.value_);
  }
  /// Negation.
  friend TraceScalar operator-(const TraceScalar& a) {
    if (a.is_literal()) return TraceScalar(-a.value_);
    return make("-" + a.ref_, -a.value_, a.known());
  }
  /// Unary plus (identity).
  friend TraceScalar operator+(const TraceScalar& a) { return a; }

  /// Comparisons: decided now if both sides are known, else explored (see `trace_paths`).
  friend bool operator<(const TraceScalar& a, const TraceScalar& b) { return compare(a, b, "<", a.value_ < b.value_); }
  friend bool operator<=(const TraceScalar& a, const TraceScalar& b) { return compare(a, b, "<=", a.value_ <= b.value_); }
  friend bool operator>(const TraceScalar& a, const TraceScalar& b) { return compare(a, b, ">", a.value_ > b.value_); }
  friend bool operator>=(const TraceScalar& a, const TraceScalar& b) { return compare(a, b, ">=", a.value_ >= b.value_); }
  friend bool operator==(const TraceScalar& a, const TraceScalar& b) { return compare(a, b, "==", a.value_ == b.value_); }
  friend bool operator!=(const TraceScalar& a, const TraceScalar& b) { return compare(a, b, "!=", a.value_ != b.value_); }

  /// Emits (or folds) `fn(a)`; `v` is the folded value when `a` is known.
  /// `fn` is the double function's C name; single-precision code calls its `f` twin.
  static TraceScalar call(const char* fn, const TraceScalar& a, double v) {
    if (a.is_literal()) return TraceScalar(v);
    return make(codegen::c_math(fn) + "(" + a.ref_ + ")", v, a.known());
  }
  /// Emits (or folds) `fn(a, b)`.
  static TraceScalar call(const char* fn, const TraceScalar& a, const TraceScalar& b, double v) {
    if (a.is_literal() && b.is_literal()) return TraceScalar(v);
    return make(codegen::c_math(fn) + "(" + a.ref_ + ", " + b.ref_ + ")", v, a.known() && b.known());
  }
  /// Emits `(a OP b ? x : y)` — a branch-free select with the semantics of `nlid::max/min`.
  static TraceScalar select(const TraceScalar& a, const char* op, const TraceScalar& b, const TraceScalar& x,
                            const TraceScalar& y, bool known_outcome) {
    const bool all_known = a.known() && b.known() && x.known() && y.known();
    if (a.known() && b.known()) return known_outcome ? x : y;
    return make("(" + a.ref_ + " " + op + " " + b.ref_ + " ? " + x.ref_ + " : " + y.ref_ + ")", 0.0, all_known);
  }
  /// Emits a call of a generated C helper function (e.g. "nlid_logistic").
  static TraceScalar helper(const char* fn, const TraceScalar& a, double v) {
    if (a.is_literal()) return TraceScalar(v);
    if (codegen::Tape* t = codegen::Tape::active()) t->use_helper(fn);
    return make(std::string(fn) + "(" + a.ref_ + ")", v, a.known());
  }

 private:
  enum class Kind { literal, parameter, signal };

  static codegen::Tape& tape() {
    codegen::Tape* t = codegen::Tape::active();
    require(t != nullptr, "TraceScalar: an operation on a traced signal or parameter outside a trace "
                          "(use nlid::codegen::trace_paths)",
            at_parameter("TraceScalar"));
    return *t;
  }
  TraceScalar(std::string ref, double v, Kind kind) : ref_(std::move(ref)), value_(v), kind_(kind) {}

  static TraceScalar make(std::string rhs, double v, bool known) {
    return TraceScalar(tape().emit(std::move(rhs)), known ? v : 0.0, known ? Kind::parameter : Kind::signal);
  }
  static TraceScalar binary(const TraceScalar& a, const TraceScalar& b, const char* op, double v) {
    if (a.is_literal() && b.is_literal()) return TraceScalar(v);
    return make(a.ref_ + " " + op + " " + b.ref_, v, a.known() && b.known());
  }
  static bool compare(const TraceScalar& a, const TraceScalar& b, const char* op, bool v) {
    if (a.known() && b.known()) return v;
    return tape().decide(a.ref_ + " " + op + " " + b.ref_);
  }

  std::string ref_;
  double value_ = 0.0;
  Kind kind_ = Kind::literal;
};

// ---- math on traced scalars (found by ADL and as nlid::f) ------------------------------------
// Each folds on literals with the same std:: function the C library provides under that name.

/// |x| (C fabs).
inline TraceScalar abs(const TraceScalar& x) { return TraceScalar::call("fabs", x, std::abs(x.value())); }
/// |x| (C fabs).
inline TraceScalar fabs(const TraceScalar& x) { return abs(x); }
/// e^x.
inline TraceScalar exp(const TraceScalar& x) { return TraceScalar::call("exp", x, std::exp(x.value())); }
/// e^x − 1.
inline TraceScalar expm1(const TraceScalar& x) { return TraceScalar::call("expm1", x, std::expm1(x.value())); }
/// ln x.
inline TraceScalar log(const TraceScalar& x) { return TraceScalar::call("log", x, std::log(x.value())); }
/// ln(1 + x).
inline TraceScalar log1p(const TraceScalar& x) { return TraceScalar::call("log1p", x, std::log1p(x.value())); }
/// log₁₀ x.
inline TraceScalar log10(const TraceScalar& x) { return TraceScalar::call("log10", x, std::log10(x.value())); }
/// √x.
inline TraceScalar sqrt(const TraceScalar& x) { return TraceScalar::call("sqrt", x, std::sqrt(x.value())); }
/// ∛x.
inline TraceScalar cbrt(const TraceScalar& x) { return TraceScalar::call("cbrt", x, std::cbrt(x.value())); }
/// sin x.
inline TraceScalar sin(const TraceScalar& x) { return TraceScalar::call("sin", x, std::sin(x.value())); }
/// cos x.
inline TraceScalar cos(const TraceScalar& x) { return TraceScalar::call("cos", x, std::cos(x.value())); }
/// tan x.
inline TraceScalar tan(const TraceScalar& x) { return TraceScalar::call("tan", x, std::tan(x.value())); }
/// asin x.
inline TraceScalar asin(const TraceScalar& x) { return TraceScalar::call("asin", x, std::asin(x.value())); }
/// acos x.
inline TraceScalar acos(const TraceScalar& x) { return TraceScalar::call("acos", x, std::acos(x.value())); }
/// atan x.
inline TraceScalar atan(const TraceScalar& x) { return TraceScalar::call("atan", x, std::atan(x.value())); }
/// sinh x.
inline TraceScalar sinh(const TraceScalar& x) { return TraceScalar::call("sinh", x, std::sinh(x.value())); }
/// cosh x.
inline TraceScalar cosh(const TraceScalar& x) { return TraceScalar::call("cosh", x, std::cosh(x.value())); }
/// tanh x.
inline TraceScalar tanh(const TraceScalar& x) { return TraceScalar::call("tanh", x, std::tanh(x.value())); }
/// erf x.
inline TraceScalar erf(const TraceScalar& x) { return TraceScalar::call("erf", x, std::erf(x.value())); }
/// ⌊x⌋.
inline TraceScalar floor(const TraceScalar& x) { return TraceScalar::call("floor", x, std::floor(x.value())); }
/// ⌈x⌉.
inline TraceScalar ceil(const TraceScalar& x) { return TraceScalar::call("ceil", x, std::ceil(x.value())); }
/// x².
inline TraceScalar square(const TraceScalar& x) { return x * x; }
/// xʸ.
inline TraceScalar pow(const TraceScalar& x, const TraceScalar& y) {
  return TraceScalar::call("pow", x, y, std::pow(x.value(), y.value()));
}
/// atan2(y, x).
inline TraceScalar atan2(const TraceScalar& y, const TraceScalar& x) {
  return TraceScalar::call("atan2", y, x, std::atan2(y.value(), x.value()));
}
/// √(x² + y²).
inline TraceScalar hypot(const TraceScalar& x, const TraceScalar& y) {
  return TraceScalar::call("hypot", x, y, std::hypot(x.value(), y.value()));
}
/// Larger value, `x >= y ? x : y` as `nlid::max` (ties take the first argument).
inline TraceScalar max(const TraceScalar& x, const TraceScalar& y) {
  return TraceScalar::select(x, ">=", y, x, y, x.value() >= y.value());
}
/// Smaller value, `x <= y ? x : y` as `nlid::min`.
inline TraceScalar min(const TraceScalar& x, const TraceScalar& y) {
  return TraceScalar::select(x, "<=", y, x, y, x.value() <= y.value());
}
/// max with a constant on the right (`nlid::max(y1, 90.0)` in a custom regressor).
inline TraceScalar max(const TraceScalar& x, double y) { return max(x, TraceScalar(y)); }
/// max with a constant on the left.
inline TraceScalar max(double x, const TraceScalar& y) { return max(TraceScalar(x), y); }
/// min with a constant on the right.
inline TraceScalar min(const TraceScalar& x, double y) { return min(x, TraceScalar(y)); }
/// min with a constant on the left.
inline TraceScalar min(double x, const TraceScalar& y) { return min(TraceScalar(x), y); }
/// Hooks of the generic `nlid::max` / `nlid::min` (ad/dual.hpp): they reach the overloads above
/// from code compiled before this header was included.
inline TraceScalar scalar_max(const TraceScalar& x, const TraceScalar& y) { return max(x, y); }
inline TraceScalar scalar_max(const TraceScalar& x, double y) { return max(x, y); }
inline TraceScalar scalar_max(double x, const TraceScalar& y) { return max(x, y); }
inline TraceScalar scalar_min(const TraceScalar& x, const TraceScalar& y) { return min(x, y); }
inline TraceScalar scalar_min(const TraceScalar& x, double y) { return min(x, y); }
inline TraceScalar scalar_min(double x, const TraceScalar& y) { return min(x, y); }
/// The "value part" of a traced scalar is itself, so `if (value_of(s) >= 0)` becomes a traced
/// decision (or a known one).
inline TraceScalar value_of(const TraceScalar& x) { return x; }
/// Finite test: known values now, signals as a traced decision on C99 `isfinite`.
inline bool isfinite(const TraceScalar& x) {
  if (x.known()) return std::isfinite(x.value());
  codegen::Tape* t = codegen::Tape::active();
  require(t != nullptr, "TraceScalar: isfinite outside a trace", at_parameter("TraceScalar"));
  return t->decide("isfinite(" + x.expr() + ")");
}
/// NaN test: known values now, signals as a traced decision.
inline bool isnan(const TraceScalar& x) {
  if (x.known()) return std::isnan(x.value());
  codegen::Tape* t = codegen::Tape::active();
  require(t != nullptr, "TraceScalar: isnan outside a trace", at_parameter("TraceScalar"));
  return t->decide("isnan(" + x.expr() + ")");
}

namespace detail {
/// The sigmoid networks' logistic function becomes a call of the generated helper
/// `nlid_logistic`, which performs the operations of nlid's double logistic (the batch kernel of
/// core/batch.hpp), instead of 2ⁿ traced paths for n units.
template <>
inline TraceScalar logistic<TraceScalar>(const TraceScalar& s) {
  const double v = s.value();
  const double folded = logistic(v);  // nlid's own double logistic, which the helper reproduces
  return TraceScalar::helper("nlid_logistic", s, folded);
}
}  // namespace detail

namespace codegen {

/// C source of a helper function the traced code may call, by name.
inline std::string helper_source(const std::string& name) {
  if (name == "nlid_logistic" && single_precision()) {
    // float: libm's expf in the form that cannot overflow (e^(-|s|) <= 1); NaN stays NaN.
    return "/* logistic 1/(1+exp(-s)) in float; exp of a non-positive argument only */\n"
           "static float nlid_logistic(float s) {\n"
           "  if (s >= 0.0f) return 1.0f / (1.0f + expf(-s));\n"
           "  {\n"
           "    const float e = expf(s);\n"
           "    return e / (1.0f + e);\n"
           "  }\n"
           "}\n";
  }
  if (name == "nlid_logistic") {
    // The operations of nlid::detail::logistic_lanes (core/batch.hpp) in the same order, so the
    // generated code computes nlid's numbers bit for bit (when the C compiler does not contract
    // a*b+c into fused multiply-adds: compile with -ffp-contract=off on FMA targets).
    return "/* logistic 1/(1+exp(-s)) as nlid computes it: exp(-s) = 2^k (Q+P)/(Q-P) after a\n"
           "   Cody-Waite reduction (Cephes' rational form), one division; |s| > 708 or NaN by libm */\n"
           "static double nlid_logistic(double s) {\n"
           "  union { double d; unsigned long long u; } kb, tk;\n"
           "  const double x = -s;\n"
           "  if (!(s >= -708.0 && s <= 708.0)) {\n"
           "    if (s >= 0) return 1.0 / (1.0 + exp(-s));\n"
           "    return exp(s) / (1.0 + exp(s));\n"
           "  }\n"
           "  const double kd = x * 1.4426950408889634074 + 6755399441055744.0;\n"
           "  kb.d = kd;\n"
           "  const unsigned long long k = kb.u - 0x4338000000000000ULL;\n"
           "  const double kf = kd - 6755399441055744.0;\n"
           "  const double r = (x - kf * 6.93147180369123816490e-01) - kf * 1.90821492927058770002e-10;\n"
           "  const double rr = r * r;\n"
           "  const double r4 = rr * rr;\n"
           "  const double px = r * ((3.02994407707441961300e-2 * rr + 9.99999999999999999910e-1) + 1.26177193074810590878e-4 * r4);\n"
           "  const double qx = (3.00198505138664455042e-6 * rr + 2.52448340349684104192e-3) * r4 + (2.27265548208155028766e-1 * rr + 2.00000000000000000009e0);\n"
           "  tk.u = (k + 1023ULL) << 52;\n"
           "  const double den = qx - px;\n"
           "  return den / (den + tk.d * (qx + px));\n"
           "}\n";
  }
  throw Error("codegen: unknown helper function '" + name + "'", at_parameter("helper"));
}

/// A node of the decision tree of a traced function.
struct TraceNode {
  std::vector<Tape::Event> lines;        ///< SSA lines executed at this node
  std::string condition;                 ///< decision at the end (empty: leaf)
  std::unique_ptr<TraceNode> if_true;    ///< subtree when the condition holds
  std::unique_ptr<TraceNode> if_false;   ///< subtree otherwise
  std::vector<std::string> outputs;      ///< leaf: C expressions of the outputs
};

/// A traced function: its decision tree and the C helpers it uses.
struct TracedFunction {
  std::unique_ptr<TraceNode> root;  ///< decision tree
  std::set<std::string> helpers;    ///< helper functions called
  int paths = 0;                    ///< number of leaves
};

/// Runs `fn` (returning std::vector<TraceScalar>) under every sequence of outcomes of its
/// signal-dependent decisions and assembles the decision tree (file comment). Throws
/// `nlid::Error` if the function takes more paths or lines than `limits` allow, or decides
/// differently on a replayed prefix (it is not deterministic).
template <class Fn>
TracedFunction trace_paths(Fn&& fn, const TraceLimits& limits = {}) {
  TracedFunction out;
  out.root = std::make_unique<TraceNode>();
  std::vector<bool> script;
  long total_lines = 0;
  for (;;) {
    Tape tape(script);
    struct Activate {
      Tape* previous;
      explicit Activate(Tape* t) : previous(Tape::active()) { Tape::active() = t; }
      ~Activate() { Tape::active() = previous; }
    };
    std::vector<TraceScalar> result;
    {
      Activate guard(&tape);
      result = fn();
    }
    ++out.paths;
    require(out.paths <= limits.max_paths,
            "codegen: the traced function branches on its signals into more than " + std::to_string(limits.max_paths) +
                " paths; generated code would be exponential (simplify the branches or raise TraceLimits::max_paths)",
            at_parameter("max_paths"));
    total_lines += static_cast<long>(tape.events().size());
    require(total_lines <= limits.max_lines, "codegen: traced code exceeds " + std::to_string(limits.max_lines) + " lines",
            at_parameter("max_lines"));
    out.helpers.insert(tape.helpers().begin(), tape.helpers().end());
    // Insert the path into the tree.
    TraceNode* node = out.root.get();
    bool fresh = out.paths == 1;
    std::vector<bool> taken;
    for (const auto& e : tape.events()) {
      if (!e.is_decision) {
        if (fresh) node->lines.push_back(e);
        continue;
      }
      require(node->condition.empty() || node->condition == e.text,
              "codegen: the traced function is not deterministic (different decision '" + e.text + "' after '" +
                  node->condition + "')",
              at_parameter("fn"));
      node->condition = e.text;
      taken.push_back(e.outcome);
      std::unique_ptr<TraceNode>& child = e.outcome ? node->if_true : node->if_false;
      fresh = !child;
      if (!child) child = std::make_unique<TraceNode>();
      node = child.get();
    }
    for (const auto& r : result) node->outputs.push_back(r.expr());
    // Next path: flip the last `true` decision, drop everything after it.
    while (!taken.empty() && !taken.back()) taken.pop_back();
    if (taken.empty()) break;
    taken.back() = false;
    script = taken;
  }
  return out;
}

namespace detail {
inline void collect_temps(const std::string& text, std::set<int>& used) {
  for (std::size_t i = 0; i < text.size(); ++i) {
    const bool start = text[i] == 't' && (i == 0 || !(std::isalnum(static_cast<unsigned char>(text[i - 1])) ||
                                                        text[i - 1] == '_' || text[i - 1] == '>' || text[i - 1] == '.'));
    if (!start) continue;
    std::size_t j = i + 1;
    while (j < text.size() && std::isdigit(static_cast<unsigned char>(text[j]))) ++j;
    if (j > i + 1 && (j == text.size() || !(std::isalnum(static_cast<unsigned char>(text[j])) || text[j] == '_')))
      used.insert(std::stoi(text.substr(i + 1, j - i - 1)));
    i = j - 1;
  }
}

// Emits a node and returns the temps it (and its subtree) reads from enclosing scopes; lines
// whose temp is never read on any path below are dropped (no unused variables in the C).
inline std::set<int> emit_node(const TraceNode& n, const std::vector<std::string>& targets, const std::string& indent,
                               std::string& code) {
  std::set<int> used;
  std::string tail;
  if (n.condition.empty()) {
    require(n.outputs.size() == targets.size(), "codegen: traced function returned " + std::to_string(n.outputs.size()) +
                                                    " values for " + std::to_string(targets.size()) + " outputs",
            at_parameter("fn"));
    for (std::size_t i = 0; i < targets.size(); ++i) {
      tail += indent + targets[i] + " = " + n.outputs[i] + ";\n";
      collect_temps(n.outputs[i], used);
    }
  } else {
    std::string t_code, f_code;
    const std::set<int> ut = n.if_true ? emit_node(*n.if_true, targets, indent + "  ", t_code) : std::set<int>{};
    const std::set<int> uf = n.if_false ? emit_node(*n.if_false, targets, indent + "  ", f_code) : std::set<int>{};
    used.insert(ut.begin(), ut.end());
    used.insert(uf.begin(), uf.end());
    collect_temps(n.condition, used);
    tail = indent + "if (" + n.condition + ") {\n" + t_code + indent + "} else {\n" + f_code + indent + "}\n";
  }
  std::vector<std::string> kept;
  for (auto it = n.lines.rbegin(); it != n.lines.rend(); ++it) {
    if (!used.count(it->temp)) continue;
    used.erase(it->temp);
    collect_temps(it->text, used);
    kept.push_back(indent + "const " + c_real() + " " + Tape::temp_name(it->temp) + " = " + it->text + ";\n");
  }
  for (auto it = kept.rbegin(); it != kept.rend(); ++it) code += *it;
  code += tail;
  return used;
}
}  // namespace detail

/// C statements evaluating a traced function and assigning its outputs to `targets` (C
/// lvalues, one per output), indented by `indent`.
inline std::string emit_c(const TracedFunction& f, const std::vector<std::string>& targets,
                          const std::string& indent = "  ") {
  std::string code;
  detail::emit_node(*f.root, targets, indent, code);
  return code;
}

}  // namespace codegen
}  // namespace nlid
