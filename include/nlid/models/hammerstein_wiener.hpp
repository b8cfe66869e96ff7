#pragma once
/// @file
/// `HammersteinWiener<In, L, Out>`: a static input nonlinearity, a linear block and a static
/// output nonlinearity in series.
///
/// Math (Ljung 1999, sec. 5.2 "block-oriented models"; Wills et al., "Identification of
/// Hammerstein–Wiener models", Automatica 49, 2013):
///
///     w(t) = f(u(t); θ_f)                     input nonlinearity  (In, one input)
///     x(t) = B(q)/F(q) w(t − nk; θ_L)         linear block        (L, e.g. [nb nf nk])
///     y(t) = h(x(t); θ_h)                     output nonlinearity (Out, one input)
///
/// With f the identity (`UnitGain`) this is a *Wiener* model; with h the identity a
/// *Hammerstein* model. There is no noise model (output-error structure, Ljung eq. 4.25), so
/// the one-step predictor equals the simulation: `predict(e, k)` returns the simulation for
/// every k. Parameters are stacked θ = [θ_f, θ_L, θ_h]; the model has an inherent gain
/// ambiguity (f·a, B/a give the same y) which the damped Gauss–Newton steps of the estimator
/// tolerate; fix a parameter (LmOptions::fixed) for a unique θ.
///
/// State: the linear block's (transposed direct form II, `TransferFunctionBlock`): n numbers.
/// Initial conditions: `zero` (block at rest, as `nlhw2` of the study), `equilibrium` (steady
/// state for u(0) held), `estimate` (the n states by least squares, as `nlhw1`). `measured` has
/// no meaning for a block state that is not a measured signal and is rejected with an error.
///
/// Static sizes give a stack-only simulation (no allocation per sample); the components'
/// Dynamic twins give the Dynamic model running the same code.

#include <cmath>
#include <limits>
#include <span>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "nlid/ad/dual.hpp"
#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/core/initial_condition.hpp"
#include "nlid/data/experiment.hpp"
#include "nlid/models/concepts.hpp"
#include "nlid/models/detail/initial_state.hpp"
#include "nlid/models/detail/model_common.hpp"
#include "nlid/models/transfer_function_block.hpp"
#include "nlid/nonlinearities/concepts.hpp"
#include "nlid/nonlinearities/detail/bound_map.hpp"

namespace nlid {

/// Hammerstein–Wiener model y = h(B/F f(u)). Single input, single output.
/// Invariant: both nonlinearities have input dimension 1; `parameters()` has `num_parameters()`
/// entries laid out [θ_f, θ_L, θ_h].
template <ScalarNonlinearity In, LinearBlock L, ScalarNonlinearity Out>
class HammersteinWiener {
 public:
  /// Input nonlinearity type.
  using InputMap = In;
  /// Linear block type.
  using Linear = L;
  /// Output nonlinearity type.
  using OutputMap = Out;
  /// p = p_f + p_L + p_h, or Dynamic.
  static constexpr int num_params = size_sum(In::num_params, L::num_params, Out::num_params);
  /// Parameter vector of a fixed-size solver.
  using Parameters = Eigen::Matrix<double, num_params, 1>;

  /// Structure from compile-time components.
  HammersteinWiener()
    requires(std::is_default_constructible_v<In> && std::is_default_constructible_v<L> &&
             std::is_default_constructible_v<Out>)
      : HammersteinWiener(In{}, L{}, Out{}) {}

  /// Structure from components; θ starts at zero. Throws `nlid::Error` if a nonlinearity does not
  /// have exactly one input.
  HammersteinWiener(In input_map, L linear, Out output_map, double ts = 0.0)
      : f_(std::move(input_map)), lin_(std::move(linear)), h_(std::move(output_map)) {
    require(f_.input_dimension() == 1,
            "the input nonlinearity must have one input, it has " + std::to_string(f_.input_dimension()),
            at_parameter("input_nonlinearity"));
    require(h_.input_dimension() == 1,
            "the output nonlinearity must have one input, it has " + std::to_string(h_.input_dimension()),
            at_parameter("output_nonlinearity"));
    theta_ = Eigen::VectorXd::Zero(num_parameters());
    set_ts(ts);
  }

