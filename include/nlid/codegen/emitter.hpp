#pragma once
/// @file
/// The common part of nlid's C code generation: options, the generated header + source pair,
/// and the C99 skeleton every model kind fills in.
///
/// Every generated model has the same C interface (`NAME` = `CodegenOptions::name`):
///
///     #include "NAME.h"
///     NAME_state s;
///     NAME_init(&s);                       // x = NAME_x0: zero, or an equilibrium chosen at generation
///     for (;;) { NAME_step(&s, u, y); }    // one sample: y(t) from x(t), u(t); then x(t+1)
///
/// plus `NAME_set_state(&s, x)`, `NAME_parameters()` (the estimated values, read-only) and the
/// macros NAME_NUM_STATES / _INPUTS / _OUTPUTS / _PARAMS and NAME_SAMPLE_TIME. The code is C99
/// with <math.h> only, no allocation, no globals but `static const` tables, re-entrant (all
/// state in the caller's struct), and compiles warning-free under
/// `-std=c99 -Wall -Wextra -pedantic`. Parameters are `static const double NAME_p[]` with 17
/// significant digits (round-trip exact), each commented with its name.
///
/// The model-specific generators (codegen/nlarx.hpp, hammerstein_wiener.hpp, greybox.hpp) trace
/// the model's own scalar-generic C++ on `TraceScalar` (trace_scalar.hpp) to produce the body of
/// the step function; nothing of a model's math is written twice.

#include <cctype>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "nlid/codegen/trace_scalar.hpp"
#include "nlid/core/atomic_file.hpp"
#include "nlid/core/error.hpp"

namespace nlid {

/// Settings of C code generation.
struct CodegenOptions {
  /// Prefix of every generated identifier and the file names (a C identifier).
  std::string name = "nlid_model";
  /// If set, `NAME_init` starts at the equilibrium for this constant input (one value per
  /// input); otherwise at the zero state.
  std::optional<Eigen::VectorXd> equilibrium_input;
  /// Sample time of the generated step (grey box: required; black-box models: 0 = the model's).
  double ts = 0.0;
  /// Grey box: sub-steps per sample (0 = the model's rule at generation time).
  int substeps = 0;
  /// Bounds on traced branches.
  codegen::TraceLimits limits;
};

/// A generated header and source, ready to be written or compiled.
struct GeneratedCode {
  std::string name;    ///< identifier prefix and file stem
  std::string header;  ///< NAME.h
  std::string source;  ///< NAME.c
  int paths = 1;       ///< branches of the traced step (leaves of its decision tree)

