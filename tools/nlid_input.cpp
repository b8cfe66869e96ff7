// nlid-input: designs an input signal for an identification experiment and writes it as CSV
// (columns t and the input), ready for the test rig's signal player and, with the measured
// output added, for nlid-fit.
//
//   nlid-input --signal prbs --bits B [--periods P] [--hold H] --ts T [--levels LO,HI] --out u.csv
//   nlid-input --signal random-steps --samples N --hold MIN,MAX --ts T [--levels LO,HI] [--seed S]
//   --out u.csv nlid-input --signal random-binary|random-gaussian --samples N --ts T [--band LO,HI]
//   [--levels LO,HI] [--seed S] --out u.csv nlid-input --signal multisine --period N [--periods P]
//   [--band LO,HI] [--lines all|odd|random-odd]
//              [--phases schroeder|random] [--seed S] --ts T [--levels LO,HI] --out u.csv
//
// Signals, levels and bands as in nlid/data/input_design.hpp (docs/data.md, "Input design"):
// bands are fractions of the Nyquist frequency; --levels are the two values of a binary signal,
// mean ∓ one standard deviation of a Gaussian one, minimum and maximum otherwise. A summary
// (length, duration, what the signal covers) goes to stderr. The file is written atomically.
// Exit status (cli_common.hpp): 0 on success, 1 if the file cannot be written, 2 on a bad
// command line (an option that does not apply to the chosen signal included).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <iostream>
#include <limits>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "cli_common.hpp"
#include "nlid/core/atomic_file.hpp"
#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/data/input_design.hpp"

namespace {

constexpr const char* kUsage =
    "usage: nlid-input --signal KIND --ts T --out u.csv [options]\n"
    "  --signal prbs             maximum-length binary sequence: --bits B (2..24) [--periods P] "
    "[--hold H]\n"
    "  --signal random-steps     amplitude-modulated steps (APRBS): --samples N --hold MIN,MAX "
    "[--seed S]\n"
    "  --signal random-binary    sign of band-limited noise: --samples N [--band LO,HI] [--seed "
    "S]\n"
    "  --signal random-gaussian  band-limited Gaussian noise: --samples N [--band LO,HI] [--seed "
    "S]\n"
    "  --signal multisine        --period N [--periods P] [--band LO,HI] [--lines "
    "all|odd|random-odd]\n"
    "                            [--phases schroeder|random] [--seed S]\n"
    "  --levels LO,HI   binary: the two values; gaussian: mean -/+ one standard deviation;\n"
    "                   multisine, random-steps: minimum and maximum (default -1,1)\n"
    "  --band LO,HI     excited band as fractions of the Nyquist frequency (default 0,1)\n"
    "  --column NAME    name of the input column (default u)\n";

using nlid_tools::UsageError;

// "LO,HI" as two finite numbers.
std::pair<double, double> parse_pair(const std::string& flag, const std::string& v) {
  const auto comma = v.find(',');
  if (comma == std::string::npos || v.find(',', comma + 1) != std::string::npos)
    throw UsageError(flag + " needs two numbers separated by a comma (LO,HI), got '" + v + "'");
  return {nlid_tools::parse_number(flag, v.substr(0, comma)),
          nlid_tools::parse_number(flag, v.substr(comma + 1))};
}

}  // namespace

