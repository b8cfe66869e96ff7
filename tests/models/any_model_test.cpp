// AnyModel (type-erased models with value semantics), AnyNonlinearity, run-time structures
// equal to compile-time ones, the model-kind registry.
#include <catch2/catch.hpp>

#include <bit>
#include <cmath>
#include <cstdint>
#include <random>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "nlid/models/any_model.hpp"
#include "nlid/nonlinearities.hpp"
#include "nlid/nonlinearities/any_nonlinearity.hpp"
#include "nlid/regressors.hpp"
#include "nlid/regressors/expression.hpp"

using namespace nlid;

namespace {

Experiment record(int n = 400, unsigned seed = 1) {
  std::mt19937 gen(seed);
  std::uniform_real_distribution<double> level(-1.0, 1.0);
  Eigen::MatrixXd u(n, 1), y(n, 1);
  double s = 0, cur = 0;
  for (int k = 0; k < n; ++k) {
    if (k % 40 == 0) cur = level(gen);
    u(k, 0) = cur;
    s = 0.9 * s + 0.5 * cur + 0.1 * std::tanh(3 * s);
    y(k, 0) = s;
  }
  return Experiment(u, y, 0.01, "rec");
}

bool bit_equal(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  if (a.rows() != b.rows() || a.cols() != b.cols()) return false;
  for (Eigen::Index i = 0; i < a.size(); ++i)
    if (std::bit_cast<std::uint64_t>(a.data()[i]) != std::bit_cast<std::uint64_t>(b.data()[i])) return false;
  return true;
}

template <class M>
void initialise(M& m, const Experiment& e) {
  const Eigen::MatrixXd X = m.regressor_values(e);
  const Eigen::VectorXd y = e.y().col(0).tail(X.rows());
  Eigen::VectorXd th(m.num_parameters());
  m.nonlinearity().initialize(X, y, std::span<double>(th.data(), static_cast<std::size_t>(th.size())));
  m.set_parameters(th);
}

}  // namespace

static_assert(Nonlinearity<AnyNonlinearity>);
static_assert(ScalarNonlinearity<AnyNonlinearity>);
static_assert(Model<AnyModel>);
static_assert(ModelStructure<DynamicNlarx>);
static_assert(ModelStructure<DynamicHammersteinWiener>);

TEST_CASE("AnyNonlinearity evaluates exactly like the held map, on double and Dual") {
  const Experiment e = record();
  Eigen::MatrixXd X(e.size(), 2);
  X.col(0) = e.u().col(0);
  X.col(1) = e.y().col(0);
  const Eigen::VectorXd y = (X.col(0).array() * X.col(1).array()).matrix();
  SigmoidNet<Dynamic, Dynamic> typed(2, 4);
  Eigen::VectorXd th(typed.num_parameters());
  typed.initialize(X, y, std::span<double>(th.data(), static_cast<std::size_t>(th.size())));
  AnyNonlinearity any = typed;
  CHECK(any.kind() == "sigmoidnet");
  CHECK(any.has_linear_term());
  CHECK(any.input_dimension() == 2);
  CHECK(any.num_parameters() == typed.num_parameters());
  CHECK(any.parameter_names() == typed.parameter_names());
  const std::span<const double> ts(th.data(), static_cast<std::size_t>(th.size()));
  for (Eigen::Index i = 0; i < X.rows(); i += 37) {
    const Eigen::RowVectorXd xi = X.row(i);
    const std::span<const double> xs(xi.data(), 2);
    CHECK(std::bit_cast<std::uint64_t>(any(xs, ts)) == std::bit_cast<std::uint64_t>(typed(xs, ts)));
  }
  using D = Dual<double, 2>;
  std::vector<D> xd{D::variable(0.3, 0, 2), D::variable(-0.2, 1, 2)};
  std::vector<D> thd(th.data(), th.data() + th.size());
  const D a = any(std::span<const D>(xd), std::span<const D>(thd));
  const D b = typed(std::span<const D>(xd), std::span<const D>(thd));
  CHECK(a.a == b.a);
  CHECK(a.v == b.v);
  CHECK_THAT(any.describe(ts), Catch::Contains("sigmoid network"));
}

