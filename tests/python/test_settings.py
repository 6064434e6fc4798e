# SPDX-License-Identifier: Apache-2.0
"""The settings table (drivenshape/settings_table.h, issue 27) as the Python module and the
Blender add-on see it: EvaluatorSettings' keywords, attributes and repr come from the table, and
the add-on's properties (apps/blender/drivenshape_blender/properties.py, read here as source
without Blender) have the table's names, defaults, ranges and choices."""

import ast
import math
from pathlib import Path

import pytest

import drivenshape as ds

ADDON = Path(__file__).resolve().parents[2] / "apps" / "blender" / "drivenshape_blender"

# Where the add-on differs from the table on purpose: the setting, and why.
ADDON_DEFAULTS = {
    "audit": (False, "live mode evaluates every frame the animator scrubs to; the audit costs "
                     "time there and its counts are only shown when asked for"),
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
        if row["type"] in ("int", "number"):
            assert row["minimum"] <= row["default"], key
            assert row["maximum"] is None or row["default"] <= row["maximum"], key
        if row["type"] == "choice":
            assert row["default"] in row["choices"], key
    assert table["exit_fade"]["default"] == 0.15 and table["exit_fade"]["flag"] == "--exit-fade"
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


def _addon_properties():
    """{name: (property type, {keyword: value})} of DrivenShapeSettings, and the module's
    constants (the enum items), from the add-on's source."""
    tree = ast.parse((ADDON / "properties.py").read_text())
    constants = {}
    properties = {}
    for node in tree.body:
        if isinstance(node, ast.Assign) and len(node.targets) == 1:
            try:
                constants[node.targets[0].id] = ast.literal_eval(node.value)
            except ValueError:
                pass
        if isinstance(node, ast.ClassDef) and node.name == "DrivenShapeSettings":
            # Blender's properties are annotations: `name: FloatProperty(...)`.
            for item in node.body:
                if isinstance(item, ast.AnnAssign) and isinstance(item.annotation, ast.Call):
                    call = item.annotation
                    keywords = {}
                    for keyword in call.keywords:
                        if isinstance(keyword.value, ast.Name):
                            keywords[keyword.arg] = constants.get(keyword.value.id)
                        else:
                            try:
                                keywords[keyword.arg] = ast.literal_eval(keyword.value)
                            except ValueError:
                                pass  # callbacks, types
                    properties[item.target.id] = (call.func.id, keywords)
    return properties


def _engine_keywords():
    """The keywords engine.evaluator_kwargs passes to EvaluatorSettings."""
    tree = ast.parse((ADDON / "engine.py").read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef) and node.name == "evaluator_kwargs":
            call = next(n for n in ast.walk(node) if isinstance(n, ast.Call))
            return [keyword.arg for keyword in call.keywords]
    raise AssertionError("engine.py has no evaluator_kwargs")


def test_addon_properties_match_the_table(table):
    properties = _addon_properties()
    passed = _engine_keywords()
    assert passed, "engine.evaluator_kwargs passes no settings"
    for key in passed:
        assert key in table, f"the add-on passes '{key}', which is not in the settings table"
        assert key in properties, f"the add-on passes '{key}' but has no property of that name"
    checked = sorted(set(properties) & set(table))
    assert set(passed) <= set(checked)
    for key in checked:
        row = table[key]
        kind, keywords = properties[key]
        assert PROPERTY_TYPES[kind] == row["type"], f"{key}: {kind} for a {row['type']} setting"
        default = ADDON_DEFAULTS.get(key, (row["default"], ""))[0]
        assert keywords.get("default") == default, (
            f"{key}: the add-on's default {keywords.get('default')!r}, the table's "
            f"{row['default']!r}")
        if row["type"] in ("int", "number"):
            assert keywords.get("min") == row["minimum"], f"{key}: min {keywords.get('min')}"
            if row["maximum"] is None:
                assert "max" not in keywords, f"{key}: the table has no maximum"
            else:
                assert keywords.get("max") == row["maximum"], f"{key}: max {keywords.get('max')}"
        if row["type"] == "choice":
            items = [item[0] for item in keywords["items"]]
            assert sorted(items) == sorted(row["choices"]), f"{key}: items {items}"
    # The deliberate differences are still differences (else drop them from ADDON_DEFAULTS).
    for key, (value, why) in ADDON_DEFAULTS.items():
        assert table[key]["default"] != value and why, key


def test_table_is_finite_json(table):
    for key, row in table.items():
        for field in ("default", "minimum", "maximum"):
            value = row.get(field)
            if isinstance(value, float):
                assert math.isfinite(value), (key, field)
