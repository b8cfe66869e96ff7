// Writes a report that exercises every HtmlReport block and chart feature, for the headless
// browser check (render_check.sh). Usage: nlid_io_render_report <out.html> [<throttle data dir>]
// Prints the number of charts written on stdout, so the caller can pass it to the check.
//
// The report deliberately contains hostile text (a <script> that would throw, quotes, invalid
// UTF-8): if escaping ever broke, the browser would record a script error and the check fails.
#include <cmath>
#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include "nlid/data/csv.hpp"
#include "nlid/io.hpp"

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s <out.html> [<throttle data dir>]\n", argv[0]);
    return 2;
  }
  try {
    nlid::HtmlReport r("nlid render check <script>throw new Error('escaping broken')</script>");
    r.paragraph(
        "Hostile text must show, not run: <script>throw new Error('paragraph')</script> "
        "& \"quotes\" 'single' \xC3\x28 (invalid UTF-8)\nsecond line.");
    r.note("A located mismatch is shaded in the first chart.", nlid::NoteKind::warning);

    // A real 1 kHz recording (2e4 samples) when the data directory is given, plus a 1e5-sample
    // synthetic trace with one spike, so decimation is exercised on both.
    std::vector<double> t, y;
    if (argc > 2) {
      const nlid::Experiment e = nlid::read_csv(std::string(argv[2]) + "/data1.csv");
      const Eigen::VectorXd tt = e.time();
      t.assign(tt.data(), tt.data() + tt.size());
      y.assign(e.y().col(0).data(), e.y().col(0).data() + e.size());
    } else {
      for (int k = 0; k < 20000; ++k) {
        t.push_back(k * 1e-3);
        y.push_back(15 + 60 * (std::sin(k * 1e-3) > 0));
      }
    }
    std::vector<double> ysim(y.size());
    for (std::size_t k = 0; k < y.size(); ++k) ysim[k] = 0.95 * y[k] + 1.0;
    r.heading("Measured and simulated");
    nlid::LineChart c("Throttle angle, data1");
    c.x_label("time (s)").y_label("angle (deg)");
    c.line("measured", t, y).line("model <b>sim</b>", t, ysim, "", nlid::LineStyle::dashed);
    c.shade(t[t.size() / 3], t[t.size() / 2], "mismatch: hard stop?").band(88, 92, "upper stop");
    r.chart(c, "Shaded: located mismatch interval.");

    std::vector<double> xs(100000), ys(100000);
    for (std::size_t k = 0; k < xs.size(); ++k) {
      xs[k] = static_cast<double>(k) * 1e-4;
      ys[k] = std::sin(xs[k] * 6.0) + (k == 54321 ? 5.0 : 0.0);
    }
    ys[70000] = std::nan("");
    r.chart(nlid::LineChart("1e5 samples, one spike, one NaN").line("trace", xs, ys));

    r.heading("Order selection");
    nlid::BarChart b("ARX loss by order");
    b.category_label("[na nb nk]").value_label("loss").log_scale(true);
    const char* orders[] = {"[1 1 0]", "[2 1 0]", "[2 1 1]", "[3 2 0]", "[4 4 1]"};
    const double loss[] = {4.1, 0.52, 0.31, 0.30, 0.29};
    for (int i = 0; i < 5; ++i) b.add(orders[i], loss[i]);
    b.highlight(2);
    nlid::BarChart rank("Candidate fit on data5 (%)");
    rank.horizontal(true).value_label("fit (%)");
    rank.add("nlarx5 sigmoidnet(5) [3 3 0]", 91.2).add("nlhw2 pwlinear", 89.7);
    rank.add("nlarx1 linear", -12.5).add("grey box", std::nan(""));
    rank.highlight(0);
    r.grid({b.svg(), rank.svg()}, 2);

    r.heading("Fit table");
    r.table({"model", "data3", "data4", "data5", "iterations"},
            {{"nlarx5", 93.1234, 91.72, 88.2, 90}, {"<nlhw2>", 90.5, 89.9, std::nan(""), 200}},
            "Fit (%) per validation experiment");
    r.preformatted(
        "y(t) = F(y(t-1), y(t-2), y(t-3), u(t), u(t-1), u(t-2))\n  </pre><script>x</script>");
    r.write(argv[1]);
    std::printf("%zu\n", r.chart_count());
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }
}
