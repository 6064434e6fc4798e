# SPDX-License-Identifier: Apache-2.0
"""Checker-textured renders of one frame of a garment, side by side: the simulation and one or
more bakes of it, so that stretch shows as it does to a TD (squares that grow, shrink or shear),
not only as a number. Blender 3.4 (Workbench, no GPU needed), run headless:

    DRIVENSHAPE_PYTHONPATH=build/python blender -b --factory-startup --python-exit-code 1 \
        --python scripts/render_strain.py -- \
        --driver-mesh CLIP/driver_rest.obj --driven-mesh CLIP/driven_rest.obj \
        --driver CLIP/extremes.driver.pc2 --frame 60 \
        --column "simulation=CLIP/extremes.driven.pc2" \
        --column "bake, no strain limit=off/c.####.exr" \
        --column "bake, defaults=on/c.####.exr" \
        --title "sleeve_ext15, frame 60" -o docs/images/strain_sleeve.png

Every column shows the body (grey) and the garment at --frame, textured with a black and white
checker laid out on the garment's own UVs (the rest mesh's OBJ `vt`), seen from the front (the
clip generator's convention: Z up, the character faces -Y). Under each column its label and the
frame's mean |strain| (|edge| / |rest edge| - 1 over the rest mesh's edges, as `drivenshape eval`
computes it with the module's `frame_strain`). Caches are PC2 files or point-cache EXR
sequences, read with the drivenshape module. Exit status 1 on any failure (Blender's
--python-exit-code), with the reason on stderr.
"""

import argparse
import math
import os
import sys

import bpy
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "scripts"))
from drivenshape_import import import_drivenshape  # noqa: E402

