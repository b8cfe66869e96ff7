#pragma once
/// @file
/// Umbrella header of the data layer: experiments and data sets, CSV input/output, filters and
/// preprocessing (offsets, trends, time windows, decimation, resampling), input design (PRBS,
/// band-limited noise, multisines, amplitude-modulated steps).
///
/// Typical use, as in the throttle study (decimate 1 kHz records to 100 Hz, merge two for
/// estimation):
///
///     nlid::Dataset est = nlid::decimate(
///         nlid::read_csv_dataset({"data1.csv", "data2.csv"}), 10);
///     nlid::Experiment val = nlid::decimate(nlid::read_csv("data3.csv"), 10);

#include "nlid/data/concepts.hpp"    // IWYU pragma: export
#include "nlid/data/csv.hpp"         // IWYU pragma: export
#include "nlid/data/dataset.hpp"     // IWYU pragma: export
#include "nlid/data/experiment.hpp"  // IWYU pragma: export
#include "nlid/data/filter.hpp"      // IWYU pragma: export
#include "nlid/data/input_design.hpp"  // IWYU pragma: export
#include "nlid/data/preprocess.hpp"  // IWYU pragma: export
#include "nlid/data/resample.hpp"    // IWYU pragma: export
