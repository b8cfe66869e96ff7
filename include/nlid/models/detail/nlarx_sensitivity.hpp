#pragma once
/// @file
/// Structured Jacobian of an Nlarx model's free-run simulation errors (simulation focus).
///
/// Forward AD through the recursion (`AutoDiffProblem<SimulationResiduals>`) carries all P
/// derivatives through every arithmetic operation of the network: O(P) per operation. The
/// free-run Jacobian has more structure (Ljung 1999, eq. 10.43): with S(t) = ∂ŷ_s(t)/∂θ,
///
///     S(t) = ∂F/∂θ (φ(t))  +  Σ_{k=1..Ly} cₖ(t) S(t−k),     cₖ(t) = Σⱼ ∂F/∂φⱼ · ∂φⱼ/∂ŷ(t−k),
///
/// so a sample costs one local gradient of F (analytic: `DifferentiableNonlinearity`), one pass
/// of the regressors on an Ly-wide dual (custom regressors may be nonlinear in past outputs, so
/// ∂φ/∂ŷ(t−k) is not just a selection), and Ly·P multiply-adds. Estimated initial states are
/// columns of θ too: S(−k) is then the unit vector of the parameter holding ŷ(−k).
///
/// The residuals are exactly those of `SimulationResiduals`, which the problem holds (the
/// residual-only path *is* its `residuals`; the gradient path reproduces its values bitwise), and the Jacobian equals
/// the forward-AD one to rounding (tests/models/sensitivity_test.cpp). Sizes: a static
/// parameter count keeps every buffer on the stack, so a fixed-size evaluation allocates
/// nothing (tests/nomalloc).

#include <algorithm>
#include <array>
#include <cmath>
#include <span>
#include <type_traits>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "nlid/ad/dual.hpp"
#include "nlid/core/error.hpp"
#include "nlid/core/initial_condition.hpp"
#include "nlid/core/sizes.hpp"
#include "nlid/models/detail/estimation_segment.hpp"
#include "nlid/models/detail/simulation_residuals.hpp"
#include "nlid/models/detail/model_common.hpp"
#include "nlid/nonlinearities/concepts.hpp"
#include "nlid/regressors/history.hpp"
#include "nlid/regressors/lag_window.hpp"

namespace nlid::detail {

/// An Nlarx type whose simulation Jacobian `NlarxSimulationProblem` can build: a nonlinearity
/// with an analytic gradient and a compile-time output lag (the dual width of the regressor pass).
template <class M>
concept HasStructuredSimulationJacobian = requires {
  typename M::Regressors;
  typename M::Map;
} && M::Regressors::max_output_lag != Dynamic && DifferentiableNonlinearity<typename M::Map>;

/// n values of T: on the stack for a static N, else in a per-thread vector grown once (so a
/// Dynamic problem allocates on its first evaluation only). `Slot` keeps buffers apart.
template <class T, int N, int Slot>
class SensitivityBuffer {
 public:
  explicit SensitivityBuffer(std::size_t n) : n_(n) {
    if constexpr (N == Dynamic) {
      thread_local std::vector<T> storage;
      if (storage.size() < n) storage.resize(n);
      ptr_ = storage.data();
    } else {
      ptr_ = arr_.data();
    }
  }
  SensitivityBuffer(const SensitivityBuffer&) = delete;
  SensitivityBuffer& operator=(const SensitivityBuffer&) = delete;
  T* data() { return ptr_; }
  std::span<T> span() { return {ptr_, n_}; }

 private:
  std::array<T, (N == Dynamic || N < 1) ? 1 : static_cast<std::size_t>(N)> arr_{};
  std::size_t n_;
  T* ptr_ = nullptr;
};

/// The regressors' view of the past with each past output ŷ(t−k) seeded as dual variable k−1.
template <class Inner, class D>
class SeededWindow {
 public:
  using Scalar = D;
  explicit SeededWindow(const Inner& w) : w_(&w) {}
  [[nodiscard]] D y(int lag) const { return D::variable(w_->y(lag), lag - 1); }
  [[nodiscard]] D u(int channel, int lag) const { return D(w_->u(channel, lag)); }

 private:
  const Inner* w_;
};

/// Free-run residuals of an Nlarx model with the structured Jacobian (see file comment): a
/// `LeastSquaresProblem` with the same θ layout as `SimulationResiduals<M, P>` (model
/// parameters, then each experiment's estimated past outputs).
template <class M, int P>
  requires HasStructuredSimulationJacobian<M>
class NlarxSimulationProblem {
 public:
  /// Static parameter count (the model's, or Dynamic with estimated initial states).
  static constexpr int num_params = P;

  /// `free` lists the x0 entries estimated per experiment (empty unless ic == estimate); they
  /// must be past outputs (indices < Ly), as `model_free_states` gives for Nlarx.
  NlarxSimulationProblem(const M& model, std::vector<EstimationSegment> segments, std::vector<int> free,
                         InitialCondition ic, double limit)
      : res_(model, std::move(segments), std::move(free), ic, limit) {
    require(ic != InitialCondition::equilibrium,
            "the structured simulation Jacobian supports zero, measured and estimated initial conditions",
            at_parameter("initial_condition"));
    for (int k : res_.free_states()) {
      require(k >= 0 && k < model.output_lag(), "an estimated initial-state entry is not a past output",
              at_parameter("initial_condition"));
    }
  }

  /// Model parameters plus estimated initial states.
  [[nodiscard]] int num_parameters() const { return res_.num_parameters(); }
  /// Σ over experiments of the simulated samples.
  [[nodiscard]] Eigen::Index num_residuals() const { return res_.num_residuals(); }

