#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Position maps as compositing tools read them (issue 16): real `oiiotool` (OpenImageIO) and
the OpenEXR Python bindings, on maps of the bundled sleeve written by the library.

  (a) the channels group as the documented layers: `oiiotool --info -v` lists
      R, G, B, A, N.R, N.G, N.B (position and coverage as the colour image, then layer N), and
      OpenEXR.File() hands out an "RGBA" array and an "N" array, bit for bit what was written;
  (b) `oiiotool map.exr -o x.png` writes the position as R G B (clamped to 0-1 and quantised,
      checked against the written positions) and the coverage as alpha; `--ch 0,1,2` and
      `--ch R,G,B` select the position exactly;
  (c) the statistics recipe of docs/formats.md,
          oiiotool map.exr --ch R,G,B map.exr --ch A,A,A --powc -1 --mul --printstats
      gives the min and max of the covered texels (A = 1) only: its FiniteCount is the number
      of covered texels, and min/max equal those of this script's own barycentric
      interpolation of the mesh and cache at every covered texel (independent of the library's
      gather), which lie within the bounds of the frame's vertices; plain `--stats` does not
      (it counts the background's zeros: the sleeve lies at x > 0 and z > 1.1);
  (d) --channels legacy (posmap_sample ... legacy) still writes P.X P.Y P.Z, A, N.X N.Y N.Z with
      the same pixels and header, listed by OpenImageIO as before (A first) and not grouped by
      the bindings; the recipe works on it with those names.

A missing oiiotool, Python module or Pillow (matplotlib's dependency, for reading the PNG) is a
failure, never a skip. Run by CTest (test_posmap_readers) through tests/support/run_python.cmake.
"""

import argparse
import os
import re
import shutil
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import check_posmap_exr as ref  # noqa: E402  (its OBJ/PC2 readers and point-in-triangle search)

np = ref.np
OpenEXR = ref.OpenEXR
try:
    from PIL import Image
except ImportError as error:  # a failure, not a skip
    print(f"check_posmap_readers: {error}; run scripts/setup.sh (matplotlib brings Pillow)",
          file=sys.stderr)
    sys.exit(1)

FRAME = 21
WIDTH, HEIGHT = 96, 80
PADDING = 3
REL_TOL = ref.REL_TOL  # independent interpolation vs the map, of the bounding-box diagonal
PRINT_TOL = 1e-6  # oiiotool --printstats prints 6 decimals
RGBA_LIST = "R, G, B, A, N.R, N.G, N.B"
LEGACY_LIST = "A, N.X, N.Y, N.Z, P.X, P.Y, P.Z"


def fail(message):
    print(f"check_posmap_readers: FAILED: {message}", file=sys.stderr)
    sys.exit(1)


def oiiotool(*args):
    """stdout + stderr of oiiotool; a non-zero exit fails the check."""
    result = subprocess.run(["oiiotool", *args], capture_output=True, text=True)
    output = result.stdout + result.stderr
    if result.returncode != 0:
        fail(f"oiiotool {' '.join(args)} exited with {result.returncode}:\n{output}")
    return output


def channel_list(path):
    match = re.search(r"channel list: (.*)\n", oiiotool("--info", "-v", path))
    if not match:
        fail(f"oiiotool --info -v {path} printed no channel list")
    return match.group(1).strip()


def printed_stats(output):
    """{"Min": [...], "Max": [...], "FiniteCount": [...], ...} from oiiotool's stats lines."""
    stats = {}
    for line in output.splitlines():
        match = re.match(r"\s*Stats (\w+):\s*(.*)", line)
        if match:
            words = match.group(2).replace("(float)", "").split()
            stats[match.group(1)] = [float(w) for w in words]
    for key in ("Min", "Max", "FiniteCount"):
        if key not in stats:
            fail(f"no 'Stats {key}' line in:\n{output}")
    return stats


def recipe(path, position, alpha="A"):
    """The documented recipe: multiply by A^-1 (exactly 1 where covered, +inf elsewhere), so
    that uncovered texels become Inf or NaN, which --printstats leaves out of Min and Max."""
    return printed_stats(oiiotool(path, "--ch", ",".join(position), path, "--ch",
                                  ",".join([alpha] * len(position)), "--powc", "-1", "--mul",
                                  "--printstats"))


def independent_positions(mesh_path, cache_path, covered):
    """P at the given covered texels (K x 2 rows, cols) by this script's own interpolation of
    the triangle under each texel centre (check_posmap_exr's readers and search)."""
    positions, uvs, faces = ref.read_obj(mesh_path)
    xyz = ref.read_pc2_frame(cache_path, FRAME)
    if xyz.shape[0] != positions.shape[0]:
        fail("cache and mesh vertex counts differ")
    verts, uvids = ref.fan_triangles(faces)
    tx = uvs[uvids, 0] * WIDTH
    ty = (1.0 - uvs[uvids, 1]) * HEIGHT
    out = np.empty((len(covered), 3))
    for i, (row, col) in enumerate(covered):
        w = ref.locate(col + 0.5, row + 0.5, tx, ty)
        best = int(np.nanargmax(np.min(w, axis=1)))
        if np.min(w[best]) < -1e-3:
            fail(f"covered texel (row {row}, col {col}) lies in no UV triangle")
        out[i] = w[best] @ xyz[verts[best]]
    return out, xyz


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--writer", required=True, help="posmap_sample executable")
    parser.add_argument("--data", required=True, help="tests/data")
    parser.add_argument("--work", required=True, help="scratch folder")
    args = parser.parse_args()
    if shutil.which("oiiotool") is None:
        fail("oiiotool is not installed; install the Debian package openimageio-tools "
             "(scripts/setup.sh installs it)")

    mesh_path = ref.squeezed_sleeve(args.data, args.work)
    cache_path = os.path.join(args.data, "sleeve", "test.driven.pc2")
    exr = os.path.join(args.work, f"map.{FRAME:04d}.exr")
    legacy = os.path.join(args.work, f"legacy.{FRAME:04d}.exr")
    for path, naming in ((exr, "rgba"), (legacy, "legacy")):
        subprocess.run([args.writer, mesh_path, cache_path, str(FRAME), f"{WIDTH}x{HEIGHT}",
                        str(PADDING), path, naming], check=True)
    raw = {k: np.fromfile(f"{exr}.{k}.raw", "<f4") for k in ("P", "A", "N")}
    P = raw["P"].reshape(HEIGHT, WIDTH, 3)
    A = raw["A"].reshape(HEIGHT, WIDTH)
    N = raw["N"].reshape(HEIGHT, WIDTH, 3)

    # (a) Layers. OpenImageIO: the default layer's R G B A first, then layer N.
    if channel_list(exr) != RGBA_LIST:
        fail(f"oiiotool lists '{channel_list(exr)}', expected '{RGBA_LIST}'")
    # The bindings, grouping as they do by default: one RGBA array and one N array.
    image = OpenEXR.File(exr)
    groups = image.channels()
    if sorted(groups) != ["N", "RGBA"]:
        fail(f"OpenEXR.File groups the channels as {sorted(groups)}, expected ['N', 'RGBA']")
    rgba, normals = groups["RGBA"].pixels, groups["N"].pixels
    if rgba.shape != (HEIGHT, WIDTH, 4) or normals.shape != (HEIGHT, WIDTH, 3):
        fail(f"RGBA is {rgba.shape} and N {normals.shape}, expected {(HEIGHT, WIDTH, 4)} and "
             f"{(HEIGHT, WIDTH, 3)}")
    for name, got, want in (("RGBA[..., :3] (position)", rgba[..., :3], P),
                            ("RGBA[..., 3] (coverage)", rgba[..., 3], A),
                            ("N", normals, N)):
        if not np.array_equal(np.ascontiguousarray(got).view(np.uint32), want.view(np.uint32)):
            fail(f"{name} differs from what the library wrote")

    # (b) What a viewer or an 8-bit conversion shows: the position as R G B, coverage as alpha.
    png = os.path.join(args.work, "map.png")
    oiiotool(exr, "-o", png)
    if channel_list(png) != "R, G, B, A":
        fail(f"the PNG holds '{channel_list(png)}', expected 'R, G, B, A'")
    with Image.open(png) as picture:
        if picture.mode != "RGBA" or picture.size != (WIDTH, HEIGHT):
            fail(f"the PNG is {picture.mode} {picture.size}, expected RGBA {(WIDTH, HEIGHT)}")
        pixels = np.asarray(picture).astype(np.int64)
    covered_mask = A == 1.0
    expected = np.round(np.clip(P, 0.0, 1.0) * 255.0)
    worst = np.abs(pixels[..., :3][covered_mask] - expected[covered_mask]).max()
    if worst > 1:
        fail(f"PNG R G B of covered texels differ from the clamped position by {worst} levels")
    if not np.array_equal(pixels[..., 3], (A * 255).astype(np.int64)):
        fail("PNG alpha is not the coverage")
    spread = np.unique(pixels[..., 0][covered_mask]).size
    if spread < 20:
        fail(f"PNG red holds only {spread} levels on covered texels: not the position's x")
    for selection in ("0,1,2", "R,G,B"):
        first = os.path.join(args.work, "first.exr")
        oiiotool(exr, "--ch", selection, "-o", first)
        picked = OpenEXR.File(first).channels()
        if list(picked) != ["RGB"] or not np.array_equal(picked["RGB"].pixels, P):
            fail(f"oiiotool --ch {selection} gives {list(picked)}, not the position")

    # (c) Statistics of the covered texels only.
    covered = np.argwhere(covered_mask)
    stats = recipe(exr, ["R", "G", "B"])
    if stats["FiniteCount"] != [float(len(covered))] * 3:
        fail(f"the recipe counts {stats['FiniteCount']} texels, the map covers {len(covered)}")
    reference, xyz = independent_positions(mesh_path, cache_path, covered)
    diagonal = float(np.linalg.norm(xyz.max(axis=0) - xyz.min(axis=0)))
    tol = REL_TOL * diagonal + PRINT_TOL
    true_min, true_max = reference.min(axis=0), reference.max(axis=0)
    for key, got, want in (("Min", stats["Min"], true_min), ("Max", stats["Max"], true_max)):
        error = np.abs(np.array(got) - want).max()
        if error > tol:
            fail(f"recipe {key} {got} vs the interpolated mesh's {want.tolist()}: {error:.3g} > "
                 f"{tol:.3g}")
    stored = P[covered_mask]
    if np.abs(np.array(stats["Min"]) - stored.min(axis=0)).max() > PRINT_TOL or \
            np.abs(np.array(stats["Max"]) - stored.max(axis=0)).max() > PRINT_TOL:
        fail(f"recipe min/max {stats['Min']} {stats['Max']} are not those of the covered texels "
             f"{stored.min(axis=0).tolist()} {stored.max(axis=0).tolist()}")
    if np.any(np.array(stats["Min"]) < xyz.min(axis=0) - PRINT_TOL) or \
            np.any(np.array(stats["Max"]) > xyz.max(axis=0) + PRINT_TOL):
        fail("the recipe's min/max leave the bounds of the frame's vertices")
    plain = printed_stats(oiiotool("--stats", exr))
    if plain["Min"][0] != 0.0 or plain["Min"][2] != 0.0:
        fail(f"plain --stats gives min {plain['Min']}; expected the background's 0 in x and z "
             "(the check that the recipe matters has lost its premise)")
    normal_stats = recipe(exr, ["N.R", "N.G", "N.B"])
    n_covered = N[covered_mask]
    if np.abs(np.array(normal_stats["Min"]) - n_covered.min(axis=0)).max() > PRINT_TOL or \
            np.abs(np.array(normal_stats["Max"]) - n_covered.max(axis=0)).max() > PRINT_TOL:
        fail(f"recipe on N: {normal_stats['Min']} {normal_stats['Max']}")

    # (d) The legacy names: same pixels and header, the former channel list, no grouping.
    if channel_list(legacy) != LEGACY_LIST:
        fail(f"legacy map: oiiotool lists '{channel_list(legacy)}', expected '{LEGACY_LIST}'")
    old = OpenEXR.File(legacy)
    old_channels = old.channels()
    if sorted(old_channels) != ["A", "N.X", "N.Y", "N.Z", "P.X", "P.Y", "P.Z"]:
        fail(f"legacy map: the bindings see {sorted(old_channels)}")
    pairs = {"P.X": P[..., 0], "P.Y": P[..., 1], "P.Z": P[..., 2], "A": A, "N.X": N[..., 0],
             "N.Y": N[..., 1], "N.Z": N[..., 2]}
    for name, want in pairs.items():
        if not np.array_equal(old_channels[name].pixels.view(np.uint32),
                              np.ascontiguousarray(want).view(np.uint32)):
            fail(f"legacy map: {name} differs from what was written")
    new_header = {k: v for k, v in image.header().items() if k != "channels"}
    old_header = {k: v for k, v in old.header().items() if k != "channels"}
    if repr(sorted(new_header.items())) != repr(sorted(old_header.items())):
        fail(f"legacy and rgba headers differ beyond the channels:\n{old_header}\n{new_header}")
    old_stats = recipe(legacy, ["P.X", "P.Y", "P.Z"])
    if old_stats["Min"] != stats["Min"] or old_stats["Max"] != stats["Max"]:
        fail(f"recipe on the legacy names: {old_stats['Min']} {old_stats['Max']}")

    print(f"check_posmap_readers: OK (oiiotool lists {RGBA_LIST}; bindings group RGBA + N; "
          f"{len(covered)} covered texels; recipe min {stats['Min']} max {stats['Max']}, plain "
          f"--stats min {plain['Min'][:3]}; OpenEXR {OpenEXR.__version__})")


if __name__ == "__main__":
    main()
