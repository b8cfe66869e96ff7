// Shared by the command-line tool tests: run a tool binary with arguments and collect its exit
// code, stdout and stderr; write small first-order-lag recordings as CSV.
#pragma once

#include <catch2/catch.hpp>

#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "../support/scratch_dir.hpp"

namespace tool_test {

namespace fs = std::filesystem;

struct Run {
  int code = -1;
  std::string out, err;
};

/// A scratch directory per test process, removed at exit.
inline const fs::path& work_dir() { return nlid_test::scratch_dir(); }

inline std::string slurp(const fs::path& p) {
  std::ifstream f(p);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

/// Runs `exe args` through the shell; stdout captured, stderr via a file. `limit_kb` > 0 caps the
/// tool's virtual memory (`ulimit -v`), to make an allocation fail.
inline Run run_tool(const std::string& exe, const std::string& args, long limit_kb = 0) {
  const fs::path err = work_dir() / "stderr.txt";
  const std::string cmd = (limit_kb > 0 ? "ulimit -v " + std::to_string(limit_kb) + "; " : std::string()) + "\"" +
                          exe + "\" " + args + " 2>\"" + err.string() + "\"";
  Run r;
  FILE* p = ::popen(cmd.c_str(), "r");
  REQUIRE(p != nullptr);
  char buf[4096];
  std::size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, p)) > 0) r.out.append(buf, n);
  const int status = ::pclose(p);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.err = slurp(err);
  return r;
}

/// A first-order lag tau*y' = -(y - offset) + gain*u(t - delay) sampled at ts with zero-order-hold
/// input, random steps, Gaussian noise of `sigma`; written as CSV (with or without a time column).
inline fs::path write_record(const std::string& name, int n, unsigned seed, double delay_samples, bool time_column = true,
                             const std::string& ycol = "y", double ts = 0.01, double sigma = 0.01) {
  const double tau = 0.2, gain = 2.0, offset = 0.5;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> level(-1.0, 1.0);
  std::uniform_int_distribution<int> hold(30, 120);
  std::normal_distribution<double> noise(0.0, sigma);
  std::vector<double> u(static_cast<std::size_t>(n));
  for (int k = 0; k < n;) {
    const double v = level(rng);
    for (int h = hold(rng); h > 0 && k < n; --h) u[static_cast<std::size_t>(k++)] = v;
  }
  const double a = std::exp(-ts / tau);
  double y = offset;
  const fs::path p = work_dir() / (name + ".csv");
  std::ofstream f(p);
  f << (time_column ? "t," : "") << "u," << ycol << "\n";
  f.precision(10);
  const int d = static_cast<int>(delay_samples);
  for (int k = 0; k < n; ++k) {
    if (time_column) f << k * ts << ",";
    f << u[static_cast<std::size_t>(k)] << "," << y + noise(rng) << "\n";
    const double ud = u[static_cast<std::size_t>(std::max(0, k - d))];
    y = a * y + (1 - a) * (offset + gain * ud);
  }
  return p;
}

/// Quoted path for a shell command line.
inline std::string q(const fs::path& p) { return "\"" + p.string() + "\""; }

/// Column `col` (0-based) of a comma-separated file with a header row, as numbers.
inline std::vector<double> csv_column(const fs::path& p, int col) {
  std::ifstream f(p);
  std::string line;
  std::getline(f, line);
  std::vector<double> v;
  while (std::getline(f, line)) {
    std::stringstream s(line);
    std::string cell;
    for (int c = 0; c <= col; ++c) std::getline(s, cell, ',');
    v.push_back(std::stod(cell));
  }
  return v;
}

/// The column named `name` in the header row (the first one if none is).
inline std::vector<double> csv_column(const fs::path& p, const std::string& name) {
  std::ifstream f(p);
  std::string line;
  std::getline(f, line);
  std::stringstream h(line);
  std::string cell;
  int col = 0;
  for (int c = 0; std::getline(h, cell, ','); ++c)
    if (cell == name) col = c;
  return csv_column(p, col);
}

// Each tool with its command-line arguments (paths from the build: NLID_<TOOL>_EXE).
inline Run fit(const std::string& args) { return run_tool(NLID_FIT_EXE, args); }
inline Run sim(const std::string& args) { return run_tool(NLID_SIM_EXE, args); }
inline Run codegen(const std::string& args) { return run_tool(NLID_CODEGEN_EXE, args); }
inline Run diagnose(const std::string& args) { return run_tool(NLID_DIAGNOSE_EXE, args); }
inline Run input(const std::string& args) { return run_tool(NLID_INPUT_EXE, args); }
inline Run distortion(const std::string& args) { return run_tool(NLID_DISTORTION_EXE, args); }

}  // namespace tool_test
