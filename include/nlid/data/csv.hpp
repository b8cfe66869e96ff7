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
/// Sample time. Unless `CsvReadOptions::ts` overrides it, T_s is inferred from the time column
/// as (t_{N−1} − t_0)/(N−1), then nudged by a few units in the last place to the value whose grid
/// t_0 + k·T_s reproduces the column best, so `write_csv` → `read_csv` returns the same `ts`
/// bit for bit. Every step must be increasing and lie within `time_tolerance`·T_s of T_s; a
/// dropped sample (a step of 2·T_s) is therefore reported, not smoothed over. The uniform grid is
/// what every discrete-time model assumes (Ljung 1999, sec. 2.1).
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
#include <utility>
#include <vector>

#include "nlid/core/atomic_file.hpp"
#include "nlid/core/error.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/data/detail/missing.hpp"
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
  /// only supplies t_0 and must still increase; a disagreement with it is recorded in the notes.
  double ts = 0.0;
  /// What to do with NaN/Inf/empty cells in input and output columns.
  NonFinitePolicy non_finite = NonFinitePolicy::error;
  /// Field separator. ' ' splits on runs of spaces and tabs.
  char delimiter = ',';
  /// Decimal separator of the numbers ('.' or ','; ',' needs another delimiter, e.g. ';').
  char decimal_point = '.';
  /// Largest accepted relative deviation |Δt − T_s| / T_s of one time step. 1 % absorbs rounding
  /// of printed time stamps and logger jitter, yet flags a dropped sample (100 %).
  double time_tolerance = 1e-2;
  /// Longest gap (samples) that `NonFinitePolicy::interpolate` may fill.
  int max_gap = default_max_gap;
};

/// Options of the generic table reader.
struct CsvTableOptions {
  char delimiter = ',';                                 ///< field separator (' ' = blank runs)
  char decimal_point = '.';                             ///< decimal separator of the numbers
  NonFinitePolicy non_finite = NonFinitePolicy::error;  ///< NaN/Inf/empty cells, all columns
  int max_gap = default_max_gap;  ///< longest gap `interpolate` fills (per column)
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
    l.column_name = std::string(name);
    throw Error("no column named '" + std::string(name) + "'; available columns: " + list(header),
                l);
  }
  /// The column called `name` as a vector.
  [[nodiscard]] Eigen::VectorXd col(std::string_view name) const { return data.col(column(name)); }

  /// "'t', 'u', 'y'" – used by error messages.
  static std::string list(const std::vector<std::string>& names) {
    std::string s;
    for (const auto& n : names) s += (s.empty() ? "'" : ", '") + n + "'";
    return s.empty() ? "(none)" : s;
  }
};

