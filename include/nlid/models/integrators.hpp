#pragma once
/// @file
/// Explicit ODE integrators for grey-box simulation: Euler, classical Runge–Kutta 4 and the
/// adaptive Dormand–Prince 5(4) pair, generic over the scalar (double, float, Dual).
///
/// Problem. Given an autonomous system ẋ = f(x) (the input is held constant over a sample
/// interval, so within one interval the system *is* autonomous), advance x over a step h.
///
///     Euler            x⁺ = x + h k₁                                            order 1
///     RK4              k₁ = f(x), k₂ = f(x + h/2 k₁), k₃ = f(x + h/2 k₂), k₄ = f(x + h k₃)
///                      x⁺ = x + h/6 (k₁ + 2k₂ + 2k₃ + k₄)                       order 4
///     Dormand–Prince   7 stages (FSAL), 5th-order solution, embedded 4th-order error estimate
///
/// (Hairer, Nørsett & Wanner, "Solving ODEs I", 2nd ed., 1993, Sec. II.1 (RK4, Table 1.2) and
/// Sec. II.5 (DOPRI5, Table 5.2); Dormand & Prince, J. Comput. Appl. Math. 6(1), 1980.)
///
/// Stability and the sub-step rule. Applied to the test equation ẋ = λx an explicit method
/// multiplies x by a polynomial R(hλ) per step; it is stable only while |R(hλ)| ≤ 1. For RK4
/// that region reaches hλ = −2.785 on the negative real axis and |hλ| = 2√2 ≈ 2.83 on the
/// imaginary axis (Hairer & Wanner, "Solving ODEs II", 1996, Sec. IV.2, Fig. 2.1). Euler is
/// stable on the real axis only for hλ ≥ −2 and *never* for a pure oscillation (|1 + iωh| > 1).
///
/// Grey-box models are often mildly stiff: a hard stop modelled as a contact spring
/// K·(max(y, y_hi) − y_hi) with large K has, while in contact, eigenvalues λ ≈ ±i√K, so one
/// sample of h = 10 ms with K = 10⁶ s⁻² gives |hλ| = 10 — far outside every explicit method's
/// region, and the simulation explodes. nlid therefore sub-steps each sample interval:
///
///     n = clamp(⌈ h · ρ / s ⌉, min_substeps, max_substeps),   h_sub = h / n
///
/// where ρ is an upper bound on the spectral radius of ∂f/∂x over the operating range (the
/// physics reports it, e.g. ρ = max(c, √(k + K)) for the throttle) and s is
/// `IntegratorOptions::stability_target` (default 1.0: well inside RK4's 2.78 bound, so a contact
/// phase is also *accurate*, not just stable; the amplitude error per step is (hρ)⁶/144).
/// `IntegratorOptions::substeps > 0` overrides the rule with a fixed count.
///
/// Derivatives through an integrator. All methods are plain arithmetic on the state, so a Dual
/// state yields exact sensitivities ∂x(t)/∂θ of the *discrete* solution map. The adaptive method
/// controls its step size from the value parts only, so a Dual run takes exactly the steps the
/// double run takes and its derivative is that of the same discrete map (the step sequence is
/// treated as fixed, as in Ceres' and CVODES' "internal differentiation").
///
/// Notation: a *system* is any callable `f(const State& x, State& dx)` (Boost.Odeint style), a
/// *state* is an Eigen column vector `Eigen::Matrix<T, N, 1>` with N fixed or `Dynamic`.
/// Steppers own their stage vectors, so a fixed-size step allocates nothing and a dynamic one
/// allocates only on the first call.

#include <algorithm>
#include <cmath>
#include <concepts>
#include <limits>
#include <string>
#include <type_traits>

#include <Eigen/Core>

#include "nlid/ad/dual.hpp"
#include "nlid/core/error.hpp"

// RK4's step inlines the right-hand side into its four stages: called out of line, a physics
// evaluated on Batch lanes passed every operand through memory (perf: 45 % of a batched throttle
// simulation in the call). Right-hand sides are small; the stages are where the time goes.
#if defined(__GNUC__)
#define NLID_FLATTEN [[gnu::flatten]]
#else
#define NLID_FLATTEN
#endif

