// SPDX-License-Identifier: Apache-2.0
// The LayerStack the bake runs (src/pipeline/layer_stack.cpp) and the mix layer on both backends
// (kernels/mix.cl vs src/devices/host/host_mix.cpp): weight 1 reproduces DrivenShape and weight
// 0 the other cache bitwise, the band in between is the float mix; bad inputs give clear errors.

#include <drivenshape/error.h>
#include <drivenshape/layers.h>
#include <drivenshape/point_cache.h>

#include "cl_backends.h"

#include <nlohmann/json.hpp>

#include <cmath>
#include <functional>
#include <limits>

#include "hash.h"
#include "io_test_util.h"
#include "layers_test_util.h"
#include "test_support.h"

namespace drivenshape::testing {
namespace {

constexpr int kStackColumns = 30;
constexpr int kStackRows = 8;
constexpr int kStackSplit = 15;
constexpr int kFirstFrame = 1001;
constexpr int kFrames = 5;

class LayerStackTest : public OpenClTest {
 protected:
  void SetUp() override {
    OpenClTest::SetUp();
    mMesh = gridMesh(kStackColumns, kStackRows, kStackSplit);
    mDriven = jitteredFrames(mMesh, kFrames, 0.02f, testSeed());
    mOther = jitteredFrames(mMesh, kFrames, 0.05f, testSeed() + 1);
    // Values a blend formula would change: -0 where weight 1 keeps DrivenShape (-0 + 0 = +0),
    // NaN in the other cache there (0 * NaN = NaN: a hood simulation need not cover the legs),
    // and -0 in the other cache where weight 0 takes it. Column 0 is deep in "left" (weight 1),
    // the last column deep in "right" (weight 0).
    mDriven[0] = -0.0f;
    mOther[1] = std::numeric_limits<float>::quiet_NaN();
    mOther[3 * (kStackColumns - 1) + 1] = -0.0f;
    for (int f = 0; f < kFrames; ++f) {
      mFrames.push_back(kFirstFrame + f);
    }
    mOtherPath = mDir.file("other.pc2");
    writePc2(mOtherPath, mMesh.vertexCount(), static_cast<float>(kFirstFrame), kFrames,
             mOther.data());
  }

  /// The mix result on `backend` with the left group weighted 1 and `rings` of falloff.
  std::vector<float> mixed(LayerBackend& backend, int rings, std::vector<float>& weights) {
    LayerOptions options;
    options.mixCache = mOtherPath;
    options.mixWeight = "group:left";
    options.mixFalloff = rings;
    LayerStack stack(loadLayers(options, mMesh), mMesh, backend);
    EXPECT_FALSE(stack.empty());
    stack.checkFrames(mFrames);
    std::vector<float> positions = mDriven;
    stack.apply(kFrames, mFrames.data(), positions.data(), nullptr);
    weights = stack.mixWeights();
    return positions;
  }

  void checkMix(const std::vector<float>& positions, const std::vector<float>& weights,
                bool expectBand) {
    const std::size_t count = static_cast<std::size_t>(mMesh.vertexCount());
    int ones = 0;
    int zeros = 0;
    int between = 0;
    for (std::size_t f = 0; f < static_cast<std::size_t>(kFrames); ++f) {
      for (std::size_t v = 0; v < count; ++v) {
        for (std::size_t a = 0; a < 3; ++a) {
          const std::size_t at = f * 3 * count + 3 * v + a;
          const float w = weights[v];
          if (w == 1.0f) {
            ASSERT_TRUE(sameBits(positions[at], mDriven[at])) << "vertex " << v;
            ++ones;
          } else if (w == 0.0f) {
            ASSERT_TRUE(sameBits(positions[at], mOther[at])) << "vertex " << v;
            ++zeros;
          } else {
            const double a0 = mDriven[at];
            const double b0 = mOther[at];
            const double expected = w * a0 + (1.0 - w) * b0;
            const double scale = std::max(std::abs(a0), std::abs(b0));
            ASSERT_LE(std::abs(positions[at] - expected), kMixRelTol * scale)
                << "vertex " << v << " weight " << w << " tolerance " << kMixRelTol;
            ++between;
          }
        }
      }
    }
    EXPECT_GT(ones, 0);
    EXPECT_GT(zeros, 0);
    EXPECT_EQ(between > 0, expectBand);
  }

