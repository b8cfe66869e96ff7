// Model files: round trips of every model kind (bit-exact simulation after reload), damaged and
// newer-version files with message checks, atomic writes.
#include <catch2/catch.hpp>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "nlid/io/model_file.hpp"
#include "nlid/core/atomic_file.hpp"
#include "nlid/models/any_model.hpp"
#include "nlid/models/any_model_band.hpp"
#include "nlid/models/physics/catalogue.hpp"
#include "nlid/nonlinearities.hpp"
#include "nlid/regressors.hpp"
#include "nlid/regressors/expression.hpp"

#include "../support/scratch_dir.hpp"

namespace fs = std::filesystem;
using namespace nlid;

namespace {

std::string temp_dir() { return nlid_test::scratch_dir().string(); }
std::string temp_path(const std::string& name) { return (fs::path(temp_dir()) / name).string(); }

// A throttle-like record: steps and pulses through a saturating second-order system, 100 Hz.
Experiment test_experiment(int n = 600, unsigned seed = 3) {
  std::mt19937 gen(seed);
  std::uniform_real_distribution<double> level(-0.2, 1.0);
  Eigen::MatrixXd u(n, 1);
  Eigen::MatrixXd y(n, 1);
  double x1 = 15, x2 = 0, cur = 0;
  for (int k = 0; k < n; ++k) {
    if (k % 60 == 0) cur = level(gen);
    u(k, 0) = cur;
    const double acc = -6.0 * x2 - 30.0 * (x1 - 15.0) + 2500.0 * cur - 400.0 * (std::max(x1, 90.0) - 90.0);
    x2 += 0.01 * acc;
    x1 += 0.01 * x2;
    y(k, 0) = x1;
  }
  Experiment e(u, y, 0.01, "synthetic");
  return e;
}

bool bit_equal(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  if (a.rows() != b.rows() || a.cols() != b.cols()) return false;
  for (Eigen::Index i = 0; i < a.size(); ++i) {
    if (std::bit_cast<std::uint64_t>(a.data()[i]) != std::bit_cast<std::uint64_t>(b.data()[i])) return false;
  }
  return true;
}

// Message of the nlid::Error thrown by f (empty if none).
template <class F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return {};
}

// Writes `text` to a file and returns its path.
std::string write_text(const std::string& name, const std::string& text) {
  const std::string p = temp_path(name);
  std::ofstream(p) << text;
  return p;
}

std::string read_text(const std::string& p) { return read_file(p); }

// Replaces the first occurrence of `from` in a file's text.
std::string edited(const std::string& text, const std::string& from, const std::string& to) {
  const auto i = text.find(from);
  REQUIRE(i != std::string::npos);
  std::string s = text;
  s.replace(i, from.size(), to);
  return s;
}

// Estimation-like state: nonlinearity initialised on data (normalisation learned), θ perturbed
// to values with full 17-digit mantissas.
template <class M>
void initialise(M& m, const Experiment& e) {
  const Eigen::MatrixXd X = m.regressor_values(e);
  const Eigen::VectorXd y = e.y().col(0).tail(X.rows());
  Eigen::VectorXd th(m.num_parameters());
  m.nonlinearity().initialize(X, y, std::span<double>(th.data(), static_cast<std::size_t>(th.size())));
  for (Eigen::Index i = 0; i < th.size(); ++i) th(i) *= 1.0 + 1e-3 / 3.0 * static_cast<double>(i % 7);
  m.set_parameters(th);
}

const auto spring = [](auto y1) { return nlid::max(y1, 90.0) + nlid::min(y1, 15.0) - 105.0; };

}  // namespace

TEST_CASE("model file: a network input held constant in the data is stored unused (scale 0) and stays unused") {
  // Two inputs, the second held at 0.1 throughout: the network marks it unused (s = 0, z = 0).
  const Experiment one = test_experiment();
  Eigen::MatrixXd u(one.size(), 2);
  u.col(0) = one.u().col(0);
  u.col(1).setConstant(0.1);
  const Experiment e(u, one.y(), 0.01, "held");
  using Regs = RegressorSet<LaggedRegressors<2, 1, 0>, InputLags<1, 0, 1>>;
  Nlarx model(Regs{}, SigmoidNet<4, 5>{}, 0.01);
  initialise(model, e);
  REQUIRE(model.nonlinearity().scale()(3) == 0.0);
  const std::string path = temp_path("held_input.json");
  save_model(path, model);
  CHECK_THAT(read_text(path), Catch::Contains("\"scale\""));
  const AnyModel any = load_model(path);
  const Eigen::MatrixXd y0 = model.simulate(e, InitialCondition::measured);
  CHECK(bit_equal(any.simulate(e, InitialCondition::measured), y0));
  // Moving the held input changes nothing, before and after the round trip.
  Eigen::MatrixXd u2 = u;
  u2.col(1).setConstant(3.0);
  const Experiment moved(u2, one.y(), 0.01, "moved");
  CHECK(bit_equal(model.simulate(moved, InitialCondition::measured), y0));
  CHECK(bit_equal(any.simulate(moved, InitialCondition::measured), y0));
  // A negative scale is still refused; 0 is the one non-positive value a file may give.
  const std::string text = read_text(path);
  const auto at = text.find("\"scale\"");
  REQUIRE(at != std::string::npos);
  const auto open = text.find('[', at), comma = text.find(',', open);
  REQUIRE(comma != std::string::npos);
  std::string bad = text;
  bad.replace(open + 1, comma - open - 1, "-1");  // the first scale entry becomes negative
  const std::string bad_path = write_text("held_input_bad.json", bad);
  CHECK_THAT(error_of([&] { (void)load_model(bad_path); }), Catch::Contains("positive finite scale (or 0: input not used)"));
}

TEST_CASE("model file: a C++ custom regressor whose name reads another channel under the model's names is saved by name only") {
  // The lambda squares input 2 (u2(t-1)). Files are read back with the model's channel names, and
  // under inputs {u2, u1} the text "u2(t-1)^2" reads input 1: written as the expression, the file
  // loaded as another model (found by a multi-input review).
  const Experiment one = test_experiment();
  Eigen::MatrixXd u(one.size(), 2);
  u.col(0) = one.u().col(0);
  u.col(1) = one.u().col(0).reverse();
  const Experiment e(u, one.y(), 0.01, "two");
  const auto square = [](auto v) { return v * v; };
  RegressorSet regs{LaggedRegressors<1, 1, 0>{}, InputLags<1, 0, 1>{}, custom_regressor<InputLag<1, 1>>("u2(t-1)^2", square)};
  Nlarx model(regs, LinearMap<4>{}, 0.01);
  Eigen::VectorXd th(5);
  th << 0.9, 0.5, -0.25, 0.125, 1.0;
  model.set_parameters(th);
  const Eigen::MatrixXd y0 = model.simulate(e, InitialCondition::zero);
  // Names under which the text reads input 2: written as the expression, loadable at run time.
  model.set_channel_names({"a", "b"}, "y");
  const std::string named = temp_path("lambda_named.json");
  save_model(named, model);
  CHECK_THAT(read_text(named), Catch::Contains("\"expression\": \"u2(t-1)^2\""));
  Experiment ab = e;
  ab.set_input_names({"a", "b"});
  CHECK(bit_equal(load_model(named).simulate(ab, InitialCondition::zero), y0));
  // Inputs named {u2, u1}: the name only, so only a C++ prototype holding the lambda loads it.
  model.set_channel_names({"u2", "u1"}, "y");
  const std::string swapped = temp_path("lambda_swapped.json");
  save_model(swapped, model);
  CHECK_THAT(error_of([&] { (void)load_model(swapped); }), Catch::Contains("C++ function without an expression"));
  Nlarx proto(regs, LinearMap<4>{}, 0.0);
  load_model(swapped, proto);
  Experiment uu = e;
  uu.set_input_names({"u2", "u1"});
  CHECK(bit_equal(proto.simulate(uu, InitialCondition::zero), y0));
}

