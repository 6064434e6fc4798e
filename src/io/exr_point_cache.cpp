// SPDX-License-Identifier: Apache-2.0
#include <drivenshape/point_cache.h>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfFramesPerSecond.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <OpenEXR/ImfStandardAttributes.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenEXR/ImfVecAttribute.h>

#include <zlib.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <utility>

#include <drivenshape/error.h>
#include <drivenshape/version.h>

#include "hash.h"

#include "exr_common.h"

namespace drivenshape {
namespace {

using namespace exr_detail;  // the names shared with the other EXR kind

// Header attributes of point caches only (the shared names: exr_common.h).
constexpr const char* kAttrVertexCount = "dsVertexCount";
constexpr const char* kAttrSettingsHash = "dsSettingsHash";
constexpr const char* kAttrPixelsCrc = "dsPixelsCrc32";

/// Running zlib CRC-32 over float planes (the hosts we build for are little-endian, so the
/// bytes in memory are the bytes in the file).
class PlaneCrc {
 public:
  /// Adds `count` floats read `stride` floats apart, starting at `values`.
  void add(const float* values, std::size_t count, std::size_t stride) {
    float buffer[4096];
    for (std::size_t done = 0; done < count;) {
      const std::size_t step = std::min<std::size_t>(count - done, 4096);
      for (std::size_t i = 0; i < step; ++i) {
        buffer[i] = values[(done + i) * stride];
      }
      mCrc = crc32(mCrc, reinterpret_cast<const Bytef*>(buffer),
                   static_cast<uInt>(step * sizeof(float)));
      done += step;
    }
  }
  std::uint32_t value() const { return static_cast<std::uint32_t>(mCrc); }

