// Jacobian evaluation (issue 5, item 4): the 1997 × 47 Jacobian of nlarx5's free-run simulation
// residuals on data1 (100 Hz, measured initial past), one forward-mode pass seeding all 47
// parameters, with three dual-number types on the *same* templated residual code
// (perf::Nlarx5Residuals), plus nlid's model path:
//
//   NlidDual        nlid::Dual<double, 47>
//   EigenAutoDiff   Eigen::AutoDiffScalar<Eigen::Matrix<double, 47, 1>>
//   CeresJet        ceres::Jet<double, 47>                        (if Ceres is installed)
//   NlidModel       nlid::AutoDiffProblem over Nlarx::simulate (forward AD through the model)
//   NlidStructured  the structured simulation Jacobian — what estimate() runs for this model
//   Residuals       the same functor on double (no Jacobian): the floor
//
// Results, machine and command: docs/performance.md.
#include <benchmark/benchmark.h>

#include <vector>

#include <Eigen/Core>
#include <unsupported/Eigen/AutoDiff>

#include "nlid/ad/dual.hpp"
#include "nlid/estimation/autodiff.hpp"
#include "nlid/models/estimate.hpp"
#include "perf_models.hpp"

#ifdef NLID_HAVE_CERES
#include <ceres/jet.h>
#endif

namespace {

constexpr int P = perf::kNlarx5Params;

struct Setup {
  nlid::Dataset data;
  perf::Nlarx5 model;
  Eigen::VectorXd theta;
  std::vector<nlid::detail::EstimationSegment> segs;
  long m = 0;
};

const Setup& setup() {
  static const Setup s = [] {
    Setup st;
    st.data = nlid::Dataset(perf::throttle_data(1));
    nlid::EstimateOptions o;
    o.solver.max_iterations = 5;  // a realistic θ (prediction focus, a few iterations)
    st.model = nlid::estimate(perf::Nlarx5{}, st.data, o);
    st.theta = st.model.parameters();
    nlid::detail::EstimationSegment seg;
    seg.u = &st.data[0].u();
    seg.y = st.data[0].y().col(0);
    seg.start = st.model.history_length();
    seg.x0 = st.model.measured_state(*seg.u, seg.y, seg.start);
    st.segs.push_back(seg);
    st.m = st.data[0].size() - seg.start;
    return st;
  }();
  return s;
}

// One pass of the templated residuals on a dual type D; `seed(x, k)` makes θ_k a variable,
// `deriv(r, k)` reads ∂r/∂θ_k.
template <class D, class Seed, class Deriv>
void run_dual(benchmark::State& state, Seed seed, Deriv deriv) {
  const Setup& s = setup();
  const perf::Nlarx5Residuals f(s.model, s.data);
  std::vector<D> th(P), r(static_cast<std::size_t>(s.m));
  for (int k = 0; k < P; ++k) th[static_cast<std::size_t>(k)] = seed(s.theta(k), k);
  Eigen::MatrixXd J(s.m, P);
  for (auto _ : state) {
    f(th.data(), r.data());
    for (long i = 0; i < s.m; ++i)
      for (int k = 0; k < P; ++k) J(i, k) = deriv(r[static_cast<std::size_t>(i)], k);
    benchmark::DoNotOptimize(J.data());
  }
  state.counters["samples/s"] = benchmark::Counter(static_cast<double>(s.m) * static_cast<double>(state.iterations()),
                                                   benchmark::Counter::kIsRate);
}

void NlidDual(benchmark::State& state) {
  using D = nlid::Dual<double, P>;
  run_dual<D>(state, [](double x, int k) { return D::variable(x, k, P); }, [](const D& r, int k) { return r.v[k]; });
}

void EigenAutoDiff(benchmark::State& state) {
  using D = Eigen::AutoDiffScalar<Eigen::Matrix<double, P, 1>>;
  run_dual<D>(
      state, [](double x, int k) { return D(x, P, k); }, [](const D& r, int k) { return r.derivatives()(k); });
}

#ifdef NLID_HAVE_CERES
void CeresJet(benchmark::State& state) {
  using D = ceres::Jet<double, P>;
  run_dual<D>(state, [](double x, int k) { return D(x, k); }, [](const D& r, int k) { return r.v[k]; });
}
#endif

// One full Jacobian per iteration of a problem built on the setup's segments.
template <class Problem>
void run_problem(benchmark::State& state, const Problem& problem) {
  const Setup& s = setup();
  Eigen::Matrix<double, P, 1> th = s.theta;
  Eigen::VectorXd r(s.m);
  Eigen::Matrix<double, Eigen::Dynamic, P> J(s.m, P);
  for (auto _ : state) {
    const bool ok = problem.evaluate(th, r, &J);
    benchmark::DoNotOptimize(ok);
    benchmark::DoNotOptimize(J.data());
  }
  state.counters["samples/s"] = benchmark::Counter(static_cast<double>(s.m) * static_cast<double>(state.iterations()),
                                                   benchmark::Counter::kIsRate);
}

void NlidModel(benchmark::State& state) {
  const Setup& s = setup();
  using F = nlid::detail::SimulationResiduals<perf::Nlarx5, P>;
  run_problem(state, nlid::AutoDiffProblem<F>(F(s.model, s.segs, {}, nlid::InitialCondition::measured, 1e12)));
}

// What estimate() runs for this structure: the structured simulation Jacobian
// (models/detail/nlarx_sensitivity.hpp), one analytic network gradient per sample.
void NlidStructured(benchmark::State& state) {
  const Setup& s = setup();
  run_problem(state, nlid::detail::NlarxSimulationProblem<perf::Nlarx5, P>(s.model, s.segs, {},
                                                                           nlid::InitialCondition::measured, 1e12));
}

void Residuals(benchmark::State& state) {
  const Setup& s = setup();
  const perf::Nlarx5Residuals f(s.model, s.data);
  std::vector<double> r(static_cast<std::size_t>(s.m));
  for (auto _ : state) {
    f(s.theta.data(), r.data());
    benchmark::DoNotOptimize(r.data());
  }
  state.counters["samples/s"] = benchmark::Counter(static_cast<double>(s.m) * static_cast<double>(state.iterations()),
                                                   benchmark::Counter::kIsRate);
}

}  // namespace

