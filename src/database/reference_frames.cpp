// SPDX-License-Identifier: Apache-2.0
#include "reference_frames.h"

#include <algorithm>
#include <limits>
#include <set>

#include <drivenshape/error.h>
#include <drivenshape/frames.h>

namespace drivenshape {

void checkClipVertexCount(const PointCacheReader& cache, const Mesh& mesh, const char* role,
                          const std::string& what) {
  if (cache.vertexCount() != mesh.vertexCount()) {
    DS_THROW(kInput, what, ": ", role, " cache '", cache.path(), "' has ", cache.vertexCount(),
             " vertices but the ", role, " mesh has ", mesh.vertexCount(),
             "; give caches written for the rest meshes (the same character and cloth)");
  }
}

void checkFramesHeld(const PointCacheReader& cache, const std::vector<int>& frames,
                     const std::string& what, const char* role, const char* advice) {
  for (int frame : frames) {
    if (!cache.hasFrame(frame)) {
      const std::vector<int> held = cache.frames();
      DS_THROW(kInput, what, ": ", role, "cache '", cache.path(), "' has no frame ", frame,
               " (it holds ", held.empty() ? std::string("no frames") : formatFrameRange(held),
               "); ", advice);
    }
  }
}

std::vector<int> clipFrames(const PointCacheReader& cache, std::vector<int> frames,
                            const std::string& what) {
  if (frames.empty()) {
    frames = cache.frames();
  }
  std::sort(frames.begin(), frames.end());
  frames.erase(std::unique(frames.begin(), frames.end()), frames.end());
  if (frames.empty()) {
    DS_THROW(kInput, what, ": cache '", cache.path(), "' holds no frames");
  }
  checkFramesHeld(cache, frames, what, "", "choose frames within that range");
  return frames;
}

std::vector<int> earlierFrames(const PointCacheReader& cache, const std::vector<int>& frames,
                               int need) {
  const std::set<int> wanted(frames.begin(), frames.end());
  std::set<int> earlier;
  for (int frame : frames) {
    for (int j = 1; j <= need; ++j) {
      const long long before = static_cast<long long>(frame) - j;
      if (before >= std::numeric_limits<int>::min() &&
          wanted.count(static_cast<int>(before)) == 0 && cache.hasFrame(static_cast<int>(before))) {
        earlier.insert(static_cast<int>(before));
      }
    }
  }
  return std::vector<int>(earlier.begin(), earlier.end());
}

std::vector<float> readFiniteFrames(const PointCacheReader& cache, const std::vector<int>& frames,
                                    const char* role) {
  for (int frame : frames) {
    if (!cache.hasFrame(frame)) {
      DS_THROW(kInput, role, " cache '", cache.path(), "' has no frame ", frame);
    }
  }
  const std::size_t perFrame = static_cast<std::size_t>(cache.vertexCount()) * 3;
  std::vector<float> values(frames.size() * perFrame);
  for (std::size_t i = 0; i < frames.size(); ++i) {
    readFiniteFrame(cache, frames[i], values.data() + i * perFrame, std::string(role) + " cache");
  }
  return values;
}

}  // namespace drivenshape
