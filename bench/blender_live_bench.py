# SPDX-License-Identifier: Apache-2.0
"""Live-mode frame rate of the Blender add-on in a real Blender (a benchmark, not a test).

    blender -b --factory-startup --python bench/blender_live_bench.py -- \
        [--scene sleeve|pants|DIR] [--passes 3] [--audit] [--device auto] [--json OUT.json]

DRIVENSHAPE_PYTHONPATH must name the folder that holds the drivenshape module (build/python).
The add-on is loaded from the source tree (apps/blender), as "install by path" does.

A scene folder holds driver_rest.obj, driven_rest.obj, train.driver.pc2, train.driven.pc2 and a
test driver clip (test.driver.pc2 or test_public.driver.pc2). `sleeve` is the bundled
tests/data/sleeve (2146 driver / 2244 cloth vertices); `pants` is out/data/pants, the public
pants clips made by scripts/validation/generate_clips.sh --link-data out/data out/clips (4241 /
4501 vertices; the figures in docs/blender.md were measured on an earlier generator's pants of
4311 / 4581), which only benchmarks read. The database (30 shapes from every training frame) is
built once with the module and kept in out/bench/.

The driver plays the test clip through a Mesh Cache modifier with live mode on. Per frame it
times what an animator's frame change costs: scene.frame_set() (Blender evaluates the driver,
then the add-on's frame_change_post handler reads it, evaluates one frame and writes the cloth)
plus the depsgraph update that re-evaluates the cloth; the handler's own split (read driver /
evaluate / write cloth) comes from the live session. One untimed pass warms up, then --passes
timed passes; medians and 90th percentiles are printed. Then frames that start a batch: jumps to
the clip's frames in a shuffled order and the clip played backwards, each frame with its warm-up
frames read by setting the scene to them. Viewport drawing is not included (no window in
background mode).
"""

import argparse
import collections
import json
import os
import platform
import sys
import time

import bpy
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.dont_write_bytecode = True  # Blender ignores PYTHONDONTWRITEBYTECODE: keep the tree clean
sys.path.insert(0, os.path.join(ROOT, "apps", "blender"))
import drivenshape_blender  # noqa: E402

SCENES = {
    "sleeve": os.path.join(ROOT, "tests", "data", "sleeve"),
    "pants": os.path.join(ROOT, "out", "data", "pants"),
}


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(description="live-mode frames per second in Blender")
    parser.add_argument("--scene", default="sleeve", help="sleeve, pants or a folder")
    parser.add_argument("--passes", type=int, default=3, help="timed passes over the clip")
    parser.add_argument("--audit", action="store_true", help="turn the per-frame audit on")
    parser.add_argument("--device", default="auto")
    parser.add_argument("--json", help="also write the figures to this JSON file")
    return parser.parse_args(argv)


def test_clip(folder):
    for name in ("test.driver.pc2", "test_public.driver.pc2"):
        if os.path.exists(os.path.join(folder, name)):
            return os.path.join(folder, name)
    raise SystemExit(f"no test driver clip in {folder}")


def database_for(ds, name, folder):
    path = os.path.join(ROOT, "out", "bench", f"{name}.dsdb")
    if not os.path.exists(path):
        os.makedirs(os.path.dirname(path), exist_ok=True)
        started = time.perf_counter()
        database = ds.build_database(
            os.path.join(folder, "driver_rest.obj"), os.path.join(folder, "driven_rest.obj"),
            os.path.join(folder, "train.driver.pc2"), os.path.join(folder, "train.driven.pc2"),
            count=30)
        database.save(path)
        print(f"built {path} in {time.perf_counter() - started:.1f} s")
    return path


def import_obj(path, name):
    bpy.ops.object.select_all(action="DESELECT")
    bpy.ops.wm.obj_import(filepath=path, forward_axis="Y", up_axis="Z")
    obj = bpy.context.selected_objects[0]
    obj.name = name
    return obj


def percentiles(values):
    values = np.array(values) * 1000.0
    return float(np.median(values)), float(np.percentile(values, 90))


def time_frame_changes(scene, order):
    """Seconds of each frame change to the frames of `order`, the cloth re-evaluated after."""
    times = []
    for frame in order:
        began = time.perf_counter()
        scene.frame_set(int(frame))
        bpy.context.evaluated_depsgraph_get()
        times.append(time.perf_counter() - began)
    return times


def time_jumps(scene, frames, live):
    """What frames that start a batch cost (a jump, playing backwards): every frame evaluates
    its warm-up frames first, read by setting the scene to each (the history of the pose model,
    the temporal bound's warm-up). Frames in a shuffled order (seeded), then the clip backwards;
    per kind the median and p90 of the frame change and of the handler's read (the current frame
    and the warm-up frames) and evaluate parts."""
    out = {}
    order = np.random.default_rng(27).permutation(frames)
    for kind, frames_in_order in (("jumps", order), ("backwards", frames[::-1])):
        time_frame_changes(scene, frames_in_order)  # warm-up
        live.SESSION.timings = collections.deque(maxlen=len(frames))
        read_before = live.SESSION.warmup_frames_read
        totals = time_frame_changes(scene, frames_in_order)
        handler = np.array(live.SESSION.timings)
        out[kind] = {"frame_ms": percentiles(totals),
                     "read_ms": percentiles(handler[:, 0]),
                     "evaluate_ms": percentiles(handler[:, 1]),
                     "warmup_frames_read": (live.SESSION.warmup_frames_read - read_before)
                     / len(frames)}
    return out


