#pragma once
/// @file
/// Forward-mode automatic differentiation: the dual number `Dual<T, N>`.
///
/// A dual number carries a value and its gradient with respect to N seeded variables:
///
///     x = a + v·ε,   ε² = 0,   a ∈ T, v ∈ Tᴺ.
///
/// Evaluating any function built from the overloads below on duals yields f(a) and the
/// directional derivatives ∇f(a)·v exactly (to rounding), with no truncation error as finite
/// differences have. Seeding variable k with v = e_k gives the whole gradient in one pass.
///
/// Design choices (following Ceres' Jet rather than Eigen's AutoDiffScalar):
/// - a plain value type, no expression templates: every operation evaluates at once, so a
///   result never aliases a temporary and the compiler sees straight-line code it can vectorise;
/// - `N` is a compile-time size (the derivative vector lives on the stack, no allocation), with
///   the runtime twin `Dual<T, Dynamic>` for parameter counts known only at run time. In the
///   dynamic twin an empty `v` means "constant" (all-zero gradient); operations accept mixing
///   empty and sized gradients, so constants need not be padded with zeros.
///
/// Every overload states the derivative rule it implements in a one-line comment.
/// Reference: Griewank & Walther, "Evaluating Derivatives", 2nd ed., SIAM 2008, ch. 3.

#include <cmath>
#include <limits>
#include <ostream>
#include <type_traits>

#include <Eigen/Core>

#include "nlid/core/sizes.hpp"

namespace nlid {

/// Dual number with value `a` of type T and N derivative components `v`.
/// Invariant (fixed N): `v` always has N entries. (Dynamic N): `v` is empty (constant) or has the
/// size chosen by the seeding code; all sized operands of one expression share that size.
template <class T, int N>
struct Dual {
  using Scalar = T;
  using Gradient = Eigen::Matrix<T, N, 1>;
  static constexpr int num_derivatives = N;

  T a{};       ///< value
  Gradient v;  ///< derivatives

  /// Zero value, zero gradient.
  Dual() : a(T(0)) { set_zero_gradient(); }
  /// A constant: value `x`, zero gradient. Implicit, so `2.0 * dual` and Eigen literals work.
  Dual(T x) : a(x) { set_zero_gradient(); }  // NOLINT(google-explicit-constructor)
  /// Integer constants (e.g. Eigen's `Scalar(0)`, `Scalar(1)`).
  template <class I, std::enable_if_t<std::is_integral_v<I>, int> = 0>
  Dual(I x) : Dual(T(x)) {}  // NOLINT(google-explicit-constructor)
  /// Value and gradient.
  Dual(T x, const Gradient& g) : a(x), v(g) {}

  /// The independent variable number `k` of `n` (n is used only for the dynamic twin).
  static Dual variable(T x, int k, int n = N) {
    Dual d;
    d.a = x;
    d.v = Gradient::Zero(n);
    d.v[k] = T(1);
    return d;
  }

  Dual& operator+=(const Dual& o) { a += o.a; add_grad(o.v, T(1)); return *this; }
  Dual& operator-=(const Dual& o) { a -= o.a; add_grad(o.v, T(-1)); return *this; }
  // (xy)' = x'y + xy'
  Dual& operator*=(const Dual& o) { scale_grad(o.a); add_grad(o.v, a); a *= o.a; return *this; }
  // (x/y)' = (x' - (x/y) y') / y
  Dual& operator/=(const Dual& o) {
    const T inv = T(1) / o.a;
    a *= inv;
    scale_grad(inv);
    add_grad(o.v, -a * inv);
    return *this;
  }
  Dual& operator+=(T s) { a += s; return *this; }
  Dual& operator-=(T s) { a -= s; return *this; }
  Dual& operator*=(T s) { a *= s; scale_grad(s); return *this; }
  Dual& operator/=(T s) { const T inv = T(1) / s; a *= inv; scale_grad(inv); return *this; }

