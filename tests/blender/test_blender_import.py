# SPDX-License-Identifier: Apache-2.0
"""The import settings of docs/conventions.md, checked in a real (background) Blender 3.4.

`drivenshape export` writes the bundled sleeve's cloth (its test clip renumbered to start at
frame 1001, written here byte by byte) as OBJ + PC2, Z up (the default) and with --up-axis Y, one
sample per frame and every other frame (`1001-1047x2`, rate 2). Each pair is imported exactly as
docs/conventions.md says (the OBJ importer's axes; a Mesh Cache modifier with Frame Start
S / R and Frame Scale 1 / R), the scene steps through the cache's frames, and the cloth's
evaluated vertices in world space must be the source frame of that number (Blender's own
evaluation against the source PC2, decoded here with numpy; blender_test_util.TOLERANCE: 1e-6
of the bounding-box diagonal). Then it shows why the page is needed: with Blender's defaults the
OBJ lies on its side, a cache starting at 1001 shows its last frame, one starting at 1 shows
frame f + 1 at scene frame f, and an `x2` cache without Frame Scale 0.5 runs twice as fast.

No add-on here: plain Blender, the command line and numpy. Arguments (after `--`):
--cli the built drivenshape, --data tests/data/sleeve, --work a scratch folder.
"""

import argparse
import os
import subprocess
import sys
import time

import bpy
import numpy as np

sys.dont_write_bytecode = True  # Blender ignores PYTHONDONTWRITEBYTECODE: keep the tree clean
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import blender_test_util as util  # noqa: E402

# docs/conventions.md, "Blender": the OBJ importer's axes per exported up axis (Blender 3.4's
# wm.obj_import, File > Import > Wavefront (.obj) > Forward Axis / Up Axis).
OBJ_IMPORT_AXES = {"Z": {"forward_axis": "Y", "up_axis": "Z"},
                   "Y": {"forward_axis": "NEGATIVE_Z", "up_axis": "Y"}}


def mesh_cache_settings(start, rate):
    """docs/conventions.md, "Blender": the Mesh Cache modifier for a PC2 whose header says
    start S and rate R. Blender reads sample (Frame Scale * scene frame - Frame Start)."""
    return {"cache_format": "PC2", "time_mode": "FRAME", "play_mode": "SCENE",
            "frame_start": start / rate, "frame_scale": 1.0 / rate,
            "interpolation": "LINEAR", "deform_mode": "OVERWRITE", "factor": 1.0,
            "forward_axis": "POS_Y", "up_axis": "POS_Z"}


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser()
    parser.add_argument("--cli", required=True)
    parser.add_argument("--data", required=True)
    parser.add_argument("--work", required=True)
    return parser.parse_args(argv)


def read_pc2(path):
    """(start, rate, samples (S, V, 3) float32) decoded byte by byte (no drivenshape code)."""
    raw = open(path, "rb").read()
    if raw[:12] != b"POINTCACHE2\0":
        raise SystemExit(f"{path}: not a PC2 file")
    points = int(np.frombuffer(raw[16:20], "<i4")[0])
    start, rate = (float(v) for v in np.frombuffer(raw[20:28], "<f4"))
    samples = int(np.frombuffer(raw[28:32], "<i4")[0])
    xyz = np.frombuffer(raw, "<f4", offset=32).reshape(samples, points, 3)
    return start, rate, xyz.astype(np.float32)


def write_pc2(path, start, rate, xyz):
    header = (b"POINTCACHE2\0" + np.array([1, xyz.shape[1]], "<i4").tobytes() +
              np.array([start, rate], "<f4").tobytes() + np.array([len(xyz)], "<i4").tobytes())
    with open(path, "wb") as stream:
        stream.write(header + np.ascontiguousarray(xyz, "<f4").tobytes())


def export(cli, *arguments):
    command = [cli, "export", *arguments, "--quiet"]
    result = subprocess.run(command, capture_output=True, text=True)
    if result.returncode != 0:
        raise SystemExit(f"{' '.join(command)} exited {result.returncode}:\n{result.stderr}")


def import_obj(path, **axes):
    """The OBJ through Blender's importer (File > Import > Wavefront (.obj)); `axes` as in the
    dialog, none = Blender's defaults. Checks the vertices keep the file's order and values."""
    util.clear_scene()
    bpy.ops.object.select_all(action="DESELECT")
    bpy.ops.wm.obj_import(filepath=path, **axes)
    (obj,) = bpy.context.selected_objects
    local = np.empty((len(obj.data.vertices), 3), dtype=np.float32)
    obj.data.vertices.foreach_get("co", local.reshape(-1))
    in_file = np.array([line.split()[1:4] for line in open(path) if line.startswith("v ")],
                       dtype=np.float32)
    if not np.array_equal(local, in_file):
        raise SystemExit(f"Blender's import of {path} changed the vertex order or values")
    return obj


