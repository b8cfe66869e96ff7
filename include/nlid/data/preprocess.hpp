#pragma once
/// @file
/// Preprocessing of experiments: offsets, means, linear trends, time windows; plus (through
/// resample.hpp) decimation and resampling, and channel selection. Every function that returns an
/// experiment returns a new one with a note added to its history (channel selection included);
/// all but `linear_trend` have a `Dataset` overload, applied per experiment (`mean_trend` pools),
/// whose errors name the experiment index.
///
/// Offsets and trends (Ljung 1999, sec. 14.1, "Slow disturbances: offsets, trends and drift").
/// A linear model describes deviations from an operating point, so levels that the model cannot
/// produce must go first: the throttle rests at 15° with zero command, which a linear ARX model
/// without a constant term would have to explain as dynamics. Per channel x, a trend is
///
///     x̄(t) = o + s·(t − t_ref),
///
/// and removing it gives x(t_k) − x̄(t_k). `remove_mean` uses s = 0, o = mean; `detrend` fits o, s
/// by least squares with t_ref = mean(t_k), where the two unknowns decouple:
///
///     s = Σ (t_k − t̄)(x_k − x̄) / Σ (t_k − t̄)²,   o = x̄.
///
/// The fitted `Trend` is returned by `mean_trend` / `linear_trend`, so the *same* offsets can be
/// removed from validation data (`remove_trend`) and added back to simulated outputs
/// (`add_trend`), as MATLAB's `getTrend` / `retrend` do. Removing each record's own mean from
/// validation data would hide an offset error of the model.
///
/// Time windows. `select(e, t_begin, t_end)` keeps the samples with t_begin ≤ t_k ≤ t_end (with a
/// 1e-9·T_s rounding allowance) and keeps their original times (t_0 becomes the first kept t_k),
/// so a window of a record still lines up with the record.

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/data/detail/per_experiment.hpp"
#include "nlid/data/experiment.hpp"
#include "nlid/data/resample.hpp"

namespace nlid {

/// Offsets and slopes per channel: x̄(t) = offset + slope·(t − t_ref).
struct Trend {
  Eigen::VectorXd input_offset;   ///< n_u values at t_ref
  Eigen::VectorXd output_offset;  ///< n_y values at t_ref
  Eigen::VectorXd input_slope;    ///< n_u slopes per unit time
  Eigen::VectorXd output_slope;   ///< n_y slopes per unit time
  double t_ref = 0.0;             ///< reference time of the offsets

