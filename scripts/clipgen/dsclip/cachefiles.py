# SPDX-License-Identifier: Apache-2.0
"""Point caches (PC2) and Wavefront OBJ files (numpy only).

PC2, little endian: the 12 bytes b"POINTCACHE2\\0", int32 version 1, int32 point count,
float32 start frame, float32 sample rate, int32 sample count, then float32 x, y, z for every
point of every sample (sample-major).

OBJ: `v` lines (positions exactly as given: Blender world coordinates, so OBJ, Blender and PC2
agree), `vt` lines (one per polygon corner) and `f v/vt` polygons, 1-based, in mesh order.
"""
import struct

import numpy as np

PC2_HEAD = struct.Struct("<12siiffi")
PC2_MAGIC = b"POINTCACHE2\0"


def write_pc2(path, samples, start=1.0, rate=1.0):
    data = np.ascontiguousarray(samples, dtype="<f4")
    if data.ndim != 3 or data.shape[2] != 3:
        raise ValueError(f"{path}: samples must be (frames, points, 3), not {data.shape}")
    with open(path, "wb") as fh:
        fh.write(PC2_HEAD.pack(PC2_MAGIC, 1, data.shape[1], float(start), float(rate),
                               data.shape[0]))
        fh.write(data.tobytes())


def read_pc2(path):
    """-> (samples (S, N, 3) float32, header dict)."""
    with open(path, "rb") as fh:
        raw = fh.read()
    magic, version, points, start, rate, count = PC2_HEAD.unpack_from(raw, 0)
    if magic != PC2_MAGIC or version != 1:
        raise ValueError(f"{path}: not a version 1 PC2 file")
    body = np.frombuffer(raw, dtype="<f4", offset=PC2_HEAD.size)
    if body.size != count * points * 3:
        raise ValueError(f"{path}: {body.size} floats for {count} samples of {points} points")
    return body.reshape(count, points, 3), dict(magic=magic, version=version, points=points,
                                                start=start, rate=rate, samples=count)


def write_obj(path, name, verts, faces, corner_uvs, header="drivenshape scripts/clipgen"):
    """Positions are written with 9 significant digits, so float32 values survive exactly."""
    lines = [f"# {header}", f"o {name}"]
    lines += ["v %.9g %.9g %.9g" % tuple(p) for p in np.asarray(verts, dtype=float)]
    corner = 1
    flines = []
    for f, uv in zip(faces, corner_uvs):
        refs = []
        for v, (u, w) in zip(f, uv):
            lines.append("vt %.6f %.6f" % (u, w))
            refs.append(f"{v + 1}/{corner}")
            corner += 1
        flines.append("f " + " ".join(refs))
    lines += flines
    with open(path, "w") as fh:
        fh.write("\n".join(lines) + "\n")


def read_obj(path):
    """-> (verts (n, 3), faces [[0-based ids]], uvs (k, 2), face uv ids [[0-based ids]])."""
    V, T, F, FT = [], [], [], []
    with open(path) as fh:
        for line in fh:
            parts = line.split()
            if not parts:
                continue
            if parts[0] == "v":
                V.append([float(x) for x in parts[1:4]])
            elif parts[0] == "vt":
                T.append([float(x) for x in parts[1:3]])
            elif parts[0] == "f":
                refs = [p.split("/") for p in parts[1:]]
                F.append([int(r[0]) - 1 for r in refs])
                FT.append([int(r[1]) - 1 if len(r) > 1 and r[1] else -1 for r in refs])
    return np.array(V, dtype=float), F, np.array(T, dtype=float), FT
