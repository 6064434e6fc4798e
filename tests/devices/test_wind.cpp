// SPDX-License-Identifier: Apache-2.0
// Procedural wind (kernels/wind.cl, kernels/layer_types.h, src/devices/host/host_wind.cpp):
// amplitude 0 changes nothing, OpenCL agrees with the host reference, runs and chunkings agree,
// the motion is continuous in time within the analytic bound, and the clearance limit keeps
// cloth out of the body.

#include <drivenshape/error.h>
#include <drivenshape/layers.h>

#include "cl_backends.h"

#include <algorithm>
#include <cmath>

#include "io_test_util.h"
#include "layers_test_util.h"
#include "test_support.h"

namespace drivenshape::testing {
namespace {

constexpr int kWindColumns = 40;
constexpr int kWindRows = 25;
constexpr double kFps = 24.0;

class WindTest : public OpenClTest {
 protected:
  void SetUp() override {
    OpenClTest::SetUp();
    mMesh = gridMesh(kWindColumns, kWindRows, kWindColumns / 2);
    LayerOptions options;  // only for the centred rest positions and the weight tables
    options.windAmplitude = 1.0;
    options.windWeight = "group:right";
    options.windFalloff = 3;
    auto host = makeHostLayers();
    LayerStack stack(loadLayers(options, mMesh), mMesh, *host);
    mTables.vertexCount = mMesh.vertexCount();
    mTables.windWeights = stack.windWeights();
    const Bounds bounds = computeBounds(mMesh.positions.data(), mMesh.vertexCount());
    const Eigen::Vector3f centre = 0.5f * (bounds.min + bounds.max);
    for (int v = 0; v < mMesh.vertexCount(); ++v) {
      for (int a = 0; a < 3; ++a) {
        mTables.rest.push_back(mMesh.positions(v, a) - centre[a]);
      }
    }
    mSettings.amplitude = 0.05f;
    mSettings.frequency = 2.0f;
    mSettings.direction = {0.6, 0.0, 0.8};
    mSettings.speed = 1.5;
    mSettings.octaves = 4;
    mSettings.seed = testSeed();
    mSettings.framesPerSecond = kFps;
  }

  /// `frames` of the rest positions (frame-major) with the wind of `settings` on `backend`.
  std::vector<float> blow(LayerBackend& backend, const std::vector<int>& frames,
                          const WindSettings& settings, const float* clearance = nullptr) {
    backend.upload(mTables);
    std::vector<float> positions;
    for (std::size_t f = 0; f < frames.size(); ++f) {
      for (int v = 0; v < mMesh.vertexCount(); ++v) {
        for (int a = 0; a < 3; ++a) {
          positions.push_back(mMesh.positions(v, a));
        }
      }
    }
    backend.wind(static_cast<int>(frames.size()), frames.data(), settings, clearance,
                 positions.data());
    return positions;
  }

  /// Displacement of vertex v in frame slot f of a blow() result.
  Eigen::Vector3d displacement(const std::vector<float>& positions, std::size_t f, int v) const {
    const std::size_t at = f * 3 * static_cast<std::size_t>(mMesh.vertexCount()) + 3 * v;
    return Eigen::Vector3d(positions[at] - static_cast<double>(mMesh.positions(v, 0)),
                           positions[at + 1] - static_cast<double>(mMesh.positions(v, 1)),
                           positions[at + 2] - static_cast<double>(mMesh.positions(v, 2)));
  }

