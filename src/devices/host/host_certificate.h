// SPDX-License-Identifier: Apache-2.0
#pragma once

// The host reference of kernels/certificate.cl (the clearance certificate of
// ClosestBackend::closestOrClearBlock; the scheme and its proof: src/devices/certificate.cpp):
// the same tree, cones, walk and comparisons, in double, frames in parallel on host threads.

#include <cstdint>
#include <vector>

#include <drivenshape/mesh.h>

#include "closest.h"

#include "bvh.h"

namespace drivenshape::correction {

class HostCertificate {
 public:
  /// The BVH of `driver` for `mask`, as the OpenCL backend builds it; `sceneScale` sets the
  /// margin. Forgets the seeds.
  void setSurface(const Mesh& driver, const BindingMask& mask, double sceneScale);

  /// Clears what it can of a chunk's items k = f * Vd + i with active[k] != 0: when point i
  /// of frame f is proven at signed distance >= clearance, and every point within `reach` of it
  /// at signed distance >= clearance - reach with the same witness
  /// (ClosestBackend::closestOrClearBlock), active[k] becomes 0, hits[k] a witness and cleared[f]
  /// grows by one; other items are left as they are. With `seedFromHits` (the hits hold each
  /// item's answer of the call before, as dsCertCheck's params.keep) an item's walk starts from
  /// its own hit's triangle; otherwise the first call takes its seeds from the first frame
  /// (seedTriangles), later ones from remember().
  ///   poses F x 3Vp;  points F x 3Vd;  hits, active F x Vd;  cleared F
  void clear(int frameCount, const float* poses, const float* points, float clearance, float reach,
             bool seedFromHits, SurfaceHit* hits, std::uint8_t* active, int* cleared, int threads);

  /// The seeds of the next call: the hits of a chunk's last frame (Vd).
  void remember(const SurfaceHit* lastFrame);

 private:
  int mVertexCount = 0;
  int mPointCount = 0;
  double mMargin = 0.0;
  bool mEnabled = false;
  std::vector<std::int32_t> mTriangles;  ///< T x 3
  BvhTables mBvh;
  std::vector<std::int32_t> mNodeTriangles;  ///< N, nodeTriangles()
  std::vector<std::int32_t> mSeeds;          ///< Vd, empty until the first call
};

}  // namespace drivenshape::correction
