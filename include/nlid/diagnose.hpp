#pragma once
/// @file
/// Umbrella header of the diagnosis layer: when simulation and recordings differ, locate the
/// mismatch (noise floor, intervals, operating regions), name the physics left out (effect
/// catalogue, greedy refit search with significance tests), model it (augmented grey-box model
/// with re-estimated named parameters) and show the fit improve (explanation, JSON, HTML report).
///
///     auto d = nlid::diagnose("throttle", est, val, {.decimate = 10});
///     std::cout << d.explanation;
///     nlid::write_diagnosis_json(d, "diagnosis.json");
///     nlid::write_diagnosis_html(d, "diagnosis.html");
///
/// See docs/diagnosis.md for the method, the thresholds and the throttle result.

#include "nlid/diagnose/augmented.hpp"
#include "nlid/diagnose/candidates/search.hpp"
#include "nlid/diagnose/diagnose.hpp"
#include "nlid/diagnose/effects.hpp"
#include "nlid/diagnose/explain.hpp"
#include "nlid/diagnose/locate.hpp"
#include "nlid/diagnose/noise_floor.hpp"
#include "nlid/diagnose/refit.hpp"
#include "nlid/diagnose/significance.hpp"
