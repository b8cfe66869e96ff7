#include "nlid/io/json.hpp"

#include <algorithm>
#include <bit>
#include <catch2/catch.hpp>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "../support/error_of.hpp"
#include "../support/sanitizer.hpp"

namespace {

using nlid_test::error_of;

nlid::Error parse_error(const std::string& text) {
  return error_of([&] { (void)nlid::Json::parse(text, "t.json"); });
}

bool same_bits(double a, double b) {
  return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b);
}

// Milliseconds that f takes, for the tests that catch an O(n²) slip on large documents.
template <class F>
double json_test_milliseconds(F&& f) {
  const auto t0 = std::chrono::steady_clock::now();
  f();
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// The calls these tests time take 1-30 ms in Release (150 ms seen on a loaded machine), the
// O(n²) versions 5-15 s; sanitizers slow everything about tenfold.
constexpr double json_test_budget_ms = NLID_TEST_ASAN ? 5000.0 : 1000.0;

}  // namespace

TEST_CASE("Json builder makes nested objects and arrays in insertion order") {
  nlid::Json j;
  j["name"] = "nlarx5";
  j["orders"] = std::vector<int>{3, 3, 0};
  j["fit"]["data3"] = 93.25;
  j["fit"]["data4"] = -1.5;
  j["converged"] = true;
  j["note"] = nullptr;
  j["log"].push_back("start");
  j["log"].push_back(2);
  j["name"] = "nlarx5b";  // assigning an existing key keeps its position
  CHECK(j.dump(-1) == R"({"name":"nlarx5b","orders":[3,3,0],"fit":{"data3":93.25,"data4":-1.5},)"
                      R"("converged":true,"note":null,"log":["start",2]})");
  CHECK(j.dump() == R"({
  "name": "nlarx5b",
  "orders": [3, 3, 0],
  "fit": {
    "data3": 93.25,
    "data4": -1.5
  },
  "converged": true,
  "note": null,
  "log": ["start", 2]
})");
  CHECK(nlid::Json::array().dump() == "[]");
  CHECK(nlid::Json::object().dump() == "{}");
  CHECK(nlid::Json::object({{"a", 1}, {"b", nlid::Json::array({1, "x", false})}}).dump(-1) ==
        R"({"a":1,"b":[1,"x",false]})");
  CHECK(j.size() == 6);
  CHECK(j.contains("fit"));
  CHECK_FALSE(j.contains("missing"));
  CHECK(j.erase("note"));
  CHECK_FALSE(j.erase("note"));
  CHECK(j.size() == 5);
}

TEST_CASE("Json numbers: integers exact, doubles shortest round trip, bit-exact") {
  CHECK(nlid::Json(42).dump() == "42");
  CHECK(nlid::Json(42.0).dump() == "42");
  CHECK(nlid::Json(-7LL).dump() == "-7");
  CHECK(nlid::Json(9007199254740992.0).dump() == "9007199254740992");
  CHECK(nlid::Json(1e15).dump() == "1000000000000000");
  CHECK(nlid::Json(1e300).dump() == "1e+300");
  CHECK(nlid::Json(0.1).dump() == "0.1");
  CHECK(nlid::Json(-0.0).dump() == "-0");
  CHECK(nlid::Json(0.1f).dump() == "0.10000000149011612");  // float widened exactly
  CHECK(nlid::Json(std::numeric_limits<std::uint32_t>::max()).dump() == "4294967295");

  // Random doubles over the whole exponent range, plus the awkward ones, survive bit for bit.
  std::mt19937_64 rng(7);
  std::vector<double> xs = {0.0,
                            -0.0,
                            std::numeric_limits<double>::min(),
                            std::numeric_limits<double>::denorm_min(),
                            -std::numeric_limits<double>::denorm_min(),
                            std::numeric_limits<double>::max(),
                            std::numeric_limits<double>::lowest(),
                            std::numeric_limits<double>::epsilon(),
                            1.0 / 3.0,
                            9007199254740993.0,
                            123456789.125};
  while (xs.size() < 2000) {
    const double x = std::bit_cast<double>(rng());
    if (std::isfinite(x)) xs.push_back(x);
  }
  nlid::Json doc;
  doc["xs"] = xs;
  for (int indent : {-1, 0, 2}) {
    const nlid::Json back = nlid::Json::parse(doc.dump(indent));
    const auto ys = back.at("xs").get<std::vector<double>>();
    REQUIRE(ys.size() == xs.size());
    std::size_t mismatches = 0;
    for (std::size_t i = 0; i < xs.size(); ++i) mismatches += !same_bits(xs[i], ys[i]);
    CHECK(mismatches == 0);
    CHECK(back == doc);
  }
}