namespace detail {

/// Tokenised CSV text: header, data rows as strings, and the file line of each row. Kept as text
/// so only the columns a caller asks for must be numeric (a file may carry a comment column).
struct CsvText {
  std::string file;
  std::vector<std::string> header;
  long header_line = 0;
  std::vector<std::vector<std::string>> rows;
  std::vector<long> lines;  // 1-based line number of each row
};

inline Location csv_at(const std::string& file, long row = -1, long col = -1,
                       const std::string& name = {}) {
  Location l;
  l.file = file;
  l.row = row;
  l.column = col;
  l.column_name = name;
  return l;
}

inline std::string_view trim_blanks(std::string_view s, bool tabs) {
  auto blank = [tabs](char c) { return c == ' ' || (tabs && c == '\t'); };
  while (!s.empty() && blank(s.front())) s.remove_prefix(1);
  while (!s.empty() && blank(s.back())) s.remove_suffix(1);
  return s;
}

/// Splits one line into fields (trimmed, unquoted). Throws on an unterminated quote.
inline void split_csv_line(std::string_view line, char delim, std::vector<std::string>& out,
                           const std::string& file, long line_no) {
  out.clear();
  const bool blank_delim = delim == ' ';
  const bool trim_tabs = delim != '\t';
  if (blank_delim) line = trim_blanks(line, true);
  std::size_t i = 0;
  const std::size_t n = line.size();
  while (true) {
    // Leading blanks of a field.
    while (i < n && (line[i] == ' ' || (trim_tabs && line[i] == '\t'))) ++i;
    std::string field;
    if (i < n && line[i] == '"') {
      ++i;
      bool closed = false;
      while (i < n) {
        if (line[i] == '"') {
          if (i + 1 < n && line[i + 1] == '"') {
            field += '"';
            i += 2;
            continue;
          }
          ++i;
          closed = true;
          break;
        }
        field += line[i++];
      }
      if (!closed) {
        throw Error("unterminated quoted field",
                    csv_at(file, line_no, static_cast<long>(out.size()) + 1));
      }
      while (i < n && (line[i] == ' ' || (trim_tabs && line[i] == '\t')) && line[i] != delim) ++i;
      if (i < n && line[i] != delim && !(blank_delim && (line[i] == '\t'))) {
        throw Error("unexpected text after a quoted field",
                    csv_at(file, line_no, static_cast<long>(out.size()) + 1));
      }
    } else {
      std::size_t j = i;
      if (blank_delim) {
        while (j < n && line[j] != ' ' && line[j] != '\t') ++j;
      } else {
        while (j < n && line[j] != delim) ++j;
      }
      field = std::string(trim_blanks(line.substr(i, j - i), trim_tabs));
      i = j;
    }
    out.push_back(std::move(field));
    if (i >= n) break;
    // Skip the delimiter (a run of blanks when the delimiter is ' ').
    if (blank_delim) {
      while (i < n && (line[i] == ' ' || line[i] == '\t')) ++i;
    } else {
      ++i;
      if (i == n) {  // "a,b," – a final empty field
        out.emplace_back();
        break;
      }
    }
  }
}

/// Reads and tokenises `path`; checks header sanity and that every row has the header's width.
inline CsvText tokenize_csv(const std::string& path, char delimiter) {
  if (delimiter == '"' || delimiter == '\n' || delimiter == '\r' || delimiter == '#') {
    throw Error(std::string("invalid delimiter '") + delimiter + "'", at_parameter("delimiter"));
  }
  CsvText t;
  t.file = path;
  std::string text = read_file(path);  // names the file if missing / a directory
  std::string_view s(text);
  if (s.size() >= 3 && s.substr(0, 3) == "\xEF\xBB\xBF") s.remove_prefix(3);  // UTF-8 BOM
  if (s.find_first_not_of(" \t\r\n") == std::string_view::npos) {
    throw Error("file is empty", csv_at(path));
  }
  std::vector<std::string> fields;
  long line_no = 0;
  bool have_header = false;
  std::size_t pos = 0;
  while (pos < s.size()) {
    std::size_t eol = s.find('\n', pos);
    if (eol == std::string_view::npos) eol = s.size();
    std::string_view line = s.substr(pos, eol - pos);
    pos = eol + 1;
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    const std::string_view content = trim_blanks(line, true);
    if (content.empty() || content.front() == '#') continue;
    split_csv_line(line, delimiter, fields, path, line_no);
    if (!have_header) {
      have_header = true;
      t.header = fields;
      t.header_line = line_no;
      for (std::size_t j = 0; j < t.header.size(); ++j) {
        if (t.header[j].empty()) continue;  // unnamed (e.g. a pandas index) – cannot be requested
        for (std::size_t i = 0; i < j; ++i) {
          if (t.header[i] == t.header[j]) {
            throw Error("duplicate column name '" + t.header[j] + "' (also column " +
                            std::to_string(i + 1) + ")",
                        csv_at(path, line_no, static_cast<long>(j) + 1, t.header[j]));
          }
        }
      }
      continue;
    }
    if (fields.size() != t.header.size()) {
      throw Error("ragged row: expected " + std::to_string(t.header.size()) +
                      " fields (as in the header on row " + std::to_string(t.header_line) +
                      "), found " + std::to_string(fields.size()),
                  csv_at(path, line_no));
    }
    t.rows.push_back(fields);
    t.lines.push_back(line_no);
  }
  if (!have_header) throw Error("file has no header row (only comments)", csv_at(path));
  if (t.rows.empty()) {
    throw Error("file has a header but no data rows", csv_at(path, t.header_line));
  }
  return t;
}

/// Parses one cell. Empty → NaN (a missing value). Throws quoting the cell if it is not a number.
inline double parse_cell(const std::string& cell, char decimal_point, const CsvText& t,
                         std::size_t row, std::size_t col) {
  if (cell.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::string buf;
  std::string_view s(cell);
  if (decimal_point != '.') {
    buf = cell;
    std::replace(buf.begin(), buf.end(), decimal_point, '.');
    s = buf;
  }
  if (s.size() > 1 && s.front() == '+' && s[1] != '-' && s[1] != '+') s.remove_prefix(1);
  double v = 0.0;
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  const auto where = [&] {
    return csv_at(t.file, t.lines[row], static_cast<long>(col) + 1, t.header[col]);
  };
  if (ec == std::errc::result_out_of_range) {
    throw Error("number out of the range of double: '" + cell + "'", where());
  }
  if (ec != std::errc() || ptr != s.data() + s.size()) {
    throw Error("non-numeric cell '" + cell + "'", where());
  }
  return v;
}

/// Column `col` of the table as numbers.
inline Eigen::VectorXd parse_column(const CsvText& t, std::size_t col, char decimal_point) {
  Eigen::VectorXd v(static_cast<Eigen::Index>(t.rows.size()));
  for (std::size_t r = 0; r < t.rows.size(); ++r) {
    v(static_cast<Eigen::Index>(r)) = parse_cell(t.rows[r][col], decimal_point, t, r, col);
  }
  return v;
}

/// "row 12" or "rows 12-15" of the file, for a gap of data rows [g.begin, g.end).
inline std::string row_span(const CsvText& t, const Gap& g) {
  const long a = t.lines[static_cast<std::size_t>(g.begin)];
  const long b = t.lines[static_cast<std::size_t>(g.end - 1)];
  return a == b ? "row " + std::to_string(a)
                : "rows " + std::to_string(a) + "-" + std::to_string(b);
}

/// Applies the non-finite policy to data column `j` of `m`, which came from file column `col`.
/// Returns a note describing what was filled ("" if nothing).
inline std::string apply_csv_policy(Eigen::MatrixXd& m, Eigen::Index j, const CsvText& t,
                                    std::size_t col, NonFinitePolicy policy, int max_gap) {
  if (policy == NonFinitePolicy::keep) return {};
  const std::vector<Gap> gaps = find_gaps(m, j);
  if (gaps.empty()) return {};
  const auto at = [&](Eigen::Index r) {
    return csv_at(t.file, t.lines[static_cast<std::size_t>(r)], static_cast<long>(col) + 1,
                  t.header[col]);
  };
  if (policy == NonFinitePolicy::error) {
    const Eigen::Index r = gaps.front().begin;
    const std::string& cell = t.rows[static_cast<std::size_t>(r)][col];
    throw Error((cell.empty() ? std::string("empty cell (missing value)")
                              : "non-finite value '" + cell + "'") +
                    " under NonFinitePolicy::error; use NonFinitePolicy::keep or ::interpolate "
                    "for missing data",
                at(r));
  }
  std::string list;
  Eigen::Index filled = 0;
  for (const auto& g : gaps) {
    if (g.begin == 0 || g.end == m.rows()) {
      throw Error("cannot interpolate missing values at the " +
                      std::string(g.begin == 0 ? "start" : "end") + " of the data (" +
                      row_span(t, g) + "); remove those rows or use NonFinitePolicy::keep",
                  at(g.begin));
    }
    if (g.length() > max_gap) {
      throw Error("gap of " + std::to_string(g.length()) + " missing values (" + row_span(t, g) +
                      ") is longer than max_gap = " + std::to_string(max_gap),
                  at(g.begin));
    }
  }
  for (const auto& g : gaps) {
    fill_gap_linear(m, j, g);
    filled += g.length();
    list += (list.empty() ? "" : ", ") + row_span(t, g);
  }
  return "filled " + std::to_string(filled) + " missing value(s) of column '" + t.header[col] +
         "' by linear interpolation (" + list + ")";
}

inline std::size_t find_column(const CsvText& t, const std::string& name, const char* role) {
  for (std::size_t j = 0; j < t.header.size(); ++j) {
    if (t.header[j] == name) return j;
  }
  Location l = csv_at(t.file, t.header_line, -1, name);
  throw Error(std::string(role) + " column '" + name +
                  "' not found; available columns: " + CsvTable::list(t.header),
              l);
}

inline std::string format_double(double x) {
  char buf[64];
  const auto res = std::to_chars(buf, buf + sizeof buf, x);  // shortest round-trip form
  return std::string(buf, res.ptr);
}

inline std::string quote_if_needed(const std::string& s, char delim) {
  const bool needs = s.find(delim) != std::string::npos || s.find('"') != std::string::npos ||
                     s.find('\n') != std::string::npos || s.find('\r') != std::string::npos ||
                     (!s.empty() && (s.front() == ' ' || s.front() == '\t' || s.front() == '#' ||
                                     s.back() == ' ' || s.back() == '\t'));
  if (!needs) return s;
  std::string q = "\"";
  for (char c : s) {
    if (c == '\n' || c == '\r') {
      throw Error("column name contains a line break: '" + s + "'", at_parameter("header"));
    }
    q += c;
    if (c == '"') q += '"';
  }
  return q + "\"";
}

/// The sample time whose grid t0 + k·ts reproduces `t` exactly, if there is one near the endpoint
/// estimate (t_{N−1} − t_0)/(N−1); otherwise that estimate. Makes write → read of `ts` exact.
///
/// fl(t_0 + fl(k·ts)) is monotone in ts, so the doubles that reproduce the last time stamp form an
/// interval, found by bisection over the (ordered) bit patterns of positive doubles. Candidates in
/// it are checked against every time stamp, shortest decimals first: when t_0 is large several
/// doubles reproduce the column, and the shortest (0.001 rather than 0.0010000000000004686) is the
/// one a person or a writer used.
inline double snap_sample_time(const Eigen::VectorXd& t) {
  const Eigen::Index n = t.size();
  const double t0 = t(0), tl = t(n - 1);
  const double est = (tl - t0) / static_cast<double>(n - 1);
  const auto last = static_cast<double>(n - 1);
  auto grid_last = [&](double ts) { return t0 + last * ts; };
  auto bits = [](double x) { return std::bit_cast<std::uint64_t>(x); };
  auto from = [](std::uint64_t b) { return std::bit_cast<double>(b); };
  std::uint64_t lo = bits(est * (1.0 - 1e-9)), hi = bits(est * (1.0 + 1e-9));
  if (!(grid_last(from(lo)) < tl && grid_last(from(hi)) > tl)) return est;
  // L = first double with grid_last >= tl.
  std::uint64_t a = lo, b = hi;
  while (b - a > 1) {
    const std::uint64_t m = a + (b - a) / 2;
    (grid_last(from(m)) < tl ? a : b) = m;
  }
  const std::uint64_t first = b;
  // U = last double with grid_last <= tl.
  a = lo, b = hi;
  while (b - a > 1) {
    const std::uint64_t m = a + (b - a) / 2;
    (grid_last(from(m)) <= tl ? a : b) = m;
  }
  const std::uint64_t final_ = a;
  if (final_ < first) return est;
  auto exact = [&](double ts) {
    for (Eigen::Index k = 1; k < n; ++k) {
      if (t0 + static_cast<double>(k) * ts != t(k)) return false;
    }
    return true;
  };
  const double fa = from(first), fb = from(final_);
  // Shortest decimals first: round the interval's ends and middle to 1, 2, … significant digits.
  for (int d = 1; d <= 17; ++d) {
    for (double x : {fa + (fb - fa) / 2, fa, fb}) {
      char buf[64];
      std::snprintf(buf, sizeof buf, "%.*e", d - 1, x);
      double c = 0.0;
      std::from_chars(buf, buf + std::char_traits<char>::length(buf), c);
      if (c >= fa && c <= fb && exact(c)) return c;
    }
  }
  // Otherwise the exact candidate nearest to the estimate (at most 256 tried).
  const std::uint64_t c = std::clamp(bits(est), first, final_);
  for (std::uint64_t i = 0; i <= 128; ++i) {
    if (c - first >= i && exact(from(c - i))) return from(c - i);
    if (final_ - c >= i && exact(from(c + i))) return from(c + i);
  }
  return est;
}

inline std::string percent(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g %%", 100.0 * x);
  return buf;
}

inline std::string num(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.10g", x);
  return buf;
}

}  // namespace detail

/// Reads a whole numeric CSV file: every column must be numeric (NaN/Inf/empty cells follow
/// `options.non_finite`). For tools that handle arbitrary tables; experiments use `read_csv`.
inline CsvTable read_csv_table(const std::string& path, const CsvTableOptions& options = {}) {
  const detail::CsvText t = detail::tokenize_csv(path, options.delimiter);
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
/// Throws if the header width differs from the column count.
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
      out += detail::format_double(data(r, c));
    }
    out += '\n';
  }
  write_file_atomically(path, out);
}