def main():
    args = parse_args()
    drivenshape_blender.register()
    ds = drivenshape_blender.module.get()
    name = args.scene if args.scene in SCENES else os.path.basename(args.scene.rstrip("/"))
    folder = SCENES.get(args.scene, args.scene)
    database = database_for(ds, name, folder)

    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    driver = import_obj(os.path.join(folder, "driver_rest.obj"), "driver")
    cloth = import_obj(os.path.join(folder, "driven_rest.obj"), "cloth")
    clip = test_clip(folder)
    _positions, start, _rate = ds.read_pc2(clip)
    frames = list(range(int(start), int(start) + len(_positions)))
    modifier = driver.modifiers.new("clip", "MESH_CACHE")
    modifier.cache_format = "PC2"
    modifier.filepath = clip
    modifier.frame_start = start  # scene frame f shows the clip's frame f

    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = frames[0], frames[-1]
    settings = scene.drivenshape
    settings.driver, settings.cloth, settings.database_path = driver, cloth, database
    settings.audit = args.audit
    settings.device = args.device
    scene.frame_set(frames[0])
    started = time.perf_counter()
    bpy.ops.drivenshape.live_start()
    setup = time.perf_counter() - started
    engine = drivenshape_blender.engine
    live = drivenshape_blender.live

    def play():
        times = []
        for frame in frames:
            began = time.perf_counter()
            scene.frame_set(frame)
            bpy.context.evaluated_depsgraph_get()  # the cloth, re-evaluated after the write
            times.append(time.perf_counter() - began)
        return times

    play()  # warm-up
    live.SESSION.timings = collections.deque(maxlen=len(frames) * args.passes)
    totals = []
    for _ in range(args.passes):
        totals += play()
    handler = np.array(live.SESSION.timings)
    frame_median, frame_p90 = percentiles(totals)
    split = {part: percentiles(handler[:, i])
             for i, part in enumerate(("read_driver", "evaluate", "write_cloth", "handler"))}
    blender_rest = percentiles(np.array(totals) - handler[:, 3])
    history = engine.CACHE.evaluator.history_frames
    jumps = time_jumps(scene, frames, live)
    bpy.ops.drivenshape.live_stop()

    database_object = engine.CACHE.database
    result = {
        "scene": name,
        "driver_vertices": database_object.driver_vertex_count,
        "cloth_vertices": database_object.driven_vertex_count,
        "shapes": database_object.shape_count,
        "frames_timed": len(totals),
        "audit": args.audit,
        "device": engine.CACHE.device.description,
        "blender": bpy.app.version_string,
        "cpu": platform.processor() or platform.machine(),
        "cores": os.cpu_count(),
        "setup_seconds": setup,
        "frame_ms_median": frame_median,
        "frame_ms_p90": frame_p90,
        "fps_median": 1000.0 / frame_median,
        "handler_ms": split,
        "blender_ms": blender_rest,
        "history_frames": history,
        "batch_starts": jumps,
    }
    print(f"\nlive mode, {name}: {result['driver_vertices']} driver / "
          f"{result['cloth_vertices']} cloth vertices, {result['shapes']} shapes, "
          f"audit {'on' if args.audit else 'off'}, {len(totals)} frames timed "
          f"({args.passes} passes after a warm-up), {os.cpu_count()} cores")
    print(f"device: {result['device']}; start (load, evaluator, first frame) {setup:.2f} s")
    print(f"{'per frame, ms':<40}{'median':>8}{'p90':>8}")
    rows = [("frame change, all (frame_set + cloth)", (frame_median, frame_p90)),
            ("  read driver (foreach_get)", split["read_driver"]),
            ("  evaluate (evaluate_into)", split["evaluate"]),
            ("  write cloth (foreach_set, update)", split["write_cloth"]),
            ("  handler in all", split["handler"]),
            ("  Blender (driver cache, cloth eval)", blender_rest)]
    for label, (median, p90) in rows:
        print(f"{label:<40}{median:>8.2f}{p90:>8.2f}")
    print(f"=> {result['fps_median']:.1f} frames/s (median frame)")
    print_jumps(jumps, history)
    if args.json:
        os.makedirs(os.path.dirname(os.path.abspath(args.json)), exist_ok=True)
        with open(args.json, "w", encoding="utf-8") as file:
            json.dump(result, file, indent=1)


def print_jumps(jumps, history):
    print(f"frames that start a batch ({history} history frames), ms    median     p90")
    for kind, label in (("jumps", "jumps, shuffled order"), ("backwards", "playing backwards")):
        row = jumps[kind]
        print(f"{label} ({row['warmup_frames_read']:.1f} warm-up frames read per frame)")
        for part, name in (("frame_ms", "frame change, all"),
                           ("read_ms", "  read driver + warm-up"), ("evaluate_ms", "  evaluate")):
            print(f"{name:<40}{row[part][0]:>8.2f}{row[part][1]:>8.2f}")


main()
