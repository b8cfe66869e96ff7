// CSV reading and writing: the throttle files, exact round trips, tolerated formatting, and one
// test per user error checking that the message names the file, row and column.
#include "nlid/data/csv.hpp"
#include "nlid/core/utf8.hpp"
#include "nlid/data/dataset.hpp"

#include <catch2/catch.hpp>

#include "../support/decimal_comma_locale.hpp"
#include "../support/error_of.hpp"

#include <chrono>
#include <clocale>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <limits>
#include <random>
#include <sstream>
#include <string>

namespace {

namespace fs = std::filesystem;
using Catch::Matchers::Contains;

// A fresh directory per test case, removed afterwards.
struct TempDir {
  fs::path path;
  TempDir() {
    std::random_device rd;
    path = fs::temp_directory_path() /
           ("nlid_csv_test_" + std::to_string(rd()) + std::to_string(rd()));
    fs::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
  // Writes `text` byte for byte (no newline translation) and returns the file path.
  std::string write(const std::string& name, const std::string& text) const {
    const fs::path p = path / name;
    std::ofstream out(p, std::ios::binary);
    out << text;
    return p.string();
  }
  std::string file(const std::string& name) const { return (path / name).string(); }
};

using nlid_test::error_of;

std::string throttle(int i) {
  return std::string(NLID_TEST_DATA_DIR) + "/throttle/data" + std::to_string(i) + ".csv";
}

}  // namespace

TEST_CASE("read_csv reads the throttle recordings", "[data][csv]") {
  const nlid::Experiment e = nlid::read_csv(throttle(1));
  CHECK(e.size() == 20001);
  CHECK(e.ts() == 0.001);  // inferred from the time column, exactly
  CHECK(e.t0() == 0.0);
  CHECK(e.name() == "data1");
  CHECK(e.input_names() == std::vector<std::string>{"u"});
  CHECK(e.output_names() == std::vector<std::string>{"y"});
  CHECK(e.y()(0, 0) == 14.9);
  CHECK(e.y()(1, 0) == 15.1);
  CHECK(e.y()(20000, 0) == 23.4);
  CHECK(e.u()(20000, 0) == 0.172605);
  CHECK_FALSE(e.has_missing());
  REQUIRE_FALSE(e.notes().empty());
  CHECK_THAT(e.notes()[0], Contains("data1.csv"));

  const nlid::Dataset d = nlid::read_csv_dataset({throttle(1), throttle(2)});
  CHECK(d.size() == 2);
  CHECK(d[1].name() == "data2");
  CHECK(d.total_samples() == 40002);
}

TEST_CASE("write_csv -> read_csv is exact", "[data][csv]") {
  TempDir dir;
  std::mt19937 rng(42);
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::MatrixXd u(257, 2), y(257, 3);
  for (Eigen::Index k = 0; k < u.size(); ++k) u.data()[k] = g(rng) * std::pow(10.0, g(rng) * 3);
  for (Eigen::Index k = 0; k < y.size(); ++k) y.data()[k] = g(rng) / 3.0;
  y(0, 0) = 1e-300;
  y(1, 1) = -0.0;
  y(2, 2) = std::numeric_limits<double>::max();
  y(3, 0) = std::numeric_limits<double>::denorm_min();
  nlid::Experiment e(u, y, 1.0 / 3.0, "rt");
  e.set_t0(-7.1);
  e.set_input_names({"cmd", "load, N"});  // a name with the delimiter is quoted
  e.set_output_names({"a", "b", "c"});
  const std::string path = dir.file("rt.csv");
  nlid::write_csv(path, e);

  nlid::CsvReadOptions opt;
  opt.inputs = {"cmd", "load, N"};
  opt.outputs = {"a", "b", "c"};
  const nlid::Experiment r = nlid::read_csv(path, opt);
  CHECK(r.ts() == e.ts());
  CHECK(r.t0() == e.t0());
  CHECK(r.u() == e.u());
  CHECK(r.y() == e.y());
  CHECK(std::signbit(r.y()(1, 1)));
  CHECK(r.input_names() == e.input_names());

  SECTION("sample times survive the round trip") {
    // Decimal sample times come back bit for bit even with a large t0; for any sample time the
    // grid t0 + k ts reproduces every written time stamp exactly.
    for (double ts : {1e-3, 2.5e-4, 0.1, 0.3, 123.456, 1.0 / 7.0}) {
      nlid::Experiment s(u.topRows(100), y.topRows(100).leftCols(1), ts);
      s.set_t0(1000.0 + ts);
      nlid::write_csv(path, s);
      nlid::CsvReadOptions o;
      o.inputs = {"u1", "u2"};
      const nlid::Experiment back = nlid::read_csv(path, o);
      CHECK(back.t0() == s.t0());
      CHECK((back.time().array() == s.time().array()).all());
      CHECK(back.ts() == Approx(ts).epsilon(1e-14));
      if (ts != 1.0 / 7.0) CHECK(back.ts() == ts);
    }
    nlid::Experiment s(u.topRows(100), y.topRows(100).leftCols(1), 1.0 / 7.0);
    nlid::write_csv(path, s);
    nlid::CsvReadOptions o;
    o.inputs = {"u1", "u2"};
    CHECK(nlid::read_csv(path, o).ts() == 1.0 / 7.0);  // t0 = 0: the only exact candidate
  }
  SECTION("missing samples are written as nan and kept on request") {
    Eigen::MatrixXd y1 = y.leftCols(1);
    y1(5, 0) = std::numeric_limits<double>::quiet_NaN();
    const nlid::Experiment m(u.leftCols(1), y1, 0.5, "m", nlid::NonFinitePolicy::keep);
    nlid::write_csv(path, m);
    nlid::CsvReadOptions o;
    o.non_finite = nlid::NonFinitePolicy::keep;
    const nlid::Experiment back = nlid::read_csv(path, o);
    CHECK(std::isnan(back.y()(5, 0)));
    CHECK(back.y()(6, 0) == y1(6, 0));
    CHECK_THROWS_WITH(nlid::read_csv(path), Contains("non-finite value 'nan'"));
  }
}

TEST_CASE("write_csv_table -> read_csv_table is exact", "[data][csv]") {
  TempDir dir;
  Eigen::MatrixXd m(4, 3);
  m << 0.1, 1e20, -3, 1.0 / 3.0, 2e-308, 4, 5, 6, 7, 8, 9, 10;
  const std::string path = dir.file("table.csv");
  nlid::write_csv_table(path, {"a", " spaced ", "q\"uote"}, m);
  const nlid::CsvTable t = nlid::read_csv_table(path);
  CHECK(t.header == std::vector<std::string>{"a", " spaced ", "q\"uote"});
  CHECK(t.data == m);
  CHECK(t.column("q\"uote") == 2);
  CHECK(t.col(" spaced ")(1) == 2e-308);
  CHECK_THROWS_WITH(t.column("zz"), Contains("available columns: 'a', ' spaced ', 'q\"uote'"));
  CHECK_THROWS_WITH(nlid::write_csv_table(path, {"a"}, m),
                    Contains("1 names but the matrix has 3"));
}

TEST_CASE("read_csv tolerates CRLF, BOM, blanks, quotes, comments and a missing final newline",
          "[data][csv]") {
  TempDir dir;
  const std::string text =
      "\xEF\xBB\xBF# exported by a logger\r\n"
      " \"t\" ;  u ; y \r\n"
      "\r\n"
      "0,0 ; 1 ; 10,5\r\n"
      "  0,5;2;+11\r\n"
      "# pause\r\n"
      "1,0 ; 3 ; \"12\"";
  nlid::CsvReadOptions opt;
  opt.delimiter = ';';
  opt.decimal_point = ',';
  const nlid::Experiment e = nlid::read_csv(dir.write("eu.csv", text), opt);
  REQUIRE(e.size() == 3);
  CHECK(e.ts() == 0.5);
  CHECK(e.u()(2, 0) == 3.0);
  CHECK(e.y()(0, 0) == 10.5);
  CHECK(e.y()(1, 0) == 11.0);
  CHECK(e.y()(2, 0) == 12.0);

  SECTION("classic-Mac line endings (CR only) read like LF") {
    // Read as one line they gave "duplicate column name '0'".
    const nlid::Experiment cr = nlid::read_csv(dir.write("cr.csv", "t,u,y\r0,1,10\r0.5,2,11\r1,3,12\r"));
    REQUIRE(cr.size() == 3);
    CHECK(cr.u()(2, 0) == 3.0);
    CHECK(cr.y()(1, 0) == 11.0);
    CHECK(cr.ts() == 0.5);
  }

  SECTION("whitespace- and tab-delimited files") {
    nlid::CsvReadOptions ws;
    ws.delimiter = ' ';
    const nlid::Experiment a =
        nlid::read_csv(dir.write("ws.txt", "t   u y\n0 1\t2\n  1   3  4  \n"), ws);
    CHECK(a.y()(1, 0) == 4.0);
    nlid::CsvReadOptions tab;
    tab.delimiter = '\t';
    const nlid::Experiment b =
        nlid::read_csv(dir.write("tab.tsv", "t\tu\ty\n0\t 1\t2\n1\t3\t4\n\n\n"), tab);
    CHECK(b.u()(0, 0) == 1.0);
  }
  SECTION("unrequested columns may hold text; the column order is free") {
    const nlid::Experiment c =
        nlid::read_csv(dir.write("extra.csv", "note,y,t,u\nstart,1,0,5\n,2,1,6\nend,3,2,7\n"));
    CHECK(c.u()(2, 0) == 7.0);
    CHECK(c.y()(1, 0) == 2.0);
  }
}

TEST_CASE("read_csv options: several channels, no time column, ts override", "[data][csv]") {
  TempDir dir;
  const std::string p =
      dir.write("multi.csv", "time,u1,u2,y1,y2\n10,1,2,3,4\n10.1,5,6,7,8\n10.2,9,10,11,12\n");
  nlid::CsvReadOptions opt;
  opt.time_column = "time";
  opt.inputs = {"u2", "u1"};
  opt.outputs = {"y2"};
  const nlid::Experiment e = nlid::read_csv(p, opt);
  CHECK(e.num_inputs() == 2);
  CHECK(e.num_outputs() == 1);
  CHECK(e.u()(1, 0) == 6.0);
  CHECK(e.u()(1, 1) == 5.0);
  CHECK(e.t0() == 10.0);
  CHECK(e.ts() == Approx(0.1).epsilon(1e-12));
  CHECK(e.input_names() == std::vector<std::string>{"u2", "u1"});

  SECTION("time series (no inputs) without a time column") {
    nlid::CsvReadOptions o;
    o.time_column = "";
    o.inputs = {};
    o.outputs = {"y1"};
    o.ts = 0.25;
    const nlid::Experiment t = nlid::read_csv(p, o);
    CHECK(t.num_inputs() == 0);
    CHECK(t.ts() == 0.25);
    CHECK(t.t0() == 0.0);
    o.ts = 0;
    CHECK_THROWS_WITH(nlid::read_csv(p, o),
                      Contains("no time column (time_column is empty) and no sample time"));
  }
  SECTION("an override that disagrees with the time column is noted, not silent") {
    opt.ts = 0.2;
    const nlid::Experiment o = nlid::read_csv(p, opt);
    CHECK(o.ts() == 0.2);
    CHECK_THAT(o.notes().back(), Contains("the time column's step is 0.1"));
    // The same fact as a number, for programs (the tools' own note).
    nlid::CsvReadInfo info;
    (void)nlid::read_csv(p, opt, info);
    CHECK(info.time_column_step == Approx(0.1).epsilon(1e-12));
  }
  SECTION("no time column: no step") {
    nlid::CsvReadOptions o = opt;
    o.time_column = "";
    o.ts = 0.5;
    nlid::CsvReadInfo info;
    info.time_column_step = 1.0;  // overwritten
    (void)nlid::read_csv(p, o, info);
    CHECK(std::isnan(info.time_column_step));
  }
}

TEST_CASE("read_csv: a sample-time override does not hide a gap in the time column", "[data][csv][errors]") {
  TempDir dir;
  // Row 4 (t = 0.003) was dropped by the logger.
  const std::string gap = dir.write("gap.csv", "t,u,y\n0,1,2\n0.001,1,2\n0.002,1,3\n0.004,1,3\n0.005,1,3\n");
  nlid::CsvReadOptions o;
  o.ts = 0.001;
  CHECK_THROWS_WITH(nlid::read_csv(gap, o), Contains("non-uniform time column: step 0.002") && Contains("gap.csv") &&
                                                Contains("cut the record at the gap"));
  o.ts = 0;
  CHECK_THROWS_WITH(nlid::read_csv(gap, o), Contains("non-uniform time column"));
}

TEST_CASE("read_csv reports file-level errors with the file name", "[data][csv]") {
  TempDir dir;
  auto err = error_of([&] { (void)nlid::read_csv(dir.file("nope.csv")); });
  CHECK(err.where().file == dir.file("nope.csv"));
  CHECK_THAT(err.what(), Contains("file not found"));
  CHECK_THAT(err.what(), Contains("nope.csv"));

  err = error_of([&] { (void)nlid::read_csv(dir.path.string()); });
  CHECK_THAT(err.what(), Contains("directory"));

  err = error_of([&] { (void)nlid::read_csv(dir.write("empty.csv", "")); });
  CHECK_THAT(err.what(), Contains("file is empty"));
  err = error_of([&] { (void)nlid::read_csv(dir.write("blank.csv", "\r\n  \n")); });
  CHECK_THAT(err.what(), Contains("file is empty"));

  err = error_of([&] { (void)nlid::read_csv(dir.write("header.csv", "t,u,y\r\n")); });
  CHECK_THAT(err.what(), Contains("header but no data rows"));
  CHECK(err.where().row == 1);
}

TEST_CASE("read_csv reports header errors", "[data][csv]") {
  TempDir dir;
  auto err =
      error_of([&] { (void)nlid::read_csv(dir.write("m.csv", "t,u,angle\n0,1,2\n1,1,2\n")); });
  CHECK_THAT(err.what(),
             Contains("output column 'y' not found; available columns: 't', 'u', 'angle'"));
  CHECK(err.where().column_name == "y");

  err = error_of([&] { (void)nlid::read_csv(dir.write("d.csv", "t,u,y,u\n0,1,2,3\n")); });
  CHECK_THAT(err.what(), Contains("duplicate column name 'u' (also column 2)"));
  CHECK(err.where().column == 4);
  CHECK(err.where().row == 1);

  nlid::CsvReadOptions twice;
  twice.outputs = {"u"};
  err = error_of([&] { (void)nlid::read_csv(dir.write("t.csv", "t,u,y\n0,1,2\n1,1,2\n"), twice); });
  CHECK_THAT(err.what(), Contains("column 'u' is requested twice (input 1 and output 1)"));

  err = error_of([&] { (void)nlid::read_csv(dir.write("q.csv", "t,\"u,y\n0,1,2\n")); });
  CHECK_THAT(err.what(), Contains("unterminated quoted field"));
}

TEST_CASE("read_csv says when a file is separated by another character or has no time column", "[data][csv]") {
  TempDir dir;
  // A spreadsheet export with decimal commas: ';' separates, so the header is one field and the
  // data rows split at the decimal commas.
  auto err = error_of([&] { (void)nlid::read_csv(dir.write("eu.csv", "t;u;y\n0;1,5;2,25\n0,1;1,5;2,5\n")); });
  CHECK_THAT(err.what(), Contains("ragged row: expected 1 fields") &&
                             Contains("the header is a single field - is the file separated by ';'?"));
  err = error_of([&] { (void)nlid::read_csv(dir.write("tab.csv", "t\tu\ty\n0\t1\t2\n1\t1\t2\n")); });
  CHECK_THAT(err.what(), Contains("input column 'u' not found") && Contains("separated by tabs?"));
  // The hint names the separator only when the wanted column is among the parts.
  err = error_of([&] { (void)nlid::read_csv(dir.write("other.csv", "a;b\n1\n2\n")); });
  CHECK_THAT(err.what(), Contains("input column 'u' not found") && !Contains("separated by"));
  err = error_of([&] { (void)nlid::read_csv(dir.write("notime.csv", "u,y\n1,2\n1,3\n")); });
  CHECK_THAT(err.what(), Contains("time column 't' not found; available columns: 'u', 'y'; a file without a time "
                                  "column needs the sample time"));
  // With the separator and decimal point given, the same file reads.
  nlid::CsvReadOptions eu;
  eu.delimiter = ';';
  eu.decimal_point = ',';
  const nlid::Experiment e = nlid::read_csv(dir.write("eu2.csv", "t;u;y\n0;1,5;2,25\n0,1;1,5;2,5\n"), eu);
  CHECK(e.ts() == Approx(0.1));
  CHECK(e.y()(1, 0) == 2.5);
}

TEST_CASE("read_csv reports cell errors with row and column", "[data][csv]") {
  TempDir dir;
  auto err = error_of(
      [&] { (void)nlid::read_csv(dir.write("n.csv", "t,u,y\n0,1,2\n0.1,1,abc\n0.2,1,2\n")); });
  CHECK_THAT(err.what(), Contains("non-numeric cell 'abc'"));
  CHECK(err.where().row == 3);
  CHECK(err.where().column == 3);
  CHECK(err.where().column_name == "y");
  CHECK_THAT(err.what(), Contains("row 3, column 3 ('y')"));

  err = error_of([&] { (void)nlid::read_csv(dir.write("n2.csv", "t,u,y\n0,1,2\n0.1,1.5.2,2\n")); });
  CHECK_THAT(err.what(), Contains("non-numeric cell '1.5.2'"));
  CHECK(err.where().column_name == "u");

  err = error_of([&] { (void)nlid::read_csv(dir.write("big.csv", "t,u,y\n0,1,2\n1,1,1e999\n")); });
  CHECK_THAT(err.what(), Contains("out of the range of double: '1e999'"));

  err = error_of(
      [&] { (void)nlid::read_csv(dir.write("r.csv", "# c\nt,u,y\n0,1,2\n1,1\n2,1,2\n")); });
  CHECK_THAT(err.what(),
             Contains("ragged row: expected 3 fields (as in the header on row 2), found 2"));
  CHECK(err.where().row == 4);
  err = error_of([&] { (void)nlid::read_csv(dir.write("r2.csv", "t,u,y\n0,1,2,\n")); });
  CHECK_THAT(err.what(), Contains("found 4"));
}

TEST_CASE("read_csv applies the non-finite policy", "[data][csv]") {
  TempDir dir;
  const std::string p =
      dir.write("gaps.csv", "t,u,y\n0,0,0\n1,1,nan\n2,2,\n3,3,inf\n4,4,4\n5,5,-Inf\n6,6,6\n");
  auto err = error_of([&] { (void)nlid::read_csv(p); });
  CHECK_THAT(err.what(), Contains("non-finite value 'nan' under NonFinitePolicy::error"));
  CHECK(err.where().row == 3);
  CHECK(err.where().column_name == "y");

  nlid::CsvReadOptions keep;
  keep.non_finite = nlid::NonFinitePolicy::keep;
  const nlid::Experiment k = nlid::read_csv(p, keep);
  CHECK(std::isnan(k.y()(2, 0)));  // empty cell = missing
  CHECK(std::isinf(k.y()(5, 0)));
  CHECK(k.has_missing());

  nlid::CsvReadOptions interp;
  interp.non_finite = nlid::NonFinitePolicy::interpolate;
  const nlid::Experiment i = nlid::read_csv(p, interp);
  CHECK(i.y()(1, 0) == Approx(1.0));
  CHECK(i.y()(2, 0) == Approx(2.0));
  CHECK(i.y()(3, 0) == Approx(3.0));
  CHECK(i.y()(5, 0) == Approx(5.0));
  CHECK_FALSE(i.has_missing());
  CHECK_THAT(
      i.notes().back(),
      Contains(
          "filled 4 missing value(s) of column 'y' by linear interpolation (rows 3-5, row 7)"));

  interp.max_gap = 2;
  err = error_of([&] { (void)nlid::read_csv(p, interp); });
  CHECK_THAT(err.what(), Contains("gap of 3 missing values (rows 3-5) is longer than max_gap = 2"));
  // The limit is inclusive: a gap of exactly max_gap values is filled, one more is refused.
  interp.max_gap = 3;
  const nlid::Experiment at_limit = nlid::read_csv(p, interp);
  CHECK(at_limit.y()(2, 0) == Approx(2.0));
  CHECK(at_limit.y()(3, 0) == Approx(3.0));
  CHECK_FALSE(at_limit.has_missing());
  interp.max_gap = 0;
  err = error_of([&] { (void)nlid::read_csv(p, interp); });
  CHECK_THAT(err.what(), Contains("gap of 3 missing values (rows 3-5) is longer than max_gap = 0"));

  interp.max_gap = 10;
  err = error_of(
      [&] { (void)nlid::read_csv(dir.write("lead.csv", "t,u,y\n0,nan,0\n1,1,1\n"), interp); });
  CHECK_THAT(err.what(),
             Contains("cannot interpolate missing values at the start of the data (row 2)"));
  CHECK(err.where().column_name == "u");

  err =
      error_of([&] { (void)nlid::read_csv(dir.write("empty_cell.csv", "t,u,y\n0,,0\n1,1,1\n")); });
  CHECK_THAT(err.what(), Contains("empty cell (missing value)"));
}

TEST_CASE("a one-column file reads an empty line between samples as a missing value, not a skipped line") {
  // Its empty cell is an empty line: skipped, the samples after it moved up one place in time.
  TempDir dir;
  const std::string p = dir.write("one_column.csv", "y\n\n1\n\n# note\n3\n4\n\n\n");
  const nlid::Error err = error_of([&] { (void)nlid::read_csv_table(p); });
  CHECK_THAT(err.what(), Contains("empty cell (missing value)"));
  CHECK(err.where().row == 4);
  nlid::CsvTableOptions keep;
  keep.non_finite = nlid::NonFinitePolicy::keep;
  const nlid::CsvTable k = nlid::read_csv_table(p, keep);
  // The blank line after the header and those after the last sample are not samples.
  REQUIRE(k.data.rows() == 4);
  CHECK(k.data(0, 0) == 1.0);
  CHECK(std::isnan(k.data(1, 0)));
  CHECK(k.data(2, 0) == 3.0);
  CHECK(k.data(3, 0) == 4.0);
  nlid::CsvTableOptions interp;
  interp.non_finite = nlid::NonFinitePolicy::interpolate;
  CHECK(nlid::read_csv_table(p, interp).data(1, 0) == Approx(2.0));
  // With two columns an empty line is no sample (its empty cells would be a ragged row).
  CHECK(nlid::read_csv_table(dir.write("two_columns.csv", "u,y\n0,1\n\n1,2\n")).data.rows() == 2);
}

TEST_CASE("read_csv checks the time column", "[data][csv]") {
  TempDir dir;
  auto err = error_of([&] {
    (void)nlid::read_csv(
        dir.write("gap.csv", "t,u,y\n0,0,0\n0.001,0,0\n0.002,0,0\n0.004,0,0\n0.005,0,0\n"));
  });
  CHECK_THAT(err.what(), Contains("non-uniform time column"));
  CHECK_THAT(err.what(), Contains("from row 4"));
  CHECK(err.where().row == 5);
  CHECK(err.where().column_name == "t");

  err =
      error_of([&] { (void)nlid::read_csv(dir.write("dec.csv", "t,u,y\n0,0,0\n1,0,0\n1,0,0\n")); });
  CHECK_THAT(err.what(), Contains("time column is not increasing: t = 1 follows t = 1 on row 3"));
  CHECK(err.where().row == 4);

  err = error_of([&] { (void)nlid::read_csv(dir.write("one.csv", "t,u,y\n0,0,0\n")); });
  CHECK_THAT(err.what(), Contains("too few rows to infer the sample time"));

  err = error_of([&] { (void)nlid::read_csv(dir.write("nant.csv", "t,u,y\n0,0,0\nnan,0,0\n")); });
  CHECK_THAT(err.what(), Contains("non-finite time stamp 'nan'"));

  nlid::CsvReadOptions neg;
  neg.ts = -0.1;
  err = error_of([&] { (void)nlid::read_csv(dir.write("ok.csv", "t,u,y\n0,0,0\n1,0,0\n"), neg); });
  CHECK_THAT(err.what(), Contains("sample time override must be positive"));
  CHECK(err.where().parameter == "ts");

  // Jitter within the 1 % tolerance is accepted; the sample time is the mean step.
  const nlid::Experiment j =
      nlid::read_csv(dir.write("jit.csv", "t,u,y\n0,0,0\n1.004,0,0\n1.998,0,0\n3,0,0\n"));
  CHECK(j.ts() == Approx(1.0));
  nlid::CsvReadOptions strict;
  strict.time_tolerance = 1e-3;
  CHECK_THROWS_WITH(
      nlid::read_csv(dir.file("jit.csv"), strict),
      Contains("step 1.004 from row 2 deviates by 0.2 % from the typical step 1.002"));
}

// A logger that prints time stamps with fixed decimals: no double reproduces such a column, and
// the endpoint estimate of ts depends on which rows a file holds (for 51.2 kHz at 8 decimals,
// 0.39 s of samples are off by 1.3e-8 relative), so two slices of one recording could not be put
// into one Dataset. The reader takes the shortest sample time or rate that reproduces every stamp
// to within the printing resolution.
TEST_CASE("read_csv recovers the sample time from time stamps rounded to fixed decimals", "[data][csv]") {
  TempDir dir;
  // time stamp k: k / rate for rate > 0, else k · (−rate) (a sample time)
  auto write = [&](const std::string& name, long first, long count, double rate, int decimals) {
    std::ostringstream os;
    os << "t,u,y\n";
    char buf[64];
    for (long k = first; k < first + count; ++k) {
      const double tk = rate > 0 ? static_cast<double>(k) / rate : static_cast<double>(k) * -rate;
      std::snprintf(buf, sizeof buf, "%.*f", decimals, tk);
      os << buf << "," << 0.001 * static_cast<double>(k % 17) << "," << 0.5 << "\n";
    }
    return dir.write(name, os.str());
  };
  SECTION("a rate: 51.2 kHz printed with 8 decimals, two slices of one record") {
    const nlid::Experiment a = nlid::read_csv(write("a.csv", 0, 85200, 51200.0, 8));
    const nlid::Experiment b = nlid::read_csv(write("b.csv", 85200, 20000, 51200.0, 8));
    CHECK(a.ts() == 1.0 / 51200.0);
    CHECK(b.ts() == 1.0 / 51200.0);
    CHECK(b.t0() == 1.6640625);
    nlid::Dataset d;
    d.add(a);
    CHECK_NOTHROW(d.add(b));
  }
  SECTION("a sample time: 1.2345 ms printed with 5 decimals") {
    const nlid::Experiment e = nlid::read_csv(write("c.csv", 3, 4000, -0.0012345, 5));
    CHECK(e.ts() == 0.0012345);
    CHECK(e.t0() == 0.0037);  // 3 · 1.2345 ms = 0.0037035, printed as 0.00370
  }
  SECTION("300 Hz printed with 6 decimals: a rate with no short decimal sample time") {
    const nlid::Experiment e = nlid::read_csv(write("d.csv", 0, 5000, 300.0, 6));
    CHECK(e.ts() == 1.0 / 300.0);
  }
  SECTION("a grid off by more than the printing resolution is not snapped") {
    // 1000.3 Hz at 6 decimals: the stamps rule out 1 kHz (3000 samples drift by 0.9 ms); the
    // shortest sample time they allow, 0.0009997, is 1e-7 relative from 1/1000.3
    std::ostringstream os;
    os << "t,u,y\n";
    for (int k = 0; k < 3000; ++k) {
      char buf[64];
      std::snprintf(buf, sizeof buf, "%.6f", k / 1000.3);
      os << buf << ",0,0\n";
    }
    const nlid::Experiment e = nlid::read_csv(dir.write("e.csv", os.str()));
    CHECK(e.ts() == 0.0009997);
    CHECK(e.ts() == Approx(1.0 / 1000.3).epsilon(2e-7));
  }
}

// A logger whose clock is read at every sample: the stamps jitter around k·T_s, no short grid
// reproduces them, and the endpoint estimate (t_last − t0)/(N − 1) is off by up to 2J/(N − 1).
// Two such records of one 100 Hz logger read 0.00999988... and 0.00999992... (3e-6 apart): they
// could not form one Dataset, and a model estimated on one refused the other's rate.
TEST_CASE("read_csv takes the sample time jittering stamps were logged at", "[data][csv]") {
  TempDir dir;
  auto write = [&](const std::string& name, unsigned seed, int count, double ts, double jitter, int late = -1) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> e(-jitter, jitter);
    std::ostringstream os;
    os << "t,u,y\n";
    char buf[64];
    for (int k = 0; k < count; ++k) {
      std::snprintf(buf, sizeof buf, "%.9f", k * ts + e(rng) + (k == late ? 0.4 * ts : 0.0));
      os << buf << "," << 0.01 * (k % 7) << ",1\n";
    }
    return dir.write(name, os.str());
  };
  nlid::CsvReadOptions o;
  o.time_tolerance = 0.05;
  const nlid::Experiment a = nlid::read_csv(write("a.csv", 5u, 400, 0.01, 2e-4), o);
  const nlid::Experiment b = nlid::read_csv(write("b.csv", 6u, 400, 0.01, 2e-4), o);
  CHECK(a.ts() == 0.01);
  CHECK(b.ts() == 0.01);
  nlid::Dataset d;
  d.add(a);
  CHECK_NOTHROW(d.add(b));
  // A rate the stamps rule out is not taken. 99.9 Hz with one stamp 0.4 T late (accepted by a
  // 0.5 tolerance): the other stamps are exact, so 100 Hz is 0.4 T off by the record's end. And
  // 99.3 Hz under +-2 ms jitter, 100 samples: 0.01 drifts 0.7 T over the record. (A snap to
  // anything within twice the largest deviation over N - 1 took 0.01 in both.)
  o.time_tolerance = 0.5;
  const nlid::Experiment c = nlid::read_csv(write("c.csv", 7u, 400, 1.0 / 99.9, 0.0, 200), o);
  CHECK(c.ts() == Approx(1.0 / 99.9).epsilon(1e-9));
  for (unsigned seed = 1; seed <= 5; ++seed) {
    CAPTURE(seed);
    const nlid::Experiment h = nlid::read_csv(write("h.csv", seed, 100, 1.0 / 99.3, 2e-3), o);
    CHECK(std::abs(h.ts() - 0.01) > 5e-5);
    CHECK(h.ts() == Approx(1.0 / 99.3).epsilon(2e-3));
  }
  o.time_tolerance = 0.05;
  // Records of different rates still differ, and the hint for nearly equal ones names the remedy.
  const nlid::Experiment f = nlid::read_csv(write("f.csv", 8u, 400, 0.0101, 1e-6), o);
  CHECK(f.ts() == Approx(0.0101).epsilon(1e-6));
  CHECK_THROWS_WITH(d.add(f), Contains("relative difference 0.01)") && !Contains("set that sample time"));
  const nlid::Experiment g = nlid::read_csv(write("g.csv", 9u, 400, 0.0100001, 1e-8), o);
  CHECK_THROWS_WITH(d.add(g), Contains("if both were logged at one rate, set that sample time (CsvReadOptions::ts)"));
}

