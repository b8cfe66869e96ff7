#pragma once
/// @file
/// ARX models: estimation by linear least squares, simulation, k-step prediction.
///
/// Model (Ljung 1999, eq. 4.7 and 4.10), single output, m inputs:
///
///     A(q) y(t) = Σᵢ Bᵢ(q) uᵢ(t − nkᵢ) + c + e(t)
///     A(q)  = 1 + a₁q⁻¹ + … + a_na q⁻ⁿᵃ
///     Bᵢ(q) = bᵢ,₀ + bᵢ,₁q⁻¹ + … + bᵢ,nbᵢ₋₁ q⁻⁽ⁿᵇⁱ⁻¹⁾
///
/// orders [na nb nk] (nb, nk one entry per input), an optional constant c ("offset", e.g. the
/// 15° rest angle of the throttle), and white equation error e. The one-step predictor is linear
/// in θ = [a₁ … a_na, b₁,₀ … , c]ᵀ (Ljung 1999, eq. 4.11–4.13):
///
///     ŷ(t|θ) = φ(t)ᵀθ,   φ(t) = [−y(t−1) … −y(t−na), u₁(t−nk₁) … u₁(t−nk₁−nb₁+1), …, 1]ᵀ
///
/// so the prediction-error estimate is the linear least-squares solution of Φθ ≈ Y (eq. 7.34).
/// nlid solves it by Householder QR with column pivoting on the column-equilibrated Φ, never by
/// the normal equations ΦᵀΦθ = ΦᵀY, which square the condition number (Golub & Van Loan 2013,
/// §5.3.7). Rows are built per experiment and start at t = n with n = max(na, nkᵢ + nbᵢ − 1) (the
/// largest lag), so no row straddles the boundary between two experiments (Ljung 1999, §14.3).
///
/// Parameter standard deviations: Cov θ = σ² (ΦᵀΦ)⁻¹, σ² = ‖Y − Φθ‖²/(N − d) (eq. 9.17),
/// computed from the triangular factor R of the QR factorisation.
///
/// Simulation (free run) ŷ(t) = Σ Bᵢ/A uᵢ(t − nkᵢ) + c/A from the chosen `InitialCondition`:
/// - `zero`: outputs and inputs before t = 0 are zero;
/// - `equilibrium`: past inputs equal u(0), past outputs the matching steady state
///   (Σ Bᵢ(1) uᵢ(0) + c) / A(1);
/// - `estimate`: any initial state of the n-th order recursion adds a free response
///   Σⱼ γⱼ h(t − j), j < n, with h the impulse response of 1/A. The n numbers γ are fitted by
///   least squares to the whole measured record (they are linear in the output);
/// - `measured`: the first n measured outputs serve as past data: ŷ(t) = y(t) for t < n, after
///   which the model runs on its own outputs.
/// k-step prediction ŷ(t | t − k) uses measured outputs up to t − k and the model's own
/// predictions after that (Ljung 1999, eq. 3.31); the first n samples are measured past data as
/// with `measured`. k = 1 is the one-step predictor, k = `infinite_horizon` the simulation.

#include <algorithm>
#include <cmath>
#include <locale>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/QR>

#include "nlid/core/error.hpp"
#include "nlid/core/sizes.hpp"
#include "nlid/core/initial_condition.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/data/experiment.hpp"
#include "nlid/linear/concepts.hpp"
#include "nlid/linear/detail/checks.hpp"
#include "nlid/linear/detail/least_squares.hpp"
#include "nlid/linear/polynomial.hpp"
#include "nlid/linear/report.hpp"
#include "nlid/linear/state_space.hpp"

namespace nlid {

/// ARX orders [na nb nk]: nb and nk have one entry per input.
struct ArxOrders {
  int na = 0;           ///< number of poles (A coefficients after the leading 1)
  std::vector<int> nb;  ///< per input: number of B coefficients (0 = input not used)
  std::vector<int> nk;  ///< per input: input delay in samples

  /// No orders (invalid until filled in).
  ArxOrders() = default;
  /// Single-input orders [na nb nk].
  ArxOrders(int na_, int nb_, int nk_) : na(na_), nb{nb_}, nk{nk_} {}
  /// Multi-input orders [na [nb₁ …] [nk₁ …]].
  ArxOrders(int na_, std::vector<int> nb_, std::vector<int> nk_)
      : na(na_), nb(std::move(nb_)), nk(std::move(nk_)) {}

