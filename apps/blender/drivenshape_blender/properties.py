# SPDX-License-Identifier: Apache-2.0
"""The add-on's settings: one DrivenShapeSettings per scene (scene.drivenshape) and the
add-on preference that says where the drivenshape module is."""

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

WEIGHT_MODES = (
    ("auto", "Auto", "The pose model when the database has one, else the DrivenShape QP"),
    ("model", "Pose Model", "The rest binding plus the pose model's learned correction, fitted "
     "over the whole reference clip"),
    ("qp", "QP Blend", "DrivenShape as in the talk: blend weights that best reproduce the pose "
     "(a QP)"),
    ("nearest", "Nearest", "Baseline: all weight on the closest database driver shape"),
    ("bind", "Bind Only", "Baseline: no database shapes; the rest cloth carried by the driver"),
)
ALIGN_MODES = (
    ("rigid", "Rigid", "Fit each frame rigidly to the rest driver, following its most rigid "
     "part (the pelvis, not the legs) before solving the weights"),
    ("rigid-all", "Rigid (All)", "The same rigid fit, every vertex weighted alike"),
    ("none", "None", "Compare world positions, as in the talk"),
)
BLEND_MODES = (
    ("local", "Local Frames", "Blend the shapes' offsets in the driver's local frames and "
     "rebuild them on the current pose (no per-frame search)"),
    ("world", "World", "Blend world positions, then correct onto the pose (the talk)"),
)
RESOLVE_DIRECTIONS = (
    ("nearest", "Nearest", "Cloth within the offset moves along the line from its closest point on "
     "the driver (smooth where that point crosses an edge); cloth inside along the normal"),
    ("normal", "Normal", "Every vertex moves along the driver's normal at its closest point "
     "(0.1; jumps where that point crosses from a face onto an edge)"),
)
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
    build_count: IntProperty(
        name="Shapes", default=30, min=1, soft_max=128,
        description="Number of database shapes (driver/cloth pairs) to pick")
    build_model: BoolProperty(
        name="Pose Model", default=True,
        description="Also fit the pose model over every reference frame (what the Auto weights "
        "evaluate); off keeps the picked shapes only")
    build_output: StringProperty(
        name="Save As", subtype="FILE_PATH", default="//drivenshape.dsdb",
        description="Where the new database is written; it then becomes the scene's database")

    # Evaluator settings (defaults: the command line's bake).
    weight_mode: EnumProperty(name="Weights", items=WEIGHT_MODES, default="auto",
                              update=_settings_changed)
    align: EnumProperty(name="Align", items=ALIGN_MODES, default="rigid",
                        update=_settings_changed)
    blend: EnumProperty(name="Blend", items=BLEND_MODES, default="local",
                        update=_settings_changed)
    correct: BoolProperty(
        name="Collision Correction", default=True, update=_settings_changed,
        description="Carry the blended cloth onto the current pose of the driver")
    resolve: BoolProperty(
        name="Resolve Penetrations", default=True, update=_settings_changed,
        description="Move cloth vertices inside the driver (or closer than the skin offset) out")
    skin_offset: FloatProperty(
        name="Skin Offset", default=0.002, min=0.0, soft_max=0.05, precision=4, step=0.01,
        update=_settings_changed,
        description="Distance the penetration resolution keeps between cloth and driver "
        "(scene units)")
    resolve_direction: EnumProperty(name="Direction", items=RESOLVE_DIRECTIONS, default="nearest",
                                    update=_settings_changed)
    exit_fade: FloatProperty(
        name="Exit Fade", default=0.15, min=0.0, soft_max=1.0, precision=2, step=1,
        update=_settings_changed,
        description="Cloth deep in a limb or a bent joint whose two nearest exits are nearly "
        "equally far moves only part of the way out, so it does not jump across (0: always "
        "all the way)")
    max_weight_change: FloatProperty(
        name="Temporal Bound", default=0.0, min=0.0, max=1.0, precision=3, step=1,
        update=_settings_changed,
        description="Largest change of a shape's weight between consecutive frames (0: off)")
    audit: BoolProperty(
        name="Audit", default=False, update=_settings_changed,
        description="Count cloth vertices inside the driver and the largest jump per frame "
        "(shown in the panel; costs time)")
    device: StringProperty(
        name="Device", default="auto", update=_settings_changed,
        description="auto, host, cpu, gpu, an index from `drivenshape devices` or part of a "
        "device name")
    threads: IntProperty(
        name="Threads", default=0, min=0, soft_max=64, update=_settings_changed,
        description="Host threads (0: all cores)")
    space: EnumProperty(name="Space", items=SPACES, default="LOCAL", update=_settings_changed)
    coverage_tolerance: FloatProperty(
        name="Tolerance", default=0.0, min=0.0, soft_max=0.1, precision=4, step=0.1,
        unit="LENGTH", update=_settings_changed,
        description="Coverage tolerance: a frame whose predicted mean vertex error (pose model) "
        "is over it is flagged to simulate (0: 2% of the cloth's rest bounding-box diagonal, "
        "as in the command line)")

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


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Scene.drivenshape = PointerProperty(type=DrivenShapeSettings)


def unregister():
    del bpy.types.Scene.drivenshape
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
