// Batch<T, W>: lane-wise arithmetic and math, masks without bool conversion, the explicit
// conversion's "largest lane" meaning, and the point of the type — a batched simulation of W
// parameter sets equals W single simulations (nlarx5-like sigmoid network, grey-box throttle).
#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <random>
#include <span>
#include <type_traits>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/batch.hpp"
#include "nlid/models/greybox_simulate.hpp"
#include "nlid/models/nlarx.hpp"
#include "nlid/nonlinearities/sigmoid_network.hpp"
#include "nlid/regressors/lagged.hpp"

#include "../support/register_widths.hpp"
#include "../support/study_throttle.hpp"

namespace {

using B4 = nlid::Batch<double, 4>;
using B8 = nlid::Batch<double, 8>;

// ulp distance of two finite doubles of the same sign.
double ulps(double a, double b) {
  if (a == b) return 0.0;
  return std::abs(a - b) / std::abs(std::nextafter(b, 2 * b) - b);
}

// Largest ulp distance of a batched function from its scalar reference over 20 000 random
// batches: half uniform on ±range, half on ±range/narrow (where the reduction is most used).
template <class F, class Ref>
double worst_ulps(F batched, Ref reference, double range, double narrow, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> dist(-range, range);
  double worst = 0.0;
  for (int rep = 0; rep < 20000; ++rep) {
    B8 x;
    for (int i = 0; i < 8; ++i) x[i] = rep < 10000 ? dist(rng) : dist(rng) / narrow;
    const B8 v = batched(x);
    for (int i = 0; i < 8; ++i) worst = std::max(worst, ulps(v[i], reference(x[i])));
  }
  return worst;
}

using nlid_test::StudyThrottle;  // the study's grey-box equation (tests/support/study_throttle.hpp)

// Throttle command switching between 1.2 (into the upper stop) and 0.2 every `hold` samples.
Eigen::MatrixXd throttle_square_wave(int n, int hold) {
  Eigen::MatrixXd u(n, 1);
  for (int t = 0; t < n; ++t) u(t, 0) = (t / hold) % 2 == 0 ? 1.2 : 0.2;
  return u;
}

// Lane w of a batched throttle run, simulated alone on double from the same start (20, 0).
template <int W, class OnSample>
Eigen::Index throttle_lane(const std::array<nlid::Batch<double, W>, 4>& pb, int w, const nlid::IntegratorOptions& opt,
                           const Eigen::MatrixXd& u, double ts, int sub, OnSample&& on_sample) {
  double p[4], x[2] = {20.0, 0.0};
  for (int j = 0; j < 4; ++j) p[j] = pb[j][w];
  return nlid::simulate_physics<double>(StudyThrottle{}, opt, sub, u, ts, p, x, on_sample);
}

using nlid_test::register_widths;  // tests/support/register_widths.hpp

// The throttle batch `pb` (lanes of Batch<double, W>) from (20, 0) on registers of `r` bytes
// (nlid::with_register_bytes); returns simulate_physics' sample count.
template <int W, class OnSample>
Eigen::Index throttle_on_registers(std::size_t r, const std::array<nlid::Batch<double, W>, 4>& pb,
                                   const nlid::IntegratorOptions& opt, const Eigen::MatrixXd& u, double ts, int sub,
                                   OnSample&& on_sample) {
  Eigen::Index steps = -1;
  nlid::with_register_bytes(
      [&]<std::size_t R>() {
        using BR = nlid::Batch<double, W, R>;
        std::array<BR, 4> p;
        for (int j = 0; j < 4; ++j) p[static_cast<std::size_t>(j)] = BR::load(&pb[static_cast<std::size_t>(j)][0]);
        std::array<BR, 2> x{BR(20.0), BR(0.0)};
        steps = nlid::simulate_physics<BR>(StudyThrottle{}, opt, sub, u, ts, p.data(), x.data(),
                                           [&](Eigen::Index k, const BR* y) { on_sample(k, y[0]); });
      },
      r);
  return steps;
}

}  // namespace

