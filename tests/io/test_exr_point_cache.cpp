// SPDX-License-Identifier: Apache-2.0
#include <drivenshape/point_cache.h>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfRationalAttribute.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenEXR/ImfVecAttribute.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <functional>
#include <limits>
#include <map>
#include <random>

#include <drivenshape/version.h>

#include "io_test_util.h"
#include "test_support.h"

namespace drivenshape::testing {
namespace {

std::vector<float> randomPositions(int vertexCount, std::uint32_t seed) {
  std::mt19937 random(seed);
  std::uniform_real_distribution<float> value(-2.0f, 2.0f);
  std::vector<float> xyz(3 * static_cast<std::size_t>(vertexCount));
  for (float& v : xyz) {
    v = value(random);
  }
  return xyz;
}

void expectBitwiseEqual(const std::vector<float>& a, const std::vector<float>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    ASSERT_LE(std::abs(a[i] - b[i]), kFileRoundTripTol) << "float " << i;
    ASSERT_EQ(std::memcmp(&a[i], &b[i], 4), 0) << "float " << i << " differs in its bits";
  }
}

/// One channel of a whole EXR, read with plain OpenEXR (not the code under test).
std::vector<float> readChannel(const std::string& path, const char* name, int& width, int& height) {
  Imf::InputFile file(path.c_str());
  const Imath::Box2i window = file.header().dataWindow();
  width = window.max.x - window.min.x + 1;
  height = window.max.y - window.min.y + 1;
  std::vector<float> values(static_cast<std::size_t>(width) * height, -1.0f);
  Imf::FrameBuffer frameBuffer;
  frameBuffer.insert(name, Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(values.data()),
                                      sizeof(float), sizeof(float) * width));
  file.setFrameBuffer(frameBuffer);
  file.readPixels(window.min.y, window.max.y);
  return values;
}

std::string hex16(std::uint64_t value) {
  char text[32];
  std::snprintf(text, sizeof(text), "%016llx", static_cast<unsigned long long>(value));
  return text;
}

constexpr int kVertices = 2500;  // not a multiple of the width: the last row is padded
constexpr std::uint64_t kTopology = 0x0123456789abcdefULL;

TEST(ExrPointCache, RoundTripIsBitwiseExactForEveryCompression) {
  TempDir dir;
  const std::vector<float> xyz = randomPositions(kVertices, testSeed());
  for (ExrCompression compression :
       {ExrCompression::kZip, ExrCompression::kNone, ExrCompression::kZips, ExrCompression::kPiz}) {
    SCOPED_TRACE(exrCompressionName(compression));
    const std::string path = dir.file(std::string("c_") + exrCompressionName(compression) + ".exr");
    ExrWriteOptions options;
    options.compression = compression;
    options.frame = 1001;
    options.topologyHash = kTopology;
    writePointCacheExr(path, kVertices, xyz.data(), nullptr, options);
    std::vector<float> back;
    const ExrPointCacheInfo info = readPointCacheExr(path, back, kVertices, kTopology);
    expectBitwiseEqual(back, xyz);
    EXPECT_EQ(info.compression, compression);
    EXPECT_EQ(info.vertexCount, kVertices);
    EXPECT_EQ(info.width, 1024);

    Imf::InputFile raw(path.c_str());
    const Imf::Compression expected[] = {Imf::ZIP_COMPRESSION, Imf::NO_COMPRESSION,
                                         Imf::ZIPS_COMPRESSION, Imf::PIZ_COMPRESSION};
    EXPECT_EQ(raw.header().compression(), expected[static_cast<int>(compression)]);
  }
  EXPECT_EQ(parseExrCompression("zip"), ExrCompression::kZip);
  EXPECT_EQ(parseExrCompression("none"), ExrCompression::kNone);
  EXPECT_EQ(parseExrCompression("ZIPS"), ExrCompression::kZips);
  EXPECT_EQ(parseExrCompression("piz"), ExrCompression::kPiz);
  const Error error = catchError([] { parseExrCompression("dwaa"); });
  EXPECT_EQ(error.code(), ErrorCode::kUsage);
  EXPECT_TRUE(contains(error.what(), "dwaa"));
}

