// SPDX-License-Identifier: Apache-2.0
#include "exr_common.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfIO.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStandardAttributes.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenEXR/ImfVecAttribute.h>

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <map>
#include <vector>

#include <drivenshape/error.h>

#include "atomic_file.h"
#include "exr_zip_writer.h"
#include "hash.h"

namespace drivenshape::exr_detail {
// Named, not anonymous: classes declared in headers hold these types (GCC's
// -Wsubobject-linkage in unity builds).
namespace exr_streams {

/// OpenEXR's output stream over a std::ostream (Imf::StdOFStream takes only a std::ofstream,
/// which would have to open the file by its name again).
class ExrOStream : public Imf::OStream {
 public:
  ExrOStream(std::ostream& stream, const std::string& path)
      : Imf::OStream(path.c_str()), mStream(stream), mPath(path) {}
  void write(const char data[], int count) override {
    errno = 0;
    mStream.write(data, count);
    check();
  }
  std::uint64_t tellp() override { return static_cast<std::uint64_t>(mStream.tellp()); }
  void seekp(std::uint64_t position) override {
    mStream.seekp(static_cast<std::streamoff>(position));
    check();
  }

 private:
  void check() const {
    if (!mStream) {
      DS_THROW(kOutput, "cannot write '", mPath, "': ", std::strerror(errno != 0 ? errno : EIO),
               "; is the disk full?");
    }
  }
  std::ostream& mStream;
  std::string mPath;
};

/// The fields of a header that size what OpenEXR and our readers allocate.
struct RawHeader {
  bool hasWindow = false;
  std::int64_t minX = 0, minY = 0, maxX = -1, maxY = -1;
  std::uint64_t bytesPerPixel = 0;
};

/// Reads the header of an OpenEXR file byte by byte (the layout of the OpenEXR file format
/// document: magic, version and flags, then name/type/size/value attributes up to an empty
/// name), checking every size against the bytes the file has before anything is allocated.
class HeaderScan {
 public:
  HeaderScan(const std::string& path, const char* kind, std::uint64_t fileSize)
      : mPath(path), mKind(kind), mFileSize(fileSize), mIn(path, std::ios::binary) {
    if (!mIn) {
      DS_THROW(kInput, "cannot open ", kind, " EXR '", path, "': ", std::strerror(errno));
    }
  }

  RawHeader scan() {
    unsigned char prefix[8];
    readBytes(prefix, sizeof(prefix));
    if (prefix[0] != 0x76 || prefix[1] != 0x2f || prefix[2] != 0x31 || prefix[3] != 0x01) {
      fail("is not an OpenEXR file (no EXR magic number)");
    }
    const unsigned flags = static_cast<unsigned>(prefix[5]) << 8;
    if ((flags & 0x1a00u) != 0) {  // tiled 0x200, deep 0x800, multi-part 0x1000
      fail("is a ",
           (flags & 0x1000u)  ? "multi-part"
           : (flags & 0x800u) ? "deep"
                              : "tiled",
           " image; drivenshape reads single-part scan-line EXRs: save it as scan lines");
    }
    const std::size_t maxName = (flags & 0x400u) ? 255 : 31;
    RawHeader header;
    for (;;) {
      const std::string name = readName(maxName);
      if (name.empty()) {
        return header;
      }
      const std::string type = readName(maxName);
      unsigned char sizeBytes[4];
      readBytes(sizeBytes, 4);
      const std::int32_t size = static_cast<std::int32_t>(
          static_cast<std::uint32_t>(sizeBytes[0]) | static_cast<std::uint32_t>(sizeBytes[1]) << 8 |
          static_cast<std::uint32_t>(sizeBytes[2]) << 16 |
          static_cast<std::uint32_t>(sizeBytes[3]) << 24);
      const std::uint64_t left = mFileSize - mOffset;
      if (size < 0 || static_cast<std::uint64_t>(size) > left) {
        fail("header attribute '", name, "' claims ", size, " bytes where the file has ", left,
             " left; the file is corrupt");
      }
      std::vector<unsigned char> value(static_cast<std::size_t>(size));
      readBytes(value.data(), value.size());
      checkValueSize(name, type, value, maxName);
      if (name == "dataWindow" && type == "box2i") {
        header.hasWindow = true;
        header.minX = int32At(value, 0);
        header.minY = int32At(value, 4);
        header.maxX = int32At(value, 8);
        header.maxY = int32At(value, 12);
      } else if (name == "channels" && type == "chlist") {
        header.bytesPerPixel = channelBytes(value);
      }
    }
  }

