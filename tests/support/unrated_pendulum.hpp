// The pendulum of docs/greybox.md as the sub-step tests need it: no spectral_radius, and a
// Jacobian whose size depends on the angle — |∂f/∂x| (Gershgorin) is max(1, c) released
// horizontal and g/L + c hanging down, so a sub-step count judged at the start alone is too few.
#pragma once

#include <array>
#include <cmath>

#include "nlid/models/greybox_concepts.hpp"

namespace nlid_test {

struct UnratedPendulum {
  static constexpr int num_states = 2, num_inputs = 1, num_outputs = 1, num_params = 3;
  std::array<nlid::ParameterInfo, 3> parameter_info() const {
    return {{{"g_l", "1/s^2", "gravity / length", 10.0, 0.0, INFINITY, 1, 100, true, false},
             {"c", "1/s", "damping", 0.5, 0.0, INFINITY, 0.05, 5, true, false},
             {"b", "{y}/({u}*s^2)", "input gain", 1.0, -INFINITY, INFINITY, 0.2, 5, true, false}}};
  }
  template <class T>
  void derivative(const T* x, const T* u, const T* p, T* dx) const {
    using std::sin;
    dx[0] = x[1];
    dx[1] = -p[0] * sin(x[0]) - p[1] * x[1] + p[2] * u[0];
  }
  template <class T>
  void output(const T* x, const T*, const T*, T* y) const {
    y[0] = x[0];
  }
};

}  // namespace nlid_test
