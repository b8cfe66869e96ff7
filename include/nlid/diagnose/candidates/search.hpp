#pragma once
/// @file
/// Greedy search over the effect catalogue: screen, refit, score on validation data, add the
/// best significant effect, repeat.
///
/// One round, with current model M (fitted on the estimation data):
///
///  0. Gate. M is simulated on the validation records (x₀ fitted per record). If the residual is
///     consistent with the noise floor (significance.hpp), nothing is missing: stop.
///  1. Candidates. Every applicable catalogue effect not yet in M, one per variant (upper/lower
///     for one-sided effects), with starting values placed by the data scales of M's simulated
///     trajectory (effects.hpp). Effects that cannot apply (mechanical effects on a baseline
///     without a position/velocity pair) are listed with the reason.
///  2. Screening. Each candidate's starts are refitted briefly (`screen_iterations`
///     Levenberg–Marquardt steps on *all* parameters, from M's optimum plus the effect's start;
///     the records' initial states held at M's, so the Jacobian has the model's columns only);
///     the best start per candidate is kept. This is where the search is
///     fast: a wrong effect gains little in a few steps.
///  3. Verdict by refit. The `refine_top` candidates with the lowest estimation cost are refitted
///     to convergence (`refine_iterations`, initial states estimated again); only these can win.
///     Every candidate is then simulated on the validation records and scored (significance.hpp): noise test, relevance to the excess above the floor,
///     and the validation BIC score, which ranks the table.
///  4. Decision. The refined candidate with the best score among the significant ones joins M,
///     with all its re-estimated parameters. If none is significant, the search stops: a model
///     with nothing missing gets nothing added.
///  5. Ablation check. A refit of M + effect also moves M's own parameters, and the extra
///     dimension can lead the optimiser out of a local minimum of M: then the gain belongs to
///     a better-fitted M, not to the effect. So M alone is re-fitted from the winner's values of
///     its parameters (the control). If the control validates better than M, the winner must
///     pass the same tests against the control; if it does not, the control replaces M (an
///     improved fit of the same structure, reported in the round's `note`) and the search goes
///     on without the effect. This choice between two fits of one structure is the one place
///     where the validation records choose parameters (docs/diagnosis.md).
///  Stops (`SearchStop`): the gate, `max_effects` reached, no applicable effect left, no
///  significant candidate, or more than `max_effects` + 2 rounds ending in a re-fit.
///
/// Candidates of a round run in parallel on `threads` std::threads (each refit is independent;
/// results are placed by index, so they do not depend on scheduling).

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <thread>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/format.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/diagnose/augmented.hpp"
#include "nlid/diagnose/effects.hpp"
#include "nlid/diagnose/locate.hpp"
#include "nlid/diagnose/noise_floor.hpp"
#include "nlid/diagnose/refit.hpp"
#include "nlid/diagnose/significance.hpp"
#include "nlid/models/greybox_init.hpp"
#include "nlid/models/greybox_simulate.hpp"

