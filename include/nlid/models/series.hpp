#pragma once
/// @file
/// `Series<Blocks...>`: any chain of linear dynamic blocks and static scalar nonlinearities,
/// composed at compile time — Hammerstein, Wiener, Wiener–Hammerstein and Hammerstein–Wiener
/// models are aliases of this one template.
///
/// Math (Ljung 1999, sec. 5.2 "block-oriented models"; Giri & Bai (eds.), "Block-oriented
/// Nonlinear System Identification", Springer 2010, ch. 1; Schoukens & Tiels, "Identification
/// of block-oriented nonlinear systems starting from linear approximations: a survey",
/// Automatica 85, 2017). A signal v₀(t) = u(t) passes K blocks in turn,
///
///     v_k(t) = G_k(q; θ_k) v_{k−1}(t)        linear block:  B_k(q)/F_k(q) v(t − nk_k)
///     v_k(t) = g_k(v_{k−1}(t); θ_k)          static block:  a scalar map (ScalarNonlinearity)
///
/// and y(t) = v_K(t). Common chains and their aliases:
///
///     Hammerstein          N–L     y = G(q) f(u)                 `Hammerstein<N, L>`
///     Wiener               L–N     y = h(G(q) u)                 `Wiener<L, N>`
///     Wiener–Hammerstein   L–N–L   y = G₂(q) g(G₁(q) u)          `WienerHammerstein<L1, N, L2>`
///     Hammerstein–Wiener   N–L–N   y = h(G(q) f(u))              `HammersteinWienerSeries<N1, L, N2>`
///
/// Parameters are stacked in chain order, θ = [θ₁, …, θ_K]; the model's state is the stacked
/// state of its linear blocks (each in transposed direct form II, see
/// transfer_function_block.hpp), x = [s₁, s₂, …]. There is no noise model (output-error
/// structure, Ljung 1999 eq. 4.25): the one-step predictor equals the simulation.
///
/// Ambiguities (why estimates are not unique without extra constraints): a gain can move
/// between neighbouring blocks (G₁·a, g(·/a)), and for L–N–L the poles and zeros of the
/// product G₁G₂ can be assigned to either side only once — which is why the estimator
/// (series_estimate.hpp) searches the assignments explicitly instead of hoping the
/// optimiser finds the right one.
///
/// Sizes: each block's sizes are static or `Dynamic`. With all of them static, parameters and
/// state have compile-time sizes and a simulation allocates nothing (tests/nomalloc); the
/// Dynamic twins of the blocks run exactly the same code.
///
/// Scalar genericity: `simulate<T>` runs on double, float and `Dual` (Jacobians of the free-run
/// simulation by forward AD, as the estimators use).

#include <array>
#include <cmath>
#include <cstddef>
#include <limits>
#include <span>
#include <string>
#include <tuple>
#include <type_traits>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "nlid/ad/dual.hpp"
#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/core/initial_condition.hpp"
#include "nlid/core/sizes.hpp"
#include "nlid/data/experiment.hpp"
#include "nlid/models/concepts.hpp"
#include "nlid/models/detail/initial_state.hpp"
#include "nlid/models/detail/model_common.hpp"
#include "nlid/models/transfer_function_block.hpp"
#include "nlid/nonlinearities/concepts.hpp"

