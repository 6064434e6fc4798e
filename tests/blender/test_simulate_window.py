# SPDX-License-Identifier: Apache-2.0
"""The window runner (apps/blender/drivenshape_blender/simulate_window.py, issue 44) in real
Blenders against a full simulation made here.

    blender -b --factory-startup --python-exit-code 1 --python test_simulate_window.py -- \
        --runner apps/blender/drivenshape_blender/simulate_window.py --work WORK

Builds the small cloth scene of cloth_scene.py (a sleeve of 480 vertices on an arm that swings
up 30 degrees, 40 frames), saves it as WORK/shot.blend, simulates it here from frame 1 (the
truth) and writes the truth's frames as world-space point-cache EXRs with the module: the
"bake". Then runs the runner as
`drivenshape simulate` does, one background Blender per window:

(a) goal 0 on frames 24-32 of the truth: frame 24 is the truth's (float32 round trip through
    object space and the Mesh Cache's PC2), and every later frame is much closer to the truth
    than a cold start (the same window simulated from the cloth's rest shape, here); the same
    with --space object on the truth in the cloth's object space;
(b) a bake that is the truth at frame 24 and the truth displaced smoothly by a few centimetres
    after it, goal 0, 0.05, 0.3 and 1: the mean distance of frames 25-32 to that bake falls as
    the goal rises, goal 1 is the bake (the pinned ring excepted: it keeps its own input, the
    truth's), and goal 0 is (a)'s window: a free simulation reads the bake's first frame only;
(c) a missing object, an object without cloth, a missing bake frame, a bake of another vertex
    count and a module that is not there: exit status 1, one line naming it, no output file;
    and --module-path finds the module without DRIVENSHAPE_PYTHONPATH;
and that shot.blend is byte for byte what it was, with no cache folder beside it.
"""

import hashlib
import os
import subprocess
import sys
import time

import bpy
import numpy as np

sys.dont_write_bytecode = True  # Blender ignores PYTHONDONTWRITEBYTECODE: keep the tree clean
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import blender_test_util as util  # noqa: E402
import cloth_scene  # noqa: E402
from cloth_scene import FRAMES, mean_distance, simulate_here, write_exrs  # noqa: E402

# Every position comparison that must hold exactly up to float32 rounding (a frame that went
# world -> object space -> PC2 -> Blender -> world space): metres, about 10 float32 ulps at the
# scene's 1.5 m.
ROUND_TRIP = 2e-6
# (a): the warm-started window's mean distance to the truth, at every frame after the first, at
# most this share of the cold start's at that frame (measured: 0.02-0.03; a window that ignored
# the warm start would be the cold start, 1).
WARM_SHARE = 0.1
FIRST, LAST = 24, 32
GOALS = (0.0, 0.05, 0.3, 1.0)


args = util.parse_args(("--runner", "--work"))
checks = util.Checks("test_simulate_window")
ds = util.import_module_from_path()
MODULE_FOLDER = os.path.dirname(os.path.dirname(os.path.abspath(ds.__file__)))
work = util.fresh_folder(args.work)
blend = os.path.join(work, "shot.blend")


def run_window(name, bake, first=FIRST, last=LAST, goal=0.0, obj="garment", env=None,
               extra=()):
    """The runner on shot.blend as `drivenshape simulate` runs it: (exit status, stderr,
    output folder)."""
    out = os.path.join(work, "windows", name)
    command = [bpy.app.binary_path, "-b", "--factory-startup", blend, "--python-exit-code", "1",
               "--python", args.runner, "--", "--object", obj,
               "--bake", os.path.join(bake, "x.####.exr"), "--first", str(first),
               "--last", str(last), "--goal-strength", str(goal),
               "-o", os.path.join(out, "w.####.exr"), *extra]
    began = time.perf_counter()
    result = subprocess.run(command, capture_output=True, text=True, env=env, check=False)
    print(f"  runner {name}: exit {result.returncode} in {time.perf_counter() - began:.1f} s")
    if result.returncode != 0:
        print("  stderr: " + result.stderr.strip().replace("\n", "\n  stderr: "))
    return result.returncode, result.stderr, out