namespace nlid {

/// Which integrator a simulation uses.
enum class IntegratorMethod {
  euler,           ///< explicit Euler, order 1 (for comparison and quick checks)
  rk4,             ///< classical Runge–Kutta, order 4, fixed sub-steps (default)
  dormand_prince,  ///< Dormand–Prince 5(4), adaptive step size with error control
};

/// Largest fixed sub-step count per sample (`IntegratorOptions::substeps`, `min_substeps`,
/// `max_substeps`): fifty times the default ceiling of the automatic rule. More would only make a
/// simulation of an ordinary record run for hours (a model file asking 2³⁰ sub-steps per sample
/// would hang its reader's first simulation).
inline constexpr int max_integrator_substeps = 100000;
/// Largest step budget per sample of the adaptive method (`IntegratorOptions::max_adaptive_steps`):
/// ten times the default. A budget that is never reached because the tolerance cannot be met
/// (a relative tolerance of 1e-300) is spent in full before the run fails.
inline constexpr int max_adaptive_step_budget = 1000000;

/// Settings of the integrator used between two samples.
struct IntegratorOptions {
  /// The method.
  IntegratorMethod method = IntegratorMethod::rk4;
  /// Fixed number of sub-steps per sample interval; 0 = automatic from the stiffness bound ρ by
  /// the rule n = ⌈h ρ / stability_target⌉ (see the file comment).
  int substeps = 0;
  /// Lower limit of the automatic sub-step count (accuracy floor for smooth, slow physics).
  int min_substeps = 1;
  /// Upper limit of the automatic sub-step count (cost ceiling). If the rule asks for more, the
  /// ceiling is used and a diverging simulation is reported rather than silently accepted.
  int max_substeps = 2000;
  /// Target value of h_sub·ρ for the automatic rule; must be in (0, 2.5] for RK4 stability.
  double stability_target = 1.0;
  /// Relative tolerance of the adaptive method (per component, on the value part).
  double relative_tolerance = 1e-6;
  /// Absolute tolerance of the adaptive method.
  double absolute_tolerance = 1e-8;
  /// Step budget of the adaptive method per sample interval (a stiff or diverging system stops
  /// here instead of grinding on).
  int max_adaptive_steps = 100000;
};

/// An ODE state: an Eigen column vector (fixed or dynamic length).
/// Satisfied by `Eigen::Matrix<T, N, 1>` for T = double, float, Dual<double, M>, and N ≥ 1 or Dynamic.
template <class S>
concept OdeState = std::derived_from<S, Eigen::MatrixBase<S>> && S::ColsAtCompileTime == 1;

/// A right-hand side ẋ = f(x): callable as `f(x, dx)` with `dx` pre-sized like `x`.
/// Satisfied by any lambda or functor `void(const State&, State&)` (Boost.Odeint's "system").
template <class F, class S>
concept OdeSystem = OdeState<S> && requires(F& f, const S& x, S& dx) { f(x, dx); };

/// Checks integrator options; throws `nlid::Error` naming the bad option.
inline void validate(const IntegratorOptions& o) {
  require(o.substeps >= 0, "substeps must be >= 0 (0 = automatic)", at_parameter("substeps"));
  require(o.min_substeps >= 1, "min_substeps must be >= 1", at_parameter("min_substeps"));
  require(o.max_substeps >= o.min_substeps, "max_substeps must be >= min_substeps",
          at_parameter("max_substeps"));
  if (o.substeps > max_integrator_substeps || o.max_substeps > max_integrator_substeps) {
    const bool fixed = o.substeps > max_integrator_substeps;
    throw Error(std::string(fixed ? "substeps" : "max_substeps") + " = " +
                    std::to_string(fixed ? o.substeps : o.max_substeps) + " is more than the " +
                    std::to_string(max_integrator_substeps) + " sub-steps per sample an integrator may take",
                at_parameter(fixed ? "substeps" : "max_substeps"));
  }
  require(o.stability_target > 0.0 && o.stability_target <= 2.5,
          "stability_target must be in (0, 2.5] (RK4 is unstable beyond h*rho = 2.78)",
          at_parameter("stability_target"));
  require(o.relative_tolerance > 0.0, "relative_tolerance of the adaptive method must be positive",
          at_parameter("relative_tolerance"));
  require(o.absolute_tolerance > 0.0, "absolute_tolerance of the adaptive method must be positive",
          at_parameter("absolute_tolerance"));
  require(o.max_adaptive_steps >= 1, "max_adaptive_steps must be >= 1",
          at_parameter("max_adaptive_steps"));
  if (o.max_adaptive_steps > max_adaptive_step_budget) {
    throw Error("max_adaptive_steps = " + std::to_string(o.max_adaptive_steps) + " is more than the " +
                    std::to_string(max_adaptive_step_budget) + " steps per sample the adaptive method may take",
                at_parameter("max_adaptive_steps"));
  }
}

/// Sub-steps per sample interval of length `h` for a system whose Jacobian has spectral radius
/// at most `spectral_radius` (the rule of the file comment). A non-finite or non-positive radius
/// means "unknown": then only the floor `min_substeps` applies.
inline int substeps_for(double h, double spectral_radius, const IntegratorOptions& o) {
  if (o.substeps > 0) return o.substeps;
  if (!(spectral_radius > 0.0) || !std::isfinite(spectral_radius)) return o.min_substeps;
  const double need = std::ceil(h * spectral_radius / o.stability_target);
  // Written so that a NaN h also lands on the ceiling: converting NaN to int is undefined.
  if (!(need < static_cast<double>(o.max_substeps))) return o.max_substeps;
  return std::max(o.min_substeps, static_cast<int>(need));
}

/// The least number of sub-steps per sample of length h whose fixed step keeps the method stable
/// (h·ρ/n ≤ 2.78 for RK4, 2 for Euler: the real-axis limits) when `substeps` does not; 0 when it
/// does, the method is adaptive or ρ is unknown. ρ is the stiffness at one state: stiffer states
/// elsewhere need more.
inline double unstable_fixed_substeps(double h, double spectral_radius, int substeps, IntegratorMethod method) {
  if (method == IntegratorMethod::dormand_prince || !(spectral_radius > 0.0) || !std::isfinite(spectral_radius) ||
      substeps <= 0)
    return 0.0;
  const double limit = method == IntegratorMethod::euler ? 2.0 : 2.78;
  if (h * spectral_radius / substeps <= limit) return 0.0;
  return std::ceil(h * spectral_radius / limit);
}

/// Sub-steps a stable step would need when the automatic rule stopped at its ceiling with a
/// step beyond the fixed-step method's stability limit (h·ρ ≈ 2.78 for RK4, 2 for Euler) —
/// what a diverging simulation or refused code generation should name; 0 otherwise (a fixed
/// count, the adaptive method, an unknown ρ, or a capped step that is still stable).
inline double unstable_capped_substeps(double h, double spectral_radius, int substeps, const IntegratorOptions& o) {
  if (o.substeps > 0 || substeps < o.max_substeps) return 0.0;
  if (unstable_fixed_substeps(h, spectral_radius, substeps, o.method) == 0.0) return 0.0;
  return std::ceil(h * spectral_radius / o.stability_target);
}

namespace detail {
/// A dual number with a compile-time derivative count (its gradient lives inside the object).
template <class S>
inline constexpr bool is_fixed_dual_v = false;
template <class T, int N>
inline constexpr bool is_fixed_dual_v<Dual<T, N>> = N != Dynamic;

/// The real type under a scalar: double for Dual<double, N>, float for float.
template <class S>
using real_of_t = std::remove_cvref_t<decltype(value_of(std::declval<S>()))>;

/// True if every component's value is finite (derivative parts are not inspected: a finite value
/// with a huge derivative is legal).
template <class S>
bool values_finite(const Eigen::MatrixBase<S>& x) {
  // value_is_finite tests a Batch's lanes together (a few vector instructions); converting it to
  // one double first reduced over the lanes, 20 % of a batched simulation at one test per RK4
  // sub-step.
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    if (!value_is_finite(x.derived().coeff(i))) return false;
  }
  return true;
}
}  // namespace detail

