// simulate_batched for grey-box models (models/greybox_batched.hpp): K parameter sets of one
// physics in the lanes of a Batch equal K single simulations with the batch's sub-step count,
// on every register width the CPU offers; a diverging run stops only its own batch; the
// catalogue's smoothed stop contact batches too; bad arguments are refused by name.
#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>

#include <Eigen/Core>

#include "nlid/models/greybox.hpp"
#include "nlid/models/greybox_batched.hpp"
#include "nlid/models/physics/throttle.hpp"

#include "../support/register_widths.hpp"
#include "../support/study_throttle.hpp"

namespace {

using nlid_test::StudyThrottle;

// Throttle command between 1.2 (into the upper stop) and 0.2, switching every `hold` samples.
Eigen::MatrixXd square_wave(int n, int hold) {
  Eigen::MatrixXd u(n, 1);
  for (int t = 0; t < n; ++t) u(t, 0) = (t / hold) % 2 == 0 ? 1.2 : 0.2;
  return u;
}

// Parameter sets around the study's values; the stop stiffness grows with k (sub-step counts by
// the model's rule: 2 for k = 0…2, 3 from k = 3), so the runs of the first batch of 4 differ.
Eigen::MatrixXd study_thetas(int runs) {
  Eigen::MatrixXd th(4, runs);
  for (int k = 0; k < runs; ++k) th.col(k) << 22.0 + k, 110.0 - 2.0 * k, 1.2e4 * (1.0 + k), 9000.0 + 50.0 * k;
  return th;
}

// Run k alone on double with `sub` sub-steps (the reference a lane must reproduce).
template <class P>
Eigen::VectorXd single_run(const nlid::GreyBox<P>& model, const Eigen::MatrixXd& u, double ts, const Eigen::VectorXd& p,
                           Eigen::VectorXd x, int sub, int output = 0) {
  Eigen::VectorXd y = Eigen::VectorXd::Constant(u.rows(), std::numeric_limits<double>::quiet_NaN());
  model.simulate_with(u, ts, p.data(), x.data(), sub, [&](Eigen::Index t, const double* yt) { y(t) = yt[output]; });
  return y;
}

// Sub-steps the model's rule gives a run of parameters p from x0 under the first input u0.
template <class P>
int own_substeps(const nlid::GreyBox<P>& model, const Eigen::VectorXd& p, double ts, const Eigen::VectorXd& x0,
                 double u0) {
  return nlid::substeps_for(ts, nlid::physics_spectral_radius(model.physics(), p.data(), x0.data(), &u0),
                            model.integrator());
}

// A damped oscillator with two outputs (position, velocity), for the output index.
struct TwoOutputs {
  static constexpr int num_states = 2, num_inputs = 1, num_outputs = 2, num_params = 2;
  std::string name() const { return "two_outputs"; }
  std::array<nlid::ParameterInfo, 2> parameter_info() const {
    constexpr double inf = std::numeric_limits<double>::infinity();
    return {{{"c", "1/s", "damping", 2.0, 0.0, inf}, {"k", "1/s^2", "spring", 40.0, 0.0, inf}}};
  }
  template <class T>
  void derivative(const T* x, const T* u, const T* p, T* dx) const {
    dx[0] = x[1];
    dx[1] = u[0] - p[0] * x[1] - p[1] * x[0];
  }
  template <class T>
  void output(const T* x, const T* /*u*/, const T* /*p*/, T* y) const {
    y[0] = x[0];
    y[1] = x[1];
  }
};

}  // namespace