TEST_CASE("Batch arithmetic acts lane by lane", "[core][batch]") {
  B4 a, b;
  for (int i = 0; i < 4; ++i) {
    a[i] = 1.5 + i;
    b[i] = -0.25 * (i + 1);
  }
  const B4 s = a + b, d = a - b, p = a * b, q = a / b, c = 2.0 - a * 3.0 + b / 4.0, n = -a;
  for (int i = 0; i < 4; ++i) {
    CHECK(s[i] == a[i] + b[i]);
    CHECK(d[i] == a[i] - b[i]);
    CHECK(p[i] == a[i] * b[i]);
    CHECK(q[i] == a[i] / b[i]);
    CHECK(c[i] == 2.0 - a[i] * 3.0 + b[i] / 4.0);
    CHECK(n[i] == -a[i]);
  }
  const B4 m = max(a, -b), mn = min(a, b), ab = abs(b), sq = sqrt(a), lg = log(a), th = tanh(b);
  for (int i = 0; i < 4; ++i) {
    CHECK(m[i] == std::max(a[i], -b[i]));
    CHECK(mn[i] == std::min(a[i], b[i]));
    CHECK(ab[i] == std::abs(b[i]));
    CHECK(sq[i] == std::sqrt(a[i]));
    CHECK(lg[i] == std::log(a[i]));
    CHECK(th[i] == std::tanh(b[i]));
  }
  CHECK(B4(0)[3] == 0.0);  // int broadcast (generic code writes T(0))
}

// Every operation of Batch<T, W> against the same operation on each lane alone, bit for bit.
// W picks the storage (core/batch.hpp): a plain array (W = 7), one register-wide vector, several
// (W = 16, 32 exceed every x86 register), float lanes. Lane values include −0, ±∞ and NaN, and
// the special lanes sit in the *last* lanes, so a reduction or a fix-up pass that only looks at
// the first register of a multi-register batch fails here.
template <class T, int W>
void check_lanes_like_scalars() {
  using B = nlid::Batch<T, W>;
  static_assert(sizeof(B) == sizeof(T) * W, "Batch has the size of T[W]");
  const T inf = std::numeric_limits<T>::infinity(), nan = std::numeric_limits<T>::quiet_NaN();
  B a, b;
  for (int i = 0; i < W; ++i) {
    a[i] = static_cast<T>(0.75 * (i - W / 2) + 0.125);
    b[i] = static_cast<T>(-0.5 * (i % 5) + 1.0);
  }
  a[W - 1] = nan;
  b[W - 2] = -0.0f;  // W ≥ 2 here
  if (W >= 4) {
    a[W - 3] = inf;
    b[W - 4] = nan;
  }
  const auto same = [](T x, T y) { return std::bit_cast<nlid::detail::lane_bits_t<T>>(x) == std::bit_cast<nlid::detail::lane_bits_t<T>>(y); };
  const B s = a + b, d = a - b, p = a * b, q = a / b, n = -a, mx = max(a, b), mn = min(a, b), ab = abs(b);
  const B sel = select(a < b, a, b), bc(static_cast<T>(-0.0));
  const auto lt = a < b, ge = a >= b, eq = a == a, ne = a != a;
  for (int i = 0; i < W; ++i) {
    INFO("W = " << W << ", lane " << i);
    CHECK(same(s[i], a[i] + b[i]));
    CHECK(same(d[i], a[i] - b[i]));
    CHECK(same(p[i], a[i] * b[i]));
    CHECK(same(q[i], a[i] / b[i]));
    CHECK(same(n[i], -a[i]));
    CHECK(same(mx[i], std::max(a[i], b[i])));
    CHECK(same(mn[i], std::min(a[i], b[i])));
    CHECK(same(ab[i], std::fabs(b[i])));
    CHECK(same(sel[i], a[i] < b[i] ? a[i] : b[i]));
    CHECK(same(bc[i], static_cast<T>(-0.0)));  // the broadcast keeps −0's sign
    CHECK(lt[i] == (a[i] < b[i]));
    CHECK(ge[i] == (a[i] >= b[i]));
    CHECK(eq[i] == (a[i] == a[i]));
    CHECK(ne[i] == (a[i] != a[i]));
  }
  CHECK_FALSE(nlid::isfinite(a));  // the NaN is in the last lane
  B fin(static_cast<T>(1.5));
  CHECK(nlid::isfinite(fin));
  fin[W - 1] = -inf;
  CHECK_FALSE(nlid::isfinite(fin));
  CHECK(std::isnan(static_cast<T>(a)));
  // Pointer round trip: load/store move the W lanes in order.
  std::array<T, static_cast<std::size_t>(W)> buf{};
  b.store(buf.data());
  const B back = B::load(buf.data());
  for (int i = 0; i < W; ++i) CHECK(same(back[i], b[i]));
  if constexpr (std::is_same_v<T, double>) {
    // exp and logistic: the far-argument fix-up must reach lanes in every register.
    B x(0.25);
    x[W - 1] = 710.0;  // overflows: +∞ from std::exp
    if (W >= 2) x[W - 2] = -745.5;  // subnormal
    const B e = exp(x), g = nlid::logistic(-x);
    CHECK(e[W - 1] == std::exp(710.0));
    if (W >= 2) CHECK(e[W - 2] == std::exp(-745.5));
    CHECK(g[W - 1] >= 0.0);
    CHECK(g[W - 1] < 1e-300);
    if (W >= 3) {  // lane 0 keeps its ordinary argument
      CHECK(ulps(e[0], std::exp(0.25)) <= 2.0);
      CHECK(ulps(g[0], nlid::detail::logistic(-0.25)) <= 4.0);
    }
  }
}