/// Explicit Euler stepper: x⁺ = x + h f(x). First order; kept for comparison and order tests.
template <OdeState State>
class EulerStepper {
 public:
  /// Number of right-hand-side evaluations per step.
  static constexpr int stages = 1;
  /// Classical order of the method.
  static constexpr int order = 1;

  /// Advances `x` by one step of length `h`.
  template <class System>
    requires OdeSystem<System, State>
  void step(System& f, State& x, double h) {
    using R = detail::real_of_t<typename State::Scalar>;
    reserve(x.size());
    f(x, k1_);
    x += R(h) * k1_;
  }
  /// Sizes the stage buffer for states of `n` entries (every step does; a caller that must not
  /// allocate while stepping does it beforehand).
  void reserve(Eigen::Index n) { k1_.resize(n); }

 private:
  State k1_;
};

/// Classical fourth-order Runge–Kutta stepper (Hairer–Nørsett–Wanner I, Table 1.2).
template <OdeState State>
class Rk4Stepper {
 public:
  /// Number of right-hand-side evaluations per step.
  static constexpr int stages = 4;
  /// Classical order of the method: the global error falls as h⁴.
  static constexpr int order = 4;

  /// Advances `x` by one step of length `h`.
  template <class System>
    requires OdeSystem<System, State>
  NLID_FLATTEN void step(System& f, State& x, double h) {
    using S = typename State::Scalar;
    if constexpr (State::SizeAtCompileTime != Eigen::Dynamic && detail::is_fixed_dual_v<S>) {
      // Fixed-size dual states (the grey-box Jacobian pass): stage slopes as locals, which the
      // compiler keeps in registers or short-lived stack slots; as members every stage went
      // through the stepper object, and the throttle's Dual<4> pass took 1.2x longer. Not for
      // Batch lanes, where locals never helped: the portable Batch<double, 8> throttle ran 1.3x
      // slower with them (before Batch copied lane by lane), the native Batch<double, 4> 10 %
      // slower (after); plain doubles measured the same either way (docs/performance.md).
      // Not for DynamicDual either: fresh locals would allocate their gradients every step.
      State k1, k2, k3, k4, tmp;
      step_with(f, x, h, k1, k2, k3, k4, tmp);
    } else {
      reserve(x.size());
      step_with(f, x, h, k1_, k2_, k3_, k4_, tmp_);
    }
  }

