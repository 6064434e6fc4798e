#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Export a drivenshape result to USD: one UsdGeomMesh with time-sampled points and extents.

The mesh's faces, UVs (primvars:st, face-varying) and groups (UsdGeomSubsets) come from the
driven rest OBJ; the positions come from a point-cache EXR sequence written by `drivenshape
bake` or from a PC2 file (e.g. `drivenshape export --pc2`). Time codes are frame numbers; the
stage's timeCodesPerSecond is --fps (for EXR input, the files' framesPerSecond by default).

  .venv/bin/python scripts/export_usd.py --mesh driven_rest.obj \
      --exr out/pants.####.exr --frames 1001-1100 -o pants.usdc
  .venv/bin/python scripts/export_usd.py --mesh driven_rest.obj --pc2 guides.pc2 -o guides.usda

The stage is written by the drivenshape Python module's `drivenshape.usd.write_mesh_usd` (the
one USD writer; found on PYTHONPATH or in build/python), with metersPerUnit 1 and Z up, the
axis of drivenshape's caches; --up-axis Y writes a Y-up stage and rotates the points to match,
(x, y, z) -> (x, z, -y), exactly (docs/conventions.md). Needs usd-core, numpy and OpenEXR (scripts/requirements.txt, installed
into .venv by scripts/setup.sh). Exit codes: 0 ok, 2 usage, 3 input, 4 output.
"""

import argparse
import os
import re
import sys

import numpy as np

from drivenshape_import import import_drivenshape

EXIT_USAGE, EXIT_INPUT, EXIT_OUTPUT = 2, 3, 4


class ExportError(Exception):
    def __init__(self, code, message):
        super().__init__(message)
        self.code = code


# ---- inputs ----------------------------------------------------------------------------------

def read_obj(path):
    """Positions, faces (counts + indices), UVs (values + face-varying indices or None), groups
    (name -> face ids), vertex order exactly as in the file."""
    positions, uvs, counts, indices, uv_indices, groups = [], [], [], [], [], {}
    group = None
    has_uvs = True
    try:
        lines = open(path, encoding="utf-8", errors="replace").read().splitlines()
    except OSError as error:
        raise ExportError(EXIT_INPUT, f"cannot read OBJ '{path}': {error.strerror}")
    for number, line in enumerate(lines, 1):
        words = line.split()
        if not words or words[0].startswith("#"):
            continue
        try:
            if words[0] == "v":
                positions.append([float(w) for w in words[1:4]])
            elif words[0] == "vt":
                uvs.append([float(words[1]), float(words[2]) if len(words) > 2 else 0.0])
            elif words[0] in ("g", "o"):
                group = line.split(None, 1)[1].strip() if len(words) > 1 else "default"
            elif words[0] == "f":
                corners = words[1:]
                for corner in corners:
                    fields = corner.split("/")
                    v = int(fields[0])
                    indices.append(v - 1 if v > 0 else len(positions) + v)
                    if len(fields) > 1 and fields[1]:
                        t = int(fields[1])
                        uv_indices.append(t - 1 if t > 0 else len(uvs) + t)
                    else:
                        has_uvs = False
                groups.setdefault(group or "default", []).append(len(counts))
                counts.append(len(corners))
        except (ValueError, IndexError):
            raise ExportError(EXIT_INPUT, f"{path}:{number}: malformed line '{line.strip()}'")
    if not positions or not counts:
        raise ExportError(EXIT_INPUT, f"OBJ '{path}' has no vertices or no faces")
    indices = np.asarray(indices, dtype=np.int32)
    if indices.min() < 0 or indices.max() >= len(positions):
        raise ExportError(EXIT_INPUT, f"OBJ '{path}': a face index is out of range")
    uv_data = None
    if has_uvs and uvs:
        uv_data = (np.asarray(uvs, dtype=np.float32), np.asarray(uv_indices, dtype=np.int32))
    return {
        "positions": np.asarray(positions, dtype=np.float32),
        "counts": np.asarray(counts, dtype=np.int32),
        "indices": indices,
        "uvs": uv_data,
        "groups": groups,
    }


def read_pc2(path):
    """(frames, positions F x V x 3 float32) of a PC2 file; frames are start + s * rate."""
    try:
        data = open(path, "rb").read()
    except OSError as error:
        raise ExportError(EXIT_INPUT, f"cannot read PC2 '{path}': {error.strerror}")
    if len(data) < 32 or data[:12] != b"POINTCACHE2\0":
        raise ExportError(EXIT_INPUT, f"'{path}' is not a PC2 file (no POINTCACHE2 header)")
    version, points = np.frombuffer(data[12:20], "<i4")
    start, rate = np.frombuffer(data[20:28], "<f4")
    samples = int(np.frombuffer(data[28:32], "<i4")[0])
    if version != 1 or points <= 0 or samples < 0 or not rate > 0:
        raise ExportError(EXIT_INPUT, f"'{path}': unsupported PC2 header (version {version}, "
                                      f"{points} points, rate {rate}, {samples} samples)")
    expected = 32 + samples * int(points) * 12
    if len(data) != expected:
        raise ExportError(EXIT_INPUT, f"'{path}': {len(data)} bytes but the header promises "
                                      f"{expected}; the file is truncated or corrupt")
    xyz = np.frombuffer(data, "<f4", offset=32).reshape(samples, int(points), 3)
    frames = [float(start) + s * float(rate) for s in range(samples)]
    return frames, xyz.astype(np.float32)


def parse_frames(text):
    """`1001-1100`, `1001-1100x2`, `1001,1005,1010-1020` -> list of ints (order kept)."""
    frames = []
    for part in text.split(","):
        match = re.fullmatch(r"\s*(-?\d+)(?:-(-?\d+)(?:x(\d+))?)?\s*", part)
        if not match:
            raise ExportError(EXIT_USAGE, f"--frames '{text}': cannot read '{part}'")
        first = int(match.group(1))
        last = int(match.group(2)) if match.group(2) is not None else first
        step = int(match.group(3)) if match.group(3) else 1
        if last < first or step <= 0:
            raise ExportError(EXIT_USAGE, f"--frames '{text}': bad range '{part}'")
        frames.extend(f for f in range(first, last + 1, step) if f not in frames)
    return frames


def expand_pattern(pattern, frame):
    """Replaces ####, %04d or $F4 with the frame number."""
    match = re.search(r"#+", pattern)
    if match:
        width = len(match.group(0))
        return pattern[:match.start()] + f"{frame:0{width}d}" + pattern[match.end():]
    match = re.search(r"%0?(\d*)d", pattern)
    if match:
        width = int(match.group(1) or 1)
        return pattern[:match.start()] + f"{frame:0{width}d}" + pattern[match.end():]
    match = re.search(r"\$F(\d*)", pattern)
    if match:
        width = int(match.group(1) or 1)
        return pattern[:match.start()] + f"{frame:0{width}d}" + pattern[match.end():]
    raise ExportError(EXIT_USAGE, f"--exr '{pattern}' has no frame token (####, %04d or $F4)")


