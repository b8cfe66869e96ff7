#pragma once
/// @file
/// `Batch<T, W>`: W independent values of T processed in lock step — a SIMD-pack scalar that
/// makes every scalar-generic simulation in nlid run W trajectories at once.
///
/// Why. A free-run simulation is a recursion, ŷ(t) = F(ŷ(t−1), …, u(t); θ): sample t cannot
/// start before sample t−1 is done, so one trajectory is bound by the *latency* of F (an exp,
/// a division and a chain of multiply-adds), not by the throughput of the core. Many studies
/// need many trajectories of the same model — Monte-Carlo parameter sets drawn from the
/// estimate's covariance (Ljung 1999, Sec. 9.4), multi-start screening, sensitivity sweeps —
/// and those are independent. Evaluating them lane by lane in one `Batch` turns W dependency
/// chains into W-wide vector instructions and fills the pipeline with independent work:
///
///     ŷ_w(t) = F(φ_w(t); θ_w),   w = 0 … W−1,   all lanes advanced by the same instructions.
///
/// The models are templated on the scalar (`Nlarx::simulate<T>`, `simulate_physics<T>`), so with
/// T = Batch<double, W> they simulate W parameter sets (θ_w, x0_w) on a shared input record
/// without a line of model code changed; `simulate_batched` below packs and unpacks.
///
/// Semantics (the invariants that keep generic code correct):
/// - Arithmetic and math functions act lane-wise: `exp(b)[w] == exp(b[w])` up to rounding (the
///   double exp is a vectorisable Cody–Waite/rational kernel within 2 ulp of libm's; every other
///   function calls std:: per lane).
/// - Comparisons give a `BatchMask`, which deliberately has *no* conversion to bool: a branch
///   on a batched value (`if (x < y)`) has no single answer and fails to compile instead of
///   silently following lane 0. Branch-free code uses `select(mask, a, b)`; code whose branch
///   is only a choice between algebraically equal forms (nonlinearities' logistic) selects per
///   lane. Models that branch on values by nature (piecewise-linear segment search) therefore
///   do not batch — a compile error, not a wrong answer.
/// - `static_cast<T>(b)` (explicit) is the lane of largest magnitude, NaN if any lane is NaN.
///   Generic code converts to a real number only to ask "is it finite?", "does it exceed the
///   divergence limit?" or "how large is the error?" — questions whose batched answer must
///   cover every lane, which this representative does.
/// - `isfinite(b)` is true if every lane is finite.
///
/// Storage: with GCC or Clang and W a power of two the lanes are GNU vectors of the target's
/// register width (`v.c[k]`; 16 bytes on baseline x86-64, 32 with AVX, 64 with AVX-512), so
/// each Batch operation is one packed instruction per register whatever the auto-vectoriser
/// would decide; otherwise a std::array. Either way a Batch has the size of T[W]; with vectors
/// its alignment is that of one register (at most Eigen's EIGEN_MAX_ALIGN_BYTES, so Eigen's,
/// std::vector's and `new`'s allocations of Batch scalars are aligned).
/// (So the default register width is a property of the translation unit, as it is for Eigen:
/// link translation units compiled for different instruction sets only across non-inline
/// boundaries.)
///
/// Wider registers at run time. `Batch<T, W, R>` names the register width R (bytes) explicitly;
/// `with_register_bytes(f)` calls `f.template operator()<R>()` with R the widest width of the CPU
/// running the program (`cpu_register_bytes()`), inside a function compiled for that
/// instruction set (`target("avx512f…")` / `target("avx2,fma")`, with `flatten` so the model
/// code below it is compiled there too). A program built for baseline x86-64 thus runs its
/// batches on AVX-512 registers where the machine has them; `simulate_batched` does this for
/// models of static size. docs/models.md ("Registers chosen at run time") has the rules.
///
/// Eigen glue (`NumTraits`, `ScalarBinaryOpTraits` with T) lets a Batch be the scalar of Eigen
/// matrices (integrator states, regressor vectors).
///
/// Throughput measured with benchmarks/simulation_benchmark.cpp: docs/performance.md.

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <concepts>
#include <cstdint>
#include <cstring>
#include <limits>
#include <span>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/error.hpp"

