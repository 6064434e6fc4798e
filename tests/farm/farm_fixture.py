# SPDX-License-Identifier: Apache-2.0
"""CTest fixture of the farm tests: a small database of the sleeve sample and the reference
bake (one uninterrupted bake of all 48 test frames, default settings) that every farm test
compares its outputs with, byte for byte."""

import sys

from farm_test_util import FRAMES, check, exr_files, main


def build_fixture(farm):
    farm.work.mkdir(parents=True, exist_ok=True)
    farm.run("db", "build", "--driver-mesh", farm.data / "driver_rest.obj",
             "--driven-mesh", farm.data / "driven_rest.obj",
             "--driver", farm.data / "train.driver.pc2", "--driven", farm.data / "train.driven.pc2",
             "--count", "10", "--quiet", "-o", farm.db)
    ref = farm.scratch("ref")
    farm.run(*farm.bake_args(ref), "--quiet")
    check(len(exr_files(ref)) == len(FRAMES),
          f"the reference bake wrote {len(exr_files(ref))} frames, not {len(FRAMES)}")


if __name__ == "__main__":
    sys.exit(main([build_fixture]))
