#pragma once
/// @file
/// The grey-box simulation engine: zero-order-hold simulation of a `Physics` on any scalar,
/// state Jacobians, equilibria and the sub-step rule. `GreyBox` and the estimation problem are
/// thin layers over these functions; they are public so that code composing physics at run time
/// (missing-physics diagnosis) can use the same engine.
///
/// Sampling. With samples u_k = u(t₀ + k T_s), k = 0 … N−1, the input is held constant over
/// [t_k, t_{k+1}) (zero-order hold) and the output is read at the sample instants:
///
///     ŷ_k = g(x(t_k), u_k, p),     x(t_{k+1}) = x(t_k) + ∫_{t_k}^{t_{k+1}} f(x(τ), u_k, p) dτ,
///
/// the integral computed by the method of `IntegratorOptions` with n sub-steps (RK4, Euler) or
/// adaptively (Dormand–Prince). The first output sample depends on x₀ only, so the free-run
/// simulation error ε_k = y_k − ŷ_k (Ljung 1999, Sec. 4.5 and eq. 7.15 with the simulation
/// predictor) starts at k = 0.
///
/// Sub-steps. n = `substeps_for(T_s, ρ, options)` (integrators.hpp) with ρ an upper bound on the
/// spectral radius of ∂f/∂x: the physics' `spectral_radius(p)` when it has one (state-dependent
/// stiffness such as a hard stop can only be known from the physics), otherwise the largest
/// Gershgorin bound max_i Σ_j |∂f_i/∂x_j| along the run (`physics_substeps`). n is computed from the
/// `double` parameter values, so value and Dual runs take identical steps (their derivatives then
/// describe exactly the discrete map that produced the residuals).
///
/// Equilibrium. x̄ with f(x̄, ū, p) = 0 is found by Newton's method with a least-squares step
/// (column-pivoting QR, so singular directions such as a free position are left at the guess)
/// and backtracking on ‖f‖; where ∂f/∂x is not finite, a step along the flow f itself. Its
/// parameter sensitivity follows from the implicit function theorem, ∂x̄/∂p = −(∂f/∂x)⁻¹ ∂f/∂p,
/// which `equilibrium_sensitivity_step` evaluates as one Newton step in Dual arithmetic from the
/// converged point.

#include <algorithm>
#include <array>
#include <cmath>
#include <concepts>
#include <limits>
#include <string>
#include <type_traits>
#include <vector>

#include <Eigen/Core>
#include <Eigen/QR>

#include "nlid/ad/dual.hpp"
#include "nlid/core/error.hpp"
#include "nlid/models/greybox_concepts.hpp"
#include "nlid/models/integrators.hpp"

