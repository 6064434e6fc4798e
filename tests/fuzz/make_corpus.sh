#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Regenerates the binary seeds (PC2, EXR, .dsdb) and the computed regression files with the
# project's own writers (make_corpus.cpp); the text seeds and regressions are kept by hand.
# Builds the fuzz project first (clang, as for CTest) in BUILD (default: build-fuzz).
#   usage: tests/fuzz/make_corpus.sh [BUILD]
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
build=${1:-$root/build-fuzz}
cxx=$(command -v clang++-14 || command -v clang++ || true)
if [[ -z $cxx ]]; then
  echo "make_corpus: no clang++; install clang-14 and libclang-rt-14-dev" >&2
  exit 1
fi
cmake -S "$here/project" -B "$build" -DCMAKE_CXX_COMPILER="$cxx" >/dev/null
cmake --build "$build" --target fuzz_make_corpus --parallel "$(nproc 2>/dev/null || echo 2)"
"$build/fuzz_make_corpus" "$here"
