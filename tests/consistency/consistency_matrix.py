# SPDX-License-Identifier: Apache-2.0
"""The consistency matrix (issue 27, point 5): every tool that evaluates a shot against
`drivenshape bake`, bitwise, frame by frame, on the bundled sleeve sample.

Columns (database x device): the database `drivenshape db build` makes with its defaults (the
pose model), baked with the default weights (`--weights auto`: the pose model) and with
`--weights qp` (the 2008 QP blend), each on the host reference path (`--device host`) and on the
OpenCL device (`--device auto`, PoCL in CI, or DS_TEST_DEVICE; a missing one is a failure).

Rows (the tools), each against the CLI bake of the same cell (the reference), frames 1-48:
  Python evaluate_cache   the module in this interpreter, the test PC2 through open_point_cache
  USD bake                `python -m drivenshape.usd bake` of a driver stage written by
                          `python -m drivenshape.usd export --mesh driver_rest.obj --pc2 ...`
  Blender bake            the add-on's Bake operator (scene range 1-48, PC2) in `blender -b`
  Blender live            live mode through LIVE_SEQUENCE: forward 1-48, jumps, backwards 48-1
  farm chunks + resume    `bake --chunk-size 16 --chunk-index I` for chunks 2, 0, 1, chunk 1's
                          last 8 frames deleted (a task killed half-way) and chunk 1 re-run with
                          --skip-existing (it must keep 8 and bake 8)

A cell is ✓ when every frame's float32 bit patterns equal the CLI's; otherwise it shows the first
differing frame and the largest coordinate difference over the frames compared. Any mismatch, or
a tool that fails, fails the test (exit 1). Blender and the OpenCL device are required.

    consistency_matrix.py --cli build/apps/drivenshape --data tests/data/sleeve --work DIR \
        --blender /usr/bin/blender [--cmake cmake] [--opencl-device SPEC]

Run with the module on PYTHONPATH (build/python) and usd-core installed (scripts/setup.sh).
"""

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from pxr import Usd, UsdGeom

import drivenshape as ds

HERE = Path(__file__).resolve().parent
SOURCE = HERE.parent.parent
FRAMES = list(range(1, 49))  # the sample's test clip, tests/data/sleeve/test.driver.pc2
JUMPS = [30, 10, 47, 17, 25, 3, 40]
LIVE_SEQUENCE = FRAMES + JUMPS + FRAMES[::-1]
CHUNK_SIZE = 16
RESUMED_CHUNK = 1
NAME = "sleeve.####.exr"

ROWS = ["Python evaluate_cache", "USD bake", "Blender bake", "Blender live",
        "farm chunks + resume"]
ROW_FRAMES = {
    "Python evaluate_cache": "frames 1-48",
    "USD bake": "frames 1-48",
    "Blender bake": "frames 1-48",
    "Blender live": f"{len(LIVE_SEQUENCE)} steps: 1-48, then {', '.join(map(str, JUMPS))}, "
                    "then 48-1",
    "farm chunks + resume": f"frames 1-48 in chunks of {CHUNK_SIZE}, chunk {RESUMED_CHUNK} "
                            "resumed",
}


class Cell:
    """One (database, weights, device) column."""

    def __init__(self, weights, device, label):
        self.weights, self.device = weights, device
        self.name = f"{'default' if weights == 'auto' else weights}_{label}"
        self.label = f"{'default' if weights == 'auto' else '--weights qp'} / {label}"
        self.reference = None  # (F, V, 3) float32: the CLI bake of FRAMES
        self.report = None


class Result:
    """A cell of the matrix: the tool's frames against the CLI's."""

    def __init__(self, text, ok):
        self.text, self.ok = text, ok


def compare(got, want, frames):
    """✓ when bitwise equal; else the first differing frame and the largest difference."""
    got = np.asarray(got)
    if got.dtype != np.float32 or got.shape != want.shape:
        return Result(f"✗ {got.dtype} {got.shape} != float32 {want.shape}", False)
    same = (got.view(np.uint32) == want.view(np.uint32)).reshape(len(frames), -1).all(axis=1)
    if same.all():
        return Result("✓", True)
    first = frames[int(np.argmin(same))]
    largest = float(np.nanmax(np.abs(got.astype(np.float64) - want)))
    return Result(f"✗ f{first} {largest:.2g}", False)


def failed(what):
    return Result(f"✗ {what}", False)


