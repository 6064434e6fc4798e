// SPDX-License-Identifier: Apache-2.0
// Tests for src/io/exr_zip_writer.cpp, the libdeflate ZIP writer behind the default
// point-cache and position-map files: its container is OpenEXR's byte for byte (with zlib at
// OpenEXR's level it writes the very file Imf::OutputFile writes), and its libdeflate files
// decode to the written bits with OpenEXR's reader and with oiiotool.

#include "exr_zip_writer.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStringAttribute.h>

#include <Imath/half.h>

#include <array>
#include <cstdio>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include <drivenshape/point_cache.h>

#include "io_test_util.h"
#include "test_support.h"

namespace drivenshape::testing {
namespace {

using exr_detail::Deflater;
using exr_detail::encodeZipExr;
using exr_detail::ZipEncoding;

/// A W x H image: float channels "P.X" (random), "A" (ones, then zeros: a padded last row), a
/// HALF channel "N.X", and "Z" that has no slice (OpenEXR writes zeros for it).
struct TestImage {
  int width = 0;
  int height = 0;
  std::vector<float> px;
  std::vector<float> alpha;
  std::vector<half> nx;
  Imf::Header header{1, 1};
  Imf::FrameBuffer frameBuffer;
};

TestImage testImage(int width, int height, Imf::Compression compression, std::uint32_t seed) {
  TestImage image;
  image.width = width;
  image.height = height;
  const std::size_t pixels = static_cast<std::size_t>(width) * height;
  std::mt19937 random(seed);
  std::uniform_real_distribution<float> value(-2.0f, 2.0f);
  for (std::size_t i = 0; i < pixels; ++i) {
    image.px.push_back(value(random));
    image.alpha.push_back(i + static_cast<std::size_t>(width) / 3 < pixels ? 1.0f : 0.0f);
    image.nx.push_back(half(value(random)));
  }
  image.header = Imf::Header(width, height);
  image.header.compression() = compression;
  image.header.channels().insert("P.X", Imf::Channel(Imf::FLOAT));
  image.header.channels().insert("A", Imf::Channel(Imf::FLOAT));
  image.header.channels().insert("N.X", Imf::Channel(Imf::HALF));
  image.header.channels().insert("Z", Imf::Channel(Imf::FLOAT));
  image.header.insert("dsNote", Imf::StringAttribute("a header attribute of our own"));
  const std::size_t row = static_cast<std::size_t>(width);
  image.frameBuffer.insert("P.X", Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(image.px.data()),
                                             sizeof(float), sizeof(float) * row));
  image.frameBuffer.insert("A", Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(image.alpha.data()),
                                           sizeof(float), sizeof(float) * row));
  image.frameBuffer.insert("N.X", Imf::Slice(Imf::HALF, reinterpret_cast<char*>(image.nx.data()),
                                             sizeof(half), sizeof(half) * row));
  return image;
}

/// The file OpenEXR's own writer makes of the image.
std::vector<unsigned char> openExrFile(const TestImage& image, const std::string& path) {
  {
    Imf::OutputFile file(path.c_str(), image.header);
    file.setFrameBuffer(image.frameBuffer);
    file.writePixels(image.height);
  }
  return readBytes(path);
}

std::vector<unsigned char> bytesOf(const std::string& text) {
  return std::vector<unsigned char>(text.begin(), text.end());
}

/// Every channel of the file as float, read with plain OpenEXR.
std::vector<std::vector<float>> decode(const std::string& path) {
  Imf::InputFile file(path.c_str());
  const Imath::Box2i window = file.header().dataWindow();
  const std::size_t width = static_cast<std::size_t>(window.max.x - window.min.x + 1);
  const std::size_t height = static_cast<std::size_t>(window.max.y - window.min.y + 1);
  std::vector<std::vector<float>> planes;
  Imf::FrameBuffer frameBuffer;
  for (auto it = file.header().channels().begin(); it != file.header().channels().end(); ++it) {
    planes.emplace_back(width * height, -1.0f);
    frameBuffer.insert(it.name(),
                       Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(planes.back().data()),
                                  sizeof(float), sizeof(float) * width));
  }
  file.setFrameBuffer(frameBuffer);
  file.readPixels(window.min.y, window.max.y);
  return planes;
}

/// Bitwise equality of two sets of planes (EXPECT_EQ on floats would let -0 equal 0).
::testing::AssertionResult sameBits(const std::vector<std::vector<float>>& a,
                                    const std::vector<std::vector<float>>& b) {
  if (a.size() != b.size()) {
    return ::testing::AssertionFailure() << a.size() << " vs " << b.size() << " channels";
  }
  for (std::size_t c = 0; c < a.size(); ++c) {
    if (a[c].size() != b[c].size() ||
        std::memcmp(a[c].data(), b[c].data(), a[c].size() * sizeof(float)) != 0) {
      return ::testing::AssertionFailure() << "channel " << c << " differs";
    }
  }
  return ::testing::AssertionSuccess();
}

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

