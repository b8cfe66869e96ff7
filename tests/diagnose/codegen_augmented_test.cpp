// Generated C for augmented grey-box models (codegen/augmented.hpp): every effect of the
// catalogue, in three combinations on a mass-spring-damper, is generated, compiled with the
// system C compiler (warnings are errors) and run; the outputs must equal
// AugmentedModel::simulate to 1e-12 relative — from the zero state and from an equilibrium.
// Also: simulate itself, rebuilt from the per-sample members the generator traces, must be
// unchanged (a fixed trajectory checked against values computed before the refactoring).
#include <catch2/catch.hpp>

#include <cmath>
#include <string>
#include <vector>

#include "nlid/codegen/augmented.hpp"
#include "nlid/diagnose.hpp"
#include "nlid/models/physics/mass_spring_damper.hpp"
#include "synth.hpp"
#include "../support/generated_c.hpp"

using namespace nlid;

namespace {

AugmentedModel<physics::MassSpringDamper> msd_with(int variant) {
  const physics::MassSpringDamper msd;
  const double ts = 0.01;
  const DataScales s = diag_test::unit_scales(ts, 1.1);
  const auto info = msd.parameter_info();
  std::vector<ParameterInfo> tab(info.begin(), info.end());
  tab[0].value = 8;
  tab[1].value = 100;
  tab[2].value = 100;
  AugmentedModel<physics::MassSpringDamper> m(msd, tab, ts);
  if (variant == 0) {
    m.add_effect(diag_test::effect(EffectKind::coulomb_friction, {2.0}, s));
    m.add_effect(diag_test::effect(EffectKind::dead_time, {0.023}, s));
    m.add_effect(diag_test::effect(EffectKind::backlash, {0.05}, s));
    m.add_effect(diag_test::effect(EffectKind::actuator_lag, {0.02}, s));
    m.add_effect(diag_test::effect(EffectKind::input_deadzone, {0.1}, s));
  } else if (variant == 1) {
    m.add_effect(diag_test::effect(EffectKind::cubic_stiffness, {30.0, 0.05}, s));
    m.add_effect(diag_test::effect(EffectKind::quadratic_drag, {0.05}, s));
    m.add_effect(diag_test::effect(EffectKind::preload, {5.0, 0.1}, s));
    m.add_effect(diag_test::effect(EffectKind::output_offset, {0.1}, s));
    m.add_effect(diag_test::effect(EffectKind::hard_stop, {0.3, 1e4}, s, "upper"));
    m.add_effect(diag_test::effect(EffectKind::input_saturation, {0.7}, s, "upper"));
    m.add_effect(diag_test::effect(EffectKind::output_saturation, {-0.2}, s, "lower"));
  } else {
    m.add_effect(diag_test::effect(EffectKind::viscous_friction, {3.0}, s));
    m.add_effect(diag_test::effect(EffectKind::input_offset, {0.05}, s));
    m.add_effect(diag_test::effect(EffectKind::dead_time, {0.004}, s));  // under one sample: m = 0
    m.add_effect(diag_test::effect(EffectKind::hard_stop, {-0.4, 2e3}, s, "lower"));
    m.add_effect(diag_test::effect(EffectKind::output_saturation, {0.6}, s, "upper"));
  }
  return m;
}

}  // namespace

TEST_CASE("codegen: augmented grey-box models (every effect) reproduce simulate to 1e-12", "[diagnose][codegen]") {
  for (int variant = 0; variant < 3; ++variant) {
    DYNAMIC_SECTION("effect set " << variant) {
      const auto m = msd_with(variant);
      const Eigen::MatrixXd u = diag_test::random_steps(1500, -1.0, 1.0, 20, 60, 3u + static_cast<unsigned>(variant));
      const Experiment e(u, Eigen::MatrixXd::Zero(u.rows(), 1), m.ts(), "steps");
      CodegenOptions o;
      o.name = "aug";
      const GeneratedCode g = generate_c(m, o);
      CHECK(g.header.find("#define AUG_NUM_STATES") != std::string::npos);
      const Eigen::VectorXd yc = nlid_test::run_generated_c(g, u, "aug" + std::to_string(variant));
      const Eigen::VectorXd yn = m.simulate(e, InitialCondition::zero).col(0);
      REQUIRE(yc.size() == yn.size());
      CHECK(nlid_test::max_relative_error(yc, yn) <= 1e-12);
      // The effects act: the repaired model differs from its baseline by far more than that.
      const AugmentedModel<physics::MassSpringDamper> bare(m.physics(), m.baseline_parameters(), m.ts());
      CHECK(nlid_test::max_relative_error(bare.simulate(e, InitialCondition::zero).col(0), yn) > 1e-3);

      // From the equilibrium of the first input, as simulate(e, equilibrium).
      o.name = "aug_eq";
      o.equilibrium_input = Eigen::VectorXd::Constant(1, u(0, 0));
      const Eigen::VectorXd yce = nlid_test::run_generated_c(generate_c(m, o), u, "aug" + std::to_string(variant) + "eq");
      const Eigen::VectorXd yne = m.simulate(e, InitialCondition::equilibrium).col(0);
      CHECK(nlid_test::max_relative_error(yce, yne) <= 1e-12);
      CHECK(std::abs(yne(0) - yn(0)) > 1e-6);

      // Single precision (FPUs without double): no double in the code, float rounding of simulate.
      o.name = "aug" + std::to_string(variant);
      o.equilibrium_input.reset();
      nlid_test::check_single_precision(m, o, u, yn, 1e-4);
    }
  }
}