TEST(ExrPointCache, ExtraStringAttributesRoundTrip) {
  TempDir dir;
  const std::vector<float> xyz = randomPositions(kVertices, testSeed());
  ExrWriteOptions options;
  options.topologyHash = kTopology;
  const std::string layers = "{\"wind\":{\"amplitude\":0.02,\"seed\":7}}";
  options.stringAttributes = {{"dsLayers", layers}, {"note", "waistband mixed"}};
  writePointCacheExr(dir.file("a.exr"), kVertices, xyz.data(), nullptr, options);
  const ExrPointCacheInfo info = readPointCacheExrInfo(dir.file("a.exr"));
  EXPECT_EQ(info.stringAttributes, (std::map<std::string, std::string>{
                                       {"dsLayers", layers}, {"note", "waistband mixed"}}));
  Imf::InputFile raw(dir.file("a.exr").c_str());
  const auto* attribute = raw.header().findTypedAttribute<Imf::StringAttribute>("dsLayers");
  ASSERT_NE(attribute, nullptr);
  EXPECT_EQ(attribute->value(), layers);

  for (const std::string& bad :
       {std::string("dsFrame"), std::string("compression"), std::string(32, 'x'), std::string()}) {
    ExrWriteOptions clash = options;
    clash.stringAttributes = {{bad, "v"}};
    const Error error = catchError(
        [&] { writePointCacheExr(dir.file("b.exr"), kVertices, xyz.data(), nullptr, clash); });
    EXPECT_EQ(error.code(), ErrorCode::kUsage) << bad;
    EXPECT_TRUE(contains(error.what(), "reserved")) << bad;
  }
  EXPECT_EQ(listFolder(dir.path()), std::vector<std::string>{"a.exr"});
}

TEST(ExrPointCache, LayoutChannelsAndAttributes) {
  TempDir dir;
  const std::string path = dir.file("cloth.1001.exr");
  const std::vector<float> xyz = randomPositions(kVertices, testSeed() + 1);
  ExrWriteOptions options;
  options.frame = 1001;
  options.topologyHash = kTopology;
  options.settingsHash = 0xfeedULL;
  writePointCacheExr(path, kVertices, xyz.data(), nullptr, options);

  Imf::InputFile file(path.c_str());
  const Imf::Header& header = file.header();
  const Imath::Box2i window = header.dataWindow();
  EXPECT_EQ(window.min, Imath::V2i(0, 0));
  EXPECT_EQ(window.max, Imath::V2i(1023, 2));  // H = ceil(2500 / 1024) = 3
  std::vector<std::string> channels;
  for (auto it = header.channels().begin(); it != header.channels().end(); ++it) {
    channels.push_back(it.name());
    EXPECT_EQ(it.channel().type, Imf::FLOAT) << it.name();
  }
  EXPECT_EQ(channels, (std::vector<std::string>{"A", "P.X", "P.Y", "P.Z"}));

  const auto* count = header.findTypedAttribute<Imf::IntAttribute>("dsVertexCount");
  ASSERT_NE(count, nullptr);
  EXPECT_EQ(count->value(), kVertices);
  const auto* frame = header.findTypedAttribute<Imf::IntAttribute>("dsFrame");
  ASSERT_NE(frame, nullptr);
  EXPECT_EQ(frame->value(), 1001);
  const auto* topology = header.findTypedAttribute<Imf::StringAttribute>("dsTopologyHash");
  ASSERT_NE(topology, nullptr);
  EXPECT_EQ(topology->value(), "0123456789abcdef");
  const auto* settings = header.findTypedAttribute<Imf::StringAttribute>("dsSettingsHash");
  ASSERT_NE(settings, nullptr);
  EXPECT_EQ(settings->value(), "000000000000feed");
  const auto* version = header.findTypedAttribute<Imf::StringAttribute>("dsToolVersion");
  ASSERT_NE(version, nullptr);
  EXPECT_EQ(version->value(), std::string(kVersion));
  const auto* fps = header.findTypedAttribute<Imf::RationalAttribute>("framesPerSecond");
  ASSERT_NE(fps, nullptr);
  EXPECT_EQ(fps->value().n, 24);
  EXPECT_EQ(fps->value().d, 1u);

  Imath::V3f lo(xyz[0], xyz[1], xyz[2]);
  Imath::V3f hi = lo;
  for (int v = 0; v < kVertices; ++v) {
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], xyz[3 * v + k]);
      hi[k] = std::max(hi[k], xyz[3 * v + k]);
    }
  }
  const auto* boundsMin = header.findTypedAttribute<Imf::V3fAttribute>("dsBoundsMin");
  const auto* boundsMax = header.findTypedAttribute<Imf::V3fAttribute>("dsBoundsMax");
  ASSERT_NE(boundsMin, nullptr);
  ASSERT_NE(boundsMax, nullptr);
  EXPECT_EQ(boundsMin->value(), lo);
  EXPECT_EQ(boundsMax->value(), hi);

  // Pixels: vertex v at (v mod W, v div W); A = 1 on vertices, A = 0 and P = 0 on padding.
  int width = 0;
  int height = 0;
  const std::vector<float> a = readChannel(path, "A", width, height);
  const std::vector<float> py = readChannel(path, "P.Y", width, height);
  ASSERT_EQ(width * height, 3072);
  for (int pixel = 0; pixel < width * height; ++pixel) {
    if (pixel < kVertices) {
      ASSERT_EQ(a[pixel], 1.0f) << "pixel " << pixel;
      ASSERT_EQ(py[pixel], xyz[3 * pixel + 1]) << "pixel " << pixel;
    } else {
      ASSERT_EQ(a[pixel], 0.0f) << "padding pixel " << pixel;
      ASSERT_EQ(py[pixel], 0.0f) << "padding pixel " << pixel;
    }
  }
  EXPECT_EQ(py[1 * 1024 + 5], xyz[3 * (1024 + 5) + 1]);

  const ExrPointCacheInfo info = readPointCacheExrInfo(path);
  EXPECT_EQ(info.vertexCount, kVertices);
  EXPECT_EQ(info.frame, 1001);
  EXPECT_EQ(info.width, 1024);
  EXPECT_EQ(info.topologyHash, kTopology);
  EXPECT_EQ(info.settingsHash, 0xfeedULL);
  EXPECT_EQ(info.toolVersion, kVersion);
  EXPECT_EQ(info.framesPerSecond, 24.0);
  EXPECT_EQ(info.bounds.min, Eigen::Vector3f(lo.x, lo.y, lo.z));
  EXPECT_EQ(info.bounds.max, Eigen::Vector3f(hi.x, hi.y, hi.z));
  EXPECT_FALSE(info.hasNormals);
  EXPECT_EQ(info.compression, ExrCompression::kZip);
}