TEST_CASE("Batch acts like W scalars for every lane storage (array, one or several registers, float)", "[core][batch]") {
  check_lanes_like_scalars<double, 2>();
  check_lanes_like_scalars<double, 4>();
  check_lanes_like_scalars<double, 7>();
  check_lanes_like_scalars<double, 8>();
  check_lanes_like_scalars<double, 16>();
  check_lanes_like_scalars<double, 32>();
  check_lanes_like_scalars<float, 4>();
  check_lanes_like_scalars<float, 16>();
}

TEST_CASE("Batch on every register width the CPU offers acts like its lanes alone", "[core][batch]") {
  // nlid::with_register_bytes compiles its callable for registers of R bytes (AVX2, AVX-512)
  // and picks R at run time, also in a build for baseline x86-64. The lanes must not notice:
  // each operation below is computed inside the dispatched call on Batch<double, 8, R> and
  // compared, lane by lane and bit for bit, with the same operation on plain doubles. Special
  // values sit in the last lanes, as in the test above; exp and logistic (whose kernels may
  // use fused multiply-adds in the wider code) are compared within their ulp bounds.
  constexpr int W = 8;
  using Lanes = std::array<double, W>;
  const double inf = std::numeric_limits<double>::infinity(), nan = std::numeric_limits<double>::quiet_NaN();
  Lanes a{}, b{};
  for (int i = 0; i < W; ++i) {
    a[i] = 0.75 * (i - W / 2) + 0.125;
    b[i] = -0.5 * (i % 5) + 1.0;
  }
  a[W - 1] = nan;
  a[W - 3] = inf;
  b[W - 2] = -0.0;
  b[W - 4] = nan;
  Lanes x{};  // exp/logistic arguments: ordinary ones and far ones in the last register's lanes
  for (int i = 0; i < W; ++i) x[i] = 0.37 * i - 1.1;
  x[W - 1] = 710.0;
  x[W - 2] = -745.5;
  const auto same = [](double p, double q) { return std::bit_cast<std::uint64_t>(p) == std::bit_cast<std::uint64_t>(q); };
  for (std::size_t r : register_widths()) {
    INFO("registers of " << r << " bytes");
    std::array<Lanes, 12> out{};
    std::size_t seen_r = 0, seen_align = 0;
    bool a_finite = true, fin_finite = false;
    double a_largest = 0.0;
    nlid::with_register_bytes(
        [&]<std::size_t R>() {
          using B = nlid::Batch<double, W, R>;
          seen_r = R;
          seen_align = alignof(B);
          const B ba = B::load(a.data()), bb = B::load(b.data()), bx = B::load(x.data());
          const B res[12] = {ba + bb, ba - bb, ba * bb, ba / bb, -ba, max(ba, bb), min(ba, bb), abs(bb),
                             select(ba < bb, ba, bb), B(-0.0), exp(bx), nlid::logistic(-bx)};
          for (int k = 0; k < 12; ++k) res[k].store(out[static_cast<std::size_t>(k)].data());
          a_finite = nlid::isfinite(ba);
          fin_finite = nlid::isfinite(B(1.5));
          a_largest = static_cast<double>(ba);
        },
        r);
    CHECK(seen_r == r);
    CHECK(seen_align == std::min<std::size_t>(r, 64));
    for (int i = 0; i < W; ++i) {
      INFO("lane " << i);
      const auto o = [&](int k) { return out[static_cast<std::size_t>(k)][static_cast<std::size_t>(i)]; };
      CHECK(same(o(0), a[i] + b[i]));
      CHECK(same(o(1), a[i] - b[i]));
      CHECK(same(o(2), a[i] * b[i]));
      CHECK(same(o(3), a[i] / b[i]));
      CHECK(same(o(4), -a[i]));
      CHECK(same(o(5), std::max(a[i], b[i])));
      CHECK(same(o(6), std::min(a[i], b[i])));
      CHECK(same(o(7), std::fabs(b[i])));
      CHECK(same(o(8), a[i] < b[i] ? a[i] : b[i]));
      CHECK(same(o(9), -0.0));  // the broadcast keeps −0's sign
      if (i < W - 2) {
        CHECK(ulps(o(10), std::exp(x[i])) <= 2.0);
        CHECK(ulps(o(11), nlid::detail::logistic(-x[i])) <= 4.0);
      }
    }
    CHECK(out[10][W - 1] == std::exp(710.0));
    CHECK(out[10][W - 2] == std::exp(-745.5));
    CHECK(out[11][W - 1] >= 0.0);
    CHECK(out[11][W - 1] < 1e-300);
    CHECK_FALSE(a_finite);
    CHECK(fin_finite);
    CHECK(std::isnan(a_largest));
  }
}

