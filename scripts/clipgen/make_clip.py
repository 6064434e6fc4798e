# SPDX-License-Identifier: Apache-2.0
"""Make one simulated clip with Blender's cloth solver: (character, family, seed) -> files.

  blender -b --factory-startup --python-exit-code 1 --python scripts/clipgen/make_clip.py -- \\
      --scene {pants,sleeve} --family {train,test_public,extremes,travel} --out DIR \\
      [--seed N] [--frames T] [--set GROUP.KEY=VALUE ...] [--save-blend PATH [--blend-only]]

Writes into DIR/<scene>/: driver_rest.obj, driven_rest.obj, rig.json (the same for every clip of
the character), <family>.driver.pc2, <family>.driven.pc2 and <family>.json (written last: a
clip without it is unfinished). See scripts/clipgen/README.md.
"""
import argparse
import json
import os
import platform
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bpy  # noqa: E402
import numpy as np  # noqa: E402

from dsclip import blendscene, cachefiles, config, moves, shapes, weights  # noqa: E402


def options():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    ap = argparse.ArgumentParser(prog="make_clip.py", description=__doc__.split("\n")[0])
    ap.add_argument("--scene", required=True, choices=sorted(config.CHARACTERS))
    ap.add_argument("--family", required=True, choices=list(config.FAMILIES))
    ap.add_argument("--seed", type=int, help="default: train 1, test_public 2, extremes 5, travel 6")
    ap.add_argument("--out", required=True, help="the clip folder; files go to OUT/<scene>/")
    ap.add_argument("--frames", type=int,
                    help="motion frames after the 20 preroll frames (default: train 300, others 120)")
    ap.add_argument("--set", action="append", default=[], metavar="GROUP.KEY=VALUE",
                    help="override a simulation setting (groups cloth, cloth_collision, "
                    "body_collision; e.g. cloth.bending_stiffness=0.5); recorded in the json")
    ap.add_argument("--save-blend", metavar="PATH",
                    help="also save the set-up scene (animated body, garment with its Cloth "
                    "modifier and pin group, collision) before simulating")
    ap.add_argument("--blend-only", action="store_true",
                    help="with --save-blend: stop after saving it (no simulation, no clip files)")
    a = ap.parse_args(argv)
    if a.seed is None:
        a.seed = config.FAMILIES[a.family]["seed"]
    if a.blend_only and not a.save_blend:
        ap.error("--blend-only needs --save-blend")
    try:
        a.sim = config.sim_settings(a.set)
    except ValueError as error:
        ap.error(str(error))
    return a


def build_meshes(scene):
    """Body and garment meshes, skin weights, pinned garment vertices (numpy, deterministic)."""
    C = config.CHARACTERS[scene]
    if scene == "pants":
        where = dict(shape=C["shape"], hip=config.HIP, knee=config.KNEE, ankle=config.ANKLE)
        body = shapes.lower_body(**where, **C["body"])
        garment = shapes.lower_body(**where, **C["garment"])
        pinned = [i for ring in garment["rings"]["torso"][-C["pinned_rings"]:] for i in ring]
    else:
        body = shapes.arm(C["shape"], **C["body"])
        garment = shapes.arm(C["shape"], **C["garment"])
        pinned = [i for ring in garment["rings"]["tube"][:C["pinned_rings"]] for i in ring]
    for label, mesh, closed in (("body", body, True), ("garment", garment, False)):
        edges = shapes.edge_report(mesh["faces"])
        if edges["misoriented"] or edges["non_manifold"] or (closed and edges["open"]):
            raise RuntimeError(f"{scene} {label}: bad topology {edges}")
    if shapes.signed_volume(body["verts"], body["faces"]) <= 0:
        raise RuntimeError(f"{scene} body: faces look inward")
    names, W_body = weights.bone_weights(body["verts"], body["faces"], C["weight_segments"])
    W_garment, gap, side = weights.copy_weights(body["verts"], body["faces"], W_body,
                                                garment["verts"])
    if (side <= 0).any():
        raise RuntimeError(f"{scene}: {int((side <= 0).sum())} garment vertices start inside the body")
    return dict(body=body, garment=garment, names=names, W_body=W_body, W_garment=W_garment,
                gap=gap, pinned=sorted(pinned))


def rounded(x, digits=6):
    return np.round(np.asarray(x, dtype=float), digits).tolist()


