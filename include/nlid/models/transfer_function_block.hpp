#pragma once
/// @file
/// `TransferFunctionBlock<Nb, Nf, Nk>`: the linear block x = B(q)/F(q) w(t−nk) of a
/// Hammerstein–Wiener model, stepped one sample at a time on any scalar.
///
/// Math (Ljung 1999, eq. 4.24, the output-error structure; toolbox idnlhw "[nb nf nk]"):
///
///     F(q) x(t) = B(q) w(t − nk),
///     B(q) = b₁ + b₂ q⁻¹ + … + b_nb q⁻⁽ⁿᵇ⁻¹⁾,   F(q) = 1 + f₁ q⁻¹ + … + f_nf q⁻ⁿᶠ,
///
/// with parameters θ = [b₁ … b_nb, f₁ … f_nf]. In the toolbox's polynomial convention the
/// numerator including the delay is B̃(q) = q⁻ⁿᵏ B(q) = [0 … 0 b₁ … b_nb] (nk leading zeros);
/// `polynomials()` returns that form, so numbers can be compared with an `OutputError` model.
///
/// State. The block is run in *transposed direct form II* (observer canonical form): with
/// β_j the coefficient of q⁻ʲ in B̃ and n = max(nf, nk + nb − 1) states,
///
///     x(t)      = β₀ w(t) + s₁(t),
///     s_i(t+1)  = s_{i+1}(t) + β_i w(t) − f_i x(t),   i = 1 … n   (s_{n+1} ≡ 0).
///
/// This is a *minimal* state (n numbers, not the nf + nb + nk past samples a difference-equation
/// buffer would hold), which matters when the initial state is estimated as extra parameters: a
/// non-minimal state would make the Jacobian rank-deficient. s = 0 is the block at rest; the
/// steady state for a constant w₀ is s_i = Σ_{j ≥ i} (β_j w₀ − f_j x₀), x₀ = B(1)/F(1) w₀.
///
/// Sizes: each of Nb, Nf, Nk is compile-time or `Dynamic` (the Dynamic twin, orders from the
/// constructor). With static orders the state lives in a fixed-size Eigen vector: stepping
/// allocates nothing.

#include <algorithm>
#include <cmath>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "nlid/ad/dual.hpp"
#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/core/sizes.hpp"
#include "nlid/linear/polynomial.hpp"

namespace nlid {

/// Linear block x = B(q)/F(q) w(t−nk), θ = [b₁ … b_nb, f₁ … f_nf]; orders static or `Dynamic`.
/// Invariant: nb ≥ 1, nf ≥ 0, nk ≥ 0.
template <int Nb, int Nf, int Nk>
  requires(Nb == Dynamic || Nb >= 1) && (Nf == Dynamic || Nf >= 0) && (Nk == Dynamic || Nk >= 0)
class TransferFunctionBlock {
 public:
  /// p = nb + nf.
  static constexpr int num_params = size_sum(Nb, Nf);
  /// n = max(nf, nk + nb − 1).
  static constexpr int num_states =
      (Nb == Dynamic || Nf == Dynamic || Nk == Dynamic) ? Dynamic : std::max(Nf, Nk + Nb - 1);
  /// State vector type for scalar T (fixed size when the orders are static).
  template <class T>
  using State = Eigen::Matrix<T, num_states, 1>;

  /// Compile-time orders.
  TransferFunctionBlock() requires(Nb != Dynamic && Nf != Dynamic && Nk != Dynamic) = default;
  /// Run-time orders (each must equal its template value unless that is Dynamic).
  TransferFunctionBlock(int nb, int nf, int nk)
      : nb_(checked(nb, Nb, 1, "nb")), nf_(checked(nf, Nf, 0, "nf")), nk_(checked(nk, Nk, 0, "nk")) {}

  /// Number of numerator coefficients.
  [[nodiscard]] int nb() const { return nb_; }
  /// Number of denominator coefficients (F is monic).
  [[nodiscard]] int nf() const { return nf_; }
  /// Input delay in samples.
  [[nodiscard]] int nk() const { return nk_; }
  /// p = nb + nf.
  [[nodiscard]] int num_parameters() const { return nb_ + nf_; }
  /// n = max(nf, nk + nb − 1).
  [[nodiscard]] int num_states_runtime() const { return std::max(nf_, nk_ + nb_ - 1); }

