#pragma once
/// @file
/// `nlid::Json`: a small JSON value that nlid uses for model files, run summaries and reports.
///
/// Data model (RFC 8259 / ECMA-404). A JSON value is one of
///
///     null | true | false | number | "string" | [ value, ... ] | { "key": value, ... }
///
/// * Numbers are IEEE-754 doubles. `dump()` prints the *shortest* decimal string that reads back
///   to the same bits (Steele & White 1990, "How to print floating-point numbers accurately";
///   C++17 `std::to_chars`), so `parse(dump(x)) == x` bit for bit, -0 included. Integral values
///   with |x| < 2^53 print as plain integers ("42", never "42.0" or "4.2e1").
/// * NaN and ±Inf have no JSON spelling. Writing one is an `nlid::Error` that names the key
///   path ("cannot write non-finite number (nan) at fit.theta[3]"), never the invalid token `NaN`.
/// * Objects keep their keys in insertion order, so a file written by nlid reads like the code
///   that built it, and diffs of two model files line up. Keys are unique.
/// * Strings are UTF-8. `parse` decodes `\uXXXX` escapes, including UTF-16 surrogate pairs
///   (`\ud83d\ude00` -> U+1F600), and rejects lone surrogates and malformed UTF-8.
///
/// Building (writer side):
///
///     nlid::Json j;                        // null; becomes an object on first operator[]
///     j["name"] = "nlarx5";
///     j["orders"] = std::vector<double>{3, 3, 0};
///     j["fit"]["data3"] = 93.1;            // nested objects are created on demand
///     j["log"].push_back("converged");     // null becomes an array on first push_back
///     nlid::write_json("model.json", j);   // atomic: temp file + rename
///
/// Reading (reader side). `at()` returns a `JsonView` that remembers the key path by which it was
/// reached, so a wrong type or a missing key is reported where it is:
///
///     const nlid::Json j = nlid::read_json("model.json");
///     double s = j.at("models").at("nlarx5").at("seconds").as_number();
///     //  nlid: expected number at models.nlarx5.seconds, found string "fast"
///     //        [at file 'model.json', row 12, column 18]
///
/// Parse errors carry the file (the `source_name` argument), line and column (1-based; columns
/// count Unicode code points, as an editor shows them), e.g. for `[1, 2,]`:
/// "trailing comma is not allowed in JSON [at file 'x.json', row 1, column 7]".
///
/// Other types take part through `nlid::JsonTraits<T>` (the customisation point: `to_json` and
/// `from_json`); `std::vector<T>` is provided here, Eigen vectors and matrices in
/// `nlid/io/json_eigen.hpp` (kept apart so this header does not pull in Eigen).
///
/// References: T. Bray (ed.), RFC 8259, "The JavaScript Object Notation (JSON) Data Interchange
/// Format", 2017, sections 2–8 (grammar: section 2 values, 6 numbers, 7 strings, 8.2 Unicode);
/// The Unicode Standard, section 3.9 (UTF-8 well-formedness, table 3-7).

#include <algorithm>
#include <charconv>
#include <cmath>
#include <concepts>
#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <limits>
#include <list>
#include <memory>
#include <string>
#include <string_view>
#include <system_error>
#include <type_traits>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <variant>
#include <vector>

#include "nlid/core/atomic_file.hpp"
#include "nlid/core/error.hpp"
#include "nlid/core/utf8.hpp"

namespace nlid {

class Json;
class JsonView;

/// Customisation point: specialise with `static Json to_json(const T&)` and/or
/// `static T from_json(const JsonView&)` to make `Json(value)` and `view.get<T>()` work for T.
/// `from_json` should report problems through `view.fail(...)` so errors name the key path.
template <class T>
struct JsonTraits;

/// A type that can be turned into a `Json` through `JsonTraits<T>::to_json`.
/// Satisfied by `std::vector<T>` of JSON-constructible T and, with `nlid/io/json_eigen.hpp`,
/// by `Eigen::Matrix`/`Eigen::Array` of double or float.
template <class T>
concept JsonConvertible = requires(const T& value) {
  { JsonTraits<T>::to_json(value) } -> std::same_as<Json>;
};

/// A type that can be read from a `JsonView` through `JsonTraits<T>::from_json`.
/// Satisfied by `std::vector<T>` of readable T and, with `nlid/io/json_eigen.hpp`, by
/// `Eigen::Matrix`/`Eigen::Array` of double or float.
template <class T>
concept JsonReadable = requires(const JsonView& view) {
  { JsonTraits<T>::from_json(view) } -> std::same_as<T>;
};

namespace detail {
/// Integers that become JSON numbers (bool and the character types are excluded on purpose:
/// `Json('a')` or `Json(true)` must not silently become a number).
template <class T>
concept JsonInteger = std::integral<T> && !std::same_as<T, bool> && !std::same_as<T, char> &&
                      !std::same_as<T, wchar_t> && !std::same_as<T, char8_t> &&
                      !std::same_as<T, char16_t> && !std::same_as<T, char32_t>;
inline std::string json_preview(const Json& value);
class JsonParser;
/// A key given as a C string. Turning a null `const char*` into a `std::string_view` is
/// undefined behaviour (it reads the pointee for the length), so it is refused here first.
inline std::string_view json_key(const char* key, const char* where) {
  if (key == nullptr)
    throw Error(std::string(where) + " got a null const char* as the key; a key must be a string");
  return key;
}
/// Deepest nesting `parse` reads and `dump` writes: the root is level 0, and a value at level
/// 513 is refused. It bounds the parser's and the writer's recursion; refusing to write what could
/// not be read back keeps `parse(dump(x)) == x` true for every `x` that `dump` accepts.
inline constexpr int json_max_depth = 512;
}  // namespace detail

/// One JSON value: null, boolean, number (double), string, array or object (ordered keys).
///
/// Invariants: numbers held are always finite when they came from `parse`; objects never hold
/// two members with the same key. Values built in code may hold NaN; `dump()` refuses them.
///
/// Depth. A tree built in code may nest arbitrarily deep (a loop wrapping one array in another a
/// million times). Copying, comparing and destroying it work on an explicit stack instead of
/// recursing, so they cannot overflow the call stack; `dump()` refuses nesting deeper than
/// `parse` reads (512 levels) with an `nlid::Error`.
class Json {
 public:
  /// The six JSON types.
  enum class Type { null, boolean, number, string, array, object };
  /// Array storage.
  using Array = std::vector<Json>;
  /// One object member.
  using Member = std::pair<std::string, Json>;
  /// Object storage: members in insertion order. A list, not a vector, so that adding a member
  /// never moves the others: `j["new"] = j["a"]` evaluates `j["a"]` first, and a vector's
  /// reallocation for "new" left that reference dangling. (Model-file objects have a few
  /// members; their arrays of numbers, where contiguity counts, are `Array`s.)
  using Object = std::list<Member>;

