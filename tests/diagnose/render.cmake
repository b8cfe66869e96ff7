# Browser render test of the diagnosis HTML report. Include from tests/CMakeLists.txt:
#   include("${CMAKE_CURRENT_SOURCE_DIR}/diagnose/render.cmake")
# Reuses the io layer's driver and checker (tests/io/render/): the generator writes a diagnosis
# report of a concealed dead time, Chromium must render it with every chart laid out and no
# script error, and the checker must reject a copy with an injected script error.
add_executable(nlid_diagnose_render_report "${CMAKE_CURRENT_LIST_DIR}/render/make_report.cpp")
target_link_libraries(nlid_diagnose_render_report PRIVATE nlid::nlid)
target_compile_options(nlid_diagnose_render_report PRIVATE ${NLID_WARNINGS})
find_package(Threads REQUIRED)
target_link_libraries(nlid_diagnose_render_report PRIVATE Threads::Threads)
add_test(NAME "diagnose: report renders in chromium"
  COMMAND ${CMAKE_COMMAND}
          "-DGENERATOR=$<TARGET_FILE:nlid_diagnose_render_report>"
          "-DCHECK=${CMAKE_CURRENT_LIST_DIR}/../io/render/render_check.sh"
          "-DOUT_DIR=${CMAKE_CURRENT_BINARY_DIR}/diagnose_render"
          -P "${CMAKE_CURRENT_LIST_DIR}/../io/render/render_test.cmake")
set_tests_properties("diagnose: report renders in chromium" PROPERTIES TIMEOUT 300 LABELS browser)
