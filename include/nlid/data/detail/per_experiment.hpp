#pragma once
/// @file
/// Helpers of the `Experiment → Experiment` operations: carrying metadata over to new samples,
/// and applying an operation to every experiment of a `Dataset`, adding the experiment index to any
/// `nlid::Error` so a failure in a multi-experiment set says which record.

#include <Eigen/Core>
#include <cstdio>
#include <string>
#include <utility>

#include "nlid/core/error.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/data/experiment.hpp"

namespace nlid::detail {

/// A new experiment with these samples and everything else (name, channel names and units,
/// notes) from `like`.
inline Experiment with_samples(const Experiment& like, Eigen::MatrixXd u, Eigen::MatrixXd y,
                               double ts, double t0) {
  Experiment e(std::move(u), std::move(y), ts, like.name(), NonFinitePolicy::keep);
  e.set_t0(t0);
  e.set_input_names(like.input_names());
  e.set_output_names(like.output_names());
  e.set_input_units(like.input_units());
  e.set_output_units(like.output_units());
  for (const auto& n : like.notes()) e.add_note(n);
  return e;
}

/// `op` applied to each experiment of `d`; errors get the experiment index.

template <class Op>
Dataset per_experiment(const Dataset& d, Op&& op) {
  Dataset out;
  for (std::size_t i = 0; i < d.size(); ++i) {
    Experiment e;
    try {
      e = op(d[i]);
    } catch (const Error& err) {
      Location l = err.where();
      l.experiment = static_cast<long>(i);
      throw Error(err.message(), l);
    }
    out.add(std::move(e));
  }
  return out;
}

}  // namespace nlid::detail
