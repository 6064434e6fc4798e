# SPDX-License-Identifier: Apache-2.0
"""USD in and out for drivenshape (usd-core's `pxr`).

Read a driver animation from the time-sampled points of a UsdGeomMesh, evaluate it, and write
the cloth as a UsdGeomMesh with one time sample of points and extent per frame, the faces and
UVs of the driven rest mesh, and the stage's upAxis and metersPerUnit:

    import drivenshape as ds
    from drivenshape import usd

    db = ds.load_database("sleeve.dsdb")
    shot = usd.read_mesh_animation("shot.usda", "/Character/Arm")
    usd.check_driver(shot, db.driver_mesh)                 # vertex count and faces
    evaluator = ds.Evaluator(db, ds.EvaluatorSettings(), ds.open_device("auto"))
    cloth, records = ds.evaluate_cache(evaluator, shot.cache(), shot.frames)
    usd.write_mesh_usd("cloth.usdc", db.driven_mesh, shot.frames, cloth,
                       fps=shot.time_codes_per_second, up_axis=shot.up_axis,
                       meters_per_unit=shot.meters_per_unit)

or from a shell (python -m drivenshape.usd bake --help):

    python -m drivenshape.usd bake --db sleeve.dsdb --usd shot.usda --prim /Character/Arm \\
        --out cloth.usdc

and a result already on disk (EXRs of `drivenshape bake`, a PC2) with `export`:

    python -m drivenshape.usd export --mesh driven_rest.obj --exr out/pants.####.exr \\
        --frames 1001-1100 [--up-axis Y] -o pants.usdc

Points are read and written as float32 exactly (no unit conversion, no interpolation): the
driver, the database and the cloth share one scene unit. An output up axis other than the
points' own rotates them about X (Z up -> Y up: (x, y, z) -> (x, z, -y)), which is exact too
(drivenshape.convert_up_axis: values are moved and negated, never rounded). Exit codes of the command: 0 ok,
2 usage, 3 input, 4 output, 5 OpenCL device, 6 numerical (those of the drivenshape command
line).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import re
import sys
import tempfile
import warnings
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from typing import Any, Optional, SupportsFloat, SupportsIndex, TypedDict, Union

import numpy as np
import numpy.typing as npt

from . import (Database, Device, Error, EvaluatorSettings, FrameRecord, Mesh, PointCache, _files,
               convert_up_axis)

EXIT_OK: int = 0
EXIT_USAGE: int = 2
EXIT_INPUT: int = 3
EXIT_OUTPUT: int = 4
_CODES: dict[str, int] = {"usage": EXIT_USAGE, "input": EXIT_INPUT, "output": EXIT_OUTPUT}

#: Scene conventions of drivenshape's data (Blender: Z up, metres) when a stage says nothing.
DEFAULT_UP_AXIS: str = "Z"
DEFAULT_METERS_PER_UNIT: float = 1.0

# The types of the signatures below. usd-core's `pxr` ships no type information (no stubs, no
# py.typed marker): its modules and the objects they return are Any here.
_Path = Union[str, "os.PathLike[str]"]
_TimeCode = Union[SupportsFloat, SupportsIndex]  # a USD time code: a frame number, maybe fractional
_Float32Array = npt.NDArray[np.float32]
_Int32Array = npt.NDArray[np.int32]
_UVs = tuple[npt.ArrayLike, npt.ArrayLike]  # (uv values (U, 2), one uv id per face corner)
_Pxr = tuple[Any, Any, Any, Any]  # (Sdf, Usd, UsdGeom, Vt)


class _MeshTopology(TypedDict):
    counts: npt.ArrayLike  # vertices per face
    indices: npt.ArrayLike  # the faces' vertex ids, concatenated


class MeshArrays(_MeshTopology, total=False):
    """write_mesh_usd's mesh as plain arrays: `counts` and `indices` (required), `uvs` (a pair
    of uv values and uv ids per face corner, or None) and `groups` ({name: face ids})."""

    uvs: Optional[_UVs]
    groups: Mapping[str, Iterable[int]]


class ExportSummary(TypedDict):
    """What export() returns."""

    frames: list[SupportsIndex]
    vertices: int
    fps: float


class BakeSummary(TypedDict):
    """What bake() returns: `verdict` is the shot's coverage verdict (the bake report's
    `coverage` object, drivenshape.shot_verdict), None without the pose model."""

    frames: list[int]
    device: str
    seconds: dict[str, float]
    records: list[FrameRecord]
    note: str
    warnings: list[str]
    verdict: Optional[dict[str, Any]]


def _error(kind: str, message: str) -> Error:
    error = Error(message)
    # The stubs declare kind and code as the class's defaults (ClassVar); an instance gets its own.
    error.kind = kind  # type: ignore[misc]
    error.code = _CODES[kind]  # type: ignore[misc]
    return error


def _pxr() -> _Pxr:
    try:
        from pxr import Sdf, Usd, UsdGeom, Vt
    except ImportError as error:
        raise _error("usage", f"drivenshape.usd needs usd-core (pip install usd-core): {error}")
    return Sdf, Usd, UsdGeom, Vt


# ---- Reading -------------------------------------------------------------------------------

class MeshAnimation:
    """Time-sampled points of one UsdGeomMesh.

    frames: list of int frame numbers (the points' time samples); positions: (F, V, 3)
    float32; face_counts, face_indices: int32 topology of the prim; up_axis ('Y' or 'Z') and
    meters_per_unit: the stage's, or None where the stage does not author them;
    time_codes_per_second: the stage's; layers: the files of the stage's layers (its own file,
    its sublayers and references), which a bake must not overwrite.
    """

    def __init__(self, path: str, prim_path: str, frames: list[int], positions: _Float32Array,
                 face_counts: _Int32Array, face_indices: _Int32Array, up_axis: Optional[str],
                 meters_per_unit: Optional[float], time_codes_per_second: float,
                 layers: Sequence[str] = ()) -> None:
        self.path = path
        self.prim_path = prim_path
        self.frames = frames
        self.positions = positions
        self.face_counts = face_counts
        self.face_indices = face_indices
        self.up_axis = up_axis
        self.meters_per_unit = meters_per_unit
        self.time_codes_per_second = time_codes_per_second
        self.layers = list(layers) or [path]

    @property
    def vertex_count(self) -> int:
        return int(self.positions.shape[1])

    def cache(self) -> PointCache:
        """A drivenshape.PointCache over the positions (no copy)."""
        return PointCache.from_array(self.positions, frames=self.frames)

    def __repr__(self) -> str:
        return (f"<MeshAnimation {self.path}:{self.prim_path}, {self.vertex_count} points, "
                f"{len(self.frames)} frames>")


def _open_mesh(path: str, prim_path: str) -> tuple[Any, Any]:
    """(stage, UsdGeom.Mesh) of the mesh prim `prim_path` in the USD file `path`."""
    Sdf, Usd, UsdGeom, Vt = _pxr()
    problem = _files.regular_problem(path)
    if problem:
        raise _error("input", f"USD file '{path}' {problem}")
    try:
        stage = Usd.Stage.Open(path)
    except Exception as error:  # pxr raises Tf.ErrorException
        raise _error("input", f"cannot open USD '{path}': {error}")
    if stage is None:
        raise _error("input", f"cannot open USD '{path}'")
    try:
        prim = stage.GetPrimAtPath(prim_path)
    except Exception:
        raise _error("usage", f"'{prim_path}' is not a valid prim path")
    if not prim or not prim.IsValid():
        meshes = [str(p.GetPath()) for p in stage.Traverse() if p.IsA(UsdGeom.Mesh)]
        raise _error("input", f"{path}: no prim at '{prim_path}'; the stage's meshes: "
                              f"{', '.join(meshes[:20]) or 'none'}")
    if not prim.IsA(UsdGeom.Mesh):
        raise _error("input", f"{path}: '{prim_path}' is a {prim.GetTypeName() or 'typeless'} "
                              "prim, not a Mesh")
    return stage, UsdGeom.Mesh(prim)


def _whole_frames(mesh: Any) -> tuple[list[int], int]:
    """(the whole frames among the time samples of the mesh's points, how many samples)."""
    samples = mesh.GetPointsAttr().GetTimeSamples()
    return [int(round(t)) for t in samples if abs(t - round(t)) < 1e-6], len(samples)


def _frames_to_read(path: str, prim_path: str, whole: list[int], samples: int,
                    frames: Optional[Iterable[SupportsIndex]]) -> list[int]:
    """`frames` (every whole frame when None), each checked to be a time sample."""
    if frames is None:
        if not whole:
            raise _error("input", f"{path}: {prim_path}.points has no time samples at whole "
                                  f"frames ({samples} samples); drivenshape needs one per "
                                  "frame")
        return whole
    read = [int(f) for f in frames]
    have = set(whole)
    missing = [f for f in read if f not in have]
    if missing:
        raise _error("input", f"{path}: {prim_path}.points has no time sample at frame "
                              f"{missing[0]} ({len(missing)} of the {len(read)} frames "
                              f"asked are missing; the samples cover "
                              f"{_frame_text(whole)}); nothing is interpolated")
    if not read:
        raise _error("usage", "no frames to read")
    return read


def _read_points(path: str, prim_path: str, mesh: Any, read: list[int],
                 space: str) -> _Float32Array:
    """The points (F, V, 3) float32 of the mesh at frames `read`, through the prim's transform
    for space 'world'."""
    UsdGeom = _pxr()[2]
    points = mesh.GetPointsAttr()
    positions: Optional[_Float32Array] = None
    cache = UsdGeom.XformCache()
    for index, frame in enumerate(read):
        value = points.Get(float(frame))
        xyz = np.asarray(value if value is not None else [], dtype=np.float32).reshape(-1, 3)
        if positions is None:
            positions = np.empty((len(read), len(xyz), 3), dtype=np.float32)
        elif len(xyz) != positions.shape[1]:
            raise _error("input", f"{path}: {prim_path}.points has {len(xyz)} points at frame "
                                  f"{frame} but {positions.shape[1]} at frame {read[0]}; the "
                                  "topology must not change over the shot")
        if space == "world":
            cache.SetTime(float(frame))
            matrix = np.array(cache.GetLocalToWorldTransform(mesh.GetPrim()), dtype=np.float64)
            xyz = (xyz.astype(np.float64) @ matrix[:3, :3] + matrix[3, :3]).astype(np.float32)
        positions[index] = xyz
    assert positions is not None  # `read` is not empty
    if positions.shape[1] == 0:
        raise _error("input", f"{path}: {prim_path} has no points")
    return positions


def _stage_units(stage: Any) -> tuple[Optional[str], Optional[float]]:
    """(upAxis, metersPerUnit) where the stage authors them, else None."""
    UsdGeom = _pxr()[2]
    up_axis = None
    if stage.HasAuthoredMetadata("upAxis"):
        up_axis = str(UsdGeom.GetStageUpAxis(stage))
    meters = None
    if stage.HasAuthoredMetadata("metersPerUnit"):
        meters = float(UsdGeom.GetStageMetersPerUnit(stage))
    return up_axis, meters


def _layer_files(stage: Any) -> list[str]:
    """The files behind the stage's layers (anonymous layers have none)."""
    return [str(layer.realPath) for layer in stage.GetUsedLayers() if layer.realPath]


def mesh_time_samples(path: _Path, prim_path: str) -> list[int]:
    """The whole frames at which the points of the UsdGeomMesh at `prim_path` are sampled
    (ascending), without reading the points: the frames a bake may read as history."""
    _, mesh = _open_mesh(os.fspath(path), prim_path)
    return _whole_frames(mesh)[0]


def read_mesh_animation(path: _Path, prim_path: str,
                        frames: Optional[Iterable[SupportsIndex]] = None,
                        space: str = "local") -> MeshAnimation:
    """Reads the points of the UsdGeomMesh at `prim_path` at every whole-frame time sample (or
    at `frames`, each of which must be a time sample: nothing is interpolated). space 'local'
    reads the points as authored; 'world' applies the prim's local-to-world transform per frame
    (in double, then float32). Raises drivenshape.Error (kind 'input') naming the file, the prim
    and the frame."""
    path = os.fspath(path)
    if space not in ("local", "world"):
        raise _error("usage", f"space '{space}' is not one of local, world")
    stage, mesh = _open_mesh(path, prim_path)
    read = _frames_to_read(path, prim_path, *_whole_frames(mesh), frames)
    counts = mesh.GetFaceVertexCountsAttr().Get()
    indices = mesh.GetFaceVertexIndicesAttr().Get()
    positions = _read_points(path, prim_path, mesh, read, space)
    up_axis, meters = _stage_units(stage)
    return MeshAnimation(path, prim_path, read, positions,
                         np.asarray(counts if counts is not None else [], dtype=np.int32),
                         np.asarray(indices if indices is not None else [], dtype=np.int32),
                         up_axis, meters, float(stage.GetTimeCodesPerSecond()),
                         _layer_files(stage))


def check_driver(animation: MeshAnimation, mesh: Mesh) -> None:
    """Raises drivenshape.Error (kind 'input') unless the animation's prim has the vertex count
    and the faces of `mesh` (the database's driver mesh), saying what differs."""
    where = f"{animation.path}: {animation.prim_path}"
    if animation.vertex_count != mesh.vertex_count:
        raise _error("input", f"{where} has {animation.vertex_count} points but the database's "
                              f"driver mesh has {mesh.vertex_count} vertices; give the prim of "
                              "the driver the database was built from")
    counts = np.diff(mesh.face_start)
    if len(animation.face_counts) != len(counts):
        raise _error("input", f"{where} has {len(animation.face_counts)} faces but the "
                              f"database's driver mesh has {len(counts)}; same vertex count, "
                              "other topology (triangulated or re-exported?)")
    if not np.array_equal(animation.face_counts, counts):
        face = int(np.flatnonzero(animation.face_counts != counts)[0])
        raise _error("input", f"{where}: face {face} has {animation.face_counts[face]} corners, "
                              f"{counts[face]} in the database's driver mesh; the topology "
                              "differs")
    if not np.array_equal(animation.face_indices, mesh.face_vertices):
        corner = int(np.flatnonzero(animation.face_indices != mesh.face_vertices)[0])
        face = int(np.searchsorted(mesh.face_start, corner, side="right") - 1)
        raise _error("input", f"{where}: face {face} uses other vertices than in the database's "
                              f"driver mesh (corner {corner}: vertex "
                              f"{animation.face_indices[corner]}, expected "
                              f"{mesh.face_vertices[corner]}); the vertex order differs")


def _frame_text(frames: list[int]) -> str:
    if not frames:
        return "no frames"
    return f"{frames[0]}-{frames[-1]} ({len(frames)} frames)"


# ---- Writing -------------------------------------------------------------------------------

def _mesh_arrays(mesh: Union[Mesh, MeshArrays]
                 ) -> tuple[_Int32Array, _Int32Array, Optional[_UVs], Mapping[str, Iterable[int]]]:
    """(face counts, face indices, (uv values, uv indices) or None, {group: [faces]})."""
    if isinstance(mesh, Mesh):
        counts = np.diff(mesh.face_start).astype(np.int32)
        indices = np.ascontiguousarray(mesh.face_vertices, dtype=np.int32)
        uvs = None
        if mesh.has_uvs and len(mesh.face_uvs) and mesh.face_uvs.min() >= 0:
            uvs = (np.ascontiguousarray(mesh.uvs), np.ascontiguousarray(mesh.face_uvs))
        groups: dict[str, list[int]] = {}
        for face, group in enumerate(mesh.face_groups.tolist()):
            groups.setdefault(mesh.group_names[group], []).append(face)
        return counts, indices, uvs, groups
    return (np.asarray(mesh["counts"], dtype=np.int32), np.asarray(mesh["indices"],
                                                                   dtype=np.int32),
            mesh.get("uvs"), mesh.get("groups", {}))


def _check_prim_path(prim_path: str) -> None:
    Sdf = _pxr()[0]
    if not prim_path.startswith("/") or not Sdf.Path.IsValidPathString(prim_path):
        raise _error("usage", f"'{prim_path}' is not an absolute prim path")


def _check_output(path: _Path) -> tuple[str, str]:
    """(extension, folder) of an output stage; Error unless both are usable."""
    path = os.fspath(path)
    extension = os.path.splitext(path)[1].lower()
    if extension not in (".usd", ".usda", ".usdc"):
        raise _error("usage", f"'{path}': use a .usd, .usda or .usdc file name")
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise _error("output", f"'{path}': folder '{folder}' does not exist; create it first")
    return extension, folder


def vertex_normals(positions: npt.ArrayLike, counts: npt.ArrayLike,
                   indices: npt.ArrayLike) -> _Float32Array:
    """Unit vertex normals (F, V, 3) float32 of points (F, V, 3) on polygons (`counts` vertices
    each, `indices` flattened): the area-weighted sum of the normals of the fan triangles
    around each vertex, right-handed (counter-clockwise faces point at the viewer). A vertex no
    face uses, or whose faces have no area, gets (0, 0, 0)."""
    positions = np.asarray(positions, dtype=np.float64)
    counts = np.asarray(counts, dtype=np.int64)
    indices = np.asarray(indices, dtype=np.int64)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
    fans = [np.stack([indices[starts[counts > k + 1]], indices[starts[counts > k + 1] + k],
                      indices[starts[counts > k + 1] + k + 1]], axis=1)
            for k in range(1, int(counts.max(initial=0)) - 1)]
    triangles = np.concatenate(fans) if fans else np.zeros((0, 3), dtype=np.int64)
    vertex_count = positions.shape[1]
    normals = np.zeros(positions.shape, dtype=np.float64)
    for frame, xyz in enumerate(positions):
        a, b, c = (xyz[triangles[:, corner]] for corner in range(3))
        face = np.cross(b - a, c - a)  # twice the area, along the face normal
        for axis in range(3):
            normals[frame, :, axis] = sum(
                np.bincount(triangles[:, corner], weights=face[:, axis], minlength=vertex_count)
                for corner in range(3))
    length = np.linalg.norm(normals, axis=2, keepdims=True)
    unit: _Float32Array = np.divide(normals, length, out=np.zeros_like(normals),
                                    where=length > 0).astype(np.float32)
    return unit


def point_velocities(positions: npt.ArrayLike, frames: npt.ArrayLike,
                     fps: float) -> _Float32Array:
    """Velocities (F, V, 3) float32 in stage units per second of points (F, V, 3) at time codes
    `frames` (timeCodesPerSecond `fps`): central differences between the neighbouring samples,
    one-sided at the first and last; zero for a single sample. What renderers use for motion
    blur (UsdGeomPointBased.velocities)."""
    positions = np.asarray(positions, dtype=np.float64)
    seconds = np.asarray(frames, dtype=np.float64) / float(fps)
    if len(positions) < 2:
        return np.zeros(positions.shape, dtype=np.float32)
    after = np.minimum(np.arange(len(positions)) + 1, len(positions) - 1)
    before = np.maximum(np.arange(len(positions)) - 1, 0)
    step = (seconds[after] - seconds[before])[:, np.newaxis, np.newaxis]
    velocities: _Float32Array = ((positions[after] - positions[before]) / step).astype(np.float32)
    return velocities


def _scene_number(value: float, what: str) -> float:
    """A positive finite number of the stage (time codes per second, metres per unit)."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise _error("usage", f"{what} {value!r} is not a number")
    if not (number > 0 and np.isfinite(number)):
        raise _error("usage", f"{what} {value} is not a positive finite number")
    return number


def _checked_positions(positions: npt.ArrayLike, times: list[float], vertex_count: int,
                       up_axis: str, points_up_axis: Optional[str]) -> _Float32Array:
    """write_mesh_usd's positions as (F, V, 3) float32 in `up_axis`, checked: one frame per
    time code, every vertex the faces use, finite."""
    points = np.asarray(positions, dtype=np.float32)
    if points.ndim == 2:
        points = points[np.newaxis]
    if points.ndim != 3 or points.shape[2] != 3 or len(times) != len(points):
        raise _error("usage", f"positions {points.shape} do not match {len(times)} frames "
                              "of (vertices, 3)")
    if points.shape[1] < vertex_count:
        raise _error("input", f"positions hold {points.shape[1]} points but the faces use "
                              f"{vertex_count} vertices")
    if not times:
        raise _error("usage", "no frames to write")
    if not np.isfinite(times).all():
        raise _error("usage", "a time code is not finite")
    if not np.isfinite(points).all():
        frame, vertex = np.argwhere(~np.isfinite(points))[0][:2]
        raise _error("input", f"the positions of frame {times[frame]:g} vertex {vertex} are "
                              "not finite")
    if up_axis not in ("Y", "Z"):
        raise _error("usage", f"up axis '{up_axis}' is not Y or Z")
    if points_up_axis not in (None, "Y", "Z"):
        raise _error("usage", f"points up axis '{points_up_axis}' is not Y or Z")
    if points_up_axis is not None and points_up_axis != up_axis:
        points = convert_up_axis(points, points_up_axis, up_axis)
    return points


def _new_stage(temp: str, times: list[float], fps: float, up_axis: str,
               meters_per_unit: float) -> Any:
    """A new stage in the file `temp` with the scene's axis, unit, rate and frame range."""
    Sdf, Usd, UsdGeom, Vt = _pxr()
    stage = Usd.Stage.CreateNew(temp)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y if up_axis == "Y" else UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, meters_per_unit)
    stage.SetStartTimeCode(min(times))
    stage.SetEndTimeCode(max(times))
    stage.SetTimeCodesPerSecond(fps)
    stage.SetFramesPerSecond(fps)
    return stage


def _define_mesh(stage: Any, prim_path: str, counts: _Int32Array, indices: _Int32Array) -> Any:
    """The UsdGeom.Mesh at prim_path (its parents Xforms, the root the default prim and a
    component model) with its faces."""
    Sdf, Usd, UsdGeom, Vt = _pxr()
    names = prim_path.strip("/").split("/")
    for depth in range(1, len(names)):
        UsdGeom.Xform.Define(stage, "/" + "/".join(names[:depth]))
    geom = UsdGeom.Mesh.Define(stage, prim_path)
    stage.SetDefaultPrim(stage.GetPrimAtPath("/" + names[0]))
    geom.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    geom.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(counts))
    geom.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(indices))
    geom.CreateOrientationAttr(UsdGeom.Tokens.rightHanded)
    Usd.ModelAPI(stage.GetPrimAtPath("/" + names[0])).SetKind("component")
    return geom


