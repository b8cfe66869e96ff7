// A scratch directory for one test process, removed when the process exits.
// ctest runs every test case in its own process, so a fixed name would be shared by concurrent
// cases, and a per-process name that is never removed piles up in the temporary directory.
#pragma once

#include <filesystem>
#include <string>
#include <system_error>

#include <unistd.h>

namespace nlid_test {

inline const std::filesystem::path& scratch_dir() {
  struct Dir {
    std::filesystem::path path;
    Dir() : path(std::filesystem::temp_directory_path() / ("nlid_test_" + std::to_string(::getpid()))) {
      std::filesystem::create_directories(path);
    }
    ~Dir() {
      std::error_code ignored;  // best effort: a failed clean-up must not fail the test run
      std::filesystem::remove_all(path, ignored);
    }
  };
  static const Dir dir;
  return dir.path;
}

}  // namespace nlid_test
