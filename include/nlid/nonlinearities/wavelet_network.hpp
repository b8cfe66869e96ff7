#pragma once
/// @file
/// `WaveletNet<M, Units, LinearTerm>`: a radial wavelet network with a linear term — the
/// toolbox's `wavenet` / idWaveletNetwork (model `nlarx3` of the throttle study).
///
/// Math (Zhang & Benveniste, "Wavelet networks", IEEE TNN 3(6), 1992; Zhang, "Using wavelet
/// network in nonparametric estimation", IEEE TNN 8(2), 1997; Sjöberg et al. 1995, Sec. 6):
///
///     z    = (x − r) ⊘ s                                    standardised regressors
///     ρₖ   = bₖ² ‖z − cₖ‖²                                   dilated, translated radius²
///     φ(ρ) = exp(−ρ/2)                                       scaling function
///     ψ(ρ) = (m − ρ) exp(−ρ/2)                               wavelet ("Mexican hat", zero mean in Rᵐ)
///     g(x) = zᵀL + d + Σₖ [ aₖ φ(ρₖ) + wₖ ψ(ρₖ) ],  k = 0 … n−1.
///
/// Each unit carries both a scaling and a wavelet coefficient on one dilation bₖ and translation
/// cₖ: the toolbox's separate lists of scaling and wavelet terms are the special cases wₖ = 0 and
/// aₖ = 0, and the initialisation chooses both coefficients by least squares. r, s are the
/// regressor mean and standard deviation (structure learned by `initialize`; `set_standardize`
/// (false) makes s = 1, the toolbox's identity projection).
///
/// Parameter vector (linear-in-θ parameters first):
///
///     θ = [ L[0..m−1] (if LinearTerm), d, a[0..n−1], w[0..n−1], b[0..n−1], c[0][0..m−1] … c[n−1][0..m−1] ]
///
/// p = (LinearTerm ? m : 0) + 1 + n(m + 3).
///
/// Initialisation — the toolbox's "iterative" option, made deterministic:
/// 1. r, s from the data, Z standardised;
/// 2. candidate centres: k-means (Lloyd) centres of Z seeded by farthest-point traversal, plus
///    the data mean; candidate dilations: b ∈ {0.5, 1, 2, 4}/√m — from a unit as wide as the
///    cloud (radius ≈ √m in standardised units) down to one an eighth as wide (a dyadic ladder,
///    as in the wavelet frames of Zhang 1997);
/// 3. each (centre, dilation) pair is a candidate unit contributing two columns, φ and ψ; with the
///    offset and linear term in the model, forward selection by orthogonal least squares adds the
///    unit whose two columns best explain the current residual, n times (Zhang 1997, Sec. IV);
/// 4. L, d, a, w by linear least squares on all samples with b, c fixed.
///
/// Sizes: M and Units fixed or `nlid::Dynamic`; with both fixed evaluation uses the stack only.

#include <algorithm>
#include <array>
#include <cmath>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/core/sizes.hpp"
#include "nlid/nonlinearities/detail/common.hpp"
#include "nlid/nonlinearities/detail/forward_selection.hpp"
#include "nlid/nonlinearities/detail/regressor_cloud.hpp"
#include "nlid/nonlinearities/detail/standardizer.hpp"

namespace nlid {

/// Radial wavelet network g(x) = zᵀL + d + Σₖ aₖφ(ρₖ) + wₖψ(ρₖ) (see file comment).
/// Invariants: input_dimension() ≥ 1, units() ≥ 1, equal to M / Units when fixed; s > 0.
template <int M, int Units, bool LinearTerm = true>
  requires((M == Dynamic || M >= 1) && (Units == Dynamic || Units >= 1))
class WaveletNet {
 public:
  /// m (or Dynamic).
  static constexpr int num_inputs = M;
  /// n (or Dynamic).
  static constexpr int num_units = Units;
  /// Whether the linear term zᵀL is present.
  static constexpr bool has_linear_term = LinearTerm;
  /// p = (LinearTerm ? m : 0) + 1 + n(m + 3), or Dynamic.
  static constexpr int num_params =
      (M == Dynamic || Units == Dynamic) ? Dynamic : (LinearTerm ? M : 0) + 1 + Units * (M + 3);

