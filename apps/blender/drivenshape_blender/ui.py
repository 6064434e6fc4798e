# SPDX-License-Identifier: Apache-2.0
"""The DrivenShape tab of the 3D view's sidebar (N panel).

Everything fits the sidebar's default width (about 190 pixels of text at a UI scale of 1): short
labels in a property split (the tooltips carry the detail), values that could be long as
label-value pairs, messages wrapped to the region's width, rarely changed settings in closed
sub-panels. scripts/blender_screenshot.py shows it at that width.

The library's settings are drawn from the settings table (settings_generated.SETTINGS: which
panel, the row's text and heading, what greys it out), in the table's order; a setting added
to the table with a panel shows up there without a change here."""

import bpy

from . import coverage, engine, live, module
from .settings_generated import SETTINGS

# Average width of a character of the UI font at a UI scale of 1, in pixels (for wrapping).
CHAR_PIXELS = 7.0


class _Panel:
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "DrivenShape"


def _split(layout):
    layout.use_property_split = True
    layout.use_property_decorate = False
    return layout


def _chars(context):
    """How many characters of a message fit on a line of the region (after an icon)."""
    region = getattr(context, "region", None)
    width = region.width if region else 220
    return max(16, int(width / (CHAR_PIXELS * context.preferences.view.ui_scale)) - 7)


def _wrapped(layout, text, width, icon="NONE", alert=False):
    """A long message as several labels (panels do not wrap text)."""
    column = layout.column(align=True)
    column.alert = alert
    words, line, first = text.split(), "", True
    for word in words:
        if line and len(line) + 1 + len(word) > width:
            column.label(text=line, icon=icon if first else "BLANK1")
            line, first = word, False
        else:
            line = f"{line} {word}" if line else word
    if line:
        column.label(text=line, icon=icon if first else "BLANK1")


def _pair(layout, label, value, icon="NONE", alert=False):
    """A read-only value beside its label, aligned as a property split aligns them."""
    split = layout.split(factor=0.4)
    left = split.row()
    left.alignment = "RIGHT"
    left.label(text=label)
    right = split.row()
    right.alert = alert
    right.label(text=value, icon=icon)


def _table_settings(layout, settings, panel):
    """The settings table's settings of `panel`, one row each."""
    for setting in SETTINGS:
        if setting["panel"] != panel:
            continue
        heading = setting["heading"]
        column = layout.column(heading=heading) if heading else layout.column()
        if setting["active_with"]:
            column.active = getattr(settings, setting["active_with"])
        column.prop(settings, setting["property"], text=setting["text"])


def length_text(value, unit_settings):
    return engine.length_text(value, unit_settings)


def coverage_lines(record, settings, unit_settings):
    """The pose model's verdict on the live frame: [(label, value, alert)], empty when the model
    that evaluated it predicts nothing (the QP, the nearest shape, the rest binding). `settings`
    is the Evaluator's describe_settings() (its coverage_tolerance, what the bake's report
    states)."""
    if record is None or record.predicted_error < 0:
        return []
    predicted = length_text(record.predicted_error, unit_settings)
    tolerance = settings.get("coverage_tolerance")
    limit = "tolerance" if tolerance is None else length_text(tolerance, unit_settings)
    bound = length_text(record.error_bound, unit_settings)
    lines = [("Predicted", predicted, False), ("Bound", bound, False)]
    if record.flagged == 1:
        lines.append(("Simulate", f"Yes: > {limit}", True))
    else:
        lines.append(("Simulate", f"No: ≤ {limit}", False))
    return lines


def verdict_lines(settings, unit_settings):
    """What the stored verdicts (the last bake or marking) say: [(label, value, alert)], empty
    when none are stored."""
    verdicts = settings.verdicts
    if not verdicts:
        return []
    flagged = len(coverage.flagged_frames(settings))
    frames = f"{verdicts[0].frame}-{verdicts[-1].frame}"
    return [("Frames", frames, False),
            ("Simulate", f"{flagged} of {len(verdicts)}", flagged > 0),
            ("Tolerance", length_text(settings.verdict_tolerance, unit_settings), False)]


