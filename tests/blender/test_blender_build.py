# SPDX-License-Identifier: Apache-2.0
"""The Build Database operator in a real (background) Blender against `drivenshape db build`.

The driver and cloth objects play the training clip through Mesh Cache modifiers; the operator
samples their evaluated meshes over frames 1-61 and builds a 30-shape database. It must pick the
same frames and hold the same shapes and topologies (the same content hash) as the command
line's database built from the same PC2 files and rest OBJs. The same again with the PC2 files
as the reference, and the new database must become the scene's database.
"""

import os
import sys

import bpy
import numpy as np

sys.dont_write_bytecode = True  # Blender ignores PYTHONDONTWRITEBYTECODE: keep the tree clean
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import blender_test_util as util  # noqa: E402

args = util.parse_args()
checks = util.Checks("test_blender_build")
addon = util.install_addon(args.work)
ds = util.drivenshape_module(addon)
cli_database = ds.load_database(os.path.join(args.work, "sleeve.dsdb"))
out = os.path.join(args.work, "build_out")

util.clear_scene()
driver = util.import_obj(ds, os.path.join(args.data, "driver_rest.obj"), "arm")
cloth = util.import_obj(ds, os.path.join(args.data, "driven_rest.obj"), "sleeve")
train_driver = os.path.join(args.data, "train.driver.pc2")
train_cloth = os.path.join(args.data, "train.driven.pc2")
_positions, start, _rate = ds.read_pc2(train_driver)
util.drive_with_pc2(driver, train_driver, start)
util.drive_with_pc2(cloth, train_cloth, start)
scene = bpy.context.scene
settings = scene.drivenshape
settings.driver = driver
settings.cloth = cloth
settings.build_frame_start = int(start)
settings.build_frame_end = int(start) + len(_positions) - 1
settings.build_count = cli_database.shape_count
settings.build_model = False  # the fixture's database: db build --model none


def same_database(path, label):
    built = ds.load_database(path)
    checks.check(built.frames == cli_database.frames,
                 f"{label}: the same picks as the CLI ({built.frames[:6]}...)")
    checks.check(np.array_equal(built.driver_shapes, cli_database.driver_shapes)
                 and np.array_equal(built.driven_shapes, cli_database.driven_shapes),
                 f"{label}: the same driver and driven shapes, bit for bit")
    checks.check(built.driver_mesh.topology_hash == cli_database.driver_mesh.topology_hash
                 and built.driven_mesh.topology_hash == cli_database.driven_mesh.topology_hash,
                 f"{label}: the same topologies as the rest OBJs")
    checks.check(built.content_hash == cli_database.content_hash,
                 f"{label}: the same content hash as the CLI's database")


settings.build_source = "ANIMATION"
settings.build_output = os.path.join(out, "animation.dsdb")
scene.frame_set(7)
result = bpy.ops.drivenshape.build_database()
checks.check(result == {"FINISHED"}, f"building from the objects' animation finished ({result})")
checks.check(scene.frame_current == 7, "the scene is back on its frame")
checks.check(settings.database_path == settings.build_output,
             "the new database becomes the scene's database")
same_database(settings.build_output, "from the objects' animation")

settings.build_source = "PC2"
settings.build_driver_pc2 = train_driver
settings.build_cloth_pc2 = train_cloth
settings.build_output = os.path.join(out, "pc2.dsdb")
result = bpy.ops.drivenshape.build_database()
checks.check(result == {"FINISHED"}, f"building from the PC2 files finished ({result})")
same_database(settings.build_output, "from the PC2 files")
checks.finish()
