// nlid-codegen: dependency-free C99 code for a saved model, for a microcontroller, a PLC runtime
// or any C code base.
//
//   nlid-codegen --model model.json --out DIR [--name NAME] [--ts T] [--substeps N]
//                [--x0 zero|equilibrium|X1,X2,..] [--u0 V|V1,V2,..] [--allow-extrapolation]
//                [--precision double|single] [--linear-form auto|direct|delta]
//
// Kinds: nlarx, hammerstein_wiener, series, greybox, augmented_greybox (the repaired model of
// nlid-diagnose --save), arx and output_error. Writes DIR/NAME.h and DIR/NAME.c (atomically; DIR must exist): NAME_init, NAME_step,
// NAME_set_state, NAME_parameters (docs/codegen.md). NAME defaults to the model file's stem made
// a C identifier. The generated step reproduces `nlid-sim` on the same model to the last bits
// (same operations in the same order). Grey-box models are continuous: --ts sets the sample
// time of the generated step (required for them). --x0 equilibrium makes NAME_init start in
// the steady state for the constant input --u0 (default 0; one value for every input or one per
// input); --x0 X1,X2,.. starts it from that state in nlid's layout (the x0 of the model's
// simulate), mapped to the generated layout (generated_c_state). A --u0 outside the input range of
// the estimation data recorded in the model file, or a steady output far outside its output
// range, is refused (the model extrapolates there) unless --allow-extrapolation is given. Exit status (cli_common.hpp) 0 on success, 1 on a
// bad file or model (a model kind that is not generated, no or a non-finite equilibrium, a
// missing --out directory — the message says which), 2 on a bad command line (an invalid --name
// included, refused before the model is read). --precision single writes float code (no double anywhere) for FPUs
// without double arithmetic; it computes the model in float rounding, not nlid's bits, and writes
// the linear blocks of Hammerstein-Wiener, series, ARX and output-error models in delta-operator
// form (docs/codegen.md); --linear-form direct keeps their polynomial form (for comparison).
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <string>

#include "nlid/codegen.hpp"
#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/core/sample_time.hpp"
#include "nlid/io/augmented_serial.hpp"  // repaired models from nlid-diagnose --save
#include "nlid/models/any_model.hpp"
#include "nlid/models/spec.hpp"
#include "cli_common.hpp"
#include "linear_poles.hpp"

