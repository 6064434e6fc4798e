# SPDX-License-Identifier: Apache-2.0
"""Simulating what the verdict flags from Python (issue 44): plan_simulation gives the plan
`drivenshape simulate` writes, and splice over numpy arrays gives, bit for bit, the frames and
sources the command writes, with the default settings. Blender is the stand-in of the command's
tests (tests/cli/stand_in_blender.cpp, $DS_STAND_IN_BLENDER), run here too to make the windows'
frames: it tests the plumbing; the real runner in Blender is tests/blender's."""

import json
import os
import subprocess
from pathlib import Path

import jsonschema
import numpy as np
import pytest

import drivenshape as ds
from conftest import assert_bitwise, run

FIRST, LAST, VERTICES = 1, 60, 7
FLAGGED = {30, 31, 32, 47}
SCHEMA = json.loads((Path(__file__).resolve().parents[2] / "docs" / "schemas" /
                     "simulate_report.schema.json").read_text())


@pytest.fixture
def shot(tmp_path):
    """A bake of frames 1-60 in tmp_path/out, its report flagging 30-32 and 47, a scene file and
    a runner file (the stand-in checks only that they exist)."""
    (tmp_path / "out").mkdir()
    frames = np.arange(FIRST, LAST + 1, dtype=np.float32)[:, None, None]
    vertex = np.arange(VERTICES, dtype=np.float32)[None, :, None]
    baked = np.concatenate([vertex + 0.1 * frames, np.sin(0.2 * frames + vertex),
                            0.01 * vertex * frames], axis=2).astype(np.float32)
    for i, frame in enumerate(range(FIRST, LAST + 1)):
        ds.write_point_cache_exr(tmp_path / "out" / f"x.{frame:04d}.exr", baked[i], frame=frame,
                                 topology_hash=0x1234, sync=False)
    report = {"coverage": {"tolerance": 0.02},
              "frames": [{"frame": f, "predicted_error": 0.01,
                          "coverage": {"flagged": f in FLAGGED}} for f in range(FIRST, LAST + 1)]}
    (tmp_path / "out" / "x.report.json").write_text(json.dumps(report))
    (tmp_path / "shot.blend").write_text("a scene")
    (tmp_path / "simulate_window.py").write_text("# the runner")
    return tmp_path, baked


def stand_in():
    path = os.environ.get("DS_STAND_IN_BLENDER", "")
    assert os.access(path, os.X_OK), f"the stand-in Blender {path!r} is not built"
    return path


def test_plan_simulation_is_the_commands_plan(cli, shot):
    root, _ = shot
    run([cli, "simulate", "--report", root / "out/x.report.json", "-o", root / "final/x.####.exr",
         "--plan-only", "--merge-gap", "3", "--warmup", "20"])
    written = json.loads((root / "final/x.simulation-plan.json").read_text())
    plan = ds.plan_simulation(str(root / "out/x.report.json"), merge_gap=3, warmup=20)
    assert plan == written
    # The report as a dict plans the same windows; the settings are the table's keywords.
    report = json.loads((root / "out/x.report.json").read_text())
    assert ds.plan_simulation(report, merge_gap=3, warmup=20)["windows"] == written["windows"]
    # 47's warm-up (from 27) overlaps 30-32's window: one window, handing back 30-47.
    assert written["windows"] == [{"warmup_from": 10, "from": 30, "to": 47}]
    with pytest.raises(ds.Error) as error:
        ds.plan_simulation(report, seam=-1)
    assert error.value.kind == "usage" and "--seam" in str(error.value)
    with pytest.raises(ds.Error):
        ds.plan_simulation(report, seams=2)


def test_splice_is_bitwise_the_commands(cli, shot):
    root, baked = shot
    env = dict(os.environ, DRIVENSHAPE_SIMULATE_RUNNER=str(root / "simulate_window.py"))
    result = subprocess.run(
        [cli, "simulate", "--blend", root / "shot.blend", "--object", "pants", "--report",
         root / "out/x.report.json", "--bake", root / "out/x.####.exr", "-o",
         root / "final/x.####.exr", "--blender", stand_in(), "--quiet"],
        capture_output=True, text=True, env=env)
    assert result.returncode == 0, result.stderr
    plan = ds.plan_simulation(root / "out/x.report.json")
    assert plan == json.loads((root / "final/x.simulation-plan.json").read_text())
    # The windows' frames, made by the same stand-in with the runner's command line.
    windows = []
    for window in plan["windows"]:
        pattern = root / "windows" / f"w{window['from']}.####.exr"
        (root / "windows").mkdir(exist_ok=True)
        run([stand_in(), "-b", root / "shot.blend", "--python-exit-code", "1", "--python",
             root / "simulate_window.py", "--", "--object", "pants", "--bake",
             root / "out/x.####.exr", "--first", window["warmup_from"], "--last", window["to"],
             "--goal-strength", "0", "-o", pattern])
        windows.append(np.stack([
            ds.read_point_cache_exr(str(pattern).replace("####", f"{f:04d}"))[0]
            for f in range(window["warmup_from"], window["to"] + 1)]))
    positions, sources = ds.splice(plan, baked, windows)
    written = np.stack([ds.read_point_cache_exr(root / "final" / f"x.{f:04d}.exr")[0]
                        for f in range(FIRST, LAST + 1)])
    assert_bitwise(positions, written, "splice against drivenshape simulate")
    report = json.loads((root / "final/x.report.json").read_text())
    assert [entry["source"] for entry in report["frames"]] == sources
    # The report and the plan file hold the schema's fields, the plan's settings the table's.
    jsonschema.validate(report, SCHEMA)
    jsonschema.validate(plan, {"$ref": "#/$defs/plan", "$defs": SCHEMA["$defs"]})
    simulate = [row["key"] for row in ds.settings_table() if row["scope"] == "simulate"]
    assert SCHEMA["$defs"]["settings"]["required"] == simulate
    assert sources.count("simulated") == 47 - 30 + 1 and sources.count("blended") == 4 + 10
    # Something was spliced in: the frames differ from the bake where the windows are.
    assert not np.array_equal(positions, baked)
    with pytest.raises(ds.Error) as error:
        ds.splice(plan, baked[1:], windows)
    assert error.value.kind == "usage" and "the baked frames" in str(error.value)
