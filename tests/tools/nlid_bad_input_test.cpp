// Bad input to the four command-line tools, as a user would give it: every case must end with a
// clear message naming what and where (file, row, column, flag) and the documented exit code
// (0 ok, 1 bad file/data/model or a failed run, 2 bad command line; docs/tools.md) - never a
// crash, a silent NaN, wrapped-around numbers or a destroyed input file.
#include <catch2/catch.hpp>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "tool_runner.hpp"

namespace fs = std::filesystem;
using tool_test::q;
using tool_test::fit;
using tool_test::sim;
using tool_test::codegen;
using tool_test::diagnose;
using tool_test::Run;
using tool_test::slurp;
using tool_test::work_dir;
using tool_test::write_record;

namespace {

// A record whose input is `u` everywhere (output: a noisy constant).
fs::path constant_input_record(const std::string& name, double u, int n = 600) {
  const fs::path p = work_dir() / (name + ".csv");
  std::ofstream f(p);
  f << "t,u,y\n";
  for (int k = 0; k < n; ++k) f << k * 0.01 << "," << u << "," << 1.0 + 0.01 * ((k * 7919) % 13 - 6) << "\n";
  return p;
}

// `src` without its data row `drop` (0-based): a dropped sample in a file with a time column.
fs::path without_row(const fs::path& src, const std::string& name, int drop) {
  const fs::path p = work_dir() / (name + ".csv");
  std::ifstream in(src);
  std::ofstream out(p);
  std::string line;
  for (int k = -1; std::getline(in, line); ++k)
    if (k != drop) out << line << "\n";
  return p;
}

}  // namespace

TEST_CASE("tools: out of memory is one clear line and exit 1, not a std::bad_alloc abort", "[tools][fit][bad_input]") {
  // A sigmoid network of 1000 units on 6000 samples needs a Jacobian of 6000 x 3000 doubles
  // (144 MB) and more; with the address space capped at 300 MB the allocation fails.
  const fs::path est = write_record("oom_est", 6000, 201u, 0);
  const fs::path model = work_dir() / "oom.json";
  const Run r = tool_test::run_tool(
      NLID_FIT_EXE, "--model nlarx:na=1,nb=1,nk=1:sigmoidnet:1000 --est " + q(est) + " --save " + q(model), 300000);
  INFO(r.err);
  CHECK(r.code == 1);
  CHECK_THAT(r.err, !Catch::Contains("terminate called"));
  CHECK_THAT(r.err, Catch::Contains("nlid-fit: out of memory while estimating nlarx:na=1,nb=1,nk=1:sigmoidnet:1000") &&
                        Catch::Contains("too large for memory"));
  CHECK_FALSE(fs::exists(model));
}

TEST_CASE("nlid-sim: an unstable model's inf/NaN output is refused, naming the first sample", "[tools][sim][bad_input]") {
  const fs::path input = write_record("unstable_in", 1500, 202u, 0);  // 2^1024 overflows
  const fs::path model = work_dir() / "unstable_arx.json";
  std::ofstream(model) << R"json({"format": "nlid-model", "version": 1, "kind": "arx", "ts": 0.01,
 "created": "2026-11-26T00:00:00Z", "generator": "test", "description": "y(t) = 2 y(t-1) + u(t-1)",
 "inputs": [{"name": "u", "unit": ""}], "outputs": [{"name": "y", "unit": ""}], "initial_condition": "zero",
 "structure": {"a": [-2, 0], "b": [[1, 0]], "nk": [1], "offset": 0},
 "parameters": {"names": ["a1", "a2", "b1", "b2"], "values": [-2, 0, 1, 0]},
 "report": {"method": "", "focus": "", "num_experiments": 0, "num_samples": 0, "num_parameters": 4, "loss": 0,
            "fit_percent": 0, "iterations": 0, "solver_message": ""}})json";
  const fs::path out = work_dir() / "unstable_out.csv";
  const Run r = sim("--model " + q(model) + " --input " + q(input) + " --out " + q(out));
  INFO(r.err);
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("not finite") && Catch::Contains("from sample") &&
                        Catch::Contains("unstable or diverges") && Catch::Contains("unstable_in.csv"));
  CHECK_FALSE(fs::exists(out));
}

