#pragma once
/// @file
/// Linearisation of nonlinear models about an operating point (the toolbox's `linearize`),
/// exact through dual numbers.
///
/// Every nlid model is a sampled state-space map (x the model's state, u the input):
///
///     x(t+1) = Φ(x(t), u(t)),      y(t) = H(x(t), u(t)).
///
/// About an operating point (x₀, u₀) with y₀ = H(x₀, u₀), the deviations δx = x − x₀,
/// δu = u − u₀, δy = y − y₀ obey to first order (Khalil 2002, Sec. 2.3; Ljung 1999, Sec. 5.1)
///
///     δx(t+1) = A δx(t) + B δu(t) + (Φ(x₀, u₀) − x₀),      δy(t) = C δx(t) + D δu(t),
///     A = ∂Φ/∂x,  B = ∂Φ/∂u,  C = ∂H/∂x,  D = ∂H/∂u   (at x₀, u₀).
///
/// At an equilibrium Φ(x₀, u₀) = x₀ and the drift term vanishes; on a trajectory it is
/// `Linearization::drift`. A, B, C, D are computed by forward-mode AD (`Dual<double, 8>`, seeded
/// in chunks of 8 of the n_x + n_u variables), so they are exact to rounding — not finite
/// differences — and they are the derivatives of exactly the map nlid simulates.
///
/// The state of each model kind:
///  - Nonlinear ARX: the lag window x(t) = [y(t−1) … y(t−Ly), u₁(t−1) … u₁(t−Lu), u₂(t−1) …]
///    (`Nlarx::state_dimension`, the layout of its x0). This is the toolbox's state definition
///    for idnlarx (the delayed outputs and inputs the regressors read). Φ shifts the window and
///    puts ŷ(t) = F(φ(t)) in front, so A is a companion-like matrix whose first row is ∂F/∂y(t−k).
///    The realisation is not minimal when regressors skip lags (unused states give poles at 0).
///  - Hammerstein–Wiener: the linear block's state (transposed direct form II); A, B, C, D are
///    the block's matrices scaled by f′(u₀) (inputs) and h′(x₀) (output), so with unit-gain maps
///    the result is exactly the block B/F.
///  - Grey box: the physical state. Φ is one sample of the zero-order-hold integration nlid uses
///    (same method, same sub-steps), so A ≈ e^{A_c T_s} to the integrator's accuracy, and the
///    continuous-time linearisation A_c = ∂f/∂x, B_c = ∂f/∂u, C = ∂g/∂x, D = ∂g/∂u is returned
///    too (`Linearization::continuous`).
///
/// Operating points: `linearize(model, x0, u0)` at any point (e.g. a state on a simulated
/// trajectory, see `trajectory_state`); `linearize_at_equilibrium(model, u0)` at the steady
/// state of a constant input (models/equilibrium.hpp). The discrete result is an
/// `nlid::StateSpace` (linear/state_space.hpp): poles, frequency response, simulation, transfer
/// function are available on it.

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>

#include "nlid/ad/dual.hpp"
#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/core/initial_condition.hpp"
#include "nlid/data/experiment.hpp"
#include "nlid/linear/state_space.hpp"
#include "nlid/models/equilibrium.hpp"
#include "nlid/models/greybox.hpp"
#include "nlid/models/greybox_simulate.hpp"
#include "nlid/models/hammerstein_wiener.hpp"
#include "nlid/models/integrators.hpp"
#include "nlid/models/nlarx.hpp"

namespace nlid {

/// Continuous-time linearisation ẋ ≈ A δx + B δu, δy = C δx + D δu of a grey-box model.
struct ContinuousLinearization {
  Eigen::MatrixXd a;  ///< ∂f/∂x (n_x × n_x)
  Eigen::MatrixXd b;  ///< ∂f/∂u (n_x × n_u)
  Eigen::MatrixXd c;  ///< ∂g/∂x (n_y × n_x)
  Eigen::MatrixXd d;  ///< ∂g/∂u (n_y × n_u)
  /// Eigenvalues of A (continuous poles, 1/s).
  [[nodiscard]] Eigen::VectorXcd poles() const {
    return a.rows() ? Eigen::VectorXcd(Eigen::EigenSolver<Eigen::MatrixXd>(a, false).eigenvalues()) : Eigen::VectorXcd();
  }
};

/// Result of `linearize`: the discrete linear model of the deviations and the point it holds at.
struct Linearization {
  StateSpace discrete;          ///< δx(t+1) = A δx + B δu, δy = C δx + D δu (sample time of the model)
  std::optional<ContinuousLinearization> continuous;  ///< grey-box models only
  OperatingPoint point;         ///< (x₀, u₀, y₀)
  Eigen::VectorXd drift;        ///< Φ(x₀, u₀) − x₀: zero at an equilibrium
  std::vector<std::string> state_names;  ///< one per state (e.g. "y1(t-1)", "v")

