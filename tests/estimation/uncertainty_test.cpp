// Parameter uncertainty: the white formula against σ²(XᵀX)⁻¹ of a linear regression, the
// correlated (prewhitened Newey–West) covariance against its defining sums, both against the
// spread of estimates over Monte Carlo replicates with white and with strongly correlated noise,
// unidentifiable combinations, fixed and bound parameters, and errors that name what is wrong.
#include <catch2/catch.hpp>

#include <cmath>
#include <limits>
#include <random>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Dense>

#include "nlid/estimation.hpp"
#include "nlid/estimation/uncertainty.hpp"
#include "test_problems.hpp"

using Catch::Matchers::Contains;
using nlid::ParameterUncertainty;
using nlid::ResidualModel;
using nlid::UncertaintyOptions;

namespace {

// y = a + b t + c t² on [0, 1] with given noise; analytic Jacobian (the design matrix X).
struct Quadratic {
  Eigen::VectorXd t, y;
  Eigen::MatrixXd X;
  explicit Quadratic(const Eigen::VectorXd& noise) : t(noise.size()), y(noise.size()), X(noise.size(), 3) {
    const Eigen::Index m = noise.size();
    for (Eigen::Index i = 0; i < m; ++i) {
      t[i] = static_cast<double>(i) / static_cast<double>(m - 1);
      X.row(i) << 1.0, t[i], t[i] * t[i];
      y[i] = 1.0 - 2.0 * t[i] + 0.5 * t[i] * t[i] + noise[i];
    }
  }
  auto problem() const {
    return nlid::make_problem<3>(3, t.size(), [this](const Eigen::Vector3d& th, Eigen::VectorXd& r,
                                                     Eigen::Matrix<double, Eigen::Dynamic, 3>* J) {
      r = X * th - y;
      if (J) *J = X;
      return true;
    });
  }
  Eigen::Vector3d solve() const { return X.colPivHouseholderQr().solve(y); }
};

Eigen::VectorXd ar1_noise(Eigen::Index m, double rho, double sigma, std::mt19937_64& gen) {
  std::normal_distribution<double> nd(0.0, 1.0);
  Eigen::VectorXd e(m);
  double v = sigma * nd(gen);  // stationary start
  for (Eigen::Index i = 0; i < m; ++i) {
    if (i > 0) v = rho * v + std::sqrt(1.0 - rho * rho) * sigma * nd(gen);
    e[i] = v;
  }
  return e;
}

// Spread of the estimates of y = a exp(bt) + c over Monte Carlo replicates (AR(1) noise of
// lag-1 correlation rho), against the mean predicted standard deviations.
struct MonteCarlo {
  Eigen::Vector3d empirical, correlated, white;
};
MonteCarlo exp_fit_monte_carlo(double rho, int m, int replicates, unsigned seed) {
  std::mt19937_64 gen(seed);
  Eigen::MatrixXd est(replicates, 3), sc(replicates, 3), sw(replicates, 3);
  for (int k = 0; k < replicates; ++k) {
    nlid_test::ExpFit<3> f(2.0, -1.3, 0.5, m);
    f.y += ar1_noise(m, rho, 0.05, gen);
    nlid::AutoDiffProblem p(f);
    Eigen::Vector3d th(2.0, -1.3, 0.5);
    REQUIRE(nlid::solve_least_squares(p, th).converged());
    const ParameterUncertainty u = nlid::parameter_uncertainty(p, th);
    est.row(k) = th.transpose();
    sc.row(k) = u.stddev.transpose();
    sw.row(k) = u.stddev_white.transpose();
  }
  MonteCarlo mc;
  const Eigen::RowVector3d mean = est.colwise().mean();
  mc.empirical = ((est.rowwise() - mean).array().square().colwise().sum() / (replicates - 1)).sqrt().transpose();
  mc.correlated = sc.colwise().mean().transpose();
  mc.white = sw.colwise().mean().transpose();
  return mc;
}

}  // namespace

