# SPDX-License-Identifier: Apache-2.0
"""Kill and resume. A bake of all 48 frames (--batch 1, so it stops promptly) is stopped with
SIGTERM (exit 7, finished frames kept, no temporary file left) and, separately, killed with
SIGKILL (no clean-up possible: a temporary file may remain); each time a rerun with
--skip-existing bakes only what is missing and every output is bitwise identical to an
uninterrupted bake. A truncated EXR and an EXR of another frame planted in the output folder are
detected and baked again.

Stale temporary files (`.c.NNNN.exr.tmp-` and random digits, left by SIGKILL) are never taken
for an output, and the rerun removes those of its own frames (docs/commands.md: only its own,
since another chunk's task may be writing beside it); a temporary file of a frame outside the
rerun's frames stays."""

import re
import signal
import subprocess
import sys
import time

from farm_test_util import (FRAMES, check, compare_report_with_reference,
                            compare_with_reference, exr_files, frame_name, main, shot_report,
                            temp_files, wait_for_outputs)


def kept_and_baked(stdout):
    match = re.search(r"baked (\d+) frames \((\d+) kept\)", stdout)
    check(match is not None, f"no 'baked N frames (K kept)' summary in stdout: {stdout}")
    return int(match.group(2)), int(match.group(1))


def interrupt(farm, out, signum, while_writing=False, after=3, extra=("--batch", "1")):
    """Starts a full bake, sends `signum` once `after` frames are on disk (and, `while_writing`,
    when a temporary file is being written if that is seen within 5 s); returns (code,
    stderr)."""
    log = out.parent / (out.name + ".stderr")
    with open(log, "w") as stderr:
        process = subprocess.Popen([str(farm.cli)] + [str(w) for w in farm.bake_args(out)] +
                                   list(extra), stdout=subprocess.DEVNULL, stderr=stderr,
                                   env=farm.env)
        try:
            running = wait_for_outputs(out, after, process)
            check(running, f"the bake ended (exit {process.poll()}) before it could be "
                           f"signalled; see {log}")
            deadline = time.monotonic() + 5
            while while_writing and not temp_files(out) and time.monotonic() < deadline:
                time.sleep(0.001)
            process.send_signal(signum)
            code = process.wait(timeout=60)
        finally:
            if process.poll() is None:
                process.kill()
                process.wait()
    return code, log.read_text()


def resume(farm, out, expect_kept):
    """Reruns the whole bake with --skip-existing; returns its result."""
    result = farm.run(*farm.bake_args(out), "--skip-existing")
    kept, baked = kept_and_baked(result.stdout)
    check(kept == expect_kept and kept + baked == len(FRAMES),
          f"the rerun kept {kept} and baked {baked} frames; expected to keep the {expect_kept} "
          f"finished ones and bake the other {len(FRAMES) - expect_kept}")
    compare_with_reference(farm, out)
    compare_report_with_reference(farm, out / "c.report.json")
    return result


def sigterm_then_resume(farm):
    out = farm.scratch("resume-term")
    code, stderr = interrupt(farm, out, signal.SIGTERM)
    check(code == 7, f"SIGTERM: expected exit code 7 (interrupted), got {code}; stderr:\n"
                     f"{stderr[-2000:]}")
    check("interrupted" in stderr and "--skip-existing" in stderr,
          f"SIGTERM: the message should say the bake was interrupted and how to resume:\n"
          f"{stderr[-1000:]}")
    check(not temp_files(out), f"SIGTERM left temporary files: {temp_files(out)}")
    finished = len(exr_files(out))
    check(3 <= finished < len(FRAMES), f"SIGTERM: {finished} frames finished; expected some, "
                                       f"not all (the bake should stop within a frame)")
    # Every frame on disk is complete and final: identical to the uninterrupted bake.
    compare_with_reference(farm, out, allow_missing=True)
    print(f"SIGTERM after {finished} frames: exit 7, no temporary file", flush=True)
    resume(farm, out, finished)


