// SPDX-License-Identifier: Apache-2.0
// Local-frame encoding and rebuild (the halves of the transfer, for bindings made once):
// round trip, rigid motion, agreement with transfer (degenerate frames included), OpenCL vs
// host, bad input.

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include <drivenshape/error.h>

#include "closest.h"
#include "local_encoding.h"

#include "correction_fixture.h"
#include "correction_test_util.h"
#include "test_support.h"

namespace drivenshape::testing {
namespace {

/// The sleeve with frames 5 and 30 of the shot, and the cloth bound once on the rest pose:
/// host hits of the rest cloth on the rest driver and their local coordinates.
struct Binding {
  SleeveData sleeve;
  std::vector<float> restPose;
  std::vector<float> restPoints;
  std::vector<SurfaceHit> hits;  ///< Vd
  std::vector<float> local;      ///< Vd x 3
};

Binding bindOnRest(ClosestBackend& host) {
  Binding out;
  out.sleeve = loadSleeve({5, 30});
  const Mesh& driver = out.sleeve.driver;
  const Mesh& driven = out.sleeve.driven;
  out.restPose = flatPositions(driver);
  out.restPoints = flatPositions(driven);
  out.hits = closestHits(host, driver, BindingMask::all(driven.vertexCount()), 1,
                         out.restPose.data(), out.restPoints.data());
  out.local.resize(out.restPoints.size());
  encodeLocal(driver, out.restPose.data(), driven.vertexCount(), out.restPoints.data(),
              out.hits.data(), out.local.data());
  return out;
}

/// `copies` copies of one frame block.
std::vector<float> repeat(const std::vector<float>& block, int copies) {
  std::vector<float> out;
  for (int c = 0; c < copies; ++c) {
    out.insert(out.end(), block.begin(), block.end());
  }
  return out;
}

TEST_F(CorrectionClTest, EncodeThenRebuildOnTheSamePoseGivesThePointsBack) {
  const Binding binding = bindOnRest(*hostBackend());
  const int vd = binding.sleeve.driven.vertexCount();
  const double scale = sceneScale(binding.restPose.data(), binding.sleeve.driver.vertexCount(),
                                  binding.restPoints.data(), vd);
  // The local coordinates are not the world positions (the test is not an identity).
  EXPECT_GT(maxPointError(binding.local, binding.restPoints), 1e-2 * scale);
  for (ClosestBackend* backend : {hostBackend(), clBackend()}) {
    SCOPED_TRACE(backend->name());
    backend->setSurface(binding.sleeve.driver, BindingMask::all(vd));
    std::vector<float> out(2 * binding.restPoints.size());
    backend->rebuild(2, binding.hits.data(), repeat(binding.restPose, 2).data(),
                     repeat(binding.local, 2).data(), out.data());
    const double error = maxPointError(out, repeat(binding.restPoints, 2));
    EXPECT_LE(error, kTransferRelTol * scale)
        << "largest |rebuild(encode(p)) - p| " << error << ", tolerance " << kTransferRelTol
        << " x " << scale;
  }
}

TEST_F(CorrectionClTest, RebuildOnARigidlyMovedPoseMovesThePointsRigidly) {
  const Binding binding = bindOnRest(*hostBackend());
  const int vd = binding.sleeve.driven.vertexCount();
  std::mt19937 rng(testSeed());
  std::normal_distribution<double> normal(0.0, 1.0);
  // Three frames, three different rigid motions.
  std::vector<float> poses;
  std::vector<float> expected;
  for (int f = 0; f < 3; ++f) {
    const Eigen::Matrix3d rotation =
        Eigen::AngleAxisd(0.5 + f,
                          Eigen::Vector3d(normal(rng), normal(rng), normal(rng)).normalized())
            .toRotationMatrix();
    const Eigen::Vector3d translation(normal(rng), normal(rng), normal(rng));
    const std::vector<float> pose = rigidlyMoved(binding.restPose, rotation, translation);
    const std::vector<float> points = rigidlyMoved(binding.restPoints, rotation, translation);
    poses.insert(poses.end(), pose.begin(), pose.end());
    expected.insert(expected.end(), points.begin(), points.end());
  }
  const double scale = sceneScale(poses.data(), static_cast<int>(poses.size() / 3), expected.data(),
                                  static_cast<int>(expected.size() / 3));
  for (ClosestBackend* backend : {hostBackend(), clBackend()}) {
    SCOPED_TRACE(backend->name());
    backend->setSurface(binding.sleeve.driver, BindingMask::all(vd));
    std::vector<float> out(expected.size());
    backend->rebuild(3, binding.hits.data(), poses.data(), repeat(binding.local, 3).data(),
                     out.data());
    const double error = maxPointError(out, expected);
    EXPECT_LE(error, kTransferRelTol * scale)
        << "largest |rebuild - (R p + t)| " << error << ", tolerance " << kTransferRelTol << " x "
        << scale;
  }
}

TEST_F(CorrectionClTest, OpenClRebuildMatchesHostOnDeformingPoses) {
  const Binding binding = bindOnRest(*hostBackend());
  const int vd = binding.sleeve.driven.vertexCount();
  const std::vector<float>& poses = binding.sleeve.poses;  // frames 5 and 30
  const std::vector<float> local = repeat(binding.local, 2);
  std::vector<std::vector<float>> results;
  for (ClosestBackend* backend : {hostBackend(), clBackend()}) {
    backend->setSurface(binding.sleeve.driver, BindingMask::all(vd));
    std::vector<float> out(local.size());
    backend->rebuild(2, binding.hits.data(), poses.data(), local.data(), out.data());
    results.push_back(out);
  }
  const Bounds bounds = computeBounds(results[0].data(), static_cast<int>(results[0].size() / 3));
  expectDeviceMatchesHost(results[0], results[1], bounds.diagonal());
  // The driver moved the cloth (not an identity in disguise).
  EXPECT_GT(maxPointError(results[0], repeat(binding.restPoints, 2)), 1e-3 * bounds.diagonal());
  // `out` may alias `local`.
  std::vector<float> inPlace = local;
  clBackend()->rebuild(2, binding.hits.data(), poses.data(), inPlace.data(), inPlace.data());
  EXPECT_EQ(maxPointError(inPlace, results[1]), 0.0);
}

TEST_F(CorrectionClTest, EncodeThenRebuildIsTransferIncludingDegenerateFrames) {
  // Transfer is the reference: rebuild(encode on from, to) must equal it.
  const auto [from, mesh, to, points, hits] = degenerateFrames();
  std::vector<float> local(points.size());
  encodeLocal(mesh, from.data(), 3, points.data(), hits.data(), local.data());
  for (ClosestBackend* backend : {hostBackend(), clBackend()}) {
    SCOPED_TRACE(backend->name());
    backend->setSurface(mesh, BindingMask::all(3));
    std::vector<float> expected(points.size());
    backend->transfer(1, hits.data(), from.data(), to.data(), points.data(), expected.data());
    std::vector<float> out(points.size());
    backend->rebuild(1, hits.data(), to.data(), local.data(), out.data());
    EXPECT_LE(maxPointError(out, expected), kTransferRelTol * 10.0);
  }
}

TEST_F(CorrectionClTest, RebuildAndEncodeRejectNonFiniteInputAndForeignHits) {
  const std::vector<float> pose = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  const Mesh mesh = makeMesh(pose, {{0, 1, 2}});
  const std::vector<float> local = {0.2f, 0.2f, 1.0f};
  const std::vector<SurfaceHit> good = {{0, 0.2f, 0.2f, 1.0f}};
  const std::vector<SurfaceHit> foreign = {{7, 0.2f, 0.2f, 1.0f}};
  std::vector<float> out(3);
  std::vector<float> badPose = pose;
  badPose[4] = std::nanf("");
  std::vector<float> badLocal = local;
  badLocal[2] = INFINITY;
  for (ClosestBackend* backend : {hostBackend(), clBackend()}) {
    SCOPED_TRACE(backend->name());
    backend->setSurface(mesh, BindingMask::all(1));
    expectThrows(
        [&] { backend->rebuild(1, good.data(), badPose.data(), local.data(), out.data()); },
        ErrorCode::kNumerical, "vertex of the 'to' pose 1");
    expectThrows(
        [&] { backend->rebuild(1, good.data(), pose.data(), badLocal.data(), out.data()); },
        ErrorCode::kNumerical, "driven point 0");
    expectThrows(
        [&] { backend->rebuild(1, foreign.data(), pose.data(), local.data(), out.data()); },
        ErrorCode::kInput, "hit triangle 7");
  }
  expectThrows([&] { encodeLocal(mesh, badPose.data(), 1, local.data(), good.data(), out.data()); },
               ErrorCode::kNumerical, "driver vertex 1");
  expectThrows([&] { encodeLocal(mesh, pose.data(), 1, local.data(), foreign.data(), out.data()); },
               ErrorCode::kInput, "hit triangle 7");
}

}  // namespace
}  // namespace drivenshape::testing
