#pragma once
/// @file
/// Applies an `Experiment → Experiment` operation to every experiment of a `Dataset`, adding the
/// experiment index to any `nlid::Error` so a failure in a multi-experiment set says which record.

#include <utility>

#include "nlid/core/error.hpp"
#include "nlid/data/dataset.hpp"
#include "nlid/data/experiment.hpp"

namespace nlid::detail {

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
