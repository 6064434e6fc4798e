# SPDX-License-Identifier: Apache-2.0
"""`drivenshape simulate` end to end with the real Blender (issue 44): a real window, a real
splice, checked against references made here.

    blender -b --factory-startup --python-exit-code 1 --python test_simulate_command.py -- \
        --cli build/apps/drivenshape \
        --runner apps/blender/drivenshape_blender/simulate_window.py --work WORK

Builds the small cloth shot of cloth_scene.py, saves it as WORK/shot.blend and simulates it here
(the truth). The "bake" is the truth displaced smoothly by about a centimetre (so that a baked
frame is never a simulated one), written as world-space point-cache EXRs, and its report (written
here) flags frames 12-14 and 28-30. With --warmup 5 --merge-gap 2 --seam 3 --carry 3
--goal-strength 0.25 the plan is, worked by hand: windows [7, 12-14] and [23, 28-30];
sources baked 1-8, blended 9-11 (seam), simulated 12-14, blended 15-17 (carry), baked 18-24,
blended 25-27, simulated 28-30, blended 31-33, baked 34-40.

1. The references: simulate_window.py run directly, once per window, with the command line that
   docs/commands.md gives for a window (the frames of the hand-worked plan).
2. The command with the real Blender behind a logging wrapper that refuses the second window:
   exit 3 naming the window, no output frame, the first window complete in the windows folder
   and equal to its reference (this measures whether Blender's cloth is deterministic from one
   process to the next on one machine).
3. The command again: the first window kept (the wrapper's log shows one Blender, for the
   second window), every frame 1-40 written with its source in the header and the report, the
   plan's windows the hand-worked ones, and every frame equal to the splice computed here in
   numpy from the bake and the references (docs: simulation.h, spliceSimulation): baked frames
   bitwise, simulated and blended ones within SAME; nothing else written, shot.blend unchanged.
4. The add-on's Simulate Flagged Frames (drivenshape.simulate_flagged) in this Blender on the
   same scene, verdicts and settings: its spliced files are the command's byte for byte.
"""

import hashlib
import json
import os
import stat
import subprocess
import sys
import time

import bpy
import numpy as np

sys.dont_write_bytecode = True  # Blender ignores PYTHONDONTWRITEBYTECODE: keep the tree clean
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import blender_test_util as util  # noqa: E402
import cloth_scene  # noqa: E402
from cloth_scene import FRAMES  # noqa: E402

# The largest coordinate difference allowed between a frame of the command and the reference
# made here from the direct runs: 0, since Blender's cloth is deterministic from one process to
# the next on one machine (measured on the test machine: the command's first window and its
# direct run are bitwise equal). A nondeterministic solver fails here, naming the difference.
SAME = 0.0
FLAGGED = (12, 13, 14, 28, 29, 30)
SETTINGS = dict(warmup=5, merge_gap=2, seam=3, carry=3, goal_strength=0.25)
# The plan, worked by hand from FLAGGED and SETTINGS: (warmup_from, from, to).
WINDOWS = ((7, 12, 14), (23, 28, 30))
SOURCES = "B" * 8 + "LLL" + "SSS" + "LLL" + "B" * 7 + "LLL" + "SSS" + "LLL" + "B" * 7
NAMES = {"B": "baked", "S": "simulated", "L": "blended"}

args = util.parse_args(("--cli", "--runner", "--work"))
checks = util.Checks("test_simulate_command")
ds = util.import_module_from_path()
work = util.fresh_folder(args.work)
blend = os.path.join(work, "shot.blend")
bake_dir = os.path.join(work, "bake")
bake_pattern = os.path.join(bake_dir, "x.####.exr")
report_path = os.path.join(bake_dir, "x.report.json")
final_dir = os.path.join(work, "final")
out_pattern = os.path.join(final_dir, "x.####.exr")
# Blender and the runner make their temporary folders here; the test checks that none is left.
temp = os.path.join(work, "tmp")
os.makedirs(temp)
run_env = dict(os.environ, TMPDIR=temp)
assert len(SOURCES) == FRAMES