TEST_CASE("Json numbers that underflow read as a zero of their own sign") {
  const double pos = nlid::Json::parse("1e-400").as_number();
  const double neg = nlid::Json::parse("-1e-400").as_number();
  const double neg_frac = nlid::Json::parse("-0.5e-330").as_number();
  CHECK(pos == 0.0);
  CHECK_FALSE(std::signbit(pos));
  CHECK(neg == 0.0);
  CHECK(std::signbit(neg));
  CHECK(std::signbit(neg_frac));
  // The smallest subnormal is not an underflow and stays exact.
  CHECK(nlid::Json::parse("-4.9406564584124654e-324").as_number() == -std::numeric_limits<double>::denorm_min());
}

TEST_CASE("Json tells underflow from overflow by magnitude, not by the exponent's sign or digit count") {
  // No exponent at all, yet far below the smallest subnormal.
  const double tiny = nlid::Json::parse("-0." + std::string(400, '0') + "1").as_number();
  CHECK(tiny == 0.0);
  CHECK(std::signbit(tiny));
  CHECK(nlid::Json::parse("0." + std::string(400, '0') + "1e+5").as_number() == 0.0);
  // Many integer digits and a negative exponent: 1e-400, an underflow.
  CHECK(nlid::Json::parse("1" + std::string(300, '0') + "e-700").as_number() == 0.0);
  // Overflow stays an error, also with a negative exponent; the message marks a cut number.
  const nlid::Error big = parse_error("[1" + std::string(500, '0') + "e-100]");
  CHECK_THAT(big.what(), Catch::Contains("too large for a double"));
  CHECK_THAT(big.what(), Catch::Contains("0000..."));
  CHECK(big.where().column == 2);
  CHECK_THAT(parse_error("1e99999999999999999999").what(), Catch::Contains("too large"));
}

TEST_CASE("Json refuses integers a double cannot hold and non-finite numbers, naming the path") {
  CHECK_THROWS_WITH(nlid::Json(9007199254740993LL), Catch::Contains("cannot be stored exactly"));
  CHECK_NOTHROW(nlid::Json(-9007199254740992LL));

  nlid::Json j;
  j["models"]["nlarx5"]["theta"] = std::vector<double>{1.0, 2.0, std::nan(""), 4.0};
  const nlid::Error e = error_of([&] { (void)j.dump(); });
  CHECK(e.message() ==
        "cannot write non-finite number (nan) at models.nlarx5.theta[2]: JSON has no NaN or "
        "Infinity");
  nlid::Json k = nlid::Json::array({1, -std::numeric_limits<double>::infinity()});
  CHECK_THROWS_WITH(k.dump(-1), Catch::Contains("(-inf) at [1]"));
  CHECK_THROWS_WITH(nlid::Json(std::numeric_limits<double>::infinity()).dump(),
                    Catch::Contains("(inf) at top level"));

  // The file on disk is untouched when dump fails: nothing half-written.
  const std::string path = (std::filesystem::temp_directory_path() / "nlid_json_nan.json").string();
  nlid::write_json(path, nlid::Json::object({{"ok", true}}));
  CHECK_THROWS(nlid::write_json(path, j));
  CHECK(nlid::read_json(path) == nlid::Json::object({{"ok", true}}));
  std::filesystem::remove(path);
}

TEST_CASE("Json strings: escapes, control characters and unicode round trip") {
  const std::string tricky = std::string("quote\" backslash\\ slash/ tab\t nl\n cr\r bs\b ff\f") +
                             std::string(1, '\0') + "\x01\x1f\x7f" + " é 日本 😀";
  const nlid::Json j(tricky);
  const std::string text = j.dump();
  CHECK(
      text ==
      "\"quote\\\" backslash\\\\ slash/ tab\\t nl\\n cr\\r bs\\b ff\\f\\u0000\\u0001\\u001f\\u007f"
      " é 日本 😀\"");
  CHECK(nlid::Json::parse(text).as_string() == tricky);

  // \uXXXX decoding, including a surrogate pair for U+1F600 and escaped solidus.
  CHECK(nlid::Json::parse(R"("\u00e9\u65E5\ud83d\ude00\/\u0041")").as_string() == "é日😀/A");
  CHECK(nlid::Json::parse(R"("\u0000")").as_string() == std::string(1, '\0'));

  // Keys are escaped too, and reading back finds them.
  nlid::Json o;
  o["a \"b\"\n"] = 1;
  CHECK(nlid::Json::parse(o.dump()).at("a \"b\"\n").as_number() == 1);
}

