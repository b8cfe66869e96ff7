#pragma once
/// @file
/// Runs of missing (NaN/Inf) samples in one column, and their linear fill. Shared by
/// `Experiment::fill_missing` and the CSV reader, which word their errors differently (sample
/// indices vs file line numbers) but must agree on what a gap is.

#include <Eigen/Core>
#include <cmath>
#include <vector>

namespace nlid::detail {

/// A run of non-finite samples: rows [begin, end) of one column.
struct Gap {
  Eigen::Index begin;
  Eigen::Index end;
  [[nodiscard]] Eigen::Index length() const { return end - begin; }
};

/// All maximal runs of non-finite values in column `c` of `m`, in order.
inline std::vector<Gap> find_gaps(const Eigen::MatrixXd& m, Eigen::Index c) {
  std::vector<Gap> gaps;
  const Eigen::Index n = m.rows();
  for (Eigen::Index k = 0; k < n;) {
    if (std::isfinite(m(k, c))) {
      ++k;
      continue;
    }
    Eigen::Index e = k;
    while (e < n && !std::isfinite(m(e, c))) ++e;
    gaps.push_back({k, e});
    k = e;
  }
  return gaps;
}

/// Straight line between the finite neighbours m(begin-1, c) and m(end, c). The caller has checked
/// that both exist (the gap is interior).
inline void fill_gap_linear(Eigen::MatrixXd& m, Eigen::Index c, const Gap& g) {
  const double a = m(g.begin - 1, c);
  const double b = m(g.end, c);
  const double span = static_cast<double>(g.length() + 1);
  for (Eigen::Index j = g.begin; j < g.end; ++j) {
    const double w = static_cast<double>(j - g.begin + 1) / span;
    m(j, c) = a + w * (b - a);
  }
}

}  // namespace nlid::detail
