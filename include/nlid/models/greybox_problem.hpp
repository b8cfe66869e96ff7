#pragma once
/// @file
/// Grey-box estimation by simulation error as a `LeastSquaresProblem`, with exact sensitivities.
///
/// Criterion (Ljung 1999, Sec. 7.2, eq. 7.12 with the simulation predictor of Sec. 4.5; Bohlin
/// 2006, Sec. 2.4). For experiments e = 1 … E with N_e samples and outputs j = 1 … n_y,
///
///     V(θ) = ½ Σ_e Σ_k Σ_j ( w_j · (ŷ_{e,k,j}(θ) − y_{e,k,j}) )²,     w_j = 1 / std(y_j),
///
/// where ŷ is the free-run simulation from the input alone (greybox_simulate.hpp). The weights
/// make outputs in different units count alike; for one output they only scale V. Missing
/// outputs (NaN samples kept by `NonFinitePolicy::keep`) contribute a zero residual and a zero
/// Jacobian row: they are skipped, not invented.
///
/// Unknowns. θ = [p; x₀⁽¹⁾; …; x₀⁽ᴱ⁾]: the physical parameters, then — with
/// `InitialCondition::estimate` — one initial state per experiment (each record starts from its
/// own state, so merged records are never glued together). With `zero` or `equilibrium` the
/// initial states are not unknowns (equilibrium: x₀ = x̄(u₀, p), differentiated through the
/// implicit function theorem). The `states_only` mode fixes p and estimates only the x₀ blocks:
/// that is how `simulate(…, InitialCondition::estimate)` finds the initial state of a record.
///
/// Sensitivities. ∂ŷ/∂θ is computed exactly by forward AD through the integrator: a static
/// physics is simulated once per experiment on `Dual<double, n_p + n_x>` (only that experiment's
/// x₀ block can affect its residuals, so the Jacobian's block structure costs nothing), or on
/// `Dual<double, n_p>` when the initial states are not estimated; a runtime
/// physics in chunks of 8 columns on `RuntimeDual`. Jacobian columns of fixed parameters are zero.
/// The sub-step count is computed from the double parameter values, so value and Dual runs take
/// the same steps and the Jacobian is that of the residual function actually evaluated.
///
/// Threads. `evaluate` is const and uses only local storage: one problem may be evaluated from
/// several threads at once (multi-start), provided the physics' members are const-thread-safe.
/// The problem keeps a pointer to the data set, which must outlive it.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <string>
#include <type_traits>
#include <vector>

#include <Eigen/Core>
#include <Eigen/LU>

#include "nlid/ad/dual.hpp"
#include "nlid/core/batch.hpp"
#include "nlid/core/error.hpp"
#include "nlid/core/initial_condition.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/models/greybox_concepts.hpp"
#include "nlid/models/greybox_simulate.hpp"
#include "nlid/models/integrators.hpp"

namespace nlid {

/// Simulation-error least-squares problem of a grey-box physics on a data set (file comment).
/// Satisfies `LeastSquaresProblem` with `num_params = Dynamic`.
template <Physics P>
class GreyBoxProblem {
 public:
  /// Parameter count is known at run time only (it grows with the number of experiments).
  static constexpr int num_params = Dynamic;

  /// Builds the problem. `fixed` (size n_p, may be empty = none) marks parameters held at their
  /// value; in `states_only` mode `p_values` gives the physical parameters and only initial
  /// states are unknowns (then `ic` must be `estimate`). Throws `nlid::Error` for a channel-count
  /// mismatch, an experiment shorter than 2 samples, a non-finite input sample, an initial-
  /// condition policy that does not apply, or fewer residuals than free unknowns.
  GreyBoxProblem(P physics, IntegratorOptions options, const Dataset& data, InitialCondition ic,
                 std::vector<bool> fixed = {}, bool states_only = false,
                 Eigen::VectorXd p_values = {})
      : GreyBoxProblem(std::move(physics), options, data, ic, std::move(fixed), states_only, std::move(p_values), true) {}

  /// The problem with every parameter and (for `estimate`) every initial state free, to evaluate
  /// residuals and Jacobian at given values — not to estimate them: records shorter than the
  /// unknowns are accepted (a simulation band of a 3-sample record). The other checks apply.
  [[nodiscard]] static GreyBoxProblem for_evaluation(P physics, IntegratorOptions options, const Dataset& data,
                                                     InitialCondition ic) {
    return GreyBoxProblem(std::move(physics), options, data, ic, {}, false, {}, false);
  }

