#pragma once
/// @file
/// Geometry of the regressor cloud for the deterministic initialisation of unit networks:
/// standardisation, principal and quasi-random directions, and cluster centres.

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>

namespace nlid::detail {

/// Whether a column with the given mean is constant up to rounding: its standard deviation is
/// at most 1e-12 of its magnitude. Purely relative (an absolute floor of 1e-12 made every
/// signal recorded in small SI units — picoamperes, nanometres — "constant").
inline bool is_constant_column(const Eigen::Ref<const Eigen::VectorXd>& col, double mean) {
  const double s = std::sqrt((col.array() - mean).square().mean());
  return !(s > 1e-12 * std::abs(mean));
}

/// Column means and standard deviations of X; a (numerically) constant column gets scale 1, so
/// it does not divide by zero (`Standardizer::fit` then marks it unused: s = 0, z ≡ 0).
inline void column_moments_into(const Eigen::MatrixXd& X, Eigen::VectorXd& mean, Eigen::VectorXd& scale) {
  mean = X.colwise().mean().transpose();
  scale.resize(X.cols());
  for (Eigen::Index j = 0; j < X.cols(); ++j) {
    const double s = std::sqrt((X.col(j).array() - mean(j)).square().mean());
    scale(j) = is_constant_column(X.col(j), mean(j)) ? 1.0 : s;
  }
}

/// Rows of X with the given indices.
inline Eigen::MatrixXd take_rows(const Eigen::MatrixXd& X, const std::vector<Eigen::Index>& rows) {
  Eigen::MatrixXd R(static_cast<Eigen::Index>(rows.size()), X.cols());
  for (std::size_t i = 0; i < rows.size(); ++i) R.row(static_cast<Eigen::Index>(i)) = X.row(rows[i]);
  return R;
}

/// Unit directions for projections of a standardised cloud Z (N × m): principal axes (largest
/// variance first, Jolliffe 2002), the coordinate axes, then quasi-random directions from the
/// R_m low-discrepancy sequence (Roberts 2018: fractional parts of k·αⱼ, αⱼ = φ_m^−j with φ_m
/// the generalised golden ratio), until `count` directions that differ pairwise by more than
/// ≈ 11° exist. Sign is irrelevant for sigmoids (σ(−s) = 1 − σ(s)), so ±v count as one.
/// (A template only so that the eigen-solver is instantiated where initialisation is used:
/// as a plain inline function it cost every includer ~5 s of compile time, measured by
/// scripts/minimal_size.)
template <class Dense = Eigen::MatrixXd>
std::vector<Eigen::VectorXd> projection_directions(const Eigen::MatrixXd& Z, int count) {
  const Eigen::Index m = Z.cols();
  std::vector<Eigen::VectorXd> dirs;
  auto add = [&](Eigen::VectorXd v) {
    const double n = v.norm();
    if (!(n > 0)) return;
    v /= n;
    for (const auto& d : dirs) {
      if (std::abs(d.dot(v)) > 0.98) return;
    }
    dirs.push_back(std::move(v));
  };
  if (m == 1) {
    dirs.push_back(Eigen::VectorXd::Ones(1));
    return dirs;
  }
  const Eigen::MatrixXd C = Z.transpose() * Z / static_cast<double>(std::max<Eigen::Index>(Z.rows(), 1));
  Eigen::SelfAdjointEigenSolver<Dense> eig(C);
  const double top = eig.eigenvalues().maxCoeff();
  for (Eigen::Index j = m - 1; j >= 0; --j) {
    if (eig.eigenvalues()(j) > 1e-9 * top) add(eig.eigenvectors().col(j));
  }
  for (Eigen::Index j = 0; j < m; ++j) add(Eigen::VectorXd::Unit(m, j));
  // Generalised golden ratio: the root > 1 of x^(m+1) = x + 1.
  double phi = 2.0;
  for (int it = 0; it < 60; ++it) phi = std::pow(1.0 + phi, 1.0 / static_cast<double>(m + 1));
  Eigen::VectorXd alpha(m);
  for (Eigen::Index j = 0; j < m; ++j) alpha(j) = std::pow(1.0 / phi, static_cast<double>(j + 1));
  for (int k = 1; static_cast<int>(dirs.size()) < count && k < 50 * count; ++k) {
    Eigen::VectorXd v(m);
    for (Eigen::Index j = 0; j < m; ++j) {
      const double u = 0.5 + k * alpha(j);
      v(j) = 2.0 * (u - std::floor(u)) - 1.0;
    }
    add(v);
  }
  return dirs;
}

/// K cluster centres of the rows of Z: farthest-point seeding from the point nearest the mean
/// (Gonzalez 1985), then Lloyd iterations (k-means) so centres sit where the data are dense.
/// Deterministic; K is reduced to the number of distinct rows if that is smaller.
inline std::vector<Eigen::VectorXd> cluster_centres(const Eigen::MatrixXd& Z, int K, int lloyd_iterations = 10) {
  const Eigen::Index N = Z.rows();
  std::vector<Eigen::VectorXd> c;
  if (N == 0 || K <= 0) return c;
  const Eigen::RowVectorXd mean = Z.colwise().mean();
  Eigen::Index first = 0;
  (Z.rowwise() - mean).rowwise().squaredNorm().minCoeff(&first);
  c.push_back(Z.row(first).transpose());
  Eigen::VectorXd dmin = (Z.rowwise() - Z.row(first)).rowwise().squaredNorm();
  while (static_cast<int>(c.size()) < K) {
    Eigen::Index far = 0;
    const double d = dmin.maxCoeff(&far);
    if (!(d > 1e-18)) break;  // fewer distinct points than K
    c.push_back(Z.row(far).transpose());
    dmin = dmin.cwiseMin((Z.rowwise() - Z.row(far)).rowwise().squaredNorm());
  }
  const auto k = static_cast<Eigen::Index>(c.size());
  std::vector<Eigen::Index> assign(static_cast<std::size_t>(N), 0);
  for (int it = 0; it < lloyd_iterations; ++it) {
    for (Eigen::Index i = 0; i < N; ++i) {
      double best = std::numeric_limits<double>::infinity();
      for (Eigen::Index j = 0; j < k; ++j) {
        const double d = (Z.row(i).transpose() - c[static_cast<std::size_t>(j)]).squaredNorm();
        if (d < best) {
          best = d;
          assign[static_cast<std::size_t>(i)] = j;
        }
      }
    }
    std::vector<Eigen::VectorXd> sum(static_cast<std::size_t>(k), Eigen::VectorXd::Zero(Z.cols()));
    std::vector<double> cnt(static_cast<std::size_t>(k), 0.0);
    for (Eigen::Index i = 0; i < N; ++i) {
      const auto a = static_cast<std::size_t>(assign[static_cast<std::size_t>(i)]);
      sum[a] += Z.row(i).transpose();
      cnt[a] += 1;
    }
    for (std::size_t j = 0; j < static_cast<std::size_t>(k); ++j) {
      if (cnt[j] > 0) c[j] = sum[j] / cnt[j];  // an empty cluster keeps its seed
    }
  }
  return c;
}

}  // namespace nlid::detail
