# SPDX-License-Identifier: Apache-2.0
"""The panel's coverage lines in a real (background) Blender: live mode with a pose-model
database shows the live frame's predicted error, its error bound and the verdict, in mm.

Blender cannot draw a panel in the background, so the check calls the function the panel draws
from (ui.coverage_lines) with live mode's own record and Evaluator. The expected texts are made
here: the tolerance from the cloth's rest bounding box (the default is 2% of its diagonal), the
unit scale from the scene; the predicted error and the bound from a second Evaluator of the
module run on the same driver frame outside Blender's handlers, the bound checked against the
prediction plus the database's verdict margin. With the QP there is nothing to show."""

import os
import sys
import types

import bpy
import numpy as np

sys.dont_write_bytecode = True  # Blender ignores PYTHONDONTWRITEBYTECODE: keep the tree clean
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import blender_test_util as util  # noqa: E402

# The default coverage tolerance: this fraction of the cloth's rest bounding-box diagonal
# (docs/commands.md#coverage-verdict).
DEFAULT_TOLERANCE_OF_DIAGONAL = 0.02
FRAME = 20

args = util.parse_args()
checks = util.Checks("test_blender_panel")
addon = util.install_addon(args.work)
ds = util.drivenshape_module(addon)
database = os.path.join(args.work, "panel_pose.dsdb")
data = args.data
ds.save_database(database, ds.build_database(os.path.join(data, "driver_rest.obj"),
                                             os.path.join(data, "driven_rest.obj"),
                                             os.path.join(data, "train.driver.pc2"),
                                             os.path.join(data, "train.driven.pc2")))
driver, cloth = util.sleeve_scene(ds, data, database)
scene = bpy.context.scene
settings = scene.drivenshape
checks.check(settings.weight_mode == "auto", "the add-on's default weights are auto")

rest = np.asarray(ds.read_obj(os.path.join(data, "driven_rest.obj")).positions)
tolerance = DEFAULT_TOLERANCE_OF_DIAGONAL * float(np.linalg.norm(rest.max(axis=0)
                                                                 - rest.min(axis=0)))

# Played from frame 1 one frame at a time, so live mode's Evaluator has seen every frame before
# FRAME (the pose model reads the history of the frames it was given).
scene.frame_set(1)
bpy.ops.drivenshape.live_start()
for frame in range(2, FRAME + 1):
    scene.frame_set(frame)
record = addon.live.SESSION.last_record
evaluator = addon.engine.CACHE.evaluator
checks.check(record is not None and record.frame == FRAME, f"live mode evaluated frame {FRAME}")
checks.check(record.predicted_error > 0, "auto runs the pose model, which predicts an error")

# Frames 1 to FRAME through the module on the same device, outside Blender: the same prediction.
reference = ds.Evaluator(ds.load_database(database), None, addon.engine.CACHE.device)
driver_cache = ds.open_point_cache(os.path.join(data, "test.driver.pc2"))
played = list(range(1, FRAME + 1))
_, records = reference.evaluate(played, driver_cache.read_frames(played), warmup=FRAME - 1)
predicted, bound = records[0].predicted_error, records[0].error_bound
checks.check(record.predicted_error == predicted and record.error_bound == bound,
             f"live mode's prediction {record.predicted_error!r} and bound {record.error_bound!r}"
             f" are the module's {predicted!r} and {bound!r}")
margin = reference.describe_settings()["pose_model"]["verdict_margin"]
checks.check(margin >= 0.0 and abs(bound - (predicted + margin)) <= 1e-12 * bound,
             f"the bound {bound!r} is the prediction {predicted!r} plus the verdict margin "
             f"{margin!r}")

units = scene.unit_settings
checks.check(units.system == "METRIC" and units.scale_length == 1.0,
             "the factory scene is metric at scale 1 (a Blender unit is a metre)")
lines = addon.ui.coverage_lines(record, evaluator.describe_settings(), units)
print(lines)
over = bound > tolerance
expected = [("Predicted", f"{predicted * 1000.0:.1f} mm", False),
            ("Bound", f"{bound * 1000.0:.1f} mm", False),
            ("Simulate", f"Yes: > {tolerance * 1000.0:.1f} mm" if over else
             f"No: ≤ {tolerance * 1000.0:.1f} mm", over)]
checks.check(record.flagged == (1 if over else 0),
             f"frame {FRAME} is flagged exactly when its bound is over the default tolerance "
             f"{tolerance:.4g}")
checks.check(lines == expected, f"the panel says {lines}, expected {expected}")

# A scene in centimetres (unit scale 0.01): a Blender unit is 10 mm.
units.scale_length = 0.01
lines = addon.ui.coverage_lines(record, evaluator.describe_settings(), units)
checks.check(lines[0][1] == f"{predicted * 10.0:.1f} mm", f"centimetre scene: {lines[0]}")
units.system = "NONE"
lines = addon.ui.coverage_lines(record, evaluator.describe_settings(), units)
checks.check(lines[0][1] == f"{predicted:.4g} BU", f"a scene without units: {lines[0]}")
units.system, units.scale_length = "METRIC", 1.0

# A frame over the tolerance is an alert (the record's flag decides, as in the bake's report).
over = types.SimpleNamespace(predicted_error=0.01, error_bound=0.02, flagged=1)
lines = addon.ui.coverage_lines(over, {"coverage_tolerance": 0.0125}, units)
checks.check(lines[1:] == [("Bound", "20.0 mm", False), ("Simulate", "Yes: > 12.5 mm", True)],
             f"a flagged frame: {lines[1:]}")

# The QP predicts nothing: no coverage lines.
settings.weight_mode = "qp"
scene.frame_set(FRAME + 1)
record = addon.live.SESSION.last_record
checks.check(record.predicted_error < 0, "the QP predicts no error")
checks.check(addon.ui.coverage_lines(record, addon.engine.CACHE.evaluator.describe_settings(),
                                     units) == [], "no coverage lines for a QP frame")
bpy.ops.drivenshape.live_stop()
checks.finish()
