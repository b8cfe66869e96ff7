#pragma once
/// @file
/// Estimation of `Series` models (Hammerstein, Wiener, Wiener–Hammerstein, …) by simulation
/// error, started from the best linear approximation instead of from luck.
///
/// Criterion (Ljung 1999, sec. 7.2, eq. 7.11, simulation focus; output-error structure):
///
///     θ̂ = arg min ½ Σ_e Σ_t ρ((y_e(t) − ŷ_s(t; θ, x0_e))²),
///
/// Jacobians by forward AD through the whole free-run recursion (`AutoDiffProblem`), solved by
/// `solve_least_squares`; the same stage as `estimate` for Hammerstein–Wiener models (estimate.hpp).
///
/// Initialisation (Sjöberg, Lauwers & Schoukens, "Identification of Wiener–Hammerstein models:
/// two algorithms based on the best split of a linear model applied to the SYSID'09 benchmark
/// problem", Control Engineering Practice 20, 2012; Schoukens & Tiels, Automatica 85, 2017):
///
/// 1. Best linear approximation (BLA). For Gaussian-like inputs the BLA of a block-oriented
///    system is proportional to the product of its linear blocks (Bussgang's theorem; Pintelon &
///    Schoukens 2012, ch. 3): G_BLA = c · G₁ G₂ ⋯. It is estimated as an output-error model
///    (linear/output_error.hpp, with an offset) of orders [Σ(nb_i − 1) + 1, Σ nf_i, Σ nk_i].
/// 2. Split. The poles and zeros of G_BLA (real ones, and complex-conjugate pairs kept
///    together) are distributed over the linear blocks within their orders; every admissible
///    split is scored by a *quick fit*: the "pivot" static block (the last static block, which
///    only linear blocks follow) is replaced by a polynomial surrogate Σ_j c_j T_j(z) of the
///    standardised signal z at its input (Chebyshev T_j), and because the blocks after it are
///    linear, the output is linear in c:  y ≈ Σ_j c_j G_after[T_j(z)]  — one least-squares
///    solve per split, no iterations. The split with the smallest residual wins. (Static blocks
///    before the pivot are taken as identities during the search.)
/// 3. Static blocks. The pivot block is fitted to the surrogate's curve v = Σ c_j T_j(z) by its
///    own `initialize(x, v)` (so a PwLinear or Saturation inherits the shape the data asked
///    for); other static blocks start as identities (`initialize(x, x)`). Linear blocks before
///    the pivot are scaled to unit RMS gain on the data, so the static block sees a signal of
///    the size of u. A static block of fixed unit slope (Saturation, DeadZone) cannot take the
///    gain from there to the output's units: when the initialised model simulates more than 10
///    points of fit below the quick fit, the linear block next to the pivot (before it, else
///    after it) is rescaled by multiples of the target's slope on the pivot's input, and the
///    scale with the smallest free-run error is kept.
/// 4. Joint refinement of all θ by simulation error — first a short run for each of the
///    `candidates` best splits (the quick fit ranks splits well but not perfectly), then the
///    full run from the best of them.
///
/// With a single linear block (Hammerstein, Wiener, Hammerstein–Wiener) there is one split and
/// the procedure reduces to: BLA → linear block, quick fit → static block, joint refinement.
/// `initialize = false` skips 1–3 and refines from the model's current parameters.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <complex>
#include <functional>
#include <limits>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/QR>

#include "nlid/analysis/fit.hpp"
#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/core/initial_condition.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/estimation/levenberg_marquardt.hpp"
#include "nlid/linear/detail/least_squares.hpp"
#include "nlid/linear/polynomial.hpp"
#include "nlid/models/detail/model_common.hpp"
#include "nlid/models/estimate.hpp"
#include "nlid/models/series.hpp"

