#pragma once
/// @file
/// Levenberg–Marquardt for bound-constrained, robust nonlinear least squares.
///
/// Problem (see `concepts.hpp`, `robust_loss.hpp`):
///
///     min_θ F(θ) = ½ Σᵢ ρ(rᵢ(θ)²)   subject to  l ≤ θ ≤ u,  θ_k = θ⁰_k for fixed k
///     (plus ½λ_R Σ_k R_k(θ_k − θ̄_k)² when regularized, below).
///
/// Each iteration linearises r about θ, r(θ + δ) ≈ r + Jδ, and minimises the damped model
/// (Levenberg 1944; Marquardt 1963; Moré 1978; Ljung 1999, sec. 10.2, eq. 10.40)
///
///     m(δ) = ½‖r̃ + J̃δ‖² + ½λ‖Dδ‖²   ⇔   (J̃ᵀJ̃ + λD²) δ = −J̃ᵀr̃,
///
/// where r̃ = w∘r, J̃ = diag(w)J are the robustly reweighted residuals and Jacobian (w = 1 for
/// squared loss; J̃ᵀr̃ = ∇F exactly). Notation used below: A = J̃ᵀJ̃, g = J̃ᵀr̃.
///
/// Scaling D (`LmOptions::scaling`). `running_max` (`automatic` here; Marquardt 1963, Moré 1978 sec. 3):
/// D = diag(d_k), d_k the largest column norm ‖J̃_k‖ seen so far in this solve: the iteration
/// becomes invariant to the units of the parameters (a gain in degrees and a time constant in
/// seconds are damped alike). `current`: d_k the column norm at the current θ, floored at
/// 10⁻³(1 + ‖J̃_k‖) (Marquardt's original choice; Ceres Solver's LM). `levenberg`:
/// D = √(max_k A_kk)·I (Levenberg damping made dimensionless, Madsen et al. 2004, eq. 3.14). The
/// solver works in the scaled variables y = Dδ, so λ is dimensionless: the
/// scaled system is (Â + λI) y = −ĝ with Â = D⁻¹AD⁻¹ (diagonal ≤ 1), ĝ = D⁻¹g.
///
/// Linear algebra. The damped system is factored by LDLT (pivoted Cholesky, n³/3 flops). If the
/// factorisation is not positive definite or its reciprocal condition estimate is below 10⁻¹²
/// (forming Â squares the condition number of J), the step is recomputed from a Householder QR
/// of the scaled Jacobian, Ĵ = QR, followed per λ by the QR of the 2n×n matrix [R; √λ I]
/// (Moré's MINPACK scheme, 1978, sec. 3): accurate to cond(J)·ε instead of cond(J)²·ε.
///
/// Damping update (Nielsen 1999; Madsen, Nielsen & Tingleff 2004, eq. 3.15): with the gain
/// ratio ϱ = (F(θ) − F(θ+δ)) / (m(0) − m(δ)), a step is accepted when ϱ > 10⁻³, then
/// λ ← λ·max(⅓, 1 − (2ϱ − 1)³), ν ← 2; otherwise λ ← λν, ν ← 2ν.
///
/// Bounds (projected LM; Kanzow, Yamashita & Fukushima 2004; Bertsekas 1982 for the active
/// set). A parameter on a bound whose gradient points out of the box (k at l_k with g_k > 0 or
/// at u_k with g_k < 0) is held for that iteration; the others take the damped step, and the
/// result is projected onto [l, u]. The model decrease m(0) − m(δ) is computed for the projected
/// step, so the gain-ratio test stays honest. First-order optimality is measured by the
/// projected gradient ‖θ − P(θ − ∇F)‖∞, which is zero exactly at KKT points.
///
/// Fixed parameters are held the same way and are returned bit-for-bit unchanged.
///
/// Regularization (`LmOptions::regularization`; Ljung 1999, sec. 7.2 "regularization", the
/// toolbox's `Regularization.Lambda/R/Nominal`): F gains ½λ_R Σ_k R_k (θ_k − θ̄_k)², a pull
/// towards a nominal θ̄ that keeps over-parameterised models (many network units, short data)
/// from fitting noise. It is exact in the quadratic model: A += λ_R R, g += λ_R R(θ − θ̄); the QR
/// fallback stacks the rows √(λ_R R_k)·δ_k under R before the damping rows. The reported costs
/// include the penalty.
///
/// Memory. `LevenbergMarquardt<Problem>` allocates all workspace in `setup` (r, trial r, IRLS
/// weights, the m×n Jacobian, n×n matrices); the QR fallback works in place in the Jacobian
/// buffer. With a static parameter count and a problem whose `evaluate` allocates nothing,
/// `solve` performs no heap allocation (tested under EIGEN_RUNTIME_NO_MALLOC).
///
/// References: K. Levenberg, Q. Appl. Math. 2 (1944) 164–168; D. W. Marquardt, SIAM J. Appl.
/// Math. 11 (1963) 431–441; J. J. Moré, "The Levenberg–Marquardt algorithm: implementation and
/// theory", LNM 630 (1978); H. B. Nielsen, "Damping parameter in Marquardt's method", IMM-REP-
/// 1999-05; K. Madsen, H. B. Nielsen, O. Tingleff, "Methods for non-linear least squares
/// problems", 2nd ed., DTU 2004; C. Kanzow, N. Yamashita, M. Fukushima, J. Comput. Appl. Math.
/// 172 (2004) 375–397; L. Ljung, "System Identification: Theory for the User", 2nd ed., 1999.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/Householder>  // makeHouseholderInPlace

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/estimation/concepts.hpp"
#include "nlid/estimation/robust_loss.hpp"

