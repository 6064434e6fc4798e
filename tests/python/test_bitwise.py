# SPDX-License-Identifier: Apache-2.0
"""The module's database and frames against the command line's, bitwise.

`drivenshape db build` and build_database() (from files and from in-memory arrays) must pick
the same shapes; `drivenshape bake` (host and the default OpenCL device, EXR outputs) and the
Python Evaluator on the same frames (one call, one frame per call, batches of 7, and
evaluate_cache) must give the same float32 bit patterns. The EXRs are read by the module and by
the OpenEXR PyPI package, which must agree with each other too."""

import json
import re

import numpy as np
import pytest

import drivenshape as ds
from conftest import TEST_FRAMES, assert_bitwise, parse_pc2, run


@pytest.fixture(scope="module")
def python_database(data):
    return ds.build_database(data / "driver_rest.obj", data / "driven_rest.obj",
                             data / "train.driver.pc2", data / "train.driven.pc2", model="none")


@pytest.fixture(scope="module")
def test_driver(data):
    return parse_pc2(data / "test.driver.pc2")[0]


def test_database_equals_the_command_lines(cli_database, python_database, data):
    cli = ds.load_database(cli_database)
    for db, how in ((python_database, "files"), (_from_arrays(data), "arrays")):
        assert db.frames == cli.frames, f"build_database from {how} picked other frames"
        assert db.reasons == cli.reasons
        assert db.content_hash == cli.content_hash
        assert_bitwise(db.driver_shapes, cli.driver_shapes, f"driver shapes ({how})")
        assert_bitwise(db.driven_shapes, cli.driven_shapes, f"driven shapes ({how})")


def test_every_db_build_setting_is_a_keyword(cli, data, tmp_path):
    # The settings table gives build_database db build's settings under the same names: set
    # away from their defaults, the two tools build the same database.
    # ("model" is given its default, pose: none would leave the model's settings unused.)
    given = {"count": 7, "duplicate_tolerance": 0.002, "model": "pose", "model_parts": 3,
             "model_velocity": 2, "model_history": 0, "model_siblings": 0.25,
             "model_rank": 16, "model_per_clip": "off", "verdict_level": 0.8}
    # Every setting the docstring lists (one line each, from the table) is set here.
    listed = re.findall(r"^  ([a-z_]+) \(--", ds.build_database.__doc__, re.MULTILINE)
    assert sorted(listed) == sorted(given), listed
    flags = []
    for key, value in given.items():
        flags += ["--" + key.replace("_", "-"), value]
    path = tmp_path / "settings.dsdb"
    run([cli, "db", "build", "--driver-mesh", data / "driver_rest.obj",
         "--driven-mesh", data / "driven_rest.obj", "--driver", data / "train.driver.pc2",
         "--driven", data / "train.driven.pc2", "--quiet", "-o", path, *flags])
    db = ds.build_database(data / "driver_rest.obj", data / "driven_rest.obj",
                           data / "train.driver.pc2", data / "train.driven.pc2", **given)
    default = ds.build_database(data / "driver_rest.obj", data / "driven_rest.obj",
                                data / "train.driver.pc2", data / "train.driven.pc2")
    assert db.shape_count == 7
    assert db.content_hash == ds.load_database(path).content_hash != default.content_hash
    for key, value, kind in (("model_history", 500, "model_history"),
                             ("model_per_clip", "sometimes", "--model-per-clip"),
                             ("modle_rank", 8, "model_rank")):
        with pytest.raises(ds.Error) as error:
            ds.build_database(data / "driver_rest.obj", data / "driven_rest.obj",
                              data / "train.driver.pc2", data / "train.driven.pc2",
                              **{key: value})
        assert error.value.kind == "usage" and key in str(error.value) and kind in str(
            error.value)


def _from_arrays(data):
    # What Blender hands over: meshes from polygons, caches as arrays with a start frame.
    meshes = [ds.read_obj(data / f"{side}_rest.obj") for side in ("driver", "driven")]
    meshes = [ds.Mesh.from_polygons(m.positions, m.face_start, m.face_vertices, m.uvs,
                                    m.face_uvs if m.has_uvs else None, m.face_groups,
                                    m.group_names) for m in meshes]
    caches = [parse_pc2(data / f"train.{side}.pc2") for side in ("driver", "driven")]
    return ds.build_database(meshes[0], meshes[1], caches[0][0], caches[1][0],
                             start_frame=int(caches[0][1]), model="none")


def test_the_two_exr_readers_agree(cli_bakes):
    for device in ("host", "auto"):
        module = cli_bakes.frames(device, TEST_FRAMES)
        independent = cli_bakes.frames(device, TEST_FRAMES, reader="openexr")
        assert_bitwise(module, independent, f"module vs OpenEXR reader ({device} bake)")


