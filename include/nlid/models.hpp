#pragma once
/// @file
/// Umbrella header of the model layer: nonlinear ARX (`Nlarx`), Hammerstein–Wiener
/// (`HammersteinWiener` with `TransferFunctionBlock`), their estimation (`estimate`), and the
/// grey-box models (`GreyBox`, integrators, physics catalogue, batched runs of many parameter sets),
/// the parameter uncertainty of estimated models (`parameter_uncertainty`), and `Stepper`, which runs a
/// model one sample at a time.

#include "nlid/models/concepts.hpp"
#include "nlid/models/estimate.hpp"
#include "nlid/models/greybox.hpp"
#include "nlid/models/greybox_batched.hpp"
#include "nlid/models/greybox_estimate.hpp"
#include "nlid/models/hammerstein_wiener.hpp"
#include "nlid/models/integrators.hpp"
#include "nlid/models/nlarx.hpp"
#include "nlid/models/simulation_band.hpp"
#include "nlid/models/stepper.hpp"
#include "nlid/models/transfer_function_block.hpp"
#include "nlid/models/uncertainty.hpp"
