#pragma once
// A C locale whose decimal point is a comma (de_DE), set for LC_NUMERIC while the object lives.
// What follows LC_NUMERIC (strtod, printf) must not reach numbers nlid reads or writes as text:
// CSV cells, JSON, generated C. The test build makes the locale itself with localedef
// (tests/CMakeLists.txt, NLID_TEST_LOCPATH) so the check runs on a machine that has installed
// none; without that definition, the tests try the system's locales and skip if none has commas.
#include <clocale>
#include <cstdlib>
#include <string>

namespace nlid_test {

class DecimalCommaLocale {
 public:
  DecimalCommaLocale() {
#ifdef NLID_TEST_LOCPATH
    if (const char* old = std::getenv("LOCPATH")) old_locpath_ = old, had_locpath_ = true;
    ::setenv("LOCPATH", NLID_TEST_LOCPATH, 1);
#endif
    for (const char* name : {"de_DE.UTF-8", "de_DE.utf8", "de_DE", "fr_FR.UTF-8", "fr_FR.utf8", "fr_FR"}) {
      if (std::setlocale(LC_NUMERIC, name) != nullptr && std::string(std::localeconv()->decimal_point) == ",") {
        active_ = true;
        return;
      }
    }
    std::setlocale(LC_NUMERIC, saved_.c_str());
  }
  ~DecimalCommaLocale() {
    std::setlocale(LC_NUMERIC, saved_.c_str());
#ifdef NLID_TEST_LOCPATH
    if (had_locpath_) ::setenv("LOCPATH", old_locpath_.c_str(), 1);
    else ::unsetenv("LOCPATH");
#endif
  }
  DecimalCommaLocale(const DecimalCommaLocale&) = delete;
  DecimalCommaLocale& operator=(const DecimalCommaLocale&) = delete;

  /// True when LC_NUMERIC now has a decimal comma.
  [[nodiscard]] bool active() const { return active_; }
  /// True when the build made the locale: then a test must not skip (it could not fail).
  [[nodiscard]] static constexpr bool required() {
#ifdef NLID_TEST_LOCPATH
    return true;
#else
    return false;
#endif
  }

 private:
  std::string saved_ = std::setlocale(LC_NUMERIC, nullptr);
  std::string old_locpath_;
  bool had_locpath_ = false;
  bool active_ = false;
};

}  // namespace nlid_test
