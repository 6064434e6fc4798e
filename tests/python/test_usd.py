# SPDX-License-Identifier: Apache-2.0
"""USD in and out (drivenshape.usd): the sample's test driver PC2 written as a UsdGeomMesh, baked
through `python -m drivenshape.usd bake`, and read back with usd-core: the cloth's points must
be bitwise the command line's bake of the PC2 (its EXRs read by the OpenEXR PyPI package).
Written stages are checked by usd-core's validators (UsdValidation, the successor of
UsdUtils.ComplianceChecker, which usd-core 26 no longer ships)."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from pxr import Usd, UsdGeom, UsdValidation

import drivenshape as ds
from conftest import TEST_FRAMES, assert_bitwise, parse_obj, parse_pc2
from drivenshape import usd


def validation_errors(path):
    """What every registered usd-core validator says about the stage, as text lines."""
    validators = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()
    errors = UsdValidation.ValidationContext(validators).Validate(Usd.Stage.Open(str(path)))
    return [f"{e.GetName()} ({e.GetType()}): {e.GetMessage()}" for e in errors]


def z_up_to_y_up(xyz):
    """(x, y, z) -> (x, z, -y) on the float32 bit patterns (the sign flip is bit 31)."""
    bits = np.ascontiguousarray(xyz, dtype=np.float32).view(np.uint32)
    out = np.stack([bits[..., 0], bits[..., 2], bits[..., 1] ^ np.uint32(0x80000000)], axis=-1)
    return np.ascontiguousarray(out).view(np.float32)


def usd_bake(*args, expect=0):
    command = [sys.executable, "-m", "drivenshape.usd", "bake", *map(str, args)]
    result = subprocess.run(command, capture_output=True, text=True, env=os.environ)
    assert result.returncode == expect, (f"{' '.join(command)} exited {result.returncode}, "
                                         f"expected {expect}:\n{result.stdout}{result.stderr}")
    return result


@pytest.fixture(scope="module")
def database(cli_database):
    return ds.load_database(cli_database)


@pytest.fixture(scope="module")
def driver_usd(database, data, tmp_path_factory):
    """The test driver PC2 as a UsdGeomMesh (written by the module) with the driver's faces."""
    positions, _, _ = parse_pc2(data / "test.driver.pc2")
    path = tmp_path_factory.mktemp("usd") / "shot.usda"
    usd.write_mesh_usd(path, database.driver_mesh, TEST_FRAMES, positions,
                       prim_path="/Character/Arm", fps=24.0)
    return path


def test_driver_stage_holds_the_pc2_exactly(driver_usd, data):
    positions, _, _ = parse_pc2(data / "test.driver.pc2")
    stage = Usd.Stage.Open(str(driver_usd))
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/Character/Arm"))
    assert [round(t) for t in mesh.GetPointsAttr().GetTimeSamples()] == TEST_FRAMES
    for frame in (1, 17, 48):
        points = np.asarray(mesh.GetPointsAttr().Get(frame), dtype=np.float32)
        assert_bitwise(points, positions[frame - 1], f"driver points at {frame}")
    assert validation_errors(driver_usd) == []


def test_usd_bake_equals_the_pc2_bake(driver_usd, cli_bakes, data, tmp_path, opencl_device):
    out = tmp_path / "cloth.usdc"
    result = usd_bake("--db", cli_bakes.database, "--usd", driver_usd, "--prim",
                      "/Character/Arm", "--out", out)
    assert "48 frames" in result.stdout and opencl_device.description in result.stdout
    reference = cli_bakes.frames("auto", TEST_FRAMES, reader="openexr")

    stage = Usd.Stage.Open(str(out))
    assert validation_errors(out) == []
    assert UsdGeom.GetStageUpAxis(stage) == "Z" and UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert stage.GetTimeCodesPerSecond() == 24.0
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (1.0, 48.0)
    assert stage.GetDefaultPrim().GetPath() == "/Garment"
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/Garment/Mesh"))
    assert [round(t) for t in mesh.GetPointsAttr().GetTimeSamples()] == TEST_FRAMES
    for index, frame in enumerate(TEST_FRAMES):
        points = np.asarray(mesh.GetPointsAttr().Get(frame), dtype=np.float32)
        assert_bitwise(points, reference[index], f"USD cloth at frame {frame}")
        extent = np.asarray(mesh.GetExtentAttr().Get(frame), dtype=np.float32)
        assert_bitwise(extent, np.stack([reference[index].min(0), reference[index].max(0)]),
                       f"extent at frame {frame}")
    # Faces and UVs of the driven rest mesh, parsed here from its OBJ.
    _, sizes, corners = parse_obj(data / "driven_rest.obj")
    assert list(mesh.GetFaceVertexCountsAttr().Get()) == sizes.tolist()
    assert list(mesh.GetFaceVertexIndicesAttr().Get()) == corners.tolist()
    st = UsdGeom.PrimvarsAPI(mesh).GetPrimvar("st")
    assert st and st.GetInterpolation() == UsdGeom.Tokens.faceVarying
    assert len(st.GetIndices()) == len(corners)


