# SPDX-License-Identifier: Apache-2.0
"""The settings table (drivenshape/settings_table.h, issue 27) as the Python module and the
Blender add-on see it: EvaluatorSettings' keywords, attributes and repr come from the table; so
do load_layers' and build_database's keywords; the add-on's properties (apps/blender/
drivenshape_blender/settings_generated.py, generated from the table by
scripts/generate_from_settings.py, read here without Blender) have the table's names, defaults,
ranges and choices, and keep the names and menu numbers that saved .blend files hold."""

import ast
import math
from pathlib import Path

import pytest

import drivenshape as ds

ADDON = Path(__file__).resolve().parents[2] / "apps" / "blender" / "drivenshape_blender"

# What .blend files saved by earlier add-ons hold: each property by name, and an enum as the
# number of its item. A renamed property or a renumbered item would silently reset (or change)
# the artist's setting: the table may add settings and items, never move these.
SAVED_PROPERTIES = {
    "weight_mode": ("EnumProperty", {"auto": 0, "model": 1, "qp": 2, "nearest": 3, "bind": 4}),
    "align": ("EnumProperty", {"rigid": 0, "rigid-all": 1, "none": 2}),
    "blend": ("EnumProperty", {"local": 0, "world": 1}),
    "resolve_direction": ("EnumProperty", {"nearest": 0, "normal": 1}),
    "correct": ("BoolProperty", None), "resolve": ("BoolProperty", None),
    "skin_offset": ("FloatProperty", None), "exit_fade": ("FloatProperty", None),
    "max_weight_change": ("FloatProperty", None), "audit": ("BoolProperty", None),
    "threads": ("IntProperty", None), "coverage_tolerance": ("FloatProperty", None),
    "build_count": ("IntProperty", None), "build_model": ("BoolProperty", None),
}

PROPERTY_TYPES = {"BoolProperty": "bool", "IntProperty": "int", "FloatProperty": "number",
                  "EnumProperty": "choice", "StringProperty": "text"}


@pytest.fixture(scope="module")
def table():
    return {row["key"]: row for row in ds.settings_table()}


def evaluator_keys(table):
    return [key for key, row in table.items() if row["scope"] == "evaluator"]


def test_table_rows_are_complete(table):
    for key, row in table.items():
        assert row["help"] and row["label"], key
        assert row["type"] in ("bool", "int", "number", "text", "choice", "object"), key
        # A default outside the range is one of the words ("auto" for model_history).
        words = [word["value"] for word in row["words"]]
        if row["type"] in ("int", "number") and row["default"] not in words:
            assert row["minimum"] <= row["default"], key
            assert row["maximum"] is None or row["default"] <= row["maximum"], key
        if row["type"] == "choice":
            assert row["default"] in row["choices"], key
    assert table["exit_fade"]["default"] == 0.25 and table["exit_fade"]["flag"] == "--exit-fade"
    assert table["exit_fade"]["hashed"] and not table["audit"]["hashed"]


def test_keywords_attributes_and_repr_come_from_the_table(table):
    defaults = ds.EvaluatorSettings()
    text = repr(defaults)
    position = 0
    for key in evaluator_keys(table):
        row = table[key]
        value = getattr(defaults, key)
        if row["type"] != "object":
            assert value == row["default"], key
        # The repr lists every evaluator setting in table order.
        found = text.find(f"{key}=", position)
        assert found > 0, f"{key} missing from {text}"
        position = found
    custom = ds.EvaluatorSettings(exit_fade=0.25, max_weight_change=0.1, threads=2)
    assert custom.exit_fade == 0.25 and "exit_fade=0.25" in repr(custom)
    assert custom.threads == 2 and "threads=2" in repr(custom)
    with pytest.raises(TypeError):
        ds.EvaluatorSettings(exit_fades=0.2)
    # Ranges are checked when a value is set, whichever way.
    with pytest.raises(ds.Error) as error:
        ds.EvaluatorSettings(exit_fade=-1)
    assert error.value.kind == "usage" and "--exit-fade" in str(error.value)
    with pytest.raises(ds.Error) as error:
        custom.max_weight_change = 2
    assert error.value.kind == "usage" and "max_weight_change" in str(error.value)
    assert custom.max_weight_change == 0.1


