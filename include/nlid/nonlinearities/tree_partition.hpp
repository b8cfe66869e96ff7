#pragma once
/// @file
/// `TreePartition<M, Depth>`: a piecewise-affine map on a binary-tree partition of the regressor
/// space (the toolbox's `treepartition` / idTreePartition for nonlinear ARX).
///
/// Math. The standardised regressor z = (x − r) ⊘ s is routed from the root of a complete binary
/// tree of depth D to one of 2^D leaves: at node ν it goes right if vᵥᵀz > tᵥ (a hyperplane
/// split), else left. Each leaf ℓ holds an affine model,
///
///     g(x) = zᵀLₗ + dₗ,     ℓ = leaf(z),
///
/// so g is affine on each cell of the partition and may jump across a split — a regression tree
/// with linear leaves (Breiman et al., "Classification and Regression Trees", 1984, Ch. 8;
/// Quinlan's M5 model trees, 1992). It suits systems that switch between operating regimes
/// (the throttle's spring-loaded rest, free travel and hard stop).
///
/// Structure vs parameters. The split directions vᵥ and thresholds tᵥ are structure, chosen by
/// `initialize` and kept in the object (the partition is not differentiable, so it is not left to
/// a gradient method). θ holds only the leaf models, in which g is linear:
///
///     θ = [L[0][0..m−1], d[0], L[1][0..m−1], d[1], …],   p = 2^D (m + 1).
///
/// ∂g/∂θ is exact everywhere; ∂g/∂x is the leaf's L ⊘ s (piecewise constant).
///
/// Initialisation (deterministic): the tree is grown top-down. At each node the candidate splits
/// are the coordinate axes and the node's principal axes, each at the 25/50/75 % quantiles of the
/// projection; the split minimising the summed residual of affine least-squares fits in the two
/// children is taken (children need at least 2(m + 1) samples, else the node is not split: its
/// right child is empty and both children share its model). Leaf models are least-squares fits
/// with a small ridge pull towards the parent's model, so a sparsely populated leaf stays close
/// to its parent instead of extrapolating wildly.

#include <algorithm>
#include <cmath>
#include <limits>
#include <span>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/core/sizes.hpp"
#include "nlid/nonlinearities/detail/common.hpp"
#include "nlid/nonlinearities/detail/regressor_cloud.hpp"
#include "nlid/nonlinearities/detail/standardizer.hpp"

namespace nlid {

/// Piecewise-affine map on a depth-D binary-tree partition; θ = per-leaf [L[ℓ][·], d[ℓ]].
/// Invariants: input_dimension() ≥ 1, 1 ≤ depth() ≤ 12, equal to M / Depth when fixed; the
/// split table has 2^D − 1 nodes (unsplit nodes have threshold +∞: everything goes left).
template <int M, int Depth>
  requires((M == Dynamic || M >= 1) && (Depth == Dynamic || (Depth >= 1 && Depth <= 12)))
class TreePartition {
 public:
  /// m (or Dynamic).
  static constexpr int num_inputs = M;
  /// p = 2^D (m + 1), or Dynamic.
  static constexpr int num_params = (M == Dynamic || Depth == Dynamic) ? Dynamic : (1 << Depth) * (M + 1);

  /// Fixed sizes; until `initialize` every node sends everything left (one active leaf).
  TreePartition()
    requires(M != Dynamic && Depth != Dynamic)
  { reset_splits(); }
  /// m inputs, depth D (1 … 12). Throws naming "m" or "depth", and naming "m" if the tree would
  /// have more than `max_nonlinearity_parameters` parameters.
  TreePartition(int m, int depth)
      : m_(detail::checked_size(m, M, 1, "m", "TreePartition")),
        depth_(detail::checked_size(depth, Depth, 1, "depth", "TreePartition")),
        norm_(m_) {
    if (depth_ > 12) throw Error("TreePartition: depth must be at most 12, got " + std::to_string(depth_), at_parameter("depth"));
    detail::check_parameter_count((1LL << depth_) * (m_ + 1LL), "m", "TreePartition", 1 << depth_, "leaves", m_);
    reset_splits();
  }

  /// Number of inputs m.
  [[nodiscard]] int input_dimension() const { return m_; }
  /// Tree depth D.
  [[nodiscard]] int depth() const { return depth_; }
  /// Number of leaves 2^D.
  [[nodiscard]] int leaves() const { return 1 << depth_; }
  /// Number of parameters 2^D (m + 1).
  [[nodiscard]] int num_parameters() const { return leaves() * (m_ + 1); }

