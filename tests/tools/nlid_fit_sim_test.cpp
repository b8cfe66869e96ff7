// nlid-fit and nlid-sim end to end: a model is estimated from generated CSV recordings by
// nlid-fit, saved, and simulated by nlid-sim on another recording; the simulated output must
// reproduce the known system. Every user error the tools promise to report clearly is fed in
// and its message checked (exit codes: 0 ok, 1 bad file/data/model, 2 bad command line).
#include <catch2/catch.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "nlid/core/atomic_file.hpp"
#include "nlid/io/json.hpp"
#include "tool_runner.hpp"

namespace fs = std::filesystem;
using tool_test::q;
using tool_test::fit;
using tool_test::sim;
using tool_test::Run;
using tool_test::slurp;
using tool_test::work_dir;
using tool_test::write_record;

using tool_test::csv_column;

TEST_CASE("nlid-fit + nlid-sim: a nonlinear ARX model of a known first-order lag round-trips through the model file",
          "[tools][fit][sim]") {
  // y(t) = a y(t-1) + 2(1 - a) u(t-1) + 0.5(1 - a), a = exp(-0.05): exactly the structure
  // nlarx [1 1 1] with a linear map and offset; noise 0.01 on a range of about 4.
  const fs::path est = write_record("fit_est", 1500, 31u, 0), val = write_record("fit_val", 1500, 32u, 0);
  const fs::path model = work_dir() / "lag.json";
  const Run f = fit("--model nlarx:na=1,nb=1,nk=1:linear --est " + q(est) + " --val " + q(val) + " --save " + q(model));
  INFO(f.err);
  REQUIRE(f.code == 0);
  CHECK_THAT(f.out, Catch::Contains("fit"));
  // Each parameter with its standard deviation on the estimation data, before the last line.
  CHECK_THAT(f.out, Catch::Contains("Parameter uncertainty (1 sigma; correlated residuals") && Catch::Contains("+- ") &&
                        Catch::Contains("unknowns, rank 3;"));
  CHECK(f.out.find("Parameter uncertainty") < f.out.find("saved "));
  // The validation record's simulation band, with a verdict on its error: the structure is exact,
  // so what is left is the white measurement noise, which no parameter change reaches.
  const std::string vname = val.filename().string();
  CHECK_THAT(f.out, Catch::Contains("validation records: Simulation band (1 sigma") &&
                        Catch::Contains("  " + vname + ": no change of the parameters removes more than"));
  CHECK(f.out.find("Parameter uncertainty") < f.out.find("Simulation band"));
  CHECK(f.out.find("Simulation band") < f.out.find("saved "));
  CHECK_THAT(f.out, Catch::Contains("(with the parameters' covariance: nlid-sim --band)"));
  REQUIRE(fs::exists(model));
  const nlid::Json j = nlid::Json::parse(slurp(model));
  CHECK(j["format"].as_string() == "nlid-model");

  const fs::path out = work_dir() / "lag_sim.csv";
  const Run s = sim("--model " + q(model) + " --input " + q(val) + " --out " + q(out));
  INFO(s.err);
  REQUIRE(s.code == 0);
  const std::vector<double> t = csv_column(out, 0), yhat = csv_column(out, 1);
  const std::vector<double> y = csv_column(val, 2);
  REQUIRE(yhat.size() == y.size());
  CHECK(t[1] - t[0] == Approx(0.01));
  // Free-run fit of the simulated output against the noisy measurement after the start-up
  // transient (nlid-sim starts at rest, the record at y = 0.5; 0.95^100 < 0.01): noise limits it.
  const std::size_t skip = 100;
  double num = 0, den = 0, mean = 0;
  for (std::size_t k = skip; k < y.size(); ++k) mean += y[k] / static_cast<double>(y.size() - skip);
  for (std::size_t k = skip; k < y.size(); ++k) {
    num += (y[k] - yhat[k]) * (y[k] - yhat[k]);
    den += (y[k] - mean) * (y[k] - mean);
  }
  const double fit_pct = 100.0 * (1.0 - std::sqrt(num / den));
  CHECK(fit_pct > 98.5);
}

