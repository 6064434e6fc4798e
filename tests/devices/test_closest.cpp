// SPDX-License-Identifier: Apache-2.0
// Closest triangle: both backends against an independent brute-force search (exactness), ties,
// degenerate triangles, masks and NaN input.

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <drivenshape/error.h>

#include "closest.h"

#include "cl_backends.h"

#include "correction_fixture.h"
#include "correction_test_util.h"
#include "test_support.h"

namespace drivenshape::testing {
namespace {

/// Random scene: a triangle soup and `frameCount` jittered poses with their own query points.
PosedScene makeRandomScene(std::uint32_t seed, int frameCount, int pointCount) {
  return randomSoupScene(seed, 150, 400, 0.01f, frameCount, pointCount);
}

TEST_F(CorrectionClTest, RandomSoupsWithSliversAndFarPointsAreExactOnBothBackends) {
  const PosedScene scene = makeRandomScene(testSeed(), 3, 4000);
  const BindingMask mask = BindingMask::all(scene.pointCount);
  expectExactOnBothBackends(scene, mask);
}

TEST_F(CorrectionClTest, SleeveRestAndShotFramesAreExactOnBothBackends) {
  // Rest meshes, then frames 0, 20 and 47 of the test shot (driven from the simulation).
  const SleeveData sleeve = loadSleeve({0, 20, 47});
  const PosedScene scene = restAndFrames(sleeve);
  const std::vector<std::vector<SurfaceHit>> results =
      expectExactOnBothBackends(scene, BindingMask::all(scene.pointCount));
  // Same candidates, same arithmetic, same tie band: the same triangles.
  int differ = 0;
  for (std::size_t k = 0; k < results[0].size(); ++k) {
    differ += results[0][k].triangle != results[1][k].triangle;
  }
  EXPECT_EQ(differ, 0) << "points whose host and OpenCL triangles differ, of " << results[0].size();
}

TEST_F(CorrectionClTest, SinglePrecisionDevicePathIsExactToItsTolerance) {
  const SleeveData sleeve = loadSleeve({10});
  const int vd = sleeve.driven.vertexCount();
  const BindingMask mask = BindingMask::all(vd);
  const std::vector<double> brute =
      bruteForceAll(sleeve.driver, 1, sleeve.poses.data(), sleeve.points.data(), mask);
  ClosestOptions options;
  options.forceSinglePrecision = true;
  const auto single = makeClClosest(context(), device(), queue(), options);
  single->setSurface(sleeve.driver, mask);
  std::vector<SurfaceHit> hits(static_cast<std::size_t>(vd));
  single->closest(1, sleeve.poses.data(), sleeve.points.data(), hits.data());
  expectExact(sleeve.driver, 1, sleeve.poses.data(), sleeve.points.data(), mask, hits, brute,
              kClosestSingleTol);
}

TEST_F(CorrectionClTest, MaskRestrictsHitsAndMatchesRestrictedBruteForce) {
  const std::uint32_t seed = testSeed() + 1;
  const PosedScene scene = makeRandomScene(seed, 2, 3000);
  std::mt19937 rng(seed);
  // Three classes of random triangle subsets (one of a single triangle); a quarter of the
  // points unrestricted.
  const BindingMask mask =
      randomClassMask(scene.mesh, scene.pointCount, scene.mesh.triangleCount() / 2, rng);
  expectExactOnBothBackends(scene, mask);
}

TEST_F(CorrectionClTest, TiesGoToTheSmallerTriangleIndex) {
  // A flat square as four triangles around its centre (indices 0..3) plus a far triangle.
  // A point above the centre is equally close to all four; a point above the diagonal edge
  // between triangles 1 and 2 is equally close to those two.
  const std::vector<float> xyz = {-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0,
                                  0,  0,  0, 5, 5,  5, 6, 5, 5, 5,  6, 5};
  const Mesh mesh = makeMesh(xyz, {{5, 6, 7}, {2, 3, 4}, {1, 2, 4}, {0, 1, 4}, {3, 0, 4}});
  const std::vector<float> points = {0.0f, 0.0f, 0.5f, 0.5f, 0.5f, 0.25f, 0.0f, 0.0f, 0.0f};
  const BindingMask mask = BindingMask::all(3);
  for (ClosestBackend* backend : {hostBackend(), clBackend()}) {
    SCOPED_TRACE(backend->name());
    backend->setSurface(mesh, mask);
    std::vector<SurfaceHit> hits(3);
    backend->closest(1, xyz.data(), points.data(), hits.data());
    EXPECT_EQ(hits[0].triangle, 1);
    EXPECT_NEAR(hits[0].distance2, 0.25f, 1e-7f);
    EXPECT_EQ(hits[1].triangle, 1);
    EXPECT_NEAR(hits[1].distance2, 0.0625f, 1e-7f);
    EXPECT_EQ(hits[2].triangle, 1);
    EXPECT_EQ(hits[2].distance2, 0.0f);
  }
}

TEST_F(CorrectionClTest, ZeroAreaTrianglesAreMeasuredAsSegmentsAndPoints) {
  // Only degenerate triangles: collinear, a repeated vertex, a single point.
  const std::vector<float> xyz = {0, 0, 0, 1, 0, 0, 2, 0, 0, 0, 1, 0, 3, 3, 3};
  const Mesh mesh = makeMesh(xyz, {{0, 1, 2}, {0, 0, 3}, {4, 4, 4}});
  std::mt19937 rng(testSeed());
  std::uniform_real_distribution<float> box(-1.0f, 4.0f);
  const int pointCount = 400;
  std::vector<float> points;
  for (int i = 0; i < pointCount; ++i) {
    points.insert(points.end(), {box(rng), box(rng), box(rng)});
  }
  // Points exactly on the degenerate triangles, too.
  points.insert(points.end(), {1.5f, 0.0f, 0.0f, 0.0f, 0.5f, 0.0f, 3.0f, 3.0f, 3.0f});
  const int total = pointCount + 3;
  const BindingMask mask = BindingMask::all(total);
  const std::vector<double> brute = bruteForceAll(mesh, 1, xyz.data(), points.data(), mask);
  for (ClosestBackend* backend : {hostBackend(), clBackend()}) {
    SCOPED_TRACE(backend->name());
    backend->setSurface(mesh, mask);
    std::vector<SurfaceHit> hits(static_cast<std::size_t>(total));
    backend->closest(1, xyz.data(), points.data(), hits.data());
    for (const SurfaceHit& hit : hits) {
      ASSERT_TRUE(std::isfinite(hit.u) && std::isfinite(hit.v) && std::isfinite(hit.distance2));
    }
    expectExact(mesh, 1, xyz.data(), points.data(), mask, hits, brute, kClosestDistanceTol);
    EXPECT_EQ(hits[static_cast<std::size_t>(total - 1)].triangle, 2);
    EXPECT_EQ(hits[static_cast<std::size_t>(total - 1)].distance2, 0.0f);
  }
}

TEST_F(CorrectionClTest, NonFinitePositionsAreNumericalErrorsNamingFrameAndVertex) {
  const std::vector<float> xyz = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  const Mesh mesh = makeMesh(xyz, {{0, 1, 2}});
  std::vector<float> poses = xyz;
  poses.insert(poses.end(), xyz.begin(), xyz.end());
  std::vector<float> points = {0.2f, 0.2f, 1.0f, 0.3f, 0.3f, 1.0f};
  std::vector<SurfaceHit> hits(2);
  for (ClosestBackend* backend : {hostBackend(), clBackend()}) {
    SCOPED_TRACE(backend->name());
    backend->setSurface(mesh, BindingMask::all(1));
    std::vector<float> badPoses = poses;
    badPoses[3 * 3 + 2 * 3 + 1] = std::nanf("");  // frame 1, vertex 2, y
    expectThrows([&] { backend->closest(2, badPoses.data(), points.data(), hits.data()); },
                 ErrorCode::kNumerical, "frame 1 of the chunk: driver vertex 2");
    std::vector<float> badPoints = points;
    badPoints[3] = INFINITY;  // frame 1, point 0
    expectThrows([&] { backend->closest(2, poses.data(), badPoints.data(), hits.data()); },
                 ErrorCode::kNumerical, "frame 1 of the chunk: driven point 0");
  }
}

TEST_F(CorrectionClTest, SurfaceErrorsAreInputErrors) {
  Mesh empty = makeMesh({0, 0, 0, 1, 0, 0}, {{0, 1}});
  const std::vector<float> xyz = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  const Mesh mesh = makeMesh(xyz, {{0, 1, 2}});
  for (ClosestBackend* backend : {hostBackend(), clBackend()}) {
    SCOPED_TRACE(backend->name());
    try {
      backend->setSurface(empty, BindingMask::all(1));
      ADD_FAILURE() << "driver without triangles accepted";
    } catch (const Error& error) {
      EXPECT_EQ(error.code(), ErrorCode::kInput);
    }
    expectThrows([&] { backend->setSurface(mesh, BindingMask({0}, {{1}})); }, ErrorCode::kInput,
                 "triangle 1");
  }
}

}  // namespace
}  // namespace drivenshape::testing
