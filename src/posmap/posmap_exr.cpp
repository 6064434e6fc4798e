// Position-map EXR files (layout and attributes: position_map.h).

#include <drivenshape/position_map.h>

#include <Imath/half.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfFramesPerSecond.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <OpenEXR/ImfStandardAttributes.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenEXR/ImfVecAttribute.h>

#include <cmath>
#include <filesystem>
#include <optional>
#include <vector>

#include <drivenshape/error.h>
#include <drivenshape/hash.h>
#include <drivenshape/version.h>

#include "exr_common.h"

namespace drivenshape {
namespace {

using namespace exr_detail;  // the names shared with the other EXR kind

// Header attributes of position maps only (all well under OpenEXR's 31-byte limit). The names
// shared with point-cache EXRs (dsFrame, dsTopologyHash, dsToolVersion, dsBounds*, the P, N and
// A channels) are in io/exr_common.h and mean the same thing in both.
constexpr const char* kAttrKind = "dsKind";
constexpr const char* kKindValue = "positionMap";
constexpr const char* kAttrMeshVertexCount = "dsMeshVertexCount";
constexpr const char* kAttrPadding = "dsPadding";
constexpr const char* kAttrUvLayout = "dsUvLayout";
constexpr const char* kUvLayoutValue =
    "texel (x,y) centre = (u,v) = ((x+0.5)/W, 1-(y+0.5)/H); row 0 is v = 1 (top)";

}  // namespace

void writePositionMapExr(const std::string& path, int width, int height, const float* positions,
                         const float* coverage, const float* normals,
                         const PositionMapFrameHeader& header) {
  if (width < 1 || height < 1 || width > kMaxPositionMapSide || height > kMaxPositionMapSide) {
    DS_THROW(kUsage, "position map size ", width, "x", height, " is outside 1..",
             kMaxPositionMapSide, " texels per side (", path, ")");
  }
  if (!(header.framesPerSecond > 0.0) || !std::isfinite(header.framesPerSecond)) {
    DS_THROW(kUsage, "frames per second ", header.framesPerSecond, " must be positive (", path,
             ")");
  }
  if (positions == nullptr || coverage == nullptr) {
    DS_THROW(kInternal, "writePositionMapExr '", path, "': no positions or coverage");
  }
  const std::size_t rowTexels = static_cast<std::size_t>(width);

  writeExrAtomically(path, "position-map", [&](const std::string& tempPath) {
    Imf::Header exrHeader(width, height);
    exrHeader.compression() = toImf(header.compression);
    for (const char* name : kPositionChannels) {
      exrHeader.channels().insert(name, Imf::Channel(Imf::FLOAT));
    }
    exrHeader.channels().insert(kCoverageChannel, Imf::Channel(Imf::FLOAT));
    if (normals != nullptr) {
      const Imf::PixelType type = header.halfNormals ? Imf::HALF : Imf::FLOAT;
      for (const char* name : kNormalChannels) {
        exrHeader.channels().insert(name, Imf::Channel(type));
      }
    }
    exrHeader.insert(kAttrKind, Imf::StringAttribute(kKindValue));
    exrHeader.insert(kAttrFrame, Imf::IntAttribute(header.frame));
    exrHeader.insert(kAttrTopologyHash, Imf::StringAttribute(hashToHex(header.topologyHash)));
    exrHeader.insert(kAttrToolVersion, Imf::StringAttribute(kVersion));
    exrHeader.insert(kAttrMeshVertexCount, Imf::IntAttribute(header.meshVertexCount));
    const Bounds& b = header.bounds;
    exrHeader.insert(kAttrBoundsMin,
                     Imf::V3fAttribute(Imath::V3f(b.min.x(), b.min.y(), b.min.z())));
    exrHeader.insert(kAttrBoundsMax,
                     Imf::V3fAttribute(Imath::V3f(b.max.x(), b.max.y(), b.max.z())));
    exrHeader.insert(kAttrPadding, Imf::IntAttribute(header.padding));
    exrHeader.insert(kAttrUvLayout, Imf::StringAttribute(kUvLayoutValue));
    Imf::addFramesPerSecond(exrHeader, Imf::guessExactFps(header.framesPerSecond));

    Imf::FrameBuffer frameBuffer;
    insertXyzSlices(frameBuffer, kPositionChannels, positions, rowTexels);
    frameBuffer.insert(kCoverageChannel,
                       Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(const_cast<float*>(coverage)),
                                  sizeof(float), sizeof(float) * rowTexels));
    // OpenEXR does not convert FLOAT slices to HALF channels on write: round here.
    std::vector<half> halfNormals;
    if (normals != nullptr && header.halfNormals) {
      const std::size_t count = 3 * rowTexels * static_cast<std::size_t>(height);
      halfNormals.resize(count);
      for (std::size_t i = 0; i < count; ++i) {
        halfNormals[i] = half(normals[i]);
      }
      char* bytes = reinterpret_cast<char*>(halfNormals.data());
      for (int k = 0; k < 3; ++k) {
        frameBuffer.insert(kNormalChannels[k],
                           Imf::Slice(Imf::HALF, bytes + k * sizeof(half), 3 * sizeof(half),
                                      3 * sizeof(half) * rowTexels));
      }
    } else if (normals != nullptr) {
      insertXyzSlices(frameBuffer, kNormalChannels, normals, rowTexels);
    }

    writeScanlines(path, tempPath, exrHeader, frameBuffer, height);
  });
}

namespace {

/// The header of `path` if it is a position map, else nothing; Error(kInput) on a bad hash.
std::optional<PositionMapInfo> positionMapHeader(const std::string& path) {
  const auto file = openExr(path, "position-map");
  const Imf::Header& header = file->header();
  const auto* kind = header.findTypedAttribute<Imf::StringAttribute>(kAttrKind);
  if (kind == nullptr || kind->value() != kKindValue) {
    return std::nullopt;
  }
  PositionMapInfo info;
  static_cast<ExrSharedHeader&>(info) = readSharedHeader(path, header);
  const Imath::Box2i& window = header.dataWindow();
  info.width = window.max.x - window.min.x + 1;
  info.height = window.max.y - window.min.y + 1;
  if (const auto* count = header.findTypedAttribute<Imf::IntAttribute>(kAttrMeshVertexCount)) {
    info.meshVertexCount = count->value();
  }
  if (const auto* padding = header.findTypedAttribute<Imf::IntAttribute>(kAttrPadding)) {
    info.padding = padding->value();
  }
  if (info.hasNormals) {
    info.halfNormals = header.channels().findChannel(kNormalChannels[0])->type == Imf::HALF;
  }
  return info;
}

}  // namespace

bool isPositionMapExr(const std::string& path) {
  try {
    return positionMapHeader(path).has_value();
  } catch (const std::exception&) {
    return false;
  }
}

PositionMapInfo readPositionMapExrInfo(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    DS_THROW(kInput, "position-map EXR '", path, "' does not exist");
  }
  std::optional<PositionMapInfo> info;
  try {
    info = positionMapHeader(path);
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    DS_THROW(kInput, "cannot read EXR '", path, "': ", e.what());
  }
  if (!info) {
    DS_THROW(kInput, path, ": not a drivenshape position map (no ", kAttrKind, " '", kKindValue,
             "' attribute); `drivenshape info` describes point caches too");
  }
  return *info;
}

}  // namespace drivenshape
