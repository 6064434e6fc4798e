#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""`python -m drivenshape.usd export` end to end: files the tool writes (point-cache EXRs through
the library, PC2 + OBJ through `drivenshape export`) go through the command, and usd-core (pxr)
reads back the same points at a given time, the extents, the faces and the UVs. The expected
positions come from the bundled PC2, decoded here byte by byte. With --up-axis Y (both tools)
the stage says Y up and its points are the Z-up points rotated, (x, y, z) -> (x, z, -y), bit for
bit: the same bits as `drivenshape export --up-axis Y` writes, and every written stage passes
usd-core's validators. scripts/layering_preview.py (which reads through the module too) renders
both kinds of output. Any mismatch exits non-zero."""

import argparse
import os
import subprocess
import sys

import numpy as np
from pxr import Usd, UsdGeom, UsdValidation


def fail(message):
    print(f"test_export_usd: FAIL: {message}", file=sys.stderr)
    sys.exit(1)


def pc2_frames(path):
    data = open(path, "rb").read()
    points = int(np.frombuffer(data[16:20], "<i4")[0])
    start = float(np.frombuffer(data[20:24], "<f4")[0])
    rate = float(np.frombuffer(data[24:28], "<f4")[0])
    samples = int(np.frombuffer(data[28:32], "<i4")[0])
    xyz = np.frombuffer(data, "<f4", offset=32).reshape(samples, points, 3)
    return {round(start + s * rate): xyz[s] for s in range(samples)}


def z_up_to_y_up(xyz):
    """(x, y, z) -> (x, z, -y) on the float32 bit patterns: the sign flip is bit 31."""
    bits = np.ascontiguousarray(xyz, dtype=np.float32).view(np.uint32)
    out = np.stack([bits[..., 0], bits[..., 2], bits[..., 1] ^ np.uint32(0x80000000)], axis=-1)
    return np.ascontiguousarray(out).view(np.float32)


def same_bits(a, b):
    a, b = np.asarray(a, dtype=np.float32), np.asarray(b, dtype=np.float32)
    return a.shape == b.shape and np.array_equal(a.view(np.uint32), b.view(np.uint32))


def validation_errors(path):
    """What every registered usd-core validator says about the stage."""
    validators = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()
    errors = UsdValidation.ValidationContext(validators).Validate(Usd.Stage.Open(str(path)))
    return [f"{e.GetName()}: {e.GetMessage()}" for e in errors]


def obj_faces(path):
    counts, indices, uv_count = [], [], 0
    for line in open(path):
        words = line.split()
        if words and words[0] == "f":
            counts.append(len(words) - 1)
            indices.extend(int(w.split("/")[0]) - 1 for w in words[1:])
        elif words and words[0] == "vt":
            uv_count += 1
    return counts, indices, uv_count


def run(command, expect=0):
    result = subprocess.run(command, capture_output=True, text=True)
    if result.returncode != expect:
        fail(f"{' '.join(command)} exited {result.returncode}, expected {expect}:\n"
             f"{result.stdout}{result.stderr}")
    return result


def check_stage(path, mesh_path, expected, fps, up_axis="Z"):
    stage = Usd.Stage.Open(path)
    if stage is None:
        fail(f"usd-core cannot open {path}")
    if UsdGeom.GetStageUpAxis(stage) != up_axis:
        fail(f"{path}: upAxis {UsdGeom.GetStageUpAxis(stage)}, expected {up_axis}")
    errors = validation_errors(path)
    if errors:
        fail(f"{path}: usd-core's validators complain: {errors}")
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/Garment/Mesh"))
    if not mesh:
        fail(f"{path}: no UsdGeomMesh at /Garment/Mesh")
    if stage.GetTimeCodesPerSecond() != fps:
        fail(f"{path}: timeCodesPerSecond {stage.GetTimeCodesPerSecond()}, expected {fps}")
    counts, indices, uv_count = obj_faces(mesh_path)
    if list(mesh.GetFaceVertexCountsAttr().Get()) != counts:
        fail(f"{path}: faceVertexCounts differ from the OBJ")
    if list(mesh.GetFaceVertexIndicesAttr().Get()) != indices:
        fail(f"{path}: faceVertexIndices differ from the OBJ")
    st = UsdGeom.PrimvarsAPI(mesh).GetPrimvar("st")
    if uv_count and (not st or len(st.Get()) != uv_count or
                     st.GetInterpolation() != UsdGeom.Tokens.faceVarying):
        fail(f"{path}: primvars:st missing or not face-varying with {uv_count} values")
    times = mesh.GetPointsAttr().GetTimeSamples()
    if [round(t) for t in times] != sorted(expected):
        fail(f"{path}: time samples {times}, expected frames {sorted(expected)}")
    for frame, xyz in expected.items():
        points = np.array(mesh.GetPointsAttr().Get(frame), dtype=np.float32)
        if not same_bits(points, xyz):
            worst = np.abs(points - xyz).max() if points.shape == xyz.shape else "shape"
            fail(f"{path}: points at time {frame} differ from the cache (worst {worst})")
        extent = np.array(mesh.GetExtentAttr().Get(frame), dtype=np.float32)
        if not np.array_equal(extent, np.stack([xyz.min(axis=0), xyz.max(axis=0)])):
            fail(f"{path}: extent at time {frame} is not the bounds of the points")
    # Between samples USD interpolates linearly: a check that the samples are really timed.
    first, second = sorted(expected)[:2]
    middle = 0.5 * (first + second)
    points = np.array(mesh.GetPointsAttr().Get(middle), dtype=np.float64)
    linear = 0.5 * (expected[first].astype(np.float64) + expected[second].astype(np.float64))
    if np.abs(points - linear).max() > 1e-5 * (1.0 + np.abs(linear).max()):
        fail(f"{path}: points at time {middle} are not between the samples")


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--cli", required=True)
    parser.add_argument("--writer", required=True)
    parser.add_argument("--preview", required=True, help="scripts/layering_preview.py")
    parser.add_argument("--data", required=True)
    parser.add_argument("--work", required=True)
    args = parser.parse_args()
    python = sys.executable
    export = [python, "-m", "drivenshape.usd", "export"]
    rest = os.path.join(args.data, "sleeve", "driven_rest.obj")
    cache = os.path.join(args.data, "sleeve", "test.driven.pc2")
    truth = pc2_frames(cache)

    # 1. A point-cache EXR sequence written by the library, 25 fps in its headers.
    exr = os.path.join(args.work, "exr", "sleeve.####.exr")
    os.makedirs(os.path.dirname(exr), exist_ok=True)
    run([args.writer, cache, rest, "3", "7", exr, "25"])
    usdc = os.path.join(args.work, "from_exr.usdc")
    run([*export, "--mesh", rest, "--exr", exr, "--frames", "3-7", "-o", usdc])
    check_stage(usdc, rest, {f: truth[f] for f in range(3, 8)}, 25.0)

    # 2. `drivenshape export` guides (PC2 every other frame + first-frame OBJ), then USD.
    pc2 = os.path.join(args.work, "guides.pc2")
    first = os.path.join(args.work, "drape.obj")
    run([args.cli, "export", "--cache", cache, "--frames", "10-20x2", "--pc2", pc2, "--obj",
         first, "--mesh", rest, "--quiet"])
    usda = os.path.join(args.work, "from_pc2.usda")
    run([*export, "--mesh", first, "--pc2", pc2, "--fps", "24", "-o", usda])
    check_stage(usda, rest, {f: truth[f] for f in range(10, 21, 2)}, 24.0)

    # 2b. Y up: `drivenshape export --up-axis Y` rotates the PC2 and the OBJ; drivenshape.usd
    #     --up-axis Y rotates the Z-up EXRs and PC2 it reads. All of them hold the truth's points
    #     rotated, (x, y, z) -> (x, z, -y), bit for bit, and the stages say upAxis = "Y".
    pc2_y = os.path.join(args.work, "guides_y.pc2")
    first_y = os.path.join(args.work, "drape_y.obj")
    run([args.cli, "export", "--cache", cache, "--frames", "10-20x2", "--pc2", pc2_y, "--obj",
         first_y, "--mesh", rest, "--up-axis", "Y", "--quiet"])
    rotated = {f: z_up_to_y_up(truth[f]) for f in range(10, 21, 2)}
    exported = pc2_frames(pc2_y)
    if sorted(exported) != sorted(rotated) or not all(same_bits(exported[f], rotated[f])
                                                      for f in rotated):
        fail("`drivenshape export --up-axis Y` PC2 is not the rotated truth bit for bit")
    obj_points = np.array([line.split()[1:4] for line in open(first_y) if line.startswith("v ")],
                          dtype=np.float32)
    if not same_bits(obj_points, rotated[10]):
        fail("`drivenshape export --up-axis Y` OBJ is not the rotated first frame bit for bit")
    usd_y = os.path.join(args.work, "from_exr_y.usda")
    run([*export, "--mesh", rest, "--exr", exr, "--frames", "3-7", "--up-axis", "Y",
         "-o", usd_y])
    check_stage(usd_y, rest, {f: z_up_to_y_up(truth[f]) for f in range(3, 8)}, 25.0, "Y")
    usd_y = os.path.join(args.work, "from_pc2_y.usdc")
    run([*export, "--mesh", first, "--pc2", pc2, "--fps", "24", "--up-axis", "Y",
         "-o", usd_y])
    check_stage(usd_y, rest, exported, 24.0, "Y")  # the CLI's Y-up PC2, bit for bit
    result = run([args.cli, "export", "--cache", cache, "--frames", "10-20", "--pc2",
                  os.path.join(args.work, "never.pc2"), "--up-axis", "X"], expect=2)
    if "--up-axis 'X'" not in result.stderr:
        fail(f"a bad --up-axis is not named in the error: {result.stderr}")
    result = run([*export, "--mesh", rest, "--pc2", pc2, "--up-axis", "X", "-o",
                  os.path.join(args.work, "never.usda")], expect=2)
    if "--up-axis" not in result.stderr:
        fail(f"drivenshape.usd export's bad --up-axis error does not name the flag: "
             f"{result.stderr}")

    # 3. Bad input: a mesh with another vertex count is an input error (exit 3), no file left.
    bad = os.path.join(args.work, "bad.usda")
    result = run([*export, "--mesh", os.path.join(args.data, "sleeve",
                                                              "driver_rest.obj"),
                  "--pc2", pc2, "-o", bad], expect=3)
    if "points but" not in result.stderr or os.path.exists(bad):
        fail(f"wrong-mesh error unclear or a file was left: {result.stderr}")
    # 4. scripts/layering_preview.py renders both kinds of output to a PNG (a smoke test: the
    #    file is a PNG of the expected size; the picture itself is for people).
    preview = args.preview
    for source in (["--exr", exr, "--frame", "5"], ["--pc2", pc2, "--frame", "14"]):
        png = os.path.join(args.work, "preview.png")
        run([python, preview, "--mesh", rest, *source, "--mix-weight", "group:sleeve",
             "--compare", cache, "-o", png])
        header = open(png, "rb").read(24)
        width, height = int.from_bytes(header[16:20], "big"), int.from_bytes(header[20:24], "big")
        if header[:8] != b"\x89PNG\r\n\x1a\n" or width < 600 or height < 600:
            fail(f"layering_preview.py wrote no proper PNG ({width}x{height})")
        os.remove(png)

    leftovers = [n for n in os.listdir(args.work) if ".tmp-" in n]
    if leftovers:
        fail(f"temporary files left behind: {leftovers}")
    print("test_export_usd: EXR and PC2 exports, Z and Y up, read back identically with "
          "usd-core")


if __name__ == "__main__":
    main()
