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

/// A chunk as the file stores it: the zlib stream, or the raw bytes when deflate does not make
/// them smaller. The buffer is left uninitialised up to `size`: no page is touched for nothing.
struct StoredChunk {
  std::unique_ptr<char[]> bytes;
  std::size_t size = 0;
};

/// One thread's scratch for its chunks, grown to the largest and kept for the next chunk: fresh
/// buffers for every chunk cost a memset and a page fault per 4 KiB. Chunks larger than this
/// (wider than 16,384 texels of R G B A and N, 16 rows) free it again rather than hold it for
/// the thread's life.
constexpr std::size_t kKeptScratchBytes = std::size_t{8} << 20;

struct ChunkScratch {
  std::vector<unsigned char> split;
  std::vector<unsigned char> predicted;
};

ChunkScratch& threadScratch(std::size_t size) {
  thread_local ChunkScratch scratch;
  if (scratch.split.size() < size) {
    scratch.split.resize(size);
    scratch.predicted.resize(size);
  }
  return scratch;
}

/// Splits one channel's row into the even-indexed bytes (at `even`) and the odd-indexed bytes
/// (at `odd`) of the chunk. A row starts at an even offset of the chunk and holds an even number
/// of bytes (values of 2 or 4 bytes), so each of its bytes keeps its parity in the chunk.
template <std::size_t kValueBytes>
void splitRow(const char* row, std::size_t xStride, std::size_t width, unsigned char* even,
              unsigned char* odd) {
  constexpr std::size_t kPairs = kValueBytes / 2;
  for (std::size_t x = 0; x < width; ++x) {
    const char* value = row + x * xStride;
    for (std::size_t b = 0; b < kPairs; ++b) {
      even[x * kPairs + b] = static_cast<unsigned char>(value[2 * b]);
      odd[x * kPairs + b] = static_cast<unsigned char>(value[2 * b + 1]);
    }
  }
}

/// The scan lines firstY..lastY as OpenEXR's ZIP codec prepares them for deflate (ImfZip.cpp,
/// the file format's "ZIP compression"): the lines' bytes (each channel's row in turn, in the
/// channel list's order) split into the even-indexed bytes, then the odd-indexed ones (into
/// `split`), and a byte-delta predictor over the result: each byte minus the one before, plus
/// 128 (mod 256), the first byte as it is (into `predicted`). `size` bytes each.
void predictedChunk(const std::vector<ChannelSource>& sources, std::size_t width, int minX,
                    int firstY, int lastY, std::size_t size, unsigned char* split,
                    unsigned char* predicted) {
  const std::size_t half = size / 2;  // even: every row is
  std::size_t offset = 0;             // in the chunk's raw bytes
  for (int y = firstY; y <= lastY; ++y) {
    for (const ChannelSource& source : sources) {
      const char* row = source.base + static_cast<std::ptrdiff_t>(source.yStride) * y +
                        static_cast<std::ptrdiff_t>(source.xStride) * minX;
      unsigned char* even = split + offset / 2;
      unsigned char* odd = split + half + offset / 2;
      if (source.valueBytes == 2) {
        splitRow<2>(row, source.xStride, width, even, odd);
      } else {
        splitRow<4>(row, source.xStride, width, even, odd);
      }
      offset += width * source.valueBytes;
    }
  }
  if (size > 0) {
    predicted[0] = split[0];
  }
  for (std::size_t i = 1; i < size; ++i) {
    predicted[i] = static_cast<unsigned char>(split[i] - split[i - 1] + 128);
  }
}

