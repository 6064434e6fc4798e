# SPDX-License-Identifier: Apache-2.0
# Runs one add-on test script in a background Blender; used by add_test as
#   cmake -DBLENDER=blender -DSCRIPT=test.py [-DARGS=arg|arg|...] -P run_blender.cmake
# ARGS are separated by '|' (a ';' would split the -D argument). A missing Blender FAILS the
# test (CI must run it), with what to install. --python-exit-code 1 turns an exception in the
# script into exit code 1; the scripts call sys.exit(1) on a failed check.
if(NOT BLENDER OR NOT EXISTS "${BLENDER}")
  message(FATAL_ERROR "Blender not found ('${BLENDER}'): install it (apt-get install blender, "
                      "Blender 3.4 on Debian 12; scripts/setup.sh does) or configure with "
                      "-DDRIVENSHAPE_BLENDER=/path/to/blender")
endif()
string(REPLACE "|" ";" args "${ARGS}")
execute_process(COMMAND "${BLENDER}" -b --factory-startup --python-exit-code 1
                        --python "${SCRIPT}" -- ${args}
                RESULT_VARIABLE status)
if(NOT status EQUAL 0)
  message(FATAL_ERROR "${SCRIPT} failed in Blender (exit ${status})")
endif()