class Matrix:
    def __init__(self, args):
        self.cli = Path(args.cli).resolve()
        self.data = Path(args.data).resolve()
        self.work = Path(args.work).resolve()
        self.blender = args.blender
        self.cmake = args.cmake
        self.pc2 = self.data / "test.driver.pc2"
        self.db = self.work / "sleeve_pose.dsdb"
        self.cells = [Cell(weights, device, label)
                      for weights in ("auto", "qp")
                      for device, label in (("host", "host"), (args.opencl_device, "OpenCL"))]
        self.results = {row: {} for row in ROWS}
        self.problems = []  # checks outside the matrix (the columns mean what they say)
        self.env = dict(os.environ)
        self.env.setdefault("POCL_CACHE_DIR", str(self.work / "pocl-cache"))

    def run(self, *words):
        """Runs a command that must succeed; returns the CompletedProcess."""
        command = [str(w) for w in words]
        started = time.monotonic()
        result = subprocess.run(command, capture_output=True, text=True, env=self.env)
        print(f"$ {' '.join(command)}  -> exit {result.returncode} in "
              f"{time.monotonic() - started:.1f} s", flush=True)
        if result.returncode != 0:
            raise RuntimeError(f"exit {result.returncode} from {' '.join(command)}\n"
                               f"{result.stdout}{result.stderr[-3000:]}")
        return result

    def check(self, condition, message):
        print(f"{'ok' if condition else 'FAILED'}: {message}", flush=True)
        if not condition:
            self.problems.append(message)

    def bake_args(self, cell, out):
        weights = [] if cell.weights == "auto" else ["--weights", cell.weights]
        return ["bake", "--db", self.db, "--driver", self.pc2, "--frames", "1-48",
                "--device", cell.device, *weights, "--quiet", "-o", Path(out) / NAME]

    @staticmethod
    def read_exrs(folder, frames=FRAMES):
        return np.stack([ds.read_point_cache_exr(Path(folder) / f"sleeve.{f:04d}.exr")[0]
                         for f in frames])

    # ---- The references ----------------------------------------------------------------------

    def references(self):
        self.run(self.cli, "db", "build", "--driver-mesh", self.data / "driver_rest.obj",
                 "--driven-mesh", self.data / "driven_rest.obj",
                 "--driver", self.data / "train.driver.pc2",
                 "--driven", self.data / "train.driven.pc2", "--quiet", "-o", self.db)
        opencl = ds.open_device(self.cells[1].device)
        self.check(opencl.is_opencl, f"'--device {self.cells[1].device}' opens an OpenCL device "
                   f"({opencl.description}; {opencl.note or 'no note'}); install "
                   "pocl-opencl-icd (scripts/setup.sh)")
        for cell in self.cells:
            folder = self.work / "cli" / cell.name
            self.run(self.cli, *self.bake_args(cell, folder))
            cell.reference = self.read_exrs(folder)
            cell.report = json.loads((folder / "sleeve.report.json").read_text())
            used = cell.report["settings"]["weights"]
            expected = "model" if cell.weights == "auto" else "qp"
            self.check(used == expected, f"{cell.label}: the CLI bake ran weights {used} "
                       f"(expected {expected})")
            on_host = cell.device == "host"
            self.check(("reference path" in cell.report["device"]) == on_host,
                       f"{cell.label}: the CLI bake ran on {cell.report['device']}")
        for device in (0, 1):
            pose, qp = self.cells[device], self.cells[device + 2]
            self.check(not np.array_equal(pose.reference, qp.reference),
                       f"{pose.label} and {qp.label} differ: the QP path is another cloth")
        for weights in (0, 2):  # information: a tool on the wrong device shows where they differ
            host, opencl = self.cells[weights], self.cells[weights + 1]
            print(f"{opencl.label} against {host.label}: "
                  f"{compare(opencl.reference, host.reference, FRAMES).text}", flush=True)

    # ---- The rows ----------------------------------------------------------------------------

    def python_row(self):
        database = ds.load_database(self.db)
        cache = ds.open_point_cache(self.pc2)
        for cell in self.cells:
            device = ds.open_device(cell.device)
            evaluator = ds.Evaluator(database, ds.EvaluatorSettings(weight_mode=cell.weights),
                                     device)
            if evaluator.device_name != cell.report["device"]:
                self.results["Python evaluate_cache"][cell.name] = failed(
                    f"ran on {evaluator.device_name}")
                continue
            cloth, _records = ds.evaluate_cache(evaluator, cache, FRAMES)
            self.results["Python evaluate_cache"][cell.name] = compare(cloth, cell.reference,
                                                                       FRAMES)

    def usd_row(self):
        folder = self.work / "usd"
        folder.mkdir()
        driver = folder / "driver.usda"
        self.run(sys.executable, "-m", "drivenshape.usd", "export", "--mesh",
                 self.data / "driver_rest.obj", "--pc2", self.pc2, "-o", driver)
        for cell in self.cells:
            out = folder / f"{cell.name}.usdc"
            weights = [] if cell.weights == "auto" else ["--weights", cell.weights]
            said = self.run(sys.executable, "-m", "drivenshape.usd", "bake", "--db", self.db,
                            "--usd", driver, "--prim", "/Garment/Mesh", "--device", cell.device,
                            *weights, "--out", out).stdout
            if cell.report["device"] not in said:
                self.results["USD bake"][cell.name] = failed(
                    f"not on the CLI's device: {said.strip()[:60]}")
                continue
            stage = Usd.Stage.Open(str(out))  # held: its prims die with it
            mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/Garment/Mesh"))
            points = mesh.GetPointsAttr()
            times = [round(t) for t in points.GetTimeSamples()]
            if times != FRAMES:
                self.results["USD bake"][cell.name] = failed(f"time samples {times[:3]}...")
                continue
            cloth = np.stack([np.asarray(points.Get(f), dtype=np.float32) for f in FRAMES])
            self.results["USD bake"][cell.name] = compare(cloth, cell.reference, FRAMES)

    def farm_row(self):
        for cell in self.cells:
            out = self.work / "farm" / cell.name
            for index in (2, 0, 1):  # out of order, as farm tasks finish
                self.run(self.cli, *self.bake_args(cell, out), "--chunk-size", CHUNK_SIZE,
                         "--chunk-index", index)
            resumed = FRAMES[RESUMED_CHUNK * CHUNK_SIZE:(RESUMED_CHUNK + 1) * CHUNK_SIZE]
            lost = resumed[CHUNK_SIZE // 2:]
            for frame in lost:
                (out / f"sleeve.{frame:04d}.exr").unlink()
            rerun = self.run(self.cli, *self.bake_args(cell, out), "--chunk-size", CHUNK_SIZE,
                             "--chunk-index", RESUMED_CHUNK, "--skip-existing").stdout
            counts = re.search(r"baked (\d+) frames \((\d+) kept\)", rerun)
            expected = (len(lost), len(resumed) - len(lost))
            if not counts or tuple(map(int, counts.groups())) != expected:
                self.results["farm chunks + resume"][cell.name] = failed(
                    f"resume: '{counts.group(0) if counts else rerun.strip()}'")
                continue
            self.results["farm chunks + resume"][cell.name] = compare(self.read_exrs(out),
                                                                      cell.reference, FRAMES)

    def blender_rows(self):
        folder = self.work / "blender"
        folder.mkdir()
        self.run(sys.executable, SOURCE / "scripts" / "blender_package.py", "-o",
                 folder / "drivenshape_blender.zip")
        plan = {"database": str(self.db), "live_sequence": LIVE_SEQUENCE,
                "cells": [{"name": c.name, "device": c.device, "weights": c.weights}
                          for c in self.cells]}
        (folder / "plan.json").write_text(json.dumps(plan, indent=1))
        env = dict(self.env, BLENDER_USER_SCRIPTS=str(folder / "scripts"),
                   BLENDER_USER_CONFIG=str(folder / "config"),
                   # The add-on finds the module this interpreter imported.
                   DRIVENSHAPE_PYTHONPATH=str(Path(ds.__file__).resolve().parent.parent))
        command = [self.cmake, f"-DBLENDER={self.blender}",
                   f"-DSCRIPT={HERE / 'consistency_blender.py'}",
                   f"-DARGS=--data|{self.data}|--work|{folder}",
                   "-P", str(SOURCE / "tests" / "blender" / "run_blender.cmake")]
        started = time.monotonic()
        blender = subprocess.run(command, capture_output=True, text=True, env=env)
        print(f"$ {' '.join(command)}  -> exit {blender.returncode} in "
              f"{time.monotonic() - started:.1f} s", flush=True)
        if blender.returncode != 0:
            print(blender.stdout[-4000:] + blender.stderr[-4000:], flush=True)
            self.check(False, f"Blender exited {blender.returncode} (its output above)")
        for cell in self.cells:
            self.blender_cell(folder, cell)

    def blender_cell(self, folder, cell):
        summary = folder / f"{cell.name}.json"
        if not summary.exists():
            for row in ("Blender bake", "Blender live"):
                self.results[row][cell.name] = failed("no output")
            return
        ran = json.loads(summary.read_text())
        want_device = cell.report["device"]
        if "live_error" in ran:
            print(f"{cell.label}: live mode failed:\n{ran['live_error']}", flush=True)
            self.results["Blender live"][cell.name] = failed("error (above)")
        elif ran["live"]["device"] != want_device:
            self.results["Blender live"][cell.name] = failed(f"ran on {ran['live']['device']}")
        elif ran["live"]["evaluations"] < len(LIVE_SEQUENCE):
            self.results["Blender live"][cell.name] = failed(
                f"{ran['live']['evaluations']} evaluations for {len(LIVE_SEQUENCE)} steps")
        else:
            steps = np.load(folder / f"{cell.name}.live.npy")
            want = cell.reference[[f - FRAMES[0] for f in LIVE_SEQUENCE]]
            self.results["Blender live"][cell.name] = compare(steps, want, LIVE_SEQUENCE)
        if "bake_error" in ran:
            print(f"{cell.label}: the add-on's bake failed:\n{ran['bake_error']}", flush=True)
            self.results["Blender bake"][cell.name] = failed("error (above)")
        elif ran["bake"]["device"] != want_device:
            self.results["Blender bake"][cell.name] = failed(f"ran on {ran['bake']['device']}")
        else:
            positions, start, _rate = ds.read_pc2(folder / f"{cell.name}.bake.pc2")
            if start != FRAMES[0]:
                self.results["Blender bake"][cell.name] = failed(f"PC2 starts at {start}")
            else:
                self.results["Blender bake"][cell.name] = compare(positions, cell.reference,
                                                                  FRAMES)

    # ---- The report --------------------------------------------------------------------------

    def print_matrix(self):
        text = {(row, c.name): self.results[row].get(c.name, failed("not run")).text
                for row in ROWS for c in self.cells}
        width = max(len(row) for row in ROWS) + 2
        columns = [max([len(c.label)] + [len(text[row, c.name]) for row in ROWS]) + 2
                   for c in self.cells]
        lines = ["", "consistency matrix: each tool against `drivenshape bake` of the same cell, "
                 "bitwise (✓), or the first differing frame and the largest difference",
                 " " * width + "".join(c.label.ljust(w) for c, w in zip(self.cells, columns))]
        for row in ROWS:
            cells = [text[row, c.name] for c in self.cells]
            lines.append(row.ljust(width) + "".join(t.ljust(w) for t, w in zip(cells, columns)))
        lines.append("frames compared:")
        lines += [f"  {row}: {ROW_FRAMES[row]}" for row in ROWS]
        lines.append(f"database: {self.db.name} (db build defaults: the pose model); OpenCL: "
                     f"{self.cells[1].report['device'] if self.cells[1].report else '?'}")
        print("\n".join(line.rstrip() for line in lines), flush=True)


def main():
    for stream in (sys.stdout, sys.stderr):
        stream.reconfigure(encoding="utf-8")
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cli", required=True, help="the drivenshape executable")
    parser.add_argument("--data", required=True, help="tests/data/sleeve")
    parser.add_argument("--work", required=True, help="a folder to empty and work in")
    parser.add_argument("--blender", required=True, help="Blender 3.4 or later")
    parser.add_argument("--cmake", default=shutil.which("cmake") or "cmake",
                        help="cmake, to run tests/blender/run_blender.cmake")
    parser.add_argument("--opencl-device", default=os.environ.get("DS_TEST_DEVICE", "auto"),
                        help="the OpenCL device's --device spec [default: DS_TEST_DEVICE, "
                        "else auto]")
    args = parser.parse_args()
    started = time.monotonic()
    work = Path(args.work)
    if work.exists():
        shutil.rmtree(work)
    work.mkdir(parents=True)
    matrix = Matrix(args)
    Path(matrix.env["POCL_CACHE_DIR"]).mkdir(parents=True, exist_ok=True)
    try:
        matrix.references()
        for row in (matrix.python_row, matrix.usd_row, matrix.farm_row, matrix.blender_rows):
            try:
                row()
            except Exception as error:  # the row's cells stay "not run"; the others still run
                matrix.check(False, f"{row.__name__}: {error}")
    except Exception as error:
        matrix.check(False, f"the references: {error}")
    matrix.print_matrix()
    mismatches = [f"{row} / {c.label}: {matrix.results[row].get(c.name, failed('not run')).text}"
                  for row in ROWS for c in matrix.cells
                  if not matrix.results[row].get(c.name, failed("not run")).ok]
    seconds = time.monotonic() - started
    if mismatches or matrix.problems:
        print(f"consistency_matrix FAILED in {seconds:.1f} s:", flush=True)
        for line in matrix.problems + mismatches:
            print(f"  {line}", flush=True)
        return 1
    print(f"consistency_matrix: every cell bitwise equal to the CLI bake in {seconds:.1f} s",
          flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
