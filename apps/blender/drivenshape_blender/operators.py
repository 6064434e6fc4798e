# SPDX-License-Identifier: Apache-2.0
"""Operators: live mode on and off, building a database, baking and marking the frames to simulate
(modal with progress and Esc from the UI, all at once from scripts), going to the flagged
frames, simulating them (simulate.py), the Mesh Cache modifier, retrying the module import.
Every failure is reported with self.report({'ERROR'}, ...) naming the file, frame or object."""

import time

import bpy
from bpy.props import BoolProperty, StringProperty

from . import bake, coverage, engine, live, module, simulate
from .engine import UserError


def _report_failure(operator, error):
    if isinstance(error, (UserError, module.ModuleMissing)):
        operator.report({"ERROR"}, str(error))
    else:
        operator.report({"ERROR"}, engine.describe_error(error))
    return {"CANCELLED"}


def _run_reporting(operator, context, work):
    """Runs work(context), which returns a summary, at once with the progress bar up; reports
    the summary, or the failure."""
    window_manager = context.window_manager
    window_manager.progress_begin(0, 1)
    try:
        summary = work(context)
    except Exception as error:
        return _report_failure(operator, error)
    finally:
        window_manager.progress_end()
    operator.report({"INFO"}, summary)
    return {"FINISHED"}


class DRIVENSHAPE_OT_live_start(bpy.types.Operator):
    bl_idname = "drivenshape.live_start"
    bl_label = "Start Live Mode"
    bl_description = ("Deform the cloth with the database on every frame change and while "
                      "scrubbing")
    bl_options = {"REGISTER"}

    def execute(self, context):
        try:
            live.start(context)
        except Exception as error:  # UserError, ModuleMissing, or an evaluator error
            return _report_failure(self, error)
        cloth = context.scene.drivenshape.cloth
        for modifier in cloth.modifiers:
            if modifier.show_viewport and modifier.type in {"MESH_CACHE", "CLOTH",
                                                            "MESH_SEQUENCE_CACHE"}:
                self.report({"WARNING"}, f"The cloth's modifier '{modifier.name}' replaces "
                            "its positions: the live result is hidden while it is on")
        return {"FINISHED"}


class DRIVENSHAPE_OT_live_stop(bpy.types.Operator):
    bl_idname = "drivenshape.live_stop"
    bl_label = "Stop Live Mode"
    bl_description = "Stop deforming the cloth (its rest positions come back, if set so)"
    bl_options = {"REGISTER"}

    def execute(self, _context):
        live.stop(restore=True)
        return {"FINISHED"}


class DRIVENSHAPE_OT_build_database(bpy.types.Operator):
    bl_idname = "drivenshape.build_database"
    bl_label = "Build Database"
    bl_description = ("Pick the database shapes from the reference animation (farthest-point), "
                      "save the .dsdb and use it")
    bl_options = {"REGISTER"}

    def execute(self, context):
        return _run_reporting(self, context, bake.build_database)


