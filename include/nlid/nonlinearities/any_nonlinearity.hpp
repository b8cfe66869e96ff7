#pragma once
/// @file
/// `AnyNonlinearity`: any catalogue nonlinearity, chosen at run time, as one value type.
///
/// A nonlinear ARX or Hammerstein–Wiener model read from a file, or specified on a command line
/// ("sigmoidnet, 5 units"), does not know its nonlinearity when the program is compiled. The
/// toolbox answers with class polymorphism; nlid answers with a closed sum type (`std::variant`)
/// over the `Dynamic`-size twins of the catalogue (table in nonlinearities.hpp):
///
///     UnitGain, LinearMap<Dynamic>, SigmoidNet<Dynamic, Dynamic, true|false>,
///     WaveletNet<Dynamic, Dynamic, true|false>, PwLinear<Dynamic>, Saturation, DeadZone,
///     Poly1d<Dynamic>, TreePartition<Dynamic, Dynamic>.
///
/// Why a variant rather than a virtual interface: the evaluation `g(x; θ)` is a member *template*
/// on the scalar (double, float, Dual), which a virtual function cannot be; `std::visit`
/// dispatches a template call to the held alternative, so AnyNonlinearity is itself a
/// `Nonlinearity` (scalar-generic, value semantics, copyable) and every model template accepts
/// it. The cost is one branch per evaluation; the values are those of the held alternative,
/// bit for bit, because the same code runs.
///
/// Names (`kind()`, used in model files and by `make_nonlinearity`): "unitgain", "linear",
/// "sigmoidnet", "wavenet", "pwlinear", "saturation", "deadzone", "poly1d", "treepartition"
/// (the toolbox's idSigmoidNetwork, idWaveletNetwork, idPiecewiseLinear, idSaturation,
/// idDeadZone, idPolynomial1D, idTreePartition, idLinear, idUnitGain).

#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <variant>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/core/sizes.hpp"
#include "nlid/nonlinearities/concepts.hpp"
#include "nlid/nonlinearities/dead_zone.hpp"
#include "nlid/nonlinearities/linear.hpp"
#include "nlid/nonlinearities/piecewise_linear.hpp"
#include "nlid/nonlinearities/polynomial.hpp"
#include "nlid/nonlinearities/saturation.hpp"
#include "nlid/nonlinearities/sigmoid_network.hpp"
#include "nlid/nonlinearities/tree_partition.hpp"
#include "nlid/nonlinearities/unit_gain.hpp"
#include "nlid/nonlinearities/wavelet_network.hpp"

namespace nlid {

/// A catalogue nonlinearity chosen at run time (see the file comment). Satisfies
/// `Nonlinearity` and `ScalarNonlinearity` (sizes `Dynamic`).
/// Invariant: always holds one alternative (default: `UnitGain`).
class AnyNonlinearity {
 public:
  /// The alternatives, in the order of `kind_names()`.
  using Variant = std::variant<UnitGain, LinearMap<Dynamic>, SigmoidNet<Dynamic, Dynamic, true>,
                               SigmoidNet<Dynamic, Dynamic, false>, WaveletNet<Dynamic, Dynamic, true>,
                               WaveletNet<Dynamic, Dynamic, false>, PwLinear<Dynamic>, Saturation, DeadZone,
                               Poly1d<Dynamic>, TreePartition<Dynamic, Dynamic>>;
  /// m known at run time.
  static constexpr int num_inputs = Dynamic;
  /// p known at run time.
  static constexpr int num_params = Dynamic;

  /// The identity (unit gain).
  AnyNonlinearity() = default;
  /// Holds `f` (one of the `Variant` alternatives, e.g. `SigmoidNet<Dynamic, Dynamic>(3, 5)`).
  template <class F>
    requires std::is_constructible_v<Variant, F&&> && (!std::is_same_v<std::remove_cvref_t<F>, AnyNonlinearity>)
  AnyNonlinearity(F&& f) : v_(std::forward<F>(f)) {}  // NOLINT(google-explicit-constructor)

  /// The held alternative.
  [[nodiscard]] const Variant& variant() const { return v_; }
  /// The held alternative (mutable: its `initialize` learns normalisation).
  [[nodiscard]] Variant& variant() { return v_; }
  /// Pointer to the held alternative if it is an F, else null.
  template <class F>
  [[nodiscard]] const F* get_if() const {
    return std::get_if<F>(&v_);
  }

  /// The kind's name ("sigmoidnet", …; see the file comment). SigmoidNet and WaveletNet with and
  /// without linear term share a name; `has_linear_term()` tells them apart.
  [[nodiscard]] std::string kind() const { return kind_names()[v_.index() == 3 ? 2 : v_.index() == 5 ? 4 : v_.index()]; }
  /// False only for a sigmoid or wavelet network built without its linear term.
  [[nodiscard]] bool has_linear_term() const { return v_.index() != 3 && v_.index() != 5; }
  /// Names by variant index (without-linear-term networks repeat their kind's name).
  [[nodiscard]] static const std::vector<std::string>& kind_names() {
    static const std::vector<std::string> names{"unitgain", "linear",     "sigmoidnet", "sigmoidnet",
                                                "wavenet",  "wavenet",    "pwlinear",   "saturation",
                                                "deadzone", "poly1d",     "treepartition"};
    return names;
  }

