#pragma once
/// @file
/// Line and bar charts as self-contained inline SVG strings, for HTML reports and figure files.
///
/// A `LineChart` draws series y(x) (measured output, simulated outputs, residuals ...) with axis
/// ticks, labels, a title and a legend, optional shaded x-intervals (where a located mismatch
/// lies) and an optional horizontal band (a tolerance, a hard-stop region). A `BarChart` draws one
/// value per category (order-selection loss, candidate fit %), vertical or horizontal.
///
/// Mapping. With axis limits [x_lo, x_hi] x [y_lo, y_hi] and a plot box of pw x ph pixels whose
/// top-left corner is (L, T), a point maps to
///
///     px = L + (x - x_lo) / (x_hi - x_lo) * pw,      py = T + (y_hi - y) / (y_hi - y_lo) * ph.
///
/// The x axis is tight to the data (as MATLAB's `plot` of a time series); the y axis adds 5 %
/// padding each side, so a saturated trace does not hide under the frame.
///
/// Ticks use "nice numbers" (Heckbert 1990, "Nice numbers for graph labels", Graphics Gems I,
/// pp. 61-63): the step is 1, 2 or 5 x 10^k chosen so that about one tick per 80 px (x) or 50 px
/// (y) appears, and labels carry exactly the decimals the step needs.
///
/// Decimation. A 20 s record at 1 kHz has 2e4 samples per channel, far more than the ~640 pixel
/// columns that show it. For x sorted ascending, a series with more than 4 points per pixel
/// column is reduced per column to its first, last, minimum and maximum sample, kept in time
/// order (the M4 aggregation of Jugel et al. 2014, "M4: a visualization-oriented time series data
/// aggregation", PVLDB 7(10)). The drawn polyline is then the same at pixel resolution as
/// the full one: a one-sample spike still reaches its peak, and a 1e5-sample trace costs < 4 x pw
/// points (~30 kB). Unsorted x (phase plots) is drawn in full.
///
/// Honesty rules: non-finite samples (NaN/Inf) break the line (a gap, never a fake value) and
/// the legend says how many were not drawn; all text is XML-escaped (and invalid UTF-8 or
/// control characters replaced), so a series called `<y & "z">` cannot break the page; output
/// is deterministic (no random ids, locale-independent number formatting), so a report can be
/// diffed. The root element is `<svg class="nlid-chart" ...>`, which the report's status script
/// counts.

#include <algorithm>
#include <charconv>
#include <cmath>
#include <concepts>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "nlid/core/atomic_file.hpp"
#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/core/utf8.hpp"

namespace nlid {

/// Stroke pattern of a series.
enum class LineStyle {
  solid,   ///< continuous line (measured data)
  dashed,  ///< 6 px dash, 4 px gap (a model's simulation)
  dotted   ///< round dots (a second model, a reference)
};

/// A contiguous sequence of doubles: anything with `data()` and `size()`.
/// Satisfied by `std::vector<double>`, `std::span<const double>`, `std::array<double, N>` and
/// `Eigen::VectorXd` (any Eigen column vector of double with direct access).
template <class R>
concept DoubleSequence = requires(const R& r) {
  { r.data() } -> std::convertible_to<const double*>;
  { r.size() } -> std::convertible_to<std::ptrdiff_t>;
};

/// One line of a `LineChart`.
struct ChartSeries {
  std::string name;       ///< legend text (escaped)
  std::vector<double> x;  ///< abscissae, same length as `y`
  std::vector<double> y;  ///< ordinates; NaN/Inf are gaps
  std::string colour;     ///< CSS colour ("#1f77b4", "black"); empty: next palette colour
  LineStyle style = LineStyle::solid;  ///< stroke pattern
  double width = 1.5;                  ///< stroke width in px, > 0
};

/// A shaded x-interval across the full plot height, e.g. a located mismatch [t0, t1].
struct ShadedInterval {
  double x_begin = 0;  ///< one end of the interval (order does not matter)
  double x_end = 0;    ///< the other end
  std::string label;   ///< printed at the top of the interval (may be empty)
  std::string colour;  ///< fill colour; empty: a translucent red
};

/// A filled region between two curves over the same abscissae, e.g. a simulation ± 2σ.
struct ChartEnvelope {
  std::string name;            ///< legend text (escaped); empty: no legend entry
  std::vector<double> x;       ///< abscissae, non-decreasing over the finite samples
  std::vector<double> lower;   ///< one edge; a non-finite sample (in x, lower or upper) is a gap
  std::vector<double> upper;   ///< the other edge
  std::string colour;          ///< fill colour; empty: the palette's first (blue), translucent
};

/// A horizontal band across the full plot width, e.g. hard stops or a tolerance.
struct HorizontalBand {
  double y_low = 0;    ///< one edge of the band
  double y_high = 0;   ///< the other edge
  std::string label;   ///< printed at the right end (may be empty)
  std::string colour;  ///< fill colour; empty: a translucent grey
};

namespace detail {
inline std::string escape_xml(std::string_view text);
inline std::string format_general(double v, int significant);
struct SvgFrame;
}  // namespace detail

/// A line chart. Build with the chained setters, then `svg()` for the markup or `write(path)`
/// for a standalone `.svg` file.
///
///     nlid::LineChart c("Validation on data3");
///     c.x_label("time (s)").y_label("angle (deg)");
///     c.line("measured", t, y).line("nlarx5 (fit 93.1 %)", t, yhat, "", nlid::LineStyle::dashed);
///     c.shade(4.2, 4.9, "mismatch: hard stop");
///     report.chart(c);
class LineChart {
 public:
  /// An empty chart (720 x 360 px).
  LineChart() = default;
  /// An empty chart with a title.
  explicit LineChart(std::string title) : title_(std::move(title)) {}

  /// Title above the plot.
  LineChart& title(std::string text) {
    title_ = std::move(text);
    return *this;
  }
  /// Label under the x axis.
  LineChart& x_label(std::string text) {
    x_label_ = std::move(text);
    return *this;
  }
  /// Label left of the y axis (rotated).
  LineChart& y_label(std::string text) {
    y_label_ = std::move(text);
    return *this;
  }
  /// Overall size in px (the plot box is what remains after margins). At least 240 x 160.
  LineChart& size(int width, int height) {
    require(width >= 240 && height >= 160 && width <= 20000 && height <= 20000,
            "chart size must be between 240 x 160 and 20000 x 20000 px, got " +
                std::to_string(width) + " x " + std::to_string(height));
    width_ = width;
    height_ = height;
    return *this;
  }
  /// Fixes the x-axis limits (default: tight to the data). Data outside is clipped.
  LineChart& x_limits(double lo, double hi) {
    check_limits(lo, hi, "x_limits");
    x_limits_ = {lo, hi};
    has_x_limits_ = true;
    return *this;
  }
  /// Fixes the y-axis limits (default: data range plus 5 % each side). Data outside is clipped.
  LineChart& y_limits(double lo, double hi) {
    check_limits(lo, hi, "y_limits");
    y_limits_ = {lo, hi};
    has_y_limits_ = true;
    return *this;
  }
  /// Turns min/max-per-pixel decimation off (on by default; see the file comment).
  LineChart& decimate(bool on) {
    decimate_ = on;
    return *this;
  }