  /// Regressor centre r.
  [[nodiscard]] const Eigen::Matrix<double, M, 1>& center() const { return norm_.center(); }
  /// Regressor scale s.
  [[nodiscard]] Eigen::Matrix<double, M, 1> scale() const { return norm_.scale(); }
  /// Split direction of node ν (heap order: children of ν are 2ν+1, 2ν+2), in z coordinates.
  [[nodiscard]] Eigen::VectorXd split_direction(int node) const {
    check_node(node);
    return Eigen::Map<const Eigen::VectorXd>(dir_.data() + static_cast<std::size_t>(node * m_), m_);
  }
  /// Split threshold of node ν (+∞: not split).
  [[nodiscard]] double split_threshold(int node) const {
    check_node(node);
    return thr_[static_cast<std::size_t>(node)];
  }
  /// Sets the split of node ν (to restore a saved model, or to impose a known regime boundary).
  /// threshold = +∞ marks the node as not split. Throws naming "direction" (wrong length, not
  /// finite) or "threshold" (NaN or −∞).
  void set_split(int node, const Eigen::VectorXd& direction, double threshold) {
    check_node(node);
    if (direction.size() != m_) {
      throw Error("TreePartition: split direction needs " + std::to_string(m_) + " entries", at_parameter("direction"));
    }
    if (!direction.allFinite()) {
      throw Error("TreePartition: split direction of node " + std::to_string(node) + " is not finite",
                  at_parameter("direction"));
    }
    // NaN would silently send everything left and −∞ everything right, while `describe` calls
    // both "not split"; +∞ is the one non-finite value with a meaning.
    if (std::isnan(threshold) || threshold == -std::numeric_limits<double>::infinity()) {
      throw Error("TreePartition: split threshold of node " + std::to_string(node) +
                      " must be a number or +inf (not split), got " + detail::format_g(threshold),
                  at_parameter("threshold"));
    }
    for (int j = 0; j < m_; ++j) dir_[static_cast<std::size_t>(node * m_ + j)] = direction(j);
    thr_[static_cast<std::size_t>(node)] = threshold;
  }
  /// Sets r and s directly (loading a saved model). Throws naming "normalization".
  void set_normalization(const Eigen::VectorXd& center, const Eigen::VectorXd& scale) {
    norm_.set_normalization(center, scale, "TreePartition");
  }

  /// The leaf (0 … 2^D − 1) that x falls into.
  template <class T>
  [[nodiscard]] int leaf_of(std::span<const T> x) const {
    if (static_cast<int>(x.size()) != m_) detail::check_size(x.size(), m_, "x", "TreePartition");
    // The split test uses the value part only (no derivative flows through the choice of leaf).
    // V is double for double and Dual, and the tracer itself for TraceScalar, so that generated
    // code makes the same comparison on the signal instead of freezing one leaf.
    using V = std::remove_cvref_t<decltype(value_of(std::declval<const T&>()))>;
    int node = 0;
    for (int level = 0; level < depth_; ++level) {
      V s(0.0);
      for (int j = 0; j < m_; ++j) {
        s += dir_[static_cast<std::size_t>(node * m_ + j)] * value_of(norm_.z(x[static_cast<std::size_t>(j)], j));
      }
      node = 2 * node + (s > thr_[static_cast<std::size_t>(node)] ? 2 : 1);
    }
    return node - (leaves() - 1);
  }

  /// g(x) = zᵀL_leaf + d_leaf. Throws `nlid::Error` if a span has the wrong length.
  template <class T>
  [[nodiscard]] T operator()(std::span<const T> x, std::span<const T> theta) const {
    if (static_cast<int>(theta.size()) != num_parameters()) {
      detail::check_size(theta.size(), num_parameters(), "theta", "TreePartition");
    }
    const int leaf = leaf_of(x);
    const auto base = static_cast<std::size_t>(leaf * (m_ + 1));
    T g = theta[base + static_cast<std::size_t>(m_)];
    for (int j = 0; j < m_; ++j) g += theta[base + static_cast<std::size_t>(j)] * norm_.z(x[static_cast<std::size_t>(j)], j);
    return g;
  }

