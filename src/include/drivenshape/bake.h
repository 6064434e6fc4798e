#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <drivenshape/correction.h>
#include <drivenshape/database.h>
#include <drivenshape/point_cache.h>
#include <drivenshape/stages.h>

namespace drivenshape {

/// How the per-frame weights are chosen.
enum class WeightMode {
  kQp,       ///< the DrivenShape QP: min ||A w - b|| with sum w = 1, 0 <= w <= 1
  kNearest,  ///< baseline: one-hot on the closest database driver shape
  kBind      ///< baseline: no database; the rest cloth bound to the rest driver and carried to
             ///< every frame by the correction (what Houdini's Point Deform does)
};

struct BakeOptions {
  std::vector<int> frames;    ///< frames of the driver cache to bake
  std::string outputPattern;  ///< EXR sequence with a frame token, e.g. out/cloth.####.exr
  std::string reportPath;     ///< per-bake JSON report; empty = none
  int chunkSize = 64;         ///< frames per kernel launch (`--batch`)
  int threads = 0;            ///< host threads (QP, EXR); 0 = all cores
  bool skipExisting = false;  ///< keep complete outputs of this database and settings
  WeightMode weightMode = WeightMode::kQp;
  int exrWidth = 1024;
  ExrCompression compression = ExrCompression::kZip;
  double framesPerSecond = 24.0;
  /// Collision correction: bind every blended cloth vertex to its exact closest triangle of
  /// the blended driver P~ and carry it to the shot's driver P_new in that triangle's frame.
  bool correct = true;
  /// Binding mask file (see readBindingMask); empty = every vertex may bind anywhere.
  std::string bindingMaskPath;
  /// Per-frame audit: cloth vertices inside the shot's driver before and after correction,
  /// binding switches, the largest frame-to-frame jump.
  bool audit = true;
};

/// The backends a bake runs on, all on one device (or all host): the per-frame stages, the
/// closest-triangle search used for binding (the mask is applied to it), and a second one for
/// the inside/outside audit (always against every triangle). The last two may be null when
/// options.correct and options.audit are off.
struct BakeBackends {
  StageBackend* stages = nullptr;
  ClosestBackend* binding = nullptr;
  ClosestBackend* audit = nullptr;
};

/// What happened to one frame.
struct FrameRecord {
  int frame = 0;
  bool skipped = false;         ///< an existing complete output was kept
  std::vector<double> weights;  ///< k
  std::vector<int> atZero;      ///< shapes held at weight 0 (active bounds)
  std::vector<int> atOne;
  double relativeResidual = 0.0;  ///< ||A w - b|| / ||b||
  double kktResidual = 0.0;
  int iterations = 0;
  std::string output;
  // Audit (-1 where not measured).
  int insideBefore = -1;     ///< blended cloth vertices inside the shot's driver
  int insideAfter = -1;      ///< the same after correction (= before without correction)
  int bindingSwitches = -1;  ///< vertices bound to another triangle than the previous frame
  double maxJump = -1.0;     ///< largest vertex move since the previous baked frame
  int maxJumpVertex = -1;
};

/// Seconds spent per stage, summed over chunks.
struct StageTimes {
  double read = 0, project = 0, weights = 0, blend = 0, correct = 0, audit = 0, write = 0,
         total = 0;
};

struct BakeResult {
  std::vector<FrameRecord> frames;
  StageTimes times;
  std::string device;
  std::uint64_t settingsHash = 0;
  int baked = 0;
  int skipped = 0;
};

/// Receives progress from a bake (called on the bake's thread).
struct BakeObserver {
  virtual ~BakeObserver() = default;
  virtual void frameDone(const FrameRecord& /*record*/, double /*seconds*/) {}
  /// Polled between chunks; return true to stop (finished frames are kept).
  virtual bool stopRequested() { return false; }
  /// Called after each launch batch is written, with the baked positions of its frames
  /// (records.size() x 3Vd, frame-major), e.g. to write position maps without re-reading.
  virtual void batchBaked(const std::vector<const FrameRecord*>& /*records*/,
                          const float* /*positions*/) {}
};

/// Bakes `options.frames` of `driver` with `database` on `stages` (host or OpenCL) and writes
/// one point-cache EXR per frame (atomically). Validates everything it can before the first
/// frame: vertex counts, frames present, output folder writable. Throws drivenshape::Error.
BakeResult bake(const Database& database, const PointCacheReader& driver,
                const BakeBackends& backends, const BakeOptions& options,
                BakeObserver* observer = nullptr);

/// Flat tables for the stage backends, built from a database (projection basis, shapes).
ShapeTables makeShapeTables(const Database& database);

}  // namespace drivenshape
