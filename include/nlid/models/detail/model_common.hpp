#pragma once
/// @file
/// Shared pieces of the user-level models (Nlarx, HammersteinWiener): the estimation report,
/// experiment checks with located messages, and helpers generic over the scalar.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "nlid/ad/dual.hpp"
#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/core/initial_condition.hpp"
#include "nlid/core/sample_time.hpp"
#include "nlid/data/experiment.hpp"

namespace nlid {

/// What an estimation did, kept in the model so that `describe()` can tell it.
struct EstimationReport {
  bool estimated = false;                  ///< false until an estimator filled this in
  std::string focus;                       ///< "prediction" or "simulation"
  std::string initial_condition;           ///< initial condition used during estimation
  int iterations = 0;                      ///< Levenberg–Marquardt iterations (all stages)
  double initial_cost = std::numeric_limits<double>::quiet_NaN();  ///< ½Σρ(r²) at the start
  double final_cost = std::numeric_limits<double>::quiet_NaN();    ///< ½Σρ(r²) at the end
  double seconds = 0.0;                    ///< wall-clock time of the whole estimation
  std::string status;                      ///< solver's stopping message
  std::vector<std::string> data_names;     ///< estimation experiments
  /// Simulation fit (%) on each estimation experiment; −∞ if its simulation diverged, NaN if the
  /// fit is undefined because that experiment's measured output is constant.
  std::vector<double> fit_percent;
  std::vector<Eigen::VectorXd> initial_states;  ///< estimated x0 per experiment (if estimated)
  /// Multi-start estimation (`EstimateOptions::starts` > 1): cost of each start after its pilot
  /// iterations (+∞ if it could not run), and the index of the start that was continued.
  std::vector<double> start_costs;
  int chosen_start = -1;   ///< −1: a single start
};

/// Readable name of an initial-condition policy.
inline const char* to_string(InitialCondition ic) {
  switch (ic) {
    case InitialCondition::zero: return "zero";
    case InitialCondition::estimate: return "estimate";
    case InitialCondition::equilibrium: return "equilibrium";
    case InitialCondition::measured: return "measured";
  }
  return "?";
}

namespace detail {

/// "experiment 'data3'" or "experiment 2" — how messages name an experiment.
inline std::string experiment_label(const Experiment& e, long index) {
  if (!e.name().empty()) return "experiment '" + e.name() + "'";
  if (index >= 0) return "experiment " + std::to_string(index);
  return "experiment";
}

/// Location of an experiment in a data set (index −1: a lone experiment).
inline Location experiment_location(long index) {
  Location l;
  l.experiment = index;
  return l;
}

/// Checks that an experiment fits a single-output model with `num_inputs` inputs, enough
/// samples (> `min_history`) and a matching sample time (`model_ts` 0: any). Throws naming it.
inline void check_experiment(const Experiment& e, long index, int num_inputs, int min_history,
                             double model_ts, const char* model_kind) {
  const Location where = experiment_location(index);
  const std::string who = experiment_label(e, index);
  e.validate(true);  // u() and y() are mutable: a record resized through one would be read past its end
  require(e.num_outputs() == 1,
          who + " has " + std::to_string(e.num_outputs()) + " outputs; a " + model_kind +
              " model has one output (estimate one model per output)",
          where);
  require(e.num_inputs() == num_inputs,
          who + " has " + std::to_string(e.num_inputs()) + " input(s) but the " + model_kind +
              " model reads " + std::to_string(num_inputs),
          where);
  require(e.size() > min_history,
          min_history == 0 ? who + " has no samples"
                           : who + " has " + std::to_string(e.size()) + " samples, not more than the " +
                                 std::to_string(min_history) + " needed by the model's lags",
          where);
  if (model_ts > 0.0) {
    // format_g(·, 10): std::to_string's six decimals print 0.0100000002 and 0.01 alike.
    require(same_sample_time(e.ts(), model_ts),
            who + " has sample time " + format_g(e.ts(), 10) + " s but the model's is " +
                format_g(model_ts, 10) + " s (resample the data or re-estimate)",
            where);
  }
}

/// Refuses a record with a missing (non-finite) input sample — and output sample when
/// `outputs_too` (one-step prediction reads the measured outputs) — before a simulation or
/// prediction runs into it and the stop is reported as a divergence of the model.
inline void require_complete_for(const Experiment& e, long index, bool outputs_too, const char* run) {
  // first_missing scans every input before any output: an output found first means no input gap.
  const auto m = e.first_missing();
  if (!m || (m->output && !outputs_too)) return;
  const char* what = m->output ? "output" : "input";
  throw Error(experiment_label(e, index) + " has a missing (non-finite) " + what + " sample at sample index " +
                  std::to_string(m->sample) + " (" + what + " " + std::to_string(m->channel) + "): a " + run +
                  " cannot run through it; fill the gap (Experiment::fill_missing) or cut the record there",
              experiment_location(index));
}

/// Throws unless every value of θ is finite, naming the first that is not by its index and name
/// (a NaN parameter would otherwise surface much later as a "diverging" simulation).
inline void require_finite_parameters(const Eigen::VectorXd& theta, const std::vector<std::string>& names) {
  for (Eigen::Index i = 0; i < theta.size(); ++i) {
    if (std::isfinite(theta[i])) continue;
    const auto k = static_cast<std::size_t>(i);
    const std::string name = k < names.size() ? names[k] : "theta[" + std::to_string(i) + "]";
    throw Error("parameter " + std::to_string(i) + " ('" + name + "') is " + (std::isnan(theta[i]) ? "NaN" : "infinite") +
                    "; every parameter must be a finite number",
                at_parameter(name));
  }
}

/// Throws if an experiment has a missing (NaN or infinite) sample, naming the experiment, the
/// channel and the sample. Estimation needs complete records: one missing sample poisons every
/// later residual of a simulation, and the data-driven initialisation would otherwise report it
/// at a row of its regression matrix, which the user cannot map back to the data.
/// Name of input or output channel c of e ("input2"-style when the record names none) and the
/// location of its sample k: experiment `index`, data row k + 1, that column.
inline std::pair<std::string, Location> sample_location(const Experiment& e, long index, bool output, Eigen::Index c,
                                                        Eigen::Index k) {
  const auto& names = output ? e.output_names() : e.input_names();
  const auto ch = static_cast<std::size_t>(c);
  std::string name = ch < names.size() ? names[ch] : std::string(output ? "output" : "input") + std::to_string(ch + 1);
  Location where = experiment_location(index);
  where.row = static_cast<long>(k) + 1;
  where.column_name = name;
  return {std::move(name), std::move(where)};
}

inline void require_complete(const Experiment& e, long index) {
  const auto m = e.first_missing();
  if (!m) return;
  const char* kind = m->output ? "output" : "input";
  const auto [name, where] = sample_location(e, index, m->output, m->channel, m->sample);
  throw Error(experiment_label(e, index) + " has a missing " + kind + " sample: '" + name + "' is " +
                  (std::isnan(m->value) ? "NaN" : m->value > 0 ? "Inf" : "-Inf") + " at sample " +
                  std::to_string(m->sample) +
                  "; estimation needs complete records - Experiment::fill_missing() interpolates short gaps, "
                  "or split the record at a long one",
              where);
}

/// Number of `true` flags in an `LmOptions::fixed` mask of a model with `num_parameters`
/// parameters (0 when the mask is empty or sized otherwise; the solver rejects such masks).
inline Eigen::Index count_fixed(const std::vector<bool>& fixed, Eigen::Index num_parameters) {
  if (static_cast<Eigen::Index>(fixed.size()) != num_parameters) return 0;
  Eigen::Index n = 0;
  for (const bool f : fixed) n += f ? 1 : 0;
  return n;
}

/// Throws if an estimation has more free parameters than residuals, one output per sample:
/// residuals = Σ (samples − `history`) over the experiments of `data`. Such data cannot determine
/// the model: a continuum of parameter vectors reproduces them exactly (a "100 % fit" that says
/// nothing about the system). A large enough model would also spend hours in its data-driven
/// initialisation and then exhaust memory in the solver's normal equations, so estimators call
/// this before anything else.
template <class D>
void require_enough_samples(const std::string& model_kind, Eigen::Index free_parameters, const D& data,
                            Eigen::Index history) {
  Eigen::Index residuals = 0, samples = 0;
  for (std::size_t i = 0; i < data.size(); ++i) {
    samples += data[i].size();
    residuals += std::max<Eigen::Index>(0, data[i].size() - history);
  }
  if (free_parameters <= residuals) return;
  std::string how = std::to_string(samples) + " samples in " + std::to_string(data.size()) + " experiment" +
                    (data.size() == 1 ? "" : "s");
  if (history > 0) how += ", less " + std::to_string(history) + " of lag history in each";
  throw Error("the " + model_kind + " model has " + std::to_string(free_parameters) +
                  " free parameters but the estimation data give only " + std::to_string(residuals) +
                  " residuals (" + how + "); the data cannot determine it - use more data or a smaller model "
                  "(fewer units, breakpoints or lags)",
              at_parameter("data"));
}

/// Throws if the model's input delay (the summed nk of its linear blocks) is at least as long as
/// every experiment of `data`: no residual then depends on the input. Found by the model-spec
/// fuzzer: wh:nb=4,nf=2,nk=40960:... fitted to 60 samples ran its whole initialisation and
/// estimation (20 s under the sanitizers) for a model whose output never depends on its input.
template <class D>
void require_input_reaches_output(const std::string& model_kind, Eigen::Index delay, const D& data) {
  Eigen::Index longest = 0;
  for (std::size_t i = 0; i < data.size(); ++i) longest = std::max<Eigen::Index>(longest, data[i].size());
  if (delay < longest) return;
  throw Error("the " + model_kind + " model delays its input by " + std::to_string(delay) +
                  " samples (the nk of its linear blocks), as long as or longer than the longest estimation record (" +
                  std::to_string(longest) + " samples): no output sample depends on the input - use longer records "
                  "or a smaller nk",
              at_parameter("nk"));
}

/// The delay nk of a linear block, 0 for a block without one (a static nonlinearity).
template <class B>
Eigen::Index block_input_delay(const B& block) {
  if constexpr (requires { block.nk(); }) {
    return block.nk();
  } else {
    return 0;
  }
}

/// Finite check on a scalar including a dual's derivatives (a NaN Jacobian is as bad as a
/// NaN value for the solver).
template <class T>
bool is_finite_scalar(const T& x) {
  if constexpr (is_dual_v<T>) {
    return isfinite(x);
  } else {
    using std::isfinite;  // ADL: a Batch (core/batch.hpp) is finite if every lane is
    return isfinite(x);
  }
}

/// θ (double) as scalar T: constants with zero derivative.
template <class T>
std::vector<T> cast_parameters(std::span<const double> theta) {
  std::vector<T> out;
  out.reserve(theta.size());
  for (double v : theta) out.push_back(T(v));
  return out;
}

/// std::span over an Eigen vector.
template <class V>
auto as_span(V& v) {
  return std::span<typename V::Scalar>(v.data(), static_cast<std::size_t>(v.size()));
}
template <class V>
auto as_const_span(const V& v) {
  return std::span<const typename V::Scalar>(v.data(), static_cast<std::size_t>(v.size()));
}

/// The estimation part of a model's `describe()`.
inline std::string describe_report(const EstimationReport& r) {
  if (!r.estimated) return "  not estimated (parameters set by hand or at their initial values)\n";
  std::string s = "  estimated with " + r.focus + " focus, initial condition " + r.initial_condition + ": " +
                  std::to_string(r.iterations) + " iterations, " + detail::format_g(r.seconds, 3) + " s, cost " +
                  detail::format_g(r.initial_cost, 4) + " -> " + detail::format_g(r.final_cost, 4) + "\n";
  if (!r.status.empty()) s += "    solver: " + r.status + "\n";
  if (!r.start_costs.empty()) {
    s += "    " + std::to_string(r.start_costs.size()) + " data-driven starts, cost after the pilot iterations:";
    for (double c : r.start_costs) s += " " + detail::format_g(c, 4);
    s += "; continued start " + std::to_string(r.chosen_start) + "\n";
  }
  for (std::size_t i = 0; i < r.fit_percent.size(); ++i) {
    const std::string name = i < r.data_names.size() && !r.data_names[i].empty() ? r.data_names[i]
                                                                                  : "experiment " + std::to_string(i);
    s += "    fit to " + name + " (simulation): " +
         (std::isnan(r.fit_percent[i]) ? std::string("undefined (constant measured output)")
                                       : detail::format_g(r.fit_percent[i], 4) + " %") +
         "\n";
  }
  return s;
}

}  // namespace detail
}  // namespace nlid
