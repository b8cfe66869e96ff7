#pragma once
/// @file
/// Standard (lagged) regressors from model orders [na nb nk].
///
/// For a single-output model with orders na (output lags), nb (input lags) and nk (input delay)
/// the standard regressors are (Ljung 1999, eq. 4.11 for ARX, used unchanged by nonlinear ARX,
/// eq. 5.46):
///
///     φ(t) = [ y(t−1) … y(t−na),  u(t−nk) … u(t−nk−nb+1) ]ᵀ,
///
/// so the model sees na + nb regressors and needs na past outputs and nk + nb − 1 past inputs.
/// With nk = 0 the current input u(t) is a regressor (a direct feed-through, as in the study's
/// `arx210` and `nlarx5` = [3 3 0]).
///
/// Three building blocks:
/// - `OutputLags<Na>`: y(t−1) … y(t−Na);
/// - `InputLags<Nb, Nk, Channel>`: u_Channel(t−Nk) … u_Channel(t−Nk−Nb+1), one per input channel of a
///   multi-input model;
/// - `LaggedRegressors<Na, Nb, Nk>`: the single-input standard set (both of the above).
/// Each order may be `Dynamic` and then comes from the constructor: the *Dynamic twin* used for
/// order sweeps, which must give the same numbers as the fixed variant.
///
/// Names follow the toolbox's getreg: "y1(t-1)", "u1(t)", "u1(t-2)".

#include <span>
#include <string>
#include <vector>

#include "nlid/core/error.hpp"
#include "nlid/regressors/concepts.hpp"

namespace nlid {

namespace detail {
/// Checks an order against its compile-time value (if any) and the largest model order (as
/// `RegressorList` does; nk + nb − 1 of two huge orders overflowed int); throws `nlid::Error`
/// naming it.
inline int checked_order(int value, int compile_time, const char* name) {
  require(value >= 0, std::string("model order ") + name + " must be >= 0, got " + std::to_string(value),
          at_parameter(name));
  require(value <= max_model_order,
          std::string("model order ") + name + " must be <= " + std::to_string(max_model_order) +
              " (the largest model order), got " + std::to_string(value),
          at_parameter(name));
  require(compile_time == Dynamic || compile_time == value,
          std::string("model order ") + name + " = " + std::to_string(value) +
              " differs from its compile-time value " + std::to_string(compile_time),
          at_parameter(name));
  return value;
}
}  // namespace detail

/// Past outputs y(t−1) … y(t−Na). `Na` may be `Dynamic` (then set by the constructor).
template <int Na>
class OutputLags {
 public:
  static_assert(Na == Dynamic || Na >= 0, "OutputLags: Na must be >= 0 or Dynamic");
  /// Number of regressors (= Na).
  static constexpr int num_regressors = Na;
  /// Output history needed (= Na).
  static constexpr int max_output_lag = Na;
  /// Input history needed (none).
  static constexpr int max_input_lag = 0;

  /// Compile-time order.
  OutputLags() requires(Na != Dynamic) = default;
  /// Run-time order (must equal Na unless Na is Dynamic).
  explicit OutputLags(int na) : na_(detail::checked_order(na, Na, "na")) {}

  /// Number of regressors.
  [[nodiscard]] int size() const { return na_; }
  /// Output history needed.
  [[nodiscard]] int output_lag() const { return na_; }
  /// Input history needed.
  [[nodiscard]] int input_lag() const { return 0; }
  /// Reads no input.
  [[nodiscard]] int num_input_channels() const { return 0; }

  /// out[i] = y(t−1−i).
  template <LagWindow W>
  void evaluate(const W& w, std::span<typename W::Scalar> out) const {
    const int na = Na != Dynamic ? Na : na_;  // a constant bound unrolls (fixed orders)
    for (int i = 0; i < na; ++i) out[static_cast<std::size_t>(i)] = w.y(i + 1);
  }

  /// "y1(t-1)", "y1(t-2)", …
  [[nodiscard]] std::vector<std::string> names(const std::vector<std::string>& /*input_names*/,
                                               const std::string& output_name) const {
    std::vector<std::string> n;
    for (int i = 0; i < na_; ++i) n.push_back(detail::lag_name(output_name, i + 1));
    return n;
  }

