#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""`drivenshape simulate` on the validation clips (issue 44's acceptance): for every clip of
scripts/validation/spread.txt whose clip and 10-step twin have been generated, bake the whole
clip (its preroll included: the frames a simulation of the shot would start from) with the
character's one-reference database and the default settings, let `drivenshape simulate`
simulate what the verdict flags in the clip's own scene (the generator's `--save-blend`, its
cloth settings) and splice it in, then judge the spliced cloth against the full simulation:

- on the flagged motion frames: the mean vertex distance of the spliced, the baked cloth and the
  10-step twin (the sim-to-sim spread) to the truth, and spliced / spread (bar: 1.5);
- the motion frames where the spliced cloth is farther from the truth than the bake (bar: none);
- the largest frame jump (largest vertex step between two motion frames) of the spliced cloth
  against the truth's (bar: 1.5 x), and the largest at the seams (the blended frames and the
  frames beside them);
- the frames simulated (windows and warm-ups) against the clip's, and the wall time of the
  command against simulating the whole clip from its first frame (the window runner over every
  frame, run here only when the plan leaves a frame out; otherwise the plan is the whole clip).

    python3 scripts/validation/simulate_acceptance.py --clips CLIPS [--spread DIR] [--db DIR]
        [--build build] [--out out/simulate] [--only NAME...] [--blender blender]
        [--simulate-flags '--warmup 20']

