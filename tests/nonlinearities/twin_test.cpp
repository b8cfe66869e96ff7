// The Dynamic twins compute exactly what the fixed-size types compute.
#include <catch2/catch.hpp>

#include <cmath>
#include <random>
#include <span>
#include <vector>

#include "nlid/nonlinearities.hpp"

namespace {

using nlid::Dynamic;

struct Data {
  Eigen::MatrixXd X;
  Eigen::VectorXd y;
};

Data make_data(int m) {
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> u(-2, 2);
  Data d{Eigen::MatrixXd(300, m), Eigen::VectorXd(300)};
  for (int i = 0; i < 300; ++i) {
    for (int j = 0; j < m; ++j) d.X(i, j) = u(rng);
    d.y(i) = std::tanh(d.X(i, 0)) + 0.3 * d.X(i, m - 1) * d.X(i, m - 1);
  }
  return d;
}

// Initialises both on the same data, then compares θ and values at every data row.
template <class A, class B>
void check_twins(A a, B b) {
  REQUIRE(a.num_parameters() == b.num_parameters());
  REQUIRE(a.input_dimension() == b.input_dimension());
  const Data d = make_data(a.input_dimension());
  std::vector<double> ta(static_cast<std::size_t>(a.num_parameters())), tb(ta.size());
  a.initialize(d.X, d.y, ta);
  b.initialize(d.X, d.y, tb);
  for (std::size_t i = 0; i < ta.size(); ++i) CHECK(ta[i] == Approx(tb[i]).epsilon(1e-12).margin(1e-12));
  const Eigen::VectorXd ya = nlid::evaluate_rows(a, d.X, ta);
  const Eigen::VectorXd yb = nlid::evaluate_rows(b, d.X, ta);  // same θ into both
  CHECK((ya - yb).cwiseAbs().maxCoeff() < 1e-12);
  CHECK(a.parameter_names() == b.parameter_names());
  CHECK(a.describe(ta) == b.describe(ta));
}

}  // namespace

TEST_CASE("Dynamic twins equal the fixed-size nonlinearities", "[nonlinearities][twin]") {
  check_twins(nlid::LinearMap<3>{}, nlid::LinearMap<Dynamic>(3));
  check_twins(nlid::SigmoidNet<2, 4>{}, nlid::SigmoidNet<Dynamic, Dynamic>(2, 4));
  check_twins(nlid::SigmoidNet<2, 4>{}, nlid::SigmoidNet<2, Dynamic>(2, 4));
  check_twins(nlid::SigmoidNet<3, 2, false>{}, nlid::SigmoidNet<Dynamic, 2, false>(3, 2));
  check_twins(nlid::WaveletNet<2, 3>{}, nlid::WaveletNet<Dynamic, Dynamic>(2, 3));
  check_twins(nlid::WaveletNet<1, 3, false>{}, nlid::WaveletNet<1, Dynamic, false>(1, 3));
  check_twins(nlid::PwLinear<6>{}, nlid::PwLinear<Dynamic>(6));
  check_twins(nlid::Poly1d<3>{}, nlid::Poly1d<Dynamic>(3));
  check_twins(nlid::TreePartition<2, 3>{}, nlid::TreePartition<Dynamic, Dynamic>(2, 3));
}