def test_usd_bake_with_the_defaults_equals_the_cli_bake_with_the_pose_model(
        driver_usd, pose_bakes, tmp_path, opencl_device):
    # Issue 27: the USD bake offered --weights qp|nearest|bind with qp as its default, so its
    # cloth was 14-39 mm from the default (pose-model) bake of every other tool.
    out = tmp_path / "cloth_pose.usdc"
    usd_bake("--db", pose_bakes.database, "--usd", driver_usd, "--prim", "/Character/Arm",
             "--out", out)
    reference = pose_bakes.frames("auto", TEST_FRAMES, reader="openexr")
    stage = Usd.Stage.Open(str(out))
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/Garment/Mesh"))
    for index, frame in enumerate(TEST_FRAMES):
        points = np.asarray(mesh.GetPointsAttr().Get(frame), dtype=np.float32)
        assert_bitwise(points, reference[index], f"USD pose-model cloth at frame {frame}")
    # The tool's defaults are the library's.
    args = usd._parser().parse_args(["bake", "--db", "x", "--usd", "y", "--prim", "/p",
                                     "--out", "z"])
    defaults = ds.EvaluatorSettings()
    for row in ds.settings_table():
        if row["scope"] == "evaluator" and row["flag"] and row["type"] != "object":
            assert getattr(args, row["key"]) == getattr(defaults, row["key"]), row["key"]


def test_usd_bake_prints_the_evaluators_warnings_as_the_cli_does(
        driver_usd, pose_bakes, tmp_path, opencl_device):
    # A tolerance below the database's smallest error bound: the library warns that every frame
    # is flagged; the tool prints it as one "warning:" line, also with --quiet.
    result = usd_bake("--db", pose_bakes.database, "--usd", driver_usd, "--prim",
                      "/Character/Arm", "--out", tmp_path / "warned.usdc",
                      "--coverage-tolerance", "0.001", "--quiet")
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("warning: the coverage tolerance 0.001 "), \
        result.stderr
    assert "every frame will be flagged for simulation" in lines[0]


def test_usd_bake_through_the_api_on_the_host(driver_usd, cli_bakes, database, tmp_path,
                                              host_device):
    out = tmp_path / "cloth_host.usda"
    shot = usd.read_mesh_animation(driver_usd, "/Character/Arm", frames=[3, 4, 5, 9])
    summary = usd.bake(database, shot, out, device=host_device, up_axis="Y",
                       meters_per_unit=0.01, fps=25.0, out_prim="/Cloth")
    assert summary["frames"] == [3, 4, 5, 9] and len(summary["records"]) == 4
    reference = cli_bakes.frames("host", [3, 4, 5, 9], reader="openexr")
    stage = Usd.Stage.Open(str(out))
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/Cloth"))
    # The driver stage is Z up (write_mesh_usd's default), the output Y up: the cloth's points
    # are the bake's rotated, (x, y, z) -> (x, z, -y), bit for bit (built here on the bits).
    for index, frame in enumerate([3, 4, 5, 9]):
        points = np.asarray(mesh.GetPointsAttr().Get(frame), dtype=np.float32)
        assert_bitwise(points, z_up_to_y_up(reference[index]), f"host USD cloth at {frame}")
    assert UsdGeom.GetStageUpAxis(stage) == "Y" and UsdGeom.GetStageMetersPerUnit(stage) == 0.01
    assert stage.GetTimeCodesPerSecond() == 25.0
    assert validation_errors(out) == []