  /// Adds a series. Throws if x and y differ in length or the width is not positive.
  LineChart& add(ChartSeries s) {
    if (s.x.size() != s.y.size()) {
      throw Error("series '" + s.name + "': x has " + std::to_string(s.x.size()) +
                  " values but y has " + std::to_string(s.y.size()));
    }
    if (!(s.width > 0 && s.width < 100)) {
      throw Error("series '" + s.name + "': line width must be in (0, 100) px, got " +
                  detail::format_f(s.width, 6));
    }
    series_.push_back(std::move(s));
    return *this;
  }
  /// Adds a series from any two `DoubleSequence`s (std::vector, std::span, Eigen::VectorXd).
  template <DoubleSequence X, DoubleSequence Y>
  LineChart& line(std::string name, const X& x, const Y& y, std::string colour = {},
                  LineStyle style = LineStyle::solid, double width = 1.5) {
    ChartSeries s{std::move(name), copy(x), copy(y), std::move(colour), style, width};
    return add(std::move(s));
  }
  /// Adds a series plotted against the sample index 0, 1, 2, ...
  template <DoubleSequence Y>
  LineChart& line(std::string name, const Y& y, std::string colour = {},
                  LineStyle style = LineStyle::solid, double width = 1.5) {
    std::vector<double> x(static_cast<std::size_t>(y.size()));
    for (std::size_t i = 0; i < x.size(); ++i) x[i] = static_cast<double>(i);
    ChartSeries s{std::move(name), std::move(x), copy(y), std::move(colour), style, width};
    return add(std::move(s));
  }
  /// Shades the x-interval [x_begin, x_end] (either order) over the full plot height.
  LineChart& shade(double x_begin, double x_end, std::string label = {}, std::string colour = {}) {
    require(std::isfinite(x_begin) && std::isfinite(x_end),
            "shaded interval '" + label + "' needs finite bounds");
    shaded_.push_back(
        {std::min(x_begin, x_end), std::max(x_begin, x_end), std::move(label), std::move(colour)});
    return *this;
  }
  /// Fills the region between `lower` and `upper` over `x` (a simulation's ±2σ band), under the
  /// lines. Long envelopes keep, per pixel column, the lowest lower and highest upper edge.
  /// Throws if the lengths differ or x decreases.
  template <DoubleSequence X, DoubleSequence L, DoubleSequence U>
  LineChart& envelope(std::string name, const X& x, const L& lower, const U& upper, std::string colour = {}) {
    ChartEnvelope e{std::move(name), copy(x), copy(lower), copy(upper), std::move(colour)};
    if (e.lower.size() != e.x.size() || e.upper.size() != e.x.size()) {
      throw Error("envelope '" + e.name + "': x has " + std::to_string(e.x.size()) + " values, lower " +
                  std::to_string(e.lower.size()) + " and upper " + std::to_string(e.upper.size()));
    }
    double prev = -std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < e.x.size(); ++i) {
      if (!std::isfinite(e.x[i])) continue;
      if (e.x[i] < prev) {
        throw Error("envelope '" + e.name + "': x decreases at sample " + std::to_string(i) +
                    " (an envelope is drawn over increasing x)");
      }
      prev = e.x[i];
    }
    envelopes_.push_back(std::move(e));
    return *this;
  }
  /// Draws a horizontal band between y_low and y_high (either order) over the full width.
  LineChart& band(double y_low, double y_high, std::string label = {}, std::string colour = {}) {
    require(std::isfinite(y_low) && std::isfinite(y_high),
            "horizontal band '" + label + "' needs finite bounds");
    bands_.push_back(
        {std::min(y_low, y_high), std::max(y_low, y_high), std::move(label), std::move(colour)});
    return *this;
  }

  /// Number of series added.
  [[nodiscard]] std::size_t num_series() const noexcept { return series_.size(); }
  /// The series added, in order.
  [[nodiscard]] const std::vector<ChartSeries>& series() const noexcept { return series_; }

  /// The chart as an `<svg class="nlid-chart">` element (inline in HTML, or a file by itself).
  [[nodiscard]] std::string svg() const;
  /// Writes `svg()` as a standalone SVG file, atomically.
  void write(const std::string& path) const { write_file_atomically(path, svg() + "\n"); }

 private:
  template <class R>
  static std::vector<double> copy(const R& r) {
    const double* p = r.data();
    return std::vector<double>(p, p + static_cast<std::ptrdiff_t>(r.size()));
  }
  static void check_limits(double lo, double hi, const char* what) {
    require(std::isfinite(lo) && std::isfinite(hi) && lo < hi && std::isfinite(hi - lo),
            std::string(what) + " needs finite lo < hi");
  }

  std::string title_, x_label_, y_label_;
  int width_ = 720;
  int height_ = 360;
  std::pair<double, double> x_limits_{0, 1}, y_limits_{0, 1};
  bool has_x_limits_ = false;
  bool has_y_limits_ = false;
  bool decimate_ = true;
  std::vector<ChartSeries> series_;
  std::vector<ShadedInterval> shaded_;
  std::vector<HorizontalBand> bands_;
  std::vector<ChartEnvelope> envelopes_;
};

/// One bar of a `BarChart`.
struct ChartBar {
  std::string label;       ///< category text (escaped)
  double value = 0;        ///< bar length; NaN is shown as "n/a" without a bar
  std::string colour;      ///< empty: the chart's bar colour (or the highlight colour)
  bool highlight = false;  ///< draw in the accent colour (the chosen order, the best candidate)
};

/// A bar chart: one value per category, e.g. loss per ARX order or fit % per candidate model.
///
///     nlid::BarChart b("Fit on data5 (%)");
///     b.horizontal(true).value_label("fit (%)");
///     for (auto& [name, fit] : ranking) b.add(name, fit);
///     b.highlight(0);   // the winner
class BarChart {
 public:
  /// An empty chart (720 x 360 px).
  BarChart() = default;
  /// An empty chart with a title.
  explicit BarChart(std::string title) : title_(std::move(title)) {}

