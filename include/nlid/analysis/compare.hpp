#pragma once
/// @file
/// Compare a model's simulated output with measured data: the fit per experiment and output.
///
/// For each experiment e of a data set and each output j, the model is simulated from the
/// experiment's inputs alone (free run, from the chosen `InitialCondition`), and scored by
///
///     fit_ej = 100 · (1 − ‖y_ej − ŷ_ej‖ / ‖y_ej − mean(y_ej)‖)   [%]       (analysis/fit.hpp)
///
/// as the toolbox's `compare` does (Ljung 1999, §16.6). Validation means doing this on data the
/// model was not estimated on. The result keeps the simulated outputs for plotting and prints
/// as a table; `FitTable` collects the results of several models into one table (models as
/// rows, experiments as columns), the form in which the study reports its models.
///
/// A model whose simulation diverges on an experiment is a result, not an error: its fit there
/// is −∞ (the table prints "diverged at sample k"), as in the toolbox's compare plot, so one
/// unstable candidate does not abort a comparison of several. A diverging simulation is a
/// `DivergenceError` or, for models that do not check (linear models, most grey boxes), an
/// output that overflows to inf/NaN: the first such sample is where it diverged. Other errors are located: a
/// simulation that returns the wrong shape, or an output that is constant in some experiment,
/// throws `nlid::Error` naming the experiment.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <ostream>
#include <locale>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "nlid/analysis/concepts.hpp"
#include "nlid/analysis/fit.hpp"
#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/core/initial_condition.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/linear/concepts.hpp"

namespace nlid {

namespace detail {
// Policy name for tables. (models/ has a public nlid::to_string for it; not reused here so this
// header does not depend on the models layer.)
inline const char* initial_condition_name(InitialCondition ic) {
  switch (ic) {
    case InitialCondition::zero: return "zero";
    case InitialCondition::estimate: return "estimate";
    case InitialCondition::equilibrium: return "equilibrium";
    case InitialCondition::measured: return "measured";
  }
  return "?";
}
}  // namespace detail

/// Outcome of `compare`: fit (%) per experiment and output, and the simulated outputs.
struct CompareResult {
  std::vector<std::string> experiment_names;  ///< one per experiment ("experiment k" if unnamed)
  std::vector<std::string> output_names;      ///< one per output channel
  Eigen::MatrixXd fit;                        ///< experiments x outputs, percent (−∞: diverged)
  /// Per experiment, N x ny simulated output; empty (0 x 0) where the simulation diverged.
  std::vector<Eigen::MatrixXd> simulated;
  /// Per experiment, the first sample (0-based) at which a model that threw
  /// `DivergenceError` stopped being finite; −1 where it did not.
  std::vector<long> diverged_at;
  InitialCondition initial_condition = InitialCondition::zero;  ///< policy used (simulation)
  /// 0: free-run simulation (`compare`); k ≥ 1: k-step-ahead prediction (`compare_prediction`).
  int horizon = 0;

  /// Fit of experiment `e`, output `j`; throws if out of range.
  [[nodiscard]] double fit_of(std::size_t e, int j = 0) const {
    require(e < experiment_names.size() && j >= 0 && j < fit.cols(),
            "CompareResult: experiment " + std::to_string(e) + ", output " + std::to_string(j) +
                " out of range",
            at_experiment(static_cast<long>(e)));
    return fit(static_cast<Eigen::Index>(e), j);
  }