TEST_CASE("A register width the CPU or the build cannot use is refused by name", "[core][batch]") {
  const auto never = []<std::size_t R>() {};
  CHECK_THROWS_WITH(nlid::with_register_bytes(never, 24),
                    Catch::Contains("register width 24 bytes: use 16, 32 or 64") && Catch::Contains("register_bytes"));
  CHECK_THROWS_WITH(nlid::with_register_bytes(never, 128), Catch::Contains("use 16, 32 or 64"));
  if (nlid::cpu_register_bytes() < 64) {
    CHECK_THROWS_WITH(nlid::with_register_bytes(never, 64), Catch::Contains("this CPU offers at most"));
  }
  std::size_t widest = 0;
  nlid::with_register_bytes([&]<std::size_t R>() { widest = R; });  // 0: the widest
  CHECK(widest == nlid::cpu_register_bytes());
  CHECK(widest >= nlid::default_register_bytes);
}

TEST_CASE("Batch lives in any storage: members, std::vector, Eigen's heap", "[core][batch]") {
  // Batch<double, 8> is aligned to one vector register (16, 32 or 64 bytes by the build's
  // instruction set). The places a Batch lives must honour that, or the packed loads fault:
  // a struct member after a double, std::vector's and Eigen's heap blocks (EIGEN_MAX_ALIGN_BYTES
  // bounds the register width, core/batch.hpp).
  struct Packed {
    double pad;
    B8 x, y;
  };
  static_assert(alignof(B8) >= alignof(double) && sizeof(B8) == 8 * sizeof(double));
  static_assert(alignof(B8) <= EIGEN_MAX_ALIGN_BYTES || alignof(B8) <= 16);
  Packed s{};
  for (int i = 0; i < 8; ++i) {
    s.x[i] = 0.1 * (i + 1);
    s.y[i] = 2.0 - 0.2 * i;
  }
  s.y = nlid::logistic(s.x * s.y + exp(s.x)) / max(s.x, s.y);
  for (int i = 0; i < 8; ++i) {
    const double xi = 0.1 * (i + 1), yi = 2.0 - 0.2 * i;
    CHECK(s.y[i] == Approx(nlid::detail::logistic(xi * yi + std::exp(xi)) / std::max(xi, yi)).epsilon(1e-15));
  }
  std::vector<B8> many(7, B8(1.5));
  for (auto& b : many) b = b * b + 1.0;
  CHECK(many[6][7] == 3.25);
  Eigen::Matrix<B8, Eigen::Dynamic, 1> m(5);
  for (Eigen::Index k = 0; k < m.size(); ++k) m(k) = B8(static_cast<double>(k));
  m = m * 2.0;
  const B8 total = m.sum();
  CHECK(total[7] == 20.0);
}

