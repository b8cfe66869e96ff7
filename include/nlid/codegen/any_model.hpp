#pragma once
/// @file
/// C code for a model known only at run time: `generate_c(const AnyModel&)` — the model in a
/// file written by nlid-fit or `save()`, or the result of a search.
///
/// Why. A control engineer fits with the command-line tools and deploys on a target; neither
/// step should need a C++ program that names the model's type. A model file is loaded as the
/// `Dynamic` twin of its compile-time type (`DynamicNlarx`, `DynamicHammersteinWiener`, the
/// run-time series chains, `GreyBox<AnyPhysics>`), and every one of those evaluates on any
/// scalar — `AnyNonlinearity` dispatches a template call through its variant, run-time physics
/// has `TraceScalar` overloads — so the tracer of codegen/trace_scalar.hpp runs through them as
/// through the compile-time types. The generated code is the same as for the compile-time
/// model with the same parameters, and reproduces `load_model(path).simulate(...)` to the last
/// bits (tested through nlid-codegen and nlid-sim).
///
/// Kinds: "nlarx", "hammerstein_wiener", "series" (LNL, LN, NL, NLN, NLNL), "greybox"
/// (catalogue or registered physics; `CodegenOptions::ts` is required, the model is
/// continuous), "augmented_greybox" (a diagnosis' repaired model, codegen/augmented.hpp), "arx"
/// and "output_error" (codegen/linear.hpp). State-space models are not generated; asking for
/// them is an `nlid::Error` that names the kind and lists the supported ones.
///
/// A model file that records the range of its estimation data (`data_range`, written by
/// nlid-fit) gets it in the header as NAME_INPUTi_MIN / _MAX and NAME_OUTPUTi_MIN / _MAX
/// (`codegen::add_data_range`): where the model was fitted, for the caller to check or clamp
/// the inputs against — outside it a nonlinear model extrapolates.

#include <concepts>
#include <string>
#include <vector>

#include "nlid/codegen/augmented.hpp"
#include "nlid/codegen/emitter.hpp"
#include "nlid/codegen/greybox.hpp"
#include "nlid/codegen/hammerstein_wiener.hpp"
#include "nlid/codegen/linear.hpp"
#include "nlid/codegen/nlarx.hpp"
#include "nlid/codegen/series.hpp"
#include "nlid/io/augmented_serial.hpp"
#include "nlid/io/series_serial.hpp"
#include "nlid/models/any_model.hpp"
#include "nlid/models/greybox_dynamic.hpp"