  /// Fixed sizes; normalisation r = 0, s = 1 until `initialize`.
  WaveletNet()
    requires(M != Dynamic && Units != Dynamic)
  = default;
  /// m inputs and n units (each must match the compile-time value when fixed). Throws naming
  /// "m" or "units", and naming "units" if the network would have more than
  /// `max_nonlinearity_parameters` parameters.
  WaveletNet(int m, int units)
      : m_(detail::checked_size(m, M, 1, "m", "WaveletNet")),
        units_(detail::checked_size(units, Units, 1, "units", "WaveletNet")),
        norm_(m_) {
    detail::check_parameter_count((LinearTerm ? m_ : 0) + 1 + static_cast<long long>(units_) * (m_ + 3LL), "units",
                                  "WaveletNet", units_, "units", m_);
  }

  /// Number of inputs m.
  [[nodiscard]] int input_dimension() const { return m_; }
  /// Number of units n (runtime).
  [[nodiscard]] int units() const { return units_; }
  /// Number of parameters p.
  [[nodiscard]] int num_parameters() const { return offset_c() + units_ * m_; }

  /// Regressor centre r.
  [[nodiscard]] const Eigen::Matrix<double, M, 1>& center() const { return norm_.center(); }
  /// Regressor scale s.
  [[nodiscard]] Eigen::Matrix<double, M, 1> scale() const { return norm_.scale(); }
  /// True (default) if `initialize` sets s to the standard deviation; false: s = 1.
  [[nodiscard]] bool standardize() const { return norm_.standardize(); }
  /// See `standardize()`; takes effect at the next `initialize`.
  void set_standardize(bool on) { norm_.set_standardize(on); }
  /// Sets r and s directly (loading a saved model). Throws naming "normalization".
  void set_normalization(const Eigen::VectorXd& center, const Eigen::VectorXd& scale) {
    norm_.set_normalization(center, scale, "WaveletNet");
  }

  /// Index of d in θ (L, if present, starts at 0).
  [[nodiscard]] int offset_d() const { return LinearTerm ? m_ : 0; }
  /// Index of a[0] (scaling coefficients).
  [[nodiscard]] int offset_a() const { return offset_d() + 1; }
  /// Index of w[0] (wavelet coefficients).
  [[nodiscard]] int offset_w() const { return offset_a() + units_; }
  /// Index of b[0] (dilations).
  [[nodiscard]] int offset_b() const { return offset_w() + units_; }
  /// Index of c[0][0] (translations; c[k][j] at offset_c() + k·m + j).
  [[nodiscard]] int offset_c() const { return offset_b() + units_; }

  /// g(x). Throws `nlid::Error` if x or θ has the wrong length.
  template <class T>
  [[nodiscard]] T operator()(std::span<const T> x, std::span<const T> theta) const {
    if (static_cast<int>(x.size()) != m_) detail::check_size(x.size(), m_, "x", "WaveletNet");
    if (static_cast<int>(theta.size()) != num_parameters()) {
      detail::check_size(theta.size(), num_parameters(), "theta", "WaveletNet");
    }
    if constexpr (M != Dynamic) {
      std::array<T, static_cast<std::size_t>(M)> z;
      for (int j = 0; j < M; ++j) z[static_cast<std::size_t>(j)] = norm_.z(x[static_cast<std::size_t>(j)], j);
      return evaluate(theta, [&z](int j) -> const T& { return z[static_cast<std::size_t>(j)]; });
    } else {
      return evaluate(theta, [&](int j) { return norm_.z(x[static_cast<std::size_t>(j)], j); });
    }
  }

