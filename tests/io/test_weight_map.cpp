// SPDX-License-Identifier: Apache-2.0
// Weight maps (src/io/weight_map.cpp): the three forms, their errors, and the edge-ring
// falloff (monotone across a boundary, exact far from it).

#include <drivenshape/error.h>
#include <drivenshape/layers.h>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <OpenEXR/ImfOutputFile.h>

#include <cmath>
#include <limits>

#include "io_test_util.h"
#include "layers_test_util.h"
#include "test_support.h"

namespace drivenshape::testing {
namespace {

constexpr int kColumns = 24;
constexpr int kRows = 9;
constexpr int kSplit = 12;  // faces with left column < 12 are "left": vertices of columns 0..12

/// Writes a one-channel EXR by hand (not through writeWeightMapExr), to plant bad values.
void writeRawWeightExr(const std::string& path, const std::vector<float>& values, int width,
                       int vertexCount, const char* channel = "W") {
  const int height = (static_cast<int>(values.size()) + width - 1) / width;
  std::vector<float> pixels(static_cast<std::size_t>(width * height), 0.0f);
  std::copy(values.begin(), values.end(), pixels.begin());
  Imf::Header header(width, height);
  header.channels().insert(channel, Imf::Channel(Imf::FLOAT));
  header.insert("dsVertexCount", Imf::IntAttribute(vertexCount));
  Imf::FrameBuffer frameBuffer;
  frameBuffer.insert(channel, Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(pixels.data()),
                                         sizeof(float), sizeof(float) * width));
  Imf::OutputFile file(path.c_str(), header);
  file.setFrameBuffer(frameBuffer);
  file.writePixels(height);
}

TEST(WeightMap, JsonArrayAndObjectForms) {
  TempDir dir;
  const Mesh mesh = gridMesh(3, 2, 1);
  writeTextFile(dir.file("a.json"), "[0, 1, 0.25, 0.5, 1.0, 0.125]");
  writeTextFile(dir.file("b.json"),
                "{\"comment\": \"waist\", \"weights\": [0, 1, 0.25, 0.5, 1.0, 0.125]}");
  const std::vector<float> expected = {0.0f, 1.0f, 0.25f, 0.5f, 1.0f, 0.125f};
  EXPECT_EQ(readWeightMap(dir.file("a.json"), mesh), expected);
  EXPECT_EQ(readWeightMap(dir.file("b.json"), mesh), expected);
}

TEST(WeightMap, JsonErrorsNameFileIndexAndValue) {
  TempDir dir;
  const Mesh mesh = gridMesh(3, 2, 1);  // 6 vertices
  writeTextFile(dir.file("short.json"), "[0, 1, 0.5]");
  Error error = catchError([&] { readWeightMap(dir.file("short.json"), mesh, "--mix-weight"); });
  EXPECT_EQ(error.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(error.what(), "short.json"));
  EXPECT_TRUE(contains(error.what(), "has 3 weights but the driven mesh has 6 vertices"));
  EXPECT_TRUE(contains(error.what(), "--mix-weight"));

  writeTextFile(dir.file("range.json"), "[0, 1, 1.5, 0, 0, 0]");
  error = catchError([&] { readWeightMap(dir.file("range.json"), mesh); });
  EXPECT_EQ(error.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(error.what(), "weight of vertex 2 is 1.5, outside [0, 1]"));

  writeTextFile(dir.file("negative.json"), "[0, 1, 0, 0, -0.25, 0]");
  error = catchError([&] { readWeightMap(dir.file("negative.json"), mesh); });
  EXPECT_TRUE(contains(error.what(), "weight of vertex 4 is -0.25, outside [0, 1]"));

  writeTextFile(dir.file("null.json"), "[0, 1, 0, null, 0, 0]");
  error = catchError([&] { readWeightMap(dir.file("null.json"), mesh); });
  EXPECT_EQ(error.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(error.what(), "weight of vertex 3 is null, not a number"));

  writeTextFile(dir.file("bad.json"), "[0, 1,");
  error = catchError([&] { readWeightMap(dir.file("bad.json"), mesh); });
  EXPECT_TRUE(contains(error.what(), "not valid JSON"));

  error = catchError([&] { readWeightMap(dir.file("missing.json"), mesh); });
  EXPECT_EQ(error.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(error.what(), "missing.json"));

  error = catchError([&] { readWeightMap(dir.file("weights.txt"), mesh, "--wind-weight"); });
  EXPECT_EQ(error.code(), ErrorCode::kUsage);
  EXPECT_TRUE(contains(error.what(), "--wind-weight '"));
}

TEST(WeightMap, ExrRoundTripIsExactAndChecksLengthAndValues) {
  TempDir dir;
  const Mesh mesh = gridMesh(kColumns, kRows, kSplit);
  std::vector<float> weights(static_cast<std::size_t>(mesh.vertexCount()));
  std::mt19937 random(testSeed());
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  for (float& w : weights) {
    w = unit(random);
  }
  weights[7] = 1.0f;
  weights[8] = 0.0f;
  writeWeightMapExr(dir.file("w.exr"), weights, 50);  // 216 vertices, 5 rows, padded
  const std::vector<float> back = readWeightMap(dir.file("w.exr"), mesh);
  ASSERT_EQ(back.size(), weights.size());
  for (std::size_t i = 0; i < weights.size(); ++i) {
    ASSERT_TRUE(sameBits(back[i], weights[i])) << "vertex " << i;
  }

  // The only channel besides A is accepted whatever its name.
  writeRawWeightExr(dir.file("y.exr"), weights, 64, mesh.vertexCount(), "Y");
  EXPECT_EQ(readWeightMap(dir.file("y.exr"), mesh), weights);

  const Mesh other = gridMesh(5, 5, 2);
  Error error = catchError([&] { readWeightMap(dir.file("w.exr"), other); });
  EXPECT_EQ(error.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(error.what(), "has 216 weights but the driven mesh has 25 vertices"));

  std::vector<float> bad = weights;
  bad[100] = std::numeric_limits<float>::quiet_NaN();
  writeRawWeightExr(dir.file("nan.exr"), bad, 64, mesh.vertexCount());
  error = catchError([&] { readWeightMap(dir.file("nan.exr"), mesh); });
  EXPECT_EQ(error.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(error.what(), "nan.exr"));
  EXPECT_TRUE(contains(error.what(), "weight of vertex 100 is NaN"));

  bad[100] = 2.0f;
  writeRawWeightExr(dir.file("big.exr"), bad, 64, mesh.vertexCount());
  error = catchError([&] { readWeightMap(dir.file("big.exr"), mesh); });
  EXPECT_TRUE(contains(error.what(), "weight of vertex 100 is 2, outside [0, 1]"));

  EXPECT_EQ(catchError([&] { writeWeightMapExr(dir.file("out.exr"), bad); }).code(),
            ErrorCode::kInput);
}

TEST(WeightMap, GroupsOfTheDrivenObj) {
  const Mesh mesh = gridMesh(kColumns, kRows, kSplit);
  const std::vector<float> left = readWeightMap("group:left", mesh);
  const std::vector<float> both = readWeightMap("group:left,right", mesh);
  for (int r = 0; r < kRows; ++r) {
    for (int c = 0; c < kColumns; ++c) {
      const std::size_t v = static_cast<std::size_t>(r * kColumns + c);
      EXPECT_EQ(left[v], c <= kSplit ? 1.0f : 0.0f) << "column " << c;
      EXPECT_EQ(both[v], 1.0f);
    }
  }
  const Error error = catchError([&] { readWeightMap("group:left,hood", mesh, "--mix-weight"); });
  EXPECT_EQ(error.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(error.what(), "no group 'hood'; its groups are: left, right"));
  EXPECT_EQ(catchError([&] { readWeightMap("group:", mesh); }).code(), ErrorCode::kUsage);
}

TEST(WeightMapFalloff, MonotoneAcrossTheBoundaryAndExactFarFromIt) {
  const Mesh mesh = gridMesh(kColumns, kRows, kSplit);
  const std::vector<float> hard = readWeightMap("group:left", mesh);
  for (int rings : {1, 2, 3, 5}) {
    const std::vector<float> soft = smoothWeightMap(hard, mesh, rings);
    for (int r = 0; r < kRows; ++r) {
      for (int c = 0; c < kColumns; ++c) {
        const std::size_t v = static_cast<std::size_t>(r * kColumns + c);
        ASSERT_GE(soft[v], 0.0f);
        ASSERT_LE(soft[v], 1.0f);
        // Columns 0..12 hold 1, 13.. hold 0: more than `rings` edges from the other value,
        // the map is unchanged, bitwise.
        if (c + rings <= kSplit) {
          ASSERT_TRUE(sameBits(soft[v], 1.0f)) << "rings " << rings << " column " << c;
        }
        if (c - rings > kSplit) {
          ASSERT_TRUE(sameBits(soft[v], 0.0f)) << "rings " << rings << " column " << c;
        }
        if (c > 0) {
          // Non-increasing along every row, strictly inside the transition band.
          const float before = soft[v - 1];
          ASSERT_LE(soft[v], before) << "rings " << rings << " row " << r << " column " << c;
          if (c > kSplit - rings + 1 && c <= kSplit + rings) {
            ASSERT_LT(soft[v], before) << "rings " << rings << " row " << r << " column " << c;
          }
        }
      }
    }
  }
  EXPECT_EQ(smoothWeightMap(hard, mesh, 0), hard);
  EXPECT_EQ(catchError([&] { smoothWeightMap(hard, mesh, 65); }).code(), ErrorCode::kUsage);
}

}  // namespace
}  // namespace drivenshape::testing