namespace nlid {

namespace codegen {

/// Adds the range of the estimation data to a generated header, after the size macros:
/// `NAME_INPUTi_MIN`, `NAME_INPUTi_MAX` (i = 0 … n_u − 1, the index into NAME_step's u) and
/// `NAME_OUTPUTi_MIN`, `NAME_OUTPUTi_MAX`, as literals of the code's precision (float literals
/// in single precision, so comparing a NAME_real with them promotes nothing). Nothing is added
/// when both lists are empty.
inline void add_data_range(GeneratedCode& g, const std::vector<ChannelRange>& inputs, const std::vector<ChannelRange>& outputs,
                           Precision precision, const std::vector<std::string>& input_names = {},
                           const std::vector<std::string>& output_names = {}) {
  if (inputs.empty() && outputs.empty()) return;
  const PrecisionScope scope(precision);
  const std::string M = macro(g.name);
  std::string block =
      "/* Where the model was fitted: the range of each input and output in its estimation data.\n"
      "   Outside it the model extrapolates (its output need not mean anything): check or clamp u. */\n";
  auto add = [&](const char* what, const std::vector<ChannelRange>& r, const std::vector<std::string>& names) {
    for (std::size_t i = 0; i < r.size(); ++i) {
      const std::string base = "#define " + M + "_" + what + std::to_string(i);
      const std::string note = i < names.size() && !names[i].empty() ? " /* " + comment_text(names[i]) + " */" : "";
      block += base + "_MIN " + c_literal(r[i].lower) + note + "\n";
      block += base + "_MAX " + c_literal(r[i].upper) + note + "\n";
    }
  };
  add("INPUT", inputs, input_names);
  add("OUTPUT", outputs, output_names);
  const std::string anchor = "/* The type of every real value";
  const std::size_t at = g.header.find(anchor);
  require(at != std::string::npos, "codegen: the generated header has no place for the data range", at_parameter("header"));
  g.header.insert(at, ascii_text(block) + "\n");
}

}  // namespace codegen

namespace detail {
/// generate_c(AnyModel) without the data range: dispatch to the run-time type.
template <class Handle>
  requires std::same_as<Handle, AnyModel>
GeneratedCode generate_c_kind(const Handle& model, const CodegenOptions& options) {
  require(!model.empty(), "codegen: the model handle is empty", at_parameter("model"));
  if (const auto* m = model.template target<DynamicNlarx>()) return generate_c(*m, options);
  if (const auto* m = model.template target<DynamicHammersteinWiener>()) return generate_c(*m, options);
  if (const auto* m = model.template target<DynamicWienerHammerstein>()) return generate_c(*m, options);
  if (const auto* m = model.template target<DynamicWienerSeries>()) return generate_c(*m, options);
  if (const auto* m = model.template target<DynamicHammersteinSeries>()) return generate_c(*m, options);
  if (const auto* m = model.template target<DynamicHammersteinWienerSeries>()) return generate_c(*m, options);
  if (const auto* m = model.template target<DynamicNLNLSeries>()) return generate_c(*m, options);
  if (const auto* m = model.template target<DynamicGreyBox>()) {
    CodegenOptions o = options;
    if (!(o.ts > 0) && model.ts() > 0) o.ts = model.ts();
    return generate_c(*m, o);
  }
  if (const auto* m = model.template target<AugmentedModel<AnyPhysics>>()) return generate_c(*m, options);
  if (const auto* m = model.template target<Arx>()) return generate_c(*m, options);
  if (const auto* m = model.template target<OutputError>()) return generate_c(*m, options);
  throw Error("codegen: models of kind '" + model.kind() +
                  "' are not generated (generated kinds: nlarx, hammerstein_wiener, series, greybox, "
                  "augmented_greybox, arx, output_error)",
              at_parameter("model"));
}
}  // namespace detail

namespace detail {
/// nlid's state as the generated state, for kinds whose C keeps nlid's layout (nlarx, grey box).
inline Eigen::VectorXd same_layout_state(int n, const Eigen::VectorXd& x, const std::string& kind) {
  require(x.size() == n,
          "codegen: the state has " + std::to_string(x.size()) + " values, the " + kind + " model has " + std::to_string(n),
          at_parameter("x"));
  return x;
}
}  // namespace detail

/// The state of the C code `generate_c(model, options)` generates for nlid's state `x` of the
/// model held by `model` (the x0 its `simulate` takes; ARX and output-error models: their past
/// samples) — the values to pass to NAME_set_state, mapped as the typed `generated_c_state`
/// overloads do (nonlinear ARX and grey-box code keep nlid's layout). Throws `nlid::Error` for
/// an empty handle, a kind that is not generated, or an `x` of the wrong size.
template <class Handle>
  requires std::same_as<Handle, AnyModel>
Eigen::VectorXd generated_c_state(const Handle& model, const Eigen::VectorXd& x, const CodegenOptions& options = {}) {
  require(!model.empty(), "codegen: the model handle is empty", at_parameter("model"));
  if (const auto* m = model.template target<DynamicNlarx>()) return detail::same_layout_state(m->state_dimension(), x, "nlarx");
  if (const auto* m = model.template target<DynamicGreyBox>()) return detail::same_layout_state(m->state_dimension(), x, "grey-box");
  if (const auto* m = model.template target<DynamicHammersteinWiener>()) return generated_c_state(*m, x, options);
  if (const auto* m = model.template target<DynamicWienerHammerstein>()) return generated_c_state(*m, x, options);
  if (const auto* m = model.template target<DynamicWienerSeries>()) return generated_c_state(*m, x, options);
  if (const auto* m = model.template target<DynamicHammersteinSeries>()) return generated_c_state(*m, x, options);
  if (const auto* m = model.template target<DynamicHammersteinWienerSeries>()) return generated_c_state(*m, x, options);
  if (const auto* m = model.template target<DynamicNLNLSeries>()) return generated_c_state(*m, x, options);
  if (const auto* m = model.template target<AugmentedModel<AnyPhysics>>()) return generated_c_state(*m, x, options);
  if (const auto* m = model.template target<Arx>()) return generated_c_state(*m, x, options);
  if (const auto* m = model.template target<OutputError>()) return generated_c_state(*m, x, options);
  throw Error("codegen: models of kind '" + model.kind() + "' are not generated, so they have no generated state",
              at_parameter("model"));
}

/// Generates C99 code for the model held by `model` (see the file comment), with the
/// estimation data's range in the header when the model records it. Throws
/// `nlid::Error` for an empty handle, a kind that is not generated (naming it), a grey box
/// without `options.ts`, and everything the typed `generate_c` overloads throw.
/// (A template on the handle's type, which must be `AnyModel`, so that every expression below is
/// dependent and compiled only where the function is called: it instantiates the tracer for every
/// run-time model family — about 30 s of g++ time that `nlid/nlid.hpp` paid in every program
/// while this was a `template <int = 0>` with non-dependent calls.)
template <class Handle>
  requires std::same_as<Handle, AnyModel>
GeneratedCode generate_c(const Handle& model, const CodegenOptions& options = {}) {
  GeneratedCode g = detail::generate_c_kind(model, options);
  codegen::add_data_range(g, model.info().input_range, model.info().output_range, options.precision, model.input_names(),
                          model.output_names());
  return g;
}

}  // namespace nlid