namespace nlid {

/// A block of a series chain: a linear dynamic block or a static map of one input.
/// Satisfied by `TransferFunctionBlock<Nb, Nf, Nk>` (LinearBlock) and by every
/// ScalarNonlinearity (UnitGain, PwLinear, Saturation, DeadZone, Poly1d, SigmoidNet<1,…>, …).
template <class B>
concept SeriesBlock = LinearBlock<B> || ScalarNonlinearity<B>;

namespace detail {

/// Static state count contributed by one block (static blocks have none).
template <class B>
constexpr int series_block_states() {
  if constexpr (LinearBlock<B>) {
    return B::num_states;
  } else {
    return 0;
  }
}

/// Pattern of a chain as letters, e.g. "LNL" — the basis of its name and its role labels.
template <class... B>
std::string series_pattern() {
  std::string s;
  ((s += LinearBlock<B> ? 'L' : 'N'), ...);
  return s;
}

}  // namespace detail

/// A chain of linear blocks and static scalar nonlinearities, y = B_K ∘ … ∘ B_1 (u).
/// Single input, single output.
/// Invariant: every static block has input dimension 1; `parameters()` has `num_parameters()`
/// entries laid out [θ₁, …, θ_K]; the state is [s of each linear block, in chain order].
template <SeriesBlock... Blocks>
  requires(sizeof...(Blocks) >= 1)
class Series {
 public:
  /// Number of blocks K.
  static constexpr std::size_t num_blocks = sizeof...(Blocks);
  /// p = Σ p_k, or Dynamic.
  static constexpr int num_params = size_sum(Blocks::num_params...);
  /// n = Σ over linear blocks of their state counts, or Dynamic.
  static constexpr int num_states = size_sum(detail::series_block_states<Blocks>()...);
  /// Parameter vector of a fixed-size solver.
  using Parameters = Eigen::Matrix<double, num_params, 1>;
  /// Type of block I.
  template <std::size_t I>
  using Block = std::tuple_element_t<I, std::tuple<Blocks...>>;
  /// True if block I is linear (dynamic), false if it is a static nonlinearity.
  template <std::size_t I>
  static constexpr bool is_linear = LinearBlock<Block<I>>;
  /// Number of linear blocks.
  static constexpr int num_linear_blocks = (0 + ... + (LinearBlock<Blocks> ? 1 : 0));

  /// Structure from compile-time components.
  Series()
    requires(std::is_default_constructible_v<Blocks> && ...)
      : Series(Blocks{}...) {}

  /// Structure from components (θ starts at zero). Throws `nlid::Error` naming the block if a
  /// static block does not have exactly one input.
  explicit Series(Blocks... blocks, double ts = 0.0) : blocks_(std::move(blocks)...) {
    layout(std::index_sequence_for<Blocks...>{});
    theta_ = Eigen::VectorXd::Zero(num_parameters());
    set_ts(ts);
  }

  // ---- structure -----------------------------------------------------------------------------

  /// Block I (const).
  template <std::size_t I>
  [[nodiscard]] const Block<I>& block() const { return std::get<I>(blocks_); }
  /// Block I (mutable: e.g. for a nonlinearity's `initialize`, which learns normalisations).
  /// Do not change its parameter or state counts: the model's layout was fixed at construction.
  template <std::size_t I>
  [[nodiscard]] Block<I>& block() { return std::get<I>(blocks_); }

  /// p = Σ p_k.
  [[nodiscard]] int num_parameters() const { return p_off_[num_blocks]; }
  /// Offset of θ_k in θ (k = 0 … K; k = K gives p). Throws `nlid::Error` for k > K.
  [[nodiscard]] int parameter_offset(std::size_t k) const {
    check_block_index(k, num_blocks);
    return p_off_[k];
  }
  /// Number of parameters of block k. Throws `nlid::Error` for k ≥ K.
  [[nodiscard]] int block_num_parameters(std::size_t k) const {
    check_block_index(k, num_blocks - 1);
    return p_off_[k + 1] - p_off_[k];
  }
  /// Offset of block k's state in x0 (static blocks: where the next linear block's state starts).
  /// Throws `nlid::Error` for k > K.
  [[nodiscard]] int state_offset(std::size_t k) const {
    check_block_index(k, num_blocks);
    return s_off_[k];
  }
  /// One input.
  [[nodiscard]] int num_inputs() const { return 1; }
  /// One output.
  [[nodiscard]] int num_outputs() const { return 1; }
  /// Size of x0: the stacked linear-block states.
  [[nodiscard]] int state_dimension() const { return s_off_[num_blocks]; }
  /// "L"/"N" per block in chain order, e.g. "LNL" for a Wiener–Hammerstein model.
  [[nodiscard]] static std::string pattern() { return detail::series_pattern<Blocks...>(); }
  /// The chain's common name: "Hammerstein", "Wiener", "Wiener-Hammerstein",
  /// "Hammerstein-Wiener", "linear", or "block-oriented series" for other chains.
  [[nodiscard]] static std::string kind() {
    const std::string p = pattern();
    if (p == "NL") return "Hammerstein";
    if (p == "LN") return "Wiener";
    if (p == "LNL") return "Wiener-Hammerstein";
    if (p == "NLN") return "Hammerstein-Wiener";
    if (p == "L") return "linear";
    return "block-oriented series";
  }
  /// Role label of block k as used in parameter names: "input"/"output" for a static block at
  /// the start/end of the chain, "static" (or "static2", …) inside, "linear" for the only
  /// linear block (or "linear1", "linear2", … in chain order).
  [[nodiscard]] std::string block_label(std::size_t k) const { return labels_.at(k); }

