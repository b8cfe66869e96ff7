#pragma once
/// @file
/// `nlid::HtmlReport`: one self-contained HTML file with text, tables and SVG charts.
///
/// The identification loop ends in a document a person reads: which data, which models, how
/// well each fits (fit % of the simulated output, MATLAB `compare`; validation by simulation as in
/// Ljung 1999, ch. 16), where simulation and measurement part, what was changed. `HtmlReport`
/// collects those pieces in order and writes them as a single file that opens anywhere, offline,
/// years later:
///
/// * everything is inline: CSS in a `<style>` element, charts as `<svg>` (see svg_chart.hpp);
///   no web fonts, no images, no scripts from the network. A Content-Security-Policy meta tag
///   (`default-src 'none'`) makes the browser refuse any external load, so a report that
///   accidentally referenced one would show it as an error rather than silently phone home;
/// * all text passed in is HTML-escaped (a model called `<b>` is shown, not interpreted);
/// * numbers in tables are formatted with a fixed count of significant digits and aligned on
///   the right; NaN/Inf are shown as such, highlighted, never as an empty cell;
/// * the output is deterministic (no time stamps, no random ids), so two reports can be diffed.
///
/// A tiny inline script makes the page testable by a headless browser: on load it counts the
/// `<svg class="nlid-chart">` elements, counts the ones laid out with a non-zero size, and
/// records script errors (`window.onerror`), failed resource loads and CSP violations into
///
///     <div id="nlid-report-status" hidden data-ready="1" data-charts="N" data-rendered="N"
///          data-errors="M" data-expected-charts="N">(error messages, separated by " | ")</div>
///
/// `tests/io/render/render_check.sh report.html N` renders a report in headless Chromium and
/// fails unless data-errors is 0 and the chart counts equal N.
///
///     nlid::HtmlReport r("Throttle identification");
///     r.heading("Validation").paragraph("Models estimated on data1+data2, simulated from u
///     only."); r.table({"model", "data3", "data4", "data5"}, {{"nlarx5", 93.1, 91.7, 88.2}});
///     r.chart(compare_chart);
///     r.write("throttle_report.html");

#include <algorithm>
#include <cmath>
#include <concepts>
#include <cstddef>
#include <initializer_list>
#include <string>
#include <string_view>
#include <utility>
#include <variant>
#include <vector>

#include "nlid/core/atomic_file.hpp"
#include "nlid/core/error.hpp"
#include "nlid/io/svg_chart.hpp"

namespace nlid {

/// One table cell: text, or a number that the table formats.
class TableCell {
 public:
  /// An empty text cell.
  TableCell() = default;
  /// A text cell (escaped on output).
  TableCell(std::string text) : value_(std::move(text)) {}  // NOLINT(google-explicit-constructor)
  /// A text cell.
  TableCell(const char* text) : value_(std::string(text)) {}  // NOLINT(google-explicit-constructor)
  /// A text cell.
  TableCell(std::string_view text) : value_(std::string(text)) {}  // NOLINT
  /// A number cell (formatted with the table's significant digits).
  template <std::floating_point F>
  TableCell(F x) : value_(static_cast<double>(x)) {}  // NOLINT(google-explicit-constructor)
  /// An integer cell (printed exactly; not limited by the table's digits).
  template <std::integral I>
  requires(!std::same_as<I, bool> && !std::same_as<I, char>) TableCell(I i)
      : value_(std::to_string(i)), numeric_text_(true) {}  // NOLINT

  /// True for number cells (right-aligned).
  [[nodiscard]] bool is_number() const noexcept {
    return std::holds_alternative<double>(value_) || numeric_text_;
  }
  /// The cell as HTML-ready text (not yet escaped) given the table's significant digits.
  [[nodiscard]] std::string text(int digits) const {
    if (const double* x = std::get_if<double>(&value_)) return detail::format_general(*x, digits);
    return std::get<std::string>(value_);
  }
  /// True for a number cell holding NaN or ±Inf (shown highlighted).
  [[nodiscard]] bool is_non_finite() const noexcept {
    const double* x = std::get_if<double>(&value_);
    return x != nullptr && !std::isfinite(*x);
  }

