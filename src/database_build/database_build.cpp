// SPDX-License-Identifier: Apache-2.0
#include <drivenshape/database_build.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <ctime>
#include <limits>
#include <memory>
#include <ostream>
#include <set>

#include <drivenshape/device.h>
#include <drivenshape/error.h>
#include <drivenshape/evaluator.h>
#include <drivenshape/frames.h>
#include <drivenshape/point_cache.h>
#include <drivenshape/version.h>

#include "closest.h"
#include "reference_frames.h"

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
             "); choose candidate frames within that range");
  }
}

/// Throws unless at least one shape is wanted, each mesh matches its cache and no frame is
/// both added and removed.
void checkBuildInputs(const Mesh& driverMesh, const Mesh& drivenMesh,
                      const PointCacheReader& driverCache, const PointCacheReader& drivenCache,
                      const DatabaseBuildOptions& options) {
  if (options.count < 1) {
    DS_THROW(kUsage, "the shape count must be at least 1 (got ", options.count, ")");
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
      DS_THROW(kUsage, "frame ", frame, " is both an added and a removed frame");
    }
  }
}

/// The candidate frames: the added ones (in the order given, without repeats), then the given
/// frames (or the whole driver cache) minus the removed ones. The added ones must exist even if
/// outside --frames; throws unless both caches hold every candidate.
std::vector<int> candidateFrames(const PointCacheReader& driverCache,
                                 const PointCacheReader& drivenCache,
                                 const DatabaseBuildOptions& options) {
  const std::set<int> removed(options.removeFrames.begin(), options.removeFrames.end());
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
             formatFrameRange(options.frames), " minus the removed frames)");
  }
  for (int frame : candidates) {
    checkFrame(driverCache, frame, "driver");
    checkFrame(drivenCache, frame, "driven");
  }
  return candidates;
}

/// The candidates' driver shapes, C x 3Vp (`driverValues` = 3Vp); throws on a non-finite value.
std::vector<float> readCandidateShapes(const PointCacheReader& driverCache,
                                       const std::vector<int>& candidates,
                                       std::size_t driverValues) {
  std::vector<float> shapes = readFrames(driverCache, candidates);
  for (std::size_t c = 0; c < candidates.size(); ++c) {
    for (std::size_t i = 0; i < driverValues; ++i) {
      if (!(std::fabs(shapes[c * driverValues + i]) <= kMaxCoordinate)) {
        DS_THROW(kInput, "driver cache '", driverCache.path(), "' frame ", candidates[c],
                 " vertex ", i / 3, " is not a finite number within +/-", kMaxCoordinate,
                 " scene units; fix the cache or its units");
      }
    }
  }
  return shapes;
}

/// The greedy farthest-point pick over the candidates' driver shapes: every pick is recorded
/// in the database (frame, reason, distance) and lowers the others' distance to the chosen set.
class ShapePicker {
 public:
  /// `shapes` C x 3Vp (`driverValues` = 3Vp) of `candidates`; `log` may be null.
  ShapePicker(const std::vector<int>& candidates, const std::vector<float>& shapes,
              std::size_t driverValues, Database& db, std::ostream* log)
      : mCandidates(candidates),
        mShapes(shapes),
        mDriverValues(driverValues),
        mDb(db),
        mLog(log),
        mMinDistance(candidates.size(), std::numeric_limits<double>::infinity()),
        mChosen(candidates.size(), false) {}

  /// Candidate indices in the order picked.
  const std::vector<std::size_t>& picks() const { return mPicks; }

  /// Seeds with the settled rest pose: the candidate whose driver is closest to the rest
  /// driver (`rest`, 3Vp), and among those within `tolerance` of it the latest.
  void pickRestSeed(const float* rest, double tolerance) {
    const std::size_t n = mCandidates.size();
    std::vector<double> toRest(n);
    for (std::size_t c = 0; c < n; ++c) {
      toRest[c] = rmsDistance(&mShapes[c * mDriverValues], rest, mDriverValues);
    }
    const double nearest = *std::min_element(toRest.begin(), toRest.end());
    std::size_t seed = n;
    for (std::size_t c = 0; c < n; ++c) {
      if (toRest[c] <= nearest + tolerance && (seed == n || mCandidates[c] > mCandidates[seed])) {
        seed = c;
      }
    }
    take(seed, PickReason::kSeed);
  }