  // ---- Hammerstein–Wiener-compatible accessors (superset of HammersteinWiener's API) --------

  /// The static block at the start of the chain (f of Hammerstein and Hammerstein–Wiener).
  [[nodiscard]] const Block<0>& input_nonlinearity() const
    requires(!is_linear<0>)
  { return block<0>(); }
  /// Mutable input nonlinearity (for `initialize`).
  [[nodiscard]] Block<0>& input_nonlinearity()
    requires(!is_linear<0>)
  { return block<0>(); }
  /// The static block at the end of the chain (h of Wiener and Hammerstein–Wiener).
  [[nodiscard]] const Block<num_blocks - 1>& output_nonlinearity() const
    requires(!is_linear<num_blocks - 1>)
  { return block<num_blocks - 1>(); }
  /// Mutable output nonlinearity (for `initialize`).
  [[nodiscard]] Block<num_blocks - 1>& output_nonlinearity()
    requires(!is_linear<num_blocks - 1>)
  { return block<num_blocks - 1>(); }
  /// The only linear block of a chain with exactly one (Hammerstein, Wiener, H–W).
  [[nodiscard]] const auto& linear_block() const
    requires(num_linear_blocks == 1)
  { return block<first_linear()>(); }
  /// Offset of the only linear block's θ in θ.
  [[nodiscard]] int linear_offset() const
    requires(num_linear_blocks == 1)
  { return p_off_[first_linear()]; }
  /// Offset of the output nonlinearity's θ in θ.
  [[nodiscard]] int output_offset() const
    requires(!is_linear<num_blocks - 1>)
  { return p_off_[num_blocks - 1]; }
  /// θ of the input nonlinearity (view of the stored parameters).
  [[nodiscard]] std::span<const double> input_parameters() const
    requires(!is_linear<0>)
  { return block_parameters(0); }
  /// θ of the only linear block: [b₁ … b_nb, f₁ … f_nf].
  [[nodiscard]] std::span<const double> linear_parameters() const
    requires(num_linear_blocks == 1)
  { return block_parameters(first_linear()); }
  /// θ of the output nonlinearity.
  [[nodiscard]] std::span<const double> output_parameters() const
    requires(!is_linear<num_blocks - 1>)
  { return block_parameters(num_blocks - 1); }
  /// Sets the only linear block from toolbox polynomials B (with or without the nk leading
  /// zeros) and monic F.
  void set_linear_polynomials(const Eigen::VectorXd& b, const Eigen::VectorXd& f)
    requires(num_linear_blocks == 1)
  { set_block_polynomials<first_linear()>(b, f); }
  /// Sets the only linear block from a previously estimated linear model with the toolbox
  /// polynomials `b_polynomial()` and monic `f_polynomial()` (an `OutputError` model).
  template <class LinearModel>
    requires(num_linear_blocks == 1) && requires(const LinearModel& m) {
      { m.b_polynomial() } -> std::convertible_to<Eigen::VectorXd>;
      { m.f_polynomial() } -> std::convertible_to<Eigen::VectorXd>;
    }
  void set_linear_block(const LinearModel& m) {
    set_linear_polynomials(m.b_polynomial(), m.f_polynomial());
  }

  // ---- per-block parameters ------------------------------------------------------------------