  /// True if the point is an equilibrium (‖drift‖∞ ≤ 1e-9·(1 + ‖x₀‖∞)).
  [[nodiscard]] bool at_equilibrium() const {
    const double scale = 1.0 + (point.x.size() ? point.x.cwiseAbs().maxCoeff() : 0.0);
    return drift.size() == 0 || drift.cwiseAbs().maxCoeff() <= 1e-9 * scale;
  }

  /// Operating point, matrices, discrete (and continuous) poles and the static gain, as text.
  [[nodiscard]] std::string describe() const {
    auto num = [](double v) { return detail::format_g(v, 6); };
    auto vec = [&](const Eigen::VectorXd& v) {
      std::string s = "[";
      for (Eigen::Index i = 0; i < v.size(); ++i) s += (i ? ", " : "") + num(v(i));
      return s + "]";
    };
    auto mat = [&](const char* name, const Eigen::MatrixXd& m) {
      std::string s = std::string("  ") + name + " =\n";
      for (Eigen::Index i = 0; i < m.rows(); ++i) s += "    " + vec(m.row(i).transpose()) + "\n";
      return s;
    };
    auto cplx = [&](const Eigen::VectorXcd& p) {
      std::string s;
      for (Eigen::Index i = 0; i < p.size(); ++i) {
        s += (i ? ", " : "") + num(p(i).real());
        if (std::abs(p(i).imag()) > 1e-12 * (1.0 + std::abs(p(i).real())))
          s += (p(i).imag() < 0 ? " - " : " + ") + num(std::abs(p(i).imag())) + "i";
      }
      return s;
    };
    std::string s = "Linearisation at x0 = " + vec(point.x) + ", u0 = " + vec(point.u) + ", y0 = " + vec(point.y) +
                    (at_equilibrium() ? " (equilibrium)" : " (not an equilibrium: drift " + vec(drift) + ")") + "\n";
    if (!state_names.empty()) {
      s += "  states: ";
      for (std::size_t i = 0; i < state_names.size(); ++i) s += (i ? ", " : "") + state_names[i];
      s += "\n";
    }
    s += "  discrete, ts = " + num(discrete.ts()) + " s:\n";
    s += mat("A", discrete.a()) + mat("B", discrete.b()) + mat("C", discrete.c()) + mat("D", discrete.d());
    s += "  discrete poles: " + cplx(discrete.poles()) + "\n";
    if (discrete.order() > 0 && (Eigen::MatrixXd::Identity(discrete.order(), discrete.order()) - discrete.a()).fullPivLu().isInvertible()) {
      // One row per output (columns: inputs); a single output keeps the one-line form.
      const Eigen::MatrixXd gain = discrete.dc_gain();
      if (gain.rows() == 1) {
        s += "  static gain dy/du: " + vec(Eigen::VectorXd(gain.row(0).transpose())) + "\n";
      } else {
        s += "  static gain dy/du (one row per output, one column per input):\n";
        for (Eigen::Index i = 0; i < gain.rows(); ++i)
          s += "    y" + std::to_string(i + 1) + ": " + vec(Eigen::VectorXd(gain.row(i).transpose())) + "\n";
      }
    }
    if (continuous) {
      s += "  continuous:\n" + mat("A", continuous->a) + mat("B", continuous->b) + mat("C", continuous->c) +
           mat("D", continuous->d);
      s += "  continuous poles (1/s): " + cplx(continuous->poles()) + "\n";
    }
    return s;
  }
};

namespace detail {

/// The AD scalar of linearisation: 8 directions per pass (the runtime grey box's chunk width,
/// so run-time physics evaluate on it too).
using LinDual = Dual<double, 8>;

/// Jacobian of `map(const LinDual* z, LinDual* out)` (n_in → n_out) at z0, in chunks of 8
/// seeded variables; also returns the value.
template <class Map>
void chunked_jacobian(const Eigen::VectorXd& z0, int n_out, Map&& map, Eigen::MatrixXd& jac, Eigen::VectorXd& value) {
  constexpr int W = LinDual::num_derivatives;
  const auto n_in = static_cast<int>(z0.size());
  jac.setZero(n_out, n_in);
  value.resize(n_out);
  std::vector<LinDual> z(static_cast<std::size_t>(n_in)), out(static_cast<std::size_t>(n_out));
  for (int c0 = 0; c0 < std::max(n_in, 1); c0 += W) {
    for (int j = 0; j < n_in; ++j)
      z[static_cast<std::size_t>(j)] = (j >= c0 && j < c0 + W) ? LinDual::variable(z0(j), j - c0) : LinDual(z0(j));
    map(z.data(), out.data());
    for (int i = 0; i < n_out; ++i) {
      const LinDual& o = out[static_cast<std::size_t>(i)];
      value(i) = o.a;
      for (int j = c0; j < std::min(n_in, c0 + W); ++j) jac(i, j) = o.v[j - c0];
    }
  }
  require(jac.allFinite() && value.allFinite(),
          "linearize: the model is not differentiable (non-finite value or derivative) at the operating point",
          at_parameter("x0"));
}

/// Lag window over explicit state and input arrays: y(k) = x[k−1], u(c, 0) = u[c],
/// u(c, k) = x[Ly + c·Lu + k − 1] — the `Nlarx` state layout.
template <class T>
class StateLagWindow {
 public:
  using Scalar = T;
  StateLagWindow(const T* x, const T* u, int ly, int lu) : x_(x), u_(u), ly_(ly), lu_(lu) {}
  [[nodiscard]] T y(int lag) const { return x_[lag - 1]; }
  [[nodiscard]] T u(int channel, int lag) const {
    return lag == 0 ? u_[channel] : x_[ly_ + channel * lu_ + lag - 1];
  }

