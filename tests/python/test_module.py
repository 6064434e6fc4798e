# SPDX-License-Identifier: Apache-2.0
"""The Python module on its own: meshes, point caches (PC2, EXR, arrays), devices, settings,
errors, what is copied and what is not, and the GIL. References are parsed here or read by the
OpenEXR PyPI package, never produced by the module itself."""

import gc
import io
import json
import threading
import time

import numpy as np
import pytest

import drivenshape as ds
from conftest import (TEST_FRAMES, assert_bitwise, parse_obj, parse_pc2, read_exr_openexr,
                      run)


@pytest.fixture(scope="module")
def database(cli_database):
    return ds.load_database(cli_database)


@pytest.fixture(scope="module")
def test_driver(data):
    return parse_pc2(data / "test.driver.pc2")[0]


def test_version_is_the_command_lines(cli):
    assert run([cli, "version"]).stdout.split()[-1] == ds.__version__
    assert issubclass(ds.Error, RuntimeError)


# ---- Meshes ------------------------------------------------------------------------------

def test_read_obj_matches_the_file(data):
    for name in ("driver_rest.obj", "driven_rest.obj"):
        mesh = ds.read_obj(data / name)
        positions, sizes, corners = parse_obj(data / name)
        assert_bitwise(mesh.positions, positions, f"{name} positions")
        assert np.array_equal(np.diff(mesh.face_start), sizes)
        assert np.array_equal(mesh.face_vertices, corners)
        assert mesh.vertex_count == len(positions) and mesh.face_count == len(sizes)
        # Fan triangulation: a quad (a, b, c, d) gives (a, b, c) and (a, c, d).
        assert mesh.triangle_count == int((sizes - 2).sum())
        first = corners[:sizes[0]]
        assert mesh.triangles[0].tolist() == [first[0], first[1], first[2]]
        face_start, face_vertices = mesh.faces
        assert np.array_equal(face_start, mesh.face_start)
        assert mesh.group_names == [("sleeve" if "driven" in name else "arm")]


def test_mesh_arrays_are_read_only_views(data):
    mesh = ds.read_obj(data / "driver_rest.obj")
    positions = mesh.positions
    assert positions.dtype == np.float32 and positions.shape == (mesh.vertex_count, 3)
    assert not positions.flags.writeable
    # Two reads show the same memory: a view of the mesh, not a copy per access.
    assert np.shares_memory(positions, mesh.positions)
    assert np.shares_memory(mesh.triangles, mesh.triangles)
    with pytest.raises(ValueError):
        positions[0, 0] = 1.0
    # The view keeps the mesh alive.
    expected = positions.copy()
    del mesh
    gc.collect()
    assert_bitwise(positions, expected, "positions after the mesh went out of scope")


def test_mesh_from_polygons_blender_style(data, tmp_path):
    source = ds.read_obj(data / "driven_rest.obj")
    # Blender gives loop_start (one entry per face), loops' vertex ids, and UVs per loop.
    mesh = ds.Mesh.from_polygons(np.array(source.positions, dtype=np.float64),
                                 source.face_start[:-1], source.face_vertices,
                                 uvs=source.uvs, face_uvs=source.face_uvs,
                                 face_groups=source.face_groups,
                                 group_names=source.group_names)
    assert_bitwise(mesh.positions, source.positions, "positions")
    assert np.array_equal(mesh.triangles, source.triangles)
    assert mesh.topology_hash == source.topology_hash
    assert_bitwise(mesh.uvs, source.uvs, "uvs")
    ds.write_obj(tmp_path / "copy.obj", mesh)
    again = ds.read_obj(tmp_path / "copy.obj")
    assert_bitwise(again.positions, source.positions, "positions after write_obj")
    assert again.topology_hash == source.topology_hash


