#pragma once
/// @file
/// C code for a nonlinear ARX model `Nlarx<R, F>`: regressors (custom ones included) and the
/// nonlinearity (sigmoid, wavelet, piecewise linear, saturation, dead zone, polynomial, linear,
/// unit gain — any scalar-generic map) traced into one step function.
///
/// Generated state (NAME_NUM_STATES = Ly + n_u·Lu): the lag window of nlid's `Nlarx` x0,
///
///     x = [y(t−1) … y(t−Ly), u₁(t−1) … u₁(t−Lu), u₂(t−1) …],
///
/// and NAME_step computes ŷ(t) = F(φ(x, u(t))) and shifts the window — exactly the free-run
/// simulation `Nlarx::simulate` (Ljung 1999, eq. 5.46 with simulated past outputs). Starting
/// from NAME_init with the zero state reproduces `simulate(e, InitialCondition::zero)`; with
/// `CodegenOptions::equilibrium_input` it reproduces a start from that equilibrium.
///
/// Custom regressors are generic lambdas; they are traced like everything else, which is why
/// the toolbox's restriction ("code generation does not support custom regressors") does not
/// apply. A regressor written with `nlid::max(y1, 90.0)` becomes `(x >= 90.0 ? x : 90.0)`.
/// The header order does not matter: a lambda that calls `nlid::max`/`nlid::min` and was
/// compiled before this header reaches the `TraceScalar` overloads through the generic
/// `nlid::max`/`nlid::min` of ad/dual.hpp (tests/static/codegen_include_order.cpp).

#include <span>
#include <string>
#include <vector>

#include "nlid/analysis/linearize.hpp"
#include "nlid/codegen/emitter.hpp"
#include "nlid/codegen/trace_scalar.hpp"
#include "nlid/core/format.hpp"
#include "nlid/models/equilibrium.hpp"
#include "nlid/models/nlarx.hpp"

namespace nlid {

/// Generates C99 code for a nonlinear ARX model (see the file comment and emitter.hpp for the
/// interface). Throws `nlid::Error` on a bad name, a missing sample time or an untraceable
/// nonlinearity (too many branches).
template <class R, class F>
GeneratedCode generate_c(const Nlarx<R, F>& model, const CodegenOptions& options = {}) {
  const codegen::PrecisionScope precision(options.precision);
  codegen::check_name(options.name);
  codegen::ModelShape m;
  m.name = options.name;
  m.kind = "nonlinear ARX";
  m.description = model.describe();
  codegen::check_state_count(model.output_lag() + static_cast<long long>(model.num_inputs()) * model.input_lag(),
                             options, "nonlinear ARX");
  m.nx = model.state_dimension();
  m.nu = model.num_inputs();
  m.ny = 1;
  m.ts = codegen::sampled_model_ts(model.ts(), options.ts);
  require(m.ts > 0, "codegen: the model has no sample time; set it (set_ts) or CodegenOptions::ts", at_parameter("ts"));
  m.parameters = model.parameters();
  m.parameter_names = model.parameter_names();
  const auto names = detail::nlarx_state_names(model);
  m.state_doc = "the lag window x = [";
  for (std::size_t i = 0; i < names.size(); ++i) m.state_doc += (i ? ", " : "") + names[i];
  m.state_doc += "]" + std::string(names.empty() ? " (empty: the model has no memory)" : "");
  if (const auto x = codegen::given_initial_state(options, m.nx, "the lag window", m)) {
    m.x0 = *x;
  } else if (options.equilibrium_input) {
    const OperatingPoint op = equilibrium(model, *options.equilibrium_input);
    m.x0 = op.x;
    m.x0_doc = "the equilibrium for u held at " + detail::format_g((*options.equilibrium_input)(0), 17) +
               " (y = " + detail::format_g(op.y(0), 17) + ")";
  } else {
    m.x0 = Eigen::VectorXd::Zero(m.nx);
    m.x0_doc = "zero (all past outputs and inputs 0)";
  }
  const int nx = m.nx, nu = m.nu;
  const std::string name = m.name;
  const auto th_values = detail::as_const_span(model.parameters());
  const codegen::TracedFunction f = codegen::trace_paths(
      [&] {
        const std::vector<TraceScalar> x = codegen::signals("s->x", nx);
        const std::vector<TraceScalar> u = codegen::signals("u", nu);
        const std::vector<TraceScalar> th = codegen::parameters(name, th_values);
        std::vector<TraceScalar> out(static_cast<std::size_t>(1 + nx));
        out[0] = detail::nlarx_step<TraceScalar>(model, x.data(), u.data(), std::span<const TraceScalar>(th), out.data() + 1);
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