  // ---- structure -----------------------------------------------------------------------------

  /// Input nonlinearity f.
  [[nodiscard]] const In& input_nonlinearity() const { return f_; }
  /// Mutable input nonlinearity (for `initialize`).
  [[nodiscard]] In& input_nonlinearity() { return f_; }
  /// Linear block.
  [[nodiscard]] const L& linear_block() const { return lin_; }
  /// Output nonlinearity h.
  [[nodiscard]] const Out& output_nonlinearity() const { return h_; }
  /// Mutable output nonlinearity (for `initialize`).
  [[nodiscard]] Out& output_nonlinearity() { return h_; }

  /// p = p_f + p_L + p_h.
  [[nodiscard]] int num_parameters() const {
    return f_.num_parameters() + lin_.num_parameters() + h_.num_parameters();
  }
  /// Offset of θ_L in θ.
  [[nodiscard]] int linear_offset() const { return f_.num_parameters(); }
  /// Offset of θ_h in θ.
  [[nodiscard]] int output_offset() const { return f_.num_parameters() + lin_.num_parameters(); }
  /// One input.
  [[nodiscard]] int num_inputs() const { return 1; }
  /// One output.
  [[nodiscard]] int num_outputs() const { return 1; }
  /// Size of x0 (the linear block's state).
  [[nodiscard]] int state_dimension() const { return lin_.num_states_runtime(); }

  // ---- scalar-generic core -------------------------------------------------------------------

  /// Free-run simulation ŷ(0 … N−1) for inputs `u` (N×1) from the linear block's state `x0`
  /// (empty: at rest). Returns false if the output becomes non-finite or exceeds `limit`.
  template <class T>
  bool simulate(const Eigen::Ref<const Eigen::MatrixXd>& u, std::span<const T> theta,
                std::span<const T> x0, std::span<T> y,
                double limit = std::numeric_limits<double>::infinity()) const {
    return simulate_until(u, theta, x0, y, limit) < 0;
  }

  /// As `simulate`, returning the first sample at which the output diverged, or −1.
  template <class T>
  Eigen::Index simulate_until(const Eigen::Ref<const Eigen::MatrixXd>& u, std::span<const T> theta,
                              std::span<const T> x0, std::span<T> y,
                              double limit = std::numeric_limits<double>::infinity()) const {
    check_core_sizes(u.cols(), theta.size(), x0.size(), static_cast<Eigen::Index>(y.size()), u.rows());
    const auto [th_f, th_l, th_h] = split(theta);
    State<T> s = make_state<T>();
    for (int i = 0; i < s.size(); ++i) s(i) = x0.empty() ? T(0) : x0[static_cast<std::size_t>(i)];
    const std::span<T> ss(s.data(), static_cast<std::size_t>(s.size()));
    // θ-only work of the maps (PwLinear's breakpoint positions) once, not per sample.
    const detail::BoundScalarMap<In, T> f(f_, th_f);
    const detail::BoundScalarMap<Out, T> h(h_, th_h);
    for (Eigen::Index t = 0; t < u.rows(); ++t) {
      const T w = f(T(u(t, 0)));
      const T x = lin_.step(ss, w, th_l);
      T yt = h(x);
      if (!detail::is_finite_scalar(yt) || std::abs(static_cast<double>(value_of(yt))) > limit) return t;
      y[static_cast<std::size_t>(t)] = std::move(yt);
    }
    return -1;
  }

  /// One-step prediction: equal to the simulation from `x0` (output-error structure).
  template <class T>
  bool predict(const Eigen::Ref<const Eigen::MatrixXd>& u, const Eigen::Ref<const Eigen::VectorXd>& /*y*/,
               std::span<const T> theta, std::span<const T> x0, std::span<T> yhat) const {
    return simulate(u, theta, x0, yhat);
  }

