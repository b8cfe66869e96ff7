// AutoDiffProblem: Jacobian against central differences (NumericDiffProblem), static vs chunked
// dynamic evaluation agree exactly, chunk boundaries, size errors; check_jacobian on analytic
// problems (a correct and a deliberately wrong one); concept checks.
#include <catch2/catch.hpp>

#include <cmath>
#include <span>
#include <string>
#include <thread>
#include <vector>

#include "nlid/estimation.hpp"
#include "test_problems.hpp"

using Catch::Matchers::Contains;
using nlid::AutoDiffProblem;
using nlid::NumericDiffProblem;

static_assert(nlid::ResidualFunctor<nlid_test::Rosenbrock<2>>);
static_assert(nlid::ResidualFunctor<nlid_test::ExtendedRosenbrock>);
static_assert(nlid::LeastSquaresProblem<AutoDiffProblem<nlid_test::ExpFit<3>>>);
static_assert(nlid::LeastSquaresProblem<AutoDiffProblem<nlid_test::SigmoidNetFit, 4>>);
static_assert(nlid::LeastSquaresProblem<NumericDiffProblem<nlid_test::SigmoidNetFit>>);
static_assert(nlid::LeastSquaresProblem<nlid::StackedProblem<NumericDiffProblem<nlid_test::ExpFit<3>>>>);
static_assert(AutoDiffProblem<nlid_test::ExpFit<3>>::chunk_size == 3);
static_assert(AutoDiffProblem<nlid_test::SigmoidNetFit>::chunk_size == nlid::default_ad_chunk_size);

namespace {
// Not functors: wrong member shapes must be rejected at the interface.
struct NoTemplate {
  static constexpr int num_params = 2;
  int num_parameters() const { return 2; }
  Eigen::Index num_residuals() const { return 1; }
  bool residuals(std::span<const double>, std::span<double>) const { return true; }  // no Dual
};
struct BadCount {
  static constexpr int num_params = 0;
  int num_parameters() const { return 0; }
  Eigen::Index num_residuals() const { return 1; }
  template <class T>
  bool residuals(std::span<const T>, std::span<T>) const { return true; }
};
struct NoSizes {
  template <class T>
  bool residuals(std::span<const T>, std::span<T>) const { return true; }
};
}  // namespace
static_assert(!nlid::ResidualFunctor<NoTemplate>);
static_assert(!nlid::ResidualFunctor<BadCount>);
static_assert(!nlid::ResidualFunctor<NoSizes>);
static_assert(!nlid::LeastSquaresProblem<nlid_test::ExpFit<3>>);  // a functor is not a problem
static_assert(!nlid::LeastSquaresProblem<int>);

TEST_CASE("AD Jacobian equals central differences to 1e-6", "[estimation][autodiff]") {
  const nlid_test::SigmoidNetFit f(4, 60);  // 13 parameters, dynamic: chunks of 8 + 5
  AutoDiffProblem ad(f);
  NumericDiffProblem nd(f);
  Eigen::VectorXd th(13);
  for (int k = 0; k < 13; ++k) th[k] = 0.3 * std::sin(1.7 * k + 0.4) + (k % 3 == 1 ? 1.0 : 0.0);
  Eigen::VectorXd r1(60), r2(60);
  Eigen::MatrixXd J1(60, 13), J2(60, 13);
  REQUIRE(ad.evaluate(th, r1, &J1));
  REQUIRE(nd.evaluate(th, r2, &J2));
  CHECK((r1 - r2).cwiseAbs().maxCoeff() < 1e-14);  // same values from the Dual and double runs
  const double err = (J1 - J2).cwiseAbs().maxCoeff();
  INFO("max |J_ad - J_fd| = " << err);
  CHECK(err < 1e-6);
  CHECK(err > 0);  // differences are not exact: the comparison is real
  // Residual-only evaluation gives the same residuals as the derivative pass.
  Eigen::VectorXd r3(60);
  REQUIRE(ad.evaluate(th, r3, nullptr));
  CHECK((r3 - r1).cwiseAbs().maxCoeff() < 1e-14);
}

