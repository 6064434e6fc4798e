# SPDX-License-Identifier: Apache-2.0
"""One window of real cloth simulation, warm-started and guided by a bake (issue 44): the work
behind `simulate_window.py` (what `drivenshape simulate` runs on the farm, one Blender per
window) and the "Simulate Flagged Frames" operator, without the UI.

The garment's own Cloth modifier simulates frames first..last of its .blend, with the TD's
settings and collision bodies. What the window changes, in memory only:

- **Start state.** Blender's cloth takes its positions from the mesh that reaches the Cloth
  modifier at the point cache's start frame (cloth.c `cloth_from_object`). A Mesh Cache modifier
  put just before the Cloth modifier reads the bake's frames (a PC2 written to a temporary
  folder), and the cache runs from `first` to `last`, so the cloth starts from the bake's cloth
  at `first`. Vertices the TD's pin group pins fully (Blender's goal, the weight to the 4th
  power, at least 0.999) keep the input they had (the armature's): the PC2 holds, for them, the
  positions that reached the Cloth modifier before (read frame by frame with the cloth off), so
  the pins hold the garment as they did in the full simulation. (A vertex group on the Mesh
  Cache would do it without that pass, but Blender 3.4 then crashes when it quits.)
- **Rest shape.** The same function takes the spring rest lengths from that first input unless a
  rest shape key is set; the bake's cloth is stretched and folded, so without a rest key the
  window adds one ("drivenshape_rest", the mesh's own positions: the shape a simulation started
  at the rest pose has) and uses it. A rest key the TD set is kept.
- **Velocities.** Blender 3.4's Python API gives no access to the solver's state: the cloth
  starts with zero velocities (`cloth_from_object` sets `v = 0`), and only a hand-written disk
  cache frame (.bphys) could give others. The window does not write one, so it starts at rest
  and the warm-up frames before the handed-back ones absorb the difference.
- **Goal.** With a goal strength S > 0 every vertex's pin weight in the group
  "drivenshape_goal" is S^(1/4), which Blender raises to the 4th power: its goal is S, a spring
  of stiffness S x the cloth's Pin Stiffness / average spring length toward the cloth's input,
  the bake (SIM_mass_spring.cpp `cloth_calc_force`). S = 1 pins every vertex to the bake
  (goal >= 0.999 is a hard pin). The TD's own pin weights are kept where they are higher. S = 0
  leaves the TD's pin group as it is: a free simulation from the warm start.

Outputs: the evaluated cloth at each frame (modifiers after the Cloth modifier are switched off
while the window runs, so the vertices are the cloth's), in the bake's space, one point-cache
EXR per frame through the module's writer (the bake's writer: a temporary file renamed into
place), with the bake's topology hash and a provenance record, attribute `dsSimulation` (one
line of JSON: blend file, object, window, goal strength, space, the bake's pattern, Blender's
version, what the start state was).

Space: a bake's EXRs hold the evaluator's output: world space for the command line and the
add-on's Space = World, the cloth object's space for the add-on's Space = Object (the same when
the cloth has no transform). `space` says which; it converts with the object's matrix at each
frame.
"""

import json
import os
import shutil
import tempfile

import bpy
import numpy as np

from . import engine, live, module
from .engine import UserError

GOAL_GROUP = "drivenshape_goal"
REST_KEY = "drivenshape_rest"
INPUT_MODIFIER = "DrivenShape Simulation Input"
PROVENANCE_ATTRIBUTE = "dsSimulation"
# Blender pins a cloth vertex whose goal (its pin weight to the 4th power) reaches this
# (BKE_cloth.h SOFTGOALSNAP); below it the goal is a spring.
SOFT_GOAL_SNAP = 0.999
SPACES = ("WORLD", "OBJECT")


def cloth_modifier(obj):
    """The object's Cloth modifier; UserError naming the object when it has none."""
    for modifier in obj.modifiers:
        if modifier.type == "CLOTH":
            return modifier
    raise UserError(f"The object '{obj.name}' has no Cloth modifier: simulating a window needs "
                    "the garment with its cloth settings")


