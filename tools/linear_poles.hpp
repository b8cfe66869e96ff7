#pragma once
// The poles a tool can show for a saved model: nlid-fit warns when it saves a model whose linear
// dynamics are unstable, nlid-codegen when it is asked to put one on a target.

#include <Eigen/Core>

#include "nlid/linear/arx.hpp"
#include "nlid/linear/output_error.hpp"
#include "nlid/linear/polynomial.hpp"
#include "nlid/linear/state_space.hpp"
#include "nlid/models/any_model.hpp"
#include "nlid/models/spec.hpp"

namespace nlid_tools {

/// The largest pole magnitude of the model's linear dynamics (ARX, OE, state space, the linear
/// block of a Hammerstein-Wiener model), or -1 for models without such poles to show.
inline double largest_pole(const nlid::AnyModel& m) {
  Eigen::VectorXcd p;
  if (const auto* a = m.target<nlid::Arx>()) {
    p = a->poles();
  } else if (const auto* o = m.target<nlid::OutputError>()) {
    p = o->poles();
  } else if (const auto* ss = m.target<nlid::StateSpace>()) {
    p = ss->poles();
  } else if (const auto* h = m.target<nlid::DynamicHammersteinWiener>()) {
    p = nlid::roots(h->linear_block().polynomials(h->linear_parameters()).second);
  }
  return p.size() > 0 ? p.cwiseAbs().maxCoeff() : -1.0;
}

/// Whether `largest_pole` says unstable; a pole on the unit circle within rounding (an
/// integrator) is not.
inline bool unstable_pole(double largest) { return largest > 1.0 + 1e-9; }

}  // namespace nlid_tools
