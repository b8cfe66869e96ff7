#pragma once
/// @file
/// `Dataset`: several experiments of one system, used together (multi-experiment data).
///
/// Identification criteria over several records simply add up (Ljung 1999, sec. 14.3 "merging
/// experiments"): with experiments e = 1…E of lengths N_e,
///
///     V(θ) = Σ_e Σ_{k} ‖ y_e(t_k) − ŷ_e(t_k | θ) ‖²,
///
/// where every predictor or simulation restarts at the beginning of each record; the records are
/// never glued end to end, which would create a fake jump at the seam. The throttle study
/// estimates on data1 + data2 merged this way and validates on data3…data5.
///
/// For the sum to mean one model, all experiments must share the sample time (delays are counted
/// in samples) and the channel counts. `Dataset` enforces both when an experiment is added: equal
/// `ts` within a relative 1e-6 (`sample_time_tolerance`, core/sample_time.hpp), equal n_u and n_y, and no channel that two records name
/// differently. Errors name the experiment index (0-based, as `operator[]` takes it) and the
/// record's name.

#include <Eigen/Core>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <initializer_list>
#include <string>
#include <utility>
#include <vector>

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/core/sample_time.hpp"
#include "nlid/data/detail/printable.hpp"
#include "nlid/data/experiment.hpp"

namespace nlid {

/// Relative tolerance for "same sample time" across the experiments of a `Dataset`: the one
/// tolerance of the library (core/sample_time.hpp says why it is 10⁻⁶).
inline constexpr double dataset_ts_tolerance = sample_time_tolerance;

/// An ordered collection of experiments with a common sample time and common channel counts.
/// Invariant: every experiment satisfies `Experiment::validate(true)`; all have the `ts`,
/// `num_inputs()` and `num_outputs()` of the first one.
class Dataset {
 public:
  using iterator = std::vector<Experiment>::iterator;              ///< mutable iteration
  using const_iterator = std::vector<Experiment>::const_iterator;  ///< read-only iteration

  /// No experiments.
  Dataset() = default;
  /// A data set of one experiment; implicit, so a single `Experiment` can be passed wherever a
  /// `Dataset` is expected.
  Dataset(const Experiment& e) { add(e); }  // NOLINT(google-explicit-constructor)
  /// Takes the experiments in order; throws on the first one that does not match the first.
  explicit Dataset(std::vector<Experiment> experiments) {
    for (auto& e : experiments) add(std::move(e));
  }
  /// `Dataset{e1, e2}`.
  Dataset(std::initializer_list<Experiment> experiments) {
    for (const auto& e : experiments) add(e);
  }

  /// Appends an experiment. Throws `nlid::Error` (naming the index it would get) if its sample
  /// time differs from the others by more than a relative 1e-6 (`sample_time_tolerance`), its channel counts differ, or a
  /// channel that both it and the first record name (not a default or empty name) has another name.
  void add(Experiment e) {
    const long index = static_cast<long>(experiments_.size());
    try {
      e.validate(true);
    } catch (const Error& err) {
      Location l = err.where();
      l.experiment = index;
      throw Error(err.message(), l);
    }
    if (!experiments_.empty()) {
      const Experiment& first = experiments_.front();
      const double rel = std::abs(e.ts() - first.ts()) / first.ts();
      if (rel > dataset_ts_tolerance) {
        // Nearly equal sample times are one logger's rate read from different jittering stamps.
        throw Error(label(e) + "has sample time " + number(e.ts()) + " but the data set has " +
                        number(first.ts()) + " (relative difference " + detail::format_g(rel, 3) +
                        "); resample or decimate it first" +
                        (rel < one_rate_hint_tolerance ? std::string("; if both were logged at one rate, set that sample time (CsvReadOptions::ts)")
                                    : std::string()),
                    at_experiment(index));
      }
      if (e.num_inputs() != first.num_inputs() || e.num_outputs() != first.num_outputs()) {
        throw Error(label(e) + "has " + std::to_string(e.num_inputs()) + " inputs and " +
                        std::to_string(e.num_outputs()) + " outputs but the data set has " +
                        std::to_string(first.num_inputs()) + " inputs and " +
                        std::to_string(first.num_outputs()) + " outputs",
                    at_experiment(index));
      }
      check_names(e, first, index, "input", e.input_names(), first.input_names());
      check_names(e, first, index, "output", e.output_names(), first.output_names());
    }
    experiments_.push_back(std::move(e));
  }

  /// Number of experiments.
  [[nodiscard]] std::size_t size() const { return experiments_.size(); }
  /// True if there are no experiments.
  [[nodiscard]] bool empty() const { return experiments_.empty(); }

  /// Experiment `i` (0-based); throws `nlid::Error` if out of range.
  [[nodiscard]] const Experiment& operator[](std::size_t i) const {
    check_index(i);
    return experiments_[i];
  }
  /// Mutable experiment `i`. Changing its `ts` or channel counts through this reference breaks the
  /// invariant; preprocessing re-validates and will report it.
  [[nodiscard]] Experiment& operator[](std::size_t i) {
    check_index(i);
    return experiments_[i];
  }