/// Reads one experiment from a CSV file, taking the columns named in `options`. The experiment
/// is named after the file's stem ("data1" for ".../data1.csv"); channel names are the column
/// names. See the file comment for the accepted format and the errors.
inline Experiment read_csv(const std::string& path, const CsvReadOptions& options = {}) {
  using detail::csv_at;
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
  const detail::CsvText t = detail::tokenize_csv(path, options.delimiter);
  const auto n = static_cast<Eigen::Index>(t.rows.size());

  // Resolve the columns first: a misspelt name is reported before any cell is parsed.
  std::vector<std::size_t> in_cols, out_cols;
  for (const auto& name : options.inputs) in_cols.push_back(detail::find_column(t, name, "input"));
  for (const auto& name : options.outputs) {
    out_cols.push_back(detail::find_column(t, name, "output"));
  }
  const bool has_time = !options.time_column.empty();
  const std::size_t time_col = has_time ? detail::find_column(t, options.time_column, "time") : 0;
  {
    std::vector<std::pair<std::size_t, std::string>> used;
    if (has_time) used.emplace_back(time_col, "the time column");
    for (std::size_t i = 0; i < in_cols.size(); ++i)
      used.emplace_back(in_cols[i], "input " + std::to_string(i + 1));
    for (std::size_t i = 0; i < out_cols.size(); ++i)
      used.emplace_back(out_cols[i], "output " + std::to_string(i + 1));
    for (std::size_t a = 0; a < used.size(); ++a) {
      for (std::size_t b = 0; b < a; ++b) {
        if (used[a].first == used[b].first) {
          throw Error("column '" + t.header[used[a].first] + "' is requested twice (" +
                          used[b].second + " and " + used[a].second + ")",
                      csv_at(path, t.header_line, static_cast<long>(used[a].first) + 1,
                             t.header[used[a].first]));
        }
      }
    }
  }

  double ts = options.ts;
  double t0 = 0.0;
  std::vector<std::string> notes;
  notes.push_back("read from '" + path + "' (" + std::to_string(n) + " rows)");
  if (!has_time) {
    if (ts <= 0.0) {
      Location l = at_parameter("ts");
      l.file = path;
      throw Error(
          "no time column (time_column is empty) and no sample time given: set "
          "CsvReadOptions::ts",
          l);
    }
  } else {
    const Eigen::VectorXd time = detail::parse_column(t, time_col, options.decimal_point);
    const auto at_row = [&](Eigen::Index k) {
      return csv_at(path, t.lines[static_cast<std::size_t>(k)], static_cast<long>(time_col) + 1,
                    t.header[time_col]);
    };
    for (Eigen::Index k = 0; k < n; ++k) {
      if (!std::isfinite(time(k))) {
        const std::string& cell = t.rows[static_cast<std::size_t>(k)][time_col];
        throw Error(
            cell.empty() ? std::string("empty time stamp") : "non-finite time stamp '" + cell + "'",
            at_row(k));
      }
      if (k > 0 && !(time(k) > time(k - 1))) {
        throw Error("time column is not increasing: t = " + detail::num(time(k)) +
                        " follows t = " + detail::num(time(k - 1)) + " on row " +
                        std::to_string(t.lines[static_cast<std::size_t>(k - 1)]),
                    at_row(k));
      }
    }
    t0 = time(0);
    if (ts <= 0.0) {
      if (n < 2) {
        throw Error(
            "too few rows to infer the sample time from the time column (1 data row); "
            "set CsvReadOptions::ts",
            at_row(0));
      }
      // Steps are checked against the median step, so the message points at the odd step
      // (e.g. a dropped sample) rather than at whichever step the outlier-biased mean disfavours.
      Eigen::VectorXd steps = time.tail(n - 1) - time.head(n - 1);
      std::vector<double> sorted(steps.data(), steps.data() + steps.size());
      std::nth_element(sorted.begin(),
                       sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2),
                       sorted.end());
      const double typical = sorted[sorted.size() / 2];
      for (Eigen::Index k = 1; k < n; ++k) {
        const double dev = std::abs(steps(k - 1) - typical) / typical;
        if (dev > options.time_tolerance) {
          throw Error("non-uniform time column: step " + detail::num(steps(k - 1)) + " from row " +
                          std::to_string(t.lines[static_cast<std::size_t>(k - 1)]) +
                          " deviates by " + detail::percent(dev) + " from the typical step " +
                          detail::num(typical) + " (tolerance " +
                          detail::percent(options.time_tolerance) +
                          "); missing samples? resample first or set CsvReadOptions::ts",
                      at_row(k));
        }
      }
      ts = detail::snap_sample_time(time);
    } else if (n >= 2) {
      const double implied = (time(n - 1) - t0) / static_cast<double>(n - 1);
      if (std::abs(implied - ts) > options.time_tolerance * ts) {
        notes.push_back("sample time " + detail::num(ts) +
                        " set by the caller; the time column "
                        "implies " +
                        detail::num(implied));
      }
    }
  }

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

  Experiment e(std::move(u), std::move(y), ts, std::filesystem::path(path).stem().string(),
               NonFinitePolicy::keep);
  e.set_t0(t0);
  e.set_input_names(options.inputs);
  e.set_output_names(options.outputs);
  for (auto& note : notes) e.add_note(std::move(note));
  return e;
}

