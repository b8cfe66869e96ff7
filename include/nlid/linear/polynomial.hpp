#pragma once
/// @file
/// Polynomials in the backward shift operator q⁻¹ and the filters they define.
///
/// Notation (Ljung 1999, §2.1 and §4.2): q⁻¹ x(t) = x(t − 1). A polynomial
///
///     P(q) = p₀ + p₁ q⁻¹ + … + pₙ q⁻ⁿ
///
/// is stored as the coefficient vector [p₀, p₁, …, pₙ] (ascending powers of q⁻¹), exactly as the
/// System Identification Toolbox stores A, B, C, D, F. A *monic* polynomial has p₀ = 1 (the
/// A and F polynomials of ARX and OE models). A pure delay q⁻ⁿᵏ shows as nk leading zeros.
///
/// The filter y = B(q)/A(q) x is the difference equation (Ljung 1999, eq. 4.7)
///
///     a₀ y(t) = b₀ x(t) + … + b_nb x(t − nb) − a₁ y(t − 1) − … − a_na y(t − na),
///
/// run from rest (x(t) = y(t) = 0 for t < 0). Its poles are the roots of zⁿ A(z) in the complex
/// z-plane: z^na + a₁ z^(na−1) + … + a_na = 0. The filter is (BIBO) stable iff all poles lie
/// strictly inside the unit circle. `reflect_unstable` mirrors a pole r outside the circle to
/// 1/r̄: the magnitude of the frequency response changes only by a constant factor (the
/// mirrored factor is all-pass up to a gain), which is why output-error estimators use it to
/// restart from a stable denominator (Ljung 1999, §10.2; Söderström & Stoica 1989, §C7.6).
///
/// All filter functions are templates over the scalar, so the same code runs on `double`,
/// `float` and `nlid::Dual` (coefficients and signals may differ in type, e.g. Dual
/// coefficients filtering a `double` input, as a Hammerstein–Wiener Jacobian needs).

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>

#include "nlid/ad/dual.hpp"
#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"

