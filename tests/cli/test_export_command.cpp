// SPDX-License-Identifier: Apache-2.0
// Tests for apps/export_command.cpp (`drivenshape export`): PC2 guides read back identically
// with the header fields Blender's importer checks (start frame and sample rate exactly), the
// first-frame OBJ keeps the rest mesh's faces and UVs, EXR inputs, --up-axis Y rotates every
// point bit for bit, and the errors it must give.

#include "export_command.h"

#include <cstring>

#include <drivenshape/error.h>
#include <drivenshape/frames.h>
#include <drivenshape/mesh.h>
#include <drivenshape/point_cache.h>

#include "io_test_util.h"
#include "layers_test_util.h"
#include "test_support.h"

namespace drivenshape::testing {
namespace {

std::string sleeveMesh() {
  return dataDir() + "/sleeve/driven_rest.obj";
}
std::string sleeveCache() {
  return dataDir() + "/sleeve/test.driven.pc2";
}

std::uint32_t u32(const std::vector<unsigned char>& bytes, std::size_t at) {
  std::uint32_t value = 0;
  for (int i = 3; i >= 0; --i) {
    value = (value << 8) | bytes[at + static_cast<std::size_t>(i)];
  }
  return value;
}
float f32(const std::vector<unsigned char>& bytes, std::size_t at) {
  const std::uint32_t bits = u32(bytes, at);
  float value;
  std::memcpy(&value, &bits, 4);
  return value;
}

/// The PC2 header as Blender's Mesh Cache importer reads it (io_mesh_pc2 / MOD_meshcache_pc2):
/// signature, version 1, point count equal to the mesh's vertex count, start, rate, samples,
/// and a file size that matches.
void checkBlenderHeader(const std::string& path, int points, float start, float rate, int samples) {
  const std::vector<unsigned char> bytes = readBytes(path);
  ASSERT_GE(bytes.size(), 32u);
  EXPECT_EQ(std::memcmp(bytes.data(), "POINTCACHE2\0", 12), 0);
  EXPECT_EQ(u32(bytes, 12), 1u);
  EXPECT_EQ(u32(bytes, 16), static_cast<std::uint32_t>(points));
  EXPECT_EQ(f32(bytes, 20), start);
  EXPECT_EQ(f32(bytes, 24), rate);
  EXPECT_EQ(u32(bytes, 28), static_cast<std::uint32_t>(samples));
  EXPECT_EQ(bytes.size(), 32u + 12u * static_cast<std::size_t>(points) * samples);
}

void expectSameFrames(const PointCacheReader& a, const PointCacheReader& b,
                      const std::vector<int>& framesA, const std::vector<int>& framesB) {
  ASSERT_EQ(framesA.size(), framesB.size());
  const std::vector<float> x = readFrames(a, framesA);
  const std::vector<float> y = readFrames(b, framesB);
  ASSERT_EQ(x.size(), y.size());
  for (std::size_t i = 0; i < x.size(); ++i) {
    ASSERT_TRUE(sameBits(x[i], y[i])) << "float " << i;
  }
}

TEST(ExportCommand, Pc2FromPc2IsIdenticalWithBlenderHeader) {
  TempDir dir;
  const std::string out = dir.file("guides.pc2");
  ASSERT_EQ(cli::runExport({"--cache", sleeveCache(), "--frames", "2-6", "--pc2", out, "--quiet"}),
            0);
  const auto source = openPointCache(sleeveCache());
  checkBlenderHeader(out, source->vertexCount(), 2.0f, 1.0f, 5);
  const auto written = openPointCache(out);
  EXPECT_EQ(written->frames(), (std::vector<int>{2, 3, 4, 5, 6}));
  expectSameFrames(*source, *written, {2, 3, 4, 5, 6}, {2, 3, 4, 5, 6});
  EXPECT_EQ(listFolder(dir.path()), std::vector<std::string>{"guides.pc2"});

  // Every other frame: the step is the sample rate.
  ASSERT_EQ(cli::runExport({"--cache", sleeveCache(), "--frames", "2-8x2", "--pc2", out}), 0);
  checkBlenderHeader(out, source->vertexCount(), 2.0f, 2.0f, 4);
  expectSameFrames(*source, *openPointCache(out), {2, 4, 6, 8}, {2, 4, 6, 8});
}

TEST(ExportCommand, FirstFrameObjKeepsTheRestMeshTopologyAndUvs) {
  TempDir dir;
  const std::string obj = dir.file("drape.obj");
  ASSERT_EQ(cli::runExport({"--cache", sleeveCache(), "--frames", "3-5", "--obj", obj, "--mesh",
                            sleeveMesh()}),
            0);
  const Mesh rest = readObj(sleeveMesh());
  const Mesh drape = readObj(obj);
  EXPECT_EQ(drape.faceStart, rest.faceStart);
  EXPECT_EQ(drape.faceVertices, rest.faceVertices);
  EXPECT_EQ(drape.faceUvs, rest.faceUvs);
  ASSERT_EQ(drape.uvs.size(), rest.uvs.size());
  for (std::size_t i = 0; i < rest.uvs.size(); ++i) {
    ASSERT_EQ(drape.uvs[i], rest.uvs[i]);
  }
  EXPECT_EQ(topologyHash(drape), topologyHash(rest));
  std::vector<float> frame(3 * static_cast<std::size_t>(rest.vertexCount()));
  openPointCache(sleeveCache())->readFrame(3, frame.data());
  for (int v = 0; v < rest.vertexCount(); ++v) {
    for (int a = 0; a < 3; ++a) {
      ASSERT_TRUE(sameBits(drape.positions(v, a), frame[3 * static_cast<std::size_t>(v) + a]))
          << "vertex " << v;
    }
  }
}

TEST(ExportCommand, ExrSequenceInput) {
  TempDir dir;
  const Mesh rest = readObj(sleeveMesh());
  const auto source = openPointCache(sleeveCache());
  std::vector<float> xyz(3 * static_cast<std::size_t>(rest.vertexCount()));
  for (int frame = 1001; frame <= 1003; ++frame) {
    source->readFrame(frame - 999, xyz.data());
    ExrWriteOptions options;
    options.frame = frame;
    options.topologyHash = topologyHash(rest);
    writePointCacheExr(dir.file("bake." + std::to_string(frame) + ".exr"), rest.vertexCount(),
                       xyz.data(), nullptr, options);
  }
  const std::string out = dir.file("out.pc2");
  ASSERT_EQ(cli::runExport({"--cache", dir.file("bake.####.exr"), "--frames", "1001-1003", "--pc2",
                            out, "--obj", dir.file("first.obj"), "--mesh", sleeveMesh()}),
            0);
  checkBlenderHeader(out, rest.vertexCount(), 1001.0f, 1.0f, 3);
  expectSameFrames(*source, *openPointCache(out), {2, 3, 4}, {1001, 1002, 1003});
}

/// `source` rotated from Z up to Y up, (x, y, z) -> (x, z, -y), built on the bit patterns (a
/// sign flip is bit 31), independently of the arithmetic of the code under test.
std::vector<std::uint32_t> zUpToYUpBits(const std::vector<float>& source) {
  std::vector<std::uint32_t> out(source.size());
  for (std::size_t i = 0; i < source.size(); i += 3) {
    std::uint32_t bits[3];
    std::memcpy(bits, source.data() + i, 12);
    out[i] = bits[0];
    out[i + 1] = bits[2];
    out[i + 2] = bits[1] ^ 0x80000000u;
  }
  return out;
}

void expectBits(const std::vector<float>& got, const std::vector<std::uint32_t>& expected,
                const std::string& what) {
  ASSERT_EQ(got.size(), expected.size()) << what;
  for (std::size_t i = 0; i < got.size(); ++i) {
    std::uint32_t bits;
    std::memcpy(&bits, &got[i], 4);
    ASSERT_EQ(bits, expected[i]) << what << ": float " << i << "; tolerance: bitwise";
  }
}

TEST(ExportCommand, UpAxisYRotatesPc2AndObjPointsBitForBit) {
  TempDir dir;
  const std::string pc2 = dir.file("y_up.pc2");
  const std::string obj = dir.file("y_up.obj");
  ASSERT_EQ(cli::runExport({"--cache", sleeveCache(), "--frames", "3-9x3", "--pc2", pc2, "--obj",
                            obj, "--mesh", sleeveMesh(), "--up-axis", "Y", "--quiet"}),
            0);
  const auto source = openPointCache(sleeveCache());
  // The header is untouched by the rotation: start 3, rate 3, 3 samples.
  checkBlenderHeader(pc2, source->vertexCount(), 3.0f, 3.0f, 3);
  const auto written = openPointCache(pc2);
  ASSERT_EQ(written->frames(), (std::vector<int>{3, 6, 9}));
  expectBits(readFrames(*written, {3, 6, 9}), zUpToYUpBits(readFrames(*source, {3, 6, 9})),
             "PC2 --up-axis Y");

  // The OBJ's vertices (its first frame), read back from the text: shortest round-trip floats.
  const Mesh drape = readObj(obj);
  const std::vector<float> objPoints(drape.positions.data(),
                                     drape.positions.data() + drape.positions.size());
  expectBits(objPoints, zUpToYUpBits(readFrames(*source, {3})), "OBJ --up-axis Y");
  const Mesh rest = readObj(sleeveMesh());
  EXPECT_EQ(topologyHash(drape), topologyHash(rest));
  EXPECT_EQ(drape.faceUvs, rest.faceUvs);

  // Z (the default, named or not) writes the cache's own points: the same bytes either way.
  const std::string zNamed = dir.file("z_named.pc2");
  const std::string zDefault = dir.file("z_default.pc2");
  ASSERT_EQ(cli::runExport({"--cache", sleeveCache(), "--frames", "3-9x3", "--pc2", zNamed,
                            "--up-axis", "Z", "--quiet"}),
            0);
  ASSERT_EQ(cli::runExport({"--cache", sleeveCache(), "--frames", "3-9x3", "--pc2", zDefault}), 0);
  EXPECT_EQ(readBytes(zNamed), readBytes(zDefault));
  expectSameFrames(*source, *openPointCache(zNamed), {3, 6, 9}, {3, 6, 9});
}

/// A synthetic cache of `frames` frames from `start` (`rate` frames apart), 5 points each,
/// every float distinct; returns its frames flattened.
std::vector<float> writeSyntheticPc2(const std::string& path, float start, int frames, float rate) {
  constexpr int kPoints = 5;
  std::vector<float> xyz(static_cast<std::size_t>(frames) * kPoints * 3);
  for (std::size_t i = 0; i < xyz.size(); ++i) {
    xyz[i] = 0.001f * static_cast<float>(i) - 1.5f;
  }
  writePc2(path, kPoints, start, frames, xyz.data(), rate);
  return xyz;
}

TEST(ExportCommand, Pc2StartFrameAndRateAreExactAndReadBack) {
  // `export --frames 1001-1100x2`: start 1001 and rate 2 in the header, bit for bit, and a
  // reader (ours; Blender's formula is checked in tests/blender) gets the same frames back.
  TempDir dir;
  const std::string shot = dir.file("shot.pc2");
  writeSyntheticPc2(shot, 1001.0f, 100, 1.0f);  // frames 1001-1100
  const std::string out = dir.file("every_other.pc2");
  ASSERT_EQ(cli::runExport({"--cache", shot, "--frames", "1001-1100x2", "--pc2", out}), 0);
  checkBlenderHeader(out, 5, 1001.0f, 2.0f, 50);
  const auto source = openPointCache(shot);
  const auto written = openPointCache(out);
  const std::vector<int> frames = parseFrameRange("1001-1099x2");
  EXPECT_EQ(written->frames(), frames);
  expectSameFrames(*source, *written, frames, frames);

  // A cache with two samples per frame (rate 0.5, as a subframe simulation writes them): its
  // whole frames are the even samples; exported, they become a rate-1 cache of those samples.
  const std::string subframes = dir.file("subframes.pc2");
  const std::vector<float> all = writeSyntheticPc2(subframes, 1001.0f, 21, 0.5f);
  EXPECT_EQ(openPointCache(subframes)->frames(), parseFrameRange("1001-1011"));
  const std::string whole = dir.file("whole.pc2");
  ASSERT_EQ(cli::runExport({"--cache", subframes, "--frames", "1001-1011", "--pc2", whole}), 0);
  checkBlenderHeader(whole, 5, 1001.0f, 1.0f, 11);
  const std::vector<float> got = readFrames(*openPointCache(whole), parseFrameRange("1001-1011"));
  for (int s = 0; s < 11; ++s) {
    for (int k = 0; k < 15; ++k) {
      ASSERT_TRUE(sameBits(got[static_cast<std::size_t>(15 * s + k)],
                           all[static_cast<std::size_t>(15 * 2 * s + k)]))
          << "frame " << 1001 + s;
    }
  }
}

TEST(ExportCommand, BadInputsGiveClearErrors) {
  TempDir dir;
  const auto code = [&](const std::vector<std::string>& args) {
    return catchError([&] { cli::runExport(args); });
  };
  Error error = code({"--cache", sleeveCache(), "--frames", "2-4"});
  EXPECT_EQ(error.code(), ErrorCode::kUsage);
  EXPECT_TRUE(contains(error.what(), "--pc2 OUT.pc2 and/or --obj"));

  error = code({"--cache", sleeveCache(), "--frames", "2-4", "--obj", dir.file("a.obj")});
  EXPECT_EQ(error.code(), ErrorCode::kUsage);
  EXPECT_TRUE(contains(error.what(), "--obj needs --mesh"));

  error = code({"--cache", sleeveCache(), "--frames", "2,3,5", "--pc2", dir.file("a.pc2")});
  EXPECT_EQ(error.code(), ErrorCode::kUsage);
  EXPECT_TRUE(contains(error.what(), "frames 3 and 5 break the step of 1"));

  error = code({"--cache", sleeveCache(), "--frames", "2-4", "--obj", dir.file("a.obj"), "--mesh",
                dataDir() + "/sleeve/driver_rest.obj"});
  EXPECT_EQ(error.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(error.what(), "pass the driven mesh"));

  error = code({"--cache", sleeveCache(), "--frames", "2-100000", "--pc2", dir.file("a.pc2")});
  EXPECT_EQ(error.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(error.what(), "is missing"));

  // --up-axis: Y or Z exactly (USD's spelling); the message names the flag and the value.
  for (const char* bad : {"X", "y", "-Z"}) {
    error = code({"--cache", sleeveCache(), "--frames", "2-4", "--pc2", dir.file("a.pc2"),
                  "--up-axis", bad});
    EXPECT_EQ(error.code(), ErrorCode::kUsage);
    EXPECT_TRUE(contains(error.what(), std::string("--up-axis '") + bad + "'"));
  }

  // PC2 headers hold the start frame as float32: whole frames beyond 2^24 would not survive.
  error =
      code({"--cache", sleeveCache(), "--frames", "16777217-16777218", "--pc2", dir.file("a.pc2")});
  EXPECT_EQ(error.code(), ErrorCode::kUsage);
  EXPECT_TRUE(contains(error.what(), "frame 16777217 cannot be stored exactly"));

  error = code({"--cache", sleeveCache(), "--frames", "2-4", "--pc2", dir.file("no/such/a.pc2")});
  EXPECT_EQ(error.code(), ErrorCode::kOutput);
  EXPECT_TRUE(listFolder(dir.path()).empty());
}

}  // namespace
}  // namespace drivenshape::testing
