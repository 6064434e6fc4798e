#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Installs what is missing, builds (for x86-64, and checks x86-64-v4 compiles), and runs the
# whole test suite (CTest: unit, command-line, farm, Python and fuzz tests). CI runs this.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
# The tree must also compile warning-free for AVX-512 CPUs (x86-64-v4), whatever CPU runs this.
bash scripts/check_targets.sh x86-64-v4
mkdir -p build/pocl-cache
jobs=$(nproc 2>/dev/null || echo 2)
cd build
# wheel_full_build (label full_build) compiles everything again under pip: run it by hand
# (`ctest -L full_build`); python_wheel checks the same wheel with this build's extension.
ctest --output-on-failure -j"$jobs" --timeout 600 -LE full_build