def test_write_mesh_usd_converts_points_to_the_stage_axis(database, data, tmp_path):
    cloth, _, _ = parse_pc2(data / "test.driven.pc2")
    frames = [1, 2, 3]
    # drivenshape's Z-up points into a Y-up stage: rotated, exactly.
    path = tmp_path / "y_up.usda"
    usd.write_mesh_usd(path, database.driven_mesh, frames, cloth[:3], up_axis="Y",
                       points_up_axis="Z")
    stage = Usd.Stage.Open(str(path))
    assert UsdGeom.GetStageUpAxis(stage) == "Y"
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/Garment/Mesh"))
    for index, frame in enumerate(frames):
        points = np.asarray(mesh.GetPointsAttr().Get(frame), dtype=np.float32)
        assert_bitwise(points, z_up_to_y_up(cloth[index]), f"Y-up points at {frame}")
        extent = np.asarray(mesh.GetExtentAttr().Get(frame), dtype=np.float32)
        rotated = z_up_to_y_up(cloth[index])
        assert_bitwise(extent, np.stack([rotated.min(0), rotated.max(0)]), "Y-up extent")
    assert validation_errors(path) == []
    # Points already in the stage's axis (points_up_axis None or equal) are written as given.
    for points_axis in (None, "Y"):
        same = tmp_path / f"as_given_{points_axis}.usda"
        usd.write_mesh_usd(same, database.driven_mesh, [1], cloth[:1], up_axis="Y",
                           points_up_axis=points_axis)
        same_stage = Usd.Stage.Open(str(same))  # kept: the prim lives as long as its stage
        mesh = UsdGeom.Mesh(same_stage.GetPrimAtPath("/Garment/Mesh"))
        assert_bitwise(np.asarray(mesh.GetPointsAttr().Get(1), dtype=np.float32), cloth[0],
                       f"points_up_axis={points_axis}")
    with pytest.raises(ds.Error, match="points up axis 'X'"):
        usd.write_mesh_usd(tmp_path / "bad.usda", database.driven_mesh, [1], cloth[:1],
                           points_up_axis="X")


def test_usd_bake_up_axis_flag_rotates_the_cloth(driver_usd, cli_bakes, tmp_path):
    out = tmp_path / "cloth_y.usda"
    usd_bake("--db", cli_bakes.database, "--usd", driver_usd, "--prim", "/Character/Arm",
             "--out", out, "--frames", "3-5", "--device", "host", "--up-axis", "Y", "--quiet")
    reference = cli_bakes.frames("host", [3, 4, 5], reader="openexr")
    stage = Usd.Stage.Open(str(out))
    assert UsdGeom.GetStageUpAxis(stage) == "Y"
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/Garment/Mesh"))
    for index, frame in enumerate([3, 4, 5]):
        points = np.asarray(mesh.GetPointsAttr().Get(frame), dtype=np.float32)
        assert_bitwise(points, z_up_to_y_up(reference[index]), f"--up-axis Y cloth at {frame}")
    assert validation_errors(out) == []
    result = usd_bake("--db", cli_bakes.database, "--usd", driver_usd, "--prim",
                      "/Character/Arm", "--out", tmp_path / "never.usda", "--up-axis", "X",
                      expect=2)
    assert "--up-axis" in result.stderr


def test_the_validators_do_find_problems(tmp_path):
    # A stage without upAxis, metersPerUnit and a default prim: proof the checks run.
    path = tmp_path / "bare.usda"
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.Mesh.Define(stage, "/Bare")
    stage.GetRootLayer().Save()
    errors = "\n".join(validation_errors(path))
    for missing in ("upAxis", "metersPerUnit", "defaultPrim"):
        assert missing in errors, f"no complaint about {missing}: {errors}"