 private:
  GreyBoxProblem(P physics, IntegratorOptions options, const Dataset& data, InitialCondition ic, std::vector<bool> fixed,
                 bool states_only, Eigen::VectorXd p_values, bool check_count)
      : phys_(std::move(physics)),
        options_(options),
        data_(&data),
        ic_(ic),
        fixed_(std::move(fixed)),
        states_only_(states_only),
        p_values_(std::move(p_values)) {
    validate(options_);
    nx_ = detail::physics_states(phys_);
    nu_ = detail::physics_inputs(phys_);
    ny_ = detail::physics_outputs(phys_);
    np_ = detail::physics_params(phys_);
    require(data.size() > 0, "grey-box estimation needs at least one experiment");
    require(ic != InitialCondition::measured,
            "InitialCondition::measured applies to regression models (past outputs); a grey-box "
            "model starts from a state: use estimate, zero or equilibrium");
    require(!states_only || ic == InitialCondition::estimate,
            "states-only estimation needs InitialCondition::estimate");
    if (fixed_.empty()) fixed_.assign(static_cast<std::size_t>(np_), false);
    require(static_cast<int>(fixed_.size()) == np_,
            "fixed flags: expected " + std::to_string(np_) + ", got " + std::to_string(fixed_.size()));
    if (states_only_) {
      require(p_values_.size() == np_, "states-only estimation needs the " + std::to_string(np_) +
                                           " parameter values");
    }
    Eigen::Index rows = 0;
    weights_ = Eigen::VectorXd::Ones(ny_);
    Eigen::VectorXd sum = Eigen::VectorXd::Zero(ny_), sum2 = Eigen::VectorXd::Zero(ny_);
    Eigen::VectorXd count = Eigen::VectorXd::Zero(ny_);
    for (std::size_t e = 0; e < data.size(); ++e) {
      const Experiment& ex = data[e];
      const Location where = at_experiment(static_cast<long>(e));
      const std::string label = "experiment " + std::to_string(e) +
                                (ex.name().empty() ? std::string() : " ('" + ex.name() + "')");
      require(ex.num_inputs() == nu_,
              label + " has " + std::to_string(ex.num_inputs()) + " input(s), the physics takes " +
                  std::to_string(nu_),
              where);
      require(ex.num_outputs() == ny_,
              label + " has " + std::to_string(ex.num_outputs()) + " output(s), the physics gives " +
                  std::to_string(ny_),
              where);
      require(ex.size() >= 2,
              label + " has " + std::to_string(ex.size()) +
                  " sample(s); a simulation needs at least 2 (data too short)",
              where);
      for (Eigen::Index k = 0; k < ex.size(); ++k) {
        for (int j = 0; j < nu_; ++j) {
          if (!std::isfinite(ex.u()(k, j))) {
            Location w = where;
            w.row = static_cast<long>(k) + 1;
            w.column = j + 1;
            throw Error(label + ": input " + std::to_string(j) + " is not finite at sample " +
                            std::to_string(k) + "; a simulation cannot run through missing inputs "
                            "(interpolate or cut the record)",
                        w);
          }
        }
        for (int j = 0; j < ny_; ++j) {
          const double v = ex.y()(k, j);
          if (std::isfinite(v)) {
            sum[j] += v;
            sum2[j] += v * v;
            count[j] += 1.0;
          }
        }
      }
      offsets_.push_back(rows);
      rows += ex.size() * ny_;
    }
    rows_ = rows;
    for (int j = 0; j < ny_; ++j) {
      if (count[j] > 1.0) {
        const double mean = sum[j] / count[j];
        const double var = std::max(sum2[j] / count[j] - mean * mean, 0.0);
        if (var > 0.0) weights_[j] = 1.0 / std::sqrt(var);
      }
    }
    int free = states_only_ ? 0 : static_cast<int>(std::count(fixed_.begin(), fixed_.end(), false));
    if (ic_ == InitialCondition::estimate) free += nx_ * static_cast<int>(data.size());
    require(!check_count || rows_ >= free,
            "grey-box estimation: the data are too short: " + std::to_string(rows_) + " residual(s) for " +
                std::to_string(free) + " free unknown(s) (the parameters not fixed" +
                (ic_ == InitialCondition::estimate ? ", and the initial states of every experiment)" : ")"),
            at_parameter("data"));
  }