TEST_CASE("nlid-sim: a diverging nonlinear ARX gets the same message (file, time, row) as a linear model",
          "[tools][sim][bad_input]") {
  // Nlarx::simulate stops at the first non-finite sample with a DivergenceError; nlid-sim used to
  // pass its text on ("simulation of experiment diverges ..."), naming neither the file nor the time.
  const fs::path input = write_record("unstable_nlarx_in", 1500, 204u, 0);
  const fs::path model = work_dir() / "unstable_nlarx.json";
  std::ofstream(model) << R"json({"format": "nlid-model", "version": 1, "kind": "nlarx", "ts": 0.01,
 "created": "2026-11-26T00:00:00Z", "generator": "test", "description": "y(t) = 2 y(t-1) + u(t)",
 "inputs": [{"name": "u", "unit": ""}], "outputs": [{"name": "y", "unit": ""}], "initial_condition": "zero",
 "structure": {"regressors": {"blocks": [{"type": "output_lags", "na": 1},
                                         {"type": "input_lags", "nb": 1, "nk": 0, "channel": 0}],
                              "names": ["y(t-1)", "u(t)"]},
               "nonlinearity": {"type": "linear", "inputs": 2}},
 "parameters": {"names": ["L[0]", "L[1]", "d"], "values": [2, 1, 0]},
 "report": {"estimated": false, "focus": "simulation", "initial_condition": "zero", "iterations": 0,
            "initial_cost": 0, "final_cost": 0, "seconds": 0, "status": "", "data_names": [],
            "fit_percent": [], "initial_states": []}})json";
  const fs::path out = work_dir() / "unstable_nlarx_out.csv";
  const Run r = sim("--model " + q(model) + " --input " + q(input) + " --out " + q(out));
  INFO(r.err);
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("the simulated output is not finite from sample") && Catch::Contains("data row") &&
                        Catch::Contains("unstable or diverges") && Catch::Contains("unstable_nlarx_in.csv") &&
                        Catch::Contains("nothing written to"));
  CHECK_THAT(r.err, !Catch::Contains("simulation of experiment"));
  CHECK_FALSE(fs::exists(out));
}

TEST_CASE("tools: integer options are range-checked, never wrapped around", "[tools][bad_input]") {
  const fs::path est = write_record("int_est", 1500, 203u, 0);
  const fs::path model = work_dir() / "int.json";
  const std::string base = "--model linear:arx:na=1,nb=1,nk=1 --est " + q(est) + " --save " + q(model);
  Run r = fit(base + " --decimate 4294967297");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--decimate needs an integer from 1 to") && Catch::Contains("out of range"));
  r = fit(base + " --iterations 4294967296");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--iterations needs an integer from 0 to"));
  r = fit(base + " --rows 1000:4294968296");  // wrapped to 1000:2000 before
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("--rows 1000:4294968296 is outside the 1500 data rows"));
  r = fit(base + " --rows 99999999999999999999:2");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--rows FIRST") && Catch::Contains("out of range"));
  CHECK_FALSE(fs::exists(model));
  r = sim("--model " + q(model) + " --input " + q(est) + " --out y.csv --decimate 4294967297");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--decimate"));
  r = codegen("--model " + q(model) + " --out " + q(work_dir()) + " --substeps 4294967297");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--substeps"));
  r = diagnose("--baseline first_order --est a.csv --val b.csv --starts 4294967297");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--starts needs an integer from 1 to"));
  r = diagnose("--baseline first_order --est a.csv --val b.csv --threads 99999999999999999999");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--threads") && Catch::Contains("out of range"));
}

TEST_CASE("tools: --ts does not hide a dropped sample, another uniform rate is noted", "[tools][fit][sim][bad_input]") {
  const fs::path full = write_record("ts_full", 800, 204u, 0);
  const fs::path gap = without_row(full, "ts_gap", 400);
  const fs::path model = work_dir() / "ts.json";
  const std::string spec = "--model linear:arx:na=2,nb=2,nk=1";
  Run r = fit(spec + " --est " + q(gap) + " --ts 0.01 --save " + q(model));
  INFO(r.err);
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("ts_gap.csv") && Catch::Contains("non-uniform time column") &&
                        Catch::Contains("from row 401") && Catch::Contains("row 402") &&
                        Catch::Contains("missing samples?") && Catch::Contains("--ts cannot make it even") &&
                        !Catch::Contains("CsvReadOptions"));
  CHECK_FALSE(fs::exists(model));
  // Without --ts the library's message points at the row, and its hint is the tools' one.
  r = fit(spec + " --est " + q(gap) + " --save " + q(model));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("non-uniform time column") && !Catch::Contains("CsvReadOptions"));
  // A uniform column at another rate: --ts wins and the disagreement is printed, naming the file.
  r = fit(spec + " --est " + q(full) + " --ts 0.02 --save " + q(model));
  CHECK(r.code == 0);
  CHECK_THAT(r.err, Catch::Contains("note:") && Catch::Contains("ts_full.csv") &&
                        Catch::Contains("--ts 0.02 s overrides the sample time 0.01 s"));
  r = fit(spec + " --est " + q(full) + " --ts 0.01 --save " + q(model));
  CHECK(r.code == 0);
  CHECK_THAT(r.err, !Catch::Contains("note:"));
  r = sim("--model " + q(model) + " --input " + q(gap) + " --ts 0.01 --out " + q(work_dir() / "ts_y.csv"));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("non-uniform time column"));
  CHECK_FALSE(fs::exists(work_dir() / "ts_y.csv"));
}

