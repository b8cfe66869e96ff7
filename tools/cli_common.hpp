#pragma once
// What every command-line tool does the same way: exit codes, the command-line parser, integer
// options with a range, output paths checked before any work, library messages in the tools'
// words, and a top level that turns every exception into one line and an exit code.
//
// Exit codes (docs/tools.md): 0 success; 1 the command line is fine but a file, the data or the
// model is not, or the computation failed (out of memory, a diverging model); 2 the command line
// itself is wrong (unknown, missing, repeated or malformed options, an output that is an input).

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <iostream>
#include <limits>
#include <map>
#include <new>
#include <stdexcept>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include "nlid/core/atomic_file.hpp"
#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/data/experiment.hpp"

namespace nlid_tools {

inline constexpr int exit_ok = 0;
inline constexpr int exit_error = 1;  ///< bad file, data or model; out of memory; divergence
inline constexpr int exit_usage = 2;  ///< bad command line

/// A bad command line (exit 2).
struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// An integer option value in [lo, hi]; anything else (text, a fraction, overflow, out of range)
/// is a usage error naming the option and the range. No wrap-around: 4294967297 is not 1.
inline long parse_integer(const std::string& flag, const std::string& v, long lo, long hi) {
  long x = 0;
  const char* b = v.data();
  const char* e = v.data() + v.size();
  const auto [ptr, ec] = std::from_chars(b, e, x);
  const std::string range = hi == std::numeric_limits<long>::max()
                                ? "an integer >= " + std::to_string(lo)
                                : "an integer from " + std::to_string(lo) + " to " + std::to_string(hi);
  if (v.empty() || ec == std::errc::invalid_argument || ptr != e)
    throw UsageError(flag + " needs " + range + ", got '" + v + "'");
  if (ec == std::errc::result_out_of_range || x < lo || x > hi)
    throw UsageError(flag + " needs " + range + ", got '" + v + "' (out of range)");
  return x;
}

inline int parse_int(const std::string& flag, const std::string& v, int lo, int hi) {
  return static_cast<int>(parse_integer(flag, v, lo, hi));
}

/// A finite floating-point option value; anything else is a usage error naming the option.
inline double parse_number(const std::string& flag, const std::string& v) {
  std::size_t pos = 0;
  double x = std::numeric_limits<double>::quiet_NaN();
  try {
    x = std::stod(v, &pos);
  } catch (const std::out_of_range&) {
    // A number, but not one a double holds: 1e-320 (below the normal range) read as "not a
    // finite number", which it is.
    throw UsageError(flag + " needs a number within the range of a double (0, or 2.2e-308 to 1.8e308 in magnitude), got '" +
                     v + "'");
  } catch (...) {
    pos = 0;
  }
  if (v.empty() || pos != v.size() || !std::isfinite(x)) throw UsageError(flag + " needs a finite number, got '" + v + "'");
  return x;
}

/// A sample time in seconds: a positive number in the range of a double. One parser for the
/// --ts of every tool (they read it three ways: 1e-320 was a valid sample time to one, not a
/// finite number to another).
inline double parse_sample_time(const std::string& flag, const std::string& v) {
  const double x = parse_number(flag, v);
  if (!(x > 0.0)) throw UsageError(flag + " needs a positive sample time in seconds, got '" + v + "'");
  return x;
}

/// A comma-separated list of finite numbers ("0.5" or "0.2,-1,3"); an empty item, text or a
/// non-finite value is a usage error naming the option and the item (one value: as parse_number).
inline std::vector<double> parse_number_list(const std::string& flag, const std::string& v) {
  if (v.find(',') == std::string::npos) return {parse_number(flag, v)};  // one value: parse_number's message
  std::vector<double> out;
  std::size_t start = 0;
  for (;;) {
    const std::size_t comma = v.find(',', start);
    const std::string item = v.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    if (item.empty() || item.find_first_not_of(" ") == std::string::npos)
      throw UsageError(flag + " needs finite numbers separated by commas, got '" + v + "' (an empty item)");
    try {
      out.push_back(parse_number(flag, item));
    } catch (const UsageError&) {
      throw UsageError(flag + " needs finite numbers separated by commas, got '" + v + "' (item " +
                       std::to_string(out.size() + 1) + ": '" + item + "')");
    }
    if (comma == std::string::npos) return out;
    start = comma + 1;
  }
}

/// One option of a tool's command line. Every tool's messages for a bad command line come from
/// parse_options, so the six tools word them alike.
struct OptionSpec {
  enum Kind {
    once,       ///< takes one value; a second occurrence is an error (it used to win silently)
    repeated,   ///< takes a value, any number of times (--est, --val)
    flag,       ///< a switch without a value; given twice it means the same
  };
  std::string name;
  Kind kind = once;
  std::vector<std::string> allowed = {};  ///< the values it accepts; empty: any (the tool checks)
};

/// What parse_options read: the values of each option given, in command-line order (a flag holds
/// one empty value per occurrence), or `help` when -h or --help came first.
struct ParsedOptions {
  bool help = false;
  std::map<std::string, std::vector<std::string>> given;