def write_rest(out, scene, objects, body_ob, garment_ob, built):
    C = config.CHARACTERS[scene]
    for fname, ob, mesh in (("driver_rest.obj", body_ob, built["body"]),
                            ("driven_rest.obj", garment_ob, built["garment"])):
        path = os.path.join(out, fname)
        cachefiles.write_obj(path, ob.name, blendscene.rest_coordinates(ob), mesh["faces"],
                             mesh["uvs"])
        back, faces, _, _ = cachefiles.read_obj(path)
        if len(back) != len(mesh["verts"]) or faces != mesh["faces"]:
            raise RuntimeError(f"{path}: read back differently")
    rig = dict(
        scene=scene, generator="drivenshape scripts/clipgen",
        bone_names=built["names"],
        bones=[dict(name=n, parent=p, head=list(h), tail=list(t), deform=d)
               for n, h, t, p, d in C["bones"]],
        note="weight rows follow the OBJ/PC2 vertex order, columns bone_names; skinning with "
             "the bone_matrices of <family>.json reproduces the driver, and the driven mesh's "
             "skinning is the 'follow the body' baseline",
        driver_weights=rounded(built["W_body"]), driven_weights=rounded(built["W_garment"]),
        driven_pin_vertices=built["pinned"],
        driven_rest_gap_to_driver_m=dict(min=float(built["gap"].min()),
                                         mean=float(built["gap"].mean()),
                                         max=float(built["gap"].max())))
    with open(os.path.join(out, "rig.json"), "w") as fh:
        json.dump(rig, fh)


def checks(scene, motion, built, drv, dvn, mats):
    """Numbers that tell a good clip: Blender's pose against numpy's, nothing NaN, how far the
    cloth strays from plain skinning."""
    mine = moves.bone_matrices(scene, motion["angles"], motion["root_pos"], motion["root_yaw"])
    follow = moves.skin(built["garment"]["verts"], built["names"], built["W_garment"], mats)
    stray = np.linalg.norm(dvn - follow, axis=2)
    skinned = moves.skin(built["body"]["verts"], built["names"], built["W_body"], mats)
    step = np.abs(np.diff(dvn, axis=0)).max(axis=(1, 2)) if len(dvn) > 1 else np.zeros(0)
    return dict(
        numpy_vs_blender_bone_matrices_max_abs=max(float(np.abs(mine[b] - mats[b]).max())
                                                   for b in mine),
        numpy_skinning_vs_blender_driver_max_abs_m=float(np.abs(skinned - drv).max()),
        driver_frame1_vs_rest_max_abs_m=float(np.abs(drv[0] - built["body"]["verts"]).max()),
        driven_frame1_vs_rest_max_abs_m=float(np.abs(dvn[0] - built["garment"]["verts"]).max()),
        finite=bool(np.isfinite(drv).all() and np.isfinite(dvn).all()),
        driven_largest_vertex_step_m=float(step.max()) if len(step) else 0.0,
        driven_frames_identical_to_previous=int((step == 0).sum()),
        driven_minus_skinned_follow_m=dict(
            per_frame_mean=rounded(stray.mean(axis=1), 5), per_frame_max=rounded(stray.max(axis=1), 5),
            mean=float(stray.mean()), max=float(stray.max())),
    )


