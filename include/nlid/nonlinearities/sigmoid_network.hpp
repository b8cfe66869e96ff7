#pragma once
/// @file
/// `SigmoidNet<M, Units, LinearTerm>`: a one-hidden-layer sigmoid network with a linear term —
/// the toolbox's `sigmoidnet` / idSigmoidNetwork, the nonlinearity of the study's best black-box
/// model `nlarx5` (5 units on the regressors of orders [3 3 0]).
///
/// Math (Sjöberg et al. 1995, Automatica 31(12), eqs. (8), (19); Ljung 1999, Sec. 5.4):
///
///     z    = (x − r) ⊘ s                                  standardised regressors
///     g(x) = zᵀL + d + Σₖ aₖ σ(zᵀbₖ + cₖ),  k = 0 … n−1,   σ(t) = 1/(1 + e^(−t)).
///
/// r is the regressor mean and s the regressor standard deviation, both learned by `initialize`
/// and kept as structure (not parameters). In the toolbox notation g = (x−r)ᵀPL + d +
/// Σ aₖσ((x−r)ᵀQbₖ + cₖ) this is P = Q = diag(1/s); `set_standardize(false)` gives s = 1, i.e.
/// P = Q = I as in MATLAB. Standardising makes one set of initial slopes fit data in any units
/// (degrees next to a normalised command) and conditions the Jacobian. `describe` also prints L
/// converted back to the units of x (Lⱼ/sⱼ).
///
/// Parameter vector (linear-in-θ parameters first, so a caller can solve them by least squares):
///
///     θ = [ L[0..m−1] (only if LinearTerm),  d,  a[0..n−1],  b[0][0..m−1] … b[n−1][0..m−1],  c[0..n−1] ]
///
/// p = (LinearTerm ? m : 0) + 1 + n(m + 2).
///
/// Initialisation (deterministic; no random restarts):
/// 1. r, s from the data; Z = standardised regressors;
/// 2. a dictionary of candidate units σ(β(vᵀz − q)/σ_v): directions v = principal axes of Z,
///    coordinate axes and quasi-random (low-discrepancy) directions; for each, offsets q at
///    quantiles of the projection vᵀz (so the transition of every candidate lies inside the data)
///    and slopes β ∈ {1, 2.5, 6} relative to the projection's spread σ_v;
/// 3. forward selection by orthogonal least squares (Chen, Cowan & Grant 1991): with the offset
///    and the linear term already in the model, repeatedly add the candidate that explains most
///    of the remaining residual, n times;
/// 4. with the unit parameters b, c fixed, L, d and a by linear least squares on all samples.
/// Alternative starts (`initialize(X, y, θ, k)`, compared by `EstimateOptions::starts`) extend
/// the slope ladder by k rungs of ×2.5 (15.6, 39, 98, …), so the dictionary also offers units
/// with a narrow transition, e.g. the sign of a velocity for Coulomb friction.
/// The result is already a good fit (the dictionary covers the directions and places where the
/// data bend), and a local optimiser (Levenberg–Marquardt) refines all of θ from there.
///
/// Sizes: M (inputs) and Units may each be fixed or `nlid::Dynamic` (runtime arguments of the
/// constructor). With both fixed, evaluation uses stack storage only.

#include <algorithm>
#include <array>
#include <cmath>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/core/sizes.hpp"
#include "nlid/nonlinearities/detail/common.hpp"
#include "nlid/nonlinearities/detail/forward_selection.hpp"
#include "nlid/nonlinearities/detail/regressor_cloud.hpp"
#include "nlid/nonlinearities/detail/standardizer.hpp"

namespace nlid {

/// Sigmoid network g(x) = zᵀL + d + Σₖ aₖ σ(zᵀbₖ + cₖ), z = (x − r) ⊘ s (see file comment).
/// Invariants: input_dimension() ≥ 1, num_units() ≥ 1, each equal to M / Units when fixed;
/// the scale s is positive.
template <int M, int Units, bool LinearTerm = true>
  requires((M == Dynamic || M >= 1) && (Units == Dynamic || Units >= 1))
class SigmoidNet {
 public:
  /// m (or Dynamic).
  static constexpr int num_inputs = M;
  /// n (or Dynamic).
  static constexpr int num_units = Units;
  /// Whether the linear term zᵀL is present.
  static constexpr bool has_linear_term = LinearTerm;
  /// p = (LinearTerm ? m : 0) + 1 + n(m + 2), or Dynamic.
  static constexpr int num_params =
      (M == Dynamic || Units == Dynamic) ? Dynamic : (LinearTerm ? M : 0) + 1 + Units * (M + 2);