TEST_CASE("white formula: a linear regression's covariance is sigma^2 (X'X)^-1 exactly",
          "[estimation][uncertainty]") {
  std::mt19937_64 gen(3);
  const Quadratic q(ar1_noise(200, 0.0, 0.1, gen));
  const auto pb = q.problem();
  const Eigen::Vector3d th = q.solve();
  UncertaintyOptions o;
  o.residuals = ResidualModel::white;
  o.names = {"a", "b", "c"};
  const ParameterUncertainty u = nlid::parameter_uncertainty(pb, th, o);

  const Eigen::VectorXd e = q.X * th - q.y;
  const double s2 = e.squaredNorm() / (200 - 3);
  const Eigen::Matrix3d P = s2 * (q.X.transpose() * q.X).inverse();
  CHECK(u.noise_variance == Approx(s2).epsilon(1e-12));
  CHECK(u.observations == 200);
  CHECK(u.degrees_of_freedom == 197);
  CHECK(u.rank == 3);
  CHECK((u.covariance - P).cwiseAbs().maxCoeff() < 1e-12 * P.cwiseAbs().maxCoeff());
  for (int i = 0; i < 3; ++i) {
    CHECK(u.stddev[i] == Approx(std::sqrt(P(i, i))).epsilon(1e-10));
    CHECK(u.stddev_white[i] == u.stddev[i]);
    CHECK(u.correlation(i, i) == Approx(1.0).epsilon(1e-12));
  }
  CHECK(u.correlation(0, 1) == Approx(P(0, 1) / std::sqrt(P(0, 0) * P(1, 1))).epsilon(1e-10));
  CHECK(u.max_lag == 0);
  CHECK_THAT(u.report(), Contains("white residuals") && Contains("a = ") && Contains("+- "));
}

TEST_CASE("correlated formula: H^-1 S H^-1 with Bartlett-weighted lag sums inside each series, leverage-corrected",
          "[estimation][uncertainty]") {
  std::mt19937_64 gen(5);
  const Quadratic q(ar1_noise(120, 0.6, 0.1, gen));
  const auto pb = q.problem();
  const Eigen::Vector3d th = q.solve();
  UncertaintyOptions o;
  o.prewhiten = false;
  o.max_lag = 3;
  o.series = {{0, 50, 1}, {50, 70, 1}};  // two records: no lag product crosses row 49 → 50
  const ParameterUncertainty u = nlid::parameter_uncertainty(pb, th, o);

  // The defining sums, written out (in parameter units: the normalisation cancels), with each
  // residual divided by √(1 − h_t), h_t the leverage of row t.
  const Eigen::VectorXd e = q.X * th - q.y;
  const Eigen::Matrix3d XtXi = (q.X.transpose() * q.X).inverse();
  Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
  auto g = [&](Eigen::Index t) -> Eigen::Vector3d {
    const double h = q.X.row(t) * XtXi * q.X.row(t).transpose();
    return q.X.row(t).transpose() * e[t] / std::sqrt(1.0 - h);
  };
  for (Eigen::Index t = 0; t < 120; ++t) S += g(t) * g(t).transpose();
  for (const auto& s : o.series) {
    for (int tau = 1; tau <= 3; ++tau) {
      const double w = 1.0 - tau / 4.0;
      for (Eigen::Index t = s.offset + tau; t < s.offset + s.length; ++t) {
        S += w * (g(t) * g(t - tau).transpose() + g(t - tau) * g(t).transpose());
      }
    }
  }
  const Eigen::Matrix3d P = XtXi * S * XtXi;
  CHECK(u.max_lag == 3);
  CHECK((u.covariance - P).cwiseAbs().maxCoeff() < 1e-10 * P.cwiseAbs().maxCoeff());

  // One series instead of two: the lag products across the join change the answer.
  o.series.clear();
  const ParameterUncertainty one = nlid::parameter_uncertainty(pb, th, o);
  CHECK((one.covariance - P).cwiseAbs().maxCoeff() > 1e-6 * P.cwiseAbs().maxCoeff());
}

