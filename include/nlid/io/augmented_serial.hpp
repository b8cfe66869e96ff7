#pragma once
/// @file
/// Augmented grey-box models (diagnose/augmented.hpp) in model files: kind "augmented_greybox".
///
/// A diagnosis returns a baseline physics with catalogue effects (friction, stops, dead zone,
/// dead time …) composed around it. The file keeps what rebuilds it exactly:
///
///     "structure": {
///       "physics": "throttle",                      catalogue name of the baseline
///       "baseline_parameters": [ParameterInfo...],  names, units, bounds, ranges, fixed flags
///       "effects": [ {"effect": "coulomb_friction", "variant": "", "width": 0.05, "speed": 0,
///                     "parameters": [ParameterInfo...]}, ... ],   in the order they were added
///       "integrator": {...}
///     }
///
/// with θ = [baseline; effect₁; effect₂; …] in "parameters". Including this header registers the
/// kind, so `load_model(path)` returns an `AnyModel` holding `AugmentedModel<AnyPhysics>`.

#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "nlid/core/error.hpp"
#include "nlid/diagnose/augmented.hpp"
#include "nlid/diagnose/effects.hpp"
#include "nlid/io/json.hpp"
#include "nlid/io/model_serial.hpp"
#include "nlid/io/serial_common.hpp"
#include "nlid/models/any_model.hpp"
#include "nlid/models/greybox_dynamic.hpp"

