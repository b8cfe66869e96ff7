// nlid-diagnose end to end: the binary is run on small generated CSV files; exit codes, stdout,
// stderr and the written JSON/HTML are checked, including every user error the tool promises to
// report clearly (the nlid::Error text; exit code 2 for a bad command line, 1 for a bad file or data).
#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <string>

#include "nlid/io/json.hpp"
#include "tool_runner.hpp"

namespace fs = std::filesystem;
using tool_test::q;
using tool_test::diagnose;
using tool_test::Run;
using tool_test::slurp;
using tool_test::work_dir;
using tool_test::write_record;

TEST_CASE("nlid-diagnose: help and usage errors", "[tools][diagnose]") {
  Run r = diagnose("--help");
  CHECK(r.code == 0);
  CHECK_THAT(r.out, Catch::Contains("--baseline NAME") && Catch::Contains("--time-tolerance R"));
  r = diagnose("");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("no arguments") && Catch::Contains("usage:"));
  r = diagnose("--baseline throttle --est a.csv --val b.csv --frobnicate 3");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("unknown option '--frobnicate'"));
  // The one-line format of all six tools (docs/tools.md): "TOOL: message", no extra "error:".
  CHECK(r.err.rfind("nlid-diagnose: unknown option '--frobnicate'", 0) == 0);
  r = diagnose("--baseline throttle --val b.csv");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("at least one --est file is required"));
  r = diagnose("--baseline throttle --est a.csv --val b.csv --decimate zero");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--decimate needs an integer from 1 to 1000000, got 'zero'"));
  r = diagnose("--baseline throttle --est a.csv --val b.csv --x0 measured");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--x0 must be estimate or zero, got 'measured'"));
}

TEST_CASE("nlid-diagnose: unknown baseline lists the catalogue", "[tools][diagnose]") {
  const Run r = diagnose("--baseline valve --est a.csv --val b.csv");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("unknown physics 'valve'") && Catch::Contains("first_order") &&
                        Catch::Contains("mass_spring_damper") && Catch::Contains("rigid_body") &&
                        Catch::Contains("throttle") && Catch::Contains("two_tank"));
  const Run e = diagnose("--baseline first_order --est a.csv --val b.csv --effects coulomb_friction,stiction");
  CHECK(e.code == 2);
  CHECK_THAT(e.err, Catch::Contains("unknown effect 'stiction'"));
  // A list that names nothing read as the whole catalogue; a name twice was tried twice.
  Run u = diagnose("--baseline first_order --est a.csv --val b.csv --effects ,");
  CHECK(u.code == 2);
  CHECK_THAT(u.err, Catch::Contains("--effects has an empty name"));
  u = diagnose("--baseline first_order --est a.csv --val b.csv --effects dead_time,dead_time");
  CHECK(u.code == 2);
  CHECK_THAT(u.err, Catch::Contains("--effects names 'dead_time' twice"));
  // Effects are tested on records no parameter was fitted to.
  u = diagnose("--baseline first_order --est a.csv --val b.csv --val a.csv");
  CHECK(u.code == 2);
  CHECK_THAT(u.err, Catch::Contains("is both an --est and a --val record"));
}

