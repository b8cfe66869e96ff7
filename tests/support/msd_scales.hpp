#pragma once
// Data scales of a mass-spring-damper record (position 0..2 about 1, input 0..1 at 100 Hz), from
// which the diagnosis effects take their shape constants: the model-file tests and the fuzzer's
// seed writer build augmented models from the same candidates.
#include "nlid/diagnose/effects.hpp"

namespace nlid_test {

inline nlid::DataScales msd_effect_scales() {
  nlid::DataScales s;
  s.ts = 0.01;
  s.q_lo = 0.0;
  s.q_hi = 2.0;
  s.q_mid = 1.0;
  s.speed = 3.0;
  s.accel = 30.0;
  s.stiffness = 100.0;
  s.u_lo = 0.0;
  s.u_hi = 1.0;
  s.u_abs = 1.0;
  return s;
}

}  // namespace nlid_test