namespace nlid {

/// One parameter description (name, unit, description, value, bounds, range, flags) as JSON.
[[nodiscard]] inline Json parameter_info_to_json(const ParameterInfo& q) {
  Json p = Json::object();
  p["name"] = q.name;
  p["unit"] = q.unit;
  p["description"] = q.description;
  p["value"] = q.value;
  p["lower"] = extended_number(q.lower);
  p["upper"] = extended_number(q.upper);
  p["range_lower"] = extended_number(q.range_lower);
  p["range_upper"] = extended_number(q.range_upper);
  p["log_scale"] = q.log_scale;
  p["fixed"] = q.fixed;
  return p;
}

/// Reads `parameter_info_to_json`.
[[nodiscard]] inline ParameterInfo parameter_info_from_json(const JsonView& v) {
  v.check_keys({"name", "unit", "description", "value", "lower", "upper", "range_lower", "range_upper", "log_scale",
                "fixed"});
  ParameterInfo q;
  q.name = v.at("name").as_string();
  q.unit = v.at("unit").as_string();
  q.description = v.value_or<std::string>("description", "");
  q.value = v.at("value").as_number();
  q.lower = read_extended_number(v.at("lower"));
  q.upper = read_extended_number(v.at("upper"));
  q.range_lower = read_extended_number(v.at("range_lower"));
  q.range_upper = read_extended_number(v.at("range_upper"));
  q.log_scale = v.at("log_scale").as_bool();
  q.fixed = v.at("fixed").as_bool();
  return q;
}

namespace detail {
inline Json parameter_table_json(const std::vector<ParameterInfo>& t) {
  Json::Array a;
  for (const auto& q : t) a.push_back(parameter_info_to_json(q));
  return Json(std::move(a));
}
inline std::vector<ParameterInfo> parameter_table_from_json(const JsonView& v) {
  std::vector<ParameterInfo> t;
  for (std::size_t i = 0; i < v.as_array().size(); ++i) t.push_back(parameter_info_from_json(v.at(i)));
  return t;
}
template <class P>
std::string physics_name_of(const P& p) {
  if constexpr (requires { p.name(); }) {
    return std::string(p.name());
  } else {
    return "custom";
  }
}
}  // namespace detail

/// AugmentedModel<P> (see the file comment).
template <class P>
struct ModelSerial<AugmentedModel<P>> {
  /// Kind name in the file.
  static constexpr const char* kind = "augmented_greybox";
  /// Writes the model's members.
  static void save(Json& j, const AugmentedModel<P>& m, const ModelFileInfo& info) {
    ModelFileInfo i2 = info;
    if (i2.output_units.empty() && !m.output_unit().empty()) i2.output_units = {m.output_unit()};
    if (i2.input_units.empty() && !m.input_unit().empty()) i2.input_units = {m.input_unit()};
    const EstimationReport report = info.report ? *info.report : EstimationReport{};
    std::vector<std::string> in = m.input_names(), out = m.output_names();
    if (in.empty()) in = default_input_names(detail::physics_inputs(m.physics()));
    if (out.empty()) out = {"y1"};
    detail::write_common(j, m.ts(), in, out, i2, &report);
    if (!info.initial_condition && !report.estimated) j["initial_condition"] = "estimate";
    Json s = Json::object();
    s["physics"] = detail::physics_name_of(m.physics());
    s["baseline_parameters"] = detail::parameter_table_json(m.baseline_parameters());
    Json::Array effects;
    for (const Effect& e : m.effects()) {
      Json x = Json::object();
      x["effect"] = e.name();
      x["variant"] = e.variant;
      x["width"] = e.width;
      x["speed"] = e.speed;
      x["parameters"] = detail::parameter_table_json(e.params);
      effects.push_back(std::move(x));
    }
    s["effects"] = Json(std::move(effects));
    s["integrator"] = detail::integrator_json(m.integrator());
    j["structure"] = std::move(s);
    std::vector<std::string> names;
    for (const auto& q : m.parameter_info()) names.push_back(q.name);
    j["parameters"] = detail::parameters_json(names, m.parameters());
    j["report"] = report_to_json(report);
  }
  /// Rebuilds the model (baseline by catalogue name for `AnyPhysics`).
  static AugmentedModel<P> load(const JsonView& file, ModelFileInfo& info)
    requires std::is_same_v<P, AnyPhysics> || std::default_initializable<P>
  {
    detail::expect_kind(file, kind);
    std::vector<std::string> in, out;
    const double ts = detail::read_common(file, info, in, out);
    const JsonView s = file.at("structure");
    s.check_keys({"physics", "baseline_parameters", "effects", "integrator"});
    const std::string name = s.at("physics").as_string();
    P phys = make(name, s.at("physics"));
    std::vector<ParameterInfo> base = detail::parameter_table_from_json(s.at("baseline_parameters"));
    AugmentedModel<P> m = detail::located(s, [&] { return AugmentedModel<P>(std::move(phys), base, ts); });
    const JsonView effects = s.at("effects");
    for (std::size_t i = 0; i < effects.as_array().size(); ++i) {
      const JsonView x = effects.at(i);
      x.check_keys({"effect", "variant", "width", "speed", "parameters"});
      Effect e;
      e.kind = detail::located(x.at("effect"), [&] { return effect_kind(x.at("effect").as_string()); });
      e.variant = x.at("variant").as_string();
      e.width = x.at("width").as_number();
      e.speed = x.at("speed").as_number();
      e.params = detail::parameter_table_from_json(x.at("parameters"));
      detail::located(x, [&] {
        m.add_effect(std::move(e));
        return 0;
      });
    }
    detail::located(s.at("integrator"), [&] {
      m.set_integrator(detail::integrator_from_json(s.at("integrator")));
      return 0;
    });
    const Eigen::VectorXd th = detail::read_parameters(file, m.num_parameters());
    detail::located(file.at("parameters"), [&] {
      m.set_parameters(th);
      return 0;
    });
    m.set_units(info.output_units.empty() ? std::string() : info.output_units[0],
                info.input_units.empty() ? std::string() : info.input_units[0]);
    detail::expect_channel_count(file.at("inputs"), in.size(), detail::physics_inputs(m.physics()), "inputs");
    detail::expect_channel_count(file.at("outputs"), out.size(), 1, "outputs");
    m.set_channel_names(in, out);
    info.report = report_from_json(file.at("report"));
    return m;
  }

 private:
  static P make(const std::string& name, const JsonView& where) {
    if constexpr (std::is_same_v<P, AnyPhysics>) {
      return detail::located(where, [&] { return make_physics(name); });
    } else {
      P p{};
      if (detail::physics_name_of(p) != name) {
        where.fail("the file's baseline physics is \"" + name + "\", this model's is \"" + detail::physics_name_of(p) +
                   "\"");
      }
      return p;
    }
  }
};

namespace detail {
/// Registers "augmented_greybox" with `load_model(path)` once per program (when this header is
/// included anywhere).
inline const bool augmented_kind_registered = [] {
  register_model_kind("augmented_greybox", [](const JsonView& file, ModelFileInfo& info) {
    AugmentedModel<AnyPhysics> m = ModelSerial<AugmentedModel<AnyPhysics>>::load(file, info);
    return AnyModel(std::move(m), info);
  });
  return true;
}();
}  // namespace detail

}  // namespace nlid
