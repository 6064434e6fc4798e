# SPDX-License-Identifier: Apache-2.0
"""Chunking determinism: a bake in 3 uneven chunks (17 + 17 + 14 frames of 48) run out of order
(2, 0, 1), with other thread counts and launch batches than the reference, is bitwise identical
to one bake of all frames, and the farm's last task (the whole shot with --skip-existing) writes
that bake's report apart from `run` and `seconds`; a chunk's own report names the shot's
simulation runs, which may start before the chunk."""

import json
import sys

from farm_test_util import (FRAMES, check, compare_report_with_reference,
                            compare_with_reference, exr_files, main, temp_files)


def uneven_chunks_out_of_order(farm):
    out = farm.scratch("chunking")
    settings = {2: ["--threads", "1", "--batch", "5"],
                0: ["--threads", "2", "--batch", "3"],
                1: ["--batch", "64"]}
    expected = {0: range(1, 18), 1: range(18, 35), 2: range(35, 49)}
    for index in (2, 0, 1):
        result = farm.run(*farm.bake_args(out), "--chunk-size", "17", "--chunk-index", str(index),
                          *settings[index])
        first, last = expected[index][0], expected[index][-1]
        check(f"baked {len(expected[index])} frames" in result.stdout,
              f"chunk {index} should bake {len(expected[index])} frames ({first}-{last}); "
              f"stdout: {result.stdout}")
        check(f"({first}-{last})" in result.stderr or f"frames {first}-{last}" in result.stdout,
              f"chunk {index} should cover frames {first}-{last}; stdout: {result.stdout}")
    check(not temp_files(out), f"temporary files left: {temp_files(out)}")
    check(len(exr_files(out)) == len(FRAMES), f"{len(exr_files(out))} outputs, not {len(FRAMES)}")
    compare_with_reference(farm, out)
    chunk = json.loads((out / "c.chunk1.report.json").read_text())
    flagged = [r["frame"] for r in chunk["frames"] if r["coverage"]["flagged"]]
    runs = chunk["coverage"]["simulate_runs"]
    check(18 in flagged, f"the test needs frame 18 (chunk 1's first) flagged: {flagged}")
    check(runs[0]["from"] == 1, f"chunk 1's first simulation run should start 20 frames before "
                                f"frame 18, at the shot's first frame 1, not at the chunk's "
                                f"edge: {runs}")
    result = farm.run(*farm.bake_args(out), "--skip-existing")
    check("baked 0 frames (48 kept)" in result.stdout,
          f"the report task should keep every frame: {result.stdout}")
    compare_report_with_reference(farm, out / "c.report.json")


def chunks_on_batch_boundaries(farm):
    """Chunks of 16 baked in batches of 8: each chunk's first frame starts a batch whose batch
    before another task baked. Its record (its largest jump is from the frame before) is the
    one-shot bake's, so the shot's report is too."""
    out = farm.scratch("chunking-aligned")
    for index in (2, 1, 0):
        farm.run(*farm.bake_args(out), "--chunk-size", "16", "--chunk-index", str(index),
                 "--batch", "8")
    compare_with_reference(farm, out)
    farm.run(*farm.bake_args(out), "--skip-existing")
    compare_report_with_reference(farm, out / "c.report.json")


def chunk_from_slurm_environment(farm):
    # --chunk-index env reads SLURM_ARRAY_TASK_ID: chunk 1 of 17 is frames 18-34.
    out = farm.scratch("chunking-env")
    env = dict(farm.env, SLURM_ARRAY_TASK_ID="1")
    farm.run(*farm.bake_args(out), "--chunk-size", "17", "--chunk-index", "env", env=env)
    check(exr_files(out) == [f"c.{f:04d}.exr" for f in range(18, 35)],
          f"SLURM_ARRAY_TASK_ID=1 baked {exr_files(out)}, not frames 18-34")
    compare_with_reference(farm, out, frames=range(18, 35))
    # An index past the last chunk is a usage error (2), never a frame number.
    farm.run(*farm.bake_args(out), "--chunk-size", "17", "--chunk-index", "3", expect=2)


if __name__ == "__main__":
    sys.exit(main([uneven_chunks_out_of_order, chunks_on_batch_boundaries,
                   chunk_from_slurm_environment]))