def find_garment(scene, name):
    """The garment object called `name` in the scene; UserError naming it when it is missing,
    is not a mesh or has no Cloth modifier."""
    obj = scene.objects.get(name)
    if obj is None:
        raise UserError(f"No object '{name}' in the scene '{scene.name}' of "
                        f"{bpy.data.filepath or 'the unsaved file'}")
    if obj.type != "MESH":
        raise UserError(f"The object '{name}' is a {obj.type.lower()}, not a mesh")
    cloth_modifier(obj)
    return obj


def check_cache(cache, obj, own_file):
    """Refuses a point cache that the window would destroy: a bake, a disk cache (whose frames
    beside the .blend are deleted when it is freed) or an external cache, unless `own_file`
    says the open file is a throwaway copy (the runner saves one into a temporary folder
    first, where a disk cache lives and is freed)."""
    if cache.use_external:
        raise UserError(f"The cloth of '{obj.name}' reads an external cache "
                        f"({cache.filepath}): turn External off to simulate it")
    if own_file:
        return
    if cache.is_baked:
        raise UserError(f"The cloth of '{obj.name}' is baked: free its bake (or run the "
                        "windows with `drivenshape simulate`, which works on a copy)")
    if cache.use_disk_cache:
        raise UserError(f"The cloth of '{obj.name}' caches to disk: simulating would replace "
                        "those frames. Turn Disk Cache off, or run the windows with "
                        "`drivenshape simulate`, which works on a copy")


def read_bake(bake_pattern, frames, obj, topology_hash):
    """The bake's frames (F, V, 3) float32 in their own space, read with the module; UserError
    naming the file and frame when one is missing, unreadable, of another frame, vertex count
    or topology. Returns (positions, the bake's topology hash, 0 when its headers have none)."""
    ds = module.get()
    vertices = len(obj.data.vertices)
    out = np.empty((len(frames), vertices, 3), dtype=np.float32)
    bake_topology = 0
    for i, frame in enumerate(frames):
        path = engine.expand_pattern(bake_pattern, frame)
        if not os.path.isfile(path):
            raise UserError(f"Bake frame {frame}: {path} does not exist")
        try:
            positions, info = ds.read_point_cache_exr(path)
        except Exception as error:
            raise UserError(f"Bake frame {frame}: cannot read {path}: "
                            f"{engine.describe_error(error)}") from None
        if info["frame"] != frame:
            raise UserError(f"Bake frame {frame}: {path} holds frame {info['frame']}")
        if len(positions) != vertices:
            raise UserError(f"Bake frame {frame}: {path} has {len(positions)} vertices; the "
                            f"object '{obj.name}' has {vertices}")
        header_topology = info.get("topology_hash", 0)
        if header_topology and header_topology != topology_hash:
            raise UserError(f"Bake frame {frame}: {path} is of another mesh (topology "
                            f"{header_topology:016x}) than the object '{obj.name}' "
                            f"({topology_hash:016x}): same vertex count, other faces or order")
        bake_topology = bake_topology or header_topology
        out[i] = positions
    return out, bake_topology


class _Restore:
    """What the window changed on the object and its cloth, put back by undo(): modifiers added,
    switched off or moved, vertex groups and shape keys added, cloth settings and the cache's
    frame range."""

    def __init__(self):
        self.steps = []

    def add(self, step):
        self.steps.append(step)

    def undo(self):
        while self.steps:
            step = self.steps.pop()
            try:
                step()
            except (ReferenceError, RuntimeError, KeyError):
                pass  # what it restores is gone already (the object was deleted meanwhile)


def _set_group(obj, name, weights, restore):
    """A vertex group `name` holding weights (V,) (vertices of weight 0 left out), replacing one
    of that name; removed again on restore."""
    group = obj.vertex_groups.get(name)
    if group is not None:
        obj.vertex_groups.remove(group)
    group = obj.vertex_groups.new(name=name)
    for weight in np.unique(weights[weights > 0]):
        group.add(np.nonzero(weights == weight)[0].tolist(), float(weight), "REPLACE")
    restore.add(lambda: obj.vertex_groups.remove(obj.vertex_groups[name]))
    return group


