# SPDX-License-Identifier: Apache-2.0
"""The pose model's verdict across the shot, where an animator looks: markers on the timeline,
and optionally the cloth coloured by the predicted error.

A bake, or Mark Frames to Simulate, stores each evaluated frame's predicted error and verdict in
the scene (scene.drivenshape.verdicts, saved with the .blend) and puts a timeline marker named
"DS simulate 12.3 mm" on every frame the verdict flags. The markers the add-on made are known by
the names it stored with the verdicts: the next evaluation removes those and no others (a user's
marker stays, and so does one of ours the user renamed).

Error Colors: the pose model predicts one mean vertex error per frame (the records have no
per-vertex prediction), so the cloth gets one colour per frame, in a point colour attribute that
Solid shading shows in its Attribute colour mode: green at half the coverage tolerance and below,
yellow at the tolerance, red at 1.5 times it and above, grey where nothing is predicted. Live mode
paints the frame it evaluates; otherwise a frame change paints the stored verdict of the frame."""

import bpy
import numpy as np
from bpy.app.handlers import persistent

from . import engine

MARKER_PREFIX = "DS simulate"
COLOR_ATTRIBUTE = "DS predicted error"

# The colour scale, in multiples of the tolerance: (error / tolerance, linear RGB).
SCALE = ((0.5, (0.05, 0.60, 0.05)), (1.0, (0.90, 0.75, 0.02)), (1.5, (0.80, 0.03, 0.02)))
NO_PREDICTION = (0.25, 0.25, 0.25)

# Set while a bake or a marking steps the scene through its frames: painting every frame it
# visits would only cost time.
SUSPENDED = False


def marker_name(error, unit_settings):
    return f"{MARKER_PREFIX} {engine.length_text(error, unit_settings)}"


def remove_markers(scene):
    """Removes the timeline markers the add-on put there (by the names stored with the verdicts);
    returns how many."""
    ours = {verdict.marker for verdict in scene.drivenshape.verdicts if verdict.marker}
    removed = 0
    for marker in list(scene.timeline_markers):
        if marker.name in ours:
            scene.timeline_markers.remove(marker)
            removed += 1
    return removed


def store(scene, verdicts, tolerance):
    """Replaces the scene's verdicts with `verdicts`, [(frame, error bound, flagged)] in scene
    units (frames without a prediction left out), and the add-on's markers with one per flagged
    frame. `tolerance`: the coverage tolerance they were judged by (scene units). Returns the
    flagged frames."""
    settings = scene.drivenshape
    remove_markers(scene)
    settings.verdicts.clear()
    settings.verdict_tolerance = tolerance if verdicts else -1.0
    flagged = []
    for frame, error, is_flagged in verdicts:
        item = settings.verdicts.add()
        item.frame, item.error_bound, item.flagged = frame, error, is_flagged
        if is_flagged:
            item.marker = marker_name(error, scene.unit_settings)
            scene.timeline_markers.new(item.marker, frame=frame)
            flagged.append(frame)
    paint_stored(scene)
    return flagged


def clear(scene):
    remove_markers(scene)
    scene.drivenshape.verdicts.clear()
    scene.drivenshape.verdict_tolerance = -1.0
    paint_stored(scene)


def flagged_frames(settings):
    return [verdict.frame for verdict in settings.verdicts if verdict.flagged]


def next_flagged(settings, frame, previous=False):
    """The flagged frame after `frame` (before it with `previous`), wrapping around the shot;
    None when no frame is flagged."""
    frames = sorted(flagged_frames(settings))
    if not frames:
        return None
    if previous:
        earlier = [f for f in frames if f < frame]
        return earlier[-1] if earlier else frames[-1]
    later = [f for f in frames if f > frame]
    return later[0] if later else frames[0]