TEST_CASE("prewhitened formula: VAR(1) inside each series, Andrews' lag, Bartlett sums, recoloured",
          "[estimation][uncertainty]") {
  // The default path written out in the normalised coordinates the code works in (the VAR fit and
  // Andrews' weights are not invariant to column scaling); a transposed A or recolouring, or a lag
  // pair across the join of the two series, moves the covariance by far more than the tolerance.
  std::mt19937_64 gen(29);
  const Quadratic q(ar1_noise(150, 0.8, 0.1, gen));
  const auto pb = q.problem();
  const Eigen::Vector3d th = q.solve();
  UncertaintyOptions o;
  o.series = {{0, 70, 1}, {70, 80, 1}};
  const ParameterUncertainty u = nlid::parameter_uncertainty(pb, th, o);

  const Eigen::VectorXd e = q.X * th - q.y;
  const Eigen::Vector3d d = q.X.colwise().norm().transpose();
  const Eigen::MatrixXd Xn = q.X * d.cwiseInverse().asDiagonal();
  const Eigen::Matrix3d Hi = (Xn.transpose() * Xn).inverse();
  Eigen::MatrixXd G(150, 3);
  for (Eigen::Index t = 0; t < 150; ++t) {
    const double h = Xn.row(t) * Hi * Xn.row(t).transpose();
    G.row(t) = Xn.row(t) * e[t] / std::sqrt(1.0 - h);
  }
  Eigen::Matrix3d Sxx = Eigen::Matrix3d::Zero(), Syx = Eigen::Matrix3d::Zero();
  for (const auto& s : o.series) {
    for (Eigen::Index t = s.offset + 1; t < s.offset + s.length; ++t) {
      Sxx += G.row(t - 1).transpose() * G.row(t - 1);
      Syx += G.row(t).transpose() * G.row(t - 1);
    }
  }
  // g(t) ≈ A g(t−1), singular values held below 0.97 (here the largest is above: collinear scores).
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(Syx * Sxx.inverse(), Eigen::ComputeFullU | Eigen::ComputeFullV);
  REQUIRE(svd.singularValues().maxCoeff() > 0.97);
  const Eigen::Matrix3d A =
      svd.matrixU() * svd.singularValues().cwiseMin(0.97).asDiagonal() * svd.matrixV().transpose();
  Eigen::MatrixXd V = G;
  for (const auto& s : o.series) {
    for (Eigen::Index t = s.offset + 1; t < s.offset + s.length; ++t) V.row(t) = G.row(t) - G.row(t - 1) * A.transpose();
  }
  double num = 0.0, den = 0.0;
  for (int a = 0; a < 3; ++a) {
    double sxy = 0.0, sxx = 0.0;
    for (const auto& s : o.series) {
      for (Eigen::Index t = s.offset + 1; t < s.offset + s.length; ++t) {
        sxy += V(t, a) * V(t - 1, a);
        sxx += V(t - 1, a) * V(t - 1, a);
      }
    }
    const double rho = sxy / sxx;
    REQUIRE(std::abs(rho) < 0.97);
    double e2 = 0.0;
    for (const auto& s : o.series) {
      for (Eigen::Index t = s.offset + 1; t < s.offset + s.length; ++t) e2 += std::pow(V(t, a) - rho * V(t - 1, a), 2);
    }
    const double s2 = e2 / 148.0;
    num += 4.0 * rho * rho * s2 * s2 / (std::pow(1.0 - rho, 6) * std::pow(1.0 + rho, 2));
    den += s2 * s2 / std::pow(1.0 - rho, 4);
  }
  const int M = static_cast<int>(std::min(std::ceil(1.1447 * std::cbrt(num / den * 75.0)), 70.0 / 4.0));
  REQUIRE(M >= 1);
  CHECK(u.max_lag == M);
  Eigen::Matrix3d S = V.transpose() * V;
  for (const auto& s : o.series) {
    for (int tau = 1; tau <= M; ++tau) {
      const double w = 1.0 - tau / (M + 1.0);
      for (Eigen::Index t = s.offset + tau; t < s.offset + s.length; ++t) {
        S += w * (V.row(t).transpose() * V.row(t - tau) + V.row(t - tau).transpose() * V.row(t));
      }
    }
  }
  const Eigen::Matrix3d R = (Eigen::Matrix3d::Identity() - A).inverse();
  S = R * S * R.transpose();
  const Eigen::Matrix3d P = d.cwiseInverse().asDiagonal() * (Hi * S * Hi) * d.cwiseInverse().asDiagonal();
  INFO("code:\n" << u.covariance << "\nwritten out:\n" << P);
  CHECK((u.covariance - P).cwiseAbs().maxCoeff() < 1e-9 * P.cwiseAbs().maxCoeff());
}