CHECKER_PIXELS = 1024
CHECKER_SQUARES = 24  # per side of the UV square
GAP = 0.3  # between columns, in units of a column's width
BODY_GREY = (0.55, 0.55, 0.58, 1.0)


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    ap = argparse.ArgumentParser(prog="render_strain.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("--driver-mesh", required=True)
    ap.add_argument("--driven-mesh", required=True)
    ap.add_argument("--driver", required=True, help="the body's cache (PC2 or EXR sequence)")
    ap.add_argument("--frame", type=int, required=True)
    ap.add_argument("--column", action="append", required=True, metavar="LABEL=CACHE")
    ap.add_argument("--title", default="")
    ap.add_argument("--resolution", type=int, default=900, help="image height in pixels")
    ap.add_argument("-o", "--out", required=True)
    return ap.parse_args(argv)


def frame_positions(ds, spec, frame, vertex_count):
    """The (V, 3) positions of `frame` of a PC2 file or an EXR sequence."""
    cache = ds.open_point_cache(spec)
    if cache.vertex_count != vertex_count:
        raise RuntimeError(f"{spec}: {cache.vertex_count} vertices, the mesh has {vertex_count}")
    return np.asarray(cache.read(frame), dtype=np.float64)


def checker_material():
    image = bpy.data.images.new("checker", CHECKER_PIXELS, CHECKER_PIXELS)
    cells = np.indices((CHECKER_PIXELS, CHECKER_PIXELS)) * CHECKER_SQUARES // CHECKER_PIXELS
    value = np.where((cells[0] + cells[1]) % 2 == 0, 0.95, 0.08).astype(np.float32)
    rgba = np.stack([value, value, value, np.ones_like(value)], axis=-1)
    image.pixels.foreach_set(rgba.ravel())
    material = bpy.data.materials.new("checker")
    material.use_nodes = True
    nodes = material.node_tree.nodes
    texture = nodes.new("ShaderNodeTexImage")
    texture.image = image
    texture.interpolation = "Closest"
    shader = nodes["Principled BSDF"]
    material.node_tree.links.new(texture.outputs["Color"], shader.inputs["Base Color"])
    return material


def flat_material(name, rgba):
    material = bpy.data.materials.new(name)
    material.diffuse_color = rgba  # what Workbench shows of a material without an image
    return material


def make_object(name, mesh, positions, material):
    """A Blender object with `mesh`'s faces (and UVs) at `positions`."""
    data = bpy.data.meshes.new(name)
    starts, corners = mesh.faces
    polygons = [corners[starts[i]:starts[i + 1]].tolist() for i in range(len(starts) - 1)]
    data.from_pydata(positions.tolist(), [], polygons)
    if mesh.has_uvs:
        uv_layer = data.uv_layers.new(name="uv")
        uvs = np.asarray(mesh.uvs)[np.asarray(mesh.face_uvs)]
        uv_layer.data.foreach_set("uv", uvs.astype(np.float32).ravel())
    data.update()
    obj = bpy.data.objects.new(name, data)
    bpy.context.scene.collection.objects.link(obj)
    data.materials.append(material)
    for polygon in data.polygons:
        polygon.use_smooth = True
    return obj


def add_text(body, location, size, material):
    curve = bpy.data.curves.new("label", "FONT")
    curve.body = body
    curve.size = size
    curve.align_x = "CENTER"
    obj = bpy.data.objects.new("label", curve)
    obj.location = location
    obj.rotation_euler = (math.pi / 2, 0.0, 0.0)  # stand up, facing -Y
    curve.materials.append(material)
    bpy.context.scene.collection.objects.link(obj)


def setup_render(scene, width, height, box_min, box_max):
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.display.shading.light = "STUDIO"
    scene.display.shading.color_type = "TEXTURE"
    scene.display.shading.show_object_outline = False
    scene.render.resolution_x = width
    scene.render.resolution_y = height
    scene.render.film_transparent = False
    scene.world = bpy.data.worlds.new("white")
    scene.world.color = (1.0, 1.0, 1.0)
    scene.view_settings.view_transform = "Standard"
    camera = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    camera.data.type = "ORTHO"
    centre = (box_min + box_max) / 2
    extent = box_max - box_min
    camera.data.ortho_scale = max(extent[0], extent[2] * width / height) * 1.05
    camera.location = (centre[0], box_min[1] - 5.0, centre[2])
    camera.rotation_euler = (math.pi / 2, 0.0, 0.0)  # looking along +Y
    camera.data.clip_end = 100.0
    scene.collection.objects.link(camera)
    scene.camera = camera


def main():
    args = parse_args()
    ds = import_drivenshape()
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    driver_mesh = ds.read_obj(args.driver_mesh)
    driven_mesh = ds.read_obj(args.driven_mesh)
    if not driven_mesh.has_uvs:
        raise RuntimeError(f"{args.driven_mesh}: no UVs (vt) to lay the checker out on")
    body = frame_positions(ds, args.driver, args.frame, driver_mesh.vertex_count)
    rest = np.asarray(driven_mesh.positions, dtype=np.float64)
    edges = np.asarray(driven_mesh.edges)
    columns = []
    for spec in args.column:
        label, _, cache = spec.partition("=")
        if not cache:
            raise RuntimeError(f"--column {spec!r}: expected LABEL=CACHE")
        cloth = frame_positions(ds, cache, args.frame, driven_mesh.vertex_count)
        strain = ds.frame_strain(rest, cloth, edges)
        columns.append((label, cloth, strain))

    both = np.vstack([body] + [cloth for _, cloth, _ in columns])
    low, high = both.min(axis=0), both.max(axis=0)
    step = (high[0] - low[0]) * (1 + GAP)
    material = checker_material()
    grey = flat_material("body", BODY_GREY)
    black = flat_material("label", (0.0, 0.0, 0.0, 1.0))
    label_size = 0.032 * (max(high[2] - low[2], high[0] - low[0]) + 0.2)
    for i, (label, cloth, strain) in enumerate(columns):
        shift = np.array([i * step, 0.0, 0.0])
        make_object(f"body{i}", driver_mesh, body + shift, grey)
        make_object(f"cloth{i}", driven_mesh, cloth + shift, material)
        text = (f"{label}\nmean |strain| {100 * strain['strain_mean']:.1f}%\n"
                f"edges over 10%: {100 * strain['strain_share_over_10pct']:.1f}%")
        add_text(text, (low[0] + (high[0] - low[0]) / 2 + i * step, low[1] - 0.5,
                        low[2] - 1.6 * label_size), label_size, black)
    if args.title:
        add_text(args.title, (low[0] + (len(columns) * step - step * GAP / (1 + GAP)) / 2,
                              low[1] - 0.5, high[2] + 0.6 * label_size), label_size, black)

    box_min = np.array([low[0], low[1], low[2] - 4.6 * label_size])
    box_max = np.array([low[0] + len(columns) * step - (step - (high[0] - low[0])), high[1],
                        high[2] + (1.8 * label_size if args.title else 0.0)])
    aspect = (box_max[0] - box_min[0]) / (box_max[2] - box_min[2])
    height = args.resolution
    width = int(round(height * aspect / 2)) * 2
    setup_render(bpy.context.scene, width, height, box_min, box_max)
    out = os.path.abspath(args.out)
    bpy.context.scene.render.filepath = out
    bpy.ops.render.render(write_still=True)
    print(f"render_strain: wrote {out} ({width} x {height})")


try:
    main()
except Exception as error:  # the message, not a traceback, and Blender's exit code 1
    print(f"render_strain: {error}", file=sys.stderr)
    sys.exit(1)
