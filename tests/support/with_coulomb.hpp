// A user's run-time physics as the greybox and codegen tests need it: a baseline chosen at run
// time plus friction F_c·tanh(v / 0.5) on the velocity state, written once as member templates
// (RuntimePhysicsBase), so it evaluates on double, Dual and the code generator's TraceScalar.
#pragma once

#include <limits>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "nlid/models/greybox_dynamic.hpp"

namespace nlid_test {

// A baseline chosen at run time plus viscous-to-Coulomb friction F_c·tanh(v / v_s) on the
// velocity state x[1]: the shape of every "augmented" model of the diagnosis layer.
class WithCoulomb final : public nlid::RuntimePhysicsBase<WithCoulomb> {
 public:
  explicit WithCoulomb(nlid::AnyPhysics base) : base_(std::move(base)) {}
  std::string name() const override { return base_.name() + "+coulomb_friction"; }
  int state_dimension() const override { return base_.state_dimension(); }
  int input_dimension() const override { return base_.input_dimension(); }
  int output_dimension() const override { return base_.output_dimension(); }
  int num_parameters() const override { return base_.num_parameters() + 1; }
  std::vector<nlid::ParameterInfo> parameter_info() const override {
    auto v = base_.parameter_info();
    v.push_back({"Fc", "{y}/s^2", "Coulomb friction / mass", 1.0, 0.0,
                 std::numeric_limits<double>::infinity(), 0.1, 100.0, true, false});
    return v;
  }
  std::vector<nlid::StateInfo> state_info() const override { return base_.state_info(); }
  double spectral_radius(const double* p) const override { return base_.spectral_radius(p); }
  void initialize(const nlid::Dataset& d, std::span<nlid::ParameterInfo> p) const override {
    base_.initialize(d, p.first(static_cast<std::size_t>(base_.num_parameters())));
  }
  bool initial_state(const double* y0, const double* u0, const double* p, double* x0) const override {
    return base_.initial_state(y0, u0, p, x0);
  }
  template <class T>
  void compute_derivative(const T* x, const T* u, const T* p, T* dx) const {
    using std::tanh;
    base_.derivative(x, u, p, dx);
    dx[1] -= p[base_.num_parameters()] * tanh(x[1] / T(0.5));
  }
  template <class T>
  void compute_output(const T* x, const T* u, const T* p, T* y) const {
    base_.output(x, u, p, y);
  }

 private:
  nlid::AnyPhysics base_;
};

}  // namespace nlid_test
