// Compile-only checks of the regressor and model concepts (mp-units style): every positive case
// is a static_assert, every misuse a `requires !requires` negative. Building this file is the test.
#include <span>

#include "nlid/analysis/concepts.hpp"
#include "nlid/models.hpp"
#include "nlid/models/physics/throttle.hpp"
#include "nlid/nonlinearities.hpp"
#include "nlid/regressors.hpp"

namespace static_checks {

using nlid::Dynamic;

// A type that looks like a nonlinearity but has no `initialize`: not a Nonlinearity.
struct NoInitialize {
  static constexpr int num_inputs = 3;
  static constexpr int num_params = 4;
  int input_dimension() const { return 3; }
  int num_parameters() const { return 4; }
  template <class T>
  T operator()(std::span<const T> x, std::span<const T>) const { return x[0]; }
  std::vector<std::string> parameter_names() const { return {}; }
  std::string describe(std::span<const double>) const { return {}; }
};

template <class R, class F>
concept FormsNlarx = requires { typename nlid::Nlarx<R, F>; };
template <class In, class L, class Out>
concept FormsHw = requires { typename nlid::HammersteinWiener<In, L, Out>; };
// Negative checks must be dependent: a non-dependent invalid expression inside a requires
// expression at namespace scope is a hard error, not `false`.
template <class Lag, class Fn>
concept MakesCustomRegressor = requires(Fn fn) { nlid::custom_regressor<Lag>("", fn); };
template <class... R>
concept FormsRegressorSet = requires { typename nlid::RegressorSet<R...>; };
template <int Nb, int Nf, int Nk>
concept FormsTransferFunction = requires { typename nlid::TransferFunctionBlock<Nb, Nf, Nk>; };
inline auto identity = [](auto y) { return y; };

using Lag210 = nlid::LaggedRegressors<2, 1, 0>;
inline auto spring = nlid::custom_regressor<nlid::OutputLag<1>>(
    "", [](auto y) { return nlid::max(y, 90.0) + nlid::min(y, 15.0) - 105.0; });
using Spring = decltype(spring);

// ---- regressors ------------------------------------------------------------------------------
static_assert(nlid::Regressor<Lag210> && nlid::Regressor<Spring>);
static_assert(nlid::Regressor<nlid::RegressorSet<Lag210, Spring>>);
static_assert(nlid::RegressorSet<Lag210, Spring>::num_regressors == 4);
static_assert(nlid::RegressorSet<nlid::LaggedRegressors<Dynamic, 1, 0>, Spring>::num_regressors == Dynamic);
static_assert(nlid::RegressorSet<nlid::OutputLags<3>, nlid::InputLags<2, 4, 1>>::max_input_lag == 5);
static_assert(!nlid::Regressor<int> && !nlid::Regressor<nlid::LinearMap<3>>);
inline auto double_only = [](double y) { return y; };
static_assert(!nlid::RegressorFunction<decltype(double_only), 1>);
static_assert(MakesCustomRegressor<nlid::OutputLag<1>, decltype(identity)>);
static_assert(!MakesCustomRegressor<nlid::OutputLag<1>, decltype(double_only)>);
static_assert(!MakesCustomRegressor<int, decltype(identity)>);  // not a lag
static_assert(FormsRegressorSet<Lag210, Spring> && !FormsRegressorSet<Lag210, int>);

// ---- Nlarx -----------------------------------------------------------------------------------
static_assert(FormsNlarx<Lag210, nlid::LinearMap<3>>);
static_assert(FormsNlarx<nlid::RegressorSet<Lag210, Spring>, nlid::SigmoidNet<4, 5>>);
static_assert(FormsNlarx<Lag210, nlid::SigmoidNet<Dynamic, Dynamic>>);     // checked at run time
static_assert(!FormsNlarx<Lag210, nlid::LinearMap<4>>);                   // 3 regressors, 4 inputs
static_assert(!FormsNlarx<Lag210, NoInitialize>);                         // not a Nonlinearity
static_assert(!FormsNlarx<int, nlid::LinearMap<3>>);                      // not a Regressor
static_assert(nlid::Nlarx<nlid::LaggedRegressors<3, 3, 0>, nlid::SigmoidNet<6, 5>>::num_params == 47);
static_assert(nlid::ModelStructure<nlid::Nlarx<Lag210, nlid::LinearMap<3>>>);
static_assert(nlid::Model<nlid::Nlarx<Lag210, nlid::LinearMap<3>>>);

// ---- Hammerstein-Wiener ----------------------------------------------------------------------
using Tf330 = nlid::TransferFunctionBlock<3, 3, 0>;
static_assert(nlid::LinearBlock<Tf330> && Tf330::num_states == 3);
static_assert(nlid::LinearBlock<nlid::TransferFunctionBlock<Dynamic, Dynamic, Dynamic>>);
static_assert(FormsHw<nlid::UnitGain, Tf330, nlid::Saturation>);
static_assert(FormsHw<nlid::PwLinear<5>, Tf330, nlid::PwLinear<5>>);
static_assert(nlid::HammersteinWiener<nlid::PwLinear<5>, Tf330, nlid::PwLinear<5>>::num_params == 26);
static_assert(!FormsHw<nlid::SigmoidNet<2, 3>, Tf330, nlid::Saturation>);  // input map of 2 inputs
static_assert(!FormsHw<nlid::UnitGain, nlid::LinearMap<1>, nlid::Saturation>);  // not a LinearBlock
static_assert(FormsTransferFunction<1, 2, 1> && !FormsTransferFunction<0, 2, 1>);  // nb >= 1
static_assert(nlid::Model<nlid::HammersteinWiener<nlid::UnitGain, Tf330, nlid::Saturation>>);

// ---- Grey box --------------------------------------------------------------------------------
// Continuous time without a noise model: what `compare` needs, not the discrete-time `Model`
// (docs/models.md says so).
static_assert(nlid::SimulationModel<nlid::GreyBox<nlid::physics::Throttle>>);
static_assert(!nlid::Model<nlid::GreyBox<nlid::physics::Throttle>>);

}  // namespace static_checks
