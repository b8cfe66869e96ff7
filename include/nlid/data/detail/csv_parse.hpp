#pragma once
/// @file
/// Internals of the CSV reader and writer (csv.hpp): tokenising, cell parsing, missing-value
/// policy with file-line locations, number formatting, and the exact sample-time recovery.

#include <Eigen/Core>
#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <string>
#include <string_view>
#include <system_error>
#include <unordered_map>
#include <utility>
#include <vector>

#include "nlid/core/atomic_file.hpp"
#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/data/detail/missing.hpp"
#include "nlid/data/detail/printable.hpp"
#include "nlid/data/experiment.hpp"

namespace nlid {

namespace detail {

/// "'t', 'u', 'y'" for error messages ("(none)" if empty); names are shown `printable`.
inline std::string quoted_list(const std::vector<std::string>& names) {
  std::string s;
  for (const auto& n : names) s += (s.empty() ? "'" : ", '") + printable(n) + "'";
  return s.empty() ? "(none)" : s;
}

/// Remembers column names by their first column, so a header of 10⁵ names (a wide logger or
/// spectrum export) is checked for repeats with 10⁵ lookups, not 5·10⁹ string comparisons.
/// The names must outlive it.
class CsvNameIndex {
 public:
  /// The earlier column (0-based) named `name`, or npos after recording `j` as its first column.
  std::size_t earlier(std::string_view name, std::size_t j) {
    const auto [it, fresh] = first_.emplace(name, j);
    return fresh ? std::string::npos : it->second;
  }