namespace nlid {

namespace detail {
// Batch's kernels and helpers are forced inline: called out of line (as GCC chose for W = 8) every call
// spills the lanes to memory and back, which cost more than the arithmetic (perf, see
// docs/performance.md).
#if defined(__GNUC__)
#define NLID_BATCH_INLINE [[gnu::always_inline]] inline
// The same for the lambdas given to for_each_chunk: a kernel's body repeated for 8 registers is
// large enough for GCC's inliner to keep it out of line, every operand then through memory
// (portable nlarx5 Batch<16>: 85 -> 18 M samples/s).
#define NLID_CHUNK_LAMBDA __attribute__((always_inline))
#else
#define NLID_BATCH_INLINE inline
#define NLID_CHUNK_LAMBDA
#endif

/// Calls f(0), f(1), …, f(N−1), expanded at compile time. Why not a loop over a Batch's
/// registers: at -O2 GCC keeps such a loop, and every register it touches then lives in memory
/// (the batched nlarx5 simulation ran 3x slower at -O2 than at -O3 that way).
template <int N, class F>
NLID_BATCH_INLINE void for_each_chunk(F&& f) {
  [&]<int... K>(std::integer_sequence<int, K...>) NLID_CHUNK_LAMBDA { (f(K), ...); }(std::make_integer_sequence<int, N>{});
}

/// Unsigned integer of a lane's width: masks are all-ones/all-zero lanes, as SIMD compares give.
template <class T>
using lane_bits_t = std::conditional_t<sizeof(T) == 8, std::uint64_t, std::uint32_t>;

/// True where the lanes are stored as GNU vectors (GCC, Clang): float or double, W ≥ 2 and a
/// power of two (what `vector_size` accepts). Every other W keeps a plain array.
template <class T, int W>
inline constexpr bool batch_simd_v =
#if defined(__GNUC__)
    (std::is_same_v<T, double> || std::is_same_v<T, float>) && W >= 2 && (W & (W - 1)) == 0;
#else
    false;
#endif

/// Bytes of the widest vector register of the target the translation unit is compiled for.
inline constexpr std::size_t isa_bytes =
#if defined(__AVX512F__)
    64;
#elif defined(__AVX__)
    32;
#else
    16;  // SSE2 (baseline x86-64), NEON
#endif
/// Bytes per Batch register: the target's width, but no more than Eigen aligns its heap blocks
/// to (a Batch in an Eigen matrix must be aligned; EIGEN_MAX_ALIGN_BYTES follows the same
/// instruction-set macros unless the user lowers it). malloc's 16 bytes are the floor.
inline constexpr std::size_t simd_bytes =
    std::max(std::size_t{16}, std::min(isa_bytes, static_cast<std::size_t>(EIGEN_MAX_ALIGN_BYTES)));

/// True for a register width a Batch can be built on: a power of two of at least 16 bytes.
inline constexpr bool valid_register_bytes(std::size_t r) { return r >= 16 && (r & (r - 1)) == 0; }

/// Lane storage: `type` for the values, `bits` for masks of the same width; R bytes per register.
template <class T, int W, std::size_t R, bool Simd = batch_simd_v<T, W>>
struct batch_storage {
  using type = std::array<T, static_cast<std::size_t>(W)>;
  using bits = std::array<lane_bits_t<T>, static_cast<std::size_t>(W)>;
};
#if defined(__GNUC__)
// Why vectors and not an array: as std::array the lanes reach the compiler as W separate
// memory slots, and whether a chain of Batch operations became packed instructions was left to
// the auto-vectoriser — which, inside a long inlined model, vectorised some operations,
// scalarised others and copied values in 16-byte pieces that the next 32-byte load could not
// forward from (docs/performance.md: the native nlarx5 batch ran at 0.55–0.9× one trajectory).
// A vector is a value the compiler keeps in a register. Why chunks of the target's register
// width and not one vector of all W lanes: a vector wider than any register of the target has
// no machine mode, so GCC keeps it in memory and every operation loads and stores its pieces
// (the portable throttle batch ran 1.4–2.2× slower that way). The vectors keep their natural
// alignment: a typedef that lowers it (aligned(alignof(T))) is not honoured by Clang in every
// templated expression — Clang -O1 emitted an aligned SSE load of a Batch at an 8-byte offset,
// a crash (tests/core/batch_test.cpp).
template <class T, int W, std::size_t R>
struct batch_storage<T, W, R, true> {
  /// Bytes per chunk: the register width, or all W lanes if they fit in less.
  static constexpr std::size_t bytes = sizeof(T) * W < R ? sizeof(T) * W : R;
  /// Number of chunks.
  static constexpr int chunks = static_cast<int>(sizeof(T) * W / bytes);
  /// Lanes per chunk.
  static constexpr int per_chunk = static_cast<int>(bytes / sizeof(T));
  /// One register of lanes. Aligned to its size explicitly: GCC caps a vector type's natural
  /// alignment at the translation unit's widest register (16 bytes on baseline x86-64), yet code
  /// compiled for AVX (run-time dispatch, `with_register_bytes`) loads a 32-byte vector with
  /// aligned instructions — a crash on memory the standard allocator aligned to 16.
  typedef T vec __attribute__((vector_size(bytes), aligned(bytes)));
  /// One register of lane masks.
  typedef lane_bits_t<T> vbits __attribute__((vector_size(bytes), aligned(bytes)));
  /// The values.
  struct type {
    vec c[chunks];
  };
  /// The masks.
  struct bits {
    vbits c[chunks];
  };
};
#endif
/// One chunk's lane types: the `L` of the math kernels, which also take `scalar_lanes` (one
/// double), so scalar and vector lanes run one source. Declared for every compiler so that the
/// vector branches of the operations parse; instantiated only where `batch_simd_v` holds.
template <class T, int W, std::size_t R>
struct batch_chunk {
  using type = typename batch_storage<T, W, R>::vec;
  using bits = typename batch_storage<T, W, R>::vbits;
};
}  // namespace detail

/// W lanes of T, operated on lane-wise (see file comment). Invariant: W ≥ 1. R is the width of
/// the registers the lanes are stored in (bytes): by default the translation unit's; only
/// `simulate_batched`'s run-time dispatch names a wider one (see there).
template <class T, int W, std::size_t R = detail::simd_bytes>
  requires(std::is_floating_point_v<T> && W >= 1 && detail::valid_register_bytes(R))
struct Batch {
  /// Number of lanes.
  static constexpr int lanes = W;
  /// The lane type.
  using value_type = T;
  /// True if the lanes are GNU vectors (`detail::batch_storage`), false for a plain array.
  static constexpr bool simd = detail::batch_simd_v<T, W>;
  /// The lanes' storage: register-wide GNU vectors `v.c[k]` (GCC, Clang; W a power of two) or
  /// a std::array. Either way W consecutive T in memory; `operator[]` reads or writes lane i.
  using storage = typename detail::batch_storage<T, W, R>::type;

  /// The lanes (public, like Dual's `a` and `v`: a plain value type).
  storage v{};

  /// All lanes zero.
  constexpr Batch() = default;
  /// Copies the lanes. Why not the implicit copy: for the array storage GCC expands it in
  /// 16-byte pieces even where lanes are 32-byte AVX vectors, and the first 32-byte load of the
  /// copy then waits for two 16-byte stores (a failed store-to-load forward,
  /// docs/performance.md); for vectors a register-wide copy is what is wanted anyway.
  constexpr Batch(const Batch& o) { copy_from(o); }
  /// Assigns the lanes (see the copy constructor).
  constexpr Batch& operator=(const Batch& o) {
    copy_from(o);
    return *this;
  }
  /// Broadcast: every lane equals x (implicit, as a constant enters an expression).
  constexpr Batch(T x) {  // NOLINT(google-explicit-constructor)
    if constexpr (simd) {
      using S = detail::batch_storage<T, W, R>;
      if constexpr (R <= detail::isa_bytes) {
        // x − (+0) is x for every x, −0 and NaN included: a broadcast.
        detail::for_each_chunk<S::chunks>([&](int k) NLID_CHUNK_LAMBDA { v.c[k] = x - typename S::vec{}; });
      } else {
        // Registers wider than the translation unit's (code dispatched at run time, see
        // `with_register_bytes`): there GCC expands x − (+0) into one masked insert per lane,
        // 8 per AVX-512 register (the batched nlarx5 ran at 146 instead of 183 M samples/s);
        // lane by lane it emits one broadcast. In the translation unit's own width the lane
        // form is the slower one (portable nlarx5 batch 76 → 61–69 M samples/s), hence both.
        detail::for_each_chunk<S::chunks>([&](int k) NLID_CHUNK_LAMBDA {
          typename S::vec c{};
          for (int i = 0; i < S::per_chunk; ++i) c[i] = x;
          v.c[k] = c;
        });
      }
    } else {
      v.fill(x);
    }
  }
  /// Broadcast from another arithmetic type (int literals of generic code: `T(0)`).
  template <class U>
    requires(std::is_arithmetic_v<U> && !std::is_same_v<U, T>)
  constexpr explicit Batch(U x) : Batch(static_cast<T>(x)) {}

  /// Lanes from W consecutive values.
  static Batch load(const T* p) {
    Batch b;
    std::memcpy(&b.v, p, sizeof(storage));
    return b;
  }
  /// Writes the W lanes to consecutive values.
  void store(T* p) const { std::memcpy(p, &v, sizeof(storage)); }

  /// Lane i.
  T& operator[](int i) {
    if constexpr (simd) {
      // A vector's element cannot bind a reference; the lanes are W consecutive T, and GCC and
      // Clang let T access a vector's elements.
      return reinterpret_cast<T*>(&v)[i];
    } else {
      return v[static_cast<std::size_t>(i)];
    }
  }
  /// Lane i.
  const T& operator[](int i) const {
    if constexpr (simd) {
      return reinterpret_cast<const T*>(&v)[i];
    } else {
      return v[static_cast<std::size_t>(i)];
    }
  }

  /// The lane of largest magnitude; NaN if any lane is NaN (see file comment for why).
  explicit operator T() const {
    // Branch-free reductions (max, min, NaN flag) rather than an early-exit scan: generic code
    // asks this once per sample, so it must cost a few vector instructions.
    T hi = (*this)[0], lo = (*this)[0];
    int nan = 0;
    for (int i = 0; i < W; ++i) {
      const T x = (*this)[i];
      hi = x > hi ? x : hi;
      lo = x < lo ? x : lo;
      nan |= static_cast<int>(x != x);
    }
    if (nan != 0) return std::numeric_limits<T>::quiet_NaN();
    return -lo > hi ? lo : hi;
  }

