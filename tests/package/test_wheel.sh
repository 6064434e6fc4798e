#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# `pip install .` end to end (pyproject.toml, scikit-build-core): a fresh venv gets the test
# dependencies (scripts/requirements.txt) and the package built from the source tree; the
# console scripts answer --help, the module imports from the venv (not from the build tree) and
# says the project's version, its types check (tests/python/check_typing.py) and the Python tests
# run against the installed package.
#   test_wheel.sh BUILD_DIR SOURCE_DIR CLI [--reuse MODULE]
# Without --reuse (CTest wheel_full_build): pip compiles the library and the extension itself;
# the wheel's CMake build stays in BUILD_DIR/wheel-build, so a second run is incremental.
# With --reuse MODULE (CTest python_wheel): everything of `pip install .` runs as a user's does
# (build isolation, scikit-build-core reading pyproject.toml, CMake configuring the whole
# project in its SKBUILD mode in a fresh build folder, the install of the component `python`,
# the metadata, the console scripts), except the compiler: the build folder is handed the
# extension MODULE that this build made from the same sources at the place where its target
# writes it, and only the target that copies the pure-Python files is built
# (build.targets=drivenshape_python_package). The install rule of the extension's target then
# packs that file, as it packs the one it compiles.
set -euo pipefail
build=$1
source=$2
cli=$3
module=
if [ "${4:-}" = --reuse ]; then
  module=$5
fi
if [ -n "$module" ]; then
  work="$build/wheel-test"
  wheel_build="$work/wheel-build"
  rm -rf "$work"
  mkdir -p "$wheel_build/python/drivenshape"
  cp "$module" "$wheel_build/python/drivenshape/"
  pip_build=(--config-settings=build-dir="$wheel_build"
             --config-settings=build.targets=drivenshape_python_package)
else
  work="$build/wheel-test-full"
  rm -rf "$work"
  pip_build=(--config-settings=build-dir="$build/wheel-build")
fi
mkdir -p "$work"
python3 -m venv "$work/venv"
python="$work/venv/bin/python"
"$python" -m pip install -q --upgrade pip > /dev/null
"$python" -m pip install -q -r "$source/scripts/requirements.txt"
"$python" -m pip install -q "${pip_build[@]}" "$source"

cd "$work"
unset PYTHONPATH
version=$(sed -n 's/^project(drivenshape VERSION \([0-9.]*\).*/\1/p' "$source/CMakeLists.txt")
"$python" - "$work/venv" "$version" <<'PY'
import os, sys
import drivenshape
venv, version = sys.argv[1:]
where = os.path.realpath(drivenshape.__file__)
assert where.startswith(os.path.realpath(venv)), f"drivenshape imported from {where}, not the venv"
assert drivenshape.__version__ == version, (drivenshape.__version__, version)
print(f"drivenshape {drivenshape.__version__} from {where}")
PY
# The types reach the wheel (wheel.packages copies apps/python/drivenshape): mypy, finding the
# installed package through py.typed, accepts the typed example and rejects the wrong uses.
site=$("$python" -c 'import drivenshape, os; print(os.path.dirname(drivenshape.__file__))')
test -f "$site/_drivenshape.pyi"
test -f "$site/py.typed"
"$python" "$source/tests/python/check_typing.py" --data "$source/tests/data/sleeve" \
  --work "$work/typing"
"$work/venv/bin/drivenshape-usd" --help > /dev/null
"$work/venv/bin/drivenshape-qc" --help > /dev/null
"$python" -m pytest -q -p no:cacheprovider "$source/tests/python" --basetemp="$work/pytest" \
  --cli="$cli" --data="$source/tests/data/sleeve"
echo "the installed wheel passed"