  /// Writes DIR/NAME.h and DIR/NAME.c atomically (the directory must exist); returns the paths.
  std::vector<std::string> write(const std::string& dir) const {
    require(std::filesystem::is_directory(dir), "codegen: output directory '" + dir + "' does not exist",
            at_parameter("dir"));
    const std::string h = (std::filesystem::path(dir) / (name + ".h")).string();
    const std::string c = (std::filesystem::path(dir) / (name + ".c")).string();
    write_file_atomically(h, header);
    write_file_atomically(c, source);
    return {h, c};
  }
};

namespace codegen {

/// Throws unless `name` is a C identifier that does not start with "nlid_" (reserved for helpers).
inline void check_name(const std::string& name) {
  bool ok = !name.empty() && (std::isalpha(static_cast<unsigned char>(name[0])) || name[0] == '_');
  for (char c : name) ok = ok && (std::isalnum(static_cast<unsigned char>(c)) || c == '_');
  require(ok, "codegen: name '" + name + "' is not a C identifier (letters, digits, '_', not starting with a digit)",
          at_parameter("name"));
  require(name.rfind("nlid_", 0) != 0 || name == "nlid_model",
          "codegen: names starting with 'nlid_' are reserved for generated helpers", at_parameter("name"));
}

/// Upper-case macro prefix of a name.
inline std::string macro(const std::string& name) {
  std::string m = name;
  for (char& c : m) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return m;
}

/// Sizes and documentation shared by the header and the source skeleton.
struct ModelShape {
  std::string name;                         ///< identifier prefix
  std::string kind;                         ///< "nonlinear ARX", …
  std::string description;                  ///< the model's describe() (becomes a comment)
  std::string state_doc;                    ///< what the state vector holds
  int nx = 0, nu = 1, ny = 1;               ///< sizes
  double ts = 0.0;                          ///< sample time
  Eigen::VectorXd parameters;               ///< values of NAME_p
  std::vector<std::string> parameter_names; ///< one comment per value
  Eigen::VectorXd x0;                       ///< NAME_x0
  std::string x0_doc;                       ///< how x0 was chosen
};

/// Text as a C block comment ("*/" defused).
inline std::string comment_block(const std::string& text, const std::string& indent = "") {
  std::string s = indent + "/*\n";
  std::string line;
  auto flush = [&]() {
    std::string l = line;
    for (std::size_t p = 0; (p = l.find("*/", p)) != std::string::npos;) l.replace(p, 2, "* /");
    s += indent + " * " + l + "\n";
    line.clear();
  };
  for (char c : text) {
    if (c == '\n') flush(); else line += c;
  }
  if (!line.empty()) flush();
  return s + indent + " */\n";
}

/// The header NAME.h.
inline std::string make_header(const ModelShape& m) {
  const std::string M = macro(m.name);
  const int nxs = m.nx > 0 ? m.nx : 1;
  std::string h;
  h += "/* " + m.name + ".h — generated by nlid (header-only C++ system identification) from a " + m.kind +
       " model.\n * Dependency-free C99: include this header, compile " + m.name +
       ".c with your code, link with -lm.\n *\n";
  h += " *   " + m.name + "_state s;\n *   " + m.name + "_init(&s);\n *   each sample: " + m.name +
       "_step(&s, u, y);   (u: inputs at t, y: outputs at t)\n */\n";
  h += "#ifndef " + M + "_H\n#define " + M + "_H\n\n#ifdef __cplusplus\nextern \"C\" {\n#endif\n\n";
  h += "#define " + M + "_NUM_STATES " + std::to_string(m.nx) + "\n";
  h += "#define " + M + "_NUM_INPUTS " + std::to_string(m.nu) + "\n";
  h += "#define " + M + "_NUM_OUTPUTS " + std::to_string(m.ny) + "\n";
  h += "#define " + M + "_NUM_PARAMS " + std::to_string(m.parameters.size()) + "\n";
  h += "#define " + M + "_SAMPLE_TIME " + c_literal(m.ts) + " /* seconds */\n\n";
  h += comment_block("State: " + m.state_doc);
  h += "typedef struct {\n  double x[" + std::to_string(nxs) + "];" + (m.nx == 0 ? " /* unused: the model has no state */" : "") +
       "\n} " + m.name + "_state;\n\n";
  h += "/* Sets the state to " + m.name + "_x0 (" + m.x0_doc + "). */\nvoid " + m.name + "_init(" + m.name +
       "_state* s);\n";
  h += "/* Sets the state to x (" + M + "_NUM_STATES values, layout above). */\nvoid " + m.name + "_set_state(" +
       m.name + "_state* s, const double* x);\n";
  h += "/* One sample: outputs y (" + M + "_NUM_OUTPUTS) at time t from the state and inputs u (" + M +
       "_NUM_INPUTS) at t;\n   then advances the state to t + 1. */\nvoid " + m.name + "_step(" + m.name +
       "_state* s, const double* u, double* y);\n";
  h += "/* The estimated parameters (" + M + "_NUM_PARAMS values, read-only). */\nconst double* " + m.name +
       "_parameters(void);\n\n";
  h += "#ifdef __cplusplus\n}\n#endif\n\n#endif /* " + M + "_H */\n";
  return h;
}

/// The top of NAME.c: includes, the model description, parameter and initial-state tables, helpers.
inline std::string make_source_prelude(const ModelShape& m, const std::set<std::string>& helpers) {
  std::string s = "/* " + m.name + ".c — generated by nlid; see " + m.name + ".h. Do not edit: regenerate. */\n";
  s += "#include \"" + m.name + ".h\"\n\n#include <math.h>\n\n";
  s += comment_block("Model:\n" + m.description);
  s += "\n/* Parameters (17 significant digits: the exact estimated doubles). */\n";
  const auto np = m.parameters.size();
  s += "static const double " + m.name + "_p[" + std::to_string(np > 0 ? np : 1) + "] = {\n";
  if (np == 0) s += "    0.0 /* no parameters */\n";
  for (Eigen::Index i = 0; i < np; ++i) {
    const std::string pn = static_cast<std::size_t>(i) < m.parameter_names.size() ? m.parameter_names[static_cast<std::size_t>(i)]
                                                                                : "p" + std::to_string(i);
    std::string safe = pn;
    for (std::size_t p = 0; (p = safe.find("*/", p)) != std::string::npos;) safe.replace(p, 2, "* /");
    s += "    " + c_literal(m.parameters(i)) + (i + 1 < np ? "," : " ") + " /* [" + std::to_string(i) + "] " + safe + " */\n";
  }
  s += "};\n\n";
  const int nxs = m.nx > 0 ? m.nx : 1;
  s += "/* Initial state: " + m.x0_doc + ". */\nstatic const double " + m.name + "_x0[" + std::to_string(nxs) + "] = {";
  for (int i = 0; i < nxs; ++i) s += std::string(i ? ", " : "") + c_literal(i < m.x0.size() ? m.x0(i) : 0.0);
  s += "};\n\n";
  for (const auto& h : helpers) s += helper_source(h) + "\n";
  const std::string M = macro(m.name);
  s += "void " + m.name + "_init(" + m.name + "_state* s) {\n  int i;\n  for (i = 0; i < " + std::to_string(nxs) +
       "; ++i) s->x[i] = " + m.name + "_x0[i];\n}\n\n";
  s += "void " + m.name + "_set_state(" + m.name + "_state* s, const double* x) {\n  int i;\n  for (i = 0; i < " + M +
       "_NUM_STATES; ++i) s->x[i] = x[i];\n}\n\n";
  s += "const double* " + m.name + "_parameters(void) { return " + m.name + "_p; }\n\n";
  return s;
}

/// Signals "base[0]", …, "base[n−1]" as traced scalars.
inline std::vector<TraceScalar> signals(const std::string& base, int n) {
  std::vector<TraceScalar> v;
  for (int i = 0; i < n; ++i) v.push_back(TraceScalar::signal(base + "[" + std::to_string(i) + "]"));
  return v;
}

/// Parameters NAME_p[offset + i] with their values as traced scalars.
inline std::vector<TraceScalar> parameters(const std::string& name, std::span<const double> values, int offset = 0) {
  std::vector<TraceScalar> v;
  for (std::size_t i = 0; i < values.size(); ++i)
    v.push_back(TraceScalar::parameter(name + "_p[" + std::to_string(offset + static_cast<int>(i)) + "]", values[i]));
  return v;
}

/// Targets "base[0]", … for `emit_c`.
inline std::vector<std::string> targets(const std::string& base, int n) {
  std::vector<std::string> t;
  for (int i = 0; i < n; ++i) t.push_back(base + "[" + std::to_string(i) + "]");
  return t;
}

/// A step function for a one-step map traced as [y; x_next]: computes into y and xn, then
/// copies xn into the state (so every new state value is computed from the old ones).
inline std::string discrete_step_function(const ModelShape& m, const TracedFunction& f) {
  std::vector<std::string> t = targets("y", m.ny);
  for (int i = 0; i < m.nx; ++i) t.push_back("xn[" + std::to_string(i) + "]");
  std::string s = "void " + m.name + "_step(" + m.name + "_state* s, const double* u, double* y) {\n";
  if (m.nx > 0) s += "  double xn[" + std::to_string(m.nx) + "];\n  int i;\n";
  s += "  (void)s;\n  (void)u;\n";
  s += emit_c(f, t, "  ");
  if (m.nx > 0) s += "  for (i = 0; i < " + std::to_string(m.nx) + "; ++i) s->x[i] = xn[i];\n";
  return s + "}\n";
}

}  // namespace codegen
}  // namespace nlid