TEST_CASE("model file: nlarx with a custom regressor and a sigmoid net round-trips bit for bit") {
  const Experiment e = test_experiment();
  RegressorSet regs{LaggedRegressors<2, 1, 0>{},
                    custom_regressor<OutputLag<1>>("max(y1(t-1),90)+min(y1(t-1),15)-105", spring)};
  Nlarx model(regs, SigmoidNet<4, 5>{}, 0.01);
  initialise(model, e);
  model.set_channel_names({"command"}, "angle");
  EstimationReport r;
  r.estimated = true;
  r.focus = "simulation";
  r.initial_condition = "measured";
  r.iterations = 17;
  r.initial_cost = 123.25;
  r.final_cost = 1.0 / 3.0;
  r.seconds = 0.5;
  r.status = "converged: relative cost change below tolerance";
  r.data_names = {"data1", "data2"};
  r.fit_percent = {91.5, 88.25};
  model.set_report(r);

  ModelFileInfo info;
  info.input_units = {"1"};
  info.output_units = {"deg"};
  info.description = "nlarx4-like";
  const std::string path = temp_path("nlarx.json");
  save_model(path, model, info);

  Experiment named = e;
  named.set_input_names({"command"});
  named.set_output_names({"angle"});
  const Eigen::MatrixXd y0 = model.simulate(e, InitialCondition::measured);

  SECTION("run-time structure from the file (AnyModel)") {
    const AnyModel any = load_model(path);
    CHECK(any.kind() == "nlarx");
    CHECK(any.ts() == 0.01);
    CHECK(any.input_names() == std::vector<std::string>{"command"});
    CHECK(any.output_names() == std::vector<std::string>{"angle"});
    CHECK(any.info().output_units == std::vector<std::string>{"deg"});
    CHECK(any.info().description == "nlarx4-like");
    CHECK(any.initial_condition() == InitialCondition::measured);
    CHECK(bit_equal(any.parameters(), model.parameters()));
    CHECK(bit_equal(any.simulate(e, InitialCondition::measured), y0));
    CHECK(bit_equal(any.simulate(e), y0));  // the file's default policy is the estimation's
    CHECK(bit_equal(any.predict(e, 1), model.predict(e, 1)));
    CHECK(bit_equal(any.predict(e, 5), model.predict(e, 5)));
    const auto* dyn = any.target<DynamicNlarx>();
    REQUIRE(dyn != nullptr);
    CHECK(dyn->regressor_names() == model.regressor_names());
    CHECK(dyn->report().iterations == 17);
    CHECK(dyn->report().final_cost == 1.0 / 3.0);
    CHECK(dyn->report().fit_percent == std::vector<double>{91.5, 88.25});
    CHECK(dyn->report().data_names == std::vector<std::string>{"data1", "data2"});
    CHECK_THAT(any.describe(), Catch::Contains("max(y1(t-1),90)+min(y1(t-1),15)-105"));

    // Saving the run-time model again gives the same file (apart from nothing: same stamp kept).
    const std::string again = temp_path("nlarx_again.json");
    any.save(again);
    CHECK(read_text(again) == read_text(path));
  }
  SECTION("into a C++ prototype holding the lambda") {
    Nlarx proto(regs, SigmoidNet<4, 5>{}, 0.0);
    ModelFileInfo got;
    load_model(path, proto, &got);
    CHECK(bit_equal(proto.simulate(e, InitialCondition::measured), y0));
    CHECK(proto.ts() == 0.01);
    CHECK(proto.output_name() == "angle");
    CHECK(got.input_units == std::vector<std::string>{"1"});
  }
  SECTION("a prototype with different regressors is refused, naming the regressor") {
    Nlarx other(RegressorSet{LaggedRegressors<2, 1, 1>{},
                             custom_regressor<OutputLag<1>>("max(y1(t-1),90)+min(y1(t-1),15)-105", spring)},
                SigmoidNet<4, 5>{});
    const std::string msg = error_of([&] { load_model(path, other); });
    CHECK_THAT(msg, Catch::Contains("regressor 2 is 'command(t)' in the file") &&
                        Catch::Contains("'command(t-1)' in this model") && Catch::Contains("nlarx.json"));
    Nlarx units(regs, SigmoidNet<4, 6>{});
    CHECK_THAT(error_of([&] { load_model(path, units); }),
               Catch::Contains("units = 5") && Catch::Contains("this model has 6"));
  }
}

