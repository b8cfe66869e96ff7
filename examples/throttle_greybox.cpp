// The grey-box section of the engine-throttle study, then the model put to work.
//
//   example_throttle_greybox [--data DIR] [--out DIR]
//
// 1. data1..data5 (1 kHz) decimated to 100 Hz; estimation data = data1 + data2 (one
//    multi-experiment data set), validation = data3, data4, data5.
// 2. The catalogue's throttle physics  y'' + c y' + k (y - rest) + K (stop penetration) = b u,
//    scaled from the data and estimated by simulation error with multi-start Levenberg-Marquardt
//    (quasi-random starts over each parameter's range: no hand-picked initial guesses).
// 3. Fit (%) of the free-run simulation on data1..5 (initial state estimated, as the study).
// 4. Linearisation at the equilibrium holding the valve at 45 degrees (discrete and continuous).
// 5. Residual analysis on the validation data (whiteness, independence of u).
// 6. C code: OUT/throttle_model.h/.c (RK4, same sub-steps, starts at rest for u = 0), and
//    OUT/greybox.json with every number printed here; residual charts OUT/greybox_resid_*.svg;
//    OUT/greybox_band_data4.svg: data4's simulation error against the parameters' ±2σ band.
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "nlid/analysis/compare.hpp"
#include "nlid/analysis/linearize.hpp"
#include "nlid/analysis/resid.hpp"
#include "nlid/codegen.hpp"
#include "nlid/core/atomic_file.hpp"
#include "nlid/data.hpp"
#include "nlid/io/json.hpp"
#include "nlid/io/json_eigen.hpp"
#include "nlid/io/svg_chart.hpp"
#include "nlid/models/equilibrium.hpp"
#include "nlid/models/greybox.hpp"
#include "nlid/models/simulation_band.hpp"
#include "nlid/models/greybox_estimate.hpp"
#include "nlid/models/physics/throttle.hpp"

namespace {
void rule(const char* title) { std::cout << "\n== " << title << " ==\n"; }
}  // namespace

