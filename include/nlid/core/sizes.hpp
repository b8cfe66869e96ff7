#pragma once
/// @file
/// Compile-time sizes. nlid follows Eigen: a block's dimension is an `int` template parameter,
/// and `Dynamic` (the same value as `Eigen::Dynamic`) means "chosen at run time". Static sizes
/// describe per-block dimensions only (parameters, regressors, states), never data lengths.

namespace nlid {

/// "Size chosen at run time" (equal to `Eigen::Dynamic`, so it can be passed straight to Eigen).
inline constexpr int Dynamic = -1;

/// Largest model order or delay (na, nb, nf, nk) accepted anywhere: far beyond any real model
/// (10⁵ samples of delay), and small enough that lag arithmetic such as nk + nb − 1 cannot
/// overflow an int. The model-file loader and the model specs use the same limit.
inline constexpr int max_model_order = 100000;

/// Sum of sizes; `Dynamic` if any term is dynamic. Used by compositions to compute their own size.
template <class... Ints>
constexpr int size_sum(Ints... n) {
  bool dyn = ((n == Dynamic) || ...);
  return dyn ? Dynamic : (0 + ... + n);
}

/// Product of sizes; `Dynamic` if any factor is dynamic.
template <class... Ints>
constexpr int size_product(Ints... n) {
  bool dyn = ((n == Dynamic) || ...);
  return dyn ? Dynamic : (1 * ... * n);
}

/// True if the size is fixed at compile time.
constexpr bool is_static(int n) { return n != Dynamic; }

}  // namespace nlid