TEST_CASE("nlid-diagnose: bad files, missing columns, data too short", "[tools][diagnose]") {
  const fs::path good = write_record("good", 400, 1u, 0);
  const fs::path other = write_record("good_val", 400, 3u, 0);  // est and val must be distinct records
  Run r = diagnose("--baseline first_order --est " + q(work_dir() / "missing.csv") + " --val " + q(good));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("missing.csv"));
  r = diagnose("--baseline first_order --est " + q(good) + " --val " + q(other) + " --output angle");
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("angle") && Catch::Contains("available columns"));
  const fs::path bad = work_dir() / "bad.csv";
  {
    std::ofstream f(bad);
    f << "t,u,y\n0,0,1\n0.01,0,abc\n0.02,0,1\n";
  }
  r = diagnose("--baseline first_order --est " + q(bad) + " --val " + q(good));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("bad.csv") && Catch::Contains("row 3"));
  // (write_record holds each input level >= 30 samples: its 30-sample record has a constant input,
  // which is refused first - see nlid_bad_input_test.cpp)
  const fs::path shorty = work_dir() / "short.csv";
  {
    std::ofstream f(shorty);
    f << "t,u,y\n";
    for (int k = 0; k < 30; ++k) f << k * 0.01 << "," << (k / 5) % 2 << "," << 0.5 + 0.01 * k << "\n";
  }
  r = diagnose("--baseline first_order --est " + q(shorty) + " --val " + q(good));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("too short") && Catch::Contains("30 samples"));
  // Located at the file the user named, not at the record's name (the stem).
  CHECK_THAT(r.err, Catch::Contains("[at file '" + shorty.string() + "'"));
  r = diagnose("--baseline first_order --est " + q(good) + " --val " + q(other) + " --decimate 10");
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("too short") && Catch::Contains("after decimation by 10"));
  // Records at other rates: named by file, with the remedy - --ts for nearly equal rates (one
  // logger, differently rounded stamps), resampling for really different ones.
  const fs::path drift = write_record("good_drift", 400, 5u, 0, true, "y", 0.0100005);
  r = diagnose("--baseline first_order --est " + q(good) + " --est " + q(drift) + " --val " + q(other));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("sample time 0.0100005") && Catch::Contains("differs from the other records' 0.01 s") &&
                        Catch::Contains("give that sample time with --ts") &&
                        Catch::Contains("[at file '" + drift.string() + "'"));
  const fs::path slow = write_record("good_slow", 400, 5u, 0, true, "y", 0.02);
  r = diagnose("--baseline first_order --est " + q(good) + " --val " + q(slow));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("but validation records at 0.02 s") &&
                        Catch::Contains("resample one of them to the other's rate first"));
  // An output without measurable noise (here the step input read as the output): the hint named
  // DiagnoseOptions::noise, a C++ field no flag set; --noise now gives the floor.
  r = diagnose("--baseline first_order --est " + q(good) + " --val " + q(other) + " --input y --output u --quiet");
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("give one with --noise SIGMA") && !Catch::Contains("DiagnoseOptions"));
  const fs::path noise_json = work_dir() / "noise.json";
  r = diagnose("--baseline first_order --est " + q(good) + " --val " + q(other) +
               " --input y --output u --quiet --max-effects 0 --noise 0.05 --refine-top 2 --json " + q(noise_json));
  INFO(r.err);
  CHECK(r.code == 0);
  if (r.code == 0) {
    const nlid::Json j = nlid::Json::parse(slurp(noise_json), noise_json.string());
    CHECK(j["noise_floor"]["sigma"].as_number() == 0.05);
    CHECK(j["noise_floor"]["method"].as_string() == "given with --noise");
  }
  const std::pair<const char*, const char*> bad_flags[] = {
      {"--noise 0", "--noise needs a positive standard deviation in the output's units, got '0'"},
      {"--noise -1", "--noise needs a positive standard deviation"},
      {"--noise x", "--noise needs a finite number, got 'x'"},
      {"--refine-top 0", "--refine-top needs an integer from 1 to 1000, got '0'"}};
  for (const auto& [flag, text] : bad_flags) {
    r = diagnose("--baseline first_order --est " + q(good) + " --val " + q(other) + " " + flag);
    CHECK(r.code == 2);
    CHECK_THAT(r.err, Catch::Contains(text));
  }
  // A record in absurd units is named with its file, not left to fail every start of the fit.
  const fs::path huge = work_dir() / "huge.csv";
  {
    std::ifstream in(other);
    std::ofstream f(huge);
    f.precision(10);
    std::string line;
    std::getline(in, line);
    f << line << "\n";
    double t = 0, u = 0, y = 0;
    char c1 = 0, c2 = 0;
    while (in >> t >> c1 >> u >> c2 >> y) f << t << "," << u << "," << y * 1e200 << "\n";
  }
  r = diagnose("--baseline first_order --est " + q(good) + " --val " + q(huge));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("validation record: experiment 'huge', output 'y'") && Catch::Contains("beyond 1e100") &&
                        Catch::Contains("[at file '" + huge.string() + "'"));
  const fs::path notime = write_record("notime", 400, 3u, 0, false);
  r = diagnose("--baseline first_order --est " + q(notime) + " --val " + q(good));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("'t'"));
}

TEST_CASE("nlid-diagnose: names a concealed dead time and writes JSON and HTML", "[tools][diagnose]") {
  const fs::path est = write_record("est", 1500, 11u, 4);
  const fs::path val = write_record("val", 1500, 12u, 4, false);  // sample time from --ts
  const fs::path json = work_dir() / "out.json", html = work_dir() / "out.html";
  const Run r = diagnose("--baseline first_order --est " + q(est) + " --val " + q(val) + " --ts 0.01 --starts 2 --threads 2" +
                    " --json " + q(json) + " --html " + q(html));
  INFO(r.err);
  REQUIRE(r.code == 0);
  CHECK_THAT(r.out, Catch::Contains("added dead_time"));
  CHECK_THAT(r.err, Catch::Contains("estimating the baseline") && Catch::Contains("round 1"));
  const nlid::Json j = nlid::Json::parse(slurp(json), json.string());
  for (const char* k : {"baseline", "mismatch", "candidates", "effects", "final", "explanation"}) CHECK(j.contains(k));
  CHECK(j["baseline"].contains("fit_est"));
  CHECK(j["baseline"].contains("fit_val"));
  CHECK(j["mismatch"].contains("intervals"));
  CHECK(j["mismatch"].contains("regions"));
  REQUIRE(j["effects"].size() >= 1);
  CHECK(j["effects"][0]["name"].as_string() == "dead_time");
  const double tau = j["effects"][0]["params"]["tau"].as_number();
  CHECK(tau == Approx(0.04).margin(0.006));
  CHECK(j["final"]["fit_val"][0].as_number() > j["baseline"]["fit_val"][0].as_number());
  const std::string h = slurp(html);
  CHECK_THAT(h, Catch::Contains("class=\"nlid-chart\"") && Catch::Contains("dead_time"));
}

TEST_CASE("nlid-diagnose: records of 10^5 samples", "[tools][diagnose][large]") {
  const fs::path est = write_record("big_est", 100000, 21u, 0, true, "level");
  const fs::path val = write_record("big_val", 100000, 22u, 0, true, "level");
  const Run r = diagnose("--baseline first_order --est " + q(est) + " --val " + q(val) +
                    " --output level --starts 1 --threads 2 --effects output_offset,dead_time --quiet");
  INFO(r.err);
  REQUIRE(r.code == 0);
  CHECK_THAT(r.out, Catch::Contains("effects added: none"));
  CHECK(r.err.empty());
}
