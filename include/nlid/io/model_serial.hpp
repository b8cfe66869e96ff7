#pragma once
/// @file
/// Models in model files: `ModelSerial<M>` for nonlinear ARX, Hammerstein–Wiener, grey-box and
/// the linear ARX / output-error / state-space models (the file envelope is in model_file.hpp).
///
/// Every model writes the same top-level members (docs/model_files.md):
///
///     "kind"              "nlarx" | "hammerstein_wiener" | "greybox" | "arx" | "output_error" | "state_space"
///     "ts"                sample time in seconds (0: not set)
///     "inputs", "outputs" [{"name": "u1", "unit": "V"}, …]
///     "initial_condition" the policy a simulation of this model should start from by default
///     "structure"         kind-specific: regressors + nonlinearity, blocks, physics, polynomials
///     "parameters"        {"names": [...], "values": [...]} — θ, exact
///     "report"            what the estimation did (fit, iterations, cost, status, time)
///     "data_range"        optional: [min, max] of each input and output in the estimation data
///
/// `ModelSerial<M>`: `kind`; `save(j, model, info)` fills those members; `load(j, info)` builds an
/// M from a file (for the types whose structure can be rebuilt from text); `restore(j, model,
/// info)` checks that a prototype has the file's structure and copies the rest into it (for
/// models holding C++ lambdas, e.g. custom regressors or user physics).

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/core/initial_condition.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/estimation/uncertainty.hpp"
#include "nlid/io/json.hpp"
#include "nlid/io/json_eigen.hpp"
#include "nlid/io/nonlinearity_serial.hpp"
#include "nlid/io/regressor_serial.hpp"
#include "nlid/io/serial_common.hpp"
#include "nlid/linear/arx.hpp"
#include "nlid/linear/output_error.hpp"
#include "nlid/linear/state_space.hpp"
#include "nlid/models/greybox.hpp"
#include "nlid/models/greybox_dynamic.hpp"
#include "nlid/models/greybox_estimate.hpp"
#include "nlid/models/hammerstein_wiener.hpp"
#include "nlid/models/nlarx.hpp"
#include "nlid/models/transfer_function_block.hpp"