  /// Fixed sizes; normalisation r = 0, s = 1 until `initialize`.
  SigmoidNet()
    requires(M != Dynamic && Units != Dynamic)
  = default;
  /// m inputs and n units (each must match the compile-time value when fixed). Throws naming
  /// "m" or "units" if a value is < 1 or contradicts the template argument, and naming "units"
  /// if the network would have more than `max_nonlinearity_parameters` parameters.
  SigmoidNet(int m, int units)
      : m_(detail::checked_size(m, M, 1, "m", "SigmoidNet")),
        units_(detail::checked_size(units, Units, 1, "units", "SigmoidNet")),
        norm_(m_) {
    detail::check_parameter_count((LinearTerm ? m_ : 0) + 1 + static_cast<long long>(units_) * (m_ + 2LL), "units",
                                  "SigmoidNet", units_, "units", m_);
  }

  /// Number of inputs m.
  [[nodiscard]] int input_dimension() const { return m_; }
  /// Number of sigmoid units n (runtime).
  [[nodiscard]] int units() const { return units_; }
  /// Number of parameters p.
  [[nodiscard]] int num_parameters() const { return off_c() + units_; }

  /// Regressor centre r.
  [[nodiscard]] const Eigen::Matrix<double, M, 1>& center() const { return norm_.center(); }
  /// Regressor scale s.
  [[nodiscard]] Eigen::Matrix<double, M, 1> scale() const { return norm_.scale(); }
  /// True (default) if `initialize` sets s to the standard deviation; false: s = 1.
  [[nodiscard]] bool standardize() const { return norm_.standardize(); }
  /// See `standardize()`; takes effect at the next `initialize`.
  void set_standardize(bool on) { norm_.set_standardize(on); }
  /// Sets r and s directly (loading a saved model). Throws naming "normalization".
  void set_normalization(const Eigen::VectorXd& center, const Eigen::VectorXd& scale) {
    norm_.set_normalization(center, scale, "SigmoidNet");
  }

  /// Index of the first entry of each parameter block in θ (layout in the file comment).
  [[nodiscard]] int offset_L() const { return 0; }
  /// Index of d in θ.
  [[nodiscard]] int offset_d() const { return LinearTerm ? m_ : 0; }
  /// Index of a[0] in θ.
  [[nodiscard]] int offset_a() const { return offset_d() + 1; }
  /// Index of b[0][0] in θ (b[k][j] at offset_b() + k·m + j).
  [[nodiscard]] int offset_b() const { return offset_a() + units_; }
  /// Index of c[0] in θ.
  [[nodiscard]] int offset_c() const { return off_c(); }

  /// g(x). Throws `nlid::Error` if x or θ has the wrong length.
  template <class T>
  [[nodiscard]] T operator()(std::span<const T> x, std::span<const T> theta) const {
    if (static_cast<int>(x.size()) != m_) detail::check_size(x.size(), m_, "x", "SigmoidNet");
    if (static_cast<int>(theta.size()) != num_parameters()) {
      detail::check_size(theta.size(), num_parameters(), "theta", "SigmoidNet");
    }
    if constexpr (M != Dynamic) {
      std::array<T, static_cast<std::size_t>(M)> z;
      for (int j = 0; j < M; ++j) z[static_cast<std::size_t>(j)] = norm_.z(x[static_cast<std::size_t>(j)], j);
      return evaluate(theta, [&z](int j) -> const T& { return z[static_cast<std::size_t>(j)]; });
    } else {
      // No buffer for a runtime m (it would allocate); zⱼ is recomputed per unit instead.
      return evaluate(theta, [&](int j) { return norm_.z(x[static_cast<std::size_t>(j)], j); });
    }
  }