TEST_CASE("nlid-sim notes where the input leaves the range the model was fitted on", "[tools][sim]") {
  // The model file records its estimation data's range; a record whose input goes beyond it is
  // simulated (nlid-sim reproduces the model, extrapolation included) with a note on stderr.
  const fs::path est = tool_test::write_record("range_est", 800, 91u, 1);
  const fs::path model = tool_test::work_dir() / "range.json";
  const Run f = fit("--model nlarx:na=1,nb=1,nk=1:sigmoidnet:units=2 --est " + q(est) + " --iterations 3 --save " + q(model));
  REQUIRE(f.code == 0);
  CHECK(f.out.find("Simulation band") == std::string::npos);  // no --val, no band
  Run s = sim("--model " + q(model) + " --input " + q(est) + " --out " + q(tool_test::work_dir() / "range_y.csv"));
  CHECK(s.code == 0);
  CHECK(s.err.find("note") == std::string::npos);
  // The same record with the input tripled from row 300 on.
  const fs::path wide = tool_test::work_dir() / "range_wide.csv";
  {
    std::ifstream in(est);
    std::ofstream out(wide);
    std::string line;
    std::getline(in, line);
    out << line << "\n";
    for (int row = 0; std::getline(in, line); ++row) {
      std::stringstream cells(line);
      std::string t, u, y;
      std::getline(cells, t, ',');
      std::getline(cells, u, ',');
      std::getline(cells, y, ',');
      out << t << "," << (row >= 300 ? 3.0 : 1.0) * std::stod(u) << "," << y << "\n";
    }
  }
  s = sim("--model " + q(model) + " --input " + q(wide) + " --out " + q(tool_test::work_dir() / "range_y.csv"));
  INFO(s.err);
  CHECK(s.code == 0);
  CHECK_THAT(s.err, Catch::Contains("note: the input leaves the range of the model's estimation data") &&
                        Catch::Contains("the model extrapolates there"));
  const std::size_t at = s.err.find("from sample ");
  REQUIRE(at != std::string::npos);
  CHECK(std::stol(s.err.substr(at + 12)) >= 300);  // not before the tripled part
}

TEST_CASE("nlid-fit: unknown specs say what is accepted, bad files and columns are located", "[tools][fit]") {
  const fs::path good = write_record("fit_good", 400, 33u, 0);
  const fs::path model = work_dir() / "m.json";
  Run r = fit("--model wx:nb=2 --est " + q(good) + " --save " + q(model));
  CHECK(r.code == 2);  // a SPEC that does not parse is a bad command line
  CHECK_THAT(r.err, Catch::Contains("unknown model family 'wx'") && Catch::Contains("accepted:") &&
                        Catch::Contains("nlarx"));
  r = fit("--model nlarx:na=2,nb=2,nk=0:sigmoid --est " + q(good) + " --save " + q(model));
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("unknown nonlinearity 'sigmoid'") && Catch::Contains("sigmoidnet"));
  r = fit("--model linear:oe:nb=1,nf=1,nk=0 --est " + q(work_dir() / "nowhere.csv") + " --save " + q(model));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("nowhere.csv"));
  r = fit("--model linear:oe:nb=1,nf=1,nk=0 --est " + q(good) + " --output angle --save " + q(model));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("angle"));
  const fs::path bad = work_dir() / "fit_bad.csv";
  {
    std::ofstream f(bad);
    f << "t,u,y\n0,0,1\n0.01,0,1\n0.02,x,1\n";
  }
  r = fit("--model linear:oe:nb=1,nf=1,nk=0 --est " + q(bad) + " --save " + q(model));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("fit_bad.csv") && Catch::Contains("row 4"));
  CHECK_FALSE(fs::exists(model));  // nothing written on failure
  // Validation data at another rate: both sample times with enough digits to tell them apart.
  const fs::path slow = work_dir() / "fit_slow.csv";
  {
    std::ofstream f(slow);
    f << "t,u,y\n";
    for (int k = 0; k < 50; ++k) f << 0.02 * k << ",0,1\n";
  }
  r = fit("--model linear:oe:nb=1,nf=1,nk=0 --est " + q(good) + " --val " + q(slow) + " --save " + q(model));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("validation data have sample time 0.02 s, estimation data 0.01 s") &&
                        Catch::Contains("--val") && Catch::Contains("file '" + slow.string() + "'") &&
                        Catch::Contains("resample one of them to the other's rate first"));
  CHECK_FALSE(fs::exists(model));
  // Nearly the same rate: one logger read from differently rounded stamps; --ts sets it.
  const fs::path drift = write_record("fit_drift", 300, 36u, 0, true, "y", 0.0100005);
  r = fit("--model linear:oe:nb=1,nf=1,nk=0 --est " + q(good) + " --val " + q(drift) + " --save " + q(model));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("validation data have sample time 0.0100005") &&
                        Catch::Contains("if both were logged at one rate, give that sample time with --ts"));
  // Two --est records at different rates: the second is named by its file, not only "experiment 1".
  r = fit("--model linear:oe:nb=1,nf=1,nk=0 --est " + q(good) + " --est " + q(slow) + " --save " + q(model));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("has sample time 0.02 but the data set has 0.01") &&
                        Catch::Contains("file '" + slow.string() + "'") && Catch::Contains("experiment 1"));
}

