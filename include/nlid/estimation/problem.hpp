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
/// order the parts were given. Each part evaluates into a per-thread buffer that is then copied
/// into its rows (the contract hands a part a whole `VectorXd`, not a segment). The buffers are
/// sized in the constructor for the constructing thread and re-sized only when a different
/// stack is evaluated on the same thread, so `evaluate` allocates nothing in steady state; it is
/// const and thread-safe if the parts' `evaluate` is.
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
      sizes_.push_back(mk);
      m_ += mk;
    }
    scratch();
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
    for (std::size_t j = 0; j < k && j < parts_.size(); ++j) o += sizes_[j];
    return o;
  }

  /// Evaluates every part; false as soon as one part is not evaluable. Throws `nlid::Error` if
  /// `theta`, `r` or `*J` has the wrong size (the rows are copied into segments of them).
  bool evaluate(const ParameterVector<num_params>& theta, Eigen::VectorXd& r,
                JacobianMatrix<num_params>* J) const {
    if (theta.size() != n_ || r.size() != m_ || (J && (J->rows() != m_ || J->cols() != n_))) {
      throw Error("StackedProblem::evaluate: argument sizes do not match the problem (" + std::to_string(n_) +
                      " parameters, " + std::to_string(m_) + " residuals)",
                  at_parameter(theta.size() != n_ ? "theta" : r.size() != m_ ? "r" : "J"));
    }
    Scratch& s = scratch();
    Eigen::Index row = 0;
    for (std::size_t k = 0; k < parts_.size(); ++k) {
      const Eigen::Index mk = sizes_[k];
      if (!parts_[k].evaluate(theta, s.r[k], J ? &s.J[k] : nullptr)) return false;
      r.segment(row, mk) = s.r[k];
      if (J) J->middleRows(row, mk) = s.J[k];
      row += mk;
    }
    return true;
  }

 private:
  struct Scratch {
    std::vector<Eigen::VectorXd> r;
    std::vector<JacobianMatrix<num_params>> J;
  };
  // This thread's buffers, shaped for this stack (re-shaped only if another stack of the same
  // type was evaluated on this thread in between).
  Scratch& scratch() const {
    thread_local Scratch s;
    if (s.r.size() != sizes_.size()) {
      s.r.resize(sizes_.size());
      s.J.resize(sizes_.size());
    }
    for (std::size_t k = 0; k < sizes_.size(); ++k) {
      if (s.r[k].size() != sizes_[k]) s.r[k].resize(sizes_[k]);
      if (s.J[k].rows() != sizes_[k] || s.J[k].cols() != n_) s.J[k].resize(sizes_[k], n_);
    }
    return s;
  }

  std::vector<Pb> parts_;
  std::vector<Eigen::Index> sizes_;
  int n_ = 0;
  Eigen::Index m_ = 0;
};

}  // namespace nlid