  /// Sizes the stage buffers for states of `n` entries, so that later steps allocate nothing.
  void reserve(Eigen::Index n) {
    k1_.resize(n);
    k2_.resize(n);
    k3_.resize(n);
    k4_.resize(n);
    tmp_.resize(n);
  }
  /// Advances `x` by `n` equal steps covering `h`. Returns false (x then holds the first
  /// non-finite state) if the solution left the finite numbers: the caller reports divergence.
  template <class System>
    requires OdeSystem<System, State>
  bool integrate(System& f, State& x, double h, int n) {
    const double hs = h / n;
    for (int i = 0; i < n; ++i) {
      step(f, x, hs);
      if (!detail::values_finite(x)) return false;
    }
    return true;
  }

 private:
  template <class System>
  NLID_FLATTEN static void step_with(System& f, State& x, double h, State& k1, State& k2, State& k3, State& k4,
                                     State& tmp) {
    using R = detail::real_of_t<typename State::Scalar>;
    const Eigen::Index n = x.size();
    const R hh = R(h), half = R(0.5) * R(h), sixth = R(h) / R(6);
    // Element loops, not Eigen expressions: the physics writes each slope as scalars, and a
    // packet load right after scalar stores defeats store-to-load forwarding — a 2-state step
    // took 1.4x longer (docs/performance.md). Same roundings as the vector form.
    f(x, k1);
    for (Eigen::Index i = 0; i < n; ++i) tmp[i] = x[i] + half * k1[i];
    f(tmp, k2);
    for (Eigen::Index i = 0; i < n; ++i) tmp[i] = x[i] + half * k2[i];
    f(tmp, k3);
    for (Eigen::Index i = 0; i < n; ++i) tmp[i] = x[i] + hh * k3[i];
    f(tmp, k4);
    // Sum the slopes first: one rounding of the weighted average instead of four updates of x.
    for (Eigen::Index i = 0; i < n; ++i) x[i] += sixth * ((k1[i] + k4[i]) + R(2) * (k2[i] + k3[i]));
  }

