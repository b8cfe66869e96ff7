#pragma once
/// @file
/// `Nlarx<R, F>`: the nonlinear ARX model y(t) = F(φ(t)) with a compile-time regressor set R and
/// a nonlinearity F.
///
/// Math (Ljung 1999, sec. 5.2, eq. 5.46; Sjöberg et al. 1995, sec. 4). With regressors
/// φ(t) = [y(t−1) … y(t−na), u(t−nk) …, custom(…)]ᵀ and a static map F(φ; θ):
///
///     one-step prediction   ŷ(t | t−1) = F(φ(t); θ),       φ from measured y,
///     free-run simulation   ŷ_s(t)     = F(φ_s(t); θ),     φ_s from ŷ_s(t−1), ŷ_s(t−2), …
///
/// Prediction-focus estimation minimises Σ (y(t) − ŷ(t|t−1))² (a regression problem: cheap,
/// but the model may drift in free run); simulation-focus estimation minimises
/// Σ (y(t) − ŷ_s(t))², the quality measure of the study, at the price of a recursion in the
/// Jacobian: ∂ŷ_s(t)/∂θ = ∂F/∂θ + Σ_k ∂F/∂y(t−k) · ∂ŷ_s(t−k)/∂θ (Ljung 1999, eq. 10.43).
/// nlid evaluates that recursion exactly, either by running `simulate` on dual numbers or, for a
/// nonlinearity with an analytic gradient, by the recursion itself (models/detail/nlarx_sensitivity.hpp).
///
/// Initial conditions of a simulation (`InitialCondition`), for an experiment of N samples:
/// - `zero`: all past outputs and inputs before t = 0 are zero;
/// - `measured`: the first n₀ = max(output lag, input lag) samples serve as the past; ŷ equals
///   the measured y there and the free run starts at t = n₀ (the toolbox's "past data");
/// - `equilibrium`: the past is the steady state y* = F(φ(y*, u(0))) for u(0) held constant;
/// - `estimate`: past inputs are u(0) held, the Ly past outputs are chosen by least squares to
///   make the simulation fit the whole record (the toolbox's default for `compare`).
/// State vector x0 (`state_dimension()` values, empty = zero):
/// [y(−1) … y(−Ly), u₁(−1) … u₁(−Lu), u₂(−1) …].
///
/// Sizes: `num_params` = F::num_params; a static regressor set keeps its past outputs in a
/// stack ring buffer, so a fixed-size simulation allocates nothing per sample. A `Dynamic`
/// regressor set or nonlinearity (orders or units chosen at run time) gives the Dynamic twin;
/// both run the same code and agree to rounding.
///
/// Concepts in the template head (`Regressor`, `Nonlinearity`, matching sizes) reject a bad
/// component at the declaration `Nlarx<R, F>` with one constraint error.

#include <algorithm>
#include <cmath>
#include <limits>
#include <span>
#include <string>
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
#include "nlid/nonlinearities/concepts.hpp"
#include "nlid/regressors/concepts.hpp"
#include "nlid/regressors/history.hpp"
#include "nlid/regressors/lag_window.hpp"
#include "nlid/regressors/regressor_set.hpp"

namespace nlid {

namespace detail {
/// The regressor count matches the nonlinearity's input count (or one of them is Dynamic).
template <class R, class F>
concept RegressorsFitNonlinearity =
    R::num_regressors == Dynamic || F::num_inputs == Dynamic || R::num_regressors == F::num_inputs;
}  // namespace detail

/// Nonlinear ARX model y(t) = F(φ(t)): regressor set R, nonlinearity F, parameters θ of F.
/// Invariant: `nonlinearity().input_dimension() == regressors().size()`, and `parameters()`
/// has `num_parameters()` entries.
template <Regressor R, Nonlinearity F>
  requires detail::RegressorsFitNonlinearity<R, F>
class Nlarx {
 public:
  /// Regressor set type.
  using Regressors = R;
  /// Nonlinearity type.
  using Map = F;
  /// Number of parameters (those of F), or Dynamic.
  static constexpr int num_params = F::num_params;
  /// Number of regressors, or Dynamic.
  static constexpr int num_regressors = R::num_regressors;
  /// Parameter vector of a fixed-size solver.
  using Parameters = Eigen::Matrix<double, num_params, 1>;

