#pragma once
/// @file
/// Series block chains (models/series.hpp: Hammerstein, Wiener, Wiener–Hammerstein, N–L–N) in
/// model files: kind "series".
///
///     "structure": {"pattern": "LNL",
///                   "blocks": [ {"type": "transfer_function", "nb": 3, "nf": 3, "nk": 0},
///                               {"type": "pwlinear", "breakpoints": 10, ...},
///                               {"type": "transfer_function", ...} ]}
///
/// Each block is its own layout (a linear block's or a nonlinearity's, both named by "type").
/// θ = [θ₁, …, θ_K] in chain order. Including this header registers the kind with
/// `load_model(path)`, which rebuilds the chains N–L, L–N, L–N–L, N–L–N and N–L–N–L with
/// `AnyNonlinearity` static blocks and `TransferFunctionBlock<Dynamic, Dynamic, Dynamic>` linear
/// blocks; any chain loads into its compile-time type with `load_model<Series<…>>(path)`.
/// This is the only serialiser of series chains (nlid-fit's "wh", "wiener" and "hammerstein"
/// models use it too). Files of the first layout, which wrapped every block as
/// {"linear": …} or {"nonlinearity": …}, are still read.

#include <cstddef>
#include <string>
#include <tuple>
#include <type_traits>
#include <utility>
#include <vector>

#include "nlid/core/error.hpp"
#include "nlid/io/json.hpp"
#include "nlid/io/model_serial.hpp"
#include "nlid/io/nonlinearity_serial.hpp"
#include "nlid/io/serial_common.hpp"
#include "nlid/models/any_model.hpp"
#include "nlid/models/series.hpp"
#include "nlid/models/transfer_function_block.hpp"

namespace nlid {

namespace detail {
template <class B>
struct IsTransferFunctionBlock : std::false_type {};
template <int Nb, int Nf, int Nk>
struct IsTransferFunctionBlock<TransferFunctionBlock<Nb, Nf, Nk>> : std::true_type {};

template <class B>
Json series_block_json(const B& b) {
  if constexpr (IsTransferFunctionBlock<B>::value) {
    return LinearBlockSerial<Dynamic, Dynamic, Dynamic>::save(TransferFunctionBlock<Dynamic, Dynamic, Dynamic>(b.nb(), b.nf(), b.nk()));
  } else {
    return NonlinearitySerial<B>::save(b);
  }
}

template <int Nb, int Nf, int Nk>
TransferFunctionBlock<Nb, Nf, Nk> load_tfb(const JsonView& v, TransferFunctionBlock<Nb, Nf, Nk>* /*tag*/) {
  return LinearBlockSerial<Nb, Nf, Nk>::load(v);
}

/// The block's own layout: the value itself, or inside the first layout's wrapper key.
inline JsonView series_block_body(const JsonView& v, bool linear) {
  const char* key = linear ? "linear" : "nonlinearity";
  if (v.contains(key)) {
    v.check_keys({key});
    return v.at(key);
  }
  if (v.contains(linear ? "nonlinearity" : "linear") ||
      (linear && v.contains("type") && v.at("type").as_string() != "transfer_function") ||
      (!linear && v.contains("type") && v.at("type").as_string() == "transfer_function")) {
    v.fail("block " + v.path_text() + (linear ? " must be linear (type \"transfer_function\")" : " must be a static nonlinearity"));
  }
  return v;
}

template <class B>
B series_block_load(const JsonView& v) {
  if constexpr (IsTransferFunctionBlock<B>::value) {
    return load_tfb(series_block_body(v, true), static_cast<B*>(nullptr));
  } else {
    return NonlinearitySerial<B>::load(series_block_body(v, false));
  }
}

template <class B>
void series_block_restore(const JsonView& v, B& b) {
  if constexpr (IsTransferFunctionBlock<B>::value) {
    const JsonView body = series_block_body(v, true);
    const auto l = LinearBlockSerial<Dynamic, Dynamic, Dynamic>::load(body);
    if (l.nb() != b.nb() || l.nf() != b.nf() || l.nk() != b.nk()) {
      v.fail("the file's linear block at " + v.path_text() + " has orders [" + std::to_string(l.nb()) + " " +
             std::to_string(l.nf()) + " " + std::to_string(l.nk()) + "], this model's differ");
    }
  } else {
    NonlinearitySerial<B>::restore(series_block_body(v, false), b);
  }
}
}  // namespace detail

/// Series<Blocks...> (see the file comment).
template <class... Blocks>
struct ModelSerial<Series<Blocks...>> {
  /// The model type.
  using M = Series<Blocks...>;
  /// Kind name in the file.
  static constexpr const char* kind = "series";
  /// Writes the model's members.
  static void save(Json& j, const M& m, const ModelFileInfo& info) {
    detail::write_common(j, m.ts(), {m.input_name()}, {m.output_name()}, info, &m.report());
    Json s = Json::object();
    s["pattern"] = M::pattern();
    Json::Array blocks;
    save_blocks(m, blocks, std::index_sequence_for<Blocks...>{});
    s["blocks"] = Json(std::move(blocks));
    j["structure"] = std::move(s);
    j["parameters"] = detail::parameters_json(m.parameter_names(), m.parameters());
    j["report"] = report_to_json(m.report());
  }
  /// Builds the chain from the file (block kinds must match `Blocks...`).
  static M load(const JsonView& file, ModelFileInfo& info) {
    detail::expect_kind(file, kind);
    std::vector<std::string> in, out;
    const double ts = detail::read_common(file, info, in, out);
    const JsonView s = file.at("structure");
    s.check_keys({"pattern", "blocks"});
    check_pattern(s);
    const JsonView blocks = s.at("blocks");
    M m = load_blocks(blocks, ts, std::index_sequence_for<Blocks...>{});
    finish(file, m, in, out, info);
    return m;
  }
  /// Fills a prototype of the same chain.
  static void restore(const JsonView& file, M& m, ModelFileInfo& info) {
    detail::expect_kind(file, kind);
    std::vector<std::string> in, out;
    const double ts = detail::read_common(file, info, in, out);
    const JsonView s = file.at("structure");
    s.check_keys({"pattern", "blocks"});
    check_pattern(s);
    restore_blocks(s.at("blocks"), m, std::index_sequence_for<Blocks...>{});
    m.set_ts(ts);
    finish(file, m, in, out, info);
  }

