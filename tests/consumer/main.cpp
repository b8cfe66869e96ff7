// Uses the installed package: a Dual-number derivative and an nlid::Error, printed and checked.
#include <cmath>
#include <cstdio>

#include "nlid/ad.hpp"  // an area umbrella: installed from its own file set
#include "nlid/core/error.hpp"

int main() {
  using D = nlid::Dual<double, 1>;
  const D x = D::variable(0.5, 0);
  const D f = exp(x) * x;  // f' = e^x (1 + x)
  const double expected = std::exp(0.5) * 1.5;
  if (std::abs(f.v[0] - expected) > 1e-14) return 1;
  try {
    nlid::require(false, "consumer check", nlid::at_parameter("k"));
  } catch (const nlid::Error& e) {
    std::printf("consumer ok: %s\n", e.what());
    return 0;
  }
  return 2;
}