def _write_points(geom: Any, times: list[float], positions: _Float32Array) -> None:
    """One time sample of points and of their extent per frame."""
    Vt = _pxr()[3]
    points = geom.CreatePointsAttr()
    extent = geom.CreateExtentAttr()
    for frame, xyz in zip(times, positions):
        points.Set(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(xyz)), frame)
        bounds = np.stack([xyz.min(axis=0), xyz.max(axis=0)])
        extent.Set(Vt.Vec3fArray.FromNumpy(bounds), frame)


def _write_uvs_and_groups(geom: Any, uvs: Optional[_UVs],
                          groups: Mapping[str, Iterable[int]]) -> None:
    """primvars:st (face-varying) and one UsdGeomSubset per face group when there are several."""
    Sdf, Usd, UsdGeom, Vt = _pxr()
    if uvs is not None:
        values, uv_indices = uvs
        primvar = UsdGeom.PrimvarsAPI(geom).CreatePrimvar(
            "st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.faceVarying)
        primvar.Set(Vt.Vec2fArray.FromNumpy(np.asarray(values, dtype=np.float32)))
        primvar.SetIndices(Vt.IntArray.FromNumpy(np.asarray(uv_indices, dtype=np.int32)))
    if len(groups) > 1:
        for name, faces in groups.items():
            token = re.sub(r"[^A-Za-z0-9_]", "_", name)
            if not token or token[0].isdigit():
                token = "g_" + token
            UsdGeom.Subset.CreateGeomSubset(geom, token, UsdGeom.Tokens.face,
                                            Vt.IntArray(list(faces)))


def _temp_beside(path: str, extension: str, folder: str) -> str:
    """A new empty file beside `path` to write the stage into (renamed into place after)."""
    try:
        handle, temp = tempfile.mkstemp(prefix="." + os.path.basename(path) + ".tmp-",
                                        suffix=extension, dir=folder)
        os.close(handle)
    except OSError as error:
        raise _error("output", f"cannot write in '{folder}': {error.strerror}")
    return temp


def write_mesh_usd(path: _Path, mesh: Union[Mesh, MeshArrays], frames: Iterable[_TimeCode],
                   positions: npt.ArrayLike, *, prim_path: str = "/Garment/Mesh",
                   fps: float = 24.0, up_axis: str = DEFAULT_UP_AXIS,
                   meters_per_unit: float = DEFAULT_METERS_PER_UNIT,
                   points_up_axis: Optional[str] = None, normals: bool = True,
                   velocities: bool = True,
                   provenance: Optional[Mapping[str, str]] = None) -> None:
    """Writes a UsdGeomMesh at `prim_path` (its parent an Xform, the root the default prim)
    with points (F, V, 3) at time codes `frames` and their extent per sample, faces, UVs
    (primvars:st, face-varying) and face groups (UsdGeomSubsets, when there are several) of
    `mesh` (a drivenshape.Mesh, or a dict with counts, indices, uvs, groups), the stage's
    upAxis, metersPerUnit, time codes per second and frame range. The file (.usd, .usda,
    .usdc) appears atomically, with the mode any new file gets (0666 less the umask). Points
    are written as float32 exactly; non-finite points, and an fps or meters_per_unit that is
    not a positive finite number, are refused.

    With `normals`, per-sample vertex normals (vertex_normals); with `velocities`, per-sample
    velocities in units per second (point_velocities) for motion blur. The root prim is a
    `component` model. `provenance`, a dict of strings (tool version, hashes, source files),
    goes into the mesh prim's customData under "drivenshape".

    up_axis is the stage's upAxis ('Y' or 'Z'); points_up_axis the axis `positions` are in.
    When they differ the points are rotated about X to up_axis (convert_up_axis: Z -> Y is
    (x, y, z) -> (x, z, -y), exact); None (the default) means the positions are already in
    up_axis and are written as given. drivenshape's own results are Z up: pass
    points_up_axis="Z" to write them into a Y-up stage."""
    path = os.fspath(path)
    counts, indices, uvs, groups = _mesh_arrays(mesh)
    times = [float(f) for f in frames]
    vertex_count = int(indices.max()) + 1 if len(indices) else 0
    points = _checked_positions(positions, times, vertex_count, up_axis, points_up_axis)
    fps = _scene_number(fps, "fps")
    meters_per_unit = _scene_number(meters_per_unit, "meters per unit")
    _check_prim_path(prim_path)
    extension, folder = _check_output(path)
    temp = _temp_beside(path, extension, folder)
    try:
        stage = _new_stage(temp, times, fps, up_axis, meters_per_unit)
        geom = _define_mesh(stage, prim_path, counts, indices)
        _write_points(geom, times, points)
        _write_motion(geom, _pxr()[3], times, points, counts, indices, fps, normals, velocities)
        if provenance:
            geom.GetPrim().SetCustomDataByKey(
                "drivenshape", {str(k): str(v) for k, v in provenance.items()})
        _write_uvs_and_groups(geom, uvs, groups)
        stage.GetRootLayer().Save()
        del stage
        # mkstemp made the file 0600; a stage is for render nodes and other users too.
        os.chmod(temp, _files.new_file_mode())
        os.replace(temp, path)
    except Error:
        raise
    except Exception as error:
        raise _error("output", f"cannot write USD '{path}': {error}")
    finally:
        if os.path.exists(temp):
            os.remove(temp)


def _write_motion(geom: Any, Vt: Any, frames: list[float], positions: _Float32Array,
                  counts: _Int32Array, indices: _Int32Array, fps: float, normals: bool,
                  velocities: bool) -> None:
    """The per-sample normals and velocities write_mesh_usd adds to `geom`."""
    if normals:
        attribute = geom.CreateNormalsAttr()
        geom.SetNormalsInterpolation("vertex")
        for frame, values in zip(frames, vertex_normals(positions, counts, indices)):
            attribute.Set(Vt.Vec3fArray.FromNumpy(values), frame)
    if velocities:
        attribute = geom.CreateVelocitiesAttr()
        for frame, values in zip(frames, point_velocities(positions, frames, fps)):
            attribute.Set(Vt.Vec3fArray.FromNumpy(values), frame)


# ---- The export command --------------------------------------------------------------------

def export(mesh: Union[Mesh, _Path], out_path: _Path, *, exr: Optional[str] = None,
           frames: Union[str, Iterable[SupportsIndex], None] = None,
           pc2: Optional[_Path] = None, fps: Optional[float] = None,
           prim_path: str = "/Garment/Mesh", up_axis: str = DEFAULT_UP_AXIS) -> ExportSummary:
    """A drivenshape result on disk to USD: the faces, UVs and groups of `mesh` (the driven rest
    OBJ's path, or a drivenshape.Mesh) with the points of a point-cache EXR sequence `exr`
    (a pattern: ####, %04d, $F4; `frames` a range text or a list) or of a PC2 file `pc2` (every
    whole-frame sample), read with the module's readers. Time codes are frame numbers at `fps`
    (default: the first EXR's framesPerSecond, else 24). The points are drivenshape's, Z up; a
    Y-up stage gets them rotated, (x, y, z) -> (x, z, -y), exactly. Returns a summary dict
    (frames, vertices, fps)."""
    import drivenshape as ds

    if (exr is None) == (pc2 is None):
        raise _error("usage", "give one of exr (a point-cache EXR pattern) and pc2")
    if up_axis not in ("Y", "Z"):
        raise _error("usage", f"up axis '{up_axis}' is not Y or Z")
    _check_output(out_path)
    _check_prim_path(prim_path)
    read: list[_files.NamedPath] = [] if isinstance(mesh, Mesh) else [("the mesh", mesh)]
    if not isinstance(mesh, Mesh):
        mesh = ds.read_obj(mesh)
    if pc2 is not None:
        cache = ds.open_point_cache(pc2)
        frames = cache.frames
    else:
        if frames is None:
            raise _error("usage", "an EXR sequence needs its frames (a range such as 1001-1100)")
        frames = ds.parse_frame_range(frames) if isinstance(frames, str) else list(frames)
        assert exr is not None  # one of exr and pc2 (checked above)
        cache = ds.open_point_cache(exr)
        if fps is None and frames:
            fps = ds.read_point_cache_exr_info(ds.expand_frame_pattern(exr, frames[0])).get(
                "frames_per_second")
    if not frames:
        raise _error("input", f"no frames to export from '{pc2 or exr}'")
    if pc2 is not None:
        read.append(("the PC2", pc2))
    else:
        assert exr is not None
        read += [("a frame of the EXR sequence", ds.expand_frame_pattern(exr, int(f)))
                 for f in frames]
    _files.check_distinct([("the output", out_path)], read,
                          lambda message: _error("usage", message))
    if cache.vertex_count != mesh.vertex_count:
        raise _error("input", f"'{pc2 or exr}' holds {cache.vertex_count} points but the mesh "
                              f"has {mesh.vertex_count} vertices; pass the driven mesh of the "
                              "bake")
    fps = fps or 24.0
    write_mesh_usd(out_path, mesh, frames, cache.read_frames(frames), prim_path=prim_path,
                   fps=fps, up_axis=up_axis, meters_per_unit=1.0, points_up_axis="Z")
    return {"frames": list(frames), "vertices": mesh.vertex_count, "fps": fps}


# ---- The bake command ----------------------------------------------------------------------

def _driver_source(shot: Union[MeshAnimation, _Path], prim_path: Optional[str],
                   frames: Optional[Iterable[SupportsIndex]], space: str, evaluator: Any,
                   batch: int, temporal_warmup: int) -> tuple[MeshAnimation, list[int]]:
    """(the driver animation to read from, the frames to bake). From a USD file, the frames
    read are those the shot planner (plan_shot, as `drivenshape bake` plans) evaluates: the
    frames to bake and the history and warm-up frames before each batch, so that a bake of any
    sub-range is the command line's bake of those frames."""
    import drivenshape as ds

    if isinstance(shot, MeshAnimation):
        return shot, [int(f) for f in frames] if frames is not None else list(shot.frames)
    if prim_path is None:
        raise _error("usage", "bake() needs prim_path with a USD path")
    available = mesh_time_samples(shot, prim_path)
    wanted = [int(f) for f in frames] if frames is not None else available
    plan = ds.plan_shot(evaluator, wanted, available, batch=batch,
                        temporal_warmup=temporal_warmup)
    needed = sorted({frame for step in plan for frame in step.solve_frames})
    return read_mesh_animation(shot, prim_path, needed or wanted, space), wanted


def _check_driver_scale(db: Database, source: MeshAnimation, frames: list[int],
                        force: bool) -> list[str]:
    """`drivenshape bake`'s driver check (check_driver_scale: units, another character):
    Error (input) for a finding it refuses unless `force`; returns the warnings."""
    import drivenshape as ds

    found: list[str] = []
    for refuse, message in ds.check_driver_scale(db, source.cache(), frames):
        if refuse and not force:
            raise _error("input", f"{message} (force=True, --force, bakes it anyway)")
        found.append("forced: " + message if refuse else message)
    return found


@contextlib.contextmanager
def _warnings_kept(found: list[str]) -> Iterator[None]:
    """Collects the Python warnings raised inside (the evaluator's) into `found`, for the
    report, and raises them again after it for the caller."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        yield
    for warning in caught:
        found.append(str(warning.message))
        warnings.warn_explicit(warning.message, warning.category, warning.filename,
                               warning.lineno)


def _bake_inputs(database: Union[Database, _Path], database_path: Optional[_Path],
                 shot: Union[MeshAnimation, _Path],
                 inputs: Iterable[_files.NamedPath]) -> list[_files.NamedPath]:
    """The files a bake reads, named for messages."""
    named: list[_files.NamedPath] = list(inputs)
    for source in (database, database_path):
        if isinstance(source, (str, os.PathLike)):
            named.append(("the database", source))
    if isinstance(shot, MeshAnimation):
        named += [("a layer of the driver stage", layer) for layer in shot.layers]
    else:
        named.append(("the driver stage", shot))
    return named


def _write_report(path: _Path, evaluator: Any, records: list[FrameRecord], driver: str,
                  output: _Path, seconds: Mapping[str, float], found: list[str], batch: int,
                  temporal_warmup: int, fps: float) -> None:
    """The bake report `drivenshape bake --report` writes (bake_report), atomically."""
    import drivenshape as ds

    text = ds.bake_report(evaluator, records, driver=driver, output=os.path.abspath(output),
                          seconds=dict(seconds), warnings=found, batch=batch,
                          temporal_warmup=temporal_warmup, frames_per_second=fps)
    try:
        _files.write_text_atomically(path, text)
    except OSError as error:
        raise _error("output", f"cannot write the report '{os.fspath(path)}': {error}")


def bake(database: Union[Database, _Path], shot: Union[MeshAnimation, _Path], out_path: _Path,
         *, prim_path: Optional[str] = None, frames: Optional[Iterable[SupportsIndex]] = None,
         device: Union[Device, str] = "auto", settings: Optional[EvaluatorSettings] = None,
         out_prim: str = "/Garment/Mesh", up_axis: Optional[str] = None,
         meters_per_unit: Optional[float] = None, fps: Optional[float] = None,
         space: str = "local", check_topology: bool = True, batch: int = 64,
         temporal_warmup: int = 8, database_path: Optional[_Path] = None,
         report_path: Optional[_Path] = None, force: bool = False,
         inputs: Iterable[_files.NamedPath] = ()) -> BakeSummary:
    """The shot from a USD driver to a USD cloth: reads the driver prim's points (`shot` is a
    MeshAnimation, or a USD path with `prim_path`), checks them against the database's driver
    mesh (vertex count, faces, and `drivenshape bake`'s scale check: a driver in other units or
    of another character is refused unless `force`), evaluates `frames` (default: every time
    sample) as `drivenshape bake` does (evaluate_cache: the shot planner's batches of `batch`
    frames with their history and warm-up, read from the stage's samples before each batch, so
    any sub-range is bitwise the command line's bake of those frames) and writes the cloth with
    write_mesh_usd, and with `report_path` the bake report `drivenshape bake --report` writes
    (the frames' records and the shot's coverage verdict). A MeshAnimation is the source as
    read: give it the frames before `frames` for their history. up_axis, meters_per_unit and
    fps default to the input stage's (Z, 1 and its time codes per second where it authors
    none); given, they must be positive finite numbers. The cloth comes out in the driver's axis
    (the input stage's upAxis, Z where it authors none); an up_axis other than that rotates the
    cloth's points to it, exactly (write_mesh_usd's points_up_axis). No output may be one of the
    files read (the database, the driver stage and its layers, `inputs`: (name, path) pairs),
    compared by name and by file identity. Returns a dict summary (frames, device, note,
    seconds per stage, records, warnings, verdict: the report's coverage object or None).

    The cloth prim's customData["drivenshape"] records where it came from: tool_version,
    database_content_hash, evaluator_settings_hash (Evaluator.settings_hash: the model and its
    settings; an EXR bake's settings_hash also covers its file options), the database file
    (`database`, or `database_path` when `database` is a loaded Database), the driver file and
    prim, and the device."""
    import drivenshape as ds

    outputs: list[_files.NamedPath] = [("the output", out_path)]
    if report_path is not None:
        outputs.append(("the report", report_path))
    refuse = lambda message: _error("usage", message)  # noqa: E731
    _files.check_distinct(outputs, _bake_inputs(database, database_path, shot, inputs), refuse)
    _check_output(out_path)  # before the evaluation, not after it
    _check_prim_path(out_prim)
    fps = None if fps is None else _scene_number(fps, "fps")
    meters_per_unit = (None if meters_per_unit is None
                       else _scene_number(meters_per_unit, "meters per unit"))
    db = database if isinstance(database, ds.Database) else ds.load_database(database)
    target = device if isinstance(device, ds.Device) else ds.open_device(device)
    built: list[str] = []  # the evaluator's warnings
    with _warnings_kept(built):
        evaluator = ds.Evaluator(db, settings or ds.EvaluatorSettings(), target)
    source, wanted = _driver_source(shot, prim_path, frames, space, evaluator, batch,
                                    temporal_warmup)
    _files.check_distinct(outputs, _bake_inputs(database, database_path, source, inputs),
                          refuse)
    if check_topology or source.vertex_count != db.driver_vertex_count:
        check_driver(source, db.driver_mesh)  # the vertex count is never optional
    # The bake's warnings in the command line's order: the driver's, the evaluator's.
    found = _check_driver_scale(db, source, wanted, force)
    for message in found:
        warnings.warn(message)
    found += built
    with _warnings_kept(found):
        cloth, records, seconds = ds.evaluate_cache(evaluator, source.cache(), wanted,
                                                    batch=batch, temporal_warmup=temporal_warmup,
                                                    with_seconds=True)
    driver_axis = source.up_axis or DEFAULT_UP_AXIS
    fps = fps or source.time_codes_per_second
    write_mesh_usd(out_path, db.driven_mesh, wanted, cloth, prim_path=out_prim, fps=fps,
                   up_axis=up_axis or driver_axis, meters_per_unit=meters_per_unit or
                   source.meters_per_unit or DEFAULT_METERS_PER_UNIT,
                   points_up_axis=driver_axis,
                   provenance=_provenance(db, evaluator, database_path or database, source))
    if report_path is not None:
        _write_report(report_path, evaluator, records, f"{source.path}:{source.prim_path}",
                      out_path, seconds, found, batch, temporal_warmup, fps)
    return {"frames": wanted, "device": evaluator.device_name, "seconds": seconds,
            "records": records, "note": target.note, "warnings": found,
            "verdict": ds.shot_verdict(evaluator, records)}


def _provenance(db: Database, evaluator: Any, database: object,
                source: MeshAnimation) -> dict[str, str]:
    """The cloth prim's customData["drivenshape"] (see bake)."""
    import drivenshape as ds

    return {"tool_version": ds.__version__,
            "database_content_hash": format(db.content_hash, "016x"),
            "evaluator_settings_hash": format(evaluator.settings_hash, "016x"),
            "database": _source_name(database),
            "driver": f"{_source_name(source.path)}:{source.prim_path}",
            "device": evaluator.device_name}


def _source_name(source: object) -> str:
    """An absolute file name for the provenance, or "(in memory)" for an object."""
    return os.path.abspath(source) if isinstance(source, (str, os.PathLike)) else "(in memory)"


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m drivenshape.usd",
        description="USD in and out for drivenshape.",
        epilog="Exit codes: 0 ok, 2 usage, 3 input, 4 output, 5 OpenCL device, 6 numerical.")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    _bake_parser(commands)
    _export_parser(commands)
    return parser


def _bake_parser(commands: Any) -> None:
    """`bake`'s options: its own, the settings table's and the layers'."""
    bake_parser = commands.add_parser(
        "bake", help="bake a driver UsdGeomMesh into a cloth UsdGeomMesh",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Reads the time-sampled points of the driver mesh --prim in --usd, checks its "
                    "vertex count and faces against the database's driver mesh, evaluates every "
                    "frame exactly as `drivenshape bake` does (the same history frames before "
                    "each batch: bitwise the same cloth for the same frames, settings and "
                    "device) and writes the cloth as a UsdGeomMesh with one "
                    "time sample of points and extent per frame, the faces, UVs and groups of "
                    "the database's driven rest mesh, and the stage's upAxis and metersPerUnit. "
                    "Points are never rescaled or interpolated.",
        epilog="Exit codes: 0 ok, 2 usage, 3 input (a missing file or prim, a wrong vertex "
               "count or topology, a non-finite point, a driver in other units), 4 output, 5 "
               "OpenCL device, 6 numerical. An output that is one of the inputs (by name or "
               "file identity) and an --fps or --meters-per-unit that is not a positive number "
               "are usage errors.\n\n"
               "example:\n  python -m drivenshape.usd bake --db sleeve.dsdb --usd shot.usda "
               "--prim /Character/Arm --out cloth.usdc --frames 1001-1100")
    add = bake_parser.add_argument
    add("--db", metavar="DB", required=True, help="database from `drivenshape db build`")
    add("--usd", metavar="STAGE", required=True,
        help="stage holding the driver animation (.usd, .usda, .usdc)")
    add("--prim", metavar="PATH", required=True,
        help="path of the driver UsdGeomMesh, e.g. /Character/Legs")
    add("--out", "-o", metavar="OUT", required=True,
        help="cloth stage to write (.usd, .usda or .usdc)")
    add("--frames", metavar="RANGE",
        help="frames to bake: 1001-1100, 1001-1100x2, 1001,1005 [default: every whole-frame "
             "time sample of the prim's points]")
    add("--device", metavar="SPEC", default="auto",
        help="auto, host, cpu, gpu, an index or a name substring [default: auto]")
    add("--out-prim", metavar="PATH", default="/Garment/Mesh",
        help="cloth prim path [default: /Garment/Mesh]")
    add("--up-axis", choices=("Y", "Z"),
        help="upAxis of the output; the cloth's points are rotated to it from the input stage's "
             "axis when they differ (Z -> Y: (x, y, z) -> (x, z, -y), exact) [default: the input "
             "stage's, else Z]")
    add("--meters-per-unit", metavar="M", type=float,
        help="metersPerUnit of the output [default: the input stage's, else 1]")
    add("--fps", metavar="FPS", type=float,
        help="time codes per second of the output and the wind's time [default: the input "
             "stage's]")
    add("--space", choices=("local", "world"), default="local",
        help="driver points as authored (local) or through the prim's transform (world) "
             "[default: local]")
    add("--ignore-topology", action="store_true",
        help="accept a driver whose faces differ from the database's (the vertex count must "
             "still match)")
    _add_settings(add)
    add("--report", metavar="REPORT.json",
        help="the bake report, as `drivenshape bake --report` writes it (every frame's record "
             "and the shot's coverage verdict) [default: OUT's name with .report.json]")
    add("--no-report", action="store_true", help="write no report")
    add("--force", action="store_true",
        help="bake a driver the scale check refuses (other units, another character), as "
             "`drivenshape bake --force`")
    add("--quiet", action="store_true", help="print nothing but errors")


def _export_parser(commands: Any) -> None:
    """`export`'s options."""
    export_parser = commands.add_parser(
        "export", help="write a drivenshape result (EXR sequence or PC2) as a UsdGeomMesh",
        description="Writes a UsdGeomMesh with time-sampled points and extents: the faces, UVs "
                    "(primvars:st) and groups (UsdGeomSubsets) of the driven rest OBJ, the "
                    "points of a point-cache EXR sequence written by `drivenshape bake` or of a "
                    "PC2 file (e.g. `drivenshape export --pc2`). Time codes are frame numbers; "
                    "metersPerUnit is 1.",
        epilog="Exit codes: 0 ok, 2 usage, 3 input, 4 output.")
    add = export_parser.add_argument
    add("--mesh", required=True, help="driven rest OBJ (faces, UVs, groups)")
    source = export_parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--exr", metavar="PATTERN",
                        help="point-cache EXR sequence, e.g. out/pants.####.exr (needs --frames)")
    source.add_argument("--pc2", metavar="FILE", help="PC2 point cache (every whole-frame "
                                                      "sample)")
    add("--frames", metavar="RANGE", help="frames of the EXR sequence: 1001-1100, 1001-1100x2")
    add("--fps", type=float,
        help="time codes per second (default: the EXR's framesPerSecond, else 24)")
    add("--prim", default="/Garment/Mesh", help="mesh prim path [default: /Garment/Mesh]")
    add("--up-axis", choices=("Y", "Z"), default="Z",
        help="stage upAxis: Z (default) keeps the points as they are, the axis of drivenshape's "
             "caches; Y rotates them to Y up, (x, y, z) -> (x, z, -y), exactly")
    add("-o", "--output", required=True, help="OUT.usd, .usda or .usdc")


