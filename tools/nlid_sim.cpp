// nlid-sim: free-run simulation of a saved model on an input recording.
//
//   nlid-sim --model model.json --input u.csv [--x0 zero|equilibrium|measured|estimate] [--column u[,u2..]]
//            [--output y[,y2..]] [--band] [--with-input] [--decimate N] [--time t] [--ts T] [--delimiter C]
//            [--decimal C] --out y.csv
//
// The input CSV has a time column t (or --ts) and the model's input columns (their names from the
// model file, or --column, one name per input); other columns are ignored. --delimiter and --decimal read files
// written with other separators (record_options.hpp). --decimate N filters and keeps every N-th
// input sample as nlid-fit does, so a model fitted with `nlid-fit --decimate N` runs on the same
// raw recordings. The output CSV has columns t,y (the
// model's output name is not used so that scripts can rely on "y"; a model with several outputs
// writes y1,y2,..); with --band one more per output, y_std (y1_std,..):
// the standard deviation of y from the parameter covariance the model file carries (grey-box,
// nonlinear ARX and Hammerstein-Wiener files written by nlid-fit; simulation_band; other kinds
// keep no covariance, and --band refuses them). --with-input writes the inputs the model ran on
// (after --decimate) between t and y, under their column names: the input to replay through
// generated C code (nlid-codegen) and compare. --x0 measured (past outputs from the record) and
// --x0 estimate (the start that fits the record's first samples) read the measured outputs too
// (the model's output names, or --output): the starts nlid-fit scores its table with. A model whose output is not
// finite on the input (unstable, diverging) is an error naming the first such sample; nothing is
// written. Exit status (cli_common.hpp) 0 on success, 1 on a bad file, data or model (missing
// column, sample-time mismatch, divergence — the message says which), 2 on a bad command line.
#include <cmath>
#include <cstdio>
#include <iostream>
#include <string>
#include <vector>

#include "nlid/core/atomic_file.hpp"
#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/core/sample_time.hpp"
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
    "usage: nlid-sim --model model.json --input u.csv [--x0 zero|equilibrium|measured|estimate] [--column NAME[,NAME..]]\n"
    "                [--output NAME[,NAME..]] [--band] [--with-input] [--decimate N] [--time t] [--ts T]\n"
    "                [--delimiter C] [--decimal C] [--time-tolerance R] --out y.csv\n"
    "  --x0 X           start: zero (default), equilibrium (for the first input), measured (past outputs\n"
    "                   from the file), estimate (fitted to the file's first outputs): the last two read\n"
    "                   the measured outputs and give the start nlid-fit's table uses for those models\n"
    "  --column NAMES   the input columns, one per model input (default: the names in the model file)\n"
    "  --output NAMES   the measured output columns for --x0 measured|estimate (default: the model's names)\n"
    "  --decimate N     anti-alias filter the input and keep every N-th sample (as nlid-fit --decimate)\n"
    "  --band           add a column y_std: 1 sigma of y from the parameter covariance the model file carries\n"
    "  --with-input     also write the inputs the model ran on (after --decimate), between t and y\n"
    "Reading the input CSV file:\n";
std::string usage_text() { return std::string(kUsageHead) + nlid_tools::record_usage; }

// --column's (--output's) comma-separated names; an empty one is a usage error (a CSV column is
// never unnamed).
std::vector<std::string> column_list(const std::string& v, const char* flag = "--column") {
  std::vector<std::string> out;
  std::size_t start = 0;
  for (;;) {
    const std::size_t comma = v.find(',', start);
    out.push_back(v.substr(start, comma == std::string::npos ? std::string::npos : comma - start));
    if (out.back().empty()) throw nlid_tools::UsageError(std::string(flag) + " has an empty name in '" + v + "'");
    if (comma == std::string::npos) return out;
    start = comma + 1;
  }
}
}  // namespace