  /// Lane-wise compound arithmetic.
  Batch& operator+=(const Batch& o) {
    if constexpr (simd) {
      detail::for_each_chunk<detail::batch_storage<T, W, R>::chunks>([&](int k) NLID_CHUNK_LAMBDA { v.c[k] += o.v.c[k]; });
    } else {
      for (int i = 0; i < W; ++i) v[i] += o.v[i];
    }
    return *this;
  }
  /// Lane-wise difference.
  Batch& operator-=(const Batch& o) {
    if constexpr (simd) {
      detail::for_each_chunk<detail::batch_storage<T, W, R>::chunks>([&](int k) NLID_CHUNK_LAMBDA { v.c[k] -= o.v.c[k]; });
    } else {
      for (int i = 0; i < W; ++i) v[i] -= o.v[i];
    }
    return *this;
  }
  /// Lane-wise product.
  Batch& operator*=(const Batch& o) {
    if constexpr (simd) {
      detail::for_each_chunk<detail::batch_storage<T, W, R>::chunks>([&](int k) NLID_CHUNK_LAMBDA { v.c[k] *= o.v.c[k]; });
    } else {
      for (int i = 0; i < W; ++i) v[i] *= o.v[i];
    }
    return *this;
  }
  /// Lane-wise quotient.
  Batch& operator/=(const Batch& o) {
    if constexpr (simd) {
      detail::for_each_chunk<detail::batch_storage<T, W, R>::chunks>([&](int k) NLID_CHUNK_LAMBDA { v.c[k] /= o.v.c[k]; });
    } else {
      for (int i = 0; i < W; ++i) v[i] /= o.v[i];
    }
    return *this;
  }

