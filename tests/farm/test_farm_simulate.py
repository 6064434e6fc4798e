# SPDX-License-Identifier: Apache-2.0
"""Farm jobs of `drivenshape simulate` (issue 44 part 4): a task per window of the plan
(`simulate ... --window N`) and a splice task after them (`simulate ... --splice-only`), with
the stand-in Blender (tests/cli/stand_in_blender.cpp, --blender of this script), which tests
the plumbing of the tasks only: the real Blender is tests/blender's test_simulate_command_blender.

The shot is the fixture's reference bake (48 frames) with a report written here that flags
frames 10-12 and 30-31; with --warmup 4 --merge-gap 2 --seam 2 --carry 3 the library's plan has
two windows (6-12 and 26-31). The reference is one local `drivenshape simulate` of it.

* job control: --splice-only before the windows exits 3 naming window 1 and the task that makes
  it, writing no frame; --window 3 (of 2) and --window with --splice-only exit 2; --window 2
  runs one Blender and writes no frame; again, it keeps the window (no Blender, the files
  untouched); --window 1 and then --splice-only (no Blender) write frames byte for byte the
  local run's, and a report that is the local run's apart from `seconds`;
* Slurm (scripts/slurm_local_cluster.sh): `farm slurm simulate --submit` runs array tasks 1-2
  and the splice job after them; the spliced frames are the local run's byte for byte. A window
  that fails (the stand-in told to) ends FAILED 3:0 and the splice job never runs; resubmitted,
  the array keeps the complete window (its log says so) and the splice completes;
* Open Job Description: `farm openjd simulate` passes `openjd check` and openjd-model, and
  `openjd run` of step Simulate (2 tasks) and then step Splice gives the local run's bytes."""

import json
import os
import sys
from pathlib import Path

from farm_test_util import FRAMES, check, check_template_with_openjd_model, main, temp_files
from test_farm_openjd import openjd
from test_farm_slurm import Cluster

FLAGGED = {10, 11, 12, 30, 31}
SETTINGS = ["--warmup", "4", "--merge-gap", "2", "--seam", "2", "--carry", "3"]