def _group_weights(obj, name):
    """(V,) float32 weights of the vertex group `name` (0 where a vertex is not in it)."""
    weights = np.zeros(len(obj.data.vertices), dtype=np.float32)
    group = obj.vertex_groups.get(name)
    if group is None:
        return weights
    index = group.index
    for vertex in obj.data.vertices:
        for element in vertex.groups:
            if element.group == index:
                weights[vertex.index] = element.weight
    return weights


def _setattr(restore, owner, attribute, value):
    before = getattr(owner, attribute)
    setattr(owner, attribute, value)
    restore.add(lambda: setattr(owner, attribute, before))


def _set_frame_range(restore, cache, first, last):
    """cache.frame_start/end = first/last whatever they were (Blender keeps end >= start)."""
    start, end = cache.frame_start, cache.frame_end

    def put(a, b):
        cache.frame_end = max(b, cache.frame_start)
        cache.frame_start = a
        cache.frame_end = b

    put(first, last)
    restore.add(lambda: put(start, end))


def _add_input_modifier(obj, cloth, pc2_path, first, restore):
    """The Mesh Cache modifier that feeds the bake to the cloth, just before it (see the module
    docstring); its settings are bake.add_mesh_cache's (frame f shows the PC2's frame f)."""
    modifier = obj.modifiers.new(INPUT_MODIFIER, "MESH_CACHE")
    restore.add(lambda: obj.modifiers.remove(obj.modifiers[INPUT_MODIFIER]))
    modifier.cache_format = "PC2"
    modifier.filepath = pc2_path
    modifier.time_mode = "FRAME"
    modifier.play_mode = "SCENE"
    modifier.frame_scale = 1.0
    modifier.frame_start = float(first)
    modifier.deform_mode = "OVERWRITE"
    modifier.interpolation = "LINEAR"
    modifier.factor = 1.0
    modifier.forward_axis = "POS_Y"
    modifier.up_axis = "POS_Z"
    modifier.flip_axis = set()
    index = list(obj.modifiers).index(cloth)
    with bpy.context.temp_override(object=obj):
        bpy.ops.object.modifier_move_to_index(modifier=modifier.name, index=index)
    return modifier


def _use_rest_key(obj, settings, restore):
    """Springs rest at the mesh's own shape, not at the bake's first frame (module docstring)."""
    if settings.rest_shape_key is not None or settings.use_dynamic_mesh:
        return
    mesh = obj.data
    had_keys = mesh.shape_keys is not None
    if not had_keys:
        obj.shape_key_add(name="Basis", from_mix=False)
    key = obj.shape_key_add(name=REST_KEY, from_mix=False)
    key.value = 0.0

    def remove():
        if had_keys:
            obj.shape_key_remove(mesh.shape_keys.key_blocks[REST_KEY])
        else:
            obj.shape_key_clear()

    restore.add(remove)
    _setattr(restore, settings, "rest_shape_key", key)


def _cloth_inputs(scene, obj, frames, pinned):
    """(matrices (F, 4, 4), inputs (F, V, 3) float32 or None): the object's matrix_world and,
    when some vertices are pinned, the positions that reach its Cloth modifier (object space),
    at each frame, read frame by frame with the cloth and what follows it switched off (the
    caller's doing). Without pins and with a transform that cannot change (no animation,
    parent or constraints) the current matrix serves every frame and nothing is evaluated."""
    moving = bool(obj.animation_data or obj.parent or obj.constraints)
    if not moving and not pinned.any():
        matrix = np.array(obj.matrix_world, dtype=np.float64)
        return np.repeat(matrix[None], len(frames), 0), None
    matrices = np.empty((len(frames), 4, 4))
    inputs = np.empty((len(frames), len(obj.data.vertices), 3), dtype=np.float32)
    for i, frame in enumerate(frames):
        scene.frame_set(frame)
        depsgraph = bpy.context.evaluated_depsgraph_get()
        engine.read_evaluated(obj, depsgraph, inputs[i], world=False, role="cloth")
        matrices[i] = np.array(obj.evaluated_get(depsgraph).matrix_world, dtype=np.float64)
    return matrices, inputs


