#pragma once
/// @file
/// Text from files and users made safe to embed in error messages.

#include <cstddef>
#include <cstdio>
#include <string>

namespace nlid::detail {

/// The cell as it can be shown in a message: control characters (a NUL byte would end the
/// message early) as \xNN, and at most `limit` characters.
inline std::string printable(const std::string& cell, std::size_t limit = 80) {
  std::string out;
  for (const char ch : cell) {
    const auto c = static_cast<unsigned char>(ch);
    if (c < 0x20 || c == 0x7f) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02x", c);
      out += buf;
    } else {
      out += ch;
    }
    if (out.size() >= limit) {
      out += "...";
      break;
    }
  }
  return out;
}

}  // namespace nlid::detail