namespace {
constexpr const char* kUsage =
    "usage: nlid-codegen --model model.json --out DIR [--name NAME] [--ts T] [--substeps N]\n"
    "                    [--x0 zero|equilibrium|X1,X2,..] [--u0 V|V1,V2,..] [--allow-extrapolation]\n"
    "                    [--precision double|single] [--linear-form auto|direct|delta]\n"
    "  --model FILE     a model file (nlid-fit --save, or save() in C++)\n"
    "  --out DIR        existing directory for NAME.h and NAME.c\n"
    "  --name NAME      C identifier prefixing every generated name (default: the file's stem)\n"
    "  --ts T           sample time of the generated step in seconds (grey box: required;\n"
    "                   sampled models: must equal the model's if given)\n"
    "  --substeps N     grey box: integrator sub-steps per sample (default: the model's rule)\n"
    "  --x0 MODE        NAME_init state: zero (default), equilibrium for the input --u0, or\n"
    "                   a state X1,X2,.. in nlid's layout (the x0 of the model's simulate: an\n"
    "                   nlarx lag window, the linear blocks' registers, a grey box's physical\n"
    "                   state, an arx/output_error model's past samples)\n"
    "  --u0 V           constant input of the equilibrium (default 0): one value for every input\n"
    "                   or one per input, V1,V2,..; it must lie in the input range of the\n"
    "                   estimation data recorded in the model file\n"
    "  --allow-extrapolation  generate an equilibrium start outside that range (a warning)\n"
    "  --precision P    double (default: nlid's numbers to the last bit) or single (float\n"
    "                   throughout, for FPUs without double; float rounding)\n"
    "  --linear-form F  linear blocks of hammerstein_wiener, series, arx and output_error models:\n"
    "                   auto (default: delta-operator form in single precision, nlid's direct\n"
    "                   form in double), direct (polynomial form), or delta (single precision only)\n"
    "Generated kinds: nlarx, hammerstein_wiener, series (wh, wiener, hammerstein), greybox,\n"
    "augmented_greybox (nlid-diagnose --save), arx, output_error.\n";

using nlid_tools::UsageError;

// "throttle-nlarx5.json" -> "throttle_nlarx5": the default prefix of the generated names.
std::string identifier_from(const std::string& path) {
  std::string s = std::filesystem::path(path).stem().string();
  for (char& c : s)
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  if (s.empty() || std::isdigit(static_cast<unsigned char>(s[0]))) s = "model_" + s;
  if (s.rfind("nlid_", 0) == 0) s = "m_" + s;  // "nlid_" is reserved for generated helpers
  return s;
}

std::string num(double v) { return nlid::detail::format_g(v); }

// "0.5" or "0.2,-1": the values as the messages show them.
std::string num_list(const Eigen::VectorXd& v) {
  std::string s;
  for (Eigen::Index i = 0; i < v.size(); ++i) s += (i ? "," : "") + num(v(i));
  return s;
}

// Checks an equilibrium start against the estimation data's range recorded in the model file:
// outside it the model extrapolates (a sigmoid network continues its linear term, a
// piecewise-linear map its end segments), and its "steady state" can be a finite but absurd
// value (950 deg for a throttle that stops at 90). `y` is the steady output (empty if unknown).
// Returns the problem in words, or "" if there is none.
std::string extrapolation_problem(const nlid::AnyModel& m, const std::string& model, const Eigen::VectorXd& u0,
                                  const std::string& u0_shown, bool u0_given, const Eigen::VectorXd& y) {
  const auto& ir = m.info().input_range;
  const auto& outr = m.info().output_range;
  const auto in_names = m.input_names(), out_names = m.output_names();
  auto name = [](const std::vector<std::string>& names, std::size_t i, const char* fallback) {
    return i < names.size() && !names[i].empty() ? names[i] : fallback + std::to_string(i + 1);
  };
  std::string steady;
  if (y.size() > 0) {
    steady = " (its steady state there: " + name(out_names, 0, "y") + " = " + num(y(0));
    if (outr.size() > 0) steady += "; the estimation data's output range is " + num(outr[0].lower) + " to " + num(outr[0].upper);
    steady += ")";
  }
  for (std::size_t i = 0; i < ir.size() && static_cast<int>(i) < m.num_inputs(); ++i) {
    const double v = u0(static_cast<Eigen::Index>(i));
    const std::string which = u0_shown.find(',') == std::string::npos ? "" : " (" + name(in_names, i, "u") + " = " + num(v) + ")";
    if (!ir[i].contains(v))
      return "--u0 " + u0_shown + which + (u0_given ? "" : " (the default)") + " is outside the input range of the estimation data recorded in " + model + " (" +
             name(in_names, i, "u") + ": " + num(ir[i].lower) + " to " + num(ir[i].upper) +
             "): the model was not fitted there, so its equilibrium is an extrapolation" + steady;
  }
  // Inside the input range, a steady output far outside the outputs seen (more than 10 % of
  // their range beyond either end) is a spurious equilibrium of the fitted map.
  for (Eigen::Index k = 0; k < y.size() && k < static_cast<Eigen::Index>(outr.size()); ++k) {
    const nlid::ChannelRange& r = outr[static_cast<std::size_t>(k)];
    const double margin = 0.1 * (r.upper - r.lower);
    if (y(k) < r.lower - margin || y(k) > r.upper + margin)
      return "the equilibrium for --u0 " + u0_shown + " has the output " + name(out_names, static_cast<std::size_t>(k), "y") +
             " = " + num(y(k)) + ", far outside the output range of the estimation data recorded in " + model + " (" +
             num(r.lower) + " to " + num(r.upper) + "): the fitted model's steady state there is not one the data showed";
  }
  return "";
}
}  // namespace

