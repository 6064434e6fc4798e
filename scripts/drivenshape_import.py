# SPDX-License-Identifier: Apache-2.0
"""Finding the project's Python module from the scripts in scripts/: PYTHONPATH first, else this
checkout's build folder (build/python, where scripts/setup.sh builds it)."""

import importlib
import os
import sys


def import_drivenshape(submodule=None):
    """drivenshape (or drivenshape.<submodule>). Raises ImportError with what to do."""
    name = "drivenshape" + (f".{submodule}" if submodule else "")
    try:
        return importlib.import_module(name)
    except ImportError:
        build = os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir, "build",
                             "python")
        sys.path.insert(0, os.path.normpath(build))
        try:
            return importlib.import_module(name)
        except ImportError as error:
            raise ImportError(f"the drivenshape Python module is not available ({error}): build "
                              "it (scripts/setup.sh) or set PYTHONPATH to the build's python "
                              "folder") from None