  /// Title above the plot.
  BarChart& title(std::string text) {
    title_ = std::move(text);
    return *this;
  }
  /// Axis label of the categories.
  BarChart& category_label(std::string text) {
    category_label_ = std::move(text);
    return *this;
  }
  /// Axis label of the values.
  BarChart& value_label(std::string text) {
    value_label_ = std::move(text);
    return *this;
  }
  /// Overall size in px, at least 240 x 160.
  BarChart& size(int width, int height) {
    require(width >= 240 && height >= 160 && width <= 20000 && height <= 20000,
            "chart size must be between 240 x 160 and 20000 x 20000 px, got " +
                std::to_string(width) + " x " + std::to_string(height));
    width_ = width;
    height_ = height;
    return *this;
  }
  /// Bars grow rightwards with categories listed top to bottom (good for long names).
  BarChart& horizontal(bool on) {
    horizontal_ = on;
    return *this;
  }
  /// Logarithmic value axis (every value must then be positive; checked in `svg()`).
  BarChart& log_scale(bool on) {
    log_ = on;
    return *this;
  }
  /// Significant digits of the value printed at each bar (default 4; 0 hides the values).
  BarChart& value_digits(int digits) {
    require(digits >= 0 && digits <= 17, "value_digits must be in [0, 17]");
    digits_ = digits;
    return *this;
  }
  /// Adds a bar.
  BarChart& add(std::string label, double value, std::string colour = {}) {
    bars_.push_back({std::move(label), value, std::move(colour), false});
    return *this;
  }
  /// Adds a prepared bar.
  BarChart& add(ChartBar bar) {
    bars_.push_back(std::move(bar));
    return *this;
  }
  /// Highlights bar `index` (throws if out of range).
  BarChart& highlight(std::size_t index) {
    require(index < bars_.size(), "highlight index " + std::to_string(index) + " out of range (" +
                                      std::to_string(bars_.size()) + " bars)");
    bars_[index].highlight = true;
    return *this;
  }
  /// Number of bars.
  [[nodiscard]] std::size_t num_bars() const noexcept { return bars_.size(); }
  /// The chart as an `<svg class="nlid-chart">` element.
  [[nodiscard]] std::string svg() const;
  /// Writes `svg()` as a standalone SVG file, atomically.
  void write(const std::string& path) const { write_file_atomically(path, svg() + "\n"); }

 private:
  std::string title_, category_label_, value_label_;
  int width_ = 720;
  int height_ = 360;
  bool horizontal_ = false;
  bool log_ = false;
  int digits_ = 4;
  std::vector<ChartBar> bars_;
};

/// The default series colours, in order (Tableau 10: distinguishable, print well in grey).
inline constexpr const char* chart_palette[] = {"#1f77b4", "#ff7f0e", "#2ca02c", "#d62728",
                                                "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
                                                "#bcbd22", "#17becf"};

// ==== Implementation details below ============================================================

namespace detail {

/// XML/HTML text and attribute escaping. Also replaces what XML 1.0 forbids (C0 controls other
/// than tab/newline/CR) and malformed UTF-8 with U+FFFD, so the result is valid in both an HTML
/// page and a standalone .svg file.
inline std::string escape_xml(std::string_view text) {
  std::string out;
  out.reserve(text.size() + 8);
  std::size_t i = 0;
  while (i < text.size()) {
    const unsigned char c = static_cast<unsigned char>(text[i]);
    if (c >= 0x80) {
      const std::size_t n = utf8_sequence_length(text, i);  // core/utf8.hpp: Unicode table 3-7
      if (n == 0) {
        out.append("\xEF\xBF\xBD");  // U+FFFD replacement character
        ++i;
        continue;
      }
      // U+FFFE and U+FFFF are well-formed UTF-8 but not XML 1.0 characters: one replacement
      // for the whole sequence, as for any other character the markup cannot hold.
      if (n == 3 && c == 0xEF && static_cast<unsigned char>(text[i + 1]) == 0xBF &&
          static_cast<unsigned char>(text[i + 2]) >= 0xBE) {
        out.append("\xEF\xBF\xBD");
      } else {
        out.append(text.substr(i, n));
      }
      i += n;
      continue;
    }
    switch (c) {
      case '&':
        out.append("&amp;");
        break;
      case '<':
        out.append("&lt;");
        break;
      case '>':
        out.append("&gt;");
        break;
      case '"':
        out.append("&quot;");
        break;
      case '\'':
        out.append("&#39;");
        break;
      default:
        if (c < 0x20 && c != '\t' && c != '\n' && c != '\r') {
          out.append("\xEF\xBF\xBD");
        } else {
          out.push_back(static_cast<char>(c));
        }
    }
    ++i;
  }
  return out;
}

/// `v` with `significant` digits, shortest of fixed/scientific (like printf %g), "-0" -> "0".
inline std::string format_general(double v, int significant) {
  if (std::isnan(v)) return "NaN";
  if (std::isinf(v)) return v > 0 ? "Inf" : "-Inf";
  if (v == 0) return "0";
  char buf[64];
  const auto r =
      std::to_chars(buf, buf + sizeof buf, v, std::chars_format::general, std::max(1, significant));
  return std::string(buf, r.ptr);
}

/// `v` with exactly `decimals` digits after the point.
inline std::string format_fixed(double v, int decimals) {
  if (std::isnan(v)) return "NaN";
  if (std::isinf(v)) return v > 0 ? "Inf" : "-Inf";
  char buf[512];
  const auto r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::fixed, decimals);
  std::string s(buf, r.ptr);
  if (s.front() == '-' && s.find_first_not_of("-0.") == std::string::npos) s.erase(0, 1);  // -0
  return s;
}

/// A pixel coordinate with one decimal (0.1 px is below what a screen shows).
inline void append_coord(std::string& out, double v) {
  // Far-off points are clipped anyway; clamping keeps the text short, and NaN (from an
  // overflowing mapping) must never reach the markup, where it would void the whole path.
  v = std::isnan(v) ? 0.0 : std::clamp(v, -1e6, 1e6);
  char buf[32];
  const auto r =
      std::to_chars(buf, buf + sizeof buf, std::round(v * 10) / 10, std::chars_format::fixed, 1);
  std::string_view s(buf, static_cast<std::size_t>(r.ptr - buf));
  if (s.size() > 2 && s.substr(s.size() - 2) == ".0") s.remove_suffix(2);
  if (s == "-0") s = "0";
  out.append(s);
}

/// Approximate rendered width of `text` in px for a sans-serif font of `font_px` (average
/// advance ~0.58 em per code point): enough to lay out legends and margins without a font.
inline double text_width(std::string_view text, double font_px) {
  std::size_t points = 0;
  for (char ch : text) points += (static_cast<unsigned char>(ch) & 0xC0) != 0x80;
  return 0.58 * font_px * static_cast<double>(points);
}

/// `text` cut at a code-point boundary so that it fits `max_px`, with "..." appended if cut.
inline std::string fit_text(const std::string& text, double max_px, double font_px) {
  if (text_width(text, font_px) <= max_px) return text;
  const double budget = max_px - text_width("...", font_px);
  std::size_t end = 0;
  double w = 0;
  while (end < text.size()) {
    std::size_t next = end + 1;
    while (next < text.size() && (static_cast<unsigned char>(text[next]) & 0xC0) == 0x80) ++next;
    w += 0.58 * font_px;
    if (w > budget) break;
    end = next;
  }
  return text.substr(0, end) + "...";
}