  /// g(x) together with its gradient, for plain numbers: ∂g/∂θ into `g_theta` (p entries) and
  /// ∂g/∂x into `g_x` (m entries). The value is bitwise that of `operator()` on double (same
  /// operations in the same order, for the fixed and the Dynamic twin). With aₖ' = aₖσₖ(1 − σₖ):
  ///     ∂g/∂L = z,  ∂g/∂d = 1,  ∂g/∂aₖ = σₖ,  ∂g/∂bₖ = aₖ' z,  ∂g/∂cₖ = aₖ',
  ///     ∂g/∂xⱼ = (Lⱼ + Σₖ aₖ' bₖⱼ) / sⱼ.
  /// Why: Nlarx's simulation-focus Jacobian needs one local gradient per sample
  /// (models/detail/nlarx_sensitivity.hpp); written out it costs O(p) flops, where a p-wide
  /// dual costs O(p) per operation of the network. Throws `nlid::Error` on wrong lengths.
  double gradient(std::span<const double> x, std::span<const double> theta, std::span<double> g_theta,
                  std::span<double> g_x) const {
    if (static_cast<int>(x.size()) != m_) detail::check_size(x.size(), m_, "x", "SigmoidNet");
    if (static_cast<int>(g_x.size()) != m_) detail::check_size(g_x.size(), m_, "g_x", "SigmoidNet");
    if (static_cast<int>(theta.size()) != num_parameters()) {
      detail::check_size(theta.size(), num_parameters(), "theta", "SigmoidNet");
    }
    if (static_cast<int>(g_theta.size()) != num_parameters()) {
      detail::check_size(g_theta.size(), num_parameters(), "g_theta", "SigmoidNet");
    }
    if constexpr (M != Dynamic) {
      std::array<double, static_cast<std::size_t>(M)> z;
      for (int j = 0; j < M; ++j) z[static_cast<std::size_t>(j)] = norm_.z(x[static_cast<std::size_t>(j)], j);
      return evaluate_gradient(theta, [&z](int j) { return z[static_cast<std::size_t>(j)]; }, g_theta, g_x);
    } else {
      return evaluate_gradient(theta, [&](int j) { return norm_.z(x[static_cast<std::size_t>(j)], j); }, g_theta, g_x);
    }
  }

  /// Data-driven start (see file comment). X is N × m, y has N entries, θ has p entries.
  void initialize(const Eigen::MatrixXd& X, const Eigen::VectorXd& y, std::span<double> theta) {
    initialize(X, y, theta, 0);
  }