TEST(ExrPointCache, NormalsWidthAndNtscRate) {
  TempDir dir;
  const std::string path = dir.file("n.exr");
  constexpr int kCount = 40;
  const std::vector<float> xyz = randomPositions(kCount, testSeed() + 2);
  const std::vector<float> normals = randomPositions(kCount, testSeed() + 3);
  ExrWriteOptions options;
  options.width = 16;
  options.framesPerSecond = 23.976;
  writePointCacheExr(path, kCount, xyz.data(), normals.data(), options);

  Imf::InputFile file(path.c_str());
  EXPECT_EQ(file.header().dataWindow().max, Imath::V2i(15, 2));
  EXPECT_EQ(file.header().findTypedAttribute<Imf::StringAttribute>("dsSettingsHash"), nullptr);
  const auto* fps = file.header().findTypedAttribute<Imf::RationalAttribute>("framesPerSecond");
  ASSERT_NE(fps, nullptr);
  EXPECT_EQ(fps->value().n, 24000);
  EXPECT_EQ(fps->value().d, 1001u);
  int width = 0;
  int height = 0;
  const char* names[3] = {"N.X", "N.Y", "N.Z"};
  for (int k = 0; k < 3; ++k) {
    const std::vector<float> channel = readChannel(path, names[k], width, height);
    for (int v = 0; v < kCount; ++v) {
      ASSERT_EQ(channel[v], normals[3 * v + k]) << names[k] << " vertex " << v;
    }
    for (int pixel = kCount; pixel < width * height; ++pixel) {
      ASSERT_EQ(channel[pixel], 0.0f) << names[k] << " padding " << pixel;
    }
  }
  const ExrPointCacheInfo info = readPointCacheExrInfo(path);
  EXPECT_TRUE(info.hasNormals);
  EXPECT_EQ(info.width, 16);
  EXPECT_NEAR(info.framesPerSecond, 24000.0 / 1001.0, 1e-12);
  std::vector<float> back;
  readPointCacheExr(path, back);
  expectBitwiseEqual(back, xyz);
}

