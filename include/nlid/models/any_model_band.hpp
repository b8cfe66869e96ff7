#pragma once
/// @file
/// `simulation_band(any_model, data)`: the simulation band of a model held by `AnyModel` — one
/// loaded from a file with `load_model(path)`, or what `fit_model_spec` (nlid-fit) returned —
/// from the uncertainty it carries: a grey box its own covariance (`GreyBox::parameter_covariance`),
/// a nonlinear ARX or Hammerstein–Wiener model `info().uncertainty` (the file's top-level
/// "uncertainty"). A header of its own so that `AnyModel` users who never ask for a band
/// do not compile the forward-AD simulation it needs.

#include <concepts>
#include <string>

#include "nlid/core/error.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/models/any_model.hpp"
#include "nlid/models/simulation_band.hpp"

namespace nlid {

/// Band of `model`'s simulation on `data` (see models/simulation_band.hpp). The initial condition
/// defaults to the one `model.simulate(e)` starts from (`AnyModel::initial_condition()`), so the
/// band belongs to that simulation. Throws `nlid::Error` for a kind without a band (linear and
/// series models: their files keep no covariance), for a model that carries no uncertainty
/// (estimated without it, or changed since), and as the typed overloads. A template on exactly
/// `AnyModel` so that a typed model does not convert to one silently (and then lack the
/// uncertainty the typed overloads take as an argument).
template <std::same_as<AnyModel> A>
SimulationBand simulation_band(const A& held, const Dataset& data, SimulationBandOptions options = {}) {
  const AnyModel& model = held;  // not dependent from here on
  if (!options.initial_condition) options.initial_condition = model.initial_condition();
  const auto* g = model.target<DynamicGreyBox>();
  const bool carries = g != nullptr ? g->parameter_covariance().size() > 0 : model.info().uncertainty.has_value();
  if (!carries && !model.info().uncertainty_left_out.empty()) {
    throw Error("simulation_band: the model file's parameter covariance was not loaded: " +
                    model.info().uncertainty_left_out + "; estimate the changed model again for a band",
                at_parameter("covariance"));
  }
  if (g != nullptr) return simulation_band(*g, data, options);
  const auto* arx = model.target<DynamicNlarx>();
  const auto* hw = model.target<DynamicHammersteinWiener>();
  if (arx == nullptr && hw == nullptr) {
    throw Error("simulation_band: a " + model.kind() +
                    " model held this way has no simulation band (nlid propagates the parameter covariance of "
                    "nonlinear ARX, Hammerstein-Wiener and grey-box models as load_model(path) and fit_model_spec "
                    "build them; call simulation_band on a compile-time model directly)",
                at_parameter("model"));
  }
  if (!model.info().uncertainty) {
    throw Error("simulation_band: this " + model.kind() +
                    " model carries no parameter covariance (estimate it with nlid-fit, or set "
                    "ModelFileInfo::uncertainty from parameter_uncertainty before saving; a model whose parameters "
                    "were changed since has none)",
                at_parameter("covariance"));
  }
  if (arx != nullptr) return simulation_band(*arx, data, *model.info().uncertainty, options);
  return simulation_band(*hw, data, *model.info().uncertainty, options);
}

}  // namespace nlid