  /// Number of inputs the orders are written for.
  [[nodiscard]] int num_inputs() const { return static_cast<int>(nb.size()); }
  /// Number of polynomial coefficients d = na + Σ nbᵢ.
  [[nodiscard]] int num_coefficients() const {
    int d = na;
    for (int b : nb) d += b;
    return d;
  }
  /// Largest lag n = max(na, nkᵢ + nbᵢ − 1): samples needed before the first regression row.
  [[nodiscard]] int max_lag() const {
    int n = na;
    for (std::size_t i = 0; i < nb.size() && i < nk.size(); ++i)
      if (nb[i] > 0) n = std::max(n, nk[i] + nb[i] - 1);
    return n;
  }
  /// "[2 1 0]" or "[2 [1 2] [0 1]]", as the toolbox writes orders.
  [[nodiscard]] std::string str() const {
    auto list = [](const std::vector<int>& v) {
      if (v.size() == 1) return std::to_string(v[0]);
      std::string s = "[";
      for (std::size_t i = 0; i < v.size(); ++i) s += (i ? " " : "") + std::to_string(v[i]);
      return s + "]";
    };
    return "[" + std::to_string(na) + " " + list(nb) + " " + list(nk) + "]";
  }
};

/// Options of `arx`.
struct ArxOptions {
  bool offset = false;  ///< estimate the constant c in A y = B u + c + e
};

class Arx;
namespace detail {
inline Arx arx_estimate(const Dataset& data, const ArxOrders& o, const ArxOptions& opt,
                        int min_start, const std::string& who, bool* rank_deficient);
}  // namespace detail

/// An ARX model A(q) y(t) = Σ Bᵢ(q) uᵢ(t − nkᵢ) + c + e(t) (see file comment).
/// Invariant: one `b`/`nk` entry per input, nk ≥ 0, ts > 0.
class Arx {
 public:
  /// Empty model (no inputs).
  Arx() = default;

  /// Model from its coefficients: `a` = [a₁ … a_na] (without the leading 1), `b[i]` =
  /// [bᵢ,₀ … bᵢ,nbᵢ₋₁] acting on uᵢ(t − nkᵢ − j), delays `nk`, sample time `ts`, offset `c`.
  /// Throws `nlid::Error` naming the offending argument.
  Arx(Eigen::VectorXd a, std::vector<Eigen::VectorXd> b, std::vector<int> nk, double ts,
      double c = 0.0)
      : a_(std::move(a)), b_(std::move(b)), nk_(std::move(nk)), ts_(ts), offset_(c) {
    require(b_.size() == nk_.size(),
            "Arx: " + std::to_string(b_.size()) + " B polynomials but " +
                std::to_string(nk_.size()) + " delays; give one of each per input",
            at_parameter("nk"));
    for (std::size_t i = 0; i < nk_.size(); ++i)
      require(nk_[i] >= 0 && nk_[i] <= max_model_order,
              "Arx: delay nk must be in 0 ... " + std::to_string(max_model_order) + ", got " + std::to_string(nk_[i]),
              at_parameter("nk[" + std::to_string(i) + "]"));
    require(a_.size() <= max_model_order, "Arx: more than " + std::to_string(max_model_order) + " A coefficients",
            at_parameter("a"));
    for (std::size_t i = 0; i < b_.size(); ++i)
      require(b_[i].size() <= max_model_order,
              "Arx: more than " + std::to_string(max_model_order) + " B coefficients",
              at_parameter("b[" + std::to_string(i) + "]"));
    require(ts_ > 0 && std::isfinite(ts_), "Arx: sample time must be positive",
            at_parameter("ts"));
    bool finite = a_.allFinite() && std::isfinite(offset_);
    for (const auto& bi : b_) finite = finite && bi.allFinite();
    require(finite, "Arx: coefficients must be finite", at_parameter("a, b"));
    has_offset_ = offset_ != 0.0;
    stddev_ = Eigen::VectorXd::Zero(num_parameters());
  }

