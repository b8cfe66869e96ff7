// nlid-distortion end to end: a random-odd multisine written by nlid-input drives a known Wiener
// system (written here as a CSV record); the tool reports the distortion theory predicts (none
// for a linear system, even for a square term; on an odd multisine, that odd distortion is not
// measurable), writes the levels as JSON, and refuses bad command lines (status 2) and records it
// cannot analyse (status 1, naming the file).
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <tuple>

#include "nlid/data/csv.hpp"
#include "nlid/data/input_design.hpp"
#include "nlid/io/json.hpp"
#include "tool_runner.hpp"

namespace fs = std::filesystem;
using tool_test::q;
using tool_test::Run;
using tool_test::work_dir;

namespace {

// x(t) = 0.9 x(t-1) + 0.1 u(t), y = x + a2 x² + a3 x³ + small deterministic "noise"; u the
// (by default random-odd) multisine of 5 periods of 256 samples that nlid-input writes (read
// back from its file).
fs::path record(const std::string& name, double a2, double a3 = 0.0,
                const std::string& lines = "random-odd") {
  const fs::path u = work_dir() / (name + "_u.csv");
  const Run r = tool_test::input(
      "--signal multisine --period 256 --periods 5 --band 0,0.4 --lines " + lines +
      " --phases random --seed 3 --ts 0.01 --out " + q(u));
  REQUIRE(r.code == 0);
  const Eigen::VectorXd uu = nlid::read_csv_table(u.string()).col("u");  // the tool's own file
  REQUIRE(uu.size() == 5 * 256);
  const Eigen::VectorXd noise = nlid::random_gaussian(uu.size(), {}, {-1e-3, 1e-3}, 5);
  const fs::path p = work_dir() / (name + ".csv");
  std::ofstream f(p);
  f << "t,u,y\n";
  f.precision(17);
  double x = 0.0;
  for (Eigen::Index t = 0; t < uu.size(); ++t) {
    x = 0.9 * x + 0.1 * uu[t];
    f << static_cast<double>(t) * 0.01 << "," << uu[t] << "," << x + a2 * x * x + a3 * x * x * x + noise[t]
      << "\n";
  }
  return p;
}

}  // namespace

TEST_CASE("nlid-distortion reports what theory predicts and writes the levels",
          "[tools][distortion]") {
  const fs::path lin = record("dist_linear", 0.0);
  Run r = tool_test::distortion("--data " + q(lin) + " --period 256");
  INFO(r.err);
  REQUIRE(r.code == 0);
  CHECK_THAT(
      r.out,
      Catch::Contains("4 periods of 256 samples") &&
          Catch::Contains("no distortion above the noise: a linear model can explain these data"));
  const fs::path sq = record("dist_square", 0.5), js = work_dir() / "dist.json";
  r = tool_test::distortion("--data " + q(sq) + " --period 256 --json " + q(js));
  REQUIRE(r.code == 0);
  CHECK_THAT(r.out, Catch::Contains("a nonlinear structure is warranted"));
  nlid::Json j = nlid::read_json(js.string());
  CHECK(j["even_detected"].as_bool());
  CHECK_FALSE(j["odd_detected"].as_bool());
  CHECK(j["even_measurable"].as_bool());
  CHECK(j["odd_measurable"].as_bool());
  CHECK(j["even_db"].as_number() > 20.0);
  CHECK(j["periods"].as_number() == 4.0);
  CHECK(j["frf"]["frequency_hz"].size() == j["excited_lines"].size());
  CHECK(j["frf"]["frequency_hz"][std::size_t{0}].as_number() ==
        Approx(j["excited_lines"][std::size_t{0}].as_number() / 2.56));
  // A Latin-1 file name: the analysis was printed, then the JSON write failed ("string at data
  // is not valid UTF-8") and nothing was written. Repaired as in nlid-fit's model files.
  const fs::path latin = work_dir() / "mess\xE4ung.csv";
  fs::copy_file(sq, latin, fs::copy_options::overwrite_existing);
  r = tool_test::distortion("--data " + q(latin) + " --period 256 --json " + q(js));
  INFO(r.err);
  REQUIRE(r.code == 0);
  CHECK_THAT(nlid::read_json(js.string())["data"].as_string(), Catch::Contains("mess\xEF\xBF\xBDung.csv"));
}

