# SPDX-License-Identifier: Apache-2.0
# Configures and builds the fuzz targets (tests/fuzz/project) with clang; the CTest fuzz_build:
#   cmake -DCXX=clang++ -DSOURCE=tests/fuzz/project -DBINARY=folder -DGENERATOR=name
#         [-DMAKE_PROGRAM=path] -DJOBS=n -P build_fuzzers.cmake
# A missing clang or libFuzzer FAILS the test (CI must fuzz), with the packages to install.
if(NOT CXX)
  message(FATAL_ERROR "no clang++ was found when the project was configured: install clang-14 "
                      "and libclang-rt-14-dev (scripts/setup.sh), then configure again")
endif()
set(generator_args -G "${GENERATOR}")
if(MAKE_PROGRAM)
  list(APPEND generator_args "-DCMAKE_MAKE_PROGRAM=${MAKE_PROGRAM}")
endif()
execute_process(
  COMMAND "${CMAKE_COMMAND}" -S "${SOURCE}" -B "${BINARY}" ${generator_args}
          "-DCMAKE_CXX_COMPILER=${CXX}" -DDRIVENSHAPE_FUZZ_INSTRUMENT=sanitize
          -DCMAKE_UNITY_BUILD=ON
  RESULT_VARIABLE status)
if(NOT status EQUAL 0)
  message(FATAL_ERROR "configuring the fuzz targets in ${BINARY} failed (${status})")
endif()
execute_process(COMMAND "${CMAKE_COMMAND}" --build "${BINARY}" --target fuzz_targets
                        --parallel "${JOBS}"
                RESULT_VARIABLE status)
if(NOT status EQUAL 0)
  message(FATAL_ERROR "building the fuzz targets in ${BINARY} failed (${status})")
endif()
