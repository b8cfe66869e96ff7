#pragma once
/// @file
/// C code for a Hammerstein–Wiener model: input map f, linear block B/F (transposed direct
/// form II, the state nlid uses) and output map h, traced into one step function:
///
///     w = f(u(t)),   x(t) = β₀ w + s₁,   s ← next block state,   y(t) = h(x(t)).
///
/// Generated state (NAME_NUM_STATES = max(nf, nk + nb − 1)): the linear block's state s, the
/// x0 of `HammersteinWiener::simulate`. NAME_init gives the block at rest (the study's `nlhw2`,
/// initial state zero) or, with `CodegenOptions::equilibrium_input`, its steady state for that
/// input. Saturation, dead zone and piecewise-linear maps become nested if/else on the signal
/// (their branches are explored while tracing; see trace_scalar.hpp).
///
/// Single precision: the linear block is written in delta-operator form by default
/// (`CodegenOptions::linear_form`, delta_form.hpp), with the δ state e = T s as the generated
/// state (`generated_c_state` maps an nlid state to it); NAME_x0 is T applied to the state above.

#include <optional>
#include <span>
#include <string>
#include <vector>

#include "nlid/codegen/delta_form.hpp"
#include "nlid/codegen/emitter.hpp"
#include "nlid/codegen/trace_scalar.hpp"
#include "nlid/core/format.hpp"
#include "nlid/models/equilibrium.hpp"
#include "nlid/models/hammerstein_wiener.hpp"

namespace nlid {

namespace codegen::detail {
/// The δ form of a Hammerstein–Wiener model's linear block, if `o` asks for it and it applies.
template <class In, class L, class Out>
std::optional<DeltaBlock> hw_delta_block(const HammersteinWiener<In, L, Out>& model, const CodegenOptions& o) {
  if (!use_delta_form(o) || !delta_applies(model.linear_block())) return std::nullopt;
  return delta_block(model.linear_block(), model.linear_parameters());
}
}  // namespace codegen::detail

/// The state of the C code `generate_c(model, options)` generates for nlid's state `x`
/// (`state_dimension()` values, the x0 of `simulate`): `x` itself in the direct form, its δ
/// state (delta_form.hpp) in the delta form — the values to pass to NAME_set_state.
template <class In, class L, class Out>
Eigen::VectorXd generated_c_state(const HammersteinWiener<In, L, Out>& model, const Eigen::VectorXd& x,
                                  const CodegenOptions& options = {}) {
  require(x.size() == model.state_dimension(),
          "codegen: the state has " + std::to_string(x.size()) + " values, the model has " +
              std::to_string(model.state_dimension()),
          at_parameter("x"));
  const auto db = codegen::detail::hw_delta_block(model, options);
  return db ? db->state_from_tdf2(x) : x;
}

/// Generates C99 code for a Hammerstein–Wiener model (see the file comment and emitter.hpp).
template <class In, class L, class Out>
GeneratedCode generate_c(const HammersteinWiener<In, L, Out>& model, const CodegenOptions& options = {}) {
  const codegen::PrecisionScope precision(options.precision);
  codegen::check_name(options.name);
  codegen::ModelShape m;
  m.name = options.name;
  m.kind = "Hammerstein-Wiener";
  m.description = model.describe();
  m.nx = model.state_dimension();
  m.nu = 1;
  m.ny = 1;
  m.ts = codegen::sampled_model_ts(model.ts(), options.ts);
  require(m.ts > 0, "codegen: the model has no sample time; set it (set_ts) or CodegenOptions::ts", at_parameter("ts"));
  m.parameters = model.parameters();
  m.parameter_names = model.parameter_names();
  const std::optional<codegen::DeltaBlock> db = codegen::detail::hw_delta_block(model, options);
  m.state_doc = "the linear block's state s1 .. s" + std::to_string(m.nx) +
                " (transposed direct form II: x(t) = b0*w(t) + s1(t))";
  if (db)
    m.state_doc = "the linear block's state e1 .. e" + std::to_string(m.nx) +
                  " in delta-operator form (single precision): x(t) = c0*w(t) + e1(t), e_i(t+1) = e_i(t) + "
                  "e_(i+1)(t) + c_i*w(t) - a_i*x(t) with d = q - 1 and B(z)/F(z) = (c0 d^n + .. + cn)/(d^n + a1 "
                  "d^(n-1) + .. + an), " + db->describe() +
                  ". In terms of nlid's transposed-direct-form-II state s (x(t) = b0*w(t) + s1(t)): "
                  "e_i = sum over j <= i of C(n-j, i-j)*s_j (the coefficients of s1 z^(n-1) + .. + sn "
                  "in powers of z - 1; e1 = s1, en = s1 + .. + sn)";
  if (const auto x = codegen::given_initial_state(options, m.nx, "the linear block's registers", m)) {
    m.x0 = *x;
  } else if (options.equilibrium_input) {
    const OperatingPoint op = equilibrium(model, *options.equilibrium_input);
    m.x0 = op.x;
    m.x0_doc = "the steady state for u held at " + detail::format_g((*options.equilibrium_input)(0), 17) +
               " (y = " + detail::format_g(op.y(0), 17) + ")";
  } else {
    m.x0 = Eigen::VectorXd::Zero(m.nx);
    m.x0_doc = "zero (the linear block at rest)";
  }
  if (db) m.x0 = db->state_from_tdf2(m.x0);
  const int nx = m.nx;
  const std::string name = m.name;
  const int off_l = model.linear_offset(), off_h = model.output_offset();
  const codegen::TracedFunction f = codegen::trace_paths(
      [&] {
        std::vector<TraceScalar> s = codegen::signals("s->x", nx);
        const TraceScalar u = TraceScalar::signal("u[0]");
        const std::vector<TraceScalar> tf = codegen::parameters(name, model.input_parameters(), 0);
        const std::vector<TraceScalar> tl = codegen::parameters(name, model.linear_parameters(), off_l);
        const std::vector<TraceScalar> th = codegen::parameters(name, model.output_parameters(), off_h);
        const TraceScalar w = model.input_nonlinearity()(std::span<const TraceScalar>(&u, 1), std::span<const TraceScalar>(tf));
        const TraceScalar x = db ? db->step(std::span<TraceScalar>(s), w)
                                 : model.linear_block().step(std::span<TraceScalar>(s), w, std::span<const TraceScalar>(tl));
        std::vector<TraceScalar> out;
        out.push_back(model.output_nonlinearity()(std::span<const TraceScalar>(&x, 1), std::span<const TraceScalar>(th)));
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