namespace nlid {

/// What a model file holds besides the model object itself: channel units, the default
/// initial-condition policy, a description, the creation time, and (for models that do not keep
/// one, e.g. grey-box) the estimation report.
/// [lower, upper] of one channel in the data a model was estimated on.
struct ChannelRange {
  double lower = 0.0;  ///< smallest value in the estimation data
  double upper = 0.0;  ///< largest value in the estimation data
  /// True if `v` lies in [lower, upper].
  [[nodiscard]] bool contains(double v) const { return v >= lower && v <= upper; }
};

struct ModelFileInfo {
  std::vector<std::string> input_units;   ///< one per input, or empty
  std::vector<std::string> output_units;  ///< one per output, or empty
  /// Policy a simulation should start from by default; empty: the estimation's, else zero.
  std::optional<InitialCondition> initial_condition;
  std::string description;                ///< free text (e.g. "nlarx5 of the throttle study")
  std::string created;                    ///< ISO 8601 UTC time; filled by save when empty
  std::optional<EstimationReport> report;  ///< report of a model that holds none itself
  /// Range of each input / output in the estimation data (empty: not recorded): where the model
  /// was fitted. Outside it a nonlinear model extrapolates (a sigmoid network continues its
  /// linear term, a piecewise-linear map its end segments); nlid-codegen refuses an equilibrium
  /// start there. Filled by `record_data_range` (nlid-fit and nlid-diagnose --save do).
  std::vector<ChannelRange> input_range, output_range;
  /// Uncertainty of the parameters from the estimation, for the models that keep none
  /// themselves (nonlinear ARX, Hammerstein–Wiener; a grey box keeps its own,
  /// `GreyBox::parameter_covariance`, and this member is neither saved nor loaded for it). Saved
  /// as the top-level "uncertainty": {"stddev", "covariance"} of the model's parameters (an
  /// uncertainty with estimated initial states appended keeps only the parameters' block); saving
  /// throws if it belongs to other parameter names or values. Loading fills it from that member
  /// (`uncertainty_from_covariance`), ready for `simulation_band(model, data, *info.uncertainty)`.
  /// `fit_model_spec` (nlid-fit) sets it when it computes the uncertainty.
  std::optional<ParameterUncertainty> uncertainty;
  /// Why loading left out the uncertainty the file carries, else empty: a covariance records the
  /// parameter values it was computed at ("at"), and a file whose parameters were changed since
  /// (edited by hand) no longer matches them — its covariance describes another estimate, and a
  /// simulation band from it would be wrong. Names the first changed parameter and both values.
  std::string uncertainty_left_out;
};

/// Records the range of every input and output of `data` (all experiments) in `info`, over the
/// finite values; records nothing if a channel has none (a file never holds a non-finite range).
inline void record_data_range(ModelFileInfo& info, const Dataset& data) {
  info.input_range.clear();
  info.output_range.clear();
  std::vector<ChannelRange> in, out;
  std::vector<bool> seen_in, seen_out;
  auto widen = [](std::vector<ChannelRange>& r, std::vector<bool>& seen, const Eigen::MatrixXd& v) {
    if (r.size() < static_cast<std::size_t>(v.cols())) {
      r.resize(static_cast<std::size_t>(v.cols()));
      seen.resize(static_cast<std::size_t>(v.cols()), false);
    }
    for (Eigen::Index c = 0; c < v.cols(); ++c) {
      auto& rc = r[static_cast<std::size_t>(c)];
      for (Eigen::Index i = 0; i < v.rows(); ++i) {
        const double x = v(i, c);
        if (!std::isfinite(x)) continue;
        if (!seen[static_cast<std::size_t>(c)]) {
          rc = {x, x};
          seen[static_cast<std::size_t>(c)] = true;
        }
        rc.lower = std::min(rc.lower, x);
        rc.upper = std::max(rc.upper, x);
      }
    }
  };
  for (const Experiment& e : data) {
    widen(in, seen_in, e.u());
    widen(out, seen_out, e.y());
  }
  for (bool s : seen_in)
    if (!s) return;
  for (bool s : seen_out)
    if (!s) return;
  info.input_range = std::move(in);
  info.output_range = std::move(out);
}

/// The estimation report of a grey-box estimation, in the common form kept in model files.
[[nodiscard]] inline EstimationReport estimation_report(const GreyBoxEstimate& g) {
  EstimationReport r;
  r.estimated = true;
  r.focus = "simulation";
  r.initial_condition = "estimate";
  r.iterations = g.summary.iterations;
  r.initial_cost = g.summary.initial_cost;
  r.final_cost = g.cost;
  r.seconds = g.seconds;
  r.status = g.summary.message();
  r.data_names = g.experiment_names;
  for (Eigen::Index e = 0; e < g.fit.rows(); ++e) r.fit_percent.push_back(g.fit.cols() > 0 ? g.fit(e, 0) : 0.0);
  r.initial_states = g.initial_states;
  return r;
}

/// Serialiser of model type M (see the file comment).
template <class M>
struct ModelSerial;

/// A model type that can be saved. Satisfied by Nlarx and HammersteinWiener of savable
/// components, GreyBox, Arx, OutputError and StateSpace.
template <class M>
concept SavableModel = requires(const M& m, Json& j, const ModelFileInfo& info) {
  { ModelSerial<M>::kind } -> std::convertible_to<std::string>;
  ModelSerial<M>::save(j, m, info);
};

/// A model type that can be rebuilt from a file alone (no lambdas in its structure).
template <class M>
concept LoadableModel = SavableModel<M> && requires(const JsonView& v, ModelFileInfo& info) {
  { ModelSerial<M>::load(v, info) } -> std::same_as<M>;
};

/// A model type whose prototype can take the state a file holds.
template <class M>
concept RestorableModel = SavableModel<M> && requires(const JsonView& v, M& m, ModelFileInfo& info) {
  ModelSerial<M>::restore(v, m, info);
};

namespace detail {

inline Json channel_list(const std::vector<std::string>& names, const std::vector<std::string>& units) {
  Json::Array a;
  for (std::size_t i = 0; i < names.size(); ++i) {
    a.push_back(Json::object({{"name", names[i]}, {"unit", i < units.size() ? units[i] : std::string()}}));
  }
  return Json(std::move(a));
}

/// Reads "inputs"/"outputs": names, and units into `units`.
inline std::vector<std::string> read_channels(const JsonView& v, std::vector<std::string>& units) {
  std::vector<std::string> names;
  units.clear();
  for (std::size_t i = 0; i < v.as_array().size(); ++i) {
    const JsonView c = v.at(i);
    c.check_keys({"name", "unit"});
    names.push_back(c.at("name").as_string());
    units.push_back(c.value_or<std::string>("unit", ""));
  }
  bool any = false;
  for (const auto& u : units) any = any || !u.empty();
  if (!any) units.clear();
  return names;
}

inline Json parameters_json(const std::vector<std::string>& names, const Eigen::VectorXd& values) {
  Json j = Json::object();
  j["names"] = string_list(names);
  j["values"] = values;
  return j;
}

/// θ of `n` values from "parameters"; checks the count.
inline Eigen::VectorXd read_parameters(const JsonView& file, int n, bool with_stddev = false) {
  const JsonView p = file.at("parameters");
  if (with_stddev) {
    p.check_keys({"names", "values", "stddev", "covariance", "covariance_at"});
  } else {
    p.check_keys({"names", "values"});
  }
  const Eigen::VectorXd th = read_vector(p.at("values"));
  if (th.size() != n) {
    p.at("values").fail("the file has " + std::to_string(th.size()) + " parameter values at " +
                        p.at("values").path_text() + ", the model structure has " + std::to_string(n));
  }
  if (!th.allFinite()) p.at("values").fail("non-finite parameter value at " + p.at("values").path_text());
  return th;
}

/// Writes "parameters": "stddev" and "covariance" (n × n rows), and "covariance_at": the values
/// they belong to (θ, so that a reader can tell a hand-edited θ); nothing if `covariance` is empty.
inline void write_parameter_covariance(Json& j, const Eigen::VectorXd& stddev, const Eigen::MatrixXd& covariance,
                                       const Eigen::VectorXd& values) {
  if (stddev.size() > 0) j["parameters"]["stddev"] = extended_vector(stddev);
  if (covariance.size() == 0) return;
  j["parameters"]["covariance_at"] = extended_vector(values);
  Json::Array rows;
  for (Eigen::Index i = 0; i < covariance.rows(); ++i) rows.push_back(extended_vector(Eigen::VectorXd(covariance.row(i).transpose())));
  j["parameters"]["covariance"] = Json(std::move(rows));
}

/// Writes `info.uncertainty` for a model whose parameters are `names` = `values` as the top-level
/// member "uncertainty": {"stddev", "covariance"} of the model's block (a top-level member, so
/// readers that predate it ignore it). Throws naming the parameter if the uncertainty belongs to
/// another model or to other values (a covariance from before `set_parameters` describes a
/// different estimate), and as `uncertainty_from_covariance` for a block a reader would refuse.
inline void write_info_uncertainty(Json& j, const ModelFileInfo& info, const std::vector<std::string>& names,
                                   const Eigen::VectorXd& values) {
  if (!info.uncertainty) return;
  const ParameterUncertainty& u = *info.uncertainty;
  const Eigen::Index n = values.size();
  require(u.theta.size() >= n && u.covariance.rows() == u.theta.size() && u.covariance.cols() == u.theta.size(),
          "model file: the uncertainty to save covers " + std::to_string(u.theta.size()) + " unknowns with a " +
              std::to_string(u.covariance.rows()) + "x" + std::to_string(u.covariance.cols()) +
              " covariance; the model has " + std::to_string(n) + " parameters",
          at_parameter("uncertainty"));
  require(u.stddev.size() == 0 || u.stddev.size() == u.theta.size(),
          "model file: the uncertainty to save has " + std::to_string(u.stddev.size()) + " standard deviations for " +
              std::to_string(u.theta.size()) + " unknowns",
          at_parameter("uncertainty"));
  auto number = [](double v) { return detail::format_g(v, 17); };
  for (Eigen::Index i = 0; i < n; ++i) {
    const auto iu = static_cast<std::size_t>(i);
    const std::string& name = names[iu];
    if (iu < u.names.size() && u.names[iu] != name) {
      throw Error("model file: parameter " + std::to_string(i) + " is '" + name + "' in the model but '" + u.names[iu] +
                      "' in the uncertainty to save (another model's?)",
                  at_parameter(name));
    }
    const double a = values[i], b = u.theta[i];
    require(std::abs(a - b) <= 1e-12 * std::max({1.0, std::abs(a), std::abs(b)}),
            "model file: the uncertainty to save was computed at " + name + " = " + number(b) + ", the model has " +
                number(a) + " (recompute it for the changed model, or reset ModelFileInfo::uncertainty)",
            at_parameter(name));
  }
  // What a reader would refuse is refused here, before a file is written.
  const Eigen::VectorXd sd = u.stddev.size() > 0 ? Eigen::VectorXd(u.stddev.head(n)) : Eigen::VectorXd();
  const Eigen::MatrixXd c = u.covariance.topLeftCorner(n, n);
  try {
    (void)uncertainty_from_covariance(names, values, c, sd);
  } catch (const Error& e) {
    throw Error("model file: the uncertainty to save: " + e.message(), e.where());
  }
  Json block = Json::object();
  if (sd.size() > 0) block["stddev"] = extended_vector(sd);
  Json::Array rows;
  for (Eigen::Index i = 0; i < n; ++i) rows.push_back(extended_vector(Eigen::VectorXd(c.row(i).transpose())));
  block["covariance"] = Json(std::move(rows));
  block["at"] = extended_vector(values);
  j["uncertainty"] = std::move(block);
}

/// Empty if the covariance recorded at `at` (the values written beside it) still belongs to the
/// file's parameters `values`; else the first parameter that changed, with both values. (Files
/// written before "at" existed carry none and are taken as they are.) The sizes must agree:
/// a wrong count is a malformed file, reported naming the key path.
inline std::string uncertainty_mismatch(const JsonView& at, const std::vector<std::string>& names,
                                        const Eigen::VectorXd& values) {
  const Eigen::VectorXd a = read_extended_vector(at);
  if (a.size() != values.size()) {
    at.fail("the file has " + std::to_string(a.size()) + " values at " + at.path_text() + ", the model has " +
            std::to_string(values.size()) + " parameters");
  }
  // The values are written with 17 digits and read back exactly; a tolerance still lets a file
  // pass through a tool that rounds in the last place.
  for (Eigen::Index i = 0; i < values.size(); ++i) {
    const double x = values[i], y = a[i];
    if (std::abs(x - y) <= 1e-12 * std::max({1.0, std::abs(x), std::abs(y)})) continue;
    return "its covariance was computed at " + names[static_cast<std::size_t>(i)] + " = " + detail::format_g(y, 17) +
           ", the file's parameters have " + detail::format_g(x, 17) +
           " (changed after the estimation): it describes another estimate";
  }
  return {};
}

/// An n × n parameter covariance written as n rows (grey boxes' "parameters.covariance", the
/// others' "uncertainty.covariance"); errors name the row and its key path.
inline Eigen::MatrixXd read_covariance_rows(const JsonView& cv, Eigen::Index n) {
  if (cv.type() != Json::Type::array || static_cast<Eigen::Index>(cv.size()) != n) {
    cv.fail("the parameter covariance at " + cv.path_text() + " must be an array of " + std::to_string(n) +
            " rows (one per parameter)");
  }
  Eigen::MatrixXd c(n, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const JsonView row = cv.at(static_cast<std::size_t>(i));
    const Eigen::VectorXd v = read_extended_vector(row);
    if (v.size() != n) {
      row.fail("row " + std::to_string(i) + " of the parameter covariance at " + row.path_text() + " has " +
               std::to_string(v.size()) + " entries, the model has " + std::to_string(n) + " parameters");
    }
    c.row(i) = v.transpose();
  }
  return c;
}

/// The top-level "uncertainty" a file keeps for a model whose parameters are `names` = `values`
/// (nullopt without it). Errors name the key path of the offending entry or row.
/// A file whose parameters changed after the covariance was computed (see
/// `uncertainty_mismatch`) gives nullopt and the reason in `left_out`.
inline std::optional<ParameterUncertainty> read_info_uncertainty(const JsonView& file, const std::vector<std::string>& names,
                                                                 const Eigen::VectorXd& values, std::string& left_out) {
  left_out.clear();
  if (!file.contains("uncertainty")) return std::nullopt;
  const JsonView block = file.at("uncertainty");
  block.check_keys({"stddev", "covariance", "at"});
  if (block.contains("at")) {
    left_out = uncertainty_mismatch(block.at("at"), names, values);
    if (!left_out.empty()) return std::nullopt;
  }
  const Eigen::Index n = values.size();
  Eigen::VectorXd sd;
  if (block.contains("stddev")) {
    const JsonView v = block.at("stddev");
    sd = read_extended_vector(v);
    if (sd.size() != n) {
      v.fail("the file has " + std::to_string(sd.size()) + " standard deviations at " + v.path_text() + ", the model has " +
             std::to_string(n) + " parameters");
    }
    for (Eigen::Index i = 0; i < n; ++i) {
      if (!(sd[i] >= 0.0)) {
        v.at(static_cast<std::size_t>(i)).fail("the standard deviation of " + names[static_cast<std::size_t>(i)] +
                                               " at " + v.at(static_cast<std::size_t>(i)).path_text() +
                                               " must be >= 0 (or inf)");
      }
    }
  }
  const JsonView cv = block.at("covariance");
  Eigen::MatrixXd c = read_covariance_rows(cv, n);
  try {
    return uncertainty_from_covariance(names, values, std::move(c), std::move(sd));
  } catch (const Error& e) {
    // The deviations are checked above: what is left is about a row of the covariance.
    for (std::size_t i = 0; i < names.size(); ++i) {
      if (e.where().parameter == names[i]) cv.at(i).fail(e.message() + " (at " + cv.at(i).path_text() + ")");
    }
    cv.fail(e.message() + " (at " + cv.path_text() + ")");
  }
}

inline void write_common(Json& j, double ts, const std::vector<std::string>& in, const std::vector<std::string>& out,
                         const ModelFileInfo& info, const EstimationReport* report) {
  j["ts"] = ts;
  j["inputs"] = channel_list(in, info.input_units);
  j["outputs"] = channel_list(out, info.output_units);
  InitialCondition ic = InitialCondition::zero;
  if (info.initial_condition) {
    ic = *info.initial_condition;
  } else if (report != nullptr && report->estimated) {
    for (InitialCondition c : {InitialCondition::zero, InitialCondition::estimate, InitialCondition::equilibrium,
                               InitialCondition::measured})
      if (report->initial_condition == to_string(c)) ic = c;
  }
  j["initial_condition"] = to_string(ic);
  if (!info.input_range.empty() || !info.output_range.empty()) {
    auto ranges = [](const std::vector<ChannelRange>& r) {
      Json::Array a;
      for (const ChannelRange& c : r) a.push_back(Json::array({c.lower, c.upper}));
      return Json(std::move(a));
    };
    j["data_range"] = Json::object({{"inputs", ranges(info.input_range)}, {"outputs", ranges(info.output_range)}});
  }
}

/// Reads the optional "data_range" member (a top-level annotation: older readers ignore it).
inline void read_data_range(const JsonView& file, ModelFileInfo& info) {
  info.input_range.clear();
  info.output_range.clear();
  if (!file.contains("data_range")) return;
  const JsonView d = file.at("data_range");
  d.check_keys({"inputs", "outputs"});
  auto read = [&](const char* key, std::vector<ChannelRange>& r) {
    if (!d.contains(key)) return;
    const JsonView list = d.at(key);
    for (std::size_t i = 0; i < list.as_array().size(); ++i) {
      const JsonView item = list.at(i);
      const Eigen::VectorXd v = read_vector(item, 2);
      if (!v.allFinite() || !(v(0) <= v(1)))
        item.fail("a data range at " + item.path_text() + " must be [lower, upper] with finite lower <= upper");
      r.push_back({v(0), v(1)});
    }
  };
  read("inputs", info.input_range);
  read("outputs", info.output_range);
}

/// Reads the common members into `info`; returns ts and the channel names.
inline double read_common(const JsonView& file, ModelFileInfo& info, std::vector<std::string>& in,
                          std::vector<std::string>& out) {
  const double ts = file.at("ts").as_number();
  if (!(ts >= 0) || !std::isfinite(ts)) file.at("ts").fail("sample time at ts must be >= 0 and finite");
  in = read_channels(file.at("inputs"), info.input_units);
  out = read_channels(file.at("outputs"), info.output_units);
  info.initial_condition = read_initial_condition(file.at("initial_condition"));
  read_data_range(file, info);
  // One range per channel or none: an extra range would describe an input the model does not
  // have (and nlid-codegen would emit its macros), a missing one would leave a channel unchecked.
  const auto check_count = [&](const char* key, std::size_t ranges, std::size_t channels, const char* what) {
    if (ranges == 0 || ranges == channels) return;
    const JsonView list = file.at("data_range").at(key);
    list.fail("data range at " + list.path_text() + " has " + std::to_string(ranges) + " entries, the model has " +
              std::to_string(channels) + " " + what);
  };
  check_count("inputs", info.input_range.size(), in.size(), "inputs");
  check_count("outputs", info.output_range.size(), out.size(), "outputs");
  return ts;
}

inline void expect_kind(const JsonView& file, const char* kind) {
  const std::string& k = file.at("kind").as_string();
  if (k != kind) file.at("kind").fail("the file holds a \"" + k + "\" model, expected \"" + kind + "\"");
}

inline void expect_channel_count(const JsonView& v, std::size_t got, int want, const char* what) {
  if (static_cast<int>(got) != want) {
    v.fail(std::string("the file lists ") + std::to_string(got) + " " + what + " at " + v.path_text() +
           ", the model has " + std::to_string(want));
  }
}

}  // namespace detail

// ---- nonlinear ARX ----------------------------------------------------------------------------

/// Nlarx<R, F>: "structure": {"regressors": {blocks, names}, "nonlinearity": {...}}.
template <class R, class F>
struct ModelSerial<Nlarx<R, F>> {
  /// Kind name in the file.
  static constexpr const char* kind = "nlarx";
  /// Writes the model's members.
  static void save(Json& j, const Nlarx<R, F>& m, const ModelFileInfo& info)
    requires SavableRegressor<R> && SavableNonlinearity<F>
  {
    detail::write_common(j, m.ts(), m.input_names(), {m.output_name()}, info, &m.report());
    Json s = Json::object();
    s["regressors"] = regressors_to_json(m.regressors(), m.input_names(), m.output_name());
    s["nonlinearity"] = NonlinearitySerial<F>::save(m.nonlinearity());
    j["structure"] = std::move(s);
    j["parameters"] = detail::parameters_json(m.parameter_names(), m.parameters());
    detail::write_info_uncertainty(j, info, m.parameter_names(), m.parameters());
    j["report"] = report_to_json(m.report());
  }
  /// Builds the model from the file.
  static Nlarx<R, F> load(const JsonView& file, ModelFileInfo& info)
    requires LoadableRegressor<R> && LoadableNonlinearity<F>
  {
    detail::expect_kind(file, kind);
    std::vector<std::string> in, out;
    const double ts = detail::read_common(file, info, in, out);
    const JsonView s = file.at("structure");
    s.check_keys({"regressors", "nonlinearity"});
    const JsonView regs = s.at("regressors");
    regs.check_keys({"blocks", "names"});
    const JsonView blocks = regs.at("blocks");
    std::size_t next = 0;
    const std::string out_name = out.empty() ? std::string("y1") : out[0];
    R r = RegressorSerial<R>::load(blocks, next, in, out_name);
    if (next != blocks.as_array().size()) {
      blocks.at(next).fail("regressor block " + blocks.at(next).path_text() + " is not used by this model type");
    }
    F f = NonlinearitySerial<F>::load(s.at("nonlinearity"));
    if (f.input_dimension() != r.size()) {
      s.at("nonlinearity").fail("the nonlinearity at " + s.at("nonlinearity").path_text() + " takes " +
                                std::to_string(f.input_dimension()) + " inputs but there are " +
                                std::to_string(r.size()) + " regressors");
    }
    Nlarx<R, F> m(std::move(r), std::move(f), ts);
    finish(file, m, in, out, info);
    return m;
  }
  /// Fills a prototype whose regressors (by getreg names) and nonlinearity match the file.
  static void restore(const JsonView& file, Nlarx<R, F>& m, ModelFileInfo& info)
    requires SavableRegressor<R> && SavableNonlinearity<F>
  {
    detail::expect_kind(file, kind);
    std::vector<std::string> in, out;
    const double ts = detail::read_common(file, info, in, out);
    const JsonView s = file.at("structure");
    s.check_keys({"regressors", "nonlinearity"});
    check_regressor_names(s.at("regressors"), m.regressors(), in, out.empty() ? std::string("y1") : out[0]);
    NonlinearitySerial<F>::restore(s.at("nonlinearity"), m.nonlinearity());
    m.set_ts(ts);
    finish(file, m, in, out, info);
  }