namespace nlid {

namespace detail {

template <class P>
concept HasSpectralRadius = requires(const P& p, const double* th) {
  { p.spectral_radius(th) } -> std::convertible_to<double>;
};
template <class P>
concept HasInitialStateHook = requires(const P& p, const double* y0, const double* u0,
                                       const double* th, double* x0) {
  { p.initial_state(y0, u0, th, x0) } -> std::convertible_to<bool>;
};
template <class P>
concept HasParameterCheck = requires(const P& p, const double* th) { p.check_parameters(th); };

}  // namespace detail

/// The physics' relations between parameter values (`check_parameters`, greybox_concepts.hpp):
/// throws its `nlid::Error`, with `context` (e.g. "grey-box estimation start") put before the
/// message; does nothing for physics without the hook.
template <Physics P>
void physics_check_parameters(const P& phys, const double* p, const std::string& context = {}) {
  if constexpr (detail::HasParameterCheck<P>) {
    if (context.empty()) {
      phys.check_parameters(p);
    } else {
      try {
        phys.check_parameters(p);
      } catch (const Error& e) {
        throw Error(context + ": " + e.message(), e.where());
      }
    }
  } else {
    (void)phys, (void)p, (void)context;
  }
}

/// True if `physics_check_parameters` accepts p (for trial points, which are rejected, not fatal).
template <Physics P>
bool physics_parameters_consistent(const P& phys, const double* p) {
  if constexpr (detail::HasParameterCheck<P>) {
    try {
      phys.check_parameters(p);
    } catch (const Error&) {
      return false;
    }
  } else {
    (void)phys, (void)p;
  }
  return true;
}

/// Jacobian ∂f/∂x (n_x × n_x) of a physics at (x, u, p), exact by forward AD in chunks of 8.
template <Physics P>
Eigen::MatrixXd physics_state_jacobian(const P& phys, const double* x, const double* u,
                                       const double* p) {
  const int nx = detail::physics_states(phys), nu = detail::physics_inputs(phys),
            np = detail::physics_params(phys);
  using D = RuntimeDual;
  constexpr int W = D::num_derivatives;
  std::vector<D> xd(static_cast<std::size_t>(nx)), ud(static_cast<std::size_t>(nu)),
      pd(static_cast<std::size_t>(np)), dx(static_cast<std::size_t>(nx));
  for (int j = 0; j < nu; ++j) ud[static_cast<std::size_t>(j)] = D(u[j]);
  for (int j = 0; j < np; ++j) pd[static_cast<std::size_t>(j)] = D(p[j]);
  Eigen::MatrixXd J(nx, nx);
  for (int c0 = 0; c0 < nx; c0 += W) {
    for (int j = 0; j < nx; ++j) {
      xd[static_cast<std::size_t>(j)] =
          (j >= c0 && j < c0 + W) ? D::variable(x[j], j - c0) : D(x[j]);
    }
    phys.derivative(xd.data(), ud.data(), pd.data(), dx.data());
    for (int i = 0; i < nx; ++i) {
      for (int j = c0; j < std::min(nx, c0 + W); ++j) J(i, j) = dx[static_cast<std::size_t>(i)].v[j - c0];
    }
  }
  return J;
}

namespace detail {

// Gershgorin bound max_i Σ_j |∂f_i/∂x_j| at (x, u); 0 (unknown) if the Jacobian is not finite.
// A static physics is differentiated in one pass on Dual<double, n_x> held on the stack, so the
// trajectory rule below allocates nothing per sample.
template <Physics P>
double gershgorin_bound(const P& phys, const double* x, const double* u, const double* p) {
  if constexpr (StaticPhysics<P>) {
    constexpr int NX = P::num_states, NU = P::num_inputs, NP = P::num_params;
    using D = Dual<double, NX>;
    std::array<D, NX> xd, dx;
    std::array<D, (NU > 0 ? NU : 1)> ud;
    std::array<D, (NP > 0 ? NP : 1)> pd;
    for (int j = 0; j < NX; ++j) xd[static_cast<std::size_t>(j)] = D::variable(x[j], j);
    for (int j = 0; j < NU; ++j) ud[static_cast<std::size_t>(j)] = D(u[j]);
    for (int j = 0; j < NP; ++j) pd[static_cast<std::size_t>(j)] = D(p[j]);
    phys.derivative(xd.data(), ud.data(), pd.data(), dx.data());
    double bound = 0.0;
    for (const D& d : dx) {
      const double row = d.v.cwiseAbs().sum();
      if (!std::isfinite(row)) return 0.0;
      bound = std::max(bound, row);
    }
    return bound;
  } else {
    const Eigen::MatrixXd J = physics_state_jacobian(phys, x, u, p);
    return J.allFinite() ? J.cwiseAbs().rowwise().sum().maxCoeff() : 0.0;
  }
}

// One sample interval of length ts in `sub` fixed steps of RK4 or Euler (`method` not
// dormand_prince); false if the state left the finite numbers. The simulation loop and the
// sub-step rule's pass over a run step alike through this.
template <class F, class State>
bool fixed_step_interval(IntegratorMethod method, Rk4Stepper<State>& rk4, EulerStepper<State>& euler, F& f,
                         State& xs, double ts, int sub) {
  if (method == IntegratorMethod::rk4) return rk4.integrate(f, xs, ts, sub);
  for (int i = 0; i < sub; ++i) {
    euler.step(f, xs, ts / sub);
    if (!values_finite(xs)) return false;
  }
  return true;
}

}  // namespace detail

/// Upper bound on the spectral radius of ∂f/∂x used by the sub-step rule: the physics' own
/// `spectral_radius(p)` if it has one and it is a number ≥ 0, else (negative or NaN: "unknown")
/// the Gershgorin bound max_i Σ_j |∂f_i/∂x_j| at (x, u). Throws `nlid::Error` naming
/// `spectral_radius` if the physics returns +inf.
template <Physics P>
double physics_spectral_radius(const P& phys, const double* p, const double* x, const double* u) {
  if constexpr (detail::HasSpectralRadius<P>) {
    const double rho = static_cast<double>(phys.spectral_radius(p));
    // An infinitely stiff system has no stable explicit step: the sub-step rule reads a
    // non-finite radius as unknown and would take the fewest sub-steps, the opposite of what
    // the physics means.
    require(rho != std::numeric_limits<double>::infinity(),
            "the physics' spectral_radius(p) is +inf: no number of explicit integrator sub-steps is stable; return a "
            "finite bound, or a negative value for unknown",
            at_parameter("spectral_radius"));
    if (rho >= 0.0) return rho;
  }
  return detail::gershgorin_bound(phys, x, u, p);
}

/// True if the physics states its stiffness at p (`spectral_radius(p)` ≥ 0, +inf included): its
/// sub-step count then follows from p alone, not from the states a run reaches
/// (`physics_substeps`; a negative value or NaN means "unknown").
template <Physics P>
bool physics_stiffness_known(const P& phys, const double* p) {
  if constexpr (detail::HasSpectralRadius<P>) {
    return static_cast<double>(phys.spectral_radius(p)) >= 0.0;
  } else {
    (void)phys;
    (void)p;
    return false;
  }
}

/// False if the physics declares itself infinitely stiff at p (`spectral_radius(p)` = +inf),
/// where `physics_spectral_radius` throws: an estimator rejects such a trial point like a
/// diverging one instead of ending the search.
template <Physics P>
bool physics_stiffness_finite(const P& phys, const double* p) {
  if constexpr (detail::HasSpectralRadius<P>) {
    return static_cast<double>(phys.spectral_radius(p)) != std::numeric_limits<double>::infinity();
  } else {
    (void)phys;
    (void)p;
    return true;
  }
}

/// Sub-steps per sample for a fixed-step run of `phys` at parameters p from the state x0 over
/// the inputs u (N × n_u) with sample time ts — the count `GreyBox::simulate` and the estimator
/// use, so every caller that must reproduce their numbers calls this.
///
/// `IntegratorOptions::substeps` if set; else the rule n = ⌈T_s ρ / s⌉ with ρ the physics'
/// `spectral_radius(p)` when it knows one. A physics that does not (no member, or a negative or
/// NaN value) gets ρ = the largest Gershgorin bound of ∂f/∂x met along the run itself: a
/// double-precision pass from x0 evaluates the bound at every sample's state and input and
/// raises n as soon as a stiffer state is reached. Why the whole run: the bound at the start
/// alone can be far below the rest — a pendulum started horizontal has |∂f/∂x| ≈ 1 there
/// against g/L at the bottom of its swing; one RK4 step per 0.2 s sample instead of three left
/// its swing 70 times further off (tests/greybox/greybox_test.cpp).
/// n only grows during the pass, and the pass stops where the state leaves the finite numbers
/// (the simulation proper then reports the divergence). The adaptive method takes no count:
/// for it the rule at the start is returned, as before. `rho`, if given, receives the ρ the
/// count came from (for messages on a capped count). Throws `nlid::Error` naming
/// `spectral_radius` if the physics returns +inf.
template <Physics P>
int physics_substeps(const P& phys, const IntegratorOptions& options, const double* p, const double* x0,
                     const Eigen::MatrixXd& u, double ts, double* rho = nullptr) {
  constexpr int NX = P::num_states, NU = P::num_inputs;
  const int nx = detail::physics_states(phys), nu = detail::physics_inputs(phys);
  Eigen::Matrix<double, NU, 1> uk(nu);
  for (int j = 0; j < nu; ++j) uk[j] = u.rows() > 0 ? u(0, j) : 0.0;
  if (physics_stiffness_known(phys, p)) {
    // +inf lands here too, and physics_spectral_radius throws for it.
    const double own = physics_spectral_radius(phys, p, x0, uk.data());
    if (rho != nullptr) *rho = own;
    return substeps_for(ts, own, options);
  }
  double worst = detail::gershgorin_bound(phys, x0, uk.data(), p);
  if (rho != nullptr) *rho = worst;
  if (options.substeps > 0) return options.substeps;
  int n = substeps_for(ts, worst, options);
  if (options.method == IntegratorMethod::dormand_prince) return n;
  using State = Eigen::Matrix<double, NX, 1>;
  State xs(nx);
  for (int i = 0; i < nx; ++i) xs[i] = x0[i];
  auto f = [&](const State& s, State& ds) { phys.derivative(s.data(), uk.data(), p, ds.data()); };
  Rk4Stepper<State> rk4;
  EulerStepper<State> euler;
  for (Eigen::Index k = 0; k + 1 < u.rows(); ++k) {
    for (int j = 0; j < nu; ++j) uk[j] = u(k, j);
    if (k > 0) {
      const double r = detail::gershgorin_bound(phys, xs.data(), uk.data(), p);
      if (r > worst) {
        worst = r;
        n = substeps_for(ts, worst, options);
      }
    }
    if (!detail::fixed_step_interval(options.method, rk4, euler, f, xs, ts, n)) break;
  }
  if (rho != nullptr) *rho = worst;
  return n;
}

namespace detail {

// The simulation loop of `simulate_physics`, entered at sample `k0` with `xs` the state at t_{k0}
// (k0 = 0 is a whole run; the lockstep pair below hands a lane's tail over to it). Returns the
// number of samples delivered counted from 0, as `simulate_physics` does.
template <class T, Physics P, class State, class OnSample>
Eigen::Index simulate_physics_from(const P& phys, const IntegratorOptions& options, int substeps,
                                   const Eigen::MatrixXd& u, Eigen::Index k0, double ts, const T* p,
                                   State& xs, OnSample& on_sample) {
  constexpr int NU = P::num_inputs, NY = P::num_outputs;
  const int nu = physics_inputs(phys), ny = physics_outputs(phys);
  // Size 0 inputs (autonomous physics) still need a valid array type; Eigen handles 0 rows.
  Eigen::Matrix<T, NU, 1> uk(nu);
  Eigen::Matrix<T, NY, 1> yk(ny);
  auto f = [&](const State& s, State& ds) { phys.derivative(s.data(), uk.data(), p, ds.data()); };
  Rk4Stepper<State> rk4;
  EulerStepper<State> euler;
  DormandPrinceStepper<State> dopri;
  double h_try = 0.0;
  const Eigen::Index n = u.rows();
  const int sub = std::max(1, substeps);
  for (Eigen::Index k = k0; k < n; ++k) {
    for (int j = 0; j < nu; ++j) uk[j] = T(u(k, j));
    phys.output(xs.data(), uk.data(), p, yk.data());
    if (!values_finite(yk)) return k;
    on_sample(k, static_cast<const T*>(yk.data()));
    if (k + 1 == n) break;
    bool ok = true;
    switch (options.method) {
      case IntegratorMethod::rk4:
      case IntegratorMethod::euler:
        ok = fixed_step_interval(options.method, rk4, euler, f, xs, ts, sub);
        break;
      case IntegratorMethod::dormand_prince:
        ok = dopri.integrate(f, xs, ts, h_try, options);
        break;
    }
    if (!ok) return k + 1;
  }
  return n;
}

}  // namespace detail

/// Zero-order-hold simulation of `phys` on scalar T (double, float, Dual).
///
/// `u` is N × n_u (row k = input sample k), `p` points to n_p parameters and `x` to the n_x
/// initial states (overwritten with the state at the last sample). For every sample k the
/// callback `on_sample(k, y)` receives the n_y outputs. `substeps` is the fixed sub-step count
/// (Euler/RK4; ignored by the adaptive method). Returns the number of samples delivered: N on
/// success, fewer if the state or output left the finite numbers (a diverging simulation).
/// Allocates nothing when the physics has static sizes.
template <class T, Physics P, class OnSample>
Eigen::Index simulate_physics(const P& phys, const IntegratorOptions& options, int substeps,
                              const Eigen::MatrixXd& u, double ts, const T* p, T* x,
                              OnSample&& on_sample) {
  constexpr int NX = P::num_states;
  const int nx = detail::physics_states(phys);
  using State = Eigen::Matrix<T, NX, 1>;
  State xs(nx);
  for (int i = 0; i < nx; ++i) xs[i] = x[i];
  const Eigen::Index got = detail::simulate_physics_from<T>(phys, options, substeps, u, 0, ts, p, xs, on_sample);
  if (got == u.rows()) {
    for (int i = 0; i < nx; ++i) x[i] = xs[i];
  }
  return got;
}

/// Two experiments of one physics with the same parameters and sub-step count, simulated in
/// lockstep on scalar T (double, or a Dual for a Jacobian pass): exactly the numbers (and
/// callbacks) of two `simulate_physics<T>` calls, in about two thirds of their time (throttle,
/// RK4, double: 511 → 345 µs for 2 × 2000 samples).
///
/// Why: a single trajectory is one long dependency chain (each RK4 stage waits for the one
/// before), so the core idles most cycles; the other experiment's independent chain fills them
/// (docs/performance.md, "Grey-box residuals"). The pair advances sample by sample while both
/// have samples; the longer tail, or the surviving lane after a divergence, continues alone.
/// Fixed-step methods only: with Dormand–Prince each experiment chooses its own steps, and the
/// call falls back to two sequential runs.
///
/// `ua`, `ub`: the inputs (N_a × n_u, N_b × n_u); `xa`, `xb`: initial states, overwritten as in
/// `simulate_physics`; `on_a(k, y)`, `on_b(k, y)`: per-sample outputs. Returns the samples
/// delivered per experiment (N_a, N_b on success). Allocates nothing for static physics.
template <class T, Physics P, class OnA, class OnB>
std::array<Eigen::Index, 2> simulate_physics_pair(const P& phys, const IntegratorOptions& options,
                                                  int substeps, const Eigen::MatrixXd& ua,
                                                  const Eigen::MatrixXd& ub, double ts, const T* p,
                                                  T* xa, T* xb, OnA&& on_a, OnB&& on_b) {
  if (options.method == IntegratorMethod::dormand_prince) {
    return {simulate_physics<T>(phys, options, substeps, ua, ts, p, xa, on_a),
            simulate_physics<T>(phys, options, substeps, ub, ts, p, xb, on_b)};
  }
  constexpr int NX = P::num_states, NU = P::num_inputs, NY = P::num_outputs;
  const int nx = detail::physics_states(phys), nu = detail::physics_inputs(phys),
            ny = detail::physics_outputs(phys);
  using State = Eigen::Matrix<T, NX, 1>;
  State sa(nx), sb(nx);
  for (int i = 0; i < nx; ++i) {
    sa[i] = xa[i];
    sb[i] = xb[i];
  }
  Eigen::Matrix<T, NU, 1> uka(nu), ukb(nu);
  Eigen::Matrix<T, NY, 1> yka(ny), ykb(ny);
  auto fa = [&](const State& s, State& ds) { phys.derivative(s.data(), uka.data(), p, ds.data()); };
  auto fb = [&](const State& s, State& ds) { phys.derivative(s.data(), ukb.data(), p, ds.data()); };
  Rk4Stepper<State> rk4a, rk4b;
  EulerStepper<State> eua, eub;
  const bool rk4 = options.method == IntegratorMethod::rk4;
  const int sub = std::max(1, substeps);
  const double h = ts / sub;
  auto step = [&](auto& f, auto& rk, auto& eu, State& x) {
    if (rk4) {
      rk.step(f, x, h);
    } else {
      eu.step(f, x, h);
    }
  };
  // One interval of a lane alone, with the same steps and checks as the lockstep loop.
  auto interval = [&](auto& f, auto& rk, auto& eu, State& x) {
    for (int i = 0; i < sub; ++i) {
      step(f, rk, eu, x);
      if (!detail::values_finite(x)) return false;
    }
    return true;
  };
  // Lockstep up to the last sample both share; from sample `resume` on, each lane still alive
  // runs in the single-trajectory loop, which also reports a non-finite output as alone.
  const Eigen::Index shared = std::min(ua.rows(), ub.rows());
  State a0(nx), b0(nx);  // states at t_k, kept to redo an interval in which a lane diverged
  bool alive_a = true, alive_b = true;
  Eigen::Index resume = 0;
  for (; resume + 1 < shared; ++resume) {
    const Eigen::Index k = resume;
    for (int j = 0; j < nu; ++j) {
      uka[j] = T(ua(k, j));
      ukb[j] = T(ub(k, j));
    }
    phys.output(sa.data(), uka.data(), p, yka.data());
    phys.output(sb.data(), ukb.data(), p, ykb.data());
    if (!detail::values_finite(yka) || !detail::values_finite(ykb)) break;
    on_a(k, static_cast<const T*>(yka.data()));
    on_b(k, static_cast<const T*>(ykb.data()));
    a0 = sa;
    b0 = sb;
    bool finite = true;
    for (int i = 0; i < sub && finite; ++i) {
      step(fa, rk4a, eua, sa);
      step(fb, rk4b, eub, sb);
      finite = detail::values_finite(sa) && detail::values_finite(sb);
    }
    if (!finite) {
      // A lane left the finite numbers in this interval: redo it lane by lane from t_k, so
      // each lane stops (or goes on) exactly where it would alone.
      sa = a0;
      sb = b0;
      alive_a = interval(fa, rk4a, eua, sa);
      alive_b = interval(fb, rk4b, eub, sb);
      resume = k + 1;
      break;
    }
  }
  const Eigen::Index ga =
      alive_a ? detail::simulate_physics_from<T>(phys, options, substeps, ua, resume, ts, p, sa, on_a) : resume;
  const Eigen::Index gb =
      alive_b ? detail::simulate_physics_from<T>(phys, options, substeps, ub, resume, ts, p, sb, on_b) : resume;
  if (ga == ua.rows()) {
    for (int i = 0; i < nx; ++i) xa[i] = sa[i];
  }
  if (gb == ub.rows()) {
    for (int i = 0; i < nx; ++i) xb[i] = sb[i];
  }
  return {ga, gb};
}

/// Result of `physics_equilibrium`.
struct EquilibriumResult {
  bool converged = false;   ///< ‖f(x̄)‖ reached the tolerance
  double residual = 0.0;    ///< final ‖f(x̄, ū, p)‖∞
  int iterations = 0;       ///< Newton iterations used
};

/// Solves f(x, u, p) = 0 for x by damped Newton from the guess in `x` (overwritten). Tolerance:
/// ‖f‖∞ ≤ tol·(1 + ‖f(guess)‖∞). See the file comment.
template <Physics P>
EquilibriumResult physics_equilibrium(const P& phys, const double* u, const double* p, double* x,
                                      double tol = 1e-11, int max_iterations = 100) {
  const int nx = detail::physics_states(phys);
  Eigen::VectorXd xv = Eigen::Map<const Eigen::VectorXd>(x, nx);
  Eigen::VectorXd fx(nx), ft(nx), xt(nx);
  auto eval = [&](const Eigen::VectorXd& xx, Eigen::VectorXd& out) {
    phys.derivative(xx.data(), u, p, out.data());
    return out.allFinite() ? out.lpNorm<Eigen::Infinity>() : std::numeric_limits<double>::infinity();
  };
  EquilibriumResult res;
  double fn = eval(xv, fx);
  const double target = tol * (1.0 + (std::isfinite(fn) ? fn : 0.0));
  for (res.iterations = 0; res.iterations < max_iterations && fn > target; ++res.iterations) {
    const Eigen::MatrixXd J = physics_state_jacobian(phys, xv.data(), u, p);
    Eigen::VectorXd dx;
    if (J.allFinite()) dx = Eigen::ColPivHouseholderQR<Eigen::MatrixXd>(J).solve(-fx);
    // Where ∂f/∂x is not finite (√x of an emptying tank at x = 0, the guess every search without
    // a better one starts from) follow the flow x' = f instead: towards a stable equilibrium it
    // lowers ‖f‖, and a few steps reach states where Newton's step is defined.
    if (dx.size() != nx || !dx.allFinite()) dx = fx;
    // Backtracking: piecewise-smooth physics (stops, saturations) can overshoot a kink.
    double step = 1.0;
    bool improved = false;
    for (int b = 0; b < 30; ++b, step *= 0.5) {
      xt = xv + step * dx;
      const double fnt = eval(xt, ft);
      if (fnt < fn) {
        xv = xt;
        fx = ft;
        fn = fnt;
        improved = true;
        break;
      }
    }
    if (!improved) break;
  }
  res.residual = fn;
  res.converged = fn <= target;
  for (int i = 0; i < nx; ++i) x[i] = xv[i];
  return res;
}

/// Initial-state guess for a record that starts with output `y0` and input `u0`: the physics'
/// `initial_state` hook when it has one and y0 is finite, else the equilibrium for u0 held when
/// Newton from zero finds one, else zero. The start of every equilibrium search of a record, so
/// that estimation and simulation settle on the same equilibrium where there are several (a
/// free position, several stable levels).
template <Physics P>
void physics_initial_guess(const P& phys, const double* y0, const double* u0, const double* p, double* x0) {
  const int nx = detail::physics_states(phys);
  if constexpr (detail::HasInitialStateHook<P>) {
    const int ny = detail::physics_outputs(phys);
    bool finite = true;
    for (int j = 0; j < ny; ++j) finite = finite && std::isfinite(y0[j]);
    if (finite && phys.initial_state(y0, u0, p, x0)) return;
  }
  for (int i = 0; i < nx; ++i) x0[i] = 0.0;
  Eigen::VectorXd xe = Eigen::VectorXd::Zero(nx);
  if (physics_equilibrium(phys, u0, p, xe.data()).converged) {
    for (int i = 0; i < nx; ++i) x0[i] = xe[i];
  }
}

/// One Newton step in Dual arithmetic from a converged equilibrium x̄ (double), giving
/// x̄(p) with exact first-order sensitivities to the dual parameters `p`:
/// x = x̄ − J⁻¹ f(x̄, u, p), J = ∂f/∂x at x̄ (implicit function theorem). `jinv` is J⁻¹ (n_x × n_x,
/// column-major) and `x_out` receives n_x duals. `work` must hold n_x duals.
template <class D, Physics P>
void equilibrium_sensitivity_step(const P& phys, const double* xbar, const D* u, const D* p,
                                  const double* jinv, D* work, D* x_out) {
  const int nx = detail::physics_states(phys);
  for (int i = 0; i < nx; ++i) x_out[i] = D(xbar[i]);
  phys.derivative(x_out, u, p, work);
  for (int i = 0; i < nx; ++i) {
    D acc(xbar[i]);
    for (int l = 0; l < nx; ++l) acc -= jinv[i + static_cast<std::ptrdiff_t>(l) * nx] * work[l];
    x_out[i] = acc;
  }
}

}  // namespace nlid
