#pragma once
/// @file
/// Umbrella header of the regressor layer: lag windows, ring buffer, standard lagged regressors,
/// custom regressors and compile-time regressor sets (see each header for the math).

#include "nlid/regressors/concepts.hpp"
#include "nlid/regressors/custom.hpp"
#include "nlid/regressors/history.hpp"
#include "nlid/regressors/lag_window.hpp"
#include "nlid/regressors/lagged.hpp"
#include "nlid/regressors/regressor_set.hpp"