TEST_CASE("tools: --time-tolerance reads a logger's jittering stamps, and still finds a dropped sample",
          "[tools][fit][sim][bad_input]") {
  // The stamps of write_record's data moved by +-3 % of the step (a logger's jitter).
  const fs::path clean = write_record("jitter_src", 800, 205u, 0);
  const fs::path jitter = work_dir() / "jitter.csv";
  {
    std::ifstream in(clean);
    std::ofstream out(jitter);
    std::string header, row;
    std::getline(in, header);
    out << header << "\n";
    // Data row k: its time stamp replaced, the rest of the row kept.
    for (int k = 0; std::getline(in, row); ++k) out << 0.01 * k + 0.0003 * ((k % 3) - 1) << row.substr(row.find(',')) << "\n";
  }
  const fs::path model = work_dir() / "jitter.json";
  const std::string spec = "--model linear:arx:na=2,nb=2,nk=1 --save " + q(model);
  Run r = fit(spec + " --est " + q(jitter));
  INFO(r.err);
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("non-uniform time column") && Catch::Contains("--time-tolerance"));
  r = fit(spec + " --est " + q(jitter) + " --time-tolerance 0.1");
  CHECK(r.code == 0);
  r = sim("--model " + q(model) + " --input " + q(jitter) + " --time-tolerance 0.1 --out " +
          q(work_dir() / "jitter_y.csv"));
  CHECK(r.code == 0);
  // The option is for jitter, not for gaps: its ceiling still finds a dropped sample.
  const fs::path gap = without_row(clean, "jitter_gap", 300);
  r = fit(spec + " --est " + q(gap) + " --time-tolerance 0.5");
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("non-uniform time column") && Catch::Contains("from row 301"));
  // Two records of one logger with +-0.2 ms jitter on 10 ms: their sample times by the end points
  // differed by 3e-6, so they could not be estimated on together, and the model refused the
  // clean 100 Hz record. Both now read 0.01 s.
  std::vector<fs::path> jittered;
  for (const unsigned seed : {5u, 6u}) {
    std::ifstream in(clean);
    const fs::path p = work_dir() / ("jitter_" + std::to_string(seed) + ".csv");
    std::ofstream out(p);
    std::string header, row;
    std::getline(in, header);
    out << header << "\n";
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> e(-2e-4, 2e-4);
    char stamp[32];
    for (int k = 0; std::getline(in, row); ++k) {
      std::snprintf(stamp, sizeof stamp, "%.6f", 0.01 * k + e(rng));
      out << stamp << row.substr(row.find(',')) << "\n";
    }
    jittered.push_back(p);
  }
  r = fit(spec + " --est " + q(jittered[0]) + " --est " + q(jittered[1]) + " --time-tolerance 0.05");
  INFO(r.err);
  CHECK(r.code == 0);
  r = sim("--model " + q(model) + " --input " + q(clean) + " --out " + q(work_dir() / "jitter_clean_y.csv"));
  INFO(r.err);
  CHECK(r.code == 0);
  // nlid-fit fits one input: a list is one (missing) column name, and the message says so.
  r = fit(spec + " --est " + q(clean) + " --input u,y2");
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("input column 'u,y2' not found") && Catch::Contains("--input and --output each name one column"));
  // A nonlinear ARX file without a sample time ("ts": 0, "not set") runs at the file's rate, with
  // a note that no sample-time check was possible (it ran silently on data at any rate).
  const fs::path narx = work_dir() / "no_ts.json";
  r = fit("--model nlarx:na=1,nb=1,nk=1:linear --est " + q(clean) + " --save " + q(narx));
  REQUIRE(r.code == 0);
  std::string text = slurp(narx);
  const auto at = text.find("\"ts\": 0.01");
  REQUIRE(at != std::string::npos);
  text.replace(at, 10, "\"ts\": 0");
  std::ofstream(narx) << text;
  r = sim("--model " + q(narx) + " --input " + q(clean) + " --out " + q(work_dir() / "no_ts_y.csv"));
  INFO(r.err);
  CHECK(r.code == 0);
  CHECK_THAT(r.err, Catch::Contains("has no sample time (ts 0): it runs at the file's 0.01 s without a sample-time check"));
  // A free run from rest reads no past: a record shorter than the lags simulates (it was refused,
  // "2 samples, not more than the 3 needed by the model's lags"); a measured start still needs them.
  const fs::path lag3 = work_dir() / "lag3.json", two = work_dir() / "two_rows.csv";
  REQUIRE(fit("--model nlarx:na=3,nb=3,nk=0:linear --est " + q(clean) + " --save " + q(lag3)).code == 0);
  std::ofstream(two) << "t,u,y\n0,0.5,0\n0.01,0.5,0\n";
  r = sim("--model " + q(lag3) + " --input " + q(two) + " --x0 zero --out " + q(work_dir() / "two_y.csv"));
  INFO(r.err);
  CHECK(r.code == 0);
  CHECK(slurp(work_dir() / "two_y.csv").rfind("t,y\n0,", 0) == 0);
  r = sim("--model " + q(lag3) + " --input " + q(two) + " --x0 measured --out " + q(work_dir() / "two_y.csv"));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("needed by the model's lags"));
  for (const char* bad : {"0.6", "-0.1", "x", "nan"}) {
    r = fit(spec + " --est " + q(jitter) + " --time-tolerance " + bad);
    CHECK(r.code == 2);
    CHECK_THAT(r.err, Catch::Contains("--time-tolerance needs a relative step deviation from 0 to 0.5") &&
                          Catch::Contains(std::string("got '") + bad + "'"));
  }
}

