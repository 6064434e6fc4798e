# SPDX-License-Identifier: Apache-2.0
"""Shared by the add-on tests, which run inside Blender:

    blender -b --factory-startup --python-exit-code 1 --python test_blender_X.py -- \
        --data tests/data/sleeve --work WORK

WORK holds what blender_fixture.sh made with the command line (the database, the reference
bakes, the add-on's zip). Every test installs the zip into the user-scripts folder that
BLENDER_USER_SCRIPTS names (CTest gives each test its own), enables it, and compares what the
add-on produces in Blender with the command line's output.
"""

import argparse
import os
import shutil
import sys
import time

import bpy
import numpy as np

# The one tolerance of every comparison with the command line: the largest vertex distance,
# divided by the bounding-box diagonal of the command line's cloth for that frame.
TOLERANCE = 1e-6

ADDON = "drivenshape_blender"


def parse_args(names=("--data", "--work")):
    """The script's arguments after `--`: each of `names`, required."""
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser()
    for name in names:
        parser.add_argument(name, required=True)
    return parser.parse_args(argv)


class Checks:
    """Counts failed checks; finish() exits non-zero if any failed."""

    def __init__(self, name):
        self.name = name
        self.failures = []
        self.start = time.perf_counter()

    def check(self, condition, message):
        if condition:
            print(f"ok: {message}")
        else:
            print(f"FAILED: {message}")
            self.failures.append(message)
        return condition

    def finish(self):
        seconds = time.perf_counter() - self.start
        if self.failures:
            print(f"{self.name}: {len(self.failures)} check(s) failed in {seconds:.1f} s:")
            for message in self.failures:
                print(f"  {message}")
            sys.stdout.flush()
            sys.exit(1)
        print(f"{self.name}: every check passed in {seconds:.1f} s")
        sys.stdout.flush()
        sys.exit(0)


def install_addon(work):
    """Installs the fixture's zip as a user would (Preferences > Add-ons > Install) and enables
    it; returns the add-on package."""
    scripts = os.environ.get("BLENDER_USER_SCRIPTS")
    if not scripts:
        raise SystemExit("BLENDER_USER_SCRIPTS must name a throwaway folder for the add-on")
    zip_path = os.path.join(work, "drivenshape_blender.zip")
    bpy.ops.preferences.addon_install(filepath=zip_path, overwrite=True)
    bpy.ops.preferences.addon_enable(module=ADDON)
    if ADDON not in bpy.context.preferences.addons:
        raise SystemExit(f"the add-on {ADDON} did not enable from {zip_path}")
    import drivenshape_blender  # noqa: PLC0415 (installed just above)

    if not os.path.realpath(drivenshape_blender.__file__).startswith(os.path.realpath(scripts)):
        raise SystemExit(f"the add-on loaded from {drivenshape_blender.__file__}, not from the "
                         f"installed zip in {scripts}")
    return drivenshape_blender


def drivenshape_module(addon):
    """The drivenshape module, found the way the add-on finds it (DRIVENSHAPE_PYTHONPATH)."""
    return addon.module.get()


def import_module_from_path():
    """The drivenshape module from the first folder of DRIVENSHAPE_PYTHONPATH, without the add-on
    (the window runner's tests run it as a separate Blender does)."""
    folders = [f for f in os.environ.get("DRIVENSHAPE_PYTHONPATH", "").split(os.pathsep) if f]
    if not folders:
        raise SystemExit("DRIVENSHAPE_PYTHONPATH must name the folder that holds drivenshape/")
    sys.path.insert(0, folders[0])
    import drivenshape  # noqa: E402

    return drivenshape


def fresh_folder(path):
    """`path`, absolute, emptied (made when missing)."""
    path = os.path.abspath(path)
    shutil.rmtree(path, ignore_errors=True)
    os.makedirs(path)
    return path