def test_mesh_from_polygons_refuses_bad_faces():
    positions = np.zeros((4, 3), np.float32)
    with pytest.raises(ds.Error) as error:
        ds.Mesh.from_polygons(positions, [0, 3], [0, 1, 7])
    assert error.value.kind == "input" and error.value.code == 3
    assert "from_polygons" in str(error.value) and "7" in str(error.value)
    with pytest.raises(ds.Error) as error:
        ds.Mesh.from_polygons(np.zeros((4, 2)), [0, 3], [0, 1, 2])
    assert error.value.kind == "usage" and "(vertices, 3)" in str(error.value)


# ---- Strain (issue 43): Mesh.edges, edge_strain, frame_strain -----------------------------

def unit_square():
    """The unit square (0,0) (1,0) (1,1) (0,1) as two triangles sharing the diagonal 0-2."""
    positions = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
    return ds.Mesh.from_polygons(positions, [0, 3, 6], [0, 1, 2, 0, 2, 3])


def stretched_x(positions, factor):
    out = np.array(positions, np.float32)
    out[:, 0] *= factor
    return out


def test_mesh_edges_are_the_polygon_sides_once_each():
    # Two quads sharing the side 1-4; by hand: 2 sides along x per row, 3 upright ones.
    positions = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0], [1, 1, 0], [2, 1, 0]],
                         np.float32)
    mesh = ds.Mesh.from_polygons(positions, [0, 4, 8], [0, 1, 4, 3, 1, 2, 5, 4])
    assert mesh.edges.dtype == np.int32
    assert mesh.edges.tolist() == [[0, 1], [0, 3], [1, 2], [1, 4], [2, 5], [3, 4], [4, 5]]
    assert unit_square().edges.tolist() == [[0, 1], [0, 2], [0, 3], [1, 2], [2, 3]]
    figures = ds.frame_strain(positions, stretched_x(positions, 1.2), mesh.edges)
    assert figures["edges"] == 7
    assert figures["strain_mean"] == pytest.approx(4 * 0.2 / 7, abs=1e-6)
    assert figures["strain_p95"] == pytest.approx(0.2, abs=1e-6)  # rank ceil(6.65) = 7 of 7
    assert figures["strain_share_over_10pct"] == 4 / 7


def test_strain_of_a_stretched_and_a_shrunk_square():
    square = unit_square()
    stretched = stretched_x(square.positions, 1.2)
    strains = ds.edge_strain(square.positions, stretched, square.edges)
    assert strains.dtype == np.float64 and strains.shape == (5,)
    # Along x +20%, along y 0, the diagonal sqrt(1.2^2 + 1) / sqrt(2) - 1 = 10.45%.
    diagonal = np.sqrt(2.44 / 2) - 1
    assert strains == pytest.approx([0.2, diagonal, 0.0, 0.0, 0.2], abs=1e-6)
    figures = ds.frame_strain(square.positions, stretched, square.edges)
    assert figures == pytest.approx({"edges": 5, "strain_mean": (0.4 + diagonal) / 5,
                                     "strain_p95": 0.2, "strain_share_over_10pct": 0.6},
                                    abs=1e-6)
    # Shrunk by 20%: the magnitudes count; the diagonal shrinks by 9.45%, under 10%.
    shrunk = ds.frame_strain(square.positions, stretched_x(square.positions, 0.8), square.edges)
    assert shrunk["strain_mean"] == pytest.approx((0.4 + 1 - np.sqrt(0.82)) / 5, abs=1e-6)
    assert shrunk["strain_share_over_10pct"] == 0.4


