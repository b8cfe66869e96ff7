#include "nlid/core/atomic_file.hpp"

#include <catch2/catch.hpp>
#include <filesystem>

namespace fs = std::filesystem;

TEST_CASE("write_file_atomically replaces the file and leaves no temporary behind") {
  const fs::path dir = fs::temp_directory_path() / "nlid_atomic_test";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string path = (dir / "out.txt").string();
  nlid::write_file_atomically(path, "first");
  nlid::write_file_atomically(path, "second\nline");
  CHECK(nlid::read_file(path) == "second\nline");
  int entries = 0;
  for (const auto& e : fs::directory_iterator(dir)) {
    (void)e;
    ++entries;
  }
  CHECK(entries == 1);
  fs::remove_all(dir);
}

TEST_CASE("atomic write and read report the file on failure") {
  CHECK_THROWS_WITH(nlid::write_file_atomically("/nonexistent-dir-xyz/out.txt", "x"),
                    Catch::Contains("directory does not exist") &&
                        Catch::Contains("/nonexistent-dir-xyz/out.txt"));
  CHECK_THROWS_WITH(nlid::read_file("/nonexistent-file-xyz.csv"),
                    Catch::Contains("file not found") && Catch::Contains("nonexistent-file-xyz.csv"));
  CHECK_THROWS_WITH(nlid::read_file(fs::temp_directory_path().string()),
                    Catch::Contains("directory"));
}
