#include "nlid/core/atomic_file.hpp"

#include <catch2/catch.hpp>
#include <filesystem>
#include <string>

namespace fs = std::filesystem;

namespace {

// An empty scratch directory under the system's temporary directory.
fs::path fresh_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// Number of entries in `dir` (files left behind show up here).
int entries(const fs::path& dir) {
  int n = 0;
  for (const auto& e : fs::directory_iterator(dir)) {
    (void)e;
    ++n;
  }
  return n;
}

}  // namespace

TEST_CASE("write_file_atomically replaces the file and leaves no temporary behind") {
  const fs::path dir = fresh_dir("nlid_atomic_test");
  const std::string path = (dir / "out.txt").string();
  nlid::write_file_atomically(path, "first");
  nlid::write_file_atomically(path, "second\nline");
  CHECK(nlid::read_file(path) == "second\nline");
  CHECK(entries(dir) == 1);
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

TEST_CASE("files written as a set change together or not at all") {
  const fs::path dir = fresh_dir("nlid_atomic_set_test");
  const std::string h = (dir / "m.h").string(), c = (dir / "m.c").string();
  nlid::write_files_atomically({{h, "header 1"}, {c, "source 1"}});
  CHECK(nlid::read_file(h) == "header 1");
  CHECK(nlid::read_file(c) == "source 1");
  // The second target is a directory: the first file must keep its old content.
  fs::remove(c);
  fs::create_directories(dir / "m.c");
  CHECK_THROWS_WITH(nlid::write_files_atomically({{h, "header 2"}, {c, "source 2"}}),
                    Catch::Contains("path is a directory") && Catch::Contains("m.c"));
  CHECK(nlid::read_file(h) == "header 1");
  // Nothing but m.h and the directory m.c is left behind (no temporaries).
  CHECK(entries(dir) == 2);
  fs::remove_all(dir);
}

TEST_CASE("a long file name still gets a temporary within the name limit") {
  const fs::path dir = fresh_dir("nlid_atomic_long_test");
  const std::string name(240, 'n');
  const std::string path = (dir / (name + ".json")).string();
  nlid::write_file_atomically(path, "{}");
  CHECK(nlid::read_file(path) == "{}");
  fs::remove_all(dir);
}

TEST_CASE("read_file reports a failing read instead of returning what came before it") {
  // Reading /proc/self/mem from offset 0 fails with EIO (that page is never mapped): a file that
  // opens but cannot be read, as a disk error would leave it.
  const std::string mem = "/proc/self/mem";
  if (!fs::exists(mem)) {
    SUCCEED("no /proc/self/mem on this system");
    return;
  }
  CHECK_THROWS_AS(nlid::read_file(mem), nlid::Error);
  CHECK_THROWS_WITH(nlid::read_file(mem), Catch::Contains("read error") && Catch::Contains("/proc/self/mem"));
}
