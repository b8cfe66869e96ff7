// libFuzzer harness for nlid::Json (json.hpp) and the Eigen readers (json_eigen.hpp).
// Contract: bad text is an nlid::Error naming file, row and column; anything else escaping
// (another exception type aborts through libFuzzer), a sanitizer report or a failed check below
// is a defect. On success it checks what the header promises of a parsed value.
#include <Eigen/Core>
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "nlid/core/error.hpp"
#include "nlid/core/utf8.hpp"
#include "nlid/io/json.hpp"
#include "nlid/io/json_eigen.hpp"

namespace {

void check(bool ok, const char* what) {
  if (!ok) {
    std::fprintf(stderr, "json_fuzz: invariant broken: %s\n", what);
    std::abort();
  }
}

// A location must point into the text: row within its lines, column at most one past the end
// of that line, counted in code points as the parser counts them (bytes that start a sequence).
// Line widths are counted once per input: per error, a long line would make the check O(n²).
struct Lines {
  std::vector<long> width{0};
  explicit Lines(std::string_view text) {
    for (char c : text) {
      if (c == '\n') {
        width.push_back(0);
      } else {
        width.back() += (static_cast<unsigned char>(c) & 0xC0) != 0x80;
      }
    }
  }
  bool inside(long row, long column) const {
    return row >= 1 && row <= static_cast<long>(width.size()) && column >= 1 &&
           column <= width[static_cast<std::size_t>(row - 1)] + 1;
  }
};

// Runs f, which must throw nlid::Error (a wrong-type or missing-key access); an error about a
// parsed value must carry that value's position.
template <class F>
void expect_error(F&& f, const Lines& lines) {
  try {
    f();
  } catch (const nlid::Error& e) {
    check(lines.inside(e.where().row, e.where().column), "accessor error outside the text");
    check(e.where().file == "fuzz.json", "accessor error lost the source name");
    return;
  }
  check(false, "accessor accepted a value of the wrong type");
}

// Reads an array through the Eigen and vector readers. Each may refuse the shape with
// nlid::Error; what a double reader accepts must convert back to the same JSON.
void read_as_matrices(const nlid::JsonView& v, const Lines& lines) {
  const auto attempt = [&](auto reader) {
    try {
      reader();
    } catch (const nlid::Error& e) {
      check(lines.inside(e.where().row, e.where().column), "reader error outside the text");
    }
  };
  attempt([&] { check(nlid::Json(v.get<Eigen::VectorXd>()) == v.json(), "VectorXd round trip"); });
  attempt([&] { check(nlid::Json(v.get<Eigen::MatrixXd>()) == v.json(), "MatrixXd round trip"); });
  attempt([&] { check(nlid::Json(v.get<std::vector<std::vector<double>>>()) == v.json(), "nested vector round trip"); });
  attempt([&] { (void)v.get<Eigen::Vector3f>(); });
  attempt([&] { (void)v.get<Eigen::RowVector2d>(); });
  attempt([&] { (void)v.get<Eigen::Matrix<double, 2, 3>>(); });
  attempt([&] { (void)v.get<Eigen::Matrix<double, Eigen::Dynamic, 3>>(); });
  // Bounded dynamic sizes: a wrong bound check would write past the inline storage.
  attempt([&] { (void)v.get<Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 4, 1>>(); });
  attempt([&] { (void)v.get<Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, 0, 3, 2>>(); });
  attempt([&] { (void)v.get<Eigen::Array<double, 1, Eigen::Dynamic, Eigen::RowMajor, 1, 3>>(); });
}

// Visits every value through JsonView, iteratively (a parsed tree is up to 512 levels deep).
void walk(const nlid::Json& root, const Lines& lines) {
  std::vector<nlid::JsonView> todo{root.view()};
  while (!todo.empty()) {
    const nlid::JsonView v = std::move(todo.back());
    todo.pop_back();
    const nlid::Json& j = v.json();
    check(lines.inside(j.line(), j.column()), "value position outside the text");
    using T = nlid::Json::Type;
    if (j.type() != T::number) expect_error([&] { (void)v.as_number(); }, lines);
    if (j.type() != T::object) expect_error([&] { (void)v.at("k"); }, lines);
    if (j.type() != T::array) expect_error([&] { (void)v.at(0); }, lines);
    switch (j.type()) {
      case T::null:
        expect_error([&] { (void)v.as_bool(); }, lines);
        break;
      case T::boolean:
        (void)v.as_bool();
        break;
      case T::number: {
        const double x = v.as_number();
        check(x - x == 0, "parsed number is not finite");
        expect_error([&] { (void)v.as_string(); }, lines);
        // Integer and float reads may refuse the value, never misbehave.
        try { (void)v.get<int>(); } catch (const nlid::Error&) {}
        try { (void)v.get<std::uint8_t>(); } catch (const nlid::Error&) {}
        try { (void)v.get<float>(); } catch (const nlid::Error&) {}
        break;
      }
      case T::string: {
        const std::string& s = v.as_string();
        check(nlid::first_invalid_utf8(s) == std::string::npos, "parsed string not UTF-8");
        // Error messages preview a string as JSON text of its start (cut past 40 bytes, then
        // "..."): it must read back as a prefix of the string.
        std::string shown = nlid::detail::json_preview(j).substr(7);  // after "string "
        if (s.size() > 40) shown.erase(shown.size() - 4, 3);
        const std::string prefix = nlid::Json::parse(shown).as_string();
        check(s.starts_with(prefix) && (s.size() > 40 ? prefix.size() + 3 >= 40 : prefix == s),
              "string preview is not the start of the string");
        break;
      }
      case T::array:
        expect_error([&] { (void)v.at(v.size()); }, lines);
        read_as_matrices(v, lines);
        for (std::size_t i = 0; i < v.size(); ++i) todo.push_back(v[i]);
        break;
      case T::object: {
        const std::vector<std::string> keys = v.keys();
        check(keys.size() == v.size(), "keys() size");
        if (!keys.empty()) expect_error([&] { v.check_keys({}); }, lines);
        if (!v.contains("")) expect_error([&] { (void)v.at(""); }, lines);
        for (const std::string& k : keys) {
          check(v.contains(k) && j.find(k) == &v.at(k).json(), "find/at disagree on a key");
          try { (void)v.value_or<double>(k, 0.0); } catch (const nlid::Error&) {}
          todo.push_back(v.at(k));
        }
        break;
      }
    }
  }
}

// The first element or member of a non-empty array or object.
template <class J>
J& first_child(J& j) {
  return j.is_array() ? j.as_array().front() : j.as_object().front().second;
}

// dump must read back to an equal value whose dump is the same text, in both layouts.
void check_round_trip(const nlid::Json& x, int indent) {
  const std::string text = x.dump(indent);
  const nlid::Json back = nlid::Json::parse(text, "dumped");
  check(back == x && x == back, "parse(dump(x)) != x");
  check(back.dump(indent) == text, "dump(parse(dump(x))) != dump(x)");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  const Lines lines(text);
  nlid::Json x;
  try {
    x = nlid::Json::parse(text, "fuzz.json");
  } catch (const nlid::Error& e) {
    check(e.where().file == "fuzz.json", "parse error lost the source name");
    check(lines.inside(e.where().row, e.where().column), "parse error position outside the text");
    return 0;
  }
  check(x == x, "x != x");
  check_round_trip(x, -1);
  check_round_trip(x, 2);
  check_round_trip(x, 0);
  const nlid::Json copy = x;
  check(copy == x && copy.dump(-1) == x.dump(-1), "copy differs from the original");
  walk(x, lines);
  // A value replaced by one of its own members (j = std::move(j["a"]), j = j[0]): the member
  // lives inside the value being replaced, so it must be taken before the old value goes.
  if (x.size() > 0) {
    nlid::Json moved = x, copied = x;
    moved = std::move(first_child(moved));
    copied = first_child(copied);
    check(moved == first_child(x) && copied == first_child(x), "assigning a member over its parent");
  }

  // Depth: wrap the value in arrays until its deepest value sits at the limit (it must still
  // round trip), then once more (dump must refuse it with nlid::Error); copy, == and the
  // destructors meet the full depth too.
  int depth = 0;
  std::vector<std::pair<const nlid::Json*, int>> nodes{{&x, 0}};
  while (!nodes.empty()) {
    const auto [p, d] = nodes.back();
    nodes.pop_back();
    depth = std::max(depth, d);
    if (p->is_array()) for (const nlid::Json& e : p->as_array()) nodes.emplace_back(&e, d + 1);
    if (p->is_object()) for (const auto& m : p->as_object()) nodes.emplace_back(&m.second, d + 1);
  }
  nlid::Json deep = x;
  for (int d = depth; d < nlid::detail::json_max_depth; ++d) {
    nlid::Json::Array wrap;
    wrap.push_back(std::move(deep));
    deep = nlid::Json(std::move(wrap));
  }
  check_round_trip(deep, -1);
  const nlid::Json too_deep = nlid::Json::array({deep});
  check(nlid::Json(too_deep) == too_deep, "deep copy or compare");
  try {
    (void)too_deep.dump(-1);
  } catch (const nlid::Error&) {
    return 0;
  }
  check(false, "dump wrote a value nested deeper than parse reads");
  return 0;
}