TEST_CASE("nlid-fit and nlid-diagnose refuse an input that is constant in every estimation record",
          "[tools][fit][diagnose][bad_input]") {
  const fs::path c1 = constant_input_record("const_a", 1.0), c2 = constant_input_record("const_b", 1.0);
  const fs::path model = work_dir() / "const.json";
  for (const char* spec : {"nlarx:na=2,nb=2,nk=0:sigmoidnet", "wh:nb=2,nf=2,nk=0:poly1d:3:nb=2,nf=2,nk=0",
                           "greybox:throttle", "nlarx:na=2,nb=2,nk=0:treepartition"}) {
    INFO(spec);
    const Run r = fit(std::string("--model '") + spec + "' --est " + q(c1) + " --est " + q(c2) + " --save " + q(model));
    CHECK(r.code == 1);
    CHECK_THAT(r.err, Catch::Contains("input 'u' is constant (1) in every estimation record") &&
                          Catch::Contains("const_a.csv") && Catch::Contains("const_b.csv") &&
                          Catch::Contains("cannot be identified"));
    CHECK_FALSE(fs::exists(model));
  }
  // One varying record is enough.
  const fs::path varying = write_record("const_var", 600, 205u, 0);
  const Run ok = fit("--model linear:arx:na=1,nb=1,nk=1 --est " + q(c1) + " --est " + q(varying) + " --save " + q(model));
  INFO(ok.err);
  CHECK(ok.code == 0);
  const fs::path z = constant_input_record("const_zero", 0.0);
  const Run d = diagnose("--baseline throttle --est " + q(z) + " --val " + q(varying) + " --quiet");
  CHECK(d.code == 1);
  CHECK_THAT(d.err, Catch::Contains("input 'u' is constant (0)") && Catch::Contains("const_zero.csv") &&
                        Catch::Contains("cannot be identified"));
  CHECK_THAT(d.out, !Catch::Contains("nothing is missing"));
}

