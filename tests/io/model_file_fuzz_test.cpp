// Model files found by the model_file fuzzer (tests/fuzz/model_file_fuzz.cpp): files that parse
// and pass the member checks but describe a model that would overflow, allocate gigabytes or hang
// when built, simulated, predicted or generated as C. Sizes a file can hold are refused at load
// with an nlid::Error naming the file and the key path of the offending value; what only a use
// makes too large (an initial state to fit, a state to write out in C) is refused by that use.
#include <catch2/catch.hpp>

#include <cmath>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "nlid/codegen/linear.hpp"
#include "nlid/codegen/nlarx.hpp"
#include "nlid/diagnose/effects.hpp"
#include "nlid/io/augmented_serial.hpp"
#include "nlid/io/model_file.hpp"
#include "nlid/models/any_model.hpp"
#include "nlid/models/physics/catalogue.hpp"
#include "nlid/nonlinearities.hpp"
#include "nlid/regressors.hpp"
#include "nlid/regressors/expression.hpp"

#include "../support/scratch_dir.hpp"
#include "../support/msd_scales.hpp"

using namespace nlid;

namespace mff_test {

std::string mff_path(const std::string& name) { return (nlid_test::scratch_dir() / name).string(); }

// The text of `model` saved as a model file.
template <class M>
std::string mff_saved_text(const M& model, const std::string& name) {
  const std::string p = mff_path(name);
  save_model(p, model);
  std::ifstream in(p);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// `text` with the first `from` replaced by `to`.
std::string mff_edited_file_text(const std::string& text, const std::string& from, const std::string& to) {
  const auto i = text.find(from);
  REQUIRE(i != std::string::npos);
  std::string s = text;
  s.replace(i, from.size(), to);
  return s;
}

// `text` with the first `from` replaced by `to`, written to `name`; returns the path.
std::string mff_edited_file(const std::string& text, const std::string& from, const std::string& to,
                            const std::string& name) {
  const std::string p = mff_path(name);
  std::ofstream(p) << mff_edited_file_text(text, from, to);
  return p;
}

// The message of the nlid::Error load_model(path) throws ("" if it loads; another exception
// type propagates and fails the test).
std::string mff_load_error(const std::string& path) {
  try {
    (void)load_model(path);
  } catch (const Error& e) {
    return e.what();
  }
  return {};
}

DynamicNlarx mff_tree_model() {
  DynamicNlarx m(RegressorList::lagged(1, 1, 1), AnyNonlinearity(TreePartition<Dynamic, Dynamic>(2, 2)), 0.01);
  return m;
}

}  // namespace mff_test

TEST_CASE("model file: a tree partition or network too large for an int parameter count is refused at load",
          "[io][errors][fuzz]") {
  using namespace mff_test;
  using Catch::Contains;
  // 4095 splits of 2^20 inputs: (leaves - 1) * m overflowed an int while the tree was built,
  // before the file's parameter count was compared.
  const std::string text = mff_saved_text(mff_tree_model(), "mff_tree.json");
  const std::string p = mff_edited_file(mff_edited_file_text(text, "\"inputs\": 2", "\"inputs\": 1048576"),
                                        "\"depth\": 2", "\"depth\": 12", "mff_tree_big.json");
  CHECK_THAT(mff_load_error(p), Contains("TreePartition: 4096 leaves over 1048576 inputs would need") &&
                                    Contains("structure.nonlinearity") && Contains(p));
  // The maps themselves refuse such sizes (their parameter counts are ints).
  CHECK_THROWS_WITH((TreePartition<Dynamic, Dynamic>(1 << 20, 12)), Contains("more than the 16777216"));
  CHECK_THROWS_WITH((SigmoidNet<Dynamic, Dynamic>(1 << 20, 1 << 20)), Contains("SigmoidNet: 1048576 units"));
  CHECK_THROWS_WITH((WaveletNet<Dynamic, Dynamic, false>(1 << 20, 1 << 20)), Contains("WaveletNet: 1048576 units"));
  CHECK_NOTHROW(SigmoidNet<Dynamic, Dynamic>(1000, 100));
}

TEST_CASE("model file: regressor blocks are counted before they are built, up to what a nonlinearity takes",
          "[io][errors][fuzz]") {
  using namespace mff_test;
  using Catch::Contains;
  // 35 bytes per block made 100000 regressors each: a 1 MB file asked for billions before the
  // nonlinearity's input count was compared.
  const std::string text = mff_saved_text(mff_tree_model(), "mff_regs.json");
  std::string many;
  for (int i = 0; i < 11; ++i) many += "{\"type\": \"output_lags\", \"na\": 100000}, ";
  const std::string p = mff_edited_file(text, "\"blocks\": [", "\"blocks\": [" + many, "mff_regs_many.json");
  CHECK_THAT(mff_load_error(p), Contains("hold more than 1048576 regressors by block structure.regressors.blocks") &&
                                    Contains(p));
  // Up to the limit the blocks are built, and the nonlinearity's size is what is refused.
  std::string some;
  for (int i = 0; i < 3; ++i) some += "{\"type\": \"output_lags\", \"na\": 100000}, ";
  const std::string q = mff_edited_file(text, "\"blocks\": [", "\"blocks\": [" + some, "mff_regs_some.json");
  CHECK_THAT(mff_load_error(q), Contains("takes 2 inputs but there are 300002 regressors") && Contains(q));
}

TEST_CASE("model file: a grey box's integrator cannot ask for more sub-steps or adaptive steps than the integrator "
          "takes",
          "[io][errors][fuzz]") {
  using namespace mff_test;
  using Catch::Contains;
  // 2^30 RK4 sub-steps per sample loaded, and the first simulation of 50 samples ran for hours.
  const std::string text = mff_saved_text(make_greybox("first_order"), "mff_greybox.json");
  const std::string p = mff_edited_file(text, "\"substeps\": 0", "\"substeps\": 1073741824", "mff_gb_substeps.json");
  CHECK_THAT(mff_load_error(p), Contains("value 1073741824 at structure.integrator.substeps is out of range [0, 100000]") &&
                                    Contains(p));
  const std::string q = mff_edited_file(text, "\"max_substeps\": 2000", "\"max_substeps\": 100001", "mff_gb_max.json");
  CHECK_THAT(mff_load_error(q), Contains("structure.integrator.max_substeps is out of range [0, 100000]"));
  // An unreachable tolerance spent a budget of 2^31 - 1 adaptive steps on the first sample.
  const std::string r = mff_edited_file(text, "\"max_adaptive_steps\": 100000", "\"max_adaptive_steps\": 2147483647",
                                        "mff_gb_adaptive.json");
  CHECK_THAT(mff_load_error(r), Contains("structure.integrator.max_adaptive_steps is out of range [0, 1000000]") &&
                                    Contains(r));
  // The C++ API has the same limits, so that every model it builds can be saved and read back.
  IntegratorOptions o;
  o.substeps = max_integrator_substeps + 1;
  CHECK_THROWS_WITH(validate(o), Contains("substeps = 100001 is more than the 100000 sub-steps per sample"));
  o.substeps = 0;
  o.max_adaptive_steps = max_adaptive_step_budget + 1;
  CHECK_THROWS_WITH(validate(o), Contains("max_adaptive_steps = 1000001 is more than the 1000000 steps"));
  o.max_adaptive_steps = max_adaptive_step_budget;
  o.max_substeps = max_integrator_substeps;
  CHECK_NOTHROW(validate(o));
}

TEST_CASE("model file: a grey box's parameter range or state window the model refuses is located in the file",
          "[io][errors][fuzz]") {
  using namespace mff_test;
  using Catch::Contains;
  const std::string text = mff_saved_text(make_greybox("first_order"), "mff_gb_range.json");
  // range_lower > range_upper: GreyBox::set_range's error named the parameter but not the file.
  const std::string p = mff_edited_file(text, "\"range_upper\": 10", "\"range_upper\": 0.01", "mff_gb_range_crossed.json");
  CHECK_THAT(mff_load_error(p), Contains("range of 'tau' must be finite with lower <= upper") &&
                                    Contains("structure.parameter_table[0]") && Contains(p));
  // A log-spaced range through zero.
  const std::string q = mff_edited_file(text, "\"range_lower\": 0.1", "\"range_lower\": -1", "mff_gb_range_log.json");
  CHECK_THAT(mff_load_error(q), Contains("log-spaced range of 'tau' must be positive") && Contains(q));
  const std::string r = mff_edited_file(text, "\"initial_state_window\": 2000", "\"initial_state_window\": -5",
                                        "mff_gb_window.json");
  CHECK_THAT(mff_load_error(r), Contains("initial-state window -5 at structure.initial_state_window must be >= 0") &&
                                    Contains(r));
}

TEST_CASE("model file: a Hammerstein-Wiener model with a delay of 1e5 samples predicts with an error, not std::bad_alloc",
          "[io][errors][fuzz]") {
  using namespace mff_test;
  using Catch::Contains;
  DynamicHammersteinWiener hw(AnyNonlinearity(UnitGain{}), TransferFunctionBlock<Dynamic, Dynamic, Dynamic>(2, 0, 0),
                              AnyNonlinearity(UnitGain{}), 0.01);
  Eigen::VectorXd th(2);
  th << 0.5, 0.25;
  hw.set_parameters(th);
  const std::string p =
      mff_edited_file(mff_saved_text(hw, "mff_hw.json"), "\"nk\": 0", "\"nk\": 100000", "mff_hw_delay.json");
  const AnyModel m = load_model(p);
  Eigen::MatrixXd u(50, 1), y(50, 1);
  for (int k = 0; k < 50; ++k) {
    u(k, 0) = std::sin(0.3 * k);
    y(k, 0) = 0.1 * k;
  }
  const Experiment e(u, y, 0.01, "short");
  CHECK(m.simulate(e, InitialCondition::zero).rows() == 50);
  // predict (and simulate from InitialCondition::estimate) fitted all 100001 register values: the
  // Levenberg-Marquardt solve asked for 10^5 x 10^5 matrices.
  CHECK_THROWS_WITH(m.predict(e, 1), Contains("cannot estimate an initial state of 100001 values (at most 1000"));
  CHECK_THROWS_WITH(m.simulate(e, InitialCondition::estimate), Contains("use InitialCondition::zero or equilibrium"));
}

TEST_CASE("codegen refuses a lag window or delay line longer than its line budget before building it",
          "[io][errors][fuzz]") {
  using namespace mff_test;
  using Catch::Contains;
  // 100 inputs each delayed 99999 samples: a 5 kB model file generated 378 MB of C (and 200
  // inputs of a nonlinear ARX model 738 MB, in a minute and 4.5 GB of memory).
  const int nu = 100;
  std::vector<Eigen::VectorXd> b(nu, Eigen::VectorXd::Constant(1, 0.1));
  const std::vector<int> nk(nu, 99999);
  const Arx arx(Eigen::VectorXd::Constant(1, -0.5), b, nk, 0.01);
  CHECK_THROWS_WITH(generate_c(arx), Contains("codegen: the ARX model's state has 9999901 values, more than the "
                                              "TraceLimits::max_lines = 2000000"));
  const OutputError oe(b, std::vector<Eigen::VectorXd>(nu, Eigen::VectorXd::Constant(1, -0.5)), nk, 0.01);
  CHECK_THROWS_WITH(generate_c(oe), Contains("codegen: the output-error model's state has 10000000 values"));
  // (Typed regressors: a RegressorList's expressions trace only where codegen was included first.)
  using Regs = RegressorSet<OutputLags<1>, InputLags<Dynamic, Dynamic, 199>>;
  const Nlarx<Regs, LinearMap<2>> nlarx(Regs(OutputLags<1>{}, InputLags<Dynamic, Dynamic, 199>(1, 99999)), LinearMap<2>{},
                                        0.01);
  CHECK_THROWS_WITH(generate_c(nlarx), Contains("codegen: the nonlinear ARX model's state has 19999801 values"));
  // A delay line within the budget is generated.
  const Arx small(Eigen::VectorXd::Constant(1, -0.5), {Eigen::VectorXd::Constant(1, 0.1)}, {1000}, 0.01);
  CHECK(generate_c(small).source.size() > 1000);
}

TEST_CASE("model file: an augmented grey box's dead time must be 0 to 100000 samples over its whole bounds",
          "[io][errors][fuzz]") {
  using namespace mff_test;
  using Catch::Contains;
  GreyBox<physics::MassSpringDamper> g;
  AugmentedModel<AnyPhysics> m(make_physics("mass_spring_damper"), g.parameter_info(), 0.01);
  const DataScales s = nlid_test::msd_effect_scales();
  const auto dead = make_effect_candidates(effect_kind("dead_time"), s);
  REQUIRE(!dead.empty());
  m.add_effect(dead[0].effect);
  const std::string text = mff_saved_text(m, "mff_dead.json");
  const auto at = text.find("\"effect\": \"dead_time\"");
  REQUIRE(at != std::string::npos);
  const auto edit_after = [&](const std::string& from, const std::string& to) {
    std::string t = text;
    const auto i = t.find(from, at);
    REQUIRE(i != std::string::npos);
    t.replace(i, from.size(), to);
    return t;
  };
  // A negative dead time read the input before the record's start (an Eigen index out of range).
  const std::string p = mff_edited_file(edit_after("\"lower\": 0,", "\"lower\": -1,"), "{", "{", "mff_dead_neg.json");
  CHECK_THAT(mff_load_error(p), Contains("effect dead_time: the bounds of 'tau' must lie in [0, 1000] s") &&
                                    Contains("structure.effects[0]") && Contains(p));
  // 1e300 s overflowed the int sample count (UBSan); 1e6 s generated 500 MB of C.
  const std::string q = mff_edited_file(edit_after("\"upper\": 0.5,", "\"upper\": 1e300,"), "{", "{", "mff_dead_huge.json");
  CHECK_THAT(mff_load_error(q), Contains("got [0, 1e+300]") && Contains(q));
}