/// Reads several files into one multi-experiment `Dataset` (same options for all). Errors from a
/// file name that file; mismatched sample times or channel counts name the experiment index.
inline Dataset read_csv_dataset(const std::vector<std::string>& paths,
                                const CsvReadOptions& options = {}) {
  Dataset d;
  for (const auto& p : paths) d.add(read_csv(p, options));
  return d;
}

/// Writes an experiment atomically with columns time, inputs, outputs (the channel names as
/// headers), full precision, so `read_csv` with matching options gives it back exactly.
/// NaN/Inf samples are written as `nan`/`inf` (read them back with `NonFinitePolicy::keep`).
inline void write_csv(const std::string& path, const Experiment& e,
                      const CsvWriteOptions& options = {}) {
  e.validate(true);
  std::vector<std::string> header;
  header.push_back(options.time_column);
  header.insert(header.end(), e.input_names().begin(), e.input_names().end());
  header.insert(header.end(), e.output_names().begin(), e.output_names().end());
  for (std::size_t j = 0; j < header.size(); ++j) {
    Location l;
    l.file = path;
    l.column = static_cast<long>(j) + 1;
    l.column_name = header[j];
    if (header[j].empty()) throw Error("channel has an empty name; it could not be read back", l);
    for (std::size_t i = 0; i < j; ++i) {
      if (header[i] == header[j]) {
        throw Error("duplicate column name '" + header[j] + "' (also column " +
                        std::to_string(i + 1) + "); rename the channel",
                    l);
      }
    }
  }
  Eigen::MatrixXd table(e.size(), static_cast<Eigen::Index>(header.size()));
  table.col(0) = e.time();
  table.middleCols(1, e.num_inputs()) = e.u();
  table.rightCols(e.num_outputs()) = e.y();
  write_csv_table(path, header, table, options.delimiter);
}

}  // namespace nlid