  /// Grows the partition and fits the leaf models (see file comment).
  void initialize(const Eigen::MatrixXd& X, const Eigen::VectorXd& y, std::span<double> theta) {
    detail::check_init_data(X, y, theta.size(), m_, num_parameters(), m_ + 1, "TreePartition");
    const Eigen::MatrixXd Z = norm_.fit(X);
    reset_splits();
    std::vector<Eigen::Index> all(static_cast<std::size_t>(Z.rows()));
    for (Eigen::Index i = 0; i < Z.rows(); ++i) all[static_cast<std::size_t>(i)] = i;
    const Eigen::VectorXd root = fit_affine(Z, y, all, Eigen::VectorXd::Zero(m_ + 1), 0.0);
    grow(Z, y, all, 0, 0, root, theta);
  }

  /// "L[ℓ][j]", "d[ℓ]" leaf by leaf.
  [[nodiscard]] std::vector<std::string> parameter_names() const {
    std::vector<std::string> n;
    for (int l = 0; l < leaves(); ++l) {
      for (int j = 0; j < m_; ++j) n.push_back("L[" + std::to_string(l) + "][" + std::to_string(j) + "]");
      n.push_back("d[" + std::to_string(l) + "]");
    }
    return n;
  }

  /// Splits and leaf models.
  [[nodiscard]] std::string describe(std::span<const double> theta) const { return describe(theta, {}); }

  /// As `describe(theta)`, naming the inputs.
  [[nodiscard]] std::string describe(std::span<const double> theta, const std::vector<std::string>& input_names) const {
    detail::check_size(theta.size(), num_parameters(), "theta", "TreePartition");
    const auto names = detail::input_names_or_default(input_names, m_, "TreePartition");
    const Eigen::VectorXd r = norm_.center(), s = norm_.scale();
    std::string o = "tree partition (" + std::to_string(m_) + " inputs, depth " + std::to_string(depth_) + ", " +
                    std::to_string(leaves()) + " leaves): g(x) = z'L[leaf] + d[leaf],  z = (x - r)./s\n";
    o += "  r = [";
    for (int j = 0; j < m_; ++j) o += (j ? ", " : "") + detail::format_g(r(j));
    o += "],  s = [";
    for (int j = 0; j < m_; ++j) o += (j ? ", " : "") + detail::scale_text(s(j));
    o += "]\n" + detail::unused_note(s) + "  splits (node: go right if v'z > t; children 2n+1, 2n+2):\n";
    for (int nd = 0; nd < leaves() - 1; ++nd) {
      o += "    " + std::to_string(nd) + ": ";
      if (!std::isfinite(thr_[static_cast<std::size_t>(nd)])) {
        o += "not split\n";
        continue;
      }
      bool first = true;
      for (int j = 0; j < m_; ++j) {
        const double v = dir_[static_cast<std::size_t>(nd * m_ + j)];
        if (v == 0.0) continue;
        o += (first ? (v < 0 ? "-" : "") : (v < 0 ? " - " : " + ")) + detail::format_g(std::abs(v)) + "*z(" +
             names[static_cast<std::size_t>(j)] + ")";
        first = false;
      }
      o += " > " + detail::format_g(thr_[static_cast<std::size_t>(nd)]) + "\n";
    }
    o += "  leaf models:\n";
    for (int l = 0; l < leaves(); ++l) {
      o += "    " + std::to_string(l) + ": L = [";
      for (int j = 0; j < m_; ++j) {
        o += (j ? ", " : "") + detail::format_g(theta[static_cast<std::size_t>(l * (m_ + 1) + j)]);
      }
      o += "], d = " + detail::format_g(theta[static_cast<std::size_t>(l * (m_ + 1) + m_)]) + "\n";
    }
    return o;
  }

  // ---- Implementation details below ----------------------------------------------------------
 private:
  void check_node(int node) const {
    if (node < 0 || node >= leaves() - 1) {
      throw Error("TreePartition: node " + std::to_string(node) + " does not exist (0 … " +
                      std::to_string(leaves() - 2) + ")",
                  at_parameter("node"));
    }
  }

  void reset_splits() {
    dir_.assign(static_cast<std::size_t>((leaves() - 1) * m_), 0.0);
    thr_.assign(static_cast<std::size_t>(leaves() - 1), std::numeric_limits<double>::infinity());
  }

