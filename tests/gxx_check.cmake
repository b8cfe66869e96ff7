# g++ compiles the library even when the build uses another compiler: every header at once
# (JOB=umbrella: nlid/nlid.hpp, -fsyntax-only: parsing and every template instantiated by
# non-template code) and the minimal example (JOB=minimal: -O2, object code), with the project's
# warnings as errors. One ctest entry per job.
#   cmake -DCXX=g++ -DINCLUDES="a;b" -DSOURCE_DIR=... -DWORK=... -DJOB=umbrella|minimal -P gxx_check.cmake
set(flags -std=c++20 -Wall -Wextra -Wpedantic -Werror)
foreach(dir IN LISTS INCLUDES)
  list(APPEND flags "-isystem${dir}")
endforeach()
list(PREPEND flags "-I${SOURCE_DIR}/include")
file(MAKE_DIRECTORY "${WORK}")
if(JOB STREQUAL "umbrella")
  file(WRITE "${WORK}/umbrella.cpp" "#include \"nlid/nlid.hpp\"\n")
  set(job -fsyntax-only "${WORK}/umbrella.cpp")
  set(what "nlid/nlid.hpp")
elseif(JOB STREQUAL "minimal")
  set(job -O2 -c "${SOURCE_DIR}/examples/minimal_nlarx.cpp" -o "${WORK}/minimal_nlarx.o")
  set(what "examples/minimal_nlarx.cpp")
else()
  message(FATAL_ERROR "gxx_check.cmake: JOB must be umbrella or minimal, got '${JOB}'")
endif()
execute_process(COMMAND "${CXX}" ${flags} ${job} RESULT_VARIABLE rc ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "${CXX} failed on ${job}:\n${err}")
endif()
message(STATUS "${CXX}: ${what} compiles without warnings")