namespace nlid {

/// What the solver reports to the iteration callback after every step attempt (and once with
/// `iteration == 0` for the starting point).
struct IterationReport {
  int iteration;         ///< 0 for the start, then 1, 2, … (accepted and rejected attempts)
  double cost;           ///< F(θ) at the current (last accepted) θ
  double step_norm;      ///< ‖Δθ‖₂ of the step just tried (0 at iteration 0)
  double lambda;         ///< damping λ after this attempt (the next step's; initial λ at iteration 0)
  double gradient_norm;  ///< projected gradient ‖θ − P(θ − ∇F)‖∞ at the current θ
  bool step_accepted;    ///< whether the step was taken (true at iteration 0)
};

/// How the damping term λ‖Dδ‖² scales the parameters (file comment: "Scaling D").
enum class LmScaling {
  /// The caller's default: `solve_least_squares` takes `running_max`; `estimate` takes
  /// `levenberg` with each parameter's unit from the data (`parameter_scale`) for
  /// Hammerstein–Wiener models and `running_max` for every other structure
  /// (docs/estimation.md, "Scaling D", has the evidence).
  automatic,
  /// d_k = the largest column norm ‖J̃_k‖ seen so far in this solve (Moré 1978): invariant to
  /// parameter units, and the damping never relaxes in a direction that was once steep.
  running_max,
  /// d_k = the column norm at the current θ (Marquardt 1963), floored at 10⁻³(1 + ‖J̃_k‖) so a
  /// momentarily inactive parameter is still damped. This is the scaling of Ceres Solver's
  /// Levenberg–Marquardt strategy (its Jacobi-scaled diagonal clamped at 10⁻⁶).
  current,
  /// D = √(max_k A_kk)·I, the running maximum over the solve (Levenberg 1944, made
  /// dimensionless): not invariant to parameter units — unless `LmOptions::parameter_scale`
  /// gives each parameter's unit, then D = c·diag(1/s_k) with c the running maximum of
  /// s_k·√A_kk: uniform damping of θ_k/s_k.
  levenberg,
};

/// Quadratic regularization ½·lambda·Σ_k weights_k (θ_k − nominal_k)² added to the cost (file
/// comment, "Regularization"). Off while `lambda` is 0.
struct LmRegularization {
  double lambda = 0.0;      ///< λ_R ≥ 0, in units of the cost per squared parameter unit
  Eigen::VectorXd weights;  ///< R's diagonal: empty (all 1) or n entries ≥ 0 (0 = not penalised)
  Eigen::VectorXd nominal;  ///< θ̄: empty (zero) or n finite entries
};

/// Options of `solve_least_squares`. Every field is validated at the start of a solve; a bad
/// value throws `nlid::Error` whose location names the option (and the parameter, if any).
struct LmOptions {
  int max_iterations = 100;            ///< step attempts (accepted + rejected), ≥ 0
  double function_tolerance = 1e-10;   ///< relative cost decrease to stop, ≥ 0
  double gradient_tolerance = 1e-10;   ///< projected-gradient max-norm to stop, ≥ 0
  double parameter_tolerance = 1e-8;   ///< relative step size to stop, ≥ 0
  double initial_lambda = 1e-3;        ///< starting damping (dimensionless, see file comment), > 0
  LmScaling scaling = LmScaling::automatic;  ///< the damping's scale D (see LmScaling)
  Eigen::VectorXd lower_bounds;        ///< empty (none) or n entries; −∞ allowed
  Eigen::VectorXd upper_bounds;        ///< empty (none) or n entries; +∞ allowed
  std::vector<bool> fixed;             ///< empty (none) or n flags: true = hold at initial value
  RobustLoss loss;                     ///< ρ: squared (default) or Huber
  LmRegularization regularization;     ///< pull towards a nominal θ (default: none)
  /// Called after every step attempt; return false to stop (status `user_abort`).
  std::function<bool(const IterationReport&)> callback;
  /// Optional names of the n parameters, used in error messages (default "theta[k]").
  std::vector<std::string> parameter_names;
  /// Empty (all 1) or n finite entries > 0: the unit of each parameter, e.g. the output's
  /// RMS for a parameter measured in output units. `levenberg` damping and the
  /// parameter-tolerance test then work on θ_k/s_k, which makes them independent of the units
  /// the data are in when the scales follow the data (Hammerstein–Wiener estimation sets them;
  /// the other scalings are unit-invariant without them).
  Eigen::VectorXd parameter_scale;
};

namespace detail {

// The solver's form of `reg` for n parameters: weight = λ·R (λ where R is empty, 0 when λ = 0),
// nominal = θ̄ (zero where empty).
template <class W, class N>
void regularization_terms(const LmRegularization& reg, Eigen::Index n, W& weight, N& nominal) {
  weight.setZero(n);
  nominal.setZero(n);
  if (reg.lambda > 0.0) {
    weight.setConstant(n, reg.lambda);
    if (reg.weights.size() == n) weight = reg.lambda * reg.weights;
    if (reg.nominal.size() == n) nominal = reg.nominal;
  }
}

// ½ Σ_k weight_k (x_k − nominal_k)² over the first n entries.
template <class W, class N, class X>
double regularization_penalty(const W& weight, const N& nominal, const X& x, Eigen::Index n) {
  double p = 0.0;
  for (Eigen::Index k = 0; k < n; ++k) {
    const double e = x[k] - nominal[k];
    p += weight[k] * e * e;
  }
  return 0.5 * p;
}

}  // namespace detail

/// The cost F(θ) a solve with these options minimises, for residuals r at θ: ½ Σ ρ(r_i²) of the
/// robust loss plus the regularization penalty. Lets a caller rank points by the solver's own
/// criterion (multi-start screening) so that the ranking and the solves' final costs agree.
/// Regularization weights or nominal values whose size is not θ's are treated as the solver
/// treats empty ones (all 1, zero); the solve itself refuses them.
template <class RDerived, class TDerived>
double lm_cost(const LmOptions& o, const Eigen::MatrixBase<RDerived>& r, const Eigen::MatrixBase<TDerived>& theta) {
  double c = robust_cost(o.loss, r);
  if (o.regularization.lambda > 0.0) {
    Eigen::VectorXd weight, nominal;
    detail::regularization_terms(o.regularization, theta.size(), weight, nominal);
    c += detail::regularization_penalty(weight, nominal, theta, theta.size());
  }
  return c;
}

/// Why the solver stopped. Each comment states the exact criterion (n_free = non-fixed count;
/// norms over non-fixed parameters; ε-terms as written).
enum class LmStatus {
  /// ‖θ − P_[l,u](θ − ∇F(θ))‖∞ ≤ gradient_tolerance·min(1, G₀) at the current θ, G₀ that
  /// norm at the start (with `LmOptions::parameter_scale` s, the same in θ_k/s_k:
  /// ‖(θ − P(θ − s²∘∇F))/s‖∞): first-order optimal. (The factor keeps a problem whose data are in
  /// small units — a cost of 10⁻¹⁸ has gradients to match — from stopping at its start; for
  /// G₀ ≥ 1 the test is the absolute one.)
  gradient_tolerance_reached,
  /// An accepted step decreased the cost by F_old − F_new ≤ function_tolerance · F_old; or, at
  /// the start, a tiny step was rejected and even the undamped Gauss–Newton step predicts a
  /// decrease ½gᵀA⁻¹g ≤ function_tolerance · F (the start is the optimum; `LmSummary::detail`
  /// says so).
  function_tolerance_reached,
  /// The step just tried satisfies ‖Δθ‖₂ ≤ parameter_tolerance·(‖θ‖₂ + parameter_tolerance)
  /// (Δθ after projection onto the bounds, θ before the step; both divided entry by entry by
  /// `LmOptions::parameter_scale` when it is given). An accepted step is taken
  /// first; after a rejected one θ stays (a larger λ would only shorten the step further).
  /// If no step at all was accepted, θ is the start and nothing certifies it: `converged()`
  /// is false and the message says the solve stalled (typically exploding sensitivities, e.g.
  /// a simulation-focus start whose free run is locally unstable).
  parameter_tolerance_reached,
  /// `max_iterations` step attempts were made without meeting another criterion.
  max_iterations_reached,
  /// λ exceeded 10³² after consecutive rejections: no step along the damped Gauss–Newton
  /// direction reduces F (e.g. `evaluate` fails everywhere near θ, or θ sits on a kink of r).
  lambda_limit_reached,
  /// At an accepted θ the Jacobian was not finite or `evaluate` failed when asked for it;
  /// θ is left at that point and `LmSummary::detail` names the parameter and residual.
  jacobian_not_finite,
  /// The callback returned false.
  user_abort,
  /// n_free = 0 (every parameter fixed): nothing to estimate; F is reported at θ.
  all_parameters_fixed,
};

/// Short name of a status (e.g. "gradient_tolerance_reached").
inline const char* to_string(LmStatus s) {
  switch (s) {
    case LmStatus::gradient_tolerance_reached: return "gradient_tolerance_reached";
    case LmStatus::function_tolerance_reached: return "function_tolerance_reached";
    case LmStatus::parameter_tolerance_reached: return "parameter_tolerance_reached";
    case LmStatus::max_iterations_reached: return "max_iterations_reached";
    case LmStatus::lambda_limit_reached: return "lambda_limit_reached";
    case LmStatus::jacobian_not_finite: return "jacobian_not_finite";
    case LmStatus::user_abort: return "user_abort";
    case LmStatus::all_parameters_fixed: return "all_parameters_fixed";
  }
  return "unknown";
}

/// Outcome of a solve. θ itself is returned through the caller's vector.
struct LmSummary {
  LmStatus status = LmStatus::max_iterations_reached;  ///< why it stopped
  int iterations = 0;                ///< step attempts made (accepted + rejected)
  int accepted_steps = 0;            ///< of which accepted
  double initial_cost = 0;           ///< F at the (projected) initial θ
  double final_cost = 0;             ///< F at the returned θ
  double final_gradient_norm = 0;    ///< projected-gradient max-norm at the returned θ (NaN
                                     ///< if status is jacobian_not_finite, or if Jᵀr overflowed:
                                     ///< not computable, and then never "converged")
  double final_lambda = 0;           ///< damping at exit
  int residual_evaluations = 0;      ///< calls of `evaluate` (with or without J)
  int jacobian_evaluations = 0;      ///< calls of `evaluate` with J
  int qr_fallbacks = 0;              ///< steps solved by QR because LDLT was ill-conditioned
  int projected_parameters = 0;      ///< initial values moved onto their bounds
  double seconds = 0;                ///< wall-clock time of the solve
  std::string detail;                ///< extra information for some statuses (else empty)

