#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Runs the OpenCL tests, a bake of the bundled sample and the W1/W2 benchmarks on one OpenCL
# device, e.g. a GPU farm node's driver, from an existing build (scripts/setup.sh). Use it to
# check a new node or driver before it takes shots.
#
#   bash scripts/device_check.sh DEVICE_NAME [OUT_DIR]
#
# DEVICE_NAME is a part of the device's name as `drivenshape devices` lists it (e.g. NVIDIA).
# OUT_DIR (default out/device_check) receives one log per test binary, the sample bake, its
# evaluation against the simulation and the benchmarks' JSON. DRIVENSHAPE_BUILD names another
# build folder. Exit status: the number of failed steps (0 when everything passed).
set -uo pipefail
cd "$(dirname "$0")/.."
device=${1:?usage: device_check.sh DEVICE_NAME [OUT_DIR]}
out=${2:-out/device_check}
build=${DRIVENSHAPE_BUILD:-build}
ds=$build/apps/drivenshape
bench=$build/bench/drivenshape_bench
data=tests/data/sleeve
mkdir -p "$out/bake"
export DS_TEST_DEVICE=$device # the OpenCL tests take the first device whose name contains it
failed=0
step() { # step NAME COMMAND...: runs one step, logs it to $out/NAME.log, counts a failure
  local name=$1 start end rc
  shift
  start=$(date +%s.%N)
  "$@" >"$out/$name.log" 2>&1
  rc=$?
  end=$(date +%s.%N)
  printf '%-24s %s %6.1f s\n' "$name" "$([ $rc -eq 0 ] && echo passed || echo "FAILED ($rc)")" \
    "$(echo "$end $start" | awk '{print $1 - $2}')"
  [ $rc -eq 0 ] || failed=$((failed + 1))
}
"$ds" devices
for test in devices/test_stages core/test_device_array pipeline/test_evaluator \
  pipeline/test_layers cli/test_export_command io/test_posmap cli/test_posmap_command \
  cli/test_eval cli/test_cli devices/correction_test shot/test_bake database/test_pose_model \
  database_build/test_bake_sides shot/test_bake_layers database_build/test_reference_clips \
  shot/test_coverage_check shot/test_bake_fidelity; do
  step "$(basename $test)" "$build/tests/$test"
done
step db_build "$ds" db build --driver-mesh $data/driver_rest.obj \
  --driven-mesh $data/driven_rest.obj --driver $data/train.driver.pc2 \
  --driven $data/train.driven.pc2 --count 30 --quiet -o "$out/sleeve.dsdb"
step sample_bake "$ds" bake --db "$out/sleeve.dsdb" --driver $data/test.driver.pc2 \
  --frames 1-48 --device "$device" -o "$out/bake/sleeve.####.exr"
step sample_eval "$ds" eval --truth $data/test.driven.pc2 --bake "$out/bake/sleeve.####.exr" \
  --frames 1-48 --driver $data/test.driver.pc2 --db "$out/sleeve.dsdb" --json "$out/eval.json"
step bench_w1 "$bench" --workload W1 --device "$device" --json "$out/w1.json"
step bench_w1_full_search "$bench" --workload W1 --device "$device" --no-host --full-search
step bench_w2 "$bench" --workload W2 --device "$device" --no-host --json "$out/w2.json"
echo "logs and outputs: $out ($failed failed)"
exit $failed
