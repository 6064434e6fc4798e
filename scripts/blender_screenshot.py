# SPDX-License-Identifier: Apache-2.0
"""Screenshot of the add-on at work: a real Blender window (on a virtual X server), the bundled
sleeve scene in live mode, the DrivenShape tab open in the 3D view's sidebar at its default
width, the frames to simulate marked on the timeline and the sleeve coloured by its predicted
error.

    xvfb-run -s "-screen 0 1600x900x24" blender --factory-startup --enable-event-simulate \
        --python scripts/blender_screenshot.py -- [--out docs/images/blender_live.png]

DRIVENSHAPE_PYTHONPATH must name the folder that holds the drivenshape module (build/python).
The add-on is loaded from the source tree (apps/blender). The database is built with the module
from tests/data/sleeve's training clip (out/screenshot/sleeve.dsdb, with the pose model); the
driver plays the test clip through a Mesh Cache modifier. The coverage tolerance is TOLERANCE
(the default, 12.5 mm here, flags every frame of the test clip). Blender quits after writing the image (exit code 1 on a
failure).
"""

import argparse
import os
import sys
import traceback

import bpy
import mathutils

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.dont_write_bytecode = True  # Blender ignores PYTHONDONTWRITEBYTECODE: keep the tree clean
sys.path.insert(0, os.path.join(ROOT, "apps", "blender"))
import drivenshape_blender  # noqa: E402

DATA = os.path.join(ROOT, "tests", "data", "sleeve")
FRAME = 33
TOLERANCE = 0.0235  # metres


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser()
    parser.add_argument("--out", default=os.path.join(ROOT, "docs", "images",
                                                      "blender_live.png"))
    # To check every label at the default width: open the sub-panels that start closed and
    # scroll the sidebar down by this many mouse-wheel steps.
    parser.add_argument("--open-all", action="store_true")
    parser.add_argument("--scroll", type=int, default=0)
    return parser.parse_args(argv)


ARGS = parse_args()


def import_obj(name, label, color):
    bpy.ops.object.select_all(action="DESELECT")
    bpy.ops.wm.obj_import(filepath=os.path.join(DATA, name), forward_axis="Y", up_axis="Z")
    obj = bpy.context.selected_objects[0]
    obj.name = label
    obj.color = color
    return obj


def view3d():
    for area in bpy.context.window.screen.areas:
        if area.type == "VIEW_3D":
            region = next(r for r in area.regions if r.type == "WINDOW")
            return area, region
    raise RuntimeError("no 3D view in the default layout")


def setup():
    if ARGS.open_all:
        for panel in drivenshape_blender.ui.CLASSES:
            panel.bl_options = set(getattr(panel, "bl_options", set())) - {"DEFAULT_CLOSED"}
    drivenshape_blender.register()
    ds = drivenshape_blender.module.get()
    database = os.path.join(ROOT, "out", "screenshot", "sleeve.dsdb")
    os.makedirs(os.path.dirname(database), exist_ok=True)
    ds.build_database(os.path.join(DATA, "driver_rest.obj"),
                      os.path.join(DATA, "driven_rest.obj"),
                      os.path.join(DATA, "train.driver.pc2"),
                      os.path.join(DATA, "train.driven.pc2"), count=30).save(database)

    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    driver = import_obj("driver_rest.obj", "arm", (0.80, 0.55, 0.45, 1.0))
    cloth = import_obj("driven_rest.obj", "sleeve", (0.25, 0.45, 0.80, 1.0))
    clip = os.path.join(DATA, "test.driver.pc2")
    _positions, start, _rate = ds.read_pc2(clip)
    modifier = driver.modifiers.new("test clip", "MESH_CACHE")
    modifier.cache_format = "PC2"
    modifier.filepath = clip
    modifier.frame_start = start

    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = int(start), int(start) + len(_positions) - 1
    settings = scene.drivenshape
    settings.driver, settings.cloth, settings.database_path = driver, cloth, database
    settings.bake_pc2_path = "//drivenshape/sleeve.pc2"
    settings.coverage_tolerance = TOLERANCE
    bpy.ops.drivenshape.mark_frames()
    settings.error_colors = True
    scene.frame_set(scene.frame_start)
    bpy.ops.drivenshape.live_start()
    for frame in range(scene.frame_start, FRAME + 1):  # play up to FRAME: the panel's timings
        scene.frame_set(frame)

    area, _region = view3d()
    space = area.spaces.active
    space.show_region_ui = True
    space.shading.type = "SOLID"
    space.shading.color_type = "VERTEX"  # Attribute: the cloth's error colours
    view = space.region_3d
    view.view_perspective = "PERSP"
    view.view_location = mathutils.Vector(cloth.location) + mathutils.Vector(
        [sum(axis) / 8.0 for axis in zip(*cloth.bound_box)])
    view.view_rotation = mathutils.Euler((1.25, 0.0, 0.75)).to_quaternion()
    view.view_distance = 0.75
    bpy.ops.object.select_all(action="DESELECT")
    window = bpy.context.window
    for timeline in window.screen.areas:
        if timeline.type == "DOPESHEET_EDITOR":
            # Taller than the factory layout's, so that the markers show under the frames.
            with bpy.context.temp_override(window=window, screen=window.screen, area=timeline):
                bpy.ops.screen.area_move(x=timeline.x + timeline.width // 2,
                                         y=timeline.y + timeline.height, delta=40)
            with bpy.context.temp_override(area=timeline, region=timeline.regions[-1]):
                bpy.ops.action.view_all()
    bpy.app.timers.register(click_tab, first_interval=0.5)