  /// True for the statuses that certify a (local) solution: gradient, function or parameter
  /// tolerance reached (the last after at least one accepted step), or nothing to estimate.
  bool converged() const {
    return status == LmStatus::gradient_tolerance_reached ||
           status == LmStatus::function_tolerance_reached ||
           (status == LmStatus::parameter_tolerance_reached && !stalled_at_start()) ||
           status == LmStatus::all_parameters_fixed;
  }
  /// True if the solve stopped on a rejected tiny step without ever moving from the start.
  bool stalled_at_start() const {
    return status == LmStatus::parameter_tolerance_reached && accepted_steps == 0;
  }
  /// One-paragraph human-readable account: status, costs, counts, time.
  std::string message() const {
    auto num = [](double v) { return detail::format_g(v); };
    std::string s = std::string("Levenberg-Marquardt: ") + to_string(status) +
                    (converged()          ? " (converged)"
                     : stalled_at_start() ? " (stalled: no step reduced the cost, the start was kept)"
                                          : " (not converged)") +
                    " after " +
                    std::to_string(iterations) + " iterations (" + std::to_string(accepted_steps) +
                    " accepted); cost " + num(initial_cost) + " -> " + num(final_cost) +
                    ", |projected gradient| " + num(final_gradient_norm) + ", lambda " +
                    num(final_lambda) + "; " + std::to_string(residual_evaluations) +
                    " residual and " + std::to_string(jacobian_evaluations) +
                    " Jacobian evaluations";
    if (qr_fallbacks > 0) s += ", " + std::to_string(qr_fallbacks) + " QR fallback steps";
    if (projected_parameters > 0) {
      s += ", " + std::to_string(projected_parameters) + " initial values projected onto bounds";
    }
    s += "; " + num(seconds) + " s.";
    if (!detail.empty()) s += " " + detail;
    return s;
  }
};

namespace detail {

// Householder QR of a (rows × cols), in place: R in the upper triangle, the essential parts of
// the reflectors v = [1; a(k+1:, k)] below it, their coefficients in tau. The reflectors are
// applied column by column with dot products, so nothing is allocated (Eigen's HouseholderQR and
// applyHouseholderOnTheLeft evaluate panel / outer-product temporaries on the heap).
template <class M, class V>
void householder_qr_in_place(M& a, V& tau) {
  const Eigen::Index rows = a.rows(), cols = a.cols(), size = std::min(rows, cols);
  for (Eigen::Index k = 0; k < size; ++k) {
    double beta;
    a.col(k).tail(rows - k).makeHouseholderInPlace(tau[k], beta);
    a(k, k) = beta;
    const Eigen::Index len = rows - k - 1;
    for (Eigen::Index j = k + 1; j < cols; ++j) {
      // a(k:, j) ← (I − τ v vᵀ) a(k:, j)
      const double w = tau[k] * (a(k, j) + a.col(k).tail(len).dot(a.col(j).tail(len)));
      a(k, j) -= w;
      a.col(j).tail(len) -= w * a.col(k).tail(len);
    }
  }
}

// b ← Qᵀ b for the Q stored by householder_qr_in_place (Qᵀ = H_{s−1} ⋯ H_0).
template <class M, class V, class B>
void apply_qt(const M& a, const V& tau, B& b) {
  const Eigen::Index rows = a.rows(), size = std::min(rows, a.cols());
  for (Eigen::Index k = 0; k < size; ++k) {
    const Eigen::Index len = rows - k - 1;
    const double w = tau[k] * (b[k] + a.col(k).tail(len).dot(b.tail(len)));
    b[k] -= w;
    b.tail(len) -= w * a.col(k).tail(len);
  }
}

}  // namespace detail

namespace detail {

/// A problem's `evaluate` behind one function pointer: the solver's iteration and linear algebra
/// (`LmEngine`) are then compiled once per parameter count, not once per problem type — an
/// estimation builds several problems of the same size (prediction and simulation stages,
/// structured and forward-AD Jacobians), and each solver instantiation costs seconds of compile
/// time. One indirect call per evaluation of a whole residual vector costs nothing measurable.
template <int P>
struct LmEvaluator {
  const void* problem;
  bool (*evaluate)(const void* problem, const ParameterVector<P>& theta, Eigen::VectorXd& r, JacobianMatrix<P>* J);
  int num_parameters;
  Eigen::Index num_residuals;
  bool operator()(const ParameterVector<P>& theta, Eigen::VectorXd& r, JacobianMatrix<P>* J) const {
    return evaluate(problem, theta, r, J);
  }
};

template <LeastSquaresProblem Problem>
LmEvaluator<Problem::num_params> make_lm_evaluator(const Problem& problem) {
  return {&problem,
          [](const void* p, const ParameterVector<Problem::num_params>& theta, Eigen::VectorXd& r,
             JacobianMatrix<Problem::num_params>* J) -> bool {
            return static_cast<bool>(static_cast<const Problem*>(p)->evaluate(theta, r, J));
          },
          problem.num_parameters(), problem.num_residuals()};
}

/// The solver for problems of P parameters (see `LevenbergMarquardt`).
template <int P>
class LmEngine {
 public:
  static constexpr int num_params = P;  ///< static parameter count (or Dynamic)
  using Parameters = ParameterVector<num_params>;          ///< θ

