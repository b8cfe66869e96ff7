#pragma once
/// @file
/// `BoundScalarMap<F, T>`: a one-input nonlinearity with θ fixed for a whole simulation.
///
/// Why: a block model (Hammerstein–Wiener, series) evaluates its static maps once per sample
/// with the same θ. Where F offers `prepare(θ)` / `evaluate_prepared(p, x)` — θ-only work done
/// once, e.g. PwLinear's breakpoint positions xₖ = x_{k−1} + exp(γₖ) — that work leaves the
/// per-sample loop; otherwise this is just `f(x, θ)`. Both routes give the same value.

#include <span>
#include <utility>

namespace nlid::detail {

/// F offers a prepared evaluation on scalar T.
template <class F, class T>
concept PreparedEvaluation = requires(const F& f, std::span<const T> theta, const T& x) {
  f.evaluate_prepared(f.prepare(theta), x);
};

/// What `prepare` returns, or an empty placeholder.
template <class F, class T, bool = PreparedEvaluation<F, T>>
struct PreparedType {
  struct type {};
};
template <class F, class T>
struct PreparedType<F, T, true> {
  using type = decltype(std::declval<const F&>().prepare(std::declval<std::span<const T>>()));
};

/// f(·; θ) for a fixed θ (see file comment). Views `f` and θ: both must outlive it.
template <class F, class T>
class BoundScalarMap {
 public:
  BoundScalarMap(const F& f, std::span<const T> theta) : f_(&f), theta_(theta) {
    if constexpr (PreparedEvaluation<F, T>) prepared_ = f.prepare(theta);
  }

  /// f(x; θ).
  T operator()(const T& x) const {
    if constexpr (PreparedEvaluation<F, T>) {
      return f_->evaluate_prepared(prepared_, x);
    } else {
      return (*f_)(std::span<const T>(&x, 1), theta_);
    }
  }

 private:
  using Prepared = typename PreparedType<F, T>::type;
  const F* f_;
  std::span<const T> theta_;
  Prepared prepared_{};
};

}  // namespace nlid::detail