TEST(ExrPointCache, ExrheaderToolSeesTheFile) {
  TempDir dir;
  const std::string path = dir.file("tool.exr");
  const std::vector<float> xyz = randomPositions(10, 9);
  writePointCacheExr(path, 10, xyz.data(), nullptr, ExrWriteOptions{});
  const std::string command = "exrheader '" + path + "' 2>&1";
  std::FILE* pipe = ::popen(command.c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  std::string output;
  char buffer[4096];
  std::size_t got;
  while ((got = std::fread(buffer, 1, sizeof(buffer), pipe)) > 0) {
    output.append(buffer, got);
  }
  const int status = ::pclose(pipe);
  ASSERT_EQ(status, 0) << output;
  EXPECT_TRUE(contains(output, "P.X"));
  EXPECT_TRUE(contains(output, "dsVertexCount"));
  EXPECT_TRUE(contains(output, "framesPerSecond"));
  EXPECT_TRUE(contains(output, "dsTopologyHash"));
}

TEST(ExrPointCache, WrongVertexCountOrTopologyIsRefused) {
  TempDir dir;
  const std::string path = dir.file("cloth.0001.exr");
  const std::vector<float> xyz = randomPositions(100, 10);
  ExrWriteOptions options;
  options.topologyHash = kTopology;
  writePointCacheExr(path, 100, xyz.data(), nullptr, options);
  std::vector<float> back;

  Error error = catchError([&] { readPointCacheExr(path, back, 101); });
  EXPECT_EQ(error.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(error.what(), path));
  EXPECT_TRUE(contains(error.what(), "100"));
  EXPECT_TRUE(contains(error.what(), "101"));
  EXPECT_TRUE(contains(error.what(), "rebake"));

  error = catchError([&] { readPointCacheExr(path, back, 100, kTopology + 1); });
  EXPECT_EQ(error.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(error.what(), path));
  EXPECT_TRUE(contains(error.what(), hex16(kTopology)));
  EXPECT_TRUE(contains(error.what(), hex16(kTopology + 1)));

  readPointCacheExr(path, back, 100, kTopology);
  expectBitwiseEqual(back, xyz);
}

/// A plain OpenEXR file with the given channels and, optionally, a dsVertexCount.
void writePlainExr(const std::string& path, const std::vector<const char*>& channels,
                   int vertexCountAttribute, int width, int height) {
  Imf::Header header(width, height);
  for (const char* name : channels) {
    header.channels().insert(name, Imf::Channel(Imf::FLOAT));
  }
  if (vertexCountAttribute > 0) {
    header.insert("dsVertexCount", Imf::IntAttribute(vertexCountAttribute));
  }
  std::vector<float> pixels(static_cast<std::size_t>(width) * height, 0.5f);
  Imf::FrameBuffer frameBuffer;
  for (const char* name : channels) {
    frameBuffer.insert(name, Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(pixels.data()),
                                        sizeof(float), sizeof(float) * width));
  }
  Imf::OutputFile file(path.c_str(), header);
  file.setFrameBuffer(frameBuffer);
  file.writePixels(height);
}

TEST(ExrPointCache, MissingChannelOrAttributeIsRefused) {
  TempDir dir;
  std::vector<float> back;
  const std::string noY = dir.file("no_y.exr");
  writePlainExr(noY, {"P.X", "P.Z", "A"}, 8, 8, 1);
  Error error = catchError([&] { readPointCacheExr(noY, back); });
  EXPECT_EQ(error.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(error.what(), noY));
  EXPECT_TRUE(contains(error.what(), "P.Y"));

  const std::string plain = dir.file("beauty.exr");
  writePlainExr(plain, {"R", "G", "B"}, 0, 8, 8);
  error = catchError([&] { readPointCacheExr(plain, back); });
  EXPECT_EQ(error.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(error.what(), plain));
  EXPECT_TRUE(contains(error.what(), "not a drivenshape point cache (no dsVertexCount attribute)"));
  EXPECT_EQ(catchError([&] { readPointCacheExrInfo(plain); }).code(), ErrorCode::kInput);

  // 8x8 pixels cannot hold 1000 vertices.
  const std::string small = dir.file("small.exr");
  writePlainExr(small, {"P.X", "P.Y", "P.Z"}, 1000, 8, 8);
  error = catchError([&] { readPointCacheExr(small, back); });
  EXPECT_EQ(error.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(error.what(), small));
  EXPECT_TRUE(contains(error.what(), "1000"));

  const std::string garbage = dir.file("garbage.exr");
  writeTextFile(garbage, "this is not an image");
  error = catchError([&] { readPointCacheExr(garbage, back); });
  EXPECT_EQ(error.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(error.what(), garbage));

  error = catchError([&] { readPointCacheExrInfo(dir.file("missing.exr")); });
  EXPECT_EQ(error.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(error.what(), dir.file("missing.exr")));
}