def main():
    a = options()
    began = time.perf_counter()
    C = config.CHARACTERS[a.scene]
    out = os.path.join(a.out, a.scene)
    os.makedirs(out, exist_ok=True)
    motion = moves.make_motion(a.scene, a.family, a.seed, a.frames)
    F = len(motion["root_yaw"])
    built = build_meshes(a.scene)

    scene = blendscene.empty_scene(F, config.FPS)
    body_name, garment_name = C["objects"]
    body_ob = blendscene.mesh_object(body_name, built["body"])
    garment_ob = blendscene.mesh_object(garment_name, built["garment"])
    rig = blendscene.armature(C["bones"])
    blendscene.bind(body_ob, rig, built["names"], built["W_body"])
    blendscene.make_collider(body_ob, a.sim["body_collision"])
    blendscene.bind(garment_ob, rig, built["names"], built["W_garment"])
    blendscene.make_cloth(garment_ob, built["pinned"], a.sim["cloth"], a.sim["cloth_collision"], F)
    blendscene.animate(rig, C, motion, moves.joint_matrix)
    scene.frame_set(1)
    if a.save_blend:
        bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(a.save_blend))
        print(f"saved {a.save_blend}", flush=True)
        if a.blend_only:
            return
    write_rest(out, a.scene, C["objects"], body_ob, garment_ob, built)
    setup_s = time.perf_counter() - began

    print(f"[{a.scene} {a.family} seed {a.seed}] {F} frames; driver {len(built['body']['verts'])} "
          f"vertices, driven {len(built['garment']['verts'])}", flush=True)
    drv, dvn, seconds, cpu, mats = blendscene.run(scene, body_ob, garment_ob, rig, F)
    cachefiles.write_pc2(os.path.join(out, f"{a.family}.driver.pc2"), drv)
    cachefiles.write_pc2(os.path.join(out, f"{a.family}.driven.pc2"), dvn)
    found = checks(a.scene, motion, built, drv, dvn, mats)
    print("checks: " + ", ".join(f"{k} {v}" for k, v in found.items() if not isinstance(v, dict)),
          flush=True)
    if not found["finite"]:
        raise RuntimeError("the simulation produced NaN or infinite positions")

    later = seconds[1:] if F > 1 else seconds
    later_cpu = cpu[1:] if F > 1 else cpu
    info = dict(
        generator="drivenshape scripts/clipgen/make_clip.py",
        scene=a.scene, family=a.family, sequence=a.family, seed=a.seed, overrides=a.set,
        about=config.FAMILIES[a.family]["about"],
        blender_version=bpy.app.version_string, python=platform.python_version(),
        numpy=np.__version__,
        machine=dict(platform=platform.platform(), cpu_count=os.cpu_count()),
        fps=config.FPS, frames=F, num_frames=F, frame_start=1, frame_end=F,
        preroll=config.PREROLL, preroll_frames=config.PREROLL,
        preroll_rest_frames=config.PREROLL_REST, motion_start_frame=config.PREROLL + 1,
        motion_frames=F - config.PREROLL,
        pc2=dict(driver=f"{a.family}.driver.pc2", driven=f"{a.family}.driven.pc2",
                 start_frame=1.0, sample_rate=1.0, num_samples=F,
                 layout="float32 little endian [frame][vertex][xyz], Blender world space, metres"),
        driver=dict(object=body_name, rest_obj="driver_rest.obj",
                    num_vertices=len(built["body"]["verts"]), num_faces=len(built["body"]["faces"])),
        driven=dict(object=garment_name, rest_obj="driven_rest.obj",
                    num_vertices=len(built["garment"]["verts"]),
                    num_faces=len(built["garment"]["faces"]), pin_vertex_group="pin",
                    num_pinned=len(built["pinned"])),
        coordinate_system="Blender world space, metres, Z up, the character faces -Y, its left "
                          "is +X; OBJ, Blender and PC2 coordinates are the same",
        cloth_settings=a.sim,
        setup=config.setup_record(a.scene),
        motion=motion["about"],
        joint_angles_deg={k: rounded(v, 4) for k, v in motion["angles"].items()},
        root_translation_m=rounded(motion["root_pos"], 5),
        root_yaw_deg=rounded(motion["root_yaw"], 4),
        bone_matrices=dict(note="world-from-rest 4x4, row-major, per frame, read from Blender's pose",
                           bones={b: rounded(m.reshape(F, 16)) for b, m in mats.items()}),
        timing=dict(seconds_per_frame=rounded(seconds, 4), mean_frame_s=float(later.mean()),
                    total_simulation_s=float(seconds.sum()),
                    cpu_seconds_per_frame=rounded(cpu, 4), mean_frame_cpu_s=float(later_cpu.mean()),
                    setup_s=setup_s,
                    total_s=time.perf_counter() - began,
                    note="wall and process CPU time (all threads) of scene.frame_set per frame "
                         "(cloth solve, skinning, collision); frame 1 initialises the cache; the "
                         "means leave frame 1 out"),
        checks=found,
    )
    with open(os.path.join(out, f"{a.family}.json"), "w") as fh:
        json.dump(info, fh)
    print(f"[{a.scene} {a.family} seed {a.seed}] done: {F} frames, {seconds.sum():.1f} s "
          f"simulating ({later.mean():.2f} s per frame, {later_cpu.mean():.2f} s CPU), "
          f"{time.perf_counter() - began:.1f} s in all",
          flush=True)


if __name__ == "__main__":
    main()
