# SPDX-License-Identifier: Apache-2.0
"""Every number that defines a clip: characters, skeletons, joint ranges, cloth, families.

A change of setup is a change of this file; `setup_record` copies it into each clip's json.

Space: Blender world, metres, Z up. Both characters face -Y; their left side is +X.

Joints turn a bone about its head, in the armature's rest axes (world axes at rest). With
`rot(axis, deg)` a right-handed rotation about a world axis:
  pants   hip.L   rot(X, -flex) . rot(Y, -abd) . rot(Z, -twist)
          hip.R   rot(X, -flex) . rot(Y, +abd) . rot(Z, +twist)
          knee.*  rot(X, +flex)
            flex > 0 swings the thigh forward (-Y), the shin backward; abd > 0 moves the leg
            away from the midline; twist > 0 turns the knee inward.
  sleeve  shoulder.L  rot(Z, -hflex) . rot(Y, -elev) . rot(X, twist)
          elbow.L     rot(Z, -flex)
            the arm rests along +X (T-pose); hflex > 0 swings it forward (-Y), elev > 0 up
            (+Z), twist turns it about its own axis; flex > 0 folds the forearm forward.
  root    translate(tx, ty, tz) . rot(Z, yaw)   (the character's world placement; rest = identity)
"""
import copy

FPS = 24
PREROLL = 20        # frames before the motion, in every clip and every output file
PREROLL_REST = 8    # of which the first ones hold the exact rest pose; the rest ease in

# motion frames after the preroll and the default seed of each family
FAMILIES = {
    "train": dict(frames=300, seed=1,
                  about="random range of motion: a new key pose every 12-20 frames"),
    "test_public": dict(frames=120, seed=2,
                        about="pants: walk in place with two high-knee steps; "
                              "sleeve: reach forward, then raise the forearm and wave"),
    "extremes": dict(frames=120, seed=5,
                     about="random range of motion with forced extreme keys: sitting, "
                           "cross-step, lunge (pants); overhead, hand to shoulder (sleeve)"),
    "travel": dict(frames=120, seed=6,
                   about="the walk / the reach and wave while the root walks forward at "
                         "1.2 m/s and turns 90 degrees to the left"),
}

# ---------------------------------------------------------------------------------------------
# pants: a pelvis block on two legs, and trousers over them
# ---------------------------------------------------------------------------------------------
HIP = (0.10, 0.0, 0.94)      # left hip joint; the right one is mirrored in X
KNEE = (0.105, 0.0, 0.50)
ANKLE = (0.11, 0.0, 0.08)

LOWER_BODY = dict(
    crotch_z=0.86,
    seam_dip=0.02,           # the crotch seam hangs this far below crotch_z (plus the offset)
    roundness=2.3,           # superellipse exponent of the torso sections (2 = ellipse)
    # torso sections: height, half width (X), half depth (Y)
    torso=[(0.86, 0.170, 0.100), (0.94, 0.172, 0.106), (1.00, 0.158, 0.099),
           (1.06, 0.146, 0.094), (1.12, 0.142, 0.093), (1.17, 0.145, 0.095)],
    # leg radius by height (thigh, knee, calf, ankle)
    leg=[(0.86, 0.072), (0.76, 0.066), (0.63, 0.057), (0.53, 0.050), (0.49, 0.049),
         (0.44, 0.051), (0.35, 0.054), (0.24, 0.045), (0.14, 0.036), (0.08, 0.033)],
    calf=dict(z=0.35, back=0.008, width=0.09),   # the calf sits a little behind the shin line
)

PANTS = dict(
    name="pants",
    objects=("body", "pants"),
    shape=LOWER_BODY,
    # W vertices per torso ring, S on the crotch seam, ring spacing dz; cap_h: dome height
    body=dict(offset=0.0, W=48, S=10, dz=0.018, top=1.17, bottom=0.08, cap_h=0.03, closed=True),
    garment=dict(offset=0.02, W=52, S=13, dz=0.016, top=1.07, bottom=0.11, seam_extra=0.006,
                 closed=False),
    pinned_rings=2,          # the two top rings of the trousers: the waistband
    bones=[  # name, head, tail, parent, deforms
        ("root", (0, 0, 0), (0, 0.2, 0), None, False),
        ("pelvis", (0, 0, 0.94), (0, 0, 1.17), "root", True),
        ("thigh.L", HIP, KNEE, "pelvis", True),
        ("shin.L", KNEE, ANKLE, "thigh.L", True),
        ("thigh.R", (-HIP[0], 0, HIP[2]), (-KNEE[0], 0, KNEE[2]), "pelvis", True),
        ("shin.R", (-KNEE[0], 0, KNEE[2]), (-ANKLE[0], 0, ANKLE[2]), "thigh.R", True),
    ],
    # segments whose distance sets the skin weights; the thighs start 5 cm under the hip so
    # that the seat and the waist stay with the pelvis
    weight_segments={
        "pelvis": [((-0.10, 0, 0.94), (0.10, 0, 0.94)), ((0, 0, 0.94), (0, 0, 1.20))],
        "thigh.L": [((0.1006, 0, 0.89), KNEE)],
        "shin.L": [(KNEE, (0.1105, 0, 0.04))],
        "thigh.R": [((-0.1006, 0, 0.89), (-KNEE[0], 0, KNEE[2]))],
        "shin.R": [((-KNEE[0], 0, KNEE[2]), (-0.1105, 0, 0.04))],
    },
    joints={"hip.L": ("thigh.L", ("flex", "abd", "twist")), "knee.L": ("shin.L", ("flex",)),
            "hip.R": ("thigh.R", ("flex", "abd", "twist")), "knee.R": ("shin.R", ("flex",))},
    ranges={"hip.L.flex": (-20, 92), "hip.L.abd": (-5, 40), "hip.L.twist": (-30, 30),
            "knee.L.flex": (0, 118), "hip.R.flex": (-20, 92), "hip.R.abd": (-5, 40),
            "hip.R.twist": (-30, 30), "knee.R.flex": (0, 118)},
    # radii (cloth included) of the capsules that keep the two legs apart in random poses
    leg_capsules=dict(thigh=0.085, shin=0.066, foot_z=0.03),
)