namespace nlid {

/// Options of `estimate` for `Series` models.
struct SeriesEstimateOptions {
  /// Initial condition of each experiment's simulation during estimation (default `zero`;
  /// `estimate` adds each experiment's stacked block state to the parameters; `equilibrium`
  /// starts each experiment in the steady state for its first input).
  std::optional<InitialCondition> initial_condition;
  /// Data-driven initialisation (BLA, split search, static fit); false: refine the model's
  /// current parameters.
  bool initialize = true;
  /// Levenberg–Marquardt iterations of the BLA's output-error refinement.
  int bla_iterations = 100;
  /// Degree of the polynomial surrogate of the static block in the split search (≥ 1).
  int surrogate_degree = 5;
  /// Samples of the window used to score splits (the window of the largest output variance).
  Eigen::Index split_samples = 20000;
  /// At most this many splits are scored (enumeration order is deterministic).
  int max_splits = 20000;
  /// Best-scoring splits carried into a short joint refinement (≥ 1).
  int candidates = 3;
  /// Iterations of each candidate's short refinement (0: take the best quick fit as it is).
  int candidate_iterations = 8;
  /// Solver options of the main stage (`max_iterations`, `loss`, `callback`, bounds/fixed sized
  /// to the model's parameters, tolerances).
  LmOptions solver;
  /// Receives one line per initialisation stage (BLA fit, splits scored, chosen split); empty:
  /// silent.
  std::function<void(const std::string&)> progress;
};

/// What the initialisation found (returned by `initialize_series`).
struct SeriesInitialization {
  double bla_fit_percent = std::numeric_limits<double>::quiet_NaN();  ///< simulation fit of the BLA
  int splits_scored = 0;                     ///< number of pole/zero splits scored
  double best_quick_fit_percent = std::numeric_limits<double>::quiet_NaN();  ///< best split's quick fit
  std::string chosen_split;                  ///< poles and zeros per linear block, readable
  int candidate_iterations = 0;              ///< iterations spent refining candidates
  /// One line summary.
  [[nodiscard]] std::string summary() const {
    return "BLA fit " + detail::format_g(bla_fit_percent, 4) + " %, " + std::to_string(splits_scored) +
           " split(s) scored, best quick fit " + detail::format_g(best_quick_fit_percent, 4) + " %" +
           (chosen_split.empty() ? std::string() : " (" + chosen_split + ")");
  }
};

namespace detail {

/// Samples before the input reaches the output: the delays nk of the linear blocks, summed.
template <class M>
Eigen::Index series_input_delay(const M& model) {
  return [&]<std::size_t... I>(std::index_sequence<I...>) {
    return (Eigen::Index{0} + ... + block_input_delay(model.template block<I>()));
  }(std::make_index_sequence<M::num_blocks>{});
}

/// A real root (size 1) or a complex-conjugate pair (size 2, `r` with Im > 0).
struct RootGroup {
  std::complex<double> r;
  int size = 1;
};

/// Groups roots into reals and conjugate pairs (the pair's partner is the nearest conjugate).
inline std::vector<RootGroup> group_roots(const Eigen::VectorXcd& roots) {
  std::vector<RootGroup> g;
  std::vector<bool> used(static_cast<std::size_t>(roots.size()), false);
  for (Eigen::Index i = 0; i < roots.size(); ++i) {
    if (used[static_cast<std::size_t>(i)]) continue;
    const std::complex<double> r = roots(i);
    used[static_cast<std::size_t>(i)] = true;
    if (std::abs(r.imag()) <= 1e-9 * std::max(1.0, std::abs(r))) {
      g.push_back({std::complex<double>(r.real(), 0.0), 1});
      continue;
    }
    Eigen::Index best = -1;
    double dist = std::numeric_limits<double>::infinity();
    for (Eigen::Index j = 0; j < roots.size(); ++j) {
      if (used[static_cast<std::size_t>(j)]) continue;
      const double d = std::abs(roots(j) - std::conj(r));
      if (d < dist) {
        dist = d;
        best = j;
      }
    }
    if (best >= 0) used[static_cast<std::size_t>(best)] = true;
    g.push_back({std::complex<double>(r.real(), std::abs(r.imag())), 2});
  }
  return g;
}

/// Assignments of root groups to blocks within their capacities (−1: dropped). Kept are the
/// *maximal* ones — no dropped root could still be placed — so a BLA with more roots than the
/// blocks hold (or pairs that do not fit an odd room) leaves the choice of what to drop to the
/// quick fit. A complex pair may also enter a room of one as a single real root at its modulus
/// (code −2 − b for block b): real blocks often appear as a close pair in a BLA. At most `limit`.
inline std::vector<std::vector<int>> assign_groups(const std::vector<RootGroup>& groups, const std::vector<int>& caps,
                                                   std::size_t limit) {
  std::vector<std::vector<int>> out;
  std::vector<int> a(groups.size(), -1), room = caps;
  std::function<void(std::size_t)> rec = [&](std::size_t g) {
    if (out.size() >= limit) return;
    if (g == groups.size()) {
      for (std::size_t d = 0; d < groups.size(); ++d) {
        if (a[d] != -1) continue;
        for (int r : room)
          if (r >= 1) return;  // a dropped root could still be placed (at least as a real root)
      }
      out.push_back(a);
      return;
    }
    for (std::size_t b = 0; b < caps.size(); ++b) {
      if (room[b] >= groups[g].size) {
        room[b] -= groups[g].size;
        a[g] = static_cast<int>(b);
        rec(g + 1);
        room[b] += groups[g].size;
      } else if (groups[g].size == 2 && room[b] == 1) {
        room[b] -= 1;
        a[g] = -2 - static_cast<int>(b);
        rec(g + 1);
        room[b] += 1;
      }
    }
    a[g] = -1;
    rec(g + 1);
  };
  rec(0);
  return out;
}

/// Removes pole–zero pairs that (nearly) cancel: they do not shape the BLA but would take up
/// order in the split.
inline void remove_cancellations(Eigen::VectorXcd& poles, Eigen::VectorXcd& zeros, double tol = 0.01) {
  std::vector<std::complex<double>> p(poles.data(), poles.data() + poles.size()), z(zeros.data(), zeros.data() + zeros.size());
  for (std::size_t i = 0; i < p.size();) {
    std::size_t best = z.size();
    double d = tol;
    for (std::size_t j = 0; j < z.size(); ++j) {
      const double dj = std::abs(p[i] - z[j]) / std::max(1.0, std::abs(p[i]));
      if (dj < d) {
        d = dj;
        best = j;
      }
    }
    if (best < z.size()) {
      p.erase(p.begin() + static_cast<std::ptrdiff_t>(i));
      z.erase(z.begin() + static_cast<std::ptrdiff_t>(best));
    } else {
      ++i;
    }
  }
  poles = Eigen::Map<Eigen::VectorXcd>(p.data(), static_cast<Eigen::Index>(p.size()));
  zeros = Eigen::Map<Eigen::VectorXcd>(z.data(), static_cast<Eigen::Index>(z.size()));
}

/// Monic polynomial (descending powers of z = ascending powers of q⁻¹) of the groups assigned to
/// `block`, padded with zeros (roots at the origin) to `length` coefficients.
inline Eigen::VectorXd polynomial_of(const std::vector<RootGroup>& groups, const std::vector<int>& assign, int block,
                                     Eigen::Index length) {
  std::vector<std::complex<double>> r;
  for (std::size_t g = 0; g < groups.size(); ++g) {
    if (assign[g] == -2 - block) {
      r.push_back(std::abs(groups[g].r) * (groups[g].r.real() < 0 ? -1.0 : 1.0));
      continue;
    }
    if (assign[g] != block) continue;
    r.push_back(groups[g].r);
    if (groups[g].size == 2) r.push_back(std::conj(groups[g].r));
  }
  const Eigen::VectorXd p =
      poly_from_roots(Eigen::Map<const Eigen::VectorXcd>(r.data(), static_cast<Eigen::Index>(r.size())));
  Eigen::VectorXd out = Eigen::VectorXd::Zero(length);
  out.head(std::min(length, p.size())) = p.head(std::min(length, p.size()));
  return out;
}

/// Readable roots of a block, e.g. "0.9±0.2i, 0.5".
inline std::string describe_groups(const std::vector<RootGroup>& groups, const std::vector<int>& assign, int block) {
  std::string s;
  for (std::size_t g = 0; g < groups.size(); ++g) {
    if (assign[g] == -2 - block) {
      s += (s.empty() ? "" : ", ") + detail::format_g(std::abs(groups[g].r), 4) + " (from pair)";
      continue;
    }
    if (assign[g] != block) continue;
    if (!s.empty()) s += ", ";
    s += detail::format_g(groups[g].r.real(), 4);
    if (groups[g].size == 2) s += "±" + detail::format_g(groups[g].r.imag(), 4) + "i";
  }
  return s.empty() ? "none" : s;
}

/// x(t) = B(q)/F(q) w(t − nk) from rest for toolbox-form B̃ (with nk leading zeros) and monic F.
inline Eigen::VectorXd filter_rest(const Eigen::VectorXd& b, const Eigen::VectorXd& f, const Eigen::VectorXd& w) {
  return filter(b, f, w);
}

/// RMS of a vector (0 for an empty one).
inline double series_rms(const Eigen::VectorXd& v) { return v.size() ? std::sqrt(v.squaredNorm() / double(v.size())) : 0.0; }

/// Chebyshev basis T_0 … T_D of z (columns).
inline Eigen::MatrixXd chebyshev_basis(const Eigen::VectorXd& z, int degree) {
  Eigen::MatrixXd t(z.size(), degree + 1);
  t.col(0).setOnes();
  if (degree >= 1) t.col(1) = z;
  for (int j = 2; j <= degree; ++j) t.col(j) = 2.0 * z.cwiseProduct(t.col(j - 1)) - t.col(j - 2);
  return t;
}

/// Standardisation z = (x − μ)/σ of the pivot's input, shared by scoring and initialisation.
struct SeriesStandardizer {
  double mu = 0.0, sigma = 1.0;
  [[nodiscard]] Eigen::VectorXd operator()(const Eigen::VectorXd& x) const {
    return ((x.array() - mu) / sigma).matrix();
  }
};

/// A best linear approximation B/F (toolbox form: B̃ with nk leading zeros, monic F) + offset.
struct Bla {
  Eigen::VectorXd b, f;
  double offset = 0.0;
};

/// Welch-averaged H1 frequency response Ŝ_yu/Ŝ_uu of the mean-removed data at ω_k = 2πk/L,
/// k = 1 … L/2 − 1 (Hann window, 50 % overlap; Pintelon & Schoukens 2012, sec. 2.6), and the
/// input power Ŝ_uu used as the fit weight (so unexcited bands do not count).
inline void welch_frf(const Dataset& data, int len, std::vector<std::complex<double>>& h, std::vector<double>& suu) {
  const int nfreq = len / 2 - 1;
  std::vector<std::complex<double>> syu(static_cast<std::size_t>(nfreq));
  suu.assign(static_cast<std::size_t>(nfreq), 0.0);
  std::vector<std::complex<double>> tw(static_cast<std::size_t>(len));
  std::vector<double> win(static_cast<std::size_t>(len));
  const double pi = 3.14159265358979323846;
  for (int n = 0; n < len; ++n) {
    tw[static_cast<std::size_t>(n)] = std::polar(1.0, -2.0 * pi * n / len);
    win[static_cast<std::size_t>(n)] = 0.5 - 0.5 * std::cos(2.0 * pi * n / len);
  }
  std::vector<double> us(static_cast<std::size_t>(len)), ys(static_cast<std::size_t>(len));
  for (std::size_t e = 0; e < data.size(); ++e) {
    const Eigen::VectorXd u = data[e].u().col(0).array() - data[e].u().col(0).mean();
    const Eigen::VectorXd y = data[e].y().col(0).array() - data[e].y().col(0).mean();
    for (Eigen::Index s = 0; s + len <= u.size(); s += len / 2) {
      for (int n = 0; n < len; ++n) {
        us[static_cast<std::size_t>(n)] = win[static_cast<std::size_t>(n)] * u(s + n);
        ys[static_cast<std::size_t>(n)] = win[static_cast<std::size_t>(n)] * y(s + n);
      }
      for (int k = 1; k <= nfreq; ++k) {
        std::complex<double> uk, yk;
        int idx = 0;
        for (int n = 0; n < len; ++n) {
          const std::complex<double>& c = tw[static_cast<std::size_t>(idx)];
          uk += us[static_cast<std::size_t>(n)] * c;
          yk += ys[static_cast<std::size_t>(n)] * c;
          idx += k;
          if (idx >= len) idx -= len;
        }
        syu[static_cast<std::size_t>(k - 1)] += yk * std::conj(uk);
        suu[static_cast<std::size_t>(k - 1)] += std::norm(uk);
      }
    }
  }
  h.resize(static_cast<std::size_t>(nfreq));
  for (int k = 0; k < nfreq; ++k) {
    const auto ks = static_cast<std::size_t>(k);
    h[ks] = suu[ks] > 0 ? syu[ks] / suu[ks] : std::complex<double>(0.0, 0.0);
  }
}

/// Rational fit B(z)/F(z) ≈ H(e^{iω}) by Sanathanan–Koerner iterations (IEEE TAC 8, 1963):
/// each step solves the linear least-squares problem Σ w_k |B(z_k) − H_k F(z_k)|² / |F_prev(z_k)|²;
/// an unstable F is reflected into the unit disc.
inline void sk_fit(const std::vector<std::complex<double>>& h, const std::vector<double>& w, int len, int nb, int nf,
                   int nk, Eigen::VectorXd& b, Eigen::VectorXd& f, int iterations = 25) {
  const auto nfreq = static_cast<Eigen::Index>(h.size());
  const double pi = 3.14159265358979323846;
  const double wmax = *std::max_element(w.begin(), w.end());
  f = Eigen::VectorXd::Zero(nf + 1);
  f(0) = 1.0;
  b = Eigen::VectorXd::Zero(nb);
  Eigen::MatrixXd a(2 * nfreq, nb + nf);
  Eigen::VectorXd rhs(2 * nfreq);
  for (int it = 0; it < iterations; ++it) {
    for (Eigen::Index k = 0; k < nfreq; ++k) {
      const std::complex<double> zi = std::polar(1.0, -2.0 * pi * double(k + 1) / len);  // z⁻¹
      std::complex<double> fk = 0.0, zp = 1.0;
      for (int j = 0; j <= nf; ++j, zp *= zi) fk += f(j) * zp;
      const double wk = wmax > 0 ? std::sqrt(w[static_cast<std::size_t>(k)] / wmax) / std::max(std::abs(fk), 1e-12) : 1.0;
      const std::complex<double> hk = h[static_cast<std::size_t>(k)];
      std::complex<double> zb = std::pow(zi, nk);
      for (int j = 0; j < nb; ++j, zb *= zi) {
        a(2 * k, j) = wk * zb.real();
        a(2 * k + 1, j) = wk * zb.imag();
      }
      std::complex<double> zf = zi;
      for (int j = 1; j <= nf; ++j, zf *= zi) {
        const std::complex<double> v = -hk * zf;
        a(2 * k, nb + j - 1) = wk * v.real();
        a(2 * k + 1, nb + j - 1) = wk * v.imag();
      }
      rhs(2 * k) = wk * hk.real();
      rhs(2 * k + 1) = wk * hk.imag();
    }
    // B's columns are unitless, F's carry H's units (y/u): equilibrated, as in arx_initialize.
    const Eigen::VectorXd sol = solve_equilibrated(a, rhs);
    if (!sol.allFinite()) break;
    b = sol.head(nb);
    f.tail(nf) = sol.tail(nf);
    if (nf > 0 && !is_stable_polynomial(f)) f = reflect_unstable(f);
  }
}

/// BLA of orders [nb nf nk] with an output offset: frequency-domain start (Welch H1 + SK), then
/// output-error refinement in the time domain (simulation error, the block started in steady
/// state). Robust where time-domain OE iterations from Steiglitz–McBride stall in pole–zero
/// cancellations (seen on lightly damped, oversampled systems such as the WH benchmark).
inline Bla best_linear_approximation(const Dataset& data, int nb, int nf, int nk, int iterations) {
  Eigen::Index nmax = 0;
  for (std::size_t e = 0; e < data.size(); ++e) nmax = std::max(nmax, data[e].size());
  int len = 16;
  while (len * 2 <= 1024 && len * 2 * 4 <= nmax) len *= 2;
  std::vector<std::complex<double>> h;
  std::vector<double> suu;
  welch_frf(data, len, h, suu);
  Eigen::VectorXd b, f;
  sk_fit(h, suu, len, nb, nf, nk, b, f);
  // Time-domain output-error refinement with an offset.
  using Tf = TransferFunctionBlock<Dynamic, Dynamic, Dynamic>;
  const Tf block(nb, nf, nk);
  std::vector<Eigen::VectorXd> w(data.size()), y(data.size());
  double usum = 0.0, ysum = 0.0;
  Eigen::VectorXd y_all(data.total_samples());
  Eigen::Index q = 0;
  for (std::size_t e = 0; e < data.size(); ++e) {
    w[e] = data[e].u().col(0);
    y[e] = data[e].y().col(0);
    usum += w[e].sum();
    ysum += y[e].sum();
    y_all.segment(q, y[e].size()) = y[e];
    q += y[e].size();
  }
  const double n = static_cast<double>(data.total_samples());
  Eigen::VectorXd th(nb + nf + 1);
  th.head(nb) = b;
  th.segment(nb, nf) = f.tail(nf);
  const double gain = std::abs(f.sum()) > 1e-12 ? b.sum() / f.sum() : 0.0;
  th(nb + nf) = ysum / n - gain * usum / n;
  if (iterations > 0) {
    LinearStageResiduals<Tf> r(block, w, y, divergence_limit(y_all));
    Eigen::VectorXd res(r.num_residuals());
    if (r.residuals(as_const_span(th), as_span(res))) {
      LmOptions o;
      o.max_iterations = iterations;
      solve_functor<Dynamic>(std::move(r), th, o);
    }
  }
  Bla out;
  out.b = Eigen::VectorXd::Zero(nk + nb);
  out.b.tail(nb) = th.head(nb);
  out.f = Eigen::VectorXd(nf + 1);
  out.f << 1.0, th.segment(nb, nf);
  out.offset = th(nb + nf);
  return out;
}

}  // namespace detail

/// Initialises `model` from `data` (steps 1–3 of the file comment); θ, sample time and channel
/// names are set. Returns what was found. Throws `nlid::Error` naming the experiment for data
/// that do not fit the model.
template <SeriesBlock... B>
SeriesInitialization initialize_series(Series<B...>& model, const Dataset& data, const SeriesEstimateOptions& options = {}) {
  using M = Series<B...>;
  constexpr std::size_t K = M::num_blocks;
  detail::adopt_data(model, data, 0, M::kind().c_str());
  // As estimate() counts them: parameters held by solver.fixed are not estimated (docs/models.md).
  detail::require_enough_samples(M::kind(),
                                 model.num_parameters() - detail::count_fixed(options.solver.fixed, model.num_parameters()),
                                 data, 0);
  detail::require_input_reaches_output(M::kind(), detail::series_input_delay(model), data);
  require(options.surrogate_degree >= 1, "surrogate_degree must be >= 1", at_parameter("surrogate_degree"));
  require(options.candidates >= 1, "candidates must be >= 1", at_parameter("candidates"));
  SeriesInitialization info;
  Eigen::VectorXd theta = model.parameters();
  const std::string pat = M::pattern();

  // Block bookkeeping (run time): linear block indices, orders, pivot static block.
  std::vector<std::size_t> lin_idx;
  for (std::size_t k = 0; k < K; ++k)
    if (pat[k] == 'L') lin_idx.push_back(k);
  long pivot = -1;
  for (std::size_t k = 0; k < K; ++k)
    if (pat[k] == 'N') pivot = static_cast<long>(k);
  std::vector<int> nb(K, 0), nf(K, 0), nk(K, 0);
  bool orders_known = true;
  [&]<std::size_t... I>(std::index_sequence<I...>) {
    (
        [&] {
          if constexpr (M::template is_linear<I>) {
            const auto& b = model.template block<I>();
            if constexpr (requires { b.nb(); b.nf(); b.nk(); }) {
              nb[I] = b.nb();
              nf[I] = b.nf();
              nk[I] = b.nk();
            } else {
              orders_known = false;
            }
          }
        }(),
        ...);
  }(std::make_index_sequence<K>{});

  // The scoring window: the stretch of the data with the largest output variance.
  std::size_t we = 0;
  Eigen::Index ws = 0, wl = 0;
  {
    double best = -1.0;
    for (std::size_t e = 0; e < data.size(); ++e) {
      const Eigen::Index n = data[e].size();
      const Eigen::Index len = std::min(n, options.split_samples);
      const Eigen::Index step = std::max<Eigen::Index>(1, len / 2);
      for (Eigen::Index s = 0; s + len <= n; s += step) {
        const Eigen::VectorXd y = data[e].y().col(0).segment(s, len);
        const double v = (y.array() - y.mean()).square().mean();
        if (v > best) {
          best = v;
          we = e;
          ws = s;
          wl = len;
        }
        if (s + len == n) break;
        if (s + step + len > n) s = n - len - step;
      }
    }
  }
  const Eigen::VectorXd uw = data[we].u().col(0).segment(ws, wl);
  const Eigen::VectorXd yw = data[we].y().col(0).segment(ws, wl);
  const Eigen::Index skip = std::min<Eigen::Index>(wl / 10, 200);

  // Per-split linear polynomials (toolbox form) for every linear block.
  struct Split {
    std::vector<Eigen::VectorXd> b, f;  // indexed by block k (empty for static blocks)
    std::string text;
    double score = std::numeric_limits<double>::infinity();
    Eigen::VectorXd c;
    detail::SeriesStandardizer zs;
  };
  std::vector<Split> splits;

  if (!lin_idx.empty() && orders_known) {
    // 1. BLA.
    int nbt = 1, nft = 0, nkt = 0;
    for (std::size_t k : lin_idx) {
      nbt += nb[k] - 1;
      nft += nf[k];
      nkt += nk[k];
    }
    const detail::Bla bla = detail::best_linear_approximation(data, nbt, nft, nkt, options.bla_iterations);
    {
      const Eigen::VectorXd ys = detail::filter_rest(bla.b, bla.f, uw).array() + bla.offset;
      info.bla_fit_percent = fit_percent(Eigen::VectorXd(yw.tail(wl - skip)), Eigen::VectorXd(ys.tail(wl - skip)));
    }
    if (options.progress)
      options.progress("initialisation: best linear approximation [nb nf nk] = [" + std::to_string(nbt) + " " +
                       std::to_string(nft) + " " + std::to_string(nkt) + "], fit " +
                       detail::format_g(info.bla_fit_percent, 4) + " %");
    Eigen::VectorXcd bla_poles = nft > 0 ? roots(bla.f) : Eigen::VectorXcd();
    Eigen::VectorXcd bla_zeros = roots(Eigen::VectorXd(bla.b.tail(nbt)));
    detail::remove_cancellations(bla_poles, bla_zeros);
    const auto pole_groups = detail::group_roots(bla_poles);
    const auto zero_groups = detail::group_roots(bla_zeros);
    std::vector<int> pcap, zcap;
    for (std::size_t k : lin_idx) {
      pcap.push_back(nf[k]);
      zcap.push_back(nb[k] - 1);
    }
    const auto limit = static_cast<std::size_t>(std::max(1, options.max_splits));
    const auto pa = detail::assign_groups(pole_groups, pcap, limit);
    const auto za = detail::assign_groups(zero_groups, zcap, limit);
    const double b_lead = bla.b(nkt);
    for (const auto& p : pa) {
      for (const auto& z : za) {
        if (splits.size() >= limit) break;
        Split s;
        s.b.resize(K);
        s.f.resize(K);
        for (std::size_t j = 0; j < lin_idx.size(); ++j) {
          const std::size_t k = lin_idx[j];
          Eigen::VectorXd bk = Eigen::VectorXd::Zero(nk[k] + nb[k]);
          bk.tail(nb[k]) = detail::polynomial_of(zero_groups, z, static_cast<int>(j), nb[k]);
          // The leading coefficient of the BLA goes to the first block; scaling is fixed below.
          if (j == 0) bk *= b_lead;
          s.b[k] = bk;
          s.f[k] = detail::polynomial_of(pole_groups, p, static_cast<int>(j), nf[k] + 1);
          if (!s.text.empty()) s.text += "; ";
          s.text += model.block_label(k) + ": poles " + detail::describe_groups(pole_groups, p, static_cast<int>(j)) +
                    ", zeros " + detail::describe_groups(zero_groups, z, static_cast<int>(j));
        }
        splits.push_back(std::move(s));
      }
    }
  }

  // 2. Quick fit of each split: linear in the surrogate coefficients.
  const int degree = pivot >= 0 ? options.surrogate_degree : 1;
  auto through = [&](const Split& s, std::size_t from, std::size_t to, Eigen::VectorXd x) {
    for (std::size_t k = from; k < to; ++k)
      if (pat[k] == 'L' && !s.b.empty() && s.b[k].size() > 0) x = detail::filter_rest(s.b[k], s.f[k], x);
    return x;
  };
  const std::size_t piv = pivot >= 0 ? static_cast<std::size_t>(pivot) : K;
  auto score = [&](Split& s) {
    // Signals at the pivot's input (static blocks before it taken as identities).
    const Eigen::VectorXd x = through(s, 0, piv, uw);
    const double mu = x.mean();
    double sigma = std::sqrt((x.array() - mu).square().mean());
    if (!(sigma > 0) || !std::isfinite(sigma)) return;
    s.zs = {mu, sigma};
    const Eigen::MatrixXd t = detail::chebyshev_basis(s.zs(x), degree);
    Eigen::MatrixXd a(wl - skip, degree + 1);
    for (int j = 0; j <= degree; ++j) {
      const Eigen::VectorXd col = piv < K ? through(s, piv + 1, K, t.col(j)) : Eigen::VectorXd(t.col(j));
      a.col(j) = col.tail(wl - skip);
    }
    if (!a.allFinite()) return;
    s.c = a.colPivHouseholderQr().solve(yw.tail(wl - skip));
    const double r = (a * s.c - yw.tail(wl - skip)).norm();
    if (std::isfinite(r)) s.score = r;
  };
  for (auto& s : splits) score(s);
  info.splits_scored = static_cast<int>(splits.size());
  std::vector<std::size_t> order(splits.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return splits[a].score < splits[b].score; });
  const Eigen::VectorXd ywt = yw.tail(wl - skip);
  const double ynorm = (ywt.array() - ywt.mean()).matrix().norm();
  if (!order.empty() && std::isfinite(splits[order[0]].score)) {
    info.best_quick_fit_percent = 100.0 * (1.0 - splits[order[0]].score / ynorm);
    info.chosen_split = splits[order[0]].text;
  }
  if (options.progress && !splits.empty())
    options.progress("initialisation: " + std::to_string(splits.size()) + " pole/zero split(s) scored, best quick fit " +
                     detail::format_g(info.best_quick_fit_percent, 4) + " %" +
                     (info.chosen_split.empty() ? std::string() : " (" + info.chosen_split + ")"));

