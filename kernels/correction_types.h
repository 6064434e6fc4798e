// SPDX-License-Identifier: Apache-2.0
// Types and constants of the correction stage (closest triangle, local-frame transfer), shared
// by the host (C++, src/database, src/devices) and the device (kernels/closest.cl,
// kernels/transfer.cl, kernels/resolve.cl). The OpenCL programs get this text as their first
// source, so both sides see one layout; the host checks the sizes with static_assert.
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

// Scalars of one dsResolve or dsCountInside launch (passed by value).
typedef struct DsResolveParams {
  ds_int frameCount;     // F
  ds_int pointCount;     // Vd
  ds_int vertexCount;    // Vp
  ds_int triangleCount;  // T
  float offset;          // scene units, >= 0
  ds_int sided;          // 1: read each point's side from `sides`; 0: every point lives outside
  float fade;            // dsResolve's exit fade (ClosestBackend::setExitFade), 0 = off
  ds_int nodeCount;      // N, the BVH's nodes (read when fade > 0)
  ds_int alongNormal;    // dsResolve: 1 moves along the pseudo-normal, 0 the nearest way
  float depth;           // dsSkinPlanes: how deep on the wrong side a point still gets a plane
  ds_int answered;       // dsSkinPlanes: 1 reads `answered` (points not searched get no plane)
  float reach;           // dsSkinPlanes: points at this signed distance or more get no plane
} DsResolveParams;

// One node of a bounding-volume hierarchy over driver triangles (kernels/bvh.cl, built by
// src/database/bvh.cpp). A leaf (count > 0) holds leafTriangles[first .. first + count - 1];
// an inner node (count == 0) has two children, node ids `left` and `right`.
typedef struct DsBvhNode {
  ds_int left;
  ds_int right;
  ds_int first;
  ds_int count;
} DsBvhNode;

// Scalars of one dsBvhRefit launch: the nodes [levelFirst, levelFirst + levelCount) of every
// frame (one depth of the trees; deeper levels were refitted by earlier launches).
typedef struct DsBvhRefitParams {
  ds_int frameCount;   // F
  ds_int vertexCount;  // Vp
  ds_int nodeCount;    // N, nodes per frame
  ds_int levelFirst;
  ds_int levelCount;
  ds_int pad0;
  ds_int pad1;
  ds_int pad2;
} DsBvhRefitParams;

// Scalars of one dsBvhClosest launch. The tie band is that of DsClosestParams; a box is
// skipped when its squared distance exceeds band * (1 + pruneRelative) + pruneAbsolute, a
// margin far wider than the rounding of the distance arithmetic (see kernels/bvh.cl).
typedef struct DsBvhQueryParams {
  ds_int frameCount;   // F
  ds_int pointCount;   // Vd
  ds_int vertexCount;  // Vp
  ds_int nodeCount;    // N
  float tieRelative;
  float tieAbsolute;    // squared length
  float pruneRelative;  //
  float pruneAbsolute;  // squared length
} DsBvhQueryParams;

// The deepest BVH a query can walk (its stack size); the host builds balanced trees (median
// splits), so a tree of 2^40 leaves would still fit.
#define DS_BVH_MAX_DEPTH 48

// How many triangles within the tie band a BVH walk remembers (a point closest to a vertex
// ties with every triangle around it); beyond that a second walk breaks the tie.
#define DS_BVH_TIES 16

// Pruning margins of the BVH walk (DsBvhQueryParams), relative to the band and to the squared
// scale S^2 of the scene. The computed squared distances of a triangle and of a box are each
// within a few unit roundoffs u of (d^2 + S^2) of the truth (the coordinates are at most S, the
// differences are formed before squaring); the margins are about 1e4 u in double and 16 u in
// float (where a wider margin would open many more boxes), so a box is never skipped because
// of rounding.
#define DS_PRUNE_RELATIVE_DOUBLE 1e-12
#define DS_PRUNE_RELATIVE_SINGLE 1e-6

// A closest point (u, v) counts as on an edge when one of its barycentric weights
// (1 - u - v, u, v) is at most DS_FEATURE_TOL, on a vertex when two are (pseudo-normals of the
// inside audit and of the penetration resolution; see src/database/surface_features.h).
#define DS_FEATURE_TOL 1e-6

// The nearest-way resolution's steadying band (ClosestBackend::setAlongNormal): a point closer to
// the skin than DS_RESOLVE_STEADY x the offset has the pseudo-normal, weighted by what it lacks
// of that distance, added to p - q, so a point on the skin itself (p = q) still has a direction;
// farther points go exactly along p - q (continuity measured in tests/devices/test_resolve.cpp).
#define DS_RESOLVE_STEADY 1e-4

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

// The clearance certificate (kernels/certificate.cl, src/devices/certificate.cpp): per frame,
// every BVH node gets a cone of its triangles' unit normals (axis, and a bound on how far any of
// them lies from it); a walk of the tree proves a point clear where every triangle that could be
// nearest lies behind it by the clearance.

