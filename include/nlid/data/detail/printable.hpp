#pragma once
/// @file
/// Text from files and users made safe to embed in error messages.

#include <cstddef>
#include <string>
#include <string_view>

#include "nlid/core/utf8.hpp"

namespace nlid::detail {

/// The cell as it can be shown in a message: control characters (a NUL byte would end the
/// message early) and bytes that are not well-formed UTF-8 as \xHH, and at most about `limit`
/// bytes. A Latin-1 header such as "Winkel\xB0" stays readable, and the message stays UTF-8:
/// messages end up in JSON reports, whose writer refuses malformed text (the whole report would
/// be lost for one name). A cut never splits a character.
inline std::string printable(std::string_view cell, std::size_t limit = 80) {
  std::string out;
  for (std::size_t i = 0; i < cell.size();) {
    const auto c = static_cast<unsigned char>(cell[i]);
    const std::size_t n = (c < 0x20 || c == 0x7f) ? 0 : utf8_sequence_length(cell, i);
    if (n == 0) {
      append_escaped_byte(out, c);
      ++i;
    } else {
      out.append(cell.substr(i, n));
      i += n;
    }
    if (out.size() >= limit && i < cell.size()) {
      out += "...";
      break;
    }
  }
  return out;
}

}  // namespace nlid::detail
