#pragma once
/// @file
/// `RegressorSet<Terms...>`: regressor blocks composed at compile time into one vector φ(t).
///
/// A nonlinear ARX model's regressor vector is the concatenation of its blocks, e.g. for the
/// study's `nlarx2`/`nlarx4`
///
///     φ(t) = [ y(t−1), y(t−2), u(t), max(y(t−1),90) + min(y(t−1),15) − 105 ]ᵀ
///          =  LaggedRegressors<2,1,0>  ⊕  CustomRegressor(spring).
///
/// The set computes its own sizes at compile time: `num_regressors` is the sum of the blocks'
/// counts and the history requirements are the maxima of theirs (`Dynamic` as soon as one
/// block is dynamic). Sets nest, because a set is itself a `Regressor`. Class template argument
/// deduction lets users write `RegressorSet regs{LaggedRegressors<2, 1, 0>{}, spring};` and let
/// the compiler spell the (lambda-containing) type.
///
/// Also here: `history_length`, the number of leading samples whose regressors reach before
/// t = 0, and `regressor_matrix`, the matrix [φ(n₀) … φ(N−1)]ᵀ of measured regressors used to
/// initialise a nonlinearity by regression (Sjöberg et al. 1995, sec. 7) and by getreg.

#include <algorithm>
#include <cstddef>
#include <span>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/regressors/concepts.hpp"
#include "nlid/regressors/lag_window.hpp"

namespace nlid {

/// Concatenation of regressor blocks, in order. Sizes computed at compile time.
template <Regressor... Terms>
  requires(sizeof...(Terms) >= 1)
class RegressorSet {
 public:
  /// Sum of the blocks' counts (`Dynamic` if any is).
  static constexpr int num_regressors = size_sum(Terms::num_regressors...);
  /// Largest output lag of the blocks.
  static constexpr int max_output_lag = detail::size_max(Terms::max_output_lag...);
  /// Largest input lag of the blocks.
  static constexpr int max_input_lag = detail::size_max(Terms::max_input_lag...);
  /// Number of blocks.
  static constexpr std::size_t num_terms = sizeof...(Terms);

  /// All blocks default-constructed (compile-time orders).
  RegressorSet() requires(std::is_default_constructible_v<Terms> && ...) = default;
  /// From block objects (needed for run-time orders and custom regressors).
  explicit RegressorSet(Terms... terms) : terms_(std::move(terms)...) {}

  /// Number of regressors.
  [[nodiscard]] int size() const {
    return std::apply([](const auto&... t) { return (0 + ... + t.size()); }, terms_);
  }
  /// Output history needed.
  [[nodiscard]] int output_lag() const {
    return std::apply([](const auto&... t) { return std::max({0, t.output_lag()...}); }, terms_);
  }
  /// Input history needed.
  [[nodiscard]] int input_lag() const {
    return std::apply([](const auto&... t) { return std::max({0, t.input_lag()...}); }, terms_);
  }
  /// 1 + the highest input channel read by any block.
  [[nodiscard]] int num_input_channels() const {
    return std::apply([](const auto&... t) { return std::max({0, t.num_input_channels()...}); },
                      terms_);
  }

  /// Lets every block that can check its printed names against channel names do so (custom
  /// regressors from text: `ExpressionRegressor::check_channel_names`).
  void check_channel_names(const std::vector<std::string>& input_names, const std::string& output_name) const {
    std::apply(
        [&](const auto&... t) {
          (
              [&](const auto& b) {
                if constexpr (requires { b.check_channel_names(input_names, output_name); })
                  b.check_channel_names(input_names, output_name);
              }(t),
              ...);
        },
        terms_);
  }

  /// Block I.
  template <std::size_t I>
  [[nodiscard]] const auto& term() const {
    return std::get<I>(terms_);
  }

  /// Each block writes its slice of `out`, in order.
  template <LagWindow W>
  void evaluate(const W& w, std::span<typename W::Scalar> out) const {
    std::size_t offset = 0;
    std::apply(
        [&](const auto&... t) {
          ((t.evaluate(w, out.subspan(offset, static_cast<std::size_t>(t.size()))),
            offset += static_cast<std::size_t>(t.size())),
           ...);
        },
        terms_);
  }

  /// Names of all regressors, in order.
  [[nodiscard]] std::vector<std::string> names(const std::vector<std::string>& input_names,
                                               const std::string& output_name) const {
    std::vector<std::string> n;
    std::apply(
        [&](const auto&... t) {
          (([&] {
             for (auto& s : t.names(input_names, output_name)) n.push_back(std::move(s));
           }()),
           ...);
        },
        terms_);
    return n;
  }

 private:
  std::tuple<Terms...> terms_;
};

/// Deduction guide: `RegressorSet regs{a, b}` → `RegressorSet<A, B>`.
template <class... Terms>
RegressorSet(Terms...) -> RegressorSet<Terms...>;

/// Samples at the start of a record whose regressors would reach before t = 0:
/// n₀ = max(output lag, input lag). One-step prediction from measured data starts at t = n₀.
template <Regressor R>
[[nodiscard]] int history_length(const R& r) {
  return std::max(r.output_lag(), r.input_lag());
}

/// Regressors from measured data: row i is φ(n₀ + i)ᵀ, i = 0 … N − n₀ − 1.
/// `u`: N×nu inputs, `y`: N outputs. Throws `nlid::Error` (located by `where`, e.g. an experiment)
/// if the data are shorter than the lags or have too few input channels.
template <Regressor R>
[[nodiscard]] Eigen::MatrixXd regressor_matrix(const R& r, const Eigen::Ref<const Eigen::MatrixXd>& u,
                                               const Eigen::Ref<const Eigen::VectorXd>& y,
                                               const Location& where = {}) {
  require(u.rows() == y.rows(),
          "inputs have " + std::to_string(u.rows()) + " samples but outputs have " +
              std::to_string(y.rows()),
          where);
  require(u.cols() >= r.num_input_channels(),
          "the regressors read " + std::to_string(r.num_input_channels()) +
              " input channel(s) but the data have " + std::to_string(u.cols()),
          where);
  const int n0 = history_length(r);
  require(y.rows() > n0,
          "data have " + std::to_string(y.rows()) + " samples, not more than the " +
              std::to_string(n0) + " needed by the regressor lags",
          where);
  const Eigen::Index rows = y.rows() - n0;
  Eigen::MatrixXd x(rows, r.size());
  Eigen::VectorXd phi(r.size());
  MeasuredWindow<double> w(u, y);
  for (Eigen::Index i = 0; i < rows; ++i) {
    w.set_time(n0 + i);
    r.evaluate(w, std::span<double>(phi.data(), static_cast<std::size_t>(phi.size())));
    x.row(i) = phi.transpose();
  }
  return x;
}

}  // namespace nlid
