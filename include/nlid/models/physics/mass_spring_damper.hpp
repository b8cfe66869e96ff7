#pragma once
/// @file
/// Catalogue physics `mass_spring_damper`: a linear second-order mechanical (or electrical RLC)
/// system driven through an input gain, around a rest position.
///
/// Model (normalised by the mass):
///
///     ÿ + c·ẏ + k·(y − rest) = b·u
///
/// States x = [y, ẏ]; output y; input u. Natural frequency ωₙ = √k, damping ratio ζ = c/(2√k),
/// static gain b/k, and rest = output at u = 0 (a sensor offset or an equilibrium shift).
///
/// | parameter | meaning                            | unit         |
/// | --------- | ---------------------------------- | ------------ |
/// | c         | viscous damping per mass           | 1/s          |
/// | k         | stiffness per mass                 | 1/s²         |
/// | b         | input gain per mass                | {y}/({u}·s²) |
/// | rest      | rest position (output offset)      | {y}          |
///
/// Stiffness bound: |λ| ≤ max(c, √k) (see throttle.hpp). Initialisation: second-order ARX fit on
/// all samples (greybox_init.hpp); multi-start explores a decade around c and k and a factor 5
/// around b.

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <span>
#include <string>

#include "nlid/ad/dual.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/models/greybox_concepts.hpp"
#include "nlid/models/greybox_init.hpp"

namespace nlid::physics {

/// Damped linear oscillator with input gain and rest position. Parameters [c, k, b, rest];
/// states [y, ẏ].
struct MassSpringDamper {
  static constexpr int num_states = 2;   ///< position, velocity
  static constexpr int num_inputs = 1;   ///< force command
  static constexpr int num_outputs = 1;  ///< position
  static constexpr int num_params = 4;   ///< c, k, b, rest

  /// Catalogue name.
  [[nodiscard]] std::string name() const { return "mass_spring_damper"; }
  /// The equation, in the parameter names.
  [[nodiscard]] std::string equation() const { return "y'' + c*y' + k*(y - rest) = b*u"; }

  /// Parameter metadata (unit-free defaults: ωₙ = 10 rad/s, ζ = 1, unit static gain).
  [[nodiscard]] std::array<ParameterInfo, num_params> parameter_info() const {
    constexpr double inf = std::numeric_limits<double>::infinity();
    return {{
        {"c", "1/s", "viscous damping / mass", 20.0, 0.0, inf, 2.0, 200.0, true, false},
        {"k", "1/s^2", "stiffness / mass", 100.0, 0.0, inf, 10.0, 1000.0, true, false},
        {"b", "{y}/({u}*s^2)", "input gain / mass", 100.0, -inf, inf, 20.0, 500.0, true, false},
        {"rest", "{y}", "rest position (output at u = 0)", 0.0, -inf, inf, -1.0, 1.0, false, false},
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
    dx[1] = p[2] * u[0] - p[0] * x[1] - p[1] * (x[0] - p[3]);
  }

  /// y = position.
  template <class T>
  void output(const T* x, const T* /*u*/, const T* /*p*/, T* y) const {
    y[0] = x[0];
  }

  /// Bound on |eig ∂f/∂x|: max(c, √k).
  [[nodiscard]] double spectral_radius(const double* p) const {
    return std::max(std::abs(p[0]), std::sqrt(std::abs(p[1])));
  }

  /// At rest at the first measured position.
  bool initial_state(const double* y0, const double* /*u0*/, const double* /*p*/, double* x0) const {
    x0[0] = y0[0];
    x0[1] = 0.0;
    return true;
  }

  /// Data-driven values and multi-start ranges from a second-order ARX fit.
  void initialize(const Dataset& data, std::span<ParameterInfo> p) const {
    const Eigen::VectorXd y = pooled(data, Channel::output, 0);
    const Eigen::VectorXd u = pooled(data, Channel::input, 0);
    if (y.size() < 10 || u.size() < 10) return;
    const double range = std::max(quantile(y, 0.995) - quantile(y, 0.005), 1e-12);
    const LinearResponse fit = fit_second_order(data, 0, 0);
    double c, k, gain, rest;
    if (fit.ok) {
      c = fit.c;
      k = fit.k;
      gain = fit.gain;
      rest = fit.offset;
    } else {
      const double w = 0.05 / data.ts();
      c = 2.0 * w;
      k = w * w;
      gain = range / std::max(quantile(u, 0.995) - quantile(u, 0.005), 1e-12);
      rest = quantile(y, 0.5);
    }
    const double b = gain * k;
    set_start(p[0], c, c / 10.0, c * 10.0, true);
    set_start(p[1], k, k / 10.0, k * 10.0, true);
    set_start(p[2], b, b / 5.0, b * 5.0, true);
    set_start(p[3], rest, rest - 0.5 * range, rest + 0.5 * range, false);
  }
};

}  // namespace nlid::physics