  // 3. θ from a split: linear blocks (scaled), static blocks (pivot from the surrogate).
  // `gain` multiplies one linear block next to the pivot on top of the unit-RMS scaling: the
  // last one before it, else the first one after it. A pivot that can absorb any gain (a
  // network, a piecewise-linear map) does not need it; one with a fixed unit slope (Saturation,
  // DeadZone) does: its input must already be in the output's units (see `apply_best`).
  // Returns the least-squares slope of the pivot's target on its input (NaN when unknown).
  auto apply = [&](const Split& s, Eigen::VectorXd& th, double gain = 1.0) -> double {
    double slope = std::numeric_limits<double>::quiet_NaN();
    Split sc = s;
    // Unit RMS gain on the data for linear blocks before the pivot; the blocks after it keep
    // the scale the BLA gave (the pivot's fit absorbs whatever is left).
    Eigen::VectorXd x = uw;
    for (std::size_t k = 0; k < piv && k < K; ++k) {
      if (pat[k] != 'L' || sc.b[k].size() == 0) continue;
      const Eigen::VectorXd xn = detail::filter_rest(sc.b[k], sc.f[k], x);
      const double g = detail::series_rms(x) > 0 && detail::series_rms(xn) > 0 ? detail::series_rms(x) / detail::series_rms(xn) : 1.0;
      sc.b[k] *= g;
      x = xn * g;
    }
    for (std::size_t k = piv + 1; k < K; ++k) {
      if (pat[k] != 'L' || sc.b[k].size() == 0) continue;
      const Eigen::VectorXd xn = detail::filter_rest(sc.b[k], sc.f[k], uw);
      const double g = detail::series_rms(uw) > 0 && detail::series_rms(xn) > 0 ? detail::series_rms(uw) / detail::series_rms(xn) : 1.0;
      sc.b[k] *= g;
    }
    if (gain != 1.0 && sc.b.size() == K) {
      long at = -1;
      for (std::size_t k = 0; k < piv && k < K; ++k)
        if (pat[k] == 'L' && sc.b[k].size() > 0) at = static_cast<long>(k);
      for (std::size_t k = piv + 1; at < 0 && k < K; ++k)
        if (pat[k] == 'L' && sc.b[k].size() > 0) at = static_cast<long>(k);
      if (at >= 0) sc.b[static_cast<std::size_t>(at)] *= gain;
    }
    // Recompute the quick fit with the scaled blocks (scales change c, not the residual).
    score(sc);
    Eigen::VectorXd v_all, x_all;
    model.set_parameters(th);
    [&]<std::size_t... I>(std::index_sequence<I...>) {
      (
          [&] {
            if constexpr (M::template is_linear<I>) {
              if (sc.b.size() == K && sc.b[I].size() > 0) model.template set_block_polynomials<I>(sc.b[I], sc.f[I]);
            }
          }(),
          ...);
    }(std::make_index_sequence<K>{});
    th = model.parameters();
    // Static blocks, in chain order, on all data.
    Eigen::Index total = data.total_samples();
    std::vector<Eigen::VectorXd> sig(data.size());
    for (std::size_t e = 0; e < data.size(); ++e) sig[e] = data[e].u().col(0);
    [&]<std::size_t... I>(std::index_sequence<I...>) {
      (
          [&] {
            auto thk = std::span<double>(th.data() + model.parameter_offset(I),
                                         static_cast<std::size_t>(model.block_num_parameters(I)));
            if constexpr (M::template is_linear<I>) {
              if (sc.b.size() == K && sc.b[I].size() > 0)
                for (auto& v : sig) v = detail::filter_rest(sc.b[I], sc.f[I], v);
            } else {
              Eigen::MatrixXd xin(total, 1);
              Eigen::VectorXd target(total);
              Eigen::Index r = 0;
              for (auto& v : sig) {
                xin.col(0).segment(r, v.size()) = v;
                if (static_cast<long>(I) == pivot && sc.c.size() == degree + 1) {
                  target.segment(r, v.size()) = detail::chebyshev_basis(sc.zs(v), degree) * sc.c;
                } else {
                  target.segment(r, v.size()) = v;
                }
                r += v.size();
              }
              if (static_cast<long>(I) == pivot && sc.c.size() != degree + 1) {
                // No split information (no linear block orders): fit the output directly.
                Eigen::Index q = 0;
                for (std::size_t e = 0; e < data.size(); ++e) {
                  target.segment(q, data[e].size()) = data[e].y().col(0);
                  q += data[e].size();
                }
              }
              if (static_cast<long>(I) == pivot) {
                const double xm = xin.col(0).mean(), vm = target.mean();
                const double sxx = (xin.col(0).array() - xm).square().sum();
                const double sxv = ((xin.col(0).array() - xm) * (target.array() - vm)).sum();
                if (sxx > 0.0) slope = sxv / sxx;
              }
              model.template block<I>().initialize(xin, target, thk);
              for (auto& v : sig) {
                for (Eigen::Index t = 0; t < v.size(); ++t) {
                  const double xv = v(t);
                  v(t) = model.template block<I>()(std::span<const double>(&xv, 1), std::span<const double>(thk));
                }
              }
            }
          }(),
          ...);
    }(std::make_index_sequence<K>{});
    (void)x_all;
    (void)v_all;
    return slope;
  };

