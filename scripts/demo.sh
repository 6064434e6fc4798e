#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# The main job on the bundled sample shot (a slice of the sleeve scene in tests/data/sleeve):
# builds a 30-shape database from the range-of-motion clip, bakes the test clip through OpenCL
# into point-cache EXRs, compares the bake with the simulated truth, simulates the frames the
# verdict flags in Blender and splices them in, writes a QC page (HTML and plots), and prints
# where it all is.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh

export POCL_CACHE_DIR="$PWD/build/pocl-cache"
mkdir -p "$POCL_CACHE_DIR"
data=tests/data/sleeve
out=out/sample
mkdir -p "$out/bake"
ds=build/apps/drivenshape

"$ds" db build --driver-mesh $data/driver_rest.obj --driven-mesh $data/driven_rest.obj \
  --driver $data/train.driver.pc2 --driven $data/train.driven.pc2 --count 30 --quiet \
  -o $out/sleeve.dsdb
"$ds" bake --db $out/sleeve.dsdb --driver $data/test.driver.pc2 --frames 1-48 \
  -o $out/bake/sleeve.####.exr 2>$out/bake.log
"$ds" eval --truth $data/test.driven.pc2 --bake "$out/bake/sleeve.####.exr" --frames 1-48 \
  --driver $data/test.driver.pc2 --db $out/sleeve.dsdb --baseline \
  --report $out/bake/sleeve.report.json --json $out/eval.json
# The frames the verdict cannot vouch for, simulated: the sample's cloth scene (its caches with
# the clip generator's sleeve cloth, scripts/sample_scene.py), then `drivenshape simulate` plans
# windows over the flagged frames, runs each in Blender's cloth solver from the bake's cloth and
# splices them into the bake (about a minute and a half on 2 cores; a rerun keeps the windows).
blender -b --factory-startup --python-exit-code 1 --python scripts/sample_scene.py -- \
  -o $out/shot.blend >$out/simulate.log 2>&1
DRIVENSHAPE_PYTHONPATH="$PWD/build/python" "$ds" simulate --blend $out/shot.blend --object sleeve \
  --report $out/bake/sleeve.report.json --bake "$out/bake/sleeve.####.exr" \
  -o "$out/final/sleeve.####.exr" >>$out/simulate.log 2>&1
"$ds" eval --truth $data/test.driven.pc2 --bake "$out/final/sleeve.####.exr" --frames 1-48 \
  --json $out/final_eval.json >/dev/null
# The QC page (which model made the bake, the pose model's predicted error and verdict, the
# penetrations, popping, the error per frame and a per-vertex error heat map; the Python
# module's drivenshape.qc), for a supervisor's browser. The sample is in metres: lengths are
# shown in mm.
PYTHONPATH=build/python .venv/bin/python -m drivenshape.qc --report $out/bake/sleeve.report.json \
  --eval $out/eval.json --simulated $out/final/sleeve.report.json --mesh $data/driven_rest.obj \
  --units m -o $out/qc >/dev/null
# The same shot through USD, as a USD pipeline would take it: the driver written as a time-sampled
# UsdGeomMesh (the sample's USD driver, to try `drivenshape.usd bake` on), baked into USD cloth
# with normals, velocities and provenance.
PYTHONPATH=build/python .venv/bin/python -m drivenshape.usd export --mesh $data/driver_rest.obj \
  --pc2 $data/test.driver.pc2 --prim /Character/Arm -o $out/test.driver.usda >/dev/null
PYTHONPATH=build/python .venv/bin/python -m drivenshape.usd bake --db $out/sleeve.dsdb \
  --usd $out/test.driver.usda --prim /Character/Arm --out $out/sleeve.usdc --quiet >/dev/null
echo "usd:      $PWD/$out/sleeve.usdc (from the USD driver $PWD/$out/test.driver.usda)"
echo "log:      $PWD/$out/bake.log"
echo "spliced:  $PWD/$out/final/sleeve.####.exr (the flagged frames simulated; $PWD/$out/simulate.log)"
PYTHONPATH=build/python .venv/bin/python -c "import json, sys
baked, final = (json.load(open(p))['mean'] * 1000 for p in sys.argv[1:])
print(f'error:    {baked:.1f} mm baked, {final:.1f} mm spliced (mean vertex distance to the simulated truth)')" \
  $out/eval.json $out/final_eval.json
echo "accuracy: $PWD/$out/eval.json"
echo "qc:       $PWD/$out/qc/index.html"
