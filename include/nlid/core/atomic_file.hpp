#pragma once
/// @file
/// Atomic file writes: a reader (or a crash) never sees a half-written file.
///
/// The content goes to a temporary file in the same directory (same file system, so the final
/// rename is atomic on POSIX), is flushed, and is then renamed over the destination. On any
/// failure the temporary file is removed and `nlid::Error` names the destination file.

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#if defined(__unix__) || defined(__APPLE__)
#include <fcntl.h>
#include <unistd.h>
#endif

#include "nlid/core/error.hpp"

namespace nlid {

namespace detail {

// A temporary name next to `target`: hidden, unique, and short enough for the file system's name
// limit even when the target's own name is long.
inline std::filesystem::path temporary_sibling(const std::filesystem::path& target) {
  const std::filesystem::path dir = target.has_parent_path() ? target.parent_path() : std::filesystem::path(".");
  std::string stem = target.filename().string();
  if (stem.size() > 64) stem.resize(64);
  std::random_device rd;
  return dir / ("." + stem + ".tmp" + std::to_string(rd()) + std::to_string(rd()));
}

// Writes `content` to the new file `tmp` and flushes it to the device (fsync where POSIX has
// it), so that the rename that follows can never expose an empty or partial file after a crash.
inline void write_temporary(const std::filesystem::path& tmp, std::string_view content, const Location& where) {
#if defined(__unix__) || defined(__APPLE__)
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
  if (fd < 0) {
    throw Error("cannot create temporary file '" + tmp.string() + "': " + std::strerror(errno), where);
  }
  const char* p = content.data();
  std::size_t left = content.size();
  int err = 0;
  while (left > 0) {
    const ssize_t n = ::write(fd, p, left);
    if (n < 0) {
      if (errno == EINTR) continue;
      err = errno;
      break;
    }
    p += n;
    left -= static_cast<std::size_t>(n);
  }
  if (err == 0 && ::fsync(fd) != 0) err = errno;
  if (::close(fd) != 0 && err == 0) err = errno;
  if (err != 0) {
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    throw Error(std::string("write failed: ") + std::strerror(err), where);
  }
#else
  std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
  if (!out) throw Error("cannot create temporary file '" + tmp.string() + "'", where);
  out.write(content.data(), static_cast<std::streamsize>(content.size()));
  out.flush();
  if (!out) {
    out.close();
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    throw Error("write failed (disk full?)", where);
  }
#endif
}

inline Location file_location(const std::string& path) {
  Location where;
  where.file = path;
  return where;
}

// Checks that `path` can be replaced: its directory exists and it is not itself a directory.
inline void check_writable_target(const std::string& path) {
  namespace fs = std::filesystem;
  if (path.empty()) throw Error("empty file name: give a path to write to", file_location(path));
  const fs::path target(path);
  const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw Error("directory does not exist: '" + dir.string() + "'", file_location(path));
  if (fs::is_directory(target, ec)) throw Error("path is a directory, not a file", file_location(path));
}

}  // namespace detail

/// Writes `content` to `path` atomically (temp file + rename). Throws `nlid::Error` on failure.
inline void write_file_atomically(const std::string& path, std::string_view content) {
  namespace fs = std::filesystem;
  const Location where = detail::file_location(path);
  detail::check_writable_target(path);
  const fs::path target(path);
  const fs::path tmp = detail::temporary_sibling(target);
  detail::write_temporary(tmp, content, where);
  std::error_code ec;
  fs::rename(tmp, target, ec);
  if (ec) {
    std::error_code ec2;
    fs::remove(tmp, ec2);
    throw Error("cannot move temporary file into place: " + ec.message(), where);
  }
}

/// Writes several files that belong together (a generated header and its source) so that a
/// failure leaves all of them as they were: every target is checked and every content written
/// to a temporary file first; only then are the temporaries renamed into place. Throws
/// `nlid::Error` naming the file that failed.
inline void write_files_atomically(const std::vector<std::pair<std::string, std::string_view>>& files) {
  namespace fs = std::filesystem;
  for (const auto& [path, content] : files) detail::check_writable_target(path);
  std::vector<fs::path> tmps;
  auto discard = [&] {
    std::error_code ec;
    for (const auto& t : tmps) fs::remove(t, ec);
  };
  try {
    for (const auto& [path, content] : files) {
      tmps.push_back(detail::temporary_sibling(fs::path(path)));
      try {
        detail::write_temporary(tmps.back(), content, detail::file_location(path));
      } catch (...) {
        tmps.pop_back();  // write_temporary removed its own file
        throw;
      }
    }
  } catch (...) {
    discard();
    throw;
  }
  for (std::size_t i = 0; i < files.size(); ++i) {
    std::error_code ec;
    fs::rename(tmps[i], fs::path(files[i].first), ec);
    if (ec) {
      // Only a file-system failure between the checks above and here can land here.
      tmps.erase(tmps.begin(), tmps.begin() + static_cast<std::ptrdiff_t>(i));
      discard();
      throw Error("cannot move temporary file into place: " + ec.message() +
                      (i > 0 ? " (the " + std::to_string(i) + " file(s) before it were already replaced)" : std::string()),
                  detail::file_location(files[i].first));
    }
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
  // Read in blocks through istream::read, which turns a failing read (an I/O error, a file that
  // vanished underneath) into badbit; istreambuf_iterator just stops, as at the end of the file,
  // and the caller would parse the truncated text as if it were all.
  std::string s;
  char block[1 << 16];
  while (in.read(block, sizeof block) || in.gcount() > 0) {
    s.append(block, static_cast<std::size_t>(in.gcount()));
    if (!in) break;
  }
  if (in.bad() || !in.eof()) {
    throw Error("read error after " + std::to_string(s.size()) + " bytes; the file is incomplete or unreadable", where);
  }
  return s;
}

}  // namespace nlid