  /// Constant offsets only (slopes zero).
  static Trend constant(Eigen::VectorXd input_offset, Eigen::VectorXd output_offset) {
    Trend t;
    t.input_slope = Eigen::VectorXd::Zero(input_offset.size());
    t.output_slope = Eigen::VectorXd::Zero(output_offset.size());
    t.input_offset = std::move(input_offset);
    t.output_offset = std::move(output_offset);
    return t;
  }
};

// ---- Implementation details below (helpers of the functions that follow) ----------------
namespace detail {

// A trend fitted on another record must match this record's channels one for one; broadcasting a
// single offset silently would subtract the wrong level from some channel.
inline void check_trend(const Experiment& e, const Trend& t) {
  auto check = [](Eigen::Index got, int want, const char* name) {
    if (got != want) {
      throw Error(std::string(name) + " has " + std::to_string(got) +
                      " entries but the experiment has " + std::to_string(want) + " channels",
                  at_parameter(name));
    }
  };
  check(t.input_offset.size(), e.num_inputs(), "input_offset");
  check(t.output_offset.size(), e.num_outputs(), "output_offset");
  check(t.input_slope.size(), e.num_inputs(), "input_slope");
  check(t.output_slope.size(), e.num_outputs(), "output_slope");
  if (!t.input_offset.allFinite() || !t.output_offset.allFinite() || !t.input_slope.allFinite() ||
      !t.output_slope.allFinite() || !std::isfinite(t.t_ref)) {
    throw Error("trend has non-finite offsets, slopes or t_ref", at_parameter("trend"));
  }
}

/// x − sign·(o + s(t − t_ref)) column by column.
inline Eigen::MatrixXd apply_trend(const Eigen::MatrixXd& x, const Eigen::VectorXd& o,
                                   const Eigen::VectorXd& s, const Eigen::VectorXd& dt,
                                   double sign) {
  Eigen::MatrixXd out = x;
  for (Eigen::Index c = 0; c < x.cols(); ++c) {
    if (s(c) == 0.0) {
      out.col(c).array() -= sign * o(c);  // no dt term: exact for constant trends
    } else {
      out.col(c).array() -= sign * (o(c) + s(c) * dt.array());
    }
  }
  return out;
}

// validate(true): offsets may be applied to records with kept missing samples (NaN − o stays
// NaN), so the gap is still visible to fill_missing() or to the next function that needs data.
inline Experiment trend_applied(const Experiment& e, const Trend& t, double sign,
                                const std::string& note) {
  e.validate(true);
  check_trend(e, t);
  const Eigen::VectorXd dt = e.time().array() - t.t_ref;
  Experiment out =
      with_samples(e, apply_trend(e.u(), t.input_offset, t.input_slope, dt, sign),
                   apply_trend(e.y(), t.output_offset, t.output_slope, dt, sign), e.ts(), e.t0());
  out.add_note(note);
  return out;
}

// "[15, 0.2]" for the notes: six digits are enough for a human reading the history.
inline std::string vec_str(const Eigen::VectorXd& v) {
  std::string s = "[";
  for (Eigen::Index i = 0; i < v.size(); ++i) {
    s += (i ? ", " : "") + detail::format_g(v(i));
  }
  return s + "]";
}

// A mean of nothing is NaN and a line through one point is undetermined: refuse both up front.
inline void require_samples(const Experiment& e, Eigen::Index n, const char* what) {
  if (e.size() < n) {
    throw Error(std::string(what) + " needs at least " + std::to_string(n) +
                    " sample(s), the experiment has " + std::to_string(e.size()),
                at_parameter("experiment"));
  }
}

}  // namespace detail

/// The channel means as a constant `Trend` (t_ref = t_0). Throws on an empty or incomplete record.
inline Trend mean_trend(const Experiment& e) {
  e.validate(false);
  detail::require_samples(e, 1, "mean_trend");
  Trend t = Trend::constant(e.u().colwise().mean().transpose(), e.y().colwise().mean().transpose());
  t.t_ref = e.t0();
  return t;
}

/// Least-squares line per channel, t_ref = mean sample time (see the file comment).
inline Trend linear_trend(const Experiment& e) {
  e.validate(false);
  detail::require_samples(e, 2, "linear_trend");
  const Eigen::VectorXd t = e.time();
  const double tm = t.mean();
  const Eigen::VectorXd dt = t.array() - tm;
  const double sxx = dt.squaredNorm();
  Trend tr;
  tr.t_ref = tm;
  tr.input_offset = e.u().colwise().mean().transpose();
  tr.output_offset = e.y().colwise().mean().transpose();
  tr.input_slope = (e.u().transpose() * dt) / sxx;
  tr.output_slope = (e.y().transpose() * dt) / sxx;
  return tr;
}

/// x(t) − x̄(t) for every channel. Missing samples stay missing.
inline Experiment remove_trend(const Experiment& e, const Trend& trend) {
  return detail::trend_applied(e, trend, 1.0,
                               "removed trend: input offset " +
                                   detail::vec_str(trend.input_offset) + ", output offset " +
                                   detail::vec_str(trend.output_offset));
}

/// x(t) + x̄(t): undoes `remove_trend` (e.g. to put a simulated output back in physical units).
inline Experiment add_trend(const Experiment& e, const Trend& trend) {
  return detail::trend_applied(e, trend, -1.0,
                               "added trend: input offset " + detail::vec_str(trend.input_offset) +
                                   ", output offset " + detail::vec_str(trend.output_offset));
}

/// Subtracts the constants `u_off` (n_u) and `y_off` (n_y) from the channels.
inline Experiment remove_offset(const Experiment& e, const Eigen::VectorXd& u_off,
                                const Eigen::VectorXd& y_off) {
  return remove_trend(e, Trend::constant(u_off, y_off));
}

/// Subtracts `u_off` from every input and `y_off` from every output.
inline Experiment remove_offset(const Experiment& e, double u_off, double y_off) {
  return remove_offset(e, Eigen::VectorXd::Constant(e.num_inputs(), u_off),
                       Eigen::VectorXd::Constant(e.num_outputs(), y_off));
}

/// Subtracts each channel's mean (MATLAB `detrend(data, 0)`).
inline Experiment remove_mean(const Experiment& e) { return remove_trend(e, mean_trend(e)); }

/// Subtracts each channel's least-squares line (MATLAB `detrend(data, 1)`).
inline Experiment detrend(const Experiment& e) { return remove_trend(e, linear_trend(e)); }

/// Samples `first` … `first + count − 1` (0-based), keeping their times.
inline Experiment select_samples(const Experiment& e, Eigen::Index first, Eigen::Index count) {
  e.validate(true);
  if (first < 0 || count < 1 || first > e.size() - count) {
    // first + count may overflow for absurd counts: name the two numbers instead.
    throw Error("sample range of " + std::to_string(count) + " sample(s) from index " + std::to_string(first) +
                    " is empty or outside the record of " + std::to_string(e.size()) + " samples",
                at_parameter("first"));
  }
  Experiment out =
      detail::with_samples(e, e.u().middleRows(first, count), e.y().middleRows(first, count),
                           e.ts(), e.t0() + static_cast<double>(first) * e.ts());
  out.add_note("selected samples " + std::to_string(first) + ".." +
               std::to_string(first + count - 1));
  return out;
}

/// Samples with t_begin ≤ t_k ≤ t_end. Throws if the window is reversed, reaches outside the
/// record [t_0, t_end] by more than half a sample, or contains no sample.
inline Experiment select(const Experiment& e, double t_begin, double t_end) {
  e.validate(true);
  const std::string range = "[" + detail::format_g(t_begin, 10) + ", " + detail::format_g(t_end, 10) + "]";
  const std::string rec = "[" + detail::format_g(e.t0(), 10) + ", " + detail::format_g(e.t_end(), 10) + "]";
  if (!std::isfinite(t_begin) || !std::isfinite(t_end) || t_begin > t_end) {
    throw Error("time window " + range + " is not a finite, ordered interval",
                at_parameter("t_begin"));
  }
  if (e.empty()) throw Error("cannot select from an empty experiment", at_parameter("t_begin"));
  const double half = 0.5 * e.ts();
  if (t_begin < e.t0() - half || t_end > e.t_end() + half) {
    throw Error("time window " + range + " reaches outside the record " + rec,
                at_parameter(t_begin < e.t0() - half ? "t_begin" : "t_end"));
  }
  // (0.5 − 0)/0.1 evaluates to 4.999…: without the allowance, asking for t = 0.5 would silently
  // start at 0.6. 1e-9 of a sample is far below any meaningful time but far above rounding.
  const double eps = 1e-9;
  const auto k0 = static_cast<Eigen::Index>(std::ceil((t_begin - e.t0()) / e.ts() - eps));
  const auto k1 = static_cast<Eigen::Index>(std::floor((t_end - e.t0()) / e.ts() + eps));
  const Eigen::Index first = std::max<Eigen::Index>(k0, 0);
  const Eigen::Index last = std::min<Eigen::Index>(k1, e.size() - 1);
  if (last < first) {
    throw Error(
        "time window " + range + " contains no sample (sample time " + detail::format_g(e.ts(), 10) + ")",
        at_parameter("t_begin"));
  }
  Experiment out = select_samples(e, first, last - first + 1);
  out.add_note("selected time window " + range);
  return out;
}

/// The named input and output channels, in the order given (MATLAB `z(:, 'y2', 'u1')`); names,
/// units and times are kept. Throws naming an unknown channel and listing the available ones.
inline Experiment select_channels(const Experiment& e, const std::vector<std::string>& inputs,
                                  const std::vector<std::string>& outputs) {
  e.validate(true);
  auto pick = [](const Eigen::MatrixXd& x, const std::vector<std::string>& have,
                 const std::vector<std::string>& units, const std::vector<std::string>& want,
                 const char* kind, std::vector<std::string>& out_units) {
    Eigen::MatrixXd out(x.rows(), static_cast<Eigen::Index>(want.size()));
    for (std::size_t j = 0; j < want.size(); ++j) {
      const auto it = std::find(have.begin(), have.end(), want[j]);
      if (it == have.end()) {
        std::string list;
        for (const auto& h : have) list += (list.empty() ? "'" : ", '") + h + "'";
        throw Error(std::string("no ") + kind + " channel named '" + want[j] +
                        "'; available: " + (list.empty() ? "(none)" : list),
                    at_parameter(std::string(kind) + "s"));
      }
      const auto c = static_cast<std::size_t>(it - have.begin());
      out.col(static_cast<Eigen::Index>(j)) = x.col(static_cast<Eigen::Index>(c));
      out_units.push_back(units[c]);
    }
    return out;
  };
  std::vector<std::string> iu, ou;
  Eigen::MatrixXd u = pick(e.u(), e.input_names(), e.input_units(), inputs, "input", iu);
  Eigen::MatrixXd y = pick(e.y(), e.output_names(), e.output_units(), outputs, "output", ou);
  Experiment out(std::move(u), std::move(y), e.ts(), e.name(), NonFinitePolicy::keep);
  out.set_t0(e.t0());
  out.set_input_names(inputs);
  out.set_output_names(outputs);
  out.set_input_units(std::move(iu));
  out.set_output_units(std::move(ou));
  for (const auto& n : e.notes()) out.add_note(n);
  // Which columns of the original record these are is part of its history, as for a window.
  const auto list = [](const std::vector<std::string>& names) {
    std::string s;
    for (const auto& n : names) s += (s.empty() ? "'" : ", '") + n + "'";
    return s.empty() ? std::string("none") : s;
  };
  out.add_note("selected channels: inputs " + list(inputs) + "; outputs " + list(outputs));
  return out;
}

/// The same channels taken from every experiment.
inline Dataset select_channels(const Dataset& d, const std::vector<std::string>& inputs,
                               const std::vector<std::string>& outputs) {
  return detail::per_experiment(
      d, [&](const Experiment& e) { return select_channels(e, inputs, outputs); });
}

/// Same offsets removed from every experiment.
inline Dataset remove_offset(const Dataset& d, const Eigen::VectorXd& u_off,
                             const Eigen::VectorXd& y_off) {
  return detail::per_experiment(
      d, [&](const Experiment& e) { return remove_offset(e, u_off, y_off); });
}
/// Same scalar offsets removed from every channel of every experiment.
inline Dataset remove_offset(const Dataset& d, double u_off, double y_off) {
  return detail::per_experiment(
      d, [&](const Experiment& e) { return remove_offset(e, u_off, y_off); });
}
/// Each experiment's own means removed.
inline Dataset remove_mean(const Dataset& d) {
  return detail::per_experiment(d, [](const Experiment& e) { return remove_mean(e); });
}
/// Each experiment's own linear trend removed.
inline Dataset detrend(const Dataset& d) {
  return detail::per_experiment(d, [](const Experiment& e) { return detrend(e); });
}
/// The same trend removed from every experiment.
inline Dataset remove_trend(const Dataset& d, const Trend& trend) {
  return detail::per_experiment(d, [&](const Experiment& e) { return remove_trend(e, trend); });
}
/// The same trend added to every experiment.
inline Dataset add_trend(const Dataset& d, const Trend& trend) {
  return detail::per_experiment(d, [&](const Experiment& e) { return add_trend(e, trend); });
}
/// The same time window cut from every experiment.
inline Dataset select(const Dataset& d, double t_begin, double t_end) {
  return detail::per_experiment(d, [&](const Experiment& e) { return select(e, t_begin, t_end); });
}

/// The same sample range cut from every experiment (an experiment too short for it is named).
inline Dataset select_samples(const Dataset& d, Eigen::Index first, Eigen::Index count) {
  return detail::per_experiment(d, [&](const Experiment& e) { return select_samples(e, first, count); });
}

/// Pooled channel means over all samples of all experiments, as a constant trend: the one
/// operating point to remove from estimation and validation data alike.
inline Trend mean_trend(const Dataset& d) {
  if (d.empty()) throw Error("empty data set has no mean", at_parameter("dataset"));
  Eigen::VectorXd su = Eigen::VectorXd::Zero(d.num_inputs());
  Eigen::VectorXd sy = Eigen::VectorXd::Zero(d.num_outputs());
  Eigen::Index n = 0;
  for (std::size_t i = 0; i < d.size(); ++i) {
    try {
      d[i].validate(false);
    } catch (const Error& err) {
      Location l = err.where();
      l.experiment = static_cast<long>(i);
      throw Error(err.message(), l);
    }
    // Sums, not means of means: every sample weighs the same, so a long record counts more.
    su += d[i].u().colwise().sum().transpose();
    sy += d[i].y().colwise().sum().transpose();
    n += d[i].size();
  }
  if (n == 0) throw Error("data set has no samples", at_parameter("dataset"));
  Trend t = Trend::constant(su / static_cast<double>(n), sy / static_cast<double>(n));
  t.t_ref = d[0].t0();
  return t;
}

}  // namespace nlid
