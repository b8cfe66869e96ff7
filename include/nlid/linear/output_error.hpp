#pragma once
/// @file
/// Output-error (OE) models: y = B/F u + e, estimated with simulation focus.
///
/// Model (Ljung 1999, eq. 4.25), single output, m inputs, orders [nb nf nk] per input:
///
///     y(t) = Σᵢ Bᵢ(q)/Fᵢ(q) uᵢ(t − nkᵢ) + c + e(t)
///     Bᵢ(q) = bᵢ,₀ + bᵢ,₁q⁻¹ + … + bᵢ,nbᵢ₋₁ q⁻⁽ⁿᵇⁱ⁻¹⁾,   Fᵢ(q) = 1 + fᵢ,₁q⁻¹ + … + fᵢ,nfᵢ q⁻ⁿᶠⁱ
///
/// with white e added at the output (H = 1). Because the noise does not enter the dynamics, the
/// optimal predictor is the simulation ŷ(t) = Σ wᵢ(t) + c,  Fᵢ(q) wᵢ(t) = Bᵢ(q) uᵢ(t − nkᵢ),
/// and the prediction-error criterion V = (1/N) Σ (y − ŷ)² is the simulation error: OE is the
/// linear model of "simulation focus" (Ljung 1999, §7.3 and §14.4).
///
/// Estimation, in two stages:
/// 1. Start: Steiglitz–McBride iterations (Steiglitz & McBride 1965; Ljung 1999, §10.4,
///    eq. 10.83–10.85). With the current F, filter input and output by 1/F and fit an ARX model
///    [nf nb nk] to the filtered data by linear least squares; its A is the next F. Each step is
///    a QR solve, the fixed point is (for white e) the OE estimate, and no derivatives or
///    starting guesses are needed. The start is the iterate (the first is plain ARX) whose
///    simulation error is least: on data from a nonlinear plant the last one can be worse. An unstable F from a step is made stable by reflecting its
///    roots (polynomial.hpp). Several inputs are handled by backfitting: each sweep fits input i
///    to y minus the current simulated contributions of the other inputs.
///    (Chosen over "high-order ARX then model reduction" because it needs no order choice for the
///    intermediate model and is unbiased in the OE noise setting where ARX is biased.)
/// 2. Refinement: prediction-error minimisation of ½ Σ (ŷ − y)² with `solve_least_squares`
///    (Levenberg–Marquardt) and an analytic Jacobian from the sensitivity filters
///
///        ∂wᵢ(t)/∂bᵢ,ⱼ = (1/Fᵢ) uᵢ(t − nkᵢ − j),     ∂wᵢ(t)/∂fᵢ,ₖ = −(1/Fᵢ) wᵢ(t − k)
///
///    (Ljung 1999, eq. 10.55). Every evaluation checks that each Fᵢ is strictly stable and
///    reports the point as not evaluable otherwise, so LM rejects steps that leave the stability
///    region: the returned F is always stable.
///
/// Initial conditions. A block wᵢ of order nᵢ = max(nfᵢ, nkᵢ + nbᵢ − 1) started from an
/// arbitrary past differs from the zero-state response by a free response
/// Σ_{j<nᵢ} γᵢ,ⱼ hᵢ(t − j), hᵢ the impulse response of 1/Fᵢ. `InitialCondition::estimate` makes
/// the γ (per experiment and input) extra parameters of the PEM fit; at simulation time they are
/// the linear least-squares fit to the record. `zero` uses a rest start, `equilibrium` the
/// steady state for u(0), and `measured` (single input only) takes the first nᵢ measured outputs
/// (minus c) as the past of w.

#include <algorithm>
#include <cmath>
#include <limits>
#include <locale>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/core/sizes.hpp"
#include "nlid/core/initial_condition.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/data/experiment.hpp"
#include "nlid/estimation/levenberg_marquardt.hpp"
#include "nlid/linear/arx.hpp"
#include "nlid/linear/concepts.hpp"
#include "nlid/linear/detail/checks.hpp"
#include "nlid/linear/detail/least_squares.hpp"
#include "nlid/linear/polynomial.hpp"
#include "nlid/linear/report.hpp"
#include "nlid/linear/state_space.hpp"

namespace nlid {

/// OE orders [nb nf nk], one entry per input.
struct OeOrders {
  std::vector<int> nb;  ///< per input: number of B coefficients (≥ 1)
  std::vector<int> nf;  ///< per input: number of F coefficients after the leading 1 (≥ 0)
  std::vector<int> nk;  ///< per input: delay in samples (≥ 0)

  /// No orders (invalid until filled in).
  OeOrders() = default;
  /// Single-input orders [nb nf nk].
  OeOrders(int nb_, int nf_, int nk_) : nb{nb_}, nf{nf_}, nk{nk_} {}
  /// Multi-input orders.
  OeOrders(std::vector<int> nb_, std::vector<int> nf_, std::vector<int> nk_)
      : nb(std::move(nb_)), nf(std::move(nf_)), nk(std::move(nk_)) {}
  /// Number of inputs the orders are written for.
  [[nodiscard]] int num_inputs() const { return static_cast<int>(nb.size()); }
  /// Block order nᵢ = max(nfᵢ, nkᵢ + nbᵢ − 1) of input `i` (initial-condition terms).
  [[nodiscard]] int block_order(std::size_t i) const { return std::max(nf[i], nk[i] + nb[i] - 1); }
  /// "[2 2 0]" or "[[2 1] [2 2] [0 1]]".
  [[nodiscard]] std::string str() const {
    auto list = [](const std::vector<int>& v) {
      if (v.size() == 1) return std::to_string(v[0]);
      std::string s = "[";
      for (std::size_t i = 0; i < v.size(); ++i) s += (i ? " " : "") + std::to_string(v[i]);
      return s + "]";
    };
    return "[" + list(nb) + " " + list(nf) + " " + list(nk) + "]";
  }
};

/// Options of `oe`.
struct OeOptions {
  /// Initial condition in the criterion: `zero` (rest) or `estimate` (γ per experiment).
  InitialCondition initial_state = InitialCondition::zero;
  bool offset = false;              ///< estimate the output offset c
  int steiglitz_mcbride_iterations = 20;  ///< start-up iterations (stage 1), ≥ 0
  bool refine = true;               ///< run the PEM refinement (stage 2)
  /// Options of the refinement; the default allows 100 iterations.
  LmOptions lm;
};

class OutputError;
namespace detail {
inline OutputError oe_estimate(const Dataset& data, const OeOrders& o, const OeOptions& opt);
}

/// An output-error model y = Σ Bᵢ/Fᵢ uᵢ(t − nkᵢ) + c + e (see file comment).
/// Invariant: one b, f, nk per input; nbᵢ ≥ 1; nkᵢ ≥ 0; ts > 0.
class OutputError {
 public:
  /// Empty model.
  OutputError() = default;

