#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""The validation table (issue 17): every clip x every mode against the simulated truth.

For each character: one database from its public `train` clip (the reference a TD has:
`drivenshape db build`, 30 picks plus the pose model over the whole clip); then every clip of
scripts/validation/clips.txt that has been generated (scripts/validation/generate_clips.sh) and
the public `test_public` clip is baked in every mode and judged by `drivenshape eval` on its
motion frames (after the 20 preroll frames):

  talk      the 2008 talk: --weights qp --align none --blend world --no-resolve --strain-limit 0
  bind      the binding baseline: --weights bind --no-resolve --strain-limit 0
  qp        the 0.1 defaults: --weights qp --strain-limit 0 (rigid alignment, local blend,
            resolution)
  defaults  the defaults: the pose model (--weights auto on a database with a model) and the
            strain limit

The public clips are entries of clips.txt too, found by name in the clip folder (--clips):
<scene>_train1 (the database) and <scene>_test_public2 (the last two rows). --reference DIR
takes them from DIR/<scene>/{train,test_public}.* instead (e.g. the folder of
generate_clips.sh --link-data).

Prints one Markdown table (mean vertex error in mm per mode, the defaults against the better of
talk and binding, cloth inside the body per frame against the truth's, the largest frame jump
against the truth's, the coverage verdict), then the strain table (issue 43: per clip and mode,
the bake's mean |strain| of the cloth's edges, its nearest-rank 95th percentile and the share of
edges over 10%, each beside the simulation's, from eval's JSON), then the coverage figures:
Spearman rank correlation of the predicted error with the true per-frame error over every
validation frame, and the true mean error of the frames the verdict calls covered. Writes
everything under --out.

Usage: scripts/validation/run_validation.py [--clips DIR] [--reference DIR]
       [--build build] [--out out/validation] [--modes talk,bind,qp,defaults] [--only NAME...]
       [--skip NAME...] [--db-flags FLAGS] [--bake-flags FLAGS]
       scripts/validation/run_validation.py --from-tables RUN1/table.json RUN2/table.json ...
"""
import argparse
import json
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))

MODES = {
    "talk": ["--weights", "qp", "--align", "none", "--blend", "world", "--no-resolve",
             "--strain-limit", "0"],
    "bind": ["--weights", "bind", "--no-resolve", "--strain-limit", "0"],
    "qp": ["--weights", "qp", "--strain-limit", "0", "--exit-fade", "0.15"],
    "defaults": [],
}

# The strain figures of eval's JSON (fractions; the table shows them in %), with their column
# headings: per clip and mode, the bake's and, in brackets, the simulation's (the truth's).
STRAIN_COLUMNS = (("strain_mean", "mean \\|strain\\| % (truth)"),
                  ("strain_p95", "strain p95 % (truth)"),
                  ("strain_share_over_10pct", "edges > 10% strain, % (truth)"))


# The public clips of clips.txt, by character: the database's `train` clip and the public
# `test_public` clip (the table's last rows).
DATABASE_CLIP = "{}_train1"
PUBLIC_TEST_CLIP = "{}_test_public2"


def public_folder(clips_dir, reference, scene, family):
    """The folder of a character's public `train` or `test_public` clip."""
    if reference:
        return os.path.join(reference, scene)
    name = (DATABASE_CLIP if family == "train" else PUBLIC_TEST_CLIP).format(scene)
    return os.path.join(clips_dir, name, scene)


def clips(clips_dir, reference):
    """(name, scene, directory, family) of every generated clip, then the public test clips."""
    public = {f.format(s) for f in (DATABASE_CLIP, PUBLIC_TEST_CLIP) for s in ("pants", "sleeve")}
    out = []
    for line in open(os.path.join(HERE, "clips.txt")):
        if not line.strip() or line.startswith("#"):
            continue
        name, scene, family = line.split()[:3]
        d = os.path.join(clips_dir, name, scene)
        if name not in public and os.path.exists(os.path.join(d, family + ".json")):
            out.append((name, scene, d, family))
    for scene in ("pants", "sleeve"):
        d = public_folder(clips_dir, reference, scene, "test_public")
        if os.path.exists(os.path.join(d, "test_public.json")):
            out.append((scene + "_test_public (public)", scene, d, "test_public"))
        else:
            print(f"note: no public test clip in {d} (generate_clips.sh CLIPS "
                  f"{PUBLIC_TEST_CLIP.format(scene)}); its row is left out", file=sys.stderr)
    return out


