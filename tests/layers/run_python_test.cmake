# Runs test_export_usd.py with the project's interpreter. A missing interpreter fails the test
# with what to do; it never skips.
#   cmake -DPYTHON=... -DSCRIPT=... -DCLI=... -DWRITER=... -DEXPORTER=... -DDATA=... -DWORK=...
#         -P run_python_test.cmake
if(NOT EXISTS "${PYTHON}")
  message(FATAL_ERROR "Python interpreter '${PYTHON}' not found: run scripts/setup.sh (it "
                      "creates .venv from scripts/requirements.txt) or configure with "
                      "-DDRIVENSHAPE_PYTHON=/path/to/python")
endif()
file(REMOVE_RECURSE "${WORK}")
file(MAKE_DIRECTORY "${WORK}")
execute_process(COMMAND "${PYTHON}" "${SCRIPT}" --cli "${CLI}" --writer "${WRITER}"
                        --script "${EXPORTER}" --data "${DATA}" --work "${WORK}"
                RESULT_VARIABLE status)
if(NOT status EQUAL 0)
  message(FATAL_ERROR "test_export_usd.py failed (${status})")
endif()