  /// `null`.
  Json() noexcept = default;
  /// A deep copy; iterative, so any depth is safe (see "Depth" above).
  Json(const Json& other);
  /// Takes `other`'s value (an array or object is left empty, a string valid but unspecified).
  Json(Json&& other) noexcept = default;
  /// A deep copy of `other` (iterative).
  Json& operator=(const Json& other) {
    if (this != &other) *this = Json(other);
    return *this;
  }
  /// Takes `other`'s value; the old value is destroyed as by `~Json`. `other` may be part of the
  /// old value (`j = std::move(j["data"])` unwraps a member): it is moved out first, and the old
  /// value destroyed last. (The defaulted assignment destroyed the old value, and `other` with
  /// it, before reading `other`.)
  Json& operator=(Json&& other) noexcept {
    Json taken(std::move(other));
    value_.swap(taken.value_);
    std::swap(line_, taken.line_);
    std::swap(column_, taken.column_);
    source_.swap(taken.source_);
    return *this;  // `taken` holds the old value now, and destroys it
  }
  /// Dismantles nested arrays and objects on an explicit stack, so destroying a tree of any depth
  /// does not recurse through it (see "Depth" above).
  ~Json() {
    if (has_nested_containers()) dismantle();
  }
  /// `null`.
  Json(std::nullptr_t) noexcept {}  // NOLINT(google-explicit-constructor): JSON literal syntax
  /// `true` / `false`. (Taking `bool` exactly keeps pointers from decaying into booleans.)
  template <std::same_as<bool> B>
  Json(B b) : value_(b) {}  // NOLINT(google-explicit-constructor)
  /// A number from float or double (float widens exactly; long double is not accepted because
  /// narrowing it could change the value).
  template <class F>
  requires std::same_as<F, double> || std::same_as<F, float> Json(F x)
      : value_(static_cast<double>(x)) {}  // NOLINT(google-explicit-constructor)
  /// A number from an integer. Throws `nlid::Error` if |i| > 2^53, where a double could no
  /// longer hold it exactly (the value would change silently on the way through the file).
  template <detail::JsonInteger I>
  Json(I i) : value_(integer_to_double(i)) {}  // NOLINT(google-explicit-constructor)
  /// A string (UTF-8). A null pointer is not a string: it throws `nlid::Error` (write `nullptr`
  /// or `Json()` for JSON null).
  Json(const char* s) : value_(string_from(s)) {}  // NOLINT(google-explicit-constructor)
  /// A string (UTF-8).
  Json(std::string s) : value_(std::move(s)) {}  // NOLINT(google-explicit-constructor)
  /// A string (UTF-8).
  Json(std::string_view s) : value_(std::string(s)) {}  // NOLINT(google-explicit-constructor)
  /// An array.
  Json(Array a) : value_(std::move(a)) {}  // NOLINT(google-explicit-constructor)
  /// Any type with a `JsonTraits<T>::to_json` (std::vector<double>, Eigen vectors, ...).
  template <JsonConvertible T>
  Json(const T& value) : Json(JsonTraits<T>::to_json(value)) {}  // NOLINT

  /// An array from a brace list: `Json::array({1, "two", nullptr})`.
  static Json array(std::initializer_list<Json> items = {}) { return Json(Array(items)); }
  /// An object from a brace list: `Json::object({{"a", 1}, {"b", true}})`. Throws on a
  /// duplicate key.
  static Json object(std::initializer_list<Member> members = {}) {
    Json j;
    j.value_ = Object{};
    for (const Member& m : members) {
      if (j.find(m.first) != nullptr)
        throw Error("duplicate key '" + m.first + "' in Json::object");
      std::get<Object>(j.value_).push_back(m);
    }
    return j;
  }

  /// Parses JSON text (RFC 8259, no extensions: no comments, no trailing commas, no NaN).
  /// `source_name` names the text in error messages (usually the file path). Throws
  /// `nlid::Error` with `Location{file = source_name, row = line, column}` on malformed input.
  static Json parse(std::string_view text, const std::string& source_name = "<string>");

  /// Serialises. `indent < 0`: one line, no spaces. `indent >= 0`: one member per line, nested
  /// levels indented by `indent` spaces; arrays whose elements are all scalars stay on one
  /// line (wrapped near 100 columns), so a vector of 10^4 parameters does not become 10^4
  /// lines. Throws `nlid::Error` naming the key path for NaN/Inf or a string that is not UTF-8.
  [[nodiscard]] std::string dump(int indent = 2) const;

  /// The type of this value.
  [[nodiscard]] Type type() const noexcept { return static_cast<Type>(value_.index()); }
  /// "null", "boolean", "number", "string", "array" or "object".
  [[nodiscard]] static const char* type_name(Type t) noexcept {
    constexpr const char* names[] = {"null", "boolean", "number", "string", "array", "object"};
    return names[static_cast<int>(t)];
  }
  /// Type tests.
  [[nodiscard]] bool is_null() const noexcept { return type() == Type::null; }
  /// @copydoc is_null
  [[nodiscard]] bool is_bool() const noexcept { return type() == Type::boolean; }
  /// @copydoc is_null
  [[nodiscard]] bool is_number() const noexcept { return type() == Type::number; }
  /// @copydoc is_null
  [[nodiscard]] bool is_string() const noexcept { return type() == Type::string; }
  /// @copydoc is_null
  [[nodiscard]] bool is_array() const noexcept { return type() == Type::array; }
  /// @copydoc is_null
  [[nodiscard]] bool is_object() const noexcept { return type() == Type::object; }

  // ---- building -------------------------------------------------------------------------

  /// Object member by key, inserted as null if missing. A null value first becomes an empty
  /// object, so `j["a"]["b"] = 1` builds nested objects. Throws if this is another type.
  /// Inserting a member moves no other member, so `j["new"] = j["a"]` is safe (see `Object`).
  Json& operator[](std::string_view key) {
    if (is_null()) value_ = Object{};
    if (!is_object()) {
      throw Error("cannot set key '" + std::string(key) + "' on a JSON " + type_name(type()) +
                  " (only objects have keys)");
    }
    auto& members = std::get<Object>(value_);
    for (Member& m : members) {
      if (m.first == key) return m.second;
    }
    members.emplace_back(std::string(key), Json());
    return members.back().second;
  }
  /// Member access with a C-string key: the same, but a null pointer throws `nlid::Error`.
  /// (A template, so that `j[0]` still takes the index overload below.)
  template <std::same_as<char> C>
  Json& operator[](const C* key) {
    return (*this)[detail::json_key(key, "Json::operator[]")];
  }
  /// Array element `index` for modification. Throws if this is not an array or the index is out
  /// of range (arrays grow only through `push_back`, so a typo cannot create 10^6 nulls).
  /// Also keeps `j[0]` from converting 0 to a null `const char*` key.
  Json& operator[](std::size_t index) {
    if (!is_array()) {
      throw Error("cannot index a JSON " + std::string(type_name(type())) + " with [" +
                  std::to_string(index) + "] (only arrays have elements)");
    }
    auto& items = std::get<Array>(value_);
    if (index >= items.size()) {
      throw Error("index " + std::to_string(index) + " out of range (array has " +
                  std::to_string(items.size()) + " elements)");
    }
    return items[index];
  }
  /// Read-only member access on a const value: same as `at(key)` (throws if missing).
  [[nodiscard]] JsonView operator[](std::string_view key) const;
  /// @copydoc operator[](std::string_view) const
  /// A null pointer throws `nlid::Error`.
  template <std::same_as<char> C>
  [[nodiscard]] JsonView operator[](const C* key) const;
  /// Read-only element access on a const value: same as `at(index)`.
  [[nodiscard]] JsonView operator[](std::size_t index) const;
  /// Appends to an array (a null value first becomes an empty array). Returns the new element.
  Json& push_back(Json item) {
    if (is_null()) value_ = Array{};
    if (!is_array()) {
      throw Error(std::string("cannot push_back onto a JSON ") + type_name(type()) +
                  " (only arrays have elements)");
    }
    auto& items = std::get<Array>(value_);
    items.push_back(std::move(item));
    return items.back();
  }
  /// Removes a member; returns whether it was there.
  bool erase(std::string_view key) {
    if (!is_object()) return false;
    auto& members = std::get<Object>(value_);
    for (auto it = members.begin(); it != members.end(); ++it) {
      if (it->first == key) {
        members.erase(it);
        return true;
      }
    }
    return false;
  }
  /// `erase(key)` with a C-string key; a null pointer names no member (false).
  template <std::same_as<char> C>
  bool erase(const C* key) {
    return key != nullptr && erase(std::string_view(key));
  }

  // ---- reading --------------------------------------------------------------------------