  /// Structure from compile-time components.
  Nlarx() requires(std::is_default_constructible_v<R> && std::is_default_constructible_v<F>)
      : Nlarx(R{}, F{}) {}

  /// Structure from components; θ starts at zero. Throws `nlid::Error` if F's input dimension
  /// differs from the number of regressors.
  Nlarx(R regressors, F nonlinearity, double ts = 0.0)
      : regs_(std::move(regressors)), f_(std::move(nonlinearity)) {
    require(f_.input_dimension() == regs_.size(),
            "the nonlinearity takes " + std::to_string(f_.input_dimension()) +
                " inputs but the regressor set has " + std::to_string(regs_.size()) + " regressors",
            at_parameter("nonlinearity"));
    // The state x0 holds Ly + nu·Lu values. Each factor is bounded on its own (lags by
    // max_model_order, channels by what the expressions name), the product is not: a regressor
    // that reads input channel 30 000 at lag 10⁵ asks for 3·10⁹ values, past int.
    const long long state_values = static_cast<long long>(regs_.output_lag()) +
                                   static_cast<long long>(regs_.num_input_channels()) * regs_.input_lag();
    require(state_values <= std::numeric_limits<int>::max(),
            "the model's state would hold " + std::to_string(state_values) + " values (output lag " +
                std::to_string(regs_.output_lag()) + " + " + std::to_string(regs_.num_input_channels()) +
                " input channels x input lag " + std::to_string(regs_.input_lag()) + "), more than an int can count",
            at_parameter("regressors"));
    theta_ = Eigen::VectorXd::Zero(f_.num_parameters());
    input_names_ = default_input_names(regs_.num_input_channels());
    set_ts(ts);
  }

  // ---- structure -----------------------------------------------------------------------------

  /// The regressor set.
  [[nodiscard]] const R& regressors() const { return regs_; }
  /// The nonlinearity (structure and normalisation; θ is separate).
  [[nodiscard]] const F& nonlinearity() const { return f_; }
  /// Mutable nonlinearity (its `initialize` learns normalisation from data).
  [[nodiscard]] F& nonlinearity() { return f_; }
  /// Number of parameters.
  [[nodiscard]] int num_parameters() const { return f_.num_parameters(); }
  /// Number of input channels the regressors read.
  [[nodiscard]] int num_inputs() const { return regs_.num_input_channels(); }
  /// One output.
  [[nodiscard]] int num_outputs() const { return 1; }
  /// Largest output lag Ly.
  [[nodiscard]] int output_lag() const { return regs_.output_lag(); }
  /// Largest input lag Lu.
  [[nodiscard]] int input_lag() const { return regs_.input_lag(); }
  /// n₀ = max(Ly, Lu): samples before the first one-step prediction.
  [[nodiscard]] int history_length() const { return nlid::history_length(regs_); }
  /// Size of x0: Ly + nu·Lu.
  [[nodiscard]] int state_dimension() const { return output_lag() + num_inputs() * input_lag(); }

  // ---- scalar-generic core (θ explicit; T = double, float or Dual) ---------------------------

  /// F(φ; θ) for one regressor vector.
  template <class T>
  [[nodiscard]] T evaluate(std::span<const T> phi, std::span<const T> theta) const {
    return f_(phi, theta);
  }

