#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Checks the library's layering from its #include lines (docs/architecture.md, "The layers").

The rooms of src/, lowest first: a file may include headers of its own room and of the rooms
under it, never of a room above. Each public header (src/include/drivenshape/) belongs to the
room that implements it, listed in PUBLIC_ROOMS below; a public header missing from that list
is an error, so a new one is placed on purpose. The OpenCL kernels' shared headers (kernels/,
also reached as <drivenshape_kernels/NAME_cl.h>) are plain types every room may see.

Every quoted include in src/, apps/, bench/ and tests/ must also name a file inside the repository:
an absolute path, or a relative one that leaves the clone or names nothing there, is an error.

  python3 scripts/check_layers.py              # check; exit 1 naming each offending line
  python3 scripts/check_layers.py --self-test  # prove the check fails on an upward include
"""
import argparse
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
ROOMS = ["core", "io", "database", "devices", "pipeline", "database_build", "shot"]
# The room of each public header: where the code it declares lives.
PUBLIC_ROOMS = {
    "error.h": "core",
    "version.h": "core",
    "frames.h": "io",
    "mesh.h": "io",
    "mesh_check.h": "io",
    "point_cache.h": "io",
    "weight_map.h": "io",
    "position_map.h": "io",
    "binding.h": "database",
    "database.h": "database",
    "pose_model.h": "database",
    "regions.h": "database",
    "position_map_tables.h": "database",
    "device.h": "devices",
    "device_cl.h": "devices",
    "position_map_backend.h": "devices",
    "layer_backend.h": "devices",
    "evaluator.h": "pipeline",
    "layers.h": "pipeline",
    "settings_table.h": "pipeline",
    "bake_options.h": "pipeline",
    "database_build.h": "database_build",
    "bake.h": "shot",
    "shot_plan.h": "shot",
    "evaluate.h": "shot",
    "coverage_check.h": "shot",
    "simulation.h": "shot",
    "position_map_sequence.h": "shot",
}
INCLUDE = re.compile(r'^\s*#\s*include\s*([<"])([^>"]+)[>"]')


def private_headers(src):
    """Private header name -> (room, path): every room's folders are on the include path."""
    found = {}
    for room in ROOMS:
        for path in sorted((src / room).rglob("*.h")):
            found.setdefault(path.name, (room, path))
    return found


def room_of(path, src):
    parts = path.relative_to(src).parts
    if parts[0] == "include":
        name = parts[-1][: -len(".in")] if parts[-1].endswith(".in") else parts[-1]
        return PUBLIC_ROOMS.get(name)
    return parts[0] if parts[0] in ROOMS else None


def resolve_quoted(source, name, root, private):
    """The file a quoted include names (its own folder, the private path, then any folder of
    apps/, bench/, tests/ or kernels/ that a target adds to its include path), or None."""
    if name.startswith("/"):
        return None
    beside = (source.parent / name).resolve()
    if beside.is_file():
        return beside
    if "/" not in name and name in private:
        return private[name][1]
    for folder in ("kernels", "apps", "bench", "tests"):
        for candidate in (root / folder).rglob(Path(name).name):
            if candidate.is_file() and candidate.as_posix().endswith("/" + name):
                return candidate.resolve()
    return None


def check(root):
    src = root / "src"
    private = private_headers(src)
    problems = []
    for header in sorted((src / "include" / "drivenshape").iterdir()):
        name = header.name[: -len(".in")] if header.name.endswith(".in") else header.name
        if name not in PUBLIC_ROOMS:
            problems.append(f"{header.relative_to(root)}: a public header of no room; add it to "
                            "PUBLIC_ROOMS in scripts/check_layers.py")
    for folder in ("src", "apps", "bench", "tests"):
        for path in sorted((root / folder).rglob("*")):
            if path.suffix not in (".h", ".cpp", ".in") or not path.is_file():
                continue
            problems += check_file(path, root, src, private)
    return problems


def check_file(path, root, src, private):
    problems = []
    in_src = src in path.parents
    room = room_of(path, src) if in_src else None
    for number, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
        match = INCLUDE.match(line)
        if not match:
            continue
        quote, name = match.groups()
        where = f"{path.relative_to(root)}:{number}"
        target_room = None
        if quote == '"':
            target = resolve_quoted(path, name, root, private)
            if target is None or root not in target.parents:
                problems.append(f"{where}: includes \"{name}\", which is not a file of the "
                                "repository")
                continue
            if src in target.parents:
                target_room = room_of(target, src)
        elif name.startswith("drivenshape/"):
            target_room = PUBLIC_ROOMS.get(name.split("/", 1)[1])
        if not in_src or room is None or target_room is None:
            continue
        if ROOMS.index(target_room) > ROOMS.index(room):
            problems.append(f"{where}: {room} includes {name} of {target_room}, a room above it "
                            f"(rooms, lowest first: {', '.join(ROOMS)})")
    return problems


def self_test():
    """Copies the tree, adds an upward include to a core file, and expects the check to fail."""
    with tempfile.TemporaryDirectory() as folder:
        copy = Path(folder) / "tree"
        for part in ("src", "apps", "bench", "tests", "kernels", "scripts"):
            shutil.copytree(ROOT / part, copy / part)
        if check(copy):
            print("check_layers --self-test: the tree fails before the change", file=sys.stderr)
            return 1
        victim = copy / "src" / "core" / "progress.cpp"
        victim.write_text(victim.read_text() + '\n#include "executor.h"\n')
        result = subprocess.run([sys.executable, str(copy / "scripts" / "check_layers.py")],
                                capture_output=True, text=True)
        if result.returncode == 0 or "core includes executor.h of pipeline" not in result.stderr:
            print("check_layers --self-test: an upward include was not caught:\n" + result.stderr,
                  file=sys.stderr)
            return 1
        outside = copy / "src" / "io" / "frames.cpp"
        outside.write_text(outside.read_text() + '\n#include "../../../elsewhere/x.h"\n')
        victim.write_text(victim.read_text().replace('#include "executor.h"\n', ""))
        result = subprocess.run([sys.executable, str(copy / "scripts" / "check_layers.py")],
                                capture_output=True, text=True)
        if result.returncode == 0 or "not a file of the repository" not in result.stderr:
            print("check_layers --self-test: an include outside the repository was not caught:\n" +
                  result.stderr, file=sys.stderr)
            return 1
    print("check_layers --self-test: an upward include and an outside include both fail")
    return 0


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--self-test", action="store_true",
                        help="prove the check fails on an upward include")
    if parser.parse_args().self_test:
        return self_test()
    problems = check(ROOT)
    for problem in problems:
        print(problem, file=sys.stderr)
    if problems:
        print(f"check_layers: {len(problems)} include(s) break the layering "
              "(docs/architecture.md, \"The layers\")", file=sys.stderr)
        return 1
    print("check_layers: every include calls down")
    return 0


if __name__ == "__main__":
    sys.exit(main())
