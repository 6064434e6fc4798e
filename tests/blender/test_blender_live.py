# SPDX-License-Identifier: Apache-2.0
"""Live mode in a real (background) Blender against the command line's bake of the same frames.

The driver object is driven by the test clip's PC2 through a Mesh Cache modifier; live mode,
with the command line's database, deforms the cloth object on every frame change. The cloth's
evaluated vertices must match `drivenshape bake` within blender_test_util.TOLERANCE, for:
playback (consecutive frames), scrubbing (jumps, backwards, the same frame twice), a temporal
bound (the bound holds across consecutive frames and is reset on a jump, as the bake resets it
at a batch start), an edit of the driver without a frame change (depsgraph update). World space
with moved objects is checked against the module's Evaluator given the same world positions.
Stopping live mode gives the cloth its rest positions back.
"""

import os
import sys

import bpy
import numpy as np

sys.dont_write_bytecode = True  # Blender ignores PYTHONDONTWRITEBYTECODE: keep the tree clean
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import blender_test_util as util  # noqa: E402

args = util.parse_args()
checks = util.Checks("test_blender_live")
addon = util.install_addon(args.work)
ds = util.drivenshape_module(addon)
driver, cloth = util.sleeve_scene(ds, args.data, os.path.join(args.work, "sleeve.dsdb"))
scene = bpy.context.scene
settings = scene.drivenshape
cli = os.path.join(args.work, "cli")
rest = util.evaluated_positions(cloth)


def compare(frames, folder, label):
    """Steps the timeline through `frames` and compares the cloth with the CLI's EXRs."""
    worst, worst_frame = 0.0, None
    for frame in frames:
        scene.frame_set(frame)
        error = util.relative_error(util.evaluated_positions(cloth),
                                    util.cli_frame(ds, folder, frame))
        if error >= worst:
            worst, worst_frame = error, frame
    checks.check(worst <= util.TOLERANCE,
                 f"{label}: largest difference from the CLI {worst:.3g} of the bounding-box "
                 f"diagonal (frame {worst_frame}; tolerance {util.TOLERANCE:g})")
    return worst


scene.frame_set(1)
bpy.ops.drivenshape.live_start()
checks.check(addon.live.is_live(scene), "live mode started")
checks.check(settings.device == "auto", "the device is 'auto', as the CLI bake's")
evaluator = addon.engine.CACHE.evaluator
print(f"device: {addon.engine.CACHE.device.description}")
checks.check(addon.engine.CACHE.device.is_opencl,
             "live mode runs on an OpenCL device (PoCL), as the CLI bake does")

worst = compare(range(1, 49), os.path.join(cli, "default"), "playback, frames 1-48")
worst = max(worst, compare([30, 10, 11, 47, 2, 2, 1], os.path.join(cli, "default"),
                           "scrubbing (jumps, backwards, the same frame twice)"))
checks.check(addon.engine.CACHE.evaluator is evaluator,
             "the Evaluator is kept between frames (not rebuilt)")
checks.check(addon.live.SESSION.frames >= 55, f"every frame change evaluated a frame "
             f"({addon.live.SESSION.frames} evaluations)")

# The temporal bound: consecutive frames keep it, a jump resets it (as a bake batch starts).
# Without the strain limit, as the fixture's bounded bakes (blender_fixture.sh says why).
settings.strain_limit = 0.0
settings.exit_fade = 0.15
settings.max_weight_change = 0.02
checks.check(addon.engine.CACHE.evaluator is not evaluator,
             "changing a setting rebuilds the Evaluator")
bound = os.path.join(cli, "bound")
bound_jump = os.path.join(cli, "bound_jump")
differs = max(util.relative_error(util.cli_frame(ds, bound, f),
                                  util.cli_frame(ds, os.path.join(cli, "default"), f))
              for f in range(1, 49))
checks.check(differs > 100 * util.TOLERANCE,
             f"the bound changes the CLI's cloth ({differs:.3g}), so the next checks mean "
             "something")
jump_differs = max(util.relative_error(util.cli_frame(ds, bound, f),
                                       util.cli_frame(ds, bound_jump, f))
                   for f in range(30, 41))
