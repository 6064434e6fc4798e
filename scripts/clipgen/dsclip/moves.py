# SPDX-License-Identifier: Apache-2.0
"""Motion (numpy only): joint angles per frame for each family, forward kinematics, skinning.

A motion is dict(angles={"hip.L.flex": (F,) degrees, ...}, root_pos=(F, 3) metres,
root_yaw=(F,) degrees, about={...}) over every output frame: the PREROLL frames first (the exact
rest pose, then an ease into the motion's first pose), then the motion. Index i is Blender
frame i + 1. Everything is drawn from numpy.random.default_rng(seed), so a seed gives the same
motion on any machine.
"""
import numpy as np

from . import config, curves

TWO_PI = 2.0 * np.pi


def rot(axis, degrees):
    """3x3 right-handed rotation about the world axis 'X', 'Y' or 'Z'."""
    a = np.radians(degrees)
    c, s = np.cos(a), np.sin(a)
    i, j = {"X": (1, 2), "Y": (2, 0), "Z": (0, 1)}[axis]
    R = np.eye(3)
    R[i, i], R[i, j], R[j, i], R[j, j] = c, -s, s, c
    return R


def joint_matrix(joint, v):
    """The rotation of a joint from its dof values in degrees (conventions in config)."""
    if joint in ("hip.L", "hip.R"):
        side = -1.0 if joint == "hip.L" else 1.0
        return rot("X", -v["flex"]) @ rot("Y", side * v["abd"]) @ rot("Z", side * v["twist"])
    if joint in ("knee.L", "knee.R"):
        return rot("X", v["flex"])
    if joint == "shoulder.L":
        return rot("Z", -v["hflex"]) @ rot("Y", -v["elev"]) @ rot("X", v["twist"])
    if joint == "elbow.L":
        return rot("Z", -v["flex"])
    raise KeyError(joint)


def dof_names(character):
    C = config.CHARACTERS[character]
    return [f"{j}.{d}" for j, (_, dofs) in C["joints"].items() for d in dofs]


def bone_matrices(character, angles, root_pos, root_yaw):
    """World-from-rest 4x4 matrix of each bone per frame -> {bone: (F, 4, 4)} (what the
    Armature modifier applies to a vertex bound to the bone alone)."""
    C = config.CHARACTERS[character]
    F = len(root_yaw)
    joint_of = {bone: j for j, (bone, _) in C["joints"].items()}
    out = {}
    for name, head, _, parent, _ in C["bones"]:
        M = np.tile(np.eye(4), (F, 1, 1))
        if parent is None:
            for f in range(F):
                M[f, :3, :3] = rot("Z", root_yaw[f])
                M[f, :3, 3] = root_pos[f]
        else:
            h = np.asarray(head, dtype=float)
            j = joint_of.get(name)
            for f in range(F):
                local = np.eye(4)
                if j is not None:
                    R = joint_matrix(j, {d: angles[f"{j}.{d}"][f] for d in C["joints"][j][1]})
                    local[:3, :3] = R
                    local[:3, 3] = h - R @ h
                M[f] = out[parent][f] @ local
        out[name] = M
    return out


def skin(rest, names, W, mats):
    """Linear blend skinning of rest points (n, 3) with weights W (n, len(names)) -> (F, n, 3)."""
    F = len(next(iter(mats.values())))
    Ph = np.column_stack([rest, np.ones(len(rest))])
    out = np.zeros((F, len(rest), 3))
    for b, name in enumerate(names):
        w = W[:, b]
        if not w.any():
            continue
        moved = np.einsum("fij,nj->fni", mats[name][:, :3, :], Ph)
        out += w[None, :, None] * moved
    return out