  /// Stores the options (validated in `setup`).
  explicit LmEngine(LmOptions options = {}) : options_(std::move(options)) {}

  /// The options in use.
  const LmOptions& options() const { return options_; }
  /// Replaces the options; the next `solve` re-validates them.
  void set_options(LmOptions options) {
    options_ = std::move(options);
    n_ = -1;
  }

  /// Validates the options for this problem and allocates all workspace.
  /// Throws `nlid::Error` naming the offending option / parameter.
  void setup(const LmEvaluator<P>& problem) {
    const int n = problem.num_parameters;
    const Eigen::Index m = problem.num_residuals;
    // n = 0 (nothing to estimate) is allowed: the solve reports all_parameters_fixed at the start.
    if (n < 0 || (num_params != Dynamic && n != num_params)) {
      throw Error("problem reports " + std::to_string(n) + " parameters; expected " +
                      (num_params == Dynamic ? std::string("0 or more")
                                             : std::to_string(num_params)),
                  at_parameter("num_parameters"));
    }
    if (m < 1) throw Error("problem has no residuals", at_parameter("num_residuals"));
    n_ = -1;  // stays invalid if validation throws
    validate_options(n);

    lower_.setConstant(n, -std::numeric_limits<double>::infinity());
    upper_.setConstant(n, std::numeric_limits<double>::infinity());
    if (options_.lower_bounds.size() == n) lower_ = options_.lower_bounds;
    if (options_.upper_bounds.size() == n) upper_ = options_.upper_bounds;
    detail::regularization_terms(options_.regularization, n, reg_weight_, reg_nominal_);
    regularized_ = (reg_weight_.array() > 0.0).any();
    fixed_.setZero(n);
    if (!options_.fixed.empty()) {
      for (int k = 0; k < n; ++k) fixed_[k] = options_.fixed[static_cast<std::size_t>(k)] ? 1 : 0;
    }
    x_.resize(n);
    x_trial_.resize(n);
    g_.resize(n);
    d_.resize(n);
    s_.resize(n);
    y_.resize(n);
    rhs_.resize(n);
    free_.resize(n);
    A_.resize(n, n);
    Ahat_.resize(n, n);
    R_.resize(n, n);
    tau_.resize(n);
    small_.resize(2 * n, n);
    c_.resize(n);
    small_rhs_.resize(2 * n);
    small_tau_.resize(n);
    ldlt_.compute(Matrix::Identity(n, n));  // sizes LDLT's internal buffers now, not in solve
    r_.resize(m);
    r_trial_.resize(m);
    rw_.resize(m);
    w_.resize(m);
    J_.resize(m, n);
    n_ = n;
    m_ = m;
  }

