# Browser render test of nlid::HtmlReport. Included from tests/CMakeLists.txt:
#   include("${CMAKE_CURRENT_SOURCE_DIR}/io/render/render.cmake")
# Needs Chromium at test time (Debian package 'chromium'); the test fails without it.
add_executable(nlid_io_render_report "${CMAKE_CURRENT_LIST_DIR}/make_report.cpp")
target_link_libraries(nlid_io_render_report PRIVATE nlid::nlid)
target_compile_options(nlid_io_render_report PRIVATE ${NLID_WARNINGS})
add_test(NAME "io: report renders in chromium"
  COMMAND ${CMAKE_COMMAND}
          "-DGENERATOR=$<TARGET_FILE:nlid_io_render_report>"
          "-DCHECK=${CMAKE_CURRENT_LIST_DIR}/render_check.sh"
          "-DOUT_DIR=${CMAKE_CURRENT_BINARY_DIR}/io_render"
          "-DDATA_DIR=${PROJECT_SOURCE_DIR}/examples/data/throttle"
          -P "${CMAKE_CURRENT_LIST_DIR}/render_test.cmake")
set_tests_properties("io: report renders in chromium" PROPERTIES TIMEOUT 300 LABELS browser)
