# Script behind the CTest test `package_consumer` (run with cmake -P):
#   1. cmake --install the ICE build tree ICE_BINARY_DIR into WORK_DIR/prefix,
#   2. configure and build tests/package_consumer against that prefix only,
#   3. run the resulting executable.
# Inputs (-D): ICE_BINARY_DIR, CONSUMER_SOURCE_DIR, WORK_DIR, BUILD_TYPE, GENERATOR, CXX_COMPILER.
cmake_minimum_required(VERSION 3.16)
foreach(_var ICE_BINARY_DIR CONSUMER_SOURCE_DIR WORK_DIR BUILD_TYPE GENERATOR CXX_COMPILER)
  if(NOT DEFINED ${_var})
    message(FATAL_ERROR "PackageConsumerTest.cmake: -D${_var}=... is required")
  endif()
endforeach()

function(run_step name)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE _rc OUTPUT_VARIABLE _out ERROR_VARIABLE _out)
  if(NOT _rc EQUAL 0)
    message("${_out}")
    message(FATAL_ERROR "package_consumer: step '${name}' failed (${_rc})")
  endif()
  message(STATUS "package_consumer: ${name}: ok")
  set(_last_output "${_out}" PARENT_SCOPE)
endfunction()

file(REMOVE_RECURSE "${WORK_DIR}")
file(MAKE_DIRECTORY "${WORK_DIR}")
set(_prefix "${WORK_DIR}/prefix")

run_step("install" "${CMAKE_COMMAND}" --install "${ICE_BINARY_DIR}" --prefix "${_prefix}" --config "${BUILD_TYPE}")
run_step("configure consumer" "${CMAKE_COMMAND}" -S "${CONSUMER_SOURCE_DIR}" -B "${WORK_DIR}/build"
  -G "${GENERATOR}"
  "-DCMAKE_BUILD_TYPE=${BUILD_TYPE}"
  "-DCMAKE_CXX_COMPILER=${CXX_COMPILER}"
  "-DCMAKE_PREFIX_PATH=${_prefix}"
  "-DICE_EXPECTED_PREFIX=${_prefix}"
  -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF
  -DCMAKE_FIND_PACKAGE_NO_PACKAGE_REGISTRY=ON)
run_step("build consumer" "${CMAKE_COMMAND}" --build "${WORK_DIR}/build" --config "${BUILD_TYPE}")
set(_exe "${WORK_DIR}/build/ice_package_consumer")
if(NOT EXISTS "${_exe}")
  set(_exe "${WORK_DIR}/build/${BUILD_TYPE}/ice_package_consumer")
endif()
run_step("run consumer" "${_exe}")
message("${_last_output}")
