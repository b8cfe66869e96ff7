// Free-run simulation throughput (issue 5, items 1 and 2): the study's nlarx5-like, nlhw2-like
// and grey-box throttle models, each as
//
//   Fixed    the all-static nlid type (stack storage, compile-time sizes)
//   Dynamic  the Dynamic twin (orders/units/physics chosen at run time)
//   Hand     a plain hand-written loop of the same model — the one-trajectory limit
//   Batch<W> W parameter sets at once on nlid::Batch (core/batch.hpp), on the widest vector
//            registers of the CPU (run-time dispatch: AVX-512 code in the portable build too);
//            nlarx5 through nlid::simulate_batched, the call a user makes
//   BatchOwnIsa<W>  the same on the translation unit's own registers (no dispatch; 16 bytes in
//            the portable build), for comparison
//
// on 2000 samples of throttle input (data1 at 100 Hz). Counter samples/s counts simulated
// samples of all trajectories. The ratio table at the end checks the targets:
//   nlid fixed nlarx5 ≥ 0.9× hand loop and ≥ 3× the Dynamic twin;
//   batched ≥ 4× the single-trajectory throughput on one core.
// Results, machine and command: docs/performance.md.
#include <benchmark/benchmark.h>

#include <array>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/batch.hpp"
#include "nlid/models/greybox_dynamic.hpp"
#include "nlid/models/greybox_simulate.hpp"
#include "nlid/models/integrators.hpp"
#include "perf_models.hpp"