TEST_CASE("Json string errors: lone surrogates, bad escapes, raw control characters, bad UTF-8") {
  CHECK(parse_error(R"(["\ud83d"])").message() ==
        "JSON parse error: unpaired UTF-16 high surrogate in \\u escape");
  CHECK(parse_error(R"(["\ud83d"])").where().column == 3);
  CHECK(parse_error(R"("\ude00")").message() ==
        "JSON parse error: unpaired UTF-16 low surrogate in \\u escape");
  CHECK(parse_error(R"("\ud83d\u0041")").message() ==
        "JSON parse error: high surrogate not followed by a low surrogate in \\u escape");
  CHECK(parse_error(R"("\x")").message() == "JSON parse error: invalid escape '\\x' in string");
  // A control byte after the backslash is named in hex: a NUL in the text cut what() short there,
  // losing the file and position.
  const nlid::Error nul = parse_error(std::string("\"\\\0\"", 4));
  CHECK(nul.message() == "JSON parse error: invalid escape: backslash before byte 0x00 in string");
  CHECK(std::string(nul.what()).find("t.json") != std::string::npos);
  CHECK(parse_error("\"\\\xc3\xa9\"").message() ==
        "JSON parse error: invalid escape: backslash before byte 0xc3 in string");
  CHECK(parse_error(R"("\u12G4")").message() ==
        "JSON parse error: \\u escape needs four hex digits");
  CHECK(parse_error("\"a\nb\"").message() ==
        "JSON parse error: line break inside a string (write \\n, or close the quote)");
  CHECK(parse_error("\"a\tb\"").message() ==
        "JSON parse error: control character inside a string must be escaped");
  CHECK(parse_error("\"\xC3\x28\"").message() == "JSON parse error: invalid UTF-8 byte in string");
  CHECK(parse_error("\"\xED\xA0\x80\"").message() ==  // CESU-style encoded surrogate
        "JSON parse error: invalid UTF-8 byte in string");
  CHECK(parse_error("\"\xC0\xAF\"").message() ==  // overlong '/'
        "JSON parse error: invalid UTF-8 byte in string");

  nlid::Json j;
  j["name"] = std::string("caf\xE9");  // Latin-1, not UTF-8
  CHECK(error_of([&] { (void)j.dump(); }).message() ==
        "string at name is not valid UTF-8 (byte 3)");
}

TEST_CASE("Json parse error columns do not count a byte-order mark, which editors do not show") {
  CHECK(nlid::Json::parse("\xEF\xBB\xBF[1]").size() == 1);
  const nlid::Error e = parse_error("\xEF\xBB\xBF[1, x]");
  CHECK(e.where().row == 1);
  CHECK(e.where().column == 5);
  CHECK(parse_error("\xEF\xBB\xBF").where().column == 1);
}