 public:

  /// Number of unknowns: n_p (unless states-only) + n_x per experiment (estimate only).
  [[nodiscard]] int num_parameters() const {
    return (states_only_ ? 0 : np_) + (ic_ == InitialCondition::estimate ? nx_ * num_experiments() : 0);
  }
  /// Total number of residuals Σ_e N_e · n_y.
  [[nodiscard]] Eigen::Index num_residuals() const { return rows_; }
  /// Number of experiments.
  [[nodiscard]] int num_experiments() const { return static_cast<int>(data_->size()); }
  /// Column of experiment e's first initial state in θ, or −1 if initial states are not unknowns.
  [[nodiscard]] int state_column(std::size_t e) const {
    if (ic_ != InitialCondition::estimate) return -1;
    return (states_only_ ? 0 : np_) + static_cast<int>(e) * nx_;
  }
  /// First residual row of experiment e (rows are sample-major, output-minor).
  [[nodiscard]] Eigen::Index residual_offset(std::size_t e) const { return offsets_.at(e); }
  /// The output weights w_j = 1/std(y_j) (1 for a constant output).
  [[nodiscard]] const Eigen::VectorXd& output_weights() const { return weights_; }
  /// The initial-condition policy.
  [[nodiscard]] InitialCondition initial_condition() const { return ic_; }
  /// Fixed flags of the physical parameters.
  [[nodiscard]] const std::vector<bool>& fixed() const { return fixed_; }
  /// The physics.
  [[nodiscard]] const P& physics() const { return phys_; }

  /// Whether Jacobian evaluations simulate two experiments at a time in lockstep, as residual
  /// evaluations always do. The numbers are the same either way (tested bit for bit); only the
  /// speed differs, and the default is the faster choice for the build's registers: on where a
  /// dual's derivative lanes fit one register (AVX2, AVX-512 builds for up to 4 or 8 columns),
  /// off with SSE2 alone.
  void set_lockstep_jacobians(bool on) { lockstep_jacobians_ = on; }
  [[nodiscard]] bool lockstep_jacobians() const { return lockstep_jacobians_; }

  /// Per-parameter fixed mask over θ (physical parameters as given, initial states free), for
  /// `LmOptions::fixed`.
  [[nodiscard]] std::vector<bool> fixed_mask() const {
    std::vector<bool> m;
    if (!states_only_) m = fixed_;
    m.resize(static_cast<std::size_t>(num_parameters()), false);
    return m;
  }

  /// Guesses of every experiment's initial state for physical parameters `p`: the physics'
  /// `initial_state` hook from the first sample, else the equilibrium at the first input, else 0.
  [[nodiscard]] Eigen::VectorXd initial_state_guesses(const double* p) const {
    Eigen::VectorXd x(nx_ * num_experiments());
    for (std::size_t e = 0; e < data_->size(); ++e) {
      guess_state(e, p, x.data() + static_cast<Eigen::Index>(e) * nx_);
    }
    return x;
  }

  /// Writes initial-state guesses for θ's own physical parameters into θ's x₀ blocks (no-op
  /// unless initial states are unknowns). Used to prepare each multi-start point.
  void refresh_initial_states(Eigen::VectorXd& theta) const {
    if (ic_ != InitialCondition::estimate) return;
    const double* p = states_only_ ? p_values_.data() : theta.data();
    for (std::size_t e = 0; e < data_->size(); ++e) guess_state(e, p, theta.data() + state_column(e));
  }

  /// The initial state experiment e starts from at θ (double). Returns false if an equilibrium
  /// start has no equilibrium.
  bool initial_state(const Eigen::VectorXd& theta, std::size_t e, double* x0) const {
    const double* p = states_only_ ? p_values_.data() : theta.data();
    switch (ic_) {
      case InitialCondition::estimate:
        for (int i = 0; i < nx_; ++i) x0[i] = theta[state_column(e) + i];
        return true;
      case InitialCondition::zero:
        for (int i = 0; i < nx_; ++i) x0[i] = 0.0;
        return true;
      default:
        return equilibrium_start(e, p, x0, nullptr);
    }
  }

  /// Whether experiment e's equilibrium start exists at physical parameters p and can follow
  /// them (∂f/∂x invertible there): what a Jacobian pass from that start needs.
  [[nodiscard]] bool equilibrium_start_usable(std::size_t e, const double* p) const {
    Eigen::VectorXd x0(nx_);
    Eigen::MatrixXd jinv;
    return equilibrium_start(e, p, x0.data(), &jinv);
  }