def build_database(ds, src, scene, out, db_flags, log):
    """The character's database from its `train` clip in `src` (30 picks and the pose model):
    out/<scene>.dsdb, its model's figures in out/<scene>.model.json. Returns the database."""
    db = os.path.join(out, scene + ".dsdb")
    run([ds, "db", "build", "--driver-mesh", f"{src}/driver_rest.obj", "--driven-mesh",
         f"{src}/driven_rest.obj", "--driver", f"{src}/train.driver.pc2", "--driven",
         f"{src}/train.driven.pc2", "--count", "30", "-o", db,
         "--model-json", os.path.join(out, scene + ".model.json")]
        + db_flags.replace("{scene}", src).replace("{character}", scene).split(), log)
    return db


def spread(d, family, twin, meta, build):
    """Mean vertex distance (scene units) between a clip's cloth and its twin's over the motion
    frames, the caches read by the built module (BUILD/python); None when the twin was not
    generated."""
    import numpy as np
    path = os.path.join(twin, family + ".driven.pc2")
    if not os.path.exists(path):
        return None
    sys.path.insert(0, os.path.join(build, "python"))
    import drivenshape
    a = drivenshape.read_pc2(os.path.join(d, family + ".driven.pc2"))[0]
    b = drivenshape.read_pc2(path)[0]
    first = meta["motion_start_frame"] - 1
    return float(np.linalg.norm(a[first:] - b[first:], axis=2).mean())


def run(cmd, log):
    with open(log, "a") as fh:
        fh.write("$ " + " ".join(cmd) + "\n")
        fh.flush()
        result = subprocess.run(cmd, stdout=fh, stderr=fh)
    if result.returncode != 0:
        sys.exit(f"failed ({result.returncode}): {' '.join(cmd)}; see {log}")


