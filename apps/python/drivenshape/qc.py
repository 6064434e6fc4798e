# SPDX-License-Identifier: Apache-2.0
"""QC page of a bake: one HTML page with PNG plots that a supervisor opens in a browser.

    python -m drivenshape.qc --report out/cloth.report.json \\
        [--eval eval.json] [--mesh driven_rest.obj [--truth sim.pc2] [--bake out/cloth.####.exr]] \\
        [--units m|cm|mm|scene] [--title "sh010 cloth"] -o qc/sh010

The page reads every model a bake can run (the report's `settings.weights`) and says plainly
which one made the bake:

* the pose model (`model`, the default): its predicted mean vertex error per frame against the
  coverage tolerance, the frames over it (to simulate) and the shot's verdict;
* the QP blend (`qp`) and the nearest database shape (`nearest`): the weights over time and the
  relative residual;
* the rest binding (`bind`): neither (it solves nothing).

Whatever the model: the audit counts (cloth inside the driver after the correction and after
the resolution, vertices resolved) and the largest frame-to-frame jump per frame; with
`drivenshape eval --json` (--eval) the error to the truth per frame and, when eval had the
cloth's rest mesh, the strain of its edges per frame (bake, baseline, truth); with --mesh (the
driven rest OBJ) and a truth, the mean error per vertex over the frames and the bake's strain
per vertex as heat maps on the mesh. Caches
and meshes are read with the module's readers (open_point_cache, read_obj). Lengths are shown in
mm (--units names the scene's unit, metres by default; --units scene shows them as stored).

The page (DIR/index.html, images DIR/*.png, relative links, no JavaScript) is drawn in a
temporary folder inside DIR and each file renamed into place, the page last. DIR may be any
folder (the shot's, beside the bake's frames and report): the page writes only its own files,
replaces only those an earlier page wrote (listed with their content in DIR/.drivenshape-qc.json)
and leaves everything else; a name of the page taken by another file is refused. Needs numpy and
matplotlib (scripts/requirements.txt). Exit codes: 0 ok, 2 usage, 3 input, 4 output.
"""

from __future__ import annotations

import argparse
import datetime
import hashlib
import html
import json
import os
import re
import shutil
import stat
import sys
import tempfile
from collections.abc import Callable, Iterable, Sequence
from typing import TYPE_CHECKING, Any, ClassVar, Optional, TypedDict

import numpy as np
import numpy.typing as npt

from . import (Error, Mesh, PointCache, _files, edge_strain, format_frame_range,
               merge_bake_reports, open_point_cache, read_obj, settings_table, verdict_holds)

if TYPE_CHECKING:  # matplotlib is imported where the plots are drawn, not with the module
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

EXIT_USAGE: int = 2
EXIT_INPUT: int = 3
EXIT_OUTPUT: int = 4
GENERATOR: str = "drivenshape qc"
WORST_FRAMES: int = 5
FRAMES_PER_READ: int = 32
# Relative tolerance of the per-frame mean error computed here against the eval JSON's (both
# are means of float32 distances; a larger gap means the caches are not the ones eval compared).
EVAL_MATCH_TOLERANCE: float = 1e-3

# The types of the signatures below.
_Json = dict[str, Any]  # a JSON object: a bake report, an eval JSON, one of their records
_ErrorFrames = dict[int, tuple[float, float]]  # {frame: (mean, max)} distance to the truth
_Float64Array = npt.NDArray[np.float64]
_FrameArray = npt.NDArray[Any]  # frame numbers: integers (float64 when empty)


class _VertexErrors(TypedDict):
    """vertex_errors(): the caches' distance per vertex and per frame, and their strain."""

    mesh: Mesh
    mean: _Float64Array  # (V,) mean over the frames
    per_frame: dict[int, tuple[float, float, int]]  # {frame: (mean, max, argmax)}
    strain: _Float64Array  # (V,) the bake's VertexStrain over the frames
    truth_strain: _Float64Array  # (V,) the truth's
    truth: str
    bake: str
    frames: list[int]


# What each value of the report's settings.weights means, for the page's first lines.
MODELS: dict[str, tuple[str, str]] = {
    "model": ("the pose model",
              "the rest binding plus the pose model's learned correction (the default, "
              "<code>--weights auto</code> on a database with a pose model)"),
    "qp": ("the QP blend",
           "the 2008 DrivenShape blend: per frame, weights of the database shapes from a "
           "quadratic programme (<code>--weights qp</code>)"),
    "nearest": ("the nearest database shape",
                "a baseline: per frame, the one database shape closest to the pose "
                "(<code>--weights nearest</code>)"),
    "bind": ("the rest binding",
             "a baseline: the rest cloth bound to the rest driver and carried along, like "
             "Point Deform; nothing is solved (<code>--weights bind</code>)"),
}
# The models with weights and a residual per frame.
SOLVING_MODELS: tuple[str, ...] = ("qp", "nearest")


class QcError(Exception):
    def __init__(self, code: int, message: str) -> None:
        super().__init__(message)
        self.code = code


class Units:
    """Lengths as the page shows them: mm with one decimal (the truth's own spread is several
    mm), or scene units with 4 significant digits (--units scene)."""

    SCALES: ClassVar[dict[str, float]] = {"m": 1000.0, "cm": 10.0, "mm": 1.0}

    def __init__(self, name: str) -> None:
        self.scale = self.SCALES.get(name, 1.0)
        self.unit = "mm" if name in self.SCALES else "scene units"

    def value(self, length: Optional[float]) -> Optional[float]:
        return None if length is None else length * self.scale

    def text(self, length: Optional[float]) -> str:
        if length is None:
            return "-"
        if self.unit == "mm":
            return f"{length * self.scale:.1f}"
        return f"{length:.4g}"

    def with_unit(self, length: Optional[float]) -> str:
        return f"{self.text(length)} {self.unit}"


def ratio_text(value: Optional[float]) -> str:
    """A relative figure (residual, weight ratio): 3 significant digits."""
    return "-" if value is None else f"{value:.3g}"


def count_text(value: Optional[float]) -> str:
    return "-" if value is None else str(int(value))


def percent_text(fraction: float) -> str:
    return f"{100.0 * fraction:.0f}%"


def strain_text(fraction: float) -> str:
    """A strain figure (a fraction) in percent, 3 significant digits, without the sign."""
    return f"{100.0 * fraction:.3g}"


# ---- inputs ----------------------------------------------------------------------------------

# The largest magnitude a number of a report or an eval JSON may have: far beyond any length or
# count a bake writes, and small enough that the page's scaling (lengths x 1000 in mm, plot
# margins) stays finite.
LARGEST_NUMBER = 1e300


def _finite_float(text: str) -> float:
    value = float(text)
    if not abs(value) <= LARGEST_NUMBER:
        raise ValueError(f"the number {text} is out of range")
    return value


def _finite_int(text: str) -> int:
    value = int(text)
    if not abs(value) <= LARGEST_NUMBER:
        raise ValueError(f"the number {text[:20]}... is out of range")
    return value


def _no_constant(name: str) -> float:
    raise ValueError(f"{name} is not a number JSON allows")


# The largest report or eval JSON read (a bake report of 10 000 frames with the weights of 200
# shapes is about 40 MB); parsing takes several times the file's size in memory.
JSON_LIMIT: int = 256 << 20


def load_json(path: str, what: str) -> Any:
    """The JSON of the regular file `path`: anything else (a FIFO, a device, a folder) is refused
    without waiting on it, as are files over JSON_LIMIT, text that is not JSON, nesting deeper
    than Python parses, and numbers the page cannot scale (NaN, Infinity, beyond 1e300)."""
    def refuse(message: str) -> QcError:
        return QcError(EXIT_INPUT, f"{what} {message}")

    try:
        with _files.open_regular(path, JSON_LIMIT, refuse) as stream:
            text = stream.read().decode("utf-8")
        return json.loads(text, parse_float=_finite_float, parse_int=_finite_int,
                          parse_constant=_no_constant)
    except OSError as error:
        raise QcError(EXIT_INPUT, f"cannot read {what} '{path}': {error.strerror}")
    except RecursionError:
        raise QcError(EXIT_INPUT, f"{what} '{path}' is not valid JSON: nested too deeply")
    except (UnicodeDecodeError, json.JSONDecodeError, ValueError) as error:
        raise QcError(EXIT_INPUT, f"{what} '{path}' is not valid JSON: {error}")


def require(condition: object, path: str, message: str) -> None:
    if not condition:
        raise QcError(EXIT_INPUT, f"'{path}': {message}")


# Where a frame of a spliced shot comes from (drivenshape simulate's report), and its colour on
# the timeline.
SOURCE_COLOURS = {"baked": "0.78", "blended": "tab:olive", "simulated": "tab:green"}


def load_simulate_report(path: str, report: _Json) -> dict[int, str]:
    """Each frame's source (baked, simulated, blended) from `drivenshape simulate`'s report
    (format drivenshape-simulate-report, version 1): every frame of the bake report must have
    one."""
    data = load_json(path, "simulate report")
    require(isinstance(data, dict) and data.get("format") == "drivenshape-simulate-report", path,
            "is not the report of drivenshape simulate (format drivenshape-simulate-report)")
    require(data.get("version") == 1, path,
            f"is version {data.get('version')!r}; this page reads version 1")
    frames = data.get("frames")
    require(isinstance(frames, list) and frames, path, "has no frames")
    sources: dict[int, str] = {}
    for i, entry in enumerate(frames):
        require(isinstance(entry, dict) and isinstance(entry.get("frame"), int)
                and entry.get("source") in SOURCE_COLOURS, path,
                f"frames[{i}] is not {{frame, source}} with a source of baked, simulated or "
                "blended")
        require(entry["frame"] not in sources, path, f"lists frame {entry['frame']} twice")
        sources[entry["frame"]] = entry["source"]
    missing = sorted({r["frame"] for r in report["frames"]} - sources.keys())
    require(not missing, path, f"has no source for frame {missing[0] if missing else 0} of the "
            "bake report: give the simulate report of this bake")
    return sources


