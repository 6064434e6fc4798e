// SPDX-License-Identifier: Apache-2.0
// The host reference of kernels/transfer.cl: HostClosest::transfer and rebuild (host_closest.h),
// in double, frames in parallel on host threads.

#include "host_closest.h"

#include <cstddef>
#include <cstdint>

#include "parallel.h"

#include "triangle_distance.h"

namespace drivenshape {

void HostClosest::transfer(int frameCount, const SurfaceHit* hits, const float* fromPoses,
                           const float* toPoses, const float* points, float* out) {
  correction::checkTransfer(mSearch, frameCount, hits, fromPoses, toPoses, points, out);
  const int pointCount = mSearch.pointCount();
  const std::size_t poseStride = 3 * static_cast<std::size_t>(mSearch.vertexCount());
  const std::int32_t* triangles = mSearch.triangles().data();
  parallelFor(frameCount, mSearch.threads(), [&](int f) {
    const float* from = fromPoses + static_cast<std::size_t>(f) * poseStride;
    const float* to = toPoses + static_cast<std::size_t>(f) * poseStride;
    for (int i = 0; i < pointCount; ++i) {
      const std::size_t item = static_cast<std::size_t>(f) * pointCount + i;
      const SurfaceHit& hit = hits[item];
      const std::int32_t* tri = triangles + 3 * static_cast<std::size_t>(hit.triangle);
      const double u = hit.u;
      const double v = hit.v;
      correction::LocalFrame f0;
      correction::LocalFrame f1;
      const bool ok0 = correction::localFrame(correction::loadPoint(from, tri[0]),
                                              correction::loadPoint(from, tri[1]),
                                              correction::loadPoint(from, tri[2]), u, v, f0);
      const bool ok1 = correction::localFrame(correction::loadPoint(to, tri[0]),
                                              correction::loadPoint(to, tri[1]),
                                              correction::loadPoint(to, tri[2]), u, v, f1);
      const Eigen::Vector3d d = correction::loadPoint(points, static_cast<long>(item)) - f0.q;
      const Eigen::Vector3d result =
          ok0 && ok1 ? Eigen::Vector3d(f1.q + d.dot(f0.e1) * f1.e1 + d.dot(f0.e2) * f1.e2 +
                                       d.dot(f0.n) * f1.n)
                     : Eigen::Vector3d(f1.q + d);
      for (int a = 0; a < 3; ++a) {
        out[3 * item + static_cast<std::size_t>(a)] = static_cast<float>(result[a]);
      }
    }
  });
}

void HostClosest::rebuild(int frameCount, const SurfaceHit* hits, const float* toPoses,
                          const float* local, float* out) {
  correction::checkRebuild(mSearch, frameCount, hits, toPoses, local, out);
  const int pointCount = mSearch.pointCount();
  const std::size_t poseStride = 3 * static_cast<std::size_t>(mSearch.vertexCount());
  const std::int32_t* triangles = mSearch.triangles().data();
  parallelFor(frameCount, mSearch.threads(), [&](int f) {
    const float* to = toPoses + static_cast<std::size_t>(f) * poseStride;
    for (int i = 0; i < pointCount; ++i) {
      const std::size_t item = static_cast<std::size_t>(f) * pointCount + i;
      const SurfaceHit& hit = hits[i];
      const std::int32_t* tri = triangles + 3 * static_cast<std::size_t>(hit.triangle);
      correction::LocalFrame frame;
      const bool ok = correction::localFrame(
          correction::loadPoint(to, tri[0]), correction::loadPoint(to, tri[1]),
          correction::loadPoint(to, tri[2]), hit.u, hit.v, frame);
      const Eigen::Vector3d l = correction::loadPoint(local, static_cast<long>(item));
      const Eigen::Vector3d result =
          ok ? Eigen::Vector3d(frame.q + l.x() * frame.e1 + l.y() * frame.e2 + l.z() * frame.n)
             : Eigen::Vector3d(frame.q + l);
      for (int a = 0; a < 3; ++a) {
        out[3 * item + static_cast<std::size_t>(a)] = static_cast<float>(result[a]);
      }
    }
  });
}

}  // namespace drivenshape
