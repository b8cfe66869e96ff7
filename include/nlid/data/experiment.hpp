#pragma once
/// @file
/// `Experiment`: one uniformly sampled input-output record, the unit of data in nlid.
///
/// Notation (Ljung 1999, ch. 1 and sec. 14.1): an experiment is the sequence
///
///     Z^N = { u(t_k), y(t_k) },   t_k = t_0 + k·T_s,   k = 0, …, N−1,
///
/// with input u(t_k) ∈ R^{n_u} and output y(t_k) ∈ R^{n_y}. Samples are stored row-wise, as an
/// MATLAB `iddata` object or a CSV file shows them: `u()` is N × n_u, `y()` is N × n_y, and row k
/// of both belongs to the same instant t_k. Either side may have zero columns: n_u = 0 is a time
/// series, n_y = 0 an input-only record.
///
/// Class invariants (established by the constructors, checked again by every preprocessing
/// function because `u()` and `y()` hand out mutable references):
///   - `u().rows() == y().rows()`;
///   - `ts() > 0` and finite, `t0()` finite;
///   - one name and one unit string per channel;
///   - every sample is finite, unless the experiment was built with `NonFinitePolicy::keep`
///     (missing data kept on purpose; `has_missing()` tells, `fill_missing()` repairs).
///
/// The sample time matters to every model: delays n_k are counted in samples (Ljung 1999,
/// eq. 4.7), so decimating by 10 divides them by 10. That is why `ts` is part of the record and
/// not an afterthought.
///
/// `notes()` is the record's history (file it came from, samples interpolated, filters applied).
/// Nothing that changes the numbers happens silently; preprocessing appends a note each time.

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/data/detail/missing.hpp"
#include "nlid/data/detail/printable.hpp"

namespace nlid {

/// What to do with NaN or ±Inf samples in inputs and outputs (the "missing data" note of the
/// study). Time stamps must always be finite; this policy never applies to them.
enum class NonFinitePolicy {
  error,        ///< throw `nlid::Error` naming the first non-finite sample (default)
  keep,         ///< keep NaN/Inf as they are; `Experiment::has_missing()` reports them
  interpolate,  ///< fill interior gaps linearly from the neighbouring finite samples; a note says
                ///< which samples were filled. Gaps at either end or longer than the allowed
                ///< gap length still throw.
};

/// Readable name of a policy, for messages ("NonFinitePolicy::error").
inline const char* to_string(NonFinitePolicy p) {
  switch (p) {
    case NonFinitePolicy::error:
      return "NonFinitePolicy::error";
    case NonFinitePolicy::keep:
      return "NonFinitePolicy::keep";
    case NonFinitePolicy::interpolate:
      return "NonFinitePolicy::interpolate";
  }
  return "NonFinitePolicy::?";
}

/// Default length limit (samples) of a gap that `NonFinitePolicy::interpolate` may fill. Longer
/// gaps are not "missing samples" but missing stretches of the experiment; bridging them with a
/// straight line would invent dynamics, so they are reported instead.
inline constexpr int default_max_gap = 10;

/// A missing (NaN or ±Inf) sample of an experiment: `Experiment::first_missing`.
struct MissingSample {
  bool output = false;       ///< false: an input channel
  Eigen::Index channel = 0;  ///< 0-based channel (column of u() or y())
  Eigen::Index sample = 0;   ///< 0-based sample index
  double value = 0.0;        ///< the NaN or ±Inf found there
};

/// One uniformly sampled input-output experiment. See the file comment for notation and invariants.
class Experiment {
 public:
  /// Empty experiment: no samples, no channels, `ts() == 1`.
  Experiment() = default;

  /// Takes the N × n_u input and N × n_y output matrices and the sample time. Channel names
  /// default to "u"/"y" (one channel) or "u1", "u2", … (several); units default to "".
  /// Throws `nlid::Error` if the row counts differ, `ts` is not positive and finite, or a sample
  /// is NaN/Inf.
  Experiment(Eigen::MatrixXd u, Eigen::MatrixXd y, double ts, std::string name = {})
      : Experiment(std::move(u), std::move(y), ts, std::move(name), NonFinitePolicy::error) {}