BENCHMARK(NlidDual)->Unit(benchmark::kMicrosecond);
BENCHMARK(EigenAutoDiff)->Unit(benchmark::kMicrosecond);
#ifdef NLID_HAVE_CERES
BENCHMARK(CeresJet)->Unit(benchmark::kMicrosecond);
#endif
BENCHMARK(NlidModel)->Unit(benchmark::kMicrosecond);
BENCHMARK(NlidStructured)->Unit(benchmark::kMicrosecond);
BENCHMARK(Residuals)->Unit(benchmark::kMicrosecond);

int main(int argc, char** argv) {
  return perf::run_with_ratios(argc, argv,
                               {
                                   {"nlid Dual / Eigen AutoDiffScalar (same functor)", "NlidDual", "EigenAutoDiff", 0.0},
                                   {"nlid Dual / Ceres Jet (same functor)", "NlidDual", "CeresJet", 0.0},
                                   {"nlid model path / Ceres Jet functor", "NlidModel", "CeresJet", 0.0},
                                   {"nlid structured Jacobian / Ceres Jet functor", "NlidStructured", "CeresJet", 0.0},
                                   {"nlid structured Jacobian / nlid model path (forward AD)", "NlidStructured", "NlidModel", 0.0},
                                   {"Jacobian / residuals-only (cost of 47 derivatives)", "NlidModel", "Residuals", 0.0},
                                   {"structured Jacobian / residuals-only", "NlidStructured", "Residuals", 0.0},
                               });
}