TEST(ExrZipWriter, WithZlibAtOpenExrsLevelItWritesTheFileOpenExrWrites) {
  TempDir dir;
  // Heights around the chunk sizes (ZIP: 16 rows, ZIPS: 1): one partial chunk, exactly one,
  // one and a row, several; widths odd and even.
  for (Imf::Compression compression : {Imf::ZIP_COMPRESSION, Imf::ZIPS_COMPRESSION}) {
    for (auto [width, height] : {std::pair{7, 1}, {64, 16}, {33, 17}, {128, 40}}) {
      SCOPED_TRACE(std::to_string(width) + "x" + std::to_string(height) +
                   (compression == Imf::ZIP_COMPRESSION ? " zip" : " zips"));
      const TestImage image = testImage(width, height, compression, testSeed() + height);
      ZipEncoding zlib;
      zlib.deflater = Deflater::kZlib;
      zlib.level = 4;  // OpenEXR 3.1's default ZIP level
      for (int threads : {1, 3}) {
        zlib.threads = threads;
        EXPECT_EQ(bytesOf(encodeZipExr(image.header, image.frameBuffer, zlib)),
                  openExrFile(image, dir.file("openexr.exr")))
            << threads << " threads";
      }
    }
  }
}

TEST(ExrZipWriter, InterleavedSlicesAndAnOffsetWindowWriteTheFileOpenExrWrites) {
  // The position maps' layout: x, y, z of a FLOAT image interleaved (a stride of 12 bytes) and
  // of a HALF one (6 bytes), beside a plain FLOAT plane; here in a data window that does not
  // start at (0, 0), whose slices point at pixel (0, 0) outside the buffers.
  TempDir dir;
  const int width = 37;
  const int height = 21;
  const Imath::Box2i window(Imath::V2i(-5, 3), Imath::V2i(-5 + width - 1, 3 + height - 1));
  const std::size_t pixels = static_cast<std::size_t>(width) * height;
  std::mt19937 random(testSeed() + 11);
  std::uniform_real_distribution<float> value(-3.0f, 3.0f);
  std::vector<float> xyz(3 * pixels);
  std::vector<half> normals(3 * pixels);
  std::vector<float> alpha(pixels);
  for (std::size_t i = 0; i < pixels; ++i) {
    for (std::size_t k = 0; k < 3; ++k) {
      xyz[3 * i + k] = value(random);
      normals[3 * i + k] = half(value(random));
    }
    alpha[i] = i % 5 == 0 ? 0.0f : 1.0f;
  }
  const auto origin = [&](auto* data, std::size_t xStride) {
    const std::ptrdiff_t offset = window.min.x * static_cast<std::ptrdiff_t>(xStride) +
                                  window.min.y * static_cast<std::ptrdiff_t>(xStride * width);
    return reinterpret_cast<char*>(data) - offset;
  };
  const char* const xyzNames[3] = {"R", "G", "B"};
  const char* const normalNames[3] = {"N.R", "N.G", "N.B"};
  for (Imf::Compression compression : {Imf::ZIP_COMPRESSION, Imf::ZIPS_COMPRESSION}) {
    SCOPED_TRACE(compression == Imf::ZIP_COMPRESSION ? "zip" : "zips");
    TestImage image;
    image.height = height;
    image.header = Imf::Header(window, window);
    image.header.compression() = compression;
    image.header.channels().insert("A", Imf::Channel(Imf::FLOAT));
    image.frameBuffer.insert("A", Imf::Slice(Imf::FLOAT, origin(alpha.data(), sizeof(float)),
                                             sizeof(float), sizeof(float) * width));
    for (int k = 0; k < 3; ++k) {
      image.header.channels().insert(xyzNames[k], Imf::Channel(Imf::FLOAT));
      image.header.channels().insert(normalNames[k], Imf::Channel(Imf::HALF));
      image.frameBuffer.insert(xyzNames[k],
                               Imf::Slice(Imf::FLOAT, origin(xyz.data(), 3 * sizeof(float)) + 4 * k,
                                          3 * sizeof(float), 3 * sizeof(float) * width));
      image.frameBuffer.insert(
          normalNames[k], Imf::Slice(Imf::HALF, origin(normals.data(), 3 * sizeof(half)) + 2 * k,
                                     3 * sizeof(half), 3 * sizeof(half) * width));
    }
    ZipEncoding zlib;
    zlib.deflater = Deflater::kZlib;
    zlib.level = 4;  // OpenEXR 3.1's default ZIP level
    for (int threads : {1, 3}) {
      zlib.threads = threads;
      EXPECT_EQ(bytesOf(encodeZipExr(image.header, image.frameBuffer, zlib)),
                openExrFile(image, dir.file("openexr.exr")))
          << threads << " threads";
    }
  }
}

