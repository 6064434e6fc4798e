// SPDX-License-Identifier: Apache-2.0
#include <drivenshape/evaluate.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>

#include <drivenshape/device.h>
#include <drivenshape/error.h>
#include <drivenshape/frames.h>
#include <drivenshape/mesh_check.h>

#include "closest.h"
#include "parallel.h"
#include "strain_total.h"

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

/// Running state of one cloth sequence while the frames are read in batches.
struct Accumulator {
  explicit Accumulator(ClothMetrics* target) : metrics(target) {}
  ClothMetrics* metrics = nullptr;
  std::vector<float> previous;  // last frame's positions (empty before the first)
  double sumDistance = 0.0, sumSquares = 0.0;
  std::optional<StrainTotal> strain;  // every edge of every frame, when strain is measured
};

/// Sizes shared by the batch steps of evaluateShot, and the strain's rest edges.
struct ShotLayout {
  int vd = 0;                    // cloth vertices
  std::size_t drivenValues = 0;  // vd x 3
  std::size_t driverValues = 0;  // driver vertices x 3 (0 without a driver)
  bool driver = false;           // driver frames are read (penetrations or the baseline)
  bool penetrations = false;
  const float* restCloth = nullptr;  // the cloth's rest positions (null: no strain)
  std::vector<MeshEdge> edges;       // its edges of non-zero rest length
};

/// The sequences of evaluateShot, in the order of ShotBatch::cloth.
enum { kShotBake = 0, kShotTruth = 1, kShotBaseline = 2 };

/// Buffers of one batch of frames, reused from batch to batch.
struct ShotBatch {
  std::vector<std::vector<float>> cloth;  // per sequence: count x Vd x 3
  std::vector<float> driverBlock;         // count x Vp x 3
  std::vector<float> restDriver, restDriven, signedDistance;
  std::vector<SurfaceHit> hits, baseHits;
};

/// Throws unless the inputs of evaluateShot fit together: a truth and a bake of one cloth that
/// hold every frame, and for penetrations and the baseline the meshes and caches they need.
void checkShotInput(const ShotEvaluationInput& input, const std::vector<int>& frames) {
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
  if (input.drivenMesh != nullptr && input.drivenMesh->vertexCount() != vd) {
    DS_THROW(kInput, "the cloth's rest mesh '", input.drivenMeshName, "' has ",
             input.drivenMesh->vertexCount(), " vertices but the truth '", truth.path(), "' has ",
             vd, "; pass the rest mesh of the cloth those caches animate");
  }
  if (input.baseline && input.mask != nullptr && input.mask->drivenVertexCount() != vd) {
    DS_THROW(kInput, "the binding mask covers ", input.mask->drivenVertexCount(),
             " cloth vertices but the cloth has ", vd);
  }
}

/// The result's description (frames, sizes, which metrics, sequence names) with no metrics yet.
ShotEvaluation emptyShotEvaluation(const ShotEvaluationInput& input, const std::vector<int>& frames,
                                   const ShotLayout& layout, int vp) {
  ShotEvaluation result;
  result.frames = frames;
  result.vertexCount = layout.vd;
  result.driverVertexCount = vp;
  result.penetrations = layout.penetrations;
  result.strain = layout.restCloth != nullptr;
  result.edgeCount = static_cast<int>(layout.edges.size());
  result.hasBaseline = input.baseline;
  result.bake.name = "bake";
  result.bake.source = input.bake->path();
  result.truth.name = "truth";
  result.truth.source = input.truth->path();
  result.baseline.name = "baseline";
  return result;
}

/// The strain's inputs into `layout`: the rest cloth and its edges, those of zero rest length
/// left out (their count returned). Strain is measured (restCloth set) when an edge is left.
int prepareStrain(const ShotEvaluationInput& input, ShotLayout& layout) {
  if (input.drivenMesh == nullptr) {
    return 0;
  }
  const float* rest = input.drivenMesh->positions.data();
  int zeroLength = 0;
  for (const MeshEdge& edge : meshEdges(*input.drivenMesh)) {
    const float* a = rest + 3 * std::size_t(edge[0]);
    const float* b = rest + 3 * std::size_t(edge[1]);
    if (a[0] == b[0] && a[1] == b[1] && a[2] == b[2]) {
      ++zeroLength;
    } else {
      layout.edges.push_back(edge);
    }
  }
  layout.restCloth = layout.edges.empty() ? nullptr : rest;
  return zeroLength;
}

