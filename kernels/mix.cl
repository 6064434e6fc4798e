// SPDX-License-Identifier: Apache-2.0
// Per-vertex mix of the DrivenShape result with another cache (contract: LayerBackend::mix in
// src/include/drivenshape/layers.h; host reference: src/devices/host/host_mix.cpp):
//
//   out = w * drivenshape + (1 - w) * other,   out = drivenshape where w = 1, other where w = 0
//
// The two ends are copies, not arithmetic, so weight 1 and weight 0 are bitwise exact.
//
// Mapping: 2-D range, local size (DS_LOCAL_SIZE, 1); item (v, f) is vertex v of frame f.
//
//   positions, other  F x 3Vd floats   vertex v of frame f at [f * 3Vd + 3v]
//   weights           Vd floats in [0, 1]

#pragma OPENCL FP_CONTRACT OFF

__kernel __attribute__((reqd_work_group_size(DS_LOCAL_SIZE, 1, 1))) void dsMix(
    __global float* positions, __global const float* other, __global const float* weights,
    const DsMixParams params) {
  const int v = (int)get_global_id(0);
  const int f = (int)get_global_id(1);
  if (v >= params.vertexCount || f >= params.frameCount) {
    return;
  }
  const float w = weights[v];
  if (w == 1.0f) {
    return;
  }
  const size_t at = (size_t)f * (size_t)(3 * params.vertexCount) + (size_t)(3 * v);
  for (int a = 0; a < 3; ++a) {
    positions[at + a] =
        w == 0.0f ? other[at + a] : w * positions[at + a] + (1.0f - w) * other[at + a];
  }
}