// The certificate's margin, relative to the scene scale S: every bound it compares is widened
// by DS_CERT_MARGIN_* x S, far more than the rounding of its own arithmetic (double: ~1e-15 S;
// float: ~1e-6 S), of the float (u, v) of hits (~1e-7 S), the reach of the feature tolerance
// (DS_FEATURE_TOL x an edge) and of the tie band (sqrt of DS_TIE_SCALE2_* x S^2: 1e-7 S in
// double, 3e-5 S in float).
#define DS_CERT_MARGIN_DOUBLE 1e-5
#define DS_CERT_MARGIN_SINGLE 2e-4

// A triangle proves the side of a point only when it is well shaped: |(b-a) x (c-a)|^2 >
// DS_CERT_SIN2_* |b-a|^2 |c-a|^2 (the sine of its angle at a above 1e-4 in double, 0.1 in
// float), so that the rounding of its normal's direction stays far below the margin.
#define DS_CERT_SIN2_DOUBLE 1e-8
#define DS_CERT_SIN2_SINGLE 1e-2

// Added to every leaf cone's spread (a length on the unit sphere): above the rounding of a
// well-shaped triangle's unit normal (double: ~1e-15 / sine; float: ~1e-6 S / (edge x sine)).
#define DS_CERT_CONE_SLACK_DOUBLE 1e-9
#define DS_CERT_CONE_SLACK_SINGLE 1e-3

// The (u, v) of a witness hit: 1/3 rounded to float, a face point of its triangle.
#define DS_CERT_THIRD 0.333333343f

// Tie band (see DsClosestParams), relative to best_d2 and to the squared scale of the scene.
#define DS_TIE_RELATIVE_DOUBLE 1e-12
#define DS_TIE_SCALE2_DOUBLE 1e-14
#define DS_TIE_RELATIVE_SINGLE 1e-5
#define DS_TIE_SCALE2_SINGLE 1e-9

// The cone of one BVH node's triangles on one frame: `axis` (unit, or zero), `spread`, a bound
// on |n_t - axis| over the unit normals n_t of its triangles (INFINITY when one of them is not
// well shaped, DS_CERT_SIN2_*, or the cone is useless), and `offset`, a bound on axis . x over
// the points x of its triangles.
typedef struct DsCertCone {
  float axis[3];
  float spread;
  float offset;
  float pad0;
  float pad1;
  float pad2;
} DsCertCone;

// Scalars of the certificate launches (passed by value).
typedef struct DsCertParams {
  ds_int frameCount;   // F
  ds_int pointCount;   // Vd
  ds_int vertexCount;  // Vp
  ds_int nodeCount;    // N, nodes per frame
  ds_int levelFirst;   // dsCertRefitCones: the nodes of one depth
  ds_int levelCount;
  ds_int keep;  // dsCertCheck: items marked in `answered` keep their hit
  ds_int pad0;
  float clearance;  // scene units, >= 0
  float margin;     // DS_CERT_MARGIN_* x S
  float reach;      // dsCertCheck: the answer must hold within this of the point (>= 0)
  float pad2;
} DsCertParams;

#ifndef __cplusplus
// Device arithmetic of the correction kernels: double where the host defined DS_USE_DOUBLE
// (the device has cl_khr_fp64), else float. Inputs and outputs are float either way.
#ifdef DS_USE_DOUBLE
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
typedef double ds_real;
typedef double3 ds_real3;
#define DS_FLAT_SIN2 DS_FLAT_SIN2_DOUBLE
#define DS_FRAME_SIN2 DS_FRAME_SIN2_DOUBLE
#define DS_CERT_SIN2 DS_CERT_SIN2_DOUBLE
#define DS_CERT_CONE_SLACK DS_CERT_CONE_SLACK_DOUBLE
#else
typedef float ds_real;
typedef float3 ds_real3;
#define DS_FLAT_SIN2 DS_FLAT_SIN2_SINGLE
#define DS_FRAME_SIN2 DS_FRAME_SIN2_SINGLE
#define DS_CERT_SIN2 DS_CERT_SIN2_SINGLE
#define DS_CERT_CONE_SLACK DS_CERT_CONE_SLACK_SINGLE
#endif
#endif

#ifdef __cplusplus
static_assert(sizeof(DsSurfaceHit) == 16, "DsSurfaceHit layout");
static_assert(sizeof(DsClosestParams) == 32, "DsClosestParams layout");
static_assert(sizeof(DsTransferParams) == 16, "DsTransferParams layout");
static_assert(sizeof(DsResolveParams) == 48, "DsResolveParams layout");
static_assert(sizeof(DsBvhNode) == 16, "DsBvhNode layout");
static_assert(sizeof(DsBvhRefitParams) == 32, "DsBvhRefitParams layout");
static_assert(sizeof(DsBvhQueryParams) == 32, "DsBvhQueryParams layout");
static_assert(sizeof(DsCertCone) == 32, "DsCertCone layout");
static_assert(sizeof(DsCertParams) == 48, "DsCertParams layout");
}  // namespace drivenshape
#endif

#endif