// Estimation and validation files cut from one recording whose time stamps are printed with fixed
// decimals (as the Wiener-Hammerstein benchmark's: 51.2 kHz, 8 decimals). The endpoint estimate of
// each file's sample time differs by ~1e-7 here; nlid-fit refused such a pair until read_csv
// recovered the grid the stamps were printed from (benchmarks/real/wh2009 --cv).
TEST_CASE("nlid-fit: slices of one recording with rounded time stamps share a sample time", "[tools][fit]") {
  const fs::path est = work_dir() / "rounded_est.csv", val = work_dir() / "rounded_val.csv";
  {
    std::ofstream fe(est), fv(val);
    fe << "t,u,y\n";
    fv << "t,u,y\n";
    double y = 0.0;
    for (int k = 0; k < 4000; ++k) {
      const double u = ((k / 37) % 3) - 1.0;  // steps -1, 0, 1
      char line[96];
      std::snprintf(line, sizeof line, "%.8f,%g,%.10g\n", k / 51200.0, u, y);
      (k < 3000 ? fe : fv) << line;
      y = 0.9 * y + 0.2 * u;
    }
  }
  const fs::path model = work_dir() / "rounded.json";
  const Run r = fit("--model linear:oe:nb=1,nf=1,nk=1 --est " + q(est) + " --val " + q(val) + " --save " + q(model));
  INFO(r.err);
  CHECK(r.code == 0);
  CHECK_THAT(r.err, Catch::Contains("ts = 1.95312e-05 s") || Catch::Contains("ts = 1.95313e-05 s"));
  CHECK(fs::exists(model));
}

TEST_CASE("nlid-fit: a model whose free run diverges on a record is reported in the table and still saved",
          "[tools][fit]") {
  // Data of the unstable y(t) = 1.05 y(t-1) + 0.1 u(t-1): 200 samples stay finite, so the
  // prediction-focus ARX-like model (a ≈ 1.05) simulates the estimation record, but its free run
  // overflows on a 16000-sample validation record (1.05^k passes 1e308 near k = 14500).
  const fs::path est = work_dir() / "growing_est.csv", val = work_dir() / "growing_val.csv";
  {
    std::ofstream fe(est), fv(val);
    fe << "t,u,y\n";
    double y = 1.0;
    for (int k = 0; k < 200; ++k) {
      const double u = (k / 9) % 2 ? 1.0 : -1.0;
      fe << k * 0.01 << ',' << u << ',' << y << '\n';
      y = 1.05 * y + 0.1 * u;
    }
    fv << "t,u,y\n";
    for (int k = 0; k < 16000; ++k) fv << k * 0.01 << ",1," << std::sin(0.01 * k) << '\n';
  }
  const fs::path model = work_dir() / "growing.json";
  const Run r = fit("--model nlarx:na=1,nb=1,nk=1:linear:focus=prediction --est " + q(est) + " --val " + q(val) +
                    " --save " + q(model));
  INFO(r.out << r.err);
  CHECK(r.code == 0);
  CHECK_THAT(r.out, Catch::Contains("growing_est.csv") && Catch::Contains("diverged") &&
                        Catch::Contains("free run not finite from sample") && Catch::Contains("saved"));
  CHECK(fs::exists(model));
  // The estimation record itself is scored normally.
  CHECK(r.out.find("estimation   growing_est.csv") != std::string::npos);
  CHECK(r.out.find("diverged") > r.out.find("validation"));
}

TEST_CASE("nlid-fit: usage errors exit with 2", "[tools][fit]") {
  Run r = fit("--help");
  CHECK(r.code == 0);
  CHECK_THAT(r.out + r.err, Catch::Contains("usage: nlid-fit"));
  r = fit("--est a.csv --save m.json");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--model SPEC is required"));
  r = fit("--model linear:oe:nb=1,nf=1,nk=0 --est a.csv --save m.json --iterations many");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--iterations") && Catch::Contains("'many'"));
  r = fit("--model linear:oe:nb=1,nf=1,nk=0 --est a.csv --save m.json --iterations -1");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--iterations needs an integer from 0 to 1000000, got '-1'"));
  r = fit("--model linear:oe:nb=1,nf=1,nk=0 --est a.csv --save m.json --rows 50:20");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--rows 50:20 needs 0 <= FIRST < LAST"));
  r = fit("--model linear:oe:nb=1,nf=1,nk=0 --est a.csv --save m.json --wobble 1");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("unknown option '--wobble'"));
  r = fit("--model linear:oe:nb=1,nf=1,nk=0 --est a.csv --save m.json --input y --output y");
  CHECK(r.code == 2);  // was 1, after trying to read a.csv
  CHECK_THAT(r.err, Catch::Contains("--input and --output both name column 'y'"));
}