  /// One sample: returns x(t) for input w(t) and advances the state `s` (size n) to t + 1.
  template <class T>
  T step(std::span<T> s, const T& w, std::span<const T> theta) const {
    const int n = num_states_runtime();
    T x = n > 0 ? s[0] : T(0);
    if (nk_ == 0) x += theta[0] * w;
    for (int i = 1; i <= n; ++i) {
      T next = i < n ? s[static_cast<std::size_t>(i)] : T(0);
      const int bi = i - nk_;  // β_i = b_{bi+1}
      if (bi >= 0 && bi < nb_) next += theta[static_cast<std::size_t>(bi)] * w;
      if (i <= nf_) next -= theta[static_cast<std::size_t>(nb_ + i - 1)] * x;
      s[static_cast<std::size_t>(i - 1)] = next;
    }
    return x;
  }

  /// Runs the block over a whole sequence: x(t) for w(t), t = 0 … N−1, from state `s0`
  /// (empty: at rest).
  template <class T>
  void simulate(std::span<const T> w, std::span<const T> theta, std::span<const T> s0,
                std::span<T> x) const {
    State<T> s = zero_state<T>();
    if (!s0.empty()) {
      require(static_cast<int>(s0.size()) == num_states_runtime(),
              "initial state has " + std::to_string(s0.size()) + " values, the block has " +
                  std::to_string(num_states_runtime()) + " states",
              at_parameter("s0"));
      for (int i = 0; i < s.size(); ++i) s(i) = s0[static_cast<std::size_t>(i)];
    }
    const std::span<T> ss(s.data(), static_cast<std::size_t>(s.size()));
    for (std::size_t t = 0; t < w.size(); ++t) x[t] = step(ss, w[t], theta);
  }

  /// A zero state of the right size (fixed-size: on the stack).
  template <class T>
  [[nodiscard]] State<T> zero_state() const {
    if constexpr (num_states == Dynamic) {
      return State<T>::Constant(num_states_runtime(), T(0));
    } else {
      return State<T>::Constant(T(0));
    }
  }

  /// Static gain B(1)/F(1).
  template <class T>
  [[nodiscard]] T dc_gain(std::span<const T> theta) const {
    T num(0), den(1);
    for (int i = 0; i < nb_; ++i) num += theta[static_cast<std::size_t>(i)];
    for (int i = 0; i < nf_; ++i) den += theta[static_cast<std::size_t>(nb_ + i)];
    return num / den;
  }

  /// Writes into `s` the steady state for the constant input w0. Returns false (and leaves `s`
  /// untouched) if F(1) = 0: an integrator has no steady state for w0 ≠ 0.
  template <class T>
  bool equilibrium_state(const T& w0, std::span<const T> theta, std::span<T> s) const {
    T den(1);
    for (int i = 0; i < nf_; ++i) den += theta[static_cast<std::size_t>(nb_ + i)];
    using std::abs;
    if (abs(value_of(den)) < 1e-12) return false;
    const T x0 = dc_gain(theta) * w0;
    const int n = num_states_runtime();
    T acc(0);
    for (int i = n; i >= 1; --i) {
      const int bi = i - nk_;
      if (bi >= 0 && bi < nb_) acc += theta[static_cast<std::size_t>(bi)] * w0;
      if (i <= nf_) acc -= theta[static_cast<std::size_t>(nb_ + i - 1)] * x0;
      s[static_cast<std::size_t>(i - 1)] = acc;
    }
    return true;
  }

  /// The toolbox polynomials: B̃ = [0 … 0 b₁ … b_nb] (nk leading zeros) and F = [1 f₁ … f_nf].
  [[nodiscard]] std::pair<Eigen::VectorXd, Eigen::VectorXd> polynomials(
      std::span<const double> theta) const {
    check_theta(theta.size());
    Eigen::VectorXd b = Eigen::VectorXd::Zero(nk_ + nb_);
    Eigen::VectorXd f(nf_ + 1);
    f(0) = 1.0;
    for (int i = 0; i < nb_; ++i) b(nk_ + i) = theta[static_cast<std::size_t>(i)];
    for (int i = 0; i < nf_; ++i) f(i + 1) = theta[static_cast<std::size_t>(nb_ + i)];
    return {b, f};
  }