TEST_CASE("codegen: an augmented model runs at its own sample time", "[diagnose][codegen]") {
  const auto m = msd_with(2);
  CodegenOptions o;
  o.ts = 0.02;
  try {
    (void)generate_c(m, o);
    FAIL("another sample time was accepted");
  } catch (const Error& err) {
    CHECK_THAT(err.what(), Catch::Contains("runs at its own sample time 0.01 s") && Catch::Contains("0.02"));
  }
  o.ts = 0.01;
  CHECK_NOTHROW(generate_c(m, o));
}

TEST_CASE("augmented model: simulate, rebuilt from its per-sample pieces, is unchanged", "[diagnose][augmented]") {
  // Values of the simulation before simulate() was split into input_chain / augmented_derivative /
  // output_at / friction_after (x0 = [0.1, -0.2], 2000 samples of random steps): the pieces
  // perform the same operations, so these are exact.
  const double before[3] = {-0.67766245259184832, -0.10000000000000001, 0.66934490919881473};
  for (int variant = 0; variant < 2; ++variant) {
    const auto m = msd_with(variant);
    const Eigen::MatrixXd u = diag_test::random_steps(2000, -1.0, 1.0, 20, 60, 3u + static_cast<unsigned>(variant));
    const Eigen::VectorXd th = m.parameters();
    const Eigen::Vector2d x0(0.1, -0.2);
    Eigen::VectorXd y(2000);
    REQUIRE(m.simulate<double>(u, th.data(), x0.data(), y.data()) == 2000);
    CHECK(y(1999) == before[variant]);
  }
}

TEST_CASE("codegen: an augmented model's sub-step count must keep RK4 stable", "[diagnose][codegen]") {
  auto m = msd_with(2);
  // A stiff end stop (K = 1e6 1/s^2): rho >= 1000 1/s, h*rho >= 10 at ts = 0.01 s.
  m.add_effect(diag_test::effect(EffectKind::hard_stop, {1.0, 1e6}, diag_test::unit_scales(0.01, 1.1), "upper"));
  CodegenOptions o;
  o.substeps = 1;
  CHECK_THROWS_WITH(generate_c(m, o), Catch::Contains("CodegenOptions::substeps = 1 per sample gives an unstable RK4 step") &&
                                          Catch::Contains("needs at least"));
  o.substeps = 0;  // nlid's rule picks a stable count
  CHECK_NOTHROW(generate_c(m, o));
}

TEST_CASE("codegen: an augmented model starts from a given baseline state as simulate(e, x0)", "[diagnose][codegen]") {
  // Effect set 0 has a dead time (a history in the generated state) and an actuator lag.
  const auto m = msd_with(0);
  const Eigen::MatrixXd u = diag_test::random_steps(800, -1.0, 1.0, 20, 60, 5u);
  const Experiment e(u, Eigen::MatrixXd::Zero(u.rows(), 1), m.ts(), "steps");
  const Eigen::Vector2d x0(0.12, -0.4);  // away from rest and from any equilibrium
  CodegenOptions o;
  o.name = "aug_x0";
  o.initial_state = x0;
  const GeneratedCode g = generate_c(m, o);
  CHECK(g.source.find("CodegenOptions::initial_state") != std::string::npos);  // NAME_x0's comment says so
  const Eigen::VectorXd yc = nlid_test::run_generated_c(g, u, "aug_x0");
  const Eigen::VectorXd yn = m.simulate(e, Eigen::VectorXd(x0)).col(0);
  CHECK(nlid_test::max_relative_error(yc, yn) <= 1e-12);
  CHECK(std::abs(yn(0) - m.simulate(e, InitialCondition::zero)(0, 0)) > 1e-3);  // the start matters

  // generated_c_state: the baseline state, the effect states zero and the first-sample flag set.
  const Eigen::VectorXd gs = generated_c_state(m, Eigen::VectorXd(x0));
  REQUIRE(gs.size() == 2 + 4 + m.dead_time_samples(m.parameters().data()) + 1);
  CHECK(gs.head(2) == x0);
  CHECK(gs(5) == 1.0);
  CHECK(gs.tail(gs.size() - 6).isZero(0.0));
  CHECK_THROWS_WITH(generated_c_state(m, Eigen::VectorXd::Zero(3)), Catch::Contains("the baseline has 2"));
  o.initial_state = Eigen::VectorXd::Zero(3);
  CHECK_THROWS_WITH(generate_c(m, o), Catch::Contains("initial_state has 3 values") &&
                                          Catch::Contains("the baseline's state"));
  o.initial_state = x0;
  o.equilibrium_input = Eigen::VectorXd::Constant(1, 0.2);
  CHECK_THROWS_WITH(generate_c(m, o), Catch::Contains("both set"));
}