  /// Table: one row per experiment, one column per output, fit in percent.
  [[nodiscard]] std::string table() const {
    std::ostringstream os;
    os.imbue(std::locale::classic());  // a global locale's grouping or decimal comma must not reach the text
    char buf[128];
    if (horizon == infinite_horizon) {
      os << "Fit (%) of the output predicted infinitely many steps ahead (simulated from measured past data)\n";
    } else if (horizon > 0) {
      os << "Fit (%) of the " << horizon << "-step-ahead predicted output\n";
    } else {
      os << "Fit (%) of the simulated output, initial condition '"
         << detail::initial_condition_name(initial_condition) << "'\n";
    }
    std::snprintf(buf, sizeof buf, "%-20s", "experiment");
    os << buf;
    for (const auto& n : output_names) {
      std::snprintf(buf, sizeof buf, " %10s", n.c_str());
      os << buf;
    }
    os << "\n";
    for (std::size_t e = 0; e < experiment_names.size(); ++e) {
      std::snprintf(buf, sizeof buf, "%-20s", experiment_names[e].c_str());
      os << buf;
      for (Eigen::Index j = 0; j < fit.cols(); ++j) {
        const double f = fit(static_cast<Eigen::Index>(e), j);
        os << ' '
           << detail::right_aligned(f == -std::numeric_limits<double>::infinity() ? "diverged" : detail::format_f(f, 2),
                                    10);
      }
      if (e < diverged_at.size() && diverged_at[e] >= 0) os << "  (diverged at sample " << diverged_at[e] << ")";
      os << "\n";
    }
    return os.str();
  }
};

/// Prints `r.table()`.
inline std::ostream& operator<<(std::ostream& os, const CompareResult& r) { return os << r.table(); }

namespace detail {

// The loop of `compare` and `compare_prediction`: `output(e)` is the model's N × n_y answer for
// experiment e (it may throw DivergenceError).
template <class Output>
CompareResult compare_each(const Dataset& data, CompareResult r, const Output& output) {
  require(data.size() > 0, "compare: the data set is empty", at_parameter("data"));
  r.output_names = data[0].output_names();
  r.fit.resize(static_cast<Eigen::Index>(data.size()), data.num_outputs());
  for (std::size_t e = 0; e < data.size(); ++e) {
    const Experiment& ex = data[e];
    const std::string label =
        ex.name().empty() ? "experiment " + std::to_string(e) : ex.name();
    r.experiment_names.push_back(label);
    Eigen::MatrixXd yhat;
    try {
      yhat = output(ex);
    } catch (const DivergenceError& d) {
      r.fit.row(static_cast<Eigen::Index>(e)).setConstant(-std::numeric_limits<double>::infinity());
      r.simulated.emplace_back();
      r.diverged_at.push_back(d.sample());
      continue;
    }
    if (yhat.rows() != ex.size() || yhat.cols() != ex.num_outputs())
      throw Error("compare: model returned a " + std::to_string(yhat.rows()) + " x " +
                      std::to_string(yhat.cols()) + " output for experiment " +
                      std::to_string(e) + " ('" + label + "') with " +
                      std::to_string(ex.size()) + " samples and " +
                      std::to_string(ex.num_outputs()) + " output(s)",
                  at_experiment(static_cast<long>(e)));
    // Models that do not throw DivergenceError (linear models, most grey boxes) let an unstable
    // simulation overflow to inf/NaN: the same result as a divergence, from the first such row.
    Eigen::Index bad = 0;
    while (bad < yhat.rows() && yhat.row(bad).allFinite()) ++bad;
    if (bad < yhat.rows()) {
      r.fit.row(static_cast<Eigen::Index>(e)).setConstant(-std::numeric_limits<double>::infinity());
      r.simulated.emplace_back();
      r.diverged_at.push_back(static_cast<long>(bad));
      continue;
    }
    r.diverged_at.push_back(-1);
    try {
      r.fit.row(static_cast<Eigen::Index>(e)) = fit_percent(ex.y(), yhat).transpose();
    } catch (const Error& err) {
      Location l = err.where();
      l.experiment = static_cast<long>(e);
      throw Error("compare: experiment '" + label + "': " + err.message(), l);
    }
    r.simulated.push_back(std::move(yhat));
  }
  return r;
}

}  // namespace detail

/// Simulates `model` on every experiment of `data` from `ic` and scores it (see file comment).
/// The default start is `zero`, which costs nothing and lets a model's own transient count; the
/// toolbox's `compare` estimates the initial state by default — pass `InitialCondition::estimate`
/// for its numbers (the study does).
/// Throws `nlid::Error` naming the experiment if the simulated output has the wrong shape or a
/// measured output is constant; errors of the model's own checks pass through.
template <SimulationModel M>
CompareResult compare(const M& model, const Dataset& data,
                      InitialCondition ic = InitialCondition::zero) {
  CompareResult r;
  r.initial_condition = ic;
  return detail::compare_each(data, std::move(r), [&](const Experiment& ex) { return model.simulate(ex, ic); });
}

/// Fit of the k-step-ahead prediction ŷ(t | t − k) on every experiment (the toolbox's
/// `compare(data, sys, k)`): the model is run k samples from the measured past, so k = 1 scores
/// the one-step predictor and a k beyond the record the simulation from measured past data. The
/// first samples, which have no past to predict from, are the measured ones (each model's
/// `predict`) and count in the fit, which they raise on a short record; models without a noise
/// model (output error, Hammerstein–Wiener) predict by simulating, whatever k. Result as
/// `compare`, with `horizon` = k (the simulated outputs hold the predictions). Throws
/// `nlid::Error` naming "k" if k < 1.
template <KStepPredictor M>
CompareResult compare_prediction(const M& model, const Dataset& data, int k) {
  require(k >= 1, "compare_prediction: the horizon k must be >= 1, got " + std::to_string(k), at_parameter("k"));
  CompareResult r;
  r.horizon = k;
  return detail::compare_each(data, std::move(r), [&](const Experiment& ex) { return model.predict(ex, k); });
}

/// Fit (%) of several models on several experiments, printed as one table (models as rows).
/// Experiments are columns in order of first appearance (matched by name); a model not
/// compared on an experiment shows "-". With several outputs, columns are experiment/output.
/// A row from `compare_prediction` says its horizon after the name ("arx221 (k = 1)"): a
/// one-step fit beside free-run fits is otherwise read as a far better model.
class FitTable {
 public:
  /// Adds the results of one model under `model_name`.
  void add(std::string model_name, const CompareResult& r) {
    Row row;
    row.name = std::move(model_name);
    if (r.horizon > 0)
      row.name += " (k = " + (r.horizon == infinite_horizon ? std::string("inf") : std::to_string(r.horizon)) + ")";
    for (std::size_t e = 0; e < r.experiment_names.size(); ++e)
      for (Eigen::Index j = 0; j < r.fit.cols(); ++j) {
        std::string col = r.experiment_names[e];
        if (r.fit.cols() > 1) col += "/" + r.output_names[static_cast<std::size_t>(j)];
        std::size_t k = 0;
        while (k < columns_.size() && columns_[k] != col) ++k;
        if (k == columns_.size()) columns_.push_back(col);
        row.cells.emplace_back(k, r.fit(static_cast<Eigen::Index>(e), j));
      }
    rows_.push_back(std::move(row));
  }

