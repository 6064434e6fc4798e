# SPDX-License-Identifier: Apache-2.0
"""Wrong uses of the module that its stubs must reject: the CTest python_typing runs mypy on
this file and passes only when mypy reports an error on exactly the lines marked
`# wrong: CODE` (CODE being mypy's error code), and on no other line. Never run.

Without the stubs (every binding `typing.Any`) none of these would be seen, nor the wrong uses
of drivenshape.usd and drivenshape.qc without their annotations.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

import drivenshape as ds
from drivenshape import qc, usd


def wrong(data: Path) -> None:
    database = ds.load_database(data / "sleeve.dsdb")
    ds.load_database(42)  # wrong: arg-type
    evaluator = ds.Evaluator(database, "defaults", ds.open_device("host"))  # wrong: arg-type
    driver, start, rate = ds.read_pc2(data / "test.driver.pc2")
    cloth, records = evaluator.evaluate("1-10", driver)  # wrong: arg-type
    first: int = records[0]  # wrong: assignment
    records[0].weights.upper()  # wrong: attr-defined
    ds.EvaluatorSettings(weight_mode="fast")  # wrong: arg-type
    ds.EvaluatorSettings(skin_ofset=0.003)  # wrong: call-arg
    settings = ds.EvaluatorSettings()
    settings.resolve = "yes"  # wrong: assignment
    ds.plan_shot(database, [1, 2, 3], range(1, 4))  # wrong: arg-type
    ds.write_obj(data / "out.obj", database)  # wrong: arg-type
    out: list[float] = ds.convert_up_axis(driver, "Z", "Y")  # wrong: assignment
    ds.write_point_cache_exr(data / "out.exr", cloth[0], frame=1.5)  # wrong: arg-type
    ds.read_point_cache_exr(data / "out.exr")[1].shape  # wrong: attr-defined
    frames: list[int] = ds.open_point_cache(data / "x.pc2").frame  # wrong: attr-defined
    np.float32(start + rate)


def wrong_usd_qc(data: Path, database: ds.Database) -> None:
    shot = usd.read_mesh_animation(data / "shot.usda", "/Arm", frames="1-10")  # wrong: arg-type
    count: str = shot.vertex_count  # wrong: assignment
    usd.write_mesh_usd(data / "cloth.usda", database.driven_mesh, shot.frames, shot.positions,
                       fps="24")  # wrong: arg-type
    no_indices = {"counts": [3]}
    usd.write_mesh_usd(data / "cloth.usda", no_indices, [1], shot.positions)  # wrong: arg-type
    summary = usd.bake(database, shot, data / "cloth.usdc", device=0)  # wrong: arg-type
    summary["record"]  # wrong: typeddict-item
    usd.export(database.driven_mesh, data / "cloth.usda", pc2=data / "x.pc2",
               fps="24")  # wrong: arg-type
    status: str = qc.main(["--report", "cloth.report.json", "-o", "qc"])  # wrong: assignment