  /// Alternative data-driven start number `start` ≥ 0 (0: the default start above). Start k
  /// extends the dictionary's ladder of slopes β ∈ {1, 2.5, 6} by k further rungs 6.25·2.5^j,
  /// j = 1 … k (15.6, 39, 98, …): steeper candidate units whose transition is narrow compared
  /// with the spread of their projection — the near-discontinuous effects a smooth start misses, e.g. the
  /// sign change of Coulomb friction at zero velocity, which is a tiny part of a velocity
  /// projection's range. Which start is best is a matter of the estimation cost
  /// (`EstimateOptions::starts` compares them). Throws naming "start" if start < 0.
  void initialize(const Eigen::MatrixXd& X, const Eigen::VectorXd& y, std::span<double> theta, int start) {
    detail::check_init_data(X, y, theta.size(), m_, num_parameters(), 2, "SigmoidNet");
    if (start < 0) throw Error("SigmoidNet: start must be >= 0, got " + std::to_string(start), at_parameter("start"));
    const Eigen::MatrixXd Z = norm_.fit(X);
    const auto rows = detail::subsample_rows(Z.rows(), 2000);
    const Eigen::MatrixXd Zs = detail::take_rows(Z, rows);
    Eigen::VectorXd ys(static_cast<Eigen::Index>(rows.size()));
    for (std::size_t i = 0; i < rows.size(); ++i) ys(static_cast<Eigen::Index>(i)) = y(rows[i]);

    // Candidate dictionary.
    const auto dirs = detail::projection_directions(Zs, std::min(48, std::max(16, 4 * m_)));
    std::vector<double> slopes{1.0, 2.5, 6.0};
    for (int k = 0; k < start; ++k) slopes.push_back(6.25 * std::pow(2.5, k + 1));
    const int per_dir = static_cast<int>(slopes.size());
    const int levels = std::max(7, 2 * units_ / (per_dir * static_cast<int>(dirs.size())) + 2);
    std::vector<Eigen::VectorXd> cand_b;
    std::vector<double> cand_c;
    for (Eigen::VectorXd v : dirs) {
      // An unused regressor's z is 0: a weight on it would change nothing, so it gets none
      // (the projection, and so the dictionary, is the same).
      for (int j = 0; j < m_; ++j)
        if (!norm_.used(j)) v(j) = 0.0;
      const Eigen::VectorXd p = Zs * v;
      const double sd = std::sqrt((p.array() - p.mean()).square().mean());
      if (!(sd > 1e-12)) continue;
      const auto sorted = detail::sorted_copy(p);
      for (double beta : slopes) {
        for (int l = 0; l < levels; ++l) {
          const double q = detail::quantile_sorted(sorted, (l + 0.5) / levels);
          cand_b.push_back(v * (beta / sd));
          cand_c.push_back(-beta * q / sd);
        }
      }
    }
    const auto nc = static_cast<Eigen::Index>(cand_b.size());
    Eigen::MatrixXd H(Zs.rows(), nc);
    for (Eigen::Index j = 0; j < nc; ++j) {
      const Eigen::VectorXd s = Zs * cand_b[static_cast<std::size_t>(j)];
      for (Eigen::Index i = 0; i < Zs.rows(); ++i) H(i, j) = detail::logistic(s(i) + cand_c[static_cast<std::size_t>(j)]);
    }
    detail::ForwardSelector sel(ys, std::move(H), 1);
    sel.add_fixed(Eigen::VectorXd::Ones(Zs.rows()));
    if constexpr (LinearTerm) {
      for (int j = 0; j < m_; ++j) sel.add_fixed(Zs.col(j));
    }
    if (nc == 0) {
      throw Error("SigmoidNet: the regressors do not vary; no sigmoid unit can be placed",
                  at_parameter("X"));
    }
    std::vector<int> chosen;
    for (int k = 0; k < units_; ++k) {
      const int j = sel.select();
      if (j < 0) break;
      chosen.push_back(j);
    }
    // A dictionary smaller than n (tiny data sets) repeats units with shifted offsets, keeping
    // them distinct; their weights come out of the least-squares fit below.
    for (int k = static_cast<int>(chosen.size()); k < units_; ++k) chosen.push_back(k % static_cast<int>(nc));

    for (int k = 0; k < units_; ++k) {
      const auto j = static_cast<std::size_t>(chosen[static_cast<std::size_t>(k)]);
      const double shift = k < static_cast<int>(nc) ? 0.0 : 0.5 * (k / static_cast<int>(nc));
      for (int i = 0; i < m_; ++i) theta[static_cast<std::size_t>(offset_b() + k * m_ + i)] = cand_b[j](i);
      theta[static_cast<std::size_t>(off_c() + k)] = cand_c[j] + shift;
    }
    solve_linear(Z, y, theta);
  }

  /// With the unit parameters b, c in θ held fixed, sets L, d and a to their least-squares
  /// values for (X, y) under the current normalisation: the linear sub-problem of the fit
  /// (useful after changing units by hand, or for separable least squares).
  void fit_linear_parameters(const Eigen::MatrixXd& X, const Eigen::VectorXd& y, std::span<double> theta) const {
    detail::check_init_data(X, y, theta.size(), m_, num_parameters(), 1, "SigmoidNet");
    solve_linear(norm_.transform(X), y, theta);
  }

  /// "L[j]", "d", "a[k]", "b[k][j]", "c[k]" in θ order.
  [[nodiscard]] std::vector<std::string> parameter_names() const {
    std::vector<std::string> n;
    if constexpr (LinearTerm) {
      for (int j = 0; j < m_; ++j) n.push_back("L[" + std::to_string(j) + "]");
    }
    n.emplace_back("d");
    for (int k = 0; k < units_; ++k) n.push_back("a[" + std::to_string(k) + "]");
    for (int k = 0; k < units_; ++k) {
      for (int j = 0; j < m_; ++j) n.push_back("b[" + std::to_string(k) + "][" + std::to_string(j) + "]");
    }
    for (int k = 0; k < units_; ++k) n.push_back("c[" + std::to_string(k) + "]");
    return n;
  }