/// The baseline's binding: the closest hits of the rest cloth on the rest driver, once (the
/// bake redoes the same search for every frame, with the same inputs and so the same hits).
/// Empty without the baseline.
std::vector<SurfaceHit> bindRestCloth(const ShotEvaluationInput& input, int vd,
                                      ClosestBackend& closest) {
  std::vector<SurfaceHit> restHits;
  if (input.baseline) {
    const BindingMask all = BindingMask::all(vd);
    closest.setSurface(*input.driverMesh, input.mask != nullptr ? *input.mask : all);
    restHits.resize(static_cast<std::size_t>(vd));
    closest.closest(1, input.driverMesh->positions.data(), input.drivenMesh->positions.data(),
                    restHits.data());
  }
  return restHits;
}

/// Reads frames[begin .. begin + count) of the bake, the truth and (for penetrations) the
/// driver into the batch, refusing non-finite positions.
void readShotBatch(const ShotEvaluationInput& input, const std::vector<int>& frames, int begin,
                   int count, const ShotLayout& layout, ShotBatch& batch) {
  const std::size_t drivenValues = layout.drivenValues;
  const std::size_t driverValues = layout.driverValues;
  for (auto& block : batch.cloth) {
    block.resize(count * drivenValues);
  }
  batch.driverBlock.resize(count * driverValues);
  for (int i = 0; i < count; ++i) {
    const int frame = frames[begin + i];
    readFiniteFrame(*input.bake, frame, &batch.cloth[kShotBake][i * drivenValues], "bake");
    readFiniteFrame(*input.truth, frame, &batch.cloth[kShotTruth][i * drivenValues], "truth");
    if (layout.driver) {
      readFiniteFrame(*input.driver, frame, &batch.driverBlock[i * driverValues], "driver");
    }
  }
}

/// The baseline cloth of the batch: the rest binding carried from the rest driver onto each
/// frame's driver.
void transferBaseline(const ShotEvaluationInput& input, const std::vector<SurfaceHit>& restHits,
                      int count, const ShotLayout& layout, ClosestBackend& closest,
                      ShotBatch& batch) {
  const int vd = layout.vd;
  const std::size_t drivenValues = layout.drivenValues;
  const std::size_t driverValues = layout.driverValues;
  batch.restDriver.resize(count * driverValues);
  batch.restDriven.resize(count * drivenValues);
  batch.baseHits.resize(static_cast<std::size_t>(count) * vd);
  for (int i = 0; i < count; ++i) {
    std::copy_n(input.driverMesh->positions.data(), driverValues,
                &batch.restDriver[i * driverValues]);
    std::copy_n(input.drivenMesh->positions.data(), drivenValues,
                &batch.restDriven[i * drivenValues]);
    std::copy(restHits.begin(), restHits.end(), batch.baseHits.begin() + std::size_t(i) * vd);
  }
  closest.transfer(count, batch.baseHits.data(), batch.restDriver.data(), batch.driverBlock.data(),
                   batch.restDriven.data(), batch.cloth[kShotBaseline].data());
}

/// Signed distances to the driver of every point of one sequence's batch `block` (exact
/// closest triangle, then InsideAudit), into batch.signedDistance.
void measureSignedDistances(const std::vector<float>& block, int count, const ShotLayout& layout,
                            int threads, const InsideAudit& audit, ClosestBackend& closest,
                            ShotBatch& batch) {
  const int vd = layout.vd;
  const std::size_t drivenValues = layout.drivenValues;
  const std::size_t driverValues = layout.driverValues;
  batch.hits.resize(static_cast<std::size_t>(count) * vd);
  batch.signedDistance.resize(static_cast<std::size_t>(count) * vd);
  closest.closest(count, batch.driverBlock.data(), block.data(), batch.hits.data());
  parallelFor(count, threads, [&](int i) {
    audit.signedDistances(&batch.driverBlock[i * driverValues], vd, &block[i * drivenValues],
                          &batch.hits[std::size_t(i) * vd],
                          &batch.signedDistance[std::size_t(i) * vd]);
  });
}