def color_scale_lines(tolerance, unit_settings):
    """The Error Colors scale: [(icon, text)] from green to red, in the scene's units."""
    if tolerance is None or tolerance <= 0:
        return [("SEQUENCE_COLOR_09", "No prediction yet")]
    return [("SEQUENCE_COLOR_04", f"{length_text(0.5 * tolerance, unit_settings)} or less"),
            ("SEQUENCE_COLOR_03", f"{length_text(tolerance, unit_settings)} tolerance"),
            ("SEQUENCE_COLOR_01", f"{length_text(1.5 * tolerance, unit_settings)} or more"),
            ("SEQUENCE_COLOR_09", "No prediction")]


class DRIVENSHAPE_PT_main(_Panel, bpy.types.Panel):
    bl_label = "DrivenShape"

    def draw(self, context):
        layout = self.layout
        settings = context.scene.drivenshape
        ok, text = module.status()
        if not ok:
            _wrapped(layout, text, _chars(context), icon="ERROR", alert=True)
            layout.operator("drivenshape.retry_import", text="Retry", icon="FILE_REFRESH")
            return

        column = _split(layout.column())
        column.prop(settings, "driver", icon="OUTLINER_OB_ARMATURE")
        column.prop(settings, "cloth", icon="MOD_CLOTH")
        column.prop(settings, "database_path")

        box = layout.box()
        units = context.scene.unit_settings
        if live.is_live(context.scene):
            box.operator("drivenshape.live_stop", text="Live Mode", icon="PAUSE", depress=True)
            stats = live.SESSION.stats()
            if stats:
                read, evaluate, write, total = stats
                _pair(box, "Frame", f"{total:.1f} ms, {1000.0 / total:.0f} fps")
                _pair(box, "Evaluate", f"{evaluate:.1f} ms")
                _pair(box, "Read", f"{read:.2f} ms")
                _pair(box, "Write", f"{write:.2f} ms")
            record = live.SESSION.last_record
            if record is not None and record.inside_after >= 0:  # measured with Audit on
                _pair(box, "Inside", f"{record.inside_after} vertices")
                if record.max_jump >= 0:
                    _pair(box, "Jump", length_text(record.max_jump, units))
            evaluator = engine.CACHE.evaluator
            if record is not None and evaluator is not None:
                for label, value, alert in coverage_lines(record, evaluator.describe_settings(),
                                                          units):
                    _pair(box, label, value, alert=alert)
            device = engine.CACHE.device
            if device is not None and device.note:  # "auto" found no OpenCL device
                _wrapped(box, device.note, _chars(context), icon="INFO")
        else:
            box.operator("drivenshape.live_start", text="Live Mode", icon="PLAY")
        box.prop(settings, "live_restore", text="Restore on Stop")
        if live.LAST_ERROR:
            _wrapped(box, live.LAST_ERROR, _chars(context), icon="ERROR", alert=True)


class DRIVENSHAPE_PT_coverage(_Panel, bpy.types.Panel):
    bl_label = "Frames to Simulate"
    bl_parent_id = "DRIVENSHAPE_PT_main"

    def draw(self, context):
        layout = self.layout
        scene = context.scene
        settings = scene.drivenshape
        units = scene.unit_settings
        _table_settings(_split(layout), settings, "coverage")
        layout.operator("drivenshape.mark_frames", text="Mark Frames", icon="MARKER_HLT")
        lines = verdict_lines(settings, units)
        if not lines:
            _wrapped(layout, "Bake or mark frames (pose model) to see which to simulate.",
                     _chars(context), icon="INFO")
        for label, value, alert in lines:
            _pair(layout, label, value, alert=alert)
        if coverage.flagged_frames(settings):
            row = layout.row(align=True)
            row.operator("drivenshape.jump_flagged", text="", icon="TRIA_LEFT").previous = True
            row.operator("drivenshape.jump_flagged", text="Next", icon="TRIA_RIGHT").previous \
                = False
            row.operator("drivenshape.clear_marks", text="", icon="X")
            _table_settings(_split(layout), settings, "simulate")
            layout.operator("drivenshape.simulate_flagged", icon="MOD_CLOTH")
        elif lines:
            layout.operator("drivenshape.clear_marks", text="Clear", icon="X")

        layout.prop(settings, "error_colors")
        if settings.error_colors:
            tolerance = settings.verdict_tolerance
            if live.is_live(scene) and live.SESSION.tolerance > 0:
                tolerance = live.SESSION.tolerance
            column = layout.column(align=True)
            for icon, text in color_scale_lines(tolerance, units):
                column.label(text=text, icon=icon)


