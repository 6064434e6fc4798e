#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Line coverage of the reader sources reached by the fuzz targets (not a test: a measurement).
# Builds the fuzz project with clang's source-based coverage in BUILD (default build-fuzz-
# coverage), fuzzes each target for SECONDS from a copy of its seeds, replays the corpus it grew
# with profiling on, and prints `llvm-cov report` for the reader files only.
#   usage: tests/fuzz/coverage.sh [BUILD] [SECONDS]
# Needs clang-14, libclang-rt-14-dev and llvm-14 (llvm-profdata-14, llvm-cov-14).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
build=${1:-$root/build-fuzz-coverage}
seconds=${2:-20}
cxx=$(command -v clang++-14 || command -v clang++)
profdata=$(command -v llvm-profdata-14 || command -v llvm-profdata)
cov=$(command -v llvm-cov-14 || command -v llvm-cov)
targets=(obj mesh_check pc2 point_cache_exr position_map_exr database binding_mask regions weight_map
  bake_report frames rig)
readers=(src/io/obj.cpp src/io/mesh.cpp src/io/mesh_check.cpp src/io/pc2.cpp src/io/point_cache.cpp
  src/io/exr_point_cache.cpp src/io/exr_common.cpp src/io/frames.cpp src/io/posmap_exr.cpp
  src/database/database.cpp src/database/regions.cpp src/database/binding_mask.cpp
  src/io/weight_map.cpp src/shot/coverage_check.cpp src/database/rig.cpp)

cmake -S "$here/project" -B "$build" -DCMAKE_CXX_COMPILER="$cxx" \
  -DDRIVENSHAPE_FUZZ_INSTRUMENT=coverage >/dev/null
cmake --build "$build" --target fuzz_targets --parallel "$(nproc 2>/dev/null || echo 2)"

scratch=$(mktemp -d /dev/shm/drivenshape-fuzz.XXXXXX 2>/dev/null || mktemp -d)
trap 'rm -rf "$scratch"' EXIT
export DRIVENSHAPE_FUZZ_TMPDIR=$scratch
rm -rf "$build/coverage"
objects=()
for name in "${targets[@]}"; do
  work=$build/coverage/$name
  mkdir -p "$work/corpus" "$work/artifacts"
  cp "$here/corpus/$name"/* "$work/corpus/"
  flags=(-timeout=10 -rss_limit_mb=2048 -malloc_limit_mb=1024 "-artifact_prefix=$work/artifacts/")
  [[ $name == frames ]] && flags+=(-max_len=256)
  # Fork mode goes on past crashes (the CTests report those), so a known crash does not end
  # the measurement early.
  LLVM_PROFILE_FILE=$work/fuzz-%p.profraw "$build/fuzz_$name" "${flags[@]}" -fork=1 \
    -ignore_crashes=1 -ignore_ooms=1 -ignore_timeouts=1 -max_total_time="$seconds" \
    "$work/corpus" >"$work/fuzz.log" 2>&1 || true
  # Replayed in a process that exits normally, so its profile is written.
  LLVM_PROFILE_FILE=$work/replay.profraw "$build/fuzz_$name" "${flags[@]}" -runs=0 \
    "$work/corpus" >"$work/replay.log" 2>&1 || true
  echo "fuzz_$name: $(find "$work/corpus" -type f | wc -l) corpus inputs," \
    "$(grep -o 'cov: [0-9]*' "$work/fuzz.log" | tail -1 || echo 'cov: ?') edges"
  objects+=("$build/fuzz_$name")
done
"$profdata" merge -sparse "$build"/coverage/*/replay.profraw -o "$build/coverage/merged.profdata"
source_dir=$(sed -n 's/^DRIVENSHAPE_SOURCE_DIR:PATH=//p' "$build/CMakeCache.txt")
# llvm-cov takes the first binary as is and every further one after -object.
others=()
for binary in "${objects[@]:1}"; do
  others+=(-object "$binary")
done
"$cov" report "${objects[0]}" "${others[@]}" -instr-profile="$build/coverage/merged.profdata" \
  "${readers[@]/#/$source_dir/}"
