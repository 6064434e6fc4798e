// SPDX-License-Identifier: Apache-2.0
// PositionMapWriter and writePositionMapSequence: tables once (or a band of rows at a time for
// a map too large to hold them), then chunks of frames through a backend into EXR files (and
// PNG previews).

#include <drivenshape/position_map_sequence.h>

#include "parallel.h"
#include "stopwatch.h"

#include <algorithm>
#include <chrono>
#include <exception>
#include <memory>
#include <ostream>
#include <string>
#include <vector>

#include <drivenshape/error.h>
#include <drivenshape/frames.h>
#include <drivenshape/position_map_tables.h>

#include "atomic_file.h"

namespace drivenshape {
namespace {

constexpr int kMaxChunkFrames = 16;
/// Bytes per texel of a map's tables (texels, triangles, weights, sources, coverage) with the
/// backend's copy and the rasterisation's scratch (owner, distance, entry): what keeping them
/// whole costs, and what a band's cost besides its maps.
constexpr std::size_t kTableBytesPerTexel = 64;
/// A banded map's bands are whole ZIP chunks (16 rows) but the last.
constexpr int kBandRowStep = 16;

}  // namespace

/// One launch's files being written, a band at a time.
struct PositionMapWriter::Chunk {
  int count = 0;
  const float* xyz = nullptr;
  std::vector<PositionMapFrameHeader> headers;
  std::vector<std::unique_ptr<PositionMapExrWriter>> files;
  std::vector<std::unique_ptr<PositionMapPreview>> previews;
  std::vector<std::exception_ptr> failures;  ///< per frame: its file is dropped on the first
};

PositionMapWriter::PositionMapWriter(const Mesh& mesh, const PositionMapOptions& options,
                                     std::unique_ptr<PositionMapBackend> backend,
                                     const std::string& meshName, std::ostream* log)
    : mOptions(options), mBackend(std::move(backend)) {
  if (!mBackend) {
    DS_THROW(kInternal, "PositionMapWriter needs a backend");
  }
  if (mOptions.halfNormals) {
    mOptions.normals = true;
  }
  if (mOptions.threads < 0 || mOptions.chunkSize < 0) {
    DS_THROW(kUsage, "position map threads (", mOptions.threads, ") and chunk size (",
             mOptions.chunkSize, ") must not be negative");
  }
  if (!(mOptions.framesPerSecond > 0.0)) {
    DS_THROW(kUsage, "frames per second ", mOptions.framesPerSecond, " must be positive (--fps)");
  }
  mOptions.launchBytes = std::max<std::size_t>(mOptions.launchBytes, 1);
  auto raster = std::make_unique<PositionMapRaster>(mesh, mOptions.width, mOptions.height,
                                                    mOptions.padding, meshName);
  const std::size_t texels = raster->shared().texelCount();
  const std::size_t limit = std::min(mOptions.launchBytes, mBackend->maxBufferBytes() / 2);
  if (texels * kTableBytesPerTexel <= 4 * mOptions.launchBytes) {
    mTables = raster->band(0, mOptions.height);
    mBackend->upload(mTables);
    const std::size_t frameBytes = 3 * texels * sizeof(float) * (mOptions.normals ? 2 : 1);
    const int fit = static_cast<int>(std::min<std::size_t>(
        kMaxChunkFrames, std::max<std::size_t>(1, limit / std::max<std::size_t>(1, frameBytes))));
    mChunkSize = mOptions.chunkSize > 0 ? mOptions.chunkSize : fit;
  } else {
    mRaster = std::move(raster);
    mChunkSize = mOptions.chunkSize > 0 ? mOptions.chunkSize : kMaxChunkFrames;
    mTables = mRaster->survey(bandRows(0));
  }
  if (log != nullptr && !mTables.overlaps.empty()) {
    *log << "warning: " << meshName << ": " << mTables.overlaps.describe() << "\n";
  }
}

PositionMapWriter::~PositionMapWriter() = default;

std::string PositionMapWriter::backendName() const {
  return mBackend->name();
}

int PositionMapWriter::bandRows(int frames) const {
  if (!mRaster) {
    return mTables.height;
  }
  const std::size_t mapBytes = 3 * sizeof(float) * (mOptions.normals ? 2 : 1);
  const std::size_t rowBytes = static_cast<std::size_t>(mOptions.width) *
                               (kTableBytesPerTexel + static_cast<std::size_t>(frames) * mapBytes);
  const std::size_t limit = std::min(mOptions.launchBytes, mBackend->maxBufferBytes() / 2);
  const std::size_t rows = limit / rowBytes / kBandRowStep * kBandRowStep;
  return static_cast<int>(std::min<std::size_t>(static_cast<std::size_t>(mOptions.height),
                                                std::max<std::size_t>(kBandRowStep, rows)));
}

void PositionMapWriter::writeFrame(int frame, const float* xyz, const std::string& path) {
  writeChunk(1, &frame, xyz, &path);
}

void PositionMapWriter::writeFrames(const std::vector<int>& frames, const float* xyz,
                                    const std::vector<std::string>& paths) {
  if (frames.size() != paths.size()) {
    DS_THROW(kInternal, "PositionMapWriter::writeFrames: ", frames.size(), " frames but ",
             paths.size(), " paths");
  }
  const std::size_t vertexFloats = 3 * static_cast<std::size_t>(mTables.vertexCount);
  for (std::size_t first = 0; first < frames.size();
       first += static_cast<std::size_t>(mChunkSize)) {
    const int count =
        static_cast<int>(std::min(frames.size() - first, static_cast<std::size_t>(mChunkSize)));
    writeChunk(count, frames.data() + first, xyz + first * vertexFloats, paths.data() + first);
  }
}

void PositionMapWriter::writeChunk(int count, const int* frames, const float* xyz,
                                   const std::string* paths) {
  if (count <= 0) {
    return;
  }
  if (xyz == nullptr) {
    DS_THROW(kInternal, "PositionMapWriter: no positions for frame ", frames[0]);
  }
  const auto openStart = std::chrono::steady_clock::now();
  const std::size_t vertexFloats = 3 * static_cast<std::size_t>(mTables.vertexCount);
  Chunk chunk;
  chunk.count = count;
  chunk.xyz = xyz;
  chunk.headers.resize(static_cast<std::size_t>(count));
  chunk.files.resize(static_cast<std::size_t>(count));
  chunk.previews.resize(static_cast<std::size_t>(count));
  chunk.failures.resize(static_cast<std::size_t>(count));
  // The cores left over by the files deflate the chunks within each file (one frame per call,
  // as `bake --posmap` writes with --batch 1, still uses every core).
  const int encodeThreads =
      std::max(1, resolveThreads(mOptions.threads) / resolveThreads(mOptions.threads, count));
  for (int i = 0; i < count; ++i) {
    const std::size_t f = static_cast<std::size_t>(i);
    PositionMapFrameHeader& header = chunk.headers[f];
    header.frame = frames[i];
    header.topologyHash = mTables.topologyHash;
    header.meshVertexCount = mTables.vertexCount;
    header.padding = mTables.padding;
    header.bounds = computeBounds(xyz + f * vertexFloats, mTables.vertexCount);
    header.compression = mOptions.compression;
    header.zipEncoder = mOptions.zipEncoder;
    header.encodeThreads = encodeThreads;
    header.framesPerSecond = mOptions.framesPerSecond;
    header.halfNormals = mOptions.halfNormals;
    header.channels = mOptions.channels;
    try {
      chunk.files[f] = std::make_unique<PositionMapExrWriter>(
          paths[i], mOptions.width, mOptions.height, mOptions.normals, header);
      if (mOptions.preview) {
        chunk.previews[f] =
            std::make_unique<PositionMapPreview>(mOptions.width, mOptions.height, header.bounds);
      }
    } catch (...) {
      chunk.failures[f] = std::current_exception();
      chunk.files[f].reset();
    }
  }
  mWriteSeconds += secondsSince(openStart);
  const int rows = bandRows(count);
  for (int firstRow = 0; firstRow < mOptions.height; firstRow += rows) {
    writeBand(chunk, firstRow, std::min(rows, mOptions.height - firstRow));
  }
  const auto commitStart = std::chrono::steady_clock::now();
  parallelFor(count, resolveThreads(mOptions.threads, count), [&](int i) {
    const std::size_t f = static_cast<std::size_t>(i);
    if (!chunk.files[f]) {
      return;
    }
    try {
      chunk.files[f]->commit();
      if (chunk.previews[f]) {
        chunk.previews[f]->write(positionMapPreviewPath(paths[i]));
      }
    } catch (...) {
      chunk.failures[f] = std::current_exception();
    }
    chunk.files[f].reset();
    chunk.previews[f].reset();
  });
  mWriteSeconds += secondsSince(commitStart);
  for (const std::exception_ptr& failure : chunk.failures) {
    if (failure) {
      std::rethrow_exception(failure);  // the first frame's; the others are written
    }
  }
}

void PositionMapWriter::writeBand(Chunk& chunk, int firstRow, int rows) {
  if (std::none_of(chunk.files.begin(), chunk.files.end(),
                   [](const auto& file) { return file != nullptr; })) {
    return;  // every file of the launch failed
  }
  const auto evaluateStart = std::chrono::steady_clock::now();
  PositionMapTables bandTables;
  if (mRaster) {
    bandTables = mRaster->band(firstRow, rows);
    mBackend->upload(bandTables);
  }
  const PositionMapTables& band = mRaster ? bandTables : mTables;
  const std::size_t mapFloats = 3 * band.texelCount();
  const std::size_t needed = static_cast<std::size_t>(chunk.count) * mapFloats;
  if (mPositions.size() < needed) {
    mPositions.resize(needed);
  }
  if (mOptions.normals && mNormals.size() < needed) {
    mNormals.resize(needed);
  }
  mBackend->evaluate(chunk.count, chunk.xyz, mPositions.data(),
                     mOptions.normals ? mNormals.data() : nullptr);
  mEvaluateSeconds += secondsSince(evaluateStart);

  const auto writeStart = std::chrono::steady_clock::now();
  parallelFor(chunk.count, resolveThreads(mOptions.threads, chunk.count), [&](int i) {
    const std::size_t f = static_cast<std::size_t>(i);
    if (!chunk.files[f]) {
      return;
    }
    const float* positions = mPositions.data() + f * mapFloats;
    try {
      chunk.files[f]->writeRows(rows, positions, band.coverage.data(),
                                mOptions.normals ? mNormals.data() + f * mapFloats : nullptr);
      if (chunk.previews[f]) {
        chunk.previews[f]->draw(band, firstRow, positions);
      }
    } catch (...) {
      chunk.failures[f] = std::current_exception();
      chunk.files[f].reset();  // its temporary file goes
      chunk.previews[f].reset();
    }
  });
  mWriteSeconds += secondsSince(writeStart);
}

PositionMapRunResult writePositionMapSequence(
    PositionMapWriter& writer, const PointCacheReader& cache, const std::vector<int>& frames,
    const std::string& outputPattern,
    const std::function<void(int, const std::string&)>& frameDone) {
  const auto start = std::chrono::steady_clock::now();
  const PositionMapTables& tables = writer.tables();
  if (cache.vertexCount() != tables.vertexCount) {
    DS_THROW(kInput, cache.path(), ": the cache holds ", cache.vertexCount(),
             " vertices but the mesh has ", tables.vertexCount,
             "; pass the mesh the cache was made for (same vertex count and order)");
  }
  if (frames.empty()) {
    DS_THROW(kUsage, "no frames to write (--frames)");
  }
  std::vector<int> missing;
  for (int frame : frames) {
    if (!cache.hasFrame(frame)) {
      missing.push_back(frame);
    }
  }
  if (!missing.empty()) {
    const std::vector<int> available = cache.frames();
    DS_THROW(kInput, cache.path(), ": frames ", formatFrameRange(missing),
             " are not in the cache (it holds ",
             available.empty() ? std::string("no frames") : formatFrameRange(available), ")");
  }
  if (!hasFramePattern(outputPattern)) {
    DS_THROW(kUsage, "-o '", outputPattern, "' has no frame token; use e.g. maps/cloth.####.exr");
  }
  checkOutputFolderWritable(expandFramePattern(outputPattern, frames.front()));

  PositionMapRunResult result;
  const double evaluateBefore = writer.evaluateSeconds();
  const double writeBefore = writer.writeSeconds();
  const std::size_t chunk = static_cast<std::size_t>(writer.chunkSize());
  const std::size_t vertexFloats = 3 * static_cast<std::size_t>(tables.vertexCount);
  std::vector<float> xyz;
  for (std::size_t first = 0; first < frames.size(); first += chunk) {
    const std::size_t count = std::min(chunk, frames.size() - first);
    const std::vector<int> chunkFrames(frames.begin() + static_cast<std::ptrdiff_t>(first),
                                       frames.begin() + static_cast<std::ptrdiff_t>(first + count));
    const auto readStart = std::chrono::steady_clock::now();
    xyz.resize(count * vertexFloats);
    for (std::size_t i = 0; i < count; ++i) {
      cache.readFrame(chunkFrames[i], xyz.data() + i * vertexFloats);
    }
    result.readSeconds += secondsSince(readStart);
    std::vector<std::string> paths;
    for (int frame : chunkFrames) {
      paths.push_back(expandFramePattern(outputPattern, frame));
    }
    writer.writeFrames(chunkFrames, xyz.data(), paths);
    result.written += static_cast<int>(count);
    if (frameDone) {
      for (std::size_t i = 0; i < count; ++i) {
        frameDone(chunkFrames[i], paths[i]);
      }
    }
  }
  result.evaluateSeconds = writer.evaluateSeconds() - evaluateBefore;
  result.writeSeconds = writer.writeSeconds() - writeBefore;
  result.totalSeconds = secondsSince(start);
  return result;
}

}  // namespace drivenshape