def is_number(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def residual_key(report: _Json) -> str:
    """The frame records' relative residual: relative_residual_direct (from the shapes) since
    0.2.0; a report of 0.1.0 has only the QP's own relative_residual."""
    records = [r for r in report["frames"] if isinstance(r, dict) and not r.get("skipped")]
    if records and all("relative_residual_direct" not in r for r in records):
        return "relative_residual"
    return "relative_residual_direct"


# The optional fields the page reads, per object of the report (docs/schemas/
# bake_report.schema.json), and the JSON type each must have when present: a report of another
# shape is refused naming the field rather than failing halfway through the page.
_NUMBER = (int, float)
OPTIONAL_FIELDS: dict[str, dict[str, Any]] = {
    "": {"output": str, "driver_cache": str, "device": str, "tool": str, "tool_version": str,
         "settings_hash": str, "seconds": dict, "warnings": list, "coverage": dict},
    "database": {"content_hash": str, "shape_count": int, "frames": list},
    "settings": {"max_weight_change": _NUMBER, "regions": list, "regions_file": str,
                 "binding_mask": str, "layers": dict, "batch": int, "compression": str,
                 "resolve_direction": str, "skin_offset": _NUMBER, "exit_fade": _NUMBER,
                 "pose_model": dict},
    "settings.pose_model": {"cross_validation_error": _NUMBER, "binding_error": _NUMBER},
    "coverage": {"level": _NUMBER},
}


_TYPE_NAMES = {str: "a string", int: "an integer", dict: "an object", list: "a list",
               _NUMBER: "a number"}


# ... and in each baked frame's record.
RECORD_FIELDS: dict[str, Any] = {
    "inside_before": int, "inside_corrected": int, "inside_after": int, "resolved": int,
    "max_jump": _NUMBER, "error_bound": _NUMBER, "pose_distance": _NUMBER,
}


def check_fields(holder: _Json, fields: dict[str, Any], where: str, path: str) -> None:
    """`fields` of `holder`, when present, with their types (null and booleans are none of
    them); `where` names the holder in the message."""
    for key, kind in fields.items():
        value = holder.get(key)
        require(key not in holder or (isinstance(value, kind) and not isinstance(value, bool)),
                path, f"{where}{key} is {json.dumps(value)[:60]}; expected {_TYPE_NAMES[kind]}")


def check_optional_fields(report: _Json, path: str) -> None:
    """OPTIONAL_FIELDS and every baked frame's RECORD_FIELDS (check_fields)."""
    for where, fields in OPTIONAL_FIELDS.items():
        holder = report
        for key in where.split(".") if where else []:
            holder = holder.get(key, {})  # an object when present (checked a level up)
        check_fields(holder, fields, f"{where}." if where else "", path)
    require(all(isinstance(w, str) for w in report.get("warnings", [])), path,
            "warnings holds something other than sentences (strings)")
    for record in report["frames"]:
        if not record.get("skipped"):
            check_fields(record, RECORD_FIELDS, f"frame {record['frame']}: ", path)


def load_report(path: str) -> _Json:
    """A bake report (docs/schemas/bake_report.schema.json), checked for what the page reads."""
    report: _Json = load_json(path, "bake report")  # checked next
    require(isinstance(report, dict) and isinstance(report.get("frames"), list), path,
            "not a drivenshape bake report (no 'frames' list)")
    for key in ("database", "settings"):
        require(isinstance(report.get(key), dict), path, f"no '{key}' object; is this a "
                "report written by `drivenshape bake`?")
    model = report["settings"].get("weights")
    require(isinstance(model, str) and model in MODELS, path,
            f"settings.weights is {json.dumps(model)}; expected one of {', '.join(MODELS)} (a "
            "report of `drivenshape bake`)")
    for index, record in enumerate(report["frames"]):
        require(isinstance(record, dict) and isinstance(record.get("frame"), int), path,
                f"frame record {index} has no integer 'frame'")
    check_optional_fields(report, path)
    residual = residual_key(report)
    for record in report["frames"]:
        if record.get("skipped"):
            continue
        if model in SOLVING_MODELS:
            require("weights" in record and is_number(record.get(residual)),
                    path, f"frame {record['frame']} of a --weights {model} bake has no "
                    f"'weights' or no number '{residual}'")
            check_weights(record, report["database"].get("shape_count"), path)
        if model == "model":
            require(is_number(record.get("predicted_error"))
                    and isinstance(record.get("coverage"), dict)
                    and isinstance(record["coverage"].get("flagged"), bool), path,
                    f"frame {record['frame']} of a pose-model bake has no number "
                    "'predicted_error' or no coverage.flagged")
    if model == "model" and any(not r.get("skipped") for r in report["frames"]):
        require(is_number(report["settings"].get("coverage_tolerance")), path,
                "a pose-model bake without a number settings.coverage_tolerance")
    return report


def check_weights(record: _Json, shape_count: object, path: str) -> None:
    """A frame's weights: k numbers, or one list of k per region."""
    weights = record["weights"]
    rows = weights if isinstance(weights, list) and weights and isinstance(weights[0], list) \
        else [weights]
    for row in rows:
        require(isinstance(row, list) and all(is_number(w) for w in row)
                and len(row) == shape_count, path,
                f"frame {record['frame']}: the weights are not {shape_count} numbers (the "
                "database's shape_count) per region")


def merge_reports(paths: Sequence[str]) -> _Json:
    """One report from the reports of parts of one bake (farm chunks), as the library merges
    them (drivenshape.merge_bake_reports): every frame once, the verdict over all of them."""
    reports = [load_report(path) for path in paths]
    if len(reports) == 1:
        return reports[0]
    try:
        text = merge_bake_reports([json.dumps(r) for r in reports], list(paths))
    except Error as error:
        raise QcError(EXIT_INPUT, str(error)) from None
    merged: _Json = json.loads(text)
    return merged


# The eval JSON's fields the page reads (`drivenshape eval --json`), where they are, and what
# each must be: a JSON of another shape is refused naming the field, never drawn as if fine.
_LENGTH = "a length (a number >= 0)"
_LENGTH_OR_NULL = "a length or null"
_COUNT = "a count (an integer >= 0)"
_TEXT_OR_NULL = "a string or null"
_BOOLEAN = "a boolean"
_STRAIN = "a strain magnitude (a number >= 0)"
_SHARE = "a share (a number from 0 to 1)"
# A sequence's strain figures (issue 43), in its summary and in each frame's record: fractions,
# mean |strain|, its nearest-rank 95th percentile, the share of edges with |strain| > 0.1.
STRAIN_FIELDS: dict[str, str] = {"strain_mean": _STRAIN, "strain_p95": _STRAIN,
                                 "strain_share_over_10pct": _SHARE}
EVAL_FIELDS: dict[str, dict[str, str]] = {
    "": {"mean": _LENGTH, "rms": _LENGTH, "max": _LENGTH, "vertices": "an integer >= 1",
         "truth": _TEXT_OR_NULL, "bake": _TEXT_OR_NULL, "device": _TEXT_OR_NULL,
         "summary": "an object", "baseline": _BOOLEAN, "strain": _BOOLEAN, "edges": _COUNT,
         "zero_length_edges": _COUNT},
    "summary": {"bake": "an object", "truth": "an object", "baseline": "an object"},
    "summary.bake": {"max_jump": _LENGTH_OR_NULL, "mean_inside": "a number >= 0 or null",
                     **STRAIN_FIELDS},
    "summary.truth": {"max_jump": _LENGTH_OR_NULL, **STRAIN_FIELDS},
    "summary.baseline": {"mean": _LENGTH, **STRAIN_FIELDS},
}
EVAL_RECORD_FIELDS: dict[str, dict[str, str]] = {
    "": {"mean": _LENGTH, "max": _LENGTH, "rms": _LENGTH, "max_vertex": _COUNT,
         "bake": "an object", "truth": "an object", "baseline": "an object"},
    "bake": dict(STRAIN_FIELDS),
    "truth": {"jump": _LENGTH_OR_NULL, **STRAIN_FIELDS},
    "baseline": {"mean": _LENGTH, **STRAIN_FIELDS},
}
# Room for rounding between figures eval computes in double from the same distances, and
# between its mean over every vertex of every frame and the average of its frames' means.
_ROUNDING = 1e-9
_MEAN_AGREEMENT = 1e-6


def _fits(value: object, kind: str) -> bool:
    """Whether `value` is what EVAL_FIELDS' `kind` says."""
    if kind.endswith("or null") and value is None:
        return True
    if kind.startswith("a string"):
        return isinstance(value, str)
    if kind == "an object":
        return isinstance(value, dict)
    if kind == _BOOLEAN:
        return isinstance(value, bool)
    if kind == _SHARE:
        return is_number(value) and 0 <= value <= 1  # type: ignore[operator]
    if kind.startswith(("an integer", "a count")):
        return isinstance(value, int) and not isinstance(value, bool) and \
            value >= (1 if ">= 1" in kind else 0)
    return is_number(value) and value >= 0  # type: ignore[operator]


def check_eval_fields(holder: _Json, fields: dict[str, dict[str, str]], where: str,
                      path: str, required: Iterable[str] = ()) -> None:
    """Each of `fields` (by the dotted place of its object in `holder`), when present, is what
    it says; those `required` (dotted) are present. `where` starts the messages."""
    for place, kinds in fields.items():
        node: Any = holder
        for key in place.split(".") if place else []:
            node = node.get(key, {})  # an object when present (checked a level up)
        for key, kind in kinds.items():
            name = f"{place}.{key}" if place else key
            require(key in node or name not in required, path, f"{where}no '{name}'")
            require(key not in node or _fits(node[key], kind), path,
                    f"{where}{name} is {json.dumps(node.get(key))[:60]}; expected {kind}")


def _eval_frames(data: _Json, path: str) -> list[int]:
    """The eval's frame records, each checked; their frame numbers."""
    records: Any = data.get("frames")
    require(isinstance(records, list) and records, path,
            "not the JSON of `drivenshape eval --json` (no 'frames' list, or an empty one)")
    frames: list[int] = []
    for index, record in enumerate(records):
        frame: Any = record.get("frame") if isinstance(record, dict) else None
        require(isinstance(frame, int) and not isinstance(frame, bool)
                and -2**31 <= frame < 2**31, path, f"frame record {index} has no integer "
                "'frame'")
        check_eval_fields(record, EVAL_RECORD_FIELDS, f"frame {frame}: ", path,
                          ("mean", "max"))
        require(record["mean"] <= record["max"] * (1 + _ROUNDING), path,
                f"frame {frame}: mean {record['mean']} is over max {record['max']}")
        frames.append(frame)
    repeated = len(frames) - len(set(frames))
    require(not repeated, path, f"frames lists {repeated} frame(s) twice")
    return frames


def load_eval(path: str) -> _Json:
    """`drivenshape eval --json`, checked for what the page reads: every field it shows of the
    right type, lengths >= 0, frames listed once, and the shot's figures those of its frames
    (max_frame one of them, max their largest max, mean <= rms <= max)."""
    data: _Json = load_json(path, "eval JSON")  # checked next
    require(isinstance(data, dict), path, "not the JSON of `drivenshape eval --json` (not an "
                                          "object)")
    frames = _eval_frames(data, path)
    check_eval_fields(data, EVAL_FIELDS, "", path, ("mean", "rms", "max"))
    require(data.get("max_frame") in frames and not isinstance(data.get("max_frame"), bool),
            path, f"max_frame is {json.dumps(data.get('max_frame'))[:60]}; expected one of "
                  "its frames")
    largest = max(r["max"] for r in data["frames"])
    require(abs(data["max"] - largest) <= _ROUNDING * largest, path,
            f"max is {data['max']} but the largest of its frames' max is {largest}")
    average = mean_of([r["mean"] for r in data["frames"]])
    require(abs(data["mean"] - average) <= _MEAN_AGREEMENT * average, path,
            f"mean is {data['mean']} but its frames' means average {average}")
    require(data["mean"] <= data["rms"] * (1 + _ROUNDING)
            and data["rms"] <= data["max"] * (1 + _ROUNDING), path,
            f"mean {data['mean']}, rms {data['rms']} and max {data['max']} are not in that "
            "order")
    if data.get("strain") is True:
        check_eval_strain(data, path)
    return data


def strain_sequences(evaluation: _Json) -> tuple[str, ...]:
    """The sequences an eval JSON measured the strain of: none without `strain`; the bake and
    the truth, and the baseline when it has one."""
    if evaluation.get("strain") is not True:
        return ()
    return ("bake", "truth", "baseline") if evaluation.get("baseline") is True else (
        "bake", "truth")


def check_eval_strain(data: _Json, path: str) -> None:
    """An eval with `strain` true: every strain field of every sequence, in its summary and in
    each frame, and the summary's figures those of its frames (each frame covers every edge
    once: the summary's mean and share are the frames' averaged, and its percentile lies
    between theirs)."""
    require(is_number(data.get("edges")) and data["edges"] >= 1, path,
            f"edges is {json.dumps(data.get('edges'))[:60]}; expected the edges the strain "
            "covers (an integer >= 1)")
    for sequence in strain_sequences(data):
        place = f"summary.{sequence}"
        check_eval_fields(data, {place: STRAIN_FIELDS}, "", path,
                          [f"{place}.{key}" for key in STRAIN_FIELDS])
        for record in data["frames"]:
            check_eval_fields(record, {sequence: STRAIN_FIELDS}, f"frame {record['frame']}: ",
                              path, [f"{sequence}.{key}" for key in STRAIN_FIELDS])
        shot = data["summary"][sequence]
        frames = [r[sequence] for r in data["frames"]]
        for key, agreement in (("strain_mean", _MEAN_AGREEMENT), ("strain_share_over_10pct",
                                                                   _ROUNDING)):
            average = mean_of([f[key] for f in frames])
            require(abs(shot[key] - average) <= agreement * average + 1e-12, path,
                    f"{place}.{key} is {shot[key]} but its frames' average {average}")
        p95 = [f["strain_p95"] for f in frames]
        require(min(p95) * (1 - _ROUNDING) <= shot["strain_p95"] <= max(p95) * (1 + _ROUNDING),
                path, f"{place}.strain_p95 is {shot['strain_p95']}, outside its frames' "
                      f"{min(p95)} to {max(p95)}")


def check_eval_matches(report: _Json, evaluation: _Json, eval_path: str) -> None:
    """The eval is of the report's cloth: the same vertex count when both state it."""
    cloth = report["database"].get("driven_vertices")
    vertices = evaluation.get("vertices")
    require(not isinstance(cloth, int) or vertices is None or vertices == cloth, eval_path,
            f"an eval of {vertices} cloth vertices, but the bake report's cloth has {cloth}: "
            "give the eval of this bake")


class Coverage:
    """The pose model's prediction per baked frame and the shot's verdict, from the frames
    (so merged farm chunks get one verdict over all of them)."""

    def __init__(self, report: _Json) -> None:
        # A number when any frame was predicted (load_report checks it): read only then.
        self.tolerance: float = report["settings"].get("coverage_tolerance")
        # The share of frames the error bound was calibrated to hold for (0 before 0.2.0).
        stated = report.get("coverage")
        self.level: float = float(stated.get("level", 0.0)) if isinstance(stated, dict) else 0.0
        # frame -> predicted mean vertex error (scene units)
        self.predicted: dict[int, float] = {}
        # frame -> the verdict's error bound (the predicted error in a report before 0.2.0)
        self.bound: dict[int, float] = {}
        self.flagged: list[int] = []
        for record in report["frames"]:
            if record.get("skipped") or not is_number(record.get("predicted_error")):
                continue
            self.predicted[record["frame"]] = float(record["predicted_error"])
            bound = record.get("error_bound")
            self.bound[record["frame"]] = float(bound if is_number(bound)
                                                else record["predicted_error"])
            if record["coverage"]["flagged"]:
                self.flagged.append(record["frame"])

    def __bool__(self) -> bool:
        return bool(self.predicted)

    @property
    def covered_fraction(self) -> float:
        return 1.0 - len(self.flagged) / len(self.predicted)

    @property
    def enough(self) -> bool:
        return not self.flagged

    def against_truth(self, error_frames: _ErrorFrames
                      ) -> Optional[tuple[float, list[int], int]]:
        """(true mean error of the frames judged enough, [enough frames whose true mean error
        is over the tolerance], how many frames are judged enough) from the eval's per-frame
        errors; None without them."""
        enough = [f for f in sorted(self.predicted) if f not in self.flagged and f in error_frames]
        if not enough:
            return None
        true_error = mean_of([error_frames[f][0] for f in enough])
        return true_error, [f for f in enough if error_frames[f][0] > self.tolerance], len(enough)

    def holds(self, checked: tuple[float, list[int], int]) -> bool:
        """Whether the verdict holds against the truth: at least `level` of the frames judged
        enough are truly within the tolerance (a report without a level: their true mean
        error is within it): the library's rule, as `drivenshape eval --report` judges it."""
        true_error, missed, count = checked
        return verdict_holds(count, len(missed), true_error, self.tolerance, self.level)

    def verdict(self, units: Units) -> str:
        tolerance = units.with_unit(self.tolerance)
        if self.enough:
            return (f"DrivenShape is enough: all {len(self.predicted)} frames have their error "
                    f"bound within the {tolerance} tolerance")
        return (f"simulate {format_frame_range(self.flagged)}: {len(self.flagged)} of "
                f"{len(self.predicted)} frames have their error bound over the {tolerance} "
                "tolerance")


def open_cache(candidates: Iterable[str], what: str, option: str) -> tuple[PointCache, str]:
    """The first candidate path that opens as a point cache; an input error naming them all."""
    errors = []
    for path in dict.fromkeys(candidates):
        try:
            return open_point_cache(path), path
        except Error as error:
            errors.append(f"'{path}': {error}")
    raise QcError(EXIT_INPUT, f"cannot open the {what} ({'; '.join(errors)}); give it with "
                              f"{option}")


def beside(path: str, json_path: str) -> list[str]:
    """Candidates for a path a JSON names: as given, then its file name beside the JSON."""
    candidates = [path]
    if not os.path.isabs(path):
        candidates.append(os.path.join(os.path.dirname(os.path.abspath(json_path)),
                                       os.path.basename(path)))
    return candidates


class VertexStrain:
    """The strain per vertex of a cloth over frames: on each frame, the largest |strain| of the
    vertex's edges (|edge| / |rest edge| - 1 against the rest mesh, the module's edge_strain
    over Mesh.edges, those of zero rest length left out as eval leaves them out); mean() is its
    mean over the frames added. A vertex on no edge has 0."""

    def __init__(self, mesh: Mesh) -> None:
        rest = np.asarray(mesh.positions, dtype=np.float64)
        edges = np.asarray(mesh.edges)
        length = np.linalg.norm(rest[edges[:, 1]] - rest[edges[:, 0]], axis=1)
        self.rest = mesh.positions
        self.edges = np.ascontiguousarray(edges[length > 0])
        # Both ends of every edge, grouped by vertex: one maximum.reduceat per frame.
        ends = self.edges.T.reshape(-1)
        self.order = np.argsort(ends, kind="stable")
        self.vertices, self.starts = np.unique(ends[self.order], return_index=True)
        self.total = np.zeros(mesh.vertex_count)
        self.frames = 0

    def add(self, positions: npt.NDArray[np.float32]) -> None:
        self.frames += 1
        if len(self.edges):
            magnitude = np.abs(edge_strain(self.rest, positions, self.edges))
            both = np.concatenate([magnitude, magnitude])[self.order]
            self.total[self.vertices] += np.maximum.reduceat(both, self.starts)

    def mean(self) -> _Float64Array:
        return self.total / max(self.frames, 1)


def vertex_errors(args: argparse.Namespace, report: _Json, evaluation: Optional[_Json],
                  frames: list[int]) -> _VertexErrors:
    """Per-vertex mean error over `frames` and the per-frame mean/max/argmax, from the caches
    (read with the module's point-cache readers)."""
    if args.truth:
        truth_candidates = [args.truth]
    elif evaluation and evaluation.get("truth"):
        truth_candidates = beside(evaluation["truth"], args.eval)
    else:
        raise QcError(EXIT_USAGE, "the heat map needs the truth: give --truth CACHE or --eval")
    if args.bake:
        bake_candidates = [args.bake]
    else:
        bake_candidates = []
        if evaluation and evaluation.get("bake"):
            bake_candidates += beside(evaluation["bake"], args.eval)
        if report.get("output"):
            bake_candidates += beside(report["output"], args.report[0])
    truth, truth_path = open_cache(truth_candidates, "truth cache", "--truth")
    bake, bake_path = open_cache(bake_candidates, "baked cache", "--bake")
    try:
        mesh = read_obj(args.mesh)
    except Error as error:
        raise QcError(EXIT_INPUT, str(error))
    for cache, path in ((truth, truth_path), (bake, bake_path)):
        if cache.vertex_count != mesh.vertex_count:
            raise QcError(EXIT_INPUT, f"'{path}' holds {cache.vertex_count} vertices but the "
                                      f"mesh '{args.mesh}' has {mesh.vertex_count}")
    total = np.zeros(mesh.vertex_count)
    per_frame: dict[int, tuple[float, float, int]] = {}
    strain, truth_strain = VertexStrain(mesh), VertexStrain(mesh)
    for start in range(0, len(frames), FRAMES_PER_READ):
        chunk = frames[start:start + FRAMES_PER_READ]
        try:
            a = bake.read_frames(chunk)
            b = truth.read_frames(chunk)
            for i in range(len(chunk)):
                strain.add(a[i])
                truth_strain.add(b[i])
        except Error as error:
            raise QcError(EXIT_INPUT, str(error))
        distance = np.linalg.norm(a.astype(np.float64) - b, axis=2)
        total += distance.sum(axis=0)
        for frame, row in zip(chunk, distance):
            per_frame[frame] = (float(row.mean()), float(row.max()), int(row.argmax()))
    return {"mesh": mesh, "mean": total / len(frames), "per_frame": per_frame,
            "strain": strain.mean(), "truth_strain": truth_strain.mean(),
            "truth": truth_path, "bake": bake_path, "frames": frames}


def check_against_eval(errors: _VertexErrors, evaluation: _Json, eval_path: str) -> None:
    for record in evaluation["frames"]:
        mine = errors["per_frame"].get(record["frame"])
        if mine is None:
            continue
        gap = abs(mine[0] - record["mean"])
        if gap > EVAL_MATCH_TOLERANCE * max(abs(record["mean"]), 1e-12):
            raise QcError(EXIT_INPUT, f"the truth '{errors['truth']}' and the bake "
                                      f"'{errors['bake']}' give a mean error of {mine[0]:.6g} at "
                                      f"frame {record['frame']}, '{eval_path}' says "
                                      f"{record['mean']:.6g}: give the caches eval compared "
                                      "(--truth, --bake)")


# ---- figures ---------------------------------------------------------------------------------

# Every plot over time has the same width, axes margins (room on the right for the legend) and
# frame range, so a frame sits at the same place in every plot down the page.
FIGURE_WIDTH: float = 11.0
MARGINS: dict[str, float] = {"left": 0.07, "right": 0.79}
SHAPE_COLOURS: tuple[str, ...] = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple",
                                  "tab:brown", "tab:pink", "tab:olive", "tab:cyan", "#393b79")