TEST_CASE("write_csv refuses unreadable headers and bad paths", "[data][csv]") {
  TempDir dir;
  nlid::Experiment e(Eigen::MatrixXd::Zero(3, 1), Eigen::MatrixXd::Zero(3, 1), 1.0);
  e.set_input_names({"t"});
  CHECK_THROWS_WITH(nlid::write_csv(dir.file("x.csv"), e), Contains("duplicate column name 't'"));
  e.set_input_names({""});
  CHECK_THROWS_WITH(nlid::write_csv(dir.file("x.csv"), e), Contains("empty name"));
  e.set_input_names({"u"});
  CHECK_THROWS_WITH(nlid::write_csv(dir.file("no/such/dir/x.csv"), e),
                    Contains("directory does not exist"));
  CHECK_FALSE(fs::exists(dir.file("x.csv")));
  nlid::write_csv(dir.file("x.csv"), e, {"time", ';'});
  nlid::CsvReadOptions o;
  o.time_column = "time";
  o.delimiter = ';';
  CHECK(nlid::read_csv(dir.file("x.csv"), o).size() == 3);
}

TEST_CASE("read_csv: control bytes are shown escaped, underflow reads as the nearest double, bad options are named",
          "[data][csv][errors]") {
  TempDir dir;
  const std::string nul = dir.write("nul.csv", std::string("t,u,y\n0,1,2\n0.001,1,2\0x\n", 24));
  const nlid::Error e = error_of([&] { (void)nlid::read_csv(nul); });
  // The whole message survives (a raw NUL ended it after "cell '2"): cell, file and row.
  CHECK_THAT(e.what(), Contains("non-numeric cell '2\\x00x'") && Contains("nul.csv") && Contains("row 3"));
  // A Latin-1 header ("Winkel°" as the byte B0) is shown with that byte escaped: the raw byte made
  // the message malformed UTF-8, and a report that carries the message could not be written.
  const std::string latin1 = dir.write("latin1.csv", "t,u,Winkel\xB0\n0,1,2\n0.001,1,2\n");
  const nlid::Error l1 = error_of([&] { (void)nlid::read_csv(latin1); });  // no column 'y
  CHECK_THAT(l1.what(), Contains("'Winkel\\xB0'"));
  CHECK(nlid::first_invalid_utf8(l1.what()) == std::string::npos);
  // A long name is cut between characters, never inside one, and only when something is left out.
  CHECK(nlid::detail::printable(std::string(79, 'a') + "\xC3\xA9\xC3\xA9") == std::string(79, 'a') + "\xC3\xA9...");
  CHECK(nlid::detail::printable(std::string(80, 'a')) == std::string(80, 'a'));

  const std::string tiny = dir.write("tiny.csv", "t,u,y\n0,1e-400,2\n0.001,1,2\n0.002,1,3\n");
  const nlid::Experiment ex = nlid::read_csv(tiny);
  CHECK(ex.u()(0, 0) == 0.0);
  const std::string huge = dir.write("huge.csv", "t,u,y\n0,1e400,2\n0.001,1,2\n0.002,1,3\n");
  CHECK_THROWS_WITH(nlid::read_csv(huge), Contains("number out of the range of double: '1e400'"));

  nlid::CsvReadOptions o;
  o.max_gap = -5;
  CHECK_THROWS_WITH(nlid::read_csv(tiny, o), Contains("max_gap must be >= 0") && Contains("max_gap"));
  o = {};
  o.delimiter = '\0';
  CHECK_THROWS_WITH(nlid::read_csv(tiny, o), Contains("delimiter must be a printable separator"));
  o = {};
  o.decimal_point = ',';
  CHECK_THROWS_WITH(nlid::read_csv(tiny, o), Contains("decimal_point and delimiter are both ','"));
  nlid::CsvTableOptions to;
  to.decimal_point = ':';
  CHECK_THROWS_WITH(nlid::read_csv_table(tiny, to), Contains("decimal_point must be '.' or ','"));
}

