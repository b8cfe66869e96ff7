#pragma once
/// @file
/// Multi-start Levenberg–Marquardt: many deterministic initial guesses, run in parallel.
///
/// Why. Simulation-error criteria of nonlinear models are non-convex; a local method started in
/// the wrong basin stops at a poor local minimum, and finding a good start by trial and error is
/// exactly what the throttle study had to do. Multi-start replaces the trial and error by a
/// systematic search (Rinnooy Kan & Timmer, Math. Programming 39, 1987: "multi-level single
/// linkage" in its simplest form; Ugray et al., INFORMS J. Computing 19(3), 2007 ("OQNLP") for
/// the screen-then-refine pattern used here):
///
///  1. Candidates. θ⁽⁰⁾ is the caller's guess; θ⁽¹⁾ … θ⁽ᴹ⁻¹⁾ fill the search box
///     [range_lower, range_upper] with a low-discrepancy sequence. Positive scale parameters
///     (stiffnesses, time constants) are spaced logarithmically: θ = lo·(hi/lo)^z, so each decade
///     gets the same number of points. Parameters that are fixed or have no finite range keep
///     their value in every candidate. An optional `prepare` hook adjusts each candidate (e.g.
///     re-guesses initial states that depend on the physical parameters).
///  2. Screening. The cost F(θ) of every candidate is evaluated (cheap: no Jacobian) — the
///     solver's own criterion (`lm_cost`: robust loss and regularization of `lm` included), so
///     the ranking agrees with the final costs; candidates that cannot be evaluated are dropped.
///  3. Refinement. Levenberg–Marquardt runs from the `num_starts` best candidates (θ⁽⁰⁾ always
///     among them when `include_initial` and it could be evaluated), in parallel on
///     `num_threads` threads.
///  4. The lowest final cost wins; ties go to the earlier candidate, so the result does not
///     depend on the thread count or on scheduling.
///
/// The summary says how trustworthy the optimum is: how many starts ended within
/// `cost_tolerance` (default 1 %) of the best cost. Several independent starts agreeing is the
/// practical evidence of a global optimum; a best found by a single start deserves more starts.
///
/// Sequences. Halton (radical inverse in the first d primes; Halton, Numer. Math. 2, 1960) for
/// up to 12 dimensions, where it is excellent; beyond that the Kronecker/R_d sequence
/// z_i = frac(½ + i·α), α_j = φ_d^{−j}, φ_d the real root of x^{d+1} = x + 1 (Roberts 2018,
/// "The unreasonable effectiveness of quasirandom sequences"), which does not degrade with d
/// the way Halton's large prime bases do. Both are deterministic: the same call gives the same
/// candidates, results are reproducible.
///
/// Threads. The problem's `evaluate` must be safe to call concurrently on one const object (it
/// is for `GreyBoxProblem`, and for `AutoDiffProblem`, `NumericDiffProblem` and `StackedProblem`
/// of thread-safe parts, whose scratch buffers are per thread; a user problem with mutable
/// buffers is not — use `num_threads = 1` for such problems). The LM callback, if set, is
/// called from several threads.

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <functional>
#include <limits>
#include <mutex>
#include <numeric>
#include <string>
#include <thread>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/estimation/concepts.hpp"
#include "nlid/estimation/levenberg_marquardt.hpp"

