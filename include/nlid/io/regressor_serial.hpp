#pragma once
/// @file
/// Regressors in model files: a flat list of blocks, written by every regressor type and read
/// back into compile-time sets or into the run-time `RegressorList`.
///
/// Layout (docs/model_files.md):
///
///     "regressors": {
///       "blocks": [ {"type": "output_lags", "na": 2},
///                   {"type": "input_lags", "nb": 1, "nk": 0, "channel": 0},
///                   {"type": "custom", "expression": "max(y1(t-1),90)+min(y1(t-1),15)-105"} ],
///       "names":  [ "y1(t-1)", "y1(t-2)", "u1(t)", "max(y1(t-1),90)+min(y1(t-1),15)-105" ] }
///
/// `names` is the getreg list (for people, and to check a compile-time prototype against the
/// file). A C++ lambda regressor (`CustomRegressor`) is written with its display name as the
/// expression when that name parses and computes what the lambda computes on 64 probe windows
/// (the recommended spelling, e.g. the study's hard-stop regressor); otherwise as
/// {"type": "custom", "expression": null, "name": "..."}, which only a program holding the
/// lambda can load (`load_model(path, prototype)`) — never as an expression that would load as
/// a different model.
///
/// `RegressorSerial<R>`: `save_blocks(r, blocks)` appends r's blocks; `load(view, next)` builds an
/// R from the blocks starting at index `next` and advances it (for the types that can be rebuilt:
/// `OutputLags`, `InputLags`, `LaggedRegressors`, `ExpressionRegressor`, `RegressorList` and sets
/// of them).

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/core/sizes.hpp"
#include "nlid/io/json.hpp"
#include "nlid/io/serial_common.hpp"
#include "nlid/regressors/custom.hpp"
#include "nlid/regressors/expression.hpp"
#include "nlid/regressors/lag_window.hpp"
#include "nlid/regressors/lagged.hpp"
#include "nlid/regressors/regressor_set.hpp"

