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

/// Largest parameter count of one nonlinearity (a network's units × inputs, a tree's leaves ×
/// inputs): far beyond any model nlid can estimate (2²⁴ ≈ 1.7·10⁷ values, 128 MiB of θ), and small
/// enough that the size arithmetic of the maps (offsets, split tables) cannot overflow an int. The
/// constructors refuse more, so a model file cannot make the loader allocate gigabytes.
inline constexpr long long max_nonlinearity_parameters = 1LL << 24;

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