class DRIVENSHAPE_PT_settings(_Panel, bpy.types.Panel):
    bl_label = "Settings"
    bl_parent_id = "DRIVENSHAPE_PT_main"

    def draw(self, context):
        layout = _split(self.layout)
        settings = context.scene.drivenshape
        _table_settings(layout, settings, "settings")
        layout.prop(settings, "space")


class DRIVENSHAPE_PT_collision(_Panel, bpy.types.Panel):
    bl_label = "Collision"
    bl_parent_id = "DRIVENSHAPE_PT_settings"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        _table_settings(_split(self.layout), context.scene.drivenshape, "collision")


class DRIVENSHAPE_PT_device(_Panel, bpy.types.Panel):
    bl_label = "Device"
    bl_parent_id = "DRIVENSHAPE_PT_settings"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = _split(self.layout)
        settings = context.scene.drivenshape
        layout.prop(settings, "device")
        _table_settings(layout, settings, "device")


class DRIVENSHAPE_PT_build(_Panel, bpy.types.Panel):
    bl_label = "Build Database"
    bl_parent_id = "DRIVENSHAPE_PT_main"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = _split(self.layout)
        settings = context.scene.drivenshape
        layout.prop(settings, "build_source", text="From")
        if settings.build_source == "PC2":
            layout.prop(settings, "build_driver_pc2", text="Driver")
            layout.prop(settings, "build_cloth_pc2", text="Cloth")
        column = layout.column(align=True)
        column.prop(settings, "build_frame_start", text="Frame Start")
        column.prop(settings, "build_frame_end", text="End")
        _table_settings(layout, settings, "build")
        layout.prop(settings, "build_output")
        layout.operator("drivenshape.build_database", text="Build", icon="IMPORT")


class DRIVENSHAPE_PT_bake(_Panel, bpy.types.Panel):
    bl_label = "Bake"
    bl_parent_id = "DRIVENSHAPE_PT_main"

    def draw(self, context):
        layout = _split(self.layout)
        settings = context.scene.drivenshape
        layout.prop(settings, "bake_use_scene_range")
        column = layout.column(align=True)
        column.active = not settings.bake_use_scene_range
        column.prop(settings, "bake_frame_start", text="Frame Start")
        column.prop(settings, "bake_frame_end", text="End")
        layout.prop(settings, "bake_pc2_path")
        layout.column(heading="EXR").prop(settings, "bake_write_exr", text="Point Caches")
        row = layout.row()
        row.active = settings.bake_write_exr
        row.prop(settings, "bake_exr_pattern", text="Pattern")
        layout.column(heading="Add").prop(settings, "bake_add_mesh_cache", text="Mesh Cache")
        layout.operator("drivenshape.bake", icon="RENDER_ANIMATION")
        layout.operator("drivenshape.add_mesh_cache", icon="MOD_MESHDEFORM")


CLASSES = (DRIVENSHAPE_PT_main, DRIVENSHAPE_PT_coverage, DRIVENSHAPE_PT_settings,
           DRIVENSHAPE_PT_collision, DRIVENSHAPE_PT_device, DRIVENSHAPE_PT_build,
           DRIVENSHAPE_PT_bake)


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
