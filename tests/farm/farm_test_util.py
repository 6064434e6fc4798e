# SPDX-License-Identifier: Apache-2.0
"""Shared helpers of the farm tests (tests/farm): paths, running the CLI, comparing outputs.

Every test script takes the same arguments (see CMakeLists.txt):
  --cli PATH      the drivenshape executable
  --data DIR      tests/data/sleeve
  --work DIR      the fixture folder written by farm_fixture.py (database, reference bake)
  --scripts DIR   the project's scripts/ folder
  --blender PATH  the stand-in Blender of tests/cli (test_farm_simulate only)

The reference is one uninterrupted bake of all 48 frames of test.driver.pc2 with default
settings (ref/c.####.exr). Outputs are compared byte for byte: a frame must be bitwise identical
whatever the chunking, order, thread count or interruptions.

A failed check raises CheckFailed with what was expected and what happened; main() prints it and
exits 1. A missing tool is a failure, never a skip.
"""

import argparse
import json
import os
import shutil
import subprocess
import time
from pathlib import Path

FRAMES = list(range(1, 49))
FRAME_RANGE = "1-48"
OUTPUT_NAME = "c.####.exr"


class CheckFailed(Exception):
    pass


def check(condition, message):
    if not condition:
        raise CheckFailed(message)


class Farm:
    """Paths and helpers for one test run."""

    def __init__(self, args):
        self.cli = Path(args.cli).resolve()
        self.data = Path(args.data).resolve()
        self.work = Path(args.work).resolve()
        self.scripts = Path(args.scripts).resolve()
        self.blender = Path(args.blender).resolve() if args.blender else None
        self.db = self.work / "db.dsdb"
        self.driver = self.data / "test.driver.pc2"
        self.ref = self.work / "ref"
        check(self.cli.is_file(), f"drivenshape executable {self.cli} does not exist; build it")
        self.env = dict(os.environ)
        self.env.setdefault("POCL_CACHE_DIR", str(self.work / "pocl-cache"))
        Path(self.env["POCL_CACHE_DIR"]).mkdir(parents=True, exist_ok=True)

    def scratch(self, name):
        """A fresh folder for one test under the work folder (kept after the run to inspect)."""
        folder = self.work / name
        if folder.exists():
            for path in folder.rglob("*"):  # read-only leftovers of an earlier run
                try:
                    path.chmod(0o755)
                except OSError:
                    pass
            shutil.rmtree(folder)
        folder.mkdir(parents=True)
        return folder

    def run(self, *words, expect=0, cwd=None, timeout=300, env=None):
        """Runs drivenshape WORDS...; checks the exit code; returns the CompletedProcess."""
        command = [str(self.cli)] + [str(w) for w in words]
        started = time.monotonic()
        result = subprocess.run(command, capture_output=True, text=True, cwd=cwd,
                                env=env or self.env, timeout=timeout)
        seconds = time.monotonic() - started
        print(f"$ {' '.join(command)}  -> exit {result.returncode} in {seconds:.1f} s", flush=True)
        if expect is not None and result.returncode != expect:
            raise CheckFailed(f"expected exit code {expect}, got {result.returncode} from\n"
                              f"  {' '.join(command)}\nstdout:\n{result.stdout}\n"
                              f"stderr (last 3000 chars):\n{result.stderr[-3000:]}")
        return result

    def bake_args(self, out_folder, frames=FRAME_RANGE, driver=None):
        return ["bake", "--db", self.db, "--driver", driver or self.driver, "--frames", frames,
                "-o", Path(out_folder) / OUTPUT_NAME]

    def ref_frame(self, frame):
        return self.ref / frame_name(frame)


def frame_name(frame):
    return f"c.{frame:04d}.exr"


def temp_files(folder):
    """Temporary files of atomic writes (`.NAME.tmp-` and 16 random hex digits) left in `folder`."""
    return sorted(p.name for p in Path(folder).iterdir() if ".tmp-" in p.name)


def exr_files(folder):
    return sorted(p.name for p in Path(folder).glob("c.*.exr"))


def compare_with_reference(farm, folder, frames=FRAMES, allow_missing=False):
    """Checks that every frame in `folder` is byte-identical to the reference bake."""
    different, missing = [], []
    for frame in frames:
        path = Path(folder) / frame_name(frame)
        if not path.exists():
            missing.append(frame)
        elif path.read_bytes() != farm.ref_frame(frame).read_bytes():
            different.append(frame)
    check(not different, f"{folder}: frames {different} differ from the reference bake "
                         f"{farm.ref} (byte comparison)")
    if not allow_missing:
        check(not missing, f"{folder}: frames {missing} are missing")
    return len(frames) - len(missing)


