# SPDX-License-Identifier: Apache-2.0
"""Shared fixtures of the Python module's tests: the command line (the independent reference),
the bundled sleeve sample, readers that do not use the module (PC2 and OBJ parsed here, EXR read
by the OpenEXR PyPI package), and the command line's database and bakes, made once per run.

Every comparison of frames is bitwise: equal float32 bit patterns (assert_bitwise)."""

import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

import drivenshape as ds

TEST_FRAMES = list(range(1, 49))  # the sample's test clip (tests/data/sleeve/test.*.pc2)


def pytest_addoption(parser):
    parser.addoption("--cli", required=True, help="the built `drivenshape` command line")
    parser.addoption("--data", required=True, help="tests/data/sleeve")


def pytest_report_header(config):
    return [f"drivenshape module {ds.__version__} from {os.path.dirname(ds.__file__)}"]


@pytest.fixture(scope="session")
def cli(request):
    path = request.config.getoption("--cli")
    assert os.access(path, os.X_OK), f"the command line {path} is not built"
    return path


@pytest.fixture(scope="session")
def data(request):
    return Path(request.config.getoption("--data"))


def run(command, expect=0):
    """Runs a command, fails with its output unless it exits `expect`."""
    result = subprocess.run([str(c) for c in command], capture_output=True, text=True)
    assert result.returncode == expect, (
        f"{' '.join(map(str, command))} exited {result.returncode}, expected {expect}:\n"
        f"{result.stdout}{result.stderr}")
    return result


def assert_bitwise(actual, expected, what):
    """Equal shapes, dtype float32 and bit patterns; the message says how far off it is."""
    actual = np.asarray(actual)
    expected = np.asarray(expected)
    assert actual.dtype == np.float32 and expected.dtype == np.float32, (
        f"{what}: dtypes {actual.dtype} and {expected.dtype}, expected float32")
    assert actual.shape == expected.shape, f"{what}: shape {actual.shape} != {expected.shape}"
    same = actual.view(np.uint32) == expected.view(np.uint32)
    if not same.all():
        worst = np.nanmax(np.abs(actual.astype(np.float64) - expected))
        raise AssertionError(f"{what}: {np.count_nonzero(~same)} of {same.size} values differ "
                             f"(tolerance: bitwise; largest difference {worst:.3g})")


# ---- Readers that do not use the module -----------------------------------------------------

def parse_pc2(path):
    """(positions (F, V, 3) float32, start frame, sample rate) decoded here byte by byte."""
    raw = Path(path).read_bytes()
    assert raw[:12] == b"POINTCACHE2\0", f"{path}: no PC2 magic"
    version, points = np.frombuffer(raw[12:20], "<i4")
    start, rate = np.frombuffer(raw[20:28], "<f4")
    samples = int(np.frombuffer(raw[28:32], "<i4")[0])
    assert version == 1 and len(raw) == 32 + samples * int(points) * 12, f"{path}: bad header"
    xyz = np.frombuffer(raw, "<f4", offset=32).reshape(samples, int(points), 3)
    return xyz.astype(np.float32), float(start), float(rate)


def parse_obj(path):
    """(positions (V, 3) float32, face sizes, face vertex ids) of an OBJ, parsed here."""
    positions, sizes, corners = [], [], []
    for line in Path(path).read_text().splitlines():
        words = line.split()
        if words and words[0] == "v":
            positions.append(words[1:4])
        elif words and words[0] == "f":
            sizes.append(len(words) - 1)
            corners.extend(int(w.split("/")[0]) - 1 for w in words[1:])
    return (np.array(positions, dtype=np.float32), np.array(sizes, dtype=np.int32),
            np.array(corners, dtype=np.int32))


def read_exr_openexr(path):
    """(positions (V, 3) float32, header) of a point-cache EXR read by the OpenEXR PyPI package:
    vertex v is pixel (v mod W, v div W), channels P.X P.Y P.Z."""
    import OpenEXR

    with OpenEXR.File(str(path), separate_channels=True) as image:
        header = dict(image.header())
        channels = image.channels()
        count = int(header["dsVertexCount"])
        xyz = np.stack([np.asarray(channels[name].pixels, dtype=np.float32).reshape(-1)[:count]
                        for name in ("P.X", "P.Y", "P.Z")], axis=1)
    return np.ascontiguousarray(xyz), header


# ---- The command line's database and bakes (the references) ---------------------------------

@pytest.fixture(scope="session")
def cli_database(cli, data, tmp_path_factory):
    path = tmp_path_factory.mktemp("cli_db") / "sleeve.dsdb"
    run([cli, "db", "build", "--driver-mesh", data / "driver_rest.obj",
         "--driven-mesh", data / "driven_rest.obj", "--driver", data / "train.driver.pc2",
         "--driven", data / "train.driven.pc2", "--model", "none", "--quiet", "-o", path])
    return path


class CliBakes:
    """`drivenshape bake` of the test clip into EXRs, once per device and extra arguments."""

    def __init__(self, cli, data, database, root):
        self.cli, self.data, self.database, self.root = cli, data, database, root
        self.done = {}

    def folder(self, device, *extra, frames="1-48"):
        key = (device, extra, frames)
        if key not in self.done:
            folder = self.root / f"bake{len(self.done)}_{device}"
            folder.mkdir(parents=True)
            run([self.cli, "bake", "--db", self.database, "--driver",
                 self.data / "test.driver.pc2", "--frames", frames, "-o",
                 folder / "sleeve.####.exr", "--device", device, "--quiet", *extra])
            self.done[key] = folder
        return self.done[key]

    def frames(self, device, frames, *extra, frame_text="1-48", reader="module"):
        """(F, Vd, 3) of the bake's EXRs, read by the module or by OpenEXR (PyPI)."""
        folder = self.folder(device, *extra, frames=frame_text)
        paths = [folder / f"sleeve.{f:04d}.exr" for f in frames]
        if reader == "module":
            return np.stack([ds.read_point_cache_exr(p)[0] for p in paths])
        return np.stack([read_exr_openexr(p)[0] for p in paths])


@pytest.fixture(scope="session")
def cli_bakes(cli, data, cli_database, tmp_path_factory):
    return CliBakes(cli, data, cli_database, tmp_path_factory.mktemp("cli_bakes"))


@pytest.fixture(scope="session")
def pose_bakes(cli, data, tmp_path_factory):
    """Bakes of a database built with `db build`'s defaults: the pose model (issue 27)."""
    path = tmp_path_factory.mktemp("pose_db") / "sleeve_pose.dsdb"
    run([cli, "db", "build", "--driver-mesh", data / "driver_rest.obj",
         "--driven-mesh", data / "driven_rest.obj", "--driver", data / "train.driver.pc2",
         "--driven", data / "train.driven.pc2", "--quiet", "-o", path])
    return CliBakes(cli, data, path, tmp_path_factory.mktemp("pose_bakes"))


@pytest.fixture(scope="session")
def opencl_device():
    """The default OpenCL device; a machine without one fails here (never a skip)."""
    device = ds.open_device("auto")
    assert device.is_opencl, (f"no OpenCL device ({device.note}); install pocl-opencl-icd "
                              "(scripts/setup.sh)")
    return device


@pytest.fixture(scope="session")
def host_device():
    return ds.open_device("host")