  /// Number of inputs.
  [[nodiscard]] int num_inputs() const { return static_cast<int>(b_.size()); }
  /// Always 1: ARX models here are single-output (estimate one per output column).
  [[nodiscard]] int num_outputs() const { return 1; }
  /// Sample time (s).
  [[nodiscard]] double ts() const { return ts_; }
  /// Orders [na nb nk].
  [[nodiscard]] ArxOrders orders() const {
    ArxOrders o;
    o.na = na();
    for (const auto& bi : b_) o.nb.push_back(static_cast<int>(bi.size()));
    o.nk = nk_;
    return o;
  }
  /// na.
  [[nodiscard]] int na() const { return static_cast<int>(a_.size()); }
  /// nb of input `i`.
  [[nodiscard]] int nb(int i = 0) const { return static_cast<int>(b_.at(checked(i)).size()); }
  /// nk of input `i`.
  [[nodiscard]] int nk(int i = 0) const { return nk_.at(checked(i)); }
  /// Free A coefficients [a₁ … a_na].
  [[nodiscard]] const Eigen::VectorXd& a() const { return a_; }
  /// Free B coefficients of input `i`: [bᵢ,₀ … bᵢ,nbᵢ₋₁] (they act on uᵢ(t − nkᵢ − j)).
  [[nodiscard]] const Eigen::VectorXd& b(int i = 0) const { return b_.at(checked(i)); }
  /// Offset c (0 unless estimated or given).
  [[nodiscard]] double offset() const { return offset_; }
  /// True if the model has an offset term (estimated with `offset = true` or c ≠ 0 given).
  [[nodiscard]] bool has_offset() const { return has_offset_; }
  /// A(q) = [1, a₁, …, a_na] (toolbox convention).
  [[nodiscard]] Eigen::VectorXd a_polynomial() const {
    Eigen::VectorXd p(na() + 1);
    p << 1.0, a_;
    return p;
  }
  /// q^(−nkᵢ) Bᵢ(q) = [0 … 0 (nkᵢ zeros), bᵢ,₀, …] (toolbox convention).
  [[nodiscard]] Eigen::VectorXd b_polynomial(int i = 0) const {
    const auto& bi = b(i);
    Eigen::VectorXd p = Eigen::VectorXd::Zero(nk(i) + bi.size());
    p.tail(bi.size()) = bi;
    return p;
  }

  /// All parameters θ = [a; b₁; …; bₘ; c (if has_offset)] in regression order.
  [[nodiscard]] Eigen::VectorXd parameters() const {
    Eigen::VectorXd th(num_parameters());
    Eigen::Index k = 0;
    th.segment(k, na()) = a_;
    k += na();
    for (const auto& bi : b_) {
      th.segment(k, bi.size()) = bi;
      k += bi.size();
    }
    if (has_offset_) th(k) = offset_;
    return th;
  }
  /// Number of parameters d.
  [[nodiscard]] int num_parameters() const {
    int d = na() + (has_offset_ ? 1 : 0);
    for (const auto& bi : b_) d += static_cast<int>(bi.size());
    return d;
  }
  /// Names in the order of `parameters()`: a1…, then b<power of q⁻¹> (SISO) or
  /// b<input>_<power> (several inputs), then c.
  [[nodiscard]] std::vector<std::string> parameter_names() const {
    std::vector<std::string> names;
    for (int k = 1; k <= na(); ++k) names.push_back("a" + std::to_string(k));
    for (int i = 0; i < num_inputs(); ++i)
      for (int j = 0; j < nb(i); ++j)
        names.push_back(num_inputs() == 1 ? "b" + std::to_string(nk_[i] + j)
                                          : "b" + std::to_string(i + 1) + "_" +
                                                std::to_string(nk_[i] + j));
    if (has_offset_) names.push_back("c");
    return names;
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
    detail::check_parameter_stddev(sd, parameter_names(), "Arx");
    stddev_ = std::move(sd);
  }

