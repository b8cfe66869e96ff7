#pragma once
/// @file
/// Umbrella header of the automatic-differentiation layer: `Dual<T, N>`, `DynamicDual<T>`, the
/// math overloads with their derivative rules, the Eigen scalar glue and the `AdScalar` concept.

#include "nlid/ad/concepts.hpp"
#include "nlid/ad/dual.hpp"
