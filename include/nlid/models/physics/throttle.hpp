#pragma once
/// @file
/// Catalogue physics `throttle`: an electronic throttle valve, or any positioning mechanism in
/// which a motor drives a load against a return spring between two hard stops.
///
/// Model (normalised by the inertia, as in the throttle study's grey-box model):
///
///     ÿ + c·ẏ + k·(y − rest) + K·(max(y, upper_stop) − upper_stop + min(y, lower_stop) − lower_stop) = b·u
///
/// States x = [y, ẏ]; output y (the position); input u (motor command).
///
/// | parameter    | meaning                                        | unit          |
/// | ------------ | ---------------------------------------------- | ------------- |
/// | c            | viscous damping per inertia                    | 1/s           |
/// | k            | return-spring stiffness per inertia            | 1/s²          |
/// | K            | contact stiffness of the stops per inertia     | 1/s²          |
/// | b            | input gain (motor torque per command / inertia)| {y}/({u}·s²)  |
/// | lower_stop   | position of the lower hard stop                | {y}           |
/// | upper_stop   | position of the upper hard stop                | {y}           |
/// | rest         | spring rest position (preload = k·(stop − rest))| {y}          |
///
/// The study's equation is the special case rest = 0, lower_stop = 15°, upper_stop = 90°; here
/// the stops and the rest position are parameters, initialised from the data, so the model fits
/// a record in any unit (degrees, radians, percent of travel, raw sensor counts). A valve that
/// rests on its lower stop with the motor off has rest < lower_stop: the spring preloads it
/// against the stop with force k·(lower_stop − rest).
///
/// Contact. The stop term is evaluated with `penetration` (contact.hpp): exactly max/min when
/// `contact_smoothing` = 0, and by default smoothed over 10⁻³ of the travel — below a 0.1°
/// sensor's quantisation on a 75° throttle — so that the simulation error is differentiable and
/// Levenberg–Marquardt does not stall where a trajectory grazes a stop.
///
/// Stiffness. In contact the oscillator's eigenvalues are λ = −c/2 ± √(c²/4 − (k + K)), so
/// |λ| ≤ max(c, √(k + K)); `spectral_radius` returns that bound and the integrator sub-steps
/// each sample so that h·|λ| stays inside RK4's stability region (see integrators.hpp).
///
/// The stops must not cross: lower_stop < upper_stop (`check_parameters`). With crossed stops
/// the contact term pushes from both sides at once and the "travel" has negative length, so no
/// value of the other parameters makes the model mean anything; `GreyBox` refuses such values
/// where a set of values is set or used (set_parameters, initialize, simulate, estimate; not
/// set_parameter, which sets one at a time), and estimation never steps to them.
///
/// Initialisation from data (`initialize`): stops where the output is pinned while the input
/// moves (`detect_stop`), otherwise just beyond the data range; c, k, the static gain b/k and the
/// rest position from a second-order ARX fit on the samples between the stops (`fit_second_order`);
/// K = 100·k (contact much stiffer than the spring). Multi-start explores a decade either side of
/// c and k, K in [10, 10⁴]·k, b within a factor 5, stops ±5 % and rest ±50 % of the output range.
/// An input that does not move leaves b (and its range) as it was: the data say nothing about it.

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <span>
#include <string>

#include "nlid/ad/dual.hpp"
#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/models/greybox_concepts.hpp"
#include "nlid/models/greybox_init.hpp"
#include "nlid/models/physics/contact.hpp"

namespace nlid::physics {

/// Throttle valve: spring-loaded, damped, motor-driven positioner with two hard stops.
/// Parameters [c, k, K, b, lower_stop, upper_stop, rest]; states [y, ẏ]. See the file comment.
struct Throttle {
  static constexpr int num_states = 2;   ///< position, velocity
  static constexpr int num_inputs = 1;   ///< motor command
  static constexpr int num_outputs = 1;  ///< position
  static constexpr int num_params = 7;   ///< c, k, K, b, lower_stop, upper_stop, rest

  /// Catalogue name.
  [[nodiscard]] std::string name() const { return "throttle"; }
  /// The equation, in the parameter names.
  [[nodiscard]] std::string equation() const {
    return "y'' + c*y' + k*(y - rest) + K*(max(y, upper_stop) - upper_stop + min(y, lower_stop) - "
           "lower_stop) = b*u";
  }

  /// Parameter metadata with unit-free defaults (travel 0..1); `initialize` rescales to the data.
  [[nodiscard]] std::array<ParameterInfo, num_params> parameter_info() const {
    constexpr double inf = std::numeric_limits<double>::infinity();
    return {{
        {"c", "1/s", "viscous damping / inertia", 20.0, 0.0, inf, 2.0, 200.0, true, false},
        {"k", "1/s^2", "return-spring stiffness / inertia", 100.0, 0.0, inf, 10.0, 1000.0, true, false},
        {"K", "1/s^2", "hard-stop contact stiffness / inertia", 1e4, 0.0, inf, 1e3, 1e6, true, false},
        {"b", "{y}/({u}*s^2)", "input gain / inertia", 100.0, -inf, inf, 20.0, 500.0, true, false},
        {"lower_stop", "{y}", "lower hard-stop position", 0.0, -inf, inf, -0.05, 0.05, false, false},
        {"upper_stop", "{y}", "upper hard-stop position", 1.0, -inf, inf, 0.95, 1.05, false, false},
        {"rest", "{y}", "spring rest position (preload against a stop)", 0.0, -inf, inf, -0.5, 0.5,
         false, false},
    }};
  }

