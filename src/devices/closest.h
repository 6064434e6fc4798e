// SPDX-License-Identifier: Apache-2.0
#pragma once

// Collision correction (docs/method.md, "Exact closest triangle" and "Local frames"): for every
// point d of the blended cloth D~, the exact closest triangle of the blended driver P~, and the
// local-frame transfer of d from P~ to the shot's pose P_new (ClosestBackend, one per device:
// src/devices/host/host_closest.h, src/devices/cl/cl_closest.h, defined one file per kernel
// stem); InsideAudit tells which points lie inside the driver.

#include <algorithm>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <drivenshape/binding.h>
#include <drivenshape/mesh.h>

#include "device_array.h"

namespace drivenshape {

/// Settings shared by both backends.
struct ClosestOptions {
  /// Host threads for the candidate search (and the host backend's exact step); 0 = one per
  /// hardware thread.
  int threads = 0;
  /// OpenCL only: do the kernels' arithmetic in float even where the device has cl_khr_fp64
  /// (devices without it always use float). Float is exact to about 1e-5 of the scene scale
  /// on well-shaped triangles but loses digits on needle-like slivers.
  bool forceSinglePrecision = false;
  /// OpenCL only: how the device finds the exact closest triangle. kBvh (the default) refits a
  /// bounding-volume hierarchy per frame on the device and walks it from a FLANN warm start
  /// (src/database/bvh.cpp); kCandidates reduces the host FLANN candidate lists of the host
  /// backend (src/database/candidates.cpp) on the device. Both are exact; kBvh is faster.
  enum class DeviceSearch { kBvh, kCandidates };
  DeviceSearch deviceSearch = DeviceSearch::kBvh;
};

/// The correction stage for chunks of F frames. Two implementations share this contract:
/// OpenCL kernels (makeClClosest) and the plain C++ host reference (makeHostClosest). Both
/// get their candidates from FLANN: the host backend from KD-trees over triangle centroids with
/// a bound that provably keeps the closest triangle (src/database/candidates.cpp); the OpenCL
/// backend from a FLANN warm start refined by a walk of per-frame refitted bounding-volume
/// hierarchies (src/database/bvh.cpp). Frame blocks are frame-major, float32:
///
///   poses   F x 3Vp   driver vertex v of frame f, axis a at [f * 3Vp + 3v + a]
///   points  F x 3Vd   driven point i of frame f at [f * 3Vd + 3i]
///   hits    F x Vd    SurfaceHit of point i of frame f at [f * Vd + i]
///
/// Vp is the driver mesh's vertex count, Vd the mask's driven vertex count. setSurface() is
/// called once (again to change the surface), then closest()/transfer() many times. Not
/// thread-safe.
class ClosestBackend {
 public:
  virtual ~ClosestBackend() = default;
  /// "host" or the OpenCL device name.
  virtual std::string name() const = 0;

  /// Takes the driver topology (its triangles) and the binding mask; the driver's positions
  /// only set the length scale of the tie band (max of bounding-box diagonal and largest
  /// coordinate). Throws Error(kInput) when the driver has no triangles or the mask names a
  /// triangle the driver does not have. Every point lives outside until setSides().
  virtual void setSurface(const Mesh& driver, const BindingMask& mask) = 0;

  /// Which side of the driver each point lives on, for resolve() and countInside(): Vd values
  /// (the mask's driven vertex count), kSideOutside or kSideInside, shared by every frame and
  /// uploaded once; empty = every point outside (cloth, the default). Call after setSurface().
  /// Throws Error(kInput) on a wrong length or another value.
  virtual void setSides(const std::vector<std::int8_t>& sides) = 0;

