// nlid-diagnose: missing-physics diagnosis of recordings against a catalogue grey-box baseline.
//
//   nlid-diagnose --baseline throttle --est a.csv --est b.csv --val c.csv [options]
//
// Fits the baseline (catalogue defaults scaled from the data, multi-start simulation error),
// locates where its simulation leaves the noise floor, tries the effect catalogue (refit by
// simulation error, scored on the validation records), and reports what was missing. Progress
// goes to stderr, a short summary to stdout; --json and --html write the full result.
// Exit codes (cli_common.hpp, as the other tools): 0 success; 1 a bad file, column or data (too
// short, a constant input), or a failed run (out of memory, internal error); 2 a bad command line
// (unknown, missing, repeated or malformed option, unknown baseline or effect, an output that is an
// input).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <iostream>
#include <sstream>
#include <string>
#include <system_error>
#include <vector>

#include "nlid/core/format.hpp"
#include "nlid/core/sample_time.hpp"
#include "nlid/data/csv.hpp"
#include "nlid/diagnose.hpp"
#include "nlid/diagnose/report.hpp"
#include "nlid/io/augmented_serial.hpp"
#include "nlid/io/model_file.hpp"
#include "cli_common.hpp"
#include "record_options.hpp"

namespace {

// The record-reading options' lines are record_options.hpp's, as in the other tools' help.
const std::string usage = std::string(
    "usage: nlid-diagnose --baseline NAME --est FILE [--est FILE ...] --val FILE [--val FILE ...]\n"
    "                     [--input u] [--output y] [--time t] [--ts T] [--delimiter C] [--decimal C]\n"
    "                     [--time-tolerance R] [--decimate N]\n"
    "                     [--x0 estimate|zero] [--starts N] [--max-effects N] [--effects a,b,...]\n"
    "                     [--refine-top N] [--noise SIGMA]\n"
    "                     [--threads N] [--json out.json] [--html report.html] [--save model.json]\n"
    "                     [--quiet]\n"
    "\n"
    "  --baseline NAME   catalogue grey-box model: first_order, mass_spring_damper, rigid_body,\n"
    "                    throttle, two_tank\n"
    "  --est FILE        estimation record (CSV with a header row); repeat for several\n"
    "  --val FILE        validation record; repeat for several\n"
    "  --input/--output  column names of the input and output (default u, y)\n") +
    nlid_tools::record_usage +
    "  --decimate N      anti-alias filter and keep every N-th sample (noise floor at the raw rate)\n"
    "  --x0 MODE         initial states: estimate (default) or zero\n"
    "  --starts N        multi-start runs of the baseline fit (default 6)\n"
    "  --max-effects N   largest number of effects added (default 3)\n"
    "  --effects LIST    comma-separated effect names to try (default: the whole catalogue)\n"
    "  --refine-top N    screened effects refitted to convergence per round (default 3)\n"
    "  --noise SIGMA     the output's measurement-noise standard deviation in the records as read\n"
    "                    (before --decimate), in its units (default: estimated from the records;\n"
    "                    needed for noise-free data)\n"
    "  --threads N       worker threads (default: all cores, at most 8)\n"
    "  --json FILE       write the diagnosis as JSON\n"
    "  --html FILE       write a self-contained HTML report\n"
    "  --save FILE       write the repaired model (baseline + effects found) as a model file, for\n"
    "                    nlid-sim and nlid-codegen (kind augmented_greybox)\n"
    "  --quiet           no progress on stderr\n";

using nlid_tools::UsageError;

}  // namespace