namespace nlid {

/// Thrown by `multi_start` when neither the initial guess nor any candidate can be evaluated, as
/// opposed to a refused option: a caller that knows the model can then say where it fails.
class UnevaluableStartsError : public Error {
 public:
  using Error::Error;
};

/// Low-discrepancy sequence used to spread the candidates.
enum class StartSequence {
  automatic,  ///< Halton up to 12 sampled dimensions, Kronecker beyond
  halton,     ///< Halton sequence (first d primes)
  kronecker,  ///< Kronecker / R_d sequence
};

struct StartResult;

/// Settings of `multi_start`.
struct MultiStartOptions {
  int num_starts = 8;        ///< Levenberg–Marquardt runs (from the best screened candidates), ≥ 1
  int num_candidates = 64;   ///< candidates screened by cost (raised to num_starts if smaller)
  int num_threads = 0;       ///< worker threads, ≥ 0; 0 = std::thread::hardware_concurrency()
  double cost_tolerance = 0.01;  ///< relative band that counts as "reached the best cost"
  /// The caller's θ (then all finite) is candidate 0 and refined whenever it can be evaluated.
  bool include_initial = true;
  /// Search box per parameter; empty = LmOptions bounds. Non-finite ends: not sampled.
  Eigen::VectorXd range_lower, range_upper;
  /// Per parameter: space samples logarithmically (needs range_lower > 0). Empty = none.
  std::vector<bool> log_scale;
  StartSequence sequence = StartSequence::automatic;  ///< candidate sequence
  /// Options of every Levenberg–Marquardt run (bounds and fixed flags apply to sampling too).
  LmOptions lm;
  /// Called on every candidate after sampling and before screening (may adjust unsampled
  /// entries, e.g. initial states that depend on the sampled parameters). Must be thread-safe.
  std::function<void(Eigen::VectorXd&)> prepare;
  /// Called when a start's refinement has ended (converged, stopped or failed), with how many
  /// of the `total` starts have ended so far: progress for a caller's user. Calls come one at a
  /// time (under a lock) but, with several threads, from the workers and in completion order.
  std::function<void(const StartResult&, int done, int total)> start_done;
};

/// One refined start.
struct StartResult {
  int candidate = -1;        ///< index in the candidate sequence (0 = caller's guess)
  Eigen::VectorXd start;     ///< θ the run started from
  Eigen::VectorXd theta;     ///< θ it ended at
  double start_cost = std::numeric_limits<double>::infinity();  ///< F at the start
  double cost = std::numeric_limits<double>::infinity();        ///< F at the end (∞ if it failed)
  LmSummary summary;         ///< the run's summary
  std::string error;         ///< message if the run threw (then cost = ∞)
};

/// Outcome of `multi_start`.
struct MultiStartSummary {
  std::vector<StartResult> starts;   ///< refined starts, in candidate order
  int best = -1;                     ///< index into `starts` of the lowest final cost
  double best_cost = std::numeric_limits<double>::infinity();  ///< that cost
  int num_within_tolerance = 0;      ///< starts with cost ≤ best·(1 + cost_tolerance)
  int num_converged = 0;             ///< starts whose LM summary reports convergence
  int num_candidates = 0;            ///< candidates generated
  int num_evaluable = 0;             ///< candidates with a finite cost
  int num_sampled_parameters = 0;    ///< dimensions of the search
  int threads = 1;                   ///< worker threads used
  double cost_tolerance = 0.01;      ///< the band used for `num_within_tolerance`
  double seconds = 0.0;              ///< wall-clock time
  std::string sequence;              ///< "halton" or "kronecker"