  /// Free-run simulation ŷ(0 … N−1) for inputs `u` (N×nu) from initial state `x0` (empty: zero).
  /// Returns false if the output becomes non-finite or exceeds `limit` in magnitude (a
  /// diverging simulation: the estimator rejects the step). Allocation: none for static sizes.
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
    const int ly = output_lag();
    const int lu = input_lag();
    History<T, R::max_output_lag> past(ly);
    if (!x0.empty()) {
      for (int k = ly; k >= 1; --k) past.push(x0[static_cast<std::size_t>(k - 1)]);
    }
    const std::span<const T> u_past = x0.empty() ? std::span<const T>{} : x0.subspan(static_cast<std::size_t>(ly));
    SimulationWindow<T, R::max_output_lag> w(u, past, u_past, lu);
    RegressorVector<T> phi = make_regressor_vector<T>();
    const std::span<T> phi_span(phi.data(), static_cast<std::size_t>(phi.size()));
    const std::span<const T> phi_const(phi.data(), static_cast<std::size_t>(phi.size()));
    constexpr double kNoLimit = std::numeric_limits<double>::infinity();
    for (Eigen::Index t = 0; t < u.rows(); ++t) {
      w.set_time(t);
      regs_.evaluate(w, phi_span);
      T yt = f_(phi_const, theta);
      // The magnitude test only with a finite limit: for a Batch, static_cast<double> reduces the
      // lanes through memory at every sample (an infinite limit is the default of simulate()).
      if (!detail::is_finite_scalar(yt) || (limit < kNoLimit && std::abs(static_cast<double>(value_of(yt))) > limit)) return t;
      past.push(yt);
      y[static_cast<std::size_t>(t)] = std::move(yt);
    }
    return -1;
  }

  /// One-step-ahead prediction from measured data: ŷ(t | t−1) for t = n₀ … N−1 (`yhat` has
  /// N − n₀ entries). Returns false if a prediction is non-finite.
  template <class T>
  bool predict(const Eigen::Ref<const Eigen::MatrixXd>& u, const Eigen::Ref<const Eigen::VectorXd>& y,
               std::span<const T> theta, std::span<T> yhat) const {
    const int n0 = history_length();
    check_core_sizes(u.cols(), theta.size(), 0, static_cast<Eigen::Index>(yhat.size()) + n0, u.rows());
    require(y.rows() == u.rows(), "predict: u and y have different sample counts", at_parameter("y"));
    MeasuredWindow<T> w(u, y);
    RegressorVector<T> phi = make_regressor_vector<T>();
    const std::span<T> phi_span(phi.data(), static_cast<std::size_t>(phi.size()));
    const std::span<const T> phi_const(phi.data(), static_cast<std::size_t>(phi.size()));
    for (std::size_t i = 0; i < yhat.size(); ++i) {
      w.set_time(n0 + static_cast<Eigen::Index>(i));
      regs_.evaluate(w, phi_span);
      yhat[i] = f_(phi_const, theta);
      if (!detail::is_finite_scalar(yhat[i])) return false;
    }
    return true;
  }

  /// x0 that starts a simulation at sample `t` of measured data (t ≥ n₀): the lag window
  /// [y(t−1) … y(t−Ly), u₁(t−1) … u₁(t−Lu), …].
  [[nodiscard]] Eigen::VectorXd measured_state(const Eigen::Ref<const Eigen::MatrixXd>& u,
                                               const Eigen::Ref<const Eigen::VectorXd>& y,
                                               Eigen::Index t) const {
    require(t >= history_length() && t <= y.rows(),
            "measured_state: time " + std::to_string(t) + " needs " + std::to_string(history_length()) +
                " samples of past data",
            at_parameter("t"));
    const int ly = output_lag(), lu = input_lag();
    Eigen::VectorXd x0(state_dimension());
    for (int k = 1; k <= ly; ++k) x0(k - 1) = y(t - k);
    for (int c = 0; c < num_inputs(); ++c)
      for (int k = 1; k <= lu; ++k) x0(ly + c * lu + k - 1) = u(t - k, c);
    return x0;
  }

