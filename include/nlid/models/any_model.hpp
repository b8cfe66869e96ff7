#pragma once
/// @file
/// `AnyModel`: any estimated model as one value type, and `load_model(path)`, which rebuilds a
/// model's structure at run time from its file.
///
/// Why. Command-line tools (nlid-fit, nlid-sim), reports and comparisons handle models whose
/// kind is known only while the program runs: "the model in this file", "the best of these
/// candidates". `AnyModel` erases the type behind a small virtual interface (simulate, predict,
/// parameters, describe, save) — the classic external-polymorphism pattern (Parent, "Inheritance
/// is the base class of evil", 2013): the concrete model keeps its value semantics and its fast
/// compile-time code, and copying an AnyModel copies the model.
///
///     nlid::AnyModel m = nlid::load_model("nlarx5.json");   // structure from the file
///     Eigen::MatrixXd y = m.simulate(data3);                // its default initial condition
///     std::cout << m.describe();
///     m.save("copy.json");                                   // bit-exact round trip
///
/// What `load_model(path)` builds, by the file's "kind":
///
///     nlarx               Nlarx<RegressorList, AnyNonlinearity>   (`DynamicNlarx`)
///     hammerstein_wiener  HammersteinWiener<AnyNonlinearity, TransferFunctionBlock<Dynamic, Dynamic,
///                         Dynamic>, AnyNonlinearity>               (`DynamicHammersteinWiener`)
///     greybox             GreyBox<AnyPhysics> of the catalogue physics named in the file
///     arx, output_error, state_space   the linear model classes
///
/// Other kinds (series compositions, augmented grey-box models) plug in through
/// `register_model_kind(kind, loader)`, so a layer above can add its own without this header
/// knowing it. Run-time models simulate bit for bit like the compile-time model that was saved
/// (same operations in the same order; tested).
///
/// Layering note: this header includes the io serialisers (io/model_file.hpp) because `save`
/// and `load_model` are part of the run-time model's contract.

#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <type_traits>
#include <typeinfo>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/core/initial_condition.hpp"
#include "nlid/data/experiment.hpp"
#include "nlid/io/model_file.hpp"
#include "nlid/linear/concepts.hpp"
#include "nlid/models/concepts.hpp"
#include "nlid/models/greybox_dynamic.hpp"
#include "nlid/models/hammerstein_wiener.hpp"
#include "nlid/models/nlarx.hpp"
#include "nlid/models/transfer_function_block.hpp"
#include "nlid/nonlinearities/any_nonlinearity.hpp"
#include "nlid/regressors/expression.hpp"

namespace nlid {

/// Nonlinear ARX with regressors and nonlinearity chosen at run time.
using DynamicNlarx = Nlarx<RegressorList, AnyNonlinearity>;
/// Hammerstein–Wiener with blocks chosen at run time.
using DynamicHammersteinWiener =
    HammersteinWiener<AnyNonlinearity, TransferFunctionBlock<Dynamic, Dynamic, Dynamic>, AnyNonlinearity>;

/// What `AnyModel` can hold: simulates experiments, describes itself, and has a model-file
/// serialiser. Satisfied by Nlarx, HammersteinWiener, GreyBox, Arx, OutputError, StateSpace.
template <class M>
concept ErasableModel = SavableModel<M> && requires(const M& m, const Experiment& e, InitialCondition ic) {
  { m.simulate(e, ic) } -> std::convertible_to<Eigen::MatrixXd>;
  { m.describe() } -> std::convertible_to<std::string>;
};

/// Any model behind one interface, with value semantics (see the file comment).
/// Satisfies `Model`. Invariant: `empty()` or holds exactly one model.
class AnyModel {
 public:
  /// No model (every call but `empty()` throws).
  AnyModel() = default;

  /// Holds `model` (copied); `info` carries units, the default initial condition and the
  /// description written to files.
  template <class M>
    requires ErasableModel<M> && (!std::is_same_v<std::remove_cvref_t<M>, AnyModel>)
  AnyModel(M model, ModelFileInfo info = {})  // NOLINT(google-explicit-constructor)
      : impl_(std::make_shared<Holder<M>>(std::move(model))), info_(std::move(info)) {}