# ---------------------------------------------------------------------------------------------
# the pants' legs must not pass through each other
# ---------------------------------------------------------------------------------------------
def leg_gap(pose):
    """Smallest distance (m) between the surfaces of the left and right leg capsules."""
    caps = config.PANTS["leg_capsules"]
    one = {k: np.array([v]) for k, v in pose.items()}
    M = bone_matrices("pants", one, np.zeros((1, 3)), np.zeros(1))
    s = np.linspace(0.0, 1.0, 12)[:, None]
    parts = {}
    for side, x in (("L", 1.0), ("R", -1.0)):
        hip = np.array([x * config.HIP[0], 0.0, config.HIP[2]])
        knee = np.array([x * config.KNEE[0], 0.0, config.KNEE[2]])
        foot = np.array([x * config.ANKLE[0], 0.0, caps["foot_z"]])
        T = M["thigh." + side][0]
        S = M["shin." + side][0]
        move = lambda A, p: A[:3, :3] @ p + A[:3, 3]
        parts[side] = [(move(T, hip) + s * (move(T, knee) - move(T, hip)), caps["thigh"]),
                       (move(S, knee) + s * (move(S, foot) - move(S, knee)), caps["shin"])]
    gap = np.inf
    for a, ra in parts["L"]:
        for b, rb in parts["R"]:
            d = np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2).min()
            gap = min(gap, d - ra - rb)
    return gap


# ---------------------------------------------------------------------------------------------
# families (motion frames only; the preroll is added by `make_motion`)
# ---------------------------------------------------------------------------------------------
PANTS_EXTREME_KEYS = {   # key index -> pose, for the extremes family
    3: {"hip.L.flex": 90, "hip.L.abd": 10, "hip.L.twist": 0, "knee.L.flex": 108,   # seated
        "hip.R.flex": 88, "hip.R.abd": 10, "hip.R.twist": 0, "knee.R.flex": 112},
    5: {"hip.L.flex": 28, "hip.L.abd": -18, "hip.L.twist": -8, "knee.L.flex": 22,  # the left
        "hip.R.flex": -6, "hip.R.abd": 4, "hip.R.twist": 0, "knee.R.flex": 6},     # leg crosses
    7: {"hip.L.flex": -16, "hip.L.abd": 6, "hip.L.twist": 0, "knee.L.flex": 28,    # a lunge
        "hip.R.flex": 84, "hip.R.abd": 6, "hip.R.twist": 4, "knee.R.flex": 98},
}
SLEEVE_EXTREME_KEYS = {
    2: {"shoulder.L.hflex": 4, "shoulder.L.elev": 78, "shoulder.L.twist": -28,     # overhead
        "elbow.L.flex": 14},
    4: {"shoulder.L.hflex": 62, "shoulder.L.elev": 12, "shoulder.L.twist": -58,    # hand to
        "elbow.L.flex": 128},                                                      # shoulder
    6: {"shoulder.L.hflex": 38, "shoulder.L.elev": 76, "shoulder.L.twist": 28,     # overhead,
        "elbow.L.flex": 72},                                                       # bent
}


def random_motion(character, T, rng, forced=None, gap=(12, 20), keep_share=0.3, margin=0.01):
    """Key poses at random gaps of 12-20 frames, each dof redrawn within its range (or kept,
    with probability keep_share), joined by a monotone cubic spline. `forced` keys replace
    drawn ones. For the pants a drawn key is redrawn until the legs keep `margin` apart, at the
    key and on the way to it."""
    C = config.CHARACTERS[character]
    names = dof_names(character)
    times = [0]
    while times[-1] < T - 1:
        times.append(times[-1] + int(rng.integers(gap[0], gap[1] + 1)))
    keys, redrawn = [], 0
    last = {n: 0.0 for n in names}
    for index in range(len(times)):
        if forced and index in forced:
            pose = {**last, **forced[index]}
        else:
            for _ in range(400):
                pose = {n: (float(rng.uniform(*C["ranges"][n]))
                            if index == 0 or rng.random() >= keep_share else last[n])
                        for n in names}
                if character != "pants":
                    break
                path = [{n: last[n] + a * (pose[n] - last[n]) for n in names}
                        for a in (0.25, 0.5, 0.75, 1.0)]
                if all(leg_gap(p) >= margin for p in path):
                    break
                redrawn += 1
        keys.append(pose)
        last = pose
    values = curves.hermite(times, np.array([[k[n] for n in names] for k in keys]),
                            np.arange(T, dtype=float))
    angles = {n: values[:, i] for i, n in enumerate(names)}
    about = dict(kind="random range of motion", key_frames=times, key_gap=list(gap),
                 keep_share=keep_share, redrawn_keys=redrawn,
                 forced_keys={str(k): v for k, v in (forced or {}).items()})
    return angles, np.zeros((T, 3)), np.zeros(T), about


