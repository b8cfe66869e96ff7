#pragma once
/// @file
/// The two lag windows: measured data (one-step prediction) and a simulation's own past.
///
/// Both satisfy `LagWindow`: at the current time t, `y(k)` = y(t−k) (k ≥ 1) and
/// `u(c, k)` = u_c(t−k) (k ≥ 0). They differ only in where y comes from:
///
/// - `MeasuredWindow<T>` reads y from the recorded output: the one-step-ahead predictor
///   ŷ(t|t−1) = F(φ(t)) of Ljung (1999) eq. 5.46 with φ built from measurements;
/// - `SimulationWindow<T, L>` reads y from a `History` ring buffer holding the model's own past
///   outputs: the simulation ŷ_s(t) = F(φ_s(t)) (Ljung 1999 eq. 5.48 applied to a nonlinear
///   predictor), whose error is what simulation-focus estimation minimises.
///
/// Samples before t = 0 come from an *initial window* (the model's initial state): for outputs
/// the history's initial contents, for inputs an optional table `u_past` laid out per channel
/// as [u_c(−1), u_c(−2), …, u_c(−Lu)] (channel-major), or zero when that table is empty.
/// Measured data are double; the window converts to the scalar T on access.

#include <span>

#include <Eigen/Core>

#include "nlid/regressors/concepts.hpp"
#include "nlid/regressors/history.hpp"

namespace nlid {

/// Window over recorded data. Valid for t ≥ the regressors' history (no access before t = 0).
template <class T>
class MeasuredWindow {
 public:
  /// Scalar the regressors are evaluated on.
  using Scalar = T;

  /// `u`: N×nu inputs; `y`: N outputs. Both are viewed, not copied; they must outlive the window.
  MeasuredWindow(const Eigen::Ref<const Eigen::MatrixXd>& u,
                 const Eigen::Ref<const Eigen::VectorXd>& y)
      : u_(u), y_(y) {}

  /// Moves the window to time t.
  void set_time(Eigen::Index t) { t_ = t; }
  /// The current time.
  [[nodiscard]] Eigen::Index time() const { return t_; }

  /// y(t−lag), lag ≥ 1.
  [[nodiscard]] T y(int lag) const { return T(y_(t_ - lag)); }
  /// u_channel(t−lag), lag ≥ 0.
  [[nodiscard]] T u(int channel, int lag) const { return T(u_(t_ - lag, channel)); }

 private:
  Eigen::Ref<const Eigen::MatrixXd> u_;
  Eigen::Ref<const Eigen::VectorXd> y_;
  Eigen::Index t_ = 0;
};

/// Window of a free-run simulation: outputs from the model's past (a `History<T, L>`), inputs
/// from the data matrix, and samples before t = 0 from the initial window.
template <class T, int L>
class SimulationWindow {
 public:
  /// Scalar the regressors are evaluated on.
  using Scalar = T;

  /// `u`: N×nu inputs; `history`: the simulated past outputs (updated by the caller after each
  /// step); `u_past`: initial input window, nu·input_lag values channel-major, or empty (zero).
  SimulationWindow(const Eigen::Ref<const Eigen::MatrixXd>& u, const History<T, L>& history,
                   std::span<const T> u_past, int input_lag)
      : u_(u), history_(history), u_past_(u_past), input_lag_(input_lag) {}

  /// Moves the window to time t.
  void set_time(Eigen::Index t) { t_ = t; }

  /// ŷ(t−lag), lag ≥ 1: from the history (the caller pushes ŷ(t) after each step).
  [[nodiscard]] const T& y(int lag) const { return history_(lag); }

  /// u_channel(t−lag), lag ≥ 0; before t = 0 from the initial window (zero if it is empty).
  [[nodiscard]] T u(int channel, int lag) const {
    const Eigen::Index i = t_ - lag;
    if (i >= 0) return T(u_(i, channel));
    if (u_past_.empty()) return T(0);
    // u(−1) is entry 0 of the channel's block: -i - 1 steps before the first sample.
    return u_past_[static_cast<std::size_t>(channel * input_lag_ + (-i - 1))];
  }

 private:
  Eigen::Ref<const Eigen::MatrixXd> u_;
  const History<T, L>& history_;
  std::span<const T> u_past_;
  int input_lag_;
  Eigen::Index t_ = 0;
};

}  // namespace nlid
