# SPDX-License-Identifier: Apache-2.0
"""The frames to simulate where an animator looks (issue 29): the timeline markers that Mark
Frames to Simulate and the add-on's bake put on the frames the pose model flags, and the cloth
coloured by the error bound, against the report of `drivenshape bake` of the same shot and
database (the fixture's cli/pose_tolerance bake: per frame its error_bound and
coverage.flagged), a tool path that shares nothing with the add-on but the library.

Also checked: a new marking removes the add-on's old markers and none of the user's (one of them
named like the add-on's); the marking writes no file and puts the scene back on its frame; the
panel's count; Next/Previous frame to simulate; a bake of a part of the range; the QP refused.
The colour scale is docs/blender.md's, written out here."""

import json
import os
import sys

import bpy
import numpy as np

sys.dont_write_bytecode = True  # Blender ignores PYTHONDONTWRITEBYTECODE: keep the tree clean
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import blender_test_util as util  # noqa: E402

# docs/blender.md#frames-to-simulate: linear RGB at half the tolerance and below, at the
# tolerance, at 1.5 times it and above; grey without a prediction. Colours are float32 in Blender.
GREEN, YELLOW, RED, GREY = (0.05, 0.60, 0.05), (0.90, 0.75, 0.02), (0.80, 0.03, 0.02), \
    (0.25, 0.25, 0.25)
COLOR_TOLERANCE = 1e-6
# A tolerance that flags every frame of the test clip, for the first marking.
LOOSE_TOLERANCE = 9.0 / 1024.0

args = util.parse_args()
checks = util.Checks("test_blender_coverage")
addon = util.install_addon(args.work)
ds = util.drivenshape_module(addon)
driver, cloth = util.sleeve_scene(ds, args.data, os.path.join(args.work, "sleeve_pose.dsdb"))
scene = bpy.context.scene
settings = scene.drivenshape

with open(os.path.join(args.work, "cli", "pose_tolerance", "sleeve.report.json")) as file:
    report = json.load(file)
tolerance = report["settings"]["coverage_tolerance"]
cli = {f["frame"]: (f["error_bound"], f["coverage"]["flagged"]) for f in report["frames"]}
flagged = sorted(frame for frame, (_error, is_flagged) in cli.items() if is_flagged)
checks.check(sorted(cli) == list(range(1, 49)) and 0 < len(flagged) < 48,
             f"the CLI's report has frames 1-48, {len(flagged)} flagged ({flagged}): the markers "
             "have something to get right either way")
checks.check(np.float32(tolerance) == tolerance, f"the CLI's tolerance {tolerance} is a float32")
units = scene.unit_settings
checks.check(units.system == "METRIC" and units.scale_length == 1.0,
             "the factory scene is metric at scale 1 (a Blender unit is a metre)")


def expected_markers(frames):
    return {(frame, f"DS simulate {cli[frame][0] * 1000.0:.1f} mm") for frame in frames}


def markers():
    return {(marker.frame, marker.name) for marker in scene.timeline_markers}


USER = {(flagged[0], "blocking pass"), (5, "DS simulate 99.9 mm")}
for frame, name in USER:
    scene.timeline_markers.new(name, frame=frame)

out = os.path.join(args.work, "coverage_bake")
settings.bake_pc2_path = os.path.join(out, "sleeve.pc2")
settings.bake_add_mesh_cache = False

# A first marking that flags nearly every frame, then the one to check: the first one's markers
# must all be gone.
scene.frame_set(7)
settings.coverage_tolerance = LOOSE_TOLERANCE
result = bpy.ops.drivenshape.mark_frames()
loose = markers() - USER
checks.check(result == {"FINISHED"} and len(loose) > len(flagged),
             f"a marking with a tolerance of {LOOSE_TOLERANCE} marks {len(loose)} frames")
# That tolerance is below the smallest error bound the database's verdict gives (its error line
# at deviation 0 plus its margin, as `drivenshape info` states it): the job warns, as the
# library does in every tool, and the operators report it; the CLI's tolerance is not.
job = addon.bake.Bake(bpy.context, write_files=False)
below = [w for w in job.warnings if "every frame will be flagged for simulation" in w]
checks.check(len(loose) == 48 and len(below) == 1,
             f"a tolerance that flags all 48 frames ({len(loose)}) warns once: {job.warnings}")
settings.coverage_tolerance = tolerance
checks.check(addon.bake.Bake(bpy.context, write_files=False).warnings == [],
             "the CLI's tolerance flags some frames and warns of nothing")
result = bpy.ops.drivenshape.mark_frames()
want = expected_markers(flagged) | USER
checks.check(result == {"FINISHED"} and markers() == want,
             "Mark Frames to Simulate: the markers are the CLI's flagged frames named with its "
             "error bounds, the user's markers kept and the earlier marking's gone "
             f"(missing {sorted(want - markers())}, extra {sorted(markers() - want)})")
