#pragma once
/// @file
/// Column-equilibrated, rank-revealing linear least squares (internal).
///
/// min ‖Φθ − y‖ by Householder QR with column pivoting on Φ·diag(1/s), s = column norms, so the
/// rank decision does not depend on the units of the regressors (degrees vs. normalised input).

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Core>
#include <Eigen/QR>
#include <Eigen/SVD>

namespace nlid::detail {

struct LeastSquaresSolution {
  Eigen::VectorXd theta;              // solution (basic solution if rank deficient)
  int rank = 0;                       // numerical rank (pivots above 1e-10 of the largest)
  double residual_norm = 0.0;         // ‖Φθ − y‖
  // diag((ΦᵀΦ)⁻¹). Rank deficient: +∞ for a parameter the data do not determine (it has a
  // component along the null space of Φ), and for the others diag((ΦᵀΦ)⁺), their variance given
  // any choice of the undetermined ones. Never 0 for a parameter that is not known exactly.
  Eigen::VectorXd unscaled_variance;
};

// Tolerance on a parameter's share of the null space of Φ (unit basis vectors, column-scaled
// coordinates) below which it still counts as determined by the data.
inline constexpr double identifiable_tolerance = 1e-8;

inline LeastSquaresSolution solve_least_squares_qr(const Eigen::MatrixXd& phi,
                                                   const Eigen::VectorXd& y,
                                                   double rank_threshold = 1e-10) {
  const Eigen::Index d = phi.cols();
  LeastSquaresSolution s;
  if (d == 0) {
    s.theta.resize(0);
    s.residual_norm = y.norm();
    return s;
  }
  Eigen::VectorXd scale = phi.colwise().norm().transpose();
  for (Eigen::Index j = 0; j < d; ++j)
    if (!(scale(j) > 0.0)) scale(j) = 1.0;
  const Eigen::MatrixXd scaled = phi * scale.cwiseInverse().asDiagonal();
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(phi.rows(), d);
  qr.setThreshold(rank_threshold);
  qr.compute(scaled);
  s.rank = static_cast<int>(qr.rank());
  s.theta = qr.solve(y).cwiseQuotient(scale);
  s.residual_norm = (phi * s.theta - y).norm();
  s.unscaled_variance = Eigen::VectorXd::Zero(d);
  const auto& perm = qr.colsPermutation().indices();
  if (s.rank == d && phi.rows() >= d) {
    const Eigen::MatrixXd r = qr.matrixR().topLeftCorner(d, d).triangularView<Eigen::Upper>();
    const Eigen::MatrixXd rinv =
        r.triangularView<Eigen::Upper>().solve(Eigen::MatrixXd::Identity(d, d));
    for (Eigen::Index k = 0; k < d; ++k) {
      const Eigen::Index j = perm(k);
      s.unscaled_variance(j) = rinv.row(k).squaredNorm() / (scale(j) * scale(j));
    }
    return s;
  }
  // ΦᵀΦ = P RᵀR Pᵀ, so the SVD of the small factor R (not of Φ) gives the null space and the
  // pseudo-inverse; its first `rank` singular values are the ones the QR kept.
  const Eigen::Index k = std::min<Eigen::Index>(phi.rows(), d);
  Eigen::MatrixXd r = Eigen::MatrixXd::Zero(k, d);
  for (Eigen::Index i = 0; i < k; ++i) r.row(i).tail(d - i) = qr.matrixR().row(i).tail(d - i);
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(r, Eigen::ComputeFullV);
  const Eigen::MatrixXd& v = svd.matrixV();
  const Eigen::VectorXd& sv = svd.singularValues();
  const Eigen::Index rank = std::min<Eigen::Index>(s.rank, sv.size());
  for (Eigen::Index row = 0; row < d; ++row) {
    const Eigen::Index j = perm(row);
    if (v.row(row).tail(d - rank).norm() > identifiable_tolerance) {
      s.unscaled_variance(j) = std::numeric_limits<double>::infinity();
      continue;
    }
    double acc = 0.0;
    for (Eigen::Index i = 0; i < rank; ++i) acc += v(row, i) * v(row, i) / (sv(i) * sv(i));
    s.unscaled_variance(j) = acc / (scale(j) * scale(j));
  }
  return s;
}

// min ‖Aθ − b‖ for a start or an inner iteration, where only θ is needed: the columns are scaled
// to norm ≈ 1 by powers of two (exact, so where the plain QR's column order stays, the numbers
// stay too) and solved with the QR's default rank tolerance. Without the scaling, columns in
// different units (a lagged input beside a lagged output) 1e14 apart are judged zero.
inline Eigen::VectorXd solve_equilibrated(Eigen::MatrixXd a, const Eigen::VectorXd& b) {
  Eigen::VectorXd scale = Eigen::VectorXd::Ones(a.cols());
  for (Eigen::Index j = 0; j < a.cols(); ++j) {
    const double n = a.col(j).norm();
    if (n > 0.0 && std::isfinite(n)) {
      scale(j) = std::ldexp(1.0, -std::ilogb(n));
      a.col(j) *= scale(j);
    }
  }
  return a.colPivHouseholderQr().solve(b).cwiseProduct(scale);
}

// Standard deviations √(σ² vᵢ) from unscaled variances v: +∞ (not identifiable) stays +∞ even
// when σ² = 0, where the product would be NaN.
inline Eigen::VectorXd stddev_from_variance(double sigma2, const Eigen::VectorXd& v) {
  Eigen::VectorXd sd(v.size());
  for (Eigen::Index i = 0; i < v.size(); ++i)
    sd(i) = std::isinf(v(i)) ? v(i) : std::sqrt(sigma2 * v(i));
  return sd;
}

}  // namespace nlid::detail
