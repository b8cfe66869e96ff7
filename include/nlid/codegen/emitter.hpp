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
///     for (;;) {                           // one sample: y(t) from x(t), u(t); then x(t+1)
///       if (NAME_step(&s, u, y) != 0) { /* a non-finite sample: state kept, y not usable */ }
///     }
///
/// NAME_step returns 0, or 1 when an input, an output or the next state is not finite (a NaN
/// from a failed sensor, an input so far outside the model's range that it overflows): then the
/// state is left as it was — one bad sample does not poison the state for good, as it would in
/// a lag window or a filter register — and y holds what the model gives for that input.
///
/// plus `NAME_set_state(&s, x)`, `NAME_parameters()` (the estimated values, read-only) and the
/// macros NAME_NUM_STATES / _INPUTS / _OUTPUTS / _PARAMS and NAME_SAMPLE_TIME. The code is C99
/// with <math.h> only, no allocation, no globals but `static const` tables, re-entrant (all
/// state in the caller's struct), and compiles warning-free under
/// `-std=c99 -Wall -Wextra -pedantic`. Parameters are `static const double NAME_p[]` with 17
/// significant digits (round-trip exact), each commented with its name. With
/// `CodegenOptions::precision = single_precision` every real is a float instead (`NAME_real`
/// names the type in both cases) and the code compiles under `-Wdouble-promotion` as well.
///
/// The model-specific generators (codegen/nlarx.hpp, hammerstein_wiener.hpp, greybox.hpp) trace
/// the model's own scalar-generic C++ on `TraceScalar` (trace_scalar.hpp) to produce the body of
/// the step function; nothing of a model's math is written twice.

#include <cctype>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "nlid/codegen/delta_form.hpp"
#include "nlid/codegen/trace_scalar.hpp"
#include "nlid/core/atomic_file.hpp"
#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/core/sample_time.hpp"

namespace nlid {

/// Settings of C code generation.
struct CodegenOptions {
  /// Prefix of every generated identifier and the file names (a C identifier, not the name of a
  /// C standard header such as math or stdio, whose NAME.h it would shadow).
  std::string name = "nlid_model";
  /// If set, `NAME_init` starts at the equilibrium for this constant input (one value per
  /// input); otherwise at the zero state (or `initial_state`).
  std::optional<Eigen::VectorXd> equilibrium_input;
  /// If set, `NAME_init` starts from this state, given in nlid's layout — the x0 the model's
  /// `simulate` takes: an nlarx lag window, a Hammerstein–Wiener or series model's block
  /// registers, a grey box's physical state (an augmented model's baseline state: its effects
  /// start from the first sample), an ARX or output-error model's past samples (see
  /// `generated_c_state`) — and mapped to the generated layout as `generated_c_state` does. An
  /// estimated initial state deploys so. Not together with `equilibrium_input`.
  std::optional<Eigen::VectorXd> initial_state;
  /// Sample time of the generated step (grey box: required; sampled models: 0 = the model's,
  /// and a value that differs from a model's known sample time is refused — the coefficients
  /// belong to that sample time, only a model without one takes it from here).
  double ts = 0.0;
  /// Grey box: sub-steps per sample (0 = the model's rule at generation time).
  int substeps = 0;
  /// Bounds on traced branches.
  codegen::TraceLimits limits;
  /// double (default: nlid's numbers to the last bit) or float throughout (FPUs without double;
  /// see codegen::Precision).
  codegen::Precision precision = codegen::Precision::double_precision;
  /// Form of the linear blocks of Hammerstein–Wiener, series, ARX and output-error models
  /// (codegen::LinearForm, delta_form.hpp): `automatic` is the delta-operator form in single
  /// precision and nlid's direct form in double; `direct` keeps the polynomial form in single
  /// precision too (for comparison); `delta` with double precision is an error for those kinds.
  /// Other model kinds (nlarx, grey box, augmented) have no linear block and ignore it.
  codegen::LinearForm linear_form = codegen::LinearForm::automatic;
};

/// A generated header and source, ready to be written or compiled.
struct GeneratedCode {
  std::string name;    ///< identifier prefix and file stem
  std::string header;  ///< NAME.h
  std::string source;  ///< NAME.c
  int paths = 1;       ///< branches of the traced step (leaves of its decision tree)

