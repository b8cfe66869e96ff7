#pragma once
/// @file
/// The checks a parameter covariance must pass wherever one is handed in (internal): a grey
/// box's `set_parameter_covariance` and `uncertainty_from_covariance` (model files of every kind).

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"

namespace nlid::detail {

/// Throws `nlid::Error` (message prefixed by `who`, located at the parameter) unless `c` is
/// finite, symmetric to 1e-9 of its largest entry and has a non-negative diagonal. `names`
/// must hold one name per row; the size check is the caller's, with its own wording.
inline void check_covariance(const std::string& who, const std::vector<std::string>& names, const Eigen::MatrixXd& c) {
  const Eigen::Index n = c.rows();
  // Every entry finite before the symmetry test, whose scale one NaN would spoil.
  for (Eigen::Index i = 0; i < n; ++i) {
    const std::string& q = names[static_cast<std::size_t>(i)];
    for (Eigen::Index j = 0; j < n; ++j) {
      require(std::isfinite(c(i, j)),
              who + "the covariance of " + q + " with " + names[static_cast<std::size_t>(j)] + " is not finite",
              at_parameter(q));
    }
  }
  const double scale = n > 0 ? c.cwiseAbs().maxCoeff() : 0.0;
  for (Eigen::Index i = 0; i < n; ++i) {
    const std::string& q = names[static_cast<std::size_t>(i)];
    require(c(i, i) >= 0.0, who + "the variance of " + q + " must be >= 0, got " + detail::format_g(c(i, i)),
            at_parameter(q));
    for (Eigen::Index j = 0; j < i; ++j) {
      require(std::abs(c(i, j) - c(j, i)) <= 1e-9 * scale,
              who + "the covariance is not symmetric (" + q + " with " + names[static_cast<std::size_t>(j)] + ": " +
                  detail::format_g(c(i, j)) + " and " + detail::format_g(c(j, i)) + ")",
              at_parameter(q));
    }
  }
}

}  // namespace nlid::detail
