// nlid-sim: free-run simulation of a saved model on an input recording.
//
//   nlid-sim --model model.json --input u.csv [--x0 zero|equilibrium] [--column u]
//            [--decimate N] [--time t] [--ts T] [--delimiter C] [--decimal C] --out y.csv
//
// The input CSV has a time column t (or --ts) and the model's input column (its name from the
// model file, or --column); other columns are ignored. --delimiter and --decimal read files
// written with other separators (record_options.hpp). --decimate N filters and keeps every N-th
// input sample as nlid-fit does, so a model fitted with `nlid-fit --decimate N` runs on the same
// raw recordings. The output CSV has columns t,y (the
// model's output name is not used so that scripts can rely on "y"). Exit status 0 on success,
// 1 on a user error (bad file, missing column, sample-time mismatch — the message says which),
// 2 on bad usage.
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
#include "nlid/models/spec.hpp"
#include "record_options.hpp"

namespace {
constexpr const char* kUsageHead =
    "usage: nlid-sim --model model.json --input u.csv [--x0 zero|equilibrium] [--column NAME]\n"
    "                [--decimate N] [--time t] [--ts T] [--delimiter C] [--decimal C] --out y.csv\n"
    "  --decimate N     anti-alias filter the input and keep every N-th sample (as nlid-fit --decimate)\n"
    "Reading the input CSV file:\n";
std::string usage_text() { return std::string(kUsageHead) + nlid_tools::record_usage; }
}

int main(int argc, char** argv) {
  std::string model, input, out, x0 = "zero", column;
  int decimate = 1;
  nlid_tools::RecordOptions record;
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    if (k == "-h" || k == "--help") {
      std::cout << usage_text();
      return 0;
    }
    if (i + 1 >= argc) {
      std::cerr << "nlid-sim: option " << k << " needs a value\n" << usage_text();
      return 2;
    }
    const std::string v = argv[++i];
    if (k == "--model") model = v;
    else if (k == "--input") input = v;
    else if (k == "--out") out = v;
    else if (k == "--x0") x0 = v;
    else if (k == "--column") column = v;
    else if (k == "--decimate") {
      std::size_t pos = 0;
      long n = 0;
      try {
        n = std::stol(v, &pos);
      } catch (...) {
        pos = 0;
      }
      if (v.empty() || pos != v.size() || n < 1 || n > 1000000) {
        std::cerr << "nlid-sim: --decimate needs an integer from 1 to 1000000, got '" << v << "'\n";
        return 2;
      }
      decimate = static_cast<int>(n);
    }
    else if (k == "--time" || k == "--ts" || k == "--delimiter" || k == "--decimal") {
      try {
        nlid_tools::parse_record_option(k, v, record);
      } catch (const nlid::Error& e) {
        std::cerr << "nlid-sim: " << e.what() << "\n";
        return 2;
      }
    } else {
      std::cerr << "nlid-sim: unknown option '" << k << "'\n" << usage_text();
      return 2;
    }
  }
  if (model.empty() || input.empty() || out.empty()) {
    std::cerr << "nlid-sim: --model, --input and --out are required\n" << usage_text();
    return 2;
  }
  try {
    nlid_tools::check_record_options(record);
  } catch (const nlid::Error& e) {
    std::cerr << "nlid-sim: " << e.what() << "\n";
    return 2;
  }
  if (x0 != "zero" && x0 != "equilibrium") {
    std::cerr << "nlid-sim: --x0 must be zero or equilibrium, got '" << x0 << "'\n";
    return 2;
  }
  try {
    nlid::register_series_model_kind();
    const nlid::AnyModel m = nlid::load_model(model);
    if (m.num_inputs() != 1 && column.empty())
      throw nlid::Error("the model in " + model + " reads " + std::to_string(m.num_inputs()) +
                        " inputs; nlid-sim simulates single-input models");
    nlid::CsvReadOptions o = nlid_tools::csv_read_options(record, input);
    const auto names = m.input_names();
    o.inputs = {!column.empty() ? column : (!names.empty() && !names[0].empty() ? names[0] : std::string("u"))};
    o.outputs = {};
    nlid::Experiment e = nlid::read_csv(input, o);
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
    const Eigen::MatrixXd y =
        m.simulate(named, x0 == "zero" ? nlid::InitialCondition::zero : nlid::InitialCondition::equilibrium);
    std::string text = "t,y\n";
    text.reserve(static_cast<std::size_t>(e.size()) * 40);
    char buf[96];
    const Eigen::VectorXd t = named.time();
    for (Eigen::Index i = 0; i < y.rows(); ++i) {
      std::snprintf(buf, sizeof buf, "%.17g,%.17g\n", t(i), y(i, 0));
      text += buf;
    }
    nlid::write_file_atomically(out, text);
    std::cerr << "nlid-sim: " << y.rows() << " samples simulated (" << m.kind() << ", x0 " << x0 << ") -> " << out << "\n";
    return 0;
  } catch (const nlid::Error& err) {
    std::cerr << "nlid-sim: " << err.what() << "\n";
    return 1;
  }
}