  /// Sub-step count for experiment e at physical parameters p and initial state x0: the count
  /// `GreyBox::simulate` takes for the same run (`physics_substeps`).
  [[nodiscard]] int substeps(std::size_t e, const double* p, const double* x0) const {
    const Experiment& ex = (*data_)[e];
    return physics_substeps(phys_, options_, p, x0, ex.u(), ex.ts());
  }

  /// Residuals and (if `J` is not null) the Jacobian at θ; false if a simulation diverged, an
  /// equilibrium start does not exist at θ, θ violates a relation of the physics
  /// (`check_parameters`), or the physics' `spectral_radius` is +inf at θ. `r` and `J` must be pre-sized (LeastSquaresProblem).
  bool evaluate(const Eigen::VectorXd& theta, Eigen::VectorXd& r, Eigen::MatrixXd* J) const {
    if (theta.size() != num_parameters() || !theta.allFinite()) return false;
    const double* p = states_only_ ? p_values_.data() : theta.data();
    // Values that violate a relation of the physics (crossed throttle stops) are not a model:
    // a trial step there is rejected like a diverging one (box bounds cannot keep it out).
    if (!physics_parameters_consistent(phys_, p)) return false;
    if (!physics_stiffness_finite(phys_, p)) return false;
    const std::size_t ne = data_->size();
    // Experiments in lockstep pairs (simulate_physics_pair): one trajectory is a single chain
    // of dependent operations, and the second one fills the cycles it leaves idle. Same numbers
    // as one after the other. Residuals alone (every LM trial step, every multi-start
    // candidate) take about two thirds of the time; Jacobian passes gain where the duals fit one
    // register (set_lockstep_jacobians).
    std::size_t e = 0;
    if (J) {
      J->setZero();
      for (; lockstep_jacobians_ && e + 1 < ne; e += 2) {
        if (!jacobian_pair(e, theta, p, r, *J)) return false;
      }
      for (; e < ne; ++e) {
        if (!evaluate_experiment(e, theta, p, r, J)) return false;
      }
      return true;
    }
    for (; e + 1 < ne; e += 2) {
      if (!residuals_pair(e, theta, p, r)) return false;
    }
    return e == ne || evaluate_experiment(e, theta, p, r, nullptr);
  }

  // ---- Implementation details below ---------------------------------------------------------

 private:
  static constexpr int NP = P::num_params, NX = P::num_states, NU = P::num_inputs;
  static constexpr bool kStatic = StaticPhysics<P>;
  // One-pass dual widths for static physics (fall back to chunks of 8 for physics that only
  // evaluate on double and RuntimeDual).
  static constexpr int full_width() {
    if constexpr (kStatic) {
      if constexpr (detail::EvaluatesPhysicsOn<P, Dual<double, NP + NX>>) return NP + NX;
    }
    return RuntimeDual::num_derivatives;
  }
  // Parameters only (initial states known: zero, equilibrium, or a fixed x0): no dual lanes
  // are spent on states no column asks for.
  static constexpr int params_width() {
    if constexpr (kStatic) {
      if constexpr (detail::EvaluatesPhysicsOn<P, Dual<double, NP>>) return NP;
    }
    return RuntimeDual::num_derivatives;
  }
  static constexpr int states_width() {
    if constexpr (kStatic) {
      if constexpr (detail::EvaluatesPhysicsOn<P, Dual<double, NX>>) return NX;
    }
    return RuntimeDual::num_derivatives;
  }
  static constexpr int kMaxActive = kStatic ? NP + NX : Dynamic;

  // One Jacobian column of this experiment: a physical parameter or an initial state.
  struct Active {
    bool is_state;
    int index;   // parameter or state index
    int column;  // column in θ / J
  };
  using ActiveList = std::conditional_t<kStatic, std::array<Active, (kStatic ? NP + NX : 1)>,
                                        std::vector<Active>>;

  void guess_state(std::size_t e, const double* p, double* x0) const {
    const Experiment& ex = (*data_)[e];
    Eigen::Matrix<double, P::num_outputs, 1> y0(ny_);
    Eigen::Matrix<double, NU, 1> u0(nu_);
    for (int j = 0; j < ny_; ++j) y0[j] = ex.y()(0, j);
    for (int j = 0; j < nu_; ++j) u0[j] = ex.u()(0, j);
    physics_initial_guess(phys_, y0.data(), u0.data(), p, x0);
  }