TEST_CASE("read_csv: Unix-time stamps with a short step round-trip, and a dropped sample is still caught",
          "[data][csv]") {
  TempDir dir;
  // One ulp of 1.7e9 is 2.4e-7 s, 2.4 % of the step: the steps of the written column jitter by
  // that much, beyond the 1 % tolerance, though every stamp is as exact as a double can be.
  Eigen::MatrixXd u(200, 1), y(200, 1);
  for (Eigen::Index k = 0; k < 200; ++k) u(k, 0) = std::sin(0.1 * static_cast<double>(k)), y(k, 0) = 0.5 * u(k, 0);
  nlid::Experiment e(u, y, 1e-5, "unix");
  e.set_t0(1.7e9);
  const std::string path = dir.file("unix.csv");
  nlid::write_csv(path, e);
  const nlid::Experiment back = nlid::read_csv(path);
  CHECK(back.ts() == 1e-5);
  CHECK(back.t0() == e.t0());
  CHECK(back.u() == e.u());
  CHECK(back.y() == e.y());

  // The same column with row 100 left out.
  std::string text = "t,u,y\n";
  for (Eigen::Index k = 0; k < 200; ++k) {
    if (k == 100) continue;
    text += nlid::detail::format_double(e.time()(k)) + ",0,0\n";
  }
  const nlid::Error err = error_of([&] { (void)nlid::read_csv(dir.write("gap.csv", text)); });
  CHECK_THAT(err.what(), Contains("non-uniform time column") && Contains("from row 101"));
  CHECK(err.where().row == 102);
  nlid::CsvReadOptions o;
  o.ts = 1e-5;
  CHECK_THROWS_WITH(nlid::read_csv(dir.file("gap.csv"), o), Contains("non-uniform time column"));
}

