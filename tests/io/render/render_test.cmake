# CTest driver of the browser check (run with cmake -P):
#   cmake -DGENERATOR=<nlid_io_render_report> -DCHECK=<render_check.sh> -DOUT_DIR=<dir>
#         [-DDATA_DIR=<examples/data/throttle>] -P render_test.cmake
# 1. the generator writes OUT_DIR/report.html and prints how many charts it holds;
# 2. render_check.sh renders it in headless Chromium (DOM status + screenshot) and must pass;
# 3. the same check must FAIL on a copy with an injected script error, so a check that has
#    stopped looking (e.g. a status script that never runs) cannot pass unnoticed.
foreach(var GENERATOR CHECK OUT_DIR)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "render_test.cmake: -D${var}=... is required")
  endif()
endforeach()
find_program(BASH_PROGRAM bash REQUIRED)
file(REMOVE_RECURSE "${OUT_DIR}")
file(MAKE_DIRECTORY "${OUT_DIR}")
set(report "${OUT_DIR}/report.html")

execute_process(COMMAND "${GENERATOR}" "${report}" ${DATA_DIR}
  RESULT_VARIABLE rc OUTPUT_VARIABLE charts ERROR_VARIABLE err OUTPUT_STRIP_TRAILING_WHITESPACE)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "report generator failed (${rc}): ${err}")
endif()
message(STATUS "report written: ${report} (${charts} charts)")

execute_process(COMMAND "${BASH_PROGRAM}" "${CHECK}" "${report}" "${charts}" "${OUT_DIR}/report.png"
  RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "render check failed for ${report}")
endif()

file(READ "${report}" html)
string(REPLACE "</main>" "<script>nlid_render_selftest_undefined();</script></main>" html "${html}")
file(WRITE "${OUT_DIR}/broken.html" "${html}")
execute_process(COMMAND "${BASH_PROGRAM}" "${CHECK}" "${OUT_DIR}/broken.html" "${charts}"
  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(rc EQUAL 0 OR NOT err MATCHES "nlid_render_selftest_undefined")
  message(FATAL_ERROR "render check did not catch an injected script error (rc=${rc}):\n${out}${err}")
endif()
message(STATUS "render check rejects a broken report: ok")