  /// The exit fade of resolve() (>= 0; 0, the default after construction, turns it off): a
  /// point on the wrong side of the skin at depth d = |p - q| is moved only the fraction
  /// a = clamp((d2 - d) / (fade d), 0, 1) of the way to its target, where d2 is its distance to
  /// the nearest *other* exit: the least distance to a triangle whose own closest point lies
  /// farther than d from q (brute force on the host, a walk of the refitted BVH on OpenCL).
  /// Where two exits are about equally near (deep inside a limb, or where the driver passes
  /// through itself at a bent joint) the nearest one flips from frame to frame and a full move
  /// jumps across the limb; faded, the point stays put there and moves continuously as one exit
  /// wins. A point within the offset on its own side always moves all the way. Throws
  /// Error(kInput) on a negative or non-finite fade.
  virtual void setExitFade(float fade) = 0;

  /// Which way resolve() moves a point (EvaluatorSettings::resolveDirection). Along the normal
  /// (the default after construction, 0.1's resolution) the target is q +- offset N. Otherwise a
  /// point on its own side of the skin (within the offset of it) goes to q +- offset D, D the unit
  /// vector of sigma (p - q) + max(DS_RESOLVE_STEADY offset - |s|, 0) N with sigma the sign of s:
  /// the direction from q to p turned to the outside, the shortest way to the offset, continuous
  /// where q crosses from a face onto an edge or a vertex (N jumps there by up to half the angle
  /// between the faces; the N term only steadies points within 1e-4 of the offset from the
  /// skin); a point on the wrong side still moves along N, which leaves a crease of the body
  /// along its bisector (moved the nearest way, more cloth stayed inside on the validation
  /// table's trousers).
  virtual void setAlongNormal(bool alongNormal) = 0;

  /// For every point of every frame, the closest triangle of that frame's pose among the
  /// triangles its mask allows: the distance equals a brute-force search over those triangles
  /// (to rounding), distances within a tie band of about 1e-7 of the scene scale count as
  /// equal, and ties go to the smaller triangle index. Zero-area triangles are measured as
  /// their edges (or their point). Throws Error(kNumerical) naming the frame of the chunk and
  /// the vertex when a pose or point is NaN or infinite.
  virtual void closest(int frameCount, const float* poses, const float* points,
                       SurfaceHit* hits) = 0;

  /// Local-frame transfer: each point is expressed in the frame of its hit on `fromPoses`
  /// (origin q, axes: unit first edge e1 = (b - a)/|b - a|, unit normal n of (b - a) x (c - a),
  /// e2 = n x e1) and rebuilt at the same (u, v) of the same triangle of `toPoses` with that
  /// triangle's frame. Where either frame is degenerate (zero first edge, or the sine of the
  /// angle at a below 1e-10; 1e-5 in float arithmetic), the offset p - q is kept in world axes:
  /// deterministic, exact for translations, but not rotated with the triangle. fromPoses, toPoses F
  /// x 3Vp; points, out F x 3Vd
  /// (`out` may alias `points`). Throws Error(kNumerical) on NaN/infinite input and
  /// Error(kInput) on a hit whose triangle is out of range.
  virtual void transfer(int frameCount, const SurfaceHit* hits, const float* fromPoses,
                        const float* toPoses, const float* points, float* out) = 0;

  /// The second half of transfer, for bindings made once (local-frame blending): point i of
  /// frame f is rebuilt from its local coordinates local[f * 3Vd + 3i + (0, 1, 2)] = (along e1,
  /// along e2, along n) in the frame of hits[i] on toPoses[f] (same frame construction and the
  /// same degenerate-frame rule as transfer: where the frame is degenerate the local
  /// coordinates are a world-axes offset from q). `hits` is Vd long and shared by every frame.
  ///   hits  Vd;  toPoses  F x 3Vp;  local, out  F x 3Vd (`out` may alias `local`)
  /// Throws as transfer does.
  virtual void rebuild(int frameCount, const SurfaceHit* hits, const float* toPoses,
                       const float* local, float* out) = 0;

