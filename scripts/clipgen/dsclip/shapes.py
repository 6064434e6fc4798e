# SPDX-License-Identifier: Apache-2.0
"""The characters' meshes (numpy only): rings of vertices joined by quad bands.

Both characters are tubes. The garment is the body's surface with every section grown by an
offset, its own resolution, cut open where the body is capped.

Lower body. A torso tube runs from the crotch height up to the waist (garment) or to the top
of the pelvis block (body, closed by a dome). Its lowest ring (W vertices, vertex 0 at the front
centre, counter-clockwise seen from above, so W/4 is the left side and W/2 the back centre) is
cut in two halves. A seam of S vertices in the plane x = 0 hangs under the crotch from the back
centre to the front centre. The left leg's first ring is the left half of that ring followed by
the seam; the right leg's is the right half followed by the same seam, so the three tubes share
those vertices and the surface has no hole. Down each leg the rings turn from that "D" shape
into circles about the leg's axis. The right leg is the left one mirrored in X (its faces wound
the other way, so that every face still looks out).

Arm. One tube along +X at the shoulder height, rings in planes x = const, dome caps on the body.

Faces are wound so that their normals point away from the body; `edge_report` checks it
(closed bodies: every edge in two faces, walked once each way).
"""
import numpy as np

from . import curves


class MeshBuild:
    """Vertices, polygons and one UV per polygon corner, collected in order."""

    def __init__(self):
        self.points = []
        self.polys = []
        self.corner_uv = []

    def add(self, P):
        P = np.asarray(P, dtype=float).reshape(-1, 3)
        first = len(self.points)
        self.points.extend(P)
        return np.arange(first, first + len(P))

    def poly(self, ids, uv):
        self.polys.append([int(i) for i in ids])
        self.corner_uv.append([(float(u), float(v)) for u, v in uv])

    def band(self, upper, lower, u, v_upper, v_lower, flip):
        """Quads between two closed rings of equal length. u has len(ring) + 1 entries (the
        last closes the loop at the UV seam). flip reverses the winding."""
        n = len(upper)
        for k in range(n):
            j = (k + 1) % n
            quad = [(upper[k], (u[k], v_upper)), (lower[k], (u[k], v_lower)),
                    (lower[j], (u[k + 1], v_lower)), (upper[j], (u[k + 1], v_upper))]
            if flip:
                quad.reverse()
            self.poly([q[0] for q in quad], [q[1] for q in quad])

    def cone(self, ring, tip, u, v_ring, uv_tip, flip):
        """Triangles from a closed ring to one tip vertex."""
        n = len(ring)
        for k in range(n):
            j = (k + 1) % n
            tri = [(ring[k], (u[k], v_ring)), (tip, uv_tip), (ring[j], (u[k + 1], v_ring))]
            if flip:
                tri.reverse()
            self.poly([t[0] for t in tri], [t[1] for t in tri])

    def mesh(self):
        return dict(verts=np.asarray(self.points, dtype=float), faces=self.polys,
                    uvs=self.corner_uv)


def edge_report(faces):
    """Counts of edges used by one face (open), more than two (non-manifold), and edges whose
    two faces walk them the same way (misoriented)."""
    walked = {}
    for f in faces:
        for a, b in zip(f, f[1:] + f[:1]):
            walked.setdefault((min(a, b), max(a, b)), []).append(a < b)
    open_, fins, flipped = 0, 0, 0
    for ways in walked.values():
        if len(ways) == 1:
            open_ += 1
        elif len(ways) > 2:
            fins += 1
        elif ways[0] == ways[1]:
            flipped += 1
    return dict(edges=len(walked), open=open_, non_manifold=fins, misoriented=flipped)


def signed_volume(verts, faces):
    """Volume enclosed by a closed mesh (> 0 when its faces look outward)."""
    total = 0.0
    for f in faces:
        p0 = verts[f[0]]
        for a, b in zip(f[1:-1], f[2:]):
            total += np.dot(p0, np.cross(verts[a], verts[b])) / 6.0
    return total