  /// Picks the first `addedCount` candidates (the artist's frames) in order, skipping those
  /// within `tolerance` of a chosen shape.
  void pickAdded(std::size_t addedCount, double tolerance) {
    for (std::size_t c = 0; c < addedCount; ++c) {
      if (!mPicks.empty() && mMinDistance[c] < tolerance) {
        if (mLog != nullptr) {
          *mLog << "skip added frame " << mCandidates[c] << ": a near-duplicate of a chosen shape "
                << "(RMS distance " << mMinDistance[c] << " < tolerance " << tolerance << ")\n";
        }
        mChosen[c] = true;  // never reconsider it
        continue;
      }
      take(c, PickReason::kAdded);
    }
  }

  /// Picks the candidate farthest from the chosen shapes until there are `count` of them or
  /// every remaining one is within `tolerance` of a chosen shape.
  void pickFarthest(int count, double tolerance) {
    const std::size_t n = mCandidates.size();
    while (static_cast<int>(mPicks.size()) < count) {
      std::size_t best = n;
      for (std::size_t c = 0; c < n; ++c) {
        if (!mChosen[c] && (best == n || mMinDistance[c] > mMinDistance[best])) {
          best = c;
        }
      }
      if (best == n || mMinDistance[best] < tolerance) {
        if (mLog != nullptr) {
          *mLog << "stopping at " << mPicks.size() << " shapes: every remaining frame is within "
                << tolerance << " (RMS) of a chosen shape\n";
        }
        break;
      }
      take(best, PickReason::kFarthest);
    }
  }

 private:
  /// Chooses candidate c, records it and lowers the others' distance to the chosen set.
  void take(std::size_t c, PickReason reason) {
    mChosen[c] = true;
    mPicks.push_back(c);
    mDb.frames.push_back(mCandidates[c]);
    mDb.reasons.push_back(reason);
    mDb.pickDistances.push_back(mPicks.size() == 1 ? 0.0 : mMinDistance[c]);
    if (mLog != nullptr) {
      *mLog << "pick " << mPicks.size() << ": frame " << mCandidates[c] << " ("
            << pickReasonName(reason) << ", RMS distance to the others " << mDb.pickDistances.back()
            << ")\n";
    }
    for (std::size_t other = 0; other < mCandidates.size(); ++other) {
      if (!mChosen[other]) {
        mMinDistance[other] =
            std::min(mMinDistance[other], rmsDistance(&mShapes[other * mDriverValues],
                                                      &mShapes[c * mDriverValues], mDriverValues));
      }
    }
  }

  const std::vector<int>& mCandidates;
  const std::vector<float>& mShapes;
  std::size_t mDriverValues;
  Database& mDb;
  std::ostream* mLog;
  std::vector<double> mMinDistance;  // per candidate: RMS distance to the nearest chosen shape
  std::vector<bool> mChosen;
  std::vector<std::size_t> mPicks;
};

/// Fills the database's shapes: the picked candidates' driver shapes and their frames of the
/// driven cache; throws on a non-finite driven value.
void fillPickedShapes(Database& db, const std::vector<float>& shapes,
                      const std::vector<std::size_t>& picks, std::size_t driverValues,
                      const PointCacheReader& drivenCache, const Mesh& drivenMesh) {
  const int k = static_cast<int>(picks.size());
  db.driverShapes.resize(static_cast<std::size_t>(k) * driverValues);
  for (int i = 0; i < k; ++i) {
    std::copy_n(&shapes[picks[i] * driverValues], driverValues, &db.driverShapes[i * driverValues]);
  }
  db.drivenShapes = readFrames(drivenCache, db.frames);
  for (std::size_t i = 0; i < db.drivenShapes.size(); ++i) {
    if (!(std::fabs(db.drivenShapes[i]) <= kMaxCoordinate)) {
      const std::size_t values = static_cast<std::size_t>(drivenMesh.vertexCount()) * 3;
      DS_THROW(kInput, "driven cache '", drivenCache.path(), "' frame ", db.frames[i / values],
               " vertex ", (i % values) / 3, " is not a finite number within +/-", kMaxCoordinate,
               " scene units; fix the cache or its units");
    }
  }
}

/// Frames the pose model's velocity and history read before a frame (PoseModel::historyNeeded);
/// `options` has its history chosen (historyFramesFor).
int historyNeeded(const PoseModelOptions& options) {
  PoseModel model;
  model.velocityLag = options.velocityLag;
  model.historyFrames = options.historyFrames;
  return model.historyNeeded();
}