  /// Penetration resolution: every point stays on its side of the skin (setSides), at least
  /// `offset` from it. `hits` are the exact closest points of `points` on `poses` over every
  /// driver triangle (a search with BindingMask::all). With s the signed distance (InsideAudit's
  /// angle-weighted pseudo-normal sign), q the closest point and N the unit pseudo-normal at q
  /// (face normal, edge normal or angle-weighted vertex normal), an outside point with
  /// s < offset moves to q + offset * N, an inside point with s > -offset to q - offset * N
  /// (N replaced by D on the own side when setAlongNormal(false); on the wrong side, only part of
  /// the way when setExitFade() is on); other points (and points where N is zero, or whose fade is
  /// 0) are left untouched. Points are updated in place; moved[f] receives how many points of frame
  /// f moved (may be null).
  ///   poses  F x 3Vp;  hits  F x Vd;  points  F x 3Vd;  moved  F
  /// offset >= 0 in scene units. Throws Error(kNumerical) on NaN/infinite input.
  virtual void resolve(int frameCount, const float* poses, const SurfaceHit* hits, float offset,
                       float* points, int* moved) = 0;

  /// The strain limit's skin planes (StrainLimitBackend::limit): for each point, from its exact
  /// closest point q on `poses` (`hits`, as resolve() takes them) and with s, N as there, the
  /// plane (m, c), m a unit vector, that the strain limit keeps the point in front of
  /// (m . x >= c), so that the limit cannot pull cloth into the body. A point on its own side of
  /// the skin (s >= 0) gets the way resolve() would move it (N, or D when setAlongNormal(false))
  /// with c = m . q + offset; a point on the wrong side at depth d = -s gets m = N and the same c
  /// up to `depth` deep (resolve() would move it there in one step), then a plane that sinks
  /// away continuously, c = m . q + offset - depth (1 - w) / w with w = (1.5 depth - d) /
  /// (0.5 depth), until there is none at 1.5 `depth` (deeper ones are left to the limit, which
  /// often brings them back to their neighbours, and to the resolution after it; a plane that
  /// switched off at once would make such a vertex jump between frames). Every other point gets
  /// (0, 0, 0, 0), no plane: a point that lives inside (setSides), one whose N is zero, one at
  /// least 1.5 `depth` deep, one answered without a search (answered[f * Vd + i] != 0,
  /// closestOrClearBlock(); null = every point searched), and one at signed distance `reach` or
  /// more. Given the clearance of the closestOrClearBlock() call that made the hits as `reach`,
  /// the planes are those of the full search: a point it answered is at least that clearance
  /// away, so whether the certificate answered a point (which depends on its seeds, and so on
  /// the chunking) changes no plane.
  ///   poses  F x 3Vp;  hits  F x Vd;  answered  F x Vd or null;  points  F x 3Vd;
  ///   planes  F x Vd x 4 floats (m.x, m.y, m.z, c)
  /// offset, depth, reach >= 0 in scene units. Throws as resolve() does.
  virtual void skinPlanes(int frameCount, const float* poses, const SurfaceHit* hits,
                          const std::int32_t* answered, const float* points, float offset,
                          float depth, float reach, float* planes) = 0;

  /// How many points of each frame are on the wrong side of the skin: inside[f] counts the
  /// points of frame f whose signed distance is negative for an outside point (cloth inside
  /// the driver; every point without setSides) or positive for an inside point, by
  /// InsideAudit's rule (angle-weighted pseudo-normal at the closest point), from their exact
  /// closest points `hits` over every triangle.
  ///   poses  F x 3Vp;  hits  F x Vd;  points  F x 3Vd;  inside  F
  virtual void countInside(int frameCount, DeviceArray& poses, DeviceArray& hits,
                           DeviceArray& points, int* inside) = 0;