TEST_CASE("read_csv: time stamps too far apart for a double are named, not passed on", "[data][csv][errors]") {
  TempDir dir;
  const std::string p = dir.write("far.csv", "t,u,y\n-1e308,0,0\n1e308,0,0\n");
  const nlid::Error err = error_of([&] { (void)nlid::read_csv(p); });
  CHECK_THAT(err.what(), Contains("spans more than the largest double"));
  CHECK(err.where().file == p);
  CHECK(err.where().row == 3);
  CHECK(err.where().column_name == "t");
  const std::string q = dir.write("far3.csv", "t,u,y\n-1e308,0,0\n0,0,0\n1e308,0,0\n");
  CHECK(error_of([&] { (void)nlid::read_csv(q); }).where().file == q);
}

TEST_CASE("read_csv_table refuses a file whose first row is numbers: it has no header", "[data][csv][errors]") {
  TempDir dir;
  const std::string p = dir.write("bare.csv", "1,2\n3,4\n");
  nlid::Error err = error_of([&] { (void)nlid::read_csv_table(p); });
  CHECK_THAT(err.what(), Contains("seems to have no header row") && Contains("'1', '2'"));
  CHECK(err.where().file == p);
  CHECK(err.where().row == 1);
  nlid::CsvTableOptions numeric;
  numeric.numeric_header = true;
  const nlid::CsvTable t = nlid::read_csv_table(p, numeric);
  CHECK(t.header == std::vector<std::string>{"1", "2"});
  CHECK(t.data.rows() == 1);

  // numpy.savetxt(header="t u y") writes "# t u y": the header is a comment.
  const std::string np = dir.write("np.txt", "# t u y\n0.0 1.5 2.5\n1.0e-03 1.5 2.5\n");
  nlid::CsvTableOptions blank;
  blank.delimiter = ' ';
  err = error_of([&] { (void)nlid::read_csv_table(np, blank); });
  CHECK_THAT(err.what(), Contains("no header row") && Contains("numpy.savetxt"));
  CHECK(err.where().row == 2);
  nlid::CsvReadOptions ro;
  ro.delimiter = ' ';
  CHECK_THROWS_WITH(nlid::read_csv(np, ro), Contains("no header row"));
  // Names that are partly numbers are names.
  CHECK(nlid::read_csv_table(dir.write("mixed.csv", "t,1\n0,2\n")).data.rows() == 1);
}