def test_driver_problems_are_input_errors(driver_usd, database, cli_bakes, data, tmp_path):
    args = ("--db", cli_bakes.database, "--out", tmp_path / "never.usdc")
    result = usd_bake(*args, "--usd", driver_usd, "--prim", "/Character/Leg", expect=3)
    assert "no prim at '/Character/Leg'" in result.stderr and "/Character/Arm" in result.stderr
    result = usd_bake(*args, "--usd", tmp_path / "missing.usda", "--prim", "/A", expect=3)
    assert "missing.usda" in result.stderr
    result = usd_bake(*args, "--usd", driver_usd, "--prim", "/Character/Arm", "--frames",
                      "40-60", expect=3)
    assert "frame 49" in result.stderr
    # The cloth mesh given as the driver: a vertex count the database's driver does not have.
    cloth = tmp_path / "cloth_as_driver.usda"
    driven, _, _ = parse_pc2(data / "test.driven.pc2")
    usd.write_mesh_usd(cloth, database.driven_mesh, [1, 2], driven[:2], prim_path="/Cloth")
    result = usd_bake(*args, "--usd", cloth, "--prim", "/Cloth", expect=3)
    assert "2244 points but the database's driver mesh has 2146" in result.stderr
    # The right vertex count with other faces (every face's corners rotated).
    mesh = database.driver_mesh
    starts, corners = mesh.face_start, mesh.face_vertices.copy()
    for face in range(mesh.face_count):
        corners[starts[face]:starts[face + 1]] = np.roll(corners[starts[face]:starts[face + 1]],
                                                         1)
    rotated = {"counts": np.diff(starts), "indices": corners, "uvs": None, "groups": {}}
    other = tmp_path / "rotated.usda"
    usd.write_mesh_usd(other, rotated, [1], mesh.positions, prim_path="/Arm")
    result = usd_bake(*args, "--usd", other, "--prim", "/Arm", expect=3)
    assert "face 0 uses other vertices" in result.stderr
    assert not (tmp_path / "never.usdc").exists()
    # --ignore-topology accepts it (the vertex count matches).
    usd_bake("--db", cli_bakes.database, "--out", tmp_path / "ok.usdc", "--usd", other,
             "--prim", "/Arm", "--ignore-topology", "--device", "host", "--quiet")


def test_usage_and_output_errors(driver_usd, cli_bakes, tmp_path):
    result = usd_bake("--help")
    assert "Exit codes: 0 ok, 2 usage, 3 input" in result.stdout and "--prim" in result.stdout
    usd_bake("--db", cli_bakes.database, "--usd", driver_usd, expect=2)  # no --prim, --out
    result = usd_bake("--db", cli_bakes.database, "--usd", driver_usd, "--prim",
                      "/Character/Arm", "--out", tmp_path / "cloth.usdc", "--frames", "5-1",
                      expect=2)
    assert "5-1" in result.stderr
    result = usd_bake("--db", cli_bakes.database, "--usd", driver_usd, "--prim",
                      "/Character/Arm", "--out", tmp_path / "no" / "cloth.usdc", "--device",
                      "host", expect=4)
    assert "does not exist" in result.stderr


def test_world_space_applies_the_prims_transform(database, data, tmp_path):
    from pxr import Gf

    positions, _, _ = parse_pc2(data / "test.driver.pc2")
    path = tmp_path / "moved.usda"
    usd.write_mesh_usd(path, database.driver_mesh, [1, 2], positions[:2],
                       prim_path="/Character/Arm")
    stage = Usd.Stage.Open(str(path))
    xform = UsdGeom.Xformable(stage.GetPrimAtPath("/Character"))
    xform.AddTranslateOp().Set(Gf.Vec3d(1.0, 2.0, 3.0))
    xform.AddRotateZOp().Set(90.0)  # applied first: (x, y, z) -> (-y, x, z), then translated
    stage.Save()
    local = usd.read_mesh_animation(path, "/Character/Arm")
    world = usd.read_mesh_animation(path, "/Character/Arm", space="world")
    assert_bitwise(local.positions, positions[:2], "local points")
    expected = np.stack([-positions[:2, :, 1] + 1.0, positions[:2, :, 0] + 2.0,
                         positions[:2, :, 2] + 3.0], axis=-1)
    # Tolerance: the matrix's cos(90 degrees) is 6e-17, not 0; float32 rounding after it.
    assert np.abs(world.positions - expected).max() < 1e-6


