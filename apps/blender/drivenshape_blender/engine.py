# SPDX-License-Identifier: Apache-2.0
"""What live mode, bakes and database builds share: the database, device and Evaluator (kept
between frames, rebuilt only when what they depend on changes), reading and writing mesh
positions through numpy without a Python loop over vertices, and the messages the UI shows.

Every call into the drivenshape module goes through this file."""

import os

import bpy
import numpy as np

from . import module
from .settings_generated import SETTINGS


class UserError(Exception):
    """A problem the artist can fix; the text is reported as is (it names the file, frame or
    object at fault)."""


def scene_objects(scene, driver_editable):
    """(driver, cloth) picked in the scene's DrivenShape settings; UserError when one is missing,
    both are the same object, or one is in Edit Mode (the driver may be, if `driver_editable`)."""
    settings = scene.drivenshape
    driver, cloth = settings.driver, settings.cloth
    if driver is None or cloth is None:
        raise UserError("Pick the driver and the cloth objects in the DrivenShape panel")
    if driver == cloth:
        raise UserError(f"'{driver.name}' is both the driver and the cloth")
    for role, obj in (("driver", driver), ("cloth", cloth)):
        if obj.mode == "EDIT" and not (role == "driver" and driver_editable):
            raise UserError(f"The {role} object '{obj.name}' is in Edit Mode: leave it first")
    return driver, cloth


def abspath(path):
    """An absolute file path from a setting; `//` means the .blend file's folder."""
    if not path:
        return ""
    if path.startswith("//") and not bpy.data.filepath:
        raise UserError(f"The path {path} is relative to the .blend file, which is not saved "
                        "yet: save it first, or give an absolute path")
    return os.path.normpath(bpy.path.abspath(path))


def describe_error(error):
    """Text of a drivenshape.Error (its message names the file, frame or vertex) or of any
    other exception, for a report."""
    text = str(error)
    if type(error).__name__ == "Error":
        return text
    return f"{type(error).__name__}: {text}" if text else type(error).__name__


def module_kwargs(settings, scope):
    """The scene's settings of the settings table's `scope` as the module's keyword arguments:
    "evaluator" for drivenshape.EvaluatorSettings, "build" for drivenshape.build_database
    (settings_generated.SETTINGS: a checkbox passes the choice it stands for)."""
    kwargs = {}
    for setting in SETTINGS:
        if setting["scope"] == scope:
            value = getattr(settings, setting["property"])
            if setting["checkbox"]:
                value = setting["checkbox"] if value else setting["off"]
            kwargs[setting["key"]] = value
    return kwargs


def evaluator_kwargs(settings):
    """The scene's settings as drivenshape.EvaluatorSettings keyword arguments."""
    return module_kwargs(settings, "evaluator")


def length_text(value, unit_settings):
    """A length in Blender units as the scene shows lengths: mm for a metric or imperial scene
    (Blender units x the unit scale are metres), Blender units when the scene has no unit."""
    if unit_settings.system == "NONE":
        return f"{value:.4g} BU"
    return f"{value * unit_settings.scale_length * 1000.0:.1f} mm"


class EvaluatorCache:
    """The loaded database, the open device and an Evaluator for the current settings.

    Loading a database and building an Evaluator (shape alignment, QP factorisation, rest
    binding, uploads) take far longer than a frame, so they are made once and kept: the
    database until its file changes, the device until its specification changes, the Evaluator
    until either of those or a setting changes."""

    def __init__(self):
        self.clear()

    def clear(self):
        self.database_key = None
        self.database = None
        self.device_spec = None
        self.device = None
        self.evaluator_key = None
        self.evaluator = None

    def load_database(self, path_setting):
        ds = module.get()
        path = abspath(path_setting)
        if not path:
            raise UserError("No database: set a .dsdb file (or build one) in the DrivenShape "
                            "panel")
        try:
            stat = os.stat(path)
        except OSError as error:
            raise UserError(f"Cannot read the database {path}: {error.strerror}") from None
        key = (path, stat.st_mtime_ns, stat.st_size)
        if key != self.database_key:
            # Forget the old one first: a failed load must not leave it looking current.
            self.database_key = self.database = self.evaluator = self.evaluator_key = None
            try:
                self.database = ds.load_database(path)
            except Exception as error:
                raise UserError(f"Cannot load the database {path}: "
                                f"{describe_error(error)}") from None
            self.database_key = key
        return self.database

    def open_device(self, spec):
        ds = module.get()
        spec = spec.strip() or "auto"
        if spec != self.device_spec:
            self.device_spec = self.device = self.evaluator = self.evaluator_key = None
            try:
                self.device = ds.open_device(spec)
            except Exception as error:
                raise UserError(f"Cannot open the device '{spec}': "
                                f"{describe_error(error)}") from None
            self.device_spec = spec
        return self.device

    def evaluator_for(self, settings):
        """(evaluator, rebuilt): an Evaluator for the scene's settings, made only when they
        changed since the last call."""
        ds = module.get()
        database = self.load_database(settings.database_path)
        device = self.open_device(settings.device)
        kwargs = evaluator_kwargs(settings)
        key = (self.database_key, self.device_spec, tuple(sorted(kwargs.items())))
        if key == self.evaluator_key:
            return self.evaluator, False
        self.evaluator = self.evaluator_key = None
        try:
            self.evaluator = ds.Evaluator(database, ds.EvaluatorSettings(**kwargs), device)
        except Exception as error:
            raise UserError(f"Cannot set up the evaluator for {abspath(settings.database_path)}:"
                            f" {describe_error(error)}") from None
        self.evaluator_key = key
        return self.evaluator, True


