// SPDX-License-Identifier: Apache-2.0
#pragma once

// The host half of the closest-triangle stage shared by both backends: the driver topology and
// mask as flat tables, input checks, and the candidate search (FLANN) whose lists the exact
// step (kernels/closest.cl or src/devices/host/host_closest.cpp) reduces to one triangle per point.

#include <cstddef>
#include <cstdint>
#include <vector>

#include <drivenshape/binding.h>
#include <drivenshape/mesh.h>

namespace drivenshape::correction {

/// Candidate lists of a chunk, compressed rows. Item k = f * Vd + i (frame f, point i):
///
///   start       F*Vd + 1    item k's candidates are triangles[start[k] .. start[k+1]-1]
///   triangles   start[F*Vd] driver triangle ids, increasing within an item, never empty
///
///   start:     | 0 | 3 | 7 | 9 | ...
///   triangles: | t t t | t t t t | t t | ...
///                item 0  item 1    item 2
struct CandidateTable {
  std::vector<std::int32_t> start;
  std::vector<std::int32_t> triangles;
};

/// Throws Error(kNumerical) naming `stage`, the frame of the chunk and the vertex when one of
/// frameCount x count xyz triples is NaN or infinite; `what` names the vertex kind
/// ("driver vertex", "driven point"). Null data: nothing to check (a block that is only on the
/// device was made there by this library's kernels and checked where it came in).
void checkFinite(const char* stage, const char* what, int frameCount, int count, const float* data);

class CandidateSearch;

/// Checks a transfer call: surface set, buffers present, sizes, no NaN/infinite input
/// (Error(kNumerical)), hit triangles in range (Error(kInput)).
void checkTransfer(const CandidateSearch& search, int frameCount, const SurfaceHit* hits,
                   const float* fromPoses, const float* toPoses, const float* points,
                   const float* out);

/// Throws Error(kInput) naming `stage` when one of `count` hits has a triangle out of
/// [0, triangleCount) or a non-finite (u, v); `perFrame` (> 0) is the hit count of one frame,
/// for the frame number in the message. Null hits: nothing to check (as for checkFinite).
void checkHits(const char* stage, int triangleCount, std::size_t count, int perFrame,
               const SurfaceHit* hits);

/// Checks a rebuild call (see ClosestBackend::rebuild) the way checkTransfer does.
void checkRebuild(const CandidateSearch& search, int frameCount, const SurfaceHit* hits,
                  const float* toPoses, const float* local, const float* out);

/// Throws Error(kInput) unless the resolution's offset is finite and >= 0.
void checkOffset(float offset);

/// Throws Error(kInput) unless the resolution's exit fade is finite and >= 0.
void checkExitFade(float fade);

/// Checks a resolve call (see ClosestBackend::resolve): also the offset (checkOffset).
void checkResolve(const CandidateSearch& search, int frameCount, const float* poses,
                  const SurfaceHit* hits, float offset, const float* points);

/// Checks a side table (see ClosestBackend::setSides): empty, or `pointCount` values each
/// kSideOutside or kSideInside. Throws Error(kInput) naming the first bad entry.
void checkSides(const std::vector<std::int8_t>& sides, int pointCount);

/// Driver topology, mask and candidate search. setSurface() once, find() per chunk.
class CandidateSearch {
 public:
  explicit CandidateSearch(int threads) : mThreads(threads) {}

  /// Validates and keeps the topology and the mask (see ClosestBackend::setSurface).
  void setSurface(const Mesh& driver, const BindingMask& mask);

  bool ready() const { return mReady; }
  int vertexCount() const { return mVertexCount; }
  int pointCount() const { return mPointCount; }
  int triangleCount() const { return static_cast<int>(mTriangles.size() / 3); }
  int threads() const { return mThreads; }
  /// T x 3 vertex ids, interleaved.
  const std::vector<std::int32_t>& triangles() const { return mTriangles; }
  /// The length scale of the scene (rest driver: max of bounding-box diagonal and largest
  /// coordinate magnitude) that sets the absolute part of the tie band.
  double sceneScale() const { return mSceneScale; }

  /// Checks a chunk call of `stage` (surface set, sizes within int range, buffers present).
  void checkChunk(const char* stage, int frameCount, bool buffersPresent) const;

  /// Candidate lists for every point of every frame (see candidates.cpp for the bound that
  /// makes them contain the exact closest triangle). Checks the input for NaN first. With
  /// `active` (F x Vd flags), only the items flagged non-zero get candidates; the others get an
  /// empty list.
  ///   poses F x 3Vp, points F x 3Vd
  void find(int frameCount, const float* poses, const float* points, CandidateTable& table,
            const std::uint8_t* active = nullptr) const;

 private:
  struct SearchClass {
    std::vector<int> triangles;  ///< allowed triangles, increasing
    std::vector<int> points;     ///< driven points of the class, increasing
  };
  struct FrameCandidates {
    std::vector<std::int32_t> count;  ///< per point
    std::vector<std::int32_t> triangles;
    std::vector<std::int32_t> offset;  ///< per point, into triangles
  };
  void findFrame(const float* pose, const float* points, const std::uint8_t* active,
                 double frameScale, FrameCandidates& out) const;

  int mThreads = 0;
  bool mReady = false;
  int mVertexCount = 0;
  int mPointCount = 0;
  double mSceneScale = 1.0;
  std::vector<std::int32_t> mTriangles;
  std::vector<SearchClass> mClasses;
};

}  // namespace drivenshape::correction