TEST_CASE("correlated formula, white noise and many parameters per sample: unbiased like the white one",
          "[estimation][uncertainty]") {
  // HC2 already makes E[e_t²/(1 − h_t)] = σ² for homoscedastic residuals; a further N/(N − k)
  // (the white formula's degrees-of-freedom correction) inflates the variance by that factor —
  // 1.5 here, with k = 10 parameters on N = 30 rows.
  const int N = 30, k = 10, replicates = 2000;
  std::mt19937_64 gen(31);
  std::normal_distribution<double> nd(0.0, 1.0);
  Eigen::MatrixXd X(N, k);
  for (Eigen::Index i = 0; i < X.size(); ++i) X.data()[i] = nd(gen);
  const Eigen::VectorXd truth = (X.transpose() * X).inverse().diagonal();  // σ = 1
  Eigen::VectorXd y(N);
  auto pb = nlid::make_problem<nlid::Dynamic>(k, N, [&](const Eigen::VectorXd& th, Eigen::VectorXd& r, Eigen::MatrixXd* J) {
    r = X * th - y;
    if (J) *J = X;
    return true;
  });
  UncertaintyOptions lag0;
  lag0.max_lag = 0;
  lag0.prewhiten = false;
  UncertaintyOptions white;
  white.residuals = ResidualModel::white;
  double mean_lag0 = 0.0, mean_default = 0.0, mean_white = 0.0;
  for (int rep = 0; rep < replicates; ++rep) {
    for (Eigen::Index i = 0; i < N; ++i) y[i] = nd(gen);
    const Eigen::VectorXd th = X.colPivHouseholderQr().solve(y);
    mean_lag0 += nlid::parameter_uncertainty(pb, th, lag0).covariance.diagonal().cwiseQuotient(truth).mean() / replicates;
    mean_default += nlid::parameter_uncertainty(pb, th).covariance.diagonal().cwiseQuotient(truth).mean() / replicates;
    mean_white += nlid::parameter_uncertainty(pb, th, white).covariance.diagonal().cwiseQuotient(truth).mean() / replicates;
  }
  INFO("E[variance] / truth: lag 0 " << mean_lag0 << ", default " << mean_default << ", white " << mean_white);
  CHECK(mean_white == Approx(1.0).margin(0.05));
  CHECK(mean_lag0 == Approx(1.0).margin(0.05));  // exactly unbiased in expectation
  CHECK(mean_default == Approx(1.0).margin(0.15));
}

TEST_CASE("Monte Carlo, white noise: both formulas match the spread of the estimates",
          "[estimation][uncertainty]") {
  const MonteCarlo mc = exp_fit_monte_carlo(0.0, 400, 200, 11);
  for (int i = 0; i < 3; ++i) {
    INFO("parameter " << i << ": empirical " << mc.empirical[i] << ", correlated " << mc.correlated[i]
                      << ", white " << mc.white[i]);
    // 200 replicates: the empirical standard deviation itself scatters by about 5 %.
    CHECK(mc.correlated[i] / mc.empirical[i] == Approx(1.0).margin(0.15));
    CHECK(mc.white[i] / mc.empirical[i] == Approx(1.0).margin(0.15));
  }
}

