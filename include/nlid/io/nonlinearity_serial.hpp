#pragma once
/// @file
/// Nonlinearities in model files: structure and learned normalisation of every catalogue map,
/// and of `AnyNonlinearity` (the kind is read from the file).
///
/// A nonlinearity object holds structure (sizes) and what `initialize` learned that is not a
/// parameter: the regressor centre r and scale s of the unit networks and trees, the split
/// planes of a tree, given breakpoint positions and initial limits. The parameters θ live in
/// the model and are written there. Layout, one object per map (docs/model_files.md):
///
///     {"type": "sigmoidnet", "inputs": 4, "units": 5, "linear_term": true,
///      "standardize": true, "center": [...], "scale": [...]}
///
/// Exact normalisation. The networks evaluate z = (x − r)·(1/s) with 1/s stored; 1/(1/x) ≠ x for
/// about one double in eight, so writing s = 1/(1/s) and inverting again could change the last bit
/// of z. The writer therefore picks, among the doubles next to s, one whose reciprocal restores
/// the held factor exactly (checked by evaluating probe points on a restored copy), so that a
/// reloaded model simulates bit for bit like the saved one.
///
/// `NonlinearitySerial<F>`: `save(f)` → Json; `restore(view, f)` checks that the file describes
/// f's type and sizes and copies the learned state into f; `load(view)` builds an F from the file.

#include <cmath>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/io/json.hpp"
#include "nlid/io/json_eigen.hpp"
#include "nlid/io/serial_common.hpp"
#include "nlid/nonlinearities/any_nonlinearity.hpp"