  /// A path-aware read-only view of this value as a document root.
  [[nodiscard]] JsonView view() const;
  /// Member `key` of this object, as a view that names its path in errors. Throws if this is
  /// not an object or the key is missing.
  [[nodiscard]] JsonView at(std::string_view key) const;
  /// @copydoc at(std::string_view) const
  /// A null pointer throws `nlid::Error`.
  template <std::same_as<char> C>
  [[nodiscard]] JsonView at(const C* key) const;
  /// Element `index` of this array (throws if not an array or out of range).
  [[nodiscard]] JsonView at(std::size_t index) const;
  /// Pointer to member `key`, or null if absent or this is not an object. Never throws.
  [[nodiscard]] const Json* find(std::string_view key) const noexcept {
    if (!is_object()) return nullptr;
    for (const Member& m : std::get<Object>(value_)) {
      if (m.first == key) return &m.second;
    }
    return nullptr;
  }
  /// `find(key)` with a C-string key: a null pointer names no member (null), so these calls
  /// that never throw stay defined for it.
  template <std::same_as<char> C>
  [[nodiscard]] const Json* find(const C* key) const noexcept {
    return key == nullptr ? nullptr : find(std::string_view(key));
  }
  /// True if this is an object with member `key`.
  [[nodiscard]] bool contains(std::string_view key) const noexcept { return find(key) != nullptr; }
  /// `contains(key)` with a C-string key (false for a null pointer).
  template <std::same_as<char> C>
  [[nodiscard]] bool contains(const C* key) const noexcept {
    return find(key) != nullptr;
  }
  /// Number of elements (array) or members (object); 0 for scalars.
  [[nodiscard]] std::size_t size() const noexcept {
    if (is_array()) return std::get<Array>(value_).size();
    if (is_object()) return std::get<Object>(value_).size();
    return 0;
  }

  /// Typed access; each throws `nlid::Error` ("expected number at top level, found string ...")
  /// on the wrong type. Use `at()` chains to get the key path into the message.
  [[nodiscard]] double as_number() const;
  /// The number as an exact integer (throws if it has a fractional part or does not fit).
  [[nodiscard]] long long as_integer() const;
  /// @copydoc as_number
  [[nodiscard]] bool as_bool() const;
  /// @copydoc as_number
  [[nodiscard]] const std::string& as_string() const;
  /// @copydoc as_number
  [[nodiscard]] const Array& as_array() const;
  /// @copydoc as_number
  [[nodiscard]] const Object& as_object() const;
  /// Mutable array (a null value becomes an empty array first).
  Array& as_array() {
    if (is_null()) value_ = Array{};
    if (!is_array()) (void)static_cast<const Json&>(*this).as_array();  // throws: wrong type
    return std::get<Array>(value_);
  }
  /// Mutable object (a null value becomes an empty object first). Editing the list directly
  /// can create duplicate keys; prefer `operator[]`.
  Object& as_object() {
    if (is_null()) value_ = Object{};
    if (!is_object()) (void)static_cast<const Json&>(*this).as_object();  // throws: wrong type
    return std::get<Object>(value_);
  }
  /// Converts to T: double, float, integers, bool, std::string, or any `JsonReadable` type.
  template <class T>
  [[nodiscard]] T get() const;

  /// Where this value started in the parsed text (1-based), 0 if it was built in code.
  [[nodiscard]] long line() const noexcept { return static_cast<long>(line_); }
  /// @copydoc line
  [[nodiscard]] long column() const noexcept { return static_cast<long>(column_); }
  /// The `source_name` given to `parse`, empty if built in code.
  [[nodiscard]] const std::string& source() const noexcept {
    static const std::string empty;
    return source_ ? *source_ : empty;
  }

  /// Structural equality. Objects compare as unordered sets of members (JSON semantics);
  /// numbers compare with `==` (so -0 == 0; compare bits yourself if that matters).
  /// Source positions are ignored. Iterative, so any depth is safe (see "Depth" above).
  friend bool operator==(const Json& a, const Json& b) { return equal(a, b); }

 private:
  friend class JsonView;
  friend class detail::JsonParser;

  static std::string string_from(const char* s) {
    if (s == nullptr) {
      throw Error(
          "Json(const char*) got a null pointer, which is not a string (write nullptr or Json() for "
          "JSON null)");
    }
    return std::string(s);
  }
  static bool equal(const Json& a, const Json& b);
  /// Copies a scalar's value, or gives a container as many null children as `from` has and
  /// queues their copies on `pending` (scalar children are copied at once).
  static void copy_node(Json& to, const Json& from, std::vector<std::pair<Json*, const Json*>>& pending);
  /// Whether a child is a non-empty array or object (then destruction would recurse).
  bool has_nested_containers() const noexcept;
  void dismantle() noexcept;

  template <class I>
  static double integer_to_double(I i) {
    constexpr long long limit = 1LL << 53;  // every integer up to 2^53 is exact in a double
    bool exact = true;
    if constexpr (std::is_signed_v<I>) {
      exact = static_cast<long long>(i) >= -limit && static_cast<long long>(i) <= limit;
    } else {
      exact = static_cast<unsigned long long>(i) <= static_cast<unsigned long long>(limit);
    }
    if (!exact) {
      throw Error("integer " + std::to_string(i) +
                  " cannot be stored exactly in a JSON number (a double holds integers exactly "
                  "only up to 2^53); store it as a string");
    }
    return static_cast<double>(i);
  }

  std::variant<std::nullptr_t, bool, double, std::string, Array, Object> value_;
  std::uint32_t line_ = 0;
  std::uint32_t column_ = 0;
  std::shared_ptr<const std::string> source_;  // shared by every node of one parse
};

/// A read-only view of a value inside a JSON document that remembers the key path by which it
/// was reached ("models.nlarx5.theta[3]"). Accessors throw `nlid::Error` whose message names
/// that path and whose `Location` gives the file, line and column of the value when it was
/// parsed. The viewed `Json` must outlive the view (as with `std::string_view`).
class JsonView {
 public:
  /// A view of `node` reached by `path` ("" = the document root).
  explicit JsonView(const Json& node, std::string path = {})
      : node_(&node), path_(std::move(path)) {}

  /// The viewed value.
  [[nodiscard]] const Json& json() const noexcept { return *node_; }
  /// Implicit access to the viewed value (e.g. to compare or dump it).
  operator const Json&() const noexcept { return *node_; }  // NOLINT(google-explicit-constructor)
  /// The key path, e.g. "models.nlarx5.seconds" or "runs[2].fit"; "" for the root.
  [[nodiscard]] const std::string& path() const noexcept { return path_; }
  /// The path as messages print it ("top level" for the root).
  [[nodiscard]] std::string path_text() const { return path_.empty() ? "top level" : path_; }
  /// The type of the viewed value.
  [[nodiscard]] Json::Type type() const noexcept { return node_->type(); }

  /// Member `key` (throws if not an object, or "missing key 'k' at <path>").
  [[nodiscard]] JsonView at(std::string_view key) const {
    require_type(Json::Type::object);
    const Json* child = node_->find(key);
    if (child == nullptr) fail("missing key '" + std::string(key) + "' at " + path_text());
    return JsonView(*child, child_path(key));
  }
  /// Element `index` (throws if not an array or out of range).
  [[nodiscard]] JsonView at(std::size_t index) const {
    require_type(Json::Type::array);
    const auto& items = std::get<Json::Array>(node_->value_);
    if (index >= items.size()) {
      fail("index " + std::to_string(index) + " out of range at " + path_text() + " (array has " +
           std::to_string(items.size()) + " elements)");
    }
    return JsonView(items[index], path_ + "[" + std::to_string(index) + "]");
  }
  /// `at(key)` with a C-string key; a null pointer throws `nlid::Error` naming the path.
  template <std::same_as<char> C>
  [[nodiscard]] JsonView at(const C* key) const {
    if (key == nullptr) fail("a null const char* is not a key (at " + path_text() + ")");
    return at(std::string_view(key));
  }
  /// Same as `at(key)`.
  [[nodiscard]] JsonView operator[](std::string_view key) const { return at(key); }
  /// Same as `at(key)` (a null pointer throws).
  template <std::same_as<char> C>
  [[nodiscard]] JsonView operator[](const C* key) const {
    return at(key);
  }
  /// Same as `at(index)`.
  [[nodiscard]] JsonView operator[](std::size_t index) const { return at(index); }
  /// True if this is an object with member `key`.
  [[nodiscard]] bool contains(std::string_view key) const noexcept { return node_->contains(key); }
  /// `contains(key)` with a C-string key (false for a null pointer).
  template <std::same_as<char> C>
  [[nodiscard]] bool contains(const C* key) const noexcept {
    return node_->contains(key);
  }
  /// Elements or members; 0 for scalars.
  [[nodiscard]] std::size_t size() const noexcept { return node_->size(); }
  /// Keys of this object in order (throws if not an object).
  [[nodiscard]] std::vector<std::string> keys() const {
    std::vector<std::string> k;
    for (const Json::Member& m : as_object()) k.push_back(m.first);
    return k;
  }