namespace {
// The same residuals with a static parameter count, to compare one-pass and chunked evaluation.
template <int P>
struct SigmoidStatic : nlid_test::SigmoidNetFit {
  static constexpr int num_params = P;
  SigmoidStatic() : SigmoidNetFit((P - 1) / 3, 40) {}
};
}  // namespace

TEST_CASE("static one-pass and dynamic chunked AD give identical Jacobians",
          "[estimation][autodiff]") {
  SigmoidStatic<13> fs;
  const nlid_test::SigmoidNetFit& fd = fs;
  AutoDiffProblem one_pass(fs);
  Eigen::Matrix<double, 13, 1> th;
  for (int k = 0; k < 13; ++k) th[k] = 0.2 * std::cos(0.9 * k) + 0.5;
  Eigen::VectorXd r(40);
  nlid::JacobianMatrix<13> Js(40, 13);
  REQUIRE(one_pass.evaluate(th, r, &Js));
  // Chunk sizes that divide n, do not divide it, exceed it, and the degenerate 1.
  auto check_chunk = [&](auto problem) {
    Eigen::VectorXd rd(40);
    Eigen::MatrixXd Jd(40, 13);
    Eigen::VectorXd thd = th;
    REQUIRE(problem.evaluate(thd, rd, &Jd));
    CHECK(rd == r);
    CHECK(Jd == Eigen::MatrixXd(Js));  // bit-identical: same operations in the same order
  };
  check_chunk(AutoDiffProblem<nlid_test::SigmoidNetFit, 1>(fd));
  check_chunk(AutoDiffProblem<nlid_test::SigmoidNetFit, 4>(fd));
  check_chunk(AutoDiffProblem<nlid_test::SigmoidNetFit, 8>(fd));
  check_chunk(AutoDiffProblem<nlid_test::SigmoidNetFit, 13>(fd));
  check_chunk(AutoDiffProblem<nlid_test::SigmoidNetFit, 16>(fd));
}

TEST_CASE("AutoDiffProblem checks argument sizes with named errors", "[estimation][autodiff]") {
  AutoDiffProblem p(nlid_test::ExtendedRosenbrock{});
  Eigen::VectorXd th = Eigen::VectorXd::Ones(10), r(10), short_r(9);
  Eigen::MatrixXd J(10, 10), badJ(10, 9);
  Eigen::VectorXd short_th = Eigen::VectorXd::Ones(9);
  CHECK_THROWS_WITH(p.evaluate(short_th, r, nullptr), Contains("theta has 9 entries, expected 10"));
  CHECK_THROWS_WITH(p.evaluate(th, short_r, nullptr), Contains("r has 9 entries, expected 10"));
  CHECK_THROWS_WITH(p.evaluate(th, r, &badJ), Contains("J is 10 x 9, expected 10 x 10"));
  CHECK(p.evaluate(th, r, &J));
  CHECK(r.isZero());  // (1, …, 1) is the minimum
  nlid_test::ExtendedRosenbrock bad;
  bad.n = -1;
  CHECK_THROWS_WITH(AutoDiffProblem<nlid_test::ExtendedRosenbrock>(bad),
                    Contains("functor reports -1 parameters"));
  bad.n = 0;
  CHECK_THROWS_WITH(AutoDiffProblem<nlid_test::ExtendedRosenbrock>(bad), Contains("reports no residuals"));
  CHECK_THROWS_WITH(NumericDiffProblem<nlid_test::ExpFit<3>>(nlid_test::ExpFit<3>(1, 1, 1), 0.0),
                    Contains("relative finite-difference step must be in (0, 1)"));
}

