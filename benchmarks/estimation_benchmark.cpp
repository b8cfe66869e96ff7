// Estimation speed (issue 5, item 3): nlid vs Ceres Solver on identical data, starting point and
// residuals — the throttle study's data1 + data2 at 100 Hz (two experiments of 2000 samples).
//
//   Nlarx5_Full_Nlid     nlid::estimate(nlarx5, simulation focus, 90 iterations): everything a
//                        user waits for (initialisation, prediction stage, simulation stage).
//   Nlarx5_Sim_{Nlid,Ceres}     the simulation-focus stage alone (47 parameters, 3994 free-run
//                        residuals, measured initial past) from the same start, ≤ 90 iterations.
//   Nlhw2_{Nlid,Ceres}   pwlinear(10) → B/F [3 3 0] → pwlinear(10), 46 parameters, zero initial
//                        state, ≤ 200 iterations from nlid's data-driven start.
//   Throttle_{Nlid,Ceres} the study's grey-box equation, 4 parameters, RK4, ≤ 100 iterations.
//   Throttle_NlidBroyden  an experiment: every other Jacobian a Broyden update (see its comment).
//
// Both sides: Levenberg–Marquardt, each with its own defaults (nlid: the options estimate()
// uses, i.e. uniform damping for Hammerstein-Wiener; Nlhw2_NlidCeresDamping: Ceres' damping, so
// nearly the same iterates and the per-iteration cost). nlid's Jacobians: the structured ones
// estimate() uses for nlarx5 (models/detail/nlarx_sensitivity.hpp) and nlhw2
// (models/detail/hw_sensitivity.hpp), with *_NlidForwardAD (forward AD through the whole
// simulation) for comparison; for the grey box forward AD (Dual) through the ODE solution.
// Ceres: AutoDiffCostFunction + Jet through a templated functor of the same residuals,
// DENSE_NORMAL_CHOLESKY, one thread. Before timing, the residual vectors of both are compared at
// the start (they must agree to 1e-9). Counters: final cost ½Σr², iterations. The ratio table
// checks "nlid ≥ 2× faster"; the cost check is printed beside it.
// Results, machine and command: docs/performance.md.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "nlid/estimation/autodiff.hpp"
#include "nlid/estimation/levenberg_marquardt.hpp"
#include "nlid/models/estimate.hpp"
#include "nlid/models/greybox_problem.hpp"
#include "nlid/models/integrators.hpp"
#include "perf_models.hpp"

#ifdef NLID_HAVE_CERES
#include <ceres/ceres.h>
#endif