  /// The number (throws "expected number at <path>, found <type> <preview>").
  [[nodiscard]] double as_number() const {
    require_type(Json::Type::number);
    return std::get<double>(node_->value_);
  }
  /// The number as an exact integer: throws if it has a fraction or exceeds ±2^53.
  [[nodiscard]] long long as_integer() const {
    const double x = as_number();
    if (!(std::abs(x) <= 9007199254740992.0) || std::floor(x) != x) {
      fail("expected integer at " + path_text() + ", found " + detail::json_preview(*node_));
    }
    return static_cast<long long>(x);
  }
  /// The boolean.
  [[nodiscard]] bool as_bool() const {
    require_type(Json::Type::boolean);
    return std::get<bool>(node_->value_);
  }
  /// The string.
  [[nodiscard]] const std::string& as_string() const {
    require_type(Json::Type::string);
    return std::get<std::string>(node_->value_);
  }
  /// The array elements.
  [[nodiscard]] const Json::Array& as_array() const {
    require_type(Json::Type::array);
    return std::get<Json::Array>(node_->value_);
  }
  /// The object members, in order.
  [[nodiscard]] const Json::Object& as_object() const {
    require_type(Json::Type::object);
    return std::get<Json::Object>(node_->value_);
  }

  /// Converts to T: double, float (range-checked), integers (exact and range-checked), bool,
  /// std::string, or any `JsonReadable` type (vectors, Eigen types with json_eigen.hpp).
  template <class T>
  [[nodiscard]] T get() const {
    if constexpr (std::same_as<T, double>) {
      return as_number();
    } else if constexpr (std::same_as<T, float>) {
      const double x = as_number();
      if (std::abs(x) > static_cast<double>(std::numeric_limits<float>::max())) {
        fail("number " + detail::json_preview(*node_) + " at " + path_text() +
             " is out of range for float");
      }
      return static_cast<float>(x);
    } else if constexpr (std::same_as<T, bool>) {
      return as_bool();
    } else if constexpr (detail::JsonInteger<T>) {
      const long long i = as_integer();
      if (!std::in_range<T>(i)) {
        fail("integer " + std::to_string(i) + " at " + path_text() +
             " is out of range for the requested integer type");
      }
      return static_cast<T>(i);
    } else if constexpr (std::same_as<T, std::string>) {
      return as_string();
    } else if constexpr (std::same_as<T, Json>) {
      return *node_;
    } else {
      static_assert(JsonReadable<T>, "no JsonTraits<T>::from_json for this type");
      return JsonTraits<T>::from_json(*this);
    }
  }
  /// Member `key` converted to T, or `fallback` if the key is absent or null. A member that is
  /// present with the wrong type is an error, never silently replaced by the fallback.
  template <class T>
  [[nodiscard]] T value_or(std::string_view key, T fallback) const {
    require_type(Json::Type::object);
    const Json* child = node_->find(key);
    if (child == nullptr || child->is_null()) return fallback;
    return JsonView(*child, child_path(key)).get<T>();
  }
  /// `value_or(key, fallback)` with a C-string key; a null pointer is refused with an
  /// `nlid::Error` naming the path (a fallback would hide the caller's bug).
  template <class T, std::same_as<char> C>
  [[nodiscard]] T value_or(const C* key, T fallback) const {
    if (key == nullptr) fail("a null const char* is not a key (value_or at " + path_text() + ")");
    return value_or(std::string_view(key), std::move(fallback));
  }
  /// Throws if this object has a key outside `allowed` (catches typos in hand-edited files:
  /// "unknown key 'iteratons' at options (allowed: max_iterations, tolerance)").
  void check_keys(std::initializer_list<std::string_view> allowed) const {
    for (const Json::Member& m : as_object()) {
      bool ok = false;
      for (std::string_view a : allowed) ok = ok || (a == m.first);
      if (!ok) {
        std::string list;
        for (std::string_view a : allowed) {
          if (!list.empty()) list.append(", ");
          list.append(a);
        }
        JsonView(m.second, child_path(m.first))
            .fail("unknown key '" + m.first + "' at " + path_text() + " (allowed: " + list + ")");
      }
    }
  }

  /// Throws `nlid::Error(message)` located at this value (file, line, column when parsed).
  /// For validation by callers: `if (n < 1) v.at("order").fail("order must be >= 1 at ...")`.
  [[noreturn]] void fail(const std::string& message) const {
    Location where;
    where.file = node_->source();
    if (node_->line_ > 0) {
      where.row = node_->line();
      where.column = node_->column();
    }
    throw Error(message, std::move(where));
  }

 private:
  void require_type(Json::Type t) const {
    if (node_->type() != t) {
      fail(std::string("expected ") + Json::type_name(t) + " at " + path_text() + ", found " +
           detail::json_preview(*node_));
    }
  }
  // Identifier-like keys read as "a.b"; anything else as a["odd key"], so a path is unambiguous.
  std::string child_path(std::string_view key) const {
    bool plain = !key.empty();
    for (char c : key) {
      const bool word = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') ||
                        (c >= '0' && c <= '9') || c == '_' || c == '-';
      plain = plain && word;
    }
    std::string p = path_;
    if (plain) {
      if (!p.empty()) p.push_back('.');
      p.append(key);
    } else {
      p.append("[\"").append(key).append("\"]");
    }
    return p;
  }