TEST_CASE("check_jacobian accepts a correct analytic Jacobian and locates a wrong one",
          "[estimation][numeric_diff]") {
  const int m = 30;
  Eigen::VectorXd t = Eigen::VectorXd::LinSpaced(m, 0.0, 3.0);
  auto make = [&](double error_in_b) {
    return nlid::make_problem<2>(2, m, [t, error_in_b](const Eigen::Vector2d& th,
                                                       Eigen::VectorXd& r,
                                                       nlid::JacobianMatrix<2>* J) {
      r = (th[0] * (-th[1] * t.array()).exp()).matrix() - Eigen::VectorXd::Ones(t.size());
      if (J) {
        J->col(0) = (-th[1] * t.array()).exp().matrix();
        J->col(1) = (-th[0] * t.array() * (-th[1] * t.array()).exp()).matrix();
        (*J)(7, 1) += error_in_b;
      }
      return true;
    });
  };
  const Eigen::Vector2d th(1.5, 0.7);
  const auto good = nlid::check_jacobian(make(0.0), th);
  CHECK(good.ok);
  CHECK(good.max_error < 1e-8);
  const auto bad = nlid::check_jacobian(make(1e-3), th);
  CHECK_FALSE(bad.ok);
  CHECK(bad.row == 7);
  CHECK(bad.column == 1);
  CHECK(bad.max_error == Approx(1e-3).epsilon(1e-3));
  // numeric_jacobian on its own.
  nlid::JacobianMatrix<2> J;
  REQUIRE(nlid::numeric_jacobian(make(0.0), th, J));
  CHECK(J.rows() == m);
  CHECK(J(0, 0) == Approx(1.0));
}

namespace {
// r = (θ³, θ²): J = (3θ², 2θ). Central differences are exact for the square and off by h² for the
// cube; a one-sided difference would be off by ~h·f''/2 (≈ 1e-4 here).
struct CubeSquare {
  static constexpr int num_params = 1;
  int num_parameters() const { return 1; }
  Eigen::Index num_residuals() const { return 2; }
  template <class T>
  bool residuals(std::span<const T> th, std::span<T> r) const {
    r[0] = th[0] * th[0] * th[0];
    r[1] = th[0] * th[0];
    return true;
  }
};
}  // namespace

TEST_CASE("NumericDiffProblem and numeric_jacobian are central differences: known derivatives to 1e-8",
          "[estimation][numeric_diff]") {
  const Eigen::Matrix<double, 1, 1> th(3.0);
  NumericDiffProblem nd(CubeSquare{});
  Eigen::VectorXd r(2);
  nlid::JacobianMatrix<1> J(2, 1);
  REQUIRE(nd.evaluate(th, r, &J));
  CHECK(r[0] == 27.0);
  CHECK(r[1] == 9.0);
  CHECK(J(0, 0) == Approx(27.0).epsilon(0).margin(1e-8));
  CHECK(J(1, 0) == Approx(6.0).epsilon(0).margin(1e-8));
  nlid::JacobianMatrix<1> Jn;
  REQUIRE(nlid::numeric_jacobian(AutoDiffProblem(CubeSquare{}), th, Jn));
  CHECK(Jn(0, 0) == Approx(27.0).epsilon(0).margin(1e-8));
  CHECK(Jn(1, 0) == Approx(6.0).epsilon(0).margin(1e-8));
}

TEST_CASE("FunctionProblem validates its sizes", "[estimation][problem]") {
  auto fn = [](const Eigen::VectorXd&, Eigen::VectorXd&, Eigen::MatrixXd*) { return true; };
  CHECK_THROWS_WITH(nlid::make_problem<nlid::Dynamic>(0, 3, fn), Contains("must be >= 1"));
  CHECK_THROWS_WITH(nlid::make_problem<nlid::Dynamic>(2, 0, fn),
                    Contains("residual count must be >= 1"));
  auto fn2 = [](const Eigen::Vector2d&, Eigen::VectorXd&, nlid::JacobianMatrix<2>*) { return true; };
  CHECK_THROWS_WITH(nlid::make_problem<2>(3, 4, fn2), Contains("differs from the static count 2"));
  const auto ok = nlid::make_problem<2>(2, 4, fn2);
  CHECK(ok.num_residuals() == 4);
}