  /// Intermediate signals of a simulation (double): columns w, x, y. Useful to see which
  /// block does what (e.g. how often the output saturation is active).
  [[nodiscard]] Eigen::MatrixXd signals(const Eigen::Ref<const Eigen::MatrixXd>& u,
                                        std::span<const double> theta, std::span<const double> x0) const {
    check_core_sizes(u.cols(), theta.size(), x0.size(), u.rows(), u.rows());
    const auto [th_f, th_l, th_h] = split(theta);
    State<double> s = make_state<double>();
    for (int i = 0; i < s.size(); ++i) s(i) = x0.empty() ? 0.0 : x0[static_cast<std::size_t>(i)];
    const std::span<double> ss(s.data(), static_cast<std::size_t>(s.size()));
    Eigen::MatrixXd out(u.rows(), 3);
    for (Eigen::Index t = 0; t < u.rows(); ++t) {
      const double ut = u(t, 0);
      const double w = f_(std::span<const double>(&ut, 1), th_f);
      const double x = lin_.step(ss, w, th_l);
      out.row(t) << w, x, h_(std::span<const double>(&x, 1), th_h);
    }
    return out;
  }

  /// Linear-block state in steady state for the constant input u0 (zero if F(1) = 0: the
  /// estimators' generic start; `initial_state` refuses that case for a non-zero input).
  template <class T>
  [[nodiscard]] Eigen::Matrix<T, Eigen::Dynamic, 1> equilibrium_state(double u0, std::span<const T> theta) const {
    const auto [th_f, th_l, th_h] = split(theta);
    const T ut(u0);
    const T w = f_(std::span<const T>(&ut, 1), th_f);
    Eigen::Matrix<T, Eigen::Dynamic, 1> s = Eigen::Matrix<T, Eigen::Dynamic, 1>::Constant(state_dimension(), T(0));
    if (!lin_.equilibrium_state(w, th_l, std::span<T>(s.data(), static_cast<std::size_t>(s.size())))) {
      s.setConstant(T(0));
    }
    return s;
  }

  // ---- user-level model ----------------------------------------------------------------------

  /// Estimated (or set) parameters [θ_f, θ_L, θ_h].
  [[nodiscard]] const Eigen::VectorXd& parameters() const { return theta_; }
  /// Sets θ. Throws `nlid::Error` if its length is not `num_parameters()` or a value is not finite.
  void set_parameters(const Eigen::VectorXd& theta) {
    require(theta.size() == num_parameters(),
            "parameter vector has " + std::to_string(theta.size()) + " values, the model has " +
                std::to_string(num_parameters()),
            at_parameter("theta"));
    detail::require_finite_parameters(theta, parameter_names());
    theta_ = theta;
  }
  /// θ_f, θ_L, θ_h views of the stored parameters.
  [[nodiscard]] std::span<const double> input_parameters() const { return std::get<0>(split(detail::as_const_span(theta_))); }
  /// θ_L = [b₁ … b_nb, f₁ … f_nf].
  [[nodiscard]] std::span<const double> linear_parameters() const { return std::get<1>(split(detail::as_const_span(theta_))); }
  /// θ_h.
  [[nodiscard]] std::span<const double> output_parameters() const { return std::get<2>(split(detail::as_const_span(theta_))); }

  /// Sets the linear block's parameters from toolbox polynomials B (with or without the nk
  /// leading zeros) and monic F.
  void set_linear_polynomials(const Eigen::VectorXd& b, const Eigen::VectorXd& f) {
    lin_.set_from_polynomials(b, f, std::span<double>(theta_.data() + linear_offset(),
                                                      static_cast<std::size_t>(lin_.num_parameters())));
  }
  /// Sets the linear block from a previously estimated linear model with the toolbox polynomials
  /// `b_polynomial()` (nk leading zeros) and monic `f_polynomial()` — an `OutputError` model; the
  /// toolbox GUI cannot do this, the API can. (Its `b()`/`f()` are the free coefficients, F
  /// without its leading 1.) An offset of the linear model is not carried: the block has none.
  template <class LinearModel>
    requires requires(const LinearModel& m) {
      { m.b_polynomial() } -> std::convertible_to<Eigen::VectorXd>;
      { m.f_polynomial() } -> std::convertible_to<Eigen::VectorXd>;
    }
  void set_linear_block(const LinearModel& m) {
    set_linear_polynomials(m.b_polynomial(), m.f_polynomial());
  }
  /// Names "input:…", "linear:b1", …, "output:…".
  [[nodiscard]] std::vector<std::string> parameter_names() const {
    std::vector<std::string> n;
    for (auto& s : f_.parameter_names()) n.push_back("input:" + s);
    for (auto& s : lin_.parameter_names()) n.push_back("linear:" + s);
    for (auto& s : h_.parameter_names()) n.push_back("output:" + s);
    return n;
  }

