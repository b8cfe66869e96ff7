// expect: ScalarNonlinearity
// Expect-compile-failure: a Hammerstein-Wiener input block must be a one-input nonlinearity.
#include "nlid/models/hammerstein_wiener.hpp"
#include "nlid/nonlinearities/linear.hpp"
#include "nlid/nonlinearities/saturation.hpp"

nlid::HammersteinWiener<nlid::LinearMap<2>, nlid::TransferFunctionBlock<2, 2, 1>, nlid::Saturation>* model = nullptr;

int main() { return model == nullptr ? 0 : 1; }