OTHERS_COLOUR: str = "0.82"
FLAG_COLOUR: str = "tab:red"
MIN_SHOWN_WEIGHT: float = 0.01  # shapes whose weight never reaches it are summed into "others"


class Plots:
    """Writes the PNGs into one folder; each method returns the file name, or None when the
    inputs hold nothing to draw."""

    def __init__(self, folder: str, frames: Sequence[int], flagged: list[int],
                 units: Units) -> None:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        plt.rcParams.update({"font.size": 10, "axes.grid": True, "grid.alpha": 0.3,
                             "axes.spines.top": False, "axes.spines.right": False})
        self.plt = plt
        self.folder = folder
        self.frame_range = (min(frames), max(frames)) if frames else (0, 1)
        self.flagged = flagged
        self.units = units

    def figure(self, height: float, rows: int = 1) -> tuple[Figure, list[Axes]]:
        fig, axes = self.plt.subplots(rows, 1, figsize=(FIGURE_WIDTH, height), sharex=True,
                                      squeeze=False)
        top = 1.0 - 0.4 / height
        fig.subplots_adjust(bottom=0.5 / height, top=top, hspace=0.35, **MARGINS)
        return fig, list(axes[:, 0])

    def dress(self, axes: Axes, ylabel: str, title: str) -> None:
        """The common dressing of a plot over frames; frames over the coverage tolerance are
        shaded."""
        for frame in self.flagged:
            axes.axvspan(frame - 0.5, frame + 0.5, color=FLAG_COLOUR, alpha=0.12, lw=0)
        axes.set_xlim(self.frame_range[0] - 0.5, self.frame_range[1] + 0.5)
        axes.set_ylabel(ylabel)
        axes.set_title(title, loc="left")
        if axes.get_legend_handles_labels()[0]:
            axes.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)

    def save(self, fig: Figure, axes: Axes, name: str) -> str:
        axes.set_xlabel("frame")
        fig.savefig(os.path.join(self.folder, name), dpi=100)
        self.plt.close(fig)
        return name

    def coverage(self, coverage: Optional[Coverage],
                 error_frames: _ErrorFrames) -> Optional[str]:
        """The pose model's predicted error and error bound per frame, the tolerance as a line,
        the frames whose bound is over it circled in red, and the true mean error when an eval
        gives it."""
        if not coverage:
            return None
        units = self.units
        frames = np.array(sorted(coverage.predicted))
        predicted = np.array([coverage.predicted[f] for f in frames]) * units.scale
        tolerance = coverage.tolerance * units.scale
        fig, (axes,) = self.figure(3.4)
        bound = np.array([coverage.bound[f] for f in frames]) * units.scale
        axes.plot(frames, predicted, ".-", color="tab:blue", label="predicted mean error")
        level = percent_text(coverage.level) if coverage.level > 0 else "= prediction"
        axes.plot(frames, bound, "-", color="tab:orange", label=f"error bound ({level})")
        top = max(float(bound.max()), tolerance)
        if error_frames:
            t_frames = np.array(sorted(error_frames))
            true_mean = np.array([error_frames[f][0] for f in t_frames]) * units.scale
            axes.plot(t_frames, true_mean, "--", color="0.35", label="true mean error (eval)")
            top = max(top, float(true_mean.max()))
        axes.axhline(tolerance, color=FLAG_COLOUR, ls="--", lw=1.3,
                     label=f"tolerance {units.with_unit(coverage.tolerance)}")
        if coverage.flagged:
            over = np.array([coverage.bound[f] for f in coverage.flagged]) * units.scale
            axes.plot(coverage.flagged, over, "o", ms=8, mfc="none", mec=FLAG_COLOUR, mew=1.5,
                      label=f"over: simulate ({len(coverage.flagged)})")
        axes.set_ylim(0, top * 1.15)
        self.dress(axes, f"mean vertex error ({units.unit})",
                   "Pose model: predicted mean vertex error and its bound per frame against the "
                   "coverage tolerance")
        return self.save(fig, axes, "coverage.png")

    def weights(self, report: _Json, model: str) -> Optional[str]:
        blocks = weight_blocks(report)
        if not blocks:
            return None
        db_frames = report["database"].get("frames") or []
        # One colour per shape on every region's plot: the shapes with the largest peak weight
        # over all regions get the colours, the rest is summed as "others".
        peak = np.max([weights.max(axis=0) for _, _, weights in blocks], axis=0)
        ranked = [s for s in np.argsort(-peak, kind="stable") if peak[s] >= MIN_SHOWN_WEIGHT]
        colour = {s: c for s, c in zip(sorted(ranked[:len(SHAPE_COLOURS)]), SHAPE_COLOURS)}
        fig, axes_list = self.figure(3.4 * len(blocks), rows=len(blocks))
        what = ("QP weights of the database shapes" if model == "qp"
                else "The nearest database shape")
        for (title, frames, weights), axes in zip(blocks, axes_list):
            k = weights.shape[1]
            shown = [s for s in colour if weights[:, s].max() >= MIN_SHOWN_WEIGHT]
            rest = [s for s in range(k) if s not in shown]
            layers = [weights[:, s] for s in shown]
            labels = [f"shape {s}" + (f" (db frame {db_frames[s]})" if s < len(db_frames)
                                      else "") for s in shown]
            colours = [colour[s] for s in shown]
            if rest:
                layers.append(weights[:, rest].sum(axis=1))
                labels.append(f"{len(rest)} others")
                colours.append(OTHERS_COLOUR)
            # Each frame a full-width block: steps at the midpoints between frames.
            edges = np.concatenate([[frames[0] - 0.5], (frames[:-1] + frames[1:]) / 2.0,
                                    [frames[-1] + 0.5]])
            layers = [np.append(layer, layer[-1]) for layer in layers]
            axes.stackplot(edges, *layers, labels=labels, colors=colours, step="post")
            axes.set_ylim(0, max(1.0, float(weights.sum(axis=1).max())))
            self.dress(axes, "weight", f"{what} per frame, stacked"
                       f"{' in ' + title if title else ''} ({k} shapes"
                       + (f"; {len(shown)} shown, the others summed)" if rest else ")"))
        return self.save(fig, axes_list[-1], "weights.png")

    def residual(self, report: _Json, model: str) -> Optional[str]:
        frames, values = records_series(report, residual_key(report))
        if len(frames) == 0:
            return None
        fig, (axes,) = self.figure(3.0)
        positive = values[values > 0]
        # A frame equal to a database shape has residual 0: drawn at the plot's floor.
        floor = float(positive.min()) / 10.0 if len(positive) else 1e-6
        axes.semilogy(frames, np.maximum(values, floor), ".-", color="tab:blue")
        if model == "qp":
            title = ("QP: relative residual ||A w - b|| / ||b||, how far the blend of database "
                     "poses is from the shot's pose")
        else:
            title = ("Nearest shape: relative distance ||a - b|| / ||b|| from the shot's pose "
                     "to the closest database pose")
        self.dress(axes, "relative residual", title)
        return self.save(fig, axes, "residual.png")

    def audit(self, report: _Json) -> Optional[str]:
        fig, (axes,) = self.figure(3.2)
        drawn = False
        for key, label, colour, style in AUDIT_SERIES:
            frames, values = records_series(report, key)
            if len(frames):
                axes.plot(frames, values, style, marker=".", color=colour, label=label)
                drawn = True
        frames, values = records_series(report, "resolved")
        if len(frames):
            axes.bar(frames, values, width=0.8, color="tab:green", alpha=0.35,
                     label="moved out by the resolution")
            drawn = True
        if not drawn:
            self.plt.close(fig)
            return None
        axes.set_ylim(bottom=0)
        if axes.get_ylim()[1] < 1.0:  # all zero: a readable axis rather than 0 to 0.06
            axes.set_ylim(0, 1)
        self.dress(axes, "vertices", "Cloth vertices inside the driver, and vertices resolved")
        return self.save(fig, axes, "audit.png")

    def jump(self, report: _Json, evaluation: Optional[_Json]) -> Optional[str]:
        frames, values = records_series(report, "max_jump")
        if len(frames) == 0:
            return None
        units = self.units
        fig, (axes,) = self.figure(3.0)
        axes.plot(frames, values * units.scale, ".-", color="tab:purple", label="bake")
        if evaluation:
            truth = [(r["frame"], r["truth"]["jump"]) for r in evaluation["frames"]
                     if isinstance(r.get("truth"), dict) and is_number(r["truth"].get("jump"))]
            if truth:
                t_frames, t_values = zip(*truth)
                axes.plot(t_frames, np.array(t_values) * units.scale, "--", color="0.4",
                          label="truth")
        axes.set_ylim(bottom=0)
        self.dress(axes, f"max jump ({units.unit})",
                   "Largest vertex move from the previous frame (popping shows as spikes)")
        return self.save(fig, axes, "jump.png")

    def error(self, error_frames: _ErrorFrames, baseline: dict[int, float]) -> Optional[str]:
        if not error_frames:
            return None
        scale, unit = self.units.scale, self.units.unit
        frames = np.array(sorted(error_frames))
        mean = np.array([error_frames[f][0] for f in frames]) * scale
        top = np.array([error_frames[f][1] for f in frames]) * scale
        fig, (axes,) = self.figure(3.2)
        axes.fill_between(frames, mean, top, color="tab:red", alpha=0.1)
        axes.plot(frames, top, ".-", color="tab:red", label="bake: max over vertices")
        axes.plot(frames, mean, ".-", color="tab:blue", label="bake: mean over vertices")
        if baseline:
            b_frames = sorted(baseline)
            axes.plot(b_frames, np.array([baseline[f] for f in b_frames]) * scale, "--",
                      color="0.45", label="binding baseline: mean")
        axes.set_ylim(bottom=0)
        self.dress(axes, f"error ({unit})", "Distance to the truth per frame")
        return self.save(fig, axes, "error.png")

    def strain(self, evaluation: Optional[_Json]) -> Optional[str]:
        """Per frame, the mean |strain| of the cloth's edges and the share of them over 10%,
        for every sequence the eval measured (bake, truth, baseline), in percent."""
        sequences = strain_sequences(evaluation) if evaluation else ()
        if not sequences:
            return None
        assert evaluation is not None
        frames = np.array([r["frame"] for r in evaluation["frames"]])
        fig, (top, bottom) = self.figure(6.0, rows=2)
        for name, label, colour, style in STRAIN_SERIES:
            if name in sequences:
                figures = [r[name] for r in evaluation["frames"]]
                for axes, key in ((top, "strain_mean"), (bottom, "strain_share_over_10pct")):
                    axes.plot(frames, [100.0 * f[key] for f in figures], style, marker=".",
                              color=colour, label=label)
        for axes in (top, bottom):
            axes.set_ylim(bottom=0)
        self.dress(top, "mean |strain| (%)",
                   "Edge strain per frame: mean |strain| over the cloth's edges "
                   "(strain = |edge| / |rest edge| - 1)")
        self.dress(bottom, "edges with |strain| > 10% (%)",
                   "Share of the cloth's edges stretched or shrunk by more than 10%")
        return self.save(fig, bottom, "strain.png")

    def sources(self, sources: dict[int, str]) -> str:
        """Each frame's source after drivenshape simulate as a coloured band over the frames,
        the frames the verdict flagged shaded as on every plot."""
        fig, (axes,) = self.figure(1.9)
        for source, colour in SOURCE_COLOURS.items():
            frames = [f for f, s in sorted(sources.items()) if s == source]
            if frames:
                axes.bar(frames, 1.0, width=1.0, color=colour, lw=0,
                         label=f"{source} ({len(frames)})")
        axes.set_ylim(0, 1)
        axes.set_yticks([])
        axes.grid(False)
        self.dress(axes, "", "Where each frame of the shot comes from after drivenshape simulate")
        return self.save(fig, axes, "sources.png")

    def heat_map(self, errors: _VertexErrors, up_axis: str) -> str:
        return self.mesh_map(errors["mesh"], errors["mean"] * self.units.scale, up_axis,
                             "heatmap.png", "inferno", f"mean error ({self.units.unit})",
                             f"Mean distance to the truth per vertex over "
                             f"{len(errors['frames'])} frames, on the rest mesh")

    def strain_map(self, errors: _VertexErrors, up_axis: str) -> str:
        return self.mesh_map(errors["mesh"], errors["strain"] * 100.0, up_axis, "strainmap.png",
                             "viridis", "largest |strain| of its edges (%), mean over frames",
                             f"The bake's strain per vertex: the largest |strain| of its edges, "
                             f"mean over {len(errors['frames'])} frames, on the rest mesh")

    def mesh_map(self, mesh: Mesh, values: _Float64Array, up_axis: str, name: str, cmap: str,
                 bar_label: str, title: str) -> str:
        """`values` per vertex drawn on the rest mesh from two opposite sides, in colour from 0
        to their largest, with a colour bar."""
        from matplotlib.colors import Normalize
        positions = np.asarray(mesh.positions, dtype=np.float64)
        triangles = np.asarray(mesh.triangles)
        norm = Normalize(vmin=0.0, vmax=max(float(values.max()), 1e-12))
        views = view_axes(positions, up_axis)
        right, up = views[0][1], views[0][2]
        width = np.ptp(positions @ right)
        height = max(np.ptp(positions @ up), 1e-12 * max(width, 1.0))
        # Long, low meshes (a sleeve) stack their two views; tall ones sit side by side.
        stacked = width > 2.0 * height
        rows, columns = (2, 1) if stacked else (1, 2)
        panel_aspect = height / width
        fig_height = (min(2 * 8.8 * panel_aspect, 7.0) if stacked
                      else min(4.4 * panel_aspect, 7.0)) + 1.2
        fig, axes_grid = self.plt.subplots(rows, columns, figsize=(FIGURE_WIDTH, fig_height),
                                           squeeze=False)
        fig.subplots_adjust(left=0.02, right=0.86, bottom=0.04, top=1.0 - 0.7 / fig_height,
                            wspace=0.05, hspace=0.25)
        image = None
        for axes, (label, right, up, toward) in zip(axes_grid.flat, views):
            x, y = positions @ right, positions @ up
            # Painter's order: the farthest triangles first.
            depth = (positions @ toward)[triangles].mean(axis=1)
            order = np.argsort(-depth, kind="stable")
            image = axes.tripcolor(x, y, triangles[order], values, shading="gouraud",
                                   cmap=cmap, norm=norm)
            axes.set_aspect("equal")
            axes.set_axis_off()
            axes.set_title(label, fontsize=10)
        fig.suptitle(title, x=0.02, ha="left")
        bar_axes = fig.add_axes((0.89, 0.1, 0.016, 0.75))
        assert image is not None  # drawn in both views
        fig.colorbar(image, cax=bar_axes).set_label(bar_label)
        fig.savefig(os.path.join(self.folder, name), dpi=100)
        self.plt.close(fig)
        return name


