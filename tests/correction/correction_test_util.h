#pragma once
// Helpers of the correction tests: an independent brute-force closest-triangle search, mesh
// builders, random scenes, and the tolerances of the correction quantities (one each).

#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include <drivenshape/correction.h>
#include <drivenshape/mesh.h>

#include "test_support.h"

namespace drivenshape::testing {

// Tolerances of the correction quantities live with all the others in test_support.h.

// ---- The oracle ----

/// Distance from p to triangle (a, b, c), written independently of the library (which works
/// with barycentric coordinates from cross products): the smallest of the three segment
/// distances and, when p projects into the triangle, the plane distance, the projection tested
/// in 2-D in an orthonormal frame built by Gram-Schmidt on the longest edge. A triangle whose
/// height over its longest edge is below 1e-12 of that edge is measured as its segments.
double oracleTriangleDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                              const Eigen::Vector3d& b, const Eigen::Vector3d& c);

/// Brute force over `allowed` triangles of `mesh` (all when empty) on `pose` (V x 3 floats):
/// the smallest distance.
double bruteForceDistance(const Mesh& mesh, const float* pose, const float* point,
                          const std::vector<int>& allowed = {});

/// Distance from `point` to the hit's point q = a + u (b - a) + v (c - a) on `pose`.
double hitDistance(const Mesh& mesh, const float* pose, const float* point, const SurfaceHit& hit);

/// max(bounding-box diagonal, largest coordinate magnitude) of one or two point sets.
double sceneScale(const float* xyz, int count, const float* more = nullptr, int moreCount = 0);

// ---- Meshes ----

/// A mesh from positions and polygons (all in group "default"), triangulated.
Mesh makeMesh(const std::vector<float>& xyz, const std::vector<std::vector<int>>& faces);

/// A "triangle soup" scene: `triangleCount` triangles over `vertexCount` random vertices in
/// the unit cube, about a quarter long thin slivers (aspect 1e2 .. 1e4), a few zero-area
/// triangles (collinear, repeated vertex, all three equal).
Mesh randomSoup(std::mt19937& rng, int vertexCount, int triangleCount);

/// Random query points for `mesh`: on and near its triangles, in its box, and far outside
/// (up to 100 box sizes away).
std::vector<float> randomPoints(std::mt19937& rng, const Mesh& mesh, const float* pose, int count);

/// A closed, outward-oriented cube [-1, 1]^3 with each face split into n x n quads (fan
/// triangulated).
Mesh subdividedCube(int n);

/// The bundled sleeve data (tests/data/sleeve): rest meshes and a few frames of the test caches.
struct SleeveData {
  Mesh driver;
  Mesh driven;
  std::vector<int> frames;    ///< cache frames read
  std::vector<float> poses;   ///< frames x 3Vp
  std::vector<float> points;  ///< frames x 3Vd
};
SleeveData loadSleeve(const std::vector<int>& frameIndices);

}  // namespace drivenshape::testing
