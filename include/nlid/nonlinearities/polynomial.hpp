#pragma once
/// @file
/// `Poly1d<Degree>`: a one-dimensional polynomial g(x) = Σₖ cₖ xᵏ (toolbox `poly1d` /
/// idPolynomial1D), a smooth input or output nonlinearity for Hammerstein–Wiener models
/// (e.g. a cubic for a sensor's gain curve).
///
/// Math. θ = [c₀, c₁, …, c_D] (ascending powers: "c[k]" multiplies xᵏ; MATLAB's
/// `polyval` lists the same numbers highest power first). Evaluation is Horner's rule,
///
///     g(x) = c₀ + x(c₁ + x(c₂ + … + x c_D)),
///
/// D multiplications and additions, exact for Dual as well (∂g/∂cₖ = xᵏ).
///
/// Initialisation: linear least squares on the Vandermonde matrix [1 x … x^D]. Its columns
/// differ in scale by up to max|x|^D (for angles in degrees and D = 3, about 10⁶), so the fit is
/// computed in the centred, scaled variable t = (x − μ)/σ and the coefficients are converted
/// back exactly by the binomial expansion of (x − μ)ᵏ — the conditioning of the solve then
/// does not depend on the units of x. A constant x (σ below 1e-12 of |μ|) gives the constant
/// polynomial g = mean(y).

#include <cmath>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/core/sizes.hpp"
#include "nlid/nonlinearities/detail/common.hpp"

namespace nlid {

/// Polynomial of one input, g(x) = Σₖ c[k] xᵏ, k = 0 … Degree; p = Degree + 1.
/// Invariant: degree() ≥ 1 and equals Degree when Degree is fixed.
template <int Degree>
  requires(Degree == Dynamic || Degree >= 1)
class Poly1d {
 public:
  /// m = 1.
  static constexpr int num_inputs = 1;
  /// p = Degree + 1 (or Dynamic).
  static constexpr int num_params = size_sum(Degree, 1);

  /// Fixed-degree polynomial.
  Poly1d()
    requires(Degree != Dynamic)
  = default;
  /// Polynomial of the given degree (≥ 1; must equal Degree when fixed). Throws naming "degree".
  explicit Poly1d(int degree) : degree_(detail::checked_size(degree, Degree, 1, "degree", "Poly1d")) {}

  /// The polynomial degree D.
  [[nodiscard]] int degree() const { return degree_; }
  /// Number of inputs (1).
  [[nodiscard]] int input_dimension() const { return 1; }
  /// Number of parameters D + 1.
  [[nodiscard]] int num_parameters() const { return degree_ + 1; }

  /// Horner evaluation. Throws `nlid::Error` if a span has the wrong length.
  template <class T>
  [[nodiscard]] T operator()(std::span<const T> x, std::span<const T> theta) const {
    if (x.size() != 1) detail::check_size(x.size(), 1, "x", "Poly1d");
    if (static_cast<int>(theta.size()) != degree_ + 1) detail::check_size(theta.size(), degree_ + 1, "theta", "Poly1d");
    T s = theta[static_cast<std::size_t>(degree_)];
    for (int k = degree_ - 1; k >= 0; --k) s = s * x[0] + theta[static_cast<std::size_t>(k)];
    return s;
  }

  /// Least-squares coefficients for (X, y), X is N × 1 with at least D + 1 samples.
  void initialize(const Eigen::MatrixXd& X, const Eigen::VectorXd& y, std::span<double> theta) {
    detail::check_init_data(X, y, theta.size(), 1, degree_ + 1, degree_ + 1, "Poly1d");
    const Eigen::VectorXd x = X.col(0);
    const double mu = x.mean();
    const double sigma = std::sqrt((x.array() - mu).square().mean());
    if (!(sigma > 1e-12 * std::abs(mu))) {  // relative, as detail::is_constant_column
      // A constant input determines g at one point only: the constant polynomial, mean(y). The
      // general path would divide the rounding noise x − μ ≈ 1e-17 by itself (t = ±1) and give
      // coefficients of 1e50 through the expansion below.
      theta[0] = y.mean();
      for (int k = 1; k <= degree_; ++k) theta[static_cast<std::size_t>(k)] = 0.0;
      return;
    }
    const int n = degree_ + 1;
    Eigen::MatrixXd V(x.size(), n);
    V.col(0).setOnes();
    const Eigen::ArrayXd t = (x.array() - mu) / sigma;
    for (int k = 1; k < n; ++k) V.col(k) = V.col(k - 1).array() * t;
    const Eigen::VectorXd e = detail::least_squares(V, y);  // g = Σ e_k ((x − μ)/σ)^k
    // Expand Σ e_k σ^-k (x − μ)^k = Σ e_k σ^-k Σ_j C(k,j) x^j (−μ)^(k−j).
    std::vector<double> c(static_cast<std::size_t>(n), 0.0);
    for (int k = 0; k < n; ++k) {
      const double ek = e(k) / std::pow(sigma, k);
      double binom = 1.0;  // C(k, j), updated along j
      for (int j = 0; j <= k; ++j) {
        c[static_cast<std::size_t>(j)] += ek * binom * std::pow(-mu, k - j);
        binom = binom * (k - j) / (j + 1);
      }
    }
    for (int k = 0; k < n; ++k) theta[static_cast<std::size_t>(k)] = c[static_cast<std::size_t>(k)];
  }

  /// The unit of each parameter when x is measured in units of size `in` and g(x) in units of
  /// size `out` (estimation uses them to damp steps alike whatever units the data are in).
  bool parameter_scales(double in, double out, std::span<double> s) const {
    double unit = out;
    for (int k = 0; k <= degree_; ++k, unit /= in) {
      // out/inᵏ leaves the doubles for extreme units and high degrees; such a coefficient is
      // then damped as if unitless rather than with 0 or ∞.
      s[static_cast<std::size_t>(k)] = std::isfinite(unit) && unit > 0 ? unit : 1.0;
    }
    return true;
  }

  /// "c[0]", …, "c[D]" (c[k] multiplies xᵏ).
  [[nodiscard]] std::vector<std::string> parameter_names() const {
    std::vector<std::string> n;
    for (int k = 0; k <= degree_; ++k) n.push_back("c[" + std::to_string(k) + "]");
    return n;
  }

  /// The polynomial, highest power first, e.g. "g(x) = 2·x^3 - 0.5·x + 1".
  [[nodiscard]] std::string describe(std::span<const double> theta) const {
    detail::check_size(theta.size(), degree_ + 1, "theta", "Poly1d");
    std::string s = "polynomial (degree " + std::to_string(degree_) + "): g(x) =";
    bool first = true;
    for (int k = degree_; k >= 0; --k) {
      const double v = theta[static_cast<std::size_t>(k)];
      if (v == 0.0 && !(k == 0 && first)) continue;
      std::string mag = detail::format_g(std::abs(v));
      std::string term = k == 0 ? mag : (k == 1 ? mag + "·x" : mag + "·x^" + std::to_string(k));
      s += first ? (v < 0 ? " -" + term : " " + term) : (v < 0 ? " - " : " + ") + term;
      first = false;
    }
    return s + "\n";
  }

 private:
  int degree_ = Degree;
};

}  // namespace nlid