  /// θ_k as a view of the stored parameters.
  [[nodiscard]] std::span<const double> block_parameters(std::size_t k) const {
    check_block_index(k, num_blocks - 1);
    return std::span<const double>(theta_.data() + p_off_[k], static_cast<std::size_t>(block_num_parameters(k)));
  }
  /// Sets θ_k. Throws `nlid::Error` naming the block if the length is wrong or a value is not
  /// finite.
  void set_block_parameters(std::size_t k, std::span<const double> theta_k) {
    check_block_index(k, num_blocks - 1);
    require(static_cast<int>(theta_k.size()) == block_num_parameters(k),
            "block " + std::to_string(k) + " (" + labels_.at(k) + ") has " +
                std::to_string(block_num_parameters(k)) + " parameters, got " + std::to_string(theta_k.size()),
            at_parameter(labels_.at(k)));
    for (std::size_t j = 0; j < theta_k.size(); ++j)
      require(std::isfinite(theta_k[j]),
              "block " + std::to_string(k) + " (" + labels_.at(k) + "): parameter " + std::to_string(j) + " is not finite",
              at_parameter(labels_.at(k)));
    for (std::size_t j = 0; j < theta_k.size(); ++j) theta_(p_off_[k] + static_cast<Eigen::Index>(j)) = theta_k[j];
  }
  /// Sets linear block I from toolbox polynomials B̃ (with or without nk leading zeros) and
  /// monic F. Throws `nlid::Error` naming "B" or "F" on wrong lengths.
  template <std::size_t I>
    requires(is_linear<I>)
  void set_block_polynomials(const Eigen::VectorXd& b, const Eigen::VectorXd& f) {
    block<I>().set_from_polynomials(b, f, std::span<double>(theta_.data() + p_off_[I],
                                                            static_cast<std::size_t>(block_num_parameters(I))));
  }
  /// Toolbox polynomials (B̃ with nk leading zeros, monic F) of linear block I.
  template <std::size_t I>
    requires(is_linear<I>)
  [[nodiscard]] std::pair<Eigen::VectorXd, Eigen::VectorXd> block_polynomials() const {
    return block<I>().polynomials(block_parameters(I));
  }

  // ---- scalar-generic core -------------------------------------------------------------------

  /// Free-run simulation ŷ(0 … N−1) for inputs `u` (N×1) from the stacked linear-block state
  /// `x0` (empty: at rest). Returns false if the output becomes non-finite or exceeds `limit`.
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
    State<T> s = make_state<T>();
    for (Eigen::Index i = 0; i < s.size(); ++i) s(i) = x0.empty() ? T(0) : x0[static_cast<std::size_t>(i)];
    const std::span<T> ss(s.data(), static_cast<std::size_t>(s.size()));
    using std::abs;
    for (Eigen::Index t = 0; t < u.rows(); ++t) {
      T v(u(t, 0));
      step_all(v, theta, ss, std::index_sequence_for<Blocks...>{});
      if (!detail::is_finite_scalar(v) || abs(static_cast<double>(value_of(v))) > limit) return t;
      y[static_cast<std::size_t>(t)] = std::move(v);
    }
    return -1;
  }

  /// One sample of the chain on any scalar: ŷ(t) for input `u` at t, advancing the stacked state
  /// `s` (`state_dimension()` entries) to t + 1 — the operations of `simulate`'s loop body, so
  /// generated C code (codegen/series.hpp) can trace it. Sizes are not checked here.
  template <class T>
  T step(std::span<T> s, T u, std::span<const T> theta) const {
    step_all(u, theta, s, std::index_sequence_for<Blocks...>{});
    return u;
  }

  /// One-step prediction: equal to the simulation from `x0` (output-error structure).
  template <class T>
  bool predict(const Eigen::Ref<const Eigen::MatrixXd>& u, const Eigen::Ref<const Eigen::VectorXd>& /*y*/,
               std::span<const T> theta, std::span<const T> x0, std::span<T> yhat) const {
    return simulate(u, theta, x0, yhat);
  }

  /// Intermediate signals of a simulation (double): column k is the output of block k, so the
  /// last column is ŷ. Shows which block does what (e.g. the range the static block sees).
  [[nodiscard]] Eigen::MatrixXd signals(const Eigen::Ref<const Eigen::MatrixXd>& u, std::span<const double> theta,
                                        std::span<const double> x0) const {
    check_core_sizes(u.cols(), theta.size(), x0.size(), u.rows(), u.rows());
    State<double> s = make_state<double>();
    for (Eigen::Index i = 0; i < s.size(); ++i) s(i) = x0.empty() ? 0.0 : x0[static_cast<std::size_t>(i)];
    const std::span<double> ss(s.data(), static_cast<std::size_t>(s.size()));
    Eigen::MatrixXd out(u.rows(), static_cast<Eigen::Index>(num_blocks));
    for (Eigen::Index t = 0; t < u.rows(); ++t) {
      double v = u(t, 0);
      record_all(v, theta, ss, out, t, std::index_sequence_for<Blocks...>{});
    }
    return out;
  }

