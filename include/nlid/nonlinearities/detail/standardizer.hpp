#pragma once
/// @file
/// Regressor standardisation z = (x − r) ⊘ s shared by the unit networks. r and s are structure
/// (learned by `initialize`, not estimated), stored at the compile-time size M so fixed-size
/// evaluation needs no heap.

#include <cmath>
#include <string>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/nonlinearities/detail/common.hpp"
#include "nlid/nonlinearities/detail/regressor_cloud.hpp"

namespace nlid::detail {

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
  /// Regressor scale s (standard deviation, or 1 if standardisation is off).
  [[nodiscard]] Vector scale() const { return inv_scale_.cwiseInverse(); }
  /// ∂zⱼ/∂xⱼ = 1/sⱼ (analytic gradients).
  [[nodiscard]] double inv_scale(Eigen::Index j) const { return inv_scale_(j); }
  /// Whether `initialize` divides by the standard deviation (default) or only centres.
  [[nodiscard]] bool standardize() const { return standardize_; }
  /// Chooses scaling by the standard deviation (true) or centring only (false, as MATLAB's
  /// r = mean(x) with identity projections). Takes effect at the next `initialize`.
  void set_standardize(bool on) { standardize_ = on; }

  /// Sets r and s explicitly (e.g. when loading a saved model). s must be positive and finite.
  void set_normalization(const Eigen::VectorXd& center, const Eigen::VectorXd& scale, const char* component) {
    const auto m = center_.size();
    if (center.size() != m || scale.size() != m) {
      throw Error(std::string(component) + ": normalisation vectors need " + std::to_string(m) +
                      " entries, got " + std::to_string(center.size()) + " and " +
                      std::to_string(scale.size()),
                  at_parameter("normalization"));
    }
    for (Eigen::Index j = 0; j < m; ++j) {
      if (!std::isfinite(center(j)) || !(scale(j) > 0) || !std::isfinite(scale(j))) {
        throw Error(std::string(component) + ": normalisation of input " + std::to_string(j) +
                        " must have a finite centre and a positive finite scale",
                    at_parameter("normalization"));
      }
    }
    center_ = center;
    inv_scale_ = scale.cwiseInverse();
  }

  /// Learns r (and s) from the rows of X and returns the standardised data Z. A numerically
  /// constant column of X gives an exactly zero column of Z.
  Eigen::MatrixXd fit(const Eigen::MatrixXd& X) {
    Eigen::VectorXd mean, sd;
    detail::column_moments_into(X, mean, sd);
    center_ = mean;
    inv_scale_ = standardize_ ? Vector(sd.cwiseInverse()) : Vector(Vector::Ones(X.cols()));
    Eigen::MatrixXd Z = transform(X);
    // x − mean of a constant column is rounding noise (0.1 − mean(0.1, …) ≈ 1e-17), not 0. The
    // least-squares solves equilibrate columns, so that noise would become a unit column and get
    // a coefficient of ~1e15: harmless on these data, a blow-up wherever the regressor moves.
    for (Eigen::Index j = 0; j < X.cols(); ++j) {
      if (detail::is_constant_column(X.col(j), mean(j))) Z.col(j).setZero();
    }
    return Z;
  }

  /// Z = (X − r) ⊘ s row-wise.
  [[nodiscard]] Eigen::MatrixXd transform(const Eigen::MatrixXd& X) const {
    return ((X.rowwise() - center_.transpose()).array().rowwise() * inv_scale_.transpose().array()).matrix();
  }

  /// zⱼ in the evaluation scalar.
  template <class T>
  [[nodiscard]] T z(const T& xj, Eigen::Index j) const {
    return (xj - cast_to<T>(center_(j))) * cast_to<T>(inv_scale_(j));
  }

 private:
  Vector center_;
  Vector inv_scale_;
  bool standardize_ = true;
};

}  // namespace nlid::detail