namespace nlid {

/// Serialiser of nonlinearity F (specialised for every catalogue map; see the file comment).
template <class F>
struct NonlinearitySerial;

/// A nonlinearity type that can be written to a model file.
/// Satisfied by every catalogue map and `AnyNonlinearity`.
template <class F>
concept SavableNonlinearity = requires(const F& f) {
  { NonlinearitySerial<F>::save(f) } -> std::same_as<Json>;
};

/// A nonlinearity type that can be rebuilt from a model file.
/// Satisfied by every catalogue map and `AnyNonlinearity`.
template <class F>
concept LoadableNonlinearity = requires(const JsonView& v) {
  { NonlinearitySerial<F>::load(v) } -> std::same_as<F>;
};

namespace detail {

/// Checks the "type" member of a nonlinearity object.
inline void expect_nonlinearity_type(const JsonView& v, const std::string& type) {
  const std::string& got = v.at("type").as_string();
  if (got != type) {
    v.at("type").fail("the file has nonlinearity \"" + got + "\" at " + v.path_text() + ", this model needs \"" +
                      type + "\"");
  }
}

/// Checks an integer size member against the object's value.
inline void expect_size(const JsonView& v, const char* key, int want) {
  const int got = read_int(v.at(key), 0, 1 << 30);
  if (got != want) {
    v.at(key).fail(std::string("the file has ") + key + " = " + std::to_string(got) + " at " + v.at(key).path_text() +
                   ", this model has " + std::to_string(want));
  }
}

/// Probe: do a and b (same type and sizes) evaluate input j identically? Uses θ that exposes zⱼ
/// (or, without a linear term, a steep sigmoid of it). Returns false when no probe applies.
template <class F>
bool same_standardisation(const F& a, const F& b, int j) {
  const int m = a.input_dimension();
  const Eigen::VectorXd c = a.center(), s = a.scale();
  Eigen::VectorXd x = c;
  x(j) += s(j);
  Eigen::VectorXd th = Eigen::VectorXd::Zero(a.num_parameters());
  if constexpr (requires { F::has_linear_term; }) {
    if constexpr (F::has_linear_term) {
      th(j) = 1.0;  // g = zⱼ exactly
    } else if constexpr (requires { a.offset_b(); a.offset_a(); a.offset_c(); a.units(); } &&
                         requires { a.standardize(); } && !requires { a.offset_w(); }) {
      // Sigmoid net without linear term: g = σ(−16 zⱼ), σ' ≈ σ in the far tail, so one ulp of zⱼ
      // changes g by many ulps.
      th(a.offset_a()) = 1.0;
      th(a.offset_b() + j) = -16.0;
    } else {
      return false;
    }
  } else {
    for (int l = 0; l < a.num_parameters() / (m + 1); ++l) th(l * (m + 1) + j) = 1.0;  // tree leaves
  }
  const std::span<const double> xs(x.data(), static_cast<std::size_t>(m));
  const std::span<const double> ts(th.data(), static_cast<std::size_t>(th.size()));
  return a(xs, ts) == b(xs, ts);
}

/// A scale vector whose reciprocal reproduces f's stored inverse scale (see the file comment).
template <class F>
Eigen::VectorXd exact_scale(const F& f) {
  Eigen::VectorXd s = f.scale();
  const Eigen::VectorXd c = f.center();
  for (int j = 0; j < f.input_dimension(); ++j) {
    const double s0 = s(j);
    if (s0 == 0.0) continue;  // an unused input: 0 is exact
    double best = s0;
    bool found = false;
    // Candidates in order of distance: s0, then one, two, … ulps either side.
    for (int k = 0; k <= 4 && !found; ++k) {
      for (int dir = -1; dir <= 1 && !found; dir += 2) {
        if (k == 0 && dir == 1) continue;
        double cand = s0;
        for (int i = 0; i < k; ++i) cand = std::nextafter(cand, dir < 0 ? 0.0 : HUGE_VAL);
        if (!(cand > 0) || !std::isfinite(cand)) continue;
        F g = f;
        Eigen::VectorXd s2 = s;
        s2(j) = cand;
        g.set_normalization(c, s2);
        if (same_standardisation(f, g, j)) {
          best = cand;
          found = true;
        }
      }
    }
    s(j) = best;
  }
  return s;
}


template <class F>
Json network_to_json(const F& f, const char* type) {
  Json j = Json::object();
  j["type"] = type;
  j["inputs"] = f.input_dimension();
  j["units"] = f.units();
  j["linear_term"] = F::has_linear_term;
  j["standardize"] = f.standardize();
  j["center"] = Eigen::VectorXd(f.center());
  j["scale"] = exact_scale(f);
  return j;
}

template <class F>
void network_restore(const JsonView& v, F& f, const char* type) {
  v.check_keys({"type", "inputs", "units", "linear_term", "standardize", "center", "scale"});
  expect_nonlinearity_type(v, type);
  expect_size(v, "inputs", f.input_dimension());
  expect_size(v, "units", f.units());
  if (v.at("linear_term").as_bool() != F::has_linear_term) {
    v.at("linear_term").fail(std::string("the file's network ") + (F::has_linear_term ? "has no" : "has a") +
                             " linear term at " + v.at("linear_term").path_text() + ", this model's " +
                             (F::has_linear_term ? "has one" : "has none"));
  }
  f.set_standardize(v.at("standardize").as_bool());
  const Eigen::VectorXd c = read_vector(v.at("center"), f.input_dimension());
  const Eigen::VectorXd s = read_vector(v.at("scale"), f.input_dimension());
  try {
    f.set_normalization(c, s);
  } catch (const Error& e) {
    v.at("scale").fail(e.message() + " (at " + v.path_text() + ")");
  }
}

template <class F>
void limits_to_json(Json& j, const F& f) {
  const auto l = f.initial_limits();
  if (l) {
    j["initial_limits"] = Json::array({l->first, l->second});
  } else {
    j["initial_limits"] = nullptr;
  }
}

template <class F>
void limits_restore(const JsonView& v, F& f, const char* type) {
  v.check_keys({"type", "initial_limits"});
  expect_nonlinearity_type(v, type);
  if (!v.at("initial_limits").json().is_null()) {
    const Eigen::VectorXd l = read_vector(v.at("initial_limits"), 2);
    try {
      f.set_initial_limits(l(0), l(1));
    } catch (const Error& e) {
      v.at("initial_limits").fail(e.message() + " (at " + v.at("initial_limits").path_text() + ")");
    }
  }
}

}  // namespace detail

/// {"type": "unitgain"}.
template <>
struct NonlinearitySerial<UnitGain> {
  /// Writes the map.
  static Json save(const UnitGain&) { return Json::object({{"type", "unitgain"}}); }
  /// Checks the file describes a unit gain.
  static void restore(const JsonView& v, UnitGain&) {
    v.check_keys({"type"});
    detail::expect_nonlinearity_type(v, "unitgain");
  }
  /// Builds the map.
  static UnitGain load(const JsonView& v) {
    UnitGain f;
    restore(v, f);
    return f;
  }
};

/// {"type": "linear", "inputs": m}.
template <int M>
struct NonlinearitySerial<LinearMap<M>> {
  /// Writes the map.
  static Json save(const LinearMap<M>& f) {
    return Json::object({{"type", "linear"}, {"inputs", f.input_dimension()}});
  }
  /// Checks type and size.
  static void restore(const JsonView& v, LinearMap<M>& f) {
    v.check_keys({"type", "inputs"});
    detail::expect_nonlinearity_type(v, "linear");
    detail::expect_size(v, "inputs", f.input_dimension());
  }
  /// Builds the map.
  static LinearMap<M> load(const JsonView& v) {
    detail::expect_nonlinearity_type(v, "linear");
    LinearMap<M> f(read_int(v.at("inputs"), 1, 1 << 20));
    restore(v, f);
    return f;
  }
};

/// {"type": "sigmoidnet", "inputs", "units", "linear_term", "standardize", "center", "scale"}.
template <int M, int U, bool L>
struct NonlinearitySerial<SigmoidNet<M, U, L>> {
  /// Writes structure and normalisation.
  static Json save(const SigmoidNet<M, U, L>& f) { return detail::network_to_json(f, "sigmoidnet"); }
  /// Checks structure, restores normalisation.
  static void restore(const JsonView& v, SigmoidNet<M, U, L>& f) { detail::network_restore(v, f, "sigmoidnet"); }
  /// Builds the network.
  static SigmoidNet<M, U, L> load(const JsonView& v) {
    detail::expect_nonlinearity_type(v, "sigmoidnet");
    SigmoidNet<M, U, L> f = detail::located(v, [&] {
      return SigmoidNet<M, U, L>(read_int(v.at("inputs"), 1, 1 << 20), read_int(v.at("units"), 1, 1 << 20));
    });
    restore(v, f);
    return f;
  }
};

/// {"type": "wavenet", …} as the sigmoid network.
template <int M, int U, bool L>
struct NonlinearitySerial<WaveletNet<M, U, L>> {
  /// Writes structure and normalisation.
  static Json save(const WaveletNet<M, U, L>& f) { return detail::network_to_json(f, "wavenet"); }
  /// Checks structure, restores normalisation.
  static void restore(const JsonView& v, WaveletNet<M, U, L>& f) { detail::network_restore(v, f, "wavenet"); }
  /// Builds the network.
  static WaveletNet<M, U, L> load(const JsonView& v) {
    detail::expect_nonlinearity_type(v, "wavenet");
    WaveletNet<M, U, L> f = detail::located(v, [&] {
      return WaveletNet<M, U, L>(read_int(v.at("inputs"), 1, 1 << 20), read_int(v.at("units"), 1, 1 << 20));
    });
    restore(v, f);
    return f;
  }
};

/// {"type": "pwlinear", "breakpoints": n, "positions": [given positions or empty]}.
template <int B>
struct NonlinearitySerial<PwLinear<B>> {
  /// Writes the map.
  static Json save(const PwLinear<B>& f) {
    Json j = Json::object({{"type", "pwlinear"}, {"breakpoints", f.num_breakpoints()}});
    j["positions"] = Json(f.given_positions());
    return j;
  }
  /// Checks the breakpoint count and the given positions.
  static void restore(const JsonView& v, PwLinear<B>& f) {
    v.check_keys({"type", "breakpoints", "positions"});
    detail::expect_nonlinearity_type(v, "pwlinear");
    detail::expect_size(v, "breakpoints", f.num_breakpoints());
  }
  /// Builds the map (with its given positions, if any).
  static PwLinear<B> load(const JsonView& v) {
    detail::expect_nonlinearity_type(v, "pwlinear");
    const auto pos = v.at("positions").get<std::vector<double>>();
    const int n = read_int(v.at("breakpoints"), 2, 1 << 20);
    try {
      PwLinear<B> f = pos.empty() ? PwLinear<B>(n) : PwLinear<B>(pos);
      restore(v, f);
      return f;
    } catch (const Error& e) {
      if (e.where().file.empty()) v.fail(e.message() + " (at " + v.path_text() + ")");
      throw;
    }
  }
};

/// {"type": "saturation", "initial_limits": [lower, upper] or null}.
template <>
struct NonlinearitySerial<Saturation> {
  /// Writes the map.
  static Json save(const Saturation& f) {
    Json j = Json::object({{"type", "saturation"}});
    detail::limits_to_json(j, f);
    return j;
  }
  /// Restores the initial limits.
  static void restore(const JsonView& v, Saturation& f) { detail::limits_restore(v, f, "saturation"); }
  /// Builds the map.
  static Saturation load(const JsonView& v) {
    Saturation f;
    restore(v, f);
    return f;
  }
};

/// {"type": "deadzone", "initial_limits": [lower, upper] or null}.
template <>
struct NonlinearitySerial<DeadZone> {
  /// Writes the map.
  static Json save(const DeadZone& f) {
    Json j = Json::object({{"type", "deadzone"}});
    detail::limits_to_json(j, f);
    return j;
  }
  /// Restores the initial limits.
  static void restore(const JsonView& v, DeadZone& f) { detail::limits_restore(v, f, "deadzone"); }
  /// Builds the map.
  static DeadZone load(const JsonView& v) {
    DeadZone f;
    restore(v, f);
    return f;
  }
};

/// {"type": "poly1d", "degree": d}.
template <int D>
struct NonlinearitySerial<Poly1d<D>> {
  /// Writes the map.
  static Json save(const Poly1d<D>& f) { return Json::object({{"type", "poly1d"}, {"degree", f.degree()}}); }
  /// Checks the degree.
  static void restore(const JsonView& v, Poly1d<D>& f) {
    v.check_keys({"type", "degree"});
    detail::expect_nonlinearity_type(v, "poly1d");
    detail::expect_size(v, "degree", f.degree());
  }
  /// Builds the map.
  static Poly1d<D> load(const JsonView& v) {
    detail::expect_nonlinearity_type(v, "poly1d");
    Poly1d<D> f(read_int(v.at("degree"), 1, 1 << 20));
    restore(v, f);
    return f;
  }
};

/// {"type": "treepartition", "inputs", "depth", "center", "scale",
///  "splits": [{"direction": [...], "threshold": x or "inf"}, ...]} (2^depth − 1 nodes, heap order).
template <int M, int D>
struct NonlinearitySerial<TreePartition<M, D>> {
  /// Writes structure, normalisation and splits.
  static Json save(const TreePartition<M, D>& f) {
    Json j = Json::object({{"type", "treepartition"}, {"inputs", f.input_dimension()}, {"depth", f.depth()}});
    j["center"] = Eigen::VectorXd(f.center());
    j["scale"] = detail::exact_scale(f);
    Json::Array splits;
    for (int node = 0; node < f.leaves() - 1; ++node) {
      Json s = Json::object();
      s["direction"] = f.split_direction(node);
      s["threshold"] = extended_number(f.split_threshold(node));
      splits.push_back(std::move(s));
    }
    j["splits"] = Json(std::move(splits));
    return j;
  }
  /// Checks sizes; restores normalisation and splits.
  static void restore(const JsonView& v, TreePartition<M, D>& f) {
    v.check_keys({"type", "inputs", "depth", "center", "scale", "splits"});
    detail::expect_nonlinearity_type(v, "treepartition");
    detail::expect_size(v, "inputs", f.input_dimension());
    detail::expect_size(v, "depth", f.depth());
    try {
      f.set_normalization(read_vector(v.at("center"), f.input_dimension()),
                          read_vector(v.at("scale"), f.input_dimension()));
    } catch (const Error& e) {
      if (e.where().file.empty()) v.at("scale").fail(e.message() + " (at " + v.path_text() + ")");
      throw;
    }
    const JsonView splits = v.at("splits");
    if (static_cast<int>(splits.as_array().size()) != f.leaves() - 1) {
      splits.fail("expected " + std::to_string(f.leaves() - 1) + " splits at " + splits.path_text() + ", found " +
                  std::to_string(splits.as_array().size()));
    }
    for (int node = 0; node < f.leaves() - 1; ++node) {
      const JsonView s = splits.at(static_cast<std::size_t>(node));
      s.check_keys({"direction", "threshold"});
      try {
        f.set_split(node, read_vector(s.at("direction"), f.input_dimension()), read_extended_number(s.at("threshold")));
      } catch (const Error& e) {  // a NaN direction or threshold: say where in the file
        if (e.where().file.empty()) s.fail(e.message() + " (at " + s.path_text() + ")");
        throw;
      }
    }
  }
  /// Builds the tree.
  static TreePartition<M, D> load(const JsonView& v) {
    detail::expect_nonlinearity_type(v, "treepartition");
    TreePartition<M, D> f = detail::located(
        v, [&] { return TreePartition<M, D>(read_int(v.at("inputs"), 1, 1 << 20), read_int(v.at("depth"), 1, 12)); });
    restore(v, f);
    return f;
  }
};

/// `AnyNonlinearity`: the held map's layout; the kind is read from "type".
template <>
struct NonlinearitySerial<AnyNonlinearity> {
  /// Writes the held map.
  static Json save(const AnyNonlinearity& f) {
    return std::visit([](const auto& g) { return NonlinearitySerial<std::remove_cvref_t<decltype(g)>>::save(g); },
                      f.variant());
  }
  /// Checks the file describes the held map's kind and sizes; restores its state.
  static void restore(const JsonView& v, AnyNonlinearity& f) {
    std::visit([&](auto& g) { NonlinearitySerial<std::remove_cvref_t<decltype(g)>>::restore(v, g); }, f.variant());
  }
  /// Builds the map named by "type".
  static AnyNonlinearity load(const JsonView& v) {
    const std::string& type = v.at("type").as_string();
    constexpr int D = Dynamic;
    if (type == "unitgain") return NonlinearitySerial<UnitGain>::load(v);
    if (type == "linear") return NonlinearitySerial<LinearMap<D>>::load(v);
    if (type == "sigmoidnet") {
      if (v.at("linear_term").as_bool()) return NonlinearitySerial<SigmoidNet<D, D, true>>::load(v);
      return NonlinearitySerial<SigmoidNet<D, D, false>>::load(v);
    }
    if (type == "wavenet") {
      if (v.at("linear_term").as_bool()) return NonlinearitySerial<WaveletNet<D, D, true>>::load(v);
      return NonlinearitySerial<WaveletNet<D, D, false>>::load(v);
    }
    if (type == "pwlinear") return NonlinearitySerial<PwLinear<D>>::load(v);
    if (type == "saturation") return NonlinearitySerial<Saturation>::load(v);
    if (type == "deadzone") return NonlinearitySerial<DeadZone>::load(v);
    if (type == "poly1d") return NonlinearitySerial<Poly1d<D>>::load(v);
    if (type == "treepartition") return NonlinearitySerial<TreePartition<D, D>>::load(v);
    v.at("type").fail("unknown nonlinearity \"" + type + "\" at " + v.at("type").path_text() +
                      " (accepted: unitgain, linear, sigmoidnet, wavenet, pwlinear, saturation, deadzone, poly1d, "
                      "treepartition)");
  }
};

}  // namespace nlid
