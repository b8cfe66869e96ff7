#pragma once
/// @file
/// Catalogue physics `rigid_body`: a free mass (a cart, a spindle, a conveyor, a rotor without a
/// return spring) driven by an actuator, with viscous friction and an input offset.
///
/// Model (normalised by the mass):
///
///     ÿ = −c·ẏ + b·(u − u_offset)
///
/// States x = [y, ẏ]; output y (position); input u. The body is a double integrator with a
/// friction pole at −c: commanded at a constant u, its speed settles at (b/c)·(u − u_offset) and
/// its position ramps. u_offset is the command that holds it still (gravity or bias compensation,
/// an amplifier offset), in input units.
///
/// | parameter | meaning                                   | unit          |
/// | --------- | ----------------------------------------- | ------------- |
/// | c         | viscous friction per mass                 | 1/s           |
/// | b         | input gain per mass                       | {y}/({u}·s²)  |
/// | u_offset  | input that produces no acceleration       | {u}           |
///
/// There is no equilibrium unless u = u_offset, so `InitialCondition::equilibrium` reports an
/// error for other inputs. Stiffness bound: |λ| ≤ c. Initialisation: a first-order ARX fit on the
/// sampled velocity Δy/T_s: v_t = a·v_{t−1} + β·u_{t−1} + δ gives c = −ln(a)/T_s,
/// b = β·c/(1 − a), u_offset = −δ/β.

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include "nlid/ad/dual.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/models/greybox_concepts.hpp"
#include "nlid/models/greybox_init.hpp"

namespace nlid::physics {

/// Double integrator with viscous friction, input gain and input offset. Parameters
/// [c, b, u_offset]; states [y, ẏ].
struct RigidBody {
  static constexpr int num_states = 2;   ///< position, velocity
  static constexpr int num_inputs = 1;   ///< force command
  static constexpr int num_outputs = 1;  ///< position
  static constexpr int num_params = 3;   ///< c, b, u_offset

  /// Catalogue name.
  [[nodiscard]] std::string name() const { return "rigid_body"; }
  /// The equation, in the parameter names.
  [[nodiscard]] std::string equation() const { return "y'' = -c*y' + b*(u - u_offset)"; }

  /// Parameter metadata (unit-free defaults: friction pole at 1 rad/s, unit gain).
  [[nodiscard]] std::array<ParameterInfo, num_params> parameter_info() const {
    constexpr double inf = std::numeric_limits<double>::infinity();
    return {{
        {"c", "1/s", "viscous friction / mass", 1.0, 0.0, inf, 0.1, 10.0, true, false},
        {"b", "{y}/({u}*s^2)", "input gain / mass", 1.0, -inf, inf, 0.2, 5.0, true, false},
        {"u_offset", "{u}", "input producing no acceleration", 0.0, -inf, inf, -0.1, 0.1, false,
         false},
    }};
  }

  /// State metadata.
  [[nodiscard]] std::array<StateInfo, num_states> state_info() const {
    return {{{"y", "{y}", "position"}, {"v", "{y}/s", "velocity"}}};
  }

  /// ẋ = f(x, u, p).
  template <class T>
  void derivative(const T* x, const T* u, const T* p, T* dx) const {
    dx[0] = x[1];
    dx[1] = p[1] * (u[0] - p[2]) - p[0] * x[1];
  }

  /// y = position.
  template <class T>
  void output(const T* x, const T* /*u*/, const T* /*p*/, T* y) const {
    y[0] = x[0];
  }

  /// |λ| ≤ c.
  [[nodiscard]] double spectral_radius(const double* p) const { return std::abs(p[0]); }

  /// At the first measured position, at rest.
  bool initial_state(const double* y0, const double* /*u0*/, const double* /*p*/, double* x0) const {
    x0[0] = y0[0];
    x0[1] = 0.0;
    return true;
  }

  /// Data-driven values from a first-order fit of the sampled velocity (see the file comment).
  void initialize(const Dataset& data, std::span<ParameterInfo> p) const {
    // Velocity records as a derived data set (same inputs, Δy/T_s as output).
    const double ts = data.ts();
    Dataset vel;
    for (const Experiment& e : data) {
      if (e.size() < 3) continue;
      const Eigen::Index n = e.size() - 1;
      Eigen::MatrixXd v = (e.y().bottomRows(n).col(0) - e.y().topRows(n).col(0)) / ts;
      Eigen::MatrixXd uu = e.u().topRows(n).leftCols(1);
      if (!v.allFinite() || !uu.allFinite()) continue;
      vel.add(Experiment(std::move(uu), std::move(v), ts));
    }
    if (vel.size() == 0) return;
    const LinearResponse fit = fit_first_order(vel, 0, 0);
    if (!fit.ok || fit.gain == 0.0) return;
    const double c = fit.c;
    const double b = fit.gain * c;           // steady speed (b/c)(u − u_off): gain = b/c
    const double u_off = -fit.offset / fit.gain;  // offset = −gain·u_off
    const Eigen::VectorXd u = pooled(data, Channel::input, 0);
    const double urange = std::max(quantile(u, 0.995) - quantile(u, 0.005), 1e-12);
    set_start(p[0], c, c / 10.0, c * 10.0, true);
    set_start(p[1], b, b / 5.0, b * 5.0, true);
    set_start(p[2], u_off, u_off - 0.1 * urange, u_off + 0.1 * urange, false);
  }
};

}  // namespace nlid::physics