def _dome(mb, ring, axis, height, u, v, flip):
    """Close a ring with three shrinking rings and a tip, bulging `height` along `axis`."""
    P = np.asarray(mb.points)[ring]
    centre = P.mean(axis=0)
    previous = ring
    for j in (1, 2, 3):
        angle = 0.5 * np.pi * j / 4.0
        R = mb.add(centre + (P - centre) * np.cos(angle) + axis * height * np.sin(angle))
        mb.band(previous, R, u, v, v, flip)
        previous = R
    tip = mb.add(centre + axis * height)[0]
    mb.cone(previous, tip, u, v, (0.5, v), flip)


# ---------------------------------------------------------------------------------------------
# lower body
# ---------------------------------------------------------------------------------------------
def _leg_axis(shape_hip, knee, ankle, calf):
    """(x, y) of the left leg's axis at heights z: straight hip-knee-ankle lines extended
    beyond both ends, with the calf set back a little."""
    pts = np.array([ankle, knee, shape_hip], dtype=float)
    below = pts[0] + (pts[0] - pts[1]) * 0.3 / (pts[1][2] - pts[0][2])
    above = pts[2] + (pts[2] - pts[1]) * 0.3 / (pts[2][2] - pts[1][2])
    pts = np.vstack([below, pts, above])

    def axis(z):
        z = np.asarray(z, dtype=float)
        x = np.interp(z, pts[:, 2], pts[:, 0])
        y = np.interp(z, pts[:, 2], pts[:, 1])
        y = y + calf["back"] * np.exp(-(((z - calf["z"]) / calf["width"]) ** 2))
        return x, y
    return axis


def _torso_ring(half_w, half_d, z, count, roundness):
    """`count` points evenly spread around a superellipse section, from the front centre
    counter-clockwise (seen from above)."""
    e = 2.0 / roundness

    def at(u):
        t = -0.5 * np.pi + 2.0 * np.pi * np.asarray(u)
        c, s = np.cos(t), np.sin(t)
        return np.stack([half_w * np.sign(c) * np.abs(c) ** e,
                         half_d * np.sign(s) * np.abs(s) ** e], axis=-1)
    xy = at(curves.even_by_length(at, count, closed=True))
    return np.column_stack([xy, np.full(count, z)])


