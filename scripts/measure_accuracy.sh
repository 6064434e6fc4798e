#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Measures bake accuracy on the public clips (DRIVENSHAPE_DATA: made by
# scripts/validation/generate_clips.sh --link-data out/data out/clips): builds a
# 30-shape database from each scene's `train` clip, bakes `test_public` in every mode (the
# talk's method, the binding baseline, and the fidelity options of issue 4) and compares each
# with the simulated truth: mean / RMS / max vertex error (mm), cloth vertices inside the
# driver per frame (and the truth's, when `drivenshape eval` measures penetrations), and the
# largest frame-to-frame vertex jump against the truth's. Prints a Markdown table (the
# accuracy table in docs/method.md). Not a test: it reads generated clips.
#
# Usage: scripts/measure_accuracy.sh [SCENE...]   (default: pants sleeve)
# Environment: DRIVENSHAPE_DATA (default out/data), DRIVENSHAPE_BUILD (default build),
#              DRIVENSHAPE_DEVICE (bake --device, default auto), MODES (space-separated keys to
#              run, default all), DB_FLAGS (extra `db build` flags, e.g. "--add-frames 1"
#              to seed the database with the simulation's undraped first frame instead of the
#              settled rest pose `db build` picks), ACCURACY_OUT (default out/accuracy).
#
# Regions: the reference OBJs have no left/right groups (one `o` each), so this script derives
# index lists: pants by the sign of the rest x (the character's left is +x) on both meshes;
# sleeve by the middle of the rest bounding box along its longest axis (upper arm / forearm).
set -euo pipefail
cd "$(dirname "$0")/.."
data=${DRIVENSHAPE_DATA:-out/data}
build=${DRIVENSHAPE_BUILD:-build}
device=${DRIVENSHAPE_DEVICE:-auto}
db_flags=${DB_FLAGS:-}
accuracy_out=${ACCURACY_OUT:-out/accuracy}
ds=$build/apps/drivenshape
export POCL_CACHE_DIR="$PWD/$build/pocl-cache"
scenes=("$@")
((${#scenes[@]})) || scenes=(pants sleeve)
python=python3
[[ -x .venv/bin/python ]] && python=.venv/bin/python

# key|label|bake flags (REGIONS is replaced by the scene's region file)
all_modes=(
  "talk|talk: --align none --blend world --no-resolve|--align none --blend world --no-resolve --strain-limit 0"
  "bind|binding baseline: --weights bind --no-resolve|--weights bind --no-resolve --strain-limit 0"
  "talk_resolve|--align none --blend world (resolve)|--align none --blend world"
  "rigid_all_world|--align rigid-all --blend world (resolve)|--align rigid-all --blend world"
  "rigid_all_local|--align rigid-all (local, resolve)|--align rigid-all"
  "rigid_world|--blend world (rigid, resolve)|--blend world"
  "default|defaults (--align rigid --blend local, resolve)|"
  "rigid_noresolve|--no-resolve (rigid, local)|--no-resolve"
  "none_local|--align none (local, resolve)|--align none"
  "regions|--regions (rigid, local, resolve)|--regions REGIONS"
  "regions_world|--regions --blend world (rigid, resolve)|--blend world --regions REGIONS"
  "temporal|defaults + --max-weight-change 0.05|--max-weight-change 0.05"
)
wanted=${MODES:-}

eval_has_driver=0
if "$ds" eval --help 2>/dev/null | grep -q -- "--driver-mesh"; then
  eval_has_driver=1
fi

for scene in "${scenes[@]}"; do
  src=$data/$scene
  out=$accuracy_out/$scene
  mkdir -p "$out"
  frames=$($python -c "import json;d=json.load(open('$src/test_public.json'));print(f\"{d['frame_start']}-{d['frame_end']}\")")
  # shellcheck disable=SC2086
  "$ds" db build --driver-mesh "$src/driver_rest.obj" --driven-mesh "$src/driven_rest.obj" \
    --driver "$src/train.driver.pc2" --driven "$src/train.driven.pc2" --count 30 --quiet \
    $db_flags -o "$out/db.dsdb" >/dev/null
  # Region file from the rest meshes (see the header).
  $python - "$src" "$scene" "$out/regions.json" <<'PY'
import json, sys
src, scene, path = sys.argv[1:]
def verts(obj):
    return [tuple(map(float, l.split()[1:4])) for l in open(obj) if l.startswith("v ")]
drv, dvn = verts(f"{src}/driver_rest.obj"), verts(f"{src}/driven_rest.obj")
if scene == "pants":
    axis, middle, names = 0, 0.0, ("left", "right")
else:
    lo = [min(p[a] for p in drv) for a in range(3)]
    hi = [max(p[a] for p in drv) for a in range(3)]
    axis = max(range(3), key=lambda a: hi[a] - lo[a])
    middle, names = 0.5 * (lo[axis] + hi[axis]), ("upper", "lower")
def split(points, high):
    return [i for i, p in enumerate(points) if (p[axis] > middle) == high]
regions = [{"name": names[0], "driver": {"vertices": split(drv, True)},
            "driven": {"vertices": split(dvn, True)}},
           {"name": names[1], "driver": {"vertices": split(drv, False)},
            "driven": {"vertices": split(dvn, False)}}]
json.dump({"comment": f"derived by measure_accuracy.sh: axis {axis} at {middle:.4f}",
           "falloff": 3, "regions": regions}, open(path, "w"))
PY
  for entry in "${all_modes[@]}"; do
    IFS='|' read -r key _ flags <<<"$entry"
    if [[ -n "$wanted" && " $wanted " != *" $key "* ]]; then
      continue
    fi
    flags=${flags//REGIONS/$out/regions.json}
    rm -rf "${out:?}/$key"
    mkdir -p "$out/$key"
    # shellcheck disable=SC2086
    "$ds" bake --db "$out/db.dsdb" --driver "$src/test_public.driver.pc2" --frames "$frames" \
      --device "$device" $flags --quiet -o "$out/$key/$scene.####.exr" \
      --report "$out/$key.report.json" >/dev/null
    eval_args=(--truth "$src/test_public.driven.pc2" --bake "$out/$key/$scene.####.exr"
      --frames "$frames" --json "$out/$key.eval.json")
    if ((eval_has_driver)); then
      eval_args+=(--driver "$src/test_public.driver.pc2" --driver-mesh "$src/driver_rest.obj")
    fi
    "$ds" eval "${eval_args[@]}" >/dev/null
    echo "measured $scene $key" >&2
  done
done

$python - "$data" "$accuracy_out" "${scenes[@]}" <<'PY'
import json, os, struct, sys
import numpy as np
data, out, scenes = sys.argv[1], sys.argv[2], sys.argv[3:]
keys = ["talk", "bind", "talk_resolve", "rigid_all_world", "rigid_all_local", "rigid_world",
        "default", "rigid_noresolve", "none_local", "regions", "regions_world", "temporal"]
labels = {
    "talk": "talk (`--align none --blend world --no-resolve`)",
    "bind": "binding baseline (`--weights bind --no-resolve`)",
    "talk_resolve": "`--align none --blend world` (resolve)",
    "rigid_all_world": "`--align rigid-all --blend world` (resolve)",
    "rigid_all_local": "`--align rigid-all` (local, resolve)",
    "rigid_world": "`--blend world` (rigid, resolve)",
    "default": "**defaults** (`--align rigid --blend local`, resolve 2 mm)",
    "rigid_noresolve": "`--no-resolve` (rigid, local)",
    "none_local": "`--align none` (local, resolve)",
    "regions": "`--regions` (rigid, local, resolve)",
    "regions_world": "`--regions --blend world` (rigid, resolve)",
    "temporal": "defaults + `--max-weight-change 0.05`",
}

def pc2(path):
    with open(path, "rb") as f:
        head = f.read(32)
        _, _, points, start, rate, samples = struct.unpack("<12siiffi", head)
        return np.frombuffer(f.read(), dtype="<f4").reshape(samples, points, 3)

print("| scene | mode | mean (mm) | RMS (mm) | max (mm) | inside the driver / frame (truth) "
      "| largest jump mm (truth) |")
print("|---|---|---|---|---|---|---|")
for scene in scenes:
    truth = pc2(f"{data}/{scene}/test_public.driven.pc2").astype(np.float64)
    truth_jump = np.linalg.norm(np.diff(truth, axis=0), axis=2).max()
    for key in keys:
        base = f"{out}/{scene}/{key}"
        if not os.path.exists(base + ".eval.json"):
            continue
        e = json.load(open(base + ".eval.json"))
        r = json.load(open(base + ".report.json"))
        frames = [f for f in r["frames"] if not f.get("skipped")]
        summary = e.get("summary", {})
        if "mean_inside" in summary.get("bake", {}):
            # `drivenshape eval --driver`: the same measurement on the bake and on the truth.
            inside = summary["bake"]["mean_inside"]
            truth_inside = f"{summary['truth']['mean_inside']:.1f}"
        else:
            inside = sum(f.get("inside_after", 0) for f in frames) / len(frames)
            truth_inside = "-"
        jump = max(f.get("max_jump", 0) for f in frames)
        print(f"| {scene} | {labels[key]} | {e['mean']*1000:.2f} | {e['rms']*1000:.2f} "
              f"| {e['max']*1000:.1f} | {inside:.1f} ({truth_inside}) "
              f"| {jump*1000:.1f} ({truth_jump*1000:.1f}) |")
PY