 private:
  uLong mCrc = crc32(0L, Z_NULL, 0);
};

std::string crcText(std::uint32_t crc) {
  char text[9];
  std::snprintf(text, sizeof(text), "%08x", static_cast<unsigned>(crc));
  return text;
}

/// Interleaved xyz of W * H pixels: the V vertices, then zero padding.
std::vector<float> paddedXyz(const float* xyz, int vertexCount, std::size_t pixels) {
  std::vector<float> padded(pixels * 3, 0.0f);
  std::copy(xyz, xyz + 3 * static_cast<std::size_t>(vertexCount), padded.begin());
  return padded;
}

void checkExists(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    DS_THROW(kInput, "point-cache EXR '", path, "' does not exist");
  }
}

/// Extra attribute names: 1..31 bytes (OpenEXR's limit), unique, and none of the names this
/// writer sets itself or OpenEXR requires.
void checkStringAttributes(const std::string& path, const ExrWriteOptions& options) {
  static const char* const kReserved[] = {kAttrVertexCount,  kAttrFrame,     kAttrTopologyHash,
                                          kAttrToolVersion,  kAttrBoundsMin, kAttrBoundsMax,
                                          kAttrSettingsHash, kAttrPixelsCrc};
  const Imf::Header standard(1, 1);
  for (std::size_t i = 0; i < options.stringAttributes.size(); ++i) {
    const std::string& name = options.stringAttributes[i].first;
    bool clash = name.empty() || name.size() > 31 || standard.find(name) != standard.end() ||
                 name == "framesPerSecond";
    for (const char* reserved : kReserved) {
      clash = clash || name == reserved;
    }
    for (std::size_t j = 0; j < i; ++j) {
      clash = clash || options.stringAttributes[j].first == name;
    }
    if (clash) {
      DS_THROW(kUsage, "EXR attribute name '", name, "' for ", path,
               " is empty, longer than 31 bytes, repeated or reserved by the point-cache format");
    }
  }
}

/// Every string attribute that is not one of ours.
std::map<std::string, std::string> extraStrings(const Imf::Header& header) {
  std::map<std::string, std::string> strings;
  for (auto it = header.begin(); it != header.end(); ++it) {
    const std::string name = it.name();
    if (name == kAttrTopologyHash || name == kAttrToolVersion || name == kAttrSettingsHash ||
        name == kAttrPixelsCrc) {
      continue;
    }
    if (const auto* text = dynamic_cast<const Imf::StringAttribute*>(&it.attribute())) {
      strings[name] = text->value();
    }
  }
  return strings;
}

/// Header -> info, with every check that needs no pixels.
ExrPointCacheInfo parseHeader(const std::string& path, const Imf::Header& header) {
  ExrPointCacheInfo info;
  const auto* vertexCount = header.findTypedAttribute<Imf::IntAttribute>(kAttrVertexCount);
  if (vertexCount == nullptr) {
    DS_THROW(kInput, path, ": not a drivenshape point cache (no ", kAttrVertexCount, " attribute)");
  }
  info.vertexCount = vertexCount->value();
  if (info.vertexCount <= 0) {
    DS_THROW(kInput, path, ": ", kAttrVertexCount, " is ", info.vertexCount,
             "; a point cache holds at least one vertex");
  }
  static_cast<ExrSharedHeader&>(info) = readSharedHeader(path, header);
  if (const auto* hash = header.findTypedAttribute<Imf::StringAttribute>(kAttrSettingsHash)) {
    if (!hexToHash(hash->value(), info.settingsHash)) {
      DS_THROW(kInput, path, ": ", kAttrSettingsHash, " '", hash->value(),
               "' is not 16 hex digits");
    }
  }
  if (const auto* crc = header.findTypedAttribute<Imf::StringAttribute>(kAttrPixelsCrc)) {
    std::uint64_t value = 0;
    if (crc->value().size() != 8 || !hexToHash("00000000" + crc->value(), value)) {
      DS_THROW(kInput, path, ": ", kAttrPixelsCrc, " '", crc->value(), "' is not 8 hex digits");
    }
    info.pixelsCrc = static_cast<std::uint32_t>(value);
    info.hasPixelsCrc = true;
  }
  info.stringAttributes = extraStrings(header);

  const Imath::Box2i& window = header.dataWindow();
  const long long width = static_cast<long long>(window.max.x) - window.min.x + 1;
  const long long height = static_cast<long long>(window.max.y) - window.min.y + 1;
  info.width = static_cast<int>(width);
  if (width <= 0 || height <= 0 || (info.vertexCount + width - 1) / width != height) {
    DS_THROW(kInput, path, ": the image is ", width, "x", height, " pixels but ", kAttrVertexCount,
             " is ", info.vertexCount, " (a ", width, "-wide image needs ",
             width > 0 ? (info.vertexCount + width - 1) / width : 0,
             " rows); the file was not written by drivenshape or was modified");
  }
  return info;
}

std::string hashText(std::uint64_t hash) {
  return hash == 0 ? "none" : hashToHex(hash);
}

}  // namespace

ExrCompression parseExrCompression(const std::string& text) {
  std::string lower = text;
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](unsigned char ch) { return static_cast<char>(std::tolower(ch)); });
  for (ExrCompression compression :
       {ExrCompression::kZip, ExrCompression::kNone, ExrCompression::kZips, ExrCompression::kPiz}) {
    if (lower == exrCompressionName(compression)) {
      return compression;
    }
  }
  DS_THROW(kUsage, "unknown EXR compression '", text,
           "'; use zip, none, zips or piz (lossless codecs only)");
}

const char* exrCompressionName(ExrCompression compression) {
  switch (compression) {
    case ExrCompression::kZip:
      return "zip";
    case ExrCompression::kNone:
      return "none";
    case ExrCompression::kZips:
      return "zips";
    case ExrCompression::kPiz:
      return "piz";
  }
  return "zip";
}