  // The steps above on DeviceArrays (drivenshape/device_array.h), for a block of frames that
  // stays on the device between stages: an OpenCL backend reads and writes the arrays' device
  // memory and copies nothing back; these defaults work on the host copies through the calls
  // above. Output arrays are sized by the caller. NaN and infinity are refused in the host
  // copies that are current when the call starts (a block made on the device was checked where
  // it came in).
  virtual void closestBlock(int frameCount, DeviceArray& poses, DeviceArray& points,
                            DeviceArray& hits) {
    closest(frameCount, poses.read<float>(), points.read<float>(), hits.write<SurfaceHit>());
  }
  /// closestBlock() searched only where it can matter: the penetration resolution and the
  /// inside count need of a point only whether its signed distance (InsideAudit's sign) is
  /// below the offset or below 0. A point proven at signed distance >= `clearance` on its
  /// frame (src/devices/certificate.cpp: normal cones on the BVH) is not searched: its hit
  /// is a witness, the centroid (t, 1/3, 1/3) of a triangle whose face it lies at least
  /// `clearance` in front of. Every other point gets its exact hit, as closestBlock() finds
  /// it. So resolveBlock() with an offset <= `clearance` and countInside() give bitwise the
  /// results they give with closestBlock()'s hits (and resolveBlock() leaves every cleared
  /// point where it is); nothing else may read the witnesses as closest points.
  ///
  /// `answered` (F x Vd ints, or null) marks on return the items answered without a search.
  /// With `keep`, it is read first: items marked non-zero keep their hit in `hits`, which the
  /// caller vouches came from an earlier call on the same poses that answered them: with a
  /// clearance >= this one, their points unchanged since (e.g. a recount after resolveBlock(),
  /// which does not move them), or with a `reach` and clearance - reach >= this one, their
  /// points moved less than that reach since. cleared[f] counts the items of frame f answered
  /// without a search, kept ones included. `clearance` >= 0 in scene units; cleared F (may be
  /// null).
  ///
  /// `reach` >= 0 (scene units): a point is answered only when its answer also holds for every
  /// point within `reach` of it: at signed distance >= clearance - reach, with the same verdicts
  /// from the same witness, for offsets <= clearance - reach (the walk checks every triangle
  /// within U + 2 reach of the point instead of U: those hold the closest triangle of any point
  /// within reach, and the features its pseudo-normal is made of). So a caller may keep the
  /// answer of a point that has since moved less than `reach` (StrainLimitBackend's `stayed`
  /// marks). A distance bound alone would not do: where the driver is open or limbs cross, a
  /// point can change sides without coming near the surface.
  /// This default searches every point.
  virtual void closestOrClearBlock(int frameCount, DeviceArray& poses, DeviceArray& points,
                                   float /*clearance*/, DeviceArray& hits, int* cleared,
                                   DeviceArray* answered = nullptr, bool /*keep*/ = false,
                                   float /*reach*/ = 0.0f) {
    closestBlock(frameCount, poses, points, hits);
    if (cleared != nullptr) {
      std::fill(cleared, cleared + frameCount, 0);
    }
    if (answered != nullptr) {
      std::fill_n(answered->write<std::int32_t>(), answered->size<std::int32_t>(), 0);
    }
  }
  virtual void transferBlock(int frameCount, DeviceArray& hits, DeviceArray& fromPoses,
                             DeviceArray& toPoses, DeviceArray& points, DeviceArray& out) {
    const float* in = points.read<float>();
    transfer(frameCount, hits.read<SurfaceHit>(), fromPoses.read<float>(), toPoses.read<float>(),
             in, out.write<float>());
  }
  /// rebuild() with the bindings `hits` (Vd, made once) in an array too.
  virtual void rebuildBlock(int frameCount, DeviceArray& hits, DeviceArray& toPoses,
                            DeviceArray& local, DeviceArray& out) {
    const float* in = local.read<float>();
    rebuild(frameCount, hits.read<SurfaceHit>(), toPoses.read<float>(), in, out.write<float>());
  }
  virtual void resolveBlock(int frameCount, DeviceArray& poses, DeviceArray& hits, float offset,
                            DeviceArray& points, int* moved) {
    resolve(frameCount, poses.read<float>(), hits.read<SurfaceHit>(), offset,
            points.modify<float>(), moved);
  }
  /// skinPlanes() on arrays; `planes` is sized by the caller (F x Vd x 4 floats).
  virtual void skinPlanesBlock(int frameCount, DeviceArray& poses, DeviceArray& hits,
                               DeviceArray* answered, DeviceArray& points, float offset,
                               float depth, float reach, DeviceArray& planes) {
    skinPlanes(frameCount, poses.read<float>(), hits.read<SurfaceHit>(),
               answered != nullptr ? answered->read<std::int32_t>() : nullptr, points.read<float>(),
               offset, depth, reach, planes.write<float>());
  }
};

/// The host reference implementation (plain C++, double arithmetic).
std::unique_ptr<ClosestBackend> makeHostClosest(const ClosestOptions& options = {});

/// The whole correction of a chunk: hits on the blended driver, then the transfer of the
/// blended cloth to the shot's driver.
///   blendedDriver, shotDriver  F x 3Vp;  blendedDriven, corrected  F x 3Vd;  hits  F x Vd
inline void correct(ClosestBackend& backend, int frameCount, const float* blendedDriver,
                    const float* blendedDriven, const float* shotDriver, float* corrected,
                    SurfaceHit* hits) {
  backend.closest(frameCount, blendedDriver, blendedDriven, hits);
  backend.transfer(frameCount, hits, blendedDriver, shotDriver, blendedDriven, corrected);
}

/// Inside/outside of points with respect to the driver, from their closest points (Baerentzen
/// & Aanaes, "Signed distance computation using the angle weighted pseudonormal", 2005): the
/// sign of (p - q) . N, where N is the face normal when q is inside a triangle, the sum of the
/// normals of the triangles sharing the edge when q is on an edge, and the angle-weighted
/// vertex normal when q is on a vertex. This is correct only for a closed, consistently
/// oriented (outward normals, counter-clockwise faces) driver; on an open driver such as a
/// sleeve's arm without caps, points beyond the border are classified by the border's
/// pseudo-normals, which is a guess.
class InsideAudit {
 public:
  /// Takes the driver topology (triangles and vertex count; positions are not used).
  explicit InsideAudit(const Mesh& driver);