TEST_CASE("one problem object may be evaluated from several threads at once",
          "[estimation][autodiff][threads]") {
  // Parallel multi-start solves share one const problem: per-thread scratch must keep the
  // Jacobians of different θ apart.
  const nlid_test::SigmoidNetFit f(4, 200);
  AutoDiffProblem ad(f);
  NumericDiffProblem nd(f);
  nlid::StackedProblem<AutoDiffProblem<nlid_test::SigmoidNetFit>> stacked({ad, ad});
  constexpr int kThreads = 4;
  auto theta_for = [](int t) {
    Eigen::VectorXd th(13);
    for (int k = 0; k < 13; ++k) th[k] = 0.1 * t + 0.3 * std::sin(1.3 * k + t);
    return th;
  };
  std::vector<Eigen::MatrixXd> serial(kThreads), parallel(kThreads), fd(kThreads), st(kThreads);
  for (int t = 0; t < kThreads; ++t) {
    Eigen::VectorXd r(200);
    serial[t].resize(200, 13);
    REQUIRE(ad.evaluate(theta_for(t), r, &serial[t]));
  }
  std::vector<int> ok(kThreads, 0);
  {
    std::vector<std::thread> pool;
    for (int t = 0; t < kThreads; ++t) {
      pool.emplace_back([&, t] {
        Eigen::VectorXd r(200), r2(400);
        parallel[t].resize(200, 13);
        fd[t].resize(200, 13);
        st[t].resize(400, 13);
        bool good = true;
        for (int rep = 0; rep < 20; ++rep) {
          good = good && ad.evaluate(theta_for(t), r, &parallel[t]);
          good = good && nd.evaluate(theta_for(t), r, &fd[t]);
          good = good && stacked.evaluate(theta_for(t), r2, &st[t]);
        }
        ok[t] = good ? 1 : 0;
      });
    }
    for (auto& th : pool) th.join();
  }
  for (int t = 0; t < kThreads; ++t) {
    CHECK(ok[t] == 1);
    CHECK(parallel[t] == serial[t]);
    CHECK((fd[t] - serial[t]).cwiseAbs().maxCoeff() < 1e-6);
    CHECK(st[t].topRows(200) == serial[t]);
    CHECK(st[t].bottomRows(200) == serial[t]);
  }
}

namespace {
// r = y − 2u: a model with nothing to estimate (nlid-fit's 'nlarx:na=0,nb=1,nk=0:unitgain').
struct NothingToEstimate {
  static constexpr int num_params = nlid::Dynamic;
  int num_parameters() const { return 0; }
  Eigen::Index num_residuals() const { return 3; }
  template <class T>
  bool residuals(std::span<const T>, std::span<T> r) const {
    for (int i = 0; i < 3; ++i) r[static_cast<std::size_t>(i)] = T(1.0 + i) - T(2.0 * i);
    return true;
  }
};
}  // namespace

TEST_CASE("AutoDiffProblem with no parameters gives residuals, an empty Jacobian, and LM stops at once",
          "[estimation][autodiff]") {
  // It refused with "functor reports 0 parameters": nlid-fit failed on a spec it documents.
  AutoDiffProblem p(NothingToEstimate{});
  Eigen::VectorXd th(0), r = Eigen::VectorXd::Constant(3, 99.0);
  Eigen::MatrixXd J(3, 0);
  REQUIRE(p.evaluate(th, r, &J));
  CHECK(r == Eigen::Vector3d(1, 0, -1));
  const nlid::LmSummary s = nlid::solve_least_squares(p, th, nlid::LmOptions{});
  CHECK(s.status == nlid::LmStatus::all_parameters_fixed);
  CHECK(s.final_cost == Approx(1.0));
}
