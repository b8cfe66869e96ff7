#pragma once
/// @file
/// Not-a-knot cubic spline on a uniform grid (de Boor, "A Practical Guide to Splines", 2001,
/// ch. IV), plus hold and linear interpolation, used by `resample`.

#include <Eigen/Core>
#include <algorithm>

namespace nlid::detail {

/// Not-a-knot cubic spline through x(k) at k = 0…n−1 (unit spacing), evaluated at positions s
/// (in samples, 0 ≤ s ≤ n−1). Falls back to linear for n < 4.
inline Eigen::VectorXd spline_at(const Eigen::VectorXd& x, const Eigen::VectorXd& s) {
  const Eigen::Index n = x.size();
  Eigen::VectorXd out(s.size());
  if (n < 4) {
    for (Eigen::Index i = 0; i < s.size(); ++i) {
      const Eigen::Index k = std::min<Eigen::Index>(static_cast<Eigen::Index>(s(i)), n - 2);
      const double f = s(i) - static_cast<double>(k);
      out(i) = n == 1 ? x(0) : x(k) + f * (x(k + 1) - x(k));
    }
    return out;
  }
  // Second derivatives M: M_{k−1} + 4M_k + M_{k+1} = 6(x_{k+1} − 2x_k + x_{k−1}). Not-a-knot
  // (M_0 = 2M_1 − M_2, M_{n−1} = 2M_{n−2} − M_{n−3}) reduces the first and last equations to
  // 6M_1 = d_1 and 6M_{n−2} = d_{n−2}; the rest is tridiagonal (Thomas algorithm).
  Eigen::VectorXd d(n), m = Eigen::VectorXd::Zero(n);
  for (Eigen::Index k = 1; k + 1 < n; ++k) d(k) = 6.0 * (x(k + 1) - 2.0 * x(k) + x(k - 1));
  m(1) = d(1) / 6.0;
  m(n - 2) = d(n - 2) / 6.0;
  if (n > 4) {
    const Eigen::Index lo = 2, hi = n - 3;  // unknowns M_lo..M_hi
    Eigen::VectorXd c(n), r(n);
    for (Eigen::Index k = lo; k <= hi; ++k) {
      double rhs = d(k);
      if (k == lo) rhs -= m(1);
      if (k == hi) rhs -= m(n - 2);
      const double diag = k == lo ? 4.0 : 4.0 - c(k - 1);
      c(k) = 1.0 / diag;
      r(k) = (k == lo ? rhs : rhs - r(k - 1)) / diag;
    }
    m(hi) = r(hi);
    for (Eigen::Index k = hi - 1; k >= lo; --k) m(k) = r(k) - c(k) * m(k + 1);
  }
  m(0) = 2.0 * m(1) - m(2);
  m(n - 1) = 2.0 * m(n - 2) - m(n - 3);
  for (Eigen::Index i = 0; i < s.size(); ++i) {
    const Eigen::Index k = std::clamp<Eigen::Index>(static_cast<Eigen::Index>(s(i)), 0, n - 2);
    const double f = s(i) - static_cast<double>(k), g = 1.0 - f;
    out(i) = g * x(k) + f * x(k + 1) + ((g * g * g - g) * m(k) + (f * f * f - f) * m(k + 1)) / 6.0;
  }
  return out;
}

/// Zero-order hold (`hold`) or linear interpolation of x at positions s (in samples). A position
/// within 1e-9 of a sample counts as that sample: new grids rarely land on old samples exactly.
inline Eigen::VectorXd step_or_line_at(const Eigen::VectorXd& x, const Eigen::VectorXd& s,
                                       bool hold) {
  const Eigen::Index n = x.size();
  Eigen::VectorXd out(s.size());
  for (Eigen::Index i = 0; i < s.size(); ++i) {
    const double pos = std::min(s(i) + 1e-9, static_cast<double>(n - 1));
    const auto k = static_cast<Eigen::Index>(pos);
    if (hold || k >= n - 1) {
      out(i) = x(k);
    } else {
      const double f = std::max(0.0, s(i) - static_cast<double>(k));
      out(i) = x(k) + f * (x(k + 1) - x(k));
    }
  }
  return out;
}

}  // namespace nlid::detail