TEST_CASE("Json parse errors say what and where (line and column)") {
  // Truncated input: reported at the end, naming what was left open.
  nlid::Error e = parse_error("{\n  \"a\": [1, 2,\n    3");
  CHECK(e.message() ==
        "JSON parse error: unexpected end of input: unterminated array starting at line 2");
  CHECK(e.where().file == "t.json");
  CHECK(e.where().row == 3);
  CHECK(e.where().column == 6);
  CHECK(std::string(e.what()) ==
        "nlid: JSON parse error: unexpected end of input: unterminated array starting at line 2 "
        "[at file 't.json', row 3, column 6]");

  e = parse_error(R"({"a": "unterminated)");
  CHECK(e.message() ==
        "JSON parse error: unexpected end of input: unterminated string starting at line 1");

  // Trailing commas.
  e = parse_error("[1, 2,]");
  CHECK(e.message() == "JSON parse error: trailing comma is not allowed in JSON");
  CHECK(e.where().row == 1);
  CHECK(e.where().column == 7);
  e = parse_error("{\n  \"a\": 1,\n}");
  CHECK(e.message() == "JSON parse error: trailing comma is not allowed in JSON");
  CHECK(e.where().row == 3);
  CHECK(e.where().column == 1);

  // Bad literals.
  e = parse_error("[true, fals]");
  CHECK(e.message() == "JSON parse error: invalid literal 'fals' (expected true, false or null)");
  CHECK(e.where().column == 8);
  CHECK(parse_error("[NaN]").message() ==
        "JSON parse error: 'NaN' is not valid JSON (JSON has no NaN or Infinity)");
  CHECK(parse_error("-Infinity").message() ==
        "JSON parse error: -Infinity is not valid JSON (no NaN/Inf)");

  // Column counts code points, not bytes: "é" is one column.
  e = parse_error("{\"é\": tru}");
  CHECK(e.where().column == 7);

  // Numbers.
  CHECK(parse_error("[01]").message() ==
        "JSON parse error: leading zeros are not allowed in JSON numbers");
  CHECK(parse_error("[1.]").message() ==
        "JSON parse error: expected a digit after the decimal point");
  CHECK(parse_error("[1e]").message() == "JSON parse error: expected a digit in the exponent");
  CHECK(parse_error("[+1]").message() == "JSON parse error: unexpected '+': expected a value");
  CHECK(parse_error("1e400").message() ==
        "JSON parse error: number 1e400 is too large for a double");
  CHECK(nlid::Json::parse("1e-400").as_number() == 0.0);  // underflow rounds to zero, as IEEE does

  // Structure.
  CHECK(parse_error("").message() == "JSON parse error: empty input: expected a JSON value");
  CHECK(parse_error("  \n ").where().row == 2);
  CHECK(parse_error("[1 2]").message() ==
        "JSON parse error: expected ',' or ']' after array element, found '2'");
  CHECK(parse_error(R"({"a" 1})").message() ==
        "JSON parse error: expected ':' after key 'a', found '1'");
  CHECK(parse_error("{a: 1}").message() ==
        "JSON parse error: expected a string key in double quotes, found 'a'");
  CHECK(parse_error(R"({"a": 1 "b": 2})").message() ==
        "JSON parse error: expected ',' or '}' after object member, found '\"'");
  CHECK(parse_error("[1] x").message() == "JSON parse error: unexpected 'x' after the JSON value");
  CHECK(parse_error("[1] // note").message() ==
        "JSON parse error: comments are not allowed in JSON");
  e = parse_error("{\"a\": 1,\n \"a\": 2}");
  CHECK(e.message() == "JSON parse error: duplicate key 'a' in object");
  CHECK(e.where().row == 2);
  CHECK(e.where().column == 2);
  CHECK(parse_error(std::string(600, '[')).message() ==
        "JSON parse error: nesting deeper than 512 levels");
  // A large object (past the 32 members checked by a scan) finds a repeat of an early key and
  // of a late one, and reads back whole when there is none.
  std::string big = "{";
  for (int k = 0; k < 100; ++k) big += (k ? ", \"k" : "\"k") + std::to_string(k) + "\": " + std::to_string(k);
  CHECK(nlid::Json::parse(big + "}").as_object().size() == 100);
  CHECK(parse_error(big + ", \"k3\": 0}").message() == "JSON parse error: duplicate key 'k3' in object");
  CHECK(parse_error(big + ", \"k77\": 0}").message() == "JSON parse error: duplicate key 'k77' in object");
}