 private:
  void set_zero_gradient() {
    if constexpr (N != Dynamic) v.setZero();
  }
  void scale_grad(T s) { v *= s; }
  // v += s * g, where either side may be empty (constant) in the dynamic twin.
  void add_grad(const Gradient& g, T s) {
    if constexpr (N == Dynamic) {
      if (g.size() == 0) return;
      if (v.size() == 0) { v = s * g; return; }
    }
    v += s * g;
  }
};

/// Dual with a runtime number of derivatives.
template <class T>
using DynamicDual = Dual<T, Dynamic>;

// ---- trait helpers ----------------------------------------------------------------------------

/// True for any `Dual<T, N>`.
template <class X>
struct is_dual : std::false_type {};
template <class T, int N>
struct is_dual<Dual<T, N>> : std::true_type {};
template <class X>
inline constexpr bool is_dual_v = is_dual<std::remove_cvref_t<X>>::value;

/// The value part of a scalar: `x.a` for a dual (recursively), `x` otherwise.
template <class X>
constexpr auto value_of(const X& x) {
  if constexpr (is_dual_v<X>) {
    return value_of(x.a);
  } else {
    return x;
  }
}

// ---- arithmetic -------------------------------------------------------------------------------

template <class T, int N> Dual<T, N> operator+(const Dual<T, N>& x) { return x; }
// (-x)' = -x'
template <class T, int N> Dual<T, N> operator-(const Dual<T, N>& x) { return Dual<T, N>(-x.a, -x.v); }
// (x+y)' = x' + y'
template <class T, int N> Dual<T, N> operator+(Dual<T, N> x, const Dual<T, N>& y) { return x += y; }
// (x-y)' = x' - y'
template <class T, int N> Dual<T, N> operator-(Dual<T, N> x, const Dual<T, N>& y) { return x -= y; }
// (xy)' = x'y + xy'
template <class T, int N> Dual<T, N> operator*(Dual<T, N> x, const Dual<T, N>& y) { return x *= y; }
// (x/y)' = (x'y - xy')/y²
template <class T, int N> Dual<T, N> operator/(Dual<T, N> x, const Dual<T, N>& y) { return x /= y; }

// Mixed with a plain scalar: the scalar has zero derivative.
template <class T, int N> Dual<T, N> operator+(Dual<T, N> x, T s) { return x += s; }
template <class T, int N> Dual<T, N> operator+(T s, Dual<T, N> x) { return x += s; }
template <class T, int N> Dual<T, N> operator-(Dual<T, N> x, T s) { return x -= s; }
// (s - x)' = -x'
template <class T, int N> Dual<T, N> operator-(T s, const Dual<T, N>& x) { return Dual<T, N>(s - x.a, -x.v); }
template <class T, int N> Dual<T, N> operator*(Dual<T, N> x, T s) { return x *= s; }
template <class T, int N> Dual<T, N> operator*(T s, Dual<T, N> x) { return x *= s; }
template <class T, int N> Dual<T, N> operator/(Dual<T, N> x, T s) { return x /= s; }
// (s/x)' = -s x'/x²
template <class T, int N> Dual<T, N> operator/(T s, const Dual<T, N>& x) {
  const T inv = T(1) / x.a;
  const T r = s * inv;
  return Dual<T, N>(r, x.v * (-r * inv));
}

// ---- comparisons: on the value only (derivatives do not order numbers) --------------------------

#define NLID_DUAL_COMPARE(op)                                                                    \
  template <class T, int N> bool operator op(const Dual<T, N>& x, const Dual<T, N>& y) { return x.a op y.a; } \
  template <class T, int N> bool operator op(const Dual<T, N>& x, T s) { return x.a op s; }     \
  template <class T, int N> bool operator op(T s, const Dual<T, N>& x) { return s op x.a; }
NLID_DUAL_COMPARE(<)
NLID_DUAL_COMPARE(<=)
NLID_DUAL_COMPARE(>)
NLID_DUAL_COMPARE(>=)
NLID_DUAL_COMPARE(==)
NLID_DUAL_COMPARE(!=)
#undef NLID_DUAL_COMPARE

// ---- elementary functions ---------------------------------------------------------------------
// Each applies the chain rule f(x)' = f'(a)·x'. Helper: make a dual from value and slope.
namespace detail {
template <class T, int N>
Dual<T, N> chain(const Dual<T, N>& x, T fa, T slope) {
  return Dual<T, N>(fa, x.v * slope);
}
}  // namespace detail

using std::abs, std::exp, std::log, std::sqrt, std::sin, std::cos, std::tan, std::tanh,
    std::sinh, std::cosh, std::atan, std::asin, std::acos, std::pow, std::atan2, std::floor,
    std::ceil, std::cbrt, std::log1p, std::expm1, std::hypot, std::erf;

// |x|' = sign(x) x'   (the derivative at 0 is taken as 0's right limit +1, like Ceres)
template <class T, int N> Dual<T, N> abs(const Dual<T, N>& x) { return x.a < T(0) ? -x : x; }
// exp(x)' = exp(x) x'
template <class T, int N> Dual<T, N> exp(const Dual<T, N>& x) { const T e = exp(x.a); return detail::chain(x, e, e); }
// expm1(x)' = exp(x) x'
template <class T, int N> Dual<T, N> expm1(const Dual<T, N>& x) { return detail::chain(x, expm1(x.a), exp(x.a)); }
// log(x)' = x'/x
template <class T, int N> Dual<T, N> log(const Dual<T, N>& x) { return detail::chain(x, log(x.a), T(1) / x.a); }
// log1p(x)' = x'/(1+x)
template <class T, int N> Dual<T, N> log1p(const Dual<T, N>& x) { return detail::chain(x, log1p(x.a), T(1) / (T(1) + x.a)); }
// sqrt(x)' = x'/(2 sqrt(x))
template <class T, int N> Dual<T, N> sqrt(const Dual<T, N>& x) { const T s = sqrt(x.a); return detail::chain(x, s, T(0.5) / s); }
// cbrt(x)' = x'/(3 cbrt(x)²)
template <class T, int N> Dual<T, N> cbrt(const Dual<T, N>& x) { const T c = cbrt(x.a); return detail::chain(x, c, T(1) / (T(3) * c * c)); }
// sin(x)' = cos(x) x'
template <class T, int N> Dual<T, N> sin(const Dual<T, N>& x) { return detail::chain(x, sin(x.a), cos(x.a)); }
// cos(x)' = -sin(x) x'
template <class T, int N> Dual<T, N> cos(const Dual<T, N>& x) { return detail::chain(x, cos(x.a), -sin(x.a)); }
// tan(x)' = (1 + tan²x) x'
template <class T, int N> Dual<T, N> tan(const Dual<T, N>& x) { const T t = tan(x.a); return detail::chain(x, t, T(1) + t * t); }
// asin(x)' = x'/sqrt(1-x²)
template <class T, int N> Dual<T, N> asin(const Dual<T, N>& x) { return detail::chain(x, asin(x.a), T(1) / sqrt(T(1) - x.a * x.a)); }
// acos(x)' = -x'/sqrt(1-x²)
template <class T, int N> Dual<T, N> acos(const Dual<T, N>& x) { return detail::chain(x, acos(x.a), -T(1) / sqrt(T(1) - x.a * x.a)); }
// atan(x)' = x'/(1+x²)
template <class T, int N> Dual<T, N> atan(const Dual<T, N>& x) { return detail::chain(x, atan(x.a), T(1) / (T(1) + x.a * x.a)); }
// sinh(x)' = cosh(x) x'
template <class T, int N> Dual<T, N> sinh(const Dual<T, N>& x) { return detail::chain(x, sinh(x.a), cosh(x.a)); }
// cosh(x)' = sinh(x) x'
template <class T, int N> Dual<T, N> cosh(const Dual<T, N>& x) { return detail::chain(x, cosh(x.a), sinh(x.a)); }
// tanh(x)' = (1 - tanh²x) x'
template <class T, int N> Dual<T, N> tanh(const Dual<T, N>& x) { const T t = tanh(x.a); return detail::chain(x, t, T(1) - t * t); }
// erf(x)' = 2/sqrt(pi) exp(-x²) x'
template <class T, int N> Dual<T, N> erf(const Dual<T, N>& x) {
  return detail::chain(x, erf(x.a), T(1.1283791670955126) * exp(-x.a * x.a));
}
// floor, ceil: piecewise constant, derivative 0
template <class T, int N> Dual<T, N> floor(const Dual<T, N>& x) { return Dual<T, N>(floor(x.a)); }
template <class T, int N> Dual<T, N> ceil(const Dual<T, N>& x) { return Dual<T, N>(ceil(x.a)); }
// (x^p)' = p x^(p-1) x'
template <class T, int N> Dual<T, N> pow(const Dual<T, N>& x, T p) {
  return detail::chain(x, pow(x.a, p), p == T(0) ? T(0) : p * pow(x.a, p - T(1)));
}
template <class T, int N> Dual<T, N> pow(const Dual<T, N>& x, int p) { return pow(x, T(p)); }
// (s^y)' = s^y log(s) y'
template <class T, int N> Dual<T, N> pow(T s, const Dual<T, N>& y) {
  const T r = pow(s, y.a);
  return detail::chain(y, r, s == T(0) ? T(0) : r * log(s));
}
// (x^y)' = x^y (y' log x + y x'/x)
template <class T, int N> Dual<T, N> pow(const Dual<T, N>& x, const Dual<T, N>& y) {
  return exp(y * log(x));
}
// atan2(y, x)' = (x y' - y x')/(x² + y²)
template <class T, int N> Dual<T, N> atan2(const Dual<T, N>& y, const Dual<T, N>& x) {
  const T d = T(1) / (x.a * x.a + y.a * y.a);
  Dual<T, N> r(atan2(y.a, x.a));
  r.v = y.v * (x.a * d);
  Dual<T, N> tmp(T(0), x.v * (-y.a * d));
  r += tmp;
  return r;
}
// hypot(x, y)' = (x x' + y y')/hypot
template <class T, int N> Dual<T, N> hypot(const Dual<T, N>& x, const Dual<T, N>& y) { return sqrt(x * x + y * y); }
// x²' = 2 x x'
template <class T, int N> Dual<T, N> square(const Dual<T, N>& x) { return detail::chain(x, x.a * x.a, T(2) * x.a); }
template <class T> T square(T x) requires std::is_arithmetic_v<T> { return x * x; }

// min/max pick the active branch; its derivative is the branch's (ties take the first argument).
template <class T, int N> Dual<T, N> max(const Dual<T, N>& x, const Dual<T, N>& y) { return x.a >= y.a ? x : y; }
template <class T, int N> Dual<T, N> min(const Dual<T, N>& x, const Dual<T, N>& y) { return x.a <= y.a ? x : y; }
template <class T, int N> Dual<T, N> max(const Dual<T, N>& x, T s) { return x.a >= s ? x : Dual<T, N>(s); }
template <class T, int N> Dual<T, N> max(T s, const Dual<T, N>& x) { return max(x, s); }
template <class T, int N> Dual<T, N> min(const Dual<T, N>& x, T s) { return x.a <= s ? x : Dual<T, N>(s); }
template <class T, int N> Dual<T, N> min(T s, const Dual<T, N>& x) { return min(x, s); }
template <class T> T max(T x, T y) requires std::is_arithmetic_v<T> { return x >= y ? x : y; }
template <class T> T min(T x, T y) requires std::is_arithmetic_v<T> { return x <= y ? x : y; }

template <class T, int N> bool isfinite(const Dual<T, N>& x) {
  using std::isfinite;
  return isfinite(x.a) && x.v.allFinite();
}
template <class T, int N> bool isnan(const Dual<T, N>& x) {
  using std::isnan;
  return isnan(x.a) || x.v.hasNaN();
}

template <class T, int N>
std::ostream& operator<<(std::ostream& os, const Dual<T, N>& x) {
  return os << "[" << x.a << "; " << x.v.transpose() << "]";
}

}  // namespace nlid