  /// x0 of a steady past: every past output y0, every past input u0 (one value per channel).
  template <class T>
  [[nodiscard]] Eigen::Matrix<T, Eigen::Dynamic, 1> held_state(const T& y0,
                                                               const Eigen::RowVectorXd& u0) const {
    const int ly = output_lag(), lu = input_lag();
    Eigen::Matrix<T, Eigen::Dynamic, 1> x0(state_dimension());
    for (int k = 0; k < ly; ++k) x0(k) = y0;
    for (int c = 0; c < num_inputs(); ++c)
      for (int k = 0; k < lu; ++k) x0(ly + c * lu + k) = T(u0(c));
    return x0;
  }

  /// Steady-state output y* = F(φ(y*, u0)) for the constant input u0 (Newton's method from
  /// `guess`, then a held-input simulation if Newton fails). Throws `nlid::Error` if none is found.
  [[nodiscard]] double equilibrium_output(const Eigen::RowVectorXd& u0, std::span<const double> theta,
                                          double guess = 0.0) const {
    using D = Dual<double, 1>;
    const std::vector<D> th = detail::cast_parameters<D>(theta);
    const Eigen::MatrixXd u1 = u0;
    double yv = guess;
    auto residual = [&](double y0, D& g) {
      const auto x0 = held_state<D>(D::variable(y0, 0), u0);
      D out[1];
      if (!simulate(u1, std::span<const D>(th), detail::as_const_span(x0), std::span<D>(out, 1))) return false;
      g = out[0] - D::variable(y0, 0);
      return true;
    };
    for (int it = 0; it < 60; ++it) {
      D g;
      if (!residual(yv, g)) break;
      if (std::abs(g.a) <= 1e-11 * (1.0 + std::abs(yv))) return yv;
      if (g.v[0] == 0.0) break;
      double step = -g.a / g.v[0];
      // Damped Newton: halve the step until |g| decreases (kinks of saturating maps).
      bool improved = false;
      for (int h = 0; h < 30 && !improved; ++h, step *= 0.5) {
        D g2;
        if (residual(yv + step, g2) && std::abs(g2.a) < std::abs(g.a)) {
          yv += step;
          improved = true;
        }
      }
      if (!improved) break;
    }
    // Fallback for maps where Newton stalls: let the model settle under the held input.
    const int n = 20000;
    Eigen::MatrixXd uh = u0.replicate(n, 1);
    Eigen::VectorXd ys(n);
    const Eigen::VectorXd x0 = held_state<double>(guess, u0);
    if (simulate(uh, theta, detail::as_const_span(x0), detail::as_span(ys))) {
      const double tail = (ys.tail(100).array() - ys(n - 1)).abs().maxCoeff();
      if (tail <= 1e-9 * (1.0 + std::abs(ys(n - 1)))) return ys(n - 1);
    }
    // A DivergenceError (at sample 0: the start cannot be formed), so that compare scores the
    // record as diverged, as it does a zero start that blows up.
    // Every channel: with several inputs, u0(0) alone misstated the operating point.
    std::string held = u0.size() == 1 ? "" : "(";
    for (Eigen::Index c = 0; c < u0.size(); ++c) held += (c ? ", " : "") + detail::format_g(u0(c), 4);
    if (u0.size() != 1) held += ")";
    throw DivergenceError("no steady state found for the held input u = " + held + " (the model oscillates or diverges)",
                          0, at_parameter("initial"));
  }

  // ---- user-level model (stored θ, sample time, channel names) -------------------------------

  /// Estimated (or set) parameters.
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
  /// Names of the parameters (those of the nonlinearity).
  [[nodiscard]] std::vector<std::string> parameter_names() const { return f_.parameter_names(); }

  /// Sample time in seconds (0: not set; then any data's sample time is accepted).
  [[nodiscard]] double ts() const { return ts_; }
  /// Sets the sample time (≥ 0).
  void set_ts(double ts) {
    require(ts >= 0.0 && std::isfinite(ts), "sample time must be >= 0 and finite", at_parameter("ts"));
    ts_ = ts;
  }
  /// Input channel names (default "u1", …).
  [[nodiscard]] const std::vector<std::string>& input_names() const { return input_names_; }
  /// Output channel name (default "y1").
  [[nodiscard]] const std::string& output_name() const { return output_name_; }
  /// Sets channel names (used by `regressor_names` and `describe`). Throws `nlid::Error` if a
  /// custom regressor's text would then name other channels than it reads (RegressorList).
  void set_channel_names(std::vector<std::string> inputs, std::string output) {
    if constexpr (requires { regs_.check_channel_names(inputs, output); }) regs_.check_channel_names(inputs, output);
    input_names_ = std::move(inputs);
    output_name_ = std::move(output);
  }