TEST_CASE("write_csv_table refuses names its reader would refuse or misread, before writing", "[data][csv][errors]") {
  TempDir dir;
  const Eigen::MatrixXd m = Eigen::MatrixXd::Ones(2, 2);
  const std::string path = dir.file("w.csv");
  nlid::Error err = error_of([&] { nlid::write_csv_table(path, {"a", "a"}, m); });
  CHECK_THAT(err.what(), Contains("duplicate column name 'a' (also column 1)"));
  CHECK(err.where().column == 2);
  CHECK(err.where().file == path);
  err = error_of([&] { nlid::write_csv_table(path, {"a", ""}, m); });
  CHECK_THAT(err.what(), Contains("column 2 has an empty name"));
  CHECK_THROWS_WITH(nlid::write_csv_table(path, {"a", "b\nc"}, m), Contains("line break"));
  CHECK_THROWS_WITH(nlid::write_csv_table(path, {"a", "b"}, m, '"'), Contains("delimiter must be"));
  CHECK_FALSE(fs::exists(path));

  // With blank runs as the separator, names with a blank or a tab inside are quoted.
  nlid::write_csv_table(path, {"a b", "c\td"}, m, ' ');
  nlid::CsvTableOptions o;
  o.delimiter = ' ';
  const nlid::CsvTable t = nlid::read_csv_table(path, o);
  CHECK(t.header == std::vector<std::string>{"a b", "c\td"});
  CHECK(t.data == m);
}

