#pragma once

#include <string>
#include <vector>

#include <drivenshape/point_cache.h>

namespace drivenshape {

/// Per-vertex position error of a bake against a truth cache (metres, or the caches' unit).
struct FrameError {
  int frame = 0;
  double mean = 0, rms = 0, max = 0;
  int maxVertex = -1;  ///< the vertex where `max` occurs
};

struct EvaluationResult {
  std::vector<FrameError> frames;
  double mean = 0, rms = 0, max = 0;  ///< over all vertices of all frames
  int maxFrame = 0;
  int vertexCount = 0;
};

/// Compares two caches frame by frame. Throws Error(kInput) if the vertex counts differ or a
/// frame is missing from either.
EvaluationResult evaluateCaches(const PointCacheReader& truth, const PointCacheReader& baked,
                                const std::vector<int>& frames);

}  // namespace drivenshape
