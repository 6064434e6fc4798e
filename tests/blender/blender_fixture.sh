#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Shared data of the Blender add-on tests (CTest fixture blender_data), made with the command
# line, independently of the add-on:
#   WORK/sleeve.dsdb                  db build from the bundled sleeve's training clip
#   WORK/cli/default/sleeve.####.exr  bake of the test clip, frames 1-48, default settings
#   WORK/cli/bound/sleeve.####.exr    the same with a temporal bound, one batch from frame 1,
#                                     without the strain limit
#   WORK/cli/bound_jump/...           the same bound from frame 30 (a timeline jump), with the
#                                     bake's default temporal warm-up before it
#   WORK/sleeve_pose.dsdb             db build with its defaults: the pose model, which reads
#                                     history frames before every frame
#   WORK/cli/pose/sleeve.####.exr     bake of the test clip with it, frames 1-48, defaults
#   WORK/cli/pose_tolerance/          the same with a coverage tolerance that flags part of the
#     sleeve.report.json              clip; its report's per-frame verdicts
#   WORK/drivenshape_blender.zip      the add-on, packed by scripts/blender_package.py
# Usage: blender_fixture.sh CLI SOURCE_DIR WORK
set -euo pipefail
cli=$1
source_dir=$2
work=$3
data=$source_dir/tests/data/sleeve

rm -rf "$work"
mkdir -p "$work/cli/default" "$work/cli/bound" "$work/cli/bound_jump" "$work/cli/pose" \
  "$work/cli/pose_tolerance"

"$cli" db build --driver-mesh "$data/driver_rest.obj" --driven-mesh "$data/driven_rest.obj" \
  --driver "$data/train.driver.pc2" --driven "$data/train.driven.pc2" --count 30 --model none --quiet \
  -o "$work/sleeve.dsdb"
"$cli" bake --db "$work/sleeve.dsdb" --driver "$data/test.driver.pc2" --frames 1-48 --quiet \
  -o "$work/cli/default/sleeve.####.exr"
# The temporal bound holds between consecutive frames; the bake starts each batch afresh after
# its warm-up frames (none before frame 1), as live mode does after a jump. Without the strain
# limit: live mode's bounded weights differ from the batch's by float rounding, which the limit's
# iterations amplify (docs/validation.md, "The limit's conditioning"); the bound is what these
# bakes check.
bound=(--max-weight-change 0.02 --batch 64 --strain-limit 0 --exit-fade 0.15)
"$cli" bake --db "$work/sleeve.dsdb" --driver "$data/test.driver.pc2" --frames 1-48 --quiet \
  "${bound[@]}" -o "$work/cli/bound/sleeve.####.exr"
"$cli" bake --db "$work/sleeve.dsdb" --driver "$data/test.driver.pc2" --frames 30-40 --quiet \
  "${bound[@]}" -o "$work/cli/bound_jump/sleeve.####.exr"

"$cli" db build --driver-mesh "$data/driver_rest.obj" --driven-mesh "$data/driven_rest.obj" \
  --driver "$data/train.driver.pc2" --driven "$data/train.driven.pc2" --quiet \
  -o "$work/sleeve_pose.dsdb"
"$cli" bake --db "$work/sleeve_pose.dsdb" --driver "$data/test.driver.pc2" --frames 1-48 --quiet \
  -o "$work/cli/pose/sleeve.####.exr"
# The default tolerance flags every frame of the test clip (the sample's 61 reference frames
# bound each one's error at 21.2-24.6 mm); this one flags part of it. It is 186/8192, a float32
# exactly, as Blender's float properties hold it, and 0.08 mm from the nearest bound.
"$cli" bake --db "$work/sleeve_pose.dsdb" --driver "$data/test.driver.pc2" --frames 1-48 --quiet \
  --coverage-tolerance 0.022705078125 -o "$work/cli/pose_tolerance/sleeve.####.exr"

python3 "$source_dir/scripts/blender_package.py" -o "$work/drivenshape_blender.zip"
