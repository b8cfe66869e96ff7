// A minimal compiled model variant: one nonlinear ARX type fixed at compile time (the study's
// nlarx5: orders [3 3 0], sigmoid network with 5 units and a linear term), its parameters read
// from a plain-text file, a free-run simulation printed to stdout. This is what an application
// embeds — no estimation, no CSV/JSON/report machinery — and scripts/minimal_size measures its
// compile time (-O2) and stripped size against the targets (≤ 10 s, ≤ 100 KB).
//
//   minimal_nlarx params.txt [input.txt]
//
// params.txt: whitespace-separated numbers — 6 regressor centres, 6 scales, then the 47
// parameters in SigmoidNet order (L[6], d, a[5], b[5][6], c[5]). input.txt: one input sample per
// line (default: a 0 → 1 step of 300 samples). cstdio rather than iostream keeps the binary small.
#include <cstdio>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "nlid/models/nlarx.hpp"
#include "nlid/nonlinearities/sigmoid_network.hpp"
#include "nlid/regressors/lagged.hpp"

using Model = nlid::Nlarx<nlid::LaggedRegressors<3, 3, 0>, nlid::SigmoidNet<6, 5>>;

namespace {

// Reads exactly n numbers; false (with a message naming the file and position) otherwise.
bool read_numbers(std::FILE* f, const char* path, double* out, int n) {
  for (int i = 0; i < n; ++i) {
    if (std::fscanf(f, "%lf", &out[i]) != 1) {
      std::fprintf(stderr, "%s: expected %d numbers, number %d is missing or not a number\n", path, n, i + 1);
      return false;
    }
  }
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s params.txt [input.txt]\n", argv[0]);
    return 2;
  }
  Model model;
  constexpr int P = Model::num_params;
  double centre[6], scale[6], theta[P];
  std::FILE* f = std::fopen(argv[1], "r");
  if (!f) {
    std::fprintf(stderr, "%s: cannot open\n", argv[1]);
    return 1;
  }
  const bool ok = read_numbers(f, argv[1], centre, 6) && read_numbers(f, argv[1], scale, 6) &&
                  read_numbers(f, argv[1], theta, P);
  std::fclose(f);
  if (!ok) return 1;
  // The normalisation is structure (learned at estimation), θ the parameters.
  model.nonlinearity().set_normalization(Eigen::Map<Eigen::VectorXd>(centre, 6), Eigen::Map<Eigen::VectorXd>(scale, 6));

  std::vector<double> u;
  if (argc > 2) {
    std::FILE* in = std::fopen(argv[2], "r");
    if (!in) {
      std::fprintf(stderr, "%s: cannot open\n", argv[2]);
      return 1;
    }
    double v;
    while (std::fscanf(in, "%lf", &v) == 1) u.push_back(v);
    std::fclose(in);
  } else {
    for (int t = 0; t < 300; ++t) u.push_back(t < 50 ? 0.0 : 1.0);
  }
  std::vector<double> y(u.size());
  const Eigen::Map<const Eigen::MatrixXd> um(u.data(), static_cast<Eigen::Index>(u.size()), 1);
  if (!model.simulate(um, std::span<const double>(theta, P), std::span<const double>(), std::span<double>(y))) {
    std::fprintf(stderr, "the simulation diverged\n");
    return 1;
  }
  for (double v : y) std::printf("%.10g\n", v);
  return 0;
}
