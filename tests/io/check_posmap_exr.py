#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Reads a position map written by drivenshape back with the OpenEXR Python bindings.

Checks, on the bundled sleeve (channels R G B, A, N.R N.G N.B; check_posmap_readers.py checks
the layers as OpenImageIO and these bindings group them, and the legacy names):
  * P, A and N read back bit for bit equal to the arrays the C++ wrote (posmap_sample dumps
    them raw next to the EXR);
  * the header holds the documented attributes (dsKind, dsFrame, dsTopologyHash, ...);
  * at random covered texels P equals this script's own barycentric interpolation of the
    triangle under the texel centre (its own OBJ and PC2 readers, its own point-in-triangle
    search), within 1e-5 of the bounding-box diagonal;
  * texels farther than the padding from every covered texel are 0.

Run by CTest (test_posmap_python) through tests/support/run_python.cmake. A missing module
fails the test with what to do; it never skips.
"""

import argparse
import os
import subprocess
import sys

try:
    import numpy as np
    import OpenEXR
except ImportError as error:  # a failure, not a skip: CI must run this check
    print(f"check_posmap_exr: {error}; run scripts/setup.sh to create .venv with "
          "scripts/requirements.txt (numpy, OpenEXR)", file=sys.stderr)
    sys.exit(1)

FRAME = 13
WIDTH, HEIGHT = 96, 80
PADDING = 3
REL_TOL = 1e-5  # of the bounding-box diagonal (issue 6 acceptance)
SAMPLES = 400
SEED = int(os.environ.get("DS_SEED", "20081112"))


def read_obj(path):
    """Positions (V x 3), UVs (N x 2) and faces as lists of (vertex, uv) corners, 0-based."""
    positions, uvs, faces = [], [], []
    with open(path) as f:
        for line in f:
            parts = line.split()
            if not parts:
                continue
            if parts[0] == "v":
                positions.append([float(x) for x in parts[1:4]])
            elif parts[0] == "vt":
                uvs.append([float(x) for x in parts[1:3]])
            elif parts[0] == "f":
                face = []
                for corner in parts[1:]:
                    ids = corner.split("/")
                    v = int(ids[0])
                    t = int(ids[1])
                    face.append((v - 1 if v > 0 else len(positions) + v,
                                 t - 1 if t > 0 else len(uvs) + t))
                faces.append(face)
    return np.array(positions), np.array(uvs), faces


def read_pc2_frame(path, frame):
    with open(path, "rb") as f:
        header = f.read(32)
        assert header[:12] == b"POINTCACHE2\0", "not a PC2 file"
        points = int(np.frombuffer(header[16:20], "<i4")[0])
        start = float(np.frombuffer(header[20:24], "<f4")[0])
        rate = float(np.frombuffer(header[24:28], "<f4")[0])
        sample = int(round((frame - start) / rate))
        f.seek(32 + sample * points * 12)
        return np.frombuffer(f.read(points * 12), "<f4").reshape(points, 3).astype(np.float64)


def fan_triangles(faces):
    """(vertex ids T x 3, uv ids T x 3), fan order per face."""
    verts, uvids = [], []
    for face in faces:
        for i in range(1, len(face) - 1):
            corners = (face[0], face[i], face[i + 1])
            verts.append([c[0] for c in corners])
            uvids.append([c[1] for c in corners])
    return np.array(verts), np.array(uvids)


def locate(px, py, tx, ty):
    """Barycentrics of point (px, py) in every triangle (T x 3), in pixel space."""
    x0, y0 = tx[:, 0], ty[:, 0]
    d = (tx[:, 1] - x0) * (ty[:, 2] - y0) - (tx[:, 2] - x0) * (ty[:, 1] - y0)
    with np.errstate(divide="ignore", invalid="ignore"):
        b1 = ((px - x0) * (ty[:, 2] - y0) - (tx[:, 2] - x0) * (py - y0)) / d
        b2 = ((tx[:, 1] - x0) * (py - y0) - (px - x0) * (ty[:, 1] - y0)) / d
    return np.stack([1.0 - b1 - b2, b1, b2], axis=1)


def squeezed_sleeve(data, work):
    """The bundled sleeve with its UVs squeezed into part of the square, so that a map also has
    texels beyond the padding (the islands fill 96% of the square). Returns the OBJ's path."""
    mesh_path = os.path.join(work, "sleeve_squeezed.obj")
    with open(os.path.join(data, "sleeve", "driven_rest.obj")) as source, \
            open(mesh_path, "w") as target:
        for line in source:
            if line.startswith("vt "):
                u, v = (float(x) for x in line.split()[1:3])
                line = f"vt {0.1 + 0.6 * u:.6f} {0.3 + 0.6 * v:.6f}\n"
            target.write(line)
    return mesh_path


