# SPDX-License-Identifier: Apache-2.0
"""Golden bakes of the bundled sleeve sample, shared by record_goldens.py and check_goldens.py.

One table (CONFIGS x DEVICES) says what is baked; one function (bake_all) builds the database
and runs every bake with a given `drivenshape` binary, one at a time, and returns per bake the
report's per-frame records (timing and paths removed), the report's settings, and per frame
the sha256 of the decoded pixels and of the file bytes (golden_pixels.py) of the point-cache
EXRs (and of the position maps for the posmap configuration).

The records are compared exactly: every float is the double the report's JSON text spells
(Python's float() of nlohmann's shortest round-trip text is that double, and json.dumps writes
it back with the same digits: record_goldens.py checks that for every float it stores).
"""

import json
import math
import os
import shutil
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import golden_pixels  # noqa: E402

FORMAT = "drivenshape-golden-bakes"
FORMAT_VERSION = 1

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
DATA = os.path.join(REPO, "tests", "data")
SLEEVE = os.path.join(DATA, "sleeve")
GOLDEN_DATA = os.path.join(DATA, "golden")

# Inputs, relative to tests/data ({data} in flags below).
INPUTS = ["sleeve/driver_rest.obj", "sleeve/driven_rest.obj", "sleeve/train.driver.pc2",
          "sleeve/train.driven.pc2", "sleeve/test.driver.pc2", "golden/regions.json",
          "golden/bind_mask.json"]

DB_FLAGS = ["db", "build", "--driver-mesh", "{data}/sleeve/driver_rest.obj",
            "--driven-mesh", "{data}/sleeve/driven_rest.obj",
            "--driver", "{data}/sleeve/train.driver.pc2",
            "--driven", "{data}/sleeve/train.driven.pc2", "--count", "30"]
BAKE_DRIVER = "{data}/sleeve/test.driver.pc2"
BAKE_FRAMES = "1-48"
FRAMES = golden_pixels.parse_frames(BAKE_FRAMES)
OUTPUT_NAME = "sleeve.####.exr"
POSMAP_NAME = "sleeve.posmap.####.exr"  # the default --posmap-out for OUTPUT_NAME

# name, extra bake flags, what part of the pipeline it pins down.
CONFIGS = [
    ("default", [],
     "rigid alignment, exact QP weights, local-frame blend, penetration resolution, audit"),
    ("talk", ["--align", "none", "--blend", "world", "--no-resolve"],
     "the talk's method: world-space blend, per-frame closest-triangle correction"),
    ("bind", ["--weights", "bind"], "binding baseline (no database) + resolution"),
    ("nearest", ["--weights", "nearest", "--no-audit"], "nearest-shape weights, no audit"),
    ("temporal", ["--max-weight-change", "0.05", "--batch", "7", "--temporal-warmup", "3"],
     "temporal bound, warm-up frames, batches of 7 (48 = 6 x 7 + 6)"),
    ("regions", ["--regions", "{data}/golden/regions.json"],
     "region-local QPs and their partition of unity (incl. the implicit 'rest' region)"),
    ("mask_layers", ["--bind", "{data}/golden/bind_mask.json", "--wind-amplitude", "0.01",
                     "--wind-seed", "3", "--align", "rigid-all"],
     "binding mask, procedural wind layer, area-weighted rigid alignment"),
    ("noresolve_batch1", ["--no-resolve", "--batch", "1", "--threads", "1"],
     "no resolution, one frame per launch batch, one thread"),
    ("posmap", ["--posmap", "64", "--posmap-normals"],
     "position maps (64x64, normals) written from memory beside the point caches"),
]
# Flags a configuration needs, beyond those it was recorded with, because a default changed
# after the recording: with them the current binary writes what the recorded binary wrote by
# default, so the goldens keep proving that nothing else changed. check_goldens.py adds them
# (bake_all(since_recording=True)); record_goldens.py does not (the recorded commit's binary
# may not know them), and the recorded flags stay those of CONFIGS.
# Issue 17: `db build` fits the pose model by default and the default bake evaluates it; the
# goldens hold QP bakes of a database without one, which --model none builds.
DB_SINCE_RECORDING = ["--model", "none"]
# Issue 18: ZIP files are deflated by libdeflate by default (the same pixels in other bytes);
# the goldens hold the bytes of OpenEXR's own zlib writer, which --zip-encoder openexr writes.
OPENEXR_ZIP = ["--zip-encoder", "openexr"]
SINCE_RECORDING = {name: list(OPENEXR_ZIP) for name, _, _ in CONFIGS}
# Issue 16: position maps are named R G B, A, N.R N.G N.B by default; the goldens hold the
# former P.X P.Y P.Z, A, N.X N.Y N.Z maps, which --posmap-channels legacy writes (pixels and
# file bytes).
SINCE_RECORDING["posmap"] += ["--posmap-channels", "legacy"]
# Issue 17: the penetration resolution fades the move of deep vertices with two nearly equal
# exits (--exit-fade 0.15); the goldens were recorded without it, which --exit-fade 0 restores.
for name, _, _ in CONFIGS:
    SINCE_RECORDING[name] += ["--exit-fade", "0"]