 private:
  static void finish(const JsonView& file, Nlarx<R, F>& m, const std::vector<std::string>& in,
                     const std::vector<std::string>& out, ModelFileInfo& info) {
    detail::expect_channel_count(file.at("outputs"), out.size(), 1, "outputs");
    if (static_cast<int>(in.size()) < m.num_inputs()) {
      detail::expect_channel_count(file.at("inputs"), in.size(), m.num_inputs(), "inputs");
    }
    m.set_channel_names(in, out[0]);
    m.set_parameters(detail::read_parameters(file, m.num_parameters()));
    info.uncertainty = detail::read_info_uncertainty(file, m.parameter_names(), m.parameters(), info.uncertainty_left_out);
    m.set_report(report_from_json(file.at("report")));
    info.report.reset();
  }
};

// ---- Hammerstein–Wiener -----------------------------------------------------------------------

/// The linear block: {"nb", "nf", "nk"}.
template <int Nb, int Nf, int Nk>
struct LinearBlockSerial {
  /// Writes the orders.
  static Json save(const TransferFunctionBlock<Nb, Nf, Nk>& l) {
    return Json::object({{"type", "transfer_function"}, {"nb", l.nb()}, {"nf", l.nf()}, {"nk", l.nk()}});
  }
  /// Builds the block (orders must fit the compile-time ones).
  static TransferFunctionBlock<Nb, Nf, Nk> load(const JsonView& v) {
    v.check_keys({"type", "nb", "nf", "nk"});
    if (v.at("type").as_string() != "transfer_function") {
      v.at("type").fail("unknown linear block \"" + v.at("type").as_string() + "\" at " + v.at("type").path_text() +
                        " (accepted: transfer_function)");
    }
    try {
      return TransferFunctionBlock<Nb, Nf, Nk>(read_int(v.at("nb"), 1, 100000), read_int(v.at("nf"), 0, 100000),
                                               read_int(v.at("nk"), 0, 100000));
    } catch (const Error& e) {
      if (e.where().file.empty()) v.fail(e.message() + " (at " + v.path_text() + ")");
      throw;
    }
  }
};

/// HammersteinWiener<In, TransferFunctionBlock, Out>: "structure": {"input_nonlinearity",
/// "linear": {"type": "transfer_function", "nb", "nf", "nk"}, "output_nonlinearity"}.
template <class In, int Nb, int Nf, int Nk, class Out>
struct ModelSerial<HammersteinWiener<In, TransferFunctionBlock<Nb, Nf, Nk>, Out>> {
  /// The model type.
  using M = HammersteinWiener<In, TransferFunctionBlock<Nb, Nf, Nk>, Out>;
  /// Kind name in the file.
  static constexpr const char* kind = "hammerstein_wiener";
  /// Writes the model's members.
  static void save(Json& j, const M& m, const ModelFileInfo& info)
    requires SavableNonlinearity<In> && SavableNonlinearity<Out>
  {
    detail::write_common(j, m.ts(), {m.input_name()}, {m.output_name()}, info, &m.report());
    Json s = Json::object();
    s["input_nonlinearity"] = NonlinearitySerial<In>::save(m.input_nonlinearity());
    s["linear"] = LinearBlockSerial<Nb, Nf, Nk>::save(m.linear_block());
    s["output_nonlinearity"] = NonlinearitySerial<Out>::save(m.output_nonlinearity());
    j["structure"] = std::move(s);
    j["parameters"] = detail::parameters_json(m.parameter_names(), m.parameters());
    detail::write_info_uncertainty(j, info, m.parameter_names(), m.parameters());
    j["report"] = report_to_json(m.report());
  }
  /// Builds the model from the file.
  static M load(const JsonView& file, ModelFileInfo& info)
    requires LoadableNonlinearity<In> && LoadableNonlinearity<Out>
  {
    detail::expect_kind(file, kind);
    std::vector<std::string> in, out;
    const double ts = detail::read_common(file, info, in, out);
    const JsonView s = file.at("structure");
    s.check_keys({"input_nonlinearity", "linear", "output_nonlinearity"});
    In f = NonlinearitySerial<In>::load(s.at("input_nonlinearity"));
    auto l = LinearBlockSerial<Nb, Nf, Nk>::load(s.at("linear"));
    Out h = NonlinearitySerial<Out>::load(s.at("output_nonlinearity"));
    if (f.input_dimension() != 1) s.at("input_nonlinearity").fail("the input nonlinearity at " + s.at("input_nonlinearity").path_text() + " must have one input");
    if (h.input_dimension() != 1) s.at("output_nonlinearity").fail("the output nonlinearity at " + s.at("output_nonlinearity").path_text() + " must have one input");
    M m(std::move(f), std::move(l), std::move(h), ts);
    finish(file, m, in, out, info);
    return m;
  }
  /// Fills a prototype of the file's structure.
  static void restore(const JsonView& file, M& m, ModelFileInfo& info)
    requires SavableNonlinearity<In> && SavableNonlinearity<Out>
  {
    detail::expect_kind(file, kind);
    std::vector<std::string> in, out;
    const double ts = detail::read_common(file, info, in, out);
    const JsonView s = file.at("structure");
    s.check_keys({"input_nonlinearity", "linear", "output_nonlinearity"});
    NonlinearitySerial<In>::restore(s.at("input_nonlinearity"), m.input_nonlinearity());
    const auto l = LinearBlockSerial<Dynamic, Dynamic, Dynamic>::load(s.at("linear"));
    if (l.nb() != m.linear_block().nb() || l.nf() != m.linear_block().nf() || l.nk() != m.linear_block().nk()) {
      s.at("linear").fail("the file's linear block [nb nf nk] = [" + std::to_string(l.nb()) + " " +
                          std::to_string(l.nf()) + " " + std::to_string(l.nk()) + "] at " +
                          s.at("linear").path_text() + " differs from this model's");
    }
    NonlinearitySerial<Out>::restore(s.at("output_nonlinearity"), m.output_nonlinearity());
    m.set_ts(ts);
    finish(file, m, in, out, info);
  }

