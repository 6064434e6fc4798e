# SPDX-License-Identifier: Apache-2.0
"""drivenshape: data-driven cloth (DrivenShape, Kim & Vendrovsky 2008) evaluated in memory.

The C++ library behind the `drivenshape` command line, for Python and Blender: read meshes and
point caches, build or load a database, and evaluate frames of driver positions into cloth
positions with the same Evaluator the command line's `bake` runs (bitwise the same frames).

    import numpy as np
    import drivenshape as ds

    db = ds.load_database("sleeve.dsdb")
    device = ds.open_device("auto")             # or "host"
    evaluator = ds.Evaluator(db, ds.EvaluatorSettings(), device)
    driver, start, _ = ds.read_pc2("shot.driver.pc2")           # (F, Vp, 3) float32
    frames = [int(start) + i for i in range(len(driver))]
    cloth, records = evaluator.evaluate(frames, driver)         # (F, Vd, 3) float32

Arrays are numpy float32, shaped (frames, vertices, 3). C-contiguous float32 inputs are read in
place and outputs own the C++ memory they were computed in: see docs/python.md for what is
copied and what is not, threads and the GIL, and `drivenshape.usd` for USD in and out.
Errors are `drivenshape.Error` (a RuntimeError) with `.kind` ('usage', 'input', 'output',
'device', 'numerical', ...) and `.code` (the command line's exit code).
"""

from __future__ import annotations

import os as _os
import typing as _typing
from collections.abc import Sequence as _Sequence

from ._drivenshape import (  # noqa: F401
    BindingMask,
    Database,
    Device,
    Error,
    Evaluator,
    EvaluatorSettings,
    FrameRecord,
    LayerSettings,
    Mesh,
    PlaybackPlanner,
    PointCache,
    RegionSet,
    BatchPlan,
    __version__,
    bake_report,
    build_database,
    check_driver_scale,
    convert_up_axis,
    edge_strain,
    expand_frame_pattern,
    format_frame_range,
    frame_strain,
    list_devices,
    load_binding_mask,
    load_database,
    load_layers,
    load_regions,
    merge_bake_reports,
    open_device,
    open_point_cache,
    parse_binding_mask,
    parse_frame_range,
    parse_regions,
    plan_shot,
    plan_simulation,
    read_obj,
    read_pc2,
    read_point_cache_exr,
    read_point_cache_exr_info,
    save_database,
    settings_table,
    shot_verdict,
    simulation_runs,
    splice,
    splice_files,
    verdict_holds,
    write_obj,
    write_pc2,
    write_point_cache_exr,
)

import numpy as _np
import numpy.typing as _npt

# evaluate_cache's frames: one frame number, or a sequence or an integer array of them.
_FrameList = _typing.Union[int, "_np.integer[_typing.Any]", _Sequence[_typing.SupportsIndex],
                           "_npt.NDArray[_np.integer[_typing.Any]]"]
_Cloth = _npt.NDArray[_np.float32]


