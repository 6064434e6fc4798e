// SPDX-License-Identifier: Apache-2.0
#pragma once

// Angle-weighted pseudo-normals (Baerentzen & Aanaes 2005) of a triangle mesh, shared by the
// inside audit (src/pipeline/inside_audit.cpp), the host penetration resolution
// (src/devices/host/host_resolve.cpp) and, through the same tables uploaded to the device, by
// kernels/resolve.cl, which repeats pseudoNormal() in OpenCL C.

#include <cstdint>
#include <vector>

#include <Eigen/Core>

namespace drivenshape::correction {

/// Which triangles share each edge and each vertex, compressed rows:
///
///   edgeStart        3T + 1   triangles on edge e of triangle t (e = 0: ab, 1: bc, 2: ca),
///   edgeTriangles             t included: edgeTriangles[edgeStart[3t + e] .. edgeStart[3t+e+1]-1]
///   vertexStart      V + 1    triangles around vertex v:
///   vertexTriangles           vertexTriangles[vertexStart[v] .. vertexStart[v + 1] - 1]
struct FeatureTables {
  std::vector<std::int32_t> edgeStart;
  std::vector<std::int32_t> edgeTriangles;
  std::vector<std::int32_t> vertexStart;
  std::vector<std::int32_t> vertexTriangles;
};

/// The same tables by pointer (InsideAudit keeps its own vectors).
struct FeatureView {
  const std::int32_t* edgeStart;
  const std::int32_t* edgeTriangles;
  const std::int32_t* vertexStart;
  const std::int32_t* vertexTriangles;
};

inline FeatureView viewOf(const FeatureTables& tables) {
  return {tables.edgeStart.data(), tables.edgeTriangles.data(), tables.vertexStart.data(),
          tables.vertexTriangles.data()};
}

/// Builds the tables of `triangleCount` triangles (T x 3 vertex ids, interleaved, each in
/// [0, vertexCount); the caller checks that).
FeatureTables buildFeatureTables(const std::int32_t* triangles, int triangleCount, int vertexCount);

/// The (not normalised) pseudo-normal at the point (u, v) of triangle t on `pose` (V x 3):
/// the face normal when (u, v) is inside, the sum of the unit normals of the triangles on the
/// edge when one barycentric weight is within DS_FEATURE_TOL of 0, the angle-weighted sum of
/// the unit normals around the vertex when two are. Zero-area triangles contribute nothing, so
/// the result is zero where only such triangles meet.
Eigen::Vector3d pseudoNormal(const float* pose, const std::int32_t* triangles,
                             const FeatureView& tables, int t, double u, double v);

/// The nearest way out (ClosestBackend::setAlongNormal) of a point at `offset` = p - q from its
/// closest point q, with signed distance `s` and unit pseudo-normal `n` there, for the skin
/// offset `skin`: the unit vector of sign(s) (p - q) + max(DS_RESOLVE_STEADY skin - |s|, 0) n,
/// or n where that vanishes (kernels/resolve.cl's dsNearestWayOut).
Eigen::Vector3d nearestWayOut(const Eigen::Vector3d& offset, double s, const Eigen::Vector3d& n,
                              float skin);

}  // namespace drivenshape::correction