 private:
  static void finish(const JsonView& file, M& m, const std::vector<std::string>& in,
                     const std::vector<std::string>& out, ModelFileInfo& info) {
    detail::expect_channel_count(file.at("inputs"), in.size(), 1, "inputs");
    detail::expect_channel_count(file.at("outputs"), out.size(), 1, "outputs");
    m.set_channel_names(in[0], out[0]);
    m.set_parameters(detail::read_parameters(file, m.num_parameters()));
    info.uncertainty = detail::read_info_uncertainty(file, m.parameter_names(), m.parameters(), info.uncertainty_left_out);
    m.set_report(report_from_json(file.at("report")));
    info.report.reset();
  }
};

// ---- grey box ---------------------------------------------------------------------------------

namespace detail {

inline const char* integrator_name(IntegratorMethod m) {
  switch (m) {
    case IntegratorMethod::euler: return "euler";
    case IntegratorMethod::rk4: return "rk4";
    case IntegratorMethod::dormand_prince: return "dormand_prince";
  }
  return "rk4";
}

inline Json integrator_json(const IntegratorOptions& o) {
  Json j = Json::object();
  j["method"] = integrator_name(o.method);
  j["substeps"] = o.substeps;
  j["min_substeps"] = o.min_substeps;
  j["max_substeps"] = o.max_substeps;
  j["stability_target"] = o.stability_target;
  j["relative_tolerance"] = o.relative_tolerance;
  j["absolute_tolerance"] = o.absolute_tolerance;
  j["max_adaptive_steps"] = o.max_adaptive_steps;
  return j;
}

inline IntegratorOptions integrator_from_json(const JsonView& v) {
  v.check_keys({"method", "substeps", "min_substeps", "max_substeps", "stability_target", "relative_tolerance",
                "absolute_tolerance", "max_adaptive_steps"});
  IntegratorOptions o;
  const std::string& m = v.at("method").as_string();
  if (m == "euler") o.method = IntegratorMethod::euler;
  else if (m == "rk4") o.method = IntegratorMethod::rk4;
  else if (m == "dormand_prince") o.method = IntegratorMethod::dormand_prince;
  else v.at("method").fail("unknown integrator \"" + m + "\" at " + v.at("method").path_text() + " (accepted: euler, rk4, dormand_prince)");
  // Bounded as `validate` bounds them (integrators.hpp): a file cannot ask for hours per sample.
  o.substeps = read_int(v.at("substeps"), 0, max_integrator_substeps);
  o.min_substeps = read_int(v.at("min_substeps"), 0, max_integrator_substeps);
  o.max_substeps = read_int(v.at("max_substeps"), 0, max_integrator_substeps);
  o.stability_target = v.at("stability_target").as_number();
  o.relative_tolerance = v.at("relative_tolerance").as_number();
  o.absolute_tolerance = v.at("absolute_tolerance").as_number();
  o.max_adaptive_steps = read_int(v.at("max_adaptive_steps"), 0, max_adaptive_step_budget);
  return o;
}

template <class P>
GreyBox<P> make_greybox_for(const std::string& name, const JsonView& where) {
  if constexpr (std::is_same_v<P, AnyPhysics>) {
    try {
      return make_greybox(name);
    } catch (const Error& e) {
      where.fail(e.message() + " (physics at " + where.path_text() + ")");
    }
  } else {
    GreyBox<P> m;
    if (m.name() != name) {
      where.fail("the file's grey-box physics is \"" + name + "\" (at " + where.path_text() + "), this model's is \"" +
                 m.name() + "\"");
    }
    return m;
  }
}

}  // namespace detail

/// GreyBox<P>: "structure": {"physics": name, "parameter_table": [...], "integrator": {...},
/// "initial_state_window": n, "states": [...]}, "estimated_initial_states": [[...], ...].
template <class P>
struct ModelSerial<GreyBox<P>> {
  /// Kind name in the file.
  static constexpr const char* kind = "greybox";
  /// Writes the model's members.
  static void save(Json& j, const GreyBox<P>& m, const ModelFileInfo& info) {
    const EstimationReport report = info.report ? *info.report : EstimationReport{};
    detail::write_common(j, 0.0,
                         m.input_names().empty() ? default_input_names(m.input_dimension()) : m.input_names(),
                         m.output_names().empty() ? output_names(m.output_dimension()) : m.output_names(), info, &report);
    if (!info.initial_condition && !report.estimated) j["initial_condition"] = "estimate";
    Json s = Json::object();
    s["physics"] = m.name();
    Json::Array table;
    for (const ParameterInfo& q : m.parameter_info()) {
      Json p = Json::object();
      p["name"] = q.name;
      p["unit"] = q.unit;
      p["lower"] = extended_number(q.lower);
      p["upper"] = extended_number(q.upper);
      p["range_lower"] = extended_number(q.range_lower);
      p["range_upper"] = extended_number(q.range_upper);
      p["log_scale"] = q.log_scale;
      p["fixed"] = q.fixed;
      table.push_back(std::move(p));
    }
    s["parameter_table"] = Json(std::move(table));
    s["integrator"] = detail::integrator_json(m.integrator());
    s["initial_state_window"] = static_cast<long long>(m.initial_state_window());
    Json::Array states;
    for (const StateInfo& st : m.state_info()) states.emplace_back(st.name);
    s["states"] = Json(std::move(states));
    j["structure"] = std::move(s);
    j["parameters"] = detail::parameters_json(m.parameter_names(), Eigen::VectorXd(m.parameters()));
    detail::write_parameter_covariance(j, m.parameter_stddev(), m.parameter_covariance(), Eigen::VectorXd(m.parameters()));
    Json::Array x0;
    for (const auto& x : m.estimated_initial_states()) x0.push_back(extended_vector(x));
    j["estimated_initial_states"] = Json(std::move(x0));
    j["report"] = report_to_json(report);
  }
  /// Builds the model (catalogue physics by name for `GreyBox<AnyPhysics>`).
  static GreyBox<P> load(const JsonView& file, ModelFileInfo& info)
    requires std::is_same_v<P, AnyPhysics> || std::default_initializable<P>
  {
    detail::expect_kind(file, kind);
    const JsonView name = file.at("structure").at("physics");
    GreyBox<P> m = detail::make_greybox_for<P>(name.as_string(), name);
    restore(file, m, info);
    return m;
  }
  /// Fills a prototype of the same physics.
  static void restore(const JsonView& file, GreyBox<P>& m, ModelFileInfo& info) {
    detail::expect_kind(file, kind);
    std::vector<std::string> in, out;
    (void)detail::read_common(file, info, in, out);
    detail::expect_channel_count(file.at("inputs"), in.size(), m.input_dimension(), "inputs");
    detail::expect_channel_count(file.at("outputs"), out.size(), m.output_dimension(), "outputs");
    m.set_channel_names(in, out);
    const JsonView s = file.at("structure");
    s.check_keys({"physics", "parameter_table", "integrator", "initial_state_window", "states"});
    if (s.at("physics").as_string() != m.name()) {
      s.at("physics").fail("the file's grey-box physics is \"" + s.at("physics").as_string() + "\", this model's is \"" +
                           m.name() + "\"");
    }
    // The states are the physics', not the file's; a list that disagrees was edited or belongs
    // to another version of the physics, whose estimated initial states would be misread.
    if (s.contains("states")) {
      const JsonView xs = s.at("states");
      const auto& info_x = m.state_info();
      detail::expect_channel_count(xs, xs.as_array().size(), static_cast<int>(info_x.size()), "states");
      for (std::size_t i = 0; i < info_x.size(); ++i) {
        const JsonView x = xs.at(i);
        if (x.as_string() != info_x[i].name)
          x.fail("state " + std::to_string(i) + " is '" + x.as_string() + "' in the file (at " + x.path_text() +
                 ") but '" + info_x[i].name + "' in physics '" + m.name() + "'");
      }
    }
    const JsonView table = s.at("parameter_table");
    detail::expect_channel_count(table, table.as_array().size(), m.num_parameters(), "parameters");
    const Eigen::VectorXd values = detail::read_parameters(file, m.num_parameters(), true);
    const auto names = m.parameter_names();
    for (int i = 0; i < m.num_parameters(); ++i) {
      const JsonView q = table.at(static_cast<std::size_t>(i));
      q.check_keys({"name", "unit", "lower", "upper", "range_lower", "range_upper", "log_scale", "fixed"});
      const std::string& name = names[static_cast<std::size_t>(i)];
      if (q.at("name").as_string() != name) {
        q.at("name").fail("parameter " + std::to_string(i) + " is '" + q.at("name").as_string() + "' in the file (at " +
                          q.at("name").path_text() + ") but '" + name + "' in physics '" + m.name() + "'");
      }
      const double lo = read_extended_number(q.at("lower")), hi = read_extended_number(q.at("upper"));
      const double v = values(i);
      if (!(lo <= v && v <= hi)) {
        q.fail("value of '" + name + "', " + detail::format_g(v, 17) + ", lies outside its bounds [" +
               detail::format_g(lo, 17) + ", " + detail::format_g(hi, 17) + "] in the file (at " + q.path_text() + ")");
      }
      const double rl = read_extended_number(q.at("range_lower")), ru = read_extended_number(q.at("range_upper"));
      const bool log_scale = q.at("log_scale").as_bool(), fixed = q.at("fixed").as_bool();
      // The setters check what the file says (a range with lower > upper, a log range through
      // zero): their errors name the parameter, located here at its entry in the file.
      try {
        // Open the bounds, set the value, then close them: the old bounds need not contain it.
        const double inf = std::numeric_limits<double>::infinity();
        m.set_bounds(name, -inf, inf);
        m.set_parameter(name, v);
        m.set_bounds(name, lo, hi);
        if (std::isfinite(rl) && std::isfinite(ru)) m.set_range(name, rl, ru, log_scale);
        m.fix(name, fixed);
      } catch (const Error& e) {
        if (!e.where().file.empty()) throw;
        q.fail(e.message() + " (at " + q.path_text() + ")");
      }
    }
    // The values were set one by one (set_parameter checks each alone); the relations between
    // them (the throttle's lower_stop < upper_stop) are checked once all are in, so that a file
    // with crossed stops is refused here, naming the file, not at its first simulation.
    try {
      physics_check_parameters(m.physics(), values.data());
    } catch (const Error& e) {
      file.at("parameters").at("values").fail(e.message() + " (at " + file.at("parameters").at("values").path_text() + ")");
    }
    try {
      m.set_integrator(detail::integrator_from_json(s.at("integrator")));
    } catch (const Error& e) {
      if (e.where().file.empty()) s.at("integrator").fail(e.message() + " (at " + s.at("integrator").path_text() + ")");
      throw;
    }
    const JsonView window = s.at("initial_state_window");
    if (window.as_integer() < 0) {
      window.fail("initial-state window " + std::to_string(window.as_integer()) + " at " + window.path_text() +
                  " must be >= 0 (0 = whole record)");
    }
    m.set_initial_state_window(static_cast<Eigen::Index>(window.as_integer()));
    std::vector<Eigen::VectorXd> x0;
    const JsonView xs = file.at("estimated_initial_states");
    for (std::size_t i = 0; i < xs.as_array().size(); ++i) {
      x0.push_back(read_extended_vector(xs.at(i)));
      if (x0.back().size() != m.state_dimension()) {
        xs.at(i).fail("initial state at " + xs.at(i).path_text() + " has " + std::to_string(x0.back().size()) +
                      " entries, the model has " + std::to_string(m.state_dimension()) + " states");
      }
    }
    m.set_estimated_initial_states(std::move(x0));
    // A covariance computed at other values (θ edited by hand) is left out, with its deviations.
    info.uncertainty_left_out.clear();
    if (file.at("parameters").contains("covariance_at")) {
      info.uncertainty_left_out = detail::uncertainty_mismatch(file.at("parameters").at("covariance_at"),
                                                               m.parameter_names(), Eigen::VectorXd(m.parameters()));
    }
    // After the values: setting a value clears the deviations.
    if (info.uncertainty_left_out.empty() && file.at("parameters").contains("stddev")) {
      const JsonView sd = file.at("parameters").at("stddev");
      const Eigen::VectorXd v = read_extended_vector(sd);
      if (v.size() == 0) sd.fail("empty standard deviations at " + sd.path_text() + " (leave the key out instead)");
      try {
        m.set_parameter_stddev(v);
      } catch (const Error& e) {
        sd.fail(e.message() + " (at " + sd.path_text() + ")");
      }
    }
    if (info.uncertainty_left_out.empty() && file.at("parameters").contains("covariance")) {
      const JsonView cv = file.at("parameters").at("covariance");
      const Eigen::MatrixXd c = detail::read_covariance_rows(cv, m.num_parameters());
      try {
        m.set_parameter_covariance(c);
      } catch (const Error& e) {
        cv.fail(e.message() + " (at " + cv.path_text() + ")");
      }
    }
    m.set_units(info.output_units.empty() ? std::string() : info.output_units[0],
                info.input_units.empty() ? std::string() : info.input_units[0]);
    info.report = report_from_json(file.at("report"));
  }