def frame_path(pattern, frame):
    return pattern.replace("####", f"{frame:04d}")


def read_frames(pattern, frames):
    """(F, V, 3) float32 and the headers of frames `frames` of a sequence."""
    positions, infos = [], []
    for frame in frames:
        xyz, info = ds.read_point_cache_exr(frame_path(pattern, frame))
        positions.append(xyz)
        infos.append(info)
    return np.array(positions), infos


def digests(folder):
    return {name: hashlib.sha256(open(os.path.join(folder, name), "rb").read()).hexdigest()
            for name in sorted(os.listdir(folder)) if name.endswith(".exr")}


def window_args(first, last, out):
    """The runner's command line for a window (docs/commands.md, "drivenshape simulate")."""
    return ["-b", blend, "--python-exit-code", "1", "--python", args.runner, "--",
            "--object", "garment", "--bake", bake_pattern, "--first", str(first),
            "--last", str(last), "--goal-strength", "0.25", "-o", out]


def write_wrapper():
    """A `blender` that logs each command line and runs the real one, except the window whose
    --first is $WRAPPER_REFUSE (exit 1 without starting Blender): the command's plumbing seen
    from outside, the simulation Blender's own."""
    path = os.path.join(work, "bin", "blender")
    os.makedirs(os.path.dirname(path))
    log = os.path.join(work, "blender_runs.log")
    with open(path, "w") as script:
        script.write(f"""#!/bin/sh
echo "$*" >> '{log}'
case " $* " in
  *" --first ${{WRAPPER_REFUSE:-none}} "*) echo "wrapper: refused window $WRAPPER_REFUSE" >&2; \
exit 1;;
esac
exec '{bpy.app.binary_path}' "$@"
""")
    os.chmod(path, os.stat(path).st_mode | stat.S_IXUSR)
    return path, log


def simulate(blender, refuse=None):
    command = [args.cli, "simulate", "--blend", blend, "--object", "garment", "--report",
               report_path, "--bake", bake_pattern, "-o", out_pattern, "--blender", blender,
               "--warmup", "5", "--merge-gap", "2", "--seam", "3", "--carry", "3",
               "--goal-strength", "0.25"]
    env = dict(run_env, WRAPPER_REFUSE=str(refuse)) if refuse else run_env
    began = time.perf_counter()
    result = subprocess.run(command, capture_output=True, text=True, env=env, check=False)
    seconds = time.perf_counter() - began
    print(f"  drivenshape simulate: exit {result.returncode} in {seconds:.1f} s")
    for line in (result.stdout + result.stderr).strip().splitlines():
        print(f"    {line}")
    return result, seconds


def spliced_reference(baked, windows):
    """The splice of simulation.h's spliceSimulation, in numpy (float64, rounded to float32):
    frame f of the result at [f - 1]; `windows` the reference frames warmup_from..to."""
    out = baked.copy()
    b64 = baked.astype(np.float64)
    seam, carry = SETTINGS["seam"], SETTINGS["carry"]
    for w, ((warmup_from, first, last), sim) in enumerate(zip(WINDOWS, windows)):
        s64 = sim.astype(np.float64)
        out[first - 1:last] = sim[first - warmup_from:]
        s = min(seam, first - warmup_from)
        for k in range(1, s + 1):
            f = first - s - 1 + k
            weight = k / (s + 1)
            out[f - 1] = (b64[f - 1] + weight * (s64[f - warmup_from] - b64[f - 1])).astype(
                np.float32)
        residual = s64[last - warmup_from] - b64[last - 1]
        stop = (WINDOWS[w + 1][1] - min(seam, WINDOWS[w + 1][1] - WINDOWS[w + 1][0]) - 1
                if w + 1 < len(WINDOWS) else FRAMES)
        for k in range(1, carry + 1):
            f = last + k
            if f > stop:
                break
            out[f - 1] = (b64[f - 1] + (1.0 - k / (carry + 1)) * residual).astype(np.float32)
    return out