  /// The equation, the normalisation and all parameter values.
  [[nodiscard]] std::string describe(std::span<const double> theta) const { return describe(theta, {}); }

  /// As `describe(theta)`, naming the inputs (e.g. regressor names); `input_names` empty or m.
  [[nodiscard]] std::string describe(std::span<const double> theta, const std::vector<std::string>& input_names) const {
    detail::check_size(theta.size(), num_parameters(), "theta", "SigmoidNet");
    const auto names = detail::input_names_or_default(input_names, m_, "SigmoidNet");
    const auto th = [&](int i) { return theta[static_cast<std::size_t>(i)]; };
    const Eigen::VectorXd r = norm_.center(), s = norm_.scale();
    using detail::left_aligned;  // the table columns
    std::string o = "sigmoid network (" + std::to_string(m_) + " inputs, " + std::to_string(units_) + " units" +
                    (LinearTerm ? ", linear term" : "") + "):\n";
    o += std::string("  g(x) = ") + (LinearTerm ? "z'L + " : "") +
         "d + sum_k a[k]*sigma(z'b[k] + c[k]),  sigma(t) = 1/(1+exp(-t)),  z = (x - r)./s\n";
    o += "  input            r (centre)    s (scale)";
    if constexpr (LinearTerm) o += "     L[j]          L[j]/s (per unit of x)";
    o += "\n";
    for (int j = 0; j < m_; ++j) {
      o += "  " + left_aligned(names[static_cast<std::size_t>(j)], 16) + " " +
           left_aligned(detail::format_g(r(j)), 13) + " " + left_aligned(detail::scale_text(s(j)), 13);
      if constexpr (LinearTerm)
        o += " " + left_aligned(detail::format_g(th(j)), 13) + " " + detail::per_unit_text(th(j), s(j));
      o += "\n";
    }
    o += detail::unused_note(s);
    o += "  d = " + detail::format_g(th(offset_d())) + "\n";
    o += "  unit  a[k]          c[k]          b[k]\n";
    for (int k = 0; k < units_; ++k) {
      o += "  " + left_aligned(std::to_string(k), 5) + " " + left_aligned(detail::format_g(th(offset_a() + k)), 13) +
           " " + left_aligned(detail::format_g(th(off_c() + k)), 13) + " [";
      for (int j = 0; j < m_; ++j) o += (j ? ", " : "") + detail::format_g(th(offset_b() + k * m_ + j));
      o += "]\n";
    }
    return o;
  }

  // ---- Implementation details below ----------------------------------------------------------
 private:
  [[nodiscard]] int off_c() const { return offset_b() + units_ * m_; }

  template <class T, class Z>
  T evaluate(std::span<const T> theta, Z&& z) const {
    // Fixed sizes as compile-time constants: the loops unroll and the offsets fold, which is
    // what makes the fixed-size model as fast as a hand-written loop (benchmarks/).
    const int m = M != Dynamic ? M : m_;
    const int units = Units != Dynamic ? Units : units_;
    const auto at = [&theta](int i) -> const T& { return theta[static_cast<std::size_t>(i)]; };
    const int od = LinearTerm ? m : 0, oa = od + 1, ob = oa + units, oc = ob + units * m;
    if constexpr (std::is_same_v<T, double> && Units != Dynamic) {
      // Plain numbers, unit count known (the fixed-size fast path; the loop below computes the
      // same numbers one unit at a time, for the Dynamic twin, Duals and code generation):
      // - the units are independent, so their logistic functions run side by side in SIMD
      //   lanes (core/batch.hpp's kernel, one division per unit; detail::logistic on double is
      //   one lane of the same kernel) instead of one libm exp and two divisions after another;
      // - sums run from the last regressor to the first: in a free run the first regressors
      //   are the most recent outputs (ŷ(t−1) first in LaggedRegressors), so the terms of the
      //   inputs and older outputs are summed while the previous sample is still being
      //   computed, and ŷ(t−1) enters last, shortening the recursion's critical path.
      return evaluate_lanes(theta, z, m, od, oa, ob, oc);
    } else {
      // The same order of operations as evaluate_lanes (last regressor first), so on double the
      // twins agree bitwise.
      T g = at(od);
      if constexpr (LinearTerm) {
        for (int j = m - 1; j >= 0; --j) g += at(j) * z(j);
      }
      for (int k = 0; k < units; ++k) {
        T s = at(oc + k);
        for (int j = m - 1; j >= 0; --j) s += at(ob + k * m + j) * z(j);
        g += at(oa + k) * detail::logistic(s);
      }
      return g;
    }
  }

