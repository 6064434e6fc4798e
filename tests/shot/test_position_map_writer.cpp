// SPDX-License-Identifier: Apache-2.0
// Tests for src/shot/position_map_writer.cpp: batching, the sequence loop over a cache and
// its refusals (vertex count, missing frames, output folder).

#include <drivenshape/position_map.h>
#include <drivenshape/position_map_backend.h>
#include <drivenshape/position_map_sequence.h>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>

#include <filesystem>

#include <drivenshape/error.h>

#include "cl_backends.h"

#include "posmap_test_util.h"
#include "test_support.h"

namespace drivenshape::testing {
namespace {

std::vector<float> readP(const std::string& path) {
  Imf::InputFile file(path.c_str());
  const Imath::Box2i window = file.header().dataWindow();
  const std::size_t width = static_cast<std::size_t>(window.max.x - window.min.x + 1);
  const std::size_t height = static_cast<std::size_t>(window.max.y - window.min.y + 1);
  std::vector<float> xyz(3 * width * height, -1.0f);
  Imf::FrameBuffer frameBuffer;
  const char* names[3] = {"R", "G", "B"};  // the default naming (PositionMapChannels::kRgba)
  for (int a = 0; a < 3; ++a) {
    EXPECT_NE(file.header().channels().findChannel(names[a]), nullptr) << names[a] << " " << path;
    frameBuffer.insert(names[a], Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(xyz.data() + a),
                                            3 * sizeof(float), 3 * sizeof(float) * width));
  }
  file.setFrameBuffer(frameBuffer);
  file.readPixels(window.min.y, window.max.y);
  return xyz;
}

PositionMapOptions smallOptions() {
  PositionMapOptions options;
  options.width = 64;
  options.height = 48;
  options.padding = 2;
  return options;
}

class PositionMapWriterCl : public OpenClTest {};

TEST_F(PositionMapWriterCl, BatchedFramesMatchSingleFramesAndTheHost) {
  const Sleeve sleeve = loadSleeve();
  const std::vector<int> frames{3, 4, 5, 6, 7};
  const std::vector<float> xyz = readSleeveFrames(sleeve, frames);
  TempDir dir;

  PositionMapOptions options = smallOptions();
  options.chunkSize = 2;  // five frames: launches of 2, 2 and 1
  options.threads = 3;
  PositionMapWriter batched(sleeve.mesh, options, makeClPositionMaps(context(), device(), queue()));
  EXPECT_EQ(batched.chunkSize(), 2);
  std::vector<std::string> paths;
  for (int frame : frames) {
    paths.push_back(dir.file("b." + std::to_string(frame) + ".exr"));
  }
  batched.writeFrames(frames, xyz.data(), paths);

  PositionMapWriter single(sleeve.mesh, smallOptions(), makeHostPositionMaps());
  const std::size_t vertexFloats = 3 * static_cast<std::size_t>(sleeve.mesh.vertexCount());
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const std::string path = dir.file("s." + std::to_string(frames[i]) + ".exr");
    single.writeFrame(frames[i], xyz.data() + i * vertexFloats, path);
    const std::vector<float> want = readP(path);
    const std::vector<float> got = readP(paths[i]);
    const double diagonal =
        computeBounds(xyz.data() + i * vertexFloats, sleeve.mesh.vertexCount()).diagonal();
    ASSERT_EQ(want.size(), got.size());
    for (std::size_t k = 0; k < want.size(); ++k) {
      ASSERT_LE(std::abs(want[k] - got[k]), kDeviceVsHostRelTol * diagonal)
          << "frame " << frames[i] << ", float " << k;
    }
  }
  EXPECT_GE(batched.evaluateSeconds(), 0.0);
}

TEST(PositionMapWriter, SequenceWritesEveryFrameFromTheCache) {
  const Sleeve sleeve = loadSleeve();
  TempDir dir;
  PositionMapOptions options = smallOptions();
  options.normals = true;
  options.preview = true;
  PositionMapWriter writer(sleeve.mesh, options, makeHostPositionMaps());
  std::vector<int> done;
  const PositionMapRunResult result =
      writePositionMapSequence(writer, *sleeve.cache, {1, 2, 10}, dir.file("m.####.exr"),
                               [&](int frame, const std::string&) { done.push_back(frame); });
  EXPECT_EQ(result.written, 3);
  EXPECT_EQ(done, (std::vector<int>{1, 2, 10}));
  for (const char* name : {"m.0001.exr", "m.0002.exr", "m.0010.exr", "m.0010.png"}) {
    EXPECT_TRUE(std::filesystem::exists(dir.file(name))) << name;
  }
  // Nothing but the outputs is left behind (no temporary files).
  int files = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir.path())) {
    files += entry.is_regular_file() ? 1 : 0;
  }
  EXPECT_EQ(files, 6);
}

TEST(PositionMapWriter, CacheWithAnotherVertexCountIsRefused) {
  const Sleeve sleeve = loadSleeve();
  const std::string driverCache = dataDir() + "/sleeve/test.driver.pc2";
  const auto driver = openPointCache(driverCache);
  ASSERT_NE(driver->vertexCount(), sleeve.mesh.vertexCount());
  TempDir dir;
  PositionMapWriter writer(sleeve.mesh, smallOptions(), makeHostPositionMaps());
  std::string message;
  EXPECT_EQ(codeOf([&] { writePositionMapSequence(writer, *driver, {1}, dir.file("m.####.exr")); },
                   message),
            ErrorCode::kInput);
  EXPECT_NE(message.find(driverCache), std::string::npos) << message;
  EXPECT_NE(message.find(std::to_string(driver->vertexCount())), std::string::npos) << message;
  EXPECT_NE(message.find("2244"), std::string::npos) << message;
  EXPECT_TRUE(std::filesystem::is_empty(dir.path())) << "nothing written";
}

TEST(PositionMapWriter, MissingFramesAndBadOutputsAreRefusedBeforeWriting) {
  const Sleeve sleeve = loadSleeve();
  TempDir dir;
  PositionMapWriter writer(sleeve.mesh, smallOptions(), makeHostPositionMaps());
  std::string message;
  EXPECT_EQ(codeOf(
                [&] {
                  writePositionMapSequence(writer, *sleeve.cache, {47, 48, 49, 50},
                                           dir.file("m.####.exr"));
                },
                message),
            ErrorCode::kInput);
  EXPECT_NE(message.find("49-50"), std::string::npos) << message;
  EXPECT_EQ(codeOf(
                [&] {
                  writePositionMapSequence(writer, *sleeve.cache, {1}, dir.file("nope/m.####.exr"));
                },
                message),
            ErrorCode::kOutput);
  EXPECT_EQ(codeOf([&] { writePositionMapSequence(writer, *sleeve.cache, {1}, dir.file("m.exr")); },
                   message),
            ErrorCode::kUsage);
  EXPECT_TRUE(std::filesystem::is_empty(dir.path())) << "nothing written";
}

}  // namespace
}  // namespace drivenshape::testing
