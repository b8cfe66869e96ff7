#pragma once
/// @file
/// Umbrella header of the linear models: ARX, output-error (B/F), state space (PO-MOESP and
/// prediction-error refinement), order selection, and the polynomial and filter helpers.
///
/// Typical use (the linear part of the throttle study):
///
///     nlid::Arx arx210 = nlid::arx(data3lin, {2, 1, 0});
///     nlid::OutputError oe220 = nlid::oe(data3lin, {2, 2, 0});
///     nlid::StateSpace ss2 = nlid::ssest(data3lin, 2);
///     nlid::OrderSelection sel = nlid::arx_order_selection(data3lin);
///     std::cout << arx210.describe() << sel.table();

#include "nlid/linear/arx.hpp"
#include "nlid/linear/concepts.hpp"
#include "nlid/linear/order_selection.hpp"
#include "nlid/linear/output_error.hpp"
#include "nlid/linear/polynomial.hpp"
#include "nlid/linear/report.hpp"
#include "nlid/linear/ssest.hpp"
#include "nlid/linear/state_space.hpp"
#include "nlid/linear/subspace.hpp"
