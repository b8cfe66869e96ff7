// Writes a diagnosis HTML report for the browser render check (tests/diagnose/render.cmake):
//   nlid_diagnose_render_report OUT.html
// A first-order lag with a concealed dead time is diagnosed (fast, deterministic); prints the
// number of charts the page holds, which render_check.sh then requires Chromium to lay out.
#include <cstdio>
#include <iostream>

#include "../synth.hpp"
#include "nlid/diagnose.hpp"
#include "nlid/diagnose/report.hpp"
#include "nlid/models/physics/first_order.hpp"

int main(int argc, char** argv) {
  if (argc < 2) {
    std::cerr << "usage: nlid_diagnose_render_report OUT.html\n";
    return 2;
  }
  try {
    using namespace nlid;
    const physics::FirstOrder fo;
    const double ts = 0.01;
    DataScales s;
    s.ts = ts / 4;
    AugmentedModel<physics::FirstOrder> truth(fo, diag_test::table(fo, {{"tau", 0.2}, {"gain", 2.0}, {"offset", 0.5}}), ts / 4);
    truth.add_effect(diag_test::effect(EffectKind::dead_time, {0.03}, s));
    const Eigen::VectorXd x0 = Eigen::VectorXd::Constant(1, 0.5);
    Dataset est, val;
    est.add(diag_test::synthesize(truth, diag_test::random_steps(1500, -1, 1, 40, 150, 11u), ts, x0, 0.01, 21u, "est", 4));
    val.add(diag_test::synthesize(truth, diag_test::random_steps(1500, -1, 1, 40, 150, 12u), ts, x0, 0.01, 22u, "val a", 4));
    val.add(diag_test::synthesize(truth, diag_test::random_steps(1500, -1, 1, 40, 150, 13u), ts, x0, 0.01, 23u, "val <b>", 4));
    DiagnoseOptions o;
    o.starts = 2;
    const auto d = diagnose(GreyBox<physics::FirstOrder>(), est, val, o);
    std::cout << write_diagnosis_html(d, argv[1]) << "\n";
    return 0;
  } catch (const std::exception& e) {
    std::cerr << e.what() << "\n";
    return 1;
  }
}