// ---- Eigen glue: lets Dual be the Scalar of Eigen matrices -------------------------------------
namespace Eigen {

template <class T, int N>
struct NumTraits<nlid::Dual<T, N>> : NumTraits<T> {
  using Real = nlid::Dual<T, N>;
  using NonInteger = nlid::Dual<T, N>;
  using Nested = nlid::Dual<T, N>;
  using Literal = nlid::Dual<T, N>;
  enum {
    IsComplex = 0,
    IsInteger = 0,
    IsSigned = 1,
    RequireInitialization = 1,
    ReadCost = (N == Dynamic ? 10 : N + 1) * NumTraits<T>::ReadCost,
    AddCost = (N == Dynamic ? 10 : N + 1) * NumTraits<T>::AddCost,
    MulCost = (N == Dynamic ? 10 : 2 * N + 1) * NumTraits<T>::MulCost,
  };
  static Real epsilon() { return Real(NumTraits<T>::epsilon()); }
  static Real dummy_precision() { return Real(NumTraits<T>::dummy_precision()); }
  static Real highest() { return Real(NumTraits<T>::highest()); }
  static Real lowest() { return Real(NumTraits<T>::lowest()); }
  static inline int digits10() { return NumTraits<T>::digits10(); }
};

// Mixed Dual/plain-scalar products in Eigen expressions (e.g. MatrixXd * Matrix<Dual>) yield Dual.
template <class T, int N, class BinaryOp>
struct ScalarBinaryOpTraits<nlid::Dual<T, N>, T, BinaryOp> {
  using ReturnType = nlid::Dual<T, N>;
};
template <class T, int N, class BinaryOp>
struct ScalarBinaryOpTraits<T, nlid::Dual<T, N>, BinaryOp> {
  using ReturnType = nlid::Dual<T, N>;
};

}  // namespace Eigen
