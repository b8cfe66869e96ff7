#pragma once
/// @file
/// `SimulationResiduals<M, P>`: the free-run errors ŷ_s − y of any `ModelStructure` over several
/// experiments — the residual functor of simulation-focus estimation (models/estimate.hpp), and
/// the residuals and initial states the structured Nlarx Jacobian builds on
/// (models/detail/nlarx_sensitivity.hpp).

#include <span>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/initial_condition.hpp"
#include "nlid/models/detail/estimation_segment.hpp"

namespace nlid::detail {

/// Free-run residuals of any `ModelStructure` over several experiments; `P` = the solver's
/// static parameter count (the model's, or Dynamic when initial states are estimated).
template <class M, int P>
class SimulationResiduals {
 public:
  /// Static parameter count.
  static constexpr int num_params = P;

  /// `free` lists the x0 entries estimated per experiment (empty unless ic == estimate).
  SimulationResiduals(const M& model, std::vector<EstimationSegment> segments, std::vector<int> free,
                      InitialCondition ic, double limit)
      : model_(&model), segs_(std::move(segments)), free_(std::move(free)), ic_(ic), limit_(limit) {
    for (const auto& s : segs_) m_ += s.y.size() - s.start;
  }

  /// Model parameters plus estimated initial states.
  [[nodiscard]] int num_parameters() const {
    return model_->num_parameters() + static_cast<int>(free_.size() * (ic_ == InitialCondition::estimate ? segs_.size() : 0));
  }
  /// Σ over experiments of the simulated samples.
  [[nodiscard]] Eigen::Index num_residuals() const { return m_; }

  /// The model simulated.
  [[nodiscard]] const M& model() const { return *model_; }
  /// The experiments.
  [[nodiscard]] const std::vector<EstimationSegment>& segments() const { return segs_; }
  /// The estimated x0 entries of each experiment.
  [[nodiscard]] const std::vector<int>& free_states() const { return free_; }
  /// Divergence limit of the simulations.
  [[nodiscard]] double limit() const { return limit_; }

  /// x0 of experiment `s` under the full θ (model parameters, then estimated states): its
  /// equilibrium, its stored x0 with the estimated entries taken from θ, or empty (zero), in
  /// `x0`'s storage.
  template <class T>
  std::span<const T> initial_state(const EstimationSegment& s, std::span<const T> theta, std::vector<T>& x0) const {
    const auto np = static_cast<std::size_t>(model_->num_parameters());
    if (ic_ == InitialCondition::equilibrium) {
      if constexpr (requires { model_->template equilibrium_state<T>(0.0, theta.first(np)); }) {
        const auto xe = model_->template equilibrium_state<T>((*s.u)(0, 0), theta.first(np));
        x0.assign(xe.data(), xe.data() + xe.size());
        return std::span<const T>(x0);
      }
      return {};
    }
    if (s.x0.size() == 0) return {};
    x0.resize(static_cast<std::size_t>(s.x0.size()));
    for (Eigen::Index k = 0; k < s.x0.size(); ++k) x0[static_cast<std::size_t>(k)] = T(s.x0(k));
    if (s.free_offset >= 0) {
      for (std::size_t k = 0; k < free_.size(); ++k)
        x0[static_cast<std::size_t>(free_[k])] = theta[np + static_cast<std::size_t>(s.free_offset) + k];
    }
    return std::span<const T>(x0);
  }

  /// The outer loop of a structured Jacobian (nlarx_sensitivity.hpp, hw_sensitivity.hpp): for
  /// each experiment `simulate(s, x0, off)` writes ŷ_s into r[off …] and its Jacobian rows (false:
  /// diverged); the measured y is then subtracted. Returns false at the first divergence.
  template <class Simulate>
  bool stacked_with_sensitivity(std::span<const double> theta, Eigen::VectorXd& r, Simulate&& simulate) const {
    std::vector<double>& x0 = initial_state_scratch<double>();
    Eigen::Index off = 0;
    for (const auto& s : segs_) {
      if (!simulate(s, initial_state(s, theta, x0), off)) return false;
      const Eigen::Index len = s.y.size() - s.start;
      for (Eigen::Index t = 0; t < len; ++t) r(off + t) -= s.y(s.start + t);
      off += len;
    }
    return true;
  }

  /// r = ŷ_s − y, stacked; false if a simulation diverges.
  template <class T>
  bool residuals(std::span<const T> theta, std::span<T> r) const {
    const std::span<const T> th = theta.first(static_cast<std::size_t>(model_->num_parameters()));
    std::size_t off = 0;
    // Per-thread scratch for x0: grown on the first call, reused afterwards, so a fixed-size
    // estimation allocates nothing per iteration (tests/nomalloc) and threads do not share it.
    std::vector<T>& x0 = initial_state_scratch<T>();
    for (const auto& s : segs_) {
      const Eigen::Index len = s.y.size() - s.start;
      const std::span<T> ri = r.subspan(off, static_cast<std::size_t>(len));
      if (!model_->simulate(s.u->bottomRows(len), th, initial_state(s, theta, x0), ri, limit_)) return false;
      for (Eigen::Index t = 0; t < len; ++t) ri[static_cast<std::size_t>(t)] -= s.y(s.start + t);
      off += static_cast<std::size_t>(len);
    }
    return true;
  }

 private:
  const M* model_;
  std::vector<EstimationSegment> segs_;
  std::vector<int> free_;
  InitialCondition ic_;
  double limit_;
  Eigen::Index m_ = 0;
};

}  // namespace nlid::detail
