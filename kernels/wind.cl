// SPDX-License-Identifier: Apache-2.0
// Procedural wind (contract: LayerBackend::wind in src/include/drivenshape/layers.h; host
// reference: src/devices/host/host_wind.cpp). The noise and the clearance limit are the shared
// functions of kernels/layer_types.h, so the arithmetic is the host's, operation for operation.
//
// Mapping: 2-D range, local size (DS_LOCAL_SIZE, 1); item (v, f) is vertex v of frame f.
//
//   positions  F x 3Vd floats   vertex v of frame f at [f * 3Vd + 3v]      (in/out)
//   rest       3Vd floats       centred rest positions (the noise domain)
//   weights    Vd floats        the wind weight map, in [0, 1]
//   clearance  F x Vd floats    distance of vertex v to the driver surface in frame f
//                               (read only when params.hasClearance)
//   offsets    F x DS_WIND_MAX_OCTAVES x 4 floats (see DsWindParams)

#pragma OPENCL FP_CONTRACT OFF

__kernel __attribute__((reqd_work_group_size(DS_LOCAL_SIZE, 1, 1))) void dsWind(
    __global float* positions, __global const float* rest, __global const float* weights,
    __global const float* clearance, __global const float* offsets, const DsWindParams params) {
  const int v = (int)get_global_id(0);
  const int f = (int)get_global_id(1);
  if (v >= params.vertexCount || f >= params.frameCount) {
    return;
  }
  const float weight = weights[v];
  if (weight == 0.0f) {
    return;
  }
  const float p[3] = {rest[3 * v], rest[3 * v + 1], rest[3 * v + 2]};
  float displacement[3];
  dsWindDisplacement(p, offsets + (size_t)f * (DS_WIND_MAX_OCTAVES * 4), params, displacement);

  const size_t at = (size_t)f * (size_t)(3 * params.vertexCount) + (size_t)(3 * v);
  float position[3] = {positions[at], positions[at + 1], positions[at + 2]};
  const float c =
      params.hasClearance ? clearance[(size_t)f * (size_t)params.vertexCount + (size_t)v] : 0.0f;
  dsWindApply(position, displacement, weight, c, params.hasClearance);
  positions[at] = position[0];
  positions[at + 1] = position[1];
  positions[at + 2] = position[2];
}