  /// The winning start (throws `nlid::Error` if every start failed).
  [[nodiscard]] const StartResult& best_start() const {
    require(best >= 0, "multi-start: no start succeeded");
    return starts[static_cast<std::size_t>(best)];
  }
  /// Human-readable table: one line per start, the best marked, and the agreement count.
  [[nodiscard]] std::string report() const {
    auto num = [](double v) { return detail::format_g(v); };
    std::string s = "Multi-start: " + std::to_string(starts.size()) +
                    " Levenberg-Marquardt run(s) from the best of " + std::to_string(num_candidates) +
                    " candidates (" + sequence + ", " + std::to_string(num_sampled_parameters) +
                    " sampled parameter(s), " + std::to_string(num_evaluable) + " evaluable), " +
                    std::to_string(threads) + " thread(s), " + num(seconds) + " s\n";
    s += "  best cost " + num(best_cost) + "; " + std::to_string(num_within_tolerance) + " of " +
         std::to_string(starts.size()) + " starts within " + num(100.0 * cost_tolerance) +
         " % of it; " + std::to_string(num_converged) + " converged\n";
    s += "  candidate    start cost    final cost  iterations  status\n";
    for (std::size_t i = 0; i < starts.size(); ++i) {
      const StartResult& r = starts[i];
      s += "  " + detail::right_aligned(std::to_string(r.candidate), 9) + "  " +
           detail::right_aligned(detail::format_g(r.start_cost, 6), 12) + "  " +
           detail::right_aligned(detail::format_g(r.cost, 6), 12) + "  " +
           detail::right_aligned(std::to_string(r.summary.iterations), 10) + "  " +
           (r.error.empty() ? std::string(to_string(r.summary.status)) : std::string("failed")) +
           (static_cast<int>(i) == best ? "  <- best" : "") + "\n";
      if (!r.error.empty()) s += "             " + r.error + "\n";
    }
    return s;
  }
};

/// The first 12 primes: Halton bases.
inline constexpr int halton_primes[12] = {2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37};

/// Radical inverse of `i` in base `b`: the digits of i mirrored about the radix point.
inline double radical_inverse(unsigned long long i, int b) {
  double inv = 1.0 / b, f = inv, r = 0.0;
  while (i > 0) {
    r += f * static_cast<double>(i % static_cast<unsigned long long>(b));
    i /= static_cast<unsigned long long>(b);
    f *= inv;
  }
  return r;
}

/// Point `i` (i ≥ 1) of a d-dimensional low-discrepancy sequence in [0, 1)^d.
inline Eigen::VectorXd low_discrepancy_point(unsigned long long i, int d, StartSequence seq) {
  Eigen::VectorXd z(d);
  if (seq == StartSequence::automatic) seq = d <= 12 ? StartSequence::halton : StartSequence::kronecker;
  if (seq == StartSequence::halton) {
    if (d > 12) throw Error("Halton sequence supports at most 12 dimensions; use kronecker");
    for (int j = 0; j < d; ++j) z[j] = radical_inverse(i, halton_primes[j]);
    return z;
  }
  // φ_d: root of x^{d+1} = x + 1 by fixed-point iteration x ← (1 + x)^{1/(d+1)} (contracting).
  double phi = 2.0;
  for (int it = 0; it < 60; ++it) phi = std::pow(1.0 + phi, 1.0 / (d + 1));
  double a = 1.0;
  for (int j = 0; j < d; ++j) {
    a /= phi;
    const double v = 0.5 + static_cast<double>(i) * a;
    z[j] = v - std::floor(v);
  }
  return z;
}

namespace detail {

// Runs fn(task) for task = 0..n−1 on `threads` workers; rethrows the first exception.
template <class Fn>
void parallel_for(int n, int threads, Fn&& fn) {
  if (threads <= 1 || n <= 1) {
    for (int t = 0; t < n; ++t) fn(t);
    return;
  }
  std::atomic<int> next{0};
  std::exception_ptr error;
  std::mutex error_mutex;
  auto worker = [&] {
    for (;;) {
      const int t = next.fetch_add(1);
      if (t >= n) return;
      try {
        fn(t);
      } catch (...) {
        std::lock_guard<std::mutex> lock(error_mutex);
        if (!error) error = std::current_exception();
      }
    }
  };
  std::vector<std::thread> pool;
  for (int w = 0; w < std::min(threads, n); ++w) pool.emplace_back(worker);
  for (auto& th : pool) th.join();
  if (error) std::rethrow_exception(error);
}

inline int resolve_threads(int requested) {
  if (requested > 0) return requested;
  const unsigned hc = std::thread::hardware_concurrency();
  return hc == 0 ? 1 : static_cast<int>(hc);
}

}  // namespace detail

/// Multi-start Levenberg–Marquardt from `theta` (which receives the best result); see the file
/// comment. Throws `nlid::Error` for invalid options, `options.lm` included (naming them, before
/// any candidate is evaluated), a non-finite entry of `theta` when it is candidate 0, or if no
/// candidate can be evaluated at all.
template <LeastSquaresProblem P>
MultiStartSummary multi_start(const P& problem, Eigen::Matrix<double, P::num_params, 1>& theta,
                              const MultiStartOptions& options = {}) {
  using Vec = Eigen::Matrix<double, P::num_params, 1>;
  const auto t0 = std::chrono::steady_clock::now();
  const int n = problem.num_parameters();
  const MultiStartOptions& o = options;
  require(theta.size() == n, "multi-start: theta has " + std::to_string(theta.size()) +
                                 " entries, the problem has " + std::to_string(n),
          at_parameter("theta"));
  require(o.num_starts >= 1, "multi-start: num_starts must be >= 1", at_parameter("num_starts"));
  require(o.cost_tolerance >= 0.0, "multi-start: cost_tolerance must be >= 0",
          at_parameter("cost_tolerance"));
  require(o.num_threads >= 0,
          "multi-start: num_threads must be >= 0 (0: one per hardware thread), got " + std::to_string(o.num_threads),
          at_parameter("num_threads"));
  // The solver's options first: the sampling below indexes their bounds and fixed flags, and a
  // bad option would otherwise surface only as every run's failure, after the whole screening.
  LevenbergMarquardt<P>(o.lm).setup(problem);
  if (o.include_initial) {
    for (int k = 0; k < n; ++k) {
      const std::string name = o.lm.parameter_names.empty() ? "theta[" + std::to_string(k) + "]"
                                                             : o.lm.parameter_names[static_cast<std::size_t>(k)];
      require(std::isfinite(theta[k]),
              "multi-start: the initial value of parameter '" + name + "' is not finite (" +
                  detail::format_g(theta[k]) + "); it is candidate 0 (include_initial)",
              at_parameter(name));
    }
  }
  auto check_size = [n](const Eigen::VectorXd& v, const char* what) {
    require(v.size() == 0 || v.size() == n,
            std::string("multi-start: ") + what + " must be empty or have " + std::to_string(n) +
                " entries",
            at_parameter(what));
  };
  check_size(o.range_lower, "range_lower");
  check_size(o.range_upper, "range_upper");
  require(o.log_scale.empty() || static_cast<int>(o.log_scale.size()) == n,
          "multi-start: log_scale must be empty or have " + std::to_string(n) + " entries",
          at_parameter("log_scale"));
  const double inf = std::numeric_limits<double>::infinity();
  auto at = [](const Eigen::VectorXd& v, int k, double dflt) { return v.size() > 0 ? v[k] : dflt; };

  // Sampled dimensions: free, with a finite box.
  std::vector<int> dims;
  Eigen::VectorXd lo(n), hi(n);
  for (int k = 0; k < n; ++k) {
    const bool fixed = !o.lm.fixed.empty() && o.lm.fixed[static_cast<std::size_t>(k)];
    const double bl = at(o.lm.lower_bounds, k, -inf), bu = at(o.lm.upper_bounds, k, inf);
    lo[k] = std::max(at(o.range_lower, k, bl), bl);
    hi[k] = std::min(at(o.range_upper, k, bu), bu);
    if (fixed || !std::isfinite(lo[k]) || !std::isfinite(hi[k]) || !(hi[k] > lo[k])) continue;
    const bool logs = !o.log_scale.empty() && o.log_scale[static_cast<std::size_t>(k)];
    require(!logs || lo[k] > 0.0,
            "multi-start: log-spaced parameter " + std::to_string(k) + " needs a positive range",
            at_parameter(o.lm.parameter_names.size() == static_cast<std::size_t>(n)
                             ? o.lm.parameter_names[static_cast<std::size_t>(k)]
                             : "theta[" + std::to_string(k) + "]"));
    dims.push_back(k);
  }
  const int d = static_cast<int>(dims.size());
  StartSequence seq = o.sequence;
  if (seq == StartSequence::automatic) seq = d <= 12 ? StartSequence::halton : StartSequence::kronecker;
  require(!(seq == StartSequence::halton && d > 12),
          "multi-start: Halton sequence supports at most 12 sampled parameters (" +
              std::to_string(d) + " given); use StartSequence::kronecker",
          at_parameter("sequence"));

  // 1. Candidates.
  const int m = d == 0 ? 1 : std::max({o.num_candidates, o.num_starts, 1});
  std::vector<Eigen::VectorXd> cand(static_cast<std::size_t>(m));
  for (int c = 0; c < m; ++c) {
    Eigen::VectorXd th = theta;
    const bool initial = o.include_initial && c == 0;
    if (!initial) {
      // Skip point 0 of the sequence (the box corner / centre) when the caller's guess is used.
      const Eigen::VectorXd z =
          low_discrepancy_point(static_cast<unsigned long long>(c + (o.include_initial ? 0 : 1)), d, seq);
      for (int j = 0; j < d; ++j) {
        const int k = dims[static_cast<std::size_t>(j)];
        const bool logs = !o.log_scale.empty() && o.log_scale[static_cast<std::size_t>(k)];
        th[k] = logs ? lo[k] * std::pow(hi[k] / lo[k], z[j]) : lo[k] + z[j] * (hi[k] - lo[k]);
      }
    }
    cand[static_cast<std::size_t>(c)] = std::move(th);
  }
  const int threads = detail::resolve_threads(o.num_threads);

  // 2. Screening.
  std::vector<double> cost(static_cast<std::size_t>(m), inf);
  detail::parallel_for(m, threads, [&](int c) {
    Eigen::VectorXd& th = cand[static_cast<std::size_t>(c)];
    const bool initial = o.include_initial && c == 0;
    if (o.prepare && !initial) o.prepare(th);
    Eigen::VectorXd r(problem.num_residuals());
    const Vec tv = th;
    if (tv.allFinite() && problem.evaluate(tv, r, nullptr) && r.allFinite()) {
      cost[static_cast<std::size_t>(c)] = lm_cost(o.lm, r, tv);
    }
  });
  MultiStartSummary sum;
  sum.num_candidates = m;
  sum.num_sampled_parameters = d;
  sum.cost_tolerance = o.cost_tolerance;
  sum.sequence = seq == StartSequence::halton ? "halton" : "kronecker";
  for (double c : cost) sum.num_evaluable += std::isfinite(c) ? 1 : 0;
  if (sum.num_evaluable == 0) {
    throw UnevaluableStartsError("multi-start: the problem cannot be evaluated at the initial guess nor at any of " +
                                 std::to_string(m) + " candidates; check the model, data and search ranges");
  }

  // 3. Refinement from the best candidates (stable order: ties keep candidate order).
  std::vector<int> order(static_cast<std::size_t>(m));
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    return cost[static_cast<std::size_t>(a)] < cost[static_cast<std::size_t>(b)];
  });
  std::vector<int> chosen;
  if (o.include_initial && std::isfinite(cost[0])) chosen.push_back(0);
  for (int c : order) {
    if (static_cast<int>(chosen.size()) >= o.num_starts) break;
    if (!std::isfinite(cost[static_cast<std::size_t>(c)])) break;
    if (std::find(chosen.begin(), chosen.end(), c) == chosen.end()) chosen.push_back(c);
  }
  std::sort(chosen.begin(), chosen.end());
  sum.starts.resize(chosen.size());
  sum.threads = std::min(threads, static_cast<int>(chosen.size()));
  std::mutex done_mutex;
  int done = 0;
  detail::parallel_for(static_cast<int>(chosen.size()), threads, [&](int s) {
    StartResult& res = sum.starts[static_cast<std::size_t>(s)];
    const int c = chosen[static_cast<std::size_t>(s)];
    res.candidate = c;
    res.start = cand[static_cast<std::size_t>(c)];
    res.start_cost = cost[static_cast<std::size_t>(c)];
    Vec th = res.start;
    try {
      LevenbergMarquardt<P> lm(o.lm);
      res.summary = lm.solve(problem, th);
      res.theta = th;
      res.cost = std::isfinite(res.summary.final_cost) ? res.summary.final_cost : inf;
    } catch (const Error& e) {
      res.theta = res.start;
      res.cost = inf;
      res.error = e.what();
    }
    if (o.start_done) {
      const std::lock_guard<std::mutex> lock(done_mutex);
      o.start_done(res, ++done, static_cast<int>(chosen.size()));
    }
  });

  // 4. Best and agreement.
  for (std::size_t s = 0; s < sum.starts.size(); ++s) {
    if (sum.starts[s].cost < sum.best_cost) {
      sum.best_cost = sum.starts[s].cost;
      sum.best = static_cast<int>(s);
    }
    if (sum.starts[s].error.empty() && sum.starts[s].summary.converged()) ++sum.num_converged;
  }
  if (sum.best >= 0) {
    for (const StartResult& r : sum.starts) {
      if (r.cost <= sum.best_cost + o.cost_tolerance * std::abs(sum.best_cost)) ++sum.num_within_tolerance;
    }
    theta = sum.starts[static_cast<std::size_t>(sum.best)].theta;
  }
  sum.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (sum.best < 0) {
    throw Error("multi-start: every Levenberg-Marquardt run failed; first error: " +
                sum.starts.front().error);
  }
  return sum;
}

}  // namespace nlid
