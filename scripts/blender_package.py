#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Packs the Blender add-on (apps/blender/drivenshape_blender) into a zip that Blender installs
with Edit > Preferences > Add-ons > Install... (or bpy.ops.preferences.addon_install).

    python3 scripts/blender_package.py [-o out/drivenshape_blender-VERSION.zip]

The zip holds the folder drivenshape_blender/ at its top level, sources only (no __pycache__),
with fixed timestamps so that the same sources give the same bytes. Standard library only.
Prints the zip's path.
"""

import argparse
import ast
import pathlib
import sys
import zipfile

ROOT = pathlib.Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "apps" / "blender" / "drivenshape_blender"


def addon_version():
    """bl_info["version"] of the add-on, read without importing it (it needs bpy)."""
    tree = ast.parse((PACKAGE / "__init__.py").read_text(encoding="utf-8"))
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(
                getattr(target, "id", None) == "bl_info" for target in node.targets):
            info = ast.literal_eval(node.value)
            return ".".join(str(part) for part in info["version"])
    raise SystemExit(f"blender_package: no bl_info in {PACKAGE / '__init__.py'}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", type=pathlib.Path,
                        help="zip to write (default: out/drivenshape_blender-VERSION.zip)")
    args = parser.parse_args()
    output = args.output or ROOT / "out" / f"drivenshape_blender-{addon_version()}.zip"
    output.parent.mkdir(parents=True, exist_ok=True)
    files = sorted(path for path in PACKAGE.rglob("*")
                   if path.is_file() and "__pycache__" not in path.parts
                   and path.suffix not in {".pyc", ".pyo"})
    if not files:
        raise SystemExit(f"blender_package: no files under {PACKAGE}")
    temporary = output.with_name(output.name + ".tmp")
    with zipfile.ZipFile(temporary, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for path in files:
            name = str(path.relative_to(PACKAGE.parent))
            info = zipfile.ZipInfo(name, date_time=(2024, 1, 1, 0, 0, 0))
            info.external_attr = 0o644 << 16
            info.compress_type = zipfile.ZIP_DEFLATED
            archive.writestr(info, path.read_bytes())
    temporary.replace(output)
    print(output)
    return 0


if __name__ == "__main__":
    sys.exit(main())