TEST(ExrPointCache, DataWindowNotAtTheOriginIsRead) {
  // A file re-saved by another tool may move its data window; vertex v is still the v-th
  // pixel of the window.
  TempDir dir;
  const std::string path = dir.file("moved.exr");
  constexpr int kWidth = 4;
  constexpr int kCount = 7;
  const Imath::Box2i window(Imath::V2i(10, 20), Imath::V2i(10 + kWidth - 1, 21));
  Imf::Header header(window, window);
  header.insert("dsVertexCount", Imf::IntAttribute(kCount));
  const char* names[3] = {"P.X", "P.Y", "P.Z"};
  std::vector<float> pixels(3 * kWidth * 2);
  for (std::size_t i = 0; i < pixels.size(); ++i) {
    pixels[i] = static_cast<float>(i) + 0.25f;
  }
  Imf::FrameBuffer frameBuffer;
  char* base = reinterpret_cast<char*>(pixels.data()) - (10 + 20 * kWidth) * 3 * sizeof(float);
  for (int k = 0; k < 3; ++k) {
    header.channels().insert(names[k], Imf::Channel(Imf::FLOAT));
    frameBuffer.insert(names[k], Imf::Slice(Imf::FLOAT, base + k * sizeof(float), 3 * sizeof(float),
                                            3 * sizeof(float) * kWidth));
  }
  {
    Imf::OutputFile file(path.c_str(), header);
    file.setFrameBuffer(frameBuffer);
    file.writePixels(2);
  }
  std::vector<float> back;
  const ExrPointCacheInfo info = readPointCacheExr(path, back, kCount);
  EXPECT_EQ(info.width, kWidth);
  expectBitwiseEqual(back, std::vector<float>(pixels.begin(), pixels.begin() + 3 * kCount));
}

TEST(ExrPointCache, IsCompleteExrRejectsTruncatedCopies) {
  TempDir dir;
  const std::string path = dir.file("whole.exr");
  const std::vector<float> xyz = randomPositions(5000, testSeed() + 4);
  ExrWriteOptions options;
  options.compression = ExrCompression::kNone;  // big enough to cut inside the pixels
  writePointCacheExr(path, 5000, xyz.data(), nullptr, options);
  EXPECT_TRUE(isCompleteExr(path));
  const std::vector<unsigned char> bytes = readBytes(path);
  ASSERT_GT(bytes.size(), 5000u * 12);
  for (std::size_t keep : {bytes.size() - 1, bytes.size() - 4000, bytes.size() / 2,
                           std::size_t{300}, std::size_t{10}, std::size_t{0}}) {
    const std::string cut = dir.file("cut_" + std::to_string(keep) + ".exr");
    writeBytes(cut, std::vector<unsigned char>(bytes.begin(), bytes.begin() + keep));
    EXPECT_FALSE(isCompleteExr(cut)) << "kept " << keep << " of " << bytes.size() << " bytes";
    std::vector<float> back;
    const Error error = catchError([&] { readPointCacheExr(cut, back); });
    EXPECT_EQ(error.code(), ErrorCode::kInput) << "kept " << keep;
    EXPECT_TRUE(contains(error.what(), cut));
  }
  // Same for the default (ZIP) file, cut just before its end.
  const std::string zip = dir.file("zip.exr");
  writePointCacheExr(zip, 5000, xyz.data(), nullptr, ExrWriteOptions{});
  EXPECT_TRUE(isCompleteExr(zip));
  const std::vector<unsigned char> zipBytes = readBytes(zip);
  writeBytes(dir.file("zip_cut.exr"),
             std::vector<unsigned char>(zipBytes.begin(), zipBytes.end() - 1));
  EXPECT_FALSE(isCompleteExr(dir.file("zip_cut.exr")));

  EXPECT_FALSE(isCompleteExr(dir.file("missing.exr")));
  writeTextFile(dir.file("garbage.exr"), "not an exr at all");
  EXPECT_FALSE(isCompleteExr(dir.file("garbage.exr")));
  EXPECT_FALSE(isCompleteExr(dir.path()));  // a folder
}

