// Text checks on generated C, shared by the code-generation tests of the library and of the
// nlid-codegen tool (no nlid dependency, so the tool tests stay light).
#pragma once

#include <string>

namespace nlid_test {

/// The C text without its comments (model descriptions may contain any word).
inline std::string c_code_only(const std::string& s) {
  std::string out;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (s.compare(i, 2, "/*") == 0) {
      i = s.find("*/", i + 2);
      if (i == std::string::npos) break;
      ++i;
      continue;
    }
    out += s[i];
  }
  return out;
}

}  // namespace nlid_test