  // Equilibrium at the first input, from the initial-state guess; optionally J⁻¹ at the solution.
  bool equilibrium_start(std::size_t e, const double* p, double* x0, Eigen::MatrixXd* jinv) const {
    guess_state(e, p, x0);
    const Experiment& ex = (*data_)[e];
    const Eigen::VectorXd u0 = ex.u().row(0).transpose();
    const EquilibriumResult res = physics_equilibrium(phys_, u0.data(), p, x0);
    if (!res.converged) return false;
    if (jinv) {
      const Eigen::MatrixXd Jx = physics_state_jacobian(phys_, x0, u0.data(), p);
      Eigen::FullPivLU<Eigen::MatrixXd> lu(Jx);
      if (!lu.isInvertible()) return false;
      *jinv = lu.inverse();
    }
    return true;
  }

  // What a Jacobian pass over experiment e needs: its start, and the θ columns it can affect.
  struct PassSetup {
    Eigen::Matrix<double, NX, 1> x0;
    Eigen::MatrixXd jinv;  // (∂f/∂x)⁻¹ at the equilibrium start
    ActiveList act{};
    int nact = 0;
    int sub = 1;
  };

  bool setup_pass(std::size_t e, const Eigen::VectorXd& theta, const double* p, PassSetup& s) const {
    s.x0.resize(nx_);
    if (ic_ == InitialCondition::equilibrium) {
      if (!equilibrium_start(e, p, s.x0.data(), &s.jinv)) return false;
    } else {
      initial_state(theta, e, s.x0.data());
    }
    s.sub = substeps(e, p, s.x0.data());
    s.nact = 0;
    auto push = [&](bool is_state, int index, int column) {
      if constexpr (kStatic) {
        s.act[static_cast<std::size_t>(s.nact)] = Active{is_state, index, column};
      } else {
        s.act.push_back(Active{is_state, index, column});
      }
      ++s.nact;
    };
    if (!states_only_) {
      for (int i = 0; i < np_; ++i) {
        if (!fixed_[static_cast<std::size_t>(i)]) push(false, i, i);
      }
    }
    if (ic_ == InitialCondition::estimate) {
      for (int i = 0; i < nx_; ++i) push(true, i, state_column(e) + i);
    }
    return true;
  }

  // The dual width of the passes: every active column in one pass where the physics allows.
  static constexpr int pass_width(bool states_only, InitialCondition ic) {
    if (states_only) return states_width();
    return ic != InitialCondition::estimate ? params_width() : full_width();
  }
  // f.template operator()<W>() with this problem's pass width W as a compile-time constant.
  template <class F>
  bool with_pass_width(F&& f) const {
    if (states_only_) return f.template operator()<pass_width(true, InitialCondition::zero)>();
    if (ic_ != InitialCondition::estimate) return f.template operator()<pass_width(false, InitialCondition::zero)>();
    return f.template operator()<pass_width(false, InitialCondition::estimate)>();
  }

  // Jacobian passes in lockstep pairs by default only where a dual's derivative lanes fill at
  // most one register: then a dual operation is one short dependency chain and the core has
  // room for a second one (throttle, Dual<4>: 35.3 -> 29.3 ms per solve with AVX-512, 38.5 ->
  // 37.4 ms with AVX2). With SSE2 the same dual takes two or three packets per operation, the
  // core is already busy, and pairs ran 2 % slower (docs/performance.md).
  static constexpr bool lockstep_jacobians_by_default() {
    return static_cast<std::size_t>(pass_width(false, InitialCondition::zero)) * sizeof(double) <=
           default_register_bytes;
  }

  bool evaluate_experiment(std::size_t e, const Eigen::VectorXd& theta, const double* p,
                           Eigen::VectorXd& r, Eigen::MatrixXd* J) const {
    if (!J) {
      Eigen::Matrix<double, NX, 1> x0(nx_);
      if (ic_ == InitialCondition::equilibrium) {
        if (!equilibrium_start(e, p, x0.data(), nullptr)) return false;
      } else {
        initial_state(theta, e, x0.data());
      }
      return residuals_alone(e, p, x0.data(), substeps(e, p, x0.data()), r);
    }
    PassSetup s;
    if (!setup_pass(e, theta, p, s)) return false;
    return with_pass_width([&]<int W>() { return passes<W>(e, p, s, r, *J); });
  }

