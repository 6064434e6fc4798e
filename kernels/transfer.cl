// SPDX-License-Identifier: Apache-2.0
// Local-frame transfer (contract: ClosestBackend::transfer in
// src/devices/closest.h; host reference: src/devices/host/host_transfer.cpp).
//
// Point p was found closest to triangle t of the `from` pose at q = a + u (b - a) + v (c - a).
// The frame at q is
//
//   e1 = unit(b - a)              (the first edge)
//   n  = unit((b - a) x (c - a))  (the face normal)
//   e2 = n x e1
//
// and p's local coordinates are l = ((p - q).e1, (p - q).e2, (p - q).n). The result is
// q' + l.x e1' + l.y e2' + l.z n', with q', e1', e2', n' the same construction on triangle t of
// the `to` pose at the same (u, v).
//
// Degenerate frames: when either triangle's frame is undefined (zero first edge, or flat in the
// sense of DS_FRAME_SIN2), the offset is kept in world axes: result = q' + (p - q). This is
// deterministic, continuous in p, and exact for translations.
//
// Mapping: 1-D, local size DS_LOCAL_SIZE, one item per (frame f, point i), item id f * Vd + i.
//
//   hits        F x Vd DsSurfaceHit   (triangle ids checked by the host)
//   fromPoses   F x 3Vp float
//   toPoses     F x 3Vp float
//   triangles   T x 3 int
//   points      F x 3Vd float
//   out         F x 3Vd float

inline ds_real3 dsLoadPoint(__global const float* xyz, int index) {
  return (ds_real3)((ds_real)xyz[3 * index], (ds_real)xyz[3 * index + 1],
                    (ds_real)xyz[3 * index + 2]);
}

// Point q at (u, v) of triangle (a, b, c) and its frame; returns 0 when the frame is degenerate
// (q is set either way).
inline int dsFrame(ds_real3 a, ds_real3 b, ds_real3 c, ds_real u, ds_real v, ds_real3* q,
                   ds_real3* e1, ds_real3* e2, ds_real3* n) {
  const ds_real3 ab = b - a;
  const ds_real3 ac = c - a;
  *q = a + u * ab + v * ac;
  const ds_real3 nv = cross(ab, ac);
  const ds_real abab = dot(ab, ab);
  const ds_real nn = dot(nv, nv);
  if (!(abab > 0) || !(nn > DS_FRAME_SIN2 * abab * dot(ac, ac))) {
    return 0;
  }
  *e1 = ab / sqrt(abab);
  *n = nv / sqrt(nn);
  *e2 = cross(*n, *e1);
  return 1;
}

__kernel __attribute__((reqd_work_group_size(DS_LOCAL_SIZE, 1, 1))) void dsTransfer(
    __global const DsSurfaceHit* hits, __global const float* fromPoses,
    __global const float* toPoses, __global const int* triangles, __global const float* points,
    __global float* out, const DsTransferParams params) {
  const int item = (int)get_global_id(0);
  if (item >= params.frameCount * params.pointCount) {
    return;
  }
  const int frame = item / params.pointCount;
  const size_t poseOffset = (size_t)frame * (size_t)(3 * params.vertexCount);
  __global const float* from = fromPoses + poseOffset;
  __global const float* to = toPoses + poseOffset;
  const DsSurfaceHit hit = hits[item];
  const int ia = triangles[3 * hit.triangle];
  const int ib = triangles[3 * hit.triangle + 1];
  const int ic = triangles[3 * hit.triangle + 2];
  const ds_real u = (ds_real)hit.u;
  const ds_real v = (ds_real)hit.v;

  ds_real3 q0, e10, e20, n0;
  ds_real3 q1, e11, e21, n1;
  const int ok0 = dsFrame(dsLoadPoint(from, ia), dsLoadPoint(from, ib), dsLoadPoint(from, ic), u, v,
                          &q0, &e10, &e20, &n0);
  const int ok1 = dsFrame(dsLoadPoint(to, ia), dsLoadPoint(to, ib), dsLoadPoint(to, ic), u, v, &q1,
                          &e11, &e21, &n1);
  const ds_real3 d = dsLoadPoint(points, item) - q0;
  ds_real3 result;
  if (ok0 && ok1) {
    result = q1 + dot(d, e10) * e11 + dot(d, e20) * e21 + dot(d, n0) * n1;
  } else {
    result = q1 + d;
  }
  out[3 * item] = (float)result.x;
  out[3 * item + 1] = (float)result.y;
  out[3 * item + 2] = (float)result.z;
}

// Rebuild from local coordinates (contract: ClosestBackend::rebuild): the second half of
// dsTransfer with the local coordinates given. hits[i] is shared by every frame; where the frame
// is degenerate, the coordinates are a world-axes offset from q (the same rule as dsTransfer).
//
// Mapping: 1-D, local size DS_LOCAL_SIZE, one item per (frame f, point i), item id f * Vd + i.
//
//   hits        Vd DsSurfaceHit   (triangle ids checked by the host)
//   toPoses     F x 3Vp float
//   triangles   T x 3 int
//   coordinates F x 3Vd float     local coordinates (along e1, along e2, along n)
//   out         F x 3Vd float
__kernel __attribute__((reqd_work_group_size(DS_LOCAL_SIZE, 1, 1))) void dsRebuild(
    __global const DsSurfaceHit* hits, __global const float* toPoses, __global const int* triangles,
    __global const float* coordinates, __global float* out, const DsTransferParams params) {
  const int item = (int)get_global_id(0);
  if (item >= params.frameCount * params.pointCount) {
    return;
  }
  const int frame = item / params.pointCount;
  __global const float* to = toPoses + (size_t)frame * (size_t)(3 * params.vertexCount);
  const DsSurfaceHit hit = hits[item - frame * params.pointCount];
  const int ia = triangles[3 * hit.triangle];
  const int ib = triangles[3 * hit.triangle + 1];
  const int ic = triangles[3 * hit.triangle + 2];
  ds_real3 q, e1, e2, n;
  const int ok = dsFrame(dsLoadPoint(to, ia), dsLoadPoint(to, ib), dsLoadPoint(to, ic),
                         (ds_real)hit.u, (ds_real)hit.v, &q, &e1, &e2, &n);
  const ds_real3 l = dsLoadPoint(coordinates, item);
  const ds_real3 result = ok ? q + l.x * e1 + l.y * e2 + l.z * n : q + l;
  out[3 * item] = (float)result.x;
  out[3 * item + 1] = (float)result.y;
  out[3 * item + 2] = (float)result.z;
}
