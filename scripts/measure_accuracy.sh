#!/usr/bin/env bash
# Measures bake accuracy on the reference data beside the checkout (../shared/data): builds a
# 30-shape database from each scene's `train` clip, bakes `test_public` with the QP weights and
# with the nearest-shape baseline, and compares both with the simulated truth.
# Usage: scripts/measure_accuracy.sh [SCENE...]   (default: pants sleeve). Needs a build.
set -euo pipefail
cd "$(dirname "$0")/.."
data=${DRIVENSHAPE_DATA:-../shared/data}
ds=build/apps/drivenshape
export POCL_CACHE_DIR="$PWD/build/pocl-cache"
scenes=("$@")
((${#scenes[@]})) || scenes=(pants sleeve)
for scene in "${scenes[@]}"; do
  src=$data/$scene
  out=out/accuracy/$scene
  mkdir -p "$out/qp" "$out/nearest"
  frames=$(python3 -c "import json;d=json.load(open('$src/test_public.json'));print(f\"{d['frame_start']}-{d['frame_end']}\")")
  "$ds" db build --driver-mesh "$src/driver_rest.obj" --driven-mesh "$src/driven_rest.obj" \
    --driver "$src/train.driver.pc2" --driven "$src/train.driven.pc2" --count 30 --quiet \
    -o "$out/db.dsdb"
  for mode in qp nearest; do
    "$ds" bake --db "$out/db.dsdb" --driver "$src/test_public.driver.pc2" --frames "$frames" \
      --weights $mode --quiet -o "$out/$mode/$scene.####.exr"
    echo "== $scene, weights $mode"
    "$ds" eval --truth "$src/test_public.driven.pc2" --bake "$out/$mode/$scene.####.exr" \
      --frames "$frames" --json "$out/$mode.eval.json"
  done
done