  const Json* node_;
  std::string path_;
};

/// Writes `json.dump(indent)` plus a final newline to `path` atomically (temp file + rename).
inline void write_json(const std::string& path, const Json& json, int indent = 2) {
  std::string text = json.dump(indent);
  text.push_back('\n');
  write_file_atomically(path, text);
}

/// Reads and parses a JSON file; errors name the file, line and column.
[[nodiscard]] inline Json read_json(const std::string& path) {
  return Json::parse(read_file(path), path);
}

/// `std::vector<T>` <-> JSON array.
template <class T>
struct JsonTraits<std::vector<T>> {
  /// Each element through `Json(T)`.
  static Json to_json(const std::vector<T>& v) requires std::constructible_from<Json, const T&> {
    Json::Array a;
    a.reserve(v.size());
    for (const T& x : v) a.emplace_back(x);
    return Json(std::move(a));
  }
  /// Each element through `get<T>()`; errors name the element ("theta[3]").
  static std::vector<T> from_json(const JsonView& view) {
    std::vector<T> v;
    v.reserve(view.as_array().size());
    for (std::size_t i = 0; i < view.size(); ++i) v.push_back(view.at(i).template get<T>());
    return v;
  }
};

// ==== Implementation details below ============================================================

namespace detail {

/// Appends code point `cp` (<= 0x10FFFF, not a surrogate) as UTF-8.
inline void append_utf8(std::string& out, std::uint32_t cp) {
  if (cp < 0x80) {
    out.push_back(static_cast<char>(cp));
  } else if (cp < 0x800) {
    out.push_back(static_cast<char>(0xC0 | (cp >> 6)));
    out.push_back(static_cast<char>(0x80 | (cp & 0x3F)));
  } else if (cp < 0x10000) {
    out.push_back(static_cast<char>(0xE0 | (cp >> 12)));
    out.push_back(static_cast<char>(0x80 | ((cp >> 6) & 0x3F)));
    out.push_back(static_cast<char>(0x80 | (cp & 0x3F)));
  } else {
    out.push_back(static_cast<char>(0xF0 | (cp >> 18)));
    out.push_back(static_cast<char>(0x80 | ((cp >> 12) & 0x3F)));
    out.push_back(static_cast<char>(0x80 | ((cp >> 6) & 0x3F)));
    out.push_back(static_cast<char>(0x80 | (cp & 0x3F)));
  }
}

/// Shortest round-trip text of a finite double; integral values below 2^53 without exponent.
inline void append_json_number(std::string& out, double x) {
  char buf[64];
  std::to_chars_result r{};
  if (x == 0.0) {
    out.append(std::signbit(x) ? "-0" : "0");
    return;
  }
  if (std::floor(x) == x && std::abs(x) < 9007199254740992.0) {
    r = std::to_chars(buf, buf + sizeof buf, static_cast<long long>(x));
  } else {
    r = std::to_chars(buf, buf + sizeof buf, x);  // shortest repr that reads back exactly
  }
  out.append(buf, r.ptr);
}

/// Appends `s` as a quoted JSON string. Returns the byte offset of the first invalid UTF-8
/// byte, or npos if the string is well-formed (then the output is complete).
inline std::size_t append_json_string(std::string& out, std::string_view s) {
  out.push_back('"');
  std::size_t i = 0;
  while (i < s.size()) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    if (c >= 0x80) {
      const std::size_t n = utf8_sequence_length(s, i);
      if (n == 0) return i;
      out.append(s.substr(i, n));
      i += n;
      continue;
    }
    switch (c) {
      case '"':
        out.append("\\\"");
        break;
      case '\\':
        out.append("\\\\");
        break;
      case '\n':
        out.append("\\n");
        break;
      case '\r':
        out.append("\\r");
        break;
      case '\t':
        out.append("\\t");
        break;
      case '\b':
        out.append("\\b");
        break;
      case '\f':
        out.append("\\f");
        break;
      default:
        if (c < 0x20 || c == 0x7F) {
          constexpr char hex[] = "0123456789abcdef";
          out.append("\\u00");
          out.push_back(hex[c >> 4]);
          out.push_back(hex[c & 0xF]);
        } else {
          out.push_back(static_cast<char>(c));
        }
    }
    ++i;
  }
  out.push_back('"');
  return std::string_view::npos;
}

/// Short text of a value for error messages: `string "fast"`, `number 2.5`, `array of 3`.
inline std::string json_preview(const Json& value) {
  std::string s = Json::type_name(value.type());
  switch (value.type()) {
    case Json::Type::null:
      break;
    case Json::Type::boolean:
      s.append(value.as_bool() ? " true" : " false");
      break;
    case Json::Type::number: {
      const double x = value.as_number();
      s.push_back(' ');
      if (std::isfinite(x)) {
        append_json_number(s, x);
      } else {
        s.append(std::isnan(x) ? "nan" : (x > 0 ? "inf" : "-inf"));
      }
      break;
    }
    case Json::Type::string: {
      std::string_view t = value.as_string();
      const bool cut = t.size() > 40;
      // Cut at a character boundary: cutting inside a multi-byte character would make a valid
      // string look malformed below. (Steps back at most 3 bytes, even in malformed text.)
      std::size_t keep = 40;
      for (int k = 0; cut && k < 3 && (static_cast<unsigned char>(t[keep]) & 0xC0) == 0x80; ++k) --keep;
      std::string q;
      if (append_json_string(q, cut ? t.substr(0, keep) : t) != std::string_view::npos) {
        q = "\"<not UTF-8>\"";
      }
      if (cut) q.insert(q.size() - 1, "...");
      s.append(" ").append(q);
      break;
    }
    case Json::Type::array:
      s.append(" of " + std::to_string(value.size()));
      break;
    case Json::Type::object:
      s.append(" with " + std::to_string(value.size()) + " keys");
      break;
  }
  return s;
}

/// Writes a value tree; keeps a stack of path segments so an error can name where it is.
/// The path is materialised as text only on failure, so the happy path costs one small
/// push/pop per nesting level.
class JsonWriter {
 public:
  explicit JsonWriter(int indent) : indent_(indent) {}

  void write(const Json& v, int depth) {
    if (depth > json_max_depth) {
      // The path of a value this deep is at least 513 segments long: its start says where.
      std::string where = path_text();
      if (where.size() > 80) {
        const std::size_t cut = where.find_last_of(".[", 80);  // at a segment's start
        where = where.substr(0, cut == 0 || cut == std::string::npos ? 80 : cut) + "...";
      }
      fail("cannot write JSON nested deeper than " + std::to_string(json_max_depth) +
           " levels (at " + where + "): Json::parse reads no deeper, so the text could not be read back");
    }
    switch (v.type()) {
      case Json::Type::null:
        out_.append("null");
        break;
      case Json::Type::boolean:
        out_.append(v.as_bool() ? "true" : "false");
        break;
      case Json::Type::number: {
        const double x = v.as_number();
        if (!std::isfinite(x)) {
          fail(std::string("cannot write non-finite number (") +
               (std::isnan(x) ? "nan" : (x > 0 ? "inf" : "-inf")) + ") at " + path_text() +
               ": JSON has no NaN or Infinity");
        }
        append_json_number(out_, x);
        break;
      }
      case Json::Type::string:
        string(v.as_string(), "string");
        break;
      case Json::Type::array:
        array(v.as_array(), depth);
        break;
      case Json::Type::object:
        object(v.as_object(), depth);
        break;
    }
  }
  std::string take() { return std::move(out_); }

 private:
  struct Segment {
    std::string_view key;
    std::size_t index;
    bool is_key;
  };

  void string(std::string_view s, const char* what) {
    const std::size_t mark = out_.size();
    const std::size_t bad = append_json_string(out_, s);
    if (bad != std::string_view::npos) {
      out_.resize(mark);
      fail(std::string(what) + " at " + path_text() + " is not valid UTF-8 (byte " +
           std::to_string(bad) + ")");
    }
  }
  static bool is_scalar(const Json& v) { return !v.is_array() && !v.is_object(); }
  void newline(int depth) {
    out_.push_back('\n');
    out_.append(static_cast<std::size_t>(indent_) * static_cast<std::size_t>(depth), ' ');
  }
  void array(const Json::Array& a, int depth) {
    out_.push_back('[');
    const bool compact = indent_ < 0;
    bool all_scalar = true;
    for (const Json& e : a) all_scalar = all_scalar && is_scalar(e);
    const std::size_t wrap = 100;  // scalar arrays wrap near this column
    // Only the indented layout wraps. There the scan back to the line start is short (every
    // array that is not the root begins a line or follows a key); in one-line output it would
    // cross the whole text for every array, O(n²) for "[[],[],...]".
    std::size_t line_start = 0;
    if (!compact) {
      line_start = out_.rfind('\n');
      line_start = line_start == std::string::npos ? 0 : line_start + 1;
    }
    for (std::size_t i = 0; i < a.size(); ++i) {
      path_.push_back({{}, i, false});
      if (i > 0) out_.push_back(',');
      if (!compact && !all_scalar) {
        newline(depth + 1);
      } else if (!compact) {
        if (out_.size() - line_start > wrap) {
          newline(depth + 1);
          line_start = out_.size() - static_cast<std::size_t>(indent_) * (depth + 1);
        } else if (i > 0) {
          out_.push_back(' ');
        }
      }
      write(a[i], depth + 1);
      path_.pop_back();
    }
    if (!compact && !all_scalar && !a.empty()) newline(depth);
    out_.push_back(']');
  }
  void object(const Json::Object& o, int depth) {
    out_.push_back('{');
    bool first = true;
    for (const Json::Member& m : o) {
      path_.push_back({m.first, 0, true});
      if (!first) out_.push_back(',');
      first = false;
      if (indent_ >= 0) newline(depth + 1);
      string(m.first, "key");
      out_.append(indent_ >= 0 ? ": " : ":");
      write(m.second, depth + 1);
      path_.pop_back();
    }
    if (indent_ >= 0 && !o.empty()) newline(depth);
    out_.push_back('}');
  }
  std::string path_text() const {
    if (path_.empty()) return "top level";
    std::string p;
    for (const Segment& s : path_) {
      if (s.is_key) {
        if (!p.empty()) p.push_back('.');
        p.append(s.key);
      } else {
        p.append("[" + std::to_string(s.index) + "]");
      }
    }
    return p;
  }
  [[noreturn]] void fail(const std::string& message) const { throw Error(message); }