# The shot, its truth and the bake.
scene, cloth, body, _pinned = cloth_scene.build_scene()
bpy.ops.wm.save_as_mainfile(filepath=blend)
blend_digest = hashlib.sha256(open(blend, "rb").read()).hexdigest()
hash_value = cloth_scene.topology_hash(ds, cloth)
began = time.perf_counter()
truth = cloth_scene.simulate_here(scene, cloth, 1, FRAMES)
print(f"truth: {FRAMES} frames of {truth.shape[1]} vertices in "
      f"{time.perf_counter() - began:.1f} s")
baked = truth.copy()
baked[..., 0] += 0.01 * np.sin(4.0 * truth[..., 1])
baked[..., 1] += 0.01 * np.cos(3.0 * truth[..., 0])
baked[..., 2] += 0.005
cloth_scene.write_exrs(ds, bake_dir, baked, 1, hash_value)
baked = baked.astype(np.float32)
report = {"coverage": {"tolerance": 0.02},
          "frames": [{"frame": f, "predicted_error": 0.05 if f in FLAGGED else 0.01,
                      "coverage": {"flagged": f in FLAGGED}} for f in range(1, FRAMES + 1)]}
with open(report_path, "w") as stream:
    json.dump(report, stream)

# 1. The references: the runner run directly, one Blender per window.
references = []
for warmup_from, _first, last in WINDOWS:
    out = os.path.join(work, "reference", f"window_{warmup_from}", "w.####.exr")
    began = time.perf_counter()
    result = subprocess.run([bpy.app.binary_path, *window_args(warmup_from, last, out)],
                            capture_output=True, text=True, env=run_env, check=False)
    print(f"  reference window {warmup_from}-{last}: exit {result.returncode} in "
          f"{time.perf_counter() - began:.1f} s")
    checks.check(result.returncode == 0, f"the runner simulates frames {warmup_from}-{last} "
                 f"directly ({result.stderr.strip()[-300:]})")
    references.append(read_frames(out, range(warmup_from, last + 1))[0])
expected = spliced_reference(baked, references)

# 2. The command, the second window refused.
blender, blender_log = write_wrapper()
result, _ = simulate(blender, refuse=WINDOWS[1][0])
checks.check(result.returncode == 3 and "window 28-30 (simulated from 23): Blender exited with "
             "status 1" in result.stderr and "refused window 23" in result.stderr,
             "a failed window: exit 3 naming the window and the last line of Blender's log")
written = [f for f in range(1, FRAMES + 1) if os.path.exists(frame_path(out_pattern, f))]
checks.check(not written, f"a failed window writes no output frame ({written})")
kept_pattern = os.path.join(final_dir, "x.simulate-windows", "window_12", "w.####.exr")
kept, _ = read_frames(kept_pattern, range(7, 15))
difference = float(np.abs(kept.astype(np.float64) - references[0]).max())
print(f"  determinism: the command's window 7-14 against its direct run: largest coordinate "
      f"difference {difference:.3g} m")
checks.check(difference <= SAME, f"the command's first window is its direct run's (largest "
             f"difference {difference:.3g} m, allowed {SAME:g})")

# 3. The rerun: the first window kept, the second simulated, the splice.
os.remove(blender_log)
result, seconds = simulate(blender)
checks.check(result.returncode == 0, "the rerun simulates the second window and splices")
runs = open(blender_log).read().splitlines() if os.path.exists(blender_log) else []
checks.check(len(runs) == 1 and " --first 23 --last 30 " in runs[0]
             and "window 1/2: frames 7-14 kept from a run before" in result.stderr,
             f"the rerun keeps the first window and starts one Blender, for the second "
             f"({len(runs)} started, {seconds:.1f} s)")
output, infos = read_frames(out_pattern, range(1, FRAMES + 1))
with open(os.path.join(final_dir, "x.report.json")) as stream:
    simulate_report = json.load(stream)
with open(os.path.join(final_dir, "x.simulation-plan.json")) as stream:
    plan = json.load(stream)