# 0.2: the resolution moves cloth the nearest way out, along the line from its closest point
# (continuous where that point crosses onto an edge); the goldens moved it along the pseudo-normal,
# which --resolve-direction normal restores.
for name, _, _ in CONFIGS:
    SINCE_RECORDING[name] += ["--resolve-direction", "normal"]
# Issue 43: the strain limit brings the cloth's edges back to their length by default
# (--strain-limit 0.01); the goldens were recorded without it, which --strain-limit 0 restores.
for name, _, _ in CONFIGS:
    SINCE_RECORDING[name] += ["--strain-limit", "0"]
DEVICES = ["host", "cpu"]  # cpu = the OpenCL CPU device (PoCL); it must exist (never skipped)

# Per-frame report keys that are not results.
FRAME_IGNORED = ("output",)
# Record fields the recording has that moved to the report's `run` since 0.2.0 (a record is
# the frame's, whichever run baked it): not compared; the run's counts are, in the summary.
FRAME_MOVED = ("skipped", "rebaked_because", "closest_queries", "closest_cleared")
# Settings keys holding paths given on the command line: compared by file name only.
SETTINGS_PATHS = ("binding_mask", "regions_file")


def expand(flags, data=DATA):
    return [f.replace("{data}", data) for f in flags]


def sha256_file(path):
    return golden_pixels.file_sha256(path)


def input_hashes():
    return {name: sha256_file(os.path.join(DATA, name)) for name in INPUTS}


class JsonFloat(float):
    """A float that remembers the text it was parsed from (kept verbatim in the goldens)."""

    def __new__(cls, text):
        value = super().__new__(cls, text)
        value.text = text
        return value


class FloatText:
    """json parse_float hook: JsonFloat values; counts them and those whose text is not the
    shortest round-trip form (nlohmann's Grisu2 sometimes writes 17 digits)."""

    def __init__(self):
        self.count = 0
        self.not_shortest = 0

    def __call__(self, text):
        value = JsonFloat(text)
        self.count += 1
        self.not_shortest += repr(float(value)) != text
        return value


def load_json(path, float_text=None):
    """JSON with floats as JsonFloat (the exact double, and its text)."""
    with open(path) as f:
        return json.load(f, parse_float=float_text or JsonFloat)


def run(cmd, log, env):
    """Runs cmd; its stdout and stderr go to `log`. Raises with the log's tail on failure."""
    with open(log, "w") as out:
        status = subprocess.run(cmd, stdout=out, stderr=subprocess.STDOUT, env=env).returncode
    if status != 0:
        with open(log) as f:
            tail = f.read()[-3000:]
        raise RuntimeError(f"exit code {status}: {' '.join(cmd)}\n--- log tail ---\n{tail}")