 private:
  std::variant<std::string, double> value_;
  bool numeric_text_ = false;
};

/// A table: header, rows of cells, optional caption.
struct ReportTable {
  std::vector<std::string> header;           ///< column titles (may be empty: no header row)
  std::vector<std::vector<TableCell>> rows;  ///< each row as long as the header (if any)
  std::string caption;                       ///< shown above the table
  int digits = 4;                            ///< significant digits of number cells
};

/// Style of a `note` call-out.
enum class NoteKind {
  info,    ///< neutral remark
  good,    ///< a check that passed, an improvement
  warning  ///< something the reader must not miss (a located mismatch, a failed validation)
};

/// Builder of a self-contained HTML report (see the file comment).
class HtmlReport {
 public:
  /// A report whose `<title>` and top `<h1>` are `title`.
  explicit HtmlReport(std::string title) : title_(std::move(title)) {}

  /// A section heading; `level` 2 (section) to 4. Level-2 headings get anchors and, when there
  /// are three or more, a table of contents under the title.
  HtmlReport& heading(std::string text, int level = 2) {
    require(level >= 2 && level <= 4,
            "heading level must be 2, 3 or 4 (level 1 is the report title), got " +
                std::to_string(level));
    Block b{Kind::heading, std::move(text), level};
    blocks_.push_back(std::move(b));
    return *this;
  }
  /// A paragraph of plain text (escaped; line breaks kept).
  HtmlReport& paragraph(std::string text) {
    blocks_.push_back({Kind::paragraph, std::move(text), 0});
    return *this;
  }
  /// Preformatted monospace text: equations, model descriptions, solver logs (escaped).
  HtmlReport& preformatted(std::string text) {
    blocks_.push_back({Kind::preformatted, std::move(text), 0});
    return *this;
  }
  /// A highlighted call-out.
  HtmlReport& note(std::string text, NoteKind kind = NoteKind::info) {
    blocks_.push_back({Kind::note, std::move(text), static_cast<int>(kind)});
    return *this;
  }
  /// A table. Throws if a row's length differs from the header's, naming the row.
  HtmlReport& table(ReportTable t) {
    require(t.digits >= 1 && t.digits <= 17, "table digits must be in [1, 17]");
    for (std::size_t r = 0; r < t.rows.size(); ++r) {
      if (!t.header.empty() && t.rows[r].size() != t.header.size()) {
        throw Error("table '" + t.caption + "': row " + std::to_string(r + 1) + " has " +
                    std::to_string(t.rows[r].size()) + " cells but the header has " +
                    std::to_string(t.header.size()));
      }
    }
    Block b{Kind::table, render_table(t), 0};
    blocks_.push_back(std::move(b));
    return *this;
  }
  /// A table from header and rows, numbers with `digits` significant digits.
  HtmlReport& table(std::vector<std::string> header, std::vector<std::vector<TableCell>> rows,
                    std::string caption = {}, int digits = 4) {
    return table(ReportTable{std::move(header), std::move(rows), std::move(caption), digits});
  }
  /// A chart, full width, with an optional caption under it.
  HtmlReport& chart(const LineChart& c, std::string caption = {}) {
    return chart_svg(c.svg(), std::move(caption));
  }
  /// @copydoc chart(const LineChart&, std::string)
  HtmlReport& chart(const BarChart& c, std::string caption = {}) {
    return chart_svg(c.svg(), std::move(caption));
  }
  /// A chart given as markup from `LineChart::svg()` / `BarChart::svg()`. Throws unless it is
  /// one `<svg class="nlid-chart">` element (other markup would break the page's chart count).
  HtmlReport& chart_svg(std::string svg, std::string caption = {}) {
    check_svg(svg);
    blocks_.push_back(
        {Kind::chart, "<figure class=\"chart\">" + svg + figcaption(caption) + "</figure>", 0});
    ++charts_;
    return *this;
  }
  /// Charts side by side, `columns` per row (collapsing to one column on narrow screens).
  HtmlReport& grid(const std::vector<std::string>& svgs, int columns = 2) {
    require(columns >= 1 && columns <= 6, "grid columns must be in [1, 6]");
    std::string html = "<div class=\"grid\" style=\"grid-template-columns:repeat(" +
                       std::to_string(columns) + ",minmax(0,1fr))\">";
    for (const std::string& s : svgs) {
      check_svg(s);
      html.append("<figure class=\"chart\">").append(s).append("</figure>");
    }
    html.append("</div>");
    blocks_.push_back({Kind::chart, std::move(html), 0});
    charts_ += svgs.size();
    return *this;
  }
  /// @copydoc grid(const std::vector<std::string>&, int)
  HtmlReport& grid(const std::vector<LineChart>& charts, int columns = 2) {
    std::vector<std::string> svgs;
    for (const LineChart& c : charts) svgs.push_back(c.svg());
    return grid(svgs, columns);
  }

