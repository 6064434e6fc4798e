# SPDX-License-Identifier: Apache-2.0
"""The Bake operator in a real (background) Blender against the command line's bake.

Bakes the test clip (frames 1-48) through bpy.ops.drivenshape.bake with PC2 and EXR output,
reloads both through the module's readers and compares every frame with `drivenshape bake`'s
EXRs (blender_test_util.TOLERANCE). Then checks the Mesh Cache modifier the bake set up: at
scene frame f the cloth shows the CLI's frame f (Blender's defaults would show f + 1), and the
Add Mesh Cache operator does the same for a PC2 that starts at frame 101.
"""

import os
import sys

import bpy
import numpy as np

sys.dont_write_bytecode = True  # Blender ignores PYTHONDONTWRITEBYTECODE: keep the tree clean
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import blender_test_util as util  # noqa: E402

args = util.parse_args()
checks = util.Checks("test_blender_bake")
addon = util.install_addon(args.work)
ds = util.drivenshape_module(addon)
driver, cloth = util.sleeve_scene(ds, args.data, os.path.join(args.work, "sleeve.dsdb"))
scene = bpy.context.scene
settings = scene.drivenshape
cli = os.path.join(args.work, "cli", "default")
out = os.path.join(args.work, "bake_out")
frames = range(1, 49)
expected = {frame: util.cli_frame(ds, cli, frame) for frame in frames}


def worst_error(get):
    worst, worst_frame = 0.0, None
    for frame in frames:
        error = util.relative_error(get(frame), expected[frame])
        if error >= worst:
            worst, worst_frame = error, frame
    return worst, worst_frame


settings.bake_pc2_path = os.path.join(out, "sleeve.pc2")
settings.bake_write_exr = True
settings.bake_exr_pattern = os.path.join(out, "exr", "sleeve.####.exr")
settings.bake_add_mesh_cache = True
# A modifier already on the cloth (a deform that changes nothing): the bake's goes before it.
cloth.modifiers.new("existing", "DISPLACE").strength = 0.0
scene.frame_set(17)
result = bpy.ops.drivenshape.bake()
checks.check(result == {"FINISHED"}, f"the bake operator finished ({result})")
checks.check(scene.frame_current == 17, "the scene is back on the frame it was on")

positions, start, rate = ds.read_pc2(settings.bake_pc2_path)
checks.check(positions.shape == (48, 2244, 3) and start == 1.0 and rate == 1.0,
             f"the PC2 holds 48 frames of 2244 vertices from frame 1, one per frame "
             f"(got {positions.shape}, start {start}, rate {rate})")
worst, frame = worst_error(lambda f: positions[f - 1])
checks.check(worst <= util.TOLERANCE,
             f"PC2 vs CLI: largest difference {worst:.3g} of the bounding-box diagonal "
             f"(frame {frame}; tolerance {util.TOLERANCE:g})")
overall = worst

exr_header = {}


def exr_frame(frame):
    path = os.path.join(out, "exr", f"sleeve.{frame:04d}.exr")
    cli_info = ds.read_point_cache_exr_info(os.path.join(cli, f"sleeve.{frame:04d}.exr"))
    got, info = ds.read_point_cache_exr(path, expected_topology=cli_info["topology_hash"])
    exr_header[frame] = info
    return got


worst, frame = worst_error(exr_frame)
checks.check(worst <= util.TOLERANCE,
             f"EXR vs CLI (with the CLI's topology hash): largest difference {worst:.3g} "
             f"(frame {frame})")
overall = max(overall, worst)
checks.check(all(exr_header[f]["frame"] == f for f in frames),
             "every EXR header names its frame")

# The Mesh Cache modifier the bake added: first in the stack, frame f shows frame f.
modifier = cloth.modifiers.get("DrivenShape Bake")
checks.check(modifier is not None and cloth.modifiers[0] == modifier
             and len(cloth.modifiers) == 2
             and modifier.cache_format == "PC2" and modifier.frame_start == 1.0
             and modifier.frame_scale == 1.0,
             "the bake added a first Mesh Cache modifier (PC2, frame start 1, scale 1)")
worst, frame = worst_error(lambda f: (scene.frame_set(f), util.evaluated_positions(cloth))[1])
checks.check(worst <= util.TOLERANCE,
             f"the cloth with the bake's Mesh Cache shows at scene frame f the CLI's frame f: "
             f"largest difference {worst:.3g} (frame {frame})")
overall = max(overall, worst)
modifier.frame_start = 0.0  # Blender's default: one frame late
scene.frame_set(10)
late = util.relative_error(util.evaluated_positions(cloth), expected[11])
checks.check(late <= util.TOLERANCE,
             "with Blender's default frame start (0) scene frame 10 shows frame 11 (why the "
             "add-on sets it)")

# Add Mesh Cache on a PC2 that starts at frame 101: scene frame 101 + i shows sample i.
shifted = os.path.join(out, "shifted.pc2")
ds.write_pc2(shifted, positions, start_frame=101.0, sample_rate=1.0)
result = bpy.ops.drivenshape.add_mesh_cache(filepath=shifted)
checks.check(result == {"FINISHED"} and modifier.frame_start == 101.0,
             "Add Mesh Cache on a PC2 from frame 101 sets frame start 101")
worst, frame = worst_error(lambda f: (scene.frame_set(100 + f),
                                      util.evaluated_positions(cloth))[1])
checks.check(worst <= util.TOLERANCE,
             f"scene frame 100 + f shows the CLI's frame f: largest difference {worst:.3g}")

# Live mode hides the bake modifier (else it would hide the live result) and shows it again.
scene.frame_set(3)
bpy.ops.drivenshape.live_start()
checks.check(not modifier.show_viewport, "live mode turns the bake's modifier off")
bpy.ops.drivenshape.live_stop()
checks.check(modifier.show_viewport, "stopping live mode turns it back on")

print(f"bake vs CLI: largest difference {overall:.3g} of the bounding-box diagonal")
checks.finish()