  bool has(const std::string& name) const { return given.count(name) > 0; }
  std::string get(const std::string& name, const std::string& fallback = "") const {
    const auto it = given.find(name);
    return it == given.end() ? fallback : it->second.back();
  }
  std::vector<std::string> all(const std::string& name) const {
    const auto it = given.find(name);
    return it == given.end() ? std::vector<std::string>() : it->second;
  }
  /// The value as an integer in [lo, hi] (parse_integer), or `fallback` if the option is not given.
  long get_integer(const std::string& name, long lo, long hi, long fallback) const {
    return has(name) ? parse_integer(name, get(name), lo, hi) : fallback;
  }
  int get_int(const std::string& name, int lo, int hi, int fallback) const {
    return static_cast<int>(get_integer(name, lo, hi, fallback));
  }
  /// The value as a finite number (parse_number), or `fallback` if the option is not given.
  double get_number(const std::string& name, double fallback) const {
    return has(name) ? parse_number(name, get(name)) : fallback;
  }
};

/// Reads argv against `options`. The first problem, in command-line order, is a usage error naming
/// the word: an unknown option (no tool takes positional arguments, so any other word is one too),
/// an option without its value, a once-option given twice, a value not among `allowed`. -h or
/// --help stops the scan (what follows is not checked). A value that is one of the tool's own
/// options (or -h, --help) counts as missing: "--save --val b.csv" is a forgotten file name, not
/// a model saved as "./--val". `dashed_value_is_missing`: any value starting with "--" does, as
/// nlid-diagnose has always read it.
inline ParsedOptions parse_options(int argc, const char* const* argv, const std::vector<OptionSpec>& options,
                                   bool dashed_value_is_missing = false) {
  ParsedOptions r;
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    if (k == "-h" || k == "--help") {
      r.help = true;
      return r;
    }
    const auto spec = std::find_if(options.begin(), options.end(), [&](const OptionSpec& o) { return o.name == k; });
    if (spec == options.end()) throw UsageError("unknown option '" + k + "'");
    std::vector<std::string>& values = r.given[k];
    if (spec->kind == OptionSpec::flag) {
      values.emplace_back();
      continue;
    }
    const auto names_option = [&](const std::string& w) {
      return w == "-h" || w == "--help" ||
             std::any_of(options.begin(), options.end(), [&](const OptionSpec& o) { return o.name == w; });
    };
    if (i + 1 >= argc || names_option(argv[i + 1]) ||
        (dashed_value_is_missing && std::string(argv[i + 1]).rfind("--", 0) == 0))
      throw UsageError("option " + k + " needs a value");
    const std::string v = argv[++i];
    if (spec->kind == OptionSpec::once && !values.empty())
      throw UsageError("option " + k + " is given twice; it takes one value");
    const auto& ok = spec->allowed;
    if (!ok.empty() && std::find(ok.begin(), ok.end(), v) == ok.end()) {
      std::string list = ok.front();  // "a, b or c"
      for (std::size_t j = 1; j < ok.size(); ++j) list += (j + 1 < ok.size() ? ", " : " or ") + ok[j];
      throw UsageError(k + " must be " + list + ", got '" + v + "'");
    }
    values.push_back(v);
  }
  return r;
}