def lower_body(shape, hip, knee, ankle, offset, W, S, dz, top, bottom, closed, cap_h=0.0,
               seam_extra=0.0):
    """Pelvis + legs (closed=True) or trousers (closed=False). Returns the mesh dict with
    `rings` (torso rings bottom-up, leg rings top-down) for pinning."""
    assert W % 4 == 0
    half_w = curves.profile([(z, a) for z, a, _ in shape["torso"]])
    half_d = curves.profile([(z, b) for z, _, b in shape["torso"]])
    radius = curves.profile(shape["leg"])
    axis = _leg_axis(hip, knee, ankle, shape["calf"])
    zc = shape["crotch_z"]
    mb = MeshBuild()

    n_torso = max(1, int(round((top - zc) / dz)))
    torso_z = np.linspace(zc, top, n_torso + 1)
    torso = [mb.add(_torso_ring(half_w(z) + offset, half_d(z) + offset, z, W, shape["roundness"]))
             for z in torso_z]

    # the crotch seam: S points on a half ellipse under the crotch, back centre -> front centre
    depth = half_d(zc) + offset
    sag = shape["seam_dip"] + offset + seam_extra

    def seam_curve(u):
        u = np.asarray(u)
        return np.stack([depth * np.cos(np.pi * u), -sag * np.sin(np.pi * u)], axis=-1)
    yz = seam_curve(curves.even_by_length(seam_curve, S, closed=False))
    seam = mb.add(np.column_stack([np.zeros(S), yz[:, 0], zc + yz[:, 1]]))

    half = W // 2
    first_L = np.concatenate([torso[0][:half + 1], seam])
    first_R = np.concatenate([torso[0][[(W - k) % W for k in range(half + 1)]], seam])
    L = len(first_L)
    D = np.asarray(mb.points)[first_L]
    cx, cy = axis(zc)
    around = np.linalg.norm(np.roll(D, -1, axis=0) - D, axis=1)
    frac = np.concatenate([[0.0], np.cumsum(around)[:-1]]) / around.sum()
    phi = np.arctan2(D[0, 1] - cy, D[0, 0] - cx) + 2.0 * np.pi * frac

    n_leg = max(2, int(round((zc - bottom) / dz)))
    leg_z = np.linspace(zc, bottom, n_leg + 1)
    legs_L, legs_R = [first_L], [first_R]
    for n in range(1, n_leg + 1):
        z = leg_z[n]
        blend = 1.0 - (1.0 - min(n / 6.0, 1.0)) ** 2   # quick at first: a round crotch arch
        x0, y0 = axis(z)
        r = radius(z) + offset
        circle = np.column_stack([x0 + r * np.cos(phi), y0 + r * np.sin(phi), np.full(L, z)])
        P = (1.0 - blend) * (D + [0.0, 0.0, z - zc]) + blend * circle
        legs_L.append(mb.add(P))
        legs_R.append(mb.add(P * [-1.0, 1.0, 1.0]))

    # UVs: the torso band on top, the two legs side by side under it
    u_torso = np.linspace(0.0, 1.0, W + 1)
    v_torso = lambda z: 0.80 + 0.19 * (z - zc) / (top - zc)
    for m in range(n_torso):   # upper ring of the band first when wound with flip=True
        mb.band(torso[m + 1], torso[m], u_torso, v_torso(torso_z[m + 1]), v_torso(torso_z[m]),
                flip=False)
    u_L = np.linspace(0.01, 0.49, L + 1)
    u_R = np.linspace(0.51, 0.99, L + 1)
    v_leg = lambda z: 0.01 + 0.77 * (z - bottom) / (zc - bottom)
    for n in range(n_leg):
        va, vb = v_leg(leg_z[n]), v_leg(leg_z[n + 1])
        mb.band(legs_L[n], legs_L[n + 1], u_L, va, vb, flip=False)
        mb.band(legs_R[n], legs_R[n + 1], u_R, va, vb, flip=True)

    if closed:
        _dome(mb, torso[-1], np.array([0.0, 0.0, 1.0]), cap_h, u_torso, 0.995, flip=True)
        _dome(mb, legs_L[-1], np.array([0.0, 0.0, -1.0]), cap_h, u_L, 0.005, flip=False)
        _dome(mb, legs_R[-1], np.array([0.0, 0.0, -1.0]), cap_h, u_R, 0.005, flip=True)
    out = mb.mesh()
    out["rings"] = dict(torso=[r.tolist() for r in torso], leg_L=[r.tolist() for r in legs_L],
                        leg_R=[r.tolist() for r in legs_R], seam=seam.tolist())
    return out


# ---------------------------------------------------------------------------------------------
# arm
# ---------------------------------------------------------------------------------------------
def arm(shape, offset, N, dx, start, end, closed, cap_h=0.0):
    """Arm (closed=True) or sleeve (closed=False) along +X. Ring vertex k sits at the angle
    2 pi k / N from +Y towards +Z about the arm's axis."""
    radius = curves.profile(shape["radius"])
    z0 = shape["axis_z"]
    mb = MeshBuild()
    n = max(2, int(round((end - start) / dx)))
    xs = np.linspace(start, end, n + 1)
    ang = 2.0 * np.pi * np.arange(N) / N
    rings = []
    for x in xs:
        r = radius(x) + offset
        rings.append(mb.add(np.column_stack([np.full(N, x), r * np.cos(ang),
                                             z0 + r * np.sin(ang)])))
    u = np.linspace(0.0, 1.0, N + 1)
    v = lambda x: 0.02 + 0.96 * (x - start) / (end - start)
    for j in range(n):
        mb.band(rings[j], rings[j + 1], u, v(xs[j]), v(xs[j + 1]), flip=True)
    if closed:
        _dome(mb, rings[0], np.array([-1.0, 0.0, 0.0]), cap_h, u, 0.01, flip=False)
        _dome(mb, rings[-1], np.array([1.0, 0.0, 0.0]), cap_h * 0.85, u, 0.99, flip=True)
    out = mb.mesh()
    out["rings"] = dict(tube=[r.tolist() for r in rings])
    return out
