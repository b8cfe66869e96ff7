// nlid-fit: estimate a model chosen at run time by a short text spec on CSV recordings, print
// progress (stderr) and a fit summary (stdout), and save it as a versioned model file.
//
//   nlid-fit --model SPEC --est a.csv [--est b.csv] [--val c.csv] [--input u] [--output y]
//            [--time t] [--ts T] [--delimiter C] [--decimal C]
//            [--decimate N] [--iterations N] [--rows FIRST:LAST] --save model.json
//
// SPEC grammar: include/nlid/models/spec.hpp and docs/tools.md. Exit status (cli_common.hpp) 0 on
// success, 1 on a bad file, data or model or a failed run (the message on stderr names the
// file/row/column/option), 2 on a bad command line (including a SPEC that does not parse).
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "nlid/analysis/fit.hpp"
#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/core/sample_time.hpp"
#include "nlid/core/utf8.hpp"
#include "nlid/data/csv.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/data/resample.hpp"
#include "nlid/io/json.hpp"
#include "nlid/models/any_model.hpp"
#include "nlid/models/greybox_dynamic.hpp"
#include "nlid/models/spec.hpp"
#include "cli_common.hpp"
#include "linear_poles.hpp"
#include "record_options.hpp"

namespace {

constexpr const char* kUsageHead =
    "usage: nlid-fit --model SPEC --est a.csv [--est b.csv ...] [--val c.csv ...] [--input u] [--output y]\n"
    "                [--time t] [--ts T] [--delimiter C] [--decimal C] [--time-tolerance R]\n"
    "                [--decimate N] [--iterations N] [--rows FIRST:LAST] --save model.json\n"
    "  SPEC examples: linear:arx:na=2,nb=1,nk=0   linear:oe:nb=2,nf=2,nk=0\n"
    "                 nlarx:na=3,nb=3,nk=0:sigmoidnet:units=5   hw:nb=3,nf=3,nk=0:in=pwlinear:10:out=saturation\n"
    "                 wh:nb=4,nf=3,nk=0:poly1d:9:nb=4,nf=3,nk=0   hammerstein:poly1d:3:nb=2,nf=2,nk=0\n"
    "                 wiener:nb=2,nf=2,nk=1:saturation   greybox:throttle\n"
    "  --rows FIRST:LAST keeps rows FIRST..LAST-1 (0-based data rows) of every file (e.g. a benchmark split).\n"
    "Reading the CSV files:\n";

std::string usage_text() { return std::string(kUsageHead) + nlid_tools::record_usage; }

struct Args {
  std::string model, save, input = "u", output = "y";
  std::vector<std::string> est, val;
  int decimate = 1, iterations = -1;
  long first = 0, last = -1;
  nlid_tools::RecordOptions record;
};

using nlid_tools::UsageError;

// The command line as Args; nullopt when it asks for the help text.
std::optional<Args> parse(int argc, char** argv) {
  using nlid_tools::OptionSpec;
  const nlid_tools::ParsedOptions p = nlid_tools::parse_options(
      argc, argv,
      nlid_tools::with_record_options({{"--model"},
                                       {"--est", OptionSpec::repeated},
                                       {"--val", OptionSpec::repeated},
                                       {"--input"},
                                       {"--output"},
                                       {"--save"},
                                       {"--decimate"},
                                       {"--rows"},
                                       {"--iterations"}}));
  if (p.help) return std::nullopt;
  Args a;
  a.model = p.get("--model");
  a.est = p.all("--est");
  a.val = p.all("--val");
  a.input = p.get("--input", a.input);
  a.output = p.get("--output", a.output);
  a.save = p.get("--save");
  a.decimate = p.get_int("--decimate", 1, 1000000, a.decimate);
  a.iterations = p.get_int("--iterations", 0, 1000000, a.iterations);
  if (p.has("--rows")) {
    const std::string v = p.get("--rows");
    const auto c = v.find(':');
    if (c == std::string::npos) throw UsageError("--rows needs FIRST:LAST, got '" + v + "'");
    a.first = nlid_tools::parse_integer("--rows FIRST", v.substr(0, c), 0, std::numeric_limits<long>::max());
    a.last = nlid_tools::parse_integer("--rows LAST", v.substr(c + 1), 0, std::numeric_limits<long>::max());
    if (a.last <= a.first) throw UsageError("--rows " + v + " needs 0 <= FIRST < LAST (rows FIRST..LAST-1 are kept)");
  }
  a.record = nlid_tools::record_options_from(p);
  // The model file names its channels in UTF-8: a column name in another encoding would fail the
  // save after the whole estimation.
  for (const auto& [flag, name] : {std::pair<const char*, const std::string&>{"--input", a.input}, {"--output", a.output}}) {
    const std::size_t bad = nlid::first_invalid_utf8(name);
    if (bad != std::string::npos)
      throw UsageError(std::string(flag) + " '" + name + "' is not valid UTF-8 (byte " + std::to_string(bad) +
                       "); model files name channels in UTF-8: rename the column");
  }
  // Options that do not go together are a usage error (exit 2), found before any file is read.
  if (a.input == a.output)
    throw UsageError("--input and --output both name column '" + a.input + "': a channel is either the input or the output");
  if (a.model.empty()) throw UsageError("--model SPEC is required");
  if (a.est.empty()) throw UsageError("at least one --est FILE is required");
  if (a.save.empty()) throw UsageError("--save FILE is required");
  std::vector<nlid_tools::FlagPath> inputs;
  for (const auto& f : a.est) inputs.emplace_back("--est", f);
  for (const auto& f : a.val) inputs.emplace_back("--val", f);
  nlid_tools::check_outputs_distinct({{"--save", a.save}}, inputs);
  return a;
}

nlid::Experiment load(const std::string& path, const Args& a) {
  nlid::Experiment e;
  try {
    e = nlid_tools::read_record(a.record, path, {a.input}, {a.output}, "nlid-fit");
  } catch (const nlid::Error& err) {
    // nlid-sim's --column takes a list; here "u,v" is one (missing) column name.
    const bool listed = a.input.find(',') != std::string::npos || a.output.find(',') != std::string::npos;
    if (!listed || err.message().find("not found") == std::string::npos) throw;
    throw nlid::Error(err.message() + " (nlid-fit fits one input and one output: --input and --output each name one column)",
                      err.where());
  }
  if (a.last >= 0) {  // --rows given; parse() has checked 0 <= FIRST < LAST
    const long last = a.last;
    if (last > e.size())
      throw nlid::Error("--rows " + std::to_string(a.first) + ":" + std::to_string(last) + " is outside the " +
                            std::to_string(e.size()) + " data rows of " + path,
                        nlid::at_parameter("--rows"));
    nlid::Experiment s(e.u().middleRows(a.first, last - a.first), e.y().middleRows(a.first, last - a.first), e.ts());
    s.set_t0(e.t0() + static_cast<double>(a.first) * e.ts());
    s.set_input_names(e.input_names());
    s.set_output_names(e.output_names());
    e = s;
  }
  if (a.decimate > 1) {
    try {
      e = nlid::decimate(e, a.decimate);
    } catch (const nlid::Error& err) {
      // With several --est/--val files the library's message alone does not say which is short.
      nlid::Location l = nlid::at_parameter("--decimate");
      l.file = path;
      throw nlid::Error(err.message(), l);
    }
  }
  std::string name = path;
  const auto slash = name.find_last_of('/');
  if (slash != std::string::npos) name = name.substr(slash + 1);
  // The name is saved in the model file, which holds UTF-8 only: repaired now, the save after
  // the estimation cannot fail on a file name in another encoding.
  e.set_name(nlid::valid_utf8(name));
  return e;
}

// One row of the fit table. A model whose free run diverges on a record (a prediction-focus
// model can be unstable in simulation) is reported as such: the model is saved and usable for
// prediction, and the other records are still scored. So is a record the model cannot be
// scored on (shorter than its history, a constant output for fit %): the row says why, the
// table and the summary go on.
void print_fit_row(const char* role, const nlid::AnyModel& m, const nlid::Experiment& e) {
  Eigen::MatrixXd y;
  try {
    y = m.simulate(e);
  } catch (const nlid::DivergenceError& d) {
    std::printf("%-12s %-30s %10s %14s  (free run not finite from sample %ld)\n", role, e.name().c_str(), "diverged", "-",
                d.sample());
    return;
  } catch (const nlid::Error& err) {
    std::printf("%-12s %-30s %10s %14s  (not scored: %s)\n", role, e.name().c_str(), "-", "-", err.message().c_str());
    return;
  }
  // Linear and grey-box models do not throw on a diverging free run: their output turns inf/NaN.
  for (Eigen::Index i = 0; i < y.rows(); ++i) {
    if (!y.row(i).allFinite()) {
      std::printf("%-12s %-30s %10s %14s  (free run not finite from sample %ld)\n", role, e.name().c_str(), "diverged",
                  "-", static_cast<long>(i));
      return;
    }
  }
  const Eigen::VectorXd d = y.col(0) - e.y().col(0);
  const double rmse = std::sqrt(d.squaredNorm() / static_cast<double>(d.size()));
  try {
    const double f = nlid::fit_percent(Eigen::VectorXd(e.y().col(0)), Eigen::VectorXd(y.col(0)));
    std::printf("%-12s %-30s %10s %14s\n", role, e.name().c_str(), nlid::detail::format_f(f, 4).c_str(),
                nlid::detail::format_g(rmse, 6).c_str());
  } catch (const nlid::Error& err) {
    std::printf("%-12s %-30s %10s %14s  (fit %% not defined: %s)\n", role, e.name().c_str(), "-",
                nlid::detail::format_g(rmse, 6).c_str(), err.message().c_str());
    return;
  }
}

// The solver's stopping message when it did not certify a solution, up to its first "; " (the
// counts after it make the line long), else "". The model file keeps the whole message, but a
// file is not where one learns that --iterations cut the estimation short.
std::string unconverged_status(const nlid::AnyModel& m) {
  const nlid::Json j = m.to_json();
  const nlid::JsonView v = j.view();
  if (!v.contains("report")) return {};
  const nlid::JsonView r = v.at("report");
  std::string s = r.contains("status") ? r.at("status").as_string()
                  : r.contains("solver_message") ? r.at("solver_message").as_string()
                                                 : std::string();
  if (s.find("(not converged)") == std::string::npos && s.find("(stalled") == std::string::npos) return {};
  const auto cut = s.find("; ");
  if (cut != std::string::npos) s.resize(cut);
  return s;
}

}  // namespace

