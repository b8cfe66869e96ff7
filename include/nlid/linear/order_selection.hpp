#pragma once
/// @file
/// ARX order selection: loss and information criteria over a grid of orders [na nb nk].
///
/// For every candidate in the grid an ARX model is estimated by least squares and scored by
///
///     V   = (1/N) Σ ε(t)²        one-step prediction error on the estimation data
///     AIC = N log V + 2d,   MDL = N log V + d log N          (report.hpp; Ljung 1999, §16.4)
///
/// with d = na + Σ nb (+1 with an offset). All candidates use the *same* N samples: rows start at
/// the largest lag of the whole grid in every experiment, so criteria of different orders are
/// comparable (the toolbox's `arxstruc` does the same). With validation data the table also
/// holds the one-step prediction loss on it (the toolbox's cross-validation criterion) and the
/// simulation fit (%), the study's "simulation focus" view.
///
/// The result prints as a table, and as an ASCII version of the toolbox's order-selection plot:
/// the best model for each number of parameters, its bar showing the unexplained output
/// variance 100·V/var(y) in percent, the AIC and MDL choices marked.
///
/// For several inputs, nb and nk of a candidate apply to every input.
///
/// `delayest` is the toolbox's function of that name on the same machinery: ARX [na nb nk] for
/// each delay nk of a range, all on the same rows; equal parameter counts make the smallest loss
/// also the smallest AIC and MDL, so the delay with the smallest loss is the estimate.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <locale>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/core/sizes.hpp"
#include "nlid/core/initial_condition.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/linear/arx.hpp"
#include "nlid/linear/report.hpp"

namespace nlid {

/// The orders to try: every combination of the listed na, nb and nk values.
struct ArxOrderGrid {
  std::vector<int> na{1, 2, 3, 4};  ///< candidate numbers of poles
  std::vector<int> nb{1, 2, 3, 4};  ///< candidate numbers of B coefficients (every input)
  std::vector<int> nk{0, 1, 2};     ///< candidate delays (every input)
};

/// Criterion by which a candidate is "best".
enum class OrderCriterion {
  aic,              ///< smallest AIC on the estimation data
  mdl,              ///< smallest MDL on the estimation data
  validation_loss,  ///< smallest one-step prediction loss on the validation data
  validation_fit,   ///< largest simulation fit (%) on the validation data
};

/// Name of a criterion ("AIC", "MDL", "validation loss", "validation fit").
inline const char* to_string(OrderCriterion c) {
  switch (c) {
    case OrderCriterion::aic: return "AIC";
    case OrderCriterion::mdl: return "MDL";
    case OrderCriterion::validation_loss: return "validation loss";
    case OrderCriterion::validation_fit: return "validation fit";
  }
  return "?";
}

/// One row of the order-selection table.
struct OrderCandidate {
  ArxOrders orders;                       ///< [na nb nk]
  int num_parameters = 0;                 ///< d
  bool valid = true;                      ///< false if the regression was rank deficient
  /// V on the estimation data; also for a rank-deficient candidate (a basic solution reaches the
  /// least-squares minimum), where the criteria below are not computed.
  double loss = 0.0;
  double aic = 0.0;                       ///< N log V + 2d
  double mdl = 0.0;                       ///< N log V + d log N
  std::optional<double> validation_loss;  ///< one-step V on the validation data
  /// Simulation fit (%) on the validation data, initial state estimated: 100 (1 − √(Σ‖y − ŷ‖² /
  /// Σ‖y − ȳ‖²)) summed over the records, each about its own mean (one record: `compare`'s fit).
  std::optional<double> validation_fit;
};

/// The order-selection table with the best candidate by each criterion.
struct OrderSelection {
  std::vector<OrderCandidate> candidates;  ///< grid order: na outermost, then nb, then nk
  Eigen::Index num_samples = 0;            ///< N: residuals per candidate (all experiments)
  int first_row = 0;                       ///< per experiment, rows start at this sample
  double output_variance = 0.0;            ///< variance of y on those rows (for "% unexplained")
  bool has_validation = false;             ///< validation columns filled

