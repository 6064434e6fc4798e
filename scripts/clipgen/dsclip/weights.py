# SPDX-License-Identifier: Apache-2.0
"""Skin weights (numpy only): the body's from its distance to the bones, the garment's copied
from the nearest point of the body's surface (so skinning the garment alone is the "just follow
the body" baseline)."""
import numpy as np


def triangles(faces):
    """Fan triangles of the polygons -> (T, 3) int array."""
    return np.array([(f[0], f[i], f[i + 1]) for f in faces for i in range(1, len(f) - 1)],
                    dtype=np.int64)


def edges(faces):
    pairs = {(min(a, b), max(a, b)) for f in faces for a, b in zip(f, f[1:] + f[:1])}
    return np.array(sorted(pairs), dtype=np.int64)


def segment_distance(P, a, b):
    """Distance of the points P (n, 3) to the segment a-b."""
    a = np.asarray(a, dtype=float)
    ab = np.asarray(b, dtype=float) - a
    t = np.clip((P - a) @ ab / (ab @ ab), 0.0, 1.0)
    return np.linalg.norm(P - (a + t[:, None] * ab), axis=1)


def bone_weights(verts, faces, segments, falloff=0.012, passes=8, keep=0.02):
    """Weights (n, bones) from the distance to each bone's segments: exp(-(d - d_nearest) /
    falloff), averaged with the mesh neighbours `passes` times (half own, half neighbours),
    then the weights under `keep` dropped and each row normalised. -> (names, W)."""
    names = list(segments)
    d = np.column_stack([np.min([segment_distance(verts, a, b) for a, b in segs], axis=0)
                         for segs in segments.values()])
    W = np.exp(-(d - d.min(axis=1, keepdims=True)) / falloff)
    W /= W.sum(axis=1, keepdims=True)
    E = edges(faces)
    count = np.bincount(E.ravel(), minlength=len(verts)).astype(float)[:, None]
    for _ in range(passes):
        total = np.zeros_like(W)
        np.add.at(total, E[:, 0], W[E[:, 1]])
        np.add.at(total, E[:, 1], W[E[:, 0]])
        W = 0.5 * W + 0.5 * total / np.maximum(count, 1.0)
    W[W < keep] = 0.0
    W /= W.sum(axis=1, keepdims=True)
    return names, W


def closest_on_triangles(P, A, B, C):
    """Closest points of triangles ABC (..., 3) to points P (..., 3), broadcast together.
    -> (Q, barycentric (..., 3)). The projection on the plane when it falls inside the
    triangle, else the nearest of the three edges' closest points."""
    e1, e2 = B - A, C - A
    d11 = np.einsum("...i,...i", e1, e1)
    d12 = np.einsum("...i,...i", e1, e2)
    d22 = np.einsum("...i,...i", e2, e2)
    w = P - A
    p1 = np.einsum("...i,...i", w, e1)
    p2 = np.einsum("...i,...i", w, e2)
    det = d11 * d22 - d12 * d12
    det = np.where(np.abs(det) < 1e-30, 1e-30, det)
    s = (d22 * p1 - d12 * p2) / det
    t = (d11 * p2 - d12 * p1) / det
    inside = (s >= 0) & (t >= 0) & (s + t <= 1)
    best_bary = np.stack([1 - s - t, s, t], axis=-1)
    best_q = A + s[..., None] * e1 + t[..., None] * e2
    best_d = np.where(inside, np.einsum("...i,...i", P - best_q, P - best_q), np.inf)
    # the three edges: (from, to, barycentric index of from, of to)
    for X, Y, ix, iy in ((A, B, 0, 1), (B, C, 1, 2), (C, A, 2, 0)):
        xy = Y - X
        u = np.clip(np.einsum("...i,...i", P - X, xy)
                    / np.maximum(np.einsum("...i,...i", xy, xy), 1e-30), 0.0, 1.0)
        q = X + u[..., None] * xy
        dq = np.einsum("...i,...i", P - q, P - q)
        better = dq < best_d
        bary = np.zeros(u.shape + (3,))
        bary[..., ix] = 1.0 - u
        bary[..., iy] = u
        best_q = np.where(better[..., None], q, best_q)
        best_bary = np.where(better[..., None], bary, best_bary)
        best_d = np.where(better, dq, best_d)
    return best_q, best_bary