/// True if `a` and `b` name the same file: std::filesystem::equivalent when both exist (hard
/// links, symbolic links, ./x vs x), else their weakly canonical paths are compared.
inline bool same_file(const std::string& a, const std::string& b) {
  namespace fs = std::filesystem;
  std::error_code ec1, ec2;
  if (fs::exists(a, ec1) && fs::exists(b, ec2)) {
    std::error_code ec;
    const bool eq = fs::equivalent(a, b, ec);
    if (!ec) return eq;
  }
  std::error_code ea, eb;
  const fs::path ca = fs::weakly_canonical(fs::absolute(a), ea), cb = fs::weakly_canonical(fs::absolute(b), eb);
  if (ea || eb) return fs::absolute(a).lexically_normal() == fs::absolute(b).lexically_normal();
  return ca == cb;
}

/// A (flag, path) pair of the command line.
using FlagPath = std::pair<std::string, std::string>;

/// Refuses an output that is the same file as an input or as another output (usage error): the
/// output would destroy the input before, or while, it is read.
inline void check_outputs_distinct(const std::vector<FlagPath>& outputs, const std::vector<FlagPath>& inputs) {
  for (std::size_t i = 0; i < outputs.size(); ++i) {
    const auto& [of, op] = outputs[i];
    if (op.empty()) continue;
    for (const auto& [inf, ip] : inputs)
      if (!ip.empty() && same_file(op, ip))
        throw UsageError(of + " " + op + " is the same file as " + inf + " " + ip +
                         ": writing it would destroy the input; choose another output file");
    for (std::size_t j = 0; j < i; ++j)
      if (!outputs[j].second.empty() && same_file(op, outputs[j].second))
        throw UsageError(of + " " + op + " is the same file as " + outputs[j].first + " " + outputs[j].second +
                         ": one would overwrite the other; choose another output file");
  }
}

/// Checks, before any work, that an output file can be created where asked: its directory exists
/// and the path is not itself a directory (exit 1 via nlid::Error naming the option).
/// Creates and removes a probe file where `target` would be written (the atomic writer's own
/// temporary-name scheme), so an unwritable location (no permission, a read-only or virtual file
/// system such as /proc) stops the tool before any work, not after it.
inline void check_can_create(const std::string& flag, const std::string& shown, const std::string& target,
                             const std::string& dir) {
  const std::filesystem::path probe = nlid::detail::temporary_sibling(std::filesystem::path(target));
  try {
    nlid::detail::write_temporary(probe, std::string_view(), nlid::detail::file_location(target));
  } catch (const nlid::Error& e) {
    throw nlid::Error(flag + " " + shown + ": cannot create files in directory '" + dir + "' (" + e.message() + ")",
                      nlid::at_parameter(flag));
  }
  std::error_code ec;
  std::filesystem::remove(probe, ec);
}

inline void check_output_file(const std::string& flag, const std::string& path) {
  namespace fs = std::filesystem;
  if (path.empty()) return;
  std::error_code ec;
  if (fs::is_directory(path, ec))
    throw nlid::Error(flag + " " + path + " is a directory; give a file name", nlid::at_parameter(flag));
  fs::path dir = fs::path(path).parent_path();
  if (dir.empty()) dir = ".";
  if (!fs::exists(dir, ec))
    throw nlid::Error(flag + " " + path + ": output directory '" + dir.string() + "' does not exist; create it first",
                      nlid::at_parameter(flag));
  if (!fs::is_directory(dir, ec))
    throw nlid::Error(flag + " " + path + ": '" + dir.string() + "' is not a directory", nlid::at_parameter(flag));
  check_can_create(flag, path, path, dir.string());
}