  /// Sample time in seconds (0: not set).
  [[nodiscard]] double ts() const { return ts_; }
  /// Sets the sample time (≥ 0).
  void set_ts(double ts) {
    require(ts >= 0.0 && std::isfinite(ts), "sample time must be >= 0 and finite", at_parameter("ts"));
    ts_ = ts;
  }
  /// Input channel name.
  [[nodiscard]] const std::string& input_name() const { return input_name_; }
  /// Output channel name.
  [[nodiscard]] const std::string& output_name() const { return output_name_; }
  /// Sets channel names (used by `describe`).
  void set_channel_names(std::string input, std::string output) {
    input_name_ = std::move(input);
    output_name_ = std::move(output);
  }

  /// What the last estimation did.
  [[nodiscard]] const EstimationReport& report() const { return report_; }
  /// Records an estimation (called by the estimators).
  void set_report(EstimationReport r) { report_ = std::move(r); }

  /// x0 (linear-block state) for an experiment under an initial-condition policy. Throws
  /// `nlid::Error` naming the experiment on bad data, or for `measured` (not applicable).
  [[nodiscard]] Eigen::VectorXd initial_state(const Experiment& e, InitialCondition ic, long index = -1) const {
    detail::check_experiment(e, index, 1, 0, ts_, "Hammerstein-Wiener");
    const std::span<const double> th = detail::as_const_span(theta_);
    switch (ic) {
      case InitialCondition::zero: return Eigen::VectorXd::Zero(state_dimension());
      case InitialCondition::equilibrium: {
        // An integrating block (F(1) = 0) rests only for w = 0; for any other held input there
        // is no steady state, and starting at rest instead would be a silent substitute (Nlarx
        // reports its missing steady state the same way, so compare scores the record diverged).
        const auto [th_f, th_l, th_h] = split(th);
        const double u0 = e.u()(0, 0);
        const double w0 = f_(std::span<const double>(&u0, 1), th_f);
        Eigen::VectorXd s0 = Eigen::VectorXd::Zero(state_dimension());
        const bool rests = lin_.equilibrium_state(w0, th_l, std::span<double>(s0.data(), static_cast<std::size_t>(s0.size())));
        if (!rests && w0 != 0.0) {
          Location where = detail::experiment_location(index);
          where.parameter = "initial";
          throw DivergenceError(detail::experiment_label(e, index) + ": no steady state for the held input u = " +
                                    detail::format_g(u0, 4) + ": the linear block integrates (F(1) = 0); use zero or estimate",
                                0, where);
        }
        return s0;  // the steady state, or (w0 = 0 on an integrator) the zero state it rests in
      }
      case InitialCondition::estimate: {
        detail::require_complete_for(e, index, true, "fit of the initial state");
        std::vector<int> free(static_cast<std::size_t>(state_dimension()));
        for (int i = 0; i < state_dimension(); ++i) free[static_cast<std::size_t>(i)] = i;
        const Eigen::VectorXd y = e.y().col(0);
        return detail::estimate_initial_state(*this, e.u(), y, th, equilibrium_state<double>(e.u()(0, 0), th), free);
      }
      case InitialCondition::measured: break;
    }
    throw Error("InitialCondition::measured applies to regression models (past outputs are their state); "
                "a Hammerstein-Wiener model's state is internal: use zero, equilibrium or estimate",
                at_parameter("initial"));
  }

