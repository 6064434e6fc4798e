#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Runs pytest with the arguments given (CTest calls it through tests/support/run_python.cmake)."""

import sys

import pytest

if __name__ == "__main__":
    sys.exit(pytest.main(sys.argv[1:]))
