// Many trajectories at once: a Monte-Carlo study of how parameter perturbations spread the
// validation output of the study's nlarx5 model, with nlid::simulate_batched running W
// parameter sets in the SIMD lanes of one nlid::Batch<double, W> (core/batch.hpp).
//
// One free-run simulation is a recursion, bound by the latency of its critical path; W
// independent runs fill the core's vector units instead. The same model code serves both: the
// model is templated on its scalar, so Batch<double, W> simulates W parameter sets in lock step.
//
//   example_batched_simulation [--data DIR]   (DIR holds data1.csv ... data3.csv, 1 kHz)
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <iostream>
#include <random>
#include <span>
#include <string>
#include <vector>

#include "nlid/analysis/fit.hpp"
#include "nlid/core/batch.hpp"
#include "nlid/data/csv.hpp"
#include "nlid/data/resample.hpp"
#include "nlid/models/estimate.hpp"
#include "nlid/nonlinearities/sigmoid_network.hpp"
#include "nlid/regressors/lagged.hpp"

int main(int argc, char** argv) {
  std::string data_dir = std::string(NLID_EXAMPLE_DATA_DIR) + "/throttle";
  for (int i = 1; i < argc; ++i) {
    if (std::string(argv[i]) == "--data" && i + 1 < argc) {
      data_dir = argv[++i];
    } else {
      std::cerr << "usage: " << argv[0] << " [--data DIR]\n";
      return 2;
    }
  }
  try {
    auto load = [&](int k) { return nlid::decimate(nlid::read_csv(data_dir + "/data" + std::to_string(k) + ".csv"), 10); };
    const nlid::Experiment d1 = load(1), d2 = load(2), d3 = load(3);

    // nlarx5 of the study: [3 3 0] regressors, sigmoid network of 5 units with a linear term.
    using Model = nlid::Nlarx<nlid::LaggedRegressors<3, 3, 0>, nlid::SigmoidNet<6, 5>>;
    nlid::EstimateOptions options;
    options.focus = nlid::Focus::simulation;
    options.solver.max_iterations = 90;
    const Model model = nlid::estimate(Model{}, nlid::Dataset{d1, d2}, options);
    const Eigen::VectorXd theta = model.parameters();
    const Eigen::VectorXd x0 = model.initial_state(d3, nlid::InitialCondition::measured);

    // K parameter sets: every parameter perturbed by 0.3 % (relative, Gaussian) — a stand-in for
    // draws from the estimate's uncertainty. Column k of `thetas` is set k.
    const int runs = 256;
    std::mt19937_64 rng(1);
    std::normal_distribution<double> n01(0.0, 1.0);
    Eigen::MatrixXd thetas(theta.size(), runs), x0s(x0.size(), runs);
    for (int k = 0; k < runs; ++k) {
      for (Eigen::Index i = 0; i < theta.size(); ++i) thetas(i, k) = theta(i) * (1.0 + 0.003 * n01(rng));
      x0s.col(k) = x0;  // every run starts from data3's measured past
    }

    // All runs, 8 per batch.
    const auto t0 = std::chrono::steady_clock::now();
    const Eigen::MatrixXd y = nlid::simulate_batched<8>(model, d3.u(), thetas, x0s);
    const auto t1 = std::chrono::steady_clock::now();

    // The same runs one at a time, for comparison (and as a check of the batched numbers).
    Eigen::VectorXd one(d3.size());
    double worst = 0.0;
    for (int k = 0; k < runs; ++k) {
      const Eigen::VectorXd th = thetas.col(k);
      const bool ok = model.simulate(d3.u(), std::span<const double>(th.data(), static_cast<std::size_t>(th.size())),
                                     std::span<const double>(x0.data(), static_cast<std::size_t>(x0.size())),
                                     std::span<double>(one.data(), static_cast<std::size_t>(one.size())));
      if (ok) worst = std::max(worst, (one - y.col(k)).cwiseAbs().maxCoeff());
    }
    const auto t2 = std::chrono::steady_clock::now();

    // Spread of the validation fit over the runs, and the widest output band.
    std::vector<double> fits;
    for (int k = 0; k < runs; ++k) {
      if (y.col(k).allFinite()) fits.push_back(nlid::fit_percent(d3.y().col(0), y.col(k)));
    }
    std::sort(fits.begin(), fits.end());
    const Eigen::VectorXd band = y.rowwise().maxCoeff() - y.rowwise().minCoeff();
    const double ms_batch = std::chrono::duration<double, std::milli>(t1 - t0).count();
    const double ms_single = std::chrono::duration<double, std::milli>(t2 - t1).count();

    std::printf("nominal model: fit on data3 %.1f %%\n",
                nlid::fit_percent(d3.y().col(0), model.simulate(d3, nlid::InitialCondition::measured).col(0)));
    std::printf("%d perturbed parameter sets (0.3 %% each): %zu finite runs\n", runs, fits.size());
    if (!fits.empty()) {
      std::printf("fit on data3: min %.1f  median %.1f  max %.1f %%\n", fits.front(), fits[fits.size() / 2], fits.back());
    }
    std::printf("widest band of the simulated angle: %.2f deg (at sample %td)\n", band.maxCoeff(),
                static_cast<std::ptrdiff_t>(std::max_element(band.data(), band.data() + band.size()) - band.data()));
    std::printf("batched (Batch<double, 8> on the CPU's %zu-byte registers): %.1f ms, one at a time: %.1f ms (%.1fx); "
                "largest difference %.1e\n",
                nlid::cpu_register_bytes(), ms_batch, ms_single, ms_single / ms_batch, worst);
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 1;
  }
}