def shot_report(path):
    """The bake report at `path` as the shot's: without what the run that wrote it did (`run`,
    `seconds`; docs/formats.md) and with each output by its file name (the folders differ)."""
    report = json.loads(Path(path).read_text())
    check("run" in report and "seconds" in report, f"{path}: no 'run' or 'seconds'")
    del report["run"], report["seconds"]
    report["output"] = Path(report["output"]).name
    for record in report["frames"]:
        record["output"] = Path(record["output"]).name
    return report


def compare_report_with_reference(farm, report_path, settings_given=()):
    """Checks that the report at `report_path` is the reference bake's apart from `run` and
    `seconds` (shot_report): the same frame records, warnings and verdict, value for value.
    `settings_given`: settings the bake was given other values of than the reference's (which
    change no cloth), left out of the comparison."""
    got, want = shot_report(report_path), shot_report(farm.ref / "c.report.json")
    for key in settings_given:
        check(got["settings"].pop(key) != want["settings"].pop(key), f"{key} is the same")
    if got == want:
        return
    differ = [k for k in sorted(set(got) | set(want)) if got.get(k) != want.get(k)]
    frames = [w["frame"] for g, w in zip(got.get("frames", []), want["frames"]) if g != w]
    raise CheckFailed(f"{report_path}: differs from the reference bake's report in {differ}"
                      f"{f' (frames {frames[:10]})' if frames else ''}")


def check_template_with_openjd_model(template_path, params_path=None):
    """Validates a written job template with openjd-model from PyPI (what `openjd check` runs):
    decoded as a jobtemplate-2023-09 document and, with the job parameter values written beside
    it, instantiated as a job (what `openjd run` does first). CheckFailed says why not."""
    from openjd.model import (DocumentType, create_job, decode_job_template,
                              document_string_to_object, preprocess_job_parameters)
    template_path = Path(template_path)
    kind = DocumentType.YAML if template_path.suffix in (".yaml", ".yml") else DocumentType.JSON
    try:
        template = decode_job_template(template=document_string_to_object(
            document=template_path.read_text(encoding="utf-8"), document_type=kind))
        if params_path is not None:
            values = preprocess_job_parameters(
                job_template=template,
                job_parameter_values=json.loads(Path(params_path).read_text(encoding="utf-8")),
                job_template_dir=template_path.parent, current_working_dir=template_path.parent)
            create_job(job_template=template, job_parameter_values=values)
    except Exception as error:  # the model's DecodeValidationError, ValueError, ...
        raise CheckFailed(f"openjd-model rejects {template_path}: {type(error).__name__}: "
                          f"{error}\n{template_path.read_text(errors='replace')[:3000]}")
    return template


def wait_for_outputs(folder, count, process, timeout=120):
    """Waits until `folder` holds at least `count` finished EXRs (or the process ends)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if len(exr_files(folder)) >= count:
            return True
        if process.poll() is not None:
            return False
        time.sleep(0.01)
    raise CheckFailed(f"no {count} outputs in {folder} after {timeout} s")


def main(tests):
    """Runs the named test functions (each takes a Farm) and reports; exit 1 on any failure."""
    parser = argparse.ArgumentParser()
    parser.add_argument("--cli", required=True)
    parser.add_argument("--data", required=True)
    parser.add_argument("--work", required=True)
    parser.add_argument("--scripts", required=True)
    parser.add_argument("--blender", help="the stand-in Blender (test_farm_simulate)")
    args = parser.parse_args()
    failures = 0
    try:
        farm = Farm(args)
    except CheckFailed as error:
        print(f"FAILED to set up: {error}", flush=True)
        return 1
    for test in tests:
        started = time.monotonic()
        print(f"==== {test.__name__}", flush=True)
        try:
            test(farm)
            print(f"---- ok {test.__name__} ({time.monotonic() - started:.1f} s)", flush=True)
        except CheckFailed as error:
            failures += 1
            print(f"---- FAILED {test.__name__}: {error}", flush=True)
        except subprocess.TimeoutExpired as error:
            failures += 1
            print(f"---- FAILED {test.__name__}: timed out: {error}", flush=True)
    if failures:
        print(f"{failures} of {len(tests)} checks failed", flush=True)
        return 1
    print(f"all {len(tests)} checks passed", flush=True)
    return 0
