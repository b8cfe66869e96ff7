// Multi-start Levenberg–Marquardt: low-discrepancy sequences, escaping local minima that trap a
// single start, determinism across thread counts, log spacing, fixed parameters, bad options.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <mutex>
#include <vector>

#include "nlid/estimation/multi_start.hpp"
#include "nlid/estimation/problem.hpp"

namespace {

// y_i = a·sin(ω t_i), true a = 1.5, ω = 7.3: the cost in ω has a local minimum near every
// frequency whose sinusoid partially correlates with the data, so a start at ω = 2 is stuck.
struct SineFit {
  Eigen::VectorXd t, y;
  SineFit() : t(Eigen::VectorXd::LinSpaced(200, 0.0, 4.0)), y(200) {
    for (int i = 0; i < 200; ++i) y[i] = 1.5 * std::sin(7.3 * t[i]);
  }
  auto problem() const {
    return nlid::make_problem<nlid::Dynamic>(
        2, 200, [this](const Eigen::VectorXd& th, Eigen::VectorXd& r, Eigen::MatrixXd* J) {
          for (int i = 0; i < 200; ++i) {
            const double s = std::sin(th[1] * t[i]), c = std::cos(th[1] * t[i]);
            r[i] = th[0] * s - y[i];
            if (J) {
              (*J)(i, 0) = s;
              (*J)(i, 1) = th[0] * t[i] * c;
            }
          }
          return true;
        });
  }
};

nlid::MultiStartOptions sine_options() {
  nlid::MultiStartOptions o;
  o.range_lower = Eigen::Vector2d(0.1, 0.5);
  o.range_upper = Eigen::Vector2d(3.0, 20.0);
  o.num_candidates = 64;
  o.num_starts = 6;
  return o;
}

}  // namespace

TEST_CASE("Radical inverse and Halton points", "[multi_start]") {
  CHECK(nlid::radical_inverse(1, 2) == 0.5);
  CHECK(nlid::radical_inverse(2, 2) == 0.25);
  CHECK(nlid::radical_inverse(3, 2) == 0.75);
  CHECK(nlid::radical_inverse(4, 2) == 0.125);
  CHECK(nlid::radical_inverse(1, 3) == Approx(1.0 / 3.0));
  CHECK(nlid::radical_inverse(3, 3) == Approx(1.0 / 9.0));
  CHECK(nlid::radical_inverse(5, 3) == Approx(2.0 / 3.0 + 1.0 / 9.0));
  const Eigen::VectorXd z = nlid::low_discrepancy_point(5, 3, nlid::StartSequence::halton);
  CHECK(z[0] == 0.625);
  CHECK(z[2] == Approx(1.0 / 25.0));
  CHECK_THROWS_WITH(nlid::low_discrepancy_point(1, 13, nlid::StartSequence::halton),
                    Catch::Contains("at most 12"));
}

TEST_CASE("Both sequences fill the unit cube evenly in every coordinate", "[multi_start]") {
  for (auto seq : {nlid::StartSequence::halton, nlid::StartSequence::kronecker}) {
    const int d = seq == nlid::StartSequence::halton ? 8 : 30, n = 500;
    Eigen::MatrixXi bins = Eigen::MatrixXi::Zero(d, 10);
    for (int i = 1; i <= n; ++i) {
      const Eigen::VectorXd z = nlid::low_discrepancy_point(static_cast<unsigned long long>(i), d, seq);
      REQUIRE(z.minCoeff() >= 0.0);
      REQUIRE(z.maxCoeff() < 1.0);
      for (int j = 0; j < d; ++j) ++bins(j, std::min(9, static_cast<int>(z[j] * 10)));
    }
    // 50 expected per bin; a pseudo-random sample would stray by ±3σ ≈ ±20, these by far less.
    CHECK(bins.minCoeff() >= 40);
    CHECK(bins.maxCoeff() <= 60);
  }
}

TEST_CASE("Multi-start escapes the local minima that trap a single start", "[multi_start]") {
  const SineFit s;
  const auto pb = s.problem();
  // A single LM run from ω = 2 stops in a local minimum.
  Eigen::VectorXd single(2);
  single << 1.0, 2.0;
  auto one = sine_options();
  one.num_starts = 1;
  one.num_candidates = 1;
  const auto r1 = nlid::multi_start(pb, single, one);
  CHECK(r1.best_cost > 10.0);
  CHECK(std::abs(single[1] - 7.3) > 1.0);
  // Multi-start from the same guess finds the global one.
  Eigen::VectorXd theta(2);
  theta << 1.0, 2.0;
  const auto r = nlid::multi_start(pb, theta, sine_options());
  INFO(r.report());
  CHECK(r.best_cost < 1e-12);
  CHECK(std::abs(theta[0]) == Approx(1.5).epsilon(1e-8));
  CHECK(theta[1] == Approx(7.3).epsilon(1e-10));
  CHECK(r.num_within_tolerance >= 1);
  CHECK(r.num_candidates == 64);
  CHECK(r.starts.size() == 6u);
  CHECK(r.starts[0].candidate == 0);  // the caller's guess is always refined
  CHECK(r.sequence == "halton");
  CHECK_THAT(r.report(), Catch::Contains("<- best") && Catch::Contains("within 1 %"));
}

