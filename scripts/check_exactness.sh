#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Closest-triangle exactness on every frame of the pants test clip (DRIVENSHAPE_DATA, default
# out/data: the public clips made by scripts/validation/generate_clips.sh --link-data out/data
# out/clips; not shipped with the repository): the library's OpenCL search vs an independent
# brute force, per vertex.
# Needs a build (scripts/setup.sh; DRIVENSHAPE_BUILD names another build folder). Takes a few
# minutes on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/.."
data=${DRIVENSHAPE_DATA:-out/data}
build=${DRIVENSHAPE_BUILD:-build}
export POCL_CACHE_DIR="$PWD/$build/pocl-cache"
for scene in ${*:-pants}; do
  "$build/tests/devices/check_closest_exact" "$data/$scene/driver_rest.obj" \
    "$data/$scene/test_public.driver.pc2" "$data/$scene/test_public.driven.pc2"
done
