#pragma once
// Helpers of the correction tests: an independent brute-force closest-triangle search, mesh
// builders, random scenes, and the tolerances of the correction quantities (one each).

#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include <drivenshape/correction.h>
#include <drivenshape/mesh.h>

namespace drivenshape::testing {

// ---- Tolerances of the correction quantities (each used by every test of that quantity) ----

/// How far a hit's distance may be from the brute-force oracle's: relative * d + scale * S,
/// with d the oracle distance and S the scene scale (max of bounding-box diagonal and largest
/// coordinate magnitude).
struct DistanceTolerance {
  double relative;
  double scale;
};
/// Host backend and OpenCL devices computing in double: the stored distance2 is the double
/// result rounded to float (2^-24 relative to d^2, so 3e-8 of d), plus double rounding
/// (~1e-15 of S). A triangle missed by the candidate search shows as an error above this
/// unless it is within 1e-7 of d of the true minimum.
inline constexpr DistanceTolerance kClosestDistanceTol = {1e-7, 1e-9};
/// OpenCL forced to float arithmetic (ClosestOptions::forceSinglePrecision), on scenes without
/// needle-like slivers: a few float roundings of the scene scale.
inline constexpr DistanceTolerance kClosestSingleTol = {1e-5, 2e-6};
/// The distance to the hit's point q(u, v) vs the oracle, as a fraction of (S + d): u and v
/// are stored as float, so q moves by up to 2^-24 (|b - a| + |c - a|) <= 1.2e-7 S.
inline constexpr double kHitPointRelTol = 1e-6;
/// Transfer results vs their expected positions (identity, rigid motion), as a fraction of the
/// scene scale: float outputs of a double computation.
inline constexpr double kTransferRelTol = 1e-6;
/// Barycentric range of a hit: u >= -tol, v >= -tol, u + v <= 1 + tol (float rounding).
inline constexpr double kBarycentricTol = 1e-6;

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
