#pragma once
/// @file
/// C code for the linear input/output models: ARX `Arx` and output error `OutputError`
/// (multi-input, with or without offset) — the same NAME_init / NAME_step interface as the
/// nonlinear models (emitter.hpp), so a linear reference model deploys the same way.
///
/// No tracing is needed: the step is written out term by term in the order of the models' own
/// recursions (`Arx::run`, `OutputError::block_response`), with the coefficients read from
/// NAME_p, so the C reproduces `simulate` to the last bits (same operations, same order).
///
///     ARX:  y(t) = ((c − a₁y(t−1) − … − a_na y(t−na)) + Σᵢ Σⱼ bᵢⱼ uᵢ(t−nkᵢ−j))
///           state [y(t−1) … y(t−na), u₁(t−1) … u₁(t−L₁), u₂(t−1) …],  Lᵢ = nkᵢ + nbᵢ − 1
///     OE:   wᵢ(t) = Σⱼ bᵢⱼ uᵢ(t−nkᵢ−j) − Σₖ fᵢₖ wᵢ(t−k),   y(t) = c + w₁(t) + w₂(t) + …
///           state per input [uᵢ(t−1) … uᵢ(t−Lᵢ), wᵢ(t−1) … wᵢ(t−nfᵢ)]
///
/// With `CodegenOptions::equilibrium_input` the past samples start at the steady state for that
/// constant input, as `simulate(e, InitialCondition::equilibrium)` (values computed at
/// generation with nlid's own expressions); otherwise at zero.
///
/// Single precision (`CodegenOptions::linear_form`): each output-error block with feedback is
/// written in delta-operator form (delta_form.hpp); its segment of the state holds its delta
/// state, max(nfᵢ, nkᵢ + nbᵢ − 1) values, instead of past inputs and outputs. An ARX model with
/// na > 0 becomes one multi-input delta block (`MultiInputDeltaBlock`): numerators zⁿB̃ᵢ per
/// input and, for an offset c, the constant input 1 with B̃ = c, over zⁿA, n = max(na, nkᵢ +
/// nbᵢ − 1). Its n-value state is an exact linear map of the direct form's past samples x
/// (computed in double): first the observer-form (TDF-II) state of the same recursion,
///
///     s_k = Σ_{j=k..n} (Σᵢ bᵢ,ⱼ₋ₙₖᵢ uᵢ(t−1−j+k) − aⱼ y(t−1−j+k)),   k = 1 … n
///
/// (what the past samples add to the coming outputs; the offset acts at lag 0 and adds nothing),
/// then its Taylor shift e = T s (delta_form.hpp). The map is many-to-one when nx > n (histories
/// with the same free response share e). NAME_x0 — zero or the equilibrium's past samples — is
/// mapped so; `generated_c_state(arx, x, options)` maps any past samples x.

#include <algorithm>
#include <cmath>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "nlid/codegen/delta_form.hpp"
#include "nlid/codegen/emitter.hpp"
#include "nlid/core/format.hpp"
#include "nlid/linear/arx.hpp"
#include "nlid/linear/output_error.hpp"
#include "nlid/models/detail/model_common.hpp"