  /// Writes DIR/NAME.h and DIR/NAME.c atomically and as a pair (the directory must exist): both
  /// are written to temporaries first, so if either cannot be written neither file changes
  /// (only a file-system failure between the two final renames can leave the header replaced
  /// alone, and the error says so). Returns the paths.
  std::vector<std::string> write(const std::string& dir) const {
    require(std::filesystem::is_directory(dir), "codegen: output directory '" + dir + "' does not exist",
            at_parameter("dir"));
    const std::string h = (std::filesystem::path(dir) / (name + ".h")).string();
    const std::string c = (std::filesystem::path(dir) / (name + ".c")).string();
    write_files_atomically({{h, header}, {c, source}});
    return {h, c};
  }
};

namespace codegen {

/// True if the linear blocks are generated in delta form under `o` (see
/// `CodegenOptions::linear_form`). Throws `nlid::Error` for `delta` with double precision.
inline bool use_delta_form(const CodegenOptions& o) {
  require(!(o.linear_form == LinearForm::delta && o.precision == Precision::double_precision),
          "codegen: the delta form of linear blocks is for single precision (double code is nlid's direct form, "
          "bit for bit); use LinearForm::automatic or direct",
          at_parameter("linear_form"));
  return o.precision == Precision::single_precision && o.linear_form != LinearForm::direct;
}

/// Throws unless `name` is a C identifier that does not start with "nlid_" (reserved for helpers)
/// and is not the base name of a C99/C11 standard header (math, stdio, …: NAME.h would shadow it).
inline void check_name(const std::string& name) {
  bool ok = !name.empty() && (std::isalpha(static_cast<unsigned char>(name[0])) || name[0] == '_');
  for (char c : name) ok = ok && (std::isalnum(static_cast<unsigned char>(c)) || c == '_');
  require(ok, "codegen: name '" + name + "' is not a C identifier (letters, digits, '_', not starting with a digit)",
          at_parameter("name"));
  require(name.rfind("nlid_", 0) != 0 || name == "nlid_model",
          "codegen: names starting with 'nlid_' are reserved for generated helpers", at_parameter("name"));
  // DIR/NAME.h would shadow a standard header of that name wherever DIR is on the include path
  // (the generated source itself includes <math.h>). C compares header names case-sensitively.
  for (const char* h : {"assert", "complex", "ctype", "errno", "fenv", "float", "inttypes", "iso646", "limits",
                        "locale", "math", "setjmp", "signal", "stdarg", "stdbool", "stddef", "stdint", "stdio",
                        "stdlib", "string", "tgmath", "time", "wchar", "wctype",  // C99
                        "stdalign", "stdatomic", "stdnoreturn", "threads", "uchar"})  // C11
    require(name != h,
            "codegen: name '" + name + "' is the name of the C standard header <" + name + ".h>: the generated " + name +
                ".h would shadow it wherever its directory is on the include path; choose another name",
            at_parameter("name"));
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
  std::string x0_parameter = "equilibrium_input";  ///< the option x0 came from (for errors)
};

/// `CodegenOptions::initial_state` checked against a model whose state in nlid's layout has `n`
/// values (`layout` says what they are): not together with `equilibrium_input`, the right
/// count, every value finite. Empty when no state was given. Sets `m`'s x0 documentation.
inline std::optional<Eigen::VectorXd> given_initial_state(const CodegenOptions& o, Eigen::Index n, const std::string& layout,
                                                          ModelShape& m) {
  if (!o.initial_state) return std::nullopt;
  require(!o.equilibrium_input,
          "codegen: CodegenOptions::initial_state and equilibrium_input are both set; NAME_init has one start",
          at_parameter("initial_state"));
  require(o.initial_state->size() == n,
          "codegen: initial_state has " + std::to_string(o.initial_state->size()) + " values, the model's state has " +
              std::to_string(n) + " (" + layout + ")",
          at_parameter("initial_state"));
  for (Eigen::Index i = 0; i < n; ++i)
    require(std::isfinite((*o.initial_state)(i)),
            "codegen: initial_state[" + std::to_string(i) + "] = " + nlid::detail::format_g((*o.initial_state)(i)) +
                " is not finite",
            at_parameter("initial_state"));
  m.x0_doc = "the state given at generation (CodegenOptions::initial_state)";
  m.x0_parameter = "initial_state";
  return o.initial_state;
}

/// The held input of an equilibrium start for NAME_init's comment: every input, since a comment
/// naming u[0] alone misdescribes a multi-input start, and a physics without inputs has none.
inline std::string held_input_text(const Eigen::VectorXd& u) {
  if (u.size() == 0) return "with no input";
  if (u.size() == 1) return "for u held at " + nlid::detail::format_g(u(0), 17);
  std::string s = "for u held at [";
  for (Eigen::Index i = 0; i < u.size(); ++i) s += (i ? ", " : "") + nlid::detail::format_g(u(i), 17);
  return s + "]";
}

/// Plain ASCII for the generated files: embedded compilers and MSVC under a non-UTF-8 code page
/// reject or mangle other bytes, and the only non-ASCII text nlid writes is in comments (model
/// descriptions, equations, units). Common symbols are spelled out (θ → theta, ² → ^2,
/// — → --); any other character becomes <U+XXXX>, so nothing is lost silently.
inline std::string ascii_text(const std::string& text) {
  struct Entry {
    unsigned cp;
    const char* ascii;
  };
  static constexpr Entry table[] = {
      {0x2014, "--"},
      {0x2013, "-"},
      {0x2212, "-"},
      {0x2026, "..."},
      {0x00B7, "*"},
      {0x22C5, "*"},
      {0x00D7, "x"},
      {0x00B1, "+/-"},
      {0x2264, "<="},
      {0x2265, ">="},
      {0x2260, "!="},
      {0x2248, "~"},
      {0x2192, "->"},
      {0x2190, "<-"},
      {0x221E, "inf"},
      {0x221A, "sqrt"},
      {0x2211, "sum"},
      {0x03A3, "Sum"},
      {0x2202, "d"},
      {0x2208, " in "},
      {0x2218, "o"},
      {0x2016, "||"},
      {0x2298, "/"},
      {0x00B0, " deg"},
      {0x2032, "'"},
      {0x2033, "''"},
      {0x2018, "'"},
      {0x2019, "'"},
      {0x201C, "\""},
      {0x201D, "\""},
      {0x00A0, " "},
      {0x00B2, "^2"},
      {0x00B3, "^3"},
      {0x00B9, "^1"},
      {0x2070, "^0"},
      {0x2074, "^4"},
      {0x2075, "^5"},
      {0x2076, "^6"},
      {0x2077, "^7"},
      {0x2078, "^8"},
      {0x2079, "^9"},
      {0x207B, "^-"},
      {0x1D40, "^T"},
      {0x1D4F, "^k"},
      {0x1D50, "^m"},
      {0x2080, "0"},
      {0x2081, "1"},
      {0x2082, "2"},
      {0x2083, "3"},
      {0x2084, "4"},
      {0x2085, "5"},
      {0x2086, "6"},
      {0x2087, "7"},
      {0x2088, "8"},
      {0x2089, "9"},
      {0x2096, "k"},
      {0x2097, "l"},
      {0x2099, "n"},
      {0x1D62, "i"},
      {0x2C7C, "j"},
      {0x1D65, "v"},
      {0x03B1, "alpha"},
      {0x03B2, "beta"},
      {0x03B3, "gamma"},
      {0x03B4, "delta"},
      {0x0394, "Delta"},
      {0x03B5, "eps"},
      {0x03B6, "zeta"},
      {0x03B7, "eta"},
      {0x03B8, "theta"},
      {0x0398, "Theta"},
      {0x03BA, "kappa"},
      {0x03BB, "lambda"},
      {0x039B, "Lambda"},
      {0x03BC, "mu"},
      {0x03BD, "nu"},
      {0x03BE, "xi"},
      {0x03C0, "pi"},
      {0x03C1, "rho"},
      {0x03C3, "sigma"},
      {0x03C4, "tau"},
      {0x03C6, "phi"},
      {0x03A6, "Phi"},
      {0x03C7, "chi"},
      {0x03C8, "psi"},
      {0x03C9, "omega"},
      {0x03A9, "Omega"},
      {0x2113, "l"},
      {0x1E8B, "xdot"},
      {0x1E8F, "ydot"},
      {0x1E23, "hdot"},
      {0x00FF, "yddot"},
      {0x0177, "yhat"},
      {0x016B, "ubar"},
      {0x0233, "ybar"},
      {0x00F6, "o"},
      {0x00E9, "e"},
      {0x00FC, "u"},
      {0x00E4, "a"}};
  std::string out;
  out.reserve(text.size());
  for (std::size_t i = 0; i < text.size();) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c < 0x80) {
      out += static_cast<char>(c);
      ++i;
      continue;
    }
    // Decode one UTF-8 sequence; a malformed byte is shown by its value.
    const int len = c >= 0xF0 ? 4 : c >= 0xE0 ? 3 : c >= 0xC0 ? 2 : 1;
    unsigned cp = len == 4 ? (c & 0x07u) : len == 3 ? (c & 0x0Fu) : len == 2 ? (c & 0x1Fu) : c;
    bool ok = len > 1 && i + static_cast<std::size_t>(len) <= text.size();
    for (int k = 1; ok && k < len; ++k) {
      const auto d = static_cast<unsigned char>(text[i + static_cast<std::size_t>(k)]);
      ok = (d & 0xC0u) == 0x80u;
      cp = (cp << 6) | (d & 0x3Fu);
    }
    if (!ok) {
      cp = c;
      i += 1;
    } else {
      i += static_cast<std::size_t>(len);
    }
    const char* rep = nullptr;
    for (const Entry& e : table)
      if (e.cp == cp) rep = e.ascii;
    if (rep != nullptr) {
      out += rep;
    } else if (cp == 0x0307 || cp == 0x0302 || cp == 0x0304) {
      out += cp == 0x0307 ? "dot" : cp == 0x0302 ? "hat" : "bar";  // combining accents after a letter
    } else {
      char buf[16];
      std::snprintf(buf, sizeof buf, "<U+%04X>", cp);
      out += buf;
    }
  }
  return out;
}