int main(int argc, char** argv) {
  std::string stage = "reading the command line", sizes;
  return nlid_tools::guarded_main("nlid-diagnose", usage, stage, sizes, [&]() -> int {
    if (argc < 2) throw UsageError("no arguments");
    using nlid_tools::OptionSpec;
    const nlid_tools::ParsedOptions a = nlid_tools::parse_options(
        argc, argv,
        nlid_tools::with_record_options({{"--baseline"},
                                         {"--est", OptionSpec::repeated},
                                         {"--val", OptionSpec::repeated},
                                         {"--input"},
                                         {"--output"},
                                         {"--decimate"},
                                         {"--x0", OptionSpec::once, {"estimate", "zero"}},
                                         {"--starts"},
                                         {"--max-effects"},
                                         {"--effects"},
                                         {"--refine-top"},
                                         {"--noise"},
                                         {"--threads"},
                                         {"--json"},
                                         {"--html"},
                                         {"--save"},
                                         {"--quiet", OptionSpec::flag}}),
        /*dashed_value_is_missing=*/true);
    if (a.help) {
      std::cout << usage;
      return nlid_tools::exit_ok;
    }
    const std::vector<std::string> est_files = a.all("--est"), val_files = a.all("--val");
    const std::string baseline = a.get("--baseline"), input = a.get("--input", "u"), output = a.get("--output", "y"),
                      json_path = a.get("--json"), html_path = a.get("--html"), save_path = a.get("--save");
    const bool quiet = a.has("--quiet");
    nlid::DiagnoseOptions opt;
    opt.decimate = a.get_int("--decimate", 1, 1000000, opt.decimate);
    opt.starts = a.get_int("--starts", 1, 10000, opt.starts);
    opt.max_effects = a.get_int("--max-effects", 0, 100, opt.max_effects);
    opt.threads = a.get_int("--threads", 1, 4096, opt.threads);
    opt.refine_top = a.get_int("--refine-top", 1, 1000, opt.refine_top);
    if (a.has("--noise")) {
      // Records without measurable noise (simulated, or quantised far below the signal) have no
      // floor to estimate; the library asked for DiagnoseOptions::noise, which no flag set.
      const double sigma = nlid_tools::parse_number("--noise", a.get("--noise"));
      if (!(sigma > 0.0))
        throw UsageError("--noise needs a positive standard deviation in the output's units, got '" + a.get("--noise") + "'");
      // At the records' own rate, carried through --decimate's filter as an estimated floor is
      // (σ after the filter and the inflation of its correlated samples).
      opt.noise = nlid::noise_floor_from_sigma(sigma, opt.decimate, opt.decimate_options, {}, "given with --noise");
    }
    if (a.has("--x0"))
      opt.initial_condition = a.get("--x0") == "zero" ? nlid::InitialCondition::zero : nlid::InitialCondition::estimate;
    if (a.has("--effects")) {
      // Given, the list must name something: "--effects ," or "" read as the whole catalogue, the
      // opposite of a restriction. A name given twice would be tried twice, and would tighten the
      // per-round false-detection threshold (Bonferroni over the candidates) for nothing.
      const std::string list = a.get("--effects");
      std::stringstream ss(list);
      std::string name;
      while (std::getline(ss, name, ',')) {
        if (name.empty()) throw UsageError("--effects has an empty name in '" + list + "' (names separated by commas)");
        if (std::find(opt.effects.begin(), opt.effects.end(), name) != opt.effects.end())
          throw UsageError("--effects names '" + name + "' twice");
        opt.effects.push_back(name);
      }
      if (opt.effects.empty()) throw UsageError("--effects needs at least one effect name");
    }
    const nlid_tools::RecordOptions record = nlid_tools::record_options_from(a);
    if (baseline.empty()) throw UsageError("--baseline is required");
    if (est_files.empty()) throw UsageError("at least one --est file is required");
    if (val_files.empty()) throw UsageError("at least one --val file is required");
    // Unknown names fail before any file is read (they list the known ones), located at the flag.
    try {
      (void)nlid::make_physics(baseline);
    } catch (const nlid::Error& e) {
      throw UsageError(nlid::Error(e.message(), nlid::at_parameter("--baseline")).what());
    }
    for (const std::string& e : opt.effects) {
      try {
        (void)nlid::effect_kind(e);
      } catch (const nlid::Error& err) {
        throw UsageError(nlid::Error(err.message(), nlid::at_parameter("--effects")).what());
      }
    }
    // The effect tests are decided on the validation records, which no parameter is fitted to
    // (docs/diagnosis.md): an estimation record among them would pass effects fitted to its noise.
    for (const std::string& v : val_files) {
      for (const std::string& e : est_files) {
        std::error_code ec;
        if (v == e || std::filesystem::equivalent(v, e, ec))
          throw UsageError("'" + v + "' is both an --est and a --val record; the diagnosis tests each effect on "
                           "validation records that no parameter was fitted to");
      }
    }
    std::vector<nlid_tools::FlagPath> inputs;
    for (const auto& f : est_files) inputs.emplace_back("--est", f);
    for (const auto& f : val_files) inputs.emplace_back("--val", f);
    nlid_tools::check_outputs_distinct({{"--json", json_path}, {"--html", html_path}, {"--save", save_path}}, inputs);
    nlid_tools::check_output_file("--json", json_path);
    nlid_tools::check_output_file("--html", html_path);
    nlid_tools::check_output_file("--save", save_path);

    const auto t0 = std::chrono::steady_clock::now();
    if (!quiet) {
      opt.progress = [t0](const std::string& s) {
        const double t = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        std::fprintf(stderr, "[%s s] %s\n", nlid::detail::right_aligned(nlid::detail::format_f(t, 1), 6).c_str(), s.c_str());
      };
    }
    auto read = [&](const std::vector<std::string>& files) {
      nlid::Dataset d;
      for (const std::string& f : files) {
        stage = "reading " + f;
        if (opt.progress) opt.progress("reading " + f);
        nlid::Experiment e = nlid_tools::read_record(record, f, {input}, {output}, "nlid-diagnose");
        if (d.size() > 0 && !nlid::same_sample_time(e.ts(), d.ts())) {
          nlid::Location l;
          l.file = f;
          throw nlid::Error("sample time " + nlid_tools::format_seconds(e.ts()) + " differs from the other records' " +
                                nlid_tools::format_seconds(d.ts()) + "; " + nlid_tools::sample_time_remedy(e.ts(), d.ts()),
                            l);
        }
        d.add(std::move(e));
      }
      return d;
    };
    const nlid::Dataset est = read(est_files);
    {
      std::vector<const nlid::Experiment*> records;
      for (const auto& e : est) records.push_back(&e);
      nlid_tools::check_inputs_vary(records, est_files, "--est");
    }
    const nlid::Dataset val = read(val_files);
    if (!nlid::same_sample_time(val.ts(), est.ts())) {
      nlid::Location l = nlid::at_parameter("--val");
      l.file = val_files[0];
      throw nlid::Error("estimation records are sampled at " + nlid_tools::format_seconds(est.ts()) + " (" +
                            est_files[0] + ") but validation records at " + nlid_tools::format_seconds(val.ts()) +
                            " (" + val_files[0] + "); " + nlid_tools::sample_time_remedy(val.ts(), est.ts()),
                        l);
    }
    stage = "diagnosing against the baseline " + baseline;
    sizes = std::to_string(est.total_samples()) + " estimation and " + std::to_string(val.total_samples()) +
            " validation samples";
    // Catalogue baselines run as compile-time types (fixed-size, one-pass sensitivities).
    // The library locates a record by its name (the file's stem) and index; the user gave paths.
    const auto run = [&](auto model) {
      try {
        return nlid::diagnose(std::move(model), est, val, opt);
      } catch (const nlid::Error& err) {
        nlid::Location l = err.where();
        const std::string text = err.message();
        const auto k = static_cast<std::size_t>(l.experiment);
        if (l.experiment >= 0 && text.find("validation record") != std::string::npos && k < val_files.size())
          l.file = val_files[k];
        else if (l.experiment >= 0 && text.find("estimation record") != std::string::npos && k < est_files.size())
          l.file = est_files[k];
        else
          throw;
        throw nlid::Error(text, l);
      }
    };
    return nlid::with_baseline(baseline, [&](auto model) {
      const auto d = run(std::move(model));
      std::cout << nlid::diagnosis_summary(d);
      if (!json_path.empty()) {
        stage = "writing " + json_path;
        nlid::write_diagnosis_json(d, json_path);
        if (opt.progress) opt.progress("wrote " + json_path);
      }
      if (!html_path.empty()) {
        stage = "writing " + html_path;
        const std::size_t charts = nlid::write_diagnosis_html(d, html_path);
        if (opt.progress) opt.progress("wrote " + html_path + " (" + std::to_string(charts) + " charts)");
      }
      if (!save_path.empty()) {
        stage = "writing " + save_path;
        nlid::ModelFileInfo info;
        info.description = "nlid-diagnose --baseline " + baseline + ": the repaired model";
        if (!d.model.effects().empty()) {
          info.description += " (";
          for (std::size_t i = 0; i < d.model.effects().size(); ++i)
            info.description += (i ? ", " : "") + d.model.effects()[i].label();
          info.description += ")";
        }
        // Where it was fitted, as the estimation saw the data (after --decimate's filter, as
        // nlid-fit records it): nlid-codegen checks --u0 against it, nlid-sim notes inputs beyond.
        nlid::record_data_range(info, opt.decimate > 1 ? nlid::decimate(est, opt.decimate, opt.decimate_options) : est);
        nlid::save_model(save_path, d.model, info);
        if (opt.progress) opt.progress("wrote " + save_path);
      }
      if (opt.progress) opt.progress("done");
      return nlid_tools::exit_ok;
    });
  });
}