namespace nlid {

namespace codegen::detail {
inline std::string at(const std::string& base, int i) { return base + "[" + std::to_string(i) + "]"; }
inline std::string shift_code(const std::string& x, int first, int count, const std::string& newest) {
  // x[first + count − 1] ← … ← x[first] ← newest
  std::string s;
  for (int k = count - 1; k > 0; --k) s += "  " + at(x, first + k) + " = " + at(x, first + k - 1) + ";\n";
  if (count > 0) s += "  " + at(x, first) + " = " + newest + ";\n";
  return s;
}
/// The lags Lᵢ = nkᵢ + nbᵢ − 1 of an ARX model's inputs in the direct-form state.
inline std::vector<int> arx_input_lags(const Arx& model) {
  std::vector<int> lags;
  for (int i = 0; i < model.num_inputs(); ++i) lags.push_back(std::max(0, model.nk(i) + model.nb(i) - 1));
  return lags;
}
/// ARX as one δ block (file comment), if `o` asks for the delta form and A has feedback:
/// numerators B̃ᵢ, then the offset's (a constant input, only if c ≠ 0), over A.
inline std::optional<codegen::MultiInputDeltaBlock> arx_delta_block(const Arx& model, const CodegenOptions& o) {
  if (!codegen::use_delta_form(o) || model.na() == 0) return std::nullopt;
  int n = model.na();
  std::vector<Eigen::VectorXd> beta;
  for (int i = 0; i < model.num_inputs(); ++i) {
    n = std::max(n, model.nk(i) + model.nb(i) - 1);
    beta.push_back(model.b_polynomial(i));
  }
  if (model.offset() != 0.0) beta.push_back(Eigen::VectorXd::Constant(1, model.offset()));
  return codegen::MultiInputDeltaBlock::from_tdf2(beta, model.a_polynomial(), n);
}
/// The TDF-II (observer form) state s of the ARX recursion with n states for the direct form's
/// state x = [y(t−1) … y(t−na), u₁(t−1) … u₁(t−L₁), …]: the part of the next outputs that the
/// past samples contribute, s_k = Σ_{j=k..n} (Σᵢ bᵢ,ⱼ₋ₙₖᵢ uᵢ(t−1−j+k) − aⱼ y(t−1−j+k)) (the
/// offset acts at lag 0 only and adds nothing). In double.
inline Eigen::VectorXd arx_tdf2_state(const Arx& model, int n, const Eigen::VectorXd& x) {
  const std::vector<int> lags = arx_input_lags(model);
  int nx = model.na();
  for (int l : lags) nx += l;
  require(x.size() == nx,
          "codegen: the state has " + std::to_string(x.size()) + " values, the model has " + std::to_string(nx) +
              " (past outputs and inputs)",
          at_parameter("x"));
  Eigen::VectorXd s = Eigen::VectorXd::Zero(n);
  for (int k = 1; k <= n; ++k) {
    double acc = 0.0;
    for (int j = k; j <= n; ++j) {
      const int lag = j - k + 1;  // sample t − lag; lag ≤ j, inside the state wherever a coefficient is nonzero
      if (j <= model.na()) acc -= model.a()(j - 1) * x(lag - 1);
      int off = model.na();
      for (int i = 0; i < model.num_inputs(); ++i) {
        const int bj = j - model.nk(i);
        if (bj >= 0 && bj < model.nb(i)) acc += model.b(i)(bj) * x(off + lag - 1);
        off += lags[static_cast<std::size_t>(i)];
      }
    }
    s(k - 1) = acc;
  }
  return s;
}
/// The δ form of an output-error model's block i (file comment), if `o` asks for the delta form
/// and the block has feedback; blocks without (FIR) keep their past inputs.
inline std::optional<codegen::DeltaBlock> oe_delta_block(const OutputError& model, int i, const CodegenOptions& o) {
  if (!codegen::use_delta_form(o) || model.f(i).size() == 0) return std::nullopt;
  const int nb = static_cast<int>(model.b(i).size()), nf = static_cast<int>(model.f(i).size());
  Eigen::VectorXd beta = Eigen::VectorXd::Zero(model.nk(i) + nb);
  beta.tail(nb) = model.b(i);
  return codegen::DeltaBlock::from_tdf2(beta, model.f_polynomial(i), std::max(nf, model.nk(i) + nb - 1));
}
/// Lᵢ = nkᵢ + nbᵢ − 1: the past inputs of an output-error model's block i in the direct form.
inline int oe_input_lag(const OutputError& model, int i) {
  return std::max(0, model.nk(i) + static_cast<int>(model.b(i).size()) - 1);
}
/// Σᵢ (Lᵢ + nfᵢ): the direct form's past inputs and block outputs.
inline int oe_direct_states(const OutputError& model) {
  int nx = 0;
  for (int i = 0; i < model.num_inputs(); ++i) nx += oe_input_lag(model, i) + static_cast<int>(model.f(i).size());
  return nx;
}
/// The generated state of an output-error model for the direct form's past samples x = per input
/// [uᵢ(t−1) … uᵢ(t−Lᵢ), wᵢ(t−1) … wᵢ(t−nfᵢ)]: each δ block's segment replaced by its δ state,
/// T·s with the TDF-II state s_k = Σ_{j=k..n} (βⱼ uᵢ(t−1−j+k) − fⱼ wᵢ(t−1−j+k)) of the block's
/// recursion (summed from j = n down, as the steady state of `OutputError::simulate`). In double.
inline Eigen::VectorXd oe_generated_state(const OutputError& model, const std::vector<std::optional<codegen::DeltaBlock>>& db,
                                          const Eigen::VectorXd& x) {
  const int nx = oe_direct_states(model);
  require(x.size() == nx,
          "codegen: the state has " + std::to_string(x.size()) + " values, the model has " + std::to_string(nx) +
              " (past inputs and block outputs)",
          at_parameter("x"));
  std::vector<double> out;
  int d = 0;  // block i's segment of x
  for (int i = 0; i < model.num_inputs(); ++i) {
    const int nk = model.nk(i), nb = static_cast<int>(model.b(i).size()), nf = static_cast<int>(model.f(i).size());
    const int lag_u = oe_input_lag(model, i);
    const auto& block = db[static_cast<std::size_t>(i)];
    if (!block) {
      for (int k = 0; k < lag_u + nf; ++k) out.push_back(x(d + k));
    } else {
      const int n = block->n;
      Eigen::VectorXd s(n);
      for (int k = 1; k <= n; ++k) {
        double acc = 0.0;
        for (int j = n; j >= k; --j) {
          const int lag = j - k + 1;  // sample t − lag; inside the segment wherever a coefficient is nonzero
          if (j - nk >= 0 && j - nk < nb) acc += model.b(i)(j - nk) * x(d + lag - 1);
          if (j <= nf) acc -= model.f(i)(j - 1) * x(d + lag_u + lag - 1);
        }
        s(k - 1) = acc;
      }
      const Eigen::VectorXd e = block->state_from_tdf2(s);
      out.insert(out.end(), e.data(), e.data() + e.size());
    }
    d += lag_u + nf;
  }
  return Eigen::Map<const Eigen::VectorXd>(out.data(), static_cast<Eigen::Index>(out.size()));
}
inline Eigen::VectorXd equilibrium_inputs(const CodegenOptions& o, int nu) {
  if (!o.equilibrium_input) return Eigen::VectorXd::Zero(nu);
  require(o.equilibrium_input->size() == nu,
          "codegen: equilibrium_input has " + std::to_string(o.equilibrium_input->size()) + " values, the model has " +
              std::to_string(nu) + " input(s)",
          at_parameter("equilibrium_input"));
  return *o.equilibrium_input;
}
}  // namespace codegen::detail

/// The state of the C code `generate_c(model, options)` generates for the ARX state `x` of the
/// direct form, [y(t−1) … y(t−na), u₁(t−1) … u₁(t−L₁), …] (the past samples `Arx::simulate`
/// starts from): `x` itself in the direct form, the δ state T·s(x) (file comment) in the delta
/// form — the values to pass to NAME_set_state.
inline Eigen::VectorXd generated_c_state(const Arx& model, const Eigen::VectorXd& x, const CodegenOptions& options = {}) {
  const auto db = codegen::detail::arx_delta_block(model, options);
  const Eigen::VectorXd s = codegen::detail::arx_tdf2_state(model, db ? db->n : 0, x);  // checks x's size
  return db ? db->state_from_tdf2(s) : x;
}

/// The state of the C code `generate_c(model, options)` generates for an output-error model
/// whose past samples are x = per input [uᵢ(t−1) … uᵢ(t−Lᵢ), wᵢ(t−1) … wᵢ(t−nfᵢ)] (Lᵢ = nkᵢ +
/// nbᵢ − 1, wᵢ the output of input i's block Bᵢ/Fᵢ, without the offset): `x` itself in the direct
/// form; in the delta form each block with feedback holds its δ state instead (file comment) —
/// the values to pass to NAME_set_state.
inline Eigen::VectorXd generated_c_state(const OutputError& model, const Eigen::VectorXd& x,
                                         const CodegenOptions& options = {}) {
  std::vector<std::optional<codegen::DeltaBlock>> db;
  for (int i = 0; i < model.num_inputs(); ++i) db.push_back(codegen::detail::oe_delta_block(model, i, options));
  return codegen::detail::oe_generated_state(model, db, x);
}

/// Generates C99 code for an ARX model (see the file comment). Throws `nlid::Error` on a bad
/// name, a missing sample time, or an equilibrium of a model with an integrator.
inline GeneratedCode generate_c(const Arx& model, const CodegenOptions& options = {}) {
  const codegen::PrecisionScope precision(options.precision);
  using codegen::detail::at;
  codegen::check_name(options.name);
  const int nu = model.num_inputs(), na = model.na();
  codegen::ModelShape m;
  m.name = options.name;
  m.kind = "ARX";
  m.description = model.describe();
  m.nu = nu;
  m.ny = 1;
  m.ts = codegen::sampled_model_ts(model.ts(), options.ts);
  require(m.ts > 0, "codegen: the model has no sample time; set CodegenOptions::ts", at_parameter("ts"));
  m.parameters = model.parameters();
  m.parameter_names = model.parameter_names();
  const std::vector<int> lags = codegen::detail::arx_input_lags(model);
  long long states = na;
  for (int l : lags) states += l;
  codegen::check_state_count(states, options, "ARX");
  std::vector<int> off(static_cast<std::size_t>(nu));
  int nx = na;
  for (int i = 0; i < nu; ++i) {
    off[static_cast<std::size_t>(i)] = nx;
    nx += lags[static_cast<std::size_t>(i)];
  }
  m.nx = nx;
  m.state_doc = "x = [y(t-1) .. y(t-" + std::to_string(na) + ")";
  for (int i = 0; i < nu; ++i)
    m.state_doc += ", u" + std::to_string(i + 1) + "(t-1) .. (t-" + std::to_string(lags[static_cast<std::size_t>(i)]) + ")";
  m.state_doc += "]";
  m.x0 = Eigen::VectorXd::Zero(nx);
  const Eigen::VectorXd u0 = codegen::detail::equilibrium_inputs(options, nu);
  if (const auto x = codegen::given_initial_state(options, nx, "past outputs and inputs", m)) {
    m.x0 = *x;
  } else if (options.equilibrium_input) {
    // As Arx::simulate(e, InitialCondition::equilibrium).
    const double a1 = model.a_polynomial().sum();
    double drive = model.offset();
    for (int i = 0; i < nu; ++i) drive += model.b(i).sum() * u0(i);
    require(std::abs(a1) > 1e-14 || drive == 0.0, "codegen: no equilibrium: A(q) has a root at z = 1 (integrator)",
            at_parameter("equilibrium_input"));
    const double y_past = std::abs(a1) > 1e-14 ? drive / a1 : 0.0;
    m.x0.head(na).setConstant(y_past);
    for (int i = 0; i < nu; ++i) m.x0.segment(off[static_cast<std::size_t>(i)], lags[static_cast<std::size_t>(i)]).setConstant(u0(i));
    m.x0_doc = "the steady state for u held at " + detail::format_g(u0(0), 17) +
               " (y = " + detail::format_g(y_past, 17) + ")";
  } else {
    m.x0_doc = "zero (past outputs and inputs 0)";
  }
  const std::string R = codegen::c_real();
  if (const auto db = codegen::detail::arx_delta_block(model, options)) {
    // Single precision: one multi-input block in delta form (file comment); the state is the
    // delta state of the past samples above, mapped in double.
    const int n = db->n;
    const bool offset_input = db->c.size() > static_cast<std::size_t>(nu);
    std::vector<std::string> names;
    for (int i = 0; i < nu; ++i) names.push_back("cu" + std::to_string(i + 1));
    if (offset_input) names.push_back("cc");
    std::string inputs;
    for (int i = 0; i < nu; ++i) inputs += " + cu" + std::to_string(i + 1) + "_k*u" + std::to_string(i + 1) + "(t)";
    m.nx = n;
    m.state_doc = "x = [e_1 .. e_" + std::to_string(n) +
                  "] (single precision: the model as one block in delta-operator form, d = q - 1: y(t) = e_1(t)";
    for (int i = 0; i < nu; ++i) m.state_doc += " + cu" + std::to_string(i + 1) + "_0*u" + std::to_string(i + 1) + "(t)";
    m.state_doc += ", e_k(t+1) = e_k(t) + e_(k+1)(t)" + inputs + (offset_input ? " + cc_k" : "") +
                   " - a_k*y(t), A(z) = d^n + a1 d^(n-1) + .. + an, Bi(z) = cui_0 d^n + .. + cui_n" +
                   (offset_input ? ", offset c: cc_k = c*binomial(n, k)" : "") + "; " + db->describe(names) +
                   "; e is a linear map of past outputs and inputs, nlid::generated_c_state)";
    m.x0 = db->state_from_tdf2(codegen::detail::arx_tdf2_state(model, n, m.x0));
    m.x0_doc += ", as its delta state";
    const std::string X = "s->x";
    const codegen::TracedFunction tf = codegen::trace_paths([&] {
      std::vector<TraceScalar> e, w;
      for (int k = 0; k < n; ++k) e.push_back(TraceScalar::signal(at(X, k)));
      for (int i = 0; i < nu; ++i) w.push_back(TraceScalar::signal(at("u", i)));
      if (offset_input) w.emplace_back(1.0);
      std::vector<TraceScalar> r{db->step(std::span<TraceScalar>(e), std::span<const TraceScalar>(w))};
      r.insert(r.end(), e.begin(), e.end());
      return r;
    });
    std::vector<std::string> t{"y[0]"};
    for (int k = 0; k < n; ++k) t.push_back(at("en", k));
    std::string body = "  " + R + " en[" + std::to_string(n) + "];\n  int k;\n  (void)u;\n" + codegen::emit_c(tf, t, "  ");
    body += "  for (k = 0; k < " + std::to_string(n) + "; ++k) s->x[k] = en[k];\n";
    GeneratedCode g;
    g.name = m.name;
    g.header = codegen::ascii_text(codegen::make_header(m));
    g.source = codegen::ascii_text(codegen::make_source_prelude(m, {}) + codegen::model_step_head(m.name) +
                                   "  (void)s;\n" + body + "}\n\n" + codegen::checked_step_function(m.name));
    return g;
  }
  const std::string P = m.name + "_p", X = "s->x";
  int k = 0;
  std::string body = "  " + R + " acc = " + (model.has_offset() ? at(P, model.num_parameters() - 1) : codegen::c_literal(model.offset())) +
                     ", drive = " + codegen::c_literal(0.0) + ";\n  (void)u;\n";
  for (int j = 1; j <= na; ++j) body += "  acc -= " + at(P, k++) + " * " + at(X, j - 1) + ";\n";
  for (int i = 0; i < nu; ++i) {
    for (int j = 0; j < model.nb(i); ++j) {
      const int lag = model.nk(i) + j;
      body += "  drive += " + at(P, k++) + " * " + (lag == 0 ? at("u", i) : at(X, off[static_cast<std::size_t>(i)] + lag - 1)) + ";\n";
    }
  }
  body += "  acc += drive;\n  y[0] = acc;\n";
  body += codegen::detail::shift_code(X, 0, na, "acc");
  for (int i = 0; i < nu; ++i) body += codegen::detail::shift_code(X, off[static_cast<std::size_t>(i)], lags[static_cast<std::size_t>(i)], at("u", i));
  GeneratedCode g;
  g.name = m.name;
  g.header = codegen::ascii_text(codegen::make_header(m));
  g.source = codegen::ascii_text(codegen::make_source_prelude(m, {}) + codegen::model_step_head(m.name) + "  (void)s;\n" +
                                 body + "}\n\n" + codegen::checked_step_function(m.name));
  return g;
}

/// Generates C99 code for an output-error model (see the file comment). Throws `nlid::Error`
/// on a bad name, a missing sample time, or an equilibrium of a block with F(1) = 0.
inline GeneratedCode generate_c(const OutputError& model, const CodegenOptions& options = {}) {
  const codegen::PrecisionScope precision(options.precision);
  using codegen::detail::at;
  codegen::check_name(options.name);
  const int nu = model.num_inputs();
  codegen::ModelShape m;
  m.name = options.name;
  m.kind = "output-error";
  m.description = model.describe();
  m.nu = nu;
  m.ny = 1;
  m.ts = codegen::sampled_model_ts(model.ts(), options.ts);
  require(m.ts > 0, "codegen: the model has no sample time; set CodegenOptions::ts", at_parameter("ts"));
  m.parameters = model.parameters();
  m.parameter_names = model.parameter_names();
  std::vector<int> lags(static_cast<std::size_t>(nu)), uoff(static_cast<std::size_t>(nu)), woff(static_cast<std::size_t>(nu));
  // Single precision: each block with feedback in delta form (delta_form.hpp), its segment of
  // the state then holds its delta state instead of past inputs and outputs.
  std::vector<std::optional<codegen::DeltaBlock>> db(static_cast<std::size_t>(nu));
  long long states = 0;  // the direct form's; a delta block has fewer
  for (int i = 0; i < nu; ++i)
    states += static_cast<long long>(codegen::detail::oe_input_lag(model, i)) + static_cast<long long>(model.f(i).size());
  codegen::check_state_count(states, options, "output-error");
  int nx = 0;
  m.state_doc = "x = [";
  for (int i = 0; i < nu; ++i) {
    const auto ii = static_cast<std::size_t>(i);
    db[ii] = codegen::detail::oe_delta_block(model, i, options);
    if (db[ii]) {
      lags[ii] = 0;
      uoff[ii] = woff[ii] = nx;
      nx += db[ii]->n;
      const std::string n = std::to_string(i + 1);
      m.state_doc += std::string(i ? "; " : "") + "e" + n + "_1 .. e" + n + "_" + std::to_string(db[ii]->n) +
                     " (single precision: block " + n + " in delta-operator form, d = q - 1: w" + n + "(t) = c0*u" + n +
                     "(t) + e_1(t), e_k(t+1) = e_k(t) + e_(k+1)(t) + c_k*u" + n + "(t) - a_k*w" + n +
                     "(t), B(z)/F(z) = (c0 d^n + .. + cn)/(d^n + a1 d^(n-1) + .. + an), " + db[ii]->describe() + ")";
      continue;
    }
    lags[ii] = codegen::detail::oe_input_lag(model, i);
    uoff[ii] = nx;
    woff[ii] = nx + lags[ii];
    nx += lags[ii] + static_cast<int>(model.f(i).size());
    const std::string n = std::to_string(i + 1);
    m.state_doc += std::string(i ? "; " : "") + "u" + n + "(t-1) .. (t-" + std::to_string(lags[ii]) + "), w" + n +
                   "(t-1) .. (t-" + std::to_string(model.f(i).size()) + ")";
  }
  m.state_doc += "] (w_i: the output of input i's block B_i/F_i)";
  m.nx = nx;
  const Eigen::VectorXd u0 = codegen::detail::equilibrium_inputs(options, nu);
  // The start as past samples of the direct form (per input: past inputs, past block outputs),
  // then mapped to the generated layout.
  std::vector<double> past;
  if (const auto x = codegen::given_initial_state(options, codegen::detail::oe_direct_states(model),
                                                  "past inputs and block outputs", m)) {
    past.assign(x->data(), x->data() + x->size());
  } else if (options.equilibrium_input) {
    // As OutputError::simulate(e, InitialCondition::equilibrium).
    for (int i = 0; i < nu; ++i) {
      const double f1 = model.f_polynomial(i).sum();
      require(std::abs(f1) > 1e-14 || model.b(i).sum() * u0(i) == 0.0,
              "codegen: no equilibrium: F(q) of input " + std::to_string(i + 1) + " has a root at z = 1",
              at_parameter("equilibrium_input"));
      const double w0 = std::abs(f1) > 1e-14 ? model.b(i).sum() / f1 * u0(i) : 0.0;
      past.insert(past.end(), static_cast<std::size_t>(codegen::detail::oe_input_lag(model, i)), u0(i));
      past.insert(past.end(), static_cast<std::size_t>(model.f(i).size()), w0);
    }
    m.x0_doc = "the steady state for u held at " + detail::format_g(u0(0), 17);
  } else {
    past.assign(static_cast<std::size_t>(codegen::detail::oe_direct_states(model)), 0.0);
    m.x0_doc = "zero (past inputs and block outputs 0)";
  }
  m.x0 = codegen::detail::oe_generated_state(model, db, Eigen::Map<const Eigen::VectorXd>(past.data(), static_cast<Eigen::Index>(past.size())));
  const std::string P = m.name + "_p", X = "s->x";
  // Parameter layout: all b, then all f, then the offset.
  std::vector<int> pb(static_cast<std::size_t>(nu)), pf(static_cast<std::size_t>(nu));
  int k = 0;
  for (int i = 0; i < nu; ++i) {
    pb[static_cast<std::size_t>(i)] = k;
    k += static_cast<int>(model.b(i).size());
  }
  for (int i = 0; i < nu; ++i) {
    pf[static_cast<std::size_t>(i)] = k;
    k += static_cast<int>(model.f(i).size());
  }
  const std::string R = codegen::c_real();
  std::string body = "  " + R + " out = " + (model.has_offset() ? at(P, model.num_parameters() - 1) : codegen::c_literal(model.offset())) +
                     ";\n  " + R + " w[" + std::to_string(std::max(nu, 1)) + "];\n  (void)u;\n";
  for (int i = 0; i < nu; ++i) {
    const auto ii = static_cast<std::size_t>(i);
    const std::string wi = at("w", i);
    if (db[ii]) {
      const int n = db[ii]->n;
      const codegen::TracedFunction tf = codegen::trace_paths([&] {
        std::vector<TraceScalar> e;
        for (int k = 0; k < n; ++k) e.push_back(TraceScalar::signal(at(X, uoff[ii] + k)));
        std::vector<TraceScalar> r{db[ii]->step(std::span<TraceScalar>(e), TraceScalar::signal(at("u", i)))};
        r.insert(r.end(), e.begin(), e.end());
        return r;
      });
      std::vector<std::string> t{wi};
      for (int k = 0; k < n; ++k) t.push_back(at("en", k));
      body += "  {\n    " + R + " en[" + std::to_string(n) + "];\n    int k;\n" + codegen::emit_c(tf, t, "    ");
      body += "    for (k = 0; k < " + std::to_string(n) + "; ++k) s->x[" + std::to_string(uoff[ii]) + " + k] = en[k];\n  }\n";
      body += "  out += " + wi + ";\n";
      continue;
    }
    body += "  " + wi + " = " + codegen::c_literal(0.0) + ";\n";
    for (int j = 0; j < static_cast<int>(model.b(i).size()); ++j) {
      const int lag = model.nk(i) + j;
      body += "  " + wi + " += " + at(P, pb[ii] + j) + " * " + (lag == 0 ? at("u", i) : at(X, uoff[ii] + lag - 1)) + ";\n";
    }
    for (int q = 1; q <= static_cast<int>(model.f(i).size()); ++q)
      body += "  " + wi + " -= " + at(P, pf[ii] + q - 1) + " * " + at(X, woff[ii] + q - 1) + ";\n";
    body += "  out += " + wi + ";\n";
  }
  body += "  y[0] = out;\n";
  for (int i = 0; i < nu; ++i) {
    const auto ii = static_cast<std::size_t>(i);
    if (db[ii]) continue;  // updated above
    body += codegen::detail::shift_code(X, uoff[ii], lags[ii], at("u", i));
    body += codegen::detail::shift_code(X, woff[ii], static_cast<int>(model.f(i).size()), at("w", i));
  }
  GeneratedCode g;
  g.name = m.name;
  g.header = codegen::ascii_text(codegen::make_header(m));
  g.source = codegen::ascii_text(codegen::make_source_prelude(m, {}) + codegen::model_step_head(m.name) + "  (void)s;\n" +
                                 body + "}\n\n" + codegen::checked_step_function(m.name));
  return g;
}

}  // namespace nlid
