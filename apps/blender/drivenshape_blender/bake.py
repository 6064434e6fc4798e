# SPDX-License-Identifier: Apache-2.0
"""Baking a frame range (PC2, optional point-cache EXRs, a Mesh Cache modifier to show it, the
frames to simulate on the timeline), marking the frames to simulate without a bake, and building
a database from the scene: the work behind the operators, without the UI, so that a
modal operator can run it a few frames at a time and a script can run it all at once."""

import os

import bpy
import numpy as np

from . import coverage, engine, live, module
from .engine import UserError

# Driver frames read per step(): how often the modal bake looks at the keyboard and moves the
# progress bar. The batches themselves are the library's plan (drivenshape.plan_shot), the
# command line bake's: a step evaluates a batch once its frames are read.
READ_STEP = 8


def scene_objects(scene):
    return engine.scene_objects(scene, driver_editable=False)


def bake_frames(scene):
    settings = scene.drivenshape
    if settings.bake_use_scene_range:
        first, last = scene.frame_start, scene.frame_end
    else:
        first, last = settings.bake_frame_start, settings.bake_frame_end
    if last < first:
        raise UserError(f"The bake's frame range {first}-{last} is empty")
    return list(range(first, last + 1))


def prepare_folder(path, what):
    folder = os.path.dirname(path)
    try:
        if folder:
            os.makedirs(folder, exist_ok=True)
    except OSError as error:
        raise UserError(f"Cannot create the folder {folder} for the {what}: "
                        f"{error.strerror}") from None


