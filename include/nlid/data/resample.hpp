#pragma once
/// @file
/// Changing the sample time: `decimate` (integer factor, anti-alias filtered) and `resample`
/// (any new sample time).
///
/// Why filter. Keeping every r-th sample of x(k) folds every frequency above the new Nyquist
/// frequency f_s/(2r) back into [0, f_s/(2r)] (aliasing; Ljung 1999, sec. 13.7): sensor noise
/// at 300 Hz would appear in 100 Hz data as a slow, "real-looking" disturbance. So `decimate`
/// first low-passes every channel with `filtfilt(chebyshev1_lowpass(8, 0.05, 0.8/r))`, then keeps
/// samples 0, r, 2r, … — the recipe of MATLAB `decimate`, realised here as zero-phase
/// second-order sections (see filter.hpp). With the defaults, for every factor r ≥ 2:
///
///   - pass band f ≤ 0.8 · f_s/(2r):       gain in [0, +0.10] dB, phase exactly 0;
///   - stop band f ≥ f_s/(2r) (new Nyquist): attenuation ≥ 45.5 dB (66 dB for r = 2);
///   - DC gain exactly 1 (a constant passes bit-exactly; the throttle's 15° offset is kept);
///   - edges: odd reflection and steady-state start, no start-up transient.
///
/// Inputs and outputs go through the same linear filter L(q), which leaves an LTI relation
/// y = G(q)u intact (L y = G L u; Ljung 1999, sec. 14.1, prefiltering). For a piecewise-constant
/// command whose steps must stay sharp, set `filter_inputs = false`: the input is then sampled,
/// which is exact at the new rate only if it changes on the new grid.
///
/// `resample(e, new_ts)` handles non-integer ratios: for a longer sample time it low-passes at
/// 0.8 × the new Nyquist frequency and then interpolates; for a shorter one it interpolates
/// only (no new information is created; Ljung 1999, sec. 13.7). Interpolation is a not-a-knot
/// cubic spline by default (error O(h⁴) for smooth signals), linear, or hold (zero-order hold:
/// the value of the most recent sample, right for piecewise-constant commands).

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
#include "nlid/data/detail/spline.hpp"
#include "nlid/data/experiment.hpp"
#include "nlid/data/filter.hpp"

