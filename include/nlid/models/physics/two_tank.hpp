#pragma once
/// @file
/// Catalogue physics `two_tank`: two cascaded tanks draining by gravity through orifices
/// (Torricelli's law), a pump filling the upper one, the lower tank's level measured.
///
/// Model (levels h₁, h₂; Torricelli outflow a·√(2 g h) with the constant 2g folded into aᵢ):
///
///     ḣ₁ = b·u − a₁·√h₁
///     ḣ₂ = a₁·√h₁ − a₂·√h₂
///     y  = h₂ + offset
///
/// States x = [h₁, h₂]; output y; input u (pump command). At a constant command ū the levels
/// settle at h₁ = (b ū / a₁)², h₂ = (b ū / a₂)²; linearised about a level h the tank's time
/// constant is 2√h / a. (Åström & Östberg, "A teaching laboratory for process control",
/// IEEE Control Systems Magazine 6(5), 1986; Johansson, "The quadruple-tank process", IEEE TCST
/// 8(3), 2000, eq. 1.)
///
/// | parameter | meaning                                   | unit          |
/// | --------- | ----------------------------------------- | ------------- |
/// | b         | pump gain per tank area                   | {y}/({u}·s)   |
/// | a1        | upper-tank outflow coefficient            | {y}^0.5/s     |
/// | a2        | lower-tank outflow coefficient            | {y}^0.5/s     |
/// | offset    | level sensor reading at an empty tank     | {y} (fixed 0 by default) |
///
/// √h has an infinite slope at h = 0, which would give infinite sensitivities and an unbounded
/// stiffness when a tank runs dry. The model uses q(h) = h / (h² + ε²)^¼, equal to √h to a
/// relative 10⁻⁶ for h > 10³ ε, smooth through 0 (slope 1/√ε) and odd, so an overshoot below
/// empty drains back instead of producing a NaN. ε = `epsilon` (default 10⁻⁸ level units).
///
/// Initialisation: the mean level ȳ and mean command ū fix the steady-state ratio b/a₂ = √ȳ / ū;
/// a first-order ARX fit gives the overall time constant τ, split evenly between equal tanks
/// (a₁ = a₂ = 4√ȳ / τ).

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

/// Cascade of two Torricelli tanks, pump input, lower-tank level output. Parameters
/// [b, a1, a2, offset]; states [h1, h2].
struct TwoTank {
  static constexpr int num_states = 2;   ///< upper level, lower level
  static constexpr int num_inputs = 1;   ///< pump command
  static constexpr int num_outputs = 1;  ///< lower level
  static constexpr int num_params = 4;   ///< b, a1, a2, offset

  /// Regularisation level of the square root (see the file comment), in level units.
  double epsilon = 1e-8;

  /// Catalogue name.
  [[nodiscard]] std::string name() const { return "two_tank"; }
  /// The equation, in the parameter names.
  [[nodiscard]] std::string equation() const {
    return "h1' = b*u - a1*sqrt(h1);  h2' = a1*sqrt(h1) - a2*sqrt(h2);  y = h2 + offset";
  }

  /// Parameter metadata (unit-free defaults: levels ~1, time constants ~ seconds).
  [[nodiscard]] std::array<ParameterInfo, num_params> parameter_info() const {
    constexpr double inf = std::numeric_limits<double>::infinity();
    return {{
        {"b", "{y}/({u}*s)", "pump gain / tank area", 1.0, -inf, inf, 0.2, 5.0, true, false},
        {"a1", "{y}^0.5/s", "upper-tank outflow coefficient", 1.0, 0.0, inf, 0.2, 5.0, true, false},
        {"a2", "{y}^0.5/s", "lower-tank outflow coefficient", 1.0, 0.0, inf, 0.2, 5.0, true, false},
        {"offset", "{y}", "sensor reading at empty tank", 0.0, -inf, inf, -0.1, 0.1, false, true},
    }};
  }

  /// State metadata.
  [[nodiscard]] std::array<StateInfo, num_states> state_info() const {
    return {{{"h1", "{y}", "upper-tank level"}, {"h2", "{y}", "lower-tank level"}}};
  }

  /// Regularised square root q(h) = h / (h² + ε²)^¼ (see the file comment).
  template <class T>
  T root(const T& h) const {
    const T e2 = T(epsilon * epsilon);
    return h / sqrt(sqrt(h * h + e2));
  }

  /// ẋ = f(x, u, p).
  template <class T>
  void derivative(const T* x, const T* u, const T* p, T* dx) const {
    const T q1 = p[1] * root(x[0]);
    dx[0] = p[0] * u[0] - q1;
    dx[1] = q1 - p[2] * root(x[1]);
  }

  /// y = h2 + offset.
  template <class T>
  void output(const T* x, const T* /*u*/, const T* p, T* y) const {
    y[0] = x[1] + p[3];
  }

  /// Linearised stiffness a/(2√h) is unbounded at an empty tank: report "unknown" (0), so the
  /// sub-step floor applies; choose `IntegratorOptions::min_substeps` or the adaptive method
  /// for records that drain a tank.
  [[nodiscard]] double spectral_radius(const double* /*p*/) const { return 0.0; }

  /// Levels in the steady-state ratio h1/h2 = (a2/a1)², lower level from the measurement.
  bool initial_state(const double* y0, const double* /*u0*/, const double* p, double* x0) const {
    const double h2 = std::max(y0[0] - p[3], 0.0);
    const double r = p[1] != 0.0 ? p[2] / p[1] : 1.0;
    x0[0] = h2 * r * r;
    x0[1] = h2;
    return true;
  }

  /// Data-driven values and multi-start ranges (see the file comment).
  void initialize(const Dataset& data, std::span<ParameterInfo> p) const {
    const Eigen::VectorXd y = pooled(data, Channel::output, 0);
    const Eigen::VectorXd u = pooled(data, Channel::input, 0);
    if (y.size() < 10 || u.size() < 10) return;
    const double level = y.mean() - p[3].value, ubar = u.mean();
    if (!(level > 0.0) || ubar == 0.0) return;
    const LinearResponse fit = fit_first_order(data, 0, 0);
    const double tau = fit.ok ? fit.tau : 20.0 * data.ts();
    const double a = 4.0 * std::sqrt(level) / tau;
    const double b = a * std::sqrt(level) / ubar;
    set_start(p[0], b, b / 5.0, b * 5.0, true);
    set_start(p[1], a, a / 5.0, a * 5.0, true);
    set_start(p[2], a, a / 5.0, a * 5.0, true);
  }
};

}  // namespace nlid::physics
