// SPDX-License-Identifier: Apache-2.0
// drivenshape_bench --floor (bench_floor.h): the resolution's closest-point search on a
// workload's own frames, three ways, each block timed alone with its results read back.

#include "bench_floor.h"

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <vector>

#include <drivenshape/evaluator.h>
#include <drivenshape/shot_plan.h>

#include "closest.h"
#include "device_array.h"

namespace drivenshape::bench {
namespace {

/// Seconds `body` takes, the device's queue drained by the read-back inside it.
double seconds(const std::function<void()>& body) {
  const auto start = std::chrono::steady_clock::now();
  body();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

/// One run's totals over the shot.
struct Run {
  double seconds = 0.0;
  long long searched = 0;  ///< points given a search (not answered without one)
};

/// The three runs on one block of `count` frames: poses and points hold the block (host
/// copies); every run views the poses afresh, so each refits the tree as a bake block does.
void timeBlock(ClosestBackend& backend, const InsideAudit& audit, int count, int driverValues,
               std::vector<float>& poses, std::vector<float>& points, float offset,
               DeviceArray& poseArray, DeviceArray& pointArray, DeviceArray& hits,
               DeviceArray& answered, Run runs[3]) {
  const int vd = static_cast<int>(points.size() / static_cast<std::size_t>(3 * count));
  const std::size_t items = static_cast<std::size_t>(count) * static_cast<std::size_t>(vd);
  std::vector<int> cleared(static_cast<std::size_t>(count));
  hits.resize<SurfaceHit>(items);
  answered.resize<std::int32_t>(items);
  poseArray.view(poses.data(), poses.size());
  pointArray.view(points.data(), points.size());
  runs[0].seconds += seconds([&] {
    backend.closestBlock(count, poseArray, pointArray, hits);
    hits.read<SurfaceHit>();
  });
  runs[0].searched += static_cast<long long>(items);
  const std::vector<SurfaceHit> exact(hits.read<SurfaceHit>(), hits.read<SurfaceHit>() + items);
  // The floor's knowledge: which points the resolution must see (exact signed distance below
  // the offset); the others are answered with their exact hits.
  std::vector<float> distance(items);
  std::int32_t* known = answered.write<std::int32_t>();
  for (int f = 0; f < count; ++f) {
    const std::size_t at = static_cast<std::size_t>(f) * static_cast<std::size_t>(vd);
    audit.signedDistances(&poses[static_cast<std::size_t>(f) * driverValues], vd, &points[3 * at],
                          &exact[at], &distance[at]);
  }
  for (std::size_t i = 0; i < items; ++i) {
    known[i] = distance[i] >= offset ? 1 : 0;
    runs[2].searched += known[i] == 0 ? 1 : 0;
  }
  poseArray.view(poses.data(), poses.size());
  pointArray.view(points.data(), points.size());
  runs[1].seconds += seconds([&] {
    backend.closestOrClearBlock(count, poseArray, pointArray, offset, hits, cleared.data());
    hits.read<SurfaceHit>();
  });
  for (const int c : cleared) {
    runs[1].searched += vd - c;
  }
  std::copy(exact.begin(), exact.end(), hits.write<SurfaceHit>());
  // What the floor is told is on the device before the clock starts.
  hits.deviceForRead();
  answered.deviceForRead();
  poseArray.view(poses.data(), poses.size());
  pointArray.view(points.data(), points.size());
  runs[2].seconds += seconds([&] {
    backend.closestOrClearBlock(count, poseArray, pointArray, offset, hits, cleared.data(),
                                &answered, true);
    hits.read<SurfaceHit>();
  });
}

}  // namespace

nlohmann::json measureResolutionFloor(const Database& db, const PointCacheReader& shot,
                                      Device& device, const BakeOptions& options,
                                      const std::filesystem::path& folder) {
  BakeOptions before = options;
  before.evaluator.resolve = false;
  before.evaluator.audit = false;
  before.outputPattern = (folder / "cloth.####.exr").string();
  bake(db, shot, device, before);
  const std::unique_ptr<PointCacheReader> cloth = openPointCache(before.outputPattern);
  const int vd = db.drivenVertexCount();
  const int driverValues = 3 * db.driverVertexCount();
  ClosestOptions closestOptions;
  closestOptions.threads = options.threads;
  std::unique_ptr<ClosestBackend> backend = device.makeClosest(closestOptions);
  backend->setSurface(db.driverMesh, BindingMask::all(vd));
  const InsideAudit audit(db.driverMesh);
  const float offset = static_cast<float>(options.evaluator.skinOffset);
  DeviceArray poseArray = device.makeArray(), pointArray = device.makeArray(),
              hits = device.makeArray(), answered = device.makeArray();
  Run runs[3];
  // The bake's own batches (lowered for large meshes, shotPlanSettings).
  EvaluatorSettings settings = options.evaluator;
  settings.threads = options.threads;
  const int block =
      shotPlanSettings(Evaluator(db, settings, device), options.batchFrames, options.temporalWarmup)
          .batch;
  const std::vector<int>& frames = options.frames;
  for (std::size_t first = 0; first < frames.size(); first += static_cast<std::size_t>(block)) {
    const int count = static_cast<int>(std::min<std::size_t>(block, frames.size() - first));
    std::vector<float> poses(static_cast<std::size_t>(count) * driverValues);
    std::vector<float> points(static_cast<std::size_t>(count) * 3 * vd);
    for (int f = 0; f < count; ++f) {
      shot.readFrame(frames[first + f], &poses[static_cast<std::size_t>(f) * driverValues]);
      cloth->readFrame(frames[first + f], &points[static_cast<std::size_t>(f) * 3 * vd]);
    }
    if (first == 0) {
      // Warm-up on the first block: the seeds and first allocations, untimed.
      Run warm[3];
      timeBlock(*backend, audit, count, driverValues, poses, points, offset, poseArray, pointArray,
                hits, answered, warm);
    }
    timeBlock(*backend, audit, count, driverValues, poses, points, offset, poseArray, pointArray,
              hits, answered, runs);
  }
  const double total = static_cast<double>(frames.size()) * vd;
  const char* names[3] = {"full search", "certificate", "told in advance (floor)"};
  const char* keys[3] = {"full_search", "certificate", "floor"};
  nlohmann::json json = {{"frames", frames.size()}, {"block", block}, {"offset", offset}};
  for (int r = 0; r < 3; ++r) {
    std::printf(
        "resolution search, %-24s %8.3f s  %7.1f frames/s  %5.1f%% of the points searched\n",
        names[r], runs[r].seconds, static_cast<double>(frames.size()) / runs[r].seconds,
        100.0 * static_cast<double>(runs[r].searched) / total);
    json[keys[r]] = {{"seconds", runs[r].seconds},
                     {"searched_fraction", static_cast<double>(runs[r].searched) / total}};
  }
  return json;
}

}  // namespace drivenshape::bench