TEST_CASE("nlid-sim: sample-time mismatch, missing column, bad model file", "[tools][sim]") {
  const fs::path est = write_record("sim_est", 600, 34u, 0);
  const fs::path model = work_dir() / "sim_lag.json";
  const Run f = fit("--model nlarx:na=1,nb=1,nk=1:linear --est " + q(est) + " --save " + q(model));
  INFO(f.err);
  REQUIRE(f.code == 0);
  const fs::path slow = write_record("sim_slow", 300, 35u, 0, true, "y", 0.02);
  const fs::path out = work_dir() / "sim_out.csv";
  Run r = sim("--model " + q(model) + " --input " + q(slow) + " --out " + q(out));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("sample-time mismatch") && Catch::Contains("sim_slow.csv") &&
                        Catch::Contains("sample time 0.02 s but the model 0.01 s (relative difference 1)") &&
                        Catch::Contains("resample the data or re-estimate the model"));
  CHECK_FALSE(fs::exists(out));
  // Stamps 5e-5 off the model's rate (a logger's clock, rounded stamps): --ts is the remedy, and
  // works. (read_csv reads these stamps as 99.995 Hz, 0.01000050003 s: the stamps cannot tell that
  // from 0.0100005 s, and the rate is the shorter decimal.)
  const fs::path drift = write_record("sim_drift", 300, 35u, 0, true, "y", 0.0100005);
  r = sim("--model " + q(model) + " --input " + q(drift) + " --out " + q(out));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("sim_drift.csv has sample time 0.0100005") &&
                        Catch::Contains("give it with --ts 0.01"));
  r = sim("--model " + q(model) + " --input " + q(drift) + " --ts 0.01 --out " + q(out));
  INFO(r.err);
  CHECK(r.code == 0);
  r = sim("--model " + q(model) + " --input " + q(est) + " --column throttle --out " + q(out));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("throttle"));
  const fs::path damaged = work_dir() / "damaged.json";
  {
    std::ofstream g(damaged);
    g << slurp(model).substr(0, 40);
  }
  r = sim("--model " + q(damaged) + " --input " + q(est) + " --out " + q(out));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("damaged.json"));
  r = sim("--model " + q(model) + " --input " + q(est) + " --x0 warm --out " + q(out));
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--x0 must be zero, equilibrium, measured or estimate"));
}

