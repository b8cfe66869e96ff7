#pragma once
/// @file
/// Robust losses: how much a residual of a given size costs.
///
/// The solver minimises F(θ) = ½ Σᵢ ρ(sᵢ), sᵢ = rᵢ(θ)². Two losses are provided:
///
///     squared:  ρ(s) = s                                  (ordinary least squares)
///     huber:    ρ(s) = s              for s ≤ δ²          (quadratic inside δ)
///               ρ(s) = 2δ√s − δ²      for s > δ²          (linear in |r| outside δ)
///
/// Huber's loss (Huber 1964; Huber & Ronchetti, "Robust Statistics", 2nd ed., 2009, sec. 4.5)
/// is what the System Identification Toolbox calls `LimitError` (Ljung 1999, sec. 15.2,
/// eq. 15.9): residuals larger than the limit are penalised linearly, so a few gross outliers
/// (sensor glitches, dropped samples) cannot dominate the fit. The toolbox expresses the limit
/// in units of the residual standard deviation; with nlid set `delta = c · robust_scale(r)`,
/// e.g. c = 1.345 for 95 % efficiency under Gaussian noise, where `robust_scale` is the
/// median absolute deviation scaled to σ.
///
/// How the solver uses ρ (row reweighting, Triggs et al., "Bundle Adjustment — A Modern
/// Synthesis", 2000, sec. 4.3; Holland & Welsch 1977 for IRLS). With ρ' = dρ/ds, the gradient
/// of F is ∇F = Σ ρ'(sᵢ) rᵢ ∇rᵢ. Scaling row i of r and J by wᵢ = √ρ'(sᵢ) gives r̃ = w∘r,
/// J̃ = diag(w) J and J̃ᵀr̃ = ∇F exactly, so the Gauss–Newton normal equations J̃ᵀJ̃ δ = −J̃ᵀr̃
/// have the true gradient on the right-hand side. Triggs' second-order correction adds a rank-
/// one term when ρ'' > 0; for Huber ρ'' ≤ 0 everywhere, where the correction would make the
/// model Hessian indefinite, so (like Ceres' `Corrector`) the plain weights are used — the
/// usual iteratively-reweighted least squares. Stationary points are exactly those of F.

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"

namespace nlid {

/// Loss applied to each squared residual. Aggregate: `RobustLoss{RobustLoss::Kind::huber, 0.5}`,
/// or the named constructors `RobustLoss::squared()` / `RobustLoss::huber(0.5)`.
/// Invariant checked by `validate`: `delta` finite and > 0 when `kind == huber`.
struct RobustLoss {
  /// Which ρ to use.
  enum class Kind {
    squared,  ///< ρ(s) = s: least squares (Gaussian noise, maximum likelihood)
    huber,    ///< quadratic for |r| ≤ delta, linear beyond ("LimitError")
  };
  Kind kind = Kind::squared;  ///< loss shape
  double delta = 1.0;         ///< Huber threshold δ, in residual units (ignored for squared)

  /// Ordinary least squares.
  static RobustLoss squared() { return {}; }
  /// Huber loss with threshold `delta` (residual units).
  static RobustLoss huber(double delta) { return {Kind::huber, delta}; }
};

/// ρ(s) and its first two derivatives with respect to s = r².
struct LossValue {
  double rho;   ///< ρ(s)
  double rho1;  ///< ρ'(s)  (the IRLS weight wᵢ² )
  double rho2;  ///< ρ''(s)
};

/// Throws `nlid::Error` naming `loss.delta` if the loss is not usable.
inline void validate(const RobustLoss& loss) {
  if (loss.kind == RobustLoss::Kind::huber && !(std::isfinite(loss.delta) && loss.delta > 0)) {
    throw Error("Huber loss threshold delta must be finite and > 0, got " + detail::format_g(loss.delta),
                at_parameter("loss.delta"));
  }
}

/// ρ, ρ', ρ'' at s = r² ≥ 0.
inline LossValue evaluate_loss(const RobustLoss& loss, double s) {
  if (loss.kind == RobustLoss::Kind::squared) return {s, 1.0, 0.0};
  const double d2 = loss.delta * loss.delta;
  if (s <= d2) return {s, 1.0, 0.0};
  const double root = std::sqrt(s);
  // ρ = 2δ√s − δ², ρ' = δ/√s, ρ'' = −δ/(2 s^{3/2})
  return {2.0 * loss.delta * root - d2, loss.delta / root, -0.5 * loss.delta / (s * root)};
}

/// Cost ½ Σ ρ(rᵢ²) of a residual vector.
template <class Derived>
double robust_cost(const RobustLoss& loss, const Eigen::MatrixBase<Derived>& r) {
  if (loss.kind == RobustLoss::Kind::squared) return 0.5 * r.squaredNorm();
  double c = 0;
  for (Eigen::Index i = 0; i < r.size(); ++i) c += evaluate_loss(loss, r[i] * r[i]).rho;
  return 0.5 * c;
}

/// Row weights wᵢ = √ρ'(rᵢ²) of the IRLS reweighting (all 1 for squared loss).
template <class Derived, class WDerived>
void robust_weights(const RobustLoss& loss, const Eigen::MatrixBase<Derived>& r,
                    Eigen::MatrixBase<WDerived>& w) {
  for (Eigen::Index i = 0; i < r.size(); ++i) {
    w[i] = std::sqrt(evaluate_loss(loss, r[i] * r[i]).rho1);
  }
}

/// Robust estimate of the residual standard deviation: 1.4826 · median(|rᵢ − median(r)|)
/// (the normalised median absolute deviation, consistent with σ for Gaussian noise and
/// unaffected by up to half the samples being outliers). Use it to set the Huber threshold the
/// way the toolbox's LimitError does: `RobustLoss::huber(1.345 * robust_scale(r))`.
/// Throws `nlid::Error` if `r` is empty or contains a non-finite value.
inline double robust_scale(const Eigen::VectorXd& r) {
  if (r.size() == 0) throw Error("robust_scale: residual vector is empty", at_parameter("r"));
  if (!r.allFinite()) {
    for (Eigen::Index i = 0; i < r.size(); ++i) {
      if (!std::isfinite(r[i])) {
        throw Error("robust_scale: residual " + std::to_string(i) + " is not finite",
                    at_parameter("r"));
      }
    }
  }
  std::vector<double> v(r.data(), r.data() + r.size());
  auto median = [](std::vector<double>& x) {
    const std::size_t mid = x.size() / 2;
    std::nth_element(x.begin(), x.begin() + static_cast<std::ptrdiff_t>(mid), x.end());
    double m = x[mid];
    if (x.size() % 2 == 0) {
      m = 0.5 * (m + *std::max_element(x.begin(), x.begin() + static_cast<std::ptrdiff_t>(mid)));
    }
    return m;
  };
  const double med = median(v);
  for (double& x : v) x = std::abs(x - med);
  return 1.482602218505602 * median(v);
}

}  // namespace nlid