  State k1_, k2_, k3_, k4_, tmp_;
};

/// Dormand–Prince 5(4) adaptive stepper (DOPRI5; Hairer–Nørsett–Wanner I, Table 5.2), first
/// same as last, with the standard PI-free step-size controller
/// h ← h · clamp(0.9 · err^(−1/5), 0.2, 5).
template <OdeState State>
class DormandPrinceStepper {
 public:
  /// Right-hand-side evaluations per step (the 7th is reused as the next step's first).
  static constexpr int stages = 7;
  /// Order of the propagated solution (local extrapolation).
  static constexpr int order = 5;

  /// One step of length h without error control; `err` receives the embedded error estimate
  /// (5th minus 4th order solution). Used by the adaptive driver and by order tests.
  template <class System>
    requires OdeSystem<System, State>
  void step(System& f, State& x, double h, State& err) {
    using R = detail::real_of_t<typename State::Scalar>;
    resize(x.size());
    err.resize(x.size());
    const R hh = R(h);
    f(x, k1_);
    stage_from_k1(f, x, hh);
    err = hh * (R(e1) * k1_ + R(e3) * k3_ + R(e4) * k4_ + R(e5) * k5_ + R(e6) * k6_ + R(e7) * k7_);
    x = y5_;
  }

  /// Sizes the stage buffers for states of `n` entries, so that later steps allocate nothing.
  void reserve(Eigen::Index n) { resize(n); }

  /// Integrates over an interval of length `h` with adaptive steps. `h_try` carries the step
  /// size between calls (0 = choose one from h). Returns false if the step budget ran out or the
  /// state became non-finite. Error norm: RMS of eᵢ / (atol + rtol·max|xᵢ|), value parts only.
  template <class System>
    requires OdeSystem<System, State>
  bool integrate(System& f, State& x, double h, double& h_try, const IntegratorOptions& o) {
    using R = detail::real_of_t<typename State::Scalar>;
    resize(x.size());
    double t = 0.0;
    double hs = (h_try > 0.0) ? std::min(h_try, h) : h;
    bool k1_valid = false;
    int steps = 0;
    while (t < h) {
      // Do not leave a sliver: stretch the last step when less than 1 % of a step remains.
      double step_h = hs;
      if (t + step_h >= h * (1.0 - 1e-12) || h - (t + step_h) < 0.01 * step_h) step_h = h - t;
      if (++steps > o.max_adaptive_steps) return false;
      if (!k1_valid) f(x, k1_);
      stage_from_k1(f, x, R(step_h));
      const double en = error_norm(x, R(step_h), o);
      if (!std::isfinite(en)) {
        // A non-finite trial is a too-large step (or a genuinely diverging system): shrink.
        hs = step_h * 0.2;
        k1_valid = true;
        if (hs < 1e-14 * h) return false;
        continue;
      }
      if (en <= 1.0) {
        t += step_h;
        x = y5_;
        k1_ = k7_;  // FSAL: f(y5) was the 7th stage
        k1_valid = true;
        const double grow = en == 0.0 ? 5.0 : std::clamp(0.9 * std::pow(en, -0.2), 0.2, 5.0);
        // Keep the pre-stretch step as the proposal so a short final piece does not shrink it.
        hs = std::max(hs, step_h) * grow;
      } else {
        hs = step_h * std::clamp(0.9 * std::pow(en, -0.2), 0.2, 1.0);
        k1_valid = true;  // x unchanged, so k1 is still f(x)
        if (hs < 1e-14 * h) return false;
      }
    }
    h_try = hs;
    return detail::values_finite(x);
  }

