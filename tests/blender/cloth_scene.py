# SPDX-License-Identifier: Apache-2.0
"""The small cloth shot of the simulation tests (test_simulate_window, test_simulate_command),
built in the running Blender: a sleeve of AROUND x RINGS vertices on an arm that swings up SWING
degrees, the sleeve's shoulder ring pinned, both moved and turned so that object and world space
differ, Blender's cloth defaults at quality 5, a Subdivision modifier after the cloth, FRAMES
frames. Also what both tests do with it: simulate it here (the truth), read the cloth in world
space, and write frames as point-cache EXRs with the module.
"""

import math
import os

import bpy
import numpy as np

import blender_test_util as util

FRAMES = 40
AROUND, RINGS, SWING = 24, 20, 30.0


def build_scene():
    """A sleeve on a swinging arm: a tube (AROUND x RINGS vertices, radius 12 cm, 60 cm long)
    around a closed cylinder (radius 9 cm, a Collision modifier), both moved and turned by the
    same transform; the tube's first ring pinned, the arm swinging up about that end from frame
    8 to the last. Returns (scene, cloth "garment", body "body", the pinned vertices)."""
    util.clear_scene()
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, FRAMES
    verts = [(0.02 + 0.6 * j / (RINGS - 1), 0.12 * math.cos(2 * math.pi * i / AROUND),
              0.12 * math.sin(2 * math.pi * i / AROUND))
             for j in range(RINGS) for i in range(AROUND)]
    faces = [(j * AROUND + i, j * AROUND + (i + 1) % AROUND,
              (j + 1) * AROUND + (i + 1) % AROUND, (j + 1) * AROUND + i)
             for j in range(RINGS - 1) for i in range(AROUND)]
    mesh = bpy.data.meshes.new("garment")
    mesh.from_pydata(verts, [], faces)
    cloth = bpy.data.objects.new("garment", mesh)
    scene.collection.objects.link(cloth)
    cloth.location = (0.1, -0.05, 1.0)
    cloth.rotation_euler = (0.0, 0.0, math.radians(30.0))
    pinned = list(range(AROUND))
    cloth.vertex_groups.new(name="pin").add(pinned, 1.0, "REPLACE")
    modifier = cloth.modifiers.new("Cloth", "CLOTH")
    modifier.settings.quality = 5
    modifier.settings.vertex_group_mass = "pin"
    modifier.point_cache.frame_start, modifier.point_cache.frame_end = 1, FRAMES
    cloth.modifiers.new("Subdivision", "SUBSURF").levels = 1
    bpy.ops.mesh.primitive_cylinder_add(vertices=32, radius=0.09, depth=0.8,
                                        location=(0.4, 0.0, 0.0),
                                        rotation=(0.0, math.radians(90.0), 0.0))
    body = bpy.context.object
    body.name = "body"
    bpy.ops.object.transform_apply(location=True, rotation=True)
    body.location = cloth.location
    body.rotation_euler = cloth.rotation_euler
    body.modifiers.new("Collision", "COLLISION")
    body.keyframe_insert("rotation_euler", frame=8)
    body.rotation_euler = (0.0, math.radians(-SWING), math.radians(30.0))
    body.keyframe_insert("rotation_euler", frame=FRAMES)
    scene.frame_set(1)
    return scene, cloth, body, pinned


def world_cloth(cloth):
    """The cloth's vertices (V, 3) float64 in world space, read with Subdivision off."""
    local = util.evaluated_positions(cloth).astype(np.float64)
    matrix = np.array(cloth.evaluated_get(bpy.context.evaluated_depsgraph_get()).matrix_world)
    return local @ matrix[:3, :3].T + matrix[:3, 3]


def simulate_here(scene, cloth, first, last):
    """Frames first..last of the scene's own cloth, simulated from its cache start `first`
    (the cloth's own input there: the sleeve at rest), world space (F, V, 3)."""
    modifier = cloth.modifiers["Cloth"]
    subdivision = cloth.modifiers["Subdivision"]
    subdivision.show_viewport = False
    modifier.point_cache.frame_start, modifier.point_cache.frame_end = first, last
    out = []
    for frame in range(first, last + 1):
        scene.frame_set(frame)
        out.append(world_cloth(cloth))
    subdivision.show_viewport = True
    modifier.point_cache.frame_start, modifier.point_cache.frame_end = 1, FRAMES
    return np.array(out)


def topology_hash(ds, cloth):
    """The module's topology hash of the cloth's mesh (what a bake of it records)."""
    mesh = cloth.data
    sizes = np.array([len(p.vertices) for p in mesh.polygons], dtype=np.int32)
    starts = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int32)
    indices = np.array([v for p in mesh.polygons for v in p.vertices], dtype=np.int32)
    rest = np.array([v.co for v in mesh.vertices], dtype=np.float32)
    return ds.Mesh.from_polygons(rest, starts, indices).topology_hash


def write_exrs(ds, folder, positions, first, hash_value, name="x"):
    """positions (F, V, 3) as the point-cache EXRs folder/name.####.exr from frame `first`."""
    os.makedirs(folder, exist_ok=True)
    for i, frame_positions in enumerate(positions):
        ds.write_point_cache_exr(os.path.join(folder, f"{name}.{first + i:04d}.exr"),
                                 np.ascontiguousarray(frame_positions, dtype=np.float32),
                                 frame=first + i, topology_hash=hash_value, sync=False)


def mean_distance(a, b):
    """Mean vertex distance per frame (F,)."""
    return np.linalg.norm(a - b, axis=2).mean(axis=1)
