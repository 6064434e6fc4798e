# SPDX-License-Identifier: Apache-2.0
"""Live mode: the cloth follows the driver on every frame change and while scrubbing.

On frame_change_post (and on depsgraph_update_post when the driver's geometry changed without a
frame change, e.g. an animator posing a rig), the driver's evaluated vertices are copied into a
preallocated numpy array (foreach_get), the frame is evaluated with the cached Evaluator
(evaluate_into) and the result goes into the cloth object's own mesh (foreach_set on co, then
mesh.update()).

Every frame is the frame of `drivenshape bake` (bitwise, in object space), whatever the way to
it: the library's PlaybackPlanner says whether a frame continues the evaluator's state (the
frame after the last one: nothing else is read) or starts a batch (a jump, scrubbing, playing
backwards, the same frame again), which first evaluates its warm-up frames, the earlier frames
the pose model's history and the temporal bound read, within the scene's frame range. On a frame
change those are read by setting the scene to each of them (scene.frame_set) and back; where no
frame change is under way (starting with the frames read before, a setting changed, the driver
edited on its frame) they come from the frames read last, never from a frame change that would
re-apply the animation over an unkeyed pose.

The session keeps only names and numpy arrays between frames, never bpy objects, which undo and
file loads invalidate: the driver and cloth are looked up in scene.drivenshape every frame.
"""

import collections
import time

import bpy
import numpy as np
from bpy.app.handlers import persistent

from . import coverage, engine
from .engine import UserError

# The one live session of this Blender (None when live mode is off), and the reason the last
# one stopped on its own (shown in the panel until live mode starts again).
SESSION = None
LAST_ERROR = None

# The add-on's own bake modifier on the cloth, hidden in the viewport while live mode runs.
BAKE_MODIFIER = "DrivenShape Bake"