  /// Minimises F from the initial `theta`, which receives the result (always the best accepted
  /// point, whatever the status). Throws `nlid::Error` for invalid options, a non-finite initial
  /// value, a fixed parameter outside its bounds, or a problem not evaluable at the start.
  LmSummary solve(const LmEvaluator<P>& problem, Parameters& theta) {
    const auto t0 = std::chrono::steady_clock::now();
    if (n_ != problem.num_parameters || m_ != problem.num_residuals) setup(problem);
    LmSummary sum;
    if (theta.size() != n_) {
      throw Error("theta has " + std::to_string(theta.size()) + " entries, the problem has " +
                      std::to_string(n_) + " parameters",
                  at_parameter("theta"));
    }
    prepare_start(theta, sum);

    // ---- start: full evaluation, normal equations -------------------------------------------
    if (!evaluate_with_jacobian(problem, sum)) {
      throw Error("the problem cannot be evaluated at the initial parameters: " + bad_detail_,
                  at_parameter(bad_param_));
    }
    cost_ = robust_cost(options_.loss, r_) + penalty(x_);
    sum.initial_cost = cost_;
    double lambda = options_.initial_lambda;
    double nu = 2.0;
    build_normal_equations();
    double gnorm = projected_gradient_norm();
    const double gradient_tolerance = options_.gradient_tolerance * std::min(1.0, std::isnan(gnorm) ? 1.0 : gnorm);
    int n_free = 0;
    for (int k = 0; k < n_; ++k) n_free += fixed_[k] ? 0 : 1;

    bool done = false;
    if (n_free == 0) {
      sum.status = LmStatus::all_parameters_fixed;
      done = true;
    } else if (gnorm <= gradient_tolerance) {
      sum.status = LmStatus::gradient_tolerance_reached;
      done = true;
    }
    if (!report({0, cost_, 0.0, lambda, gnorm, true}) && !done) {
      sum.status = LmStatus::user_abort;
      done = true;
    }

    // ---- iterations ----------------------------------------------------------------------------
    for (int iter = 1; !done && iter <= options_.max_iterations; ++iter) {
      compute_step(lambda, sum);  // x_trial_ = P(x + δ)
      y_ = x_trial_ - x_;         // the projected step δ
      const double step_norm = y_.norm();
      const bool tiny_step =
          scaled_step_norm() <= options_.parameter_tolerance * (free_norm(x_) + options_.parameter_tolerance);
      sum.iterations = iter;
      // Model decrease of the projected step: m(0) − m(δ) = −(gᵀδ + ½ δᵀAδ).
      rhs_.noalias() = A_ * y_;
      const double predicted = -(g_.dot(y_) + 0.5 * y_.dot(rhs_));
      ++sum.residual_evaluations;
      bool ok = problem(x_trial_, r_trial_, nullptr);
      check_residual_size(r_trial_);
      ok = ok && r_trial_.allFinite();
      const double new_cost = ok ? robust_cost(options_.loss, r_trial_) + penalty(x_trial_) : 0.0;
      const double actual = cost_ - new_cost;
      const double gain = ok && predicted > 0 ? actual / predicted : -1.0;
      const bool accepted = ok && predicted > 0 && actual > 0 && gain > 1e-3;

      if (accepted) {
        ++sum.accepted_steps;
        const double old_cost = cost_;
        x_.swap(x_trial_);
        r_.swap(r_trial_);
        cost_ = new_cost;
        const double t = 2.0 * gain - 1.0;
        lambda = std::max(lambda * std::max(1.0 / 3.0, 1.0 - t * t * t), 1e-16);
        nu = 2.0;
        if (!evaluate_with_jacobian(problem, sum)) {
          sum.status = LmStatus::jacobian_not_finite;
          sum.detail = "At the accepted parameters " + bad_detail_ + ".";
          gnorm = std::numeric_limits<double>::quiet_NaN();
          report({iter, cost_, step_norm, lambda, gnorm, true});
          break;
        }
        build_normal_equations();
        gnorm = projected_gradient_norm();
        if (actual <= options_.function_tolerance * old_cost) {
          sum.status = LmStatus::function_tolerance_reached;
          done = true;
        } else if (tiny_step) {
          sum.status = LmStatus::parameter_tolerance_reached;
          done = true;
        } else if (gnorm <= gradient_tolerance) {
          sum.status = LmStatus::gradient_tolerance_reached;
          done = true;
        }
      } else {
        lambda *= nu;
        nu = std::min(2.0 * nu, 1e10);  // ν doubles; capped so λ·ν stays finite
        if (tiny_step) {  // larger λ only shortens the step further: no progress possible
          sum.status = LmStatus::parameter_tolerance_reached;
          // A start that is already the optimum (a least-squares start of a model linear in θ)
          // rejects its first tiny step on rounding alone. If even the undamped Gauss–Newton
          // step is predicted to lower the cost by no more than the function tolerance, that is
          // convergence, not a stall. (The damped step's own prediction cannot tell: a wrong
          // Jacobian also ends on a tiny step with a tiny prediction.) Only the label changes:
          // the solve stops here either way.
          if (sum.accepted_steps == 0 &&
              gauss_newton_decrease() <= options_.function_tolerance * cost_) {
            sum.status = LmStatus::function_tolerance_reached;
            sum.detail = "The start is optimal: no step is predicted to lower the cost by more than " +
                         detail::format_g(options_.function_tolerance) + " of it.";
          }
          done = true;
        } else if (lambda > 1e32) {
          sum.status = LmStatus::lambda_limit_reached;
          done = true;
        }
      }
      if (!report({iter, cost_, step_norm, lambda, gnorm, accepted}) && !done) {
        sum.status = LmStatus::user_abort;
        done = true;
      }
    }
    theta = x_;
    sum.final_cost = cost_;
    sum.final_gradient_norm = gnorm;
    sum.final_lambda = lambda;
    sum.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return sum;
  }

 private:
  using Vector = Eigen::Matrix<double, num_params, 1>;
  using Matrix = Eigen::Matrix<double, num_params, num_params>;
  static constexpr int twice = num_params == Dynamic ? Dynamic : 2 * num_params;
  using SmallMatrix = Eigen::Matrix<double, twice, num_params>;
  using SmallVector = Eigen::Matrix<double, twice, 1>;

  std::string param_name(int k) const {
    if (!options_.parameter_names.empty()) return options_.parameter_names[static_cast<std::size_t>(k)];
    return "theta[" + std::to_string(k) + "]";
  }
  static std::string num(double v) { return detail::format_g(v, 9); }