  /// Copies share nothing mutable: the held model is cloned on copy.
  AnyModel(const AnyModel& o) : impl_(o.impl_ ? o.impl_->clone() : nullptr), info_(o.info_) {}
  /// See the copy constructor.
  AnyModel& operator=(const AnyModel& o) {
    if (this != &o) {
      impl_ = o.impl_ ? o.impl_->clone() : nullptr;
      info_ = o.info_;
    }
    return *this;
  }
  /// Moves.
  AnyModel(AnyModel&&) noexcept = default;
  /// Moves.
  AnyModel& operator=(AnyModel&&) noexcept = default;
  ~AnyModel() = default;

  /// True if no model is held.
  [[nodiscard]] bool empty() const { return impl_ == nullptr; }
  /// Kind name ("nlarx", "hammerstein_wiener", "greybox", "arx", "output_error", "state_space", …).
  [[nodiscard]] std::string kind() const { return get().kind(); }

  /// Free-run simulation from the model's default initial condition (`initial_condition()`).
  [[nodiscard]] Eigen::MatrixXd simulate(const Experiment& e) const { return get().simulate(e, initial_condition()); }
  /// Free-run simulation from the given initial condition (N × ny).
  [[nodiscard]] Eigen::MatrixXd simulate(const Experiment& e, InitialCondition ic) const {
    return get().simulate(e, ic);
  }
  /// k-step-ahead prediction (N × ny); models without a noise model return their simulation.
  [[nodiscard]] Eigen::MatrixXd predict(const Experiment& e, int k = 1) const {
    return get().predict(e, k, initial_condition());
  }
  /// True if the held model has a predictor of its own (nonlinear ARX, ARX, Hammerstein–Wiener,
  /// the linear models); false where `predict` stands in with the simulation from the default
  /// initial condition (a grey box, a registered kind without `predict`). `resid` uses it to
  /// take simulation residuals with its own initial condition instead.
  [[nodiscard]] bool has_predictor() const { return get().has_predictor(); }
  /// True if the held model is linear (the `LinearModel` concept: ARX, output error, state
  /// space): `step_response` leaves out its output offset and `impulse_response` takes it.
  [[nodiscard]] bool is_linear() const { return get().is_linear(); }
  /// Leading samples that `predict` (and a simulation from `InitialCondition::measured`) copy
  /// from the data instead of computing: n₀ of a nonlinear ARX model, the largest lag of an ARX
  /// model, 0 otherwise. Their residuals are exactly zero; `resid` skips them.
  [[nodiscard]] int history_length() const { return get().history_length(); }
  /// Sample time in seconds (0: not set, e.g. continuous-time grey-box models).
  [[nodiscard]] double ts() const { return get().ts(); }
  /// Human-readable description of the held model.
  [[nodiscard]] std::string describe() const { return get().describe(); }

  /// Parameters θ of the held model.
  [[nodiscard]] Eigen::VectorXd parameters() const { return get().parameters(); }
  /// Sets θ (throws `nlid::Error` on a size mismatch or a value outside a bound). Drops
  /// `info().uncertainty`: it described the estimate, not the new values.
  void set_parameters(const Eigen::VectorXd& theta) {
    const Eigen::VectorXd before = info_.uncertainty ? parameters() : Eigen::VectorXd();
    get().set_parameters(theta);
    if (info_.uncertainty && !(before.size() == theta.size() && before == theta)) info_.uncertainty.reset();
  }
  /// Names of θ's entries.
  [[nodiscard]] std::vector<std::string> parameter_names() const { return get().parameter_names(); }

  /// Number of inputs.
  [[nodiscard]] int num_inputs() const { return get().num_inputs(); }
  /// Number of outputs.
  [[nodiscard]] int num_outputs() const { return get().num_outputs(); }
  /// Input channel names.
  [[nodiscard]] std::vector<std::string> input_names() const { return get().input_names(); }
  /// Output channel names.
  [[nodiscard]] std::vector<std::string> output_names() const { return get().output_names(); }

  /// Units, default initial condition, description, creation time (and report of models that
  /// keep none themselves).
  [[nodiscard]] const ModelFileInfo& info() const { return info_; }
  /// Mutable metadata.
  [[nodiscard]] ModelFileInfo& info() { return info_; }
  /// The policy `simulate(e)` starts from: the file's / the estimation's, else zero.
  [[nodiscard]] InitialCondition initial_condition() const {
    if (info_.initial_condition) return *info_.initial_condition;
    return get().estimation_initial_condition();
  }

