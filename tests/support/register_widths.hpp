#pragma once
// Register widths this machine can run nlid::Batch values on: 16 bytes always, 32 and 64 where the
// CPU has them (nlid::cpu_register_bytes; run-time dispatch where they exceed the build's own
// width). Tests of batched code run once per width (tests/core/batch_test.cpp,
// tests/greybox/batched_test.cpp).

#include <cstddef>
#include <vector>

#include "nlid/core/batch.hpp"

namespace nlid_test {

inline std::vector<std::size_t> register_widths() {
  std::vector<std::size_t> r;
  for (std::size_t b : {std::size_t{16}, std::size_t{32}, std::size_t{64}})
    if (b <= nlid::cpu_register_bytes()) r.push_back(b);
  return r;
}

}  // namespace nlid_test
