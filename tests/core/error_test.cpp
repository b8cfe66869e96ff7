#include "nlid/core/error.hpp"

#include <Eigen/Core>
#include <catch2/catch.hpp>

#include "nlid/core/sizes.hpp"

TEST_CASE("Error message names what and where") {
  nlid::Location where;
  where.file = "a.csv";
  where.row = 12;
  where.column = 3;
  where.column_name = "y";
  const nlid::Error e("non-numeric cell 'abc'", where);
  CHECK(std::string(e.what()) ==
        "nlid: non-numeric cell 'abc' [at file 'a.csv', row 12, column 3 ('y')]");
  CHECK(e.message() == "non-numeric cell 'abc'");
  CHECK(e.where().row == 12);
}

TEST_CASE("Error without location has no suffix, experiment and parameter locations") {
  CHECK(std::string(nlid::Error("x").what()) == "nlid: x");
  CHECK(std::string(nlid::Error("too short", nlid::at_experiment(2)).what()) ==
        "nlid: too short [at experiment 2]");
  CHECK_THROWS_WITH(nlid::require(false, "must be positive", nlid::at_parameter("ts")),
                    "nlid: must be positive [at parameter 'ts']");
  CHECK_NOTHROW(nlid::require(true, "never"));
}

TEST_CASE("Error text stays whole and UTF-8 whatever bytes it quotes") {
  // A NUL ended what() early; a Latin-1 byte (0xB0 for the degree sign, 0xE4 for ä in a file
  // name) made the text malformed UTF-8, which the JSON writer of reports refuses.
  nlid::Location where;
  where.file = "mess\xE4ung.csv";
  const std::string raw = std::string("column 'Winkel\xB0' has a NUL \0 here,\nsee\tbelow; 'caf\xC3\xA9' is fine", 61);
  const nlid::Error e(raw, where);
  const std::string expected_message =
      "column 'Winkel\\xB0' has a NUL \\x00 here,\nsee\tbelow; 'caf\xC3\xA9' is fine";
  CHECK(e.message() == expected_message);
  CHECK(std::string(e.what()) == "nlid: " + expected_message + " [at file 'mess\\xE4ung.csv']");
  CHECK(nlid::first_invalid_utf8(e.what()) == std::string::npos);
  CHECK(e.where().file == "mess\xE4ung.csv");  // the structured field is the path as given
  // Already-safe text comes back unchanged, and escaping twice changes nothing more.
  CHECK(nlid::Error(e.message()).message() == e.message());
  CHECK(nlid::detail::message_safe("plain \xE2\x82\xAC text") == "plain \xE2\x82\xAC text");
  CHECK(nlid::detail::message_safe(std::string("\x7F\xC3", 2)) == "\\x7F\\xC3");
}

TEST_CASE("Compile-time size arithmetic propagates Dynamic") {
  static_assert(nlid::size_sum(2, 3, 4) == 9);
  static_assert(nlid::size_sum(2, nlid::Dynamic) == nlid::Dynamic);
  static_assert(nlid::size_product(2, 3) == 6);
  static_assert(nlid::size_product(nlid::Dynamic, 3) == nlid::Dynamic);
  static_assert(nlid::Dynamic == Eigen::Dynamic);
  CHECK(nlid::is_static(4));
  CHECK_FALSE(nlid::is_static(nlid::Dynamic));
}
