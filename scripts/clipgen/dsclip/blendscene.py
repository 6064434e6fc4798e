# SPDX-License-Identifier: Apache-2.0
"""The Blender side (bpy): objects, rig, modifiers, keys, and the frame-by-frame simulation.

Modifier stacks: body = Armature, Collision; garment = Armature, Cloth (the armature carries
the pinned vertices, the cloth solver moves the rest).
"""
import time

import bpy
import numpy as np
from mathutils import Matrix


def empty_scene(frames, fps):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.fps, scene.render.fps_base = fps, 1.0
    scene.frame_start, scene.frame_end = 1, frames
    scene.use_gravity = True
    scene.gravity = (0.0, 0.0, -9.81)
    return scene


def mesh_object(name, mesh):
    """A mesh object from shapes' mesh dict (vertex and polygon order kept, one UV map)."""
    me = bpy.data.meshes.new(name)
    me.from_pydata(mesh["verts"].tolist(), [], mesh["faces"])
    uv = me.uv_layers.new(name="UVMap")
    uv.data.foreach_set("uv", np.array([c for face in mesh["uvs"] for corner in face
                                        for c in corner], dtype=np.float32))
    if me.validate(verbose=False):
        raise RuntimeError(f"{name}: Blender had to repair the generated mesh")
    if len(me.vertices) != len(mesh["verts"]) or len(me.polygons) != len(mesh["faces"]):
        raise RuntimeError(f"{name}: Blender changed the vertex or polygon count")
    for p in me.polygons:
        p.use_smooth = True
    ob = bpy.data.objects.new(name, me)
    bpy.context.scene.collection.objects.link(ob)
    return ob


def rest_coordinates(ob):
    """The mesh's own (float32) rest positions, as Blender holds them."""
    co = np.empty(3 * len(ob.data.vertices), dtype=np.float32)
    ob.data.vertices.foreach_get("co", co)
    return co.reshape(-1, 3)


def armature(bones):
    """The rig: one armature object at the origin; bones (name, head, tail, parent, deforms)
    with roll 0, so a bone along +Y (the root) has the identity rest matrix."""
    data = bpy.data.armatures.new("rig")
    rig = bpy.data.objects.new("rig", data)
    bpy.context.scene.collection.objects.link(rig)
    bpy.context.view_layer.objects.active = rig
    bpy.ops.object.mode_set(mode="EDIT")
    for name, head, tail, parent, deforms in bones:
        eb = data.edit_bones.new(name)
        eb.head, eb.tail, eb.roll = head, tail, 0.0
        eb.use_deform = deforms
        if parent:
            eb.parent = data.edit_bones[parent]
            eb.use_connect = False
    bpy.ops.object.mode_set(mode="OBJECT")
    if not np.allclose(np.array(data.bones["root"].matrix_local), np.eye(4), atol=1e-6):
        raise RuntimeError("the root bone's rest matrix is not the identity")
    for pb in rig.pose.bones:
        pb.rotation_mode = "QUATERNION"
    return rig


def bind(ob, rig, names, W):
    """Vertex groups from the weight columns, then an Armature modifier on the rig."""
    for b, name in enumerate(names):
        group = ob.vertex_groups.new(name=name)
        for weight in np.unique(W[:, b][W[:, b] > 0]):
            ids = np.nonzero(W[:, b] == weight)[0].tolist()
            group.add(ids, float(weight), "REPLACE")
    mod = ob.modifiers.new("Armature", "ARMATURE")
    mod.object = rig
    mod.use_vertex_groups = True
    mod.use_deform_preserve_volume = False
    return mod


def make_collider(ob, settings):
    ob.modifiers.new("Collision", "COLLISION")
    for key, value in settings.items():
        setattr(ob.collision, key, value)


