// SPDX-License-Identifier: Apache-2.0
// Tests for src/io/posmap_exr.cpp and posmap_preview.cpp: the EXR layout read back with
// plain OpenEXR, the same files through the real readers (exrheader, oiiotool), PNG previews.

#include <drivenshape/position_map.h>
#include <drivenshape/position_map_backend.h>
#include <drivenshape/position_map_sequence.h>
#include <drivenshape/position_map_tables.h>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfFramesPerSecond.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStandardAttributes.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenEXR/ImfVecAttribute.h>
#include <zlib.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>

#include <drivenshape/point_cache.h>
#include <drivenshape/version.h>

#include "hash.h"

#include "posmap_test_util.h"
#include "test_support.h"

namespace drivenshape::testing {
namespace {

/// One channel of a whole EXR as float, read with plain OpenEXR (not the code under test).
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

/// Maps of one sleeve frame, evaluated on the host.
struct FrameMaps {
  Sleeve sleeve;
  PositionMapTables tables;
  std::vector<float> xyz;
  std::vector<float> positions;
  std::vector<float> normals;
};

FrameMaps sleeveMaps(int width, int height, int padding, int frame) {
  FrameMaps maps;
  maps.sleeve = loadSleeve();
  maps.tables = buildPositionMapTables(maps.sleeve.mesh, width, height, padding);
  maps.xyz = readSleeveFrames(maps.sleeve, {frame});
  auto host = makeHostPositionMaps();
  host->upload(maps.tables);
  maps.positions.resize(3 * maps.tables.texelCount());
  maps.normals.resize(3 * maps.tables.texelCount());
  host->evaluate(1, maps.xyz.data(), maps.positions.data(), maps.normals.data());
  return maps;
}

PositionMapFrameHeader headerFor(const FrameMaps& maps, int frame) {
  PositionMapFrameHeader header;
  header.frame = frame;
  header.topologyHash = maps.tables.topologyHash;
  header.meshVertexCount = maps.tables.vertexCount;
  header.padding = maps.tables.padding;
  header.bounds = computeBounds(maps.xyz.data(), maps.tables.vertexCount);
  header.framesPerSecond = 25.0;
  return header;
}

/// stdout + stderr of a shell command, and its exit status.
std::string run(const std::string& command, int& status) {
  std::string output;
  FILE* pipe = popen((command + " 2>&1").c_str(), "r");
  if (pipe == nullptr) {
    status = -1;
    return output;
  }
  std::array<char, 4096> buffer{};
  while (std::fgets(buffer.data(), buffer.size(), pipe) != nullptr) {
    output += buffer.data();
  }
  status = pclose(pipe);
  return output;
}

/// Fails (never skips) when a reader the acceptance names is not installed.
bool haveTool(const std::string& tool, const std::string& package) {
  int status = 0;
  run("command -v " + tool, status);
  if (status != 0) {
    ADD_FAILURE() << tool << " is not installed; install the Debian package " << package
                  << " (scripts/setup.sh installs it)";
    return false;
  }
  return true;
}

/// The names a map is documented to have (docs/formats.md), spelled out here rather than
/// taken from the library: position x y z, coverage, normals x y z.
struct DocumentedNames {
  PositionMapChannels naming;
  std::array<const char*, 7> names;
};
constexpr DocumentedNames kRgbaNames{PositionMapChannels::kRgba,
                                     {"R", "G", "B", "A", "N.R", "N.G", "N.B"}};
constexpr DocumentedNames kLegacyNames{PositionMapChannels::kLegacy,
                                       {"P.X", "P.Y", "P.Z", "A", "N.X", "N.Y", "N.Z"}};

/// The channel names of an EXR as OpenEXR lists them (alphabetical).
std::vector<std::string> channelNamesOf(const std::string& path) {
  Imf::InputFile file(path.c_str());
  std::vector<std::string> names;
  for (auto it = file.header().channels().begin(); it != file.header().channels().end(); ++it) {
    names.emplace_back(it.name());
  }
  return names;
}

TEST(PosmapExr, ChannelsAttributesAndValuesReadBackForEveryCompressionAndNaming) {
  const FrameMaps maps = sleeveMaps(96, 64, 2, 12);
  TempDir dir;
  for (const DocumentedNames& documented : {kRgbaNames, kLegacyNames}) {
    for (ExrCompression compression : {ExrCompression::kZip, ExrCompression::kNone,
                                       ExrCompression::kZips, ExrCompression::kPiz}) {
      for (bool half : {false, true}) {
        const char* naming = positionMapChannelsName(documented.naming);
        SCOPED_TRACE(std::string(naming) + " " + exrCompressionName(compression) +
                     (half ? " half" : " float"));
        const std::string path =
            dir.file(std::string("m_") + naming + "_" + exrCompressionName(compression) +
                     (half ? "_h" : "_f") + ".exr");
        PositionMapFrameHeader header = headerFor(maps, 12);
        header.compression = compression;
        header.halfNormals = half;
        header.channels = documented.naming;
        writePositionMapExr(path, 96, 64, maps.positions.data(), maps.tables.coverage.data(),
                            maps.normals.data(), header);

        Imf::InputFile file(path.c_str());
        const Imf::Header& h = file.header();
        EXPECT_EQ(h.dataWindow().max.x, 95);
        EXPECT_EQ(h.dataWindow().max.y, 63);
        EXPECT_EQ(h.lineOrder(), Imf::INCREASING_Y);
        EXPECT_FALSE(h.hasTileDescription()) << "position maps are scanline images";
        std::vector<std::string> expected(documented.names.begin(), documented.names.end());
        std::sort(expected.begin(), expected.end());
        EXPECT_EQ(channelNamesOf(path), expected) << "exactly the documented channels";
        for (int k = 0; k < 4; ++k) {
          const Imf::Channel* channel = h.channels().findChannel(documented.names[k]);
          ASSERT_NE(channel, nullptr) << documented.names[k];
          EXPECT_EQ(channel->type, Imf::FLOAT) << documented.names[k];
        }
        for (int k = 4; k < 7; ++k) {
          const Imf::Channel* channel = h.channels().findChannel(documented.names[k]);
          ASSERT_NE(channel, nullptr) << documented.names[k];
          EXPECT_EQ(channel->type, half ? Imf::HALF : Imf::FLOAT) << documented.names[k];
        }
        EXPECT_EQ(h.typedAttribute<Imf::StringAttribute>("dsKind").value(), "positionMap");
        EXPECT_EQ(h.typedAttribute<Imf::IntAttribute>("dsFrame").value(), 12);
        EXPECT_EQ(h.typedAttribute<Imf::StringAttribute>("dsTopologyHash").value(),
                  hashToHex(topologyHash(maps.sleeve.mesh)));
        EXPECT_EQ(h.typedAttribute<Imf::StringAttribute>("dsToolVersion").value(), kVersion);
        EXPECT_EQ(h.typedAttribute<Imf::IntAttribute>("dsMeshVertexCount").value(), 2244);
        EXPECT_EQ(h.typedAttribute<Imf::IntAttribute>("dsPadding").value(), 2);
        EXPECT_EQ(h.findTypedAttribute<Imf::IntAttribute>("dsVertexCount"), nullptr)
            << "a position map must not look like a point cache";
        EXPECT_EQ(h.typedAttribute<Imf::V3fAttribute>("dsBoundsMax").value().x,
                  header.bounds.max.x());
        ASSERT_TRUE(Imf::hasFramesPerSecond(h));
        EXPECT_EQ(Imf::framesPerSecond(h), Imf::Rational(25, 1));

        for (int a = 0; a < 3; ++a) {
          const std::vector<float> p = readChannel(path, documented.names[a]);
          const std::vector<float> n = readChannel(path, documented.names[4 + a]);
          for (std::size_t i = 0; i < p.size(); ++i) {
            ASSERT_LE(std::abs(p[i] - maps.positions[3 * i + a]), kFileRoundTripTol) << i;
            ASSERT_LE(std::abs(n[i] - maps.normals[3 * i + a]),
                      half ? kHalfNormalTol : static_cast<double>(kFileRoundTripTol))
                << i;
          }
        }
        const std::vector<float> alpha = readChannel(path, "A");
        EXPECT_EQ(alpha, maps.tables.coverage);

        // What `drivenshape info` reads back: the header it was written with.
        ASSERT_TRUE(isPositionMapExr(path));
        const PositionMapInfo info = readPositionMapExrInfo(path);
        EXPECT_EQ(info.width, 96);
        EXPECT_EQ(info.height, 64);
        EXPECT_EQ(info.frame, 12);
        EXPECT_EQ(info.topologyHash, header.topologyHash);
        EXPECT_EQ(info.meshVertexCount, header.meshVertexCount);
        EXPECT_EQ(info.padding, 2);
        EXPECT_EQ(info.toolVersion, kVersion);
        EXPECT_EQ(info.framesPerSecond, 25.0);
        EXPECT_EQ(info.bounds.min, header.bounds.min);
        EXPECT_EQ(info.bounds.max, header.bounds.max);
        EXPECT_TRUE(info.hasNormals);
        EXPECT_EQ(info.halfNormals, half);
        EXPECT_EQ(info.compression, compression);
        EXPECT_EQ(info.channels, documented.naming);
      }
    }
  }
}

TEST(PosmapExr, ChannelNamingsParseAndListTheDocumentedNames) {
  EXPECT_EQ(parsePositionMapChannels("rgba"), PositionMapChannels::kRgba);
  EXPECT_EQ(parsePositionMapChannels("Legacy"), PositionMapChannels::kLegacy);
  EXPECT_STREQ(positionMapChannelsName(PositionMapChannels::kRgba), "rgba");
  EXPECT_STREQ(positionMapChannelsName(PositionMapChannels::kLegacy), "legacy");
  expectThrows([] { parsePositionMapChannels("xyz", "--posmap-channels"); }, ErrorCode::kUsage,
               "--posmap-channels 'xyz' is not a channel naming; use rgba");
  for (const DocumentedNames& documented : {kRgbaNames, kLegacyNames}) {
    EXPECT_EQ(positionMapChannelNames(documented.naming, true),
              std::vector<std::string>(documented.names.begin(), documented.names.end()));
    EXPECT_EQ(positionMapChannelNames(documented.naming, false),
              std::vector<std::string>(documented.names.begin(), documented.names.begin() + 4));
  }
  EXPECT_EQ(PositionMapOptions().channels, PositionMapChannels::kRgba) << "the default";
}

TEST(PosmapExr, AMapWithoutPositionChannelsIsRefusedNamingWhatItHas) {
  // A file that says it is a position map but holds neither R G B nor P.X P.Y P.Z.
  TempDir dir;
  const std::string path = dir.file("odd.0001.exr");
  Imf::Header header(4, 2);
  header.channels().insert("A", Imf::Channel(Imf::FLOAT));
  header.channels().insert("P.R", Imf::Channel(Imf::FLOAT));
  header.insert("dsKind", Imf::StringAttribute("positionMap"));
  std::vector<float> zeros(8, 0.0f);
  Imf::FrameBuffer frameBuffer;
  for (const char* name : {"A", "P.R"}) {
    frameBuffer.insert(name, Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(zeros.data()),
                                        sizeof(float), 4 * sizeof(float)));
  }
  {
    Imf::OutputFile file(path.c_str(), header);
    file.setFrameBuffer(frameBuffer);
    file.writePixels(2);
  }
  EXPECT_TRUE(isPositionMapExr(path)) << "dsKind says what the file means to be";
  expectThrows([&] { readPositionMapExrInfo(path); }, ErrorCode::kInput,
               "odd.0001.exr': no position channels (R G B, or P.X P.Y P.Z as --channels legacy "
               "writes); it has: A P.R");
}

TEST(PosmapExr, PointCachesAndMissingFilesAreNotPositionMaps) {
  TempDir dir;
  const std::string cache = dir.file("cache.0001.exr");
  const std::vector<float> xyz = {0.0f, 1.0f, 2.0f, 3.0f, 4.0f, 5.0f};
  writePointCacheExr(cache, 2, xyz.data(), nullptr, ExrWriteOptions());
  EXPECT_FALSE(isPositionMapExr(cache));
  expectThrows([&] { readPositionMapExrInfo(cache); }, ErrorCode::kInput,
               "cache.0001.exr: not a drivenshape position map");
  const std::string missing = dir.file("missing.exr");
  EXPECT_FALSE(isPositionMapExr(missing));
  expectThrows([&] { readPositionMapExrInfo(missing); }, ErrorCode::kInput, "does not exist");
}

TEST(PosmapExr, RowZeroOfTheMapIsTheFirstScanline) {
  // A triangle in the top-left UV corner (v near 1) must be in the first scanlines' left ends.
  const Mesh mesh =
      makeMesh({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, {{0.0f, 1.0f}, {0.3f, 1.0f}, {0.0f, 0.7f}},
               {{{0, 0}, {1, 1}, {2, 2}}});
  TempDir dir;
  PositionMapOptions options;
  options.width = 20;
  options.height = 10;
  options.padding = 0;
  PositionMapWriter writer(mesh, options, makeHostPositionMaps());
  const std::vector<float> xyz{0, 0, 0, 1, 0, 0, 0, 1, 0};
  writer.writeFrame(1, xyz.data(), dir.file("corner.0001.exr"));
  const std::vector<float> alpha = readChannel(dir.file("corner.0001.exr"), "A");
  EXPECT_EQ(alpha[0], 1.0f) << "scanline 0, pixel 0";
  EXPECT_EQ(alpha[19], 0.0f) << "scanline 0, last pixel (u = 1)";
  for (int x = 0; x < 20; ++x) {
    EXPECT_EQ(alpha[9 * 20 + x], 0.0f) << "last scanline is v = 0";
  }
}

TEST(PosmapExr, ExrheaderShowsTheDocumentedChannelsAndAttributes) {
  if (!haveTool("exrheader", "openexr")) {
    return;
  }
  const FrameMaps maps = sleeveMaps(64, 64, 2, 3);
  TempDir dir;
  const std::string path = dir.file("map.0003.exr");
  PositionMapFrameHeader header = headerFor(maps, 3);
  header.halfNormals = true;
  writePositionMapExr(path, 64, 64, maps.positions.data(), maps.tables.coverage.data(),
                      maps.normals.data(), header);
  int status = 0;
  const std::string out = run("exrheader '" + path + "'", status);
  ASSERT_EQ(status, 0) << out;
  for (const char* expected :
       {" R, 32-bit floating-point", " G, 32-bit floating-point", " B, 32-bit floating-point",
        " A, 32-bit floating-point", " N.R, 16-bit floating-point", " N.G, 16-bit floating-point",
        " N.B, 16-bit floating-point", "dsFrame (type int): 3", "dsTopologyHash (type string)",
        "dsToolVersion (type string)", "dsKind (type string)", "dsMeshVertexCount (type int): 2244",
        "dsBoundsMin (type v3f)", "dsPadding (type int): 2",
        "framesPerSecond (type rational): 25/1", "compression (type compression): zip"}) {
    EXPECT_NE(out.find(expected), std::string::npos) << "missing '" << expected << "' in:\n" << out;
  }
}

TEST(PosmapExr, OiiotoolShowsTheDocumentedChannelsAndAttributes) {
  if (!haveTool("oiiotool", "openimageio-tools")) {
    return;
  }
  const FrameMaps maps = sleeveMaps(64, 32, 1, 4);
  TempDir dir;
  const std::string path = dir.file("map.0004.exr");
  PositionMapFrameHeader header = headerFor(maps, 4);
  header.compression = ExrCompression::kPiz;
  writePositionMapExr(path, 64, 32, maps.positions.data(), maps.tables.coverage.data(),
                      maps.normals.data(), header);
  const std::string legacy = dir.file("legacy.0004.exr");
  header.channels = PositionMapChannels::kLegacy;
  writePositionMapExr(legacy, 64, 32, maps.positions.data(), maps.tables.coverage.data(),
                      maps.normals.data(), header);
  int status = 0;
  // OpenImageIO puts the default layer's R G B A first, then the other layers.
  std::string out = run("oiiotool --info -v '" + legacy + "'", status);
  ASSERT_EQ(status, 0) << out;
  EXPECT_NE(out.find("channel list: A, N.X, N.Y, N.Z, P.X, P.Y, P.Z\n"), std::string::npos) << out;
  out = run("oiiotool --info -v '" + path + "'", status);
  ASSERT_EQ(status, 0) << out;
  for (const char* expected :
       {"64 x   32, 7 channel, float openexr", "channel list: R, G, B, A, N.R, N.G, N.B\n",
        "dsFrame: 4", "dsMeshVertexCount: 2244", "dsPadding: 1", "dsKind: \"positionMap\"",
        "dsTopologyHash: \"", "dsToolVersion: \"", "dsBoundsMin: ", "dsBoundsMax: ",
        "dsUvLayout: \"", "compression: \"piz\"", "framesPerSecond: 25/1"}) {
    EXPECT_NE(out.find(expected), std::string::npos) << "missing '" << expected << "' in:\n" << out;
  }
}

TEST(PosmapPreview, WritesAnRgbPngOfTheMapSize) {
  const FrameMaps maps = sleeveMaps(48, 40, 2, 20);
  TempDir dir;
  const std::string path = dir.file("map.0020.png");
  const Bounds bounds = computeBounds(maps.xyz.data(), maps.tables.vertexCount);
  writePositionMapPreview(path, maps.tables, maps.positions.data(), bounds);
  std::ifstream in(path, std::ios::binary);
  const std::string png((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ASSERT_GT(png.size(), 33u);
  EXPECT_EQ(png.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  const auto be32 = [&](std::size_t at) {
    return (static_cast<std::uint32_t>(static_cast<unsigned char>(png[at])) << 24) |
           (static_cast<std::uint32_t>(static_cast<unsigned char>(png[at + 1])) << 16) |
           (static_cast<std::uint32_t>(static_cast<unsigned char>(png[at + 2])) << 8) |
           static_cast<std::uint32_t>(static_cast<unsigned char>(png[at + 3]));
  };
  EXPECT_EQ(png.substr(12, 4), "IHDR");
  EXPECT_EQ(be32(16), 48u);
  EXPECT_EQ(be32(20), 40u);
  EXPECT_EQ(png[24], 8) << "bit depth";
  EXPECT_EQ(png[25], 2) << "RGB";
  // IDAT right after IHDR (8 + 25 bytes): inflate it and look at the pixels.
  const std::size_t idat = 33;
  ASSERT_EQ(png.substr(idat + 4, 4), "IDAT");
  const std::uint32_t length = be32(idat);
  std::vector<unsigned char> rows((1 + 3 * 48) * 40);
  uLongf size = static_cast<uLongf>(rows.size());
  ASSERT_EQ(
      uncompress(rows.data(), &size, reinterpret_cast<const Bytef*>(png.data() + idat + 8), length),
      Z_OK);
  ASSERT_EQ(size, rows.size());
  int lit = 0;
  for (std::size_t texel = 0; texel < maps.tables.texelCount(); ++texel) {
    const unsigned char* pixel = rows.data() + (texel / 48) * (1 + 3 * 48) + 1 + 3 * (texel % 48);
    const bool active = std::binary_search(maps.tables.texels.begin(), maps.tables.texels.end(),
                                           static_cast<int>(texel));
    if (!active) {
      ASSERT_EQ(pixel[0] + pixel[1] + pixel[2], 0) << "background is black";
    } else if (maps.tables.coverage[texel] == 1.0f) {
      lit += pixel[0] + pixel[1] + pixel[2] > 0 ? 1 : 0;
    }
  }
  EXPECT_GT(lit, 0);
  EXPECT_EQ(positionMapPreviewPath("out/cloth.1001.exr"), "out/cloth.1001.png");
  EXPECT_EQ(positionMapPreviewPath("out.d/cloth"), "out.d/cloth.png");
}

}  // namespace
}  // namespace drivenshape::testing
