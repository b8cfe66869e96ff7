// nlid-distortion: from a periodic recording (a multisine with empty lines, e.g. from
// `nlid-input --signal multisine --lines random-odd`), measures whether the system distorts —
// even and odd nonlinear distortion against the noise — before any model is estimated.
//
//   nlid-distortion --data rec.csv --period N [--skip P] [--threshold DB] [--input u] [--output y]
//                   [--json out.json] [--time t] [--ts T] [--delimiter C] [--decimal C]
//                   [--time-tolerance R]
//
// The record holds whole periods of N samples; the first --skip (default 1) are the transient.
// Prints `distortion_analysis`'s report (nlid/analysis/distortion.hpp, docs/analysis.md);
// --json writes the levels, the verdicts, whether each kind of distortion was measurable (an odd
// multisine leaves no odd lines to measure odd distortion on), the line lists and the frequency
// response (atomically). Exit status
// (cli_common.hpp): 0 on success (whatever the verdict), 1 on a bad file or record (too few
// periods, a constant input), 2 on a bad command line.
#include <cmath>
#include <iostream>
#include <string>
#include <vector>

#include "cli_common.hpp"
#include "nlid/analysis/distortion.hpp"
#include "nlid/core/atomic_file.hpp"
#include "nlid/core/error.hpp"
#include "nlid/core/utf8.hpp"
#include "nlid/data/csv.hpp"
#include "nlid/io/json.hpp"
#include "record_options.hpp"

namespace {
constexpr const char* kUsageHead =
    "usage: nlid-distortion --data rec.csv --period N [--skip P] [--threshold DB] [--input u] "
    "[--output y]\n"
    "                       [--json out.json] [--time t] [--ts T] [--delimiter C] [--decimal C]\n"
    "                       [--time-tolerance R]\n"
    "  --period N       samples per period of the periodic input\n"
    "  --skip P         periods skipped as the transient (default 1); at least 2 must remain\n"
    "  --threshold DB   level above the noise that counts as distortion (default 6)\n"
    "Reading the CSV file:\n";
std::string usage_text() { return std::string(kUsageHead) + nlid_tools::record_usage; }

nlid::Json number_or_null(double v) {
  return std::isfinite(v) ? nlid::Json(v) : nlid::Json(nullptr);
}
}  // namespace

int main(int argc, char** argv) {
  std::string stage = "reading the command line", sizes;
  return nlid_tools::guarded_main("nlid-distortion", usage_text(), stage, sizes, [&]() -> int {
    using nlid_tools::UsageError;
    const nlid_tools::ParsedOptions a = nlid_tools::parse_options(
        argc, argv,
        nlid_tools::with_record_options(
            {{"--data"}, {"--period"}, {"--skip"}, {"--threshold"}, {"--input"}, {"--output"}, {"--json"}}));
    if (a.help) {
      std::cout << usage_text();
      return nlid_tools::exit_ok;
    }
    const std::string data = a.get("--data"), json = a.get("--json"), input = a.get("--input", "u"),
                      output = a.get("--output", "y");
    const long period = a.get_integer("--period", 8, 100000000, 0);
    const int skip = a.get_int("--skip", 0, 1000000, 1);
    const double threshold = a.get_number("--threshold", 6.0);
    if (!(threshold > 0.0))
      throw UsageError("--threshold must be a level above the noise, in dB greater than 0, got '" +
                       a.get("--threshold") + "'");
    const nlid_tools::RecordOptions record = nlid_tools::record_options_from(a);
    if (data.empty() || period == 0) throw UsageError("--data and --period are required");
    if (!json.empty()) {
      nlid_tools::check_outputs_distinct({{"--json", json}}, {{"--data", data}});
      nlid_tools::check_output_file("--json", json);
    }
    stage = "reading " + data;
    const nlid::Experiment e =
        nlid_tools::read_record(record, data, {input}, {output}, "nlid-distortion");
    stage = "analysing " + data;
    sizes = std::to_string(e.size()) + " samples";
    nlid::DistortionAnalysis d;
    try {
      d = nlid::distortion_analysis(e, period, skip, threshold);
    } catch (const nlid::Error& err) {
      nlid::Location l = err.where();
      l.file = data;
      // The library names its arguments; the user typed the options.
      if (l.parameter == "period") l.parameter = "--period";
      else if (l.parameter == "skip_periods") l.parameter = "--skip";
      else if (l.parameter == "threshold_db") l.parameter = "--threshold";
      throw nlid::Error(err.message(), l);
    }
    std::cout << d.report();
    if (!json.empty()) {
      stage = "writing " + json;
      nlid::Json j = nlid::Json::object();
      j["data"] = nlid::valid_utf8(data);  // a Latin-1 file name would fail the write after the analysis
      j["period"] = static_cast<double>(d.period);
      j["periods"] = d.periods;
      j["ts"] = d.ts;
      j["threshold_db"] = d.threshold_db;
      j["snr_db"] = number_or_null(d.snr_db());
      j["even_db"] = number_or_null(d.even_db());
      j["odd_db"] = number_or_null(d.odd_db());
      j["even_detected"] = d.even_detected();
      j["odd_detected"] = d.odd_detected();
      // Whether the input left lines to measure each kind on (an odd multisine has no empty odd
      // lines): "not detected" means something only where the kind is measurable.
      j["even_measurable"] = d.even_measurable();
      j["odd_measurable"] = d.odd_measurable();
      auto lines = [](const std::vector<Eigen::Index>& v) {
        nlid::Json a = nlid::Json::array();
        for (Eigen::Index k : v) a.push_back(static_cast<double>(k));
        return a;
      };
      j["excited_lines"] = lines(d.excited);
      j["even_lines"] = lines(d.even_lines);
      j["odd_lines"] = lines(d.odd_lines);
      nlid::Json f = nlid::Json::array(), re = nlid::Json::array(), im = nlid::Json::array();
      for (std::size_t i = 0; i < d.excited.size(); ++i) {
        f.push_back(d.frequency(d.excited[i]));
        re.push_back(d.frf[static_cast<Eigen::Index>(i)].real());
        im.push_back(d.frf[static_cast<Eigen::Index>(i)].imag());
      }
      j["frf"] = nlid::Json::object();
      j["frf"]["frequency_hz"] = f;
      j["frf"]["real"] = re;
      j["frf"]["imag"] = im;
      nlid::write_file_atomically(json, j.dump(2) + "\n");
    }
    return nlid_tools::exit_ok;
  });
}
