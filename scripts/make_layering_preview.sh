#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# The layering picture of docs/commands.md (issue 8): the pants of the reference data with the waistband
# mixed with the skin-only result and light wind on the lower legs.
#
#   1. db build: 30 shapes from the pants `train` clip;
#   2. bake `test_public` plain (the defaults) and the skin-only result (`--weights bind`, the
#      rest cloth bound to the rest legs and carried along);
#   3. derive two JSON weight maps from the heights of the driven rest OBJ (Z up):
#      mix weight 0 on the waistband (the top WAIST_M of the trousers, taken from the skin-only
#      cache) and 1 elsewhere; wind weight 1 on the lower legs (the bottom SHIN_M) and 0
#      elsewhere;
#   4. bake the layered version (--mix-falloff 3, light wind, --wind-falloff 2);
#   5. `drivenshape eval` of the plain, skin-only and layered bakes against the simulated truth
#      (error and cloth vertices inside the legs), summarised as a Markdown table;
#   6. scripts/layering_preview.py renders the layered frame PREVIEW_FRAME from three sides,
#      coloured by the mix weight, the wind weight and |layered - plain|.
#
# Not a test: it reads the public pants clips made by scripts/validation/generate_clips.sh
# --link-data out/data out/clips (a pants/ folder with the rest OBJs, train.* and test_public.*).
# Usage: scripts/make_layering_preview.sh
# Environment: DRIVENSHAPE_DATA (or DATA; default out/data, in the clone), DRIVENSHAPE_BUILD
#              (default build), OUT (default
#              out/layering), FRAMES (default 1-140, the whole test clip), PREVIEW_FRAME
#              (default 100), IMAGE (default scripts/readme_images/layering_pants.png),
#              DRIVENSHAPE_DEVICE (bake --device, default auto).
set -euo pipefail
cd "$(dirname "$0")/.."
data=${DRIVENSHAPE_DATA:-${DATA:-out/data}}
build=${DRIVENSHAPE_BUILD:-build}
out=${OUT:-out/layering}
frames=${FRAMES:-1-140}
preview_frame=${PREVIEW_FRAME:-100}
image=${IMAGE:-scripts/readme_images/layering_pants.png}
device=${DRIVENSHAPE_DEVICE:-auto}
# Layer settings (scene units are metres).
waist_m=0.12
shin_m=0.35
mix_falloff=3
wind_falloff=2
wind=(--wind-amplitude 0.01 --wind-frequency 4 --wind-direction "1,0,0" --wind-speed 1.5
  --wind-falloff "$wind_falloff")

ds=$build/apps/drivenshape
src=$data/pants
if [[ ! -x $ds ]]; then
  echo "make_layering_preview: '$ds' not found; build it first (bash scripts/setup.sh, or" \
    "cmake --build $build --target drivenshape_cli) or set DRIVENSHAPE_BUILD" >&2
  exit 2
fi
for file in driver_rest.obj driven_rest.obj train.driver.pc2 train.driven.pc2 \
  test_public.driver.pc2 test_public.driven.pc2; do
  if [[ ! -f $src/$file ]]; then
    echo "make_layering_preview: '$src/$file' not found; make the public clips with" \
      "scripts/validation/generate_clips.sh --link-data $data out/clips, or set" \
      "DRIVENSHAPE_DATA to a folder that holds pants/" >&2
    exit 3
  fi
done
if ! .venv/bin/python -c "import matplotlib, numpy, OpenEXR" 2>/dev/null; then
  echo "make_layering_preview: preparing .venv with scripts/setup.sh" >&2
  bash scripts/setup.sh
fi
python=.venv/bin/python
export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$PWD/$build/pocl-cache}
mkdir -p "$POCL_CACHE_DIR" "$out/plain" "$out/skin" "$out/layered"
start=$SECONDS

"$ds" db build --driver-mesh "$src/driver_rest.obj" --driven-mesh "$src/driven_rest.obj" \
  --driver "$src/train.driver.pc2" --driven "$src/train.driven.pc2" --count 30 --quiet \
  -o "$out/pants.dsdb"

bake() { # bake NAME [FLAGS...]: one bake of the test clip into $out/NAME
  local name=$1
  shift
  "$ds" bake --db "$out/pants.dsdb" --driver "$src/test_public.driver.pc2" --frames "$frames" \
    --device "$device" --quiet -o "$out/$name/pants.####.exr" "$@" |
    sed -n "s/^baked /$name: baked /p"
}
bake plain
bake skin --weights bind

# Weight maps from the rest heights (one number per driven vertex, OBJ order).
$python - "$src/driven_rest.obj" "$out" "$waist_m" "$shin_m" <<'PY'
import json, sys
obj, out, waist, shin = sys.argv[1], sys.argv[2], float(sys.argv[3]), float(sys.argv[4])
z = [float(line.split()[3]) for line in open(obj) if line.startswith("v ")]
top, bottom = max(z), min(z)
mix = [0.0 if h > top - waist else 1.0 for h in z]
wind = [1.0 if h < bottom + shin else 0.0 for h in z]
json.dump(mix, open(f"{out}/mix_weight.json", "w"))
json.dump(wind, open(f"{out}/wind_weight.json", "w"))
print(f"weight maps: {mix.count(0.0)} waistband vertices (z > {top - waist:.3f}) take the "
      f"skin-only result, {int(sum(wind))} lower-leg vertices (z < {bottom + shin:.3f}) get wind, "
      f"of {len(z)}")
PY

bake layered --mix "$out/skin/pants.####.exr" --mix-weight "$out/mix_weight.json" \
  --mix-falloff $mix_falloff "${wind[@]}" --wind-weight "$out/wind_weight.json"

for name in plain skin layered; do
  "$ds" eval --truth "$src/test_public.driven.pc2" --bake "$out/$name/pants.####.exr" \
    --frames "$frames" --driver "$src/test_public.driver.pc2" \
    --driver-mesh "$src/driver_rest.obj" --json "$out/eval_$name.json" >/dev/null
done
$python - "$out" <<'PY'
import json, sys
out = sys.argv[1]
labels = {"plain": "DrivenShape (defaults)", "skin": "skin-only (`--weights bind`)",
          "layered": "layered (waistband mix + wind)"}
print("| bake | mean error (mm) | RMS (mm) | max (mm) | inside the legs / frame | deepest (mm) |")
print("|---|---|---|---|---|---|")
for name, label in labels.items():
    s = json.load(open(f"{out}/eval_{name}.json"))["summary"]["bake"]
    print(f"| {label} | {1e3 * s['mean']:.1f} | {1e3 * s['rms']:.1f} | {1e3 * s['max']:.1f} "
          f"| {s['mean_inside']:.2f} | {1e3 * s['max_depth']:.2f} |")
PY

$python scripts/layering_preview.py --mesh "$src/driven_rest.obj" \
  --exr "$out/layered/pants.####.exr" --frame "$preview_frame" \
  --mix-weight "$out/mix_weight.json" --mix-falloff $mix_falloff \
  --wind-weight "$out/wind_weight.json" --wind-falloff $wind_falloff \
  --compare "$out/plain/pants.####.exr" \
  --title "pants, test_public frame $preview_frame: waistband mixed with the skin-only result,\
 wind on the lower legs" \
  -o "$image"
echo "done in $((SECONDS - start)) s: bakes and evals in $out, picture $image"
