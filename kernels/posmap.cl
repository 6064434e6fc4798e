// SPDX-License-Identifier: Apache-2.0
// Position maps (contract: PositionMapBackend in src/include/drivenshape/position_map.h; host
// reference: src/devices/host/host_posmap.cpp). Two kernels per chunk of F frames:
//
//   dsPosmapVertexNormals  area-weighted vertex normals of every frame (only with normals)
//   dsPosmapGather         one work item per active texel, looping over the chunk's frames
//
// Layouts (all interleaved xyz, frame-major; V vertices, E active texels, M = W * H texels):
//
//   frames          F x 3V    frame f, vertex v at [f * 3V + 3v]
//   vertexNormals   F x 3V    same layout
//   triangles       T x 3     vertex ids
//   triStart        V + 1     incident triangles of v: triIds[triStart[v] .. triStart[v+1]-1]
//   texels          E         texel index y * W + x (row 0 = top of the map)
//   texelTriangles  E         triangle whose barycentrics the texel uses
//   texelWeights    E x 2     (b1, b2); corner 0 weighs 1 - b1 - b2
//   positions       F x 3M    frame f, texel i at [f * 3M + 3i]
//   normals         F x 3M    same layout
//
//          frame 0                    frame 1
//   +----------------------------+----------------------------+--
//   | x y z | x y z | ... M texels| x y z | ...                |
//   +----------------------------+----------------------------+--
//
// Only active texels are stored; the host zero-fills the output buffers once when it
// allocates them, so the texels no kernel writes stay 0 in every frame.

// Area-weighted normal: the sum of incident cross products, each |cross| = 2 * area.
// Gathered per vertex (no atomics), normalised; 0 when the sum is 0.
__kernel __attribute__((reqd_work_group_size(DS_LOCAL_SIZE, 1, 1))) void dsPosmapVertexNormals(
    __global const float* frames, __global const int* triangles, __global const int* triStart,
    __global const int* triIds, __global float* vertexNormals, const int vertexCount,
    const int frameCount) {
  const int v = (int)get_global_id(0);
  const int f = (int)get_global_id(1);
  if (v >= vertexCount || f >= frameCount) {
    return;
  }
  __global const float* p = frames + (size_t)f * 3 * (size_t)vertexCount;
  float3 sum = (float3)(0.0f);
  for (int i = triStart[v]; i < triStart[v + 1]; ++i) {
    const int3 c = vload3(triIds[i], triangles);
    const float3 p0 = vload3(c.x, p);
    sum += cross(vload3(c.y, p) - p0, vload3(c.z, p) - p0);
  }
  const float len = sqrt(dot(sum, sum));
  const float3 n = len > 0.0f ? sum / len : (float3)(0.0f);
  vstore3(n, v, vertexNormals + (size_t)f * 3 * (size_t)vertexCount);
}

inline float3 dsInterpolate(__global const float* values, const int3 c, const float b1,
                            const float b2) {
  const float3 p0 = vload3(c.x, values);
  return (p0 + b1 * (vload3(c.y, values) - p0)) + b2 * (vload3(c.z, values) - p0);
}

// One work item per active texel: loads its triangle and weights once, then writes every
// frame of the chunk. withNormals = 0 leaves `vertexNormals` and `normals` untouched.
__kernel __attribute__((reqd_work_group_size(DS_LOCAL_SIZE, 1, 1))) void dsPosmapGather(
    __global const float* frames, __global const float* vertexNormals,
    __global const int* triangles, __global const int* texels, __global const int* texelTriangles,
    __global const float* texelWeights, __global float* positions, __global float* normals,
    const int activeCount, const int vertexCount, const int texelCount, const int frameCount,
    const int withNormals) {
  const int e = (int)get_global_id(0);
  if (e >= activeCount) {
    return;
  }
  const size_t texel = (size_t)texels[e];
  const int3 c = vload3(texelTriangles[e], triangles);
  const float2 b = vload2(e, texelWeights);
  const size_t vertexFloats = 3 * (size_t)vertexCount;
  const size_t mapFloats = 3 * (size_t)texelCount;
  for (int f = 0; f < frameCount; ++f) {
    const float3 p = dsInterpolate(frames + (size_t)f * vertexFloats, c, b.x, b.y);
    vstore3(p, texel, positions + (size_t)f * mapFloats);
    if (withNormals) {
      const float3 n = dsInterpolate(vertexNormals + (size_t)f * vertexFloats, c, b.x, b.y);
      const float len = sqrt(dot(n, n));
      vstore3(len > 0.0f ? n / len : (float3)(0.0f), texel, normals + (size_t)f * mapFloats);
    }
  }
}
