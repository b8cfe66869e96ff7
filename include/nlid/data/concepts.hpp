#pragma once
/// @file
/// Concepts of the data layer.
///
/// The data containers hold `double` samples (files and experiments are measured data). The
/// filters are different: a model may filter its own simulated output (e.g. to compare it with
/// decimated data) while `nlid::Dual` carries parameter derivatives through it. So the filter
/// kernels take any scalar that is a field under +, −, × and can be made from a `double`
/// coefficient; filtering is linear, so derivatives pass through exactly.

#include <concepts>

namespace nlid {

/// A scalar the digital filters can run on: copyable, constructible from a `double` coefficient,
/// closed under `+`, `-` and `*`, and not an integer type (coefficients such as 0.0675 would be
/// truncated to 0).
/// Satisfied by `double`, `float`, `long double` and `nlid::Dual<T, N>` (fixed or dynamic N).
template <class T>
concept FilterScalar = std::copyable<T> && !std::integral<T> &&
                       std::constructible_from<T, double> && requires(const T& a, const T& b) {
  { a + b } -> std::convertible_to<T>;
  { a - b } -> std::convertible_to<T>;
  { a* b } -> std::convertible_to<T>;
};

}  // namespace nlid