  /// State metadata.
  [[nodiscard]] std::array<StateInfo, num_states> state_info() const {
    return {{{"y", "{y}", "position"}, {"v", "{y}/s", "velocity"}}};
  }

  /// Width of the smoothed stop contact as a fraction of the travel upper_stop − lower_stop;
  /// 0 gives the study's exact max/min kinks (see contact.hpp for why the default is not 0).
  double contact_smoothing = 1e-3;

  /// ẋ = f(x, u, p).
  template <class T>
  void derivative(const T* x, const T* u, const T* p, T* dx) const {
    const T& y = x[0];
    // Penetration into either stop, zero between them: max(y, hi) − hi + min(y, lo) − lo.
    const T width = T(contact_smoothing) * abs(p[5] - p[4]);
    const T contact = penetration(T(y - p[5]), width) - penetration(T(p[4] - y), width);
    dx[0] = x[1];
    dx[1] = p[3] * u[0] - p[0] * x[1] - p[1] * (y - p[6]) - p[2] * contact;
  }

  /// y = position.
  template <class T>
  void output(const T* x, const T* /*u*/, const T* /*p*/, T* y) const {
    y[0] = x[0];
  }

  /// Bound on |eig ∂f/∂x| over both regimes (free and in contact): max(c, √(k + K)).
  [[nodiscard]] double spectral_radius(const double* p) const {
    return std::max(std::abs(p[0]), std::sqrt(std::abs(p[1]) + std::abs(p[2])));
  }

  /// Throws `nlid::Error` (at parameter "lower_stop", naming both stops and their values) unless
  /// lower_stop < upper_stop. A box bound per parameter cannot say this.
  void check_parameters(const double* p) const {
    if (!(p[4] < p[5])) {
      throw Error("throttle: lower_stop = " + detail::format_g(p[4]) + " must be below upper_stop = " +
                      detail::format_g(p[5]) + " (" + (p[4] == p[5] ? "equal" : "crossed") +
                      " stops leave no travel between them)",
                  at_parameter("lower_stop"));
    }
  }

  /// Initial-state guess from the first measured sample: at rest at the measured position.
  bool initial_state(const double* y0, const double* /*u0*/, const double* /*p*/, double* x0) const {
    x0[0] = y0[0];
    x0[1] = 0.0;
    return true;
  }

  /// Data-driven values and multi-start ranges (see the file comment).
  void initialize(const Dataset& data, std::span<ParameterInfo> p) const {
    const Eigen::VectorXd y = pooled(data, Channel::output, 0);
    const Eigen::VectorXd u = pooled(data, Channel::input, 0);
    if (y.size() < 10 || u.size() < 10) return;
    const double ylo = quantile(y, 0.005), yhi = quantile(y, 0.995);
    const double range = yhi - ylo > 0.0 ? yhi - ylo : std::max(1.0, std::abs(yhi));
    const double ulo = quantile(u, 0.005), uhi = quantile(u, 0.995);
    const double urange = uhi - ulo;
    // An input that does not move says nothing about the gain b (range / urange was 1e15 for a
    // held command, from a floor in absolute units): b keeps its value then. "Held" includes the
    // rounding a stored command carries (a CSV's 6 significant digits, a float's 7): 1e-5 of
    // its level.
    const bool input_moves = urange > 1e-5 * std::max(std::abs(ulo), std::abs(uhi));
    const StopEstimate lo = detect_stop(data, 0, 0, false), hi = detect_stop(data, 0, 0, true);
    const double band = 0.05 * range;
    const LinearResponse fit = fit_second_order(data, 0, 0, lo.position + band, hi.position - band);
    const double ts = data.ts();
    double c = 0, k = 0, gain = 0, rest = 0;
    if (fit.ok) {
      c = fit.c;
      k = fit.k;
      gain = fit.gain;
      rest = fit.offset;
    } else {
      // No usable linear stretch: a critically damped guess 20 samples wide and the range gain.
      const double w = 0.05 / ts;
      c = 2.0 * w;
      k = w * w;
      gain = input_moves ? range / urange : 0.0;
      rest = lo.position;
    }
    const double b = gain * k;
    set_start(p[0], c, c / 10.0, c * 10.0, true);
    set_start(p[1], k, k / 10.0, k * 10.0, true);
    set_start(p[2], 100.0 * k, 10.0 * k, 1e4 * k, true);
    if (fit.ok || input_moves) set_start(p[3], b, b / 5.0, b * 5.0, true);
    set_start(p[4], lo.position, lo.position - band, lo.position + band, false);
    set_start(p[5], hi.position, hi.position - band, hi.position + band, false);
    set_start(p[6], rest, rest - 10.0 * band, rest + 10.0 * band, false);
  }
};

}  // namespace nlid::physics