  // Sum of squared free-run errors of θ on all data from rest (∞ if the run fails).
  auto simulation_sse = [&](const Eigen::VectorXd& th) {
    double sse = 0.0;
    try {
      model.set_parameters(th);
      for (std::size_t e = 0; e < data.size(); ++e) sse += (data[e].y().col(0) - model.simulate(data[e]).col(0)).squaredNorm();
    } catch (const Error&) {
      return std::numeric_limits<double>::infinity();
    }
    return std::isfinite(sse) ? sse : std::numeric_limits<double>::infinity();
  };
  // `apply` at unit RMS scaling, unless the initialised model simulates far worse than the
  // quick fit promised: then the pivot could not take the surrogate's gain (a saturation has
  // slope 1 — fed a signal the size of u while the output is in degrees, its least-squares
  // limits collapse to one value, a constant model with no gradient to the linear blocks).
  // The gain next to the pivot is then chosen among multiples of the target's slope on the
  // pivot's input by the free-run error.
  double y_spread = 0.0;  // Σ (y − ȳ)² per record: the fit's denominator
  for (std::size_t e = 0; e < data.size(); ++e) y_spread += (data[e].y().col(0).array() - data[e].y().col(0).mean()).square().sum();
  auto apply_best = [&](const Split& s, Eigen::VectorXd& th) {
    const Eigen::VectorXd th0 = th;
    const double slope = apply(s, th);
    if (pivot < 0 || !(std::isfinite(slope) && slope != 0.0) || !std::isfinite(info.best_quick_fit_percent)) return;
    double best = simulation_sse(th);
    const double fit = y_spread > 0.0 ? 100.0 * (1.0 - std::sqrt(best / y_spread)) : 100.0;
    if (fit >= info.best_quick_fit_percent - 10.0) return;
    Eigen::VectorXd keep = th;
    for (const double m : {1.0, 0.5, 2.0, 0.25, 4.0}) {
      Eigen::VectorXd t = th0;
      (void)apply(s, t, slope * m);
      const double c = simulation_sse(t);
      if (c < best) {
        best = c;
        keep = t;
      }
    }
    th = keep;
    model.set_parameters(th);
  };

