// SPDX-License-Identifier: Apache-2.0
#include <drivenshape/point_cache.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <map>

#include <drivenshape/error.h>
#include <drivenshape/frames.h>

#include "hash.h"

#include "finite.h"
#include "frame_token.h"

namespace drivenshape {
namespace {

bool endsWithPc2(const std::string& spec) {
  if (spec.size() < 4) {
    return false;
  }
  std::string tail = spec.substr(spec.size() - 4);
  std::transform(tail.begin(), tail.end(), tail.begin(),
                 [](unsigned char ch) { return static_cast<char>(std::tolower(ch)); });
  return tail == ".pc2";
}

/// The files of the point-cache EXR sequence `pattern` by frame, found by listing the
/// pattern's folder (io::listSequenceFiles says which names belong to it). Throws Error(kInput)
/// for a pattern without exactly one frame token in its file name, a missing folder, or no file.
std::map<int, std::string> listExrSequence(const std::string& pattern) {
  const std::vector<io::FrameToken> tokens = io::findFrameTokens(pattern);
  if (tokens.size() != 1) {
    DS_THROW(kInput, "'", pattern, "' has ", tokens.size(),
             " frame tokens; an EXR sequence pattern needs exactly one (name.####.exr)");
  }
  const io::FrameToken& token = tokens.front();
  const std::string fileName = std::filesystem::path(pattern).filename().string();
  const std::size_t nameStart = pattern.size() - fileName.size();
  if (token.pos < nameStart) {
    DS_THROW(kInput, "'", pattern,
             "': the frame token must be in the file name, not in a folder name");
  }
  const std::string folderText = pattern.substr(0, nameStart);
  const std::filesystem::path folder = folderText.empty() ? "." : folderText;

  std::error_code ec;
  if (!std::filesystem::is_directory(folder, ec)) {
    DS_THROW(kInput, "EXR sequence '", pattern, "': folder '", folder.string(), "' does not exist");
  }
  std::map<int, std::string> found = io::listSequenceFiles(pattern, ec);
  if (ec) {
    DS_THROW(kInput, "EXR sequence '", pattern, "': cannot list folder '", folder.string(),
             "': ", ec.message());
  }
  if (found.empty()) {
    DS_THROW(kInput, "EXR sequence '", pattern, "': no files match in folder '", folder.string(),
             "' (e.g. ", expandFramePattern(pattern, 1001), ")");
  }
  return found;
}

/// Throws Error(kInput) when the header `info` of `file` holds another frame than `frame`, the
/// one its name says (a file without the frame attribute is taken at its name).
void requireNamedFrame(const std::string& file, int frame, const ExrPointCacheInfo& info) {
  if (info.hasFrame && info.frame != frame) {
    DS_THROW(kInput, "point-cache EXR '", file, "' holds frame ", info.frame,
             " (its header's dsFrame), not frame ", frame,
             " as its name says: it was copied or renamed to the wrong place; rename it or "
             "bake the frame again");
  }
}

/// A point-cache EXR sequence: one file per frame (listExrSequence).
class ExrSequenceReader final : public PointCacheReader {
 public:
  ExrSequenceReader(std::string pattern, std::uint64_t expectedTopology)
      : mPattern(std::move(pattern)), mExpectedTopology(expectedTopology) {
    for (const auto& [frame, file] : listExrSequence(mPattern)) {
      mFrames.push_back(frame);
      mFiles.push_back(file);
    }
    // The first frame defines the vertex count; every frame read later must agree.
    const ExrPointCacheInfo info = readPointCacheExrInfo(mFiles.front());
    mVertexCount = info.vertexCount;
    if (mExpectedTopology != 0 && info.topologyHash != 0 &&
        info.topologyHash != mExpectedTopology) {
      DS_THROW(kInput, mFiles.front(), ": topology hash ", hashToHex(info.topologyHash),
               " differs from ", hashToHex(mExpectedTopology),
               "; the cache was baked for another mesh; rebake it or pass the matching mesh");
    }
  }

  int vertexCount() const override { return mVertexCount; }
  std::vector<int> frames() const override { return mFrames; }
  bool hasFrame(int frame) const override { return indexOf(frame) >= 0; }
  const std::string& path() const override { return mPattern; }