  /// θ from toolbox polynomials: `b` either with the nk leading zeros (length nk + nb) or
  /// without (length nb); `f` monic of length nf + 1. This is how a previously estimated
  /// `OutputError` model initialises the linear part. Throws `nlid::Error` naming "B" or "F".
  void set_from_polynomials(const Eigen::VectorXd& b, const Eigen::VectorXd& f,
                            std::span<double> theta) const {
    check_theta(theta.size());
    const Eigen::Index nb = nb_, nf = nf_, nk = nk_;
    require(b.size() == nk + nb || b.size() == nb,
            "B has " + std::to_string(b.size()) + " coefficients; the block needs nb = " +
                std::to_string(nb) + " (or nk + nb = " + std::to_string(nk + nb) +
                " with the delay's leading zeros)",
            at_parameter("B"));
    if (b.size() == nk + nb && nk > 0) {
      require(b.head(nk).cwiseAbs().maxCoeff() == 0.0,
              "B's first nk = " + std::to_string(nk) + " coefficients must be zero (the input delay)",
              at_parameter("B"));
    }
    require(f.size() == nf + 1, "F has " + std::to_string(f.size()) + " coefficients; the block needs nf + 1 = " +
                                    std::to_string(nf + 1),
            at_parameter("F"));
    require(f(0) == 1.0, "F must be monic (F(0) = 1), got " + detail::format_f(f(0), 6), at_parameter("F"));
    // A NaN here would surface much later as a "diverging" simulation or an unwritable file.
    require(b.allFinite(), "B has a non-finite coefficient", at_parameter("B"));
    require(f.allFinite(), "F has a non-finite coefficient", at_parameter("F"));
    const Eigen::VectorXd bt = b.tail(nb);
    for (Eigen::Index i = 0; i < nb; ++i) theta[static_cast<std::size_t>(i)] = bt(i);
    for (Eigen::Index i = 0; i < nf; ++i) theta[static_cast<std::size_t>(nb + i)] = f(i + 1);
  }

  /// The unit of each parameter when w is measured in units of size `in` and x in units of size
  /// `out`: out/in for the b's, 1 for the f's (estimation uses them to damp steps alike whatever
  /// units the data are in).
  bool parameter_scales(double in, double out, std::span<double> s) const {
    for (int i = 0; i < nb_; ++i) s[static_cast<std::size_t>(i)] = out / in;
    for (int i = 0; i < nf_; ++i) s[static_cast<std::size_t>(nb_ + i)] = 1.0;
    return true;
  }

  /// "b1" … "b<nb>", "f1" … "f<nf>".
  [[nodiscard]] std::vector<std::string> parameter_names() const {
    std::vector<std::string> n;
    for (int i = 1; i <= nb_; ++i) n.push_back("b" + std::to_string(i));
    for (int i = 1; i <= nf_; ++i) n.push_back("f" + std::to_string(i));
    return n;
  }

  /// "B(q) = …  F(q) = …" with poles and static gain, as the toolbox displays the linear block.
  [[nodiscard]] std::string describe(std::span<const double> theta) const {
    const auto [b, f] = polynomials(theta);
    std::string s = "linear block [nb nf nk] = [" + std::to_string(nb_) + " " + std::to_string(nf_) +
                    " " + std::to_string(nk_) + "]: x(t) = B(q)/F(q) w(t)\n";
    s += "  B(q) = " + format_polynomial(b) + "\n";
    s += "  F(q) = " + format_polynomial(f) + "\n";
    if (nf_ > 0) s += "  poles: " + describe_roots(f) + "\n";  // not factored past max_described_root_degree
    const double den = f.sum();
    s += "  static gain B(1)/F(1) = " + (std::abs(den) > 1e-12 ? format_number(b.sum() / den) : std::string("inf")) + "\n";
    return s;
  }

  // ---- Implementation details below ----------------------------------------------------------
 private:
  static int checked(int v, int compile_time, int min, const char* name) {
    require(v >= min, std::string("linear block order ") + name + " must be >= " + std::to_string(min) +
                          ", got " + std::to_string(v),
            at_parameter(name));
    require(v <= max_model_order,
            std::string("linear block order ") + name + " must be <= " + std::to_string(max_model_order) +
                " (the largest model order), got " + std::to_string(v),
            at_parameter(name));
    require(compile_time == Dynamic || v == compile_time,
            std::string("linear block order ") + name + " = " + std::to_string(v) +
                " differs from its compile-time value " + std::to_string(compile_time),
            at_parameter(name));
    return v;
  }
  void check_theta(std::size_t n) const {
    require(static_cast<int>(n) == num_parameters(),
            "linear block parameter vector has " + std::to_string(n) + " values, expected nb + nf = " +
                std::to_string(num_parameters()),
            at_parameter("theta"));
  }

  int nb_ = Nb;
  int nf_ = Nf;
  int nk_ = Nk;
};

}  // namespace nlid
