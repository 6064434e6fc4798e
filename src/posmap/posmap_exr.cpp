// Position-map EXR files (layout and attributes: position_map.h).

#include <drivenshape/position_map.h>

#include <Imath/half.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfFramesPerSecond.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <OpenEXR/ImfStandardAttributes.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenEXR/ImfVecAttribute.h>

#include <cmath>
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

}  // namespace drivenshape
