#pragma once
/// @file
/// C code for a grey-box model `GreyBox<P>`: the physics' f and g traced into C functions, and
/// the same zero-order-hold integrator nlid simulates with (classical RK4 or Euler, the same
/// number of sub-steps, the same operation order), so the generated step reproduces
/// `GreyBox::simulate` to rounding:
///
///     y(t_k) = g(x_k, u_k, p)
///     x_{k+1} = Φ(x_k, u_k): n sub-steps of h = T_s/n,   k₁ = f(x), k₂ = f(x + h/2·k₁),
///               k₃ = f(x + h/2·k₂), k₄ = f(x + h·k₃),   x ← x + h/6·((k₁ + k₄) + 2(k₂ + k₃))
///
/// (Hairer, Nørsett & Wanner 1993, Table 1.2; n from nlid's sub-step rule, integrators.hpp).
/// The physics is written once as `template <class T> derivative(...)`; tracing it on
/// `TraceScalar` emits its C, including its branches (a smoothed hard stop becomes an if/else
/// on the penetration) — grey-box code generation the toolbox did not offer.
///
/// Generated state: the physical state x (names in the header). NAME_init starts at the
/// equilibrium for `CodegenOptions::equilibrium_input` if given (solved at generation time by
/// `physics_equilibrium`, as `InitialCondition::equilibrium` does), else at zero.
///
/// Limits: the adaptive Dormand–Prince method is not generated (its step sequence depends on
/// the data). Run-time physics (`GreyBox<AnyPhysics>`, e.g. a model loaded from a file) is
/// traced through its `TraceScalar` overloads (`RuntimePhysics`, greybox_dynamic.hpp); a
/// run-time physics that does not provide them, or a compile-time physics that is not templated
/// on its scalar, is reported as `nlid::Error`.

#include <span>
#include <string>
#include <type_traits>
#include <vector>

#include "nlid/codegen/emitter.hpp"
#include "nlid/codegen/trace_scalar.hpp"
#include "nlid/core/format.hpp"
#include "nlid/models/equilibrium.hpp"
#include "nlid/models/greybox.hpp"
#include "nlid/models/greybox_simulate.hpp"