checks.check(scene.frame_current == 7, "the marking puts the scene back on its frame")
checks.check(not os.path.exists(out), f"the marking wrote no file ({out} does not exist)")
stored = [(v.frame, v.error_bound, v.flagged) for v in settings.verdicts]
checks.check(stored == [(f, float(np.float32(cli[f][0])), cli[f][1]) for f in range(1, 49)],
             "the scene stores each frame's error bound and verdict as the CLI's report")
lines = addon.ui.verdict_lines(settings, units)
want_lines = [("Frames", "1-48", False), ("Simulate", f"{len(flagged)} of 48", True),
              ("Tolerance", f"{tolerance * 1000.0:.1f} mm", False)]
checks.check(lines == want_lines, f"the panel says {lines}, expected {want_lines}")

# Next and previous frame to simulate, from frame 1: every flagged frame in order, then around.
scene.frame_set(1)
visited = []
for _ in range(len(flagged) + 1):
    bpy.ops.drivenshape.jump_flagged()
    visited.append(scene.frame_current)
checks.check(visited == flagged + flagged[:1],
             f"Next visits the CLI's flagged frames and wraps around: {visited}")
bpy.ops.drivenshape.jump_flagged(previous=True)
checks.check(scene.frame_current == flagged[-1],
             f"Previous from the first flagged frame wraps to the last: {scene.frame_current}")

# The add-on's bake marks the same frames; a bake of frames 30-40 marks those of its range only.
for first, last in ((1, 48), (30, 40)):
    settings.bake_use_scene_range = (first, last) == (1, 48)
    settings.bake_frame_start, settings.bake_frame_end = first, last
    result = bpy.ops.drivenshape.bake()
    want = expected_markers([f for f in flagged if first <= f <= last]) | USER
    checks.check(result == {"FINISHED"} and os.path.exists(settings.bake_pc2_path)
                 and markers() == want,
                 f"the bake of frames {first}-{last} marks the CLI's flagged frames of its range "
                 f"(missing {sorted(want - markers())}, extra {sorted(markers() - want)})")

# Only the pose model predicts: with the QP, marking is refused and the markers stay.
settings.weight_mode = "qp"
ok, message = util.expect_operator_error(bpy.ops.drivenshape.mark_frames, "pose model")
checks.check(ok and markers() == want, f"marking with the QP is refused: {message}")
settings.weight_mode = "auto"


# Error Colors: one colour per frame from its predicted error.
def ramp(error):
    x = min(max(error / tolerance, 0.5), 1.5)
    low, high, t = (GREEN, YELLOW, 2.0 * (x - 0.5)) if x <= 1.0 else (YELLOW, RED, 2.0 * (x - 1.0))
    return np.array([a + (b - a) * t for a, b in zip(low, high)] + [1.0])


def cloth_colors():
    attribute = cloth.data.color_attributes.get("DS predicted error")
    if attribute is None or attribute.domain != "POINT":
        return None
    colors = np.empty((len(cloth.data.vertices), 4), dtype=np.float32)
    attribute.data.foreach_get("color", colors.reshape(-1))
    return colors


def check_colors(rgba, label):
    colors = cloth_colors()
    off = float("inf") if colors is None else float(np.abs(colors - rgba).max())
    checks.check(off <= COLOR_TOLERANCE and
                 cloth.data.color_attributes.active_color_name == "DS predicted error",
                 f"{label}: every vertex is {np.round(rgba, 4).tolist()} ({off:.2g} off, "
                 f"tolerance {COLOR_TOLERANCE})")


bpy.ops.drivenshape.mark_frames()
settings.error_colors = True
for frame in (4, flagged[0], 30):
    scene.frame_set(frame)
    check_colors(ramp(cli[frame][0]), f"frame {frame} ({cli[frame][0] * 1000.0:.2f} mm, "
                 f"{'flagged' if cli[frame][1] else 'not flagged'})")
# Yellow is the tolerance: an unflagged frame is on the green side of it (more green per red),
# a flagged one on the red side.
unflagged, over = ramp(cli[4][0]), ramp(cli[30][0])
checks.check(not cli[4][1] and cli[30][1] and
             unflagged[1] / unflagged[0] > YELLOW[1] / YELLOW[0] > over[1] / over[0],
             "an unflagged frame is greener than the tolerance's yellow, a flagged one redder")

scene.frame_set(25)
bpy.ops.drivenshape.live_start()
check_colors(ramp(addon.live.SESSION.last_record.error_bound), "live mode on frame 25")
checks.check(addon.live.SESSION.last_record.error_bound == cli[25][0],
             "live mode's error bound on frame 25 is the CLI's")
scene.frame_set(26)
check_colors(ramp(cli[26][0]), "live mode, playing on to frame 26")
bpy.ops.drivenshape.live_stop()
check_colors(ramp(cli[26][0]), "live mode stopped on frame 26: the stored verdict's colour")

bpy.ops.drivenshape.clear_marks()
checks.check(markers() == USER and len(settings.verdicts) == 0,
             "Clear removes the add-on's markers and verdicts, not the user's markers")
check_colors(np.array(GREY + (1.0,)), "no verdict stored: grey")
settings.error_colors = False
checks.check(cloth_colors() is None, "Error Colors off removes the colour attribute")

checks.finish()