TEST_CASE("model file: every nonlinearity and compile-time types round-trip exactly") {
  const Experiment e = test_experiment(500, 7);
  SECTION("nlarx5: [3 3 0] sigmoid net, typed load") {
    using M = Nlarx<LaggedRegressors<3, 3, 0>, SigmoidNet<6, 5>>;
    M m(LaggedRegressors<3, 3, 0>{}, SigmoidNet<6, 5>{}, 0.01);
    initialise(m, e);
    const std::string p = temp_path("nlarx5.json");
    save_model(p, m);
    const M back = load_model<M>(p);
    CHECK(bit_equal(back.simulate(e, InitialCondition::zero), m.simulate(e, InitialCondition::zero)));
    CHECK(bit_equal(load_model(p).simulate(e, InitialCondition::zero), m.simulate(e, InitialCondition::zero)));
    // A compile-time type with other orders cannot take this file.
    using Other = Nlarx<LaggedRegressors<2, 3, 0>, SigmoidNet<5, 5>>;
    CHECK_THAT(error_of([&] { (void)load_model<Other>(p); }),
               Catch::Contains("model order na = 3 differs from its compile-time value 2"));
  }
  SECTION("sigmoid net without linear term, wavelet nets, tree partition, linear map") {
    auto check = [&](auto f, const char* name) {
      Nlarx m(LaggedRegressors<2, 2, 1>{}, std::move(f), 0.01);
      initialise(m, e);
      const std::string p = temp_path(std::string(name) + ".json");
      save_model(p, m);
      INFO(name);
      CHECK(bit_equal(load_model(p).simulate(e, InitialCondition::measured), m.simulate(e, InitialCondition::measured)));
      using M = decltype(m);
      CHECK(bit_equal(load_model<M>(p).simulate(e, InitialCondition::measured),
                      m.simulate(e, InitialCondition::measured)));
    };
    check(SigmoidNet<4, 4, false>{}, "sig_nolin");
    check(WaveletNet<4, 3, true>{}, "wave");
    check(TreePartition<4, 2>{}, "tree");
    check(LinearMap<4>{}, "linmap");
    check(SigmoidNet<Dynamic, Dynamic>(4, 3), "sig_dyn");
  }
  SECTION("Hammerstein-Wiener nlhw2: pwlinear - [3 3 0] - pwlinear; nlhw1: saturation output") {
    using L = TransferFunctionBlock<3, 3, 0>;
    HammersteinWiener hw(PwLinear<5>{}, L{}, Saturation(15.0, 90.0), 0.01);
    Eigen::VectorXd th(hw.num_parameters());
    for (Eigen::Index i = 0; i < th.size(); ++i) th(i) = 0.1 * std::sin(1.0 + i);
    // Valid breakpoints: x0, log gaps, values; stable F.
    th.head(10) << -0.3, std::log(0.3), std::log(0.4), std::log(0.2), std::log(0.5), 0.0, 0.2, 0.5, 0.7, 0.75;
    th.segment(10, 6) << 0.05, 0.03, 0.01, -1.2, 0.5, -0.1;
    th.tail(2) << 0.02, 0.09;
    hw.set_parameters(th);
    const std::string p = temp_path("hw.json");
    save_model(p, hw, ModelFileInfo{{}, {}, InitialCondition::zero, "nlhw2", {}, {}, {}, {}, {}, {}});
    const AnyModel any = load_model(p);
    CHECK(any.kind() == "hammerstein_wiener");
    CHECK(bit_equal(any.simulate(e), hw.simulate(e, InitialCondition::zero)));
    const auto typed = load_model<decltype(hw)>(p);
    CHECK(bit_equal(typed.simulate(e, InitialCondition::zero), hw.simulate(e, InitialCondition::zero)));
    CHECK(typed.output_nonlinearity().initial_limits() == std::optional<std::pair<double, double>>({15.0, 90.0}));

    HammersteinWiener hw2(UnitGain{}, TransferFunctionBlock<Dynamic, Dynamic, Dynamic>(2, 2, 1), DeadZone(-0.1, 0.2));
    Eigen::VectorXd t2(hw2.num_parameters());
    t2 << 0.3, 0.2, -1.1, 0.3, -0.05, 0.07;
    hw2.set_parameters(t2);
    save_model(p, hw2);
    CHECK(bit_equal(load_model(p).simulate(e, InitialCondition::zero), hw2.simulate(e, InitialCondition::zero)));

    HammersteinWiener hw3(Poly1d<3>{}, TransferFunctionBlock<Dynamic, Dynamic, Dynamic>(1, 1, 0), UnitGain{});
    Eigen::VectorXd t3(hw3.num_parameters());
    t3 << 0.1, 1.0, -0.2, 0.05, 0.4, -0.6;
    hw3.set_parameters(t3);
    save_model(p, hw3);
    CHECK(bit_equal(load_model(p).simulate(e, InitialCondition::zero), hw3.simulate(e, InitialCondition::zero)));
  }
}

TEST_CASE("model file: an empty path is named as such") {
  GreyBox<physics::Throttle> g;
  CHECK_THROWS_WITH(save_model("", g), Catch::Contains("empty file name"));
}

TEST_CASE("model file: grey-box throttle by catalogue name, parameter table and bounds") {
  GreyBox<physics::Throttle> g;
  const auto names = g.parameter_names();
  Eigen::VectorXd p = g.parameters();
  for (Eigen::Index i = 0; i < p.size(); ++i) p(i) = std::nextafter(p(i), p(i) + 1.0);  // full-precision values
  g.set_parameters(p);
  g.fix(names[0]);
  g.set_estimated_initial_states({Eigen::Vector2d(15.0, 0.0), Eigen::Vector2d(16.5, -0.25)});
  const Experiment e = test_experiment(300, 11);
  const std::string path = temp_path("greybox.json");
  ModelFileInfo info;
  info.output_units = {"deg"};
  save_model(path, g, info);

  const AnyModel any = load_model(path);
  CHECK(any.kind() == "greybox");
  CHECK(any.initial_condition() == InitialCondition::estimate);
  CHECK(bit_equal(any.simulate(e, InitialCondition::zero), g.simulate(e, InitialCondition::zero)));
  CHECK(bit_equal(any.parameters(), Eigen::VectorXd(g.parameters())));
  const auto* dyn = any.target<DynamicGreyBox>();
  REQUIRE(dyn != nullptr);
  CHECK(dyn->is_fixed(names[0]));
  CHECK(dyn->estimated_initial_states().size() == 2);
  CHECK(dyn->parameter_info()[0].lower == g.parameter_info()[0].lower);

  const auto typed = load_model<GreyBox<physics::Throttle>>(path);
  CHECK(bit_equal(typed.simulate(e, InitialCondition::zero), g.simulate(e, InitialCondition::zero)));
  CHECK_THAT(error_of([&] { (void)load_model<GreyBox<physics::MassSpringDamper>>(path); }),
             Catch::Contains("grey-box physics is \"throttle\""));

  // Crossed stops in a file (each value alone is fine): refused at loading, naming the relation
  // and the file; before, the file loaded and the first simulation failed.
  {
    Json j = Json::parse(read_text(path));
    Json& values = j["parameters"]["values"];
    const auto at = [&](const char* n) {
      return static_cast<std::size_t>(std::find(names.begin(), names.end(), n) - names.begin());
    };
    values[at("lower_stop")] = 95.0;
    values[at("upper_stop")] = 20.0;
    const std::string crossed = write_text("greybox_crossed_stops.json", j.dump());
    const std::string msg = error_of([&] { (void)load_model(crossed); });
    CHECK_THAT(msg, Catch::Contains("lower_stop") && Catch::Contains("upper_stop") &&
                        Catch::Contains("greybox_crossed_stops.json"));
  }
  // A value outside the bounds the file gives it: the message shows the value and the bounds.
  {
    Json j = Json::parse(read_text(path));
    j["structure"]["parameter_table"][1]["upper"] = j["parameters"]["values"][1].as_number() - 1.0;
    const std::string out = write_text("greybox_out_of_bounds.json", j.dump());
    CHECK_THAT(error_of([&] { (void)load_model(out); }),
               Catch::Contains("value of '" + names[1] + "', ") && Catch::Contains("lies outside its bounds [") &&
                   Catch::Contains("parameter_table"));
  }
  // A file naming physics this program does not know.
  const std::string bad = write_text("greybox_unknown.json",
                                     edited(read_text(path), "\"physics\": \"throttle\"", "\"physics\": \"pendulum\""));
  CHECK_THAT(error_of([&] { (void)load_model(bad); }), Catch::Contains("pendulum"));
}

