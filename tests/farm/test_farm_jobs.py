# SPDX-License-Identifier: Apache-2.0
"""`drivenshape farm slurm` without a cluster: what the sbatch script holds (array of chunk
indices, a log per task, absolute paths, this executable, --skip-existing, TERM trapped, PoCL
cache), the usage errors (Slurm's MaxArraySize, options the farm command owns), and the script
run by bash as Slurm would run one task: SIGTERM to the shell reaches the bake, the task exits
with the bake's code 7 and leaves no temporary file, and running the task again resumes it."""

import os
import re
import signal
import subprocess
import sys

from farm_test_util import (FRAMES, check, compare_with_reference, exr_files, main, temp_files,
                            wait_for_outputs)


def script_content(farm):
    folder = farm.scratch("jobs")
    # Relative paths on the command line: the script must hold absolute ones.
    relative_driver = os.path.relpath(farm.driver, folder)
    farm.run("farm", "slurm", "--db", "../db.dsdb", "--driver", relative_driver,
             "--frames", "1-48", "-o", "out/c.####.exr", "--chunk-size", "17",
             "--partition", "shots", "--time", "01:30:00", "--cpus", "2", "--mem", "2000",
             "--job-name", "sleeve", "-O", "job.sbatch", cwd=folder)
    text = (folder / "job.sbatch").read_text()
    for line in ["#SBATCH --array=0-2\n", "#SBATCH --job-name=sleeve\n",
                 f"#SBATCH --output={folder}/out/logs/sleeve_%A_%a.log\n",
                 "#SBATCH --partition=shots\n", "#SBATCH --time=01:30:00\n",
                 "#SBATCH --cpus-per-task=2\n", "#SBATCH --mem=2000\n", "trap 'forward TERM' TERM",
                 f"'{farm.cli}' 'bake' '--db' '{farm.work / 'db.dsdb'}' '--driver' "
                 f"'{farm.driver}' '--frames' '1-48' '-o' '{folder}/out/c.####.exr' "
                 "'--chunk-size' '17' '--chunk-index' 'env' '--skip-existing'",
                 "POCL_CACHE_DIR", 'wait "$bake"', 'exit "$status"']:
        check(line in text, f"the script lacks {line!r}:\n{text}")
    check((folder / "out" / "logs").is_dir(), "the log folder was not created")
    check(os.access(folder / "job.sbatch", os.X_OK), "the script is not executable")
    syntax = subprocess.run(["bash", "-n", str(folder / "job.sbatch")], capture_output=True,
                            text=True)
    check(syntax.returncode == 0, f"bash -n rejects the script: {syntax.stderr}")


def usage_errors(farm):
    folder = farm.scratch("jobs-usage")
    common = ["--db", farm.db, "--driver", farm.driver, "-o", folder / "c.####.exr"]
    # 2000 chunks: more than Slurm's default MaxArraySize (1001) -> usage error naming the fix.
    result = farm.run("farm", "slurm", *common, "--frames", "1-2000", "--chunk-size", "1",
                      "--no-check", "-O", folder / "big.sbatch", expect=2)
    check("MaxArraySize" in result.stderr and "--chunk-size to at least 2" in result.stderr,
          f"the message should name MaxArraySize and the chunk size that fits:\n{result.stderr}")
    check(not (folder / "big.sbatch").exists(), "a script was written despite the error")
    farm.run("farm", "slurm", *common, "--frames", "1-2000", "--chunk-size", "1", "--no-check",
             "--max-array-size", "5000", "-O", folder / "big.sbatch")
    check("#SBATCH --array=0-1999\n" in (folder / "big.sbatch").read_text(),
          "--max-array-size 5000 should allow 2000 tasks (0-1999)")
    # 1001 chunks is the most the default allows.
    farm.run("farm", "slurm", *common, "--frames", "1-1001", "--chunk-size", "1", "--no-check",
             "-O", folder / "max.sbatch")
    for extra in ["--chunk-index 3", "--skip-existing", "--frames=1-3"]:
        result = farm.run("farm", "slurm", *common, "--frames", "1-48", "--chunk-size", "16",
                          "--extra-args", extra, "-O", folder / "x.sbatch", expect=2)
        check("farm command sets it" in result.stderr, f"--extra-args {extra!r}: {result.stderr}")
    farm.run("farm", "slurm", *common, "--frames", "1-48", "--chunk-size", "16", "--time",
             "soon", "-O", folder / "x.sbatch", expect=2)
    farm.run("farm", "slurm", "--db", folder / "none.dsdb", "--driver", farm.driver, "-o",
             folder / "c.####.exr", "--frames", "1-48", "--chunk-size", "16", "-O",
             folder / "x.sbatch", expect=3)
    farm.run("farm", "slurm", *common, "--frames", "1-60", "--chunk-size", "16", "-O",
             folder / "x.sbatch", expect=3)  # the driver has frames 1-48 only
    farm.run("farm", "pbs", expect=2)
    check(not (folder / "x.sbatch").exists(), "a script was written despite the errors")


