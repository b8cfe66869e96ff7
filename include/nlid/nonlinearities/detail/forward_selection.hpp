#pragma once
/// @file
/// Greedy forward selection of basis functions by orthogonal least squares (Chen, Cowan & Grant,
/// "Orthogonal least squares learning algorithm for radial basis function networks", IEEE TNN
/// 2(2), 1991). Used by the data-driven initialisation of the sigmoid and wavelet networks and of
/// the piecewise-linear breakpoints.
///
/// A dictionary of candidate columns is given, grouped in blocks (a block is the set of columns
/// one unit contributes: 1 for a sigmoid or hinge, 2 for a wavelet unit's scaling and wavelet
/// functions). Columns already in the model span an orthonormal basis Q. Each step picks the
/// block whose part orthogonal to Q explains most of the current residual, adds it to Q, and
/// deflates every remaining candidate, so each step costs O(N · columns). Selection is
/// deterministic: ties go to the lower index.

#include <cmath>
#include <utility>
#include <vector>

#include <Eigen/Core>

namespace nlid::detail {

/// Orthogonal-least-squares forward selector over a dictionary of column blocks.
class ForwardSelector {
 public:
  /// `y`: the target; `candidates`: N × (blocks · block_size) dictionary; columns of one block
  /// are adjacent.
  ForwardSelector(const Eigen::VectorXd& y, Eigen::MatrixXd candidates, int block_size)
      : r_(y), c_(std::move(candidates)), bs_(block_size) {
    norm0_ = c_.colwise().squaredNorm().transpose();
    used_.assign(static_cast<std::size_t>(c_.cols() / bs_), false);
  }

  /// Adds a column that must be in the model (offset, linear term) before selection starts.
  void add_fixed(const Eigen::VectorXd& col) { add_basis(col); }

  /// Number of candidate blocks.
  [[nodiscard]] int num_blocks() const { return static_cast<int>(used_.size()); }

  /// Selects the best unused block, adds it to the basis and returns its index (−1 if none
  /// is left). Blocks whose columns are numerically inside the span of the basis score 0 and
  /// are taken only when nothing better remains.
  int select() {
    double ignored = 0;
    return select(ignored);
  }

  /// As `select()`, also reporting the residual sum of squares the chosen block removes.
  int select(double& explained) {
    int best = -1;
    double best_score = -1;
    for (int b = 0; b < num_blocks(); ++b) {
      if (used_[static_cast<std::size_t>(b)]) continue;
      const double s = score(b);
      if (s > best_score) {
        best_score = s;
        best = b;
      }
    }
    explained = best_score;
    if (best < 0) return -1;
    used_[static_cast<std::size_t>(best)] = true;
    for (int k = 0; k < bs_; ++k) {
      const Eigen::Index j = static_cast<Eigen::Index>(best) * bs_ + k;
      if (c_.col(j).squaredNorm() > kTol * norm0_(j)) add_basis(c_.col(j));
    }
    return best;
  }

  /// Residual sum of squares block b would remove if it were selected next.
  [[nodiscard]] double explained_by(int b) const { return score(b); }

  /// The current residual (target minus its projection on the basis).
  [[nodiscard]] const Eigen::VectorXd& residual() const { return r_; }

 private:
  static constexpr double kTol = 1e-9;

  // Residual explained by block b: ‖P_b r‖² with P_b the projector on its deflated columns
  // (orthogonalised against each other within the block).
  double score(int b) const {
    double s = 0;
    Eigen::VectorXd prev;
    for (int k = 0; k < bs_; ++k) {
      const Eigen::Index j = static_cast<Eigen::Index>(b) * bs_ + k;
      Eigen::VectorXd v = c_.col(j);
      if (k > 0 && prev.size() > 0) v -= prev * prev.dot(v);
      const double nn = v.squaredNorm();
      if (!(nn > kTol * norm0_(j)) || !std::isfinite(nn)) continue;
      v /= std::sqrt(nn);
      const double proj = v.dot(r_);
      s += proj * proj;
      prev = v;
    }
    return s;
  }

  // Gram–Schmidt (twice, for orthogonality to rounding) of col against Q, then deflation of the
  // residual and of all candidate columns.
  void add_basis(const Eigen::VectorXd& col) {
    Eigen::VectorXd q = col;
    const double n0 = q.squaredNorm();
    for (int pass = 0; pass < 2; ++pass) {
      for (const auto& b : basis_) q -= b * b.dot(q);
    }
    const double nn = q.squaredNorm();
    if (!(nn > kTol * n0) || n0 == 0) return;
    q /= std::sqrt(nn);
    r_ -= q * q.dot(r_);
    const Eigen::RowVectorXd proj = q.transpose() * c_;
    c_.noalias() -= q * proj;
    basis_.push_back(std::move(q));
  }

  Eigen::VectorXd r_;
  Eigen::MatrixXd c_;
  int bs_;
  Eigen::VectorXd norm0_;
  std::vector<bool> used_;
  std::vector<Eigen::VectorXd> basis_;
};

/// Deterministic row subsample (every k-th row) so dictionary selection costs O(max_rows) per
/// candidate on long records; the final least-squares fit still uses all rows.
inline std::vector<Eigen::Index> subsample_rows(Eigen::Index n, Eigen::Index max_rows) {
  std::vector<Eigen::Index> rows;
  const Eigen::Index stride = n <= max_rows ? 1 : (n + max_rows - 1) / max_rows;
  for (Eigen::Index i = 0; i < n; i += stride) rows.push_back(i);
  return rows;
}

}  // namespace nlid::detail
