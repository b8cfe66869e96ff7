#pragma once
// The nlid::Error a call throws, for tests that check its message and location (what and
// where); the test fails if the call throws nothing or something else.
#include <catch2/catch.hpp>

#include "nlid/core/error.hpp"

namespace nlid_test {

template <class F>
nlid::Error error_of(F&& f) {
  try {
    f();
  } catch (const nlid::Error& e) {
    return e;
  }
  FAIL("expected nlid::Error");
  return nlid::Error("unreachable");
}

}  // namespace nlid_test