TEST_CASE("Monte Carlo, correlated noise: the white formula understates, the correlated one does not",
          "[estimation][uncertainty]") {
  const MonteCarlo mc = exp_fit_monte_carlo(0.9, 1000, 200, 13);
  for (int i = 0; i < 3; ++i) {
    INFO("parameter " << i << ": empirical " << mc.empirical[i] << ", correlated " << mc.correlated[i]
                      << ", white " << mc.white[i]);
    CHECK(mc.correlated[i] / mc.empirical[i] == Approx(1.0).margin(0.15));  // 0.8 without prewhitening
    CHECK(mc.white[i] / mc.empirical[i] < 0.4);  // about 0.23: why the default is not white
  }
}

TEST_CASE("an unidentifiable product: rank, infinite deviations, and the combination named",
          "[estimation][uncertainty]") {
  // y = a·b·t + c: only the product a·b is determined.
  std::mt19937_64 gen(17);
  const Eigen::VectorXd noise = ar1_noise(100, 0.0, 0.01, gen);
  auto pb = nlid::make_problem<3>(3, 100, [&](const Eigen::Vector3d& th, Eigen::VectorXd& r,
                                              Eigen::Matrix<double, Eigen::Dynamic, 3>* J) {
    for (int i = 0; i < 100; ++i) {
      const double t = i / 99.0;
      r[i] = th[0] * th[1] * t + th[2] - (6.0 * t + 1.0 + noise[i]);
      if (J) J->row(i) << th[1] * t, th[0] * t, 1.0;
    }
    return true;
  });
  const Eigen::Vector3d th(2.0, 3.0, 1.0);
  UncertaintyOptions o;
  o.names = {"a", "b", "c"};
  const ParameterUncertainty u = nlid::parameter_uncertainty(pb, th, o);
  CHECK(u.rank == 2);
  CHECK(std::isinf(u.stddev[0]));
  CHECK(std::isinf(u.stddev[1]));
  CHECK(std::isfinite(u.stddev[2]));
  CHECK(u.stddev[2] > 0.0);
  REQUIRE(u.unidentifiable.size() == 1);
  const Eigen::VectorXd& v = u.unidentifiable[0];
  // +1 % of a with −1 % of b (or the reverse) leaves a·b unchanged; c takes no part.
  CHECK(std::abs(v[0] / th[0]) == Approx(0.01).epsilon(1e-6));
  CHECK(v[1] / th[1] == Approx(-v[0] / th[0]).epsilon(1e-6));
  CHECK(v[2] == 0.0);
  CHECK(std::isnan(u.correlation(0, 1)));
  const std::string rep = u.report();
  const bool ab = rep.find("data: a +1 % with b -1 %") != std::string::npos || rep.find("data: a -1 % with b +1 %") != std::string::npos;
  const bool ba = rep.find("data: b +1 % with a -1 %") != std::string::npos || rep.find("data: b -1 % with a +1 %") != std::string::npos;
  INFO(rep);
  CHECK((ab || ba));
  CHECK_THAT(rep, Contains("a = 2 +- inf") && !Contains("with c"));
}

TEST_CASE("fixed parameters and parameters on a bound are left out of the covariance",
          "[estimation][uncertainty]") {
  std::mt19937_64 gen(19);
  const Quadratic q(ar1_noise(150, 0.0, 0.1, gen));
  const auto pb = q.problem();
  const Eigen::Vector3d th = q.solve();
  UncertaintyOptions o;
  o.residuals = ResidualModel::white;
  o.names = {"a", "b", "c"};
  o.fixed = {false, false, true};
  o.lower_bounds = Eigen::Vector3d(-1e9, th[1], -1e9);  // b rests on its lower bound
  const ParameterUncertainty u = nlid::parameter_uncertainty(pb, th, o);
  CHECK(u.free == std::vector<bool>{true, false, false});
  CHECK(u.at_bound == std::vector<bool>{false, true, false});
  CHECK(u.stddev[1] == 0.0);
  CHECK(u.stddev[2] == 0.0);
  CHECK(u.degrees_of_freedom == 149);
  // a alone: σ² / Σ1² with σ² from the residuals at θ over 149 degrees of freedom.
  const Eigen::VectorXd e = q.X * th - q.y;
  CHECK(u.stddev[0] == Approx(std::sqrt(e.squaredNorm() / 149.0 / 150.0)).epsilon(1e-12));
  CHECK(u.covariance.col(1).cwiseAbs().maxCoeff() == 0.0);
  CHECK_THAT(u.report(), Contains("b = ") && Contains("(on its bound") && Contains("(fixed)"));
}

