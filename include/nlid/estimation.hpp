#pragma once
/// @file
/// Umbrella header of the estimation layer: least-squares problem concepts, problem adapters
/// (analytic, automatic and numeric differentiation, stacked experiments), robust losses, the
/// bound-constrained Levenberg–Marquardt solver, and parameter uncertainty of an estimate.

#include "nlid/estimation/autodiff.hpp"
#include "nlid/estimation/concepts.hpp"
#include "nlid/estimation/levenberg_marquardt.hpp"
#include "nlid/estimation/numeric_diff.hpp"
#include "nlid/estimation/problem.hpp"
#include "nlid/estimation/robust_loss.hpp"
#include "nlid/estimation/uncertainty.hpp"
