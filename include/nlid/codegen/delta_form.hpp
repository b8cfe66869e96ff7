#pragma once
/// @file
/// Linear blocks of single-precision C in *delta-operator* form (Middleton & Goodwin, "Digital
/// Control and Estimation: A Unified Approach", 1990, ch. 2–3): why and how.
///
/// A block B̃(q)/F(q) with poles close to z = 1 (slow dynamics, fast sampling) is badly
/// conditioned in its polynomial form: its static gain B(1)/F(1) depends on F(1) = 1 + f₁ + … +
/// f_n, a small difference of O(1) coefficients, and rounding the fᵢ to float (relative 6·10⁻⁸)
/// moves F(1) by about 10⁻⁷ absolute — percent of the gain when F(1) ~ 10⁻⁵.
///
/// With δ = q − 1 the same transfer function, written over n = max(nf, nk + nb − 1) states, is
///
///     B̃(z)/F(z) = (c₀ δⁿ + c₁ δⁿ⁻¹ + … + cₙ) / (δⁿ + a₁ δⁿ⁻¹ + … + aₙ),   z = 1 + δ,
///
/// whose coefficients are the Taylor coefficients of zⁿB̃ and zⁿF about z = 1 (computed in
/// double at generation time): aₙ = F(1), cₙ = B(1), a₁ = n + f₁ … — small quantities are now
/// coefficients of their own and keep float's full relative precision. The realization is the
/// observer canonical form in δ, the transposed direct form II with q⁻¹ replaced by δ⁻¹:
///
///     y(t)      = c₀ w(t) + e₁(t),
///     eᵢ(t+1)   = eᵢ(t) + (eᵢ₊₁(t) + cᵢ w(t) − aᵢ y(t)),   i = 1 … n   (eₙ₊₁ ≡ 0).
///
/// State. nlid's TDF-II state s and the δ state e describe the same free response when the
/// polynomial s₁zⁿ⁻¹ + … + sₙ written in powers of δ = z − 1 has the coefficients e₁ … eₙ:
/// e = T s with T the Taylor shift (lower triangular, eᵢ = Σ_{j ≤ i} C(n − j, i − j) sⱼ; e₁ = s₁,
/// eₙ = s₁ + … + sₙ). NAME_x0 is T applied to nlid's state in double, rounded once.
///
/// Input delay. The δ form covers only the h = nf states that carry feedback. When the numerator
/// reaches further (nk + nb − 1 > nf: an input delay, or a long numerator), the TDF-II registers
/// s_{h+1} … s_n only shift the input, s_i(t+1) = s_{i+1}(t) + βᵢ w(t), and stay as they are;
/// s_{h+1} enters e_h's update as the e_{h+1} of the recursion above. Writing them in δ too
/// would fold the delay's n − h poles at z = 0 into a degree-n polynomial in δ whose binomial
/// coefficients (C(26, 13) ≈ 10⁷ for nk = 25) cancel in float: the generated step diverged for
/// an ARX model with nk = 25. With the split the state keeps its n values: e = T s on the first
/// h, sᵢ above.
///
/// Blocks with nf = 0 (FIR: no feedback, no sensitivity to rounding) and blocks without state
/// stay in the direct form.
///
/// Several inputs over one denominator (ARX: A(q) y = Σᵢ Bᵢ(q) uᵢ(t − nkᵢ) + c) make one δ block
/// `MultiInputDeltaBlock` with one numerator per input — cᵢ,ₖ the Taylor coefficients of zⁿB̃ᵢ —
/// and the same recursion with Σᵢ cᵢ,ₖ wᵢ(t) in place of cₖ w(t). A constant c is an input held
/// at 1 with B̃ = c (no delay): its coefficients c·C(n, k) become constants of the update.

#include <algorithm>
#include <cstddef>
#include <cstdio>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "nlid/codegen/trace_scalar.hpp"
#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"