TEST_CASE("bad input to parameter_uncertainty is named", "[estimation][uncertainty]") {
  std::mt19937_64 gen(23);
  const Quadratic q(ar1_noise(40, 0.0, 0.1, gen));
  const auto pb = q.problem();
  const Eigen::Vector3d th = q.solve();
  auto fails = [&](UncertaintyOptions o, const std::string& what, Eigen::VectorXd theta = Eigen::VectorXd()) {
    if (theta.size() == 0) theta = th;
    CHECK_THROWS_WITH(nlid::parameter_uncertainty(pb, theta, o), Contains(what));
  };
  UncertaintyOptions o;
  fails(o, "theta has 2 entries; the problem has 3", Eigen::Vector2d(1, 2));
  fails(o, "parameter theta[1] is not finite", Eigen::Vector3d(1, std::nan(""), 2));
  o.names = {"a"};
  fails(o, "names has 1 entries");
  o = {};
  o.fixed = {true};
  fails(o, "fixed has 1 entries");
  o = {};
  o.series = {{30, 20, 1}};
  fails(o, "residual series 0 (offset 30, length 20, stride 1) is empty or reaches outside the 40 residuals");
  o = {};
  o.series = {{0, 25, 1}, {20, 20, 1}};
  fails(o, "residual row 20 is in two series (the second is series 1)");
  o.series = {{0, 20, 1}, {21, 19, 1}};
  fails(o, "residual row 20 is in no series; the series must cover all 40 residuals");
  o = {};
  o.rank_tolerance = 0.0;
  fails(o, "rank_tolerance must be in (0, 1)");
  o = {};
  o.max_lag = -2;
  fails(o, "max_lag must be >= 0");

  auto broken = nlid::make_problem<3>(3, 40, [](const Eigen::Vector3d&, Eigen::VectorXd&,
                                                Eigen::Matrix<double, Eigen::Dynamic, 3>*) { return false; });
  CHECK_THROWS_WITH(nlid::parameter_uncertainty(broken, th), Contains("cannot be evaluated at theta"));
  auto nan_jacobian = nlid::make_problem<3>(3, 40, [](const Eigen::Vector3d&, Eigen::VectorXd& r,
                                                      Eigen::Matrix<double, Eigen::Dynamic, 3>* J) {
    r.setOnes();
    if (J) {
      J->setOnes();
      J->col(2).setConstant(std::numeric_limits<double>::quiet_NaN());
    }
    return true;
  });
  UncertaintyOptions named;
  named.names = {"gain", "offset", "tau"};
  CHECK_THROWS_WITH(nlid::parameter_uncertainty(nan_jacobian, th, named),
                    Contains("Jacobian column of tau is not finite"));
  auto short_problem = nlid::make_problem<3>(3, 3, [](const Eigen::Vector3d& t, Eigen::VectorXd& r,
                                                      Eigen::Matrix<double, Eigen::Dynamic, 3>* J) {
    r = t;
    if (J) J->setIdentity();
    return true;
  });
  CHECK_THROWS_WITH(nlid::parameter_uncertainty(short_problem, Eigen::Vector3d(1, 2, 3)),
                    Contains("3 data rows for 3 free parameters"));
}