TEST_CASE("model file: a grey box keeps its parameters' standard deviations, infinite ones included") {
  GreyBox<physics::Throttle> g;
  CHECK(g.parameter_stddev().size() == 0);
  const Eigen::Index n = g.num_parameters();
  Eigen::VectorXd sd = Eigen::VectorXd::LinSpaced(n, 0.5, 3.5);
  sd[2] = std::numeric_limits<double>::infinity();  // K: not identifiable
  sd[n - 1] = 0.0;                                    // rest: fixed
  g.fix("rest");
  g.set_parameter_stddev(sd);
  CHECK_THAT(g.describe(), Catch::Contains("estimated +- 0.5") && Catch::Contains("+- inf (not identifiable)"));
  const std::string path = temp_path("greybox_stddev.json");
  save_model(path, g);
  const auto typed = load_model<GreyBox<physics::Throttle>>(path);
  REQUIRE(typed.parameter_stddev().size() == n);
  CHECK(bit_equal(typed.parameter_stddev(), sd));
  const AnyModel any = load_model(path);
  const auto* dyn = any.target<DynamicGreyBox>();
  REQUIRE(dyn != nullptr);
  CHECK(bit_equal(dyn->parameter_stddev(), sd));

  // A changed value makes the deviations stale: they are dropped, and a file without them loads.
  GreyBox<physics::Throttle> changed = typed;
  changed.set_parameter("c", 25.0);
  CHECK(changed.parameter_stddev().size() == 0);
  save_model(temp_path("greybox_no_stddev.json"), changed);
  CHECK(read_text(temp_path("greybox_no_stddev.json")).find("stddev") == std::string::npos);
  CHECK(load_model<GreyBox<physics::Throttle>>(temp_path("greybox_no_stddev.json")).parameter_stddev().size() == 0);

  // Bad deviations in a file are located.
  const std::string text = read_text(path);
  const auto at = text.find("\"stddev\"");
  REQUIRE(at != std::string::npos);
  const std::string first = text.substr(at, text.find(',', at) - at);  // "stddev": [\n  0.5
  const std::string negative = write_text("greybox_stddev_negative.json", edited(text, first, first.substr(0, first.size() - 3) + "-0.5"));
  CHECK_THAT(error_of([&] { (void)load_model(negative); }),
             Catch::Contains("standard deviation of c must be >= 0") && Catch::Contains("stddev"));
  Eigen::VectorXd wrong(2);
  wrong << 1.0, 2.0;
  CHECK_THROWS_WITH(g.set_parameter_stddev(wrong), Catch::Contains("2 standard deviations for 7 parameters"));
  // NaN is an estimate left on a bound: no deviation, said so by describe() and kept by a file.
  Eigen::VectorXd on_bound = sd;
  on_bound[1] = std::nan("");
  g.set_parameter_stddev(on_bound);
  CHECK_THAT(g.describe(), Catch::Contains("estimated, on a bound (no standard deviation)"));
  save_model(path, g);
  const auto reread = load_model<GreyBox<physics::Throttle>>(path);
  REQUIRE(reread.parameter_stddev().size() == n);
  CHECK(std::isnan(reread.parameter_stddev()[1]));
  CHECK(reread.parameter_stddev()[0] == 0.5);
}

TEST_CASE("model file: a grey box keeps its parameter covariance bit for bit, and bad ones are located") {
  GreyBox<physics::Throttle> g;
  CHECK(g.parameter_covariance().size() == 0);
  const Eigen::Index n = g.num_parameters();
  Eigen::MatrixXd a = Eigen::MatrixXd::Random(n, n);
  Eigen::MatrixXd c = a * a.transpose() / 3.0;
  c.row(n - 1).setZero();  // rest: fixed
  c.col(n - 1).setZero();
  g.set_parameter_covariance(c);
  const std::string path = temp_path("greybox_covariance.json");
  save_model(path, g);
  const auto typed = load_model<GreyBox<physics::Throttle>>(path);
  REQUIRE(typed.parameter_covariance().rows() == n);
  CHECK((typed.parameter_covariance() - c).cwiseAbs().maxCoeff() == 0.0);
  const AnyModel any = load_model(path);
  REQUIRE(any.target<DynamicGreyBox>() != nullptr);
  CHECK((any.target<DynamicGreyBox>()->parameter_covariance() - c).cwiseAbs().maxCoeff() == 0.0);

  // A changed value makes it stale: dropped with the deviations.
  GreyBox<physics::Throttle> changed = typed;
  changed.set_parameter("k", 900.0);
  CHECK(changed.parameter_covariance().size() == 0);
  save_model(temp_path("greybox_no_covariance.json"), changed);
  CHECK(read_text(temp_path("greybox_no_covariance.json")).find("covariance") == std::string::npos);

  // In the API, what is wrong is said.
  CHECK_THROWS_WITH(g.set_parameter_covariance(Eigen::MatrixXd::Identity(2, 2)),
                    Catch::Contains("a 2x2 parameter covariance for 7 parameters"));
  Eigen::MatrixXd skew = c;
  skew(2, 0) += 1.0;
  CHECK_THROWS_WITH(g.set_parameter_covariance(skew), Catch::Contains("not symmetric (K with c: "));
  Eigen::MatrixXd negative = c;
  negative(1, 1) = -1.0;
  CHECK_THROWS_WITH(g.set_parameter_covariance(negative), Catch::Contains("variance of k must be >= 0"));
  Eigen::MatrixXd nan = c;
  nan(0, 3) = std::nan("");
  CHECK_THROWS_WITH(g.set_parameter_covariance(nan), Catch::Contains("the covariance of c with b is not finite"));

  // In a file, also where.
  Json j = read_json(path);
  j["parameters"]["covariance"][3][1] = 5.0;
  CHECK_THAT(error_of([&] { (void)model_from_json<GreyBox<physics::Throttle>>(j); }),
             Catch::Contains("not symmetric (b with k: ") && Catch::Contains("parameters.covariance"));
  j = read_json(path);
  j["parameters"]["covariance"][4] = Json::array({1.0, 2.0});
  CHECK_THAT(error_of([&] { (void)model_from_json<GreyBox<physics::Throttle>>(j); }),
             Catch::Contains("row 4 of the parameter covariance at parameters.covariance[4] has 2 entries") &&
                 Catch::Contains("7 parameters"));
  j = read_json(path);
  j["parameters"]["covariance"] = Json::array({1.0});
  CHECK_THAT(error_of([&] { (void)model_from_json<GreyBox<physics::Throttle>>(j); }),
             Catch::Contains("must be an array of 7 rows"));
}

