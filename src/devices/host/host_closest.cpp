// SPDX-License-Identifier: Apache-2.0
// The glue of the host correction backend (host_closest.h): setSurface and the settings, and
// the host reference of kernels/closest.cl: the same candidate lists as the OpenCL backend,
// then plain C++ in double for the exact choice, frames in parallel on host threads. (The host
// has no separate reference of kernels/bvh.cl: its walk of the refitted BVH finds the same
// closest triangle as this exact choice.)

#include "host_closest.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <vector>

#include "parallel.h"

#include "triangle_distance.h"

namespace drivenshape {

void HostClosest::setSurface(const Mesh& driver, const BindingMask& mask) {
  mSearch.setSurface(driver, mask);
  mCertificate.setSurface(driver, mask, mSearch.sceneScale());
  mFeatures = correction::buildFeatureTables(mSearch.triangles().data(), mSearch.triangleCount(),
                                             mSearch.vertexCount());
  mInside = std::make_unique<InsideAudit>(driver);
  mSides.clear();
}

void HostClosest::setExitFade(float fade) {
  correction::checkExitFade(fade);
  mFade = fade;
}

void HostClosest::setSides(const std::vector<std::int8_t>& sides) {
  correction::checkSides(sides, mSearch.pointCount());
  mSides = sides;
}

void HostClosest::closest(int frameCount, const float* poses, const float* points,
                          SurfaceHit* hits) {
  mSearch.checkChunk("closest triangle", frameCount, hits != nullptr);
  exact(frameCount, poses, points, hits, nullptr);
}

/// The exact closest triangle of every item (of those flagged in `active`, F x Vd, when
/// given; the others' hits stay as they are).
void HostClosest::exact(int frameCount, const float* poses, const float* points, SurfaceHit* hits,
                        const std::uint8_t* active) {
  if (active != nullptr &&
      std::none_of(active, active + static_cast<std::size_t>(frameCount) * mSearch.pointCount(),
                   [](std::uint8_t a) { return a != 0; })) {
    return;
  }
  mSearch.find(frameCount, poses, points, mCandidates, active);
  const int pointCount = mSearch.pointCount();
  const std::size_t poseStride = 3 * static_cast<std::size_t>(mSearch.vertexCount());
  const double tieRelative = DS_TIE_RELATIVE_DOUBLE;
  const double tieAbsolute = static_cast<double>(
      static_cast<float>(DS_TIE_SCALE2_DOUBLE * mSearch.sceneScale() * mSearch.sceneScale()));
  const std::int32_t* triangles = mSearch.triangles().data();
  parallelFor(frameCount, mSearch.threads(), [&](int f) {
    const float* pose = poses + static_cast<std::size_t>(f) * poseStride;
    for (int i = 0; i < pointCount; ++i) {
      const std::size_t item = static_cast<std::size_t>(f) * pointCount + i;
      if (active != nullptr && active[item] == 0) {
        continue;
      }
      const Eigen::Vector3d p = correction::loadPoint(points, static_cast<long>(item));
      const int first = mCandidates.start[item];
      const int last = mCandidates.start[item + 1];
      auto distance2 = [&](int t, double& u, double& v) {
        const std::int32_t* tri = triangles + 3 * static_cast<std::size_t>(t);
        return correction::triangleDistance2(p, correction::loadPoint(pose, tri[0]),
                                             correction::loadPoint(pose, tri[1]),
                                             correction::loadPoint(pose, tri[2]), u, v);
      };
      double u = 0.0;
      double v = 0.0;
      double best = std::numeric_limits<double>::infinity();
      for (int k = first; k < last; ++k) {
        best = std::fmin(best, distance2(mCandidates.triangles[static_cast<std::size_t>(k)], u, v));
      }
      // Same float-rounded tie parameters as the kernel's DsClosestParams.
      const double band =
          best + static_cast<double>(static_cast<float>(tieRelative)) * best + tieAbsolute;
      SurfaceHit hit;
      hit.distance2 = static_cast<float>(best);
      for (int k = first; k < last; ++k) {
        const int t = mCandidates.triangles[static_cast<std::size_t>(k)];
        const double d2 = distance2(t, u, v);
        if (d2 <= band) {
          hit.triangle = t;
          hit.u = static_cast<float>(u);
          hit.v = static_cast<float>(v);
          hit.distance2 = static_cast<float>(d2);
          break;
        }
      }
      hits[item] = hit;
    }
  });
}

std::unique_ptr<ClosestBackend> makeHostClosest(const ClosestOptions& options) {
  return std::make_unique<HostClosest>(options);
}

}  // namespace drivenshape