class LiveSession:
    def __init__(self, scene_name):
        self.scene_name = scene_name
        self.cloth_name = None
        self.rest = None  # the cloth mesh's positions when live mode took it over
        self.hidden = []  # modifiers whose viewport display live mode turned off
        self.planner = None  # drivenshape.PlaybackPlanner of the current Evaluator
        self.tolerance = -1.0  # the current Evaluator's coverage tolerance (scene units)
        self.driver_in = np.empty((1, 0, 3), dtype=np.float32)
        self.driver_seen = np.empty((1, 0, 3), dtype=np.float32)
        self.block = np.empty((1, 0, 3), dtype=np.float32)  # warm-up frames, then the frame
        self.cloth_out = np.empty((1, 0, 3), dtype=np.float32)
        self.recent = {}  # frame -> driver positions read last, the warm-up's own frames
        self.recent_key = None  # (driver name, world space) of those positions
        self.cloth_written = None
        self.last_frame = None
        self.busy = False
        self.frames = 0
        self.warmup_frames_read = 0  # driver frames read by scene.frame_set for warm-ups
        # Seconds per frame: (read driver, evaluate, write cloth, whole handler).
        self.timings = collections.deque(maxlen=240)
        self.last_record = None

    # -- objects --------------------------------------------------------------------------------

    def objects(self, scene):
        # Live mode follows a driver being edited; only the cloth must stay out of Edit Mode.
        return engine.scene_objects(scene, driver_editable=True)

    def take_cloth(self, cloth, database):
        """Checks the cloth against the database and remembers its rest positions."""
        expected = database.driven_vertex_count
        if len(cloth.data.vertices) != expected:
            raise UserError(
                f"The cloth object '{cloth.name}' has {len(cloth.data.vertices)} vertices; the "
                f"database's driven mesh has {expected}. The cloth must be the database's "
                "driven mesh, with its vertices in the same order")
        if cloth.name == self.cloth_name:
            return
        self.give_back_cloth(restore=True)
        self.rest = engine.read_rest(cloth)
        self.cloth_name = cloth.name
        for modifier in cloth.modifiers:
            if modifier.name == BAKE_MODIFIER and modifier.show_viewport:
                modifier.show_viewport = False
                self.hidden.append((cloth.name, modifier.name))

    def give_back_cloth(self, restore):
        """Undoes what take_cloth did to the cloth object (if it still exists)."""
        cloth = bpy.data.objects.get(self.cloth_name) if self.cloth_name else None
        if cloth is not None and restore and self.rest is not None \
                and len(cloth.data.vertices) == len(self.rest):
            engine.write_positions(cloth, self.rest)
        for object_name, modifier_name in self.hidden:
            obj = bpy.data.objects.get(object_name)
            modifier = obj.modifiers.get(modifier_name) if obj else None
            if modifier is not None:
                modifier.show_viewport = True
        self.hidden = []
        self.cloth_name = None
        self.rest = None

    # -- one frame -------------------------------------------------------------------------------

    def prepare(self, evaluator, database):
        """Buffers and the playback plan for a new Evaluator."""
        self.planner = engine.playback_planner(evaluator)
        self.tolerance = evaluator.describe_settings().get("coverage_tolerance", -1.0)
        driver_count = database.driver_vertex_count
        self.recent = {f: p for f, p in self.recent.items() if len(p) == driver_count}
        self.driver_in = np.empty((1, driver_count, 3), dtype=np.float32)
        self.driver_seen = np.full_like(self.driver_in, np.nan)
        self.block = np.empty((self.planner.warmup_frames + 1, driver_count, 3), dtype=np.float32)
        self.cloth_out = np.empty((1, database.driven_vertex_count, 3), dtype=np.float32)
        self.last_frame = None

    def update(self, scene, depsgraph, force=True, frame_change=False):
        """Evaluates the scene's current frame and writes the cloth. Without `force`, does
        nothing when neither the frame nor the driver's positions changed since the last call
        (a depsgraph update caused by something else, such as our own write to the cloth).
        `frame_change`: called for a frame change, so warm-up frames may be read by setting the
        scene's frame. Returns whether it evaluated."""
        start = time.perf_counter()
        settings = scene.drivenshape
        driver, cloth = self.objects(scene)
        evaluator, rebuilt = engine.CACHE.evaluator_for(settings)
        database = engine.CACHE.database
        if rebuilt or self.planner is None \
                or self.driver_in.shape[1] != database.driver_vertex_count:
            self.prepare(evaluator, database)
            force = True
        self.take_cloth(cloth, database)
        world = settings.space == "WORLD"
        if self.recent_key != (driver.name, world):
            self.recent.clear()  # positions of another driver, or in the other space
            self.recent_key = (driver.name, world)

        engine.read_evaluated(driver, depsgraph, self.driver_in[0], world=world)
        frame = scene.frame_current
        if not force and frame == self.last_frame \
                and np.array_equal(self.driver_in, self.driver_seen):
            return False
        step = self.planner.next(frame, engine.driver_frames(scene, [frame]))
        try:
            solve, driver_block = self.warm_up(step, scene, driver, depsgraph, world,
                                               frame_change)
            read = time.perf_counter()
            if step.restart:
                evaluator.reset_temporal_bound()
            records = evaluator.evaluate_into(solve, driver_block, self.cloth_out,
                                              warmup=len(solve) - 1)
        except BaseException:
            self.planner.reset()  # the evaluator's state is not the plan's
            raise
        evaluated = time.perf_counter()

        result = self.cloth_out[0]
        if world:
            result = engine.to_space(result.copy(), cloth.matrix_world.inverted())
        if settings.error_colors:
            coverage.paint(cloth, records[0].error_bound if records else None,
                           self.tolerance, tag=False)  # write_positions updates the mesh
        engine.write_positions(cloth, result)
        self.cloth_written = result
        done = time.perf_counter()

        np.copyto(self.driver_seen, self.driver_in)
        self.remember(frame, self.driver_in[0])
        self.last_frame = frame
        self.frames += 1
        self.timings.append((read - start, evaluated - read, done - evaluated, done - start))
        self.last_record = records[0] if records else None
        return True

    def warm_up(self, step, scene, driver, depsgraph, world, frame_change):
        """(frames, driver positions) to evaluate for `step`: its warm-up frames, then the
        current frame (self.driver_in). On a frame change the warm-up frames are read at their
        frames (the scene is set to each and back); otherwise they come from the frames read
        last, and those not there are left out (the evaluator stands the earliest frame it has
        in for the missing history)."""
        if not step.warmup:
            return step.frames, self.driver_in
        frames = []
        if frame_change:
            frame, subframe = scene.frame_current, scene.frame_subframe
            try:
                for i, warm in enumerate(step.warmup):
                    scene.frame_set(warm)
                    engine.read_evaluated(driver, depsgraph, self.block[i], world=world)
                    self.remember(warm, self.block[i])
            finally:
                scene.frame_set(frame, subframe=subframe)
            frames = list(step.warmup)
            self.warmup_frames_read += len(frames)
        else:
            for warm in step.warmup:
                if warm in self.recent:
                    self.block[len(frames)] = self.recent[warm]
                    frames.append(warm)
        self.block[len(frames)] = self.driver_in[0]
        return frames + step.frames, self.block[:len(frames) + 1]

    def remember(self, frame, positions):
        """Keeps the driver at `frame` for a later warm-up, and only the frames one could use."""
        count = self.planner.warmup_frames
        if count == 0:
            return
        kept = self.recent.pop(frame, None)
        if kept is None or kept.shape != positions.shape:
            kept = np.empty_like(positions)
        np.copyto(kept, positions)
        self.recent[frame] = kept
        for old in [f for f in self.recent if not frame - count <= f <= frame]:
            del self.recent[old]

    def stats(self):
        """Median milliseconds per frame over the recent frames: read, evaluate, write, total."""
        if not self.timings:
            return None
        return tuple(1000.0 * float(v) for v in np.median(np.array(self.timings), axis=0))


