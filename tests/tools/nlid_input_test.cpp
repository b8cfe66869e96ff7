// nlid-input end to end: each signal kind written as CSV equals the library's generator bit for
// bit (t = k·ts), the file drives nlid-sim directly, and every bad command line is exit 2 with
// a message naming the option (an unwritable --out is exit 1).
#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "nlid/data/input_design.hpp"
#include "tool_runner.hpp"

namespace fs = std::filesystem;
using tool_test::q;
using tool_test::Run;
using tool_test::work_dir;

namespace {

// Header and columns of a two-column CSV file.
struct Table {
  std::string header;
  std::vector<double> t, u;
};

Table read_table(const fs::path& p) {
  Table tb;
  std::ifstream f(p);
  std::getline(f, tb.header);
  std::string line;
  while (std::getline(f, line)) {
    const auto c = line.find(',');
    tb.t.push_back(std::stod(line.substr(0, c)));
    tb.u.push_back(std::stod(line.substr(c + 1)));
  }
  return tb;
}

void check_same(const Table& tb, const Eigen::VectorXd& want, double ts) {
  REQUIRE(tb.u.size() == static_cast<std::size_t>(want.size()));
  for (std::size_t i = 0; i < tb.u.size(); ++i) {
    INFO("row " << i + 1);
    REQUIRE(tb.u[i] == want[static_cast<Eigen::Index>(i)]);  // %.17g reads back exactly
    REQUIRE(tb.t[i] == static_cast<double>(i) * ts);
  }
}

}  // namespace

TEST_CASE("nlid-input writes each signal as the library generates it", "[tools][input]") {
  const fs::path out = work_dir() / "input.csv";
  Run r = tool_test::input("--signal prbs --bits 7 --periods 2 --hold 3 --levels 0.05,0.65 --ts 0.01 --out " + q(out));
  REQUIRE(r.code == 0);
  CHECK_THAT(r.err, Catch::Contains("prbs, 762 samples") && Catch::Contains("period 127 chips of 0.03 s"));
  Table tb = read_table(out);
  CHECK(tb.header == "t,u");
  check_same(tb, nlid::prbs(7, 2, {0.05, 0.65}, 3), 0.01);

  r = tool_test::input("--signal random-steps --samples 3000 --hold 20,80 --levels 0,1 --seed 9 --ts 0.01 --column cmd --out " +
                       q(out));
  REQUIRE(r.code == 0);
  tb = read_table(out);
  CHECK(tb.header == "t,cmd");
  check_same(tb, nlid::random_steps(3000, 20, 80, {0.0, 1.0}, 9), 0.01);

  r = tool_test::input("--signal random-gaussian --samples 500 --band 0,0.3 --levels 1,3 --seed 4 --ts 0.002 --out " + q(out));
  REQUIRE(r.code == 0);
  CHECK_THAT(r.err, Catch::Contains("band 0 to 75 Hz"));
  check_same(read_table(out), nlid::random_gaussian(500, {0.0, 0.3}, {1.0, 3.0}, 4), 0.002);

  r = tool_test::input("--signal random-binary --samples 400 --band 0.1,0.5 --seed 2 --ts 0.01 --out " + q(out));
  REQUIRE(r.code == 0);
  check_same(read_table(out), nlid::random_binary(400, {0.1, 0.5}, {}, 2), 0.01);

  nlid::MultisineOptions o;
  o.band = {0.0, 0.1};
  o.lines = nlid::MultisineLines::random_odd;
  o.phases = nlid::MultisinePhases::random;
  o.seed = 3;
  o.periods = 2;
  r = tool_test::input(
      "--signal multisine --period 1000 --periods 2 --band 0,0.1 --lines random-odd --phases random --seed 3 --ts 0.01 --out " +
      q(out));
  REQUIRE(r.code == 0);
  CHECK_THAT(r.err, Catch::Contains("lines from 0.1 Hz to") && Catch::Contains("(spacing 0.1 Hz), period 10 s"));
  check_same(read_table(out), nlid::multisine(1000, o), 0.01);
}

TEST_CASE("nlid-input's file drives nlid-sim as it is", "[tools][input][sim]") {
  const fs::path rec = tool_test::write_record("input_est", 1500, 5, 0.0);
  const fs::path model = work_dir() / "input_arx.json", u = work_dir() / "input_u.csv", y = work_dir() / "input_y.csv";
  REQUIRE(tool_test::fit("--model linear:arx:na=1,nb=1,nk=0 --est " + q(rec) + " --save " + q(model)).code == 0);
  REQUIRE(tool_test::input("--signal random-steps --samples 800 --hold 10,40 --levels -0.5,0.5 --ts 0.01 --out " + q(u)).code ==
          0);
  const Run s = tool_test::sim("--model " + q(model) + " --input " + q(u) + " --out " + q(y));
  INFO(s.err);
  REQUIRE(s.code == 0);
  CHECK(read_table(y).u.size() == 800u);
}

