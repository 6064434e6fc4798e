# SPDX-License-Identifier: Apache-2.0
"""Finds and imports the drivenshape Python module (built from apps/python).

The add-on does not bundle the compiled module: it is built for one Python version and one
machine, beside the library. The folder that holds ``drivenshape/`` is looked for, in order, in
the add-on preference, the DRIVENSHAPE_PYTHONPATH environment variable (several folders
separated by os.pathsep), the install locations below, and finally Blender's own sys.path.
A failed import is remembered with the reason for every place tried, so that the panel can show
it; "Retry" (drivenshape.retry_import) forgets it.
"""

import os
import sys

import bpy

# Where `cmake --install build --prefix PREFIX` puts the module (PREFIX/lib/python3/
# dist-packages/drivenshape, apps/python/CMakeLists.txt), for the usual prefixes.
INSTALL_PATHS = (
    "/usr/local/lib/python3/dist-packages",
    "/opt/drivenshape/lib/python3/dist-packages",
    os.path.expanduser("~/.local/lib/python3/dist-packages"),
)


class ModuleMissing(RuntimeError):
    """The drivenshape module could not be imported; the message says where it was looked for."""


_module = None
_failure = None


def _addon_preferences():
    addon = bpy.context.preferences.addons.get(__package__)
    return addon.preferences if addon else None


def candidate_folders():
    """(origin, folder) pairs, in the order they are tried."""
    folders = []
    prefs = _addon_preferences()
    if prefs is not None and prefs.module_path:
        folders.append(("the add-on preference", bpy.path.abspath(prefs.module_path)))
    for folder in os.environ.get("DRIVENSHAPE_PYTHONPATH", "").split(os.pathsep):
        if folder:
            folders.append(("DRIVENSHAPE_PYTHONPATH", folder))
    for folder in INSTALL_PATHS:
        folders.append(("the install location", folder))
    return folders


def _forget_partial_import():
    for name in list(sys.modules):
        if name == "drivenshape" or name.startswith("drivenshape."):
            del sys.modules[name]


def _try_folder(folder):
    """Imports drivenshape from `folder`; returns (module, None) or (None, reason)."""
    if not os.path.isdir(os.path.join(folder, "drivenshape")):
        return None, "no drivenshape/ folder there"
    sys.path.insert(0, folder)
    try:
        import drivenshape  # noqa: PLC0415 (imported on demand, from the folder just added)
    except Exception as error:  # an ImportError, or an error raised while loading the extension
        sys.path.remove(folder)
        _forget_partial_import()
        return None, f"{type(error).__name__}: {error}"
    return drivenshape, None


def get():
    """The drivenshape module; raises ModuleMissing with every place tried and why it failed."""
    global _module, _failure
    if _module is not None:
        return _module
    if _failure is not None:
        raise ModuleMissing(_failure)
    tried = []
    for origin, folder in candidate_folders():
        module, reason = _try_folder(folder)
        if module is not None:
            _module = module
            return module
        tried.append(f"{folder} ({origin}): {reason}")
    try:
        import drivenshape  # noqa: PLC0415 (already on sys.path, e.g. installed site-wide)

        _module = drivenshape
        return drivenshape
    except Exception as error:
        _forget_partial_import()
        tried.append(f"Blender's sys.path: {type(error).__name__}: {error}")
    _failure = (
        "cannot import the drivenshape Python module. Tried " + "; ".join(tried) + ". Set the "
        "folder that holds drivenshape/ (the build's python/ folder) in Edit > Preferences > "
        "Add-ons > DrivenShape, or start Blender with DRIVENSHAPE_PYTHONPATH set to it."
    )
    raise ModuleMissing(_failure)


def status():
    """(ok, text) for the panel: the module's version and location, or why it is missing."""
    try:
        module = get()
    except ModuleMissing as error:
        return False, str(error)
    version = getattr(module, "__version__", "?")
    return True, f"drivenshape {version} ({os.path.dirname(os.path.dirname(module.__file__))})"


def forget_failure():
    """Lets the next get() try again (after the preference or the environment changed)."""
    global _failure
    _failure = None
