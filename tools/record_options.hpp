#pragma once
// How the command-line tools read a record: the time column, an explicit sample time, the field
// separator and the decimal point. Shared by nlid-fit, nlid-sim and nlid-diagnose so the three
// accept the same options with the same meaning.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/core/sample_time.hpp"
#include "nlid/data/csv.hpp"
#include "cli_common.hpp"

namespace nlid_tools {

/// The record-reading options of a tool's command line.
struct RecordOptions {
  std::string time = "t";  ///< time column
  bool time_given = false; ///< --time was on the command line: the column must exist
  double ts = 0.0;         ///< sample time (s); 0: from the time column
  char delimiter = ',';    ///< field separator; ' ' = runs of blanks
  char decimal = '.';      ///< decimal point
  /// Accepted relative deviation of one time step from the typical one (CsvReadOptions's 1 %
  /// by default); loggers with jittery stamps need more, a dropped sample (100 %) stays an error.
  double time_tolerance = nlid::CsvReadOptions{}.time_tolerance;
};

/// Usage lines of the options, for a tool's help text.
inline constexpr const char* record_usage =
    "  --time NAME       time column (default t); the sample time is read from it\n"
    "  --ts T            sample time in seconds (needed if the files have no time column)\n"
    "  --delimiter C     field separator: , (default) ; tab space |\n"
    "  --decimal C       decimal point: . (default) or , (then the separator must be another)\n"
    "  --time-tolerance R  accepted relative deviation of a time step from the typical one\n"
    "                    (default 0.01; at most 0.5, so a dropped sample is still found)\n";

/// Consumes option `k` with value `v` if it is one of the record options (returns false
/// otherwise). Throws naming the option for a bad value: `nlid::Error`, or `UsageError` from the
/// shared number parsers (--ts); `record_options_from` makes both a usage error.
inline bool parse_record_option(const std::string& k, const std::string& v, RecordOptions& o) {
  if (k == "--time") {
    if (v.empty()) throw nlid::Error("--time needs a column name", nlid::at_parameter(k));
    o.time = v;
    o.time_given = true;
  } else if (k == "--ts") {
    o.ts = parse_sample_time(k, v);
  } else if (k == "--delimiter") {
    if (v == "," || v == ";" || v == "|") o.delimiter = v[0];
    else if (v == "tab" || v == "\\t" || v == "\t") o.delimiter = '\t';
    else if (v == "space" || v == " ") o.delimiter = ' ';
    else throw nlid::Error("--delimiter must be one of , ; tab space |, got '" + v + "'", nlid::at_parameter(k));
  } else if (k == "--time-tolerance") {
    char* end = nullptr;
    const double x = std::strtod(v.c_str(), &end);
    // Above 0.5 a step of 1.5 T would pass, and a record with every other sample dropped could
    // read as uniform at twice the step: the option is for jitter, not for gaps.
    if (v.empty() || end != v.c_str() + v.size() || !(x >= 0.0 && x <= 0.5))
      throw nlid::Error("--time-tolerance needs a relative step deviation from 0 to 0.5 (e.g. 0.05 for 5 %), got '" + v +
                            "'",
                        nlid::at_parameter(k));
    o.time_tolerance = x;
  } else if (k == "--decimal") {
    if (v != "." && v != ",") throw nlid::Error("--decimal must be . or , (got '" + v + "')", nlid::at_parameter(k));
    o.decimal = v[0];
  } else {
    return false;
  }
  return true;
}

/// Throws if the options cannot work together (a decimal comma needs another separator).
inline void check_record_options(const RecordOptions& o) {
  if (o.decimal == ',' && o.delimiter == ',')
    throw nlid::Error("--decimal , needs another field separator, e.g. --delimiter ';'", nlid::at_parameter("--decimal"));
}

inline constexpr const char* record_option_names[] = {"--time", "--ts", "--delimiter", "--decimal", "--time-tolerance"};

/// The options in a tool's table (parse_options), after the tool's own.
inline std::vector<OptionSpec> with_record_options(std::vector<OptionSpec> options) {
  for (const char* name : record_option_names) options.push_back({name});
  return options;
}

/// The record options of a parsed command line. The tools treat a bad value, or a pair that
/// cannot work together, as a bad command line (exit 2), with the option named.
inline RecordOptions record_options_from(const ParsedOptions& p) {
  RecordOptions o;
  try {
    for (const char* name : record_option_names)
      if (p.has(name)) parse_record_option(name, p.get(name), o);
    check_record_options(o);
  } catch (const nlid::Error& e) {
    throw UsageError(e.what());
  }
  return o;
}

/// The header of `path` (its first line that is neither blank nor a '#' comment), split as
/// read_csv splits it; false for an unreadable or malformed file (read_csv then reports the
/// problem with its location).
inline bool read_header(const std::string& path, char delimiter, std::vector<std::string>& fields) {
  std::ifstream f(path);
  std::string line;
  for (bool first_line = true; f && std::getline(f, line); first_line = false) {
    if (first_line && line.rfind("\xEF\xBB\xBF", 0) == 0) line.erase(0, 3);  // UTF-8 byte-order mark
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const auto first = line.find_first_not_of(" \t");
    if (first == std::string::npos || line[first] == '#') continue;
    try {
      nlid::detail::split_csv_line(line, delimiter, fields, path, 0);
    } catch (const nlid::Error&) {
      return false;
    }
    return true;
  }
  return false;
}

/// True if the header of `path` names a column `name`. Unreadable or malformed files answer true:
/// read_csv then reports the problem with its location.
inline bool header_has(const std::string& path, const std::string& name, char delimiter) {
  std::vector<std::string> fields;
  return !read_header(path, delimiter, fields) || std::find(fields.begin(), fields.end(), name) != fields.end();
}

/// A sample time for messages: 10 significant digits and " s" (std::to_string's six decimals
/// print 20 µs as "0.000020" whatever the digits after).
inline std::string format_seconds(double s) { return nlid::detail::format_g(s, 10) + " s"; }

/// What to do about two records' sample times `a` and `b` that differ: within
/// nlid::one_rate_hint_tolerance, give the one rate with --ts (it sets every file's); farther
/// apart the records were sampled at different rates.
inline std::string sample_time_remedy(double a, double b) {
  const double rel = std::abs(a - b) / std::max(std::abs(a), std::abs(b));
  return rel < nlid::one_rate_hint_tolerance ? "if both were logged at one rate, give that sample time with --ts"
                    : "resample one of them to the other's rate first";
}

/// `CsvReadOptions` for reading `path` with these options: with `--ts` and no time column in the
/// file, the file is read without one (t₀ = 0). Only the default name may be missing: a --time
/// the user typed and the file lacks is a misspelling, and reading on without it would drop the
/// time column and its check for dropped samples without a word.
inline nlid::CsvReadOptions csv_read_options(const RecordOptions& o, const std::string& path) {
  nlid::CsvReadOptions c;
  c.ts = o.ts;
  c.delimiter = o.delimiter;
  c.decimal_point = o.decimal;
  c.time_column = o.time;
  c.time_tolerance = o.time_tolerance;
  std::vector<std::string> header;
  if (o.ts > 0.0 && read_header(path, o.delimiter, header) &&
      std::find(header.begin(), header.end(), o.time) == header.end()) {
    if (o.time_given) {
      nlid::Location l = nlid::at_parameter("--time");
      l.file = path;
      throw nlid::Error("no column named '" + nlid::detail::printable(o.time) +
                            "' (--time); available columns: " + nlid::detail::quoted_list(header),
                        l);
    }
    c.time_column.clear();
  }
  return c;
}

/// Reads `path` with these options (read_csv), adding the tools' hints: --decimal for a cell with a
/// decimal comma. With --ts and a time column, read_csv still refuses a gap (a dropped sample), and
/// a column at another rate than --ts is printed as "TOOL: note: FILE: --ts T s overrides ...".

inline nlid::Experiment read_record(const RecordOptions& o, const std::string& path,
                                    const std::vector<std::string>& inputs, const std::vector<std::string>& outputs,
                                    const std::string& tool) {
  nlid::CsvReadOptions c = csv_read_options(o, path);
  c.inputs = inputs;
  c.outputs = outputs;
  try {
    nlid::CsvReadInfo info;
    nlid::Experiment e = nlid::read_csv(path, c, info);
    // The same test as read_csv's note: a step off --ts by more than the time tolerance.
    const double step = info.time_column_step;
    if (o.ts > 0.0 && std::isfinite(step) && std::abs(step - o.ts) > c.time_tolerance * o.ts) {
      std::cerr << tool << ": note: " << path << ": --ts " << format_seconds(o.ts) << " overrides the sample time "
                << format_seconds(step) << " of its time column '" << o.time << "'\n";
    }
    return e;
  } catch (const nlid::Error& e) {
    const std::string hint = decimal_hint(e, o.delimiter, o.decimal);
    if (hint.empty()) throw;
    throw nlid::Error(e.message() + hint, e.where());
  }
}

}  // namespace nlid_tools