class _ShotOperator:
    """Runs a bake.Bake job: all at once from a script (execute), a few frames per timer tick
    from the UI (invoke, modal) with a progress bar and the status text; Esc cancels."""

    STEP_SECONDS = 0.2
    WRITE_FILES = True
    STATUS = "DrivenShape"
    _bake = None
    _timer = None

    def execute(self, context):
        # From scripts (and background mode): the whole range at once.
        try:
            job = bake.Bake(context, write_files=self.WRITE_FILES)
        except Exception as error:
            return _report_failure(self, error)
        window_manager = context.window_manager
        window_manager.progress_begin(0, job.total)
        try:
            while not job.step(context):
                window_manager.progress_update(job.done)
            summary = job.finish()
        except Exception as error:
            job.restore_frame()
            return _report_failure(self, error)
        finally:
            window_manager.progress_end()
        self._report_done(summary, job.warnings)
        return {"FINISHED"}

    def _report_done(self, summary, warnings):
        self.report({"INFO"}, summary)
        for warning in warnings:
            self.report({"WARNING"}, warning)

    def invoke(self, context, _event):
        # From the UI: a few frames per timer tick, progress in the status bar, Esc cancels.
        try:
            self._bake = bake.Bake(context, write_files=self.WRITE_FILES)
        except Exception as error:
            return _report_failure(self, error)
        window_manager = context.window_manager
        window_manager.progress_begin(0, self._bake.total)
        self._timer = window_manager.event_timer_add(0.001, window=context.window)
        window_manager.modal_handler_add(self)
        self._status(context)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if event.type == "ESC":
            frame = self._bake.frames[min(self._bake.done, self._bake.total - 1)]
            self._end(context)
            self._bake.restore_frame()
            self.report({"WARNING"}, f"{self.bl_label} cancelled at frame {frame}: "
                        f"{self._cancelled()}")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"RUNNING_MODAL"}
        try:
            # Steps for up to STEP_SECONDS per tick: the viewport redraws between ticks.
            started = time.perf_counter()
            finished = self._bake.step(context)
            while not finished and time.perf_counter() - started < self.STEP_SECONDS:
                finished = self._bake.step(context)
            context.window_manager.progress_update(self._bake.done)
            self._status(context)
            if not finished:
                return {"RUNNING_MODAL"}
            summary = self._bake.finish()
        except Exception as error:
            self._end(context)
            self._bake.restore_frame()
            return _report_failure(self, error)
        self._end(context)
        self._report_done(summary, self._bake.warnings)
        return {"FINISHED"}

    def _cancelled(self):
        return "the markers are as they were"

    def _status(self, context):
        job = self._bake
        context.workspace.status_text_set(
            f"{self.STATUS}: {job.done}/{job.total} frames (Esc to cancel)")

    def _end(self, context):
        window_manager = context.window_manager
        if self._timer is not None:
            window_manager.event_timer_remove(self._timer)
            self._timer = None
        window_manager.progress_end()
        context.workspace.status_text_set(None)


class DRIVENSHAPE_OT_bake(_ShotOperator, bpy.types.Operator):
    bl_idname = "drivenshape.bake"
    bl_label = "Bake"
    bl_description = ("Evaluate the frame range, write a PC2 (and EXR point caches), show it "
                      "on the cloth with a Mesh Cache modifier and mark the frames to simulate "
                      "on the timeline. Esc cancels")
    bl_options = {"REGISTER"}
    STATUS = "DrivenShape bake"

    def _cancelled(self):
        written = (f"; {self._bake.exr_written} EXRs were written"
                   if self._bake.exr_written else "")
        return f"no PC2 written{written}"


class DRIVENSHAPE_OT_mark_frames(_ShotOperator, bpy.types.Operator):
    bl_idname = "drivenshape.mark_frames"
    bl_label = "Mark Frames to Simulate"
    bl_description = ("Evaluate the scene's frame range as the bake does, writing no file, and "
                      "put a timeline marker on every frame the pose model says to simulate "
                      "(its predicted error is over the tolerance). Esc cancels")
    bl_options = {"REGISTER", "UNDO"}
    WRITE_FILES = False
    STATUS = "DrivenShape: marking frames to simulate"


class DRIVENSHAPE_OT_jump_flagged(bpy.types.Operator):
    bl_idname = "drivenshape.jump_flagged"
    bl_label = "Next Frame to Simulate"
    bl_description = ("Go to the next frame the last bake or marking flagged to simulate "
                      "(wraps around)")
    bl_options = {"REGISTER"}

    previous: BoolProperty(name="Previous", default=False,
                           description="Go to the previous flagged frame instead")

    @classmethod
    def description(cls, _context, properties):
        if properties.previous:
            return "Go to the previous frame flagged to simulate (wraps around)"
        return cls.bl_description

    def execute(self, context):
        scene = context.scene
        frame = coverage.next_flagged(scene.drivenshape, scene.frame_current, self.previous)
        if frame is None:
            self.report({"INFO"}, "No frame is flagged to simulate: bake, or Mark Frames to "
                        "Simulate, with the pose model")
            return {"CANCELLED"}
        scene.frame_set(frame)
        return {"FINISHED"}