  /// As above, with an explicit policy for NaN/Inf samples. `interpolate` fills interior gaps of
  /// at most `max_gap` samples and records them in `notes()`.
  Experiment(Eigen::MatrixXd u, Eigen::MatrixXd y, double ts, std::string name,
             NonFinitePolicy non_finite, int max_gap = default_max_gap)
      : u_(std::move(u)), y_(std::move(y)), name_(std::move(name)) {
    if (u_.rows() != y_.rows()) {
      throw Error(prefix() + "input and output have different sample counts: u has " +
                      std::to_string(u_.rows()) + " rows, y has " + std::to_string(y_.rows()),
                  where());
    }
    set_ts(ts);
    input_names_ = default_names("u", num_inputs());
    output_names_ = default_names("y", num_outputs());
    input_units_.assign(static_cast<std::size_t>(num_inputs()), std::string());
    output_units_.assign(static_cast<std::size_t>(num_outputs()), std::string());
    apply_non_finite_policy(non_finite, max_gap);
  }

  /// N × n_u input samples, row k at time t0 + k·ts.
  [[nodiscard]] const Eigen::MatrixXd& u() const { return u_; }
  /// Mutable inputs. Keep the row count equal to `y().rows()`; preprocessing re-checks it.
  [[nodiscard]] Eigen::MatrixXd& u() { return u_; }
  /// N × n_y output samples.
  [[nodiscard]] const Eigen::MatrixXd& y() const { return y_; }
  /// Mutable outputs (same caveat as `u()`).
  [[nodiscard]] Eigen::MatrixXd& y() { return y_; }

  /// Sample time T_s (seconds by convention; any unit, as long as it is used consistently).
  [[nodiscard]] double ts() const { return ts_; }
  /// Sets the sample time; throws unless `ts > 0` and finite.
  void set_ts(double ts) {
    if (!(ts > 0.0) || !std::isfinite(ts)) {
      throw Error(prefix() + "sample time must be positive and finite, got " + number(ts),
                  with_parameter("ts"));
    }
    ts_ = ts;
  }
  /// Time of the first sample t_0.
  [[nodiscard]] double t0() const { return t0_; }
  /// Sets t_0; throws unless finite.
  void set_t0(double t0) {
    if (!std::isfinite(t0))
      throw Error(prefix() + "start time must be finite", with_parameter("t0"));
    t0_ = t0;
  }

  /// Number of samples N.
  [[nodiscard]] Eigen::Index size() const { return y_.rows(); }
  /// True if there are no samples.
  [[nodiscard]] bool empty() const { return size() == 0; }
  /// Number of input channels n_u.
  [[nodiscard]] int num_inputs() const { return static_cast<int>(u_.cols()); }
  /// Number of output channels n_y.
  [[nodiscard]] int num_outputs() const { return static_cast<int>(y_.cols()); }
  /// Time of the last sample, t_0 + (N−1)·T_s (t_0 if empty).
  [[nodiscard]] double t_end() const {
    return empty() ? t0_ : t0_ + static_cast<double>(size() - 1) * ts_;
  }
  /// Sample times t_0 + k·T_s, k = 0…N−1. Computed as t_0 + k·T_s (not by accumulation) so the
  /// rounding error does not grow with k.
  [[nodiscard]] Eigen::VectorXd time() const {
    Eigen::VectorXd t(size());
    for (Eigen::Index k = 0; k < size(); ++k) t(k) = t0_ + static_cast<double>(k) * ts_;
    return t;
  }

  /// Name of the experiment (a CSV file's stem when read from a file).
  [[nodiscard]] const std::string& name() const { return name_; }
  /// Renames the experiment.
  void set_name(std::string name) { name_ = std::move(name); }