def uv_sphere(rings=48, segments=96, radius=0.3):
    """A closed UV sphere: quads between rings, triangle fans at the poles, faces wound
    counter-clockwise seen from outside. Returns (points (V, 3), counts, indices)."""
    points = [(0.0, 0.0, radius)]
    for ring in range(1, rings):
        polar = np.pi * ring / rings
        for segment in range(segments):
            azimuth = 2 * np.pi * segment / segments
            points.append((radius * np.sin(polar) * np.cos(azimuth),
                           radius * np.sin(polar) * np.sin(azimuth), radius * np.cos(polar)))
    points.append((0.0, 0.0, -radius))
    south = len(points) - 1

    def at(ring, segment):  # ring 1..rings-1
        return 1 + (ring - 1) * segments + segment % segments

    counts, indices = [], []
    for segment in range(segments):
        counts.append(3)
        indices += [0, at(1, segment), at(1, segment + 1)]
        counts.append(3)
        indices += [south, at(rings - 1, segment + 1), at(rings - 1, segment)]
    for ring in range(1, rings - 1):
        for segment in range(segments):
            counts.append(4)
            indices += [at(ring, segment), at(ring + 1, segment), at(ring + 1, segment + 1),
                        at(ring, segment + 1)]
    return np.asarray(points, dtype=np.float32), np.asarray(counts), np.asarray(indices)


# The largest angle between a vertex normal of the 48 x 96 sphere and its exact radial normal:
# the discretisation alone (the fan normals of a quad at a vertex lean by about half a ring).
SPHERE_NORMAL_DEGREES = 2.0
# Velocities against the point differences they come from: float32 rounding of both.
VELOCITY_RELATIVE = 1e-5


def test_written_normals_are_the_surface_normals_and_velocities_the_point_differences(
        tmp_path):
    points, counts, indices = uv_sphere()
    mesh = {"counts": counts, "indices": indices, "uvs": None, "groups": {}}
    frames = [10, 11, 12, 14]  # a gap: the velocity spans the time between samples
    shifts = np.asarray([[0, 0, 0], [0.01, 0, 0], [0.03, 0.01, 0], [0.05, 0.05, 0.02]],
                        dtype=np.float32)
    positions = np.stack([points + shift for shift in shifts])
    out = tmp_path / "sphere.usda"
    usd.write_mesh_usd(out, mesh, frames, positions, prim_path="/Ball/Mesh", fps=24.0)
    stage = Usd.Stage.Open(str(out))
    geom = UsdGeom.Mesh(stage.GetPrimAtPath("/Ball/Mesh"))
    assert geom.GetNormalsInterpolation() == UsdGeom.Tokens.vertex
    for index, frame in enumerate(frames):
        normals = np.asarray(geom.GetNormalsAttr().Get(frame), dtype=np.float64)
        radial = positions[index] - shifts[index]
        radial = radial / np.linalg.norm(radial, axis=1, keepdims=True)
        cosine = np.clip(np.sum(normals * radial, axis=1), -1, 1)
        worst = np.degrees(np.arccos(cosine)).max()
        assert worst < SPHERE_NORMAL_DEGREES, f"frame {frame}: a normal {worst:.2f} deg off"
    seconds = np.asarray(frames, dtype=np.float64) / 24.0
    for index, frame in enumerate(frames):
        before, after = max(index - 1, 0), min(index + 1, len(frames) - 1)
        expected = (positions[after].astype(np.float64) - positions[before]) / (
            seconds[after] - seconds[before])
        velocities = np.asarray(geom.GetVelocitiesAttr().Get(frame), dtype=np.float64)
        scale = np.abs(expected).max()
        assert np.abs(velocities - expected).max() <= VELOCITY_RELATIVE * scale, frame
    assert Usd.ModelAPI(stage.GetPrimAtPath("/Ball")).GetKind() == "component"
    assert validation_errors(out) == []