TEST_CASE("Results do not depend on the number of threads", "[multi_start]") {
  const SineFit s;
  const auto pb = s.problem();
  auto o = sine_options();
  Eigen::VectorXd a(2), b(2);
  a << 1.0, 2.0;
  b = a;
  o.num_threads = 1;
  const auto ra = nlid::multi_start(pb, a, o);
  o.num_threads = 3;
  const auto rb = nlid::multi_start(pb, b, o);
  CHECK(a == b);
  REQUIRE(ra.starts.size() == rb.starts.size());
  for (std::size_t i = 0; i < ra.starts.size(); ++i) {
    CHECK(ra.starts[i].candidate == rb.starts[i].candidate);
    CHECK(ra.starts[i].cost == rb.starts[i].cost);
  }
  CHECK(rb.threads == 3);
}

TEST_CASE("start_done reports every refined start once, one call at a time, from any thread", "[multi_start]") {
  const SineFit s;
  const auto pb = s.problem();
  auto o = sine_options();
  o.num_threads = 3;
  int calls = 0, inside = 0, most_inside = 0, last_done = 0, total = 0;
  std::vector<int> candidates;
  o.start_done = [&](const nlid::StartResult& r, int done, int of) {
    most_inside = std::max(most_inside, ++inside);  // the lock keeps calls apart
    ++calls;
    last_done = done;
    total = of;
    candidates.push_back(r.candidate);
    --inside;
  };
  Eigen::VectorXd theta(2);
  theta << 1.0, 2.0;
  const auto r = nlid::multi_start(pb, theta, o);
  CHECK(calls == static_cast<int>(r.starts.size()));
  CHECK(total == static_cast<int>(r.starts.size()));
  CHECK(last_done == total);
  CHECK(most_inside == 1);
  std::sort(candidates.begin(), candidates.end());
  std::vector<int> expected;
  for (const auto& st : r.starts) expected.push_back(st.candidate);
  CHECK(candidates == expected);
}

TEST_CASE("Log-spaced sampling, fixed parameters and the prepare hook", "[multi_start]") {
  // Cost (log10 θ0 − 1)² + (θ1 − 3)²: any start converges; we inspect the candidates.
  auto pb = nlid::make_problem<nlid::Dynamic>(
      3, 2, [](const Eigen::VectorXd& th, Eigen::VectorXd& r, Eigen::MatrixXd* J) {
        if (th[0] <= 0.0) return false;
        r[0] = std::log10(th[0]) - 1.0;
        r[1] = th[1] - 3.0;
        if (J) {
          J->setZero();
          (*J)(0, 0) = 1.0 / (th[0] * std::log(10.0));
          (*J)(1, 1) = 1.0;
        }
        return true;
      });
  nlid::MultiStartOptions o;
  o.num_candidates = 101;
  o.num_starts = 2;
  o.num_threads = 1;
  o.range_lower = Eigen::Vector3d(1e-2, -1.0, -1.0);
  o.range_upper = Eigen::Vector3d(1e2, 1.0, 1.0);
  o.log_scale = {true, false, false};
  o.lm.fixed = {false, false, true};
  std::vector<double> seen0, seen2;
  std::mutex mu;
  o.prepare = [&](Eigen::VectorXd& th) {
    std::lock_guard<std::mutex> lock(mu);
    seen0.push_back(th[0]);
    seen2.push_back(th[2]);
  };
  Eigen::VectorXd theta(3);
  theta << 1.0, 0.0, 0.25;
  const auto r = nlid::multi_start(pb, theta, o);
  REQUIRE(seen0.size() == 100u);  // every candidate but the caller's own
  std::sort(seen0.begin(), seen0.end());
  // Log-uniform on [1e-2, 1e2]: median 1, a quarter below 0.1, a quarter above 10.
  CHECK(seen0[50] == Approx(1.0).epsilon(0.15));
  CHECK(seen0[25] == Approx(0.1).epsilon(0.2));
  CHECK(seen0[75] == Approx(10.0).epsilon(0.2));
  CHECK(std::all_of(seen2.begin(), seen2.end(), [](double v) { return v == 0.25; }));
  CHECK(r.num_sampled_parameters == 2);
  CHECK(theta[0] == Approx(10.0).epsilon(1e-6));
  CHECK(theta[2] == 0.25);
}

