# SPDX-License-Identifier: Apache-2.0
"""Error paths of the add-on in a real (background) Blender: every failure is a report naming
the object, file or frame at fault, nothing is left half done, and Blender carries on.

- a cloth (or driver) with the wrong vertex count: Live Mode and Bake report both counts;
- a missing or corrupt database file: the report names the file; a `//` path (relative to the
  .blend) in a file never saved: the report says to save it;
- the driver changing topology while live (a Subdivision modifier added): live mode stops with
  the reason shown in the panel, the cloth gets its rest positions back;
- a non-finite driver position on frame 3 (a PC2 with a NaN): live mode stops naming frame 3,
  the bake reports it and writes no PC2;
- the drivenshape module not found: the report says where it was looked for and what to set.
"""

import os
import struct
import subprocess
import sys

import bpy
import numpy as np

sys.dont_write_bytecode = True  # Blender ignores PYTHONDONTWRITEBYTECODE: keep the tree clean
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import blender_test_util as util  # noqa: E402

args = util.parse_args()
checks = util.Checks("test_blender_errors")
addon = util.install_addon(args.work)
ds = util.drivenshape_module(addon)
database = os.path.join(args.work, "sleeve.dsdb")
driver, cloth = util.sleeve_scene(ds, args.data, database)
scene = bpy.context.scene
settings = scene.drivenshape
out = os.path.join(args.work, "errors_out")
os.makedirs(out, exist_ok=True)
rest = util.evaluated_positions(cloth)
ops = bpy.ops.drivenshape

# A cloth with the wrong vertex count.
bpy.ops.mesh.primitive_cube_add()
cube = bpy.context.active_object
cube.name = "wrong"
settings.cloth = cube
ok, message = util.expect_operator_error(ops.live_start, "'wrong'", "8 vertices", "2244")
checks.check(ok and not addon.live.is_live(), f"live mode on a cloth of 8 vertices: {message}")
settings.bake_pc2_path = os.path.join(out, "wrong.pc2")
ok, message = util.expect_operator_error(ops.bake, "'wrong'", "8 vertices", "2244")
checks.check(ok and not os.path.exists(settings.bake_pc2_path),
             f"bake onto a cloth of 8 vertices: {message}")

# A path relative to a .blend file that was never saved.
settings.cloth = cloth
settings.bake_pc2_path = "//drivenshape/cloth.pc2"
ok, message = util.expect_operator_error(ops.bake, "//drivenshape/cloth.pc2", "not saved")
checks.check(ok, f"a // path in an unsaved file: {message}")

# A driver with the wrong vertex count.
settings.cloth = cloth
settings.driver = cube
ok, message = util.expect_operator_error(ops.live_start, "driver", "'wrong'", "8 vertices",
                                         "2146")
checks.check(ok and not addon.live.is_live(), f"live mode on a driver of 8 vertices: {message}")
checks.check(np.array_equal(util.evaluated_positions(cloth), rest),
             "the cloth is left as it was")
settings.driver = driver

# Missing and corrupt databases.
missing = os.path.join(out, "missing.dsdb")
settings.database_path = missing
ok, message = util.expect_operator_error(ops.live_start, missing)
checks.check(ok, f"a missing database: {message}")
corrupt = os.path.join(out, "corrupt.dsdb")
with open(corrupt, "w", encoding="utf-8") as file:
    file.write("not a database\n")
settings.database_path = corrupt
ok, message = util.expect_operator_error(ops.live_start, corrupt)
checks.check(ok, f"a corrupt database: {message}")
settings.database_path = database

# The driver's topology changes while live mode runs (depsgraph update, no frame change).
scene.frame_set(5)
ops.live_start()
checks.check(addon.live.is_live(scene), "live mode starts again with the right objects")
subdivision = driver.modifiers.new("subdivide", "SUBSURF")
bpy.context.view_layer.update()
error = addon.live.LAST_ERROR or ""
checks.check(not addon.live.is_live() and "frame 5" in error and "'arm'" in error,
             f"a Subdivision modifier on the driver stops live mode: {error}")
checks.check(np.array_equal(util.evaluated_positions(cloth), rest),
             "the cloth got its rest positions back")
driver.modifiers.remove(subdivision)

# A NaN in the driver on frame 3.
positions, start, rate = ds.read_pc2(os.path.join(args.data, "test.driver.pc2"))
positions = positions.copy()
positions[3 - int(start), 7] = np.nan
broken = os.path.join(out, "nan.driver.pc2")
# Written byte by byte: the module's writers refuse a NaN (a cache holds finite positions only),
# but a broken cache from elsewhere is what this case is about.
with open(broken, "wb") as handle:
    handle.write(struct.pack("<12siiffi", b"POINTCACHE2\0", 1, positions.shape[1], float(start),
                             float(rate), positions.shape[0]))
    handle.write(np.ascontiguousarray(positions, dtype="<f4").tobytes())
driver.modifiers["reference"].filepath = broken
scene.frame_set(1)
ops.live_start()
scene.frame_set(2)
checks.check(addon.live.is_live(scene), "live mode runs on frames 1-2 of the broken cache")
scene.frame_set(3)
error = addon.live.LAST_ERROR or ""
checks.check(not addon.live.is_live() and "frame 3" in error,
             f"a NaN on frame 3 stops live mode: {error}")
settings.bake_pc2_path = os.path.join(out, "nan.pc2")
scene.frame_set(10)
ok, message = util.expect_operator_error(ops.bake, "frame 3")
checks.check(ok and not os.path.exists(settings.bake_pc2_path) and scene.frame_current == 10,
             f"the bake reports the frame and writes no PC2: {message}")

# No drivenshape module: another Blender, with the add-on installed but the module's folder
# pointing nowhere.
probe = r"""
import sys, bpy
bpy.ops.preferences.addon_enable(module="drivenshape_blender")
import drivenshape_blender as addon
ok, text = addon.module.status()
print("STATUS", ok, text)
bpy.ops.mesh.primitive_cube_add()
settings = bpy.context.scene.drivenshape
settings.driver = bpy.context.active_object
bpy.ops.mesh.primitive_ico_sphere_add()
settings.cloth = bpy.context.active_object
settings.database_path = "/nowhere/x.dsdb"
try:
    bpy.ops.drivenshape.live_start()
    print("REPORT none")
except RuntimeError as error:
    print("REPORT", error)
sys.exit(0 if not ok else 1)
"""
environment = dict(os.environ, DRIVENSHAPE_PYTHONPATH="/nonexistent/drivenshape-build/python")
run = subprocess.run([bpy.app.binary_path, "-b", "--factory-startup", "--python-exit-code", "1",
                      "--python-expr", probe], env=environment, capture_output=True, text=True,
                     timeout=120, check=False)
report = next((line for line in run.stdout.splitlines() if line.startswith("REPORT")), "")
checks.check(run.returncode == 0 and "cannot import the drivenshape Python module" in report
             and "/nonexistent/drivenshape-build/python" in report
             and "DRIVENSHAPE_PYTHONPATH" in report,
             f"without the module, Live Mode reports where it looked: {report[:300]}")
checks.finish()