namespace {

const Eigen::MatrixXd& input() {
  static const Eigen::MatrixXd u = perf::throttle_data(1).u();
  return u;
}

void count(benchmark::State& state, double samples_per_iteration) {
  state.counters["samples/s"] =
      benchmark::Counter(samples_per_iteration * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}

// One free run of the input record per iteration, any model with the uniform simulate API.
template <class Model>
void run_model(benchmark::State& state, const Model& m) {
  const Eigen::MatrixXd& u = input();
  const Eigen::VectorXd th = m.parameters();
  std::vector<double> y(static_cast<std::size_t>(u.rows()));
  for (auto _ : state) {
    const bool ok = m.simulate(u, std::span<const double>(th.data(), static_cast<std::size_t>(th.size())),
                               std::span<const double>(), std::span<double>(y));
    benchmark::DoNotOptimize(ok);
    benchmark::DoNotOptimize(y.data());
  }
  count(state, static_cast<double>(u.rows()));
}

// Counter reg_bytes: the register width a batched benchmark ran on (0 asked for the widest).
void count_registers(benchmark::State& state, std::size_t register_bytes) {
  state.counters["reg_bytes"] = static_cast<double>(register_bytes == 0 ? nlid::cpu_register_bytes() : register_bytes);
}

// ---- nlarx5 -------------------------------------------------------------------------------------

void Nlarx5_Fixed(benchmark::State& state) { run_model(state, perf::make_nlarx5()); }
void Nlarx5_Dynamic(benchmark::State& state) { run_model(state, perf::make_nlarx5_dynamic()); }
void Nlarx5_Hand(benchmark::State& state) {
  const Eigen::MatrixXd& u = input();
  const perf::HandNlarx5 hand(perf::nlarx5_theta());
  std::vector<double> y(static_cast<std::size_t>(u.rows()));
  for (auto _ : state) {
    hand.simulate(u.data(), u.rows(), y.data());
    benchmark::DoNotOptimize(y.data());
  }
  count(state, static_cast<double>(u.rows()));
}

// W parameter sets (the estimate perturbed, as in a Monte-Carlo study) in one batch, through
// nlid::simulate_batched (packing the parameter sets and unpacking the outputs included), on
// registers of `register_bytes` (0: the widest the CPU has).
template <int W>
void run_nlarx5_batch(benchmark::State& state, std::size_t register_bytes) {
  const Eigen::MatrixXd& u = input();
  const perf::Nlarx5 m = perf::make_nlarx5();
  const Eigen::VectorXd th = m.parameters();
  Eigen::MatrixXd thetas(th.size(), W);
  for (int w = 0; w < W; ++w) thetas.col(w) = th * (1.0 + 1e-3 * w);
  for (auto _ : state) {
    const Eigen::MatrixXd y = nlid::simulate_batched<W>(m, u, thetas, Eigen::MatrixXd(), register_bytes);
    benchmark::DoNotOptimize(y.data());
  }
  count(state, static_cast<double>(u.rows()) * W);
  count_registers(state, register_bytes);
}
template <int W>
void Nlarx5_Batch(benchmark::State& state) {
  run_nlarx5_batch<W>(state, 0);
}
template <int W>
void Nlarx5_BatchOwnIsa(benchmark::State& state) {
  run_nlarx5_batch<W>(state, nlid::default_register_bytes);
}

// ---- nlhw2 ----------------------------------------------------------------------------------------

void Nlhw2_Fixed(benchmark::State& state) { run_model(state, perf::make_nlhw2()); }
void Nlhw2_Dynamic(benchmark::State& state) { run_model(state, perf::make_nlhw2_dynamic()); }
void Nlhw2_Hand(benchmark::State& state) {
  const Eigen::MatrixXd& u = input();
  const perf::HandNlhw2 hand(perf::nlhw2_theta());
  std::vector<double> y(static_cast<std::size_t>(u.rows()));
  for (auto _ : state) {
    hand.simulate(u.data(), u.rows(), y.data());
    benchmark::DoNotOptimize(y.data());
  }
  count(state, static_cast<double>(u.rows()));
}

// ---- grey-box throttle (RK4, 2 sub-steps per 10 ms sample from the stability rule) ----------------

constexpr double kTs = 0.01;

int throttle_substeps() {
  const auto p = perf::throttle_theta();
  return nlid::substeps_for(kTs, perf::StudyThrottle{}.spectral_radius(p.data()), nlid::IntegratorOptions{});
}

template <class Physics>
void run_throttle(benchmark::State& state, const Physics& phys) {
  const Eigen::MatrixXd& u = input();
  const auto p = perf::throttle_theta();
  const int sub = throttle_substeps();
  const nlid::IntegratorOptions opt;
  std::vector<double> y(static_cast<std::size_t>(u.rows()));
  for (auto _ : state) {
    double x[2] = {15.0, 0.0};
    const auto n = nlid::simulate_physics<double>(phys, opt, sub, u, kTs, p.data(), x,
                                                  [&](Eigen::Index k, const double* v) { y[static_cast<std::size_t>(k)] = v[0]; });
    benchmark::DoNotOptimize(n);
    benchmark::DoNotOptimize(y.data());
  }
  count(state, static_cast<double>(u.rows()));
  state.counters["substeps"] = sub;
}

void Throttle_Fixed(benchmark::State& state) { run_throttle(state, perf::StudyThrottle{}); }
void Throttle_Dynamic(benchmark::State& state) { run_throttle(state, nlid::AnyPhysics::from(perf::StudyThrottle{})); }
void Throttle_Hand(benchmark::State& state) {
  const Eigen::MatrixXd& u = input();
  const auto p = perf::throttle_theta();
  const int sub = throttle_substeps();
  std::vector<double> y(static_cast<std::size_t>(u.rows()));
  for (auto _ : state) {
    double x[2] = {15.0, 0.0};
    perf::hand_throttle(p.data(), u.data(), u.rows(), kTs, sub, x, y.data());
    benchmark::DoNotOptimize(y.data());
  }
  count(state, static_cast<double>(u.rows()));
}

// W parameter sets of the physics in one batch: simulate_physics on Batch<double, W, R> with R
// from nlid::with_register_bytes (0: the widest registers of the CPU), as a user would write it.
template <int W>
void run_throttle_batch(benchmark::State& state, std::size_t register_bytes) {
  const Eigen::MatrixXd& u = input();
  const auto p = perf::throttle_theta();
  const int sub = throttle_substeps();
  const nlid::IntegratorOptions opt;
  nlid::with_register_bytes(
      [&]<std::size_t R>() {
        using B = nlid::Batch<double, W, R>;
        std::array<B, 4> pb;
        for (int j = 0; j < 4; ++j)
          for (int w = 0; w < W; ++w) pb[static_cast<std::size_t>(j)][w] = p[static_cast<std::size_t>(j)] * (1.0 + 1e-3 * w);
        std::vector<B> y(static_cast<std::size_t>(u.rows()));
        for (auto _ : state) {
          B x[2] = {B(15.0), B(0.0)};
          const auto n = nlid::simulate_physics<B>(perf::StudyThrottle{}, opt, sub, u, kTs, pb.data(), x,
                                                   [&](Eigen::Index k, const B* v) { y[static_cast<std::size_t>(k)] = v[0]; });
          benchmark::DoNotOptimize(n);
          benchmark::DoNotOptimize(y.data());
        }
      },
      register_bytes);
  count(state, static_cast<double>(u.rows()) * W);
  count_registers(state, register_bytes);
}
template <int W>
void Throttle_Batch(benchmark::State& state) {
  run_throttle_batch<W>(state, 0);
}
template <int W>
void Throttle_BatchOwnIsa(benchmark::State& state) {
  run_throttle_batch<W>(state, nlid::default_register_bytes);
}

}  // namespace

BENCHMARK(Nlarx5_Fixed);
BENCHMARK(Nlarx5_Dynamic);
BENCHMARK(Nlarx5_Hand);
BENCHMARK_TEMPLATE(Nlarx5_Batch, 4);
BENCHMARK_TEMPLATE(Nlarx5_Batch, 8);
BENCHMARK_TEMPLATE(Nlarx5_Batch, 16);
BENCHMARK_TEMPLATE(Nlarx5_BatchOwnIsa, 8);
BENCHMARK(Nlhw2_Fixed);
BENCHMARK(Nlhw2_Dynamic);
BENCHMARK(Nlhw2_Hand);
BENCHMARK(Throttle_Fixed);
BENCHMARK(Throttle_Dynamic);
BENCHMARK(Throttle_Hand);
BENCHMARK_TEMPLATE(Throttle_Batch, 4);
BENCHMARK_TEMPLATE(Throttle_Batch, 8);
BENCHMARK_TEMPLATE(Throttle_Batch, 16);
BENCHMARK_TEMPLATE(Throttle_BatchOwnIsa, 8);

int main(int argc, char** argv) {
  return perf::run_with_ratios(
      argc, argv,
      {
          {"nlarx5: nlid fixed / hand-written loop", "Nlarx5_Fixed", "Nlarx5_Hand", 0.9},
          {"nlarx5: nlid fixed / Dynamic twin", "Nlarx5_Fixed", "Nlarx5_Dynamic", 3.0},
          {"nlarx5: Batch<double,4> / single fixed", "Nlarx5_Batch<4>", "Nlarx5_Fixed", 0.0},
          {"nlarx5: Batch<double,8> / single fixed", "Nlarx5_Batch<8>", "Nlarx5_Fixed", 4.0},
          {"nlarx5: Batch<double,16> / single fixed", "Nlarx5_Batch<16>", "Nlarx5_Fixed", 0.0},
          {"nlarx5: Batch<double,8> / hand-written loop", "Nlarx5_Batch<8>", "Nlarx5_Hand", 0.0},
          {"nlarx5: Batch<double,8>, own ISA / single fixed", "Nlarx5_BatchOwnIsa<8>", "Nlarx5_Fixed", 0.0},
          {"nlhw2: nlid fixed / hand-written loop", "Nlhw2_Fixed", "Nlhw2_Hand", 0.0},
          {"nlhw2: nlid fixed / Dynamic twin", "Nlhw2_Fixed", "Nlhw2_Dynamic", 0.0},
          {"throttle RK4: nlid fixed / hand-written loop", "Throttle_Fixed", "Throttle_Hand", 0.0},
          {"throttle RK4: nlid fixed / Dynamic twin", "Throttle_Fixed", "Throttle_Dynamic", 0.0},
          {"throttle RK4: Batch<double,4> / single fixed", "Throttle_Batch<4>", "Throttle_Fixed", 0.0},
          {"throttle RK4: Batch<double,8> / single fixed", "Throttle_Batch<8>", "Throttle_Fixed", 4.0},
          {"throttle RK4: Batch<double,16> / single fixed", "Throttle_Batch<16>", "Throttle_Fixed", 0.0},
          {"throttle RK4: Batch<double,8>, own ISA / single fixed", "Throttle_BatchOwnIsa<8>", "Throttle_Fixed", 0.0},
      });
}