checks.check(jump_differs > 100 * util.TOLERANCE,
             f"a bake from frame 30 differs from one through it ({jump_differs:.3g})")
worst = max(worst, compare(range(1, 49), bound, "temporal bound 0.02, frames 1-48 in order"))
worst = max(worst, compare(range(30, 41), bound_jump,
                           "temporal bound after a jump to frame 30 (reset), frames 30-40"))
settings.max_weight_change = 0.0
settings.property_unset("strain_limit")
settings.property_unset("exit_fade")

# An edit of the driver without a frame change (a rig being posed): the depsgraph update
# handler evaluates the frame again. Half the Mesh Cache's influence blends the cached pose
# with the rest pose.
scene.frame_set(20)
before = util.evaluated_positions(cloth)
driver.modifiers["reference"].factor = 0.5
bpy.context.view_layer.update()
posed = util.evaluated_positions(driver)
after = util.evaluated_positions(cloth)
independent, _records = ds.Evaluator(
    addon.engine.CACHE.database, ds.EvaluatorSettings(),
    addon.engine.CACHE.device).evaluate([20], posed[np.newaxis])
error = util.relative_error(after, independent[0])
checks.check(error <= util.TOLERANCE and util.relative_error(before, after) > 1e-3,
             f"editing the driver on frame 20 updates the cloth (difference from an Evaluator "
             f"of the module {error:.3g})")
driver.modifiers["reference"].factor = 1.0

# World space: the driver rotated and moved, the cloth moved elsewhere. The driver's world
# positions go in and the result goes back into the cloth's object space. Checked against the
# module's Evaluator given the same world positions (computed here from Blender's matrices):
# against the CLI, float32 rounding of the moved coordinates alone changes the cloth by about
# 2e-6 of the diagonal (the weights are that sensitive), which says nothing about the add-on.
driver.rotation_euler = (0.0, 0.0, 1.5707963)
driver.location = (1.0, 2.0, -0.5)
cloth.location = (0.5, 0.0, 0.0)
settings.space = "WORLD"
bpy.context.view_layer.update()
reference = ds.Evaluator(addon.engine.CACHE.database, ds.EvaluatorSettings(),
                         addon.engine.CACHE.device)
world_worst = 0.0
for frame in (5, 6, 40):
    scene.frame_set(frame)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    to_world = np.array(driver.evaluated_get(depsgraph).matrix_world, dtype=np.float64)
    from_world = np.linalg.inv(np.array(cloth.matrix_world, dtype=np.float64))
    world = (util.evaluated_positions(driver).astype(np.float64) @ to_world[:3, :3].T
             + to_world[:3, 3]).astype(np.float32)
    cloth_world, _records = reference.evaluate([frame], world[np.newaxis])
    expected = (cloth_world[0].astype(np.float64) @ from_world[:3, :3].T
                + from_world[:3, 3]).astype(np.float32)
    world_worst = max(world_worst, util.relative_error(util.evaluated_positions(cloth), expected))
checks.check(world_worst <= util.TOLERANCE,
             f"world space (driver rotated and moved, cloth moved): largest difference from the "
             f"module's Evaluator on the same world positions {world_worst:.3g}")
settings.space = "LOCAL"
driver.rotation_euler = (0.0, 0.0, 0.0)
driver.location = cloth.location = (0.0, 0.0, 0.0)
bpy.context.view_layer.update()
worst = max(worst, compare([8], os.path.join(cli, "default"), "back in object space"))

stats = addon.live.SESSION.stats()
print("live mode, median ms per frame in the handler: read %.3f, evaluate %.2f, write %.3f, "
      "total %.2f" % stats)
bpy.ops.drivenshape.live_stop()
checks.check(not addon.live.is_live(), "live mode stopped")
checks.check(np.array_equal(util.evaluated_positions(cloth), rest),
             "stopping live mode puts the cloth's rest positions back")
print(f"live mode vs CLI: largest difference {worst:.3g} of the bounding-box diagonal")
checks.finish()
