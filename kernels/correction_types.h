// Types and constants of the correction stage (closest triangle, local-frame transfer), shared
// by the host (C++, src/correction, src/host, src/cl) and the device (kernels/closest.cl,
// kernels/transfer.cl). The OpenCL programs get this text as their first source, so both sides
// see one layout; the host checks the sizes with static_assert.
#ifndef DRIVENSHAPE_CORRECTION_TYPES_H
#define DRIVENSHAPE_CORRECTION_TYPES_H

#ifdef __cplusplus
#include <cstdint>
namespace drivenshape {
typedef std::int32_t ds_int;
#else
typedef int ds_int;
#endif

// One closest-point answer, bit-compatible with drivenshape::SurfaceHit (correction.h):
// q = a + u (b - a) + v (c - a) on triangle (a, b, c), at squared distance distance2.
typedef struct DsSurfaceHit {
  ds_int triangle;
  float u;
  float v;
  float distance2;
} DsSurfaceHit;

// Scalars of one dsClosest launch (passed by value).
//
//   tieRelative, tieAbsolute: two candidates are tied when
//     d2 <= best_d2 + tieRelative * best_d2 + tieAbsolute
//   and the tie goes to the smaller triangle index. The band is far wider than the rounding of
//   the distance arithmetic, so the host reference and the kernel agree on ties, and far
//   narrower than any distance a user can see (see DS_TIE_RELATIVE_*).
typedef struct DsClosestParams {
  ds_int frameCount;     // F
  ds_int pointCount;     // Vd, points per frame
  ds_int vertexCount;    // Vp, driver vertices per frame
  ds_int triangleCount;  // T
  float tieRelative;
  float tieAbsolute;  // squared length
  ds_int pad0;
  ds_int pad1;
} DsClosestParams;

// Scalars of one dsTransfer launch (passed by value).
typedef struct DsTransferParams {
  ds_int frameCount;     // F
  ds_int pointCount;     // Vd
  ds_int vertexCount;    // Vp
  ds_int triangleCount;  // T
} DsTransferParams;

// A triangle is treated as a segment/point set (no face region) when
//   |(b-a) x (c-a)|^2 <= DS_FLAT_SIN2 * |b-a|^2 |c-a|^2,
// i.e. when the sine of its angle at a is below sqrt(DS_FLAT_SIN2). Such a triangle lies within
// sin * |b-a| of its edges, so dropping its face region changes its distance by less than the
// rounding of the face-region formulas would. _DOUBLE applies where the arithmetic is double
// (host, devices with cl_khr_fp64), _SINGLE where it is float.
#define DS_FLAT_SIN2_DOUBLE 1e-24
#define DS_FLAT_SIN2_SINGLE 1e-12

// A local frame (transfer) is degenerate when its first edge has zero length or
//   |(b-a) x (c-a)|^2 <= DS_FRAME_SIN2 * |b-a|^2 |c-a|^2;
// the transfer then keeps the offset in world axes (see transfer.cl).
#define DS_FRAME_SIN2_DOUBLE 1e-20
#define DS_FRAME_SIN2_SINGLE 1e-10

// Tie band (see DsClosestParams), relative to best_d2 and to the squared scale of the scene.
#define DS_TIE_RELATIVE_DOUBLE 1e-12
#define DS_TIE_SCALE2_DOUBLE 1e-14
#define DS_TIE_RELATIVE_SINGLE 1e-5
#define DS_TIE_SCALE2_SINGLE 1e-9

#ifndef __cplusplus
// Device arithmetic of the correction kernels: double where the host defined DS_USE_DOUBLE
// (the device has cl_khr_fp64), else float. Inputs and outputs are float either way.
#ifdef DS_USE_DOUBLE
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
typedef double ds_real;
typedef double3 ds_real3;
#define DS_FLAT_SIN2 DS_FLAT_SIN2_DOUBLE
#define DS_FRAME_SIN2 DS_FRAME_SIN2_DOUBLE
#else
typedef float ds_real;
typedef float3 ds_real3;
#define DS_FLAT_SIN2 DS_FLAT_SIN2_SINGLE
#define DS_FRAME_SIN2 DS_FRAME_SIN2_SINGLE
#endif
#endif

#ifdef __cplusplus
static_assert(sizeof(DsSurfaceHit) == 16, "DsSurfaceHit layout");
static_assert(sizeof(DsClosestParams) == 32, "DsClosestParams layout");
static_assert(sizeof(DsTransferParams) == 16, "DsTransferParams layout");
}  // namespace drivenshape
#endif

#endif
