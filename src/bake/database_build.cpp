#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <limits>
#include <ostream>
#include <set>

#include <drivenshape/database.h>
#include <drivenshape/error.h>
#include <drivenshape/frames.h>
#include <drivenshape/version.h>

namespace drivenshape {
namespace {

std::string utcNow() {
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  char text[32];
  std::strftime(text, sizeof(text), "%Y-%m-%dT%H:%M:%SZ", &utc);
  return text;
}

/// RMS per-vertex distance between two interleaved shapes of `values` floats.
double rmsDistance(const float* a, const float* b, std::size_t values) {
  double sum = 0.0;
  for (std::size_t i = 0; i < values; ++i) {
    const double d = static_cast<double>(a[i]) - b[i];
    sum += d * d;
  }
  return std::sqrt(sum / static_cast<double>(values / 3));
}

void checkFrame(const PointCacheReader& cache, int frame, const char* role) {
  if (!cache.hasFrame(frame)) {
    const std::vector<int> frames = cache.frames();
    DS_THROW(kInput, role, " cache '", cache.path(), "' has no frame ", frame, " (it holds ",
             frames.empty() ? std::string("no frames") : formatFrameRange(frames),
             "); pass --frames within that range");
  }
}

}  // namespace

Database buildDatabase(const Mesh& driverMesh, const Mesh& drivenMesh,
                       const PointCacheReader& driverCache, const PointCacheReader& drivenCache,
                       const DatabaseBuildOptions& options, std::ostream* log) {
  if (options.count < 1) {
    DS_THROW(kUsage, "--count must be at least 1 (got ", options.count, ")");
  }
  if (driverCache.vertexCount() != driverMesh.vertexCount()) {
    DS_THROW(kInput, "driver cache '", driverCache.path(), "' has ", driverCache.vertexCount(),
             " vertices but the driver mesh has ", driverMesh.vertexCount(),
             "; pass the mesh the cache was written for");
  }
  if (drivenCache.vertexCount() != drivenMesh.vertexCount()) {
    DS_THROW(kInput, "driven cache '", drivenCache.path(), "' has ", drivenCache.vertexCount(),
             " vertices but the driven mesh has ", drivenMesh.vertexCount(),
             "; pass the mesh the cache was written for");
  }
  const std::set<int> removed(options.removeFrames.begin(), options.removeFrames.end());
  for (int frame : options.addFrames) {
    if (removed.count(frame) != 0) {
      DS_THROW(kUsage, "frame ", frame, " is in both --add-frames and --remove-frames");
    }
  }

  // Candidates: the given frames (or the whole driver cache) minus the removed ones, plus the
  // added ones (which must exist even if outside --frames).
  std::vector<int> candidates;
  {
    std::vector<int> pool = options.frames.empty() ? driverCache.frames() : options.frames;
    std::set<int> seen;
    for (int frame : options.addFrames) {
      if (seen.insert(frame).second) {
        candidates.push_back(frame);
      }
    }
    for (int frame : pool) {
      if (removed.count(frame) == 0 && seen.insert(frame).second) {
        candidates.push_back(frame);
      }
    }
  }
  if (candidates.empty()) {
    DS_THROW(kUsage, "no candidate frames left for the database (frames ",
             formatFrameRange(options.frames), " minus --remove-frames)");
  }
  for (int frame : candidates) {
    checkFrame(driverCache, frame, "driver");
    checkFrame(drivenCache, frame, "driven");
  }

  const std::size_t driverValues = static_cast<std::size_t>(driverMesh.vertexCount()) * 3;
  const std::vector<float> shapes = readFrames(driverCache, candidates);
  for (std::size_t c = 0; c < candidates.size(); ++c) {
    for (std::size_t i = 0; i < driverValues; ++i) {
      if (!std::isfinite(shapes[c * driverValues + i])) {
        DS_THROW(kInput, "driver cache '", driverCache.path(), "' frame ", candidates[c],
                 " vertex ", i / 3, " is not a finite number; fix the cache");
      }
    }
  }

  const Bounds bounds = computeBounds(driverMesh.positions.data(), driverMesh.vertexCount());
  const double tolerance = options.duplicateTolerance * bounds.diagonal();
  const std::size_t n = candidates.size();
  std::vector<double> minDistance(n, std::numeric_limits<double>::infinity());
  std::vector<bool> chosen(n, false);

  Database db;
  db.driverMesh = driverMesh;
  db.drivenMesh = drivenMesh;
  db.options = options;
  db.driverSource = driverCache.path();
  db.drivenSource = drivenCache.path();
  db.toolVersion = kVersion;
  db.created = utcNow();
  std::vector<std::size_t> picks;

  auto take = [&](std::size_t c, PickReason reason) {
    chosen[c] = true;
    picks.push_back(c);
    db.frames.push_back(candidates[c]);
    db.reasons.push_back(reason);
    db.pickDistances.push_back(picks.size() == 1 ? 0.0 : minDistance[c]);
    if (log != nullptr) {
      *log << "pick " << picks.size() << ": frame " << candidates[c] << " ("
           << pickReasonName(reason) << ", RMS distance to the others " << db.pickDistances.back()
           << ")\n";
    }
    for (std::size_t other = 0; other < n; ++other) {
      if (!chosen[other]) {
        minDistance[other] = std::min(
            minDistance[other],
            rmsDistance(&shapes[other * driverValues], &shapes[c * driverValues], driverValues));
      }
    }
  };

  // Seeds: the artist's frames (in the order given), else the settled rest pose: the candidate
  // whose driver is closest to the rest driver, and among those within the duplicate tolerance
  // of it the latest. Reference clips usually open with a hold at rest while the simulation
  // drapes the cloth, so the first frame's cloth is undraped; the end of the hold is not.
  const std::size_t addedCount = [&] {
    std::set<int> unique(options.addFrames.begin(), options.addFrames.end());
    return unique.size();
  }();
  if (addedCount == 0) {
    std::vector<double> toRest(n);
    for (std::size_t c = 0; c < n; ++c) {
      toRest[c] = rmsDistance(&shapes[c * driverValues], driverMesh.positions.data(), driverValues);
    }
    const double nearest = *std::min_element(toRest.begin(), toRest.end());
    std::size_t seed = n;
    for (std::size_t c = 0; c < n; ++c) {
      if (toRest[c] <= nearest + tolerance && (seed == n || candidates[c] > candidates[seed])) {
        seed = c;
      }
    }
    take(seed, PickReason::kSeed);
  }
  for (std::size_t c = 0; c < addedCount; ++c) {
    if (!picks.empty() && minDistance[c] < tolerance) {
      if (log != nullptr) {
        *log << "skip added frame " << candidates[c] << ": a near-duplicate of a chosen shape "
             << "(RMS distance " << minDistance[c] << " < tolerance " << tolerance << ")\n";
      }
      chosen[c] = true;  // never reconsider it
      continue;
    }
    take(c, PickReason::kAdded);
  }
  while (static_cast<int>(picks.size()) < options.count) {
    std::size_t best = n;
    for (std::size_t c = 0; c < n; ++c) {
      if (!chosen[c] && (best == n || minDistance[c] > minDistance[best])) {
        best = c;
      }
    }
    if (best == n || minDistance[best] < tolerance) {
      if (log != nullptr) {
        *log << "stopping at " << picks.size() << " shapes: every remaining frame is within "
             << tolerance << " (RMS) of a chosen shape\n";
      }
      break;
    }
    take(best, PickReason::kFarthest);
  }

  const int k = static_cast<int>(picks.size());
  db.driverShapes.resize(static_cast<std::size_t>(k) * driverValues);
  for (int i = 0; i < k; ++i) {
    std::copy_n(&shapes[picks[i] * driverValues], driverValues, &db.driverShapes[i * driverValues]);
  }
  db.drivenShapes = readFrames(drivenCache, db.frames);
  for (std::size_t i = 0; i < db.drivenShapes.size(); ++i) {
    if (!std::isfinite(db.drivenShapes[i])) {
      const std::size_t values = static_cast<std::size_t>(drivenMesh.vertexCount()) * 3;
      DS_THROW(kInput, "driven cache '", drivenCache.path(), "' frame ", db.frames[i / values],
               " vertex ", (i % values) / 3, " is not a finite number; fix the cache");
    }
  }
  return db;
}

}  // namespace drivenshape
