// libFuzzer harness for model specifications (models/spec.hpp): `parse_model_spec`, then
// `make_model` and, for small models, a short simulation, `describe`, and a fit of one or two
// iterations on a tiny record.
//
// Contract checked here:
// - a spec the parser refuses throws nlid::Error naming a parameter (the field: "model", "na",
//   "units", ...) whose message quotes the spec (so a command line's mistake is shown in place),
//   unless the spec is empty; any other exception, a sanitizer report, a hang or a huge
//   allocation is a defect;
// - a parsed spec has a known family, the orders and maps that family takes, orders within the
//   model-file limits (max_model_order) and map sizes the maps accept;
// - make_model either builds the model or throws nlid::Error (a size a component refuses, an
//   unknown grey-box physics, an input count the family does not take) — never std::bad_alloc:
//   absurd sizes must be refused before anything is allocated;
// - a model built has the input count asked for, one output, finite parameters whose names
//   match them, and a description; simulating a short record gives its shape or nlid::Error;
// - fitting on a tiny record either returns a model of the same kind or throws nlid::Error.
//
// The harness bounds the work per input (not the spec language): models with more than
// `spec_fuzz_max_parameters` parameters or a longer memory than the record are built but not
// simulated (past `spec_fuzz_max_described` not named or described either), and the fit runs
// one iteration, with at most two starts of two iterations.
//
// Seeds: tests/fuzz/seeds/spec/; dictionary: tests/fuzz/spec.dict.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <new>
#include <string>
#include <typeinfo>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/core/sizes.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/data/experiment.hpp"
#include "nlid/models/spec.hpp"

#include "fuzz_support.hpp"