namespace nlid {

/// Settings of `search_effects`.
struct SearchOptions {
  /// Effect kinds to try; empty = the whole catalogue.
  std::vector<EffectKind> kinds;
  /// Largest number of effects added.
  int max_effects = 3;
  /// Levenberg–Marquardt steps per start in the screening refit.
  int screen_iterations = 10;
  /// Steps of the converging refit of the best candidates.
  int refine_iterations = 50;
  /// Candidates refitted to convergence per round.
  int refine_top = 3;
  /// Worker threads (0 = hardware concurrency, at most 8).
  int threads = 0;
  /// `estimate` (initial states fitted per record) or `zero`.
  InitialCondition initial_condition = InitialCondition::estimate;
  /// Thresholds of the tests.
  SignificanceOptions significance;
  /// Ablation check of the winner (see the file comment); off only for experiments.
  bool ablation_check = true;
  /// Progress lines (e.g. to stderr); may be empty. Called from the calling thread only.
  std::function<void(const std::string&)> progress;
};

/// One candidate tried in one round, with its refit and scores.
struct CandidateResult {
  int round = 0;                 ///< 1-based round
  Effect effect;                 ///< the effect with its fitted parameter values
  bool ok = false;               ///< refit and validation simulation succeeded
  bool refined = false;          ///< refitted to convergence (only these can be accepted)
  std::string error;             ///< why it failed, if !ok
  Eigen::VectorXd theta;         ///< all parameters of the augmented model
  std::vector<Eigen::VectorXd> x0_est;  ///< its initial states on the estimation data
  double sse_est = std::numeric_limits<double>::infinity();  ///< estimation Σ ε²
  double sse_val = std::numeric_limits<double>::infinity();  ///< validation Σ ε²
  Eigen::VectorXd fit_est;       ///< estimation fit % per experiment
  Eigen::VectorXd fit_val;       ///< validation fit % per experiment
  CandidateStatistics stats;     ///< validation tests (significance.hpp)
  int added_params = 0;          ///< Δp
};

/// One round of the search.
struct SearchRound {
  int round = 0;                          ///< 1-based
  FloorConsistency gate;                  ///< noise-floor gate of the model entering the round
  double sse_val_before = 0.0;            ///< validation Σ ε² of that model
  Eigen::VectorXd fit_val_before;         ///< its validation fit % per experiment
  std::vector<CandidateResult> candidates;  ///< sorted by score, best first
  int accepted = -1;                      ///< index into `candidates`, −1 if none
  /// Set when the best candidate failed the ablation check (see the file comment): the current
  /// structure, re-fitted from the candidate's values, did as well, so the candidate only led
  /// the optimiser out of a local minimum. The model then continues re-fitted, without it.
  std::string note;
};

/// Why the greedy search ended (`SearchResult::stop`; `stop_reason` says it in words).
enum class SearchStop {
  noise_floor,          ///< the model's validation residual is consistent with the noise floor
  effect_limit,         ///< `max_effects` effects are in the model
  catalogue_exhausted,  ///< no applicable catalogue effect is left to try
  none_significant,     ///< no candidate passed the verdict
  repeated_refits,      ///< the ablation check kept re-fitting the model without adding an effect
};

/// "noise_floor", "effect_limit", …: the enumerator's name, as the diagnosis JSON writes it.
inline const char* search_stop_name(SearchStop s) {
  switch (s) {
    case SearchStop::noise_floor: return "noise_floor";
    case SearchStop::effect_limit: return "effect_limit";
    case SearchStop::catalogue_exhausted: return "catalogue_exhausted";
    case SearchStop::none_significant: return "none_significant";
    case SearchStop::repeated_refits: return "repeated_refits";
  }
  return "unknown";
}

/// Result of the search.
template <Physics P>
struct SearchResult {
  AugmentedModel<P> model;                 ///< final model (start + accepted effects)
  std::vector<Eigen::VectorXd> x0_est;     ///< its initial states on the estimation data
  std::vector<SearchRound> rounds;         ///< every round, in order
  std::vector<std::string> not_applicable; ///< "name: reason" for effects that cannot apply
  std::string stop_reason;                 ///< why the search ended
  SearchStop stop = SearchStop::none_significant;  ///< the same as a value
  int refits_without_effect = 0;           ///< rounds whose winner failed the ablation check
};

/// Data scales of a model's simulated trajectory on `data` from initial states `x0`
/// (effects.hpp). Never throws for a simulation that diverges; it falls back to output levels.
template <Physics P>
DataScales data_scales(const AugmentedModel<P>& model, const Dataset& data,
                       const std::vector<Eigen::VectorXd>& x0);

/// Throws `nlid::Error` naming the first of the search's effort settings below 1, with its
/// value (`SearchOptions` and `DiagnoseOptions` carry the same three).
inline void check_search_effort(int screen_iterations, int refine_iterations, int refine_top) {
  const auto at_least_one = [](int v, const char* name) {
    require(v >= 1, std::string(name) + " must be >= 1, got " + std::to_string(v), at_parameter(name));
  };
  at_least_one(screen_iterations, "screen_iterations");
  at_least_one(refine_iterations, "refine_iterations");
  at_least_one(refine_top, "refine_top");
}

/// Greedy effect search from `start` (fitted on `est`, with initial states `x0_est`), scored on
/// `val` against the noise floor `noise` (see the file comment).
template <Physics P>
SearchResult<P> search_effects(const AugmentedModel<P>& start, std::vector<Eigen::VectorXd> x0_est,
                               const Dataset& est, const Dataset& val, const NoiseFloor& noise,
                               const SearchOptions& options = {});

/// Runs `task(i)` for i in [0, n) on up to `threads` std::threads (0 = hardware concurrency,
/// capped at 8). Exceptions inside tasks must be caught by the task.
inline void parallel_for(int n, int threads, const std::function<void(int)>& task);

// ------------------------------------------------------------------------------------------
// Implementation details below.
// ------------------------------------------------------------------------------------------

inline void parallel_for(int n, int threads, const std::function<void(int)>& task) {
  if (n <= 0) return;
  int t = threads > 0 ? threads : static_cast<int>(std::thread::hardware_concurrency());
  t = std::clamp(t, 1, 8);
  t = std::min(t, n);
  if (t == 1) {
    for (int i = 0; i < n; ++i) task(i);
    return;
  }
  std::atomic<int> next{0};
  std::vector<std::thread> pool;
  for (int w = 0; w < t; ++w) {
    pool.emplace_back([&] {
      for (int i = next++; i < n; i = next++) task(i);
    });
  }
  for (std::thread& th : pool) th.join();
}

template <Physics P>
DataScales data_scales(const AugmentedModel<P>& model, const Dataset& data,
                       const std::vector<Eigen::VectorXd>& x0) {
  DataScales s;
  s.ts = data.ts();
  const Eigen::VectorXd y = pooled(data, Channel::output, 0);
  const Eigen::VectorXd u = pooled(data, Channel::input, 0);
  if (y.size() > 0) {
    s.y_lo = quantile(y, 0.005);
    s.y_hi = quantile(y, 0.995);
    s.y_min = y.minCoeff();
    s.y_max = y.maxCoeff();
  }
  if (u.size() > 0) {
    s.u_lo = quantile(u, 0.005);
    s.u_hi = quantile(u, 0.995);
    s.u_abs = u.cwiseAbs().maxCoeff();
    if (!(s.u_abs > 0.0)) s.u_abs = 1.0;
  }
  s.q_lo = s.y_lo;
  s.q_hi = s.y_hi;
  s.q_mid = y.size() > 0 ? quantile(y, 0.5) : 0.5;
  const MechanicalRoles& r = model.roles();
  if (!r.mechanical) {
    // A non-mechanical baseline: keep output levels; speed from the measured output's rate.
    std::vector<double> rates;
    for (const Experiment& e : data) {
      const Eigen::VectorXd rt = smoothed_rate(e.y().col(0), e.ts());
      for (Eigen::Index k = 0; k < rt.size(); ++k) rates.push_back(std::abs(rt(k)));
    }
    if (!rates.empty())
      s.speed = std::max(quantile(Eigen::Map<Eigen::VectorXd>(rates.data(), static_cast<Eigen::Index>(rates.size())), 0.95), 1e-12);
    return s;
  }
  const int nx = model.state_dimension();
  const Eigen::VectorXd th = model.parameters();
  std::vector<double> qs, vs, as;
  std::vector<std::vector<double>> probe;  // states where the stiffness is read (every 10th sample)
  std::vector<Eigen::RowVectorXd> probe_u;
  std::vector<double> p;
  for (const ParameterInfo& q : model.baseline_parameters()) p.push_back(q.value);
  for (std::size_t e = 0; e < data.size(); ++e) {
    const Experiment& x = data[e];
    const Eigen::Index n = x.size();
    Eigen::VectorXd yh(n);
    std::vector<double> st(static_cast<std::size_t>(n * nx));
    const Eigen::VectorXd s0 = e < x0.size() ? x0[e] : model.initial_state_guess(x);
    if (model.template simulate<double>(x.u(), th.data(), s0.data(), yh.data(), st.data()) < n) continue;
    for (Eigen::Index k = 0; k < n; ++k) {
      qs.push_back(st[static_cast<std::size_t>(k * nx + r.position)]);
      vs.push_back(std::abs(st[static_cast<std::size_t>(k * nx + r.velocity)]));
      if (k > 0)
        as.push_back(std::abs(st[static_cast<std::size_t>(k * nx + r.velocity)] -
                              st[static_cast<std::size_t>((k - 1) * nx + r.velocity)]) / x.ts());
      if (k % 10 == 0) {
        probe.emplace_back(st.begin() + k * nx, st.begin() + (k + 1) * nx);
        probe_u.push_back(x.u().row(k));
      }
    }
  }
  auto vecq = [](std::vector<double>& v, double q) {
    return quantile(Eigen::Map<Eigen::VectorXd>(v.data(), static_cast<Eigen::Index>(v.size())), q);
  };
  if (qs.size() > 10) {
    s.q_lo = vecq(qs, 0.005);
    s.q_hi = vecq(qs, 0.995);
    s.q_mid = vecq(qs, 0.5);
    s.speed = std::max(vecq(vs, 0.95), 1e-12);
    if (!as.empty()) s.accel = std::max(vecq(as, 0.95), 1e-12);
    // Spring stiffness −∂v̇/∂q, read in the central 80 % of the travel range (not of the samples:
    // a valve may rest on a stop for half the record) so that contact with a stop, a much
    // stiffer spring, does not pose as it.
    const double band_lo = s.q_lo + 0.1 * (s.q_hi - s.q_lo), band_hi = s.q_hi - 0.1 * (s.q_hi - s.q_lo);
    std::vector<double> ks;
    for (std::size_t i = 0; i < probe.size(); ++i) {
      const double q = probe[i][static_cast<std::size_t>(r.position)];
      if (q < band_lo || q > band_hi) continue;
      const Eigen::MatrixXd J = physics_state_jacobian(model.physics(), probe[i].data(), probe_u[i].data(), p.data());
      const double kk = -J(r.velocity, r.position);
      if (std::isfinite(kk)) ks.push_back(kk);
    }
    if (!ks.empty()) s.stiffness = std::max(0.0, vecq(ks, 0.5));
  }
  // Equilibrium at zero input: where a force step (preload) most often sits.
  {
    Eigen::VectorXd xe = data.size() > 0 ? model.initial_state_guess(data[0]) : Eigen::VectorXd::Zero(nx);
    const Eigen::VectorXd u0 = Eigen::VectorXd::Zero(std::max(1, data.num_inputs()));
    const EquilibriumResult eq = physics_equilibrium(model.physics(), u0.data(), p.data(), xe.data());
    if (eq.converged && xe.allFinite()) s.rest_position = xe(r.position);
  }
  return s;
}

namespace detail {

inline std::string format_fits(const Eigen::VectorXd& f) {
  std::string s;
  for (Eigen::Index i = 0; i < f.size(); ++i) {
    s += (i ? "/" : "") + format_f(f(i), 1);
  }
  return s;
}

}  // namespace detail

template <Physics P>
SearchResult<P> search_effects(const AugmentedModel<P>& start, std::vector<Eigen::VectorXd> x0_est,
                               const Dataset& est, const Dataset& val, const NoiseFloor& noise,
                               const SearchOptions& options) {
  require(noise.sigma > 0.0, "effect search: the noise floor must be positive", at_parameter("noise"));
  require(options.max_effects >= 0, "max_effects must be >= 0", at_parameter("max_effects"));
  check_search_effort(options.screen_iterations, options.refine_iterations, options.refine_top);
  auto say = [&](const std::string& s) {
    if (options.progress) options.progress(s);
  };
  SearchResult<P> out{start, std::move(x0_est), {}, {}, {}, SearchStop::none_significant, 0};
  const std::vector<EffectKind> kinds = options.kinds.empty() ? all_effect_kinds() : options.kinds;
  for (EffectKind k : kinds) {
    const std::string why = effect_not_applicable_reason(k, start.roles().mechanical);
    if (!why.empty()) out.not_applicable.push_back(std::string(effect_name(k)) + ": " + why);
  }
  Eigen::Index n_val = 0;
  for (const Experiment& e : val) n_val += e.size();
  const InitialCondition ic = options.initial_condition;
  RefitOptions screen, refine;
  screen.max_iterations = options.screen_iterations;
  screen.function_tolerance = 1e-6;
  screen.initial_condition = ic;
  screen.hold_initial_states = true;  // screening moves the model, not the records' starts
  refine.max_iterations = options.refine_iterations;
  refine.function_tolerance = 1e-8;
  refine.initial_condition = ic;
  const bool zero_x0 = ic == InitialCondition::zero;

  for (int round = 1;; ++round) {
    const AugmentedModel<P>& cur = out.model;
    const Evaluation base_val = evaluate_model(cur, val, {}, ic);
    SearchRound rr;
    rr.round = round;
    rr.sse_val_before = base_val.total_sse();
    rr.fit_val_before = base_val.fit;
    rr.gate = floor_consistency(rr.sse_val_before, n_val, noise.sigma, noise.inflation, options.significance);
    if (static_cast<int>(cur.effects().size()) >= options.max_effects) {
      out.stop = SearchStop::effect_limit;
      out.stop_reason = "reached the limit of " + std::to_string(options.max_effects) + " effect(s)";
      break;
    }
    if (rr.gate.consistent) {
      out.stop = SearchStop::noise_floor;
      out.stop_reason = "the validation residual is consistent with the noise floor (energy ratio " +
                        detail::format_f(rr.gate.ratio, 3) + " <= " + detail::format_f(rr.gate.bound, 3) + ")";
      out.rounds.push_back(rr);
      break;
    }
    // Candidates.
    const DataScales sc = data_scales(cur, est, out.x0_est);
    std::vector<EffectCandidate> cands;
    for (EffectKind k : kinds) {
      if (!effect_not_applicable_reason(k, cur.roles().mechanical).empty()) continue;
      for (EffectCandidate& c : make_effect_candidates(k, sc)) {
        bool present = false;
        for (const Effect& e : cur.effects()) present = present || (e.kind == c.effect.kind && e.variant == c.effect.variant);
        if (!present) cands.push_back(std::move(c));
      }
    }
    if (cands.empty()) {
      out.stop = SearchStop::catalogue_exhausted;
      out.stop_reason = "no catalogue effect left to try";
      out.rounds.push_back(rr);
      break;
    }
    say("round " + std::to_string(round) + ": screening " + std::to_string(cands.size()) + " candidate effects");
    // Screening: every (candidate, start) pair.
    struct Task { std::size_t cand; std::size_t start; };
    std::vector<Task> tasks;
    for (std::size_t c = 0; c < cands.size(); ++c)
      for (std::size_t s = 0; s < cands[c].starts.size(); ++s) tasks.push_back({c, s});
    std::vector<RefitResult> screened(tasks.size());
    std::vector<AugmentedModel<P>> models;
    for (const EffectCandidate& c : cands) models.push_back(cur.with_effect(c.effect));
    const Eigen::VectorXd th_cur = cur.parameters();
    parallel_for(static_cast<int>(tasks.size()), options.threads, [&](int i) {
      const Task& t = tasks[static_cast<std::size_t>(i)];
      Eigen::VectorXd th0(models[t.cand].num_parameters());
      th0 << th_cur, cands[t.cand].starts[t.start];
      try {
        screened[static_cast<std::size_t>(i)] =
            refit(models[t.cand], est, th0, zero_x0 ? std::vector<Eigen::VectorXd>{} : out.x0_est, screen);
      } catch (const std::exception& ex) {
        screened[static_cast<std::size_t>(i)].error = ex.what();
      }
    });
    std::vector<CandidateResult> res(cands.size());
    std::vector<RefitResult> best(cands.size());
    for (std::size_t i = 0; i < tasks.size(); ++i) {
      RefitResult& b = best[tasks[i].cand];
      if (screened[i].ok && (!b.ok || screened[i].sse < b.sse)) b = screened[i];
      if (!b.ok && b.error.empty()) b.error = screened[i].error;
    }
    // Refine the most promising by estimation cost.
    std::vector<std::size_t> order(cands.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
      const double sa = best[a].ok ? best[a].sse : std::numeric_limits<double>::infinity();
      const double sb = best[b].ok ? best[b].sse : std::numeric_limits<double>::infinity();
      return sa != sb ? sa < sb : a < b;
    });
    const std::size_t top = std::min<std::size_t>(static_cast<std::size_t>(options.refine_top), order.size());
    say("round " + std::to_string(round) + ": refitting the best " + std::to_string(top) + " to convergence");
    std::vector<char> refined(cands.size(), 0);
    parallel_for(static_cast<int>(top), options.threads, [&](int i) {
      const std::size_t c = order[static_cast<std::size_t>(i)];
      if (!best[c].ok) return;
      try {
        RefitResult r = refit(models[c], est, best[c].theta, zero_x0 ? std::vector<Eigen::VectorXd>{} : best[c].x0, refine);
        // Refined means the converging refit ran; its result replaces the screening fit unless it
        // ended higher (a run that stops at its iteration limit after a detour).
        if (!r.ok) return;  // not refined, so it cannot be accepted; its screening fit is still scored
        if (r.sse <= best[c].sse) best[c] = std::move(r);
        refined[c] = 1;
      } catch (const std::exception& ex) {
        best[c].error = ex.what();
      }
    });
    // Validation scores.
    std::vector<double> dnorm(cands.size(), 0.0);
    parallel_for(static_cast<int>(cands.size()), options.threads, [&](int i) {
      const auto c = static_cast<std::size_t>(i);
      CandidateResult& cr = res[c];
      cr.round = round;
      cr.effect = cands[c].effect;
      cr.added_params = static_cast<int>(cands[c].effect.params.size());
      cr.refined = refined[c] != 0;
      cr.error = best[c].error;
      if (!best[c].ok) return;
      try {
        AugmentedModel<P> m = models[c];
        m.set_parameters(best[c].theta);
        cr.effect = m.effects().back();
        cr.theta = best[c].theta;
        cr.x0_est = best[c].x0;
        cr.sse_est = best[c].sse;
        const Evaluation ee = evaluate_model(m, est, best[c].x0, ic);
        const Evaluation ve = evaluate_model(m, val, {}, ic);
        cr.fit_est = ee.fit;
        cr.fit_val = ve.fit;
        if (!ve.ok) {
          cr.error = "validation simulation diverged";
          return;
        }
        cr.sse_val = ve.total_sse();
        double d2 = 0.0;
        for (std::size_t e = 0; e < val.size(); ++e) d2 += (ve.yhat[e] - base_val.yhat[e]).squaredNorm();
        dnorm[c] = std::sqrt(d2);
        cr.ok = true;
      } catch (const std::exception& ex) {
        cr.error = ex.what();
      }
    });
    const int tried = static_cast<int>(cands.size());
    for (std::size_t c = 0; c < res.size(); ++c) {
      if (!res[c].ok) continue;
      res[c].stats = candidate_statistics(rr.sse_val_before, res[c].sse_val, dnorm[c], n_val, noise.sigma,
                                          noise.inflation, res[c].added_params, tried, options.significance);
    }
    std::stable_sort(res.begin(), res.end(), [](const CandidateResult& a, const CandidateResult& b) {
      if (a.ok != b.ok) return a.ok;
      return a.stats.score > b.stats.score;
    });
    rr.candidates = std::move(res);
    for (std::size_t i = 0; i < rr.candidates.size(); ++i) {
      const CandidateResult& c = rr.candidates[i];
      if (c.ok && c.refined && c.stats.significant) {
        rr.accepted = static_cast<int>(i);
        break;
      }
    }
    for (const CandidateResult& c : rr.candidates) {
      say("  " + detail::left_aligned(c.effect.label(), 28) + " fit_val " +
          detail::left_aligned(c.ok ? detail::format_fits(c.fit_val) : std::string("failed"), 18) + " score " +
          detail::right_aligned(detail::format_f(c.stats.score, 1), 10) + "  z " +
          detail::right_aligned(detail::format_f(c.stats.z, 1), 8) + "  share " +
          detail::right_aligned(detail::format_f(c.stats.relevance, 3), 6) + (c.refined ? "  refined" : "") +
          (c.stats.significant ? "  significant" : ""));
    }
    if (rr.accepted < 0) {
      out.stop = SearchStop::none_significant;
      out.stop_reason = "no candidate improved the validation fit significantly";
      out.rounds.push_back(std::move(rr));
      break;
    }
    if (options.ablation_check) {
      const CandidateResult& w = rr.candidates[static_cast<std::size_t>(rr.accepted)];
      AugmentedModel<P> wm = cur.with_effect(w.effect);
      wm.set_parameters(w.theta);
      // The control starts from the winner's values of M's parameters (clamped into M's bounds).
      Eigen::VectorXd th_ctrl = w.theta.head(cur.num_parameters());
      const std::vector<ParameterInfo> info = cur.parameter_info();
      for (Eigen::Index i = 0; i < th_ctrl.size(); ++i)
        th_ctrl(i) = std::clamp(th_ctrl(i), info[static_cast<std::size_t>(i)].lower, info[static_cast<std::size_t>(i)].upper);
      const RefitResult ctrl = refit(cur, est, th_ctrl, zero_x0 ? std::vector<Eigen::VectorXd>{} : w.x0_est, refine);
      // The control is M's own structure re-fitted on the estimation records from another start.
      // If it validates better than M and the winner is not significantly better than it, the
      // gain belongs to the structure M already has: the effect is rejected and the control
      // continues. (Tried 2026-11-27: keeping the control only when its *estimation* cost is
      // lower, so that validation records never choose between two fits of one structure; the
      // throttle null case of the concealed suite then added cubic_stiffness, a false effect —
      // the control there validates better at no lower estimation cost.)
      if (ctrl.ok) {
        AugmentedModel<P> cm = cur;
        cm.set_parameters(ctrl.theta);
        const Evaluation cv = evaluate_model(cm, val, {}, ic);
        const Evaluation wv = evaluate_model(wm, val, {}, ic);
        if (cv.ok && wv.ok && cv.total_sse() < rr.sse_val_before) {
          double d2 = 0.0;
          for (std::size_t e = 0; e < val.size(); ++e) d2 += (wv.yhat[e] - cv.yhat[e]).squaredNorm();
          const CandidateStatistics vs =
              candidate_statistics(cv.total_sse(), wv.total_sse(), std::sqrt(d2), n_val, noise.sigma, noise.inflation,
                                   w.added_params, tried, options.significance);
          if (!vs.significant) {
            rr.note = w.effect.label() + " failed the ablation check: the model without it, re-fitted from its values, "
                      "reaches validation fit " + detail::format_fits(cv.fit) + " % (with it " +
                      detail::format_fits(w.fit_val) + " %); kept the re-fitted model instead";
            say("round " + std::to_string(round) + ": " + rr.note);
            rr.accepted = -1;
            out.x0_est = ctrl.x0;
            out.rounds.push_back(std::move(rr));
            out.model = std::move(cm);
            ++out.refits_without_effect;
            if (out.refits_without_effect > options.max_effects + 2) {
              out.stop = SearchStop::repeated_refits;
              out.stop_reason = "stopped after repeated re-fits without a new effect";
              break;
            }
            continue;
          }
        }
      }
    }
    const CandidateResult& win = rr.candidates[static_cast<std::size_t>(rr.accepted)];
    say("round " + std::to_string(round) + ": added " + win.effect.label());
    AugmentedModel<P> next = cur.with_effect(win.effect);
    next.set_parameters(win.theta);
    out.x0_est = win.x0_est;
    out.rounds.push_back(std::move(rr));
    out.model = std::move(next);
  }
  return out;
}

}  // namespace nlid