  template <class Z>
  double evaluate_lanes(std::span<const double> theta, Z&& z, int m, int od, int oa, int ob, int oc) const {
    const auto at = [&theta](int i) { return theta[static_cast<std::size_t>(i)]; };
    std::array<double, static_cast<std::size_t>(Units)> s, sig;
    for (int k = 0; k < Units; ++k) {
      double sk = at(oc + k);
      for (int j = m - 1; j >= 0; --j) sk += at(ob + k * m + j) * z(j);
      s[static_cast<std::size_t>(k)] = sk;
    }
    detail::logistic_lanes<Units>(s.data(), sig.data());
    double g = at(od);
    if constexpr (LinearTerm) {
      for (int j = m - 1; j >= 0; --j) g += at(j) * z(j);
    }
    for (int k = 0; k < Units; ++k) g += at(oa + k) * sig[static_cast<std::size_t>(k)];
    return g;
  }

  template <class Z>
  double evaluate_gradient(std::span<const double> theta, Z&& z, std::span<double> g_theta, std::span<double> g_x) const {
    // The operations of `evaluate` on double in the same order (g bitwise operator()'s, for
    // both twins), plus the derivatives; σ' = σ(1 − σ).
    const int m = M != Dynamic ? M : m_;
    const int units = Units != Dynamic ? Units : units_;
    const auto at = [&theta](int i) { return theta[static_cast<std::size_t>(i)]; };
    const auto gt = [&g_theta](int i) -> double& { return g_theta[static_cast<std::size_t>(i)]; };
    const auto gx = [&g_x](int j) -> double& { return g_x[static_cast<std::size_t>(j)]; };
    const int od = LinearTerm ? m : 0, oa = od + 1, ob = oa + units, oc = ob + units * m;
    double g = at(od);
    gt(od) = 1.0;
    for (int j = m - 1; j >= 0; --j) {
      if constexpr (LinearTerm) {
        g += at(j) * z(j);
        gt(j) = z(j);
        gx(j) = at(j);
      } else {
        gx(j) = 0.0;
      }
    }
    for (int k = 0; k < units; ++k) {
      double s = at(oc + k);
      for (int j = m - 1; j >= 0; --j) s += at(ob + k * m + j) * z(j);
      const double sig = detail::logistic(s);
      g += at(oa + k) * sig;
      const double w = at(oa + k) * (sig * (1.0 - sig));
      gt(oa + k) = sig;
      gt(oc + k) = w;
      for (int j = 0; j < m; ++j) {
        gt(ob + k * m + j) = w * z(j);
        gx(j) += w * at(ob + k * m + j);
      }
    }
    for (int j = 0; j < m; ++j) gx(j) *= norm_.inv_scale(j);
    return g;
  }

  void solve_linear(const Eigen::MatrixXd& Z, const Eigen::VectorXd& y, std::span<double> theta) const {
    const int nl = LinearTerm ? m_ : 0;
    Eigen::MatrixXd A(Z.rows(), nl + 1 + units_);
    if constexpr (LinearTerm) A.leftCols(m_) = Z;
    A.col(nl).setOnes();
    for (int k = 0; k < units_; ++k) {
      Eigen::VectorXd b(m_);
      for (int j = 0; j < m_; ++j) b(j) = theta[static_cast<std::size_t>(offset_b() + k * m_ + j)];
      const double c = theta[static_cast<std::size_t>(off_c() + k)];
      const Eigen::VectorXd s = Z * b;
      for (Eigen::Index i = 0; i < Z.rows(); ++i) A(i, nl + 1 + k) = detail::logistic(s(i) + c);
    }
    const Eigen::VectorXd w = detail::least_squares(A, y);
    for (int i = 0; i < nl + 1 + units_; ++i) theta[static_cast<std::size_t>(i)] = w(i);
  }

  int m_ = M;
  int units_ = Units;
  detail::Standardizer<M> norm_;
};

}  // namespace nlid
