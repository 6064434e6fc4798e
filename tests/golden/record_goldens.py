#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Records the golden bakes of the sleeve sample (tests/golden/golden_bakes.py) with a given
`drivenshape` binary into one JSON file, which check_goldens.py (CTest golden_sample) compares
later bakes with, exactly.

  .venv/bin/python tests/golden/record_goldens.py --cli /tmp/ds-f302ac6/drivenshape \
      --commit f302ac6 --out tests/data/golden/f302ac6.json

Builds the 30-shape database from tests/data/sleeve (as scripts/demo.sh) and bakes the test
clip (frames 1-48) in every configuration of golden_bakes.CONFIGS on the host reference path
and on the OpenCL CPU device (PoCL, kernel cache in a temporary folder), one bake at a time.
"""

import argparse
import datetime
import os
import platform
import shlex
import shutil
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import golden_bakes  # noqa: E402


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cli", required=True, help="the drivenshape binary to record")
    parser.add_argument("--out", required=True, help="golden JSON to write")
    parser.add_argument("--commit", required=True, help="the commit the binary was built from")
    parser.add_argument("--work", help="scratch folder (default: a temporary one, removed)")
    args = parser.parse_args()

    cli = os.path.abspath(args.cli)
    work = args.work or tempfile.mkdtemp(prefix="ds-golden-record-")
    env_pocl = os.environ.pop("POCL_CACHE_DIR", None)  # a fresh kernel cache in `work`
    float_text = golden_bakes.FloatText()
    start = time.monotonic()
    try:
        baked = golden_bakes.bake_all(cli, work, float_text=float_text)
    finally:
        if env_pocl is not None:
            os.environ["POCL_CACHE_DIR"] = env_pocl
        if not args.work:
            shutil.rmtree(work, ignore_errors=True)
    seconds = time.monotonic() - start

    def output(cmd):
        return subprocess.run(cmd, capture_output=True, text=True).stdout.strip()

    import numpy
    import OpenEXR
    document = {
        "format": golden_bakes.FORMAT,
        "format_version": golden_bakes.FORMAT_VERSION,
        "commit": args.commit,
        "how": ("Recorded by tests/golden/record_goldens.py with the drivenshape binary built "
                f"from commit {args.commit}; checked by tests/golden/check_goldens.py (CTest "
                "golden_sample). Pixels: sha256 of the decoded EXR pixels (OpenEXR Python "
                "bindings, golden_pixels.py), compared exactly. Bytes and header: sha256 of the "
                "file and of its header without dsSettingsHash, reported only. Frames: the bake "
                "report's per-frame records without 'output' and the report's summary (no "
                "timing), floats stored with the report's own digits (compared as doubles: "
                f"{float_text.count} floats, {float_text.not_shortest} of them not in "
                "shortest form)."),
        "command": " ".join(shlex.quote(a) for a in [
            ".venv/bin/python", "tests/golden/record_goldens.py", "--cli", cli, "--commit",
            args.commit, "--out", args.out]),
        "recorded": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "seconds": round(seconds, 1),
        "binary": {"path": cli, "sha256": golden_bakes.sha256_file(cli),
                   "version": output([cli, "version"])},
        "machine": {"platform": platform.platform(), "processor": platform.processor(),
                    "cpus": os.cpu_count(), "opencl_devices": output([cli, "devices"])},
        "python": {"python": platform.python_version(), "numpy": numpy.__version__,
                   "OpenEXR": OpenEXR.__version__},
        "inputs": golden_bakes.input_hashes(),
        "database": {"command": " ".join(golden_bakes.DB_FLAGS), "report": baked["database"][
            "report"]},
        "bake": {"driver": golden_bakes.BAKE_DRIVER, "frames": golden_bakes.BAKE_FRAMES,
                 "output": golden_bakes.OUTPUT_NAME, "devices": golden_bakes.DEVICES},
        "configs": {name: {"flags": flags, "covers": what}
                    for name, flags, what in golden_bakes.CONFIGS},
        "bakes": baked["bakes"],
    }
    golden_bakes.dump(document, args.out)
    print(f"recorded {len(baked['bakes'])} bakes x {len(golden_bakes.FRAMES)} frames in "
          f"{seconds:.1f} s -> {args.out} ({os.path.getsize(args.out)} bytes)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
