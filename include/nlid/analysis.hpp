#pragma once
/// @file
/// Umbrella header of the analysis layer: fit (`fit_percent`), `compare`, residual analysis
/// (`resid`), step and impulse responses, linearisation about an operating point, nonlinear
/// distortion analysis of periodic experiments (`distortion_analysis`).

#include "nlid/analysis/compare.hpp"
#include "nlid/analysis/concepts.hpp"
#include "nlid/analysis/distortion.hpp"
#include "nlid/analysis/fit.hpp"
#include "nlid/analysis/linearize.hpp"
#include "nlid/analysis/resid.hpp"
#include "nlid/analysis/step_response.hpp"
