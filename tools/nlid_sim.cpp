// nlid-sim: free-run simulation of a saved model on an input recording.
//
//   nlid-sim --model model.json --input u.csv [--x0 zero|equilibrium] [--column u] [--band]
//            [--decimate N] [--time t] [--ts T] [--delimiter C] [--decimal C] --out y.csv
//
// The input CSV has a time column t (or --ts) and the model's input column (its name from the
// model file, or --column); other columns are ignored. --delimiter and --decimal read files
// written with other separators (record_options.hpp). --decimate N filters and keeps every N-th
// input sample as nlid-fit does, so a model fitted with `nlid-fit --decimate N` runs on the same
// raw recordings. The output CSV has columns t,y (the
// model's output name is not used so that scripts can rely on "y"); with --band a third, y_std:
// the standard deviation of y from the parameter covariance the model file carries (grey-box,
// nonlinear ARX and Hammerstein-Wiener files written by nlid-fit; simulation_band; other kinds
// keep no covariance, and --band refuses them). A model whose output is not
// finite on the input (unstable, diverging) is an error naming the first such sample; nothing is
// written. Exit status (cli_common.hpp) 0 on success, 1 on a bad file, data or model (missing
// column, sample-time mismatch, divergence — the message says which), 2 on a bad command line.
#include <cmath>
#include <cstdio>
#include <iostream>
#include <string>

#include "nlid/core/atomic_file.hpp"
#include "nlid/core/error.hpp"
#include "nlid/data/csv.hpp"
#include "nlid/data/resample.hpp"
#include "nlid/io/augmented_serial.hpp"  // repaired models from nlid-diagnose --save
#include "nlid/models/any_model.hpp"
#include "nlid/models/any_model_band.hpp"
#include "nlid/models/greybox_dynamic.hpp"
#include "nlid/models/spec.hpp"
#include "cli_common.hpp"
#include "record_options.hpp"

namespace {
constexpr const char* kUsageHead =
    "usage: nlid-sim --model model.json --input u.csv [--x0 zero|equilibrium] [--column NAME] [--band]\n"
    "                [--decimate N] [--time t] [--ts T] [--delimiter C] [--decimal C] --out y.csv\n"
    "  --decimate N     anti-alias filter the input and keep every N-th sample (as nlid-fit --decimate)\n"
    "  --band           add a column y_std: 1 sigma of y from the parameter covariance the model file carries\n"
    "Reading the input CSV file:\n";
std::string usage_text() { return std::string(kUsageHead) + nlid_tools::record_usage; }
}

