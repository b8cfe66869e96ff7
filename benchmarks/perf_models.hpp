// Shared pieces of the performance benchmarks (issue 5): the study's model structures with
// fixed parameter values, hand-written loops of the same models (the one-trajectory "limit"),
// the throttle data at 100 Hz, and a reporter that prints ratios against the targets at the
// end of a run, so each target is defended in the benchmark output itself.
#pragma once

#include <benchmark/benchmark.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <map>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "nlid/data/csv.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/data/resample.hpp"
#include "nlid/models/greybox_concepts.hpp"
#include "nlid/models/hammerstein_wiener.hpp"
#include "nlid/models/nlarx.hpp"
#include "nlid/models/transfer_function_block.hpp"
#include "nlid/nonlinearities/piecewise_linear.hpp"
#include "nlid/nonlinearities/sigmoid_network.hpp"
#include "nlid/regressors/lagged.hpp"
#include "../tests/support/study_throttle.hpp"

namespace perf {

using nlid::Dynamic;

// ---- data ----------------------------------------------------------------------------------------

/// Throttle experiment `k` (1..5) decimated to 100 Hz as in the study: 2000 samples.
inline nlid::Experiment throttle_data(int k) {
  const nlid::Experiment e =
      nlid::read_csv(std::string(NLID_EXAMPLE_DATA_DIR) + "/throttle/data" + std::to_string(k) + ".csv");
  return nlid::decimate(e, 10);
}

// ---- nlarx5: [3 3 0] regressors, sigmoid network with 5 units and a linear term -----------------

using Nlarx5 = nlid::Nlarx<nlid::LaggedRegressors<3, 3, 0>, nlid::SigmoidNet<6, 5>>;
using Nlarx5Dyn = nlid::Nlarx<nlid::LaggedRegressors<Dynamic, Dynamic, Dynamic>, nlid::SigmoidNet<Dynamic, Dynamic>>;
inline constexpr int kNlarx5Params = nlid::SigmoidNet<6, 5>::num_params;  // 6 + 1 + 5·8 = 47

/// Regressor centre and scale of a throttle-like record (y in degrees, u normalised).
inline Eigen::VectorXd nlarx5_center() { return (Eigen::VectorXd(6) << 50, 50, 50, 0.5, 0.5, 0.5).finished(); }
inline Eigen::VectorXd nlarx5_scale() { return (Eigen::VectorXd(6) << 25, 25, 25, 0.3, 0.3, 0.3).finished(); }

/// A stable nlarx5 parameter vector: linear part y = 1.5y₁ − 0.7y₂ + 0.1y₃ + 4u + 2.5u₁ + u₂
/// (gain 75°/unit, poles inside the unit circle) in standardised units, plus five bounded
/// sigmoid units with fixed pseudo-random weights.
inline Eigen::VectorXd nlarx5_theta() {
  Eigen::VectorXd th(kNlarx5Params);
  const Eigen::VectorXd s = nlarx5_scale();
  const double lin[6] = {1.5, -0.7, 0.1, 4.0, 2.5, 1.0};
  for (int j = 0; j < 6; ++j) th(j) = lin[j] * s(j);
  th(6) = 50.0;  // d: steady state 50° at u = 0.5
  for (int k = 0; k < 5; ++k) th(7 + k) = 1.5 * std::sin(1.3 * k + 0.2);                        // a
  for (int i = 0; i < 30; ++i) th(12 + i) = 0.6 * std::sin(0.77 * i + 0.5);                     // b
  for (int k = 0; k < 5; ++k) th(42 + k) = 0.4 * std::cos(2.1 * k);                             // c
  return th;
}

/// nlarx5 with the fixed structure (all sizes static) and normalisation set.
inline Nlarx5 make_nlarx5() {
  Nlarx5 m;
  m.nonlinearity().set_normalization(nlarx5_center(), nlarx5_scale());
  m.set_parameters(nlarx5_theta());
  return m;
}

/// The Dynamic twin: orders and units chosen at run time.
inline Nlarx5Dyn make_nlarx5_dynamic() {
  Nlarx5Dyn m(nlid::LaggedRegressors<Dynamic, Dynamic, Dynamic>(3, 3, 0), nlid::SigmoidNet<Dynamic, Dynamic>(6, 5));
  m.nonlinearity().set_normalization(nlarx5_center(), nlarx5_scale());
  m.set_parameters(nlarx5_theta());
  return m;
}

/// The same model written by hand: plain arrays, compile-time loop bounds, the same logistic.
struct HandNlarx5 {
  double L[6], d, a[5], b[5][6], c[5], r[6], is[6];
  explicit HandNlarx5(const Eigen::VectorXd& th) {
    for (int j = 0; j < 6; ++j) L[j] = th(j);
    d = th(6);
    for (int k = 0; k < 5; ++k) a[k] = th(7 + k);
    for (int k = 0; k < 5; ++k)
      for (int j = 0; j < 6; ++j) b[k][j] = th(12 + 6 * k + j);
    for (int k = 0; k < 5; ++k) c[k] = th(42 + k);
    const Eigen::VectorXd cr = nlarx5_center(), sc = nlarx5_scale();
    for (int j = 0; j < 6; ++j) {
      r[j] = cr(j);
      is[j] = 1.0 / sc(j);
    }
  }
  static double logistic(double s) {
    if (s >= 0) return 1.0 / (1.0 + std::exp(-s));
    const double e = std::exp(s);
    return e / (1.0 + e);
  }
  /// Free run from a zero past.
  void simulate(const double* u, long n, double* y) const {
    double y1 = 0, y2 = 0, y3 = 0, u1 = 0, u2 = 0;
    for (long t = 0; t < n; ++t) {
      const double x[6] = {y1, y2, y3, u[t], u1, u2};
      double z[6];
      for (int j = 0; j < 6; ++j) z[j] = (x[j] - r[j]) * is[j];
      double g = d;
      for (int j = 0; j < 6; ++j) g += L[j] * z[j];
      for (int k = 0; k < 5; ++k) {
        double s = c[k];
        for (int j = 0; j < 6; ++j) s += b[k][j] * z[j];
        g += a[k] * logistic(s);
      }
      y3 = y2;
      y2 = y1;
      y1 = g;
      u2 = u1;
      u1 = u[t];
      y[t] = g;
    }
  }
};

/// The same simulation residuals as a templated functor (Ceres style, any scalar): nlarx5 free run from the measured past, r(t) = ŷ(t) − y(t) for t = 3 … N−1 per experiment.
struct Nlarx5Residuals {
  const nlid::Dataset* data;
  double r[6], is[6];
  explicit Nlarx5Residuals(const Nlarx5& m, const nlid::Dataset& d) : data(&d) {
    for (int j = 0; j < 6; ++j) {
      r[j] = m.nonlinearity().center()(j);
      is[j] = 1.0 / m.nonlinearity().scale()(j);
    }
  }
  template <class T>
  static T logistic(const T& s) {
    using std::exp;
    if (s >= 0.0) return T(1.0) / (T(1.0) + exp(-s));
    const T e = exp(s);
    return e / (T(1.0) + e);
  }
  template <class T>
  bool operator()(const T* th, T* res) const {
    long off = 0;
    for (const auto& e : *data) {
      const Eigen::MatrixXd& u = e.u();
      const Eigen::MatrixXd& y = e.y();
      T y1(y(2, 0)), y2(y(1, 0)), y3(y(0, 0));
      double u1 = u(2, 0), u2 = u(1, 0);
      for (Eigen::Index t = 3; t < u.rows(); ++t) {
        const T x[6] = {y1, y2, y3, T(u(t, 0)), T(u1), T(u2)};
        T z[6];
        for (int j = 0; j < 6; ++j) z[j] = (x[j] - r[j]) * is[j];
        T g = th[6];
        for (int j = 0; j < 6; ++j) g += th[j] * z[j];
        for (int k = 0; k < 5; ++k) {
          T s = th[42 + k];
          for (int j = 0; j < 6; ++j) s += th[12 + 6 * k + j] * z[j];
          g += th[7 + k] * logistic(s);
        }
        y3 = y2;
        y2 = y1;
        y1 = g;
        u2 = u1;
        u1 = u(t, 0);
        res[off++] = g - y(t, 0);
      }
    }
    return true;
  }
};

// ---- nlhw2: pwlinear (10 breakpoints) → B/F [3 3 0] → pwlinear (10 breakpoints) -----------------

using Nlhw2 = nlid::HammersteinWiener<nlid::PwLinear<10>, nlid::TransferFunctionBlock<3, 3, 0>, nlid::PwLinear<10>>;
using Nlhw2Dyn = nlid::HammersteinWiener<nlid::PwLinear<Dynamic>, nlid::TransferFunctionBlock<Dynamic, Dynamic, Dynamic>,
                                         nlid::PwLinear<Dynamic>>;
inline constexpr int kNlhw2Params = 20 + 6 + 20;

/// θ = [θ_f (x₀, log gaps, values), b₁ b₂ b₃ f₁ f₂ f₃, θ_h]: input map u ↦ u + 0.3u² on
/// [−0.05, 1.03]; B/F with poles 0.9, 0.8, 0.5 and unit static gain; output map a soft
/// saturation 15° … 90° of x on [−0.1, 1.34].
inline Eigen::VectorXd nlhw2_theta() {
  Eigen::VectorXd th(kNlhw2Params);
  th(0) = -0.05;
  for (int k = 1; k < 10; ++k) th(k) = std::log(0.12);
  for (int k = 0; k < 10; ++k) {
    const double x = -0.05 + 0.12 * k;
    th(10 + k) = x + 0.3 * x * x;
  }
  const double lin[6] = {0.004, 0.003, 0.003, -2.2, 1.57, -0.36};
  for (int j = 0; j < 6; ++j) th(20 + j) = lin[j];
  th(26) = -0.1;
  for (int k = 1; k < 10; ++k) th(26 + k) = std::log(0.16);
  for (int k = 0; k < 10; ++k) {
    const double x = -0.1 + 0.16 * k;
    th(36 + k) = 15.0 + 75.0 * (0.5 + 0.5 * std::tanh(2.5 * (x - 0.6)));
  }
  return th;
}

inline Nlhw2 make_nlhw2() {
  Nlhw2 m;
  m.set_parameters(nlhw2_theta());
  return m;
}

inline Nlhw2Dyn make_nlhw2_dynamic() {
  Nlhw2Dyn m(nlid::PwLinear<Dynamic>(10), nlid::TransferFunctionBlock<Dynamic, Dynamic, Dynamic>(3, 3, 0),
             nlid::PwLinear<Dynamic>(10));
  m.set_parameters(nlhw2_theta());
  return m;
}

/// The same model by hand: breakpoint tables precomputed once per run (as hand-written code
/// naturally does), linear segment search, transposed direct form II of B/F.
struct HandNlhw2 {
  const Eigen::VectorXd th;
  explicit HandNlhw2(Eigen::VectorXd t) : th(std::move(t)) {}
  struct Table {
    double x[10], y[10], slope[9];
    double operator()(double v) const {
      int k = 0;
      while (k < 8 && v >= x[k + 1]) ++k;
      return y[k] + slope[k] * (v - x[k]);
    }
  };
  static Table table(const double* p) {
    Table t{};
    t.x[0] = p[0];
    for (int k = 1; k < 10; ++k) t.x[k] = t.x[k - 1] + std::exp(p[k]);
    for (int k = 0; k < 10; ++k) t.y[k] = p[10 + k];
    for (int k = 0; k < 9; ++k) t.slope[k] = (t.y[k + 1] - t.y[k]) / (t.x[k + 1] - t.x[k]);
    return t;
  }
  void simulate(const double* u, long n, double* y) const {
    const Table f = table(th.data()), h = table(th.data() + 26);
    const double b0 = th(20), b1 = th(21), b2 = th(22), f1 = th(23), f2 = th(24), f3 = th(25);
    double s0 = 0, s1 = 0, s2 = 0;
    for (long t = 0; t < n; ++t) {
      const double w = f(u[t]);
      const double x = s0 + b0 * w;
      s0 = s1 + b1 * w - f1 * x;
      s1 = s2 + b2 * w - f2 * x;
      s2 = -f3 * x;
      y[t] = h(x);
    }
  }
};

// ---- grey-box throttle: the study's equation, four parameters --------------------------------------

/// The study's grey-box model with the stops fixed at 15° and 90° (one definition for the tests
/// and the benchmarks: tests/support/study_throttle.hpp).
using StudyThrottle = nlid_test::StudyThrottle;

inline std::array<double, 4> throttle_theta() { return {25.0, 120.0, 1.5e4, 9000.0}; }

/// The same model by hand: two doubles of state, RK4 with `sub` sub-steps, zero-order hold.
inline void hand_throttle(const double* p, const double* u, long n, double ts, int sub, double* x, double* y) {
  const double c = p[0], k = p[1], K = p[2], b = p[3], h = ts / sub;
  auto acc = [&](double pos, double vel, double uk) {
    const double stop = std::max(pos, 90.0) - 90.0 + std::min(pos, 15.0) - 15.0;
    return b * uk - c * vel - k * pos - K * stop;
  };
  double p0 = x[0], v0 = x[1];
  for (long t = 0; t < n; ++t) {
    y[t] = p0;
    if (t + 1 == n) break;
    const double uk = u[t];
    for (int i = 0; i < sub; ++i) {
      const double k1p = v0, k1v = acc(p0, v0, uk);
      const double k2p = v0 + 0.5 * h * k1v, k2v = acc(p0 + 0.5 * h * k1p, v0 + 0.5 * h * k1v, uk);
      const double k3p = v0 + 0.5 * h * k2v, k3v = acc(p0 + 0.5 * h * k2p, v0 + 0.5 * h * k2v, uk);
      const double k4p = v0 + h * k3v, k4v = acc(p0 + h * k3p, v0 + h * k3v, uk);
      p0 += h / 6.0 * (k1p + 2.0 * (k2p + k3p) + k4p);
      v0 += h / 6.0 * (k1v + 2.0 * (k2v + k3v) + k4v);
    }
  }
  x[0] = p0;
  x[1] = v0;
}

// ---- ratio reporter ----------------------------------------------------------------------------------

/// One target: rate(numerator) / rate(denominator) ≥ target (rates: the samples/s counter, or
/// 1/CPU time for benchmarks without one).
struct RatioCheck {
  std::string what, numerator, denominator;
  double target;
};

/// Console reporter that remembers each benchmark's rate and prints the ratio table at the end.
class RatioReporter : public benchmark::ConsoleReporter {
 public:
  explicit RatioReporter(std::vector<RatioCheck> checks) : checks_(std::move(checks)) {}
  void ReportRuns(const std::vector<Run>& runs) override {
    for (const auto& r : runs) {
      if (r.run_type != Run::RT_Iteration || r.error_occurred) continue;
      double rate = 0;
      const auto it = r.counters.find("samples/s");
      if (it != r.counters.end()) {
        rate = it->second.value;
      } else {
        // CPU time, as the rate counters use: on a shared machine wall time measures the queue.
        rate = 1.0 / (r.GetAdjustedCPUTime() * benchmark::GetTimeUnitMultiplier(r.time_unit));
      }
      rates_[r.benchmark_name()] = rate;
    }
    ConsoleReporter::ReportRuns(runs);
  }
  void Finalize() override {
    ConsoleReporter::Finalize();
    std::printf("\n%-58s %10s %8s %s\n", "ratio (higher is better)", "measured", "target", "");
    for (const auto& c : checks_) {
      const auto a = rates_.find(c.numerator), b = rates_.find(c.denominator);
      if (a == rates_.end() || b == rates_.end()) continue;
      const double ratio = a->second / b->second;
      std::printf("%-58s %9.2fx %7.2fx %s\n", c.what.c_str(), ratio, c.target,
                  c.target <= 0 ? "(info)" : (ratio >= c.target ? "MET" : "MISSED"));
    }
    std::fflush(stdout);
  }

 private:
  std::vector<RatioCheck> checks_;
  std::map<std::string, double> rates_;
};

/// main() body: run the registered benchmarks with the ratio table at the end.
inline int run_with_ratios(int argc, char** argv, std::vector<RatioCheck> checks) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  RatioReporter reporter(std::move(checks));
  benchmark::RunSpecifiedBenchmarks(&reporter);
  benchmark::Shutdown();
  return 0;
}

}  // namespace perf