int main(int argc, char** argv) {
  std::string stage = "reading the command line", sizes;
  return nlid_tools::guarded_main("nlid-fit", usage_text(), stage, sizes, [&]() -> int {
    const std::optional<Args> parsed = parse(argc, argv);
    if (!parsed) {
      std::cout << usage_text();
      return nlid_tools::exit_ok;
    }
    const Args& a = *parsed;
    nlid::ModelSpec spec;
    try {
      spec = nlid::parse_model_spec(a.model);
      // An unknown physics is a SPEC that does not parse: say so before any data are read.
      if (spec.family == "greybox") (void)nlid::make_physics(spec.physics);
    } catch (const nlid::Error& e) {
      throw UsageError(e.what());
    }
    nlid_tools::check_output_file("--save", a.save);
    nlid::Dataset est, val;
    // A record that does not join the others (another sample time, other channels) is named by
    // its file: the data set's message knows only the experiment index.
    const auto add = [&](nlid::Dataset& set, const std::string& p) {
      stage = "reading " + p;
      nlid::Experiment e = load(p, a);
      try {
        set.add(std::move(e));
      } catch (const nlid::Error& err) {
        nlid::Location l = err.where();
        l.file = p;
        throw nlid::Error(err.message(), l);
      }
    };
    for (const auto& p : a.est) add(est, p);
    for (const auto& p : a.val) add(val, p);
    {
      std::vector<const nlid::Experiment*> records;
      for (const auto& e : est) records.push_back(&e);
      nlid_tools::check_inputs_vary(records, a.est, "--est");
    }
    if (val.size() > 0 && !nlid::same_sample_time(val.ts(), est.ts())) {
      nlid::Location where = nlid::at_parameter("--val");
      where.file = a.val.front();  // the validation set's sample time is its first record's
      // 10 digits: std::to_string's six decimals printed 20 µs as "0.000020" for both sides
      throw nlid::Error("validation data have sample time " + nlid::detail::format_g(val.ts(), 10) +
                            " s, estimation data " + nlid::detail::format_g(est.ts(), 10) +
                            " s (relative difference " + nlid::detail::format_g(std::abs(val.ts() - est.ts()) / est.ts(), 3) +
                            "); " + nlid_tools::sample_time_remedy(val.ts(), est.ts()),
                        where);
    }
    double yss = 0.0;
    {
      double n = 0.0, s = 0.0;
      for (const auto& e : est) {
        s += e.y().col(0).sum();
        n += static_cast<double>(e.size());
      }
      for (const auto& e : est) yss += (e.y().col(0).array() - s / n).square().sum();
    }
    std::cerr << "nlid-fit: estimating " << a.model << " on " << est.size() << " experiment(s), "
              << est.total_samples() << " samples, ts = " << est.ts() << " s\n";
    nlid::SpecFitOptions fo;
    fo.iterations = a.iterations;
    fo.progress = [](const std::string& s) { std::cerr << "  " << s << "\n"; };
    std::optional<nlid::ParameterUncertainty> uncertainty;
    fo.uncertainty = [&uncertainty](const nlid::ParameterUncertainty& u) { uncertainty = u; };
    // On the validation records: is what the model misses there within its parameters' reach?
    std::optional<nlid::SimulationBand> band;
    fo.band_data = val;
    fo.band = [&band](const nlid::SimulationBand& b) { band = b; };
    // With regularization the cost includes the penalty, so it no longer measures the fit.
    const bool penalised = spec.lambda > 0.0;
    fo.callback = [yss, penalised](const nlid::IterationReport& r) {
      const double fit = yss > 0 ? 100.0 * (1.0 - std::sqrt(std::max(0.0, 2.0 * r.cost) / yss)) : 0.0;
      char buf[160];
      if (penalised)
        std::snprintf(buf, sizeof buf, "  iteration %4d  cost %s (with the lambda penalty)%s\n", r.iteration,
                      nlid::detail::format_g(r.cost, 6).c_str(), r.step_accepted ? "" : "  (step rejected)");
      else
        std::snprintf(buf, sizeof buf, "  iteration %4d  cost %s  fit %s %%%s\n", r.iteration,
                      nlid::detail::format_g(r.cost, 6).c_str(), nlid::detail::format_f(fit, 4).c_str(),
                      r.step_accepted ? "" : "  (step rejected)");
      std::cerr << buf;
      return true;
    };
    // The estimation's own time: reading the files before and the uncertainty and band after it
    // are timed apart (the uncertainty of a large model can take longer than its estimation).
    using Clock = std::chrono::steady_clock;
    std::optional<Clock::time_point> t_estimated;
    fo.estimated = [&t_estimated] { t_estimated = Clock::now(); };
    stage = "estimating " + a.model;
    sizes = std::to_string(est.total_samples()) + " samples in " + std::to_string(est.size()) + " record(s)";
    const auto t0 = Clock::now();
    nlid::AnyModel m = nlid::fit_model_spec(spec, est, fo);
    const auto t1 = Clock::now();
    const double secs = std::chrono::duration<double>(t_estimated.value_or(t1) - t0).count();
    const double after = std::chrono::duration<double>(t1 - t_estimated.value_or(t1)).count();
    stage = "saving " + a.save;
    m.save(a.save);
    if (const std::string status = unconverged_status(m); !status.empty()) {
      std::cerr << "nlid-fit: warning: the estimation did not converge (" << status
                << "); the model is saved as it stands"
                << (status.find("max_iterations_reached") != std::string::npos ? ": more --iterations may improve it" : "")
                << "\n";
    }
    // A linear part with a pole outside the unit circle: the fit table shows the damage on these
    // records, but nlid-sim and the generated C of this file will grow without bound on any other.
    if (const double pole = nlid_tools::largest_pole(m); nlid_tools::unstable_pole(pole)) {
      std::cerr << "nlid-fit: warning: the model is unstable (a pole of its linear dynamics has magnitude "
                << nlid::detail::format_g(pole, 6) << " > 1): its free run grows without bound; the model is saved as it stands\n";
    }
    stage = "simulating the saved model";
    std::printf("model %s (%s), %zu parameters, estimated in %s s", a.model.c_str(), m.kind().c_str(),
                static_cast<std::size_t>(m.parameters().size()), nlid::detail::format_f(secs, 2).c_str());
    if (after >= 0.005)
      std::printf(" (then %s s for the parameters' uncertainty and the simulation band)",
                  nlid::detail::format_f(after, 2).c_str());
    std::printf("\n");
    // The start the table's free runs use (the model's own: measured past outputs for a nonlinear
    // ARX model, estimated initial states for a grey box, ...): nlid-sim --x0 with it reproduces them.
    const char* x0 = nlid::to_string(m.initial_condition());
    std::printf("free-run simulation from x0 %s (nlid-sim --x0 %s gives the same)\n", x0, x0);
    std::printf("%-12s %-30s %10s %14s\n", "data", "experiment", "fit %", "rmse");
    for (const auto& e : est) print_fit_row("estimation", m, e);
    for (const auto& e : val) print_fit_row("validation", m, e);
    // How well the estimation data determine the model's parameters (nlarx, hw, greybox; the
    // estimated initial states are unknowns of the formula but not listed).
    if (uncertainty) std::printf("%s", uncertainty->report(static_cast<int>(m.parameters().size())).c_str());
    if (band) std::printf("validation records: %s", band->report().c_str());
    // Say whether the file can give nlid-sim --band its y_std (the uncertainty may not have been computable).
    const nlid::DynamicGreyBox* grey = m.target<nlid::DynamicGreyBox>();
    const bool keeps = m.info().uncertainty.has_value() || (grey != nullptr && grey->parameter_covariance().size() > 0);
    std::printf("saved %s%s\n", a.save.c_str(), keeps ? " (with the parameters' covariance: nlid-sim --band)" : "");
    return nlid_tools::exit_ok;
  });
}