def add_mesh_cache(obj, path, **settings):
    modifier = obj.modifiers.new("cache", "MESH_CACHE")
    modifier.filepath = path
    for name, value in settings.items():
        setattr(modifier, name, value)
    return modifier


def world_positions(obj):
    """(V, 3) float64 world positions after modifiers, at the scene's current frame: Blender's
    own evaluation (depsgraph), then the object's matrix."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    evaluated = obj.evaluated_get(depsgraph)
    mesh = evaluated.data
    local = np.empty((len(mesh.vertices), 3), dtype=np.float32)
    mesh.vertices.foreach_get("co", local.reshape(-1))
    matrix = np.array(evaluated.matrix_world, dtype=np.float64)
    return local.astype(np.float64) @ matrix[:3, :3].T + matrix[:3, 3]


def worst_over(obj, frames, expected):
    """Over the scene frames: the largest relative error (util.relative_error: vertex distance
    over the expected frame's bounding-box diagonal), its frame, and the largest vertex distance
    in scene units."""
    worst, worst_frame, distance = -1.0, None, 0.0
    for frame in frames:
        bpy.context.scene.frame_set(frame)
        got = world_positions(obj)
        error = util.relative_error(got, expected[frame])
        if error > worst:
            worst, worst_frame = error, frame
        distance = max(distance, float(np.sqrt(((got - expected[frame]) ** 2).sum(1)).max()))
    return worst, worst_frame, distance


args = parse_args()
checks = util.Checks("test_blender_import")
started = time.perf_counter()
os.makedirs(args.work, exist_ok=True)
rest = os.path.join(args.data, "driven_rest.obj")

# The source: the sleeve's simulated cloth, frames 1-48, renumbered 1001-1048 (same samples).
first_start, first_rate, clip = read_pc2(os.path.join(args.data, "test.driven.pc2"))
source_pc2 = os.path.join(args.work, "source.1001.pc2")
write_pc2(source_pc2, 1001.0, 1.0, clip)
source = {1001 + s: clip[s].astype(np.float64) for s in range(len(clip))}  # world, Z up

exports = {}  # (axis, rate) -> (obj, pc2)
for axis in ("Z", "Y"):
    for rate, frames in ((1, "1001-1048"), (2, "1001-1047x2")):
        stem = os.path.join(args.work, f"sleeve_{axis}_x{rate}")
        export(args.cli, "--cache", source_pc2, "--frames", frames, "--pc2", stem + ".pc2",
               "--obj", stem + ".obj", "--mesh", rest, "--up-axis", axis)
        exports[axis, rate] = (stem + ".obj", stem + ".pc2")
print(f"exports made in {time.perf_counter() - started:.1f} s")

# 1. The documented settings: scene frame f shows source frame f, in world space, Z up.
for (axis, rate), (obj_path, pc2_path) in exports.items():
    start, header_rate, samples = read_pc2(pc2_path)
    checks.check(start == 1001.0 and header_rate == rate,
                 f"{os.path.basename(pc2_path)}: header start {start:g}, rate {header_rate:g}")
    obj = import_obj(obj_path, **OBJ_IMPORT_AXES[axis])
    modifier = add_mesh_cache(obj, pc2_path, **mesh_cache_settings(start, header_rate))
    cached = [int(start + s * header_rate) for s in range(len(samples))]
    worst, frame, _ = worst_over(obj, cached, source)
    checks.check(worst <= util.TOLERANCE,
                 f"{axis} up, rate {rate} (Frame Start {modifier.frame_start:g}, Frame Scale "
                 f"{modifier.frame_scale:g}): world positions at {len(cached)} scene frames "
                 f"{cached[0]}-{cached[-1]} are the source frames: largest difference "
                 f"{worst:.3g} of the bounding-box diagonal (frame {frame}; tolerance "
                 f"{util.TOLERANCE:g})")
    if axis == "Z":
        # Z up needs no rotation anywhere: the object's matrix is the identity, and the
        # evaluated vertices are the file's floats exactly.
        bpy.context.scene.frame_set(cached[1])
        exact = np.array_equal(world_positions(obj), source[cached[1]])
        checks.check(exact, f"Z up, rate {rate}: frame {cached[1]} is bit-identical")
    else:
        rotation = tuple(round(v, 6) for v in obj.rotation_euler)
        checks.check(rotation == (round(np.pi / 2, 6), 0.0, 0.0),
                     f"Y up: the importer turned the object +90 degrees about X to Z up "
                     f"(rotation {rotation})")

# 1b. A rate that is not a power of two, far from frame 0: Frame Start S / R and Frame Scale
#     1 / R are not exact in float32 there, and Blender's product can land just below a sample
#     (Linear then blends in a little of the previous one). Interpolation None rounds to the
#     nearest sample: exact, as docs/conventions.md says.
far_pc2 = os.path.join(args.work, "source.100001.pc2")
write_pc2(far_pc2, 100001.0, 1.0, clip)
far = {100001 + s: clip[s].astype(np.float64) for s in range(len(clip))}
far_x5 = os.path.join(args.work, "sleeve_Z_x5.pc2")
export(args.cli, "--cache", far_pc2, "--frames", "100001-100046x5", "--pc2", far_x5)
start, rate, samples = read_pc2(far_x5)
obj = import_obj(exports["Z", 1][0], **OBJ_IMPORT_AXES["Z"])
modifier = add_mesh_cache(obj, far_x5, **mesh_cache_settings(start, rate))
cached = [int(start + s * rate) for s in range(len(samples))]
linear, linear_frame, _ = worst_over(obj, cached, far)
modifier.interpolation = "NONE"
nearest, frame, _ = worst_over(obj, cached, far)
checks.check(rate == 5.0 and nearest <= util.TOLERANCE,
             f"rate 5 from frame 100001, Interpolation None: every sample exact (largest "
             f"difference {nearest:.3g}; with Linear {linear:.3g} at frame {linear_frame})")

# 2. Blender's defaults are off, which is why docs/conventions.md exists.
obj_path, pc2_path = exports["Z", 1]
obj = import_obj(obj_path)  # the importer's defaults: Forward -Z, Up Y
error, _, distance = worst_over(obj, [1001], source)
checks.check(error > 0.1,
             f"default OBJ import (Forward -Z, Up Y) of a Z-up file lies on its side: off by "
             f"{error:.3g} of the diagonal, {distance:.3f} scene units")

obj = import_obj(obj_path, **OBJ_IMPORT_AXES["Z"])
add_mesh_cache(obj, pc2_path, cache_format="PC2")  # Frame Start 0, Frame Scale 1
frozen, _, _ = worst_over(obj, [1001, 1020], {1001: source[1048], 1020: source[1048]})
off, _, distance = worst_over(obj, [1001, 1020], source)
checks.check(frozen <= util.TOLERANCE and off > 1e-3,
             f"default Mesh Cache (Frame Start 0) on a cache starting at 1001 ignores the "
             f"header's start: scene frames 1001 and 1020 show the last frame, 1048 (up to "
             f"{distance * 1000:.1f} mm off)")

from_one = os.path.join(args.work, "sleeve_from_1.pc2")
export(args.cli, "--cache", os.path.join(args.data, "test.driven.pc2"), "--frames", "1-48",
       "--pc2", from_one)
obj = import_obj(obj_path, **OBJ_IMPORT_AXES["Z"])
add_mesh_cache(obj, from_one, cache_format="PC2")
clip_frames = {f: clip[f - 1].astype(np.float64) for f in range(1, 49)}
late, _, _ = worst_over(obj, range(1, 48), {f: clip_frames[f + 1] for f in range(1, 48)})
off, _, distance = worst_over(obj, range(1, 48), clip_frames)
checks.check(late <= util.TOLERANCE and off > 1e-3,
             f"default Mesh Cache on a cache starting at 1 shows frame f + 1 at scene frame f "
             f"(up to {distance * 1000:.1f} mm off)")

obj_path, pc2_path = exports["Z", 2]
obj = import_obj(obj_path, **OBJ_IMPORT_AXES["Z"])
add_mesh_cache(obj, pc2_path, cache_format="PC2", frame_start=1001.0)  # Frame Scale left at 1
fast, _, _ = worst_over(obj, [1003, 1011], {1003: source[1005], 1011: source[1021]})
off, _, distance = worst_over(obj, [1003, 1011], source)
checks.check(fast <= util.TOLERANCE and off > 1e-3,
             f"an x2 cache with Frame Scale 1 runs twice as fast: scene frame 1003 shows 1005, "
             f"1011 shows 1021 (up to {distance * 1000:.1f} mm off)")

print(f"test_blender_import: {time.perf_counter() - started:.1f} s in all")
checks.finish()
