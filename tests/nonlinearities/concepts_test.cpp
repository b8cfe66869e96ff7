// Compile-time contract checks: every nlid nonlinearity models `Nonlinearity`, the static sizes
// are right, and types that miss a member of the contract are rejected.
#include <catch2/catch.hpp>

#include <span>
#include <string>
#include <vector>

#include "nlid/nonlinearities.hpp"

namespace {

using nlid::Dynamic;

// A complete user-defined nonlinearity: must be accepted.
struct Square {
  static constexpr int num_inputs = 1;
  static constexpr int num_params = 1;
  int input_dimension() const { return 1; }
  int num_parameters() const { return 1; }
  template <class T>
  T operator()(std::span<const T> x, std::span<const T> th) const { return th[0] * x[0] * x[0]; }
  void initialize(const Eigen::MatrixXd&, const Eigen::VectorXd&, std::span<double> th) { th[0] = 1; }
  std::vector<std::string> parameter_names() const { return {"k"}; }
  std::string describe(std::span<const double>) const { return "k x^2"; }
};

// Same, but without num_params.
struct NoNumParams {
  static constexpr int num_inputs = 1;
  int input_dimension() const { return 1; }
  int num_parameters() const { return 1; }
  template <class T>
  T operator()(std::span<const T> x, std::span<const T>) const { return x[0]; }
  void initialize(const Eigen::MatrixXd&, const Eigen::VectorXd&, std::span<double>) {}
  std::vector<std::string> parameter_names() const { return {}; }
  std::string describe(std::span<const double>) const { return ""; }
};

// Evaluates on double only (not a template): cannot give AD Jacobians, so rejected.
struct DoubleOnly {
  static constexpr int num_inputs = 1;
  static constexpr int num_params = 0;
  int input_dimension() const { return 1; }
  int num_parameters() const { return 0; }
  double operator()(std::span<const double> x, std::span<const double>) const { return x[0]; }
  void initialize(const Eigen::MatrixXd&, const Eigen::VectorXd&, std::span<double>) {}
  std::vector<std::string> parameter_names() const { return {}; }
  std::string describe(std::span<const double>) const { return ""; }
};

// No initialize.
struct NoInitialize {
  static constexpr int num_inputs = 1;
  static constexpr int num_params = 0;
  int input_dimension() const { return 1; }
  int num_parameters() const { return 0; }
  template <class T>
  T operator()(std::span<const T> x, std::span<const T>) const { return x[0]; }
  std::vector<std::string> parameter_names() const { return {}; }
  std::string describe(std::span<const double>) const { return ""; }
};

// Invalid static size (zero inputs).
struct ZeroInputs {
  static constexpr int num_inputs = 0;
  static constexpr int num_params = 0;
  int input_dimension() const { return 0; }
  int num_parameters() const { return 0; }
  template <class T>
  T operator()(std::span<const T>, std::span<const T>) const { return T(0); }
  void initialize(const Eigen::MatrixXd&, const Eigen::VectorXd&, std::span<double>) {}
  std::vector<std::string> parameter_names() const { return {}; }
  std::string describe(std::span<const double>) const { return ""; }
};

static_assert(nlid::Nonlinearity<Square>);
static_assert(!nlid::Nonlinearity<NoNumParams>);
static_assert(!nlid::Nonlinearity<DoubleOnly>);
static_assert(!nlid::Nonlinearity<NoInitialize>);
static_assert(!nlid::Nonlinearity<ZeroInputs>);
static_assert(!nlid::Nonlinearity<int>);

static_assert(nlid::Nonlinearity<nlid::UnitGain>);
static_assert(nlid::Nonlinearity<nlid::LinearMap<3>>);
static_assert(nlid::Nonlinearity<nlid::LinearMap<Dynamic>>);
static_assert(nlid::Nonlinearity<nlid::SigmoidNet<3, 5>>);
static_assert(nlid::Nonlinearity<nlid::SigmoidNet<3, 5, false>>);
static_assert(nlid::Nonlinearity<nlid::SigmoidNet<Dynamic, 5>>);
static_assert(nlid::Nonlinearity<nlid::SigmoidNet<3, Dynamic>>);
static_assert(nlid::Nonlinearity<nlid::WaveletNet<2, 4>>);
static_assert(nlid::Nonlinearity<nlid::WaveletNet<Dynamic, Dynamic, false>>);
static_assert(nlid::Nonlinearity<nlid::PwLinear<10>>);
static_assert(nlid::Nonlinearity<nlid::PwLinear<Dynamic>>);
static_assert(nlid::Nonlinearity<nlid::Saturation>);
static_assert(nlid::Nonlinearity<nlid::DeadZone>);
static_assert(nlid::Nonlinearity<nlid::Poly1d<3>>);
static_assert(nlid::Nonlinearity<nlid::Poly1d<Dynamic>>);
static_assert(nlid::Nonlinearity<nlid::TreePartition<3, 2>>);
static_assert(nlid::Nonlinearity<nlid::TreePartition<Dynamic, Dynamic>>);

// Hammerstein–Wiener blocks: one input.
static_assert(nlid::ScalarNonlinearity<nlid::UnitGain>);
static_assert(nlid::ScalarNonlinearity<nlid::PwLinear<10>>);
static_assert(nlid::ScalarNonlinearity<nlid::Saturation>);
static_assert(nlid::ScalarNonlinearity<nlid::SigmoidNet<1, 3>>);
static_assert(!nlid::ScalarNonlinearity<nlid::SigmoidNet<2, 3>>);
static_assert(!nlid::ScalarNonlinearity<nlid::LinearMap<2>>);

// Compile-time sizes, as documented in each header.
static_assert(nlid::UnitGain::num_params == 0);
static_assert(nlid::LinearMap<3>::num_params == 4);
static_assert(nlid::SigmoidNet<3, 5>::num_params == 3 + 1 + 5 * 5);
static_assert(nlid::SigmoidNet<3, 5, false>::num_params == 1 + 5 * 5);
static_assert(nlid::SigmoidNet<Dynamic, 5>::num_params == Dynamic);
static_assert(nlid::WaveletNet<2, 4>::num_params == 2 + 1 + 4 * 5);
static_assert(nlid::WaveletNet<2, 4, false>::num_params == 1 + 4 * 5);
static_assert(nlid::PwLinear<10>::num_params == 20);
static_assert(nlid::PwLinear<Dynamic>::num_params == Dynamic);
static_assert(nlid::Poly1d<3>::num_params == 4);
static_assert(nlid::Saturation::num_params == 2 && nlid::DeadZone::num_params == 2);
static_assert(nlid::TreePartition<3, 2>::num_params == 4 * 4);

// Sizes that make no sense do not instantiate (requires-clauses, not deep errors).
template <int M, int U>
concept SigmoidSizesValid = requires { typename nlid::SigmoidNet<M, U>; nlid::SigmoidNet<M, U>::num_params; };
static_assert(!SigmoidSizesValid<3, 0>);
static_assert(!SigmoidSizesValid<0, 3>);
template <int B>
concept PwSizesValid = requires { nlid::PwLinear<B>::num_params; };
static_assert(!PwSizesValid<1>);
static_assert(PwSizesValid<2>);

}  // namespace

TEST_CASE("a user-defined nonlinearity works through the generic helpers", "[nonlinearities][concepts]") {
  Square f;
  Eigen::MatrixXd X(3, 1);
  X << 1, 2, 3;
  const std::vector<double> th{2.0};
  const Eigen::VectorXd y = nlid::evaluate_rows(f, X, th);
  CHECK(y(0) == 2.0);
  CHECK(y(2) == 18.0);
}
