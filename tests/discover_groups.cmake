# Run after a test program is built (cmake -P, by lumen_grouped_tests in tests/CMakeLists.txt): lists its
# GoogleTest cases that match FILTER and writes OUT, a CTest script that adds them in groups, one process per group:
# the cases of one suite,
# at most GROUP_SIZE per process, named SUITE followed by SUFFIX (which tells apart the groups of one suite that
# other filters of the same program make) and, when the suite takes more than one group, /1, /2, ...; a case
# named in COSTS_FILE's lumen_test_costs (the long ones) runs alone under its own name SUITE.CASE, so that its
# COST still starts it first (tests/apply_test_costs.cmake: each name is appended to lumen_grouped_tests). Every
# test gets LABELS and runs in WORKING_DIRECTORY.
# Why: a test program loads about 200 shared libraries (OpenCascade through Netgen, OSMesa's LLVM, FFmpeg), 0.4 s a
# process in Release and 1 s under the sanitizers, which one process per case paid about 500 times a build.
# Inputs (-D): EXE, FILTER (a --gtest_filter, empty: every case), SUFFIX (may be empty), LABELS (','-separated),
# OUT, GROUP_SIZE, COSTS_FILE, WORKING_DIRECTORY, TIMEOUT (seconds, for the listing).
foreach(input EXE OUT GROUP_SIZE COSTS_FILE WORKING_DIRECTORY TIMEOUT)
  if(NOT DEFINED ${input} OR "${${input}}" STREQUAL "")
    message(FATAL_ERROR "discover_groups.cmake: -D${input} is required")
  endif()
endforeach()
if(NOT GROUP_SIZE MATCHES "^[1-9][0-9]*$")
  message(FATAL_ERROR "discover_groups.cmake: GROUP_SIZE must be a positive integer, got '${GROUP_SIZE}'")
endif()

# The long cases, which run alone (lumen_test_costs: "SUITE.CASE SECONDS" entries).
include("${COSTS_FILE}")
set(alone "")
foreach(entry IN LISTS lumen_test_costs)
  string(REGEX REPLACE " .*" "" name "${entry}")
  list(APPEND alone "${name}")
endforeach()

# The cases, as the program lists them: "Suite." lines, each followed by its "  Case" lines.
set(filter_arg "")
if(NOT "${FILTER}" STREQUAL "")
  set(filter_arg "--gtest_filter=${FILTER}")
endif()
execute_process(COMMAND "${EXE}" --gtest_list_tests ${filter_arg} WORKING_DIRECTORY "${WORKING_DIRECTORY}"
                TIMEOUT ${TIMEOUT} OUTPUT_VARIABLE listing ERROR_VARIABLE errors RESULT_VARIABLE result)
if(NOT result EQUAL 0)
  message(FATAL_ERROR
          "discover_groups.cmake: '${EXE} --gtest_list_tests ${filter_arg}' exited ${result}:\n${listing}${errors}")
endif()
if(listing MATCHES "[][;#\\\\\"]")
  message(FATAL_ERROR "discover_groups.cmake: ${EXE} lists a case whose name needs quoting (parameterised or typed "
                      "tests are not grouped here):\n${listing}")
endif()
string(REPLACE "\n" ";" lines "${listing}")
set(suites "")
foreach(line IN LISTS lines)
  if(line MATCHES "^([A-Za-z_][A-Za-z0-9_]*)\\.$")
    set(suite "${CMAKE_MATCH_1}")
    list(APPEND suites "${suite}")
    set(cases_${suite} "")
  elseif(line MATCHES "^  ([A-Za-z_][A-Za-z0-9_]*)$")
    list(APPEND cases_${suite} "${CMAKE_MATCH_1}")
  endif()
endforeach()

# One add_test per group.
set(script "# Written by tests/discover_groups.cmake from ${EXE} --gtest_list_tests ${filter_arg}\n")
string(REPLACE "," ";" labels "${LABELS}")
macro(add_group name filter)
  string(APPEND script "add_test([=[${name}]=] [=[${EXE}]=] [=[--gtest_filter=${filter}]=])\n"
         "set_tests_properties([=[${name}]=] PROPERTIES WORKING_DIRECTORY [=[${WORKING_DIRECTORY}]=] "
         "LABELS [=[${labels}]=])\n" "list(APPEND lumen_grouped_tests [=[${name}]=])\n")
endmacro()
foreach(suite IN LISTS suites)
  set(grouped "")
  foreach(case IN LISTS cases_${suite})
    list(FIND alone "${suite}.${case}" index)
    if(index EQUAL -1)
      list(APPEND grouped "${suite}.${case}")
    else()
      add_group("${suite}.${case}" "${suite}.${case}")
    endif()
  endforeach()
  list(LENGTH grouped n)
  if(n EQUAL 0)
    continue()
  endif()
  math(EXPR n_groups "(${n} + ${GROUP_SIZE} - 1) / ${GROUP_SIZE}")
  foreach(g RANGE 1 ${n_groups})
    math(EXPR first "(${g} - 1) * ${GROUP_SIZE}")
    list(SUBLIST grouped ${first} ${GROUP_SIZE} members)
    list(JOIN members ":" filter)
    if(n_groups EQUAL 1)
      add_group("${suite}${SUFFIX}" "${filter}")
    else()
      add_group("${suite}${SUFFIX}/${g}" "${filter}")
    endif()
  endforeach()
endforeach()
file(WRITE "${OUT}" "${script}")