  /// Model from coefficients: `b[i]` = [bᵢ,₀ …] (nbᵢ ≥ 1), `f[i]` = [fᵢ,₁ … fᵢ,nfᵢ] (without the
  /// leading 1), delays `nk`, sample time `ts`, offset `c`. Throws `nlid::Error` naming the bad
  /// argument.
  OutputError(std::vector<Eigen::VectorXd> b, std::vector<Eigen::VectorXd> f, std::vector<int> nk,
              double ts, double c = 0.0)
      : b_(std::move(b)), f_(std::move(f)), nk_(std::move(nk)), ts_(ts), offset_(c) {
    require(b_.size() == f_.size() && b_.size() == nk_.size(),
            "OutputError: " + std::to_string(b_.size()) + " B, " + std::to_string(f_.size()) +
                " F polynomials and " + std::to_string(nk_.size()) +
                " delays; give one of each per input",
            at_parameter("nk"));
    for (std::size_t i = 0; i < b_.size(); ++i) {
      require(b_[i].size() >= 1, "OutputError: B needs at least one coefficient",
              at_parameter("b[" + std::to_string(i) + "]"));
      require(nk_[i] >= 0 && nk_[i] <= max_model_order,
              "OutputError: delay nk must be in 0 ... " + std::to_string(max_model_order) + ", got " +
                  std::to_string(nk_[i]),
              at_parameter("nk[" + std::to_string(i) + "]"));
      require(b_[i].size() <= max_model_order && f_[i].size() <= max_model_order,
              "OutputError: more than " + std::to_string(max_model_order) + " B or F coefficients",
              at_parameter("b[" + std::to_string(i) + "], f[" + std::to_string(i) + "]"));
      require(b_[i].allFinite() && f_[i].allFinite(), "OutputError: coefficients must be finite",
              at_parameter("b, f"));
    }
    require(ts_ > 0 && std::isfinite(ts_), "OutputError: sample time must be positive",
            at_parameter("ts"));
    has_offset_ = c != 0.0;
    stddev_ = Eigen::VectorXd::Zero(num_parameters());
  }

  /// Number of inputs.
  [[nodiscard]] int num_inputs() const { return static_cast<int>(b_.size()); }
  /// Always 1 (single-output model).
  [[nodiscard]] int num_outputs() const { return 1; }
  /// Sample time (s).
  [[nodiscard]] double ts() const { return ts_; }
  /// Orders [nb nf nk].
  [[nodiscard]] OeOrders orders() const {
    OeOrders o;
    for (std::size_t i = 0; i < b_.size(); ++i) {
      o.nb.push_back(static_cast<int>(b_[i].size()));
      o.nf.push_back(static_cast<int>(f_[i].size()));
      o.nk.push_back(nk_[i]);
    }
    return o;
  }
  /// Free B coefficients of input `i`: [bᵢ,₀ … bᵢ,nbᵢ₋₁], acting on uᵢ(t − nkᵢ − j). These are the
  /// numbers a Hammerstein–Wiener linear block starts from.
  [[nodiscard]] const Eigen::VectorXd& b(int i = 0) const { return b_.at(checked(i)); }
  /// Free F coefficients of input `i`: [fᵢ,₁ … fᵢ,nfᵢ] (the leading 1 omitted).
  [[nodiscard]] const Eigen::VectorXd& f(int i = 0) const { return f_.at(checked(i)); }
  /// Delay nkᵢ.
  [[nodiscard]] int nk(int i = 0) const { return nk_.at(checked(i)); }
  /// Output offset c.
  [[nodiscard]] double offset() const { return offset_; }
  /// True if the model has an offset term.
  [[nodiscard]] bool has_offset() const { return has_offset_; }
  /// q^(−nkᵢ) Bᵢ(q) with nkᵢ leading zeros (toolbox convention).
  [[nodiscard]] Eigen::VectorXd b_polynomial(int i = 0) const {
    const auto& bi = b(i);
    Eigen::VectorXd p = Eigen::VectorXd::Zero(nk(i) + bi.size());
    p.tail(bi.size()) = bi;
    return p;
  }
  /// Fᵢ(q) = [1, fᵢ,₁, …] (toolbox convention).
  [[nodiscard]] Eigen::VectorXd f_polynomial(int i = 0) const {
    const auto& fi = f(i);
    Eigen::VectorXd p(fi.size() + 1);
    p << 1.0, fi;
    return p;
  }
  /// θ = [b₁; …; bₘ; f₁; …; fₘ; c (if has_offset)] (toolbox order: all B, then all F).
  [[nodiscard]] Eigen::VectorXd parameters() const {
    Eigen::VectorXd th(num_parameters());
    Eigen::Index k = 0;
    for (const auto& bi : b_) { th.segment(k, bi.size()) = bi; k += bi.size(); }
    for (const auto& fi : f_) { th.segment(k, fi.size()) = fi; k += fi.size(); }
    if (has_offset_) th(k) = offset_;
    return th;
  }
  /// Number of model parameters (initial-condition terms not included).
  [[nodiscard]] int num_parameters() const {
    int d = has_offset_ ? 1 : 0;
    for (std::size_t i = 0; i < b_.size(); ++i) d += static_cast<int>(b_[i].size() + f_[i].size());
    return d;
  }
  /// Names in the order of `parameters()`: b<power of q⁻¹>, f<k> (one input) or
  /// b<input>_<power>, f<input>_<k> (several), then c.
  [[nodiscard]] std::vector<std::string> parameter_names() const {
    std::vector<std::string> n;
    const bool one = num_inputs() == 1;
    for (int i = 0; i < num_inputs(); ++i)
      for (int j = 0; j < static_cast<int>(b_[i].size()); ++j)
        n.push_back(one ? "b" + std::to_string(nk_[i] + j)
                        : "b" + std::to_string(i + 1) + "_" + std::to_string(nk_[i] + j));
    for (int i = 0; i < num_inputs(); ++i)
      for (int k = 1; k <= static_cast<int>(f_[i].size()); ++k)
        n.push_back(one ? "f" + std::to_string(k)
                        : "f" + std::to_string(i + 1) + "_" + std::to_string(k));
    if (has_offset_) n.push_back("c");
    return n;
  }
  /// One-sigma standard deviations of `parameters()` (zeros for a hand-made model; +∞ for a
  /// parameter the estimation data do not determine, printed "not identifiable").
  [[nodiscard]] const Eigen::VectorXd& parameter_stddev() const { return stddev_; }
  /// How the model was estimated.
  [[nodiscard]] const LinearEstimationReport& report() const { return report_; }
  /// Replaces the estimation report (a model file restores it: `describe()` prints it).
  void set_report(LinearEstimationReport r) { report_ = std::move(r); }
  /// Replaces the parameter standard deviations (a model file restores them); one value per
  /// entry of `parameters()`, finite and non-negative, or +∞ for "not identifiable".
  void set_parameter_stddev(Eigen::VectorXd sd) {
    detail::check_parameter_stddev(sd, parameter_names(), "OutputError");
    stddev_ = std::move(sd);
  }