class Bake:
    """Evaluates frames of the scene in the batches of the library's shot plan (history and
    temporal warm-up frames as `drivenshape bake` reads them from a cache of the scene's frame
    range), READ_STEP driver frames per step(); then finish() stores the frames' coverage
    verdicts and the timeline markers (coverage.py) and, for a bake, writes the PC2 and sets up
    the Mesh Cache modifier. EXRs are written as batches finish.

    With `write_files` off (Mark Frames to Simulate) it evaluates the scene's frame range the
    same way, keeps only the verdicts and writes nothing."""

    def __init__(self, context, write_files=True):
        self.scene = scene = context.scene
        settings = scene.drivenshape
        self.write_files = write_files
        self.driver, self.cloth = scene_objects(scene)
        if write_files:
            self.frames = bake_frames(scene)
            self.pc2_setting = settings.bake_pc2_path
            self.pc2_path = engine.abspath(settings.bake_pc2_path)
            if not self.pc2_path:
                raise UserError("Set the PC2 file the bake writes")
            self.exr_pattern = engine.abspath(settings.bake_exr_pattern) \
                if settings.bake_write_exr else None
            if settings.bake_write_exr:
                engine.expand_pattern(self.exr_pattern, self.frames[0])  # checks the pattern
            self.add_mesh_cache = settings.bake_add_mesh_cache
        else:
            if scene.frame_end < scene.frame_start:
                raise UserError(f"The scene's frame range {scene.frame_start}-"
                                f"{scene.frame_end} is empty")
            self.frames = list(range(scene.frame_start, scene.frame_end + 1))
            self.exr_pattern = None
        self.world = settings.space == "WORLD"

        # Live mode would evaluate every frame the bake steps through, and write the cloth.
        live.stop(restore=True)
        self.evaluator, _ = engine.CACHE.evaluator_for(settings)
        database = engine.CACHE.database
        if len(self.cloth.data.vertices) != database.driven_vertex_count:
            raise UserError(
                f"The cloth object '{self.cloth.name}' has {len(self.cloth.data.vertices)} "
                f"vertices; the database's driven mesh has {database.driven_vertex_count}")
        described = self.evaluator.describe_settings()
        if not write_files and described.get("weights") != "model":
            raise UserError(
                f"Only the pose model predicts which frames to simulate; these settings evaluate "
                f"'{described.get('weights')}' weights. Set Weights to Auto or Pose model, with a "
                "database built with the pose model")
        self.tolerance = described.get("coverage_tolerance", -1.0)
        # What the library warns of these settings on this database (a setting left unused, a
        # tolerance below the smallest error bound the verdict gives), reported after the job.
        self.warnings = list(self.evaluator.warnings)
        self.database = database
        self.topology_hash = database.driven_mesh.topology_hash
        self.plan = [(b.first, b.frames, b.solve_frames, len(b.warmup))
                     for b in engine.plan_shot(self.evaluator, scene, self.frames)]
        longest = max(len(solve) for _first, _frames, solve, _warm in self.plan)
        # A bake keeps every frame for the PC2; a marking only one batch at a time.
        kept = len(self.frames) if write_files else max(len(f) for _a, f, _b, _c in self.plan)
        self.cloth_frames = np.empty((kept, database.driven_vertex_count, 3), dtype=np.float32)
        self.driver_batch = np.empty((longest, database.driver_vertex_count, 3), dtype=np.float32)
        self.cloth_matrices = [None] * len(self.frames)  # cloth to world, per frame (WORLD)
        self.verdicts = []  # (frame, error bound, flagged) of the frames with a prediction
        self.batch = 0  # the batch of the plan being read
        self.read = 0  # its driver frames read so far
        self.done = 0
        self.exr_written = 0
        self.frame_before = scene.frame_current
        coverage.SUSPENDED = True

    @property
    def total(self):
        return len(self.frames)

    def step(self, context):
        """Reads the next READ_STEP driver frames of the plan, evaluates a batch once all of its
        frames are read; returns whether every frame is done. `context` is the caller's (a modal
        operator's context is only valid during its call)."""
        first, _frames, solve, warm = self.plan[self.batch]
        end = min(len(solve), self.read + READ_STEP)
        for i in range(self.read, end):
            self.scene.frame_set(solve[i])
            depsgraph = context.evaluated_depsgraph_get()
            engine.read_evaluated(self.driver, depsgraph, self.driver_batch[i], world=self.world)
            if self.world and i >= warm:
                self.cloth_matrices[first + i - warm] = self.cloth.matrix_world.inverted()
        self.read = end
        if end == len(solve):
            self.evaluate_batch()
            self.batch += 1
            self.read = 0
        return self.batch >= len(self.plan)

    def evaluate_batch(self):
        first, frames, solve, warm = self.plan[self.batch]
        at = first if self.write_files else 0
        out = self.cloth_frames[at:at + len(frames)]
        self.evaluator.reset_temporal_bound()
        try:
            records = self.evaluator.evaluate_into(solve, self.driver_batch[:len(solve)], out,
                                                   warmup=warm)
        except Exception as error:
            raise UserError(f"Bake of frames {frames[0]}-{frames[-1]}: "
                            f"{engine.describe_error(error)}") from None
        for record in records:
            if record.predicted_error >= 0:
                self.verdicts.append((record.frame, record.error_bound, record.flagged == 1))
        if self.exr_pattern:
            for i, frame in enumerate(frames):
                self.write_exr(frame, out[i])
        self.done += len(frames)

    def write_exr(self, frame, positions):
        ds = module.get()
        path = engine.expand_pattern(self.exr_pattern, frame)
        if self.exr_written == 0:
            prepare_folder(path, "EXR point caches")
        try:
            ds.write_point_cache_exr(
                path, positions, frame=frame, topology_hash=self.topology_hash,
                settings_hash=self.evaluator.settings_hash,
                frames_per_second=self.scene.render.fps / self.scene.render.fps_base,
                sync=False)
        except Exception as error:
            raise UserError(f"Cannot write {path}: {engine.describe_error(error)}") from None
        self.exr_written += 1

    def finish(self):
        """Puts the scene back on its frame, stores the verdicts and the markers; for a bake
        writes the PC2 (cloth object space) and sets up the Mesh Cache modifier. Returns a
        summary for the report."""
        self.restore_frame()
        flagged = coverage.store(self.scene, self.verdicts, self.tolerance)
        verdict = self.verdict_summary(flagged)
        if not self.write_files:
            return f"Frames {self.frames[0]}-{self.frames[-1]}: {verdict}"
        ds = module.get()
        positions = self.cloth_frames
        if self.world:
            positions = positions.copy()
            for i, matrix in enumerate(self.cloth_matrices):
                engine.to_space(positions[i], matrix)
        prepare_folder(self.pc2_path, "PC2")
        try:
            ds.write_pc2(self.pc2_path, positions, start_frame=float(self.frames[0]),
                         sample_rate=1.0)
        except Exception as error:
            raise UserError(f"Cannot write {self.pc2_path}: "
                            f"{engine.describe_error(error)}") from None
        if self.add_mesh_cache:
            add_mesh_cache(self.cloth, self.pc2_setting, start_frame=self.frames[0])
        summary = (f"Baked frames {self.frames[0]}-{self.frames[-1]} of '{self.cloth.name}' to "
                   f"{self.pc2_path}")
        if self.exr_pattern:
            summary += f" and {self.exr_written} EXRs ({self.exr_pattern})"
        return f"{summary}; {verdict}"

    def verdict_summary(self, flagged):
        if not self.verdicts:
            return "no predicted errors (only the pose model predicts them)"
        limit = engine.length_text(self.tolerance, self.scene.unit_settings)
        if not flagged:
            return f"none of {len(self.verdicts)} frames to simulate (all within {limit})"
        return (f"{len(flagged)} of {len(self.verdicts)} frames to simulate (over {limit}), "
                f"marked '{coverage.MARKER_PREFIX}' on the timeline")

    def restore_frame(self):
        coverage.SUSPENDED = False
        if self.scene.frame_current != self.frame_before:
            self.scene.frame_set(self.frame_before)