  int indent_;
  std::string out_;
  std::vector<Segment> path_;
};

/// Recursive-descent parser for `Json::parse` (one pass, no backtracking). Tracks line and
/// column incrementally so positions cost O(1) per value even on one-line files.
class JsonParser {
 public:
  JsonParser(std::string_view text, const std::string& source)
      : s_(text), source_(std::make_shared<const std::string>(source)) {}

  Json run() {
    // Tolerate a UTF-8 byte-order mark. Editors do not show it, so columns start after it.
    if (s_.substr(0, 3) == "\xEF\xBB\xBF") pos_ = line_start_ = col_pos_ = 3;
    skip_space();
    if (pos_ >= s_.size()) fail("empty input: expected a JSON value");
    Json v = value(0);
    skip_space();
    if (pos_ < s_.size()) fail("unexpected " + describe_here() + " after the JSON value");
    return v;
  }

 private:
  // value := object | array | string | number | true | false | null   (RFC 8259 sec. 3).
  // The first byte decides the production, so no backtracking is ever needed. Each value
  // records where it started, for errors raised later by accessors (JsonView::fail).
  Json value(int depth) {
    if (depth > json_max_depth) fail("nesting deeper than " + std::to_string(json_max_depth) + " levels");
    Json v;
    position(v);
    const char c = s_[pos_];
    if (c == '{') {
      object(v, depth);
    } else if (c == '[') {
      array(v, depth);
    } else if (c == '"') {
      v.value_ = string();
    } else if (c == '-' || (c >= '0' && c <= '9')) {
      v.value_ = number();
    } else if (c == '}' || c == ']') {
      fail("unexpected '" + std::string(1, c) + "': expected a value");
    } else {
      literal(v);
    }
    return v;
  }

  // object := '{' [ string ':' value { ',' string ':' value } ] '}'. The loop is written so that
  // each way of going wrong (trailing comma, missing colon, unquoted key, end of input) gets
  // its own message at the exact offending byte, rather than a generic "syntax error".
  // Duplicate keys are rejected: RFC 8259 leaves their meaning open, and silently keeping the
  // last one would hide an edit made in the wrong place of a hand-edited model file.
  void object(Json& v, int depth) {
    const std::size_t open = pos_;
    ++pos_;
    Json::Object members;
    skip_space();
    if (peek() == '}') {
      ++pos_;
      v.value_ = std::move(members);
      return;
    }
    std::unordered_set<std::string> seen;  // keys of a large object (below)
    while (true) {
      skip_space();
      if (pos_ >= s_.size()) fail_unterminated("object", open);
      if (peek() == '}') fail("trailing comma is not allowed in JSON");
      if (peek() != '"') fail("expected a string key in double quotes, found " + describe_here());
      const std::size_t key_pos = pos_;
      std::string key = string();
      // A scan of the earlier keys is cheapest for the small objects of model files; past 32
      // members a set keeps a large (or hostile) object from costing n² comparisons.
      bool duplicate = false;
      if (members.size() < 32) {
        for (const Json::Member& m : members) duplicate = duplicate || m.first == key;
      } else {
        if (seen.empty())
          for (const Json::Member& m : members) seen.insert(m.first);
        duplicate = !seen.insert(key).second;
      }
      if (duplicate) {
        pos_ = key_pos;
        fail("duplicate key '" + key + "' in object");
      }
      skip_space();
      if (pos_ >= s_.size()) fail_unterminated("object", open);
      if (peek() != ':') fail("expected ':' after key '" + key + "', found " + describe_here());
      ++pos_;
      skip_space();
      if (pos_ >= s_.size()) fail_unterminated("object", open);
      members.emplace_back(std::move(key), value(depth + 1));
      skip_space();
      if (pos_ >= s_.size()) fail_unterminated("object", open);
      if (peek() == ',') {
        ++pos_;
        continue;
      }
      if (peek() == '}') {
        ++pos_;
        break;
      }
      fail("expected ',' or '}' after object member, found " + describe_here());
    }
    v.value_ = std::move(members);
  }

  // array := '[' [ value { ',' value } ] ']' -- same error discipline as object().
  void array(Json& v, int depth) {
    const std::size_t open = pos_;
    ++pos_;
    Json::Array items;
    skip_space();
    if (peek() == ']') {
      ++pos_;
      v.value_ = std::move(items);
      return;
    }
    while (true) {
      skip_space();
      if (pos_ >= s_.size()) fail_unterminated("array", open);
      if (peek() == ']') fail("trailing comma is not allowed in JSON");
      items.push_back(value(depth + 1));
      skip_space();
      if (pos_ >= s_.size()) fail_unterminated("array", open);
      if (peek() == ',') {
        ++pos_;
        continue;
      }
      if (peek() == ']') {
        ++pos_;
        break;
      }
      fail("expected ',' or ']' after array element, found " + describe_here());
    }
    v.value_ = std::move(items);
  }

  // string := '"' { unescaped | escape } '"'. Raw bytes are copied after UTF-8 validation, so
  // the stored text is always well-formed and dump() can never fail on parsed strings.
  std::string string() {
    const std::size_t open = pos_;
    ++pos_;  // opening quote
    std::string out;
    while (true) {
      if (pos_ >= s_.size()) fail_unterminated("string", open);
      const unsigned char c = static_cast<unsigned char>(s_[pos_]);
      if (c == '"') {
        ++pos_;
        return out;
      }
      if (c == '\\') {
        escape(out);
        continue;
      }
      if (c < 0x20) {
        fail(c == '\n' ? "line break inside a string (write \\n, or close the quote)"
                       : "control character inside a string must be escaped");
      }
      if (c >= 0x80) {
        const std::size_t n = detail::utf8_sequence_length(s_, pos_);
        if (n == 0) fail("invalid UTF-8 byte in string");
        out.append(s_.substr(pos_, n));
        pos_ += n;
        continue;
      }
      out.push_back(static_cast<char>(c));
      ++pos_;
    }
  }

  // The two-character escapes of RFC 8259 sec. 7, and \uXXXX. Characters outside the Basic
  // Multilingual Plane arrive as a UTF-16 surrogate pair (\uD83D\uDE00) that must be combined
  // into one code point before encoding it as UTF-8; a lone half has no meaning and is an error.
  void escape(std::string& out) {
    const std::size_t at = pos_;
    ++pos_;  // backslash
    if (pos_ >= s_.size()) fail("unexpected end of input in escape sequence");
    const char e = s_[pos_++];
    switch (e) {
      case '"':
        out.push_back('"');
        return;
      case '\\':
        out.push_back('\\');
        return;
      case '/':
        out.push_back('/');
        return;
      case 'b':
        out.push_back('\b');
        return;
      case 'f':
        out.push_back('\f');
        return;
      case 'n':
        out.push_back('\n');
        return;
      case 'r':
        out.push_back('\r');
        return;
      case 't':
        out.push_back('\t');
        return;
      case 'u':
        break;
      default: {
        // The byte itself only when printable: a NUL would end what() there, file name and all.
        const auto b = static_cast<unsigned char>(e);
        pos_ = at;
        if (b < 0x20 || b >= 0x7F) {
          fail(std::string("invalid escape: backslash before byte 0x") + "0123456789abcdef"[b >> 4] +
               "0123456789abcdef"[b & 15] + " in string");
        }
        fail(std::string("invalid escape '\\") + e + "' in string");
      }
    }
    std::uint32_t cp = hex4(at);
    if (cp >= 0xD800 && cp <= 0xDBFF) {
      // A high surrogate must be followed by \u + low surrogate (UTF-16 pair, RFC 8259 sec. 7).
      if (s_.substr(pos_, 2) != "\\u") {
        pos_ = at;
        fail("unpaired UTF-16 high surrogate in \\u escape");
      }
      pos_ += 2;
      const std::uint32_t lo = hex4(at);
      if (lo < 0xDC00 || lo > 0xDFFF) {
        pos_ = at;
        fail("high surrogate not followed by a low surrogate in \\u escape");
      }
      cp = 0x10000 + ((cp - 0xD800) << 10) + (lo - 0xDC00);
    } else if (cp >= 0xDC00 && cp <= 0xDFFF) {
      pos_ = at;
      fail("unpaired UTF-16 low surrogate in \\u escape");
    }
    detail::append_utf8(out, cp);
  }