def fail(message):
    print(f"check_posmap_exr: FAILED: {message}", file=sys.stderr)
    sys.exit(1)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--writer", required=True, help="posmap_sample executable")
    parser.add_argument("--data", required=True, help="tests/data")
    parser.add_argument("--work", required=True, help="scratch folder")
    args = parser.parse_args()

    mesh_path = squeezed_sleeve(args.data, args.work)
    cache_path = os.path.join(args.data, "sleeve", "test.driven.pc2")
    exr = os.path.join(args.work, f"map.{FRAME:04d}.exr")
    subprocess.run([args.writer, mesh_path, cache_path, str(FRAME), f"{WIDTH}x{HEIGHT}",
                    str(PADDING), exr], check=True)

    image = OpenEXR.File(exr, separate_channels=True)
    header = image.header()
    channels = image.channels()
    for name in ("R", "G", "B", "A", "N.R", "N.G", "N.B"):  # the default naming
        if name not in channels:
            fail(f"channel {name} missing; the file has {sorted(channels)}")
        if channels[name].pixels.dtype != np.float32:
            fail(f"channel {name} is {channels[name].pixels.dtype}, expected float32")
    expected_header = {"dsKind": "positionMap", "dsFrame": FRAME, "dsMeshVertexCount": 2244,
                       "dsPadding": PADDING}
    for key, value in expected_header.items():
        if header.get(key) != value:
            fail(f"header {key} is {header.get(key)!r}, expected {value!r}")
    for key in ("dsTopologyHash", "dsToolVersion", "dsBoundsMin", "dsBoundsMax",
                "framesPerSecond", "dsUvLayout"):
        if key not in header:
            fail(f"header attribute {key} missing")
    if len(header["dsTopologyHash"]) != 16:
        fail(f"dsTopologyHash {header['dsTopologyHash']!r} is not 16 hex digits")

    def plane(name):
        return channels[name].pixels  # (H, W), row 0 = first scanline = top of the map

    P = np.stack([plane("R"), plane("G"), plane("B")], axis=-1)
    N = np.stack([plane("N.R"), plane("N.G"), plane("N.B")], axis=-1)
    A = plane("A")
    if P.shape != (HEIGHT, WIDTH, 3):
        fail(f"P is {P.shape}, expected {(HEIGHT, WIDTH, 3)}")

    # What the C++ wrote, bit for bit.
    raw = {k: np.fromfile(f"{exr}.{k}.raw", "<f4") for k in ("P", "A", "N")}
    for name, got, want in (("P", P, raw["P"].reshape(HEIGHT, WIDTH, 3)),
                            ("A", A, raw["A"].reshape(HEIGHT, WIDTH)),
                            ("N", N, raw["N"].reshape(HEIGHT, WIDTH, 3))):
        if not np.array_equal(got.view(np.uint32), want.view(np.uint32)):
            bad = np.argwhere(got != want)[:5]
            fail(f"{name} read back differs from what was written at (row, col) {bad.tolist()}")

    # Independent interpolation at random covered texels.
    positions, uvs, faces = read_obj(mesh_path)
    xyz = read_pc2_frame(cache_path, FRAME)
    if xyz.shape[0] != positions.shape[0]:
        fail("cache and mesh vertex counts differ")
    verts, uvids = fan_triangles(faces)
    tx = uvs[uvids, 0] * WIDTH
    ty = (1.0 - uvs[uvids, 1]) * HEIGHT
    diagonal = float(np.linalg.norm(xyz.max(axis=0) - xyz.min(axis=0)))
    covered = np.argwhere(A == 1.0)
    if len(covered) < 100:
        fail(f"only {len(covered)} covered texels")
    rng = np.random.default_rng(SEED)
    worst = 0.0
    for row, col in covered[rng.choice(len(covered), size=min(SAMPLES, len(covered)),
                                       replace=False)]:
        w = locate(col + 0.5, row + 0.5, tx, ty)
        best = int(np.nanargmax(np.min(w, axis=1)))
        if np.min(w[best]) < -1e-3:
            fail(f"covered texel (row {row}, col {col}) lies in no UV triangle")
        expected = w[best] @ xyz[verts[best]]
        worst = max(worst, float(np.linalg.norm(P[row, col] - expected)) / diagonal)
    if worst > REL_TOL:
        fail(f"worst |P - P_ref| / diagonal = {worst:.3g} > {REL_TOL}")

    # Beyond the padding: A = 0 and P = 0 (chessboard distance > PADDING to every covered).
    near = np.zeros_like(A, dtype=bool)
    for dy in range(-PADDING, PADDING + 1):
        for dx in range(-PADDING, PADDING + 1):
            shifted = np.zeros_like(near)
            src = A == 1.0
            ys = slice(max(dy, 0), HEIGHT + min(dy, 0))
            xs = slice(max(dx, 0), WIDTH + min(dx, 0))
            yd = slice(max(-dy, 0), HEIGHT + min(-dy, 0))
            xd = slice(max(-dx, 0), WIDTH + min(-dx, 0))
            shifted[ys, xs] = src[yd, xd]
            near |= shifted
    far = ~near
    if np.any(A[far] != 0.0) or np.any(P[far] != 0.0):
        fail("texels beyond the padding are not 0")
    if not np.any(far):
        fail("no texel beyond the padding: the check would be empty")

    print(f"check_posmap_exr: OK ({len(covered)} covered texels, worst |P - P_ref| / diagonal "
          f"{worst:.3g}, seed {SEED}, OpenEXR {OpenEXR.__version__})")


if __name__ == "__main__":
    main()