ZipEncoder parseZipEncoder(const std::string& text, const std::string& flag) {
  std::string lower = text;
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](unsigned char ch) { return static_cast<char>(std::tolower(ch)); });
  for (ZipEncoder encoder : {ZipEncoder::kLibdeflate, ZipEncoder::kOpenExr}) {
    if (lower == zipEncoderName(encoder)) {
      return encoder;
    }
  }
  DS_THROW(kUsage, "unknown ", flag, " '", text,
           "'; use libdeflate (the default) or openexr (OpenEXR's own zlib writer: the bytes of "
           "earlier builds)");
}

const char* zipEncoderName(ZipEncoder encoder) {
  return encoder == ZipEncoder::kOpenExr ? "openexr" : "libdeflate";
}

void writePointCacheExr(const std::string& path, int vertexCount, const float* xyz,
                        const float* normals, const ExrWriteOptions& options) {
  if (options.width <= 0 || options.width > kMaxPointCacheExrWidth) {
    DS_THROW(kUsage, "EXR point-cache width ", options.width, " is outside 1..",
             kMaxPointCacheExrWidth, " (", path, ")");
  }
  if (!(options.framesPerSecond > 0.0) || !std::isfinite(options.framesPerSecond)) {
    DS_THROW(kUsage, "frames per second ", options.framesPerSecond, " must be positive (", path,
             ")");
  }
  if (vertexCount <= 0 || xyz == nullptr) {
    DS_THROW(kUsage, "point-cache EXR '", path, "': ", vertexCount,
             " vertices to write; a point cache holds at least one vertex");
  }
  checkStringAttributes(path, options);
  const std::size_t width = static_cast<std::size_t>(options.width);
  const std::size_t height = (static_cast<std::size_t>(vertexCount) + width - 1) / width;
  const std::size_t pixels = width * height;

  writeExrAtomically(
      path, "point-cache",
      [&](std::ostream& stream) {
        std::vector<float> positions = paddedXyz(xyz, vertexCount, pixels);
        std::vector<float> normalData;
        if (normals != nullptr) {
          normalData = paddedXyz(normals, vertexCount, pixels);
        }
        std::vector<float> coverage(pixels, 0.0f);
        std::fill(coverage.begin(), coverage.begin() + vertexCount, 1.0f);

        Imf::Header header(options.width, static_cast<int>(height));
        header.compression() = toImf(options.compression);
        for (const char* name : kPositionChannels) {
          header.channels().insert(name, Imf::Channel(Imf::FLOAT));
        }
        header.channels().insert(kCoverageChannel, Imf::Channel(Imf::FLOAT));
        if (normals != nullptr) {
          for (const char* name : kNormalChannels) {
            header.channels().insert(name, Imf::Channel(Imf::FLOAT));
          }
        }
        const Bounds bounds = computeBounds(xyz, vertexCount);
        header.insert(kAttrVertexCount, Imf::IntAttribute(vertexCount));
        header.insert(kAttrFrame, Imf::IntAttribute(options.frame));
        header.insert(kAttrTopologyHash, Imf::StringAttribute(hashToHex(options.topologyHash)));
        header.insert(kAttrToolVersion, Imf::StringAttribute(kVersion));
        header.insert(kAttrBoundsMin, Imf::V3fAttribute(Imath::V3f(bounds.min.x(), bounds.min.y(),
                                                                   bounds.min.z())));
        header.insert(kAttrBoundsMax, Imf::V3fAttribute(Imath::V3f(bounds.max.x(), bounds.max.y(),
                                                                   bounds.max.z())));
        // Channels in the file's order: A, N.X, N.Y, N.Z, P.X, P.Y, P.Z.
        PlaneCrc crc;
        crc.add(coverage.data(), pixels, 1);
        for (int k = 0; k < 3 && normals != nullptr; ++k) {
          crc.add(normalData.data() + k, pixels, 3);
        }
        for (int k = 0; k < 3; ++k) {
          crc.add(positions.data() + k, pixels, 3);
        }
        header.insert(kAttrPixelsCrc, Imf::StringAttribute(crcText(crc.value())));
        if (options.settingsHash != 0) {
          header.insert(kAttrSettingsHash, Imf::StringAttribute(hashToHex(options.settingsHash)));
        }
        Imf::addFramesPerSecond(header, Imf::guessExactFps(options.framesPerSecond));
        for (const auto& [name, value] : options.stringAttributes) {
          header.insert(name, Imf::StringAttribute(value));
        }

        Imf::FrameBuffer frameBuffer;
        insertXyzSlices(frameBuffer, kPositionChannels, positions.data(), width);
        frameBuffer.insert(kCoverageChannel,
                           Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(coverage.data()),
                                      sizeof(float), sizeof(float) * width));
        if (normals != nullptr) {
          insertXyzSlices(frameBuffer, kNormalChannels, normalData.data(), width);
        }

        writeScanlines(path, stream, header, frameBuffer, static_cast<int>(height),
                       options.zipEncoder, options.encodeThreads);
      },
      options.syncToDisk);
}

