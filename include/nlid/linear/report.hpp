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
#include <sstream>
#include <string>

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

/// Summary of an estimation, kept in every estimated linear model (`model.report()`).
struct LinearEstimationReport {
  std::string method;            ///< e.g. "least squares (QR)", "Steiglitz-McBride + PEM"
  std::string focus;             ///< "prediction" or "simulation": which error was minimised
  int num_experiments = 0;       ///< experiments used
  Eigen::Index num_samples = 0;  ///< N: residuals in the criterion (all experiments)
  int num_parameters = 0;        ///< d: free parameters (initial conditions included)
  double loss = 0.0;             ///< V = (1/N) Σ ε² on the estimation data
  double fit_percent = 0.0;      ///< fit (%) of the criterion's output (prediction or simulation)
  int iterations = 0;            ///< iterations of an iterative method (0 for one-shot methods)
  std::string solver_message;    ///< termination message of the iterative solver, if any

  /// AIC of the estimate.
  [[nodiscard]] double aic() const { return aic_criterion(loss, num_samples, num_parameters); }
  /// MDL of the estimate.
  [[nodiscard]] double mdl() const { return mdl_criterion(loss, num_samples, num_parameters); }
  /// FPE of the estimate.
  [[nodiscard]] double fpe() const { return fpe_criterion(loss, num_samples, num_parameters); }

  /// Multi-line human-readable summary.
  [[nodiscard]] std::string str() const {
    std::ostringstream os;
    os << "Estimated by " << (method.empty() ? std::string("(unknown)") : method) << " on "
       << num_experiments << " experiment(s), " << num_samples << " samples, " << num_parameters
       << " parameters; " << focus << " focus.\n";
    os << "Fit to estimation data: " << format_number(fit_percent, 4) << " % (" << focus
       << "), loss V = " << format_number(loss, 4) << ", FPE = " << format_number(fpe(), 4)
       << ", AIC = " << format_number(aic(), 6) << ", MDL = " << format_number(mdl(), 6) << "\n";
    if (iterations > 0 || !solver_message.empty())
      os << "Iterations: " << iterations << (solver_message.empty() ? "" : "; ") << solver_message
         << "\n";
    return os.str();
  }
};

}  // namespace nlid
