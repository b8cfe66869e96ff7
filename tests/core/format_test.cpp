// The number format every message, report and describe() goes through.
#include <catch2/catch.hpp>

#include <limits>

#include "nlid/core/format.hpp"

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

TEST_CASE("format_g: extreme and non-finite values stay whole", "[core][format]") {
  // The longest %.17g text: sign, 17 digits, point, three-digit exponent.
  CHECK(format_g(-std::numeric_limits<double>::max(), 17) == "-1.7976931348623157e+308");
  CHECK(format_g(-std::numeric_limits<double>::denorm_min(), 17) == "-4.9406564584124654e-324");
  CHECK(format_g(std::numeric_limits<double>::infinity()) == "inf");
  CHECK(format_g(-std::numeric_limits<double>::quiet_NaN()).find("nan") != std::string::npos);
}