def strip_report(report):
    """The parts of a bake report that a refactor must reproduce (no timing, no paths)."""
    frames = []
    for record in report["frames"]:
        frames.append({k: v for k, v in record.items()
                       if k not in FRAME_IGNORED and k not in FRAME_MOVED})
    settings = dict(report["settings"])
    # Added by the Evaluator (c.f. issue 14): which pipeline stages ran. Informational: the
    # settings that decide the result are the other keys, compared exactly.
    settings.pop("stages", None)
    # Added with the exit fade (issue 17); the recorded reports lack it. Off (0), it is their
    # behaviour; any other value is compared (and differs).
    if settings.get("exit_fade") == 0:
        settings.pop("exit_fade")
    # Added with the strain limit (issue 43); the recorded reports lack it. Off (0), it is their
    # behaviour; any other value is compared (and differs).
    if settings.get("strain_limit") == 0:
        settings.pop("strain_limit")
    # Added with the nearest way out (0.2); the recorded reports lack it. Along the normal, it is
    # their behaviour; the nearest way is compared (and differs).
    if settings.get("resolve_direction") == "normal":
        settings.pop("resolve_direction")
    # Added with the driver mesh check (issue 28); the recorded reports lack it. False (the
    # sample's driver passes the check) is their behaviour; true is compared (and differs).
    if settings.get("untrusted_driver") is False:
        settings.pop("untrusted_driver")
    for key in SETTINGS_PATHS:
        if settings.get(key):
            settings[key] = os.path.basename(settings[key])
    database = dict(report["database"])
    # Added for `eval --report` (issue 17 part 3): the cloth's vertex count, which the recorded
    # reports lack. Informational: it is the database's, whose content hash is compared.
    database.pop("driven_vertices", None)
    run = report.get("run", {"baked": report.get("baked"), "kept": report.get("skipped")})
    summary = {
        "baked": run["baked"],
        "skipped": run["kept"],
        "database": database,
        "settings": settings,
    }
    info = {"device": report["device"], "settings_hash": report["settings_hash"],
            "tool_version": report["tool_version"]}
    return summary, frames, info


def bake_all(cli, work, configs=None, devices=None, keep=False, log=print, float_text=None,
             since_recording=False, restamp=None):
    """Builds the database and runs every (config, device) bake with `cli`, one at a time.
    With since_recording, a configuration's SINCE_RECORDING flags follow its own. With
    `restamp` (config, device -> {attribute: value} or None), each EXR's hashes also hold its
    bytes restamped with those header values (golden_pixels.restamped_sha256).

    Returns {"database": {...}, "bakes": [{"config", "device", "flags", "summary", "frames",
    "exr", "posmap", "info", "seconds"}]}. Bake folders are removed after hashing unless keep.
    """
    configs = configs or [c[0] for c in CONFIGS]
    devices = devices or DEVICES
    os.makedirs(work, exist_ok=True)
    env = dict(os.environ)
    env.setdefault("POCL_CACHE_DIR", os.path.join(work, "pocl-cache"))
    os.makedirs(env["POCL_CACHE_DIR"], exist_ok=True)
    float_text = float_text or FloatText()

    db = os.path.join(work, "sleeve.dsdb")
    start = time.monotonic()
    db_later = DB_SINCE_RECORDING if since_recording else []
    run([cli] + expand(DB_FLAGS) + db_later + ["--quiet", "-o", db], os.path.join(work, "db.log"),
        env)
    result = {"database": {"seconds": round(time.monotonic() - start, 2)}, "bakes": []}
    log(f"database built in {result['database']['seconds']} s")

    table = {name: (flags, what) for name, flags, what in CONFIGS}
    for name in configs:
        flags, _ = table[name]
        for device in devices:
            folder = os.path.join(work, f"{name}-{device}")
            shutil.rmtree(folder, ignore_errors=True)
            os.makedirs(folder)
            pattern = os.path.join(folder, OUTPUT_NAME)
            later = SINCE_RECORDING.get(name, []) if since_recording else []
            cmd = [cli, "bake", "--db", db, "--driver", expand([BAKE_DRIVER])[0], "--frames",
                   BAKE_FRAMES, "--device", device, "-o", pattern] + expand(flags) + later
            start = time.monotonic()
            run(cmd, os.path.join(work, f"{name}-{device}.log"), env)
            seconds = time.monotonic() - start
            report = load_json(os.path.join(folder, "sleeve.report.json"), float_text)
            summary, frames, info = strip_report(report)
            if device != "host" and info["device"] == "host":
                raise RuntimeError(f"{name}/{device}: the bake ran on the host path, not OpenCL")
            stamp = restamp(name, device) if restamp else None
            exr = {}
            for frame in FRAMES:
                exr[str(frame)] = golden_pixels.exr_hashes(
                    golden_pixels.expand_pattern(pattern, frame), stamp)
            posmap = None
            if "--posmap" in flags:
                posmap = {}
                for frame in FRAMES:
                    posmap[str(frame)] = golden_pixels.exr_hashes(
                        golden_pixels.expand_pattern(os.path.join(folder, POSMAP_NAME), frame),
                        stamp)
            bake = {"config": name, "device": device, "flags": flags, "summary": summary,
                    "frames": frames, "exr": exr, "info": info, "seconds": round(seconds, 2)}
            if posmap is not None:
                bake["posmap"] = posmap
            result["bakes"].append(bake)
            log(f"{name} {device}: {len(frames)} frames in {seconds:.2f} s on {info['device']}")
            if not keep:
                shutil.rmtree(folder)
    result["database"]["report"] = result["bakes"][0]["summary"]["database"] if result[
        "bakes"] else None
    return result


