// libFuzzer harness for the CSV readers (data/csv.hpp): read_csv_table, read_csv and
// read_csv_dataset, then write_csv / write_csv_table and back.
//
// Input: byte 0 picks the options (delimiter, decimal comma, missing-value policy, which columns,
// time column or sample-time override); the rest is the file. The readers take paths, so the text
// goes to a per-process file (in /dev/shm when there is one: the writers fsync).
//
// Contract checked here:
// - bad text throws nlid::Error naming the file (and a row inside it); any other exception, or an
//   Error that lost the file, is a defect;
// - what is returned holds NaN/Inf only under NonFinitePolicy::keep, and a sample time that is
//   positive, finite and near the time column's step;
// - valid_utf8 (which names the experiment after the file) returns valid UTF-8;
// - what the writers accept reads back the same: names, every value bit for bit (NaN as NaN),
//   and the same time grid t0 + k·ts.
#include <unistd.h>

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <initializer_list>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include "nlid/core/error.hpp"
#include "nlid/core/utf8.hpp"
#include "nlid/data/csv.hpp"

namespace {

[[noreturn]] void csv_fuzz_defect(const std::string& what) {
  std::fprintf(stderr, "csv_fuzz: DEFECT: %s\n", what.c_str());
  std::fflush(stderr);
  std::abort();
}

std::string csv_fuzz_path(const char* tag) {
  static const std::string dir = [] {
    std::error_code ec;
    if (std::filesystem::is_directory("/dev/shm", ec)) return std::string("/dev/shm");
    const char* t = std::getenv("TMPDIR");
    return std::string(t != nullptr && *t != '\0' ? t : "/tmp");
  }();
  return dir + "/nlid_csv_fuzz_" + std::to_string(static_cast<long>(getpid())) + "_" + tag + ".csv";
}

// The files of this process, removed when libFuzzer exits normally (a crash leaves them to look at).
void csv_fuzz_cleanup() {
  std::error_code ec;
  for (const char* tag : {"in", "rt", "rtt"}) std::filesystem::remove(csv_fuzz_path(tag), ec);
}

bool csv_fuzz_same(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  if (a.rows() != b.rows() || a.cols() != b.cols()) return false;
  for (Eigen::Index i = 0; i < a.size(); ++i) {
    const double x = a.data()[i], y = b.data()[i];
    if (std::isnan(x) && std::isnan(y)) continue;  // the writer does not keep NaN payloads
    if (std::bit_cast<std::uint64_t>(x) != std::bit_cast<std::uint64_t>(y)) return false;
  }
  return true;
}

// Runs a reader on the fuzzed file. An nlid::Error must name that file and, if it names a row,
// one the file has; returns false when the reader refused the input.
template <class F>
bool csv_fuzz_attempt(F&& f, const std::string& path, long lines, const char* who) {
  try {
    f();
    return true;
  } catch (const nlid::Error& e) {
    if (e.where().file != path) csv_fuzz_defect(std::string(who) + ": error without the file: " + e.what());
    if (e.where().row == 0 || e.where().row > lines) {
      csv_fuzz_defect(std::string(who) + ": row outside the file: " + e.what());
    }
    if (e.where().column == 0) csv_fuzz_defect(std::string(who) + ": column 0: " + e.what());
    // Cells and names are shown escaped: a raw NUL or line break would cut or garble the message.
    const std::string_view what = e.what();
    if (std::any_of(what.begin(), what.end(), [](char c) { return static_cast<unsigned char>(c) < 0x20; })) {
      csv_fuzz_defect(std::string(who) + ": control byte in the message: " + nlid::detail::printable(e.what(), 400));
    }
  } catch (const std::exception& e) {
    csv_fuzz_defect(std::string(who) + ": non-nlid exception: " + e.what());
  }
  return false;
}

// The writers may refuse what they cannot write back (an empty name, ...) with nlid::Error.
template <class F>
bool csv_fuzz_write(F&& f) {
  try {
    f();
    return true;
  } catch (const nlid::Error&) {
    return false;
  }
}

void csv_fuzz_experiment(const nlid::Experiment& e, const nlid::CsvReadOptions& o, const nlid::CsvReadInfo& info,
                         char delim) {
  if (!(e.ts() > 0.0) || !std::isfinite(e.ts()) || !std::isfinite(e.t0())) csv_fuzz_defect("bad ts or t0");
  if (o.non_finite != nlid::NonFinitePolicy::keep && e.has_missing()) {
    csv_fuzz_defect("non-finite sample returned under " + std::string(nlid::to_string(o.non_finite)));
  }
  if (e.input_names() != o.inputs || e.output_names() != o.outputs) csv_fuzz_defect("channel names");
  // Loose on purpose: the inferred step may be snapped to a decimal, never moved far (unless the
  // tolerance lets steps differ by a factor, when the mean step may be far from the median).
  if (o.ts == 0.0 && o.time_tolerance < 1.0 && !(e.ts() > 0.5 * info.time_column_step && e.ts() < 2.0 * info.time_column_step)) {
    csv_fuzz_defect("ts " + nlid::detail::format_double(e.ts()) + " far from the column's step " +
                    nlid::detail::format_double(info.time_column_step));
  }
  // write_csv promises that read_csv with matching options gives the experiment back.
  const std::string rt = csv_fuzz_path("rt");
  nlid::CsvWriteOptions w;
  w.delimiter = delim;
  if (!csv_fuzz_write([&] { nlid::write_csv(rt, e, w); })) return;
  nlid::CsvReadOptions r = o;
  r.time_column = "t";
  r.decimal_point = '.';
  r.non_finite = nlid::NonFinitePolicy::keep;
  try {
    const nlid::Experiment b = nlid::read_csv(rt, r);
    if (!csv_fuzz_same(b.u(), e.u()) || !csv_fuzz_same(b.y(), e.y())) csv_fuzz_defect("write_csv round trip: data");
    if (b.t0() != e.t0() || !csv_fuzz_same(b.time(), e.time())) csv_fuzz_defect("write_csv round trip: time grid");
  } catch (const nlid::Error& err) {
    csv_fuzz_defect(std::string("write_csv output not read back: ") + err.what());
  }
}

void csv_fuzz_table(const nlid::CsvTable& t, const nlid::CsvTableOptions& o) {
  if (t.data.cols() != static_cast<Eigen::Index>(t.header.size())) csv_fuzz_defect("table width");
  if (o.non_finite != nlid::NonFinitePolicy::keep && !t.data.allFinite()) csv_fuzz_defect("non-finite table value");
  const std::string rt = csv_fuzz_path("rtt");
  if (!csv_fuzz_write([&] { nlid::write_csv_table(rt, t.header, t.data, o.delimiter); })) return;
  nlid::CsvTableOptions r;
  r.delimiter = o.delimiter;
  r.non_finite = nlid::NonFinitePolicy::keep;
  r.numeric_header = true;
  try {
    const nlid::CsvTable b = nlid::read_csv_table(rt, r);
    if (b.header != t.header) csv_fuzz_defect("write_csv_table round trip: header");
    if (!csv_fuzz_same(b.data, t.data)) csv_fuzz_defect("write_csv_table round trip: data");
  } catch (const nlid::Error& err) {
    csv_fuzz_defect(std::string("write_csv_table output not read back: ") + err.what());
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const unsigned sel = data[0];
  const std::string_view text(reinterpret_cast<const char*>(data) + 1, size - 1);
  static const bool cleanup_registered = std::atexit(csv_fuzz_cleanup) == 0;
  (void)cleanup_registered;
  const std::string path = csv_fuzz_path("in");
  {
    std::FILE* f = std::fopen(path.c_str(), "wb");
    if (f == nullptr) csv_fuzz_defect("cannot write " + path);
    if (!text.empty()) std::fwrite(text.data(), 1, text.size(), f);
    std::fclose(f);
  }
  const long lines = static_cast<long>(std::count(text.begin(), text.end(), '\n')) + 1;

  // read_csv names the experiment valid_utf8(file stem): the repair must give valid UTF-8 and
  // leave valid text alone.
  const std::string repaired = nlid::valid_utf8(text);
  if (nlid::first_invalid_utf8(repaired) != std::string::npos) csv_fuzz_defect("valid_utf8 output is not UTF-8");
  if (nlid::first_invalid_utf8(text) == std::string::npos && repaired != text) csv_fuzz_defect("valid_utf8 changed UTF-8");

  const char delim = ",; \t"[sel & 3];
  const char decimal = (sel & 4) && delim != ',' ? ',' : '.';
  const nlid::NonFinitePolicy policy = std::array{nlid::NonFinitePolicy::error, nlid::NonFinitePolicy::keep,
                                                  nlid::NonFinitePolicy::interpolate,
                                                  nlid::NonFinitePolicy::error}[(sel >> 3) & 3];
  const unsigned time_mode = (sel >> 6) & 3;  // inferred, override, no time column, loose tolerance

  nlid::CsvTableOptions to;
  to.delimiter = delim;
  to.decimal_point = decimal;
  to.non_finite = policy;
  to.max_gap = 3;
  to.numeric_header = time_mode == 3;
  nlid::CsvTable table;
  const bool have_table =
      csv_fuzz_attempt([&] { table = nlid::read_csv_table(path, to); }, path, lines, "read_csv_table");
  if (have_table) csv_fuzz_table(table, to);

  nlid::CsvReadOptions ro;
  ro.delimiter = delim;
  ro.decimal_point = decimal;
  ro.non_finite = policy;
  ro.max_gap = 3;
  if (time_mode == 1) ro.ts = 0.5;
  if (time_mode == 2) {
    ro.time_column.clear();
    ro.ts = 0.25;
  }
  // Exact stamps only, or steps of any length up to 2.5 T_s (above 1 the rounding allowance is not capped).
  if (time_mode == 3) ro.time_tolerance = (sel & 4) ? 1.5 : 0.0;
  if (sel & 32) {
    // Columns by position, so inputs reach the time, policy and round-trip code whatever the
    // header says: [time,] one input if there is room, the rest outputs.
    nlid::detail::CsvText t;
    if (!csv_fuzz_attempt([&] { t = nlid::detail::tokenize_csv(path, delim, decimal); }, path, lines, "tokenize")) {
      return 0;
    }
    std::vector<std::string> names = t.header;
    if (!ro.time_column.empty()) {
      ro.time_column = names.front();
      names.erase(names.begin());
    }
    ro.inputs.clear();
    if (names.size() >= 2) {
      ro.inputs.push_back(names.front());
      names.erase(names.begin());
    }
    ro.outputs = names;
  }
  nlid::CsvReadInfo info;
  nlid::Experiment e;
  if (csv_fuzz_attempt([&] { e = nlid::read_csv(path, ro, info); }, path, lines, "read_csv")) {
    csv_fuzz_experiment(e, ro, info, delim);
    // Both readers parse and fill a column alike (same cells, policy and max_gap).
    if (have_table) {
      for (std::size_t i = 0; i < ro.inputs.size(); ++i) {
        if (!csv_fuzz_same(table.col(ro.inputs[i]), e.u().col(static_cast<Eigen::Index>(i)))) {
          csv_fuzz_defect("read_csv and read_csv_table disagree on input " + ro.inputs[i]);
        }
      }
      for (std::size_t i = 0; i < ro.outputs.size(); ++i) {
        if (!csv_fuzz_same(table.col(ro.outputs[i]), e.y().col(static_cast<Eigen::Index>(i)))) {
          csv_fuzz_defect("read_csv and read_csv_table disagree on output " + ro.outputs[i]);
        }
      }
      if (!ro.time_column.empty()) {
        const Eigen::VectorXd t = table.col(ro.time_column);
        if (t(0) != e.t0()) csv_fuzz_defect("t0 differs");
        // An inferred ts reproduces the last stamp: exactly, to its printing resolution (at most
        // 1: stamps print at least whole units) or as the endpoint estimate (to rounding).
        const double last = e.time()(e.size() - 1), tl = t(t.size() - 1);
        const double slack = 1.0 + 16.0 * std::numeric_limits<double>::epsilon() * std::max(std::abs(t(0)), std::abs(tl));
        if (ro.ts == 0.0 && !(std::abs(last - tl) <= slack)) {
          csv_fuzz_defect("grid ends at " + nlid::detail::format_double(last) + ", the column at " +
                          nlid::detail::format_double(tl));
        }
      }
    }
    // The same file twice must fit one data set.
    if (!csv_fuzz_attempt([&] { (void)nlid::read_csv_dataset({path, path}, ro); }, path, lines, "read_csv_dataset")) {
      csv_fuzz_defect("read_csv_dataset refused a file read_csv accepts");
    }
  }
  return 0;
}