namespace nlid {

/// Serialiser of regressor type R (see the file comment).
template <class R>
struct RegressorSerial;

/// A regressor type whose blocks can be written. Satisfied by every nlid regressor type.
template <class R>
concept SavableRegressor = requires(const R& r, Json::Array& a) { RegressorSerial<R>::save_blocks(r, a); };

/// A regressor type that can be rebuilt from a file's blocks.
/// Satisfied by OutputLags, InputLags, LaggedRegressors, ExpressionRegressor, RegressorList and
/// RegressorSet of such terms (not by lambda `CustomRegressor`s: load those into a prototype).
template <class R>
concept LoadableRegressor = requires(const JsonView& v, std::size_t& next, const std::vector<std::string>& in,
                                     const std::string& out) {
  { RegressorSerial<R>::load(v, next, in, out) } -> std::same_as<R>;
};

namespace detail {

// Appends r's blocks for a model with these channel names: types whose text depends on the names
// (a C++ custom regressor, a set holding one) take them, the others do not need them.
template <class R>
void save_regressor_blocks(const R& r, Json::Array& a, const std::vector<std::string>& input_names,
                           const std::string& output_name) {
  if constexpr (requires { RegressorSerial<R>::save_blocks(r, a, input_names, output_name); })
    RegressorSerial<R>::save_blocks(r, a, input_names, output_name);
  else
    RegressorSerial<R>::save_blocks(r, a);
}

inline Json output_lags_block(int na) { return Json::object({{"type", "output_lags"}, {"na", na}}); }
inline Json input_lags_block(int nb, int nk, int channel) {
  return Json::object({{"type", "input_lags"}, {"nb", nb}, {"nk", nk}, {"channel", channel}});
}

/// The next block, checked to be of `type` (fails naming the path and what was expected).
inline JsonView take_block(const JsonView& blocks, std::size_t& next, const char* type) {
  if (next >= blocks.as_array().size()) {
    blocks.fail("the regressor blocks at " + blocks.path_text() + " end after " + std::to_string(next) +
                " block(s), but this model needs a \"" + type + "\" block next");
  }
  const JsonView b = blocks.at(next++);
  const std::string& got = b.at("type").as_string();
  if (got != type) {
    b.at("type").fail("regressor block " + b.path_text() + " is \"" + got + "\", this model needs \"" + type + "\"");
  }
  return b;
}

/// The expression of a "custom" block, parsed with the model's channel names; a parse error is
/// located in the file (line, and the column inside the JSON string).
inline Expression custom_block_expression(const JsonView& b, const std::vector<std::string>& input_names,
                                          const std::string& output_name) {
  b.check_keys({"type", "expression", "name"});
  const JsonView e = b.at("expression");
  if (e.json().is_null()) {
    const std::string name = b.contains("name") ? b.at("name").as_string() : std::string("?");
    b.fail("custom regressor '" + name + "' at " + b.path_text() +
           " was a C++ function without an expression; load this file into a model built in C++ "
           "(load_model(path, prototype)) or save the regressor as an expression");
  }
  try {
    return Expression::parse(e.as_string(), input_names, output_name);
  } catch (const Error& err) {
    Location where;
    where.file = e.json().source();
    where.row = e.json().line() > 0 ? e.json().line() : -1;
    // Column of the token inside the file: the string's opening quote + the token's column.
    where.column = e.json().column() > 0 ? e.json().column() + err.where().column : err.where().column;
    where.parameter = "expression";
    throw Error(err.message() + " (custom regressor at " + e.path_text() + ")", where);
  }
}

/// Most regressors a file's list may hold: as many inputs as a file's nonlinearity may take
/// (its "inputs" are read up to 2²⁰). Counted before each block is built, so that a few bytes
/// per block ("na": 100000) cannot make the reader build millions of regressors it will refuse.
inline constexpr int max_file_regressors = 1 << 20;

/// Fails at block `b` if adding `count` regressors to the `total` so far exceeds
/// `max_file_regressors`.
inline void check_regressor_total(const JsonView& b, const JsonView& blocks, long long total, long long count) {
  if (total + count > max_file_regressors) {
    b.fail("the regressor blocks at " + blocks.path_text() + " hold more than " + std::to_string(max_file_regressors) +
           " regressors by block " + b.path_text() + " (a nonlinearity takes at most that many inputs)");
  }
}

/// Builds a RegressorList from all blocks (the run-time reader).
inline RegressorList regressor_list_from_blocks(const JsonView& blocks, std::size_t& next,
                                                const std::vector<std::string>& input_names,
                                                const std::string& output_name) {
  RegressorList r;
  for (; next < blocks.as_array().size(); ++next) {
    const JsonView b = blocks.at(next);
    const std::string& type = b.at("type").as_string();
    if (type == "output_lags") {
      b.check_keys({"type", "na"});
      const int na = read_int(b.at("na"), 0, max_model_order);
      check_regressor_total(b, blocks, r.size(), na);
      r.add_output_lags(na);
    } else if (type == "input_lags") {
      b.check_keys({"type", "nb", "nk", "channel"});
      const int nb = read_int(b.at("nb"), 0, max_model_order);
      check_regressor_total(b, blocks, r.size(), nb);
      const int channel = read_int(b.at("channel"), 0, max_model_order);
      // Checked here, where the block can be named: the model would size itself to the channel
      // and the file's "inputs" list would then be reported as the one at fault.
      if (!input_names.empty() && channel >= static_cast<int>(input_names.size()))
        b.at("channel").fail("regressor block at " + b.path_text() + " reads input channel " + std::to_string(channel) +
                             ", but the file lists " + std::to_string(input_names.size()) + " input(s) (channels 0 to " +
                             std::to_string(input_names.size() - 1) + ")");
      r.add_input_lags(nb, read_int(b.at("nk"), 0, max_model_order), channel);
    } else if (type == "custom") {
      check_regressor_total(b, blocks, r.size(), 1);
      r.add_custom(custom_block_expression(b, input_names, output_name));
    } else {
      b.at("type").fail("unknown regressor block \"" + type + "\" at " + b.at("type").path_text() +
                        " (accepted: output_lags, input_lags, custom)");
    }
  }
  return r;
}

}  // namespace detail

/// y(t−1) … y(t−na): one "output_lags" block.
template <int Na>
struct RegressorSerial<OutputLags<Na>> {
  /// Appends the block.
  static void save_blocks(const OutputLags<Na>& r, Json::Array& a) { a.push_back(detail::output_lags_block(r.size())); }
  /// Reads one "output_lags" block.
  static OutputLags<Na> load(const JsonView& blocks, std::size_t& next,
                      [[maybe_unused]] const std::vector<std::string>& input_names = {},
                      [[maybe_unused]] const std::string& output_name = "y1") {
    const JsonView b = detail::take_block(blocks, next, "output_lags");
    b.check_keys({"type", "na"});
    try {
      return OutputLags<Na>(read_int(b.at("na"), 0, 100000));
    } catch (const Error& e) {
      b.at("na").fail(e.message() + " (at " + b.at("na").path_text() + ")");
    }
  }
};

/// u_c(t−nk) …: one "input_lags" block (channel must equal C).
template <int Nb, int Nk, int C>
struct RegressorSerial<InputLags<Nb, Nk, C>> {
  /// Appends the block.
  static void save_blocks(const InputLags<Nb, Nk, C>& r, Json::Array& a) {
    a.push_back(detail::input_lags_block(r.size(), r.delay(), C));
  }
  /// Reads one "input_lags" block.
  static InputLags<Nb, Nk, C> load(const JsonView& blocks, std::size_t& next,
                      [[maybe_unused]] const std::vector<std::string>& input_names = {},
                      [[maybe_unused]] const std::string& output_name = "y1") {
    const JsonView b = detail::take_block(blocks, next, "input_lags");
    b.check_keys({"type", "nb", "nk", "channel"});
    if (read_int(b.at("channel"), 0, 100000) != C) {
      b.at("channel").fail("regressor block " + b.path_text() + " reads input channel " +
                           std::to_string(b.at("channel").as_integer()) + ", this model's block reads channel " +
                           std::to_string(C));
    }
    try {
      return InputLags<Nb, Nk, C>(read_int(b.at("nb"), 0, 100000), read_int(b.at("nk"), 0, 100000));
    } catch (const Error& e) {
      b.fail(e.message() + " (at " + b.path_text() + ")");
    }
  }
};

/// [na nb nk]: an "output_lags" and an "input_lags" block.
template <int Na, int Nb, int Nk>
struct RegressorSerial<LaggedRegressors<Na, Nb, Nk>> {
  /// Appends the two blocks.
  static void save_blocks(const LaggedRegressors<Na, Nb, Nk>& r, Json::Array& a) {
    a.push_back(detail::output_lags_block(r.na()));
    a.push_back(detail::input_lags_block(r.nb(), r.nk(), 0));
  }
  /// Reads the two blocks.
  static LaggedRegressors<Na, Nb, Nk> load(const JsonView& blocks, std::size_t& next,
                      [[maybe_unused]] const std::vector<std::string>& input_names = {},
                      [[maybe_unused]] const std::string& output_name = "y1") {
    const std::size_t first = next;
    const OutputLags<Dynamic> y = RegressorSerial<OutputLags<Dynamic>>::load(blocks, next, input_names, output_name);
    const InputLags<Dynamic, Dynamic, 0> u = RegressorSerial<InputLags<Dynamic, Dynamic, 0>>::load(blocks, next, input_names, output_name);
    try {
      return LaggedRegressors<Na, Nb, Nk>(y.size(), u.size(), u.delay());
    } catch (const Error& e) {
      blocks.at(first).fail(e.message() + " (at " + blocks.at(first).path_text() + ")");
    }
  }
};

namespace detail {

// Whether the expression computes what the lambda computes, probed on 64 deterministic lag
// windows with values spread over ±1000 (both sides of any stop or threshold a regressor of
// recorded signals is likely to hold). A name that parses but means something else — or a lambda
// that cannot be evaluated on the probes — must not be written as the expression: the file
// would load as a different model, silently.
template <class Fn, class... Args>
bool expression_matches(const CustomRegressor<Fn, Args...>& r, const Expression& e) {
  if (e.output_lag() > r.output_lag() || e.input_lag() > r.input_lag() ||
      e.num_input_channels() > r.num_input_channels())
    return false;
  const int lag = std::max(r.output_lag(), r.input_lag());
  const int nu = std::max(r.num_input_channels(), 1);
  Eigen::MatrixXd u(lag + 1, nu);
  Eigen::VectorXd y(lag + 1);
  std::uint64_t state = 0x9E3779B97F4A7C15ULL;
  auto next = [&state] {  // splitmix64 → uniform in [−1000, 1000)
    state += 0x9E3779B97F4A7C15ULL;
    std::uint64_t z = state;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    z ^= z >> 31;
    return -1000.0 + 2000.0 * static_cast<double>(z >> 11) * 0x1.0p-53;
  };
  try {
    for (int probe = 0; probe < 64; ++probe) {
      for (Eigen::Index i = 0; i < u.size(); ++i) u.data()[i] = next();
      for (Eigen::Index i = 0; i < y.size(); ++i) y[i] = next();
      MeasuredWindow<double> w(u, y);
      w.set_time(lag);
      double a = 0.0;
      r.evaluate(w, std::span<double>(&a, 1));
      const double b = e.evaluate(w);
      if (std::isfinite(a) != std::isfinite(b)) return false;
      if (std::isfinite(a) && !(std::abs(a - b) <= 1e-9 * (1.0 + std::abs(a) + std::abs(b)))) return false;
    }
  } catch (...) {
    return false;
  }
  return true;
}

}  // namespace detail

/// A lambda custom regressor: written with its name as the expression when that expression
/// computes what the lambda does (see the file comment), else by name only.
template <class Fn, class... Args>
struct RegressorSerial<CustomRegressor<Fn, Args...>> {
  /// Appends one "custom" block.
  static void save_blocks(const CustomRegressor<Fn, Args...>& r, Json::Array& a) {
    save_blocks(r, a, {}, "y1");
  }
  /// Appends one "custom" block for a model whose channels carry these names: the file is read
  /// back with them, so the name is written as the expression only if it reads the same
  /// signals under them ("u2(t-1)^2" for input 2 reads input 1 when the inputs are {u2, u1}).
  static void save_blocks(const CustomRegressor<Fn, Args...>& r, Json::Array& a,
                          const std::vector<std::string>& input_names, const std::string& output_name) {
    const std::string name = r.names(default_input_names(r.num_input_channels()), "y1")[0];
    Json b = Json::object({{"type", "custom"}});
    bool matches = false;
    try {
      const Expression e = Expression::parse(name);
      matches = detail::expression_matches(r, e) &&
                (input_names.empty() || Expression::parse(name, input_names, output_name).signals() == e.signals());
    } catch (const Error&) {
      matches = false;
    }
    if (matches) {
      b["expression"] = name;
    } else {
      b["expression"] = nullptr;
      b["name"] = name;
    }
    a.push_back(std::move(b));
  }
};

/// An expression regressor: one "custom" block.
template <>
struct RegressorSerial<ExpressionRegressor> {
  /// Appends the block.
  static void save_blocks(const ExpressionRegressor& r, Json::Array& a) {
    a.push_back(Json::object({{"type", "custom"}, {"expression", r.expression().text()}}));
  }
  /// Reads one "custom" block (signals spelled y1/u<k>).
  static ExpressionRegressor load(const JsonView& blocks, std::size_t& next,
                      [[maybe_unused]] const std::vector<std::string>& input_names = {},
                      [[maybe_unused]] const std::string& output_name = "y1") {
    const JsonView b = detail::take_block(blocks, next, "custom");
    return ExpressionRegressor(detail::custom_block_expression(b, input_names, output_name));
  }
};

/// A run-time list: its blocks as they are.
template <>
struct RegressorSerial<RegressorList> {
  /// Appends every block.
  static void save_blocks(const RegressorList& r, Json::Array& a) {
    for (const auto& b : r.blocks()) {
      switch (b.kind) {
        case RegressorList::Kind::output_lags: a.push_back(detail::output_lags_block(b.na)); break;
        case RegressorList::Kind::input_lags: a.push_back(detail::input_lags_block(b.nb, b.nk, b.channel)); break;
        case RegressorList::Kind::custom:
          a.push_back(Json::object({{"type", "custom"}, {"expression", b.expression.text()}}));
          break;
      }
    }
  }
  /// Reads all remaining blocks (expressions may use the model's channel names).
  static RegressorList load(const JsonView& blocks, std::size_t& next,
                      [[maybe_unused]] const std::vector<std::string>& input_names = {},
                      [[maybe_unused]] const std::string& output_name = "y1") {
    return detail::regressor_list_from_blocks(blocks, next, input_names, output_name);
  }
};

/// A compile-time set: its terms' blocks in order.
template <class... Terms>
struct RegressorSerial<RegressorSet<Terms...>> {
  /// Appends every term's blocks.
  static void save_blocks(const RegressorSet<Terms...>& r, Json::Array& a) {
    save_terms(r, a, {}, "y1", std::index_sequence_for<Terms...>{});
  }
  /// The same for a model whose channels carry these names (terms that check names use them).
  static void save_blocks(const RegressorSet<Terms...>& r, Json::Array& a, const std::vector<std::string>& input_names,
                          const std::string& output_name) {
    save_terms(r, a, input_names, output_name, std::index_sequence_for<Terms...>{});
  }
  /// Reads the terms in order.
  static RegressorSet<Terms...> load(const JsonView& blocks, std::size_t& next,
                      [[maybe_unused]] const std::vector<std::string>& input_names = {},
                      [[maybe_unused]] const std::string& output_name = "y1")
    requires(LoadableRegressor<Terms> && ...)
  {
    // Braced initialisation evaluates the terms left to right, consuming blocks in order.
    return std::apply([](auto&&... t) { return RegressorSet<Terms...>(std::move(t)...); },
                      std::tuple<Terms...>{RegressorSerial<Terms>::load(blocks, next, input_names, output_name)...});
  }

