# g++ compiles the library even when the build uses another compiler: every header at once
# (nlid/nlid.hpp, -fsyntax-only: parsing and every template instantiated by non-template code)
# and the minimal example (-O2, object code), with the project's warnings as errors.
#   cmake -DCXX=g++ -DINCLUDES="a;b" -DSOURCE_DIR=... -DWORK=... -P gxx_check.cmake
set(flags -std=c++20 -Wall -Wextra -Wpedantic -Werror)
foreach(dir IN LISTS INCLUDES)
  list(APPEND flags "-isystem${dir}")
endforeach()
list(PREPEND flags "-I${SOURCE_DIR}/include")
file(MAKE_DIRECTORY "${WORK}")
file(WRITE "${WORK}/umbrella.cpp" "#include \"nlid/nlid.hpp\"\n")
foreach(job "-fsyntax-only;${WORK}/umbrella.cpp" "-O2;-c;${SOURCE_DIR}/examples/minimal_nlarx.cpp;-o;${WORK}/minimal_nlarx.o")
  execute_process(COMMAND "${CXX}" ${flags} ${job} RESULT_VARIABLE rc ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${CXX} failed on ${job}:\n${err}")
  endif()
endforeach()
message(STATUS "${CXX}: nlid/nlid.hpp and examples/minimal_nlarx.cpp compile without warnings")
