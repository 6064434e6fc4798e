// SPDX-License-Identifier: Apache-2.0
// Tests for apps/posmap_command.cpp (`drivenshape posmap`): end to end on the bundled sleeve,
// OpenCL against the host path, and the flags it must refuse.

#include "posmap_command.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfIntAttribute.h>

#include <filesystem>

#include <drivenshape/error.h>
#include <drivenshape/position_map.h>

#include "posmap_test_util.h"
#include "test_support.h"

namespace drivenshape::testing {
namespace {

std::vector<float> readChannel(const std::string& path, const char* name) {
  Imf::InputFile file(path.c_str());
  const Imath::Box2i window = file.header().dataWindow();
  const int width = window.max.x - window.min.x + 1;
  const int height = window.max.y - window.min.y + 1;
  std::vector<float> values(static_cast<std::size_t>(width) * height, -1.0f);
  Imf::FrameBuffer frameBuffer;
  frameBuffer.insert(name, Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(values.data()),
                                      sizeof(float), sizeof(float) * width));
  file.setFrameBuffer(frameBuffer);
  file.readPixels(window.min.y, window.max.y);
  return values;
}

std::vector<std::string> baseArgs(const std::string& out) {
  return {"--mesh",    dataDir() + "/sleeve/driven_rest.obj",
          "--cache",   dataDir() + "/sleeve/test.driven.pc2",
          "--frames",  "2-4",
          "--res",     "64x40",
          "--padding", "2",
          "-o",        out,
          "--quiet"};
}

std::vector<std::string> with(std::vector<std::string> args, const std::vector<std::string>& more) {
  args.insert(args.end(), more.begin(), more.end());
  return args;
}

ErrorCode codeOf(const std::vector<std::string>& args, std::string& message) {
  try {
    cli::runPosmap(args);
  } catch (const Error& error) {
    message = error.what();
    return error.code();
  }
  message.clear();
  return ErrorCode::kInternal;  // nothing thrown: the caller's EXPECT fails on the code
}

class PosmapCommand : public OpenClTest {};

TEST_F(PosmapCommand, WritesMapsOnOpenClThatMatchTheHostPath) {
  TempDir dir;
  ASSERT_EQ(cli::runPosmap({"--help"}), 0);
  std::filesystem::create_directories(dir.file("cl"));
  std::filesystem::create_directories(dir.file("host"));
  ASSERT_EQ(cli::runPosmap(with(baseArgs(dir.file("host/m.####.exr")),
                                {"--device", "host", "--normals", "--preview"})),
            0);
  const std::string deviceName = device().getInfo<CL_DEVICE_NAME>();
  ASSERT_EQ(cli::runPosmap(
                with(baseArgs(dir.file("cl/m.$F4.exr")), {"--device", deviceName, "--half-normals",
                                                          "--compression", "piz", "--chunk", "2"})),
            0);
  const auto cache = openPointCache(dataDir() + "/sleeve/test.driven.pc2");
  std::vector<float> xyz(3 * cache->vertexCount());
  for (int frame = 2; frame <= 4; ++frame) {
    const std::string name = "m.000" + std::to_string(frame);
    const std::string host = dir.file("host/" + name + ".exr");
    const std::string cl = dir.file("cl/" + name + ".exr");
    ASSERT_TRUE(std::filesystem::exists(dir.file("host/" + name + ".png")));
    Imf::InputFile file(cl.c_str());
    EXPECT_EQ(file.header().typedAttribute<Imf::IntAttribute>("dsFrame").value(), frame);
    EXPECT_NE(file.header().channels().findChannel("N.R"), nullptr);
    cache->readFrame(frame, xyz.data());
    const double diagonal = computeBounds(xyz.data(), cache->vertexCount()).diagonal();
    for (const char* channel : {"R", "G", "B", "A"}) {
      const std::vector<float> want = readChannel(host, channel);
      const std::vector<float> got = readChannel(cl, channel);
      ASSERT_EQ(want.size(), 64u * 40u);
      for (std::size_t i = 0; i < want.size(); ++i) {
        ASSERT_LE(std::abs(want[i] - got[i]), kDeviceVsHostRelTol * diagonal)
            << channel << " texel " << i << " of frame " << frame;
      }
    }
  }
}

TEST(PosmapCommandChannels, LegacyWritesTheFormerNamesWithTheSameValues) {
  TempDir dir;
  std::filesystem::create_directories(dir.file("rgba"));
  std::filesystem::create_directories(dir.file("legacy"));
  ASSERT_EQ(cli::runPosmap(
                with(baseArgs(dir.file("rgba/m.####.exr")), {"--device", "host", "--normals"})),
            0);
  ASSERT_EQ(cli::runPosmap(with(baseArgs(dir.file("legacy/m.####.exr")),
                                {"--device", "host", "--normals", "--channels", "legacy"})),
            0);
  const std::vector<std::pair<const char*, const char*>> pairs = {
      {"R", "P.X"},   {"G", "P.Y"},   {"B", "P.Z"},  {"A", "A"},
      {"N.R", "N.X"}, {"N.G", "N.Y"}, {"N.B", "N.Z"}};
  for (int frame = 2; frame <= 4; ++frame) {
    const std::string name = "m.000" + std::to_string(frame) + ".exr";
    Imf::InputFile rgba(dir.file("rgba/" + name).c_str());
    Imf::InputFile legacy(dir.file("legacy/" + name).c_str());
    for (const auto& [now, before] : pairs) {
      ASSERT_NE(rgba.header().channels().findChannel(now), nullptr) << now;
      ASSERT_NE(legacy.header().channels().findChannel(before), nullptr) << before;
      EXPECT_EQ(rgba.header().channels().findChannel(before) == nullptr || now == before, true)
          << before << " must not be in the default naming";
      EXPECT_EQ(readChannel(dir.file("rgba/" + name), now),
                readChannel(dir.file("legacy/" + name), before))
          << now << " vs " << before << ", frame " << frame;
    }
    EXPECT_EQ(legacy.header().channels().findChannel("R"), nullptr);
    EXPECT_EQ(readPositionMapExrInfo(dir.file("legacy/" + name)).channels,
              PositionMapChannels::kLegacy);
    EXPECT_EQ(readPositionMapExrInfo(dir.file("rgba/" + name)).channels,
              PositionMapChannels::kRgba);
  }
  std::string message;
  EXPECT_EQ(codeOf(with(baseArgs(dir.file("x/m.####.exr")), {"--channels", "xyz"}), message),
            ErrorCode::kUsage);
  EXPECT_NE(message.find("--channels 'xyz'"), std::string::npos) << message;
}

TEST(PosmapCommandInput, BadResolutionsAreUsageErrors) {
  TempDir dir;
  std::string message;
  for (const char* res : {"0", "0x64", "16385", "100000x100000", "big"}) {
    std::vector<std::string> args = baseArgs(dir.file("m.####.exr"));
    args[7] = res;
    EXPECT_EQ(codeOf(with(args, {"--device", "host"}), message), ErrorCode::kUsage) << res;
    EXPECT_NE(message.find("--res"), std::string::npos) << message;
  }
  EXPECT_EQ(codeOf(with(baseArgs(dir.file("m.####.exr")), {"--padding", "-1"}), message),
            ErrorCode::kUsage);
  EXPECT_EQ(codeOf(with(baseArgs(dir.file("m.####.exr")), {"--padding", "1000"}), message),
            ErrorCode::kUsage);
  EXPECT_NE(message.find("--padding"), std::string::npos) << message;
  EXPECT_EQ(codeOf(with(baseArgs(dir.file("m.####.exr")), {"--compression", "dwaa"}), message),
            ErrorCode::kUsage);
  EXPECT_EQ(codeOf(baseArgs(dir.file("m.exr")), message), ErrorCode::kUsage);
  EXPECT_TRUE(std::filesystem::is_empty(dir.path()));
}

TEST(PosmapCommandInput, MismatchedCacheAndMeshWithoutUvsAreInputErrors) {
  TempDir dir;
  std::string message;
  std::vector<std::string> args = baseArgs(dir.file("m.####.exr"));
  args[3] = dataDir() + "/sleeve/test.driver.pc2";
  EXPECT_EQ(codeOf(with(args, {"--device", "host"}), message), ErrorCode::kInput);
  EXPECT_NE(message.find("test.driver.pc2"), std::string::npos) << message;
  EXPECT_NE(message.find("2244"), std::string::npos) << message;

  // The same sleeve written without UVs.
  Mesh mesh = readObj(dataDir() + "/sleeve/driven_rest.obj");
  mesh.uvs.clear();
  mesh.faceUvs.clear();
  writeObj(dir.file("bare.obj"), mesh);
  args = baseArgs(dir.file("m.####.exr"));
  args[1] = dir.file("bare.obj");
  EXPECT_EQ(codeOf(with(args, {"--device", "host"}), message), ErrorCode::kInput);
  EXPECT_NE(message.find("bare.obj: the mesh has no UVs"), std::string::npos) << message;
}

}  // namespace
}  // namespace drivenshape::testing
