# SPDX-License-Identifier: Apache-2.0
"""The add-on's settings: one DrivenShapeSettings per scene (scene.drivenshape) and the
add-on preference that says where the drivenshape module is.

The settings that are the library's (weights, collision, threads, the database build's shape
count, ...) are not spelled here: they are the settings table's rows, generated into
settings_generated.py, and become properties of DrivenShapeSettings below (register). Here are
the add-on's own: objects, files, frame ranges, live mode, the space, the device."""

import bpy
from bpy.props import (
    BoolProperty,
    CollectionProperty,
    EnumProperty,
    FloatProperty,
    IntProperty,
    PointerProperty,
    StringProperty,
)

from .settings_generated import SETTINGS

SPACES = (
    ("LOCAL", "Object", "The driver's object-space positions go in and the cloth's object-space "
     "positions come out, as Mesh Cache modifiers read PC2 files"),
    ("WORLD", "World", "The driver's world positions go in; the result is world space, moved "
     "into the cloth object's space when written"),
)
BUILD_SOURCES = (
    ("ANIMATION", "Animation", "The objects' animation: sample the driver's and the cloth's "
     "evaluated meshes over the frame range (Mesh Cache modifiers, a cloth simulation, an "
     "armature)"),
    ("PC2", "PC2 Files", "Read the reference driver and cloth animation from PC2 files"),
)


def _is_mesh(_self, obj):
    return obj.type == "MESH"


def _settings_changed(_self, context):
    # Imported here: live imports this module.
    from . import live  # noqa: PLC0415

    live.settings_changed(context)


def _error_colors_changed(_self, context):
    from . import coverage  # noqa: PLC0415

    coverage.error_colors_changed(context)


class DrivenShapeVerdict(bpy.types.PropertyGroup):
    """One evaluated frame's coverage verdict, from the last bake or Mark Frames to Simulate."""

    frame: IntProperty(name="Frame")
    error_bound: FloatProperty(name="Error Bound", unit="LENGTH",
                               description="The verdict's bound on the mean vertex error (scene "
                               "units), calibrated to hold on the database's verdict level of "
                               "frames")
    flagged: BoolProperty(name="Simulate",
                          description="The error bound is over the coverage tolerance")
    marker: StringProperty(name="Marker",
                           description="The timeline marker the add-on put on the frame, if any")


class DrivenShapeSettings(bpy.types.PropertyGroup):
    # Objects and database.
    driver: PointerProperty(
        name="Driver", type=bpy.types.Object, poll=_is_mesh, update=_settings_changed,
        description="The body mesh that drives the cloth (same vertex order as the database's "
        "driver mesh)")
    cloth: PointerProperty(
        name="Cloth", type=bpy.types.Object, poll=_is_mesh, update=_settings_changed,
        description="The cloth mesh to deform (same vertex order as the database's driven mesh)")
    database_path: StringProperty(
        name="Database", subtype="FILE_PATH", update=_settings_changed,
        description="The .dsdb database that live mode and bakes use")

    # Building a database.
    build_source: EnumProperty(name="Reference", items=BUILD_SOURCES, default="ANIMATION")
    build_driver_pc2: StringProperty(
        name="Driver PC2", subtype="FILE_PATH",
        description="Reference animation of the driver (PC2, the driver's vertex order)")
    build_cloth_pc2: StringProperty(
        name="Cloth PC2", subtype="FILE_PATH",
        description="Reference animation of the cloth (PC2, the cloth's vertex order)")
    build_frame_start: IntProperty(name="Start", default=1,
                                   description="First reference frame")
    build_frame_end: IntProperty(name="End", default=250, description="Last reference frame")
    build_output: StringProperty(
        name="Save As", subtype="FILE_PATH", default="//drivenshape.dsdb",
        description="Where the new database is written; it then becomes the scene's database")

    # The evaluator's settings are the table's (register); the device and the space are
    # the add-on's.
    device: StringProperty(
        name="Device", default="auto", update=_settings_changed,
        description="auto, host, cpu, gpu, an index from `drivenshape devices` or part of a "
        "device name")
    space: EnumProperty(name="Space", items=SPACES, default="LOCAL", update=_settings_changed)

    # The last bake's or Mark Frames to Simulate's verdicts (coverage.py).
    verdicts: CollectionProperty(type=DrivenShapeVerdict)
    verdict_tolerance: FloatProperty(
        name="Tolerance Used", default=-1.0, unit="LENGTH",
        description="The coverage tolerance of the stored verdicts (-1: none stored)")
    error_colors: BoolProperty(
        name="Error Colors", default=False, update=_error_colors_changed,
        description="Color the cloth by the pose model's predicted error (one color per frame: "
        "green at half the tolerance, yellow at it, red at 1.5 times it), in a color attribute "
        "shown by Solid shading's Attribute colors")

    # Live mode.
    live_restore: BoolProperty(
        name="Restore Rest on Stop", default=True,
        description="Put the cloth mesh back to the positions it had when live mode started")

    # Baking.
    bake_use_scene_range: BoolProperty(name="Scene Range", default=True,
                                       description="Bake the scene's frame range")
    bake_frame_start: IntProperty(name="Start", default=1)
    bake_frame_end: IntProperty(name="End", default=250)
    bake_pc2_path: StringProperty(
        name="PC2", subtype="FILE_PATH", default="//drivenshape/cloth.pc2",
        description="The baked cloth as a PC2 point cache (cloth object space)")
    bake_write_exr: BoolProperty(
        name="EXR Point Caches", default=False,
        description="Also write one point-cache EXR per frame (the command line's format)")
    bake_exr_pattern: StringProperty(
        name="EXR", subtype="FILE_PATH", default="//drivenshape/cloth.####.exr",
        description="Point-cache EXR pattern; #### is the frame number")
    bake_add_mesh_cache: BoolProperty(
        name="Add Mesh Cache Modifier", default=True,
        description="Show the bake on the cloth with a Mesh Cache modifier reading the PC2")


def _module_path_changed(_self, _context):
    from . import module  # noqa: PLC0415

    module.forget_failure()


class DrivenShapePreferences(bpy.types.AddonPreferences):
    bl_idname = __package__

    module_path: StringProperty(
        name="Module Folder", subtype="DIR_PATH", update=_module_path_changed,
        description="Folder that holds the drivenshape/ Python package (the build's python/ "
        "folder). Empty: DRIVENSHAPE_PYTHONPATH, then the install locations")

    def draw(self, _context):
        from . import module  # noqa: PLC0415

        layout = self.layout
        layout.prop(self, "module_path")
        ok, text = module.status()
        row = layout.row()
        row.alert = not ok
        row.label(text=text if ok else "Not found (see the DrivenShape panel)",
                  icon="CHECKMARK" if ok else "ERROR")
        layout.operator("drivenshape.retry_import")


CLASSES = (DrivenShapeVerdict, DrivenShapeSettings, DrivenShapePreferences)


def table_property(setting):
    """The Blender property of a generated setting (settings_generated.SETTINGS); a change
    rebuilds the live evaluator."""
    kind = getattr(bpy.props, setting["kind"])
    return kind(**setting["keywords"], update=_settings_changed)


def register():
    # The table's settings become properties of DrivenShapeSettings before Blender reads its
    # annotations (register_class).
    for setting in SETTINGS:
        DrivenShapeSettings.__annotations__[setting["property"]] = table_property(setting)
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Scene.drivenshape = PointerProperty(type=DrivenShapeSettings)


def unregister():
    del bpy.types.Scene.drivenshape
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
