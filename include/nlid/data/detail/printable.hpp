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
  if (!append_shown(out, cell, false, limit)) out += "...";
  return out;
}

}  // namespace nlid::detail
