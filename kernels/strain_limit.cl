// SPDX-License-Identifier: Apache-2.0
// One Jacobi iteration of the strain limit (contract: StrainLimitBackend and StrainLimitTables
// in src/devices/strain_limit.h; host reference: src/devices/host/host_strain_limit.cpp, the
// same arithmetic in double). The host launches it once per iteration, `in` and `out` swapped
// between launches.
//
// Vertex p takes, for each incident edge (entries start[v] .. start[v + 1] - 1, in a fixed order)
// whose length l to its other end q is outside [lower, upper] (and not 0), the correction
// share * (l - t) / l * (q - p), t the band's nearer end, times params.compression when the edge
// is too short; it moves by step[v] times their sum (relaxation / n, n its edges that can move
// it, fixed per vertex so that the result is continuous in the positions), and is copied
// unchanged when there are none: x^. Where params.omega is not 1 (Chebyshev acceleration), `out`
// holds the iteration before `in` and the vertex writes omega * (x^ - out) + out, except a vertex
// with step 0 (no edge can move it), which writes x^. A vertex reads `in` and its own three
// floats of `out`, writes only those: no atomics, no order between items. Where params.planes is
// 1, the vertex then keeps in front of its skin plane (m, c) = planes[f * V + v]
// (ClosestBackend::skinPlanes; none where m is 0): a result x with m . x < c moves to
// x + (c - m . x) m.
//
// Mapping: 2-D range, local size (DS_LOCAL_SIZE, 1); item (v, f) is vertex v of frame f.
//
//   in, out                  F x 3V floats, vertex v of frame f at [f * 3V + 3v]
//   start                    V + 1 ints
//   other, lower, upper, share   one per entry
//   step                     V floats
//   planes                   F x V float4 (any buffer when params.planes is 0)

#pragma OPENCL FP_CONTRACT OFF

// Moves (x, y, z) onto the plane (m, c) = plane when it lies behind it (m . x < c): to
// x + (c - m . x) m. No plane when m is 0.
inline void dsKeepInFront(float* x, float* y, float* z, const float4 plane) {
  const float below = plane.w - (plane.x * *x + plane.y * *y + plane.z * *z);
  if (below > 0.0f) {
    *x += below * plane.x;
    *y += below * plane.y;
    *z += below * plane.z;
  }
}

__kernel __attribute__((reqd_work_group_size(DS_LOCAL_SIZE, 1, 1))) void dsStrainLimit(
    __global const float* in, __global float* out, __global const int* start,
    __global const int* other, __global const float* lower, __global const float* upper,
    __global const float* share, __global const float* step, __global const float4* planes,
    const DsStrainLimitParams params) {
  const int v = (int)get_global_id(0);
  const int f = (int)get_global_id(1);
  if (v >= params.vertexCount || f >= params.frameCount) {
    return;
  }
  const size_t frame = (size_t)f * (size_t)(3 * params.vertexCount);
  const size_t at = frame + (size_t)(3 * v);
  const float px = in[at];
  const float py = in[at + 1];
  const float pz = in[at + 2];
  float sx = 0.0f;
  float sy = 0.0f;
  float sz = 0.0f;
  int moves = 0;
  const int end = start[v + 1];
  for (int k = start[v]; k < end; ++k) {
    const float w = share[k];
    if (w == 0.0f) {
      continue;
    }
    const size_t q = frame + (size_t)(3 * other[k]);
    const float dx = in[q] - px;
    const float dy = in[q + 1] - py;
    const float dz = in[q + 2] - pz;
    const float length = sqrt(dx * dx + dy * dy + dz * dz);
    float target;
    float gain = 1.0f;
    if (length > upper[k]) {
      target = upper[k];
    } else if (length < lower[k] && length > 0.0f) {
      target = lower[k];
      gain = params.compression;
    } else {
      continue;
    }
    const float scale = gain * w * (length - target) / length;
    sx += scale * dx;
    sy += scale * dy;
    sz += scale * dz;
    moves = 1;
  }
  const float h = step[v];
  const float jx = moves != 0 ? px + h * sx : px;
  const float jy = moves != 0 ? py + h * sy : py;
  const float jz = moves != 0 ? pz + h * sz : pz;
  const float omega = params.omega;
  float x = jx;
  float y = jy;
  float z = jz;
  // A vertex no edge can move (step 0) takes no momentum: only its plane moves it.
  if (omega != 1.0f && h != 0.0f) {
    const float ox = out[at];
    const float oy = out[at + 1];
    const float oz = out[at + 2];
    x = omega * (jx - ox) + ox;
    y = omega * (jy - oy) + oy;
    z = omega * (jz - oz) + oz;
  }
  if (params.planes != 0) {
    dsKeepInFront(&x, &y, &z, planes[(size_t)f * (size_t)params.vertexCount + (size_t)v]);
  }
  out[at] = x;
  out[at + 1] = y;
  out[at + 2] = z;
}

// Which vertices stayed within reach of where the limit started them (contract:
// StrainLimitBackend::limit's `stayed`; host reference: HostStrainLimit::limit): a vertex's mark
// becomes 0 unless it was non-zero and |end - start| < params.reach, in float (the host reference
// works in double; callers leave a margin for the rounding). Same mapping as dsStrainLimit.
//
//   start, end   F x 3V floats: the positions before the first iteration and after the last
//   stayed       F x V ints, updated in place
__kernel __attribute__((reqd_work_group_size(DS_LOCAL_SIZE, 1, 1))) void dsStrainStayed(
    __global const float* start, __global const float* end, __global int* stayed,
    const DsStrainLimitParams params) {
  const int v = (int)get_global_id(0);
  const int f = (int)get_global_id(1);
  if (v >= params.vertexCount || f >= params.frameCount) {
    return;
  }
  const size_t item = (size_t)f * (size_t)params.vertexCount + (size_t)v;
  if (stayed[item] == 0) {
    return;
  }
  const size_t at = 3 * item;
  const float dx = end[at] - start[at];
  const float dy = end[at + 1] - start[at + 1];
  const float dz = end[at + 2] - start[at + 2];
  stayed[item] = sqrt(dx * dx + dy * dy + dz * dz) < params.reach ? 1 : 0;
}

// The planes' step alone (contract: StrainLimitBackend::keepInFront; host reference:
// HostStrainLimit::keepInFront): each vertex in front of its plane, as after an iteration of
// dsStrainLimit. Same mapping as dsStrainLimit; `positions` updated in place.
//
//   positions   F x 3V floats
//   planes      F x V float4
__kernel __attribute__((reqd_work_group_size(DS_LOCAL_SIZE, 1, 1))) void dsStrainInFront(
    __global float* positions, __global const float4* planes, const DsStrainLimitParams params) {
  const int v = (int)get_global_id(0);
  const int f = (int)get_global_id(1);
  if (v >= params.vertexCount || f >= params.frameCount) {
    return;
  }
  const size_t at = (size_t)f * (size_t)(3 * params.vertexCount) + (size_t)(3 * v);
  float x = positions[at];
  float y = positions[at + 1];
  float z = positions[at + 2];
  dsKeepInFront(&x, &y, &z, planes[(size_t)f * (size_t)params.vertexCount + (size_t)v]);
  positions[at] = x;
  positions[at + 1] = y;
  positions[at + 2] = z;
}