def test_usd_bake_records_its_provenance(driver_usd, pose_bakes, tmp_path, opencl_device):
    out = tmp_path / "cloth.usdc"
    usd_bake("--db", pose_bakes.database, "--usd", driver_usd, "--prim", "/Character/Arm",
             "--out", out)
    report = json.loads(
        (pose_bakes.folder("auto") / "sleeve.report.json").read_text(encoding="utf-8"))
    stage = Usd.Stage.Open(str(out))
    mesh = stage.GetPrimAtPath("/Garment/Mesh")
    provenance = mesh.GetCustomDataByKey("drivenshape")
    assert provenance["tool_version"] == ds.__version__
    # The database the CLI bake read; the default evaluator's hash (the EXR bake's own hash
    # also covers its file options), which another setting changes.
    assert provenance["database_content_hash"] == report["database"]["content_hash"]
    defaults = ds.Evaluator(ds.load_database(pose_bakes.database), ds.EvaluatorSettings(),
                            ds.open_device("host"))
    assert provenance["evaluator_settings_hash"] == format(defaults.settings_hash, "016x")
    other = tmp_path / "cloth_fade.usdc"
    usd_bake("--db", pose_bakes.database, "--usd", driver_usd, "--prim", "/Character/Arm",
             "--out", other, "--exit-fade", "0.05")
    other_stage = Usd.Stage.Open(str(other))
    changed = other_stage.GetPrimAtPath("/Garment/Mesh").GetCustomDataByKey("drivenshape")
    assert changed["evaluator_settings_hash"] != provenance["evaluator_settings_hash"]
    assert provenance["database"] == os.path.abspath(pose_bakes.database)
    assert provenance["driver"] == f"{os.path.abspath(driver_usd)}:/Character/Arm"
    geom = UsdGeom.Mesh(mesh)
    assert geom.GetNormalsAttr().GetTimeSamples() == [float(f) for f in TEST_FRAMES]
    assert geom.GetVelocitiesAttr().GetTimeSamples() == [float(f) for f in TEST_FRAMES]
    assert validation_errors(out) == []


# ---- Issue 42: inputs kept, modes, the driver check, and the CLI's frames and verdict -----------

def test_an_output_that_is_an_input_is_refused(driver_usd, cli_bakes, data, tmp_path):
    """`bake --out` equal to `--usd` replaced the shot's driver animation. Outputs are compared
    with every input by name and by file identity (a link, a hard link)."""
    shot = tmp_path / "shot.usda"
    shot.write_bytes(driver_usd.read_bytes())
    original = shot.read_bytes()
    (tmp_path / "link.usda").symlink_to(shot)
    os.link(shot, tmp_path / "hard.usda")
    args = ("--db", cli_bakes.database, "--usd", shot, "--prim", "/Character/Arm",
            "--device", "host")
    for out in (shot, tmp_path / "link.usda", tmp_path / "hard.usda",
                tmp_path / "." / "shot.usda"):
        result = usd_bake(*args, "--out", out, expect=2)
        assert "would overwrite the input --usd" in result.stderr, result.stderr
    result = usd_bake(*args, "--out", tmp_path / "cloth.usdc", "--report", cli_bakes.database,
                      expect=2)
    assert "would overwrite the input --db" in result.stderr
    result = usd_bake(*args, "--out", tmp_path / "cloth.usdc", "--report",
                      tmp_path / "cloth.usdc", expect=2)
    assert "name the same file" in result.stderr
    # Through the API: the output against the stage and its layers.
    with pytest.raises(ds.Error, match="would overwrite the input"):
        usd.bake(cli_bakes.database, usd.read_mesh_animation(shot, "/Character/Arm"),
                 tmp_path / "hard.usda", device="host")
    # export: the output against the mesh, the PC2 and every EXR frame.
    export = [sys.executable, "-m", "drivenshape.usd", "export", "--mesh",
              str(data / "driven_rest.obj")]
    pc2 = tmp_path / "cloth.pc2"
    pc2.write_bytes((data / "test.driven.pc2").read_bytes())
    pc2_link = tmp_path / "cloth_pc2.usda"
    pc2_link.symlink_to(pc2)
    frames = cli_bakes.folder("host")
    exr_link = tmp_path / "frame.usda"
    exr_link.symlink_to(frames / "sleeve.0003.exr")
    exr_frames = str(frames / "sleeve.####.exr")
    for extra in (["--pc2", str(pc2), "-o", str(pc2_link)],
                  ["--exr", exr_frames, "--frames", "1-5", "-o", str(exr_link)]):
        result = subprocess.run(export + extra, capture_output=True, text=True)
        assert result.returncode == 2 and "would overwrite the input" in result.stderr, \
            result.stderr
    assert shot.read_bytes() == original and pc2.read_bytes() == (
        data / "test.driven.pc2").read_bytes()
    assert (frames / "sleeve.0003.exr").stat().st_size > 0