def read_exr_frame(path, vertex_count):
    """(positions V x 3 float32, frames per second or None) of one point-cache EXR."""
    import OpenEXR  # imported here so PC2 exports work without it

    if not os.path.exists(path):
        raise ExportError(EXIT_INPUT, f"point-cache EXR '{path}' does not exist")
    try:
        image = OpenEXR.File(path, separate_channels=True)
    except Exception as error:  # the bindings raise plain exceptions
        raise ExportError(EXIT_INPUT, f"cannot read EXR '{path}': {error}")
    header = image.header()
    channels = image.channels()
    count = header.get("dsVertexCount")
    if count is None:
        raise ExportError(EXIT_INPUT, f"'{path}' is not a drivenshape point cache "
                                      "(no dsVertexCount)")
    if count != vertex_count:
        raise ExportError(EXIT_INPUT, f"'{path}' holds {count} vertices but the mesh has "
                                      f"{vertex_count}; pass the driven mesh of the bake")
    for name in ("P.X", "P.Y", "P.Z"):
        if name not in channels:
            raise ExportError(EXIT_INPUT, f"'{path}': channel {name} is missing")
    # Vertex v is pixel (v mod W, v div W): the pixels in row-major order.
    xyz = np.stack([channels[name].pixels.reshape(-1)[:count] for name in ("P.X", "P.Y", "P.Z")],
                   axis=1).astype(np.float32)
    fps = header.get("framesPerSecond")
    if fps is not None:
        try:
            fps = float(fps)
        except TypeError:
            fps = fps[0] / fps[1]
    return xyz, fps


