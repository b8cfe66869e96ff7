#pragma once
/// @file
/// Initial-state estimation for any `ModelStructure`: with θ fixed, choose the free entries z of
/// x0 = base + Σ zᵢ e_{free(i)} to minimise Σ_t (y(t) − ŷ_s(t; θ, x0))² (Ljung 1999, sec. 13.4,
/// "initial conditions" estimated along with, or after, θ). Solved by Levenberg–Marquardt with
/// the Jacobian ∂ŷ_s/∂x0 from forward AD through the simulation.

#include <cmath>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/estimation/autodiff.hpp"
#include "nlid/estimation/levenberg_marquardt.hpp"
#include "nlid/models/detail/model_common.hpp"

namespace nlid::detail {

/// Residuals ŷ_s(t; θ, x0(z)) − y(t) as a function of the free initial-state entries z.
template <class M>
class InitialStateResiduals {
 public:
  /// Number of free entries: known at run time only.
  static constexpr int num_params = Dynamic;

  /// Views `model`, `u`, `y` and `theta` (they must outlive the functor).
  InitialStateResiduals(const M& model, const Eigen::MatrixXd& u, const Eigen::VectorXd& y,
                        std::span<const double> theta, Eigen::VectorXd base, std::vector<int> free,
                        double limit)
      : model_(model), u_(u), y_(y), theta_(theta), base_(std::move(base)), free_(std::move(free)),
        limit_(limit) {}

  /// Number of free initial-state entries.
  [[nodiscard]] int num_parameters() const { return static_cast<int>(free_.size()); }
  /// One residual per sample.
  [[nodiscard]] Eigen::Index num_residuals() const { return y_.size(); }

  /// r(t) = ŷ_s(t) − y(t); false if the simulation diverges.
  template <class T>
  bool residuals(std::span<const T> z, std::span<T> r) const {
    const std::vector<T> th = cast_parameters<T>(theta_);
    std::vector<T> x0 = cast_parameters<T>(std::span<const double>(base_.data(), static_cast<std::size_t>(base_.size())));
    for (std::size_t i = 0; i < free_.size(); ++i) x0[static_cast<std::size_t>(free_[i])] = z[i];
    if (!model_.simulate(u_, std::span<const T>(th), std::span<const T>(x0), r, limit_)) return false;
    for (std::size_t t = 0; t < r.size(); ++t) r[t] -= y_(static_cast<Eigen::Index>(t));
    return true;
  }

 private:
  const M& model_;
  const Eigen::MatrixXd& u_;
  const Eigen::VectorXd& y_;
  std::span<const double> theta_;
  Eigen::VectorXd base_;
  std::vector<int> free_;
  double limit_;
};

/// Magnitude beyond which a simulation of data `y` counts as diverged: far outside anything
/// the data could explain, yet finite so that the solver can reject the step.
inline double divergence_limit(const Eigen::VectorXd& y) {
  const double scale = y.size() > 0 ? y.cwiseAbs().maxCoeff() : 1.0;
  return 1e3 * (1.0 + scale);
}

/// Most initial-state entries `estimate_initial_state` fits. Its Levenberg–Marquardt solve holds
/// half a dozen p × p matrices and an N × p Jacobian: at p = 1000 that is 50 MB and a second per
/// iteration; the 10⁵ states of a Hammerstein–Wiener block with a delay of 10⁵ samples asked for
/// 500 GB and ended in std::bad_alloc.
inline constexpr std::size_t max_estimated_initial_states = 1000;

/// x0 with its `free` entries estimated (the others stay as in `base`). Throws
/// `nlid::DivergenceError` (naming the first sample beyond the limit) if the simulation diverges
/// from `base`, so that `compare` scores that record as diverged, as it does a zero start, and
/// `nlid::Error` naming "initial" for more than `max_estimated_initial_states` free entries.
template <class M>
Eigen::VectorXd estimate_initial_state(const M& model, const Eigen::MatrixXd& u, const Eigen::VectorXd& y,
                                       std::span<const double> theta, Eigen::VectorXd base,
                                       std::vector<int> free, int max_iterations = 50) {
  if (free.empty()) return base;
  if (free.size() > max_estimated_initial_states) {
    throw Error("cannot estimate an initial state of " + std::to_string(free.size()) + " values (at most " +
                    std::to_string(max_estimated_initial_states) +
                    " are fitted: the model's delays and orders make its state that long); use "
                    "InitialCondition::zero or equilibrium",
                at_parameter("initial"));
  }
  Eigen::VectorXd z(static_cast<Eigen::Index>(free.size()));
  for (std::size_t i = 0; i < free.size(); ++i) z(static_cast<Eigen::Index>(i)) = base(free[i]);
  const std::vector<int> free_copy = free;
  InitialStateResiduals<M> f(model, u, y, theta, base, std::move(free), divergence_limit(y));
  {
    Eigen::VectorXd r = Eigen::VectorXd::Constant(y.size(), std::numeric_limits<double>::quiet_NaN());
    if (!f.template residuals<double>(as_const_span(z), as_span(r))) {
      const double limit = divergence_limit(y);
      Eigen::Index k = 0;  // the first sample not written or beyond the limit
      while (k < r.size() && std::isfinite(r(k)) && std::abs(r(k) + y(k)) <= limit) ++k;
      throw DivergenceError("cannot estimate the initial state: the simulation from the starting guess diverges "
                            "(beyond " + format_g(limit) + " at sample " + std::to_string(k) + ")",
                            static_cast<long>(k), at_parameter("initial"));
    }
  }
  AutoDiffProblem<InitialStateResiduals<M>> problem(f);
  LmOptions options;
  options.max_iterations = max_iterations;
  solve_least_squares(problem, z, options);
  for (std::size_t i = 0; i < free_copy.size(); ++i) base(free_copy[i]) = z(static_cast<Eigen::Index>(i));
  return base;
}

}  // namespace nlid::detail