  /// Index of the best valid candidate by `c`. Throws if `c` needs validation data that were not
  /// given, or if no candidate is valid.
  [[nodiscard]] std::size_t best_index(OrderCriterion c) const {
    require(has_validation || (c != OrderCriterion::validation_loss &&
                               c != OrderCriterion::validation_fit),
            std::string("OrderSelection: criterion '") + to_string(c) +
                "' needs validation data",
            at_parameter("criterion"));
    std::size_t best = candidates.size();
    double best_v = 0;
    for (std::size_t k = 0; k < candidates.size(); ++k) {
      const OrderCandidate& x = candidates[k];
      if (!x.valid) continue;
      double v = 0;
      switch (c) {
        case OrderCriterion::aic: v = x.aic; break;
        case OrderCriterion::mdl: v = x.mdl; break;
        case OrderCriterion::validation_loss: v = *x.validation_loss; break;
        case OrderCriterion::validation_fit: v = -*x.validation_fit; break;
      }
      if (best == candidates.size() || v < best_v) {
        best = k;
        best_v = v;
      }
    }
    require(best < candidates.size(), "OrderSelection: no valid candidate in the grid");
    return best;
  }
  /// Best candidate by `c` (see `best_index`).
  [[nodiscard]] const OrderCandidate& best(OrderCriterion c) const { return candidates[best_index(c)]; }

  /// The table: one line per candidate, best rows marked, then the picks.
  [[nodiscard]] std::string table() const {
    std::ostringstream os;
    os.imbue(std::locale::classic());  // a global locale's grouping or decimal comma must not reach the text
    char line[256];
    os << "ARX order selection: " << candidates.size() << " candidates, N = " << num_samples
       << " samples each (rows from sample " << first_row << " of every experiment)\n";
    std::snprintf(line, sizeof line, "%-16s %3s %12s %12s %12s", "orders", "d", "loss V", "AIC",
                  "MDL");
    os << line;
    if (has_validation) {
      std::snprintf(line, sizeof line, " %12s %9s", "val. loss", "val. fit%");
      os << line;
    }
    os << "\n";
    const std::size_t ia = best_index(OrderCriterion::aic), im = best_index(OrderCriterion::mdl);
    const std::size_t iv = has_validation ? best_index(OrderCriterion::validation_fit)
                                          : candidates.size();
    for (std::size_t k = 0; k < candidates.size(); ++k) {
      const OrderCandidate& x = candidates[k];
      if (!x.valid) {
        std::snprintf(line, sizeof line, "%-16s %3d", x.orders.str().c_str(), x.num_parameters);
        os << line << ' ' << detail::right_aligned(detail::format_g(x.loss, 5), 12)
           << "   (rank deficient: not identifiable)\n";
        continue;
      }
      std::snprintf(line, sizeof line, "%-16s %3d", x.orders.str().c_str(), x.num_parameters);
      os << line << ' ' << detail::right_aligned(detail::format_g(x.loss, 5), 12) << ' '
         << detail::right_aligned(detail::format_g(x.aic, 6), 12) << ' '
         << detail::right_aligned(detail::format_g(x.mdl, 6), 12);
      if (has_validation)
        os << ' ' << detail::right_aligned(detail::format_g(*x.validation_loss, 5), 12) << ' '
           << detail::right_aligned(detail::format_f(*x.validation_fit, 2), 9);
      std::string mark;
      if (k == ia) mark += " <AIC";
      if (k == im) mark += " <MDL";
      if (k == iv) mark += " <val";
      os << mark << "\n";
    }
    os << "Best by AIC: " << candidates[ia].orders.str()
       << "   Best by MDL: " << candidates[im].orders.str();
    if (has_validation) os << "   Best validation fit: " << candidates[iv].orders.str();
    os << "\n";
    return os.str();
  }