# The gestures (reach and wave, the travelling root's turn) are laid out over this many motion
# frames; a longer clip stretches them, a shorter one stops part-way (never faster than this).
GESTURE_FRAMES = 120


def walking_root(T, speed=1.2, turn=90.0, bob_phase=None):
    """A root that speeds up to `speed` m/s over 18 frames, walks forward (-Y at rest) and
    turns `turn` degrees to the left between 25% and 85% of the gesture span, bobbing 1.2 cm."""
    t = np.arange(T, dtype=float)
    span = max(T, GESTURE_FRAMES)
    start = curves.ramp(t, 0.0, 18.0)
    yaw = turn * curves.ramp(t, 0.25 * span, 0.85 * span)
    heading = np.column_stack([np.sin(np.radians(yaw)), -np.cos(np.radians(yaw)), np.zeros(T)])
    step = (speed / config.FPS) * start[:, None] * heading
    pos = np.vstack([np.zeros((1, 3)), np.cumsum(step[:-1], axis=0)])
    phase = TWO_PI * t / 26.0 if bob_phase is None else bob_phase
    pos[:, 2] = -0.012 * start * (0.5 + 0.5 * np.cos(2.0 * phase))
    return pos, yaw


def walk(T, rng, travel):
    """Pants: a walk cycle (in place, or carried by a walking root), two of its steps
    high-knee ones (one each side when there are cycles enough)."""
    t = np.arange(T, dtype=float)
    period = rng.uniform(24.0, 28.0)
    hip_amp = rng.uniform(22.0, 28.0)
    knee_amp = rng.uniform(48.0, 58.0)
    start = curves.ramp(t, 0.0, 18.0)
    phase_L = TWO_PI * t / period
    cycles = int(T // period)
    pool = np.arange(1, max(cycles, 1) + 1)
    chosen = sorted(rng.choice(pool, size=min(2, len(pool)), replace=False).tolist()) \
        if cycles >= 1 else []
    sides = ["L", "R"] if rng.random() < 0.5 else ["R", "L"]
    angles = {}
    for side, phase in (("L", phase_L), ("R", phase_L + np.pi)):
        lift = np.zeros(T)
        for cycle, s in zip(chosen, sides):
            if s == side:   # a bump centred a little after the hip's forward swing starts
                lift += np.exp(-0.5 * ((phase - (TWO_PI * cycle + 0.5)) / 0.8) ** 2)
        angles[f"hip.{side}.flex"] = start * (7.0 + hip_amp * np.sin(phase)) + 44.0 * lift
        angles[f"hip.{side}.abd"] = start * (4.0 + 2.5 * np.cos(phase))
        angles[f"hip.{side}.twist"] = start * 4.0 * np.sin(phase)
        angles[f"knee.{side}.flex"] = (start * (5.0 + knee_amp * np.maximum(0.0, np.cos(phase)) ** 2)
                                       + 46.0 * lift)
    about = dict(kind="walk", period_frames=period, hip_amplitude=hip_amp,
                 knee_amplitude=knee_amp, high_knee_cycles=chosen, high_knee_sides=sides[:len(chosen)])
    if travel:
        pos, yaw = walking_root(T, bob_phase=phase_L)
        about.update(root="walks forward at 1.2 m/s and turns 90 degrees to the left")
    else:
        pos, yaw = np.zeros((T, 3)), np.zeros(T)
    return angles, pos, yaw, about


def reach_and_wave(T, rng, travel):
    """Sleeve: reach forward with the arm straight, then raise the forearm and wave; the keys
    sit at fixed shares of the gesture span (GESTURE_FRAMES or the clip, the longer)."""
    jitter = lambda size: float(rng.uniform(-size, size))
    # share of the clip, hflex, elev, twist, elbow flex
    keys = np.array([
        [0.00, 0, 0, 0, 0],
        [0.13, 34 + jitter(5), -24 + jitter(5), 10 + jitter(5), 68 + jitter(8)],
        [0.28, 80 + jitter(5), 8 + jitter(4), jitter(5), 8 + jitter(4)],
        [0.37, 86 + jitter(4), 12 + jitter(4), -4 + jitter(5), 4 + jitter(3)],
        [0.50, 20 + jitter(5), 15 + jitter(4), -84 + jitter(5), 80 + jitter(5)],
        [0.87, 22 + jitter(5), 18 + jitter(4), -84 + jitter(5), 82 + jitter(5)],
        [0.93, 20 + jitter(5), 10 + jitter(4), -60 + jitter(5), 70 + jitter(5)],
        [1.00, 10 + jitter(5), -5 + jitter(4), -30 + jitter(5), 45 + jitter(5)],
    ])
    t = np.arange(T, dtype=float)
    span = max(T, GESTURE_FRAMES)
    Y = curves.hermite(keys[:, 0] * (span - 1), keys[:, 1:], t)
    wave_period = rng.uniform(10.0, 13.0)
    w0, w1 = 0.50 * span, 0.87 * span
    window = curves.ramp(t, w0, w0 + 0.05 * span) * (1.0 - curves.ramp(t, w1 - 0.05 * span, w1))
    wave = TWO_PI * (t - w0) / wave_period
    angles = {"shoulder.L.hflex": Y[:, 0], "shoulder.L.elev": Y[:, 1],
              "shoulder.L.twist": Y[:, 2] + 28.0 * window * np.sin(wave),
              "elbow.L.flex": Y[:, 3] + 8.0 * window * np.sin(wave + 1.0)}
    about = dict(kind="reach and wave", keys=keys.tolist(), wave_period_frames=wave_period)
    if travel:
        pos, yaw = walking_root(T)
        about.update(root="walks forward at 1.2 m/s and turns 90 degrees to the left")
    else:
        pos, yaw = np.zeros((T, 3)), np.zeros(T)
    return angles, pos, yaw, about


def make_motion(character, family, seed, frames=None):
    """The whole clip's motion: the preroll, then `frames` frames of the family."""
    T = int(frames or config.FAMILIES[family]["frames"])
    if T < 1:
        raise ValueError("--frames must be at least 1")
    rng = np.random.default_rng(seed)
    if family == "train":
        angles, pos, yaw, about = random_motion(character, T, rng)
    elif family == "extremes":
        forced = PANTS_EXTREME_KEYS if character == "pants" else SLEEVE_EXTREME_KEYS
        angles, pos, yaw, about = random_motion(character, T, rng, forced=forced)
    elif family in ("test_public", "travel"):
        make = walk if character == "pants" else reach_and_wave
        angles, pos, yaw, about = make(T, rng, travel=(family == "travel"))
    else:
        raise ValueError(f"unknown family {family}")
    P, H = config.PREROLL, config.PREROLL_REST
    i = np.arange(P, dtype=float)
    share = np.where(i < H, 0.0, curves.ease((i - H + 1.0) / (P - H + 1.0)))
    full = {n: np.concatenate([share * v[0], v]) for n, v in angles.items()}
    root_pos = np.vstack([np.repeat(pos[:1], P, axis=0), pos])
    root_yaw = np.concatenate([np.repeat(yaw[:1], P), yaw])
    about.update(character=character, family=family, seed=seed, motion_frames=T,
                 preroll=P, preroll_rest=H)
    if character == "pants":
        gaps = np.array([leg_gap({n: full[n][f] for n in full}) for f in range(len(root_yaw))])
        about["smallest_leg_capsule_gap_m"] = float(gaps.min())
        about["frames_with_leg_capsules_touching"] = int((gaps < 0).sum())
    return dict(angles=full, root_pos=root_pos, root_yaw=root_yaw, about=about)