 private:
  constexpr void copy_from(const Batch& o) {
    if constexpr (simd) {
      detail::for_each_chunk<detail::batch_storage<T, W, R>::chunks>([&](int k) NLID_CHUNK_LAMBDA { v.c[k] = o.v.c[k]; });
    } else {
      for (int i = 0; i < W; ++i) v[static_cast<std::size_t>(i)] = o.v[static_cast<std::size_t>(i)];
    }
  }
};

/// Result of comparing batches: per lane all bits set (true) or clear (false), the form SIMD
/// compare instructions produce. No conversion to bool (file comment).
template <class T, int W, std::size_t R = detail::simd_bytes>
struct BatchMask {
  /// Lane flags as bit masks (register-wide vectors `m.c[k]` where the batch's lanes are).
  typename detail::batch_storage<T, W, R>::bits m{};
  /// The bits of lane i.
  detail::lane_bits_t<T> bits(int i) const {
    if constexpr (detail::batch_simd_v<T, W>) {
      return reinterpret_cast<const detail::lane_bits_t<T>*>(&m)[i];
    } else {
      return m[static_cast<std::size_t>(i)];
    }
  }
  /// Lane i.
  bool operator[](int i) const { return bits(i) != 0; }
};

/// True for `Batch<T, W, R>` (cv/ref-qualified too).
template <class X>
struct is_batch : std::false_type {};
/// Specialisation recognising `Batch<T, W, R>`.
template <class T, int W, std::size_t R>
struct is_batch<Batch<T, W, R>> : std::true_type {};
/// True for any (cv/ref-qualified) `Batch<T, W, R>`.
template <class X>
inline constexpr bool is_batch_v = is_batch<std::remove_cvref_t<X>>::value;

/// A lane-parallel scalar.
/// Satisfied by `Batch<T, W, R>` for floating-point T.
template <class X>
concept BatchScalar = is_batch_v<X>;

// ---- masks -------------------------------------------------------------------------------------

/// True if every lane is set.
template <class T, int W, std::size_t R>
bool all(const BatchMask<T, W, R>& k) {
  detail::lane_bits_t<T> a = ~detail::lane_bits_t<T>(0);
  for (int i = 0; i < W; ++i) a &= k.bits(i);
  return a != 0;
}
/// True if some lane is set.
template <class T, int W, std::size_t R>
bool any(const BatchMask<T, W, R>& k) {
  detail::lane_bits_t<T> a = 0;
  for (int i = 0; i < W; ++i) a |= k.bits(i);
  return a != 0;
}
/// Lane-wise not.
template <class T, int W, std::size_t R>
BatchMask<T, W, R> operator!(const BatchMask<T, W, R>& k) {
  BatchMask<T, W, R> r;
  if constexpr (detail::batch_simd_v<T, W>) {
    detail::for_each_chunk<detail::batch_storage<T, W, R>::chunks>([&](int j) NLID_CHUNK_LAMBDA { r.m.c[j] = ~k.m.c[j]; });
  } else {
    for (int i = 0; i < W; ++i) r.m[static_cast<std::size_t>(i)] = ~k.m[static_cast<std::size_t>(i)];
  }
  return r;
}
/// Lane-wise and.
template <class T, int W, std::size_t R>
BatchMask<T, W, R> operator&&(const BatchMask<T, W, R>& a, const BatchMask<T, W, R>& b) {
  BatchMask<T, W, R> r;
  if constexpr (detail::batch_simd_v<T, W>) {
    detail::for_each_chunk<detail::batch_storage<T, W, R>::chunks>([&](int j) NLID_CHUNK_LAMBDA { r.m.c[j] = a.m.c[j] & b.m.c[j]; });
  } else {
    for (int i = 0; i < W; ++i) r.m[static_cast<std::size_t>(i)] = a.m[static_cast<std::size_t>(i)] & b.m[static_cast<std::size_t>(i)];
  }
  return r;
}
/// Lane-wise or.
template <class T, int W, std::size_t R>
BatchMask<T, W, R> operator||(const BatchMask<T, W, R>& a, const BatchMask<T, W, R>& b) {
  BatchMask<T, W, R> r;
  if constexpr (detail::batch_simd_v<T, W>) {
    detail::for_each_chunk<detail::batch_storage<T, W, R>::chunks>([&](int j) NLID_CHUNK_LAMBDA { r.m.c[j] = a.m.c[j] | b.m.c[j]; });
  } else {
    for (int i = 0; i < W; ++i) r.m[static_cast<std::size_t>(i)] = a.m[static_cast<std::size_t>(i)] | b.m[static_cast<std::size_t>(i)];
  }
  return r;
}
/// Per lane: a where the mask is set, b elsewhere — the batched `k ? a : b` (bitwise blend,
/// so it vectorises and passes NaN and infinities through unchanged).
template <class T, int W, std::size_t R>
Batch<T, W, R> select(const BatchMask<T, W, R>& k, const Batch<T, W, R>& a, const Batch<T, W, R>& b) {
  using U = detail::lane_bits_t<T>;
  Batch<T, W, R> r;
  if constexpr (detail::batch_simd_v<T, W>) {
    using S = detail::batch_storage<T, W, R>;
    detail::for_each_chunk<S::chunks>([&](int j) NLID_CHUNK_LAMBDA {
      r.v.c[j] = __builtin_bit_cast(typename S::vec, (__builtin_bit_cast(typename S::vbits, a.v.c[j]) & k.m.c[j]) |
                                                         (__builtin_bit_cast(typename S::vbits, b.v.c[j]) & ~k.m.c[j]));
    });
  } else {
    for (int i = 0; i < W; ++i) {
      const auto j = static_cast<std::size_t>(i);
      const U bits = (std::bit_cast<U>(a.v[j]) & k.m[j]) | (std::bit_cast<U>(b.v[j]) & ~k.m[j]);
      r.v[j] = std::bit_cast<T>(bits);
    }
  }
  return r;
}

// ---- arithmetic ----------------------------------------------------------------------------------
// Plain values enter through std::type_identity_t<T>: T is deduced from the batch alone, so an
// int or float constant converts instead of failing deduction.

/// Unary plus.
template <class T, int W, std::size_t R> Batch<T, W, R> operator+(const Batch<T, W, R>& x) { return x; }
/// Lane-wise negation.
template <class T, int W, std::size_t R> Batch<T, W, R> operator-(const Batch<T, W, R>& x) {
  Batch<T, W, R> r;
  if constexpr (detail::batch_simd_v<T, W>) {
    detail::for_each_chunk<detail::batch_storage<T, W, R>::chunks>([&](int j) NLID_CHUNK_LAMBDA { r.v.c[j] = -x.v.c[j]; });
  } else {
    for (int i = 0; i < W; ++i) r.v[i] = -x.v[i];
  }
  return r;
}
/// Lane-wise sum.
template <class T, int W, std::size_t R> Batch<T, W, R> operator+(Batch<T, W, R> x, const Batch<T, W, R>& y) { return x += y; }
/// Sum with a constant.
template <class T, int W, std::size_t R> Batch<T, W, R> operator+(Batch<T, W, R> x, std::type_identity_t<T> c) { return x += Batch<T, W, R>(c); }
/// Constant plus batch.
template <class T, int W, std::size_t R> Batch<T, W, R> operator+(std::type_identity_t<T> c, Batch<T, W, R> x) { return x += Batch<T, W, R>(c); }
/// Lane-wise difference.
template <class T, int W, std::size_t R> Batch<T, W, R> operator-(Batch<T, W, R> x, const Batch<T, W, R>& y) { return x -= y; }
/// Difference with a constant.
template <class T, int W, std::size_t R> Batch<T, W, R> operator-(Batch<T, W, R> x, std::type_identity_t<T> c) { return x -= Batch<T, W, R>(c); }
/// Constant minus batch.
template <class T, int W, std::size_t R> Batch<T, W, R> operator-(std::type_identity_t<T> c, const Batch<T, W, R>& x) { return Batch<T, W, R>(c) -= x; }
/// Lane-wise product.
template <class T, int W, std::size_t R> Batch<T, W, R> operator*(Batch<T, W, R> x, const Batch<T, W, R>& y) { return x *= y; }
/// Product with a constant.
template <class T, int W, std::size_t R> Batch<T, W, R> operator*(Batch<T, W, R> x, std::type_identity_t<T> c) { return x *= Batch<T, W, R>(c); }
/// Constant times batch.
template <class T, int W, std::size_t R> Batch<T, W, R> operator*(std::type_identity_t<T> c, Batch<T, W, R> x) { return x *= Batch<T, W, R>(c); }
/// Lane-wise quotient.
template <class T, int W, std::size_t R> Batch<T, W, R> operator/(Batch<T, W, R> x, const Batch<T, W, R>& y) { return x /= y; }
/// Quotient by a constant.
template <class T, int W, std::size_t R> Batch<T, W, R> operator/(Batch<T, W, R> x, std::type_identity_t<T> c) { return x /= Batch<T, W, R>(c); }
/// Constant over batch.
template <class T, int W, std::size_t R> Batch<T, W, R> operator/(std::type_identity_t<T> c, const Batch<T, W, R>& x) { return Batch<T, W, R>(c) /= x; }

namespace detail {
template <class T, int W, std::size_t R, class Op>
BatchMask<T, W, R> compare_lanes(const Batch<T, W, R>& a, const Batch<T, W, R>& b, Op op) {
  BatchMask<T, W, R> r;
  for (int i = 0; i < W; ++i) {
    const auto j = static_cast<std::size_t>(i);
    r.m[j] = op(a.v[j], b.v[j]) ? ~lane_bits_t<T>(0) : lane_bits_t<T>(0);
  }
  return r;
}
template <class T, int W, std::size_t R, class F>
Batch<T, W, R> map_lanes(const Batch<T, W, R>& x, F f) {
  Batch<T, W, R> r;
  for (int i = 0; i < W; ++i) r[i] = f(x[i]);
  return r;
}
template <class T, int W, std::size_t R, class F>
Batch<T, W, R> map_lanes(const Batch<T, W, R>& x, const Batch<T, W, R>& y, F f) {
  Batch<T, W, R> r;
  for (int i = 0; i < W; ++i) r[i] = f(x[i], y[i]);
  return r;
}
}  // namespace detail

// Comparisons (batch–batch and batch–constant) give masks.
#define NLID_BATCH_COMPARISON(OP)                                                                  \
  /** Lane-wise comparison (a mask). */                                                           \
  template <class T, int W, std::size_t R>                                                         \
  BatchMask<T, W, R> operator OP(const Batch<T, W, R>& a, const Batch<T, W, R>& b) {               \
    if constexpr (detail::batch_simd_v<T, W>) {                                                   \
      using S = detail::batch_storage<T, W, R>;                                                    \
      BatchMask<T, W, R> r;                                                                        \
      detail::for_each_chunk<S::chunks>(                                                          \
          [&](int j) NLID_CHUNK_LAMBDA { r.m.c[j] = __builtin_bit_cast(typename S::vbits, a.v.c[j] OP b.v.c[j]); }); \
      return r;                                                                                   \
    } else {                                                                                      \
      return detail::compare_lanes(a, b, [](T x, T y) { return x OP y; });                        \
    }                                                                                             \
  }                                                                                               \
  /** Comparison with a constant. */                                                              \
  template <class T, int W, std::size_t R>                                                         \
  BatchMask<T, W, R> operator OP(const Batch<T, W, R>& a, std::type_identity_t<T> c) {             \
    return a OP Batch<T, W, R>(c);                                                                 \
  }                                                                                               \
  /** Constant compared with a batch. */                                                          \
  template <class T, int W, std::size_t R>                                                         \
  BatchMask<T, W, R> operator OP(std::type_identity_t<T> c, const Batch<T, W, R>& b) {             \
    return Batch<T, W, R>(c) OP b;                                                                 \
  }
NLID_BATCH_COMPARISON(<)
NLID_BATCH_COMPARISON(<=)
NLID_BATCH_COMPARISON(>)
NLID_BATCH_COMPARISON(>=)
NLID_BATCH_COMPARISON(==)
NLID_BATCH_COMPARISON(!=)
#undef NLID_BATCH_COMPARISON

// ---- math ----------------------------------------------------------------------------------------

namespace detail {


/// Cody–Waite reduction of e^x: x = k·ln2 + r, |r| ≤ ln2/2, with ln2 split in a 32-bit-exact
/// high part and a low part, k taken from the rounding of x/ln2 + 1.5·2⁵² without a float→int
/// instruction (SSE2 lacks one for packed doubles). Sets two_k = 2^k, px = r·P(r²) and
/// qx = Q(r²) of Cephes' rational form e^r = (qx + px)/(qx − px), relative error below
/// 2.2·10⁻¹⁶. Valid for x in [−708, 709]; outside, the exponent bits wrap (unsigned: defined
/// behaviour). L names the lane types: `scalar_lanes` (one double) or `batch_chunk<double, W, R>`
/// (a GNU vector of doubles, `bits` its 64-bit unsigned twin): the same operations in the same
/// order, so a vector lane and a scalar call give the same bits. P and Q are evaluated in
/// Estrin's form (even and odd halves joined by r⁴) rather than Horner's: in a free-run
/// simulation the logistic sits on the recursion's critical path, and Estrin's form shortens
/// its dependency chain (sigmoid-network nlarx5 simulation 54 → 48 µs, its Dynamic twin 120 →
/// 108 µs; docs/performance.md).
/// Vectors go by reference: passed or returned by value they are a -Wpsabi warning.
template <class L>
NLID_BATCH_INLINE void exp_reduce_into(const typename L::type& x, typename L::type& two_k, typename L::type& px,
                                       typename L::type& qx) {
  using V = typename L::type;
  using U = typename L::bits;
  constexpr double kLog2e = 1.4426950408889634074;
  constexpr double kLn2Hi = 6.93147180369123816490e-01;
  constexpr double kLn2Lo = 1.90821492927058770002e-10;
  constexpr double kShift = 6755399441055744.0;  // 1.5·2⁵²: rounds to an integer in the low bits
  constexpr std::uint64_t kShiftBits = std::bit_cast<std::uint64_t>(kShift);
  const V kd = x * kLog2e + kShift;
  const U k = __builtin_bit_cast(U, kd) - kShiftBits;
  const V kf = kd - kShift;
  const V r = (x - kf * kLn2Hi) - kf * kLn2Lo;
  const V rr = r * r;
  const V r4 = rr * rr;
  px = r * ((3.02994407707441961300e-2 * rr + 9.99999999999999999910e-1) + 1.26177193074810590878e-4 * r4);
  qx = (3.00198505138664455042e-6 * rr + 2.52448340349684104192e-3) * r4 +
       (2.27265548208155028766e-1 * rr + 2.00000000000000000009e0);
  two_k = __builtin_bit_cast(V, (k + std::uint64_t{1023}) << 52);
}

/// The lane types of one double (see `exp_reduce_into`).
struct scalar_lanes {
  using type = double;
  using bits = std::uint64_t;
};

/// 1 if |x| > limit or x is NaN, else 0 — on the bit pattern, so a loop over lanes vectorises
/// (a floating-point compare would not, under the default -ftrapping-math). limit ≥ 0. L as in
/// `exp_reduce_into`.
template <class L>
NLID_BATCH_INLINE void beyond_into(const typename L::type& x, double limit, typename L::bits& out) {
  using U = typename L::bits;
  const U a = __builtin_bit_cast(U, x) & std::uint64_t{0x7fffffffffffffff};
  out = (std::bit_cast<std::uint64_t>(limit) - a) >> 63;  // wraps (top bit set) iff a > limit
}

/// `beyond_into` for one double.
NLID_BATCH_INLINE std::uint64_t beyond(double x, double limit) {
  std::uint64_t out;
  beyond_into<scalar_lanes>(x, limit, out);
  return out;
}

/// Bitwise or of a chunk's lanes (0 iff every lane is 0).
template <class T, int W, std::size_t R>
NLID_BATCH_INLINE lane_bits_t<T> or_lanes(const typename batch_chunk<T, W, R>::bits& u) {
  lane_bits_t<T> a = 0;
  for (int i = 0; i < batch_storage<T, W, R>::per_chunk; ++i) a |= u[i];
  return a;
}

/// |x| beyond which (and for NaN) the exp and logistic kernels hand a lane to libm: e^x
/// overflows or turns subnormal there.
inline constexpr double far_argument = 708.0;

/// Redoes the lanes of x beyond `far_argument` with kernel K's scalar fallback (rare).
template <class K, int W>
NLID_BATCH_INLINE void redo_far_lanes(const double* x, double* out) {
  for (int i = 0; i < W; ++i)
    if (beyond(x[i], far_argument) != 0) out[i] = K::far(x[i]);
}

/// e^x from the reduction's parts, for one double or one register (L as in `exp_reduce_into`).
/// e^r = 1 + 2·P/(Q − P): the form whose rounding keeps the result within 2 ulp of libm
/// (tests/core/batch_test.cpp). Lanes with |x| > 708 (overflow, subnormal results) or NaN are
/// rare and are redone by `far`, so every lane gets libm's special-value behaviour.
struct ExpKernel {
  template <class L>
  NLID_BATCH_INLINE static void value(const typename L::type& x, typename L::type& out) {
    typename L::type two_k, px, qx;
    exp_reduce_into<L>(x, two_k, px, qx);
    out = (1.0 + 2.0 * (px / (qx - px))) * two_k;
  }
  NLID_BATCH_INLINE static double far(double x) { return std::exp(x); }
};

/// The logistic function σ(s) = 1/(1 + e^(−s)) with *one* division per lane: with
/// e^(−s) = 2^k·N/D (N = qx + px, D = qx − px from `exp_reduce_into`), σ = D / (D + 2^k·N).
/// Computing e^(−s) first and then 1/(1 + e^(−s)) costs two divisions, the slowest operation
/// of a sigmoid network's unit. Lanes with |s| > 708 or NaN (rare) take the scalar formula.
struct LogisticKernel {
  template <class L>
  NLID_BATCH_INLINE static void value(const typename L::type& s, typename L::type& out) {
    typename L::type two_k, px, qx;
    const typename L::type minus_s = -s;
    exp_reduce_into<L>(minus_s, two_k, px, qx);
    const typename L::type den = qx - px;
    out = den / (den + two_k * (qx + px));
  }
  NLID_BATCH_INLINE static double far(double s) { return s >= 0 ? 1.0 / (1.0 + std::exp(-s)) : std::exp(s) / (1.0 + std::exp(s)); }
};

/// Kernel K on the vector lanes of a Batch<double, W>, register by register: the scalar
/// kernel's operations in its order, without the compiler's vectoriser in between. The
/// far-argument flags are or-ed as vectors and reduced across lanes once: a lane reduction costs
/// a few extract instructions per register, measurable in a sigmoid network.
template <class K, int W, std::size_t R>
NLID_BATCH_INLINE void vector_kernel(const typename batch_storage<double, W, R>::type& x, typename batch_storage<double, W, R>::type& out) {
  using L = batch_chunk<double, W, R>;
  typename L::bits outside{};
  for_each_chunk<batch_storage<double, W, R>::chunks>([&](int j) NLID_CHUNK_LAMBDA {
    K::template value<L>(x.c[j], out.c[j]);
    typename L::bits far;
    beyond_into<L>(x.c[j], far_argument, far);
    outside |= far;
  });
  if (or_lanes<double, W, R>(outside) != 0) [[unlikely]] {
    redo_far_lanes<K, W>(reinterpret_cast<const double*>(&x), reinterpret_cast<double*>(&out));
  }
}

/// Kernel K on W doubles in one vectorisable loop (the array storage, and plain double arrays
/// such as a sigmoid network's unit sums).
template <class K, int W>
NLID_BATCH_INLINE void lanes_kernel(const double* x, double* out) {
  // Branch-free body so the compiler vectorises it (a compare in this loop would stop GCC under
  // the default -ftrapping-math); out-of-range lanes produce garbage here and are redone below.
  for (int i = 0; i < W; ++i) K::template value<scalar_lanes>(x[i], out[i]);
  std::uint64_t outside = 0;
  for (int i = 0; i < W; ++i) outside |= beyond(x[i], far_argument);
  if (outside != 0) redo_far_lanes<K, W>(x, out);
}

/// e^x for W doubles (`ExpKernel`).
template <int W>
NLID_BATCH_INLINE void exp_lanes(const double* x, double* out) {
  lanes_kernel<ExpKernel, W>(x, out);
}

/// The logistic function for W doubles (`LogisticKernel`).
template <int W>
NLID_BATCH_INLINE void logistic_lanes(const double* s, double* out) {
  lanes_kernel<LogisticKernel, W>(s, out);
}
}  // namespace detail

/// Lane-wise e^x (vectorised kernel for double; std::exp per lane otherwise).
template <class T, int W, std::size_t R>
NLID_BATCH_INLINE Batch<T, W, R> exp(const Batch<T, W, R>& x) {
  if constexpr (std::is_same_v<T, double> && Batch<T, W, R>::simd) {
    Batch<T, W, R> r;
    detail::vector_kernel<detail::ExpKernel, W, R>(x.v, r.v);
    return r;
  } else if constexpr (std::is_same_v<T, double>) {
    Batch<T, W, R> r;
    detail::exp_lanes<W>(x.v.data(), r.v.data());
    return r;
  } else {
    return detail::map_lanes(x, [](T a) { return std::exp(a); });
  }
}

/// Lane-wise logistic 1/(1 + e^(−x)) for double lanes (one division per lane; see
/// `detail::logistic_lanes`), used by the sigmoid networks.
template <int W, std::size_t R>
NLID_BATCH_INLINE Batch<double, W, R> logistic(const Batch<double, W, R>& x) {
  Batch<double, W, R> r;
  if constexpr (Batch<double, W, R>::simd) {
    detail::vector_kernel<detail::LogisticKernel, W, R>(x.v, r.v);
  } else {
    detail::logistic_lanes<W>(x.v.data(), r.v.data());
  }
  return r;
}

#define NLID_BATCH_UNARY(NAME)                                                                  \
  /** Lane-wise std::NAME. */                                                                   \
  template <class T, int W, std::size_t R>                                                         \
  Batch<T, W, R> NAME(const Batch<T, W, R>& x) {                                                   \
    return detail::map_lanes(x, [](T a) { return std::NAME(a); });                              \
  }
NLID_BATCH_UNARY(sqrt)
NLID_BATCH_UNARY(cbrt)
NLID_BATCH_UNARY(log)
NLID_BATCH_UNARY(log10)
NLID_BATCH_UNARY(log2)
NLID_BATCH_UNARY(log1p)
NLID_BATCH_UNARY(expm1)
NLID_BATCH_UNARY(exp2)
NLID_BATCH_UNARY(sin)
NLID_BATCH_UNARY(cos)
NLID_BATCH_UNARY(tan)
NLID_BATCH_UNARY(asin)
NLID_BATCH_UNARY(acos)
NLID_BATCH_UNARY(atan)
NLID_BATCH_UNARY(sinh)
NLID_BATCH_UNARY(cosh)
NLID_BATCH_UNARY(tanh)
NLID_BATCH_UNARY(erf)
NLID_BATCH_UNARY(floor)
NLID_BATCH_UNARY(ceil)
NLID_BATCH_UNARY(round)
NLID_BATCH_UNARY(trunc)
#undef NLID_BATCH_UNARY

/// Lane-wise |x|.
template <class T, int W, std::size_t R>
Batch<T, W, R> abs(const Batch<T, W, R>& x) {
  Batch<T, W, R> r;
  if constexpr (Batch<T, W, R>::simd) {
    // Clearing the sign bit is std::fabs, for NaN too.
    using S = detail::batch_storage<T, W, R>;
    const auto magnitude = std::numeric_limits<detail::lane_bits_t<T>>::max() >> 1;
    detail::for_each_chunk<S::chunks>(
        [&](int j) NLID_CHUNK_LAMBDA { r.v.c[j] = __builtin_bit_cast(typename S::vec, __builtin_bit_cast(typename S::vbits, x.v.c[j]) & magnitude); });
  } else {
    for (int i = 0; i < W; ++i) r.v[static_cast<std::size_t>(i)] = std::fabs(x.v[static_cast<std::size_t>(i)]);
  }
  return r;
}
/// Lane-wise |x| (alias used by Eigen's norms).
template <class T, int W, std::size_t R>
Batch<T, W, R> fabs(const Batch<T, W, R>& x) {
  return abs(x);
}
/// Lane-wise x².
template <class T, int W, std::size_t R>
Batch<T, W, R> square(const Batch<T, W, R>& x) {
  return x * x;
}
/// Lane-wise std::atan2.
template <class T, int W, std::size_t R>
Batch<T, W, R> atan2(const Batch<T, W, R>& y, const Batch<T, W, R>& x) {
  return detail::map_lanes(y, x, [](T a, T b) { return std::atan2(a, b); });
}
/// Lane-wise std::hypot.
template <class T, int W, std::size_t R>
Batch<T, W, R> hypot(const Batch<T, W, R>& x, const Batch<T, W, R>& y) {
  return detail::map_lanes(x, y, [](T a, T b) { return std::hypot(a, b); });
}
/// Lane-wise std::pow.
template <class T, int W, std::size_t R>
Batch<T, W, R> pow(const Batch<T, W, R>& x, const Batch<T, W, R>& y) {
  return detail::map_lanes(x, y, [](T a, T b) { return std::pow(a, b); });
}
/// Lane-wise x^c for a constant exponent.
template <class T, int W, std::size_t R>
Batch<T, W, R> pow(const Batch<T, W, R>& x, std::type_identity_t<T> c) {
  return detail::map_lanes(x, [c](T a) { return std::pow(a, c); });
}
/// Lane-wise maximum (the larger lane; max(NaN, y) = y as std::fmax would not promise, so
/// the plain comparison form of std::max is kept for identical results with double code).
template <class T, int W, std::size_t R>
Batch<T, W, R> max(const Batch<T, W, R>& x, const Batch<T, W, R>& y) {
  if constexpr (Batch<T, W, R>::simd) {
    return select(x < y, y, x);  // std::max(a, b) is (a < b) ? b : a
  } else {
    return detail::map_lanes(x, y, [](T a, T b) { return std::max(a, b); });
  }
}
/// Lane-wise minimum (std::min per lane).
template <class T, int W, std::size_t R>
Batch<T, W, R> min(const Batch<T, W, R>& x, const Batch<T, W, R>& y) {
  if constexpr (Batch<T, W, R>::simd) {
    return select(y < x, y, x);  // std::min(a, b) is (b < a) ? b : a
  } else {
    return detail::map_lanes(x, y, [](T a, T b) { return std::min(a, b); });
  }
}
/// True if every lane is finite.
template <class T, int W, std::size_t R>
bool isfinite(const Batch<T, W, R>& x) {
  // x − x is +0 for finite lanes and NaN for ±∞ and NaN: one vectorisable pass, no branches.
  if constexpr (Batch<T, W, R>::simd) {
    using S = detail::batch_storage<T, W, R>;
    typename S::vbits d{};
    detail::for_each_chunk<S::chunks>([&](int j) NLID_CHUNK_LAMBDA { d |= __builtin_bit_cast(typename S::vbits, x.v.c[j] - x.v.c[j]); });
    return detail::or_lanes<T, W, R>(d) == 0;
  }
  T acc = T(0);
  for (int i = 0; i < W; ++i) acc += x[i] - x[i];
  return acc == T(0);
}
/// True if some lane is NaN.
template <class T, int W, std::size_t R>
bool isnan(const Batch<T, W, R>& x) {
  bool bad = false;
  for (int i = 0; i < W; ++i) bad |= std::isnan(x[i]);
  return bad;
}
/// True if some lane is infinite.
template <class T, int W, std::size_t R>
bool isinf(const Batch<T, W, R>& x) {
  bool bad = false;
  for (int i = 0; i < W; ++i) bad |= std::isinf(x[i]);
  return bad;
}

// ---- the register width, chosen at run time ------------------------------------------------------

namespace detail {
// Run-time dispatch exists where GCC's and Clang's x86 function multiversioning does: a function
// with `target("avx512f…")` is compiled for that instruction set inside a translation unit built
// for baseline x86-64, and `flatten` inlines the whole call tree below it, so the model's code
// runs there on registers of that width. NLID_NO_BATCH_DISPATCH switches it off.
#if defined(__GNUC__) && defined(__x86_64__) && !defined(NLID_NO_BATCH_DISPATCH)
#define NLID_BATCH_DISPATCH 1
/// f.template operator()<64>() compiled for AVX-512 (F, DQ, VL) with FMA.
template <class F>
[[gnu::target("avx512f,avx512dq,avx512vl,avx2,fma"), gnu::flatten]] void call_with_avx512(F& f) {
  f.template operator()<std::size_t{64}>();
}
/// f.template operator()<32>() compiled for AVX2 with FMA.
template <class F>
[[gnu::target("avx2,fma"), gnu::flatten]] void call_with_avx2(F& f) {
  f.template operator()<std::size_t{32}>();
}
#else
#define NLID_BATCH_DISPATCH 0
#endif

/// f.template operator()<R>(), compiled for the instruction set of R-byte registers where the
/// translation unit's own are narrower (and dispatch exists), else as the translation unit.
template <std::size_t R, class F>
void call_on_registers(F& f) {
#if NLID_BATCH_DISPATCH
  if constexpr (R == 64 && simd_bytes < 64) {
    call_with_avx512(f);
  } else if constexpr (R == 32 && simd_bytes < 32) {
    call_with_avx2(f);
  } else {
    f.template operator()<R>();
  }
#else
  f.template operator()<R>();
#endif
}
}  // namespace detail

/// Bytes of the registers a `Batch<T, W>` is stored in by default: the translation unit's widest
/// (16 on baseline x86-64 and ARM, 32 with AVX, 64 with AVX-512), capped at Eigen's
/// EIGEN_MAX_ALIGN_BYTES.
inline constexpr std::size_t default_register_bytes = detail::simd_bytes;

/// Bytes of the widest vector registers a `Batch` can use on the CPU running the program: 64
/// with AVX-512 (F, DQ, VL), 32 with AVX2 and FMA, else the translation unit's own width
/// (`detail::simd_bytes`, 16 on baseline x86-64 and ARM). Never less than the translation
/// unit's width: a program built with -march=native answers for the machine it was built for.
inline std::size_t cpu_register_bytes() {
#if NLID_BATCH_DISPATCH
  static const std::size_t bytes = [] {
    __builtin_cpu_init();
    std::size_t b = 16;
    if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) b = 32;
    if (b == 32 && __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq") &&
        __builtin_cpu_supports("avx512vl"))
      b = 64;
    return std::max(b, detail::simd_bytes);
  }();
  return bytes;
#else
  return detail::simd_bytes;
#endif
}

