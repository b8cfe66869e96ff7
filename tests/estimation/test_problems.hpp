#pragma once
// Residual functors with known minima, shared by the estimation and nomalloc tests.
#include <cmath>
#include <span>

#include <Eigen/Core>

#include "nlid/ad/dual.hpp"
#include "nlid/core/sizes.hpp"

namespace nlid_test {

// Rosenbrock as least squares: r = (10(x₂ − x₁²), 1 − x₁); minimum 0 at (1, 1).
template <int P>
struct Rosenbrock {
  static constexpr int num_params = P;
  int num_parameters() const { return 2; }
  Eigen::Index num_residuals() const { return 2; }
  template <class T>
  bool residuals(std::span<const T> x, std::span<T> r) const {
    r[0] = 10.0 * (x[1] - x[0] * x[0]);
    r[1] = 1.0 - x[0];
    return true;
  }
};

// Extended Rosenbrock in n (even) dimensions, dynamic parameter count: r_{2i} = 10(x_{2i+1} −
// x_{2i}²), r_{2i+1} = 1 − x_{2i}; minimum 0 at (1, …, 1).
struct ExtendedRosenbrock {
  static constexpr int num_params = nlid::Dynamic;
  int n = 10;
  int num_parameters() const { return n; }
  Eigen::Index num_residuals() const { return n; }
  template <class T>
  bool residuals(std::span<const T> x, std::span<T> r) const {
    for (int i = 0; i < n / 2; ++i) {
      r[2 * i] = 10.0 * (x[2 * i + 1] - x[2 * i] * x[2 * i]);
      r[2 * i + 1] = 1.0 - x[2 * i];
    }
    return true;
  }
};

// y = a exp(b t) + c sampled at m points on [0, 2]; θ = (a, b, c).
template <int P = 3>
struct ExpFit {
  static constexpr int num_params = P;
  Eigen::VectorXd t, y;
  ExpFit(double a, double b, double c, int m = 50, double outlier = 0.0) : t(m), y(m) {
    for (int i = 0; i < m; ++i) {
      t[i] = 2.0 * i / (m - 1);
      y[i] = a * std::exp(b * t[i]) + c;
    }
    if (outlier != 0.0) y[m / 2] += outlier;
  }
  int num_parameters() const { return 3; }
  Eigen::Index num_residuals() const { return t.size(); }
  template <class T>
  bool residuals(std::span<const T> th, std::span<T> r) const {
    using std::exp;
    for (Eigen::Index i = 0; i < t.size(); ++i) {
      r[static_cast<std::size_t>(i)] = th[0] * exp(th[1] * t[i]) + th[2] - y[i];
    }
    return true;
  }
};

// Straight line y = a + b t on [0, 1] with small deterministic noise and gross outliers.
struct LineWithOutliers {
  static constexpr int num_params = 2;
  Eigen::VectorXd t, y;
  LineWithOutliers(double a, double b, int m, int every_kth_outlier, double outlier_size)
      : t(m), y(m) {
    for (int i = 0; i < m; ++i) {
      t[i] = static_cast<double>(i) / (m - 1);
      y[i] = a + b * t[i] + 0.01 * std::sin(37.0 * i);
      if (every_kth_outlier > 0 && i % every_kth_outlier == 3) y[i] += outlier_size;
    }
  }
  int num_parameters() const { return 2; }
  Eigen::Index num_residuals() const { return t.size(); }
  template <class T>
  bool residuals(std::span<const T> th, std::span<T> r) const {
    for (Eigen::Index i = 0; i < t.size(); ++i) {
      r[static_cast<std::size_t>(i)] = th[0] + th[1] * t[i] - y[i];
    }
    return true;
  }
};

// A small sigmoid network g(x) = d + Σ_k a_k σ(b_k x + c_k) fitted to data: n = 3K + 1
// parameters (dynamic count), a realistic nonlinearity for Jacobian checks.
struct SigmoidNetFit {
  static constexpr int num_params = nlid::Dynamic;
  int units = 4;
  Eigen::VectorXd x, y;
  SigmoidNetFit(int k, int m) : units(k), x(m), y(m) {
    for (int i = 0; i < m; ++i) {
      x[i] = -2.0 + 4.0 * i / (m - 1);
      y[i] = std::tanh(1.5 * x[i]) + 0.3 * x[i] * x[i];
    }
  }
  int num_parameters() const { return 3 * units + 1; }
  Eigen::Index num_residuals() const { return x.size(); }
  template <class T>
  bool residuals(std::span<const T> th, std::span<T> r) const {
    using std::exp;
    for (Eigen::Index i = 0; i < x.size(); ++i) {
      T g = th[static_cast<std::size_t>(3 * units)];
      for (int k = 0; k < units; ++k) {
        const T s = th[3 * k + 1] * x[i] + th[3 * k + 2];
        g += th[3 * k] / (1.0 + exp(-s));
      }
      r[static_cast<std::size_t>(i)] = g - y[i];
    }
    return true;
  }
};

}  // namespace nlid_test
