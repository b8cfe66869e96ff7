#pragma once
/// @file
/// Regressor standardisation z = (x − r) ⊘ s shared by the unit networks. r and s are structure
/// (learned by `initialize`, not estimated), stored at the compile-time size M so fixed-size
/// evaluation needs no heap.
///
/// A regressor that was constant in the initialisation data gets s = 0, read as "not used":
/// its z is exactly 0 wherever it moves later. With the old s = 1, z was x − mean, rounding noise
/// of ~1e-17 on the estimation data (0.1 − mean(0.1, …) ≠ 0), which the estimation fitted with
/// weights of ~1e15 — a model whose output jumped by 1e11 when that input moved by 0.1. The data
/// say nothing about such a regressor, so the model must not depend on it.

#include <cmath>
#include <string>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/nonlinearities/detail/common.hpp"
#include "nlid/nonlinearities/detail/regressor_cloud.hpp"

namespace nlid::detail {

/// sⱼ in a describe() table: an unused regressor says so instead of printing a bare 0.
inline std::string scale_text(double s) { return s == 0.0 ? "0 (unused)" : format_g(s); }
/// A weight per unit of x (L[j]/sⱼ) in a describe() table; "-" for an unused regressor.
inline std::string per_unit_text(double weight, double s) { return s == 0.0 ? "-" : format_g(weight / s); }
/// The describe() line explaining s = 0, or nothing when every regressor is used.
inline std::string unused_note(const Eigen::VectorXd& s) {
  return (s.array() == 0.0).any() ? "  s = 0 (unused): the input was constant in the initialisation data; its z is 0\n"
                                  : std::string();
}

/// Centre r and scale s of M regressors, with z = (x − r) ⊘ s.
template <int M>
class Standardizer {
 public:
  using Vector = Eigen::Matrix<double, M, 1>;

  Standardizer() {
    if constexpr (M != -1) {
      center_.setZero();
      inv_scale_.setOnes();
    }
  }
  explicit Standardizer(int m) : center_(Vector::Zero(m)), inv_scale_(Vector::Ones(m)) {}

  /// Regressor centre r (mean of the initialisation data).
  [[nodiscard]] const Vector& center() const { return center_; }
  /// Regressor scale s (standard deviation, or 1 if standardisation is off; 0 for a regressor
  /// that was constant in the initialisation data, whose z is always 0).
  [[nodiscard]] Vector scale() const { return inverse_or_zero(inv_scale_); }
  /// ∂zⱼ/∂xⱼ = 1/sⱼ, 0 for an unused regressor (analytic gradients).
  [[nodiscard]] double inv_scale(Eigen::Index j) const { return inv_scale_(j); }
  /// Whether `initialize` divides by the standard deviation (default) or only centres.
  [[nodiscard]] bool standardize() const { return standardize_; }
  /// Chooses scaling by the standard deviation (true) or centring only (false, as MATLAB's
  /// r = mean(x) with identity projections). Takes effect at the next `initialize`.
  void set_standardize(bool on) { standardize_ = on; }

  /// Sets r and s explicitly (e.g. when loading a saved model). s must be finite and positive, or
  /// 0 for a regressor the function does not use (z ≡ 0).
  void set_normalization(const Eigen::VectorXd& center, const Eigen::VectorXd& scale, const char* component) {
    const auto m = center_.size();
    if (center.size() != m || scale.size() != m) {
      throw Error(std::string(component) + ": normalisation vectors need " + std::to_string(m) +
                      " entries, got " + std::to_string(center.size()) + " and " +
                      std::to_string(scale.size()),
                  at_parameter("normalization"));
    }
    for (Eigen::Index j = 0; j < m; ++j) {
      if (!std::isfinite(center(j)) || !(scale(j) >= 0) || !std::isfinite(scale(j))) {
        throw Error(std::string(component) + ": normalisation of input " + std::to_string(j) +
                        " must have a finite centre and a positive finite scale (or 0: input not used)",
                    at_parameter("normalization"));
      }
    }
    center_ = center;
    inv_scale_ = inverse_or_zero(scale);
  }

  /// Learns r (and s) from the rows of X and returns the standardised data Z. A numerically
  /// constant column of X gets s = 0 (not used): its column of Z is exactly zero.
  Eigen::MatrixXd fit(const Eigen::MatrixXd& X) {
    Eigen::VectorXd mean, sd;
    detail::column_moments_into(X, mean, sd);
    center_ = mean;
    inv_scale_ = standardize_ ? Vector(sd.cwiseInverse()) : Vector(Vector::Ones(X.cols()));
    for (Eigen::Index j = 0; j < X.cols(); ++j) {
      if (detail::is_constant_column(X.col(j), mean(j))) inv_scale_(j) = 0.0;
    }
    return transform(X);
  }

  /// Whether regressor j is used (it varied in the initialisation data).
  [[nodiscard]] bool used(Eigen::Index j) const { return inv_scale_(j) != 0.0; }

  /// Z = (X − r) ⊘ s row-wise.
  [[nodiscard]] Eigen::MatrixXd transform(const Eigen::MatrixXd& X) const {
    return ((X.rowwise() - center_.transpose()).array().rowwise() * inv_scale_.transpose().array()).matrix();
  }

  /// zⱼ in the evaluation scalar (exactly 0 for an unused regressor with finite xⱼ).
  template <class T>
  [[nodiscard]] T z(const T& xj, Eigen::Index j) const {
    return (xj - cast_to<T>(center_(j))) * cast_to<T>(inv_scale_(j));
  }

 private:
  // s ↔ 1/s both ways, with 0 (unused) kept as 0.
  static Vector inverse_or_zero(const Eigen::Ref<const Eigen::VectorXd>& v) {
    return v.unaryExpr([](double x) { return x == 0.0 ? 0.0 : 1.0 / x; });
  }

  Vector center_;
  Vector inv_scale_;
  bool standardize_ = true;
};

}  // namespace nlid::detail
