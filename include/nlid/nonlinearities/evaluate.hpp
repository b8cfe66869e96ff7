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
  Eigen::VectorXd row(X.cols());  // contiguous copy: X is column-major
  for (Eigen::Index i = 0; i < X.rows(); ++i) {
    row = X.row(i).transpose();
    out(i) = f(std::span<const double>(row.data(), static_cast<std::size_t>(row.size())), theta);
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