  TempDir mDir;
  Mesh mMesh;
  std::vector<float> mDriven;
  std::vector<float> mOther;
  std::vector<int> mFrames;
  std::string mOtherPath;
};

TEST_F(LayerStackTest, MixWeightOneIsDrivenShapeAndZeroTheOtherCacheBitwise) {
  auto host = makeHostLayers();
  auto cl = makeClLayers(context(), device(), queue());
  for (int rings : {0, 3}) {
    std::vector<float> hostWeights;
    std::vector<float> clWeights;
    const std::vector<float> hostResult = mixed(*host, rings, hostWeights);
    const std::vector<float> clResult = mixed(*cl, rings, clWeights);
    checkMix(hostResult, hostWeights, rings > 0);
    checkMix(clResult, clWeights, rings > 0);
    // Same float formula on both sides (FP_CONTRACT off in mix.cl).
    for (std::size_t i = 0; i < hostResult.size(); ++i) {
      ASSERT_LE(std::abs(hostResult[i] - clResult[i]), kMixRelTol * std::abs(hostResult[i]))
          << "float " << i;
    }
  }
}

TEST_F(LayerStackTest, EmptyStackChangesNothing) {
  auto host = makeHostLayers();
  LayerOptions options;
  LayerStack stack(loadLayers(options, mMesh), mMesh, *host);
  EXPECT_TRUE(stack.empty());
  EXPECT_EQ(stack.describe(), "{}");
  std::vector<float> positions = mDriven;
  stack.apply(kFrames, mFrames.data(), positions.data(), nullptr);
  for (std::size_t i = 0; i < positions.size(); ++i) {
    ASSERT_TRUE(sameBits(positions[i], mDriven[i]));
  }
}

TEST_F(LayerStackTest, MixCacheOfAnotherVertexCountIsRefused) {
  const Mesh small = gridMesh(4, 4, 2);
  std::vector<float> frames = jitteredFrames(small, 2, 0.0f, 1);
  writePc2(mDir.file("small.pc2"), small.vertexCount(), 1001.0f, 2, frames.data());
  auto host = makeHostLayers();
  LayerOptions options;
  options.mixCache = mDir.file("small.pc2");
  options.mixWeight = "group:left";
  const Error error =
      catchError([&] { LayerStack stack(loadLayers(options, mMesh), mMesh, *host); });
  EXPECT_EQ(error.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(error.what(), "small.pc2"));
  EXPECT_TRUE(contains(error.what(), "has 16 vertices but the driven mesh has 240"));
}

TEST_F(LayerStackTest, MixCacheMissingAFrameIsRefusedBeforeBaking) {
  auto host = makeHostLayers();
  LayerOptions options;
  options.mixCache = mOtherPath;
  options.mixWeight = "group:left";
  LayerStack stack(loadLayers(options, mMesh), mMesh, *host);
  const Error error = catchError([&] { stack.checkFrames({1003, 1010}); });
  EXPECT_EQ(error.code(), ErrorCode::kInput);
  EXPECT_TRUE(
      contains(error.what(), "frame 1010 is missing; the mix cache holds frames 1001-1005"));
}

TEST_F(LayerStackTest, BadSettingsNameTheSetting) {
  auto host = makeHostLayers();
  const auto usage = [&](const std::function<void(LayerOptions&)>& edit, const char* setting) {
    LayerOptions options;
    options.windAmplitude = 0.1;
    edit(options);
    const Error error =
        catchError([&] { LayerStack stack(loadLayers(options, mMesh), mMesh, *host); });
    EXPECT_EQ(error.code(), ErrorCode::kUsage) << setting;
    EXPECT_TRUE(contains(error.what(), setting));
  };
  usage([](LayerOptions& o) { o.windOctaves = 9; }, "the wind octaves 9 must be 1..8");
  usage([](LayerOptions& o) { o.windDirection = {0, 0, 0}; }, "the wind direction");
  usage([](LayerOptions& o) { o.windFrequency = 0; }, "the wind frequency");
  usage([](LayerOptions& o) { o.windSpeed = -1; }, "the wind speed");
  usage([](LayerOptions& o) { o.windAmplitude = -1; }, "the wind amplitude");
  usage([&](LayerOptions& o) { o.mixCache = mOtherPath; }, "needs a mix weight map");
  usage([](LayerOptions& o) { o.mixWeight = "group:left"; }, "needs a mix cache");
  usage(
      [](LayerOptions& o) {
        o.windAmplitude = 0;
        o.windWeight = "group:left";
      },
      "a wind weight map needs a wind amplitude");
}

TEST_F(LayerStackTest, DescribeAndHashRecordTheSettings) {
  auto host = makeHostLayers();
  LayerOptions options;
  options.mixCache = mOtherPath;
  options.mixWeight = "group:left";
  options.windAmplitude = 0.02;
  options.windSeed = 7;
  options.windWeight = "group:right";
  options.windFalloff = 2;
  LayerStack stack(loadLayers(options, mMesh), mMesh, *host);
  const auto json = nlohmann::json::parse(stack.describe());
  EXPECT_EQ(json["mix"]["cache"], mOtherPath);
  EXPECT_EQ(json["mix"]["falloff"], 3);
  EXPECT_EQ(json["wind"]["seed"], 7);
  EXPECT_EQ(json["wind"]["weight"], "group:right");
  EXPECT_DOUBLE_EQ(json["wind"]["amplitude"].get<double>(), 0.02);

  const auto hashOf = [&](const LayerOptions& o) {
    LayerStack s(loadLayers(o, mMesh), mMesh, *host);
    Hasher hasher;
    s.addToHash(hasher);
    return hasher.value();
  };
  const std::uint64_t base = hashOf(options);
  EXPECT_EQ(hashOf(options), base);
  LayerOptions other = options;
  other.windSeed = 8;
  EXPECT_NE(hashOf(other), base);
  other = options;
  other.mixFalloff = 2;
  EXPECT_NE(hashOf(other), base);
  other = options;
  other.windDirection = {0, 1, 0};
  EXPECT_NE(hashOf(other), base);
}

}  // namespace
}  // namespace drivenshape::testing
