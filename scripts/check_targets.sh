#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Compiles the library, the command line and every benchmark for other x86-64 instruction-set
# levels, with warnings as errors, so that a warning that only shows when the compiler targets
# a newer CPU (e.g. GCC's AVX-512 code paths in Eigen) fails CI on whatever machine CI runs on.
# The main build (scripts/setup.sh) covers the baseline, -march=x86-64, for the whole tree.
#
#   bash scripts/check_targets.sh [LEVEL ...]     default: x86-64-v4 (AVX-512)
#
# Each level builds in build-arch-LEVEL file by file, NOT as a unity build: the main build
# (scripts/setup.sh) is a unity build, so this check is also the proof that every source file
# includes what it uses, as a plain `cmake --build` (a packager's, an add_subdirectory
# embedder's) compiles it. Binaries built here may not run on this machine.
set -euo pipefail
cd "$(dirname "$0")/.."
levels=("$@")
((${#levels[@]})) || levels=(x86-64-v4)
jobs=$(nproc 2>/dev/null || echo 2)
# The library and the command line, and the two benchmarks that inline the most Eigen code (the
# others only call the library; the main build compiles them warning-free for x86-64).
targets=(drivenshape_cli drivenshape_bench bench_roofline)
for level in "${levels[@]}"; do
  build="build-arch-$level"
  echo "check_targets: compiling the library, CLI and benchmarks with -march=$level -Werror" >&2
  generator=()
  [[ -f $build/CMakeCache.txt ]] || ! command -v ninja >/dev/null || generator=(-G Ninja)
  cmake -S . -B "$build" "${generator[@]}" -DCMAKE_BUILD_TYPE=Release -DDRIVENSHAPE_WERROR=ON \
    -DDRIVENSHAPE_ARCH="$level" -DCMAKE_UNITY_BUILD=OFF >/dev/null
  cmake --build "$build" -j"$jobs" --target "${targets[@]}" >"$build/check.log" 2>&1 || {
    grep -E "error|warning" -A4 "$build/check.log" | head -60 >&2
    echo "check_targets: -march=$level does not compile warning-free (full log: $build/check.log)" >&2
    exit 1
  }
  echo "check_targets: -march=$level compiles warning-free, file by file" >&2
done