  if (splits.empty()) {
    Split none;
    apply(none, theta);  // no split: nothing to scale
    model.set_parameters(theta);
    return info;
  }

  // 4a. Short joint refinement of the best candidates.
  const std::size_t ncand = std::min<std::size_t>(static_cast<std::size_t>(options.candidates), order.size());
  Eigen::VectorXd best_theta;
  double best_cost = std::numeric_limits<double>::infinity();
  for (std::size_t c = 0; c < ncand; ++c) {
    const Split& s = splits[order[c]];
    if (!std::isfinite(s.score)) break;
    Eigen::VectorXd th = theta;
    apply_best(s, th);
    double cost = std::numeric_limits<double>::infinity();
    if (options.candidate_iterations > 0 && ncand > 1) {
      std::vector<detail::EstimationSegment> segs(data.size());
      Eigen::VectorXd y_all(data.total_samples());
      Eigen::Index q = 0;
      for (std::size_t e = 0; e < data.size(); ++e) {
        segs[e].u = &data[e].u();
        segs[e].y = data[e].y().col(0);
        y_all.segment(q, segs[e].y.size()) = segs[e].y;
        q += segs[e].y.size();
      }
      LmOptions o;
      o.max_iterations = options.candidate_iterations;
      model.set_parameters(th);
      try {
        const LmSummary sm = detail::simulation_stage(model, segs, InitialCondition::zero, th,
                                                      o, detail::divergence_limit(y_all));
        cost = sm.final_cost;
        info.candidate_iterations += sm.iterations;
      } catch (const Error&) {
        cost = std::numeric_limits<double>::infinity();
      }
      if (options.progress)
        options.progress("initialisation: candidate " + std::to_string(c + 1) + " (" + s.text + "): cost " +
                         detail::format_g(cost, 4) + " after " + std::to_string(options.candidate_iterations) +
                         " iterations");
    } else {
      cost = s.score;
    }
    if (cost < best_cost || best_theta.size() == 0) {
      best_cost = cost;
      best_theta = th;
      info.chosen_split = s.text;
    }
  }
  if (best_theta.size() == 0) {
    best_theta = theta;
    apply_best(splits[order[0]], best_theta);
  }
  model.set_parameters(best_theta);
  return info;
}

