#pragma once
/// @file
/// Custom regressors: any scalar function of chosen lagged signals.
///
/// Physical insight often says which nonlinear function of the past matters. In the throttle
/// study the hard stops at 15° and 90° act like a very stiff spring, captured by the one custom
/// regressor (Ljung 1999, sec. 5.4 "semi-physical modelling")
///
///     φ_c(t) = max(y(t−1), 90) + min(y(t−1), 15) − 105,
///
/// which is zero between the stops and grows linearly beyond them. A custom regressor here is
/// a callable `fn` together with the list of lagged signals it reads, given as types:
///
///     auto spring = nlid::custom_regressor<nlid::OutputLag<1>>(
///         "max(y1(t-1),90)+min(y1(t-1),15)-105",
///         [](auto y1) { return nlid::max(y1, 90.0) + nlid::min(y1, 15.0) - 105.0; });
///
/// The lags are compile-time, so the regressor's history requirement is known to the compiler
/// (a fixed-size simulation can keep its past outputs on the stack). `fn` is called with one
/// scalar per listed signal, in order, on double, float and `Dual` alike; a generic lambda
/// (`auto` parameters) or a functor with a templated call operator does exactly that. A function
/// that would silently drop derivatives is rejected by the `RegressorFunction` concept at the
/// declaration: a lambda taking `double`, and equally one whose result on a `Dual` is not that
/// `Dual` (`[](auto y) -> double {…}`, or a call of a double-only function on
/// `nlid::value_of(y)`), which the dual type would otherwise accept through its conversion from a
/// constant and the estimator would see a zero derivative. A piecewise-constant function, whose
/// derivative is zero anyway, must return the argument's type too:
/// `[](auto y) { using T = decltype(y); return T(std::floor(nlid::value_of(y))); }` (or use
/// `nlid::floor`, which keeps the type).
///
/// Note: `nlid::max`/`nlid::min` accept (double, double) and (Dual, double); plain `std::max`
/// does not compile on duals. Kinks such as max/min have a one-sided derivative, which is what
/// the Levenberg–Marquardt step uses.

#include <cstddef>
#include <span>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "nlid/regressors/concepts.hpp"

namespace nlid {

/// Argument of a custom regressor: the output y(t−Lag), Lag ≥ 1.
template <int Lag>
struct OutputLag {
  static_assert(Lag >= 1, "OutputLag: an output regressor must look back at least one sample");
  /// Lag in samples.
  static constexpr int lag = Lag;
  /// Reads the output.
  static constexpr bool is_output = true;
  /// Output channel (single-output models).
  static constexpr int channel = 0;
};

/// Argument of a custom regressor: the input u_Channel(t−Lag), Lag ≥ 0.
template <int Lag, int Channel = 0>
struct InputLag {
  static_assert(Lag >= 0, "InputLag: lag must be >= 0");
  static_assert(Channel >= 0, "InputLag: Channel is a 0-based input index");
  /// Lag in samples.
  static constexpr int lag = Lag;
  /// Reads an input.
  static constexpr bool is_output = false;
  /// Input channel (0-based).
  static constexpr int channel = Channel;
};

namespace detail {
/// An `OutputLag<k>` or `InputLag<k, c>`.
template <class A>
concept LagArgument = requires {
  { A::lag } -> std::convertible_to<int>;
  { A::channel } -> std::convertible_to<int>;
  { A::is_output } -> std::convertible_to<bool>;
};

template <class Fn, class T, class Seq>
struct InvocableN;
template <class Fn, class T, std::size_t... I>
struct InvocableN<Fn, T, std::index_sequence<I...>> {
  template <std::size_t>
  using Arg = T;
  /// fn(T, …, T) compiles and its result converts to T.
  static constexpr bool converts = std::is_invocable_r_v<T, const Fn&, Arg<I>...>;
  /// fn(T, …, T) compiles and its result is a T (up to cv/reference). Convertible is not enough
  /// for a dual: a `double` result converts to it as a constant, with the derivatives dropped.
  static constexpr bool returns_same = [] {
    if constexpr (std::is_invocable_v<const Fn&, Arg<I>...>) {
      return std::is_same_v<std::remove_cvref_t<std::invoke_result_t<const Fn&, Arg<I>...>>, T>;
    } else {
      return false;
    }
  }();
};

template <int N>
using ArgumentSequence = std::make_index_sequence<static_cast<std::size_t>(N)>;
}  // namespace detail

/// A function of N scalars returning a scalar, callable on `double` (a result convertible to
/// double) and on `Dual`, where it must return that very `Dual` type, so derivatives propagate
/// through it: a result that merely converts to the dual (a `double`, e.g. from `-> double` or
/// from a double-only function of `value_of(y)`) would carry a zero derivative. Float and the
/// code generator's traced scalar are not checked here, as before: `evaluate` converts the result
/// to the window's scalar (`[](auto y) { return y * 2.0; }` returns double on a float). Satisfied by
/// generic lambdas `[](auto y1) {...}` and by functors with a
/// `template <class T> T operator()(T...) const`.
template <class Fn, int N>
concept RegressorFunction =
    detail::InvocableN<Fn, double, detail::ArgumentSequence<N>>::converts &&
    detail::InvocableN<Fn, detail::ArchetypeDual, detail::ArgumentSequence<N>>::returns_same;

/// One regressor φ(t) = fn(s₁, …, s_n) of the lagged signals `Args...` (`OutputLag`/`InputLag`).
template <class Fn, class... Args>
  requires(sizeof...(Args) >= 1) && (detail::LagArgument<Args> && ...) &&
          RegressorFunction<Fn, static_cast<int>(sizeof...(Args))>
class CustomRegressor {
 public:
  /// One regressor.
  static constexpr int num_regressors = 1;
  /// Largest output lag among the arguments (0 if none).
  static constexpr int max_output_lag = detail::size_max((Args::is_output ? Args::lag : 0)...);
  /// Largest input lag among the arguments (0 if none).
  static constexpr int max_input_lag = detail::size_max((Args::is_output ? 0 : Args::lag)...);

