// Local-frame encoding and rebuild (the halves of the transfer, for bindings made once):
// round trip, rigid motion, agreement with transfer (degenerate frames included), OpenCL vs
// host, bad input.

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include <drivenshape/correction.h>
#include <drivenshape/error.h>

#include "correction_fixture.h"
#include "correction_test_util.h"
#include "test_support.h"

namespace drivenshape::testing {
namespace {

/// Largest |a_i - b_i| over interleaved xyz points.
double maxPointError(const std::vector<float>& a, const std::vector<float>& b) {
  double worst = 0.0;
  for (std::size_t i = 0; i < a.size(); i += 3) {
    const Eigen::Vector3d d(a[i] - b[i], a[i + 1] - b[i + 1], a[i + 2] - b[i + 2]);
    worst = std::max(worst, d.norm());
  }
  return worst;
}

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
  out.restPose.assign(driver.positions.data(), driver.positions.data() + 3 * driver.vertexCount());
  out.restPoints.assign(driven.positions.data(),
                        driven.positions.data() + 3 * driven.vertexCount());
  host.setSurface(driver, BindingMask::all(driven.vertexCount()));
  out.hits.resize(static_cast<std::size_t>(driven.vertexCount()));
  host.closest(1, out.restPose.data(), out.restPoints.data(), out.hits.data());
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
    for (const std::vector<float>* block : {&binding.restPose, &binding.restPoints}) {
      std::vector<float>& target = block == &binding.restPose ? poses : expected;
      for (std::size_t i = 0; i < block->size(); i += 3) {
        const Eigen::Vector3d p =
            rotation * Eigen::Vector3d((*block)[i], (*block)[i + 1], (*block)[i + 2]) + translation;
        target.insert(target.end(), {static_cast<float>(p.x()), static_cast<float>(p.y()),
                                     static_cast<float>(p.z())});
      }
    }
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
  const double error = maxPointError(results[0], results[1]);
  EXPECT_LE(error, kDeviceVsHostRelTol * bounds.diagonal())
      << "largest |cl - host| " << error << ", tolerance " << kDeviceVsHostRelTol << " x "
      << bounds.diagonal();
  // The driver moved the cloth (not an identity in disguise).
  EXPECT_GT(maxPointError(results[0], repeat(binding.restPoints, 2)), 1e-3 * bounds.diagonal());
  // `out` may alias `local`.
  std::vector<float> inPlace = local;
  clBackend()->rebuild(2, binding.hits.data(), poses.data(), inPlace.data(), inPlace.data());
  EXPECT_EQ(maxPointError(inPlace, results[1]), 0.0);
}

TEST_F(CorrectionClTest, EncodeThenRebuildIsTransferIncludingDegenerateFrames) {
  // Triangle 0 has zero area (a repeated vertex); triangle 1 is regular; triangle 2 collapses
  // to a point on `to`. Transfer is the reference: rebuild(encode on from, to) must equal it.
  const std::vector<float> from = {0, 0, 0, 1, 0, 0, 0, 1, 0, 5, 0, 0, 6, 0, 0};
  const Mesh mesh = makeMesh(from, {{0, 1, 1}, {0, 1, 2}, {3, 4, 4}});
  const std::vector<float> to = {1, 1, 1, 1, 2, 1, 0, 1, 1, 9, 9, 9, 9, 9, 9};
  const std::vector<float> points = {0.5f, 0.2f, 0.3f, 0.2f, 0.2f, 0.5f, 5.5f, 1.0f, 0.0f};
  const std::vector<SurfaceHit> hits = {
      {0, 0.5f, 0.0f, 0.0f}, {1, 0.2f, 0.2f, 0.0f}, {2, 0.5f, 0.0f, 0.0f}};
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
  auto expectThrow = [](ErrorCode code, const std::string& fragment, auto&& call) {
    try {
      call();
      ADD_FAILURE() << "accepted; expected an error with '" << fragment << "'";
    } catch (const Error& error) {
      EXPECT_EQ(error.code(), code) << error.what();
      EXPECT_NE(std::string(error.what()).find(fragment), std::string::npos) << error.what();
    }
  };
  for (ClosestBackend* backend : {hostBackend(), clBackend()}) {
    SCOPED_TRACE(backend->name());
    backend->setSurface(mesh, BindingMask::all(1));
    expectThrow(ErrorCode::kNumerical, "vertex of the 'to' pose 1", [&] {
      backend->rebuild(1, good.data(), badPose.data(), local.data(), out.data());
    });
    expectThrow(ErrorCode::kNumerical, "driven point 0", [&] {
      backend->rebuild(1, good.data(), pose.data(), badLocal.data(), out.data());
    });
    expectThrow(ErrorCode::kInput, "hit triangle 7", [&] {
      backend->rebuild(1, foreign.data(), pose.data(), local.data(), out.data());
    });
  }
  expectThrow(ErrorCode::kNumerical, "driver vertex 1",
              [&] { encodeLocal(mesh, badPose.data(), 1, local.data(), good.data(), out.data()); });
  expectThrow(ErrorCode::kInput, "hit triangle 7",
              [&] { encodeLocal(mesh, pose.data(), 1, local.data(), foreign.data(), out.data()); });
}

}  // namespace
}  // namespace drivenshape::testing