CACHE = EvaluatorCache()


def driver_frames(scene, frames):
    """The frames the driver can be read at, from which the shot planner takes history and
    warm-up frames: the scene's frame range (what a PC2 export of the shot holds, which is what
    `drivenshape bake` reads), extended to take in `frames`."""
    return range(min(scene.frame_start, min(frames)), max(scene.frame_end, max(frames)) + 1)


def plan_shot(evaluator, scene, frames):
    """The library's batches for evaluating `frames` of the scene as `drivenshape bake` does
    (its default batch and temporal warm-up): [drivenshape.BatchPlan]."""
    return module.get().plan_shot(evaluator, frames, driver_frames(scene, frames))


def playback_planner(evaluator):
    """The library's plan of live playback with the bake's defaults: which frames continue the
    evaluator and which start a batch with warm-up frames (drivenshape.PlaybackPlanner)."""
    return module.get().PlaybackPlanner(evaluator)


def is_identity(matrix):
    return all(abs(matrix[i][j] - (1.0 if i == j else 0.0)) == 0.0
               for i in range(4) for j in range(4))


def to_space(points, matrix):
    """points (..., 3) float32 moved by a 4x4 mathutils matrix, in place; skipped for the
    identity so that positions stay bit for bit."""
    if is_identity(matrix):
        return points
    m = np.array(matrix, dtype=np.float64)
    moved = points.reshape(-1, 3) @ m[:3, :3].T + m[:3, 3]
    points.reshape(-1, 3)[:] = moved
    return points


def evaluated_mesh(obj, depsgraph):
    """The object's mesh after modifiers, shape keys and constraints (depsgraph evaluation)."""
    return obj.evaluated_get(depsgraph).data


def read_evaluated(obj, depsgraph, out, world=False, role="driver"):
    """Copies the evaluated vertex positions of `obj` into `out` (V x 3 float32, C-contiguous),
    in object space, or world space with `world`. Raises UserError when the vertex count is
    not len(out) (the database's `role` mesh)."""
    evaluated = obj.evaluated_get(depsgraph)
    vertices = evaluated.data.vertices
    if len(vertices) != len(out):
        raise UserError(
            f"The {role} object '{obj.name}' has {len(vertices)} vertices after its modifiers; "
            f"the database's {role} mesh has {len(out)}. Its vertices must be the database's, "
            "in the same order (no topology-changing modifiers)")
    vertices.foreach_get("co", out.reshape(-1))
    if world:
        to_space(out, evaluated.matrix_world)
    return out


def read_rest(obj):
    """The object's own mesh positions (before modifiers), V x 3 float32."""
    out = np.empty((len(obj.data.vertices), 3), dtype=np.float32)
    obj.data.vertices.foreach_get("co", out.reshape(-1))
    return out


def write_positions(obj, positions):
    """Writes V x 3 float32 positions into the object's own mesh and tags it for redraw."""
    mesh = obj.data
    mesh.vertices.foreach_set("co", positions.reshape(-1))
    mesh.update()


def topology(obj):
    """(rest positions V x 3, face_start F+1, face_vertices) of the object's own mesh, the
    polygon lists drivenshape meshes are made of."""
    mesh = obj.data
    loop_total = np.empty(len(mesh.polygons), dtype=np.int32)
    mesh.polygons.foreach_get("loop_total", loop_total)
    face_start = np.zeros(len(mesh.polygons) + 1, dtype=np.int32)
    np.cumsum(loop_total, out=face_start[1:])
    # Polygons store their loops contiguously in polygon order.
    face_vertices = np.empty(len(mesh.loops), dtype=np.int32)
    mesh.loops.foreach_get("vertex_index", face_vertices)
    return read_rest(obj), face_start, face_vertices


def make_mesh(obj, rest=None):
    """A drivenshape mesh with the object's topology; rest positions from `rest` or the mesh."""
    ds = module.get()
    positions, face_start, face_vertices = topology(obj)
    if rest is not None:
        positions = rest
    return ds.Mesh.from_polygons(positions, face_start, face_vertices)


def expand_pattern(pattern, frame):
    """`####` (one digit per #) or `%04d` in a file pattern replaced by the frame number."""
    if "%" in pattern:
        return pattern % frame
    start = pattern.rfind("#")
    if start < 0:
        raise UserError(f"The EXR pattern {pattern} has no #### for the frame number")
    end = start + 1
    while start > 0 and pattern[start - 1] == "#":
        start -= 1
    width = end - start
    digits = f"{frame:0{width}d}" if frame >= 0 else "-" + f"{-frame:0{width}d}"
    return pattern[:start] + digits + pattern[end:]