  /// r = ŷ_s − y stacked, and with `J` the m × n Jacobian; false if a simulation diverges.
  bool evaluate(const Eigen::Matrix<double, P, 1>& theta, Eigen::VectorXd& r, Eigen::Matrix<double, Eigen::Dynamic, P>* J) const {
    const std::span<const double> th(theta.data(), static_cast<std::size_t>(theta.size()));
    if (!J) return res_.residuals(th, std::span<double>(r.data(), static_cast<std::size_t>(r.size())));
    return res_.stacked_with_sensitivity(th, r, [&](const EstimationSegment& s, std::span<const double> x0, Eigen::Index off) {
      return simulate_with_sensitivity(s, theta, x0, r, off, *J);
    });
  }

 private:
  using R = typename M::Regressors;
  using F = typename M::Map;
  static constexpr int kLy = R::max_output_lag;
  using D = Dual<double, (kLy > 0 ? kLy : 1)>;
  static constexpr int kRing = (P == Dynamic || kLy == 0) ? (kLy == 0 ? 1 : Dynamic) : kLy * P;

  bool simulate_with_sensitivity(const EstimationSegment& s, const Eigen::Matrix<double, P, 1>& theta,
                                 std::span<const double> x0, Eigen::VectorXd& r, Eigen::Index off,
                                 Eigen::Matrix<double, Eigen::Dynamic, P>& J) const {
    const M& model = res_.model();
    const int np = model.num_parameters();
    const int n = P != Dynamic ? P : num_parameters();
    const int ly = model.output_lag();
    const int lu = model.input_lag();
    const int nr = model.regressors().size();
    const Eigen::Index len = s.y.size() - s.start;
    const auto u = s.u->bottomRows(len);
    const std::span<const double> th(theta.data(), static_cast<std::size_t>(np));

    History<double, kLy> past(ly);
    if (!x0.empty()) {
      for (int k = ly; k >= 1; --k) past.push(x0[static_cast<std::size_t>(k - 1)]);
    }
    const std::span<const double> u_past = x0.empty() ? std::span<const double>{} : x0.subspan(static_cast<std::size_t>(ly));
    SimulationWindow<double, kLy> w(u, past, u_past, lu);
    const SeededWindow<SimulationWindow<double, kLy>, D> seeded(w);  // follows w.set_time

    SensitivityBuffer<D, R::num_regressors, 0> phi(static_cast<std::size_t>(nr));
    SensitivityBuffer<double, R::num_regressors, 1> x(static_cast<std::size_t>(nr));
    SensitivityBuffer<double, R::num_regressors, 2> g_x(static_cast<std::size_t>(nr));
    SensitivityBuffer<double, F::num_params, 3> g_theta(static_cast<std::size_t>(np));
    SensitivityBuffer<double, P, 4> row(static_cast<std::size_t>(n));
    // Ring of the last Ly sensitivity rows, S(t−1) at slot `head`, S(t−k) at head − k + 1.
    SensitivityBuffer<double, kRing, 5> ring(static_cast<std::size_t>(std::max(ly, 1) * n));
    double* S = ring.data();
    std::fill(S, S + static_cast<std::ptrdiff_t>(std::max(ly, 1)) * n, 0.0);
    int head = 0;
    if (s.free_offset >= 0) {
      // ŷ(−k) = θ[np + offset + i] for free[i] = k − 1: S(−k) is that unit vector.
      const std::vector<int>& free = res_.free_states();
      for (std::size_t i = 0; i < free.size(); ++i) {
        const int k = free[i] + 1;
        const int slot = ((head - k + 1) % ly + ly) % ly;
        S[static_cast<std::ptrdiff_t>(slot) * n + np + s.free_offset + static_cast<int>(i)] = 1.0;
      }
    }
    double* rw = row.data();
    double* gt = g_theta.data();
    double* gx = g_x.data();
    const auto& regs = model.regressors();
    const auto& f = model.nonlinearity();
    for (Eigen::Index t = 0; t < len; ++t) {
      w.set_time(t);
      regs.evaluate(seeded, phi.span());
      for (int j = 0; j < nr; ++j) x.data()[j] = phi.data()[j].a;
      const double yt = f.gradient(std::span<const double>(x.data(), static_cast<std::size_t>(nr)), th, g_theta.span(), g_x.span());
      if (!std::isfinite(yt) || std::abs(yt) > res_.limit()) return false;
      r(off + t) = yt;
      for (int c = 0; c < np; ++c) rw[c] = gt[c];
      for (int c = np; c < n; ++c) rw[c] = 0.0;
      for (int k = 1; k <= ly; ++k) {
        double ck = 0.0;
        for (int j = 0; j < nr; ++j) ck += gx[j] * phi.data()[j].v[k - 1];
        if (ck == 0.0) continue;
        const double* Sk = S + static_cast<std::ptrdiff_t>(((head - k + 1) % ly + ly) % ly) * n;
        for (int c = 0; c < n; ++c) rw[c] += ck * Sk[c];
      }
      for (int c = 0; c < n; ++c) J(off + t, c) = rw[c];
      if (ly > 0) {
        head = head + 1 == ly ? 0 : head + 1;  // the slot of S(t−Ly), no longer needed
        std::copy(rw, rw + n, S + static_cast<std::ptrdiff_t>(head) * n);
      }
      past.push(yt);
    }
    return true;
  }

  SimulationResiduals<M, P> res_;  // residuals, experiments and initial states, shared with forward AD
};

}  // namespace nlid::detail