def output_pattern_checked_like_the_bake(farm):
    """-o with a '#' in a folder: 2 frame tokens, which every task's bake refuses (exit 2). Both
    farm commands refuse it first with the bake's own words, naming -o and the value."""
    folder = farm.scratch("jobs-pattern")
    common = ["--db", farm.db, "--driver", farm.driver, "--frames", "1-48", "--chunk-size", "16"]
    bad = folder / "a#b" / "c.####.exr"
    bake = farm.run(*farm.bake_args(folder / "a#b", frames="1"), expect=2)
    check("2 frame tokens" in bake.stderr, f"the bake's message: {bake.stderr}")
    for scheduler, job in [("slurm", folder / "x.sbatch"), ("openjd", folder / "x.json")]:
        result = farm.run("farm", scheduler, *common, "-o", bad, "-O", job, expect=2)
        for text in [f"-o '{bad}'", "2 frame tokens", "usage error"]:
            check(text in result.stderr, f"farm {scheduler}: the message lacks {text!r}:\n"
                                         f"{result.stderr}")
        check(not job.exists(), f"farm {scheduler} wrote {job} despite exit 2")
    # A relative -o is made absolute first: a '#' in the current folder counts too.
    cwd = folder / "shot#1"
    cwd.mkdir()
    result = farm.run("farm", "slurm", *common, "-o", "out/c.####.exr", "-O", folder / "x.sbatch",
                      cwd=cwd, expect=2)
    check("-o 'out/c.####.exr'" in result.stderr and "2 frame tokens" in result.stderr,
          result.stderr)
    check(not (folder / "x.sbatch").exists() and not (cwd / "out").exists(),
          "farm slurm made files despite exit 2")