TEST_CASE("Multi-start option errors name the option", "[multi_start][errors]") {
  const SineFit s;
  const auto pb = s.problem();
  Eigen::VectorXd theta(2);
  theta << 1.0, 2.0;
  auto o = sine_options();
  o.num_starts = 0;
  CHECK_THROWS_WITH(nlid::multi_start(pb, theta, o), Catch::Contains("num_starts"));
  o = sine_options();
  o.range_lower = Eigen::Vector3d(0, 0, 0);
  CHECK_THROWS_WITH(nlid::multi_start(pb, theta, o), Catch::Contains("range_lower"));
  o = sine_options();
  o.log_scale = {true, false};
  o.range_lower[0] = -1.0;
  CHECK_THROWS_WITH(nlid::multi_start(pb, theta, o), Catch::Contains("needs a positive range"));
  auto bad = nlid::make_problem<nlid::Dynamic>(
      1, 1, [](const Eigen::VectorXd&, Eigen::VectorXd&, Eigen::MatrixXd*) { return false; });
  Eigen::VectorXd t1(1);
  t1 << 1.0;
  nlid::MultiStartOptions ob;
  ob.range_lower = Eigen::VectorXd::Constant(1, 0.0);
  ob.range_upper = Eigen::VectorXd::Constant(1, 1.0);
  CHECK_THROWS_WITH(nlid::multi_start(bad, t1, ob), Catch::Contains("cannot be evaluated"));
}

TEST_CASE("lm_cost is the solver's criterion: robust loss plus regularization", "[multi_start]") {
  const Eigen::Vector2d r(1.0, 2.0), th(1.0, 3.0);
  nlid::LmOptions o;
  CHECK(nlid::lm_cost(o, r, th) == 2.5);
  o.regularization.lambda = 2.0;
  CHECK(nlid::lm_cost(o, r, th) == Approx(2.5 + 10.0));  // ½·2·(1 + 9)
  o.regularization.weights = Eigen::Vector2d(1.0, 0.5);
  o.regularization.nominal = Eigen::Vector2d(0.0, 1.0);
  CHECK(nlid::lm_cost(o, r, th) == Approx(2.5 + 3.0));  // ½·2·(1·1 + 0.5·4)
  o.loss = nlid::RobustLoss::huber(1.5);
  // Huber with δ = 1.5: r = 1 is inside (ρ = 1), r = 2 outside (ρ = 2·1.5·2 − 1.5² = 3.75).
  CHECK(nlid::lm_cost(o, r, th) == Approx(0.5 * (1.0 + 3.75) + 3.0));
}

TEST_CASE("Screening ranks candidates by the solver's own cost", "[multi_start]") {
  // A strong pull of ω towards 2 (a local minimum of the residuals) changes which candidate is
  // best: the refined start must be the best by the regularized cost, not by ½‖r‖².
  const SineFit s;
  const auto pb = s.problem();
  auto o = sine_options();
  o.num_starts = 1;
  o.include_initial = false;
  o.num_threads = 1;
  o.lm.max_iterations = 0;
  o.lm.regularization.lambda = 50.0;
  o.lm.regularization.weights = Eigen::Vector2d(0.0, 1.0);
  o.lm.regularization.nominal = Eigen::Vector2d(0.0, 2.0);
  o.lm.loss = nlid::RobustLoss::huber(0.5);
  std::vector<Eigen::VectorXd> seen;
  o.prepare = [&](Eigen::VectorXd& th) { seen.push_back(th); };
  Eigen::VectorXd theta(2);
  theta << 1.0, 2.0;
  const auto res = nlid::multi_start(pb, theta, o);
  REQUIRE(seen.size() == 64u);
  std::size_t best_plain = 0, best_solver = 0;
  std::vector<double> plain, solver;
  for (const Eigen::VectorXd& th : seen) {
    Eigen::VectorXd rr(pb.num_residuals());
    REQUIRE(pb.evaluate(th, rr, nullptr));
    plain.push_back(0.5 * rr.squaredNorm());
    solver.push_back(nlid::lm_cost(o.lm, rr, th));
  }
  best_plain = static_cast<std::size_t>(std::min_element(plain.begin(), plain.end()) - plain.begin());
  best_solver = static_cast<std::size_t>(std::min_element(solver.begin(), solver.end()) - solver.begin());
  REQUIRE(best_plain != best_solver);  // otherwise this test could not tell the criteria apart
  REQUIRE(res.starts.size() == 1u);
  CHECK(res.starts[0].start == seen[best_solver]);
  CHECK(res.starts[0].start_cost == Approx(solver[best_solver]).epsilon(1e-12));
  // The start cost is the solver's initial cost: one criterion in the whole report.
  CHECK(res.starts[0].start_cost == Approx(res.starts[0].summary.initial_cost).epsilon(1e-12));
}
