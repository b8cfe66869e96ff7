#pragma once
/// @file
/// Model specifications as short text, chosen at run time: `parse_model_spec` reads them,
/// `make_model` builds the (unestimated) structure as an `AnyModel`, and `fit_model_spec`
/// estimates it on data and returns the estimated `AnyModel`, ready to save. This is what the
/// command-line tools (`nlid-fit`) and scripts use instead of writing C++ per trial.
///
/// Grammar (fields separated by ':'; orders as comma-separated key=value pairs):
///
///     linear:arx:na=2,nb=1,nk=0                    ARX [na nb nk]           (Ljung 1999, eq. 4.7)
///     linear:oe:nb=2,nf=2,nk=0                     output error [nb nf nk]  (Ljung 1999, eq. 4.25)
///     nlarx:na=3,nb=3,nk=0:sigmoidnet:units=5      nonlinear ARX, lagged y/u into a nonlinearity
///     hw:nb=3,nf=3,nk=0:in=pwlinear:10:out=saturation   Hammerstein–Wiener f, B/F, h
///     wh:nb=4,nf=3,nk=0:poly1d:9:nb=4,nf=3,nk=0    Wiener–Hammerstein G1, g, G2 (Series)
///     hammerstein:poly1d:3:nb=2,nf=2,nk=0          Hammerstein f, B/F (Series)
///     wiener:nb=2,nf=2,nk=1:saturation             Wiener B/F, h (Series)
///     greybox:throttle                             catalogue physics by name
///
/// A nonlinearity is a kind — unitgain, linear, sigmoidnet, wavenet, pwlinear, saturation,
/// deadzone, poly1d, treepartition — optionally followed by its size as a bare number (units
/// of a network, breakpoints of pwlinear, degree of poly1d, depth of treepartition) or by
/// key=value options (units, breakpoints, degree, depth, linear=0|1). In `hw`, `in=` and `out=`
/// name the two maps (default unitgain). Options for the whole fit may follow anywhere as
/// key=value fields: `focus=simulation|prediction` (nlarx; default simulation),
/// `ic=zero|estimate|equilibrium|measured` (initial condition during estimation; only the values
/// the family's estimator uses: nlarx zero, estimate or measured — with focus=prediction only
/// measured —, linear:oe zero or estimate, hw, the series families and greybox zero, estimate or
/// equilibrium, linear:arx none; another would be ignored in estimation yet recorded in the model
/// file, changing how the saved model simulates, and is refused), and for nlarx
/// `starts=N` / `start_iterations=N` (N data-driven starts of the network, each refined for
/// `start_iterations` ≥ 1, given only with starts > 1; the best continues — `EstimateOptions::starts`, e.g. the study's nlarx5:
/// `nlarx:na=3,nb=3,nk=0:sigmoidnet:5:starts=4,start_iterations=30` with `--iterations 90`),
/// and `lambda=X`: for nlarx, hw and the series families regularization towards zero,
/// ½·X·‖θ‖² added to the criterion (`LmOptions::regularization`, the toolbox's
/// `Regularization.Lambda`); for greybox regularization towards the physical guess in relative
/// terms, ½·X·Σᵢ((θᵢ − θ̄ᵢ)/sᵢ)² with θ̄ the values the estimation starts from (the catalogue's
/// guess after the data-driven initialisation) and sᵢ each parameter's magnitude there (|θ̄ᵢ|,
/// else its search range's width — its bounds' where it has no range —, else 1; the estimator's
/// own scale, so the penalty is uniform in the coordinates the solver works in) —
/// one X for parameters whose units differ by orders of magnitude (a stop stiffness and a
/// friction), which a penalty in their own units could not weigh.
///
/// Errors name the field and list what is accepted, e.g. "unknown model family 'wx' in model
/// spec 'wx:…' (accepted: linear:arx, linear:oe, nlarx, hw, wh, hammerstein, wiener, greybox)".
///
/// Series models are saved as model-file kind "series" (structure: the list of blocks);
/// `register_series_model_kind()` teaches `load_model` to read them (called by the functions
/// below; idempotent).

#include <algorithm>
#include <charconv>
#include <cctype>
#include <chrono>
#include <cmath>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/core/initial_condition.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/estimation/levenberg_marquardt.hpp"
#include "nlid/io/model_file.hpp"
#include "nlid/io/series_serial.hpp"
#include "nlid/linear/arx.hpp"
#include "nlid/linear/output_error.hpp"
#include "nlid/models/any_model.hpp"
#include "nlid/models/estimate.hpp"
#include "nlid/models/greybox_dynamic.hpp"
#include "nlid/models/greybox_estimate.hpp"
#include "nlid/models/series.hpp"
#include "nlid/models/series_estimate.hpp"
#include "nlid/models/simulation_band.hpp"
#include "nlid/models/uncertainty.hpp"
#include "nlid/nonlinearities/any_nonlinearity.hpp"
#include "nlid/regressors/expression.hpp"