  /// Iterative (forward-selection) initialisation, see file comment.
  void initialize(const Eigen::MatrixXd& X, const Eigen::VectorXd& y, std::span<double> theta) {
    detail::check_init_data(X, y, theta.size(), m_, num_parameters(), 2, "WaveletNet");
    const Eigen::MatrixXd Z = norm_.fit(X);
    const auto rows = detail::subsample_rows(Z.rows(), 2000);
    const Eigen::MatrixXd Zs = detail::take_rows(Z, rows);
    Eigen::VectorXd ys(static_cast<Eigen::Index>(rows.size()));
    for (std::size_t i = 0; i < rows.size(); ++i) ys(static_cast<Eigen::Index>(i)) = y(rows[i]);

    std::vector<Eigen::VectorXd> centres = detail::cluster_centres(Zs, std::clamp(3 * units_ + 6, 8, 40));
    const Eigen::VectorXd mean = Zs.colwise().mean().transpose();
    bool have_mean = false;
    for (const auto& c : centres) have_mean = have_mean || (c - mean).norm() < 1e-9;
    if (!have_mean) centres.push_back(mean);
    const double b0 = 1.0 / std::sqrt(static_cast<double>(m_));
    const std::array<double, 4> levels{0.5 * b0, b0, 2 * b0, 4 * b0};
    std::vector<std::pair<double, std::size_t>> cand;  // (dilation, centre index)
    for (double b : levels) {
      for (std::size_t c = 0; c < centres.size(); ++c) cand.emplace_back(b, c);
    }
    const auto nb = static_cast<Eigen::Index>(cand.size());
    Eigen::MatrixXd H(Zs.rows(), 2 * nb);
    for (Eigen::Index j = 0; j < nb; ++j) {
      const auto& [b, c] = cand[static_cast<std::size_t>(j)];
      const Eigen::ArrayXd rho = b * b * (Zs.rowwise() - centres[c].transpose()).rowwise().squaredNorm().array();
      const Eigen::ArrayXd e = (-0.5 * rho).exp();
      H.col(2 * j) = e.matrix();
      H.col(2 * j + 1) = ((static_cast<double>(m_) - rho) * e).matrix();
    }
    detail::ForwardSelector sel(ys, std::move(H), 2);
    sel.add_fixed(Eigen::VectorXd::Ones(Zs.rows()));
    if constexpr (LinearTerm) {
      for (int j = 0; j < m_; ++j) sel.add_fixed(Zs.col(j));
    }
    for (int k = 0; k < units_; ++k) {
      int j = sel.select();
      // More units than candidates (tiny data sets): reuse centres at finer dilations.
      const double finer = j < 0 ? std::pow(2.0, 1 + (k - static_cast<int>(nb)) / static_cast<int>(nb)) : 1.0;
      if (j < 0) j = k % static_cast<int>(nb);
      const auto& [b, c] = cand[static_cast<std::size_t>(j)];
      theta[static_cast<std::size_t>(offset_b() + k)] = b * finer;
      for (int i = 0; i < m_; ++i) theta[static_cast<std::size_t>(offset_c() + k * m_ + i)] = centres[c](i);
    }
    solve_linear(Z, y, theta);
  }

  /// With the dilations and translations in θ fixed, sets L, d, a and w to their
  /// least-squares values for (X, y) under the current normalisation.
  void fit_linear_parameters(const Eigen::MatrixXd& X, const Eigen::VectorXd& y, std::span<double> theta) const {
    detail::check_init_data(X, y, theta.size(), m_, num_parameters(), 1, "WaveletNet");
    solve_linear(norm_.transform(X), y, theta);
  }

  /// "L[j]", "d", "a[k]", "w[k]", "b[k]", "c[k][j]" in θ order.
  [[nodiscard]] std::vector<std::string> parameter_names() const {
    std::vector<std::string> n;
    if constexpr (LinearTerm) {
      for (int j = 0; j < m_; ++j) n.push_back("L[" + std::to_string(j) + "]");
    }
    n.emplace_back("d");
    for (int k = 0; k < units_; ++k) n.push_back("a[" + std::to_string(k) + "]");
    for (int k = 0; k < units_; ++k) n.push_back("w[" + std::to_string(k) + "]");
    for (int k = 0; k < units_; ++k) n.push_back("b[" + std::to_string(k) + "]");
    for (int k = 0; k < units_; ++k) {
      for (int j = 0; j < m_; ++j) n.push_back("c[" + std::to_string(k) + "][" + std::to_string(j) + "]");
    }
    return n;
  }

  /// The equation, the normalisation and all parameter values.
  [[nodiscard]] std::string describe(std::span<const double> theta) const { return describe(theta, {}); }

