# Included by CTest after the grouped tests (tests/CMakeLists.txt): the COST of the longest ones
# (tests/test_costs.cmake). A test is named only if this tree added it (lumen_grouped_tests, appended by the groups'
# scripts; test_scenes is not built in the sanitizer tree).
include(${CMAKE_CURRENT_LIST_DIR}/test_costs.cmake)
foreach(entry IN LISTS lumen_test_costs)
  string(REPLACE " " ";" entry "${entry}")
  list(GET entry 0 name)
  list(GET entry 1 seconds)
  list(FIND lumen_grouped_tests "${name}" index)
  if(NOT index EQUAL -1)
    set_tests_properties("${name}" PROPERTIES COST ${seconds})
  endif()
endforeach()
