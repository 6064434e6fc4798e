#!/bin/bash
# SPDX-License-Identifier: Apache-2.0
# Generate the validation clips listed in clips.txt with the Blender cloth
# generator (tools/blender of the shared data; Blender 3.4 headless).
#   scripts/validation/generate_clips.sh [--list FILE] GENERATOR_DIR OUT_DIR [NAME...]
# --list takes another list of the same form: references.txt (the TD's extra
# reference clips, kept apart from the validation clips) or spread.txt (every
# validation clip simulated again with a small change, the sim-to-sim spread).
# Each clip lands in OUT_DIR/NAME/<scene>/<family>.{driver,driven}.pc2 (+ json,
# rig.json, rest OBJs). Clips already generated are skipped.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
list="$here/clips.txt"
if [ "${1:-}" = "--list" ]; then
  list="${2:?--list needs a file}"
  shift 2
fi
gen="${1:?usage: generate_clips.sh GENERATOR_DIR OUT_DIR [NAME...]}"
out="${2:?usage: generate_clips.sh GENERATOR_DIR OUT_DIR [NAME...]}"
shift 2
# The generator's weight transfer needs scipy in Blender's Python (Debian's blender runs the
# system python3).
if ! /usr/bin/python3 -c "import scipy" 2>/dev/null; then
  echo "generate_clips: the generator needs scipy: apt-get install python3-scipy" >&2
  exit 1
fi
mkdir -p "$out/logs"
grep -v '^#' "$list" | while read -r name scene family seed rest; do
  [ -n "$name" ] || continue
  if [ $# -gt 0 ] && ! printf '%s\n' "$@" | grep -qx "$name"; then continue; fi
  if [ -f "$out/$name/$scene/$family.driven.pc2" ]; then
    echo "have $name"
    continue
  fi
  echo "=== $name ($scene $family seed $seed $rest) $(date +%T)"
  # shellcheck disable=SC2086
  blender -b --factory-startup --python-exit-code 1 --python "$gen/generate.py" -- \
    --scene "$scene" --seq "$family" --seed "$seed" --out "$out/$name" $rest \
    >"$out/logs/$name.log" 2>&1 || { echo "failed: $name (see $out/logs/$name.log)"; continue; }
  grep -E "done:|checks:" "$out/logs/$name.log" || true
done
