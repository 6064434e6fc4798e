// SPDX-License-Identifier: Apache-2.0
// Inside/outside audit with angle-weighted pseudo-normals (Baerentzen & Aanaes 2005): for a
// closed, consistently oriented mesh, the sign of (p - q) . N at the closest point q is the
// side of p when N is the pseudo-normal of the feature (face, edge, vertex) that holds q. The
// pseudo-normals and their adjacency tables are shared with the penetration resolution
// (src/database/surface_features.h). Counts are of points on the wrong side of the skin for
// the side each lives on (ClosestBackend::setSides; outside for cloth).

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <utility>
#include <vector>

#include <drivenshape/error.h>

#include "closest.h"

#include "parallel.h"

#include "surface_features.h"
#include "triangle_distance.h"

namespace drivenshape {
using correction::loadPoint;

InsideAudit::InsideAudit(const Mesh& driver)
    : mVertexCount(driver.vertexCount()), mTriangles(driver.triangles) {
  const int triangleCount = static_cast<int>(mTriangles.rows());
  for (int t = 0; t < triangleCount; ++t) {
    for (int k = 0; k < 3; ++k) {
      if (mTriangles(t, k) < 0 || mTriangles(t, k) >= mVertexCount) {
        DS_THROW(kInput, "inside audit: driver triangle ", t, " names vertex ", mTriangles(t, k),
                 " but the driver has ", mVertexCount, " vertices");
      }
    }
  }
  correction::FeatureTables tables =
      correction::buildFeatureTables(mTriangles.data(), triangleCount, mVertexCount);
  mEdgeStart = std::move(tables.edgeStart);
  mEdgeTriangles = std::move(tables.edgeTriangles);
  mVertexStart = std::move(tables.vertexStart);
  mVertexTriangles = std::move(tables.vertexTriangles);
}

void InsideAudit::signedDistances(const float* pose, int pointCount, const float* points,
                                  const SurfaceHit* hits, float* out) const {
  const int triangleCount = static_cast<int>(mTriangles.rows());
  auto corner = [&](int t, int k) { return loadPoint(pose, mTriangles(t, k)); };
  const correction::FeatureView features = {mEdgeStart.data(), mEdgeTriangles.data(),
                                            mVertexStart.data(), mVertexTriangles.data()};
  for (int i = 0; i < pointCount; ++i) {
    const SurfaceHit& hit = hits[i];
    if (hit.triangle < 0 || hit.triangle >= triangleCount) {
      DS_THROW(kInput, "inside audit: point ", i, " has hit triangle ", hit.triangle,
               "; the driver has ", triangleCount, " triangles");
    }
    const int t = hit.triangle;
    const double u = hit.u;
    const double v = hit.v;
    const Eigen::Vector3d q =
        corner(t, 0) + u * (corner(t, 1) - corner(t, 0)) + v * (corner(t, 2) - corner(t, 0));
    const Eigen::Vector3d offset = loadPoint(points, i) - q;
    const double distance = offset.norm();
    const Eigen::Vector3d normal =
        correction::pseudoNormal(pose, mTriangles.data(), features, t, u, v);
    const double side = offset.dot(normal);
    out[i] = static_cast<float>(side < 0.0 ? -distance : distance);
  }
}

int InsideAudit::countInside(const float* pose, int pointCount, const float* points,
                             const SurfaceHit* hits, const std::int8_t* sides) const {
  std::vector<float> distances(static_cast<std::size_t>(std::max(pointCount, 0)));
  signedDistances(pose, pointCount, points, hits, distances.data());
  int wrong = 0;
  for (std::size_t i = 0; i < distances.size(); ++i) {
    const bool inside = sides != nullptr && sides[i] == kSideInside;
    wrong += (inside ? distances[i] > 0.0f : distances[i] < 0.0f) ? 1 : 0;
  }
  return wrong;
}

void InsideAudit::countInsideFrames(int frameCount, const float* poses, int pointCount,
                                    const float* points, const SurfaceHit* hits, int* inside,
                                    int threads, const std::int8_t* sides) const {
  const std::size_t poseValues = 3 * static_cast<std::size_t>(mVertexCount);
  parallelFor(frameCount, threads, [&](int f) {
    const std::size_t first = static_cast<std::size_t>(f) * pointCount;
    inside[f] =
        countInside(poses + f * poseValues, pointCount, points + 3 * first, hits + first, sides);
  });
}

}  // namespace drivenshape
