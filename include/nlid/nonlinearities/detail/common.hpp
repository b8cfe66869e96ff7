#pragma once
/// @file
/// Internals shared by the static nonlinearities: argument validation with located errors,
/// scalar casts that work for double, float and Dual, a numerically safe logistic function,
/// number formatting for `describe`, and a rank-revealing linear least-squares solve.

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/QR>

#include "nlid/ad/dual.hpp"
#include "nlid/core/batch.hpp"
#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/core/sizes.hpp"

namespace nlid::detail {

/// Converts a stored double (normalisation, breakpoint) into the evaluation scalar T.
template <class T>
inline T cast_to(double v) {
  return static_cast<T>(v);
}

/// Logistic function 1/(1+e^(−s)), evaluated so that neither branch overflows: for s < 0 the
/// algebraically equal e^s/(1+e^s) is used. With the naive form a Dual at s ≪ 0 would get an
/// infinite exp and a NaN derivative (∞·0).
/// A lane-parallel `Batch` (core/batch.hpp) cannot branch, and needs not: its lanes are plain
/// numbers, for which 1/(1 + e^(−s)) is exact in IEEE arithmetic also when e^(−s) overflows
/// (1/∞ = 0); only a Dual's derivative needs the second form.
/// Plain doubles take one lane of the batch kernel (core/batch.hpp: Cody–Waite exp, one division,
/// within 4 ulp of the two-branch form): the fixed-size sigmoid network evaluates its units in
/// SIMD lanes with that kernel, and its Dynamic twin, a file-loaded model and the generated C
/// code (codegen) must compute bitwise the same numbers.
template <class T>
inline T logistic(const T& s) {
  using std::exp;
  const T one = cast_to<T>(1.0);
  if constexpr (std::is_same_v<T, double>) {
    double out;
    nlid::detail::logistic_lanes<1>(&s, &out);
    return out;
  } else if constexpr (is_batch_v<T>) {
    if constexpr (std::is_same_v<typename T::value_type, double>) {
      return nlid::logistic(s);  // one division per lane instead of two (core/batch.hpp)
    } else {
      return one / (one + exp(-s));
    }
  } else {
    if (value_of(s) >= 0) {
      const T e = exp(-s);
      return one / (one + e);
    }
    const T e = exp(s);
    return e / (one + e);
  }
}

/// " + 1.5" / " - 1.5" for a term appended to an equation.
inline std::string fmt_signed(double v) {
  return v < 0 ? " - " + detail::format_g(-v) : " + " + detail::format_g(v);
}

/// Throws unless `n` equals the expected count; names what was passed.
inline void check_size(std::size_t n, long expected, const char* what, const char* component) {
  if (static_cast<long>(n) != expected) {
    throw Error(std::string(component) + ": " + what + " has " + std::to_string(n) +
                    " entries, expected " + std::to_string(expected),
                at_parameter(what));
  }
}

/// Validates the arguments of `initialize`: column count, row agreement, parameter vector
/// length, a minimum number of samples and finiteness (the first bad cell is named by its
/// 1-based row and column, as a spreadsheet shows it).
inline void check_init_data(const Eigen::MatrixXd& X, const Eigen::VectorXd& y, std::size_t n_theta,
                            long m, long p, long min_rows, const char* component) {
  const std::string c(component);
  if (X.cols() != m) {
    throw Error(c + ": regressor matrix X has " + std::to_string(X.cols()) +
                    " columns, expected " + std::to_string(m) + " (the input dimension)",
                at_parameter("X"));
  }
  if (X.rows() != y.size()) {
    throw Error(c + ": X has " + std::to_string(X.rows()) + " rows but y has " +
                    std::to_string(y.size()) + " entries",
                at_parameter("y"));
  }
  if (static_cast<long>(n_theta) != p) {
    throw Error(c + ": theta has " + std::to_string(n_theta) + " entries, expected " +
                    std::to_string(p),
                at_parameter("theta"));
  }
  if (X.rows() < min_rows) {
    throw Error(c + ": initialize needs at least " + std::to_string(min_rows) +
                    " samples, got " + std::to_string(X.rows()),
                at_parameter("X"));
  }
  for (Eigen::Index i = 0; i < X.rows(); ++i) {
    for (Eigen::Index j = 0; j < X.cols(); ++j) {
      if (!std::isfinite(X(i, j))) {
        Location l = at_parameter("X");
        l.row = static_cast<long>(i) + 1;
        l.column = static_cast<long>(j) + 1;
        throw Error(c + ": non-finite value in X", l);
      }
    }
    if (!std::isfinite(y(i))) {
      Location l = at_parameter("y");
      l.row = static_cast<long>(i) + 1;
      throw Error(c + ": non-finite value in y", l);
    }
  }
}

/// Minimum-norm least-squares solution of A w ≈ b. Columns are equilibrated first (so a column
/// of x³ next to a column of ones does not decide the rank threshold), then a complete
/// orthogonal decomposition gives the minimum-norm solution when columns are collinear —
/// deterministic and bounded where a plain normal-equation solve would blow up.
/// (A template only so that the decomposition is instantiated where it is used: as a plain
/// inline function it cost every includer of a nonlinearity ~6 s of compile time.)
template <class Dense = Eigen::MatrixXd>
Eigen::VectorXd least_squares(const Eigen::MatrixXd& A, const Eigen::VectorXd& b) {
  Eigen::VectorXd scale(A.cols());
  for (Eigen::Index j = 0; j < A.cols(); ++j) {
    const double n = A.col(j).norm();
    scale(j) = n > 0 ? 1.0 / n : 1.0;
  }
  const Eigen::MatrixXd As = A * scale.asDiagonal();
  Eigen::CompleteOrthogonalDecomposition<Dense> cod(As);
  cod.setThreshold(1e-10);
  Eigen::VectorXd w = cod.solve(b);
  return (w.array() * scale.array()).matrix();
}

/// Sorted copy of a vector's entries.
inline std::vector<double> sorted_copy(const Eigen::VectorXd& v) {
  std::vector<double> s(v.data(), v.data() + v.size());
  std::sort(s.begin(), s.end());
  return s;
}

/// Quantile q ∈ [0, 1] of sorted data, linear interpolation between order statistics.
inline double quantile_sorted(const std::vector<double>& s, double q) {
  if (s.empty()) return 0.0;
  const double pos = q * static_cast<double>(s.size() - 1);
  const auto lo = static_cast<std::size_t>(std::floor(pos));
  const std::size_t hi = std::min(lo + 1, s.size() - 1);
  const double f = pos - static_cast<double>(lo);
  return s[lo] * (1 - f) + s[hi] * f;
}

/// 1 − SSE/SST of a fit (1 for a perfect fit, 0 for "no better than the mean").
inline double r_squared(const Eigen::VectorXd& y, const Eigen::VectorXd& yhat) {
  const double sst = (y.array() - y.mean()).square().sum();
  const double sse = (y - yhat).squaredNorm();
  return sst > 0 ? 1.0 - sse / sst : (sse == 0 ? 1.0 : 0.0);
}

}  // namespace nlid::detail

