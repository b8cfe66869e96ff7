#pragma once
/// @file
/// Showing a diagnosis: the JSON document for machines, the self-contained HTML report for
/// people, and the short text summary the command-line tool prints.
///
/// JSON (keys required by issue 4 marked *; the rest are extras a script may use):
///
///     { "baseline":   { "name", "fit_est"*: [..], "fit_val"*: [..], "parameters": {..} },
///       "noise_floor": { "sigma", "raw_sigma", "quantisation", "inflation", "method" },
///       "mismatch"*:  { "intervals"*: [{ "experiment"*, "name", "t0"*, "t1"*, "energy_share"*,
///                                        "rms_ratio" }],
///                       "regions"*:   [{ "variable"*, "label", "range"*: [a, b],
///                                        "energy_share"*, "excess_share", "sample_share" }],
///                       "residual_rms", "excess_share", "floor_ratio", "consistent_with_noise" },
///       "candidates"*: [{ "name"*, "variant", "round", "fit_val"*: [..], "fit_est", "score"*,
///                         "z", "relevance", "significant", "refined" (refitted to convergence:
///                         only these can be accepted), "accepted", "params",
///                         "error" (a candidate that could not be fitted or simulated) }],
///       "effects"*:    [{ "name"*, "variant", "params"*: {..}, "units", "fit_val_before"*: [..],
///                         "fit_val_after"*: [..], "round", "description" }],
///       "inert_effects": [{ "name", "variant", "params", "round" }] (added, then made inactive
///                         by the joint re-estimation, and removed),
///       "final"*:      { "fit_est", "fit_val"*: [..], "parameters": {..}, "floor_ratio",
///                        "consistent_with_noise" },
///       "not_applicable": [..], "records": { "estimation": [..], "validation": [..] },
///       "sample_time", "stop" (SearchStop's name), "stop_reason", "explanation"*, "seconds" }
///
/// Fit values are percent per experiment (estimation or validation records, in the order
/// given). `energy_share` is the share of the residual energy Σε² of the validation records
/// inside an interval or region; `score` is the validation BIC gain of a candidate
/// (significance.hpp), positive = worth its parameters. Non-finite numbers (a candidate whose
/// simulation diverged) are written as null: JSON has no NaN.
///
/// HTML. One `HtmlReport` (io/html_report.hpp): the explanation; the fit table before/after;
/// per validation record a chart of measured, baseline and repaired output, and a chart of both
/// residuals with the located mismatch intervals shaded and the ±2σ noise band drawn; a bar chart
/// of the first round's candidate scores; the ranked candidate table of every round; the
/// operating-region table; the repaired model with units; the baseline multi-start summary.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/atomic_file.hpp"
#include "nlid/core/format.hpp"
#include "nlid/diagnose/diagnose.hpp"
#include "nlid/io/html_report.hpp"
#include "nlid/io/json.hpp"
#include "nlid/io/svg_chart.hpp"

