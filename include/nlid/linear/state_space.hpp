#pragma once
/// @file
/// Discrete-time linear state-space model (output-error form).
///
///     x(t+1) = A x(t) + B u(t)
///     y(t)   = C x(t) + D u(t) + y₀ + e(t)          (Ljung 1999, eq. 4.84 with K = 0)
///
/// with n states, m inputs, p outputs and an optional constant output offset y₀ (zero unless
/// estimated with `offset = true`). The disturbance is white output noise (K = 0), so the
/// model's k-step predictor for every k equals its simulation from the estimated initial state:
/// this is the "simulation focus" model of the study. Any ARX or OE model converts to this form
/// (`to_state_space()`), so this class is also the common engine for frequency responses and
/// initial-state estimation.
///
/// Transfer function of input j to output i (Ljung 1999, eq. 4.88):
///
///     G_ij(z) = C_i (zI − A)⁻¹ B_j + D_ij
///             = [det(zI − A + B_j C_i) − det(zI − A)] / det(zI − A) + D_ij,
///
/// the second line by the matrix determinant lemma; it gives numerator and denominator from
/// two eigenvalue problems, exactly enough for the small orders of identified models.
///
/// Initial state x(0) of a simulation (`InitialCondition`):
/// - `zero`: x(0) = 0;
/// - `estimate`: x(0) minimising Σ‖y(t) − ŷ(t)‖² over the whole record — linear least squares,
///   since ŷ(t) = ŷ₀(t) + C Aᵗ x(0) (Ljung 1999, §10.4 "initial conditions");
/// - `equilibrium`: the steady state for u(0) held constant, x = (I − A)⁻¹ B u(0);
/// - `measured` is not defined for a state-space model (its state is not a list of past
///   outputs) and throws; use `estimate`.

#include <cmath>
#include <locale>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <Eigen/QR>

#include "nlid/core/error.hpp"
#include "nlid/core/initial_condition.hpp"
#include "nlid/data/experiment.hpp"
#include "nlid/linear/detail/checks.hpp"
#include "nlid/linear/polynomial.hpp"
#include "nlid/linear/report.hpp"

namespace nlid {

/// Discrete-time state-space model x(t+1) = Ax + Bu, y = Cx + Du + y₀ (see file comment).
/// Invariant: A is n x n, B n x m, C p x n, D p x m, y₀ has p entries, ts > 0.
class StateSpace {
 public:
  /// Empty model (0 states, 0 inputs, 0 outputs, ts = 1).
  StateSpace() = default;

  /// Model from its matrices. Throws `nlid::Error` naming the matrix whose size does not fit,
  /// or a non-finite entry, or ts ≤ 0.
  StateSpace(Eigen::MatrixXd a, Eigen::MatrixXd b, Eigen::MatrixXd c, Eigen::MatrixXd d,
             double ts)
      : a_(std::move(a)), b_(std::move(b)), c_(std::move(c)), d_(std::move(d)), ts_(ts) {
    const auto n = a_.rows();
    auto dims = [](const Eigen::MatrixXd& m) {
      return std::to_string(m.rows()) + " x " + std::to_string(m.cols());
    };
    require(a_.cols() == n, "StateSpace: A must be square, got " + dims(a_), at_parameter("A"));
    require(b_.rows() == n, "StateSpace: B must have " + std::to_string(n) + " rows (A is " +
                                dims(a_) + "), got " + dims(b_),
            at_parameter("B"));
    require(c_.cols() == n, "StateSpace: C must have " + std::to_string(n) + " columns (A is " +
                                dims(a_) + "), got " + dims(c_),
            at_parameter("C"));
    require(d_.rows() == c_.rows() && d_.cols() == b_.cols(),
            "StateSpace: D must be " + std::to_string(c_.rows()) + " x " +
                std::to_string(b_.cols()) + " (outputs x inputs), got " + dims(d_),
            at_parameter("D"));
    require(ts_ > 0 && std::isfinite(ts_), "StateSpace: sample time must be positive",
            at_parameter("ts"));
    require(a_.allFinite() && b_.allFinite() && c_.allFinite() && d_.allFinite(),
            "StateSpace: matrices must be finite", at_parameter("A, B, C, D"));
    offset_ = Eigen::VectorXd::Zero(c_.rows());
  }