TEST_CASE("Batch copies and assigns every lane, itself included", "[core][batch]") {
  // Batch has a hand-written lane-loop copy (core/batch.hpp: the implicit one was slow);
  // odd and wide lane counts cover the loop's remainder and multi-vector cases.
  nlid::Batch<double, 7> a;
  for (int i = 0; i < 7; ++i) a[i] = std::ldexp(1.0 + i, i) - 0.125 * i;
  const nlid::Batch<double, 7> c(a);
  nlid::Batch<double, 7> d(-1.0);
  d = a;
  auto& alias = d;
  d = alias;  // self-assignment leaves the lanes alone
  for (int i = 0; i < 7; ++i) {
    CHECK(c[i] == a[i]);
    CHECK(d[i] == a[i]);
  }
  nlid::Batch<float, 16> f;
  for (int i = 0; i < 16; ++i) f[i] = 0.5f * static_cast<float>(i) - 3.0f;
  nlid::Batch<float, 16> g = f, h;
  h = g;
  for (int i = 0; i < 16; ++i) CHECK(h[i] == 0.5f * static_cast<float>(i) - 3.0f);
}

TEST_CASE("Batch exp is within 2 ulp of std::exp and keeps its special values", "[core][batch]") {
  CHECK(worst_ulps([](const B8& x) { return exp(x); }, [](double x) { return std::exp(x); }, 700.0, 100.0, 7) <= 2.0);
  const double inf = std::numeric_limits<double>::infinity(), nan = std::numeric_limits<double>::quiet_NaN();
  B8 s;
  const double special[8] = {0.0, 709.5, 710.0, -720.0, -746.0, inf, -inf, nan};
  for (int i = 0; i < 8; ++i) s[i] = special[i];
  const B8 e = exp(s);
  CHECK(e[0] == 1.0);
  CHECK(e[1] == std::exp(709.5));
  CHECK(e[2] == inf);
  CHECK(e[3] == std::exp(-720.0));  // subnormal result
  CHECK(e[4] == 0.0);
  CHECK(e[5] == inf);
  CHECK(e[6] == 0.0);
  CHECK(std::isnan(e[7]));
  // float lanes go through std::exp.
  nlid::Batch<float, 4> f(0.5f);
  CHECK(exp(f)[2] == std::exp(0.5f));
}

TEST_CASE("Batch logistic is within 4 ulp of the scalar logistic, one division per lane", "[core][batch]") {
  CHECK(worst_ulps([](const B8& x) { return nlid::logistic(x); }, [](double x) { return nlid::detail::logistic(x); }, 40.0,
                   20.0, 9) <= 4.0);
  // The generic nonlinearity helper routes double batches here.
  B8 v(0.3);
  CHECK(nlid::detail::logistic(v)[5] == nlid::logistic(v)[5]);
  // Far tails: exactly 1, a vanishing positive number (clamped at e^-708), NaN stays NaN.
  const double inf = std::numeric_limits<double>::infinity(), nan = std::numeric_limits<double>::quiet_NaN();
  const double special[8] = {0.0, 800.0, inf, -800.0, -inf, 700.0, -700.0, nan};
  B8 s;
  for (int i = 0; i < 8; ++i) s[i] = special[i];
  const B8 g = nlid::logistic(s);
  CHECK(g[0] == 0.5);
  CHECK(g[1] == 1.0);
  CHECK(g[2] == 1.0);
  CHECK(g[3] >= 0.0);
  CHECK(g[3] < 1e-300);
  CHECK(g[4] >= 0.0);
  CHECK(g[4] < 1e-300);
  CHECK(g[5] == 1.0);
  CHECK(ulps(g[6], std::exp(-700.0)) <= 4.0);
  CHECK(std::isnan(g[7]));
}