/// Calls `f.template operator()<R>()` with R = `register_bytes` (0: `cpu_register_bytes()`), as
/// a compile-time constant: the caller then works on `Batch<double, W, R>`. Where R is wider
/// than the translation unit's registers, the call is compiled for the instruction set that has
/// them (AVX2, AVX-512) and chosen at run time — a program built for baseline x86-64 still fills
/// the AVX-512 registers of the machine it runs on.
///
/// Requirement on f for R wider than the translation unit's: no `Batch<T, W, R>` in memory that
/// Eigen allocates (a dynamic-size Eigen matrix of them): Eigen aligns its heap blocks to
/// EIGEN_MAX_ALIGN_BYTES of the translation unit, less than such a Batch needs. Fixed-size Eigen
/// objects, locals and std::vector are aligned by the compiler and the standard allocator.
/// Throws `nlid::Error` if `register_bytes` is not 0, 16, 32 or 64, or wider than the CPU has.
template <class F>
void with_register_bytes(F&& f, std::size_t register_bytes = 0) {
  const std::size_t cpu = cpu_register_bytes();
  const std::size_t r = register_bytes == 0 ? cpu : register_bytes;
  require(r == 16 || r == 32 || r == 64,
          "register width " + std::to_string(register_bytes) + " bytes: use 16, 32 or 64 (or 0 for the widest)",
          at_parameter("register_bytes"));
  require(r <= cpu,
          "register width " + std::to_string(r) + " bytes: this CPU offers at most " + std::to_string(cpu),
          at_parameter("register_bytes"));
  if (r == 16) {
    detail::call_on_registers<16>(f);
  } else if (r == 32) {
    detail::call_on_registers<32>(f);
  } else {
    detail::call_on_registers<64>(f);
  }
}