  /// Number of charts added so far (what the status element must report after rendering).
  [[nodiscard]] std::size_t chart_count() const noexcept { return charts_; }
  /// The whole document.
  [[nodiscard]] std::string str() const;
  /// Writes `str()` to `path` atomically.
  void write(const std::string& path) const { write_file_atomically(path, str()); }

 private:
  enum class Kind { heading, paragraph, preformatted, note, table, chart };
  struct Block {
    Kind kind;
    std::string content;  // text for heading/paragraph/pre/note, ready HTML for table/chart
    int level;            // heading level, or NoteKind
  };

  // Raw chart markup is accepted only in the shape the chart classes produce: one root
  // <svg class="nlid-chart">, and no <script>. This is not a sanitiser (the markup is trusted to
  // come from LineChart/BarChart), but it catches passing other HTML by mistake, which would
  // break the chart count that the status element reports.
  static void check_svg(const std::string& svg) {
    std::string lower(svg.size(), ' ');
    for (std::size_t i = 0; i < svg.size(); ++i) {
      const char c = svg[i];
      lower[i] = (c >= 'A' && c <= 'Z') ? static_cast<char>(c - 'A' + 'a') : c;
    }
    const std::string cls = "class=\"nlid-chart\"";
    const bool ok = svg.rfind("<svg", 0) == 0 && svg.find(cls) < svg.find('>') &&
                    svg.find(cls, svg.find(cls) + 1) == std::string::npos &&
                    lower.find("<script") == std::string::npos && svg.size() >= 6 &&
                    svg.compare(svg.size() - 6, 6, "</svg>") == 0;
    require(ok,
            "chart markup must be a single <svg class=\"nlid-chart\"> element without scripts, "
            "as made by LineChart::svg() or BarChart::svg()");
  }
  static std::string figcaption(const std::string& caption) {
    if (caption.empty()) return {};
    return "<figcaption>" + detail::escape_xml(caption) + "</figcaption>";
  }
  // Rendered eagerly (at table()) so a bad table is reported by the call that added it.
  static std::string render_table(const ReportTable& t) {
    std::string h = "<div class=\"table-wrap\"><table>";
    if (!t.caption.empty())
      h.append("<caption>").append(detail::escape_xml(t.caption)).append("</caption>");
    // A column is right-aligned when all its body cells are numbers.
    std::size_t ncols = t.header.size();
    for (const auto& row : t.rows) ncols = std::max(ncols, row.size());
    std::vector<bool> numeric(ncols, true);
    for (const auto& row : t.rows) {
      for (std::size_t c = 0; c < row.size(); ++c) numeric[c] = numeric[c] && row[c].is_number();
    }
    if (!t.header.empty()) {
      h.append("<thead><tr>");
      for (std::size_t c = 0; c < t.header.size(); ++c) {
        h.append(numeric[c] && !t.rows.empty() ? "<th class=\"num\">" : "<th>")
            .append(detail::escape_xml(t.header[c]))
            .append("</th>");
      }
      h.append("</tr></thead>");
    }
    h.append("<tbody>");
    for (const auto& row : t.rows) {
      h.append("<tr>");
      for (std::size_t c = 0; c < row.size(); ++c) {
        const TableCell& cell = row[c];
        if (cell.is_non_finite()) {
          h.append("<td class=\"num bad\">");
        } else {
          h.append(cell.is_number() ? "<td class=\"num\">" : "<td>");
        }
        h.append(detail::escape_xml(cell.text(t.digits))).append("</td>");
      }
      h.append("</tr>");
    }
    h.append("</tbody></table></div>");
    return h;
  }