  /// ASCII order-selection plot: for each number of parameters d, the candidate with the lowest
  /// loss and a bar of its unexplained variance 100·V/var(y) (%), `width` characters for the
  /// largest; the AIC and MDL choices are marked.
  [[nodiscard]] std::string bar_chart(int width = 50) const {
    std::ostringstream os;
    os.imbue(std::locale::classic());  // a global locale's grouping or decimal comma must not reach the text
    const std::size_t ia = best_index(OrderCriterion::aic), im = best_index(OrderCriterion::mdl);
    int dmax = 0;
    for (const auto& x : candidates) dmax = std::max(dmax, x.num_parameters);
    std::vector<std::size_t> best_at(static_cast<std::size_t>(dmax + 1), candidates.size());
    for (std::size_t k = 0; k < candidates.size(); ++k) {
      const auto& x = candidates[k];
      if (!x.valid) continue;
      auto& b = best_at[static_cast<std::size_t>(x.num_parameters)];
      if (b == candidates.size() || x.loss < candidates[b].loss) b = k;
    }
    double vmax = 0;
    for (std::size_t b : best_at)
      if (b < candidates.size()) vmax = std::max(vmax, unexplained(candidates[b]));
    os << "Unexplained output variance (% of var y) of the best model per parameter count\n";
    char line[256];
    for (int d = 0; d <= dmax; ++d) {
      const std::size_t b = best_at[static_cast<std::size_t>(d)];
      if (b >= candidates.size()) continue;
      const double v = unexplained(candidates[b]);
      const int len = vmax > 0 ? static_cast<int>(std::lround(width * v / vmax)) : 0;
      std::snprintf(line, sizeof line, "d=%2d %-16s |", d, candidates[b].orders.str().c_str());
      os << line << std::string(static_cast<std::size_t>(std::max(len, v > 0 ? 1 : 0)), '#');
      os << ' ' << detail::format_g(v, 4) << " %";
      // The criteria's picks need not be the lowest-loss model at their d; name them if not.
      for (auto [idx, name] : {std::pair{ia, "AIC"}, std::pair{im, "MDL"}})
        if (candidates[idx].num_parameters == d)
          os << "  <" << name << (idx == b ? "" : " " + candidates[idx].orders.str());
      os << "\n";
    }
    return os.str();
  }