  /// The regressors as printed by the toolbox's getreg, with this model's channel names.
  [[nodiscard]] std::vector<std::string> regressor_names() const {
    return regs_.names(input_names_, output_name_);
  }
  /// Regressor values from measured data (getreg with data): row i is φ(n₀ + i)ᵀ.
  [[nodiscard]] Eigen::MatrixXd regressor_values(const Experiment& e) const {
    detail::check_experiment(e, -1, num_inputs(), history_length(), ts_, "nonlinear ARX");
    detail::check_channel_order(e.input_names(), input_names_, "input", detail::experiment_label(e, -1), {});
    return regressor_matrix(regs_, e.u(), e.y().col(0));
  }

  /// What the last estimation did.
  [[nodiscard]] const EstimationReport& report() const { return report_; }
  /// Records an estimation (called by the estimators).
  void set_report(EstimationReport r) { report_ = std::move(r); }

  /// x0 for an experiment under an initial-condition policy (for `measured`, the state at
  /// t = n₀). Throws `nlid::Error` naming the experiment on bad data.
  [[nodiscard]] Eigen::VectorXd initial_state(const Experiment& e, InitialCondition ic,
                                              long index = -1) const {
    // Only the measured and estimated starts read the record's first n0 outputs; a free run from
    // rest or an equilibrium needs one sample (a 2-sample record was refused for a model with
    // lag 3, though nothing of its past is read).
    const bool reads_past = ic == InitialCondition::measured || ic == InitialCondition::estimate;
    detail::check_experiment(e, index, num_inputs(), reads_past ? history_length() : 0, ts_, "nonlinear ARX");
    detail::check_channel_order(e.input_names(), input_names_, "input", detail::experiment_label(e, index),
                                detail::experiment_location(index));
    const Eigen::VectorXd y = e.y().col(0);
    switch (ic) {
      case InitialCondition::zero: return Eigen::VectorXd::Zero(state_dimension());
      case InitialCondition::measured: {
        // The start reads the first n0 outputs: a gap there is the data's, not a divergence.
        for (Eigen::Index k = 0; k < history_length(); ++k)
          require(std::isfinite(y(k)),
                  detail::experiment_label(e, index) + " has a missing (non-finite) output at sample " +
                      std::to_string(k) + ": the measured start reads the first " + std::to_string(history_length()) +
                      " outputs; fill the gap (Experiment::fill_missing) or cut the record there",
                  detail::experiment_location(index));
        return measured_state(e.u(), y, history_length());
      }
      case InitialCondition::equilibrium: {
        const Eigen::RowVectorXd u0 = e.u().row(0);
        // y(0) only guides Newton's method; a missing first output leaves the default guess.
        const double guess = std::isfinite(y(0)) ? y(0) : 0.0;
        return held_state<double>(equilibrium_output(u0, detail::as_const_span(theta_), guess), u0);
      }
      case InitialCondition::estimate: {
        detail::require_complete_for(e, index, true, "fit of the initial state");
        const Eigen::RowVectorXd u0 = e.u().row(0);
        const Eigen::VectorXd base = held_state<double>(y(0), u0);
        std::vector<int> free(static_cast<std::size_t>(output_lag()));
        for (int k = 0; k < output_lag(); ++k) free[static_cast<std::size_t>(k)] = k;
        return detail::estimate_initial_state(*this, e.u(), y, detail::as_const_span(theta_), base, free);
      }
    }
    return {};
  }