TEST_CASE("header names with control bytes are shown escaped in every message", "[data][csv][errors]") {
  TempDir dir;
  const std::string nul(1, '\0');
  // A C-string view of what() ends at a raw NUL; the location comes last, so it must survive.
  const auto whole = [](const nlid::Error& e) {
    return std::string(e.what()).size() == std::char_traits<char>::length(e.what());
  };
  const std::string dup = dir.write("dup.csv", "t,a" + nul + "b,a" + nul + "b\n0,1,2\n1,1,2\n");
  nlid::Error err = error_of([&] { (void)nlid::read_csv_table(dup); });
  CHECK(whole(err));
  CHECK_THAT(err.what(), Contains("duplicate column name 'a\\x00b'") && Contains("dup.csv"));

  const std::string two = dir.write("two.csv", "t,a" + nul + "b,y\n0,1,2\n1,1,2\n");
  nlid::CsvReadOptions o;
  o.inputs = {"a" + nul + "b"};
  o.outputs = {"a" + nul + "b"};
  err = error_of([&] { (void)nlid::read_csv(two, o); });
  CHECK(whole(err));
  CHECK_THAT(err.what(), Contains("'a\\x00b' is requested twice") && Contains("two.csv"));

  err = error_of([&] { (void)nlid::read_csv(two); });  // no column 'u': the list shows the NUL name
  CHECK(whole(err));
  CHECK_THAT(err.what(), Contains("'t', 'a\\x00b', 'y'") && Contains("two.csv"));

  const nlid::CsvTable t = nlid::read_csv_table(two);
  err = error_of([&] { (void)t.column("q" + nul + "r"); });
  CHECK(whole(err));
  CHECK_THAT(err.what(), Contains("no column named 'q\\x00r'") && Contains("two.csv"));
}