def test_unused_settings_are_warned_about(cli_database, host_device):
    database = ds.load_database(cli_database)
    quiet = ds.Evaluator(database, ds.EvaluatorSettings(resolve=False), host_device)
    assert quiet.warnings == []
    with pytest.warns(UserWarning, match="exit fade"):
        noisy = ds.Evaluator(database, ds.EvaluatorSettings(resolve=False, exit_fade=0.3),
                             host_device)
    assert len(noisy.warnings) == 1 and "exit_fade=0.3" in noisy.warnings[0]
    # The settings hash does not see an unused exit fade.
    assert noisy.settings_hash == quiet.settings_hash


def _addon_settings():
    """settings_generated.SETTINGS, read as the literal it is (the add-on needs bpy)."""
    tree = ast.parse((ADDON / "settings_generated.py").read_text())
    for node in tree.body:
        if isinstance(node, ast.Assign) and node.targets[0].id == "SETTINGS":
            return ast.literal_eval(node.value)
    raise AssertionError("settings_generated.py has no SETTINGS")


def test_addon_properties_match_the_table():
    table = {row["key"]: row for row in ds.settings_table()}
    settings = _addon_settings()
    assert settings, "the add-on shows no setting of the table"
    shown = [row["key"] for row in table.values() if row["addon"]]
    assert [setting["key"] for setting in settings] == shown
    for setting in settings:
        key, kind, keywords = setting["key"], setting["kind"], setting["keywords"]
        row, view = table[key], table[key]["addon"]
        assert setting["scope"] == row["scope"] in ("evaluator", "build", "simulate"), key
        assert setting["property"] == (view["property"] or key)
        default = row["default"] if view["default"] is None else view["default"]
        if setting["checkbox"]:
            # A two-choice setting as a checkbox: on is one choice, off the other.
            assert kind == "BoolProperty" and sorted(row["choices"]) == sorted(
                [setting["checkbox"], setting["off"]]), key
            assert keywords["default"] == (default == setting["checkbox"]), key
            continue
        assert PROPERTY_TYPES[kind] == row["type"], f"{key}: {kind} for a {row['type']} setting"
        assert keywords["default"] == default, (
            f"{key}: the add-on's default {keywords['default']!r}, the table's {default!r}")
        if row["type"] in ("int", "number"):
            assert keywords["min"] == row["minimum"], f"{key}: min {keywords['min']}"
            assert keywords.get("max") == row["maximum"], f"{key}: max {keywords.get('max')}"
        if row["type"] == "choice":
            items = [item[0] for item in keywords["items"]]
            assert sorted(items) == sorted(row["choices"]), f"{key}: items {items}"
        # A default of the add-on's own differs from the table's and says why.
        if view["default"] is not None:
            assert view["default"] != row["default"] and view["default_why"], key


def test_addon_keeps_what_saved_blend_files_hold():
    properties = {setting["property"]: setting for setting in _addon_settings()}
    for name, (kind, numbers) in SAVED_PROPERTIES.items():
        assert name in properties, f"the add-on lost the property {name} of saved .blend files"
        assert properties[name]["kind"] == kind, f"{name}: {properties[name]['kind']}"
        if numbers is not None:
            items = {item[0]: item[3] for item in properties[name]["keywords"]["items"]}
            assert {choice: items.get(choice) for choice in numbers} == numbers, (
                f"{name}: the menu's numbers {items} moved an item of saved files {numbers}")


def test_layer_and_build_keywords_come_from_the_table(table):
    layer = [key for key, row in table.items() if row["scope"] == "layer"]
    build = [key for key, row in table.items() if row["scope"] == "build"]
    simulate = [key for key, row in table.items() if row["scope"] == "simulate"]
    assert "wind_octaves" in layer and "mix_falloff" in layer and "model_history" in build
    assert "goal_strength" in simulate and "carry" in simulate
    for function, keys in ((ds.load_layers, layer + ["frames_per_second"]),
                           (ds.build_database, build), (ds.plan_simulation, simulate)):
        for key in keys:
            assert f"\n  {key} ({table[key]['flag']}, default " in function.__doc__, key


def test_table_is_finite_json(table):
    for key, row in table.items():
        for field in ("default", "minimum", "maximum"):
            value = row.get(field)
            if isinstance(value, float):
                assert math.isfinite(value), (key, field)