 private:
  const T* x_;
  const T* u_;
  int ly_, lu_;
};

/// One step of an Nlarx on scalar T from state x and input u: returns ŷ(t), writes x(t+1).
template <class T, class R, class F>
T nlarx_step(const Nlarx<R, F>& m, const T* x, const T* u, std::span<const T> theta, T* x_next) {
  const int ly = m.output_lag(), lu = m.input_lag(), nu = m.num_inputs();
  StateLagWindow<T> w(x, u, ly, lu);
  std::vector<T> phi(static_cast<std::size_t>(m.regressors().size()));
  m.regressors().evaluate(w, std::span<T>(phi));
  const T y = m.template evaluate<T>(std::span<const T>(phi), theta);
  if (ly > 0) {
    x_next[0] = y;
    for (int k = 1; k < ly; ++k) x_next[k] = x[k - 1];
  }
  for (int c = 0; c < nu; ++c) {
    if (lu == 0) continue;
    x_next[ly + c * lu] = u[c];
    for (int k = 1; k < lu; ++k) x_next[ly + c * lu + k] = x[ly + c * lu + k - 1];
  }
  return y;
}

/// Names of the Nlarx lag-window states.
template <class R, class F>
std::vector<std::string> nlarx_state_names(const Nlarx<R, F>& m) {
  std::vector<std::string> n;
  for (int k = 1; k <= m.output_lag(); ++k) n.push_back(m.output_name() + "(t-" + std::to_string(k) + ")");
  for (int c = 0; c < m.num_inputs(); ++c) {
    const std::string un = c < static_cast<int>(m.input_names().size()) ? m.input_names()[static_cast<std::size_t>(c)]
                                                                         : "u" + std::to_string(c + 1);
    for (int k = 1; k <= m.input_lag(); ++k) n.push_back(un + "(t-" + std::to_string(k) + ")");
  }
  return n;
}

/// Splits a stacked Jacobian of [y; x_next] w.r.t. [x; u] into a StateSpace.
inline StateSpace split_state_space(const Eigen::MatrixXd& J, int ny, int nx, int nu, double ts) {
  return StateSpace(J.block(ny, 0, nx, nx), J.block(ny, nx, nx, nu), J.block(0, 0, ny, nx), J.block(0, nx, ny, nu), ts);
}

// A NaN in the operating point would come back as "not differentiable at the operating point"
// blaming the state: each part is checked, and named, first.
inline void require_finite_point(const Eigen::VectorXd& x0, const Eigen::VectorXd& u0) {
  for (Eigen::Index i = 0; i < x0.size(); ++i)
    require(std::isfinite(x0[i]), "linearize: state entry x0[" + std::to_string(i) + "] is not finite",
            at_parameter("x0"));
  for (Eigen::Index i = 0; i < u0.size(); ++i)
    require(std::isfinite(u0[i]), "linearize: input u0[" + std::to_string(i) + "] is not finite", at_parameter("u0"));
}

inline void require_ts(double ts, const char* kind) {
  require(ts > 0.0 && std::isfinite(ts),
          std::string("linearize: the ") + kind +
              " model has no sample time (set_ts) and the discrete linear model needs one",
          at_parameter("ts"));
}

/// One zero-order-hold sample of a grey-box physics on scalar T with the model's integrator.
template <class T, class P>
bool greybox_sample(const GreyBox<P>& model, const T* p, const T* u, Eigen::Matrix<T, Eigen::Dynamic, 1>& x, double ts,
                    int substeps) {
  using State = Eigen::Matrix<T, Eigen::Dynamic, 1>;
  const auto& phys = model.physics();
  auto f = [&](const State& s, State& ds) { phys.derivative(s.data(), u, p, ds.data()); };
  const IntegratorOptions& o = model.integrator();
  // Steppers at function scope, as in simulate_physics (GCC 12 reports false use-after-free
  // warnings for Eigen temporaries of steppers scoped inside switch cases).
  Rk4Stepper<State> rk4;
  EulerStepper<State> euler;
  DormandPrinceStepper<State> dopri;
  const int sub = std::max(1, substeps);
  bool ok = true;
  double h_try = 0.0;
  switch (o.method) {
    case IntegratorMethod::rk4:
      ok = rk4.integrate(f, x, ts, sub);
      break;
    case IntegratorMethod::euler:
      for (int i = 0; i < sub && ok; ++i) {
        euler.step(f, x, ts / sub);
        ok = detail::values_finite(x);
      }
      break;
    case IntegratorMethod::dormand_prince:
      ok = dopri.integrate(f, x, ts, h_try, o);
      break;
  }
  return ok;
}

}  // namespace detail

/// Linearisation of a nonlinear ARX model at the lag-window state `x0` (`state_dimension()`
/// values, layout in the file comment) and input `u0` (one value per channel). Throws
/// `nlid::Error` on wrong sizes, a missing sample time or a non-differentiable point.
template <class R, class F>
Linearization linearize(const Nlarx<R, F>& model, const Eigen::VectorXd& x0, const Eigen::VectorXd& u0) {
  const int nx = model.state_dimension(), nu = model.num_inputs();
  require(x0.size() == nx, "linearize: the state has " + std::to_string(nx) + " entries (" +
                               std::to_string(model.output_lag()) + " past outputs, " + std::to_string(model.input_lag()) +
                               " past values per input), got " + std::to_string(x0.size()),
          at_parameter("x0"));
  require(u0.size() == nu, "linearize: the model reads " + std::to_string(nu) + " input(s), got " + std::to_string(u0.size()),
          at_parameter("u0"));
  detail::require_finite_point(x0, u0);
  detail::require_ts(model.ts(), "nonlinear ARX");
  using D = detail::LinDual;
  const std::vector<D> th = detail::cast_parameters<D>(detail::as_const_span(model.parameters()));
  Eigen::VectorXd z(nx + nu);
  z << x0, u0;
  Eigen::MatrixXd J;
  Eigen::VectorXd v;
  detail::chunked_jacobian(z, 1 + nx, [&](const D* zz, D* out) {
    out[0] = detail::nlarx_step<D>(model, zz, zz + nx, std::span<const D>(th), out + 1);
  }, J, v);
  Linearization L;
  L.discrete = detail::split_state_space(J, 1, nx, nu, model.ts());
  L.point = {x0, u0, v.head(1)};
  L.drift = v.tail(nx) - x0;
  L.state_names = detail::nlarx_state_names(model);
  return L;
}

/// Linearisation of a Hammerstein–Wiener model at the linear-block state `x0` and input `u0`.
template <class In, class L, class Out>
Linearization linearize(const HammersteinWiener<In, L, Out>& model, const Eigen::VectorXd& x0, const Eigen::VectorXd& u0) {
  const int nx = model.state_dimension();
  require(x0.size() == nx, "linearize: the linear block has " + std::to_string(nx) + " states, got " +
                               std::to_string(x0.size()),
          at_parameter("x0"));
  require(u0.size() == 1, "linearize: a Hammerstein-Wiener model has one input, got " + std::to_string(u0.size()),
          at_parameter("u0"));
  detail::require_finite_point(x0, u0);
  detail::require_ts(model.ts(), "Hammerstein-Wiener");
  using D = detail::LinDual;
  const std::vector<D> tf = detail::cast_parameters<D>(model.input_parameters());
  const std::vector<D> tl = detail::cast_parameters<D>(model.linear_parameters());
  const std::vector<D> th = detail::cast_parameters<D>(model.output_parameters());
  Eigen::VectorXd z(nx + 1);
  z << x0, u0;
  Eigen::MatrixXd J;
  Eigen::VectorXd v;
  detail::chunked_jacobian(z, 1 + nx, [&](const D* zz, D* out) {
    std::vector<D> s(zz, zz + nx);
    const D w = model.input_nonlinearity()(std::span<const D>(zz + nx, 1), std::span<const D>(tf));
    const D xl = model.linear_block().step(std::span<D>(s), w, std::span<const D>(tl));
    out[0] = model.output_nonlinearity()(std::span<const D>(&xl, 1), std::span<const D>(th));
    for (int i = 0; i < nx; ++i) out[1 + i] = s[static_cast<std::size_t>(i)];
  }, J, v);
  Linearization R;
  R.discrete = detail::split_state_space(J, 1, nx, 1, model.ts());
  R.point = {x0, u0, v.head(1)};
  R.drift = v.tail(nx) - x0;
  for (int i = 0; i < nx; ++i) R.state_names.push_back("s" + std::to_string(i + 1));
  return R;
}

/// Linearisation of a grey-box model at state `x0` and input `u0`; `ts` is the sample time of
/// the discrete model (the grey box itself is continuous). Returns the discrete model of one
/// zero-order-hold sample as nlid simulates it, and the continuous (A, B, C, D).
template <class P>
Linearization linearize(const GreyBox<P>& model, const Eigen::VectorXd& x0, const Eigen::VectorXd& u0, double ts) {
  const int nx = model.state_dimension(), nu = model.input_dimension(), ny = model.output_dimension();
  require(x0.size() == nx, "linearize: the grey-box model has " + std::to_string(nx) + " states, got " +
                               std::to_string(x0.size()),
          at_parameter("x0"));
  require(u0.size() == nu, "linearize: the grey-box model takes " + std::to_string(nu) + " input(s), got " +
                               std::to_string(u0.size()),
          at_parameter("u0"));
  detail::require_finite_point(x0, u0);
  require(ts > 0.0 && std::isfinite(ts), "linearize: sample time must be positive and finite", at_parameter("ts"));
  using D = detail::LinDual;
  const Eigen::VectorXd pv = model.parameters();
  const std::vector<D> p = detail::cast_parameters<D>(std::span<const double>(pv.data(), static_cast<std::size_t>(pv.size())));
  const auto& phys = model.physics();
  const int sub = substeps_for(ts, physics_spectral_radius(phys, pv.data(), x0.data(), u0.data()), model.integrator());
  Eigen::VectorXd z(nx + nu);
  z << x0, u0;
  Eigen::MatrixXd J, Jc;
  Eigen::VectorXd v, vc;
  bool finite = true;
  detail::chunked_jacobian(z, ny + nx, [&](const D* zz, D* out) {
    phys.output(zz, zz + nx, p.data(), out);
    Eigen::Matrix<D, Eigen::Dynamic, 1> x(nx);
    for (int i = 0; i < nx; ++i) x(i) = zz[i];
    finite = detail::greybox_sample<D>(model, p.data(), zz + nx, x, ts, sub) && finite;
    for (int i = 0; i < nx; ++i) out[ny + i] = x(i);
  }, J, v);
  require(finite, "linearize: one sample of the grey-box simulation diverges from the operating point",
          at_parameter("x0"));
  detail::chunked_jacobian(z, ny + nx, [&](const D* zz, D* out) {
    phys.output(zz, zz + nx, p.data(), out);
    phys.derivative(zz, zz + nx, p.data(), out + ny);
  }, Jc, vc);
  Linearization R;
  R.discrete = detail::split_state_space(J, ny, nx, nu, ts);
  ContinuousLinearization c;
  c.a = Jc.block(ny, 0, nx, nx);
  c.b = Jc.block(ny, nx, nx, nu);
  c.c = Jc.block(0, 0, ny, nx);
  c.d = Jc.block(0, nx, ny, nu);
  R.continuous = c;
  R.point = {x0, u0, v.head(ny)};
  R.drift = v.tail(nx) - x0;
  for (const auto& s : model.state_info()) R.state_names.push_back(s.name);
  return R;
}

/// Linearisation at the equilibrium for the constant input `u0` (Nlarx, Hammerstein–Wiener).
/// A grey box needs the sample time too (the overload below); asking `linearize(m, x, u)` here
/// makes a call without it fail at the call, not inside this template.
template <class M>
  requires requires(const M& m, const Eigen::VectorXd& u) {
    equilibrium(m, u);
    linearize(m, u, u);
  }
Linearization linearize_at_equilibrium(const M& model, const Eigen::VectorXd& u0) {
  const OperatingPoint op = equilibrium(model, u0);
  return linearize(model, op.x, op.u);
}

/// Linearisation of a grey-box model at the equilibrium for the constant input `u0`.
template <class P>
Linearization linearize_at_equilibrium(const GreyBox<P>& model, const Eigen::VectorXd& u0, double ts) {
  const OperatingPoint op = equilibrium(model, u0);
  return linearize(model, op.x, op.u, ts);
}

/// State of a nonlinear ARX model at sample `t` of a measured experiment: the measured lag
/// window (a point on the recorded trajectory). Use with `linearize(model, x, e.u().row(t))`, so
/// t < N (the lag window itself would exist at t = N, but not the input row it is used with).
template <class R, class F>
Eigen::VectorXd trajectory_state(const Nlarx<R, F>& model, const Experiment& e, Eigen::Index t) {
  require(e.num_outputs() >= 1, "trajectory_state: the experiment has no output", at_parameter("e"));
  require(t >= 0 && t < e.size(), "trajectory_state: sample " + std::to_string(t) + " is outside the experiment (" +
                                      std::to_string(e.size()) + " samples)",
          at_parameter("t"));
  return model.measured_state(e.u(), e.y().col(0), t);
}

/// State of a Hammerstein–Wiener model at sample `t` of its simulation of `e` from `ic`.
template <class In, class L, class Out>
Eigen::VectorXd trajectory_state(const HammersteinWiener<In, L, Out>& model, const Experiment& e, Eigen::Index t,
                                 InitialCondition ic = InitialCondition::zero) {
  require(t >= 0 && t < e.size(), "trajectory_state: sample " + std::to_string(t) + " is outside the experiment (" +
                                      std::to_string(e.size()) + " samples)",
          at_parameter("t"));
  const Eigen::VectorXd x0 = model.initial_state(e, ic);
  const auto tf = model.input_parameters();
  const auto tl = model.linear_parameters();
  std::vector<double> s(x0.data(), x0.data() + x0.size());
  for (Eigen::Index k = 0; k < t; ++k) {
    const double uk = e.u()(k, 0);
    const double w = model.input_nonlinearity()(std::span<const double>(&uk, 1), tf);
    (void)model.linear_block().step(std::span<double>(s), w, tl);
  }
  return Eigen::Map<const Eigen::VectorXd>(s.data(), static_cast<Eigen::Index>(s.size()));
}

/// State of a grey-box model at sample `t` of its simulation of `e` from `ic`.
template <class P>
Eigen::VectorXd trajectory_state(const GreyBox<P>& model, const Experiment& e, Eigen::Index t,
                                 InitialCondition ic = InitialCondition::estimate) {
  require(t >= 0 && t < e.size(), "trajectory_state: sample " + std::to_string(t) + " is outside the experiment (" +
                                      std::to_string(e.size()) + " samples)",
          at_parameter("t"));
  const Eigen::VectorXd x0 = model.initial_state(e, ic);
  const Eigen::VectorXd p = model.parameters();
  Eigen::VectorXd x = x0;
  // The count of the whole record's run, so the state is the one `simulate` passes through.
  const int sub = physics_substeps(model.physics(), model.integrator(), p.data(), x.data(), e.u(), e.ts());
  const Eigen::MatrixXd u = e.u().topRows(t + 1);
  const Eigen::Index got = model.template simulate_with<double>(u, e.ts(), p.data(), x.data(), sub,
                                                                [](Eigen::Index, const double*) {});
  require(got == t + 1, "trajectory_state: the simulation diverges before sample " + std::to_string(t),
          at_parameter("t"));
  return x;
}

}  // namespace nlid
