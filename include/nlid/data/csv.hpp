#pragma once
/// @file
/// Reading and writing experiments as CSV text (one header row, one row per sample).
///
/// Format. The first line that is neither blank nor a `#` comment is the header; every later
/// non-blank, non-comment line is one sample with exactly as many fields as the header. Fields
/// are separated by `delimiter` (',' by default; ' ' means "runs of blanks"), may be surrounded by
/// spaces and may be double-quoted (RFC 4180: `""` inside quotes is one quote). CRLF line ends,
/// a UTF-8 byte-order mark and a final newline are accepted, as spreadsheets and MATLAB
/// `writetable` produce them. Numbers use C syntax (`1`, `-2.5e-3`, `nan`, `inf`); an empty cell is
/// a missing value.
///
///     t,u,y
///     0.000,0,14.9
///     0.001,0,15.1
///
/// Sample time. Every step of the time column must be increasing and lie within
/// `time_tolerance` of the median step (plus a few units in the last place of |t|, which a large
/// t_0 such as Unix time needs); a dropped sample (a step of 2·T_s) is therefore reported, not
/// smoothed over, with or without an override. Unless `CsvReadOptions::ts` overrides it, T_s is
/// then the shortest decimal whose grid t_0 + k·T_s reproduces the column exactly (so
/// `write_csv` → `read_csv` returns the same `ts` bit for bit), else the shortest decimal or rate
/// that reproduces stamps printed with fixed decimals to their resolution, else the shortest
/// decimal or rate within what jittering stamps can tell, else (t_{N−1} − t_0)/(N−1)
/// (`detail::snap_sample_time`). The uniform grid is what every
/// discrete-time model assumes (Ljung 1999, sec. 2.1).
///
/// Errors. Every problem throws `nlid::Error` whose message says what is wrong and whose
/// location names the file, the 1-based line number ("row", as an editor shows it) and the
/// column (1-based number and header name), e.g.
///
///     nlid: non-numeric cell 'abc' [at file 'run3.csv', row 17, column 3 ('y')]
///
/// Writing goes through `nlid::write_file_atomically` (a crash never leaves half a file) and
/// prints the shortest decimal that reads back to the same double (`std::to_chars`), so
/// write → read is exact.

#include <Eigen/Core>
#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <string>
#include <string_view>
#include <system_error>
#include <tuple>
#include <utility>
#include <vector>

#include "nlid/core/atomic_file.hpp"
#include "nlid/core/error.hpp"
#include "nlid/core/utf8.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/data/detail/csv_parse.hpp"
#include "nlid/data/experiment.hpp"