namespace nlid::codegen {

/// How a linear block of a Hammerstein–Wiener or series model is written in the generated C.
///  - `automatic`: `delta` in single precision, `direct` in double precision;
///  - `direct`: nlid's transposed direct form II on the polynomial coefficients (in double
///    precision nlid's own operations, bit for bit);
///  - `delta`: delta-operator form (delta_form.hpp); single precision only — in double the direct
///    form already reproduces nlid to the last bit, so asking for delta there is an error.
enum class LinearForm { automatic, direct, delta };

/// Taylor coefficients about z = 1: for P(z) = Σₖ p[k] z^(m−k) (highest power first) returns q
/// with P(1 + δ) = Σₖ q[k] δ^(m−k). Repeated synthetic division by (z − 1) (Horner), in double.
inline std::vector<double> taylor_shift_at_one(std::vector<double> p) {
  const std::size_t m = p.empty() ? 0 : p.size() - 1;
  for (std::size_t pass = 0; pass < m; ++pass)
    for (std::size_t k = 1; k <= m - pass; ++k) p[k] += p[k - 1];
  return p;
}

namespace detail {

// v's first n + 1 entries, padded with zeros (coefficients of q⁻ʲ, j = 0 … n).
inline std::vector<double> padded_coefficients(const Eigen::VectorXd& v, int n) {
  std::vector<double> p(static_cast<std::size_t>(n) + 1, 0.0);
  for (Eigen::Index j = 0; j < v.size() && j <= n; ++j) p[static_cast<std::size_t>(j)] = v(j);
  return p;
}

// δ state of an n-state TDF-II state s whose first h states carry the feedback (file comment):
// e = T s on those, the registers above them as they are; in double.
inline Eigen::VectorXd delta_state_from_tdf2(int n, int h, const Eigen::VectorXd& s) {
  require(s.size() == n, "codegen: a linear block state has " + std::to_string(s.size()) + " values, expected " +
                             std::to_string(n),
          at_parameter("x0"));
  Eigen::VectorXd e = s;
  const std::vector<double> head = taylor_shift_at_one(std::vector<double>(s.data(), s.data() + h));
  for (int i = 0; i < h; ++i) e(i) = head[static_cast<std::size_t>(i)];
  return e;
}

// "[v[first] … v[last]]" with 9 significant digits (the float values in the code).
inline std::string coefficient_list(const std::vector<double>& v, std::size_t first) {
  std::string s = "[";
  for (std::size_t i = first; i < v.size(); ++i) s += (i > first ? " " : "") + nlid::detail::format_g(v[i], 9);
  return s + "]";
}

// β's coefficients h + 1 … n (of q⁻ʲ), zero-padded: the numerator's part in the registers
// without feedback.
inline std::vector<double> tail_coefficients(const Eigen::VectorXd& beta, int h, int n) {
  std::vector<double> t(static_cast<std::size_t>(n - h), 0.0);
  for (int j = h + 1; j <= n && j < beta.size(); ++j) t[static_cast<std::size_t>(j - h - 1)] = beta(j);
  return t;
}

// The states that carry feedback: F's degree (the registers above it only shift the input).
inline int feedback_states(const Eigen::VectorXd& f, int n) {
  return std::min(n, static_cast<int>(f.size()) - 1);
}

// One traced sample of the δ block with numerators c[j] (one per input w[j]) over a, on h of the
// n states, and the registers h + 1 … n without feedback (numerator tails `tail[j]`): returns
// y(t) and advances the n-value state e. Exact zeros are left out.
inline TraceScalar delta_step(int n, int h, std::span<const std::vector<double>> c, const std::vector<double>& a,
                              std::span<const std::vector<double>> tail, std::span<TraceScalar> e,
                              std::span<const TraceScalar> w) {
  const auto term = [&](double coef, const TraceScalar& v) { return TraceScalar(coef) * v; };
  TraceScalar y = e[0];
  for (std::size_t j = 0; j < c.size(); ++j)
    if (c[j][0] != 0.0) y = y + term(c[j][0], w[j]);
  const std::vector<TraceScalar> old(e.begin(), e.end());
  // e_h's update takes e_(h+1): the first register above, or nothing when h = n.
  for (int i = 1; i <= h; ++i) {
    const auto ui = static_cast<std::size_t>(i);
    TraceScalar inc = i < n ? old[ui] : TraceScalar(0.0);
    bool any = i < n;
    for (std::size_t j = 0; j < c.size(); ++j) {
      if (c[j][ui] == 0.0) continue;
      inc = any ? inc + term(c[j][ui], w[j]) : term(c[j][ui], w[j]);
      any = true;
    }
    if (a[ui] != 0.0) {
      inc = any ? inc - term(a[ui], y) : term(-a[ui], y);
      any = true;
    }
    e[ui - 1] = any ? old[ui - 1] + inc : old[ui - 1];
  }
  // Above h the transposed direct form as it is: a shift register (the input delay) with the
  // numerator's tail added; no feedback, so nothing for float to lose.
  for (int i = h + 1; i <= n; ++i) {
    const auto ui = static_cast<std::size_t>(i);
    TraceScalar v = i < n ? old[ui] : TraceScalar(0.0);
    bool any = i < n;
    for (std::size_t j = 0; j < tail.size(); ++j) {
      const double b = tail[j][ui - static_cast<std::size_t>(h) - 1];
      if (b == 0.0) continue;
      v = any ? v + term(b, w[j]) : term(b, w[j]);
      any = true;
    }
    e[ui - 1] = v;
  }
  return y;
}

// "; e_(h+1) .. e_n ..." (nothing when h = n): how the registers above the δ part work.
inline std::string tail_description(int n, int h, const std::vector<std::vector<double>>& tail,
                                    const std::vector<std::string>& names) {
  if (h >= n) return "";
  std::string s = "; the delta recursion above holds for e_1 .. e_" + std::to_string(h) + " (n = " +
                  std::to_string(h) + ", F's degree), and e_" + std::to_string(h + 1) + " .. e_" + std::to_string(n) +
                  " are the input delay's registers s_" + std::to_string(h + 1) + " .. s_" + std::to_string(n) +
                  " of the transposed direct form, as they are: e_i(t+1) = e_(i+1)(t) + b_i*w(t), e_" +
                  std::to_string(n + 1) + " = 0";
  for (std::size_t j = 0; j < tail.size(); ++j)
    s += ", " + (j < names.size() ? names[j] + " " : std::string()) + "b_" + std::to_string(h + 1) + " .. b_" +
         std::to_string(n) + " = " + coefficient_list(tail[j], 0);
  return s;
}

}  // namespace detail

/// One linear block in delta form: c[0 … h] (numerator) and a[0 … h] (a[0] = 1) as above, on
/// the first h of its n states; the registers h + 1 … n hold the input delay (file comment).
struct DeltaBlock {
  int n = 0;              ///< states
  int h = 0;              ///< states in δ form: F's degree (the rest are delay registers)
  std::vector<double> c;  ///< numerator coefficients in δ, c[0] = β₀, c[h]
  std::vector<double> a;  ///< denominator coefficients in δ, a[0] = 1, a[h] = F(1)
  std::vector<double> tail;  ///< β's coefficients h + 1 … n, added to the delay registers