TEST_CASE("model file: nonlinear ARX and Hammerstein-Wiener files keep ModelFileInfo's uncertainty, checked") {
  using M = Nlarx<LaggedRegressors<2, 1, 0>, LinearMap<3>>;
  M m(LaggedRegressors<2, 1, 0>{}, LinearMap<3>{}, 0.01);
  m.set_parameters(Eigen::Vector4d(1.3, -0.45, 0.2, 0.7));
  const Eigen::Index n = m.num_parameters();
  // As parameter_uncertainty leaves it with an estimated initial state: one more unknown at the
  // end, whose block the file does not keep.
  std::vector<std::string> names = m.parameter_names();
  names.push_back("x0[0]");
  Eigen::VectorXd theta(n + 1);
  theta << m.parameters(), 3.0;
  Eigen::MatrixXd a = Eigen::MatrixXd::Random(n + 1, n + 1);
  Eigen::MatrixXd c = a * a.transpose() / 7.0;
  Eigen::VectorXd sd = c.diagonal().cwiseSqrt();
  sd[1] = std::numeric_limits<double>::infinity();  // left open by the data
  ModelFileInfo info;
  info.uncertainty = uncertainty_from_covariance(names, theta, c, sd);
  const std::string path = temp_path("nlarx_covariance.json");
  save_model(path, m, info);
  const std::string text = read_text(path);
  CHECK(text.find("x0[0]") == std::string::npos);
  {
    // A top-level member, which readers that predate it ignore; "parameters" stays as it was.
    const Json saved = read_json(path);
    CHECK(saved.view().at("uncertainty").contains("covariance"));
    CHECK(saved.view().at("uncertainty").contains("stddev"));
    CHECK_FALSE(saved.view().at("parameters").contains("covariance"));
    CHECK(saved.view().at("uncertainty").contains("at"));  // the values it belongs to
  }

  ModelFileInfo back;
  const M typed = load_model<M>(path, &back);
  REQUIRE(back.uncertainty.has_value());
  CHECK(bit_equal(back.uncertainty->covariance, c.topLeftCorner(n, n)));
  CHECK(bit_equal(back.uncertainty->stddev, sd.head(n)));
  CHECK(bit_equal(back.uncertainty->theta, m.parameters()));
  CHECK(back.uncertainty->names == m.parameter_names());
  CHECK_THAT(back.uncertainty->caveat, Catch::Contains("not determined") && Catch::Contains(m.parameter_names()[1]));
  // A prototype filled from the file gets it too.
  M proto(LaggedRegressors<2, 1, 0>{}, LinearMap<3>{}, 0.01);
  ModelFileInfo restored;
  load_model(path, proto, &restored);
  REQUIRE(restored.uncertainty.has_value());
  CHECK(bit_equal(restored.uncertainty->covariance, c.topLeftCorner(n, n)));

  // The run-time model keeps it in its info, writes it again, and drops it when θ changes.
  AnyModel any = load_model(path);
  REQUIRE(any.info().uncertainty.has_value());
  const std::string again = temp_path("nlarx_covariance_again.json");
  any.save(again);
  CHECK(bit_equal(load_model(again).info().uncertainty->covariance, c.topLeftCorner(n, n)));
  any.set_parameters(any.parameters());  // the same values: still the estimate's
  CHECK(any.info().uncertainty.has_value());
  Eigen::VectorXd moved = any.parameters();
  moved[3] += 0.1;
  any.set_parameters(moved);
  CHECK_FALSE(any.info().uncertainty.has_value());
  any.save(again);
  CHECK(read_text(again).find("covariance") == std::string::npos);
  CHECK_FALSE(load_model(again).info().uncertainty.has_value());

  // A file whose parameter was edited by hand after the estimation: its covariance describes
  // another estimate. The model loads; the uncertainty is left out, and the reason kept.
  {
    Json edited = read_json(path);
    Json& v = edited["parameters"]["values"][2];
    v = v.as_number() + 0.05;
    const std::string tuned = temp_path("nlarx_covariance_tuned.json");
    write_file_atomically(tuned, edited.dump(2));
    ModelFileInfo left;
    const M t = load_model<M>(tuned, &left);
    CHECK(t.parameters()[2] == m.parameters()[2] + 0.05);
    CHECK_FALSE(left.uncertainty.has_value());
    CHECK_THAT(left.uncertainty_left_out, Catch::Contains(m.parameter_names()[2] + " = 0.2") &&
                                              Catch::Contains("changed after the estimation"));
    const AnyModel held = load_model(tuned);
    CHECK_FALSE(held.info().uncertainty.has_value());
    const Dataset d(Experiment(Eigen::VectorXd::LinSpaced(50, -1.0, 1.0), Eigen::VectorXd::Zero(50), 0.01));
    CHECK_THROWS_WITH(simulation_band(held, d), Catch::Contains("covariance was not loaded") &&
                                                    Catch::Contains("changed after the estimation"));
    // An "at" of the wrong length is a malformed file, named by its key path.
    edited = read_json(path);
    edited["uncertainty"]["at"].as_array().pop_back();
    write_file_atomically(tuned, edited.dump(2));
    CHECK_THROWS_WITH(load_model<M>(tuned), Catch::Contains("uncertainty.at") && Catch::Contains("3 values"));
  }

  // Saving an uncertainty of other values or another model is refused, naming the parameter.
  M other = typed;
  other.set_parameters(moved);
  CHECK_THAT(error_of([&] { save_model(temp_path("stale.json"), other, back); }),
             Catch::Contains("was computed at") && Catch::Contains("reset ModelFileInfo::uncertainty"));
  ModelFileInfo foreign;
  foreign.uncertainty = uncertainty_from_covariance({"p", "q", "r", "s"}, m.parameters(), c.topLeftCorner(n, n));
  CHECK_THAT(error_of([&] { save_model(temp_path("foreign.json"), m, foreign); }),
             Catch::Contains("parameter 0 is '" + m.parameter_names()[0] + "' in the model but 'p'"));
  ModelFileInfo small;
  small.uncertainty = uncertainty_from_covariance({"p"}, Eigen::VectorXd::Ones(1), Eigen::MatrixXd::Identity(1, 1));
  CHECK_THAT(error_of([&] { save_model(temp_path("small.json"), m, small); }),
             Catch::Contains("covers 1 unknowns") && Catch::Contains("the model has 4 parameters"));

  // A damaged uncertainty in a file: what and where.
  Json j = read_json(path);
  j["uncertainty"]["covariance"][2][0] = 5.0;
  CHECK_THAT(error_of([&] { (void)model_from_json<M>(j); }),
             Catch::Contains("not symmetric") && Catch::Contains("uncertainty.covariance[2]"));
  j = read_json(path);
  j["uncertainty"]["covariance"] = Json::array({1.0});
  CHECK_THAT(error_of([&] { (void)model_from_json<M>(j); }), Catch::Contains("must be an array of 4 rows"));
  j = read_json(path);
  j["uncertainty"]["stddev"] = Json::array({1.0});
  CHECK_THAT(error_of([&] { (void)model_from_json<M>(j); }),
             Catch::Contains("1 standard deviations at uncertainty.stddev") && Catch::Contains("4 parameters"));
  j = read_json(path);
  j["uncertainty"]["stddev"][2] = -1.0;
  CHECK_THAT(error_of([&] { (void)model_from_json<M>(j); }),
             Catch::Contains("standard deviation of " + m.parameter_names()[2]) &&
                 Catch::Contains("uncertainty.stddev[2]") && Catch::Contains(">= 0"));
  j = read_json(path);
  j["uncertainty"]["covariance"][3][3] = -1.0;
  CHECK_THAT(error_of([&] { (void)model_from_json<M>(j); }),
             Catch::Contains("must be >= 0") && Catch::Contains("uncertainty.covariance[3]"));
  j = read_json(path);
  j["uncertainty"]["covariance"][3][1] = "nan";
  j["uncertainty"]["covariance"][1][3] = "nan";
  CHECK_THAT(error_of([&] { (void)model_from_json<M>(j); }),
             Catch::Contains("is not finite") && Catch::Contains("uncertainty.covariance[1]"));
  j = read_json(path);
  j["uncertainty"].erase("covariance");
  CHECK_THAT(error_of([&] { (void)model_from_json<M>(j); }), Catch::Contains("covariance"));
  j = read_json(path);
  j["uncertainty"]["variance"] = 1.0;
  CHECK_THAT(error_of([&] { (void)model_from_json<M>(j); }), Catch::Contains("variance"));
  // An uncertainty a reader would refuse is not written.
  ModelFileInfo bad = info;
  bad.uncertainty->covariance(0, 1) += 1.0;
  CHECK_THAT(error_of([&] { save_model(temp_path("bad_uncertainty.json"), m, bad); }),
             Catch::Contains("the uncertainty to save") && Catch::Contains("not symmetric"));
  ModelFileInfo unnamed = info;
  unnamed.uncertainty->names.clear();  // names are optional in a hand-built uncertainty
  CHECK_NOTHROW(save_model(temp_path("unnamed_uncertainty.json"), m, unnamed));

  // Hammerstein-Wiener, through the run-time model: the same round trip.
  HammersteinWiener hw(UnitGain{}, TransferFunctionBlock<Dynamic, Dynamic, Dynamic>(2, 2, 1), DeadZone(-0.1, 0.2));
  Eigen::VectorXd t2(hw.num_parameters());
  t2 << 0.3, 0.2, -1.1, 0.3, -0.05, 0.07;
  hw.set_parameters(t2);
  Eigen::MatrixXd b = Eigen::MatrixXd::Random(6, 6);
  ModelFileInfo hinfo;
  hinfo.uncertainty = uncertainty_from_covariance(hw.parameter_names(), t2, b * b.transpose());
  const std::string hpath = temp_path("hw_covariance.json");
  AnyModel(hw, hinfo).save(hpath);
  const AnyModel hback = load_model(hpath);
  REQUIRE(hback.info().uncertainty.has_value());
  CHECK(bit_equal(hback.info().uncertainty->covariance, b * b.transpose()));
  // A grey box keeps its own (parameters.covariance); the info member is not used for it.
  GreyBox<physics::Throttle> g;
  const Eigen::Index ng = g.num_parameters();
  Eigen::MatrixXd ag = Eigen::MatrixXd::Random(ng, ng);
  g.set_parameter_covariance(ag * ag.transpose());
  save_model(temp_path("greybox_info.json"), g);
  ModelFileInfo ginfo;
  const auto gback = load_model<GreyBox<physics::Throttle>>(temp_path("greybox_info.json"), &ginfo);
  CHECK_FALSE(ginfo.uncertainty.has_value());
  CHECK(bit_equal(gback.parameter_covariance(), ag * ag.transpose()));
}

