// SPDX-License-Identifier: Apache-2.0
// Blend of database shapes with per-frame weights (contract: src/devices/stages.h):
//
//   out[f] = sum_i w[f][i] S_i
//
// Positions far from the origin (100 units, say) would lose digits if summed directly in
// float, so the host uploads the shapes centred on a reference shape R (their mean, rounded
// to float): Delta_i = S_i - R, exact for nearby floats. Then, exactly in real arithmetic,
//
//   out[f] = R + ( (sum_i w[f][i] - 1) R + sum_i w[f][i] Delta_i )
//
// The bracket is small (the deltas are deformations, the weight-sum error is ~1e-7, computed
// in double on the host and passed as the extra weight w[f][k]), so its float rounding is
// negligible and the result is within about one ulp of the double reference.
//
// Mapping: 2-D range, local size (DS_LOCAL_SIZE, 1). Item (q, g) computes float4 q of the
// padded output rows for frames g*B .. g*B+B-1 (B = DS_BLEND_FRAMES), so every Delta_i float4
// it loads is used B times:
//
//                 dim 0: q = float4 index in a padded row (quadCount, rounded up to 64)
//                 q=0       q=1       q=2            q=63 | q=64 ...
//               +---------+---------+---------+-- ... ---+---------
//   dim 1:  g=0 | f 0..7  | f 0..7  | f 0..7  |          | f 0..7     B = 8 frames per item,
//           g=1 | f 8..15 | f 8..15 | f 8..15 |          | f 8..15    one float4 per frame
//           ... |         |         |         |          |
//               +---------+---------+---------+-- ... ---+---------
//                <- one work-group: 64 consecutive q, one frame block ->
//                   (coalesced float4 loads of Delta_i and stores of out)
//
//   deltas   k x quadCount float4      Delta_i at [i * quadCount + q]
//   weights  F x (k+1) float           w[f][i] at [f * (k+1) + i], w[f][k] = sum_i w[f][i] - 1
//   out      F x quadCount float4      frame f at [f * quadCount + q]
//
// Items past the last quad return at once; frames past the last one read the last frame's
// weights (a valid address) and store nothing. The frame loops are unrolled so the B
// accumulators live in registers (PoCL otherwise keeps them in memory: 7x slower).

__kernel __attribute__((reqd_work_group_size(DS_LOCAL_SIZE, 1, 1))) void dsBlend(
    __global const float4* deltas, __global const float4* reference, __global const float* weights,
    __global float4* out, const DsBlendParams params) {
  const int q = (int)get_global_id(0);
  const int firstFrame = (int)get_global_id(1) * DS_BLEND_FRAMES;
  if (q >= params.quadCount || firstFrame >= params.frameCount) {
    return;
  }

  __global const float* w[DS_BLEND_FRAMES];
  float4 acc[DS_BLEND_FRAMES];
#pragma unroll
  for (int j = 0; j < DS_BLEND_FRAMES; ++j) {
    const int frame = min(firstFrame + j, params.frameCount - 1);
    w[j] = weights + (size_t)frame * (size_t)params.weightStride;
    acc[j] = (float4)(0.0f);
  }

  const size_t quads = (size_t)params.quadCount;
  for (int i = 0; i < params.shapeCount; ++i) {
    const float4 delta = deltas[(size_t)i * quads + (size_t)q];
#pragma unroll
    for (int j = 0; j < DS_BLEND_FRAMES; ++j) {
      acc[j] += w[j][i] * delta;
    }
  }

  const float4 ref = reference[q];
#pragma unroll
  for (int j = 0; j < DS_BLEND_FRAMES; ++j) {
    const int frame = firstFrame + j;
    if (frame < params.frameCount) {
      out[(size_t)frame * quads + (size_t)q] = ref + (w[j][params.shapeCount] * ref + acc[j]);
    }
  }
}