  /// Poles: roots of A.
  [[nodiscard]] Eigen::VectorXcd poles() const { return roots(a_polynomial()); }
  /// Zeros of input `i`: roots of Bᵢ (delays give no finite zero).
  [[nodiscard]] Eigen::VectorXcd zeros(int i = 0) const { return roots(b(i)); }
  /// Frequency response q^(−nk) Bᵢ/A at e^{iωTs} for `w` in rad/s.
  [[nodiscard]] Eigen::VectorXcd frequency_response(const Eigen::VectorXd& w, int i = 0) const {
    return nlid::frequency_response(b_polynomial(i), a_polynomial(), w, ts_);
  }
  /// Static gain Bᵢ(1)/A(1). Throws if A has a root at z = 1.
  [[nodiscard]] double dc_gain(int i = 0) const {
    const double a1 = a_polynomial().sum();
    require(std::abs(a1) > 1e-14, "Arx::dc_gain: A(q) has a root at z = 1 (integrator)");
    return b(i).sum() / a1;
  }
  /// Input-output transfer function of input `i`: q^(−nk) Bᵢ(q) / A(q).
  [[nodiscard]] TransferFunction to_transfer_function(int i = 0) const {
    return TransferFunction{b_polynomial(i), a_polynomial(), ts_};
  }
  /// Observer-canonical state-space form with n = max(na, nkᵢ + nbᵢ − 1) states (Ljung 1999,
  /// eq. 4.91). The offset maps to the output offset y₀ = c/A(1): the same steady state, and the
  /// same output whenever the initial state is estimated (c's transient is a free response).
  [[nodiscard]] StateSpace to_state_space() const {
    const int n = orders().max_lag();
    const int m = num_inputs();
    Eigen::VectorXd a = Eigen::VectorXd::Zero(n + 1);
    a.head(na() + 1) = a_polynomial();
    Eigen::MatrixXd beta = Eigen::MatrixXd::Zero(n + 1, m);  // column i: padded q^-nk B_i
    for (int i = 0; i < m; ++i) {
      const Eigen::VectorXd bp = b_polynomial(i);
      beta.col(i).head(bp.size()) = bp;
    }
    Eigen::MatrixXd A = Eigen::MatrixXd::Zero(n, n), B(n, m), C = Eigen::MatrixXd::Zero(1, n);
    for (int k = 0; k < n; ++k) {
      A(k, 0) = -a(k + 1);
      if (k + 1 < n) A(k, k + 1) = 1.0;
      B.row(k) = beta.row(k + 1) - a(k + 1) * beta.row(0);
    }
    if (n > 0) C(0, 0) = 1.0;
    StateSpace ss(A, B, C, beta.row(0), ts_);
    if (has_offset_) {
      const double a1 = a.sum();
      require(std::abs(a1) > 1e-14,
              "Arx::to_state_space: an offset with a root of A at z = 1 has no steady state");
      ss.set_offset(Eigen::VectorXd::Constant(1, offset_ / a1));
    }
    return ss;
  }

  /// Free-run output (N x 1) for the inputs of `e` (see file comment for `ic`). Throws
  /// `nlid::Error` if `e` has a different number of inputs or sample time, or (for `estimate`,
  /// `measured`) not exactly one finite output.
  [[nodiscard]] Eigen::MatrixXd simulate(const Experiment& e,
                                         InitialCondition ic = InitialCondition::zero) const {
    const bool need_y = ic == InitialCondition::estimate || ic == InitialCondition::measured;
    detail::check_linear_experiment(e, num_inputs(), 1, ts_, -1, "Arx::simulate", need_y);
    detail::check_linear_channel_order(e, *this, "Arx::simulate");
    const Eigen::Index N = e.size();
    Eigen::MatrixXd y(N, 1);
    switch (ic) {
      case InitialCondition::zero:
        run(e.u(), 0.0, Eigen::RowVectorXd::Zero(num_inputs()), nullptr, 0, y.col(0));
        break;
      case InitialCondition::equilibrium: {
        if (N == 0) break;
        const Eigen::RowVectorXd u0 = e.u().row(0);
        const double a1 = a_polynomial().sum();
        double drive = offset_;
        for (int i = 0; i < num_inputs(); ++i) drive += b_[i].sum() * u0(i);
        require(std::abs(a1) > 1e-14 || drive == 0.0,
                "Arx::simulate: no equilibrium: A(q) has a root at z = 1 (integrator); use "
                "InitialCondition::zero or ::estimate",
                at_parameter("InitialCondition::equilibrium"));
        run(e.u(), std::abs(a1) > 1e-14 ? drive / a1 : 0.0, u0, nullptr, 0, y.col(0));
        break;
      }
      case InitialCondition::measured:
        run(e.u(), 0.0, Eigen::RowVectorXd::Zero(num_inputs()), &e.y(), orders().max_lag(),
            y.col(0));
        break;
      case InitialCondition::estimate:
        y.col(0) = simulate_estimated(e);
        break;
    }
    return y;
  }

