// SPDX-License-Identifier: Apache-2.0
// Local-frame transfer: identity, rigid motion, OpenCL vs host, degenerate frames, bad input.

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include <drivenshape/error.h>

#include "closest.h"

#include "correction_fixture.h"
#include "correction_test_util.h"
#include "test_support.h"

namespace drivenshape::testing {
namespace {

/// The sleeve's rest pose and frames 5 and 30 of the shot (restAndFrames), with host hits.
struct SleeveHits : PosedScene {
  SleeveData sleeve;
  std::vector<SurfaceHit> hits;
};

SleeveHits sleeveHits(ClosestBackend& host) {
  SleeveHits out;
  out.sleeve = loadSleeve({5, 30});
  static_cast<PosedScene&>(out) = restAndFrames(out.sleeve);
  out.hits = closestHits(host, out.mesh, BindingMask::all(out.pointCount), out.frameCount,
                         out.poses.data(), out.points.data());
  return out;
}

TEST_F(CorrectionClTest, TransferToTheSamePoseIsTheIdentity) {
  const SleeveHits data = sleeveHits(*hostBackend());
  const double scale = sceneScale(data.poses.data(), static_cast<int>(data.poses.size() / 3));
  for (ClosestBackend* backend : {hostBackend(), clBackend()}) {
    SCOPED_TRACE(backend->name());
    backend->setSurface(data.sleeve.driver, BindingMask::all(data.sleeve.driven.vertexCount()));
    std::vector<float> out(data.points.size());
    backend->transfer(data.frameCount, data.hits.data(), data.poses.data(), data.poses.data(),
                      data.points.data(), out.data());
    const double error = maxPointError(out, data.points);
    EXPECT_LE(error, kTransferRelTol * scale)
        << "largest |out - in| " << error << ", tolerance " << kTransferRelTol << " x " << scale;
  }
}

TEST_F(CorrectionClTest, RigidMotionOfTheDriverMovesThePointsRigidly) {
  const SleeveHits data = sleeveHits(*hostBackend());
  std::mt19937 rng(testSeed());
  std::normal_distribution<double> normal(0.0, 1.0);
  const Eigen::Matrix3d rotation =
      Eigen::AngleAxisd(2.0, Eigen::Vector3d(normal(rng), normal(rng), normal(rng)).normalized())
          .toRotationMatrix();
  const Eigen::Vector3d translation(3.0, -7.0, 12.0);
  const std::vector<float> moved = rigidlyMoved(data.poses, rotation, translation);
  const std::vector<float> expected = rigidlyMoved(data.points, rotation, translation);
  const double scale = sceneScale(moved.data(), static_cast<int>(moved.size() / 3));
  for (ClosestBackend* backend : {hostBackend(), clBackend()}) {
    SCOPED_TRACE(backend->name());
    backend->setSurface(data.sleeve.driver, BindingMask::all(data.sleeve.driven.vertexCount()));
    std::vector<float> out(data.points.size());
    backend->transfer(data.frameCount, data.hits.data(), data.poses.data(), moved.data(),
                      data.points.data(), out.data());
    const double error = maxPointError(out, expected);
    EXPECT_LE(error, kTransferRelTol * scale)
        << "largest |out - R p - t| " << error << ", tolerance " << kTransferRelTol << " x "
        << scale;
  }
}

TEST_F(CorrectionClTest, OpenClTransferMatchesHostOnADeformingPose) {
  SleeveHits data = sleeveHits(*hostBackend());
  // Transfer every frame's points onto the next frame's pose (a non-rigid change).
  const std::size_t poseSize = data.poses.size() / 3;
  std::vector<float> to(data.poses.begin() + static_cast<long>(poseSize), data.poses.end());
  to.insert(to.end(), data.poses.begin(), data.poses.begin() + static_cast<long>(poseSize));
  std::vector<std::vector<float>> results;
  for (ClosestBackend* backend : {hostBackend(), clBackend()}) {
    backend->setSurface(data.sleeve.driver, BindingMask::all(data.sleeve.driven.vertexCount()));
    std::vector<float> out(data.points.size());
    backend->transfer(data.frameCount, data.hits.data(), data.poses.data(), to.data(),
                      data.points.data(), out.data());
    results.push_back(out);
  }
  const Bounds bounds = computeBounds(data.points.data(), static_cast<int>(data.points.size() / 3));
  expectDeviceMatchesHost(results[0], results[1], bounds.diagonal());
  // The transfer really moved the points (the test is not an identity in disguise).
  EXPECT_GT(maxPointError(results[0], data.points), 1e-3 * bounds.diagonal());
}

TEST_F(CorrectionClTest, DegenerateFramesKeepTheOffsetInWorldAxes) {
  const auto [from, mesh, to, points, hits] = degenerateFrames();
  // Expected: hit 0 and 2 keep the world offset; hit 1 rotates with its frame.
  const std::vector<float> expected = {1.0f, 1.7f, 1.3f, 0.8f, 1.2f, 1.5f, 9.0f, 10.0f, 9.0f};
  for (ClosestBackend* backend : {hostBackend(), clBackend()}) {
    SCOPED_TRACE(backend->name());
    backend->setSurface(mesh, BindingMask::all(3));
    std::vector<float> out(points.size());
    backend->transfer(1, hits.data(), from.data(), to.data(), points.data(), out.data());
    for (std::size_t i = 0; i < out.size(); ++i) {
      ASSERT_TRUE(std::isfinite(out[i]));
    }
    EXPECT_LE(maxPointError(out, expected), kTransferRelTol * 10.0);
  }
}

TEST_F(CorrectionClTest, CorrectIsClosestThenTransfer) {
  SleeveHits data = sleeveHits(*hostBackend());
  const std::size_t poseSize = data.poses.size() / 3;
  std::vector<float> shot(data.poses.begin() + static_cast<long>(poseSize), data.poses.end());
  shot.insert(shot.end(), data.poses.begin(), data.poses.begin() + static_cast<long>(poseSize));
  ClosestBackend& cl = *clBackend();
  cl.setSurface(data.sleeve.driver, BindingMask::all(data.sleeve.driven.vertexCount()));
  std::vector<float> corrected(data.points.size());
  std::vector<SurfaceHit> hits(data.hits.size());
  correct(cl, data.frameCount, data.poses.data(), data.points.data(), shot.data(), corrected.data(),
          hits.data());
  std::vector<float> expected(data.points.size());
  cl.transfer(data.frameCount, hits.data(), data.poses.data(), shot.data(), data.points.data(),
              expected.data());
  EXPECT_EQ(maxPointError(corrected, expected), 0.0);
  // `out` may alias `points`.
  std::vector<float> inPlace = data.points;
  cl.transfer(data.frameCount, hits.data(), data.poses.data(), shot.data(), inPlace.data(),
              inPlace.data());
  EXPECT_EQ(maxPointError(inPlace, expected), 0.0);
}

TEST_F(CorrectionClTest, TransferRejectsNonFiniteInputAndForeignHits) {
  const std::vector<float> pose = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  const Mesh mesh = makeMesh(pose, {{0, 1, 2}});
  const std::vector<float> points = {0.2f, 0.2f, 1.0f};
  std::vector<float> out(3);
  for (ClosestBackend* backend : {hostBackend(), clBackend()}) {
    SCOPED_TRACE(backend->name());
    backend->setSurface(mesh, BindingMask::all(1));
    const std::vector<SurfaceHit> good = {{0, 0.2f, 0.2f, 1.0f}};
    std::vector<float> badPose = pose;
    badPose[4] = std::nanf("");
    try {
      backend->transfer(1, good.data(), pose.data(), badPose.data(), points.data(), out.data());
      ADD_FAILURE() << "NaN pose accepted";
    } catch (const Error& error) {
      EXPECT_EQ(error.code(), ErrorCode::kNumerical);
      EXPECT_NE(std::string(error.what()).find("frame 0 of the chunk"), std::string::npos);
      EXPECT_NE(std::string(error.what()).find("vertex of the 'to' pose 1"), std::string::npos)
          << error.what();
    }
    const std::vector<SurfaceHit> foreign = {{7, 0.2f, 0.2f, 1.0f}};
    try {
      backend->transfer(1, foreign.data(), pose.data(), pose.data(), points.data(), out.data());
      ADD_FAILURE() << "hit on a missing triangle accepted";
    } catch (const Error& error) {
      EXPECT_EQ(error.code(), ErrorCode::kInput);
    }
  }
}

}  // namespace
}  // namespace drivenshape::testing
