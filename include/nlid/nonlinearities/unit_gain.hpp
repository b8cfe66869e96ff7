#pragma once
/// @file
/// `UnitGain`: the identity map g(x) = x, with no parameters.
///
/// In a Hammerstein–Wiener model y = h(B/F f(u)) the unit gain stands in for an absent block:
/// the study's `nlhw1` has no input nonlinearity (f = unit gain) and an output saturation h. It
/// is the toolbox's `unitgain` / idUnitGain. Because p = 0, a model that uses it estimates no
/// parameters for that block and its size arithmetic (`size_sum`) stays exact at compile time.

#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "nlid/nonlinearities/detail/common.hpp"

namespace nlid {

/// Identity map of one input: g(x) = x, θ empty (p = 0).
class UnitGain {
 public:
  /// m = 1.
  static constexpr int num_inputs = 1;
  /// p = 0.
  static constexpr int num_params = 0;

  /// Number of inputs (1).
  [[nodiscard]] int input_dimension() const { return 1; }
  /// Number of parameters (0).
  [[nodiscard]] int num_parameters() const { return 0; }

  /// g(x) = x. Throws `nlid::Error` unless x has one entry and θ none.
  template <class T>
  [[nodiscard]] T operator()(std::span<const T> x, std::span<const T> theta) const {
    if (x.size() != 1) detail::check_size(x.size(), 1, "x", "UnitGain");
    if (!theta.empty()) detail::check_size(theta.size(), 0, "theta", "UnitGain");
    return x[0];
  }

  /// Nothing to fit; validates the arguments so misuse is reported where it happens.
  void initialize(const Eigen::MatrixXd& X, const Eigen::VectorXd& y, std::span<double> theta) {
    detail::check_init_data(X, y, theta.size(), 1, 0, 0, "UnitGain");
  }

  /// The unit of each parameter when x is measured in units of size `in` and g(x) in units of
  /// size `out` (estimation uses them to damp steps alike whatever units the data are in).
  bool parameter_scales(double /*in*/, double /*out*/, std::span<double> /*s*/) const { return true; }

  /// No parameters: an empty list.
  [[nodiscard]] std::vector<std::string> parameter_names() const { return {}; }

  /// "unit gain: g(x) = x".
  [[nodiscard]] std::string describe(std::span<const double> theta) const {
    detail::check_size(theta.size(), 0, "theta", "UnitGain");
    return "unit gain: g(x) = x\n";
  }
};

}  // namespace nlid