TEST_CASE("nlid-fit + nlid-sim read semicolon-separated decimal-comma files and files without a time column",
          "[tools][fit][sim]") {
  const fs::path est = write_record("rec_src", 600, 36u, 1);
  // The same record as a spreadsheet with decimal commas writes it: ';' between fields.
  const fs::path eu = work_dir() / "rec_eu.csv";
  {
    std::ifstream in(est);
    std::ofstream out(eu);
    std::string line;
    while (std::getline(in, line)) {
      for (char& c : line) c = c == ',' ? ';' : c == '.' ? ',' : c;
      out << line << "\n";
    }
  }
  const std::string spec = "--model nlarx:na=1,nb=1,nk=1:linear";
  const fs::path m_ref = work_dir() / "rec_ref.json", m_eu = work_dir() / "rec_eu.json";
  const Run ref = fit(spec + " --est " + q(est) + " --save " + q(m_ref));
  INFO(ref.err);
  REQUIRE(ref.code == 0);
  Run r = fit(spec + " --est " + q(eu) + " --save " + q(m_eu));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("is the file separated by ';'?"));
  r = fit(spec + " --est " + q(eu) + " --delimiter ';' --decimal , --save " + q(m_eu));
  INFO(r.err);
  REQUIRE(r.code == 0);
  // The same numbers were read: both models simulate both spellings of the input identically.
  const fs::path y_ref = work_dir() / "rec_y_ref.csv", y_eu = work_dir() / "rec_y_eu.csv";
  REQUIRE(sim("--model " + q(m_ref) + " --input " + q(est) + " --out " + q(y_ref)).code == 0);
  REQUIRE(sim("--model " + q(m_eu) + " --input " + q(eu) + " --delimiter ';' --decimal , --out " + q(y_eu)).code == 0);
  CHECK(slurp(y_ref) == slurp(y_eu));
  // No time column: the sample time comes from --ts.
  const fs::path bare = write_record("rec_bare", 600, 36u, 1, false);
  r = fit(spec + " --est " + q(bare) + " --save " + q(m_eu));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("needs the sample time") && Catch::Contains("--ts"));
  const fs::path m_bare = work_dir() / "rec_bare.json", y_bare = work_dir() / "rec_y_bare.csv";
  r = fit(spec + " --est " + q(bare) + " --ts 0.01 --save " + q(m_bare));
  INFO(r.err);
  REQUIRE(r.code == 0);
  REQUIRE(sim("--model " + q(m_bare) + " --input " + q(bare) + " --ts 0.01 --out " + q(y_bare)).code == 0);
  CHECK(slurp(y_ref) == slurp(y_bare));
  // Bad values are usage errors naming the option.
  r = fit(spec + " --est " + q(est) + " --decimal , --save " + q(m_eu));
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--decimal , needs another field separator"));
  r = sim("--model " + q(m_ref) + " --input " + q(est) + " --ts 0 --out " + q(y_eu));
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--ts needs a positive sample time"));
  // One parser for --ts in every tool: 1e-320 was a sample time here (nlid-fit estimated with
  // ts = 9.99e-321) and "not a finite number" to nlid-input.
  r = fit(spec + " --est " + q(bare) + " --ts 1e-320 --save " + q(m_bare));
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--ts needs a number within the range of a double") && Catch::Contains("'1e-320'"));
  r = tool_test::codegen("--model " + q(m_ref) + " --out " + q(work_dir()) + " --ts 1e-320");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--ts needs a number within the range of a double"));
}

TEST_CASE("nlid-fit greybox: --iterations bounds the refinement and the file keeps the estimation's report",
          "[tools][fit]") {
  // --iterations used to be ignored for grey boxes (each start ran up to 100 iterations), and
  // the saved report read "estimated": false with no costs or fits.
  const fs::path est = write_record("grey_it_est", 1200, 43u, 0);
  const fs::path one = work_dir() / "grey_it1.json", full = work_dir() / "grey_it100.json";
  REQUIRE(fit("--model greybox:first_order --est " + q(est) + " --iterations 1 --save " + q(one)).code == 0);
  REQUIRE(fit("--model greybox:first_order --est " + q(est) + " --save " + q(full)).code == 0);
  const nlid::Json a = nlid::read_json(one.string()), b = nlid::read_json(full.string());
  const nlid::JsonView ra = a.view().at("report"), rb = b.view().at("report");
  CHECK(ra.at("estimated").as_bool());
  CHECK(ra.at("iterations").as_integer() == 1);
  CHECK_THAT(ra.at("status").as_string(), Catch::Contains("max_iterations_reached"));
  CHECK(rb.at("estimated").as_bool());
  CHECK(rb.at("iterations").as_integer() > 1);
  CHECK_THAT(rb.at("status").as_string(), Catch::Contains("(converged)"));
  CHECK(rb.at("initial_condition").as_string() == "estimate");
  REQUIRE(rb.at("fit_percent").as_array().size() == 1);
  CHECK(rb.at("fit_percent").at(0).as_number() > 90.0);
}