int main(int argc, char** argv) {
  std::string stage = "reading the command line", sizes;
  return nlid_tools::guarded_main("nlid-codegen", kUsage, stage, sizes, [&]() -> int {
    using nlid_tools::OptionSpec;
    const nlid_tools::ParsedOptions a =
        nlid_tools::parse_options(argc, argv,
                                  {{"--model"},
                                   {"--out"},
                                   {"--name"},
                                   {"--ts"},
                                   {"--substeps"},
                                   {"--x0"},
                                   {"--u0"},
                                   {"--allow-extrapolation", OptionSpec::flag},
                                   {"--precision", OptionSpec::once, {"double", "single"}},
                                   {"--linear-form", OptionSpec::once, {"auto", "direct", "delta"}}});
    if (a.help) {
      std::cout << kUsage;
      return nlid_tools::exit_ok;
    }
    const std::string model = a.get("--model"), out = a.get("--out"), name = a.get("--name"),
                      x0 = a.get("--x0", "zero"), precision = a.get("--precision", "double"),
                      linear_form = a.get("--linear-form", "auto");
    const double ts = a.has("--ts") ? nlid_tools::parse_sample_time("--ts", a.get("--ts")) : 0.0;
    const std::vector<double> u0_values = a.has("--u0") ? nlid_tools::parse_number_list("--u0", a.get("--u0"))
                                                         : std::vector<double>{0.0};
    // --x0: a mode, or a state (a list of numbers).
    std::vector<double> x0_state;
    if (x0 != "zero" && x0 != "equilibrium") {
      if (x0.find_first_of("0123456789") == std::string::npos)
        throw UsageError("--x0 must be zero, equilibrium or a state X1,X2,.. (numbers separated by commas), got '" + x0 +
                         "'");
      x0_state = nlid_tools::parse_number_list("--x0", x0);
    }
    const bool u0_given = a.has("--u0"), allow_extrapolation = a.has("--allow-extrapolation");
    const int substeps = a.get_int("--substeps", 1, 1000000, 0);
    if (model.empty() || out.empty()) throw UsageError("--model and --out are required");
    if (linear_form == "delta" && precision != "single")
      throw UsageError("--linear-form delta is for --precision single (double code is nlid's direct form, bit for bit)");
    if (u0_given && x0 != "equilibrium") throw UsageError("--u0 sets the input of --x0 equilibrium; give both");
    if (allow_extrapolation && x0 != "equilibrium")
      throw UsageError("--allow-extrapolation permits an equilibrium start (--x0 equilibrium) outside the data range");
    const std::string stem = name.empty() ? identifier_from(model) : name;
    // A name the generator refuses is a command-line error, found before the model is read.
    try {
      nlid::codegen::check_name(stem);
    } catch (const nlid::Error& e) {
      std::string why = e.message();
      if (why.rfind("codegen: ", 0) == 0) why = why.substr(9);
      throw UsageError(name.empty() ? "the default --name '" + stem + "' (from the model file's name, " + model +
                                          "): " + why + " - give another --name"
                                    : "--name: " + why);
    }
    const std::string h_path = (std::filesystem::path(out) / (stem + ".h")).string();
    const std::string c_path = (std::filesystem::path(out) / (stem + ".c")).string();
    nlid_tools::check_outputs_distinct({{"--out", out}, {"--out (header)", h_path}, {"--out (source)", c_path}},
                                       {{"--model", model}});
    nlid_tools::check_output_dir("--out", out);

    stage = "reading " + model;
    nlid::register_series_model_kind();
    const nlid::AnyModel m = nlid::load_model(model);
    if (ts > 0 && m.ts() > 0 && !nlid::same_sample_time(ts, m.ts())) {
      throw nlid::Error("--ts " + nlid::detail::format_g(ts, 10) + " s differs from the model's sample time " +
                            nlid::detail::format_g(m.ts(), 10) + " s (" + model + "); a sampled model runs at the rate it was estimated at",
                        nlid::at_parameter("--ts"));
    }
    if (m.kind() == "greybox" && !(ts > 0) && !(m.ts() > 0))
      throw nlid::Error("a grey-box model is continuous: give --ts, the sample time of the generated step (e.g. the "
                        "sample time of the data it was estimated on) - " + model,
                        nlid::at_parameter("--ts"));
    // One --u0 value holds every input; a list gives one per input.
    if (u0_values.size() != 1 && static_cast<int>(u0_values.size()) != m.num_inputs())
      throw nlid::Error("--u0 has " + std::to_string(u0_values.size()) + " values, the model " + model + " has " +
                            std::to_string(m.num_inputs()) + " input" + (m.num_inputs() == 1 ? "" : "s") +
                            " (give one value for every input, or one per input)",
                        nlid::at_parameter("--u0"));
    const Eigen::VectorXd u0 =
        u0_values.size() == 1 ? Eigen::VectorXd::Constant(m.num_inputs(), u0_values[0])
                              : Eigen::VectorXd(Eigen::Map<const Eigen::VectorXd>(u0_values.data(), m.num_inputs()));
    const std::string u0_shown =  // as given: one value, or one per input
        num_list(Eigen::Map<const Eigen::VectorXd>(u0_values.data(), static_cast<Eigen::Index>(u0_values.size())));
    if (x0 == "equilibrium") {
      // NAME_init's state is nlid-sim's equilibrium for a record starting at u0: a steady state
      // that is not finite (an input far outside the model's range) would be written as inf/nan.
      stage = "computing the equilibrium for --u0";
      const double step = m.ts() > 0 ? m.ts() : ts;
      if (step > 0) {
        // Long enough for every model's lags (a nonlinear ARX model with nk = 20 needs more than 21
        // samples); the output at the first sample is the steady state.
        const Eigen::Index probe = 8 + std::max(0, m.history_length());
        const nlid::Experiment held(u0.transpose().replicate(probe, 1), Eigen::MatrixXd::Zero(probe, m.num_outputs()),
                                    step);
        Eigen::MatrixXd y;
        bool simulated = false;
        std::string no_steady_state;
        try {
          y = m.simulate(held, nlid::InitialCondition::equilibrium);
          simulated = true;
        } catch (const nlid::Error& e) {
          no_steady_state = e.message();  // reported below, after the range (which may explain it)
        }
        if (simulated && y.rows() > 0 && !y.row(0).allFinite()) {
          throw nlid::Error("the equilibrium of " + model + " for the input held at --u0 " + u0_shown +
                                " is not finite (output " + nlid::detail::format_g(y(0, 0)) + "): the generated initial state would be inf/nan - choose an input within "
                                               "the model's operating range",
                            nlid::at_parameter("--u0"));
        }
        const Eigen::VectorXd y0 = simulated && y.rows() > 0 ? Eigen::VectorXd(y.row(0).transpose()) : Eigen::VectorXd();
        const std::string problem = extrapolation_problem(m, model, u0, u0_shown, u0_given, y0);
        if (!problem.empty() && !allow_extrapolation)
          throw nlid::Error(problem + " - choose --u0 within the range, or give --allow-extrapolation to generate it anyway",
                            nlid::at_parameter("--u0"));
        if (!problem.empty()) std::cerr << "nlid-codegen: warning: " << problem << " (generated: --allow-extrapolation)\n";
        if (!simulated)
          throw nlid::Error("no equilibrium start for --u0 " + u0_shown + " (" + model + "): " + no_steady_state,
                            nlid::at_parameter("--u0"));
      }
      if (m.info().input_range.empty())
        std::cerr << "nlid-codegen: note: " << model << " records no range of its estimation data (written before nlid "
                  << "kept it, or saved without record_data_range), so --u0 " << u0_shown
                  << " is not checked against the inputs the model was fitted on\n";
    }
    // An unstable plant model can be what the user wants (a controller design target), so it is
    // generated; but a target that runs it open loop will see its output grow without bound.
    if (const double pole = nlid_tools::largest_pole(m); nlid_tools::unstable_pole(pole)) {
      std::cerr << "nlid-codegen: warning: " << model << " is unstable (a pole of its linear dynamics has magnitude "
                << nlid::detail::format_g(pole, 6)
                << " > 1): the generated step's output grows without bound in open loop; generated as asked\n";
    }
    stage = "generating C for " + model;
    nlid::CodegenOptions o;
    o.name = stem;
    o.ts = ts;
    o.substeps = substeps;
    if (precision == "single") o.precision = nlid::codegen::Precision::single_precision;
    if (linear_form == "direct") o.linear_form = nlid::codegen::LinearForm::direct;
    if (linear_form == "delta") o.linear_form = nlid::codegen::LinearForm::delta;
    if (x0 == "equilibrium") o.equilibrium_input = u0;
    if (!x0_state.empty())
      o.initial_state = Eigen::Map<const Eigen::VectorXd>(x0_state.data(), static_cast<Eigen::Index>(x0_state.size()));
    nlid::GeneratedCode g;
    try {
      g = nlid::generate_c(m, o);
    } catch (const nlid::Error& e) {
      // The library names its option; on this command line the state is --x0.
      if (x0_state.empty() || e.where().parameter != "initial_state") {
        // The other CodegenOptions fields under this tool's option names (the message text is
        // translated by cli_common.hpp's translate(); this is the "[at parameter ...]" part).
        static const std::pair<const char*, const char*> options[] = {
            {"substeps", "--substeps"}, {"ts", "--ts"},       {"equilibrium_input", "--u0"},
            {"name", "--name"},         {"precision", "--precision"}, {"linear_form", "--linear-form"}};
        for (const auto& [lib, flag] : options) {
          if (e.where().parameter != lib) continue;
          nlid::Location where = e.where();
          where.parameter = flag;
          throw nlid::Error(e.message(), where);
        }
        throw;
      }
      std::string text = e.message();
      const std::string lib = "codegen: initial_state";
      text = text.rfind(lib, 0) == 0 ? "--x0 " + x0 + " (" + model + ")" + text.substr(lib.size())
                                     : "--x0 " + x0 + " (" + model + "): " + text.substr(text.find(' ') + 1);
      throw nlid::Error(text, nlid::at_parameter("--x0"));
    }
    stage = "writing " + out;
    const auto files = g.write(out);
    std::cerr << "nlid-codegen: " << m.kind() << " model " << model << " -> " << files.at(0) << ", " << files.at(1)
              << " (" << m.parameters().size() << " parameters, " << g.paths << " branch path"
              << (g.paths == 1 ? "" : "s") << (precision == "single" ? ", single precision" : "") << ")\n";
    std::cout << "wrote " << files.at(0) << "\nwrote " << files.at(1) << "\n";
    return nlid_tools::exit_ok;
  });
}