  // Jacobian and residuals of experiments e and e + 1 in lockstep; one after the other when
  // their sample times or sub-step counts differ.
  bool jacobian_pair(std::size_t e, const Eigen::VectorXd& theta, const double* p, Eigen::VectorXd& r,
                     Eigen::MatrixXd& J) const {
    PassSetup a, b;
    if (!setup_pass(e, theta, p, a)) return false;
    if (!setup_pass(e + 1, theta, p, b)) return false;
    if ((*data_)[e].ts() != (*data_)[e + 1].ts() || a.sub != b.sub) {
      return evaluate_experiment(e, theta, p, r, &J) && evaluate_experiment(e + 1, theta, p, r, &J);
    }
    return with_pass_width([&]<int W>() { return passes_pair<W>(e, p, a, b, r, J); });
  }

  // Writes experiment e's weighted residuals (zero where the measurement is missing).
  auto residual_writer(std::size_t e, Eigen::VectorXd& r) const {
    return [this, &ex = (*data_)[e], off = offsets_[e], &r](Eigen::Index k, const double* y) {
      for (int j = 0; j < ny_; ++j) {
        const double ym = ex.y()(k, j);
        r[off + k * ny_ + j] = std::isfinite(ym) ? (y[j] - ym) * weights_[j] : 0.0;
      }
    };
  }

  // Writes experiment e's Jacobian columns act[c0, c1) from dual outputs (and, in the first
  // pass, its residuals).
  template <class D>
  auto jacobian_writer(std::size_t e, const PassSetup& s, int c0, int c1, Eigen::VectorXd& r,
                       Eigen::MatrixXd& J) const {
    return [this, &ex = (*data_)[e], off = offsets_[e], act = s.act.data(), c0, c1, &r, &J](Eigen::Index k,
                                                                                          const D* y) {
      const bool first = c0 == 0;
      for (int j = 0; j < ny_; ++j) {
        const double ym = ex.y()(k, j);
        const Eigen::Index row = off + k * ny_ + j;
        if (!std::isfinite(ym)) {
          if (first) r[row] = 0.0;
          continue;
        }
        const double w = weights_[j];
        if (first) r[row] = (y[j].a - ym) * w;
        for (int c = c0; c < c1; ++c) J(row, act[c].column) = y[j].v[c - c0] * w;
      }
    };
  }

  // Seeds the duals of pass [c0, c1): parameters into pd (the same for every experiment, whose
  // active parameters are the same), initial states into xd.
  template <class D>
  void seed_parameters(const double* p, const PassSetup& s, int c0, int c1, D* pd) const {
    for (int i = 0; i < np_; ++i) pd[i] = D(p[i]);
    for (int c = c0; c < c1; ++c) {
      const Active& a = s.act[static_cast<std::size_t>(c)];
      if (!a.is_state) pd[a.index] = D::variable(p[a.index], c - c0);
    }
  }
  template <class D>
  void seed_states(std::size_t e, const PassSetup& s, int c0, int c1, const D* pd, D* xd) const {
    for (int i = 0; i < nx_; ++i) xd[i] = D(ic_ == InitialCondition::zero ? 0.0 : s.x0[i]);
    for (int c = c0; c < c1; ++c) {
      const Active& a = s.act[static_cast<std::size_t>(c)];
      if (a.is_state) xd[a.index] = D::variable(s.x0[a.index], c - c0);
    }
    if (ic_ == InitialCondition::equilibrium) {
      const Experiment& ex = (*data_)[e];
      Eigen::Matrix<D, NU, 1> u0(nu_);
      Eigen::Matrix<D, NX, 1> work(nx_);
      for (int j = 0; j < nu_; ++j) u0[j] = D(ex.u()(0, j));
      equilibrium_sensitivity_step(phys_, s.x0.data(), u0.data(), pd, s.jinv.data(), work.data(), xd);
    }
  }

  // Residuals of experiment e simulated on its own from x0 (not modified).
  bool residuals_alone(std::size_t e, const double* p, const double* x0, int sub, Eigen::VectorXd& r) const {
    const Experiment& ex = (*data_)[e];
    Eigen::Matrix<double, NX, 1> x(nx_);
    for (int i = 0; i < nx_; ++i) x[i] = x0[i];
    return simulate_physics<double>(phys_, options_, sub, ex.u(), ex.ts(), p, x.data(), residual_writer(e, r)) ==
           ex.size();
  }

