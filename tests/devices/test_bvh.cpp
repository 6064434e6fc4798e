// SPDX-License-Identifier: Apache-2.0
// The OpenCL backend's BVH search (src/database/bvh.cpp, kernels/bvh.cl): the trees' shape,
// and that the answer depends neither on the chunking nor on the warm start (it must equal the
// candidate-list kernel's and brute force's).

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <memory>
#include <random>
#include <vector>

#include "closest.h"

#include "cl_backends.h"

#include "bvh.h"
#include "correction_fixture.h"
#include "correction_test_util.h"
#include "test_support.h"

namespace drivenshape::testing {
namespace {

/// A triangle soup with `frameCount` jittered poses and random points per frame.
PosedScene makeScene(std::uint32_t seed, int frameCount, int pointCount) {
  return randomSoupScene(seed, 200, 600, 0.02f, frameCount, pointCount);
}

/// Three classes (halves of the triangles and a single triangle) and a quarter unrestricted.
BindingMask makeMask(const Mesh& mesh, int pointCount, std::mt19937& rng) {
  return randomClassMask(mesh, pointCount, mesh.triangleCount() / 3, rng);
}

TEST(Bvh, TreesHoldEachAllowedTriangleOnceAndAreSortedByDepth) {
  std::mt19937 rng(testSeed());
  const PosedScene scene = makeScene(testSeed(), 1, 400);
  const BindingMask mask = makeMask(scene.mesh, scene.pointCount, rng);
  for (int leafSize : {1, 4}) {
    SCOPED_TRACE(leafSize);
    const correction::BvhTables bvh = correction::buildBvh(scene.mesh, mask, leafSize);
    ASSERT_EQ(bvh.levelStart.back(), static_cast<int>(bvh.nodes.size()));
    std::vector<int> level(bvh.nodes.size());
    for (int d = 0; d < bvh.depth(); ++d) {
      for (int n = bvh.levelStart[static_cast<std::size_t>(d)];
           n < bvh.levelStart[static_cast<std::size_t>(d) + 1]; ++n) {
        level[static_cast<std::size_t>(n)] = d;
      }
    }
    // Median splits: depth at most ceil(log2(T / leafSize)) + 1 levels.
    const int triangles = scene.mesh.triangleCount();
    EXPECT_LE(
        bvh.depth(),
        static_cast<int>(std::ceil(std::log2(static_cast<double>(triangles) / leafSize))) + 1);
    for (int i = 0; i < scene.pointCount; ++i) {
      // Walk the point's tree: children one level deeper, leaves hold its class's triangles.
      const int root = bvh.pointRoot[static_cast<std::size_t>(i)];
      ASSERT_GE(root, 0);
      EXPECT_EQ(level[static_cast<std::size_t>(root)], 0);
      std::vector<int> found;
      std::function<void(int)> visit = [&](int n) {
        const DsBvhNode& node = bvh.nodes[static_cast<std::size_t>(n)];
        if (node.count > 0) {
          EXPECT_LE(node.count, leafSize);
          for (int k = node.first; k < node.first + node.count; ++k) {
            const int t = bvh.leafTriangles[4 * static_cast<std::size_t>(k) + 3];
            found.push_back(t);
            for (int c = 0; c < 3; ++c) {
              EXPECT_EQ(
                  bvh.leafTriangles[4 * static_cast<std::size_t>(k) + static_cast<std::size_t>(c)],
                  scene.mesh.triangles(t, c));
            }
          }
          return;
        }
        for (int child : {node.left, node.right}) {
          EXPECT_EQ(level[static_cast<std::size_t>(child)], level[static_cast<std::size_t>(n)] + 1);
          visit(child);
        }
      };
      if (i < 4 || i % 97 == 0) {  // every class, a sample of points
        visit(root);
        std::sort(found.begin(), found.end());
        const int c = mask.vertexClass(i);
        std::vector<int> allowed;
        for (int t = 0; t < triangles; ++t) {
          if (c < 0 || mask.allows(i, t)) {
            allowed.push_back(t);
          }
        }
        EXPECT_EQ(found, allowed) << "point " << i << " (class " << c << ")";
      }
    }
  }
}

TEST_F(CorrectionClTest, BvhAnswerDoesNotDependOnChunkingOrWarmStart) {
  std::mt19937 rng(testSeed() + 7);
  const PosedScene scene = makeScene(testSeed() + 7, 4, 2000);
  const BindingMask mask = makeMask(scene.mesh, scene.pointCount, rng);
  const int vp = scene.mesh.vertexCount();
  const int vd = scene.pointCount;
  const std::size_t items = static_cast<std::size_t>(scene.frameCount) * vd;
  ClosestBackend& cl = *clBackend();

  // All frames in one chunk (warm start from frame 0).
  cl.setSurface(scene.mesh, mask);
  std::vector<SurfaceHit> together(items);
  cl.closest(scene.frameCount, scene.poses.data(), scene.points.data(), together.data());
  // One frame per chunk, last frame first (each chunk warm-started from another frame).
  cl.setSurface(scene.mesh, mask);
  std::vector<SurfaceHit> apart(items);
  for (int f = scene.frameCount - 1; f >= 0; --f) {
    cl.closest(1, scene.poses.data() + 3L * vp * f, scene.points.data() + 3L * vd * f,
               apart.data() + static_cast<std::size_t>(vd) * f);
  }
  EXPECT_EQ(std::memcmp(together.data(), apart.data(), items * sizeof(SurfaceHit)), 0)
      << "hits changed with the chunking";

  // The candidate-list kernel applies the same formula and tie rule to a superset of the
  // contenders, so it must choose the same triangles.
  ClosestOptions options;
  options.deviceSearch = ClosestOptions::DeviceSearch::kCandidates;
  std::unique_ptr<ClosestBackend> candidates = makeClClosest(context(), device(), queue(), options);
  candidates->setSurface(scene.mesh, mask);
  std::vector<SurfaceHit> listed(items);
  candidates->closest(scene.frameCount, scene.poses.data(), scene.points.data(), listed.data());
  int differ = 0;
  for (std::size_t k = 0; k < items; ++k) {
    if (listed[k].triangle != together[k].triangle && ++differ <= 5) {
      ADD_FAILURE() << "item " << k << ": BVH triangle " << together[k].triangle << " at d2 "
                    << together[k].distance2 << ", candidate kernel triangle " << listed[k].triangle
                    << " at d2 " << listed[k].distance2;
    }
  }
  EXPECT_EQ(differ, 0) << "of " << items;
  const std::vector<double> brute =
      bruteForceAll(scene.mesh, scene.frameCount, scene.poses.data(), scene.points.data(), mask);
  expectExact(scene.mesh, scene.frameCount, scene.poses.data(), scene.points.data(), mask, together,
              brute, kClosestDistanceTol);
}

TEST_F(CorrectionClTest, BvhStaysExactWhenTheWarmStartIsFarOff) {
  // The first chunk seeds the search; the second moves every point across the scene (the
  // points of another random set, and far points), so every seed is a poor bound.
  const PosedScene scene = makeScene(testSeed() + 11, 2, 3000);
  const int vp = scene.mesh.vertexCount();
  const int vd = scene.pointCount;
  const BindingMask mask = BindingMask::all(vd);
  ClosestBackend& cl = *clBackend();
  cl.setSurface(scene.mesh, mask);
  std::vector<SurfaceHit> first(static_cast<std::size_t>(vd));
  cl.closest(1, scene.poses.data(), scene.points.data(), first.data());
  std::vector<float> moved(scene.points.begin() + 3L * vd, scene.points.end());
  std::reverse(moved.begin(), moved.end());  // other points, axes swapped
  const float* pose = scene.poses.data() + 3L * vp;
  std::vector<SurfaceHit> hits(static_cast<std::size_t>(vd));
  cl.closest(1, pose, moved.data(), hits.data());
  const std::vector<double> brute = bruteForceAll(scene.mesh, 1, pose, moved.data(), mask);
  expectExact(scene.mesh, 1, pose, moved.data(), mask, hits, brute, kClosestDistanceTol);
}

}  // namespace
}  // namespace drivenshape::testing