 private:
  double unexplained(const OrderCandidate& x) const {
    return output_variance > 0 ? 100.0 * x.loss / output_variance : 0.0;
  }
};

namespace detail {

inline OrderSelection arx_order_selection_impl(const Dataset& est, const Dataset* val,
                                               const ArxOrderGrid& grid, const ArxOptions& opt) {
  const std::string who = "arx_order_selection";
  require(est.size() > 0, who + ": the estimation data set is empty", at_parameter("data"));
  est.require_estimable_scale(who);
  require(!grid.na.empty() && !grid.nb.empty() && !grid.nk.empty(),
          who + ": every grid list (na, nb, nk) needs at least one value", at_parameter("grid"));
  const int m = est.num_inputs();
  auto make = [m](int na, int nb, int nk) {
    return ArxOrders(na, std::vector<int>(static_cast<std::size_t>(m), nb),
                     std::vector<int>(static_cast<std::size_t>(m), nk));
  };
  int start = 0;
  for (int na : grid.na)
    for (int nb : grid.nb)
      for (int nk : grid.nk) {
        const ArxOrders o = make(na, nb, nk);
        check_arx_orders(o, m, who);
        start = std::max(start, o.max_lag());
      }
  if (val) {
    require(val->size() > 0, who + ": the validation data set is empty",
            at_parameter("validation"));
    require(val->num_inputs() == m && val->num_outputs() == est.num_outputs(),
            who + ": validation data have " + std::to_string(val->num_inputs()) + " inputs and " +
                std::to_string(val->num_outputs()) + " outputs, estimation data " +
                std::to_string(m) + " and " + std::to_string(est.num_outputs()),
            at_parameter("validation"));
    // Checked here, where the message can say which data set and experiment: the model's own
    // checks later would name neither.
    Eigen::Index longest = 0;
    for (std::size_t e = 0; e < val->size(); ++e) {
      check_linear_experiment((*val)[e], m, est.num_outputs(), est.ts(), static_cast<long>(e), who, true, "validation");
      (*val)[e].require_estimable_scale(who + " (validation data)", static_cast<long>(e));  // its losses are sums of squares
      longest = std::max(longest, (*val)[e].size());
    }
    require(longest > start,
            who + ": no validation experiment is longer than the grid's largest lag " +
                std::to_string(start) + " (the longest has " + std::to_string(longest) +
                " samples), so the validation loss would have no samples to score",
            at_parameter("validation"));
  }
  OrderSelection sel;
  sel.first_row = start;
  sel.has_validation = val != nullptr;
  for (int na : grid.na)
    for (int nb : grid.nb)
      for (int nk : grid.nk) {
        OrderCandidate c;
        c.orders = make(na, nb, nk);
        c.num_parameters = c.orders.num_coefficients() + (opt.offset ? 1 : 0);
        if (c.num_parameters == 0) continue;  // [0 0 nk]: nothing to estimate
        bool deficient = false;
        const Arx model = arx_estimate(est, c.orders, opt, start, who, &deficient);
        if (deficient) {
          c.valid = false;
          c.loss = model.report().loss;
          sel.num_samples = model.report().num_samples;
          sel.candidates.push_back(c);
          continue;
        }
        sel.num_samples = model.report().num_samples;
        c.loss = model.report().loss;
        c.aic = aic_criterion(c.loss, sel.num_samples, c.num_parameters);
        c.mdl = mdl_criterion(c.loss, sel.num_samples, c.num_parameters);
        if (val) {
          double ss = 0, ssy = 0, sse = 0;
          Eigen::Index n = 0;
          bool diverges = false;
          for (std::size_t e = 0; e < val->size(); ++e) {
            const Experiment& ex = (*val)[e];
            const Eigen::MatrixXd p = model.predict(ex, 1);
            const Eigen::Index s = std::min<Eigen::Index>(start, ex.size());
            ss += (p.col(0) - ex.y().col(0)).tail(ex.size() - s).squaredNorm();
            n += ex.size() - s;
            // Least squares may return an unstable A on noisy data; its simulation overflows and
            // `simulate` refuses it. The data were checked above, so that is the only refusal
            // left here: such a candidate simply has no validation fit (−∞).
            try {
              const Eigen::MatrixXd sim = model.simulate(ex, InitialCondition::estimate);
              sse += (sim - ex.y()).squaredNorm();
            } catch (const Error&) {
              diverges = true;
            }
            // Each record about its own mean, as compare scores it: one mean for all would count
            // the step between records at different operating points as explained variance.
            ssy += (ex.y().array() - ex.y().mean()).square().sum();
          }
          c.validation_loss = ss / static_cast<double>(n);  // n > 0: checked above
          c.validation_fit = ssy > 0 ? 100.0 * (1.0 - std::sqrt(sse / ssy))
                                     : -std::numeric_limits<double>::infinity();
          if (diverges || !std::isfinite(*c.validation_fit)) c.validation_fit = -std::numeric_limits<double>::infinity();
        }
        sel.candidates.push_back(c);
      }
  // Output variance on the common rows, for the "% unexplained" of the chart.
  double sum = 0, sq = 0;
  Eigen::Index n = 0;
  for (const auto& ex : est)
    for (Eigen::Index t = start; t < ex.size(); ++t) {
      sum += ex.y()(t, 0);
      sq += ex.y()(t, 0) * ex.y()(t, 0);
      ++n;
    }
  if (n > 0) sel.output_variance = std::max(0.0, sq / static_cast<double>(n) - (sum / static_cast<double>(n)) * (sum / static_cast<double>(n)));
  require(!sel.candidates.empty(), who + ": the grid has no candidate with parameters",
          at_parameter("grid"));
  return sel;
}

}  // namespace detail

/// Scores every ARX order of `grid` on the estimation data (see file comment). Throws
/// `nlid::Error` for invalid orders, data too short for the largest order (naming the
/// experiment), or mismatched channel counts. Rank-deficient candidates are kept as "not
/// identifiable" rows rather than aborting the search.
inline OrderSelection arx_order_selection(const Dataset& estimation, const ArxOrderGrid& grid = {},
                                          const ArxOptions& options = {}) {
  return detail::arx_order_selection_impl(estimation, nullptr, grid, options);
}

/// As above, and also scores every candidate on independent validation data (one-step loss and
/// simulation fit with estimated initial conditions).
inline OrderSelection arx_order_selection(const Dataset& estimation, const Dataset& validation,
                                          const ArxOrderGrid& grid = {},
                                          const ArxOptions& options = {}) {
  return detail::arx_order_selection_impl(estimation, &validation, grid, options);
}

/// Search range and model orders of `delayest` (the toolbox's defaults: na = nb = 2, nk from 0
/// to 20).
struct DelayestOptions {
  int na = 2;       ///< poles of the ARX models compared
  int nb = 2;       ///< B coefficients of the ARX models compared
  int nk_min = 0;   ///< smallest delay tried (samples)
  int nk_max = 20;  ///< largest delay tried (samples)
};

/// Outcome of `delayest`: the delay and the table it was chosen from.
struct DelayEstimate {
  int nk = 0;                 ///< estimated input delay in samples (dead time nk · Ts)
  OrderSelection candidates;  ///< one ARX [na nb nk] row per delay tried; `table()` prints it
};

/// Input delay (dead time in samples) of single-input data, as the toolbox's `delayest`: the nk
/// whose ARX [na nb nk] model has the smallest one-step loss over the same rows (file comment).
/// Throws `nlid::Error` naming the option for a bad range or records too short for nk_max, and
/// the data for several inputs or outputs (select one with `select_channels`) or a held input.
inline DelayEstimate delayest(const Dataset& data, const DelayestOptions& options = {}) {
  require(options.na >= 0 && options.nb >= 1,
          "delayest: na must be >= 0 and nb >= 1, got na = " + std::to_string(options.na) +
              ", nb = " + std::to_string(options.nb),
          at_parameter("na, nb"));
  require(options.nk_min >= 0 && options.nk_max >= options.nk_min && options.nk_max <= max_model_order,
          "delayest: the delays tried must satisfy 0 <= nk_min <= nk_max <= " + std::to_string(max_model_order) +
              ", got " + std::to_string(options.nk_min) + " .. " + std::to_string(options.nk_max),
          at_parameter("nk_min, nk_max"));
  require(data.num_outputs() == 1,
          "delayest: the data have " + std::to_string(data.num_outputs()) +
              " outputs; the delay is estimated for one output at a time (select it with select_channels)",
          at_parameter("data"));
  require(data.num_inputs() == 1,
          "delayest: the data have " + std::to_string(data.num_inputs()) +
              " inputs; the delay is estimated for one input at a time (select it with select_channels)",
          at_parameter("data"));
  // Every delay's rows start after the largest lag of the range; say so here, where the message
  // can name nk_max, rather than in the order selection's "regression rows" check.
  const int window = std::max(options.na, options.nk_max + options.nb - 1);
  Eigen::Index rows = 0;
  for (const Experiment& e : data) rows += std::max<Eigen::Index>(0, e.size() - window);
  require(rows > options.na + options.nb,
          "delayest: " + std::to_string(rows) + " sample(s) follow the lag window of the largest delay tried (nk_max + nb - 1 = " +
              std::to_string(window) + ") in the data; more than na + nb = " + std::to_string(options.na + options.nb) +
              " are needed: lower nk_max or use longer records",
          at_parameter("nk_max"));
  ArxOrderGrid grid;
  grid.na = {options.na};
  grid.nb = {options.nb};
  grid.nk.clear();
  for (int nk = options.nk_min; nk <= options.nk_max; ++nk) grid.nk.push_back(nk);
  DelayEstimate r{0, arx_order_selection(data, grid)};
  // The smallest loss, rank-deficient candidates included: noise-free data of a lower order than
  // [na nb] fit exactly, and so rank-deficiently, at the true delay. Exact fits also come at
  // smaller delays whose B ends in the true one's first coefficient (b = [0 … 0 b_nk …]): of the
  // delays that fit to rounding, the largest is the one the data need. If every candidate is
  // deficient and none fits better, the data say nothing about the delay (a held input).
  const auto& cs = r.candidates.candidates;
  bool any_valid = false;
  double lo = cs[0].loss, hi = cs[0].loss;
  for (const OrderCandidate& c : cs) {
    any_valid = any_valid || c.valid;
    lo = std::min(lo, c.loss);
    hi = std::max(hi, c.loss);
  }
  const bool exact = lo <= 1e-20 * r.candidates.output_variance;
  std::size_t best = 0;
  for (std::size_t k = 0; k < cs.size(); ++k) {
    if (exact ? cs[k].loss <= 1e-20 * r.candidates.output_variance : cs[k].loss < cs[best].loss) best = k;
  }
  require(cs.size() == 1 || any_valid || hi > lo * (1.0 + 1e-9),
          "delayest: every ARX model of the range is rank deficient and fits equally well: the data say nothing "
          "about the delay (is the input constant?)",
          at_parameter("data"));
  r.nk = r.candidates.candidates[best].orders.nk.at(0);
  return r;
}

}  // namespace nlid