  /// The table as text, e.g. "model | data3lin | data2lin".
  [[nodiscard]] std::string str() const {
    std::size_t wname = 5;
    for (const auto& r : rows_) wname = std::max(wname, r.name.size());
    std::vector<std::size_t> w;
    for (const auto& c : columns_) w.push_back(std::max<std::size_t>(9, c.size()));
    std::ostringstream os;
    os.imbue(std::locale::classic());  // a global locale's grouping or decimal comma must not reach the text
    os << detail::left_aligned("model", wname);
    for (std::size_t k = 0; k < columns_.size(); ++k) os << " | " << detail::right_aligned(columns_[k], w[k]);
    os << "\n" << std::string(wname, '-');
    for (std::size_t k = 0; k < columns_.size(); ++k) os << "-+-" << std::string(w[k], '-');
    os << "\n";
    for (const auto& r : rows_) {
      os << detail::left_aligned(r.name, wname);
      for (std::size_t k = 0; k < columns_.size(); ++k) {
        std::string cell = "-";
        for (const auto& [col, v] : r.cells)
          if (col == k) {
            cell = v == -std::numeric_limits<double>::infinity() ? std::string("diverged")
                                                                 : detail::format_f(v, 1) + " %";
          }
        os << " | " << detail::right_aligned(cell, w[k]);
      }
      os << "\n";
    }
    return os.str();
  }

 private:
  struct Row {
    std::string name;
    std::vector<std::pair<std::size_t, double>> cells;
  };
  std::vector<std::string> columns_;
  std::vector<Row> rows_;
};

/// Prints `t.str()`.
inline std::ostream& operator<<(std::ostream& os, const FitTable& t) { return os << t.str(); }

}  // namespace nlid
