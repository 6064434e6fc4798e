#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Preview of a layered bake: the garment at one frame from three sides, coloured by a layer
weight map, and optionally by how far the layers moved it from a plain bake.

  .venv/bin/python scripts/layering_preview.py --mesh pants_driven_rest.obj \
      --exr out/layered.####.exr --frame 1040 \
      --mix-weight group:waistband --mix-falloff 3 \
      --compare out/plain.####.exr -o scripts/readme_images/layering_pants.png

Row 1: the mix weight (1 = DrivenShape kept, 0 = the --mix cache taken), softened across
--mix-falloff edge rings exactly as the bake does (weighted ring average). With --wind-weight
the row shows that map instead (or a second row when both are given). With --compare CACHE
(the same shot baked without layers) the last row shows |layered - plain| per vertex in scene
units: where the mix and the wind changed the result. Caches are PC2 files or point-cache EXR
sequences (####, %04d, $F4); weight maps are .json arrays, one-channel .exr maps or
group:NAME[,NAME]. The mesh and the caches are read with the drivenshape Python module's
readers (PYTHONPATH, else this checkout's build/python). Needs numpy, matplotlib and OpenEXR
(scripts/requirements.txt).
"""

import argparse
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from drivenshape_import import import_drivenshape  # noqa: E402

EXIT_USAGE, EXIT_INPUT, EXIT_OUTPUT = 2, 3, 4

VIEWS = (("front", -90.0), ("side", 0.0), ("back", 90.0))
ELEVATION = 10.0


class PreviewError(Exception):
    def __init__(self, code, message):
        super().__init__(message)
        self.code = code


def read_mesh(ds, path):
    """The OBJ (drivenshape.read_obj) as positions, face sizes, face vertices and groups."""
    mesh = ds.read_obj(path)
    groups = {}
    for face, group in enumerate(mesh.face_groups.tolist()):
        groups.setdefault(mesh.group_names[group], []).append(face)
    return {"positions": np.asarray(mesh.positions, dtype=np.float32),
            "counts": np.diff(mesh.face_start).astype(np.int64),
            "indices": np.asarray(mesh.face_vertices, dtype=np.int64), "groups": groups}


def read_positions(ds, spec, frame, vertex_count):
    """One frame of a PC2 or a point-cache EXR sequence (drivenshape.open_point_cache)."""
    cache = ds.open_point_cache(spec)
    if cache.vertex_count != vertex_count:
        raise PreviewError(EXIT_INPUT, f"'{spec}' holds {cache.vertex_count} points but the "
                                       f"mesh has {vertex_count}; pass the driven mesh of the bake")
    return cache.read_frames([frame])[0]


def read_weight_map(spec, mesh):
    count = len(mesh["positions"])
    if spec.startswith("group:"):
        weights = np.zeros(count, dtype=np.float32)
        starts = np.concatenate([[0], np.cumsum(mesh["counts"])])
        for name in spec[len("group:"):].split(","):
            if name not in mesh["groups"]:
                raise PreviewError(EXIT_INPUT, f"no group '{name}'; the mesh has "
                                              f"{', '.join(mesh['groups'])}")
            for face in mesh["groups"][name]:
                weights[mesh["indices"][starts[face]:starts[face + 1]]] = 1.0
        return weights
    if spec.lower().endswith(".json"):
        data = json.load(open(spec))
        values = np.asarray(data["weights"] if isinstance(data, dict) else data, dtype=np.float32)
    elif spec.lower().endswith(".exr"):
        import OpenEXR
        image = OpenEXR.File(spec, separate_channels=True)
        channels = image.channels()
        name = "W" if "W" in channels else [n for n in channels if n != "A"][0]
        values = channels[name].pixels.reshape(-1)[:count].astype(np.float32)
    else:
        raise PreviewError(EXIT_USAGE, f"weight map '{spec}': use .json, .exr or group:NAME")
    if values.shape != (count,) or not np.all((values >= 0) & (values <= 1)):
        raise PreviewError(EXIT_INPUT, f"weight map '{spec}' needs {count} values in [0, 1]")
    return values


def smooth(weights, mesh, rings):
    """The bake's falloff (smoothWeightMap): average over `rings` edge rings, weight
    rings + 1 - distance; vertices whose neighbourhood holds one value keep it."""
    if rings <= 0:
        return weights
    count = len(weights)
    neighbours = [set() for _ in range(count)]
    start = 0
    for size in mesh["counts"]:
        face = mesh["indices"][start:start + size]
        for a, b in zip(face, np.roll(face, -1)):
            if a != b:
                neighbours[a].add(int(b))
                neighbours[b].add(int(a))
        start += size
    out = np.empty_like(weights)
    for v in range(count):
        seen = {v}
        frontier = [v]
        total = float(rings + 1)
        acc = total * float(weights[v])
        uniform = True
        for distance in range(1, rings + 1):
            following = []
            for u in frontier:
                for n in neighbours[u]:
                    if n not in seen:
                        seen.add(n)
                        following.append(n)
                        k = float(rings + 1 - distance)
                        acc += k * float(weights[n])
                        total += k
                        uniform = uniform and weights[n] == weights[v]
            frontier = following
        out[v] = weights[v] if uniform else np.float32(min(1.0, max(0.0, acc / total)))
    return out


def triangles(mesh):
    tris = []
    start = 0
    for size in mesh["counts"]:
        face = mesh["indices"][start:start + size]
        tris.extend((face[0], face[i], face[i + 1]) for i in range(1, size - 1))
        start += size
    return np.asarray(tris, dtype=np.int64)


def render(path, positions, tris, rows, up_axis, title):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    # Matplotlib's 3-D axes are Z-up: rotate Y-up scenes.
    xyz = positions[:, [0, 2, 1]] if up_axis == "Y" else positions
    lo, hi = xyz.min(axis=0), xyz.max(axis=0)
    centre, half = 0.5 * (lo + hi), 0.5 * (hi - lo).max()
    corners = xyz[tris]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-30)
    figure = plt.figure(figsize=(3.2 * len(VIEWS) + 0.8, 3.6 * len(rows) + 0.4), dpi=100)
    for r, (label, values, cmap, vmin, vmax) in enumerate(rows):
        face_colours = plt.get_cmap(cmap)(plt.Normalize(vmin, vmax)(values[tris].mean(axis=1)))
        for c, (name, azimuth) in enumerate(VIEWS):
            axis = figure.add_subplot(len(rows), len(VIEWS), r * len(VIEWS) + c + 1,
                                      projection="3d")
            # A soft two-sided headlight so folds read (the colour keeps 65-100% of its
            # brightness); edges drawn in the face colour so no background shows between faces.
            a, e = np.radians(azimuth), np.radians(ELEVATION)
            eye = np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
            colours = face_colours.copy()
            colours[:, :3] *= (0.65 + 0.35 * np.abs(normals @ eye))[:, None]
            mesh = Poly3DCollection(corners, facecolors=colours, edgecolors=colours,
                                    linewidths=0.3)
            axis.add_collection3d(mesh)
            for setter, k in ((axis.set_xlim, 0), (axis.set_ylim, 1), (axis.set_zlim, 2)):
                setter(centre[k] - half, centre[k] + half)
            axis.set_box_aspect((1, 1, 1), zoom=1.5)
            axis.view_init(elev=ELEVATION, azim=azimuth)
            axis.set_axis_off()
            axis.set_title(f"{label} ({name})", fontsize=10)
    figure.subplots_adjust(left=0.0, right=0.9, bottom=0.0, top=0.92, wspace=0.0, hspace=0.08)
    # One colour bar per row, in its own axes right of the row (placed once the grid is laid out).
    for r, (_, values, cmap, vmin, vmax) in enumerate(rows):
        box = figure.axes[r * len(VIEWS) + len(VIEWS) - 1].get_position()
        bar = figure.add_axes([0.91, box.y0 + 0.15 * box.height, 0.015, 0.7 * box.height])
        scale = plt.cm.ScalarMappable(cmap=cmap, norm=plt.Normalize(vmin, vmax))
        figure.colorbar(scale, cax=bar)
    figure.suptitle(title, fontsize=12)
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise PreviewError(EXIT_OUTPUT, f"-o '{path}': folder '{folder}' does not exist")
    temp = os.path.join(folder, "." + os.path.basename(path) + f".tmp-{os.getpid()}.png")
    try:
        figure.savefig(temp)
        os.replace(temp, path)
    finally:
        if os.path.exists(temp):
            os.remove(temp)
        plt.close(figure)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--mesh", required=True, help="driven rest OBJ of the bake")
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--exr", metavar="PATTERN", help="layered bake, point-cache EXR sequence")
    source.add_argument("--pc2", metavar="FILE", help="layered bake as PC2")
    parser.add_argument("--frame", type=int, required=True, help="frame to show")
    parser.add_argument("--mix-weight", metavar="MAP", help="the bake's --mix-weight")
    parser.add_argument("--mix-falloff", type=int, default=3, help="the bake's --mix-falloff (3)")
    parser.add_argument("--wind-weight", metavar="MAP", help="the bake's --wind-weight")
    parser.add_argument("--wind-falloff", type=int, default=0, help="the bake's --wind-falloff")
    parser.add_argument("--compare", metavar="CACHE",
                        help="the same shot without layers: colour by |layered - plain|")
    parser.add_argument("--up-axis", choices=("Y", "Z"), default="Z", help="scene up axis (Z)")
    parser.add_argument("--title", default="", help="figure title")
    parser.add_argument("-o", "--output", required=True, help="OUT.png")
    args = parser.parse_args(argv)
    try:
        ds = import_drivenshape()
    except ImportError as error:
        print(f"layering_preview: {error}", file=sys.stderr)
        return EXIT_USAGE
    try:
        mesh = read_mesh(ds, args.mesh)
        count = len(mesh["positions"])
        spec = args.exr or args.pc2
        positions = read_positions(ds, spec, args.frame, count)
        rows = []
        if args.mix_weight:
            weights = smooth(read_weight_map(args.mix_weight, mesh), mesh, args.mix_falloff)
            rows.append(("mix weight (1 = DrivenShape)", weights, "coolwarm_r", 0.0, 1.0))
        if args.wind_weight:
            weights = smooth(read_weight_map(args.wind_weight, mesh), mesh, args.wind_falloff)
            rows.append(("wind weight", weights, "viridis", 0.0, 1.0))
        if args.compare:
            plain = read_positions(ds, args.compare, args.frame, count)
            moved = np.linalg.norm(positions.astype(np.float64) - plain, axis=1)
            rows.append(("|layered - plain|", moved, "plasma", 0.0, max(float(moved.max()), 1e-12)))
        if not rows:
            raise PreviewError(EXIT_USAGE, "give --mix-weight, --wind-weight and/or --compare")
        title = args.title or f"{os.path.basename(spec)} frame {args.frame}"
        render(args.output, positions, triangles(mesh), rows, args.up_axis, title)
        print(f"wrote {args.output}")
        return 0
    except (PreviewError, ds.Error) as error:
        print(f"layering_preview: {error}", file=sys.stderr)
        return error.code


if __name__ == "__main__":
    sys.exit(main())
