# SPDX-License-Identifier: Apache-2.0
"""Errors of the module (issue 28, item 8): every error is a drivenshape.Error with a documented
kind and the command line's code, whose message names the argument and the value at fault.

* Frame numbers are C++ ints in the library: a Python frame outside -2**31..2**31-1 is a usage
  error naming it, never wrapped (2**40 used to evaluate and label frame 0, 2**32 + 5 frame 5) and
  never pybind11's own RuntimeError, whether it comes as an int, a list or a numpy array, to any
  binding that takes frames.
* A 0-vertex point-cache EXR is a usage error naming `positions` (it was kind 'internal').
* An absurd EXR width is refused before anything is allocated, naming `width` and the range
  (2**31 - 1 used to end as an output error about std::bad_alloc)."""

import numpy as np
import pytest

import drivenshape as ds
from conftest import parse_pc2

INT_MIN, INT_MAX = -2**31, 2**31 - 1
OUTSIDE = [2**31, 2**32 + 5, 2**40, INT_MIN - 1, -2**40, 2**70]
MAX_WIDTH = 65536  # kMaxPointCacheExrWidth (src/include/drivenshape/point_cache.h)


@pytest.fixture(scope="module")
def driver(data):
    return parse_pc2(data / "test.driver.pc2")[0]


@pytest.fixture(scope="module")
def evaluator(cli_database, host_device):
    return ds.Evaluator(ds.load_database(cli_database), None, host_device)


def frame_forms(frame):
    """The frame as an int, a list, and numpy arrays where numpy can hold it."""
    forms = [frame, [frame], [1, frame]]
    if -2**63 <= frame < 2**63:
        forms += [np.array([frame], dtype=np.int64), np.int64(frame)]
    if 0 <= frame < 2**64:
        forms.append(np.array([frame], dtype=np.uint64))
    return forms


def assert_usage(error, *words):
    """A drivenshape.Error of kind usage (code 2) whose message holds every word."""
    assert type(error.value) is ds.Error, f"{type(error.value).__name__}: {error.value}"
    assert error.value.kind == "usage" and error.value.code == 2, (
        f"kind {error.value.kind!r} code {error.value.code}: {error.value}")
    for word in words:
        assert str(word) in str(error.value), f"{word!r} not in: {error.value}"


def test_evaluate_refuses_frames_past_32_bits(evaluator, driver):
    for frame in OUTSIDE:
        for frames in frame_forms(frame):
            count = np.asarray(frames).size
            block = driver[:count] if count > 1 or np.ndim(frames) else driver[0]
            with pytest.raises(ds.Error) as error:
                evaluator.evaluate(frames, block)
            assert_usage(error, "frames", frame, INT_MIN, INT_MAX)
            out = np.empty((count, 2244, 3), np.float32)
            with pytest.raises(ds.Error) as error:
                evaluator.evaluate_into(frames, block, out)
            assert_usage(error, "frames", frame)
            with pytest.raises(ds.Error) as error:
                evaluator.check_frames(frames)
            assert_usage(error, "frames", frame)
        with pytest.raises(ds.Error) as error:
            ds.evaluate_cache(evaluator, ds.PointCache.from_array(driver[:2]), [1, frame])
        assert_usage(error, frame)
    # The ends of the range are frames like any other, labelled with their own numbers.
    for frame in (INT_MIN, INT_MAX):
        cloth, records = evaluator.evaluate(frame, driver[0])
        assert cloth.shape == (1, 2244, 3) and records[0].frame == frame
        evaluator.reset_history()


def test_frames_must_be_whole_numbers(evaluator, driver):
    for frames, words in [([1.5], ["frames", "1.5", "whole number"]),
                          ([True], ["frames", "True", "whole number"]),
                          (["1"], ["frames", "'1'", "whole number"]),
                          ([float("nan")], ["frames", "nan"]),
                          ([[1], [2, 3]], ["frames"])]:
        with pytest.raises(ds.Error) as error:
            evaluator.evaluate(frames, driver[:1])
        assert_usage(error, *words)
    # Whole numbers in other types are the same frames.
    _, records = evaluator.evaluate(np.array([3.0, 4.0]), driver[2:4])
    assert [r.frame for r in records] == [3, 4]


def test_every_binding_that_takes_frames_checks_them(driver, data, tmp_path):
    cache = ds.PointCache.from_array(driver[:3], start_frame=10)
    for frame in OUTSIDE:
        checks = [
            (lambda: cache.read(frame), "frame"),
            (lambda: cache.has_frame(frame), "frame"),
            (lambda: cache.read_frames([10, frame]), "frames"),
            (lambda: ds.PointCache.from_array(driver[:1], start_frame=frame), "start_frame"),
            (lambda: ds.PointCache.from_array(driver[:2], frames=[1, frame]), "frames"),
            (lambda: ds.format_frame_range([1, frame]), "frames"),
            (lambda: ds.expand_frame_pattern("out.####.exr", frame), "frame"),
            (lambda: ds.write_point_cache_exr(tmp_path / "f.exr", driver[0], frame=frame),
             "frame"),
            (lambda: ds.build_database(data / "driver_rest.obj", data / "driven_rest.obj",
                                       driver[:3], driver[:3], start_frame=frame), "start_frame"),
            (lambda: ds.build_database(data / "driver_rest.obj", data / "driven_rest.obj",
                                       cache, cache, frames=[10, frame]), "frames"),
        ]
        for call, argument in checks:
            with pytest.raises(ds.Error) as error:
                call()
            assert_usage(error, argument, frame)
    assert not (tmp_path / "f.exr").exists()
    # A block of frames may not run past the last frame number either.
    with pytest.raises(ds.Error) as error:
        ds.PointCache.from_array(driver[:3], start_frame=INT_MAX - 1)
    assert_usage(error, "start_frame", INT_MAX - 1, "3 frames")
    assert ds.PointCache.from_array(driver[:3], start_frame=INT_MAX - 2).frames == [
        INT_MAX - 2, INT_MAX - 1, INT_MAX]
    assert ds.expand_frame_pattern("out.####.exr", INT_MIN) == f"out.{INT_MIN}.exr"