def sigkill_then_resume(farm):
    out = farm.scratch("resume-kill")
    code, _ = interrupt(farm, out, signal.SIGKILL, while_writing=True)
    check(code == -signal.SIGKILL, f"SIGKILL: expected death by signal 9, got {code}")
    finished = len(exr_files(out))
    compare_with_reference(farm, out, allow_missing=True)  # renamed files are always whole
    # Whatever temporary file the kill left, plus a planted one (half of a frame) that looks
    # like the leftover of a dead process: neither may be taken for an output.
    stale = out / f".{frame_name(40)}.tmp-00000000000f423f"
    data = farm.ref_frame(40).read_bytes()
    stale.write_bytes(data[: len(data) // 2])
    # A leftover of a frame this bake does not own (another chunk's, say) must stay.
    foreign = out / f".{frame_name(99)}.tmp-0123456789abcdef"
    foreign.write_bytes(b"another task's half-written frame")
    left = temp_files(out)
    print(f"SIGKILL after {finished} frames; temporary files present: {left}", flush=True)
    result = resume(farm, out, finished)
    check(temp_files(out) == [foreign.name],
          f"the rerun should remove its own frames' temporary files and keep the other's: "
          f"before {left}, after {temp_files(out)}")
    removed = len(left) - 1
    check(f"removed {removed} temporary files" in result.stderr,
          f"the rerun should say it removed {removed} temporary files:\n{result.stderr[-1000:]}")


def killed_at_several_points(farm):
    """The report is the shot's, not the last run's: a bake killed (SIGKILL) once 2, then 20,
    then 41 frames are on disk, each time resumed with --skip-existing and batches of 5 (so
    kills land inside batches), and a last resume (the reference's settings), writes the
    reference bake's report apart from `run` and `seconds`: every frame's record and the
    verdict over all 48 frames."""
    out = farm.scratch("resume-several")
    for after in (2, 20, 41):
        code, stderr = interrupt(farm, out, signal.SIGKILL, after=after,
                                 extra=("--batch", "5", "--skip-existing"))
        check(code == -signal.SIGKILL, f"SIGKILL after {after}: expected death by signal 9, "
                                       f"got {code}:\n{stderr[-1000:]}")
        print(f"killed with {len(exr_files(out))} frames on disk", flush=True)
    finished = len(exr_files(out))
    result = farm.run(*farm.bake_args(out), "--skip-existing")
    kept, baked = kept_and_baked(result.stdout)
    check(kept == finished and kept + baked == len(FRAMES),
          f"the last resume kept {kept} and baked {baked}; {finished} were on disk")
    compare_with_reference(farm, out)
    compare_report_with_reference(farm, out / "c.report.json")
    # A rerun that keeps every frame writes the same report again (its verdict included).
    farm.run(*farm.bake_args(out), "--skip-existing")
    compare_report_with_reference(farm, out / "c.report.json")


def settings_outside_the_hash(farm):
    """Settings that change a frame's record but not its cloth (so not the settings hash): a
    resume with the audit on bakes again the frames baked with it off (their records lack its
    figures); one with another coverage tolerance keeps every frame and flags them against the
    new tolerance: its report is a fresh bake's with that tolerance."""
    out = farm.scratch("resume-record-settings")
    farm.run(*farm.bake_args(out), "--no-audit")
    result = farm.run(*farm.bake_args(out), "--skip-existing")
    kept, baked = kept_and_baked(result.stdout)
    check(kept == 0 and "with the audit off" in result.stderr,
          f"frames baked without the audit should be baked again: kept {kept}\n"
          f"{result.stderr[-1000:]}")
    compare_report_with_reference(farm, out / "c.report.json")
    tolerance = ["--coverage-tolerance", "0.05"]
    result = farm.run(*farm.bake_args(out), "--skip-existing", *tolerance)
    check(kept_and_baked(result.stdout) == (len(FRAMES), 0), "every frame should be kept")
    fresh = farm.scratch("resume-record-settings-fresh")
    farm.run(*farm.bake_args(fresh), *tolerance)
    check(shot_report(out / "c.report.json")["coverage"] ==
          shot_report(fresh / "c.report.json")["coverage"],
          "the resumed verdict is not a fresh bake's with the new tolerance")
    check(shot_report(out / "c.report.json")["frames"] ==
          shot_report(fresh / "c.report.json")["frames"],
          "the resumed records are not a fresh bake's with the new tolerance")


def truncated_and_foreign_outputs_rebaked(farm):
    out = farm.scratch("resume-truncated")
    for frame in FRAMES:
        (out / frame_name(frame)).write_bytes(farm.ref_frame(frame).read_bytes())
    whole = farm.ref_frame(20).read_bytes()
    (out / frame_name(20)).write_bytes(whole[: len(whole) // 2])  # a valid file cut in half
    (out / frame_name(21)).write_bytes(farm.ref_frame(22).read_bytes())  # header says frame 22
    (out / frame_name(30)).write_bytes(b"")  # an empty file
    result = farm.run(*farm.bake_args(out), "--skip-existing")
    kept, baked = kept_and_baked(result.stdout)
    check(baked == 3 and kept == len(FRAMES) - 3,
          f"expected frames 20 (truncated), 21 (another frame's file) and 30 (empty) to be baked "
          f"again and 45 kept; got {baked} baked, {kept} kept:\n{result.stderr[-2000:]}")
    for frame in (20, 21, 30):
        check(f"frame {frame} baked" in result.stderr,
              f"frame {frame} should have been baked again; stderr:\n{result.stderr[-2000:]}")
    compare_with_reference(farm, out)


if __name__ == "__main__":
    sys.exit(main([sigterm_then_resume, sigkill_then_resume, killed_at_several_points,
                   settings_outside_the_hash, truncated_and_foreign_outputs_rebaked]))
