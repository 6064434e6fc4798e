# Runs check_posmap_exr.py with the project's interpreter. A missing interpreter fails the test
# with what to do; it never skips.
#   cmake -DPYTHON=... -DSCRIPT=... -DWRITER=... -DDATA=... -DWORK=... -P run_python_check.cmake
if(NOT EXISTS "${PYTHON}")
  message(FATAL_ERROR "Python interpreter '${PYTHON}' not found: run scripts/setup.sh (it "
                      "creates .venv from scripts/requirements.txt) or configure with "
                      "-DDRIVENSHAPE_PYTHON=/path/to/python")
endif()
file(REMOVE_RECURSE "${WORK}")
file(MAKE_DIRECTORY "${WORK}")
execute_process(COMMAND "${PYTHON}" "${SCRIPT}" --writer "${WRITER}" --data "${DATA}"
                        --work "${WORK}"
                RESULT_VARIABLE status)
if(NOT status EQUAL 0)
  message(FATAL_ERROR "check_posmap_exr.py failed (${status})")
endif()