  /// `name` is what getreg prints (empty: "f(y1(t-1),…)" from the arguments).
  CustomRegressor(std::string name, Fn fn) : name_(std::move(name)), fn_(std::move(fn)) {}

  /// One regressor.
  [[nodiscard]] int size() const { return 1; }
  /// Output history needed.
  [[nodiscard]] int output_lag() const { return max_output_lag; }
  /// Input history needed.
  [[nodiscard]] int input_lag() const { return max_input_lag; }
  /// 1 + the highest input channel read (0 if only outputs are read).
  [[nodiscard]] int num_input_channels() const {
    return detail::size_max((Args::is_output ? 0 : Args::channel + 1)...);
  }
  /// The user's function.
  [[nodiscard]] const Fn& function() const { return fn_; }

  /// out[0] = fn(args at the window's time).
  template <LagWindow W>
  void evaluate(const W& w, std::span<typename W::Scalar> out) const {
    using T = typename W::Scalar;
    out[0] = static_cast<T>(fn_(fetch<Args>(w)...));
  }

  /// The display name, or "f(y1(t-1),u1(t))" built from the arguments when none was given.
  [[nodiscard]] std::vector<std::string> names(const std::vector<std::string>& input_names,
                                               const std::string& output_name) const {
    if (!name_.empty()) return {name_};
    std::string s = "f(";
    bool first = true;
    ((s += (first ? "" : ","),
      s += detail::lag_name(Args::is_output ? output_name : detail::input_name(input_names, Args::channel),
                            Args::lag),
      first = false),
     ...);
    return {s + ")"};
  }

 private:
  template <class A, class W>
  static typename W::Scalar fetch(const W& w) {
    if constexpr (A::is_output) {
      return w.y(A::lag);
    } else {
      return w.u(A::channel, A::lag);
    }
  }

  std::string name_;
  Fn fn_;
};

/// Makes a custom regressor reading the lagged signals `Args...` (e.g. `OutputLag<1>`),
/// printed as `name` by getreg. Returns `CustomRegressor<Fn, Args...>`; the return type is
/// deduced so that a rejected `fn` is reported by this function's constraints, which name
/// `RegressorFunction`, and not as a substitution failure of the class template.
template <class... Args, class Fn>
  requires(sizeof...(Args) >= 1) && (detail::LagArgument<Args> && ...) &&
          RegressorFunction<Fn, static_cast<int>(sizeof...(Args))>
auto custom_regressor(std::string name, Fn fn) {
  return CustomRegressor<Fn, Args...>(std::move(name), std::move(fn));
}

}  // namespace nlid