TEST_CASE("nlid-sim --band: the covariance nlid-fit saves gives y_std, models without one are refused",
          "[tools][sim]") {
  const fs::path est = write_record("band_est", 1200, 41u, 0), val = write_record("band_val", 600, 42u, 0);
  const fs::path model = work_dir() / "band_lag.json";
  const Run f = fit("--model greybox:first_order --est " + q(est) + " --save " + q(model));
  INFO(f.err);
  REQUIRE(f.code == 0);
  CHECK_THAT(slurp(model), Catch::Contains("\"covariance\""));
  const fs::path plain = work_dir() / "band_plain.csv", banded = work_dir() / "band_y.csv";
  REQUIRE(sim("--model " + q(model) + " --input " + q(val) + " --out " + q(plain)).code == 0);
  const Run s = sim("--model " + q(model) + " --input " + q(val) + " --band --out " + q(banded));
  INFO(s.err);
  REQUIRE(s.code == 0);
  CHECK(slurp(banded).rfind("t,y,y_std\n", 0) == 0);
  // A grey box is continuous-time: no "has no sample time" note (it has no ts of its own).
  CHECK_THAT(s.err, !Catch::Contains("no sample time"));
  // The same simulation, now with its standard deviation: 0 at the held initial state, then
  // positive and small against the output's range of about 4 (noise 0.01 on 1200 samples).
  const std::vector<double> y0 = csv_column(plain, 1), y = csv_column(banded, 1), sd = csv_column(banded, 2);
  REQUIRE(y.size() == y0.size());
  for (std::size_t k = 0; k < y.size(); ++k) CHECK(y[k] == y0[k]);
  CHECK(sd[0] == 0.0);
  double top = 0.0;
  for (std::size_t k = 1; k < sd.size(); ++k) {
    CHECK(sd[k] > 0.0);
    top = std::max(top, sd[k]);
  }
  CHECK(top < 0.05);

  // Nonlinear ARX and Hammerstein-Wiener files from nlid-fit carry their covariance too: the
  // same columns, y unchanged by --band, y_std finite, positive once the run has left its zero
  // start, and small (the band of a well-determined 1200-sample fit).
  for (const std::string spec : {"nlarx:na=1,nb=1,nk=1:sigmoidnet:2", "hw:nb=1,nf=1,nk=1:in=pwlinear:3:out=unitgain"}) {
    INFO(spec);
    const fs::path m = work_dir() / "band_reg.json", yp = work_dir() / "band_reg_plain.csv",
                   yb = work_dir() / "band_reg_y.csv";
    const Run fr = fit("--model " + spec + " --est " + q(est) + " --save " + q(m));
    INFO(fr.err);
    REQUIRE(fr.code == 0);
    CHECK_THAT(slurp(m), Catch::Contains("\"covariance\"") && Catch::Contains("\"stddev\""));
    REQUIRE(sim("--model " + q(m) + " --input " + q(val) + " --out " + q(yp)).code == 0);
    const Run sr = sim("--model " + q(m) + " --input " + q(val) + " --band --out " + q(yb));
    INFO(sr.err);
    REQUIRE(sr.code == 0);
    const std::vector<double> a = csv_column(yp, 1), b = csv_column(yb, 1), d = csv_column(yb, 2);
    REQUIRE(b.size() == a.size());
    for (std::size_t k = 0; k < b.size(); ++k) CHECK(b[k] == a[k]);
    double most = 0.0;
    for (std::size_t k = 0; k < d.size(); ++k) {
      CHECK(std::isfinite(d[k]));
      CHECK(d[k] >= 0.0);
      most = std::max(most, d[k]);
    }
    CHECK(d.back() > 0.0);
    CHECK(most < 0.05);
    // The same file without its uncertainty (as an older nlid or a hand edit leaves it): refused,
    // saying what is missing, nothing written.
    nlid::Json edited = nlid::read_json(m.string());
    REQUIRE(edited.erase("uncertainty"));
    const fs::path bare = work_dir() / "band_reg_bare.json", none = work_dir() / "band_reg_none.csv";
    nlid::write_file_atomically(bare.string(), edited.dump(2));
    const Run lacks = sim("--model " + q(bare) + " --input " + q(val) + " --band --out " + q(none));
    CHECK(lacks.code == 1);
    CHECK_THAT(lacks.err, Catch::Contains("--band needs the parameters' covariance") && Catch::Contains("lacks"));
    CHECK_FALSE(fs::exists(none));
    // A parameter changed by hand after the estimation: the covariance describes another
    // estimate; --band is refused naming the parameter, the plain simulation still runs.
    nlid::Json tuned = nlid::read_json(m.string());
    nlid::Json& v0 = tuned["parameters"]["values"][0];
    v0 = v0.as_number() * 1.1 + 0.01;
    const fs::path changed = work_dir() / "band_reg_tuned.json";
    nlid::write_file_atomically(changed.string(), tuned.dump(2));
    const Run stale = sim("--model " + q(changed) + " --input " + q(val) + " --band --out " + q(none));
    CHECK(stale.code == 1);
    CHECK_THAT(stale.err, Catch::Contains("carries one, but its covariance was computed at") &&
                              Catch::Contains("changed after the estimation") && Catch::Contains("nlid-fit"));
    CHECK_FALSE(fs::exists(none));
    CHECK(sim("--model " + q(changed) + " --input " + q(val) + " --out " + q(work_dir() / "band_reg_tuned_y.csv")).code == 0);
  }
  {
    // The same for the grey box, whose covariance sits in "parameters".
    nlid::Json tuned = nlid::read_json(model.string());
    nlid::Json& v0 = tuned["parameters"]["values"][0];
    v0 = v0.as_number() * 1.1;
    const fs::path changed = work_dir() / "band_lag_tuned.json", none = work_dir() / "band_lag_none.csv";
    nlid::write_file_atomically(changed.string(), tuned.dump(2));
    const Run stale = sim("--model " + q(changed) + " --input " + q(val) + " --band --out " + q(none));
    CHECK(stale.code == 1);
    CHECK_THAT(stale.err, Catch::Contains("carries one, but its covariance was computed at") &&
                              Catch::Contains("changed after the estimation"));
    CHECK_FALSE(fs::exists(none));
  }

  // A linear ARX model file keeps no covariance: refused, saying so, nothing written.
  const fs::path arx = work_dir() / "band_arx.json", none = work_dir() / "band_none.csv";
  const Run fa = fit("--model linear:arx:na=1,nb=1,nk=1 --est " + q(est) + " --save " + q(arx));
  REQUIRE(fa.code == 0);
  CHECK_THAT(fa.out, Catch::Contains("saved ") && !Catch::Contains("parameters' covariance"));
  const Run r = sim("--model " + q(arx) + " --input " + q(val) + " --band --out " + q(none));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("--band needs the parameters' covariance") && Catch::Contains("does not keep"));
  CHECK_FALSE(fs::exists(none));
}