  // Affine least squares on the rows `idx`, pulled towards `prior` with weight λ (ridge).
  Eigen::VectorXd fit_affine(const Eigen::MatrixXd& Z, const Eigen::VectorXd& y, const std::vector<Eigen::Index>& idx,
                             const Eigen::VectorXd& prior, double lambda) const {
    const auto n = static_cast<Eigen::Index>(idx.size());
    Eigen::MatrixXd A(n + (lambda > 0 ? m_ + 1 : 0), m_ + 1);
    Eigen::VectorXd b(A.rows());
    for (Eigen::Index i = 0; i < n; ++i) {
      A.row(i).head(m_) = Z.row(idx[static_cast<std::size_t>(i)]);
      A(i, m_) = 1.0;
      b(i) = y(idx[static_cast<std::size_t>(i)]);
    }
    if (lambda > 0) {
      const double w = std::sqrt(lambda);
      A.bottomRows(m_ + 1) = w * Eigen::MatrixXd::Identity(m_ + 1, m_ + 1);
      b.tail(m_ + 1) = w * prior;
    }
    if (A.rows() == 0) return prior;
    return detail::least_squares(A, b);
  }

  double sse(const Eigen::MatrixXd& Z, const Eigen::VectorXd& y, const std::vector<Eigen::Index>& idx) const {
    const Eigen::VectorXd w = fit_affine(Z, y, idx, Eigen::VectorXd::Zero(m_ + 1), 0.0);
    double s = 0;
    for (Eigen::Index i : idx) {
      const double e = y(i) - Z.row(i).dot(w.head(m_)) - w(m_);
      s += e * e;
    }
    return s;
  }

  void grow(const Eigen::MatrixXd& Z, const Eigen::VectorXd& y, const std::vector<Eigen::Index>& idx, int node,
            int level, const Eigen::VectorXd& parent, std::span<double> theta) {
    // Ridge weight: small against the data's own information (≈ 1 sample's worth per 1000).
    const double lambda = 1e-3 * std::max<double>(1.0, static_cast<double>(idx.size()) / 1000.0);
    const Eigen::VectorXd here = fit_affine(Z, y, idx, parent, idx.empty() ? 0.0 : lambda);
    if (level == depth_) {
      const int leaf = node - (leaves() - 1);
      for (int j = 0; j <= m_; ++j) theta[static_cast<std::size_t>(leaf * (m_ + 1) + j)] = here(j);
      return;
    }
    const auto min_child = static_cast<std::size_t>(2 * (m_ + 1));
    std::vector<Eigen::Index> left, right;
    double best = std::numeric_limits<double>::infinity();
    Eigen::VectorXd best_dir;
    double best_thr = std::numeric_limits<double>::infinity();
    if (idx.size() >= 2 * min_child) {
      Eigen::MatrixXd Zn(static_cast<Eigen::Index>(idx.size()), m_);
      for (std::size_t i = 0; i < idx.size(); ++i) Zn.row(static_cast<Eigen::Index>(i)) = Z.row(idx[i]);
      std::vector<Eigen::VectorXd> dirs;
      for (int j = 0; j < m_; ++j) dirs.push_back(Eigen::VectorXd::Unit(m_, j));
      if (m_ > 1) {
        const Eigen::MatrixXd C = (Zn.rowwise() - Zn.colwise().mean()).transpose() * (Zn.rowwise() - Zn.colwise().mean());
        Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(C);
        for (int j = m_ - 1; j >= std::max(0, m_ - 2); --j) dirs.push_back(eig.eigenvectors().col(j));
      }
      for (const auto& v : dirs) {
        const Eigen::VectorXd p = Zn * v;
        const auto sorted = detail::sorted_copy(p);
        for (double q : {0.25, 0.5, 0.75}) {
          const double t = detail::quantile_sorted(sorted, q);
          std::vector<Eigen::Index> l, r;
          for (std::size_t i = 0; i < idx.size(); ++i) (p(static_cast<Eigen::Index>(i)) > t ? r : l).push_back(idx[i]);
          if (l.size() < min_child || r.size() < min_child) continue;
          const double c = sse(Z, y, l) + sse(Z, y, r);
          if (c < best * (1 - 1e-12)) {
            best = c;
            best_dir = v;
            best_thr = t;
            left = std::move(l);
            right = std::move(r);
          }
        }
      }
    }
    if (std::isfinite(best)) {
      for (int j = 0; j < m_; ++j) dir_[static_cast<std::size_t>(node * m_ + j)] = best_dir(j);
      thr_[static_cast<std::size_t>(node)] = best_thr;
    } else {
      left = idx;  // not split: everything goes left, the right subtree inherits this model
      right.clear();
    }
    grow(Z, y, left, 2 * node + 1, level + 1, here, theta);
    grow(Z, y, right, 2 * node + 2, level + 1, here, theta);
  }

  int m_ = M;
  int depth_ = Depth;
  detail::Standardizer<M> norm_;
  std::vector<double> dir_;  // (2^D − 1) × m, row per node
  std::vector<double> thr_;  // 2^D − 1
};

}  // namespace nlid