int main(int argc, char** argv) {
  std::string data_dir = NLID_EXAMPLE_DATA_DIR "/throttle", out_dir = "out";
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if ((a == "--data" || a == "--out") && i + 1 < argc) {
      (a == "--data" ? data_dir : out_dir) = argv[++i];
    } else {
      std::cerr << "usage: " << argv[0] << " [--data DIR] [--out DIR]\n";
      return 2;
    }
  }
  try {
    std::filesystem::create_directories(out_dir);
    std::vector<nlid::Experiment> d;  // d[k] = data(k+1) at 100 Hz
    for (int k = 1; k <= 5; ++k) {
      nlid::Experiment e = nlid::decimate(nlid::read_csv(data_dir + "/data" + std::to_string(k) + ".csv"), 10);
      e.set_name("data" + std::to_string(k));
      d.push_back(std::move(e));
    }
    const nlid::Dataset estimation{d[0], d[1]};
    const nlid::Dataset all(d);
    const double ts = d[0].ts();

    rule("Grey-box estimation on data1 + data2 (simulation error, multi-start)");
    nlid::GreyBox<nlid::physics::Throttle> model;
    std::cout << "physics: " << model.physics().equation() << "\n";
    nlid::GreyBoxEstimateOptions opt;  // 24 quasi-random candidates, best 6 refined
    const nlid::GreyBoxEstimate est = nlid::estimate(model, estimation, opt);
    std::cout << est.report();
    std::cout << model.describe();

    rule("Fit (%) of the simulated output, initial state estimated");
    const nlid::CompareResult fit = nlid::compare(model, all, nlid::InitialCondition::estimate);
    std::cout << fit.table();

    rule("Simulation band from the parameters' uncertainty: can the parameters explain the error?");
    // The band holds each record's estimated initial state; est.uncertainty is the covariance the
    // estimation computed (correlated residuals), so the band includes c/k/b's strong correlation.
    const nlid::SimulationBand band = nlid::simulation_band(model, all, est.uncertainty);
    std::cout << band.report();
    {
      // The picture of the verdict: the error against what the parameters' uncertainty allows.
      const std::size_t k = 3;  // data4
      const Eigen::VectorXd t = all[k].time();
      const Eigen::VectorXd err = all[k].y().col(0) - band.y[k].col(0);
      const Eigen::VectorXd two_sigma = 2.0 * band.stddev[k].col(0);
      nlid::LineChart c("data4: simulation error and the parameters' +-2 sigma band");
      c.x_label("time (s)").y_label("measured - simulated (deg)");
      c.envelope("+-2 sigma from the parameters' covariance", t, Eigen::VectorXd(-two_sigma), two_sigma, "#1f77b4");
      c.line("simulation error", t, err, "#d62728");
      c.write(out_dir + "/greybox_band_data4.svg");
      std::cout << "wrote " << out_dir << "/greybox_band_data4.svg\n";
    }

    rule("Linearisation at the equilibrium holding the valve at 45 degrees");
    const nlid::OperatingPoint op45 = nlid::equilibrium_for_output(model, 45.0, 0.3);
    const nlid::Linearization lin = nlid::linearize(model, op45.x, op45.u, ts);
    std::cout << lin.describe();

    rule("Residual analysis on the validation data (data3, data4, data5)");
    nlid::ResidOptions ro;
    ro.source = nlid::ResidualSource::simulation;  // output-error model: prediction = simulation
    ro.initial_condition = nlid::InitialCondition::estimate;
    const nlid::Dataset validation{d[2], d[3], d[4]};
    const nlid::ResidAnalysis res = nlid::resid(model, validation, ro);
    std::cout << res.report();
    nlid::write_file_atomically(out_dir + "/greybox_resid_auto.svg", nlid::resid_chart_svg(res.whiteness) + "\n");
    nlid::write_file_atomically(out_dir + "/greybox_resid_cross.svg", nlid::resid_chart_svg(res.inputs[0]) + "\n");

    rule("C code generation");
    nlid::CodegenOptions co;
    co.name = "throttle_model";
    co.ts = ts;
    co.equilibrium_input = Eigen::VectorXd::Zero(1);  // NAME_init: at rest with the motor off
    const nlid::GeneratedCode code = nlid::generate_c(model, co);
    for (const auto& path : code.write(out_dir)) std::cout << "wrote " << path << "\n";
    std::cout << "step function: " << code.paths << " branch paths in f (smoothed stops), "
              << model.substeps(ts) << " RK4 sub-steps per 10 ms sample\n";

    nlid::Json j = nlid::Json::object();
    j["model"] = "throttle grey box";
    j["equation"] = model.physics().equation();
    j["sample_time"] = ts;
    j["estimation_data"] = nlid::Json::array({"data1", "data2"});
    nlid::Json params = nlid::Json::object();
    const Eigen::VectorXd p = model.parameters();
    for (std::size_t i = 0; i < model.parameter_info().size(); ++i) {
      const auto& q = model.parameter_info()[i];
      params[q.name] = nlid::Json::object({{"value", p(static_cast<Eigen::Index>(i))}, {"unit", q.unit}});
    }
    j["parameters"] = params;
    j["estimation"] = nlid::Json::object({{"cost", est.cost},
                                          {"seconds", est.seconds},
                                          {"starts_refined", static_cast<int>(est.multi_start.starts.size())},
                                          {"starts_within_1_percent", est.multi_start.num_within_tolerance},
                                          {"status", est.summary.message()}});
    nlid::Json fits = nlid::Json::object();
    for (std::size_t e = 0; e < fit.experiment_names.size(); ++e) fits[fit.experiment_names[e]] = fit.fit(static_cast<Eigen::Index>(e), 0);
    j["fit_percent"] = fits;
    nlid::Json bands = nlid::Json::object();
    for (std::size_t e = 0; e < band.experiment_names.size(); ++e) {
      const auto k = static_cast<Eigen::Index>(e);
      bands[band.experiment_names[e]] = nlid::Json::object({{"rms_sigma", band.rms_stddev(k, 0)},
                                                            {"max_sigma", band.max_stddev(k, 0)},
                                                            {"rms_error", band.rms_error(k, 0)},
                                                            {"reachable_share", band.reachable_share(k, 0)},
                                                            {"shift_sigmas", band.shift_sigmas(k, 0)},
                                                            {"plausible_share", band.plausible_share(k, 0)}});
    }
    j["simulation_band"] = bands;
    j["linearization"] = nlid::Json::object({{"u0", op45.u(0)},
                                             {"y0", op45.y(0)},
                                             {"A", nlid::to_json(lin.discrete.a())},
                                             {"B", nlid::to_json(lin.discrete.b())},
                                             {"C", nlid::to_json(lin.discrete.c())},
                                             {"D", nlid::to_json(lin.discrete.d())},
                                             {"Ac", nlid::to_json(lin.continuous->a)},
                                             {"Bc", nlid::to_json(lin.continuous->b)},
                                             {"static_gain", lin.discrete.dc_gain()(0, 0)}});
    j["residuals"] = nlid::Json::object({{"verdict", res.verdict()},
                                         {"white", res.white()},
                                         {"independent", res.independent()},
                                         {"rms", res.residual_rms}});
    j["generated_code"] = nlid::Json::array({"throttle_model.h", "throttle_model.c"});
    nlid::write_file_atomically(out_dir + "/greybox.json", j.dump() + "\n");
    std::cout << "wrote " << out_dir << "/greybox.json\n";
  } catch (const nlid::Error& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
