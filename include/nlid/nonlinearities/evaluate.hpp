#pragma once
/// @file
/// Batch helpers over any `Nonlinearity`: evaluate on every row of a regressor matrix, and the
/// coefficient of determination of a fit. Model code evaluates sample by sample through
/// `operator()`; these are for analysis, plotting and tests, where a whole record is at hand.

#include <span>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/nonlinearities/concepts.hpp"
#include "nlid/nonlinearities/detail/common.hpp"

namespace nlid {

/// ŷᵢ = g(Xᵢ,:, θ) for every row of X (N × m). Throws `nlid::Error` naming "X" if the column
/// count is not the input dimension, or "theta" if θ has the wrong length.
template <Nonlinearity F>
[[nodiscard]] Eigen::VectorXd evaluate_rows(const F& f, const Eigen::MatrixXd& X, std::span<const double> theta) {
  if (X.cols() != f.input_dimension()) {
    throw Error("evaluate_rows: X has " + std::to_string(X.cols()) + " columns, expected " +
                    std::to_string(f.input_dimension()),
                at_parameter("X"));
  }
  detail::check_size(theta.size(), f.num_parameters(), "theta", "evaluate_rows");
  Eigen::VectorXd out(X.rows());
  // X is column-major, so a row is strided; g reads a contiguous span. One transposed copy makes
  // every row a contiguous column (a row buffer re-assigned per row re-checked its size each time,
  // and g++ 12 saw a free in that resize path and warned -Wuse-after-free at the caller).
  const Eigen::MatrixXd rows = X.transpose();
  const auto m = static_cast<std::size_t>(X.cols());
  for (Eigen::Index i = 0; i < X.rows(); ++i) {
    out(i) = f(std::span<const double>(rows.col(i).data(), m), theta);
  }
  return out;
}

/// R² = 1 − ‖y − ŷ‖²/‖y − ȳ‖² of g on (X, y): 1 is a perfect fit, 0 no better than the mean.
template <Nonlinearity F>
[[nodiscard]] double r_squared(const F& f, const Eigen::MatrixXd& X, const Eigen::VectorXd& y,
                               std::span<const double> theta) {
  if (X.rows() != y.size()) {
    throw Error("r_squared: X has " + std::to_string(X.rows()) + " rows but y has " +
                    std::to_string(y.size()) + " entries",
                at_parameter("y"));
  }
  return detail::r_squared(y, evaluate_rows(f, X, theta));
}

}  // namespace nlid
