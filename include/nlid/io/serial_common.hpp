#pragma once
/// @file
/// Building blocks shared by the model-file serialisers (docs/model_files.md): numbers that may
/// be infinite or NaN, channel descriptions, estimation reports, strict reading helpers.
///
/// Exactness. `nlid::Json` prints every double as the shortest decimal that reads back to the
/// same bits (17 significant digits at most; Steele & White 1990), so a parameter written and
/// read again is the same double, and a model simulates bit for bit the same after a round trip.
///
/// Non-finite numbers. JSON has no spelling for ±∞ or NaN, but models hold them legitimately
/// (an unbounded parameter, a tree node that is not split, the cost of a model never estimated).
/// They are written as the strings "inf", "-inf" and "nan" — only where the format documents a
/// number that may be non-finite; anywhere else a non-finite value is a write error.
///
/// Reading is strict: a missing key, a wrong type or an unknown key raises `nlid::Error` naming
/// the key path (e.g. `structure.nonlinearity.units`) and the file, line and column.

#include <cmath>
#include <ctime>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/core/initial_condition.hpp"
#include "nlid/io/json.hpp"
#include "nlid/io/json_eigen.hpp"
#include "nlid/linear/report.hpp"
#include "nlid/models/detail/model_common.hpp"

namespace nlid {

/// A number that may be non-finite: finite as a JSON number, else "inf", "-inf" or "nan".
[[nodiscard]] inline Json extended_number(double x) {
  if (std::isfinite(x)) return Json(x);
  if (std::isnan(x)) return Json("nan");
  return Json(x > 0 ? "inf" : "-inf");
}

/// Reads a number written by `extended_number`. Throws naming the path for anything else.
[[nodiscard]] inline double read_extended_number(const JsonView& v) {
  if (v.type() == Json::Type::string) {
    const std::string& s = v.as_string();
    if (s == "inf") return std::numeric_limits<double>::infinity();
    if (s == "-inf") return -std::numeric_limits<double>::infinity();
    if (s == "nan") return std::numeric_limits<double>::quiet_NaN();
    v.fail("expected a number or \"inf\", \"-inf\", \"nan\" at " + v.path_text() + ", found string \"" + s + "\"");
  }
  return v.as_number();
}

/// A vector of possibly non-finite numbers.
[[nodiscard]] inline Json extended_vector(const Eigen::VectorXd& x) {
  Json::Array a;
  for (Eigen::Index i = 0; i < x.size(); ++i) a.push_back(extended_number(x(i)));
  return Json(std::move(a));
}

/// Reads `extended_vector`.
[[nodiscard]] inline Eigen::VectorXd read_extended_vector(const JsonView& v) {
  const auto n = v.as_array().size();
  Eigen::VectorXd x(static_cast<Eigen::Index>(n));
  for (std::size_t i = 0; i < n; ++i) x(static_cast<Eigen::Index>(i)) = read_extended_number(v.at(i));
  return x;
}

/// A list of strings.
[[nodiscard]] inline Json string_list(const std::vector<std::string>& s) {
  Json::Array a;
  for (const auto& x : s) a.emplace_back(x);
  return Json(std::move(a));
}

/// Reads a list of strings.
[[nodiscard]] inline std::vector<std::string> read_string_list(const JsonView& v) {
  std::vector<std::string> s;
  const auto n = v.as_array().size();
  for (std::size_t i = 0; i < n; ++i) s.push_back(v.at(i).as_string());
  return s;
}

/// Reads an integer in [lo, hi], failing with the path and the allowed range otherwise.
[[nodiscard]] inline int read_int(const JsonView& v, int lo, int hi) {
  const long long x = v.as_integer();
  if (x < lo || x > hi) {
    v.fail("value " + std::to_string(x) + " at " + v.path_text() + " is out of range [" + std::to_string(lo) +
           ", " + std::to_string(hi) + "]");
  }
  return static_cast<int>(x);
}

/// Reads a vector of doubles of exactly `n` entries (n < 0: any length).
[[nodiscard]] inline Eigen::VectorXd read_vector(const JsonView& v, Eigen::Index n = -1) {
  Eigen::VectorXd x = v.get<Eigen::VectorXd>();
  if (n >= 0 && x.size() != n) {
    v.fail("expected " + std::to_string(n) + " numbers at " + v.path_text() + ", found " + std::to_string(x.size()));
  }
  return x;
}

/// "zero", "estimate", "equilibrium", "measured" → the policy; throws naming the path otherwise.
[[nodiscard]] inline InitialCondition read_initial_condition(const JsonView& v) {
  const std::string& s = v.as_string();
  if (s == "zero") return InitialCondition::zero;
  if (s == "estimate") return InitialCondition::estimate;
  if (s == "equilibrium") return InitialCondition::equilibrium;
  if (s == "measured") return InitialCondition::measured;
  v.fail("unknown initial condition \"" + s + "\" at " + v.path_text() +
         " (accepted: zero, estimate, equilibrium, measured)");
}

/// Current UTC time as ISO 8601 ("2024-05-01T12:00:00Z"), the `created` stamp of a file.
[[nodiscard]] inline std::string utc_timestamp() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
#if defined(_WIN32)
  gmtime_s(&tm, &now);
#else
  gmtime_r(&now, &tm);
#endif
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

/// The estimation report of a nonlinear model as JSON (every field; see docs/model_files.md).
[[nodiscard]] inline Json report_to_json(const EstimationReport& r) {
  Json j = Json::object();
  j["estimated"] = r.estimated;
  j["focus"] = r.focus;
  j["initial_condition"] = r.initial_condition;
  j["iterations"] = r.iterations;
  j["initial_cost"] = extended_number(r.initial_cost);
  j["final_cost"] = extended_number(r.final_cost);
  j["seconds"] = extended_number(r.seconds);
  j["status"] = r.status;
  j["data_names"] = string_list(r.data_names);
  j["fit_percent"] = extended_vector(Eigen::Map<const Eigen::VectorXd>(r.fit_percent.data(),
                                                                      static_cast<Eigen::Index>(r.fit_percent.size())));
  Json::Array x0;
  for (const auto& x : r.initial_states) x0.push_back(extended_vector(x));
  j["initial_states"] = Json(std::move(x0));
  return j;
}

/// Reads `report_to_json`.
[[nodiscard]] inline EstimationReport report_from_json(const JsonView& v) {
  v.check_keys({"estimated", "focus", "initial_condition", "iterations", "initial_cost", "final_cost", "seconds",
                "status", "data_names", "fit_percent", "initial_states"});
  EstimationReport r;
  r.estimated = v.at("estimated").as_bool();
  r.focus = v.at("focus").as_string();
  r.initial_condition = v.at("initial_condition").as_string();
  r.iterations = read_int(v.at("iterations"), 0, std::numeric_limits<int>::max());
  r.initial_cost = read_extended_number(v.at("initial_cost"));
  r.final_cost = read_extended_number(v.at("final_cost"));
  r.seconds = read_extended_number(v.at("seconds"));
  r.status = v.at("status").as_string();
  r.data_names = read_string_list(v.at("data_names"));
  const Eigen::VectorXd f = read_extended_vector(v.at("fit_percent"));
  r.fit_percent.assign(f.data(), f.data() + f.size());
  const JsonView x0 = v.at("initial_states");
  for (std::size_t i = 0; i < x0.as_array().size(); ++i) r.initial_states.push_back(read_extended_vector(x0.at(i)));
  return r;
}

/// The estimation report of a linear model as JSON.
[[nodiscard]] inline Json linear_report_to_json(const LinearEstimationReport& r) {
  Json j = Json::object();
  j["method"] = r.method;
  j["focus"] = r.focus;
  j["num_experiments"] = r.num_experiments;
  j["num_samples"] = static_cast<long long>(r.num_samples);
  j["num_parameters"] = r.num_parameters;
  j["loss"] = extended_number(r.loss);
  j["fit_percent"] = extended_number(r.fit_percent);
  if (!r.fit_per_output.empty())
    j["fit_per_output"] = extended_vector(Eigen::Map<const Eigen::VectorXd>(
        r.fit_per_output.data(), static_cast<Eigen::Index>(r.fit_per_output.size())));
  j["iterations"] = r.iterations;
  j["solver_message"] = r.solver_message;
  return j;
}

/// Reads `linear_report_to_json`.
[[nodiscard]] inline LinearEstimationReport linear_report_from_json(const JsonView& v) {
  v.check_keys({"method", "focus", "num_experiments", "num_samples", "num_parameters", "loss", "fit_percent",
                "fit_per_output", "iterations", "solver_message"});
  LinearEstimationReport r;
  r.method = v.at("method").as_string();
  r.focus = v.at("focus").as_string();
  r.num_experiments = read_int(v.at("num_experiments"), 0, std::numeric_limits<int>::max());
  r.num_samples = static_cast<Eigen::Index>(v.at("num_samples").as_integer());
  r.num_parameters = read_int(v.at("num_parameters"), 0, std::numeric_limits<int>::max());
  r.loss = read_extended_number(v.at("loss"));
  r.fit_percent = read_extended_number(v.at("fit_percent"));
  if (v.contains("fit_per_output")) {  // per output channel (files before it have the scalar only)
    const Eigen::VectorXd f = read_extended_vector(v.at("fit_per_output"));
    r.fit_per_output.assign(f.data(), f.data() + f.size());
  }
  r.iterations = read_int(v.at("iterations"), 0, std::numeric_limits<int>::max());
  r.solver_message = v.at("solver_message").as_string();
  return r;
}

namespace detail {
/// Runs `fn`, which builds part of a model from values read at `where` (a nonlinearity from its
/// sizes, a linear model or grey box from its structure); an error of the constructor, which
/// knows no file (sizes it refuses, such as more parameters than `max_nonlinearity_parameters`),
/// is rethrown located at `where`: file, key path, line and column.
template <class Fn>
auto located(const JsonView& where, Fn&& fn) {
  try {
    return fn();
  } catch (const Error& e) {
    if (!e.where().file.empty()) throw;
    where.fail(e.message() + " (at " + where.path_text() + ")");
  }
}
}  // namespace detail

}  // namespace nlid
