# SPDX-License-Identifier: Apache-2.0
"""The Blender half of the consistency matrix (consistency_matrix.py runs it in a background
Blender through tests/blender/run_blender.cmake):

    blender -b --factory-startup --python-exit-code 1 --python consistency_blender.py -- \
        --data tests/data/sleeve --work WORK/blender

WORK/blender/plan.json (written by consistency_matrix.py) names the database, the live-mode
frame sequence and the cells (name, device, weights). For each cell the add-on, installed from
WORK/blender/drivenshape_blender.zip, drives the sleeve scene of tests/blender's helpers in live
mode through the sequence, then bakes the scene range to a PC2. It writes what it got and
compares nothing: CELL.live.npy (one cloth per step of the sequence), CELL.bake.pc2 and
CELL.json (the device the add-on ran on, or the error it reported). consistency_matrix.py
compares them with `drivenshape bake`'s frames.
"""

import json
import os
import sys
import traceback

import bpy
import numpy as np

sys.dont_write_bytecode = True  # Blender ignores PYTHONDONTWRITEBYTECODE: keep the tree clean
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "blender"))
import blender_test_util as util  # noqa: E402

args = util.parse_args()
with open(os.path.join(args.work, "plan.json"), encoding="utf-8") as file:
    plan = json.load(file)
addon = util.install_addon(args.work)
ds = util.drivenshape_module(addon)
driver, cloth = util.sleeve_scene(ds, args.data, plan["database"])
scene = bpy.context.scene
settings = scene.drivenshape
settings.bake_add_mesh_cache = False
settings.bake_use_scene_range = True


def live(sequence):
    """Live mode through `sequence` (scene frames): the cloth after each frame change, and the
    device and weights of the Evaluator it ran."""
    scene.frame_set(sequence[0])
    bpy.ops.drivenshape.live_start()
    if not addon.live.is_live(scene):
        raise RuntimeError("live mode did not start")
    cloths = []
    for frame in sequence:
        scene.frame_set(frame)
        cloths.append(util.evaluated_positions(cloth))
    cache = addon.engine.CACHE
    ran = {"device": cache.evaluator.device_name, "is_opencl": cache.device.is_opencl,
           "evaluations": addon.live.SESSION.frames}
    bpy.ops.drivenshape.live_stop()
    return np.stack(cloths), ran


for cell in plan["cells"]:
    name = cell["name"]
    settings.device = cell["device"]
    settings.weight_mode = cell["weights"]
    out = {"name": name}
    try:
        cloths, out["live"] = live(plan["live_sequence"])
        np.save(os.path.join(args.work, f"{name}.live.npy"), cloths)
    except Exception:  # recorded for the matrix; the other cells still run
        out["live_error"] = traceback.format_exc()
        if addon.live.is_live(scene):
            bpy.ops.drivenshape.live_stop()
    try:
        settings.bake_pc2_path = os.path.join(args.work, f"{name}.bake.pc2")
        result = bpy.ops.drivenshape.bake()
        if result != {"FINISHED"}:
            raise RuntimeError(f"the bake operator returned {result}")
        out["bake"] = {"device": addon.engine.CACHE.evaluator.device_name}
    except Exception:
        out["bake_error"] = traceback.format_exc()
    with open(os.path.join(args.work, f"{name}.json"), "w", encoding="utf-8") as file:
        json.dump(out, file, indent=1)
    print(f"consistency_blender: cell {name} done", flush=True)