def read_window(out, first=FIRST, last=LAST):
    frames, records = [], []
    for frame in range(first, last + 1):
        positions, info = ds.read_point_cache_exr(os.path.join(out, f"w.{frame:04d}.exr"))
        frames.append(positions.astype(np.float64))
        records.append(info)
    return np.array(frames), records


scene, cloth, body, pinned = cloth_scene.build_scene()
bpy.ops.wm.save_as_mainfile(filepath=blend)
blend_digest = hashlib.sha256(open(blend, "rb").read()).hexdigest()
hash_value = cloth_scene.topology_hash(ds, cloth)

began = time.perf_counter()
truth = simulate_here(scene, cloth, 1, FRAMES)
print(f"truth: {FRAMES} frames of {truth.shape[1]} vertices in "
      f"{time.perf_counter() - began:.1f} s")
cold = simulate_here(scene, cloth, FIRST, LAST)
truth_bake = os.path.join(work, "bake_truth")
write_exrs(ds, truth_bake, truth, 1, hash_value)
window = slice(FIRST - 1, LAST)
moved = np.linalg.norm(truth[LAST - 1] - truth[0], axis=1).mean()
checks.check(moved > 0.05, f"the truth's cloth moves: {moved * 1000:.0f} mm on average from "
             f"frame 1 to {LAST}")

# (a) goal 0, warm-started from the truth.
status, _, out = run_window("warm", truth_bake)
checks.check(status == 0, f"the runner simulates frames {FIRST}-{LAST} with goal 0")
warm, records = read_window(out)
start = float(np.abs(warm[0] - truth[FIRST - 1]).max())
checks.check(start <= ROUND_TRIP, f"frame {FIRST} is the bake's (the truth's): largest "
             f"coordinate difference {start:.2g} m (tolerance {ROUND_TRIP:g})")
warm_error = mean_distance(warm, truth[window])
cold_error = mean_distance(cold, truth[window])
for i, frame in enumerate(range(FIRST + 1, LAST + 1), start=1):
    print(f"  frame {frame}: warm {warm_error[i] * 1000:.2f} mm, cold {cold_error[i] * 1000:.1f} "
          "mm from the truth")
share = float((warm_error[1:] / cold_error[1:]).max())
checks.check(share <= WARM_SHARE, f"every later frame of the warm window is within "
             f"{WARM_SHARE:g} of the cold start's distance to the truth (worst {share:.3f}; "
             f"warm {warm_error[1:].max() * 1000:.2f} mm, cold {cold_error[1:].min() * 1000:.1f} "
             "mm at their worst and best)")
info = records[1]
record = info.get("string_attributes", {}).get("dsSimulation", "")
checks.check(info["frame"] == FIRST + 1 and info["topology_hash"] == hash_value
             and '"object":"garment"' in record and f'"window":[{FIRST},{LAST}]' in record
             and '"goal_strength":0.0' in record and blend in record,
             f"an output names its frame, the bake's topology and its provenance ({record})")

# --space object: a bake in the cloth's object space (the add-on's Space = Object) gives a
# window in that space: its first frame the bake's, the later ones as close to the truth as
# (a)'s. (Not (a)'s bit for bit: the bake's float32 values differ by rounding between the
# spaces, and the solver with its collisions turns that into differences of about a millimetre
# within 8 frames.)
to_object = np.linalg.inv(np.array(cloth.matrix_world))
local_truth = truth @ to_object[:3, :3].T + to_object[:3, 3]
local_bake = os.path.join(work, "bake_object")
write_exrs(ds, local_bake, local_truth, 1, hash_value)
status, _, out = run_window("object_space", local_bake, extra=("--space", "object"))
checks.check(status == 0, "the runner simulates an object-space bake with --space object")
local_window, _ = read_window(out)
start = float(np.abs(local_window[0] - local_truth[FIRST - 1]).max())
share = float((mean_distance(local_window, local_truth[window])[1:] / cold_error[1:]).max())
checks.check(start <= ROUND_TRIP and share <= WARM_SHARE,
             f"--space object: frame {FIRST} is the bake's ({start:.2g} m), every later frame "
             f"within {WARM_SHARE:g} of the cold start's distance to the truth (worst {share:.3f})")