  /// Poles: roots of every Fᵢ, input by input.
  [[nodiscard]] Eigen::VectorXcd poles() const {
    std::vector<std::complex<double>> all;
    for (int i = 0; i < num_inputs(); ++i) {
      const Eigen::VectorXcd r = roots(f_polynomial(i));
      all.insert(all.end(), r.data(), r.data() + r.size());
    }
    return Eigen::Map<const Eigen::VectorXcd>(all.data(), static_cast<Eigen::Index>(all.size()));
  }
  /// Zeros of input `i`: roots of Bᵢ.
  [[nodiscard]] Eigen::VectorXcd zeros(int i = 0) const { return roots(b(i)); }
  /// True if every Fᵢ has all roots strictly inside the unit circle.
  [[nodiscard]] bool is_stable() const {
    for (int i = 0; i < num_inputs(); ++i)
      if (!is_stable_polynomial(f_polynomial(i))) return false;
    return true;
  }
  /// Frequency response q^(−nk)Bᵢ/Fᵢ at e^{iωTs} for `w` in rad/s.
  [[nodiscard]] Eigen::VectorXcd frequency_response(const Eigen::VectorXd& w, int i = 0) const {
    return nlid::frequency_response(b_polynomial(i), f_polynomial(i), w, ts_);
  }
  /// Static gain Bᵢ(1)/Fᵢ(1). Throws if Fᵢ has a root at z = 1.
  [[nodiscard]] double dc_gain(int i = 0) const {
    const double f1 = f_polynomial(i).sum();
    require(std::abs(f1) > 1e-14, "OutputError::dc_gain: F(q) has a root at z = 1 (integrator)");
    return b(i).sum() / f1;
  }
  /// q^(−nkᵢ) Bᵢ(q) / Fᵢ(q).
  [[nodiscard]] TransferFunction to_transfer_function(int i = 0) const {
    return TransferFunction{b_polynomial(i), f_polynomial(i), ts_};
  }
  /// State-space form: the blocks' observer-canonical forms side by side (Σ nᵢ states, block-
  /// diagonal A), the offset as y₀.
  [[nodiscard]] StateSpace to_state_space() const {
    int n = 0;
    std::vector<StateSpace> blocks;
    for (int i = 0; i < num_inputs(); ++i) {
      const Arx single(f_[i], {b_[i]}, {nk_[i]}, ts_);
      blocks.push_back(single.to_state_space());
      n += blocks.back().order();
    }
    const int m = num_inputs();
    Eigen::MatrixXd A = Eigen::MatrixXd::Zero(n, n), B = Eigen::MatrixXd::Zero(n, m),
                    C = Eigen::MatrixXd::Zero(1, n), D = Eigen::MatrixXd::Zero(1, m);
    int k = 0;
    for (int i = 0; i < m; ++i) {
      const StateSpace& s = blocks[static_cast<std::size_t>(i)];
      const int ni = s.order();
      A.block(k, k, ni, ni) = s.a();
      B.block(k, i, ni, 1) = s.b();
      C.block(0, k, 1, ni) = s.c();
      D(0, i) = s.d()(0, 0);
      k += ni;
    }
    StateSpace ss(A, B, C, D, ts_);
    ss.set_offset(Eigen::VectorXd::Constant(1, offset_));
    return ss;
  }

