#include "nlid/io/svg_chart.hpp"

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <catch2/catch.hpp>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <map>
#include <set>
#include <string>
#include <system_error>
#include <vector>

#include "nlid/core/atomic_file.hpp"

namespace {

struct Point {
  double x, y;
};

// The polylines of every series path in `svg`: "M x,y L x,y x,y M x,y ..." -> runs of points.
std::vector<std::vector<std::vector<Point>>> series_paths(const std::string& svg) {
  std::vector<std::vector<std::vector<Point>>> out;
  // (std::regex recurses per character in libstdc++ and overflows the stack on 1e5 points.)
  const std::string tag = "<path class=\"nlid-series\"";
  for (std::size_t at = svg.find(tag); at != std::string::npos; at = svg.find(tag, at + 1)) {
    const std::size_t b = svg.find(" d=\"", at) + 4;
    const std::string d = svg.substr(b, svg.find('"', b) - b);
    std::vector<std::vector<Point>> runs;
    std::size_t i = 0;
    while (i < d.size()) {
      if (d[i] == 'M') runs.emplace_back();
      if (d[i] == 'M' || d[i] == 'L' || d[i] == ' ') {
        ++i;
        continue;
      }
      if (d[i] == 'l') break;  // isolated-point marker
      double x = 0, y = 0;
      const char* end = d.data() + d.size();
      auto r = std::from_chars(d.data() + i, end, x);
      if (r.ec != std::errc() || r.ptr == end || *r.ptr != ',') FAIL("bad path data at " << i);
      r = std::from_chars(r.ptr + 1, end, y);
      if (r.ec != std::errc()) FAIL("bad path data at " << i);
      runs.back().push_back({x, y});
      i = static_cast<std::size_t>(r.ptr - d.data());
    }
    out.push_back(std::move(runs));
  }
  return out;
}

std::size_t count(const std::string& s, const std::string& what) {
  std::size_t n = 0;
  for (std::size_t p = s.find(what); p != std::string::npos; p = s.find(what, p + 1)) ++n;
  return n;
}

}  // namespace

TEST_CASE("Nice ticks are 1-2-5 steps with the decimals the step needs") {
  auto t = nlid::detail::nice_ticks(0, 10, 5);
  CHECK(t.step == 2);
  CHECK(t.values == std::vector<double>{0, 2, 4, 6, 8, 10});
  t = nlid::detail::nice_ticks(14.2, 91.3, 5);
  CHECK(t.step == 20);
  CHECK(t.values == std::vector<double>{20, 40, 60, 80});
  t = nlid::detail::nice_ticks(-0.013, 0.027, 4);
  CHECK(t.step == Approx(0.01));
  REQUIRE(t.values.size() == 4);
  CHECK(t.values[1] == 0.0);  // exactly zero, not 1e-18
  CHECK(nlid::detail::format_tick(t.values[0], t.step, 0.027) == "-0.01");
  CHECK(nlid::detail::format_tick(0.1 + 0.2, 0.1, 1) == "0.3");
  CHECK(nlid::detail::format_tick(20, 20, 91) == "20");
  CHECK(nlid::detail::format_tick(2.5e6, 5e5, 3e6) == "2.5e+06");
  CHECK(nlid::detail::format_tick(-0.0, 0.5, 1) == "0.0");
  CHECK(nlid::detail::nice_ticks(3, 3, 5).values.empty());  // degenerate span: no ticks, no loop
}

TEST_CASE("Nice ticks on a narrow range far from zero are distinct, with distinct labels") {
  // The span is far below what 15 significant digits resolve at 1e17: the step must not be.
  const auto t = nlid::detail::nice_ticks(1e17 - 2, 1e17 + 34, 5);
  REQUIRE_FALSE(t.values.empty());
  CHECK(t.values.size() < 10);
  for (std::size_t i = 1; i < t.values.size(); ++i) CHECK(t.values[i] > t.values[i - 1]);
  nlid::LineChart c;
  c.line("y", std::vector<double>{1e17, 1e17 + 16, 1e17 + 32});
  const std::string s = c.svg();
  std::vector<std::string> labels;  // y tick labels are the end-anchored texts
  const std::string marker = "text-anchor=\"end\">";
  for (std::size_t p = s.find(marker); p != std::string::npos; p = s.find(marker, p + 1)) {
    const std::size_t b = p + marker.size();
    labels.push_back(s.substr(b, s.find('<', b) - b));
  }
  REQUIRE_FALSE(labels.empty());
  CHECK(labels.size() < 10);
  std::vector<std::string> unique = labels;
  std::sort(unique.begin(), unique.end());
  CHECK(std::unique(unique.begin(), unique.end()) == unique.end());
}