namespace {

using nlid::InitialCondition;

const nlid::Dataset& data12() {
  static const nlid::Dataset d{perf::throttle_data(1), perf::throttle_data(2)};
  return d;
}

std::map<std::string, double>& final_costs() {
  static std::map<std::string, double> c;
  return c;
}

void fail(const std::string& what) {
  std::fprintf(stderr, "estimation_benchmark: %s\n", what.c_str());
  std::exit(1);
}

// ---- the same residuals, written once as a templated functor for Ceres ---------------------------

// nlhw2 from rest: w = f(u), x = B/F w (TDF-II), ŷ = h(x), r = ŷ − y. Breakpoint tables are
// built once per evaluation (xₖ = x_{k−1} + exp γₖ, the same parametrisation as nlid's PwLinear).
struct Nlhw2Residuals {
  const nlid::Dataset* data;
  template <class T>
  struct Table {
    T x[10], y[10];
    T operator()(const T& v) const {
      int k = 0;
      while (k < 8 && !(v < x[k + 1])) ++k;
      return y[k] + (y[k + 1] - y[k]) / (x[k + 1] - x[k]) * (v - x[k]);
    }
  };
  template <class T>
  static Table<T> table(const T* p) {
    using std::exp;
    Table<T> t;
    t.x[0] = p[0];
    for (int k = 1; k < 10; ++k) t.x[k] = t.x[k - 1] + exp(p[k]);
    for (int k = 0; k < 10; ++k) t.y[k] = p[10 + k];
    return t;
  }
  template <class T>
  bool operator()(const T* th, T* res) const {
    const Table<T> f = table(th), h = table(th + 26);
    long off = 0;
    for (const auto& e : *data) {
      T s0(0.0), s1(0.0), s2(0.0);
      for (Eigen::Index t = 0; t < e.size(); ++t) {
        const T w = f(T(e.u()(t, 0)));
        const T x = s0 + th[20] * w;
        s0 = s1 + th[21] * w - th[23] * x;
        s1 = s2 + th[22] * w - th[24] * x;
        s2 = -th[25] * x;
        res[off++] = h(x) - e.y()(t, 0);
      }
    }
    return true;
  }
};

// Grey-box throttle from rest at zero, RK4 with nlid's sub-step rule, residuals weighted by w.
struct ThrottleResiduals {
  const nlid::Dataset* data;
  double weight;
  template <class T>
  static T acc(const T& pos, const T& vel, double uk, const T* p) {
    // std::max/min, as the physics writes it: inline compares on double and (through Jet's
    // operator<) on Jets. std::fmax on double is a libm call (it must order NaNs), which made
    // Ceres' residual-only evaluations 1.5x slower than the same arithmetic (0.45 vs 0.30 ms).
    using std::max;
    using std::min;
    const T stop = max(pos, T(90.0)) - 90.0 + min(pos, T(15.0)) - 15.0;
    return p[3] * uk - p[0] * vel - p[1] * pos - p[2] * stop;
  }
  template <class T>
  bool operator()(const T* p, T* res) const {
    const double pv[4] = {value(p[0]), value(p[1]), value(p[2]), value(p[3])};
    const double ts = data->ts();
    const int sub = nlid::substeps_for(ts, perf::StudyThrottle{}.spectral_radius(pv), nlid::IntegratorOptions{});
    const double h = ts / sub;
    long off = 0;
    for (const auto& e : *data) {
      T p0(0.0), v0(0.0);
      for (Eigen::Index t = 0; t < e.size(); ++t) {
        res[off++] = weight * (p0 - e.y()(t, 0));
        if (t + 1 == e.size()) break;
        const double uk = e.u()(t, 0);
        for (int i = 0; i < sub; ++i) {
          const T k1p = v0, k1v = acc(p0, v0, uk, p);
          const T k2p = v0 + 0.5 * h * k1v, k2v = acc(T(p0 + 0.5 * h * k1p), T(v0 + 0.5 * h * k1v), uk, p);
          const T k3p = v0 + 0.5 * h * k2v, k3v = acc(T(p0 + 0.5 * h * k2p), T(v0 + 0.5 * h * k2v), uk, p);
          const T k4p = v0 + h * k3v, k4v = acc(T(p0 + h * k3p), T(v0 + h * k3v), uk, p);
          p0 += h / 6.0 * (k1p + 2.0 * (k2p + k3p) + k4p);
          v0 += h / 6.0 * (k1v + 2.0 * (k2v + k3v) + k4v);
        }
      }
    }
    return true;
  }
  static double value(double x) { return x; }
#ifdef NLID_HAVE_CERES
  template <int N>
  static double value(const ceres::Jet<double, N>& x) {
    return x.a;
  }
#endif
};

// ---- problems: start point and the nlid residual functor ---------------------------------------------

// The estimation segments of data1 + data2 as estimate() builds them (`start_of` sets the initial
// condition of each), and the divergence limit from all outputs.
template <class Setup, class StartOf>
void segments_of(Setup& st, StartOf&& start_of) {
  Eigen::VectorXd yall(data12().total_samples());
  Eigen::Index k = 0;
  for (const auto& e : data12()) {
    nlid::detail::EstimationSegment seg;
    seg.u = &e.u();
    seg.y = e.y().col(0);
    start_of(e, seg);
    st.segs.push_back(seg);
    yall.segment(k, e.size()) = seg.y;
    k += e.size();
  }
  st.limit = nlid::detail::divergence_limit(yall);
}

struct Nlarx5Setup {
  perf::Nlarx5 model;
  Eigen::VectorXd theta0;
  std::vector<nlid::detail::EstimationSegment> segs;
  double limit = 0;
};

const Nlarx5Setup& nlarx5_setup() {
  static const Nlarx5Setup s = [] {
    Nlarx5Setup st;
    // nlid's own start for the simulation stage: data-driven initialisation + 20 prediction
    // iterations (what estimate() does before the simulation stage).
    nlid::EstimateOptions o;
    o.focus = nlid::Focus::prediction;
    o.solver.max_iterations = 20;
    st.model = nlid::estimate(perf::Nlarx5{}, data12(), o);
    st.theta0 = st.model.parameters();
    segments_of(st, [&](const nlid::Experiment& e, nlid::detail::EstimationSegment& seg) {
      seg.start = st.model.history_length();  // measured initial past
      seg.x0 = st.model.measured_state(e.u(), seg.y, seg.start);
    });
    return st;
  }();
  return s;
}

using Nlarx5Functor = nlid::detail::SimulationResiduals<perf::Nlarx5, perf::kNlarx5Params>;

struct Nlhw2Setup {
  perf::Nlhw2 model;
  Eigen::VectorXd theta0;
  std::vector<nlid::detail::EstimationSegment> segs;
  double limit = 0;
};

const Nlhw2Setup& nlhw2_setup() {
  static const Nlhw2Setup s = [] {
    Nlhw2Setup st;
    nlid::EstimateOptions o;
    o.solver.max_iterations = 0;  // nlid's data-driven initialisation only
    st.model = nlid::estimate(perf::Nlhw2{}, data12(), o);
    st.theta0 = st.model.parameters();
    segments_of(st, [](const nlid::Experiment&, nlid::detail::EstimationSegment&) {});  // zero initial state
    return st;
  }();
  return s;
}

using Nlhw2Functor = nlid::detail::SimulationResiduals<perf::Nlhw2, perf::kNlhw2Params>;

// A rough physical guess (not the optimum): damping, spring, stop stiffness, gain.
Eigen::VectorXd throttle_theta0() { return (Eigen::Vector4d() << 15.0, 80.0, 5e3, 6000.0).finished(); }

nlid::GreyBoxProblem<perf::StudyThrottle> throttle_problem() {
  return nlid::GreyBoxProblem<perf::StudyThrottle>(perf::StudyThrottle{}, nlid::IntegratorOptions{}, data12(),
                                                   InitialCondition::zero);
}

// ---- residual agreement (the comparison is void unless both sides minimise the same thing) -------------

template <class Functor, class CeresFunctor>
void check_same(const char* name, const Functor& f, const CeresFunctor& c, const Eigen::VectorXd& th) {
  const auto m = static_cast<std::size_t>(f.num_residuals());
  std::vector<double> a(m), b(m);
  if (!f.template residuals<double>(std::span<const double>(th.data(), static_cast<std::size_t>(th.size())), std::span<double>(a)))
    fail(name);
  c(th.data(), b.data());
  double worst = 0, scale = 0;
  for (std::size_t i = 0; i < m; ++i) {
    worst = std::max(worst, std::abs(a[i] - b[i]));
    scale = std::max(scale, std::abs(a[i]));
  }
  if (!(worst <= 1e-9 * (1 + scale))) fail(std::string(name) + ": nlid and Ceres residuals differ by " + std::to_string(worst));
}

void report(benchmark::State& state, const std::string& key, double cost, int iterations) {
  state.counters["final_cost"] = cost;
  state.counters["iterations"] = iterations;
  final_costs()[key] = cost;
}

// The solver options estimate() uses: its defaults, and for Hammerstein-Wiener models uniform
// (Levenberg) damping, which LmScaling::automatic selects there (models/estimate.hpp).
nlid::LmOptions lm_options(int iterations, nlid::LmScaling scaling = nlid::LmScaling::automatic) {
  nlid::LmOptions o;
  o.max_iterations = iterations;
  o.scaling = scaling;
  return o;
}

// estimate()'s options for the nlhw2 solve: uniform damping of each parameter in its own units,
// which follow the data's RMS (detail::hw_parameter_scales).
template <class Model>
nlid::LmOptions hw_lm_options(const Model& model, int iterations) {
  nlid::LmOptions o = lm_options(iterations, nlid::LmScaling::levenberg);
  const nlid::Dataset& d = data12();
  Eigen::VectorXd u(d.total_samples()), y(d.total_samples());
  Eigen::Index k = 0;
  for (std::size_t i = 0; i < d.size(); ++i) {
    u.segment(k, d[i].size()) = d[i].u().col(0);
    y.segment(k, d[i].size()) = d[i].y().col(0);
    k += d[i].size();
  }
  o.parameter_scale = nlid::detail::hw_parameter_scales(model, u, y);
  if (o.parameter_scale.size() != model.num_parameters()) fail("nlhw2: its maps do not know their parameters' units");
  return o;
}

// Three complete LM solves of `problem` from `theta0` (one per benchmark iteration).
template <class Problem, class Theta>
void run_solve(benchmark::State& state, const std::string& key, const Problem& problem, const Theta& theta0,
               const nlid::LmOptions& options) {
  nlid::LmSummary sum;
  for (auto _ : state) {
    Theta th = theta0;
    sum = nlid::solve_least_squares(problem, th, options);
  }
  report(state, key, sum.final_cost, sum.iterations);
}

// A structured Jacobian must equal forward AD at the start, or its timing compares nothing.
template <class Structured, class ForwardAD>
void check_structured(const char* name, const Structured& problem, const ForwardAD& ad,
                      const Eigen::Matrix<double, Structured::num_params, 1>& th) {
  constexpr int P = Structured::num_params;
  const Eigen::Index m = problem.num_residuals();
  Eigen::VectorXd r1(m), r2(m);
  nlid::JacobianMatrix<P> J1(m, P), J2(m, P);
  if (!ad.evaluate(th, r1, &J1) || !problem.evaluate(th, r2, &J2)) fail(std::string(name) + ": evaluation at the start");
  const double dj = (J1 - J2).cwiseAbs().maxCoeff() / (1.0 + J1.cwiseAbs().maxCoeff());
  const double dr = (r1 - r2).cwiseAbs().maxCoeff() / (1.0 + r1.cwiseAbs().maxCoeff());
  if (!(dj <= 1e-9 && dr <= 1e-12))
    fail(std::string(name) + ": structured Jacobian differs from forward AD by " + std::to_string(dj) + " (residuals " +
         std::to_string(dr) + ")");
}

// ---- nlid ------------------------------------------------------------------------------------------------

void Nlarx5_Full_Nlid(benchmark::State& state) {
  nlid::EstimateOptions o;
  o.focus = nlid::Focus::simulation;
  o.solver.max_iterations = 90;
  double cost = 0;
  int it = 0;
  for (auto _ : state) {
    const perf::Nlarx5 m = nlid::estimate(perf::Nlarx5{}, data12(), o);
    cost = m.report().final_cost;
    it = m.report().iterations;
  }
  report(state, "Nlarx5_Full_Nlid", cost, it);
}

// The simulation stage as estimate() runs it: the library's structured simulation Jacobian
// (models/detail/nlarx_sensitivity.hpp), checked against forward AD through the recursion before
// timing.
using Nlarx5Structured = nlid::detail::NlarxSimulationProblem<perf::Nlarx5, perf::kNlarx5Params>;

void Nlarx5_Sim_Nlid(benchmark::State& state) {
  const auto& s = nlarx5_setup();
  const Nlarx5Structured problem(s.model, s.segs, {}, InitialCondition::measured, s.limit);
  check_structured("nlarx5", problem,
                   nlid::AutoDiffProblem<Nlarx5Functor>(Nlarx5Functor(s.model, s.segs, {}, InitialCondition::measured, s.limit)),
                   s.theta0);
  run_solve(state, "Nlarx5_Sim_Nlid", problem, Eigen::Matrix<double, perf::kNlarx5Params, 1>(s.theta0), lm_options(90));
}

// The same stage with forward AD (Dual<double, 47>) through the recursion: the route of
// EstimateOptions::structured_jacobian = false and of nonlinearities without an analytic gradient.
void Nlarx5_Sim_NlidForwardAD(benchmark::State& state) {
  const auto& s = nlarx5_setup();
  const nlid::AutoDiffProblem<Nlarx5Functor> problem(Nlarx5Functor(s.model, s.segs, {}, InitialCondition::measured, s.limit));
  run_solve(state, "Nlarx5_Sim_NlidForwardAD", problem, Eigen::Matrix<double, perf::kNlarx5Params, 1>(s.theta0), lm_options(90));
}

// nlhw2 as estimate() runs it: the structured Hammerstein-Wiener Jacobian
// (models/detail/hw_sensitivity.hpp), checked against forward AD through the chain first.
using Nlhw2Structured = nlid::detail::HwSimulationProblem<perf::Nlhw2, perf::kNlhw2Params>;

void Nlhw2_Nlid(benchmark::State& state) {
  const auto& s = nlhw2_setup();
  const Nlhw2Structured problem(s.model, s.segs, InitialCondition::zero, s.limit);
  check_structured("nlhw2", problem,
                   nlid::AutoDiffProblem<Nlhw2Functor>(Nlhw2Functor(s.model, s.segs, {}, InitialCondition::zero, s.limit)),
                   s.theta0);
  run_solve(state, "Nlhw2_Nlid", problem, Eigen::Matrix<double, perf::kNlhw2Params, 1>(s.theta0),
            hw_lm_options(s.model, 200));
}

// The same structured problem with Ceres' own damping (Marquardt scaling by the current column
// norms, initial damping 1e-4 = 1 / Ceres' initial trust radius): both solvers then take 200
// iterations of the same method, so this ratio is close to the per-iteration cost alone. (The
// iterates agree with Ceres' DENSE_QR run to the final cost; Ceres' Cholesky steps round
// differently and end 0.04 % lower on this 46-parameter problem.)
void Nlhw2_NlidCeresDamping(benchmark::State& state) {
  const auto& s = nlhw2_setup();
  const Nlhw2Structured problem(s.model, s.segs, InitialCondition::zero, s.limit);
  nlid::LmOptions o = lm_options(200, nlid::LmScaling::current);
  o.initial_lambda = 1e-4;
  run_solve(state, "Nlhw2_NlidCeresDamping", problem, Eigen::Matrix<double, perf::kNlhw2Params, 1>(s.theta0), o);
}

// The same solve with forward AD (Dual<double, 46>) through the whole chain.
void Nlhw2_NlidForwardAD(benchmark::State& state) {
  const auto& s = nlhw2_setup();
  const nlid::AutoDiffProblem<Nlhw2Functor> problem(Nlhw2Functor(s.model, s.segs, {}, InitialCondition::zero, s.limit));
  run_solve(state, "Nlhw2_NlidForwardAD", problem, Eigen::Matrix<double, perf::kNlhw2Params, 1>(s.theta0),
            hw_lm_options(s.model, 200));
}

void Throttle_Nlid(benchmark::State& state) {
  run_solve(state, "Throttle_Nlid", throttle_problem(), throttle_theta0(), lm_options(100));
}

// An experiment on target 3d, not a library feature (docs/performance.md, estimation reading):
// half of the Jacobians requested at accepted points are Broyden rank-one updates of the last
// one, J += (r − r_last − J·δ)·δᵀ/(δᵀδ), which costs no Dual<4> pass; the other half are exact.
// When the solver stops while an updated Jacobian is in use it is restarted from its θ with an
// exact one (the update's errors, not the optimum, can stop it), within the same 100 attempts.
struct BroydenThrottle {
  static constexpr int num_params = 4;
  explicit BroydenThrottle(const nlid::GreyBoxProblem<perf::StudyThrottle>* p) : exact_problem(p) {}
  const nlid::GreyBoxProblem<perf::StudyThrottle>* exact_problem;
  mutable bool have = false;
  mutable int since_exact = 0;
  mutable Eigen::Vector4d th_last, th_trial;
  mutable Eigen::VectorXd r_last, r_trial;
  mutable Eigen::Matrix<double, Eigen::Dynamic, 4> j_last;
  mutable Eigen::MatrixXd j_exact;
  int num_parameters() const { return 4; }
  Eigen::Index num_residuals() const { return exact_problem->num_residuals(); }
  bool evaluate(const Eigen::Vector4d& th, Eigen::VectorXd& r, Eigen::Matrix<double, Eigen::Dynamic, 4>* J) const {
    if (J == nullptr) {
      th_trial = th;
      const bool ok = exact_problem->evaluate(Eigen::VectorXd(th), r, nullptr);
      r_trial = r;
      return ok;
    }
    if (!have || since_exact >= 1) {
      j_exact.resize(r.size(), 4);
      if (!exact_problem->evaluate(Eigen::VectorXd(th), r, &j_exact)) return false;
      j_last = j_exact;
      have = true;
      since_exact = 0;
    } else {
      if (r_trial.size() == r.size() && th_trial == th) r = r_trial;  // the accepted trial's residuals
      else if (!exact_problem->evaluate(Eigen::VectorXd(th), r, nullptr)) return false;
      const Eigen::Vector4d d = th - th_last;
      j_last += (r - r_last - j_last * d) * d.transpose() / d.squaredNorm();
      ++since_exact;
    }
    *J = j_last;
    th_last = th;
    r_last = r;
    return true;
  }
};

void Throttle_NlidBroyden(benchmark::State& state) {
  const auto problem = throttle_problem();
  nlid::LmSummary sum;
  int attempts = 0;
  for (auto _ : state) {
    BroydenThrottle b(&problem);
    Eigen::Vector4d th = throttle_theta0();
    attempts = 0;
    for (;;) {
      b.have = false;
      sum = nlid::solve_least_squares(b, th, lm_options(100 - attempts));
      attempts += sum.iterations;
      if (b.since_exact == 0 || attempts >= 100 || sum.status == nlid::LmStatus::max_iterations_reached) break;
    }
  }
  report(state, "Throttle_NlidBroyden", sum.final_cost, attempts);
}

// ---- Ceres -------------------------------------------------------------------------------------------------

#ifdef NLID_HAVE_CERES
template <int P, class F>
void run_ceres(benchmark::State& state, const std::string& key, F* functor, long residuals, const Eigen::VectorXd& start,
               int iterations) {
  ceres::Solver::Options options;
  options.minimizer_type = ceres::TRUST_REGION;
  options.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  // Normal equations + dense Cholesky, as nlid solves its steps (LDLT of JᵀJ + λD²): Ceres' fastest
  // dense solver here. DENSE_QR (used before 2026-11-25) made Ceres 17 % (nlarx5) and 29 % (nlhw2)
  // slower and so flattered the ratios (docs/performance.md).
  options.linear_solver_type = ceres::DENSE_NORMAL_CHOLESKY;
  options.max_num_iterations = iterations;
  options.num_threads = 1;
  options.logging_type = ceres::SILENT;
  // The tolerances nlid uses by default (LmOptions), so neither side stops early by fiat.
  options.function_tolerance = 1e-10;
  options.gradient_tolerance = 1e-10;
  options.parameter_tolerance = 1e-8;
  ceres::Solver::Summary summary;
  for (auto _ : state) {
    std::vector<double> th(start.data(), start.data() + start.size());
    ceres::Problem::Options po;
    po.cost_function_ownership = ceres::TAKE_OWNERSHIP;
    ceres::Problem problem(po);
    auto* cost = new ceres::AutoDiffCostFunction<F, ceres::DYNAMIC, P>(functor, static_cast<int>(residuals),
                                                                      ceres::DO_NOT_TAKE_OWNERSHIP);
    problem.AddResidualBlock(cost, nullptr, th.data());
    ceres::Solve(options, &problem, &summary);
  }
  report(state, key, summary.final_cost, static_cast<int>(summary.iterations.size()) - 1);
}

void Nlarx5_Sim_Ceres(benchmark::State& state) {
  const auto& s = nlarx5_setup();
  static perf::Nlarx5Residuals f(s.model, data12());
  const Nlarx5Functor nf(s.model, s.segs, {}, InitialCondition::measured, s.limit);
  check_same("nlarx5", nf, f, s.theta0);
  run_ceres<perf::kNlarx5Params>(state, "Nlarx5_Sim_Ceres", &f, nf.num_residuals(), s.theta0, 90);
}

void Nlhw2_Ceres(benchmark::State& state) {
  const auto& s = nlhw2_setup();
  static Nlhw2Residuals f{&data12()};
  const Nlhw2Functor nf(s.model, s.segs, {}, InitialCondition::zero, s.limit);
  check_same("nlhw2", nf, f, s.theta0);
  run_ceres<perf::kNlhw2Params>(state, "Nlhw2_Ceres", &f, nf.num_residuals(), s.theta0, 200);
}

void Throttle_Ceres(benchmark::State& state) {
  const auto problem = throttle_problem();
  const Eigen::VectorXd th0 = throttle_theta0();
  Eigen::VectorXd r(problem.num_residuals());
  if (!problem.evaluate(th0, r, nullptr)) fail("throttle: nlid residuals at the start");
  // nlid weights residuals by 1/std(y); read the weight off its residual vector.
  static ThrottleResiduals f{&data12(), 1.0};
  std::vector<double> raw(static_cast<std::size_t>(r.size()));
  f.weight = 1.0;
  f(th0.data(), raw.data());
  Eigen::Index best = 0;
  for (Eigen::Index i = 0; i < r.size(); ++i)
    if (std::abs(raw[static_cast<std::size_t>(i)]) > std::abs(raw[static_cast<std::size_t>(best)])) best = i;
  f.weight = r(best) / raw[static_cast<std::size_t>(best)];
  f(th0.data(), raw.data());
  const double worst = (r - Eigen::Map<const Eigen::VectorXd>(raw.data(), r.size())).cwiseAbs().maxCoeff();
  if (!(worst <= 1e-9 * (1 + r.cwiseAbs().maxCoeff()))) fail("throttle: nlid and Ceres residuals differ by " + std::to_string(worst));
  run_ceres<4>(state, "Throttle_Ceres", &f, r.size(), th0, 100);
}
#endif

}  // namespace