got_windows = tuple((w["warmup_from"], w["from"], w["to"]) for w in plan["windows"])
checks.check(got_windows == WINDOWS and plan["simulated_frames"] == 16,
             f"the plan's windows are the hand-worked ones ({got_windows})")
report_sources = [(entry["frame"], entry["source"]) for entry in simulate_report["frames"]]
header_sources = [info.get("string_attributes", {}).get("dsSource") for info in infos]
wanted = [NAMES[c] for c in SOURCES]
checks.check(report_sources == list(zip(range(1, FRAMES + 1), wanted)) and
             header_sources == wanted,
             "every frame 1-40 is written, its source (report and header) the plan's")
checks.check(all(info["frame"] == f and info["topology_hash"] == hash_value
                 for f, info in zip(range(1, FRAMES + 1), infos)),
             "each output names its frame and the bake's topology")
is_baked = np.array([c == "B" for c in SOURCES])
checks.check(np.array_equal(output[is_baked], baked[is_baked]),
             "the baked frames are the bake's, bit for bit")
for letter in "SL":
    rows = np.array([c == letter for c in SOURCES])
    difference = float(np.abs(output[rows].astype(np.float64) - expected[rows]).max())
    distance = float(cloth_scene.mean_distance(output[rows], baked[rows]).min())
    checks.check(difference <= SAME and distance > 1e-4,
                 f"the {NAMES[letter]} frames are the splice computed here from the direct "
                 f"runs (largest difference {difference:.3g} m) and not the bake (at least "
                 f"{distance * 1000:.2f} mm from it on average)")
digest = hashlib.sha256(open(blend, "rb").read()).hexdigest()
checks.check(digest == blend_digest, "shot.blend is unchanged")
left = {
    "work": sorted(set(os.listdir(work)) - {"shot.blend", "bake", "final", "tmp", "reference",
                                            "bin", "blender_runs.log"}),
    "bake": sorted(set(os.listdir(bake_dir)) - {"x.report.json"} -
                   {f"x.{f:04d}.exr" for f in range(1, FRAMES + 1)}),
    "final": sorted(set(os.listdir(final_dir)) - {"x.report.json", "x.simulation-plan.json",
                                                  "x.simulate-windows"} -
                    {f"x.{f:04d}.exr" for f in range(1, FRAMES + 1)}),
    "tmp": os.listdir(temp)}
checks.check(not any(left.values()), f"nothing else is written ({left})")

# 4. The add-on's operator on the same scene: the same files, byte for byte.
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(args.runner))))
import drivenshape_blender  # noqa: E402

drivenshape_blender.register()
settings = scene.drivenshape
settings.driver, settings.cloth, settings.space = body, cloth, "WORLD"
settings.bake_write_exr, settings.bake_exr_pattern = True, bake_pattern
for key, value in SETTINGS.items():
    setattr(settings, f"simulate_{key}", value)
settings.verdict_tolerance = 0.02
for f in range(1, FRAMES + 1):
    verdict = settings.verdicts.add()
    verdict.frame, verdict.error_bound, verdict.flagged = f, 0.05 if f in FLAGGED else 0.01, \
        f in FLAGGED
began = time.perf_counter()
try:
    outcome = bpy.ops.drivenshape.simulate_flagged()
except RuntimeError as error:  # the operator's report of a failure
    outcome = f"{{'CANCELLED'}}: {error}"
print(f"  Simulate Flagged Frames: {outcome} in {time.perf_counter() - began:.1f} s")
spliced_dir = os.path.join(bake_dir, "simulated")
mine, theirs = digests(spliced_dir) if os.path.isdir(spliced_dir) else {}, digests(final_dir)
differ = sorted(name for name in theirs if mine.get(name) != theirs[name])
checks.check(outcome == {"FINISHED"} and len(theirs) == FRAMES and not differ
             and sorted(mine) == sorted(theirs),
             f"the operator's spliced files are the command's byte for byte ({len(mine)} files, "
             f"{len(differ)} differ: {differ[:3]})")
checks.finish()
