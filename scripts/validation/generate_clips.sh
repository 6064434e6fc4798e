#!/bin/bash
# SPDX-License-Identifier: Apache-2.0
# Generate the clips listed in clips.txt with the project's own generator, scripts/clipgen
# (Blender 3.4 headless, its cloth solver; numpy in Blender's Python: Debian's blender uses the
# system python3, so apt-get install blender python3-numpy).
#
#   scripts/validation/generate_clips.sh [--list FILE] OUT_DIR [NAME...]
#   scripts/validation/generate_clips.sh --link-data DATA_DIR OUT_DIR
#
# Each line of the list is `name scene family seed [make_clip.py options...]` (e.g. --frames 60,
# --set cloth.bending_stiffness=0.5); the clip lands in OUT_DIR/NAME/<scene>/: driver_rest.obj,
# driven_rest.obj, rig.json, <family>.{driver,driven}.pc2, <family>.json. With NAMEs only those
# clips are made. A clip whose json exists (written last) is kept; a clip that fails, or that
# scripts/clipgen/check_clip.py refuses (its cloth inside the body, drifting off it or stretching
# like rubber: a simulation that ran away), is reported and the exit status is 1 once the others
# have run. Logs: OUT_DIR/logs/NAME.log and NAME.check.log.
# --list takes another list of the same form: references.txt (the TD's extra reference clips,
# kept apart from the validation clips) or spread.txt (every validation clip simulated again
# with a small change, the sim-to-sim spread).
# --link-data makes (when missing) the four public clips of clips.txt (pants_train1,
# sleeve_train1, pants_test_public2, sleeve_test_public2) and links them as DATA_DIR/<scene>/
# {driver_rest.obj, driven_rest.obj, rig.json, train.*, test_public.*}: the folder that
# DRIVENSHAPE_DATA names for scripts/measure_accuracy.sh, golden_clips.sh, check_exactness.sh,
# make_layering_preview.sh and the other scripts that read one `train` and one `test_public`
# clip per character.
# Environment: BLENDER (default blender).
# Cost: on the project's 2-core VM, shared with compilers, 1.4-4.4 s per frame (each clip adds 20
# preroll frames); all of clips.txt 1 to 3 hours.
# scripts/clipgen/README.md and docs/validation.md have the measured figures.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
maker="$(cd "$here/../clipgen" && pwd)/make_clip.py"
checker="$(cd "$here/../clipgen" && pwd)/check_clip.py"
blender=${BLENDER:-blender}
list="$here/clips.txt"
link_data=""
usage="usage: generate_clips.sh [--list FILE] OUT_DIR [NAME...] | --link-data DATA_DIR OUT_DIR"
case "${1:-}" in
  --list) list="${2:?--list needs a file}"; shift 2 ;;
  --link-data) link_data="${2:?--link-data needs a folder}"; shift 2 ;;
  -h | --help) awk 'NR > 2 && /^#/ { sub(/^# ?/, ""); print; next } NR > 2 { exit }' "$0"; exit 0 ;;
esac
out="${1:?$usage}"
shift
if [ -n "$link_data" ]; then
  [ $# -eq 0 ] || { echo "$usage" >&2; exit 2; }
  set -- pants_train1 sleeve_train1 pants_test_public2 sleeve_test_public2
fi
command -v "$blender" >/dev/null || { echo "generate_clips: '$blender' not found (set BLENDER)" >&2; exit 2; }
mkdir -p "$out/logs"
failed=0
while read -r name scene family seed rest; do
  [ -n "$name" ] || continue
  if [ $# -gt 0 ] && ! printf '%s\n' "$@" | grep -qx "$name"; then continue; fi
  if [ -f "$out/$name/$scene/$family.json" ]; then
    echo "have $name"
    continue
  fi
  echo "=== $name ($scene $family seed $seed $rest) $(date +%T)"
  # shellcheck disable=SC2086
  if "$blender" -b --factory-startup --python-exit-code 1 --python "$maker" -- \
      --scene "$scene" --family "$family" --seed "$seed" --out "$out/$name" $rest \
      >"$out/logs/$name.log" 2>&1 </dev/null; then
    grep -E "done:" "$out/logs/$name.log" || true
    # The clip judged from its files (scripts/clipgen/check_clip.py): a take whose cloth ran
    # away (inside the body, drifting off it, stretching like rubber) is reported, not used.
    if ! python3 "$checker" "$out/$name/$scene" "$family" >"$out/logs/$name.check.log" 2>&1; then
      echo "failed check: $name ($(tail -n 1 "$out/logs/$name.check.log"); see" \
        "$out/logs/$name.check.log): make it with another seed"
      failed=1
    fi
  else
    echo "failed: $name (see $out/logs/$name.log)"
    failed=1
  fi
done < <(grep -v '^#' "$list")

if [ -n "$link_data" ] && [ $failed -eq 0 ]; then
  for scene in pants sleeve; do
    mkdir -p "$link_data/$scene"
    train=$(cd "$out/${scene}_train1/$scene" && pwd)
    test=$(cd "$out/${scene}_test_public2/$scene" && pwd)
    for f in driver_rest.obj driven_rest.obj rig.json train.driver.pc2 train.driven.pc2 train.json; do
      ln -sfn "$train/$f" "$link_data/$scene/$f"
    done
    for f in test_public.driver.pc2 test_public.driven.pc2 test_public.json; do
      ln -sfn "$test/$f" "$link_data/$scene/$f"
    done
  done
  echo "linked the public clips under $link_data/{pants,sleeve}"
fi
exit $failed