def weight_blocks(report: _Json) -> list[tuple[str, _FrameArray, _Float64Array]]:
    """[(title, frames, weights F x k)]: one block per region (one when no regions)."""
    records = [r for r in report["frames"] if not r.get("skipped") and r.get("weights")]
    if not records:
        return []
    frames = np.array([r["frame"] for r in records])
    first = records[0]["weights"]
    if first and isinstance(first[0], list):
        names = [r.get("name", f"region {i}")
                 for i, r in enumerate(report["settings"].get("regions") or [])]
        blocks = []
        for region in range(len(first)):
            weights = np.array([r["weights"][region] for r in records], dtype=float)
            name = names[region] if region < len(names) else f"region {region}"
            blocks.append((f"region '{name}'", frames, weights))
        return blocks
    return [("", frames, np.array([r["weights"] for r in records], dtype=float))]


def records_series(report: _Json, key: str) -> tuple[_FrameArray, _Float64Array]:
    frames, values = [], []
    for record in report["frames"]:
        if not record.get("skipped") and is_number(record.get(key)):
            frames.append(record["frame"])
            values.append(record[key])
    return np.array(frames), np.array(values, dtype=float)


# (eval sequence, label, colour, line style) of the strain plot's series.
STRAIN_SERIES: tuple[tuple[str, str, str, str], ...] = (
    ("bake", "bake", "tab:blue", "-"),
    ("baseline", "binding baseline", "tab:orange", ":"),
    ("truth", "truth (simulation)", "0.3", "--"))