/// One chunk as OpenEXR's ZIP codec stores it: a zlib stream of predictedChunk's bytes, or the
/// raw bytes when deflate does not make them smaller (readers tell them apart by the size).
StoredChunk zipChunk(const std::vector<ChannelSource>& sources, std::size_t width, int minX,
                     int firstY, int lastY, std::size_t size, const ZipEncoding& encoding) {
  ChunkScratch& scratch = threadScratch(size);
  predictedChunk(sources, width, minX, firstY, lastY, size, scratch.split.data(),
                 scratch.predicted.data());
  StoredChunk chunk;
  chunk.bytes.reset(new char[std::max<std::size_t>(size, 1)]);
  if (encoding.deflater == Deflater::kLibdeflate) {
    // A stream as long as the raw bytes is stored raw: room for one byte less.
    chunk.size = size < 2 ? 0
                          : libdeflate_zlib_compress(threadCompressor(encoding.level),
                                                     scratch.predicted.data(), size,
                                                     chunk.bytes.get(), size - 1);
  } else {
    std::vector<Bytef> out(compressBound(static_cast<uLong>(size)));
    uLongf outSize = static_cast<uLongf>(out.size());
    if (compress2(out.data(), &outSize, scratch.predicted.data(), static_cast<uLong>(size),
                  encoding.level) != Z_OK) {
      DS_THROW(kInternal, "zlib compress2 failed on a chunk of ", size, " bytes");
    }
    if (outSize < size) {
      chunk.size = outSize;
      std::memcpy(chunk.bytes.get(), out.data(), outSize);
    }
  }
  if (chunk.size == 0) {  // stored raw: the split halves interleaved again
    const std::size_t half = size / 2;
    for (std::size_t i = 0; i < half; ++i) {
      chunk.bytes[2 * i] = static_cast<char>(scratch.split[i]);
      chunk.bytes[2 * i + 1] = static_cast<char>(scratch.split[half + i]);
    }
    chunk.size = size;
  }
  if (size > kKeptScratchBytes) {
    scratch = ChunkScratch();
  }
  return chunk;
}

}  // namespace

/// What ZipExrWriter keeps between bands of scan lines.
struct ZipExrWriter::State {
  std::ostream* out = nullptr;
  ZipEncoding encoding;
  const Imf::Header* header = nullptr;
  Imath::Box2i window;
  std::size_t width = 0;
  int linesPerChunk = 16;
  int nextY = 0;                       ///< the first scan line not written yet
  std::streamoff tableAt = 0;          ///< where the chunk offset table starts
  std::vector<std::uint64_t> offsets;  ///< of every chunk, from the start of the file
  std::uint64_t written = 0;           ///< bytes of the file written so far
  std::streamoff fileStart = 0;        ///< where the file starts in `out`
  bool finished = false;
};

namespace {

/// The channels of `header` in the file's order, each read through its slice of `frameBuffer`
/// (or `zeros` for a channel without one, as OpenEXR writes). Error(kInternal) for input the
/// ZIP writer does not take.
std::vector<ChannelSource> channelSources(const Imf::Header& header,
                                          const Imf::FrameBuffer& frameBuffer,
                                          const std::vector<char>& zeros) {
  const Imath::Box2i& window = header.dataWindow();
  std::vector<ChannelSource> sources;
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
  return sources;
}

}  // namespace

ZipExrWriter::ZipExrWriter(std::ostream& out, const Imf::Header& header,
                           const ZipEncoding& encoding)
    : mState(std::make_unique<State>()) {
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
  State& state = *mState;
  state.out = &out;
  state.encoding = encoding;
  state.header = &header;
  state.window = header.dataWindow();
  state.width = static_cast<std::size_t>(state.window.max.x - state.window.min.x + 1);
  state.linesPerChunk = zips ? 1 : 16;
  state.nextY = state.window.min.y;
  const int height = state.window.max.y - state.window.min.y + 1;
  const int chunkCount = (height + state.linesPerChunk - 1) / state.linesPerChunk;

  // The layout of Imf::OutputFile: magic number, version field, header (Header::writeTo, the
  // same bytes), the chunk offset table (filled in by finish()), then each chunk as y, byte
  // count, data.
  std::string head;
  appendLe32(head, static_cast<std::uint32_t>(Imf::MAGIC));
  appendLe32(head, static_cast<std::uint32_t>(Imf::EXR_VERSION |
                                              (usesLongNames(header) ? Imf::LONG_NAMES_FLAG : 0)));
  {
    Imf::StdOSStream stream;
    header.writeTo(stream);
    head += stream.str();
  }
  state.fileStart = static_cast<std::streamoff>(out.tellp());
  state.tableAt = static_cast<std::streamoff>(head.size());
  head.resize(head.size() + 8 * static_cast<std::size_t>(chunkCount));
  out.write(head.data(), static_cast<std::streamsize>(head.size()));
  state.written = head.size();
}