  std::string title_;
  std::vector<Block> blocks_;
  std::size_t charts_ = 0;
};

// ==== Implementation details below ============================================================

namespace detail {

/// Page style: readable measure, tabular numbers, charts scale down on small screens, print.
inline constexpr std::string_view report_css = R"(
:root{color-scheme:light}
body{margin:0;background:#f6f7f9;color:#1d1f23;
  font:15px/1.5 system-ui,-apple-system,"Segoe UI",Roboto,"DejaVu Sans",Arial,sans-serif}
main{max-width:1100px;margin:0 auto;padding:24px 28px 40px;background:#fff;min-height:100vh;
  box-sizing:border-box}
h1{font-size:26px;margin:0 0 12px}
h2{font-size:20px;margin:32px 0 8px;border-bottom:1px solid #ddd;padding-bottom:4px}
h3{font-size:17px;margin:24px 0 6px}
h4{font-size:15px;margin:18px 0 4px}
p{margin:8px 0;white-space:pre-line}
pre{background:#f3f4f6;border:1px solid #e3e5e8;border-radius:4px;padding:10px 12px;
  overflow-x:auto;font:13px/1.45 ui-monospace,"DejaVu Sans Mono",Menlo,Consolas,monospace}
nav.toc{background:#f3f6fa;border:1px solid #dde3ea;border-radius:4px;padding:6px 14px;
  margin:8px 0 16px;display:inline-block}
nav.toc ol{margin:4px 0;padding-left:22px}
.table-wrap{overflow-x:auto;margin:12px 0}
table{border-collapse:collapse;font-size:14px}
caption{text-align:left;font-weight:600;padding:4px 0}
th,td{border:1px solid #d9dce1;padding:4px 10px;text-align:left;vertical-align:top}
th{background:#f0f2f5}
tr:nth-child(even) td{background:#fafbfc}
.num{text-align:right;font-variant-numeric:tabular-nums}
td.bad{color:#a01c1c;font-weight:600}
figure.chart{margin:14px 0;text-align:center}
figure.chart svg{max-width:100%;height:auto}
figcaption{font-size:13px;color:#555;margin-top:2px}
.grid{display:grid;gap:12px}
.grid figure.chart{margin:0}
.note{border-left:4px solid #1f77b4;background:#eef5fb;padding:8px 12px;margin:12px 0;
  white-space:pre-line}
.note.good{border-color:#2ca02c;background:#eff8ee}
.note.warning{border-color:#d62728;background:#fcf0f0}
footer{max-width:1100px;margin:0 auto;padding:8px 28px;color:#888;font-size:12px}
@media (max-width:760px){.grid{grid-template-columns:1fr !important}main{padding:14px}}
@media print{body{background:#fff}main{max-width:none;padding:0}
  figure.chart,table{break-inside:avoid}}
)";

/// Status recorder for headless-browser tests (see the file comment). Plain ES5, no network.
inline constexpr std::string_view report_status_script = R"(
(function () {
  var errors = [];
  function update() {
    var s = document.getElementById('nlid-report-status');
    if (!s) return;
    var charts = document.querySelectorAll('svg.nlid-chart'), drawn = 0;
    for (var i = 0; i < charts.length; i++) {
      var r = charts[i].getBoundingClientRect();
      if (r.width > 0 && r.height > 0) drawn++;
    }
    s.setAttribute('data-charts', String(charts.length));
    s.setAttribute('data-rendered', String(drawn));
    s.setAttribute('data-errors', String(errors.length));
    s.textContent = errors.join(' | ');
  }
  window.onerror = function (msg, src, line, col) {
    errors.push('script error: ' + msg + ' (line ' + line + ', column ' + col + ')');
    update();
    return false;
  };
  window.addEventListener('error', function (e) {
    if (e.target && e.target !== window) {
      errors.push('failed to load: ' + (e.target.src || e.target.href || e.target.tagName));
      update();
    }
  }, true);
  document.addEventListener('securitypolicyviolation', function (e) {
    errors.push('blocked by content security policy: ' + e.blockedURI);
    update();
  });
  window.addEventListener('load', function () {
    update();
    var s = document.getElementById('nlid-report-status');
    if (s) s.setAttribute('data-ready', '1');
  });
})();
)";

}  // namespace detail

inline std::string HtmlReport::str() const {
  // The status script goes first in <head> so that window.onerror is installed before any other
  // markup is parsed: an error anywhere later in the page is then recorded, not lost. The CSP
  // allows inline style and script (the report's own) and data: images, and nothing else.
  // The status element starts with empty counts and data-ready="0": if the script never runs
  // (blocked, broken), a checker sees that rather than plausible-looking zeros.
  std::string h;
  h.reserve(16384);
  h.append("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n")
      .append("<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n")
      .append("<meta http-equiv=\"Content-Security-Policy\" content=\"default-src 'none'; ")
      .append("style-src 'unsafe-inline'; script-src 'unsafe-inline'; img-src data:\">\n")
      .append("<meta name=\"generator\" content=\"nlid\">\n<title>")
      .append(detail::escape_xml(title_))
      .append("</title>\n<script>")
      .append(detail::report_status_script)
      .append("</script>\n<style>")
      .append(detail::report_css)
      .append("</style>\n</head>\n<body>\n")
      .append("<div id=\"nlid-report-status\" hidden data-ready=\"0\" data-charts=\"\" ")
      .append("data-rendered=\"\" data-errors=\"\" data-expected-charts=\"")
      .append(std::to_string(charts_))
      .append("\"></div>\n<main>\n<h1>")
      .append(detail::escape_xml(title_))
      .append("</h1>\n");

  // A contents list pays off once there are a few sections; anchors are numbered (s1, s2, ...)
  // rather than derived from the heading text, so they stay unique and deterministic.
  std::size_t sections = 0;
  for (const Block& b : blocks_) sections += b.kind == Kind::heading && b.level == 2;
  if (sections >= 3) {
    h.append("<nav class=\"toc\"><strong>Contents</strong><ol>");
    std::size_t k = 0;
    for (const Block& b : blocks_) {
      if (b.kind != Kind::heading || b.level != 2) continue;
      h.append("<li><a href=\"#s").append(std::to_string(++k)).append("\">");
      h.append(detail::escape_xml(b.content)).append("</a></li>");
    }
    h.append("</ol></nav>\n");
  }
  // Text blocks are escaped here, at output time; tables and charts were rendered (and their
  // text escaped) when they were added, so any errors surfaced at the call that caused them.
  std::size_t section = 0;
  for (const Block& b : blocks_) {
    switch (b.kind) {
      case Kind::heading: {
        const std::string tag = "h" + std::to_string(b.level);
        h.append("<").append(tag);
        if (b.level == 2) h.append(" id=\"s").append(std::to_string(++section)).append("\"");
        h.append(">").append(detail::escape_xml(b.content)).append("</").append(tag).append(">\n");
        break;
      }
      case Kind::paragraph:
        h.append("<p>").append(detail::escape_xml(b.content)).append("</p>\n");
        break;
      case Kind::preformatted:
        // An HTML parser drops one newline right after <pre>; doubling it keeps a leading one.
        h.append(b.content.starts_with('\n') ? "<pre>\n" : "<pre>");
        h.append(detail::escape_xml(b.content)).append("</pre>\n");
        break;
      case Kind::note: {
        const char* cls = b.level == static_cast<int>(NoteKind::good)      ? "note good"
                          : b.level == static_cast<int>(NoteKind::warning) ? "note warning"
                                                                           : "note";
        h.append("<div class=\"").append(cls).append("\">");
        h.append(detail::escape_xml(b.content)).append("</div>\n");
        break;
      }
      case Kind::table:
      case Kind::chart:
        h.append(b.content).append("\n");
        break;
    }
  }
  h.append("</main>\n<footer>Generated by nlid. Self-contained: no network resources.</footer>\n")
      .append("</body>\n</html>\n");
  return h;
}

}  // namespace nlid