TEST_CASE("nlid-fit and nlid-diagnose: an estimation file whose name is not valid UTF-8 is fitted and saved",
          "[tools][fit][diagnose]") {
  // A Latin-1 name: the estimation ran, then saving failed on the name ("not valid UTF-8") and
  // the model was lost. The record's name now has U+FFFD for the invalid byte.
  const fs::path src = write_record("latin_src", 800, 41u, 0);
  const fs::path est = work_dir() / "mess\xE4ung.csv";
  fs::copy_file(src, est, fs::copy_options::overwrite_existing);
  const fs::path model = work_dir() / "latin.json";
  Run r = fit("--model nlarx:na=1,nb=1,nk=1:linear --est " + q(est) + " --save " + q(model));
  INFO(r.err);
  REQUIRE(r.code == 0);
  REQUIRE(fs::exists(model));
  const nlid::Json j = nlid::Json::parse(slurp(model));
  CHECK(j["report"]["data_names"][0].as_string() == "mess\xEF\xBF\xBDung.csv");
  // nlid-diagnose names its records by the file's stem, in the JSON report and the saved model.
  const fs::path json = work_dir() / "latin_diag.json", saved = work_dir() / "latin_diag_model.json";
  const fs::path val = write_record("latin_val", 800, 42u, 0);  // not the same data as est
  r = tool_test::diagnose("--baseline first_order --est " + q(est) + " --val " + q(val) +
                          " --starts 1 --threads 1 --quiet --json " + q(json) + " --save " + q(saved));
  INFO(r.err);
  CHECK(r.code == 0);
  CHECK(slurp(json).find("mess\xEF\xBF\xBDung") != std::string::npos);
  CHECK(fs::exists(saved));
  // A column name that is not valid UTF-8 would fail the same way: refused before any work.
  r = fit("--model nlarx:na=1,nb=1,nk=1:linear --est " + q(est) + " --input \"$(printf 'u\\344')\" --save " +
          q(work_dir() / "latin_col.json"));
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("is not valid UTF-8 (byte 1)"));
}

TEST_CASE("nlid-fit warns on stderr when the estimation did not converge, and still saves the model", "[tools][fit]") {
  const fs::path est = write_record("nonconv_est", 800, 43u, 0);
  const fs::path model = work_dir() / "nonconv.json";
  // Two iterations of a sigmoid network cannot reach a tolerance.
  Run r = fit("--model nlarx:na=2,nb=2,nk=1:sigmoidnet:3 --iterations 2 --est " + q(est) + " --save " + q(model));
  INFO(r.err);
  REQUIRE(r.code == 0);
  CHECK(fs::exists(model));
  CHECK_THAT(r.err, Catch::Contains("nlid-fit: warning: the estimation did not converge (Levenberg-Marquardt: "
                                    "max_iterations_reached (not converged) after 2 iterations") &&
                        Catch::Contains("more --iterations may improve it"));
  // One line, and the file's report says the same.
  const auto at = r.err.find("nlid-fit: warning:");
  REQUIRE(at != std::string::npos);
  CHECK_THAT(r.err.substr(at, r.err.find('\n', at) - at), Catch::EndsWith("more --iterations may improve it"));
  CHECK_THAT(slurp(model), Catch::Contains("(not converged)"));
  // A converged estimation (a linear map: one Gauss-Newton step) has no warning.
  r = fit("--model nlarx:na=1,nb=1,nk=1:linear --est " + q(est) + " --save " + q(model));
  REQUIRE(r.code == 0);
  CHECK(r.err.find("warning") == std::string::npos);
}

