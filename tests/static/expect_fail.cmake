# Compiles SOURCE (-fsyntax-only) and passes only if the compiler rejects it and its diagnostic
# names EXPECT (the concept the misuse violates): the error must point at the user's mistake.
#   cmake -DCXX=... -DSOURCE=... -DINCLUDES="a;b" -DEXPECT=... -P expect_fail.cmake
set(args -std=c++20 -fsyntax-only)
foreach(dir IN LISTS INCLUDES)
  list(APPEND args "-I${dir}")
endforeach()
execute_process(COMMAND "${CXX}" ${args} "${SOURCE}" RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(rc EQUAL 0)
  message(FATAL_ERROR "${SOURCE} compiled, but it must be rejected")
endif()
string(FIND "${err}" "${EXPECT}" pos)
if(pos EQUAL -1)
  message(FATAL_ERROR "${SOURCE} was rejected, but the diagnostic does not name '${EXPECT}':\n${err}")
endif()
string(REGEX MATCHALL "error:" errors "${err}")
list(LENGTH errors n)
message(STATUS "${SOURCE}: rejected as expected (${n} error lines, names ${EXPECT})")