def test_frame_strain_matches_numpy_on_the_sleeve(data):
    """An independent computation with numpy over the sample's truth: every edge's strain, the
    mean of the magnitudes, the value at rank ceil(0.95 n) of them sorted, the share over 0.1."""
    mesh = ds.read_obj(data / "driven_rest.obj")
    rest = np.asarray(mesh.positions, np.float64)
    edges = mesh.edges
    frames = parse_pc2(data / "test.driven.pc2")[0]
    for frame in (0, 20, 47):
        positions = frames[frame]
        now = np.linalg.norm(positions[edges[:, 1]].astype(np.float64)
                             - positions[edges[:, 0]], axis=1)
        before = np.linalg.norm(rest[edges[:, 1]] - rest[edges[:, 0]], axis=1)
        strain = np.abs(now / before - 1.0)
        rank = int(np.ceil(0.95 * len(strain) - 1e-9))
        figures = ds.frame_strain(mesh.positions, positions, edges)
        assert figures["edges"] == len(edges) == 4444
        assert figures["strain_mean"] == pytest.approx(strain.mean(), rel=1e-12)
        assert figures["strain_p95"] == pytest.approx(np.sort(strain)[rank - 1], rel=1e-12)
        assert figures["strain_share_over_10pct"] == np.count_nonzero(strain > 0.1) / len(strain)
        assert ds.edge_strain(mesh.positions, positions, edges) == pytest.approx(
            now / before - 1.0, rel=1e-12, abs=1e-15)


def test_strain_refuses_bad_arguments():
    square = unit_square()
    rest = square.positions

    def error_of(*arguments):
        with pytest.raises(ds.Error) as error:
            ds.frame_strain(*arguments)
        return error.value

    bad = error_of(rest, rest, square.edges.astype(np.float64))
    assert bad.kind == "usage" and "(edges, 2)" in str(bad)
    assert error_of(rest, rest[:3], square.edges).kind == "usage"
    assert error_of(rest, rest, [[0, 4]]).kind == "input"
    assert error_of(rest, rest, [[0, 2**32]]).kind == "input"  # not wrapped to 0
    broken = np.array(rest)
    broken[2, 1] = np.nan
    bad = error_of(rest, broken, square.edges)
    assert bad.kind == "input" and "vertex 2" in str(bad)
    twice = np.zeros((2, 3), np.float32)
    bad = error_of(twice, twice, [[0, 1]])
    assert bad.kind == "input" and "zero length at rest" in str(bad)
    assert ds.frame_strain(rest, rest, np.zeros((0, 2), np.int32))["edges"] == 0


# ---- Point caches ------------------------------------------------------------------------

def test_read_pc2_matches_the_bytes(data):
    positions, start, rate = ds.read_pc2(data / "test.driver.pc2")
    expected, expected_start, expected_rate = parse_pc2(data / "test.driver.pc2")
    assert_bitwise(positions, expected, "read_pc2")
    assert (start, rate) == (expected_start, expected_rate)
    cache = ds.open_point_cache(data / "test.driver.pc2")
    assert cache.frames == TEST_FRAMES and cache.vertex_count == expected.shape[1]
    assert_bitwise(cache.read_frames([3, 1, 48]), expected[[2, 0, 47]], "read_frames")
    assert_bitwise(cache.read(7), expected[6], "read")


def test_pc2_round_trip(tmp_path):
    rng = np.random.default_rng(15)
    positions = rng.standard_normal((5, 17, 3)).astype(np.float32)
    path = tmp_path / "every_other.pc2"
    ds.write_pc2(path, positions, start_frame=1001.0, sample_rate=2.0)
    raw, start, rate = parse_pc2(path)
    assert_bitwise(raw, positions, "written PC2 samples")
    assert (start, rate) == (1001.0, 2.0)
    again, start, rate = ds.read_pc2(path)
    assert_bitwise(again, positions, "read_pc2 of write_pc2")
    assert ds.open_point_cache(path).frames == [1001, 1003, 1005, 1007, 1009]
    # Float64 and non-contiguous inputs are converted, with the same result.
    ds.write_pc2(tmp_path / "converted.pc2", positions.astype(np.float64)[:, :, :])
    ds.write_pc2(tmp_path / "strided.pc2", np.asfortranarray(positions))
    for name in ("converted.pc2", "strided.pc2"):
        assert_bitwise(parse_pc2(tmp_path / name)[0], positions, name)