 private:
  template <typename... Args>
  [[noreturn]] void fail(const Args&... args) const {
    DS_THROW(kInput, mKind, " EXR '", mPath, "' ", args...);
  }

  void readBytes(void* out, std::size_t count) {
    if (count > mFileSize - mOffset ||
        !mIn.read(static_cast<char*>(out), static_cast<std::streamsize>(count))) {
      fail("ends inside its header (", mFileSize, " bytes); the file is truncated or corrupt");
    }
    mOffset += count;
  }

  std::string readName(std::size_t maxLength) {
    std::string name;
    for (;;) {
      char ch;
      readBytes(&ch, 1);
      if (ch == '\0') {
        return name;
      }
      if (name.size() == maxLength) {
        fail("has a header name longer than ", maxLength, " bytes; the file is corrupt");
      }
      name.push_back(ch);
    }
  }

  /// OpenEXR reads a value by its type, not by its size field: fixed-size types take their own
  /// size, a channel list runs to its empty name, a preview or string vector sizes buffers from
  /// counts inside the value. Each must end exactly where the size field says, or OpenEXR and
  /// this scan would disagree about where the next attribute starts.
  void checkValueSize(const std::string& name, const std::string& type,
                      const std::vector<unsigned char>& value, std::size_t maxName) const {
    static const std::map<std::string, std::size_t> kFixedSizes = {
        {"box2i", 16},      {"box2f", 16},   {"chromaticities", 32},
        {"compression", 1}, {"double", 8},   {"envmap", 1},
        {"float", 4},       {"int", 4},      {"keycode", 28},
        {"lineOrder", 1},   {"m33f", 36},    {"m33d", 72},
        {"m44f", 64},       {"m44d", 128},   {"rational", 8},
        {"tiledesc", 9},    {"timecode", 8}, {"v2i", 8},
        {"v2f", 8},         {"v2d", 16},     {"v3i", 12},
        {"v3f", 12},        {"v3d", 24},     {"deepImageState", 1}};
    const std::size_t size = value.size();
    bool fits = true;
    if (const auto fixed = kFixedSizes.find(type); fixed != kFixedSizes.end()) {
      fits = size == fixed->second;
    } else if (type == "chlist") {
      // name (1..maxName bytes) + '\0' + 16 bytes, repeated; then one '\0' as the last byte.
      std::size_t at = 0;
      while (fits && at < size && value[at] != 0) {
        std::size_t end = at;
        while (end < size && value[end] != 0 && end - at <= maxName) {
          ++end;
        }
        fits = end < size && value[end] == 0 && end + 17 <= size;
        at = end + 17;
      }
      fits = fits && at + 1 == size;
    } else if (type == "preview") {
      fits = size >= 8 && 8 + 4 * static_cast<std::uint64_t>(uint32At(value, 0)) *
                                      static_cast<std::uint64_t>(uint32At(value, 4)) ==
                              size;
    } else if (type == "stringvector") {
      std::size_t at = 0;
      while (fits && at < size) {
        fits = at + 4 <= size && int32At(value, at) >= 0 &&
               static_cast<std::uint64_t>(int32At(value, at)) <= size - at - 4;
        at += 4 + (fits ? static_cast<std::size_t>(int32At(value, at)) : 0);
      }
    }
    if (!fits) {
      fail("header attribute '", name, "' of type ", type, " holds ", size,
           " bytes that do not make a whole value; the file is corrupt");
    }
  }

  static std::uint32_t uint32At(const std::vector<unsigned char>& bytes, std::size_t at) {
    return static_cast<std::uint32_t>(bytes[at]) | static_cast<std::uint32_t>(bytes[at + 1]) << 8 |
           static_cast<std::uint32_t>(bytes[at + 2]) << 16 |
           static_cast<std::uint32_t>(bytes[at + 3]) << 24;
  }

  static std::int64_t int32At(const std::vector<unsigned char>& bytes, std::size_t at) {
    return static_cast<std::int32_t>(uint32At(bytes, at));
  }

  /// Bytes per pixel of a channel list (checkValueSize has checked its layout): name, '\0',
  /// int32 type (0 uint, 1 half, 2 float) and 12 more bytes per channel.
  static std::uint64_t channelBytes(const std::vector<unsigned char>& list) {
    std::uint64_t bytes = 0;
    std::size_t at = 0;
    while (at < list.size() && list[at] != 0) {
      while (list[at] != 0) {
        ++at;
      }
      bytes += int32At(list, at + 1) == 1 ? 2 : 4;
      at += 17;
    }
    return bytes;
  }

