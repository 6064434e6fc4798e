#include "exr_common.h"

#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStdIO.h>

#include <exception>
#include <fstream>

#include <drivenshape/atomic_file.h>
#include <drivenshape/error.h>

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
