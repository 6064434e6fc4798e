# SPDX-License-Identifier: Apache-2.0
"""The bundled sample shot as a Blender cloth scene, for `drivenshape simulate` in the demo.

    blender -b --factory-startup --python-exit-code 1 --python scripts/sample_scene.py -- \\
        [--data tests/data/sleeve] [--driver test.driver.pc2] -o out/sample/shot.blend

The sample (tests/data/sleeve) holds caches, not a rig: the arm's rest mesh and its motion as a
PC2, the sleeve's rest mesh. The scene is what the clip generator builds (scripts/clipgen: its
sleeve cloth and collision settings, its pin group, gravity, 24 fps), with the rig replaced by
the caches:

- the arm ("arm"): its rest mesh, a Mesh Cache modifier playing the driver PC2 (scene frame f
  is the cache's frame f), then the generator's Collision modifier;
- the sleeve ("sleeve"): its rest mesh, a Surface Deform modifier bound to the arm at rest (it
  carries the pinned vertices with the arm, as the generator's armature does), then the
  generator's Cloth modifier with the pin group "pin" on the sample's pinned vertices
  (sample.json `pin_vertices`: the source clip's rig.json `driven_pin_vertices`).

It checks that the arm it evaluates at the first and last frame is the PC2's and saves the
.blend (nothing is simulated here: `drivenshape simulate` runs the windows).
"""
import argparse
import json
import os
import sys

import bpy
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "scripts", "clipgen"))
from dsclip import blendscene, cachefiles, config  # noqa: E402 (the generator's scene)

# The largest difference, in metres, allowed between the arm Blender evaluates and the PC2's
# frame (float32 positions read back).
SAME_POSITIONS = 1e-5


def options():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(prog="sample_scene.py", description=__doc__.split("\n")[0])
    parser.add_argument("--data", default=os.path.join(ROOT, "tests", "data", "sleeve"))
    parser.add_argument("--driver", default="test.driver.pc2",
                        help="the arm's motion, a PC2 in --data (default test.driver.pc2)")
    parser.add_argument("-o", "--output", required=True, help="the .blend to write")
    return parser.parse_args(argv)


def mesh(path):
    """A rest OBJ as the generator's mesh dict (vertex and face order kept)."""
    verts, faces, uvs, face_uvs = cachefiles.read_obj(path)
    corners = [[uvs[i].tolist() if i >= 0 else [0.0, 0.0] for i in ids] for ids in face_uvs]
    return dict(verts=verts, faces=faces, uvs=corners)


def bind_to(garment, body):
    """A Surface Deform modifier on `garment`, bound to `body` as it is now (at rest)."""
    modifier = garment.modifiers.new("Surface Deform", "SURFACE_DEFORM")
    modifier.target = body
    with bpy.context.temp_override(object=garment, active_object=garment):
        bpy.ops.object.surfacedeform_bind(modifier=modifier.name)
    garment.evaluated_get(bpy.context.evaluated_depsgraph_get())  # the bind happens here
    if not modifier.is_bound:
        raise RuntimeError(f"{garment.name}: the Surface Deform modifier did not bind")


def check_arm(scene, body, frames):
    for frame in (1, len(frames)):
        scene.frame_set(frame)
        evaluated = body.evaluated_get(bpy.context.evaluated_depsgraph_get()).to_mesh()
        points = np.empty(3 * len(evaluated.vertices), dtype=np.float32)
        evaluated.vertices.foreach_get("co", points)
        difference = float(np.abs(points.reshape(-1, 3) - frames[frame - 1]).max())
        if difference > SAME_POSITIONS:
            raise RuntimeError(f"the arm at frame {frame} is {difference:.3g} m from the PC2's")


def main():
    args = options()
    info = json.load(open(os.path.join(args.data, "sample.json")))
    character = config.CHARACTERS[info["scene"]]
    sim = config.sim_settings([])
    driver = os.path.abspath(os.path.join(args.data, args.driver))
    frames = cachefiles.read_pc2(driver)[0]
    scene = blendscene.empty_scene(len(frames), info["fps"])
    body_name, garment_name = character["objects"]
    body = blendscene.mesh_object(body_name, mesh(os.path.join(args.data, "driver_rest.obj")))
    garment = blendscene.mesh_object(garment_name, mesh(os.path.join(args.data, "driven_rest.obj")))
    bind_to(garment, body)
    cache = body.modifiers.new("Mesh Cache", "MESH_CACHE")
    cache.cache_format, cache.filepath = "PC2", driver
    cache.frame_start = 1.0  # the scene's frame 1 plays the PC2's first sample
    blendscene.make_collider(body, sim["body_collision"])
    blendscene.make_cloth(garment, info["pin_vertices"], sim["cloth"], sim["cloth_collision"],
                          len(frames))
    check_arm(scene, body, frames)
    scene.frame_set(1)
    os.makedirs(os.path.dirname(os.path.abspath(args.output)), exist_ok=True)
    bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(args.output))
    print(f"sample_scene: {args.output} ({len(frames)} frames of {args.driver}; the garment "
          f"'{garment_name}', {len(info['pin_vertices'])} pinned vertices)", flush=True)


if __name__ == "__main__":
    main()
