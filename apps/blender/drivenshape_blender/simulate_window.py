# SPDX-License-Identifier: Apache-2.0
"""Simulates one window of a shot in a background Blender (issue 44): what `drivenshape
simulate` runs once per window, on the farm or locally.

    blender -b SHOT.blend --python-exit-code 1 --python simulate_window.py -- \\
        --object GARMENT --bake 'out/x.####.exr' --first A --last B --goal-strength S \\
        -o 'dir/w.####.exr' [--space world|object] [--module-path DIR]

The garment's cloth simulates frames A..B from the bake's cloth at A, pulled toward the bake with
strength S (0 = free, 1 = the bake), and writes one point-cache EXR per frame to -o
(simulate.simulate_window has the details: start state, rest shape, goal, velocities). --space
says which space the bake's EXRs hold: world (default; the command line's bakes and the add-on's
Space = World) or the cloth object's (the add-on's Space = Object). --module-path names the folder
that holds the drivenshape Python module; otherwise DRIVENSHAPE_PYTHONPATH and the add-on's
usual places (module.py).

SHOT.blend is never written: the script first saves the opened file as a copy in a temporary
folder and works on that (so freeing the cloth's bake or disk cache touches the copy's cache
only), then deletes it. Exit 0 with every frame written; 1 with one line on stderr that names
the object, file or frame at fault, and no output file left.
"""

import argparse
import os
import shutil
import sys
import tempfile

import bpy

HERE = os.path.dirname(os.path.abspath(__file__))
PACKAGE = os.path.basename(HERE)


def options():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(prog="simulate_window.py",
                                     description=__doc__.split("\n")[0])
    parser.add_argument("--object", required=True, help="the garment (a mesh with a Cloth "
                        "modifier)")
    parser.add_argument("--bake", required=True, help="the bake's point-cache EXRs (####)")
    parser.add_argument("--first", type=int, required=True)
    parser.add_argument("--last", type=int, required=True)
    parser.add_argument("--goal-strength", type=float, required=True,
                        help="0 (a free simulation) to 1 (the bake)")
    parser.add_argument("-o", "--output", required=True, help="the window's EXRs (####)")
    parser.add_argument("--space", choices=("world", "object"), default="world",
                        help="the space of the bake's EXRs and of the outputs")
    parser.add_argument("--module-path", help="the folder that holds the drivenshape module")
    return parser.parse_args(argv)


def addon():
    """The add-on package this script belongs to (its simulate and module parts)."""
    loaded = sys.modules.get(PACKAGE)
    if loaded is None:
        sys.path.insert(0, os.path.dirname(HERE))
    import importlib  # noqa: PLC0415

    return importlib.import_module(PACKAGE)


def fail(message):
    print(f"simulate_window: {message}", file=sys.stderr, flush=True)
    sys.exit(1)


def main():
    args = options()
    if args.module_path:
        os.environ["DRIVENSHAPE_PYTHONPATH"] = os.pathsep.join(
            [os.path.abspath(args.module_path), os.environ.get("DRIVENSHAPE_PYTHONPATH", "")])
    # Paths are the caller's, relative to its working folder, before the file moves.
    bake_pattern = os.path.abspath(args.bake)
    out_pattern = os.path.abspath(args.output)
    blend = bpy.data.filepath
    if not blend:
        fail("no .blend file was opened: run blender -b SHOT.blend ... --python "
             "simulate_window.py")
    package = addon()
    simulate, module = package.simulate, package.module
    try:
        module.get()
    except module.ModuleMissing as error:
        fail(str(error))
    if bpy.app.autoexec_fail:
        print(f"simulate_window: warning: {blend} has Python drivers or scripts that Blender "
              "did not run (start it with --enable-autoexec if the rig needs them)",
              file=sys.stderr, flush=True)
    scene = bpy.context.scene
    work = tempfile.mkdtemp(prefix="drivenshape_simulate_")
    try:
        obj = simulate.find_garment(scene, args.object)
        # A copy to work on: its disk cache and its bake live beside it, not beside SHOT.blend.
        bpy.ops.wm.save_as_mainfile(filepath=os.path.join(work, os.path.basename(blend)),
                                    copy=False, relative_remap=True, compress=False)
        written = simulate.simulate_window(
            scene, obj, bake_pattern, args.first, args.last, args.goal_strength, out_pattern,
            space=args.space.upper(), own_file=True, blend=blend)
    except simulate.UserError as error:
        fail(f"{args.object}, frames {args.first}-{args.last}: {error}")
    except Exception as error:  # a module Error or a bug: still one line that says where
        fail(f"{args.object}, frames {args.first}-{args.last}: "
             f"{package.engine.describe_error(error)}")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    print(f"simulate_window: wrote {len(written)} frames {args.first}-{args.last} of "
          f"'{args.object}' to {out_pattern}", flush=True)
    # Every frame is written and renamed into place. Blender 3.4 can crash (signal 11) while it
    # tears down after a cloth simulation (seen on the trouser clips' windows of 45 frames), which
    # would fail a finished window: end the process here instead of returning to Blender, after
    # removing what Blender's exit would (its session's temporary folder).
    if bpy.app.tempdir:
        shutil.rmtree(bpy.app.tempdir, ignore_errors=True)
    sys.stderr.flush()
    os._exit(0)


if __name__ == "__main__":
    main()
