// The exception rule every libFuzzer harness here enforces, in one place: a parser or model
// builder may refuse its input with nlid::Error and nothing else.
#pragma once

#include <cstdlib>
#include <exception>
#include <new>
#include <string>
#include <typeinfo>

#include "nlid/core/error.hpp"

namespace nlid_fuzz {

/// Runs `f` and returns true if it completed, false if it threw nlid::Error (the contract's
/// answer to bad input). Any other exception is handed to `defect` (which reports and aborts)
/// as a message naming `step`. std::bad_alloc has its own wording: it means a size read from
/// the input (`source`: "spec", "file", ...) was used before it was checked.
template <class F, class Defect>
bool run_step(const char* step, const char* source, F&& f, Defect&& defect) {
  try {
    f();
    return true;
  } catch (const nlid::Error&) {
    return false;
  } catch (const std::bad_alloc&) {
    defect(std::string(step) + ": std::bad_alloc (a size from the " + source + " was not validated)");
  } catch (const std::exception& e) {
    defect(std::string(step) + ": " + typeid(e).name() + ": " + e.what());
  } catch (...) {
    defect(std::string(step) + ": an exception of unknown type");
  }
  std::abort();  // a reporter that returned must not turn a defect into "accepted"
}

}  // namespace nlid_fuzz