TEST_CASE("Json accessors name the key path, file, line and column on wrong type or missing key") {
  const std::string text = R"({
  "models": {
    "nlarx5": {"seconds": "fast", "theta": [1, 2.5, "x"], "order": 3},
    "odd key": {"n": true}
  }
})";
  const nlid::Json j = nlid::Json::parse(text, "run.json");
  nlid::Error e = error_of([&] { (void)j.at("models").at("nlarx5").at("seconds").as_number(); });
  CHECK(e.message() == "expected number at models.nlarx5.seconds, found string \"fast\"");
  CHECK(e.where().file == "run.json");
  CHECK(e.where().row == 3);
  CHECK(e.where().column == 27);

  e = error_of([&] { (void)j.at("models").at("nlarx5").at("secs"); });
  CHECK(e.message() == "missing key 'secs' at models.nlarx5");
  CHECK(e.where().row == 3);

  e = error_of([&] { (void)j.at("models").at("nlarx5").at("theta").get<std::vector<double>>(); });
  CHECK(e.message() == "expected number at models.nlarx5.theta[2], found string \"x\"");
  e = error_of([&] { (void)j.at("models").at("nlarx5").at("theta").at(7); });
  CHECK(e.message() == "index 7 out of range at models.nlarx5.theta (array has 3 elements)");
  e = error_of([&] { (void)j.at("models").at("odd key").at("n").as_string(); });
  CHECK(e.message() == "expected string at models[\"odd key\"].n, found boolean true");
  e = error_of([&] { (void)j.at("models").at("nlarx5").at("theta").at(1).get<int>(); });
  CHECK(e.message() == "expected integer at models.nlarx5.theta[1], found number 2.5");
  e = error_of([&] { (void)j.at(0); });
  CHECK(e.message() == "expected array at top level, found object with 1 keys");
  CHECK_NOTHROW(j.at("models").at("nlarx5").at("order").get<std::uint8_t>());
  CHECK(j.at("models").at("nlarx5").at("order").get<int>() == 3);

  // Optional keys: absent -> fallback; present with the wrong type -> error, not the fallback.
  const auto m = j.at("models").at("nlarx5");
  CHECK(m.value_or("iterations", 90) == 90);
  CHECK(m.value_or("order", 1) == 3);
  CHECK_THROWS_WITH(m.value_or("seconds", 1.0),
                    Catch::Contains("expected number at models.nlarx5.seconds"));

  // Unknown keys (typos) in hand-edited files.
  e = error_of([&] { m.check_keys({"seconds", "theta"}); });
  CHECK(e.message() == "unknown key 'order' at models.nlarx5 (allowed: seconds, theta)");
  CHECK(e.where().row == 3);
  CHECK_NOTHROW(m.check_keys({"seconds", "theta", "order"}));
  CHECK(m.keys() == std::vector<std::string>{"seconds", "theta", "order"});

  // Values built in code have no position; errors still name the path.
  nlid::Json built;
  built["a"]["b"] = 1;
  e = error_of([&] { (void)built.at("a").at("b").as_bool(); });
  CHECK(std::string(e.what()) == "nlid: expected boolean at a.b, found number 1");

  // Index access: modifies existing elements; never grows an array or treats 0 as a key.
  nlid::Json arr = nlid::Json::array({1, 2, 3});
  arr[0] = "one";
  CHECK(arr.dump(-1) == R"(["one",2,3])");
  CHECK_THROWS_WITH(arr[3], "nlid: index 3 out of range (array has 3 elements)");
  nlid::Json obj = nlid::Json::object({{"a", 1}});
  CHECK_THROWS_WITH(obj[0], Catch::Contains("cannot index a JSON object with [0]"));
  const nlid::Json& cobj = obj;
  CHECK(cobj["a"].as_number() == 1);  // const operator[] reads, never inserts
  CHECK_THROWS_WITH(cobj["b"], "nlid: missing key 'b' at top level");
  CHECK(obj.size() == 1);

  // Builder misuse.
  nlid::Json n(3.0);
  CHECK_THROWS_WITH(n["k"], Catch::Contains("cannot set key 'k' on a JSON number"));
  CHECK_THROWS_WITH(n.push_back(1), Catch::Contains("cannot push_back onto a JSON number"));
  CHECK_THROWS_WITH(nlid::Json::object({{"a", 1}, {"a", 2}}), Catch::Contains("duplicate key 'a'"));
}

TEST_CASE("Json typed get: floats, integer ranges, strings, nested vectors") {
  const nlid::Json j = nlid::Json::parse(R"({"f": 0.5, "big": 1e300, "i": -3, "s": "x",
    "names": ["u", "y"], "m": [[1, 2], [3, 4]], "b": [true, false]})");
  CHECK(j.at("f").get<float>() == 0.5f);
  CHECK_THROWS_WITH(j.at("big").get<float>(), Catch::Contains("out of range for float"));
  CHECK(j.at("i").get<long>() == -3);
  CHECK_THROWS_WITH(j.at("i").get<unsigned>(), Catch::Contains("integer -3 at i is out of range"));
  CHECK(j.at("s").get<std::string>() == "x");
  CHECK(j.at("names").get<std::vector<std::string>>() == std::vector<std::string>{"u", "y"});
  CHECK(j.at("m").get<std::vector<std::vector<double>>>() ==
        std::vector<std::vector<double>>{{1, 2}, {3, 4}});
  CHECK(j.at("b").get<std::vector<bool>>() == std::vector<bool>{true, false});
  CHECK(j.get<nlid::Json>() == j);
  // Object equality ignores key order (JSON semantics), values matter.
  CHECK(nlid::Json::parse(R"({"a":1,"b":2})") == nlid::Json::parse(R"({"b":2,"a":1})"));
  CHECK_FALSE(nlid::Json::parse(R"({"a":1,"b":2})") == nlid::Json::parse(R"({"a":1,"b":3})"));
  CHECK_FALSE(nlid::Json::parse("[1,2]") == nlid::Json::parse("[2,1]"));
  CHECK_FALSE(nlid::Json(1) == nlid::Json("1"));
}