def test_convert_up_axis_is_exact(data):
    positions, _, _ = parse_pc2(data / "test.driven.pc2")
    positions = positions[:4].copy()
    positions[0, 0] = [-0.0, 0.0, 1e-42]  # signed zeros and a denormal keep their bits too
    # The expected rotation on the bit patterns: Z up -> Y up is (x, y, z) -> (x, z, -y).
    bits = positions.view(np.uint32)
    expected = np.stack([bits[..., 0], bits[..., 2], bits[..., 1] ^ np.uint32(0x80000000)],
                        axis=-1).view(np.float32)
    rotated = ds.convert_up_axis(positions, "Z", "Y")
    assert_bitwise(rotated, expected, "convert_up_axis Z -> Y")
    assert_bitwise(ds.convert_up_axis(rotated, "Y", "Z"), positions, "Y -> Z round trip")
    assert_bitwise(ds.convert_up_axis(positions[1], "Z", "Z"), positions[1], "Z -> Z")
    assert_bitwise(ds.convert_up_axis(positions.astype(np.float64), "Z", "Y"), expected,
                   "float64 input")
    assert rotated.base is not positions  # a copy: the input is never changed
    with pytest.raises(ds.Error, match="to_axis 'X'") as error:
        ds.convert_up_axis(positions, "Z", "X")
    assert error.value.kind == "usage" and error.value.code == 2
    with pytest.raises(ds.Error, match=r"\(\.\.\., 3\)"):
        ds.convert_up_axis(np.zeros((4, 2), np.float32), "Z", "Y")


def test_point_cache_exr_round_trip_read_by_openexr(tmp_path):
    rng = np.random.default_rng(16)
    positions = rng.standard_normal((2500, 3)).astype(np.float32)
    normals = rng.standard_normal((2500, 3)).astype(np.float32)
    path = tmp_path / "cloth.0012.exr"
    ds.write_point_cache_exr(path, positions, normals=normals, frame=12, width=1000,
                             compression="piz", topology_hash=0x1234, frames_per_second=25.0,
                             string_attributes={"dsComment": "python"}, sync=False)
    independent, header = read_exr_openexr(path)
    assert_bitwise(independent, positions, "EXR pixels read by OpenEXR")
    assert header["dsVertexCount"] == 2500 and header["dsFrame"] == 12
    assert header["dsComment"] == "python" and float(header["framesPerSecond"]) == 25.0
    assert header["dsTopologyHash"] == "0000000000001234"
    again, info = ds.read_point_cache_exr(path)
    assert_bitwise(again, positions, "read_point_cache_exr")
    assert info["vertex_count"] == 2500 and info["width"] == 1000 and info["frame"] == 12
    assert info["has_normals"] and info["compression"] == "piz"
    assert info["string_attributes"] == {"dsComment": "python"}
    assert ds.read_point_cache_exr_info(path)["topology_hash"] == 0x1234
    with pytest.raises(ds.Error) as error:
        ds.read_point_cache_exr(path, expected_vertex_count=2499)
    assert error.value.kind == "input" and str(path) in str(error.value)
    sequence = ds.open_point_cache(tmp_path / "cloth.####.exr")
    assert sequence.frames == [12]
    assert_bitwise(sequence.read(12), positions, "EXR sequence")


def test_array_point_cache_reads_in_place():
    positions = np.arange(4 * 5 * 3, dtype=np.float32).reshape(4, 5, 3)
    cache = ds.PointCache.from_array(positions, start_frame=10)
    assert cache.frames == [10, 11, 12, 13] and cache.vertex_count == 5
    assert_bitwise(cache.read(12), positions[2], "frame 12")
    positions[2, 0, 0] = -1.0  # the cache holds the caller's memory: no copy was made
    assert cache.read(12)[0, 0] == -1.0
    converted = ds.PointCache.from_array(positions.astype(np.float64), frames=[5, 1, 3, 2])
    assert converted.frames == [1, 2, 3, 5]
    positions[1, 0, 0] = -2.0  # a float64 input was converted once: it is a copy
    assert converted.read(1)[0, 0] == 3 * 5 * 1
    with pytest.raises(ds.Error) as error:
        cache.read(14)
    assert error.value.kind == "input" and "frame 14" in str(error.value)