BENCHMARK(Nlarx5_Full_Nlid)->Unit(benchmark::kMillisecond)->Iterations(3);
BENCHMARK(Nlarx5_Sim_Nlid)->Unit(benchmark::kMillisecond)->Iterations(3);
BENCHMARK(Nlarx5_Sim_NlidForwardAD)->Unit(benchmark::kMillisecond)->Iterations(3);
#ifdef NLID_HAVE_CERES
BENCHMARK(Nlarx5_Sim_Ceres)->Unit(benchmark::kMillisecond)->Iterations(3);
#endif
BENCHMARK(Nlhw2_Nlid)->Unit(benchmark::kMillisecond)->Iterations(3);
BENCHMARK(Nlhw2_NlidForwardAD)->Unit(benchmark::kMillisecond)->Iterations(3);
BENCHMARK(Nlhw2_NlidCeresDamping)->Unit(benchmark::kMillisecond)->Iterations(3);
#ifdef NLID_HAVE_CERES
BENCHMARK(Nlhw2_Ceres)->Unit(benchmark::kMillisecond)->Iterations(3);
#endif
BENCHMARK(Throttle_Nlid)->Unit(benchmark::kMillisecond)->Iterations(3);
BENCHMARK(Throttle_NlidBroyden)->Unit(benchmark::kMillisecond)->Iterations(3);
#ifdef NLID_HAVE_CERES
BENCHMARK(Throttle_Ceres)->Unit(benchmark::kMillisecond)->Iterations(3);
#endif