  /// δ-form coefficients of the TDF-II block with numerator β₀ … βₙ (coefficients of q⁻ʲ of B̃,
  /// delay included) and monic denominator f₀ = 1, f₁ … f_h, over n states.
  static DeltaBlock from_tdf2(const Eigen::VectorXd& beta, const Eigen::VectorXd& f, int n) {
    DeltaBlock d;
    d.n = n;
    d.h = detail::feedback_states(f, n);
    d.c = taylor_shift_at_one(detail::padded_coefficients(beta, d.h));
    d.a = taylor_shift_at_one(detail::padded_coefficients(f, d.h));
    d.tail = detail::tail_coefficients(beta, d.h, n);
    return d;
  }

  /// δ state of nlid's TDF-II state s (n values), in double: T s on the first h, the rest as is.
  [[nodiscard]] Eigen::VectorXd state_from_tdf2(const Eigen::VectorXd& s) const {
    return detail::delta_state_from_tdf2(n, h, s);
  }

  /// "c0 .. ch = [...], a1 .. ah = [...]" (9 significant digits: the float values in the code),
  /// and the delay registers' rule when h < n.
  [[nodiscard]] std::string describe() const {
    return "c0 .. c" + std::to_string(h) + " = " + detail::coefficient_list(c, 0) + ", a1 .. a" + std::to_string(h) +
           " = " + detail::coefficient_list(a, 1) + detail::tail_description(n, h, {tail}, {});
  }

