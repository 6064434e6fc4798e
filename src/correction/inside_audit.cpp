// Inside/outside audit with angle-weighted pseudo-normals (Baerentzen & Aanaes 2005): for a
// closed, consistently oriented mesh, the sign of (p - q) . N at the closest point q is the
// side of p when N is the pseudo-normal of the feature (face, edge, vertex) that holds q.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <tuple>
#include <vector>

#include <drivenshape/correction.h>
#include <drivenshape/error.h>

#include "triangle_distance.h"

namespace drivenshape {
namespace {

using correction::loadPoint;

/// A barycentric coordinate at most this far from 0 puts the hit on an edge or vertex.
constexpr double kFeatureTolerance = 1e-6;

}  // namespace

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
  // Edges: sort (smaller vertex, larger vertex, triangle, edge) so that equal edges are adjacent.
  std::vector<std::array<int, 4>> edges;
  edges.reserve(3 * static_cast<std::size_t>(triangleCount));
  for (int t = 0; t < triangleCount; ++t) {
    for (int e = 0; e < 3; ++e) {
      const int a = mTriangles(t, e);
      const int b = mTriangles(t, (e + 1) % 3);
      edges.push_back({std::min(a, b), std::max(a, b), t, e});
    }
  }
  std::sort(edges.begin(), edges.end());
  std::vector<std::vector<int>> onEdge(3 * static_cast<std::size_t>(triangleCount));
  for (std::size_t first = 0; first < edges.size();) {
    std::size_t last = first;
    while (last < edges.size() && edges[last][0] == edges[first][0] &&
           edges[last][1] == edges[first][1]) {
      ++last;
    }
    for (std::size_t i = first; i < last; ++i) {
      std::vector<int>& list =
          onEdge[3 * static_cast<std::size_t>(edges[i][2]) + static_cast<std::size_t>(edges[i][3])];
      for (std::size_t j = first; j < last; ++j) {
        list.push_back(edges[j][2]);
      }
    }
    first = last;
  }
  mEdgeStart.assign(onEdge.size() + 1, 0);
  for (std::size_t k = 0; k < onEdge.size(); ++k) {
    mEdgeStart[k + 1] = mEdgeStart[k] + static_cast<int>(onEdge[k].size());
    mEdgeTriangles.insert(mEdgeTriangles.end(), onEdge[k].begin(), onEdge[k].end());
  }
  mVertexStart.assign(static_cast<std::size_t>(mVertexCount) + 1, 0);
  for (int t = 0; t < triangleCount; ++t) {
    for (int k = 0; k < 3; ++k) {
      ++mVertexStart[static_cast<std::size_t>(mTriangles(t, k)) + 1];
    }
  }
  for (int v = 0; v < mVertexCount; ++v) {
    mVertexStart[static_cast<std::size_t>(v) + 1] += mVertexStart[static_cast<std::size_t>(v)];
  }
  mVertexTriangles.resize(static_cast<std::size_t>(mVertexStart.back()));
  std::vector<int> cursor(mVertexStart.begin(), mVertexStart.end() - 1);
  for (int t = 0; t < triangleCount; ++t) {
    for (int k = 0; k < 3; ++k) {
      mVertexTriangles[static_cast<std::size_t>(
          cursor[static_cast<std::size_t>(mTriangles(t, k))]++)] = t;
    }
  }
}

void InsideAudit::signedDistances(const float* pose, int pointCount, const float* points,
                                  const SurfaceHit* hits, float* out) const {
  const int triangleCount = static_cast<int>(mTriangles.rows());
  auto corner = [&](int t, int k) { return loadPoint(pose, mTriangles(t, k)); };
  // Unit face normal; zero for a zero-area triangle.
  auto faceNormal = [&](int t) -> Eigen::Vector3d {
    const Eigen::Vector3d n = (corner(t, 1) - corner(t, 0)).cross(corner(t, 2) - corner(t, 0));
    const double length = n.norm();
    return length > 0.0 ? Eigen::Vector3d(n / length) : Eigen::Vector3d::Zero();
  };
  for (int i = 0; i < pointCount; ++i) {
    const SurfaceHit& hit = hits[i];
    if (hit.triangle < 0 || hit.triangle >= triangleCount) {
      DS_THROW(kInput, "inside audit: point ", i, " has hit triangle ", hit.triangle,
               "; the driver has ", triangleCount, " triangles");
    }
    const int t = hit.triangle;
    const double u = hit.u;
    const double v = hit.v;
    const std::array<double, 3> weight = {1.0 - u - v, u, v};
    const Eigen::Vector3d q =
        corner(t, 0) + u * (corner(t, 1) - corner(t, 0)) + v * (corner(t, 2) - corner(t, 0));
    const Eigen::Vector3d offset = loadPoint(points, i) - q;
    const double distance = offset.norm();
    int zeros = 0;
    int nonZero = 0;
    int zero = 0;
    for (int k = 0; k < 3; ++k) {
      if (weight[static_cast<std::size_t>(k)] <= kFeatureTolerance) {
        ++zeros;
        zero = k;
      } else {
        nonZero = k;
      }
    }
    Eigen::Vector3d normal = Eigen::Vector3d::Zero();
    if (zeros >= 2) {
      // Vertex: angle-weighted normal of the triangles around it.
      const int vertex = mTriangles(t, nonZero);
      for (int k = mVertexStart[static_cast<std::size_t>(vertex)];
           k < mVertexStart[static_cast<std::size_t>(vertex) + 1]; ++k) {
        const int s = mVertexTriangles[static_cast<std::size_t>(k)];
        int at = 0;
        while (mTriangles(s, at) != vertex) {
          ++at;
        }
        const Eigen::Vector3d e1 = corner(s, (at + 1) % 3) - corner(s, at);
        const Eigen::Vector3d e2 = corner(s, (at + 2) % 3) - corner(s, at);
        const double lengths = e1.norm() * e2.norm();
        if (lengths > 0.0) {
          const double angle = std::acos(std::clamp(e1.dot(e2) / lengths, -1.0, 1.0));
          normal += angle * faceNormal(s);
        }
      }
    } else if (zeros == 1) {
      // Edge opposite the zero weight: corners (zero + 1, zero + 2), which is edge index
      // (zero + 1) % 3 in the ab, bc, ca numbering.
      const std::size_t edge =
          3 * static_cast<std::size_t>(t) + static_cast<std::size_t>((zero + 1) % 3);
      for (int k = mEdgeStart[edge]; k < mEdgeStart[edge + 1]; ++k) {
        normal += faceNormal(mEdgeTriangles[static_cast<std::size_t>(k)]);
      }
    } else {
      normal = faceNormal(t);
    }
    const double side = offset.dot(normal);
    out[i] = static_cast<float>(side < 0.0 ? -distance : distance);
  }
}

int InsideAudit::countInside(const float* pose, int pointCount, const float* points,
                             const SurfaceHit* hits) const {
  std::vector<float> distances(static_cast<std::size_t>(std::max(pointCount, 0)));
  signedDistances(pose, pointCount, points, hits, distances.data());
  return static_cast<int>(
      std::count_if(distances.begin(), distances.end(), [](float d) { return d < 0.0f; }));
}

}  // namespace drivenshape