TEST_CASE("nlid-input refuses bad command lines, naming the option", "[tools][input][bad_input]") {
  const std::string out = " --out " + q(work_dir() / "bad_input.csv");
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"--signal sine --ts 0.01", "--signal must be prbs, random-steps"},
      {"--signal prbs --ts 0.01", "--signal prbs needs --bits"},
      {"--signal prbs --bits 25 --ts 0.01", "--bits needs an integer from 2 to 24"},
      {"--signal prbs --bits 7 --samples 100 --ts 0.01", "option --samples does not apply to --signal prbs"},
      {"--signal prbs --bits 24 --periods 300 --ts 0.01", "more than 2^31 samples"},
      {"--signal random-steps --samples 100 --hold 5,2 --ts 0.01", "--hold needs whole sample counts 1 <= MIN <= MAX"},
      {"--signal random-steps --samples 100 --hold 5 --ts 0.01", "--hold needs two numbers separated by a comma"},
      {"--signal random-steps --samples 100 --ts 0.01", "needs --hold"},
      {"--signal random-gaussian --samples 100 --levels 2,1 --ts 0.01", "--levels needs LO < HI"},
      {"--signal random-steps --samples 100 --hold 2,5 --levels -1e308,1e308 --ts 0.01", "--levels needs a finite span"},
      {"--signal random-gaussian --samples 100 --band 0,1.5 --ts 0.01", "--band needs 0 <= LO < HI <= 1"},
      {"--signal random-binary --samples 100 --ts -1", "--ts needs a positive sample time"},
      // Below the normal range: "needs a finite number" before, while the record tools took it.
      {"--signal random-binary --samples 100 --ts 1e-320", "--ts needs a number within the range of a double"},
      {"--signal random-binary --samples 100 --ts 0.01 --seed -3", "--seed needs an integer >= 0"},
      {"--signal random-binary --samples 100 --ts 0.01 --column t", "--column needs a plain name other than 't'"},
      {"--signal multisine --period 50 --band 0,0.01 --ts 0.01", "no DFT line of a 50-sample period lies in the band"},
      {"--signal multisine --period 64 --lines even --ts 0.01", "--lines must be all, odd or random-odd"},
      {"--signal multisine --period 64 --phases zero --ts 0.01", "--phases must be schroeder or random"},
      {"--signal multisine --period 64 --ts 0.01 --ts 0.02", "option --ts is given twice"},
      {"--signal multisine --period 64 --ts 0.01 --frequency 3", "unknown option '--frequency'"},
  };
  for (const auto& [args, msg] : cases) {
    INFO(args);
    const Run r = tool_test::input(args + out);
    CHECK(r.code == 2);
    CHECK_THAT(r.err, Catch::Contains(msg));
  }
  CHECK_FALSE(fs::exists(work_dir() / "bad_input.csv"));
  const Run r = tool_test::input("--signal prbs --bits 5 --ts 0.01 --out " + q(work_dir() / "no_such_dir" / "u.csv"));
  CHECK(r.code == 1);
  CHECK_THAT(r.err, Catch::Contains("does not exist"));
  CHECK(tool_test::input("--help").code == 0);
  CHECK(tool_test::input("--signal prbs --bits 5").code == 2);  // --ts and --out are required
}

TEST_CASE("nlid-input refuses a random-binary band too narrow for --samples and a --ts whose time stamps overflow",
          "[tools][input][bad_input]") {
  const fs::path out = work_dir() / "narrow_or_huge.csv";
  // The sign of noise drifting without a zero crossing: a constant -1 was written, exit 0.
  Run r = tool_test::input("--signal random-binary --samples 100 --band 0,0.001 --ts 0.01 --out " + q(out));
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("band [0, 0.001]") && Catch::Contains("too narrow for 100 samples") &&
                        Catch::Contains("parameter '--band'"));
  CHECK_FALSE(fs::exists(out));
  // t = i * ts beyond the largest double: rows of 'inf' were written, exit 0.
  r = tool_test::input("--signal random-binary --samples 1000 --ts 1e306 --out " + q(out));
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("--ts 1e306 is too large for 1000 samples: the time stamps would not be finite"));
  CHECK_FALSE(fs::exists(out));
  // The largest sample time that still fits is accepted.
  r = tool_test::input("--signal prbs --bits 3 --ts 1e307 --out " + q(out));
  INFO(r.err);
  CHECK(r.code == 0);
  CHECK(tool_test::slurp(out).find("inf") == std::string::npos);
}