TEST_CASE("model file: a grey box's integrator options round-trip field by field") {
  // Every field differs from its default and from the others, so a field written or read under
  // another's key cannot go unnoticed.
  GreyBox<physics::Throttle> g;
  IntegratorOptions o;
  o.method = IntegratorMethod::dormand_prince;
  o.substeps = 7;
  o.min_substeps = 3;
  o.max_substeps = 900;
  o.stability_target = 0.75;
  o.relative_tolerance = std::nextafter(1e-7, 1.0);
  o.absolute_tolerance = std::nextafter(3e-10, 1.0);
  o.max_adaptive_steps = 12345;
  g.set_integrator(o);
  const std::string path = temp_path("greybox_integrator.json");
  save_model(path, g);
  for (int typed = 0; typed < 2; ++typed) {
    CAPTURE(typed);
    IntegratorOptions r;
    if (typed == 1) {
      r = load_model<GreyBox<physics::Throttle>>(path).integrator();
    } else {
      const AnyModel any = load_model(path);
      const auto* dyn = any.target<DynamicGreyBox>();
      REQUIRE(dyn != nullptr);
      r = dyn->integrator();
    }
    CHECK(r.method == IntegratorMethod::dormand_prince);
    CHECK(r.substeps == 7);
    CHECK(r.min_substeps == 3);
    CHECK(r.max_substeps == 900);
    CHECK(r.stability_target == 0.75);
    CHECK(r.relative_tolerance == o.relative_tolerance);
    CHECK(r.absolute_tolerance == o.absolute_tolerance);
    CHECK(r.max_adaptive_steps == 12345);
  }
}

TEST_CASE("model file: linear ARX, OE and state-space models") {
  const Experiment e = test_experiment(300, 5);
  Experiment small = e;
  Arx arx(Eigen::Vector2d(-1.5, 0.7), {Eigen::Vector2d(0.3, 0.1 / 3.0)}, {1}, 0.01, 0.125);
  OutputError oe({Eigen::Vector2d(0.2, 1.0 / 7.0)}, {Eigen::Vector2d(-1.1, 0.3)}, {0}, 0.01);
  Eigen::MatrixXd A(2, 2), B(2, 1), C(1, 2), D(1, 1);
  A << 0.9, 0.1, -0.05, 0.8;
  B << 1.0 / 3.0, 0.5;
  C << 1.0, 0.25;
  D << 0.0;
  StateSpace ss(A, B, C, D, 0.01);
  ss.set_offset(Eigen::VectorXd::Constant(1, 15.0));

  for (const AnyModel& m : {AnyModel(arx), AnyModel(oe), AnyModel(ss)}) {
    const std::string p = temp_path("linear_" + m.kind() + ".json");
    m.save(p);
    const AnyModel back = load_model(p);
    INFO(m.kind());
    CHECK(back.kind() == m.kind());
    CHECK(bit_equal(back.simulate(small, InitialCondition::zero), m.simulate(small, InitialCondition::zero)));
    CHECK(bit_equal(back.parameters(), m.parameters()));
    CHECK(back.parameter_names() == m.parameter_names());
  }
  // A state-space model keeps its channel names (tools find the input column by them).
  ss.set_input_names({"command"});
  ss.set_output_names({"angle"});
  const std::string ps = temp_path("state_space_named.json");
  save_model(ps, ss);
  const StateSpace ss_back = load_model<StateSpace>(ps);
  CHECK(ss_back.input_names() == std::vector<std::string>{"command"});
  CHECK(ss_back.output_names() == std::vector<std::string>{"angle"});
  CHECK(load_model(ps).input_names() == std::vector<std::string>{"command"});
  const std::string p = temp_path("arx_typed.json");
  save_model(p, arx);
  const Arx back = load_model<Arx>(p);
  CHECK(back.offset() == 0.125);
  CHECK(bit_equal(back.b(0), arx.b(0)));
}

