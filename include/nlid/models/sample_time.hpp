#pragma once
/// @file
/// Changing a model's sample time: exact zero-order-hold conversion of linear dynamics
/// (d2c / c2d by the matrix exponential and logarithm) and rescaling of input delays nk.
///
/// Math (Åström & Wittenmark, "Computer-Controlled Systems", 3rd ed. 1997, sec. 2.3; Franklin,
/// Powell & Workman, "Digital Control of Dynamic Systems", 1998, sec. 4.3.3). A continuous system
/// ẋ = A x + B u, y = C x + D u whose input is held constant over each sample interval h (zero-order
/// hold) is exactly the discrete system
///
///     x(k+1) = Φ x(k) + Γ u(k),   [Φ Γ; 0 I] = exp([A B; 0 0] h),     C, D unchanged.
///
/// `c2d` evaluates that exponential; `d2c` inverts it with the principal matrix logarithm
/// [A B; 0 0] = log([Φ Γ; 0 I]) / h, which exists (real) when Φ has no eigenvalue on the closed
/// negative real axis — a discrete pole at z ≤ 0 has no continuous-time ZOH equivalent and is
/// reported as an error. `with_sample_time` chains both: the new model is the exact ZOH
/// discretisation, at the new sample time, of the continuous system the old one came from.
///
/// Delays. A plant without direct feed-through (strictly proper), sampled with a zero-order hold,
/// answers one sample late: q⁻¹ is part of its sampled transfer function, not a dead time (Åström
/// & Wittenmark sec. 2.3). So a model q⁻ⁿᵏ B(q)/F(q) with nk ≥ 1 is read as the sampled plant
/// q⁻¹B/F — converted exactly, as the toolbox's d2d does with B's leading zeros — behind a dead
/// time of (nk − 1)·h seconds, which becomes nk' − 1 = round((nk − 1)·h/h') samples (a warning
/// says when that is not a whole number). With nk = 0, B/F has direct feed-through and no dead time.
/// (Before 2026-11-29 B/F was converted as having feed-through and nk·h was taken as dead time:
/// a first-order plant sampled with nk = 1 came back at half the sample time with nk' = 2 and a
/// feed-through — an extra half sample of delay on every input that moves between the old
/// instants.) When nb > nf and nk ≥ 1, q⁻¹B/F has poles at z = 0: its extra numerator terms stand
/// for a fraction of a sample of dead time, which no rational ZOH model converts. That input is
/// then converted the old way and marked inexact, with a warning.
///
/// The study ends with the caution this conversion needs: the smallest delay (nk = 1, or nk = 0 for
/// feed-through) states only that the dead time is less than one *old* sample. At a shorter sample
/// time it may well be one or more samples, so such a model converted to a faster rate keeps its nk
/// *with a warning*: estimate the delay again on data at the new rate (e.g. an ARX order search
/// over nk) rather than trusting it.
///
/// Which models convert how:
/// - StateSpace, OutputError, the deterministic part B/A of Arx, and the linear block of a
///   Hammerstein–Wiener model: exactly (static nonlinearities do not depend on the sample time);
/// - nonlinear ARX: its regressors are samples of a difference equation at the old rate. The
///   structure is converted (nk rescaled; lags in samples kept) and θ is kept as a starting point,
///   but the result is marked inexact: re-estimate it on data at the new rate
///   (data/resample.hpp resamples the data).

#include <cmath>
#include <complex>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <unsupported/Eigen/MatrixFunctions>

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/linear/arx.hpp"
#include "nlid/linear/output_error.hpp"
#include "nlid/linear/polynomial.hpp"
#include "nlid/linear/state_space.hpp"
#include "nlid/models/any_model.hpp"
#include "nlid/models/hammerstein_wiener.hpp"
#include "nlid/models/nlarx.hpp"
#include "nlid/models/transfer_function_block.hpp"
#include "nlid/regressors/expression.hpp"