class Surface:
    """Nearest-point queries on a polygon mesh without a spatial library: the candidates of a
    query are the triangles around its `near` nearest mesh vertices (brute force, in chunks)."""

    def __init__(self, verts, faces, near=10):
        self.verts = np.asarray(verts, dtype=float)
        self.tris = triangles(faces)
        self.near = near
        around = [[] for _ in range(len(self.verts))]
        for t, tri in enumerate(self.tris):
            for v in tri:
                around[v].append(t)
        width = max(len(a) for a in around)
        self.around = np.full((len(self.verts), width), -1, dtype=np.int64)
        for v, a in enumerate(around):
            self.around[v, :len(a)] = a
        A, B, C = (self.verts[self.tris[:, i]] for i in range(3))
        n = np.cross(B - A, C - A)
        self.normals = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)

    def at(self, verts):
        """A copy of the same mesh at other vertex positions (a deformed frame)."""
        other = Surface.__new__(Surface)
        other.verts = np.asarray(verts, dtype=float)
        other.tris, other.near, other.around = self.tris, self.near, self.around
        A, B, C = (other.verts[other.tris[:, i]] for i in range(3))
        n = np.cross(B - A, C - A)
        other.normals = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
        return other

    def closest(self, P, chunk=256):
        """For points P (m, 3): closest surface point, its triangle, barycentric coordinates,
        distance, and a side (> 0 outside) from the summed normals of the triangles tied for
        nearest (a pseudo-normal where the point is nearest an edge or a vertex)."""
        P = np.asarray(P, dtype=float)
        m = len(P)
        Q = np.zeros((m, 3))
        tri = np.zeros(m, dtype=np.int64)
        bary = np.zeros((m, 3))
        side = np.zeros(m)
        sq_norm = np.einsum("ij,ij->i", self.verts, self.verts)
        for lo in range(0, m, chunk):
            p = P[lo:lo + chunk]
            d2 = sq_norm[None, :] - 2.0 * p @ self.verts.T + np.einsum("ij,ij->i", p, p)[:, None]
            k = min(self.near, len(self.verts) - 1)
            nearest = np.argpartition(d2, k, axis=1)[:, :k]
            cand = self.around[nearest].reshape(len(p), -1)
            cand = np.sort(cand, axis=1)
            valid = cand >= 0
            valid[:, 1:] &= cand[:, 1:] != cand[:, :-1]   # each triangle once
            c = np.where(valid, cand, 0)
            T = self.tris[c]
            q, b = closest_on_triangles(p[:, None, :], self.verts[T[..., 0]],
                                        self.verts[T[..., 1]], self.verts[T[..., 2]])
            dist = np.linalg.norm(p[:, None, :] - q, axis=2)
            dist = np.where(valid, dist, np.inf)
            j = np.argmin(dist, axis=1)
            rows = np.arange(len(p))
            Q[lo:lo + chunk] = q[rows, j]
            tri[lo:lo + chunk] = c[rows, j]
            bary[lo:lo + chunk] = b[rows, j]
            best = dist[rows, j]
            tied = valid & (dist <= best[:, None] * (1 + 1e-6) + 1e-12)
            nsum = np.einsum("ij,ijk->ik", tied.astype(float), self.normals[c])
            side[lo:lo + chunk] = np.einsum("ij,ij->i", p - q[rows, j], nsum)
        return dict(points=Q, triangle=tri, bary=bary,
                    distance=np.linalg.norm(P - Q, axis=1), side=np.sign(side))


def copy_weights(body_verts, body_faces, body_W, garment_verts):
    """The garment's weights: those of the closest point on the body (barycentric mix of its
    triangle's corner weights). -> (W, distance to the body, side: +1 outside)."""
    surface = Surface(body_verts, body_faces)
    hit = surface.closest(garment_verts)
    corners = surface.tris[hit["triangle"]]
    W = np.einsum("ij,ijk->ik", hit["bary"], body_W[corners])
    W /= W.sum(axis=1, keepdims=True)
    return W, hit["distance"], hit["side"]
