#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# The installable package, end to end: install the build into a temporary prefix, build the
# consumer project (tests/package/consumer, copied out of the tree) with find_package against
# that prefix only, bake the sample's first frames with the installed CLI, and let the consumer
# evaluate the same frames in memory and compare them bitwise.
#   test_package.sh BUILD_DIR SOURCE_DIR
set -euo pipefail
build=$1
source=$2
work=$(mktemp -d "${TMPDIR:-/tmp}/ds-package.XXXXXX")
trap 'rm -rf "$work"' EXIT

cmake --install "$build" --prefix "$work/prefix" > "$work/install.log"
test -x "$work/prefix/bin/drivenshape"
test -f "$work/prefix/include/drivenshape/evaluator.h"
# Public headers that need not expose OpenCL do not include it.
if grep -l "CL/opencl.hpp" "$work/prefix/include/drivenshape/"*.h | grep -v device_cl.h; then
  echo "FAIL: the headers above include OpenCL" >&2
  exit 1
fi

# Every installed header stands on its own: it compiles alone against the prefix (and Eigen and
# OpenCL's headers), so none reaches a private header of the library or a build-tree path. The
# library's utilities (src/core) and backend interfaces are not installed at all.
for header in "$work/prefix/include/drivenshape/"*.h; do
  printf '#include <drivenshape/%s>\n' "$(basename "$header")" |
    c++ -std=c++17 -fsyntax-only -I"$work/prefix/include" -isystem /usr/include/eigen3 -x c++ - ||
    { echo "FAIL: $header does not compile alone against the installed headers" >&2; exit 1; }
done
for private in parallel.h progress.h atomic_file.h json_text.h hash.h device_array.h stages.h closest.h; do
  if [[ -e "$work/prefix/include/drivenshape/$private" ]]; then
    echo "FAIL: private header $private was installed" >&2
    exit 1
  fi
done

cp -r "$source/tests/package/consumer" "$work/consumer"
cmake -S "$work/consumer" -B "$work/consumer-build" -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_PREFIX_PATH="$work/prefix" -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF > "$work/configure.log"
cmake --build "$work/consumer-build" -j2 > "$work/build.log"

data="$source/tests/data/sleeve"
ds="$work/prefix/bin/drivenshape"
"$ds" db build --driver-mesh "$data/driver_rest.obj" --driven-mesh "$data/driven_rest.obj" \
  --driver "$data/train.driver.pc2" --driven "$data/train.driven.pc2" --count 30 --quiet \
  -o "$work/sleeve.dsdb"
mkdir "$work/bake"
"$ds" bake --db "$work/sleeve.dsdb" --driver "$data/test.driver.pc2" --frames 1-12 \
  --device cpu --quiet -o "$work/bake/cloth.####.exr" > /dev/null
"$work/consumer-build/consumer" "$work/sleeve.dsdb" "$data/test.driver.pc2" \
  "$work/bake/cloth.####.exr" 1 12

# The Python module (when built): the installed package imports from the prefix alone, with the
# interpreter it was built for (Debian's python3, which Blender embeds), and evaluates a frame
# bitwise as the installed CLI baked it.
packages="$work/prefix/lib/python3/dist-packages"
if [[ -f "$build/python/drivenshape/__init__.py" ]]; then
  test -f "$packages/drivenshape/usd.py"
  test -f "$packages/drivenshape/qc.py"
  test -f "$packages/drivenshape/_drivenshape.pyi"  # the types (docs/python.md#types)
  test -f "$packages/drivenshape/py.typed"
  (cd "$work" && PYTHONPATH="$packages" /usr/bin/python3 - "$work" "$data" <<'PY'
import sys
import drivenshape as ds
work, data = sys.argv[1], sys.argv[2]
assert ds.__file__.startswith(work), ds.__file__
evaluator = ds.Evaluator(ds.load_database(f"{work}/sleeve.dsdb"), None, ds.open_device("cpu"))
# The pose model reads the frames before 7 too (as the bake reads them from the cache).
frames = list(range(max(1, 7 - evaluator.history_frames), 8))
driver = ds.open_point_cache(f"{data}/test.driver.pc2").read_frames(frames)
cloth, _ = evaluator.evaluate(frames, driver, warmup=len(frames) - 1)
baked, _ = ds.read_point_cache_exr(f"{work}/bake/cloth.0007.exr")
assert cloth[0].tobytes() == baked.tobytes(), "installed module differs from the installed CLI"
print(f"installed module {ds.__version__} from {ds.__file__}: frame 7 bitwise as the CLI")
PY
  )
fi