def test_output_arrays_own_cpp_memory(data):
    cache = ds.open_point_cache(data / "test.driver.pc2")
    frames = cache.read_frames([1, 2])
    assert frames.flags.writeable and frames.flags.c_contiguous
    owner = frames.base.obj  # numpy -> memoryview -> the C++ buffer object
    assert type(owner).__name__ == "_Buffer"
    assert np.shares_memory(frames, np.asarray(owner))


# ---- Devices and settings ------------------------------------------------------------------

def test_devices(opencl_device, host_device):
    listed = ds.list_devices()
    assert listed and all({"index", "name", "type", "description"} <= set(d) for d in listed)
    assert opencl_device.description in [d["description"] for d in listed]
    assert not host_device.is_opencl and "host" in host_device.description
    with pytest.raises(ds.Error) as error:
        ds.open_device("no such device name")
    assert error.value.kind == "device" and error.value.code == 5


def test_settings_keywords_and_enum_strings():
    settings = ds.EvaluatorSettings()
    assert (settings.weight_mode, settings.align, settings.blend) == ("auto", "rigid", "local")
    assert settings.correct and settings.resolve and settings.audit
    assert settings.binding_mask is None and settings.regions is None and settings.layers.empty
    custom = ds.EvaluatorSettings(weight_mode="nearest", align="rigid-all", blend="world",
                                  skin_offset=0.001, max_weight_change=0.1, audit=False,
                                  threads=1, align_group="arm", exit_fade=0.3,
                                  coverage_tolerance=0.004)
    assert (custom.weight_mode, custom.align, custom.blend) == ("nearest", "rigid-all", "world")
    assert custom.skin_offset == 0.001 and custom.threads == 1 and not custom.audit
    assert custom.exit_fade == 0.3 and settings.exit_fade == 0.25
    # Issue 27: coverage_tolerance was an attribute but neither a keyword nor in the repr.
    assert custom.coverage_tolerance == 0.004 and settings.coverage_tolerance == 0
    assert "coverage_tolerance=0.004" in repr(custom)
    custom.align = "none"
    assert custom.align == "none"
    with pytest.raises(ds.Error) as error:
        ds.EvaluatorSettings(blend="sideways")
    assert error.value.kind == "usage" and "sideways" in str(error.value)
    with pytest.raises(TypeError):
        ds.EvaluatorSettings(no_such_setting=1)


def test_loaders_of_masks_regions_layers(database, tmp_path):
    mask_path = tmp_path / "mask.json"
    mask_path.write_text(json.dumps({"bindings": [
        {"driven": {"vertices": ["0-999"]}, "driver": {"faces": ["0-999"]}}]}))
    mask = ds.load_binding_mask(mask_path, database)
    assert mask.driven_vertex_count == database.driven_vertex_count and not mask.is_all
    assert mask.vertex_classes[0] == 0 and mask.vertex_classes[1500] == -1
    assert mask.class_triangles(0)[:3] == [0, 1, 2]
    with pytest.raises(ds.Error) as error:  # was an out-of-range read in C++
        mask.class_triangles(1)
    assert error.value.kind == "usage" and "1 classes" in str(error.value)
    regions = ds.load_regions(_write_regions(tmp_path), database)
    assert regions.names == ["upper", "rest"]
    layers = ds.load_layers(database, wind_amplitude=0.003, wind_weight="group:sleeve")
    assert layers.has_wind and not layers.has_mix and len(layers.wind_weights) == 2244
    bad = tmp_path / "bad.json"
    bad.write_text('{"bindings": [{"driven": "no_such_group", "driver": "arm"}]}')
    with pytest.raises(ds.Error) as error:
        ds.load_binding_mask(bad, database)
    assert error.value.kind == "input" and "bad.json" in str(error.value)
    assert "sleeve" in str(error.value)  # lists the known groups