def _kind(value):
    for kind in (bool, int, float, str, list, dict):
        if isinstance(value, kind):
            return kind
    return type(value)


def same_value(a, b):
    """Exact equality, JSON types included (0 is not 0.0, true is not 1); NaN equals NaN.
    Floats compare as doubles (the same double may be spelled with other digits)."""
    if _kind(a) is not _kind(b):
        return False
    if isinstance(a, float):
        return a == b or (math.isnan(a) and math.isnan(b))
    if isinstance(a, list):
        return len(a) == len(b) and all(same_value(x, y) for x, y in zip(a, b))
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(same_value(a[k], b[k]) for k in a)
    return a == b


def describe_difference(expected, actual, where, out, limit=8):
    """Appends to `out` up to `limit` lines naming the first differing leaves."""
    if len(out) >= limit:
        return
    if isinstance(expected, dict) and isinstance(actual, dict):
        for key in sorted(set(expected) | set(actual)):
            if key not in actual:
                out.append(f"{where}.{key}: missing (expected {short(expected[key])})")
            elif key not in expected:
                out.append(f"{where}.{key}: unexpected new field ({short(actual[key])})")
            elif not same_value(expected[key], actual[key]):
                describe_difference(expected[key], actual[key], f"{where}.{key}", out, limit)
            if len(out) >= limit:
                return
    elif isinstance(expected, list) and isinstance(actual, list) and len(expected) == len(actual):
        for i, (x, y) in enumerate(zip(expected, actual)):
            if not same_value(x, y):
                describe_difference(x, y, f"{where}[{i}]", out, limit)
            if len(out) >= limit:
                return
    else:
        out.append(f"{where}: expected {short(expected)}, got {short(actual)}")


def encode(value):
    """Compact JSON; a JsonFloat is written with the digits it was read with."""
    if isinstance(value, JsonFloat):
        return value.text
    if isinstance(value, float) and not isinstance(value, bool):
        if not math.isfinite(value):
            raise ValueError(f"non-finite float {value} cannot be stored in JSON")
        return repr(value)
    if isinstance(value, dict):
        return "{" + ",".join(json.dumps(k) + ":" + encode(v) for k, v in value.items()) + "}"
    if isinstance(value, (list, tuple)):
        return "[" + ",".join(encode(v) for v in value) + "]"
    return json.dumps(value)


def short(value, width=120):
    text = encode(value)
    return text if len(text) <= width else text[:width] + "..."


def dump(data, path, compact_depth=4):
    """JSON with the outer levels indented and deeper values on one line each (small diffs)."""
    def emit(value, depth, indent):
        if depth >= compact_depth or not isinstance(value, (dict, list)) or not value:
            return encode(value)
        pad = " " * (indent + 1)
        if isinstance(value, dict):
            items = [f"{pad}{json.dumps(k)}: {emit(v, depth + 1, indent + 1)}"
                     for k, v in value.items()]
            return "{\n" + ",\n".join(items) + "\n" + " " * indent + "}"
        items = [pad + emit(v, depth + 1, indent + 1) for v in value]
        return "[\n" + ",\n".join(items) + "\n" + " " * indent + "]"

    text = emit(data, 0, 0) + "\n"
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        f.write(text)
    os.replace(tmp, path)