/// Checks that an output directory exists and is a directory (exit 1 via nlid::Error).
inline void check_output_dir(const std::string& flag, const std::string& dir) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::exists(dir, ec))
    throw nlid::Error("output directory '" + dir + "' does not exist; create it first", nlid::at_parameter(flag));
  if (!fs::is_directory(dir, ec))
    throw nlid::Error(flag + " " + dir + " is not a directory (it names the directory for the output files)",
                      nlid::at_parameter(flag));
  check_can_create(flag, dir, (std::filesystem::path(dir) / "nlid").string(), dir);
}

/// A library message in the tools' words: hints that name C++ option fields name the flag.
inline std::string translate(std::string s) {
  static const std::pair<const char*, const char*> table[] = {
      {" (CsvReadOptions::ts with time_column \"\"; --ts in the tools)", " (--ts)"},
      {" (CsvReadOptions::delimiter; --delimiter in the tools)", " (--delimiter)"},
      // In the tools --ts does not paper over a gap (docs/tools.md): resampling is the remedy.
      {"missing samples? cut the record at the gap or fill it, or raise CsvReadOptions::time_tolerance if the stamps only jitter",
       "missing samples? cut the record at the gap or resample it onto a uniform grid (--ts cannot make it even); "
       "if the stamps only jitter, give --time-tolerance (at most 0.5)"},
      // No tool reads with gaps left open: the remedy is in the data, not in an option.
      {" under NonFinitePolicy::error; use NonFinitePolicy::keep or ::interpolate for missing data",
       ": the tools need complete records; fill or cut out the missing samples first"},
      {" (use NonFinitePolicy::keep or ::interpolate for missing data)",
       " (the tools need complete records; fill or cut out the missing samples first)"},
      {"set CsvReadOptions::ts", "give --ts"},
      {"pass one in DiagnoseOptions::noise", "give one with --noise SIGMA (the output's noise standard deviation)"},
      {"set it (set_ts) or CodegenOptions::ts", "give --ts"},
      {"set CodegenOptions::ts", "give --ts"},
      {"set CodegenOptions::substeps", "give --substeps"},
      {"more than IntegratorOptions::max_substeps = ", "more than the ceiling of "},
      {"CodegenOptions::ts", "--ts"},
      {"CodegenOptions::substeps = ", "--substeps "},
      {"CodegenOptions::substeps", "--substeps"},
      {"CodegenOptions::initial_state", "--x0"},
      {"CodegenOptions::equilibrium_input", "--u0"},
      {"CodegenOptions::name", "--name"},
      {"CodegenOptions::precision", "--precision"},
      {"CodegenOptions::linear_form", "--linear-form"},
      {"CsvReadOptions::ts", "--ts"},
      {"CsvReadOptions::delimiter", "--delimiter"},
      {"CsvReadOptions::decimal_point", "--decimal"},
      {"CsvReadOptions::time_column", "--time"},
      {"IntegratorOptions::substeps / min_substeps, or use the adaptive method", "--substeps (nlid-codegen)"},
      {"IntegratorOptions::substeps", "--substeps (nlid-codegen)"},
      // No flag sets the adaptive budget: it is part of the model file's integrator.
      {"IntegratorOptions::max_adaptive_steps", "max_adaptive_steps (the model file's structure.integrator)"},
      {"DiagnoseOptions::decimate", "--decimate"},
      {"DiagnoseOptions::starts", "--starts"},
      {"LmOptions::max_iterations", "--iterations"},
      {"use InitialCondition::zero or ::estimate", "use --x0 zero"},
      {"use InitialCondition::estimate or zero", "start from an estimated or a zero state (nlid-fit: ic=estimate or ic=zero in the greybox SPEC; nlid-sim: --x0 estimate or zero)"},
      {"equilibrium_input", "--u0"},
      // The linear models' refusals of a measured start (nlid-sim --x0 measured).
      {"use InitialCondition::estimate for a state-space model", "use --x0 estimate for a state-space model"},
      {"; use ::estimate", "; use --x0 estimate"},
      {"InitialCondition::measured", "--x0 measured"},
  };
  for (const auto& [from, to] : table) {
    for (std::size_t p = s.find(from); p != std::string::npos; p = s.find(from, p + std::string(to).size()))
      s.replace(p, std::string(from).size(), to);
  }
  return s;
}

