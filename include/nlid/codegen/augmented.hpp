#pragma once
/// @file
/// C code for an augmented grey-box model `AugmentedModel<P>` — the model a diagnosis returns
/// (baseline physics + the effects it found, re-estimated), so that the repaired model can be
/// deployed like any other.
///
/// What the generated step does, sample k (the loop body of `AugmentedModel::simulate`, whose
/// pieces `input_chain`, `augmented_derivative`, `output_at` and `friction_after` are traced
/// into static C functions, so the operations and their order are nlid's):
///
///     first sample only: dead-time history ← u(0); w ← u_e(0) (with an actuator lag)
///     u_e = input chain of u(k), u(k−m), u(k−m−1)      (m: whole samples of the dead time)
///     y   = output chain of g(x, w or u_e)             (play starts at g on the first sample)
///     n × RK4 sub-steps of [ẋ; ẇ] with u_e held; Dahl friction updated exactly after each
///     history ← u(k)
///
/// Generated state (NAME_NUM_STATES = n_x + 4 + (m + 1 with a dead time)):
///
///     x[0 … n_x−1]  the baseline's physical state     x[n_x]     actuator state w
///     x[n_x+1]      Dahl friction state               x[n_x+2]   backlash play state
///     x[n_x+3]      1 until the first sample, then 0  x[n_x+4 …] u(k−1), u(k−2), … (dead time)
///
/// NAME_init sets x to the baseline state chosen at generation (zero, the baseline's
/// equilibrium for `CodegenOptions::equilibrium_input`, found as `simulate(e, equilibrium)`
/// finds it, or `CodegenOptions::initial_state`) and the flag to 1; the effect states start from
/// the first sample as in nlid (`generated_c_state` builds such a state for NAME_set_state).
/// The sub-step count is nlid's rule at that state and input (`AugmentedModel::substeps`), or
/// `CodegenOptions::substeps`; a count that leaves RK4 unstable at the start state is refused. Like
/// `simulate`, the C step refuses a sample whose state would become non-finite (return 1).

#include <algorithm>
#include <cmath>
#include <set>
#include <span>
#include <string>
#include <vector>

#include "nlid/codegen/emitter.hpp"
#include "nlid/codegen/trace_scalar.hpp"
#include "nlid/core/format.hpp"
#include "nlid/data/experiment.hpp"
#include "nlid/diagnose/augmented.hpp"
#include "nlid/models/detail/model_common.hpp"
#include "nlid/models/greybox_simulate.hpp"
#include "nlid/models/integrators.hpp"