# (b) goal strengths on a displaced bake.
displaced = truth.copy()
x, y = truth[FIRST:, :, 0], truth[FIRST:, :, 1]
displaced[FIRST:, :, 0] += 0.03 * np.sin(4.0 * y)
displaced[FIRST:, :, 1] += 0.03 * np.cos(3.0 * x)
displaced[FIRST:, :, 2] += 0.04
displaced_bake = os.path.join(work, "bake_displaced")
write_exrs(ds, displaced_bake, displaced, 1, hash_value)
to_bake = []
outputs = {}
for goal in GOALS:
    status, _, out = run_window(f"goal_{goal:g}", displaced_bake, goal=goal)
    checks.check(status == 0, f"the runner simulates the displaced bake with goal {goal:g}")
    outputs[goal], _ = read_window(out)
    to_bake.append(float(mean_distance(outputs[goal][1:], displaced[FIRST:LAST]).mean()))
print(f"  mean distance to the displaced bake, frames {FIRST + 1}-{LAST}: " + ", ".join(
    f"goal {g:g} {d * 1000:.2f} mm" for g, d in zip(GOALS, to_bake)))
checks.check(all(a > b for a, b in zip(to_bake, to_bake[1:])),
             "the higher the goal strength, the closer the window to the bake")
free = np.ones(truth.shape[1], dtype=bool)
free[pinned] = False
pinned_to_bake = float(np.abs(outputs[1.0][:, free] - displaced[window][:, free]).max())
pinned_ring = float(np.abs(outputs[1.0][:, pinned] - truth[window][:, pinned]).max())
checks.check(pinned_to_bake <= ROUND_TRIP and pinned_ring <= ROUND_TRIP,
             f"goal 1 is the bake ({pinned_to_bake:.2g} m), and the pinned ring keeps its own "
             f"input ({pinned_ring:.2g} m)")
same = float(np.abs(outputs[0.0] - warm).max())
checks.check(same <= ROUND_TRIP, f"goal 0 on the displaced bake is goal 0 on the truth (largest "
             f"difference {same:.2g} m): a free window reads the bake's first frame only")

# (c) errors: exit 1, one line naming what is wrong, nothing written.
small_bake = os.path.join(work, "bake_small")
write_exrs(ds, small_bake, truth[:, :10], 1, 0)
no_module_env = {k: v for k, v in os.environ.items() if k != "DRIVENSHAPE_PYTHONPATH"}
for name, kwargs, fragments in (
        ("missing_object", dict(bake=truth_bake, obj="shirt"), ("'shirt'", "No object")),
        ("no_cloth", dict(bake=truth_bake, obj="body"), ("'body'", "no Cloth modifier")),
        ("missing_frame", dict(bake=truth_bake, last=FRAMES + 2),
         (f"Bake frame {FRAMES + 1}", f"x.{FRAMES + 1:04d}.exr", "does not exist")),
        ("vertex_count", dict(bake=small_bake),
         (f"Bake frame {FIRST}", "has 10 vertices", f"'garment' has {truth.shape[1]}")),
        ("no_module", dict(bake=truth_bake, env=no_module_env,
                           extra=("--module-path", os.path.join(work, "nowhere"))),
         ("cannot import the drivenshape Python module", "nowhere"))):
    status, stderr, out = run_window(name, **kwargs)
    lines = [line for line in stderr.splitlines() if line.startswith("simulate_window:")]
    left = os.listdir(out) if os.path.isdir(out) else []
    checks.check(status == 1 and len(lines) == 1
                 and all(fragment in lines[0] for fragment in fragments) and not left,
                 f"{name}: exit {status}, {lines}, {len(left)} files left")
# --module-path alone finds the module.
status, _, out = run_window("module_path", truth_bake, first=FIRST, last=FIRST + 1,
                            env=no_module_env, extra=("--module-path", MODULE_FOLDER))
checks.check(status == 0 and len(os.listdir(out)) == 2,
             "--module-path finds the module without DRIVENSHAPE_PYTHONPATH")

digest = hashlib.sha256(open(blend, "rb").read()).hexdigest()
beside = sorted(set(os.listdir(work)) - {"shot.blend", "bake_truth", "bake_displaced",
                                         "bake_object", "bake_small", "windows"})
checks.check(digest == blend_digest and not beside,
             f"shot.blend is unchanged and nothing appeared beside it ({beside})")
checks.finish()