TEST_CASE("tools: an output that is an input is refused before any work, and the input survives",
          "[tools][bad_input]") {
  const fs::path v = write_record("same_v", 600, 206u, 0);
  const std::string before = slurp(v);
  Run r = fit("--model linear:arx:na=1,nb=1,nk=1 --est " + q(v) + " --save " + q(v));
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--save") && Catch::Contains("is the same file as --est"));
  // Another spelling of the same path.
  r = fit("--model linear:arx:na=1,nb=1,nk=1 --est " + q(v) + " --save " + q(v.parent_path() / "." / v.filename()));
  CHECK(r.code == 2);
  CHECK(slurp(v) == before);
  const fs::path model = work_dir() / "same_m.json";
  REQUIRE(fit("--model linear:arx:na=1,nb=1,nk=1 --est " + q(v) + " --save " + q(model)).code == 0);
  const std::string model_text = slurp(model);
  r = sim("--model " + q(model) + " --input " + q(v) + " --out " + q(v));
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("is the same file as --input"));
  r = sim("--model " + q(model) + " --input " + q(v) + " --out " + q(model));
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("is the same file as --model"));
  CHECK(slurp(v) == before);
  CHECK(slurp(model) == model_text);
  r = codegen("--model " + q(model) + " --out " + q(model));
  CHECK(r.code == 2);
  CHECK(slurp(model) == model_text);
  r = diagnose("--baseline first_order --est " + q(v) + " --val " + q(work_dir() / "other_val.csv") + " --json " + q(v));
  CHECK(r.code == 2);
  r = diagnose("--baseline first_order --est " + q(v) + " --val " + q(work_dir() / "other_val.csv") + " --json " + q(work_dir() / "r.json") +
               " --html " + q(work_dir() / "r.json"));
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--html") && Catch::Contains("--json"));
  CHECK(slurp(v) == before);
}

TEST_CASE("nlid-codegen: a non-finite equilibrium is refused, naming --u0", "[tools][codegen][bad_input]") {
  const fs::path est = write_record("eq_est", 800, 207u, 1);
  const fs::path dir = work_dir() / "eq_cg";
  fs::create_directories(dir);
  const fs::path model = dir / "oe.json";
  REQUIRE(fit("--model linear:oe:nb=2,nf=2,nk=1 --est " + q(est) + " --save " + q(model)).code == 0);
  Run r = codegen("--model " + q(model) + " --out " + q(dir) + " --x0 equilibrium --u0 -1e308");
  INFO(r.err);
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("--u0") && Catch::Contains("not finite"));
  CHECK_FALSE(fs::exists(dir / "oe.c"));
  r = codegen("--model " + q(model) + " --out " + q(dir) + " --x0 equilibrium --u0 inf");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--u0 needs a finite number"));
  r = codegen("--model " + q(model) + " --out " + q(dir) + " --x0 equilibrium --u0 0");
  INFO(r.err);
  CHECK(r.code == 0);
  // This barely converged output-error fit has a pole near 1 and a static gain near 10^5: its
  // steady state for u = 0.5 is y = 4e4 on data whose outputs stay within -0.8 ... 1.8. Before,
  // that was written into NAME_x0 without a word; now it is refused as far outside the data.
  r = codegen("--model " + q(model) + " --out " + q(dir) + " --x0 equilibrium --u0 0.5");
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("the equilibrium for --u0 0.5 has the output y = ") &&
                        Catch::Contains("far outside the output range of the estimation data"));
}

TEST_CASE("nlid-codegen: a model without a steady state is refused with --u0 named", "[tools][codegen][bad_input]") {
  // An ARX integrator y(t) = y(t-1) + 0.5 u(t-1) has no equilibrium for u0 != 0. Before, the
  // refusal came from the library in its words ("[at parameter 'initial']", "use
  // InitialCondition::zero"); now it names --u0, the file and the tool's remedy.
  const fs::path dir = work_dir() / "integ_cg";
  fs::create_directories(dir);
  const fs::path model = dir / "integ.json";
  std::ofstream(model) << R"json({"format": "nlid-model", "version": 1, "kind": "arx", "ts": 0.01,
 "initial_condition": "zero", "created": "2026-11-26T00:00:00Z", "generator": "test", "description": "",
 "inputs": [{"name": "u", "unit": ""}], "outputs": [{"name": "y", "unit": ""}],
 "structure": {"a": [-1.0], "b": [[0.5]], "nk": [1], "offset": 0.0},
 "parameters": {"names": ["a1", "b1"], "values": [-1.0, 0.5]},
 "report": {"method": "", "focus": "", "num_experiments": 0, "num_samples": 0, "num_parameters": 2, "loss": 0,
            "fit_percent": 0, "iterations": 0, "solver_message": ""}})json";
  Run r = codegen("--model " + q(model) + " --out " + q(dir) + " --x0 equilibrium --u0 0.5");
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("no equilibrium start for --u0 0.5 (") && Catch::Contains("integ.json") &&
                        Catch::Contains("integrator") && Catch::Contains("use --x0 zero") &&
                        Catch::Contains("[at parameter '--u0']"));
  CHECK_FALSE(fs::exists(dir / "integ.c"));
  r = codegen("--model " + q(model) + " --out " + q(dir));
  CHECK(r.code == 0);
}