def test_point_cache_exr_without_vertices_is_a_usage_error(tmp_path):
    path = tmp_path / "empty.0001.exr"
    with pytest.raises(ds.Error) as error:
        ds.write_point_cache_exr(path, np.zeros((0, 3), np.float32))
    assert_usage(error, "positions", "no vertices", "(0, 3)")
    assert not path.exists() and not list(tmp_path.iterdir())


def test_absurd_width_is_refused_before_allocating(tmp_path):
    positions = np.arange(15, dtype=np.float32).reshape(5, 3)
    path = tmp_path / "wide.0001.exr"
    for width in (2**31 - 1, 2**40, MAX_WIDTH + 1, 0, -1):
        with pytest.raises(ds.Error) as error:
            ds.write_point_cache_exr(path, positions, width=width, sync=False)
        assert_usage(error, "width", width, f"1 to {MAX_WIDTH}")
    assert not list(tmp_path.iterdir())
    # The widest EXR the writer accepts is written and read back.
    ds.write_point_cache_exr(path, positions, width=MAX_WIDTH, sync=False)
    again, info = ds.read_point_cache_exr(path)
    assert info["width"] == MAX_WIDTH and np.array_equal(again, positions)


def test_raw_bytes_of_a_bad_input_are_escaped_in_the_message(cli_database, tmp_path):
    # A message quoting a bad input's bytes (nlohmann's "last read: '\xf7'") must still become a
    # drivenshape.Error (its text was passed to Python as UTF-8), with the byte escaped.
    database = ds.load_database(cli_database)
    mask = tmp_path / "mask.json"
    mask.write_bytes(b'{"bindings": \xf7\x01}')
    with pytest.raises(ds.Error) as error:
        ds.load_binding_mask(mask, database)
    assert error.value.kind == "input" and error.value.code == 3, error.value
    assert "\\xf7" in str(error.value) and "\xf7" not in str(error.value), str(error.value)


# ---- Writers and whole-shot calls (issue 42) ----------------------------------------------------

def test_writers_refuse_what_no_reader_could_use(driver, tmp_path):
    """NaN positions were written (every reader then refused the file), and a PC2 starting at
    frame 2**40 was written whole though its reader maps none of its samples to a frame."""
    bad = driver[:2].copy()
    bad[1, 7, 2] = np.nan
    for write in (lambda: ds.write_pc2(tmp_path / "nan.pc2", bad),
                  lambda: ds.write_point_cache_exr(tmp_path / "nan.exr", bad[1]),
                  lambda: ds.write_point_cache_exr(tmp_path / "nan_n.exr", driver[0],
                                                   normals=bad[1])):
        with pytest.raises(ds.Error) as error:
            write()
        assert error.value.kind == "input" and "vertex 7" in str(error.value), error.value
    for start in (2.0**40, -2.0**40, float("nan"), 2.0e9):
        with pytest.raises(ds.Error) as error:
            ds.write_pc2(tmp_path / "far.pc2", driver[:2], start_frame=start)
        assert_usage(error, "start_frame")
    with pytest.raises(ds.Error) as error:
        ds.write_pc2(tmp_path / "end.pc2", driver[:3], start_frame=1.999e9, sample_rate=1e6)
    assert_usage(error, "start_frame", "beyond")
    with pytest.raises(ds.Error) as error:
        ds.write_point_cache_exr(tmp_path / "fps.exr", driver[0], frames_per_second=0.0)
    assert_usage(error, "frames_per_second")
    assert sorted(p.name for p in tmp_path.iterdir()) == [], "a refused write left a file"
    # What a reader maps is written and read back.
    ds.write_pc2(tmp_path / "ok.pc2", driver[:2], start_frame=1.0e9)
    assert ds.open_point_cache(tmp_path / "ok.pc2").frames == [1000000000, 1000000001]


def test_write_obj_refuses_a_mesh_with_non_finite_positions(cli_database, tmp_path):
    mesh = ds.load_database(cli_database).driven_mesh
    positions = np.array(mesh.positions)
    positions[3, 0] = np.inf
    broken = ds.Mesh.from_polygons(positions, mesh.face_start, mesh.face_vertices)
    with pytest.raises(ds.Error) as error:
        ds.write_obj(tmp_path / "inf.obj", broken)
    assert error.value.kind == "input" and "vertex 3" in str(error.value)
    assert not (tmp_path / "inf.obj").exists()


def test_evaluate_cache_refuses_a_shot_too_large_for_memory_up_front(evaluator, driver):
    """evaluate_cache allocated the cloth of every frame first: MemoryError (or the machine
    swapping) for a huge range, where a usage error saying so is due."""
    cache = ds.PointCache.from_array(driver[:3], start_frame=1)
    for frames in (range(1, INT_MAX), list(range(1, 2**27))):
        with pytest.raises(ds.Error) as error:
            ds.evaluate_cache(evaluator, cache, frames)
        assert_usage(error, "GiB", "evaluate the frames in parts")
