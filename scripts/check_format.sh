#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Fails when a C++ or OpenCL source differs from the checked-in .clang-format (clang-format 14).
set -euo pipefail
cd "$(dirname "$0")/.."
mapfile -t files < <(git ls-files '*.cpp' '*.h' '*.cl' 2>/dev/null || find src apps bench tests kernels -name '*.cpp' -o -name '*.h' -o -name '*.cl')
clang-format --dry-run -Werror "${files[@]}"
echo "format: ${#files[@]} files match .clang-format"
