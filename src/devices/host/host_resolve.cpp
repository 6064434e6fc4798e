// SPDX-License-Identifier: Apache-2.0
// The host reference of kernels/resolve.cl: HostClosest::resolve with its exit fade, and
// countInside (host_closest.h), in double, frames in parallel on host threads.

#include "host_closest.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "parallel.h"

#include "triangle_distance.h"

namespace drivenshape {
namespace {

/// A point seen from its exact closest point q on one pose: the unnormalised pseudo-normal N at
/// q, its length, and the point's signed distance (InsideAudit's sign).
struct SkinPoint {
  Eigen::Vector3d p;
  Eigen::Vector3d q;
  Eigen::Vector3d normal;
  double length = 0.0;
  double signedDistance = 0.0;
};

SkinPoint skinPoint(const float* pose, const std::int32_t* triangles,
                    const correction::FeatureView& features, const SurfaceHit& hit,
                    const float* points, std::size_t item) {
  SkinPoint at;
  const std::int32_t* tri = triangles + 3 * static_cast<std::size_t>(hit.triangle);
  const Eigen::Vector3d a = correction::loadPoint(pose, tri[0]);
  const double u = hit.u;
  const double v = hit.v;
  at.q = a + u * (correction::loadPoint(pose, tri[1]) - a) +
         v * (correction::loadPoint(pose, tri[2]) - a);
  at.p = correction::loadPoint(points, static_cast<long>(item));
  at.normal = correction::pseudoNormal(pose, triangles, features, hit.triangle, u, v);
  at.length = at.normal.norm();
  const double distance = (at.p - at.q).norm();
  at.signedDistance = (at.p - at.q).dot(at.normal) < 0.0 ? -distance : distance;
  return at;
}

}  // namespace

void HostClosest::resolve(int frameCount, const float* poses, const SurfaceHit* hits, float offset,
                          float* points, int* moved) {
  correction::checkResolve(mSearch, frameCount, poses, hits, offset, points);
  const int pointCount = mSearch.pointCount();
  const std::size_t poseStride = 3 * static_cast<std::size_t>(mSearch.vertexCount());
  const std::int32_t* triangles = mSearch.triangles().data();
  const correction::FeatureView features = correction::viewOf(mFeatures);
  parallelFor(frameCount, mSearch.threads(), [&](int f) {
    const float* pose = poses + static_cast<std::size_t>(f) * poseStride;
    std::vector<float> boxes;  // exitFraction()'s, of this frame
    int count = 0;
    for (int i = 0; i < pointCount; ++i) {
      const std::size_t item = static_cast<std::size_t>(f) * pointCount + i;
      const SkinPoint at = skinPoint(pose, triangles, features, hits[item], points, item);
      const Eigen::Vector3d& p = at.p;
      const Eigen::Vector3d& q = at.q;
      const Eigen::Vector3d& normal = at.normal;
      const Eigen::Vector3d offsetVector = p - q;
      const double distance = offsetVector.norm();
      const double signedDistance = at.signedDistance;
      const double length = at.length;
      // Inside points mirror outside ones: the offset surface under the skin is at -offset.
      const bool inside = !mSides.empty() && mSides[static_cast<std::size_t>(i)] == kSideInside;
      const double target = inside ? -static_cast<double>(offset) : static_cast<double>(offset);
      if (length > 0.0 && (inside ? signedDistance > target : signedDistance < target)) {
        const bool wrongSide = inside ? signedDistance > 0.0 : signedDistance < 0.0;
        const double fraction =
            mFade > 0.0f && wrongSide ? exitFraction(pose, p, q, distance, boxes) : 1.0;
        if (fraction > 0.0) {
          const Eigen::Vector3d full =
              q + (mAlongNormal || wrongSide
                       ? (target / length) * normal
                       : target * correction::nearestWayOut(offsetVector, signedDistance,
                                                            normal / length, offset));
          const Eigen::Vector3d result = fraction < 1.0 ? p + fraction * (full - p) : full;
          for (int k = 0; k < 3; ++k) {
            points[3 * item + static_cast<std::size_t>(k)] = static_cast<float>(result[k]);
          }
          ++count;
        }
      }
    }
    if (moved != nullptr) {
      moved[f] = count;
    }
  });
}

void HostClosest::skinPlanes(int frameCount, const float* poses, const SurfaceHit* hits,
                             const std::int32_t* answered, const float* points, float offset,
                             float depth, float reach, float* planes) {
  correction::checkResolve(mSearch, frameCount, poses, hits, offset, points);
  correction::checkOffset(depth);
  correction::checkOffset(reach);
  const int pointCount = mSearch.pointCount();
  const std::size_t poseStride = 3 * static_cast<std::size_t>(mSearch.vertexCount());
  const std::int32_t* triangles = mSearch.triangles().data();
  const correction::FeatureView features = correction::viewOf(mFeatures);
  parallelFor(frameCount, mSearch.threads(), [&](int f) {
    const float* pose = poses + static_cast<std::size_t>(f) * poseStride;
    for (int i = 0; i < pointCount; ++i) {
      const std::size_t item = static_cast<std::size_t>(f) * pointCount + i;
      float* plane = planes + 4 * item;
      std::fill_n(plane, 4, 0.0f);
      const bool inside = !mSides.empty() && mSides[static_cast<std::size_t>(i)] == kSideInside;
      if (inside || (answered != nullptr && answered[item] != 0)) {
        continue;
      }
      const SkinPoint at = skinPoint(pose, triangles, features, hits[item], points, item);
      const double s = at.signedDistance;
      const double full = depth;  // the depth of the full plane
      if (!(at.length > 0.0) || !(s > -1.5 * full) || !(s < static_cast<double>(reach))) {
        continue;
      }
      const double w = s < -full ? (1.5 * full + s) / (0.5 * full) : 1.0;
      const Eigen::Vector3d n = at.normal / at.length;
      const Eigen::Vector3d m =
          s < 0.0 || mAlongNormal ? n : correction::nearestWayOut(at.p - at.q, s, n, offset);
      for (int k = 0; k < 3; ++k) {
        plane[k] = static_cast<float>(m[k]);
      }
      plane[3] = static_cast<float>(m.dot(at.q) + offset - full * (1.0 - w) / w);
    }
  });
}

/// setExitFade()'s fraction of the move for a point p at depth `depth` from its closest point
/// q on `pose`: the nearest other exit by brute force over every triangle. Only exits nearer
/// than (1 + fade) depth change the fraction, so triangles whose box (`boxes`: min xyz, max
/// xyz per triangle of this pose, filled on the first call) is farther are skipped.
double HostClosest::exitFraction(const float* pose, const Eigen::Vector3d& p,
                                 const Eigen::Vector3d& q, double depth,
                                 std::vector<float>& boxes) const {
  if (depth <= 0.0) {
    return 1.0;
  }
  const std::int32_t* triangles = mSearch.triangles().data();
  const int triangleCount = mSearch.triangleCount();
  if (boxes.empty()) {
    boxes.resize(6 * static_cast<std::size_t>(triangleCount));
    for (int t = 0; t < triangleCount; ++t) {
      float* box = boxes.data() + 6 * static_cast<std::size_t>(t);
      for (int k = 0; k < 3; ++k) {
        const float* corner[3] = {pose + 3 * static_cast<std::size_t>(triangles[3 * t]),
                                  pose + 3 * static_cast<std::size_t>(triangles[3 * t + 1]),
                                  pose + 3 * static_cast<std::size_t>(triangles[3 * t + 2])};
        box[k] = std::min({corner[0][k], corner[1][k], corner[2][k]});
        box[3 + k] = std::max({corner[0][k], corner[1][k], corner[2][k]});
      }
    }
  }
  double other = (1.0 + mFade) * depth;  // beyond it the fraction is 1 anyway
  for (int t = 0; t < triangleCount; ++t) {
    const float* box = boxes.data() + 6 * static_cast<std::size_t>(t);
    double outside2 = 0.0;
    for (int k = 0; k < 3; ++k) {
      const double e = std::max(
          {static_cast<double>(box[k]) - p[k], 0.0, p[k] - static_cast<double>(box[3 + k])});
      outside2 += e * e;
    }
    if (outside2 >= other * other) {
      continue;
    }
    const std::int32_t* tri = triangles + 3 * static_cast<std::size_t>(t);
    const Eigen::Vector3d a = correction::loadPoint(pose, tri[0]);
    const Eigen::Vector3d b = correction::loadPoint(pose, tri[1]);
    const Eigen::Vector3d c = correction::loadPoint(pose, tri[2]);
    double u = 0.0;
    double v = 0.0;
    const double d2 = correction::triangleDistance2(p, a, b, c, u, v);
    if (d2 < other * other && (a + u * (b - a) + v * (c - a) - q).squaredNorm() > depth * depth) {
      other = std::sqrt(d2);
    }
  }
  return std::min(std::max((other - depth) / (mFade * depth), 0.0), 1.0);
}

void HostClosest::countInside(int frameCount, DeviceArray& poses, DeviceArray& hits,
                              DeviceArray& points, int* inside) {
  mSearch.checkChunk("inside count", frameCount, inside != nullptr && mInside != nullptr);
  mInside->countInsideFrames(frameCount, poses.read<float>(), mSearch.pointCount(),
                             points.read<float>(), hits.read<SurfaceHit>(), inside,
                             mSearch.threads(), mSides.empty() ? nullptr : mSides.data());
}

}  // namespace drivenshape
