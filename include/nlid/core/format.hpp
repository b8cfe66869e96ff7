#pragma once
/// @file
/// The one number-to-text conversion of nlid: every number in its messages, error texts, reports,
/// tables, model descriptions, files and generated code, and in the command-line tools' output,
/// goes through these functions instead of printf's %f/%g/%e or std::to_string(double) (which is
/// printf's %f).
///
/// printf follows the C library's LC_NUMERIC: a program that calls setlocale for a decimal-comma
/// language (de_DE) would get "0,5" from it. Here the text comes from std::to_chars, which is
/// specified as printf in the "C" locale whatever locale the program has set, so a report, an
/// error message or a file reads the same everywhere (and generated C with "0,5" in an initialiser
/// list, which compiles to other numbers, cannot happen). For finite and non-finite values alike
/// the text is what printf gave in the C locale ("inf", "-inf", "nan"), so replacing a printf
/// conversion by one of these changes no output.
///
/// format_g is `%.*g`: short for round numbers, scientific for very large or small ones; each
/// caller picks the digits its reader needs (4 in toolbox-style coefficient tables, 6 in equations
/// and error messages, 10 where a time or sample value must be told apart from its neighbours).
/// format_f is `%.*f`, with_plus adds the `+` flag, and right_aligned / left_aligned give the
/// field width (`%10s` / `%-12s`) of a table column. (detail::format_fixed in io/svg_chart.hpp is
/// another function: chart tick labels, which write "NaN" and drop the sign of -0.)

#include <charconv>
#include <cstddef>
#include <string>
#include <string_view>

namespace nlid::detail {

/// Appends `v` with `digits` significant digits (`%.*g` in the C locale) to `out`: the form
/// for writers of many numbers (nlid-sim's and nlid-input's CSV), which would otherwise build a
/// heap string per number — a 17-digit number does not fit a std::string's inline buffer.
inline void append_g(std::string& out, double v, int digits = 6) {
  char buf[64];  // "%.17g" of any double, sign and exponent included, fits with room to spare
  if (digits < 0) digits = 6;  // as printf does for a negative precision
  if (digits > 40) digits = 40;  // beyond 17 the digits add nothing, and buf must hold them
  const auto r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::general, digits);
  out.append(buf, r.ptr);
}

/// `v` with `digits` significant digits (`%.*g` in the C locale), e.g.
/// format_g(0.000123456, 3) == "0.000123". std::to_chars with a precision is specified as printf
/// in the "C" locale, so the text is the same as before, whatever locale the program has set.
inline std::string format_g(double v, int digits = 6) {
  std::string s;
  append_g(s, v, digits);
  return s;
}

/// `v` with `decimals` digits after the point (`%.*f` in the C locale), e.g.
/// format_f(12.345, 2) == "12.35", format_f(99.5, 0) == "100"; non-finite values read
/// "inf", "-inf" and "nan" as printf writes them.
inline std::string format_f(double v, int decimals) {
  // Fixed notation writes every integer digit: 309 for the largest double, plus sign, point and
  // the decimals, which are capped so the whole text always fits.
  char buf[448];
  if (decimals < 0) decimals = 6;  // as printf does for a negative precision
  if (decimals > 100) decimals = 100;
  const auto r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::fixed, decimals);
  return std::string(buf, r.ptr);
}

/// `text` of a number with the sign always written (printf's `+` flag, as in `%+.1f`):
/// with_plus(format_f(2.0, 1)) == "+2.0"; a text that starts with '-' (also "-0.0" and "-inf")
/// is returned as it is.
inline std::string with_plus(std::string text) {
  if (text.empty() || text.front() != '-') text.insert(text.begin(), '+');
  return text;
}

/// `text` padded with spaces on the left to at least `width` characters (`%10s`: a right-aligned
/// table column); a longer text is returned whole, as printf does.
inline std::string right_aligned(std::string_view text, std::size_t width) {
  std::string s;
  if (text.size() < width) s.assign(width - text.size(), ' ');
  s.append(text);
  return s;
}

/// `text` padded with spaces on the right to at least `width` characters (`%-12s`: a left-aligned
/// table column); a longer text is returned whole, as printf does.
inline std::string left_aligned(std::string_view text, std::size_t width) {
  std::string s(text);
  if (s.size() < width) s.append(width - s.size(), ' ');
  return s;
}

}  // namespace nlid::detail