/// Refuses a state of more values than the step's line budget (`TraceLimits::max_lines`, each
/// state value is at least one generated line), before anything of its size is built. `nx` is
/// counted in 64 bits by the caller: a lag window of many inputs each delayed 10⁵ samples (a few
/// kilobytes of model file) would otherwise become gigabytes of C.
inline void check_state_count(long long nx, const CodegenOptions& o, const char* kind) {
  if (nx > o.limits.max_lines) {
    throw Error(std::string("codegen: the ") + kind + " model's state has " + std::to_string(nx) +
                    " values, more than the TraceLimits::max_lines = " + std::to_string(o.limits.max_lines) +
                    " lines its step may have (its delays and lags make it that long)",
                at_parameter("limits"));
  }
}

/// The sample time of a sampled (discrete-time) model's code: the model's own, or `option` when
/// the model has none; a different `option` is refused (it would relabel, not resample).
inline double sampled_model_ts(double model_ts, double option) {
  if (!(option > 0)) return model_ts;
  require(std::isfinite(option), "codegen: CodegenOptions::ts must be finite", at_parameter("ts"));
  require(!(model_ts > 0) || same_sample_time(option, model_ts),
          "codegen: the model was estimated at sample time " + nlid::detail::format_g(model_ts, 10) +
              " s; its code cannot run at CodegenOptions::ts = " + nlid::detail::format_g(option, 10) +
              " s (its coefficients belong to its own sample time)",
          at_parameter("ts"));
  return option;
}