  /// Number of states n.
  [[nodiscard]] int order() const { return static_cast<int>(a_.rows()); }
  /// Number of inputs m.
  [[nodiscard]] int num_inputs() const { return static_cast<int>(b_.cols()); }
  /// Number of outputs p.
  [[nodiscard]] int num_outputs() const { return static_cast<int>(c_.rows()); }
  /// Sample time (s).
  [[nodiscard]] double ts() const { return ts_; }
  /// State matrix A.
  [[nodiscard]] const Eigen::MatrixXd& a() const { return a_; }
  /// Input matrix B.
  [[nodiscard]] const Eigen::MatrixXd& b() const { return b_; }
  /// Output matrix C.
  [[nodiscard]] const Eigen::MatrixXd& c() const { return c_; }
  /// Feed-through matrix D.
  [[nodiscard]] const Eigen::MatrixXd& d() const { return d_; }
  /// Output offset y₀ (zero unless estimated).
  [[nodiscard]] const Eigen::VectorXd& offset() const { return offset_; }
  /// Sets y₀; throws unless it has one entry per output.
  void set_offset(Eigen::VectorXd y0) {
    require(y0.size() == num_outputs(), "StateSpace: offset needs one entry per output",
            at_parameter("offset"));
    offset_ = std::move(y0);
  }
  /// Input channel names (from the estimation data or a model file; empty if unknown, and then
  /// tools and model files call the inputs u1, u2, …).
  [[nodiscard]] const std::vector<std::string>& input_names() const { return input_names_; }
  /// Sets the input channel names: one per input, or none. Throws naming the count otherwise.
  void set_input_names(std::vector<std::string> names) {
    check_name_count(names, num_inputs(), "input_names", "inputs");
    input_names_ = std::move(names);
  }
  /// Output channel names (empty if unknown: y1, y2, …).
  [[nodiscard]] const std::vector<std::string>& output_names() const { return output_names_; }
  /// Sets the output channel names: one per output, or none.
  void set_output_names(std::vector<std::string> names) {
    check_name_count(names, num_outputs(), "output_names", "outputs");
    output_names_ = std::move(names);
  }
  /// How the model was estimated (empty for a hand-made model).
  [[nodiscard]] const LinearEstimationReport& report() const { return report_; }
  /// Replaces the estimation report (used by the estimators).
  void set_report(LinearEstimationReport r) { report_ = std::move(r); }

  /// Poles: eigenvalues of A.
  [[nodiscard]] Eigen::VectorXcd poles() const {
    if (order() == 0) return Eigen::VectorXcd();
    return Eigen::EigenSolver<Eigen::MatrixXd>(a_, false).eigenvalues();
  }
  /// True if every pole lies strictly inside the unit circle.
  [[nodiscard]] bool is_stable() const {
    const Eigen::VectorXcd p = poles();
    for (Eigen::Index k = 0; k < p.size(); ++k)
      if (!(std::abs(p(k)) < 1.0)) return false;
    return true;
  }

  /// Frequency response G_ij(e^{iωTs}) of input `input` to output `output` at `w` (rad/s).
  [[nodiscard]] Eigen::VectorXcd frequency_response(const Eigen::VectorXd& w, int output = 0,
                                                    int input = 0) const {
    check_pair(output, input);
    const int n = order();
    Eigen::VectorXcd g(w.size());
    for (Eigen::Index k = 0; k < w.size(); ++k) {
      const std::complex<double> z = std::polar(1.0, w(k) * ts_);
      std::complex<double> val = d_(output, input);
      if (n > 0) {
        const Eigen::MatrixXcd m =
            z * Eigen::MatrixXcd::Identity(n, n) - a_.cast<std::complex<double>>();
        const Eigen::VectorXcd x =
            m.partialPivLu().solve(b_.col(input).cast<std::complex<double>>());
        val += (c_.row(output).cast<std::complex<double>>() * x)(0);
      }
      g(k) = val;
    }
    return g;
  }

  /// Static gain C (I − A)⁻¹ B + D (outputs x inputs). Throws if A has a pole at z = 1.
  [[nodiscard]] Eigen::MatrixXd dc_gain() const {
    if (order() == 0) return d_;
    Eigen::FullPivLU<Eigen::MatrixXd> lu(Eigen::MatrixXd::Identity(order(), order()) - a_);
    require(lu.isInvertible(), "StateSpace::dc_gain: A has a pole at z = 1 (integrator)");
    return c_ * lu.solve(b_) + d_;
  }