  void readFrame(int frame, float* xyz) const override {
    const int index = indexOf(frame);
    if (index < 0) {
      DS_THROW(kInput, "EXR sequence '", mPattern, "': frame ", frame,
               " is missing; the sequence has frames ", formatFrameRange(mFrames));
    }
    std::vector<float> buffer;
    const std::string& file = mFiles[static_cast<std::size_t>(index)];
    const ExrPointCacheInfo info = readPointCacheExr(file, buffer, mVertexCount, mExpectedTopology);
    requireNamedFrame(file, frame, info);
    checkFinite("point-cache EXR '" + file + "'", frame, buffer.data());
    std::copy(buffer.begin(), buffer.end(), xyz);
  }

 private:
  int indexOf(int frame) const {
    const auto found = std::lower_bound(mFrames.begin(), mFrames.end(), frame);
    if (found == mFrames.end() || *found != frame) {
      return -1;
    }
    return static_cast<int>(found - mFrames.begin());
  }

  std::string mPattern;
  std::uint64_t mExpectedTopology;
  int mVertexCount = 0;
  std::vector<int> mFrames;         ///< ascending
  std::vector<std::string> mFiles;  ///< file of mFrames[i]
};

}  // namespace

std::unique_ptr<PointCacheReader> openPointCache(const std::string& spec,
                                                 std::uint64_t expectedTopology) {
  if (endsWithPc2(spec)) {
    return openPc2(spec);
  }
  if (hasFramePattern(spec)) {
    return std::make_unique<ExrSequenceReader>(spec, expectedTopology);
  }
  DS_THROW(kInput, "'", spec,
           "' is neither a .pc2 file nor an EXR sequence pattern (use name.####.exr)");
}

ExrSequenceInfo checkPointCacheExrSequence(const std::string& pattern) {
  ExrSequenceInfo sequence;
  for (const auto& [frame, file] : listExrSequence(pattern)) {
    const ExrPointCacheInfo info = readPointCacheExrInfo(file);
    requireNamedFrame(file, frame, info);
    if (!isCompleteExr(file)) {
      DS_THROW(kInput, "point-cache EXR '", file, "' (frame ", frame,
               ") is incomplete: scan lines are missing or cut short; bake the frame again");
    }
    if (sequence.files.empty()) {
      sequence.first = info;
    } else if (info.vertexCount != sequence.first.vertexCount) {
      DS_THROW(kInput, "point-cache EXR '", file, "' (frame ", frame, ") holds ", info.vertexCount,
               " vertices but frame ", sequence.frames.front(), " ('", sequence.files.front(),
               "') holds ", sequence.first.vertexCount,
               ": the sequence mixes caches of different meshes; bake the frame again");
    } else if (info.topologyHash != sequence.first.topologyHash) {
      DS_THROW(kInput, "point-cache EXR '", file, "' (frame ", frame, ") has topology hash ",
               hashToHex(info.topologyHash), " but frame ", sequence.frames.front(), " ('",
               sequence.files.front(), "') has ", hashToHex(sequence.first.topologyHash),
               ": the sequence mixes caches of different meshes; bake the frame again");
    }
    sequence.frames.push_back(frame);
    sequence.files.push_back(file);
  }
  return sequence;
}

std::vector<float> readFrames(const PointCacheReader& cache, const std::vector<int>& frames) {
  const std::size_t frameFloats = 3 * static_cast<std::size_t>(cache.vertexCount());
  std::vector<float> data(frames.size() * frameFloats);
  for (std::size_t i = 0; i < frames.size(); ++i) {
    cache.readFrame(frames[i], data.data() + i * frameFloats);
  }
  return data;
}

void PointCacheReader::checkFinite(const std::string& source, int frame, const float* xyz) const {
  if (!mAllowNonFinite) {
    requireFiniteFrame(source, frame, xyz, 3 * static_cast<std::size_t>(vertexCount()));
  }
}

void readFiniteFrame(const PointCacheReader& cache, int frame, float* xyz,
                     const std::string& role) {
  cache.readFrame(frame, xyz);
  // The readers refuse non-finite positions themselves, except one opened with
  // allowNonFinite: this contract holds whatever reader it is given.
  const std::size_t values = 3 * static_cast<std::size_t>(cache.vertexCount());
  requireFiniteFrame(role + " '" + cache.path() + "'", frame, xyz, values);
  for (std::size_t i = 0; i < values; ++i) {
    if (std::fabs(xyz[i]) > kMaxCoordinate) {
      DS_THROW(kInput, role, " '", cache.path(), "' frame ", frame, " vertex ", i / 3,
               " has the coordinate ", xyz[i], ", beyond the ", kMaxCoordinate,
               " scene units a cache may hold; fix the cache or its units");
    }
  }
}

}  // namespace drivenshape