 private:
  int na_ = Na;
};

/// Inputs of one channel u_c(t−Nk) … u_c(t−Nk−Nb+1). `Nb`, `Nk` may be `Dynamic`.
template <int Nb, int Nk, int Channel = 0>
class InputLags {
 public:
  static_assert(Nb == Dynamic || Nb >= 0, "InputLags: Nb must be >= 0 or Dynamic");
  static_assert(Nk == Dynamic || Nk >= 0, "InputLags: Nk must be >= 0 or Dynamic");
  static_assert(Channel >= 0, "InputLags: Channel is a 0-based input index");
  /// Number of regressors (= Nb).
  static constexpr int num_regressors = Nb;
  /// Output history needed (none).
  static constexpr int max_output_lag = 0;
  /// Input history needed: the oldest input read is u(t−Nk−Nb+1).
  static constexpr int max_input_lag =
      Nb == 0 ? 0 : (Nb == Dynamic || Nk == Dynamic ? Dynamic : Nk + Nb - 1);
  /// The input channel read (0-based).
  static constexpr int channel = Channel;

  /// Compile-time orders.
  InputLags() requires(Nb != Dynamic && Nk != Dynamic) = default;
  /// Run-time orders (each must equal its template value unless that is Dynamic).
  InputLags(int nb, int nk)
      : nb_(detail::checked_order(nb, Nb, "nb")), nk_(detail::checked_order(nk, Nk, "nk")) {}

  /// Number of regressors.
  [[nodiscard]] int size() const { return nb_; }
  /// Output history needed.
  [[nodiscard]] int output_lag() const { return 0; }
  /// Input history needed.
  [[nodiscard]] int input_lag() const { return nb_ == 0 ? 0 : nk_ + nb_ - 1; }
  /// The model must have at least Channel + 1 inputs.
  [[nodiscard]] int num_input_channels() const { return Channel + 1; }
  /// Input delay nk.
  [[nodiscard]] int delay() const { return nk_; }

  /// out[i] = u_c(t−nk−i).
  template <LagWindow W>
  void evaluate(const W& w, std::span<typename W::Scalar> out) const {
    const int nb = Nb != Dynamic ? Nb : nb_, nk = Nk != Dynamic ? Nk : nk_;  // constants when fixed
    for (int i = 0; i < nb; ++i) out[static_cast<std::size_t>(i)] = w.u(Channel, nk + i);
  }

  /// "u1(t)", "u1(t-1)", …
  [[nodiscard]] std::vector<std::string> names(const std::vector<std::string>& input_names,
                                               const std::string& /*output_name*/) const {
    std::vector<std::string> n;
    const std::string s = detail::input_name(input_names, Channel);
    for (int i = 0; i < nb_; ++i) n.push_back(detail::lag_name(s, nk_ + i));
    return n;
  }

 private:
  int nb_ = Nb;
  int nk_ = Nk;
};

/// The single-input standard regressors of orders [na nb nk]:
/// [y(t−1) … y(t−na), u(t−nk) … u(t−nk−nb+1)]. Any order may be `Dynamic`.
template <int Na, int Nb, int Nk>
class LaggedRegressors {
 public:
  /// Number of regressors (na + nb).
  static constexpr int num_regressors = size_sum(Na, Nb);
  /// Output history needed (na).
  static constexpr int max_output_lag = OutputLags<Na>::max_output_lag;
  /// Input history needed (nk + nb − 1, or 0 without inputs).
  static constexpr int max_input_lag = InputLags<Nb, Nk>::max_input_lag;

  /// Compile-time orders.
  LaggedRegressors() requires(Na != Dynamic && Nb != Dynamic && Nk != Dynamic) = default;
  /// Run-time orders (each must equal its template value unless that is Dynamic).
  LaggedRegressors(int na, int nb, int nk) : y_(na), u_(nb, nk) {}

  /// Number of regressors.
  [[nodiscard]] int size() const { return y_.size() + u_.size(); }
  /// Output history needed.
  [[nodiscard]] int output_lag() const { return y_.output_lag(); }
  /// Input history needed.
  [[nodiscard]] int input_lag() const { return u_.input_lag(); }
  /// One input.
  [[nodiscard]] int num_input_channels() const { return 1; }
  /// Orders.
  [[nodiscard]] int na() const { return y_.size(); }
  /// Number of input lags.
  [[nodiscard]] int nb() const { return u_.size(); }
  /// Input delay.
  [[nodiscard]] int nk() const { return u_.delay(); }

  /// Output lags first, then input lags.
  template <LagWindow W>
  void evaluate(const W& w, std::span<typename W::Scalar> out) const {
    const auto na = static_cast<std::size_t>(Na != Dynamic ? Na : y_.size());
    y_.evaluate(w, out.first(na));
    u_.evaluate(w, out.subspan(na));
  }

  /// "y1(t-1)" … "u1(t)" …
  [[nodiscard]] std::vector<std::string> names(const std::vector<std::string>& input_names,
                                               const std::string& output_name) const {
    auto n = y_.names(input_names, output_name);
    for (auto& s : u_.names(input_names, output_name)) n.push_back(std::move(s));
    return n;
  }

 private:
  OutputLags<Na> y_;
  InputLags<Nb, Nk, 0> u_;
};

}  // namespace nlid