def stored_verdict(settings, frame):
    """The stored verdict of `frame`, or None. The verdicts are stored in frame order, one per
    frame, so the frame's index is found without a search."""
    verdicts = settings.verdicts
    if not verdicts:
        return None
    index = frame - verdicts[0].frame
    if 0 <= index < len(verdicts) and verdicts[index].frame == frame:
        return verdicts[index]
    return next((verdict for verdict in verdicts if verdict.frame == frame), None)


def color(error, tolerance):
    """The linear RGBA colour of an error bound (scene units) on the scale of `tolerance`."""
    if error is None or error < 0 or tolerance is None or tolerance <= 0:
        return (*NO_PREDICTION, 1.0)
    x = min(max(error / tolerance, SCALE[0][0]), SCALE[-1][0])
    for (x0, c0), (x1, c1) in zip(SCALE, SCALE[1:]):
        if x <= x1:
            t = (x - x0) / (x1 - x0)
            return (*(a + (b - a) * t for a, b in zip(c0, c1)), 1.0)
    return (*SCALE[-1][1], 1.0)


def paint(cloth, error, tolerance, tag=True):
    """Gives every vertex of the cloth's mesh the colour of `error`, in the point colour
    attribute COLOR_ATTRIBUTE (made, and made the active colour, when missing)."""
    mesh = cloth.data
    if cloth.mode == "EDIT":
        return  # the edit mesh would overwrite it on leaving Edit Mode
    attribute = mesh.color_attributes.get(COLOR_ATTRIBUTE)
    if attribute is None or attribute.domain != "POINT" or attribute.data_type != "FLOAT_COLOR":
        if attribute is not None:
            mesh.color_attributes.remove(attribute)
        attribute = mesh.color_attributes.new(COLOR_ATTRIBUTE, "FLOAT_COLOR", "POINT")
    if mesh.color_attributes.active_color_name != COLOR_ATTRIBUTE:
        mesh.color_attributes.active_color = attribute
    rgba = np.array(color(error, tolerance), dtype=np.float32)
    attribute.data.foreach_set("color", np.tile(rgba, len(mesh.vertices)))
    if tag:
        mesh.update()


def unpaint(cloth):
    attribute = cloth.data.color_attributes.get(COLOR_ATTRIBUTE)
    if attribute is not None:
        cloth.data.color_attributes.remove(attribute)
        cloth.data.update()


def paint_stored(scene):
    """Paints the cloth with the stored verdict of the current frame (Error Colors on, live mode
    off: live mode paints what it evaluates)."""
    from . import live  # noqa: PLC0415 (live imports this module)

    settings = scene.drivenshape
    cloth = settings.cloth
    if not settings.error_colors or cloth is None or SUSPENDED or live.is_live(scene):
        return
    verdict = stored_verdict(settings, scene.frame_current)
    paint(cloth, verdict.error_bound if verdict else None, settings.verdict_tolerance)


def error_colors_changed(context):
    """Error Colors switched: paint (and show the Attribute colours in the Solid shading of this
    screen's 3D views) or take the attribute off the cloth (and show the Material colours)."""
    from . import live  # noqa: PLC0415

    scene = context.scene
    settings = scene.drivenshape
    cloth = settings.cloth
    on = settings.error_colors
    if cloth is not None:
        if not on:
            unpaint(cloth)
        elif live.is_live(scene):
            live.settings_changed(context)  # evaluates and paints the frame
        else:
            paint_stored(scene)
    screen = getattr(context, "screen", None)
    for area in screen.areas if screen else ():
        if area.type == "VIEW_3D":
            shading = area.spaces.active.shading
            if on:
                shading.color_type = "VERTEX"
            elif shading.color_type == "VERTEX":
                shading.color_type = "MATERIAL"


@persistent
def on_frame_change(scene, _depsgraph):
    paint_stored(scene)


def register():
    if on_frame_change not in bpy.app.handlers.frame_change_post:
        bpy.app.handlers.frame_change_post.append(on_frame_change)


def unregister():
    if on_frame_change in bpy.app.handlers.frame_change_post:
        bpy.app.handlers.frame_change_post.remove(on_frame_change)