def _apply(points, matrix):
    """(V, 3) float32 points moved by a 4x4 numpy matrix, in place (the identity: unchanged)."""
    if np.array_equal(matrix, np.eye(4)):
        return points
    points[:] = points.astype(np.float64) @ matrix[:3, :3].T + matrix[:3, 3]
    return points


def provenance(obj, first, last, frame, goal_strength, space, bake_pattern, blend):
    """The record each output carries (attribute dsSimulation), one line of JSON."""
    return json.dumps({
        "tool": "drivenshape_blender.simulate", "solver": f"Blender {bpy.app.version_string} "
        "cloth", "blend": blend, "object": obj.name, "window": [first, last], "frame": frame,
        "goal_strength": goal_strength, "space": space.lower(), "bake": bake_pattern,
        "start": "the bake's positions at the window's first frame, zero velocities",
    }, separators=(",", ":"))


def _checked(obj, first, last, goal_strength, space, bake_pattern, out_pattern, own_file):
    """The window's arguments checked before anything changes: (cloth modifier, space, absolute
    bake and output patterns); UserError naming what is wrong."""
    if last < first:
        raise UserError(f"The window {first}-{last} is empty")
    if not 0.0 <= goal_strength <= 1.0:
        raise UserError(f"The goal strength {goal_strength} is not between 0 (a free "
                        "simulation) and 1 (the bake)")
    space = space.upper()
    if space not in SPACES:
        raise UserError(f"Space '{space}' is neither world nor object")
    if obj.mode != "OBJECT":
        raise UserError(f"The object '{obj.name}' is in {obj.mode.title()} Mode: leave it first")
    cloth = cloth_modifier(obj)
    check_cache(cloth.point_cache, obj, own_file)
    bake_pattern, out_pattern = os.path.abspath(bake_pattern), os.path.abspath(out_pattern)
    engine.expand_pattern(bake_pattern, first)  # a pattern without #### is a UserError
    engine.expand_pattern(out_pattern, first)
    return cloth, space, bake_pattern, out_pattern


def _prepare(scene, obj, cloth, baked, frames, goal_strength, space, work, restore):
    """Sets the cloth up to simulate `frames` from the bake `baked` (F, V, 3) in `space`: the
    input modifier and its PC2 in `work`, the rest key, the goal group, the cache's range
    (module docstring). Every change is recorded in `restore`."""
    settings = cloth.settings
    pin_name = settings.vertex_group_mass
    pin = _group_weights(obj, pin_name) if pin_name else \
        np.zeros(len(obj.data.vertices), np.float32)
    pinned = pin.astype(np.float64) ** 4 >= SOFT_GOAL_SNAP
    # The cloth and what follows it off while its inputs are read; what follows it stays off
    # (it changes what is read back, not the cloth).
    index = list(obj.modifiers).index(cloth)
    for modifier in list(obj.modifiers)[index:]:
        _setattr(restore, modifier, "show_viewport", False)
    matrices, inputs = _cloth_inputs(scene, obj, frames, pinned)
    cloth.show_viewport = True
    # The Mesh Cache applies the PC2 in object space; pinned vertices keep their input.
    local = baked.copy()
    if space == "WORLD":
        for i in range(len(frames)):
            _apply(local[i], np.linalg.inv(matrices[i]))
    if inputs is not None:
        local[:, pinned] = inputs[:, pinned]
    pc2 = os.path.join(work, "bake_input.pc2")
    module.get().write_pc2(pc2, local, start_frame=float(frames[0]), sample_rate=1.0)
    _add_input_modifier(obj, cloth, pc2, frames[0], restore)
    _use_rest_key(obj, settings, restore)
    if goal_strength > 0.0:
        weights = np.maximum(pin, np.float32(goal_strength ** 0.25))
        _set_group(obj, GOAL_GROUP, weights, restore)
        _setattr(restore, settings, "vertex_group_mass", GOAL_GROUP)
    cache = cloth.point_cache
    if cache.is_baked:
        with bpy.context.temp_override(point_cache=cache):
            bpy.ops.ptcache.free_bake()
    _set_frame_range(restore, cache, frames[0], frames[-1])