/// Text that can stand inside a C block comment: every "*/" (which would end it) becomes "* /",
/// and every "/*" becomes "/ *" (a nested opener is legal C, but -Wcomment warns of it and
/// -Werror builds fail). Channel names and equations come from users' files.
inline std::string comment_text(std::string text) {
  for (std::size_t p = 0; (p = text.find("*/", p)) != std::string::npos;) text.replace(p, 2, "* /");
  for (std::size_t p = 0; (p = text.find("/*", p)) != std::string::npos;) text.replace(p, 2, "/ *");
  return text;
}

/// Text as a C block comment (through comment_text).
inline std::string comment_block(const std::string& text, const std::string& indent = "") {
  std::string s = indent + "/*\n";
  std::string line;
  auto flush = [&]() {
    s += indent + " * " + comment_text(line) + "\n";
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
  h += "/* " + m.name + ".h -- generated by nlid (header-only C++ system identification) from a " + m.kind +
       " model.\n * Dependency-free C99: include this header, compile " + m.name +
       ".c with your code, link with -lm.\n *\n";
  h += " *   " + m.name + "_state s;\n *   " + m.name + "_init(&s);\n *   each sample: if (" + m.name +
       "_step(&s, u, y) != 0) { non-finite sample: state kept, y not usable }\n"
       " *   (u: inputs at t, y: outputs at t)\n */\n";
  h += "#ifndef " + M + "_H\n#define " + M + "_H\n\n#ifdef __cplusplus\nextern \"C\" {\n#endif\n\n";
  h += "#define " + M + "_NUM_STATES " + std::to_string(m.nx) + "\n";
  h += "#define " + M + "_NUM_INPUTS " + std::to_string(m.nu) + "\n";
  h += "#define " + M + "_NUM_OUTPUTS " + std::to_string(m.ny) + "\n";
  h += "#define " + M + "_NUM_PARAMS " + std::to_string(m.parameters.size()) + "\n";
  h += "#define " + M + "_SAMPLE_TIME " + c_literal(m.ts) + " /* seconds */\n\n";
  h += "/* The type of every real value of this model (states, inputs, outputs, parameters). */\ntypedef " + c_real() +
       " " + m.name + "_real;\n\n";
  h += comment_block("State: " + m.state_doc);
  h += "typedef struct {\n  " + c_real() + " x[" + std::to_string(nxs) + "];" + (m.nx == 0 ? " /* unused: the model has no state */" : "") +
       "\n} " + m.name + "_state;\n\n";
  h += "/* Sets the state to " + m.name + "_x0 (" + m.x0_doc + "). */\nvoid " + m.name + "_init(" + m.name +
       "_state* s);\n";
  h += "/* Sets the state to x (" + M + "_NUM_STATES values, layout above). */\nvoid " + m.name + "_set_state(" +
       m.name + "_state* s, const " + c_real() + "* x);\n";
  h += "/* One sample: outputs y (" + M + "_NUM_OUTPUTS) at time t from the state and inputs u (" + M +
       "_NUM_INPUTS) at t;\n   then advances the state to t + 1. Returns 0; returns 1 and leaves the state as it was\n"
       "   when an input, an output or the next state is not finite (NaN/inf: a sensor fault, an input\n"
       "   that overflows the model), so one bad sample does not corrupt the state (y then holds what\n"
       "   the model gives for that input, e.g. NaN). Compile without -ffast-math (it drops the check). */\nint " + m.name + "_step(" + m.name +
       "_state* s, const " + c_real() + "* u, " + c_real() + "* y);\n";
  h += "/* The estimated parameters (" + M + "_NUM_PARAMS values, read-only). */\nconst " + c_real() + "* " + m.name +
       "_parameters(void);\n\n";
  h += "#ifdef __cplusplus\n}\n#endif\n\n#endif /* " + M + "_H */\n";
  return h;
}

/// The top of NAME.c: includes, the model description, parameter and initial-state tables, helpers.
inline std::string make_source_prelude(const ModelShape& m, const std::set<std::string>& helpers) {
  std::string s = "/* " + m.name + ".c -- generated by nlid; see " + m.name + ".h. Do not edit: regenerate. */\n";
  s += "#include \"" + m.name + ".h\"\n\n#include <math.h>\n\n";
  s += comment_block("Model:\n" + m.description);
  s += single_precision() ? "\n/* Parameters (the estimated values rounded to float). */\n"
                           : "\n/* Parameters (17 significant digits: the exact estimated doubles). */\n";
  const auto np = m.parameters.size();
  s += "static const " + c_real() + " " + m.name + "_p[" + std::to_string(np > 0 ? np : 1) + "] = {\n";
  if (np == 0) s += "    " + c_literal(0.0) + " /* no parameters */\n";
  for (Eigen::Index i = 0; i < np; ++i) {
    const std::string pn = static_cast<std::size_t>(i) < m.parameter_names.size() ? m.parameter_names[static_cast<std::size_t>(i)]
                                                                                : "p" + std::to_string(i);
    s += "    " + c_literal(m.parameters(i)) + (i + 1 < np ? "," : " ") + " /* [" + std::to_string(i) + "] " +
         comment_text(pn) + " */\n";
  }
  s += "};\n\n";
  const int nxs = m.nx > 0 ? m.nx : 1;
  // A start the generated step would refuse at every sample (non-finite, or beyond float's range
  // in single precision, where it is written as HUGE_VALF) is an error here, not on the target.
  for (Eigen::Index i = 0; i < m.x0.size(); ++i) {
    const double v = m.x0(i);
    require(std::isfinite(v) && !(single_precision() && beyond_float_range(v)),
            "codegen: the initial state x0[" + std::to_string(i) + "] = " + nlid::detail::format_g(v) + " (" + m.x0_doc +
                ") is " + (std::isfinite(v) ? "beyond float's range" : "not finite") +
                ": every step would refuse it; " +
                (m.x0_parameter == "initial_state" ? "choose another initial state"
                                                   : "choose another equilibrium input or the zero start"),
            at_parameter(m.x0_parameter));
  }
  s += "/* Initial state: " + m.x0_doc + ". */\nstatic const " + c_real() + " " + m.name + "_x0[" + std::to_string(nxs) + "] = {";
  for (int i = 0; i < nxs; ++i) s += std::string(i ? ", " : "") + c_literal(i < m.x0.size() ? m.x0(i) : 0.0);
  s += "};\n\n";
  for (const auto& h : helpers) s += helper_source(h) + "\n";
  const std::string M = macro(m.name);
  s += "void " + m.name + "_init(" + m.name + "_state* s) {\n  int i;\n  for (i = 0; i < " + std::to_string(nxs) +
       "; ++i) s->x[i] = " + m.name + "_x0[i];\n}\n\n";
  s += "void " + m.name + "_set_state(" + m.name + "_state* s, const " + c_real() + "* x) {\n  int i;\n  for (i = 0; i < " + M +
       "_NUM_STATES; ++i) s->x[i] = x[i];\n}\n\n";
  s += "const " + c_real() + "* " + m.name + "_parameters(void) { return " + m.name + "_p; }\n\n";
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

/// Opening line of the model's own one-sample step: a static function `NAME_advance` that the
/// public `NAME_step` (`checked_step_function`) calls on a copy of the state.
inline std::string model_step_head(const std::string& name) {
  return "static void " + name + "_advance(" + name + "_state* s, const " + c_real() + "* u, " + c_real() + "* y) {\n";
}

/// The public `NAME_step`: `NAME_advance` on a copy of the state, kept only when the inputs,
/// the outputs and the next state are all finite (returns 0; otherwise 1, state unchanged).
/// `isfinite` is C99's <math.h> macro (compile without -ffinite-math-only / -ffast-math, which
/// let the compiler assume it true).
inline std::string checked_step_function(const std::string& name) {
  const std::string M = macro(name), R = c_real();
  return "/* One sample (see " + name + ".h): the model's step on a copy of the state, kept only when the\n"
         "   inputs, the outputs and the next state are all finite; otherwise the state stays as it was. */\n"
         "int " + name + "_step(" + name + "_state* s, const " + R + "* u, " + R + "* y) {\n"
         "  " + name + "_state next = *s;\n  int i, ok = 1;\n"
         "  " + name + "_advance(&next, u, y);\n"
         "  for (i = 0; i < " + M + "_NUM_INPUTS; ++i) ok = ok && isfinite(u[i]);\n"
         "  for (i = 0; i < " + M + "_NUM_OUTPUTS; ++i) ok = ok && isfinite(y[i]);\n"
         "  for (i = 0; i < " + M + "_NUM_STATES; ++i) ok = ok && isfinite(next.x[i]);\n"
         "  if (!ok) return 1;\n"
         "  *s = next;\n"
         "  return 0;\n"
         "}\n";
}

/// A step function for a one-step map traced as [y; x_next]: computes into y and xn, then
/// copies xn into the state (so every new state value is computed from the old ones).
inline std::string discrete_step_function(const ModelShape& m, const TracedFunction& f) {
  std::vector<std::string> t = targets("y", m.ny);
  for (int i = 0; i < m.nx; ++i) t.push_back("xn[" + std::to_string(i) + "]");
  std::string s = model_step_head(m.name);
  if (m.nx > 0) s += "  " + c_real() + " xn[" + std::to_string(m.nx) + "];\n  int i;\n";
  s += "  (void)s;\n  (void)u;\n";
  s += emit_c(f, t, "  ");
  if (m.nx > 0) s += "  for (i = 0; i < " + std::to_string(m.nx) + "; ++i) s->x[i] = xn[i];\n";
  return s + "}\n\n" + checked_step_function(m.name);
}

}  // namespace codegen
}  // namespace nlid