TEST(ExrZipWriter, LibdeflateFilesDecodeToTheWrittenBitsWithOpenExr) {
  TempDir dir;
  for (Imf::Compression compression : {Imf::ZIP_COMPRESSION, Imf::ZIPS_COMPRESSION}) {
    const TestImage image = testImage(96, 40, compression, testSeed());
    const std::string reference = dir.file("openexr.exr");
    openExrFile(image, reference);
    for (int level : {1, 6, 12}) {
      for (int threads : {1, 4}) {
        SCOPED_TRACE("level " + std::to_string(level) + ", " + std::to_string(threads) +
                     " threads");
        ZipEncoding encoding;
        encoding.level = level;
        encoding.threads = threads;
        const std::string path = dir.file("libdeflate.exr");
        writeBytes(path, bytesOf(encodeZipExr(image.header, image.frameBuffer, encoding)));
        Imf::InputFile file(path.c_str());
        EXPECT_EQ(file.header().compression(), compression);
        EXPECT_TRUE(file.isComplete());
        EXPECT_TRUE(sameBits(decode(path), decode(reference)));
      }
    }
  }
}

TEST(ExrZipWriter, IncompressibleChunksAreStoredRawAsOpenExrStoresThem) {
  // Random bytes do not deflate: each chunk is stored as it is, which readers tell from its
  // size (the raw size); one constant row does deflate. Both read back.
  TempDir dir;
  Imf::Header header(4096, 2);
  header.compression() = Imf::ZIPS_COMPRESSION;
  header.channels().insert("V", Imf::Channel(Imf::UINT));
  std::vector<unsigned int> values(2 * 4096, 7u);
  std::mt19937 random(testSeed());
  for (std::size_t i = 0; i < 4096; ++i) {
    values[i] = random();
  }
  Imf::FrameBuffer frameBuffer;
  frameBuffer.insert("V", Imf::Slice(Imf::UINT, reinterpret_cast<char*>(values.data()),
                                     sizeof(unsigned), sizeof(unsigned) * 4096));
  const std::string bytes = encodeZipExr(header, frameBuffer, ZipEncoding{});
  const std::string path = dir.file("raw.exr");
  writeBytes(path, bytesOf(bytes));
  Imf::InputFile file(path.c_str());
  std::vector<unsigned int> back(values.size());
  Imf::FrameBuffer readBuffer;
  readBuffer.insert("V", Imf::Slice(Imf::UINT, reinterpret_cast<char*>(back.data()),
                                    sizeof(unsigned), sizeof(unsigned) * 4096));
  file.setFrameBuffer(readBuffer);
  file.readPixels(0, 1);
  EXPECT_EQ(back, values);
  EXPECT_GT(bytes.size(), 4096u * 4u) << "the random row is stored raw";
  EXPECT_LT(bytes.size(), 2u * 4096u * 4u) << "the constant row is deflated";
}

TEST(ExrZipWriter, WhatItDoesNotWriteIsAnInternalError) {
  const TestImage image = testImage(8, 2, Imf::PIZ_COMPRESSION, 1);
  EXPECT_EQ(
      catchError([&] { encodeZipExr(image.header, image.frameBuffer, ZipEncoding{}); }).code(),
      ErrorCode::kInternal);
  TestImage zip = testImage(8, 2, Imf::ZIP_COMPRESSION, 1);
  ZipEncoding bad;
  bad.level = 13;
  EXPECT_EQ(catchError([&] { encodeZipExr(zip.header, zip.frameBuffer, bad); }).code(),
            ErrorCode::kInternal);
  zip.header.lineOrder() = Imf::DECREASING_Y;
  EXPECT_EQ(catchError([&] { encodeZipExr(zip.header, zip.frameBuffer, ZipEncoding{}); }).code(),
            ErrorCode::kInternal);
}