  /// Signed distances (scene units, negative inside) of `pointCount` points with their hits on
  /// one pose: pose Vp x 3 (interleaved), points pointCount x 3, hits pointCount, out
  /// pointCount. A hit counts as on an edge or vertex when its barycentric coordinates are
  /// within 1e-6 of it. Points exactly on the surface get 0.
  void signedDistances(const float* pose, int pointCount, const float* points,
                       const SurfaceHit* hits, float* out) const;

  /// How many of the points are on the wrong side of the skin: inside (signed distance < 0)
  /// for a point that lives outside, outside (> 0) for one that lives inside. `sides`:
  /// pointCount values kSideOutside or kSideInside (ClosestBackend::setSides), or null when
  /// every point lives outside (then: how many are inside).
  int countInside(const float* pose, int pointCount, const float* points, const SurfaceHit* hits,
                  const std::int8_t* sides = nullptr) const;

  /// countInside of each of `frameCount` frames: poses F x 3Vp, points F x pointCount x 3,
  /// hits F x pointCount, sides pointCount (shared by every frame) or null, into inside[F];
  /// frames in parallel on `threads` host threads.
  void countInsideFrames(int frameCount, const float* poses, int pointCount, const float* points,
                         const SurfaceHit* hits, int* inside, int threads = 1,
                         const std::int8_t* sides = nullptr) const;

 private:
  int mVertexCount = 0;
  Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor> mTriangles;
  /// For triangle t and its edge e (0: ab, 1: bc, 2: ca), every triangle on that edge (t
  /// included): edgeTriangles[edgeStart[3t + e] .. edgeStart[3t + e + 1] - 1].
  std::vector<int> mEdgeStart;
  std::vector<int> mEdgeTriangles;
  /// Triangles around vertex v: vertexTriangles[vertexStart[v] .. vertexStart[v + 1] - 1].
  std::vector<int> mVertexStart;
  std::vector<int> mVertexTriangles;
};

}  // namespace drivenshape