# (report key, label, colour, line style) of the audit plot's series.
AUDIT_SERIES: tuple[tuple[str, str, str, str], ...] = (
    ("inside_before", "inside before the correction", "tab:gray", "--"),
    ("inside_corrected", "inside after the correction", "tab:orange", "-"),
    ("inside_after", "inside after the resolution", "tab:red", "-"))


def view_axes(positions: _Float64Array, up_axis: str
              ) -> list[tuple[str, _Float64Array, _Float64Array, _Float64Array]]:
    """Two opposite views along the thinner horizontal axis: [(label, right, up, toward)]."""
    up = "XYZ".index(up_axis)
    horizontal = [a for a in range(3) if a != up]
    extent = positions.max(axis=0) - positions.min(axis=0)
    depth, across = sorted(horizontal, key=lambda a: extent[a])
    unit = np.eye(3)
    # A camera looking along `toward` with `up` up has right = toward x up (right x up points
    # back at the camera); the opposite view mirrors it.
    right = np.cross(unit[depth], unit[up])
    name = "XYZ"[depth]
    return [(f"seen from -{name}", right, unit[up], unit[depth]),
            (f"seen from +{name}", -right, unit[up], -unit[depth])]


# ---- page ------------------------------------------------------------------------------------

CSS: str = """
body { font-family: "DejaVu Sans", Arial, sans-serif; margin: 24px auto; max-width: 1180px;
       color: #222; background: #fff; line-height: 1.4; }
h1 { font-size: 24px; margin-bottom: 4px; }
h2 { font-size: 19px; border-bottom: 1px solid #ccc; padding-bottom: 3px; margin-top: 32px; }
table { border-collapse: collapse; margin: 8px 0; }
th, td { border: 1px solid #ddd; padding: 3px 9px; text-align: left; font-size: 14px; }
th { background: #f2f2f2; }
#header th { white-space: nowrap; vertical-align: top; }
td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
td.weights { white-space: nowrap; }
.sub { color: #666; font-size: 13px; }
.flag { color: #b00; font-weight: bold; }
.model { font-size: 16px; margin: 10px 0 4px; }
.verdict { font-size: 17px; font-weight: bold; padding: 8px 12px; margin: 8px 0;
           border-left: 6px solid; }
#truth { font-size: 15px; font-weight: normal; }
.verdict.ok { border-color: #2a7; background: #eef8f1; }
.verdict.simulate { border-color: #c33; background: #fbeeee; }
.warning { font-size: 14px; padding: 6px 12px; margin: 8px 0; border-left: 6px solid #d90;
           background: #fdf6e3; }
img { max-width: 100%; border: 1px solid #eee; display: block; margin: 6px 0 16px; }
code { background: #f4f4f4; padding: 0 3px; }
"""


def frame_link(frame: Optional[int]) -> str:
    return f'<a href="#frame-{frame}">{frame}</a>' if frame is not None else "-"


class Summary:
    """Rows of the summary table: a stable key (data-key, for tools), label, value, detail."""

    def __init__(self) -> None:
        self.rows: list[tuple[str, str, str, str]] = []

    def add(self, key: str, label: str, value: str, detail: str = "") -> None:
        self.rows.append((key, label, value, detail))

    def html(self) -> str:
        lines = ["<table id=\"summary\"><tr><th>figure</th><th>value</th><th>where</th></tr>"]
        for key, label, value, detail in self.rows:
            lines.append(f'<tr><td>{html.escape(label)}</td><td class="num" data-key="{key}">'
                         f"{html.escape(value)}</td><td>{detail}</td></tr>")
        lines.append("</table>")
        return "\n".join(lines)


def worst(pairs: Iterable[tuple[int, float]]) -> tuple[Optional[float], Optional[int]]:
    """(value, frame) of the largest value, the earliest frame on ties; (None, None) if none."""
    best: tuple[Optional[float], Optional[int]] = (None, None)
    for frame, value in pairs:
        if best[0] is None or value > best[0]:
            best = (value, frame)
    return best


def mean_of(values: Sequence[float]) -> float:
    return sum(values) / len(values)


def _summary_bake(summary: Summary, report: _Json, model: str,
                  baked: list[_Json]) -> None:
    """The model, the frames baked and kept, and the bake's speed."""
    summary.add("model", "made by", MODELS[model][0], f"<code>--weights {model}</code>")
    summary.add("frames_baked", "frames baked", str(len(baked)))
    skipped = len(report["frames"]) - len(baked)
    if skipped:
        summary.add("frames_kept", "frames kept from an earlier run (no figures)", str(skipped))
    if baked:
        summary.add("frame_range", "first - last frame",
                    f"{baked[0]['frame']} - {baked[-1]['frame']}")
    total = report.get("seconds", {}).get("total")
    if is_number(total) and total > 0:
        summary.add("seconds", "bake seconds", f"{total:.3g}",
                    f"{len(baked) / total:.3g} frames/s")


def _summary_coverage(summary: Summary, coverage: Coverage, error_frames: _ErrorFrames,
                      units: Units) -> None:
    """The pose model's verdict, its tolerance and level, the predicted errors, and with a
    truth whether the verdict holds."""
    unit = units.unit
    summary.add("verdict", "coverage verdict",
                "DrivenShape is enough" if coverage.enough
                else f"simulate {format_frame_range(coverage.flagged)}")
    summary.add("coverage_tolerance", f"coverage tolerance ({unit})",
                units.text(coverage.tolerance), "mean vertex error bound allowed")
    if coverage.level > 0:
        summary.add("verdict_level", "verdict level", percent_text(coverage.level),
                    "share of frames the error bound is calibrated to hold for")
    summary.add("frames_over", "frames over the tolerance (to simulate)",
                str(len(coverage.flagged)), f"of {len(coverage.predicted)} predicted; "
                f"{percent_text(coverage.covered_fraction)} covered")
    predicted = list(coverage.predicted.items())
    summary.add("predicted_mean", f"predicted mean vertex error, mean ({unit})",
                units.text(mean_of([v for _, v in predicted])))
    value, frame = worst(predicted)
    summary.add("predicted_max", f"predicted mean vertex error, max ({unit})",
                units.text(value), frame_link(frame))
    checked = coverage.against_truth(error_frames)
    if checked:
        true_error, missed, count = checked
        share = percent_text((count - len(missed)) / count)
        summary.add("enough_true_error",
                    f"true mean error of the frames within the tolerance ({unit})",
                    units.text(true_error),
                    f"{share} of them truly within: the verdict holds" if coverage.holds(checked)
                    else f'<span class="flag">{share} of them truly within: the verdict does '
                    "not hold</span>")
        summary.add("missed", "frames within the tolerance whose true mean error is over it",
                    str(len(missed)), format_frame_range(missed) if missed else "-")


def _summary_records(summary: Summary, report: _Json, model: str, baked: list[_Json],
                     units: Units) -> None:
    """From the frames' records: the residual (QP, nearest), the audit counts and the largest
    jump."""
    def series(key: str) -> list[tuple[int, Any]]:
        return [(r["frame"], r[key]) for r in baked if is_number(r.get(key))]

    if model in SOLVING_MODELS:
        residual = series(residual_key(report))
        if residual:
            summary.add("residual_mean", "relative residual, mean",
                        ratio_text(mean_of([v for _, v in residual])))
            value, frame = worst(residual)
            summary.add("residual_max", "relative residual, max", ratio_text(value),
                        frame_link(frame))
    for key, label in (("inside_corrected", "inside the driver after the correction"),
                       ("inside_after", "inside the driver after the resolution")):
        values = series(key)
        if values:
            summary.add(f"{key}_mean", f"{label}, mean per frame",
                        f"{mean_of([v for _, v in values]):.3g}")
            value, frame = worst(values)
            summary.add(f"{key}_max", f"{label}, max", count_text(value),
                        frame_link(frame) if value else "-")
    resolved = series("resolved")
    if resolved:
        summary.add("resolved_total", "vertices moved out by the resolution, all frames",
                    str(sum(v for _, v in resolved)))
    jumps = series("max_jump")
    if jumps:
        value, frame = worst(jumps)
        summary.add("max_jump", f"largest frame-to-frame jump ({units.unit})", units.text(value),
                    frame_link(frame))


def _summary_eval(summary: Summary, evaluation: _Json, units: Units) -> None:
    """The eval's error to the truth, the baseline's, the jumps against the truth's and the
    penetrations it measured."""
    unit = units.unit
    bake = evaluation.get("summary", {}).get("bake", {})
    summary.add("error_mean", f"error to the truth, mean ({unit})", units.text(evaluation["mean"]))
    summary.add("error_rms", f"error to the truth, RMS ({unit})", units.text(evaluation["rms"]))
    summary.add("error_max", f"error to the truth, max ({unit})", units.text(evaluation["max"]),
                frame_link(evaluation["max_frame"]))
    baseline = evaluation.get("summary", {}).get("baseline")
    if isinstance(baseline, dict) and is_number(baseline.get("mean")):
        summary.add("baseline_error_mean", f"binding baseline error, mean ({unit})",
                    units.text(baseline["mean"]))
    truth = evaluation.get("summary", {}).get("truth", {})
    if is_number(bake.get("max_jump")) and is_number(truth.get("max_jump")) \
            and truth["max_jump"] > 0:
        summary.add("jump_ratio", "largest jump / the truth's",
                    ratio_text(bake["max_jump"] / truth["max_jump"]))
    if is_number(bake.get("mean_inside")):
        summary.add("eval_inside_mean", "inside the driver per frame (eval)",
                    f"{bake['mean_inside']:.3g}")


