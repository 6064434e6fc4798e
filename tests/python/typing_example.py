# SPDX-License-Identifier: Apache-2.0
"""The module's main API as a typed program: `mypy --strict` must accept it against the shipped
stubs and the annotations of drivenshape.usd (the CTest python_typing, and python_wheel against
the installed package), and it runs on the bundled sleeve sample, so the types describe code
that works.

  python tests/python/typing_example.py tests/data/sleeve OUT_FOLDER
"""
from __future__ import annotations

import io
import sys
from pathlib import Path

import numpy as np
import numpy.typing as npt

import drivenshape as ds
from drivenshape import usd


def build(data: Path, out: Path) -> ds.Database:
    """A small database from the sample's training clip, saved and loaded back."""
    log = io.StringIO()
    database = ds.build_database(data / "driver_rest.obj", str(data / "driven_rest.obj"),
                                 data / "train.driver.pc2", data / "train.driven.pc2", count=8,
                                 log=log)
    assert log.getvalue() and database.shape_count == 8
    database.save(out / "sleeve.dsdb")
    loaded = ds.load_database(out / "sleeve.dsdb")
    assert loaded.content_hash == database.content_hash
    return loaded


def evaluate(database: ds.Database, data: Path) -> tuple[npt.NDArray[np.float32], list[int]]:
    """The test clip's first frames, whole and in plan_shot's batches."""
    settings = ds.EvaluatorSettings(weight_mode="model", skin_offset=0.003)
    settings.resolve = True
    evaluator = ds.Evaluator(database, settings, ds.open_device("host"))
    driver, start, _rate = ds.read_pc2(data / "test.driver.pc2")
    frames = list(range(int(start), int(start) + 6))
    cloth, records = evaluator.evaluate(frames, driver[:6])
    predicted: list[float] = [record.predicted_error for record in records]
    assert len(predicted) == 6 and cloth.dtype == np.float32
    seconds: dict[str, float] = evaluator.last_stage_seconds
    assert seconds

    cache = ds.open_point_cache(data / "test.driver.pc2")
    plan = ds.plan_shot(evaluator, frames, range(cache.frames[0], cache.frames[-1] + 1), batch=4)
    assert [frame for batch in plan for frame in batch.frames] == frames
    again, _records = ds.evaluate_cache(evaluator, cache, frames, batch=4)
    _cloth, _records, stage_seconds = ds.evaluate_cache(evaluator, cache, frames, batch=4,
                                                        with_seconds=True)
    assert set(stage_seconds) == set(seconds)
    out = np.empty((1, evaluator.driven_vertex_count, 3), np.float32)
    evaluator.reset_temporal_bound()
    evaluator.evaluate_into(frames[0], cache.read(frames[0]), out)
    return again, frames


def write_and_read(database: ds.Database, cloth: npt.NDArray[np.float32], frames: list[int],
                   out: Path) -> None:
    """The cloth as PC2 and as point-cache EXRs, read back."""
    ds.write_pc2(out / "cloth.pc2", cloth, start_frame=frames[0])
    samples, start, _rate = ds.read_pc2(out / "cloth.pc2")
    assert start == frames[0] and samples.shape == cloth.shape
    topology = database.driven_mesh.topology_hash
    pattern = str(out / "cloth.####.exr")
    for index, frame in enumerate(frames):
        ds.write_point_cache_exr(ds.expand_frame_pattern(pattern, frame), cloth[index], frame=frame,
                                 topology_hash=topology)
    last = Path(ds.expand_frame_pattern(pattern, frames[-1]))
    positions, header = ds.read_point_cache_exr(last, expected_topology=topology)
    assert header["frame"] == frames[-1] and positions.shape == cloth[-1].shape
    cache = ds.open_point_cache(out / "cloth.####.exr", expected_topology=topology)
    assert ds.format_frame_range(cache.frames) == ds.format_frame_range(frames)
    positions = ds.PointCache.from_array(cloth, start_frame=frames[0]).read_frames(frames)
    triangles: npt.NDArray[np.int32] = database.driven_mesh.triangles
    assert positions.shape == cloth.shape and triangles.shape[1] == 3


def usd_round_trip(database: ds.Database, cloth: npt.NDArray[np.float32], frames: list[int],
                   out: Path) -> None:
    """The cloth as a USD mesh (drivenshape.usd), read back exactly."""
    usd.write_mesh_usd(out / "cloth.usda", database.driven_mesh, frames, cloth, fps=24.0,
                       provenance={"tool_version": ds.__version__})
    shot: usd.MeshAnimation = usd.read_mesh_animation(out / "cloth.usda", "/Garment/Mesh")
    usd.check_driver(shot, database.driven_mesh)  # the driven mesh's faces, as written
    assert shot.frames == frames and np.array_equal(shot.positions, cloth)
    assert shot.cache().read_frames(frames).shape == cloth.shape


def main(data: Path, out: Path) -> None:
    database = build(data, out)
    cloth, frames = evaluate(database, data)
    write_and_read(database, cloth, frames, out)
    usd_round_trip(database, cloth, frames, out)
    print(f"typing_example: {len(frames)} frames of {database.driven_vertex_count} vertices")


if __name__ == "__main__":
    main(Path(sys.argv[1]), Path(sys.argv[2]))