TEST_CASE("Batch comparisons give masks that cannot be used as a bool", "[core][batch]") {
  B4 a;
  for (int i = 0; i < 4; ++i) a[i] = i - 1.5;  // −1.5 −0.5 0.5 1.5
  const auto k = a > 0.0;
  CHECK_FALSE(k[0]);
  CHECK(k[3]);
  CHECK(any(k));
  CHECK_FALSE(all(k));
  CHECK(all(k || !k));
  CHECK_FALSE(any(k && !k));
  const B4 r = select(k, a, B4(0.0));
  CHECK(r[0] == 0.0);
  CHECK(r[3] == 1.5);
  // A branch on a batched comparison has no single answer: it must not compile.
  static_assert(!std::is_convertible_v<nlid::BatchMask<double, 4>, bool>);
  static_assert(!std::is_constructible_v<bool, nlid::BatchMask<double, 4>>);
  static_assert(nlid::BatchScalar<B4> && !nlid::BatchScalar<double>);
}

TEST_CASE("Batch converts explicitly to its largest lane, NaN first", "[core][batch]") {
  B4 a;
  a[0] = 1.0;
  a[1] = -7.0;
  a[2] = 3.0;
  a[3] = 0.0;
  CHECK(static_cast<double>(a) == -7.0);
  CHECK(nlid::isfinite(a));
  a[2] = std::numeric_limits<double>::quiet_NaN();
  CHECK(std::isnan(static_cast<double>(a)));
  CHECK_FALSE(nlid::isfinite(a));
  CHECK(nlid::isnan(a));
  static_assert(!std::is_convertible_v<B4, double>);  // never silently
}

TEST_CASE("Batched nlarx5-like simulation equals W single simulations", "[core][batch][models]") {
  using Regs = nlid::LaggedRegressors<3, 3, 0>;
  using Net = nlid::SigmoidNet<6, 5>;
  nlid::Nlarx<Regs, Net> model;
  constexpr int P = Net::num_params;
  const int n = 1500;
  Eigen::MatrixXd u(n, 1);
  for (int t = 0; t < n; ++t) u(t, 0) = ((t / 97) % 3 == 0 ? 0.8 : -0.3) + 0.2 * std::sin(0.05 * t);
  // A stable base network: the linear part is an AR(3) with poles inside the unit circle; the
  // units add a bounded nonlinearity. Each lane perturbs it.
  Eigen::VectorXd base = Eigen::VectorXd::Zero(P);
  base(0) = 1.2;
  base(1) = -0.5;
  base(2) = 0.1;
  base(3) = 0.6;
  base(4) = 0.2;
  base(6) = 0.3;
  std::mt19937_64 rng(3);
  std::normal_distribution<double> nd(0.0, 1.0);
  for (int i = 7; i < P; ++i) base(i) = 0.5 * nd(rng);
  constexpr int W = 8;
  const int runs = 11;  // one full batch and a padded one
  Eigen::MatrixXd thetas(P, runs), x0s(model.state_dimension(), runs);
  for (int k = 0; k < runs; ++k) {
    for (int i = 0; i < P; ++i) thetas(i, k) = base(i) + 0.02 * nd(rng);
    for (int i = 0; i < x0s.rows(); ++i) x0s(i, k) = 0.5 * nd(rng);
  }
  // Single runs, the reference.
  Eigen::MatrixXd ys(n, runs);
  double scale = 0.0;
  for (int k = 0; k < runs; ++k) {
    Eigen::VectorXd th = thetas.col(k), x0 = x0s.col(k), y(n);
    REQUIRE(model.simulate(u, std::span<const double>(th.data(), P), std::span<const double>(x0.data(), x0.size()),
                           std::span<double>(y.data(), n)));
    ys.col(k) = y;
    scale = std::max(scale, y.cwiseAbs().maxCoeff());
  }
  CHECK(scale > 0.5);  // the runs do something
  // The default (the CPU's widest registers) and every width explicitly.
  std::vector<std::size_t> widths = register_widths();
  widths.insert(widths.begin(), 0);
  for (std::size_t r : widths) {
    INFO("register_bytes " << r);
    const Eigen::MatrixXd yb = nlid::simulate_batched<W>(model, u, thetas, x0s, r);
    REQUIRE(yb.rows() == n);
    REQUIRE(yb.cols() == runs);
    CHECK((ys - yb).cwiseAbs().maxCoeff() <= 1e-12 * scale);
  }
  // Without x0s every run starts from the zero state.
  const Eigen::MatrixXd y0 = nlid::simulate_batched<4>(model, u, thetas.leftCols(3));
  Eigen::VectorXd th = thetas.col(2), y(n);
  REQUIRE(model.simulate(u, std::span<const double>(th.data(), P), std::span<const double>(), std::span<double>(y.data(), n)));
  CHECK((y - y0.col(2)).cwiseAbs().maxCoeff() <= 1e-12 * scale);
  CHECK_THROWS_WITH(nlid::simulate_batched<4>(model, u, thetas, x0s.leftCols(2)),
                    Catch::Contains("x0s has 2 columns for 11 parameter sets"));
  CHECK_THROWS_WITH(nlid::simulate_batched<4>(model, u, thetas, x0s, 48), Catch::Contains("use 16, 32 or 64"));
  // What simulate_batched takes is checked at the call (a concept), not deep inside it.
  static_assert(nlid::BatchSimulatable<decltype(model), 8>);
  static_assert(!nlid::BatchSimulatable<Eigen::MatrixXd, 8>);
}

