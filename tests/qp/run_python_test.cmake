# Runs a Python test script with the project's interpreter; used by add_test as
#   cmake -DPYTHON=interpreter -DSCRIPT=script.py [-DARGS=arg;arg] -P run_python_test.cmake
# A missing interpreter FAILS the test (CI must run it), with what to do about it.
if(NOT EXISTS "${PYTHON}")
  message(FATAL_ERROR
    "Python interpreter '${PYTHON}' not found: run scripts/setup.sh to create the project's "
    ".venv with numpy and quadprog, or configure with -DDRIVENSHAPE_PYTHON=/path/to/python.")
endif()
execute_process(COMMAND "${PYTHON}" "${SCRIPT}" ${ARGS} RESULT_VARIABLE result)
if(NOT result EQUAL 0)
  message(FATAL_ERROR "${SCRIPT} failed (${result})")
endif()