int main(int argc, char** argv) {
  const int rc = perf::run_with_ratios(argc, argv,
                                       {
                                           {"nlarx5 simulation stage: nlid speed / Ceres speed", "Nlarx5_Sim_Nlid/iterations:3",
                                            "Nlarx5_Sim_Ceres/iterations:3", 2.0},
                                           {"nlarx5 stage, forward-AD Jacobian / Ceres",
                                            "Nlarx5_Sim_NlidForwardAD/iterations:3", "Nlarx5_Sim_Ceres/iterations:3", 0.0},
                                           {"nlhw2: nlid speed / Ceres speed", "Nlhw2_Nlid/iterations:3", "Nlhw2_Ceres/iterations:3", 2.0},
                                           {"nlhw2, Ceres' damping (same iterates) / Ceres",
                                            "Nlhw2_NlidCeresDamping/iterations:3", "Nlhw2_Ceres/iterations:3", 0.0},
                                           {"nlhw2, forward-AD Jacobian / Ceres", "Nlhw2_NlidForwardAD/iterations:3",
                                            "Nlhw2_Ceres/iterations:3", 0.0},
                                           {"throttle grey-box: nlid speed / Ceres speed", "Throttle_Nlid/iterations:3",
                                            "Throttle_Ceres/iterations:3", 2.0},
                                           {"throttle, Broyden experiment / Ceres", "Throttle_NlidBroyden/iterations:3",
                                            "Throttle_Ceres/iterations:3", 0.0},
                                       });
  const auto& c = final_costs();
  auto line = [&](const char* what, const char* a, const char* b, bool info = false) {
    if (!c.count(a) || !c.count(b)) return;
    const double x = c.at(a), y = c.at(b);
    const char* verdict = info ? "(info)" : x <= y * (1 + 1e-6) ? "MET (nlid <= Ceres)" : "MISSED";
    std::printf("%-58s nlid %.9g  Ceres %.9g  %s\n", what, x, y, verdict);
  };
  std::printf("\nfinal cost 1/2 sum r^2 (nlid must reach an equal or lower cost)\n");
  line("nlarx5 simulation stage", "Nlarx5_Sim_Nlid", "Nlarx5_Sim_Ceres");
  line("nlarx5 stage, forward-AD Jacobian", "Nlarx5_Sim_NlidForwardAD", "Nlarx5_Sim_Ceres");
  line("nlhw2", "Nlhw2_Nlid", "Nlhw2_Ceres");
  line("nlhw2, Ceres' damping (same iterates)", "Nlhw2_NlidCeresDamping", "Nlhw2_Ceres", true);
  line("throttle grey-box", "Throttle_Nlid", "Throttle_Ceres");
  line("throttle, Broyden experiment", "Throttle_NlidBroyden", "Throttle_Ceres", true);
  if (c.count("Nlarx5_Full_Nlid")) std::printf("%-58s %s\n", "nlarx5 full estimate() <= 1 s", "(see Nlarx5_Full_Nlid CPU time)");
  return rc;
}