TEST_CASE("nlid-distortion: an odd multisine cannot measure odd distortion and gives no verdict",
          "[tools][distortion]") {
  // A cube on odd lines: its distortion falls on excited lines. The tool used to conclude "a
  // linear model can explain these data"; now it says odd distortion is not measurable.
  const fs::path cube = record("dist_cube_odd", 0.0, 0.5, "odd"), js = work_dir() / "dist_odd.json";
  const Run r = tool_test::distortion("--data " + q(cube) + " --period 256 --json " + q(js));
  INFO(r.err);
  REQUIRE(r.code == 0);
  CHECK_THAT(r.out, !Catch::Contains("a linear model can explain") &&
                        Catch::Contains("odd distortion: not measurable, no empty odd lines in the band "
                                        "(use random-odd lines)") &&
                        Catch::Contains("odd distortion cannot be measured with this input"));
  const nlid::Json j = nlid::read_json(js.string());
  CHECK(j["even_measurable"].as_bool());
  CHECK_FALSE(j["odd_measurable"].as_bool());
  CHECK_FALSE(j["odd_detected"].as_bool());
  CHECK(j["odd_db"].json().is_null());
  CHECK(j["odd_lines"].size() == 0);
}

TEST_CASE("nlid-distortion refuses bad command lines and records it cannot analyse",
          "[tools][distortion][bad_input]") {
  const fs::path rec = record("dist_bad", 0.0);
  const std::string d = "--data " + q(rec);
  Run r = tool_test::distortion(d);
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--data and --period are required"));
  r = tool_test::distortion(d + " --period 4");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--period needs an integer from 8"));
  r = tool_test::distortion(d + " --period 256 --skip -1");
  CHECK(r.code == 2);
  r = tool_test::distortion(d + " --period 256 --threshold x");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--threshold needs a finite number"));
  r = tool_test::distortion(d + " --period 256 --threshold -5");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--threshold must be a level above the noise") && Catch::Contains("'-5'"));
  r = tool_test::distortion(d + " --period 256 --json " + q(rec));
  CHECK(r.code == 2);
  r = tool_test::distortion(d + " --period 256 --frequency 3");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("unknown option '--frequency'"));
  r = tool_test::distortion(d +
                            " --period 512");  // 1280 samples: 2 whole periods, 1 after the skip
  CHECK(r.code == 1);
  CHECK_THAT(r.err,
             Catch::Contains("at least 2 must remain") && Catch::Contains(rec.filename().string()));
  // 5 whole periods, 4 skipped: the skip took them, so --skip is named (it was '--period').
  r = tool_test::distortion(d + " --period 256 --skip 4");
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("at least 2 must remain") && Catch::Contains("parameter '--skip'"));
  r = tool_test::distortion(d + " --period 256 --output z");
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("z"));
  CHECK(tool_test::distortion("--help").code == 0);
}

TEST_CASE("nlid-distortion: outputs and inputs near the largest doubles give the levels of ordinary ones, never nan",
          "[tools][distortion]") {
  // The power sums overflowed: y up to ~1e301 printed nan dB and "no distortion", a huge input
  // "has no power".
  const fs::path rec = record("dist_scaled_ref", 0.5);
  const nlid::CsvTable t = nlid::read_csv_table(rec.string());
  const auto scaled = [&](const std::string& name, double ku, double ky) {
    const fs::path p = work_dir() / (name + ".csv");
    std::ofstream f(p);
    f.precision(17);
    f << "t,u,y\n";
    for (Eigen::Index i = 0; i < t.data.rows(); ++i)
      f << t.data(i, 0) << "," << t.data(i, 1) * ku << "," << t.data(i, 2) * ky << "\n";
    return p;
  };
  const Run ref = tool_test::distortion("--data " + q(rec) + " --period 256");
  REQUIRE(ref.code == 0);
  REQUIRE_THAT(ref.out, Catch::Contains("even distortion") && Catch::Contains("present"));
  // The reference's dB figures, which the scaled records must repeat (the first line names no file).
  for (const auto& [name, ku, ky] : {std::tuple{"dist_huge_y", 1.0, 1e300}, std::tuple{"dist_huge_u", 1e300, 1.0}}) {
    const Run r = tool_test::distortion("--data " + q(scaled(name, ku, ky)) + " --period 256");
    INFO(r.err);
    REQUIRE(r.code == 0);
    CHECK(r.out == ref.out);
    CHECK(r.out.find("nan") == std::string::npos);
  }
}

TEST_CASE("nlid-distortion names --period, not the library's parameter", "[tools][distortion][bad_input]") {
  const fs::path rec = record("dist_period_name", 0.0);
  const Run r = tool_test::distortion("--data " + q(rec) + " --period 250");  // not the input's period
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("does not repeat every 250 samples") && Catch::Contains("parameter '--period'") &&
                        Catch::Contains(rec.filename().string()));
  CHECK(r.err.find("parameter 'period'") == std::string::npos);
}