TEST(ExrZipWriter, PointCachesOfBothEncodersHaveTheSameHeaderAndPixels) {
  TempDir dir;
  std::mt19937 random(testSeed());
  std::uniform_real_distribution<float> value(-1.0f, 1.0f);
  const int vertices = 2500;  // width 64: 40 rows, three ZIP chunks
  std::vector<float> xyz(3 * vertices);
  std::vector<float> normals(3 * vertices);
  for (std::size_t i = 0; i < xyz.size(); ++i) {
    xyz[i] = value(random);
    normals[i] = value(random);
  }
  for (ExrCompression compression : {ExrCompression::kZip, ExrCompression::kZips}) {
    SCOPED_TRACE(exrCompressionName(compression));
    ExrWriteOptions options;
    options.width = 64;
    options.compression = compression;
    options.topologyHash = 0x0123456789abcdefULL;
    options.settingsHash = 0x1111222233334444ULL;
    options.syncToDisk = false;
    const std::string openexr = dir.file("openexr.exr");
    options.zipEncoder = ZipEncoder::kOpenExr;
    writePointCacheExr(openexr, vertices, xyz.data(), normals.data(), options);
    const std::string libdeflate = dir.file("libdeflate.exr");
    options.zipEncoder = ZipEncoder::kLibdeflate;
    options.encodeThreads = 3;
    writePointCacheExr(libdeflate, vertices, xyz.data(), normals.data(), options);

    EXPECT_TRUE(sameBits(decode(libdeflate), decode(openexr)));
    std::vector<float> back;
    const ExrPointCacheInfo info = readPointCacheExr(libdeflate, back, vertices);
    EXPECT_EQ(std::memcmp(back.data(), xyz.data(), xyz.size() * sizeof(float)), 0);
    EXPECT_EQ(info.compression, compression);
    EXPECT_TRUE(isCompleteExr(libdeflate));
    EXPECT_EQ(reuseProblem(libdeflate, vertices, options.topologyHash, options.settingsHash, 0), "")
        << "the pixel checksum holds";
    // The header bytes are OpenEXR's: everything before the offset table is the same in both
    // files (the table and the chunks differ).
    const std::vector<unsigned char> a = readBytes(openexr);
    const std::vector<unsigned char> b = readBytes(libdeflate);
    const std::uint64_t chunks = compression == ExrCompression::kZip ? 3 : 40;
    std::size_t firstChunk = 0;  // where the offset table starts: its first entry points past it
    for (std::size_t at = 8; at + 8 <= a.size() && firstChunk == 0; ++at) {
      std::uint64_t offset = 0;
      std::memcpy(&offset, a.data() + at, 8);
      firstChunk = offset == at + 8 * chunks ? at : 0;
    }
    ASSERT_GT(firstChunk, 0u);
    EXPECT_TRUE(
        std::equal(a.begin(), a.begin() + static_cast<std::ptrdiff_t>(firstChunk), b.begin()));
    EXPECT_LE(b.size(), a.size() + a.size() / 50) << "libdeflate level 1 is within 2% of zlib";
  }
  EXPECT_EQ(parseZipEncoder("LibDeflate"), ZipEncoder::kLibdeflate);
  EXPECT_EQ(parseZipEncoder("openexr"), ZipEncoder::kOpenExr);
  const Error error = catchError([] { parseZipEncoder("zlib", "--zip-encoder"); });
  EXPECT_EQ(error.code(), ErrorCode::kUsage);
  EXPECT_TRUE(contains(error.what(), "--zip-encoder 'zlib'"));
  EXPECT_TRUE(contains(error.what(), "libdeflate"));
}

TEST(ExrZipWriter, OiiotoolDecodesLibdeflateFilesToTheWrittenBits) {
  int status = 0;
  run("command -v oiiotool", status);
  ASSERT_EQ(status, 0) << "oiiotool is not installed; install the Debian package "
                          "openimageio-tools (scripts/setup.sh installs it)";
  TempDir dir;
  for (Imf::Compression compression : {Imf::ZIP_COMPRESSION, Imf::ZIPS_COMPRESSION}) {
    SCOPED_TRACE(compression == Imf::ZIP_COMPRESSION ? "zip" : "zips");
    const TestImage image = testImage(200, 37, compression, testSeed() + 5);
    const std::string path = dir.file("libdeflate.exr");
    ZipEncoding encoding;
    encoding.threads = 2;
    writeBytes(path, bytesOf(encodeZipExr(image.header, image.frameBuffer, encoding)));
    const std::string reference = dir.file("openexr.exr");
    openExrFile(image, reference);

    // The same pixel hash as OpenEXR's own file, and a lossless copy that holds the bits.
    const std::string hashes =
        run("oiiotool --info --hash '" + path + "' '" + reference + "'", status);
    ASSERT_EQ(status, 0) << hashes;
    const auto first = hashes.find("SHA-1: ");
    const auto second = hashes.find("SHA-1: ", first + 1);
    ASSERT_NE(second, std::string::npos) << hashes;
    EXPECT_EQ(hashes.substr(first + 7, 40), hashes.substr(second + 7, 40)) << hashes;
    const std::string copy = dir.file("copy.exr");
    const std::string out =
        run("oiiotool '" + path + "' --compression none -o '" + copy + "'", status);
    ASSERT_EQ(status, 0) << out;
    EXPECT_TRUE(sameBits(decode(copy), decode(reference)));
    EXPECT_EQ(decode(copy)[2], image.px) << "P.X, bit for bit";
  }
}

}  // namespace
}  // namespace drivenshape::testing
