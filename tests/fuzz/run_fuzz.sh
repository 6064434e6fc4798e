#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Runs one fuzz target as its CTest does (tests/fuzz/CMakeLists.txt):
#   1. every file of regressions/NAME/ once, each in its own process (so every one that still
#      crashes is listed),
#   2. every seed of corpus/NAME/ once,
#   3. SECONDS of fresh mutations, starting from a copy of the seeds in WORK/corpus (the
#      repository is never written).
# Any crash, sanitizer report, exception other than drivenshape::Error, timeout (10 s per input)
# or allocation over 1 GiB fails it; crashing inputs are kept in WORK/artifacts/.
#
#   usage: run_fuzz.sh FUZZER NAME WORK SECONDS [libFuzzer flags...]
#   e.g.   tests/fuzz/run_fuzz.sh build/tests/fuzz/tree/fuzz_obj obj /tmp/fuzz-obj 60
set -uo pipefail
if (($# < 4)); then
  sed -n '2,13p' "$0" >&2
  exit 2
fi
fuzzer=$1
name=$2
work=$3
seconds=$4
shift 4
here=$(cd "$(dirname "$0")" && pwd)
seeds=$here/corpus/$name
regressions=$here/regressions/$name

if [[ ! -x $fuzzer ]]; then
  echo "run_fuzz: $fuzzer is missing; the fuzz_build test builds it" >&2
  exit 1
fi
rm -rf "$work"
mkdir -p "$work/corpus" "$work/artifacts"
cp "$seeds"/* "$work/corpus/"
# Readers take paths: each execution writes its input into this folder (memory when possible).
scratch=$(mktemp -d /dev/shm/drivenshape-fuzz.XXXXXX 2>/dev/null || mktemp -d)
trap 'rm -rf "$scratch"' EXIT
export DRIVENSHAPE_FUZZ_TMPDIR=$scratch
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:strict_string_checks=1:check_initialization_order=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}

flags=(-timeout=10 -rss_limit_mb=2048 -malloc_limit_mb=1024 "-artifact_prefix=$work/artifacts/"
  "$@")

# The report of a failed run: from the first line that says what happened, 45 lines.
excerpt() {
  awk '/ERROR: |FINDING|runtime error|deadly signal|==ERROR|Test unit written/ { on = 1 }
       on && shown < 45 { print "    " $0; shown++ }' "$1"
}

failed=0
crashing=()
regression_count=0
for file in "$regressions"/*; do
  [[ -f $file ]] || continue
  regression_count=$((regression_count + 1))
  log=$work/regression.$(basename "$file").log
  if ! "$fuzzer" "${flags[@]}" "$file" >"$log" 2>&1; then
    crashing+=("$(basename "$file")")
    echo "FAIL regression $name/$(basename "$file") still crashes:"
    excerpt "$log"
    failed=1
  fi
done
echo "fuzz_$name: $regression_count regression files, ${#crashing[@]} crash${crashing:+: ${crashing[*]}}"

seed_count=$(find "$seeds" -maxdepth 1 -type f | wc -l)
if ! "$fuzzer" "${flags[@]}" "$seeds"/* >"$work/seeds.log" 2>&1; then
  echo "FAIL a seed of corpus/$name crashes:"
  excerpt "$work/seeds.log"
  failed=1
fi
echo "fuzz_$name: $seed_count seeds run"

start=$(date +%s.%N)
if ! "$fuzzer" "${flags[@]}" -max_total_time="$seconds" -print_final_stats=1 \
  "$work/corpus" >"$work/fuzz.log" 2>&1; then
  echo "FAIL fuzzing $name found a crash (full log: $work/fuzz.log):"
  excerpt "$work/fuzz.log"
  failed=1
fi
elapsed=$(awk -v start="$start" -v end="$(date +%s.%N)" 'BEGIN { print end - start }')
runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$work/fuzz.log")
rate=$(awk -v runs="${runs:-0}" -v time="$elapsed" 'BEGIN { printf "%.0f", (time > 0 ? runs / time : 0) }')
added=$(sed -n 's/^stat::new_units_added: *//p' "$work/fuzz.log")
rss=$(sed -n 's/^stat::peak_rss_mb: *//p' "$work/fuzz.log")
coverage=$(grep -o 'cov: [0-9]* ft: [0-9]*' "$work/fuzz.log" | tail -1)
echo "fuzz_$name: ${runs:-?} executions in $(printf '%.1f' "$elapsed") s (${rate}/s), ${added:-?} new inputs," \
  "${coverage:-no coverage line}, peak RSS ${rss:-?} MB"

artifacts=("$work"/artifacts/*)
if [[ -e ${artifacts[0]} ]]; then
  echo "crashing inputs (reproduce: $fuzzer FILE; pin one: copy it to" \
    "tests/fuzz/regressions/$name/ under the bug's name):"
  printf '    %s\n' "${artifacts[@]}"
fi
exit $failed
