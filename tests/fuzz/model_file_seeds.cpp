// Writes the seed model files of the model_file fuzzer (tests/fuzz/seeds/model_file/): one small
// real file per model kind and nonlinearity, made by the library itself. Not built by CMake:
//   clang++ -std=c++20 -O1 -Iinclude -I/usr/include/eigen3 tests/fuzz/model_file_seeds.cpp -o /tmp/seeds
//   /tmp/seeds tests/fuzz/seeds/model_file
#include <cmath>
#include <cstdio>
#include <span>
#include <string>

#include <Eigen/Core>

#include "../support/msd_scales.hpp"
#include "nlid/diagnose/effects.hpp"
#include "nlid/io/augmented_serial.hpp"
#include "nlid/io/series_serial.hpp"
#include "nlid/models/any_model.hpp"
#include "nlid/models/physics/catalogue.hpp"
#include "nlid/nonlinearities.hpp"
#include "nlid/regressors.hpp"

using namespace nlid;

namespace {

Experiment seed_record(int nu, int n = 200) {
  Eigen::MatrixXd u(n, nu), y(n, 1);
  double x = 0;
  for (int k = 0; k < n; ++k) {
    for (int c = 0; c < nu; ++c) u(k, c) = (k / 20 % 2 == 0 ? 1.0 : -0.5) + 0.2 * std::sin(0.1 * k + c);
    x = 0.8 * x + 0.3 * std::tanh(u(k, 0)) + (nu > 1 ? 0.1 * u(k, 1) : 0.0);
    y(k, 0) = x;
  }
  return Experiment(u, y, 0.01, "seed");
}

void seed_nlarx(const std::string& dir, const std::string& name, RegressorList r, AnyNonlinearity f, int nu,
                const ModelFileInfo& info = {}) {
  DynamicNlarx m(std::move(r), std::move(f), 0.01);
  const Experiment e = seed_record(nu);
  const Eigen::MatrixXd X = m.regressor_values(e);
  const Eigen::VectorXd y = e.y().col(0).tail(X.rows());
  Eigen::VectorXd th(m.num_parameters());
  m.nonlinearity().initialize(X, y, std::span<double>(th.data(), static_cast<std::size_t>(th.size())));
  for (Eigen::Index i = 0; i < th.size(); ++i) th(i) = std::round(th(i) * 1000.0) / 1000.0;
  m.set_parameters(th);
  save_model(dir + "/" + name + ".json", m, info);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s <seed directory>\n", argv[0]);
    return 2;
  }
  const std::string dir = argv[1];
  ModelFileInfo stamped;
  stamped.created = "2026-01-01T00:00:00Z";
  auto lagged = [](int na, int nb, int nk) { return RegressorList::lagged(na, nb, nk); };

  seed_nlarx(dir, "nlarx_sigmoidnet", lagged(2, 2, 1), AnyNonlinearity(SigmoidNet<Dynamic, Dynamic, true>(4, 2)), 1, stamped);
  seed_nlarx(dir, "nlarx_sigmoidnet_nolin", lagged(1, 1, 0), AnyNonlinearity(SigmoidNet<Dynamic, Dynamic, false>(2, 2)), 1,
             stamped);
  seed_nlarx(dir, "nlarx_wavenet", lagged(1, 2, 0), AnyNonlinearity(WaveletNet<Dynamic, Dynamic, true>(3, 2)), 1, stamped);
  seed_nlarx(dir, "nlarx_pwlinear", lagged(1, 0, 0), AnyNonlinearity(PwLinear<Dynamic>(4)), 1, stamped);
  seed_nlarx(dir, "nlarx_tree", lagged(1, 1, 1), AnyNonlinearity(TreePartition<Dynamic, Dynamic>(2, 2)), 1, stamped);
  seed_nlarx(dir, "nlarx_linear", lagged(2, 1, 2), AnyNonlinearity(LinearMap<Dynamic>(3)), 1, stamped);
  {
    RegressorList r;
    r.add_output_lags(1);
    r.add_input_lags(1, 0, 0);
    r.add_input_lags(2, 1, 1);
    r.add_custom("u1(t-1)*y1(t-2)", {"u1", "u2"}, "y1");
    ModelFileInfo info = stamped;
    info.input_units = {"V", "A"};
    info.output_units = {"rad"};
    info.input_range = {{-0.7, 1.2}, {-0.7, 1.2}};
    info.output_range = {{-1.0, 1.0}};
    seed_nlarx(dir, "nlarx_two_inputs_custom", r, AnyNonlinearity(SigmoidNet<Dynamic, Dynamic, true>(5, 1)), 2, info);
  }