  /// As `describe(theta)`, naming the inputs; `input_names` empty or m entries.
  [[nodiscard]] std::string describe(std::span<const double> theta, const std::vector<std::string>& input_names) const {
    detail::check_size(theta.size(), num_parameters(), "theta", "WaveletNet");
    const auto names = detail::input_names_or_default(input_names, m_, "WaveletNet");
    const auto th = [&](int i) { return theta[static_cast<std::size_t>(i)]; };
    const Eigen::VectorXd r = norm_.center(), s = norm_.scale();
    using detail::left_aligned;  // the table columns
    std::string o = "wavelet network (" + std::to_string(m_) + " inputs, " + std::to_string(units_) + " units" +
                    (LinearTerm ? ", linear term" : "") + "):\n";
    o += std::string("  g(x) = ") + (LinearTerm ? "z'L + " : "") +
         "d + sum_k a[k]*exp(-rho_k/2) + w[k]*(m - rho_k)*exp(-rho_k/2),\n"
         "  rho_k = b[k]^2 * |z - c[k]|^2,  z = (x - r)./s,  m = " + std::to_string(m_) + "\n";
    o += "  input            r (centre)    s (scale)";
    if constexpr (LinearTerm) o += "     L[j]          L[j]/s (per unit of x)";
    o += "\n";
    for (int j = 0; j < m_; ++j) {
      o += "  " + left_aligned(names[static_cast<std::size_t>(j)], 16) + " " +
           left_aligned(detail::format_g(r(j)), 13) + " " + left_aligned(detail::scale_text(s(j)), 13);
      if constexpr (LinearTerm)
        o += " " + left_aligned(detail::format_g(th(j)), 13) + " " + detail::per_unit_text(th(j), s(j));
      o += "\n";
    }
    o += detail::unused_note(s);
    o += "  d = " + detail::format_g(th(offset_d())) + "\n";
    o += "  unit  a[k] (scaling)  w[k] (wavelet)  b[k] (dilation)  c[k] (translation, in z)\n";
    for (int k = 0; k < units_; ++k) {
      o += "  " + left_aligned(std::to_string(k), 5) + " " + left_aligned(detail::format_g(th(offset_a() + k)), 15) +
           " " + left_aligned(detail::format_g(th(offset_w() + k)), 15) + " " +
           left_aligned(detail::format_g(th(offset_b() + k)), 16) + " [";
      for (int j = 0; j < m_; ++j) o += (j ? ", " : "") + detail::format_g(th(offset_c() + k * m_ + j));
      o += "]\n";
    }
    return o;
  }

  // ---- Implementation details below ----------------------------------------------------------
 private:
  template <class T, class Z>
  T evaluate(std::span<const T> theta, Z&& z) const {
    using std::exp;
    const auto at = [&theta](int i) -> const T& { return theta[static_cast<std::size_t>(i)]; };
    T g = at(offset_d());
    if constexpr (LinearTerm) {
      for (int j = 0; j < m_; ++j) g += at(j) * z(j);
    }
    const T dim = detail::cast_to<T>(static_cast<double>(m_));
    const T half = detail::cast_to<T>(0.5);
    const int oa = offset_a(), ow = offset_w(), ob = offset_b(), oc = offset_c();
    for (int k = 0; k < units_; ++k) {
      T d2 = detail::cast_to<T>(0.0);
      for (int j = 0; j < m_; ++j) {
        const T dj = z(j) - at(oc + k * m_ + j);
        d2 += dj * dj;
      }
      // Far from a centre (d2 overflowing to inf for |z| ~ 1e155) the unit is exactly 0, but
      // (a + w(m − ρ))·exp(−ρ/2) would read (−inf)·0 = NaN. exp(−750) is already 0 in double,
      // so capping ρ there changes no finite value. The argument order keeps a NaN ρ NaN:
      // nlid::min returns its second argument when the comparison fails, Batch's min its first.
      const T rho_raw = at(ob + k) * at(ob + k) * d2;
      const T cap = detail::cast_to<T>(1500.0);
      T rho;
      if constexpr (is_batch_v<T>) {
        rho = min(rho_raw, cap);
      } else {
        rho = min(cap, rho_raw);
      }
      const T e = exp(-half * rho);
      g += (at(oa + k) + at(ow + k) * (dim - rho)) * e;
    }
    return g;
  }

  void solve_linear(const Eigen::MatrixXd& Z, const Eigen::VectorXd& y, std::span<double> theta) const {
    const int nl = LinearTerm ? m_ : 0;
    Eigen::MatrixXd A(Z.rows(), nl + 1 + 2 * units_);
    if constexpr (LinearTerm) A.leftCols(m_) = Z;
    A.col(nl).setOnes();
    for (int k = 0; k < units_; ++k) {
      Eigen::RowVectorXd c(m_);
      for (int j = 0; j < m_; ++j) c(j) = theta[static_cast<std::size_t>(offset_c() + k * m_ + j)];
      const double b = theta[static_cast<std::size_t>(offset_b() + k)];
      const Eigen::ArrayXd rho = b * b * (Z.rowwise() - c).rowwise().squaredNorm().array();
      const Eigen::ArrayXd e = (-0.5 * rho).exp();
      A.col(nl + 1 + k) = e.matrix();
      A.col(nl + 1 + units_ + k) = ((static_cast<double>(m_) - rho) * e).matrix();
    }
    const Eigen::VectorXd w = detail::least_squares(A, y);
    for (int i = 0; i < nl + 1 + 2 * units_; ++i) theta[static_cast<std::size_t>(i)] = w(i);
  }

  int m_ = M;
  int units_ = Units;
  detail::Standardizer<M> norm_;
};

}  // namespace nlid
