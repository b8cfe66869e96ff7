# g++ compiles the library even when the build uses another compiler: every header at once
# (JOB=umbrella: nlid/nlid.hpp at -O0, object code) and the minimal example (JOB=minimal: -O2),
# with the project's warnings as errors. One ctest entry per job.
# The umbrella's object is then linked twice into one program: a header-only library is included
# by many files of a user's project, and a function or variable defined in a header without
# `inline` would be a strong symbol in each of them ("multiple definition" at the user's link).
# Two copies of one object show exactly that, without compiling a second translation unit.
#   cmake -DCXX=g++ -DINCLUDES="a;b" -DSOURCE_DIR=... -DWORK=... -DJOB=umbrella|minimal -P gxx_check.cmake
set(flags -std=c++20 -Wall -Wextra -Wpedantic -Werror)
foreach(dir IN LISTS INCLUDES)
  list(APPEND flags "-isystem${dir}")
endforeach()
list(PREPEND flags "-I${SOURCE_DIR}/include")
file(MAKE_DIRECTORY "${WORK}")
if(JOB STREQUAL "umbrella")
  file(WRITE "${WORK}/umbrella.cpp" "#include \"nlid/nlid.hpp\"\n")
  set(job -O0 -c "${WORK}/umbrella.cpp" -o "${WORK}/umbrella.o")
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
if(JOB STREQUAL "umbrella")
  file(WRITE "${WORK}/main.cpp" "int main() { return 0; }\n")
  execute_process(COMMAND "${CXX}" "${WORK}/umbrella.o" "${WORK}/umbrella.o" "${WORK}/main.cpp"
                          -o "${WORK}/umbrella_twice"
                  RESULT_VARIABLE rc ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${what} defines a symbol that two files of one program cannot both include "
                        "(a function or variable in a header needs `inline`):\n${err}")
  endif()
endif()
message(STATUS "${CXX}: ${what} compiles without warnings")