TEST_CASE("Json pretty printing wraps long numeric arrays and stays parseable") {
  std::vector<double> v(1000);
  for (std::size_t i = 0; i < v.size(); ++i) v[i] = 0.001 * static_cast<double>(i * i);
  nlid::Json j;
  j["theta"] = v;
  const std::string text = j.dump(2);
  std::size_t longest = 0, line = 0;
  for (char c : text) {
    line = c == '\n' ? 0 : line + 1;
    longest = std::max(longest, line);
  }
  CHECK(longest <= 120);
  CHECK(std::count(text.begin(), text.end(), '\n') < 150);  // not one line per number
  CHECK(nlid::Json::parse(text) == j);
}

TEST_CASE("write_json / read_json round trip through a file, missing file is an error") {
  const auto dir = std::filesystem::temp_directory_path() / "nlid_json_test";
  std::filesystem::create_directories(dir);
  const std::string path = (dir / "summary.json").string();
  nlid::Json j;
  j["experiment"] = "data3";
  j["fit"] = 91.234567890123;
  j["y"] = std::vector<double>{15.0, 15.25, -0.0};
  nlid::write_json(path, j);
  const nlid::Json back = nlid::read_json(path);
  CHECK(back == j);
  CHECK(same_bits(back.at("y").at(2).as_number(), -0.0));
  CHECK(back.at("fit").json().line() == 3);
  CHECK(back.at("fit").json().source() == path);
  CHECK(nlid::read_file(path).back() == '\n');

  std::filesystem::remove(path);
  const nlid::Error e = error_of([&] { (void)nlid::read_json(path); });
  CHECK(e.message() == "file not found");
  CHECK(e.where().file == path);
  CHECK_THROWS_WITH(nlid::write_json((dir / "no" / "such" / "x.json").string(), j),
                    Catch::Contains("directory does not exist"));

  // A parse error in a file names the file.
  nlid::write_file_atomically(path, "{\"a\": [1,]}");
  CHECK_THROWS_WITH(nlid::read_json(path), Catch::Contains("trailing comma") &&
                                               Catch::Contains("summary.json") &&
                                               Catch::Contains("row 1, column 10"));
  std::filesystem::remove_all(dir);
}

namespace {

// `levels` containers around the number `leaf`, arrays and objects (key "k") alternating from
// the inside out; the leaf is at depth `levels`.
nlid::Json nested(int levels, double leaf) {
  nlid::Json j = leaf;
  for (int k = 0; k < levels; ++k) {
    nlid::Json outer;
    if (k % 2 == 0) {
      outer.push_back(std::move(j));
    } else {
      outer["k"] = std::move(j);
    }
    j = std::move(outer);
  }
  return j;
}

}  // namespace

TEST_CASE("Json trees built in code copy, compare and destroy at any depth, and dump stops at 512 levels") {
  // 200 000 levels: each of the old recursive copy, ==, dump and destructor overflowed the stack.
  const nlid::Json a = nested(200000, 1.0);
  nlid::Json b = a;
  CHECK(b == a);
  nlid::Json* leaf = &b;
  while (leaf->size() > 0) leaf = leaf->is_array() ? &(*leaf)[0] : &(*leaf)["k"];
  *leaf = 2.0;
  CHECK_FALSE(b == a);
  const nlid::Error e = error_of([&] { (void)a.dump(); });
  CHECK_THAT(e.message(), Catch::StartsWith("cannot write JSON nested deeper than 512 levels (at k[0].k[0].k") &&
                              Catch::EndsWith(".k[0]...): Json::parse reads no deeper, so the text could not be read back"));
  CHECK(e.message().size() < 250);  // not the 2000 characters of the whole path
  b = a;  // copy assignment over a deep tree
  CHECK(b == a);
  b = nlid::Json(3);  // the deep tree it held is destroyed here
  CHECK(b == nlid::Json(3));

  // dump writes exactly what parse reads: 512 levels round trip, 513 are refused by both.
  const nlid::Json deepest = nested(512, 1.0);
  CHECK(nlid::Json::parse(deepest.dump(-1)) == deepest);
  CHECK(nlid::Json::parse(deepest.dump(2)) == deepest);
  CHECK_THROWS_WITH(nested(513, 1.0).dump(), Catch::Contains("nested deeper than 512 levels"));
  CHECK(parse_error(std::string(513, '[') + "1" + std::string(513, ']')).message() ==
        "JSON parse error: nesting deeper than 512 levels");
}