def _write_regions(folder):
    path = folder / "regions.json"
    path.write_text(json.dumps({"falloff": 2, "regions": [
        {"name": "upper", "driver": {"vertices": ["0-1072"]},
         "driven": {"vertices": ["0-1121"]}}]}))
    return path


# ---- The Evaluator -------------------------------------------------------------------------

def test_evaluator_properties_and_lifetime(cli_database, test_driver, host_device):
    db = ds.load_database(cli_database)
    evaluator = ds.Evaluator(db, None, ds.open_device("host"))
    assert evaluator.driver_vertex_count == 2146 and evaluator.driven_vertex_count == 2244
    assert "host" in evaluator.device_name
    assert evaluator.stage_names[:2] == ["align", "project"]
    described = evaluator.describe_settings()
    assert described["align"] == "rigid" and described["blend"] == "local"
    assert isinstance(evaluator.settings_hash, int)
    other = ds.Evaluator(db, ds.EvaluatorSettings(skin_offset=0.003), host_device)
    assert other.settings_hash != evaluator.settings_hash
    # The evaluator keeps the database and the device it was given alive.
    del db
    gc.collect()
    cloth, records = evaluator.evaluate([5], test_driver[4])
    assert cloth.shape == (1, 2244, 3) and records[0].frame == 5
    assert set(evaluator.last_stage_seconds) >= {"weights", "blend", "resolve"}
    record = records[0].to_dict()
    assert len(record["weights"]) == 30 and abs(sum(record["weights"]) - 1) < 1e-9
    assert record["inside_after"] >= 0 and len(record["align_rotation"]) == 9
    with pytest.raises(AttributeError):
        records[0].frame = 3


def test_evaluate_into_writes_the_callers_array(database, test_driver, host_device):
    evaluator = ds.Evaluator(database, ds.EvaluatorSettings(), host_device)
    expected, _ = evaluator.evaluate([1, 2, 3], test_driver[:3])
    out = np.full((3, 2244, 3), np.nan, dtype=np.float32)
    address = out.__array_interface__["data"][0]
    records = evaluator.evaluate_into([1, 2, 3], test_driver[:3], out)
    assert out.__array_interface__["data"][0] == address and len(records) == 3
    assert_bitwise(out, expected, "evaluate_into")
    with pytest.raises(ds.Error) as error:
        evaluator.evaluate_into([1], test_driver[0], database.driven_mesh.positions)
    assert error.value.kind == "usage" and "writable" in str(error.value)
    with pytest.raises(ds.Error) as error:
        evaluator.evaluate_into([1, 2, 3], test_driver[:3], out.astype(np.float64))
    assert error.value.kind == "usage" and "float32" in str(error.value)
    empty, records = evaluator.evaluate([], np.empty((0, 2146, 3), np.float32))
    assert empty.shape == (0, 2244, 3) and records == []
    with pytest.raises(ds.Error) as error:
        evaluator.evaluate_into([1, 2], test_driver[:2], out)
    assert error.value.kind == "usage" and "(2, 2244, 3)" in str(error.value)


def test_driver_input_is_not_copied_when_float32(database, test_driver, host_device):
    # A float32 C-contiguous driver is read in place; other dtypes are converted, equal result.
    evaluator = ds.Evaluator(database, ds.EvaluatorSettings(), host_device)
    first, _ = evaluator.evaluate([2], test_driver[1:2])
    second, _ = evaluator.evaluate([2], test_driver[1:2].astype(np.float64))
    assert_bitwise(second, first, "float64 driver")


def test_bad_driver_inputs_name_the_frame_and_vertex(database, test_driver, host_device):
    evaluator = ds.Evaluator(database, ds.EvaluatorSettings(), host_device)
    with pytest.raises(ds.Error) as error:
        evaluator.evaluate([1], test_driver[0, :2000])
    assert error.value.kind == "input" and "2000" in str(error.value)
    assert "2146" in str(error.value)
    broken = test_driver[:3].copy()
    broken[1, 77, 2] = np.nan
    with pytest.raises(ds.Error) as error:
        evaluator.evaluate([1, 2, 3], broken)
    message = str(error.value)
    assert error.value.kind == "input" and "frame 2" in message and "77" in message
    with pytest.raises(ds.Error) as error:
        evaluator.evaluate([1, 2], test_driver[:3])
    assert error.value.kind == "usage" and "3 frames" in str(error.value)


