#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Does `db build --suggest` pick better reference frames than the farthest-point rule?

Issue 17: `--suggest N` must lower the true error on the shots it was given, measured against
the same number of farthest-point picks. For one character: a database from its public `train`
clip alone; the same plus N frames of a candidate clip (one of the generated validation clips,
whose simulation is known) picked by `--suggest N --candidate CLIP --shot SHOT...`; and the same
plus N frames of that clip picked by the farthest-point rule of `db build` (`--count N` on the
candidate clip alone). Each database bakes every shot with the defaults, and `drivenshape eval`
judges the bakes against the shots' simulations on their motion frames. Prints one table.

The public `train` clip is the clip folder's <scene>_train1 (an entry of clips.txt, made by
scripts/validation/generate_clips.sh); --reference DIR takes DIR/<scene>/train.* instead.

Usage: scripts/validation/suggest_check.py [--scene pants] [--candidate pants_rom31]
       [--shots pants_ext15 pants_ext16] [--count 10] [--clips DIR] [--reference DIR]
       [--build build] [--out out/suggest]
"""
import argparse
import json
import os
import re
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))


def clip_files(clips_dir, name):
    """(directory, family) of a generated clip named in clips.txt."""
    for line in open(os.path.join(HERE, "clips.txt")):
        parts = line.split()
        if parts and not line.startswith("#") and parts[0] == name:
            return os.path.join(clips_dir, name, parts[1]), parts[2]
    sys.exit(f"suggest_check: {name} is not a clip of {os.path.join(HERE, 'clips.txt')}")


def motion_frames(directory, family):
    meta = json.load(open(os.path.join(directory, family + ".json")))
    return f"{meta['motion_start_frame']}-{meta['frame_end']}"


def run(cmd, log):
    with open(log, "a") as fh:
        fh.write("$ " + " ".join(cmd) + "\n")
        fh.flush()
        result = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        fh.write(result.stdout)
    if result.returncode != 0:
        sys.exit(f"failed ({result.returncode}): {' '.join(cmd)}; see {log}")
    return result.stdout


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scene", default="pants")
    ap.add_argument("--candidate", default="pants_rom31")
    ap.add_argument("--shots", nargs="+", default=["pants_ext15", "pants_ext16"])
    ap.add_argument("--count", type=int, default=10)
    ap.add_argument("--clips", default=os.environ.get("DRIVENSHAPE_VALIDATION_CLIPS",
                                                      os.path.join(ROOT, "out", "clips")),
                    help="the folder of generate_clips.sh (default $DRIVENSHAPE_VALIDATION_CLIPS, "
                    "else out/clips)")
    ap.add_argument("--reference", default=None, metavar="DIR",
                    help="take the public train clip from DIR/<scene>/ instead of the clip "
                    "folder's <scene>_train1")
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--out", default=os.path.join(ROOT, "out", "suggest"))
    a = ap.parse_args()
    ds = os.path.join(a.build, "apps", "drivenshape")
    os.makedirs(a.out, exist_ok=True)
    log = os.path.join(a.out, "commands.log")
    open(log, "w").close()
    src = (os.path.join(a.reference, a.scene) if a.reference
           else os.path.join(a.clips, f"{a.scene}_train1", a.scene))
    if not os.path.exists(os.path.join(src, "train.driven.pc2")):
        sys.exit(f"suggest_check: no train clip in {src}; make it with "
                 f"scripts/validation/generate_clips.sh {a.clips} {a.scene}_train1")
    base = [ds, "db", "build", "--driver-mesh", f"{src}/driver_rest.obj", "--driven-mesh",
            f"{src}/driven_rest.obj", "--driver", f"{src}/train.driver.pc2", "--driven",
            f"{src}/train.driven.pc2", "--count", "30", "--quiet"]
    cand_dir, cand_family = clip_files(a.clips, a.candidate)
    cand_driver = f"{cand_dir}/{cand_family}.driver.pc2"
    cand_driven = f"{cand_dir}/{cand_family}.driven.pc2"
    cand_frames = motion_frames(cand_dir, cand_family)
    shots = []
    for name in a.shots:
        d, family = clip_files(a.clips, name)
        shots.append((name, f"{d}/{family}.driver.pc2", f"{d}/{family}.driven.pc2",
                      motion_frames(d, family)))

    # The suggestions for the shots.
    suggest_json = os.path.join(a.out, "suggest.json")
    cmd = base + ["--suggest", str(a.count), "--candidate", f"{cand_driver}:{cand_frames}",
                  "--suggest-json", suggest_json]
    for _, driver, _, frames in shots:
        cmd += ["--shot", f"{driver}:{frames}"]
    run(cmd, log)
    suggested = [s["frame"] for s in json.load(open(suggest_json))["suggestions"]]
    # The farthest-point picks of the candidate clip alone.
    listing = run([ds, "db", "build", "--driver-mesh", f"{src}/driver_rest.obj", "--driven-mesh",
                   f"{src}/driven_rest.obj", "--driver", cand_driver, "--driven", cand_driven,
                   "--frames", cand_frames, "--count", str(a.count), "--model", "none", "-o",
                   os.path.join(a.out, "farthest.dsdb")], log)
    farthest = [int(m) for m in re.findall(r"pick \d+: frame (\d+)", listing)]
    if len(farthest) != a.count or len(suggested) != a.count:
        sys.exit(f"suggest_check: {len(suggested)} suggested and {len(farthest)} farthest-point "
                 f"frames, not {a.count} each; see {log}")

    def frames_text(frames):
        return ",".join(str(f) for f in sorted(frames))

    variants = [("train only", []),
                (f"+ {len(farthest)} farthest-point frames", farthest),
                (f"+ {len(suggested)} suggested frames", suggested)]
    errors = {}
    for label, frames in variants:
        tag = re.sub(r"[^a-z]+", "_", label).strip("_")
        db = os.path.join(a.out, tag + ".dsdb")
        extra = ["--also", cand_driver, f"{cand_driven}:{frames_text(frames)}"] if frames else []
        run(base + extra + ["-o", db], log)
        for name, driver, truth, frames_range in shots:
            out = os.path.join(a.out, tag, name)
            os.makedirs(out, exist_ok=True)
            run([ds, "bake", "--db", db, "--driver", driver, "--frames", frames_range, "--quiet",
                 "-o", f"{out}/cloth.####.exr"], log)
            ev = os.path.join(out, "eval.json")
            run([ds, "eval", "--truth", truth, "--bake", f"{out}/cloth.####.exr", "--frames",
                 frames_range, "--json", ev], log)
            errors[(label, name)] = json.load(open(ev))["mean"] * 1e3
        print(f"  {label}: " + ", ".join(f"{n} {errors[(label, n)]:.2f} mm" for n, *_ in shots),
              file=sys.stderr)

    print(f"Candidate clip {a.candidate} (frames {cand_frames}); suggested frames "
          f"{frames_text(suggested)}; farthest-point frames {frames_text(farthest)}")
    print()
    print("| database | " + " | ".join(n for n, *_ in shots) + " | mean |")
    print("|---" * (len(shots) + 2) + "|")
    for label, _ in variants:
        row = [errors[(label, n)] for n, *_ in shots]
        print(f"| {label} | " + " | ".join(f"{e:.2f}" for e in row) +
              f" | {sum(row) / len(row):.2f} |")


if __name__ == "__main__":
    main()