def _export_main(args: argparse.Namespace) -> int:
    if args.exr and not args.frames:
        raise _error("usage", "--exr needs --frames RANGE")
    done = export(args.mesh, args.output, exr=args.exr, frames=args.frames, pc2=args.pc2,
                  fps=args.fps, prim_path=args.prim, up_axis=args.up_axis)
    frames = done["frames"]
    print(f"wrote {args.output}: {args.prim}, {done['vertices']} points, {len(frames)} time "
          f"samples ({frames[0]:g}-{frames[-1]:g}) at {done['fps']:g} fps, {args.up_axis} up")
    return EXIT_OK


# The bake settings that evaluate_cache's loop takes beside the evaluator's.
_LOOP_SETTINGS: tuple[str, ...] = ("batch", "temporal_warmup")
# The settings loaded from the file an option names.
_LOADERS: dict[str, str] = {"binding_mask": "load_binding_mask", "regions": "load_regions"}


def _setting_rows() -> list[dict[str, Any]]:
    """The settings table's rows this tool takes: `drivenshape bake`'s evaluator and layer
    options (--mix, --wind-*), and the batch and warm-up of its loop."""
    import drivenshape as ds

    return [row for row in ds.settings_table() if row["flag"] and
            (row["scope"] in ("evaluator", "layer") or row["key"] in _LOOP_SETTINGS)]