TEST_CASE("many undetermined directions: the report lists five, each by its five largest changes",
          "[estimation][uncertainty]") {
  // y = (θ₀ + … + θ₇)·t: only the sum is determined, seven directions are not.
  auto pb = nlid::make_problem<nlid::Dynamic>(8, 50, [](const Eigen::VectorXd& th, Eigen::VectorXd& r,
                                                        Eigen::MatrixXd* J) {
    for (int i = 0; i < 50; ++i) {
      const double t = i / 49.0;
      r[i] = th.sum() * t - (4.0 * t + 0.01 * std::sin(7.0 * i));
      if (J) J->row(i).setConstant(t);
    }
    return true;
  });
  const Eigen::VectorXd th = Eigen::VectorXd::Constant(8, 0.5);
  const ParameterUncertainty u = nlid::parameter_uncertainty(pb, th);
  CHECK(u.rank == 1);
  CHECK(u.unidentifiable.size() == 7);
  for (int i = 0; i < 8; ++i) CHECK(std::isinf(u.stddev[i]));
  const std::string rep = u.report();
  INFO(rep);
  std::size_t lines = 0;
  for (std::size_t at = rep.find("not identifiable from these data"); at != std::string::npos;
       at = rep.find("not identifiable from these data", at + 1)) {
    ++lines;
    const std::string line = rep.substr(at, rep.find('\n', at) - at);
    std::size_t withs = 0;
    for (std::size_t w = line.find(" with "); w != std::string::npos; w = line.find(" with ", w + 1)) ++withs;
    CHECK(withs <= 4);  // at most five terms
  }
  CHECK(lines == 5);
  CHECK_THAT(rep, Contains("... and 2 more undetermined directions"));
}

TEST_CASE("edge cases: nothing free, a lag longer than the record, one short record beside a long one",
          "[estimation][uncertainty]") {
  std::mt19937_64 gen(29);
  const Quadratic q(ar1_noise(60, 0.8, 0.1, gen));
  const auto pb = q.problem();
  const Eigen::Vector3d th = q.solve();

  // Every parameter fixed: zeros, not an error about degrees of freedom.
  UncertaintyOptions fixed;
  fixed.fixed = {true, true, true};
  const ParameterUncertainty none = nlid::parameter_uncertainty(pb, th, fixed);
  CHECK(none.stddev.isZero());
  CHECK(none.rank == 0);

  // A window longer than the only series is cut to what the series has.
  UncertaintyOptions wide;
  wide.max_lag = 1000;
  CHECK(nlid::parameter_uncertainty(pb, th, wide).max_lag == 59);

  // A 3-sample record beside a 57-sample one does not shrink the automatic window to nothing.
  UncertaintyOptions one, two;
  one.prewhiten = two.prewhiten = false;
  two.series = {{0, 57, 1}, {57, 3, 1}};
  const ParameterUncertainty a = nlid::parameter_uncertainty(pb, th, one);
  const ParameterUncertainty b = nlid::parameter_uncertainty(pb, th, two);
  INFO("one series: " << a.max_lag << " lags, with the short one split off: " << b.max_lag);
  CHECK(b.max_lag >= a.max_lag - 1);
  CHECK(b.max_lag > 1);
}