TEST_CASE("Json from a null const char* is an nlid::Error, not undefined behaviour") {
  const char* none = nullptr;
  const nlid::Error e = error_of([&] { nlid::Json j(none); });
  CHECK(e.message() ==
        "Json(const char*) got a null pointer, which is not a string (write nullptr or Json() for JSON null)");
  nlid::Json j;
  CHECK_THROWS_AS(j["name"] = none, nlid::Error);
  CHECK(nlid::Json(nullptr).is_null());  // the literal still means JSON null
  CHECK(nlid::Json("").as_string().empty());
}

TEST_CASE("A null const char* key is an nlid::Error, not undefined behaviour") {
  // Converted to std::string_view, a null pointer was read for its length: undefined behaviour
  // (in practice a crash inside strlen) from every keyed accessor.
  const char* none = nullptr;
  nlid::Json j = nlid::Json::object({{"a", 1}});
  CHECK(error_of([&] { (void)j[none]; }).message() ==
        "Json::operator[] got a null const char* as the key; a key must be a string");
  CHECK(j.size() == 1u);  // nothing inserted
  const nlid::Json& cj = j;
  CHECK_THROWS_WITH(cj[none], Catch::Contains("Json::operator[] got a null const char* as the key"));
  CHECK_THROWS_WITH(cj.at(none), Catch::Contains("Json::at got a null const char* as the key"));
  const nlid::Json doc = nlid::Json::parse(R"({"m": {"k": 2}})");
  CHECK_THROWS_WITH(doc.at("m")[none], Catch::Contains("a null const char* is not a key (at m)"));
  CHECK_THROWS_WITH(doc.at("m").at(none), Catch::Contains("a null const char* is not a key (at m)"));
  // C-string keys (const and not) still work, and 0 is still an index, not a null key.
  const char* k = "k";
  CHECK(doc.at("m")[k].as_number() == 2.0);
  CHECK(doc["m"].at(k).as_number() == 2.0);
  char key[] = "a";
  CHECK(j[key] == nlid::Json(1));
  CHECK(cj.at(key).as_number() == 1.0);
  nlid::Json arr = nlid::Json::array({7});
  CHECK(arr[0] == nlid::Json(7));
  CHECK(static_cast<const nlid::Json&>(arr)[0].as_number() == 7.0);
  CHECK(doc.at("m").contains("k"));
  // The accessors that never throw treat a null key as naming no member; value_or refuses it.
  CHECK(cj.find(none) == nullptr);
  CHECK_FALSE(cj.contains(none));
  CHECK_FALSE(doc.at("m").contains(none));
  CHECK_FALSE(j.erase(none));
  CHECK(j.size() == 1u);
  CHECK(cj.find(key) != nullptr);
  CHECK_THROWS_WITH(doc.at("m").value_or(none, 5.0), Catch::Contains("a null const char* is not a key (value_or at m)"));
  CHECK(doc.at("m").value_or(k, 5.0) == 2.0);
  CHECK(doc.at("m").value_or("absent", 5.0) == 5.0);
}

TEST_CASE("Json error previews cut long strings at a character boundary, not inside one") {
  // Found by tests/fuzz/json_fuzz.cpp: the preview kept the first 40 bytes, which here end inside
  // the two bytes of 'é', and the cut text then failed the UTF-8 check: a valid string was shown
  // as "<not UTF-8>".
  const std::string a39(39, 'a');
  const nlid::Json j = nlid::Json::parse("{\"s\": \"" + a39 + "\u00e9xyz\"}", "p.json");
  CHECK(error_of([&] { (void)j.at("s").as_number(); }).message() ==
        "expected number at s, found string \"" + a39 + "...\"");
  // A string that is cut after a whole 'é' keeps it.
  const nlid::Json k = nlid::Json("a\u00e9" + std::string(40, 'b'));
  CHECK(error_of([&] { (void)k.as_bool(); }).message() ==
        "expected boolean at top level, found string \"a\u00e9" + std::string(37, 'b') + "...\"");
  // Malformed text built in code is still reported as such.
  CHECK_THAT(error_of([&] { (void)nlid::Json(std::string(50, '\xff')).as_bool(); }).message(),
             Catch::EndsWith("found string \"<not UTF-8>...\""));
}

