#pragma once
/// @file
/// Umbrella header of nlid's C code generation: `generate_c(model, options)` for ARX,
/// output-error, nonlinear ARX, Hammerstein–Wiener, series (Wiener–Hammerstein, Wiener,
/// Hammerstein), grey-box and augmented grey-box models, compile-time types or a run-time
/// `AnyModel` loaded from a file
/// (dependency-free C99 header + source with `NAME_init` / `NAME_step`), built on the tracing
/// scalar `TraceScalar`. See docs/codegen.md.

#include "nlid/codegen/any_model.hpp"
#include "nlid/codegen/augmented.hpp"
#include "nlid/codegen/emitter.hpp"
#include "nlid/codegen/greybox.hpp"
#include "nlid/codegen/hammerstein_wiener.hpp"
#include "nlid/codegen/linear.hpp"
#include "nlid/codegen/nlarx.hpp"
#include "nlid/codegen/series.hpp"
#include "nlid/codegen/trace_scalar.hpp"