namespace nlid {

namespace codegen::detail {
/// A physics whose f and g can be evaluated on `TraceScalar` (compile-time, templated physics).
template <class P>
concept TraceablePhysics = requires(const P& p, const TraceScalar* x, TraceScalar* out) {
  p.derivative(x, x, x, out);
  p.output(x, x, x, out);
};
}  // namespace codegen::detail

/// Generates C99 code for a grey-box model at sample time `options.ts` (required). Throws
/// `nlid::Error` for a missing sample time, the adaptive integrator, an untraceable physics, a
/// missing equilibrium, or a bad name.
template <class P>
GeneratedCode generate_c(const GreyBox<P>& model, const CodegenOptions& options) {
  const codegen::PrecisionScope precision(options.precision);
  codegen::check_name(options.name);
  if constexpr (!codegen::detail::TraceablePhysics<P>) {
    throw Error("codegen: the physics of grey-box model '" + model.name() +
                    "' cannot be traced: its derivative/output do not accept TraceScalar (write them as templates on "
                    "the scalar, as for Dual)",
                at_parameter("physics"));
  } else {
    require(options.ts > 0 && std::isfinite(options.ts),
            "codegen: a grey-box model is continuous; set CodegenOptions::ts to the sample time of the generated step",
            at_parameter("ts"));
    const IntegratorOptions& io = model.integrator();
    require(io.method != IntegratorMethod::dormand_prince,
            "codegen: the adaptive Dormand-Prince integrator is not generated; use IntegratorMethod::rk4 (or euler) "
            "with fixed sub-steps",
            at_parameter("integrator"));
    codegen::ModelShape m;
    m.name = options.name;
    m.kind = "grey-box (" + model.name() + ")";
    m.description = model.describe();
    m.nx = model.state_dimension();
    m.nu = model.input_dimension();
    m.ny = model.output_dimension();
    m.ts = options.ts;
    const Eigen::VectorXd pv = model.parameters();
    // set_parameter edits one value at a time without the physics' relations (lower stop below
    // the upper): code for a model that violates them would run with impossible physics.
    physics_check_parameters(model.physics(), pv.data(), "code generation for grey-box model '" + model.name() + "'");
    m.parameters = pv;
    m.parameter_names = model.parameter_names();
    m.state_doc = "the physical state x = [";
    for (std::size_t i = 0; i < model.state_info().size(); ++i) m.state_doc += (i ? ", " : "") + model.state_info()[i].name;
    m.state_doc += "]";
    Eigen::VectorXd u_sub = Eigen::VectorXd::Zero(m.nu);
    if (const auto x = codegen::given_initial_state(options, m.nx, "the physical state", m)) {
      m.x0 = *x;
    } else if (options.equilibrium_input) {
      const OperatingPoint op = equilibrium(model, *options.equilibrium_input);
      m.x0 = op.x;
      u_sub = *options.equilibrium_input;
      m.x0_doc = "the equilibrium " + codegen::held_input_text(*options.equilibrium_input);
    } else {
      m.x0 = Eigen::VectorXd::Zero(m.nx);
      m.x0_doc = "zero";
    }
    // The sub-step count GreyBox::simulate uses from x0 with input u_sub for a physics with a
    // spectral_radius; without one, simulate takes the stiffest state of its record, which the
    // generated step cannot know (docs/codegen.md: pin CodegenOptions::substeps).
    const double rho = physics_spectral_radius(model.physics(), pv.data(), m.x0.data(), u_sub.data());
    const int sub = options.substeps > 0 ? options.substeps : substeps_for(m.ts, rho, io);
    // A step the method cannot keep stable, from the automatic rule at its ceiling or from a
    // count the caller gave, would blow up on the target, far from any message. Say it here.
    if (options.substeps > 0) {
      const double need = unstable_fixed_substeps(m.ts, rho, sub, io.method);
      if (need > 0.0) {
        throw Error("grey-box code generation: CodegenOptions::substeps = " + std::to_string(sub) +
                        " gives an unstable integrator step at the start state (spectral radius " +
                        detail::format_g(rho) + " 1/s, sample time " + detail::format_g(m.ts) + " s); it needs at least " +
                        detail::format_g(need) + " sub-steps per sample",
                    at_parameter("substeps"));
      }
    }
    const double need = options.substeps == 0 ? unstable_capped_substeps(m.ts, rho, sub, io) : 0.0;
    if (need > 0.0) {
      throw Error("grey-box code generation: at the sample time " + detail::format_g(m.ts) +
                      " s the model's stiffness (spectral radius " + detail::format_g(rho) +
                      " 1/s) needs " + detail::format_g(need) +
                      " integrator sub-steps per sample for a stable step, more than the ceiling of " +
                      std::to_string(io.max_substeps) + "; use a shorter sample time or set CodegenOptions::substeps",
                  at_parameter("ts"));
    }
    const std::string name = m.name;
    const auto pspan = std::span<const double>(pv.data(), static_cast<std::size_t>(pv.size()));
    const int nx = m.nx, nu = m.nu, ny = m.ny;
    const auto& phys = model.physics();
    const codegen::TracedFunction fd = codegen::trace_paths(
        [&] {
          const std::vector<TraceScalar> x = codegen::signals("x", nx), u = codegen::signals("u", nu),
                                         p = codegen::parameters(name, pspan);
          std::vector<TraceScalar> dx(static_cast<std::size_t>(nx));
          phys.derivative(x.data(), u.data(), p.data(), dx.data());
          return dx;
        },
        options.limits);
    const codegen::TracedFunction fg = codegen::trace_paths(
        [&] {
          const std::vector<TraceScalar> x = codegen::signals("x", nx), u = codegen::signals("u", nu),
                                         p = codegen::parameters(name, pspan);
          std::vector<TraceScalar> y(static_cast<std::size_t>(ny));
          phys.output(x.data(), u.data(), p.data(), y.data());
          return y;
        },
        options.limits);
    std::set<std::string> helpers = fd.helpers;
    helpers.insert(fg.helpers.begin(), fg.helpers.end());
    const std::string M = codegen::macro(name), N = std::to_string(nx), R = codegen::c_real();
    std::string src = codegen::make_source_prelude(m, helpers);
    src += "#define " + M + "_SUBSTEPS " + std::to_string(sub) + " /* integrator sub-steps per sample */\n\n";
    std::string equation = "the physics";
    if constexpr (detail::HasEquation<P>) equation = phys.equation();
    src += "/* dx = f(x, u, p): " + codegen::comment_text(equation) +
           " */\nstatic void " + name + "_derivative(const " + R + "* x, const " + R + "* u, " + R + "* dx) {\n  (void)x;\n  (void)u;\n" +
           codegen::emit_c(fd, codegen::targets("dx", nx), "  ") + "}\n\n";
    src += "/* y = g(x, u, p) */\nstatic void " + name + "_output(const " + R + "* x, const " + R + "* u, " + R + "* y) {\n  (void)x;\n  (void)u;\n" +
           codegen::emit_c(fg, codegen::targets("y", ny), "  ") + "}\n\n";
    src += codegen::model_step_head(name);
    src += "  const " + R + " h = " + M + "_SAMPLE_TIME / " + M + "_SUBSTEPS;\n";
    src += "  " + R + " k1[" + N + "], k2[" + N + "], k3[" + N + "], k4[" + N + "], tmp[" + N + "];\n  int i, j;\n";
    src += "  " + name + "_output(s->x, u, y);\n";
    if (io.method == IntegratorMethod::euler) {
      src += "  (void)k2;\n  (void)k3;\n  (void)k4;\n  (void)tmp;\n";
      src += "  for (i = 0; i < " + M + "_SUBSTEPS; ++i) {\n    " + name + "_derivative(s->x, u, k1);\n";
      src += "    for (j = 0; j < " + N + "; ++j) s->x[j] += h * k1[j];\n  }\n}\n";
    } else {
      src += "  {\n    const " + R + " half = " + codegen::c_literal(0.5) + " * h, sixth = h / " + codegen::c_literal(6.0) + ";\n";
      src += "    for (i = 0; i < " + M + "_SUBSTEPS; ++i) {\n";
      src += "      " + name + "_derivative(s->x, u, k1);\n";
      src += "      for (j = 0; j < " + N + "; ++j) tmp[j] = s->x[j] + half * k1[j];\n";
      src += "      " + name + "_derivative(tmp, u, k2);\n";
      src += "      for (j = 0; j < " + N + "; ++j) tmp[j] = s->x[j] + half * k2[j];\n";
      src += "      " + name + "_derivative(tmp, u, k3);\n";
      src += "      for (j = 0; j < " + N + "; ++j) tmp[j] = s->x[j] + h * k3[j];\n";
      src += "      " + name + "_derivative(tmp, u, k4);\n";
      src += "      for (j = 0; j < " + N + "; ++j) {\n        tmp[j] = k1[j] + k4[j];\n        tmp[j] += " + codegen::c_literal(2.0) + " * (k2[j] + k3[j]);\n"
             "        s->x[j] += sixth * tmp[j];\n      }\n    }\n  }\n}\n";
    }
    GeneratedCode g;
    g.name = name;
    g.paths = fd.paths;
    g.header = codegen::ascii_text(codegen::make_header(m));
    g.source = codegen::ascii_text(src + "\n" + codegen::checked_step_function(name));
    return g;
  }
}

}  // namespace nlid