TEST_CASE("Batched grey-box runs equal single runs with the batch's sub-step count, on every register width",
          "[greybox][batch]") {
  const nlid::GreyBox<StudyThrottle> model;
  const int n = 700, runs = 11;  // two full batches of 4 and one padded batch
  const double ts = 0.01;
  const Eigen::MatrixXd u = square_wave(n, 120);
  const Eigen::MatrixXd thetas = study_thetas(runs);
  Eigen::MatrixXd x0s(2, runs);
  for (int k = 0; k < runs; ++k) x0s.col(k) << 15.0 + 2.0 * k, 0.5 * k;
  // The reference: each run alone, with the largest sub-step count of its batch of 4.
  Eigen::MatrixXd ref(n, runs);
  bool counts_differ = false, hit_stop = false;
  for (int k0 = 0; k0 < runs; k0 += 4) {
    int sub = 1;
    for (int k = k0; k < std::min(k0 + 4, runs); ++k) {
      const int own = own_substeps(model, thetas.col(k), ts, x0s.col(k), u(0, 0));
      counts_differ = counts_differ || (k > k0 && own != sub);
      sub = std::max(sub, own);
    }
    for (int k = k0; k < std::min(k0 + 4, runs); ++k) ref.col(k) = single_run(model, u, ts, thetas.col(k), x0s.col(k), sub);
  }
  REQUIRE(ref.allFinite());
  hit_stop = ref.maxCoeff() > 90.0;
  CHECK(counts_differ);  // the max-over-lanes rule is exercised
  CHECK(hit_stop);       // and the contact term
  std::vector<std::size_t> widths = nlid_test::register_widths();
  widths.insert(widths.begin(), 0);  // 0: the CPU's widest, the default
  for (std::size_t r : widths) {
    INFO("register_bytes " << r);
    const Eigen::MatrixXd y = nlid::simulate_batched<4>(model, u, ts, thetas, x0s, 0, r);
    REQUIRE(y.rows() == n);
    REQUIRE(y.cols() == runs);
    CHECK((y - ref).cwiseAbs().maxCoeff() <= 1e-10);
  }
  // A batch whose runs all need the same count is GreyBox::simulate itself, run by run.
  Eigen::MatrixXd same(4, 3);
  for (int k = 0; k < 3; ++k) same.col(k) << 22.0 + k, 110.0, 1.2e4, 9000.0 - 100.0 * k;
  const Eigen::MatrixXd ys = nlid::simulate_batched<4>(model, u, ts, same);  // zero initial states
  for (int k = 0; k < 3; ++k) {
    nlid::GreyBox<StudyThrottle> m = model;
    m.set_parameters(same.col(k));
    const Eigen::MatrixXd y1 = m.simulate(u, ts, Eigen::Vector2d::Zero());
    CHECK((ys.col(k) - y1.col(0)).cwiseAbs().maxCoeff() <= 1e-10);
  }
}

TEST_CASE("A diverging batched grey-box run stops its own batch only", "[greybox][batch]") {
  nlid::GreyBox<StudyThrottle> model;
  nlid::IntegratorOptions o;
  o.substeps = 1;  // fixed: a large stop stiffness is then outside RK4's stability region
  model.set_integrator(o);
  const int n = 500;
  const Eigen::MatrixXd u = square_wave(n, 100);
  Eigen::MatrixXd thetas = study_thetas(8);
  thetas(2, 5) = 1e7;  // run 5 (second batch of 4) blows up once it reaches a stop
  const Eigen::MatrixXd y = nlid::simulate_batched<4>(model, u, 0.01, thetas);
  const Eigen::VectorXd bad = single_run(model, u, 0.01, thetas.col(5), Eigen::Vector2d::Zero(), 1);
  Eigen::Index first_nan = 0;
  while (first_nan < n && std::isfinite(bad(first_nan))) ++first_nan;
  REQUIRE(first_nan < n);
  REQUIRE(first_nan > 0);
  for (int k = 0; k < 4; ++k) {  // the first batch is untouched
    INFO("run " << k);
    CHECK(y.col(k).allFinite());
    CHECK((y.col(k) - single_run(model, u, 0.01, thetas.col(k), Eigen::Vector2d::Zero(), 1)).cwiseAbs().maxCoeff() <= 1e-10);
  }
  for (int k = 4; k < 8; ++k) {  // the second: kept up to the divergence, NaN from there on
    INFO("run " << k);
    CHECK(y.col(k).head(first_nan).allFinite());
    CHECK(y.col(k).tail(n - first_nan).array().isNaN().all());
  }
}