def shot(farm, folder):
    """The shot's inputs in `folder`: a scene file (the stand-in only checks that it exists) and
    the report; returns the simulate words up to -o, and an environment logging the stand-in's
    runs to folder/runs.log."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "shot.blend").write_text("a scene")
    frames = [{"frame": f, "predicted_error": 0.05 if f in FLAGGED else 0.01,
               "coverage": {"flagged": f in FLAGGED}} for f in FRAMES]
    (folder / "c.report.json").write_text(json.dumps({"coverage": {"tolerance": 0.02},
                                                      "frames": frames}))
    words = ["--blend", folder / "shot.blend", "--object", "pants", "--report",
             folder / "c.report.json", "--bake", farm.ref / "c.####.exr"]
    env = dict(farm.env, STAND_IN_LOG=str(folder / "runs.log"))
    env.pop("STAND_IN_FAIL_AT", None)
    return words, env


def runs(folder):
    log = Path(folder) / "runs.log"
    return log.read_text().splitlines() if log.exists() else []


def frames_of(folder):
    return sorted(p.name for p in Path(folder).glob("c.*.exr"))


def same_as_local(folder, local, what):
    """The spliced frames and the report in `folder` are the local run's (report: but
    `seconds`; its plan names the report file, which each test writes beside itself)."""
    got, want = frames_of(folder), frames_of(local)
    check(got == want and len(got) == len(FRAMES), f"{what}: {len(got)} frames, expected "
                                                   f"{len(want)}")
    differ = [n for n in got if (Path(folder) / n).read_bytes() != (Path(local) / n).read_bytes()]
    check(not differ, f"{what}: frames {differ[:5]} differ from the local run's (bytes)")
    reports = []
    for report_folder in (folder, local):
        report = json.loads((Path(report_folder) / "c.report.json").read_text())
        del report["seconds"], report["plan"]["report"]
        reports.append(report)
    check(reports[0] == reports[1], f"{what}: the report is not the local run's")
    check((Path(folder) / "c.simulate-windows").is_dir(), f"{what}: the windows were not kept")
    check(not temp_files(folder), f"{what}: temporary files {temp_files(folder)}")


_LOCAL = []


def local_run(farm):
    """The reference: one local run (made once per test run)."""
    folder = farm.work / "simulate-local"
    if not _LOCAL:
        folder = farm.scratch("simulate-local")
        words, env = shot(farm, folder)
        farm.run("simulate", *words, "-o", folder / "out" / "c.####.exr", "--blender",
                 farm.blender, *SETTINGS, env=env)
        check(len(runs(folder)) == 2, f"the local run simulates 2 windows: {runs(folder)}")
        _LOCAL.append(folder / "out")
    return _LOCAL[0]


def job_control(farm):
    local = local_run(farm)
    folder = farm.scratch("simulate-tasks")
    words, env = shot(farm, folder)
    out = folder / "out"
    common = ["simulate", *words, "-o", out / "c.####.exr", "--blender", farm.blender, *SETTINGS]

    result = farm.run(*common, "--splice-only", expect=3, env=env)
    check("--splice-only: window 1 of 2 (frames 6-12) is not complete" in result.stderr
          and "--window 1" in result.stderr, f"the splice names the missing window: "
                                             f"{result.stderr}")
    check(not frames_of(out) and not runs(folder), "the failed splice wrote frames or ran Blender")
    result = farm.run(*common, "--window", "3", expect=2, env=env)
    check("--window 3" in result.stderr and "2 windows (1-2)" in result.stderr, result.stderr)
    result = farm.run(*common, "--window", "1", "--splice-only", expect=2, env=env)
    check("exclude each other" in result.stderr, result.stderr)

    farm.run(*common, "--window", "2", env=env)
    window = out / "c.simulate-windows" / "window_30"
    check([" --first 26 --last 31 " in r for r in runs(folder)] == [True],
          f"--window 2 runs one Blender, for frames 26-31: {runs(folder)}")
    check(not frames_of(out), "a window task writes no output frame")
    before = {p.name: (p.stat().st_mtime_ns, p.read_bytes()) for p in window.iterdir()}
    result = farm.run(*common, "--window", "2", env=env)
    after = {p.name: (p.stat().st_mtime_ns, p.read_bytes()) for p in window.iterdir()}
    check(len(runs(folder)) == 1 and "window 2/2: frames 26-31 kept from a run before" in
          result.stderr and before == after,
          f"a complete window is kept, untouched ({len(runs(folder))} runs)")
    farm.run(*common, "--window", "1", env=env)
    farm.run(*common, "--splice-only", env=env)
    check(len(runs(folder)) == 2, f"the splice ran Blender: {runs(folder)}")
    same_as_local(out, local, "--window 1, --window 2, --splice-only")


def submit_simulate(farm, cluster, folder, **env_extra):
    """`farm slurm simulate --submit` of the shot in `folder`: (window job id, splice job id)."""
    words, env = shot(farm, folder)
    result = farm.run("farm", "slurm", "simulate", *words, "-o", folder / "out" / "c.####.exr",
                      "--blender", farm.blender, *SETTINGS, "-O", folder / "job.sbatch",
                      "--submit", env=dict(cluster.env, **env, **env_extra))
    ids = [line.split()[2] for line in result.stdout.splitlines()
           if line.startswith("submitted: job")]
    check(len(ids) == 2 and "(the splice, after job" in result.stdout, result.stdout)
    return ids


def slurm(farm):
    local = local_run(farm)
    with Cluster(farm).running() as cluster:
        folder = farm.scratch("simulate-slurm")
        out = folder / "out"
        ids = submit_simulate(farm, cluster, folder)
        tasks, splice = cluster.wait(ids[0]), cluster.wait(ids[1])
        check(tasks == {1: ("COMPLETED", "0:0"), 2: ("COMPLETED", "0:0")}
              and splice == {0: ("COMPLETED", "0:0")},
              f"windows {tasks}, splice {splice}\n{cluster.logs()}")
        logs = sorted(p.name for p in (out / "logs").glob("*.log"))
        check(logs == [f"ds_c_simulate_{ids[0]}_{i}.log" for i in (1, 2)] +
              [f"ds_c_simulate_{ids[1]}_0.log"], f"task logs: {logs}")
        same_as_local(out, local, "the Slurm job")
        print(f"jobs {ids}: 2 window tasks and the splice COMPLETED, the local run's bytes",
              flush=True)

        # A window that fails, then the array resubmitted: the complete window is kept.
        folder = farm.scratch("simulate-slurm-fail")
        out = folder / "out"
        ids = submit_simulate(farm, cluster, folder, STAND_IN_FAIL_AT="28")
        tasks = cluster.wait(ids[0])
        cluster.never_runs(ids[1])
        check(tasks == {1: ("COMPLETED", "0:0"), 2: ("FAILED", "3:0")},
              f"a failed window: {tasks}\n{cluster.logs()}")
        check(not frames_of(out), "frames written after a failed window")
        array = cluster.tool("sbatch", "--parsable", folder / "job.sbatch").strip()
        tasks = cluster.wait(array)
        kept = (out / "logs" / f"ds_c_simulate_{array}_1.log").read_text()
        check(tasks == {1: ("COMPLETED", "0:0"), 2: ("COMPLETED", "0:0")}
              and "window 1/2: frames 6-12 kept from a run before" in kept,
              f"the resubmitted array keeps window 1: {tasks}\n{kept[-1500:]}")
        splice = cluster.tool("sbatch", "--parsable", "--array=0", folder / "job.sbatch",
                              "splice").strip()
        check(cluster.wait(splice) == {0: ("COMPLETED", "0:0")}, cluster.logs())
        same_as_local(out, local, "the resubmitted Slurm job")
        print("a failed window: FAILED 3:0, no splice; resubmitted: kept window 1, spliced",
              flush=True)


def openjd_job(farm):
    local = local_run(farm)
    folder = farm.scratch("simulate-openjd")
    words, env = shot(farm, folder)
    out = folder / "out"
    job = folder / "simulate.template.json"
    params = folder / "simulate.template.params.json"
    farm.run("farm", "openjd", "simulate", *words, "-o", out / "c.####.exr", "--blender",
             farm.blender, *SETTINGS, "-O", job, env=env)
    template = json.loads(job.read_text())
    space = template["steps"][0]["parameterSpace"]["taskParameterDefinitions"]
    check(space == [{"name": "Window", "type": "INT", "range": "1-2"}]
          and template["steps"][1]["dependencies"] == [{"dependsOn": "Simulate"}],
          f"the steps: {template['steps']}")
    openjd("check", job)
    check_template_with_openjd_model(job, params)
    saved = dict(os.environ)
    os.environ.update(env)  # openjd run's tasks inherit the stand-in's log
    try:
        result = openjd("run", job, "--step", "Simulate", "--job-param", f"file://{params}")
        check(len(runs(folder)) == 2, f"step Simulate ran {len(runs(folder))} windows:\n"
                                      f"{result.stdout[-2000:]}")
        openjd("run", job, "--step", "Splice", "--job-param", f"file://{params}")
    finally:
        os.environ.clear()
        os.environ.update(saved)
    check(len(runs(folder)) == 2, "step Splice ran Blender")
    same_as_local(out, local, "openjd run")


if __name__ == "__main__":
    sys.exit(main([job_control, openjd_job, slurm]))