@pytest.mark.parametrize("mask", [0o022, 0o027])
def test_stages_and_reports_get_the_users_umask(driver_usd, cli_bakes, tmp_path, mask):
    """USD files were written 0600 (mkstemp's mode): render nodes and other users could not
    read them."""
    out = tmp_path / "cloth.usdc"
    command = [sys.executable, "-m", "drivenshape.usd", "bake", "--db", str(cli_bakes.database),
               "--usd", str(driver_usd), "--prim", "/Character/Arm", "--out", str(out),
               "--frames", "1-3", "--device", "host", "--quiet"]
    result = subprocess.run(command, capture_output=True, text=True,
                            preexec_fn=lambda: os.umask(mask))
    assert result.returncode == 0, result.stderr
    for path in (out, tmp_path / "cloth.report.json"):
        assert path.stat().st_mode & 0o777 == 0o666 & ~mask, (path, oct(path.stat().st_mode))
    old = os.umask(mask)
    try:
        usd.write_mesh_usd(tmp_path / "api.usda", {"counts": [3], "indices": [0, 1, 2]}, [1],
                           np.eye(3, dtype=np.float32))
    finally:
        os.umask(old)
    assert (tmp_path / "api.usda").stat().st_mode & 0o777 == 0o666 & ~mask


def test_usd_bake_checks_the_driver_as_the_cli_does(database, pose_bakes, data, tmp_path,
                                                    cli):
    """A centimetre driver baked silently; --fps 0 and --meters-per-unit 0 were ignored."""
    positions, _, _ = parse_pc2(data / "test.driver.pc2")
    centimetres = tmp_path / "shot_cm.usda"
    usd.write_mesh_usd(centimetres, database.driver_mesh, [1, 2, 3], positions[:3] * 100,
                       prim_path="/Character/Arm")
    args = ("--db", pose_bakes.database, "--usd", centimetres, "--prim", "/Character/Arm",
            "--device", "host")
    result = usd_bake(*args, "--out", tmp_path / "cm.usdc", expect=3)
    # The library's own finding, word for word the command line's (bake of the same points).
    pc2 = tmp_path / "shot_cm.pc2"
    ds.write_pc2(pc2, positions[:3] * 100)
    cli_result = subprocess.run([cli, "bake", "--db", pose_bakes.database, "--driver", pc2,
                                 "--frames", "1-3", "-o", tmp_path / "cm" / "c.####.exr",
                                 "--device", "host"], capture_output=True, text=True)
    assert cli_result.returncode == 3
    finding = cli_result.stderr.strip().split("error: ", 1)[1].split(str(pc2))[-1]
    assert finding[:40] in result.stderr, (finding, result.stderr)
    assert not (tmp_path / "cm.usdc").exists()
    forced = usd_bake(*args, "--out", tmp_path / "cm.usdc", "--force")
    assert "warning: forced: " in forced.stderr
    report = json.loads((tmp_path / "cm.report.json").read_text())
    assert any(w.startswith("forced: ") for w in report["warnings"])
    for option in ("--fps", "--meters-per-unit"):
        for value in ("0", "-24", "nan", "inf"):
            result = usd_bake("--db", pose_bakes.database, "--usd", centimetres, "--prim",
                              "/Character/Arm", "--out", tmp_path / "never.usdc", option,
                              value, expect=2)
            assert option in result.stderr and "positive" in result.stderr, result.stderr
    assert not (tmp_path / "never.usdc").exists()