 private:
  // Butcher tableau (Dormand & Prince 1980).
  static constexpr double a21 = 1.0 / 5;
  static constexpr double a31 = 3.0 / 40, a32 = 9.0 / 40;
  static constexpr double a41 = 44.0 / 45, a42 = -56.0 / 15, a43 = 32.0 / 9;
  static constexpr double a51 = 19372.0 / 6561, a52 = -25360.0 / 2187, a53 = 64448.0 / 6561,
                          a54 = -212.0 / 729;
  static constexpr double a61 = 9017.0 / 3168, a62 = -355.0 / 33, a63 = 46732.0 / 5247,
                          a64 = 49.0 / 176, a65 = -5103.0 / 18656;
  static constexpr double b1 = 35.0 / 384, b3 = 500.0 / 1113, b4 = 125.0 / 192,
                          b5 = -2187.0 / 6784, b6 = 11.0 / 84;
  // e = b(5th order) − b̂(4th order).
  static constexpr double e1 = 71.0 / 57600, e3 = -71.0 / 16695, e4 = 71.0 / 1920,
                          e5 = -17253.0 / 339200, e6 = 22.0 / 525, e7 = -1.0 / 40;

  void resize(Eigen::Index n) {
    k1_.resize(n); k2_.resize(n); k3_.resize(n); k4_.resize(n);
    k5_.resize(n); k6_.resize(n); k7_.resize(n); y5_.resize(n); tmp_.resize(n);
  }

  // Stages 2..7 from k1 = f(x); leaves the 5th-order solution in y5_ and f(y5_) in k7_.
  template <class System, class R>
  void stage_from_k1(System& f, const State& x, R h) {
    tmp_ = x + h * (R(a21) * k1_);
    f(tmp_, k2_);
    tmp_ = x + h * (R(a31) * k1_ + R(a32) * k2_);
    f(tmp_, k3_);
    tmp_ = x + h * (R(a41) * k1_ + R(a42) * k2_ + R(a43) * k3_);
    f(tmp_, k4_);
    tmp_ = x + h * (R(a51) * k1_ + R(a52) * k2_ + R(a53) * k3_ + R(a54) * k4_);
    f(tmp_, k5_);
    tmp_ = x + h * (R(a61) * k1_ + R(a62) * k2_ + R(a63) * k3_ + R(a64) * k4_ + R(a65) * k5_);
    f(tmp_, k6_);
    y5_ = x + h * (R(b1) * k1_ + R(b3) * k3_ + R(b4) * k4_ + R(b5) * k5_ + R(b6) * k6_);
    f(y5_, k7_);
  }

  // Scaled RMS norm of the embedded error estimate, on value parts only (see file comment).
  template <class R>
  double error_norm(const State& x, R h, const IntegratorOptions& o) const {
    auto v = [](const auto& s) { return static_cast<double>(value_of(s)); };
    double sum = 0.0;
    const Eigen::Index n = x.size();
    for (Eigen::Index i = 0; i < n; ++i) {
      const double e = v(h) * (e1 * v(k1_[i]) + e3 * v(k3_[i]) + e4 * v(k4_[i]) + e5 * v(k5_[i]) +
                               e6 * v(k6_[i]) + e7 * v(k7_[i]));
      const double sc = o.absolute_tolerance +
                        o.relative_tolerance * std::max(std::abs(v(x[i])), std::abs(v(y5_[i])));
      sum += (e / sc) * (e / sc);
    }
    return n > 0 ? std::sqrt(sum / static_cast<double>(n)) : 0.0;
  }

  State k1_, k2_, k3_, k4_, k5_, k6_, k7_, y5_, tmp_;
};

}  // namespace nlid