// Regression (fuzzing): a 2 KB file whose attribute claims 0x7fffffff bytes made OpenEXR
// allocate gigabytes before failing. The size is checked against the file first.
TEST(ExrPointCache, AttributeLargerThanTheFileIsRefusedBeforeOpenExrReadsIt) {
  TempDir dir;
  const std::string path = dir.file("small.exr");
  const std::vector<float> xyz = randomPositions(50, testSeed() + 7);
  writePointCacheExr(path, 50, xyz.data(), nullptr, ExrWriteOptions{});
  std::vector<unsigned char> bytes = readBytes(path);
  // "dsToolVersion\0string\0" then the int32 size: claim 0x7fffffff bytes.
  const std::string marker = std::string("dsToolVersion") + '\0' + "string" + '\0';
  const auto at = std::search(bytes.begin(), bytes.end(), marker.begin(), marker.end());
  ASSERT_NE(at, bytes.end());
  const std::size_t size = static_cast<std::size_t>(at - bytes.begin()) + marker.size();
  for (int i = 0; i < 4; ++i) {
    bytes[size + i] = i == 3 ? 0x7f : 0xff;
  }
  const std::string bad = dir.file("huge_attribute.exr");
  writeBytes(bad, bytes);
  for (const auto& read : std::vector<std::function<void()>>{
           [&] { readPointCacheExrInfo(bad); },
           [&] {
             std::vector<float> back;
             readPointCacheExr(bad, back);
           },
       }) {
    const Error error = catchError(read);
    EXPECT_EQ(error.code(), ErrorCode::kInput);
    EXPECT_TRUE(contains(error.what(), "dsToolVersion"));
    EXPECT_TRUE(contains(error.what(), bad));
  }
  EXPECT_FALSE(isCompleteExr(bad));
}

// Regression: a resume kept frames that no longer decoded or decoded to other numbers.
// reuseProblem() decodes every pixel and checks the CRC written with them.
TEST(ExrPointCache, ReuseFindsEveryFlippedPixelByte) {
  TempDir dir;
  constexpr int kCount = 700;  // one row and a bit: padding pixels are covered too
  const std::vector<float> xyz = randomPositions(kCount, testSeed() + 8);
  ExrWriteOptions options;
  options.width = 512;
  options.frame = 12;
  options.topologyHash = 0x1234;
  options.settingsHash = 0x5678;
  for (ExrCompression compression : {ExrCompression::kNone, ExrCompression::kZip}) {
    SCOPED_TRACE(exrCompressionName(compression));
    options.compression = compression;
    const std::string path = dir.file("frame.exr");
    writePointCacheExr(path, kCount, xyz.data(), nullptr, options);
    EXPECT_EQ(reuseProblem(path, kCount, 0x1234, 0x5678, 12), "");
    EXPECT_TRUE(contains(reuseProblem(path, kCount, 0x1234, 0x9999, 12), "other settings"));
    EXPECT_TRUE(contains(reuseProblem(path, kCount, 0x1234, 0x5678, 13), "frame 12"));
    EXPECT_TRUE(contains(reuseProblem(path, kCount, 0x4321, 0x5678, 12), "topology"));
    EXPECT_TRUE(contains(reuseProblem(path, kCount + 1, 0x1234, 0x5678, 12), "vertices"));
    const std::vector<unsigned char> bytes = readBytes(path);
    // The pixel data is the second half of the file and more (the header is ~600 bytes).
    std::mt19937 random(testSeed() + 9);
    std::uniform_int_distribution<std::size_t> where(bytes.size() / 2, bytes.size() - 1);
    for (int trial = 0; trial < 40; ++trial) {
      std::vector<unsigned char> damaged = bytes;
      const std::size_t at = where(random);
      damaged[at] ^= static_cast<unsigned char>(1u << (trial % 8));
      const std::string bad = dir.file("damaged.exr");
      writeBytes(bad, damaged);
      EXPECT_NE(reuseProblem(bad, kCount, 0x1234, 0x5678, 12), "")
          << "byte " << at << " of " << bytes.size();
    }
  }
}