def test_build_database_errors_name_the_cache(data, tmp_path):
    # A driven cache of another mesh: the message names the cache and both vertex counts.
    with pytest.raises(ds.Error) as error:
        ds.build_database(data / "driver_rest.obj", data / "driven_rest.obj",
                          data / "train.driver.pc2", data / "test.driver.pc2")
    assert error.value.kind == "input" and "test.driver.pc2" in str(error.value)
    for loader, name in ((ds.read_obj, "missing.obj"), (ds.open_point_cache, "missing.pc2"),
                         (ds.load_database, "missing.dsdb"), (ds.read_pc2, "missing.pc2")):
        with pytest.raises(ds.Error) as error:
            loader(tmp_path / name)
        assert error.value.kind == "input" and name in str(error.value)
    log = io.StringIO()
    arrays = [ds.read_pc2(data / f"train.{side}.pc2")[0] for side in ("driver", "driven")]
    db = ds.build_database(ds.read_obj(data / "driver_rest.obj"),
                           ds.read_obj(data / "driven_rest.obj"), arrays[0], arrays[1][:10],
                           count=5, frames=range(1, 11), start_frame=1, remove_frames=[3],
                           log=log)
    assert db.shape_count == 5 and 3 not in db.frames and max(db.frames) <= 10
    assert log.getvalue()  # the pick log
    db.save(tmp_path / "small.dsdb")
    assert ds.load_database(tmp_path / "small.dsdb").content_hash == db.content_hash
    assert db.driver_shapes.shape == (5, 2146, 3) and not db.driver_shapes.flags.writeable


def test_build_database_with_more_clips(data):
    # db build --also: the picks stay those of the main clip, the pose model sees both clips.
    log = io.StringIO()
    args = (data / "driver_rest.obj", data / "driven_rest.obj", data / "train.driver.pc2",
            data / "train.driven.pc2")
    one = ds.build_database(*args, count=5)
    clip = (data / "test.driver.pc2", data / "test.driven.pc2", range(1, 25))
    two = ds.build_database(*args, count=5, log=log, also=[clip])
    assert two.frames == one.frames and two.content_hash != one.content_hash
    assert "reference clip 2" in log.getvalue() and "main clip alone" in log.getvalue()
    with pytest.raises(ds.Error) as error:
        ds.build_database(*args, also=[(data / "test.driven.pc2", data / "test.driven.pc2")])
    assert error.value.kind == "input" and "test.driven.pc2" in str(error.value)
    with pytest.raises(ds.Error) as error:
        ds.build_database(*args, also=[(data / "test.driver.pc2",)])
    assert error.value.kind == "usage"


def test_evaluate_releases_the_gil(database, test_driver, host_device):
    evaluator = ds.Evaluator(database, ds.EvaluatorSettings(threads=1), host_device)
    started = time.perf_counter()
    evaluator.evaluate(TEST_FRAMES[:12], test_driver[:12])
    duration = time.perf_counter() - started
    worker = threading.Thread(target=evaluator.evaluate, args=(TEST_FRAMES[:12],
                                                               test_driver[:12]))
    ticks = []
    worker.start()
    while worker.is_alive():
        ticks.append(time.perf_counter())
        time.sleep(0.001)
    worker.join()
    gaps = np.diff(ticks) if len(ticks) > 1 else [duration]
    # With the GIL held for the whole call this thread would stall for `duration`.
    assert len(ticks) > 10 and max(gaps) < 0.5 * duration, (
        f"{len(ticks)} ticks, longest gap {max(gaps):.3f} s of a {duration:.3f} s evaluate")