namespace nlid {

/// Transfer-function block with run-time orders.
using DynamicTransferFunction = TransferFunctionBlock<Dynamic, Dynamic, Dynamic>;
/// Wiener–Hammerstein model with run-time blocks.
using DynamicWienerHammerstein = Series<DynamicTransferFunction, AnyNonlinearity, DynamicTransferFunction>;
/// Wiener model with run-time blocks.
using DynamicWiener = Series<DynamicTransferFunction, AnyNonlinearity>;
/// Hammerstein model with run-time blocks.
using DynamicHammerstein = Series<AnyNonlinearity, DynamicTransferFunction>;
/// Hammerstein–Wiener chain (N–L–N) as a series, with run-time blocks.
using DynamicHammersteinWienerSeries = Series<AnyNonlinearity, DynamicTransferFunction, AnyNonlinearity>;

/// Teaches `load_model(path)` the "series" kind. Including io/series_serial.hpp (this header
/// does) registers it when the program starts; this call only makes that dependency explicit
/// for programs that load series files without fitting one. Idempotent.
inline void register_series_model_kind() { (void)detail::series_kind_registered; }

/// A static block of a spec: kind and structure options.
struct NonlinearitySpec {
  std::string kind = "unitgain";  ///< unitgain, linear, sigmoidnet, wavenet, pwlinear, saturation, …
  NonlinearityOptions options;    ///< units, breakpoints, degree, depth, linear term
};

/// Orders of a linear block or a regressor set: na, nb, nf, nk (absent ones stay −1).
struct OrderSpec {
  int na = -1, nb = -1, nf = -1, nk = -1;
};

/// A parsed model specification (see the file comment for the grammar).
struct ModelSpec {
  std::string text;    ///< the spec as given
  std::string family;  ///< "linear:arx", "linear:oe", "nlarx", "hw", "wh", "hammerstein", "wiener", "greybox"
  std::vector<OrderSpec> orders;             ///< in order of appearance
  std::vector<NonlinearitySpec> nonlinearities;  ///< in order of appearance (hw: in, out)
  std::string physics;                       ///< greybox: catalogue name
  std::optional<Focus> focus;                ///< nlarx: prediction or simulation (default simulation)
  std::optional<InitialCondition> initial_condition;  ///< during estimation
  int starts = 1;                            ///< nlarx: data-driven starts (EstimateOptions::starts)
  std::optional<int> start_iterations;       ///< nlarx: iterations per start (EstimateOptions::start_iterations)
  double lambda = 0.0;                       ///< regularization towards zero (LmRegularization::lambda)
};

/// Options of `fit_model_spec`.
struct SpecFitOptions {
  int iterations = -1;  ///< main-stage iterations (−1: the family's default)
  /// Called after each solver step (iteration, cost, …) — for progress output.
  std::function<bool(const IterationReport&)> callback;
  /// Stage messages: initialisation (nlarx, hw, series models), the grey box's multi-start plan
  /// and each refined start as it ends, the start of the uncertainty computation.
  std::function<void(const std::string&)> progress;
  /// Called once the estimator has returned, before the parameter uncertainty and the band are
  /// computed (a caller times the estimation alone with it; the grey box's uncertainty is part of
  /// its estimator, so there it comes after both).
  std::function<void()> estimated;
  /// If set, receives the parameter uncertainty of the estimate on the estimation data (nlarx,
  /// hw: `parameter_uncertainty(model, data)`; greybox: `GreyBoxEstimate::uncertainty`). Not
  /// called for the linear and series families (ARX and OE keep their own deviations), nor when
  /// the uncertainty cannot be computed: `progress` then says why, and the fit still returns.
  /// When it is computed, the returned model keeps it for its file (nlarx, hw:
  /// `ModelFileInfo::uncertainty`; greybox: its own covariance), so `simulation_band` and
  /// `nlid-sim --band` work on the saved model.
  std::function<void(const ParameterUncertainty&)> uncertainty;
  /// With `uncertainty` (nlarx, hw, greybox): records — typically the validation data — on which
  /// to compute the simulation band of that uncertainty (`simulation_band`, from the initial
  /// condition the saved model simulates with), handed to `band`. Not called where the
  /// uncertainty or the band cannot be computed: `progress` then says why.
  Dataset band_data;
  std::function<void(const SimulationBand&)> band;
};

namespace detail {

inline std::vector<std::string> split_text(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::string cur;
  for (char c : s) {
    if (c == sep) {
      out.push_back(cur);
      cur.clear();
    } else if (!std::isspace(static_cast<unsigned char>(c))) {
      cur += c;
    }
  }
  out.push_back(cur);
  return out;
}

inline const char* spec_families() {
  return "linear:arx, linear:oe, nlarx, hw, wh, hammerstein, wiener, greybox";
}

inline const char* spec_nonlinearities() {
  return "unitgain, linear, sigmoidnet, wavenet, pwlinear, saturation, deadzone, poly1d, treepartition";
}

inline bool is_nonlinearity_kind(const std::string& k) {
  for (const char* n : {"unitgain", "linear", "sigmoidnet", "wavenet", "pwlinear", "saturation", "deadzone", "poly1d",
                        "treepartition"})
    if (k == n) return true;
  return false;
}

// The largest value a spec accepts for `key`: the limits of the model-file loader (orders and
// delays 100000, units / breakpoints / degree 2^20, tree depth 12), so that a typo such as
// nk=2147483647 is an error here and not an integer overflow or an allocation of gigabytes later.
inline int spec_int_limit(const std::string& key) {
  if (key == "na" || key == "nb" || key == "nf" || key == "nk") return 100000;
  if (key == "depth" || key == "treepartition") return 12;
  if (key == "linear") return 1;
  return 1 << 20;
}

inline int spec_int(const std::string& v, const std::string& key, const std::string& spec) {
  std::size_t pos = 0;
  long long x = -1;
  try {
    x = std::stoll(v, &pos);
  } catch (...) {
    pos = 0;
  }
  require(pos == v.size() && !v.empty() && x >= 0,
          "'" + key + "=" + v + "' in model spec '" + spec + "' is not a non-negative integer", at_parameter(key));
  const int limit = spec_int_limit(key);
  require(x <= limit,
          "'" + key + "=" + v + "' in model spec '" + spec + "' is too large (at most " + std::to_string(limit) + ")",
          at_parameter(key));
  return static_cast<int>(x);
}

/// The option a bare size number sets for a nonlinearity kind ("" if the kind takes no size).
inline std::string size_key(const std::string& kind) {
  if (kind == "sigmoidnet" || kind == "wavenet") return "units";
  if (kind == "pwlinear") return "breakpoints";
  if (kind == "poly1d") return "degree";
  if (kind == "treepartition") return "depth";
  return {};
}

/// Whether a nonlinearity kind has option `key` (units, breakpoints, degree, depth, linear).
inline bool takes_option(const std::string& kind, const std::string& key) {
  if (key == "linear") return kind == "sigmoidnet" || kind == "wavenet";
  return !key.empty() && size_key(kind) == key;
}

/// The options a nonlinearity kind takes, for messages: "units, linear" or "none".
inline std::string options_of(const std::string& kind) {
  const std::string k = size_key(kind);
  if (k.empty()) return "none";
  return takes_option(kind, "linear") ? k + ", linear" : k;
}

/// The `ic=` values the estimator of `s.family` uses (with `s.focus` for nlarx), for the spec's
/// messages: an `ic` it does not use would be recorded in the model file and change how the
/// saved model simulates while the estimate stays the same, so it is refused. Empty: none.
inline std::vector<InitialCondition> spec_initial_conditions(const ModelSpec& s) {
  using IC = InitialCondition;
  if (s.family == "linear:arx") return {};  // least squares on the measured past
  if (s.family == "linear:oe") return {IC::zero, IC::estimate};  // OeOptions::initial_state
  if (s.family == "nlarx") {
    // Prediction focus: one-step predictions from the measured past, whatever ic says.
    if (s.focus == Focus::prediction) return {IC::measured};
    return {IC::zero, IC::estimate, IC::measured};  // Nlarx estimation refuses equilibrium
  }
  // hw, the series families and greybox: a state-space start (measured past outputs do not apply).
  return {IC::zero, IC::estimate, IC::equilibrium};
}

/// Refuses an `ic` the family's estimator does not use, naming the family and what it takes.
inline void check_spec_initial_condition(const ModelSpec& s) {
  if (!s.initial_condition) return;
  const auto accepted = spec_initial_conditions(s);
  if (std::find(accepted.begin(), accepted.end(), *s.initial_condition) != accepted.end()) return;
  const bool prediction = s.family == "nlarx" && s.focus == Focus::prediction;
  const std::string who = s.family + " models" + (prediction ? " with focus=prediction" : "");
  std::string list;
  for (std::size_t i = 0; i < accepted.size(); ++i)
    list += std::string(i == 0 ? "" : i + 1 == accepted.size() ? " or " : ", ") + "ic=" + nlid::to_string(accepted[i]);
  std::string why = "they take " + list;
  if (s.family == "linear:arx") why = "ARX is estimated by least squares on the measured past: it takes no ic";
  if (prediction)
    why = "one-step predictions start from the measured past: they take " + list +
          "; focus=simulation takes ic=zero, ic=estimate or ic=measured";
  throw Error("model spec '" + s.text + "': ic=" + nlid::to_string(*s.initial_condition) +
                  " is not used in estimating " + who + " (" + why +
                  "); an unused ic would only change how the saved model simulates",
              at_parameter("ic"));
}

}  // namespace detail

/// Parses a model spec. Throws `nlid::Error` naming the bad field and listing what is accepted.
inline ModelSpec parse_model_spec(const std::string& text) {
  ModelSpec s;
  s.text = text;
  const auto f = detail::split_text(text, ':');
  require(!f.empty() && !f[0].empty(),
          "empty model spec (accepted families: " + std::string(detail::spec_families()) + ")", at_parameter("model"));
  std::size_t i = 1;
  if (f[0] == "linear") {
    require(f.size() >= 2 && (f[1] == "arx" || f[1] == "oe"),
            "model spec '" + text + "': linear models are 'linear:arx:na=..,nb=..,nk=..' or 'linear:oe:nb=..,nf=..,nk=..'",
            at_parameter("model"));
    s.family = "linear:" + f[1];
    i = 2;
  } else if (f[0] == "nlarx" || f[0] == "hw" || f[0] == "wh" || f[0] == "hammerstein" || f[0] == "wiener" ||
             f[0] == "greybox") {
    s.family = f[0];
  } else {
    throw Error("unknown model family '" + f[0] + "' in model spec '" + text + "' (accepted: " +
                    detail::spec_families() + ")",
                at_parameter("model"));
  }
  if (s.family == "greybox") {
    require(f.size() >= 2 && !f[1].empty(), "model spec '" + text + "': give the physics, e.g. greybox:throttle",
            at_parameter("model"));
    s.physics = f[1];
    i = 2;
  }
  NonlinearitySpec* last = nullptr;  // the map a following bare number or option belongs to
  std::vector<std::string>* last_keys = nullptr;  // the options already given to that map
  std::vector<std::vector<std::string>> map_keys;  // per entry of s.nonlinearities
  std::vector<std::string> fit_keys;  // whole-fit options seen so far
  // A map's option given twice (as a bare size and as key=value, or in two fields) would
  // silently take the last value, and an option the map does not have would be ignored:
  // refuse both, naming the map.
  auto set_option = [&](const std::string& key, int x) {
    require(detail::takes_option(last->kind, key),
            "model spec '" + text + "': " + last->kind + " has no option '" + key + "' (its options: " +
                detail::options_of(last->kind) + ")",
            at_parameter(key));
    require(std::find(last_keys->begin(), last_keys->end(), key) == last_keys->end(),
            "model spec '" + text + "': the " + key + " of " + last->kind + " is given twice", at_parameter(key));
    last_keys->push_back(key);
    // The smallest sizes the maps accept (checked here so a command line fails before any data
    // are read, with the spec's words).
    const int least = key == "breakpoints" ? 2 : key == "linear" ? 0 : 1;
    require(x >= least,
            "model spec '" + text + "': the " + key + " of " + last->kind + " must be >= " + std::to_string(least) +
                ", got " + std::to_string(x),
            at_parameter(key));
    if (key == "units") last->options.units = x;
    if (key == "breakpoints") last->options.breakpoints = x;
    if (key == "degree") last->options.degree = x;
    if (key == "depth") last->options.depth = x;
    if (key == "linear") last->options.linear_term = x != 0;
  };
  bool in_given = false, out_given = false;
  for (; i < f.size(); ++i) {
    const std::string& tok = f[i];
    require(!tok.empty(), "model spec '" + text + "' has an empty field " + std::to_string(i + 1), at_parameter("model"));
    if (std::isdigit(static_cast<unsigned char>(tok[0]))) {
      require(last != nullptr, "model spec '" + text + "': the number '" + tok + "' follows no nonlinearity",
              at_parameter("model"));
      const std::string key = detail::size_key(last->kind);
      require(!key.empty(),
              "nonlinearity '" + last->kind + "' takes no size, got " + tok + " in model spec '" + text + "'",
              at_parameter("model"));
      set_option(key, detail::spec_int(tok, last->kind, text));
      continue;
    }
    std::string kind = tok;
    if (tok.rfind("in=", 0) == 0 || tok.rfind("out=", 0) == 0) {
      require(s.family == "hw", "model spec '" + text + "': 'in=' and 'out=' belong to hw models", at_parameter("model"));
      kind = tok.substr(tok.find('=') + 1);
      const bool is_in = tok[0] == 'i';
      // The two slots exist only if no bare map came first ("hw:...:saturation:out=pwlinear"
      // would otherwise write past the list).
      require(s.nonlinearities.empty() || in_given || out_given,
              "model spec '" + text + "': '" + tok.substr(0, tok.find('=') + 1) +
                  "' cannot follow a nonlinearity given without in= or out= (name both maps: in=KIND:out=KIND)",
              at_parameter("model"));
      if (s.nonlinearities.empty()) {
        s.nonlinearities.resize(2);
        map_keys.resize(2);
      }
      require(detail::is_nonlinearity_kind(kind), "unknown nonlinearity '" + kind + "' in model spec '" + text +
                                                      "' (accepted: " + detail::spec_nonlinearities() + ")",
              at_parameter("model"));
      require(!(is_in ? in_given : out_given),
              "model spec '" + text + "': '" + std::string(is_in ? "in=" : "out=") + "' is given twice",
              at_parameter("model"));
      (is_in ? in_given : out_given) = true;
      last = &s.nonlinearities[is_in ? 0 : 1];
      last_keys = &map_keys[is_in ? 0 : 1];
      *last = NonlinearitySpec{kind, {}};
      continue;
    }
    if (tok.find('=') == std::string::npos) {
      require(detail::is_nonlinearity_kind(kind), "unknown nonlinearity '" + kind + "' in model spec '" + text +
                                                      "' (accepted: " + detail::spec_nonlinearities() + ")",
              at_parameter("model"));
      s.nonlinearities.push_back(NonlinearitySpec{kind, {}});
      map_keys.emplace_back();
      last = &s.nonlinearities.back();
      last_keys = &map_keys.back();
      continue;
    }
    // key=value list: orders, nonlinearity options or fit options.
    OrderSpec o;
    bool has_order = false;
    std::vector<std::string> field_keys;
    for (const auto& kv : detail::split_text(tok, ',')) {
      const auto eq = kv.find('=');
      require(eq != std::string::npos && eq > 0, "model spec '" + text + "': '" + kv + "' is not key=value",
              at_parameter("model"));
      const std::string k = kv.substr(0, eq), v = kv.substr(eq + 1);
      // A key given twice would silently take the last value: refuse it (whole-fit options
      // across the spec, the others within their field).
      const bool whole_fit = k == "focus" || k == "ic" || k == "starts" || k == "start_iterations" || k == "lambda";
      std::vector<std::string>& seen = whole_fit ? fit_keys : field_keys;
      require(std::find(seen.begin(), seen.end(), k) == seen.end(),
              "model spec '" + text + "': '" + k + "' is given twice", at_parameter(k));
      seen.push_back(k);
      if (k == "na" || k == "nb" || k == "nf" || k == "nk") {
        const int x = detail::spec_int(v, k, text);
        (k == "na" ? o.na : k == "nb" ? o.nb : k == "nf" ? o.nf : o.nk) = x;
        has_order = true;
      } else if (k == "units" || k == "breakpoints" || k == "degree" || k == "depth" || k == "linear") {
        require(last != nullptr, "model spec '" + text + "': '" + kv + "' follows no nonlinearity", at_parameter("model"));
        set_option(k, detail::spec_int(v, k, text));
      } else if (k == "starts" || k == "start_iterations") {
        require(s.family == "nlarx", "model spec '" + text + "': '" + k + "' applies to nlarx models", at_parameter(k));
        const int x = detail::spec_int(v, k, text);
        require(k != "starts" || (x >= 1 && x <= 64), "model spec '" + text + "': starts must be in 1 ... 64, got " + v,
                at_parameter(k));
        // 0 would compare the starts unrefined (from their initial cost): not what the option is for.
        require(k != "start_iterations" || x >= 1,
                "model spec '" + text + "': start_iterations must be >= 1 (the iterations each start is refined "
                "for before the starts are compared), got " + v,
                at_parameter(k));
        if (k == "starts") s.starts = x;
        else s.start_iterations = x;
      } else if (k == "lambda") {
        require(s.family == "nlarx" || s.family == "hw" || s.family == "wh" || s.family == "hammerstein" ||
                    s.family == "wiener" || s.family == "greybox",
                "model spec '" + text + "': lambda applies to nlarx, hw, wh, hammerstein, wiener and greybox models",
                at_parameter(k));
        // from_chars, not stod: stod follows LC_NUMERIC, so under a decimal-comma locale
        // "lambda=0.5" was refused. A leading '+' is accepted, as stod did.
        double x = -1.0;
        const bool plus = !v.empty() && v.front() == '+';
        const char* first = v.data() + (plus ? 1 : 0);
        const char* last = v.data() + v.size();
        const auto [end, ec] = std::from_chars(first, last, x);
        const std::size_t pos = ec == std::errc() && !(plus && (*first == '-' || *first == '+'))
                                    ? static_cast<std::size_t>(end - v.data())
                                    : 0;
        require(pos == v.size() && !v.empty() && std::isfinite(x) && x >= 0.0,
                "'lambda=" + v + "' in model spec '" + text + "' is not a finite number >= 0", at_parameter(k));
        s.lambda = x;
      } else if (k == "focus") {
        require(s.family == "nlarx",
                "model spec '" + text + "': focus applies to nlarx models (the others are estimated by "
                "their own criterion: ARX prediction, output-error and block models simulation)",
                at_parameter("focus"));
        require(v == "simulation" || v == "prediction",
                "model spec '" + text + "': focus must be simulation or prediction, got '" + v + "'", at_parameter("focus"));
        s.focus = v == "simulation" ? Focus::simulation : Focus::prediction;
      } else if (k == "ic") {
        if (v == "zero") s.initial_condition = InitialCondition::zero;
        else if (v == "estimate") s.initial_condition = InitialCondition::estimate;
        else if (v == "equilibrium") s.initial_condition = InitialCondition::equilibrium;
        else if (v == "measured") s.initial_condition = InitialCondition::measured;
        else
          throw Error("model spec '" + text + "': ic must be zero, estimate, equilibrium or measured, got '" + v + "'",
                      at_parameter("ic"));
      } else {
        throw Error("unknown key '" + k + "' in model spec '" + text +
                        "' (accepted: na, nb, nf, nk, units, breakpoints, degree, depth, linear, focus, ic, starts, start_iterations, lambda)",
                    at_parameter(k));
      }
    }
    if (has_order) s.orders.push_back(o);
  }
  detail::check_spec_initial_condition(s);
  // Without several starts there is nothing to compare and start_iterations would be ignored.
  require(!s.start_iterations || s.starts > 1,
          "model spec '" + text + "': start_iterations is the refinement of each of several starts; give starts=N "
          "(N > 1) with it, or leave it out",
          at_parameter("start_iterations"));
  require(s.starts == 1 || (s.nonlinearities.size() == 1 && s.nonlinearities[0].kind == "sigmoidnet"),
          "model spec '" + text + "': starts > 1 needs a sigmoidnet (the only map with alternative starts)",
          at_parameter("starts"));
  // Shape checks per family.
  auto need = [&](std::size_t norders, std::size_t nnl, const char* example) {
    require(s.orders.size() == norders && s.nonlinearities.size() == nnl,
            "model spec '" + text + "' does not match the form " + example, at_parameter("model"));
  };
  auto need_keys = [&](const OrderSpec& o, bool na, bool nf) {
    require(o.nb >= 1 && o.nk >= 0 && (!na || o.na >= 0) && (!nf || o.nf >= 0),
            "model spec '" + text + "': orders need " + std::string(na ? "na, " : "") + "nb (>= 1), " +
                (nf ? "nf, " : "") + "nk",
            at_parameter("model"));
    // An order the family has no use for would be dropped silently ("hw:na=2,..." is not an ARX part).
    for (const auto& [key, given, used] : {std::tuple{"na", o.na >= 0, na}, std::tuple{"nf", o.nf >= 0, nf}})
      require(!given || used,
              "model spec '" + text + "': " + key + " does not apply to " + s.family + " models (their orders: " +
                  (na ? "na, " : "") + "nb, " + (nf ? "nf, " : "") + "nk)",
              at_parameter(key));
  };
  if (s.family == "linear:arx") { need(1, 0, "linear:arx:na=2,nb=1,nk=0"); need_keys(s.orders[0], true, false); }
  if (s.family == "linear:oe") { need(1, 0, "linear:oe:nb=2,nf=2,nk=0"); need_keys(s.orders[0], false, true); }
  if (s.family == "nlarx") {
    need(1, 1, "nlarx:na=3,nb=3,nk=0:sigmoidnet:units=5");
    need_keys(s.orders[0], true, false);
    // A one-input map cannot take the regressor vector: na past outputs and nb past values of
    // each input, at least na + nb whatever the input count (exactly that for one input, so
    // na=0,nb=1 is left to make_model, which knows the input count).
    const auto& o = s.orders[0];
    const std::string& k = s.nonlinearities[0].kind;
    const bool one_input = k == "unitgain" || k == "pwlinear" || k == "saturation" || k == "deadzone" || k == "poly1d";
    require(!one_input || o.na + o.nb <= 1,
            "model spec '" + text + "': " + k + " has one input, but nlarx feeds its nonlinearity " +
                std::to_string(o.na + o.nb) + " regressors or more (na=" + std::to_string(o.na) + " past outputs, nb=" +
                std::to_string(o.nb) + " past values of each input); nlarx takes sigmoidnet, wavenet, treepartition or "
                "linear (a one-input map only with na=0,nb=1 and one input)",
            at_parameter("model"));
  }
  if (s.family == "hw") {
    if (s.nonlinearities.empty()) s.nonlinearities.resize(2);
    need(1, 2, "hw:nb=3,nf=3,nk=0:in=pwlinear:10:out=saturation");
    need_keys(s.orders[0], false, true);
  }
  if (s.family == "wh") {
    need(2, 1, "wh:nb=4,nf=3,nk=0:poly1d:9:nb=4,nf=3,nk=0");
    need_keys(s.orders[0], false, true);
    need_keys(s.orders[1], false, true);
  }
  if (s.family == "hammerstein") { need(1, 1, "hammerstein:poly1d:3:nb=2,nf=2,nk=0"); need_keys(s.orders[0], false, true); }
  if (s.family == "wiener") { need(1, 1, "wiener:nb=2,nf=2,nk=1:saturation"); need_keys(s.orders[0], false, true); }
  if (s.family == "greybox") need(0, 0, "greybox:throttle");
  return s;
}

namespace detail {

inline AnyNonlinearity make_spec_nonlinearity(const NonlinearitySpec& n, int inputs) {
  return make_nonlinearity(n.kind, inputs, n.options);
}

inline DynamicTransferFunction make_spec_block(const OrderSpec& o) { return DynamicTransferFunction(o.nb, o.nf, o.nk); }

template <class M>
AnyModel fit_series_spec(M model, const ModelSpec& s, const Dataset& data, const SpecFitOptions& o) {
  SeriesEstimateOptions so;
  so.initial_condition = s.initial_condition;
  so.progress = o.progress;
  so.solver.callback = o.callback;
  so.solver.max_iterations = o.iterations >= 0 ? o.iterations : 200;
  so.solver.regularization.lambda = s.lambda;
  M m = estimate(std::move(model), data, so);
  if (o.estimated) o.estimated();
  ModelFileInfo info;
  info.description = "nlid-fit --model " + s.text;
  info.initial_condition = s.initial_condition.value_or(InitialCondition::zero);
  return AnyModel(std::move(m), info);
}

// Hands `o.band` the simulation band of `u` on `o.band_data` (if both are given).
template <class M>
void spec_band(const M& m, const ParameterUncertainty& u, const SpecFitOptions& o, InitialCondition simulated_from) {
  if (!o.band || o.band_data.size() == 0) return;
  SimulationBandOptions bo;
  bo.initial_condition = simulated_from;
  try {
    o.band(simulation_band(m, o.band_data, u, bo));
  } catch (const Error& err) {
    if (o.progress) o.progress(std::string("no simulation band: ") + err.what());
  }
}

// Hands `o.uncertainty` the model's uncertainty on its estimation data. The estimate stands even
// where the uncertainty cannot be computed (estimation accepts as many residuals as unknowns,
// which leaves no degrees of freedom for the noise level): the progress callback says why.
// Returns it too, for the model file (ModelFileInfo::uncertainty).
template <class M>
std::optional<ParameterUncertainty> spec_uncertainty(const M& m, const Dataset& data, const LmOptions& solver,
                                                     const SpecFitOptions& o, InitialCondition simulated_from) {
  if (o.estimated) o.estimated();
  if (!o.uncertainty) return std::nullopt;
  if (m.parameters().size() == 0) {  // nothing was estimated: no covariance, no band to save
    if (o.progress) o.progress("no parameter uncertainty: the model has no parameters");
    return std::nullopt;
  }
  if (o.progress) o.progress("computing the parameters' uncertainty on the estimation data");
  ModelUncertaintyOptions uo;
  uo.uncertainty.caveat = uncertainty_caveat(solver);
  ParameterUncertainty u;
  try {
    u = parameter_uncertainty(m, data, uo);
  } catch (const Error& err) {
    if (o.progress) o.progress(std::string("no parameter uncertainty: ") + err.what());
    return std::nullopt;
  }
  o.uncertainty(u);
  spec_band(m, u, o, simulated_from);
  return u;
}


}  // namespace detail

/// The unestimated structure of a spec (for inspection: `describe()`, parameter names).
/// `num_inputs` is the number of input channels (nlarx regressors count them). Throws
/// `nlid::Error` for sizes a component rejects.
// A template only so that its body (one AnyModel instantiation per model family, estimators
// included) is compiled where it is called, not in every file that includes this header.
template <int = 0>
AnyModel make_model(const ModelSpec& s, int num_inputs = 1) {
  register_series_model_kind();
  require(num_inputs == 1 || s.family == "nlarx" || s.family == "linear:arx",
          "a " + s.family + " model has one input, the data have " + std::to_string(num_inputs), at_parameter("input"));
  if (s.family == "linear:arx") {
    const auto& o = s.orders[0];
    return AnyModel(Arx(Eigen::VectorXd::Zero(o.na), std::vector<Eigen::VectorXd>(static_cast<std::size_t>(num_inputs), Eigen::VectorXd::Zero(o.nb)),
                        std::vector<int>(static_cast<std::size_t>(num_inputs), o.nk), 1.0));
  }
  if (s.family == "linear:oe") {
    const auto& o = s.orders[0];
    return AnyModel(OutputError({Eigen::VectorXd::Zero(o.nb)}, {Eigen::VectorXd::Zero(o.nf)}, {o.nk}, 1.0));
  }
  if (s.family == "nlarx") {
    const auto& o = s.orders[0];
    RegressorList r = RegressorList::lagged(o.na, std::vector<int>(static_cast<std::size_t>(num_inputs), o.nb),
                                            std::vector<int>(static_cast<std::size_t>(num_inputs), o.nk));
    const int nr = static_cast<int>(r.size());
    return AnyModel(DynamicNlarx(std::move(r), detail::make_spec_nonlinearity(s.nonlinearities[0], nr)));
  }
  if (s.family == "hw")
    return AnyModel(DynamicHammersteinWiener(detail::make_spec_nonlinearity(s.nonlinearities[0], 1),
                                             detail::make_spec_block(s.orders[0]),
                                             detail::make_spec_nonlinearity(s.nonlinearities[1], 1)));
  if (s.family == "wh")
    return AnyModel(DynamicWienerHammerstein(detail::make_spec_block(s.orders[0]),
                                             detail::make_spec_nonlinearity(s.nonlinearities[0], 1),
                                             detail::make_spec_block(s.orders[1])));
  if (s.family == "hammerstein")
    return AnyModel(DynamicHammerstein(detail::make_spec_nonlinearity(s.nonlinearities[0], 1), detail::make_spec_block(s.orders[0])));
  if (s.family == "wiener")
    return AnyModel(DynamicWiener(detail::make_spec_block(s.orders[0]), detail::make_spec_nonlinearity(s.nonlinearities[0], 1)));
  return AnyModel(make_greybox(s.physics));
}

namespace detail {
/// fit_model_spec without the data range (below).
template <int = 0>  // compiled where called, as make_model
AnyModel fit_model_spec_kind(const ModelSpec& s, const Dataset& data, const SpecFitOptions& o) {
  register_series_model_kind();
  require(data.size() > 0, "no estimation data", at_parameter("data"));
  const int nu = data.num_inputs();
  (void)make_model(s, nu);  // checks the input count and the component sizes first
  detail::check_spec_initial_condition(s);  // a spec built in code, not parsed
  ModelFileInfo info;
  info.description = "nlid-fit --model " + s.text;
  if (s.initial_condition) info.initial_condition = s.initial_condition;
  if (s.family == "linear:arx") {
    const auto& od = s.orders[0];
    Arx m = arx(data, ArxOrders(od.na, std::vector<int>(static_cast<std::size_t>(nu), od.nb),
                                std::vector<int>(static_cast<std::size_t>(nu), od.nk)));
    if (o.estimated) o.estimated();
    return AnyModel(std::move(m), info);
  }
  if (s.family == "linear:oe") {
    const auto& od = s.orders[0];
    OeOptions oo;
    if (o.iterations >= 0) oo.lm.max_iterations = o.iterations;
    oo.lm.callback = o.callback;
    oo.initial_state = s.initial_condition.value_or(InitialCondition::zero);
    OutputError m = oe(data, OeOrders(od.nb, od.nf, od.nk), oo);
    if (o.estimated) o.estimated();
    return AnyModel(std::move(m), info);
  }
  if (s.family == "nlarx" || s.family == "hw") {
    EstimateOptions eo;
    eo.focus = s.focus.value_or(Focus::simulation);
    eo.initial_condition = s.initial_condition;
    eo.solver.callback = o.callback;
    eo.progress = o.progress;
    if (o.iterations >= 0) eo.solver.max_iterations = o.iterations;
    eo.starts = s.starts;
    if (s.start_iterations) eo.start_iterations = *s.start_iterations;
    eo.solver.regularization.lambda = s.lambda;
    if (s.family == "nlarx") {
      const auto& od = s.orders[0];
      RegressorList r = RegressorList::lagged(od.na, std::vector<int>(static_cast<std::size_t>(nu), od.nb),
                                              std::vector<int>(static_cast<std::size_t>(nu), od.nk));
      const int nr = static_cast<int>(r.size());
      DynamicNlarx m = estimate(DynamicNlarx(std::move(r), detail::make_spec_nonlinearity(s.nonlinearities[0], nr)), data, eo);
      info.uncertainty = detail::spec_uncertainty(m, data, eo.solver, o,
                                                  s.initial_condition.value_or(detail::initial_condition_from_report(
                                                      m.report().initial_condition, InitialCondition::zero)));
      return AnyModel(std::move(m), info);
    }
    DynamicHammersteinWiener m = estimate(
        DynamicHammersteinWiener(detail::make_spec_nonlinearity(s.nonlinearities[0], 1), detail::make_spec_block(s.orders[0]),
                                 detail::make_spec_nonlinearity(s.nonlinearities[1], 1)),
        data, eo);
    info.uncertainty = detail::spec_uncertainty(m, data, eo.solver, o,
                                                s.initial_condition.value_or(detail::initial_condition_from_report(
                                                    m.report().initial_condition, InitialCondition::zero)));
    return AnyModel(std::move(m), info);
  }
  if (s.family == "wh")
    return detail::fit_series_spec(DynamicWienerHammerstein(detail::make_spec_block(s.orders[0]),
                                                            detail::make_spec_nonlinearity(s.nonlinearities[0], 1),
                                                            detail::make_spec_block(s.orders[1])),
                                   s, data, o);
  if (s.family == "hammerstein")
    return detail::fit_series_spec(
        DynamicHammerstein(detail::make_spec_nonlinearity(s.nonlinearities[0], 1), detail::make_spec_block(s.orders[0])), s,
        data, o);
  if (s.family == "wiener")
    return detail::fit_series_spec(
        DynamicWiener(detail::make_spec_block(s.orders[0]), detail::make_spec_nonlinearity(s.nonlinearities[0], 1)), s, data,
        o);
  DynamicGreyBox g = make_greybox(s.physics);
  GreyBoxEstimateOptions go;
  if (s.initial_condition) go.initial_condition = *s.initial_condition;
  // The refinement of each start is the grey box's main stage (SpecFitOptions::iterations).
  if (o.iterations >= 0) go.multi_start.lm.max_iterations = o.iterations;
  if (s.lambda > 0.0) {
    // Relative deviations (see the file comment): weights 1/s² from the values after the
    // data-driven initialisation (run here, so the estimator does not repeat it), the nominal
    // left empty so that the estimator pulls towards those same values.
    if (go.initialize_from_data && !g.initialized()) g.initialize(data);
    const std::vector<ParameterInfo>& info = g.parameter_info();
    Eigen::VectorXd w(static_cast<Eigen::Index>(info.size()));
    for (std::size_t i = 0; i < info.size(); ++i) {
      const double mag = nlid::detail::parameter_magnitude(info[i]);
      w[static_cast<Eigen::Index>(i)] = 1.0 / (mag * mag);
    }
    go.multi_start.lm.regularization.lambda = s.lambda;
    go.multi_start.lm.regularization.weights = w;
  }
  // Progress: the plan, then each start as its refinement ends (in completion order when several
  // threads refine). The costs are the solver's ½Σr² of the simulation error.
  if (o.progress) {
    const MultiStartOptions& ms = go.multi_start;
    o.progress("grey box " + s.physics + ": " + std::to_string(ms.num_candidates) + " start candidates screened, the best " +
               std::to_string(ms.num_starts) + " refined (up to " + std::to_string(ms.lm.max_iterations) +
               " iterations each)");
    go.multi_start.start_done = [progress = o.progress](const StartResult& r, int done, int total) {
      std::string line = "start " + std::to_string(done) + " of " + std::to_string(total) + " (candidate " +
                         std::to_string(r.candidate) + "): ";
      if (!r.error.empty()) {
        line += "failed: " + r.error;
      } else {
        line += "cost " + nlid::detail::format_g(r.start_cost, 6) + " -> " + nlid::detail::format_g(r.cost, 7) + " in " +
                std::to_string(r.summary.iterations) + " iterations, " +
                (r.summary.converged() ? std::string("converged") : std::string(to_string(r.summary.status)));
      }
      progress(line);
    };
  }
  const GreyBoxEstimate ge = estimate(g, data, go);
  if (o.estimated) o.estimated();
  // A grey box holds no report itself: the file keeps the estimation's (it read "estimated":
  // false before, with no iterations, costs or fits).
  info.report = estimation_report(ge);
  info.report->initial_condition = nlid::to_string(go.initial_condition);
  if (o.uncertainty && ge.uncertainty.theta.size() > 0) {
    o.uncertainty(ge.uncertainty);
    detail::spec_band(g, ge.uncertainty, o, s.initial_condition.value_or(InitialCondition::estimate));
  }
  if (o.uncertainty && ge.uncertainty.theta.size() == 0 && o.progress) o.progress(ge.uncertainty.caveat);
  return AnyModel(std::move(g), info);
}
}  // namespace detail

/// Estimates the model a spec describes on `data` (one or more experiments) and returns it
/// estimated, with the spec as the file description and the range of every channel in `data`
/// (`ModelFileInfo::input_range`, `output_range`), and — when `o.uncertainty` is set and the
/// uncertainty could be computed — the parameters' uncertainty (nlarx, hw:
/// `ModelFileInfo::uncertainty`; greybox: its own covariance). Estimators: arx/oe of the linear layer,
/// `estimate` (models/estimate.hpp) for nlarx and hw, the series estimator for wh, hammerstein
/// and wiener, the grey-box estimator for greybox. Throws `nlid::Error` on data that do not fit.
template <int = 0>  // compiled where called, as make_model
AnyModel fit_model_spec(const ModelSpec& s, const Dataset& data, const SpecFitOptions& o = {}) {
  AnyModel m = detail::fit_model_spec_kind(s, data, o);
  record_data_range(m.info(), data);  // where the model was fitted (ModelFileInfo::input_range)
  return m;
}
}  // namespace nlid