  std::uint32_t hex4(std::size_t escape_start) {
    std::uint32_t v = 0;
    for (int k = 0; k < 4; ++k) {
      if (pos_ >= s_.size()) fail("unexpected end of input in \\u escape");
      const char c = s_[pos_];
      std::uint32_t d = 0;
      if (c >= '0' && c <= '9') {
        d = static_cast<std::uint32_t>(c - '0');
      } else if (c >= 'a' && c <= 'f') {
        d = static_cast<std::uint32_t>(c - 'a' + 10);
      } else if (c >= 'A' && c <= 'F') {
        d = static_cast<std::uint32_t>(c - 'A' + 10);
      } else {
        pos_ = escape_start;
        fail("\\u escape needs four hex digits");
      }
      v = v * 16 + d;
      ++pos_;
    }
    return v;
  }

  // The grammar is checked here, byte by byte, because std::from_chars alone accepts forms JSON
  // forbids ("01", "1.", "inf", "nan"); from_chars then does the correctly rounded conversion
  // (so parse(dump(x)) == x bit for bit).
  double number() {
    // Grammar (RFC 8259 sec. 6): -? (0 | [1-9][0-9]*) (. [0-9]+)? ([eE] [+-]? [0-9]+)?
    const std::size_t start = pos_;
    const auto digit = [&] { return pos_ < s_.size() && s_[pos_] >= '0' && s_[pos_] <= '9'; };
    if (s_[pos_] == '-') ++pos_;
    if (!digit()) {
      if (s_.substr(pos_, 8) == "Infinity") fail("-Infinity is not valid JSON (no NaN/Inf)");
      fail("expected a digit after '-'");
    }
    if (s_[pos_] == '0') {
      ++pos_;
      if (digit()) {
        pos_ = start;
        fail("leading zeros are not allowed in JSON numbers");
      }
    } else {
      while (digit()) ++pos_;
    }
    if (pos_ < s_.size() && s_[pos_] == '.') {
      ++pos_;
      if (!digit()) fail("expected a digit after the decimal point");
      while (digit()) ++pos_;
    }
    if (pos_ < s_.size() && (s_[pos_] == 'e' || s_[pos_] == 'E')) {
      ++pos_;
      if (pos_ < s_.size() && (s_[pos_] == '+' || s_[pos_] == '-')) ++pos_;
      if (!digit()) fail("expected a digit in the exponent");
      while (digit()) ++pos_;
    }
    double x = 0;
    const auto r = std::from_chars(s_.data() + start, s_.data() + pos_, x);
    if (r.ec == std::errc::result_out_of_range) {
      // Underflow rounds to zero, as IEEE arithmetic would; overflow would invent an infinity.
      // from_chars reports both alike, and neither the exponent's sign nor the digit count
      // tells them apart ("0.000...1" has no exponent, "1000...0e-700" has 301 digits).
      if (decimal_order(start, pos_) < 0) {
        x = s_[start] == '-' ? -0.0 : 0.0;
      } else {
        const std::size_t shown = std::min<std::size_t>(pos_ - start, 40);
        const std::string text(s_.substr(start, shown));
        pos_ = start;
        fail("number " + text + (shown < 40 ? "" : "...") + " is too large for a double");
      }
    } else if (r.ec != std::errc() || r.ptr != s_.data() + pos_) {
      pos_ = start;
      fail("malformed number");
    }
    return x;
  }