TEST_CASE("model file: estimated linear models keep their report and standard deviations, and an edit of one copy of the coefficients is refused") {
  // ARX data with noise, so that the estimate has a report and non-zero standard deviations.
  std::mt19937 gen(11);
  std::normal_distribution<double> noise(0.0, 0.05);
  const int n = 400;
  Eigen::MatrixXd u(n, 1), y(n, 1);
  for (int k = 0; k < n; ++k) {
    u(k, 0) = (k / 20) % 2 ? 1.0 : -0.5 + 0.3 * std::sin(0.3 * k);
    y(k, 0) = (k >= 2 ? 1.2 * y(k - 1, 0) - 0.5 * y(k - 2, 0) : 0.0) + (k >= 1 ? 0.4 * u(k - 1, 0) : 0.0) + noise(gen);
  }
  const Dataset data(Experiment(u, y, 0.01, "noisy"));
  const Arx a = arx(data, ArxOrders(2, 1, 1));
  const OutputError o = oe(data, OeOrders(1, 2, 1));
  REQUIRE((a.parameter_stddev().array() > 0).all());
  REQUIRE((o.parameter_stddev().array() > 0).all());
  REQUIRE_FALSE(a.report().method.empty());

  const std::string pa = temp_path("arx_estimated.json"), po = temp_path("oe_estimated.json");
  save_model(pa, a);
  save_model(po, o);
  const Arx a2 = load_model<Arx>(pa);
  const OutputError o2 = load_model<OutputError>(po);
  CHECK(bit_equal(a2.parameter_stddev(), a.parameter_stddev()));
  CHECK(bit_equal(o2.parameter_stddev(), o.parameter_stddev()));
  CHECK(a2.report().fit_percent == a.report().fit_percent);
  CHECK(o2.report().iterations == o.report().iterations);
  CHECK(a2.describe() == a.describe());  // "+/-" and the report included
  CHECK(o2.describe() == o.describe());
  CHECK(load_model(pa).describe() == a.describe());

  // The structure holds the coefficients; "parameters" repeats them. Editing one copy only is refused.
  const std::string text = read_text(pa);
  Json j = read_json(pa);
  j["parameters"]["values"][1] = 0.75;  // a2, while structure.a keeps the estimate
  std::string msg = error_of([&] { (void)model_from_json<Arx>(j); });
  CHECK_THAT(msg, Catch::Contains("parameter a2 is 0.75 at parameters.values[1]") && Catch::Contains("structure"));
  j = read_json(pa);
  j["parameters"]["names"][0] = "alpha1";
  CHECK_THAT(error_of([&] { (void)model_from_json<Arx>(j); }),
             Catch::Contains("do not match the structure's (a1, a2, b1)"));
  j = read_json(pa);
  j["parameters"]["stddev"][2] = -1.0;
  CHECK_THAT(error_of([&] { (void)model_from_json<Arx>(j); }),
             Catch::Contains("the standard deviation of b1 (entry 2) must be finite and >= 0") && Catch::Contains("parameters.stddev"));
  CHECK_THAT(error_of([&] { (void)load_model(write_text("arx_count.json", edited(text, "\"values\": [", "\"values\": [1, "))); }),
             Catch::Contains("4 values at parameters.values") && Catch::Contains("3 parameters"));
  // A parameter the data did not determine has an infinite standard deviation ("not
  // identifiable"), and a multi-output report its fit per output: both survive the file.
  Arx undetermined = a;
  Eigen::VectorXd sd = a.parameter_stddev();
  sd(1) = std::numeric_limits<double>::infinity();
  undetermined.set_parameter_stddev(sd);
  LinearEstimationReport rep = a.report();
  rep.set_fit({91.5, 62.25});
  undetermined.set_report(rep);
  const std::string pu = temp_path("arx_undetermined.json");
  save_model(pu, undetermined);
  const Arx u2 = load_model<Arx>(pu);
  CHECK(bit_equal(u2.parameter_stddev(), sd));
  CHECK(u2.report().fit_per_output == std::vector<double>{91.5, 62.25});
  CHECK(u2.report().fit_percent == 62.25);
  CHECK(u2.describe() == undetermined.describe());
  // Without "parameters" (a hand-written file) the structure alone defines the model.
  j = read_json(pa);
  j.erase("parameters");
  CHECK(bit_equal(model_from_json<Arx>(j).parameters(), a.parameters()));
  // State space: the same check.
  Eigen::MatrixXd A(1, 1), B(1, 1), C(1, 1), D(1, 1);
  A << 0.9;
  B << 0.5;
  C << 1.0;
  D << 0.0;
  const std::string ps = temp_path("ss_edit.json");
  save_model(ps, StateSpace(A, B, C, D, 0.01));
  j = read_json(ps);
  j["parameters"]["values"][0] = 0.95;
  CHECK_THAT(error_of([&] { (void)model_from_json<StateSpace>(j); }), Catch::Contains("parameter A(1,1) is 0.95"));
}

TEST_CASE("model file: doubles are exact, non-finite numbers are spelled out") {
  // Subnormal, tiny, huge, negative zero and 17-digit values survive bit for bit.
  const std::vector<double> v{0.1 + 0.2, 1.0 / 3.0, 5e-324, 1e-300, -0.0, 1.7976931348623157e308, -2.0 / 7.0};
  HammersteinWiener hw(Poly1d<6>{}, TransferFunctionBlock<1, 0, 0>{}, UnitGain{});
  Eigen::VectorXd th(8);
  for (int i = 0; i < 7; ++i) th(i) = v[static_cast<std::size_t>(i)];
  th(7) = 1.0;
  hw.set_parameters(th);
  const std::string p = temp_path("exact.json");
  save_model(p, hw);
  const Eigen::VectorXd back = load_model(p).parameters();
  CHECK(bit_equal(back, th));
  CHECK(std::signbit(back(4)));

  // A tree's unsplit nodes have threshold +inf: written as "inf", read back as inf.
  TreePartition<Dynamic, Dynamic> tree(2, 2);
  const Json j = NonlinearitySerial<TreePartition<Dynamic, Dynamic>>::save(tree);
  CHECK(j.dump().find("\"inf\"") != std::string::npos);
  const auto t2 = NonlinearitySerial<TreePartition<Dynamic, Dynamic>>::load(j.view());
  CHECK(std::isinf(t2.split_threshold(0)));
  // A NaN threshold is refused by the tree, and the file's key path says where it came from.
  Json bad_tree = j;
  bad_tree["splits"][0]["threshold"] = "nan";
  CHECK_THAT(error_of([&] { (void)NonlinearitySerial<TreePartition<Dynamic, Dynamic>>::load(bad_tree.view()); }),
             Catch::Contains("threshold") && Catch::Contains("splits[0]"));

  // A non-finite parameter cannot get into a model (so no file holds one): the error names it.
  Eigen::VectorXd bad = th;
  bad(2) = std::numeric_limits<double>::quiet_NaN();
  CHECK_THAT(error_of([&] { hw.set_parameters(bad); }), Catch::Contains("parameter 2 ('input:c[2]') is NaN"));
}

