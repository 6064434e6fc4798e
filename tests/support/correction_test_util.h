// SPDX-License-Identifier: Apache-2.0
#pragma once
// Helpers of the correction tests: an independent brute-force closest-triangle search, mesh
// builders, random scenes and masks, and point-set arithmetic.

#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Core>

#include <drivenshape/mesh.h>

#include "closest.h"

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

/// A driver mesh with `frameCount` poses and `pointCount` query points per frame.
struct PosedScene {
  Mesh mesh;
  int frameCount = 0;
  int pointCount = 0;
  std::vector<float> poses;   ///< frameCount x 3V
  std::vector<float> points;  ///< frameCount x 3 pointCount
};

/// randomSoup(rng, vertexCount, triangleCount) with rng seeded by `seed`, and `frameCount`
/// poses: the first is the soup itself, each later one the soup with every coordinate moved by
/// a normal deviate of standard deviation `jitter`; each frame gets its own randomPoints.
PosedScene randomSoupScene(std::uint32_t seed, int vertexCount, int triangleCount, float jitter,
                           int frameCount, int pointCount);

/// A mask of three classes over `mesh`'s triangles: a random half (a coin flip from `rng` per
/// triangle), the other half, and the single triangle `single`. Point i has class i % 4 - 1, so
/// a quarter of the points are unrestricted.
BindingMask randomClassMask(const Mesh& mesh, int pointCount, int single, std::mt19937& rng);

/// A closed, outward-oriented cube [-1, 1]^3 with each face split into n x n quads (fan
/// triangulated).
Mesh subdividedCube(int n);

/// A scene whose local frames degenerate, for transfer and rebuild: triangle 0 of `mesh` has
/// zero area (a repeated vertex), triangle 1 is regular, and triangle 2 (two vertices, one
/// repeated) collapses to a point on `to`, which also turns triangle 1 by 90 degrees about z and
/// moves it. One point per triangle, with its hit on that triangle.
struct DegenerateFrames {
  std::vector<float> from;  ///< the pose of `points` and `hits` (also the mesh's rest pose)
  Mesh mesh;
  std::vector<float> to;
  std::vector<float> points;
  std::vector<SurfaceHit> hits;
};
DegenerateFrames degenerateFrames();

/// The bundled sleeve data (tests/data/sleeve): rest meshes and a few frames of the test caches.
struct SleeveData {
  Mesh driver;
  Mesh driven;
  std::vector<int> frames;    ///< cache frames read
  std::vector<float> poses;   ///< frames x 3Vp
  std::vector<float> points;  ///< frames x 3Vd
};
SleeveData loadSleeve(const std::vector<int>& frameIndices);

/// The sleeve as a scene: its driver mesh, the rest pose then the loaded frames' poses, and as
/// the points the rest cloth then the loaded frames' cloth (1 + frames.size() frames).
PosedScene restAndFrames(const SleeveData& sleeve);

// ---- Backends and point sets ----

/// Sets `backend`'s surface to `mesh` with `mask` and returns its hits of `frameCount` frames
/// (frame f: `points` of frame f on `poses` of frame f), frameCount x mask.drivenVertexCount().
std::vector<SurfaceHit> closestHits(ClosestBackend& backend, const Mesh& mesh,
                                    const BindingMask& mask, int frameCount, const float* poses,
                                    const float* points);

/// The mesh's positions as interleaved xyz (one pose, 3V floats).
std::vector<float> flatPositions(const Mesh& mesh);

/// rotation * p + translation for every interleaved xyz point, computed in double, rounded to
/// float.
std::vector<float> rigidlyMoved(const std::vector<float>& xyz, const Eigen::Matrix3d& rotation,
                                const Eigen::Vector3d& translation);

/// Largest |a_i - b_i| over interleaved xyz points.
double maxPointError(const std::vector<float>& a, const std::vector<float>& b);

}  // namespace drivenshape::testing