/// Counts the vertices inside the driver (signed distance `sd` < 0) and finds the deepest.
void measureInside(int vd, const float* sd, ClothFrameMetrics& m) {
  m.inside = 0;
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

/// Adds the metrics of one sequence's frames of the batch (error against the truth, jump since
/// the frame before, vertices inside the driver) to its accumulator.
void addSequenceBatch(Accumulator& acc, const std::vector<float>& block,
                      const std::vector<float>& truthBlock, const std::vector<int>& frames,
                      int begin, int count, const ShotLayout& layout, const ShotBatch& batch) {
  const int vd = layout.vd;
  const std::size_t drivenValues = layout.drivenValues;
  for (int i = 0; i < count; ++i) {
    ClothFrameMetrics m;
    m.frame = frames[begin + i];
    const float* now = &block[i * drivenValues];
    m.error = frameError(m.frame, vd, &truthBlock[i * drivenValues], now, acc.sumDistance,
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
    if (layout.penetrations) {
      measureInside(vd, &batch.signedDistance[std::size_t(i) * vd], m);
    }
    if (acc.strain) {
      const std::vector<double> strains = edgeStrains(layout.restCloth, now, vd, layout.edges);
      m.strain = strainFigures(strains);
      acc.strain->add(strains);
    }
    acc.metrics->frames.push_back(m);
  }
  acc.previous.assign(block.end() - drivenValues, block.end());
}

/// The sequence's totals over the frame list: mean and RMS error, the worst frames of error,
/// jump, inside count and depth, the mean inside count and the strain over every frame.
void summarizeSequence(Accumulator& acc, int vd, int frameCount, bool penetrations) {
  const double total = static_cast<double>(vd) * frameCount;
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
  if (acc.strain) {
    c.strain = acc.strain->figures();
  }
}

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
  checkShotInput(input, frames);
  ShotLayout layout;
  layout.driver = input.driver != nullptr;
  const std::string untrusted = layout.driver
                                    ? checkDriverMesh(*input.driverMesh, input.driverMeshName,
                                                      DriverMeshUse::kEval, input.untrustedDriver)
                                    : std::string();
  layout.penetrations = layout.driver && untrusted.empty();
  layout.vd = input.truth->vertexCount();
  const int vp = layout.driver ? input.driverMesh->vertexCount() : 0;
  layout.drivenValues = static_cast<std::size_t>(layout.vd) * 3;
  layout.driverValues = static_cast<std::size_t>(vp) * 3;
  const int zeroLengthEdges = prepareStrain(input, layout);
  ShotEvaluation result = emptyShotEvaluation(input, frames, layout, vp);
  result.untrustedDriver = untrusted;
  result.zeroLengthEdges = zeroLengthEdges;

  const std::vector<SurfaceHit> restHits = bindRestCloth(input, layout.vd, closest);
  std::unique_ptr<InsideAudit> audit;
  if (layout.penetrations) {
    closest.setSurface(*input.driverMesh, BindingMask::all(layout.vd));
    audit = std::make_unique<InsideAudit>(*input.driverMesh);
  }

  std::vector<Accumulator> sequences{Accumulator(&result.bake), Accumulator(&result.truth)};
  if (input.baseline) {
    sequences.emplace_back(&result.baseline);
  }
  const auto frameCount = static_cast<int>(frames.size());
  if (result.strain) {
    for (Accumulator& acc : sequences) {
      acc.strain.emplace(static_cast<long long>(layout.edges.size()) * frameCount);
    }
  }

  const int batchSize = std::max(1, input.batch);
  ShotBatch batch;
  batch.cloth.resize(sequences.size());
  for (int begin = 0; begin < frameCount; begin += batchSize) {
    const int count = std::min(batchSize, frameCount - begin);
    readShotBatch(input, frames, begin, count, layout, batch);
    if (input.baseline) {
      transferBaseline(input, restHits, count, layout, closest, batch);
    }
    for (std::size_t s = 0; s < sequences.size(); ++s) {
      const std::vector<float>& block = batch.cloth[s];
      if (layout.penetrations) {
        measureSignedDistances(block, count, layout, input.threads, *audit, closest, batch);
      }
      addSequenceBatch(sequences[s], block, batch.cloth[kShotTruth], frames, begin, count, layout,
                       batch);
    }
  }

  for (Accumulator& acc : sequences) {
    summarizeSequence(acc, layout.vd, frameCount, layout.penetrations);
  }
  return result;
}

ShotEvaluation evaluateShot(const ShotEvaluationInput& input, const std::vector<int>& frames,
                            Device& device) {
  ClosestOptions search;
  search.threads = input.threads;
  const std::unique_ptr<ClosestBackend> closest = device.makeClosest(search);
  return evaluateShot(input, frames, *closest);
}

}  // namespace drivenshape