  /// Simulated output (N×1) of an experiment from its input alone, with the given initial
  /// condition (see the file comment). Throws `nlid::Error` naming the experiment if the data
  /// do not fit the model or the simulation diverges.
  [[nodiscard]] Eigen::MatrixXd simulate(const Experiment& e,
                                         InitialCondition ic = InitialCondition::zero) const {
    detail::require_complete_for(e, -1, false, "simulation");
    const Eigen::VectorXd x0 = initial_state(e, ic);
    const Eigen::Index n = e.size();
    Eigen::MatrixXd yhat(n, 1);
    Eigen::Index start = 0;
    if (ic == InitialCondition::measured) {
      start = history_length();
      yhat.topRows(start) = e.y().topRows(start);
    }
    const Eigen::Index bad = simulate_until(
        e.u().bottomRows(n - start), detail::as_const_span(theta_), detail::as_const_span(x0),
        std::span<double>(yhat.data() + start, static_cast<std::size_t>(n - start)));
    if (bad >= 0) {
      throw DivergenceError("simulation of " + detail::experiment_label(e, -1) + " diverges (output not finite at sample " +
                      std::to_string(bad + start) + ")",
                  static_cast<long>(bad + start), detail::experiment_location(-1));
    }
    return yhat;
  }

  /// k-step-ahead prediction ŷ(t | t−k) (N×1): the model is run k steps from the measured past
  /// at t−k. k = 1 is the one-step predictor; k ≥ N gives the simulation from measured past
  /// data. The first n₀ samples are the measured ones. Throws `nlid::Error` if k < 1.
  [[nodiscard]] Eigen::MatrixXd predict(const Experiment& e, int k = 1) const {
    require(k >= 1, "prediction horizon k must be >= 1, got " + std::to_string(k), at_parameter("k"));
    detail::check_experiment(e, -1, num_inputs(), history_length(), ts_, "nonlinear ARX");
    detail::check_channel_order(e.input_names(), input_names_, "input", detail::experiment_label(e, -1), {});
    detail::require_complete_for(e, -1, true, "prediction");
    const Eigen::Index n = e.size();
    const int n0 = history_length();
    const Eigen::VectorXd y = e.y().col(0);
    Eigen::MatrixXd yhat = Eigen::MatrixXd::Constant(n, 1, std::numeric_limits<double>::quiet_NaN());
    yhat.topRows(n0) = e.y().topRows(n0);
    if (k == 1) {
      // The core stops at the first non-finite prediction (the model overflows there): say
      // where, as the k-step branch does, instead of returning the unwritten rest.
      if (!predict(e.u(), y, detail::as_const_span(theta_),
                   std::span<double>(yhat.data() + n0, static_cast<std::size_t>(n - n0)))) {
        Eigen::Index t = n0;
        while (t < n && std::isfinite(yhat(t, 0))) ++t;
        throw DivergenceError("one-step prediction of " + detail::experiment_label(e, -1) +
                                  " is not finite at sample " + std::to_string(t) + " (the model overflows there)",
                              static_cast<long>(t), detail::experiment_location(-1));
      }
      return yhat;
    }
    if (k >= n - n0 && n > n0) {
      // Every window then starts at n0: the k-step predictions are one free run from the
      // measured state there (the loop below would re-run it for every t, O(N²)). A run that
      // diverges takes the loop, which names the sample.
      const Eigen::VectorXd x0 = measured_state(e.u(), y, n0);
      Eigen::VectorXd run(n - n0);
      if (simulate(e.u().middleRows(n0, n - n0), detail::as_const_span(theta_), detail::as_const_span(x0),
                   std::span<double>(run.data(), static_cast<std::size_t>(n - n0)))) {
        yhat.col(0).tail(n - n0) = run;
        return yhat;
      }
    }
    Eigen::VectorXd buf(std::min<Eigen::Index>(k, n));
    for (Eigen::Index t = n0; t < n; ++t) {
      const Eigen::Index s = std::max<Eigen::Index>(n0, t - k + 1);  // first simulated sample
      const Eigen::Index len = t - s + 1;
      const Eigen::VectorXd x0 = measured_state(e.u(), y, s);
      const bool ok = simulate(e.u().middleRows(s, len), detail::as_const_span(theta_), detail::as_const_span(x0),
                               std::span<double>(buf.data(), static_cast<std::size_t>(len)));
      if (!ok)
        throw DivergenceError("k-step prediction of " + detail::experiment_label(e, -1) + " diverges at sample " +
                                  std::to_string(t),
                              static_cast<long>(t), detail::experiment_location(-1));
      yhat(t, 0) = buf(len - 1);
    }
    return yhat;
  }

