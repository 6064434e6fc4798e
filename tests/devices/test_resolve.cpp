// SPDX-License-Identifier: Apache-2.0
// Penetration resolution on a closed cube, where the distance to the surface and the side are
// known in closed form: which points move, where they go (at the offset, outside; under the
// skin for points that live inside), that the others keep their bits, the per-frame counts and
// wrong-side counts, the strain limit's skin planes, OpenCL vs host, bad input.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include <drivenshape/error.h>

#include "closest.h"

#include "correction_fixture.h"
#include "correction_test_util.h"
#include "test_support.h"

namespace drivenshape::testing {
namespace {

constexpr float kOffset = 0.1f;
/// How far outside the skin the skin planes reach (SkinPlanesPassThrough... below).
constexpr float kPlaneReach = 0.3f;

/// Signed distance from p to the surface of the axis-aligned cube [c - 1, c + 1]^3 (negative
/// inside), in closed form.
double cubeSignedDistance(const float* p, const Eigen::Vector3d& centre) {
  const Eigen::Vector3d d =
      (Eigen::Vector3d(p[0], p[1], p[2]) - centre).cwiseAbs() - Eigen::Vector3d::Ones();
  const double outside = d.cwiseMax(0.0).norm();
  const double inside = std::min(d.maxCoeff(), 0.0);
  return outside + inside;
}

/// Where the resolution moves p to `target` (+offset outside, -offset under the skin) on the
/// cube [c - 1, c + 1]^3, in closed form: q + target N with q the closest surface point and N
/// the unit pseudo-normal there. Outside, q clamps p to the cube and N is the normalised sum of
/// the normals of the faces it clamped to (a face, an edge or a corner); inside, q is p moved
/// onto the nearest face and N that face's normal.
Eigen::Vector3d cubeResolved(const float* p, const Eigen::Vector3d& centre, double target) {
  const Eigen::Vector3d r = Eigen::Vector3d(p[0], p[1], p[2]) - centre;
  Eigen::Vector3d q = r;
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
  if (r.cwiseAbs().maxCoeff() > 1.0) {
    for (int a = 0; a < 3; ++a) {
      if (std::fabs(r[a]) > 1.0) {
        q[a] = std::copysign(1.0, r[a]);
        n[a] = q[a];
      }
    }
  } else {
    int a = 0;
    r.cwiseAbs().maxCoeff(&a);
    q[a] = std::copysign(1.0, r[a]);
    n[a] = q[a];
  }
  return centre + q + target * n.normalized();
}

/// Whether p is clear (by 1e-3) of where the closed forms above change case: the surface, the
/// offset surfaces outside and under the skin, the reach of the skin planes, the planes through the
/// cube's edges (outside) and the cube's medial axis (inside, where two faces are equally near).
bool clearOfFeatures(const float* p, const Eigen::Vector3d& centre) {
  constexpr double kClear = 1e-3;
  const double d = cubeSignedDistance(p, centre);
  if (std::fabs(d) <= kClear || std::fabs(d - kOffset) <= kClear ||
      std::fabs(d + kOffset) <= kClear || std::fabs(d - kPlaneReach) <= kClear) {
    return false;
  }
  const Eigen::Vector3d r = (Eigen::Vector3d(p[0], p[1], p[2]) - centre).cwiseAbs();
  if (d > 0.0) {
    return (r.array() - 1.0).abs().minCoeff() > kClear;
  }
  Eigen::Vector3d sorted = r;
  std::sort(sorted.data(), sorted.data() + 3);
  return sorted[2] - sorted[1] > kClear;
}

/// Two frames of a subdivided cube (the second moved by `shift`) and random points around it,
/// clear of the surface, the offset surfaces and the features of the closed forms above (so
/// the decision to move is not a rounding question), plus points exactly at an edge and a
/// corner direction.
struct CubeScene : PosedScene {
  std::vector<Eigen::Vector3d> centres;  ///< the cube's centre in each frame
};

CubeScene makeCubeScene() {
  CubeScene scene;
  scene.mesh = subdividedCube(3);
  scene.frameCount = 2;
  const int vp = scene.mesh.vertexCount();
  const Eigen::Vector3d shift(0.3, -0.2, 0.15);
  scene.centres = {Eigen::Vector3d::Zero(), shift};
  for (const Eigen::Vector3d& centre : scene.centres) {
    for (int v = 0; v < vp; ++v) {
      for (int a = 0; a < 3; ++a) {
        scene.poses.push_back(scene.mesh.positions(v, a) + static_cast<float>(centre[a]));
      }
    }
  }
  std::mt19937 rng(testSeed());
  std::uniform_real_distribution<float> box(-1.6f, 1.6f);
  // Same points in both frames: near a corner and an edge (outside, within the offset), deep
  // inside, then random ones.
  std::vector<float> frame = {1.03f, 1.04f, 1.02f, 1.05f, 1.02f, 0.2f, 0.1f, -0.2f, 0.3f};
  while (frame.size() < 3 * 2000) {
    const float p[3] = {box(rng), box(rng), box(rng)};
    bool clear = true;
    for (const Eigen::Vector3d& centre : scene.centres) {
      clear = clear && clearOfFeatures(p, centre);
    }
    if (clear) {
      frame.insert(frame.end(), p, p + 3);
    }
  }
  scene.pointCount = static_cast<int>(frame.size() / 3);
  scene.points = frame;
  scene.points.insert(scene.points.end(), frame.begin(), frame.end());
  return scene;
}

/// Exact hits of `points` on `poses` with the host backend (every triangle allowed).
std::vector<SurfaceHit> hostHits(ClosestBackend& host, const CubeScene& scene,
                                 const std::vector<float>& points) {
  return closestHits(host, scene.mesh, BindingMask::all(scene.pointCount), scene.frameCount,
                     scene.poses.data(), points.data());
}

TEST_F(CorrectionClTest, ResolveMovesInsideAndNearPointsToTheOffsetOutside) {
  const CubeScene scene = makeCubeScene();
  const int vp = scene.mesh.vertexCount();
  const int vd = scene.pointCount;
  const std::vector<SurfaceHit> hits = hostHits(*hostBackend(), scene, scene.points);
  // Independent expectation from the closed form.
  std::vector<int> expectedMoved(static_cast<std::size_t>(scene.frameCount), 0);
  std::vector<char> shouldMove(scene.points.size() / 3, 0);
  for (int f = 0; f < scene.frameCount; ++f) {
    for (int i = 0; i < vd; ++i) {
      const std::size_t k = static_cast<std::size_t>(f) * vd + i;
      shouldMove[k] = cubeSignedDistance(&scene.points[3 * k], scene.centres[f]) < kOffset;
      expectedMoved[static_cast<std::size_t>(f)] += shouldMove[k];
    }
  }
  ASSERT_GT(expectedMoved[0], 100);
  ASSERT_LT(expectedMoved[0], vd - 100);
  ASSERT_NE(expectedMoved[0], expectedMoved[1]);

  const double scale = sceneScale(scene.poses.data(), scene.frameCount * vp, scene.points.data(),
                                  scene.frameCount * vd);
  const InsideAudit audit(scene.mesh);
  std::vector<std::vector<float>> results;
  for (ClosestBackend* backend : {hostBackend(), clBackend()}) {
    SCOPED_TRACE(backend->name());
    backend->setSurface(scene.mesh, BindingMask::all(vd));
    std::vector<float> points = scene.points;
    std::vector<int> moved(static_cast<std::size_t>(scene.frameCount), -1);
    backend->resolve(scene.frameCount, scene.poses.data(), hits.data(), kOffset, points.data(),
                     moved.data());
    EXPECT_EQ(moved, expectedMoved);

    // A fresh exact search on the resolved points: the moved ones sit at the offset, outside.
    const std::vector<SurfaceHit> after = hostHits(*hostBackend(), scene, points);
    const std::vector<double> brute = bruteForceAll(
        scene.mesh, scene.frameCount, scene.poses.data(), points.data(), BindingMask::all(vd));
    int wrong = 0;
    double worst = 0.0;
    for (int f = 0; f < scene.frameCount; ++f) {
      const float* pose = scene.poses.data() + 3L * vp * f;
      std::vector<float> side(static_cast<std::size_t>(vd));
      audit.signedDistances(pose, vd, points.data() + 3L * vd * f, after.data() + vd * f,
                            side.data());
      for (int i = 0; i < vd; ++i) {
        const std::size_t k = static_cast<std::size_t>(f) * vd + i;
        const float* p = &points[3 * k];
        bool ok;
        if (shouldMove[k]) {
          const double error =
              std::max(std::fabs(brute[k] - kOffset),
                       std::fabs(cubeSignedDistance(p, scene.centres[f]) - kOffset));
          worst = std::max(worst, error);
          ok = error <= kResolveRelTol * scale && side[static_cast<std::size_t>(i)] > 0.0f;
        } else {
          ok = std::memcmp(p, &scene.points[3 * k], 3 * sizeof(float)) == 0;
        }
        if (!ok && ++wrong <= 5) {
          ADD_FAILURE() << "frame " << f << " point " << i << " (" << scene.points[3 * k] << ", "
                        << scene.points[3 * k + 1] << ", " << scene.points[3 * k + 2] << ") -> ("
                        << p[0] << ", " << p[1] << ", " << p[2]
                        << "): " << (shouldMove[k] ? "should move" : "should stay")
                        << "; brute-force distance " << brute[k] << ", audit side "
                        << side[static_cast<std::size_t>(i)] << ", offset " << kOffset
                        << ", tolerance " << kResolveRelTol << " x " << scale;
        }
      }
    }
    EXPECT_EQ(wrong, 0) << "of " << scene.frameCount * vd << " points";
    std::printf("[ resolve  ] %s: worst |distance - offset| %.3g (tolerance %.3g)\n",
                backend->name().c_str(), worst, kResolveRelTol * scale);
    results.push_back(points);
  }
  // OpenCL vs host.
  double difference = 0.0;
  for (std::size_t k = 0; k < results[0].size(); ++k) {
    difference =
        std::max(difference, static_cast<double>(std::fabs(results[0][k] - results[1][k])));
  }
  const Bounds bounds = computeBounds(results[0].data(), static_cast<int>(results[0].size() / 3));
  EXPECT_LE(difference, kDeviceVsHostRelTol * bounds.diagonal())
      << "largest |cl - host| " << difference << ", tolerance " << kDeviceVsHostRelTol << " x "
      << bounds.diagonal();
}

/// Wrong-side counts of `points` per frame through ClosestBackend::countInside (host-memory
/// arrays, which both backends take).
std::vector<int> wrongSideCounts(ClosestBackend& backend, const CubeScene& scene,
                                 const std::vector<SurfaceHit>& hits,
                                 const std::vector<float>& points) {
  DeviceArray poses;
  DeviceArray hitArray;
  DeviceArray pointArray;
  poses.view(scene.poses.data(), scene.poses.size());
  hitArray.view(hits.data(), hits.size());
  pointArray.view(points.data(), points.size());
  std::vector<int> counts(static_cast<std::size_t>(scene.frameCount), -1);
  backend.countInside(scene.frameCount, poses, hitArray, pointArray, counts.data());
  return counts;
}

// Issue 17 ("other deformables"): a muscle under the skin must stay under it. Every other
// point lives inside: those closer to the skin than the offset, or through it, move in to the
// offset along the pseudo-normal; the outside points behave exactly as without a side table.
TEST_F(CorrectionClTest, ResolveKeepsEachPointOnItsSideOfTheSkin) {
  const CubeScene scene = makeCubeScene();
  const int vd = scene.pointCount;
  std::vector<std::int8_t> sides(static_cast<std::size_t>(vd));
  for (int i = 0; i < vd; ++i) {
    sides[static_cast<std::size_t>(i)] = i % 2 == 0 ? kSideInside : kSideOutside;
  }
  const std::vector<SurfaceHit> hits = hostHits(*hostBackend(), scene, scene.points);
  // Independent expectations from the closed form.
  std::vector<int> expectedMoved(static_cast<std::size_t>(scene.frameCount), 0);
  std::vector<int> expectedWrong(static_cast<std::size_t>(scene.frameCount), 0);
  std::vector<char> shouldMove(scene.points.size() / 3, 0);
  int throughTheSkin = 0;  // inside points outside the cube
  int nearTheSkin = 0;     // inside points within the offset under the skin
  for (int f = 0; f < scene.frameCount; ++f) {
    for (int i = 0; i < vd; ++i) {
      const std::size_t k = static_cast<std::size_t>(f) * vd + i;
      const double d = cubeSignedDistance(&scene.points[3 * k], scene.centres[f]);
      const bool inside = sides[static_cast<std::size_t>(i)] == kSideInside;
      shouldMove[k] = inside ? d > -kOffset : d < kOffset;
      expectedMoved[static_cast<std::size_t>(f)] += shouldMove[k];
      expectedWrong[static_cast<std::size_t>(f)] += inside ? d > 0.0 : d < 0.0;
      throughTheSkin += inside && d > 0.0;
      nearTheSkin += inside && d < 0.0 && d > -kOffset;
    }
  }
  ASSERT_GT(throughTheSkin, 100);
  ASSERT_GT(nearTheSkin, 20);

  const double scale = sceneScale(scene.poses.data(), scene.frameCount * scene.mesh.vertexCount(),
                                  scene.points.data(), scene.frameCount * vd);
  std::vector<std::vector<float>> results;
  for (ClosestBackend* backend : {hostBackend(), clBackend()}) {
    SCOPED_TRACE(backend->name());
    backend->setSurface(scene.mesh, BindingMask::all(vd));
    backend->setSides(sides);
    EXPECT_EQ(wrongSideCounts(*backend, scene, hits, scene.points), expectedWrong);
    std::vector<float> points = scene.points;
    std::vector<int> moved(static_cast<std::size_t>(scene.frameCount), -1);
    backend->resolve(scene.frameCount, scene.poses.data(), hits.data(), kOffset, points.data(),
                     moved.data());
    EXPECT_EQ(moved, expectedMoved);
    int wrong = 0;
    double worst = 0.0;
    for (int f = 0; f < scene.frameCount; ++f) {
      for (int i = 0; i < vd; ++i) {
        const std::size_t k = static_cast<std::size_t>(f) * vd + i;
        const bool inside = sides[static_cast<std::size_t>(i)] == kSideInside;
        const float* p = &points[3 * k];
        bool ok;
        if (shouldMove[k]) {
          const Eigen::Vector3d expected =
              cubeResolved(&scene.points[3 * k], scene.centres[f], inside ? -kOffset : kOffset);
          const double error = (Eigen::Vector3d(p[0], p[1], p[2]) - expected).norm();
          const double d = cubeSignedDistance(p, scene.centres[f]);
          worst = std::max(worst, error);
          ok = error <= kResolveRelTol * scale && (inside ? d < 0.0 : d > 0.0);
        } else {
          ok = std::memcmp(p, &scene.points[3 * k], 3 * sizeof(float)) == 0;
        }
        if (!ok && ++wrong <= 5) {
          ADD_FAILURE() << "frame " << f << " point " << i << " (lives "
                        << (inside ? "inside" : "outside") << ") (" << scene.points[3 * k] << ", "
                        << scene.points[3 * k + 1] << ", " << scene.points[3 * k + 2] << ") -> ("
                        << p[0] << ", " << p[1] << ", " << p[2]
                        << "): " << (shouldMove[k] ? "should move" : "should stay") << "; offset "
                        << kOffset << ", tolerance " << kResolveRelTol << " x " << scale;
        }
      }
    }
    EXPECT_EQ(wrong, 0) << "of " << scene.frameCount * vd << " points";
    std::printf(
        "[ resolve  ] %s, sides: worst distance from the closed form %.3g (tolerance %.3g)\n",
        backend->name().c_str(), worst, kResolveRelTol * scale);
    // Nothing is left on the wrong side, by a fresh exact search.
    const std::vector<SurfaceHit> after = hostHits(*hostBackend(), scene, points);
    backend->setSurface(scene.mesh, BindingMask::all(vd));  // hostHits() reset the host backend
    backend->setSides(sides);
    EXPECT_EQ(wrongSideCounts(*backend, scene, after, points),
              std::vector<int>(static_cast<std::size_t>(scene.frameCount), 0));
    results.push_back(points);
  }
  expectDeviceMatchesHost(
      results[0], results[1],
      computeBounds(results[0].data(), static_cast<int>(results[0].size() / 3)).diagonal());

  // Without a side table (setSurface() forgets it) every point is cloth: the outside points
  // move bit for bit as with the table, and the inside ones are pushed out through the skin,
  // which the checks above would catch.
  for (std::size_t b = 0; b < 2; ++b) {
    ClosestBackend* backend = b == 0 ? hostBackend() : clBackend();
    SCOPED_TRACE(backend->name());
    backend->setSurface(scene.mesh, BindingMask::all(vd));
    std::vector<float> points = scene.points;
    backend->resolve(scene.frameCount, scene.poses.data(), hits.data(), kOffset, points.data(),
                     nullptr);
    int outsideDifferent = 0;
    int pushedOut = 0;
    for (int f = 0; f < scene.frameCount; ++f) {
      for (int i = 0; i < vd; ++i) {
        const std::size_t k = static_cast<std::size_t>(f) * vd + i;
        if (sides[static_cast<std::size_t>(i)] == kSideOutside) {
          outsideDifferent += std::memcmp(&points[3 * k], &results[b][3 * k], 3 * sizeof(float));
        } else {
          pushedOut += cubeSignedDistance(&points[3 * k], scene.centres[f]) > 0.0;
        }
      }
    }
    EXPECT_EQ(outsideDifferent, 0);
    EXPECT_GE(pushedOut, throughTheSkin + nearTheSkin);
  }
}

TEST_F(CorrectionClTest, SideTablesOfTheWrongLengthOrWithOtherValuesAreRefused) {
  const CubeScene scene = makeCubeScene();
  const int vd = scene.pointCount;
  for (ClosestBackend* backend : {hostBackend(), clBackend()}) {
    SCOPED_TRACE(backend->name());
    backend->setSurface(scene.mesh, BindingMask::all(vd));
    expectThrows([&] { backend->setSides(std::vector<std::int8_t>(3, kSideInside)); },
                 ErrorCode::kInput, "3 entries for " + std::to_string(vd));
    std::vector<std::int8_t> sides(static_cast<std::size_t>(vd), kSideOutside);
    sides[7] = 0;
    expectThrows([&] { backend->setSides(sides); }, ErrorCode::kInput, "driven point 7 has side 0");
    EXPECT_NO_THROW(backend->setSides({}));
  }
}

TEST_F(CorrectionClTest, ResolveWithZeroOffsetMovesOnlyInsidePointsOntoTheSurface) {
  const CubeScene scene = makeCubeScene();
  const int vd = scene.pointCount;
  const std::vector<SurfaceHit> hits = hostHits(*hostBackend(), scene, scene.points);
  int inside = 0;
  for (int i = 0; i < vd; ++i) {
    inside +=
        cubeSignedDistance(&scene.points[3 * static_cast<std::size_t>(i)], scene.centres[0]) < 0.0;
  }
  for (ClosestBackend* backend : {hostBackend(), clBackend()}) {
    SCOPED_TRACE(backend->name());
    backend->setSurface(scene.mesh, BindingMask::all(vd));
    std::vector<float> points = scene.points;
    std::vector<int> moved(2, -1);
    backend->resolve(scene.frameCount, scene.poses.data(), hits.data(), 0.0f, points.data(),
                     moved.data());
    EXPECT_EQ(moved[0], inside);
    for (int i = 0; i < vd; ++i) {
      const std::size_t k = 3 * static_cast<std::size_t>(i);
      if (cubeSignedDistance(&scene.points[k], scene.centres[0]) < 0.0) {
        EXPECT_LE(std::fabs(cubeSignedDistance(&points[k], scene.centres[0])), kResolveRelTol * 3.0)
            << "inside point " << i << " not moved onto the surface";
      } else {
        EXPECT_EQ(std::memcmp(&points[k], &scene.points[k], 3 * sizeof(float)), 0)
            << "outside point " << i << " moved";
      }
      if (HasFailure()) {
        break;
      }
    }
    // moved may be null.
    std::vector<float> again = scene.points;
    backend->resolve(scene.frameCount, scene.poses.data(), hits.data(), 0.0f, again.data(),
                     nullptr);
    EXPECT_EQ(again, points);
  }
}

/// Where the nearest-way resolution (setAlongNormal(false)) moves p on the cube
/// [c - 1, c + 1]^3, in closed form: outside, q + offset (p - q) / |p - q| with q the clamp of p
/// (a face, an edge or a corner: the shortest way to the offset); inside (the wrong side), along
/// the normal as before (q on the nearest face).
Eigen::Vector3d cubeResolvedNearest(const float* p, const Eigen::Vector3d& centre) {
  if (cubeSignedDistance(p, centre) <= 0.0) {
    return cubeResolved(p, centre, kOffset);
  }
  const Eigen::Vector3d r = Eigen::Vector3d(p[0], p[1], p[2]) - centre;
  const Eigen::Vector3d q = r.cwiseMax(-1.0).cwiseMin(1.0);
  return centre + q + kOffset * (r - q).normalized();
}

/// Sets each backend's direction for one test and restores 0.1's (the backends are shared).
class NearestWay {
 public:
  explicit NearestWay(std::initializer_list<ClosestBackend*> backends) : mBackends(backends) {
    for (ClosestBackend* backend : mBackends) {
      backend->setAlongNormal(false);
    }
  }
  ~NearestWay() {
    for (ClosestBackend* backend : mBackends) {
      backend->setAlongNormal(true);
    }
  }
  NearestWay(const NearestWay&) = delete;
  NearestWay& operator=(const NearestWay&) = delete;

