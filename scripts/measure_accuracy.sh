#!/usr/bin/env bash
# Measures bake accuracy on the reference data beside the checkout (../shared/data): builds a
# 30-shape database from each scene's `train` clip, bakes `test_public` in several modes and
# compares each with the simulated truth. Prints a Markdown table (the README's accuracy table).
# Usage: scripts/measure_accuracy.sh [SCENE...]   (default: pants sleeve). Needs a build.
set -euo pipefail
cd "$(dirname "$0")/.."
data=${DRIVENSHAPE_DATA:-../shared/data}
ds=build/apps/drivenshape
export POCL_CACHE_DIR="$PWD/build/pocl-cache"
scenes=("$@")
((${#scenes[@]})) || scenes=(pants sleeve)
modes=("qp" "qp --no-correct" "nearest --no-correct" "bind")
for scene in "${scenes[@]}"; do
  src=$data/$scene
  out=out/accuracy/$scene
  mkdir -p "$out"
  frames=$(python3 -c "import json;d=json.load(open('$src/test_public.json'));print(f\"{d['frame_start']}-{d['frame_end']}\")")
  "$ds" db build --driver-mesh "$src/driver_rest.obj" --driven-mesh "$src/driven_rest.obj" \
    --driver "$src/train.driver.pc2" --driven "$src/train.driven.pc2" --count 30 --quiet \
    -o "$out/db.dsdb" >/dev/null
  for mode in "${modes[@]}"; do
    name=${mode// /}
    name=${name//--/_}
    mkdir -p "$out/$name"
    # shellcheck disable=SC2086
    "$ds" bake --db "$out/db.dsdb" --driver "$src/test_public.driver.pc2" --frames "$frames" \
      --weights $mode --quiet -o "$out/$name/$scene.####.exr" --report "$out/$name.report.json" >/dev/null
    "$ds" eval --truth "$src/test_public.driven.pc2" --bake "$out/$name/$scene.####.exr" \
      --frames "$frames" --json "$out/$name.eval.json" >/dev/null
  done
done
python3 - "${scenes[@]}" <<'PY'
import json, sys
modes = [("qp", "DrivenShape (QP) + correction"), ("qp_no-correct", "DrivenShape (QP), blend only"),
         ("nearest_no-correct", "nearest database shape"), ("bind", "binding baseline (Point Deform)")]
print("| scene | mode | mean (mm) | RMS (mm) | max (mm) | inside the driver / frame | binding switches / frame | largest jump (mm) |")
print("|---|---|---|---|---|---|---|---|")
for scene in sys.argv[1:]:
    for key, label in modes:
        e = json.load(open(f"out/accuracy/{scene}/{key}.eval.json"))
        r = json.load(open(f"out/accuracy/{scene}/{key}.report.json"))
        frames = [f for f in r["frames"] if not f["skipped"]]
        inside = sum(f.get("inside_after", 0) for f in frames) / len(frames)
        sw = [f["binding_switches"] for f in frames if "binding_switches" in f]
        switches = f"{sum(sw) / len(sw):.1f}" if sw else "-"
        jump = max(f.get("max_jump", 0) for f in frames)
        print(f"| {scene} | {label} | {e['mean']*1000:.1f} | {e['rms']*1000:.1f} | {e['max']*1000:.1f} "
              f"| {inside:.1f} | {switches} | {jump*1000:.1f} |")
PY