TEST_CASE("Line chart: axes, legend, shading, band, output is deterministic") {
  std::vector<double> t, y, yhat;
  for (int k = 0; k <= 200; ++k) {
    t.push_back(k * 0.05);
    y.push_back(15 + 70 * (k > 50));
    yhat.push_back(15 + 68 * (k > 52));
  }
  nlid::LineChart c("Validation on data3");
  c.x_label("time (s)").y_label("angle (deg)");
  c.line("measured", t, y).line("nlarx5 (fit 93.1 %)", t, yhat, "#000", nlid::LineStyle::dashed, 2);
  c.shade(4.0, 3.0, "mismatch").band(90, 100, "hard stop");
  const std::string svg = c.svg();

  CHECK(
      svg.rfind(
          R"(<svg xmlns="http://www.w3.org/2000/svg" class="nlid-chart" width="720" height="360")",
          0) == 0);
  CHECK(svg.find("<title>Validation on data3</title>") != std::string::npos);
  CHECK(svg.find(">time (s)</text>") != std::string::npos);
  CHECK(svg.find(">angle (deg)</text>") != std::string::npos);
  CHECK(svg.find(">nlarx5 (fit 93.1 %)</text>") != std::string::npos);
  CHECK(svg.find(">mismatch</text>") != std::string::npos);
  CHECK(svg.find(">hard stop</text>") != std::string::npos);
  CHECK(svg.find(R"(stroke="#000" stroke-width="2")") != std::string::npos);
  CHECK(svg.find(R"(stroke-dasharray="6 4")") != std::string::npos);
  CHECK(svg.find(R"(stroke="#1f77b4")") != std::string::npos);  // first palette colour
  // x ticks 0..10 step 2 (tight axis), y axis covers 15..100 plus padding with nice steps of 20.
  for (const char* label : {">0</text>", ">2</text>", ">10</text>", ">20</text>", ">100</text>"}) {
    CHECK(svg.find(label) != std::string::npos);
  }
  CHECK(count(svg, "<text") == count(svg, "</text>"));
  CHECK(count(svg, "<svg") == count(svg, "</svg>"));
  CHECK(c.svg() == svg);  // deterministic
  const auto paths = series_paths(svg);
  REQUIRE(paths.size() == 2);
  CHECK(paths[0].size() == 1);
  CHECK(paths[0][0].size() == 201);  // short series are drawn point for point
  // The first point sits on the left edge of the plot box, the last on the right edge.
  CHECK(paths[0][0].front().x < paths[0][0].back().x);
  CHECK(paths[0][0].back().x == 704);  // width 720 - right margin 16
}

TEST_CASE("Decimation keeps per-pixel extremes, so spikes survive and files stay small") {
  const std::size_t n = 100000;
  std::vector<double> x(n), y(n);
  for (std::size_t k = 0; k < n; ++k) {
    x[k] = static_cast<double>(k) * 1e-4;
    y[k] = std::sin(x[k] * 37.0) + 0.3 * std::sin(x[k] * 2100.0);
  }
  y[54321] = 5.0;   // a one-sample spike
  y[77777] = -4.0;  // and a one-sample dip
  nlid::LineChart full, dec;
  full.line("trace", x, y).decimate(false);
  dec.line("trace", x, y);
  const std::string s_full = full.svg(), s_dec = dec.svg();
  CHECK(s_dec.size() < 60000);
  CHECK(s_full.size() > 10 * s_dec.size());
  const auto p_full = series_paths(s_full), p_dec = series_paths(s_dec);
  REQUIRE(p_full.size() == 1);
  REQUIRE(p_dec.size() == 1);
  CHECK(p_full[0][0].size() == n);
  CHECK(p_dec[0][0].size() < 4 * 720);
  CHECK(s_dec.find("data-samples=\"100000\"") != std::string::npos);

  // Per pixel column, the decimated polyline reaches the same min and max as the full one.
  std::map<long, std::pair<double, double>> col_full, col_dec;
  const auto fill = [](const std::vector<Point>& pts,
                       std::map<long, std::pair<double, double>>& m) {
    for (const Point& p : pts) {
      const long c = static_cast<long>(std::floor(p.x));
      auto [it, fresh] = m.try_emplace(c, p.y, p.y);
      if (!fresh) {
        it->second.first = std::min(it->second.first, p.y);
        it->second.second = std::max(it->second.second, p.y);
      }
    }
  };
  fill(p_full[0][0], col_full);
  fill(p_dec[0][0], col_dec);
  // Coordinates are rounded to 0.1 px, so a sample near a column boundary may print in the next
  // column: the extremes of each column of the full drawing must be reached by the decimated
  // drawing within +-1 column, and every decimated point must be a point of the full drawing.
  std::size_t differing = 0;
  for (const auto& [c, mm] : col_full) {
    double lo = INFINITY, hi = -INFINITY;
    for (long k = c - 1; k <= c + 1; ++k) {
      const auto it = col_dec.find(k);
      if (it == col_dec.end()) continue;
      lo = std::min(lo, it->second.first);
      hi = std::max(hi, it->second.second);
    }
    differing += lo > mm.first || hi < mm.second;
  }
  std::set<std::pair<double, double>> full_points;
  for (const Point& p : p_full[0][0]) full_points.emplace(p.x, p.y);
  std::size_t foreign = 0;
  for (const Point& p : p_dec[0][0]) foreign += full_points.count({p.x, p.y}) == 0;
  CHECK(foreign == 0);
  CHECK(col_full.size() > 600);
  CHECK(differing == 0);
  const auto ymin = [](const std::vector<Point>& v) {
    return std::min_element(v.begin(), v.end(), [](Point a, Point b) { return a.y < b.y; })->y;
  };
  const auto ymax = [](const std::vector<Point>& v) {
    return std::max_element(v.begin(), v.end(), [](Point a, Point b) { return a.y < b.y; })->y;
  };
  CHECK(ymin(p_dec[0][0]) == ymin(p_full[0][0]));  // the spike's peak is drawn
  CHECK(ymax(p_dec[0][0]) == ymax(p_full[0][0]));  // and the dip's bottom
}

TEST_CASE("Non-finite samples are gaps and are counted in the legend") {
  std::vector<double> y = {1, 2, std::nan(""), 4, 5, INFINITY, 7};
  nlid::LineChart c;
  c.line("sim", y);
  const std::string svg = c.svg();
  CHECK(svg.find(">sim (2 non-finite samples not drawn)</text>") != std::string::npos);
  const auto p = series_paths(svg);
  REQUIRE(p.size() == 1);
  REQUIRE(p[0].size() == 3);  // three finite runs: [1 2] [4 5] [7]
  CHECK(p[0][0].size() == 2);
  CHECK(p[0][1].size() == 2);
  CHECK(p[0][2].size() == 1);
  CHECK(svg.find(" l0,0") != std::string::npos);  // the lone sample is still visible
}

TEST_CASE("Unsorted x is drawn in full, x_limits clip to the visible part plus one point") {
  std::vector<double> x, y;
  for (int k = 0; k < 10000; ++k) {
    x.push_back(std::cos(k * 0.01));
    y.push_back(std::sin(k * 0.013));
  }
  nlid::LineChart phase;
  phase.line("phase", x, y);
  CHECK(series_paths(phase.svg())[0][0].size() == 10000);

  std::vector<double> t(1000), v(1000);
  for (int k = 0; k < 1000; ++k) t[k] = v[k] = k;
  nlid::LineChart zoom;
  zoom.line("v", t, v).x_limits(100, 199.5);
  const auto p = series_paths(zoom.svg());
  CHECK(p[0][0].size() == 102);  // 99 (one before) ... 200 (one after)
  // The y range follows the visible data, not the whole series.
  CHECK(zoom.svg().find(">900</text>") == std::string::npos);
}

TEST_CASE("All text is escaped, invalid UTF-8 and control characters are replaced") {
  nlid::LineChart c("<script>alert('x')</script>");
  c.x_label("a & b").y_label("\"q\"");
  c.line(std::string("bad \xC3\x28 utf8 \x01 ctl"), std::vector<double>{1, 2},
         std::vector<double>{3, 4}, "red\" onload=\"x");
  const std::string svg = c.svg();
  CHECK(svg.find("<script") == std::string::npos);
  CHECK(svg.find("&lt;script&gt;alert(&#39;x&#39;)&lt;/script&gt;") != std::string::npos);
  CHECK(svg.find(">a &amp; b</text>") != std::string::npos);
  CHECK(svg.find(">&quot;q&quot;</text>") != std::string::npos);
  CHECK(svg.find("bad \xEF\xBF\xBD( utf8 \xEF\xBF\xBD ctl") != std::string::npos);
  CHECK(svg.find("onload=\"") == std::string::npos);
  CHECK(svg.find("red&quot; onload=&quot;x") != std::string::npos);
}

TEST_CASE("Escaping replaces the noncharacters U+FFFE and U+FFFF, which XML 1.0 forbids") {
  CHECK(nlid::detail::escape_xml("a\xEF\xBF\xBF" "b\xEF\xBF\xBE" "c") ==
        "a\xEF\xBF\xBD" "b\xEF\xBF\xBD" "c");
  // Their neighbours are ordinary characters and stay.
  CHECK(nlid::detail::escape_xml("\xEF\xBF\xBD\xEF\xBF\xBC") == "\xEF\xBF\xBD\xEF\xBF\xBC");
}

TEST_CASE("Line chart inputs: Eigen vectors and std::array work, bad input is an error") {
  Eigen::VectorXd t = Eigen::VectorXd::LinSpaced(50, 0, 1);
  Eigen::VectorXd y = t.array().square();
  std::array<double, 3> a{1, 2, 3};
  nlid::LineChart c;
  c.line("eigen", t, y).line("array", a);
  CHECK(c.num_series() == 2);
  CHECK(c.series()[0].y[49] == 1.0);

  CHECK_THROWS_WITH(
      nlid::LineChart().line("sim", std::vector<double>{1, 2, 3}, std::vector<double>{1, 2}),
      "nlid: series 'sim': x has 3 values but y has 2");
  CHECK_THROWS_WITH(nlid::LineChart().line("w", a, a, "", nlid::LineStyle::solid, 0.0),
                    Catch::StartsWith("nlid: series 'w': line width must be in (0, 100) px"));
  CHECK_THROWS_WITH(
      nlid::LineChart().size(100, 50),
      "nlid: chart size must be between 240 x 160 and 20000 x 20000 px, got 100 x 50");
  CHECK_THROWS_WITH(nlid::LineChart().y_limits(2, 1), "nlid: y_limits needs finite lo < hi");
  CHECK_THROWS_WITH(nlid::LineChart().shade(0, NAN, "m"),
                    "nlid: shaded interval 'm' needs finite bounds");
  CHECK_THROWS_WITH(nlid::LineChart().band(INFINITY, 1, "b"),
                    "nlid: horizontal band 'b' needs finite bounds");
  // A legend too big for the chart is reported, not drawn over the plot.
  nlid::LineChart crowded;
  crowded.size(240, 160);
  for (int i = 0; i < 12; ++i) crowded.line("a rather long series name " + std::to_string(i), a);
  CHECK_THROWS_WITH(crowded.svg(), Catch::Contains("too small for its legend"));
}

TEST_CASE("Empty and constant charts still render with sensible axes") {
  const std::string empty = nlid::LineChart("nothing").svg();
  CHECK(empty.find(">no data</text>") != std::string::npos);
  nlid::LineChart flat;
  flat.line("c", std::vector<double>{0, 1, 2}, std::vector<double>{5, 5, 5});
  const std::string s = flat.svg();
  CHECK(s.find("NaN") == std::string::npos);
  CHECK(s.find(">5.0</text>") != std::string::npos);  // range widened around the constant
}

TEST_CASE("Extreme values: a diverged trace or huge offsets never put NaN into the markup") {
  nlid::LineChart diverged;
  diverged.line("sim", std::vector<double>{0, 1, 2}, std::vector<double>{-1e308, 1e308, 0});
  const std::string s = diverged.svg();
  CHECK(s.find("nan") == std::string::npos);
  CHECK(s.find("inf") == std::string::npos);
  CHECK(series_paths(s)[0][0].size() == 3);
  nlid::BarChart bars;
  bars.add("a", 1e308).add("b", -1e308);
  CHECK(bars.svg().find("nan") == std::string::npos);
  CHECK_THROWS_WITH(nlid::LineChart().x_limits(-1e308, 1e308),
                    "nlid: x_limits needs finite lo < hi");

  // Time stamps with a large offset: labels are long, so fewer ticks are used and none overlap.
  nlid::LineChart stamps;
  stamps.line("y", std::vector<double>{1e9, 1e9 + 1e-3}, std::vector<double>{1, 2});
  const std::string t = stamps.svg();
  std::vector<double> tick_x;
  const std::string marker = "\" text-anchor=\"middle\">1000000000";
  for (std::size_t p = t.find(marker); p != std::string::npos; p = t.find(marker, p + 1)) {
    const std::size_t x = t.rfind("<text x=\"", p) + 9;
    tick_x.push_back(std::stod(t.substr(x, t.find('"', x) - x)));
  }
  REQUIRE(tick_x.size() >= 2);
  for (std::size_t i = 1; i < tick_x.size(); ++i) {
    CHECK(tick_x[i] - tick_x[i - 1] > nlid::detail::text_width("1000000000.0002", 11));
  }
}

TEST_CASE("Bar chart: highlight, negative values, missing values, log scale") {
  nlid::BarChart b("Fit on data5 (%)");
  b.value_label("fit (%)").category_label("model");
  b.add("nlarx5", 91.25).add("nlhw2", 89.7).add("arx", -12.5).add("greybox", NAN);
  b.highlight(0);
  const std::string svg = b.svg();
  CHECK(count(svg, "class=\"nlid-bar\"") == 3);
  CHECK(count(svg, "fill=\"#d62728\" class=\"nlid-bar\"") == 1);
  CHECK(svg.find(">91.25</text>") != std::string::npos);
  CHECK(svg.find(">-12.5</text>") != std::string::npos);
  CHECK(svg.find(">n/a</text>") != std::string::npos);
  CHECK(svg.find(">nlarx5</text>") != std::string::npos);
  CHECK(b.svg() == svg);

  nlid::BarChart h;
  h.size(900, 300)
      .horizontal(true)
      .add("a very long candidate model name that needs room", 3)
      .add("b", 1);
  CHECK(h.svg().find(">a very long candidate model name that needs room</text>") !=
        std::string::npos);
  // Labels longer than 40 % of the width are shortened at a code point, full text as tooltip.
  nlid::BarChart cut;
  const std::string long_name = "\xC3\xA9" + std::string(80, 'x') + " tail";
  cut.horizontal(true).add(long_name, 1.0);
  const std::string cs = cut.svg();
  CHECK(cs.find("<title>" + long_name + "</title>") != std::string::npos);
  CHECK(cs.find("\xC3\xA9xxxx") != std::string::npos);
  CHECK(cs.find("x...</text>") != std::string::npos);
  CHECK(cs.find("\xEF\xBF\xBD") == std::string::npos);  // never a cut UTF-8 sequence

  nlid::BarChart lg("loss");
  lg.log_scale(true).add("[1 1 0]", 4.1).add("[2 1 0]", 0.052);
  const std::string ls = lg.svg();
  for (const char* tick : {">0.01</text>", ">0.1</text>", ">1</text>", ">10</text>"}) {
    CHECK(ls.find(tick) != std::string::npos);
  }
  lg.add("bad", -1);
  CHECK_THROWS_WITH(lg.svg(),
                    "nlid: bar chart 'loss': log scale needs positive values, bar 'bad' has -1");
  CHECK_THROWS_WITH(nlid::BarChart().highlight(0), "nlid: highlight index 0 out of range (0 bars)");

  // Many categories: labels rotate instead of overlapping.
  nlid::BarChart many;
  for (int i = 0; i < 30; ++i) many.add("order [" + std::to_string(i) + " 1 0]", i + 1.0);
  CHECK(many.svg().find("rotate(-45") != std::string::npos);
}

TEST_CASE("Charts write standalone SVG files atomically") {
  const auto path = (std::filesystem::temp_directory_path() / "nlid_chart_test.svg").string();
  nlid::LineChart c("file");
  c.line("y", std::vector<double>{1, 3, 2});
  c.write(path);
  CHECK(nlid::read_file(path) == c.svg() + "\n");
  std::filesystem::remove(path);
}

namespace {
// The closed polygons of the first envelope path: "M x,y L x,y ... Z M ..." -> point lists.
std::vector<std::vector<Point>> envelope_polygons(const std::string& svg) {
  std::vector<std::vector<Point>> out;
  const std::size_t at = svg.find("<path class=\"nlid-envelope\"");
  if (at == std::string::npos) return out;
  const std::size_t b = svg.find(" d=\"", at) + 4;
  const std::string d = svg.substr(b, svg.find('"', b) - b);
  std::size_t i = 0;
  while (i < d.size()) {
    if (d[i] == 'M') out.emplace_back();
    if (d[i] == 'M' || d[i] == 'L' || d[i] == 'Z' || d[i] == ' ') {
      ++i;
      continue;
    }
    double x = 0, y = 0;
    const char* end = d.data() + d.size();
    auto r = std::from_chars(d.data() + i, end, x);
    if (r.ec != std::errc() || r.ptr == end || *r.ptr != ',') FAIL("bad envelope data at " << i);
    r = std::from_chars(r.ptr + 1, end, y);
    if (r.ec != std::errc()) FAIL("bad envelope data at " << i);
    out.back().push_back({x, y});
    i = static_cast<std::size_t>(r.ptr - d.data());
  }
  return out;
}
}  // namespace

TEST_CASE("Envelope: a filled region between two curves under the lines, in the axes and the legend") {
  const std::vector<double> x{0, 1, 2, 3, 4}, y{0.0, 0.5, 1.0, 0.5, 0.0};
  const std::vector<double> lo{-1, -0.5, 0, -0.5, -1}, hi{3, 3.5, 4, 3.5, 3};
  nlid::LineChart plain, banded;
  plain.line("simulated", x, y);
  banded.envelope("+-2 sigma", x, lo, hi, "#2ca02c").line("simulated", x, y);
  const std::string s = banded.svg();
  // Under the line: the area is drawn first.
  REQUIRE(s.find("nlid-envelope") != std::string::npos);
  CHECK(s.find("nlid-envelope") < s.find("nlid-series"));
  CHECK(s.find("fill=\"#2ca02c\" fill-opacity=\"0.2\"") != std::string::npos);
  const auto poly = envelope_polygons(s);
  REQUIRE(poly.size() == 1);
  REQUIRE(poly[0].size() == 10);  // upper edge forwards, lower edge back
  for (std::size_t k = 0; k < 5; ++k) {
    CHECK(poly[0][k].x == poly[0][9 - k].x);
    CHECK(poly[0][k].y < poly[0][9 - k].y);  // upper above lower (pixel y grows downwards)
  }
  // The axes hold the envelope: the same line is drawn lower and flatter than without it.
  const auto line_plain = series_paths(plain.svg()), line_banded = series_paths(s);
  REQUIRE(line_plain.size() == 1);
  REQUIRE(line_banded.size() == 1);
  const double rise_plain = line_plain[0][0][0].y - line_plain[0][0][2].y;
  const double rise_banded = line_banded[0][0][0].y - line_banded[0][0][2].y;
  CHECK(rise_banded < 0.5 * rise_plain);
  // Its legend entry: a filled swatch and the text.
  CHECK(s.find("+-2 sigma") != std::string::npos);
  CHECK(count(s, "fill-opacity=\"0.35\"") == 1);
  // Edges given the other way round are the same region.
  nlid::LineChart swapped;
  swapped.envelope("+-2 sigma", x, hi, lo, "#2ca02c").line("simulated", x, y);
  CHECK(swapped.svg() == s);

  // A gap splits it into two polygons.
  std::vector<double> lo_gap = lo;
  lo_gap[2] = std::nan("");
  nlid::LineChart gap;
  gap.envelope("", x, lo_gap, hi);
  const auto two = envelope_polygons(gap.svg());
  REQUIRE(two.size() == 2);
  CHECK(two[0].size() == 4);
  CHECK(two[1].size() == 4);
  CHECK(gap.svg().find("fill-opacity=\"0.35\"") == std::string::npos);  // no name, no legend entry

  // Bad input is said.
  CHECK_THROWS_WITH(nlid::LineChart().envelope("e", x, std::vector<double>{1, 2}, hi),
                    Catch::Contains("envelope 'e': x has 5 values, lower 2 and upper 5"));
  const std::vector<double> back{0, 1, 2, 1.5, 4};
  CHECK_THROWS_WITH(nlid::LineChart().envelope("e", back, lo, hi), Catch::Contains("x decreases at sample 3"));
}

TEST_CASE("Envelope decimation keeps each pixel column's lowest and highest edge") {
  const std::size_t n = 100000;
  std::vector<double> x(n), lo(n), hi(n);
  for (std::size_t k = 0; k < n; ++k) {
    x[k] = static_cast<double>(k) * 1e-4;
    lo[k] = std::sin(x[k] * 3.0) - 0.2;
    hi[k] = std::sin(x[k] * 3.0) + 0.2;
  }
  hi[43210] = 6.0;   // one sample's wide spread
  lo[65432] = -5.0;
  nlid::LineChart full, dec;
  full.envelope("band", x, lo, hi).decimate(false);
  dec.envelope("band", x, lo, hi);
  const auto pf = envelope_polygons(full.svg()), pd = envelope_polygons(dec.svg());
  REQUIRE(pf.size() == 1);
  REQUIRE(pd.size() == 1);
  CHECK(pf[0].size() == 2 * n);
  CHECK(pd[0].size() <= 2 * 730);
  CHECK(dec.svg().find("data-samples=\"100000\"") != std::string::npos);
  const auto top = [](const std::vector<Point>& v) {
    return std::min_element(v.begin(), v.end(), [](Point a, Point b) { return a.y < b.y; })->y;
  };
  const auto bottom = [](const std::vector<Point>& v) {
    return std::max_element(v.begin(), v.end(), [](Point a, Point b) { return a.y < b.y; })->y;
  };
  CHECK(top(pd[0]) == top(pf[0]));        // the one-sample spread upwards is drawn
  CHECK(bottom(pd[0]) == bottom(pf[0]));  // and downwards
}

TEST_CASE("Envelope with fixed x limits: the visible part, one sample beyond each side, any distance away") {
  const std::size_t n = 5000;
  std::vector<double> x(n), lo(n), hi(n);
  for (std::size_t k = 0; k < n; ++k) {
    x[k] = static_cast<double>(k);
    lo[k] = -1.0;
    hi[k] = 1.0;
  }
  // The samples just outside the visible window, which are drawn to reach the frame, lie
  // astronomically far away.
  for (std::size_t k = 0; k < 1000; ++k) x[k] = -1e300;
  for (std::size_t k = 1501; k < n; ++k) x[k] = 1e300;
  nlid::LineChart c;
  c.envelope("band", x, lo, hi).x_limits(1000.0, 1500.0);
  const std::string s = c.svg();
  const auto p = envelope_polygons(s);
  REQUIRE(p.size() == 1);
  CHECK(p[0].size() <= 2 * 740);
  CHECK(s.find("nan") == std::string::npos);
  CHECK(s.find("inf") == std::string::npos);
}