/// A non-numeric cell that looks like a decimal comma ('0,5') read with the decimal point: the
/// hint names --decimal (only for tools that have the option).
inline std::string decimal_hint(const nlid::Error& e, char delimiter, char decimal) {
  const std::string& m = e.message();
  const std::string key = "non-numeric cell '";
  if (decimal != '.' || delimiter == ',' || m.rfind(key, 0) != 0) return {};
  const std::string cell = m.substr(key.size(), m.find('\'', key.size()) - key.size());
  std::string dotted = cell;
  bool comma = false;
  for (char& c : dotted)
    if (c == ',') c = '.', comma = true;
  if (!comma) return {};
  double x = 0;
  const auto [p, ec] = std::from_chars(dotted.data(), dotted.data() + dotted.size(), x);
  if (ec != std::errc() || p != dotted.data() + dotted.size()) return {};
  return "; the cell has a decimal comma - read the file with --decimal ,";
}

/// Refuses estimation data in which an input channel holds one value in every record: the
/// input's effect on the output cannot be identified from it (exit 1).
inline void check_inputs_vary(const std::vector<const nlid::Experiment*>& records,
                              const std::vector<std::string>& files, const std::string& flag) {
  if (records.empty()) return;
  const Eigen::Index nu = records.front()->u().cols();
  for (Eigen::Index j = 0; j < nu; ++j) {
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (const nlid::Experiment* e : records) {
      if (e->size() == 0) continue;
      lo = std::min(lo, e->u().col(j).minCoeff());
      hi = std::max(hi, e->u().col(j).maxCoeff());
    }
    if (lo == hi) {
      const auto names = records.front()->input_names();
      const std::string name = static_cast<std::size_t>(j) < names.size() ? names[static_cast<std::size_t>(j)] : "u";
      std::string list;
      for (std::size_t i = 0; i < files.size(); ++i) list += (i ? ", " : "") + files[i];
      const std::string value = nlid::detail::format_g(lo, 10);
      nlid::Location l;
      l.column_name = name;
      l.parameter = flag;
      if (files.size() == 1) l.file = files[0];
      throw nlid::Error("input '" + name + "' is constant (" + value + ") in every estimation record (" + list +
                            "): its effect on the output cannot be identified; estimate on records in which '" +
                            name + "' varies",
                        l);
    }
  }
}

/// The top level of a tool: runs `body` and turns every exception into one line on stderr and an
/// exit code. `stage` says what the tool was doing (for out-of-memory and internal errors);
/// `sizes` what was being processed (e.g. the model spec and the sample count).
template <class Body>
int guarded_main(const std::string& tool, const std::string& usage, const std::string& stage, const std::string& sizes,
                 Body&& body) {
  const std::string head = tool + ": ";
  const auto where = [&] {
    std::string s = stage.empty() ? std::string() : " while " + stage;
    if (!sizes.empty()) s += " (" + sizes + ")";
    return s;
  };
  try {
    return body();
  } catch (const UsageError& e) {
    std::cerr << head << translate(e.what()) << "\n";
    if (!usage.empty()) std::cerr << "\n" << usage;
    return exit_usage;
  } catch (const nlid::Error& e) {
    std::cerr << head << translate(e.what()) << "\n";
    return exit_error;
  } catch (const std::bad_alloc&) {
    std::cerr << head << "out of memory" << where()
              << ": the model or the data are too large for memory; use a smaller model or fewer samples\n";
    return exit_error;
  } catch (const std::length_error& e) {
    std::cerr << head << "size limit exceeded" << where() << " (" << e.what()
              << "): the model or the data are too large; use a smaller model or fewer samples\n";
    return exit_error;
  } catch (const std::exception& e) {
    std::cerr << head << "internal error" << where() << ": " << e.what() << "\n";
    return exit_error;
  } catch (...) {
    std::cerr << head << "internal error" << where() << " (unknown exception)\n";
    return exit_error;
  }
}

}  // namespace nlid_tools