/// Throws unless every extra clip has both caches, matches the rest meshes and comes with the
/// pose model.
/// Refuses a clip in other units than the rest meshes: on its first, middle and last frames,
/// each cache's median edge length against its rest mesh's (medianEdgeScale) must be within a
/// factor of 2 (the reference clips stay within 1.05; cloth a few percent).
void checkClipUnits(const PointCacheReader& cache, const Mesh& mesh, const char* kind,
                    const std::string& what) {
  const std::vector<int> frames = cache.frames();
  if (frames.empty() || cache.vertexCount() != mesh.vertexCount()) {
    return;  // the other checks name these
  }
  std::vector<float> xyz(static_cast<std::size_t>(cache.vertexCount()) * 3);
  for (const int frame : {frames.front(), frames[frames.size() / 2], frames.back()}) {
    cache.readFrame(frame, xyz.data());
    const double scale = medianEdgeScale(mesh, xyz.data());
    if (scale > 0.0 && !(scale >= 0.5 && scale <= 2.0)) {
      DS_THROW(kInput, kind, " cache '", cache.path(), "' (", what, ") frame ", frame, " is ",
               scale, " times the size of the rest ", kind,
               " mesh (median edge length): another unit (100: centimetres against metres)? "
               "Give every clip in the rest meshes' units");
    }
  }
}

void checkExtraClips(const Mesh& driverMesh, const Mesh& drivenMesh,
                     const std::vector<ReferenceClip>& extraClips,
                     const DatabaseBuildOptions& options) {
  if (!extraClips.empty() && !options.poseModel) {
    DS_THROW(kUsage,
             "extra reference clips feed the pose model only; build with the pose model "
             "(--model pose) or without the extra clips");
  }
  for (std::size_t c = 0; c < extraClips.size(); ++c) {
    const std::string what = "reference clip " + std::to_string(c + 2);
    if (extraClips[c].driver == nullptr || extraClips[c].driven == nullptr) {
      DS_THROW(kUsage, what, " needs a driver and a driven cache");
    }
    checkClipVertexCount(*extraClips[c].driver, driverMesh, "driver", what);
    checkClipVertexCount(*extraClips[c].driven, drivenMesh, "driven", what);
    checkClipUnits(*extraClips[c].driver, driverMesh, "driver", what);
    checkClipUnits(*extraClips[c].driven, drivenMesh, "driven", what);
  }
}

/// The frames of every clip the pose model is fitted on, clip after clip (the main clip's
/// candidates first), numbered apart (referenceClipOffsets), with the earlier frames velocity
/// and history read from each clip's own driver cache.
struct FitFrames {
  std::vector<int> frames;  ///< model frame numbers
  std::vector<float> driver, driven;
  std::vector<int> earlier;  ///< model frame numbers
  std::vector<float> earlierDriver;
  std::vector<int> clipStart = {0};  ///< index of each clip's first frame, then the total
  std::size_t mainEarlier = 0;       ///< the main clip's earlier frames come first
};

FitFrames gatherFitFrames(Database& db, const std::vector<int>& candidates,
                          const std::vector<float>& shapes, const PointCacheReader& driverCache,
                          const PointCacheReader& drivenCache,
                          const std::vector<ReferenceClip>& extraClips, int need,
                          std::ostream* log) {
  struct Clip {
    const PointCacheReader* driver;
    const PointCacheReader* driven;
    std::vector<int> frames, earlier;
  };
  std::vector<Clip> clips = {{&driverCache, &drivenCache, candidates, {}}};
  for (std::size_t c = 0; c < extraClips.size(); ++c) {
    const ReferenceClip& clip = extraClips[c];
    const std::string what = "reference clip " + std::to_string(c + 2);
    std::vector<int> frames = clipFrames(*clip.driver, clip.frames, what);
    checkFramesHeld(*clip.driven, frames, what, "driven ",
                    "give the driven cache of the same frames");
    clips.push_back({clip.driver, clip.driven, std::move(frames), {}});
  }
  std::vector<std::array<int, 2>> ranges;
  for (Clip& clip : clips) {
    clip.earlier = earlierFrames(*clip.driver, clip.frames, need);
    const auto [low, high] = std::minmax_element(clip.frames.begin(), clip.frames.end());
    ranges.push_back({clip.earlier.empty() ? *low : std::min(*low, clip.earlier.front()), *high});
  }
  const std::vector<int> offsets = referenceClipOffsets(ranges, need);

  FitFrames fit;
  for (std::size_t c = 0; c < clips.size(); ++c) {
    const Clip& clip = clips[c];
    if (c == 0) {
      fit.driver.insert(fit.driver.end(), shapes.begin(), shapes.end());  // read already
    } else {
      const std::vector<float> driver = readFiniteFrames(*clip.driver, clip.frames, "driver");
      fit.driver.insert(fit.driver.end(), driver.begin(), driver.end());
    }
    const std::vector<float> driven = readFiniteFrames(*clip.driven, clip.frames, "driven");
    const std::vector<float> earlier = readFiniteFrames(*clip.driver, clip.earlier, "driver");
    fit.driven.insert(fit.driven.end(), driven.begin(), driven.end());
    fit.earlierDriver.insert(fit.earlierDriver.end(), earlier.begin(), earlier.end());
    for (int frame : clip.frames) {
      fit.frames.push_back(frame + offsets[c]);
    }
    for (int frame : clip.earlier) {
      fit.earlier.push_back(frame + offsets[c]);
    }
    fit.clipStart.push_back(static_cast<int>(fit.frames.size()));
    if (c == 0) {
      fit.mainEarlier = clip.earlier.size();
      continue;
    }
    db.extraClips.push_back({clip.driver->path(), clip.driven->path(), clip.frames, offsets[c]});
    if (log != nullptr) {
      *log << "reference clip " << c + 1 << ": '" << clip.driver->path() << "' and '"
           << clip.driven->path() << "', frames " << formatFrameRange(clip.frames)
           << " (pose model frames " << clip.frames.front() + offsets[c] << "-"
           << clip.frames.back() + offsets[c] << "), " << clip.earlier.size()
           << " earlier frames read for velocity and history\n";
    }
  }
  return fit;
}

