// The number format every message, report and describe() goes through.
#include <catch2/catch.hpp>

#include <cstdio>
#include <limits>
#include <string>

#include "nlid/core/format.hpp"
#include "../support/decimal_comma_locale.hpp"

using nlid::detail::format_g;

TEST_CASE("format_g: significant digits as asked, 6 by default", "[core][format]") {
  CHECK(format_g(1.0 / 3.0) == "0.333333");
  CHECK(format_g(1.0 / 3.0, 4) == "0.3333");
  CHECK(format_g(123456789.0, 10) == "123456789");
  CHECK(format_g(123456789.0) == "1.23457e+08");
  CHECK(format_g(0.000123456, 3) == "0.000123");
  CHECK(format_g(-2.5) == "-2.5");
  CHECK(format_g(0.0) == "0");
}

TEST_CASE("append_g: appends exactly format_g's text", "[core][format]") {
  std::string text = "t=";
  nlid::detail::append_g(text, 0.1, 17);
  CHECK(text == "t=0.10000000000000001");
  for (const double v : {1.0 / 3.0, -123456789.0, 1e-300, -std::numeric_limits<double>::infinity()}) {
    for (const int digits : {-1, 1, 6, 17, 60}) {
      std::string s = "x";
      nlid::detail::append_g(s, v, digits);
      CHECK(s == "x" + format_g(v, digits));
    }
  }
}

TEST_CASE("format_g: extreme and non-finite values stay whole", "[core][format]") {
  // The longest %.17g text: sign, 17 digits, point, three-digit exponent.
  CHECK(format_g(-std::numeric_limits<double>::max(), 17) == "-1.7976931348623157e+308");
  CHECK(format_g(-std::numeric_limits<double>::denorm_min(), 17) == "-4.9406564584124654e-324");
  CHECK(format_g(std::numeric_limits<double>::infinity()) == "inf");
  CHECK(format_g(-std::numeric_limits<double>::quiet_NaN()).find("nan") != std::string::npos);
}

namespace {
// printf's text for one double in the current C locale: the reference the helpers must match
// while LC_NUMERIC is "C" (the tests below run before any decimal-comma locale is set).
std::string format_test_printf(const char* fmt, double v) {
  char buf[512];
  std::snprintf(buf, sizeof buf, fmt, v);
  return buf;
}
}  // namespace

TEST_CASE("format_f and format_g: the same text as printf in the C locale", "[core][format]") {
  const double inf = std::numeric_limits<double>::infinity();
  const double values[] = {0.0, -0.0, 0.5, 0.125, 2.5, -2.5, 99.95, 99.995, 1.0 / 3.0, -2.0 / 3.0, 1e-7,
                           123456.789, -98765.4321, 1e21, 1e300, std::numeric_limits<double>::max(),
                           std::numeric_limits<double>::denorm_min(), inf, -inf};
  for (double v : values) {
    CAPTURE(v);
    CHECK(nlid::detail::format_f(v, 0) == format_test_printf("%.0f", v));
    CHECK(nlid::detail::format_f(v, 1) == format_test_printf("%.1f", v));
    CHECK(nlid::detail::format_f(v, 2) == format_test_printf("%.2f", v));
    CHECK(nlid::detail::format_f(v, 4) == format_test_printf("%.4f", v));
    CHECK(nlid::detail::with_plus(nlid::detail::format_f(v, 1)) == format_test_printf("%+.1f", v));
    CHECK(nlid::detail::with_plus(format_g(v, 3)) == format_test_printf("%+.3g", v));
    CHECK(format_g(v) == format_test_printf("%g", v));
    CHECK(format_g(v, 3) == format_test_printf("%.3g", v));
    CHECK(format_g(v, 17) == format_test_printf("%.17g", v));
    CHECK(nlid::detail::right_aligned(nlid::detail::format_f(v, 2), 10) == format_test_printf("%10.2f", v));
    CHECK(nlid::detail::right_aligned(format_g(v, 5), 12) == format_test_printf("%12.5g", v));
  }
  CHECK(nlid::detail::format_f(std::numeric_limits<double>::quiet_NaN(), 1) == "nan");
  CHECK(nlid::detail::with_plus(nlid::detail::format_f(inf, 1)) == "+inf");
  CHECK(nlid::detail::format_f(-inf, 1) == "-inf");
  CHECK(nlid::detail::format_f(12.345, 2) == "12.35");  // 12.345 is 12.3450000000000006...
  CHECK(nlid::detail::format_f(99.5, 0) + " %" == "100 %");
  CHECK(nlid::detail::format_f(-0.04, 1) == "-0.0");  // printf keeps the sign of what rounds to 0
}

TEST_CASE("right_aligned and left_aligned pad like %10s and %-12s, never cut", "[core][format]") {
  CHECK(nlid::detail::right_aligned("ab", 5) == "   ab");
  CHECK(nlid::detail::left_aligned("ab", 5) == "ab   ");
  CHECK(nlid::detail::right_aligned("abcdef", 3) == "abcdef");
  CHECK(nlid::detail::left_aligned("abcdef", 3) == "abcdef");
  CHECK(nlid::detail::right_aligned("", 2) == "  ");
}

TEST_CASE("format_f, format_g and with_plus write '.' under a decimal-comma LC_NUMERIC", "[core][format][locale]") {
  const std::string c_fixed = format_test_printf("%.2f", 1234.5);
  const nlid_test::DecimalCommaLocale comma;
  if (nlid_test::DecimalCommaLocale::required()) REQUIRE(comma.active());
  if (!comma.active()) {
    WARN("no locale with decimal commas installed: not checked");
    return;
  }
  REQUIRE(format_test_printf("%.2f", 1234.5) == "1234,50");  // the locale is the one printf follows
  CHECK(nlid::detail::format_f(1234.5, 2) == c_fixed);
  CHECK(nlid::detail::format_f(-0.25, 1) == "-0.2");
  CHECK(format_g(0.5) == "0.5");
  CHECK(nlid::detail::with_plus(nlid::detail::format_f(3.25, 1)) == "+3.2");
}
