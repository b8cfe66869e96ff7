#pragma once
/// @file
/// Normalised fit: the one number by which the study ranks models.
///
/// For a measured output y and a model output ŷ (N samples),
///
///     fit = 100 · (1 − ‖y − ŷ‖₂ / ‖y − ȳ‖₂)   [%],   ȳ = mean(y),
///
/// i.e. one minus the normalised root-mean-square error (NRMSE). 100 % is a perfect match, 0 %
/// is no better than the constant ȳ, negative values are worse than that constant. This is the
/// measure the System Identification Toolbox's `compare` reports (Ljung 1999, §16.6, "fit"),
/// and the mission's quality measure; there ŷ is the *simulated* (free-run) output.
///
/// Conventions:
/// - Matrices are N x ny (one column per output, as `Experiment::y()`); the fit is per column.
/// - A constant measured output has no variation to explain, so the fit is undefined and an
///   `nlid::Error` names the output column instead of returning ±inf or NaN.
/// - A non-finite measured value is a data error (`nlid::Error` naming the sample).
/// - A non-finite model output (a diverged simulation) scores −∞: "infinitely worse than the
///   mean" keeps a comparison table printable and sortable, and is never NaN.

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <type_traits>

#include <Eigen/Core>

#include "nlid/core/error.hpp"

namespace nlid {

namespace detail {

/// True if a signal of n samples with mean `mean` and squared spread Σ(y − mean)² = `var2` is
/// constant for the normalised fit. Relative to the signal's own size, so a constant offset
/// (e.g. 15 degrees) with rounding noise in the last digit is still recognised as constant,
/// and a signal in small units (a spread of 1e-13) is not (it was, under a floor of 1).
inline bool negligible_spread(double var2, double mean, Eigen::Index n) {
  return !(var2 > 1e-24 * mean * mean * static_cast<double>(n));
}

// One column's fit; `column` (0-based) only labels errors.
template <class Dy, class Dh>
double fit_percent_column(const Eigen::MatrixBase<Dy>& y, const Eigen::MatrixBase<Dh>& yhat,
                          Eigen::Index column, bool is_matrix) {
  Location where;
  if (is_matrix) where.column = static_cast<long>(column) + 1;
  const Eigen::Index n = y.size();
  require(n == yhat.size(),
          "fit_percent: measured output has " + std::to_string(n) + " samples but model output has " +
              std::to_string(yhat.size()),
          where);
  require(n > 0, "fit_percent: empty signal", where);
  // Every sum runs on y / max|y|: the fit is a ratio and so independent of the unit, and the
  // squares of a signal near 1e200 (or 1e-200) neither overflow nor underflow on the way.
  double scale = 0.0;
  for (Eigen::Index k = 0; k < n; ++k) {
    const double v = static_cast<double>(y(k));
    if (!std::isfinite(v)) {
      where.row = static_cast<long>(k) + 1;
      throw Error("fit_percent: measured output is not finite at sample " + std::to_string(k), where);
    }
    scale = std::max(scale, std::abs(v));
  }
  if (scale == 0.0) scale = 1.0;  // all zero: the spread test below calls it constant
  double mean = 0.0;
  for (Eigen::Index k = 0; k < n; ++k) mean += static_cast<double>(y(k)) / scale;
  mean /= static_cast<double>(n);
  double err2 = 0.0;
  double var2 = 0.0;
  bool model_finite = true;
  for (Eigen::Index k = 0; k < n; ++k) {
    const double v = static_cast<double>(y(k)) / scale;
    const double h = static_cast<double>(yhat(k)) / scale;
    if (!std::isfinite(h)) model_finite = false;
    err2 += (v - h) * (v - h);
    var2 += (v - mean) * (v - mean);
  }
  require(!negligible_spread(var2, mean, n),
          "fit_percent: measured output" +
              (is_matrix ? " column " + std::to_string(column + 1) : std::string()) +
              " is constant, so the normalised fit is undefined",
          where);
  if (!model_finite || !std::isfinite(err2)) return -std::numeric_limits<double>::infinity();
  return 100.0 * (1.0 - std::sqrt(err2) / std::sqrt(var2));
}

}  // namespace detail

/// Normalised fit in percent of a model output `yhat` to a measured output `y` (vectors).
/// Throws `nlid::Error` if the lengths differ, `y` is empty, constant or not finite; returns −∞
/// if `yhat` is not finite (diverged model).
template <class Dy, class Dh>
  requires(Dy::ColsAtCompileTime == 1 && Dh::ColsAtCompileTime == 1 &&
           std::is_floating_point_v<typename Dy::Scalar> &&
           std::is_floating_point_v<typename Dh::Scalar>)
double fit_percent(const Eigen::MatrixBase<Dy>& y, const Eigen::MatrixBase<Dh>& yhat) {
  return detail::fit_percent_column(y, yhat, 0, false);
}

/// Normalised fit in percent per output column of N x ny matrices (one entry per column).
/// Throws `nlid::Error` naming the column on mismatched shapes or a constant column.
template <class Dy, class Dh>
  requires(!(Dy::ColsAtCompileTime == 1 && Dh::ColsAtCompileTime == 1) &&
           std::is_floating_point_v<typename Dy::Scalar> &&
           std::is_floating_point_v<typename Dh::Scalar>)
Eigen::VectorXd fit_percent(const Eigen::MatrixBase<Dy>& y, const Eigen::MatrixBase<Dh>& yhat) {
  require(y.rows() == yhat.rows() && y.cols() == yhat.cols(),
          "fit_percent: measured output is " + std::to_string(y.rows()) + " x " +
              std::to_string(y.cols()) + " but model output is " + std::to_string(yhat.rows()) +
              " x " + std::to_string(yhat.cols()));
  Eigen::VectorXd fit(y.cols());
  for (Eigen::Index j = 0; j < y.cols(); ++j)
    fit(j) = detail::fit_percent_column(y.col(j), yhat.col(j), j, true);
  return fit;
}

}  // namespace nlid
