// SPDX-License-Identifier: Apache-2.0
// Projection of driver frames onto the QP basis (contract: src/devices/stages.h):
//
//   out[f] = { M^T (b_f - m)  (rowCount values),  ||b_f - m||^2,  ||b_f||^2 }
//
// It is a GEMM (F x 3Vp) * (3Vp x rowCount) plus two norms per frame. The reduction runs over
// 3Vp ~ 15,000 products and the result feeds a QP whose positions must match the double host
// reference, so each work item keeps compensated (Kahan) sums, lane-wise in float4, and the 64
// partial sums of a work-group are added pairwise (a tree). The error stays within about ten
// float roundings of sum |terms| <= ||row|| ||b - m|| whatever the vertex count, without
// cl_khr_fp64.
//
// Mapping: one work-group of DS_LOCAL_SIZE items per (frame, tile of DS_PROJECT_ROWS rows).
//
//   group g = frame * tileCount + tile              global size = F * tileCount * 64
//
//   frame f (a padded row of quadCount float4s, the padding is zero):
//     | q0 q1 ... q63 | q64 ... q127 | q128 ...        item t takes quads t, t+64, t+128, ...
//       t0 t1 ... t63   t0  ... t63    t0 ...          (coalesced float4 loads)
//
//   rows (tileCount * R padded rows, zero rows past rowCount), R = DS_PROJECT_ROWS:
//     tile 0: rows 0 .. R-1 | tile 1: rows R .. 2R-1 | ...
//
//   Each item keeps R float4 Kahan sums (and, in tile 0 only, the two norms), folds its
//   lanes into the local table, and the group reduces each column by a tree:
//
//     partial[v * 64 + t]     v = 0 .. R-1: row tile*R + v
//                             v = R, R+1:   ||b - m||^2, ||b||^2 (zero outside tile 0)
//
// The frame (60 KB at W1 scale) stays in cache for the tileCount groups that read it, and the
// padded rows are shared by every frame.

// Adds `value` to the compensated sum (*sum, *comp), lane by lane; the total is *sum - *comp.
inline void dsKahanAdd4(float4* sum, float4* comp, float4 value) {
  const float4 y = value - *comp;
  const float4 t = *sum + y;
  *comp = (t - *sum) - y;
  *sum = t;
}

// The four lanes of a compensated float4 sum, added pairwise.
inline float dsLaneTotal(float4 sum, float4 comp) {
  const float4 v = sum - comp;
  return (v.x + v.y) + (v.z + v.w);
}

__kernel __attribute__((reqd_work_group_size(DS_LOCAL_SIZE, 1, 1))) void dsProject(
    __global const float4* frames, __global const float4* center, __global const float4* rows,
    __global float* out, const DsProjectParams params) {
  __local float partial[(DS_PROJECT_ROWS + 2) * DS_LOCAL_SIZE];

  const int lid = (int)get_local_id(0);
  const int group = (int)get_group_id(0);
  const int frame = group / params.tileCount;
  const int tile = group - frame * params.tileCount;
  if (frame >= params.frameCount) {
    return;  // whole groups only, so no barrier below is ever split
  }
  const int quads = params.quadCount;
  __global const float4* b = frames + (size_t)frame * (size_t)quads;
  __global const float4* tileRows = rows + (size_t)tile * DS_PROJECT_ROWS * (size_t)quads;

  float4 sum[DS_PROJECT_ROWS];
  float4 comp[DS_PROJECT_ROWS];
#pragma unroll
  for (int r = 0; r < DS_PROJECT_ROWS; ++r) {
    sum[r] = (float4)(0.0f);
    comp[r] = (float4)(0.0f);
  }
  float4 rrSum = (float4)(0.0f), rrComp = (float4)(0.0f);
  float4 bbSum = (float4)(0.0f), bbComp = (float4)(0.0f);

  // Two copies of the loop, so that outside tile 0 the hot loop carries no norm work and no
  // branch (`tile` is uniform over the group).
  if (tile == 0) {
    for (int q = lid; q < quads; q += DS_LOCAL_SIZE) {
      const float4 bq = b[q];
      const float4 d = bq - center[q];
#pragma unroll
      for (int r = 0; r < DS_PROJECT_ROWS; ++r) {
        dsKahanAdd4(&sum[r], &comp[r], tileRows[r * quads + q] * d);
      }
      dsKahanAdd4(&rrSum, &rrComp, d * d);
      dsKahanAdd4(&bbSum, &bbComp, bq * bq);
    }
  } else {
    for (int q = lid; q < quads; q += DS_LOCAL_SIZE) {
      const float4 d = b[q] - center[q];
#pragma unroll
      for (int r = 0; r < DS_PROJECT_ROWS; ++r) {
        dsKahanAdd4(&sum[r], &comp[r], tileRows[r * quads + q] * d);
      }
    }
  }

#pragma unroll
  for (int r = 0; r < DS_PROJECT_ROWS; ++r) {
    partial[r * DS_LOCAL_SIZE + lid] = dsLaneTotal(sum[r], comp[r]);
  }
  partial[DS_PROJECT_ROWS * DS_LOCAL_SIZE + lid] = dsLaneTotal(rrSum, rrComp);
  partial[(DS_PROJECT_ROWS + 1) * DS_LOCAL_SIZE + lid] = dsLaneTotal(bbSum, bbComp);

  // Pairwise tree over the 64 partials of every column: log2(64) = 6 additions deep. (One item
  // summing a column serially was 1.4x slower on PoCL at W1 sizes, 4x at 500 vertices.)
#pragma unroll
  for (int stride = DS_LOCAL_SIZE / 2; stride > 0; stride >>= 1) {
    barrier(CLK_LOCAL_MEM_FENCE);
    if (lid < stride) {
#pragma unroll
      for (int v = 0; v < DS_PROJECT_ROWS + 2; ++v) {
        partial[v * DS_LOCAL_SIZE + lid] += partial[v * DS_LOCAL_SIZE + lid + stride];
      }
    }
  }
  barrier(CLK_LOCAL_MEM_FENCE);

  __global float* frameOut = out + (size_t)frame * (size_t)params.outStride;
  if (lid < DS_PROJECT_ROWS) {
    const int row = tile * DS_PROJECT_ROWS + lid;
    if (row < params.rowCount) {
      frameOut[row] = partial[lid * DS_LOCAL_SIZE];
    }
  } else if (tile == 0 && lid < DS_PROJECT_ROWS + 2) {
    frameOut[params.rowCount + (lid - DS_PROJECT_ROWS)] = partial[lid * DS_LOCAL_SIZE];
  }
}
