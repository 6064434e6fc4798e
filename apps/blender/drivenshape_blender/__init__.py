# SPDX-License-Identifier: Apache-2.0
"""DrivenShape for Blender: data-driven cloth (Kim & Vendrovsky, Rhythm and Hues, SIGGRAPH 2008)
from a database of simulated examples, live in the viewport while animating and baked to PC2 /
point-cache EXRs. Built on the drivenshape Python module (apps/python), which it finds through
the add-on preference or DRIVENSHAPE_PYTHONPATH (module.py). See docs/blender.md."""

bl_info = {
    "name": "DrivenShape",
    "author": "drivenshape developers",
    # Blender needs a literal tuple: it must spell project(drivenshape VERSION ...) of the top
    # CMakeLists.txt, which the CTest version_check (tests/version) enforces.
    "version": (0, 2, 0),
    "blender": (3, 4, 0),
    "location": "3D Viewport > Sidebar > DrivenShape",
    "description": "Data-driven cloth: live preview and bakes from a database of simulated "
                   "examples",
    "category": "Animation",
}

if "bpy" in locals():
    # F8 / "Reload Scripts": reload the submodules in dependency order.
    import importlib

    for _name in ("settings_generated", "module", "engine", "coverage", "live", "bake",
                  "simulate", "properties", "operators", "ui"):
        if _name in locals():
            importlib.reload(locals()[_name])

import bpy  # noqa: E402,F401 (the reload test above looks for it)

from . import (  # noqa: E402,F401
    bake,
    coverage,
    engine,
    live,
    module,
    operators,
    properties,
    settings_generated,
    simulate,
    ui,
)

_PARTS = (properties, operators, ui, live, coverage)


def register():
    for part in _PARTS:
        part.register()


def unregister():
    for part in reversed(_PARTS):
        part.unregister()