def spearman(a, b):
    def ranks(x):
        order = sorted(range(len(x)), key=lambda i: x[i])
        r = [0.0] * len(x)
        i = 0
        while i < len(order):
            j = i
            while j + 1 < len(order) and x[order[j + 1]] == x[order[i]]:
                j += 1
            for k in range(i, j + 1):
                r[order[k]] = (i + j) / 2.0
            i = j + 1
        return r
    ra, rb = ranks(a), ranks(b)
    ma, mb = sum(ra) / len(ra), sum(rb) / len(rb)
    cov = sum((x - ma) * (y - mb) for x, y in zip(ra, rb))
    va = sum((x - ma) ** 2 for x in ra) ** 0.5
    vb = sum((y - mb) ** 2 for y in rb) ** 0.5
    return cov / (va * vb) if va > 0 and vb > 0 else float("nan")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--clips", default=os.environ.get("DRIVENSHAPE_VALIDATION_CLIPS",
                                                      os.path.join(ROOT, "out", "clips")),
                    help="the folder of generate_clips.sh (default $DRIVENSHAPE_VALIDATION_CLIPS, "
                    "else out/clips)")
    ap.add_argument("--reference", default=None, metavar="DIR",
                    help="take the public train and test_public clips from DIR/<scene>/ instead "
                    "of the clip folder's <scene>_train1 and <scene>_test_public2")
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--out", default=os.path.join(ROOT, "out", "validation"))
    ap.add_argument("--modes", default="talk,bind,qp,defaults")
    ap.add_argument("--only", nargs="*", default=[])
    ap.add_argument("--skip", nargs="*", default=[],
                    help="clips to leave out (e.g. those given to `db build --also`)")
    ap.add_argument("--db-flags", default="",
                    help="extra `db build` flags; {scene} becomes the character's reference "
                    "folder (e.g. --rig {scene}/rig.json), {character} its name (pants, sleeve; "
                    "e.g. --also CLIPS/{character}_rom31/{character}/train.driver.pc2 "
                    "CLIPS/{character}_rom31/{character}/train.driven.pc2)")
    ap.add_argument("--spread", default=None, metavar="DIR",
                    help="the clips of spread.txt (generate_clips.sh --list spread.txt): each "
                    "clip's NAME_q10 twin, simulated again with 10 solver steps; the table "
                    "gives the mean vertex distance between the two simulations (the sim-to-sim "
                    "spread) beside the model's error")
    ap.add_argument("--bake-flags", default="",
                    help="extra `bake` flags of the defaults mode (e.g. --exit-fade 0.2)")
    ap.add_argument("--baselines", metavar="TABLE.json",
                    help="take the modes not run here (e.g. talk and bind, which the --also "
                    "clips do not change) from an earlier run's table.json, clip by clip")
    ap.add_argument("--error-bar", type=float, default=0.8,
                    help="the defaults' largest ratio to the better of talk and bind (issue 30: "
                    "0.8 with one reference clip, 0.6 with three)")
    ap.add_argument("--spread-bar", type=float, default=0.0,
                    help="the defaults' largest ratio to the clip's sim-to-sim spread (issue "
                    "30: 2 with three reference clips; 0 = not judged)")
    ap.add_argument("--from-tables", nargs="+", metavar="TABLE.json",
                    help="print the table of earlier runs (their table.json) together, bake nothing")
    a = ap.parse_args()
    if a.from_tables:
        rows = [r for t in a.from_tables for r in json.load(open(t))]
        rows.sort(key=lambda r: "public" in r["clip"])  # the public clips stay the last rows
        if a.spread:
            for r in rows:
                meta = json.load(open(os.path.join(r["dir"], r["family"] + ".json")))
                twin = os.path.join(a.spread, r["clip"].split()[0] + "_q10", r["scene"])
                metres = spread(r["dir"], r["family"], twin, meta, a.build)
                r["spread"] = None if metres is None else metres * 1e3
        modes = [m for m in a.modes.split(",") if all(m in r for r in rows)]
        print_table(rows, modes, a)
        print_strain_table(rows, modes)
        print_summary(rows)
        return
    ds = os.path.join(a.build, "apps", "drivenshape")
    modes = a.modes.split(",")
    os.makedirs(a.out, exist_ok=True)
    log = os.path.join(a.out, "commands.log")
    open(log, "w").close()
    dbs = {}
    for scene in ("pants", "sleeve"):
        src = public_folder(a.clips, a.reference, scene, "train")
        if not os.path.exists(os.path.join(src, "train.driven.pc2")):
            sys.exit(f"run_validation: no train clip in {src}; make it with "
                     f"scripts/validation/generate_clips.sh {a.clips} {DATABASE_CLIP.format(scene)}")
        dbs[scene] = (build_database(ds, src, scene, a.out, a.db_flags, log), src)
    rows, pooled_pred, pooled_true = [], [], []
    for name, scene, d, family in clips(a.clips, a.reference):
        if (a.only and name.split()[0] not in a.only) or name.split()[0] in a.skip:
            continue
        meta = json.load(open(os.path.join(d, family + ".json")))
        frames = f"{meta['motion_start_frame']}-{meta['frame_end']}"
        db, src = dbs[scene]
        row = {"clip": name, "scene": scene, "frames": frames, "dir": d, "family": family}
        if a.spread:
            twin = os.path.join(a.spread, name.split()[0] + "_q10", scene)
            metres = spread(d, family, twin, meta, a.build)
            row["spread"] = None if metres is None else metres * 1e3
        for mode in modes:
            out = os.path.join(a.out, name.split()[0], mode)
            os.makedirs(out, exist_ok=True)
            report = os.path.join(out, "report.json")
            run([ds, "bake", "--db", db, "--driver", f"{d}/{family}.driver.pc2", "--frames",
                 frames, "--quiet", "-o", f"{out}/cloth.####.exr", "--report", report]
                + MODES[mode] + (a.bake_flags.split() if mode == "defaults" else []), log)
            ev = os.path.join(out, "eval.json")
            run([ds, "eval", "--truth", f"{d}/{family}.driven.pc2", "--bake",
                 f"{out}/cloth.####.exr", "--frames", frames, "--driver",
                 f"{d}/{family}.driver.pc2", "--driver-mesh", f"{src}/driver_rest.obj",
                 "--driven-mesh", f"{src}/driven_rest.obj", "--json", ev], log)
            e = json.load(open(ev))
            s = e["summary"]
            row[mode] = {"mean": e["mean"] * 1e3, "inside": s["bake"]["mean_inside"],
                         "inside_max": s["bake"]["max_inside"],
                         "jump": s["bake"]["max_jump"] * 1e3,
                         "truth_inside": s["truth"]["mean_inside"],
                         "truth_jump": s["truth"]["max_jump"] * 1e3,
                         "vertices": e["vertices"]}
            row[mode].update(strain_of(e))
            rep = json.load(open(report))
            if "coverage" in rep:
                true_err = {f["frame"]: f["mean"] for f in e["frames"]}
                pred = [(f["predicted_error"], true_err[f["frame"]], f["coverage"]["flagged"],
                         f.get("error_bound", f["predicted_error"]))
                        for f in rep["frames"] if "predicted_error" in f]
                row[mode]["coverage"] = rep["coverage"]
                row[mode]["spearman"] = spearman([p[0] for p in pred], [p[1] for p in pred])
                covered = [p[1] for p in pred if not p[2]]
                row[mode]["covered_true_mean"] = (sum(covered) / len(covered) * 1e3
                                                  if covered else None)
                if mode == "defaults":
                    pooled_pred += [p[0] for p in pred]
                    pooled_true += [p[1] for p in pred]
                    row["pred"] = pred
            print(f"  {name} {mode}: {row[mode]['mean']:.2f} mm", file=sys.stderr)
        rows.append(row)
    if a.baselines:
        earlier = {r["clip"]: r for r in json.load(open(a.baselines))}
        for row in rows:
            for mode in MODES:
                if mode not in row and mode in earlier.get(row["clip"], {}):
                    row[mode] = earlier[row["clip"]][mode]
        modes = [m for m in MODES if all(m in r for r in rows)]
    json.dump(rows, open(os.path.join(a.out, "table.json"), "w"), indent=1)
    print_table(rows, modes, a)
    print_strain_table(rows, modes)
    print_summary(rows)