  using L = TransferFunctionBlock<Dynamic, Dynamic, Dynamic>;
  {
    DynamicHammersteinWiener hw(AnyNonlinearity(PwLinear<Dynamic>(3)), L(2, 2, 1), AnyNonlinearity(Saturation(-1.0, 1.0)),
                                0.01);
    Eigen::VectorXd th(hw.num_parameters());
    th << -0.5, std::log(0.5), std::log(0.5), -0.4, 0.0, 0.4,  // pwlinear
        0.3, 0.1, -1.2, 0.4,                                   // linear
        -0.8, 0.9;                                             // saturation
    hw.set_parameters(th);
    save_model(dir + "/hw_pwlinear_saturation.json", hw, stamped);
  }
  {
    DynamicHammersteinWiener hw(AnyNonlinearity(Poly1d<Dynamic>(2)), L(1, 1, 0), AnyNonlinearity(DeadZone(-0.1, 0.2)), 0.01);
    Eigen::VectorXd th(hw.num_parameters());
    th << 0.1, 1.0, -0.2, 0.4, -0.6, -0.1, 0.2;
    hw.set_parameters(th);
    save_model(dir + "/hw_poly_deadzone.json", hw, stamped);
  }
  {
    DynamicHammersteinWiener hw(AnyNonlinearity(UnitGain{}), L(2, 0, 0), AnyNonlinearity(UnitGain{}), 0.01);
    Eigen::VectorXd th(hw.num_parameters());
    th << 0.5, 0.25;
    hw.set_parameters(th);
    save_model(dir + "/hw_unitgain_fir.json", hw, stamped);
  }

  save_model(dir + "/arx.json", Arx(Eigen::Vector2d(-1.5, 0.7), {Eigen::Vector2d(0.3, 0.1)}, {1}, 0.01, 0.125), stamped);
  save_model(dir + "/oe.json", OutputError({Eigen::Vector2d(0.2, 0.1)}, {Eigen::Vector2d(-1.1, 0.3)}, {0}, 0.01), stamped);
  {
    Eigen::MatrixXd A(2, 2), B(2, 1), C(1, 2), D(1, 1);
    A << 0.9, 0.1, -0.05, 0.8;
    B << 0.25, 0.5;
    C << 1.0, 0.25;
    D << 0.0;
    StateSpace ss(A, B, C, D, 0.01);
    save_model(dir + "/state_space.json", ss, stamped);
  }
  save_model(dir + "/greybox_first_order.json", make_greybox("first_order"), stamped);
  save_model(dir + "/greybox_throttle.json", make_greybox("throttle"), stamped);
  {
    DynamicWienerHammerstein wh(L(1, 1, 0), AnyNonlinearity(PwLinear<Dynamic>(3)), L(1, 1, 1), 0.01);
    Eigen::VectorXd th(wh.num_parameters());
    th << 0.3, -0.5, -0.5, std::log(0.5), std::log(0.5), -0.4, 0.0, 0.4, 0.5, -0.3;
    wh.set_parameters(th);
    save_model(dir + "/series_lnl.json", wh, stamped);
  }
  {
    DynamicHammersteinSeries h(AnyNonlinearity(SigmoidNet<Dynamic, Dynamic, true>(1, 1)), L(1, 1, 1), 0.01);
    Eigen::VectorXd th = Eigen::VectorXd::Constant(h.num_parameters(), 0.25);
    h.set_parameters(th);
    save_model(dir + "/series_nl.json", h, stamped);
  }
  save_model(dir + "/greybox_mass_spring_damper.json", make_greybox("mass_spring_damper"), stamped);
  save_model(dir + "/greybox_two_tank.json", make_greybox("two_tank"), stamped);
  save_model(dir + "/greybox_rigid_body.json", make_greybox("rigid_body"), stamped);
  {
    DynamicHammersteinWienerSeries nln(AnyNonlinearity(Saturation(-1.0, 1.0)), L(1, 1, 0), AnyNonlinearity(Poly1d<Dynamic>(2)),
                                       0.01);
    Eigen::VectorXd th = Eigen::VectorXd::Constant(nln.num_parameters(), 0.25);
    th(0) = -1.0;
    th(1) = 1.0;
    nln.set_parameters(th);
    save_model(dir + "/series_nln.json", nln, stamped);
  }
  {
    // Every effect the diagnosis can add, one file each, on the mass-spring-damper baseline.
    GreyBox<physics::MassSpringDamper> g;
    const DataScales s = nlid_test::msd_effect_scales();
    for (EffectKind k : all_effect_kinds()) {
      const auto c = make_effect_candidates(k, s);
      if (c.empty()) continue;
      AugmentedModel<AnyPhysics> m(make_physics("mass_spring_damper"), g.parameter_info(), 0.01);
      try {
        m.add_effect(c[0].effect);
      } catch (const Error&) {
        continue;
      }
      save_model(dir + "/augmented_msd_" + effect_name(k) + ".json", m, stamped);
    }
  }
  {
    GreyBox<physics::FirstOrder> g;
    AugmentedModel<AnyPhysics> m(make_physics("first_order"), g.parameter_info(), 0.01);
    const DataScales s = nlid_test::msd_effect_scales();
    const auto dz = make_effect_candidates(effect_kind("input_deadzone"), s);
    if (!dz.empty()) m.add_effect(dz[0].effect);
    save_model(dir + "/augmented_first_order.json", m, stamped);
  }
  return 0;
}