ZipExrWriter::~ZipExrWriter() = default;

void ZipExrWriter::writeLines(const Imf::FrameBuffer& frameBuffer, int lines) {
  State& state = *mState;
  const int lastY = state.nextY + lines - 1;
  if (state.finished || lines < 1 || lastY > state.window.max.y ||
      (lastY < state.window.max.y && lines % state.linesPerChunk != 0)) {
    DS_THROW(kInternal, "writeZipExr: ", lines, " scan lines from ", state.nextY,
             " are not whole chunks of the image");
  }
  const std::vector<char> zeros(state.width * 4, '\0');  // the row of every channel without a slice
  const std::vector<ChannelSource> sources = channelSources(*state.header, frameBuffer, zeros);
  std::size_t lineBytes = 0;
  for (const ChannelSource& source : sources) {
    lineBytes += state.width * source.valueBytes;
  }
  const int chunkCount = (lines + state.linesPerChunk - 1) / state.linesPerChunk;
  std::vector<StoredChunk> chunks(static_cast<std::size_t>(chunkCount));
  parallelFor(chunkCount, state.encoding.threads, [&](int c) {
    const int firstY = state.nextY + c * state.linesPerChunk;
    const int chunkLastY = std::min(firstY + state.linesPerChunk - 1, lastY);
    chunks[static_cast<std::size_t>(c)] =
        zipChunk(sources, state.width, state.window.min.x, firstY, chunkLastY,
                 lineBytes * static_cast<std::size_t>(chunkLastY - firstY + 1), state.encoding);
  });
  for (int c = 0; c < chunkCount; ++c) {
    StoredChunk& chunk = chunks[static_cast<std::size_t>(c)];
    state.offsets.push_back(state.written);
    state.written += 8 + chunk.size;
    std::string prefix;
    appendLe32(prefix, static_cast<std::uint32_t>(state.nextY + c * state.linesPerChunk));
    appendLe32(prefix, static_cast<std::uint32_t>(chunk.size));
    state.out->write(prefix.data(), static_cast<std::streamsize>(prefix.size()));
    state.out->write(chunk.bytes.get(), static_cast<std::streamsize>(chunk.size));
    chunk.bytes.reset();  // written: free it
  }
  state.nextY = lastY + 1;
}

void ZipExrWriter::finish() {
  State& state = *mState;
  if (state.finished || state.nextY != state.window.max.y + 1) {
    DS_THROW(kInternal, "writeZipExr: finished after ", state.nextY - state.window.min.y, " of ",
             state.window.max.y - state.window.min.y + 1, " scan lines");
  }
  state.finished = true;
  std::string table(8 * state.offsets.size(), '\0');
  for (std::size_t c = 0; c < state.offsets.size(); ++c) {
    storeLe64(&table[8 * c], state.offsets[c]);
  }
  state.out->seekp(state.fileStart + state.tableAt);
  state.out->write(table.data(), static_cast<std::streamsize>(table.size()));
  state.out->seekp(state.fileStart + static_cast<std::streamoff>(state.written));
}

void writeZipExr(std::ostream& out, const Imf::Header& header, const Imf::FrameBuffer& frameBuffer,
                 const ZipEncoding& encoding) {
  ZipExrWriter writer(out, header, encoding);
  const Imath::Box2i& window = header.dataWindow();
  writer.writeLines(frameBuffer, window.max.y - window.min.y + 1);
  writer.finish();
}

std::string encodeZipExr(const Imf::Header& header, const Imf::FrameBuffer& frameBuffer,
                         const ZipEncoding& encoding) {
  std::ostringstream out;
  writeZipExr(out, header, frameBuffer, encoding);
  return out.str();
}

}  // namespace drivenshape::exr_detail
