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

#include <concepts>
#include <string>

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

/// Generates C99 code for the model held by `model` (see the file comment). Throws
/// `nlid::Error` for an empty handle, a kind that is not generated (naming it), a grey box
/// without `options.ts`, and everything the typed `generate_c` overloads throw.
/// (A template on the handle's type, which must be `AnyModel`, so that every expression below is
/// dependent and compiled only where the function is called: it instantiates the tracer for every
/// run-time model family — about 30 s of g++ time that `nlid/nlid.hpp` paid in every program
/// while this was a `template <int = 0>` with non-dependent calls.)
template <class Handle>
  requires std::same_as<Handle, AnyModel>
GeneratedCode generate_c(const Handle& model, const CodegenOptions& options = {}) {
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

}  // namespace nlid