CLIPS is the folder of generate_clips.sh (clips.txt and spread.txt made into it); --db a folder
with <scene>.dsdb (run_validation.py's, built from <scene>_train1 into --out when not given).
Prints a Markdown table and writes the rows to OUT/acceptance.json. Needs Debian's python3 with
numpy, the build's drivenshape module (BUILD/python) and Blender 3.4. Each clip simulates up to
its whole length in Blender: about 1-2 s a frame on the project's 2-core VM.
"""
import argparse
import json
import os
import subprocess
import sys
import time
import types

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, HERE)
import run_validation  # noqa: E402 (the database and the commands' log, as in the table)
import window_curve  # noqa: E402 (the clip's scene and the window runner)

# The bars of issue 44, each a ratio: spliced / spread on the flagged frames, the spliced
# cloth's largest frame jump / the truth's.
SPREAD_BAR = 1.5
JUMP_BAR = 1.5


def options():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--clips", required=True, help="the folder of generate_clips.sh")
    ap.add_argument("--spread", help="the folder of the _q10 twins (default: --clips)")
    ap.add_argument("--reference", help="the train clips from DIR/<scene>/ (run_validation.py)")
    ap.add_argument("--db", help="a folder with pants.dsdb and sleeve.dsdb (default: built)")
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--out", default=os.path.join(ROOT, "out", "simulate"))
    ap.add_argument("--only", nargs="*", default=[])
    ap.add_argument("--blender", default=os.environ.get("BLENDER", "blender"))
    ap.add_argument("--simulate-flags", default="", help="extra `simulate` flags")
    return ap.parse_args()


def acceptance_clips(a):
    """(name, scene, family, folder, twin folder) of every clip of spread.txt made with its
    twin."""
    out = []
    for line in open(os.path.join(HERE, "spread.txt")):
        if not line.strip() or line.startswith("#"):
            continue
        twin, scene, family = line.split()[:3]
        name = twin[:-len("_q10")]
        folder = os.path.join(a.clips, name, scene)
        twin_folder = os.path.join(a.spread or a.clips, twin, scene)
        made = all(os.path.exists(os.path.join(d, family + ".json"))
                   for d in (folder, twin_folder))
        if made and (not a.only or name in a.only):
            out.append((name, scene, family, folder, twin_folder))
    return out


def databases(a, ds, log):
    dbs = {}
    for scene in ("pants", "sleeve"):
        if a.db:
            dbs[scene] = os.path.join(a.db, scene + ".dsdb")
        else:
            src = run_validation.public_folder(a.clips, a.reference, scene, "train")
            dbs[scene] = run_validation.build_database(ds, src, scene, a.out, "", log)
    return dbs


def largest_jumps_mm(np, cloth, frames):
    """The largest vertex step into each of `frames` (0-based rows) from the frame before."""
    steps = cloth[frames].astype(np.float64) - cloth[[f - 1 for f in frames]]
    return np.linalg.norm(steps, axis=2).max(axis=1) * 1000.0


def read_sequence(ds, np, pattern, count):
    return np.array([ds.read_point_cache_exr(ds.expand_frame_pattern(pattern, f))[0]
                     for f in range(1, count + 1)])


def whole_clip_seconds(a, blend, obj, bake, end, work):
    """The window runner over every frame of the clip from the bake's first: what simulating
    the whole clip costs here."""
    runner = types.SimpleNamespace(blender=a.blender, bake=bake,
                                   module_path=os.path.join(a.build, "python"))
    return window_curve.run_window(runner, blend, obj, 1, end, 0.0,
                                   os.path.join(work, "whole", "w.####.exr"))


def judge(ds, np, meta, folder, twin, work, final):
    """The row's figures from the clip, its twin, the bake and the spliced cloth."""
    family, end, first = meta["family"], meta["frame_end"], meta["motion_start_frame"]
    truth = ds.read_pc2(os.path.join(folder, family + ".driven.pc2"))[0]
    spread = ds.read_pc2(os.path.join(twin, family + ".driven.pc2"))[0]
    baked = read_sequence(ds, np, os.path.join(work, "bake", "cloth.####.exr"), end)
    spliced = read_sequence(ds, np, final, end)
    report = json.load(open(os.path.join(work, "bake", "report.json")))
    flagged = [f["frame"] for f in report["frames"]
               if f.get("coverage", {}).get("flagged") and f["frame"] >= first]
    sources = {f["frame"]: f["source"] for f in json.load(open(
        final.replace(".####.exr", ".report.json")))["frames"]}
    rows = [f - 1 for f in flagged]
    motion = list(range(first - 1, end))
    e_spliced, e_baked, e_spread = (window_curve.distances(np, cloth, truth)
                                    for cloth in (spliced, baked, spread))
    worse = [r + 1 for r in motion if e_spliced[r] > e_baked[r]]
    seams = sorted({f - 1 + d for f, s in sources.items() if s == "blended" for d in (0, 1)
                    if first <= f - 1 + d < end})
    jumps = largest_jumps_mm(np, spliced, motion[1:])
    row = dict(flagged=len(flagged), motion_frames=len(motion),
               spliced_mm=float(e_spliced[rows].mean()) if rows else None,
               baked_mm=float(e_baked[rows].mean()) if rows else None,
               spread_mm=float(e_spread[rows].mean()) if rows else None,
               worse_frames=worse,
               worse_by_mm=float(max((e_spliced[f - 1] - e_baked[f - 1] for f in worse),
                                     default=0.0)),
               jump_mm=float(jumps.max()),
               truth_jump_mm=float(largest_jumps_mm(np, truth, motion[1:]).max()),
               baked_jump_mm=float(largest_jumps_mm(np, baked, motion[1:]).max()),
               seam_jump_mm=float(largest_jumps_mm(np, spliced, seams).max()) if seams else None,
               sources={s: list(sources.values()).count(s) for s in sorted(set(sources.values()))})
    if rows:
        row["ratio"] = row["spliced_mm"] / row["spread_mm"]
    return row


def run_clip(a, ds, np, db, clip):
    name, scene, family, folder, twin = clip
    meta = json.load(open(os.path.join(folder, family + ".json")))
    work = os.path.join(a.out, name)
    os.makedirs(work, exist_ok=True)
    log = os.path.join(work, "commands.log")
    cli = os.path.join(a.build, "apps", "drivenshape")
    bake = os.path.join(work, "bake", "cloth.####.exr")
    end = meta["frame_end"]
    run_validation.run([cli, "bake", "--db", db, "--driver", f"{folder}/{family}.driver.pc2",
                        "--frames", f"1-{end}", "--quiet", "-o", bake, "--report",
                        os.path.join(work, "bake", "report.json")], log)
    blend = window_curve.make_blend(a, meta, work)
    final = os.path.join(work, "final", "x.####.exr")
    began = time.perf_counter()
    run_validation.run([cli, "simulate", "--blend", blend, "--object", meta["driven"]["object"],
                        "--report", os.path.join(work, "bake", "report.json"), "--bake", bake,
                        "-o", final, "--blender", a.blender] + a.simulate_flags.split(), log)
    wall = time.perf_counter() - began
    plan = json.load(open(os.path.join(work, "final", "x.simulation-plan.json")))
    row = dict(clip=name, scene=scene, frames=end, windows=plan["windows"],
               simulated_frames=plan["simulated_frames"], wall_s=wall)
    row.update(judge(ds, np, meta, folder, twin, work, final))
    row["whole_clip_s"] = (wall if plan["simulated_frames"] == end else
                           whole_clip_seconds(a, blend, meta["driven"]["object"], bake, end, work))
    return row


def cell(value, form):
    return "-" if value is None else format(value, form)


def table(rows):
    head = ["clip", "flagged motion frames", "windows (frames simulated of the clip's)",
            "spliced mm", "baked mm", "spread mm", "spliced / spread", "frames worse than baked",
            "largest jump mm: spliced, at seams (truth)", "wall s (whole clip)", "bars"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        windows = ", ".join(f"{w['warmup_from']}/{w['from']}-{w['to']}" for w in r["windows"])
        worse = str(len(r["worse_frames"])) + (f" (by up to {r['worse_by_mm']:.2f})"
                                               if r["worse_frames"] else "")
        held = (r.get("ratio") is None or r["ratio"] <= SPREAD_BAR) and not r["worse_frames"] \
            and r["jump_mm"] <= JUMP_BAR * r["truth_jump_mm"]
        lines.append("| " + " | ".join([
            r["clip"], f"{r['flagged']} of {r['motion_frames']}",
            f"{windows or 'none'} ({r['simulated_frames']} of {r['frames']})",
            cell(r["spliced_mm"], ".2f"), cell(r["baked_mm"], ".2f"), cell(r["spread_mm"], ".2f"),
            cell(r.get("ratio"), ".2f"), worse,
            f"{r['jump_mm']:.1f}, {cell(r['seam_jump_mm'], '.1f')} ({r['truth_jump_mm']:.1f})",
            f"{r['wall_s']:.0f} ({r['whole_clip_s']:.0f})", "yes" if held else "no"]) + " |")
    return "\n".join(lines)


def main():
    a = options()
    sys.path.insert(0, os.path.join(a.build, "python"))
    import numpy as np  # noqa: PLC0415 (Debian's python3, as the module)

    import drivenshape as ds  # noqa: PLC0415 (found in the build)

    os.makedirs(a.out, exist_ok=True)
    # The module the window runner imports in Blender: this build's.
    os.environ.setdefault("DRIVENSHAPE_PYTHONPATH", os.path.abspath(os.path.join(a.build, "python")))
    dbs = databases(a, os.path.join(a.build, "apps", "drivenshape"),
                    os.path.join(a.out, "commands.log"))
    rows = []
    for clip in acceptance_clips(a):
        print(f"{clip[0]}: bake, simulate, judge", flush=True)
        rows.append(run_clip(a, ds, np, dbs[clip[1]], clip))
        with open(os.path.join(a.out, "acceptance.json"), "w") as handle:
            json.dump(rows, handle, indent=1)
    print(table(rows))


if __name__ == "__main__":
    main()