 private:
  static void check_pattern(const JsonView& s) {
    const std::string& p = s.at("pattern").as_string();
    if (p != M::pattern()) {
      s.at("pattern").fail("the file's chain is " + p + " (at " + s.at("pattern").path_text() + "), this model's is " +
                           M::pattern());
    }
    if (s.at("blocks").as_array().size() != sizeof...(Blocks)) {
      s.at("blocks").fail("expected " + std::to_string(sizeof...(Blocks)) + " blocks at " + s.at("blocks").path_text());
    }
  }
  template <std::size_t... I>
  static void save_blocks(const M& m, Json::Array& a, std::index_sequence<I...>) {
    (a.push_back(detail::series_block_json(m.template block<I>())), ...);
  }
  template <std::size_t... I>
  static M load_blocks(const JsonView& blocks, double ts, std::index_sequence<I...>) {
    std::tuple<Blocks...> b{detail::series_block_load<Blocks>(blocks.at(I))...};
    return M(std::get<I>(std::move(b))..., ts);
  }
  template <std::size_t... I>
  static void restore_blocks(const JsonView& blocks, M& m, std::index_sequence<I...>) {
    (detail::series_block_restore(blocks.at(I), m.template block<I>()), ...);
  }
  static void finish(const JsonView& file, M& m, const std::vector<std::string>& in,
                     const std::vector<std::string>& out, ModelFileInfo& info) {
    detail::expect_channel_count(file.at("inputs"), in.size(), 1, "inputs");
    detail::expect_channel_count(file.at("outputs"), out.size(), 1, "outputs");
    m.set_channel_names(in[0], out[0]);
    m.set_parameters(detail::read_parameters(file, m.num_parameters()));
    m.set_report(report_from_json(file.at("report")));
    info.report.reset();
  }
};

/// Run-time chains read by `load_model(path)`.
using DynamicLinearBlock = TransferFunctionBlock<Dynamic, Dynamic, Dynamic>;
/// N–L with run-time blocks.
using DynamicHammersteinSeries = Series<AnyNonlinearity, DynamicLinearBlock>;
/// L–N with run-time blocks.
using DynamicWienerSeries = Series<DynamicLinearBlock, AnyNonlinearity>;
/// L–N–L with run-time blocks.
using DynamicWienerHammerstein = Series<DynamicLinearBlock, AnyNonlinearity, DynamicLinearBlock>;
/// N–L–N with run-time blocks.
using DynamicHammersteinWienerSeries = Series<AnyNonlinearity, DynamicLinearBlock, AnyNonlinearity>;
/// N–L–N–L with run-time blocks.
using DynamicNLNLSeries = Series<AnyNonlinearity, DynamicLinearBlock, AnyNonlinearity, DynamicLinearBlock>;

namespace detail {
template <class M>
bool try_series(const JsonView& file, ModelFileInfo& info, AnyModel& out) {
  if (file.at("structure").at("pattern").as_string() != M::pattern()) return false;
  out = AnyModel(ModelSerial<M>::load(file, info), info);
  return true;
}
/// Registers "series" with `load_model(path)` once per program.
inline const bool series_kind_registered = [] {
  register_model_kind("series", [](const JsonView& file, ModelFileInfo& info) {
    AnyModel m;
    if (try_series<DynamicWienerHammerstein>(file, info, m) || try_series<DynamicHammersteinSeries>(file, info, m) ||
        try_series<DynamicWienerSeries>(file, info, m) || try_series<DynamicHammersteinWienerSeries>(file, info, m) ||
        try_series<DynamicNLNLSeries>(file, info, m)) {
      return m;
    }
    const JsonView p = file.at("structure").at("pattern");
    p.fail("series chain " + p.as_string() + " at " + p.path_text() +
           " cannot be built at run time (supported: " + DynamicHammersteinSeries::pattern() + ", " +
           DynamicWienerSeries::pattern() + ", " + DynamicWienerHammerstein::pattern() + ", " +
           DynamicHammersteinWienerSeries::pattern() + ", " + DynamicNLNLSeries::pattern() +
           "); load it with load_model<Series<...>>(path)");
  });
  return true;
}();
}  // namespace detail

}  // namespace nlid