// ---- many trajectories -----------------------------------------------------------------------------

namespace detail {
/// True if `Model` declares a static parameter count: nlid's fixed-size models keep every value
/// of a simulation on the stack (tests/nomalloc), so they may run on registers wider than the
/// translation unit's (see `with_register_bytes`).
template <class Model>
inline constexpr bool static_size_model_v = [] {
  if constexpr (requires { Model::num_params; }) {
    return Model::num_params >= 0;
  } else {
    return false;
  }
}();

/// `simulate_batched` on `Batch<double, W, R>`; `out` is N × K.
template <int W, std::size_t R, class Model>
void simulate_batched_into(const Model& model, const Eigen::Ref<const Eigen::MatrixXd>& u,
                           const Eigen::Ref<const Eigen::MatrixXd>& thetas, const Eigen::Ref<const Eigen::MatrixXd>& x0s,
                           Eigen::MatrixXd& out) {
  using B = Batch<double, W, R>;
  const Eigen::Index k_runs = thetas.cols(), p = thetas.rows(), n = u.rows(), nx = x0s.rows();
  std::vector<B> th(static_cast<std::size_t>(p)), x0(x0s.cols() > 0 ? static_cast<std::size_t>(nx) : 0),
      y(static_cast<std::size_t>(n));
  for (Eigen::Index k0 = 0; k0 < k_runs; k0 += W) {
    const auto lane_run = [&](int w) { return k0 + w < k_runs ? k0 + w : k0; };
    for (Eigen::Index j = 0; j < p; ++j)
      for (int w = 0; w < W; ++w) th[static_cast<std::size_t>(j)][w] = thetas(j, lane_run(w));
    for (std::size_t j = 0; j < x0.size(); ++j)
      for (int w = 0; w < W; ++w) x0[j][w] = x0s(static_cast<Eigen::Index>(j), lane_run(w));
    const bool ok = model.simulate(u, std::span<const B>(th), std::span<const B>(x0), std::span<B>(y));
    for (int w = 0; w < W && k0 + w < k_runs; ++w)
      for (Eigen::Index t = 0; t < n; ++t)
        out(t, k0 + w) = ok ? y[static_cast<std::size_t>(t)][w] : std::numeric_limits<double>::quiet_NaN();
  }
}
}  // namespace detail