TEST_CASE("read_csv_dataset names the file whose record does not fit", "[data][csv][errors]") {
  TempDir dir;
  fs::create_directories(dir.path / "a");
  fs::create_directories(dir.path / "b");
  const std::string first = dir.write("a/run.csv", "t,u,y\n0,0,0\n0.01,0,0\n0.02,0,0\n");
  const std::string second = dir.write("b/run.csv", "t,u,y\n0,0,0\n0.02,0,0\n0.04,0,0\n");
  const nlid::Error err = error_of([&] { (void)nlid::read_csv_dataset({first, second}); });
  CHECK_THAT(err.what(), Contains("sample time"));
  CHECK(err.where().file == second);
  CHECK(err.where().experiment == 1);
}

TEST_CASE("read_csv: a file name that is not valid UTF-8 gives a valid UTF-8 experiment name", "[data][csv]") {
  // A Latin-1 name (0xE4 = a-umlaut): model files and reports hold UTF-8 only, so a raw name
  // made saving fail after a whole estimation. Each invalid byte becomes U+FFFD.
  const TempDir dir;
  const std::string path = dir.write("mess\xE4ung.csv", "t,u,y\n0,1,2\n0.1,2,3\n0.2,3,4\n");
  const nlid::Experiment e = nlid::read_csv(path);
  CHECK(e.name() == "mess\xEF\xBF\xBDung");
  CHECK(nlid::first_invalid_utf8(e.name()) == std::string::npos);
  // Valid UTF-8 is kept as it is.
  CHECK(nlid::read_csv(dir.write("mess\xC3\xA4ung.csv", "t,u,y\n0,1,2\n0.1,2,3\n")).name() == "mess\xC3\xA4ung");
  CHECK(nlid::valid_utf8("a\xFF\xC3") == "a\xEF\xBF\xBD\xEF\xBF\xBD");
  CHECK(nlid::first_invalid_utf8("ab\xE4") == 2u);
}

TEST_CASE("write_csv_table quotes a first name that starts with a byte-order mark", "[data][csv]") {
  // Found by tests/fuzz/csv_fuzz.cpp: written bare as the file's first bytes, the BOM of such a
  // name was stripped on reading, so the column came back as "" (or "x" for "\xEF\xBB\xBFx").
  TempDir dir;
  const std::string path = dir.file("bom.csv");
  const Eigen::MatrixXd m = Eigen::MatrixXd::Ones(2, 2);
  for (const std::string& name : {std::string("\xEF\xBB\xBF"), std::string("\xEF\xBB\xBFx")}) {
    nlid::write_csv_table(path, {name, "b"}, m);
    const nlid::CsvTable t = nlid::read_csv_table(path);
    CHECK(t.header == std::vector<std::string>{name, "b"});
    CHECK(t.data == m);
  }
}

TEST_CASE("read_csv reads the same numbers and sample time under a locale with decimal commas", "[data][csv]") {
  // strtod (which read cells below the smallest double) and snprintf (which rounded sample-time
  // candidates) follow LC_NUMERIC: under de_DE "1.5e-400" read as 1, and a sample time printed
  // with fixed decimals was not recovered. The test build makes the locale (NLID_TEST_LOCPATH).
  TempDir dir;
  std::ostringstream os;
  os << "t,u,y\n";
  for (int k = 0; k < 2000; ++k) {
    const char* u = k == 0 ? "1.5e-400" : k == 1 ? "-2.5e-400" : "0.25";
    os << std::fixed << std::setprecision(8) << k / 51200.0 << "," << u << ",0.5\n";
  }
  const std::string path = dir.write("rate.csv", os.str());
  const nlid::Experiment in_c = nlid::read_csv(path);
  REQUIRE(in_c.ts() == 1.0 / 51200.0);

  const nlid_test::DecimalCommaLocale comma;
  if (nlid_test::DecimalCommaLocale::required()) REQUIRE(comma.active());
  if (!comma.active()) {
    WARN("no locale with decimal commas installed: not checked");
    return;
  }
  const nlid::Experiment e = nlid::read_csv(path);
  CHECK(e.u()(0, 0) == 0.0);
  CHECK_FALSE(std::signbit(e.u()(0, 0)));
  CHECK(e.u()(1, 0) == 0.0);
  CHECK(std::signbit(e.u()(1, 0)));
  CHECK(e.ts() == in_c.ts());
}