def _step(scene, obj, frames, space, out_pattern, header, written, log):
    """Steps the scene through `frames` in order and writes the cloth of each (in `space`) to
    `out_pattern`; `header(frame)` gives the writer's keywords. Appends each file to
    `written` as it lands."""
    ds = module.get()
    positions = np.empty((len(obj.data.vertices), 3), dtype=np.float32)
    for frame in frames:
        scene.frame_set(frame)
        depsgraph = bpy.context.evaluated_depsgraph_get()
        engine.read_evaluated(obj, depsgraph, positions, world=False, role="cloth")
        if space == "WORLD":
            matrix = obj.evaluated_get(depsgraph).matrix_world
            _apply(positions, np.array(matrix, dtype=np.float64))
        if not np.isfinite(positions).all():
            raise UserError(f"Frame {frame}: the cloth of '{obj.name}' went to infinity or NaN")
        path = engine.expand_pattern(out_pattern, frame)
        if not written:
            os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
        try:
            ds.write_point_cache_exr(path, positions, frame=frame, sync=False, **header(frame))
        except Exception as error:
            raise UserError(f"Frame {frame}: cannot write {path}: "
                            f"{engine.describe_error(error)}") from None
        written.append(path)
        if log:
            log(f"frame {frame}: {path}")


def simulate_window(scene, obj, bake_pattern, first, last, goal_strength, out_pattern,
                    space="WORLD", own_file=False, blend=None, log=None):
    """Simulates frames first..last of `obj`'s cloth from the bake's cloth at `first`, pulled
    toward the bake with `goal_strength` (0 to 1), and writes one point-cache EXR per frame to
    `out_pattern` (#### or %04d). Patterns are absolute paths or relative to the working folder.
    Everything it changes on the object and the scene is put back; the cloth's point cache then
    holds the window's frames (a memory cache; see check_cache for what it refuses). `blend`
    names the file in the provenance record (default: the open file). Returns the list of files
    written; on an error none is left and UserError names the file, frame or object."""
    cloth, space, bake_pattern, out_pattern = _checked(
        obj, first, last, goal_strength, space, bake_pattern, out_pattern, own_file)
    blend = blend or bpy.data.filepath
    frames = list(range(first, last + 1))
    try:
        topology_hash = engine.make_mesh(obj).topology_hash
    except Exception as error:
        raise UserError(f"Cannot use the mesh of '{obj.name}': "
                        f"{engine.describe_error(error)}") from None
    baked, bake_topology = read_bake(bake_pattern, frames, obj, topology_hash)
    fps = scene.render.fps / scene.render.fps_base

    def header(frame):
        record = provenance(obj, first, last, frame, goal_strength, space, bake_pattern, blend)
        return dict(topology_hash=bake_topology or topology_hash, frames_per_second=fps,
                    string_attributes={PROVENANCE_ATTRIBUTE: record})

    restore = _Restore()
    work = tempfile.mkdtemp(prefix="drivenshape_window_")
    written = []
    frame_before = scene.frame_current
    try:
        _prepare(scene, obj, cloth, baked, frames, goal_strength, space, work, restore)
        _step(scene, obj, frames, space, out_pattern, header, written, log)
    except BaseException:
        for path in written:
            try:
                os.remove(path)
            except OSError:
                pass
        raise
    finally:
        restore.undo()
        shutil.rmtree(work, ignore_errors=True)
        if scene.frame_current != frame_before:
            scene.frame_set(frame_before)
    return written


# --- Simulate Flagged Frames (the operator): the windows of the library's plan, run here ------
# The library half of issue 44 (drivenshape.plan_simulation, drivenshape.splice) is written
# beside this one; _plan_windows and _splice are the only two places that call it.

LIBRARY_FUNCTIONS = ("plan_simulation", "splice_files")