namespace nlid {

/// Anti-alias filter settings of `decimate` (defaults as MATLAB `decimate`).
struct DecimateOptions {
  int order = 8;               ///< Chebyshev type I order
  double ripple_db = 0.05;     ///< single-pass pass-band ripple (zero-phase: twice this)
  double cutoff = 0.8;         ///< pass-band edge as a fraction of the *new* Nyquist frequency
  bool filter_inputs = true;   ///< low-pass the inputs (false: sample them, for held commands)
  bool filter_outputs = true;  ///< low-pass the outputs
};

/// How `resample` evaluates a channel between the original samples.
enum class Interpolation {
  hold,    ///< zero-order hold: the most recent sample (piecewise-constant commands); not filtered
  linear,  ///< straight line between neighbours
  spline,  ///< not-a-knot cubic spline (band-limited signals)
};

/// Settings of `resample`.
struct ResampleOptions {
  Interpolation inputs = Interpolation::spline;   ///< input channels
  Interpolation outputs = Interpolation::spline;  ///< output channels
  int order = 8;            ///< anti-alias Chebyshev order (longer sample time only)
  double ripple_db = 0.05;  ///< anti-alias ripple (single pass)
  double cutoff = 0.8;      ///< anti-alias edge as a fraction of the new Nyquist frequency
};

/// Decimation by an integer `factor` ≥ 1: zero-phase anti-alias low-pass, then samples
/// 0, r, 2r, …, so t_0 is kept, `ts` becomes r·ts and the length is ⌈N/r⌉. Throws if the record
/// has missing samples (fill them first) or the options are invalid. See the file comment.
inline Experiment decimate(const Experiment& e, int factor, const DecimateOptions& options = {}) {
  e.validate(false);
  if (factor < 1) {
    throw Error("decimation factor must be >= 1, got " + std::to_string(factor),
                at_parameter("factor"));
  }
  if (factor == 1) return e;
  // One sample out is no record, and what the filter leaves of it is mostly its start-up.
  if (e.size() <= factor) {
    throw Error("decimation by " + std::to_string(factor) + " needs more than " + std::to_string(factor) +
                    " samples (at least two out), the record has " + std::to_string(e.size()),
                at_parameter("factor"));
  }
  if (!(options.cutoff > 0.0 && options.cutoff < 1.0)) {
    throw Error(
        "cutoff must lie strictly between 0 and 1 (fraction of the new Nyquist "
        "frequency), got " +
            detail::format_g(options.cutoff, 10),
        at_parameter("cutoff"));
  }
  const double edge = options.cutoff / static_cast<double>(factor);
  const bool filtered = options.filter_inputs || options.filter_outputs;
  // Named here rather than left to the filter design, which could only blame its 'cutoff'.
  if (filtered && edge < min_lowpass_cutoff) {
    throw Error("decimation by " + std::to_string(factor) + " in one step needs an anti-alias low-pass at " +
                    detail::format_g(edge, 6) +
                    " of the Nyquist frequency, narrower than double precision can realise (1e-06); "
                    "decimate in stages",
                at_parameter("factor"));
  }
  const SosFilter lp = filtered ? chebyshev1_lowpass(options.order, options.ripple_db, edge) : SosFilter();
  const Eigen::Index m = e.size() == 0 ? 0 : (e.size() - 1) / factor + 1;
  auto pick = [&](const Eigen::MatrixXd& x, bool filter) {
    const Eigen::MatrixXd f = filter ? Eigen::MatrixXd(filtfilt(lp, x)) : x;
    Eigen::MatrixXd out(m, x.cols());
    for (Eigen::Index k = 0; k < m; ++k) out.row(k) = f.row(k * factor);
    return out;
  };
  Experiment out = detail::with_samples(e, pick(e.u(), options.filter_inputs),
                                        pick(e.y(), options.filter_outputs),
                                        e.ts() * static_cast<double>(factor), e.t0());
  out.add_note("decimated by " + std::to_string(factor) + " (zero-phase Chebyshev I order " +
               std::to_string(options.order) + ", edge " + detail::format_g(options.cutoff, 10) +
               " x new Nyquist" + (options.filter_inputs ? "" : "; inputs sampled unfiltered") +
               (options.filter_outputs ? "" : "; outputs sampled unfiltered") + ")");
  return out;
}

/// New sample time `new_ts` (any positive value). An integer multiple of `ts` (within 1e-9) is
/// delegated to `decimate`. Otherwise: samples at t_0 + k·new_ts up to the last original time;
/// for new_ts > ts the spline/linear channels are first low-passed (edge `cutoff` × new Nyquist).
/// Throws if `new_ts` is not positive and finite or the record has missing samples.
inline Experiment resample(const Experiment& e, double new_ts,
                           const ResampleOptions& options = {}) {
  e.validate(false);
  if (!(new_ts > 0.0) || !std::isfinite(new_ts)) {
    throw Error("new sample time must be positive and finite, got " + detail::format_g(new_ts, 10),
                at_parameter("new_ts"));
  }
  const double ratio = new_ts / e.ts();
  const double r = std::round(ratio);
  if (r >= 1.0 && std::abs(ratio - r) <= 1e-9 * ratio && r < 1e9) {
    // An exact multiple gets the exact algorithm (no interpolation error at all); held channels
    // are sampled, which is what a zero-order hold means at the coarser grid.
    DecimateOptions d;
    d.order = options.order;
    d.ripple_db = options.ripple_db;
    d.cutoff = options.cutoff;
    d.filter_inputs = options.inputs != Interpolation::hold;
    d.filter_outputs = options.outputs != Interpolation::hold;
    Experiment out = decimate(e, static_cast<int>(r), d);
    out.set_ts(new_ts);  // exactly what was asked, not r·ts rounded
    return out;
  }
  if (e.size() < 2) {
    throw Error("resampling needs at least 2 samples, the record has " + std::to_string(e.size()),
                at_parameter("new_ts"));
  }
  const double span = static_cast<double>(e.size() - 1) * e.ts();
  // The last new sample may coincide with the last old one; 1e-12 keeps rounding from dropping it.
  const double count = std::floor(span / new_ts * (1.0 + 1e-12)) + 1.0;
  // As `decimate`: one sample out is no record (and with a ratio above N - 1 nothing but the
  // first sample would be kept, silently).
  if (count < 2.0) {
    throw Error("resampling " + std::to_string(e.size()) + " samples from ts " + detail::format_g(e.ts(), 10) +
                    " to " + detail::format_g(new_ts, 10) + " would leave " + detail::format_g(count, 10) +
                    " sample (at least two out are needed); choose a shorter sample time or a longer record",
                at_parameter("new_ts"));
  }
  // A sample time far below the record's would ask for more samples than memory holds (or an
  // index type does): say so instead of overflowing the count.
  if (!(count <= 2147483647.0)) {
    throw Error("resampling to " + detail::format_g(new_ts, 10) + " s would give " + detail::format_g(count, 10) +
                    " samples (more than 2^31 - 1); choose a longer sample time or a shorter record",
                at_parameter("new_ts"));
  }
  const auto m = static_cast<Eigen::Index>(count);
  Eigen::VectorXd pos(m);  // new sample instants in units of old samples
  for (Eigen::Index k = 0; k < m; ++k) {
    pos(k) = std::min(static_cast<double>(k) * ratio, static_cast<double>(e.size() - 1));
  }
  // Only a longer sample time can alias. Shorter ones interpolate the samples as they are: any
  // filter there would only remove information the record has.
  SosFilter lp;
  const bool down = ratio > 1.0;
  const bool filtered = options.inputs != Interpolation::hold || options.outputs != Interpolation::hold;
  if (down && filtered) {
    if (options.cutoff > 0.0 && options.cutoff / ratio < min_lowpass_cutoff) {
      throw Error("resampling from ts " + detail::format_g(e.ts(), 10) + " to " + detail::format_g(new_ts, 10) +
                      " in one step needs an anti-alias low-pass at " + detail::format_g(options.cutoff / ratio, 6) +
                      " of the Nyquist frequency, narrower than double precision can realise (1e-06); "
                      "decimate or resample in stages",
                  at_parameter("new_ts"));
    }
    lp = chebyshev1_lowpass(options.order, options.ripple_db, options.cutoff / ratio);
  }
  auto convert = [&](const Eigen::MatrixXd& x, Interpolation how) {
    Eigen::MatrixXd src = x;
    if (down && how != Interpolation::hold) src = filtfilt(lp, x);
    Eigen::MatrixXd out(m, x.cols());
    for (Eigen::Index c = 0; c < x.cols(); ++c) {
      out.col(c) = how == Interpolation::spline
                       ? detail::spline_at(src.col(c), pos)
                       : detail::step_or_line_at(src.col(c), pos, how == Interpolation::hold);
    }
    return out;
  };
  Experiment out = detail::with_samples(e, convert(e.u(), options.inputs),
                                        convert(e.y(), options.outputs), new_ts, e.t0());
  out.add_note(
      "resampled from ts " + detail::format_g(e.ts(), 10) + " to " + detail::format_g(new_ts, 10) +
      (down ? " (zero-phase anti-alias low-pass, then interpolation)" : " (interpolation)"));
  return out;
}

/// `decimate` applied to every experiment; errors name the experiment index.
inline Dataset decimate(const Dataset& d, int factor, const DecimateOptions& options = {}) {
  return detail::per_experiment(d,
                                [&](const Experiment& e) { return decimate(e, factor, options); });
}

/// `resample` applied to every experiment; errors name the experiment index.
inline Dataset resample(const Dataset& d, double new_ts, const ResampleOptions& options = {}) {
  return detail::per_experiment(d,
                                [&](const Experiment& e) { return resample(e, new_ts, options); });
}

}  // namespace nlid
