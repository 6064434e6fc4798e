#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# One-off bitwise check of a refactored bake on the two public clips (DRIVENSHAPE_DATA/{pants,
# sleeve}, made by scripts/validation/generate_clips.sh --link-data): for each clip, a 30-shape
# database from the `train` clip, then `test_public` baked (all its frames) in three modes
# (default; talk: --align none --blend world --no-resolve --strain-limit 0; bind:
# --weights bind --strain-limit 0) on the host path and the OpenCL CPU device, with an OLD and a NEW
# drivenshape binary. Per frame it compares the decoded pixels (sha256 through the OpenEXR
# Python bindings, tests/golden/golden_pixels.py) and the file bytes, and the bake report's
# per-frame records (no timing, no paths), and prints one line per (clip, mode, device):
#
#   pants default cpu: 140/140 frames pixel-identical, 140/140 byte-identical, 140/140 report records identical
#
# Not a test (it reads generated clips); the sample-scale check is CTest golden_sample.
#
# Usage: scripts/golden_clips.sh OLD_BIN NEW_BIN [OUTDIR]      (OUTDIR default out/golden-clips)
#   OLD_BIN or NEW_BIN may be `-` to skip that side: record the OLD side now
#   (scripts/golden_clips.sh /tmp/ds-f302ac6/drivenshape - /tmp/golden-clips) and compare the
#   NEW side later (scripts/golden_clips.sh - build/apps/drivenshape /tmp/golden-clips).
# The OLD side's hashes are cached in OUTDIR/old-<clip>-<mode>-<device>.json and reused while
# the OLD binary's sha256 matches; the NEW side is baked every run (OUTDIR/new-*.json). Bakes go
# to OUTDIR/work and are deleted once hashed (KEEP_BAKES=1 keeps them).
# Environment: DRIVENSHAPE_DATA (default out/data, in the clone), CLIPS (default "pants sleeve"),
#   MODES (default "default talk bind"; also qp: --weights qp), DEVICES (default "host cpu"), HOST_STEP (bake every
#   Nth frame on the host path; default 1 = every frame: the host bakes a whole clip in ~5 s).
# Exit status: 0 when every compared bake is pixel-identical with identical report records, 1
# otherwise (or on a failed bake).
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$PWD

if (($# < 2 || $# > 3)); then
  sed -n '2,30p' "$0" | sed 's/^# \{0,1\}//' >&2
  exit 2
fi
old_bin=$1
new_bin=$2
outdir=${3:-out/golden-clips}
data=${DRIVENSHAPE_DATA:-out/data}
read -ra clips <<<"${CLIPS:-pants sleeve}"
read -ra modes <<<"${MODES:-default talk bind}"
read -ra devices <<<"${DEVICES:-host cpu}"
host_step=${HOST_STEP:-1}
keep=${KEEP_BAKES:-0}
python=python3
[[ -x .venv/bin/python ]] && python=$repo/.venv/bin/python
helper=$repo/tests/golden/golden_clips_helper.py

mkdir -p "$outdir/work"
outdir=$(cd "$outdir" && pwd)
export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$outdir/pocl-cache}
mkdir -p "$POCL_CACHE_DIR"

mode_flags() {
  case $1 in
    default) echo "" ;;
    talk) echo "--align none --blend world --no-resolve --strain-limit 0" ;;
    bind) echo "--weights bind --strain-limit 0" ;;
    qp) echo "--weights qp --strain-limit 0" ;;
    *) echo "golden_clips: unknown mode '$1'" >&2; exit 2 ;;
  esac
}

# bake_side SIDE BIN CLIP: database + every mode x device for one binary; writes
# OUTDIR/SIDE-CLIP-MODE-DEVICE.json (skipped for the OLD side when cached for this binary).
bake_side() {
  local side=$1 bin=$2 clip=$3
  local src=$data/$clip
  local bin_sha
  bin_sha=$(sha256sum "$bin" | cut -d' ' -f1)
  local range
  range=$("$bin" info "$src/test_public.driver.pc2" | sed -n 's/.*frames (\([-0-9]*-[-0-9]*\)).*/\1/p')
  [[ -n $range ]] || { echo "golden_clips: no frame range in '$bin info' of $src/test_public.driver.pc2" >&2; exit 1; }
  local db=$outdir/work/$side-$clip.dsdb
  local need_db=1
  for mode in "${modes[@]}"; do
    for device in "${devices[@]}"; do
      local cache=$outdir/$side-$clip-$mode-$device.json
      if [[ $side == old && -f $cache ]] && "$python" "$helper" cached "$cache" "$bin_sha"; then
        echo "  $side $clip $mode $device: cached ($cache)"
        continue
      fi
      local frames=$range
      if [[ $device == host && $host_step != 1 ]]; then
        frames="${range}x$host_step"
        echo "  NOTE: $side $clip $mode host bakes every ${host_step}th frame only ($frames)"
      fi
      if ((need_db)); then
        "$bin" db build --driver-mesh "$src/driver_rest.obj" --driven-mesh "$src/driven_rest.obj" \
          --driver "$src/train.driver.pc2" --driven "$src/train.driven.pc2" --count 30 --quiet \
          -o "$db" >/dev/null
        need_db=0
      fi
      local dir=$outdir/work/$side-$clip-$mode-$device
      rm -rf "$dir"
      mkdir -p "$dir"
      local start=$SECONDS
      # shellcheck disable=SC2046
      if ! "$bin" bake --db "$db" --driver "$src/test_public.driver.pc2" --frames "$frames" \
        --device "$device" -o "$dir/$clip.####.exr" $(mode_flags "$mode") >"$dir.log" 2>&1; then
        echo "golden_clips: $side $clip $mode $device: bake failed (log: $dir.log):" >&2
        tail -5 "$dir.log" >&2
        exit 1
      fi
      local seconds=$((SECONDS - start))
      "$python" "$helper" record "$cache" --binary "$bin" --binary-sha "$bin_sha" --clip "$clip" \
        --mode "$mode" --device "$device" --flags="$(mode_flags "$mode")" --frames "$frames" \
        --pattern "$dir/$clip.####.exr" --report "$dir/$clip.report.json" --seconds "$seconds"
      echo "  $side $clip $mode $device: baked $frames in ${seconds} s -> $cache"
      ((keep)) || rm -rf "$dir"
    done
  done
}

for clip in "${clips[@]}"; do
  [[ $old_bin == - ]] || bake_side old "$old_bin" "$clip"
  [[ $new_bin == - ]] || bake_side new "$new_bin" "$clip"
done

status=0
compare_flags=()
[[ $new_bin == - ]] && compare_flags=(--old-only)
echo "summary (OLD: $old_bin, NEW: $new_bin; hashes in $outdir):"
for clip in "${clips[@]}"; do
  for mode in "${modes[@]}"; do
    for device in "${devices[@]}"; do
      "$python" "$helper" compare "$outdir/old-$clip-$mode-$device.json" \
        "$outdir/new-$clip-$mode-$device.json" --label "$clip $mode $device" \
        "${compare_flags[@]}" || status=1
    done
  done
done
exit $status
