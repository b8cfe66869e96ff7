#pragma once
/// @file
/// Eigen vectors and matrices as JSON, kept out of `json.hpp` so that header stays Eigen-free.
///
/// Layout (the one numpy's `tolist()` and MATLAB's `jsonencode` use, so files written by nlid
/// load directly in Python or MATLAB):
///
/// * a vector (one compile-time dimension equal to 1) is a flat array `[x0, x1, ...]`;
/// * any other matrix is an array of rows `[[a00, a01], [a10, a11]]`, row-major whatever the
///   storage order, because that is how people read a matrix.
///
/// With this header included, `Json j = theta;` works for `Eigen::VectorXd theta`, and
/// `view.get<Eigen::MatrixXd>()` reads one back. Reading checks the shape: a fixed-size target
/// must get exactly its size, rows must all be as long as the first, every element a number,
/// and every failure names its key path ("expected 4 elements at model.theta, found 3").
/// Values are stored as doubles, so `double` round-trips bit for bit and `float` exactly.
///
/// Expressions (`A * x`, `v.head(3)`) are not types with `JsonTraits`; convert them with
/// `nlid::to_json(expr)` (which evaluates them) or `.eval()`.

#include <Eigen/Core>
#include <concepts>
#include <cstddef>
#include <string>

#include "nlid/io/json.hpp"

namespace nlid {

/// Any Eigen dense expression of double or float values -> JSON (flat array for vectors,
/// array of rows otherwise, decided by the compile-time shape).
template <class Derived>
requires std::same_as<typename Derived::Scalar, double> ||
    std::same_as<typename Derived::Scalar, float>
[[nodiscard]] Json to_json(const Eigen::DenseBase<Derived>& m) {
  Json::Array out;
  if constexpr (Derived::IsVectorAtCompileTime) {
    out.reserve(static_cast<std::size_t>(m.size()));
    for (Eigen::Index i = 0; i < m.size(); ++i) out.emplace_back(m.derived().coeff(i));
  } else {
    out.reserve(static_cast<std::size_t>(m.rows()));
    for (Eigen::Index r = 0; r < m.rows(); ++r) {
      Json::Array row;
      row.reserve(static_cast<std::size_t>(m.cols()));
      for (Eigen::Index c = 0; c < m.cols(); ++c) row.emplace_back(m.derived().coeff(r, c));
      out.emplace_back(std::move(row));
    }
  }
  return Json(std::move(out));
}

namespace detail {
/// Shared reader for Eigen::Matrix and Eigen::Array targets (`Plain` = the concrete type).
template <class Plain>
Plain eigen_from_json(const JsonView& view) {
  using S = typename Plain::Scalar;
  constexpr int R = Plain::RowsAtCompileTime;
  constexpr int C = Plain::ColsAtCompileTime;
  const auto& items = view.as_array();
  const auto n = static_cast<Eigen::Index>(items.size());
  Plain m;
  if constexpr (Plain::IsVectorAtCompileTime) {
    constexpr int fixed = R == 1 ? C : R;
    if (fixed != Eigen::Dynamic && n != fixed) {
      view.fail("expected " + std::to_string(fixed) + " elements at " + view.path_text() +
                ", found " + std::to_string(n));
    }
    // A bounded dynamic vector (MaxRows set) cannot grow past its bound: resize() would
    // assert, or write past the inline storage with NDEBUG.
    constexpr int bound = R == 1 ? Plain::MaxColsAtCompileTime : Plain::MaxRowsAtCompileTime;
    if (bound != Eigen::Dynamic && n > bound) {
      view.fail("expected at most " + std::to_string(bound) + " elements at " + view.path_text() +
                ", found " + std::to_string(n));
    }
    if constexpr (R == 1) {
      m.resize(1, n);
    } else {
      m.resize(n, 1);
    }
    for (Eigen::Index i = 0; i < n; ++i)
      m(i) = view.at(static_cast<std::size_t>(i)).template get<S>();
  } else {
    if (R != Eigen::Dynamic && n != R) {
      view.fail("expected " + std::to_string(R) + " rows at " + view.path_text() + ", found " +
                std::to_string(n));
    }
    constexpr int max_rows = Plain::MaxRowsAtCompileTime;
    constexpr int max_cols = Plain::MaxColsAtCompileTime;
    if (max_rows != Eigen::Dynamic && n > max_rows) {
      view.fail("expected at most " + std::to_string(max_rows) + " rows at " + view.path_text() +
                ", found " + std::to_string(n));
    }
    const Eigen::Index cols = n == 0 ? 0 : static_cast<Eigen::Index>(view.at(0).as_array().size());
    if (C != Eigen::Dynamic && n > 0 && cols != C) {
      view.at(0).fail("expected " + std::to_string(C) + " columns at " + view.at(0).path_text() +
                      ", found " + std::to_string(cols));
    }
    if (max_cols != Eigen::Dynamic && cols > max_cols) {
      view.at(0).fail("expected at most " + std::to_string(max_cols) + " columns at " +
                      view.at(0).path_text() + ", found " + std::to_string(cols));
    }
    m.resize(n, n == 0 && C != Eigen::Dynamic ? C : cols);
    for (Eigen::Index r = 0; r < n; ++r) {
      const JsonView row = view.at(static_cast<std::size_t>(r));
      const auto len = static_cast<Eigen::Index>(row.as_array().size());
      if (len != cols) {
        row.fail("ragged matrix: row " + row.path_text() + " has " + std::to_string(len) +
                 " elements, row 0 has " + std::to_string(cols));
      }
      for (Eigen::Index c = 0; c < cols; ++c) {
        m(r, c) = row.at(static_cast<std::size_t>(c)).template get<S>();
      }
    }
  }
  return m;
}
}  // namespace detail

/// `Eigen::Matrix` of double or float <-> JSON (see the file comment for the layout).
template <class S, int R, int C, int O, int MR, int MC>
requires std::same_as<S, double> || std::same_as<S, float>
struct JsonTraits<Eigen::Matrix<S, R, C, O, MR, MC>> {
  /// Flat array for vectors, array of rows for matrices.
  static Json to_json(const Eigen::Matrix<S, R, C, O, MR, MC>& m) { return nlid::to_json(m); }
  /// Shape-checked read; errors name the key path.
  static Eigen::Matrix<S, R, C, O, MR, MC> from_json(const JsonView& view) {
    return detail::eigen_from_json<Eigen::Matrix<S, R, C, O, MR, MC>>(view);
  }
};

/// `Eigen::Array` of double or float <-> JSON (same layout as `Eigen::Matrix`).
template <class S, int R, int C, int O, int MR, int MC>
requires std::same_as<S, double> || std::same_as<S, float>
struct JsonTraits<Eigen::Array<S, R, C, O, MR, MC>> {
  /// Flat array for vectors, array of rows otherwise.
  static Json to_json(const Eigen::Array<S, R, C, O, MR, MC>& m) { return nlid::to_json(m); }
  /// Shape-checked read; errors name the key path.
  static Eigen::Array<S, R, C, O, MR, MC> from_json(const JsonView& view) {
    return detail::eigen_from_json<Eigen::Array<S, R, C, O, MR, MC>>(view);
  }
};

}  // namespace nlid