  /// The whole model file as JSON.
  [[nodiscard]] Json to_json() const { return get().to_json(info_); }
  /// Writes the model file atomically.
  void save(const std::string& path) const {
    std::string text = to_json().dump(2);
    text.push_back('\n');
    write_file_atomically(path, text);
  }

  /// The held model if it is an M, else null.
  template <class M>
  [[nodiscard]] const M* target() const {
    return impl_ && impl_->type() == typeid(M) ? static_cast<const M*>(impl_->pointer()) : nullptr;
  }
  /// The held model if it is an M, else null (mutable).
  template <class M>
  [[nodiscard]] M* target() {
    return impl_ && impl_->type() == typeid(M) ? static_cast<M*>(impl_->pointer()) : nullptr;
  }

  // ---- Implementation details below ----------------------------------------------------------
 private:
  struct Interface {
    virtual ~Interface() = default;
    [[nodiscard]] virtual std::shared_ptr<Interface> clone() const = 0;
    [[nodiscard]] virtual std::string kind() const = 0;
    [[nodiscard]] virtual Eigen::MatrixXd simulate(const Experiment& e, InitialCondition ic) const = 0;
    [[nodiscard]] virtual Eigen::MatrixXd predict(const Experiment& e, int k, InitialCondition ic) const = 0;
    [[nodiscard]] virtual bool has_predictor() const = 0;
    [[nodiscard]] virtual bool is_linear() const = 0;
    [[nodiscard]] virtual int history_length() const = 0;
    [[nodiscard]] virtual double ts() const = 0;
    [[nodiscard]] virtual std::string describe() const = 0;
    [[nodiscard]] virtual Eigen::VectorXd parameters() const = 0;
    virtual void set_parameters(const Eigen::VectorXd& theta) = 0;
    [[nodiscard]] virtual std::vector<std::string> parameter_names() const = 0;
    [[nodiscard]] virtual int num_inputs() const = 0;
    [[nodiscard]] virtual int num_outputs() const = 0;
    [[nodiscard]] virtual std::vector<std::string> input_names() const = 0;
    [[nodiscard]] virtual std::vector<std::string> output_names() const = 0;
    [[nodiscard]] virtual InitialCondition estimation_initial_condition() const = 0;
    [[nodiscard]] virtual Json to_json(const ModelFileInfo& info) const = 0;
    [[nodiscard]] virtual const std::type_info& type() const = 0;
    [[nodiscard]] virtual void* pointer() = 0;
    [[nodiscard]] virtual const void* pointer() const = 0;
  };