def _memory_bytes() -> int:
    """The machine's physical memory in bytes (0 where the system does not say)."""
    try:
        return int(_os.sysconf("SC_PHYS_PAGES")) * int(_os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return 0


def _check_cloth_memory(frames: int, vertices: int) -> None:
    """Error (usage) before anything is allocated when the cloth of `frames` frames of
    `vertices` vertices (float32 xyz) would not fit in the machine's memory."""
    need = frames * vertices * 3 * 4
    have = _memory_bytes()
    if have and need > have:
        error = Error(f"evaluating {frames} frames of {vertices} cloth vertices needs "
                      f"{need / 2**30:.1f} GiB for the cloth alone, more than this machine's "
                      f"{have / 2**30:.1f} GiB of memory; evaluate the frames in parts")
        error.kind = "usage"  # type: ignore[misc]
        error.code = 2  # type: ignore[misc]
        raise error


@_typing.overload
def evaluate_cache(evaluator: Evaluator, cache: PointCache, frames: _FrameList, batch: int = 64,
                   temporal_warmup: int = 8, with_seconds: _typing.Literal[False] = False
                   ) -> tuple[_Cloth, list[FrameRecord]]: ...


@_typing.overload
def evaluate_cache(evaluator: Evaluator, cache: PointCache, frames: _FrameList, batch: int = 64,
                   temporal_warmup: int = 8, *, with_seconds: _typing.Literal[True]
                   ) -> tuple[_Cloth, list[FrameRecord], dict[str, float]]: ...


@_typing.overload
def evaluate_cache(evaluator: Evaluator, cache: PointCache, frames: _FrameList, batch: int = 64,
                   temporal_warmup: int = 8, with_seconds: bool = False
                   ) -> (tuple[_Cloth, list[FrameRecord]]
                         | tuple[_Cloth, list[FrameRecord], dict[str, float]]): ...


def evaluate_cache(evaluator: Evaluator, cache: PointCache, frames: _FrameList, batch: int = 64,
                   temporal_warmup: int = 8, with_seconds: bool = False
                   ) -> (tuple[_Cloth, list[FrameRecord]]
                         | tuple[_Cloth, list[FrameRecord], dict[str, float]]):
    """Evaluates `frames` (any order) of a PointCache the way `drivenshape bake` does, without
    files, in the batches plan_shot gives: each starts the evaluator's temporal state afresh
    after its warm-up frames from the cache (the pose model's history, and `temporal_warmup`
    frames with max_weight_change > 0), so every frame is bitwise the bake's. Returns
    (cloth (F, Vd, 3) float32, [FrameRecord]) and, with with_seconds, the seconds per stage
    summed over the batches. Frames whose cloth would not fit in the machine's memory are
    refused (drivenshape.Error, usage) before anything is allocated."""
    if not isinstance(frames, (int, _np.integer)):
        _check_cloth_memory(len(frames) if hasattr(frames, "__len__") else 0,
                            evaluator.driven_vertex_count)
    frame_list: list[_typing.SupportsIndex] = (
        [frames] if isinstance(frames, (int, _np.integer)) else list(frames))
    _check_cloth_memory(len(frame_list), evaluator.driven_vertex_count)
    evaluator.check_frames(frame_list)  # drivenshape.Error (usage) for a frame outside C++ ints
    plan = plan_shot(evaluator, frame_list, cache.frames, batch=batch,
                     temporal_warmup=temporal_warmup)
    cloth = _np.empty((len(frame_list), evaluator.driven_vertex_count, 3), dtype=_np.float32)
    records: list[FrameRecord] = []
    seconds: dict[str, float] = {}
    for step in plan:
        solve = step.solve_frames
        evaluator.reset_temporal_bound()
        records += evaluator.evaluate_into(solve, cache.read_frames(solve),
                                           cloth[step.first:step.first + len(step.frames)],
                                           warmup=len(step.warmup))
        for stage, value in evaluator.last_stage_seconds.items():
            seconds[stage] = seconds.get(stage, 0.0) + value
    return (cloth, records, seconds) if with_seconds else (cloth, records)


for _type in (BindingMask, Database, Device, Error, Evaluator, EvaluatorSettings, FrameRecord,
              LayerSettings, Mesh, PlaybackPlanner, PointCache, RegionSet, BatchPlan):
    _type.__module__ = __name__
del _type

__all__ = [
    "BindingMask", "Database", "Device", "Error", "Evaluator", "EvaluatorSettings", "FrameRecord",
    "LayerSettings", "Mesh", "PlaybackPlanner", "PointCache", "RegionSet", "BatchPlan",
    "__version__", "bake_report", "build_database", "check_driver_scale", "convert_up_axis",
    "edge_strain", "evaluate_cache", "expand_frame_pattern",
    "format_frame_range", "frame_strain", "list_devices", "load_binding_mask", "load_database",
    "load_layers", "load_regions", "merge_bake_reports", "open_device", "open_point_cache",
    "parse_binding_mask", "parse_frame_range",
    "parse_regions", "plan_shot", "plan_simulation", "read_obj", "read_pc2", "read_point_cache_exr",
    "read_point_cache_exr_info", "save_database", "settings_table", "shot_verdict",
    "simulation_runs", "splice", "splice_files", "verdict_holds", "write_obj",
    "write_pc2", "write_point_cache_exr",
]
