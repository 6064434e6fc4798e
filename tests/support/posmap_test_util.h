// SPDX-License-Identifier: Apache-2.0
#pragma once
// Independent references for the position-map tests: UV triangles, point-in-triangle search
// and barycentric interpolation in double, written without the library's rasteriser (no
// snapping, no tie rule), plus small meshes built in code.

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <drivenshape/mesh.h>
#include <drivenshape/point_cache.h>

#include "test_support.h"

namespace drivenshape::testing {

/// One UV triangle of a face (fan order), in pixel space of a W x H map: x = u W,
/// y = (1 - v) H (row 0 at v = 1, as the library documents).
struct RefTriangle {
  int face = 0;
  int vertices[3] = {0, 0, 0};
  double x[3] = {0, 0, 0};
  double y[3] = {0, 0, 0};
};

inline std::vector<RefTriangle> refTriangles(const Mesh& mesh, int width, int height) {
  std::vector<RefTriangle> out;
  for (int f = 0; f + 1 < static_cast<int>(mesh.faceStart.size()); ++f) {
    const int begin = mesh.faceStart[f];
    for (int i = begin + 1; i + 1 < mesh.faceStart[f + 1]; ++i) {
      RefTriangle tri;
      tri.face = f;
      const int corners[3] = {begin, i, i + 1};
      for (int k = 0; k < 3; ++k) {
        tri.vertices[k] = mesh.faceVertices[corners[k]];
        const Eigen::Vector2f& uv = mesh.uvs[mesh.faceUvs[corners[k]]];
        tri.x[k] = static_cast<double>(uv.x()) * width;
        tri.y[k] = (1.0 - static_cast<double>(uv.y())) * height;
      }
      out.push_back(tri);
    }
  }
  return out;
}

/// Barycentric weights of (px, py) in `tri` and the signed distance (in texels) from the point
/// to the nearest edge: positive inside, negative outside. NaN distance when degenerate.
struct RefHit {
  int triangle = -1;
  double w[3] = {0, 0, 0};
  double margin = -std::numeric_limits<double>::infinity();
};

inline RefHit refLocate(const RefTriangle& tri, double px, double py) {
  RefHit hit;
  const double area2 =
      (tri.x[1] - tri.x[0]) * (tri.y[2] - tri.y[0]) - (tri.x[2] - tri.x[0]) * (tri.y[1] - tri.y[0]);
  if (area2 == 0.0) {
    return hit;
  }
  hit.w[1] =
      ((px - tri.x[0]) * (tri.y[2] - tri.y[0]) - (tri.x[2] - tri.x[0]) * (py - tri.y[0])) / area2;
  hit.w[2] =
      ((tri.x[1] - tri.x[0]) * (py - tri.y[0]) - (px - tri.x[0]) * (tri.y[1] - tri.y[0])) / area2;
  hit.w[0] = 1.0 - hit.w[1] - hit.w[2];
  double margin = std::numeric_limits<double>::infinity();
  for (int k = 0; k < 3; ++k) {
    const int a = (k + 1) % 3;
    const int b = (k + 2) % 3;
    const double edge = std::hypot(tri.x[b] - tri.x[a], tri.y[b] - tri.y[a]);
    margin = std::min(margin, hit.w[k] * std::fabs(area2) / edge);
  }
  hit.margin = margin;
  return hit;
}

/// For every texel centre of a W x H map: the triangle whose interior reaches deepest around
/// it (largest margin), found by scanning each triangle's bounding box.
inline std::vector<RefHit> refCoverage(const std::vector<RefTriangle>& tris, int width, int height,
                                       double slack) {
  std::vector<RefHit> best(static_cast<std::size_t>(width) * height);
  for (int t = 0; t < static_cast<int>(tris.size()); ++t) {
    const RefTriangle& tri = tris[t];
    const double minX = std::min({tri.x[0], tri.x[1], tri.x[2]}) - slack;
    const double maxX = std::max({tri.x[0], tri.x[1], tri.x[2]}) + slack;
    const double minY = std::min({tri.y[0], tri.y[1], tri.y[2]}) - slack;
    const double maxY = std::max({tri.y[0], tri.y[1], tri.y[2]}) + slack;
    for (int y = std::max(0, static_cast<int>(std::floor(minY - 0.5)));
         y <= std::min(height - 1, static_cast<int>(std::ceil(maxY - 0.5))); ++y) {
      for (int x = std::max(0, static_cast<int>(std::floor(minX - 0.5)));
           x <= std::min(width - 1, static_cast<int>(std::ceil(maxX - 0.5))); ++x) {
        RefHit hit = refLocate(tri, x + 0.5, y + 0.5);
        RefHit& current = best[static_cast<std::size_t>(y) * width + x];
        if (hit.margin > current.margin) {
          hit.triangle = t;
          current = hit;
        }
      }
    }
  }
  return best;
}

/// sum_k w_k p_{v_k} in double.
inline Eigen::Vector3d refInterpolate(const RefTriangle& tri, const double w[3], const float* xyz) {
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  for (int k = 0; k < 3; ++k) {
    for (int a = 0; a < 3; ++a) {
      p[a] += w[k] * static_cast<double>(xyz[3 * tri.vertices[k] + a]);
    }
  }
  return p;
}

/// A mesh built in code: positions (V x 3), UVs, faces as lists of (vertex, uv) corners.
inline Mesh makeMesh(const std::vector<Eigen::Vector3f>& positions,
                     const std::vector<Eigen::Vector2f>& uvs,
                     const std::vector<std::vector<std::pair<int, int>>>& faces) {
  Mesh mesh;
  mesh.positions.resize(static_cast<Eigen::Index>(positions.size()), 3);
  for (std::size_t v = 0; v < positions.size(); ++v) {
    mesh.positions.row(static_cast<Eigen::Index>(v)) = positions[v].transpose();
  }
  mesh.uvs = uvs;
  mesh.faceStart.push_back(0);
  for (const auto& face : faces) {
    for (const auto& [vertex, uv] : face) {
      mesh.faceVertices.push_back(vertex);
      mesh.faceUvs.push_back(uv);
    }
    mesh.faceStart.push_back(static_cast<int>(mesh.faceVertices.size()));
    mesh.faceGroup.push_back(0);
  }
  mesh.groupNames = {"default"};
  mesh.triangulate();
  return mesh;
}

/// The bundled sleeve: driven rest mesh (2244 vertices, UVs) and its test cache (48 frames).
struct Sleeve {
  Mesh mesh;
  std::unique_ptr<PointCacheReader> cache;
  std::string meshPath;
  std::string cachePath;
};

inline Sleeve loadSleeve() {
  Sleeve sleeve;
  sleeve.meshPath = dataDir() + "/sleeve/driven_rest.obj";
  sleeve.cachePath = dataDir() + "/sleeve/test.driven.pc2";
  sleeve.mesh = readObj(sleeve.meshPath);
  sleeve.cache = openPointCache(sleeve.cachePath);
  return sleeve;
}

/// Frames of a cache, F x 3V.
inline std::vector<float> readSleeveFrames(const Sleeve& sleeve, const std::vector<int>& frames) {
  return readFrames(*sleeve.cache, frames);
}

/// The code of the drivenshape::Error that `body` throws, its message in `message`; kInternal
/// (which no caller expects) when nothing is thrown.
template <typename Body>
ErrorCode codeOf(Body&& body, std::string& message) {
  try {
    body();
  } catch (const Error& error) {
    message = error.what();
    return error.code();
  }
  message.clear();
  return ErrorCode::kInternal;  // nothing thrown: the caller's EXPECT fails on the code
}

}  // namespace drivenshape::testing
