#pragma once
/// @file
/// Atomic file writes: a reader (or a crash) never sees a half-written file.
///
/// The content goes to a temporary file in the same directory (same file system, so the final
/// rename is atomic on POSIX), is flushed, and is then renamed over the destination. On any
/// failure the temporary file is removed and `nlid::Error` names the destination file.

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <string_view>

#include "nlid/core/error.hpp"

namespace nlid {

/// Writes `content` to `path` atomically (temp file + rename). Throws `nlid::Error` on failure.
inline void write_file_atomically(const std::string& path, std::string_view content) {
  namespace fs = std::filesystem;
  Location where;
  where.file = path;
  const fs::path target(path);
  const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw Error("directory does not exist: '" + dir.string() + "'", where);

  std::random_device rd;
  const fs::path tmp = dir / ("." + target.filename().string() + ".tmp" + std::to_string(rd()));
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw Error("cannot create temporary file '" + tmp.string() + "'", where);
    out.write(content.data(), static_cast<std::streamsize>(content.size()));
    out.flush();
    if (!out) {
      out.close();
      fs::remove(tmp, ec);
      throw Error("write failed (disk full?)", where);
    }
  }
  fs::rename(tmp, target, ec);
  if (ec) {
    std::error_code ec2;
    fs::remove(tmp, ec2);
    throw Error("cannot move temporary file into place: " + ec.message(), where);
  }
}

/// Reads a whole file into a string. Throws `nlid::Error` naming the file if it cannot be read.
inline std::string read_file(const std::string& path) {
  Location where;
  where.file = path;
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw Error("file not found", where);
  if (std::filesystem::is_directory(path, ec)) throw Error("path is a directory, not a file", where);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error("cannot open file for reading", where);
  std::string s((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  return s;
}

}  // namespace nlid