  // Residuals of experiments e and e + 1 in lockstep; one after the other when their sample
  // times or sub-step counts differ (lockstep needs equal steps).
  bool residuals_pair(std::size_t e, const Eigen::VectorXd& theta, const double* p, Eigen::VectorXd& r) const {
    Eigen::Matrix<double, NX, 1> xa(nx_), xb(nx_);
    if (!initial_state(theta, e, xa.data()) || !initial_state(theta, e + 1, xb.data())) return false;
    const int sub = substeps(e, p, xa.data()), sub_b = substeps(e + 1, p, xb.data());
    const Experiment& a = (*data_)[e];
    const Experiment& b = (*data_)[e + 1];
    if (a.ts() != b.ts() || sub != sub_b) {
      return residuals_alone(e, p, xa.data(), sub, r) && residuals_alone(e + 1, p, xb.data(), sub_b, r);
    }
    const std::array<Eigen::Index, 2> got = simulate_physics_pair(
        phys_, options_, sub, a.u(), b.u(), a.ts(), p, xa.data(), xb.data(), residual_writer(e, r),
        residual_writer(e + 1, r));
    return got[0] == a.size() && got[1] == b.size();
  }

  // Simulates experiment e on Dual<double, W>, seeding `W` active columns per pass.
  template <int W>
  bool passes(std::size_t e, const double* p, const PassSetup& s, Eigen::VectorXd& r, Eigen::MatrixXd& J) const {
    using D = Dual<double, W>;
    const Experiment& ex = (*data_)[e];
    Eigen::Matrix<D, NP, 1> pd(np_);
    Eigen::Matrix<D, NX, 1> xd(nx_);
    for (int c0 = 0; c0 < std::max(s.nact, 1); c0 += W) {
      const int c1 = std::min(s.nact, c0 + W);
      seed_parameters(p, s, c0, c1, pd.data());
      seed_states(e, s, c0, c1, pd.data(), xd.data());
      const Eigen::Index got = simulate_physics<D>(phys_, options_, s.sub, ex.u(), ex.ts(), pd.data(), xd.data(),
                                                   jacobian_writer<D>(e, s, c0, c1, r, J));
      if (got != ex.size()) return false;
    }
    return true;
  }

  // The same for experiments e and e + 1 in lockstep (equal sample times and sub-steps; both
  // have the same active parameters, and their state columns sit at the same lanes).
  template <int W>
  bool passes_pair(std::size_t e, const double* p, const PassSetup& a, const PassSetup& b, Eigen::VectorXd& r,
                   Eigen::MatrixXd& J) const {
    using D = Dual<double, W>;
    const Experiment& ea = (*data_)[e];
    const Experiment& eb = (*data_)[e + 1];
    Eigen::Matrix<D, NP, 1> pd(np_);
    Eigen::Matrix<D, NX, 1> xa(nx_), xb(nx_);
    for (int c0 = 0; c0 < std::max(a.nact, 1); c0 += W) {
      const int c1 = std::min(a.nact, c0 + W);
      seed_parameters(p, a, c0, c1, pd.data());
      seed_states(e, a, c0, c1, pd.data(), xa.data());
      seed_states(e + 1, b, c0, c1, pd.data(), xb.data());
      const std::array<Eigen::Index, 2> got = simulate_physics_pair(
          phys_, options_, a.sub, ea.u(), eb.u(), ea.ts(), static_cast<const D*>(pd.data()), xa.data(), xb.data(),
          jacobian_writer<D>(e, a, c0, c1, r, J), jacobian_writer<D>(e + 1, b, c0, c1, r, J));
      if (got[0] != ea.size() || got[1] != eb.size()) return false;
    }
    return true;
  }

  P phys_;
  IntegratorOptions options_;
  const Dataset* data_;
  InitialCondition ic_;
  std::vector<bool> fixed_;
  bool states_only_;
  Eigen::VectorXd p_values_;
  int nx_ = 0, nu_ = 0, ny_ = 0, np_ = 0;
  std::vector<Eigen::Index> offsets_;
  Eigen::Index rows_ = 0;
  Eigen::VectorXd weights_;
  bool lockstep_jacobians_ = lockstep_jacobians_by_default();
};

}  // namespace nlid