  /// Transfer function of input `input` to output `output` as B(q)/A(q) in q⁻¹, with A =
  /// det(I − A q⁻¹) monic of degree n (not reduced: pole-zero cancellations are kept).
  [[nodiscard]] TransferFunction to_transfer_function(int output = 0, int input = 0) const {
    check_pair(output, input);
    TransferFunction tf;
    tf.ts = ts_;
    const Eigen::VectorXd den = characteristic(a_);
    const Eigen::MatrixXd bc = b_.col(input) * c_.row(output);
    tf.numerator = characteristic(a_ - bc) - den + d_(output, input) * den;
    tf.denominator = den;
    return tf;
  }

  /// Free-run output (N x p) for the input matrix `u` (N x m) from the state `x0` (n).
  /// Throws on a size mismatch. A diverging (unstable) simulation returns its non-finite values
  /// so that `fit_percent` reports −∞ rather than the model being silently altered.
  [[nodiscard]] Eigen::MatrixXd simulate(const Eigen::MatrixXd& u, const Eigen::VectorXd& x0) const {
    require(u.cols() == num_inputs(),
            "StateSpace::simulate: input has " + std::to_string(u.cols()) +
                " columns, model has " + std::to_string(num_inputs()) + " inputs",
            at_parameter("u"));
    require(x0.size() == order(),
            "StateSpace::simulate: initial state has " + std::to_string(x0.size()) +
                " entries, model has " + std::to_string(order()) + " states",
            at_parameter("x0"));
    Eigen::MatrixXd y(u.rows(), num_outputs());
    Eigen::VectorXd x = x0;
    Eigen::VectorXd xn(order());
    for (Eigen::Index t = 0; t < u.rows(); ++t) {
      y.row(t).noalias() = (c_ * x + d_ * u.row(t).transpose() + offset_).transpose();
      xn.noalias() = a_ * x + b_ * u.row(t).transpose();
      x.swap(xn);
    }
    return y;
  }

  /// Initial state x(0) chosen by the policy `ic` for experiment `e` (see file comment).
  [[nodiscard]] Eigen::VectorXd initial_state(const Experiment& e, InitialCondition ic) const {
    const bool need_y = ic == InitialCondition::estimate;
    detail::check_linear_experiment(e, num_inputs(), num_outputs(), ts_, -1, "StateSpace", need_y);
    detail::check_linear_channel_order(e, *this, "StateSpace");
    const int n = order();
    switch (ic) {
      case InitialCondition::zero:
        return Eigen::VectorXd::Zero(n);
      case InitialCondition::equilibrium: {
        if (n == 0 || e.size() == 0) return Eigen::VectorXd::Zero(n);
        const Eigen::VectorXd bu = b_ * e.u().row(0).transpose();
        Eigen::FullPivLU<Eigen::MatrixXd> lu(Eigen::MatrixXd::Identity(n, n) - a_);
        if (lu.isInvertible()) return lu.solve(bu);
        require(bu.norm() == 0.0,
                "StateSpace: no equilibrium for the first input sample: A has a pole at z = 1 "
                "(integrator); use InitialCondition::zero or ::estimate",
                at_parameter("InitialCondition::equilibrium"));
        return Eigen::VectorXd::Zero(n);
      }
      case InitialCondition::estimate:
        return estimate_initial_state(e);
      case InitialCondition::measured:
        break;
    }
    throw Error(
        "StateSpace: InitialCondition::measured needs a model whose state is a list of past "
        "outputs (ARX); use InitialCondition::estimate for a state-space model",
        at_parameter("InitialCondition::measured"));
  }

  /// Free-run output (N x p) for experiment `e` from the initial state chosen by `ic`.
  [[nodiscard]] Eigen::MatrixXd simulate(const Experiment& e,
                                         InitialCondition ic = InitialCondition::zero) const {
    return simulate(e.u(), initial_state(e, ic));
  }

  /// k-step-ahead prediction. With K = 0 the predictor does not use measured outputs, so for
  /// every k ≥ 1 it is the simulation from the estimated initial state. Throws for k < 1.
  [[nodiscard]] Eigen::MatrixXd predict(const Experiment& e, int k) const {
    require(k >= 1, "StateSpace::predict: horizon k must be >= 1, got " + std::to_string(k),
            at_parameter("k"));
    return simulate(e, InitialCondition::estimate);
  }

