// SPDX-License-Identifier: Apache-2.0
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <drivenshape/bake_options.h>
#include <drivenshape/database.h>
#include <drivenshape/device.h>
#include <drivenshape/evaluator.h>
#include <drivenshape/layers.h>
#include <drivenshape/point_cache.h>
#include <drivenshape/shot_plan.h>

namespace drivenshape {

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
  int baked = 0;    ///< frames this run wrote
  int skipped = 0;  ///< frames a resume kept (their records read back from their files)
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
/// one point-cache EXR per frame (atomically), each carrying its frame's record (the report's
/// frames[] entry, EXR attribute dsRecord). The batches are planned over the shot
/// (options.shotFrames, or the frames); a resume (options.skipExisting) keeps complete
/// outputs with the records they carry and evaluates only the batches that have frames to
/// write, so a resumed or chunked bake writes the same frames and reports the same records as
/// one run. Validates everything it can before the first frame: vertex counts, frames
/// present, output folder writable. Throws drivenshape::Error.
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
/// verdict), or "null" when no record has a pose-model prediction. Records without a
/// prediction are not counted.
std::string coverageVerdictJson(const std::vector<FrameRecord>& records, double tolerance,
                                double level);

/// One bake report from the reports of parts of one shot (`texts`, named `sources` in
/// messages; farm chunks, or bakes of frame ranges): every frame's record once, in frame
/// order; the verdict over all of them, its simulation runs from the first frame; the
/// warnings of all; `run` and `seconds` summed. Reports of another database or other
/// settings, or two records of one frame that differ, are Error(kInput) naming the report. A
/// frame kept by a resume up to 0.2.0 (`"skipped": true`) gives way to a record of it.
std::string mergeBakeReports(const std::vector<std::string>& texts,
                             const std::vector<std::string>& sources);

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
