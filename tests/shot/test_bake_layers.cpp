// SPDX-License-Identifier: Apache-2.0
// Layers inside the bake (docs/commands.md, "Layering"): the mix and the wind run after the
// correction, on the device of the bake, and are recorded in the settings hash, the report
// and the EXR header. The layer maths is tested in test_layers; these tests check the wiring.

#include <drivenshape/bake.h>

#include <gtest/gtest.h>

#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>

#include <drivenshape/layers.h>

#include "bake_test_util.h"
#include "test_support.h"

namespace drivenshape {
namespace {

using testing::readBake;
using testing::sample;
using testing::sampleDatabase;
using testing::TempDir;

const std::vector<int> kFrames = {1, 2, 3, 5, 8, 13};

/// A weight map (JSON array) with `value` on every driven vertex of the sample.
std::string writeConstantMap(const TempDir& dir, const std::string& name, double value) {
  nlohmann::json weights = nlohmann::json::array();
  for (int v = 0; v < sampleDatabase().drivenVertexCount(); ++v) {
    weights.push_back(value);
  }
  const std::string path = dir.file(name);
  std::ofstream(path) << weights.dump();
  return path;
}

class BakeLayersTest : public testing::BakeClTest {
 protected:
  /// Bakes kFrames with `layers` on the OpenCL device; returns the result.
  BakeResult bakeWith(const LayerOptions& layers, const std::string& pattern) {
    const testing::Backends backends = clBackends();
    Device& view = backends.view();
    BakeOptions options;
    options.frames = kFrames;
    options.outputPattern = pattern;
    options.layers = layers;
    const auto driver = openPointCache(sample("test.driver.pc2"));
    return bake(sampleDatabase(), *driver, view, options);
  }
};

TEST_F(BakeLayersTest, MixWeightZeroWritesTheOtherCacheAndOneTheBake) {
  TempDir dir;
  const BakeResult plain = bakeWith({}, dir.file("plain.####.exr"));
  // The other cache: the simulated truth of the sample shot.
  LayerOptions layers;
  layers.mixCache = sample("test.driven.pc2");
  layers.mixWeight = writeConstantMap(dir, "zero.json", 0.0);
  const BakeResult other = bakeWith(layers, dir.file("other.####.exr"));
  layers.mixWeight = writeConstantMap(dir, "one.json", 1.0);
  const BakeResult same = bakeWith(layers, dir.file("same.####.exr"));

  EXPECT_EQ(readBake(dir.file("other.####.exr"), kFrames),
            readBake(sample("test.driven.pc2"), kFrames));
  EXPECT_EQ(readBake(dir.file("same.####.exr"), kFrames),
            readBake(dir.file("plain.####.exr"), kFrames));
  // Layers change the settings hash (so --skip-existing never keeps a plain output), and the
  // header says what ran.
  EXPECT_NE(other.settingsHash, plain.settingsHash);
  EXPECT_NE(other.settingsHash, same.settingsHash);
  const ExrPointCacheInfo info = readPointCacheExrInfo(dir.file("other.0005.exr"));
  ASSERT_EQ(info.stringAttributes.count("dsLayers"), 1u);
  const nlohmann::json described = nlohmann::json::parse(info.stringAttributes.at("dsLayers"));
  EXPECT_TRUE(described.contains("mix")) << info.stringAttributes.at("dsLayers");
  EXPECT_EQ(readPointCacheExrInfo(dir.file("plain.0005.exr")).stringAttributes.count("dsLayers"),
            0u);
}

TEST_F(BakeLayersTest, MixCacheWithNanWhereItIsTakenIsAnInputErrorNamingTheVertex) {
  TempDir dir;
  const int vd = sampleDatabase().drivenVertexCount();
  std::vector<float> other = readBake(sample("test.driven.pc2"), {1, 2, 3});
  other[3 * vd + 3 * 17 + 1] = std::numeric_limits<float>::quiet_NaN();  // frame 2, vertex 17
  writePc2(dir.file("other.pc2"), vd, 1.0f, 3, other.data());
  LayerOptions layers;
  layers.mixCache = dir.file("other.pc2");
  layers.mixWeight = writeConstantMap(dir, "zero.json", 0.0);
  const testing::Backends backends = clBackends();
  Device& view = backends.view();
  BakeOptions options;
  options.frames = {1, 2, 3};
  options.outputPattern = dir.file("out.####.exr");
  options.layers = layers;
  const auto driver = openPointCache(sample("test.driver.pc2"));
  testing::expectThrows([&] { bake(sampleDatabase(), *driver, view, options); }, ErrorCode::kInput,
                        "frame 2 vertex 17");
}

TEST_F(BakeLayersTest, WindMovesTheClothBoundedByItsAmplitudeAndKeepsItOutOfTheBody) {
  TempDir dir;
  const BakeResult plain = bakeWith({}, dir.file("plain.####.exr"));
  LayerOptions layers;
  layers.windAmplitude = 0.01;
  layers.windFrequency = 4.0;
  const BakeResult windy = bakeWith(layers, dir.file("windy.####.exr"));
  const std::vector<float> a = readBake(dir.file("plain.####.exr"), kFrames);
  const std::vector<float> b = readBake(dir.file("windy.####.exr"), kFrames);
  ASSERT_EQ(a.size(), b.size());
  double largest = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    largest = std::max(largest, std::abs(double(a[i]) - b[i]));
  }
  // Wind displaces every axis by at most the amplitude, and does displace.
  EXPECT_GT(largest, 0.0);
  EXPECT_LE(largest, layers.windAmplitude * (1 + testing::kWindRoundingRelTol));
  EXPECT_NE(windy.settingsHash, plain.settingsHash);
  // The clearance limit keeps the cloth where the resolution left it: outside the driver.
  for (const FrameRecord& record : windy.frames) {
    EXPECT_EQ(record.insideAfter, 0) << "frame " << record.frame;
  }
}

}  // namespace
}  // namespace drivenshape