  template <class M>
  struct Holder final : Interface {
    explicit Holder(M model) : m(std::move(model)) {}
    std::shared_ptr<Interface> clone() const override { return std::make_shared<Holder>(m); }
    std::string kind() const override { return ModelSerial<M>::kind; }
    Eigen::MatrixXd simulate(const Experiment& e, InitialCondition ic) const override { return m.simulate(e, ic); }
    Eigen::MatrixXd predict(const Experiment& e, int k, InitialCondition ic) const override {
      if constexpr (requires { m.predict(e, k); }) {
        return m.predict(e, k);
      } else {
        (void)k;
        return m.simulate(e, ic);  // output-error structure: the predictor is the simulation
      }
    }
    bool has_predictor() const override { return requires(const Experiment& e) { m.predict(e, 1); }; }
    bool is_linear() const override { return LinearModel<M>; }
    int history_length() const override {
      if constexpr (requires { { m.history_length() } -> std::convertible_to<int>; }) {
        return m.history_length();
      } else if constexpr (std::is_same_v<M, Arx>) {
        return m.orders().max_lag();  // Arx::predict copies the first max_lag samples
      } else {
        return 0;
      }
    }
    double ts() const override {
      if constexpr (requires { m.ts(); }) {
        return m.ts();
      } else {
        return 0.0;
      }
    }
    std::string describe() const override { return m.describe(); }
    Eigen::VectorXd parameters() const override {
      if constexpr (requires { m.parameters(); }) {
        return Eigen::VectorXd(m.parameters());
      } else {
        return to_json(ModelFileInfo{}).view().at("parameters").at("values").template get<Eigen::VectorXd>();
      }
    }
    void set_parameters(const Eigen::VectorXd& theta) override {
      if constexpr (requires { m.set_parameters(theta); }) {
        m.set_parameters(theta);
      } else if constexpr (std::is_same_v<M, Arx>) {
        require(theta.size() == m.num_parameters(), "parameter vector has " + std::to_string(theta.size()) +
                    " values, the ARX model has " + std::to_string(m.num_parameters()), at_parameter("theta"));
        Eigen::Index k = 0;
        const Eigen::VectorXd a = theta.segment(k, m.na());
        k += m.na();
        std::vector<Eigen::VectorXd> b;
        std::vector<int> nk;
        for (int i = 0; i < m.num_inputs(); ++i) {
          b.push_back(theta.segment(k, m.nb(i)));
          k += m.nb(i);
          nk.push_back(m.nk(i));
        }
        const auto names = m.input_names();
        const auto out_names = m.output_names();
        m = Arx(a, b, nk, m.ts(), m.has_offset() ? theta(k) : 0.0);
        if (static_cast<int>(names.size()) == m.num_inputs()) m.set_input_names(names);
        m.set_output_names(out_names);
      } else if constexpr (std::is_same_v<M, OutputError>) {
        require(theta.size() == m.num_parameters(), "parameter vector has " + std::to_string(theta.size()) +
                    " values, the output-error model has " + std::to_string(m.num_parameters()), at_parameter("theta"));
        Eigen::Index k = 0;
        std::vector<Eigen::VectorXd> b, f;
        std::vector<int> nk;
        for (int i = 0; i < m.num_inputs(); ++i) {
          b.push_back(theta.segment(k, m.b(i).size()));
          k += m.b(i).size();
          nk.push_back(m.nk(i));
        }
        for (int i = 0; i < m.num_inputs(); ++i) {
          f.push_back(theta.segment(k, m.f(i).size()));
          k += m.f(i).size();
        }
        const auto names = m.input_names();
        const auto out_names = m.output_names();
        m = OutputError(b, f, nk, m.ts(), m.has_offset() ? theta(k) : 0.0);
        if (static_cast<int>(names.size()) == m.num_inputs()) m.set_input_names(names);
        m.set_output_names(out_names);
      } else {
        (void)theta;
        throw Error("a " + kind() + " model cannot take a parameter vector; build a new model from its matrices",
                    at_parameter("theta"));
      }
    }
    std::vector<std::string> parameter_names() const override {
      if constexpr (requires { m.parameter_names(); }) {
        return m.parameter_names();
      } else {
        return read_string_list(to_json(ModelFileInfo{}).view().at("parameters").at("names"));
      }
    }
    int num_inputs() const override {
      if constexpr (requires { m.num_inputs(); }) {
        return m.num_inputs();
      } else if constexpr (requires { m.input_dimension(); }) {
        return m.input_dimension();
      } else {
        return 1;  // single-input models (e.g. augmented grey-box) name no count
      }
    }
    int num_outputs() const override {
      if constexpr (requires { m.num_outputs(); }) {
        return m.num_outputs();
      } else if constexpr (requires { m.output_dimension(); }) {
        return m.output_dimension();
      } else {
        return 1;
      }
    }
    std::vector<std::string> input_names() const override {
      if constexpr (requires { m.input_names(); }) {
        auto n = std::vector<std::string>(m.input_names());
        if (static_cast<int>(n.size()) == num_inputs()) return n;
      } else if constexpr (requires { m.input_name(); }) {
        return {m.input_name()};
      }
      return default_input_names(num_inputs());
    }
    std::vector<std::string> output_names() const override {
      if constexpr (requires { m.output_name(); }) {
        return {m.output_name()};
      } else {
        if constexpr (requires { m.output_names(); }) {
          auto n = std::vector<std::string>(m.output_names());
          if (static_cast<int>(n.size()) == num_outputs()) return n;
        }
        std::vector<std::string> s;
        for (int i = 0; i < num_outputs(); ++i) s.push_back("y" + std::to_string(i + 1));
        return s;
      }
    }
    InitialCondition estimation_initial_condition() const override {
      if constexpr (requires { m.report().initial_condition; m.report().estimated; }) {
        const auto& r = m.report();
        if (r.estimated) {
          for (InitialCondition c : {InitialCondition::zero, InitialCondition::estimate, InitialCondition::equilibrium,
                                     InitialCondition::measured})
            if (r.initial_condition == to_string(c)) return c;
        }
      }
      if constexpr (requires { m.estimated_initial_states(); }) return InitialCondition::estimate;  // grey box
      return InitialCondition::zero;
    }
    Json to_json(const ModelFileInfo& info) const override { return model_to_json(m, info); }
    const std::type_info& type() const override { return typeid(M); }
    void* pointer() override { return &m; }
    const void* pointer() const override { return &m; }