TEST_CASE("The catalogue throttle's smoothed stops batch (lanes inside the smoothing band included)", "[greybox][batch]") {
  // physics::Throttle smooths its stop contact over a band (physics/contact.hpp); a batch takes
  // the smoothing per lane where some lane is inside the band and the exact max elsewhere.
  nlid::GreyBox<nlid::physics::Throttle> model;
  const Eigen::VectorXd p0 = model.parameters();  // c, k, K, b, lower_stop, upper_stop, rest
  const int n = 600, runs = 6;
  const double ts = 0.01;
  Eigen::MatrixXd u(n, 1);
  for (int t = 0; t < n; ++t) u(t, 0) = (t / 90) % 2 == 0 ? 0.9 : 0.0;
  Eigen::MatrixXd thetas(p0.size(), runs);
  for (int k = 0; k < runs; ++k) {
    thetas.col(k) = p0;
    thetas(3, k) = p0(3) * (1.0 + 0.4 * k);  // some runs reach the upper stop, some do not
  }
  Eigen::MatrixXd x0s(2, runs);
  for (int k = 0; k < runs; ++k) x0s.col(k) << p0(4), 0.0;  // resting on the lower stop
  const Eigen::MatrixXd y = nlid::simulate_batched<4>(model, u, ts, thetas, x0s);
  double scale = 0.0;
  for (int k0 = 0; k0 < runs; k0 += 4) {
    int sub = 1;
    for (int k = k0; k < std::min(k0 + 4, runs); ++k)
      sub = std::max(sub, own_substeps(model, thetas.col(k), ts, x0s.col(k), u(0, 0)));
    for (int k = k0; k < std::min(k0 + 4, runs); ++k) {
      const Eigen::VectorXd ref = single_run(model, u, ts, thetas.col(k), x0s.col(k), sub);
      REQUIRE(ref.allFinite());
      scale = std::max(scale, ref.cwiseAbs().maxCoeff());
      INFO("run " << k);
      CHECK((y.col(k) - ref).cwiseAbs().maxCoeff() <= 1e-9 * (1.0 + ref.cwiseAbs().maxCoeff()));
    }
  }
  CHECK(scale > p0(5) - 1.0);  // some run presses against the upper stop
}

TEST_CASE("Batched grey-box runs return the output channel asked for", "[greybox][batch]") {
  const nlid::GreyBox<TwoOutputs> model;
  Eigen::MatrixXd u(300, 1);
  for (int t = 0; t < 300; ++t) u(t, 0) = std::sin(0.05 * t);
  Eigen::MatrixXd thetas(2, 3);
  thetas << 2.0, 3.0, 4.0, 40.0, 50.0, 60.0;
  const Eigen::MatrixXd v = nlid::simulate_batched<4>(model, u, 0.01, thetas, Eigen::MatrixXd(), 1);
  for (int k = 0; k < 3; ++k) {
    const int sub = own_substeps(model, thetas.col(k), 0.01, Eigen::Vector2d::Zero(), u(0, 0));
    const Eigen::VectorXd ref = single_run(model, u, 0.01, thetas.col(k), Eigen::Vector2d::Zero(), sub, 1);
    CHECK((v.col(k) - ref).cwiseAbs().maxCoeff() <= 1e-12);
  }
}

TEST_CASE("Batched grey-box runs refuse bad arguments by name", "[greybox][batch]") {
  nlid::GreyBox<StudyThrottle> model;
  const Eigen::MatrixXd u = square_wave(50, 10);
  const Eigen::MatrixXd th = study_thetas(3);
  using Catch::Contains;
  CHECK_THROWS_WITH(nlid::simulate_batched<4>(model, u, 0.01, th.topRows(3)),
                    Contains("thetas has 3 rows, the model has 4 parameters") && Contains("parameter 'thetas'"));
  CHECK_THROWS_WITH(nlid::simulate_batched<4>(model, u, 0.01, th, Eigen::MatrixXd::Zero(2, 2)),
                    Contains("x0s is 2 x 2, expected 2 x 3"));
  CHECK_THROWS_WITH(nlid::simulate_batched<4>(model, u, 0.0, th), Contains("sample time must be positive"));
  CHECK_THROWS_WITH(nlid::simulate_batched<4>(model, u, 0.01, th, Eigen::MatrixXd(), 1),
                    Contains("output 1 out of range: the model has 1 output(s)"));
  CHECK_THROWS_WITH(nlid::simulate_batched<4>(model, Eigen::MatrixXd::Zero(50, 2), 0.01, th),
                    Contains("input has 2 column(s), the model takes 1"));
  Eigen::MatrixXd bad_u = u;
  bad_u(7, 0) = std::numeric_limits<double>::quiet_NaN();
  CHECK_THROWS_WITH(nlid::simulate_batched<4>(model, bad_u, 0.01, th), Contains("input contains non-finite samples"));
  Eigen::MatrixXd bad_th = th;
  bad_th(1, 2) = std::numeric_limits<double>::infinity();
  CHECK_THROWS_WITH(nlid::simulate_batched<4>(model, u, 0.01, bad_th), Contains("thetas contains non-finite values"));
  CHECK_THROWS_WITH(nlid::simulate_batched<4>(model, u, 0.01, th, Eigen::MatrixXd(), 0, 40), Contains("use 16, 32 or 64"));
  nlid::IntegratorOptions o;
  o.method = nlid::IntegratorMethod::dormand_prince;
  model.set_integrator(o);
  CHECK_THROWS_WITH(nlid::simulate_batched<4>(model, u, 0.01, th), Contains("fixed-step method"));
}