# How the page names the eval's sequences.
SEQUENCE_NAMES: dict[str, str] = {"bake": "bake", "truth": "simulation (truth)",
                                  "baseline": "binding baseline"}


def _summary_strain(summary: Summary, evaluation: _Json) -> None:
    """The eval's strain over every edge of every frame: the bake's, the others beside it."""
    sequences = strain_sequences(evaluation)
    shot = evaluation["summary"] if sequences else {}
    for key, label in (("strain_mean", "edge strain, mean |strain| (%)"),
                       ("strain_p95", "edge strain, 95th percentile of |strain| (%)"),
                       ("strain_share_over_10pct", "edges over 10% strain (% of edges)")):
        if sequences:
            others = "; ".join(f"{SEQUENCE_NAMES[s]} {strain_text(shot[s][key])}"
                               for s in sequences if s != "bake")
            summary.add(key, label, strain_text(shot["bake"][key]), html.escape(others))


def _summary_truth(summary: Summary, error_frames: _ErrorFrames,
                   errors: Optional[_VertexErrors], units: Units) -> None:
    """Without an eval, the error to the truth computed from the caches; the worst vertex."""
    unit = units.unit
    if error_frames:
        means = [v[0] for v in error_frames.values()]
        value, frame = worst((f, v[1]) for f, v in error_frames.items())
        summary.add("error_mean", f"error to the truth, mean ({unit})",
                    units.text(mean_of(means)))
        summary.add("error_max", f"error to the truth, max ({unit})", units.text(value),
                    frame_link(frame))
    if errors:
        vertex = int(np.argmax(errors["mean"]))
        summary.add("worst_vertex", "vertex with the largest mean error", str(vertex))
        summary.add("worst_vertex_error", f"its mean error ({unit})",
                    units.text(float(errors["mean"][vertex])))


def summary_rows(report: _Json, model: str, coverage: Optional[Coverage],
                 evaluation: Optional[_Json], errors: Optional[_VertexErrors],
                 error_frames: _ErrorFrames, units: Units) -> Summary:
    """The page's summary table, in this order: the bake, the verdict, the records' figures,
    the error to the truth and the worst vertex."""
    summary = Summary()
    baked = [r for r in report["frames"] if not r.get("skipped")]
    _summary_bake(summary, report, model, baked)
    if coverage:
        _summary_coverage(summary, coverage, error_frames, units)
    _summary_records(summary, report, model, baked, units)
    if evaluation:
        _summary_eval(summary, evaluation, units)
        _summary_strain(summary, evaluation)
    _summary_truth(summary, {} if evaluation else error_frames, errors, units)
    return summary


def worst_frames(report: _Json, model: str, coverage: Optional[Coverage],
                 error_frames: _ErrorFrames) -> tuple[str, list[int]]:
    """The frames to look at first: by max error when known, else by the model's own measure
    (predicted error, residual), else by the largest jump."""
    def ranked(pairs: Iterable[tuple[int, float]]) -> list[int]:
        return [f for f, _ in sorted(pairs, key=lambda p: (-p[1], p[0]))[:WORST_FRAMES]]

    if error_frames:
        return "max error to the truth", ranked((f, v[1]) for f, v in error_frames.items())
    if coverage:
        return "predicted error", ranked(coverage.predicted.items())
    if model in SOLVING_MODELS:
        frames, values = records_series(report, residual_key(report))
        return "relative residual", ranked(zip(frames.tolist(), values.tolist()))
    frames, values = records_series(report, "max_jump")
    return "largest jump", ranked(zip(frames.tolist(), values.tolist()))


def top_weights(record: _Json, db_frames: Sequence[object]) -> str:
    weights = record.get("weights") or []
    if weights and isinstance(weights[0], list):
        return f"{len(weights)} regions"
    ranked = sorted(range(len(weights)), key=lambda s: -weights[s])[:3]
    parts = []
    for s in ranked:
        if weights[s] < 0.005:
            break
        label = db_frames[s] if s < len(db_frames) else f"shape {s}"
        parts.append(f"{label}: {weights[s]:.2f}")
    return ", ".join(parts)


def frame_table(report: _Json, model: str, coverage: Optional[Coverage],
                error_frames: _ErrorFrames, units: Units) -> str:
    """One row per frame of the report (id frame-N, the target of the links above); each
    column's <th> has a data-key naming what it holds."""
    unit = units.unit
    db_frames = report["database"].get("frames") or []
    baked = [r for r in report["frames"] if not r.get("skipped")]
    # (key, header, cell(record) -> (class, html)); the count columns' cells also take their key
    columns: list[tuple[str, str, Callable[..., tuple[str, str]]]] = []
    if model in SOLVING_MODELS:
        residual = residual_key(report)
        columns.append(("weights", "largest weights (db frame: weight)",
                        lambda r: ("weights", html.escape(top_weights(r, db_frames)))))
        columns.append(("residual", "rel. residual",
                        lambda r: ("num", ratio_text(r.get(residual)))))
    if coverage:
        columns.append(("predicted", f"predicted error ({unit})",
                        lambda r: ("num", units.text(coverage.predicted.get(r["frame"])))))
        columns.append(("bound", f"error bound ({unit})",
                        lambda r: ("num", units.text(coverage.bound.get(r["frame"])))))
        columns.append(("over", "bound over the tolerance",
                        lambda r: ("text", '<span class="flag">over: simulate</span>'
                                   if r["frame"] in coverage.flagged else "within")))
    for key, header in (("inside_before", "inside blended"),
                        ("inside_corrected", "inside corrected"),
                        ("inside_after", "inside after"), ("resolved", "resolved")):
        if any(key in r for r in baked):
            columns.append((key, header, lambda r, k=key: ("num", count_text(r.get(k)))))
    columns.append(("max_jump", f"max jump ({unit})",
                    lambda r: ("num", units.text(r.get("max_jump")))))
    if error_frames:
        columns.append(("error_mean", f"mean error ({unit})",
                        lambda r: ("num", units.text(error_frames.get(r["frame"], (None,))[0]))))
        columns.append(("error_max", f"max error ({unit})",
                        lambda r: ("num", units.text(error_frames.get(r["frame"],
                                                                      (None, None))[1]))))
    lines = ['<table id="frames"><tr><th data-key="frame">frame</th>'
             + "".join(f'<th data-key="{key}">{html.escape(header)}</th>'
                       for key, header, _ in columns) + "</tr>"]
    for record in report["frames"]:
        frame = record["frame"]
        if record.get("skipped"):
            cells = [("text", "kept from an earlier run")] + [("num", "")] * (len(columns) - 1)
        else:
            cells = [cell(record) for _, _, cell in columns]
        row = "".join(f'<td class="{kind}">{text}</td>' for kind, text in cells)
        lines.append(f'<tr id="frame-{frame}"><td>{frame}</td>{row}</tr>')
    lines.append("</table>")
    return "\n".join(lines)


def on_off(value: object) -> str:
    return "on" if value else "off"


def setting_rows() -> dict[str, _Json]:
    """The settings table's rows (drivenshape.settings_table()) by each entry they write into the
    report's settings: where the page finds a setting's label and unit."""
    rows: dict[str, _Json] = {}
    for row in settings_table():
        for entry in row["report"]:
            rows.setdefault(entry["path"], row)
    return rows


def setting_text(key: str, value: object, rows: dict[str, _Json], units: Units) -> str:
    """"skin offset 2.0 mm": a setting of the report by its label in the settings table, a
    length (the table's unit: scene units) in the page's unit."""
    row = rows.get(key)
    label = row["label"] if row else key.replace("_", " ")
    if isinstance(value, bool):
        return f"{label} {on_off(value)}"
    if row is not None and row["unit"] == "scene units" and isinstance(value, (int, float)):
        return f"{label} {units.with_unit(float(value))}"
    if isinstance(value, float):
        return f"{label} {value:g}"
    return f"{label} {value}"


def settings_text(settings: _Json, units: Units) -> str:
    """The settings a supervisor asks about, by the settings table's labels, lengths in the
    page's unit; the resolution's own settings with it, when it is on."""
    rows = setting_rows()

    def text(key: str) -> str:
        return setting_text(key, settings[key], rows, units)

    parts = [text(key) for key in ("weights", "align", "blend", "correct") if key in settings]
    if "resolve" in settings:
        resolve = text("resolve")
        details = [text(key) for key in ("skin_offset", "resolve_direction", "exit_fade")
                   if settings["resolve"] and key in settings]
        parts.append(resolve + (f" ({', '.join(details)})" if details else ""))
    parts += [text(key) for key in ("audit", "coverage_tolerance") if key in settings]
    if settings.get("max_weight_change"):
        parts.append(text("max_weight_change"))
    if settings.get("regions"):
        parts.append(f"{len(settings['regions'])} {rows['regions']['label']} "
                     f"({settings.get('regions_file', '')})")
    if settings.get("binding_mask"):
        parts.append(text("binding_mask"))
    if settings.get("layers"):
        parts.append(f"{rows['layers']['label']} " + ", ".join(sorted(settings["layers"])))
    parts += [text(key) for key in ("batch", "compression") if key in settings]
    return "; ".join(parts)


def pose_model_text(pose: _Json, units: Units) -> str:
    text = (f"{pose.get('parts')} rigid parts, {pose.get('reference_frames')} reference frames, "
            f"rank {pose.get('rank')}; cross-validated mean vertex error over the reference "
            f"clip {units.with_unit(pose.get('cross_validation_error'))} (the rest binding "
            f"alone: {units.with_unit(pose.get('binding_error'))})")
    per_clip = pose.get("per_clip_models")
    if isinstance(per_clip, dict):
        text += (f"; a model of each of its {per_clip.get('clips')} reference clips mixed in "
                 f"(weight of the model over every clip {per_clip.get('weight')})")
    return text


def shot_name(report: _Json) -> str:
    output = report.get("output") or ""
    name = os.path.basename(output)
    for token in ("####", "%04d", "$F4"):
        name = name.replace("." + token, "").replace(token, "")
    return os.path.splitext(name)[0] or "bake"


def header_html(args: argparse.Namespace, report: _Json, evaluation: Optional[_Json], title: str,
                model: str, coverage: Optional[Coverage], error_frames: _ErrorFrames,
                units: Units) -> str:
    db = report["database"]
    settings = report["settings"]
    rows = [("shot", f"{report.get('output', '-')} (driver {report.get('driver_cache', '-')})"),
            ("database", f"{db.get('shape_count', '-')} shapes, content hash "
                         f"{db.get('content_hash', '-')}; database frames "
                         f"{', '.join(str(f) for f in db.get('frames', []))}")]
    if isinstance(settings.get("pose_model"), dict):
        rows.append(("pose model", pose_model_text(settings["pose_model"], units)))
    rows += [("settings", settings_text(settings, units)),
             ("settings hash", str(report.get("settings_hash", "-"))),
             ("device", str(report.get("device", "-"))),
             ("tool", f"{report.get('tool', '-')} {report.get('tool_version', '')}"),
             ("bake report", ", ".join(args.report))]
    if evaluation:
        rows.append(("eval", f"{args.eval}: truth {evaluation.get('truth')}, "
                             f"{evaluation.get('vertices')} vertices, closest triangles on "
                             f"{evaluation.get('device')}"))
    rows.append(("lengths", "mm" if units.unit == "mm" else
                 "scene units, as stored (give --units m, cm or mm for mm)"))
    rows.append(("written", datetime.datetime.now().isoformat(timespec="seconds")))
    body = "\n".join(f"<tr><th>{html.escape(k)}</th><td>{html.escape(v)}</td></tr>"
                     for k, v in rows)
    name, what = MODELS[model]
    parts = [f"<h1>{html.escape(title)}</h1>",
             f'<p class="model" id="model">Made by <b>{html.escape(name)}</b>: {what}.</p>']
    if coverage:
        kind = "ok" if coverage.enough else "simulate"
        parts.append(f'<p class="verdict {kind}" id="verdict">Verdict (predicted): '
                     f"{html.escape(coverage.verdict(units))}.</p>")
        checked = coverage.against_truth(error_frames)
        if checked:
            true_error, missed, count = checked
            holds = coverage.holds(checked)
            level = (f"at least {percent_text(coverage.level)} must be" if coverage.level > 0
                     else "their mean must be")
            text = (f"Against the truth ({args.eval or 'the caches'}): the frames judged "
                    f"enough have a true mean error of {units.with_unit(true_error)}, and "
                    f"{count - len(missed)} of {count} are within the tolerance ({level}): "
                    "the verdict " + ("holds" if holds else "does not hold"))
            if missed:
                text += (f"; {len(missed)} of them are over it on their own "
                         f"({format_frame_range(missed)})")
            parts.append(f'<p class="verdict {"ok" if holds else "simulate"}" id="truth">'
                         f"{html.escape(text)}.</p>")
    # What the bake warned about its inputs and settings, each as the report says it.
    for index, warning in enumerate(report.get("warnings", []), 1):
        parts.append(f'<p class="warning" id="warning-{index}">The bake warned: '
                     f"{html.escape(warning)}</p>")
    parts.append(f'<table id="header">\n{body}\n</table>')
    return "\n".join(parts)


