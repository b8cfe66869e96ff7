#pragma once
/// @file
/// Concepts of the automatic-differentiation layer.
///
/// Generic model code in nlid is written once over a scalar type T and evaluated three ways:
/// on `double` (estimation, simulation), on `float` (deployment on small targets) and on
/// `Dual<double, N>` (Jacobians by forward AD, see `nlid/ad/dual.hpp`). `AdScalar` names that
/// set, so a template head can say what it accepts:
///
///     template <AdScalar T> T predict(std::span<const T> theta) const;
///
/// The concept checks membership (floating point, or a dual over such) *and* the operations the
/// library relies on (field arithmetic with T and with plain constants, ordering, and the
/// elementary functions exp, log, sqrt, tanh, abs found as `nlid::` names), so a type that only
/// looks like a scalar is rejected at the interface instead of deep inside a model.
///
/// Reference: Griewank & Walther, "Evaluating Derivatives", 2nd ed., SIAM 2008, ch. 3.

#include <concepts>
#include <type_traits>

#include "nlid/ad/dual.hpp"

namespace nlid {

namespace detail {
// Membership: floating point, or a (possibly nested) dual whose innermost value is.
template <class X>
struct is_ad_scalar : std::bool_constant<std::is_floating_point_v<X>> {};
template <class T, int N>
struct is_ad_scalar<Dual<T, N>> : is_ad_scalar<T> {};
}  // namespace detail

/// A scalar type that nlid's generic code can be evaluated on.
/// Satisfied by `float`, `double`, `long double` and `Dual<T, N>` (fixed or `Dynamic` N, nested
/// duals included) whose value type T is itself an `AdScalar`.
template <class T>
concept AdScalar =
    detail::is_ad_scalar<std::remove_cv_t<T>>::value && std::copyable<T> &&
    requires(T x, T y, const T& cx) {
      { x + y } -> std::convertible_to<T>;
      { x - y } -> std::convertible_to<T>;
      { x * y } -> std::convertible_to<T>;
      { x / y } -> std::convertible_to<T>;
      { -x } -> std::convertible_to<T>;
      { 2 * x } -> std::convertible_to<T>;
      { x + 1.0 } -> std::convertible_to<T>;
      { x < y } -> std::convertible_to<bool>;
      { cx < 0 } -> std::convertible_to<bool>;
      { nlid::exp(cx) } -> std::convertible_to<T>;
      { nlid::log(cx) } -> std::convertible_to<T>;
      { nlid::sqrt(cx) } -> std::convertible_to<T>;
      { nlid::tanh(cx) } -> std::convertible_to<T>;
      { nlid::abs(cx) } -> std::convertible_to<T>;
      { value_of(cx) };
    };

/// A dual number type (any `Dual<T, N>`), for code that must seed or read derivatives.
/// Satisfied by `Dual<T, N>` and `DynamicDual<T>`; not by plain floating-point types.
template <class T>
concept DualNumber = is_dual_v<T> && AdScalar<std::remove_cvref_t<T>>;

}  // namespace nlid