int main(int argc, char** argv) {
  std::string stage = "reading the command line", sizes;
  return nlid_tools::guarded_main("nlid-sim", usage_text(), stage, sizes, [&]() -> int {
    using nlid_tools::UsageError;
    const nlid_tools::ParsedOptions a = nlid_tools::parse_options(
        argc, argv,
        nlid_tools::with_record_options({{"--model"},
                                         {"--input"},
                                         {"--out"},
                                         {"--x0", nlid_tools::OptionSpec::once, {"zero", "equilibrium", "measured", "estimate"}},
                                         {"--output"},
                                         {"--column"},
                                         {"--band", nlid_tools::OptionSpec::flag},
                                         {"--with-input", nlid_tools::OptionSpec::flag},
                                         {"--decimate"}}));
    if (a.help) {
      std::cout << usage_text();
      return nlid_tools::exit_ok;
    }
    const std::string model = a.get("--model"), input = a.get("--input"), out = a.get("--out"),
                      x0 = a.get("--x0", "zero"), column = a.get("--column"),
                      output_column = a.get("--output");
    // parse_options has checked the name against the four policies.
    const nlid::InitialCondition ic = nlid::detail::initial_condition_from_report(x0, nlid::InitialCondition::zero);
    // Only these two starts read the record's outputs.
    const bool reads_outputs = ic == nlid::InitialCondition::measured || ic == nlid::InitialCondition::estimate;
    if (!output_column.empty() && !reads_outputs)
      throw UsageError("--output names the measured outputs that --x0 measured or --x0 estimate read; with --x0 " + x0 +
                       " no output is read");
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
      if (!carries && !m.info().uncertainty_left_out.empty()) {
        throw nlid::Error("--band needs the parameters' covariance: " + model + " carries one, but " +
                          m.info().uncertainty_left_out + "; estimate the changed model again (nlid-fit) for a band");
      }
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
    // The columns of the inputs (and, for measured or estimated starts, of the outputs): the
    // option's names, one per channel, else the model file's. An unnamed channel of a
    // single-channel model reads `single` ("u", "y"); an unnamed input of several is an error (a
    // guess would read the wrong column), an unnamed output of several reads y1, y2, ...
    const auto channel_columns = [&](const char* flag, const std::string& given, const std::vector<std::string>& names,
                                     int count, const char* what, const char* single, bool guess_several) {
      std::vector<std::string> cols;
      if (a.has(flag)) {  // not given.empty(): `--column ""` is an empty name, not "use the defaults"
        cols = column_list(given, flag);
        if (static_cast<int>(cols.size()) != count)
          throw UsageError(std::string(flag) + " names " + std::to_string(cols.size()) + " column(s) but the model in " +
                           model + (what[0] == 'i' ? " reads " : " has ") + std::to_string(count) + " " + what +
                           "(s): give one name per " + what + ", comma-separated");
        return cols;
      }
      for (int j = 0; j < count; ++j) {
        const std::string n = static_cast<int>(names.size()) == count ? names[static_cast<std::size_t>(j)] : std::string();
        if (!n.empty()) {
          cols.push_back(n);
        } else if (count == 1) {
          cols.emplace_back(single);
        } else if (guess_several) {
          cols.push_back(single + std::to_string(j + 1));
        } else {
          throw nlid::Error("the model in " + model + " reads " + std::to_string(count) + " " + what +
                            "s but does not name " + what + " " + std::to_string(j + 1) + ": name the columns with " +
                            flag + " " + single + "1," + single + "2,..");
        }
      }
      return cols;
    };
    const int nu = m.num_inputs(), ny = m.num_outputs();
    const std::vector<std::string> columns =
        channel_columns("--column", column, m.input_names(), nu, "input", "u", false);
    const std::vector<std::string> outputs =
        reads_outputs ? channel_columns("--output", output_column, m.output_names(), ny, "output", "y", true)
                      : std::vector<std::string>();
    stage = "reading " + input;
    nlid::Experiment e = nlid_tools::read_record(record, input, columns, outputs, "nlid-sim");
    if (decimate > 1) {
      try {
        // decimate() filters every channel; without measured outputs give it a zero one.
        if (reads_outputs) {
          e = nlid::decimate(e, decimate);
        } else {
          nlid::Experiment with_y(e.u(), Eigen::MatrixXd::Zero(e.size(), 1), e.ts());
          with_y.set_t0(e.t0());
          with_y.set_input_names(e.input_names());
          e = nlid::decimate(with_y, decimate);
        }
      } catch (const nlid::Error& err) {
        // The library names its argument 'factor'; the user typed --decimate, for this file.
        nlid::Location l = nlid::at_parameter("--decimate");
        l.file = input;
        throw nlid::Error(err.message(), l);
      }
    }
    if (!(m.ts() > 0) && m.kind() != "greybox" && m.kind() != "augmented_greybox") {
      // A discrete-time model without a sample time (a hand-made file, "ts": 0) runs at whatever
      // rate the file has: no check can catch a record at the wrong rate, so say so. (A grey box
      // is continuous-time: it integrates over any sample time.)
      std::cerr << "nlid-sim: note: " << model << " has no sample time (ts 0): it runs at the file's "
                << nlid::detail::format_g(e.ts(), 10) << " s without a sample-time check\n";
    }
    if (m.ts() > 0 && !nlid::same_sample_time(e.ts(), m.ts())) {
      // 10 digits, not std::to_string's six decimals, which print 20 µs as "0.000020" for both sides
      const std::string buf = " has sample time " + nlid::detail::format_g(e.ts(), 10) + " s but the model " +
                              nlid::detail::format_g(m.ts(), 10) + " s (relative difference " +
                              nlid::detail::format_g(std::abs(e.ts() - m.ts()) / m.ts(), 3) + ")";
      // Nearly equal: the file's stamps jitter or are rounded around the model's rate.
      std::string hint = std::abs(e.ts() - m.ts()) < nlid::one_rate_hint_tolerance * m.ts()
                             ? "if the file was logged at the model's rate, give it with --ts " +
                                   nlid::detail::format_g(m.ts() / static_cast<double>(decimate), 10)
                             : "resample the data or re-estimate the model";
      // Against the file's own sample time: the remedy is a --decimate factor, or none at all.
      const double ratio = m.ts() / (e.ts() / decimate);
      const double whole = std::round(ratio);
      if (whole >= 1 && std::abs(ratio - whole) < 1e-6 * ratio) {
        const auto factor = static_cast<long>(whole);
        hint = factor == 1 ? "the file already has the model's sample time: drop --decimate"
                           : "the model's sample time is " + std::to_string(factor) + " times the file's: use --decimate " +
                                 std::to_string(factor);
      }
      throw nlid::Error("sample-time mismatch: " + input + (decimate > 1 ? " decimated by " + std::to_string(decimate) : "") +
                        buf + "; the model is " + model + " - " + hint);
    }
    // A free run: from zero or an equilibrium the simulation needs no output (a zero column of
    // the right size); measured and estimated starts read the record's. Within the tolerance the
    // run takes the model's sample time, so the model's own check agrees.
    const nlid::Experiment run(e.u(), reads_outputs ? e.y() : Eigen::MatrixXd::Zero(e.size(), ny),
                               m.ts() > 0 ? m.ts() : e.ts());
    nlid::Experiment named = run;
    named.set_t0(e.t0());
    named.set_input_names(e.input_names());
    if (reads_outputs) named.set_output_names(e.output_names());
    // Outside the inputs the model was fitted on it extrapolates (a sigmoid network continues its
    // linear term: the study's nlarx5 gives 950 deg at u = 5). Say so, once, with where and how far.
    for (std::size_t c = 0; c < m.info().input_range.size() && static_cast<Eigen::Index>(c) < e.u().cols(); ++c) {
      const nlid::ChannelRange& r = m.info().input_range[c];
      const auto col = e.u().col(static_cast<Eigen::Index>(c));
      Eigen::Index first = -1;
      for (Eigen::Index i = 0; i < col.size() && first < 0; ++i)
        if (!r.contains(col(i))) first = i;
      if (first < 0) continue;
      std::cerr << "nlid-sim: note: the input leaves the range of the model's estimation data ("
                << nlid::detail::format_g(r.lower, 6) << " to " << nlid::detail::format_g(r.upper, 6) << ") from sample "
                << static_cast<long>(first) << " on (t = "
                << nlid::detail::format_g(e.t0() + static_cast<double>(first) * e.ts(), 10)
                << " s; the input spans " << nlid::detail::format_g(col.minCoeff(), 6) << " to "
                << nlid::detail::format_g(col.maxCoeff(), 6) << "): the model extrapolates there\n";
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
      std::snprintf(buf, sizeof buf, "the simulated output is not finite%s from sample %ld on (t = %s s",
                    value.c_str(), i, nlid::detail::format_g(t(static_cast<Eigen::Index>(i)), 10).c_str());
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
      y = m.simulate(named, ic);
    } catch (const nlid::DivergenceError& d) {
      if (d.sample() < 0 || d.sample() >= static_cast<long>(t.size())) throw;
      throw diverged(d.sample(), "");
    } catch (const nlid::Error& err) {
      // The library says "InitialCondition::measured"; a tool user wrote --x0 measured.
      if (ic == nlid::InitialCondition::measured && err.where().parameter == "InitialCondition::measured") {
        // The linear models say why in their own words (OE with several inputs, state space).
        nlid::Location l = nlid::at_parameter("--x0");
        l.file = input;
        throw nlid::Error(err.message(), l);
      }
      if (ic == nlid::InitialCondition::measured &&
          (err.where().parameter == "initial" || err.where().parameter == "initial_condition"))
        throw nlid::Error("--x0 measured takes the start from the record's past outputs, which are not the state of a " +
                              m.kind() + " model: use --x0 zero, equilibrium or estimate",
                          nlid::at_parameter("--x0"));
      // The model's checks of the record (too short for its history, ...) know no file.
      if (!err.where().file.empty()) throw;
      nlid::Location l = err.where();
      l.file = input;
      if (l.parameter == "initial") l.parameter = "--x0";
      throw nlid::Error(err.message(), l);
    }
    for (Eigen::Index i = 0; i < y.rows(); ++i) {
      if (!y.row(i).allFinite()) {
        Eigen::Index j = 0;
        while (std::isfinite(y(i, j))) ++j;
        const std::string value = ny == 1 ? " (" + nlid::detail::format_g(y(i, j)) + ")"
                                          : " (y" + std::to_string(j + 1) + " = " + nlid::detail::format_g(y(i, j)) + ")";
        throw diverged(static_cast<long>(i), value);
      }
    }
    Eigen::MatrixXd y_std;
    if (band) {
      stage = "computing the simulation band of " + model;
      nlid::SimulationBandOptions bo;
      bo.initial_condition = ic;
      y_std = nlid::simulation_band(m, nlid::Dataset(named), bo).stddev[0];
    }
    stage = "writing " + out;
    const bool with_input = a.has("--with-input");
    std::vector<std::string> header{"t"};
    if (with_input) header.insert(header.end(), columns.begin(), columns.end());
    const auto y_name = [&](Eigen::Index j) { return ny == 1 ? std::string("y") : "y" + std::to_string(j + 1); };
    for (Eigen::Index j = 0; j < ny; ++j) header.push_back(y_name(j));
    if (band)
      for (Eigen::Index j = 0; j < ny; ++j) header.push_back(y_name(j) + "_std");
    for (std::size_t i = 0; i < header.size(); ++i)
      for (std::size_t k = 0; k < i; ++k)
        if (header[i] == header[k])
          throw UsageError("--with-input: the input column '" + header[i] +
                           "' has the name of an output column of nlid-sim's file; rename it in " + input);
    std::string text;
    // Quoted as write_csv quotes: an input column "cmd, V" must read back as one column.
    for (std::size_t i = 0; i < header.size(); ++i) text += (i ? "," : "") + nlid::detail::quote_if_needed(header[i], ',');
    text += '\n';
    text.reserve(static_cast<std::size_t>(e.size()) * 26 * header.size());
    const auto put = [&](double v, bool last) {
      nlid::detail::append_g(text, v, 17);
      text += last ? '\n' : ',';
    };
    for (Eigen::Index i = 0; i < y.rows(); ++i) {
      put(t(i), false);
      if (with_input)
        for (Eigen::Index j = 0; j < e.u().cols(); ++j) put(e.u()(i, j), false);
      for (Eigen::Index j = 0; j < ny; ++j) put(y(i, j), !band && j + 1 == ny);
      if (band)
        for (Eigen::Index j = 0; j < ny; ++j) put(y_std(i, j), j + 1 == ny);
    }
    nlid::write_file_atomically(out, text);
    std::cerr << "nlid-sim: " << y.rows() << " samples simulated (" << m.kind() << ", x0 " << x0 << ") -> " << out << "\n";
    return nlid_tools::exit_ok;
  });
}