TEST_CASE("make_nonlinearity builds every kind by name and names what it accepts") {
  for (const char* k : {"sigmoidnet", "wavenet", "treepartition", "linear"}) {
    const AnyNonlinearity f = make_nonlinearity(k, 3);
    CHECK(f.kind() == k);
    CHECK(f.input_dimension() == 3);
  }
  for (const char* k : {"unitgain", "pwlinear", "saturation", "deadzone", "poly1d"}) {
    const AnyNonlinearity f = make_nonlinearity(k, 1);
    CHECK(f.kind() == k);
  }
  NonlinearityOptions o;
  o.units = 7;
  o.linear_term = false;
  const AnyNonlinearity s = make_nonlinearity("sigmoidnet", 2, o);
  CHECK(!s.has_linear_term());
  CHECK(s.get_if<SigmoidNet<Dynamic, Dynamic, false>>()->units() == 7);
  o.limits = std::make_pair(15.0, 90.0);
  CHECK(make_nonlinearity("saturation", 1, o).get_if<Saturation>()->initial_limits()->second == 90.0);
  o.degree = 4;
  CHECK(make_nonlinearity("poly1d", 1, o).num_parameters() == 5);
  CHECK_THROWS_WITH(make_nonlinearity("neuralnet", 2), Catch::Contains("unknown nonlinearity 'neuralnet'") &&
                                                            Catch::Contains("accepted: unitgain"));
  CHECK_THROWS_WITH(make_nonlinearity("saturation", 3), Catch::Contains("has one input but 3"));
  CHECK_THROWS_WITH(make_nonlinearity("linear", 0), Catch::Contains("at least one input"));
}

TEST_CASE("run-time nlarx (RegressorList + AnyNonlinearity) simulates bit for bit like the typed one") {
  const Experiment e = record(500, 4);
  Nlarx typed(RegressorSet{LaggedRegressors<3, 3, 0>{},
                           custom_regressor<OutputLag<1>>("max(y1(t-1),0.5)+min(y1(t-1),-0.5)",
                                                          [](auto y) { return nlid::max(y, 0.5) + nlid::min(y, -0.5); })},
              SigmoidNet<7, 5>{}, 0.01);
  initialise(typed, e);
  RegressorList regs = RegressorList::lagged(3, 3, 0);
  regs.add_custom("max(y1(t-1),0.5)+min(y1(t-1),-0.5)");
  SigmoidNet<Dynamic, Dynamic> net(7, 5);
  net.set_normalization(typed.nonlinearity().center(), typed.nonlinearity().scale());
  DynamicNlarx dyn(regs, AnyNonlinearity(net), 0.01);
  dyn.set_parameters(typed.parameters());
  // Same normalisation up to the reciprocal of the scale; same operations.
  const Eigen::MatrixXd a = typed.simulate(e, InitialCondition::measured);
  const Eigen::MatrixXd b = dyn.simulate(e, InitialCondition::measured);
  CHECK((a - b).cwiseAbs().maxCoeff() <= 1e-12 * (1.0 + a.cwiseAbs().maxCoeff()));
  CHECK(dyn.regressor_names() == typed.regressor_names());

  // Through AnyModel: the file round trip is exact (tested in io), the erased calls are the model's.
  const AnyModel any(typed);
  CHECK(bit_equal(any.simulate(e, InitialCondition::measured), a));
  CHECK(bit_equal(any.predict(e, 3), typed.predict(e, 3)));
  CHECK(any.describe() == typed.describe());
  CHECK(any.num_inputs() == 1);
  CHECK(any.num_outputs() == 1);
  CHECK(any.ts() == 0.01);
  CHECK(any.parameter_names() == typed.parameter_names());
}

TEST_CASE("run-time nlarx whose state would overflow an int is refused at construction") {
  // Each factor is legal on its own (lag 10^5 = max_model_order, channel 30 000 of 30 000 named
  // inputs), the state Ly + nu*Lu = 3*10^9 values is not: state_dimension() returned a negative int.
  std::vector<std::string> names;
  for (int c = 1; c <= 30000; ++c) names.push_back("in" + std::to_string(c));
  RegressorList huge;
  huge.add_custom("in30000(t-100000)", names);
  CHECK_THROWS_WITH(DynamicNlarx(huge, AnyNonlinearity(LinearMap<Dynamic>(1)), 0.01),
                    Catch::Contains("state would hold 3000000000 values") &&
                        Catch::Contains("30000 input channels x input lag 100000") && Catch::Contains("regressors"));
  // The largest state that still fits is built.
  RegressorList big;
  big.add_custom("in20000(t-100000)", names);
  const DynamicNlarx ok(big, AnyNonlinearity(LinearMap<Dynamic>(1)), 0.01);
  CHECK(ok.state_dimension() == 2000000000);
}