  /// Iteration over the experiments in order.
  [[nodiscard]] iterator begin() { return experiments_.begin(); }
  /// End of iteration.
  [[nodiscard]] iterator end() { return experiments_.end(); }
  /// Read-only iteration.
  [[nodiscard]] const_iterator begin() const { return experiments_.begin(); }
  /// End of read-only iteration.
  [[nodiscard]] const_iterator end() const { return experiments_.end(); }
  /// The experiments as a vector.
  [[nodiscard]] const std::vector<Experiment>& experiments() const { return experiments_; }

  /// Common sample time. Throws if the data set is empty (there is no sample time to report).
  [[nodiscard]] double ts() const { return first("ts").ts(); }
  /// Common number of inputs n_u. Throws if empty.
  [[nodiscard]] int num_inputs() const { return first("num_inputs").num_inputs(); }
  /// Common number of outputs n_y. Throws if empty.
  [[nodiscard]] int num_outputs() const { return first("num_outputs").num_outputs(); }
  /// Σ N_e over all experiments (0 if empty).
  [[nodiscard]] Eigen::Index total_samples() const {
    Eigen::Index n = 0;
    for (const auto& e : experiments_) n += e.size();
    return n;
  }
  /// `Experiment::require_estimable_scale` of every experiment, each named by its index.
  void require_estimable_scale(const std::string& who) const {
    for (std::size_t i = 0; i < experiments_.size(); ++i) experiments_[i].require_estimable_scale(who, static_cast<long>(i));
  }
  /// Names of the experiments in order.
  [[nodiscard]] std::vector<std::string> names() const {
    std::vector<std::string> v;
    v.reserve(experiments_.size());
    for (const auto& e : experiments_) v.push_back(e.name());
    return v;
  }

  // ---- Implementation details below ----------------------------------------------------------

 private:
  // 10 digits tell apart sample times the 1e-6 tolerance refuses; 17 printed 0.0099999159579789894.
  static std::string number(double x) { return detail::format_g(x, 10); }
  static std::string label(const Experiment& e) {
    return e.name().empty() ? std::string("experiment ") : "experiment '" + e.name() + "' ";
  }
  // The default names (u, y; u1, u2, …) say nothing about what a channel is, and neither does an
  // empty one: only two chosen names can disagree.
  static bool chosen(const std::string& name, const char* stem, std::size_t i, std::size_t n) {
    if (name.empty()) return false;
    return name != (n == 1 ? std::string(stem) : stem + std::to_string(i + 1));
  }
  // ... except a default name at the wrong position: 'u2' as the first of two inputs says the
  // channels were reordered (a CSV with columns u1,u2 read as {u2, u1}).
  static bool misplaced_default(const std::string& name, const char* stem, std::size_t i, std::size_t n) {
    for (std::size_t k = 0; n > 1 && k < n; ++k)
      if (k != i && name == stem + std::to_string(k + 1)) return true;
    return false;
  }
  static bool disagree(const std::string& a, const std::string& b, const char* stem, std::size_t i, std::size_t n) {
    if (a.empty() || b.empty() || a == b) return false;
    return (chosen(a, stem, i, n) && chosen(b, stem, i, n)) || misplaced_default(a, stem, i, n) ||
           misplaced_default(b, stem, i, n);
  }
  // Channels are matched by position when criteria add up over records, so two records whose
  // channels carry different names (inputs {cmd, load} and {load, cmd}) would be fitted as one
  // system with the signals swapped.
  static void check_names(const Experiment& e, const Experiment& first, long index, const char* kind,
                          const std::vector<std::string>& names, const std::vector<std::string>& have) {
    const char* stem = kind[0] == 'i' ? "u" : "y";
    for (std::size_t i = 0; i < names.size() && i < have.size(); ++i) {
      if (names.size() == have.size() && disagree(names[i], have[i], stem, i, names.size())) {
        Location l = at_experiment(index);
        l.column = static_cast<long>(i) + 1;
        l.column_name = detail::printable(names[i], std::string::npos);
        throw Error(label(e) + "has " + kind + " " + std::to_string(i + 1) + " named '" + detail::printable(names[i]) +
                        "' but the data set's " + kind + " " + std::to_string(i + 1) + " is '" +
                        detail::printable(have[i]) + "' (" + label(first) +
                        "at index 0); channels are matched by position: reorder them (select_channels) or, if "
                        "they are the same signal, rename them (set_" + kind + "_names)",
                    l);
      }
    }
  }
  void check_index(std::size_t i) const {
    if (i >= experiments_.size()) {
      throw Error("experiment index " + std::to_string(i) + " out of range: the data set has " +
                      std::to_string(experiments_.size()) + " experiment(s)",
                  at_experiment(static_cast<long>(i)));
    }
  }
  const Experiment& first(const char* what) const {
    if (experiments_.empty()) {
      throw Error(std::string("empty data set has no ") + what, at_parameter(what));
    }
    return experiments_.front();
  }

  std::vector<Experiment> experiments_;
};

/// Multi-experiment merge: the experiments of `a` followed by those of `b` (MATLAB `merge`).
/// Throws `nlid::Error` naming the index (in the merged set) of the first experiment whose sample
/// time or channel counts differ.
inline Dataset merge(const Dataset& a, const Dataset& b) {
  Dataset out = a;
  for (const auto& e : b) out.add(e);
  return out;
}

}  // namespace nlid
