#include "nlid/io/html_report.hpp"

#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "nlid/core/atomic_file.hpp"

namespace {

std::size_t count(const std::string& s, const std::string& what) {
  std::size_t n = 0;
  for (std::size_t p = s.find(what); p != std::string::npos; p = s.find(what, p + 1)) ++n;
  return n;
}

bool contains(const std::string& s, const std::string& what) {
  return s.find(what) != std::string::npos;
}

nlid::LineChart small_chart(const std::string& title) {
  nlid::LineChart c(title);
  c.line("y", std::vector<double>{1, 2, 3}, std::vector<double>{3, 1, 2});
  return c;
}

}  // namespace

TEST_CASE("HtmlReport writes a self-contained page with every block kind, in order") {
  nlid::HtmlReport r("Throttle identification");
  r.heading("Data").paragraph("Estimation on data1+data2.\nValidation on data3..5.");
  r.heading("Models").preformatted("y(t) = a1 y(t-1) + b0 u(t)");
  r.note("nlarx5 validates on all sets", nlid::NoteKind::good);
  r.note("nlhw1 fails on data5", nlid::NoteKind::warning);
  r.heading("Details", 3);
  r.table({"model", "fit data3 (%)", "iterations"},
          {{"nlarx5", 93.123456, 90}, {"nlhw1", std::nan(""), 200}}, "Validation fit");
  r.chart(small_chart("compare"), "Measured vs simulated");
  nlid::BarChart b("orders");
  b.add("[2 1 0]", 0.5);
  r.chart(b);
  r.heading("Grids");
  r.grid({small_chart("a"), small_chart("b"), small_chart("c")}, 3);
  CHECK(r.chart_count() == 5);

  const std::string h = r.str();
  CHECK(h.rfind("<!DOCTYPE html>\n<html lang=\"en\">", 0) == 0);
  CHECK(contains(h, "<meta charset=\"utf-8\">"));
  CHECK(contains(h, "<title>Throttle identification</title>"));
  CHECK(contains(h, "<h1>Throttle identification</h1>"));
  // Self-contained: no external references of any kind, and a policy that forbids them.
  CHECK(contains(h, "Content-Security-Policy\" content=\"default-src 'none';"));
  for (const char* external : {"http://", "https://", "src=", "href=\"http", "@import", "url("}) {
    INFO(external);
    const std::string e(external);
    // The SVG namespace URI is an identifier, not a download.
    CHECK(count(h, e) == (e == "http://" ? count(h, "xmlns=\"http://www.w3.org/2000/svg\"") : 0));
  }
  // Status element with the expected chart count, filled in by the inline script on load.
  CHECK(contains(h,
                 "<div id=\"nlid-report-status\" hidden data-ready=\"0\" data-charts=\"\" "
                 "data-rendered=\"\" data-errors=\"\" data-expected-charts=\"5\"></div>"));
  CHECK(contains(h, "window.onerror"));
  CHECK(contains(h, "querySelectorAll('svg.nlid-chart')"));
  CHECK(count(h, "<svg xmlns=\"http://www.w3.org/2000/svg\" class=\"nlid-chart\"") == 5);
  // Three level-2 headings -> a table of contents with anchors.
  CHECK(
      contains(h,
               "<nav class=\"toc\"><strong>Contents</strong><ol><li><a href=\"#s1\">Data</a></li>"
               "<li><a href=\"#s2\">Models</a></li><li><a href=\"#s3\">Grids</a></li></ol></nav>"));
  CHECK(contains(h, "<h2 id=\"s2\">Models</h2>"));
  CHECK(contains(h, "<h3>Details</h3>"));
  CHECK(contains(h, "<p>Estimation on data1+data2.\nValidation on data3..5.</p>"));
  CHECK(contains(h, "<pre>y(t) = a1 y(t-1) + b0 u(t)</pre>"));
  CHECK(contains(h, "<div class=\"note good\">nlarx5 validates on all sets</div>"));
  CHECK(contains(h, "<div class=\"note warning\">nlhw1 fails on data5</div>"));
  // Tables: numbers with 4 significant digits, right-aligned; NaN shown and flagged; integers
  // exact.
  CHECK(contains(h, "<caption>Validation fit</caption>"));
  CHECK(contains(
      h, "<th>model</th><th class=\"num\">fit data3 (%)</th><th class=\"num\">iterations</th>"));
  CHECK(contains(h, "<td>nlarx5</td><td class=\"num\">93.12</td><td class=\"num\">90</td>"));
  CHECK(contains(h, "<td class=\"num bad\">NaN</td>"));
  CHECK(contains(h, "<figcaption>Measured vs simulated</figcaption>"));
  CHECK(contains(h, "grid-template-columns:repeat(3,minmax(0,1fr))"));
  // Order of blocks is the order of calls.
  CHECK(h.find("<h2 id=\"s1\">Data</h2>") < h.find("<pre>"));
  CHECK(h.find("<pre>") < h.find("<table>"));
  CHECK(h.find("<table>") < h.find("class=\"grid\""));
  CHECK(r.str() == h);  // deterministic
}

