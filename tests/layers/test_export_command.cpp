// Tests for apps/export_command.cpp (`drivenshape export`): PC2 guides read back identically
// with the header fields Blender's importer checks, the first-frame OBJ keeps the rest mesh's
// faces and UVs, EXR inputs, and the errors it must give.

#include "export_command.h"

#include <cstring>

#include <drivenshape/error.h>
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

  error = code({"--cache", sleeveCache(), "--frames", "2-4", "--pc2", dir.file("no/such/a.pc2")});
  EXPECT_EQ(error.code(), ErrorCode::kOutput);
  EXPECT_TRUE(listFolder(dir.path()).empty());
}

}  // namespace
}  // namespace drivenshape::testing
