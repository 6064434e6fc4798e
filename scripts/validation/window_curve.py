#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""What a simulation window needs (issue 44, part 5): the distance of a warm-started window's
frames to the full simulation, against warm-up length and goal strength, on a validation clip.

    python3 scripts/validation/window_curve.py CLIP_DIR 'BAKE/cloth.####.exr' \\
        [--from-truth] [--ends 60,100] [--hand-back 5] [--warmups 0,5,10,20,40] \\
        [--goals 0,0.1,0.3] [--blend CLIP.blend] [--spread SPREAD_CLIP_DIR] [--work DIR] \\
        [--json OUT.json] [--blender blender] [--module-path build/python]

CLIP_DIR is a clip of scripts/validation/generate_clips.sh (e.g. /work/clips/sleeve_rom33/
sleeve): its <family>.driven.pc2 is the full simulation (the truth) and its <family>.json the
generator's settings. BAKE is a bake of that clip's driver (`drivenshape bake ... -o BAKE`),
world space as the command line writes it. The clip's scene comes from --blend, or is made
once into --work by the generator itself (make_clip.py with the clip's scene, family, seed,
motion frames and --set overrides, `--save-blend PATH --blend-only`: the same set-up the clip
was simulated from, the generator's own cloth settings).

For every end frame E, warm-up W (a number, or `start`: from the first frame the bake holds)
and goal strength S, the window runner (apps/blender/drivenshape_blender/simulate_window.py,
what `drivenshape simulate` runs) simulates frames E - H + 1 - W .. E from the bake's cloth,
one background Blender each, and the H handed-back frames E - H + 1 .. E are measured: their
mean vertex distance to the truth in mm (mean over vertices and frames; the worst frame too),
beside the bake's own on those frames and, with --spread (the clip simulated again, e.g. with
10 solver steps: scripts/validation/spread.txt), the sim-to-sim spread on them. A window that
would start before the bake's first frame starts there (its row says so). Wall time is the
runner's whole Blender run (start-up, reading, simulating, writing); the clip json's own
simulation time per frame is printed for the full-simulation comparison. --from-truth starts the
windows from the truth instead of a bake: what is left is the solver's own divergence from a
restart (zero velocities, Blender's cloth cannot be given others) and from the float32 round
trip, the floor under any bake.

Prints a Markdown table and writes the rows as JSON (--json). Needs python3 with numpy and the
drivenshape module (Debian's python3; --module-path or DRIVENSHAPE_PYTHONPATH, default
build/python), and Blender 3.4. Not a CTest: each window is a Blender run of seconds to minutes
(the clips' cloth takes 0.5-1.5 s a frame on the project's VM).
"""
import argparse
import glob
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
RUNNER = os.path.join(ROOT, "apps", "blender", "drivenshape_blender", "simulate_window.py")
MAKE_CLIP = os.path.join(ROOT, "scripts", "clipgen", "make_clip.py")


def options():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("clip", help="the clip folder (<family>.driven.pc2, <family>.json)")
    parser.add_argument("bake", nargs="?", help="the bake's point-cache EXRs (####)")
    parser.add_argument("--from-truth", action="store_true",
                        help="start the windows from the truth itself instead of a bake (its "
                        "frames written as EXRs into --work): the floor that the solver's own "
                        "divergence and the zero start velocities leave")
    parser.add_argument("--family", help="default: the clip folder's one <family>.json")
    parser.add_argument("--ends", help="end frames of the windows, comma-separated (default: "
                        "the clip's last frame)")
    parser.add_argument("--hand-back", type=int, default=5,
                        help="frames each window hands back, ending at its end frame")
    parser.add_argument("--warmups", default="0,5,10,20,40",
                        help="warm-up lengths; `start` = from the bake's first frame")
    parser.add_argument("--goals", default="0,0.1,0.3", help="goal strengths, 0 to 1")
    parser.add_argument("--blend", help="the clip's scene (default: made into --work)")
    parser.add_argument("--spread", help="the same clip simulated again (its folder)")
    parser.add_argument("--work", help="windows and the made .blend (default: a temporary "
                        "folder, removed after)")
    parser.add_argument("--json", help="write the rows here")
    parser.add_argument("--blender", default=os.environ.get("BLENDER", "blender"))
    parser.add_argument("--module-path", default=os.environ.get(
        "DRIVENSHAPE_PYTHONPATH", os.path.join(ROOT, "build", "python")))
    return parser.parse_args()


def clip_info(folder, family):
    if family is None:
        names = [n for n in glob.glob(os.path.join(folder, "*.json"))
                 if os.path.basename(n) != "rig.json"]
        if len(names) != 1:
            raise SystemExit(f"window_curve: {folder} holds {len(names)} clip jsons; pass "
                             "--family")
        family = os.path.basename(names[0])[:-len(".json")]
    with open(os.path.join(folder, f"{family}.json")) as handle:
        info = json.load(handle)
    return family, info


def make_blend(args, info, work):
    """The clip's scene saved by the generator (no simulation): work/<scene>_<family>.blend."""
    path = os.path.join(work, f"{info['scene']}_{info['family']}{info['seed']}.blend")
    if os.path.exists(path):
        return path
    command = [args.blender, "-b", "--factory-startup", "--python-exit-code", "1", "--python",
               MAKE_CLIP, "--", "--scene", info["scene"], "--family", info["family"],
               "--seed", str(info["seed"]), "--frames", str(info["motion_frames"]),
               "--out", os.path.join(work, "clipgen"), "--save-blend", path, "--blend-only"]
    for override in info.get("overrides", []):
        command += ["--set", override]
    print("making the clip's scene: " + " ".join(command), flush=True)
    result = subprocess.run(command, capture_output=True, text=True, check=False)
    if result.returncode != 0 or not os.path.exists(path):
        raise SystemExit(f"window_curve: the generator failed (exit {result.returncode}):\n"
                         + result.stdout[-2000:] + result.stderr[-2000:])
    return path


def bake_frames(ds, pattern, last):
    return [f for f in range(1, last + 1) if os.path.exists(ds.expand_frame_pattern(pattern, f))]


def run_window(args, blend, obj, first, last, goal, out_pattern):
    command = [args.blender, "-b", "--factory-startup", blend, "--python-exit-code", "1",
               "--python", RUNNER, "--", "--object", obj, "--bake", args.bake,
               "--first", str(first), "--last", str(last), "--goal-strength", str(goal),
               "-o", out_pattern, "--module-path", args.module_path]
    began = time.perf_counter()
    result = subprocess.run(command, capture_output=True, text=True, check=False)
    seconds = time.perf_counter() - began
    if result.returncode != 0:
        lines = [line for line in result.stderr.splitlines() if "simulate_window" in line]
        raise SystemExit(f"window_curve: the runner failed on frames {first}-{last} goal {goal} "
                         f"(exit {result.returncode}): {' '.join(lines) or result.stderr[-2000:]}")
    return seconds


def distances(np, a, b):
    """Mean vertex distance per frame, mm."""
    return np.linalg.norm(a.astype(np.float64) - b, axis=2).mean(axis=1) * 1000.0


def measure(args, ds, np, context, end, warmup, goal):
    truth, spread, available, blend, obj, work = context
    hand = list(range(end - args.hand_back + 1, end + 1))
    wanted = available[0] if warmup == "start" else hand[0] - int(warmup)
    first = max(wanted, available[0])
    missing = [f for f in range(first, end + 1) if f not in set(available)]
    if missing:
        raise SystemExit(f"window_curve: the bake has no frame {missing[0]} (window {first}-{end})")
    out = os.path.join(work, f"w_{end}_{warmup}_{goal:g}", "w.####.exr")
    seconds = run_window(args, blend, obj, first, end, goal, out)
    window = np.array([ds.read_point_cache_exr(ds.expand_frame_pattern(out, f))[0] for f in hand])
    baked = np.array([ds.read_point_cache_exr(ds.expand_frame_pattern(args.bake, f))[0]
                      for f in hand])
    rows = [f - 1 for f in hand]  # the PC2s start at frame 1, one sample per frame
    error = distances(np, window, truth[rows])
    row = dict(end=end, warmup=warmup, goal=goal, first=first, last=end,
               started_at_bake_start=first != wanted, handed_back=hand,
               simulated_frames=end - first + 1, mean_mm=float(error.mean()),
               worst_frame_mm=float(error.max()), per_frame_mm=[round(float(e), 3) for e in error],
               bake_mm=float(distances(np, baked, truth[rows]).mean()), wall_s=seconds)
    if spread is not None:
        row["spread_mm"] = float(distances(np, spread[rows], truth[rows]).mean())
    return row


def table(rows):
    spread = any("spread_mm" in r for r in rows)
    head = ["end", "warm-up", "goal", "window", "simulated", "mm (hand-back)", "worst frame mm",
            "bake mm"] + (["spread mm"] if spread else []) + ["wall s"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        window = f"{r['first']}-{r['last']}" + (" (bake's start)" if r["started_at_bake_start"]
                                                 else "")
        cells = [r["end"], r["warmup"], f"{r['goal']:g}", window, r["simulated_frames"],
                 f"{r['mean_mm']:.2f}", f"{r['worst_frame_mm']:.2f}", f"{r['bake_mm']:.2f}"]
        cells += [f"{r['spread_mm']:.2f}"] if spread else []
        cells += [f"{r['wall_s']:.1f}"]
        lines.append("| " + " | ".join(str(c) for c in cells) + " |")
    return "\n".join(lines)


def main():
    args = options()
    sys.path.insert(0, os.path.abspath(args.module_path))
    import numpy as np  # noqa: PLC0415 (Debian's python3, as the module)

    import drivenshape as ds  # noqa: PLC0415 (found through --module-path)

    family, info = clip_info(args.clip, args.family)
    truth, _start, _rate = ds.read_pc2(os.path.join(args.clip, f"{family}.driven.pc2"))
    spread = None
    if args.spread:
        spread, _start, _rate = ds.read_pc2(os.path.join(args.spread, f"{family}.driven.pc2"))
    frames = len(truth)
    ends = [int(e) for e in args.ends.split(",")] if args.ends else [frames]
    warmups = [w if w == "start" else int(w) for w in args.warmups.split(",")]
    goals = [float(g) for g in args.goals.split(",")]
    work = args.work or tempfile.mkdtemp(prefix="window_curve_")
    os.makedirs(work, exist_ok=True)
    if args.from_truth:
        args.bake = os.path.join(work, "truth", "x.####.exr")
        os.makedirs(os.path.dirname(args.bake), exist_ok=True)
        for i, positions in enumerate(truth):
            ds.write_point_cache_exr(ds.expand_frame_pattern(args.bake, i + 1), positions,
                                     frame=i + 1, sync=False)
    elif not args.bake:
        raise SystemExit("window_curve: give the bake's EXR pattern, or --from-truth")
    available = bake_frames(ds, args.bake, frames)
    if not available:
        raise SystemExit(f"window_curve: no frame of {args.bake} in 1-{frames}")
    try:
        blend = args.blend or make_blend(args, info, work)
        obj = info["driven"]["object"]
        timing = info.get("timing", {})
        print(f"clip {args.clip} ({family}, {frames} frames, bake frames {available[0]}-"
              f"{available[-1]}); the full simulation took {timing.get('mean_frame_s', 0):.2f} s "
              f"a frame when the clip was made ({timing.get('total_simulation_s', 0):.0f} s in "
              "all)", flush=True)
        context = (truth, spread, available, blend, obj, work)
        rows = []
        for end in ends:
            for warmup in warmups:
                for goal in goals:
                    row = measure(args, ds, np, context, end, warmup, goal)
                    rows.append(row)
                    print(f"  end {end} warm-up {warmup} goal {goal:g}: {row['mean_mm']:.2f} mm "
                          f"(bake {row['bake_mm']:.2f}) in {row['wall_s']:.1f} s", flush=True)
    finally:
        if not args.work:
            shutil.rmtree(work, ignore_errors=True)
    print(table(rows))
    if args.json:
        with open(args.json, "w") as handle:
            json.dump(dict(clip=args.clip, family=family,
                           bake="truth" if args.from_truth else args.bake, blend=args.blend,
                           hand_back=args.hand_back, rows=rows), handle, indent=1)


if __name__ == "__main__":
    main()