TEST_CASE("HtmlReport escapes all text so none of it can become markup or script") {
  nlid::HtmlReport r("<script>alert(1)</script>");
  r.heading("<img src=x onerror=alert(2)>");
  r.paragraph("a < b && c > d \"quoted\" 'single'");
  r.preformatted("</pre><script>alert(3)</script>");
  r.note("<b>bold?</b>");
  r.table({"<th>"}, {{"<td>"}}, "<caption>");
  r.chart(small_chart("</svg><script>alert(4)</script>"), "<figcaption>");
  const std::string h = r.str();
  // The only <script> element is the report's own status script.
  CHECK(count(h, "<script>") == 1);
  CHECK_FALSE(contains(h, "<img"));
  CHECK_FALSE(contains(h, "<b>"));
  CHECK(contains(h, "<title>&lt;script&gt;alert(1)&lt;/script&gt;</title>"));
  CHECK(contains(h, "&lt;img src=x onerror=alert(2)&gt;"));
  CHECK(contains(h, "a &lt; b &amp;&amp; c &gt; d &quot;quoted&quot; &#39;single&#39;"));
  CHECK(contains(h, "<pre>&lt;/pre&gt;&lt;script&gt;alert(3)&lt;/script&gt;</pre>"));
  CHECK(contains(h, "<th>&lt;th&gt;</th>"));
  CHECK(contains(h, "<td>&lt;td&gt;</td>"));
  CHECK(contains(h, "&lt;/svg&gt;&lt;script&gt;alert(4)&lt;/script&gt;"));
}

TEST_CASE("HtmlReport keeps a leading blank line of preformatted text") {
  // HTML drops one newline right after <pre>, so the markup must carry one more.
  nlid::HtmlReport r("t");
  r.preformatted("\nafter a blank line").preformatted("no blank line");
  const std::string h = r.str();
  CHECK(contains(h, "<pre>\n\nafter a blank line</pre>"));
  CHECK(contains(h, "<pre>no blank line</pre>"));
}

TEST_CASE("HtmlReport rejects malformed input with a message saying what and where") {
  nlid::HtmlReport r("x");
  CHECK_THROWS_WITH(r.heading("h", 1),
                    "nlid: heading level must be 2, 3 or 4 (level 1 is the report title), got 1");
  CHECK_THROWS_WITH(r.table({"a", "b"}, {{"1", "2"}, {"3"}}, "fits"),
                    "nlid: table 'fits': row 2 has 1 cells but the header has 2");
  CHECK_THROWS_WITH(
      r.chart_svg("<div>not a chart</div>"),
      Catch::StartsWith("nlid: chart markup must be a single <svg class=\"nlid-chart\">"));
  CHECK_THROWS_WITH(r.chart_svg("<svg class=\"other\"></svg>"), Catch::Contains("nlid-chart"));
  const std::string chart = small_chart("c").svg();
  CHECK_THROWS_WITH(r.chart_svg(chart + "<SCRIPT>x()</SCRIPT>" + chart),
                    Catch::Contains("without scripts"));
  CHECK_THROWS_WITH(r.chart_svg(chart + chart), Catch::Contains("single"));
  CHECK_THROWS_WITH(r.grid(std::vector<std::string>{small_chart("a").svg()}, 0),
                    "nlid: grid columns must be in [1, 6]");
  CHECK(r.chart_count() == 0);  // nothing half-added
  CHECK_NOTHROW(r.chart_svg(small_chart("ok").svg()));
  CHECK(r.chart_count() == 1);
  // A table without header is allowed (key/value lists); cells may then vary in number.
  CHECK_NOTHROW(r.table({}, {{"key", 1.5}, {"only"}}));
  // No TOC for fewer than three sections.
  CHECK_FALSE(contains(r.str(), "<nav"));
}

TEST_CASE("HtmlReport::write is atomic and leaves no temporary files") {
  const auto dir = std::filesystem::temp_directory_path() / "nlid_report_test";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  nlid::HtmlReport r("file");
  r.chart(small_chart("c"));
  const std::string path = (dir / "report.html").string();
  r.write(path);
  CHECK(nlid::read_file(path) == r.str());
  std::size_t files = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) files += e.is_regular_file();
  CHECK(files == 1);
  CHECK_THROWS_WITH(r.write((dir / "missing" / "r.html").string()),
                    Catch::Contains("directory does not exist"));
  std::filesystem::remove_all(dir);
}

TEST_CASE("Table cells format numbers by significant digits and integers exactly") {
  CHECK(nlid::TableCell(93.123456).text(4) == "93.12");
  CHECK(nlid::TableCell(1.0e-7).text(3) == "1e-07");
  CHECK(nlid::TableCell(123456789.0).text(4) == "1.235e+08");
  CHECK(nlid::TableCell(1234567890123LL).text(4) == "1234567890123");
  CHECK(nlid::TableCell(-0.0).text(4) == "0");
  CHECK(nlid::TableCell(INFINITY).text(4) == "Inf");
  CHECK(nlid::TableCell(INFINITY).is_non_finite());
  CHECK(nlid::TableCell(2.5f).is_number());
  CHECK_FALSE(nlid::TableCell("2.5").is_number());
}