ExrPointCacheInfo readPointCacheExrInfo(const std::string& path) {
  checkExists(path);
  try {
    const auto file = openExr(path, "point-cache");
    return parseHeader(path, file->header());
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    DS_THROW(kInput, "cannot read EXR '", path, "': ", e.what());
  }
}

ExrPointCacheInfo readPointCacheExr(const std::string& path, std::vector<float>& xyz,
                                    int expectedVertexCount, std::uint64_t expectedTopology) {
  checkExists(path);
  try {
    const auto file = openExr(path, "point-cache");
    const Imf::Header& header = file->header();
    const ExrPointCacheInfo info = parseHeader(path, header);
    if (expectedVertexCount != 0 && expectedVertexCount != info.vertexCount) {
      DS_THROW(kInput, path, ": the cache holds ", info.vertexCount, " vertices but ",
               expectedVertexCount,
               " are expected; the cache was baked for another mesh; rebake it or pass the "
               "matching mesh");
    }
    // A file without a recorded topology (hash 0) cannot be checked; its vertex count was.
    if (expectedTopology != 0 && info.topologyHash != 0 && expectedTopology != info.topologyHash) {
      DS_THROW(kInput, path, ": topology hash ", hashText(info.topologyHash), " differs from ",
               hashToHex(expectedTopology),
               " (same vertex count, different faces); the cache was baked for another mesh; "
               "rebake it or pass the matching mesh");
    }
    for (const char* name : kPositionChannels) {
      if (header.channels().findChannel(name) == nullptr) {
        DS_THROW(kInput, path, ": channel ", name,
                 " is missing; a point cache needs P.X, P.Y and P.Z");
      }
    }
    const Imath::Box2i& window = header.dataWindow();
    const std::size_t width = static_cast<std::size_t>(info.width);
    const std::size_t height = static_cast<std::size_t>(window.max.y - window.min.y + 1);
    xyz.assign(width * height * 3, 0.0f);
    // OpenEXR addresses slices from the data window origin, which may be nonzero.
    const std::ptrdiff_t origin =
        static_cast<std::ptrdiff_t>(window.min.x) +
        static_cast<std::ptrdiff_t>(window.min.y) * static_cast<std::ptrdiff_t>(width);
    char* base = reinterpret_cast<char*>(xyz.data()) -
                 origin * static_cast<std::ptrdiff_t>(3 * sizeof(float));
    Imf::FrameBuffer frameBuffer;
    for (int k = 0; k < 3; ++k) {
      frameBuffer.insert(kPositionChannels[k],
                         Imf::Slice(Imf::FLOAT, base + k * sizeof(float), 3 * sizeof(float),
                                    3 * sizeof(float) * width));
    }
    file->setFrameBuffer(frameBuffer);
    file->readPixels(window.min.y, window.max.y);
    xyz.resize(3 * static_cast<std::size_t>(info.vertexCount));
    return info;
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    DS_THROW(kInput, "cannot read point-cache EXR '", path, "': ", e.what());
  }
}

