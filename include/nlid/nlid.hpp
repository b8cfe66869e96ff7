#pragma once
/// @file
/// The whole library in one include: every layer's umbrella header plus the run-time model
/// machinery (model files, `AnyModel`, structure specs, block series). Convenient for tools and
/// first experiments; a program that compiles one model variant per application includes only
/// the headers of its components (examples/minimal_nlarx.cpp) and compiles several times faster.

#include "nlid/core/atomic_file.hpp"
#include "nlid/core/batch.hpp"
#include "nlid/core/error.hpp"
#include "nlid/core/format.hpp"
#include "nlid/core/initial_condition.hpp"
#include "nlid/core/sample_time.hpp"
#include "nlid/core/sizes.hpp"

#include "nlid/ad.hpp"
#include "nlid/analysis.hpp"
#include "nlid/codegen.hpp"
#include "nlid/data.hpp"
#include "nlid/diagnose.hpp"
#include "nlid/estimation.hpp"
#include "nlid/io.hpp"
#include "nlid/linear.hpp"
#include "nlid/models.hpp"
#include "nlid/nonlinearities.hpp"
#include "nlid/regressors.hpp"

#include "nlid/diagnose/report.hpp"
#include "nlid/estimation/multi_start.hpp"
#include "nlid/io/model_file.hpp"
#include "nlid/models/any_model.hpp"
#include "nlid/models/any_model_band.hpp"
#include "nlid/models/equilibrium.hpp"
#include "nlid/models/greybox_dynamic.hpp"
#include "nlid/models/physics/catalogue.hpp"
#include "nlid/models/sample_time.hpp"
#include "nlid/models/series.hpp"
#include "nlid/models/series_estimate.hpp"
#include "nlid/models/spec.hpp"