class DRIVENSHAPE_OT_clear_marks(bpy.types.Operator):
    bl_idname = "drivenshape.clear_marks"
    bl_label = "Clear Frames to Simulate"
    bl_description = ("Remove the add-on's timeline markers and the stored verdicts (your own "
                      "markers stay)")
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        coverage.clear(context.scene)
        return {"FINISHED"}


class DRIVENSHAPE_OT_simulate_flagged(bpy.types.Operator):
    bl_idname = "drivenshape.simulate_flagged"
    bl_label = "Simulate Flagged Frames"
    bl_description = ("Simulate the frames the last bake flagged with the cloth's own Cloth "
                      "modifier, in windows warm-started from the bake, and splice them into "
                      "the bake's EXRs (written to a 'simulated' folder beside them); what "
                      "`drivenshape simulate` does on the farm")
    bl_options = {"REGISTER"}

    def execute(self, context):
        return _run_reporting(self, context, simulate.simulate_flagged)


class DRIVENSHAPE_OT_add_mesh_cache(bpy.types.Operator):
    bl_idname = "drivenshape.add_mesh_cache"
    bl_label = "Add Mesh Cache Modifier"
    bl_description = ("Show the bake's PC2 on the cloth: a Mesh Cache modifier whose scene frame "
                      "f shows the PC2's frame f")
    bl_options = {"REGISTER", "UNDO"}

    filepath: StringProperty(name="PC2", subtype="FILE_PATH",
                             description="PC2 file; empty: the bake's PC2")

    def execute(self, context):
        ds_settings = context.scene.drivenshape
        cloth = ds_settings.cloth
        if cloth is None:
            self.report({"ERROR"}, "Pick the cloth object in the DrivenShape panel")
            return {"CANCELLED"}
        path_setting = self.filepath or ds_settings.bake_pc2_path
        path = engine.abspath(path_setting)
        try:
            _array, start, rate = module.get().read_pc2(path)
        except Exception as error:
            return _report_failure(self, UserError(
                f"Cannot read the PC2 {path}: {engine.describe_error(error)}"))
        if _array.shape[1] != len(cloth.data.vertices):
            self.report({"ERROR"}, f"The PC2 {path} has {_array.shape[1]} points; the cloth "
                        f"'{cloth.name}' has {len(cloth.data.vertices)} vertices")
            return {"CANCELLED"}
        bake.add_mesh_cache(cloth, path_setting, start_frame=start, sample_rate=rate)
        self.report({"INFO"}, f"'{cloth.name}' shows {path} (frames {start:g}-"
                    f"{start + rate * (_array.shape[0] - 1):g})")
        return {"FINISHED"}


class DRIVENSHAPE_OT_retry_import(bpy.types.Operator):
    bl_idname = "drivenshape.retry_import"
    bl_label = "Retry Loading the Module"
    bl_description = "Look for the drivenshape Python module again (after setting its folder)"

    def execute(self, _context):
        module.forget_failure()
        ok, text = module.status()
        self.report({"INFO"} if ok else {"ERROR"}, text)
        return {"FINISHED"} if ok else {"CANCELLED"}


CLASSES = (
    DRIVENSHAPE_OT_live_start,
    DRIVENSHAPE_OT_live_stop,
    DRIVENSHAPE_OT_build_database,
    DRIVENSHAPE_OT_bake,
    DRIVENSHAPE_OT_mark_frames,
    DRIVENSHAPE_OT_jump_flagged,
    DRIVENSHAPE_OT_clear_marks,
    DRIVENSHAPE_OT_simulate_flagged,
    DRIVENSHAPE_OT_add_mesh_cache,
    DRIVENSHAPE_OT_retry_import,
)


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