def make_cloth(ob, pinned, cloth, collision, frames):
    group = ob.vertex_groups.new(name="pin")
    group.add([int(i) for i in pinned], 1.0, "REPLACE")
    mod = ob.modifiers.new("Cloth", "CLOTH")
    for key, value in cloth.items():
        setattr(mod.settings, key, value)
    mod.settings.vertex_group_mass = "pin"
    for key, value in collision.items():
        setattr(mod.collision_settings, key, value)
    mod.point_cache.frame_start = 1
    mod.point_cache.frame_end = frames
    return mod


def animate(rig, character, motion, joint_matrix):
    """A key on every frame: the root's location and rotation, each jointed bone's rotation.
    A rotation R about the bone's head in armature axes is the pose quaternion of
    B^T R B, B the bone's rest orientation."""
    joints = character["joints"]
    rest = {b.name: np.array(b.matrix_local.to_3x3()) for b in rig.data.bones}
    root = rig.pose.bones["root"]
    F = len(motion["root_yaw"])
    for f in range(F):
        yaw = np.radians(motion["root_yaw"][f])
        root.location = tuple(motion["root_pos"][f])
        root.rotation_quaternion = (np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2))
        root.keyframe_insert("location", frame=f + 1)
        root.keyframe_insert("rotation_quaternion", frame=f + 1)
        for joint, (bone, dofs) in joints.items():
            R = joint_matrix(joint, {d: motion["angles"][f"{joint}.{d}"][f] for d in dofs})
            B = rest[bone]
            q = Matrix((B.T @ R @ B).tolist()).to_quaternion()
            pb = rig.pose.bones[bone]
            if f:
                q.make_compatible(pb.rotation_quaternion)
            pb.rotation_quaternion = q
            pb.keyframe_insert("rotation_quaternion", frame=f + 1)
    for curve in rig.animation_data.action.fcurves:
        for point in curve.keyframe_points:
            point.interpolation = "LINEAR"


def world_points(ob, depsgraph):
    """The evaluated (deformed, simulated) vertex positions in world space."""
    evaluated = ob.evaluated_get(depsgraph)
    me = evaluated.to_mesh()
    co = np.empty(3 * len(me.vertices))
    me.vertices.foreach_get("co", co)
    evaluated.to_mesh_clear()
    M = np.array(evaluated.matrix_world)
    return co.reshape(-1, 3) @ M[:3, :3].T + M[:3, 3]


def pose_matrices(rig):
    """World-from-rest matrix of each bone in the current pose."""
    W = np.array(rig.matrix_world)
    return {pb.name: W @ np.array(pb.matrix) @ np.linalg.inv(np.array(pb.bone.matrix_local))
            for pb in rig.pose.bones}


def run(scene, body, garment, rig, frames, report_every=20):
    """Frames 1..F in order (the cloth solves each from the one before). -> body (F, n, 3),
    garment (F, m, 3) float32, wall and CPU (all threads) seconds per frame_set, bone
    matrices {bone: (F, 4, 4)}."""
    body_at = np.zeros((frames, len(body.data.vertices), 3), dtype=np.float32)
    cloth_at = np.zeros((frames, len(garment.data.vertices), 3), dtype=np.float32)
    seconds = np.zeros(frames)
    cpu = np.zeros(frames)
    mats = {pb.name: np.zeros((frames, 4, 4)) for pb in rig.pose.bones}
    began = time.perf_counter()
    for f in range(frames):
        t0, c0 = time.perf_counter(), time.process_time()
        scene.frame_set(f + 1)
        seconds[f] = time.perf_counter() - t0
        cpu[f] = time.process_time() - c0
        depsgraph = bpy.context.evaluated_depsgraph_get()
        body_at[f] = world_points(body, depsgraph)
        cloth_at[f] = world_points(garment, depsgraph)
        for name, M in pose_matrices(rig).items():
            mats[name][f] = M
        if report_every and (f % report_every == 0 or f == frames - 1):
            print(f"  frame {f + 1}/{frames}: {seconds[f]:.2f} s, "
                  f"{time.perf_counter() - began:.0f} s so far", flush=True)
    return body_at, cloth_at, seconds, cpu, mats
