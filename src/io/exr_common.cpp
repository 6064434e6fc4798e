#include "exr_common.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStandardAttributes.h>
#include <OpenEXR/ImfStdIO.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenEXR/ImfVecAttribute.h>

#include <exception>
#include <fstream>

#include <drivenshape/atomic_file.h>
#include <drivenshape/error.h>
#include <drivenshape/hash.h>

namespace drivenshape::exr_detail {

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

ExrCompression fromImf(Imf::Compression compression) {
  switch (compression) {
    case Imf::NO_COMPRESSION:
    case Imf::RLE_COMPRESSION:
      return ExrCompression::kNone;
    case Imf::ZIPS_COMPRESSION:
      return ExrCompression::kZips;
    case Imf::PIZ_COMPRESSION:
      return ExrCompression::kPiz;
    default:
      return ExrCompression::kZip;
  }
}

ExrSharedHeader readSharedHeader(const std::string& path, const Imf::Header& header) {
  ExrSharedHeader shared;
  if (const auto* frame = header.findTypedAttribute<Imf::IntAttribute>(kAttrFrame)) {
    shared.frame = frame->value();
  }
  if (const auto* hash = header.findTypedAttribute<Imf::StringAttribute>(kAttrTopologyHash)) {
    if (!hexToHash(hash->value(), shared.topologyHash)) {
      DS_THROW(kInput, path, ": ", kAttrTopologyHash, " '", hash->value(),
               "' is not 16 hex digits");
    }
  }
  if (const auto* version = header.findTypedAttribute<Imf::StringAttribute>(kAttrToolVersion)) {
    shared.toolVersion = version->value();
  }
  const auto* boundsMin = header.findTypedAttribute<Imf::V3fAttribute>(kAttrBoundsMin);
  const auto* boundsMax = header.findTypedAttribute<Imf::V3fAttribute>(kAttrBoundsMax);
  if (boundsMin != nullptr && boundsMax != nullptr) {
    const Imath::V3f& lo = boundsMin->value();
    const Imath::V3f& hi = boundsMax->value();
    shared.bounds.min = Eigen::Vector3f(lo.x, lo.y, lo.z);
    shared.bounds.max = Eigen::Vector3f(hi.x, hi.y, hi.z);
  }
  if (Imf::hasFramesPerSecond(header)) {
    shared.framesPerSecond = static_cast<double>(Imf::framesPerSecond(header));
  }
  const Imf::ChannelList& channels = header.channels();
  shared.hasNormals = channels.findChannel(kNormalChannels[0]) != nullptr &&
                      channels.findChannel(kNormalChannels[1]) != nullptr &&
                      channels.findChannel(kNormalChannels[2]) != nullptr;
  shared.compression = fromImf(header.compression());
  return shared;
}

void insertXyzSlices(Imf::FrameBuffer& frameBuffer, const char* const names[3], const float* base,
                     std::size_t width) {
  char* bytes = reinterpret_cast<char*>(const_cast<float*>(base));
  for (int k = 0; k < 3; ++k) {
    frameBuffer.insert(names[k], Imf::Slice(Imf::FLOAT, bytes + k * sizeof(float),
                                            3 * sizeof(float), 3 * sizeof(float) * width));
  }
}

void writeExrAtomically(const std::string& path, const char* kind,
                        const std::function<void(const std::string& tempPath)>& body,
                        bool syncToDisk) {
  AtomicFile atomic(path);
  try {
    body(atomic.tempPath());
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    DS_THROW(kOutput, "cannot write ", kind, " EXR '", path, "': ", e.what());
  }
  atomic.commit(syncToDisk);
}

void writeScanlines(const std::string& path, const std::string& tempPath, const Imf::Header& header,
                    const Imf::FrameBuffer& frameBuffer, int height) {
  std::ofstream stream(tempPath, std::ios::binary | std::ios::trunc);
  if (!stream) {
    DS_THROW(kOutput, "cannot create '", path, "' (temporary file ", tempPath, ")");
  }
  {
    Imf::StdOFStream exrStream(stream, tempPath.c_str());
    Imf::OutputFile file(exrStream, header);
    file.setFrameBuffer(frameBuffer);
    file.writePixels(height);
  }
  stream.flush();
  stream.close();
  if (stream.fail()) {
    DS_THROW(kOutput, "cannot write '", path, "'; is the disk full?");
  }
}

}  // namespace drivenshape::exr_detail