namespace nlid {

/// How `read_csv` maps columns of a file onto an `Experiment`.
struct CsvReadOptions {
  /// Name of the time column; "" if the file has none (then `ts` must be given, and t_0 = 0).
  std::string time_column = "t";
  /// Input columns, in order (empty for a time series).
  std::vector<std::string> inputs{"u"};
  /// Output columns, in order.
  std::vector<std::string> outputs{"y"};
  /// Sample time override; 0 means "infer from the time column". When given, the time column
  /// supplies t_0 and must still be increasing and evenly spaced (a gap is an error: the
  /// override would hide a lost sample); a rate different from the column's is recorded in the
  /// notes.
  double ts = 0.0;
  /// What to do with NaN/Inf/empty cells in input and output columns.
  NonFinitePolicy non_finite = NonFinitePolicy::error;
  /// Field separator. ' ' splits on runs of spaces and tabs.
  char delimiter = ',';
  /// Decimal separator of the numbers ('.' or ','; ',' needs another delimiter, e.g. ';', and
  /// refuses a number holding a '.', which there is a thousands separator or a wrong option).
  char decimal_point = '.';
  /// Largest accepted relative deviation |Δt − T_s| / T_s of one time step. 1 % absorbs rounding
  /// of printed time stamps and logger jitter, yet flags a dropped sample (100 %).
  double time_tolerance = 1e-2;
  /// Longest gap (samples) that `NonFinitePolicy::interpolate` may fill.
  int max_gap = default_max_gap;
};

/// What `read_csv` learnt about a file beyond the experiment itself.
struct CsvReadInfo {
  /// The time column's typical (median) step in seconds; NaN without a time column or with a
  /// single row. With `CsvReadOptions::ts` set, compare the two to see whether the override
  /// changes the rate (the experiment's notes say so in words).
  double time_column_step = std::numeric_limits<double>::quiet_NaN();
};

/// Options of the generic table reader.
struct CsvTableOptions {
  char delimiter = ',';                                 ///< field separator (' ' = blank runs)
  char decimal_point = '.';                             ///< decimal separator of the numbers
  NonFinitePolicy non_finite = NonFinitePolicy::error;  ///< NaN/Inf/empty cells, all columns
  int max_gap = default_max_gap;  ///< longest gap `interpolate` fills (per column)
  /// Accept a header whose every name is a number (pandas' default names 0, 1, …). Off, such a
  /// first row is refused: it is far more often the first sample of a file without a header.
  bool numeric_header = false;
};

/// Options of `write_csv`.
struct CsvWriteOptions {
  std::string time_column = "t";  ///< header of the time column
  char delimiter = ',';           ///< field separator
};

/// A numeric table: header names and an N × m matrix, row k = data line k of the file.
struct CsvTable {
  std::vector<std::string> header;  ///< column names, in file order
  Eigen::MatrixXd data;             ///< N × m values
  std::string file;                 ///< the file it was read from ("" if built in memory)

