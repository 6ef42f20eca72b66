# ctest script: install, configure + build the consumer, run it, check output.
file(REMOVE_RECURSE ${WORK_DIR})
set(prefix ${WORK_DIR}/prefix)
execute_process(COMMAND ${CMAKE_COMMAND} --install ${OPL_BINARY_DIR} --prefix ${prefix}
  RESULT_VARIABLE rc OUTPUT_QUIET)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "install failed: ${rc}")
endif()
if(NOT EXISTS ${prefix}/lib/cmake/opl/oplConfig.cmake AND NOT EXISTS ${prefix}/lib64/cmake/opl/oplConfig.cmake
   AND NOT EXISTS ${prefix}/lib/x86_64-linux-gnu/cmake/opl/oplConfig.cmake)
  message(FATAL_ERROR "no oplConfig.cmake under ${prefix}")
endif()
# Configures and builds the project in `source` against the installed OPL,
# into `binary`; stops the test naming `what` on failure.
function(build_against_install what source binary)
  execute_process(COMMAND ${CMAKE_COMMAND} -S ${source} -B ${binary} -G Ninja
    -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH=${prefix}
    RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${what} configure failed:\n${out}\n${err}")
  endif()
  execute_process(COMMAND ${CMAKE_COMMAND} --build ${binary}
    RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${what} build failed:\n${out}\n${err}")
  endif()
endfunction()
build_against_install(consumer ${CONSUMER_SOURCE_DIR} ${WORK_DIR}/build)
execute_process(COMMAND ${WORK_DIR}/build/consumer RESULT_VARIABLE rc OUTPUT_VARIABLE out)
if(NOT rc EQUAL 0 OR NOT out MATCHES "origin error [0-9.e+-]+ OK")
  message(FATAL_ERROR "consumer run failed (${rc}): ${out}")
endif()
message(STATUS "consumer: ${out}")

# The README's library program (examples/library/measure_spots.cc): README
# quotes the file verbatim, it builds against the installed OPL, and it prints
# the s that opl_measure gives for the same bundled example.
file(READ ${SOURCE_DIR}/README.md readme)
file(READ ${SOURCE_DIR}/examples/library/measure_spots.cc program)
string(FIND "${readme}" "```cpp\n${program}```" at)
if(at EQUAL -1)
  message(FATAL_ERROR "README.md does not quote examples/library/measure_spots.cc verbatim in a cpp block")
endif()
build_against_install(examples/library ${SOURCE_DIR}/examples/library ${WORK_DIR}/example)
set(cal ${SOURCE_DIR}/examples/prototype_calibration.json)
set(spots ${SOURCE_DIR}/examples/prototype_spots.csv)
execute_process(COMMAND ${WORK_DIR}/example/measure_spots ${cal} ${spots}
  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0 OR NOT out MATCHES "^s = ([0-9.]+) \\+- ([0-9.]+)\n$")
  message(FATAL_ERROR "measure_spots failed (${rc}): ${out}${err}")
endif()
set(s_program ${CMAKE_MATCH_1})
set(u_program ${CMAKE_MATCH_2})
if(NOT OPL_MEASURE)
  message(STATUS "measure_spots: ${out}(not compared: opl_measure not built)")
  return()
endif()
execute_process(COMMAND ${OPL_MEASURE} --calibration ${cal} --spots ${spots} --json
  RESULT_VARIABLE rc OUTPUT_VARIABLE json)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "opl_measure --json failed (${rc})")
endif()
string(JSON s_tool GET "${json}" scale_factor)
string(JSON u_tool GET "${json}" u_scale_factor)
# printf's %.6f against the tool's full digits.
execute_process(COMMAND ${PYTHON} -c
  "import sys; a = [float(x) for x in sys.argv[1:]]; sys.exit(0 if abs(a[0] - a[2]) <= 5.01e-7 and abs(a[1] - a[3]) <= 5.01e-7 and a[1] > 0 else 1)"
  ${s_program} ${u_program} ${s_tool} ${u_tool} RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "measure_spots printed s = ${s_program} +- ${u_program}, opl_measure gives ${s_tool} +- ${u_tool}")
endif()
message(STATUS "measure_spots: ${out}")