namespace nlid {

/// Filters `x` through B(q)/A(q) from rest: a₀y(t) = Σ bₖ x(t−k) − Σₖ≥₁ aₖ y(t−k).
/// Scalars may be double, float or Dual (mixed types allowed where their product is defined).
/// Throws `nlid::Error` if `a` is empty or a₀ = 0 (the filter would not be causal).
template <class Db, class Da, class Dx>
auto filter(const Eigen::MatrixBase<Db>& b, const Eigen::MatrixBase<Da>& a,
            const Eigen::MatrixBase<Dx>& x) {
  using Sb = typename Db::Scalar;
  using Sa = typename Da::Scalar;
  using Sx = typename Dx::Scalar;
  using R = std::decay_t<decltype(std::declval<Sb>() * std::declval<Sx>() -
                                  std::declval<Sa>() * std::declval<Sx>())>;
  require(a.size() > 0, "filter: denominator polynomial is empty", at_parameter("a"));
  require(static_cast<double>(value_of(a(0))) != 0.0, "filter: leading denominator coefficient a0 is zero",
          at_parameter("a"));
  const Eigen::Index n = x.size();
  Eigen::Matrix<R, Eigen::Dynamic, 1> y(n);
  const Sa a0 = a(0);
  for (Eigen::Index t = 0; t < n; ++t) {
    R acc = R(0);
    const Eigen::Index kb = std::min<Eigen::Index>(b.size() - 1, t);
    for (Eigen::Index k = 0; k <= kb; ++k) acc += b(k) * x(t - k);
    const Eigen::Index ka = std::min<Eigen::Index>(a.size() - 1, t);
    for (Eigen::Index k = 1; k <= ka; ++k) acc -= a(k) * y(t - k);
    y(t) = acc / a0;
  }
  return y;
}

/// Product of two polynomials in q⁻¹ (convolution of the coefficient vectors).
inline Eigen::VectorXd convolve(const Eigen::VectorXd& p, const Eigen::VectorXd& r) {
  if (p.size() == 0 || r.size() == 0) return Eigen::VectorXd();
  Eigen::VectorXd c = Eigen::VectorXd::Zero(p.size() + r.size() - 1);
  for (Eigen::Index i = 0; i < p.size(); ++i)
    for (Eigen::Index j = 0; j < r.size(); ++j) c(i + j) += p(i) * r(j);
  return c;
}

/// Roots in the z-plane of P(q) = p₀ + p₁q⁻¹ + … + pₙq⁻ⁿ, i.e. of p₀zⁿ + … + pₙ.
/// Leading zero coefficients are pure delays (q⁻ᵏ has no finite root in z) and are skipped;
/// trailing zeros give roots at z = 0. Computed as eigenvalues of the companion matrix.
template <int = 0>
Eigen::VectorXcd roots(const Eigen::VectorXd& p) {
  Eigen::Index first = 0;
  while (first < p.size() && p(first) == 0.0) ++first;
  const Eigen::Index degree = p.size() - first - 1;
  if (degree <= 0) return Eigen::VectorXcd();
  Eigen::MatrixXd companion = Eigen::MatrixXd::Zero(degree, degree);
  for (Eigen::Index k = 0; k < degree; ++k) companion(0, k) = -p(first + 1 + k) / p(first);
  for (Eigen::Index k = 1; k < degree; ++k) companion(k, k - 1) = 1.0;
  Eigen::EigenSolver<Eigen::MatrixXd> eig(companion, false);
  return eig.eigenvalues();
}

/// Monic polynomial Π (1 − rₖ q⁻¹) with the given roots. Complex roots must come in conjugate
/// pairs for a real result (the imaginary rounding residue is dropped).
inline Eigen::VectorXd poly_from_roots(const Eigen::VectorXcd& r) {
  Eigen::VectorXcd c = Eigen::VectorXcd::Zero(r.size() + 1);
  c(0) = 1.0;
  for (Eigen::Index k = 0; k < r.size(); ++k)
    for (Eigen::Index j = k + 1; j >= 1; --j) c(j) -= r(k) * c(j - 1);
  return c.real();
}

/// Largest root magnitude of P (0 for a constant): < 1 means B/P is stable.
template <int = 0>
double spectral_radius(const Eigen::VectorXd& p) {
  const Eigen::VectorXcd r = roots(p);
  double m = 0.0;
  for (Eigen::Index k = 0; k < r.size(); ++k) m = std::max(m, std::abs(r(k)));
  return m;
}

/// True if every root of the monic polynomial lies strictly inside the circle |z| < `radius`.
template <int = 0>
bool is_stable_polynomial(const Eigen::VectorXd& p, double radius = 1.0) {
  return spectral_radius(p) < radius;
}

/// Monic polynomial with every root r outside the unit circle replaced by 1/r̄ (roots on or
/// inside the circle are kept). Used to restart an output-error search from a stable F.
template <int = 0>
Eigen::VectorXd reflect_unstable(const Eigen::VectorXd& p) {
  require(p.size() > 0 && p(0) != 0.0, "reflect_unstable: polynomial must have p0 != 0",
          at_parameter("p"));
  Eigen::VectorXcd r = roots(p);
  bool changed = false;
  for (Eigen::Index k = 0; k < r.size(); ++k) {
    if (std::abs(r(k)) > 1.0) {
      r(k) = 1.0 / std::conj(r(k));
      changed = true;
    }
  }
  if (!changed) return p / p(0);
  Eigen::VectorXd q = poly_from_roots(r);
  q.conservativeResize(p.size());  // same length as the input (trailing zeros = roots at 0)
  for (Eigen::Index k = r.size() + 1; k < p.size(); ++k) q(k) = 0.0;
  return q;
}

/// P evaluated at the complex point z: Σ pₖ z⁻ᵏ. With z = e^{iωTs} this is the frequency
/// response of the polynomial at ω rad/s.
inline std::complex<double> evaluate_polynomial(const Eigen::VectorXd& p, std::complex<double> z) {
  // Horner in w = z⁻¹, from the highest power down.
  const std::complex<double> w = 1.0 / z;
  std::complex<double> acc = 0.0;
  for (Eigen::Index k = p.size() - 1; k >= 0; --k) acc = acc * w + p(k);
  return acc;
}

/// Frequency response B(e^{iωTs}) / A(e^{iωTs}) at the angular frequencies `w` (rad/s).
inline Eigen::VectorXcd frequency_response(const Eigen::VectorXd& b, const Eigen::VectorXd& a,
                                           const Eigen::VectorXd& w, double ts) {
  Eigen::VectorXcd g(w.size());
  for (Eigen::Index k = 0; k < w.size(); ++k) {
    const std::complex<double> z = std::polar(1.0, w(k) * ts);
    g(k) = evaluate_polynomial(b, z) / evaluate_polynomial(a, z);
  }
  return g;
}

/// A number with `digits` significant digits, as the toolbox prints coefficients.
inline std::string format_number(double v, int digits = 4) { return detail::format_g(v, digits); }

/// The toolbox's ` (+/- s)` after an estimate; ` (not identifiable)` for s = +∞ (the data do
/// not determine the parameter); nothing for s = 0 (not estimated, e.g. a hand-made model).
inline std::string format_stddev(double s) {
  if (std::isinf(s) && s > 0) return " (not identifiable)";
  if (s > 0.0) return " (+/- " + format_number(s, 2) + ")";
  return "";
}

/// Human-readable polynomial, e.g. `1 - 1.523 q^-1 + 0.5891 q^-2` (zero terms skipped).
/// `stddev`, if given (same length), appends ` (+/- s)` after each coefficient, as the
/// toolbox's `present` does.
inline std::string format_polynomial(const Eigen::VectorXd& p, int digits = 4,
                                     const std::string& variable = "q",
                                     const Eigen::VectorXd* stddev = nullptr) {
  std::string s;
  for (Eigen::Index k = 0; k < p.size(); ++k) {
    if (p(k) == 0.0) continue;
    const double mag = std::abs(p(k));
    if (s.empty()) {
      if (p(k) < 0) s += "-";
    } else {
      s += p(k) < 0 ? " - " : " + ";
    }
    const bool unit = mag == 1.0 && k > 0 && stddev == nullptr;
    if (!unit) s += format_number(mag, digits);
    if (stddev != nullptr && k < stddev->size()) s += format_stddev((*stddev)(k));
    if (k > 0) {
      if (!unit) s += " ";
      s += variable + "^-" + std::to_string(k);
    }
  }
  return s.empty() ? std::string("0") : s;
}

/// Roots as text, conjugate pairs folded: `0.9 +/- 0.1i, 0.5`. Used by the models' describe().
inline std::string format_roots(const Eigen::VectorXcd& r, int digits = 4) {
  std::string s;
  std::vector<bool> used(static_cast<std::size_t>(r.size()), false);
  for (Eigen::Index k = 0; k < r.size(); ++k) {
    if (used[static_cast<std::size_t>(k)]) continue;
    used[static_cast<std::size_t>(k)] = true;
    if (!s.empty()) s += ", ";
    const double re = r(k).real(), im = r(k).imag();
    const double tol = 1e-12 * std::max(1.0, std::abs(r(k)));
    if (std::abs(im) <= tol) {
      s += format_number(re, digits);
      continue;
    }
    // Find the conjugate partner, if any, and print the pair once.
    for (Eigen::Index j = k + 1; j < r.size(); ++j) {
      if (!used[static_cast<std::size_t>(j)] && std::abs(r(j) - std::conj(r(k))) <= 1e-8 * std::max(1.0, std::abs(r(k)))) {
        used[static_cast<std::size_t>(j)] = true;
        break;
      }
    }
    s += format_number(re, digits) + " +/- " + format_number(std::abs(im), digits) + "i";
  }
  return s.empty() ? std::string("(none)") : s;
}

/// Largest degree whose roots a model's describe() lists. Roots are the eigenvalues of the
/// companion matrix, degree² doubles and O(degree³) time: describe() of an ARX model with the
/// valid order na = 54096 asked for 23 GB (found by the model-spec fuzzer). Past this degree
/// describe() gives the degree instead; poles() and zeros() still compute the roots if asked.
inline constexpr Eigen::Index max_described_root_degree = 500;

namespace detail {
/// Degree in z of P(q) as `roots` factors it (leading zero coefficients are delays).
inline Eigen::Index root_degree(const Eigen::VectorXd& p) {
  Eigen::Index first = 0;
  while (first < p.size() && p(first) == 0.0) ++first;
  return std::max<Eigen::Index>(p.size() - first - 1, 0);
}
/// What describe() prints instead of the roots of a polynomial of this degree.
inline std::string roots_not_described(Eigen::Index degree) {
  return "not listed (degree " + std::to_string(degree) + ", above " + std::to_string(max_described_root_degree) + ")";
}
}  // namespace detail

/// `format_roots(roots(p))` for a model's describe(), or a note with the degree past
/// `max_described_root_degree`.
template <int = 0>
std::string describe_roots(const Eigen::VectorXd& p, int digits = 4) {
  const Eigen::Index degree = detail::root_degree(p);
  return degree > max_described_root_degree ? detail::roots_not_described(degree) : format_roots(roots(p), digits);
}

/// A rational transfer operator G(q) = B(q)/A(q) with sample time `ts` (one input-output pair).
struct TransferFunction {
  Eigen::VectorXd numerator;    ///< B(q) coefficients, ascending powers of q^-1
  Eigen::VectorXd denominator;  ///< A(q) coefficients, monic (a0 = 1)
  double ts = 1.0;              ///< sample time (s)

  /// G(e^{iωTs}) at the angular frequencies `w` (rad/s).
  [[nodiscard]] Eigen::VectorXcd frequency_response(const Eigen::VectorXd& w) const {
    return nlid::frequency_response(numerator, denominator, w, ts);
  }
  /// Poles: roots of the denominator.
  template <int = 0>
  [[nodiscard]] Eigen::VectorXcd poles() const { return roots(denominator); }
  /// Zeros: roots of the numerator (leading zeros are delays and give no root).
  template <int = 0>
  [[nodiscard]] Eigen::VectorXcd zeros() const { return roots(numerator); }
  /// "B(q)/A(q)" as text.
  [[nodiscard]] std::string str(int digits = 4) const {
    return "(" + format_polynomial(numerator, digits) + ") / (" +
           format_polynomial(denominator, digits) + ")";
  }
};

}  // namespace nlid