  /// Index of the column called `name`; throws `nlid::Error` listing the available columns.
  [[nodiscard]] Eigen::Index column(std::string_view name) const {
    for (std::size_t j = 0; j < header.size(); ++j) {
      if (header[j] == name) return static_cast<Eigen::Index>(j);
    }
    Location l;
    l.file = file;
    l.column_name = detail::printable(std::string(name), std::string::npos);
    throw Error("no column named '" + detail::printable(std::string(name)) +
                    "'; available columns: " + detail::quoted_list(header),
                l);
  }
  /// The column called `name` as a vector.
  [[nodiscard]] Eigen::VectorXd col(std::string_view name) const { return data.col(column(name)); }
};

namespace detail {
// Checks the format options every reader shares; a bad one is named before the file is opened.
inline void check_csv_format(char delimiter, char decimal_point, int max_gap) {
  const auto d = static_cast<unsigned char>(delimiter);
  require(delimiter == '\t' || (d >= 0x20 && d != 0x7f && delimiter != '"' && !(delimiter >= '0' && delimiter <= '9') &&
                                 delimiter != '.' && delimiter != '-' && delimiter != '+'),
          "delimiter must be a printable separator such as ',', ';', ' ' or a tab (not a digit, sign, '.', quote "
          "or control character), got code " + std::to_string(static_cast<int>(d)),
          at_parameter("delimiter"));
  require(decimal_point == '.' || decimal_point == ',',
          std::string("decimal_point must be '.' or ',', got '") + decimal_point + "'", at_parameter("decimal_point"));
  require(decimal_point != delimiter,
          "decimal_point and delimiter are both '" + std::string(1, delimiter) +
              "'; with decimal commas use another delimiter, e.g. ';'",
          at_parameter("decimal_point"));
  require(max_gap >= 0, "max_gap must be >= 0 samples, got " + std::to_string(max_gap), at_parameter("max_gap"));
}
}  // namespace detail

/// Reads a whole numeric CSV file: every column must be numeric (NaN/Inf/empty cells follow
/// `options.non_finite`). For tools that handle arbitrary tables; experiments use `read_csv`.
inline CsvTable read_csv_table(const std::string& path, const CsvTableOptions& options = {}) {
  detail::check_csv_format(options.delimiter, options.decimal_point, options.max_gap);
  const detail::CsvText t = detail::tokenize_csv(path, options.delimiter, options.decimal_point);
  if (!options.numeric_header && detail::header_is_numeric(t, options.decimal_point)) {
    throw detail::no_header_error(t, "; or set CsvTableOptions::numeric_header if these are the names");
  }
  CsvTable table;
  table.file = path;
  table.header = t.header;
  table.data.resize(static_cast<Eigen::Index>(t.rows.size()),
                    static_cast<Eigen::Index>(t.header.size()));
  for (std::size_t j = 0; j < t.header.size(); ++j) {
    table.data.col(static_cast<Eigen::Index>(j)) =
        detail::parse_column(t, j, options.decimal_point);
  }
  for (std::size_t j = 0; j < t.header.size(); ++j) {
    detail::apply_csv_policy(table.data, static_cast<Eigen::Index>(j), t, j, options.non_finite,
                             options.max_gap);
  }
  return table;
}

/// Writes `header` and the rows of `data` atomically, numbers in shortest round-trip form.
/// Throws, before writing anything, if the header width differs from the column count, a name is
/// empty, repeated or holds a line break, or the delimiter is one `read_csv_table` refuses.
/// Names holding the delimiter, quotes, edge blanks or a leading byte-order mark are quoted. A
/// header of numbers only reads back with `CsvTableOptions::numeric_header`.
inline void write_csv_table(const std::string& path, const std::vector<std::string>& header,
                            const Eigen::MatrixXd& data, char delimiter = ',') {
  if (header.size() != static_cast<std::size_t>(data.cols())) {
    Location l;
    l.file = path;
    l.parameter = "header";
    throw Error("header has " + std::to_string(header.size()) + " names but the matrix has " +
                    std::to_string(data.cols()) + " columns",
                l);
  }
  if (header.empty()) {
    Location l;
    l.file = path;
    throw Error("cannot write a table without columns", l);
  }
  {
    Location l;
    l.file = path;
    l.parameter = "delimiter";
    try {
      detail::check_csv_format(delimiter, '.', 0);
    } catch (const Error& err) {
      throw Error(err.message(), l);
    }
  }
  // Everything read_csv_table would refuse or misread is refused before the file is touched.
  detail::CsvNameIndex names;
  for (std::size_t j = 0; j < header.size(); ++j) {
    Location l;
    l.file = path;
    l.column = static_cast<long>(j) + 1;
    l.column_name = detail::printable(header[j], std::string::npos);
    l.parameter = "header";
    if (header[j].empty()) {
      throw Error("column " + std::to_string(j + 1) + " has an empty name; it could not be read back by name", l);
    }
    if (header[j].find_first_of("\n\r") != std::string::npos) {
      throw Error("column name contains a line break: '" + detail::printable(header[j]) + "'", l);
    }
    if (const std::size_t i = names.earlier(header[j], j); i != std::string::npos) {
      throw Error("duplicate column name '" + detail::printable(header[j]) + "' (also column " +
                      std::to_string(i + 1) + ")",
                  l);
    }
  }
  std::string out;
  out.reserve(static_cast<std::size_t>(data.size()) * 12 + 64);
  for (std::size_t j = 0; j < header.size(); ++j) {
    if (j) out += delimiter;
    out += detail::quote_if_needed(header[j], delimiter);
  }
  out += '\n';
  for (Eigen::Index r = 0; r < data.rows(); ++r) {
    for (Eigen::Index c = 0; c < data.cols(); ++c) {
      if (c) out += delimiter;
      detail::append_double(out, data(r, c));
    }
    out += '\n';
  }
  write_file_atomically(path, out);
}

/// Reads one experiment from a CSV file, taking the columns named in `options`. The experiment
/// is named after the file's stem ("data1" for ".../data1.csv"); channel names are the column
/// names. See the file comment for the accepted format and the errors.
inline Experiment read_csv(const std::string& path, const CsvReadOptions& options, CsvReadInfo& info) {
  using detail::csv_at;
  info = CsvReadInfo{};
  if (!(options.ts >= 0.0) || !std::isfinite(options.ts)) {
    Location l = at_parameter("ts");
    l.file = path;
    throw Error(
        "sample time override must be positive (or 0 to infer it from the time column), "
        "got " +
            detail::num(options.ts),
        l);
  }
  if (!(options.time_tolerance >= 0.0)) {
    throw Error("time_tolerance must be >= 0", at_parameter("time_tolerance"));
  }
  detail::check_csv_format(options.delimiter, options.decimal_point, options.max_gap);
  const detail::CsvText t = detail::tokenize_csv(path, options.delimiter, options.decimal_point);
  const auto n = static_cast<Eigen::Index>(t.rows.size());

  // Resolve the columns first: a misspelt name is reported before any cell is parsed.
  std::vector<std::size_t> in_cols, out_cols;
  for (const auto& name : options.inputs) in_cols.push_back(detail::find_column(t, name, "input"));
  for (const auto& name : options.outputs) {
    out_cols.push_back(detail::find_column(t, name, "output"));
  }
  const bool has_time = !options.time_column.empty();
  const std::size_t time_col = has_time ? detail::find_column(t, options.time_column, "time") : 0;
  detail::check_distinct_columns(t, has_time, time_col, in_cols, out_cols);

  std::vector<std::string> notes;
  notes.push_back("read from '" + path + "' (" + std::to_string(n) + " rows)");
  double ts = options.ts;
  double t0 = 0.0;
  if (has_time) {
    std::tie(ts, t0) = detail::time_axis(t, time_col, options.decimal_point, options.ts,
                                         options.time_tolerance, notes, &info.time_column_step);
  } else if (ts <= 0.0) {
    Location l = at_parameter("ts");
    l.file = path;
    throw Error(
        "no time column (time_column is empty) and no sample time given: set "
        "CsvReadOptions::ts",
        l);
  }

  // Only the requested columns are parsed: other columns may hold text (comments, labels).
  Eigen::MatrixXd u(n, static_cast<Eigen::Index>(in_cols.size()));
  Eigen::MatrixXd y(n, static_cast<Eigen::Index>(out_cols.size()));
  for (std::size_t i = 0; i < in_cols.size(); ++i) {
    u.col(static_cast<Eigen::Index>(i)) =
        detail::parse_column(t, in_cols[i], options.decimal_point);
  }
  for (std::size_t i = 0; i < out_cols.size(); ++i) {
    y.col(static_cast<Eigen::Index>(i)) =
        detail::parse_column(t, out_cols[i], options.decimal_point);
  }
  // The policy runs after parsing so its messages can cite file rows; what it fills is noted.
  for (std::size_t i = 0; i < in_cols.size(); ++i) {
    std::string note = detail::apply_csv_policy(u, static_cast<Eigen::Index>(i), t, in_cols[i],
                                                options.non_finite, options.max_gap);
    if (!note.empty()) notes.push_back(std::move(note));
  }
  for (std::size_t i = 0; i < out_cols.size(); ++i) {
    std::string note = detail::apply_csv_policy(y, static_cast<Eigen::Index>(i), t, out_cols[i],
                                                options.non_finite, options.max_gap);
    if (!note.empty()) notes.push_back(std::move(note));
  }

  // `keep`: the policy has been applied above, with file locations; the constructor must not
  // apply it again with sample indices. The name goes into model files and reports, which hold
  // UTF-8 only: a file name in another encoding is repaired here, not refused after an estimation.
  Experiment e(std::move(u), std::move(y), ts, valid_utf8(std::filesystem::path(path).stem().string()),
               NonFinitePolicy::keep);
  e.set_t0(t0);
  e.set_input_names(options.inputs);
  e.set_output_names(options.outputs);
  for (auto& note : notes) e.add_note(std::move(note));
  return e;
}

/// As above, without the file information.
inline Experiment read_csv(const std::string& path, const CsvReadOptions& options = {}) {
  CsvReadInfo info;
  return read_csv(path, options, info);
}

/// Reads several files into one multi-experiment `Dataset` (same options for all). Every error
/// names the file; one that does not fit the files before it (sample time, channel counts) also
/// names its experiment index.
inline Dataset read_csv_dataset(const std::vector<std::string>& paths,
                                const CsvReadOptions& options = {}) {
  Dataset d;
  for (const auto& p : paths) {
    Experiment e = read_csv(p, options);
    try {
      d.add(std::move(e));
    } catch (const Error& err) {
      // The experiment's name is only the stem: two directories can hold a "run1.csv".
      Location l = err.where();
      l.file = p;
      throw Error(err.message(), l);
    }
  }
  return d;
}

/// Writes an experiment atomically with columns time, inputs, outputs (the channel names as
/// headers), full precision, so `read_csv` with matching options gives it back exactly.
/// NaN/Inf samples are written as `nan`/`inf` (read them back with `NonFinitePolicy::keep`).
/// Throws, before writing anything, if a channel name is empty or repeated, the experiment has
/// no samples, or its time grid t0 + k·ts does not round to evenly spaced doubles (a short ts
/// after a large t0), since `read_csv` would refuse such a file.
inline void write_csv(const std::string& path, const Experiment& e,
                      const CsvWriteOptions& options = {}) {
  e.validate(true);
  std::vector<std::string> header;
  header.push_back(options.time_column);
  header.insert(header.end(), e.input_names().begin(), e.input_names().end());
  header.insert(header.end(), e.output_names().begin(), e.output_names().end());
  detail::CsvNameIndex names;
  for (std::size_t j = 0; j < header.size(); ++j) {
    Location l;
    l.file = path;
    l.column = static_cast<long>(j) + 1;
    l.column_name = detail::printable(header[j], std::string::npos);
    if (header[j].empty()) throw Error("channel has an empty name; it could not be read back", l);
    if (const std::size_t i = names.earlier(header[j], j); i != std::string::npos) {
      throw Error("duplicate column name '" + detail::printable(header[j]) + "' (also column " +
                      std::to_string(i + 1) + "); rename the channel",
                  l);
    }
  }
  Eigen::MatrixXd table(e.size(), static_cast<Eigen::Index>(header.size()));
  table.col(0) = e.time();
  table.middleCols(1, e.num_inputs()) = e.u();
  table.rightCols(e.num_outputs()) = e.y();
  // t0 + k·ts is rounded to the doubles near t0, which after a large t0 can be too coarse for ts
  // (0.5 after 1e17, where doubles are 16 apart) or overflow: stamps that repeat or step
  // unevenly, which read_csv refuses. Refused here (with read_csv's default tolerance) rather
  // than written as a file that cannot be read back.
  Location at_time;
  at_time.file = path;
  at_time.column = 1;
  at_time.column_name = detail::printable(options.time_column, std::string::npos);
  if (e.empty()) throw Error("experiment has no samples: read_csv could not read the file back", at_time);
  if (e.size() >= 2) {
    const Eigen::VectorXd time = table.col(0);
    const Eigen::Index n = time.size();
    Eigen::Index k = 1;
    while (k < n && std::isfinite(time(k) - time(0)) && time(k) > time(k - 1)) ++k;
    double typical = 0.0;
    if (k == n) k = detail::first_irregular_step(time, CsvReadOptions{}.time_tolerance, typical);
    if (k < n) {
      throw Error("the time stamps t0 + k*ts (t0 = " + detail::num(e.t0()) + ", ts = " + detail::num(e.ts()) +
                      ") are not evenly spaced doubles from sample " + std::to_string(k) + " on (t = " +
                      detail::num(time(k)) + " after " + detail::num(time(k - 1)) +
                      "): read_csv would refuse the file; make t0 smaller (Experiment::set_t0)",
                  at_time);
    }
  }
  write_csv_table(path, header, table, options.delimiter);
}

}  // namespace nlid