/// Estimates a `Series` model (Hammerstein, Wiener, Wiener–Hammerstein, …) on `data` by
/// simulation error, initialised as described in the file comment. Returns the model with θ,
/// sample time, channel names and `report()` (its status line names the initialisation).
/// Throws `nlid::Error` naming the experiment for data that do not fit the model, for
/// `InitialCondition::measured`, or if the initial model's simulation diverges.
template <SeriesBlock... B>
[[nodiscard]] Series<B...> estimate(Series<B...> model, const Dataset& data, const SeriesEstimateOptions& options = {}) {
  using M = Series<B...>;
  const auto t0 = std::chrono::steady_clock::now();
  detail::adopt_data(model, data, 0, M::kind().c_str());
  detail::require_enough_samples(M::kind(),
                                 model.num_parameters() - detail::count_fixed(options.solver.fixed, model.num_parameters()),
                                 data, 0);
  detail::require_input_reaches_output(M::kind(), detail::series_input_delay(model), data);
  model.set_channel_names(data[0].input_names().empty() ? "u1" : data[0].input_names()[0],
                          data[0].output_names().empty() ? "y1" : data[0].output_names()[0]);
  const InitialCondition ic = options.initial_condition.value_or(InitialCondition::zero);
  require(ic != InitialCondition::measured,
          "InitialCondition::measured is not defined for a " + M::kind() + " model; use zero, equilibrium or estimate",
          at_parameter("initial_condition"));
  SeriesInitialization info;
  if (options.initialize) info = initialize_series(model, data, options);

  std::vector<detail::EstimationSegment> segs(data.size());
  Eigen::VectorXd y_all(data.total_samples());
  {
    Eigen::Index k = 0;
    for (std::size_t i = 0; i < data.size(); ++i) {
      segs[i].u = &data[i].u();
      segs[i].y = data[i].y().col(0);
      y_all.segment(k, segs[i].y.size()) = segs[i].y;
      k += segs[i].y.size();
    }
  }
  const double limit = detail::divergence_limit(y_all);
  Eigen::VectorXd theta = model.parameters();
  for (auto& s : segs) {
    s.start = 0;
    if (ic == InitialCondition::estimate) {
      s.x0 = model.template equilibrium_state<double>((*s.u)(0, 0), detail::as_const_span(theta));
    } else {
      s.x0.resize(0);
    }
  }
  for (std::size_t i = 0; i < segs.size(); ++i) {
    Eigen::VectorXd yh;
    if (!detail::simulate_segment(model, segs[i], theta, ic, yh, limit)) {
      throw Error(M::kind() + " estimation cannot start: the initial model's simulation of " +
                      detail::experiment_label(data[i], static_cast<long>(i)) + " diverges",
                  detail::experiment_location(static_cast<long>(i)));
    }
  }
  const LmSummary summary = detail::simulation_stage(model, segs, ic, theta, options.solver, limit);
  model.set_parameters(theta);

  EstimationReport report;
  report.estimated = true;
  report.focus = "simulation";
  report.initial_condition = to_string(ic);
  report.iterations = summary.iterations + info.candidate_iterations;
  report.initial_cost = summary.initial_cost;
  report.final_cost = summary.final_cost;
  report.status = summary.message();
  if (options.initialize) report.status += "; initialisation: " + info.summary();
  for (std::size_t i = 0; i < segs.size(); ++i) {
    Eigen::VectorXd yh;
    const bool ok = detail::simulate_segment(model, segs[i], theta, ic, yh);
    report.data_names.push_back(data[i].name());
    report.fit_percent.push_back(detail::estimation_fit(segs[i].y, yh, ok));
    if (ic == InitialCondition::estimate) report.initial_states.push_back(segs[i].x0);
  }
  report.seconds = detail::seconds_since(t0);
  model.set_report(std::move(report));
  return model;
}

}  // namespace nlid