# ---- output ----------------------------------------------------------------------------------

def drivenshape_usd():
    """drivenshape.usd, the one USD writer of the project (apps/python/drivenshape/usd.py)."""
    try:
        return import_drivenshape("usd")
    except ImportError as error:
        raise ExportError(EXIT_USAGE, str(error))


def write_usd(path, mesh, frames, positions, fps, prim_path, up_axis):
    """The points (EXR or PC2 from drivenshape) are Z up; a Y-up stage gets them rotated."""
    usd = drivenshape_usd()
    try:
        usd.write_mesh_usd(path, mesh, frames, positions, prim_path=prim_path, fps=fps,
                           up_axis=up_axis, meters_per_unit=1.0, points_up_axis="Z")
    except usd.Error as error:
        raise ExportError(error.code, str(error))


def main(argv=None):
    parser = argparse.ArgumentParser(
        description="Export a drivenshape result (EXR sequence or PC2) as a UsdGeomMesh with "
                    "time-sampled points and extents.")
    parser.add_argument("--mesh", required=True, help="driven rest OBJ (faces, UVs, groups)")
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--exr", metavar="PATTERN", help="point-cache EXR sequence, e.g. "
                                                         "out/pants.####.exr (needs --frames)")
    source.add_argument("--pc2", metavar="FILE", help="PC2 point cache (all its samples)")
    parser.add_argument("--frames", help="frames of the EXR sequence: 1001-1100, 1001-1100x2")
    parser.add_argument("--fps", type=float, help="time codes per second (default: the EXR's "
                                                  "framesPerSecond, else 24)")
    parser.add_argument("--prim", default="/Garment/Mesh", help="mesh prim path (/Garment/Mesh)")
    parser.add_argument("--up-axis", choices=("Y", "Z"), default="Z",
                        help="stage upAxis: Z (default) keeps the points as they are, the axis "
                             "of drivenshape's caches; Y rotates them to Y up, (x, y, z) -> "
                             "(x, z, -y), exactly")
    parser.add_argument("-o", "--output", required=True, help="OUT.usd, .usda or .usdc")
    args = parser.parse_args(argv)
    try:
        mesh = read_obj(args.mesh)
        vertex_count = len(mesh["positions"])
        fps = args.fps
        if args.pc2:
            frames, positions = read_pc2(args.pc2)
            if positions.shape[1] != vertex_count:
                raise ExportError(EXIT_INPUT, f"'{args.pc2}' holds {positions.shape[1]} points "
                                              f"but '{args.mesh}' has {vertex_count} vertices")
        else:
            if not args.frames:
                raise ExportError(EXIT_USAGE, "--exr needs --frames RANGE")
            frames = parse_frames(args.frames)
            positions = []
            for frame in frames:
                xyz, file_fps = read_exr_frame(expand_pattern(args.exr, frame), vertex_count)
                positions.append(xyz)
                fps = fps or file_fps
            positions = np.stack(positions)
        if len(frames) == 0:
            raise ExportError(EXIT_INPUT, "no frames to export")
        if not np.isfinite(positions).all():
            raise ExportError(EXIT_INPUT, "the positions hold NaN or infinite values")
        write_usd(args.output, mesh, [float(f) for f in frames], positions, fps or 24.0,
                  args.prim, args.up_axis)
        print(f"wrote {args.output}: {args.prim}, {vertex_count} points, {len(frames)} time "
              f"samples ({frames[0]:g}-{frames[-1]:g}) at {fps or 24.0:g} fps, "
              f"{args.up_axis} up")
        return 0
    except ExportError as error:
        print(f"export_usd: {error}", file=sys.stderr)
        return error.code


if __name__ == "__main__":
    sys.exit(main())
