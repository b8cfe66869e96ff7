// nlid-diagnose: missing-physics diagnosis of recordings against a catalogue grey-box baseline.
//
//   nlid-diagnose --baseline throttle --est a.csv --est b.csv --val c.csv [options]
//
// Fits the baseline (catalogue defaults scaled from the data, multi-start simulation error),
// locates where its simulation leaves the noise floor, tries the effect catalogue (refit by
// simulation error, scored on the validation records), and reports what was missing. Progress
// goes to stderr, a short summary to stdout; --json and --html write the full result.
// Exit codes: 0 success, 2 user error (bad option, file, column, baseline, data too short),
// 1 unexpected internal failure.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "nlid/data/csv.hpp"
#include "nlid/diagnose.hpp"
#include "nlid/diagnose/report.hpp"
#include "nlid/io/augmented_serial.hpp"
#include "nlid/io/model_file.hpp"
#include "record_options.hpp"

namespace {

const char* const usage =
    "usage: nlid-diagnose --baseline NAME --est FILE [--est FILE ...] --val FILE [--val FILE ...]\n"
    "                     [--input u] [--output y] [--time t] [--ts T] [--delimiter C] [--decimal C]\n"
    "                     [--decimate N]\n"
    "                     [--x0 estimate|zero] [--starts N] [--max-effects N] [--effects a,b,...]\n"
    "                     [--threads N] [--json out.json] [--html report.html] [--save model.json]\n"
    "                     [--quiet]\n"
    "\n"
    "  --baseline NAME   catalogue grey-box model: first_order, mass_spring_damper, rigid_body,\n"
    "                    throttle, two_tank\n"
    "  --est FILE        estimation record (CSV with a header row); repeat for several\n"
    "  --val FILE        validation record; repeat for several\n"
    "  --input/--output  column names of the input and output (default u, y)\n"
    "  --time NAME       time column (default t); the sample time is read from it\n"
    "  --ts T            sample time in seconds (needed if the files have no time column)\n"
    "  --delimiter C     field separator: , (default) ; tab space |\n"
    "  --decimal C       decimal point: . (default) or , (then the separator must be another)\n"
    "  --decimate N      anti-alias filter and keep every N-th sample (noise floor at the raw rate)\n"
    "  --x0 MODE         initial states: estimate (default) or zero\n"
    "  --starts N        multi-start runs of the baseline fit (default 6)\n"
    "  --max-effects N   largest number of effects added (default 3)\n"
    "  --effects LIST    comma-separated effect names to try (default: the whole catalogue)\n"
    "  --threads N       worker threads (default: all cores)\n"
    "  --json FILE       write the diagnosis as JSON\n"
    "  --html FILE       write a self-contained HTML report\n"
    "  --save FILE       write the repaired model (baseline + effects found) as a model file, for\n"
    "                    nlid-sim and nlid-codegen (kind augmented_greybox)\n"
    "  --quiet           no progress on stderr\n";

struct UsageError : std::exception {
  explicit UsageError(std::string m) : msg(std::move(m)) {}
  const char* what() const noexcept override { return msg.c_str(); }
  std::string msg;
};

int parse_int(const std::string& opt, const std::string& v, int lo) {
  try {
    std::size_t pos = 0;
    const int x = std::stoi(v, &pos);
    if (pos == v.size() && x >= lo) return x;
  } catch (const std::exception&) {
  }
  throw UsageError(opt + " needs an integer >= " + std::to_string(lo) + ", got '" + v + "'");
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> est_files, val_files, effects;
  std::string baseline, input = "u", output = "y", json_path, html_path, save_path;
  nlid_tools::RecordOptions record;
  bool quiet = false;
  nlid::DiagnoseOptions opt;
  try {
    std::vector<std::string> args(argv + 1, argv + argc);
    if (args.empty()) throw UsageError("no arguments");
    for (std::size_t i = 0; i < args.size(); ++i) {
      const std::string& a = args[i];
      if (a == "--help" || a == "-h") {
        std::cout << usage;
        return 0;
      }
      if (a == "--quiet") {
        quiet = true;
        continue;
      }
      if (i + 1 >= args.size() || args[i + 1].rfind("--", 0) == 0)
        throw UsageError("option " + a + " needs a value");
      const std::string& v = args[++i];
      if (a == "--baseline") baseline = v;
      else if (a == "--est") est_files.push_back(v);
      else if (a == "--val") val_files.push_back(v);
      else if (a == "--input") input = v;
      else if (a == "--output") output = v;
      else if (a == "--time" || a == "--ts" || a == "--delimiter" || a == "--decimal") {
        try {
          nlid_tools::parse_record_option(a, v, record);
        } catch (const nlid::Error& e) {
          throw UsageError(e.what());
        }
      }
      else if (a == "--decimate") opt.decimate = parse_int(a, v, 1);
      else if (a == "--starts") opt.starts = parse_int(a, v, 1);
      else if (a == "--max-effects") opt.max_effects = parse_int(a, v, 0);
      else if (a == "--threads") opt.threads = parse_int(a, v, 1);
      else if (a == "--json") json_path = v;
      else if (a == "--html") html_path = v;
      else if (a == "--save") save_path = v;
      else if (a == "--x0") {
        if (v == "estimate") opt.initial_condition = nlid::InitialCondition::estimate;
        else if (v == "zero") opt.initial_condition = nlid::InitialCondition::zero;
        else throw UsageError("--x0 must be 'estimate' or 'zero', got '" + v + "'");
      } else if (a == "--effects") {
        std::stringstream ss(v);
        std::string name;
        while (std::getline(ss, name, ','))
          if (!name.empty()) opt.effects.push_back(name);
      } else {
        throw UsageError("unknown option '" + a + "'");
      }
    }
    if (baseline.empty()) throw UsageError("--baseline is required");
    if (est_files.empty()) throw UsageError("at least one --est file is required");
    if (val_files.empty()) throw UsageError("at least one --val file is required");
    try {
      nlid_tools::check_record_options(record);
    } catch (const nlid::Error& e) {
      throw UsageError(e.what());
    }
  } catch (const UsageError& e) {
    std::cerr << "nlid-diagnose: error: " << e.what() << "\n\n" << usage;
    return 2;
  }

  const auto t0 = std::chrono::steady_clock::now();
  if (!quiet) {
    opt.progress = [t0](const std::string& s) {
      const double t = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      std::fprintf(stderr, "[%6.1f s] %s\n", t, s.c_str());
    };
  }
  try {
    // Unknown names fail before any file is read (they list the known ones).
    (void)nlid::make_physics(baseline);
    for (const std::string& e : opt.effects) (void)nlid::effect_kind(e);
    auto read = [&](const std::vector<std::string>& files) {
      nlid::Dataset d;
      for (const std::string& f : files) {
        nlid::CsvReadOptions o = nlid_tools::csv_read_options(record, f);
        o.inputs = {input};
        o.outputs = {output};
        if (opt.progress) opt.progress("reading " + f);
        nlid::Experiment e = nlid::read_csv(f, o);
        if (d.size() > 0 && std::abs(e.ts() - d.ts()) > 1e-9 * d.ts()) {
          nlid::Location l;
          l.file = f;
          throw nlid::Error("sample time " + nlid_tools::format_seconds(e.ts()) + " differs from the other records' " +
                                nlid_tools::format_seconds(d.ts()),
                            l);
        }
        d.add(std::move(e));
      }
      return d;
    };
    const nlid::Dataset est = read(est_files);
    const nlid::Dataset val = read(val_files);
    if (est.ts() != val.ts() && std::abs(est.ts() - val.ts()) > 1e-9 * est.ts()) {
      throw nlid::Error("estimation records are sampled at " + nlid_tools::format_seconds(est.ts()) +
                        " but validation records at " + nlid_tools::format_seconds(val.ts()));
    }
    // Catalogue baselines run as compile-time types (fixed-size, one-pass sensitivities).
    return nlid::with_baseline(baseline, [&](auto model) {
      const auto d = nlid::diagnose(std::move(model), est, val, opt);
      std::cout << nlid::diagnosis_summary(d);
      if (!json_path.empty()) {
        nlid::write_diagnosis_json(d, json_path);
        if (opt.progress) opt.progress("wrote " + json_path);
      }
      if (!html_path.empty()) {
        const std::size_t charts = nlid::write_diagnosis_html(d, html_path);
        if (opt.progress) opt.progress("wrote " + html_path + " (" + std::to_string(charts) + " charts)");
      }
      if (!save_path.empty()) {
        nlid::ModelFileInfo info;
        info.description = "nlid-diagnose --baseline " + baseline + ": the repaired model";
        if (!d.model.effects().empty()) {
          info.description += " (";
          for (std::size_t i = 0; i < d.model.effects().size(); ++i)
            info.description += (i ? ", " : "") + d.model.effects()[i].label();
          info.description += ")";
        }
        nlid::save_model(save_path, d.model, info);
        if (opt.progress) opt.progress("wrote " + save_path);
      }
      if (opt.progress) opt.progress("done");
      return 0;
    });
  } catch (const nlid::Error& e) {
    std::cerr << "nlid-diagnose: error: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "nlid-diagnose: internal error: " << e.what() << "\n";
    return 1;
  }
}
