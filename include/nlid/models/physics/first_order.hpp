#pragma once
/// @file
/// Catalogue physics `first_order`: a first-order lag (RC circuit, thermal mass, a motor's
/// speed, a well-mixed tank's concentration) with gain and offset.
///
/// Model:
///
///     τ·ẏ = −(y − offset) + gain·u
///
/// State x = [y]; output y; input u. Step response: y approaches offset + gain·u with time
/// constant τ (63 % after τ).
///
/// | parameter | meaning                              | unit      |
/// | --------- | ------------------------------------ | --------- |
/// | tau       | time constant                        | s         |
/// | gain      | static gain                          | {y}/{u}   |
/// | offset    | output at u = 0 (ambient level)      | {y}       |
///
/// Stiffness bound: |λ| = 1/τ. Initialisation: first-order ARX fit (greybox_init.hpp);
/// multi-start explores a decade around τ and a factor 5 around the gain.

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

/// First-order lag with gain and offset. Parameters [tau, gain, offset]; state [y].
struct FirstOrder {
  static constexpr int num_states = 1;   ///< the lagged output
  static constexpr int num_inputs = 1;   ///< drive
  static constexpr int num_outputs = 1;  ///< the lagged output
  static constexpr int num_params = 3;   ///< tau, gain, offset

  /// Catalogue name.
  [[nodiscard]] std::string name() const { return "first_order"; }
  /// The equation, in the parameter names.
  [[nodiscard]] std::string equation() const { return "tau*y' = -(y - offset) + gain*u"; }

  /// Parameter metadata (unit-free defaults: τ = 1 s, unit gain).
  [[nodiscard]] std::array<ParameterInfo, num_params> parameter_info() const {
    constexpr double inf = std::numeric_limits<double>::infinity();
    return {{
        {"tau", "s", "time constant", 1.0, 1e-9, inf, 0.1, 10.0, true, false},
        {"gain", "{y}/{u}", "static gain", 1.0, -inf, inf, 0.2, 5.0, true, false},
        {"offset", "{y}", "output at u = 0", 0.0, -inf, inf, -1.0, 1.0, false, false},
    }};
  }

  /// State metadata.
  [[nodiscard]] std::array<StateInfo, num_states> state_info() const {
    return {{{"y", "{y}", "lagged output"}}};
  }

  /// ẋ = f(x, u, p).
  template <class T>
  void derivative(const T* x, const T* u, const T* p, T* dx) const {
    dx[0] = (p[1] * u[0] - (x[0] - p[2])) / p[0];
  }

  /// y = x.
  template <class T>
  void output(const T* x, const T* /*u*/, const T* /*p*/, T* y) const {
    y[0] = x[0];
  }

  /// |λ| = 1/τ.
  [[nodiscard]] double spectral_radius(const double* p) const { return 1.0 / std::abs(p[0]); }

  /// The state is the output.
  bool initial_state(const double* y0, const double* /*u0*/, const double* /*p*/, double* x0) const {
    x0[0] = y0[0];
    return true;
  }

  /// Data-driven values and multi-start ranges from a first-order ARX fit.
  void initialize(const Dataset& data, std::span<ParameterInfo> p) const {
    const Eigen::VectorXd y = pooled(data, Channel::output, 0);
    const Eigen::VectorXd u = pooled(data, Channel::input, 0);
    if (y.size() < 10 || u.size() < 10) return;
    const double range = std::max(quantile(y, 0.995) - quantile(y, 0.005), 1e-12);
    const LinearResponse fit = fit_first_order(data, 0, 0);
    double tau, gain, offset;
    if (fit.ok) {
      tau = fit.tau;
      gain = fit.gain;
      offset = fit.offset;
    } else {
      tau = 20.0 * data.ts();
      gain = range / std::max(quantile(u, 0.995) - quantile(u, 0.005), 1e-12);
      offset = quantile(y, 0.5);
    }
    set_start(p[0], tau, tau / 10.0, tau * 10.0, true);
    set_start(p[1], gain, gain / 5.0, gain * 5.0, true);
    set_start(p[2], offset, offset - 0.5 * range, offset + 0.5 * range, false);
  }
};

}  // namespace nlid::physics