  void validate_options(int n) const {
    const LmOptions& o = options_;
    if (o.scaling != LmScaling::automatic && o.scaling != LmScaling::running_max && o.scaling != LmScaling::current &&
        o.scaling != LmScaling::levenberg) {
      throw Error("LmOptions::scaling is not an LmScaling value (got " +
                      std::to_string(static_cast<int>(o.scaling)) + ")",
                  at_parameter("scaling"));
    }
    if (o.max_iterations < 0) {
      throw Error("LmOptions::max_iterations must be >= 0, got " + std::to_string(o.max_iterations),
                  at_parameter("max_iterations"));
    }
    auto check_tol = [](double v, const char* name) {
      if (!(std::isfinite(v) && v >= 0)) {
        throw Error(std::string("LmOptions::") + name + " must be finite and >= 0, got " + num(v),
                    at_parameter(name));
      }
    };
    check_tol(o.function_tolerance, "function_tolerance");
    check_tol(o.gradient_tolerance, "gradient_tolerance");
    check_tol(o.parameter_tolerance, "parameter_tolerance");
    if (!(std::isfinite(o.initial_lambda) && o.initial_lambda > 0)) {
      throw Error("LmOptions::initial_lambda must be finite and > 0, got " + num(o.initial_lambda),
                  at_parameter("initial_lambda"));
    }
    const std::string ns = std::to_string(n);
    if (!o.parameter_names.empty() && static_cast<int>(o.parameter_names.size()) != n) {
      throw Error("LmOptions::parameter_names has " + std::to_string(o.parameter_names.size()) +
                      " entries, the problem has " + ns + " parameters",
                  at_parameter("parameter_names"));
    }
    auto check_size = [&](Eigen::Index size, const char* name) {
      if (size != 0 && size != n) {
        throw Error(std::string("LmOptions::") + name + " has " + std::to_string(size) +
                        " entries, the problem has " + ns + " parameters (leave it empty for none)",
                    at_parameter(name));
      }
    };
    check_size(o.lower_bounds.size(), "lower_bounds");
    check_size(o.upper_bounds.size(), "upper_bounds");
    check_size(static_cast<Eigen::Index>(o.fixed.size()), "fixed");
    check_size(o.parameter_scale.size(), "parameter_scale");
    for (Eigen::Index k = 0; k < o.parameter_scale.size(); ++k) {
      const double v = o.parameter_scale[k];
      if (!(std::isfinite(v) && v > 0)) {
        throw Error("LmOptions::parameter_scale is " + num(v) + " for parameter '" + param_name(static_cast<int>(k)) +
                        "' (index " + std::to_string(k) + "); each scale must be finite and > 0",
                    at_parameter(param_name(static_cast<int>(k))));
      }
    }
    const double inf = std::numeric_limits<double>::infinity();
    for (int k = 0; k < n; ++k) {
      const double lo = o.lower_bounds.size() ? o.lower_bounds[k] : -inf;
      const double hi = o.upper_bounds.size() ? o.upper_bounds[k] : inf;
      const std::string where = " for parameter '" + param_name(k) + "' (index " + std::to_string(k) + ")";
      if (std::isnan(lo) || lo == inf) {
        throw Error("LmOptions::lower_bounds is " + num(lo) + where, at_parameter(param_name(k)));
      }
      if (std::isnan(hi) || hi == -inf) {
        throw Error("LmOptions::upper_bounds is " + num(hi) + where, at_parameter(param_name(k)));
      }
      if (lo > hi) {
        throw Error("LmOptions: lower bound " + num(lo) + " exceeds upper bound " + num(hi) + where,
                    at_parameter(param_name(k)));
      }
    }
    validate(o.loss);
    const LmRegularization& reg = o.regularization;
    if (!(std::isfinite(reg.lambda) && reg.lambda >= 0)) {
      throw Error("LmOptions::regularization.lambda must be finite and >= 0, got " + num(reg.lambda),
                  at_parameter("regularization.lambda"));
    }
    check_size(reg.weights.size(), "regularization.weights");
    check_size(reg.nominal.size(), "regularization.nominal");
    for (Eigen::Index k = 0; k < reg.weights.size(); ++k) {
      if (!(std::isfinite(reg.weights[k]) && reg.weights[k] >= 0)) {
        throw Error("LmOptions::regularization.weights is " + num(reg.weights[k]) + " for parameter '" +
                        param_name(static_cast<int>(k)) + "' (index " + std::to_string(k) + "); weights must be finite and >= 0",
                    at_parameter(param_name(static_cast<int>(k))));
      }
    }
    for (Eigen::Index k = 0; k < reg.nominal.size(); ++k) {
      if (!std::isfinite(reg.nominal[k])) {
        throw Error("LmOptions::regularization.nominal is " + num(reg.nominal[k]) + " for parameter '" +
                        param_name(static_cast<int>(k)) + "' (index " + std::to_string(k) + ")",
                    at_parameter(param_name(static_cast<int>(k))));
      }
    }
  }

  // ½ Σ λ_R R_k (θ_k − θ̄_k)²: the regularization part of F.
  double penalty(const Vector& x) const {
    return regularized_ ? detail::regularization_penalty(reg_weight_, reg_nominal_, x, n_) : 0.0;
  }

  // Copies θ into x_, checks it, projects free parameters onto the bounds.
  void prepare_start(const Parameters& theta, LmSummary& sum) {
    for (int k = 0; k < n_; ++k) {
      const double v = theta[k];
      if (!std::isfinite(v)) {
        throw Error("initial value of parameter '" + param_name(k) + "' is not finite (" + num(v) + ")",
                    at_parameter(param_name(k)));
      }
      double p = std::clamp(v, lower_[k], upper_[k]);
      if (p != v) {
        if (fixed_[k]) {
          throw Error("parameter '" + param_name(k) + "' is fixed at " + num(v) +
                          " which lies outside its bounds [" + num(lower_[k]) + ", " +
                          num(upper_[k]) + "]",
                      at_parameter(param_name(k)));
        }
        ++sum.projected_parameters;
      }
      x_[k] = p;
    }
    d_.setZero();
    unit_damping_ = 0.0;
    bad_detail_.clear();
    bad_param_.clear();
  }

  void check_residual_size(const Eigen::VectorXd& r) const {
    if (r.size() != m_) {
      throw Error("the problem's evaluate() resized the residual vector from " +
                      std::to_string(m_) + " to " + std::to_string(r.size()) + " entries",
                  at_parameter("num_residuals"));
    }
  }

  // r_ and J_ at x_ (J_ then reweighted). False if not evaluable; bad_detail_ says why.
  bool evaluate_with_jacobian(const LmEvaluator<P>& problem, LmSummary& sum) {
    ++sum.residual_evaluations;
    ++sum.jacobian_evaluations;
    const bool ok = problem(x_, r_, &J_);
    check_residual_size(r_);
    if (J_.rows() != m_ || J_.cols() != n_) {
      throw Error("the problem's evaluate() resized the Jacobian", at_parameter("J"));
    }
    if (!ok) {
      bad_detail_ = "evaluate() returned false";
      bad_param_ = "theta";
      return false;
    }
    for (Eigen::Index i = 0; i < m_; ++i) {
      if (!std::isfinite(r_[i])) {
        bad_detail_ = "residual " + std::to_string(i) + " is " + num(r_[i]);
        bad_param_ = "theta";
        return false;
      }
    }
    if (J_.allFinite()) return true;  // vectorised; the loop below only names the culprit
    for (int k = 0; k < n_; ++k) {
      for (Eigen::Index i = 0; i < m_; ++i) {
        if (!std::isfinite(J_(i, k))) {
          bad_detail_ = "the Jacobian entry d r[" + std::to_string(i) + "] / d '" + param_name(k) +
                        "' is " + num(J_(i, k));
          bad_param_ = param_name(k);
          return false;
        }
      }
    }
    return true;
  }

