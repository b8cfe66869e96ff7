#pragma once
/// @file
/// What an estimator tells about the model it returns, and the information criteria used to
/// compare model orders.
///
/// With N residuals ε(t) in the criterion and d estimated parameters, nlid uses
///
///     V   = (1/N) Σ ε(t)²                          loss function (mean squared residual)
///     AIC = N · log V + 2d                         Akaike (1974); Ljung 1999, eq. 16.33
///     MDL = N · log V + d · log N                  Rissanen (1978); Ljung 1999, eq. 16.37
///     FPE = V · (1 + d/N) / (1 − d/N)              Akaike's final prediction error, eq. 16.32
///
/// AIC and MDL are the Gaussian log-likelihood forms without the constant N·(log 2π + 1), so only
/// differences between models fitted to the *same* N samples mean anything; the order search
/// (order_selection.hpp) makes sure every candidate is scored on the same samples. MDL (the same
/// as BIC up to that constant) penalises parameters harder than AIC and is consistent: as N grows
/// it picks the true order with probability one, while AIC tends to over-fit by a parameter or
/// two (Ljung 1999, §16.4). A noise-free fit would give log 0; V is floored at the smallest
/// normal double so the criteria stay finite and ordered.

#include <algorithm>
#include <cmath>
#include <limits>
#include <locale>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "nlid/linear/polynomial.hpp"

namespace nlid {

/// V floored at the smallest normal double, so log V is finite for an exact fit.
inline double floored_loss(double loss) {
  return std::max(loss, std::numeric_limits<double>::min());
}

/// AIC = N log V + 2d (see file comment).
inline double aic_criterion(double loss, Eigen::Index num_samples, int num_parameters) {
  return static_cast<double>(num_samples) * std::log(floored_loss(loss)) + 2.0 * num_parameters;
}

/// MDL = N log V + d log N (see file comment).
inline double mdl_criterion(double loss, Eigen::Index num_samples, int num_parameters) {
  const double n = static_cast<double>(num_samples);
  return n * std::log(floored_loss(loss)) + num_parameters * std::log(n);
}

/// FPE = V (1 + d/N) / (1 − d/N); +∞ when d ≥ N (no degrees of freedom left).
inline double fpe_criterion(double loss, Eigen::Index num_samples, int num_parameters) {
  const double r = static_cast<double>(num_parameters) / static_cast<double>(num_samples);
  if (r >= 1.0) return std::numeric_limits<double>::infinity();
  return loss * (1.0 + r) / (1.0 - r);
}

/// Fit (%) of each of `p` outputs from the measurements `y` and residuals `r` = ŷ − y, both
/// stored sample by sample with the outputs interleaved (entry t·p + i is output i at sample t).
/// A channel whose measurement is constant has nothing to explain: its fit is 100 % if the
/// residual is zero too, −∞ otherwise (never a finite number that would read as a score).
inline std::vector<double> fit_percent_per_output(const Eigen::VectorXd& y, const Eigen::VectorXd& r, int p) {
  std::vector<double> fit(static_cast<std::size_t>(p), 0.0);
  if (p <= 0) return fit;
  const Eigen::Index n = y.size() / p;
  const Eigen::Map<const Eigen::MatrixXd> ym(y.data(), p, n), rm(r.data(), p, n);
  for (int i = 0; i < p; ++i) {
    // Each channel's own mean: a channel with a large mean must not make the others look good.
    const double spread = (ym.row(i).array() - ym.row(i).mean()).matrix().norm();
    const double err = rm.row(i).norm();
    fit[static_cast<std::size_t>(i)] = spread > 0 ? 100.0 * (1.0 - err / spread)
                                       : err == 0.0 ? 100.0
                                                    : -std::numeric_limits<double>::infinity();
  }
  return fit;
}

/// Summary of an estimation, kept in every estimated linear model (`model.report()`).
struct LinearEstimationReport {
  std::string method;            ///< e.g. "least squares (QR)", "Steiglitz-McBride + PEM"
  std::string focus;             ///< "prediction" or "simulation": which error was minimised
  int num_experiments = 0;       ///< experiments used
  Eigen::Index num_samples = 0;  ///< N: residuals in the criterion (all experiments)
  int num_parameters = 0;        ///< d: free parameters (initial conditions included)
  double loss = 0.0;             ///< V = (1/N) Σ ε² on the estimation data
  /// Fit (%) of the criterion's output (prediction or simulation); with several outputs the
  /// *worst* channel's (the smallest entry of `fit_per_output`), so no channel is better than
  /// this number says.
  double fit_percent = 0.0;
  /// Fit (%) per output channel, 100·(1 − ‖yᵢ − ŷᵢ‖/‖yᵢ − ȳᵢ‖) with ȳᵢ the mean of output i over
  /// all experiments (the toolbox's per-output fit). Empty in a report restored from a file that
  /// predates it.
  std::vector<double> fit_per_output;
  int iterations = 0;            ///< iterations of an iterative method (0 for one-shot methods)
  std::string solver_message;    ///< termination message of the iterative solver, if any

  /// Sets `fit_per_output` and `fit_percent` (its smallest entry).
  void set_fit(std::vector<double> per_output) {
    fit_per_output = std::move(per_output);
    if (!fit_per_output.empty())
      fit_percent = *std::min_element(fit_per_output.begin(), fit_per_output.end());
  }

  /// AIC of the estimate.
  [[nodiscard]] double aic() const { return aic_criterion(loss, num_samples, num_parameters); }
  /// MDL of the estimate.
  [[nodiscard]] double mdl() const { return mdl_criterion(loss, num_samples, num_parameters); }
  /// FPE of the estimate.
  [[nodiscard]] double fpe() const { return fpe_criterion(loss, num_samples, num_parameters); }

  /// Multi-line human-readable summary.
  [[nodiscard]] std::string str() const {
    std::ostringstream os;
    os.imbue(std::locale::classic());  // a global locale's grouping or decimal comma must not reach the text
    os << "Estimated by " << (method.empty() ? std::string("(unknown)") : method) << " on "
       << num_experiments << " experiment(s), " << num_samples << " samples, " << num_parameters
       << " parameters; " << focus << " focus.\n";
    os << "Fit to estimation data: " << format_number(fit_percent, 4) << " % (" << focus;
    if (fit_per_output.size() > 1) {
      os << "; worst output; per output:";
      for (std::size_t i = 0; i < fit_per_output.size(); ++i)
        os << (i ? ", " : " ") << "y" << i + 1 << " " << format_number(fit_per_output[i], 4) << " %";
    }
    os << "), loss V = " << format_number(loss, 4) << ", FPE = " << format_number(fpe(), 4)
       << ", AIC = " << format_number(aic(), 6) << ", MDL = " << format_number(mdl(), 6) << "\n";
    if (iterations > 0 || !solver_message.empty())
      os << "Iterations: " << iterations << (solver_message.empty() ? "" : "; ") << solver_message
         << "\n";
    return os.str();
  }
};

}  // namespace nlid