TEST_CASE("a header of 100 000 columns is checked for repeated names in linear time", "[data][csv]") {
  // Each name was compared with every earlier one: 5e9 comparisons, 17 s to read such a file
  // (and as long to write it); a name index takes well under a second even in a sanitizer build.
  TempDir dir;
  const std::size_t m = 100000;
  std::vector<std::string> names(m);
  for (std::size_t j = 0; j < m; ++j) names[j] = "channel_" + std::to_string(j);
  const Eigen::MatrixXd data = Eigen::MatrixXd::Zero(1, static_cast<Eigen::Index>(m));
  const std::string path = dir.file("wide.csv");
  const auto start = std::chrono::steady_clock::now();
  nlid::write_csv_table(path, names, data);
  const nlid::CsvTable t = nlid::read_csv_table(path);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  CHECK(t.header == names);
  CHECK(seconds < 3.0);

  names.back() = names.front();
  nlid::Error err = error_of([&] { nlid::write_csv_table(path, names, data); });
  CHECK_THAT(err.what(), Contains("duplicate column name 'channel_0' (also column 1)"));
  CHECK(err.where().column == static_cast<long>(m));
  std::string text = "channel_0";
  for (std::size_t j = 1; j < m; ++j) text += ",channel_" + std::to_string(j == m - 1 ? 1 : j);
  err = error_of([&] { (void)nlid::read_csv_table(dir.write("dup.csv", text + "\n" + text + "\n")); });
  CHECK_THAT(err.what(), Contains("duplicate column name 'channel_1' (also column 2)"));
  CHECK(err.where().column == static_cast<long>(m));

  // write_csv's own check shows a repeated channel name escaped, as every other message does.
  nlid::Experiment e(Eigen::MatrixXd::Zero(2, 1), Eigen::MatrixXd::Zero(2, 1), 1.0);
  e.set_input_names({std::string("a\0b", 3)});
  e.set_output_names({std::string("a\0b", 3)});
  err = error_of([&] { nlid::write_csv(path, e); });
  CHECK_THAT(err.what(), Contains("duplicate column name 'a\\x00b' (also column 2)"));
}

TEST_CASE("write_csv refuses a time grid that read_csv would refuse, rather than write it", "[data][csv][errors]") {
  // Found by tests/fuzz/csv_fuzz.cpp: a time column 1e17, 2e17 read with the override ts = 0.5
  // gives t0 = 1e17, and t0 + k*0.5 rounds to 1e17 for every k (doubles there are 16 apart):
  // write_csv wrote a constant time column that read_csv then refused as not increasing.
  TempDir dir;
  nlid::CsvReadOptions o;
  o.ts = 0.5;
  const nlid::Experiment e = nlid::read_csv(dir.write("big.csv", "t,u,y\n1e17,0,0\n2e17,0,0\n"), o);
  const std::string out = dir.file("out.csv");
  nlid::Error err = error_of([&] { nlid::write_csv(out, e); });
  CHECK_THAT(err.what(), Contains("t0 = 1e+17, ts = 0.5") && Contains("not evenly spaced doubles from sample 1"));
  CHECK(err.where().file == out);
  CHECK(err.where().column_name == "t");
  CHECK_FALSE(fs::exists(out));

  // Stamps that increase but step unevenly (1e16 + k*1.5 rounds to steps of 2 and 0 or 4), a grid
  // beyond the largest double, and a record without samples are refused too.
  const Eigen::MatrixXd z = Eigen::MatrixXd::Zero(8, 1);
  nlid::Experiment uneven(z, z, 1.5);
  uneven.set_t0(1e16);
  CHECK_THROWS_WITH(nlid::write_csv(out, uneven), Contains("not evenly spaced"));
  nlid::Experiment huge(z, z, 1e308);
  huge.set_t0(-1e308);
  CHECK_THROWS_WITH(nlid::write_csv(out, huge), Contains("not evenly spaced"));
  const nlid::Experiment none(Eigen::MatrixXd::Zero(0, 1), Eigen::MatrixXd::Zero(0, 1), 1.0);
  CHECK_THROWS_WITH(nlid::write_csv(out, none), Contains("no samples"));
  CHECK_FALSE(fs::exists(out));

  // A grid the doubles resolve still round-trips: Unix time at 1 MHz.
  nlid::Experiment unix_time(Eigen::MatrixXd::Zero(1000, 1), Eigen::MatrixXd::Zero(1000, 1), 1e-6);
  unix_time.set_t0(1.7e9);
  nlid::write_csv(out, unix_time);
  const nlid::Experiment back = nlid::read_csv(out);
  CHECK(back.t0() == unix_time.t0());
  CHECK(back.size() == 1000);
}

TEST_CASE("read_csv with decimal commas refuses a number holding a '.'", "[data][csv][errors]") {
  // Such a '.' was read as a decimal point: "1.234" (German for 1234) as 1.234, and time stamps
  // 0.123, 0.246, ... were snapped to ts = 0.1 (their resolution was counted at the commas only,
  // so taken as whole seconds), 19 % off, without a word.
  TempDir dir;
  nlid::CsvReadOptions o;
  o.delimiter = ';';
  o.decimal_point = ',';
  const std::string stamps = dir.write("stamps.csv", "t;u;y\n0;0;0\n0.123;0;0\n0.246;0;0\n0.369;0;0\n0.493;0;0\n");
  nlid::Error err = error_of([&] { (void)nlid::read_csv(stamps, o); });
  CHECK_THAT(err.what(), Contains("number '0.123' has a '.' but the decimal point is ','"));
  CHECK(err.where().row == 3);
  CHECK(err.where().column == 1);
  err = error_of([&] { (void)nlid::read_csv(dir.write("k.csv", "t;u;y\n0;1,5;1.234\n1;2;3\n"), o); });
  CHECK_THAT(err.what(), Contains("number '1.234' has a '.'"));
  CHECK(err.where().column_name == "y");
  // Text with a '.' is still just not a number; with decimal points such a file reads.
  err = error_of([&] { (void)nlid::read_csv(dir.write("x.csv", "t;u;y\n0;1;a.b\n1;2;3\n"), o); });
  CHECK_THAT(err.what(), Contains("non-numeric cell 'a.b'"));
  nlid::CsvReadOptions dots;
  dots.delimiter = ';';
  CHECK(nlid::read_csv(stamps, dots).ts() == 0.123);
}