def _plan_windows(ds, verdicts, tolerance, settings):
    """The library's plan for the scene's stored verdicts (every baked frame with its predicted
    error and whether it is flagged, and the tolerance they were judged with: the part of a bake
    report the plan reads) with the scene's simulation settings (the settings table's "simulate"
    rows), and its windows as [(warmup_from, to)]: the frames each window simulates."""
    if tolerance < 0:
        raise UserError("The stored verdicts have no tolerance: bake with the pose model (or "
                        "Mark Frames to Simulate) again")
    report = {"coverage": {"tolerance": float(tolerance)},
              "frames": [{"frame": int(v.frame), "predicted_error": max(float(v.error_bound), 0.0),
                          "coverage": {"flagged": bool(v.flagged)}} for v in verdicts]}
    plan = ds.plan_simulation(report, **settings)
    return plan, [(window["warmup_from"], window["to"]) for window in plan["windows"]]


def _splice(ds, bake_pattern, plan, window_patterns, out_pattern):
    """The library's splice of the simulated windows into the bake, written to `out_pattern`
    (the files `drivenshape simulate` writes, byte for byte). Returns each frame's source."""
    return ds.splice_files(plan, bake_pattern, window_patterns, out_pattern)


def bake_space(space):
    """The space of the add-on's bake EXRs for simulate_window: the scene setting's Object
    ("LOCAL", the cloth object's space) or World."""
    return "OBJECT" if space == "LOCAL" else space


def spliced_pattern(bake_pattern):
    """Where Simulate Flagged Frames writes the shot: the bake's pattern in a `simulated`
    folder beside the bake's EXRs."""
    folder, name = os.path.split(bake_pattern)
    return os.path.join(folder, "simulated", name)


def simulate_flagged(context, log=None):
    """Simulates the windows the library plans for the frames the last bake flagged, each with
    simulate_window on the scene's cloth, and splices them into the bake's EXRs (written to
    spliced_pattern). Needs the bake's EXR point caches; refuses a baked or disk cloth cache
    (check_cache). Returns a summary for the report."""
    ds = module.get()
    missing = [name for name in LIBRARY_FUNCTIONS if not hasattr(ds, name)]
    if missing:
        raise UserError(f"This drivenshape module ({getattr(ds, '__version__', '?')}) has no "
                        f"{' or '.join(missing)}: Simulate Flagged Frames needs the library's "
                        "simulation plan and splice (issue 44). Build the module from a source "
                        "tree that has them")
    scene = context.scene
    settings = scene.drivenshape
    _driver, cloth = engine.scene_objects(scene, driver_editable=False)
    flagged = [verdict.frame for verdict in settings.verdicts if verdict.flagged]
    if not flagged:
        raise UserError("No frame is flagged to simulate: bake with the pose model first")
    if not settings.bake_write_exr:
        raise UserError("Simulating flagged frames splices into the bake's EXR point caches: "
                        "turn EXR Point Caches on and bake again")
    bake_pattern = engine.abspath(settings.bake_exr_pattern)
    out_pattern = spliced_pattern(bake_pattern)
    simulation = engine.module_kwargs(settings, "simulate")
    live.stop(restore=True)  # live mode writes the cloth's mesh on every frame change
    plan, windows = _plan_windows(ds, settings.verdicts, settings.verdict_tolerance, simulation)
    work = tempfile.mkdtemp(prefix="drivenshape_windows_")
    try:
        patterns = []
        for first, last in windows:
            pattern = os.path.join(work, f"window_{first}_{last}", "x.####.exr")
            simulate_window(scene, cloth, bake_pattern, first, last,
                            simulation.get("goal_strength", 0.0), pattern,
                            space=bake_space(settings.space), log=log)
            patterns.append(pattern)
        os.makedirs(os.path.dirname(out_pattern), exist_ok=True)  # the library's writer wants it
        sources = _splice(ds, bake_pattern, plan, patterns, out_pattern)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    simulated = sum(last - first + 1 for first, last in windows)
    blended = sources.count("blended")
    return (f"Simulated {len(windows)} window(s), {simulated} frames, for {len(flagged)} flagged "
            f"frames of '{cloth.name}' ({blended} frames blended at the seams); the shot is in "
            f"{out_pattern}")