TEST_CASE("A batched model with run-time sizes stays on the build's own registers", "[core][batch][models]") {
  // Its values live in Eigen's heap blocks, aligned for the build's registers only, so wider
  // (dispatched) registers are refused for it rather than risked; the default just works.
  nlid::Nlarx<nlid::LaggedRegressors<nlid::Dynamic, nlid::Dynamic, nlid::Dynamic>, nlid::SigmoidNet<nlid::Dynamic, nlid::Dynamic>> model(
      nlid::LaggedRegressors<nlid::Dynamic, nlid::Dynamic, nlid::Dynamic>(2, 2, 0), nlid::SigmoidNet<nlid::Dynamic, nlid::Dynamic>(4, 3));
  const int P = model.num_parameters();
  const int n = 300;
  Eigen::MatrixXd u(n, 1);
  for (int t = 0; t < n; ++t) u(t, 0) = std::sin(0.03 * t);
  Eigen::MatrixXd thetas = Eigen::MatrixXd::Constant(P, 3, 0.05);
  thetas(0, 0) = 0.5;
  const Eigen::MatrixXd yb = nlid::simulate_batched<4>(model, u, thetas);
  Eigen::VectorXd th = thetas.col(0), y(n);
  REQUIRE(model.simulate(u, std::span<const double>(th.data(), static_cast<std::size_t>(P)), std::span<const double>(),
                         std::span<double>(y.data(), n)));
  CHECK((y - yb.col(0)).cwiseAbs().maxCoeff() <= 1e-12 * (1.0 + y.cwiseAbs().maxCoeff()));
  if (nlid::cpu_register_bytes() > nlid::default_register_bytes) {
    CHECK_THROWS_WITH(nlid::simulate_batched<4>(model, u, thetas, Eigen::MatrixXd(), nlid::cpu_register_bytes()),
                      Catch::Contains("a model with run-time sizes runs on this program's own"));
  }
}