namespace {

constexpr int spec_fuzz_max_parameters = 400;
constexpr int spec_fuzz_max_described = 200000;

[[noreturn]] void spec_fuzz_defect(const std::string& what, const std::string& text) {
  std::fprintf(stderr, "spec_fuzz: DEFECT: %s\n  spec: '%s'\n", what.c_str(), text.c_str());
  std::fflush(stderr);
  std::abort();
}

// Runs `f`; an nlid::Error is an accepted outcome (returns false), any other exception a defect.
template <class F>
bool spec_fuzz_try(const char* step, const std::string& text, F&& f) {
  return nlid_fuzz::run_step(step, "spec", f, [&](const std::string& what) { spec_fuzz_defect(what, text); });
}

// A short record of a mildly nonlinear first-order system: steps and a slow sine in.
nlid::Experiment spec_fuzz_record(int nu, int n) {
  Eigen::MatrixXd u(n, nu), y(n, 1);
  double x = 0;
  for (int k = 0; k < n; ++k) {
    for (int c = 0; c < nu; ++c) u(k, c) = (k / 8 % 2 == 0 ? 0.8 : -0.4) + 0.2 * std::sin(0.3 * k + c);
    x = 0.7 * x + 0.4 * std::tanh(u(k, 0)) + (nu > 1 ? 0.1 * u(k, 1) : 0.0);
    y(k, 0) = x + 0.01 * std::cos(1.7 * k);
  }
  return nlid::Experiment(u, y, 0.1, "fuzz");
}

void spec_fuzz_check_parsed(const nlid::ModelSpec& s, const std::string& text) {
  const std::string& f = s.family;
  std::size_t norders = 0, nmaps = 0;
  if (f == "linear:arx" || f == "linear:oe") norders = 1;
  else if (f == "nlarx" || f == "hammerstein" || f == "wiener") norders = nmaps = 1;
  else if (f == "hw") norders = 1, nmaps = 2;
  else if (f == "wh") norders = 2, nmaps = 1;
  else if (f != "greybox") spec_fuzz_defect("unknown family '" + f + "' accepted", text);
  if (s.orders.size() != norders || s.nonlinearities.size() != nmaps) spec_fuzz_defect("orders or maps miscounted", text);
  if (f == "greybox" && s.physics.empty()) spec_fuzz_defect("grey box without physics", text);
  for (const nlid::OrderSpec& o : s.orders) {
    for (int v : {o.na, o.nb, o.nf, o.nk})
      if (v < -1 || v > nlid::max_model_order) spec_fuzz_defect("order out of range", text);
    if (o.nb < 1 || o.nk < 0) spec_fuzz_defect("nb < 1 or nk < 0 accepted", text);
  }
  for (const nlid::NonlinearitySpec& n : s.nonlinearities) {
    if (!nlid::detail::is_nonlinearity_kind(n.kind)) spec_fuzz_defect("unknown map '" + n.kind + "' accepted", text);
    if (n.options.units < 1 || n.options.breakpoints < 2 || n.options.degree < 1 || n.options.depth < 1) {
      spec_fuzz_defect("a map size below its minimum accepted", text);
    }
  }
  if (s.starts < 1 || s.starts > 64 || (s.start_iterations && *s.start_iterations < 1)) spec_fuzz_defect("starts", text);
  if (!(s.lambda >= 0) || !std::isfinite(s.lambda)) spec_fuzz_defect("lambda not finite and >= 0", text);
}

void spec_fuzz_use(const nlid::ModelSpec& s, const std::string& text, int nu) {
  nlid::AnyModel m;
  if (!spec_fuzz_try("make_model", text, [&] { m = nlid::make_model(s, nu); })) return;
  if (m.empty() || m.num_inputs() != nu || m.num_outputs() != 1) {
    spec_fuzz_defect("make_model built " + std::to_string(m.num_inputs()) + " inputs, asked " + std::to_string(nu), text);
  }
  const Eigen::VectorXd theta = m.parameters();
  if (!theta.allFinite()) spec_fuzz_defect("an unestimated model has a non-finite parameter", text);
  // Names and descriptions cost a string per parameter: a valid network of 10^7 parameters
  // (nlarx:na=7,nb=1,nk=0:wavenet:642160) takes longer than the fuzzer's time-out for them.
  if (theta.size() > spec_fuzz_max_described) return;
  if (m.parameter_names().size() != static_cast<std::size_t>(theta.size())) spec_fuzz_defect("parameter names", text);
  if (m.describe().empty()) spec_fuzz_defect("empty description", text);
  if (theta.size() > spec_fuzz_max_parameters || m.history_length() > 30) return;

  const nlid::Experiment e = spec_fuzz_record(nu, 60);
  Eigen::MatrixXd y;
  if (spec_fuzz_try("simulate", text, [&] { y = m.simulate(e); }) && (y.rows() != e.size() || y.cols() != 1)) {
    spec_fuzz_defect("simulation has the wrong shape", text);
  }
  // Fitting: bounded here, so that one input stays fast (a grey box's multi-start estimation
  // screens many candidates: left out).
  if (s.family == "greybox" || theta.size() > 60) return;
  nlid::ModelSpec bounded = s;
  bounded.starts = std::min(bounded.starts, 2);
  if (bounded.starts < 2) bounded.start_iterations.reset();
  if (bounded.start_iterations) bounded.start_iterations = std::min(*bounded.start_iterations, 2);
  nlid::SpecFitOptions fo;
  fo.iterations = 1;
  nlid::AnyModel fitted;
  if (spec_fuzz_try("fit_model_spec", text, [&] { fitted = nlid::fit_model_spec(bounded, nlid::Dataset(e), fo); })) {
    if (fitted.kind() != m.kind() || fitted.parameters().size() != theta.size()) {
      spec_fuzz_defect("the fitted model differs in kind or size from make_model's", text);
    }
    if (!fitted.parameters().allFinite()) spec_fuzz_defect("a fit returned a non-finite parameter", text);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  nlid::ModelSpec s;
  try {
    s = nlid::parse_model_spec(text);
  } catch (const nlid::Error& e) {
    if (e.where().parameter.empty()) spec_fuzz_defect(std::string("error names no parameter: ") + e.what(), text);
    // An empty spec (nothing but separators and spaces) has nothing to quote.
    if (e.message().find(text) == std::string::npos && e.message().find("empty model spec") == std::string::npos) {
      spec_fuzz_defect(std::string("error does not quote the spec: ") + e.what(), text);
    }
    return 0;
  } catch (const std::bad_alloc&) {
    spec_fuzz_defect("parse_model_spec: std::bad_alloc", text);
  } catch (const std::exception& e) {
    spec_fuzz_defect(std::string("parse_model_spec: ") + typeid(e).name() + ": " + e.what(), text);
  }
  if (s.text != text) spec_fuzz_defect("the spec's text is not the text parsed", text);
  spec_fuzz_check_parsed(s, text);
  spec_fuzz_use(s, text, 1);
  if (s.family == "nlarx" || s.family == "linear:arx") spec_fuzz_use(s, text, 2);
  // A family that takes one input refuses two with nlid::Error.
  if (s.family != "nlarx" && s.family != "linear:arx" &&
      spec_fuzz_try("make_model(2 inputs)", text, [&] { (void)nlid::make_model(s, 2); })) {
    spec_fuzz_defect("a one-input family accepted two inputs", text);
  }
  return 0;
}