TEST(ExrPointCache, FailedWriteIsAnOutputErrorAndLeavesNothing) {
  TempDir dir;
  const std::vector<float> xyz = randomPositions(50, 11);
  const std::string locked = dir.file("locked");
  std::filesystem::create_directory(locked);
  ::chmod(locked.c_str(), 0555);
  // Root ignores the mode bits; then use a folder that does not exist instead.
  std::string target = locked + "/cloth.0001.exr";
  const std::string probe = locked + "/probe";
  if (std::FILE* file = std::fopen(probe.c_str(), "wb")) {
    std::fclose(file);
    std::remove(probe.c_str());
    target = dir.file("does_not_exist/cloth.0001.exr");
  }
  const Error error =
      catchError([&] { writePointCacheExr(target, 50, xyz.data(), nullptr, ExrWriteOptions{}); });
  EXPECT_EQ(error.code(), ErrorCode::kOutput);
  EXPECT_TRUE(contains(error.what(), std::filesystem::path(target).parent_path().string()));
  ::chmod(locked.c_str(), 0755);
  EXPECT_TRUE(listFolder(locked).empty());
  EXPECT_EQ(listFolder(dir.path()), std::vector<std::string>{"locked"});

  // A failure after the pixels are written (the target name is taken by a folder) removes
  // the temporary file too.
  const std::string taken = dir.file("taken.exr");
  std::filesystem::create_directory(taken);
  const Error late =
      catchError([&] { writePointCacheExr(taken, 50, xyz.data(), nullptr, ExrWriteOptions{}); });
  EXPECT_EQ(late.code(), ErrorCode::kOutput);
  EXPECT_TRUE(contains(late.what(), taken));
  EXPECT_EQ(listFolder(dir.path()), (std::vector<std::string>{"locked", "taken.exr"}));

  const Error badWidth = catchError([&] {
    ExrWriteOptions options;
    options.width = 0;
    writePointCacheExr(dir.file("w.exr"), 50, xyz.data(), nullptr, options);
  });
  EXPECT_EQ(badWidth.code(), ErrorCode::kUsage);
  // Wider than kMaxPointCacheExrWidth: refused before the padded rows are allocated (2^31 - 1
  // used to end in std::bad_alloc), naming the width and the range.
  const Error hugeWidth = catchError([&] {
    ExrWriteOptions options;
    options.width = std::numeric_limits<int>::max();
    writePointCacheExr(dir.file("w.exr"), 50, xyz.data(), nullptr, options);
  });
  EXPECT_EQ(hugeWidth.code(), ErrorCode::kUsage);
  EXPECT_TRUE(contains(hugeWidth.what(), "2147483647 is outside 1..65536"));
  // No vertices is the caller's mistake, not a bug of the writer.
  const Error noVertices = catchError(
      [&] { writePointCacheExr(dir.file("v.exr"), 0, xyz.data(), nullptr, ExrWriteOptions{}); });
  EXPECT_EQ(noVertices.code(), ErrorCode::kUsage);
  EXPECT_TRUE(contains(noVertices.what(), "0 vertices"));
  EXPECT_EQ(listFolder(dir.path()), (std::vector<std::string>{"locked", "taken.exr"}));
}

/// `prefix` + frame + `suffix`, the frame zero padded to `width` digits after its sign
/// (point_cache.h: -0012), built here with snprintf rather than by the library.
std::string sequenceName(const std::string& prefix, int frame, int width,
                         const std::string& suffix) {
  char digits[64];
  std::snprintf(digits, sizeof(digits), "%s%0*d", frame < 0 ? "-" : "", width, std::abs(frame));
  return prefix + digits + suffix;
}

/// Writes one point-cache EXR per frame, named by sequenceName.
std::vector<std::vector<float>> writeSequence(const std::string& folder, const std::string& prefix,
                                              int width, const std::string& suffix,
                                              const std::vector<int>& frames, int vertexCount,
                                              std::uint64_t topology) {
  std::vector<std::vector<float>> data;
  for (int frame : frames) {
    data.push_back(randomPositions(vertexCount, static_cast<std::uint32_t>(frame + 100) * 7u));
    ExrWriteOptions options;
    options.frame = frame;
    options.topologyHash = topology;
    writePointCacheExr(folder + "/" + sequenceName(prefix, frame, width, suffix), vertexCount,
                       data.back().data(), nullptr, options);
  }
  return data;
}

