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
    PointCache,
    RegionSet,
    __version__,
    build_database,
    convert_up_axis,
    expand_frame_pattern,
    format_frame_range,
    list_devices,
    load_binding_mask,
    load_database,
    load_layers,
    load_regions,
    open_device,
    open_point_cache,
    parse_binding_mask,
    parse_frame_range,
    parse_regions,
    read_obj,
    read_pc2,
    read_point_cache_exr,
    read_point_cache_exr_info,
    save_database,
    settings_table,
    write_obj,
    write_pc2,
    write_point_cache_exr,
)

import numpy as _np


def evaluate_cache(evaluator, cache, frames, batch=64, temporal_warmup=8, with_seconds=False):
    """Evaluates `frames` of a PointCache the way `drivenshape bake` does, without files:
    batches of `batch` frames, each starting the temporal bound afresh after up to
    `temporal_warmup` of the cache's frames before it (only with max_weight_change > 0, as the
    bake) and at least the pose model's history (Evaluator.history_frames), with a new batch at
    every gap in the frame numbers when there is history, so the cloth is bitwise the bake's. Returns (cloth (F, Vd, 3) float32, [FrameRecord])
    and, with with_seconds, the seconds per stage summed over the batches."""
    if batch < 1 or temporal_warmup < 0:
        error = Error(f"evaluate_cache: batch ({batch}) must be at least 1 and temporal_warmup "
                      f"({temporal_warmup}) at least 0")
        error.kind, error.code = "usage", 2
        raise error
    frames = [frames] if isinstance(frames, (int, _np.integer)) else list(frames)
    evaluator.check_frames(frames)  # drivenshape.Error (usage) for a frame outside C++ ints
    frames = [int(f) for f in frames]
    history = evaluator.history_frames
    warm_frames = max(temporal_warmup if evaluator.settings.max_weight_change > 0 else 0, history)
    cache_frames = cache.frames if warm_frames else []
    cloth = _np.empty((len(frames), evaluator.driven_vertex_count, 3), dtype=_np.float32)
    records, seconds = [], {}
    starts = [i for i in range(len(frames))
              if i == 0 or (history > 0 and frames[i] != frames[i - 1] + 1)]
    batches = []
    for s, e in zip(starts, starts[1:] + [len(frames)]):
        batches += [(b, min(e, b + batch)) for b in range(s, e, batch)]
    for begin, end in batches:
        chunk = frames[begin:end]
        warm = [f for f in cache_frames if chunk[0] - warm_frames <= f < chunk[0]]
        evaluator.reset_temporal_bound()
        driver = cache.read_frames(warm + chunk)
        records += evaluator.evaluate_into(warm + chunk, driver, cloth[begin:begin + len(chunk)],
                                           warmup=len(warm))
        for stage, value in evaluator.last_stage_seconds.items():
            seconds[stage] = seconds.get(stage, 0.0) + value
    return (cloth, records, seconds) if with_seconds else (cloth, records)


for _type in (BindingMask, Database, Device, Error, Evaluator, EvaluatorSettings, FrameRecord,
              LayerSettings, Mesh, PointCache, RegionSet):
    _type.__module__ = __name__
del _type

__all__ = [
    "BindingMask", "Database", "Device", "Error", "Evaluator", "EvaluatorSettings", "FrameRecord",
    "LayerSettings", "Mesh", "PointCache", "RegionSet", "__version__", "build_database",
    "convert_up_axis", "evaluate_cache", "expand_frame_pattern", "format_frame_range",
    "list_devices", "load_binding_mask", "load_database", "load_layers", "load_regions",
    "open_device", "open_point_cache", "parse_binding_mask", "parse_frame_range", "parse_regions",
    "read_obj", "read_pc2", "read_point_cache_exr", "read_point_cache_exr_info", "save_database",
    "settings_table", "write_obj", "write_pc2", "write_point_cache_exr",
]
