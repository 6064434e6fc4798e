// SPDX-License-Identifier: Apache-2.0
// Types and constants shared by the host (C++) and the device (OpenCL C). This header is
// prepended to every program and included by the host code, so both sides see one layout.
// Keep it valid in both languages: plain `int` fields only (32 bits on every host we build
// for, checked below), no host-only headers outside the __cplusplus block.
#ifndef DRIVENSHAPE_SHARED_TYPES_H
#define DRIVENSHAPE_SHARED_TYPES_H

// Work-group size used for every launch (PoCL wants an explicit local size >= 64).
#define DS_LOCAL_SIZE 64

// ---- project.cl ----

// Projection rows one work-group dots its frame with. Rows are padded with zero rows to a
// multiple of this on upload, so the kernel's row loop has a fixed trip count.
#define DS_PROJECT_ROWS 8

// Arguments of dsProject, passed by value. Device rows (frames, center, projection rows) are
// padded from 3V floats to a multiple of 4 so every row starts on a float4.
typedef struct {
  int quadCount;   // padded row length / 4
  int rowCount;    // k-1, projection rows actually present
  int tileCount;   // ceil(rowCount / DS_PROJECT_ROWS), at least 1 (the norms need a tile)
  int frameCount;  // F in this chunk
  int outStride;   // floats per frame in the output: rowCount + 2 (rr, bb)
} DsProjectParams;

// ---- blend.cl ----

// Frames one blend work item computes, reusing each loaded shape float4 across them.
#define DS_BLEND_FRAMES 8

// Arguments of dsBlend, passed by value.
typedef struct {
  int quadCount;     // padded row length / 4
  int shapeCount;    // k
  int frameCount;    // F in this chunk
  int weightStride;  // floats per frame in the weights block: k + 1 (the last is sum(w) - 1)
} DsBlendParams;

// ---- strain_limit.cl ----

// Arguments of dsStrainLimit, passed by value.
typedef struct {
  int vertexCount;    // V
  int frameCount;     // F in this chunk
  float omega;        // this iteration's Chebyshev weight (1: the plain Jacobi step)
  int planes;         // 1: keep each vertex in front of its skin plane (dsStrainLimit's `planes`)
  float reach;        // dsStrainStayed: a vertex that moved this far or farther loses its mark
  float compression;  // dsStrainLimit: the gain of a correction that lengthens an edge
} DsStrainLimitParams;

#ifdef __cplusplus
static_assert(sizeof(int) == 4, "OpenCL int is 32 bits; the shared structs assume the same");
static_assert(sizeof(DsProjectParams) == 20, "DsProjectParams layout differs from the device");
static_assert(sizeof(DsBlendParams) == 16, "DsBlendParams layout differs from the device");
static_assert(sizeof(DsStrainLimitParams) == 24,
              "DsStrainLimitParams layout differs from the device");
#endif

#endif
