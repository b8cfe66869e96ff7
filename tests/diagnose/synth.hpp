#pragma once
// Shared helpers of the diagnosis tests: reproducible inputs and records simulated from a known
// baseline plus known effects (the "truth"), with measurement noise and optional quantisation.
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "nlid/data/dataset.hpp"
#include "nlid/diagnose/augmented.hpp"
#include "nlid/diagnose/effects.hpp"

namespace diag_test {

/// Data scales of the synthetic truths (positions about ±1, inputs in [−1, 1], forces per inertia
/// about 100), where effects take their shape constants (friction presliding, preload width) from;
/// `y_extent` is the recorded output range ±y_extent.
inline nlid::DataScales unit_scales(double ts, double y_extent = 1.0) {
  nlid::DataScales s;
  s.ts = ts;
  s.y_lo = s.q_lo = -1.0;
  s.y_hi = s.q_hi = 1.0;
  s.y_min = -y_extent;
  s.y_max = y_extent;
  s.u_lo = -1.0;
  s.u_hi = 1.0;
  s.u_abs = 1.0;
  s.q_mid = 0.0;
  s.speed = 5.0;
  s.accel = 100.0;
  s.stiffness = 100.0;
  return s;
}

// Piecewise-constant input: levels uniform in [lo, hi], each held a uniform number of samples in
// [hold_min, hold_max] — a multi-level step test as used on real rigs.
inline Eigen::MatrixXd random_steps(int n, double lo, double hi, int hold_min, int hold_max, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> level(lo, hi);
  std::uniform_int_distribution<int> hold(hold_min, hold_max);
  Eigen::MatrixXd u(n, 1);
  int k = 0;
  while (k < n) {
    const double v = level(rng);
    const int h = hold(rng);
    for (int j = 0; j < h && k < n; ++j) u(k++, 0) = v;
  }
  return u;
}

// The truth's table with the given parameter values (by name) set.
template <class P>
std::vector<nlid::ParameterInfo> table(const P& phys, std::initializer_list<std::pair<const char*, double>> values) {
  const auto a = phys.parameter_info();
  std::vector<nlid::ParameterInfo> t(a.begin(), a.end());
  for (const auto& [name, v] : values) {
    bool found = false;
    for (auto& q : t)
      if (q.name == name) {
        q.value = v;
        found = true;
      }
    if (!found) throw nlid::Error(std::string("test table: no parameter ") + name);
  }
  return t;
}

// An effect of `kind` (variant for one-sided ones) with its parameters set in order.
inline nlid::Effect effect(nlid::EffectKind kind, std::vector<double> values, const nlid::DataScales& s,
                           const std::string& variant = {}) {
  for (nlid::EffectCandidate& c : nlid::make_effect_candidates(kind, s)) {
    if (c.effect.variant != variant) continue;
    nlid::Effect e = c.effect;
    for (std::size_t i = 0; i < values.size(); ++i) e.params.at(i).value = values[i];
    return e;
  }
  throw nlid::Error("test effect: no such variant");
}

// Simulates `truth` (built for sample time ts/oversample) on the sample-and-hold input u at
// sample time ts, from x0, and adds Gaussian noise (and rounding to `quantum` if > 0).
template <class P>
nlid::Experiment synthesize(const nlid::AugmentedModel<P>& truth, const Eigen::MatrixXd& u, double ts,
                            const Eigen::VectorXd& x0, double noise, unsigned seed, std::string name,
                            int oversample, double quantum = 0.0) {
  const Eigen::Index n = u.rows();
  Eigen::MatrixXd uf(n * oversample, u.cols());
  for (Eigen::Index k = 0; k < n * oversample; ++k) uf.row(k) = u.row(k / oversample);
  Eigen::VectorXd yf(n * oversample);
  const Eigen::VectorXd th = truth.parameters();
  const Eigen::Index got = truth.template simulate<double>(uf, th.data(), x0.data(), yf.data());
  if (got < uf.rows()) throw nlid::Error("test truth diverged");
  std::mt19937 rng(seed);
  std::normal_distribution<double> nd(0.0, 1.0);
  Eigen::MatrixXd y(n, 1);
  for (Eigen::Index k = 0; k < n; ++k) {
    double v = yf(k * oversample) + noise * nd(rng);
    if (quantum > 0.0) v = quantum * std::round(v / quantum);
    y(k, 0) = v;
  }
  return nlid::Experiment(u, y, ts, std::move(name));
}

}  // namespace diag_test
