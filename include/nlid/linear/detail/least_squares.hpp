#pragma once
/// @file
/// Column-equilibrated, rank-revealing linear least squares (internal).
///
/// min ‖Φθ − y‖ by Householder QR with column pivoting on Φ·diag(1/s), s = column norms, so the
/// rank decision does not depend on the units of the regressors (degrees vs. normalised input).

#include <Eigen/Core>
#include <Eigen/QR>

namespace nlid::detail {

struct LeastSquaresSolution {
  Eigen::VectorXd theta;              // solution (basic solution if rank deficient)
  int rank = 0;                       // numerical rank (pivots above 1e-10 of the largest)
  double residual_norm = 0.0;         // ‖Φθ − y‖
  Eigen::VectorXd unscaled_variance;  // diag((ΦᵀΦ)⁻¹); zeros if rank deficient
};

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
  if (s.rank == d && phi.rows() >= d) {
    const Eigen::MatrixXd r = qr.matrixR().topLeftCorner(d, d).triangularView<Eigen::Upper>();
    const Eigen::MatrixXd rinv =
        r.triangularView<Eigen::Upper>().solve(Eigen::MatrixXd::Identity(d, d));
    const auto& perm = qr.colsPermutation().indices();
    for (Eigen::Index k = 0; k < d; ++k) {
      const Eigen::Index j = perm(k);
      s.unscaled_variance(j) = rinv.row(k).squaredNorm() / (scale(j) * scale(j));
    }
  }
  return s;
}

}  // namespace nlid::detail