 private:
  static std::vector<std::string> output_names(int n) {
    std::vector<std::string> s;
    for (int i = 0; i < n; ++i) s.push_back("y" + std::to_string(i + 1));
    return s;
  }
};

// ---- linear models ----------------------------------------------------------------------------

namespace detail {
inline Json vector_list(const std::vector<Eigen::VectorXd>& v) {
  Json::Array a;
  for (const auto& x : v) a.emplace_back(x);
  return Json(std::move(a));
}
inline std::vector<Eigen::VectorXd> read_vector_list(const JsonView& v) {
  std::vector<Eigen::VectorXd> out;
  for (std::size_t i = 0; i < v.as_array().size(); ++i) out.push_back(read_vector(v.at(i)));
  return out;
}
/// Linear models: "structure" holds the coefficients and "parameters" repeats them for readers
/// (and carries the standard deviations, "stddev"). A file whose two copies disagree has had one
/// edited and not the other; using either silently would be wrong, so it is refused, naming the
/// first differing value. Returns the standard deviations (empty when the file has none).
inline Eigen::VectorXd check_linear_parameters(const JsonView& file, const std::vector<std::string>& names,
                                               const Eigen::VectorXd& th) {
  if (!file.contains("parameters")) return {};
  const JsonView p = file.at("parameters");
  p.check_keys({"names", "values", "stddev"});
  const auto n = static_cast<Eigen::Index>(names.size());
  if (p.contains("names")) {
    const auto got = read_string_list(p.at("names"));
    if (got != names) {
      std::string want;
      for (const auto& s : names) want += (want.empty() ? "" : ", ") + s;
      p.at("names").fail("the parameter names at " + p.at("names").path_text() +
                         " do not match the structure's (" + want + ")");
    }
  }
  // Standard deviations may be +inf ("not identifiable", written as extended numbers).
  const auto check_count = [&](const JsonView& v, bool extended = false) {
    const Eigen::VectorXd x = extended ? read_extended_vector(v) : read_vector(v);
    if (x.size() != n) {
      v.fail("the file has " + std::to_string(x.size()) + " values at " + v.path_text() +
             ", the model structure has " + std::to_string(n) + " parameters");
    }
    return x;
  };
  if (p.contains("values")) {
    const Eigen::VectorXd v = check_count(p.at("values"));
    for (Eigen::Index i = 0; i < n; ++i) {
      if (!(v(i) == th(i))) {
        p.at("values").at(static_cast<std::size_t>(i))
            .fail("parameter " + names[static_cast<std::size_t>(i)] + " is " + Json(v(i)).dump() + " at " +
                  p.at("values").at(static_cast<std::size_t>(i)).path_text() + " but " + Json(th(i)).dump() +
                  " in \"structure\", which holds a linear model's coefficients: edit both, or drop \"parameters\"");
      }
    }
  }
  if (!p.contains("stddev")) return {};
  return check_count(p.at("stddev"), true);
}

}  // namespace detail

/// Arx: "structure": {"a": [a₁…], "b": [[b₁…], …], "nk": [...], "offset": c}.
template <>
struct ModelSerial<Arx> {
  /// Kind name in the file.
  static constexpr const char* kind = "arx";
  /// Writes the model's members.
  static void save(Json& j, const Arx& m, const ModelFileInfo& info) {
    detail::write_common(j, m.ts(), names(m), m.output_names().empty() ? std::vector<std::string>{"y1"} : m.output_names(),
                         info, nullptr);
    Json s = Json::object();
    s["a"] = m.a();
    std::vector<Eigen::VectorXd> b;
    std::vector<int> nk;
    for (int i = 0; i < m.num_inputs(); ++i) {
      b.push_back(m.b(i));
      nk.push_back(m.nk(i));
    }
    s["b"] = detail::vector_list(b);
    s["nk"] = Json(nk);
    s["offset"] = m.offset();
    j["structure"] = std::move(s);
    j["parameters"] = detail::parameters_json(m.parameter_names(), m.parameters());
    if ((m.parameter_stddev().array() != 0.0).any()) j["parameters"]["stddev"] = extended_vector(m.parameter_stddev());
    j["report"] = linear_report_to_json(m.report());
  }
  /// Builds the model.
  static Arx load(const JsonView& file, ModelFileInfo& info) {
    detail::expect_kind(file, kind);
    std::vector<std::string> in, out;
    const double ts = detail::read_common(file, info, in, out);
    const JsonView s = file.at("structure");
    s.check_keys({"a", "b", "nk", "offset"});
    Arx m = detail::located(s, [&] {
      return Arx(read_vector(s.at("a")), detail::read_vector_list(s.at("b")), s.at("nk").get<std::vector<int>>(), ts,
                 s.at("offset").as_number());
    });
    detail::expect_channel_count(file.at("inputs"), in.size(), m.num_inputs(), "inputs");
    detail::expect_channel_count(file.at("outputs"), out.size(), 1, "outputs");
    m.set_input_names(in);
    m.set_output_names(out);
    const Eigen::VectorXd sd = detail::check_linear_parameters(file, m.parameter_names(), m.parameters());
    if (sd.size() > 0) detail::located(file.at("parameters").at("stddev"), [&] {
      m.set_parameter_stddev(sd);
      return 0;
    });
    if (file.contains("report")) m.set_report(linear_report_from_json(file.at("report")));
    return m;
  }
  /// Replaces the prototype by the file's model.
  static void restore(const JsonView& file, Arx& m, ModelFileInfo& info) { m = load(file, info); }

