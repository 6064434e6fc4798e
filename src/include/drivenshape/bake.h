// SPDX-License-Identifier: Apache-2.0
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <drivenshape/database.h>
#include <drivenshape/device.h>
#include <drivenshape/evaluator.h>
#include <drivenshape/layers.h>
#include <drivenshape/point_cache.h>
#include <drivenshape/shot_plan.h>

namespace drivenshape {

struct BakeOptions {
  std::vector<int> frames;    ///< frames of the driver cache to bake
  std::string outputPattern;  ///< EXR sequence with a frame token, e.g. out/cloth.####.exr
  std::string reportPath;     ///< per-bake JSON report; empty = none
  /// Frames per kernel launch (`--batch`); lowered for large meshes so that a batch's buffers
  /// stay within kBatchMemoryBudget, except with the temporal bound (which depends on it).
  /// The batches are planShot's (drivenshape/shot_plan.h).
  int chunkSize = kDefaultBatchFrames;
  int threads = 0;            ///< host threads (QP, EXR); 0 = all cores
  bool skipExisting = false;  ///< keep complete outputs of this database and settings
  int exrWidth = 1024;
  ExrCompression compression = ExrCompression::kZip;
  ZipEncoder zipEncoder = ZipEncoder::kLibdeflate;  ///< of the caches and the position maps
  double framesPerSecond = 24.0;
  /// Every evaluator setting but the three that come from files here (see
  /// drivenshape/evaluator.h; `threads` is set from the bake's own): weights, alignment, blend,
  /// correction, resolution, temporal bound, audit. The defaults are the command line's.
  EvaluatorSettings evaluator;
  /// Binding mask file (see readBindingMask); empty = evaluator.bindingMask (every triangle
  /// when that is empty too).
  std::string bindingMaskPath;
  /// Region file (see readRegions); empty = evaluator.regions (one QP on every driver row when
  /// that is empty too).
  std::string regionsPath;
  /// With the temporal bound (evaluator.maxWeightChange > 0) frames are solved in order within
  /// each launch batch (`chunkSize` frames); before each batch, `temporalWarmup` driver-cache
  /// frames preceding its first frame are solved (the first of them without the bound) but not
  /// written. The output therefore depends on chunkSize and temporalWarmup, never on the thread
  /// count, and a farm chunk whose size is a multiple of chunkSize reproduces the single bake
  /// exactly.
  int temporalWarmup = kDefaultTemporalWarmup;
  /// Layers after the correction and resolution (DESIGN.md section 3 step 7): a mix with
  /// another cache of the cloth, procedural wind, from files. Off by default. Recorded in the
  /// settings hash, the report and the EXR header (`dsLayers`).
  LayerOptions layers;
  /// fsync every output EXR before its atomic rename (`--sync`). Off by default: the rename
  /// alone already means readers never see a partial file, and a file cut short by a power
  /// loss is rebaked by --skip-existing; the fsync costs a disk (or NFS) round trip per frame.
  bool syncOutputs = false;
  /// Bake a driver that checkDriver (drivenshape/driver_check.h) refuses: another scale than
  /// the database's, or edges that do not correspond (`--force`). Its findings become warnings.
  bool force = false;
  /// Why the database's driver mesh is baked untrusted: the warning of checkDriverMesh
  /// (drivenshape/mesh_check.h) for a driver that is not a closed, consistently oriented
  /// surface, set by admitDriverMesh with `--untrusted-driver`; empty for a driver that passes.
  /// The bake lists it among its warnings and the report's settings say `untrusted_driver`.
  std::string untrustedDriver;
};

/// Seconds spent per stage, summed over batches. Reading and writing run on I/O tasks beside
/// the other stages (the bake is pipelined), so the stages can add up to more than `total`;
/// readWait and writeWait are the time the bake thread waited for them.
struct StageTimes {
  StageSeconds stages;  ///< the evaluator's stages by name (align, project, weights, ...)
  double read = 0, write = 0, total = 0;
  double readWait = 0, writeWait = 0;
  double setup = 0;  ///< before the first batch: checks, alignment weights, tables, uploads
  /// Seconds of stage `name` (0 when it did not run).
  double stage(const std::string& name) const {
    const auto found = stages.find(name);
    return found == stages.end() ? 0.0 : found->second;
  }
};

struct BakeResult {
  std::vector<FrameRecord> frames;
  StageTimes times;
  std::string device;
  std::uint64_t settingsHash = 0;
  int baked = 0;
  int skipped = 0;
  int staleTempFilesRemoved = 0;      ///< by a resume (options.skipExisting), of its own frames
  std::vector<std::string> warnings;  ///< checkDriver's findings and fit warnings
};

/// Receives progress from a bake (called on the bake's thread).
struct BakeObserver {
  virtual ~BakeObserver() = default;
  virtual void frameDone(const FrameRecord& /*record*/, double /*seconds*/) {}
  /// A warning about the bake's inputs (also kept in BakeResult::warnings and the report).
  virtual void warning(const std::string& /*message*/) {}
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
BakeResult bake(const Database& database, const PointCacheReader& driver, Device& device,
                const BakeOptions& options, BakeObserver* observer = nullptr);

/// The bake report's JSON text (docs/schemas/bake_report.schema.json, what `--report` writes)
/// of a bake of `driverPath` with `options` and `evaluator` that gave `result`: its settings,
/// every frame's record and the shot's coverage verdict. For tools that evaluate a shot
/// themselves (the USD bake) and report it as the command line does.
std::string bakeReportJson(const Database& database, const std::string& driverPath,
                           const BakeOptions& options, const Evaluator& evaluator,
                           const BakeResult& result);

/// The shot's coverage verdict over `records` (the report's `coverage` object as JSON text:
/// tolerance, level, frames_checked, covered_fraction, simulate_frames, simulate_runs, run_up,
/// verdict), or "null" when no record has a pose-model prediction. Skipped records are not
/// counted.
std::string coverageVerdictJson(const std::vector<FrameRecord>& records, double tolerance,
                                double level);

/// Checks the database's driver mesh before a bake (checkDriverMesh; `source` names the
/// database in messages). A mesh that passes changes nothing and returns "". One that does not
/// throws Error(kInput), unless `allowUntrusted` (`--untrusted-driver`) and it has a face to
/// bind to: then the bake runs without the inside audit and the penetration resolution, which
/// assume a closed surface (options.evaluator.audit and .resolve are switched off), and
/// options.untrustedDriver receives the warning, which is also returned.
std::string admitDriverMesh(const Database& database, const std::string& source,
                            bool allowUntrusted, BakeOptions& options);

/// The evaluator settings of a bake: the options' values, with the binding mask, the regions
/// and the layers loaded from the files they name (Error(kInput) naming the file).
EvaluatorSettings evaluatorSettings(const Database& database, const BakeOptions& options);

}  // namespace drivenshape