  /// k-step-ahead prediction ŷ(t | t − k) (N x 1); k = 1 one step, `infinite_horizon` (or any
  /// k ≥ N) the simulation from measured past data. Throws for k < 1 or unusable data.
  [[nodiscard]] Eigen::MatrixXd predict(const Experiment& e, int k) const {
    require(k >= 1, "Arx::predict: horizon k must be >= 1, got " + std::to_string(k),
            at_parameter("k"));
    detail::check_linear_experiment(e, num_inputs(), 1, ts_, -1, "Arx::predict", true);
    detail::check_linear_channel_order(e, *this, "Arx::predict");
    const Eigen::Index N = e.size();
    if (static_cast<Eigen::Index>(k) >= N) return simulate(e, InitialCondition::measured);
    const Eigen::Index n = std::min<Eigen::Index>(orders().max_lag(), N);
    const Eigen::MatrixXd& u = e.u();
    const auto y = e.y().col(0);
    Eigen::MatrixXd out(N, 1);
    out.col(0).head(n) = y.head(n);
    std::vector<double> chain(static_cast<std::size_t>(k));  // predictions at s = t−k+1 … t
    for (Eigen::Index t = n; t < N; ++t) {
      const Eigen::Index s0 = std::max<Eigen::Index>(n, t - k + 1);
      for (Eigen::Index s = s0; s <= t; ++s) {
        double acc = offset_;
        for (int j = 1; j <= na(); ++j) {
          const Eigen::Index r = s - j;
          const double past = r >= s0 ? chain[static_cast<std::size_t>(r - s0)] : y(r);
          acc -= a_(j - 1) * past;
        }
        acc += input_drive(u, s, Eigen::RowVectorXd());
        chain[static_cast<std::size_t>(s - s0)] = acc;
      }
      out(t, 0) = chain[static_cast<std::size_t>(t - s0)];
    }
    return out;
  }

  /// Toolbox-style description: equation, A and B with standard deviations, poles, report.
  [[nodiscard]] std::string describe() const {
    std::ostringstream os;
    os.imbue(std::locale::classic());  // a global locale's grouping or decimal comma must not reach the text
    const int m = num_inputs();
    os << "Discrete-time ARX model, orders [na nb nk] = " << orders().str() << ":\n  A(q)y(t) = ";
    for (int i = 0; i < m; ++i) os << (i ? " + " : "") << bname(i) << "(q)" << uname(i) << "(t)";
    if (m == 0) os << "0";
    os << (has_offset_ ? " + c" : "") << " + e(t)\n";
    const Eigen::VectorXd sd = stddev_.size() == num_parameters()
                                   ? stddev_
                                   : Eigen::VectorXd::Zero(num_parameters());
    Eigen::VectorXd sa(na() + 1);
    sa << 0.0, sd.head(na());
    os << "  A(q) = " << format_polynomial(a_polynomial(), 4, "q", &sa) << "\n";
    Eigen::Index k = na();
    for (int i = 0; i < m; ++i) {
      Eigen::VectorXd sb = Eigen::VectorXd::Zero(nk_[i] + b_[i].size());
      sb.tail(b_[i].size()) = sd.segment(k, b_[i].size());
      k += b_[i].size();
      os << "  " << bname(i) << "(q) = " << format_polynomial(b_polynomial(i), 4, "q", &sb)
         << "\n";
    }
    if (has_offset_) {
      os << "  c = " << format_number(offset_, 4);
      os << format_stddev(sd(k));
      os << "\n";
    }
    os << "Poles: " << describe_roots(a_polynomial()) << "\n";  // not factored past max_described_root_degree
    os << "Sample time: " << format_number(ts_, 6) << " s\n";
    if (!report_.method.empty()) os << report_.str();
    return os.str();
  }

