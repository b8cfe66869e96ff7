#pragma once
/// @file
/// Umbrella header of the output layer: JSON (`nlid::Json`, `read_json`, `write_json`, with
/// Eigen vector/matrix conversions), SVG line and bar charts (`LineChart`, `BarChart`) and the
/// self-contained HTML report (`HtmlReport`). See docs/io.md for a tour.

#include "nlid/io/html_report.hpp"
#include "nlid/io/json.hpp"
#include "nlid/io/json_eigen.hpp"
#include "nlid/io/svg_chart.hpp"
