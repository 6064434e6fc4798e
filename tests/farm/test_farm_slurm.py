# SPDX-License-Identifier: Apache-2.0
"""Real Slurm. scripts/slurm_local_cluster.sh installs slurm-wlm and munge when missing and
starts munged, slurmctld and slurmd on 127.0.0.1 with everything in a temporary folder (no
systemd, auth/munge with a key made there). Then:

* the array job written by `drivenshape farm slurm --submit` for the 48-frame shot in chunks of
  16 (3 tasks) completes, and its outputs equal a local bake bitwise, with a log per task; the
  report job it submits after the array (the script's `report` mode) writes the shot's report,
  the local bake's apart from `run` and `seconds`;
* a task given bad input (the driven cache as driver: another mesh) ends FAILED, ExitCode=3:0;
* a job name and a log folder that #SBATCH lines must quote (space, '#', quotes, backslash,
  '%') reach Slurm exactly: its JobName, and the task logs in that folder;
* a task cancelled mid-bake (scancel: SIGTERM) ends CANCELLED with the bake's ExitCode=7:0 and
  no temporary file, and the resubmitted chunk (sbatch --array=0) resumes and completes.

The cluster is torn down (daemons stopped by pid, folder removed) even when a check fails."""

import contextlib
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from farm_test_util import (FRAMES, CheckFailed, check, compare_report_with_reference,
                            compare_with_reference, exr_files, main, temp_files)