/// Nice tick positions covering [lo, hi] with about `target` intervals (Heckbert 1990).
struct Ticks {
  std::vector<double> values;
  double step = 1;
};
inline Ticks nice_ticks(double lo, double hi, double target) {
  Ticks t;
  const double span = hi - lo;
  if (!(span > 0) || !std::isfinite(span)) return t;
  // A step below ~1e-14 of the values cannot be told apart in a label (nor, near 2^53 / step,
  // counted in k += 1): y in [1e17, 1e17 + 32] gave 100 identical ticks. Such a range gets the
  // finest step its labels can show, even if that leaves a single tick.
  const double resolution = std::max(std::abs(lo), std::abs(hi)) * 1e-14;
  const double raw = std::max(span / std::max(1.0, target), resolution);
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  const double f = raw / mag;
  t.step = (f < 1.5 ? 1.0 : f < 3.0 ? 2.0 : f < 7.0 ? 5.0 : 10.0) * mag;
  const double first = std::ceil(lo / t.step - 1e-9);
  for (double k = first; k * t.step <= hi + t.step * 1e-9 && t.values.size() < 100; k += 1) {
    double v = k * t.step;
    if (std::abs(v) < t.step * 1e-9) v = 0;  // no "-0" or 1e-17 labels
    t.values.push_back(v);
  }
  return t;
}

/// Label of a tick: the decimals the step needs; scientific for very large or small values.
inline std::string format_tick(double v, double step, double max_abs) {
  if (max_abs >= 1e6 || step < 1e-4) {
    const int digits =
        std::clamp(static_cast<int>(std::floor(std::log10(std::max(max_abs, step)))) -
                       static_cast<int>(std::floor(std::log10(step))) + 1,
                   1, 15);
    return format_general(v, digits);
  }
  const int decimals = std::max(0, -static_cast<int>(std::floor(std::log10(step) + 1e-9)));
  return format_fixed(v, decimals);
}

/// Writes the common parts of both chart kinds: root element, title, frame, axis labels.
struct SvgFrame {
  int width, height;
  double left, top, right, bottom;  // plot box edges in px
  std::string out;

