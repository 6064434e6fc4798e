# SPDX-License-Identifier: Apache-2.0
"""Options of the QC report test (CTest passes them, tests/qc/CMakeLists.txt)."""


def pytest_addoption(parser):
    parser.addoption("--cli", required=True, help="the built `drivenshape` command line")
    parser.addoption("--data", required=True, help="tests/data/sleeve")
    parser.addoption("--script", required=True, help="scripts/qc_report.py")