TEST_CASE("tools: unknown last flags, repeated flags, output locations, --baseline, --decimal hints",
          "[tools][bad_input]") {
  const fs::path est = write_record("msg_est", 600, 208u, 0);
  const fs::path model = work_dir() / "msg.json";
  const std::string base = "--model linear:arx:na=1,nb=1,nk=1 --est " + q(est);
  // (a) an unknown flag at the end is unknown, not "needs a value"
  Run r = fit(base + " --save " + q(model) + " --verbose");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("unknown option '--verbose'"));
  CHECK(sim("--model m.json --input a.csv --out y.csv --verbose").err.find("unknown option '--verbose'") != std::string::npos);
  CHECK(codegen("--model m.json --out d --verbose").err.find("unknown option '--verbose'") != std::string::npos);
  r = diagnose("--baseline throttle --est a.csv --val b.csv --verbose");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("unknown option '--verbose'"));
  // (b) library hints in the tools' words
  const fs::path bare = write_record("msg_bare", 400, 209u, 0, false);
  r = fit(base + " --est " + q(bare) + " --save " + q(model));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("(--ts)") && !Catch::Contains("CsvReadOptions"));
  // (c) output locations are checked before the work
  r = fit(base + " --save " + q(work_dir() / "no_dir" / "m.json"));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("--save") && Catch::Contains("does not exist") && !Catch::Contains("estimating"));
  r = sim("--model m.json --input a.csv --out " + q(work_dir() / "no_dir" / "y.csv"));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("--out") && Catch::Contains("does not exist"));
  r = codegen("--model m.json --out " + q(est));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("is not a directory"));
  r = diagnose("--baseline first_order --est " + q(est) + " --val " + q(work_dir() / "other_val.csv") + " --html " +
               q(work_dir() / "no_dir" / "r.html"));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("--html") && Catch::Contains("does not exist") && !Catch::Contains("reading"));
  // (d) a flag that takes one value, given twice
  r = fit(base + " --model linear:oe:nb=1,nf=1,nk=1 --save " + q(model));
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("option --model is given twice"));
  r = fit(base + " --save a.json --save " + q(model));
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("option --save is given twice"));
  r = sim("--model m.json --input a.csv --out y.csv --out z.csv");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("option --out is given twice"));
  r = codegen("--model m.json --out d --out e");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("option --out is given twice"));
  r = diagnose("--baseline throttle --baseline first_order --est a.csv --val b.csv");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("option --baseline is given twice"));
  // (e) the unknown baseline is located at the flag
  r = diagnose("--baseline nosuch --est a.csv --val b.csv");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("unknown physics 'nosuch'") && Catch::Contains("parameter '--baseline'") &&
                        !Catch::Contains("parameter 'nosuch'"));
  // (f) decimal commas read with --delimiter ';' alone: the hint names --decimal
  const fs::path eu = work_dir() / "msg_eu.csv";
  {
    std::ofstream f(eu);
    f << "t;u;y\n0,000;0,0000;1,5\n0,010;1,0000;1,6\n0,020;0,0000;1,7\n";
  }
  r = fit("--model linear:arx:na=1,nb=1,nk=1 --est " + q(eu) + " --delimiter ';' --save " + q(model));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("non-numeric cell '0,000'") && Catch::Contains("--decimal ,"));
  r = diagnose("--baseline first_order --est " + q(eu) + " --val " + q(work_dir() / "other_val.csv") + " --delimiter ';'");
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("--decimal ,"));
  CHECK_FALSE(fs::exists(model));
}

