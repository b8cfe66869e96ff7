#pragma once
/// @file
/// The one number-to-text conversion of nlid's messages, reports and model descriptions.
///
/// printf's `%g` with a chosen number of significant digits: short for round numbers, scientific
/// for very large or small ones, and independent of iostream state and of the C locale (a program
/// that calls setlocale for a decimal-comma language still gets "0.5", which matters most where
/// the text is code: generated C with "0,5" in an initialiser list compiles to other numbers). Each caller picks the digits
/// its reader needs (4 in toolbox-style coefficient tables, 6 in equations and error messages, 10
/// where a time or sample value must be told apart from its neighbours).

#include <charconv>
#include <string>

namespace nlid::detail {

/// `v` with `digits` significant digits (`%.*g` in the C locale), e.g.
/// format_g(0.000123456, 3) == "0.000123". std::to_chars with a precision is specified as printf
/// in the "C" locale, so the text is the same as before, whatever locale the program has set.
inline std::string format_g(double v, int digits = 6) {
  char buf[64];  // "%.17g" of any double, sign and exponent included, fits with room to spare
  if (digits < 0) digits = 6;  // as printf does for a negative precision
  if (digits > 40) digits = 40;  // beyond 17 the digits add nothing, and buf must hold them
  const auto r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::general, digits);
  return std::string(buf, r.ptr);
}

}  // namespace nlid::detail