def figure(name: Optional[str], alt: str, missing: str) -> str:
    if name is None:
        return f'<p class="sub">{html.escape(missing)}</p>'
    return f'<img src="{html.escape(name)}" alt="{html.escape(alt)}">'


def error_frames_of(evaluation: Optional[_Json], errors: Optional[_VertexErrors]
                    ) -> tuple[_ErrorFrames, dict[int, float]]:
    """{frame: (mean, max)} to the truth, and {frame: baseline mean}."""
    error_frames: _ErrorFrames = {}
    baseline: dict[int, float] = {}
    if evaluation:
        for record in evaluation["frames"]:
            error_frames[record["frame"]] = (record["mean"], record["max"])
            if isinstance(record.get("baseline"), dict) and is_number(
                    record["baseline"].get("mean")):
                baseline[record["frame"]] = record["baseline"]["mean"]
    elif errors:
        error_frames = {f: v[:2] for f, v in errors["per_frame"].items()}
    return error_frames, baseline


def coverage_section(parts: list[str], plots: Plots, model: str, coverage: Optional[Coverage],
                     error_frames: _ErrorFrames, units: Units) -> None:
    parts.append('<h2 id="coverage">Coverage</h2>')
    if model != "model":
        parts.append(f'<p class="sub">No coverage verdict: {html.escape(MODELS[model][0])} '
                     "predicts no error (only the pose model does).</p>")
        return
    if not coverage:
        parts.append('<p class="sub">No frame was baked in this run, so none was predicted.</p>')
        return
    tolerance = units.with_unit(coverage.tolerance)
    text = ("The pose model predicts each frame's mean vertex error from how far its pose is "
            "from the reference clip (blue), and bounds it (orange): calibrated on the "
            "reference clip's held-out frames, the true error is within the bound on "
            + (f"{percent_text(coverage.level)} of frames like them. " if coverage.level > 0
               else "as many frames as the prediction (a database before 0.2.0). "))
    if coverage.flagged:
        text += (f"Frames bounded over the {tolerance} tolerance (the red dashed line; "
                 f"{len(coverage.flagged)} of {len(coverage.predicted)}, circled, and shaded red "
                 "on every plot) should be simulated: "
                 + ", ".join(frame_link(f) for f in coverage.flagged) + ".")
    else:
        text += (f"No frame is bounded over the {tolerance} tolerance (the red dashed line), "
                 "so none needs a simulation.")
    if error_frames:
        text += " The grey dashed line is the true mean error the eval measured."
    parts.append(f"<p>{text}</p>")
    parts.append(figure(plots.coverage(coverage, error_frames),
                        "predicted error and error bound per frame against the tolerance", ""))


def sources_section(parts: list[str], plots: Plots, sources: dict[int, str], path: str) -> None:
    """The frames drivenshape simulate replaced, blended and kept, on a timeline."""
    parts.append('<h2 id="simulated">Simulated frames</h2>')
    counts = {source: sum(1 for s in sources.values() if s == source) for source in SOURCE_COLOURS}
    text = (f"<code>drivenshape simulate</code> ({html.escape(path)}) replaced "
            f"{counts['simulated']} frames by Blender's cloth simulation (green), cross-faded "
            f"{counts['blended']} at its seams and after its windows (olive), and kept "
            f"{counts['baked']} baked (grey); the frames the verdict flagged are shaded red.")
    parts.append(f'<p id="sources">{text}</p>')
    parts.append(figure(plots.sources(sources), "each frame's source", ""))


def strain_section(parts: list[str], plots: Plots, evaluation: Optional[_Json],
                   eval_path: Optional[str]) -> None:
    """The eval's strain per frame, or why there is none."""
    parts.append('<h2 id="strain">Strain</h2>')
    if not evaluation:
        parts.append('<p class="sub">No strain: give --eval, the JSON of <code>drivenshape eval'
                     "</code> run with the cloth's rest mesh (--db or --driven-mesh).</p>")
        return
    if not strain_sequences(evaluation):
        parts.append('<p class="sub">No strain in the eval: it was run without the cloth\'s '
                     "rest mesh; run <code>drivenshape eval</code> with --db DB or "
                     "--driven-mesh M.obj.</p>")
        return
    text = (f"How far the cloth's {evaluation['edges']} edges stretch or shrink against its rest "
            "mesh, per frame: strain = |edge| / |rest edge| - 1 of each edge (+10%: 10% longer "
            "than at rest), from " + str(eval_path) + ". A simulated garment stays within a "
            "few percent; a bake far above the truth (the dashed line) stretches like rubber. "
            "The summary gives the figures over every edge of every frame.")
    parts.append(f'<p class="sub" id="strain-note">{html.escape(text)}</p>')
    parts.append(figure(plots.strain(evaluation), "edge strain per frame", ""))


def error_map_section(parts: list[str], plots: Plots, args: argparse.Namespace,
                      errors: Optional[_VertexErrors]) -> None:
    """The error per vertex on the rest mesh (--mesh), or why there is none."""
    parts.append("<h2>Error per vertex</h2>")
    if not errors:
        parts.append('<p class="sub">No heat map: give --mesh (the driven rest OBJ) with a '
                     "truth (--eval or --truth).</p>")
        return
    frames = errors["frames"]
    parts.append(f'<p class="sub">Mean over frames {frames[0]}-{frames[-1]} ({len(frames)} '
                 f'frames) of the distance between {html.escape(errors["bake"])} and '
                 f'{html.escape(errors["truth"])}, drawn on {html.escape(args.mesh)}.</p>')
    parts.append(figure(plots.heat_map(errors, args.up_axis), "per-vertex error heat map", ""))


def strain_map_section(parts: list[str], plots: Plots, args: argparse.Namespace,
                       errors: Optional[_VertexErrors]) -> None:
    """The bake's strain per vertex on the rest mesh (--mesh), beside the truth's figures."""
    parts.append('<h2 id="strain-per-vertex">Strain per vertex</h2>')
    if not errors:
        parts.append('<p class="sub">No strain heat map: give --mesh (the driven rest OBJ) '
                     "with a truth (--eval or --truth).</p>")
        return
    frames = errors["frames"]
    bake, truth = errors["strain"], errors["truth_strain"]
    parts.append(f'<p class="sub" id="strain-vertices">On each frame, the largest |strain| of '
                 f'the vertex\'s edges in '
                 f'{html.escape(errors["bake"])} against the rest mesh {html.escape(args.mesh)}'
                 f", averaged over the same {len(frames)} frames: over the vertices "
                 f"{strain_text(float(bake.mean()))}% on average and "
                 f"{strain_text(float(bake.max()))}% at most, where the truth has "
                 f"{strain_text(float(truth.mean()))}% and {strain_text(float(truth.max()))}%."
                 "</p>")
    parts.append(figure(plots.strain_map(errors, args.up_axis), "per-vertex strain heat map",
                        ""))


def solve_sections(parts: list[str], plots: Plots, report: _Json, model: str) -> None:
    """Weights and residual: only where the model solves for them."""
    parts.append("<h2>Weights</h2>")
    if model not in SOLVING_MODELS:
        parts.append(f'<p class="sub">No weights: {html.escape(MODELS[model][0])} blends no '
                     "database shapes.</p>")
    else:
        parts.append(figure(plots.weights(report, model), "weights over time",
                            "No frame was baked in this run."))
        parts.append("<h2>Residual</h2>")
        parts.append(figure(plots.residual(report, model), "relative residual",
                            "No frame was baked in this run."))


def build_page(args: argparse.Namespace, report: _Json, evaluation: Optional[_Json],
               errors: Optional[_VertexErrors], folder: str) -> None:
    units = Units(args.units)
    model = report["settings"]["weights"]
    coverage = Coverage(report) if model == "model" else None
    coverage = coverage if coverage else None
    error_frames, baseline = error_frames_of(evaluation, errors)
    plots = Plots(folder, [r["frame"] for r in report["frames"]] + list(error_frames),
                  coverage.flagged if coverage else [], units)
    title = args.title or f"QC: {shot_name(report)}"
    summary = summary_rows(report, model, coverage, evaluation, errors, error_frames, units)
    ranking, worst_list = worst_frames(report, model, coverage, error_frames)

    parts = [header_html(args, report, evaluation, title, model, coverage, error_frames,
                         units),
             "<h2>Summary</h2>", summary.html()]
    if worst_list:
        parts.append(f'<p id="worst">Worst frames by {html.escape(ranking)}: '
                     + ", ".join(frame_link(f) for f in worst_list) + "</p>")
    coverage_section(parts, plots, model, coverage, error_frames, units)
    if args.simulated:
        sources_section(parts, plots, load_simulate_report(args.simulated, report),
                        args.simulated)
    if args.eval or errors:
        parts.append("<h2>Error to the truth</h2>")
        if evaluation:
            source = f"from {args.eval}"
        else:
            assert errors is not None  # without --eval, the caches gave the errors
            source = f"computed from {errors['truth']} and {errors['bake']}"
        parts.append(f'<p class="sub">Per-vertex distance to the truth, {html.escape(source)}.'
                     "</p>")
        parts.append(figure(plots.error(error_frames, baseline),
                            "error per frame", "No frames in the eval."))
    error_map_section(parts, plots, args, errors)
    strain_section(parts, plots, evaluation, args.eval)
    strain_map_section(parts, plots, args, errors)
    solve_sections(parts, plots, report, model)
    parts.append("<h2>Penetrations</h2>")
    parts.append(figure(plots.audit(report), "inside counts",
                        "No audit figures in this report (baked with --no-audit)."))
    parts.append("<h2>Popping</h2>")
    parts.append(figure(plots.jump(report, evaluation),
                        "max jump per frame", "No frame-to-frame jumps in this report."))
    parts.append("<h2>Frames</h2>")
    parts.append(frame_table(report, model, coverage, error_frames, units))
    page = ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n"
            f'<meta name="generator" content="{GENERATOR}">\n'
            f"<title>{html.escape(title)}</title>\n<style>{CSS}</style></head>\n<body>\n"
            + "\n".join(parts) + "\n</body></html>\n")
    with open(os.path.join(folder, "index.html"), "w", encoding="utf-8") as stream:
        stream.write(page)


# ---- output ----------------------------------------------------------------------------------

# The page's list of the files it wrote into its folder, with each one's SHA-256: a later run
# replaces (or removes) a file only while it still has the content this tool gave it.
MANIFEST: str = ".drivenshape-qc.json"
MANIFEST_LIMIT: int = 1 << 20
# An index.html or PNG of a page written before the manifest (0.2.0 and earlier) is read this
# far to recognise it.
_LEGACY_HEAD: int = 4096


