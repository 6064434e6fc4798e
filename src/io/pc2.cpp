// SPDX-License-Identifier: Apache-2.0
#include <drivenshape/point_cache.h>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>

#include <drivenshape/error.h>
#include <drivenshape/frames.h>
#include "atomic_file.h"

#include "byte_order.h"

namespace drivenshape {
namespace {

//   offset  0: char[12] "POINTCACHE2\0"
//          12: int32    version (1)
//          16: int32    points
//          20: float32  start frame
//          24: float32  sample rate
//          28: int32    samples
//          32: float32  x y z of every point of sample 0, then sample 1, ...
constexpr char kMagic[12] = {'P', 'O', 'I', 'N', 'T', 'C', 'A', 'C', 'H', 'E', '2', '\0'};
constexpr std::uint64_t kHeaderBytes = 32;

/// Frames whose sample time is this close to an integer are that frame (float start/rate).
constexpr double kIntegralFrameTol = 1e-3;

/// Reads exactly `bytes` at `offset`; false on a short read (EOF).
bool readAt(int fd, void* data, std::uint64_t bytes, std::uint64_t offset, int& error) {
  auto* out = static_cast<unsigned char*>(data);
  while (bytes > 0) {
    const ssize_t got = ::pread(fd, out, bytes, static_cast<off_t>(offset));
    if (got < 0) {
      if (errno == EINTR) {
        continue;
      }
      error = errno;
      return false;
    }
    if (got == 0) {
      error = 0;
      return false;
    }
    out += got;
    bytes -= static_cast<std::uint64_t>(got);
    offset += static_cast<std::uint64_t>(got);
  }
  return true;
}

class Pc2Reader final : public PointCacheReader {
 public:
  explicit Pc2Reader(std::string path) : mPath(std::move(path)) {
    requireRegularFile(mPath, "PC2");
    mFd = ::open(mPath.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
    if (mFd < 0) {
      DS_THROW(kInput, "cannot open PC2 '", mPath, "': ", std::strerror(errno));
    }
    try {
      readHeader();
    } catch (...) {
      ::close(mFd);
      throw;
    }
  }
  ~Pc2Reader() override { ::close(mFd); }
  Pc2Reader(const Pc2Reader&) = delete;
  Pc2Reader& operator=(const Pc2Reader&) = delete;

  int vertexCount() const override { return mHeader.points; }
  std::vector<int> frames() const override { return mFrames; }
  bool hasFrame(int frame) const override { return sampleOf(frame) >= 0; }
  const std::string& path() const override { return mPath; }

  void readFrame(int frame, float* xyz) const override {
    const int sample = sampleOf(frame);
    if (sample < 0) {
      DS_THROW(
          kInput, mPath, ": frame ", frame, " is not in the cache; it holds ",
          mFrames.empty() ? std::string("no whole frames") : "frames " + formatFrameRange(mFrames));
    }
    const std::uint64_t floats = 3 * static_cast<std::uint64_t>(mHeader.points);
    const std::uint64_t offset = kHeaderBytes + static_cast<std::uint64_t>(sample) * floats * 4;
    int error = 0;
    if (!readAt(mFd, xyz, floats * 4, offset, error)) {
      DS_THROW(kInput, mPath, ": cannot read frame ", frame, " (sample ", sample,
               "): ", error != 0 ? std::strerror(error) : "unexpected end of file",
               "; was the file changed while reading?");
    }
    if (!io::hostIsLittleEndian()) {
      io::swapWords(xyz, floats);
    }
    checkFinite("PC2 '" + mPath + "'", frame, xyz);
  }

 private:
  void readHeader() {
    struct stat info {};
    if (::fstat(mFd, &info) != 0) {
      DS_THROW(kInput, "cannot stat PC2 '", mPath, "': ", std::strerror(errno));
    }
    const auto fileBytes = static_cast<std::uint64_t>(info.st_size);
    unsigned char header[kHeaderBytes];
    int error = 0;
    if (fileBytes < kHeaderBytes || !readAt(mFd, header, kHeaderBytes, 0, error)) {
      DS_THROW(kInput, mPath, ": not a PC2 file: ", fileBytes,
               " bytes, shorter than the 32-byte header");
    }
    if (std::memcmp(header, kMagic, sizeof(kMagic)) != 0) {
      DS_THROW(kInput, mPath, ": not a PC2 file (it does not start with POINTCACHE2)");
    }
    const std::int32_t version = io::loadLeInt32(header + 12);
    mHeader.points = io::loadLeInt32(header + 16);
    mHeader.startFrame = io::loadLeFloat(header + 20);
    mHeader.sampleRate = io::loadLeFloat(header + 24);
    mHeader.samples = io::loadLeInt32(header + 28);
    if (version != 1) {
      DS_THROW(kInput, mPath, ": PC2 version ", version, " is not supported (only version 1)");
    }
    if (mHeader.points <= 0) {
      DS_THROW(kInput, mPath, ": PC2 header says ", mHeader.points,
               " points; a cache needs at least one");
    }
    if (mHeader.samples < 0) {
      DS_THROW(kInput, mPath, ": PC2 header says ", mHeader.samples, " samples");
    }
    if (!std::isfinite(mHeader.startFrame)) {
      DS_THROW(kInput, mPath, ": PC2 start frame is not a finite number");
    }
    if (!(mHeader.sampleRate > 0.0f) || !std::isfinite(mHeader.sampleRate)) {
      DS_THROW(kInput, mPath, ": PC2 sample rate ", mHeader.sampleRate,
               " is not a positive number");
    }
    const std::uint64_t frameBytes = static_cast<std::uint64_t>(mHeader.points) * 12;
    const std::uint64_t expected =
        kHeaderBytes + static_cast<std::uint64_t>(mHeader.samples) * frameBytes;
    if (fileBytes != expected) {
      const std::uint64_t whole = (fileBytes - kHeaderBytes) / frameBytes;
      if (fileBytes < expected) {
        DS_THROW(kInput, mPath, ": PC2 file is truncated: the header promises ", mHeader.samples,
                 " samples of ", mHeader.points, " points (", expected, " bytes) but the file has ",
                 fileBytes, " bytes, ", whole, " whole frames; re-export or rebake the cache");
      }
      DS_THROW(kInput, mPath, ": PC2 file has ", fileBytes, " bytes but the header (",
               mHeader.samples, " samples of ", mHeader.points, " points) accounts for ", expected,
               "; the file is corrupt or not a PC2 cache");
    }
    for (int s = 0; s < mHeader.samples; ++s) {
      const double time = static_cast<double>(mHeader.startFrame) +
                          static_cast<double>(s) * static_cast<double>(mHeader.sampleRate);
      const double nearest = std::round(time);
      if (std::abs(time - nearest) <= kIntegralFrameTol && std::abs(nearest) < 2.0e9) {
        const int frame = static_cast<int>(nearest);
        if (mFrames.empty() || frame > mFrames.back()) {
          mFrames.push_back(frame);
          mSamples.push_back(s);
        }
      }
    }
  }

  int sampleOf(int frame) const {
    const auto found = std::lower_bound(mFrames.begin(), mFrames.end(), frame);
    if (found == mFrames.end() || *found != frame) {
      return -1;
    }
    return mSamples[static_cast<std::size_t>(found - mFrames.begin())];
  }

  std::string mPath;
  int mFd = -1;
  Pc2Header mHeader;
  std::vector<int> mFrames;   ///< ascending integral frames
  std::vector<int> mSamples;  ///< the sample holding mFrames[i]
};

}  // namespace

std::unique_ptr<PointCacheReader> openPc2(const std::string& path) {
  return std::make_unique<Pc2Reader>(path);
}

struct Pc2Writer::State {
  std::string path;
  AtomicFile atomic;
  std::FILE* file = nullptr;
  int vertexCount = 0;
  int frameCount = 0;
  int written = 0;
  std::vector<float> swapped;