int main(int argc, char** argv) {
  std::string stage = "reading the command line", sizes;
  return nlid_tools::guarded_main("nlid-input", kUsage, stage, sizes, [&]() -> int {
    // Which options each signal takes (besides --signal, --ts, --out, --levels, --column).
    const std::map<std::string, std::vector<std::string>> applies = {
        {"prbs", {"--bits", "--periods", "--hold"}},
        {"random-steps", {"--samples", "--hold", "--seed"}},
        {"random-binary", {"--samples", "--band", "--seed"}},
        {"random-gaussian", {"--samples", "--band", "--seed"}},
        {"multisine", {"--period", "--periods", "--band", "--lines", "--phases", "--seed"}},
    };
    const std::vector<std::string> common = {"--signal", "--ts", "--out", "--levels", "--column"};
    using nlid_tools::OptionSpec;
    const nlid_tools::ParsedOptions a = nlid_tools::parse_options(
        argc, argv,
        {{"--signal", OptionSpec::once, {"prbs", "random-steps", "random-binary", "random-gaussian", "multisine"}},
         {"--ts"},
         {"--out"},
         {"--levels"},
         {"--column"},
         {"--bits"},
         {"--periods"},
         {"--hold"},
         {"--samples"},
         {"--seed"},
         {"--band"},
         {"--period"},
         {"--lines", OptionSpec::once, {"all", "odd", "random-odd"}},
         {"--phases", OptionSpec::once, {"schroeder", "random"}}});
    if (a.help) {
      std::cout << kUsage;
      return nlid_tools::exit_ok;
    }
    if (!a.has("--signal") || !a.has("--ts") || !a.has("--out"))
      throw UsageError("--signal, --ts and --out are required");
    const std::string signal = a.get("--signal");
    const auto it = applies.find(signal);
    for (const auto& [k, v] : a.given) {
      if (std::find(common.begin(), common.end(), k) != common.end()) continue;
      if (std::find(it->second.begin(), it->second.end(), k) == it->second.end())
        throw UsageError("option " + k + " does not apply to --signal " + signal);
    }
    const double ts = nlid_tools::parse_sample_time("--ts", a.get("--ts"));
    nlid::InputLevels levels;
    if (a.has("--levels")) {
      const auto [lo, hi] = parse_pair("--levels", a.get("--levels"));
      if (!(lo < hi)) throw UsageError("--levels needs LO < HI, got '" + a.get("--levels") + "'");
      // The signals are scaled by HI - LO: near the largest doubles that overflows to inf.
      if (!std::isfinite(hi - lo))
        throw UsageError("--levels needs a finite span HI - LO, got '" + a.get("--levels") + "'");
      levels = {lo, hi};
    }
    nlid::InputBand band;
    if (a.has("--band")) {
      const auto [lo, hi] = parse_pair("--band", a.get("--band"));
      if (!(lo >= 0.0 && lo < hi && hi <= 1.0))
        throw UsageError(
            "--band needs 0 <= LO < HI <= 1 (fractions of the Nyquist frequency), got '" +
            a.get("--band") + "'");
      band = {lo, hi};
    }
    const std::string column = a.get("--column", "u");
    if (column.empty() || column == "t" || column.find_first_of(",;\"\n\r\t") != std::string::npos)
      throw UsageError("--column needs a plain name other than 't', got '" + column + "'");
    const auto seed =
        static_cast<std::uint64_t>(a.get_integer("--seed", 0, std::numeric_limits<long>::max(), 1));
    auto required = [&](const std::string& k) {
      if (!a.has(k)) throw UsageError("--signal " + signal + " needs " + k);
      return a.get(k);
    };
    const std::string out = a.get("--out");
    nlid_tools::check_output_file("--out", out);

    Eigen::VectorXd u;
    std::string what;
    // The generators' errors all come from option values (a band without DFT lines, …): a bad
    // command line, exit 2, with the generator's message.
    try {
      if (signal == "prbs") {
        const int bits =
            nlid_tools::parse_int("--bits", required("--bits"), 2, nlid::prbs_max_bits);
        const int periods = a.get_int("--periods", 1, 1000000, 1);
        const int hold = a.get_int("--hold", 1, 1000000, 1);
        if (((1L << bits) - 1) * static_cast<long>(periods) * hold > (1L << 31))
          throw UsageError("(2^--bits - 1) x --periods x --hold is more than 2^31 samples");
        stage = "generating the PRBS";
        u = nlid::prbs(bits, periods, levels, hold);
        what = "period " + std::to_string((1L << bits) - 1) + " chips of " + nlid::detail::format_g(hold * ts, 6) +
               " s; spectrum flat to about " + nlid::detail::format_g(0.44 / (hold * ts), 6) +
               " Hz, first null at " + nlid::detail::format_g(1.0 / (hold * ts), 6) + " Hz";
      } else if (signal == "multisine") {
        nlid::MultisineOptions o;
        o.band = band;
        o.levels = levels;
        o.seed = seed;
        o.periods = a.get_int("--periods", 1, 1000000, 1);
        const std::string lines = a.get("--lines"), phases = a.get("--phases");
        o.lines = lines == "odd"          ? nlid::MultisineLines::odd
                  : lines == "random-odd" ? nlid::MultisineLines::random_odd
                                          : nlid::MultisineLines::all;
        o.phases = phases == "random" ? nlid::MultisinePhases::random : nlid::MultisinePhases::schroeder;
        const long period =
            nlid_tools::parse_integer("--period", required("--period"), 4, 10000000);
        if (period * static_cast<long>(o.periods) > (1L << 31))
          throw UsageError("--period times --periods is more than 2^31 samples");
        stage = "generating the multisine";
        const std::vector<Eigen::Index> k = nlid::multisine_lines(period, o);
        u = nlid::multisine(period, o);
        const double df = 1.0 / (static_cast<double>(period) * ts);
        what = std::to_string(k.size()) + " lines from " + nlid::detail::format_g(static_cast<double>(k.front()) * df, 6) +
               " Hz to " + nlid::detail::format_g(static_cast<double>(k.back()) * df, 6) + " Hz (spacing " +
               nlid::detail::format_g(df, 6) + " Hz), period " +
               nlid::detail::format_g(static_cast<double>(period) * ts, 6) + " s";
      } else {
        const long n = nlid_tools::parse_integer("--samples", required("--samples"), 2, 1L << 31);
        if (signal == "random-steps") {
          const auto [lo, hi] = parse_pair("--hold", required("--hold"));
          if (!(lo >= 1 && hi >= lo && lo == std::floor(lo) && hi == std::floor(hi) &&
                hi <= static_cast<double>(n)))
            throw UsageError(
                "--hold needs whole sample counts 1 <= MIN <= MAX <= --samples, got '" +
                a.get("--hold") + "'");
          stage = "generating the random steps";
          u = nlid::random_steps(n, static_cast<Eigen::Index>(lo), static_cast<Eigen::Index>(hi),
                                 levels, seed);
          long steps = 1;
          for (Eigen::Index i = 1; i < u.size(); ++i) steps += u[i] != u[i - 1] ? 1 : 0;
          what = std::to_string(steps) + " steps held " + nlid::detail::format_g(lo * ts, 6) + " to " +
                 nlid::detail::format_g(hi * ts, 6) + " s";
        } else {
          stage = "generating the " + signal + " signal";
          u = signal == "random-binary" ? nlid::random_binary(n, band, levels, seed)
                                        : nlid::random_gaussian(n, band, levels, seed);
          what = "band " + nlid::detail::format_g(band.low * 0.5 / ts, 6) + " to " +
                 nlid::detail::format_g(band.high * 0.5 / ts, 6) + " Hz";
        }
      }
    } catch (const nlid::Error& e) {
      // The generators name their arguments; the user typed the options.
      nlid::Location l = e.where();
      static const std::pair<const char*, const char*> options[] = {
          {"band", "--band"},     {"levels", "--levels"}, {"n", "--samples"}, {"bits", "--bits"},
          {"hold", "--hold"},     {"min_hold", "--hold"}, {"max_hold", "--hold"}, {"period", "--period"},
          {"periods", "--periods"}};
      for (const auto& [from, to] : options)
        if (l.parameter == from) l.parameter = to;
      throw UsageError(nlid::Error(e.message(), l).what());
    }
    // The time stamps are i * ts: with a huge --ts the last ones overflow to inf, which no reader
    // takes as a time. Checked on the duration, which the summary line prints too.
    if (!std::isfinite(static_cast<double>(u.size()) * ts))
      throw UsageError("--ts " + a.get("--ts") + " is too large for " + std::to_string(u.size()) +
                       " samples: the time stamps would not be finite");

    stage = "writing " + out;
    std::string text = "t," + column + "\n";
    text.reserve(static_cast<std::size_t>(u.size()) * 40);
    for (Eigen::Index i = 0; i < u.size(); ++i) {
      nlid::detail::append_g(text, static_cast<double>(i) * ts, 17);
      text += ',';
      nlid::detail::append_g(text, u[i], 17);
      text += '\n';
    }
    nlid::write_file_atomically(out, text);
    std::fprintf(stderr,
                 "nlid-input: %s, %ld samples (%s s at ts %s s), %s to %s; %s -> %s\n", signal.c_str(),
                 static_cast<long>(u.size()), nlid::detail::format_g(static_cast<double>(u.size()) * ts, 6).c_str(),
                 nlid::detail::format_g(ts, 6).c_str(), nlid::detail::format_g(u.minCoeff(), 6).c_str(),
                 nlid::detail::format_g(u.maxCoeff(), 6).c_str(), what.c_str(), out.c_str());
    return nlid_tools::exit_ok;
  });
}