@pytest.mark.parametrize("device_name", ["host", "auto"])
def test_evaluator_equals_the_bake(device_name, cli_bakes, python_database, test_driver,
                                   opencl_device, host_device):
    device = host_device if device_name == "host" else opencl_device
    reference = cli_bakes.frames(device_name, TEST_FRAMES, reader="openexr")
    evaluator = ds.Evaluator(python_database, ds.EvaluatorSettings(), device)
    assert evaluator.device_name == device.description

    cloth, records = evaluator.evaluate(TEST_FRAMES, test_driver)
    assert_bitwise(cloth, reference, f"one call of {len(TEST_FRAMES)} frames on {device_name}")
    assert [r.frame for r in records] == TEST_FRAMES

    evaluator.reset_history()
    out = np.empty((1, evaluator.driven_vertex_count, 3), dtype=np.float32)
    for index, frame in enumerate(TEST_FRAMES):
        evaluator.evaluate_into(frame, test_driver[index], out)
        assert_bitwise(out[0], reference[index], f"frame {frame} alone on {device_name}")

    batched = np.empty_like(reference)
    for begin in range(0, len(TEST_FRAMES), 7):
        end = min(begin + 7, len(TEST_FRAMES))
        evaluator.evaluate_into(TEST_FRAMES[begin:end], test_driver[begin:end],
                                batched[begin:end])
    assert_bitwise(batched, reference, f"batches of 7 on {device_name}")


def test_records_match_the_bake_report(cli_bakes, python_database, test_driver, opencl_device):
    report = json.loads((cli_bakes.folder("auto") / "sleeve.report.json").read_text())
    by_frame = {entry["frame"]: entry for entry in report["frames"]}
    evaluator = ds.Evaluator(python_database, ds.EvaluatorSettings(), opencl_device)
    _, records = evaluator.evaluate(TEST_FRAMES, test_driver)
    for record in records:
        # The report writes doubles so that they read back exactly.
        expected = by_frame[record.frame]
        assert record.weights == expected["weights"], f"frame {record.frame} weights"
        assert record.relative_residual == expected["relative_residual"]
        assert record.relative_residual_direct == expected["relative_residual_direct"]
        assert record.iterations == expected["iterations"]
        assert record.at_zero == expected["active_at_zero"]
        assert record.at_one == expected["active_at_one"]
        assert record.align_rotation == expected["align_rotation"]
        assert record.inside_after == expected["inside_after"]
        assert record.resolved == expected["resolved"]


def test_evaluate_cache_equals_a_temporal_bake(cli_bakes, python_database, data, tmp_path,
                                               host_device):
    # Binding mask, regions, wind and the temporal bound with its per-batch warm-up: the file
    # loaders the command line uses, and the bake's batching, give its frames bitwise.
    mask = tmp_path / "mask.json"
    mask.write_text(json.dumps({"bindings": [
        {"driven": {"vertices": ["0-999"]}, "driver": {"faces": ["0-1199"]}}]}))
    regions = tmp_path / "regions.json"
    regions.write_text(json.dumps({"regions": [
        {"name": "upper", "driver": {"vertices": ["0-1072"]},
         "driven": {"vertices": ["0-1121"]}}]}))
    extra = ("--bind", mask, "--regions", regions, "--wind-amplitude", "0.003",
             "--wind-weight", "group:sleeve", "--max-weight-change", "0.05", "--batch", "5",
             "--temporal-warmup", "3", "--fps", "30")
    frames = list(range(4, 21))
    reference = cli_bakes.frames("host", frames, *extra, frame_text="4-20")

    db = python_database
    settings = ds.EvaluatorSettings(
        binding_mask=ds.load_binding_mask(mask, db), regions=ds.load_regions(regions, db),
        layers=ds.load_layers(db, wind_amplitude=0.003, wind_weight="group:sleeve",
                              frames_per_second=30.0),
        max_weight_change=0.05)
    evaluator = ds.Evaluator(db, settings, host_device)
    cache = ds.open_point_cache(data / "test.driver.pc2")
    cloth, records = ds.evaluate_cache(evaluator, cache, frames, batch=5, temporal_warmup=3)
    assert_bitwise(cloth, reference, "masked, regional, windy, temporally bound bake")
    assert [r.frame for r in records] == frames
    plain, _ = ds.evaluate_cache(ds.Evaluator(db, ds.EvaluatorSettings(), host_device), cache,
                                 frames)
    assert not np.array_equal(plain, cloth)  # the settings did change the result


# ---- The shot planner with the pose model (issue 27): history frames before every frame ----

