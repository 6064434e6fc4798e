#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""One version everywhere: the one declared by project(drivenshape VERSION ...) in CMakeLists.txt
is the one that `drivenshape --version` prints, that the Python module's __version__ says, that
the Blender add-on's bl_info["version"] spells (a literal tuple, so only this test keeps it in
step), and that the files written by a fresh `db build` and `bake` carry (the database header's
tool_version, the point-cache EXR's dsToolVersion attribute read by the OpenEXR PyPI package,
the bake report's tool_version).

    check_version.py --configured VERSION --source DIR --cli drivenshape --work DIR [--module]

--module also imports drivenshape (PYTHONPATH: the build tree's python folder) and compares its
__version__. Exits 1 naming every place that disagrees.
"""

import argparse
import ast
import json
import pathlib
import re
import struct
import subprocess
import sys


def declared_version(source):
    """The VERSION of project(drivenshape VERSION x.y.z ...) in CMakeLists.txt."""
    text = (source / "CMakeLists.txt").read_text(encoding="utf-8")
    match = re.search(r"^project\(drivenshape VERSION ([0-9]+\.[0-9]+\.[0-9]+)\b", text, re.M)
    if not match:
        raise SystemExit("check_version: no project(drivenshape VERSION x.y.z) in CMakeLists.txt")
    return match.group(1)


def addon_version(source):
    """bl_info["version"] of the Blender add-on as "x.y.z", read without importing it (bpy)."""
    path = source / "apps" / "blender" / "drivenshape_blender" / "__init__.py"
    for node in ast.parse(path.read_text(encoding="utf-8")).body:
        if isinstance(node, ast.Assign) and any(
                getattr(target, "id", None) == "bl_info" for target in node.targets):
            return ".".join(str(part) for part in ast.literal_eval(node.value)["version"])
    raise SystemExit(f"check_version: no bl_info in {path}")


def run(command):
    result = subprocess.run([str(part) for part in command], capture_output=True, text=True)
    if result.returncode != 0:
        raise SystemExit(f"check_version: {' '.join(map(str, command))} exited "
                         f"{result.returncode}:\n{result.stdout}{result.stderr}")
    return result.stdout


def database_tool_version(path):
    """tool_version of a .dsdb's JSON header (docs/formats.md: magic, version, reserved, H)."""
    raw = pathlib.Path(path).read_bytes()
    if raw[:8] != b"DSHAPEDB":
        raise SystemExit(f"check_version: {path} is no drivenshape database")
    (length,) = struct.unpack_from("<Q", raw, 16)
    return json.loads(raw[24:24 + length].decode("utf-8"))["tool_version"]


def exr_tool_version(path):
    """The dsToolVersion attribute of a point-cache EXR, read by the OpenEXR PyPI package."""
    import OpenEXR  # the project's venv (scripts/requirements.txt)

    value = OpenEXR.File(str(path), header_only=True).header().get("dsToolVersion")
    return value.decode() if isinstance(value, bytes) else value


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--configured", required=True, help="PROJECT_VERSION of the build")
    parser.add_argument("--source", required=True, type=pathlib.Path, help="the source tree")
    parser.add_argument("--cli", required=True, help="the built `drivenshape`")
    parser.add_argument("--work", required=True, type=pathlib.Path, help="an empty folder")
    parser.add_argument("--module", action="store_true", help="check drivenshape.__version__")
    args = parser.parse_args()
    data = args.source / "tests" / "data" / "sleeve"
    args.work.mkdir(parents=True, exist_ok=True)

    declared = declared_version(args.source)
    found = {"CMakeLists.txt project(VERSION)": declared,
             "PROJECT_VERSION of the build (configure again if stale)": args.configured}
    out = run([args.cli, "--version"]).strip()
    found["drivenshape --version"] = out.removeprefix("drivenshape ")
    if args.module:
        import drivenshape

        found["drivenshape.__version__ (Python module)"] = drivenshape.__version__
    found["bl_info['version'] (Blender add-on)"] = addon_version(args.source)

    database = args.work / "sleeve.dsdb"
    run([args.cli, "db", "build", "--driver-mesh", data / "driver_rest.obj",
         "--driven-mesh", data / "driven_rest.obj", "--driver", data / "train.driver.pc2",
         "--driven", data / "train.driven.pc2", "--model", "none", "--quiet", "-o", database])
    found["tool_version of the database header (db build)"] = database_tool_version(database)
    run([args.cli, "bake", "--db", database, "--driver", data / "test.driver.pc2", "--frames",
         "1", "-o", args.work / "sleeve.####.exr", "--device", "host", "--quiet"])
    found["dsToolVersion of the point-cache EXR (bake)"] = exr_tool_version(
        args.work / "sleeve.0001.exr")
    report = json.loads((args.work / "sleeve.report.json").read_text(encoding="utf-8"))
    found["tool_version of the bake report"] = report["tool_version"]

    width = max(map(len, found))
    for where, version in found.items():
        print(f"{where:<{width}}  {version}")
    wrong = [where for where, version in found.items() if version != declared]
    if wrong:
        print(f"check_version: CMakeLists.txt declares version {declared}; different in: "
              f"{'; '.join(wrong)}", file=sys.stderr)
        return 1
    print(f"check_version: {declared} in all {len(found)} places")
    return 0


if __name__ == "__main__":
    sys.exit(main())