  // IRLS reweighting, A = J̃ᵀJ̃, g = J̃ᵀr̃, column scale D.
  void build_normal_equations() {
    // Nothing to estimate: A and g are empty, and Eigen's product kernels must not be handed a
    // matrix without columns (they bind a reference to its null data pointer).
    if (n_ == 0) {
      qr_ready_ = false;
      return;
    }
    if (options_.loss.kind == RobustLoss::Kind::squared) {
      rw_ = r_;
    } else {
      robust_weights(options_.loss, r_, w_);
      rw_ = w_.cwiseProduct(r_);
      for (int k = 0; k < n_; ++k) J_.col(k).array() *= w_.array();
    }
    // JᵀJ is symmetric: a rank update of the lower triangle (syrk) is half the flops of the
    // general product, which was the largest single cost of a solve once the Jacobian is cheap
    // (docs/performance.md); the upper triangle is mirrored, since the step code reads all of A.
    A_.setZero();
    A_.template selfadjointView<Eigen::Lower>().rankUpdate(J_.transpose());
    for (int j = 1; j < n_; ++j)
      for (int i = 0; i < j; ++i) A_(i, j) = A_(j, i);
    g_.noalias() = J_.transpose() * rw_;
    if (regularized_) {
      for (int k = 0; k < n_; ++k) {
        A_(k, k) += reg_weight_[k];
        g_[k] += reg_weight_[k] * (x_[k] - reg_nominal_[k]);
      }
    }
    if (options_.scaling == LmScaling::running_max || options_.scaling == LmScaling::automatic) {
      for (int k = 0; k < n_; ++k) d_[k] = std::max(d_[k], std::sqrt(A_(k, k)));
    } else if (options_.scaling == LmScaling::current) {
      for (int k = 0; k < n_; ++k) {
        const double c = std::sqrt(A_(k, k));
        d_[k] = std::max(c, 1e-3 * (1.0 + c));
      }
    } else if (options_.parameter_scale.size() == n_) {
      // Uniform damping of θ_k/s_k: D = c·diag(1/s_k), c the running maximum of s_k·√A_kk.
      double c = 0.0;
      for (int k = 0; k < n_; ++k) c = std::max(c, options_.parameter_scale[k] * std::sqrt(A_(k, k)));
      if (c > unit_damping_) unit_damping_ = c;
      for (int k = 0; k < n_; ++k) d_[k] = unit_damping_ / options_.parameter_scale[k];
    } else {
      const double dmax = std::sqrt(A_.diagonal().maxCoeff());
      if (dmax > d_[0]) d_.setConstant(dmax);  // running maximum, like the scaled case
    }
    // s = D⁻¹; a parameter that has never influenced r gets unit scale (its step is 0 anyway).
    for (int k = 0; k < n_; ++k) s_[k] = d_[k] > 0 ? 1.0 / d_[k] : 1.0;
    // Free set of this linearisation: not fixed, and not pushed out of the box by −g.
    for (int k = 0; k < n_; ++k) {
      const bool at_lo = x_[k] <= lower_[k] && g_[k] > 0;
      const bool at_hi = x_[k] >= upper_[k] && g_[k] < 0;
      free_[k] = (fixed_[k] || at_lo || at_hi) ? 0.0 : 1.0;
    }
    qr_ready_ = false;
  }

  // ½ gᵀA⁻¹g over the current free set: the most any step is predicted to lower the cost (+∞
  // where A is singular there). Reuses the step buffers: only called when the solve stops.
  double gauss_newton_decrease() {
    Ahat_ = A_;
    rhs_ = g_;
    for (int k = 0; k < n_; ++k) {
      if (free_[k] != 0.0) continue;
      Ahat_.row(k).setZero();
      Ahat_.col(k).setZero();
      Ahat_(k, k) = 1.0;
      rhs_[k] = 0.0;
    }
    ldlt_.compute(Ahat_);
    if (ldlt_.info() != Eigen::Success || !ldlt_.isPositive()) return std::numeric_limits<double>::infinity();
    c_ = ldlt_.solve(rhs_);
    const double v = 0.5 * rhs_.dot(c_);
    return std::isfinite(v) && v >= 0.0 ? v : std::numeric_limits<double>::infinity();
  }

  // NaN if a free component is NaN (JᵀJ and Jᵀr overflow for Jacobian entries beyond ~1e154):
  // std::max would drop it and report 0, i.e. "converged" at a point nothing was computed for.
  // With `parameter_scale` it is the projected gradient in θ_k/s_k, (θ − P(θ − s²∘g))/s, whose
  // entries are all in units of the cost.
  double projected_gradient_norm() const {
    const bool scaled = options_.parameter_scale.size() == n_;
    double gn = 0;
    for (int k = 0; k < n_; ++k) {
      if (fixed_[k]) continue;
      const double sk = scaled ? options_.parameter_scale[k] : 1.0;
      // Inside the box the entry is the gradient step itself: θ − (θ − s²g) would round it to 0
      // wherever s²g is below θ's last digit (small units, large parameter values).
      const double step = sk * sk * g_[k], t = x_[k] - step;
      const double p = (t < lower_[k] ? x_[k] - lower_[k] : t > upper_[k] ? x_[k] - upper_[k] : step) / sk;
      if (std::isnan(p)) return std::numeric_limits<double>::quiet_NaN();
      gn = std::max(gn, std::abs(p));
    }
    return gn;
  }

  // ‖θ‖₂ over the non-fixed parameters: the scale of the parameter-tolerance test, which a large
  // held value must not loosen for the parameters being estimated.
  // With `parameter_scale` both norms of the parameter-tolerance test are taken of θ_k/s_k.
  double free_norm(const Vector& x) const {
    const bool scaled = options_.parameter_scale.size() == n_;
    double s = 0;
    for (int k = 0; k < n_; ++k) {
      const double v = scaled ? x[k] / options_.parameter_scale[k] : x[k];
      if (!fixed_[k]) s += v * v;
    }
    return std::sqrt(s);
  }

  // ‖δ‖₂ of the projected step held in y_, in the units of `free_norm`.
  double scaled_step_norm() const {
    if (options_.parameter_scale.size() != n_) return y_.norm();
    return (y_.array() / options_.parameter_scale.array()).matrix().norm();
  }

  // Solves the scaled damped system for y, sets x_trial_ = P(x + D⁻¹y).
  void compute_step(double lambda, LmSummary& sum) {
    bool ok = false;
    if (!qr_ready_) {
      for (int i = 0; i < n_; ++i) {
        for (int j = 0; j < n_; ++j) {
          Ahat_(i, j) = free_[i] * free_[j] * s_[i] * A_(i, j) * s_[j];
        }
        Ahat_(i, i) += free_[i] > 0 ? lambda : 1.0;
        rhs_[i] = -free_[i] * s_[i] * g_[i];
      }
      ldlt_.compute(Ahat_);
      ok = ldlt_.info() == Eigen::Success && ldlt_.isPositive() &&
           ldlt_.vectorD().minCoeff() > 0 && ldlt_.rcond() >= 1e-12;
      if (ok) {
        y_ = ldlt_.solve(rhs_);
        ok = y_.allFinite();
      }
    }
    if (!ok) {
      if (!qr_ready_) prepare_qr();
      solve_small(lambda);
      ++sum.qr_fallbacks;
    }
    for (int k = 0; k < n_; ++k) {
      const double step = free_[k] > 0 ? s_[k] * y_[k] : 0.0;
      x_trial_[k] = free_[k] > 0 ? std::clamp(x_[k] + step, lower_[k], upper_[k]) : x_[k];
    }
  }