def add_mesh_cache(cloth, pc2_path, start_frame, sample_rate=1.0):
    """Shows a PC2 bake on the cloth with a Mesh Cache modifier, first in the stack.

    Blender reads PC2 sample (frame_scale * scene frame - frame_start), counting samples from 0
    and ignoring the start frame written in the file; its defaults (start 0, scale 1) therefore
    show the file's second sample at scene frame 1. Sample s of our PC2 is frame
    start + s * rate, so scene frame f shows frame f when frame_scale = 1 / rate and
    frame_start = start / rate."""
    modifier = cloth.modifiers.get(live.BAKE_MODIFIER)
    if modifier is not None and modifier.type != "MESH_CACHE":
        cloth.modifiers.remove(modifier)
        modifier = None
    if modifier is None:
        modifier = cloth.modifiers.new(live.BAKE_MODIFIER, "MESH_CACHE")
    modifier.cache_format = "PC2"
    modifier.filepath = pc2_path
    modifier.time_mode = "FRAME"
    modifier.play_mode = "SCENE"
    modifier.frame_scale = 1.0 / sample_rate
    modifier.frame_start = start_frame / sample_rate
    modifier.deform_mode = "OVERWRITE"
    modifier.interpolation = "LINEAR"  # subframes (motion blur) between baked frames
    modifier.factor = 1.0
    modifier.forward_axis = "POS_Y"  # no axis conversion: the PC2 is in the object's space
    modifier.up_axis = "POS_Z"
    modifier.flip_axis = set()
    modifier.show_viewport = True
    modifier.show_render = True
    # First in the stack: it replaces positions, the other modifiers work on the result.
    index = list(cloth.modifiers).index(modifier)
    if index != 0:
        with bpy.context.temp_override(object=cloth):
            bpy.ops.object.modifier_move_to_index(modifier=modifier.name, index=0)
    return modifier


def build_database(context):
    """Builds a database from the scene's reference animation (objects or PC2 files), saves it
    and makes it the scene's database. Returns a summary for the report."""
    ds = module.get()
    scene = context.scene
    settings = scene.drivenshape
    driver, cloth = scene_objects(scene)
    output = engine.abspath(settings.build_output)
    if not output:
        raise UserError("Set the file the new database is saved to")
    first, last = settings.build_frame_start, settings.build_frame_end
    if last < first:
        raise UserError(f"The reference frame range {first}-{last} is empty")
    world = settings.space == "WORLD"
    live.stop(restore=True)

    driver_rest = engine.read_rest(driver)
    cloth_rest = engine.read_rest(cloth)
    if world:
        engine.to_space(driver_rest, driver.matrix_world)
        engine.to_space(cloth_rest, cloth.matrix_world)
    try:
        driver_mesh = engine.make_mesh(driver, driver_rest)
        driven_mesh = engine.make_mesh(cloth, cloth_rest)
    except Exception as error:
        raise UserError(f"Cannot use the meshes of '{driver.name}' and '{cloth.name}': "
                        f"{engine.describe_error(error)}") from None

    frames = list(range(first, last + 1))
    if settings.build_source == "ANIMATION":
        for modifier in cloth.modifiers:
            if modifier.name == live.BAKE_MODIFIER and modifier.show_viewport:
                raise UserError(f"The cloth '{cloth.name}' shows a DrivenShape bake (modifier "
                                f"'{modifier.name}'): disable it to build from the reference "
                                "animation")
        driver_cache = np.empty((len(frames), len(driver_rest), 3), dtype=np.float32)
        driven_cache = np.empty((len(frames), len(cloth_rest), 3), dtype=np.float32)
        frame_before = scene.frame_current
        try:
            for i, frame in enumerate(frames):
                scene.frame_set(frame)
                depsgraph = context.evaluated_depsgraph_get()
                engine.read_evaluated(driver, depsgraph, driver_cache[i], world, role="driver")
                engine.read_evaluated(cloth, depsgraph, driven_cache[i], world, role="cloth")
        finally:
            scene.frame_set(frame_before)
        driver_source = ds.PointCache.from_array(driver_cache, start_frame=first)
        driven_source = ds.PointCache.from_array(driven_cache, start_frame=first)
        described = f"the animation of '{driver.name}' and '{cloth.name}'"
    else:
        driver_source = open_cache(settings.build_driver_pc2, "driver PC2")
        driven_source = open_cache(settings.build_cloth_pc2, "cloth PC2")
        described = (f"{engine.abspath(settings.build_driver_pc2)} and "
                     f"{engine.abspath(settings.build_cloth_pc2)}")
    try:
        database = ds.build_database(driver_mesh, driven_mesh, driver_source, driven_source,
                                     frames=frames, **engine.module_kwargs(settings, "build"))
    except Exception as error:
        raise UserError(f"Cannot build a database from {described}, frames {first}-{last}: "
                        f"{engine.describe_error(error)}") from None
    prepare_folder(output, "database")
    try:
        database.save(output)
    except Exception as error:
        raise UserError(f"Cannot save the database {output}: "
                        f"{engine.describe_error(error)}") from None
    settings.database_path = settings.build_output
    return (f"Database {output}: {database.shape_count} shapes from frames {first}-{last} "
            f"(driver {database.driver_vertex_count}, cloth {database.driven_vertex_count} "
            "vertices)")


def open_cache(path_setting, what):
    ds = module.get()
    path = engine.abspath(path_setting)
    if not path:
        raise UserError(f"Set the {what} file")
    try:
        return ds.open_point_cache(path)
    except Exception as error:
        raise UserError(f"Cannot read the {what} {path}: {engine.describe_error(error)}") \
            from None
