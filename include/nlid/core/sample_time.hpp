#pragma once
/// @file
/// When two sample times are "the same": one relative tolerance for every check in nlid (records
/// merged into a data set, a record against a model, a generator's sample time against the
/// model's).
///
/// Why 10⁻⁶ and not tighter: a sample time read from jittering time stamps is only known to the
/// stamps' precision, and when no short decimal or rate fits them `read_csv` keeps the end-point
/// estimate (t_{N−1} − t₀)/(N−1). Two records of one 100 Hz logger with ±2 µs of jitter then came
/// out 10⁻⁸ apart — a 10⁻⁹ rule refused to merge them, and refused to simulate a model on the
/// records it was estimated from. A relative 10⁻⁶ still catches every real mismatch
/// (a record at another rate, a decimation forgotten), and over 10⁶ samples it amounts to one
/// sample of drift.

#include <cmath>

namespace nlid {

/// Relative tolerance of "same sample time" (see the file comment).
inline constexpr double sample_time_tolerance = 1e-6;

/// Sample times that differ (beyond `sample_time_tolerance`) by less than this, relatively, are
/// almost surely one logger's rate read from differently jittering or rounded stamps: messages then
/// suggest giving that one rate (CsvReadOptions::ts, --ts) rather than resampling.
inline constexpr double one_rate_hint_tolerance = 1e-3;

/// |a − b| ≤ sample_time_tolerance · |b|: `b` is the reference (the model's, the data set's).
inline bool same_sample_time(double a, double b) {
  return std::abs(a - b) <= sample_time_tolerance * std::abs(b);
}

}  // namespace nlid
