#pragma once
/// @file
/// The one exception type of nlid.
///
/// Every failure that a user can cause (a bad file, a bad cell, a parameter out of range, an
/// experiment too short) is reported as `nlid::Error`. Its message always says *what* went wrong
/// and *where*: the file, row and column of a data file, the experiment index of a data set, or
/// the name of a parameter. `where()` gives the same location as structured fields so a program
/// can react to it (e.g. highlight the bad cell) without parsing the text.

#include <stdexcept>
#include <initializer_list>
#include <string>
#include <string_view>
#include <utility>

#include "nlid/core/utf8.hpp"

namespace nlid {

/// Where an error happened. Fields that do not apply stay at their "unset" value (-1 / empty).
/// Rows and columns are 1-based, as a spreadsheet or text editor shows them.
struct Location {
  std::string file;         ///< data or model file
  long row = -1;            ///< 1-based line number in `file`
  long column = -1;         ///< 1-based column (field) number in `file`
  std::string column_name;  ///< header name of that column, when known
  long experiment = -1;     ///< 0-based experiment index in a data set
  std::string parameter;    ///< parameter or option name

  /// Human-readable form, e.g. `file 'a.csv', row 12, column 3 ('y')`.
  [[nodiscard]] std::string str() const {
    // Built with append() rather than operator+ chains: GCC 12 reports a false -Wrestrict on
    // `"literal" + std::string` at -O2.
    std::string s;
    auto add = [&s](std::initializer_list<std::string_view> parts) {
      if (!s.empty()) s.append(", ");
      for (std::string_view p : parts) s.append(p);
    };
    if (!file.empty()) add({"file '", file, "'"});
    if (row >= 0) add({"row ", std::to_string(row)});
    if (column >= 0 || !column_name.empty()) {
      const std::string num = column >= 0 ? std::to_string(column) : std::string();
      const std::string_view sep = column >= 0 ? " " : "";
      if (column_name.empty()) {
        add({"column", sep, num});
      } else {
        add({"column", sep, num, " ('", column_name, "')"});
      }
    }
    if (experiment >= 0) add({"experiment ", std::to_string(experiment)});
    if (!parameter.empty()) add({"parameter '", parameter, "'"});
    return s;
  }
};

/// The exception thrown for every user-caused failure. `what()` = "nlid: <message> [at <where>]".
class Error : public std::runtime_error {
 public:
  /// `what()` and `message()` show control characters (other than line feed and tab) and bytes
  /// that are not well-formed UTF-8 as \xHH, so a name or path quoted from a file cannot cut the
  /// text short or make it malformed; `where()` keeps the location's fields as given.
  explicit Error(const std::string& message, Location where = {})
      : std::runtime_error(compose(message, where)), message_(detail::message_safe(message)),
        where_(std::move(where)) {}

  /// The message without the location suffix.
  [[nodiscard]] const std::string& message() const noexcept { return message_; }
  /// Structured location of the failure.
  [[nodiscard]] const Location& where() const noexcept { return where_; }

 private:
  static std::string compose(const std::string& message, const Location& where) {
    std::string s("nlid: ");
    s.append(message);
    const std::string w = where.str();
    if (!w.empty()) s.append(" [at ").append(w).append("]");
    return detail::message_safe(std::move(s));
  }
  std::string message_;
  Location where_;
};

/// A free-run simulation whose output stopped being finite (an unstable model, or one driven
/// outside the range it was estimated on). Derived from `Error`, so code that catches `Error`
/// still sees it; code that compares models (`compare`, the tools' fit tables) catches it
/// alone and reports the model as diverged instead of failing the whole comparison.
class DivergenceError : public Error {
 public:
  /// `sample`: 0-based index of the first sample that is not finite.
  DivergenceError(const std::string& message, long sample, Location where = {})
      : Error(message, std::move(where)), sample_(sample) {}
  /// First sample (0-based) of the record at which the output is not finite.
  [[nodiscard]] long sample() const noexcept { return sample_; }

 private:
  long sample_;
};

/// Throws `Error(message, where)` unless `condition` holds. Used at API boundaries.
inline void require(bool condition, const std::string& message, const Location& where = {}) {
  if (!condition) throw Error(message, where);
}

/// As above for a literal message: the std::string is built only when the check fails, so a
/// check inside a fixed-size simulation or estimation call allocates nothing (tests/nomalloc).
/// A composed message (`"..." + std::to_string(n)`) is built before the call; in such paths
/// test first and build the message in the throwing branch.
inline void require(bool condition, const char* message, const Location& where = {}) {
  if (!condition) throw Error(message, where);
}

/// Shorthand for a parameter-named location.
inline Location at_parameter(std::string name) {
  Location l;
  l.parameter = std::move(name);
  return l;
}

/// Shorthand for an experiment-indexed location.
inline Location at_experiment(long index) {
  Location l;
  l.experiment = index;
  return l;
}

}  // namespace nlid