  /// Stacked state in steady state for the constant input u0: the constant is passed through
  /// the chain, each linear block settles at its steady state for its constant input (a block
  /// with F(1) = 0 — an integrator — stays at rest and passes its input on unchanged).
  template <class T>
  [[nodiscard]] Eigen::Matrix<T, Eigen::Dynamic, 1> equilibrium_state(double u0, std::span<const T> theta) const {
    Eigen::Matrix<T, Eigen::Dynamic, 1> s = Eigen::Matrix<T, Eigen::Dynamic, 1>::Constant(state_dimension(), T(0));
    T v(u0);
    equilibrium_all(v, theta, std::span<T>(s.data(), static_cast<std::size_t>(s.size())),
                    std::index_sequence_for<Blocks...>{});
    return s;
  }

  // ---- user-level model ----------------------------------------------------------------------

  /// Estimated (or set) parameters [θ₁, …, θ_K].
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
  /// Names "<role>:<block's name>", e.g. "linear1:b1", "static:c[3]", "output:upper".
  [[nodiscard]] std::vector<std::string> parameter_names() const {
    std::vector<std::string> n;
    names_all(n, std::index_sequence_for<Blocks...>{});
    return n;
  }

  /// Sample time in seconds (0: not set).
  [[nodiscard]] double ts() const { return ts_; }
  /// Sets the sample time (≥ 0, finite).
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