  /// Free-run output (N x 1) from the initial condition `ic` (file comment). Throws
  /// `nlid::Error` on a channel or sample-time mismatch, missing samples, `measured` with several
  /// inputs, or `equilibrium` with an integrating F.
  [[nodiscard]] Eigen::MatrixXd simulate(const Experiment& e,
                                         InitialCondition ic = InitialCondition::zero) const {
    const bool need_y = ic == InitialCondition::estimate || ic == InitialCondition::measured;
    detail::check_linear_experiment(e, num_inputs(), 1, ts_, -1, "OutputError::simulate", need_y);
    detail::check_linear_channel_order(e, *this, "OutputError::simulate");
    Eigen::MatrixXd y = Eigen::MatrixXd::Constant(e.size(), 1, offset_);
    switch (ic) {
      case InitialCondition::zero:
        for (int i = 0; i < num_inputs(); ++i) y.col(0) += block_response(i, e.u().col(i), nullptr);
        break;
      case InitialCondition::equilibrium:
        for (int i = 0; i < num_inputs(); ++i) {
          if (e.size() == 0) break;
          const double u0 = e.u()(0, i);
          const double f1 = f_polynomial(i).sum();
          require(std::abs(f1) > 1e-14 || b_[i].sum() * u0 == 0.0,
                  "OutputError::simulate: no equilibrium: F(q) has a root at z = 1",
                  at_parameter("InitialCondition::equilibrium"));
          const double w0 = std::abs(f1) > 1e-14 ? b_[i].sum() / f1 * u0 : 0.0;
          y.col(0) += block_response(i, e.u().col(i), nullptr, u0, w0);
        }
        break;
      case InitialCondition::measured: {
        require(num_inputs() == 1,
                "OutputError::simulate: InitialCondition::measured is defined for one input only "
                "(the split of past outputs between blocks is unknown); use ::estimate",
                at_parameter("InitialCondition::measured"));
        const Eigen::VectorXd past = e.y().col(0).array() - offset_;
        y.col(0) += block_response(0, e.u().col(0), &past);
        break;
      }
      case InitialCondition::estimate: {
        for (int i = 0; i < num_inputs(); ++i) y.col(0) += block_response(i, e.u().col(i), nullptr);
        const Eigen::MatrixXd g = free_responses(e.size());
        if (g.cols() > 0)
          y.col(0) += g * detail::solve_least_squares_qr(g, e.y().col(0) - y.col(0)).theta;
        break;
      }
    }
    return y;
  }

  /// k-step prediction. The OE predictor does not use measured outputs (H = 1), so for every
  /// k ≥ 1 it is the simulation from the estimated initial condition. Throws for k < 1.
  [[nodiscard]] Eigen::MatrixXd predict(const Experiment& e, int k) const {
    require(k >= 1, "OutputError::predict: horizon k must be >= 1, got " + std::to_string(k),
            at_parameter("k"));
    return simulate(e, InitialCondition::estimate);
  }

  /// Toolbox-style description: equation, B and F with standard deviations, poles, report.
  [[nodiscard]] std::string describe() const {
    std::ostringstream os;
    os.imbue(std::locale::classic());  // a global locale's grouping or decimal comma must not reach the text
    const int m = num_inputs();
    const bool one = m == 1;
    os << "Discrete-time OE model, orders [nb nf nk] = " << orders().str() << ":\n  y(t) = ";
    for (int i = 0; i < m; ++i) {
      const std::string s = one ? "" : std::to_string(i + 1);
      os << (i ? " + " : "") << "[B" << s << "(q)/F" << s << "(q)]" << uname(i) << "(t)";
    }
    os << (has_offset_ ? " + c" : "") << " + e(t)\n";
    const Eigen::VectorXd sd = stddev_.size() == num_parameters()
                                   ? stddev_
                                   : Eigen::VectorXd::Zero(num_parameters());
    Eigen::Index kb = 0, kf = 0;
    for (const auto& bi : b_) kf += bi.size();
    for (int i = 0; i < m; ++i) {
      const std::string s = one ? "" : std::to_string(i + 1);
      Eigen::VectorXd sb = Eigen::VectorXd::Zero(nk_[i] + b_[i].size());
      sb.tail(b_[i].size()) = sd.segment(kb, b_[i].size());
      kb += b_[i].size();
      Eigen::VectorXd sf = Eigen::VectorXd::Zero(f_[i].size() + 1);
      sf.tail(f_[i].size()) = sd.segment(kf, f_[i].size());
      kf += f_[i].size();
      os << "  B" << s << "(q) = " << format_polynomial(b_polynomial(i), 4, "q", &sb) << "\n";
      os << "  F" << s << "(q) = " << format_polynomial(f_polynomial(i), 4, "q", &sf) << "\n";
    }
    if (has_offset_) {
      os << "  c = " << format_number(offset_, 4);
      os << format_stddev(sd(kf));
      os << "\n";
    }
    // Not factored past max_described_root_degree (polynomial.hpp): an F of order 10^5 is valid.
    Eigen::Index degree = 0;
    for (int i = 0; i < num_inputs(); ++i) degree = std::max(degree, detail::root_degree(f_polynomial(i)));
    os << "Poles: " << (degree > max_described_root_degree ? detail::roots_not_described(degree) : format_roots(poles()))
       << "\n";
    os << "Sample time: " << format_number(ts_, 6) << " s\n";
    if (!report_.method.empty()) os << report_.str();
    return os.str();
  }

  /// Input channel names (from the estimation data; empty or "u1", … otherwise).
  [[nodiscard]] std::vector<std::string> input_names() const { return input_names_; }
  /// Sets the input channel names (one per input).
  void set_input_names(std::vector<std::string> names) {
    require(names.size() == b_.size(), "OutputError: one input name per input required", at_parameter("input_names"));
    input_names_ = std::move(names);
  }
  /// Output channel name as a one-entry list (from the estimation data; empty if unknown).
  [[nodiscard]] std::vector<std::string> output_names() const { return output_names_; }
  /// Sets the output channel name (one entry, or empty for unknown).
  void set_output_names(std::vector<std::string> names) {
    require(names.size() <= 1, "OutputError: one output name (or none) required", at_parameter("output_names"));
    output_names_ = std::move(names);
  }

  // ---- Implementation details below ----------------------------------------------------------

 private:
  friend OutputError detail::oe_estimate(const Dataset&, const OeOrders&, const OeOptions&);

  std::size_t checked(int i) const {
    require(i >= 0 && i < num_inputs(),
            "OutputError: input index " + std::to_string(i) + " out of range (model has " +
                std::to_string(num_inputs()) + " inputs)",
            at_parameter("input"));
    return static_cast<std::size_t>(i);
  }
  std::string uname(int i) const {
    if (input_names_.size() == b_.size()) return input_names_[static_cast<std::size_t>(i)];
    return num_inputs() == 1 ? "u" : "u" + std::to_string(i + 1);
  }