def strain_of(e):
    """The strain figures of an eval JSON over its frames, in %: {"strain": bake's,
    "truth_strain": the simulation's}; empty when eval measured no strain."""
    if not e.get("strain"):
        return {}
    s = e["summary"]
    return {"strain": {key: 100.0 * s["bake"][key] for key, _ in STRAIN_COLUMNS},
            "truth_strain": {key: 100.0 * s["truth"][key] for key, _ in STRAIN_COLUMNS}}


def print_strain_table(rows, modes):
    """One row per clip and mode with a strain (tables of runs before issue 43 have none): the
    bake's three figures, each with the simulation's in brackets."""
    cells = [(r["clip"], m, r[m]) for r in rows for m in modes if "strain" in r.get(m, {})]
    if not cells:
        return
    print()
    print("| clip | mode | " + " | ".join(head for _, head in STRAIN_COLUMNS) + " |")
    print("|" + "---|" * (2 + len(STRAIN_COLUMNS)))
    for clip, mode, figures in cells:
        print(f"| {clip} | {mode} | " + " | ".join(
            f"{figures['strain'][key]:.2f} ({figures['truth_strain'][key]:.2f})"
            for key, _ in STRAIN_COLUMNS) + " |")


def print_summary(rows):
    """The coverage figures under the table: pooled and per-clip Spearman, the verdict."""
    pooled_pred = [p[0] for r in rows if "pred" in r for p in r["pred"]]
    pooled_true = [p[1] for r in rows if "pred" in r for p in r["pred"]]
    if not pooled_pred:
        return
    print()
    print(f"Predicted error vs true per-frame mean error over {len(pooled_pred)} frames "
          f"of {len(rows)} clips: Spearman {spearman(pooled_pred, pooled_true):.3f}")
    for scene in ("pants", "sleeve"):
        sel = [r for r in rows if r["scene"] == scene and "pred" in r]
        cov = [p[1] for r in sel for p in r["pred"] if not p[2]]  # the default tolerance
        allf = [p for r in sel for p in r["pred"]]
        if not allf:
            continue
        t = sel[0]["defaults"]["coverage"]["tolerance"] * 1e3
        print(f"{scene}: tolerance {t:.1f} mm; {len(cov)} of {len(allf)} frames covered, "
              f"their true mean error "
              f"{(sum(cov) / len(cov) * 1e3) if cov else float('nan'):.2f} mm; all frames "
              f"{sum(p[1] for p in allf) / len(allf) * 1e3:.2f} mm")
    print()
    print("Within each clip (Spearman of predicted vs true per-frame error): " + ", ".join(
        f"{r['clip'].split()[0]} {spearman([p[0] for p in r['pred']], [p[1] for p in r['pred']]):+.2f}"
        for r in rows if "pred" in r))
    print()
    print("The verdict per frame: at each tolerance (the bake's --coverage-tolerance, a share of "
          "the rest cloth's bounding-box diagonal) the frames whose error bound is within it are "
          "called enough; the bar is that at least 90% of those have a true error within it:")
    print()
    print("| character | tolerance | frames called enough | of those truly within | their true "
          "mean error | holds (>= 90%) |")
    print("|---|---|---|---|---|---|")
    for scene in ("pants", "sleeve"):
        sel = [r for r in rows if r["scene"] == scene and "pred" in r]
        allf = [p for r in sel for p in r["pred"]]
        if not allf:
            continue
        diagonal = sel[0]["defaults"]["coverage"]["tolerance"] / 0.02
        for fraction in (0.01, 0.015, 0.02, 0.03):
            tolerance = fraction * diagonal
            enough = [p[1] for p in allf if bound(p) <= tolerance]
            within = sum(1 for e in enough if e <= tolerance)
            share = within / len(enough) if enough else float("nan")
            mean = sum(enough) / len(enough) * 1e3 if enough else float("nan")
            print(f"| {scene} | {fraction:.1%} = {tolerance * 1e3:.1f} mm | "
                  f"{len(enough)} of {len(allf)} ({len(enough) / len(allf):.0%}) | "
                  f"{within} ({share:.0%}) | {mean:.2f} mm | "
                  f"{'yes' if not enough or share >= 0.9 else 'no'} |")