ODD_FRAME_LISTS = {
    "one frame": [30],
    "reversed": list(range(48, 0, -1)),
    "gaps": [1, 2, 3, 10, 11, 12, 30, 40, 41, 47],
    "shuffled, repeats": [17, 5, 5, 33, 18, 48, 1, 2, 17],
}


@pytest.mark.parametrize("name", ODD_FRAME_LISTS)
def test_evaluate_cache_of_odd_frame_lists_equals_the_pose_bake(name, pose_bakes, data,
                                                                opencl_device):
    frames = ODD_FRAME_LISTS[name]
    reference = pose_bakes.frames("auto", TEST_FRAMES, reader="openexr")
    evaluator = ds.Evaluator(ds.load_database(pose_bakes.database), ds.EvaluatorSettings(),
                             opencl_device)
    assert evaluator.history_frames > 0, "a db build default database runs the pose model"
    cache = ds.open_point_cache(data / "test.driver.pc2")
    for batch in (64, 5):
        cloth, records = ds.evaluate_cache(evaluator, cache, frames, batch=batch)
        assert [r.frame for r in records] == frames
        assert_bitwise(cloth, reference[[f - 1 for f in frames]],
                       f"evaluate_cache of {name} frames {frames}, batch {batch}")


def test_a_part_of_the_pose_bake_is_the_whole_bake(pose_bakes, opencl_device, data):
    # The CLI itself: frames 30-48 read their history from the cache before frame 30. And the
    # history matters: frame 30 evaluated alone (no earlier frames) is another cloth.
    whole = pose_bakes.frames("auto", range(30, 49), reader="openexr")
    part = pose_bakes.frames("auto", range(30, 49), frame_text="30-48", reader="openexr")
    assert_bitwise(part, whole, "bake --frames 30-48 against the whole bake's frames 30-48")
    evaluator = ds.Evaluator(ds.load_database(pose_bakes.database), ds.EvaluatorSettings(),
                             opencl_device)
    alone, _ = evaluator.evaluate([30], parse_pc2(data / "test.driver.pc2")[0][29])
    assert np.abs(alone[0] - whole[0]).max() > 1e-4, "frame 30 does not depend on its history"


def test_plan_shot_and_the_playback_planner(python_database, host_device, pose_bakes):
    pose = ds.Evaluator(ds.load_database(pose_bakes.database), ds.EvaluatorSettings(),
                        host_device)
    history = pose.history_frames
    plan = ds.plan_shot(pose, [40, 41, 42, 10, 9], range(1, 49), batch=2)
    assert [(b.first, b.frames, b.restart) for b in plan] == [
        (0, [40, 41], True), (2, [42], True), (3, [10], True), (4, [9], True)]
    assert plan[0].warmup == list(range(40 - history, 40))
    assert plan[2].warmup == list(range(1, 10)), "the warm-up holds only frames the source has"
    assert plan[3].warmup == list(range(1, 9))
    assert plan[1].solve_frames == plan[1].warmup + [42]
    assert plan[0].warmup == ds.plan_shot(pose, [40], list(range(48, 0, -1)))[0].warmup
    assert repr(plan[0]).startswith("BatchPlan(") and "frames=[40, 41]" in repr(plan[0])

    qp = ds.Evaluator(python_database, ds.EvaluatorSettings(), host_device)
    assert all(not b.warmup for b in ds.plan_shot(qp, [5, 9, 3], range(1, 49)))
    bound = ds.Evaluator(python_database, ds.EvaluatorSettings(max_weight_change=0.05),
                         host_device)
    assert ds.plan_shot(bound, [20], range(1, 49), temporal_warmup=3)[0].warmup == [17, 18, 19]

    planner = ds.PlaybackPlanner(pose)
    assert planner.warmup_frames == history
    steps = [planner.next(f, range(1, 49)) for f in (30, 31, 32, 10, 10)]
    assert [(s.restart, len(s.warmup)) for s in steps] == [
        (True, history), (False, 0), (False, 0), (True, min(history, 9)),
        (True, min(history, 9))]
    planner.reset()
    assert planner.next(11, range(1, 49)).restart

    for call, words in [(lambda: ds.plan_shot(pose, [1], [1], batch=0), ["batch", "got 0"]),
                        (lambda: ds.plan_shot(pose, [1], [1], temporal_warmup=-1),
                         ["warm-up", "got -1"]),
                        (lambda: ds.plan_shot("evaluator", [1], [1]), ["Evaluator", "str"]),
                        (lambda: planner.next(2**40, [1]), ["frame", str(2**40)])]:
        with pytest.raises(ds.Error) as error:
            call()
        assert error.value.kind == "usage" and all(w in str(error.value) for w in words), (
            str(error.value))