int main(int argc, char** argv) {
  std::string stage = "reading the command line", sizes;
  return nlid_tools::guarded_main("nlid-sim", usage_text(), "", stage, sizes, [&]() -> int {
    using nlid_tools::UsageError;
    const nlid_tools::ParsedOptions a = nlid_tools::parse_options(
        argc, argv,
        nlid_tools::with_record_options({{"--model"},
                                         {"--input"},
                                         {"--out"},
                                         {"--x0", nlid_tools::OptionSpec::once, {"zero", "equilibrium"}},
                                         {"--column"},
                                         {"--band", nlid_tools::OptionSpec::flag},
                                         {"--decimate"}}));
    if (a.help) {
      std::cout << usage_text();
      return nlid_tools::exit_ok;
    }
    const std::string model = a.get("--model"), input = a.get("--input"), out = a.get("--out"),
                      x0 = a.get("--x0", "zero"), column = a.get("--column");
    const int decimate = a.get_int("--decimate", 1, 1000000, 1);
    const nlid_tools::RecordOptions record = nlid_tools::record_options_from(a);
    if (model.empty() || input.empty() || out.empty()) throw UsageError("--model, --input and --out are required");
    nlid_tools::check_outputs_distinct({{"--out", out}}, {{"--model", model}, {"--input", input}});
    nlid_tools::check_output_file("--out", out);

    stage = "reading " + model;
    nlid::register_series_model_kind();
    const nlid::AnyModel m = nlid::load_model(model);
    const bool band = a.has("--band");
    if (band) {
      // Refuse before the simulation: a file without a covariance cannot give the column asked for.
      const nlid::DynamicGreyBox* grey = m.target<nlid::DynamicGreyBox>();
      const bool carries = grey != nullptr ? grey->parameter_covariance().size() > 0
                                           : (m.target<nlid::DynamicNlarx>() != nullptr ||
                                              m.target<nlid::DynamicHammersteinWiener>() != nullptr) &&
                                                 m.info().uncertainty.has_value();
      if (!carries) {
        const bool kind_has = grey != nullptr || m.kind() == "nlarx" || m.kind() == "hammerstein_wiener";
        throw nlid::Error("--band needs the parameters' covariance, which " + model +
                          (kind_has ? " lacks (a " + m.kind() +
                                          " model not estimated by nlid-fit, or changed after its estimation)"
                                    : " does not keep (a " + m.kind() +
                                          " model; grey-box, nlarx and hammerstein_wiener files written by nlid-fit "
                                          "carry it)"));
      }
    }
    if (m.num_inputs() != 1 && column.empty())
      throw nlid::Error("the model in " + model + " reads " + std::to_string(m.num_inputs()) +
                        " inputs; nlid-sim simulates single-input models");
    const auto names = m.input_names();
    stage = "reading " + input;
    nlid::Experiment e = nlid_tools::read_record(
        record, input, {!column.empty() ? column : (!names.empty() && !names[0].empty() ? names[0] : std::string("u"))},
        {}, "nlid-sim");
    if (decimate > 1) {
      // decimate() filters every channel; the file has no output here, so give it a zero one.
      nlid::Experiment with_y(e.u(), Eigen::MatrixXd::Zero(e.size(), 1), e.ts());
      with_y.set_t0(e.t0());
      with_y.set_input_names(e.input_names());
      e = nlid::decimate(with_y, decimate);
    }
    if (m.ts() > 0 && std::abs(e.ts() - m.ts()) > 1e-6 * m.ts()) {
      // %.10g, not std::to_string's six decimals, which print 20 µs as "0.000020" for both sides
      char buf[192];
      std::snprintf(buf, sizeof buf, " has sample time %.10g s but the model %.10g s (relative difference %.3g)",
                    e.ts(), m.ts(), std::abs(e.ts() - m.ts()) / m.ts());
      std::string hint = "resample the data or re-estimate the model";
      const double ratio = m.ts() / e.ts();
      const double whole = std::round(ratio);
      if (whole >= 2 && std::abs(ratio - whole) < 1e-6 * ratio)
        hint = "the model's sample time is " + std::to_string(static_cast<long>(whole) * decimate) +
               " times the file's: use --decimate " + std::to_string(static_cast<long>(whole) * decimate);
      throw nlid::Error("sample-time mismatch: " + input + (decimate > 1 ? " decimated by " + std::to_string(decimate) : "") +
                        std::string(buf) + "; the model is " + model + " - " + hint);
    }
    // A free run: the simulation needs no output; give it a zero column of the right size.
    const nlid::Experiment run(e.u(), Eigen::MatrixXd::Zero(e.size(), 1), e.ts());
    nlid::Experiment named = run;
    named.set_t0(e.t0());
    named.set_input_names(e.input_names());
    // Outside the inputs the model was fitted on it extrapolates (a sigmoid network continues its
    // linear term: the study's nlarx5 gives 950 deg at u = 5). Say so, once, with where and how far.
    for (std::size_t c = 0; c < m.info().input_range.size() && static_cast<Eigen::Index>(c) < e.u().cols(); ++c) {
      const nlid::ChannelRange& r = m.info().input_range[c];
      const auto col = e.u().col(static_cast<Eigen::Index>(c));
      Eigen::Index first = -1;
      for (Eigen::Index i = 0; i < col.size() && first < 0; ++i)
        if (!r.contains(col(i))) first = i;
      if (first < 0) continue;
      char buf[320];
      std::snprintf(buf, sizeof buf,
                    "nlid-sim: note: the input leaves the range of the model's estimation data (%.6g to %.6g) from "
                    "sample %ld on (t = %.10g s; the input spans %.6g to %.6g): the model extrapolates there\n",
                    r.lower, r.upper, static_cast<long>(first), e.t0() + static_cast<double>(first) * e.ts(), col.minCoeff(),
                    col.maxCoeff());
      std::cerr << buf;
    }
    stage = "simulating " + model;
    sizes = std::to_string(e.size()) + " samples";
    const Eigen::VectorXd t = named.time();
    // A diverging model gives inf/NaN: refuse to write them (a file of NaN looks like a result).
    // Nonlinear ARX, Hammerstein-Wiener and series models stop at the first non-finite sample
    // with a DivergenceError that knows only the sample; linear and grey-box models return the
    // inf/NaN. Both end in the same message, naming the file, the time and the data row.
    const auto diverged = [&](long i, const std::string& value) {
      char buf[200];
      std::snprintf(buf, sizeof buf, "the simulated output is not finite%s from sample %ld on (t = %.10g s",
                    value.c_str(), i, t(static_cast<Eigen::Index>(i)));
      nlid::Location l;
      l.file = input;
      return nlid::Error(std::string(buf) +
                             (decimate == 1 ? ", data row " + std::to_string(i + 1) + " of " + input
                                            : ", after --decimate " + std::to_string(decimate)) +
                             "): the model " + model + " is unstable or diverges on this input (x0 " + x0 +
                             "); nothing written to " + out,
                         l);
    };
    Eigen::MatrixXd y;
    try {
      y = m.simulate(named, x0 == "zero" ? nlid::InitialCondition::zero : nlid::InitialCondition::equilibrium);
    } catch (const nlid::DivergenceError& d) {
      if (d.sample() < 0 || d.sample() >= static_cast<long>(t.size())) throw;
      throw diverged(d.sample(), "");
    }
    for (Eigen::Index i = 0; i < y.rows(); ++i) {
      if (!y.row(i).allFinite()) {
        char value[40];
        std::snprintf(value, sizeof value, " (%g)", y(i, 0));
        throw diverged(static_cast<long>(i), value);
      }
    }
    Eigen::VectorXd y_std;
    if (band) {
      stage = "computing the simulation band of " + model;
      nlid::SimulationBandOptions bo;
      bo.initial_condition = x0 == "zero" ? nlid::InitialCondition::zero : nlid::InitialCondition::equilibrium;
      y_std = nlid::simulation_band(m, nlid::Dataset(named), bo).stddev[0].col(0);
    }
    stage = "writing " + out;
    std::string text = band ? "t,y,y_std\n" : "t,y\n";
    text.reserve(static_cast<std::size_t>(e.size()) * 60);
    char buf[128];
    for (Eigen::Index i = 0; i < y.rows(); ++i) {
      if (band) {
        std::snprintf(buf, sizeof buf, "%.17g,%.17g,%.17g\n", t(i), y(i, 0), y_std(i));
      } else {
        std::snprintf(buf, sizeof buf, "%.17g,%.17g\n", t(i), y(i, 0));
      }
      text += buf;
    }
    nlid::write_file_atomically(out, text);
    std::cerr << "nlid-sim: " << y.rows() << " samples simulated (" << m.kind() << ", x0 " << x0 << ") -> " << out << "\n";
    return nlid_tools::exit_ok;
  });
}
