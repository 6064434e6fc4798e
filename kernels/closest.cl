// SPDX-License-Identifier: Apache-2.0
// Exact closest triangle among candidates (contract: ClosestBackend::closest in
// src/devices/closest.h; host reference: src/devices/host/host_closest.cpp).
//
// The host (src/database/candidates.cpp) lists, for every point of every frame, the triangles
// that can be closest (a superset of the true answer, with a proof there). This kernel computes
// the exact point-triangle distance to each candidate and keeps the smallest; distances within
// the tie band of the smallest go to the smaller triangle index.
//
// Arithmetic: `ds_real` is double where the host defined DS_USE_DOUBLE (the device has
// cl_khr_fp64), else float. Inputs and outputs are float either way.
//
// Mapping: 1-D, local size DS_LOCAL_SIZE, one item per (frame f, point i), item id f * Vd + i.
//
//   poses       F x 3Vp float   vertex v of frame f at [f * 3Vp + 3v]
//   triangles   T x 3 int       vertex ids (a, b, c)
//   points      F x 3Vd float   point i of frame f at [f * 3Vd + 3i]
//   start       F*Vd + 1 int    candidates of item k: candidates[start[k] .. start[k+1]-1],
//   candidates  start[F*Vd] int   triangle ids in increasing order, never empty
//   hits        F x Vd DsSurfaceHit

inline ds_real3 dsLoad3(__global const float* xyz, int index) {
  return (ds_real3)((ds_real)xyz[3 * index], (ds_real)xyz[3 * index + 1],
                    (ds_real)xyz[3 * index + 2]);
}

// Closest point of segment a + t e, t in [0, 1], to p: returns the squared distance, sets t.
// A zero-length segment is the point a.
inline ds_real dsSegmentDistance2(ds_real3 p, ds_real3 a, ds_real3 e, ds_real* t) {
  const ds_real ee = dot(e, e);
  ds_real s = 0;
  if (ee > 0) {
    s = clamp(dot(p - a, e) / ee, (ds_real)0, (ds_real)1);
  }
  *t = s;
  const ds_real3 d = p - (a + s * e);
  return dot(d, d);
}

// Closest point of triangle (a, b, c) to p: returns the squared distance and sets (u, v) with
// q = a + u (b - a) + v (c - a). If p projects into the triangle, the answer is the projection
// (face region); otherwise it lies on the boundary, the closest of the three edges. Flat
// triangles (see DS_FLAT_SIN2) have no face region, so a zero-area triangle is handled as its
// edges (or as a point) and never divides by zero.
inline ds_real dsTriangleDistance2(ds_real3 p, ds_real3 a, ds_real3 b, ds_real3 c, ds_real* u,
                                   ds_real* v) {
  const ds_real3 ab = b - a;
  const ds_real3 ac = c - a;
  const ds_real3 ap = p - a;
  const ds_real3 n = cross(ab, ac);
  const ds_real nn = dot(n, n);
  if (nn > DS_FLAT_SIN2 * dot(ab, ab) * dot(ac, ac)) {
    const ds_real su = dot(cross(ap, ac), n) / nn;
    const ds_real sv = dot(cross(ab, ap), n) / nn;
    if (su >= 0 && sv >= 0 && su + sv <= 1) {
      *u = su;
      *v = sv;
      const ds_real h = dot(ap, n);
      return h * h / nn;
    }
  }
  ds_real t;
  ds_real best = dsSegmentDistance2(p, a, ab, &t);
  *u = t;
  *v = 0;
  ds_real d2 = dsSegmentDistance2(p, a, ac, &t);
  if (d2 < best) {
    best = d2;
    *u = 0;
    *v = t;
  }
  d2 = dsSegmentDistance2(p, b, c - b, &t);
  if (d2 < best) {
    best = d2;
    *u = 1 - t;
    *v = t;
  }
  return best;
}

inline ds_real dsCandidateDistance2(ds_real3 p, __global const float* pose,
                                    __global const int* triangles, int t, ds_real* u, ds_real* v) {
  const ds_real3 a = dsLoad3(pose, triangles[3 * t]);
  const ds_real3 b = dsLoad3(pose, triangles[3 * t + 1]);
  const ds_real3 c = dsLoad3(pose, triangles[3 * t + 2]);
  return dsTriangleDistance2(p, a, b, c, u, v);
}

__kernel __attribute__((reqd_work_group_size(DS_LOCAL_SIZE, 1, 1))) void dsClosest(
    __global const float* poses, __global const int* triangles, __global const float* points,
    __global const int* start, __global const int* candidates, __global DsSurfaceHit* hits,
    const DsClosestParams params) {
  const int item = (int)get_global_id(0);
  if (item >= params.frameCount * params.pointCount) {
    return;
  }
  const int frame = item / params.pointCount;
  __global const float* pose = poses + (size_t)frame * (size_t)(3 * params.vertexCount);
  const ds_real3 p = dsLoad3(points, item);
  const int first = start[item];
  const int last = start[item + 1];

  // Pass 1: the smallest distance.
  ds_real best = INFINITY;
  ds_real u;
  ds_real v;
  for (int k = first; k < last; ++k) {
    best = fmin(best, dsCandidateDistance2(p, pose, triangles, candidates[k], &u, &v));
  }
  // Pass 2: the first (smallest index) candidate within the tie band of the smallest.
  const ds_real band = best + (ds_real)params.tieRelative * best + (ds_real)params.tieAbsolute;
  DsSurfaceHit hit;
  hit.triangle = -1;
  hit.u = 0.0f;
  hit.v = 0.0f;
  hit.distance2 = (float)best;
  for (int k = first; k < last; ++k) {
    const int t = candidates[k];
    const ds_real d2 = dsCandidateDistance2(p, pose, triangles, t, &u, &v);
    if (d2 <= band) {
      hit.triangle = t;
      hit.u = (float)u;
      hit.v = (float)v;
      hit.distance2 = (float)d2;
      break;
    }
  }
  hits[item] = hit;
}
