#!/usr/bin/env bash
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