  /// Input channel names (from the estimation data; "u1", … otherwise).
  [[nodiscard]] std::vector<std::string> input_names() const { return input_names_; }
  /// Sets the input channel names shown by `describe()`.
  void set_input_names(std::vector<std::string> names) {
    require(names.size() == b_.size(), "Arx: one input name per input required",
            at_parameter("input_names"));
    input_names_ = std::move(names);
  }
  /// Output channel name as a one-entry list (from the estimation data; empty if unknown).
  [[nodiscard]] std::vector<std::string> output_names() const { return output_names_; }
  /// Sets the output channel name (one entry, or empty for unknown).
  void set_output_names(std::vector<std::string> names) {
    require(names.size() <= 1, "Arx: one output name (or none) required", at_parameter("output_names"));
    output_names_ = std::move(names);
  }

  // ---- Implementation details below ----------------------------------------------------------

 private:
  friend Arx detail::arx_estimate(const Dataset&, const ArxOrders&, const ArxOptions&, int,
                                  const std::string&, bool*);

  std::size_t checked(int i) const {
    require(i >= 0 && i < num_inputs(),
            "Arx: input index " + std::to_string(i) + " out of range (model has " +
                std::to_string(num_inputs()) + " inputs)",
            at_parameter("input"));
    return static_cast<std::size_t>(i);
  }
  std::string bname(int i) const { return num_inputs() == 1 ? "B" : "B" + std::to_string(i + 1); }
  std::string uname(int i) const {
    if (input_names_.size() == b_.size()) return input_names_[static_cast<std::size_t>(i)];
    return num_inputs() == 1 ? "u" : "u" + std::to_string(i + 1);
  }

  // Σᵢ Σⱼ bᵢⱼ uᵢ(s − nkᵢ − j); samples before 0 take `u_past` (zero if empty).
  double input_drive(const Eigen::MatrixXd& u, Eigen::Index s, const Eigen::RowVectorXd& u_past) const {
    double acc = 0.0;
    for (std::size_t i = 0; i < b_.size(); ++i) {
      const auto& bi = b_[i];
      for (Eigen::Index j = 0; j < bi.size(); ++j) {
        const Eigen::Index r = s - nk_[i] - j;
        const double v = r >= 0 ? u(r, static_cast<Eigen::Index>(i))
                                : (u_past.size() ? u_past(static_cast<Eigen::Index>(i)) : 0.0);
        acc += bi(j) * v;
      }
    }
    return acc;
  }

  // The ARX recursion on the model's own outputs. Outputs before t = 0 equal `y_past`, inputs
  // before 0 equal `u_past`; the first `n_copy` outputs are copied from `measured` (past data).
  void run(const Eigen::MatrixXd& u, double y_past, const Eigen::RowVectorXd& u_past,
           const Eigen::MatrixXd* measured, Eigen::Index n_copy, Eigen::Ref<Eigen::VectorXd> y) const {
    const Eigen::Index N = u.rows();
    for (Eigen::Index t = 0; t < N; ++t) {
      if (measured != nullptr && t < n_copy) {
        y(t) = (*measured)(t, 0);
        continue;
      }
      double acc = offset_;
      for (int j = 1; j <= na(); ++j) acc -= a_(j - 1) * (t - j >= 0 ? y(t - j) : y_past);
      acc += input_drive(u, t, u_past);
      y(t) = acc;
    }
  }

  // Zero-state simulation plus the least-squares free response Σⱼ γⱼ h(t − j) (file comment).
  Eigen::VectorXd simulate_estimated(const Experiment& e) const {
    const Eigen::Index N = e.size();
    Eigen::VectorXd y0(N);
    run(e.u(), 0.0, Eigen::RowVectorXd::Zero(num_inputs()), nullptr, 0, y0);
    const Eigen::Index n = std::min<Eigen::Index>(orders().max_lag(), N);
    if (n == 0) return y0;
    Eigen::VectorXd impulse = Eigen::VectorXd::Zero(N);
    impulse(0) = 1.0;
    const Eigen::VectorXd h = filter(Eigen::VectorXd::Ones(1), a_polynomial(), impulse);
    detail::check_free_response(h, "Arx::simulate", "A(q)", [this] { return poles(); });
    Eigen::MatrixXd G = Eigen::MatrixXd::Zero(N, n);
    for (Eigen::Index j = 0; j < n; ++j) G.col(j).tail(N - j) = h.head(N - j);
    const Eigen::VectorXd gamma = detail::solve_least_squares_qr(G, e.y().col(0) - y0).theta;
    return y0 + G * gamma;
  }

