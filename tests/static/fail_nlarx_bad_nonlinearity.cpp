// expect: Nonlinearity
// Expect-compile-failure: a component that is not a Nonlinearity must be rejected at the
// declaration of the model type, with the concept named in the diagnostic.
#include <span>
#include <string>
#include <vector>

#include "nlid/models/nlarx.hpp"
#include "nlid/regressors.hpp"

struct NotANonlinearity {  // no initialize(), no parameter_names()
  static constexpr int num_inputs = 3;
  static constexpr int num_params = 4;
  int input_dimension() const { return 3; }
  int num_parameters() const { return 4; }
};

nlid::Nlarx<nlid::LaggedRegressors<2, 1, 0>, NotANonlinearity>* model = nullptr;  // error here

int main() { return model == nullptr ? 0 : 1; }