  const std::string& mPath;
  const char* mKind;
  std::uint64_t mFileSize;
  std::uint64_t mOffset = 0;
  std::ifstream mIn;
};

}  // namespace exr_streams
using namespace exr_streams;

std::unique_ptr<Imf::InputFile> openExr(const std::string& path, const char* kind) {
  std::error_code ec;
  const std::uint64_t fileSize = std::filesystem::file_size(path, ec);
  if (ec) {
    DS_THROW(kInput, "cannot read ", kind, " EXR '", path, "': ", ec.message());
  }
  const RawHeader raw = HeaderScan(path, kind, fileSize).scan();
  if (raw.hasWindow) {
    const double width = static_cast<double>(raw.maxX - raw.minX + 1);
    const double height = static_cast<double>(raw.maxY - raw.minY + 1);
    // Decoded pixel data can exceed the file (deflate reaches about 1000:1); 2048:1 plus 16 MiB
    // of slack admits every real file and stops a few corrupt bytes from asking for gigabytes.
    const double limit = 2048.0 * static_cast<double>(fileSize) + 16.0 * 1024 * 1024;
    const double pixelBytes =
        width * height * static_cast<double>(std::max<std::uint64_t>(raw.bytesPerPixel, 1));
    if (width <= 0 || height <= 0 || pixelBytes > limit || height > 32.0 * fileSize) {
      DS_THROW(kInput, kind, " EXR '", path, "' declares a data window of ",
               raw.maxX - raw.minX + 1, " x ", raw.maxY - raw.minY + 1, " pixels that a file of ",
               fileSize, " bytes cannot hold; the file is corrupt");
    }
  }
  try {
    return std::make_unique<Imf::InputFile>(path.c_str());
  } catch (const std::exception& e) {
    DS_THROW(kInput, "cannot read ", kind, " EXR '", path, "': ", e.what());
  }
}

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
    shared.hasFrame = true;
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
                        const std::function<void(std::ostream& stream)>& body, bool syncToDisk) {
  AtomicFile atomic(path);
  try {
    body(atomic.stream());
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    DS_THROW(kOutput, "cannot write ", kind, " EXR '", path, "': ", e.what());
  }
  atomic.commit(syncToDisk);
}

/// The writer behind ScanlineWriter: our ZIP writer, or OpenEXR's on our own stream.
struct ScanlineWriter::State {
  std::unique_ptr<ZipExrWriter> zip;
  std::unique_ptr<ExrOStream> exrStream;
  std::unique_ptr<Imf::OutputFile> file;
};

ScanlineWriter::ScanlineWriter(const std::string& path, std::ostream& stream,
                               const Imf::Header& header, ZipEncoder zipEncoder, int encodeThreads)
    : mPath(path), mStream(stream), mState(std::make_unique<State>()) {
  const bool zip =
      header.compression() == Imf::ZIP_COMPRESSION || header.compression() == Imf::ZIPS_COMPRESSION;
  errno = 0;  // the system's reason, should a write fail
  if (zip && zipEncoder == ZipEncoder::kLibdeflate) {
    ZipEncoding encoding;
    encoding.threads = std::max(1, encodeThreads);
    mState->zip = std::make_unique<ZipExrWriter>(stream, header, encoding);
  } else {
    mState->exrStream = std::make_unique<ExrOStream>(stream, path);
    mState->file = std::make_unique<Imf::OutputFile>(*mState->exrStream, header);
  }
  checkStream();
}

ScanlineWriter::~ScanlineWriter() = default;

void ScanlineWriter::write(const Imf::FrameBuffer& frameBuffer, int lines) {
  if (mState->zip) {
    mState->zip->writeLines(frameBuffer, lines);
  } else {
    mState->file->setFrameBuffer(frameBuffer);
    mState->file->writePixels(lines);
  }
  checkStream();
}

void ScanlineWriter::finish() {
  if (mState->zip) {
    mState->zip->finish();
  }
  mState->file.reset();  // OpenEXR writes its offset table here (and swallows a failure)
  mStream.flush();
  checkStream();
}

void ScanlineWriter::checkStream() const {
  if (mStream.fail()) {
    const int error = errno != 0 ? errno : EIO;
    DS_THROW(kOutput, "cannot write '", mPath, "': ", std::strerror(error), "; is the disk full?");
  }
}

void writeScanlines(const std::string& path, std::ostream& stream, const Imf::Header& header,
                    const Imf::FrameBuffer& frameBuffer, int height, ZipEncoder zipEncoder,
                    int encodeThreads) {
  ScanlineWriter writer(path, stream, header, zipEncoder, encodeThreads);
  writer.write(frameBuffer, height);
  writer.finish();
}

}  // namespace drivenshape::exr_detail
