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
#include <fstream>
#include <iterator>
#include <memory>
#include <set>
#include <string>
#include <vector>

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

/// The sleeve with its UV islands squeezed into part of the square: padded texels and texels
/// beyond the padding, so that padding reaches across the edges of bands.
Sleeve squeezedSleeve() {
  Sleeve sleeve = loadSleeve();
  for (Eigen::Vector2f& uv : sleeve.mesh.uvs) {
    uv = Eigen::Vector2f(0.1f, 0.3f) + 0.6f * uv;
  }
  return sleeve;
}

/// The bytes of the file at `path` (empty when it cannot be read).
std::string slurpFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

/// Names of the regular files in `folder` (temporary files included).
std::set<std::string> filesOf(const std::string& folder) {
  std::set<std::string> names;
  for (const auto& entry : std::filesystem::directory_iterator(folder)) {
    names.insert(entry.path().filename().string());
  }
  return names;
}

/// Writes `frames` of `sleeve` with `options` as `prefix`.<frame>.exr in `dir`; their paths.
std::vector<std::string> writeMaps(const Sleeve& sleeve, const PositionMapOptions& options,
                                   std::unique_ptr<PositionMapBackend> backend, bool banded,
                                   const TempDir& dir, const std::string& prefix) {
  const std::vector<int> frames{3, 4, 5};
  const std::vector<float> xyz = readSleeveFrames(sleeve, frames);
  PositionMapWriter writer(sleeve.mesh, options, std::move(backend));
  EXPECT_EQ(writer.banded(), banded);
  EXPECT_GT(writer.tables().paddedCount, 0);
  std::vector<std::string> paths;
  for (int frame : frames) {
    paths.push_back(dir.file(prefix + "." + std::to_string(frame) + ".exr"));
  }
  writer.writeFrames(frames, xyz.data(), paths);
  return paths;
}

// A map whose tables pass 4 * launchBytes (16384 x 16384 by default) is rasterised, evaluated
// and written a band of rows at a time: the files are the same bytes as those of the whole map,
// for every compression, with normals (FLOAT and HALF) and previews.
TEST(PositionMapWriter, BandedMapsAreTheSameFilesAsWholeOnes) {
  const Sleeve sleeve = squeezedSleeve();
  struct Case {
    ExrCompression compression;
    ZipEncoder encoder;
    bool normals;
    bool halfNormals;
  };
  const std::vector<Case> cases = {{ExrCompression::kZip, ZipEncoder::kLibdeflate, false, false},
                                   {ExrCompression::kZip, ZipEncoder::kOpenExr, true, false},
                                   {ExrCompression::kZips, ZipEncoder::kLibdeflate, true, true},
                                   {ExrCompression::kPiz, ZipEncoder::kLibdeflate, true, false},
                                   {ExrCompression::kNone, ZipEncoder::kLibdeflate, false, false}};
  for (const Case& c : cases) {
    SCOPED_TRACE(std::string(exrCompressionName(c.compression)) + " " + zipEncoderName(c.encoder) +
                 (c.normals ? " normals" : "") + (c.halfNormals ? " half" : ""));
    TempDir dir;
    PositionMapOptions options;
    options.width = 72;
    options.height = 70;  // bands of 16 rows: four and 6 rows
    options.padding = 3;
    options.normals = c.normals;
    options.halfNormals = c.halfNormals;
    options.preview = true;
    options.compression = c.compression;
    options.zipEncoder = c.encoder;
    options.threads = 2;
    const std::vector<std::string> whole =
        writeMaps(sleeve, options, makeHostPositionMaps(), false, dir, "whole");
    options.launchBytes = 1;  // bands of the fewest rows
    const std::vector<std::string> banded =
        writeMaps(sleeve, options, makeHostPositionMaps(), true, dir, "banded");
    for (std::size_t i = 0; i < whole.size(); ++i) {
      EXPECT_EQ(slurpFile(banded[i]), slurpFile(whole[i])) << banded[i];
      EXPECT_EQ(slurpFile(positionMapPreviewPath(banded[i])),
                slurpFile(positionMapPreviewPath(whole[i])));
    }
    EXPECT_EQ(filesOf(dir.path()).size(), 12u) << "no temporary file is left";
  }
}

TEST_F(PositionMapWriterCl, BandedMapsAreTheSameFilesAsWholeOnes) {
  const Sleeve sleeve = squeezedSleeve();
  TempDir dir;
  PositionMapOptions options;
  options.width = 64;
  options.height = 50;
  options.padding = 3;
  options.normals = true;
  const std::vector<std::string> whole = writeMaps(
      sleeve, options, makeClPositionMaps(context(), device(), queue()), false, dir, "whole");
  options.launchBytes = 1;
  const std::vector<std::string> banded = writeMaps(
      sleeve, options, makeClPositionMaps(context(), device(), queue()), true, dir, "banded");
  for (std::size_t i = 0; i < whole.size(); ++i) {
    EXPECT_EQ(slurpFile(banded[i]), slurpFile(whole[i])) << banded[i];
  }
}

// A frame whose file cannot be made does not stop the others of its launch: they are written,
// then its error is thrown, and no temporary file is left.
TEST(PositionMapWriter, AFailedFileLeavesTheOthersOfItsLaunchWritten) {
  const Sleeve sleeve = squeezedSleeve();
  for (const std::size_t launchBytes : {std::size_t{256} << 20, std::size_t{1}}) {
    TempDir dir;
    PositionMapOptions options = smallOptions();
    options.launchBytes = launchBytes;
    PositionMapWriter writer(sleeve.mesh, options, makeHostPositionMaps());
    const std::vector<int> frames{3, 4, 5};
    const std::vector<float> xyz = readSleeveFrames(sleeve, frames);
    const std::vector<std::string> paths{dir.file("a.exr"), dir.file("missing/b.exr"),
                                         dir.file("c.exr")};
    std::string message;
    EXPECT_EQ(codeOf([&] { writer.writeFrames(frames, xyz.data(), paths); }, message),
              ErrorCode::kOutput);
    EXPECT_NE(message.find("missing"), std::string::npos) << message;
    EXPECT_EQ(filesOf(dir.path()), (std::set<std::string>{"a.exr", "c.exr"}));
  }
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
