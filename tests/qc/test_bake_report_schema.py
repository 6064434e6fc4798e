# SPDX-License-Identifier: Apache-2.0
"""docs/schemas/bake_report.schema.json against real reports of `drivenshape bake`.

The sample is baked by the command line with every model a bake can run (the default, which is
the pose model on a database `db build` made with its defaults; --weights qp, nearest and bind),
plus a resumed bake (--skip-existing: frames kept from an earlier run) and a pose-model bake
that flags frames; each report must validate (jsonschema, Draft 2020-12). The schema must be
strict: every field of a real report, removed or renamed, makes it fail, and so does a report
whose fields belong to another model than the one its settings name."""

import copy
import json
from pathlib import Path

import jsonschema
import pytest

from conftest import FRAME_COUNT, LOW_TOLERANCE

# (bake name, options, settings.weights the report must state)
BAKES = (("default", (), "model"), ("qp", ("--weights", "qp"), "qp"),
         ("nearest", ("--weights", "nearest"), "nearest"), ("bind", ("--weights", "bind"), "bind"),
         ("flagged", ("--coverage-tolerance", LOW_TOLERANCE), "model"))


@pytest.fixture(scope="session")
def validator(request):
    path = Path(request.config.getoption("--schema"))
    schema = json.loads(path.read_text(encoding="utf-8"))
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


def errors_of(validator, report):
    return [f"{'/'.join(map(str, e.absolute_path))}: {e.message}"
            for e in validator.iter_errors(report)]


def report_of(shot, name):
    options, = [o for n, o, _ in BAKES if n == name]
    return json.loads(shot.bake(name, *options).read_text(encoding="utf-8"))


@pytest.mark.parametrize("name,options,model", BAKES, ids=[b[0] for b in BAKES])
def test_real_reports_validate(shot, validator, name, options, model):
    report = report_of(shot, name)
    assert report["settings"]["weights"] == model, "the bake ran another model than expected"
    assert report["run"]["baked"] == FRAME_COUNT
    assert errors_of(validator, report) == []


def test_a_layered_bake_validates(shot, validator):
    # The layers' entries are generated from the layer options' rows of the settings table:
    # a bake with a mix and a wind (its weight map and falloff too) must validate.
    report = json.loads(shot.bake(
        "layers", "--mix", shot.data / "test.driven.pc2", "--mix-weight", "group:sleeve",
        "--wind-amplitude", "0.003", "--wind-weight", "group:sleeve", "--wind-falloff", "1",
        "--wind-direction", "0,1,0").read_text(encoding="utf-8"))
    layers = report["settings"]["layers"]
    assert set(layers) == {"mix", "wind"} and layers["wind"]["falloff"] == 1
    assert errors_of(validator, report) == []
    layers["wind"]["octaves"] = 9  # beyond the table's range of --wind-octaves
    assert errors_of(validator, report) != []


def test_a_resumed_bake_validates(shot, validator):
    shot.bake("resumed", frames="1-6")
    # The same folder again with --skip-existing: frames 1-6 are kept, the rest baked.
    shot.bakes.pop("resumed")
    report = json.loads(shot.bake("resumed", "--skip-existing").read_text(encoding="utf-8"))
    assert report["run"]["kept"] == 6 and report["run"]["baked"] == FRAME_COUNT - 6
    assert all("predicted_error" in r for r in report["frames"]), "a kept frame lost its record"
    assert errors_of(validator, report) == []


def field_paths(value, path=()):
    """Every object member of a report: top-level fields, nested objects' fields, and the fields
    of one frame record in the middle of the shot."""
    if isinstance(value, dict):
        for key, member in value.items():
            yield path + (key,)
            yield from field_paths(member, path + (key,))
    elif isinstance(value, list) and value and isinstance(value[0], dict):
        middle = len(value) // 2
        yield from field_paths(value[middle], path + (middle,))


def without(report, path, rename=False):
    changed = copy.deepcopy(report)
    parent = changed
    for key in path[:-1]:
        parent = parent[key]
    value = parent.pop(path[-1])
    if rename:
        parent[path[-1] + "_renamed"] = value
    return changed


# Fields a report holds only when it has something to say (docs/formats.md): removing one
# leaves a valid report, renaming one does not.
OPTIONAL = {("warnings",)}


@pytest.mark.parametrize("name", ["default", "qp", "nearest", "bind"])
def test_every_field_is_checked(shot, validator, name):
    report = report_of(shot, name)
    paths = list(field_paths(report))
    assert len(paths) > 60, f"only {len(paths)} fields found in the {name} report"
    for path in paths:
        for rename in (False, True):
            changed = without(report, path, rename)
            if path in OPTIONAL and not rename:
                assert validator.is_valid(changed), f"{'/'.join(map(str, path))} is optional"
                continue
            assert not validator.is_valid(changed), \
                f"the {name} report with {'/'.join(map(str, path))} " \
                f"{'renamed' if rename else 'removed'} still validates"


def object_paths(value, path=()):
    """Every object in a report (the report itself, nested objects, one frame record)."""
    if isinstance(value, dict):
        yield path
        for key, member in value.items():
            yield from object_paths(member, path + (key,))
    elif isinstance(value, list) and value and isinstance(value[0], dict):
        middle = len(value) // 2
        yield from object_paths(value[middle], path + (middle,))


@pytest.mark.parametrize("name", ["default", "qp"])
def test_unknown_fields_fail(shot, validator, name):
    """A field the schema does not describe (a new one the docs lack, a misspelling) fails."""
    report = report_of(shot, name)
    paths = list(object_paths(report))
    assert len(paths) >= 6, paths
    for path in paths:
        changed = copy.deepcopy(report)
        target = changed
        for key in path:
            target = target[key]
        target["unexpected_field"] = "x"
        assert not validator.is_valid(changed), \
            f"an unknown field in {'/'.join(map(str, path)) or 'the report'} validates"


def test_fields_of_another_model_fail(shot, validator):
    pose, qp, bind = (report_of(shot, n) for n in ("default", "qp", "bind"))
    # A QP report that claims the pose model has no predictions; the pose model's report
    # claiming the QP has no weights or direct residual; a bind report with weights.
    for report, model in ((qp, "model"), (pose, "qp"), (pose, "bind"), (bind, "qp")):
        changed = copy.deepcopy(report)
        changed["settings"]["weights"] = model
        assert not validator.is_valid(changed), f"{report['settings']['weights']} as {model}"
    changed = copy.deepcopy(qp)
    middle = changed["frames"][len(changed["frames"]) // 2]
    middle["predicted_error"] = 0.01
    middle["pose_distance"] = 0.5
    middle["coverage"] = {"flagged": False, "score": 0.01}
    assert not validator.is_valid(changed), "a QP frame with a prediction validates"


def test_wrong_types_and_values_fail(shot, validator):
    pose = report_of(shot, "default")
    cases = {
        "predicted error as text": ("frames", 3, "predicted_error", "0.01"),
        "a negative predicted error": ("frames", 3, "predicted_error", -0.01),
        "flagged as a number": ("frames", 3, "coverage", "flagged", 1),
        "an unknown model": ("settings", "weights", "auto"),
        "a lossy compression": ("settings", "compression", "dwaa"),
        "a covered fraction over 1": ("coverage", "covered_fraction", 1.5),
        "a short hash": ("settings_hash", "abc"),
    }
    for label, (*path, value) in cases.items():
        changed = copy.deepcopy(pose)
        parent = changed
        for key in path[:-1]:
            parent = parent[key]
        parent[path[-1]] = value
        assert not validator.is_valid(changed), f"{label} validates"
