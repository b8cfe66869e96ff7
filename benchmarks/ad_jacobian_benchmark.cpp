// Jacobian of one residual function, computed seven ways, over a sweep of parameter counts.
//
// The function: a one-input sigmoid network with K units fitted to m = 1000 samples,
//
//     rᵢ(θ) = d + Σ_k a_k σ(b_k xᵢ + c_k) − yᵢ,   θ = (a_k, b_k, c_k)_k, d;   n = 3K + 1,
//
// the shape of the study's nonlinearity (nlarx4/nlarx5) evaluated over a data record. For
// K = 3, 8, 16 (n = 10, 25, 49) we time one full m × n Jacobian:
//
//   NlidFixed        AutoDiffProblem, static n: one pass on Dual<double, n>
//   NlidChunked<C>   AutoDiffProblem, Dynamic n: ⌈n/C⌉ passes on Dual<double, C>
//   NlidDynamicDual  one pass on DynamicDual<double> (heap-allocating gradient per operation)
//   EigenAdFixed     one pass on Eigen::AutoDiffScalar<Matrix<double, n, 1>>
//   EigenAdDynamic   one pass on Eigen::AutoDiffScalar<VectorXd>
//   NumericCentral   NumericDiffProblem: 2n residual evaluations
//   Analytic         hand-written Jacobian (lower bound), and Residuals (r only, no J)
//
// Results, machine and exact command: docs/performance.md.
#include <benchmark/benchmark.h>

#include <cmath>
#include <span>
#include <vector>

#include <Eigen/Core>
#include <unsupported/Eigen/AutoDiff>

#include "nlid/estimation.hpp"

namespace {

constexpr int kSamples = 1000;

// Residuals of the network; generic over the scalar (double, nlid::Dual, Eigen::AutoDiffScalar).
template <class T>
void network_residuals(const Eigen::VectorXd& x, const Eigen::VectorXd& y, int units,
                       std::span<const T> th, std::span<T> r) {
  using std::exp;
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    T g = th[static_cast<std::size_t>(3 * units)];
    for (int k = 0; k < units; ++k) {
      const std::size_t j = static_cast<std::size_t>(3 * k);
      const T s = th[j + 1] * x[i] + th[j + 2];
      g += th[j] / (1.0 + exp(-s));
    }
    r[static_cast<std::size_t>(i)] = g - y[i];
  }
}

struct Data {
  Eigen::VectorXd x, y;
  explicit Data(int m) : x(m), y(m) {
    for (int i = 0; i < m; ++i) {
      x[i] = -2.0 + 4.0 * i / (m - 1);
      y[i] = std::tanh(1.5 * x[i]) + 0.3 * x[i] * x[i];
    }
  }
};

// Residual functor with a static or dynamic parameter count P (n = 3K + 1 either way).
template <int K, int P>
struct Network {
  static constexpr int num_params = P;
  Data data{kSamples};
  int num_parameters() const { return 3 * K + 1; }
  Eigen::Index num_residuals() const { return data.x.size(); }
  template <class T>
  bool residuals(std::span<const T> th, std::span<T> r) const {
    network_residuals(data.x, data.y, K, th, r);
    return true;
  }
};

template <int K>
Eigen::VectorXd start_theta() {
  Eigen::VectorXd th(3 * K + 1);
  for (int k = 0; k < th.size(); ++k) th[k] = 0.3 * std::sin(1.7 * k + 0.4) + 0.5;
  return th;
}

template <int K>
void NlidFixed(benchmark::State& state) {
  constexpr int n = 3 * K + 1;
  nlid::AutoDiffProblem problem(Network<K, n>{});
  const Eigen::Matrix<double, n, 1> th = start_theta<K>();
  Eigen::VectorXd r(kSamples);
  nlid::JacobianMatrix<n> J(kSamples, n);
  for (auto _ : state) {
    problem.evaluate(th, r, &J);
    benchmark::DoNotOptimize(J.data());
    benchmark::ClobberMemory();
  }
  state.counters["n"] = n;
}

template <int K, int C>
void NlidChunked(benchmark::State& state) {
  constexpr int n = 3 * K + 1;
  nlid::AutoDiffProblem<Network<K, nlid::Dynamic>, C> problem(Network<K, nlid::Dynamic>{});
  const Eigen::VectorXd th = start_theta<K>();
  Eigen::VectorXd r(kSamples);
  Eigen::MatrixXd J(kSamples, n);
  for (auto _ : state) {
    problem.evaluate(th, r, &J);
    benchmark::DoNotOptimize(J.data());
    benchmark::ClobberMemory();
  }
  state.counters["n"] = n;
}

template <int K>
void NlidDynamicDual(benchmark::State& state) {
  constexpr int n = 3 * K + 1;
  using D = nlid::DynamicDual<double>;
  const Data data(kSamples);
  const Eigen::VectorXd th0 = start_theta<K>();
  std::vector<D> th(n), r(kSamples);
  Eigen::MatrixXd J(kSamples, n);
  for (auto _ : state) {
    for (int k = 0; k < n; ++k) th[k] = D::variable(th0[k], k, n);
    network_residuals<D>(data.x, data.y, K, th, r);
    for (int i = 0; i < kSamples; ++i) J.row(i) = r[i].v.transpose();
    benchmark::DoNotOptimize(J.data());
    benchmark::ClobberMemory();
  }
  state.counters["n"] = n;
}