/// A model whose free run `simulate_batched` can take: the scalar-generic core
/// `simulate(u, std::span<const S> theta, std::span<const S> x0, std::span<S> y) -> bool` on
/// S = Batch<double, W>. Satisfied by `Nlarx`, `HammersteinWiener` and series models (whose
/// blocks must then be branch-free to compile). Grey-box models have their own overload
/// (models/greybox_batched.hpp).
template <class M, int W>
concept BatchSimulatable = requires(const M& m, const Eigen::Ref<const Eigen::MatrixXd>& u,
                                    std::span<const Batch<double, W>> c, std::span<Batch<double, W>> y) {
  { m.simulate(u, c, c, y) } -> std::convertible_to<bool>;
};

/// Free-run simulation of K parameter sets of one model on a shared input record, W at a time.
///
/// `model` is any model with the scalar-generic core
/// `template <class S> bool simulate(u, std::span<const S> theta, std::span<const S> x0, std::span<S> y) const`
/// (Nlarx, HammersteinWiener with branch-free blocks, and compositions of such). `thetas` is
/// p × K (column k = parameter set k), `x0s` is n_x × K or empty (every run from the zero state).
/// Returns the N × K outputs; a run that diverges has NaN from the sample where its batch
/// stopped. A last incomplete batch is padded with copies of its first run.
///
/// Registers: a model of static size runs on the widest vector registers of the CPU
/// (`cpu_register_bytes()`, chosen at run time: AVX-512 or AVX2 code inside a program built for
/// baseline x86-64), or on `register_bytes` if given; a model with run-time sizes keeps its
/// values in Eigen's heap blocks and runs on the translation unit's registers. The lanes then
/// may use fused multiply-adds where a single `simulate` does not, so they agree with single runs
/// to rounding (about 1e-15 relative per sample), not bit for bit.
/// Throws `nlid::Error` if `x0s` has columns but not K of them, or for a `register_bytes` that
/// is not 16, 32 or 64, wider than the CPU offers, or wider than the translation unit's for a
/// model with run-time sizes.
template <int W, BatchSimulatable<W> Model>
Eigen::MatrixXd simulate_batched(const Model& model, const Eigen::Ref<const Eigen::MatrixXd>& u,
                                 const Eigen::Ref<const Eigen::MatrixXd>& thetas,
                                 const Eigen::Ref<const Eigen::MatrixXd>& x0s = Eigen::MatrixXd(),
                                 std::size_t register_bytes = 0) {
  const Eigen::Index k_runs = thetas.cols();
  require(x0s.cols() == 0 || x0s.cols() == k_runs,
          "x0s has " + std::to_string(x0s.cols()) + " columns for " + std::to_string(k_runs) + " parameter sets",
          at_parameter("x0s"));
  Eigen::MatrixXd out(u.rows(), k_runs);
  if constexpr (detail::static_size_model_v<Model>) {
    with_register_bytes([&]<std::size_t R>() { detail::simulate_batched_into<W, R>(model, u, thetas, x0s, out); },
                        register_bytes);
  } else {
    require(register_bytes == 0 || register_bytes == detail::simd_bytes,
            "register width " + std::to_string(register_bytes) +
                " bytes: a model with run-time sizes runs on this program's own " + std::to_string(detail::simd_bytes),
            at_parameter("register_bytes"));
    detail::simulate_batched_into<W, detail::simd_bytes>(model, u, thetas, x0s, out);
  }
  return out;
}

}  // namespace nlid