def import_obj(ds, path, name):
    """Imports an OBJ with Blender's importer, Z up and Y forward as the files are written, and
    checks that the vertices keep the file's order and values (read by the module's reader)."""
    bpy.ops.object.select_all(action="DESELECT")
    bpy.ops.wm.obj_import(filepath=path, forward_axis="Y", up_axis="Z")
    objects = bpy.context.selected_objects
    if len(objects) != 1:
        raise SystemExit(f"importing {path} made {len(objects)} objects, not one")
    obj = objects[0]
    obj.name = name
    positions = np.empty((len(obj.data.vertices), 3), dtype=np.float32)
    obj.data.vertices.foreach_get("co", positions.reshape(-1))
    expected = ds.read_obj(path).positions
    if positions.shape != expected.shape or not np.array_equal(positions, expected):
        raise SystemExit(f"Blender's import of {path} changed the vertex order or the axes")
    if any(abs(obj.matrix_world[i][j] - (i == j)) > 0 for i in range(4) for j in range(4)):
        raise SystemExit(f"Blender's import of {path} gave the object a transform")
    return obj


def drive_with_pc2(obj, path, start_frame):
    """A Mesh Cache modifier that shows the PC2's frame f at scene frame f. Blender reads PC2
    sample (frame_scale * scene frame - frame_start), from 0, whatever start frame the file
    says; the PC2s here have one sample per frame."""
    modifier = obj.modifiers.new("reference", "MESH_CACHE")
    modifier.cache_format = "PC2"
    modifier.filepath = path
    modifier.frame_start = start_frame
    modifier.frame_scale = 1.0
    return modifier


def sleeve_scene(ds, data, database):
    """The bundled sleeve in a fresh scene: driver and cloth from the rest OBJs, the driver
    driven by the test clip's PC2 (checked against the file on two frames), the scene's
    DrivenShape settings pointing at them and at `database`. Returns (driver, cloth)."""
    clear_scene()
    driver = import_obj(ds, os.path.join(data, "driver_rest.obj"), "arm")
    cloth = import_obj(ds, os.path.join(data, "driven_rest.obj"), "sleeve")
    pc2 = os.path.join(data, "test.driver.pc2")
    positions, start, rate = ds.read_pc2(pc2)
    if rate != 1.0:
        raise SystemExit(f"{pc2}: expected one sample per frame, got a rate of {rate}")
    drive_with_pc2(driver, pc2, start)
    scene = bpy.context.scene
    scene.frame_start = int(start)
    scene.frame_end = int(start) + len(positions) - 1
    for frame in (scene.frame_start, scene.frame_end):
        scene.frame_set(frame)
        got = evaluated_positions(driver)
        if not np.array_equal(got, positions[frame - int(start)]):
            raise SystemExit(f"the driver's Mesh Cache does not show {pc2}'s frame {frame} at "
                             f"scene frame {frame}")
    settings = scene.drivenshape
    settings.driver = driver
    settings.cloth = cloth
    settings.database_path = database
    return driver, cloth


def clear_scene():
    """Removes every object and mesh (the factory scene's cube, camera and light too). Loading a
    new file instead would also reset the preferences, and with them the enabled add-on."""
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    for mesh in list(bpy.data.meshes):
        bpy.data.meshes.remove(mesh)


def evaluated_positions(obj):
    """(V, 3) float32 positions of the object after modifiers, at the scene's current frame."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    mesh = obj.evaluated_get(depsgraph).data
    out = np.empty((len(mesh.vertices), 3), dtype=np.float32)
    mesh.vertices.foreach_get("co", out.reshape(-1))
    return out


def cli_frame(ds, folder, frame):
    """The command line's bake of one frame: (V, 3) float32 from its point-cache EXR."""
    positions, info = ds.read_point_cache_exr(os.path.join(folder, f"sleeve.{frame:04d}.exr"))
    if info["frame"] != frame:
        raise SystemExit(f"{folder}: the EXR of frame {frame} says frame {info['frame']}")
    return positions


def relative_error(got, expected):
    """Largest vertex distance over the bounding-box diagonal of `expected`."""
    if got.shape != expected.shape:
        return float("inf")
    diagonal = float(np.linalg.norm(expected.max(axis=0) - expected.min(axis=0)))
    return float(np.sqrt(((got.astype(np.float64) - expected) ** 2).sum(axis=1)).max()) / diagonal


def expect_operator_error(operator, *fragments, **kwargs):
    """Runs a bpy.ops operator that must report an error (Blender raises RuntimeError from a
    script); returns (ok, message) with ok when every fragment is in the message."""
    try:
        operator(**kwargs)
    except RuntimeError as error:
        message = str(error)
        return all(fragment in message for fragment in fragments), message
    return False, "no error was reported"
