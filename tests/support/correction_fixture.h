// SPDX-License-Identifier: Apache-2.0
#pragma once
// The correction tests' fixture: one host and one OpenCL backend per test binary (the OpenCL
// program is built once), and the exactness check against the brute-force oracle.

#include <memory>
#include <vector>

#include "closest.h"

#include "correction_test_util.h"
#include "test_support.h"

namespace drivenshape::testing {

class CorrectionClTest : public OpenClTest {
 protected:
  /// Backends shared by the tests of this binary; tests call setSurface() before use.
  static ClosestBackend* hostBackend();
  static ClosestBackend* clBackend();

  /// The hits of every frame of `scene` with `mask` on the host backend, then on the OpenCL one,
  /// each checked with expectExact (kClosestDistanceTol) against the brute-force distances.
  static std::vector<std::vector<SurfaceHit>> expectExactOnBothBackends(const PosedScene& scene,
                                                                        const BindingMask& mask);
};

/// The same call's interleaved xyz results on the host and on OpenCL: the largest point
/// difference must be within kDeviceVsHostRelTol x `diagonal` (a bounding-box diagonal).
void expectDeviceMatchesHost(const std::vector<float>& host, const std::vector<float>& cl,
                             double diagonal);

/// Brute-force distances (the oracle) of frameCount x Vd points to the triangles each point's
/// mask class allows, frame f on pose f. Multi-threaded.
std::vector<double> bruteForceAll(const Mesh& mesh, int frameCount, const float* poses,
                                  const float* points, const BindingMask& mask);

/// Checks hits against the brute-force distances: the hit's distance2 within `tolerance`, the
/// distance to its (u, v) point within kHitPointRelTol (or the tolerance, if looser), the
/// triangle allowed by the mask, (u, v) inside the triangle. Reports the failures, the
/// tolerance and the worst error.
struct DistanceTolerance;
void expectExact(const Mesh& mesh, int frameCount, const float* poses, const float* points,
                 const BindingMask& mask, const std::vector<SurfaceHit>& hits,
                 const std::vector<double>& brute, const DistanceTolerance& tolerance);

}  // namespace drivenshape::testing