// ---- Eigen glue: a Batch as the scalar of Eigen matrices ---------------------------------------
namespace Eigen {

/// Eigen scalar traits of a batch: precision of T, costs W times those of T.
template <class T, int W, std::size_t R>
struct NumTraits<nlid::Batch<T, W, R>> : NumTraits<T> {
  using Real = nlid::Batch<T, W, R>;
  using NonInteger = nlid::Batch<T, W, R>;
  using Nested = nlid::Batch<T, W, R>;
  using Literal = nlid::Batch<T, W, R>;
  enum {
    IsComplex = 0,
    IsInteger = 0,
    IsSigned = 1,
    RequireInitialization = 1,
    ReadCost = W * NumTraits<T>::ReadCost,
    AddCost = W * NumTraits<T>::AddCost,
    MulCost = W * NumTraits<T>::MulCost,
  };
  static Real epsilon() { return Real(NumTraits<T>::epsilon()); }
  static Real dummy_precision() { return Real(NumTraits<T>::dummy_precision()); }
  static Real highest() { return Real(NumTraits<T>::highest()); }
  static Real lowest() { return Real(NumTraits<T>::lowest()); }
  static Real infinity() { return Real(NumTraits<T>::infinity()); }
  static Real quiet_NaN() { return Real(NumTraits<T>::quiet_NaN()); }
  static inline int digits10() { return NumTraits<T>::digits10(); }
  static inline int digits() { return NumTraits<T>::digits(); }
};

namespace internal {
/// Eigen's fixed-size storage aligns its array to EIGEN_MAX_STATIC_ALIGN_BYTES (16 on baseline
/// x86-64). A Batch on wider registers (run-time dispatch, `nlid::with_register_bytes`) is
/// aligned to its register already, and Clang rejects an alignas below a type's own alignment:
/// such storage takes the Batch's alignment alone. Narrower Batches keep Eigen's default.
template <class T, int W, std::size_t R, int Size>
struct compute_default_alignment<nlid::Batch<T, W, R>, Size> {
  enum {
    value = alignof(nlid::Batch<T, W, R>) > EIGEN_MAX_STATIC_ALIGN_BYTES
                ? 0
                : compute_default_alignment_helper<Size * static_cast<int>(sizeof(nlid::Batch<T, W, R>)),
                                                   EIGEN_MAX_STATIC_ALIGN_BYTES>::value
  };
};
/// The same for dynamic sizes (disambiguates Eigen's own specialisation for them).
template <class T, int W, std::size_t R>
struct compute_default_alignment<nlid::Batch<T, W, R>, Dynamic> {
  enum { value = alignof(nlid::Batch<T, W, R>) > EIGEN_MAX_STATIC_ALIGN_BYTES ? 0 : EIGEN_MAX_ALIGN_BYTES };
};
}  // namespace internal

/// Batch/plain-scalar expressions (`double * Matrix<Batch>`) yield Batch.
template <class T, int W, std::size_t R, class BinaryOp>
struct ScalarBinaryOpTraits<nlid::Batch<T, W, R>, T, BinaryOp> {
  using ReturnType = nlid::Batch<T, W, R>;
};
/// Plain-scalar/Batch expressions yield Batch.
template <class T, int W, std::size_t R, class BinaryOp>
struct ScalarBinaryOpTraits<T, nlid::Batch<T, W, R>, BinaryOp> {
  using ReturnType = nlid::Batch<T, W, R>;
};

}  // namespace Eigen
