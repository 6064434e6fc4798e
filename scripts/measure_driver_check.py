#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""The figures behind bake's driver sanity check (docs/method.md, "The driver's sanity check").

For each public scene (--data DIR/{pants,sleeve}, default out/data: the public clips made by
scripts/validation/generate_clips.sh --link-data out/data out/clips) it builds a 30-shape
database from `train`, then measures every frame of `train` and `test_public` (scale: median
edge-length ratio against the rest driver; spread: RMS log ratio around it) and bakes both clips
to read the report's direct relative residual; then the same for drivers made wrong on purpose
(x 1.1, in centimetres, vertices shuffled). Not a test (it reads generated clips); prints one table.

  PYTHONPATH=build/python .venv/bin/python scripts/measure_driver_check.py [--data DIR]
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(REPO, "build", "python"))
import drivenshape as ds  # noqa: E402

CLI = os.path.join(REPO, "build", "apps", "drivenshape")


def edges(mesh):
    start, vertices = (np.asarray(a) for a in mesh.faces)
    pairs = set()
    for f in range(len(start) - 1):
        face = vertices[start[f]:start[f + 1]]
        for i in range(len(face)):
            a, b = int(face[i]), int(face[(i + 1) % len(face)])
            if a != b:
                pairs.add((min(a, b), max(a, b)))
    return np.array(sorted(pairs))


def measure(rest, frame, pairs):
    before = np.linalg.norm(rest[pairs[:, 0]] - rest[pairs[:, 1]], axis=1)
    after = np.linalg.norm(frame[pairs[:, 0]] - frame[pairs[:, 1]], axis=1)
    ratio = after[before > 0] / before[before > 0]
    scale = np.median(ratio)
    return scale, float(np.sqrt(np.mean(np.log(np.maximum(ratio, 1e-3 * scale) / scale) ** 2)))


def residuals(db, driver, work, name):
    out = os.path.join(work, name)
    os.makedirs(out, exist_ok=True)
    report = os.path.join(work, name + ".json")
    subprocess.run([CLI, "bake", "--db", db, "--driver", driver, "--frames", "1-140", "--quiet",
                    "--no-audit", "--no-resolve", "--force", "--report", report, "-o",
                    os.path.join(out, "c.####.exr")], check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)
    values = sorted(f["relative_residual_direct"] for f in json.load(open(report))["frames"])
    return values[len(values) // 2], values[-1]


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--data", default=os.path.join(REPO, "out", "data"))
    args = parser.parse_args()
    print("| driver | scale | edge spread | direct relative residual (median / max) |")
    print("|---|---|---|---|")
    with tempfile.TemporaryDirectory() as work:
        for scene in ("pants", "sleeve"):
            root = os.path.join(args.data, scene)
            mesh = ds.read_obj(os.path.join(root, "driver_rest.obj"))
            rest, pairs = np.asarray(mesh.positions), edges(mesh)
            db = os.path.join(work, scene + ".dsdb")
            subprocess.run([CLI, "db", "build", "--driver-mesh", os.path.join(root, "driver_rest.obj"),
                            "--driven-mesh", os.path.join(root, "driven_rest.obj"), "--driver",
                            os.path.join(root, "train.driver.pc2"), "--driven",
                            os.path.join(root, "train.driven.pc2"), "--count", "30", "--quiet",
                            "-o", db], check=True, stdout=subprocess.DEVNULL)
            test, start, rate = ds.read_pc2(os.path.join(root, "test_public.driver.pc2"))
            variants = {"train": os.path.join(root, "train.driver.pc2"),
                        "test_public": os.path.join(root, "test_public.driver.pc2")}
            rng = np.random.default_rng(1)
            for label, frames in (("x 1.1", test * 1.1), ("in centimetres", test * 100),
                                  ("vertices shuffled", test[:, rng.permutation(test.shape[1])])):
                path = os.path.join(work, f"{scene}-{label.replace(' ', '_')}.pc2")
                ds.write_pc2(path, np.ascontiguousarray(frames, dtype=np.float32),
                             start_frame=start, sample_rate=rate)
                variants["test_public " + label] = path
            for label, path in variants.items():
                clip, _, _ = ds.read_pc2(path)
                figures = np.array([measure(rest, frame, pairs) for frame in clip])
                median, worst = residuals(db, path, work, f"{scene}-{len(label)}")
                print(f"| {scene} {label} | {figures[:, 0].min():.3f} - {figures[:, 0].max():.3f} "
                      f"| {figures[:, 1].min():.3f} - {figures[:, 1].max():.3f} "
                      f"| {median:.3f} / {worst:.3f} |")


if __name__ == "__main__":
    main()
