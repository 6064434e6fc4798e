#include <drivenshape/evaluate.h>

#include <cmath>

#include <drivenshape/error.h>
#include <drivenshape/frames.h>

namespace drivenshape {

EvaluationResult evaluateCaches(const PointCacheReader& truth, const PointCacheReader& baked,
                                const std::vector<int>& frames) {
  if (frames.empty()) {
    DS_THROW(kUsage, "the frame range is empty; pass --frames");
  }
  if (truth.vertexCount() != baked.vertexCount()) {
    DS_THROW(kInput, "truth '", truth.path(), "' has ", truth.vertexCount(), " vertices but bake '",
             baked.path(), "' has ", baked.vertexCount(), "; compare caches of the same mesh");
  }
  for (const PointCacheReader* cache : {&truth, &baked}) {
    for (int frame : frames) {
      if (!cache->hasFrame(frame)) {
        DS_THROW(kInput, "'", cache->path(), "' has no frame ", frame, " (it holds ",
                 formatFrameRange(cache->frames()), ")");
      }
    }
  }
  const int v = truth.vertexCount();
  EvaluationResult result;
  result.vertexCount = v;
  std::vector<float> a(static_cast<std::size_t>(v) * 3), b(a.size());
  double sum = 0.0, sumSquares = 0.0;
  for (int frame : frames) {
    truth.readFrame(frame, a.data());
    baked.readFrame(frame, b.data());
    FrameError error;
    error.frame = frame;
    double frameSum = 0.0, frameSquares = 0.0;
    for (int i = 0; i < v; ++i) {
      const double dx = double(a[3 * i]) - b[3 * i];
      const double dy = double(a[3 * i + 1]) - b[3 * i + 1];
      const double dz = double(a[3 * i + 2]) - b[3 * i + 2];
      const double squared = dx * dx + dy * dy + dz * dz;
      const double distance = std::sqrt(squared);
      frameSum += distance;
      frameSquares += squared;
      if (distance > error.max || error.maxVertex < 0) {
        error.max = distance;
        error.maxVertex = i;
      }
    }
    error.mean = frameSum / v;
    error.rms = std::sqrt(frameSquares / v);
    sum += frameSum;
    sumSquares += frameSquares;
    if (error.max > result.max || result.frames.empty()) {
      result.max = error.max;
      result.maxFrame = frame;
    }
    result.frames.push_back(error);
  }
  const double total = static_cast<double>(v) * static_cast<double>(frames.size());
  result.mean = sum / total;
  result.rms = std::sqrt(sumSquares / total);
  return result;
}

}  // namespace drivenshape