  /// One name per input channel.
  [[nodiscard]] const std::vector<std::string>& input_names() const { return input_names_; }
  /// One name per output channel.
  [[nodiscard]] const std::vector<std::string>& output_names() const { return output_names_; }
  /// One unit per input channel ("" = unknown / dimensionless).
  [[nodiscard]] const std::vector<std::string>& input_units() const { return input_units_; }
  /// One unit per output channel.
  [[nodiscard]] const std::vector<std::string>& output_units() const { return output_units_; }
  /// Sets the input names; throws unless there is exactly one per input channel.
  void set_input_names(std::vector<std::string> names) {
    check_count(names, num_inputs(), "input_names");
    input_names_ = std::move(names);
  }
  /// Sets the output names; throws unless there is exactly one per output channel.
  void set_output_names(std::vector<std::string> names) {
    check_count(names, num_outputs(), "output_names");
    output_names_ = std::move(names);
  }
  /// Sets the input units; throws unless there is exactly one per input channel.
  void set_input_units(std::vector<std::string> units) {
    check_count(units, num_inputs(), "input_units");
    input_units_ = std::move(units);
  }
  /// Sets the output units; throws unless there is exactly one per output channel.
  void set_output_units(std::vector<std::string> units) {
    check_count(units, num_outputs(), "output_units");
    output_units_ = std::move(units);
  }

  /// History of the record: where it came from and every operation that changed its samples.
  [[nodiscard]] const std::vector<std::string>& notes() const { return notes_; }
  /// Appends a line to the history.
  void add_note(std::string note) { notes_.push_back(std::move(note)); }

  /// True if any input or output sample is NaN or ±Inf (only possible with
  /// `NonFinitePolicy::keep`, or after writing through `u()` / `y()`).
  [[nodiscard]] bool has_missing() const { return !u_.allFinite() || !y_.allFinite(); }

  /// The first missing sample — inputs before outputs, channel by channel, in time order — or
  /// nothing if the record is complete.
  [[nodiscard]] std::optional<MissingSample> first_missing() const {
    for (const bool output : {false, true}) {
      const Eigen::MatrixXd& m = output ? y_ : u_;
      for (Eigen::Index c = 0; c < m.cols(); ++c)
        for (Eigen::Index k = 0; k < m.rows(); ++k)
          if (!std::isfinite(m(k, c))) return MissingSample{output, c, k, m(k, c)};
    }
    return std::nullopt;
  }

  /// Re-checks the invariants after the matrices were modified through `u()` / `y()`; throws
  /// `nlid::Error` naming the broken one. `allow_missing` accepts NaN/Inf samples.
  void validate(bool allow_missing = false) const {
    if (u_.rows() != y_.rows()) {
      throw Error(prefix() + "input and output have different sample counts: u has " +
                      std::to_string(u_.rows()) + " rows, y has " + std::to_string(y_.rows()),
                  where());
    }
    if (input_names_.size() != static_cast<std::size_t>(num_inputs()) ||
        input_units_.size() != static_cast<std::size_t>(num_inputs())) {
      throw Error(prefix() + "input matrix has " + std::to_string(num_inputs()) + " columns but " +
                      std::to_string(input_names_.size()) + " input names and " +
                      std::to_string(input_units_.size()) +
                      " units; call set_input_names / set_input_units after resizing",
                  where());
    }
    if (output_names_.size() != static_cast<std::size_t>(num_outputs()) ||
        output_units_.size() != static_cast<std::size_t>(num_outputs())) {
      throw Error(prefix() + "output matrix has " + std::to_string(num_outputs()) +
                      " columns but " + std::to_string(output_names_.size()) +
                      " output names and " + std::to_string(output_units_.size()) +
                      " units; call set_output_names / set_output_units after resizing",
                  where());
    }
    if (!allow_missing) {
      if (const auto m = first_missing()) {
        throw Error(prefix() + "non-finite " + (m->output ? "output" : "input") + " sample " + number(m->value) +
                        " at sample index " + std::to_string(m->sample) +
                        " (use NonFinitePolicy::keep or ::interpolate for missing data)",
                    at_sample(m->sample, m->channel, m->output ? output_names_ : input_names_));
      }
    }
  }