  explicit State(const std::string& target) : path(target), atomic(target) {}
  [[noreturn]] void fail(int error) {
    DS_THROW(kOutput, "cannot write '", path, "': ", std::strerror(error), "; is the disk full?");
  }
};

Pc2Writer::Pc2Writer(const std::string& path, int vertexCount, float startFrame, int frameCount,
                     float sampleRate) {
  if (vertexCount <= 0 || frameCount < 0) {
    DS_THROW(kInternal, "Pc2Writer '", path, "': bad arguments (", vertexCount, " vertices, ",
             frameCount, " frames)");
  }
  if (!(sampleRate > 0.0f) || !std::isfinite(sampleRate) || !std::isfinite(startFrame)) {
    DS_THROW(kUsage, "PC2 '", path, "': start frame ", startFrame, " and sample rate ", sampleRate,
             " must be finite and the rate positive");
  }
  mState = std::make_unique<State>(path);
  mState->vertexCount = vertexCount;
  mState->frameCount = frameCount;
  mState->file = mState->atomic.file();
  unsigned char header[kHeaderBytes];
  std::memcpy(header, kMagic, sizeof(kMagic));
  io::storeLeInt32(header + 12, 1);
  io::storeLeInt32(header + 16, vertexCount);
  io::storeLeFloat(header + 20, startFrame);
  io::storeLeFloat(header + 24, sampleRate);
  io::storeLeInt32(header + 28, frameCount);
  if (std::fwrite(header, 1, kHeaderBytes, mState->file) != kHeaderBytes) {
    mState->fail(errno);
  }
}

Pc2Writer::~Pc2Writer() = default;

void Pc2Writer::writeFrame(const float* xyz) {
  State& state = *mState;
  if (state.file == nullptr || state.written >= state.frameCount || xyz == nullptr) {
    DS_THROW(kInternal, "Pc2Writer '", state.path, "': frame ", state.written + 1, " of ",
             state.frameCount, " written after commit, past the end or from a null buffer");
  }
  const std::size_t floats = 3 * static_cast<std::size_t>(state.vertexCount);
  const float* frame = xyz;
  if (!io::hostIsLittleEndian()) {
    state.swapped.assign(xyz, xyz + floats);
    io::swapWords(state.swapped.data(), floats);
    frame = state.swapped.data();
  }
  if (std::fwrite(frame, sizeof(float), floats, state.file) != floats) {
    state.fail(errno);
  }
  ++state.written;
}

void Pc2Writer::commit() {
  State& state = *mState;
  if (state.written != state.frameCount || state.file == nullptr) {
    DS_THROW(kInternal, "Pc2Writer '", state.path, "': ", state.written, " of ", state.frameCount,
             " frames written at commit");
  }
  state.file = nullptr;  // AtomicFile flushes, syncs and closes it
  state.atomic.commit();
}

void writePc2(const std::string& path, int vertexCount, float startFrame, int frameCount,
              const float* xyz, float sampleRate) {
  if (vertexCount <= 0 || frameCount < 0 || (frameCount > 0 && xyz == nullptr)) {
    DS_THROW(kInternal, "writePc2 '", path, "': bad arguments (", vertexCount, " vertices, ",
             frameCount, " frames)");
  }
  Pc2Writer writer(path, vertexCount, startFrame, frameCount, sampleRate);
  const std::size_t frameFloats = 3 * static_cast<std::size_t>(vertexCount);
  for (int f = 0; f < frameCount; ++f) {
    writer.writeFrame(xyz + static_cast<std::size_t>(f) * frameFloats);
  }
  writer.commit();
}

}  // namespace drivenshape
