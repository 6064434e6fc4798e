#include <drivenshape/evaluate.h>

#include <algorithm>
#include <cmath>

#include <drivenshape/error.h>
#include <drivenshape/frames.h>
#include <drivenshape/parallel.h>

namespace drivenshape {
namespace {

void checkFramesPresent(const PointCacheReader& cache, const std::vector<int>& frames,
                        const char* role) {
  for (int frame : frames) {
    if (!cache.hasFrame(frame)) {
      DS_THROW(kInput, role, " '", cache.path(), "' has no frame ", frame, " (it holds ",
               formatFrameRange(cache.frames()), "); pass --frames within that range");
    }
  }
}

/// Per-vertex distances between two V x 3 blocks.
FrameError frameError(int frame, int vertexCount, const float* a, const float* b,
                      double& sumDistance, double& sumSquares) {
  FrameError error;
  error.frame = frame;
  double frameSum = 0.0, frameSquares = 0.0;
  for (int i = 0; i < vertexCount; ++i) {
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
  error.mean = vertexCount > 0 ? frameSum / vertexCount : 0.0;
  error.rms = vertexCount > 0 ? std::sqrt(frameSquares / vertexCount) : 0.0;
  sumDistance += frameSum;
  sumSquares += frameSquares;
  return error;
}

/// Reads one frame and refuses NaN or infinite positions, naming the file, frame and vertex.
void readFinite(const PointCacheReader& cache, int frame, float* xyz, const char* role) {
  cache.readFrame(frame, xyz);
  const std::size_t values = static_cast<std::size_t>(cache.vertexCount()) * 3;
  for (std::size_t j = 0; j < values; ++j) {
    if (!std::isfinite(xyz[j])) {
      DS_THROW(kInput, role, " '", cache.path(), "' frame ", frame, " vertex ", j / 3,
               " is not a finite number; fix the cache or leave the frame out of --frames");
    }
  }
}

/// Running state of one cloth sequence while the frames are read in batches.
struct Accumulator {
  explicit Accumulator(ClothMetrics* target) : metrics(target) {}
  ClothMetrics* metrics = nullptr;
  std::vector<float> previous;  // last frame's positions (empty before the first)
  double sumDistance = 0.0, sumSquares = 0.0;
};

}  // namespace

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
    const FrameError error = frameError(frame, v, a.data(), b.data(), sum, sumSquares);
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

ShotEvaluation evaluateShot(const ShotEvaluationInput& input, const std::vector<int>& frames,
                            ClosestBackend& closest) {
  if (frames.empty()) {
    DS_THROW(kUsage, "the frame range is empty; pass --frames");
  }
  if (input.truth == nullptr || input.bake == nullptr) {
    DS_THROW(kInternal, "evaluateShot needs a truth and a bake cache");
  }
  const PointCacheReader& truth = *input.truth;
  const PointCacheReader& bake = *input.bake;
  if (truth.vertexCount() != bake.vertexCount()) {
    DS_THROW(kInput, "truth '", truth.path(), "' has ", truth.vertexCount(), " vertices but bake '",
             bake.path(), "' has ", bake.vertexCount(), "; compare caches of the same mesh");
  }
  checkFramesPresent(truth, frames, "truth");
  checkFramesPresent(bake, frames, "bake");

  const bool penetrations = input.driver != nullptr;
  if (penetrations && input.driverMesh == nullptr) {
    DS_THROW(kUsage,
             "penetrations need the driver's rest mesh (its triangles) beside the "
             "driver cache '",
             input.driver->path(), "'; pass --driver-mesh M.obj or --db DB");
  }
  if (input.baseline) {
    if (input.driver == nullptr) {
      DS_THROW(kUsage, "the binding baseline needs the shot's driver cache; pass --driver CACHE");
    }
    if (input.drivenMesh == nullptr) {
      DS_THROW(kUsage,
               "the binding baseline needs the cloth's rest mesh; pass --driven-mesh "
               "M.obj or --db DB");
    }
  }
  const int vd = truth.vertexCount();
  const int vp = penetrations ? input.driverMesh->vertexCount() : 0;
  if (penetrations) {
    if (input.driver->vertexCount() != vp) {
      DS_THROW(kInput, "driver cache '", input.driver->path(), "' has ",
               input.driver->vertexCount(), " vertices but the driver mesh '", input.driverMeshName,
               "' has ", vp, "; pass the rest mesh of the driver that cache animates");
    }
    if (input.driverMesh->triangleCount() == 0) {
      DS_THROW(kInput, "the driver mesh '", input.driverMeshName,
               "' has no faces; penetrations need a closed triangle surface");
    }
    checkFramesPresent(*input.driver, frames, "driver");
  }
  if (input.baseline && input.drivenMesh->vertexCount() != vd) {
    DS_THROW(kInput, "the cloth's rest mesh '", input.drivenMeshName, "' has ",
             input.drivenMesh->vertexCount(), " vertices but the truth '", truth.path(), "' has ",
             vd, "; pass the rest mesh of the cloth those caches animate");
  }
  if (input.baseline && input.mask != nullptr && input.mask->drivenVertexCount() != vd) {
    DS_THROW(kInput, "the binding mask covers ", input.mask->drivenVertexCount(),
             " cloth vertices but the cloth has ", vd);
  }

  ShotEvaluation result;
  result.frames = frames;
  result.vertexCount = vd;
  result.driverVertexCount = vp;
  result.penetrations = penetrations;
  result.hasBaseline = input.baseline;
  result.bake.name = "bake";
  result.bake.source = bake.path();
  result.truth.name = "truth";
  result.truth.source = truth.path();
  result.baseline.name = "baseline";

  const std::size_t drivenValues = static_cast<std::size_t>(vd) * 3;
  const std::size_t driverValues = static_cast<std::size_t>(vp) * 3;

  // The baseline's binding: the rest cloth on the rest driver, once (the bake redoes the same
  // search for every frame, with the same inputs and so the same hits).
  std::vector<SurfaceHit> restHits;
  if (input.baseline) {
    const BindingMask all = BindingMask::all(vd);
    closest.setSurface(*input.driverMesh, input.mask != nullptr ? *input.mask : all);
    restHits.resize(static_cast<std::size_t>(vd));
    closest.closest(1, input.driverMesh->positions.data(), input.drivenMesh->positions.data(),
                    restHits.data());
  }
  std::unique_ptr<InsideAudit> audit;
  if (penetrations) {
    closest.setSurface(*input.driverMesh, BindingMask::all(vd));
    audit = std::make_unique<InsideAudit>(*input.driverMesh);
  }

  std::vector<Accumulator> sequences{Accumulator(&result.bake), Accumulator(&result.truth)};
  if (input.baseline) {
    sequences.emplace_back(&result.baseline);
  }
  enum { kBake = 0, kTruth = 1, kBaseline = 2 };

  const int batch = std::max(1, input.batch);
  const auto frameCount = static_cast<int>(frames.size());
  std::vector<std::vector<float>> cloth(sequences.size());
  std::vector<float> driverBlock, restDriver, restDriven, signedDistance;
  std::vector<SurfaceHit> hits, baseHits;
  for (int begin = 0; begin < frameCount; begin += batch) {
    const int count = std::min(batch, frameCount - begin);
    for (auto& block : cloth) {
      block.resize(count * drivenValues);
    }
    driverBlock.resize(count * driverValues);
    for (int i = 0; i < count; ++i) {
      const int frame = frames[begin + i];
      readFinite(bake, frame, &cloth[kBake][i * drivenValues], "bake");
      readFinite(truth, frame, &cloth[kTruth][i * drivenValues], "truth");
      if (penetrations) {
        readFinite(*input.driver, frame, &driverBlock[i * driverValues], "driver");
      }
    }
    if (input.baseline) {
      restDriver.resize(count * driverValues);
      restDriven.resize(count * drivenValues);
      baseHits.resize(static_cast<std::size_t>(count) * vd);
      for (int i = 0; i < count; ++i) {
        std::copy_n(input.driverMesh->positions.data(), driverValues,
                    &restDriver[i * driverValues]);
        std::copy_n(input.drivenMesh->positions.data(), drivenValues,
                    &restDriven[i * drivenValues]);
        std::copy(restHits.begin(), restHits.end(), baseHits.begin() + std::size_t(i) * vd);
      }
      closest.transfer(count, baseHits.data(), restDriver.data(), driverBlock.data(),
                       restDriven.data(), cloth[kBaseline].data());
    }

    for (std::size_t s = 0; s < sequences.size(); ++s) {
      Accumulator& acc = sequences[s];
      const std::vector<float>& block = cloth[s];
      if (penetrations) {
        hits.resize(static_cast<std::size_t>(count) * vd);
        signedDistance.resize(static_cast<std::size_t>(count) * vd);
        closest.closest(count, driverBlock.data(), block.data(), hits.data());
        parallelFor(count, input.threads, [&](int i) {
          audit->signedDistances(&driverBlock[i * driverValues], vd, &block[i * drivenValues],
                                 &hits[std::size_t(i) * vd], &signedDistance[std::size_t(i) * vd]);
        });
      }
      for (int i = 0; i < count; ++i) {
        ClothFrameMetrics m;
        m.frame = frames[begin + i];
        const float* now = &block[i * drivenValues];
        m.error = frameError(m.frame, vd, &cloth[kTruth][i * drivenValues], now, acc.sumDistance,
                             acc.sumSquares);
        const float* before = i > 0                  ? now - drivenValues
                              : acc.previous.empty() ? nullptr
                                                     : acc.previous.data();
        if (before != nullptr) {
          double sumUnused = 0.0, squaresUnused = 0.0;
          const FrameError move = frameError(m.frame, vd, before, now, sumUnused, squaresUnused);
          m.jump = move.max;
          m.jumpVertex = move.maxVertex;
        }
        if (penetrations) {
          m.inside = 0;
          const float* sd = &signedDistance[std::size_t(i) * vd];
          for (int v = 0; v < vd; ++v) {
            if (sd[v] < 0.0f) {
              ++m.inside;
              if (-double(sd[v]) > m.maxDepth) {
                m.maxDepth = -double(sd[v]);
                m.maxDepthVertex = v;
              }
            }
          }
        }
        acc.metrics->frames.push_back(m);
      }
      acc.previous.assign(block.end() - drivenValues, block.end());
    }
  }

  const double total = static_cast<double>(vd) * frameCount;
  for (Accumulator& acc : sequences) {
    ClothMetrics& c = *acc.metrics;
    c.mean = total > 0 ? acc.sumDistance / total : 0.0;
    c.rms = total > 0 ? std::sqrt(acc.sumSquares / total) : 0.0;
    long long insideTotal = 0;
    for (std::size_t f = 0; f < c.frames.size(); ++f) {
      const ClothFrameMetrics& m = c.frames[f];
      if (f == 0 || m.error.max > c.max) {
        c.max = m.error.max;
        c.maxFrame = m.frame;
      }
      if (m.jump > c.maxJump) {
        c.maxJump = m.jump;
        c.maxJumpFrame = m.frame;
      }
      if (penetrations) {
        insideTotal += m.inside;
        if (m.inside > c.maxInside) {
          c.maxInside = m.inside;
          c.maxInsideFrame = m.frame;
        }
        if (m.maxDepth > c.maxDepth) {
          c.maxDepth = m.maxDepth;
          c.maxDepthFrame = m.frame;
        }
      }
    }
    if (penetrations) {
      c.meanInside = static_cast<double>(insideTotal) / frameCount;
    }
  }
  return result;
}

}  // namespace drivenshape