 private:
  template <std::size_t... I>
  static void save_terms(const RegressorSet<Terms...>& r, Json::Array& a, const std::vector<std::string>& input_names,
                         const std::string& output_name, std::index_sequence<I...>) {
    (detail::save_regressor_blocks(r.template term<I>(), a, input_names, output_name), ...);
  }
};

/// The "regressors" object of a model file: blocks and getreg names.
template <SavableRegressor R>
[[nodiscard]] Json regressors_to_json(const R& r, const std::vector<std::string>& input_names,
                                      const std::string& output_name) {
  Json::Array blocks;
  detail::save_regressor_blocks(r, blocks, input_names, output_name);
  Json j = Json::object();
  j["blocks"] = Json(std::move(blocks));
  j["names"] = string_list(r.names(input_names, output_name));
  return j;
}

/// Checks that regressors `r` (e.g. of a prototype) are the ones the file describes, by their
/// getreg names; fails naming the first difference.
template <Regressor R>
void check_regressor_names(const JsonView& regs, const R& r, const std::vector<std::string>& input_names,
                           const std::string& output_name) {
  const auto want = r.names(input_names, output_name);
  const auto got = read_string_list(regs.at("names"));
  if (got.size() != want.size()) {
    regs.at("names").fail("the file's model has " + std::to_string(got.size()) + " regressors at " +
                          regs.at("names").path_text() + ", this model has " + std::to_string(want.size()));
  }
  for (std::size_t i = 0; i < got.size(); ++i) {
    if (got[i] != want[i]) {
      regs.at("names").at(i).fail("regressor " + std::to_string(i) + " is '" + got[i] + "' in the file (at " +
                                  regs.at("names").at(i).path_text() + ") but '" + want[i] + "' in this model");
    }
  }
}

}  // namespace nlid