class Cluster:
    def __init__(self, farm):
        self.farm = farm
        self.script = farm.scripts / "slurm_local_cluster.sh"
        # Short: the munge socket path must fit in 107 bytes.
        self.dir = Path(tempfile.mkdtemp(prefix="dsslurm-", dir="/tmp"))
        self.env = dict(farm.env, SLURM_CONF=str(self.dir / "slurm.conf"))

    def start(self):
        started = time.monotonic()
        result = subprocess.run(["bash", str(self.script), "start", str(self.dir)],
                                capture_output=True, text=True, timeout=600)
        check(result.returncode == 0, f"the cluster did not start:\n{result.stdout}\n"
                                      f"{result.stderr[-4000:]}")
        print(result.stderr.strip(), f"({time.monotonic() - started:.1f} s)", flush=True)

    @contextlib.contextmanager
    def running(self):
        """The cluster started for the block and stopped (and removed) after it; when a check
        fails in the block, the last lines of its logs are printed first."""
        try:
            self.start()
            yield self
        except CheckFailed:
            print(self.logs(), flush=True)
            raise
        finally:
            self.stop()

    def stop(self):
        result = subprocess.run(["bash", str(self.script), "stop", "--remove", str(self.dir)],
                                capture_output=True, text=True, timeout=120)
        if result.returncode != 0:
            print(f"cluster teardown failed: {result.stderr}", flush=True)

    def tool(self, *words, timeout=60):
        result = subprocess.run([str(w) for w in words], capture_output=True, text=True,
                                env=self.env, timeout=timeout)
        check(result.returncode == 0, f"{' '.join(map(str, words))} failed: {result.stderr}")
        return result.stdout

    def submit(self, *farm_words):
        """(array job id, report job id) of `farm slurm ... --submit`."""
        result = self.farm.run("farm", "slurm", *farm_words, "--submit", env=self.env)
        ids = re.findall(r"submitted: job (\d+)", result.stdout)
        check(len(ids) == 2 and "the shot's report, after job" in result.stdout,
              f"expected the array job's id and the report job's: {result.stdout}")
        return ids[0], ids[1]

    def never_runs(self, job, timeout=60):
        """Waits until Slurm says `job` waits for a dependency that failed (or cancelled it for
        that); a job that runs instead is a failure. Then cancels it."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            text = self.tool("scontrol", "show", "job", job)
            state = re.search(r"JobState=(\S+)", text).group(1)
            reason = re.search(r"Reason=(\S+)", text).group(1)
            check(state in ("PENDING", "CANCELLED"), f"job {job} is {state}; it should never run")
            if state == "CANCELLED" or reason == "DependencyNeverSatisfied":
                self.tool("scancel", job)
                return
            time.sleep(0.5)
        raise CheckFailed(f"job {job} still pending without DependencyNeverSatisfied after "
                          f"{timeout} s")

    def wait(self, job, timeout=240):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if not self.tool("squeue", "-h", "-j", job, "-o", "%i").strip():
                return self.tasks(job)
            time.sleep(0.5)
        queue = self.tool("squeue")
        raise CheckFailed(f"job {job} still queued after {timeout} s:\n{queue}\n"
                          f"{self.logs()}")

    def tasks(self, job):
        """{array task id: (JobState, ExitCode)} from scontrol show job."""
        text = self.tool("scontrol", "show", "job", job)
        tasks = {}
        for record in text.split("\n\n"):
            task = re.search(r"ArrayTaskId=(\d+)", record)
            state = re.search(r"JobState=(\S+)", record)
            code = re.search(r"ExitCode=(\S+)", record)
            if task and state and code:
                tasks[int(task.group(1))] = (state.group(1), code.group(1))
        return tasks

    def logs(self):
        text = ""
        for log in sorted((self.dir / "log").glob("*.log")):
            text += f"---- {log.name}\n" + "\n".join(log.read_text().splitlines()[-15:]) + "\n"
        return text


def slurm_array_job(farm):
    with Cluster(farm).running() as cluster:
        sinfo = cluster.tool("sinfo", "-h", "-N", "-o", "%N %t %c")
        print(f"sinfo: {sinfo.strip()}", flush=True)

        # The shot: 3 array tasks, outputs equal to the local bake.
        shot = farm.scratch("slurm-shot")
        job, report = cluster.submit("--db", farm.db, "--driver", farm.driver, "--frames", "1-48",
                                     "-o", shot / "c.####.exr", "--chunk-size", "16",
                                     "-O", shot / "job.sbatch")
        tasks = cluster.wait(job)
        report_tasks = cluster.wait(report)
        logs = sorted(p.name for p in (shot / "logs").glob("*.log"))
        log_text = "".join((shot / "logs" / name).read_text() for name in logs)
        check(tasks == {i: ("COMPLETED", "0:0") for i in range(3)},
              f"job {job}: expected tasks 0-2 COMPLETED with ExitCode=0:0, got {tasks}\n"
              f"{log_text[-3000:]}")
        check(report_tasks == {0: ("COMPLETED", "0:0")},
              f"report job {report}: expected COMPLETED, got {report_tasks}\n{log_text[-3000:]}")
        check(logs == [f"ds_c_{job}_{i}.log" for i in range(3)] + [f"ds_c_{report}_0.log"],
              f"task logs: {logs}")
        check(not temp_files(shot), f"temporary files left: {temp_files(shot)}")
        compare_with_reference(farm, shot)
        compare_report_with_reference(farm, shot / "c.report.json")
        print(f"job {job}: 3 tasks COMPLETED, 48 frames identical to the local bake; report job "
              f"{report}: the shot's report is the local bake's", flush=True)

        # Bad input: the driven cache (2244 vertices) as the driver (2146) -> input error, 3.
        bad = farm.scratch("slurm-bad")
        job, report = cluster.submit("--db", farm.db, "--driver", farm.data / "train.driven.pc2",
                                     "--frames", "1-16", "-o", bad / "c.####.exr",
                                     "--chunk-size", "16", "-O", bad / "job.sbatch")
        tasks = cluster.wait(job)
        cluster.never_runs(report)  # it waits for chunks that succeed
        log_text = "".join(p.read_text() for p in (bad / "logs").glob("*.log"))
        check(tasks == {0: ("FAILED", "3:0")}, f"job {job}: expected FAILED with ExitCode=3:0, "
                                               f"got {tasks}\n{log_text[-2000:]}")
        check("input error" in log_text and "vertices" in log_text,
              f"the task log should say why:\n{log_text[-2000:]}")
        check(not exr_files(bad), f"outputs written from bad input: {exr_files(bad)}")
        print(f"job {job}: bad input -> FAILED, ExitCode=3:0", flush=True)

        # Values the #SBATCH lines quote: sbatch reads them back exactly (issue 28).
        odd = farm.scratch("slurm-values")
        name = 'sh 10 #"x\\ it\'s %j'
        job, report = cluster.submit("--db", farm.db, "--driver", farm.driver, "--frames", "1-2",
                                     "-o", odd / "c.####.exr", "--chunk-size", "1",
                                     "--job-name", name, "--log-dir", odd / "lo gs%#1",
                                     "-O", odd / "job.sbatch")
        tasks = cluster.wait(job)
        cluster.wait(report)
        check(tasks == {i: ("COMPLETED", "0:0") for i in range(2)},
              f"job {job}: expected tasks 0-1 COMPLETED, got {tasks}\n{cluster.logs()}")
        names = re.findall(r"JobName=(.*)", cluster.tool("scontrol", "show", "job", job))
        check(names == [name, name], f"Slurm's job names {names}, expected {name!r} twice")
        logs = sorted(p.name for p in (odd / "lo gs%#1").iterdir())
        check(logs == [f"sh_10___x__it_s__j_{job}_{i}.log" for i in range(2)] +
              [f"sh_10___x__it_s__j_{report}_0.log"],
              f"task logs in 'lo gs%#1': {logs}")
        compare_with_reference(farm, odd, frames=[1, 2])
        print(f"job {job}: job name {name!r} and log folder 'lo gs%#1' reached Slurm intact",
              flush=True)

        # Cancelled mid-bake, then the chunk resubmitted: it resumes.
        resume = farm.scratch("slurm-cancel")
        job, report = cluster.submit("--db", farm.db, "--driver", farm.driver, "--frames", "1-48",
                                     "-o", resume / "c.####.exr", "--chunk-size", "48",
                                     "--extra-args", "--batch 1", "-O", resume / "job.sbatch")
        deadline = time.monotonic() + 120
        while len(exr_files(resume)) < 3 and time.monotonic() < deadline:
            time.sleep(0.02)
        check(len(exr_files(resume)) >= 3, f"job {job} wrote no frames:\n{cluster.logs()}")
        cluster.tool("scancel", job)
        tasks = cluster.wait(job)
        finished = len(exr_files(resume))
        log_text = "".join(p.read_text() for p in (resume / "logs").glob("*.log"))
        check(tasks == {0: ("CANCELLED", "7:0")},
              f"job {job}: expected CANCELLED with the bake's ExitCode=7:0, got {tasks}\n"
              f"{log_text[-2000:]}")
        check(not temp_files(resume), f"temporary files left: {temp_files(resume)}")
        check(finished < len(FRAMES), "the task finished before scancel")
        cluster.never_runs(report)
        job = cluster.tool("sbatch", "--parsable", "--array=0", resume / "job.sbatch").strip()
        tasks = cluster.wait(job)
        check(tasks == {0: ("COMPLETED", "0:0")}, f"resubmitted job {job}: {tasks}")
        log_text = (resume / "logs" / f"ds_c_{job}_0.log").read_text()
        check(f"({finished} kept)" in log_text,
              f"the resubmitted task should keep the {finished} finished frames:\n{log_text}")
        compare_with_reference(farm, resume)
        print(f"scancel after {finished} frames -> CANCELLED 7:0; resubmitted chunk resumed",
              flush=True)
    check(not cluster.dir.exists(), f"{cluster.dir} was not removed")


if __name__ == "__main__":
    sys.exit(main([slurm_array_job]))
