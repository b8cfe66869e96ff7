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
///
/// Single precision: every linear block with feedback is written in delta-operator form by
/// default (`CodegenOptions::linear_form`, delta_form.hpp); its registers are then its δ state
/// e = T s (`generated_c_state` maps an nlid state), NAME_x0 is T applied block by block.

#include <cstddef>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "nlid/codegen/delta_form.hpp"
#include "nlid/codegen/emitter.hpp"
#include "nlid/codegen/trace_scalar.hpp"
#include "nlid/core/format.hpp"
#include "nlid/models/series.hpp"

namespace nlid {

namespace codegen::detail {
/// Per block of the chain: its δ form if `o` asks for it and it applies (linear with feedback).
template <SeriesBlock... Blocks>
std::vector<std::optional<DeltaBlock>> series_delta_blocks(const Series<Blocks...>& model, const CodegenOptions& o) {
  using S = Series<Blocks...>;
  std::vector<std::optional<DeltaBlock>> d(S::num_blocks);
  if (!use_delta_form(o)) return d;
  [&]<std::size_t... I>(std::index_sequence<I...>) {
    (
        [&] {
          if constexpr (S::template is_linear<I>) {
            const auto& b = model.template block<I>();
            if (delta_applies(b)) d[I] = delta_block(b, model.block_parameters(I));
          }
        }(),
        ...);
  }(std::index_sequence_for<Blocks...>{});
  return d;
}

/// One traced sample of the chain with the linear blocks in `deltas` in δ form (the others as
/// `Series::step` runs them).
template <SeriesBlock... Blocks>
TraceScalar series_delta_step(const Series<Blocks...>& model, const std::vector<std::optional<DeltaBlock>>& deltas,
                              std::span<TraceScalar> s, TraceScalar v, std::span<const TraceScalar> theta) {
  using S = Series<Blocks...>;
  [&]<std::size_t... I>(std::index_sequence<I...>) {
    (
        [&] {
          const auto& b = model.template block<I>();
          const std::span<const TraceScalar> th = theta.subspan(static_cast<std::size_t>(model.parameter_offset(I)),
                                                                static_cast<std::size_t>(model.block_num_parameters(I)));
          if constexpr (S::template is_linear<I>) {
            const std::span<TraceScalar> sk =
                s.subspan(static_cast<std::size_t>(model.state_offset(I)),
                          static_cast<std::size_t>(model.state_offset(I + 1) - model.state_offset(I)));
            v = deltas[I] ? deltas[I]->step(sk, v) : b.step(sk, v, th);
          } else {
            const TraceScalar x = v;
            v = b(std::span<const TraceScalar>(&x, 1), th);
          }
        }(),
        ...);
  }(std::index_sequence_for<Blocks...>{});
  return v;
}

/// `x` (nlid's stacked state) with each δ block's segment replaced by its δ state.
template <SeriesBlock... Blocks>
Eigen::VectorXd series_delta_state(const Series<Blocks...>& model, const std::vector<std::optional<DeltaBlock>>& deltas,
                                   Eigen::VectorXd x) {
  for (std::size_t k = 0; k < deltas.size(); ++k) {
    if (!deltas[k]) continue;
    const int off = model.state_offset(k), n = model.state_offset(k + 1) - off;
    x.segment(off, n) = deltas[k]->state_from_tdf2(x.segment(off, n));
  }
  return x;
}
}  // namespace codegen::detail

/// The state of the C code `generate_c(model, options)` generates for nlid's state `x`
/// (`state_dimension()` values, the x0 of `simulate`): `x` itself in the direct form; with
/// δ-form blocks, each one's segment replaced by its δ state (delta_form.hpp) — the values to pass
/// to NAME_set_state.
template <SeriesBlock... Blocks>
Eigen::VectorXd generated_c_state(const Series<Blocks...>& model, const Eigen::VectorXd& x,
                                  const CodegenOptions& options = {}) {
  require(x.size() == model.state_dimension(),
          "codegen: the state has " + std::to_string(x.size()) + " values, the model has " +
              std::to_string(model.state_dimension()),
          at_parameter("x"));
  return codegen::detail::series_delta_state(model, codegen::detail::series_delta_blocks(model, options), x);
}

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
  m.ts = codegen::sampled_model_ts(model.ts(), options.ts);
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
  const std::vector<std::optional<codegen::DeltaBlock>> deltas = codegen::detail::series_delta_blocks(model, options);
  bool any_delta = false;
  for (std::size_t k = 0; k < deltas.size(); ++k) {
    if (!deltas[k]) continue;
    if (!any_delta)
      m.state_doc += "\nSingle precision, delta-operator form (d = q - 1) of the linear block(s) with feedback:";
    any_delta = true;
    m.state_doc += " x[" + std::to_string(model.state_offset(k)) + ".." + std::to_string(model.state_offset(k + 1) - 1) +
                   "] (" + model.block_label(k) + ": " + deltas[k]->describe() + ")";
  }
  if (any_delta)
    m.state_doc += " hold e1 .. en instead of the registers s1 .. sn: v_out(t) = c0*v_in(t) + e1(t), e_i(t+1) = "
                   "e_i(t) + e_(i+1)(t) + c_i*v_in(t) - a_i*v_out(t), with B(z)/F(z) = (c0 d^n + .. + cn)/(d^n + a1 "
                   "d^(n-1) + .. + an); e_i = sum over j <= i of C(n-j, i-j)*s_j (the coefficients of s1 z^(n-1) + .. "
                   "+ sn in powers of z - 1; e1 = s1, en = s1 + .. + sn)";
  const std::span<const double> theta(model.parameters().data(), static_cast<std::size_t>(model.parameters().size()));
  if (const auto x = codegen::given_initial_state(options, m.nx, "the linear blocks' registers in chain order", m)) {
    m.x0 = *x;
  } else if (options.equilibrium_input) {
    require(options.equilibrium_input->size() == 1,
            "codegen: a series model has one input; equilibrium_input has " +
                std::to_string(options.equilibrium_input->size()) + " values",
            at_parameter("equilibrium_input"));
    const double u0 = (*options.equilibrium_input)(0);
    m.x0 = model.template equilibrium_state<double>(u0, theta);
    std::vector<double> s(m.x0.data(), m.x0.data() + m.x0.size());
    const double y0 = model.step(std::span<double>(s), u0, theta);
    m.x0_doc = "the steady state for u held at " + detail::format_g(u0, 17) + " (y = " + detail::format_g(y0, 17) + ")";
  } else {
    m.x0 = Eigen::VectorXd::Zero(m.nx);
    m.x0_doc = "zero (every linear block at rest)";
  }
  if (any_delta) m.x0 = codegen::detail::series_delta_state(model, deltas, m.x0);
  const int nx = m.nx;
  const std::string name = m.name;
  const codegen::TracedFunction f = codegen::trace_paths(
      [&] {
        std::vector<TraceScalar> s = codegen::signals("s->x", nx);
        const std::vector<TraceScalar> th = codegen::parameters(name, theta);
        std::vector<TraceScalar> out;
        const TraceScalar u = TraceScalar::signal("u[0]");
        out.push_back(any_delta ? codegen::detail::series_delta_step(model, deltas, std::span<TraceScalar>(s), u,
                                                                     std::span<const TraceScalar>(th))
                                : model.step(std::span<TraceScalar>(s), u, std::span<const TraceScalar>(th)));
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