  /// x0 for an experiment under an initial-condition policy: `zero` (at rest), `equilibrium`
  /// (steady state for u(0) held), `estimate` (all states by least squares on the record,
  /// started from the equilibrium). Throws `nlid::Error` naming the experiment on bad data, or
  /// for `measured` (a block state is not a measured signal).
  [[nodiscard]] Eigen::VectorXd initial_state(const Experiment& e, InitialCondition ic, long index = -1) const {
    detail::check_experiment(e, index, 1, 0, ts_, kind().c_str());
    const std::span<const double> th = detail::as_const_span(theta_);
    switch (ic) {
      case InitialCondition::zero: return Eigen::VectorXd::Zero(state_dimension());
      case InitialCondition::equilibrium: return equilibrium_state<double>(e.u()(0, 0), th);
      case InitialCondition::estimate: {
        detail::require_complete_for(e, index, true, "fit of the initial state");
        std::vector<int> free(static_cast<std::size_t>(state_dimension()));
        for (int i = 0; i < state_dimension(); ++i) free[static_cast<std::size_t>(i)] = i;
        const Eigen::VectorXd y = e.y().col(0);
        return detail::estimate_initial_state(*this, e.u(), y, th, equilibrium_state<double>(e.u()(0, 0), th), free);
      }
      case InitialCondition::measured: break;
    }
    throw Error("InitialCondition::measured applies to regression models (past outputs are their state); a " + kind() +
                    " model's state is internal: use zero, equilibrium or estimate",
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

  /// Human-readable model: the chain as a formula, each block with its equation and values,
  /// and the estimation report.
  [[nodiscard]] std::string describe() const {
    std::string s = kind() + " model (" + chain_formula() + ")";
    if (ts_ > 0) s += ", sample time " + detail::format_g(ts_, 4) + " s";
    s += "\n";
    describe_all(s, std::index_sequence_for<Blocks...>{});
    s += detail::describe_report(report_);
    return s;
  }

  // ---- Implementation details below ----------------------------------------------------------
 private:
  static void check_block_index(std::size_t k, std::size_t last) {
    require(k <= last, "block " + std::to_string(k) + " is out of range: the chain has " + std::to_string(num_blocks) +
                           " block(s), 0 ... " + std::to_string(num_blocks - 1),
            at_parameter("block"));
  }
  template <class T>
  using State = Eigen::Matrix<T, num_states, 1>;

  static constexpr std::size_t first_linear() {
    std::size_t k = 0;
    const bool lin[] = {LinearBlock<Blocks>...};
    while (k < num_blocks && !lin[k]) ++k;
    return k;
  }

  template <class T>
  State<T> make_state() const {
    if constexpr (num_states == Dynamic) {
      return State<T>(state_dimension());
    } else {
      return State<T>();
    }
  }

  template <std::size_t... I>
  void layout(std::index_sequence<I...>) {
    const std::string p = pattern();
    const int nlin = num_linear_blocks;
    const int nstat = static_cast<int>(num_blocks) - nlin;
    int li = 0, si = 0;
    // Roles first (error messages below use them).
    for (std::size_t k = 0; k < num_blocks; ++k) {
      if (p[k] == 'L') {
        ++li;
        labels_[k] = nlin == 1 ? "linear" : "linear" + std::to_string(li);
      } else if (k == 0 && num_blocks > 1) {
        labels_[k] = "input";
      } else if (k + 1 == num_blocks && num_blocks > 1) {
        labels_[k] = "output";
      } else {
        ++si;
        const int inner = nstat - (p.front() == 'N' && num_blocks > 1 ? 1 : 0) - (p.back() == 'N' && num_blocks > 1 ? 1 : 0);
        labels_[k] = inner <= 1 ? "static" : "static" + std::to_string(si);
      }
    }
    p_off_[0] = 0;
    s_off_[0] = 0;
    (layout_block<I>(), ...);
  }

  template <std::size_t I>
  void layout_block() {
    const auto& b = std::get<I>(blocks_);
    if constexpr (LinearBlock<Block<I>>) {
      s_off_[I + 1] = s_off_[I] + b.num_states_runtime();
    } else {
      require(b.input_dimension() == 1,
              "the " + role_noun(I) + " must have one input, it has " + std::to_string(b.input_dimension()),
              at_parameter(labels_[I] == "input" ? "input_nonlinearity"
                           : labels_[I] == "output" ? "output_nonlinearity" : labels_[I]));
      s_off_[I + 1] = s_off_[I];
    }
    p_off_[I + 1] = p_off_[I] + b.num_parameters();
  }

  std::string role_noun(std::size_t k) const {
    if (labels_[k] == "input") return "input nonlinearity";
    if (labels_[k] == "output") return "output nonlinearity";
    return "static nonlinearity (block " + std::to_string(k) + ")";
  }

  template <class T, std::size_t... I>
  void step_all(T& v, std::span<const T> theta, std::span<T> s, std::index_sequence<I...>) const {
    (step_block<I>(v, theta, s), ...);
  }

  template <std::size_t I, class T>
  void step_block(T& v, std::span<const T> theta, std::span<T> s) const {
    const auto& b = std::get<I>(blocks_);
    const std::span<const T> th = theta.subspan(static_cast<std::size_t>(p_off_[I]),
                                                static_cast<std::size_t>(p_off_[I + 1] - p_off_[I]));
    if constexpr (LinearBlock<Block<I>>) {
      v = b.step(s.subspan(static_cast<std::size_t>(s_off_[I]), static_cast<std::size_t>(s_off_[I + 1] - s_off_[I])),
                 v, th);
    } else {
      const T x = v;
      v = b(std::span<const T>(&x, 1), th);
    }
  }

  template <std::size_t... I>
  void record_all(double& v, std::span<const double> theta, std::span<double> s, Eigen::MatrixXd& out,
                  Eigen::Index t, std::index_sequence<I...>) const {
    ((step_block<I>(v, theta, s), out(t, static_cast<Eigen::Index>(I)) = v), ...);
  }

  template <class T, std::size_t... I>
  void equilibrium_all(T& v, std::span<const T> theta, std::span<T> s, std::index_sequence<I...>) const {
    (equilibrium_block<I>(v, theta, s), ...);
  }

  template <std::size_t I, class T>
  void equilibrium_block(T& v, std::span<const T> theta, std::span<T> s) const {
    const auto& b = std::get<I>(blocks_);
    const std::span<const T> th = theta.subspan(static_cast<std::size_t>(p_off_[I]),
                                                static_cast<std::size_t>(p_off_[I + 1] - p_off_[I]));
    if constexpr (LinearBlock<Block<I>>) {
      const std::span<T> si =
          s.subspan(static_cast<std::size_t>(s_off_[I]), static_cast<std::size_t>(s_off_[I + 1] - s_off_[I]));
      if (!b.equilibrium_state(v, th, si)) {
        for (auto& x : si) x = T(0);
        return;
      }
      // The block's steady output: one step from its steady state leaves it unchanged.
      std::vector<T> copy(si.begin(), si.end());
      v = b.step(std::span<T>(copy), v, th);
    } else {
      const T x = v;
      v = b(std::span<const T>(&x, 1), th);
    }
  }

  template <std::size_t... I>
  void names_all(std::vector<std::string>& n, std::index_sequence<I...>) const {
    (
        [&] {
          for (auto& s : std::get<I>(blocks_).parameter_names()) n.push_back(labels_[I] + ":" + s);
        }(),
        ...);
  }

  template <std::size_t... I>
  void describe_all(std::string& s, std::index_sequence<I...>) const {
    (
        [&] {
          const auto th = block_parameters(I);
          if constexpr (LinearBlock<Block<I>>) {
            s += "  " + labels_[I] + ": " + std::get<I>(blocks_).describe(th);
          } else {
            s += "  " + labels_[I] + " nonlinearity: " + std::get<I>(blocks_).describe(th);
          }
          if (s.back() != '\n') s += "\n";
        }(),
        ...);
  }

  std::string chain_formula() const {
    std::string inner = input_name_;
    const std::string p = pattern();
    int li = 0, si = 0;
    for (std::size_t k = 0; k < num_blocks; ++k) {
      if (p[k] == 'L') {
        ++li;
        inner = (num_linear_blocks == 1 ? std::string("G") : "G" + std::to_string(li)) + "(q) " +
                (k == 0 ? inner : "[" + inner + "]");
      } else {
        ++si;
        inner = (labels_[k] == "input" ? std::string("f") : labels_[k] == "output" ? std::string("h")
                                                                                  : "g" + std::to_string(si)) +
                "(" + inner + ")";
      }
    }
    return output_name_ + " = " + inner;
  }

  void check_core_sizes(Eigen::Index nu, std::size_t ntheta, std::size_t nx0, Eigen::Index ny, Eigen::Index n) const {
    if (nu != 1)
      throw Error("input matrix has " + std::to_string(nu) + " columns, the model reads 1 input", at_parameter("u"));
    if (static_cast<int>(ntheta) != num_parameters())
      throw Error("parameter vector has " + std::to_string(ntheta) + " values, the model has " +
                      std::to_string(num_parameters()),
                  at_parameter("theta"));
    if (nx0 != 0 && static_cast<int>(nx0) != state_dimension())
      throw Error("initial state has " + std::to_string(nx0) + " values, the linear blocks have " +
                      std::to_string(state_dimension()) + " states",
                  at_parameter("x0"));
    if (ny != n)
      throw Error("output buffer has " + std::to_string(ny) + " entries for " + std::to_string(n) + " samples",
                  at_parameter("y"));
  }

  std::tuple<Blocks...> blocks_;
  std::array<int, num_blocks + 1> p_off_{};
  std::array<int, num_blocks + 1> s_off_{};
  std::array<std::string, num_blocks> labels_;
  Eigen::VectorXd theta_;
  double ts_ = 0.0;
  std::string input_name_ = "u1";
  std::string output_name_ = "y1";
  EstimationReport report_;
};

/// Deduction guide: `Series s{TransferFunctionBlock<2, 2, 0>{}, Poly1d<3>{}, TransferFunctionBlock<2, 2, 0>{}}`.
template <SeriesBlock... B>
Series(B...) -> Series<B...>;
/// Deduction guides with a trailing sample time (chains of 2 to 4 blocks).
template <SeriesBlock A, SeriesBlock B>
Series(A, B, double) -> Series<A, B>;
/// See above.
template <SeriesBlock A, SeriesBlock B, SeriesBlock C>
Series(A, B, C, double) -> Series<A, B, C>;
/// See above.
template <SeriesBlock A, SeriesBlock B, SeriesBlock C, SeriesBlock D>
Series(A, B, C, D, double) -> Series<A, B, C, D>;

/// Hammerstein model y = G(q) f(u): static input map N, then linear block L.
template <ScalarNonlinearity N, LinearBlock L>
using Hammerstein = Series<N, L>;
/// Wiener model y = h(G(q) u): linear block L, then static output map N.
template <LinearBlock L, ScalarNonlinearity N>
using Wiener = Series<L, N>;
/// Wiener–Hammerstein model y = G₂(q) g(G₁(q) u): the chain "LNL".
template <LinearBlock L1, ScalarNonlinearity N, LinearBlock L2>
using WienerHammerstein = Series<L1, N, L2>;
/// Hammerstein–Wiener chain y = h(G(q) f(u)) ("NLN") — the structure of `HammersteinWiener`,
/// which is meant to become an alias of this.
template <ScalarNonlinearity N1, LinearBlock L, ScalarNonlinearity N2>
using HammersteinWienerSeries = Series<N1, L, N2>;

}  // namespace nlid
