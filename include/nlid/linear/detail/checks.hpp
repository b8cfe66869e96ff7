#pragma once
/// @file
/// Argument checks shared by the linear models (internal).

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/core/sample_time.hpp"
#include "nlid/data/experiment.hpp"

namespace nlid::detail {

// "experiment 2 ('data3')" or "experiment 2"; index < 0 gives "experiment 'data3'". `set`
// names the data set when a call sees two ("validation" gives "validation experiment 2").
inline std::string linear_experiment_label(const Experiment& e, long index, const std::string& set = "") {
  std::string s = set.empty() ? "experiment" : set + " experiment";
  if (index >= 0) s += " " + std::to_string(index);
  if (!e.name().empty()) s += index >= 0 ? " ('" + e.name() + "')" : " '" + e.name() + "'";
  return s;
}

inline Location linear_experiment_location(long index) {
  Location l;
  if (index >= 0) l.experiment = index;
  return l;
}

// Refuses a record whose channels carry the model's names in another order (see
// detail::check_channel_order): the model would run on swapped signals.
template <class M>
void check_linear_channel_order(const Experiment& e, const M& m, const std::string& who) {
  const std::string label = who + ": " + linear_experiment_label(e, -1);
  check_channel_order(e.input_names(), m.input_names(), "input", label, linear_experiment_location(-1));
  check_channel_order(e.output_names(), m.output_names(), "output", label, linear_experiment_location(-1));
}

// Checks that `e` can drive a model with `nu` inputs and sample time `ts`; with `need_y` also
// that it has `ny` finite outputs (for initial-state estimation or fitting).
inline void check_linear_experiment(const Experiment& e, int nu, int ny, double ts, long index,
                             const std::string& who, bool need_y, const std::string& set = "") {
  const Location where = linear_experiment_location(index);
  e.validate(true);  // u() and y() are mutable: a record resized through one would be read past its end
  if (e.num_inputs() != nu)
    throw Error(who + ": model has " + std::to_string(nu) + " input(s) but " +
                    linear_experiment_label(e, index, set) + " has " + std::to_string(e.num_inputs()),
                where);
  if (need_y && e.num_outputs() != ny)
    throw Error(who + ": model has " + std::to_string(ny) + " output(s) but " +
                    linear_experiment_label(e, index, set) + " has " + std::to_string(e.num_outputs()),
                where);
  if (ts > 0 && !same_sample_time(e.ts(), ts)) {
    throw Error(who + ": model sample time " + format_g(ts, 9) + " s differs from the sample time " +
                    format_g(e.ts(), 9) + " s of " + linear_experiment_label(e, index, set) +
                    " (delays are counted in samples; resample the data or the model)",
                where);
  }
  auto check_finite = [&](const Eigen::MatrixXd& m, const char* kind) {
    for (Eigen::Index c = 0; c < m.cols(); ++c)
      for (Eigen::Index k = 0; k < m.rows(); ++k)
        if (!std::isfinite(m(k, c))) {
          Location l = where;
          l.row = static_cast<long>(k) + 1;
          l.column = static_cast<long>(c) + 1;
          throw Error(who + ": " + linear_experiment_label(e, index, set) + " has a missing (non-finite) " +
                          kind + " sample at index " + std::to_string(k) +
                          "; fill or trim it first (Experiment::fill_missing, select)",
                      l);
        }
  };
  check_finite(e.u(), "input");
  if (need_y) check_finite(e.y(), "output");
}

// Refuses a free response that cannot serve as a least-squares column: past 1e150 its squares
// overflow and the fitted initial state, then the whole simulation, would come out NaN. Only an
// unstable denominator grows that far; `poly` names it ("A(q)", "F2(q)"), `roots` gives its
// roots (called only on failure).
template <class Roots>
void check_free_response(const Eigen::VectorXd& h, const std::string& who, const std::string& poly,
                         Roots roots) {
  if (h.allFinite() && (h.size() == 0 || h.cwiseAbs().maxCoeff() <= 1e150)) return;
  const Eigen::VectorXcd r = roots();
  const std::string buf = format_g(r.size() > 0 ? r.cwiseAbs().maxCoeff() : 0.0, 6);
  throw Error(who + ": InitialCondition::estimate needs the free response of 1/" + poly + ", which overflows over " +
                  std::to_string(h.size()) + " samples: " + poly + " is unstable (a pole at |z| = " + buf +
                  "); use InitialCondition::zero or a shorter record",
              at_parameter("InitialCondition::estimate"));
}

// Standard deviations for a linear model's parameters: one per parameter, each finite and >= 0
// or +∞, which an estimator sets for a parameter the data do not determine (`who` names the
// model, `names` its parameters; a bad entry is located at its parameter).
inline void check_parameter_stddev(const Eigen::VectorXd& sd, const std::vector<std::string>& names,
                                   const std::string& who) {
  if (sd.size() != static_cast<Eigen::Index>(names.size()))
    throw Error(who + ": " + std::to_string(sd.size()) + " standard deviations for " +
                    std::to_string(names.size()) + " parameters",
                at_parameter("stddev"));
  for (Eigen::Index i = 0; i < sd.size(); ++i)
    if (!(sd(i) >= 0.0))  // NaN fails too
      throw Error(who + ": the standard deviation of " + names[static_cast<std::size_t>(i)] + " (entry " +
                      std::to_string(i) + ") must be finite and >= 0 (or +inf: not identifiable)",
                  at_parameter(names[static_cast<std::size_t>(i)]));
}

}  // namespace nlid::detail