  Eigen::VectorXd a_;
  std::vector<Eigen::VectorXd> b_;
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

// Checks orders against the data's input count; messages name the offending order.
inline void check_arx_orders(const ArxOrders& o, int num_inputs, const std::string& who) {
  require(o.na >= 0, who + ": na must be >= 0, got " + std::to_string(o.na), at_parameter("na"));
  require(o.na <= max_model_order,
          who + ": na = " + std::to_string(o.na) + " is beyond the largest order " + std::to_string(max_model_order),
          at_parameter("na"));
  require(o.nb.size() == o.nk.size(),
          who + ": nb has " + std::to_string(o.nb.size()) + " entries but nk has " +
              std::to_string(o.nk.size()) + "; give one of each per input",
          at_parameter("nk"));
  require(o.num_inputs() == num_inputs,
          who + ": orders " + o.str() + " are for " + std::to_string(o.num_inputs()) +
              " input(s) but the data have " + std::to_string(num_inputs) +
              " (give nb and nk per input)",
          at_parameter("nb"));
  for (std::size_t i = 0; i < o.nb.size(); ++i) {
    const std::string idx = o.nb.size() > 1 ? "[" + std::to_string(i) + "]" : "";
    require(o.nb[i] >= 0, who + ": nb must be >= 0, got " + std::to_string(o.nb[i]),
            at_parameter("nb" + idx));
    require(o.nk[i] >= 0, who + ": nk must be >= 0, got " + std::to_string(o.nk[i]),
            at_parameter("nk" + idx));
    require(o.nb[i] <= max_model_order && o.nk[i] <= max_model_order,
            who + ": nb = " + std::to_string(o.nb[i]) + ", nk = " + std::to_string(o.nk[i]) +
                " are beyond the largest order " + std::to_string(max_model_order),
            at_parameter(o.nk[i] > max_model_order ? "nk" + idx : "nb" + idx));
  }
}

// Regression Φθ ≈ Y over all experiments; rows of experiment e are t = start … N_e − 1 with
// start = max(o.max_lag(), min_start). Throws naming an experiment that is too short.
struct ArxRegression {
  Eigen::MatrixXd phi;
  Eigen::VectorXd y;
};

inline ArxRegression arx_regression(const Dataset& data, const ArxOrders& o, bool offset,
                                    int min_start, const std::string& who) {
  const int start = std::max(o.max_lag(), min_start);
  const int d = o.num_coefficients() + (offset ? 1 : 0);
  Eigen::Index rows = 0;
  for (std::size_t e = 0; e < data.size(); ++e) {
    const Experiment& ex = data[e];
    detail::check_linear_experiment(ex, o.num_inputs(), 1, 0.0, static_cast<long>(e), who, true);
    if (ex.size() <= start)
      throw Error(who + ": " + linear_experiment_label(ex, static_cast<long>(e)) + " has " +
                      std::to_string(ex.size()) + " samples but orders " + o.str() + " need more than " +
                      std::to_string(start) + " (the largest lag) to form one regression row",
                  at_experiment(static_cast<long>(e)));
    rows += ex.size() - start;
  }
  ArxRegression r;
  r.phi.resize(rows, d);
  r.y.resize(rows);
  Eigen::Index row = 0;
  for (const Experiment& ex : data) {
    const auto y = ex.y().col(0);
    for (Eigen::Index t = start; t < ex.size(); ++t, ++row) {
      int c = 0;
      for (int j = 1; j <= o.na; ++j) r.phi(row, c++) = -y(t - j);
      for (std::size_t i = 0; i < o.nb.size(); ++i)
        for (int j = 0; j < o.nb[i]; ++j)
          r.phi(row, c++) = ex.u()(t - o.nk[i] - j, static_cast<Eigen::Index>(i));
      if (offset) r.phi(row, c++) = 1.0;
      r.y(row) = y(t);
    }
  }
  return r;
}

}  // namespace detail

/// Estimates an ARX model by linear least squares (QR) on single- or multi-experiment data.
/// Throws `nlid::Error` for negative orders, orders that do not match the number of inputs, more
/// than one output, an experiment too short for the orders (naming it), missing samples, or a
/// rank-deficient regression (input not persistently exciting).
inline Arx arx(const Dataset& data, const ArxOrders& orders, const ArxOptions& options = {}) {
  // The user's records only: OE's Steiglitz-McBride pass runs arx_estimate on filtered signals,
  // whose magnitudes are no sample of the data.
  data.require_estimable_scale("arx");
  return detail::arx_estimate(data, orders, options, 0, "arx", nullptr);
}

namespace detail {

// Estimation on the rows starting at max(largest lag, `min_start`): the order search passes a
// common start so every candidate is scored on the same samples. A rank-deficient regression
// throws, unless `rank_deficient` is given: then it is set and an empty model returned whose
// report still holds N and the loss (a basic solution reaches the least-squares minimum).
inline Arx arx_estimate(const Dataset& data, const ArxOrders& o, const ArxOptions& opt,
                        int min_start, const std::string& who, bool* rank_deficient) {
  if (rank_deficient) *rank_deficient = false;
  require(data.size() > 0, who + ": the data set is empty", at_parameter("data"));
  require(data.num_outputs() == 1,
          who + ": ARX models have one output but the data have " +
              std::to_string(data.num_outputs()) +
              "; estimate one model per output column",
          at_parameter("outputs"));
  check_arx_orders(o, data.num_inputs(), who);
  const int d = o.num_coefficients() + (opt.offset ? 1 : 0);
  require(d > 0, who + ": orders " + o.str() + " leave no parameter to estimate",
          at_parameter("na"));
  const ArxRegression reg = arx_regression(data, o, opt.offset, min_start, who);
  // rows == d would fit exactly: σ² = 0/0, zero standard deviations and a 100 % fit that says
  // nothing about the system.
  require(reg.phi.rows() > d,
          who + ": " + std::to_string(reg.phi.rows()) + " regression rows for " +
              std::to_string(d) + " parameters; more rows than parameters are needed (more data "
              "or lower orders)",
          at_parameter("data"));
  const LeastSquaresSolution sol = solve_least_squares_qr(reg.phi, reg.y);
  if (sol.rank < d && rank_deficient) {
    *rank_deficient = true;
    Arx none;
    none.report_.num_samples = reg.phi.rows();
    none.report_.loss = sol.residual_norm * sol.residual_norm / static_cast<double>(reg.phi.rows());
    return none;
  }
  if (sol.rank < d)
    throw Error(who + ": the regression matrix has rank " + std::to_string(sol.rank) + " < " +
                    std::to_string(d) + " parameters for orders " + o.str() +
                    ": the input is not persistently exciting for these orders, a channel is "
                    "constant, or the orders are redundant",
                at_parameter("nb"));
  Arx m;
  m.ts_ = data.ts();
  m.nk_ = o.nk;
  m.a_ = sol.theta.head(o.na);
  Eigen::Index k = o.na;
  for (int nbi : o.nb) {
    m.b_.push_back(sol.theta.segment(k, nbi));
    k += nbi;
  }
  m.has_offset_ = opt.offset;
  m.offset_ = opt.offset ? sol.theta(k) : 0.0;
  const Eigen::Index N = reg.phi.rows();
  const double ssr = sol.residual_norm * sol.residual_norm;
  const double sigma2 = ssr / static_cast<double>(N - d);
  m.stddev_ = stddev_from_variance(sigma2, sol.unscaled_variance);
  m.input_names_ = data[0].input_names();
  if (data[0].output_names().size() == 1) m.output_names_ = data[0].output_names();
  LinearEstimationReport& r = m.report_;
  r.method = "linear least squares (Householder QR)";
  r.focus = "prediction";
  r.num_experiments = static_cast<int>(data.size());
  r.num_samples = N;
  r.num_parameters = d;
  r.loss = ssr / static_cast<double>(N);
  r.set_fit(fit_percent_per_output(reg.y, reg.phi * sol.theta - reg.y, 1));
  return m;
}

}  // namespace detail

}  // namespace nlid
