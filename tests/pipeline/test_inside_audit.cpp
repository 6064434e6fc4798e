// SPDX-License-Identifier: Apache-2.0
// Inside/outside audit with pseudo-normals, on a closed cube where the answer is known.

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "closest.h"

#include "correction_fixture.h"
#include "correction_test_util.h"
#include "test_support.h"

namespace drivenshape::testing {
namespace {

TEST_F(CorrectionClTest, AuditSignsMatchTheCubeInsideIncludingEdgeAndVertexHits) {
  const Mesh cube = subdividedCube(3);
  const float* pose = cube.positions.data();
  std::mt19937 rng(testSeed());
  std::uniform_real_distribution<float> box(-2.0f, 2.0f);
  // Fixed points first: outside a corner (vertex hit), outside a cube edge (edge hit), outside
  // an internal quad diagonal (edge hit inside a face), inside near a corner, at the centre.
  std::vector<float> points = {1.5f, 1.5f, 1.5f, 1.5f, 1.5f, 0.1f, 0.0f,  0.0f, 1.5f,
                               0.9f, 0.9f, 0.9f, 0.0f, 0.0f, 0.0f, -1.2f, 0.3f, -1.4f};
  while (points.size() < 3 * 3000) {
    const float x = box(rng);
    const float y = box(rng);
    const float z = box(rng);
    const float linf = std::max({std::fabs(x), std::fabs(y), std::fabs(z)});
    if (std::fabs(linf - 1.0f) > 1e-3f) {
      points.insert(points.end(), {x, y, z});
    }
  }
  const int count = static_cast<int>(points.size() / 3);
  ClosestBackend& host = *hostBackend();
  host.setSurface(cube, BindingMask::all(count));
  std::vector<SurfaceHit> hits(static_cast<std::size_t>(count));
  host.closest(1, pose, points.data(), hits.data());

  const InsideAudit audit(cube);
  std::vector<float> signedDistance(static_cast<std::size_t>(count));
  audit.signedDistances(pose, count, points.data(), hits.data(), signedDistance.data());
  int wrong = 0;
  int inside = 0;
  for (int i = 0; i < count; ++i) {
    const float* p = &points[3 * static_cast<std::size_t>(i)];
    const bool expectInside = std::max({std::fabs(p[0]), std::fabs(p[1]), std::fabs(p[2])}) < 1.0f;
    inside += expectInside;
    const float d = signedDistance[static_cast<std::size_t>(i)];
    if ((d < 0.0f) != expectInside) {
      if (++wrong <= 5) {
        ADD_FAILURE() << "point " << i << " (" << p[0] << ", " << p[1] << ", " << p[2]
                      << ") signed distance " << d << ", expected "
                      << (expectInside ? "inside" : "outside") << "; hit triangle "
                      << hits[static_cast<std::size_t>(i)].triangle << " u "
                      << hits[static_cast<std::size_t>(i)].u << " v "
                      << hits[static_cast<std::size_t>(i)].v;
      }
    }
    EXPECT_NEAR(std::fabs(d), std::sqrt(hits[static_cast<std::size_t>(i)].distance2), 1e-5f);
  }
  EXPECT_EQ(wrong, 0) << "of " << count << " points";
  EXPECT_EQ(audit.countInside(pose, count, points.data(), hits.data()), inside);
  // The fixed points really are vertex and edge hits.
  auto zeros = [&](int i) {
    const SurfaceHit& h = hits[static_cast<std::size_t>(i)];
    return int(h.u <= 1e-6f) + int(h.v <= 1e-6f) + int(1.0f - h.u - h.v <= 1e-6f);
  };
  EXPECT_EQ(zeros(0), 2);
  EXPECT_EQ(zeros(1), 1);
  EXPECT_EQ(zeros(2), 1);
  EXPECT_NEAR(signedDistance[0], std::sqrt(0.75f), 1e-6f);
  EXPECT_NEAR(signedDistance[3], -0.1f, 1e-6f);
  EXPECT_NEAR(signedDistance[4], -1.0f, 1e-6f);
}

}  // namespace
}  // namespace drivenshape::testing
