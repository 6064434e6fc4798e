// Position-map EXR files (layout and attributes: position_map.h).

#include <drivenshape/position_map.h>

#include <Imath/half.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfFramesPerSecond.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStandardAttributes.h>
#include <OpenEXR/ImfStdIO.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenEXR/ImfVecAttribute.h>

#include <cmath>
#include <fstream>
#include <vector>

#include <drivenshape/atomic_file.h>
#include <drivenshape/error.h>
#include <drivenshape/hash.h>
#include <drivenshape/version.h>

namespace drivenshape {
namespace {

// Header attribute and channel names (all well under OpenEXR's 31-byte limit). dsFrame,
// dsTopologyHash, dsToolVersion and dsBounds* mean what they mean in point-cache EXRs.
constexpr const char* kAttrKind = "dsKind";
constexpr const char* kKindValue = "positionMap";
constexpr const char* kAttrFrame = "dsFrame";
constexpr const char* kAttrTopologyHash = "dsTopologyHash";
constexpr const char* kAttrToolVersion = "dsToolVersion";
constexpr const char* kAttrMeshVertexCount = "dsMeshVertexCount";
constexpr const char* kAttrBoundsMin = "dsBoundsMin";
constexpr const char* kAttrBoundsMax = "dsBoundsMax";
constexpr const char* kAttrPadding = "dsPadding";
constexpr const char* kAttrUvLayout = "dsUvLayout";
constexpr const char* kUvLayoutValue =
    "texel (x,y) centre = (u,v) = ((x+0.5)/W, 1-(y+0.5)/H); row 0 is v = 1 (top)";
constexpr const char* kPositionChannels[3] = {"P.X", "P.Y", "P.Z"};
constexpr const char* kNormalChannels[3] = {"N.X", "N.Y", "N.Z"};
constexpr const char* kCoverageChannel = "A";

Imf::Compression toImf(ExrCompression compression) {
  switch (compression) {
    case ExrCompression::kZip:
      return Imf::ZIP_COMPRESSION;
    case ExrCompression::kNone:
      return Imf::NO_COMPRESSION;
    case ExrCompression::kZips:
      return Imf::ZIPS_COMPRESSION;
    case ExrCompression::kPiz:
      return Imf::PIZ_COMPRESSION;
  }
  return Imf::ZIP_COMPRESSION;
}

/// Slices of an interleaved xyz image (3 floats per texel) for three channels.
void insertXyz(Imf::FrameBuffer& frameBuffer, const char* const names[3], const float* base,
               std::size_t width) {
  char* bytes = reinterpret_cast<char*>(const_cast<float*>(base));
  for (int k = 0; k < 3; ++k) {
    frameBuffer.insert(names[k], Imf::Slice(Imf::FLOAT, bytes + k * sizeof(float),
                                            3 * sizeof(float), 3 * sizeof(float) * width));
  }
}

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

  AtomicFile atomic(path);
  try {
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
    insertXyz(frameBuffer, kPositionChannels, positions, rowTexels);
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
      insertXyz(frameBuffer, kNormalChannels, normals, rowTexels);
    }

    // Our own stream, so that a failure while OpenEXR's destructor writes the offset table
    // (which it swallows) still shows up in the stream state below.
    std::ofstream stream(atomic.tempPath(), std::ios::binary | std::ios::trunc);
    if (!stream) {
      DS_THROW(kOutput, "cannot create '", path, "' (temporary file ", atomic.tempPath(), ")");
    }
    {
      Imf::StdOFStream exrStream(stream, atomic.tempPath().c_str());
      Imf::OutputFile file(exrStream, exrHeader);
      file.setFrameBuffer(frameBuffer);
      file.writePixels(height);
    }
    stream.flush();
    stream.close();
    if (stream.fail()) {
      DS_THROW(kOutput, "cannot write '", path, "'; is the disk full?");
    }
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    DS_THROW(kOutput, "cannot write position-map EXR '", path, "': ", e.what());
  }
  atomic.commit();
}

}  // namespace drivenshape