  // wᵢ for input column `u`. Past inputs equal `u_past`, past w equal `w_past`; with `measured`
  // the first nᵢ values of w are copied from it (past data).
  Eigen::VectorXd block_response(int i, const Eigen::VectorXd& u, const Eigen::VectorXd* measured,
                                 double u_past = 0.0, double w_past = 0.0) const {
    const auto& bi = b_[static_cast<std::size_t>(i)];
    const auto& fi = f_[static_cast<std::size_t>(i)];
    const int nk = nk_[static_cast<std::size_t>(i)];
    const Eigen::Index n_copy = measured ? orders().block_order(static_cast<std::size_t>(i)) : 0;
    const Eigen::Index N = u.size();
    Eigen::VectorXd w(N);
    for (Eigen::Index t = 0; t < N; ++t) {
      if (t < n_copy) {
        w(t) = (*measured)(t);
        continue;
      }
      double acc = 0.0;
      for (Eigen::Index j = 0; j < bi.size(); ++j) {
        const Eigen::Index r = t - nk - j;
        acc += bi(j) * (r >= 0 ? u(r) : u_past);
      }
      for (Eigen::Index k = 1; k <= fi.size(); ++k) acc -= fi(k - 1) * (t - k >= 0 ? w(t - k) : w_past);
      w(t) = acc;
    }
    return w;
  }

  // Columns hᵢ(t − j), j < nᵢ, for every input: the free responses an initial state can add.
  Eigen::MatrixXd free_responses(Eigen::Index N) const {
    const OeOrders o = orders();
    Eigen::Index cols = 0;
    for (std::size_t i = 0; i < b_.size(); ++i) cols += std::min<Eigen::Index>(o.block_order(i), N);
    Eigen::MatrixXd g = Eigen::MatrixXd::Zero(N, cols);
    Eigen::Index c = 0;
    for (int i = 0; i < num_inputs(); ++i) {
      const Eigen::Index n = std::min<Eigen::Index>(o.block_order(static_cast<std::size_t>(i)), N);
      if (n == 0) continue;
      Eigen::VectorXd impulse = Eigen::VectorXd::Zero(N);
      impulse(0) = 1.0;
      const Eigen::VectorXd h = filter(Eigen::VectorXd::Ones(1), f_polynomial(i), impulse);
      detail::check_free_response(h, "OutputError::simulate", num_inputs() == 1 ? "F(q)" : "F" + std::to_string(i + 1) + "(q)",
                                  [&] { return roots(f_polynomial(i)); });
      for (Eigen::Index j = 0; j < n; ++j, ++c) g.col(c).tail(N - j) = h.head(N - j);
    }
    return g;
  }

  std::vector<Eigen::VectorXd> b_, f_;
  std::vector<int> nk_;
  double ts_ = 1.0;
  double offset_ = 0.0;
  bool has_offset_ = false;
  Eigen::VectorXd stddev_;
  LinearEstimationReport report_;
  std::vector<std::string> input_names_;
  std::vector<std::string> output_names_;
};

namespace detail {

// The PEM criterion of stage 2 as a LeastSquaresProblem: r = ŷ(θ) − y over all experiments,
// θ = [all b; all f; c?; γ per experiment and input (if estimated)], analytic Jacobian.
class OePemProblem {
 public:
  static constexpr int num_params = Dynamic;

  OePemProblem(const Dataset& data, const OeOrders& o, bool offset, bool estimate_ic)
      : data_(data), o_(o), offset_(offset), estimate_ic_(estimate_ic) {
    m_ = o.num_inputs();
    for (std::size_t i = 0; i < o.nb.size(); ++i) nb_total_ += o.nb[i];
    for (std::size_t i = 0; i < o.nb.size(); ++i) nbf_ += o.nb[i] + o.nf[i];
    for (int i = 0; i < m_; ++i) ic_per_exp_ += o.block_order(static_cast<std::size_t>(i));
    n_ = nbf_ + (offset ? 1 : 0) + (estimate_ic ? ic_per_exp_ * static_cast<int>(data.size()) : 0);
    rows_ = data.total_samples();
  }

  [[nodiscard]] int num_parameters() const { return n_; }
  [[nodiscard]] Eigen::Index num_residuals() const { return rows_; }
  [[nodiscard]] int num_model_parameters() const { return nbf_ + (offset_ ? 1 : 0); }

  // Packs a model's (b, f, c) and initial terms into θ.
  [[nodiscard]] Eigen::VectorXd pack(const std::vector<Eigen::VectorXd>& b,
                                     const std::vector<Eigen::VectorXd>& f, double c,
                                     const std::vector<Eigen::VectorXd>& gamma) const {
    Eigen::VectorXd th = Eigen::VectorXd::Zero(n_);
    Eigen::Index k = 0;
    for (const auto& bi : b) { th.segment(k, bi.size()) = bi; k += bi.size(); }
    for (const auto& fi : f) { th.segment(k, fi.size()) = fi; k += fi.size(); }
    if (offset_) th(k++) = c;
    if (estimate_ic_)
      for (const auto& g : gamma) { th.segment(k, g.size()) = g; k += g.size(); }
    return th;
  }

  // Splits θ into per-input B and F coefficient vectors.
  void unpack(const Eigen::VectorXd& th, std::vector<Eigen::VectorXd>& b,
              std::vector<Eigen::VectorXd>& f, double& c) const {
    b.resize(static_cast<std::size_t>(m_));
    f.resize(static_cast<std::size_t>(m_));
    Eigen::Index k = 0;
    for (std::size_t i = 0; i < b.size(); ++i) { b[i] = th.segment(k, o_.nb[i]); k += o_.nb[i]; }
    for (std::size_t i = 0; i < f.size(); ++i) { f[i] = th.segment(k, o_.nf[i]); k += o_.nf[i]; }
    c = offset_ ? th(k) : 0.0;
  }