TEST_CASE("tools: a forgotten value, an unwritable location, a gap in the data, a SPEC that cannot be built",
          "[tools][bad_input]") {
  const fs::path est = write_record("more_est", 600, 211u, 0);
  const fs::path model = work_dir() / "more.json";
  const std::string base = "--model linear:arx:na=1,nb=1,nk=1 --est " + q(est);
  // (a) an option's value forgotten before the next option: not a file named "--val"
  fs::remove("--val");
  Run r = tool_test::run_tool(NLID_FIT_EXE, base + " --save --val " + q(est));
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("option --save needs a value"));
  CHECK_FALSE(fs::exists("--val"));
  r = fit("--est --val " + q(est) + " --model linear:arx:na=1,nb=1,nk=1 --save " + q(model));
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("option --est needs a value"));
  // (b) a directory that exists but takes no files: refused before the estimation
  r = fit(base + " --save /proc/nlid_probe_test.json");
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("--save") && Catch::Contains("cannot create files in directory '/proc'") &&
                        !Catch::Contains("estimating"));
  r = diagnose("--baseline first_order --est " + q(est) + " --val " + q(work_dir() / "other_val.csv") + " --json " + q(work_dir() / "d.json") +
               " --save /proc/r.json");
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("cannot create files in directory '/proc'"));
  CHECK_FALSE(fs::exists(work_dir() / "d.json"));
  // (c) a gap in a record: the remedy in the tools' words, not a C++ enum the tools do not have
  const fs::path gap = work_dir() / "gap.csv";
  {
    std::ofstream f(gap);
    f << "t,u,y\n";
    for (int k = 0; k < 300; ++k) f << k * 0.01 << "," << (k / 40 % 2) << "," << (k == 120 ? std::string() : "0.5") << "\n";
  }
  r = fit("--model linear:arx:na=1,nb=1,nk=1 --est " + q(gap) + " --save " + q(model));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("empty cell") && Catch::Contains("the tools need complete records") &&
                        !Catch::Contains("NonFinitePolicy"));
  // (d) a SPEC that parses as text but names nothing buildable is a command-line error (2),
  // found before any data are read
  r = fit("--model greybox:foo --est " + q(work_dir() / "missing.csv") + " --save " + q(model));
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("unknown physics 'foo'") && !Catch::Contains("missing.csv"));
  r = fit("--model nlarx:na=1,nb=1,nk=1:sigmoidnet:0 --est " + q(work_dir() / "missing.csv") + " --save " + q(model));
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("units of sigmoidnet must be >= 1"));
  r = fit("--model nlarx:na=1,nb=1,nk=1:sigmoidnet:5:7 --est " + q(est) + " --save " + q(model));
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("the units of sigmoidnet is given twice"));
  CHECK_FALSE(fs::exists(model));
}

TEST_CASE("nlid-fit: a validation record it cannot score gets a row saying why, and the summary completes",
          "[tools][fit][bad_input]") {
  const fs::path est = write_record("score_est", 600, 212u, 0);
  const fs::path flat = work_dir() / "score_flat.csv";
  {
    std::ofstream f(flat);
    f << "t,u,y\n";
    for (int k = 0; k < 200; ++k) f << k * 0.01 << "," << (k / 30 % 2) << ",0.5\n";
  }
  const fs::path model = work_dir() / "score.json";
  const Run r = fit("--model linear:arx:na=1,nb=1,nk=1 --est " + q(est) + " --val " + q(flat) + " --save " + q(model));
  INFO(r.out << r.err);
  CHECK(r.code == 0);
  CHECK_THAT(r.out, Catch::Contains("score_flat.csv") && Catch::Contains("fit % not defined") &&
                        Catch::Contains("saved " + model.string()));
  CHECK(fs::exists(model));
}

TEST_CASE("nlid-fit: a SPEC option the estimator would not use is a command-line error before any data are read",
          "[tools][fit][bad_input]") {
  const fs::path missing = work_dir() / "spec_missing.csv", model = work_dir() / "spec_unused.json";
  auto run = [&](const std::string& spec) { return fit("--model " + spec + " --est " + q(missing) + " --save " + q(model)); };
  // ic= that linear:oe estimation ignores would be saved and change the model's simulation.
  Run r = run("linear:oe:nb=2,nf=2,nk=0:ic=measured");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("ic=measured is not used in estimating linear:oe models (they take ic=zero or "
                                    "ic=estimate)") &&
                        !Catch::Contains("spec_missing.csv"));
  r = run("linear:arx:na=1,nb=1,nk=1:ic=zero");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("takes no ic"));
  // start_iterations without starts > 1 would be ignored.
  r = run("nlarx:na=1,nb=1,nk=1:sigmoidnet:3:start_iterations=20");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("give starts=N (N > 1) with it") && !Catch::Contains("spec_missing.csv"));
  // A one-input map for an nlarx regressor vector failed (status 1) only after all data were read.
  r = run("nlarx:na=2,nb=2,nk=0:poly1d:3");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("poly1d has one input") &&
                        Catch::Contains("nlarx takes sigmoidnet, wavenet, treepartition or linear") &&
                        !Catch::Contains("spec_missing.csv"));
  CHECK_FALSE(fs::exists(model));
}