TEST_CASE("uncertainty_from_covariance: a stored covariance back in the form the band takes, bad ones named",
          "[estimation][uncertainty]") {
  Eigen::MatrixXd c(3, 3);
  c << 4.0, 1.2, 0.0,  //
      1.2, 1.0, 0.0,   //
      0.0, 0.0, 0.0;
  const Eigen::Vector3d theta(2.0, -1.0, 0.5);
  const ParameterUncertainty u = nlid::uncertainty_from_covariance({"a", "b", "c"}, theta, c);
  CHECK(u.stddev == Eigen::Vector3d(2.0, 1.0, 0.0));
  CHECK(u.correlation(0, 1) == Approx(0.6).epsilon(1e-15));
  CHECK(std::isnan(u.correlation(0, 2)));  // c has no spread: no correlation
  CHECK(u.free == std::vector<bool>{true, true, false});
  CHECK(u.rank == 2);
  CHECK(u.observations == 0);
  CHECK(u.stored);
  CHECK(std::isnan(u.stddev_white[0]));
  CHECK(u.caveat.empty());
  const std::string r = u.report();
  CHECK_THAT(r, Contains("from a stored covariance; 3 unknowns, 2 free") && Contains("a = 2 +- 2 (100 %)") &&
                    Contains("c = 0.5  (fixed)"));
  CHECK_THAT(r, !Contains("white formula"));

  // Given deviations win over the diagonal: +inf marks a parameter the data left open.
  const ParameterUncertainty open = nlid::uncertainty_from_covariance(
      {"a", "b", "c"}, theta, c, Eigen::Vector3d(2.0, std::numeric_limits<double>::infinity(), 0.0), {false, false, true});
  CHECK(std::isinf(open.stddev[1]));
  CHECK(open.rank == 1);
  CHECK(open.free == std::vector<bool>{true, true, false});
  CHECK_THAT(open.caveat, Contains("not determined by the estimation data") && Contains(": b"));
  CHECK_THAT(open.report(), Contains("3 unknowns, 2 free, 1 of them undetermined") && Contains("b = -1 +- inf"));
  // A flagged parameter is held even with a variance.
  const ParameterUncertainty held = nlid::uncertainty_from_covariance({"a", "b", "c"}, theta, c, {}, {true, false, false});
  CHECK(held.free == std::vector<bool>{false, true, false});
  // No names: numbered.
  CHECK(nlid::uncertainty_from_covariance({}, theta, c).names[2] == "theta[2]");

  CHECK_THROWS_WITH(nlid::uncertainty_from_covariance({"a", "b", "c"}, theta, Eigen::MatrixXd::Identity(2, 2)),
                    Contains("a 2x2 covariance for 3 parameters"));
  CHECK_THROWS_WITH(nlid::uncertainty_from_covariance({"a", "b"}, theta, c), Contains("2 names for 3 parameters"));
  CHECK_THROWS_WITH(nlid::uncertainty_from_covariance({"a", "b", "c"}, theta, c, Eigen::Vector2d(1.0, 1.0)),
                    Contains("2 standard deviations for 3 parameters"));
  Eigen::MatrixXd skew = c;
  skew(1, 0) = 1.5;
  CHECK_THROWS_WITH(nlid::uncertainty_from_covariance({"a", "b", "c"}, theta, skew),
                    Contains("not symmetric (b with a: 1.5 and 1.2)"));
  Eigen::MatrixXd negative = c;
  negative(2, 2) = -0.1;
  CHECK_THROWS_WITH(nlid::uncertainty_from_covariance({"a", "b", "c"}, theta, negative),
                    Contains("variance of c must be >= 0, got -0.1"));
  Eigen::MatrixXd nan = c;
  nan(0, 2) = std::numeric_limits<double>::quiet_NaN();
  CHECK_THROWS_WITH(nlid::uncertainty_from_covariance({"a", "b", "c"}, theta, nan),
                    Contains("covariance of a with c is not finite"));
  // A NaN further down is named as such, not as an asymmetry of the rows before it.
  Eigen::MatrixXd later = c;
  later(2, 1) = later(1, 2) = std::numeric_limits<double>::quiet_NaN();
  CHECK_THROWS_WITH(nlid::uncertainty_from_covariance({"a", "b", "c"}, theta, later),
                    Contains("covariance of b with c is not finite"));
  CHECK_THROWS_WITH(nlid::uncertainty_from_covariance({"a", "b", "c"}, theta, c, Eigen::Vector3d(1.0, -1.0, 0.0)),
                    Contains("standard deviation of b must be >= 0"));
  try {
    (void)nlid::uncertainty_from_covariance({"a", "b", "c"}, theta, negative);
    FAIL("a negative variance was accepted");
  } catch (const nlid::Error& e) {
    CHECK(e.where().parameter == "c");
  }
}