/// The build log's table of what each reference clip added (PoseModel::clipErrors).
void logClipContributions(const PoseModel& model, double mainAlone, std::ostream& log) {
  log << "  pose model over " << model.clipErrors.size() << " clips: cross-validated mean error "
      << model.crossValidationError
      << "; fitted on the main clip alone (its own kernel settings): ";
  if (mainAlone >= 0.0) {
    log << mainAlone << "\n";
  } else {
    log << "too few frames\n";
  }
  log << "  what each clip adds: cross-validated mean error on each clip with every clip -> with "
         "that clip left out (on its own row: its frames predicted by the others)\n";
  for (std::size_t c = 0; c < model.clipErrors.size(); ++c) {
    const ClipContribution& row = model.clipErrors[c];
    log << "    without clip " << c + 1 << " (" << row.frames << " frames):";
    for (std::size_t k = 0; k < row.without.size(); ++k) {
      log << "  clip " << k + 1 << " " << row.withAll[k] << " -> " << row.without[k];
    }
    log << "\n";
  }
}

/// Fits the pose model over every candidate frame (the whole reference clip by default) and
/// every frame of the extra clips; with extra clips the log compares the fit on the main clip
/// alone.
void fitModel(Database& db, const std::vector<int>& candidates, const std::vector<float>& shapes,
              const PointCacheReader& driverCache, const PointCacheReader& drivenCache,
              const std::vector<ReferenceClip>& extraClips, const PoseModelOptions& chosen,
              std::ostream* log) {
  // Every fit of this build, the main clip alone included, uses the history chosen for all its
  // clips, so that the log compares like with like.
  PoseModelOptions options = chosen;
  options.historyFrames = historyFramesFor(chosen, static_cast<int>(extraClips.size()) + 1);
  const int need = historyNeeded(options);
  const FitFrames fit =
      gatherFitFrames(db, candidates, shapes, driverCache, drivenCache, extraClips, need, log);
  const int total = static_cast<int>(fit.frames.size());
  if (total < 10) {
    // Too short a clip to fit anything: the database keeps its picks (the QP runs on it).
    db.extraClips.clear();
    if (log != nullptr) {
      *log << "no pose model: " << total
           << " reference frames are too few to fit one (it needs 10)\n";
    }
    return;
  }
  ClosestOptions closestOptions;
  closestOptions.threads = options.threads;
  const std::unique_ptr<ClosestBackend> closest = makeHostClosest(closestOptions);
  closest->setSurface(db.driverMesh, BindingMask::all(db.drivenVertexCount()));
  std::vector<SurfaceHit> restHits(static_cast<std::size_t>(db.drivenVertexCount()));
  closest->closest(1, db.driverMesh.positions.data(), db.drivenMesh.positions.data(),
                   restHits.data());
  const int mainCount = static_cast<int>(candidates.size());
  const auto earlierOf = [&](std::size_t count) {
    EarlierFrames earlier;
    earlier.driverFrames = fit.earlierDriver.data();
    earlier.frames.assign(fit.earlier.begin(), fit.earlier.begin() + count);
    return earlier;
  };
  // The main clip alone, for comparison: its frames and earlier frames come first.
  double mainAlone = -1.0;
  if (!extraClips.empty() && mainCount >= 10) {
    mainAlone = fitPoseModel(db.driverMesh, db.drivenMesh, fit.driver.data(), fit.driven.data(),
                             candidates, restHits, options, nullptr, earlierOf(fit.mainEarlier))
                    .crossValidationError;
  }
  if (log != nullptr) {
    *log << "fitting the pose model on " << total << " reference frames";
    if (!extraClips.empty()) {
      *log << " of " << extraClips.size() + 1 << " clips";
    }
    *log << "\n";
  }
  PoseModelOptions allClips = options;
  for (std::size_t c = 0; c + 1 < fit.clipStart.size(); ++c) {
    allClips.clipSizes.push_back(fit.clipStart[c + 1] - fit.clipStart[c]);
  }
  db.poseModel = fitPoseModel(db.driverMesh, db.drivenMesh, fit.driver.data(), fit.driven.data(),
                              fit.frames, restHits, allClips, log, earlierOf(fit.earlier.size()));
  if (log != nullptr && !extraClips.empty()) {
    logClipContributions(db.poseModel, mainAlone, *log);
  }
}

}  // namespace

