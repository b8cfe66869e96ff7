#pragma once
/// @file
/// C code for a series chain `Series<Blocks...>` (Wiener–Hammerstein L–N–L, Wiener L–N,
/// Hammerstein N–L, N–L–N): the blocks traced in chain order into one step function.
///
/// Generated state (NAME_NUM_STATES = Σ states of the linear blocks): the stacked state of
/// nlid's `Series`, each linear block's transposed-direct-form-II registers in chain order.
/// NAME_step passes u(t) through the blocks — a static block maps the value, a linear block
/// outputs b0·v + s1 and shifts its registers — exactly the loop body of `Series::simulate`,
/// so the generated code and nlid agree to the last bits (same operations, same order).
/// With `CodegenOptions::equilibrium_input` NAME_init starts in the chain's steady state for
/// that constant input (`Series::equilibrium_state`), else at rest.

#include <span>
#include <string>
#include <vector>

#include "nlid/codegen/emitter.hpp"
#include "nlid/codegen/trace_scalar.hpp"
#include "nlid/models/series.hpp"

namespace nlid {

/// Generates C99 code for a series chain (see the file comment and emitter.hpp for the
/// interface). Throws `nlid::Error` on a bad name, a missing sample time, or a traced branch
/// count above `CodegenOptions::limits`.
template <SeriesBlock... Blocks>
GeneratedCode generate_c(const Series<Blocks...>& model, const CodegenOptions& options = {}) {
  const codegen::PrecisionScope precision(options.precision);
  codegen::check_name(options.name);
  codegen::ModelShape m;
  m.name = options.name;
  m.kind = "series (" + model.pattern() + ")";
  m.description = model.describe();
  m.nx = model.state_dimension();
  m.nu = 1;
  m.ny = 1;
  m.ts = options.ts > 0 ? options.ts : model.ts();
  require(m.ts > 0, "codegen: the model has no sample time; set it (set_ts) or CodegenOptions::ts", at_parameter("ts"));
  m.parameters = model.parameters();
  m.parameter_names = model.parameter_names();
  m.state_doc = "the linear blocks' registers in chain order (transposed direct form II):";
  for (std::size_t k = 0; k < Series<Blocks...>::num_blocks; ++k) {
    const int n = model.state_offset(k + 1) - model.state_offset(k);
    if (n > 0)
      m.state_doc += " x[" + std::to_string(model.state_offset(k)) + ".." + std::to_string(model.state_offset(k + 1) - 1) +
                     "] " + model.block_label(k) + ";";
  }
  if (m.nx == 0) m.state_doc += " none";
  const std::span<const double> theta(model.parameters().data(), static_cast<std::size_t>(model.parameters().size()));
  if (options.equilibrium_input) {
    require(options.equilibrium_input->size() == 1,
            "codegen: a series model has one input; equilibrium_input has " +
                std::to_string(options.equilibrium_input->size()) + " values",
            at_parameter("equilibrium_input"));
    const double u0 = (*options.equilibrium_input)(0);
    m.x0 = model.template equilibrium_state<double>(u0, theta);
    std::vector<double> s(m.x0.data(), m.x0.data() + m.x0.size());
    const double y0 = model.step(std::span<double>(s), u0, theta);
    m.x0_doc = "the steady state for u held at " + detail::format_value(u0, 17) + " (y = " + detail::format_value(y0, 17) + ")";
  } else {
    m.x0 = Eigen::VectorXd::Zero(m.nx);
    m.x0_doc = "zero (every linear block at rest)";
  }
  const int nx = m.nx;
  const std::string name = m.name;
  const codegen::TracedFunction f = codegen::trace_paths(
      [&] {
        std::vector<TraceScalar> s = codegen::signals("s->x", nx);
        const std::vector<TraceScalar> th = codegen::parameters(name, theta);
        std::vector<TraceScalar> out;
        out.push_back(model.step(std::span<TraceScalar>(s), TraceScalar::signal("u[0]"), std::span<const TraceScalar>(th)));
        out.insert(out.end(), s.begin(), s.end());
        return out;
      },
      options.limits);
  GeneratedCode g;
  g.name = name;
  g.paths = f.paths;
  g.header = codegen::ascii_text(codegen::make_header(m));
  g.source = codegen::ascii_text(codegen::make_source_prelude(m, f.helpers) + codegen::discrete_step_function(m, f));
  return g;
}

}  // namespace nlid