  /// Simulated output (N×1) of an experiment. Throws `nlid::Error` naming the experiment if the
  /// data do not fit the model or the simulation diverges.
  [[nodiscard]] Eigen::MatrixXd simulate(const Experiment& e, InitialCondition ic = InitialCondition::zero) const {
    detail::require_complete_for(e, -1, ic == InitialCondition::estimate, "simulation");
    const Eigen::VectorXd x0 = initial_state(e, ic);
    Eigen::MatrixXd yhat(e.size(), 1);
    const Eigen::Index bad = simulate_until(e.u(), detail::as_const_span(theta_), detail::as_const_span(x0),
                                            std::span<double>(yhat.data(), static_cast<std::size_t>(e.size())));
    if (bad >= 0) {
      throw DivergenceError("simulation of " + detail::experiment_label(e, -1) + " diverges (output not finite at sample " +
                      std::to_string(bad) + ")",
                  static_cast<long>(bad), detail::experiment_location(-1));
    }
    return yhat;
  }

  /// k-step prediction: the simulation with an estimated initial state, for every k ≥ 1 (the
  /// output-error predictor does not use measured outputs). Throws `nlid::Error` if k < 1.
  [[nodiscard]] Eigen::MatrixXd predict(const Experiment& e, int k = 1) const {
    require(k >= 1, "prediction horizon k must be >= 1, got " + std::to_string(k), at_parameter("k"));
    return simulate(e, InitialCondition::estimate);
  }

  /// Human-readable model: the three blocks with their equations and values.
  [[nodiscard]] std::string describe() const {
    const auto [th_f, th_l, th_h] = split(detail::as_const_span(theta_));
    std::string s = "Hammerstein-Wiener model: " + output_name_ + " = h(B/F f(" + input_name_ + "))";
    if (ts_ > 0) s += ", sample time " + detail::format_g(ts_, 4) + " s";
    s += "\n  input nonlinearity f: " + f_.describe(th_f);
    if (s.back() != '\n') s += "\n";
    s += "  " + lin_.describe(th_l);
    if (s.back() != '\n') s += "\n";
    s += "  output nonlinearity h: " + h_.describe(th_h);
    if (s.back() != '\n') s += "\n";
    s += detail::describe_report(report_);
    return s;
  }

  // ---- Implementation details below ----------------------------------------------------------
 private:
  template <class T>
  using State = Eigen::Matrix<T, L::num_states, 1>;

  template <class T>
  State<T> make_state() const {
    if constexpr (L::num_states == Dynamic) {
      return State<T>(lin_.num_states_runtime());
    } else {
      return State<T>();
    }
  }

  template <class T>
  std::tuple<std::span<const T>, std::span<const T>, std::span<const T>> split(std::span<const T> theta) const {
    const auto pf = static_cast<std::size_t>(f_.num_parameters());
    const auto pl = static_cast<std::size_t>(lin_.num_parameters());
    return {theta.first(pf), theta.subspan(pf, pl), theta.subspan(pf + pl)};
  }

  void check_core_sizes(Eigen::Index nu, std::size_t ntheta, std::size_t nx0, Eigen::Index ny, Eigen::Index n) const {
    if (nu != 1)
      throw Error("input matrix has " + std::to_string(nu) + " columns, the model reads 1 input", at_parameter("u"));
    if (static_cast<int>(ntheta) != num_parameters())
      throw Error("parameter vector has " + std::to_string(ntheta) + " values, the model has " +
                      std::to_string(num_parameters()),
                  at_parameter("theta"));
    if (nx0 != 0 && static_cast<int>(nx0) != state_dimension())
      throw Error("initial state has " + std::to_string(nx0) + " values, the linear block has " +
                      std::to_string(state_dimension()) + " states",
                  at_parameter("x0"));
    if (ny != n)
      throw Error("output buffer has " + std::to_string(ny) + " entries for " + std::to_string(n) + " samples",
                  at_parameter("y"));
  }

  In f_;
  L lin_;
  Out h_;
  Eigen::VectorXd theta_;
  double ts_ = 0.0;
  std::string input_name_ = "u1";
  std::string output_name_ = "y1";
  EstimationReport report_;
};

/// Deduction guide: `HammersteinWiener hw{UnitGain{}, TransferFunctionBlock<3, 3, 0>{}, Saturation{15, 90}}`.
template <class In, class L, class Out>
HammersteinWiener(In, L, Out) -> HammersteinWiener<In, L, Out>;
/// Deduction guide with a sample time.
template <class In, class L, class Out>
HammersteinWiener(In, L, Out, double) -> HammersteinWiener<In, L, Out>;

}  // namespace nlid