def _add_settings(add: Callable[..., argparse.Action]) -> None:
    """The options, help and defaults of the settings table (docs/commands.md, Settings), as
    `drivenshape bake` has them."""
    for row in _setting_rows():
        help_text = row["help"].replace("%", "%%")
        if row["type"] == "bool":
            add(row["flag"], dest=row["key"], action="store_false" if row["default"] else
                "store_true", help=("turns off " if row["default"] else "turns on ") + help_text)
        elif row["type"] == "object":
            add(row["flag"], dest=row["key"], metavar=row["value_name"], help=help_text)
        else:
            kind = {"int": int, "number": float}.get(row["type"], str)
            add(row["flag"], dest=row["key"], metavar=row["value_name"], type=kind,
                default=row["default"], choices=row["choices"] or None,
                help=f"{help_text} [default: {row['default_text'] or 'none'}]")


def _settings(args: argparse.Namespace, db: Database) -> EvaluatorSettings:
    import drivenshape as ds

    layers = ds.load_layers(db, frames_per_second=args.fps or 24.0,
                            **{row["key"]: getattr(args, row["key"]) for row in _setting_rows()
                               if row["scope"] == "layer"})  # checked by the settings table
    settings = ds.EvaluatorSettings(layers=layers)
    for row in _setting_rows():
        key = row["key"]
        value = getattr(args, key)
        if key in _LOADERS:
            value = getattr(ds, _LOADERS[key])(value, db) if value else None
        if row["scope"] == "evaluator":
            setattr(settings, key, value)  # checked by the settings table
    return settings


