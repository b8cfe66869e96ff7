// expect: RegressorFunction
// Expect-compile-failure: a custom regressor whose function returns `double` when called with a
// Dual (here through a double-only function of `value_of(y)`; `[](auto y) -> double` is the same)
// would feed the estimator a zero derivative, because a double converts to a constant dual. It
// must be rejected at the declaration, with the concept named in the diagnostic.
#include <cmath>

#include "nlid/regressors/custom.hpp"

double valve_area(double opening) { return 1.0 - std::cos(opening); }  // knows only double

auto area = nlid::custom_regressor<nlid::OutputLag<1>>(
    "area(y1(t-1))", [](auto y) { return valve_area(nlid::value_of(y)); });  // error here

int main() { return area.size() == 1 ? 0 : 1; }
