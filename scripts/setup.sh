#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Installs what is missing (Debian 12 packages, the Python venv for scripts and Python tests),
# then configures and builds drivenshape (Release, -march=x86-64, warnings as errors) in ./build.
# clang and libclang-rt-14-dev are for the fuzz targets (libFuzzer, ASan, UBSan) of the tests;
# pybind11-dev and python3-dev build the Python module, which Debian's Blender (its add-on tests)
# imports with python3-numpy. chromium renders the QC page (python -m drivenshape.qc) headless in
# its test.
# Safe to run again: it installs nothing that is already there and rebuilds incrementally.
set -euo pipefail
cd "$(dirname "$0")/.."

PACKAGES=(
  build-essential cmake ninja-build pkg-config
  ocl-icd-opencl-dev opencl-c-headers opencl-clhpp-headers pocl-opencl-icd clinfo
  libeigen3-dev libopenexr-dev openexr libflann-dev liblz4-dev libdeflate-dev nlohmann-json3-dev
  libgtest-dev openimageio-tools clang-format git slurm-wlm munge
  clang libclang-rt-14-dev llvm
  python3 python3-venv python3-pip python3-dev python3-numpy pybind11-dev
  blender chromium
)

missing=()
for package in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$package")
  fi
done
if ((${#missing[@]})); then
  echo "setup: installing ${missing[*]}" >&2
  SUDO=""
  if [[ $(id -u) -ne 0 ]]; then SUDO="sudo"; fi
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends \
    "${missing[@]}" >/dev/null
fi

# Python: a project venv for scripts/ and the Python-driven tests (quadprog cross-check).
# Debian's own interpreter is preferred so the venv works the same on every machine.
PYTHON=/usr/bin/python3
[[ -x $PYTHON ]] || PYTHON=python3
stamp=.venv/.requirements.sha256
want=$(sha256sum scripts/requirements.txt | cut -d' ' -f1)
if [[ ! -x .venv/bin/python || ! -f $stamp || $(cat "$stamp") != "$want" ]]; then
  echo "setup: preparing the Python venv in .venv" >&2
  # An existing venv is updated in place (re-running venv over one made by another interpreter
  # fails in ensurepip); a broken one is made again from scratch.
  if ! .venv/bin/python -m pip --version >/dev/null 2>&1; then
    "$PYTHON" -m venv --clear .venv
  fi
  .venv/bin/python -m pip install -q --upgrade pip >/dev/null
  .venv/bin/python -m pip install -q -r scripts/requirements.txt
  echo "$want" >"$stamp"
fi

jobs=$(nproc 2>/dev/null || echo 2)
# -march=x86-64: the baseline every x86-64 CPU runs, whatever CPU builds it (never native).
# A unity build (a few source files per compiler run) parses the large headers (Eigen, OpenCL,
# GoogleTest, nlohmann) once per batch: a build from scratch takes about a third less time.
# DRIVENSHAPE_UNITY=OFF turns it off (quicker rebuilds of one changed file while developing).
# Ninja compiles every library's sources in parallel (Make waits for each static library's
# dependencies first): on 2 cores the build from scratch takes about a sixth less. A build
# folder made earlier with another generator keeps it.
generator=()
[[ -f build/CMakeCache.txt ]] || generator=(-G Ninja)
cmake -S . -B build "${generator[@]}" -DCMAKE_BUILD_TYPE=Release -DDRIVENSHAPE_WERROR=ON \
  -DDRIVENSHAPE_ARCH=x86-64 -DCMAKE_UNITY_BUILD="${DRIVENSHAPE_UNITY:-ON}" \
  -DDRIVENSHAPE_PYTHON="$PWD/.venv/bin/python" >/dev/null
cmake --build build -j"$jobs"