namespace nlid {

/// The state of the C code `generate_c(model, options)` generates that starts the baseline at
/// `x` (`state_dimension()` values, the x0 of `simulate`) with the effect states started from the
/// first sample, as NAME_init does (file comment) — the values to pass to NAME_set_state.
template <class P>
Eigen::VectorXd generated_c_state(const AugmentedModel<P>& model, const Eigen::VectorXd& x,
                                  const CodegenOptions& /*options*/ = {}) {
  const int nx = model.state_dimension();
  require(x.size() == nx,
          "codegen: the state has " + std::to_string(x.size()) + " values, the baseline has " + std::to_string(nx),
          at_parameter("x"));
  const Eigen::VectorXd theta = model.parameters();
  const int n_hist = model.has_dead_time() ? model.dead_time_samples(theta.data()) + 1 : 0;
  Eigen::VectorXd g = Eigen::VectorXd::Zero(nx + 4 + n_hist);
  g.head(nx) = x;
  g(nx + 3) = 1.0;  // the flag: effect states start from the first sample
  return g;
}

/// Generates C99 code for an augmented grey-box model (see the file comment and emitter.hpp
/// for the interface). `options.ts` must be 0 or the model's sample time (the effects are
/// discrete-time: dead time in samples, updates between sub-steps). Throws `nlid::Error` on a
/// bad name, another sample time, a baseline that cannot be traced, or a missing equilibrium.
template <class P>
GeneratedCode generate_c(const AugmentedModel<P>& model, const CodegenOptions& options = {}) {
  const codegen::PrecisionScope precision(options.precision);
  codegen::check_name(options.name);
  require(options.ts <= 0 || same_sample_time(options.ts, model.ts()),
          "codegen: an augmented grey-box model runs at its own sample time " + detail::format_g(model.ts(), 10) +
              " s (its dead time and friction updates are per sample); CodegenOptions::ts was " +
              detail::format_g(options.ts, 10) + " s",
          at_parameter("ts"));
  const auto& phys = model.physics();
  const int nx = model.state_dimension(), nu = detail::physics_inputs(phys), nc = nx + 1;
  const Eigen::VectorXd theta = model.parameters();
  const std::span<const double> th(theta.data(), static_cast<std::size_t>(theta.size()));
  const bool dead = model.has_dead_time(), lag = model.has_actuator_lag(), dahl = model.has_coulomb_friction();
  const int m_dead = model.dead_time_samples(theta.data());
  const int i_fric = nc, i_play = nc + 1, i_first = nc + 2, i_hist = nc + 3;
  const int n_hist = dead ? m_dead + 1 : 0;

  codegen::ModelShape m;
  m.name = options.name;
  m.kind = "augmented grey-box";
  m.description = model.describe();
  m.nx = i_hist + n_hist;
  m.nu = nu;
  m.ny = 1;
  m.ts = model.ts();
  m.parameters = theta;
  for (const ParameterInfo& q : model.parameter_info()) m.parameter_names.push_back(q.name);
  const auto states = [&] {
    if constexpr (requires { phys.state_info(); }) {
      std::vector<std::string> n;
      for (const auto& s : phys.state_info()) n.push_back(s.name);
      return n;
    } else {
      std::vector<std::string> n;
      for (int i = 0; i < nx; ++i) n.push_back("x" + std::to_string(i + 1));
      return n;
    }
  }();
  m.state_doc = "x = [";
  for (int i = 0; i < nx; ++i) m.state_doc += (i ? ", " : "") + states[static_cast<std::size_t>(i)];
  m.state_doc += "] (the baseline's state), x[" + std::to_string(nx) + "] actuator state w" +
                 (lag ? "" : " (unused: no actuator lag)") + ", x[" + std::to_string(i_fric) + "] Dahl friction state" +
                 (dahl ? "" : " (unused)") + ", x[" + std::to_string(i_play) + "] backlash play state, x[" +
                 std::to_string(i_first) + "] 1 before the first sample" +
                 (dead ? ", x[" + std::to_string(i_hist) + ".." + std::to_string(i_hist + n_hist - 1) +
                             "] past inputs u(t-1), u(t-2), ... for the dead time of " + std::to_string(m_dead) +
                             "+ samples"
                       : "");

  // Baseline state of NAME_init and the input the sub-step rule is evaluated at.
  Eigen::VectorXd xb = Eigen::VectorXd::Zero(nx), u0 = Eigen::VectorXd::Zero(std::max(nu, 1));
  if (const auto x = codegen::given_initial_state(options, nx, "the baseline's state", m)) {
    xb = *x;
    m.x0_doc += " for the baseline; effect states start from the first sample";
  } else if (options.equilibrium_input) {
    require(options.equilibrium_input->size() == nu,
            "codegen: equilibrium_input has " + std::to_string(options.equilibrium_input->size()) +
                " values, the model has " + std::to_string(nu) + " input(s)",
            at_parameter("equilibrium_input"));
    u0.head(nu) = *options.equilibrium_input;
    // As simulate(e, InitialCondition::equilibrium) on a record starting at u0 (output unknown: 0).
    const Experiment e(u0.head(nu).transpose().replicate(2, 1), Eigen::MatrixXd::Zero(2, 1), model.ts());
    xb = model.initial_state_guess(e);
    std::vector<double> p;
    for (const ParameterInfo& q : model.baseline_parameters()) p.push_back(q.value);
    const EquilibriumResult eq = physics_equilibrium(phys, u0.data(), p.data(), xb.data());
    require(eq.converged, "codegen: no equilibrium of the baseline " + codegen::held_input_text(u0.head(nu)),
            at_parameter("equilibrium_input"));
    m.x0_doc = "the baseline's equilibrium " + codegen::held_input_text(u0.head(nu)) +
               "; effect states start from the first sample";
  } else {
    m.x0_doc = "zero baseline state; effect states start from the first sample";
  }
  m.x0 = generated_c_state(model, xb, options);  // the baseline at xb, effects from the first sample
  const double rho = model.stiffness(theta.data(), xb.data(), u0.data());
  const int sub = options.substeps > 0 ? options.substeps : std::max(1, substeps_for(model.ts(), rho, model.integrator()));
  // As for grey boxes (codegen/greybox.hpp): a count that leaves RK4 unstable at the start state,
  // given or from the rule at its ceiling, is refused rather than written.
  if (const double need = unstable_fixed_substeps(model.ts(), rho, sub, IntegratorMethod::rk4); need > 0.0) {
    throw Error("codegen: " + std::string(options.substeps > 0 ? "CodegenOptions::substeps = " : "the model's sub-step count ") +
                    std::to_string(sub) + " per sample gives an unstable RK4 step for this augmented model at the start "
                    "state (stiffness " + detail::format_g(rho) + " 1/s, sample time " + detail::format_g(model.ts()) +
                    " s); it needs at least " + detail::format_g(need) +
                    (options.substeps > 0 ? std::string(" sub-steps") : std::string(" sub-steps: use a shorter sample time")),
                at_parameter(options.substeps > 0 ? "substeps" : "ts"));
  }

  const std::string name = m.name, M = codegen::macro(name);
  // Traced pieces. Inputs of each C function are its parameters' names; outputs go to out[].
  const auto uin_of = [&](TraceScalar first) {
    std::vector<TraceScalar> uin(static_cast<std::size_t>(std::max(nu, 1)));
    uin[0] = first;
    for (int j = 1; j < nu; ++j) uin[static_cast<std::size_t>(j)] = TraceScalar::signal("u[" + std::to_string(j) + "]");
    return uin;
  };
  const codegen::TracedFunction f_in = codegen::trace_paths(
      [&] {
        const std::vector<TraceScalar> p = codegen::parameters(name, th);
        return std::vector<TraceScalar>{model.input_chain(p.data(), TraceScalar::signal("uk"), TraceScalar::signal("ukm"),
                                                          TraceScalar::signal("ukm1"), m_dead)};
      },
      options.limits);
  const codegen::TracedFunction f_dx = codegen::trace_paths(
      [&] {
        const std::vector<TraceScalar> p = codegen::parameters(name, th), x = codegen::signals("x", nc);
        std::vector<TraceScalar> uin = uin_of(TraceScalar(0.0)), dx(static_cast<std::size_t>(nc));
        model.augmented_derivative(x.data(), TraceScalar::signal("ue"), TraceScalar::signal("fric"), p.data(), uin.data(),
                                   dx.data());
        return dx;
      },
      options.limits);
  const auto output_trace = [&](bool first) {
    return codegen::trace_paths(
        [&] {
          const std::vector<TraceScalar> p = codegen::parameters(name, th), x = codegen::signals("x", nc);
          std::vector<TraceScalar> uin = uin_of(TraceScalar(0.0)), yb(static_cast<std::size_t>(detail::physics_outputs(phys)));
          TraceScalar play = TraceScalar::signal("play");
          const TraceScalar y = model.output_at(x.data(), TraceScalar::signal("ue"), p.data(), uin.data(), yb.data(), play, first);
          return std::vector<TraceScalar>{y, play};
        },
        options.limits);
  };
  const codegen::TracedFunction f_out_first = output_trace(true), f_out = output_trace(false);
  const codegen::TracedFunction f_fric = codegen::trace_paths(
      [&] { return std::vector<TraceScalar>{model.friction_after(TraceScalar::signal("fric"), TraceScalar::signal("dq"))}; },
      options.limits);

  std::set<std::string> helpers;
  for (const auto* f : {&f_in, &f_dx, &f_out_first, &f_out, &f_fric}) helpers.insert(f->helpers.begin(), f->helpers.end());
  std::string src = codegen::make_source_prelude(m, helpers);
  const std::string N = std::to_string(nc), R = codegen::c_real();
  src += "#define " + M + "_SUBSTEPS " + std::to_string(sub) + " /* integrator sub-steps per sample */\n";
  if (dead) src += "#define " + M + "_DELAY_SAMPLES " + std::to_string(m_dead) + " /* whole samples of the dead time */\n";
  src += "\n/* u_e: the input chain on u(t), u(t-m), u(t-m-1) */\nstatic " + R + " " + name +
         "_input(" + R + " uk, " + R + " ukm, " + R + " ukm1) {\n  " + R + " out[1];\n  (void)uk;\n  (void)ukm;\n  (void)ukm1;\n" +
         codegen::emit_c(f_in, {"out[0]"}, "  ") + "  return out[0];\n}\n\n";
  src += "/* d[x; w]/dt with u_e held and the Dahl state fric */\nstatic void " + name +
         "_derivative(const " + R + "* x, const " + R + "* u, " + R + " ue, " + R + " fric, " + R + "* dx) {\n"
         "  (void)x;\n  (void)u;\n  (void)ue;\n  (void)fric;\n" +
         codegen::emit_c(f_dx, codegen::targets("dx", nc), "  ") + "}\n\n";
  for (const bool first : {true, false}) {
    src += std::string("/* y through the output chain") + (first ? ", first sample (play starts at the output)" : "") +
           "; out = {y, play} */\nstatic void " + name + (first ? "_output_first" : "_output") +
           "(const " + R + "* x, const " + R + "* u, " + R + " ue, " + R + " play, " + R + "* out) {\n"
           "  (void)x;\n  (void)u;\n  (void)ue;\n  (void)play;\n" +
           codegen::emit_c(first ? f_out_first : f_out, {"out[0]", "out[1]"}, "  ") + "}\n\n";
  }
  if (dahl) {
    src += "/* Dahl friction state after a sub-step that moved the position by dq */\nstatic " + R + " " + name +
           "_friction(" + R + " fric, " + R + " dq) {\n  " + R + " out[1];\n  (void)fric;\n  (void)dq;\n" +
           codegen::emit_c(f_fric, {"out[0]"}, "  ") + "  return out[0];\n}\n\n";
  }
  const std::string X = "s->x";
  src += codegen::model_step_head(name);
  src += "  const " + R + " h = " + M + "_SAMPLE_TIME / " + M + "_SUBSTEPS;\n";
  src += "  const " + R + " half = " + codegen::c_literal(0.5) + " * h, sixth = h / " + codegen::c_literal(6.0) + ";\n";
  src += "  const int first = " + X + "[" + std::to_string(i_first) + "] != " + codegen::c_literal(0.0) + ";\n";
  src += "  " + R + " k1[" + N + "], k2[" + N + "], k3[" + N + "], k4[" + N + "], tmp[" + N + "], out[2], ue;\n";
  src += std::string("  int i, j;\n") + (dahl ? "  " + R + " q_before;\n" : "");
  const std::string hist = X + "[" + std::to_string(i_hist) + " + ";
  src += "  if (first) {\n";
  if (dead) src += "    for (i = 0; i <= " + M + "_DELAY_SAMPLES; ++i) " + hist + "i] = u[0]; /* u before t = 0 is u(0) */\n";
  if (lag) src += "    " + X + "[" + std::to_string(nx) + "] = " + name + "_input(u[0], u[0], u[0]); /* actuator at rest */\n";
  src += "    " + X + "[" + std::to_string(i_first) + "] = " + codegen::c_literal(0.0) + ";\n  }\n";
  if (dead) {
    src += "  ue = " + name + "_input(u[0], " +
           (m_dead == 0 ? std::string("u[0]") : hist + std::to_string(m_dead - 1) + "]") + ", " + hist +
           std::to_string(m_dead) + "]);\n";
  } else {
    src += "  ue = " + name + "_input(u[0], u[0], u[0]);\n";
  }
  src += "  if (first) " + name + "_output_first(" + X + ", u, ue, " + X + "[" + std::to_string(i_play) + "], out);\n";
  src += "  else " + name + "_output(" + X + ", u, ue, " + X + "[" + std::to_string(i_play) + "], out);\n";
  src += "  y[0] = out[0];\n  " + X + "[" + std::to_string(i_play) + "] = out[1];\n";
  const std::string fric = X + "[" + std::to_string(i_fric) + "]";
  src += "  for (i = 0; i < " + M + "_SUBSTEPS; ++i) {\n";
  if (dahl) src += "    q_before = " + X + "[" + std::to_string(model.roles().position) + "];\n";
  src += "    " + name + "_derivative(" + X + ", u, ue, " + fric + ", k1);\n";
  src += "    for (j = 0; j < " + N + "; ++j) tmp[j] = " + X + "[j] + half * k1[j];\n";
  src += "    " + name + "_derivative(tmp, u, ue, " + fric + ", k2);\n";
  src += "    for (j = 0; j < " + N + "; ++j) tmp[j] = " + X + "[j] + half * k2[j];\n";
  src += "    " + name + "_derivative(tmp, u, ue, " + fric + ", k3);\n";
  src += "    for (j = 0; j < " + N + "; ++j) tmp[j] = " + X + "[j] + h * k3[j];\n";
  src += "    " + name + "_derivative(tmp, u, ue, " + fric + ", k4);\n";
  src += "    for (j = 0; j < " + N + "; ++j) {\n      tmp[j] = k1[j] + k4[j];\n      tmp[j] += " + codegen::c_literal(2.0) + " * (k2[j] + k3[j]);\n"
         "      " + X + "[j] += sixth * tmp[j];\n    }\n";
  if (dahl) {
    src += "    " + fric + " = " + name + "_friction(" + fric + ", " + X + "[" + std::to_string(model.roles().position) +
           "] - q_before);\n";
  }
  src += "  }\n";
  if (dead) src += "  for (i = " + M + "_DELAY_SAMPLES; i > 0; --i) " + hist + "i] = " + hist + "i - 1];\n  " + hist + "0] = u[0];\n";
  src += "}\n";

  GeneratedCode g;
  g.name = name;
  g.paths = f_dx.paths;
  g.header = codegen::ascii_text(codegen::make_header(m));
  g.source = codegen::ascii_text(src + "\n" + codegen::checked_step_function(name));
  return g;
}

}  // namespace nlid