TEST_CASE("AnyModel has value semantics and reaches the held model") {
  HammersteinWiener hw(UnitGain{}, TransferFunctionBlock<2, 2, 0>{}, Saturation(-0.5, 0.5), 0.01);
  Eigen::VectorXd th(hw.num_parameters());
  th << 0.2, 0.1, -1.2, 0.4, -0.5, 0.5;
  hw.set_parameters(th);
  AnyModel a(hw);
  AnyModel b = a;
  Eigen::VectorXd th2 = th;
  th2(0) = 0.3;
  b.set_parameters(th2);
  CHECK(a.parameters()(0) == 0.2);
  CHECK(b.parameters()(0) == 0.3);
  CHECK(a.target<decltype(hw)>() != nullptr);
  CHECK(a.target<DynamicHammersteinWiener>() == nullptr);
  CHECK(a.kind() == "hammerstein_wiener");
  CHECK_FALSE(a.is_linear());
  const Experiment e = record();
  CHECK(bit_equal(a.predict(e, 1), hw.predict(e, 1)));  // the held model's own predictor
  AnyModel moved = std::move(b);
  CHECK(moved.parameters()(0) == 0.3);
  CHECK_THROWS_WITH(b.parameters(), Catch::Contains("AnyModel is empty"));  // NOLINT(bugprone-use-after-move)
  AnyModel empty;
  CHECK(empty.empty());
  CHECK_THROWS_WITH(empty.simulate(e), Catch::Contains("AnyModel is empty"));
  CHECK_THROWS_WITH(a.set_parameters(Eigen::VectorXd::Zero(2)), Catch::Contains("parameter vector has 2 values"));
}

TEST_CASE("AnyModel: linear models take parameter vectors, state space explains why it cannot") {
  Arx arx(Eigen::Vector2d(-1.5, 0.7), {Eigen::Vector2d(0.3, 0.1)}, {1}, 0.01, 0.5);
  AnyModel a(arx);
  Eigen::VectorXd th = a.parameters();
  REQUIRE(th.size() == 5);
  th(4) = 0.25;
  a.set_parameters(th);
  CHECK(a.target<Arx>()->offset() == 0.25);
  OutputError oe({Eigen::Vector2d(0.2, 0.1)}, {Eigen::Vector2d(-1.1, 0.3)}, {0}, 0.01);
  AnyModel o(oe);
  Eigen::VectorXd t2 = o.parameters();
  t2(2) = -1.0;
  o.set_parameters(t2);
  CHECK(o.target<OutputError>()->f(0)(0) == -1.0);
  StateSpace ss(Eigen::MatrixXd::Identity(1, 1) * 0.5, Eigen::MatrixXd::Ones(1, 1), Eigen::MatrixXd::Ones(1, 1),
                Eigen::MatrixXd::Zero(1, 1), 0.01);
  AnyModel s(ss);
  CHECK(s.parameters().size() == 4);
  CHECK(s.parameter_names()[0] == "A(1,1)");
  CHECK_THROWS_WITH(s.set_parameters(s.parameters()), Catch::Contains("state_space model cannot take a parameter vector"));
  CHECK(a.is_linear());
  CHECK(o.is_linear());
  CHECK(s.is_linear());
}

TEST_CASE("model kinds: the built-in list and registering a new kind") {
  const auto kinds = model_kinds();
  for (const char* k : {"arx", "greybox", "hammerstein_wiener", "nlarx", "output_error", "state_space"}) {
    CHECK(std::find(kinds.begin(), kinds.end(), k) != kinds.end());
  }
  register_model_kind("test_alias_of_arx", [](const JsonView& file, ModelFileInfo& info) {
    Json copy = file.json();
    copy["kind"] = "arx";
    return AnyModel(ModelSerial<Arx>::load(copy.view(), info), info);
  });
  CHECK_THROWS_WITH(register_model_kind("nlarx", [](const JsonView&, ModelFileInfo&) { return AnyModel(); }),
                    Catch::Contains("already registered"));
  Arx arx(Eigen::VectorXd::Constant(1, -0.5), {Eigen::VectorXd::Ones(1)}, {1}, 0.1);
  Json j = model_to_json(arx);
  j["kind"] = "test_alias_of_arx";
  const AnyModel m = any_model_from_json(j);
  CHECK(m.kind() == "arx");
  CHECK(m.parameters() == arx.parameters());
}
