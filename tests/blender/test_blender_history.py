# SPDX-License-Identifier: Apache-2.0
"""Live mode and the add-on's bake with a default database (the pose model, which reads history
frames before every frame) against `drivenshape bake` of the same database, bitwise (issue 27).

The bug this pins: after a jump live mode stood the frame itself in for its history frames, and
gave cloth up to 31 mm from the bake's frame; the tests that build with `--model none` never saw
it. Now every frame is the bake's, however the timeline got there: playing forward, jumping to
frames in any order, playing backwards, the same frame again, starting live mode on a frame, and
the add-on's bake of the scene range or of a part of it. A driver edited on its frame (no frame
change) is evaluated with the history frames read before, checked against the module's
Evaluator given the same frames. Each comparison is of float32 bit patterns.
"""

import os
import sys

import bpy
import numpy as np

sys.dont_write_bytecode = True  # Blender ignores PYTHONDONTWRITEBYTECODE: keep the tree clean
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import blender_test_util as util  # noqa: E402

args = util.parse_args()
checks = util.Checks("test_blender_history")
addon = util.install_addon(args.work)
ds = util.drivenshape_module(addon)
driver, cloth = util.sleeve_scene(ds, args.data, os.path.join(args.work, "sleeve_pose.dsdb"))
scene = bpy.context.scene
settings = scene.drivenshape
cli = os.path.join(args.work, "cli", "pose")
expected = {frame: util.cli_frame(ds, cli, frame) for frame in range(1, 49)}
test_driver, start, _rate = ds.read_pc2(os.path.join(args.data, "test.driver.pc2"))
checks.check(start == 1.0 and len(test_driver) == 48, "the test clip holds frames 1-48")


def bitwise(got, frame):
    want = expected[frame]
    return got.shape == want.shape and np.array_equal(got.view(np.uint32), want.view(np.uint32))


def compare(frames, label):
    """Sets the scene to each of `frames` and compares the cloth with the CLI's, bitwise."""
    differing = []
    for frame in frames:
        scene.frame_set(frame)
        if not bitwise(util.evaluated_positions(cloth), frame):
            differing.append(frame)
    checks.check(not differing, f"{label}: the cloth is the CLI's bitwise on every frame "
                 f"(differs on {differing or 'none'})")


scene.frame_set(30)
bpy.ops.drivenshape.live_start()
checks.check(addon.live.is_live(scene), "live mode started on frame 30")
evaluator = addon.engine.CACHE.evaluator
history = evaluator.history_frames
checks.check(0 < history < 19,
             f"the default database's pose model reads {history} history frames (1-18 here)")
checks.check(addon.engine.CACHE.device.is_opencl, "live mode runs on OpenCL (PoCL) as the CLI")
checks.check(bitwise(util.evaluated_positions(cloth), 30),
             "starting live mode on frame 30 shows the CLI's frame 30")

# The test means something: frame 30 evaluated without its history is another cloth.
alone, _records = ds.Evaluator(addon.engine.CACHE.database, ds.EvaluatorSettings(),
                               addon.engine.CACHE.device).evaluate([30], test_driver[29])
far = float(np.abs(alone[0] - expected[30]).max())
checks.check(far > 1e-4, f"frame 30 without its history frames is {far:.3g} off the CLI's")

compare(range(1, 49), "playing forward, frames 1-48")
compare([30, 10, 47, 17, 25, 3, 40, 16], "jumps to frames 30, 10, 47, 17, 25, 3, 40 and 16")
compare(range(48, 0, -1), "playing backwards, frames 48-1")
compare([12, 12, 13, 14, 35, 36], "the same frame twice, then forward, a jump and forward")
read = addon.live.SESSION.warmup_frames_read
checks.check(read > 0, f"jumps read the driver at {read} earlier frames")
checks.check(addon.engine.CACHE.evaluator is evaluator, "the Evaluator was kept between frames")

# The driver edited on frame 20 without a frame change (a rig being posed): the history frames
# are the ones read before (the jump to 20 read them), the frame is the edited pose.
scene.frame_set(20)
driver.modifiers["reference"].factor = 0.5
bpy.context.view_layer.update()
posed = util.evaluated_positions(driver)
frames = list(range(20 - history, 21))
block = np.concatenate([test_driver[20 - history - 1:19], posed[np.newaxis]])
reference, _records = ds.Evaluator(addon.engine.CACHE.database, ds.EvaluatorSettings(),
                                   addon.engine.CACHE.device).evaluate(frames, block,
                                                                       warmup=history)
got = util.evaluated_positions(cloth)
checks.check(np.array_equal(got.view(np.uint32), reference[0].view(np.uint32))
             and not bitwise(got, 20),
             "editing the driver on frame 20 gives the module's Evaluator on the edited pose after "
             "the frames before it, bitwise")
driver.modifiers["reference"].factor = 1.0
bpy.ops.drivenshape.live_stop()

# The add-on's bake: the whole scene range, then frames 30-40 alone (their history comes from
# the scene's frames before 30, as the CLI reads it from the cache).
out = os.path.join(args.work, "history_bake")
settings.bake_pc2_path = os.path.join(out, "sleeve.pc2")
settings.bake_add_mesh_cache = False
for first, last in ((1, 48), (30, 40)):
    settings.bake_use_scene_range = (first, last) == (1, 48)
    settings.bake_frame_start, settings.bake_frame_end = first, last
    result = bpy.ops.drivenshape.bake()
    positions, start, _rate = ds.read_pc2(settings.bake_pc2_path)
    differing = [f for f in range(first, last + 1) if not bitwise(positions[f - first], f)]
    checks.check(result == {"FINISHED"} and start == first and len(positions) == last - first + 1
                 and not differing,
                 f"the add-on's bake of frames {first}-{last} is the CLI's bitwise (differs on "
                 f"{differing or 'none'})")

checks.finish()
