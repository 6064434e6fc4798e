// SPDX-License-Identifier: Apache-2.0
#pragma once

// The host reference of the correction stage (private to the devices room): the class
// HostClosest, whose members are defined one file per kernel stem. The same candidate lists as
// the OpenCL backend, then plain C++ in double, frames in parallel on host threads: the glue and
// the exact choice (kernels/closest.cl; the host has no separate reference of kernels/bvh.cl,
// whose walk finds the same triangle) in host_closest.cpp; the local-frame transfer and rebuild
// (kernels/transfer.cl) in host_transfer.cpp; closestOrClearBlock with the clearance
// certificate (kernels/certificate.cl) in host_certificate.cpp; the penetration resolution and
// the inside count (kernels/resolve.cl) in host_resolve.cpp.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include <drivenshape/binding.h>
#include <drivenshape/mesh.h>

#include "closest.h"

#include "candidates.h"
#include "host_certificate.h"
#include "surface_features.h"

namespace drivenshape {

class HostClosest final : public ClosestBackend {
 public:
  explicit HostClosest(const ClosestOptions& options) : mSearch(options.threads) {}

  std::string name() const override { return "host"; }

  void setSurface(const Mesh& driver, const BindingMask& mask) override;

  void setExitFade(float fade) override;
  void setAlongNormal(bool alongNormal) override { mAlongNormal = alongNormal; }

  void setSides(const std::vector<std::int8_t>& sides) override;

  void closest(int frameCount, const float* poses, const float* points, SurfaceHit* hits) override;

  void closestOrClearBlock(int frameCount, DeviceArray& poses, DeviceArray& points, float clearance,
                           DeviceArray& hits, int* cleared, DeviceArray* answered, bool keep,
                           float reach) override;

  void transfer(int frameCount, const SurfaceHit* hits, const float* fromPoses,
                const float* toPoses, const float* points, float* out) override;

  void rebuild(int frameCount, const SurfaceHit* hits, const float* toPoses, const float* local,
               float* out) override;

  void resolve(int frameCount, const float* poses, const SurfaceHit* hits, float offset,
               float* points, int* moved) override;

  void skinPlanes(int frameCount, const float* poses, const SurfaceHit* hits,
                  const std::int32_t* answered, const float* points, float offset, float depth,
                  float reach, float* planes) override;

  void countInside(int frameCount, DeviceArray& poses, DeviceArray& hits, DeviceArray& points,
                   int* inside) override;

 private:
  // host_closest.cpp.
  /// The exact closest triangle of every item (of those flagged in `active`, F x Vd, when
  /// given; the others' hits stay as they are).
  void exact(int frameCount, const float* poses, const float* points, SurfaceHit* hits,
             const std::uint8_t* active);

  // host_resolve.cpp.
  /// setExitFade()'s fraction of the move for a point p at depth `depth` from its closest point
  /// q on `pose`: the nearest other exit by brute force over every triangle. Only exits nearer
  /// than (1 + fade) depth change the fraction, so triangles whose box (`boxes`: min xyz, max
  /// xyz per triangle of this pose, filled on the first call) is farther are skipped.
  double exitFraction(const float* pose, const Eigen::Vector3d& p, const Eigen::Vector3d& q,
                      double depth, std::vector<float>& boxes) const;

  correction::CandidateSearch mSearch;
  correction::FeatureTables mFeatures;
  correction::CandidateTable mCandidates;
  correction::HostCertificate mCertificate;
  std::vector<std::uint8_t> mActive;
  std::vector<int> mCleared;
  std::unique_ptr<InsideAudit> mInside;
  std::vector<std::int8_t> mSides;  ///< Vd, or empty: every point outside
  float mFade = 0.0f;               ///< setExitFade()
  bool mAlongNormal = true;         ///< setAlongNormal()
};

}  // namespace drivenshape