namespace nlid::detail {

/// Input names used by `describe` when the caller supplies none: "x" for one input,
/// "x[0]", "x[1]", ... otherwise (0-based, like the parameter names).
inline std::vector<std::string> input_names_or_default(const std::vector<std::string>& given,
                                                       int m, const char* component) {
  if (!given.empty()) {
    if (static_cast<int>(given.size()) != m) {
      throw Error(std::string(component) + ": " + std::to_string(given.size()) +
                      " input names given for " + std::to_string(m) + " inputs",
                  at_parameter("input_names"));
    }
    return given;
  }
  std::vector<std::string> n;
  if (m == 1) {
    n.emplace_back("x");
  } else {
    for (int j = 0; j < m; ++j) n.push_back("x[" + std::to_string(j) + "]");
  }
  return n;
}

/// Validates the parameter count of a map's sizes, computed in 64 bits by the caller: at most
/// `max_nonlinearity_parameters` (core/sizes.hpp). Throws naming `parameter` (e.g. "units"), with
/// the sizes asked for ("<size> <size_name> over <m> inputs").
inline void check_parameter_count(long long count, const char* parameter, const char* component, int size,
                                  const char* size_name, int m) {
  if (count > max_nonlinearity_parameters) {
    throw Error(std::string(component) + ": " + std::to_string(size) + " " + size_name + " over " + std::to_string(m) +
                    " inputs would need " + std::to_string(count) + " parameters, more than the " +
                    std::to_string(max_nonlinearity_parameters) + " a nonlinearity may have",
                at_parameter(parameter));
  }
}

/// Validates a runtime size against its compile-time twin (`Static` or `Dynamic`).
inline int checked_size(int value, int static_value, int minimum, const char* parameter,
                        const char* component) {
  if (static_value != -1 && value != static_value) {
    throw Error(std::string(component) + ": " + parameter + " = " + std::to_string(value) +
                    " contradicts the compile-time value " + std::to_string(static_value),
                at_parameter(parameter));
  }
  if (value < minimum) {
    throw Error(std::string(component) + ": " + parameter + " must be at least " +
                    std::to_string(minimum) + ", got " + std::to_string(value),
                at_parameter(parameter));
  }
  return value;
}

}  // namespace nlid::detail