def _digest(path: str) -> Optional[str]:
    """SHA-256 of the regular file `path` (not followed if a link), None for anything else."""
    try:
        if not stat.S_ISREG(os.lstat(path).st_mode):
            return None
        digest = hashlib.sha256()
        with open(path, "rb") as stream:
            for block in iter(lambda: stream.read(1 << 20), b""):
                digest.update(block)
    except OSError:
        return None
    return digest.hexdigest()


def _head(path: str) -> bytes:
    try:
        if not stat.S_ISREG(os.lstat(path).st_mode):
            return b""
        with open(path, "rb") as stream:
            return stream.read(_LEGACY_HEAD)
    except OSError:
        return b""


def is_qc_page(head: bytes) -> bool:
    """Whether the start of an index.html is a QC page (this module's, or scripts/qc_report.py's
    of earlier versions)."""
    return (f'content="{GENERATOR}"'.encode() in head
            or b'content="drivenshape qc_report"' in head)


def _manifest(folder: str) -> dict[str, set[str]]:
    """{file name: SHA-256s it may have} of the page's manifest in `folder` ({} without one).
    A manifest this tool did not write is refused (it would be overwritten)."""
    path = os.path.join(folder, MANIFEST)
    if not os.path.lexists(path):
        return {}

    def refuse(message: str) -> QcError:
        return QcError(EXIT_OUTPUT, f"{message}: '{MANIFEST}' in '{folder}' is not a QC page's "
                                    "list of its files; it is left alone: choose another -o")

    try:
        if os.path.islink(path):
            raise refuse("a link")
        with _files.open_regular(path, MANIFEST_LIMIT, refuse) as stream:
            data = json.loads(stream.read().decode("utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError):
        raise refuse("not JSON")
    files = data.get("files") if isinstance(data, dict) else None
    if not (isinstance(data, dict) and data.get("generator") == GENERATOR
            and isinstance(files, dict)):
        raise refuse("another format")
    known: dict[str, set[str]] = {}
    for name, digests in files.items():
        digests = digests if isinstance(digests, list) else [digests]
        if _own_name(name) and all(isinstance(d, str) for d in digests):
            known[name] = set(digests)
    return known


def _own_name(name: object) -> bool:
    """A name the page may write: a plain file name in its folder."""
    return (isinstance(name, str) and name not in ("", ".", "..") and "/" not in name
            and "\0" not in name and name != MANIFEST)


def earlier_page_files(folder: str) -> set[str]:
    """The files of `folder` an earlier run of this page wrote and nobody changed since: those
    its manifest lists with their content; in a folder without a manifest (a page of 0.2.0 or
    earlier) a QC index.html and the PNGs drawn by matplotlib that it shows."""
    known = _manifest(folder)
    if known:
        return {name for name, digests in known.items()
                if _digest(os.path.join(folder, name)) in digests}
    index = os.path.join(folder, "index.html")
    head = _head(index)
    if not is_qc_page(head):
        return set()
    try:
        with open(index, encoding="utf-8", errors="replace") as stream:
            shown = set(re.findall(r'<img src="([^"/]+\.png)"', stream.read()))
    except OSError:
        shown = set()
    own = {"index.html"}
    for name in shown:
        png = _head(os.path.join(folder, name))
        if png.startswith(b"\x89PNG\r\n\x1a\n") and b"Matplotlib" in png:
            own.add(name)
    return own


def _write_manifest(folder: str, files: dict[str, list[str]]) -> None:
    """The manifest, created beside itself and renamed into place."""
    text = json.dumps({"generator": GENERATOR, "files": files}, indent=1, sort_keys=True)
    handle, temp = tempfile.mkstemp(prefix=f"{MANIFEST}.tmp-", dir=folder)
    try:
        with os.fdopen(handle, "w", encoding="utf-8") as stream:
            stream.write(text + "\n")
        os.chmod(temp, _files.new_file_mode())
        os.replace(temp, os.path.join(folder, MANIFEST))
    except BaseException:
        if os.path.lexists(temp):
            os.remove(temp)
        raise


def _place(source: str, target: str, replace: bool) -> None:
    """Moves the page's `source` to `target`: over an earlier file of the page when `replace`,
    else only where there is no file (a hard link fails on an existing name; a file system
    without hard links gets a rename right after a check)."""
    if replace:
        os.replace(source, target)
        return
    try:
        os.link(source, target)
    except FileExistsError:
        raise QcError(EXIT_OUTPUT, f"'{target}' appeared while the page was written; it is "
                                   "left alone: choose another -o")
    except OSError:
        if os.path.lexists(target):
            raise QcError(EXIT_OUTPUT, f"'{target}' appeared while the page was written; it "
                                       "is left alone: choose another -o")
        os.rename(source, target)
        return
    os.remove(source)


def _output_folder(args: argparse.Namespace) -> tuple[str, bool]:
    """(-o as an absolute folder, whether this run created it)."""
    out = os.path.abspath(args.output)
    parent = os.path.dirname(out)
    if not os.path.isdir(parent):
        raise QcError(EXIT_OUTPUT, f"the output's parent folder '{parent}' does not exist")
    try:
        os.mkdir(out)
        return out, True
    except FileExistsError:
        if not os.path.isdir(out):
            raise QcError(EXIT_OUTPUT, f"'{args.output}' exists and is not a folder; it is left "
                                       "alone: choose another -o")
        return out, False
    except OSError as error:
        raise QcError(EXIT_OUTPUT, f"cannot create the folder '{args.output}': {error.strerror}")


def _check_inputs_kept(args: argparse.Namespace, out: str, names: Iterable[str]) -> None:
    """No file the page writes is one of its inputs (by name or by file identity)."""
    inputs = [("--report", path) for path in args.report]
    inputs += [(option, value) for option, value in (("--eval", args.eval), ("--mesh", args.mesh),
                                                     ("--truth", args.truth),
                                                     ("--bake", args.bake)) if value]
    outputs = [("-o", os.path.join(out, name)) for name in names]
    _files.check_distinct(outputs, inputs, lambda message: QcError(EXIT_OUTPUT, message))


def write_report(args: argparse.Namespace, report: _Json, evaluation: Optional[_Json],
                 errors: Optional[_VertexErrors]) -> str:
    """Writes the page into the folder -o (created when missing) and returns its index.html.
    Only the page's own files are written: each is drawn in a temporary folder inside -o, then
    moved to its name, which must be free or hold a file an earlier page wrote (its manifest,
    MANIFEST, lists them); files the earlier page wrote that this one does not are removed.
    Anything else in the folder (a bake's frames and report beside the page) is left alone, and
    a name of the page taken by another file is refused (exit 4) before anything is moved."""
    out, created = _output_folder(args)
    try:
        earlier = earlier_page_files(out)
        temp = tempfile.mkdtemp(prefix=".qc.tmp-", dir=out)
    except OSError as error:
        if created:
            os.rmdir(out)
        raise QcError(EXIT_OUTPUT, f"cannot write in '{args.output}': {error.strerror}")
    except QcError:
        if created:
            os.rmdir(out)
        raise
    try:
        build_page(args, report, evaluation, errors, temp)
        written = {name: _digest(os.path.join(temp, name)) or "" for name in os.listdir(temp)}
        _check_inputs_kept(args, out, written)
        taken = sorted(name for name in written
                       if name not in earlier and os.path.lexists(os.path.join(out, name)))
        if taken:
            raise QcError(EXIT_OUTPUT, f"'{args.output}' holds {', '.join(taken)}, not written "
                                       "by an earlier QC page; nothing is replaced: move "
                                       "them or choose another -o")
        old = {name: _digest(os.path.join(out, name)) or "" for name in earlier}
        # While files move, the manifest accepts each one's earlier and new content.
        _write_manifest(out, {name: sorted({digest, old.get(name, digest)})
                              for name, digest in {**old, **written}.items()})
        for name in sorted(written, key=lambda n: n == "index.html"):  # the page last
            _place(os.path.join(temp, name), os.path.join(out, name), name in earlier)
        for name in sorted(set(earlier) - set(written)):  # an earlier page's plots not drawn now
            os.remove(os.path.join(out, name))
        _write_manifest(out, {name: [digest] for name, digest in written.items()})
    except OSError as error:
        raise QcError(EXIT_OUTPUT, f"cannot write the page into '{args.output}': {error}")
    finally:
        shutil.rmtree(temp, ignore_errors=True)
        if created and not os.listdir(out):
            os.rmdir(out)
    return os.path.join(out, "index.html")


def parse_args(argv: Optional[Sequence[str]]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="python -m drivenshape.qc",
        description="Write a QC page (DIR/index.html and PNG plots) for a drivenshape bake: "
                    "which model made it, the pose model's coverage verdict or the QP's weights "
                    "and residual, penetrations, popping, and with --eval/--mesh the error to "
                    "the truth and the edges' strain per frame and per vertex.",
        epilog="Exit codes: 0 ok, 2 usage, 3 input (a file missing or malformed), 4 output.")
    parser.add_argument("--report", required=True, action="append", metavar="REPORT.json",
                        help="the bake report (repeat for the chunk reports of a farm bake)")
    parser.add_argument("--eval", metavar="EVAL.json",
                        help="`drivenshape eval --json` of this bake: error per frame")
    parser.add_argument("--simulated", metavar="SIMULATE_REPORT.json",
                        help="the report of `drivenshape simulate` on this bake: shows each "
                             "frame's source (baked, simulated, blended) on a timeline")
    parser.add_argument("--mesh", metavar="DRIVEN_REST.obj",
                        help="the driven rest mesh: draws the per-vertex error heat map "
                             "(needs a truth: --eval or --truth)")
    parser.add_argument("--truth", metavar="CACHE",
                        help="truth cache for the heat map (default: the eval JSON's truth)")
    parser.add_argument("--bake", metavar="CACHE",
                        help="baked cache for the heat map (default: the eval JSON's bake, else "
                             "the report's output pattern, as given or beside the JSON)")
    parser.add_argument("--units", choices=("m", "cm", "mm", "scene"), default="m",
                        help="the scene's unit: m (default), cm or mm show lengths in mm; scene "
                             "shows them as stored")
    parser.add_argument("--up-axis", choices=("Y", "Z"), default="Z",
                        help="up axis of the heat map views (Z, drivenshape's data)")
    parser.add_argument("--title", help="page title (default: QC: <shot name>)")
    parser.add_argument("-o", "--output", required=True, metavar="DIR",
                        help="folder to write index.html and the PNGs into")
    args = parser.parse_args(argv)
    if (args.truth or args.bake) and not args.mesh:
        parser.error("--truth and --bake are for the heat map: give --mesh too")
    return args


def main(argv: Optional[Sequence[str]] = None) -> int:
    args = parse_args(argv)
    try:
        try:
            import matplotlib  # noqa: F401  (the plots; checked before any work)
        except ImportError:
            raise QcError(EXIT_USAGE, "the QC page draws with matplotlib, which this Python "
                                      f"({sys.executable}) lacks: run it with the project's "
                                      "venv (scripts/setup.sh) or pip install matplotlib")
        report = merge_reports(args.report)
        evaluation = load_eval(args.eval) if args.eval else None
        if evaluation:
            check_eval_matches(report, evaluation, args.eval)
        errors = None
        if args.mesh:
            if not os.path.isfile(args.mesh):
                raise QcError(EXIT_INPUT, f"mesh '{args.mesh}' does not exist or is not a file")
            if evaluation:
                frames = [r["frame"] for r in evaluation["frames"]]
            else:
                frames = [r["frame"] for r in report["frames"] if not r.get("skipped")]
            if not frames:
                raise QcError(EXIT_INPUT, "no frames to compare with the truth")
            errors = vertex_errors(args, report, evaluation, frames)
            if evaluation:
                check_against_eval(errors, evaluation, args.eval)
        index = write_report(args, report, evaluation, errors)
    except QcError as error:
        print(f"qc: {error}", file=sys.stderr)
        return error.code
    print(f"qc: {index}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
