# SPDX-License-Identifier: Apache-2.0
"""Failures a farm meets, each with a clear message, its documented exit code, and nothing
half-written (no temporary file, every EXR under a final name complete):

* a read-only output folder -> 4 (output). A read-only tmpfs is mounted when this process may
  mount (root in CI); otherwise the folder is chmod 0555 and, when running as root (which
  ignores permissions), the bake runs as user nobody (uid 65534).
* a full disk -> 4 (output). A 100 KiB tmpfs (room for about 4 frames) when mounting is
  allowed; otherwise (or with DS_FARM_TEST_NO_MOUNT=1) RLIMIT_FSIZE (`ulimit -f`) of half a
  frame on the bake, SIGXFSZ ignored, so that the first frame's write fails with EFBIG as on a
  full disk (on the host reference path: the limit would also stop PoCL's compiler).
* a missing input frame mid-range of a driver EXR sequence -> 3 (input), before any output is
  written; the farm command refuses to write a job for it (3).
* a corrupt (truncated) input frame mid-range -> 3 (input): the frames before it are complete,
  nothing else is left, and a rerun with --skip-existing once the frame is fixed completes the
  shot.

The driver EXR sequence is made with the CLI: a database whose driven mesh is the driver mesh
itself, baked without correction, gives point-cache EXRs with the driver's topology."""

import os
import resource
import signal
import subprocess
import sys

from farm_test_util import (FRAMES, check, compare_with_reference, exr_files, main,
                            temp_files)


def try_mount(target, options):
    if os.environ.get("DS_FARM_TEST_NO_MOUNT"):  # exercise the fallbacks
        return False
    result = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(target)],
                            capture_output=True, text=True)
    if result.returncode != 0:
        print(f"mount -o {options} failed ({result.stderr.strip()}); using the fallback",
              flush=True)
    return result.returncode == 0


def unmount(target):
    subprocess.run(["umount", str(target)], check=False)


def read_only_output_folder(farm):
    out = farm.scratch("readonly")
    mounted = try_mount(out, "ro,size=1m")
    try:
        if mounted:
            result = farm.run(*farm.bake_args(out), expect=4)
        else:
            out.chmod(0o555)

            def as_nobody():
                if os.geteuid() == 0:
                    os.setgroups([])
                    os.setgid(65534)
                    os.setuid(65534)

            command = [str(farm.cli)] + [str(w) for w in farm.bake_args(out)]
            result = subprocess.run(command, capture_output=True, text=True, env=farm.env,
                                    preexec_fn=as_nobody, timeout=300)
            check(result.returncode == 4, f"read-only folder (chmod 0555"
                                          f"{', as nobody' if os.geteuid() == 0 else ''}): "
                                          f"expected exit 4, got {result.returncode}:\n"
                                          f"{result.stderr[-2000:]}")
        check("not writable" in result.stderr and str(out) in result.stderr,
              f"the message should name the folder and say it is not writable:\n{result.stderr}")
        check(not any(out.iterdir()), f"files appeared in the read-only folder: "
                                      f"{list(out.iterdir())}")
    finally:
        if mounted:
            unmount(out)
        else:
            out.chmod(0o755)


def full_disk(farm):
    out = farm.scratch("fulldisk")
    mounted = try_mount(out, "size=100k")
    limit = None
    try:
        if mounted:
            result = farm.run(*farm.bake_args(out), "--batch", "2", expect=4)
        else:
            # RLIMIT_FSIZE bounds each file, not the disk: half a frame makes the first frame's
            # write fail. It also bounds PoCL's compiler output, so the simulation bakes on the
            # host reference path.
            limit = farm.ref_frame(1).stat().st_size // 2

            def limit_file_size():
                signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
                resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

            command = ([str(farm.cli)] + [str(w) for w in farm.bake_args(out)] +
                       ["--batch", "2", "--device", "host"])
            result = subprocess.run(command, capture_output=True, text=True, env=farm.env,
                                    preexec_fn=limit_file_size, timeout=300)
            check(result.returncode == 4, f"RLIMIT_FSIZE={limit}: expected exit 4, got "
                                          f"{result.returncode}:\n{result.stderr[-2000:]}")
        message = result.stderr
        check("No space left on device" in message or "File too large" in message,
              f"the message should give the system's reason (disk full):\n{message[-2000:]}")
        check(not temp_files(out), f"temporary files left in {out}: {temp_files(out)}")
        if mounted:
            finished = compare_with_reference(farm, out, allow_missing=True)
        else:
            # Files under final names are whole: identical to the same frames baked on the host.
            done = exr_files(out)
            host = farm.scratch("fulldisk-host")
            if done:
                farm.run(*farm.bake_args(host, frames="1-8"), "--device", "host", "--quiet")
            different = [n for n in done if (out / n).read_bytes() != (host / n).read_bytes()]
            check(not different, f"incomplete or wrong files under final names: {different}")
            finished = len(done)
        check(finished < len(FRAMES), "the whole shot fit on the 'full' disk")
        print(f"full disk ({'tmpfs 100k' if mounted else f'RLIMIT_FSIZE {limit}'}): "
              f"{finished} complete frames kept, exit 4", flush=True)
    finally:
        if mounted:
            unmount(out)