TEST_CASE("nlid-fit: a spec with nothing to estimate is fitted and saved, an optimal start is no warning",
          "[tools][fit]") {
  const fs::path est = write_record("zero_param_est", 600, 47u, 0);
  const fs::path model = work_dir() / "zero_param.json";
  // docs/tools.md: a one-input map such as unitgain fits only na=0,nb=1. It failed with
  // "AutoDiffProblem: functor reports 0 parameters", then on saving an empty covariance.
  Run r = fit("--model nlarx:na=0,nb=1,nk=0:unitgain --est " + q(est) + " --save " + q(model));
  INFO(r.err);
  REQUIRE(r.code == 0);
  CHECK_THAT(r.out, Catch::Contains("0 parameters"));
  CHECK(r.err.find("warning") == std::string::npos);
  CHECK_THAT(r.err, Catch::Contains("no parameter uncertainty: the model has no parameters"));
  const fs::path out = work_dir() / "zero_param_y.csv";
  REQUIRE(sim("--model " + q(model) + " --input " + q(est) + " --out " + q(out)).code == 0);
  const std::vector<double> u = csv_column(est, 1), y = csv_column(out, 1);
  REQUIRE(y.size() == u.size());
  for (std::size_t k = 0; k < y.size(); ++k) CHECK(y[k] == u[k]);  // y(t) = u(t)
  // A linear map with prediction focus starts at its least-squares solution: the solver keeps
  // that start, which is converged, not "did not converge (stalled)".
  r = fit("--model nlarx:na=2,nb=2,nk=0:linear:focus=prediction --est " + q(est) + " --save " + q(model));
  INFO(r.err);
  REQUIRE(r.code == 0);
  CHECK(r.err.find("warning") == std::string::npos);
}

TEST_CASE("nlid-sim --x0 measured on a model whose state is internal is refused in the tool's words", "[tools][sim]") {
  const fs::path est = write_record("x0_measured_est", 600, 53u, 0);
  const fs::path model = work_dir() / "x0_measured_hw.json", out = work_dir() / "x0_measured_y.csv";
  REQUIRE(fit("--model hw:nb=1,nf=1,nk=1:in=pwlinear:3:out=unitgain --est " + q(est) + " --save " + q(model)).code == 0);
  const Run r = sim("--model " + q(model) + " --input " + q(est) + " --x0 measured --out " + q(out));
  INFO(r.err);
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("--x0 measured takes the start from the record's past outputs") &&
                        Catch::Contains("hammerstein_wiener model: use --x0 zero, equilibrium or estimate"));
  CHECK(r.err.find("InitialCondition::") == std::string::npos);  // it said "InitialCondition::measured applies ..."
  CHECK_FALSE(fs::exists(out));
}

TEST_CASE("nlid-fit warns when the estimated linear dynamics are unstable, and is silent when stable", "[tools][fit]") {
  // y(t) = 1.02 y(t-1) + u(t-1): ARX [1 1 1] recovers the pole at 1.02 exactly. The model was
  // saved (and could be turned into C) without a word that its free run diverges.
  const fs::path rec = work_dir() / "unstable.csv", model = work_dir() / "unstable.json";
  {
    std::ofstream f(rec);
    f << "t,u,y\n";
    double y = 0.0, u_prev = 0.0;
    for (int k = 0; k < 300; ++k) {
      y = 1.02 * y + u_prev;
      const double u = std::sin(0.3 * k) + 0.5 * std::sin(1.7 * k);
      f << 0.01 * k << "," << u << "," << y << "\n";
      u_prev = u;
    }
  }
  Run r = fit("--model linear:arx:na=1,nb=1,nk=1 --est " + q(rec) + " --save " + q(model));
  INFO(r.err);
  REQUIRE(r.code == 0);
  CHECK(fs::exists(model));
  CHECK_THAT(r.err, Catch::Contains("nlid-fit: warning: the model is unstable (a pole of its linear dynamics has magnitude 1.02"));
  const fs::path stable = write_record("stable_est", 600, 59u, 0);
  r = fit("--model linear:arx:na=1,nb=1,nk=1 --est " + q(stable) + " --save " + q(model));
  REQUIRE(r.code == 0);
  CHECK(r.err.find("unstable") == std::string::npos);
}