@pytest.mark.parametrize("frames", ["10-20", "30-48", "5,9-12"])
def test_a_sub_range_is_the_cli_bake_of_those_frames_with_its_report(
        driver_usd, pose_bakes, tmp_path, frames):
    """With the default database (the pose model, which reads each frame's history), `usd bake
    --frames 10-20` read only frames 10-20 and so gave other cloth than `drivenshape bake
    --frames 10-20` (11.8 mm at frame 10), and wrote no report or verdict. It now plans with
    the library's shot planner: bitwise the CLI's cloth, and the CLI's report (records and
    verdict)."""
    wanted = ds.parse_frame_range(frames)
    out = tmp_path / "cloth.usdc"
    result = usd_bake("--db", pose_bakes.database, "--usd", driver_usd, "--prim",
                      "/Character/Arm", "--out", out, "--frames", frames, "--device", "host")
    reference = pose_bakes.frames("host", wanted, frame_text=frames, reader="openexr")
    stage = Usd.Stage.Open(str(out))
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/Garment/Mesh"))
    assert [round(t) for t in mesh.GetPointsAttr().GetTimeSamples()] == wanted
    for index, frame in enumerate(wanted):
        points = np.asarray(mesh.GetPointsAttr().Get(frame), dtype=np.float32)
        assert_bitwise(points, reference[index], f"USD bake --frames {frames} at {frame}")
    mine = json.loads((tmp_path / "cloth.report.json").read_text(encoding="utf-8"))
    cli_report = json.loads((pose_bakes.folder("host", frames=frames) / "sleeve.report.json")
                            .read_text(encoding="utf-8"))
    # Every frame's record is the CLI's, but for the file it went to (the stage, an EXR).
    assert [r.pop("output") for r in mine["frames"]] == [str(out)] * len(wanted)
    for record in cli_report["frames"]:
        record.pop("output")
    assert mine["frames"] == cli_report["frames"]
    assert mine["coverage"] == cli_report["coverage"]
    assert f"verdict: {cli_report['coverage']['verdict']}" in result.stdout
    for key in ("tool", "tool_version", "database", "device", "run"):
        assert mine[key] == cli_report[key], key
    assert mine["settings"]["weights"] == cli_report["settings"]["weights"]
    assert mine["driver_cache"] == f"{driver_usd}:/Character/Arm"
    import jsonschema

    schema = Path(__file__).resolve().parents[2] / "docs/schemas/bake_report.schema.json"
    jsonschema.validate(json.loads((tmp_path / "cloth.report.json").read_text()),
                        json.loads(schema.read_text(encoding="utf-8")))


def test_the_module_gives_the_shots_verdict_and_its_runs(pose_bakes, data, host_device):
    """shot_verdict and simulation_runs: the report's coverage object, from the records of
    evaluate_cache, as the CLI's bake of the same frames writes it."""
    db = ds.load_database(pose_bakes.database)
    settings = ds.EvaluatorSettings()
    settings.coverage_tolerance = 0.0225  # flags some of the sample's frames
    evaluator = ds.Evaluator(db, settings, host_device)
    cache = ds.open_point_cache(data / "test.driver.pc2")
    _, records = ds.evaluate_cache(evaluator, cache, list(range(1, 25)))
    verdict = ds.shot_verdict(evaluator, records)
    folder = pose_bakes.folder("host", "--coverage-tolerance", "0.0225", frames="1-24")
    report = json.loads((folder / "sleeve.report.json").read_text(encoding="utf-8"))
    assert verdict == report["coverage"]
    flagged = [r.frame for r in records if r.flagged == 1]
    assert flagged, "the tolerance flags no frame: the test shows nothing"
    runs = [{"from": a, "to": b, "wanted": n} for a, b, n in ds.simulation_runs(flagged, 1)]
    assert runs == report["coverage"]["simulate_runs"]
    # The model without predictions has no verdict.
    none = ds.Evaluator(db, ds.EvaluatorSettings(weight_mode="bind"), host_device)
    assert ds.shot_verdict(none, ds.evaluate_cache(none, cache, [1, 2])[1]) is None
