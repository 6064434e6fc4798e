# SPDX-License-Identifier: Apache-2.0
# Runs a Python test script with the project's interpreter; used by add_test as
#   cmake -DPYTHON=interpreter -DSCRIPT=script.py [-DARGS=arg|arg|...] [-DWORK=folder]
#         -P run_python.cmake
# ARGS are separated by '|' (a ';' would split the -D argument). WORK, when given, is emptied
# and created first. A missing interpreter FAILS the test (CI must run it), with what to do.
if(NOT EXISTS "${PYTHON}")
  message(FATAL_ERROR "Python interpreter '${PYTHON}' not found: run scripts/setup.sh (it "
                      "creates .venv from scripts/requirements.txt) or configure with "
                      "-DDRIVENSHAPE_PYTHON=/path/to/python")
endif()
if(DEFINED WORK)
  file(REMOVE_RECURSE "${WORK}")
  file(MAKE_DIRECTORY "${WORK}")
endif()
string(REPLACE "|" ";" args "${ARGS}")
execute_process(COMMAND "${PYTHON}" "${SCRIPT}" ${args} RESULT_VARIABLE status)
if(NOT status EQUAL 0)
  message(FATAL_ERROR "${SCRIPT} failed (${status})")
endif()