 private:
  std::vector<ClosestBackend*> mBackends;
};

TEST_F(CorrectionClTest, ResolveTheNearestWayMovesToTheOffsetAlongTheLineFromTheClosestPoint) {
  const CubeScene scene = makeCubeScene();
  const int vd = scene.pointCount;
  const std::vector<SurfaceHit> hits = hostHits(*hostBackend(), scene, scene.points);
  const double scale = sceneScale(scene.poses.data(), scene.frameCount * scene.mesh.vertexCount(),
                                  scene.points.data(), scene.frameCount * vd);
  const NearestWay nearest({hostBackend(), clBackend()});
  for (ClosestBackend* backend : {hostBackend(), clBackend()}) {
    SCOPED_TRACE(backend->name());
    backend->setSurface(scene.mesh, BindingMask::all(vd));
    std::vector<float> points = scene.points;
    backend->resolve(scene.frameCount, scene.poses.data(), hits.data(), kOffset, points.data(),
                     nullptr);
    int wrong = 0;
    int atFeatures = 0;  // moved points whose way out is not a face normal
    double worst = 0.0;
    for (int f = 0; f < scene.frameCount; ++f) {
      for (int i = 0; i < vd; ++i) {
        const std::size_t k = static_cast<std::size_t>(f) * vd + i;
        const float* before = &scene.points[3 * k];
        const double d = cubeSignedDistance(before, scene.centres[f]);
        const Eigen::Vector3d got(points[3 * k], points[3 * k + 1], points[3 * k + 2]);
        const Eigen::Vector3d want = d < kOffset ? cubeResolvedNearest(before, scene.centres[f])
                                                 : Eigen::Vector3d(before[0], before[1], before[2]);
        const double error = (got - want).norm();
        worst = std::max(worst, error);
        const Eigen::Vector3d r =
            (Eigen::Vector3d(before[0], before[1], before[2]) - scene.centres[f]).cwiseAbs();
        atFeatures += d > 0.0 && d < kOffset && (r.array() > 1.0).count() >= 2;
        if (error > kResolveRelTol * scale && ++wrong <= 5) {
          ADD_FAILURE() << "frame " << f << " point " << i << " (" << before[0] << ", " << before[1]
                        << ", " << before[2] << ") -> " << got.transpose() << ", closed form "
                        << want.transpose() << ", tolerance " << kResolveRelTol << " x " << scale;
        }
      }
    }
    EXPECT_EQ(wrong, 0) << "of " << scene.frameCount * vd << " points";
    EXPECT_GT(atFeatures, 0) << "no point near an edge or a corner: the case is not exercised";
    // Points on the wrong side (inside the cube) move along the normal: bit for bit 0.1's move.
    backend->setAlongNormal(true);
    std::vector<float> alongNormal = scene.points;
    backend->resolve(scene.frameCount, scene.poses.data(), hits.data(), kOffset, alongNormal.data(),
                     nullptr);
    backend->setAlongNormal(false);
    int insideDiffer = 0, insideCount = 0;
    for (std::size_t k = 0; k < points.size() / 3; ++k) {
      if (cubeSignedDistance(&scene.points[3 * k], scene.centres[k / vd]) < 0.0) {
        ++insideCount;
        insideDiffer += std::memcmp(&points[3 * k], &alongNormal[3 * k], 3 * sizeof(float)) != 0;
      }
    }
    EXPECT_GT(insideCount, 0);
    EXPECT_EQ(insideDiffer, 0) << "of " << insideCount << " points inside";
    std::printf(
        "[ resolve  ] %s, nearest way: worst |p - closed form| %.3g, %d moved points "
        "beside an edge or corner\n",
        backend->name().c_str(), worst, atFeatures);
  }
}

// A point sliding over the cube's edge, 0.05 above the top face (within the offset): along the
// normal, its target jumps where its closest point crosses from the face onto the edge (from the
// face normal to the edge's 45-degree pseudo-normal); the nearest way is continuous, with the
// closed form's slope (at most offset / 0.05 = 2 per unit of the slide).
TEST_F(CorrectionClTest, ResolveTheNearestWayIsContinuousWhereTheClosestPointCrossesAnEdge) {
  PosedScene scene;
  scene.mesh = subdividedCube(3);
  scene.frameCount = 1;
  for (int v = 0; v < scene.mesh.vertexCount(); ++v) {
    for (int a = 0; a < 3; ++a) {
      scene.poses.push_back(scene.mesh.positions(v, a));
    }
  }
  constexpr double kStep = 1e-5;
  constexpr int kSteps = 2001;  // x from 1 - 0.01 to 1 + 0.01
  for (int i = 0; i < kSteps; ++i) {
    const double x = 1.0 - 0.01 + kStep * i;
    scene.points.insert(scene.points.end(), {static_cast<float>(x), 0.3f, 1.05f});
  }
  scene.pointCount = kSteps;
  const std::vector<SurfaceHit> hits =
      closestHits(*hostBackend(), scene.mesh, BindingMask::all(kSteps), 1, scene.poses.data(),
                  scene.points.data());
  // Consecutive inputs are kStep apart up to float rounding of x (6e-8); the slope is at most 2.
  const double slopeBound = 2.0 * (kStep + 1.2e-7) + 2.0 * kResolveRelTol * 2.0;
  for (const bool alongNormal : {true, false}) {
    for (ClosestBackend* backend : {hostBackend(), clBackend()}) {
      SCOPED_TRACE(backend->name() + (alongNormal ? ", along the normal" : ", nearest way"));
      const NearestWay nearest({backend});
      backend->setAlongNormal(alongNormal);
      backend->setSurface(scene.mesh, BindingMask::all(kSteps));
      std::vector<float> points = scene.points;
      backend->resolve(1, scene.poses.data(), hits.data(), kOffset, points.data(), nullptr);
      double largest = 0.0;
      for (int i = 1; i < kSteps; ++i) {
        const std::size_t k = 3 * static_cast<std::size_t>(i);
        double step = 0.0;
        for (int a = 0; a < 3; ++a) {
          step += std::pow(static_cast<double>(points[k + a]) - points[k - 3 + a], 2.0);
        }
        largest = std::max(largest, std::sqrt(step));
      }
      std::printf("[ resolve  ] %s, %s: largest move between neighbours %.3g apart: %.3g\n",
                  backend->name().c_str(), alongNormal ? "along the normal" : "nearest way", kStep,
                  largest);
      if (alongNormal) {
        // The jump: from (1, 0.3, 1.1) to (1, 0.3, 1) + 0.1 (1, 0, 1) / sqrt(2), 0.077 long.
        EXPECT_GT(largest, 0.07);
      } else {
        EXPECT_LE(largest, slopeBound);
      }
    }
  }
}

/// A slab |z| <= kHalf (the subdivided cube flattened) and points on a line across its middle
/// plane, where the two exits (top and bottom) tie: the exit fade in closed form. For a point at
/// height e the nearest exit is the near face at depth d = kHalf - |e|; the nearest other exit
/// is the far face at kHalf + |e| (every triangle of the near face whose closest point lies
/// farther than d from q is at least sqrt(2) d away, farther still while |e| < 0.03), so the
/// fraction of the move is clamp(2 |e| / (fade d), 0, 1).
constexpr float kHalf = 0.2f;
constexpr float kFade = 0.3f;

PosedScene makeSlabScene(const std::vector<float>& heights) {
  PosedScene scene;
  scene.mesh = subdividedCube(16);
  for (int v = 0; v < scene.mesh.vertexCount(); ++v) {
    scene.mesh.positions(v, 2) *= kHalf;
  }
  scene.frameCount = 1;
  scene.poses.assign(scene.mesh.positions.data(),
                     scene.mesh.positions.data() + 3 * scene.mesh.vertexCount());
  for (const float e : heights) {
    scene.points.insert(scene.points.end(), {0.1f, 0.05f, e});
  }
  scene.pointCount = static_cast<int>(heights.size());
  return scene;
}

std::vector<float> resolvedOnSlab(ClosestBackend& backend, ClosestBackend& host,
                                  const PosedScene& scene, float fade) {
  const BindingMask all = BindingMask::all(scene.pointCount);
  const std::vector<SurfaceHit> hits =
      closestHits(host, scene.mesh, all, 1, scene.poses.data(), scene.points.data());
  backend.setSurface(scene.mesh, all);
  backend.setExitFade(fade);
  std::vector<float> points = scene.points;
  backend.resolve(1, scene.poses.data(), hits.data(), kOffset, points.data(), nullptr);
  return points;
}

TEST_F(CorrectionClTest, ExitFadeMovesPointsWithTwoNearlyEqualExitsPartOfTheWay) {
  // Off the middle plane by 0, 2, 5, 10, 20 and 30 thousandths (fractions 0 to 1), and a deep
  // point nearer the top face (no other exit near: it moves all the way).
  const std::vector<float> heights = {0.0f,  0.002f,  -0.005f, 0.01f, -0.01f,
                                      0.02f, -0.025f, 0.03f,   0.1f};
  const PosedScene scene = makeSlabScene(heights);
  for (ClosestBackend* backend : {hostBackend(), clBackend()}) {
    SCOPED_TRACE(backend->name());
    const std::vector<float> points = resolvedOnSlab(*backend, *hostBackend(), scene, kFade);
    for (std::size_t i = 0; i < heights.size(); ++i) {
      const double e = heights[i];
      const double depth = kHalf - std::fabs(e);
      const double fraction = std::min(2.0 * std::fabs(e) / (kFade * depth), 1.0);
      const double target = std::copysign(kHalf + kOffset, e == 0.0 ? 1.0 : e);
      const double expected = e + fraction * (target - e);
      // The slab's scale is 1 (half-width 1), so the relative tolerance is absolute here.
      EXPECT_NEAR(points[3 * i], 0.1f, kResolveRelTol) << "point " << i;
      EXPECT_NEAR(points[3 * i + 1], 0.05f, kResolveRelTol) << "point " << i;
      EXPECT_NEAR(points[3 * i + 2], expected, kResolveRelTol)
          << "point " << i << " at height " << e << ": fraction " << fraction;
    }
  }
}

TEST_F(CorrectionClTest, ExitFadeMakesTheMoveContinuousAcrossTheMiddleOfALimb) {
  // A point swept across the slab's middle plane in steps of 1e-3: without the fade it jumps
  // from the bottom face to the top one (2 kHalf + 2 offsets); with it, every step moves it by
  // at most the step times 1 + (the fraction's slope, below 2 / (fade (kHalf - 0.03))) x (the
  // length of the move, below kHalf + kOffset + 0.03).
  std::vector<float> heights;
  for (int k = -30; k <= 30; ++k) {
    heights.push_back(0.001f * static_cast<float>(k) + 0.0005f);
  }
  const PosedScene scene = makeSlabScene(heights);
  for (ClosestBackend* backend : {hostBackend(), clBackend()}) {
    SCOPED_TRACE(backend->name());
    for (const float fade : {0.0f, kFade}) {
      const std::vector<float> points = resolvedOnSlab(*backend, *hostBackend(), scene, fade);
      double largestStep = 0.0;
      for (std::size_t i = 1; i < heights.size(); ++i) {
        largestStep = std::max(
            largestStep, static_cast<double>(std::fabs(points[3 * i + 2] - points[3 * i - 1])));
      }
      if (fade == 0.0f) {
        EXPECT_GT(largestStep, 2.0 * kHalf) << "without the fade the point jumps across";
      } else {
        const double slope = 2.0 / (kFade * (kHalf - 0.03));
        EXPECT_LT(largestStep, 0.001 * (1.0 + slope * (kHalf + kOffset + 0.03)))
            << "with the fade the move is continuous";
      }
    }
  }
}

// The strain limit's skin planes (ClosestBackend::skinPlanes) against the closed form: a point on
// its side of the skin, or less than `depth` inside, gets the plane through the point the
// resolution would move it to, with the resolution's direction as its normal; one between
// `depth` and 1.5 `depth` inside the same plane sunk by depth (1 - w) / w; a deeper one, one
// `reach` or farther outside, one that lives inside and one marked answered without a search get
// none.
TEST_F(CorrectionClTest, SkinPlanesPassThroughWhereTheResolutionWouldMoveEachPoint) {
  const CubeScene scene = makeCubeScene();
  const int vd = scene.pointCount;
  const std::vector<SurfaceHit> hits = hostHits(*hostBackend(), scene, scene.points);
  const double scale = sceneScale(scene.poses.data(), scene.frameCount * scene.mesh.vertexCount(),
                                  scene.points.data(), scene.frameCount * vd);
  constexpr float kDepth = 0.4f;
  std::vector<std::int32_t> answered(hits.size(), 0);
  for (std::size_t k = 0; k < answered.size(); k += 7) {
    answered[k] = 1;
  }
  std::vector<std::int8_t> sides(static_cast<std::size_t>(vd), kSideOutside);
  for (std::size_t i = 5; i < sides.size(); i += 11) {
    sides[i] = kSideInside;
  }
  std::vector<std::vector<float>> results;
  for (ClosestBackend* backend : {hostBackend(), clBackend()}) {
    SCOPED_TRACE(backend->name());
    backend->setSurface(scene.mesh, BindingMask::all(vd));
    backend->setSides(sides);
    std::vector<float> planes(4 * hits.size(), -1.0f);
    backend->skinPlanes(scene.frameCount, scene.poses.data(), hits.data(), answered.data(),
                        scene.points.data(), kOffset, kDepth, kPlaneReach, planes.data());
    backend->setSides({});
    int wrong = 0;
    int withPlane = 0;
    int sunk = 0;
    int beyond = 0;
    for (int f = 0; f < scene.frameCount; ++f) {
      for (int i = 0; i < vd; ++i) {
        const std::size_t k = static_cast<std::size_t>(f) * vd + i;
        const float* p = &scene.points[3 * k];
        const float* plane = &planes[4 * k];
        const Eigen::Vector3d m(plane[0], plane[1], plane[2]);
        const double s = cubeSignedDistance(p, scene.centres[static_cast<std::size_t>(f)]);
        beyond += s >= kPlaneReach ? 1 : 0;
        const bool expected = answered[k] == 0 &&
                              sides[static_cast<std::size_t>(i)] == kSideOutside &&
                              s > -1.5 * kDepth && s < kPlaneReach;
        bool ok;
        if (expected) {
          ++withPlane;
          const Eigen::Vector3d target =
              cubeResolved(p, scene.centres[static_cast<std::size_t>(f)], kOffset);
          const Eigen::Vector3d normal =
              (target - cubeResolved(p, scene.centres[static_cast<std::size_t>(f)], 0.0)) / kOffset;
          const double w = s < -kDepth ? (1.5 * kDepth + s) / (0.5 * kDepth) : 1.0;
          // The sunk level moves 2 / w^2 as fast as the depth: the distance's tolerance, carried.
          const double level = m.dot(target) - kDepth * (1.0 - w) / w;
          ok = std::fabs(level - plane[3]) <= kResolveRelTol * scale * (1.0 + 2.0 / (w * w)) &&
               (m - normal).norm() <= 1e-5;
          sunk += w < 1.0 ? 1 : 0;
        } else {
          ok = plane[0] == 0.0f && plane[1] == 0.0f && plane[2] == 0.0f && plane[3] == 0.0f;
        }
        if (!ok && ++wrong <= 5) {
          ADD_FAILURE() << "frame " << f << " point " << i << " (" << p[0] << ", " << p[1] << ", "
                        << p[2] << "), signed distance " << s << ": plane (" << plane[0] << ", "
                        << plane[1] << ", " << plane[2] << ", " << plane[3] << "), expected "
                        << (expected ? "one through the resolved point" : "none");
        }
      }
    }
    EXPECT_EQ(wrong, 0) << "of " << scene.frameCount * vd << " points";
    EXPECT_GT(withPlane, vd / 2);
    EXPECT_LT(withPlane, 2 * vd - vd / 4);
    EXPECT_GT(sunk, 20) << "points between depth and 1.5 depth";
    EXPECT_GT(beyond, 100) << "points beyond the planes' reach";
    results.push_back(planes);
  }
  double difference = 0.0;
  for (std::size_t k = 0; k < results[0].size(); ++k) {
    difference =
        std::max(difference, static_cast<double>(std::fabs(results[0][k] - results[1][k])));
  }
  EXPECT_LE(difference, kDeviceVsHostRelTol * scale) << "largest |cl - host| of the planes";
}

TEST_F(CorrectionClTest, ExitFadeRejectsNegativeAndNonFiniteValues) {
  for (ClosestBackend* backend : {hostBackend(), clBackend()}) {
    SCOPED_TRACE(backend->name());
    expectThrows([&] { backend->setExitFade(-0.1f); }, ErrorCode::kInput, "exit fade");
    expectThrows([&] { backend->setExitFade(NAN); }, ErrorCode::kInput, "exit fade");
  }
}

TEST_F(CorrectionClTest, ResolveRejectsNonFiniteInputBadOffsetsAndForeignHits) {
  const CubeScene scene = makeCubeScene();
  const int vd = scene.pointCount;
  const std::vector<SurfaceHit> hits = hostHits(*hostBackend(), scene, scene.points);
  for (ClosestBackend* backend : {hostBackend(), clBackend()}) {
    SCOPED_TRACE(backend->name());
    backend->setSurface(scene.mesh, BindingMask::all(vd));
    std::vector<float> points = scene.points;
    points[3 * (static_cast<std::size_t>(vd) + 17) + 1] = std::nanf("");
    const std::vector<float> before = points;
    expectThrows(
        [&] {
          backend->resolve(2, scene.poses.data(), hits.data(), kOffset, points.data(), nullptr);
        },
        ErrorCode::kNumerical, "frame 1 of the chunk: driven point 17");
    EXPECT_EQ(std::memcmp(points.data(), before.data(), points.size() * sizeof(float)), 0)
        << "a rejected call must not change the points";
    std::vector<float> poses = scene.poses;
    poses[5] = INFINITY;
    points = scene.points;
    expectThrows(
        [&] { backend->resolve(2, poses.data(), hits.data(), kOffset, points.data(), nullptr); },
        ErrorCode::kNumerical, "driver vertex 1");
    expectThrows(
        [&] {
          backend->resolve(2, scene.poses.data(), hits.data(), -0.5f, points.data(), nullptr);
        },
        ErrorCode::kInput, "offset");
    std::vector<SurfaceHit> foreign = hits;
    foreign[3].triangle = 100000;
    expectThrows(
        [&] {
          backend->resolve(2, scene.poses.data(), foreign.data(), kOffset, points.data(), nullptr);
        },
        ErrorCode::kInput, "hit triangle 100000");
  }
}

}  // namespace
}  // namespace drivenshape::testing