Database buildDatabase(const Mesh& driverMesh, const Mesh& drivenMesh,
                       const PointCacheReader& driverCache, const PointCacheReader& drivenCache,
                       const DatabaseBuildOptions& options, std::ostream* log) {
  return buildDatabase(driverMesh, drivenMesh, driverCache, drivenCache, {}, options, log);
}

Database buildDatabase(const Mesh& driverMesh, const Mesh& drivenMesh,
                       const PointCacheReader& driverCache, const PointCacheReader& drivenCache,
                       const std::vector<ReferenceClip>& extraClips,
                       const DatabaseBuildOptions& options, std::ostream* log) {
  checkBuildInputs(driverMesh, drivenMesh, driverCache, drivenCache, options);
  checkExtraClips(driverMesh, drivenMesh, extraClips, options);
  checkClipUnits(driverCache, driverMesh, "driver", "the main reference clip");
  checkClipUnits(drivenCache, drivenMesh, "driven", "the main reference clip");
  const std::vector<int> candidates = candidateFrames(driverCache, drivenCache, options);
  const std::size_t driverValues = static_cast<std::size_t>(driverMesh.vertexCount()) * 3;
  const std::vector<float> shapes = readCandidateShapes(driverCache, candidates, driverValues);

  const Bounds bounds = computeBounds(driverMesh.positions.data(), driverMesh.vertexCount());
  const double tolerance = options.duplicateTolerance * bounds.diagonal();

  Database db;
  db.driverMesh = driverMesh;
  db.drivenMesh = drivenMesh;
  db.options = options;
  db.driverSource = driverCache.path();
  db.drivenSource = drivenCache.path();
  db.toolVersion = kVersion;
  db.created = utcNow();
  ShapePicker picker(candidates, shapes, driverValues, db, log);

  // Seeds: the artist's frames (in the order given), else the settled rest pose: the candidate
  // whose driver is closest to the rest driver, and among those within the duplicate tolerance
  // of it the latest. Reference clips usually open with a hold at rest while the simulation
  // drapes the cloth, so the first frame's cloth is undraped; the end of the hold is not.
  const std::size_t addedCount = [&] {
    std::set<int> unique(options.addFrames.begin(), options.addFrames.end());
    return unique.size();
  }();
  if (addedCount == 0) {
    picker.pickRestSeed(driverMesh.positions.data(), tolerance);
  }
  picker.pickAdded(addedCount, tolerance);
  picker.pickFarthest(options.count, tolerance);

  fillPickedShapes(db, shapes, picker.picks(), driverValues, drivenCache, drivenMesh);
  if (options.poseModel) {
    fitModel(db, candidates, shapes, driverCache, drivenCache, extraClips, options.model, log);
  }
  // The side of the skin every driven vertex lives on, once here rather than at every bake's
  // start (on the host reference path: exact, and the same on every machine).
  db.drivenSides = learnDrivenSides(db, *openDevice("host"), options.model.threads);
  if (log != nullptr) {
    const auto inside = std::count(db.drivenSides.begin(), db.drivenSides.end(), kSideInside);
    *log << "sides: " << inside << " of " << db.drivenVertexCount()
         << " driven vertices live inside the driver\n";
  }
  return db;
}

}  // namespace drivenshape