 private:
  std::unordered_map<std::string_view, std::size_t> first_;
};

/// Tokenised CSV text: header, data rows as strings, and the file line of each row. Kept as text
/// so only the columns a caller asks for must be numeric (a file may carry a comment column).
struct CsvText {
  std::string file;
  char decimal_point = '.';
  std::vector<std::string> header;
  long header_line = 0;
  std::vector<std::vector<std::string>> rows;
  std::vector<long> lines;  // 1-based line number of each row
  bool comment_before_header = false;  // a '#' line came first (numpy.savetxt's "# t u y")
};

inline Location csv_at(const std::string& file, long row = -1, long col = -1,
                       const std::string& name = {}) {
  Location l;
  l.file = file;
  l.row = row;
  l.column = col;
  // Escaped but not shortened: what() must not end at a NUL byte of a header, and a program
  // matching where().column_name against its own names still finds a long one.
  l.column_name = printable(name, std::string::npos);
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

/// "; the header is a single field - is the file separated by ';'? …" when a header read as one
/// field splits at another separator (into a part equal to `name`, if one is given): a file
/// written with that separator (';' from a spreadsheet with decimal commas, or tabs). Else "".
inline std::string separator_hint(const std::vector<std::string>& header, const std::string& name = {}) {
  if (header.size() != 1) return {};
  const std::string& h = header[0];
  std::vector<std::string> parts;
  for (const char sep : {';', '\t', ',', ' ', '|'}) {
    if (h.find(sep) == std::string::npos) continue;
    try {
      split_csv_line(h, sep, parts, {}, 0);  // as read_csv would split it with that separator
    } catch (const Error&) {
      continue;  // not a well-formed line at this separator either
    }
    if (name.empty() || std::find(parts.begin(), parts.end(), name) != parts.end()) {
      const std::string shown = sep == '\t' ? "tabs" : "'" + std::string(1, sep) + "'";
      return "; the header is a single field - is the file separated by " + shown +
             "? (CsvReadOptions::delimiter; --delimiter in the tools)";
    }
  }
  return {};
}

/// Reads and tokenises `path`; checks header sanity and that every row has the header's width.
inline CsvText tokenize_csv(const std::string& path, char delimiter, char decimal_point) {
  if (delimiter == '"' || delimiter == '\n' || delimiter == '\r' || delimiter == '#') {
    throw Error(std::string("invalid delimiter '") + delimiter + "'", at_parameter("delimiter"));
  }
  CsvText t;
  t.file = path;
  t.decimal_point = decimal_point;
  std::string text = read_file(path);  // names the file if missing / a directory
  std::string_view s(text);
  if (s.size() >= 3 && s.substr(0, 3) == "\xEF\xBB\xBF") s.remove_prefix(3);  // UTF-8 BOM
  if (s.find_first_not_of(" \t\r\n") == std::string_view::npos) {
    throw Error("file is empty", csv_at(path));
  }
  std::vector<std::string> fields;
  long line_no = 0;
  bool have_header = false;
  // In a one-column file an empty cell is an empty line: between two samples it is a missing
  // value (the missing-value policy decides), not a line to skip, or the samples after it would
  // shift by one without a word. Blank lines after the last sample end the file as usual.
  std::vector<long> blank_cells;
  // Lines end in LF or CRLF; a file with CRs and no LF at all has classic-Mac line endings
  // (some loggers still write them): read as one line it gave "duplicate column name '0'".
  const char line_end = (s.find('\n') == std::string_view::npos && s.find('\r') != std::string_view::npos) ? '\r' : '\n';
  std::size_t pos = 0;
  while (pos < s.size()) {
    std::size_t eol = s.find(line_end, pos);
    if (eol == std::string_view::npos) eol = s.size();
    std::string_view line = s.substr(pos, eol - pos);
    pos = eol + 1;
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    const std::string_view content = trim_blanks(line, true);
    if (content.empty() || content.front() == '#') {
      if (!have_header && !content.empty()) t.comment_before_header = true;
      if (have_header && content.empty() && t.header.size() == 1 && !t.rows.empty()) blank_cells.push_back(line_no);
      continue;
    }
    split_csv_line(line, delimiter, fields, path, line_no);
    if (!have_header) {
      have_header = true;
      t.header = fields;
      t.header_line = line_no;
      CsvNameIndex names;
      for (std::size_t j = 0; j < t.header.size(); ++j) {
        if (t.header[j].empty()) continue;  // unnamed (e.g. a pandas index) – cannot be requested
        if (const std::size_t i = names.earlier(t.header[j], j); i != std::string::npos) {
          throw Error("duplicate column name '" + printable(t.header[j]) + "' (also column " +
                          std::to_string(i + 1) + ")",
                      csv_at(path, line_no, static_cast<long>(j) + 1, t.header[j]));
        }
      }
      continue;
    }
    if (fields.size() != t.header.size()) {
      throw Error("ragged row: expected " + std::to_string(t.header.size()) +
                      " fields (as in the header on row " + std::to_string(t.header_line) +
                      "), found " + std::to_string(fields.size()) + separator_hint(t.header),
                  csv_at(path, line_no));
    }
    for (const long blank : blank_cells) {
      t.rows.push_back({std::string()});
      t.lines.push_back(blank);
    }
    blank_cells.clear();
    t.rows.push_back(fields);
    t.lines.push_back(line_no);
  }
  if (!have_header) throw Error("file has no header row (only comments)", csv_at(path));
  if (t.rows.empty()) {
    throw Error("file has a header but no data rows", csv_at(path, t.header_line));
  }
  return t;
}

/// Decimal exponent of the first nonzero digit of a number in from_chars' syntax ([-]digits
/// [.digits][e[±]digits]), the exponent part saturated at ±10⁹: 2 for "123.4", -3 for
/// "0.00123", 398 for "1e400". For a value out of the range of double, its sign tells overflow
/// (> 0) from underflow.
inline long decimal_order(std::string_view s) {
  constexpr long cap = 1000000000L;
  std::size_t i = !s.empty() && (s.front() == '-' || s.front() == '+') ? 1 : 0;
  long int_digits = 0, digits = 0, first = -1;
  bool fraction = false;
  for (; i < s.size() && s[i] != 'e' && s[i] != 'E'; ++i) {
    if (s[i] == '.') {
      fraction = true;
      continue;
    }
    if (first < 0 && s[i] != '0') first = digits;
    ++digits;
    if (!fraction) ++int_digits;
  }
  if (first < 0) return -cap;  // zero (which from_chars never calls out of range)
  long exponent = 0;
  bool negative = false;
  if (i < s.size()) {
    ++i;
    if (i < s.size() && (s[i] == '-' || s[i] == '+')) negative = s[i++] == '-';
    for (; i < s.size(); ++i) exponent = std::min(cap, exponent * 10 + (s[i] - '0'));
  }
  return int_digits - 1 - first + (negative ? -exponent : exponent);
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
  // With decimal commas a '.' in a number is most likely a thousands separator ("1.234" for
  // 1234), which read as a decimal point is 1000 times off; and a time column's printing
  // resolution, counted at the commas, would be wrong (0.123, 0.246, ... snapped to ts = 0.1).
  if (decimal_point != '.' && ptr == s.data() + s.size() && cell.find('.') != std::string::npos) {
    throw Error("number '" + printable(cell) + "' has a '.' but the decimal point is '" +
                    std::string(1, decimal_point) + "': a thousands separator? (CsvReadOptions::decimal_point)",
                where());
  }
  if (ec == std::errc::result_out_of_range && ptr == s.data() + s.size()) {
    // from_chars reports underflow (1e-400) and overflow (1e400) alike; only overflow is an
    // error: a number below the smallest double reads as the nearest double, ±0. Told apart
    // from the text, not by strtod, which reads by the C locale ("1.5e-400" read as 1 under a
    // German LC_NUMERIC).
    if (decimal_order(s) < 0) return s.front() == '-' ? -0.0 : 0.0;
    throw Error("number out of the range of double: '" + printable(cell) + "'", where());
  }
  if (ec != std::errc() || ptr != s.data() + s.size()) {
    throw Error("non-numeric cell '" + printable(cell) + "'", where());
  }
  return v;
}

/// True if `cell` reads as a number the way `parse_cell` reads it.
inline bool is_number(const std::string& cell, char decimal_point) {
  if (decimal_point != '.' && cell.find('.') != std::string::npos) return false;
  std::string s = cell;
  if (decimal_point != '.') std::replace(s.begin(), s.end(), decimal_point, '.');
  std::string_view v(s);
  if (v.size() > 1 && v.front() == '+' && v[1] != '-' && v[1] != '+') v.remove_prefix(1);
  double x = 0.0;
  const auto [ptr, ec] = std::from_chars(v.data(), v.data() + v.size(), x);
  return !v.empty() && ptr == v.data() + v.size() && (ec == std::errc() || ec == std::errc::result_out_of_range);
}

/// True if every named field of the header is a number: then the "header" is almost surely the
/// first data row of a file without one, and taking it as names would drop that sample.
inline bool header_is_numeric(const CsvText& t, char decimal_point) {
  bool any = false;
  for (const auto& h : t.header) {
    if (h.empty()) continue;  // an unnamed index column (pandas) or a missing cell
    if (!is_number(h, decimal_point)) return false;
    any = true;
  }
  return any;
}

/// The error for a file whose first row is numbers (`header_is_numeric`); `escape` says how to
/// accept such names anyway, if the reader has a way.
inline Error no_header_error(const CsvText& t, const std::string& escape) {
  std::vector<std::string> shown(t.header.begin(), t.header.begin() + static_cast<std::ptrdiff_t>(
                                                                          std::min<std::size_t>(t.header.size(), 4)));
  std::string list = quoted_list(shown) + (t.header.size() > shown.size() ? ", ..." : "");
  return Error("the file seems to have no header row: its first row (" + list +
                   ") is all numbers, and read as column names it would be lost as a sample; add a line "
                   "with the column names" +
                   (t.comment_before_header
                        ? " (a header behind '#', as numpy.savetxt writes it, is skipped as a comment)"
                        : std::string()) +
                   escape,
               csv_at(t.file, t.header_line));
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
  if (header_is_numeric(t, t.decimal_point)) throw no_header_error(t, {});
  Location l = csv_at(t.file, t.header_line, -1, name);
  std::string hint = separator_hint(t.header, name);
  if (hint.empty() && std::string(role) == "time")
    hint = "; a file without a time column needs the sample time (CsvReadOptions::ts with time_column \"\"; "
           "--ts in the tools)";
  throw Error(std::string(role) + " column '" + printable(name) +
                  "' not found; available columns: " + quoted_list(t.header) + hint,
              l);
}

// The shortest text that reads back as the same double, appended to `out` (write_csv writes
// millions of them: no temporary string per number, most of which would not fit inline).
inline void append_double(std::string& out, double x) {
  char buf[64];
  const auto res = std::to_chars(buf, buf + sizeof buf, x);  // shortest round-trip form
  out.append(buf, res.ptr);
}

inline std::string format_double(double x) {
  std::string s;
  append_double(s, x);
  return s;
}

inline std::string quote_if_needed(const std::string& s, char delim) {
  // With delim ' ' the reader splits at runs of blanks, tabs included. A name that starts with a
  // UTF-8 byte-order mark is quoted: as the file's first bytes the reader would strip it.
  const bool needs = s.find(delim) != std::string::npos || s.find('"') != std::string::npos ||
                     s.starts_with("\xEF\xBB\xBF") ||
                     (delim == ' ' && s.find('\t') != std::string::npos) ||
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

/// x rounded to `digits` significant decimal digits (the double nearest the printed decimal).
inline double round_significant(double x, int digits) {
  // to_chars, not snprintf: under a locale with decimal commas "%e" prints "1,5e-03", of which
  // from_chars reads only the 1 (and the sample time snapped to garbage).
  char buf[64];
  const auto res = std::to_chars(buf, buf + sizeof buf, x, std::chars_format::scientific, digits - 1);
  double c = 0.0;
  std::from_chars(buf, res.ptr, c);
  return c;
}

/// The sample time of a time column `t` whose stamps were printed with `quantum` resolution
/// (10^−decimals; 0 if unknown, e.g. scientific notation). In order:
///
/// 1. Exact grid: a ts whose grid t0 + k·ts reproduces every stamp exactly, near the endpoint
///    estimate (t_{N−1} − t_0)/(N−1) (`exact_sample_time`). Makes write → read of `ts` exact.
/// 2. Rounded grid: a logger that prints fixed decimals (51.2 kHz as 0.00001953, 0.00003906, …)
///    leaves no exact grid, and the endpoint estimate is then off by up to quantum/(t_{N−1} − t_0)
///    relative — 10⁻⁸ for 2 s of such a record, so two slices of one recording disagreed beyond
///    the 10⁻⁹ that `Dataset` allows and could not be merged or compared. The shortest candidate
///    with 1, 2, … significant digits, as a sample time (0.001) or as a rate (ts = 1/51200), whose
///    grid reproduces every stamp to within one quantum (t0 is itself rounded, hence not half) is
///    taken: it is what the stamps were printed from, as far as they can tell.
/// 3. Jitter: stamps t_k = t_0 + k·T_s + e_k determine T_s only to the standard error s of the
///    least-squares slope of t_k over k (s = σ_e·√(12/(N³−N)), σ_e from the fit's residuals).
///    The shortest decimal or rate within 3s of that slope is taken: what the stamps cannot tell
///    from the rate they were logged at. Two records of one jittering logger (0.00999988 and
///    0.00999992 by their end points) then share that rate (0.01) and can be merged and
///    simulated together; before, they differed beyond `Dataset`'s 10⁻⁶. A rate the stamps rule
///    out is not taken (99.9 Hz with one late stamp, 99.3 Hz under ±2 ms jitter stay off 0.01).
/// 4. Otherwise the endpoint estimate.
inline double snap_sample_time(const Eigen::VectorXd& t, double quantum);

/// Stage 1 of `snap_sample_time`, or NaN if no double reproduces every stamp.
///
/// fl(t_0 + fl(k·ts)) is monotone in ts, so the doubles that reproduce the last time stamp form an
/// interval, found by bisection over the (ordered) bit patterns of positive doubles. Candidates in
/// it are checked against every time stamp, shortest decimals first: when t_0 is large several
/// doubles reproduce the column, and the shortest (0.001 rather than 0.0010000000000004686) is the
/// one a person or a writer used.
inline double exact_sample_time(const Eigen::VectorXd& t) {
  constexpr double none = std::numeric_limits<double>::quiet_NaN();
  const Eigen::Index n = t.size();
  const double t0 = t(0), tl = t(n - 1);
  const double est = (tl - t0) / static_cast<double>(n - 1);
  const auto last = static_cast<double>(n - 1);
  auto grid_last = [&](double ts) { return t0 + last * ts; };
  auto bits = [](double x) { return std::bit_cast<std::uint64_t>(x); };
  auto from = [](std::uint64_t b) { return std::bit_cast<double>(b); };
  // The endpoint estimate is off by the rounding of t_0 and t_{N−1} spread over the record: with
  // a large t_0 (Unix time 1.7e9, ulp 2.4e-7) and a short record that is far more than 1e-9.
  const double spread = 4.0 * std::numeric_limits<double>::epsilon() *
                        std::max(std::abs(t0), std::abs(tl)) / last;
  const double reach = std::min(1e-9 * est + spread, 0.5 * est);
  std::uint64_t lo = bits(est - reach), hi = bits(est + reach);
  if (!(grid_last(from(lo)) < tl && grid_last(from(hi)) > tl)) return none;
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
  if (final_ < first) return none;
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
      const double c = round_significant(x, d);
      if (c >= fa && c <= fb && exact(c)) return c;
    }
  }
  // Otherwise the exact candidate nearest to the estimate (at most 256 tried).
  const std::uint64_t c = std::clamp(bits(est), first, final_);
  for (std::uint64_t i = 0; i <= 128; ++i) {
    if (c - first >= i && exact(from(c - i))) return from(c - i);
    if (final_ - c >= i && exact(from(c + i))) return from(c + i);
  }
  return none;
}

/// The shortest sample time near `x` that `accept` takes: with 1, 2, … 12 significant digits, as
/// a sample time (0.001) or as a rate (1/51200); NaN if none. Stages 2 and 3 of
/// `snap_sample_time` differ only in what they accept.
template <class Accept>
double shortest_sample_time(double x, const Accept& accept) {
  for (int d = 1; d <= 12; ++d) {
    const double as_time = round_significant(x, d);
    if (accept(as_time)) return as_time;
    const double as_rate = 1.0 / round_significant(1.0 / x, d);
    if (accept(as_rate)) return as_rate;
  }
  return std::numeric_limits<double>::quiet_NaN();
}

/// Stage 3 of `snap_sample_time`: the shortest decimal or rate within 3 standard errors of the
/// least-squares slope of the stamps, else `est`.
inline double snap_jittered_sample_time(const Eigen::VectorXd& t, double est) {
  const Eigen::Index n = t.size();
  if (n < 3) return est;  // two stamps define the grid: no jitter can be seen
  // Least squares on τ_k = t_k − t_0 (a Unix-time t_0 would swamp the sums).
  const double nd = static_cast<double>(n), kbar = 0.5 * (nd - 1.0);
  double tbar = 0.0;
  for (Eigen::Index k = 0; k < n; ++k) tbar += t(k) - t(0);
  tbar /= nd;
  double skt = 0.0, skk = 0.0;
  for (Eigen::Index k = 0; k < n; ++k) {
    const double dk = static_cast<double>(k) - kbar;
    skt += dk * (t(k) - t(0) - tbar);
    skk += dk * dk;
  }
  const double slope = skt / skk;
  double ss = 0.0;
  for (Eigen::Index k = 0; k < n; ++k) {
    const double r = t(k) - t(0) - tbar - slope * (static_cast<double>(k) - kbar);
    ss += r * r;
  }
  const double se = std::sqrt(ss / (nd - 2.0) / skk);
  // 3 standard errors, and a few ulps for stamps that only rounding moved.
  const double reach = 3.0 * se + 8.0 * std::numeric_limits<double>::epsilon() * std::abs(slope);
  if (!(slope > 0.0) || !std::isfinite(slope) || !std::isfinite(reach)) return est;
  const double snapped = shortest_sample_time(slope, [&](double ts) { return std::abs(ts - slope) <= reach; });
  return std::isnan(snapped) ? est : snapped;
}

inline double snap_sample_time(const Eigen::VectorXd& t, double quantum) {
  const Eigen::Index n = t.size();
  const double est = (t(n - 1) - t(0)) / static_cast<double>(n - 1);
  const double exact = exact_sample_time(t);
  if (!std::isnan(exact)) return exact;
  if (!(quantum > 0.0)) return snap_jittered_sample_time(t, est);
  const double t0 = t(0);
  auto reproduces = [&](double ts) {
    if (!(ts > 0.0) || !std::isfinite(ts)) return false;
    for (Eigen::Index k = 1; k < n; ++k) {
      const double g = t0 + static_cast<double>(k) * ts;
      // one quantum, plus the few ulps by which the parsed stamp and the grid may round apart
      const double tol = quantum * (1.0 + 1e-9) + 8.0 * std::numeric_limits<double>::epsilon() * std::abs(t(k));
      if (!(std::abs(g - t(k)) <= tol)) return false;
    }
    return true;
  };
  const double snapped = shortest_sample_time(est, reproduces);
  return std::isnan(snapped) ? snap_jittered_sample_time(t, est) : snapped;
}

inline std::string percent(double x) { return format_g(100.0 * x, 3) + " %"; }

inline std::string num(double x) { return format_g(x, 10); }

/// Throws if one file column is used twice (time, inputs, outputs).
inline void check_distinct_columns(const CsvText& t, bool has_time, std::size_t time_col,
                                   const std::vector<std::size_t>& in_cols,
                                   const std::vector<std::size_t>& out_cols) {
  std::vector<std::pair<std::size_t, std::string>> used;
  if (has_time) used.emplace_back(time_col, "the time column");
  for (std::size_t i = 0; i < in_cols.size(); ++i) {
    used.emplace_back(in_cols[i], "input " + std::to_string(i + 1));
  }
  for (std::size_t i = 0; i < out_cols.size(); ++i) {
    used.emplace_back(out_cols[i], "output " + std::to_string(i + 1));
  }
  for (std::size_t a = 0; a < used.size(); ++a) {
    for (std::size_t b = 0; b < a; ++b) {
      if (used[a].first == used[b].first) {
        throw Error("column '" + printable(t.header[used[a].first]) + "' is requested twice (" +
                        used[b].second + " and " + used[a].second + ")",
                    csv_at(t.file, t.header_line, static_cast<long>(used[a].first) + 1,
                           t.header[used[a].first]));
      }
    }
  }
}

/// Printing resolution of a time column: 10^−d for the most decimals d any stamp shows, or 0 if a
/// stamp is in scientific notation (its resolution is then not a fixed quantum).
inline double time_quantum(const CsvText& t, std::size_t time_col, char decimal_point) {
  int decimals = 0;
  for (const auto& row : t.rows) {
    const std::string& cell = row[time_col];
    if (cell.find_first_of("eE") != std::string::npos) return 0.0;
    const auto dot = cell.find(decimal_point);
    if (dot == std::string::npos) continue;
    std::size_t end = cell.size();
    while (end > dot + 1 && (cell[end - 1] == ' ' || cell[end - 1] == '\t' || cell[end - 1] == '\r')) --end;
    decimals = std::max(decimals, static_cast<int>(end - dot - 1));
  }
  return std::pow(10.0, -decimals);
}

/// The first k whose step time(k) − time(k−1) is not the median step within `tolerance` (relative)
/// plus a rounding allowance, or time.size() if every step is; `typical` receives the median step.
/// `time` is finite and increasing with at least 2 stamps. Shared by the reader (`time_axis`) and
/// `write_csv`, which must not write a time grid the reader refuses.
inline Eigen::Index first_irregular_step(const Eigen::VectorXd& time, double tolerance, double& typical) {
  const Eigen::Index n = time.size();
  const Eigen::VectorXd steps = time.tail(n - 1) - time.head(n - 1);
  std::vector<double> sorted(steps.data(), steps.data() + steps.size());
  const auto mid = sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2);
  std::nth_element(sorted.begin(), mid, sorted.end());
  typical = *mid;
  // Each stamp is a double, off its ideal time by up to half an ulp of |t| (and write_csv's
  // t0 + k·ts by as much again), so with a large t0 and a short step (Unix time 1.7e9 in steps
  // of 1e-5: one ulp is 2.4e-7) steps jitter by a few ulps of |t| that no tolerance relative
  // to the step absorbs. A step and the median step both carry that error, hence 8 ulps. The
  // allowance stays below a quarter of the step, so a dropped sample (a whole step more) is
  // still caught; stamps too coarse for that are reported as non-uniform, as before.
  const double t_abs = std::max(std::abs(time(0)), std::abs(time(n - 1)));
  double rounding = 8.0 * std::numeric_limits<double>::epsilon() * t_abs;
  if (tolerance < 1.0) rounding = std::min(rounding, 0.25 * (1.0 - tolerance) * typical);
  for (Eigen::Index k = 1; k < n; ++k) {
    if (!(std::abs(steps(k - 1) - typical) <= tolerance * typical + rounding)) return k;
  }
  return n;
}

/// Validates the time column and returns (ts, t0): every step is checked against the median
/// step; `ts_override` > 0 then wins over the column's rate (a disagreement is noted), otherwise
/// ts is inferred from the column. `*column_step` receives the median step (NaN with one row).
inline std::pair<double, double> time_axis(const CsvText& t, std::size_t time_col,
                                           char decimal_point, double ts_override, double tolerance,
                                           std::vector<std::string>& notes, double* column_step) {
  *column_step = std::numeric_limits<double>::quiet_NaN();
  const Eigen::VectorXd time = parse_column(t, time_col, decimal_point);
  const Eigen::Index n = time.size();
  const auto at_row = [&](Eigen::Index k) {
    return csv_at(t.file, t.lines[static_cast<std::size_t>(k)], static_cast<long>(time_col) + 1,
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
      throw Error("time column is not increasing: t = " + num(time(k)) +
                      " follows t = " + num(time(k - 1)) + " on row " +
                      std::to_string(t.lines[static_cast<std::size_t>(k - 1)]),
                  at_row(k));
    }
  }
  const double t0 = n > 0 ? time(0) : 0.0;  // n > 0: tokenize_csv rejects files without data
  if (n < 2) {
    if (ts_override > 0.0) return {ts_override, t0};
    throw Error(
        "too few rows to infer the sample time from the time column (1 data row); set "
        "CsvReadOptions::ts",
        at_row(0));
  }
  // Steps are checked against the median step, so the message points at the odd step (e.g. a
  // dropped sample) rather than at whichever step an outlier-biased mean disfavours. Also with
  // a sample-time override: it sets the rate, but a gap in the column is still a lost sample
  // that evenly spaced samples would hide.
  const Eigen::VectorXd steps = time.tail(n - 1) - time.head(n - 1);
  // Finite stamps can still be too far apart for a double (-1e308 then 1e308): the step, and
  // every sample time derived from it, would be infinite.
  if (!std::isfinite(time(n - 1) - time(0))) {
    Eigen::Index k = 1;
    while (k < n - 1 && std::isfinite(steps(k - 1))) ++k;
    throw Error("time column spans more than the largest double: t = " + num(time(0)) + " to " +
                    num(time(n - 1)) + " (step from row " +
                    std::to_string(t.lines[static_cast<std::size_t>(k - 1)]) + " is " + num(steps(k - 1)) + ")",
                at_row(k));
  }
  double typical = 0.0;
  const Eigen::Index k = first_irregular_step(time, tolerance, typical);
  *column_step = typical;
  if (k < n) {
    const double dev = std::abs(steps(k - 1) - typical) / typical;
    throw Error("non-uniform time column: step " + num(steps(k - 1)) + " from row " +
                    std::to_string(t.lines[static_cast<std::size_t>(k - 1)]) + " deviates by " +
                    percent(dev) + " from the typical step " + num(typical) + " (tolerance " +
                    percent(tolerance) +
                    "); missing samples? cut the record at the gap or fill it, or raise "
                    "CsvReadOptions::time_tolerance if the stamps only jitter",
                at_row(k));
  }
  if (ts_override > 0.0) {
    if (std::abs(typical - ts_override) > tolerance * ts_override) {
      notes.push_back("sample time " + num(ts_override) + " set by the caller; the time column's step is " +
                      num(typical));
    }
    return {ts_override, t0};
  }
  const double ts = snap_sample_time(time, time_quantum(t, time_col, decimal_point));
  // The checks above leave a finite positive step; this keeps a failure of that reasoning
  // from reaching Experiment::set_ts, whose error could not name the file.
  if (!(ts > 0.0) || !std::isfinite(ts)) {
    throw Error("cannot derive a sample time from the time column (got " + num(ts) + "); set CsvReadOptions::ts",
                at_row(n - 1));
  }
  return {ts, t0};
}

}  // namespace detail

}  // namespace nlid
