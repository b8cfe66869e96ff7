#pragma once
/// @file
/// UTF-8 well-formedness, shared by the JSON writer (which refuses malformed text) and the places
/// that make names out of bytes nlid does not control (file names) and so must repair them.

#include <cstddef>
#include <string>
#include <string_view>

namespace nlid {

namespace detail {

/// Length of the UTF-8 sequence starting at s[i] if it is well-formed (Unicode table 3-7:
/// no overlongs, no surrogates, nothing above U+10FFFF), else 0.
inline std::size_t utf8_sequence_length(std::string_view s, std::size_t i) noexcept {
  const auto b = [&](std::size_t k) { return static_cast<unsigned char>(s[k]); };
  const unsigned char c = b(i);
  if (c < 0x80) return 1;
  std::size_t n = 0;
  unsigned char lo = 0x80, hi = 0xBF;  // allowed range of the second byte
  if (c >= 0xC2 && c <= 0xDF) {
    n = 2;
  } else if (c >= 0xE0 && c <= 0xEF) {
    n = 3;
    if (c == 0xE0) lo = 0xA0;
    if (c == 0xED) hi = 0x9F;  // excludes UTF-16 surrogates
  } else if (c >= 0xF0 && c <= 0xF4) {
    n = 4;
    if (c == 0xF0) lo = 0x90;
    if (c == 0xF4) hi = 0x8F;
  } else {
    return 0;
  }
  if (i + n > s.size()) return 0;
  if (b(i + 1) < lo || b(i + 1) > hi) return 0;
  for (std::size_t k = 2; k < n; ++k) {
    if (b(i + k) < 0x80 || b(i + k) > 0xBF) return 0;
  }
  return n;
}

/// Bytes of the character at s[i] as a message shows it unchanged, or 0 where the message shows
/// the byte s[i] as \xHH instead: a byte that is not part of well-formed UTF-8, or a control
/// character (line feed and tab are kept if `keep_layout`).
inline std::size_t shown_length(std::string_view s, std::size_t i, bool keep_layout) noexcept {
  const auto c = static_cast<unsigned char>(s[i]);
  if ((c < 0x20 && !(keep_layout && (c == '\n' || c == '\t'))) || c == 0x7f) return 0;
  return utf8_sequence_length(s, i);
}

/// Appends `s` to `out`, each byte that `shown_length` refuses as \xHH. Stops between characters
/// once `out` holds `limit` bytes and some of `s` remains; returns false then.
inline bool append_shown(std::string& out, std::string_view s, bool keep_layout,
                         std::size_t limit = std::string::npos) {
  constexpr const char* hex = "0123456789ABCDEF";
  for (std::size_t i = 0; i < s.size();) {
    const std::size_t n = shown_length(s, i, keep_layout);
    if (n == 0) {
      const auto c = static_cast<unsigned char>(s[i]);
      out += "\\x";
      out += hex[c >> 4];
      out += hex[c & 15];
      ++i;
    } else {
      out.append(s.substr(i, n));
      i += n;
    }
    if (out.size() >= limit && i < s.size()) return false;
  }
  return true;
}

/// `text` as a message can carry it: each control character other than line feed and tab, and
/// each byte that is not well-formed UTF-8, as \xHH; everything else unchanged (text that needs
/// nothing escaped is returned as it came, without a second pass). Error messages quote what
/// users and files supply (names, cells, paths); a NUL byte cut `what()` short, and a malformed
/// byte made the text unfit for the JSON reports and logs that carry it.
inline std::string message_safe(std::string text) {
  std::size_t i = 0;  // the first byte to escape, if any
  while (i < text.size()) {
    const std::size_t n = shown_length(text, i, true);
    if (n == 0) break;
    i += n;
  }
  if (i == text.size()) return text;
  std::string out(text, 0, i);
  append_shown(out, std::string_view(text).substr(i), true);
  return out;
}

}  // namespace detail

/// Byte offset of the first byte of `s` that is not part of well-formed UTF-8, or npos.
inline std::size_t first_invalid_utf8(std::string_view s) noexcept {
  for (std::size_t i = 0; i < s.size();) {
    const std::size_t n = detail::utf8_sequence_length(s, i);
    if (n == 0) return i;
    i += n;
  }
  return std::string_view::npos;
}

/// `s` with each byte that is not part of well-formed UTF-8 replaced by U+FFFD, as the HTML and
/// SVG writers do. For names made of bytes from outside (a Latin-1 file name such as
/// "mess\xE4ung.csv" gives "mess\uFFFDung"): model files and reports hold UTF-8 only, and guessing
/// the name's encoding (Latin-1? CP1252? Shift-JIS?) would print a wrong letter as if it were right.
inline std::string valid_utf8(std::string_view s) {
  std::string out;
  out.reserve(s.size());
  for (std::size_t i = 0; i < s.size();) {
    const std::size_t n = detail::utf8_sequence_length(s, i);
    if (n == 0) {
      out.append("\xEF\xBF\xBD");
      ++i;
    } else {
      out.append(s.substr(i, n));
      i += n;
    }
  }
  return out;
}

}  // namespace nlid