  Mesh mMesh;
  LayerTables mTables;
  WindSettings mSettings;
};

std::vector<int> frameRun(int first, int count) {
  std::vector<int> frames(static_cast<std::size_t>(count));
  for (int i = 0; i < count; ++i) {
    frames[static_cast<std::size_t>(i)] = first + i;
  }
  return frames;
}

TEST_F(WindTest, AmplitudeZeroChangesNothingBitwise) {
  WindSettings still = mSettings;
  still.amplitude = 0.0f;
  const std::vector<int> frames = frameRun(1001, 4);
  std::vector<float> rest;
  for (std::size_t f = 0; f < frames.size(); ++f) {
    for (int v = 0; v < mMesh.vertexCount(); ++v) {
      for (int a = 0; a < 3; ++a) {
        rest.push_back(mMesh.positions(v, a));
      }
    }
  }
  // Plant signed zeros too: adding a zero displacement would turn -0 into +0.
  auto host = makeHostLayers();
  auto cl = makeClLayers(context(), device(), queue());
  for (LayerBackend* backend : {host.get(), cl.get()}) {
    backend->upload(mTables);
    std::vector<float> positions = rest;
    positions[0] = -0.0f;
    std::vector<float> expected = positions;
    backend->wind(static_cast<int>(frames.size()), frames.data(), still, nullptr, positions.data());
    for (std::size_t i = 0; i < positions.size(); ++i) {
      ASSERT_TRUE(sameBits(positions[i], expected[i])) << backend->name() << " float " << i;
    }
  }
  // The stack with amplitude 0 is empty: the bake skips it.
  LayerOptions options;
  options.windAmplitude = 0.0;
  EXPECT_TRUE(LayerStack(loadLayers(options, mMesh), mMesh, *host).empty());
}

TEST_F(WindTest, OpenClMatchesTheHostReference) {
  auto host = makeHostLayers();
  auto cl = makeClLayers(context(), device(), queue());
  std::vector<int> frames = frameRun(1001, 6);
  frames.push_back(48000);  // long shots: the advection offset wraps the lattice period
  frames.push_back(-12);
  std::vector<float> clearance(frames.size() * static_cast<std::size_t>(mMesh.vertexCount()));
  std::mt19937 random(testSeed());
  std::uniform_real_distribution<float> gap(0.0f, 0.1f);
  for (float& c : clearance) {
    c = gap(random);
  }
  const float* noLimit = nullptr;
  const float* withLimit = clearance.data();
  for (const float* limit : {noLimit, withLimit}) {
    const std::vector<float> a = blow(*host, frames, mSettings, limit);
    const std::vector<float> b = blow(*cl, frames, mSettings, limit);
    // The displacements agree to kWindDeviceVsHostRelTol of the amplitude; adding them to
    // positions 100 units from the origin rounds to the position's ulp, which a tiny difference
    // can tip either way.
    double worst = 0.0;
    for (std::size_t i = 0; i < a.size(); ++i) {
      const double tolerance = kWindDeviceVsHostRelTol * mSettings.amplitude +
                               std::ldexp(std::abs(static_cast<double>(a[i])), -23);
      worst = std::max(worst, std::abs(a[i] - b[i]) / tolerance);
      ASSERT_LE(std::abs(a[i] - b[i]), tolerance)
          << "float " << i << (limit ? " (clearance limit)" : "");
    }
    std::printf("[ wind     ] OpenCL vs host: worst error %.3g of the tolerance%s\n", worst,
                limit ? " (clearance limit)" : "");
  }
}

TEST_F(WindTest, DeterministicAcrossRunsAndChunks) {
  auto host = makeHostLayers();
  auto cl = makeClLayers(context(), device(), queue());
  const std::vector<int> frames = {1001, 1002, 1010, 977, 5000};
  for (LayerBackend* backend : {host.get(), cl.get()}) {
    const std::vector<float> all = blow(*backend, frames, mSettings);
    EXPECT_EQ(blow(*backend, frames, mSettings), all) << backend->name();
    // Frame by frame, in another order: a pure function of (frame, vertex).
    const std::size_t floats = 3 * static_cast<std::size_t>(mMesh.vertexCount());
    for (std::size_t f = frames.size(); f-- > 0;) {
      const std::vector<float> one = blow(*backend, {frames[f]}, mSettings);
      ASSERT_TRUE(std::equal(one.begin(), one.end(), all.begin() + f * floats))
          << backend->name() << " frame " << frames[f];
    }
  }
  // Another seed is another wind.
  WindSettings other = mSettings;
  other.seed = mSettings.seed + 1;
  EXPECT_NE(blow(*host, frames, other), blow(*host, frames, mSettings));
}

TEST_F(WindTest, ContinuousInTimeWithinTheAnalyticBound) {
  auto host = makeHostLayers();
  // A gentle gust speed, so the bound per frame is well below the displacement itself: noise
  // drawn afresh each frame (a broken time dependence) would step by ~|d| and fail.
  WindSettings gentle = mSettings;
  gentle.speed = 0.1;
  // Around the start of a shot, and a long way in, where the offsets wrap the lattice period.
  for (int first : {1001, 47990}) {
    const std::vector<int> frames = frameRun(first, 12);
    const std::vector<float> positions = blow(*host, frames, gentle);
    const double dt = 1.0 / kFps;
    const double bound = windRateBound(gentle) * dt;
    ASSERT_LT(bound, 0.25 * gentle.amplitude);
    const double rounding = 2.0 * kWindRoundingRelTol * mSettings.amplitude;
    double largestStep = 0.0;
    double largestDisplacement = 0.0;
    for (std::size_t f = 1; f < frames.size(); ++f) {
      for (int v = 0; v < mMesh.vertexCount(); ++v) {
        const double w = mTables.windWeights[static_cast<std::size_t>(v)];
        const Eigen::Vector3d now = displacement(positions, f, v);
        const Eigen::Vector3d before = displacement(positions, f - 1, v);
        const double step = (now - before).norm();
        ASSERT_LE(step, w * bound + rounding)
            << "vertex " << v << " frames " << frames[f - 1] << "-" << frames[f] << ", bound "
            << w * bound << " + rounding " << rounding;
        // The displacement never exceeds sqrt(3) amplitude (each channel <= amplitude).
        ASSERT_LE(now.norm(), std::sqrt(3.0) * w * mSettings.amplitude + rounding);
        largestStep = std::max(largestStep, step);
        largestDisplacement = std::max(largestDisplacement, now.norm());
      }
    }
    // The wind does blow and does move: a test that nothing moves would pass trivially.
    EXPECT_GT(largestDisplacement, 0.2 * mSettings.amplitude);
    EXPECT_GT(largestStep, 0.02 * bound) << "bound " << bound;
    std::printf("[ wind     ] from frame %d: largest step %.3g of bound %.3g, largest |d| %.3g\n",
                first, largestStep, bound, largestDisplacement);
  }
}

TEST_F(WindTest, ClearanceLimitKeepsClothOutOfTheBody) {
  // The body: the plane z = 0 under the grid; every vertex sits at height h in (0, 0.05], so its
  // clearance (unsigned distance to the surface) is h. A strong wind (amplitude 1, 20x the
  // clearance) pointing mostly down must never push a vertex to z <= 0.
  std::vector<float> heights(static_cast<std::size_t>(mMesh.vertexCount()));
  std::mt19937 random(testSeed());
  std::uniform_real_distribution<float> height(1e-4f, 0.05f);
  for (float& h : heights) {
    h = height(random);
  }
  WindSettings strong = mSettings;
  strong.amplitude = 1.0f;
  strong.direction = {0.0, 0.0, -1.0};
  const std::vector<int> frames = frameRun(1001, 8);
  const std::size_t count = static_cast<std::size_t>(mMesh.vertexCount());
  std::vector<float> clearance(frames.size() * count);
  for (std::size_t f = 0; f < frames.size(); ++f) {
    std::copy(heights.begin(), heights.end(), clearance.begin() + f * count);
  }
  auto host = makeHostLayers();
  auto cl = makeClLayers(context(), device(), queue());
  for (LayerBackend* backend : {host.get(), cl.get()}) {
    backend->upload(mTables);
    std::vector<float> positions;
    for (std::size_t f = 0; f < frames.size(); ++f) {
      for (std::size_t v = 0; v < count; ++v) {
        positions.push_back(mMesh.positions(static_cast<int>(v), 0));
        positions.push_back(mMesh.positions(static_cast<int>(v), 1));
        positions.push_back(heights[v]);
      }
    }
    const std::vector<float> before = positions;
    backend->wind(static_cast<int>(frames.size()), frames.data(), strong, clearance.data(),
                  positions.data());
    int moved = 0;
    for (std::size_t i = 0; i < frames.size() * count; ++i) {
      const double dx = positions[3 * i] - before[3 * i];
      const double dy = positions[3 * i + 1] - before[3 * i + 1];
      const double dz = positions[3 * i + 2] - before[3 * i + 2];
      const double length = std::sqrt(dx * dx + dy * dy + dz * dz);
      const double c = clearance[i];
      ASSERT_LT(length, c) << backend->name() << " vertex " << i % count;
      ASSERT_GT(positions[3 * i + 2], 0.0f)
          << backend->name() << " vertex " << i % count << " crossed the surface";
      moved += length > 0.5 * c ? 1 : 0;
    }
    EXPECT_GT(moved, 0) << "the limit should let strong wind use most of the clearance";
  }

  // Far from the body the limit is nearly the identity: with 100x clearance, within 1e-4.
  std::vector<float> far(frames.size() * count, 100.0f * mSettings.amplitude * 1.8f);
  const std::vector<float> free = blow(*host, frames, mSettings);
  const std::vector<float> limited = blow(*host, frames, mSettings, far.data());
  for (std::size_t f = 0; f < frames.size(); ++f) {
    for (int v = 0; v < mMesh.vertexCount(); ++v) {
      const Eigen::Vector3d a = displacement(free, f, v);
      const Eigen::Vector3d b = displacement(limited, f, v);
      ASSERT_LE((a - b).norm(), 1e-4 * a.norm() + kWindRoundingRelTol * mSettings.amplitude)
          << "vertex " << v;
    }
  }
}

TEST_F(WindTest, CallsBeforeUploadOrWithoutWeightsAreInternalErrors) {
  auto host = makeHostLayers();
  std::vector<float> positions(3 * static_cast<std::size_t>(mMesh.vertexCount()));
  const int frame = 1;
  EXPECT_EQ(catchError([&] { host->wind(1, &frame, mSettings, nullptr, positions.data()); }).code(),
            ErrorCode::kInternal);
  host->upload(mTables);
  EXPECT_EQ(catchError([&] { host->mix(1, positions.data(), positions.data()); }).code(),
            ErrorCode::kInternal);
}

}  // namespace
}  // namespace drivenshape::testing