  /// One traced sample: returns y(t) for input w(t) and advances the state `e` (n values).
  /// The coefficients are literals of the code (rounded once to its precision); exact zeros are
  /// left out.
  [[nodiscard]] TraceScalar step(std::span<TraceScalar> e, const TraceScalar& w) const {
    return detail::delta_step(n, h, std::span<const std::vector<double>>(&c, 1), a,
                              std::span<const std::vector<double>>(&tail, 1), e, std::span<const TraceScalar>(&w, 1));
  }
};

/// One δ block for several inputs sharing the denominator (file comment): c[i][0 … h] for input
/// i, a[0 … h] (a[0] = 1). The δ state is the Taylor shift of the multi-input TDF-II state's
/// first h values, as for `DeltaBlock`; above them the delay registers.
struct MultiInputDeltaBlock {
  int n = 0;                            ///< states
  int h = 0;                            ///< states in δ form: A's degree
  std::vector<std::vector<double>> c;   ///< numerator coefficients in δ, one vector per input
  std::vector<double> a;                ///< denominator coefficients in δ, a[0] = 1, a[h] = F(1)
  std::vector<std::vector<double>> tail;  ///< per input: β's coefficients h + 1 … n

  /// δ-form coefficients of the TDF-II block with numerators beta[i] (coefficients of q⁻ʲ of
  /// B̃ᵢ, delay included) and monic denominator f, over n states.
  static MultiInputDeltaBlock from_tdf2(const std::vector<Eigen::VectorXd>& beta, const Eigen::VectorXd& f, int n) {
    MultiInputDeltaBlock d;
    d.n = n;
    d.h = detail::feedback_states(f, n);
    for (const Eigen::VectorXd& b : beta) {
      d.c.push_back(taylor_shift_at_one(detail::padded_coefficients(b, d.h)));
      d.tail.push_back(detail::tail_coefficients(b, d.h, n));
    }
    d.a = taylor_shift_at_one(detail::padded_coefficients(f, d.h));
    return d;
  }

  /// δ state of the TDF-II state s (n values), in double.
  [[nodiscard]] Eigen::VectorXd state_from_tdf2(const Eigen::VectorXd& s) const {
    return detail::delta_state_from_tdf2(n, h, s);
  }

  /// "cI_0 .. cI_h = [...] (one list per input, named by `names`), a1 .. ah = [...]", and the
  /// delay registers' rule when h < n.
  [[nodiscard]] std::string describe(const std::vector<std::string>& names) const {
    std::string s;
    for (std::size_t i = 0; i < c.size(); ++i)
      s += (i < names.size() ? names[i] : "c" + std::to_string(i + 1)) + "_0 .. _" + std::to_string(h) + " = " +
           detail::coefficient_list(c[i], 0) + ", ";
    return s + "a1 .. a" + std::to_string(h) + " = " + detail::coefficient_list(a, 1) +
           detail::tail_description(n, h, tail, names);
  }

  /// One traced sample: returns y(t) for inputs w(t) (one per numerator; a literal 1 for a
  /// constant) and advances the state `e` (n values). Exact zeros are left out.
  [[nodiscard]] TraceScalar step(std::span<TraceScalar> e, std::span<const TraceScalar> w) const {
    require(w.size() == c.size(), "codegen: a multi-input delta block got " + std::to_string(w.size()) +
                                      " inputs, expected " + std::to_string(c.size()),
            at_parameter("w"));
    return detail::delta_step(n, h, c, a, tail, e, w);
  }
};

/// The δ form of a `TransferFunctionBlock` (anything with nb(), nf(), nk(), num_states_runtime()
/// and polynomials(θ)) with parameters θ.
template <class Block>
DeltaBlock delta_block(const Block& block, std::span<const double> theta) {
  const auto [b, f] = block.polynomials(theta);  // B̃ with the nk leading zeros, monic F
  return DeltaBlock::from_tdf2(b, f, block.num_states_runtime());
}

/// True if a block with these orders is written in δ form when δ is in use (it has a state and
/// feedback).
template <class Block>
bool delta_applies(const Block& block) {
  return block.nf() > 0 && block.num_states_runtime() > 0;
}

}  // namespace nlid::codegen