  bool evaluate(const Eigen::VectorXd& th, Eigen::VectorXd& r, Eigen::MatrixXd* J) const {
    std::vector<Eigen::VectorXd> b, f;
    double c = 0;
    unpack(th, b, f, c);
    std::vector<Eigen::VectorXd> fpoly(static_cast<std::size_t>(m_));
    for (std::size_t i = 0; i < fpoly.size(); ++i) {
      fpoly[i].resize(f[i].size() + 1);
      fpoly[i] << 1.0, f[i];
      // Outside the stability region the simulation diverges: not evaluable, LM backs off.
      if (f[i].size() > 0 && !is_stable_polynomial(fpoly[i])) return false;
    }
    if (J) J->setZero();
    Eigen::Index row = 0;
    Eigen::Index kic = nbf_ + (offset_ ? 1 : 0);
    for (std::size_t e = 0; e < data_.size(); ++e) {
      const Experiment& ex = data_[e];
      const Eigen::Index N = ex.size();
      Eigen::VectorXd yhat = Eigen::VectorXd::Constant(N, c);
      Eigen::Index kb = 0, kf = nb_total_;
      for (std::size_t i = 0; i < static_cast<std::size_t>(m_); ++i) {
        const int nb = o_.nb[i], nf = o_.nf[i], nk = o_.nk[i];
        const int ni = o_.block_order(i);
        // w = (B q^-nk u + Σ γ_j δ(t − j)) / F.
        Eigen::VectorXd drive = Eigen::VectorXd::Zero(N);
        const auto u = ex.u().col(static_cast<Eigen::Index>(i));
        for (Eigen::Index t = 0; t < N; ++t)
          for (int j = 0; j < nb; ++j)
            if (t - nk - j >= 0) drive(t) += b[i](j) * u(t - nk - j);
        if (estimate_ic_)
          for (int j = 0; j < ni && j < N; ++j) drive(j) += th(kic + j);
        const Eigen::VectorXd w = filter(Eigen::VectorXd::Ones(1), fpoly[i], drive);
        yhat += w;
        if (J) {
          const Eigen::VectorXd uf = filter(Eigen::VectorXd::Ones(1), fpoly[i], Eigen::VectorXd(u));
          for (int j = 0; j < nb; ++j)
            for (Eigen::Index t = nk + j; t < N; ++t) (*J)(row + t, kb + j) = uf(t - nk - j);
          if (nf > 0) {
            const Eigen::VectorXd wf = filter(Eigen::VectorXd::Ones(1), fpoly[i], w);
            for (int k = 1; k <= nf; ++k)
              for (Eigen::Index t = k; t < N; ++t) (*J)(row + t, kf + k - 1) = -wf(t - k);
          }
          if (estimate_ic_ && ni > 0) {
            Eigen::VectorXd impulse = Eigen::VectorXd::Zero(N);
            if (N > 0) impulse(0) = 1.0;
            const Eigen::VectorXd h = filter(Eigen::VectorXd::Ones(1), fpoly[i], impulse);
            for (int j = 0; j < ni && j < N; ++j) J->col(kic + j).segment(row + j, N - j) = h.head(N - j);
          }
        }
        kb += nb;
        kf += nf;
        if (estimate_ic_) kic += ni;
      }
      if (J && offset_) J->col(nbf_).segment(row, N).setOnes();
      r.segment(row, N) = yhat - ex.y().col(0);
      row += N;
    }
    return r.allFinite();
  }

