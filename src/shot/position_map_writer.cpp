// SPDX-License-Identifier: Apache-2.0
// PositionMapWriter and writePositionMapSequence: tables once, then chunks of frames through
// a backend into EXR files (and PNG previews).

#include <drivenshape/position_map_sequence.h>

#include "parallel.h"
#include "stopwatch.h"

#include <algorithm>
#include <chrono>
#include <exception>
#include <ostream>
#include <thread>
#include <vector>

#include <drivenshape/error.h>
#include <drivenshape/frames.h>
#include <drivenshape/position_map_tables.h>

#include "atomic_file.h"

namespace drivenshape {
namespace {

/// Maps of one launch are kept within this many bytes (P, plus N when asked for).
constexpr std::size_t kChunkBytes = std::size_t{256} << 20;
constexpr int kMaxChunkFrames = 16;

}  // namespace

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
  mTables =
      buildPositionMapTables(mesh, mOptions.width, mOptions.height, mOptions.padding, meshName);
  if (log != nullptr && !mTables.overlaps.empty()) {
    *log << "warning: " << meshName << ": " << mTables.overlaps.describe() << "\n";
  }
  mBackend->upload(mTables);

  const std::size_t frameBytes =
      3 * mTables.texelCount() * sizeof(float) * (mOptions.normals ? 2 : 1);
  const std::size_t limit = std::min(kChunkBytes, mBackend->maxBufferBytes() / 2);
  const int fit = static_cast<int>(std::min<std::size_t>(
      kMaxChunkFrames, std::max<std::size_t>(1, limit / std::max<std::size_t>(1, frameBytes))));
  mChunkSize = mOptions.chunkSize > 0 ? mOptions.chunkSize : fit;
}

PositionMapWriter::~PositionMapWriter() = default;

std::string PositionMapWriter::backendName() const {
  return mBackend->name();
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
  const std::size_t mapFloats = 3 * mTables.texelCount();
  const std::size_t vertexFloats = 3 * static_cast<std::size_t>(mTables.vertexCount);
  const std::size_t needed = static_cast<std::size_t>(count) * mapFloats;
  if (mPositions.size() < needed) {
    mPositions.resize(needed);
  }
  if (mOptions.normals && mNormals.size() < needed) {
    mNormals.resize(needed);
  }
  const auto evaluateStart = std::chrono::steady_clock::now();
  mBackend->evaluate(count, xyz, mPositions.data(), mOptions.normals ? mNormals.data() : nullptr);
  mEvaluateSeconds += secondsSince(evaluateStart);

  const auto writeStart = std::chrono::steady_clock::now();
  // Files on `threads` threads; the cores left over deflate the chunks within each file (one
  // frame per call, as `bake --posmap` writes with --batch 1, still uses every core).
  const int threads = resolveThreads(mOptions.threads, count);
  const int encodeThreads = std::max(1, resolveThreads(mOptions.threads) / threads);
  parallelFor(count, threads, [&](int i) {
    const std::size_t f = static_cast<std::size_t>(i);
    PositionMapFrameHeader header;
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
    const float* positions = mPositions.data() + f * mapFloats;
    writePositionMapExr(paths[i], mTables.width, mTables.height, positions, mTables.coverage.data(),
                        mOptions.normals ? mNormals.data() + f * mapFloats : nullptr, header);
    if (mOptions.preview) {
      writePositionMapPreview(positionMapPreviewPath(paths[i]), mTables, positions, header.bounds);
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
