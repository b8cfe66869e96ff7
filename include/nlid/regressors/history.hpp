#pragma once
/// @file
/// `History<T, L>`: the ring buffer of the last L samples of a signal.
///
/// A free-run simulation of a nonlinear ARX model needs, at time t, the model's own outputs
/// ŷ(t−1) … ŷ(t−L) (L = the largest output lag of its regressors). Shifting an array by one
/// every sample costs O(L) copies of the scalar, which for a `Dual<double, 47>` is 48 doubles per
/// element; a ring buffer costs one copy. With a compile-time L the buffer is a `std::array` on the
/// stack, so a fixed-size simulation allocates nothing per sample (or at all); with `L = Dynamic`
/// it is a `std::vector` sized once per simulation.
///
/// Invariant: `length()` values are always held (initially all zero, or set by `fill`/`push`);
/// `(*this)(1)` is the most recent value, `(*this)(length())` the oldest.

#include <array>
#include <cassert>
#include <type_traits>
#include <vector>

#include "nlid/core/error.hpp"
#include "nlid/core/sizes.hpp"

namespace nlid {

/// Ring buffer of the last `length()` values; `L` is the compile-time length or `Dynamic`.
template <class T, int L>
class History {
 public:
  /// Compile-time length: zero-filled.
  History() requires(L != Dynamic) { fill(T(0)); }

  /// Run-time length (must equal `L` unless `L` is `Dynamic`): zero-filled.
  explicit History(int length) {
    if constexpr (L == Dynamic) {
      require(length >= 0, "history length must be >= 0, got " + std::to_string(length),
              at_parameter("length"));
      buf_.assign(static_cast<std::size_t>(length), T(0));
    } else {
      // Tested before the message is built: this constructor runs once per simulation, and a
      // fixed-size simulation must not allocate (tests/nomalloc).
      if (length != L)
        throw Error("history length " + std::to_string(length) + " differs from the compile-time length " +
                        std::to_string(L),
                    at_parameter("length"));
      fill(T(0));
    }
  }

  /// Number of values held.
  [[nodiscard]] int length() const {
    if constexpr (L == Dynamic) {
      return static_cast<int>(buf_.size());
    } else {
      return L;
    }
  }

  /// Sets every held value to `x` (a steady past, e.g. an equilibrium).
  void fill(const T& x) {
    for (auto& b : buf_) b = x;
    head_ = 0;
  }

  /// Appends `x`: it becomes lag 1 and every older value moves one lag back; the oldest drops out.
  void push(const T& x) {
    if constexpr (kShift) {
      // Plain numbers with a compile-time length: shift instead, so every access has a constant
      // index and the compiler keeps the past in registers (a ring index forces a store and a
      // reload on the simulation's critical path; measured in benchmarks/simulation_benchmark).
      for (int i = L - 1; i > 0; --i) buf_[static_cast<std::size_t>(i)] = buf_[static_cast<std::size_t>(i - 1)];
      if constexpr (L > 0) buf_[0] = x;
    } else {
      if (length() == 0) return;
      head_ = head_ + 1 == length() ? 0 : head_ + 1;
      buf_[static_cast<std::size_t>(head_)] = x;
    }
  }

  /// The value `lag` samples back, 1 ≤ lag ≤ length().
  [[nodiscard]] const T& operator()(int lag) const {
    assert(lag >= 1 && lag <= length());
    if constexpr (kShift) return buf_[static_cast<std::size_t>(lag - 1)];
    int i = head_ - (lag - 1);
    if (i < 0) i += length();
    return buf_[static_cast<std::size_t>(i)];
  }

 private:
  // Shift register for plain arithmetic scalars with a static length (see `push`); ring buffer
  // otherwise (a Dual is too large to shift).
  static constexpr bool kShift = L != Dynamic && std::is_arithmetic_v<T>;
  // The static case keeps its storage inline (no heap), the dynamic one on the heap.
  using Storage = std::conditional_t<L == Dynamic, std::vector<T>, std::array<T, (L > 0 ? L : 0)>>;
  Storage buf_{};
  int head_ = 0;  // index of the most recent value
};

}  // namespace nlid