TEST_CASE("Json dump without indentation of many small arrays takes linear time") {
  // The one-line writer searched back for the start of the line (which it never wraps) at
  // every array: 100 000 empty arrays took seconds.
  std::string text = "[[]";
  for (int k = 1; k < 100000; ++k) text += ",[]";
  text += "]";
  const nlid::Json j = nlid::Json::parse(text);
  std::string out;
  const double ms = json_test_milliseconds([&] { out = j.dump(-1); });
  WARN("dump(-1) of 100 000 arrays: " << ms << " ms");
  CHECK(out == text);
  CHECK(ms < json_test_budget_ms);
}

TEST_CASE("Json equality of large objects takes linear time, in any member order") {
  // Each member was looked up by a scan of the other object: 100 000 keys took seconds.
  nlid::Json a, b;
  const int n = 100000;
  // Built through as_object(): operator[] looks the key up first, itself a scan.
  for (int k = 0; k < n; ++k) a.as_object().emplace_back("k" + std::to_string(k), k);
  for (int k = n - 1; k >= 0; --k) b.as_object().emplace_back("k" + std::to_string(k), k);  // reversed
  bool same = false;
  const double ms = json_test_milliseconds([&] { same = a == b; });
  WARN("== of two objects of 100 000 members: " << ms << " ms");
  CHECK(same);
  CHECK(ms < json_test_budget_ms);
  b["k77777"] = 0;  // one value differs
  CHECK_FALSE(a == b);
  CHECK(b.erase("k5"));
  b["k5x"] = 5;  // one key differs, same size
  CHECK_FALSE(a == b);
  CHECK_FALSE(b == a);
}

TEST_CASE("Json move assignment from a member of the value itself unwraps it") {
  // The defaulted move assignment destroyed the old value, and the member inside it, before
  // reading the member: j = std::move(j["a"]) read freed memory (a garbage string, or a crash).
  nlid::Json j = nlid::Json::parse(R"({"a": {"b": ["a string longer than fifteen bytes", 2]}, "c": 3})");
  j = std::move(j["a"]);  // object member over the object
  CHECK(j == nlid::Json::parse(R"({"b": ["a string longer than fifteen bytes", 2]})"));
  j = std::move(j["b"]);
  CHECK(j.dump(-1) == R"(["a string longer than fifteen bytes",2])");
  j = std::move(j[0]);  // array element over the array, a string over an array
  CHECK(j.as_string() == "a string longer than fifteen bytes");
  CHECK(j.line() == 1);  // the member's own position, not freed memory
  CHECK(j.column() == 14);
  nlid::Json& self = j;
  j = std::move(self);  // self-move keeps the value
  CHECK(j.as_string() == "a string longer than fifteen bytes");
  nlid::Json k = nlid::Json::array({nlid::Json::array({1, 2}), 3});
  k = k[0];  // copy assignment from a member (copies first, then replaces)
  CHECK(k == nlid::Json::array({1, 2}));
}

TEST_CASE("Json new member copied from a sibling: j[\"new\"] = j[\"a\"]") {
  // The right side is evaluated first; the members lived in a vector, and inserting "new" could
  // move them, so the copy read a freed member (the sanitizer build reported it; a plain build
  // copied garbage or crashed). Each insertion below is a chance for the old storage to regrow.
  nlid::Json j;
  j["a"] = nlid::Json::object({{"b", "a string longer than fifteen bytes"}, {"c", nlid::Json::array({1, 2})}});
  for (int k = 0; k < 40; ++k) j["copy" + std::to_string(k)] = j["a"];
  REQUIRE(j.size() == 41);
  for (int k = 0; k < 40; ++k) CHECK(j["copy" + std::to_string(k)] == j["a"]);
  // A member held by reference stays valid while others are added and removed.
  nlid::Json& a = j["a"];
  for (int k = 0; k < 40; ++k) j["more" + std::to_string(k)] = k;
  CHECK(j.erase("copy0"));
  CHECK(&a == &j["a"]);
  CHECK(a.dump(-1) == R"({"b":"a string longer than fifteen bytes","c":[1,2]})");
}