  /// Human-readable model: regressors, nonlinearity equation with values, parameters, and what
  /// the estimation did.
  [[nodiscard]] std::string describe() const {
    std::string s = "Nonlinear ARX model: " + output_name_ + "(t) = F(regressors)";
    if (ts_ > 0) s += ", sample time " + detail::format_g(ts_, 4) + " s";
    s += "\n  regressors (" + std::to_string(regs_.size()) + "):\n";
    const auto names = regressor_names();
    for (std::size_t i = 0; i < names.size(); ++i) s += "    x[" + std::to_string(i) + "] = " + names[i] + "\n";
    s += "  nonlinearity F: ";
    const std::span<const double> th = detail::as_const_span(theta_);
    if constexpr (requires { f_.describe(th, names); }) {
      s += f_.describe(th, names);
    } else {
      s += f_.describe(th);
    }
    if (!s.empty() && s.back() != '\n') s += "\n";
    s += "  parameters (" + std::to_string(num_parameters()) + "):\n";
    const auto pn = parameter_names();
    for (Eigen::Index i = 0; i < theta_.size(); ++i) {
      s += "    " + (static_cast<std::size_t>(i) < pn.size() ? pn[static_cast<std::size_t>(i)] : "p" + std::to_string(i)) +
           " = " + detail::format_g(theta_(i)) + "\n";
    }
    s += detail::describe_report(report_);
    return s;
  }

  // ---- Implementation details below ----------------------------------------------------------
 private:
  template <class T>
  using RegressorVector = Eigen::Matrix<T, R::num_regressors, 1>;

  template <class T>
  RegressorVector<T> make_regressor_vector() const {
    if constexpr (R::num_regressors == Dynamic) {
      return RegressorVector<T>(regs_.size());
    } else {
      return RegressorVector<T>();
    }
  }

  void check_core_sizes(Eigen::Index nu, std::size_t ntheta, std::size_t nx0, Eigen::Index ny,
                        Eigen::Index n) const {
    if (nu != num_inputs())
      throw Error("input matrix has " + std::to_string(nu) + " columns, the model reads " +
                      std::to_string(num_inputs()) + " input(s)",
                  at_parameter("u"));
    if (static_cast<int>(ntheta) != num_parameters())
      throw Error("parameter vector has " + std::to_string(ntheta) + " values, the model has " +
                      std::to_string(num_parameters()),
                  at_parameter("theta"));
    if (nx0 != 0 && static_cast<int>(nx0) != state_dimension())
      throw Error("initial state has " + std::to_string(nx0) + " values, the model's state has " +
                      std::to_string(state_dimension()),
                  at_parameter("x0"));
    if (ny != n)
      throw Error("output buffer has " + std::to_string(ny) + " entries for " + std::to_string(n) + " samples",
                  at_parameter("y"));
  }

  R regs_;
  F f_;
  Eigen::VectorXd theta_;
  double ts_ = 0.0;
  std::vector<std::string> input_names_;
  std::string output_name_ = "y1";
  EstimationReport report_;
};

/// Deduction guide: `Nlarx model{regs, SigmoidNet<…>{}}`.
template <class R, class F>
Nlarx(R, F) -> Nlarx<R, F>;
/// Deduction guide with a sample time.
template <class R, class F>
Nlarx(R, F, double) -> Nlarx<R, F>;

}  // namespace nlid