namespace {

/// Decodes every channel of `file` as float planes and returns the CRC of them (PlaneCrc, in
/// the channel list's order, which is the order the writer used).
std::uint32_t decodedPixelsCrc(Imf::InputFile& file) {
  const Imath::Box2i& window = file.header().dataWindow();
  const std::size_t width = static_cast<std::size_t>(window.max.x - window.min.x + 1);
  const std::size_t height = static_cast<std::size_t>(window.max.y - window.min.y + 1);
  const std::size_t pixels = width * height;
  const std::ptrdiff_t origin =
      static_cast<std::ptrdiff_t>(window.min.x) +
      static_cast<std::ptrdiff_t>(window.min.y) * static_cast<std::ptrdiff_t>(width);
  const Imf::ChannelList& channels = file.header().channels();
  std::vector<std::vector<float>> planes;
  Imf::FrameBuffer frameBuffer;
  for (auto it = channels.begin(); it != channels.end(); ++it) {
    planes.emplace_back(pixels, 0.0f);
    char* base = reinterpret_cast<char*>(planes.back().data()) -
                 origin * static_cast<std::ptrdiff_t>(sizeof(float));
    frameBuffer.insert(it.name(),
                       Imf::Slice(Imf::FLOAT, base, sizeof(float), sizeof(float) * width));
  }
  file.setFrameBuffer(frameBuffer);
  file.readPixels(window.min.y, window.max.y);
  PlaneCrc crc;
  for (const std::vector<float>& plane : planes) {
    crc.add(plane.data(), plane.size(), 1);
  }
  return crc.value();
}

}  // namespace

std::string reuseProblem(const std::string& path, int vertexCount, std::uint64_t topology,
                         std::uint64_t settings, int frame, ExrPointCacheInfo* header) {
  if (!isCompleteExr(path)) {
    return "is incomplete: scan lines are missing or cut short";
  }
  ExrPointCacheInfo info;
  std::uint32_t crc = 0;
  try {
    const auto file = openExr(path, "point-cache");  // one open for the header and the pixels
    info = parseHeader(path, file->header());
    crc = decodedPixelsCrc(*file);
  } catch (const std::exception& error) {
    return std::string("does not decode: ") + error.what();
  }
  std::ostringstream problem;
  if (info.vertexCount != vertexCount) {
    problem << "holds " << info.vertexCount << " vertices, not " << vertexCount;
  } else if (info.topologyHash != topology) {
    problem << "has topology " << hashText(info.topologyHash) << ", not this mesh's "
            << hashToHex(topology);
  } else if (info.settingsHash != settings) {
    problem << "was baked with other settings (" << hashText(info.settingsHash) << ", now "
            << hashToHex(settings) << ")";
  } else if (info.frame != frame) {
    problem << "holds frame " << info.frame;
  } else if (!info.hasPixelsCrc) {
    problem << "has no " << kAttrPixelsCrc << " to verify its pixels";
  } else if (crc != info.pixelsCrc) {
    problem << "does not match its pixel checksum (" << crcText(crc) << " decoded, "
            << crcText(info.pixelsCrc) << " written): it was damaged after it was written";
  }
  if (header != nullptr && problem.str().empty()) {
    *header = std::move(info);
  }
  return problem.str();
}

bool isCompleteExr(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    return false;
  }
  try {
    const auto opened = openExr(path, "point-cache");
    Imf::InputFile& file = *opened;
    if (!file.isComplete()) {
      return false;
    }
    // isComplete() only looks at the offset table, which survives when a copy loses its
    // tail. Reading the raw first and last chunks finds that: they are the last chunk in the
    // file for increasing and decreasing line order.
    const Imath::Box2i& window = file.header().dataWindow();
    const char* data = nullptr;
    int size = 0;
    file.rawPixelData(window.min.y, data, size);
    file.rawPixelData(window.max.y, data, size);
    return true;
  } catch (const std::exception&) {
    return false;
  }
}

}  // namespace drivenshape