  SvgFrame(int w, int h, const std::string& title) : width(w), height(h) {
    left = top = right = bottom = 0;
    out.reserve(4096);
    out.append(R"(<svg xmlns="http://www.w3.org/2000/svg" class="nlid-chart" width=")")
        .append(std::to_string(w))
        .append(R"(" height=")")
        .append(std::to_string(h))
        .append(R"(" viewBox="0 0 )")
        .append(std::to_string(w) + " " + std::to_string(h))
        .append(R"(" role="img" aria-label=")")
        .append(escape_xml(title.empty() ? std::string("chart") : title))
        .append(R"(" font-family="system-ui, -apple-system, 'Segoe UI', Roboto, 'DejaVu Sans', )"
                R"(Arial, sans-serif" font-size="11">)")
        .append("\n");
    if (!title.empty()) out.append("<title>").append(escape_xml(title)).append("</title>\n");
    out.append(R"(<rect width="100%" height="100%" fill="#fff"/>)").append("\n");
    if (!title.empty()) {
      text(w / 2.0, 18, title, "middle", R"( font-size="14" font-weight="600")");
    }
  }
  // `tooltip` (the full text of a shortened label) becomes a <title> the browser shows on hover.
  void text(double x, double y, std::string_view s, const char* anchor, std::string_view extra = {},
            std::string_view tooltip = {}) {
    out.append("<text x=\"");
    append_coord(out, x);
    out.append("\" y=\"");
    append_coord(out, y);
    out.append("\" text-anchor=\"").append(anchor).append("\"").append(extra).append(">");
    if (!tooltip.empty()) out.append("<title>").append(escape_xml(tooltip)).append("</title>");
    out.append(escape_xml(s)).append("</text>\n");
  }
  void rect(double x0, double y0, double x1, double y1, std::string_view fill,
            std::string_view extra = {}) {
    out.append("<rect x=\"");
    append_coord(out, std::min(x0, x1));
    out.append("\" y=\"");
    append_coord(out, std::min(y0, y1));
    out.append("\" width=\"");
    append_coord(out, std::abs(x1 - x0));
    out.append("\" height=\"");
    append_coord(out, std::abs(y1 - y0));
    out.append("\" fill=\"").append(escape_xml(fill)).append("\"").append(extra).append("/>\n");
  }
  void line(double x0, double y0, double x1, double y1, std::string_view stroke,
            std::string_view extra = {}) {
    out.append("<line x1=\"");
    append_coord(out, x0);
    out.append("\" y1=\"");
    append_coord(out, y0);
    out.append("\" x2=\"");
    append_coord(out, x1);
    out.append("\" y2=\"");
    append_coord(out, y1);
    out.append("\" stroke=\"").append(stroke).append("\"").append(extra).append("/>\n");
  }
  // A nested <svg> clips its content to the plot box without needing a document-unique id.
  void open_clip() {
    out.append("<svg x=\"");
    append_coord(out, left);
    out.append("\" y=\"");
    append_coord(out, top);
    out.append("\" width=\"");
    append_coord(out, right - left);
    out.append("\" height=\"");
    append_coord(out, bottom - top);
    out.append("\" viewBox=\"");
    append_coord(out, left);
    out.append(" ");
    append_coord(out, top);
    out.append(" ");
    append_coord(out, right - left);
    out.append(" ");
    append_coord(out, bottom - top);
    out.append("\" overflow=\"hidden\">\n");
  }
  void close_clip() { out.append("</svg>\n"); }
  void frame() { rect(left, top, right, bottom, "none", R"( stroke="#444" stroke-width="1")"); }
  void axis_labels(const std::string& x_label, const std::string& y_label) {
    if (!x_label.empty()) text((left + right) / 2, height - 8.0, x_label, "middle");
    if (!y_label.empty()) {
      const double cy = (top + bottom) / 2;
      out.append("<text x=\"14\" y=\"");
      append_coord(out, cy);
      out.append("\" text-anchor=\"middle\" transform=\"rotate(-90 14 ");
      append_coord(out, cy);
      out.append(")\">").append(escape_xml(y_label)).append("</text>\n");
    }
  }
  std::string finish() {
    out.append("</svg>");
    return std::move(out);
  }
};

/// Dash pattern attribute of a line style. Dots use round caps on a 1.5 px dash, which renders as
/// dots at any stroke width; lengths are in px of the chart, so they scale with the figure.
inline const char* dash_array(LineStyle s) {
  switch (s) {
    case LineStyle::dashed:
      return R"( stroke-dasharray="6 4")";
    case LineStyle::dotted:
      return R"( stroke-dasharray="1.5 3" stroke-linecap="round")";
    case LineStyle::solid:
      break;
  }
  return "";
}

/// Indices of the points to draw from the finite run [b, e) of a sorted series: per pixel
/// column the first, min, max and last sample, in index order (M4, Jugel et al. 2014).
inline void m4_indices(const std::vector<double>& x, const std::vector<double>& y, std::size_t b,
                       std::size_t e, double x_lo, double x_hi, int columns,
                       std::vector<std::size_t>& keep) {
  const double scale = static_cast<double>(columns) / (x_hi - x_lo);
  // The run may include one point beyond each axis limit (so the line reaches the frame):
  // clamping puts those into virtual columns -1 and `columns`, which keeps them separate.
  const auto column_of = [&](std::size_t i) {
    const double c = std::floor((x[i] - x_lo) * scale);
    return static_cast<long>(std::clamp(c, -1.0, static_cast<double>(columns)));
  };
  std::size_t i = b;
  while (i < e) {
    const long col = column_of(i);
    std::size_t first = i, last = i, lo = i, hi = i;
    while (i < e && column_of(i) == col) {
      if (y[i] < y[lo]) lo = i;
      if (y[i] > y[hi]) hi = i;
      last = i;
      ++i;
    }
    // Time order matters: emitting min before max when the max came first would draw a
    // different polyline (and connect to the neighbouring columns at the wrong height).
    std::size_t pick[4] = {first, lo, hi, last};
    std::sort(pick, pick + 4);
    for (std::size_t k = 0; k < 4; ++k) {
      if (k == 0 || pick[k] != pick[k - 1]) keep.push_back(pick[k]);
    }
  }
}

}  // namespace detail

inline std::string LineChart::svg() const {
  using detail::append_coord;
  // ---- data ranges -------------------------------------------------------------------------
  // Only finite samples count: one NaN must not turn the whole axis into NaN. With fixed x
  // limits the y range follows the visible part, as a zoomed plot should.
  double xmin = std::numeric_limits<double>::infinity(), xmax = -xmin;
  double ymin = xmin, ymax = -xmin;
  std::vector<std::size_t> non_finite(series_.size(), 0);
  for (std::size_t s = 0; s < series_.size(); ++s) {
    const ChartSeries& se = series_[s];
    for (std::size_t i = 0; i < se.x.size(); ++i) {
      if (!std::isfinite(se.x[i]) || !std::isfinite(se.y[i])) {
        ++non_finite[s];
        continue;
      }
      xmin = std::min(xmin, se.x[i]);
      xmax = std::max(xmax, se.x[i]);
      if (!has_x_limits_ || (se.x[i] >= x_limits_.first && se.x[i] <= x_limits_.second)) {
        ymin = std::min(ymin, se.y[i]);
        ymax = std::max(ymax, se.y[i]);
      }
    }
  }
  // An envelope is data too: the axes hold its finite samples (within fixed x limits).
  for (const ChartEnvelope& en : envelopes_) {
    for (std::size_t i = 0; i < en.x.size(); ++i) {
      if (!std::isfinite(en.x[i]) || !std::isfinite(en.lower[i]) || !std::isfinite(en.upper[i])) continue;
      xmin = std::min(xmin, en.x[i]);
      xmax = std::max(xmax, en.x[i]);
      if (!has_x_limits_ || (en.x[i] >= x_limits_.first && en.x[i] <= x_limits_.second)) {
        ymin = std::min({ymin, en.lower[i], en.upper[i]});
        ymax = std::max({ymax, en.lower[i], en.upper[i]});
      }
    }
  }
  // Bands and shaded intervals are part of the message (e.g. where the hard stops are), so the
  // automatic axes always include them.
  for (const HorizontalBand& b : bands_) {
    ymin = std::min(ymin, b.y_low);
    ymax = std::max(ymax, b.y_high);
  }
  for (const ShadedInterval& s : shaded_) {
    xmin = std::min(xmin, s.x_begin);
    xmax = std::max(xmax, s.x_end);
  }
  const bool no_data = !(xmin <= xmax);
  // A degenerate range (no data, or a constant) gets a span, so the mapping never divides by 0.
  const auto widen = [](double& lo, double& hi) {
    if (!(lo <= hi)) {
      lo = 0;
      hi = 1;
    } else if (lo == hi) {
      const double d = lo == 0 ? 1.0 : std::abs(lo) * 0.1;
      lo -= d;
      hi += d;
    }
  };
  // Axis spans must stay finite: a diverged simulation can reach +-1e308, and max - min would
  // overflow to infinity. Data beyond +-1e307 is drawn clipped at the frame.
  const auto cap = [](double& v) { v = std::clamp(v, -1e307, 1e307); };
  cap(xmin), cap(xmax), cap(ymin), cap(ymax);
  widen(xmin, xmax);
  if (ymin <= ymax && ymin != ymax) {
    const double pad = 0.05 * (ymax - ymin);
    ymin -= pad;
    ymax += pad;
  }
  widen(ymin, ymax);
  const double x_lo = has_x_limits_ ? x_limits_.first : xmin;
  const double x_hi = has_x_limits_ ? x_limits_.second : xmax;
  const double y_lo = has_y_limits_ ? y_limits_.first : ymin;
  const double y_hi = has_y_limits_ ? y_limits_.second : ymax;

  // ---- layout ------------------------------------------------------------------------------
  // The left margin depends on the widest y tick label, so the y ticks are computed first. The
  // plot box then takes what is left after title, legend rows and axis labels; no font metrics
  // are available, so text widths are estimated (detail::text_width) with a safety gap.
  detail::SvgFrame f(width_, height_, title_);
  const detail::Ticks yt = detail::nice_ticks(y_lo, y_hi, (height_ - 100) / 50.0);
  const double y_abs = std::max(std::abs(y_lo), std::abs(y_hi));
  double tick_w = 0;
  for (double v : yt.values) {
    tick_w = std::max(tick_w, detail::text_width(detail::format_tick(v, yt.step, y_abs), 11));
  }
  f.left = std::ceil(tick_w) + 12 + (y_label_.empty() ? 6 : 24);
  f.right = width_ - 16.0;
  // Legend entries flow in rows under the title, like words in a paragraph. Keeping the legend
  // out of the plot box means it can never hide data (an in-plot legend box often covers the
  // very transient the chart is about). Each entry: 20 px swatch, gap, text, 14 px spacing.
  struct Entry {
    std::string text;
    double x, y;
  };
  std::vector<Entry> legend;
  double lx = f.left, ly = title_.empty() ? 14.0 : 38.0;
  for (std::size_t s = 0; s < series_.size(); ++s) {
    std::string text = series_[s].name;
    if (non_finite[s] > 0) {
      text += " (" + std::to_string(non_finite[s]) + " non-finite samples not drawn)";
    }
    if (text.empty()) continue;
    const double w = 26 + detail::text_width(text, 11) + 14;
    if (lx + w > f.right && lx > f.left) {
      lx = f.left;
      ly += 16;
    }
    legend.push_back({std::move(text), lx, ly});
    lx += w;
  }
  const std::size_t series_entries = legend.size();
  for (const ChartEnvelope& en : envelopes_) {
    if (en.name.empty()) continue;
    const double w = 26 + detail::text_width(en.name, 11) + 14;
    if (lx + w > f.right && lx > f.left) {
      lx = f.left;
      ly += 16;
    }
    legend.push_back({en.name, lx, ly});
    lx += w;
  }
  f.top = legend.empty() ? (title_.empty() ? 12.0 : 30.0) : ly + 12;
  f.bottom = height_ - (x_label_.empty() ? 24.0 : 40.0);
  require(f.bottom - f.top >= 40 && f.right - f.left >= 80,
          "chart '" + title_ + "' is too small for its legend and labels; enlarge it with size()");
  const double pw = f.right - f.left, ph = f.bottom - f.top;
  const auto px = [&](double x) { return f.left + (x - x_lo) / (x_hi - x_lo) * pw; };
  const auto py = [&](double y) { return f.top + (y_hi - y) / (y_hi - y_lo) * ph; };

  // ---- grid and ticks ----------------------------------------------------------------------
  // ~80 px per x tick leaves room for labels like "-12.5"; long labels (time stamps like
  // 1000000000.0002) get fewer ticks so they do not overlap. The grid is light so data dominates.
  const double x_abs = std::max(std::abs(x_lo), std::abs(x_hi));
  detail::Ticks xt = detail::nice_ticks(x_lo, x_hi, pw / 80.0);
  for (int attempt = 0; attempt < 4 && xt.values.size() > 2; ++attempt) {
    double widest = 0;
    for (double v : xt.values) {
      widest = std::max(widest, detail::text_width(detail::format_tick(v, xt.step, x_abs), 11));
    }
    const double spacing = pw * xt.step / (x_hi - x_lo);
    if (widest + 12 <= spacing) break;
    xt = detail::nice_ticks(x_lo, x_hi, pw / (widest + 12) * 0.9);
  }
  f.out.append("<g stroke=\"#e5e5e5\" stroke-width=\"1\">\n");
  for (double v : xt.values) f.line(px(v), f.top, px(v), f.bottom, "#e5e5e5");
  for (double v : yt.values) f.line(f.left, py(v), f.right, py(v), "#e5e5e5");
  f.out.append("</g>\n<g fill=\"#333\">\n");
  for (double v : xt.values) {
    f.line(px(v), f.bottom, px(v), f.bottom + 4, "#444");
    f.text(px(v), f.bottom + 15, detail::format_tick(v, xt.step, x_abs), "middle");
  }
  for (double v : yt.values) {
    f.line(f.left - 4, py(v), f.left, py(v), "#444");
    f.text(f.left - 6, py(v) + 4, detail::format_tick(v, yt.step, y_abs), "end");
  }
  f.out.append("</g>\n");

  // ---- shaded intervals, bands, series (clipped to the plot box) ---------------------------
  // Drawing order is painter's order: areas first, then lines over them, then their labels.
  f.open_clip();
  for (const HorizontalBand& b : bands_) {
    const std::string c = b.colour.empty() ? "#7f7f7f" : b.colour;
    f.rect(f.left, py(b.y_high), f.right, py(b.y_low), c, R"( fill-opacity="0.15")");
  }
  for (const ShadedInterval& s : shaded_) {
    const std::string c = s.colour.empty() ? "#d62728" : s.colour;
    f.rect(px(s.x_begin), f.top, px(s.x_end), f.bottom, c, R"( fill-opacity="0.15")");
  }
  // Envelopes: one closed polygon per finite run — the upper edge forwards, the lower back.
  std::vector<std::string> envelope_colours;
  for (const ChartEnvelope& en : envelopes_) {
    envelope_colours.push_back(en.colour.empty() ? std::string(chart_palette[0]) : en.colour);
    const int columns = static_cast<int>(std::ceil(pw));
    const std::size_t n = en.x.size();
    auto finite = [&](std::size_t k) {
      return std::isfinite(en.x[k]) && std::isfinite(en.lower[k]) && std::isfinite(en.upper[k]);
    };
    std::string d;
    std::size_t drawn = 0;
    std::size_t i = 0;
    std::vector<double> ex, elo, ehi;  // the run's points after per-column reduction
    while (i < n) {
      while (i < n && !finite(i)) ++i;
      std::size_t b = i;
      while (i < n && finite(i)) ++i;
      std::size_t e = i;
      if (e == b) continue;
      while (b + 1 < e && en.x[b + 1] < x_lo) ++b;  // the visible part, one sample beyond each side
      while (e - 1 > b + 1 && en.x[e - 2] > x_hi) --e;
      ex.clear(), elo.clear(), ehi.clear();
      const bool reduce = decimate_ && (e - b) > static_cast<std::size_t>(2 * columns);
      for (std::size_t k = b; k < e; ++k) {
        const double lo = std::min(en.lower[k], en.upper[k]), hi = std::max(en.lower[k], en.upper[k]);
        // A pixel column keeps its first abscissa with the widest extent of its samples (compared
        // as doubles: the one sample kept beyond fixed x limits may lie far outside int's range).
        const double col = std::floor(px(en.x[k]) - f.left);
        if (reduce && !ex.empty() && std::floor(px(ex.back()) - f.left) == col) {
          elo.back() = std::min(elo.back(), lo);
          ehi.back() = std::max(ehi.back(), hi);
          continue;
        }
        ex.push_back(en.x[k]);
        elo.push_back(lo);
        ehi.push_back(hi);
      }
      for (std::size_t k = 0; k < ex.size(); ++k) {
        d.append(k == 0 ? (d.empty() ? "M" : " M") : " L");
        append_coord(d, px(ex[k]));
        d.push_back(',');
        append_coord(d, py(ehi[k]));
      }
      for (std::size_t k = ex.size(); k-- > 0;) {
        d.append(" L");
        append_coord(d, px(ex[k]));
        d.push_back(',');
        append_coord(d, py(elo[k]));
      }
      d.append(" Z");
      drawn += ex.size();
    }
    if (d.empty()) continue;
    f.out.append("<path class=\"nlid-envelope\" data-points=\"")
        .append(std::to_string(drawn))
        .append("\" data-samples=\"")
        .append(std::to_string(n))
        .append("\" fill=\"")
        .append(detail::escape_xml(envelope_colours.back()))
        .append("\" fill-opacity=\"0.2\" stroke=\"none\" d=\"")
        .append(d)
        .append("\"/>\n");
  }
  std::size_t palette_next = 0;
  std::vector<std::string> colours;
  for (std::size_t s = 0; s < series_.size(); ++s) {
    const ChartSeries& se = series_[s];
    colours.push_back(se.colour.empty() ? chart_palette[palette_next++ % 10] : se.colour);
    // Sorted x (ignoring non-finite samples) allows per-pixel decimation: a pixel column is
    // then a contiguous index range. For unsorted x the same column is visited many times, and
    // keeping only its extremes would reorder the curve, so such series are drawn in full.
    bool sorted = true;
    double prev = -std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < se.x.size() && sorted; ++i) {
      if (!std::isfinite(se.x[i]) || !std::isfinite(se.y[i])) continue;
      sorted = se.x[i] >= prev;
      prev = se.x[i];
    }
    const int columns = static_cast<int>(std::ceil(pw));
    std::vector<std::size_t> keep;
    std::size_t i = 0;
    const std::size_t n = se.x.size();
    // Split at non-finite samples: each finite run becomes one "M ... L ..." subpath, so a NaN
    // shows as a visible gap rather than as a line bridging it.
    std::vector<std::pair<std::size_t, std::size_t>> runs;  // finite runs [b, e)
    while (i < n) {
      while (i < n && (!std::isfinite(se.x[i]) || !std::isfinite(se.y[i]))) ++i;
      const std::size_t b = i;
      while (i < n && std::isfinite(se.x[i]) && std::isfinite(se.y[i])) ++i;
      if (i > b) runs.emplace_back(b, i);
    }
    std::string d;
    std::size_t drawn = 0;
    for (auto [b, e] : runs) {
      if (sorted) {
        // Only the visible part (plus one point each side, so lines reach the frame).
        while (b + 1 < e && se.x[b + 1] < x_lo) ++b;
        while (e - 1 > b + 1 && se.x[e - 2] > x_hi) --e;
      }
      keep.clear();
      // Below 4 samples per column M4 would keep nearly everything anyway; skip its overhead.
      if (decimate_ && sorted && (e - b) > static_cast<std::size_t>(4 * columns)) {
        detail::m4_indices(se.x, se.y, b, e, x_lo, x_hi, columns, keep);
      } else {
        for (std::size_t k = b; k < e; ++k) keep.push_back(k);
      }
      for (std::size_t k = 0; k < keep.size(); ++k) {
        d.append(k == 0 ? (d.empty() ? "M" : " M") : (k == 1 ? " L" : " "));
        append_coord(d, px(se.x[keep[k]]));
        d.push_back(',');
        append_coord(d, py(se.y[keep[k]]));
      }
      if (keep.size() == 1) {  // an isolated sample: a zero-length segment with round caps
        d.append(" l0,0");
      }
      drawn += keep.size();
    }
    if (d.empty()) continue;
    // data-points / data-samples record the decimation in the markup itself, so a reader (or a
    // test) can see how much was reduced without re-running anything.
    f.out.append("<path class=\"nlid-series\" data-points=\"")
        .append(std::to_string(drawn))
        .append("\" data-samples=\"")
        .append(std::to_string(n))
        .append("\" fill=\"none\" stroke=\"")
        .append(detail::escape_xml(colours.back()))
        .append("\" stroke-width=\"");
    append_coord(f.out, se.width);
    f.out.append("\" stroke-linejoin=\"round\" stroke-linecap=\"round\"")
        .append(detail::dash_array(se.style))
        .append(" d=\"")
        .append(d)
        .append("\"/>\n");
  }
  // Labels of intervals and bands go on top of the data, still inside the plot box.
  for (const ShadedInterval& s : shaded_) {
    if (!s.label.empty()) {
      f.text(std::max(px(s.x_begin), f.left) + 3, f.top + 12, s.label, "start",
             R"( fill="#a01c1c" font-size="10")");
    }
  }
  for (const HorizontalBand& b : bands_) {
    if (!b.label.empty()) {
      f.text(f.right - 4, std::clamp(py(b.y_high) - 3, f.top + 10, f.bottom - 3), b.label, "end",
             R"( fill="#555" font-size="10")");
    }
  }
  if (no_data) {
    f.text((f.left + f.right) / 2, (f.top + f.bottom) / 2, "no data", "middle", R"( fill="#999")");
  }
  f.close_clip();
  f.frame();

  // ---- legend and axis labels --------------------------------------------------------------
  // Entries were laid out above for exactly the series with legend text, in series order; walk
  // both lists together so each swatch gets its own series' colour and dash pattern.
  std::size_t e = 0;
  for (std::size_t s = 0; s < series_.size() && e < legend.size(); ++s) {
    if (series_[s].name.empty() && non_finite[s] == 0) continue;
    const Entry& en = legend[e++];
    f.out.append("<line x1=\"");
    append_coord(f.out, en.x);
    f.out.append("\" y1=\"");
    append_coord(f.out, en.y - 4);
    f.out.append("\" x2=\"");
    append_coord(f.out, en.x + 20);
    f.out.append("\" y2=\"");
    append_coord(f.out, en.y - 4);
    f.out.append("\" stroke=\"")
        .append(detail::escape_xml(colours[s]))
        .append("\" stroke-width=\"");
    append_coord(f.out, std::min(series_[s].width, 4.0));
    f.out.append("\"").append(detail::dash_array(series_[s].style)).append("/>\n");
    f.text(en.x + 26, en.y, en.text, "start");
  }
  // Envelope entries follow the series' ones: a filled swatch in the envelope's colour.
  e = series_entries;
  for (std::size_t v = 0; v < envelopes_.size() && e < legend.size(); ++v) {
    if (envelopes_[v].name.empty()) continue;
    const Entry& en = legend[e++];
    f.rect(en.x, en.y - 9, en.x + 20, en.y + 1, envelope_colours[v], R"( fill-opacity="0.35")");
    f.text(en.x + 26, en.y, en.text, "start");
  }
  f.axis_labels(x_label_, y_label_);
  return f.finish();
}

inline std::string BarChart::svg() const {
  using detail::append_coord;
  const std::size_t n = bars_.size();
  // ---- value range -------------------------------------------------------------------------
  double vmin = std::numeric_limits<double>::infinity(), vmax = -vmin;
  for (const ChartBar& b : bars_) {
    if (!std::isfinite(b.value)) continue;
    if (log_ && !(b.value > 0)) {
      throw Error("bar chart '" + title_ + "': log scale needs positive values, bar '" + b.label +
                  "' has " + detail::format_general(b.value, 6));
    }
    vmin = std::min(vmin, std::clamp(b.value, -1e307, 1e307));  // keep spans finite
    vmax = std::max(vmax, std::clamp(b.value, -1e307, 1e307));
  }
  // Linear axes always include 0: a bar's length is its value, and an axis starting at 80 would
  // make 81 look twice as good as 80.5. Log axes span whole decades (ticks at 10^k).
  double lo = 0, hi = 1;
  if (vmin <= vmax) {
    if (log_) {
      lo = std::pow(10.0, std::floor(std::log10(vmin)));
      hi = std::pow(10.0, std::ceil(std::log10(vmax)));
      if (lo == hi) hi = lo * 10;
    } else {
      lo = std::min(0.0, vmin);
      hi = std::max(0.0, vmax);
      if (lo == hi) hi = 1;
      const double pad = 0.08 * (hi - lo);  // room for the value labels
      if (vmax > 0) hi += pad;
      if (vmin < 0) lo -= pad;
    }
  }
  // Value axis transform (log10 for log scale) and its ticks.
  const auto tv = [&](double v) { return log_ ? std::log10(v) : v; };
  const double t_lo = tv(lo), t_hi = tv(hi);

  detail::SvgFrame f(width_, height_, title_);
  double max_label = 0;
  for (const ChartBar& b : bars_) max_label = std::max(max_label, detail::text_width(b.label, 11));
  // Category labels may take up to 40 % of the width (horizontal) or 200 px (rotated).
  const double label_cap = horizontal_ ? 0.4 * width_ : 200.0;
  max_label = std::min(max_label, label_cap);
  std::vector<double> ticks;
  double step = 1;
  if (log_) {
    for (double k = std::round(t_lo); k <= std::round(t_hi); k += 1)
      ticks.push_back(std::pow(10.0, k));
  } else {
    const double extent = horizontal_ ? width_ : height_;
    const detail::Ticks t =
        detail::nice_ticks(lo, hi, (extent - 100) / (horizontal_ ? 80.0 : 50.0));
    ticks = t.values;
    step = t.step;
  }
  const double v_abs = std::max(std::abs(lo), std::abs(hi));
  const auto tick_text = [&](double v) {
    if (!log_) return detail::format_tick(v, step, v_abs);
    char buf[32];  // decades: shortest form ("0.01", "10", "1e+06")
    const auto r = std::to_chars(buf, buf + sizeof buf, v);
    return std::string(buf, r.ptr);
  };
  double tick_w = 0;
  for (double v : ticks) tick_w = std::max(tick_w, detail::text_width(tick_text(v), 11));

  // Horizontal: the category labels set the left margin. Vertical: the tick labels do, and the
  // category labels rotate by 45 degrees once they no longer fit their slot, which costs height
  // (the rotated label's vertical extent is its width times sin 45 deg).
  const double top = title_.empty() ? 12.0 : 30.0;
  bool rotate = false;
  if (horizontal_) {
    f.left = std::ceil(max_label) + 12 + (category_label_.empty() ? 6 : 24);
    f.right = width_ - 16.0;
    f.top = top;
    f.bottom = height_ - (value_label_.empty() ? 24.0 : 40.0);
  } else {
    f.left = std::ceil(tick_w) + 12 + (value_label_.empty() ? 6 : 24);
    f.right = width_ - 16.0;
    f.top = top;
    const double slot = (f.right - f.left) / std::max<std::size_t>(n, 1);
    rotate = max_label > slot - 4;
    const double label_h = rotate ? max_label * 0.72 + 10 : 16;  // sin/cos 45 deg ~ 0.71
    f.bottom = height_ - (category_label_.empty() ? 10.0 : 26.0) - label_h;
  }
  require(f.bottom - f.top >= 40 && f.right - f.left >= 80,
          "bar chart '" + title_ + "' is too small for its labels; enlarge it with size()");

  // Value -> pixel along the value axis; category slots along the other.
  const auto vpos = [&](double v) {
    const double u = (tv(v) - t_lo) / (t_hi - t_lo);
    return horizontal_ ? f.left + u * (f.right - f.left) : f.bottom - u * (f.bottom - f.top);
  };
  const double extent = horizontal_ ? f.bottom - f.top : f.right - f.left;
  const double slot = extent / static_cast<double>(std::max<std::size_t>(n, 1));

  f.out.append("<g stroke=\"#e5e5e5\" stroke-width=\"1\">\n");
  for (double v : ticks) {
    if (horizontal_) {
      f.line(vpos(v), f.top, vpos(v), f.bottom, "#e5e5e5");
    } else {
      f.line(f.left, vpos(v), f.right, vpos(v), "#e5e5e5");
    }
  }
  f.out.append("</g>\n<g fill=\"#333\">\n");
  for (double v : ticks) {
    if (horizontal_) {
      f.text(vpos(v), f.bottom + 15, tick_text(v), "middle");
    } else {
      f.text(f.left - 6, vpos(v) + 4, tick_text(v), "end");
    }
  }
  f.out.append("</g>\n");

  // Bars grow from 0 (linear) or from the lowest decade (log, where 0 is at minus infinity).
  const double base = log_ ? lo : 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const ChartBar& b = bars_[i];
    const double c0 = (horizontal_ ? f.top : f.left) + slot * static_cast<double>(i);
    const double mid = c0 + slot / 2;
    const double thick = std::max(1.0, slot * 0.7);
    const std::string colour = !b.colour.empty() ? b.colour : (b.highlight ? "#d62728" : "#1f77b4");
    const std::string label = detail::fit_text(b.label, label_cap, 11);
    const std::string_view tooltip = label == b.label ? std::string_view() : b.label;
    const char* bold = b.highlight ? R"( font-weight="600")" : "";
    if (std::isfinite(b.value)) {
      const double p0 = vpos(base), p1 = vpos(b.value);
      const std::string extra =
          " class=\"nlid-bar\"" +
          std::string(b.highlight ? R"( stroke="#7a0f0f" stroke-width="1.5")" : "");
      if (horizontal_) {
        f.rect(p0, mid - thick / 2, p1, mid + thick / 2, colour, extra);
      } else {
        f.rect(mid - thick / 2, p0, mid + thick / 2, p1, colour, extra);
      }
      if (digits_ > 0) {
        const std::string vt = detail::format_general(b.value, digits_);
        if (horizontal_) {
          const bool neg = b.value < base;
          f.text(p1 + (neg ? -4 : 4), mid + 4, vt, neg ? "end" : "start", R"( font-size="10")");
        } else {
          const bool neg = b.value < base;
          f.text(mid, p1 + (neg ? 12 : -4), vt, "middle", R"( font-size="10")");
        }
      }
    } else {
      // No bar for a missing value, but say so: a silent gap would read as zero.
      if (horizontal_) {
        f.text(vpos(base) + 4, mid + 4, "n/a", "start", R"( fill="#999" font-size="10")");
      } else {
        f.text(mid, vpos(base) - 4, "n/a", "middle", R"( fill="#999" font-size="10")");
      }
    }
    if (horizontal_) {
      f.text(f.left - 6, mid + 4, label, "end", bold, tooltip);
    } else if (rotate) {
      f.out.append("<text x=\"");
      append_coord(f.out, mid);
      f.out.append("\" y=\"");
      append_coord(f.out, f.bottom + 14);
      f.out.append("\" text-anchor=\"end\" transform=\"rotate(-45 ");
      append_coord(f.out, mid);
      f.out.append(" ");
      append_coord(f.out, f.bottom + 14);
      f.out.append(")\"").append(bold).append(">");
      if (!tooltip.empty())
        f.out.append("<title>").append(detail::escape_xml(tooltip)).append("</title>");
      f.out.append(detail::escape_xml(label)).append("</text>\n");
    } else {
      f.text(mid, f.bottom + 15, label, "middle", bold, tooltip);
    }
  }
  // Zero line, so negative and positive bars read against the same baseline.
  if (!log_ && lo < 0 && hi > 0) {
    if (horizontal_) {
      f.line(vpos(0), f.top, vpos(0), f.bottom, "#444");
    } else {
      f.line(f.left, vpos(0), f.right, vpos(0), "#444");
    }
  }
  if (n == 0) {
    f.text((f.left + f.right) / 2, (f.top + f.bottom) / 2, "no data", "middle", R"( fill="#999")");
  }
  f.frame();
  if (horizontal_) {
    f.axis_labels(value_label_, category_label_);
  } else {
    f.axis_labels(category_label_, value_label_);
  }
  return f.finish();
}

}  // namespace nlid