def sbatch_values_quoted_or_refused(farm):
    """One rule for every value of an #SBATCH line: plain values as they are, others
    double-quoted with '"' and '\\' escaped (real sbatch reads such a script back exactly in
    test_farm_slurm), control characters refused naming the option (a line break would end the
    line). The log folder is also a Slurm file name pattern: '%' doubled, a backslash refused
    (Slurm then stops replacing %A/%a). A refused value makes no file or folder."""
    folder = farm.scratch("jobs-values")
    common = ["--db", farm.db, "--driver", farm.driver, "--frames", "1-48", "--chunk-size", "16",
              "-o", folder / "out" / "c.####.exr"]
    logs = folder / "lo gs%#1"
    job = folder / "job.sbatch"
    farm.run("farm", "slurm", *common, "--partition", "my part", "--job-name",
             'sh 10 #"x\\ it\'s', "--log-dir", logs, "--time", "10", "-O", job)
    text = job.read_text()
    for line in ['#SBATCH --job-name="sh 10 #\\"x\\\\ it\'s"\n',
                 f'#SBATCH --output="{folder}/lo gs%%#1/sh_10___x__it_s_%A_%a.log"\n',
                 '#SBATCH --partition="my part"\n', "#SBATCH --time=10\n"]:
        check(line in text, f"the script lacks {line!r}:\n{text}")
    check(logs.is_dir(), f"the log folder {logs} was not made")
    syntax = subprocess.run(["bash", "-n", str(job)], capture_output=True, text=True)
    check(syntax.returncode == 0, f"bash -n rejects the script: {syntax.stderr}")

    refused = [
        (["--partition", "a\nb"], "--partition 'a\\x0ab'"),
        (["--partition", "a\tb"], "--partition 'a\\x09b'"),
        (["--job-name", "a\rb"], "--job-name 'a\\x0db'"),
        (["--log-dir", folder / "a\nb"], f"--log-dir '{folder}/a\\x0ab'"),
        (["--log-dir", folder / "a\\b"], f"--log-dir '{folder}/a\\b'"),
    ]
    for words, expected in refused:
        job = folder / "refused.sbatch"
        result = farm.run("farm", "slurm", *common, *words, "-O", job, expect=2)
        check(expected in result.stderr and "usage error" in result.stderr,
              f"farm slurm {words}: the message lacks {expected!r}:\n{result.stderr}")
        check(not job.exists(), f"farm slurm {words} wrote a script despite exit 2")
    check(sorted(p.name for p in folder.iterdir()) == ["job.sbatch", "lo gs%#1", "out"],
          f"a refused value made folders: {sorted(p.name for p in folder.iterdir())}")


def sigterm_reaches_the_bake_through_the_script(farm):
    folder = farm.scratch("jobs-term")
    out = folder / "out"
    job = folder / "job.sbatch"
    farm.run("farm", "slurm", "--db", farm.db, "--driver", farm.driver, "--frames", "1-48",
             "-o", out / "c.####.exr", "--chunk-size", "48", "--extra-args", "--batch 1",
             "-O", job)
    env = dict(farm.env, SLURM_ARRAY_TASK_ID="0", SLURM_ARRAY_JOB_ID="42")
    log = folder / "task.log"
    with open(log, "w") as stream:
        shell = subprocess.Popen(["bash", str(job)], stdout=stream, stderr=subprocess.STDOUT,
                                 env=env)
        try:
            check(wait_for_outputs(out, 3, shell), f"the task ended early:\n{log.read_text()}")
            shell.send_signal(signal.SIGTERM)  # to the shell only, as `scancel --batch` does
            code = shell.wait(timeout=60)
        finally:
            if shell.poll() is None:
                shell.kill()
                shell.wait()
    text = log.read_text()
    check(code == 7, f"the task should exit with the bake's code 7 after SIGTERM, got {code}:\n"
                     f"{text[-2000:]}")
    check("interrupted" in text and "exited with 7" in text, f"log:\n{text[-2000:]}")
    check(not temp_files(out), f"temporary files left: {temp_files(out)}")
    finished = len(exr_files(out))
    check(finished < len(FRAMES), "the task finished before SIGTERM reached it")
    # The same task again (a requeue) keeps the finished frames and completes the chunk.
    result = subprocess.run(["bash", str(job)], capture_output=True, text=True, env=env,
                            timeout=300)
    check(result.returncode == 0, f"the rerun failed ({result.returncode}):\n"
                                  f"{result.stderr[-2000:]}")
    check(re.search(rf"baked {len(FRAMES) - finished} frames \({finished} kept\)", result.stdout),
          f"the rerun should keep {finished} frames:\n{result.stdout}")
    compare_with_reference(farm, out)
    check((out / "c.chunk0.report.json").is_file(), "no per-chunk report c.chunk0.report.json")


if __name__ == "__main__":
    sys.exit(main([script_content, usage_errors, output_pattern_checked_like_the_bake,
                   sbatch_values_quoted_or_refused, sigterm_reaches_the_bake_through_the_script]))