# -- starting and stopping ---------------------------------------------------------------------


def is_live(scene=None):
    return SESSION is not None and (scene is None or SESSION.scene_name == scene.name)


def start(context):
    """Starts live mode on the context's scene and evaluates the current frame; raises
    UserError (nothing changed) when it cannot."""
    global SESSION, LAST_ERROR
    scene = context.scene
    stop(restore=True)
    session = LiveSession(scene.name)
    session.busy = True
    try:
        # Starting is a frame change of its own: the warm-up frames are read at their frames.
        session.update(scene, context.evaluated_depsgraph_get(), force=True, frame_change=True)
    except Exception:
        session.give_back_cloth(restore=True)
        raise
    finally:
        session.busy = False
    SESSION = session
    LAST_ERROR = None
    redraw_panels()


def stop(restore=True):
    """Stops live mode; with `restore`, the cloth mesh gets its rest positions back."""
    global SESSION
    session, SESSION = SESSION, None
    if session is not None:
        restore = restore and _restore_setting(session)
        session.give_back_cloth(restore=restore)
        scene = bpy.data.scenes.get(session.scene_name)
        if scene is not None:
            coverage.paint_stored(scene)  # the stored verdict's colour, not the live frame's
        redraw_panels()


def _restore_setting(session):
    scene = bpy.data.scenes.get(session.scene_name)
    return scene is None or scene.drivenshape.live_restore


def fail(scene, message):
    """Stops live mode after an error in a handler, where nothing can report it: the panel shows
    the message, the console gets it too."""
    global LAST_ERROR
    LAST_ERROR = f"Live mode stopped at frame {scene.frame_current}: {message}"
    print(f"DrivenShape: {LAST_ERROR}")
    stop(restore=True)


def redraw_panels():
    window_manager = getattr(bpy.context, "window_manager", None)
    if window_manager is None:
        return
    for window in window_manager.windows:
        for area in window.screen.areas:
            if area.type == "VIEW_3D":
                area.tag_redraw()


def _run(scene, depsgraph, force, frame_change=False):
    session = SESSION
    if session is None or session.busy or session.scene_name != scene.name:
        return
    session.busy = True
    try:
        if session.update(scene, depsgraph, force=force, frame_change=frame_change) \
                and session.frames % 12 == 0:
            redraw_panels()
    except UserError as error:
        fail(scene, str(error))
    except Exception as error:  # a drivenshape.Error from the evaluator, or a Blender error
        fail(scene, engine.describe_error(error))
    finally:
        session.busy = False


def settings_changed(context):
    """A setting or object changed in the panel: show its effect at once."""
    scene = context.scene
    if is_live(scene):
        _run(scene, context.evaluated_depsgraph_get(), force=True)


# -- handlers ----------------------------------------------------------------------------------


@persistent
def on_frame_change(scene, depsgraph):
    _run(scene, depsgraph, force=True, frame_change=True)


@persistent
def on_depsgraph_update(scene, depsgraph):
    session = SESSION
    if session is None or session.busy or session.scene_name != scene.name:
        return
    driver = scene.drivenshape.driver
    if driver is None:
        return
    for update in depsgraph.updates:
        if update.is_updated_geometry and update.id.original == driver:
            _run(scene, depsgraph, force=False)
            return


@persistent
def on_load_pre(*_args):
    # The objects belong to the file being closed: forget them without touching them.
    global SESSION, LAST_ERROR
    SESSION = None
    LAST_ERROR = None


@persistent
def on_save_pre(*_args):
    # The .blend keeps the cloth's rest positions, not the live frame.
    session = SESSION
    cloth = bpy.data.objects.get(session.cloth_name) if session and session.cloth_name else None
    if cloth is not None and session.rest is not None:
        engine.write_positions(cloth, session.rest)


@persistent
def on_save_post(*_args):
    session = SESSION
    cloth = bpy.data.objects.get(session.cloth_name) if session and session.cloth_name else None
    if cloth is not None and session.cloth_written is not None:
        engine.write_positions(cloth, session.cloth_written)


HANDLERS = (
    (bpy.app.handlers.frame_change_post, on_frame_change),
    (bpy.app.handlers.depsgraph_update_post, on_depsgraph_update),
    (bpy.app.handlers.load_pre, on_load_pre),
    (bpy.app.handlers.save_pre, on_save_pre),
    (bpy.app.handlers.save_post, on_save_post),
)


def register():
    for handlers, function in HANDLERS:
        if function not in handlers:
            handlers.append(function)


def unregister():
    stop(restore=True)
    for handlers, function in HANDLERS:
        if function in handlers:
            handlers.remove(function)