void expectSequence(const std::string& pattern, const std::vector<int>& frames,
                    const std::vector<std::vector<float>>& data, int vertexCount) {
  SCOPED_TRACE(pattern);
  const auto cache = openPointCache(pattern, kTopology);
  EXPECT_EQ(cache->path(), pattern);
  EXPECT_EQ(cache->vertexCount(), vertexCount);
  EXPECT_EQ(cache->frames(), frames);
  std::vector<float> frame(3 * static_cast<std::size_t>(vertexCount));
  for (std::size_t i = 0; i < frames.size(); ++i) {
    EXPECT_TRUE(cache->hasFrame(frames[i]));
    cache->readFrame(frames[i], frame.data());
    expectBitwiseEqual(frame, data[i]);
  }
  const std::vector<float> stacked = readFrames(*cache, {frames.back(), frames.front()});
  expectBitwiseEqual(std::vector<float>(stacked.begin(), stacked.begin() + frame.size()),
                     data.back());
  const Error error = catchError([&] { cache->readFrame(frames.back() + 1000, frame.data()); });
  EXPECT_EQ(error.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(error.what(), pattern));
  EXPECT_TRUE(contains(error.what(), std::to_string(frames.back() + 1000)));
}

TEST(ExrSequence, HashPattern) {
  TempDir dir;
  const std::vector<int> frames = {998, 999, 1001, 1002, 10000};
  const auto data = writeSequence(dir.path(), "cloth.", 4, ".exr", frames, 30, kTopology);
  // Files that must not be taken for frames of the sequence.
  writeTextFile(dir.file("cloth.01003.exr"), "wrong padding");
  writeTextFile(dir.file("cloth.1004.exr.bak"), "wrong suffix");
  writeTextFile(dir.file("cloth.10x5.exr"), "not a number");
  writeTextFile(dir.file("other.1005.exr"), "wrong prefix");
  writeTextFile(dir.file(".cloth.1006.exr.tmp-1-0"), "a temporary file");
  std::filesystem::create_directory(dir.file("cloth.1007.exr"));
  expectSequence(dir.path() + "/cloth.####.exr", frames, data, 30);
}

TEST(ExrSequence, PrintfAndHoudiniPatterns) {
  TempDir dir;
  const std::vector<int> frames = {-2, -1, 0, 1, 2};
  const auto data = writeSequence(dir.path(), "cloth.", 4, ".exr", frames, 7, kTopology);
  expectSequence(dir.path() + "/cloth.%04d.exr", frames, data, 7);
  expectSequence(dir.path() + "/cloth.$F4.exr", frames, data, 7);

  TempDir plain;
  const std::vector<int> unpadded = {9, 10, 11};
  const auto plainData = writeSequence(plain.path(), "wave_", 0, ".exr", unpadded, 5, kTopology);
  writeTextFile(plain.file("wave_012.exr"), "padded: not $F");
  expectSequence(plain.path() + "/wave_$F.exr", unpadded, plainData, 5);
  expectSequence(plain.path() + "/wave_%d.exr", unpadded, plainData, 5);
}

TEST(ExrSequence, MismatchesAndMissingFilesAreInputErrors) {
  TempDir dir;
  writeSequence(dir.path(), "cloth.", 4, ".exr", {1, 2}, 12, kTopology);
  writeSequence(dir.path(), "cloth.", 4, ".exr", {3}, 13, kTopology);
  const std::string pattern = dir.path() + "/cloth.####.exr";
  const auto cache = openPointCache(pattern);
  EXPECT_EQ(cache->vertexCount(), 12);
  std::vector<float> frame(3 * 13);
  const Error count = catchError([&] { cache->readFrame(3, frame.data()); });
  EXPECT_EQ(count.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(count.what(), dir.file("cloth.0003.exr")));
  EXPECT_TRUE(contains(count.what(), "13"));
  EXPECT_TRUE(contains(count.what(), "12"));

  const Error topology = catchError([&] { openPointCache(pattern, kTopology ^ 1); });
  EXPECT_EQ(topology.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(topology.what(), dir.file("cloth.0001.exr")));

  const Error none = catchError([&] { openPointCache(dir.path() + "/shirt.####.exr"); });
  EXPECT_EQ(none.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(none.what(), "shirt.####.exr"));

  const Error folder = catchError([&] { openPointCache(dir.path() + "/nope/cloth.####.exr"); });
  EXPECT_EQ(folder.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(folder.what(), "nope"));

  const Error single = catchError([&] { openPointCache(dir.file("cloth.0001.exr")); });
  EXPECT_EQ(single.code(), ErrorCode::kInput);
  EXPECT_TRUE(contains(single.what(), "neither a .pc2 file nor an EXR sequence pattern"));
}

}  // namespace
}  // namespace drivenshape::testing
