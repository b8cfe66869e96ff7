#pragma once
/// @file
/// Exact least-squares placement of a one-sided limit (used by Saturation and DeadZone).
///
/// Both maps are "x-like in the middle, something else beyond a limit ℓ". With the samples
/// sorted by x, the samples beyond a lower limit ℓ are a prefix of length k, and the change of the
/// sum of squares caused by that limit is
///
///     C(ℓ) = Σ_{i<k} (aᵢ + ℓ)² − bᵢ,    ℓ ∈ [x₍ₖ₋₁₎, x₍ₖ₎],
///
/// with aᵢ, bᵢ depending on the map. For each k the minimiser is −mean(a) clamped to the
/// interval; prefix sums give every k in O(1), so the global least-squares limit is found in
/// O(N log N) with no starting guess. An upper limit is the same problem mirrored (x → −x).

#include <algorithm>
#include <limits>
#include <numeric>
#include <vector>

namespace nlid::detail {

/// Result of a limit scan: the limit and how many samples lie beyond it.
struct LimitFit {
  double limit = 0;
  long active = 0;
  double cost_change = 0;
};

/// Lower limit minimising Σ_{xᵢ<ℓ} (aᵢ+ℓ)² − bᵢ. `x` must be sorted ascending; a, b in the same
/// order. With no sample beyond the limit (k = 0) the limit is put at x₍₀₎, where it is
/// inactive on the data.
inline LimitFit scan_lower_limit(const std::vector<double>& x, const std::vector<double>& a,
                                 const std::vector<double>& b) {
  const std::size_t n = x.size();
  LimitFit best;
  best.limit = n ? x[0] : 0.0;
  // A limit must beat "no limit" by more than rounding, judged against the data's own energy
  // (an absolute floor would refuse every limit of data in small units: y ~ 1e-9 gives cost
  // changes ~ 1e-18).
  double energy = 0;
  for (std::size_t i = 0; i < n; ++i) energy += a[i] * a[i] + std::abs(b[i]);
  double sa = 0, saa = 0, sb = 0;
  for (std::size_t k = 1; k <= n; ++k) {
    sa += a[k - 1];
    saa += a[k - 1] * a[k - 1];
    sb += b[k - 1];
    const double lo = x[k - 1];
    const double hi = k < n ? x[k] : std::numeric_limits<double>::infinity();
    const double kk = static_cast<double>(k);
    const double l = std::clamp(-sa / kk, lo, hi);
    const double c = kk * l * l + 2 * l * sa + saa - sb;
    if (c < best.cost_change - 1e-12 * (energy + std::abs(best.cost_change))) {
      best.cost_change = c;
      best.limit = l;
      best.active = static_cast<long>(k);
    }
  }
  return best;
}

/// Upper limit minimising Σ_{xᵢ>ℓ} (aᵢ+ℓ)² − bᵢ (x sorted ascending), via the mirror image.
inline LimitFit scan_upper_limit(const std::vector<double>& x, const std::vector<double>& a,
                                 const std::vector<double>& b) {
  const std::size_t n = x.size();
  std::vector<double> xm(n), am(n), bm(n);
  for (std::size_t i = 0; i < n; ++i) {
    xm[i] = -x[n - 1 - i];
    am[i] = -a[n - 1 - i];
    bm[i] = b[n - 1 - i];
  }
  LimitFit f = scan_lower_limit(xm, am, bm);
  f.limit = -f.limit;
  return f;
}

/// Permutation sorting x ascending (stable, so ties keep data order: deterministic).
inline std::vector<std::size_t> sort_permutation(const double* x, std::size_t n) {
  std::vector<std::size_t> idx(n);
  std::iota(idx.begin(), idx.end(), std::size_t{0});
  std::stable_sort(idx.begin(), idx.end(), [x](std::size_t i, std::size_t j) { return x[i] < x[j]; });
  return idx;
}

}  // namespace nlid::detail
