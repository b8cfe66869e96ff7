// A run summary as JSON and a one-page HTML report with a chart, from a simulated step response.
// Usage: example_report_basics [output directory]   (writes step.json and step_report.html)
#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>
#include <vector>

#include "nlid/io.hpp"

int main(int argc, char** argv) {
  const std::string dir = argc > 1 ? argv[1] : ".";
  // A damped second-order step response, y'' + 2 zeta wn y' + wn^2 y = wn^2 u, sampled at 100 Hz.
  const double zeta = 0.3, wn = 8.0, ts = 0.01;
  std::vector<double> t, u, y;
  for (int k = 0; k < 300; ++k) {
    const double tk = k * ts, wd = wn * std::sqrt(1 - zeta * zeta);
    t.push_back(tk);
    u.push_back(1.0);
    y.push_back(1 - std::exp(-zeta * wn * tk) *
                        (std::cos(wd * tk) + zeta * wn / wd * std::sin(wd * tk)));
  }
  nlid::Json summary;  // insertion-ordered; numbers round-trip exactly
  summary["system"]["zeta"] = zeta;
  summary["system"]["wn"] = wn;
  summary["overshoot_percent"] =
      100 * std::exp(-std::numbers::pi * zeta / std::sqrt(1 - zeta * zeta));
  nlid::write_json(dir + "/step.json", summary);

  nlid::LineChart chart("Step response");
  chart.x_label("time (s)").y_label("output").line("u", t, u, "#7f7f7f", nlid::LineStyle::dotted);
  chart.line("y", t, y).band(0.98, 1.02, "2 % settling band");
  nlid::HtmlReport report("Step response of a second-order system");
  report.paragraph("Parameters: " + summary.at("system").json().dump(-1));
  report.table({"quantity", "value"},
               {{"overshoot (%)", summary.at("overshoot_percent").as_number()}});
  report.chart(chart);
  report.write(dir + "/step_report.html");
  std::printf("wrote %s/step.json and %s/step_report.html\n", dir.c_str(), dir.c_str());
}