def _layer_inputs(args: argparse.Namespace) -> list[_files.NamedPath]:
    """The files `bake`'s options name besides --db and --usd (mix, maps, mask, regions)."""
    options = [("--mix", args.mix_cache), ("--mix-weight", args.mix_weight),
               ("--wind-weight", args.wind_weight)]
    options += [(row["flag"], getattr(args, row["key"])) for row in _setting_rows()
                if row["key"] in _LOADERS]
    return [(option, path) for option, path in options if path]


def _report_path(args: argparse.Namespace) -> Optional[str]:
    """--report, else OUT's name with .report.json (as `drivenshape bake` names its report);
    None with --no-report."""
    if args.no_report:
        if args.report:
            raise _error("usage", "--report and --no-report contradict each other")
        return None
    return str(args.report or os.path.splitext(args.out)[0] + ".report.json")


def _bake_main(args: argparse.Namespace) -> int:
    import time

    import drivenshape as ds

    if args.batch < 1 or args.temporal_warmup < 0:
        raise _error("usage", "--batch must be at least 1 and --temporal-warmup at least 0")
    for option, value in (("--fps", args.fps), ("--meters-per-unit", args.meters_per_unit)):
        if value is not None:
            _scene_number(value, option)
    frames = ds.parse_frame_range(args.frames) if args.frames else None
    start = time.perf_counter()
    report = _report_path(args)
    outputs = [("--out", args.out)] + ([("--report", report)] if report else [])
    inputs = [("--db", args.db), ("--usd", args.usd)] + _layer_inputs(args)
    _files.check_distinct(outputs, inputs, lambda message: _error("usage", message))
    db = ds.load_database(args.db)
    # The output's time codes and the wind's time (frame / fps) follow the stage's rate.
    args.fps = args.fps or float(_open_mesh(args.usd, args.prim)[0].GetTimeCodesPerSecond())
    settings = _settings(args, db)
    # The evaluator's warnings (Python warnings) as `drivenshape bake` prints its own: one
    # "warning:" line each on stderr, also with --quiet.
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = bake(db, args.usd, args.out, prim_path=args.prim, frames=frames,
                      space=args.space, device=args.device, settings=settings,
                      out_prim=args.out_prim, up_axis=args.up_axis,
                      meters_per_unit=args.meters_per_unit, fps=args.fps,
                      check_topology=not args.ignore_topology, batch=args.batch,
                      temporal_warmup=args.temporal_warmup, database_path=args.db,
                      report_path=report, force=args.force, inputs=inputs)
    for warning in caught:
        print(f"warning: {warning.message}", file=sys.stderr)
    if result["note"] and not args.quiet:
        print(f"warning: {result['note']}", file=sys.stderr)
    if not args.quiet:
        baked = result["frames"]
        seconds = time.perf_counter() - start
        print(f"wrote {args.out}: {args.out_prim}, {db.driven_vertex_count} points, "
              f"{len(baked)} frames ({ds.format_frame_range(baked)}) in {seconds:.2f} s on "
              f"{result['device']}")
        if result["verdict"]:
            print(f"verdict: {result['verdict']['verdict']}")
    return EXIT_OK


def main(argv: Optional[Sequence[str]] = None) -> int:
    args = _parser().parse_args(argv)
    try:
        return _export_main(args) if args.command == "export" else _bake_main(args)
    except Error as error:
        print(f"drivenshape.usd: {error.kind} error: {error}", file=sys.stderr)
        return error.code if error.code > 1 else 1


if __name__ == "__main__":
    sys.exit(main())