  /// Largest channel magnitude an estimation accepts (see `require_estimable_scale`).
  static constexpr double max_estimable_magnitude = 1e100;
  /// Smallest non-zero channel magnitude an estimation accepts.
  static constexpr double min_estimable_magnitude = 1e-100;

  /// Refuses a channel whose largest finite |sample| lies outside [1e-100, 1e100] (an all-zero
  /// channel passes: constant channels are judged by the estimators). Estimation forms sums of
  /// squares and products of the samples (least squares, variances, normalisations); beyond
  /// 1e100 they overflow to infinity, below 1e-100 they underflow to zero, and the failure would
  /// surface as a misleading "rank deficient" or "constant output". No measured quantity in
  /// any unit is that large or small, so a channel there is mis-scaled data. `who` prefixes the
  /// message, `index` (≥ 0) is the experiment's place in its data set.
  void require_estimable_scale(const std::string& who = "", long index = -1) const {
    validate(true);  // names and columns agree before a channel is named
    for (const bool output : {false, true}) {
      const Eigen::MatrixXd& m = output ? y_ : u_;
      const std::vector<std::string>& names = output ? output_names_ : input_names_;
      for (Eigen::Index c = 0; c < m.cols(); ++c) {
        double peak = 0.0;
        Eigen::Index at = 0;
        for (Eigen::Index k = 0; k < m.rows(); ++k) {
          const double a = std::abs(m(k, c));
          if (std::isfinite(a) && a > peak) {
            peak = a;
            at = k;
          }
        }
        const bool large = peak > max_estimable_magnitude;
        if (!large && !(peak > 0.0 && peak < min_estimable_magnitude)) continue;
        const std::string channel = std::string(output ? "output" : "input") + " '" +
                                    detail::printable(names[static_cast<std::size_t>(c)]) + "'";
        std::string label = name_.empty() ? std::string("experiment") : "experiment '" + detail::printable(name_) + "'";
        if (name_.empty() && index >= 0) label += " " + std::to_string(index);
        // The experiment only: its sample index is not a file row once the record was decimated
        // or cut, so the message names channel and index in its own words.
        Location l;
        l.experiment = index;
        throw Error((who.empty() ? std::string() : who + ": ") + label + ", " + channel + ": " +
                        (large ? "a sample of magnitude " + detail::format_g(peak) + " at sample index " + std::to_string(at) +
                                     " is beyond 1e100, where the sums of squares estimation forms overflow"
                               : "the largest magnitude is " + detail::format_g(peak) + " (sample index " + std::to_string(at) +
                                     "), below 1e-100, where the sums of squares estimation forms underflow to zero") +
                        "; rescale the channel (other units)",
                    l);
      }
    }
  }

  /// Fills interior gaps of NaN/Inf samples (at most `max_gap` consecutive samples per channel)
  /// by linear interpolation between the finite neighbours, and notes each filled gap. Throws if
  /// a gap touches either end of the record or is longer than `max_gap`.
  void fill_missing(int max_gap = default_max_gap) {
    fill_channels(u_, input_names_, max_gap);
    fill_channels(y_, output_names_, max_gap);
  }

  // ---- Implementation details below ----------------------------------------------------------

 private:
  static std::string number(double x) { return detail::format_g(x, 17); }

  static std::vector<std::string> default_names(const std::string& stem, int n) {
    std::vector<std::string> names;
    if (n == 1) {
      names.push_back(stem);
    } else {
      for (int i = 0; i < n; ++i) names.push_back(stem + std::to_string(i + 1));
    }
    return names;
  }

  // The experiment's name goes into the message (Location has no field for it), so an error in
  // one of several records says which one.
  std::string prefix() const {
    return name_.empty() ? std::string() : "experiment '" + detail::printable(name_) + "': ";
  }

  static Location where() { return {}; }

  static Location with_parameter(const std::string& p) { return at_parameter(p); }

  void check_count(const std::vector<std::string>& v, int n, const char* what) const {
    if (v.size() != static_cast<std::size_t>(n)) {
      throw Error(prefix() + std::string(what) + " needs one entry per channel: expected " +
                      std::to_string(n) + ", got " + std::to_string(v.size()),
                  with_parameter(what));
    }
  }