TEST_CASE("model file: damaged files are refused with the key path, file and line") {
  Nlarx m(RegressorList::lagged(2, 1, 0).add_custom("max(y1(t-1),90)+min(y1(t-1),15)-105"),
          AnyNonlinearity(SigmoidNet<Dynamic, Dynamic>(4, 3)), 0.01);
  const std::string good = temp_path("good.json");
  save_model(good, m);
  const std::string text = read_text(good);
  CHECK_NOTHROW((void)load_model(good));

  const auto fails_with = [&](const std::string& name, const std::string& damaged) {
    const std::string p = write_text(name, damaged);
    return error_of([&] { (void)load_model(p); });
  };
  std::string msg = fails_with("missing_units.json", edited(text, "\"units\": 3,", ""));
  CHECK_THAT(msg, Catch::Contains("missing key 'units' at structure.nonlinearity") && Catch::Contains("missing_units.json"));
  msg = fails_with("wrong_type.json", edited(text, "\"units\": 3", "\"units\": \"three\""));
  CHECK_THAT(msg, Catch::Contains("expected number at structure.nonlinearity.units") && Catch::Contains("row "));
  msg = fails_with("bad_expr.json", edited(text, "max(y1(t-1),90)", "max(y1(t-1),,90)"));
  CHECK_THAT(msg, Catch::Contains("column 13") && Catch::Contains("structure.regressors.blocks[2].expression"));
  msg = fails_with("unknown_nl.json", edited(text, "\"sigmoidnet\"", "\"neuralnet\""));
  CHECK_THAT(msg, Catch::Contains("unknown nonlinearity \"neuralnet\"") && Catch::Contains("accepted: unitgain"));
  msg = fails_with("typo.json", edited(text, "\"standardize\"", "\"standardise\""));
  CHECK_THAT(msg, Catch::Contains("unknown key 'standardise'"));
  msg = fails_with("count.json", edited(text, "\"values\": [", "\"values\": [1, "));
  CHECK_THAT(msg, Catch::Contains("the file has 24 parameter values at parameters.values") && Catch::Contains("structure has 23"));
  msg = fails_with("truncated.json", text.substr(0, text.size() / 2));
  CHECK_THAT(msg, Catch::Contains("truncated.json") && Catch::Contains("row "));
  msg = fails_with("not_model.json", "{\"format\": \"something-else\", \"version\": 1}");
  CHECK_THAT(msg, Catch::Contains("not an nlid model file"));
  msg = fails_with("no_format.json", "{\"kind\": \"nlarx\"}");
  CHECK_THAT(msg, Catch::Contains("missing key 'format'"));
  msg = fails_with("newer.json", edited(text, "\"version\": 1", "\"version\": 2"));
  CHECK_THAT(msg, Catch::Contains("model file version 2 is newer than this nlid can read") &&
                      Catch::Contains("update nlid"));
  msg = fails_with("kind.json", edited(text, "\"kind\": \"nlarx\"", "\"kind\": \"neural_ode\""));
  CHECK_THAT(msg, Catch::Contains("unknown model kind \"neural_ode\"") && Catch::Contains("greybox"));
  msg = fails_with("ts.json", edited(text, "\"ts\": 0.01", "\"ts\": -1"));
  CHECK_THAT(msg, Catch::Contains("sample time at ts must be >= 0"));
  msg = fails_with("ic.json", edited(text, "\"initial_condition\": \"zero\"", "\"initial_condition\": \"warm\""));
  CHECK_THAT(msg, Catch::Contains("unknown initial condition \"warm\""));
  msg = fails_with("scale.json", edited(text, "\"scale\": [", "\"scale\": [-1, "));
  CHECK_THAT(msg, Catch::Contains("scale"));
  CHECK_THAT(error_of([] { (void)load_model("/nonexistent/dir/model.json"); }), Catch::Contains("file not found"));
  // A C++ lambda regressor without an expression can only go into a prototype.
  Nlarx lambda_model(RegressorSet{LaggedRegressors<1, 1, 0>{},
                                  custom_regressor<OutputLag<1>>("", [](auto y) { return y * y; })},
                     LinearMap<3>{});
  save_model(temp_path("lambda.json"), lambda_model);
  CHECK_THAT(error_of([&] { (void)load_model(temp_path("lambda.json")); }),
             Catch::Contains("was a C++ function without an expression") && Catch::Contains("prototype"));
  auto proto = lambda_model;
  CHECK_NOTHROW(load_model(temp_path("lambda.json"), proto));
  // A lambda whose name parses as an expression that computes something else is saved by name
  // only: written as that expression it would load as a different model, silently.
  Nlarx misnamed(RegressorSet{LaggedRegressors<1, 1, 0>{},
                              custom_regressor<OutputLag<1>, InputLag<1>>("y1(t-1)+u1(t-1)",
                                                                           [](auto y, auto u) { return y * u; })},
                 LinearMap<3>{});
  save_model(temp_path("misnamed.json"), misnamed);
  CHECK_THAT(read_text(temp_path("misnamed.json")), Catch::Contains("\"expression\": null"));
  CHECK_THAT(error_of([&] { (void)load_model(temp_path("misnamed.json")); }),
             Catch::Contains("was a C++ function without an expression"));
  // Named after what it computes (the study's hard-stop spring), the expression is written.
  Nlarx named(RegressorSet{LaggedRegressors<1, 1, 0>{},
                           custom_regressor<OutputLag<1>, InputLag<1>>("y1(t-1)*u1(t-1)",
                                                                        [](auto y, auto u) { return y * u; })},
              LinearMap<3>{});
  save_model(temp_path("named.json"), named);
  CHECK_THAT(read_text(temp_path("named.json")), Catch::Contains("\"expression\": \"y1(t-1)*u1(t-1)\""));
  CHECK_NOTHROW(load_model(temp_path("named.json")));
}

TEST_CASE("model file: writes are atomic and errors name the file") {
  HammersteinWiener hw(UnitGain{}, TransferFunctionBlock<Dynamic, Dynamic, Dynamic>(1, 1, 0), UnitGain{});
  const std::string dir = temp_dir() + "/atomic";
  fs::create_directories(dir);
  const std::string p = dir + "/m.json";
  save_model(p, hw);
  const std::string first = read_text(p);
  Eigen::VectorXd th(2);
  th << 0.5, -0.25;
  hw.set_parameters(th);
  save_model(p, hw);  // replaces the old file
  CHECK(read_text(p) != first);
  int files = 0;
  for (const auto& entry : fs::directory_iterator(dir)) {
    (void)entry;
    ++files;
  }
  CHECK(files == 1);  // no temporary left behind
  const std::string msg = error_of([&] { save_model(dir + "/missing/m.json", hw); });
  CHECK_THAT(msg, Catch::Contains("directory does not exist") && Catch::Contains("missing/m.json"));
  CHECK(read_text(p).back() == '\n');
  const Json j = read_model_file(p);
  CHECK(j.at("format").as_string() == "nlid-model");
  CHECK(j.at("version").as_integer() == model_file_version);
  CHECK(j.at("created").as_string().size() == 20);
}
