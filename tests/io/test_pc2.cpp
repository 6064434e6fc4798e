// SPDX-License-Identifier: Apache-2.0
#include <drivenshape/point_cache.h>

#include <cstring>
#include <filesystem>
#include <random>

#include "io_test_util.h"
#include "test_support.h"

namespace drivenshape::testing {
namespace {

// An independent PC2 encoder/decoder, byte by byte, so the tests do not trust the code
// under test for the layout.
void putU32(std::vector<unsigned char>& out, std::uint32_t value) {
  for (int i = 0; i < 4; ++i) {
    out.push_back(static_cast<unsigned char>(value >> (8 * i)));
  }
}
void putI32(std::vector<unsigned char>& out, std::int32_t value) {
  std::uint32_t bits;
  std::memcpy(&bits, &value, 4);
  putU32(out, bits);
}
void putF32(std::vector<unsigned char>& out, float value) {
  std::uint32_t bits;
  std::memcpy(&bits, &value, 4);
  putU32(out, bits);
}
std::uint32_t getU32(const std::vector<unsigned char>& in, std::size_t at) {
  return static_cast<std::uint32_t>(in[at]) | (static_cast<std::uint32_t>(in[at + 1]) << 8) |
         (static_cast<std::uint32_t>(in[at + 2]) << 16) |
         (static_cast<std::uint32_t>(in[at + 3]) << 24);
}
float getF32(const std::vector<unsigned char>& in, std::size_t at) {
  const std::uint32_t bits = getU32(in, at);
  float value;
  std::memcpy(&value, &bits, 4);
  return value;
}

std::vector<unsigned char> pc2Bytes(int points, float start, float rate, int samples,
                                    const std::vector<float>& xyz, int version = 1) {
  const char magic[12] = "POINTCACHE2";
  std::vector<unsigned char> out(magic, magic + 12);
  out.reserve(32 + 4 * xyz.size());
  putI32(out, version);
  putI32(out, points);
  putF32(out, start);
  putF32(out, rate);
  putI32(out, samples);
  for (float value : xyz) {
    putF32(out, value);
  }
  return out;
}

std::vector<float> randomFloats(std::size_t count, std::uint32_t seed) {
  std::mt19937 random(seed);
  std::uniform_real_distribution<float> value(-3.0f, 3.0f);
  std::vector<float> out(count);
  for (float& v : out) {
    v = value(random);
  }
  return out;
}

void expectBitwiseEqual(const float* a, const float* b, std::size_t count) {
  for (std::size_t i = 0; i < count; ++i) {
    ASSERT_LE(std::abs(a[i] - b[i]), kFileRoundTripTol) << "float " << i;
    ASSERT_EQ(std::memcmp(a + i, b + i, 4), 0) << "float " << i << " differs in its bits";
  }
}

TEST(Pc2, ReadsAHandWrittenFile) {
  TempDir dir;
  const std::string path = dir.file("hand.pc2");
  constexpr int kPoints = 5;
  constexpr int kSamples = 4;
  const std::vector<float> xyz = randomFloats(kPoints * 3 * kSamples, testSeed());
  writeBytes(path, pc2Bytes(kPoints, 1.0f, 1.0f, kSamples, xyz));
  const auto cache = openPc2(path);
  EXPECT_EQ(cache->vertexCount(), kPoints);
  EXPECT_EQ(cache->frames(), (std::vector<int>{1, 2, 3, 4}));
  EXPECT_EQ(cache->path(), path);
  std::vector<float> frame(kPoints * 3);
  for (int f = 1; f <= kSamples; ++f) {
    cache->readFrame(f, frame.data());
    expectBitwiseEqual(frame.data(), xyz.data() + (f - 1) * kPoints * 3, frame.size());
  }
  // Frames read in any order; readFrames stacks them frame-major.
  const std::vector<float> stacked = readFrames(*cache, {3, 1});
  ASSERT_EQ(stacked.size(), 2u * kPoints * 3);
  expectBitwiseEqual(stacked.data(), xyz.data() + 2 * kPoints * 3, kPoints * 3);
  expectBitwiseEqual(stacked.data() + kPoints * 3, xyz.data(), kPoints * 3);
}

TEST(Pc2, WriteThenReadIsBitwiseExact) {
  TempDir dir;
  const std::string path = dir.file("baked.pc2");
  constexpr int kPoints = 37;
  constexpr int kFrames = 6;
  std::vector<float> xyz = randomFloats(kPoints * 3 * kFrames, testSeed() + 1);
  xyz[5] = -0.0f;
  xyz[6] = 1.0e-42f;  // a denormal survives too
  writePc2(path, kPoints, 1001.0f, kFrames, xyz.data());
  EXPECT_EQ(listFolder(dir.path()), std::vector<std::string>{"baked.pc2"});

  // The bytes, decoded by hand.
  const std::vector<unsigned char> bytes = readBytes(path);
  ASSERT_EQ(bytes.size(), 32u + kPoints * 12u * kFrames);
  EXPECT_EQ(std::memcmp(bytes.data(), "POINTCACHE2\0", 12), 0);
  EXPECT_EQ(getU32(bytes, 12), 1u);
  EXPECT_EQ(getU32(bytes, 16), static_cast<std::uint32_t>(kPoints));
  EXPECT_EQ(getF32(bytes, 20), 1001.0f);
  EXPECT_EQ(getF32(bytes, 24), 1.0f);
  EXPECT_EQ(getU32(bytes, 28), static_cast<std::uint32_t>(kFrames));
  for (std::size_t i = 0; i < xyz.size(); ++i) {
    const float value = getF32(bytes, 32 + 4 * i);
    ASSERT_EQ(std::memcmp(&value, &xyz[i], 4), 0) << "float " << i;
  }

  const auto cache = openPointCache(path);
  EXPECT_EQ(cache->vertexCount(), kPoints);
  EXPECT_EQ(cache->frames(), (std::vector<int>{1001, 1002, 1003, 1004, 1005, 1006}));
  EXPECT_TRUE(cache->hasFrame(1006));
  EXPECT_FALSE(cache->hasFrame(1000));
  const std::vector<float> all = readFrames(*cache, cache->frames());
  expectBitwiseEqual(all.data(), xyz.data(), xyz.size());
}

TEST(Pc2, WrittenSampleRateIsInTheHeaderAndReadBack) {
  TempDir dir;
  const std::string path = dir.file("every_other.pc2");
  constexpr int kPoints = 4;
  constexpr int kFrames = 3;
  const std::vector<float> xyz = randomFloats(kPoints * 3 * kFrames, testSeed() + 2);
  writePc2(path, kPoints, 1001.0f, kFrames, xyz.data(), 2.0f);
  const std::vector<unsigned char> bytes = readBytes(path);
  EXPECT_EQ(getF32(bytes, 20), 1001.0f);
  EXPECT_EQ(getF32(bytes, 24), 2.0f);
  EXPECT_EQ(getU32(bytes, 28), static_cast<std::uint32_t>(kFrames));
  const auto cache = openPointCache(path);
  EXPECT_EQ(cache->frames(), (std::vector<int>{1001, 1003, 1005}));
  std::vector<float> frame(kPoints * 3);
  cache->readFrame(1005, frame.data());
  expectBitwiseEqual(frame.data(), xyz.data() + 2 * kPoints * 3, frame.size());
  EXPECT_EQ(catchError([&] { writePc2(path, kPoints, 1.0f, kFrames, xyz.data(), 0.0f); }).code(),
            ErrorCode::kUsage);
}

TEST(Pc2, StartFrameAndFractionalSamples) {
  TempDir dir;
  const std::string path = dir.file("half.pc2");
  constexpr int kPoints = 2;
  // Samples at 10, 10.5, 11, 11.5, 12: only the whole frames are readable.
  const std::vector<float> xyz = randomFloats(kPoints * 3 * 5, testSeed() + 2);
  writeBytes(path, pc2Bytes(kPoints, 10.0f, 0.5f, 5, xyz));
  const auto cache = openPc2(path);
  EXPECT_EQ(cache->frames(), (std::vector<int>{10, 11, 12}));
  EXPECT_FALSE(cache->hasFrame(13));
  std::vector<float> frame(kPoints * 3);
  cache->readFrame(11, frame.data());
  expectBitwiseEqual(frame.data(), xyz.data() + 2 * kPoints * 3, frame.size());

  const std::string negative = dir.file("negative.pc2");
  writeBytes(negative, pc2Bytes(kPoints, -2.0f, 1.0f, 3, randomFloats(kPoints * 9, 7)));
  EXPECT_EQ(openPc2(negative)->frames(), (std::vector<int>{-2, -1, 0}));

  // A rate float32 cannot hold (1/3 is stored as 0.33333334): every third sample from 1001 is
  // still a whole frame (docs/conventions.md), the ones between are not.
  const std::string third = dir.file("third.pc2");
  const std::vector<float> thirds = randomFloats(kPoints * 3 * 31, testSeed() + 3);
  writeBytes(third, pc2Bytes(kPoints, 1001.0f, 1.0f / 3.0f, 31, thirds));
  const auto thirdCache = openPc2(third);
  EXPECT_EQ(thirdCache->frames(),
            (std::vector<int>{1001, 1002, 1003, 1004, 1005, 1006, 1007, 1008, 1009, 1010, 1011}));
  thirdCache->readFrame(1010, frame.data());
  expectBitwiseEqual(frame.data(), thirds.data() + 27 * kPoints * 3, frame.size());
}

TEST(Pc2, FrameOutsideTheCacheNamesFileFrameAndRange) {
  TempDir dir;
  const std::string path = dir.file("short.pc2");
  const std::vector<float> xyz = randomFloats(4 * 3 * 3, 3);
  writePc2(path, 4, 1.0f, 3, xyz.data());
  const auto cache = openPc2(path);
  std::vector<float> frame(12);
  const Error error = catchError([&] { cache->readFrame(99, frame.data()); });
  EXPECT_EQ(error.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(error.what(), path));
  EXPECT_TRUE(contains(error.what(), "99"));
  EXPECT_TRUE(contains(error.what(), "1-3"));
}

TEST(Pc2, TruncatedFileNamesFileBytesAndWholeFrames) {
  TempDir dir;
  const std::string path = dir.file("cut.pc2");
  constexpr int kPoints = 10;
  const std::vector<float> xyz = randomFloats(kPoints * 3 * 4, 4);
  writePc2(path, kPoints, 1.0f, 4, xyz.data());
  // Two whole frames and half of the third.
  const std::uintmax_t cut = 32 + 2 * kPoints * 12 + kPoints * 6;
  std::filesystem::resize_file(path, cut);
  const Error error = catchError([&] { openPc2(path); });
  EXPECT_EQ(error.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(error.what(), path));
  EXPECT_TRUE(contains(error.what(), std::to_string(32 + 4 * kPoints * 12)));  // expected
  EXPECT_TRUE(contains(error.what(), std::to_string(cut)));                    // actual
  EXPECT_TRUE(contains(error.what(), "2 whole frames"));

  std::filesystem::resize_file(path, 20);
  EXPECT_EQ(catchError([&] { openPc2(path); }).code(), ErrorCode::kInput);
}

TEST(Pc2, HeaderChecks) {
  TempDir dir;
  const std::vector<float> xyz = randomFloats(3 * 2, 5);
  const auto expectRefused = [&](const std::string& name, std::vector<unsigned char> bytes) {
    SCOPED_TRACE(name);
    const std::string path = dir.file(name);
    writeBytes(path, bytes);
    const Error error = catchError([&] { openPc2(path); });
    EXPECT_EQ(error.code(), ErrorCode::kInput);
    EXPECT_TRUE(contains(error.what(), path));
  };
  std::vector<unsigned char> badMagic = pc2Bytes(1, 1.0f, 1.0f, 2, xyz);
  badMagic[0] = 'Q';
  expectRefused("magic.pc2", badMagic);
  expectRefused("version.pc2", pc2Bytes(1, 1.0f, 1.0f, 2, xyz, 2));
  expectRefused("points.pc2", pc2Bytes(0, 1.0f, 1.0f, 2, {}));
  expectRefused("samples.pc2", pc2Bytes(1, 1.0f, 1.0f, -1, {}));
  expectRefused("rate.pc2", pc2Bytes(1, 1.0f, 0.0f, 2, xyz));
  expectRefused("long.pc2", pc2Bytes(1, 1.0f, 1.0f, 1, xyz));  // one sample too many
  expectRefused("empty.pc2", {});

  const Error missing = catchError([&] { openPc2(dir.file("missing.pc2")); });
  EXPECT_EQ(missing.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(missing.what(), dir.file("missing.pc2")));

  // Zero samples is a valid (empty) cache.
  writeBytes(dir.file("none.pc2"), pc2Bytes(3, 1.0f, 1.0f, 0, {}));
  EXPECT_TRUE(openPc2(dir.file("none.pc2"))->frames().empty());
}

TEST(Pc2, SleeveTrainingDriverCache) {
  const std::string path = dataDir() + "/sleeve/train.driver.pc2";
  const auto cache = openPointCache(path);
  EXPECT_EQ(cache->vertexCount(), 2146);
  std::vector<int> expected;
  for (int f = 1; f <= 61; ++f) {
    expected.push_back(f);
  }
  EXPECT_EQ(cache->frames(), expected);
  // Frame 61 against the file's last 2146 * 12 bytes, decoded by hand.
  const std::vector<unsigned char> bytes = readBytes(path);
  std::vector<float> frame(2146 * 3);
  cache->readFrame(61, frame.data());
  const std::size_t offset = 32 + 60u * 2146 * 12;
  for (std::size_t i = 0; i < frame.size(); i += 97) {
    EXPECT_EQ(frame[i], getF32(bytes, offset + 4 * i)) << "float " << i;
  }
}

TEST(Pc2, SpecCaseAndKind) {
  TempDir dir;
  const std::vector<float> xyz = randomFloats(6, 6);
  writePc2(dir.file("UPPER.PC2"), 2, 1.0f, 1, xyz.data());
  EXPECT_EQ(openPointCache(dir.file("UPPER.PC2"))->vertexCount(), 2);
  const Error error = catchError([&] { openPointCache(dir.file("mesh.obj")); });
  EXPECT_EQ(error.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(error.what(), "neither a .pc2 file nor an EXR sequence pattern"));
  EXPECT_TRUE(contains(error.what(), "mesh.obj"));
}

TEST(Pc2, WriteIntoMissingFolderLeavesNothing) {
  TempDir dir;
  const std::vector<float> xyz = randomFloats(6, 8);
  const Error error =
      catchError([&] { writePc2(dir.file("gone/out.pc2"), 2, 1.0f, 1, xyz.data()); });
  EXPECT_EQ(error.code(), ErrorCode::kOutput);
  EXPECT_TRUE(listFolder(dir.path()).empty());
}

}  // namespace
}  // namespace drivenshape::testing