 private:
  const Dataset& data_;
  OeOrders o_;
  bool offset_, estimate_ic_;
  int m_ = 0, nb_total_ = 0, nbf_ = 0, ic_per_exp_ = 0, n_ = 0;
  Eigen::Index rows_ = 0;
};

// Stable version of a monic polynomial: unstable roots reflected, roots on the circle pulled in.
inline Eigen::VectorXd stable_polynomial(const Eigen::VectorXd& p) {
  Eigen::VectorXd q = reflect_unstable(p);
  if (q.size() > 1 && !is_stable_polynomial(q)) {
    Eigen::VectorXcd r = roots(q);
    for (Eigen::Index k = 0; k < r.size(); ++k)
      if (std::abs(r(k)) >= 0.999) r(k) *= 0.999 / std::abs(r(k));
    Eigen::VectorXd s = poly_from_roots(r);
    q.setZero();
    q.head(s.size()) = s;
  }
  return q;
}

inline void check_oe_orders(const OeOrders& o, int num_inputs) {
  const std::string who = "oe";
  require(o.nb.size() == o.nf.size() && o.nb.size() == o.nk.size(),
          who + ": nb, nf and nk have " + std::to_string(o.nb.size()) + ", " +
              std::to_string(o.nf.size()) + " and " + std::to_string(o.nk.size()) +
              " entries; give one of each per input",
          at_parameter("nk"));
  require(o.num_inputs() == num_inputs,
          who + ": orders " + o.str() + " are for " + std::to_string(o.num_inputs()) +
              " input(s) but the data have " + std::to_string(num_inputs),
          at_parameter("nb"));
  for (std::size_t i = 0; i < o.nb.size(); ++i) {
    const std::string idx = o.nb.size() > 1 ? "[" + std::to_string(i) + "]" : "";
    require(o.nb[i] >= 1, who + ": nb must be >= 1, got " + std::to_string(o.nb[i]),
            at_parameter("nb" + idx));
    require(o.nf[i] >= 0, who + ": nf must be >= 0, got " + std::to_string(o.nf[i]),
            at_parameter("nf" + idx));
    require(o.nk[i] >= 0, who + ": nk must be >= 0, got " + std::to_string(o.nk[i]),
            at_parameter("nk" + idx));
    for (const auto& [v, name] : {std::pair{o.nb[i], "nb"}, std::pair{o.nf[i], "nf"}, std::pair{o.nk[i], "nk"}})
      require(v <= max_model_order,
              who + ": " + name + " = " + std::to_string(v) + " is beyond the largest order " +
                  std::to_string(max_model_order),
              at_parameter(name + idx));
  }
}

inline OutputError oe_estimate(const Dataset& data, const OeOrders& o, const OeOptions& opt) {
  const std::string who = "oe";
  require(data.size() > 0, who + ": the data set is empty", at_parameter("data"));
  require(data.num_outputs() == 1,
          who + ": OE models have one output but the data have " +
              std::to_string(data.num_outputs()) + "; estimate one model per output column",
          at_parameter("outputs"));
  check_oe_orders(o, data.num_inputs());
  require(opt.initial_state == InitialCondition::zero ||
              opt.initial_state == InitialCondition::estimate,
          who + ": OeOptions::initial_state must be InitialCondition::zero or ::estimate",
          at_parameter("initial_state"));
  require(opt.steiglitz_mcbride_iterations >= 0,
          who + ": steiglitz_mcbride_iterations must be >= 0",
          at_parameter("steiglitz_mcbride_iterations"));
  int max_lag = 0;
  for (std::size_t i = 0; i < o.nb.size(); ++i) max_lag = std::max(max_lag, o.block_order(i));
  int d = opt.offset ? 1 : 0;
  for (std::size_t i = 0; i < o.nb.size(); ++i) d += o.nb[i] + o.nf[i];
  for (std::size_t e = 0; e < data.size(); ++e) {
    const Experiment& ex = data[e];
    check_linear_experiment(ex, o.num_inputs(), 1, 0.0, static_cast<long>(e), who, true);
    ex.require_estimable_scale(who, static_cast<long>(e));
    if (ex.size() <= max_lag)
      throw Error(who + ": " + linear_experiment_label(ex, static_cast<long>(e)) + " has " +
                      std::to_string(ex.size()) + " samples but orders " + o.str() +
                      " need more than " + std::to_string(max_lag),
                  at_experiment(static_cast<long>(e)));
  }
  // The initial-condition terms are parameters of the fit too: with them counted, N ≤ d would
  // leave no residual degree of freedom (an exact, meaningless fit and σ² = 0/0).
  int d_ic = 0;
  if (opt.initial_state == InitialCondition::estimate)
    for (std::size_t i = 0; i < o.nb.size(); ++i)
      d_ic += o.block_order(i) * static_cast<int>(data.size());
  require(data.total_samples() > d + d_ic,
          who + ": " + std::to_string(data.total_samples()) + " samples for " +
              std::to_string(d + d_ic) + " parameters (" + std::to_string(d) + " model" +
              (d_ic > 0 ? " + " + std::to_string(d_ic) + " initial-condition" : std::string()) +
              "); more samples than parameters are needed (more data or lower orders)",
          at_parameter("data"));

  const int m = o.num_inputs();
  const std::size_t ne = data.size();
  OutputError model;
  model.ts_ = data.ts();
  model.nk_ = o.nk;
  model.input_names_ = data[0].input_names();
  if (data[0].output_names().size() == 1) model.output_names_ = data[0].output_names();
  model.b_.assign(static_cast<std::size_t>(m), Eigen::VectorXd());
  model.f_.assign(static_cast<std::size_t>(m), Eigen::VectorXd());
  for (std::size_t i = 0; i < static_cast<std::size_t>(m); ++i) {
    model.b_[i] = Eigen::VectorXd::Zero(o.nb[i]);
    model.f_[i] = Eigen::VectorXd::Zero(o.nf[i]);
  }

  // ---- Stage 1: Steiglitz–McBride with backfitting over the inputs --------------------------
  // Current simulated contribution of each input per experiment (zero before the first sweep).
  std::vector<std::vector<Eigen::VectorXd>> contrib(
      ne, std::vector<Eigen::VectorXd>(static_cast<std::size_t>(m)));
  for (std::size_t e = 0; e < ne; ++e)
    for (auto& c : contrib[e]) c = Eigen::VectorXd::Zero(data[e].size());
  // Means are removed in stage 1 so the offset does not leak into B/F; c is fitted afterwards.
  std::vector<double> ymean(ne, 0.0);
  std::vector<Eigen::RowVectorXd> umean(ne);
  for (std::size_t e = 0; e < ne; ++e) {
    ymean[e] = opt.offset ? data[e].y().col(0).mean() : 0.0;
    umean[e] = opt.offset ? Eigen::RowVectorXd(data[e].u().colwise().mean())
                          : Eigen::RowVectorXd::Zero(m);
  }
  const int sweeps = m == 1 ? 1 : 4;
  int sm_done = 0;
  for (int sweep = 0; sweep < sweeps; ++sweep) {
    for (std::size_t i = 0; i < static_cast<std::size_t>(m); ++i) {
      Eigen::VectorXd fpoly = Eigen::VectorXd::Ones(1);
      const int iters = std::max(1, opt.steiglitz_mcbride_iterations);
      Eigen::VectorXd prev;
      // What block i must explain, and its input, per experiment (fixed during its iterations).
      std::vector<Eigen::VectorXd> targets(ne), inputs(ne);
      for (std::size_t e = 0; e < ne; ++e) {
        const Experiment& ex = data[e];
        targets[e] = ex.y().col(0).array() - ymean[e];
        for (std::size_t j = 0; j < static_cast<std::size_t>(m); ++j)
          if (j != i) targets[e] -= contrib[e][j];
        inputs[e] = ex.u().col(static_cast<Eigen::Index>(i)).array() - umean[e](static_cast<Eigen::Index>(i));
      }
      // The start is the iterate with the least simulation error, not the last one: the
      // fixed point is the OE estimate only for a linear plant with white output noise. On a
      // nonlinear plant (the throttle) the iterates can drift to a pole near z = 1 whose
      // simulation is far worse than the first, plain ARX pass, and the refinement then stays
      // near that boundary (oe [2 2 0] ended at fit 55 % where the ARX start gives 61 %).
      double best_cost = std::numeric_limits<double>::infinity();
      Eigen::VectorXd best_b, best_f;
      for (int it = 0; it < iters; ++it) {
        Dataset filtered;
        for (std::size_t e = 0; e < ne; ++e) {
          const Experiment& ex = data[e];
          // The first (plain ARX) pass uses F = 1; later passes prefilter by the current 1/F.
          Eigen::MatrixXd uf(ex.size(), 1), yf(ex.size(), 1);
          uf.col(0) = filter(Eigen::VectorXd::Ones(1), fpoly, inputs[e]);
          yf.col(0) = filter(Eigen::VectorXd::Ones(1), fpoly, targets[e]);
          filtered.add(Experiment(std::move(uf), std::move(yf), ex.ts(), ex.name()));
        }
        const Arx step =
            arx_estimate(filtered, ArxOrders(o.nf[i], o.nb[i], o.nk[i]), ArxOptions{}, 0, who, nullptr);
        Eigen::VectorXd fnew(o.nf[i] + 1);
        fnew << 1.0, step.a();
        fpoly = stable_polynomial(fnew);
        model.f_[i] = fpoly.tail(o.nf[i]);
        model.b_[i] = step.b(0);
        Eigen::VectorXd cur(o.nb[i] + o.nf[i]);
        cur << model.b_[i], model.f_[i];
        ++sm_done;
        double cost = 0.0;
        for (std::size_t e = 0; e < ne; ++e)
          cost += (model.block_response(static_cast<int>(i), inputs[e], nullptr) - targets[e]).squaredNorm();
        if (std::isfinite(cost) && cost < best_cost) {
          best_cost = cost;
          best_b = model.b_[i];
          best_f = model.f_[i];
        }
        if (o.nf[i] == 0) break;  // FIR: the first least-squares fit is the OE estimate
        if (prev.size() == cur.size() && (cur - prev).norm() <= 1e-9 * (1.0 + cur.norm())) break;
        if (it + 1 >= opt.steiglitz_mcbride_iterations) break;
        prev = cur;
      }
      if (best_b.size() > 0) {
        model.b_[i] = best_b;
        model.f_[i] = best_f;
      }
      for (std::size_t e = 0; e < ne; ++e) {
        const Eigen::VectorXd ui = data[e].u().col(static_cast<Eigen::Index>(i)).array() - umean[e](static_cast<Eigen::Index>(i));
        contrib[e][i] = model.block_response(static_cast<int>(i), ui, nullptr);
      }
    }
  }
  // Offset: mean of what the dynamics leave unexplained.
  model.has_offset_ = opt.offset;
  if (opt.offset) {
    double s = 0;
    Eigen::Index n = 0;
    for (std::size_t e = 0; e < ne; ++e) {
      Eigen::VectorXd r = data[e].y().col(0);
      for (int i = 0; i < m; ++i)
        r -= model.block_response(i, data[e].u().col(i), nullptr);
      s += r.sum();
      n += r.size();
    }
    model.offset_ = s / static_cast<double>(n);
  }

  // ---- Stage 2: prediction-error refinement --------------------------------------------------
  const bool est_ic = opt.initial_state == InitialCondition::estimate;
  OePemProblem problem(data, o, opt.offset, est_ic);
  std::vector<Eigen::VectorXd> gamma;
  if (est_ic) {
    for (std::size_t e = 0; e < ne; ++e) {
      const Eigen::Index N = data[e].size();
      Eigen::MatrixXd zero = model.simulate(data[e], InitialCondition::zero);
      const Eigen::MatrixXd g = model.free_responses(N);
      gamma.push_back(detail::solve_least_squares_qr(g, data[e].y().col(0) - zero.col(0)).theta);
    }
  }
  Eigen::VectorXd theta = problem.pack(model.b_, model.f_, model.offset_, gamma);
  LmSummary summary;
  bool refined = false;
  if (opt.refine) {
    LmOptions lm = opt.lm;
    if (lm.parameter_names.empty()) {
      lm.parameter_names = model.parameter_names();
      for (std::size_t e = 0; e < ne && est_ic; ++e)
        for (int i = 0; i < m; ++i)
          for (int j = 0; j < o.block_order(static_cast<std::size_t>(i)); ++j)
            lm.parameter_names.push_back("x0[e" + std::to_string(e) + ",u" + std::to_string(i + 1) +
                                         "," + std::to_string(j) + "]");
    }
    summary = solve_least_squares(problem, theta, lm);
    refined = true;
  }
  double c = 0;
  problem.unpack(theta, model.b_, model.f_, c);
  model.offset_ = c;

  // Residuals, fit and standard deviations at the final θ.
  Eigen::VectorXd r(problem.num_residuals());
  Eigen::MatrixXd jac(problem.num_residuals(), problem.num_parameters());
  require(problem.evaluate(theta, r, &jac),
          who + ": the estimated model cannot be simulated (unstable F); try other orders",
          at_parameter("nf"));
  const Eigen::Index N = r.size();
  const int dall = problem.num_parameters();
  const double ssr = r.squaredNorm();
  const LeastSquaresSolution cov = solve_least_squares_qr(jac, r);
  const double sigma2 = ssr / static_cast<double>(N - dall);
  // The γ columns take part (B/F's uncertainty includes not knowing the initial state); when
  // they are collinear among themselves (two FIR blocks) only the γ become "not identifiable".
  model.stddev_ = stddev_from_variance(
      sigma2, cov.unscaled_variance.head(problem.num_model_parameters()));
  Eigen::VectorXd yall(N);
  Eigen::Index row = 0;
  for (const auto& ex : data) {
    yall.segment(row, ex.size()) = ex.y().col(0);
    row += ex.size();
  }
  LinearEstimationReport& rep = model.report_;
  rep.method = "Steiglitz-McBride (" + std::to_string(sm_done) + " iterations)" +
               (refined ? " + prediction-error minimisation (Levenberg-Marquardt)" : "") +
               (est_ic ? ", initial conditions estimated" : ", zero initial conditions");
  rep.focus = "simulation";
  rep.num_experiments = static_cast<int>(ne);
  rep.num_samples = N;
  rep.num_parameters = dall;
  rep.loss = ssr / static_cast<double>(N);
  rep.set_fit(fit_percent_per_output(yall, r, 1));
  rep.iterations = refined ? summary.iterations : 0;
  rep.solver_message = refined ? summary.message() : std::string();
  return model;
}

}  // namespace detail

/// Estimates an output-error model (Steiglitz–McBride start, Levenberg–Marquardt refinement; see
/// file comment) on single- or multi-experiment data. Throws `nlid::Error` for invalid orders,
/// channel-count mismatches, experiments too short for the orders (naming them), missing
/// samples, or a rank-deficient start (input not persistently exciting).
inline OutputError oe(const Dataset& data, const OeOrders& orders, const OeOptions& options = {}) {
  return detail::oe_estimate(data, orders, options);
}

}  // namespace nlid
