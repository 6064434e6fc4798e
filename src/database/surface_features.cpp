// SPDX-License-Identifier: Apache-2.0
#include "surface_features.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>

#include <Eigen/Geometry>

#include <correction_types.h>

#include "triangle_distance.h"

namespace drivenshape::correction {

FeatureTables buildFeatureTables(const std::int32_t* triangles, int triangleCount,
                                 int vertexCount) {
  FeatureTables tables;
  const std::size_t tcount = static_cast<std::size_t>(std::max(triangleCount, 0));
  // Edges: sort (smaller vertex, larger vertex, triangle, edge) so that equal edges are adjacent.
  std::vector<std::array<int, 4>> edges;
  edges.reserve(3 * tcount);
  for (std::size_t t = 0; t < tcount; ++t) {
    for (std::size_t e = 0; e < 3; ++e) {
      const int a = triangles[3 * t + e];
      const int b = triangles[3 * t + (e + 1) % 3];
      edges.push_back({std::min(a, b), std::max(a, b), static_cast<int>(t), static_cast<int>(e)});
    }
  }
  std::sort(edges.begin(), edges.end());
  std::vector<std::int32_t> count(3 * tcount + 1, 0);
  for (std::size_t first = 0; first < edges.size();) {
    std::size_t last = first;
    while (last < edges.size() && edges[last][0] == edges[first][0] &&
           edges[last][1] == edges[first][1]) {
      ++last;
    }
    for (std::size_t i = first; i < last; ++i) {
      count[3 * static_cast<std::size_t>(edges[i][2]) + static_cast<std::size_t>(edges[i][3]) + 1] =
          static_cast<std::int32_t>(last - first);
    }
    first = last;
  }
  tables.edgeStart.assign(3 * tcount + 1, 0);
  for (std::size_t k = 0; k < 3 * tcount; ++k) {
    tables.edgeStart[k + 1] = tables.edgeStart[k] + count[k + 1];
  }
  tables.edgeTriangles.resize(static_cast<std::size_t>(tables.edgeStart.back()));
  for (std::size_t first = 0; first < edges.size();) {
    std::size_t last = first;
    while (last < edges.size() && edges[last][0] == edges[first][0] &&
           edges[last][1] == edges[first][1]) {
      ++last;
    }
    for (std::size_t i = first; i < last; ++i) {
      std::size_t cursor =
          static_cast<std::size_t>(tables.edgeStart[3 * static_cast<std::size_t>(edges[i][2]) +
                                                    static_cast<std::size_t>(edges[i][3])]);
      for (std::size_t j = first; j < last; ++j) {
        tables.edgeTriangles[cursor++] = edges[j][2];
      }
    }
    first = last;
  }

  tables.vertexStart.assign(static_cast<std::size_t>(std::max(vertexCount, 0)) + 1, 0);
  for (std::size_t k = 0; k < 3 * tcount; ++k) {
    ++tables.vertexStart[static_cast<std::size_t>(triangles[k]) + 1];
  }
  for (std::size_t v = 0; v + 1 < tables.vertexStart.size(); ++v) {
    tables.vertexStart[v + 1] += tables.vertexStart[v];
  }
  tables.vertexTriangles.resize(static_cast<std::size_t>(tables.vertexStart.back()));
  std::vector<std::int32_t> cursor(tables.vertexStart.begin(), tables.vertexStart.end() - 1);
  for (std::size_t t = 0; t < tcount; ++t) {
    for (std::size_t k = 0; k < 3; ++k) {
      tables.vertexTriangles[static_cast<std::size_t>(
          cursor[static_cast<std::size_t>(triangles[3 * t + k])]++)] = static_cast<int>(t);
    }
  }
  return tables;
}

Eigen::Vector3d pseudoNormal(const float* pose, const std::int32_t* triangles,
                             const FeatureView& tables, int t, double u, double v) {
  auto corner = [&](int s, int k) {
    return loadPoint(pose,
                     triangles[3 * static_cast<std::size_t>(s) + static_cast<std::size_t>(k)]);
  };
  // Unit face normal; zero for a zero-area triangle.
  auto faceNormal = [&](int s) -> Eigen::Vector3d {
    const Eigen::Vector3d n = (corner(s, 1) - corner(s, 0)).cross(corner(s, 2) - corner(s, 0));
    const double length = n.norm();
    return length > 0.0 ? Eigen::Vector3d(n / length) : Eigen::Vector3d::Zero();
  };
  const std::array<double, 3> weight = {1.0 - u - v, u, v};
  int zeros = 0;
  int nonZero = 0;
  int zero = 0;
  for (int k = 0; k < 3; ++k) {
    if (weight[static_cast<std::size_t>(k)] <= DS_FEATURE_TOL) {
      ++zeros;
      zero = k;
    } else {
      nonZero = k;
    }
  }
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  if (zeros >= 2) {
    // Vertex: angle-weighted normal of the triangles around it.
    const int vertex =
        triangles[3 * static_cast<std::size_t>(t) + static_cast<std::size_t>(nonZero)];
    for (int k = tables.vertexStart[static_cast<std::size_t>(vertex)];
         k < tables.vertexStart[static_cast<std::size_t>(vertex) + 1]; ++k) {
      const int s = tables.vertexTriangles[static_cast<std::size_t>(k)];
      int at = 0;
      while (triangles[3 * static_cast<std::size_t>(s) + static_cast<std::size_t>(at)] != vertex) {
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
    for (int k = tables.edgeStart[edge]; k < tables.edgeStart[edge + 1]; ++k) {
      normal += faceNormal(tables.edgeTriangles[static_cast<std::size_t>(k)]);
    }
  } else {
    normal = faceNormal(t);
  }
  return normal;
}

Eigen::Vector3d nearestWayOut(const Eigen::Vector3d& offset, double s, const Eigen::Vector3d& n,
                              float skin) {
  const double steady = DS_RESOLVE_STEADY * static_cast<double>(skin) - std::fabs(s);
  const Eigen::Vector3d way = (s < 0.0 ? -offset : offset) + std::max(steady, 0.0) * n;
  const double length = way.norm();
  return length > 0.0 ? Eigen::Vector3d(way / length) : n;
}

}  // namespace drivenshape::correction