TEST_CASE("Batched grey-box throttle (RK4) equals W single simulations", "[core][batch][greybox]") {
  constexpr int W = 4;
  using B = nlid::Batch<double, W>;
  StudyThrottle phys;
  nlid::IntegratorOptions opt;
  const int n = 800;
  const double ts = 0.01;
  const Eigen::MatrixXd u = throttle_square_wave(n, 150);  // drives into both stops
  const double p0[4] = {22.0, 110.0, 1.2e4, 9000.0};
  std::array<B, 4> pb;
  for (int j = 0; j < 4; ++j)
    for (int w = 0; w < W; ++w) pb[j][w] = p0[j] * (1.0 + 0.05 * w * (j % 2 == 0 ? 1 : -1));
  const int sub = 10;
  std::vector<std::vector<double>> single(W, std::vector<double>(n));
  double hit_upper = 0;
  for (int w = 0; w < W; ++w) {
    std::vector<double>& y = single[static_cast<std::size_t>(w)];
    REQUIRE(throttle_lane<W>(pb, w, opt, u, ts, sub,
                             [&](Eigen::Index k, const double* v) { y[static_cast<std::size_t>(k)] = v[0]; }) == n);
    for (double v : y) hit_upper = std::max(hit_upper, v);
  }
  CHECK(hit_upper > 90.0);  // the contact term is exercised
  // On the build's registers, then on every width the CPU has (with_register_bytes).
  std::vector<std::array<double, W>> yb(n);
  std::array<B, 2> xb{B(20.0), B(0.0)};
  REQUIRE(nlid::simulate_physics<B>(phys, opt, sub, u, ts, pb.data(), xb.data(),
                                    [&](Eigen::Index k, const B* y) { y[0].store(yb[static_cast<std::size_t>(k)].data()); }) == n);
  const auto worst_against_single = [&] {
    double worst = 0;
    for (int w = 0; w < W; ++w)
      for (int t = 0; t < n; ++t)
        worst = std::max(worst, std::abs(single[static_cast<std::size_t>(w)][static_cast<std::size_t>(t)] -
                                         yb[static_cast<std::size_t>(t)][static_cast<std::size_t>(w)]));
    return worst;
  };
  CHECK(worst_against_single() <= 1e-12 * 100.0);
  for (std::size_t r : register_widths()) {
    INFO("registers of " << r << " bytes");
    const Eigen::Index steps = throttle_on_registers<W>(
        r, pb, opt, u, ts, sub, [&](Eigen::Index k, const auto& y) { y.store(yb[static_cast<std::size_t>(k)].data()); });
    REQUIRE(steps == n);
    CHECK(worst_against_single() <= 1e-12 * 100.0);
  }
}

TEST_CASE("A batched RK4 simulation stops where its first lane diverges, as that lane alone does",
          "[core][batch][greybox]") {
  // One lane's stop stiffness puts h·ρ far outside RK4's stability region (one sub-step), so
  // that lane blows up to ±∞/NaN; the finiteness test of every sub-step must see it although
  // the other lanes stay finite.
  constexpr int W = 4;
  using B = nlid::Batch<double, W>;
  StudyThrottle phys;
  nlid::IntegratorOptions opt;
  const int n = 600;
  const double ts = 0.01;
  const Eigen::MatrixXd u = throttle_square_wave(n, 100);
  const double p0[4] = {22.0, 110.0, 1.2e4, 9000.0};
  std::array<B, 4> pb;
  for (int j = 0; j < 4; ++j) pb[j] = B(p0[j]);
  pb[2][2] = 1e7;  // lane 2 only
  const int sub = 1;
  auto single = [&](int w) { return throttle_lane<W>(pb, w, opt, u, ts, sub, [](Eigen::Index, const double*) {}); };
  const Eigen::Index bad = single(2);
  REQUIRE(bad < n);
  for (int w : {0, 1, 3}) REQUIRE(single(w) == n);
  std::array<B, 2> xb{B(20.0), B(0.0)};
  const Eigen::Index got =
      nlid::simulate_physics<B>(phys, opt, sub, u, ts, pb.data(), xb.data(), [](Eigen::Index, const B*) {});
  CHECK(got == bad);
  for (std::size_t r : register_widths()) {  // the same on every register width
    INFO("registers of " << r << " bytes");
    CHECK(throttle_on_registers<W>(r, pb, opt, u, ts, sub, [](Eigen::Index, const auto&) {}) == bad);
  }
}