  /// m.
  [[nodiscard]] int input_dimension() const {
    return std::visit([](const auto& f) { return static_cast<int>(f.input_dimension()); }, v_);
  }
  /// p.
  [[nodiscard]] int num_parameters() const {
    return std::visit([](const auto& f) { return static_cast<int>(f.num_parameters()); }, v_);
  }
  /// g(x; θ) of the held map, on any scalar.
  template <class T>
  [[nodiscard]] T operator()(std::span<const T> x, std::span<const T> theta) const {
    return std::visit([&](const auto& f) -> T { return f(x, theta); }, v_);
  }
  /// Data-driven start of the held map.
  void initialize(const Eigen::MatrixXd& X, const Eigen::VectorXd& y, std::span<double> theta) {
    std::visit([&](auto& f) { f.initialize(X, y, theta); }, v_);
  }
  /// Alternative data-driven start `start` of the held map (`EstimateOptions::starts`), for the
  /// maps that have them (SigmoidNet); start 0 is the default start of any map. Throws naming
  /// "start" for start > 0 of a map with a single start.
  void initialize(const Eigen::MatrixXd& X, const Eigen::VectorXd& y, std::span<double> theta, int start) {
    std::visit(
        [&](auto& f) {
          if constexpr (requires { f.initialize(X, y, theta, start); }) {
            f.initialize(X, y, theta, start);
          } else {
            require(start == 0, "this nonlinearity has one data-driven start; start " + std::to_string(start) +
                                    " needs a sigmoid network",
                    at_parameter("start"));
            f.initialize(X, y, theta);
          }
        },
        v_);
  }
  /// The held map's parameter units for input units `in` and output units `out` (see e.g.
  /// PwLinear::parameter_scales); false, leaving `s` as it was, for a map that does not know
  /// them (the networks, whose inputs are standardised inside).
  bool parameter_scales(double in, double out, std::span<double> s) const {
    return std::visit([&](const auto& f) { return detail::parameter_scales_of(f, in, out, s); }, v_);
  }
  /// Parameter names of the held map.
  [[nodiscard]] std::vector<std::string> parameter_names() const {
    return std::visit([](const auto& f) { return f.parameter_names(); }, v_);
  }
  /// Description of the held map.
  [[nodiscard]] std::string describe(std::span<const double> theta) const {
    return std::visit([&](const auto& f) { return std::string(f.describe(theta)); }, v_);
  }
  /// Description naming the inputs (where the held map supports it).
  [[nodiscard]] std::string describe(std::span<const double> theta, const std::vector<std::string>& input_names) const {
    return std::visit(
        [&](const auto& f) {
          if constexpr (requires { f.describe(theta, input_names); }) {
            return std::string(f.describe(theta, input_names));
          } else {
            return std::string(f.describe(theta));
          }
        },
        v_);
  }

 private:
  Variant v_;
};

/// Structure options of `make_nonlinearity` (each used only by the kinds it applies to).
struct NonlinearityOptions {
  int units = 10;                 ///< sigmoidnet, wavenet: number of units
  bool linear_term = true;        ///< sigmoidnet, wavenet: include the linear term
  int breakpoints = 10;           ///< pwlinear: number of breakpoints
  std::vector<double> positions;  ///< pwlinear: given breakpoint positions (overrides `breakpoints`)
  int degree = 2;                 ///< poly1d: degree
  int depth = 3;                  ///< treepartition: depth
  std::optional<std::pair<double, double>> limits;  ///< saturation, deadzone: initial limits
};

/// A nonlinearity of `num_inputs` inputs by kind name (see the file comment). Throws
/// `nlid::Error` naming "nonlinearity" and listing the accepted names for an unknown kind, or
/// naming the bad option; single-input kinds require `num_inputs == 1`.
[[nodiscard]] inline AnyNonlinearity make_nonlinearity(std::string_view kind, int num_inputs,
                                                       const NonlinearityOptions& o = {}) {
  require(num_inputs >= 1, "a nonlinearity needs at least one input, got " + std::to_string(num_inputs),
          at_parameter("inputs"));
  const auto scalar_only = [&](const char* k) {
    require(num_inputs == 1,
            std::string("nonlinearity '") + k + "' has one input but " + std::to_string(num_inputs) +
                " regressors/inputs were given (use sigmoidnet, wavenet, treepartition or linear)",
            at_parameter("nonlinearity"));
  };
  if (kind == "unitgain") {
    scalar_only("unitgain");
    return UnitGain{};
  }
  if (kind == "linear") return LinearMap<Dynamic>(num_inputs);
  if (kind == "sigmoidnet") {
    if (o.linear_term) return SigmoidNet<Dynamic, Dynamic, true>(num_inputs, o.units);
    return SigmoidNet<Dynamic, Dynamic, false>(num_inputs, o.units);
  }
  if (kind == "wavenet") {
    if (o.linear_term) return WaveletNet<Dynamic, Dynamic, true>(num_inputs, o.units);
    return WaveletNet<Dynamic, Dynamic, false>(num_inputs, o.units);
  }
  if (kind == "pwlinear") {
    scalar_only("pwlinear");
    if (!o.positions.empty()) return PwLinear<Dynamic>(o.positions);
    return PwLinear<Dynamic>(o.breakpoints);
  }
  if (kind == "saturation") {
    scalar_only("saturation");
    return o.limits ? Saturation(o.limits->first, o.limits->second) : Saturation();
  }
  if (kind == "deadzone") {
    scalar_only("deadzone");
    return o.limits ? DeadZone(o.limits->first, o.limits->second) : DeadZone();
  }
  if (kind == "poly1d") {
    scalar_only("poly1d");
    return Poly1d<Dynamic>(o.degree);
  }
  if (kind == "treepartition") return TreePartition<Dynamic, Dynamic>(num_inputs, o.depth);
  throw Error("unknown nonlinearity '" + std::string(kind) +
                  "' (accepted: unitgain, linear, sigmoidnet, wavenet, pwlinear, saturation, deadzone, "
                  "poly1d, treepartition)",
              at_parameter("nonlinearity"));
}

}  // namespace nlid