namespace nlid {

/// A continuous-time state-space model ẋ = A x + B u, y = C x + D u.
struct ContinuousStateSpace {
  Eigen::MatrixXd a;  ///< A (n × n)
  Eigen::MatrixXd b;  ///< B (n × nu)
  Eigen::MatrixXd c;  ///< C (ny × n)
  Eigen::MatrixXd d;  ///< D (ny × nu)
};

/// What a sample-time change did.
struct SampleTimeReport {
  double old_ts = 0.0;                ///< sample time before (s)
  double new_ts = 0.0;                ///< sample time after (s)
  bool exact = true;                  ///< false: the result only approximates the old model
  std::vector<std::string> warnings;  ///< one sentence each (nk = 0, rounded delays, re-estimate)
};

namespace detail {

inline void check_new_ts(double ts) {
  require(ts > 0 && std::isfinite(ts), "new sample time must be positive and finite, got " + detail::format_f(ts, 6),
          at_parameter("ts"));
}

inline std::string fmt_seconds(double s) { return format_g(s, 6) + " s"; }

}  // namespace detail

namespace detail {

/// A dead time of `d` old samples in new samples, round(d·old_ts/new_ts), with the warnings of the
/// file comment; `base` is what nk adds to d (1 for a sampled plant without feed-through, 0 with).
inline int rescale_dead_time(int d, double old_ts, double new_ts, SampleTimeReport* report, const std::string& what,
                             int base) {
  check_new_ts(new_ts);
  require(old_ts > 0, "the model has no sample time to convert from", at_parameter("ts"));
  const double exact = d * old_ts / new_ts;
  const int out = static_cast<int>(std::lround(exact));
  if (report != nullptr) {
    const std::string nk = std::to_string(d + base);
    if (d == 0) {
      report->warnings.push_back(
          what + " = " + nk +
          (base == 0 ? ": the input acts within one sample of " + fmt_seconds(old_ts)
                     : ": beyond the one sample that sampling itself takes, the input acts within one sample of " +
                           fmt_seconds(old_ts)) +
          "; the true dead time lies somewhere in [0, " + fmt_seconds(old_ts) + ")" +
          (new_ts < old_ts ? " and may be one or more samples at " + fmt_seconds(new_ts) + "; nk = " + nk +
                                 " was kept - estimate the delay again on data at the new rate"
                           : "; nk = " + nk + " was kept"));
    } else if (std::abs(exact - out) > 1e-9 * std::max(1.0, exact)) {
      report->warnings.push_back(what + " = " + nk + " (" + fmt_seconds(d * old_ts) + " of dead time" +
                                 ") is not a whole number of samples of " + fmt_seconds(new_ts) + "; rounded to " +
                                 std::to_string(out + base));
      report->exact = false;
    }
  }
  return out;
}

}  // namespace detail

/// nk' for an input delay of nk samples at a new sample time, read as the file comment says: for
/// nk ≥ 1 one sample belongs to the sampled plant and the dead time (nk − 1)·old_ts is rescaled,
/// nk' = 1 + round((nk − 1)·old_ts/new_ts); nk = 0 (feed-through) stays 0. Warnings as in the
/// file comment (appended to `report`).
[[nodiscard]] inline int rescale_delay(int nk, double old_ts, double new_ts, SampleTimeReport* report = nullptr,
                                       const std::string& what = "input delay nk") {
  return nk == 0 ? detail::rescale_dead_time(0, old_ts, new_ts, report, what, 0)
                 : 1 + detail::rescale_dead_time(nk - 1, old_ts, new_ts, report, what, 1);
}

/// Continuous-time equivalent (zero-order hold) of a discrete state-space model. Throws
/// `nlid::Error` if A has an eigenvalue on the closed negative real axis.
[[nodiscard]] inline ContinuousStateSpace d2c(const StateSpace& sys) {
  const auto n = static_cast<Eigen::Index>(sys.order());
  const auto m = static_cast<Eigen::Index>(sys.num_inputs());
  if (n > 0) {
    const Eigen::VectorXcd ev = Eigen::EigenSolver<Eigen::MatrixXd>(sys.a(), false).eigenvalues();
    for (Eigen::Index i = 0; i < ev.size(); ++i) {
      if (ev(i).real() <= 0 && std::abs(ev(i).imag()) <= 1e-12 * std::max(1.0, std::abs(ev(i)))) {
        throw Error("the discrete model has a pole at z = " + detail::format_f(ev(i).real(), 6) +
                        ", on the negative real axis or at 0; it has no continuous-time (zero-order-hold) "
                        "equivalent, so its sample time cannot be converted exactly",
                    at_parameter("A"));
      }
    }
  }
  Eigen::MatrixXd big = Eigen::MatrixXd::Zero(n + m, n + m);
  big.topLeftCorner(n, n) = sys.a();
  big.topRightCorner(n, m) = sys.b();
  big.bottomRightCorner(m, m).setIdentity();
  const Eigen::MatrixXd l = n > 0 ? Eigen::MatrixXd(big.log() / sys.ts()) : Eigen::MatrixXd::Zero(n + m, n + m);
  require(l.allFinite(), "matrix logarithm failed (ill-conditioned A); the sample time cannot be converted",
          at_parameter("A"));
  return ContinuousStateSpace{l.topLeftCorner(n, n), l.topRightCorner(n, m), sys.c(), sys.d()};
}

/// Zero-order-hold discretisation at sample time `ts` (the matrix exponential of the file comment).
[[nodiscard]] inline StateSpace c2d(const ContinuousStateSpace& sys, double ts) {
  detail::check_new_ts(ts);
  const Eigen::Index n = sys.a.rows(), m = sys.b.cols();
  require(sys.a.cols() == n && sys.b.rows() == n && sys.c.cols() == n && sys.d.rows() == sys.c.rows() &&
              sys.d.cols() == m,
          "c2d: matrix sizes of A, B, C, D do not fit together", at_parameter("A, B, C, D"));
  Eigen::MatrixXd big = Eigen::MatrixXd::Zero(n + m, n + m);
  big.topLeftCorner(n, n) = sys.a * ts;
  big.topRightCorner(n, m) = sys.b * ts;
  const Eigen::MatrixXd e = big.exp();
  return StateSpace(e.topLeftCorner(n, n), e.topRightCorner(n, m), sys.c, sys.d, ts);
}

/// The state-space model at a new sample time (exact under zero-order hold).
[[nodiscard]] inline StateSpace with_sample_time(const StateSpace& sys, double new_ts,
                                                 SampleTimeReport* report = nullptr) {
  detail::check_new_ts(new_ts);
  StateSpace out = sys.order() == 0 ? StateSpace(sys.a(), sys.b(), sys.c(), sys.d(), new_ts) : c2d(d2c(sys), new_ts);
  out.set_offset(sys.offset());
  out.set_input_names(sys.input_names());
  out.set_output_names(sys.output_names());
  if (report != nullptr) {
    report->old_ts = sys.ts();
    report->new_ts = new_ts;
  }
  return out;
}

namespace detail {

/// Observer-canonical realisation of Σ B_j(q)/F(q) u_j with B_j = β_j0 + β_j1 q⁻¹ + …, F monic
/// [1 α₁ …] (no delays): x(t+1) = A x + B u, y = C x + D u.
inline StateSpace realise(const Eigen::VectorXd& f, const std::vector<Eigen::VectorXd>& b, double ts) {
  Eigen::Index n = f.size() - 1;
  for (const auto& bj : b) n = std::max(n, bj.size() - 1);
  const auto m = static_cast<Eigen::Index>(b.size());
  Eigen::VectorXd alpha = Eigen::VectorXd::Zero(n + 1);
  alpha.head(f.size()) = f;
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(n, n), B(n, m), C = Eigen::MatrixXd::Zero(1, n), D(1, m);
  for (Eigen::Index i = 0; i < n; ++i) {
    A(i, 0) = -alpha(i + 1);
    if (i + 1 < n) A(i, i + 1) = 1.0;
  }
  if (n > 0) C(0, 0) = 1.0;
  for (Eigen::Index j = 0; j < m; ++j) {
    Eigen::VectorXd beta = Eigen::VectorXd::Zero(n + 1);
    beta.head(b[static_cast<std::size_t>(j)].size()) = b[static_cast<std::size_t>(j)];
    D(0, j) = beta(0);
    for (Eigen::Index i = 0; i < n; ++i) B(i, j) = beta(i + 1) - alpha(i + 1) * beta(0);
  }
  return StateSpace(A, B, C, D, ts);
}

/// det(zI − M) as a monic polynomial in q⁻¹: [1 c₁ … c_n].
inline Eigen::VectorXd characteristic_polynomial(const Eigen::MatrixXd& M) {
  if (M.rows() == 0) return Eigen::VectorXd::Ones(1);
  const Eigen::VectorXcd ev = Eigen::EigenSolver<Eigen::MatrixXd>(M, false).eigenvalues();
  return poly_from_roots(ev);
}

/// Back from a single-output realisation to F and B_j (each of length n + 1), using
/// C adj(zI − A) B_j = det(zI − A + B_j C) − det(zI − A).
inline std::pair<Eigen::VectorXd, std::vector<Eigen::VectorXd>> polynomials_of(const StateSpace& s) {
  const Eigen::VectorXd f = characteristic_polynomial(s.a());
  std::vector<Eigen::VectorXd> b;
  for (int j = 0; j < s.num_inputs(); ++j) {
    const Eigen::VectorXd g = characteristic_polynomial(s.a() - s.b().col(j) * s.c());
    b.push_back(g - f + s.d()(0, j) * f);
  }
  return {f, b};
}

/// B/F (no delay) converted from old_ts to new_ts, exactly under zero-order hold.
inline std::pair<Eigen::VectorXd, std::vector<Eigen::VectorXd>> convert_rational(
    const Eigen::VectorXd& f, const std::vector<Eigen::VectorXd>& b, double old_ts, double new_ts) {
  const StateSpace s = realise(f, b, old_ts);
  return polynomials_of(with_sample_time(s, new_ts));
}

/// Σ q⁻ⁿᵏʲ B_j/F u_j at a new sample time (see the file comment on delays): the new F and, per
/// input, B_j' and nk_j'. `names[j]` names input j in warnings.
struct DelayedRational {
  Eigen::VectorXd f;               ///< monic [1 f₁ …]
  std::vector<Eigen::VectorXd> b;  ///< B_j' (leading coefficient first, after the delay)
  std::vector<int> nk;             ///< nk_j'
};

inline DelayedRational convert_delayed(const Eigen::VectorXd& f, const std::vector<Eigen::VectorXd>& b,
                                       const std::vector<int>& nk, double old_ts, double new_ts,
                                       SampleTimeReport* report, const std::vector<std::string>& names) {
  const auto nf = f.size() - 1;
  std::vector<Eigen::VectorXd> rational;
  std::vector<bool> proper;  // q⁻¹B_j/F is the sampled plant (nk_j ≥ 1, no poles at 0)
  for (std::size_t j = 0; j < b.size(); ++j) {
    const bool p = nk[j] >= 1 && b[j].size() <= nf;
    proper.push_back(p);
    Eigen::VectorXd r = b[j];
    if (p) {
      r.resize(b[j].size() + 1);
      r << 0.0, b[j];
    }
    rational.push_back(std::move(r));
  }
  auto [fn, bn] = convert_rational(f, rational, old_ts, new_ts);
  DelayedRational out{fn, {}, {}};
  for (std::size_t j = 0; j < b.size(); ++j) {
    if (proper[j]) {
      // ZOH keeps D = 0, so bn[j](0) is exactly 0 (polynomials_of: monic minus monic, D·F = 0).
      out.b.push_back(bn[j].tail(bn[j].size() - 1));
      out.nk.push_back(1 + rescale_dead_time(nk[j] - 1, old_ts, new_ts, report, names[j], 1));
    } else {
      out.b.push_back(bn[j]);
      if (nk[j] >= 1 && report != nullptr) {
        report->exact = false;
        report->warnings.push_back(
            names[j] + " = " + std::to_string(nk[j]) + " with nb = " + std::to_string(b[j].size()) + " > nf = " +
            std::to_string(nf) + ": the extra numerator terms stand for a fraction of a sample of dead time, "
            "which has no exact zero-order-hold conversion; converted as feed-through behind " +
            fmt_seconds(nk[j] * old_ts) + " of dead time, exact only for inputs held over the old samples");
      }
      out.nk.push_back(rescale_dead_time(nk[j], old_ts, new_ts, nk[j] >= 1 ? nullptr : report, names[j], 0));
    }
  }
  return out;
}

}  // namespace detail

/// Output-error model B/F at a new sample time: B/F converted exactly, delays rescaled.
[[nodiscard]] inline OutputError with_sample_time(const OutputError& m, double new_ts,
                                                  SampleTimeReport* report = nullptr) {
  detail::check_new_ts(new_ts);
  if (report != nullptr) {
    report->old_ts = m.ts();
    report->new_ts = new_ts;
  }
  std::vector<Eigen::VectorXd> b, f;
  std::vector<int> nk;
  for (int i = 0; i < m.num_inputs(); ++i) {
    Eigen::VectorXd fi(m.f(i).size() + 1);
    fi << 1.0, m.f(i);
    const detail::DelayedRational c = detail::convert_delayed(
        fi, {m.b(i)}, {m.nk(i)}, m.ts(), new_ts, report,
        {m.num_inputs() == 1 ? "input delay nk" : "input delay nk of u" + std::to_string(i + 1)});
    b.push_back(c.b[0]);
    f.push_back(c.f.tail(c.f.size() - 1));
    nk.push_back(c.nk[0]);
  }
  return OutputError(b, f, nk, new_ts, m.offset());
}

/// ARX model at a new sample time: its deterministic part B/A converted exactly (a common
/// denominator for all inputs), delays rescaled, the static offset kept. The noise model 1/A is
/// not preserved (a warning says so): use the result for simulation.
[[nodiscard]] inline Arx with_sample_time(const Arx& m, double new_ts, SampleTimeReport* report = nullptr) {
  detail::check_new_ts(new_ts);
  if (report != nullptr) {
    report->old_ts = m.ts();
    report->new_ts = new_ts;
    report->warnings.push_back("ARX: the deterministic part B/A is converted exactly; the noise model 1/A is not, so "
                               "one-step predictions of the converted model are not those of a re-estimated one");
  }
  const Eigen::VectorXd a = m.a_polynomial();
  std::vector<Eigen::VectorXd> b;
  std::vector<int> nk;
  std::vector<std::string> what;
  for (int i = 0; i < m.num_inputs(); ++i) {
    b.push_back(m.b(i));
    nk.push_back(m.nk(i));
    what.push_back(m.num_inputs() == 1 ? "input delay nk" : "input delay nk of u" + std::to_string(i + 1));
  }
  const detail::DelayedRational conv = detail::convert_delayed(a, b, nk, m.ts(), new_ts, report, what);
  const Eigen::VectorXd& an = conv.f;
  const std::vector<Eigen::VectorXd>& bn = conv.b;
  nk = conv.nk;
  // Same static offset y0 = c / A(1) at the new rate.
  const double a1 = a.sum();
  const double c = m.offset() == 0.0 || a1 == 0.0 ? m.offset() : m.offset() / a1 * an.sum();
  Arx out(an.tail(an.size() - 1), bn, nk, new_ts, c);
  const auto names = m.input_names();
  if (static_cast<int>(names.size()) == out.num_inputs()) out.set_input_names(names);
  return out;
}

/// Hammerstein–Wiener model at a new sample time: the linear block B/F converted exactly (its
/// orders become nb' = nf' = nf for nk ≥ 1 and nb ≤ nf, else nb' = n + 1, nf' = n with
/// n = max(nf, nb − 1); see the file comment on delays), nk rescaled, the static
/// nonlinearities unchanged.
template <class In, class Out>
[[nodiscard]] HammersteinWiener<In, TransferFunctionBlock<Dynamic, Dynamic, Dynamic>, Out> with_sample_time(
    const HammersteinWiener<In, TransferFunctionBlock<Dynamic, Dynamic, Dynamic>, Out>& m, double new_ts,
    SampleTimeReport* report = nullptr) {
  detail::check_new_ts(new_ts);
  require(m.ts() > 0, "the model has no sample time to convert from (ts = 0)", at_parameter("ts"));
  if (report != nullptr) {
    report->old_ts = m.ts();
    report->new_ts = new_ts;
  }
  const auto& l = m.linear_block();
  const auto th = m.linear_parameters();
  Eigen::VectorXd b(l.nb()), f(l.nf() + 1);
  for (int i = 0; i < l.nb(); ++i) b(i) = th[static_cast<std::size_t>(i)];
  f(0) = 1.0;
  for (int i = 0; i < l.nf(); ++i) f(i + 1) = th[static_cast<std::size_t>(l.nb() + i)];
  const detail::DelayedRational c = detail::convert_delayed(f, {b}, {l.nk()}, m.ts(), new_ts, report, {"input delay nk"});
  const Eigen::VectorXd& fn = c.f;
  const std::vector<Eigen::VectorXd>& bn = c.b;
  const int nk = c.nk[0];
  const auto nb_new = static_cast<int>(bn[0].size()), nf_new = static_cast<int>(fn.size() - 1);
  using L = TransferFunctionBlock<Dynamic, Dynamic, Dynamic>;
  HammersteinWiener<In, L, Out> out(m.input_nonlinearity(), L(nb_new, nf_new, nk), m.output_nonlinearity(), new_ts);
  Eigen::VectorXd theta(out.num_parameters());
  const auto tf = m.input_parameters(), tg = m.output_parameters();
  Eigen::Index k = 0;
  for (double v : tf) theta(k++) = v;
  for (Eigen::Index i = 0; i < nb_new; ++i) theta(k++) = bn[0](i);
  for (Eigen::Index i = 1; i <= nf_new; ++i) theta(k++) = fn(i);
  for (double v : tg) theta(k++) = v;
  out.set_parameters(theta);
  out.set_channel_names(m.input_name(), m.output_name());
  return out;
}

/// Nonlinear ARX model (run-time regressors) at a new sample time: input delays rescaled, lags in
/// samples kept, θ kept as a starting point; marked inexact with a warning to re-estimate.
template <class F>
[[nodiscard]] Nlarx<RegressorList, F> with_sample_time(const Nlarx<RegressorList, F>& m, double new_ts,
                                                      SampleTimeReport* report = nullptr) {
  detail::check_new_ts(new_ts);
  require(m.ts() > 0, "the model has no sample time to convert from (ts = 0)", at_parameter("ts"));
  SampleTimeReport local;
  SampleTimeReport& r = report != nullptr ? *report : local;
  r.old_ts = m.ts();
  r.new_ts = new_ts;
  r.exact = false;
  r.warnings.push_back(
      "nonlinear ARX: the regressors are samples of a difference equation at " + detail::fmt_seconds(m.ts()) +
      "; the structure was converted (input delays rescaled, lags kept) and the parameters kept as a starting "
      "point - re-estimate the model on data resampled to " + detail::fmt_seconds(new_ts));
  RegressorList regs;
  bool custom = false;
  for (const auto& b : m.regressors().blocks()) {
    switch (b.kind) {
      case RegressorList::Kind::output_lags: regs.add_output_lags(b.na); break;
      case RegressorList::Kind::input_lags:
        regs.add_input_lags(b.nb, rescale_delay(b.nk, m.ts(), new_ts, &r,
                                                "input delay nk of u" + std::to_string(b.channel + 1)),
                            b.channel);
        break;
      case RegressorList::Kind::custom:
        regs.add_custom(b.expression);
        custom = true;
        break;
    }
  }
  if (custom) r.warnings.push_back("custom regressors keep their lags in samples; check them at the new rate");
  Nlarx<RegressorList, F> out(std::move(regs), m.nonlinearity(), new_ts);
  out.set_parameters(m.parameters());
  out.set_channel_names(m.input_names(), m.output_name());
  return out;
}

/// Any model at a new sample time (dispatch to the overloads above; grey-box models are
/// continuous-time and only change the sample time they are simulated at, so they are returned
/// unchanged). Throws `nlid::Error` for a kind that cannot be converted.
[[nodiscard]] inline AnyModel with_sample_time(const AnyModel& m, double new_ts, SampleTimeReport* report = nullptr) {
  detail::check_new_ts(new_ts);
  AnyModel out;
  if (const auto* s = m.target<StateSpace>()) out = AnyModel(with_sample_time(*s, new_ts, report));
  else if (const auto* o = m.target<OutputError>()) out = AnyModel(with_sample_time(*o, new_ts, report));
  else if (const auto* a = m.target<Arx>()) out = AnyModel(with_sample_time(*a, new_ts, report));
  else if (const auto* h = m.target<DynamicHammersteinWiener>()) out = AnyModel(with_sample_time(*h, new_ts, report));
  else if (const auto* n = m.target<DynamicNlarx>()) out = AnyModel(with_sample_time(*n, new_ts, report));
  else if (m.kind() == "greybox") {
    if (report != nullptr) {
      report->old_ts = m.ts();
      report->new_ts = new_ts;
      report->warnings.push_back("grey-box model: continuous time, simulated at any sample time; unchanged");
    }
    return m;
  } else {
    throw Error("cannot change the sample time of a '" + m.kind() + "' model held in this form; "
                "load it with load_model(path) or re-estimate it on resampled data",
                at_parameter("model"));
  }
  ModelFileInfo info = m.info();
  // The parameters' uncertainty belonged to the model at the old rate (and to its estimate).
  info.uncertainty.reset();
  out.info() = std::move(info);
  return out;
}

}  // namespace nlid