  // Ĵ = J̃ D⁻¹ (held columns zeroed) = QR in place; c = Qᵀ(−r̃) (first n entries, zero-padded)
  // kept in c_. With regularization the rows √(λ_R R_k) s_k y_k = −√(λ_R R_k)(θ_k − θ̄_k) are
  // folded in by a second QR of [R; those rows], so solve_small sees one triangle as before.
  // Destroys J_ and rw_, which are not needed again before the next Jacobian evaluation.
  void prepare_qr() {
    for (int k = 0; k < n_; ++k) J_.col(k) *= free_[k] * s_[k];
    detail::householder_qr_in_place(J_, tau_);
    rw_ = -rw_;
    detail::apply_qt(J_, tau_, rw_);
    R_.setZero();
    c_.setZero();
    const Eigen::Index rows = std::min<Eigen::Index>(m_, n_);
    R_.topRows(rows) = J_.topRows(rows).template triangularView<Eigen::Upper>();
    c_.head(rows) = rw_.head(rows);
    if (regularized_) {
      small_.topRows(n_) = R_;
      small_.bottomRows(n_).setZero();
      small_rhs_.head(n_) = c_;
      for (int k = 0; k < n_; ++k) {
        const double w = std::sqrt(reg_weight_[k]);
        small_(n_ + k, k) = free_[k] * w * s_[k];
        small_rhs_[n_ + k] = -free_[k] * w * (x_[k] - reg_nominal_[k]);
      }
      detail::householder_qr_in_place(small_, small_tau_);
      detail::apply_qt(small_, small_tau_, small_rhs_);
      R_ = small_.topRows(n_).template triangularView<Eigen::Upper>();
      c_ = small_rhs_.head(n_);
    }
    qr_ready_ = true;
  }

  // min ‖[R; √λ I] y − [c; 0]‖ by a second, small QR (held parameters: y_k = 0).
  void solve_small(double lambda) {
    small_.topRows(n_) = R_;
    small_.bottomRows(n_).setZero();
    const double sl = std::sqrt(lambda);
    for (int k = 0; k < n_; ++k) small_(n_ + k, k) = free_[k] > 0 ? sl : 1.0;
    small_rhs_.setZero();
    small_rhs_.head(n_) = c_;
    detail::householder_qr_in_place(small_, small_tau_);
    detail::apply_qt(small_, small_tau_, small_rhs_);
    y_ = small_rhs_.head(n_);
    small_.topRows(n_).template triangularView<Eigen::Upper>().solveInPlace(y_);
    for (int k = 0; k < n_; ++k) {
      if (free_[k] == 0 || !std::isfinite(y_[k])) y_[k] = 0;
    }
  }

  bool report(const IterationReport& rep) const {
    if (!options_.callback) return true;
    return options_.callback(rep);
  }

  LmOptions options_;
  int n_ = -1;
  Eigen::Index m_ = -1;
  // Bounds, fixed flags, iterate, trial, gradient, scales, free set, solution (all size n).
  Vector lower_, upper_, fixed_, x_, x_trial_, g_, d_, s_, y_, rhs_, free_;
  // Regularization: λ_R·R_k (0 = not penalised) and θ̄; regularized_ if any weight is positive.
  Vector reg_weight_, reg_nominal_;
  bool regularized_ = false;
  // QR fallback: the right-hand side paired with R_ (size n).
  Vector c_;
  Matrix A_, Ahat_, R_;
  Vector tau_;
  SmallMatrix small_;
  SmallVector small_rhs_;
  Vector small_tau_;
  Eigen::LDLT<Matrix> ldlt_;
  // Residual-sized buffers and the Jacobian.
  Eigen::VectorXd r_, r_trial_, rw_, w_;
  JacobianMatrix<num_params> J_;
  double cost_ = 0;
  double unit_damping_ = 0;  // c of `levenberg` damping with parameter scales (running maximum)
  bool qr_ready_ = false;
  std::string bad_detail_, bad_param_;
};

}  // namespace detail

/// Levenberg–Marquardt solver object for one problem type. Construct with options, optionally
/// call `setup` once (validates options against the problem and allocates every buffer), then
/// `solve` any number of times; `solve` calls `setup` itself when sizes changed.
template <LeastSquaresProblem Problem>
class LevenbergMarquardt {
 public:
  static constexpr int num_params = Problem::num_params;  ///< static parameter count (or Dynamic)
  using Parameters = ParameterVector<num_params>;          ///< θ

  /// Stores the options (validated in `setup`).
  explicit LevenbergMarquardt(LmOptions options = {}) : engine_(std::move(options)) {}

  /// The options in use.
  const LmOptions& options() const { return engine_.options(); }
  /// Replaces the options; the next `solve` re-validates them.
  void set_options(LmOptions options) { engine_.set_options(std::move(options)); }

  /// Validates the options for this problem and allocates all workspace.
  /// Throws `nlid::Error` naming the offending option / parameter.
  void setup(const Problem& problem) { engine_.setup(detail::make_lm_evaluator(problem)); }

  /// Minimises F from the initial `theta`, which receives the result (always the best accepted
  /// point, whatever the status). Throws `nlid::Error` for invalid options, a non-finite initial
  /// value, a fixed parameter outside its bounds, or a problem not evaluable at the start.
  LmSummary solve(const Problem& problem, Parameters& theta) {
    return engine_.solve(detail::make_lm_evaluator(problem), theta);
  }

 private:
  detail::LmEngine<num_params> engine_;
};

/// Minimises ½ Σ ρ(rᵢ(θ)²) from the initial `theta` (which receives the result).
/// Convenience wrapper: `LevenbergMarquardt<P>(options).solve(problem, theta)`.
/// Throws `nlid::Error` for invalid options or an initial point where the problem cannot be
/// evaluated; otherwise the summary says how it ended.
template <LeastSquaresProblem P>
LmSummary solve_least_squares(const P& problem, Eigen::Matrix<double, P::num_params, 1>& theta,
                              const LmOptions& options = {}) {
  LevenbergMarquardt<P> lm(options);
  return lm.solve(problem, theta);
}

}  // namespace nlid