# Blender 3.4 cannot pick a sidebar tab from Python (Region.active_panel_category came in a
# later version): click down the tab strip at the sidebar's right edge, with simulated events,
# until the DrivenShape panel draws.
DRAWN = []
_draw = drivenshape_blender.ui.DRIVENSHAPE_PT_main.draw


def _recording_draw(panel, context):
    DRAWN.append(True)
    _draw(panel, context)


drivenshape_blender.ui.DRIVENSHAPE_PT_main.draw = _recording_draw
CLICK = {"step": 0}


def click_tab():
    if DRAWN:
        bpy.app.timers.register(scroll if ARGS.scroll else shoot, first_interval=1.0)
        return None
    area, _region = view3d()
    sidebar = next(r for r in area.regions if r.type == "UI")
    y = sidebar.y + sidebar.height - 8 - 12 * CLICK["step"]
    if y < sidebar.y or CLICK["step"] > 80:
        print("could not find the DrivenShape tab in the sidebar")
        os._exit(1)
    x = sidebar.x + sidebar.width - 10
    window = bpy.context.window_manager.windows[0]
    window.event_simulate(type="MOUSEMOVE", value="NOTHING", x=x, y=y)
    window.event_simulate(type="LEFTMOUSE", value="PRESS", x=x, y=y)
    window.event_simulate(type="LEFTMOUSE", value="RELEASE", x=x, y=y)
    # Park the pointer over the viewport so no tooltip shows.
    window.event_simulate(type="MOUSEMOVE", value="NOTHING", x=area.x + 60,
                          y=area.y + 60)
    DRAWN.clear()
    CLICK["step"] += 1
    return 0.3


def scroll():
    area, _region = view3d()
    sidebar = next(r for r in area.regions if r.type == "UI")
    window = bpy.context.window_manager.windows[0]
    x, y = sidebar.x + sidebar.width // 2, sidebar.y + sidebar.height // 2
    window.event_simulate(type="MOUSEMOVE", value="NOTHING", x=x, y=y)
    for _ in range(ARGS.scroll):
        window.event_simulate(type="WHEELDOWNMOUSE", value="PRESS", x=x, y=y)
    window.event_simulate(type="MOUSEMOVE", value="NOTHING", x=area.x + 60, y=area.y + 60)
    bpy.app.timers.register(shoot, first_interval=1.0)


def shoot():
    try:
        os.makedirs(os.path.dirname(os.path.abspath(ARGS.out)), exist_ok=True)
        window = bpy.context.window_manager.windows[0]
        with bpy.context.temp_override(window=window, screen=window.screen):
            bpy.ops.screen.screenshot(filepath=ARGS.out)
        print(f"wrote {ARGS.out}")
        code = 0
    except Exception:  # noqa: BLE001 (report anything, then quit with a failure)
        traceback.print_exc()
        code = 1
    os._exit(code)  # quit_blender would run the exit handlers of a half-set-up UI


def start():
    try:
        setup()
    except Exception:  # noqa: BLE001
        traceback.print_exc()
        os._exit(1)


bpy.context.preferences.view.show_splash = False
bpy.app.timers.register(start, first_interval=1.0)