def bound(p):
    """The frame's error bound (the report's error_bound; the predicted error before 0.2.0)."""
    return p[3] if len(p) > 3 else p[0]


def print_table(rows, modes, a):
    head = ["clip", "frames"] + [f"{m} (mm)" for m in modes]
    has_defaults = "defaults" in modes and "talk" in modes and "bind" in modes
    has_spread = any(r.get("spread") is not None for r in rows)
    if has_defaults:
        head += ["defaults / better baseline"]
        if has_spread:
            head += ["spread (mm)", "defaults / spread"]
        head += ["inside / frame (truth)", "largest jump mm (truth)", "covered", "verdict"]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for r in rows:
        cells = [r["clip"], r["frames"]] + [f"{r[m]['mean']:.2f}" for m in modes]
        if has_defaults:
            d = r["defaults"]
            better = min(r["talk"]["mean"], r["bind"]["mean"])
            ratio = d["mean"] / better
            limit_inside = d["truth_inside"] + 0.005 * d["vertices"]
            ok = []
            if ratio > a.error_bar:
                ok.append("error")
            spread_cells = []
            if has_spread:
                sp = r.get("spread")
                spread_cells = [f"{sp:.2f}" if sp else "-", f"{d['mean'] / sp:.2f}" if sp else "-"]
                if sp and a.spread_bar > 0 and d["mean"] > a.spread_bar * sp:
                    ok.append("spread")
            if d["inside"] > limit_inside:
                ok.append("inside")
            if d["jump"] > 1.5 * d["truth_jump"]:
                ok.append("jump")
            cov = d.get("coverage")
            cells += [f"{ratio:.2f}"] + spread_cells + [
                      f"{d['inside']:.1f} ({d['truth_inside']:.1f})",
                      f"{d['jump']:.1f} ({d['truth_jump']:.1f})",
                      f"{cov['covered_fraction']:.0%}" if cov else "-",
                      "pass" if not ok else "misses: " + ", ".join(ok)]
        print("| " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
