// Explicit instantiation (Sophus style): every member and every overload must compile for
// float and double, fixed and dynamic N. Plus compile-time checks of the AdScalar concept.
// nlid-unity: separate (explicit instantiations must be at namespace scope of nlid)
#include <catch2/catch.hpp>

#include <complex>
#include <string>

#include "nlid/ad.hpp"

template struct nlid::Dual<double, 3>;
template struct nlid::Dual<float, 3>;
template struct nlid::Dual<double, nlid::Dynamic>;
template struct nlid::Dual<float, nlid::Dynamic>;
template struct nlid::Dual<nlid::Dual<double, 1>, 2>;

#define NLID_INSTANTIATE_UNARY(T, N, fn) \
  template nlid::Dual<T, N> nlid::fn<T, N>(const nlid::Dual<T, N>&);
#define NLID_INSTANTIATE_ALL(T, N)                                                         \
  NLID_INSTANTIATE_UNARY(T, N, abs)                                                        \
  NLID_INSTANTIATE_UNARY(T, N, exp)                                                        \
  NLID_INSTANTIATE_UNARY(T, N, exp2)                                                       \
  NLID_INSTANTIATE_UNARY(T, N, expm1)                                                      \
  NLID_INSTANTIATE_UNARY(T, N, log)                                                        \
  NLID_INSTANTIATE_UNARY(T, N, log10)                                                      \
  NLID_INSTANTIATE_UNARY(T, N, log2)                                                       \
  NLID_INSTANTIATE_UNARY(T, N, log1p)                                                      \
  NLID_INSTANTIATE_UNARY(T, N, sqrt)                                                       \
  NLID_INSTANTIATE_UNARY(T, N, cbrt)                                                       \
  NLID_INSTANTIATE_UNARY(T, N, sin)                                                        \
  NLID_INSTANTIATE_UNARY(T, N, cos)                                                        \
  NLID_INSTANTIATE_UNARY(T, N, tan)                                                        \
  NLID_INSTANTIATE_UNARY(T, N, asin)                                                       \
  NLID_INSTANTIATE_UNARY(T, N, acos)                                                       \
  NLID_INSTANTIATE_UNARY(T, N, atan)                                                       \
  NLID_INSTANTIATE_UNARY(T, N, sinh)                                                       \
  NLID_INSTANTIATE_UNARY(T, N, cosh)                                                       \
  NLID_INSTANTIATE_UNARY(T, N, tanh)                                                       \
  NLID_INSTANTIATE_UNARY(T, N, erf)                                                        \
  NLID_INSTANTIATE_UNARY(T, N, floor)                                                      \
  NLID_INSTANTIATE_UNARY(T, N, ceil)                                                       \
  NLID_INSTANTIATE_UNARY(T, N, round)                                                      \
  NLID_INSTANTIATE_UNARY(T, N, trunc)                                                      \
  NLID_INSTANTIATE_UNARY(T, N, square)                                                     \
  template nlid::Dual<T, N> nlid::pow<T, N>(const nlid::Dual<T, N>&, const nlid::Dual<T, N>&); \
  template nlid::Dual<T, N> nlid::atan2<T, N>(const nlid::Dual<T, N>&, const nlid::Dual<T, N>&); \
  template nlid::Dual<T, N> nlid::hypot<T, N>(const nlid::Dual<T, N>&, const nlid::Dual<T, N>&); \
  template nlid::Dual<T, N> nlid::max<T, N>(const nlid::Dual<T, N>&, const nlid::Dual<T, N>&);   \
  template nlid::Dual<T, N> nlid::min<T, N>(const nlid::Dual<T, N>&, const nlid::Dual<T, N>&);   \
  template bool nlid::isfinite<T, N>(const nlid::Dual<T, N>&);                             \
  template bool nlid::isnan<T, N>(const nlid::Dual<T, N>&);                                \
  template bool nlid::isinf<T, N>(const nlid::Dual<T, N>&);

NLID_INSTANTIATE_ALL(double, 3)
NLID_INSTANTIATE_ALL(float, 3)
NLID_INSTANTIATE_ALL(double, nlid::Dynamic)
NLID_INSTANTIATE_ALL(float, nlid::Dynamic)

// ---- AdScalar: the positive set and some look-alikes it must reject -----------------------------
static_assert(nlid::AdScalar<double>);
static_assert(nlid::AdScalar<float>);
static_assert(nlid::AdScalar<long double>);
static_assert(nlid::AdScalar<nlid::Dual<double, 4>>);
static_assert(nlid::AdScalar<nlid::Dual<float, 1>>);
static_assert(nlid::AdScalar<nlid::DynamicDual<double>>);
static_assert(nlid::AdScalar<nlid::Dual<nlid::Dual<double, 1>, 2>>);
static_assert(!nlid::AdScalar<int>);
static_assert(!nlid::AdScalar<bool>);
static_assert(!nlid::AdScalar<std::complex<double>>);
static_assert(!nlid::AdScalar<std::string>);
static_assert(!nlid::AdScalar<nlid::Dual<int, 2>>);
static_assert(nlid::DualNumber<nlid::Dual<double, 2>>);
static_assert(!nlid::DualNumber<double>);
static_assert(nlid::is_dual_v<const nlid::Dual<double, 2>&>);
static_assert(!nlid::is_dual_v<double>);

namespace {
// A generic function constrained by the concept, as model code writes it.
template <nlid::AdScalar T>
T logistic_sum(const T& x) {
  using std::exp;
  return T(1) / (T(1) + exp(-x)) + 2 * x;
}
}  // namespace

TEST_CASE("one generic function, evaluated on float, double and Dual", "[ad][instantiation]") {
  CHECK(logistic_sum(0.0) == Approx(0.5));
  CHECK(logistic_sum(0.0f) == Approx(0.5f));
  const auto d = logistic_sum(nlid::Dual<double, 1>::variable(0.0, 0));
  CHECK(d.a == Approx(0.5));
  CHECK(d.v[0] == Approx(0.25 + 2.0));  // σ'(0) = 1/4
  const auto f = logistic_sum(nlid::Dual<float, 1>::variable(0.0f, 0));
  CHECK(f.v[0] == Approx(2.25f));
  const auto dd = logistic_sum(nlid::DynamicDual<double>::variable(0.0, 0, 1));
  CHECK(dd.v[0] == Approx(2.25));
}
