#pragma once
/// @file
/// Umbrella header of the static nonlinearities: every `Nonlinearity` of nlid and the batch
/// helpers. Include a single component header instead to keep compile times short.
///
/// | type                                  | map                                     | m   | p               |
/// | ------------------------------------- | --------------------------------------- | --- | --------------- |
/// | `UnitGain`                            | g = x                                   | 1   | 0               |
/// | `LinearMap<M>`                        | g = xᵀL + d                             | M   | M + 1           |
/// | `SigmoidNet<M, Units, LinearTerm>`    | zᵀL + d + Σ aₖσ(zᵀbₖ + cₖ)              | M   | (M) + 1 + n(M+2) |
/// | `WaveletNet<M, Units, LinearTerm>`    | zᵀL + d + Σ aₖφ(ρₖ) + wₖψ(ρₖ)           | M   | (M) + 1 + n(M+3) |
/// | `PwLinear<Breakpoints>`               | linear interpolation through n points   | 1   | 2n              |
/// | `Saturation`                          | clamp(x, lower, upper)                  | 1   | 2               |
/// | `DeadZone`                            | 0 on [lower, upper], slope 1 outside    | 1   | 2               |
/// | `Poly1d<Degree>`                      | Σ c[k] xᵏ                               | 1   | D + 1           |
/// | `TreePartition<M, Depth>`             | affine model of the tree leaf x is in   | M   | 2^D (M + 1)     |

#include "nlid/nonlinearities/concepts.hpp"
#include "nlid/nonlinearities/dead_zone.hpp"
#include "nlid/nonlinearities/evaluate.hpp"
#include "nlid/nonlinearities/linear.hpp"
#include "nlid/nonlinearities/piecewise_linear.hpp"
#include "nlid/nonlinearities/polynomial.hpp"
#include "nlid/nonlinearities/saturation.hpp"
#include "nlid/nonlinearities/sigmoid_network.hpp"
#include "nlid/nonlinearities/tree_partition.hpp"
#include "nlid/nonlinearities/unit_gain.hpp"
#include "nlid/nonlinearities/wavelet_network.hpp"
