#pragma once
/// @file
/// The one number-to-text conversion of nlid's messages, reports and model descriptions.
///
/// printf's `%g` with a chosen number of significant digits: short for round numbers, scientific
/// for very large or small ones, and independent of iostream state. Each caller picks the digits
/// its reader needs (4 in toolbox-style coefficient tables, 6 in equations and error messages, 10
/// where a time or sample value must be told apart from its neighbours).

#include <cstdio>
#include <string>

namespace nlid::detail {

/// `v` with `digits` significant digits (`%.*g`), e.g. format_g(0.000123456, 3) == "0.000123".
inline std::string format_g(double v, int digits = 6) {
  char buf[64];  // "%.17g" of any double, sign and exponent included, fits with room to spare
  std::snprintf(buf, sizeof buf, "%.*g", digits, v);
  return buf;
}

}  // namespace nlid::detail
