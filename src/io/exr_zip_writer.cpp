// SPDX-License-Identifier: Apache-2.0
#include "exr_zip_writer.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfStdIO.h>
#include <OpenEXR/ImfVersion.h>

#include <libdeflate.h>
#include <zlib.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <memory>
#include <ostream>
#include <sstream>
#include <vector>

#include <drivenshape/error.h>
#include "parallel.h"

#if !defined(__BYTE_ORDER__) || __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "exr_zip_writer.cpp copies pixels as they lie in memory: EXR data is little-endian"
#endif

namespace drivenshape::exr_detail {
namespace {

/// Where one channel's values come from: the frame-buffer slice (or zeros when it has none).
struct ChannelSource {
  const char* base = nullptr;  // pixel (0, 0), as Imf::Slice::base
  std::size_t xStride = 0;
  std::size_t yStride = 0;
  std::size_t valueBytes = 4;  // 2 for HALF, 4 for FLOAT and UINT
};

void appendLe32(std::string& out, std::uint32_t value) {
  for (int i = 0; i < 4; ++i) {
    out.push_back(static_cast<char>((value >> (8 * i)) & 0xffu));
  }
}

void storeLe64(char* at, std::uint64_t value) {
  for (int i = 0; i < 8; ++i) {
    at[i] = static_cast<char>((value >> (8 * i)) & 0xffu);
  }
}

/// The OpenEXR file format's rule (and Imf::OutputFile's): a name longer than 31 bytes anywhere
/// in the header sets the long-names flag of the version field.
bool usesLongNames(const Imf::Header& header) {
  for (auto it = header.begin(); it != header.end(); ++it) {
    if (std::strlen(it.name()) > 31 || std::strlen(it.attribute().typeName()) > 31) {
      return true;
    }
  }
  for (auto it = header.channels().begin(); it != header.channels().end(); ++it) {
    if (std::strlen(it.name()) > 31) {
      return true;
    }
  }
  return false;
}

/// libdeflate compressors cost an allocation of a few hundred KiB each: one per thread and
/// level, kept for the thread's life.
libdeflate_compressor* threadCompressor(int level) {
  struct Free {
    void operator()(libdeflate_compressor* compressor) const {
      libdeflate_free_compressor(compressor);
    }
  };
  thread_local std::unique_ptr<libdeflate_compressor, Free> compressor;
  thread_local int compressorLevel = 0;
  if (!compressor || compressorLevel != level) {
    compressor.reset(libdeflate_alloc_compressor(level));
    compressorLevel = level;
    if (!compressor) {
      DS_THROW(kInternal, "libdeflate cannot make a compressor at level ", level);
    }
  }
  return compressor.get();
}

/// One chunk as OpenEXR's ZIP codec stores it (ImfZip.cpp, the file format's "ZIP
/// compression"): the scan lines' bytes split into even and odd halves, a byte-delta predictor
/// over the result, a zlib stream of that; the raw bytes instead when deflate does not make them
/// smaller.
std::string zipChunk(const std::vector<char>& raw, const ZipEncoding& encoding) {
  const std::size_t size = raw.size();
  const std::size_t half = (size + 1) / 2;
  std::vector<unsigned char> split(size);
  for (std::size_t i = 0; i < half; ++i) {
    split[i] = static_cast<unsigned char>(raw[2 * i]);
  }
  for (std::size_t i = 0; i + half < size; ++i) {
    split[half + i] = static_cast<unsigned char>(raw[2 * i + 1]);
  }
  // Each byte minus the one before, plus 128 (mod 256); the first byte as it is.
  std::vector<unsigned char> shuffled(size);
  if (size > 0) {
    shuffled[0] = split[0];
  }
  for (std::size_t i = 1; i < size; ++i) {
    shuffled[i] = static_cast<unsigned char>(split[i] - split[i - 1] + 128);
  }
  std::string packed(size, '\0');  // a stream as long as the raw bytes is stored raw
  std::size_t packedSize = 0;
  if (encoding.deflater == Deflater::kLibdeflate) {
    packedSize = size < 2
                     ? 0
                     : libdeflate_zlib_compress(threadCompressor(encoding.level), shuffled.data(),
                                                size, packed.data(), size - 1);
  } else {
    std::vector<Bytef> out(compressBound(static_cast<uLong>(size)));
    uLongf outSize = static_cast<uLongf>(out.size());
    if (compress2(out.data(), &outSize, shuffled.data(), static_cast<uLong>(size),
                  encoding.level) != Z_OK) {
      DS_THROW(kInternal, "zlib compress2 failed on a chunk of ", size, " bytes");
    }
    if (outSize < size) {
      packedSize = outSize;
      std::memcpy(packed.data(), out.data(), outSize);
    }
  }
  if (packedSize == 0) {
    return std::string(raw.begin(), raw.end());
  }
  packed.resize(packedSize);
  return packed;
}

}  // namespace

void writeZipExr(std::ostream& out, const Imf::Header& header, const Imf::FrameBuffer& frameBuffer,
                 const ZipEncoding& encoding) {
  const bool zips = header.compression() == Imf::ZIPS_COMPRESSION;
  if (!zips && header.compression() != Imf::ZIP_COMPRESSION) {
    DS_THROW(kInternal, "writeZipExr writes ZIP and ZIPS files only");
  }
  const int maxLevel = encoding.deflater == Deflater::kLibdeflate ? 12 : 9;
  if (encoding.level < 1 || encoding.level > maxLevel) {
    DS_THROW(kInternal, "deflate level ", encoding.level, " is outside 1..", maxLevel);
  }
  if (header.lineOrder() != Imf::INCREASING_Y || header.hasType()) {
    DS_THROW(kInternal, "writeZipExr writes single-part images in increasing line order only");
  }
  header.sanityCheck();  // what Imf::OutputFile checks first (throws Iex exceptions)

  const Imath::Box2i& window = header.dataWindow();
  const std::size_t width = static_cast<std::size_t>(window.max.x - window.min.x + 1);
  const int height = window.max.y - window.min.y + 1;
  std::vector<ChannelSource> sources;              // in the channel list's (the file's) order
  const std::vector<char> zeros(width * 4, '\0');  // the row of every channel without a slice
  for (auto it = header.channels().begin(); it != header.channels().end(); ++it) {
    const Imf::Channel& channel = it.channel();
    if (channel.xSampling != 1 || channel.ySampling != 1) {
      DS_THROW(kInternal, "writeZipExr: channel ", it.name(), " is subsampled");
    }
    ChannelSource source;
    source.valueBytes = channel.type == Imf::HALF ? 2 : 4;
    if (const Imf::Slice* slice = frameBuffer.findSlice(it.name())) {
      if (slice->type != channel.type || slice->xSampling != 1 || slice->ySampling != 1) {
        DS_THROW(kInternal, "writeZipExr: the slice of channel ", it.name(),
                 " differs from the channel in type or sampling");
      }
      source.base = slice->base;
      source.xStride = slice->xStride;
      source.yStride = slice->yStride;
    } else {
      source.base = zeros.data() - window.min.x * static_cast<std::ptrdiff_t>(source.valueBytes);
      source.xStride = source.valueBytes;
    }
    sources.push_back(source);
  }
  std::size_t lineBytes = 0;
  for (const ChannelSource& source : sources) {
    lineBytes += width * source.valueBytes;
  }

  const int linesPerChunk = zips ? 1 : 16;
  const int chunkCount = (height + linesPerChunk - 1) / linesPerChunk;
  std::vector<std::string> chunks(static_cast<std::size_t>(chunkCount));
  parallelFor(chunkCount, encoding.threads, [&](int c) {
    const int firstY = window.min.y + c * linesPerChunk;
    const int lastY = std::min(firstY + linesPerChunk - 1, window.max.y);
    std::vector<char> raw(lineBytes * static_cast<std::size_t>(lastY - firstY + 1));
    char* packed = raw.data();
    for (int y = firstY; y <= lastY; ++y) {
      for (const ChannelSource& source : sources) {
        const char* row = source.base + static_cast<std::ptrdiff_t>(source.yStride) * y +
                          static_cast<std::ptrdiff_t>(source.xStride) * window.min.x;
        if (source.xStride == source.valueBytes) {
          std::memcpy(packed, row, width * source.valueBytes);
          packed += width * source.valueBytes;
        } else {
          for (std::size_t x = 0; x < width; ++x, packed += source.valueBytes) {
            std::memcpy(packed, row + x * source.xStride, source.valueBytes);
          }
        }
      }
    }
    chunks[static_cast<std::size_t>(c)] = zipChunk(raw, encoding);
  });

  // The layout of Imf::OutputFile: magic number, version field, header (Header::writeTo, the
  // same bytes), the chunk offset table, then each chunk as y, byte count, data.
  std::string head;
  appendLe32(head, static_cast<std::uint32_t>(Imf::MAGIC));
  appendLe32(head, static_cast<std::uint32_t>(Imf::EXR_VERSION |
                                              (usesLongNames(header) ? Imf::LONG_NAMES_FLAG : 0)));
  {
    Imf::StdOSStream stream;
    header.writeTo(stream);
    head += stream.str();
  }
  std::uint64_t offset = head.size() + 8 * chunks.size();
  head.resize(head.size() + 8 * chunks.size());
  for (std::size_t c = 0; c < chunks.size(); ++c) {
    storeLe64(&head[head.size() - 8 * (chunks.size() - c)], offset);
    offset += 8 + chunks[c].size();
  }
  out.write(head.data(), static_cast<std::streamsize>(head.size()));
  for (int c = 0; c < chunkCount; ++c) {
    std::string& chunk = chunks[static_cast<std::size_t>(c)];
    std::string prefix;
    appendLe32(prefix, static_cast<std::uint32_t>(window.min.y + c * linesPerChunk));
    appendLe32(prefix, static_cast<std::uint32_t>(chunk.size()));
    out.write(prefix.data(), static_cast<std::streamsize>(prefix.size()));
    out.write(chunk.data(), static_cast<std::streamsize>(chunk.size()));
    std::string().swap(chunk);  // written: free it
  }
}

std::string encodeZipExr(const Imf::Header& header, const Imf::FrameBuffer& frameBuffer,
                         const ZipEncoding& encoding) {
  std::ostringstream out;
  writeZipExr(out, header, frameBuffer, encoding);
  return out.str();
}

}  // namespace drivenshape::exr_detail
