# SPDX-License-Identifier: Apache-2.0
"""The DrivenShape tab of the 3D view's sidebar (N panel)."""

import bpy

from . import engine, live, module


class _Panel:
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "DrivenShape"


def _wrapped(layout, text, icon="NONE", alert=False, width=48):
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


def length_text(value, unit_settings):
    """A length in Blender units as the scene shows lengths: mm for a metric or imperial scene
    (Blender units x the unit scale are metres), Blender units when the scene has no unit."""
    if unit_settings.system == "NONE":
        return f"{value:.4g} BU"
    return f"{value * unit_settings.scale_length * 1000.0:.1f} mm"


def coverage_lines(record, settings, unit_settings):
    """The pose model's verdict on the live frame: [(text, icon, alert)], empty when the model that
    evaluated it predicts nothing (the QP, the nearest shape, the rest binding). `settings` is
    the Evaluator's describe_settings() (its coverage_tolerance, what the bake's report states)."""
    if record is None or record.predicted_error < 0:
        return []
    predicted = length_text(record.predicted_error, unit_settings)
    tolerance = settings.get("coverage_tolerance")
    limit = "the tolerance" if tolerance is None else length_text(tolerance, unit_settings)
    lines = [(f"Predicted error {predicted} (pose model)", "INFO", False)]
    if record.flagged == 1:
        lines.append((f"Over {limit}: simulate this pose", "ERROR", True))
    else:
        lines.append((f"Within {limit}: DrivenShape is enough", "CHECKMARK", False))
    return lines


class DRIVENSHAPE_PT_main(_Panel, bpy.types.Panel):
    bl_label = "DrivenShape"

    def draw(self, context):
        layout = self.layout
        settings = context.scene.drivenshape
        ok, text = module.status()
        if not ok:
            _wrapped(layout, text, icon="ERROR", alert=True)
            layout.operator("drivenshape.retry_import", icon="FILE_REFRESH")
            return

        column = layout.column()
        column.prop(settings, "driver", icon="OUTLINER_OB_ARMATURE")
        column.prop(settings, "cloth", icon="MOD_CLOTH")
        column.prop(settings, "database_path")

        box = layout.box()
        if live.is_live(context.scene):
            box.operator("drivenshape.live_stop", text="Live Mode", icon="PAUSE", depress=True)
            stats = live.SESSION.stats()
            if stats:
                read, evaluate, write, total = stats
                box.label(text=f"Handler: {total:.1f} ms/frame ({1000.0 / total:.0f} fps)",
                          icon="TIME")
                box.label(text=f"read {read:.2f} · evaluate {evaluate:.1f} · write {write:.2f}")
            record = live.SESSION.last_record
            if record is not None and record.inside_after >= 0:  # measured with Audit on
                units = context.scene.unit_settings
                jump = (f" · largest jump {length_text(record.max_jump, units)}"
                        if record.max_jump >= 0 else "")
                box.label(text=f"inside the body: {record.inside_after}{jump}")
            evaluator = engine.CACHE.evaluator
            if record is not None and evaluator is not None:
                for text, icon, alert in coverage_lines(record, evaluator.describe_settings(),
                                                        context.scene.unit_settings):
                    row = box.row()
                    row.alert = alert
                    row.label(text=text, icon=icon)
            device = engine.CACHE.device
            if device is not None and device.note:  # "auto" found no OpenCL device
                _wrapped(box, device.note, icon="INFO")
        else:
            box.operator("drivenshape.live_start", text="Live Mode", icon="PLAY")
        box.prop(settings, "live_restore")
        if live.LAST_ERROR:
            _wrapped(box, live.LAST_ERROR, icon="ERROR", alert=True)


class DRIVENSHAPE_PT_settings(_Panel, bpy.types.Panel):
    bl_label = "Settings"
    bl_parent_id = "DRIVENSHAPE_PT_main"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        settings = context.scene.drivenshape
        layout.prop(settings, "weight_mode")
        layout.prop(settings, "align")
        layout.prop(settings, "blend")
        layout.prop(settings, "correct")
        column = layout.column()
        column.prop(settings, "resolve")
        row = column.row()
        row.active = settings.resolve
        row.prop(settings, "skin_offset")
        row = column.row()
        row.active = settings.resolve
        row.prop(settings, "exit_fade")
        layout.prop(settings, "max_weight_change")
        layout.prop(settings, "audit")
        layout.prop(settings, "space")
        layout.prop(settings, "device")
        layout.prop(settings, "threads")


class DRIVENSHAPE_PT_build(_Panel, bpy.types.Panel):
    bl_label = "Build Database"
    bl_parent_id = "DRIVENSHAPE_PT_main"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        settings = context.scene.drivenshape
        layout.prop(settings, "build_source")
        if settings.build_source == "PC2":
            layout.prop(settings, "build_driver_pc2")
            layout.prop(settings, "build_cloth_pc2")
        column = layout.column(align=True)
        column.prop(settings, "build_frame_start", text="Frame Start")
        column.prop(settings, "build_frame_end", text="End")
        layout.prop(settings, "build_count")
        layout.prop(settings, "build_model")
        layout.prop(settings, "build_output")
        layout.operator("drivenshape.build_database", icon="IMPORT")


class DRIVENSHAPE_PT_bake(_Panel, bpy.types.Panel):
    bl_label = "Bake"
    bl_parent_id = "DRIVENSHAPE_PT_main"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        settings = context.scene.drivenshape
        layout.prop(settings, "bake_use_scene_range")
        column = layout.column(align=True)
        column.active = not settings.bake_use_scene_range
        column.prop(settings, "bake_frame_start", text="Frame Start")
        column.prop(settings, "bake_frame_end", text="End")
        layout.prop(settings, "bake_pc2_path")
        layout.prop(settings, "bake_write_exr")
        row = layout.row()
        row.active = settings.bake_write_exr
        row.prop(settings, "bake_exr_pattern")
        layout.prop(settings, "bake_add_mesh_cache")
        layout.operator("drivenshape.bake", icon="RENDER_ANIMATION")
        layout.operator("drivenshape.add_mesh_cache", icon="MOD_MESHDEFORM")


CLASSES = (DRIVENSHAPE_PT_main, DRIVENSHAPE_PT_settings, DRIVENSHAPE_PT_build,
           DRIVENSHAPE_PT_bake)


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
