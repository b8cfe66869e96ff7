#pragma once
/// @file
/// Ready-made least-squares problems: a problem from a callable, and a stack of problems that
/// share one parameter vector (multi-experiment estimation).
///
/// The `LeastSquaresProblem` contract (see `concepts.hpp`) is what the Levenberg–Marquardt
/// solver consumes. Most users obtain one from `AutoDiffProblem` (residual functor + exact
/// Jacobian by forward AD). This header adds two adapters:
///
/// - `FunctionProblem<P, Fn>` / `make_problem<P>(n, m, fn)`: a callable with the signature of
///   `evaluate` becomes a problem. Use it for analytic Jacobians or quick experiments.
/// - `StackedProblem<Pb>`: K problems with the same parameters (e.g. the same model on data1 and
///   data2 of the throttle study) become one, with stacked residuals
///
///       r(θ) = [r⁽¹⁾(θ); …; r⁽ᴷ⁾(θ)],   J(θ) = [J⁽¹⁾(θ); …; J⁽ᴷ⁾(θ)],
///
///   so F(θ) = Σₖ F⁽ᵏ⁾(θ): the multi-experiment prediction-error criterion (Ljung 1999,
///   sec. 14.3, "merging experiments"). Each part keeps its own initial conditions; only θ is
///   shared.

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/estimation/concepts.hpp"

namespace nlid {

/// A least-squares problem defined by a callable
/// `bool fn(const ParameterVector<P>& theta, Eigen::VectorXd& r, JacobianMatrix<P>* J)`
/// that follows the `evaluate` contract (r pre-sized; J null or pre-sized).
template <int P, class Fn>
  requires(P == Dynamic || P >= 1)
class FunctionProblem {
 public:
  static constexpr int num_params = P;  ///< static parameter count (or Dynamic)

  /// `n` parameters (must equal P when P is static), `m` residuals, evaluated by `fn`.
  /// Throws `nlid::Error` if the sizes are inconsistent.
  FunctionProblem(int n, Eigen::Index m, Fn fn) : n_(n), m_(m), fn_(std::move(fn)) {
    if (n < 1 || (P != Dynamic && n != P)) {
      throw Error("FunctionProblem: parameter count " + std::to_string(n) +
                      (P != Dynamic ? " differs from the static count " + std::to_string(P)
                                    : std::string(" must be >= 1")),
                  at_parameter("num_parameters"));
    }
    if (m < 1) {
      throw Error("FunctionProblem: residual count must be >= 1, got " + std::to_string(m),
                  at_parameter("num_residuals"));
    }
  }
  /// n.
  int num_parameters() const { return n_; }
  /// m.
  Eigen::Index num_residuals() const { return m_; }
  /// Calls the function.
  bool evaluate(const ParameterVector<P>& theta, Eigen::VectorXd& r, JacobianMatrix<P>* J) const {
    return static_cast<bool>(fn_(theta, r, J));
  }

 private:
  int n_;
  Eigen::Index m_;
  Fn fn_;
};

/// Builds a `FunctionProblem<P, Fn>`; `P` is given, `Fn` deduced:
/// `auto pb = make_problem<2>(2, m, [&](const auto& th, auto& r, auto* J) { ... });`
template <int P, class Fn>
FunctionProblem<P, Fn> make_problem(int n, Eigen::Index m, Fn fn) {
  return FunctionProblem<P, Fn>(n, m, std::move(fn));
}

/// Several problems of the same type sharing one parameter vector; residuals are stacked in the
/// order the parts were given. Buffers for each part's residuals and Jacobian are allocated in
/// the constructor, so `evaluate` allocates nothing (if the parts allocate nothing).
/// Not thread-safe: `evaluate` writes those buffers.
template <LeastSquaresProblem Pb>
class StackedProblem {
 public:
  static constexpr int num_params = Pb::num_params;  ///< that of the parts

  /// Takes the parts. Throws `nlid::Error` if there are none or their parameter counts differ
  /// (the location names the offending part as an experiment index).
  explicit StackedProblem(std::vector<Pb> parts) : parts_(std::move(parts)) {
    if (parts_.empty()) throw Error("StackedProblem: no parts given", at_parameter("parts"));
    n_ = parts_.front().num_parameters();
    m_ = 0;
    for (std::size_t k = 0; k < parts_.size(); ++k) {
      if (parts_[k].num_parameters() != n_) {
        throw Error("StackedProblem: part " + std::to_string(k) + " has " +
                        std::to_string(parts_[k].num_parameters()) + " parameters, part 0 has " +
                        std::to_string(n_),
                    at_experiment(static_cast<long>(k)));
      }
      const Eigen::Index mk = parts_[k].num_residuals();
      if (mk < 1) {
        throw Error("StackedProblem: part " + std::to_string(k) + " has no residuals",
                    at_experiment(static_cast<long>(k)));
      }
      r_.emplace_back(mk);
      J_.emplace_back(mk, n_);
      m_ += mk;
    }
  }
  /// Shared parameter count.
  int num_parameters() const { return n_; }
  /// Sum of the parts' residual counts.
  Eigen::Index num_residuals() const { return m_; }
  /// Number of parts.
  std::size_t size() const { return parts_.size(); }
  /// Part k.
  const Pb& part(std::size_t k) const { return parts_.at(k); }
  /// Offset of part k's residuals in the stacked vector.
  Eigen::Index offset(std::size_t k) const {
    Eigen::Index o = 0;
    for (std::size_t j = 0; j < k && j < parts_.size(); ++j) o += r_[j].size();
    return o;
  }

  /// Evaluates every part; false as soon as one part is not evaluable.
  bool evaluate(const ParameterVector<num_params>& theta, Eigen::VectorXd& r,
                JacobianMatrix<num_params>* J) const {
    Eigen::Index row = 0;
    for (std::size_t k = 0; k < parts_.size(); ++k) {
      const Eigen::Index mk = r_[k].size();
      if (!parts_[k].evaluate(theta, r_[k], J ? &J_[k] : nullptr)) return false;
      r.segment(row, mk) = r_[k];
      if (J) J->middleRows(row, mk) = J_[k];
      row += mk;
    }
    return true;
  }

 private:
  std::vector<Pb> parts_;
  int n_ = 0;
  Eigen::Index m_ = 0;
  mutable std::vector<Eigen::VectorXd> r_;
  mutable std::vector<JacobianMatrix<num_params>> J_;
};

}  // namespace nlid
