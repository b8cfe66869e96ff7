#pragma once
// The throttle study's grey-box equation with four parameters, shared by the tests
// (tests/core/batch_test.cpp, tests/nomalloc/perf_nomalloc_test.cpp) and the benchmarks
// (benchmarks/perf_models.hpp), so they all exercise one definition:
//
//     y'' + c·y' + k·y + K·(max(y, 90) − 90 + min(y, 15) − 15) = b·u,   θ = [c, k, K, b],
//
// states [y, y'], stops fixed at 15° and 90° (exact kinks). Branch-free (max/min), so it runs on
// double, Dual and Batch alike. The library's catalogue model with estimated stops and spring
// rest is nlid/models/physics/throttle.hpp.

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>

#include "nlid/models/greybox_concepts.hpp"

namespace nlid_test {

struct StudyThrottle {
  static constexpr int num_states = 2;
  static constexpr int num_inputs = 1;
  static constexpr int num_outputs = 1;
  static constexpr int num_params = 4;
  std::string name() const { return "study_throttle"; }
  std::array<nlid::ParameterInfo, 4> parameter_info() const {
    constexpr double inf = std::numeric_limits<double>::infinity();
    return {{{"c", "1/s", "damping", 25.0, 0.0, inf},
             {"k", "1/s^2", "spring", 120.0, 0.0, inf},
             {"K", "1/s^2", "stop stiffness", 1.5e4, 0.0, inf},
             {"b", "deg/s^2", "input gain", 9000.0, -inf, inf}}};
  }
  template <class T>
  void derivative(const T* x, const T* u, const T* p, T* dx) const {
    using std::max;
    using std::min;
    const T stop = max(x[0], T(90.0)) - 90.0 + min(x[0], T(15.0)) - 15.0;
    dx[0] = x[1];
    dx[1] = p[3] * u[0] - p[0] * x[1] - p[1] * x[0] - p[2] * stop;
  }
  template <class T>
  void output(const T* x, const T* /*u*/, const T* /*p*/, T* y) const {
    y[0] = x[0];
  }
  // Bounds the sub-step count the integrator chooses (stiff stops).
  double spectral_radius(const double* p) const { return std::max(std::abs(p[0]), std::sqrt(std::abs(p[1]) + std::abs(p[2]))); }
};

}  // namespace nlid_test