# ---------------------------------------------------------------------------------------------
# sleeve: an arm in T-pose with a shoulder stub, and a sleeve over it
# ---------------------------------------------------------------------------------------------
ARM = dict(
    axis_z=1.40,
    # radius along the arm (shoulder, biceps, elbow, forearm, wrist, hand)
    radius=[(0.02, 0.052), (0.08, 0.058), (0.14, 0.061), (0.21, 0.058), (0.30, 0.051),
            (0.39, 0.046), (0.46, 0.042), (0.52, 0.044), (0.59, 0.042), (0.68, 0.034),
            (0.74, 0.029), (0.79, 0.031)],
)

SLEEVE = dict(
    name="sleeve",
    objects=("arm", "sleeve"),
    shape=ARM,
    body=dict(offset=0.0, N=32, dx=0.0125, start=0.03, end=0.79, cap_h=0.028, closed=True),
    garment=dict(offset=0.02, N=44, dx=0.0115, start=0.12, end=0.70, closed=False),
    pinned_rings=2,          # the two rings at the shoulder end of the sleeve
    bones=[
        ("root", (0, 0, 0), (0, 0.2, 0), None, True),     # carries the shoulder stub
        ("upperarm.L", (0.17, 0, 1.40), (0.47, 0, 1.40), "root", True),
        ("forearm.L", (0.47, 0, 1.40), (0.77, 0, 1.40), "upperarm.L", True),
    ],
    weight_segments={
        "root": [((0.0, 0, 1.40), (0.16, 0, 1.40))],
        "upperarm.L": [((0.17, 0, 1.40), (0.47, 0, 1.40))],
        "forearm.L": [((0.47, 0, 1.40), (0.82, 0, 1.40))],
    },
    joints={"shoulder.L": ("upperarm.L", ("hflex", "elev", "twist")),
            "elbow.L": ("forearm.L", ("flex",))},
    ranges={"shoulder.L.hflex": (-30, 92), "shoulder.L.elev": (-60, 80),
            "shoulder.L.twist": (-70, 70), "elbow.L.flex": (0, 130)},
)

CHARACTERS = {"pants": PANTS, "sleeve": SLEEVE}

# ---------------------------------------------------------------------------------------------
# simulation settings, by Blender attribute name: ClothSettings (cloth), ClothCollisionSettings
# (cloth_collision) and the driver's CollisionSettings (body_collision). `--set GROUP.KEY=VALUE`
# overrides one for a clip.
# ---------------------------------------------------------------------------------------------
SIM_DEFAULTS = dict(
    cloth=dict(
        quality=8,                      # solver steps per frame
        mass=0.15,                      # kg per vertex
        air_damping=1.0,
        bending_model="ANGULAR",
        tension_stiffness=15.0, compression_stiffness=15.0, shear_stiffness=5.0,
        bending_stiffness=0.15,         # below Blender's 0.5: the folds show
        tension_damping=5.0, compression_damping=5.0, shear_damping=5.0, bending_damping=0.5,
        pin_stiffness=1.0,
    ),
    cloth_collision=dict(
        collision_quality=4,
        distance_min=0.006,             # metres kept between cloth and body
        impulse_clamp=0.0,
        use_collision=True,
        use_self_collision=False,
    ),
    body_collision=dict(
        thickness_outer=0.004,
        thickness_inner=0.05,
        cloth_friction=5.0,
        damping=0.1,
        use_culling=True,               # one-sided: the body's normals point out
    ),
)


def sim_settings(overrides):
    """The simulation settings with `GROUP.KEY=VALUE` overrides applied (typed as the default)."""
    out = copy.deepcopy(SIM_DEFAULTS)
    for item in overrides:
        if "=" not in item or "." not in item.split("=", 1)[0]:
            raise ValueError(f"--set {item}: expected GROUP.KEY=VALUE")
        key, text = item.split("=", 1)
        group, name = key.split(".", 1)
        if group not in out or name not in out[group]:
            known = ", ".join(f"{g}.{k}" for g in out for k in out[g])
            raise ValueError(f"--set {item}: unknown setting (known: {known})")
        old = out[group][name]
        if isinstance(old, bool):
            if text not in ("True", "False", "true", "false", "1", "0"):
                raise ValueError(f"--set {item}: expected True or False")
            out[group][name] = text in ("True", "true", "1")
        else:
            out[group][name] = type(old)(text)
    return out


def setup_record(character):
    """The character's setup as JSON-friendly data (copied into every clip's json)."""
    C = CHARACTERS[character]
    return dict(
        bones=[dict(name=n, head=list(h), tail=list(t), parent=p, deform=d)
               for n, h, t, p, d in C["bones"]],
        joints={j: dict(bone=b, dofs=list(d)) for j, (b, d) in C["joints"].items()},
        ranges_deg={k: list(v) for k, v in C["ranges"].items()},
        joint_conventions=__doc__,
        shape=C["shape"], body=C["body"], garment=C["garment"], pinned_rings=C["pinned_rings"],
        fps=FPS, preroll=PREROLL, preroll_rest=PREROLL_REST,
    )
