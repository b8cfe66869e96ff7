#pragma once
/// @file
/// `LinearMap<M>`: the affine map g(x) = xᵀL + d — the toolbox's "no nonlinearity" choice
/// (idLinear / `linear`) for nonlinear ARX, where it turns the model into a linear ARX with an
/// offset term d.
///
/// Math. With regressors x ∈ Rᵐ, parameters θ = [L₀ … L_{m−1}, d]:
///
///     g(x) = Σⱼ Lⱼ xⱼ + d.
///
/// The offset matters in practice: the throttle rests at ≈ 15° for zero input, which a
/// linear ARX without d cannot reproduce (model `nlarx1` of the study is exactly this map on
/// the regressors y(t−1), y(t−2), u(t)). `initialize` is the ordinary least-squares solution of
/// [X 1]θ ≈ y (Ljung 1999, eq. (7.34)), computed with a rank-revealing QR so collinear
/// regressors give the minimum-norm θ instead of a blow-up.
///
/// Sizes: `M` fixed or `nlid::Dynamic` (then pass m to the constructor). p = m + 1.

#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/core/sizes.hpp"
#include "nlid/nonlinearities/detail/common.hpp"

namespace nlid {

/// Affine map g(x) = xᵀL + d, θ = [L[0] … L[m−1], d].
/// Invariant: input_dimension() ≥ 1 and equals M when M is fixed.
template <int M>
  requires(M == Dynamic || M >= 1)
class LinearMap {
 public:
  /// m (or Dynamic).
  static constexpr int num_inputs = M;
  /// p = m + 1 (or Dynamic).
  static constexpr int num_params = size_sum(M, 1);

  /// Fixed-size map; parameters are supplied by the caller.
  LinearMap()
    requires(M != Dynamic)
  = default;
  /// Map of `m` inputs (must equal M when M is fixed). Throws if m < 1, naming "m".
  explicit LinearMap(int m) : m_(detail::checked_size(m, M, 1, "m", "LinearMap")) {}

  /// Number of inputs m.
  [[nodiscard]] int input_dimension() const { return m_; }
  /// Number of parameters p = m + 1.
  [[nodiscard]] int num_parameters() const { return m_ + 1; }

  /// g(x) = xᵀL + d. Throws `nlid::Error` if x or θ has the wrong length.
  template <class T>
  [[nodiscard]] T operator()(std::span<const T> x, std::span<const T> theta) const {
    check_spans(x.size(), theta.size());
    T s = theta[static_cast<std::size_t>(m_)];
    for (int j = 0; j < m_; ++j) s += theta[static_cast<std::size_t>(j)] * x[static_cast<std::size_t>(j)];
    return s;
  }

  /// Least-squares fit of L and d to (X, y); X is N × m, y has N entries.
  void initialize(const Eigen::MatrixXd& X, const Eigen::VectorXd& y, std::span<double> theta) {
    detail::check_init_data(X, y, theta.size(), m_, m_ + 1, 1, "LinearMap");
    Eigen::MatrixXd A(X.rows(), m_ + 1);
    A.leftCols(m_) = X;
    A.col(m_).setOnes();
    const Eigen::VectorXd w = detail::least_squares(A, y);
    for (int j = 0; j <= m_; ++j) theta[static_cast<std::size_t>(j)] = w(j);
  }

  /// The unit of each parameter when x is measured in units of size `in` and g(x) in units of
  /// size `out` (estimation uses them to damp steps alike whatever units the data are in).
  bool parameter_scales(double in, double out, std::span<double> s) const {
    for (int k = 0; k < m_; ++k) s[static_cast<std::size_t>(k)] = out / in;
    s[static_cast<std::size_t>(m_)] = out;
    return true;
  }

  /// "L[0]", …, "L[m−1]", "d".
  [[nodiscard]] std::vector<std::string> parameter_names() const {
    std::vector<std::string> n;
    for (int j = 0; j < m_; ++j) n.push_back("L[" + std::to_string(j) + "]");
    n.emplace_back("d");
    return n;
  }

  /// The equation with numbers, e.g. "g(x) = 0.9·x[0] - 0.2·x[1] + 1.5".
  [[nodiscard]] std::string describe(std::span<const double> theta) const { return describe(theta, {}); }

  /// As `describe(theta)`, writing the inputs with the caller's names (e.g. regressor names
  /// "y(t-1)", "u(t)"); `input_names` must be empty or have m entries.
  [[nodiscard]] std::string describe(std::span<const double> theta,
                                     const std::vector<std::string>& input_names) const {
    detail::check_size(theta.size(), m_ + 1, "theta", "LinearMap");
    const auto names = detail::input_names_or_default(input_names, m_, "LinearMap");
    std::string s = "linear map: g(x) = ";
    for (int j = 0; j < m_; ++j) {
      const double v = theta[static_cast<std::size_t>(j)];
      s += (j == 0 ? (v < 0 ? "-" + detail::format_g(-v) : detail::format_g(v)) : detail::fmt_signed(v)) +
           "·" + names[static_cast<std::size_t>(j)];
    }
    s += detail::fmt_signed(theta[static_cast<std::size_t>(m_)]) + "\n";
    return s;
  }

  // ---- Implementation details below ----------------------------------------------------------
 private:
  void check_spans(std::size_t nx, std::size_t nt) const {
    if (static_cast<int>(nx) != m_) detail::check_size(nx, m_, "x", "LinearMap");
    if (static_cast<int>(nt) != m_ + 1) detail::check_size(nt, m_ + 1, "theta", "LinearMap");
  }

  int m_ = M;
};

}  // namespace nlid