TEST_CASE("tools: a --time column the file lacks is an error naming the file and its columns, also with --ts",
          "[tools][fit][sim][bad_input]") {
  // A misspelt --time with --ts dropped the time column, and with it the check for a dropped sample.
  const fs::path gap = without_row(write_record("time_typo_full", 600, 205u, 0), "time_typo_gap", 300);
  const fs::path model = work_dir() / "time_typo.json";
  Run r = fit("--model linear:arx:na=2,nb=2,nk=1 --est " + q(gap) + " --time tim --ts 0.01 --save " + q(model));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("no column named 'tim' (--time); available columns: 't', 'u', 'y'") &&
                        Catch::Contains("time_typo_gap.csv") && Catch::Contains("parameter '--time'"));
  CHECK_FALSE(fs::exists(model));
  r = sim("--model " + q(model) + " --input " + q(gap) + " --time tim --ts 0.01 --out " + q(work_dir() / "tt_y.csv"));
  CHECK(r.code == 1);
  // The default name may be absent: --ts alone reads a file without a time column.
  const fs::path no_t = write_record("time_typo_no_t", 600, 206u, 0, false);
  r = fit("--model linear:arx:na=2,nb=2,nk=1 --est " + q(no_t) + " --ts 0.01 --save " + q(model));
  INFO(r.err);
  CHECK(r.code == 0);
  // The right name with --ts: the time column is read, and its gap found.
  r = fit("--model linear:arx:na=2,nb=2,nk=1 --est " + q(gap) + " --time t --ts 0.01 --save " + q(model));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("non-uniform time column"));
}

TEST_CASE("nlid-sim: --decimate and a record too short for the model name the option and the file",
          "[tools][sim][bad_input]") {
  const fs::path est = write_record("short_est", 600, 207u, 0);
  const fs::path model = work_dir() / "short_model.json";
  REQUIRE(fit("--model nlarx:na=2,nb=2,nk=0:linear --est " + q(est) + " --save " + q(model)).code == 0);
  const fs::path three = work_dir() / "short_three.csv", one = work_dir() / "short_one.csv";
  std::ofstream(three) << "t,u,y\n0,1,0\n0.01,1,0\n0.02,1,0\n";
  std::ofstream(one) << "u,y\n1,0\n";
  const fs::path out = work_dir() / "short_y.csv";
  // Was "[at parameter 'factor']": neither the option nor the file.
  Run r = sim("--model " + q(model) + " --input " + q(three) + " --decimate 10 --out " + q(out));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("parameter '--decimate'") && Catch::Contains("short_three.csv"));
  CHECK(r.err.find("'factor'") == std::string::npos);
  // Was "experiment has 1 samples, not more than the 2 needed ..." without a location. (A measured
  // start reads the past; a free run from rest needs none and runs on one sample.)
  r = sim("--model " + q(model) + " --input " + q(one) + " --ts 0.01 --x0 measured --out " + q(out));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("short_one.csv"));
  CHECK_FALSE(fs::exists(out));
}

TEST_CASE("nlid-fit: an equilibrium start of a model that integrates says why, not 'evaluate() returned false'",
          "[tools][fit][bad_input]") {
  // A rigid body's position integrates the input: under a non-zero input there is no steady
  // state, at rest a whole family. Every start failed with the solver's "evaluate() returned false".
  const fs::path est = write_record("rb_eq", 600, 207u, 0);
  const fs::path model = work_dir() / "rb_eq.json";
  const Run r = fit("--model greybox:rigid_body:ic=equilibrium --est " + q(est) + " --save " + q(model));
  INFO(r.err);
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("grey-box estimation from an equilibrium start") &&
                        Catch::Contains("ic=estimate or ic=zero") && !Catch::Contains("evaluate() returned false"));
  CHECK_FALSE(fs::exists(model));
}