  Location at_sample(Eigen::Index k, Eigen::Index c, const std::vector<std::string>& names) const {
    Location l = where();
    l.row = static_cast<long>(k) + 1;
    l.column = static_cast<long>(c) + 1;
    l.column_name = detail::printable(names[static_cast<std::size_t>(c)], std::string::npos);
    return l;
  }

  void fill_channels(Eigen::MatrixXd& m, const std::vector<std::string>& names, int max_gap) {
    for (Eigen::Index c = 0; c < m.cols(); ++c) {
      const std::vector<detail::Gap> gaps = detail::find_gaps(m, c);
      // Check every gap before filling any, so a failure leaves the record untouched.
      for (const auto& g : gaps) {
        const std::string span = std::to_string(g.begin) + ".." + std::to_string(g.end - 1);
        if (g.begin == 0 || g.end == m.rows()) {
          throw Error(prefix() + "cannot interpolate missing samples at the " +
                          std::string(g.begin == 0 ? "start" : "end") + " of the record (samples " +
                          span + "); trim it with select()",
                      at_sample(g.begin, c, names));
        }
        if (g.length() > max_gap) {
          throw Error(prefix() + "gap of " + std::to_string(g.length()) +
                          " missing samples (samples " + span + ") is longer than the allowed " +
                          std::to_string(max_gap) + "; split the record or raise max_gap",
                      at_sample(g.begin, c, names));
        }
      }
      if (gaps.empty()) continue;
      Eigen::Index filled = 0;
      std::string list;
      for (const auto& g : gaps) {
        detail::fill_gap_linear(m, c, g);
        filled += g.length();
        if (!list.empty()) list += ", ";
        list += g.length() == 1 ? std::to_string(g.begin)
                                : std::to_string(g.begin) + ".." + std::to_string(g.end - 1);
      }
      add_note("filled " + std::to_string(filled) + " missing sample(s) of '" +
               detail::printable(names[static_cast<std::size_t>(c)]) + "' by linear interpolation (sample indices " +
               list + ")");
    }
  }

  void apply_non_finite_policy(NonFinitePolicy policy, int max_gap) {
    switch (policy) {
      case NonFinitePolicy::error:
        validate(false);
        break;
      case NonFinitePolicy::keep:
        validate(true);
        break;
      case NonFinitePolicy::interpolate:
        validate(true);
        fill_missing(max_gap);
        break;
    }
  }

  Eigen::MatrixXd u_;
  Eigen::MatrixXd y_;
  double ts_ = 1.0;
  double t0_ = 0.0;
  std::string name_;
  std::vector<std::string> input_names_;
  std::vector<std::string> output_names_;
  std::vector<std::string> input_units_;
  std::vector<std::string> output_units_;
  std::vector<std::string> notes_;
};

namespace detail {

/// Throws `nlid::Error` if the experiment's channels (`kind` "input" or "output") carry the
/// model's names in another order: models read channels by position, so a record read as
/// {temp, flow} (or a CSV's u1, u2 read as {u2, u1}) would run the model on swapped signals.
/// Anything else — other names, defaults, fewer names — passes: only a reordering is certain.
inline void check_channel_order(const std::vector<std::string>& have, const std::vector<std::string>& model,
                                const char* kind, const std::string& who, Location where) {
  if (have.size() < 2 || have.size() != model.size() || have == model) return;
  std::vector<std::string> a = have, b = model;
  std::sort(a.begin(), a.end());
  std::sort(b.begin(), b.end());
  if (a != b || std::adjacent_find(a.begin(), a.end()) != a.end()) return;
  const auto list = [](const std::vector<std::string>& v) {
    std::string s;
    for (std::size_t i = 0; i < v.size(); ++i) s += (i ? ", " : "") + printable(v[i]);
    return "{" + s + "}";
  };
  throw Error(who + " has the " + kind + "s " + list(have) + " but the model reads " + list(model) +
                  " in that order; channels are matched by position: reorder them (select_channels)",
              where);
}

}  // namespace detail

}  // namespace nlid