  // Decimal exponent of the leading significant digit of the number text [b, e), i.e. k with
  // 10^k <= |x| < 10^(k+1). Only its sign is used: a double overflows beyond 10^308 and
  // underflows below 10^-324, so a saturated exponent is exact enough.
  long long decimal_order(std::size_t b, std::size_t e) const {
    long long order = -1;
    bool significant = false, fraction = false;
    std::size_t k = b;
    for (; k < e && s_[k] != 'e' && s_[k] != 'E'; ++k) {
      const char c = s_[k];
      if (c == '.') {
        fraction = true;
      } else if (c >= '0' && c <= '9') {
        significant = significant || c != '0';
        if (!fraction && significant) ++order;
        if (fraction && !significant) --order;
      }
    }
    long long exponent = 0, sign = 1;
    if (k < e) ++k;  // 'e'
    if (k < e && (s_[k] == '+' || s_[k] == '-')) sign = s_[k++] == '-' ? -1 : 1;
    for (; k < e; ++k) exponent = std::min(exponent * 10 + (s_[k] - '0'), 1'000'000'000LL);
    return order + sign * exponent;
  }

  // Reads a whole word so that "tru" or "nulll" is reported as one bad literal, and common
  // non-JSON spellings (NaN, Infinity from Python or JavaScript) get a specific explanation.
  void literal(Json& v) {
    std::size_t end = pos_;
    while (end < s_.size() &&
           ((s_[end] >= 'a' && s_[end] <= 'z') || (s_[end] >= 'A' && s_[end] <= 'Z')))
      ++end;
    const std::string_view word = s_.substr(pos_, end - pos_);
    if (word == "true") {
      v.value_ = true;
    } else if (word == "false") {
      v.value_ = false;
    } else if (word == "null") {
      v.value_ = nullptr;
    } else if (word == "NaN" || word == "nan" || word == "Infinity" || word == "inf") {
      fail("'" + std::string(word) + "' is not valid JSON (JSON has no NaN or Infinity)");
    } else if (word.empty()) {
      fail("unexpected " + describe_here() + ": expected a value");
    } else {
      fail("invalid literal '" + std::string(word) + "' (expected true, false or null)");
    }
    pos_ = end;
  }

  // Whitespace is space, tab, CR, LF only (RFC 8259 sec. 2). Line bookkeeping happens here
  // because a newline can only occur in whitespace (raw newlines in strings are errors).
  void skip_space() {
    while (pos_ < s_.size()) {
      const char c = s_[pos_];
      if (c == ' ' || c == '\t' || c == '\r') {
        ++pos_;
      } else if (c == '\n') {
        ++pos_;
        ++line_;
        line_start_ = pos_;
        col_pos_ = pos_;
        col_ = 1;
      } else if (c == '/' && pos_ + 1 < s_.size() && (s_[pos_ + 1] == '/' || s_[pos_ + 1] == '*')) {
        fail("comments are not allowed in JSON");
      } else {
        break;
      }
    }
  }
  // '\0' at the end never matches a structural character, so callers need no bounds check.
  char peek() const { return pos_ < s_.size() ? s_[pos_] : '\0'; }

  // Column of pos_ in code points; advances a cursor so the total work is linear.
  long column_here() {
    if (pos_ < col_pos_) {  // error positions may step back within the line
      col_pos_ = line_start_;
      col_ = 1;
    }
    for (; col_pos_ < pos_ && col_pos_ < s_.size(); ++col_pos_) {
      if ((static_cast<unsigned char>(s_[col_pos_]) & 0xC0) != 0x80) ++col_;
    }
    return col_;
  }
  void position(Json& v) {
    v.line_ = static_cast<std::uint32_t>(line_);
    v.column_ = static_cast<std::uint32_t>(column_here());
    v.source_ = source_;
  }

  // What is at pos_, for "expected X, found Y" messages; non-printable bytes as hex.
  std::string describe_here() const {
    if (pos_ >= s_.size()) return "end of input";
    const unsigned char c = static_cast<unsigned char>(s_[pos_]);
    if (c < 0x20 || c >= 0x7F)
      return "byte 0x" + std::string{"0123456789abcdef"[c >> 4], "0123456789abcdef"[c & 15]};
    return std::string("'") + static_cast<char>(c) + "'";
  }

  // Truncated input is reported where it ends (that is where the reader's editor cursor
  // lands), and names the line where the unclosed value began, which is where the fix goes.
  [[noreturn]] void fail_unterminated(const char* what, std::size_t open) {
    fail(std::string("unexpected end of input: unterminated ") + what + " starting at line " +
         std::to_string(line_at(open)));
  }
  long line_at(std::size_t p) const {
    long l = 1;
    for (std::size_t k = 0; k < p && k < s_.size(); ++k) l += s_[k] == '\n';
    return l;
  }

  [[noreturn]] void fail(const std::string& message) {
    // pos_ may have been moved back onto an earlier line (e.g. a duplicate key): recount.
    if (pos_ < line_start_) {
      line_ = line_at(pos_);
      const std::size_t nl = pos_ == 0 ? std::string_view::npos : s_.rfind('\n', pos_ - 1);
      line_start_ = nl == std::string_view::npos ? 0 : nl + 1;
      col_pos_ = line_start_;
      col_ = 1;
    }
    Location where;
    where.file = *source_;
    where.row = line_;
    where.column = column_here();
    throw Error("JSON parse error: " + message, std::move(where));
  }

  std::string_view s_;
  std::shared_ptr<const std::string> source_;
  std::size_t pos_ = 0;
  long line_ = 1;
  std::size_t line_start_ = 0;
  std::size_t col_pos_ = 0;  // column cursor: col_ is the column of byte col_pos_
  long col_ = 1;
};

}  // namespace detail

inline Json Json::parse(std::string_view text, const std::string& source_name) {
  return detail::JsonParser(text, source_name).run();
}

inline Json::Json(const Json& other) {
  std::vector<std::pair<Json*, const Json*>> pending;
  copy_node(*this, other, pending);
  while (!pending.empty()) {
    const auto [to, from] = pending.back();
    pending.pop_back();
    copy_node(*to, *from, pending);
  }
}

inline void Json::copy_node(Json& to, const Json& from,
                            std::vector<std::pair<Json*, const Json*>>& pending) {
  to.line_ = from.line_;
  to.column_ = from.column_;
  to.source_ = from.source_;
  const auto child = [&pending](Json& t, const Json& f) {
    if (f.is_array() || f.is_object()) {
      pending.emplace_back(&t, &f);
    } else {
      copy_node(t, f, pending);  // a scalar: no further call
    }
  };
  // The children are created first and never moved afterwards, so the queued pointers to
  // them stay valid.
  switch (from.type()) {
    case Type::null:
      to.value_ = nullptr;
      break;
    case Type::boolean:
      to.value_ = std::get<bool>(from.value_);
      break;
    case Type::number:
      to.value_ = std::get<double>(from.value_);
      break;
    case Type::string:
      to.value_ = std::get<std::string>(from.value_);
      break;
    case Type::array: {
      const Array& src = std::get<Array>(from.value_);
      Array& dst = to.value_.emplace<Array>(src.size());
      for (std::size_t i = 0; i < src.size(); ++i) child(dst[i], src[i]);
      break;
    }
    case Type::object: {
      const Object& src = std::get<Object>(from.value_);
      Object& dst = to.value_.emplace<Object>();
      for (const Member& m : src) dst.emplace_back(m.first, Json());
      auto d = dst.begin();
      for (const Member& m : src) child((d++)->second, m.second);
      break;
    }
  }
}

inline bool Json::equal(const Json& a, const Json& b) {
  std::vector<std::pair<const Json*, const Json*>> pending;  // container pairs still to compare
  // Compares x and y except for their container children, which are queued.
  const auto shallow = [&pending](const Json& x, const Json& y) {
    if (x.type() != y.type()) return false;
    switch (x.type()) {
      case Type::null:
        return true;
      case Type::boolean:
        return std::get<bool>(x.value_) == std::get<bool>(y.value_);
      case Type::number:
        return std::get<double>(x.value_) == std::get<double>(y.value_);
      case Type::string:
        return std::get<std::string>(x.value_) == std::get<std::string>(y.value_);
      case Type::array: {
        const Array& xa = std::get<Array>(x.value_);
        const Array& ya = std::get<Array>(y.value_);
        if (xa.size() != ya.size()) return false;
        for (std::size_t i = 0; i < xa.size(); ++i) pending.emplace_back(&xa[i], &ya[i]);
        return true;
      }
      case Type::object: {
        const Object& xo = std::get<Object>(x.value_);
        const Object& yo = std::get<Object>(y.value_);
        if (xo.size() != yo.size()) return false;
        // Members match by key, in any order. find() scans, which is cheapest for the small
        // objects of model files; past 32 members an index of y's keys keeps a large object
        // from costing n² key comparisons (as the parser's duplicate check does). The index
        // keeps the first of repeated keys, as find() does (code can make them via as_object()).
        if (xo.size() < 32) {
          for (const Member& m : xo) {
            const Json* other = y.find(m.first);
            if (other == nullptr) return false;
            pending.emplace_back(&m.second, other);
          }
          return true;
        }
        std::unordered_map<std::string_view, const Json*> index;
        index.reserve(yo.size());
        for (const Member& m : yo) index.emplace(m.first, &m.second);
        for (const Member& m : xo) {
          const auto it = index.find(m.first);
          if (it == index.end()) return false;
          pending.emplace_back(&m.second, it->second);
        }
        return true;
      }
    }
    return false;
  };
  if (!shallow(a, b)) return false;
  while (!pending.empty()) {
    const auto [x, y] = pending.back();
    pending.pop_back();
    if (!shallow(*x, *y)) return false;
  }
  return true;
}

inline bool Json::has_nested_containers() const noexcept {
  // size() is 0 for scalars, so a non-zero size means a non-empty array or object.
  if (const Array* a = std::get_if<Array>(&value_)) {
    for (const Json& e : *a) {
      if (e.size() > 0) return true;
    }
  } else if (const Object* o = std::get_if<Object>(&value_)) {
    for (const Member& m : *o) {
      if (m.second.size() > 0) return true;
    }
  }
  return false;
}

// Moves every non-empty container below this value onto a flat stack, one level at a time; a
// value is destroyed only when its children are scalars or emptied containers (a moved-from
// vector is empty), so no destructor call reaches more than two levels down. The stack's
// allocation failing here would terminate (a destructor cannot throw), as a deep recursion's
// stack overflow would have crashed, but only for a tree of the size of the memory.
inline void Json::dismantle() noexcept {
  std::vector<Json> pending;
  const auto take_children = [&pending](Json& node) {
    if (Array* a = std::get_if<Array>(&node.value_)) {
      for (Json& e : *a) {
        if (e.size() > 0) pending.push_back(std::move(e));
      }
    } else if (Object* o = std::get_if<Object>(&node.value_)) {
      for (Member& m : *o) {
        if (m.second.size() > 0) pending.push_back(std::move(m.second));
      }
    }
  };
  take_children(*this);
  while (!pending.empty()) {
    Json node = std::move(pending.back());
    pending.pop_back();
    take_children(node);
  }
}

inline std::string Json::dump(int indent) const {
  detail::JsonWriter w(indent);
  w.write(*this, 0);
  return w.take();
}

inline JsonView Json::view() const { return JsonView(*this); }
inline JsonView Json::at(std::string_view key) const { return view().at(key); }
inline JsonView Json::at(std::size_t index) const { return view().at(index); }
inline JsonView Json::operator[](std::string_view key) const { return view().at(key); }
inline JsonView Json::operator[](std::size_t index) const { return view().at(index); }
template <std::same_as<char> C>
inline JsonView Json::at(const C* key) const {
  return at(detail::json_key(key, "Json::at"));
}
template <std::same_as<char> C>
inline JsonView Json::operator[](const C* key) const {
  return (*this)[detail::json_key(key, "Json::operator[]")];
}
inline double Json::as_number() const { return view().as_number(); }
inline long long Json::as_integer() const { return view().as_integer(); }
inline bool Json::as_bool() const { return view().as_bool(); }
inline const std::string& Json::as_string() const { return view().as_string(); }
inline const Json::Array& Json::as_array() const { return view().as_array(); }
inline const Json::Object& Json::as_object() const { return view().as_object(); }
template <class T>
T Json::get() const {
  return view().get<T>();
}

}  // namespace nlid