def driver_sequence(farm):
    """driver.####.exr: a point-cache EXR sequence of the driver mesh, frames 1-48."""
    folder = farm.scratch("driver-exr")
    self_db = folder / "self.dsdb"
    farm.run("db", "build", "--driver-mesh", farm.data / "driver_rest.obj",
             "--driven-mesh", farm.data / "driver_rest.obj",
             "--driver", farm.data / "train.driver.pc2", "--driven", farm.data / "train.driver.pc2",
             "--count", "10", "--quiet", "-o", self_db)
    farm.run("bake", "--db", self_db, "--driver", farm.driver, "--frames", "1-48",
             "-o", folder / "driver.####.exr", "--no-correct", "--no-audit", "--quiet",
             "--report", folder / "driver.report.json")
    return folder


def missing_and_corrupt_input_frames(farm):
    drivers = driver_sequence(farm)
    pattern = drivers / "driver.####.exr"
    # The sequence is a valid driver: a short bake from it works.
    good = farm.scratch("exr-driver-ok")
    farm.run(*farm.bake_args(good, frames="1-4", driver=pattern), "--quiet")

    missing = drivers / "driver.0024.exr"
    kept = drivers / "kept.0024"
    missing.rename(kept)
    out = farm.scratch("missing-frame")
    result = farm.run(*farm.bake_args(out, driver=pattern), expect=3)
    check("no frame 24" in result.stderr, f"the message should name frame 24:\n{result.stderr}")
    check(not any(out.iterdir()), f"outputs written despite the missing frame: "
                                  f"{sorted(p.name for p in out.iterdir())}")
    farm_job = farm.scratch("missing-frame-job")
    result = farm.run("farm", "slurm", "--db", farm.db, "--driver", pattern, "--frames", "1-48",
                      "-o", farm_job / "c.####.exr", "--chunk-size", "16",
                      "-O", farm_job / "job.sbatch", expect=3)
    check("lacks frames 24" in result.stderr, f"farm slurm should name frame 24:\n"
                                              f"{result.stderr}")
    check(not (farm_job / "job.sbatch").exists(), "a job was written for a broken driver cache")
    kept.rename(missing)

    corrupt = drivers / "driver.0030.exr"
    whole = corrupt.read_bytes()
    corrupt.write_bytes(whole[: len(whole) // 4])
    out = farm.scratch("corrupt-frame")
    result = farm.run(*farm.bake_args(out, driver=pattern), "--batch", "4", expect=3)
    check("driver.0030.exr" in result.stderr, f"the message should name the corrupt file:\n"
                                              f"{result.stderr}")
    check(not temp_files(out), f"temporary files left: {temp_files(out)}")
    done = exr_files(out)
    check(0 < len(done) < len(FRAMES) and "c.0030.exr" not in done,
          f"expected the frames before 30 to be complete, got {done}")
    # Fixed input: the rerun keeps the finished frames and completes the shot, identical to an
    # uninterrupted bake from the same (fixed) driver sequence.
    corrupt.write_bytes(whole)
    result = farm.run(*farm.bake_args(out, driver=pattern), "--skip-existing")
    check(f"({len(done)} kept)" in result.stdout, f"the rerun should keep the {len(done)} "
                                                  f"finished frames: {result.stdout}")
    clean = farm.scratch("exr-driver-clean")
    farm.run(*farm.bake_args(clean, driver=pattern), "--quiet")
    different = [name for name in exr_files(clean)
                 if (clean / name).read_bytes() != (out / name).read_bytes()]
    check(len(exr_files(out)) == len(FRAMES) and not different,
          f"resumed outputs differ from a clean bake: {different}")


if __name__ == "__main__":
    sys.exit(main([read_only_output_folder, full_disk, missing_and_corrupt_input_frames]))