template <int K, class Derivative>
void eigen_autodiff(benchmark::State& state) {
  constexpr int n = 3 * K + 1;
  using AD = Eigen::AutoDiffScalar<Derivative>;
  const Data data(kSamples);
  const Eigen::VectorXd th0 = start_theta<K>();
  std::vector<AD> th(n), r(kSamples);
  Eigen::MatrixXd J(kSamples, n);
  for (auto _ : state) {
    for (int k = 0; k < n; ++k) th[k] = AD(th0[k], n, k);
    network_residuals<AD>(data.x, data.y, K, th, r);
    for (int i = 0; i < kSamples; ++i) J.row(i) = r[i].derivatives().transpose();
    benchmark::DoNotOptimize(J.data());
    benchmark::ClobberMemory();
  }
  state.counters["n"] = n;
}

template <int K>
void EigenAdFixed(benchmark::State& state) {
  eigen_autodiff<K, Eigen::Matrix<double, 3 * K + 1, 1>>(state);
}

template <int K>
void EigenAdDynamic(benchmark::State& state) {
  eigen_autodiff<K, Eigen::VectorXd>(state);
}

template <int K>
void NumericCentral(benchmark::State& state) {
  constexpr int n = 3 * K + 1;
  nlid::NumericDiffProblem problem(Network<K, n>{});
  const Eigen::Matrix<double, n, 1> th = start_theta<K>();
  Eigen::VectorXd r(kSamples);
  nlid::JacobianMatrix<n> J(kSamples, n);
  for (auto _ : state) {
    problem.evaluate(th, r, &J);
    benchmark::DoNotOptimize(J.data());
    benchmark::ClobberMemory();
  }
  state.counters["n"] = n;
}

// Hand-derived: ∂r/∂a_k = σ_k, ∂r/∂b_k = a_k σ_k(1 − σ_k) x, ∂r/∂c_k = a_k σ_k(1 − σ_k), ∂r/∂d = 1.
template <int K>
void Analytic(benchmark::State& state) {
  constexpr int n = 3 * K + 1;
  const Data data(kSamples);
  const Eigen::VectorXd th = start_theta<K>();
  Eigen::VectorXd r(kSamples);
  nlid::JacobianMatrix<n> J(kSamples, n);
  for (auto _ : state) {
    for (int i = 0; i < kSamples; ++i) {
      const double xi = data.x[i];
      double g = th[3 * K];
      for (int k = 0; k < K; ++k) {
        const double sg = 1.0 / (1.0 + std::exp(-(th[3 * k + 1] * xi + th[3 * k + 2])));
        const double ds = th[3 * k] * sg * (1.0 - sg);
        g += th[3 * k] * sg;
        J(i, 3 * k) = sg;
        J(i, 3 * k + 1) = ds * xi;
        J(i, 3 * k + 2) = ds;
      }
      J(i, 3 * K) = 1.0;
      r[i] = g - data.y[i];
    }
    benchmark::DoNotOptimize(J.data());
    benchmark::ClobberMemory();
  }
  state.counters["n"] = n;
}

template <int K>
void Residuals(benchmark::State& state) {
  constexpr int n = 3 * K + 1;
  nlid::AutoDiffProblem problem(Network<K, n>{});
  const Eigen::Matrix<double, n, 1> th = start_theta<K>();
  Eigen::VectorXd r(kSamples);
  for (auto _ : state) {
    problem.evaluate(th, r, nullptr);
    benchmark::DoNotOptimize(r.data());
    benchmark::ClobberMemory();
  }
  state.counters["n"] = n;
}

}  // namespace

#define NLID_SWEEP(fn)              \
  BENCHMARK_TEMPLATE(fn, 3)->Unit(benchmark::kMicrosecond);  \
  BENCHMARK_TEMPLATE(fn, 8)->Unit(benchmark::kMicrosecond);  \
  BENCHMARK_TEMPLATE(fn, 16)->Unit(benchmark::kMicrosecond);

NLID_SWEEP(Residuals)
NLID_SWEEP(Analytic)
NLID_SWEEP(NlidFixed)
BENCHMARK_TEMPLATE(NlidChunked, 3, 4)->Unit(benchmark::kMicrosecond);
BENCHMARK_TEMPLATE(NlidChunked, 3, 8)->Unit(benchmark::kMicrosecond);
BENCHMARK_TEMPLATE(NlidChunked, 3, 16)->Unit(benchmark::kMicrosecond);
BENCHMARK_TEMPLATE(NlidChunked, 8, 4)->Unit(benchmark::kMicrosecond);
BENCHMARK_TEMPLATE(NlidChunked, 8, 8)->Unit(benchmark::kMicrosecond);
BENCHMARK_TEMPLATE(NlidChunked, 8, 16)->Unit(benchmark::kMicrosecond);
BENCHMARK_TEMPLATE(NlidChunked, 16, 4)->Unit(benchmark::kMicrosecond);
BENCHMARK_TEMPLATE(NlidChunked, 16, 8)->Unit(benchmark::kMicrosecond);
BENCHMARK_TEMPLATE(NlidChunked, 16, 16)->Unit(benchmark::kMicrosecond);
NLID_SWEEP(NlidDynamicDual)
NLID_SWEEP(EigenAdFixed)
NLID_SWEEP(EigenAdDynamic)
NLID_SWEEP(NumericCentral)

BENCHMARK_MAIN();