    M m;
  };

  const Interface& get() const {
    if (!impl_) throw Error("the AnyModel is empty (no model loaded or assigned)");
    return *impl_;
  }
  Interface& get() {
    if (!impl_) throw Error("the AnyModel is empty (no model loaded or assigned)");
    return *impl_;
  }

  std::shared_ptr<Interface> impl_;
  ModelFileInfo info_;
};

/// Builds a model of a file's kind: parsed file → AnyModel (`info` filled with the metadata).
using ModelKindLoader = std::function<AnyModel(const JsonView& file, ModelFileInfo& info)>;

namespace detail {
struct ModelKindRegistry {
  std::mutex mutex;
  std::map<std::string, ModelKindLoader> loaders;
};
template <class M>
AnyModel load_as(const JsonView& file, ModelFileInfo& info) {
  M m = ModelSerial<M>::load(file, info);
  return AnyModel(std::move(m), info);
}
inline ModelKindRegistry& model_kind_registry() {
  static ModelKindRegistry reg;
  static std::once_flag filled;
  std::call_once(filled, [] {
    reg.loaders["nlarx"] = &load_as<DynamicNlarx>;
    reg.loaders["hammerstein_wiener"] = &load_as<DynamicHammersteinWiener>;
    reg.loaders["greybox"] = &load_as<DynamicGreyBox>;
    reg.loaders["arx"] = &load_as<Arx>;
    reg.loaders["output_error"] = &load_as<OutputError>;
    reg.loaders["state_space"] = &load_as<StateSpace>;
  });
  return reg;
}
}  // namespace detail

/// Adds a loader for a new model kind (e.g. "series" from models/series.hpp). Throws if the kind
/// is already registered.
inline void register_model_kind(const std::string& kind, ModelKindLoader loader) {
  require(!kind.empty() && static_cast<bool>(loader), "register_model_kind: empty kind or loader");
  auto& reg = detail::model_kind_registry();
  std::lock_guard<std::mutex> lock(reg.mutex);
  require(reg.loaders.find(kind) == reg.loaders.end(), "model kind '" + kind + "' is already registered",
          at_parameter("kind"));
  reg.loaders.emplace(kind, std::move(loader));
}

/// Model kinds `load_model(path)` can build, sorted.
[[nodiscard]] inline std::vector<std::string> model_kinds() {
  auto& reg = detail::model_kind_registry();
  std::lock_guard<std::mutex> lock(reg.mutex);
  std::vector<std::string> k;
  for (const auto& [name, f] : reg.loaders) k.push_back(name);
  return k;
}

/// Builds the model held by parsed model-file JSON, its structure chosen at run time.
[[nodiscard]] inline AnyModel any_model_from_json(const Json& j) {
  const JsonView file = j.view();
  const std::string kind = check_model_file(file);
  ModelKindLoader loader;
  {
    auto& reg = detail::model_kind_registry();
    std::lock_guard<std::mutex> lock(reg.mutex);
    const auto it = reg.loaders.find(kind);
    if (it != reg.loaders.end()) loader = it->second;
  }
  if (!loader) {
    std::string known;
    for (const auto& k : model_kinds()) known += (known.empty() ? "" : ", ") + k;
    file.at("kind").fail("unknown model kind \"" + kind + "\" at kind (this program reads: " + known + ")");
  }
  ModelFileInfo info = model_file_info(file);
  AnyModel m = loader(file, info);
  m.info() = std::move(info);
  return m;
}

/// Loads a model file and builds its structure at run time (see the file comment). Throws
/// `nlid::Error` naming the file and the key path of anything damaged, missing or newer.
[[nodiscard]] inline AnyModel load_model(const std::string& path) { return any_model_from_json(read_model_file(path)); }

}  // namespace nlid
