#pragma once
/// @file
/// `AutoDiffProblem<F>`: residuals written once, exact Jacobian by forward-mode AD.
///
/// Given a `ResidualFunctor` F (residuals templated on the scalar), the Jacobian
/// J = ∂r/∂θ ∈ R^{m×n} is obtained by evaluating F on dual numbers
/// (Griewank & Walther 2008, sec. 3.1): with θ_k seeded as θ_k + e_k ε, each residual comes out
/// as rᵢ + (∇rᵢ)ᵀ ε, i.e. row i of J. How the n seeds are laid out is the whole design:
///
/// - J not requested → F runs on `double`: no derivative cost at all (the solver's trial steps).
/// - n static (`F::num_params = n`) → one pass on `Dual<double, n>`: all n derivatives at once,
///   derivative vectors on the stack, no heap (Ceres' `AutoDiffCostFunction`).
/// - n dynamic → ⌈n/C⌉ passes on the fixed-size `Dual<double, C>` (C = `ChunkSize`, default 8),
///   each seeding C parameters and leaving the rest constant. A `DynamicDual` would instead heap-
///   allocate on every arithmetic operation; chunking keeps the inner loop allocation-free at the
///   price of re-evaluating the value part ⌈n/C⌉ times (see docs/performance.md for the
///   measured trade-off).
///
/// Memory and threads: the dual images of θ and r live in per-thread scratch buffers (one per
/// dual type), sized in the constructor for the constructing thread and grown only when a longer
/// residual vector is met, so `evaluate` allocates nothing in steady state. `evaluate` is const
/// and thread-safe if the functor's `residuals` is: several threads (e.g. parallel multi-start
/// solves) may share one problem object. A thread keeps its scratch until it exits.

#include <algorithm>
#include <span>
#include <string>
#include <utility>

#include <Eigen/Core>

#include "nlid/ad/dual.hpp"
#include "nlid/core/error.hpp"
#include "nlid/estimation/concepts.hpp"

namespace nlid {

namespace detail {
// Per-thread scratch of at least `size` duals of type D. Grows, never shrinks; the Eigen
// container makes any growth visible to EIGEN_RUNTIME_NO_MALLOC tests.
template <class D>
Eigen::Matrix<D, Eigen::Dynamic, 1>& ad_scratch(Eigen::Index size) {
  thread_local Eigen::Matrix<D, Eigen::Dynamic, 1> buffer;
  if (buffer.size() < size) buffer.resize(size);
  return buffer;
}
}  // namespace detail

/// Adapts a residual functor into a `LeastSquaresProblem` with an exact (AD) Jacobian.
/// `ChunkSize` is the number of derivatives per pass when `F::num_params` is `Dynamic`.
template <ResidualFunctor F, int ChunkSize = default_ad_chunk_size>
  requires(ChunkSize >= 1)
class AutoDiffProblem {
 public:
  static constexpr int num_params = F::num_params;  ///< static parameter count (or Dynamic)
  /// Derivatives carried per pass: n itself if static, else `ChunkSize`.
  static constexpr int chunk_size = num_params == Dynamic ? ChunkSize : num_params;
  using Functor = F;                                   ///< the wrapped functor type
  using DualScalar = Dual<double, chunk_size>;         ///< scalar of the derivative passes
  using Parameters = ParameterVector<num_params>;      ///< θ
  using Jacobian = JacobianMatrix<num_params>;         ///< J

  /// Wraps (and owns) the functor; allocates the dual buffers.
  /// Throws `nlid::Error` if the functor reports inconsistent sizes.
  explicit AutoDiffProblem(F functor) : f_(std::move(functor)) {
    const int n = f_.num_parameters();
    // n = 0 is a model with nothing to estimate (a unit-gain map on one regressor): its
    // residuals still make the estimation report, and the solver stops at once.
    if (n < 0 || (num_params != Dynamic && n != num_params)) {
      throw Error("AutoDiffProblem: functor reports " + std::to_string(n) +
                      " parameters but its static num_params is " + std::to_string(num_params),
                  at_parameter("num_parameters"));
    }
    if (f_.num_residuals() < 1) {
      throw Error("AutoDiffProblem: functor reports no residuals", at_parameter("num_residuals"));
    }
    detail::ad_scratch<DualScalar>(static_cast<Eigen::Index>(n) + f_.num_residuals());
  }

  /// n.
  int num_parameters() const { return f_.num_parameters(); }
  /// m.
  Eigen::Index num_residuals() const { return f_.num_residuals(); }
  /// The wrapped functor.
  const F& functor() const { return f_; }

  /// r(θ) and, if `J` is not null, J(θ). Returns what the functor returns (false: not evaluable).
  /// Throws `nlid::Error` if `theta`, `r` or `*J` has the wrong size.
  bool evaluate(const Parameters& theta, Eigen::VectorXd& r, Jacobian* J) const {
    const int n = num_parameters();
    const Eigen::Index m = num_residuals();
    check_sizes(theta, r, J, n, m);
    if (J == nullptr || n == 0) {  // no derivative pass would compute r when n = 0
      return f_.residuals(std::span<const double>(theta.data(), static_cast<std::size_t>(n)),
                          std::span<double>(r.data(), static_cast<std::size_t>(m)));
    }
    // One scratch block per thread: θ's dual image first, then r's.
    auto& scratch = detail::ad_scratch<DualScalar>(static_cast<Eigen::Index>(n) + m);
    DualScalar* theta_d = scratch.data();
    DualScalar* r_d = scratch.data() + n;
    const std::span<const DualScalar> th(theta_d, static_cast<std::size_t>(n));
    const std::span<DualScalar> rd(r_d, static_cast<std::size_t>(m));

    for (int k = 0; k < n; ++k) {
      theta_d[k].a = theta[k];
      theta_d[k].v.setZero();
    }
    // Pass c seeds parameters [c·C, c·C + w) as derivative directions 0..w−1.
    for (int first = 0; first < n; first += chunk_size) {
      const int w = std::min(chunk_size, n - first);
      for (int j = 0; j < w; ++j) theta_d[first + j].v[j] = 1.0;
      if (!f_.residuals(th, rd)) return false;
      for (int j = 0; j < w; ++j) theta_d[first + j].v[j] = 0.0;
      if (first == 0) {
        for (Eigen::Index i = 0; i < m; ++i) r[i] = r_d[i].a;
      }
      for (Eigen::Index i = 0; i < m; ++i) {
        for (int j = 0; j < w; ++j) (*J)(i, first + j) = r_d[i].v[j];
      }
    }
    return true;
  }

 private:
  static void check_sizes(const Parameters& theta, const Eigen::VectorXd& r, const Jacobian* J,
                          int n, Eigen::Index m) {
    if (theta.size() != n) {
      throw Error("AutoDiffProblem::evaluate: theta has " + std::to_string(theta.size()) +
                      " entries, expected " + std::to_string(n),
                  at_parameter("theta"));
    }
    if (r.size() != m) {
      throw Error("AutoDiffProblem::evaluate: r has " + std::to_string(r.size()) +
                      " entries, expected " + std::to_string(m) + " (num_residuals)",
                  at_parameter("r"));
    }
    if (J != nullptr && (J->rows() != m || J->cols() != n)) {
      throw Error("AutoDiffProblem::evaluate: J is " + std::to_string(J->rows()) + " x " +
                      std::to_string(J->cols()) + ", expected " + std::to_string(m) + " x " +
                      std::to_string(n),
                  at_parameter("J"));
    }
  }

  F f_;
};

}  // namespace nlid