 private:
  static std::vector<std::string> names(const Arx& m) {
    auto n = m.input_names();
    if (static_cast<int>(n.size()) != m.num_inputs()) n = default_input_names(m.num_inputs());
    return n;
  }
};

/// OutputError: "structure": {"b": [[...]], "f": [[...]], "nk": [...], "offset": c}.
template <>
struct ModelSerial<OutputError> {
  /// Kind name in the file.
  static constexpr const char* kind = "output_error";
  /// Writes the model's members.
  static void save(Json& j, const OutputError& m, const ModelFileInfo& info) {
    const auto in = m.input_names();
    detail::write_common(j, m.ts(), static_cast<int>(in.size()) == m.num_inputs() ? in : default_input_names(m.num_inputs()),
                         m.output_names().empty() ? std::vector<std::string>{"y1"} : m.output_names(), info, nullptr);
    Json s = Json::object();
    std::vector<Eigen::VectorXd> b, f;
    std::vector<int> nk;
    for (int i = 0; i < m.num_inputs(); ++i) {
      b.push_back(m.b(i));
      f.push_back(m.f(i));
      nk.push_back(m.nk(i));
    }
    s["b"] = detail::vector_list(b);
    s["f"] = detail::vector_list(f);
    s["nk"] = Json(nk);
    s["offset"] = m.offset();
    j["structure"] = std::move(s);
    j["parameters"] = detail::parameters_json(m.parameter_names(), m.parameters());
    if ((m.parameter_stddev().array() != 0.0).any()) j["parameters"]["stddev"] = extended_vector(m.parameter_stddev());
    j["report"] = linear_report_to_json(m.report());
  }
  /// Builds the model.
  static OutputError load(const JsonView& file, ModelFileInfo& info) {
    detail::expect_kind(file, kind);
    std::vector<std::string> in, out;
    const double ts = detail::read_common(file, info, in, out);
    const JsonView s = file.at("structure");
    s.check_keys({"b", "f", "nk", "offset"});
    OutputError m = detail::located(s, [&] {
      return OutputError(detail::read_vector_list(s.at("b")), detail::read_vector_list(s.at("f")),
                         s.at("nk").get<std::vector<int>>(), ts, s.at("offset").as_number());
    });
    detail::expect_channel_count(file.at("inputs"), in.size(), m.num_inputs(), "inputs");
    detail::expect_channel_count(file.at("outputs"), out.size(), 1, "outputs");
    m.set_input_names(in);
    m.set_output_names(out);
    const Eigen::VectorXd sd = detail::check_linear_parameters(file, m.parameter_names(), m.parameters());
    if (sd.size() > 0) detail::located(file.at("parameters").at("stddev"), [&] {
      m.set_parameter_stddev(sd);
      return 0;
    });
    if (file.contains("report")) m.set_report(linear_report_from_json(file.at("report")));
    return m;
  }
  /// Replaces the prototype by the file's model.
  static void restore(const JsonView& file, OutputError& m, ModelFileInfo& info) { m = load(file, info); }
};

/// StateSpace: "structure": {"A": [[...]], "B", "C", "D", "offset": [...]}.
template <>
struct ModelSerial<StateSpace> {
  /// Kind name in the file.
  static constexpr const char* kind = "state_space";
  /// Writes the model's members.
  static void save(Json& j, const StateSpace& m, const ModelFileInfo& info) {
    std::vector<std::string> out = m.output_names();
    if (out.empty())
      for (int i = 0; i < m.num_outputs(); ++i) out.push_back("y" + std::to_string(i + 1));
    detail::write_common(j, m.ts(), m.input_names().empty() ? default_input_names(m.num_inputs()) : m.input_names(),
                         out, info, nullptr);
    Json s = Json::object();
    s["A"] = to_json(m.a());
    s["B"] = to_json(m.b());
    s["C"] = to_json(m.c());
    s["D"] = to_json(m.d());
    s["offset"] = m.offset();
    j["structure"] = std::move(s);
    std::vector<std::string> names;
    const Eigen::VectorXd th = parameter_table(m, names);
    j["parameters"] = detail::parameters_json(names, th);
    j["report"] = linear_report_to_json(m.report());
  }
  /// Builds the model.
  static StateSpace load(const JsonView& file, ModelFileInfo& info) {
    detail::expect_kind(file, kind);
    std::vector<std::string> in, out;
    const double ts = detail::read_common(file, info, in, out);
    const JsonView s = file.at("structure");
    s.check_keys({"A", "B", "C", "D", "offset"});
    const auto mat = [&](const char* k) {
      const JsonView v = s.at(k);
      // An empty matrix (no states) is written as [] and has no column count: derive it.
      if (v.as_array().empty()) return Eigen::MatrixXd();
      return v.get<Eigen::MatrixXd>();
    };
    Eigen::MatrixXd A = mat("A"), B = mat("B"), C = mat("C"), D = mat("D");
    const auto nu = static_cast<Eigen::Index>(in.size()), ny = static_cast<Eigen::Index>(out.size());
    if (A.size() == 0) {
      A.resize(0, 0);
      B.resize(0, nu);
      C.resize(ny, 0);
    }
    StateSpace m = detail::located(s, [&] { return StateSpace(A, B, C, D, ts); });
    detail::expect_channel_count(file.at("inputs"), in.size(), m.num_inputs(), "inputs");
    detail::expect_channel_count(file.at("outputs"), out.size(), m.num_outputs(), "outputs");
    m.set_input_names(in);
    m.set_output_names(out);
    detail::located(s.at("offset"), [&] {
      m.set_offset(read_vector(s.at("offset"), m.num_outputs()));
      return 0;
    });
    std::vector<std::string> names;
    const Eigen::VectorXd th = parameter_table(m, names);
    (void)detail::check_linear_parameters(file, names, th);
    // Optional as for ARX and OE: a hand-written model has no estimation to report.
    if (file.contains("report")) m.set_report(linear_report_from_json(file.at("report")));
    return m;
  }
  /// Replaces the prototype by the file's model.
  static void restore(const JsonView& file, StateSpace& m, ModelFileInfo& info) { m = load(file, info); }

 private:
  /// The entries of A, B, C, D row by row, named "A(1,2)" etc.: the file's "parameters".
  static Eigen::VectorXd parameter_table(const StateSpace& m, std::vector<std::string>& names) {
    Eigen::VectorXd th(m.a().size() + m.b().size() + m.c().size() + m.d().size());
    names.clear();
    Eigen::Index k = 0;
    const auto add = [&](const Eigen::MatrixXd& x, const char* n) {
      for (Eigen::Index r = 0; r < x.rows(); ++r)
        for (Eigen::Index c = 0; c < x.cols(); ++c) {
          th(k++) = x(r, c);
          names.push_back(std::string(n) + "(" + std::to_string(r + 1) + "," + std::to_string(c + 1) + ")");
        }
    };
    add(m.a(), "A");
    add(m.b(), "B");
    add(m.c(), "C");
    add(m.d(), "D");
    return th;
  }
};

}  // namespace nlid