namespace nlid {

/// The diagnosis as a JSON document (see the file comment for the keys).
template <Physics P>
Json diagnosis_json(const Diagnosis<P>& d);

/// Writes `diagnosis_json(d)` (indented) to `path`, atomically.
template <Physics P>
void write_diagnosis_json(const Diagnosis<P>& d, const std::string& path) {
  write_file_atomically(path, diagnosis_json(d).dump(2) + "\n");
}

/// The diagnosis as a self-contained HTML report (see the file comment). `chart_count()` of the
/// result is the number of charts a browser must render.
template <Physics P>
HtmlReport diagnosis_report(const Diagnosis<P>& d);

/// Writes `diagnosis_report(d)` to `path`, atomically; returns the number of charts in it.
template <Physics P>
std::size_t write_diagnosis_html(const Diagnosis<P>& d, const std::string& path) {
  const HtmlReport r = diagnosis_report(d);
  r.write(path);
  return r.chart_count();
}

/// A few lines for a terminal: baseline and final fits, effects found with parameters, and the
/// explanation.
template <Physics P>
std::string diagnosis_summary(const Diagnosis<P>& d);

// ------------------------------------------------------------------------------------------
// Implementation details below.
// ------------------------------------------------------------------------------------------

namespace detail {

inline Json json_number(double v) { return std::isfinite(v) ? Json(v) : Json(nullptr); }

inline Json json_numbers(const Eigen::VectorXd& v) {
  Json a = Json::array();
  for (Eigen::Index i = 0; i < v.size(); ++i) a.push_back(json_number(v(i)));
  return a;
}

inline Json json_parameters(const std::vector<ParameterInfo>& info, const std::string& yu, const std::string& uu) {
  Json o = Json::object();
  for (const ParameterInfo& q : info) {
    Json p = Json::object();
    p["value"] = json_number(q.value);
    p["unit"] = substitute_units(q.unit, yu, uu);
    if (q.fixed) p["fixed"] = true;
    o[q.name] = std::move(p);
  }
  return o;
}

inline Json json_effect_params(const Effect& e) {
  Json o = Json::object();
  for (const ParameterInfo& q : e.params) o[q.name] = json_number(q.value);
  return o;
}

inline std::string fit_cell(double v) {
  if (!std::isfinite(v)) return "diverged";
  return format_f(v, 1);
}

inline std::vector<double> to_std(const Eigen::VectorXd& v) { return std::vector<double>(v.data(), v.data() + v.size()); }

inline std::string record_name(const Dataset& d, std::size_t e) {
  return d[e].name().empty() ? "record " + std::to_string(e) : d[e].name();
}

}  // namespace detail

template <Physics P>
Json diagnosis_json(const Diagnosis<P>& d) {
  using detail::json_number;
  using detail::json_numbers;
  const std::string yu = d.model.output_unit(), uu = d.model.input_unit();
  Json j = Json::object();

  Json& b = j["baseline"];
  b["name"] = d.baseline_name;
  b["fit_est"] = json_numbers(d.baseline_est.fit);
  b["fit_val"] = json_numbers(d.baseline_val.fit);
  b["parameters"] = detail::json_parameters(d.baseline.parameter_info(), yu, uu);

  Json& nf = j["noise_floor"];
  nf["sigma"] = json_number(d.noise.sigma);
  nf["raw_sigma"] = json_number(d.noise.raw_sigma);
  nf["quantisation"] = json_number(d.noise.quantisation);
  nf["inflation"] = json_number(d.noise.inflation);
  nf["method"] = d.noise.method;

  Json& m = j["mismatch"];
  m["intervals"] = Json::array();
  for (const MismatchInterval& iv : d.mismatch.intervals) {
    Json o = Json::object();
    o["experiment"] = iv.experiment;
    o["name"] = iv.name;
    o["t0"] = json_number(iv.t0);
    o["t1"] = json_number(iv.t1);
    o["energy_share"] = json_number(iv.energy_share);
    o["rms_ratio"] = json_number(iv.rms_ratio);
    m["intervals"].push_back(std::move(o));
  }
  m["regions"] = Json::array();
  for (const MismatchRegion& r : d.mismatch.regions) {
    Json o = Json::object();
    o["variable"] = r.variable;
    o["label"] = r.label;
    Json range = Json::array();
    range.push_back(json_number(r.lo));
    range.push_back(json_number(r.hi));
    o["range"] = std::move(range);
    o["energy_share"] = json_number(r.energy_share);
    o["excess_share"] = json_number(r.excess_share);
    o["sample_share"] = json_number(r.sample_share);
    m["regions"].push_back(std::move(o));
  }
  m["residual_rms"] = json_number(d.mismatch.residual_rms);
  m["excess_share"] = json_number(d.mismatch.excess_share);
  m["floor_ratio"] = json_number(d.floor_before.ratio);
  m["consistent_with_noise"] = d.floor_before.consistent;

  j["candidates"] = Json::array();
  for (const SearchRound& r : d.rounds) {
    for (std::size_t i = 0; i < r.candidates.size(); ++i) {
      const CandidateResult& c = r.candidates[i];
      Json o = Json::object();
      o["name"] = c.effect.name();
      if (!c.effect.variant.empty()) o["variant"] = c.effect.variant;
      o["round"] = r.round;
      o["fit_val"] = c.ok ? json_numbers(c.fit_val) : Json(nullptr);
      o["fit_est"] = c.ok ? json_numbers(c.fit_est) : Json(nullptr);
      o["score"] = c.ok ? json_number(c.stats.score) : Json(nullptr);
      o["z"] = c.ok ? json_number(c.stats.z) : Json(nullptr);
      o["relevance"] = c.ok ? json_number(c.stats.relevance) : Json(nullptr);
      o["significant"] = c.ok && c.stats.significant;
      o["refined"] = c.refined;
      o["accepted"] = static_cast<int>(i) == r.accepted;
      o["params"] = detail::json_effect_params(c.effect);
      if (!c.ok) o["error"] = c.error;
      j["candidates"].push_back(std::move(o));
    }
  }

  // Added by the search, then made inactive by the joint re-estimation and removed.
  j["inert_effects"] = Json::array();
  for (const FoundEffect& f : d.inert) {
    Json o = Json::object();
    o["name"] = f.effect.name();
    if (!f.effect.variant.empty()) o["variant"] = f.effect.variant;
    o["params"] = detail::json_effect_params(f.effect);
    o["round"] = f.round;
    j["inert_effects"].push_back(std::move(o));
  }

  j["effects"] = Json::array();
  for (const FoundEffect& f : d.effects) {
    Json o = Json::object();
    o["name"] = f.effect.name();
    if (!f.effect.variant.empty()) o["variant"] = f.effect.variant;
    o["params"] = detail::json_effect_params(f.effect);
    Json units = Json::object();
    for (const ParameterInfo& q : f.effect.params) units[q.name] = detail::substitute_units(q.unit, yu, uu);
    o["units"] = std::move(units);
    o["fit_val_before"] = json_numbers(f.fit_val_before);
    o["fit_val_after"] = json_numbers(f.fit_val_after);
    o["round"] = f.round;
    o["description"] = effect_description(f.effect.kind);
    j["effects"].push_back(std::move(o));
  }

  Json& fin = j["final"];
  fin["fit_est"] = json_numbers(d.final_est.fit);
  fin["fit_val"] = json_numbers(d.final_val.fit);
  fin["parameters"] = detail::json_parameters(d.model.parameter_info(), yu, uu);
  fin["floor_ratio"] = json_number(d.floor_after.ratio);
  fin["consistent_with_noise"] = d.floor_after.consistent;

  Json na = Json::array();
  for (const std::string& s : d.not_applicable) na.push_back(s);
  j["not_applicable"] = std::move(na);
  Json names = Json::object();
  Json en = Json::array(), vn = Json::array();
  for (std::size_t e = 0; e < d.estimation.size(); ++e) en.push_back(detail::record_name(d.estimation, e));
  for (std::size_t e = 0; e < d.validation.size(); ++e) vn.push_back(detail::record_name(d.validation, e));
  names["estimation"] = std::move(en);
  names["validation"] = std::move(vn);
  j["records"] = std::move(names);
  j["sample_time"] = json_number(d.estimation.size() > 0 ? d.estimation.ts() : 0.0);
  j["stop"] = search_stop_name(d.stop);
  j["stop_reason"] = d.stop_reason;
  j["explanation"] = d.explanation;
  j["seconds"] = json_number(d.seconds);
  return j;
}

template <Physics P>
HtmlReport diagnosis_report(const Diagnosis<P>& d) {
  const std::string yu = d.model.output_unit(), uu = d.model.input_unit();
  const std::string Y = yu.empty() ? "y" : "y (" + yu + ")";
  HtmlReport r("Missing-physics diagnosis: " + d.baseline_name);
  r.note(d.explanation, d.effects.empty() ? NoteKind::info : NoteKind::warning);

  // Fit table.
  r.heading("Fit before and after");
  {
    std::vector<std::vector<TableCell>> rows;
    for (std::size_t e = 0; e < d.estimation.size(); ++e)
      rows.push_back({detail::record_name(d.estimation, e), "estimation",
                      detail::fit_cell(d.baseline_est.fit(static_cast<Eigen::Index>(e))),
                      detail::fit_cell(d.final_est.fit(static_cast<Eigen::Index>(e)))});
    for (std::size_t e = 0; e < d.validation.size(); ++e)
      rows.push_back({detail::record_name(d.validation, e), "validation",
                      detail::fit_cell(d.baseline_val.fit(static_cast<Eigen::Index>(e))),
                      detail::fit_cell(d.final_val.fit(static_cast<Eigen::Index>(e)))});
    r.table({"record", "role", "baseline fit %", "repaired fit %"}, std::move(rows));
  }
  r.paragraph("Fit = 100 (1 - |y - yhat| / |y - mean(y)|) of the free-run simulation from the input alone; "
              "initial states fitted per record. Noise floor sigma = " + detail::g3(d.noise.sigma) + " " + yu +
              " (" + d.noise.method + (d.noise.quantisation > 0 ? ", quantisation " + detail::g3(d.noise.quantisation) : std::string()) +
              "); validation residual energy / noise energy: baseline " + detail::g3(d.floor_before.ratio) +
              ", repaired " + detail::g3(d.floor_after.ratio) + ".");

  // Charts per validation record.
  r.heading("Validation records");
  for (std::size_t e = 0; e < d.validation.size(); ++e) {
    const Experiment& x = d.validation[e];
    const Eigen::VectorXd t = x.time();
    const Eigen::VectorXd y = x.y().col(0);
    const std::string name = detail::record_name(d.validation, e);
    LineChart c("Output: " + name);
    c.x_label("time (s)").y_label(Y);
    c.line("measured", t, y, "black", LineStyle::solid, 1.2);
    c.line("baseline (fit " + detail::fit_cell(d.baseline_val.fit(static_cast<Eigen::Index>(e))) + " %)", t,
           d.baseline_val.yhat[e], "#d62728", LineStyle::dashed);
    c.line("repaired (fit " + detail::fit_cell(d.final_val.fit(static_cast<Eigen::Index>(e))) + " %)", t,
           d.final_val.yhat[e], "#1f77b4", LineStyle::solid);
    r.chart(c);
    LineChart res("Residual y - yhat: " + name);
    res.x_label("time (s)").y_label(Y);
    res.line("baseline", t, Eigen::VectorXd(y - d.baseline_val.yhat[e]), "#d62728", LineStyle::solid, 1.0);
    res.line("repaired", t, Eigen::VectorXd(y - d.final_val.yhat[e]), "#1f77b4", LineStyle::solid, 1.0);
    res.band(-2.0 * d.noise.sigma, 2.0 * d.noise.sigma, "noise floor +/-2 sigma");
    for (const MismatchInterval& iv : d.mismatch.intervals)
      if (iv.experiment == static_cast<int>(e)) res.shade(iv.t0, iv.t1);
    r.chart(res, "Shaded: intervals where the baseline residual exceeds the noise floor.");
  }

  // Candidates.
  r.heading("Candidate effects");
  if (!d.rounds.empty() && !d.rounds.front().candidates.empty()) {
    BarChart bc("Round 1: validation score of each candidate (BIC gain; > 0 worth its parameters)");
    bc.horizontal(true).value_label("score");
    const SearchRound& r1 = d.rounds.front();
    for (std::size_t i = 0; i < r1.candidates.size(); ++i) {
      const CandidateResult& c = r1.candidates[i];
      const double v = c.ok && std::isfinite(c.stats.score) ? c.stats.score : std::nan("");
      bc.add(c.effect.label(), v);
    }
    if (r1.accepted >= 0) bc.highlight(static_cast<std::size_t>(r1.accepted));
    bc.size(720, std::max(240, 26 * static_cast<int>(r1.candidates.size()) + 80));
    r.chart(bc);
  }
  for (const SearchRound& rr : d.rounds) {
    std::vector<std::vector<TableCell>> rows;
    for (std::size_t i = 0; i < rr.candidates.size(); ++i) {
      const CandidateResult& c = rr.candidates[i];
      std::string fits, gain;
      for (Eigen::Index k = 0; k < c.fit_val.size(); ++k) {
        fits += (k ? " / " : "") + detail::fit_cell(c.fit_val(k));
        if (k < rr.fit_val_before.size()) {
          gain += (k ? " / " : "") + detail::with_plus(detail::format_f(c.fit_val(k) - rr.fit_val_before(k), 1));
        }
      }
      rows.push_back({static_cast<int>(i + 1), c.effect.label(), c.ok ? fits : "failed: " + c.error, gain,
                      c.ok ? TableCell(c.stats.score) : TableCell("-"), c.ok ? TableCell(c.stats.z) : TableCell("-"),
                      c.ok ? TableCell(c.stats.relevance) : TableCell("-"),
                      static_cast<int>(i) == rr.accepted ? "added"
                      : !c.ok                                ? ""
                      : c.stats.significant && !c.refined
                          ? "significant on its screening fit; not refitted (estimation cost not among the lowest)"
                      : c.stats.significant ? "significant"
                                            : ""});
    }
    ReportTable t;
    t.header = {"rank", "effect", "validation fit %", "gain (points)", "score", "z", "share of excess", "verdict"};
    t.rows = std::move(rows);
    t.caption = "Round " + std::to_string(rr.round) + " (entering model: validation fit " +
                detail::fits_text(rr.fit_val_before) + ")";
    t.digits = 3;
    if (!rr.candidates.empty()) r.table(std::move(t));
  }
  r.paragraph("Stop: " + d.stop_reason + ".");
  if (!d.not_applicable.empty()) {
    std::string s;
    for (const std::string& n : d.not_applicable) s += (s.empty() ? "" : "\n") + n;
    r.paragraph("Not applicable to this baseline:\n" + s);
  }

  // Regions.
  r.heading("Where the baseline misses");
  {
    std::vector<std::vector<TableCell>> rows;
    for (const MismatchRegion& m : d.mismatch.regions)
      rows.push_back({m.variable, m.label, m.lo, m.hi, m.energy_share, m.excess_share, m.sample_share});
    ReportTable t;
    t.header = {"variable", "bin", "from", "to", "energy share", "excess share", "sample share"};
    t.rows = std::move(rows);
    t.caption = "Operating regions of the validation records (excess = residual energy above the noise floor).";
    t.digits = 3;
    r.table(std::move(t));
    std::vector<std::vector<TableCell>> iv;
    for (const MismatchInterval& m : d.mismatch.intervals)
      iv.push_back({detail::record_name(d.validation, static_cast<std::size_t>(m.experiment)), m.t0, m.t1, m.energy_share, m.rms_ratio});
    if (!iv.empty())
      r.table({"record", "t0 (s)", "t1 (s)", "energy share", "RMS / sigma"}, std::move(iv),
              "Intervals where the baseline residual exceeds the noise floor.", 3);
  }

  // Models.
  r.heading("Repaired model");
  r.preformatted(d.model.describe());
  if (!d.baseline_report.empty()) {
    r.heading("Baseline estimation");
    r.preformatted(d.baseline.describe() + "\n" + d.baseline_report);
  }
  return r;
}

template <Physics P>
std::string diagnosis_summary(const Diagnosis<P>& d) {
  std::string s = "baseline " + d.baseline_name + ": validation fit " + detail::fits_text(d.baseline_val.fit) + "\n";
  if (d.effects.empty()) s += "effects added: none\n";
  for (const FoundEffect& f : d.effects) {
    s += "added " + f.effect.label() + ":";
    for (const ParameterInfo& q : f.effect.params)
      s += " " + q.name + " = " + detail::g3(q.value) + " " +
           detail::substitute_units(q.unit, d.model.output_unit(), d.model.input_unit());
    s += "  (validation fit " + detail::fits_text(f.fit_val_before) + " -> " + detail::fits_text(f.fit_val_after) + ")\n";
  }
  s += "final: validation fit " + detail::fits_text(d.final_val.fit) + "\n";
  s += d.explanation + "\n";
  return s;
}

}  // namespace nlid