  /// Readable description: equations, matrices, poles, sample time and estimation report.
  [[nodiscard]] std::string describe() const {
    std::ostringstream os;
    os.imbue(std::locale::classic());  // a global locale's grouping or decimal comma must not reach the text
    const Eigen::IOFormat fmt(4, 0, "  ", "\n", "    [", "]");
    os << "Discrete-time state-space model: " << order() << " state(s), " << num_inputs()
       << " input(s), " << num_outputs() << " output(s)\n";
    const auto list = [&](const char* what, const std::vector<std::string>& names) {
      if (names.empty()) return;
      os << "  " << what << ":";
      for (std::size_t i = 0; i < names.size(); ++i) os << (i == 0 ? " " : ", ") << names[i];
      os << "\n";
    };
    list("inputs u", input_names_);
    list("outputs y", output_names_);
    os
       << "  x(t+Ts) = A x(t) + B u(t)\n"
       << "  y(t)    = C x(t) + D u(t)" << (offset_.isZero() ? "" : " + y0") << " + e(t)\n";
    if (order() > 0) {
      os << "  A =\n" << a_.format(fmt) << "\n  B =\n" << b_.format(fmt) << "\n  C =\n"
         << c_.format(fmt) << "\n";
    }
    os << "  D =\n" << d_.format(fmt) << "\n";
    if (!offset_.isZero()) os << "  y0 =\n" << offset_.transpose().format(fmt) << "\n";
    os << "Poles: " << format_roots(poles()) << "\n";
    os << "Sample time: " << format_number(ts_, 6) << " s\n";
    if (!report_.method.empty()) os << report_.str();
    return os.str();
  }

  // ---- Implementation details below ----------------------------------------------------------

 private:
  static void check_name_count(const std::vector<std::string>& names, int count, const char* what,
                               const char* channels) {
    require(names.empty() || static_cast<int>(names.size()) == count,
            "StateSpace: " + std::to_string(names.size()) + " " + channels + " named, the model has " +
                std::to_string(count) + " (give one name per channel, or none)",
            at_parameter(what));
  }

  void check_pair(int output, int input) const {
    require(output >= 0 && output < num_outputs(),
            "StateSpace: output index " + std::to_string(output) + " out of range (model has " +
                std::to_string(num_outputs()) + ")",
            at_parameter("output"));
    require(input >= 0 && input < num_inputs(),
            "StateSpace: input index " + std::to_string(input) + " out of range (model has " +
                std::to_string(num_inputs()) + ")",
            at_parameter("input"));
  }

  // det(I − M q⁻¹) as a monic polynomial in q⁻¹ (= det(zI − M) / zⁿ).
  static Eigen::VectorXd characteristic(const Eigen::MatrixXd& m) {
    if (m.rows() == 0) return Eigen::VectorXd::Ones(1);
    return poly_from_roots(Eigen::EigenSolver<Eigen::MatrixXd>(m, false).eigenvalues());
  }

  // x(0) by least squares: y − ŷ_zero = O x0, O(t) = C Aᵗ. Rows stop where Aᵗ would overflow
  // (an unstable model), which only drops samples that carry no usable information.
  Eigen::VectorXd estimate_initial_state(const Experiment& e) const {
    const int n = order();
    if (n == 0 || e.size() == 0) return Eigen::VectorXd::Zero(n);
    const Eigen::MatrixXd y0 = simulate(e.u(), Eigen::VectorXd::Zero(n));
    const Eigen::Index p = num_outputs();
    Eigen::MatrixXd obs(e.size() * p, n);
    Eigen::VectorXd rhs(e.size() * p);
    Eigen::MatrixXd cat = c_;  // C Aᵗ
    Eigen::Index rows = 0;
    for (Eigen::Index t = 0; t < e.size(); ++t) {
      if (!cat.allFinite() || cat.cwiseAbs().maxCoeff() > 1e150) break;
      obs.middleRows(rows, p) = cat;
      rhs.segment(rows, p) = (e.y().row(t) - y0.row(t)).transpose();
      rows += p;
      cat = cat * a_;
    }
    if (rows == 0) return Eigen::VectorXd::Zero(n);
    Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(obs.topRows(rows));
    Eigen::VectorXd x0 = qr.solve(rhs.head(rows));
    if (!x0.allFinite()) x0.setZero();
    return x0;
  }

  Eigen::MatrixXd a_, b_, c_, d_;
  Eigen::VectorXd offset_;
  double ts_ = 1.0;
  LinearEstimationReport report_;
  std::vector<std::string> input_names_, output_names_;
};

}  // namespace nlid
