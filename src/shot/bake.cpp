// SPDX-License-Identifier: Apache-2.0
// The bake: the shot loop around one Evaluator. Frames are read a batch ahead on an I/O task,
// evaluated a batch at a time, and written on another I/O task while the next batch runs
// (double buffering); a resume keeps complete outputs; a stop request ends the bake between
// batches with every written frame complete.

#include <drivenshape/bake.h>

#include "driver_check.h"
#include "frame_record_json.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <functional>
#include <future>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <unordered_map>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include <drivenshape/binding.h>
#include <drivenshape/coverage_check.h>
#include <drivenshape/error.h>
#include <drivenshape/frames.h>
#include <drivenshape/mesh_check.h>
#include <drivenshape/regions.h>
#include <drivenshape/settings_table.h>
#include <drivenshape/shot_plan.h>
#include <drivenshape/version.h>

#include "atomic_file.h"
#include "hash.h"
#include "parallel.h"
#include "stopwatch.h"

#include "json_text.h"

namespace drivenshape {
namespace {

using Clock = std::chrono::steady_clock;

/// The checks of the shot itself (the evaluator checks its settings): frames, output, driver.
void validate(const Database& db, const PointCacheReader& driver, const BakeOptions& options) {
  if (options.frames.empty()) {
    DS_THROW(kUsage, "the frame range to bake is empty; give frames, e.g. 1001-1100");
  }
  // The evaluator settings are checked by the Evaluator, with the settings they leave unused.
  checkBakeSettings(options);
  if (!hasFramePattern(options.outputPattern)) {
    DS_THROW(kUsage, "output '", options.outputPattern,
             "' has no frame token; use e.g. out/cloth.####.exr");
  }
  if (driver.vertexCount() != db.driverVertexCount()) {
    DS_THROW(kInput, "driver cache '", driver.path(), "' has ", driver.vertexCount(),
             " vertices but the database's driver has ", db.driverVertexCount(),
             "; bake with a database built for this character");
  }
  for (int frame : options.frames) {
    if (!driver.hasFrame(frame)) {
      const std::vector<int> frames = driver.frames();
      DS_THROW(kInput, "driver cache '", driver.path(), "' has no frame ", frame, " (it holds ",
               frames.empty() ? std::string("no frames") : formatFrameRange(frames),
               "); bake frames within that range");
    }
  }
  if (!options.shotFrames.empty()) {
    const std::set<int> shot(options.shotFrames.begin(), options.shotFrames.end());
    for (int frame : options.frames) {
      if (shot.count(frame) == 0) {
        DS_THROW(kUsage, "frame ", frame, " is not a frame of the shot (",
                 formatFrameRange(options.shotFrames), ") that the bake is a part of");
      }
    }
  }
  checkOutputFolderWritable(expandFramePattern(options.outputPattern, options.frames.front()));
  if (!options.reportPath.empty()) {
    checkOutputFolderWritable(options.reportPath);
  }
}

/// The evaluator's hash plus what the bake adds: the EXR layout and, with the temporal bound,
/// where batches start.
std::uint64_t bakeHash(const Evaluator& evaluator, const BakeOptions& options) {
  OutputHashFields output;
  output.exrWidth = options.exrWidth;
  output.temporalWarmup = options.temporalWarmup;
  output.batchSize = options.batchFrames;
  return evaluator.settingsHash(output);
}

/// What a kept frame's record must agree with beyond the settings hash: the settings that
/// change the record but not the cloth.
struct RecordSettings {
  std::uint64_t settingsHash = 0;
  bool audit = true;
  double coverageTolerance = 0.0;
};

/// Whether a resume can keep the existing output of `record` (reuseProblem: it decodes
/// completely and matches) and what it carries: the frame's record (dsRecord), which then
/// replaces `record`, flagged against this bake's coverage tolerance (which the settings hash
/// leaves out: it changes no cloth). Returns "" when kept, else why not.
std::string keepExisting(FrameRecord& record, int vd, std::uint64_t topology,
                         const RecordSettings& settings) {
  ExrPointCacheInfo info;
  const std::string problem =
      reuseProblem(record.output, vd, topology, settings.settingsHash, record.frame, &info);
  if (!problem.empty()) {
    return problem;
  }
  const std::string where = record.output + " " + kAttrFrameRecord;
  FrameRecord kept;
  try {
    const auto found = info.stringAttributes.find(kAttrFrameRecord);
    if (found == info.stringAttributes.end()) {
      return std::string("carries no frame record (") + kAttrFrameRecord + ")";
    }
    kept = frameRecordFromJson(parseJsonText(found->second, where), where);
  } catch (const Error& error) {
    return std::string("has a frame record that does not read: ") + error.what();
  }
  if (kept.frame != record.frame) {
    return "carries the record of frame " + std::to_string(kept.frame);
  }
  if ((kept.insideAfter >= 0) != settings.audit) {
    return std::string("was baked with the audit ") + (settings.audit ? "off" : "on") +
           ": its record lacks this bake's figures";
  }
  if (kept.predictedError >= 0) {
    kept.flagged = kept.errorBound > settings.coverageTolerance ? 1 : 0;
  }
  kept.output = record.output;
  kept.skipped = true;
  record = std::move(kept);
  return "";
}

/// The frame records of the bake: a resume keeps an existing output with its record
/// (keepExisting) and removes the temporary files that killed runs left for this task's frames.
void planFrames(BakeResult& result, const BakeOptions& options, int vd, std::uint64_t topology,
                const RecordSettings& settings, int threads) {
  for (int frame : options.frames) {
    FrameRecord record;
    record.frame = frame;
    record.output = expandFramePattern(options.outputPattern, frame);
    result.frames.push_back(std::move(record));
  }
  if (!options.skipExisting) {
    return;
  }
  std::vector<std::string> outputs;
  for (const FrameRecord& record : result.frames) {
    outputs.push_back(record.output);
  }
  result.staleTempFilesRemoved = removeStaleTempFiles(outputs);
  parallelFor(static_cast<int>(result.frames.size()), threads, [&](int i) {
    FrameRecord& record = result.frames[i];
    std::error_code ec;
    if (std::filesystem::exists(record.output, ec)) {
      record.rebakeReason = keepExisting(record, vd, topology, settings);
    }
  });
  for (const FrameRecord& record : result.frames) {
    result.skipped += record.skipped ? 1 : 0;
  }
}

/// One batch of the shot's plan as this bake runs it: the batch's frames whose records are
/// result.frames[records[i]] (-1 for a frame of the shot outside options.frames), and the
/// rows of the batch to write (those not kept). A batch with nothing to write is not run.
struct BatchWork {
  std::vector<int> records;
  std::vector<int> rows;
};

/// BatchWork for each batch of `plan` (the shot's), from the frames' records.
std::vector<BatchWork> batchWork(const std::vector<BatchPlan>& plan,
                                 const std::vector<FrameRecord>& frames) {
  std::unordered_map<int, std::vector<int>> indexOf;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    indexOf[frames[i].frame].push_back(static_cast<int>(i));
  }
  std::vector<BatchWork> work(plan.size());
  for (std::size_t b = 0; b < plan.size(); ++b) {
    for (std::size_t row = 0; row < plan[b].frames.size(); ++row) {
      std::vector<int>& ours = indexOf[plan[b].frames[row]];
      const int index = ours.empty() ? -1 : ours.front();
      if (!ours.empty()) {
        ours.erase(ours.begin());  // a repeated frame: its next record
      }
      work[b].records.push_back(index);
      if (index >= 0 && !frames[index].skipped) {
        work[b].rows.push_back(static_cast<int>(row));
      }
    }
  }
  return work;
}

/// The driver frames of one launch batch: the warm-up frames (solved, not written), then the
/// batch's own frames.
struct DriverBatch {
  std::vector<int> solveFrames;
  int warm = 0;
  std::vector<float> driver;  ///< solveFrames.size() x 3Vp
  double seconds = 0;         ///< time spent reading them
};

/// Reads the driver frames of `batch` (warm-up, then its frames) on `threads` threads.
DriverBatch readDriverBatch(const PointCacheReader& driver, const BatchPlan& batch, int threads) {
  const auto start = Clock::now();
  DriverBatch in;
  in.solveFrames = batch.solveFrames();
  in.warm = static_cast<int>(batch.warmup.size());
  const std::size_t values = static_cast<std::size_t>(driver.vertexCount()) * 3;
  in.driver.resize(in.solveFrames.size() * values);
  parallelFor(static_cast<int>(in.solveFrames.size()), threads, [&](int i) {
    readFiniteFrame(driver, in.solveFrames[i], &in.driver[i * values], "driver cache");
  });
  in.seconds = secondsSince(start);
  return in;
}

/// Reads the driver frames of the batches to run, the next one on an I/O task while the
/// current one is evaluated.
class DriverReader {
 public:
  /// `runs`: the indices in `plan` of the batches to run, in order.
  DriverReader(const PointCacheReader& driver, const std::vector<BatchPlan>& plan,
               std::vector<std::size_t> runs, int threads)
      : mDriver(driver), mPlan(plan), mRuns(std::move(runs)), mThreads(threads) {}

  /// Batch runs[k] (read ahead when it was asked for), and the read-ahead of the next.
  DriverBatch take(std::size_t k) {
    DriverBatch input = mNext.valid() ? mNext.get() : read(mRuns[k]);
    if (k + 1 < mRuns.size()) {
      mNext = std::async(std::launch::async, [this, k] { return read(mRuns[k + 1]); });
    }
    return input;
  }

 private:
  DriverBatch read(std::size_t b) const { return readDriverBatch(mDriver, mPlan[b], mThreads); }

  const PointCacheReader& mDriver;
  const std::vector<BatchPlan>& mPlan;
  const std::vector<std::size_t> mRuns;
  const int mThreads;
  std::future<DriverBatch> mNext;
};

/// Writes batch after batch of EXRs on an I/O task while the next batch is evaluated: two
/// output blocks take turns. Each file carries its frame's record (dsRecord). Observer
/// callbacks stay on the bake thread, in frame order, after a batch's files are complete.
class BatchWriter {
 public:
  BatchWriter(BakeResult& result, ExrWriteOptions exr, int vd, int shapeCount, int threads,
              BakeObserver* observer)
      : mResult(result),
        mExr(std::move(exr)),
        mVd(vd),
        mShapeCount(shapeCount),
        mThreads(threads),
        mObserver(observer) {}

  /// The block the next batch evaluates into (count x 3Vd).
  float* block(int count) {
    std::vector<float>& block = mBlocks[mTurn % 2];
    block.resize(static_cast<std::size_t>(count) * 3 * mVd);
    return block.data();
  }

  /// Waits for the batch before, then writes rows `rows` (ascending) of block() as the frames
  /// of records result.frames[indices[i]].
  void submit(const std::vector<int>& rows, std::vector<int> indices, Clock::time_point started) {
    finish();
    float* positions = mBlocks[mTurn % 2].data();
    ++mTurn;
    const std::size_t values = static_cast<std::size_t>(mVd) * 3;
    std::vector<std::string> paths, records;
    std::vector<int> frames;
    for (std::size_t i = 0; i < rows.size(); ++i) {
      if (rows[i] != static_cast<int>(i)) {  // rows ascend: moving down never overwrites one
        std::copy_n(positions + rows[i] * values, values, positions + i * values);
      }
      const FrameRecord& record = mResult.frames[indices[i]];
      paths.push_back(record.output);
      frames.push_back(record.frame);
      records.push_back(jsonText(frameRecordJson(record, mShapeCount)));
    }
    auto write = [this, paths = std::move(paths), frames = std::move(frames),
                  records = std::move(records), positions, values]() {
      const auto start = Clock::now();
      // Frames on `workers` threads; the cores left over deflate the chunks within each frame
      // (a batch of one frame of a large mesh still uses every core).
      const int files = static_cast<int>(paths.size());
      const int workers = resolveThreads(mThreads, files);
      const int encodeThreads = std::max(1, resolveThreads(mThreads) / workers);
      parallelFor(files, workers, [&](int i) {
        ExrWriteOptions frameExr = mExr;
        frameExr.frame = frames[i];
        frameExr.encodeThreads = encodeThreads;
        frameExr.stringAttributes.emplace_back(kAttrFrameRecord, records[i]);
        writePointCacheExr(paths[i], mVd, positions + i * values, nullptr, frameExr);
      });
      return secondsSince(start);
    };
    mPending = Pending{std::async(std::launch::async, std::move(write)), std::move(indices),
                       positions, started};
  }

  /// Waits for the batch being written (rethrowing its error) and reports its frames.
  void finish() {
    if (!mPending) {
      return;
    }
    Pending done = std::move(*mPending);
    mPending.reset();
    mResult.times.write += done.seconds.get();
    std::vector<const FrameRecord*> records;
    for (int index : done.indices) {
      records.push_back(&mResult.frames[index]);
    }
    if (mObserver != nullptr) {
      mObserver->batchBaked(records, done.positions);
    }
    const double perFrame = secondsSince(done.started) / static_cast<double>(records.size());
    for (const FrameRecord* record : records) {
      ++mResult.baked;
      if (mObserver != nullptr) {
        mObserver->frameDone(*record, perFrame);
      }
    }
  }

 private:
  struct Pending {
    std::future<double> seconds;
    std::vector<int> indices;
    const float* positions = nullptr;
    Clock::time_point started;
  };

  BakeResult& mResult;
  const ExrWriteOptions mExr;
  const int mVd;
  const int mShapeCount;
  const int mThreads;
  BakeObserver* mObserver;
  std::array<std::vector<float>, 2> mBlocks;
  std::size_t mTurn = 0;
  std::optional<Pending> mPending;
};

}  // namespace

namespace {

void writeReport(const std::string& path, const Database& db, const PointCacheReader& driver,
                 const BakeOptions& options, const Evaluator& evaluator, const BakeResult& result) {
  writeFileAtomically(path, bakeReportJson(db, driver.path(), options, evaluator, result));
}

/// How the bake writes its EXRs.
ExrWriteOptions exrOptions(const BakeOptions& options, const Evaluator& evaluator,
                           std::uint64_t topology, std::uint64_t settingsHash) {
  ExrWriteOptions exr;
  exr.width = options.exrWidth;
  exr.compression = options.compression;
  exr.zipEncoder = options.zipEncoder;
  exr.topologyHash = topology;
  exr.settingsHash = settingsHash;
  exr.framesPerSecond = options.framesPerSecond;
  exr.syncToDisk = options.syncOutputs;
  if (!evaluator.settings().layers.empty()) {
    exr.stringAttributes.emplace_back("dsLayers", evaluator.describeLayers());
  }
  return exr;
}

}  // namespace

std::string admitDriverMesh(const Database& db, const std::string& source, bool allowUntrusted,
                            BakeOptions& options) {
  options.untrustedDriver =
      checkDriverMesh(db.driverMesh, source, DriverMeshUse::kBake, allowUntrusted);
  const bool trusted = options.untrustedDriver.empty();
  options.evaluator.audit = options.evaluator.audit && trusted;
  options.evaluator.resolve = options.evaluator.resolve && trusted;
  return options.untrustedDriver;
}

EvaluatorSettings evaluatorSettings(const Database& db, const BakeOptions& options) {
  EvaluatorSettings settings = options.evaluator;
  if (!options.bindingMaskPath.empty()) {
    if (settings.bindingMask) {
      DS_THROW(kUsage, "the binding mask is given twice (the file ", options.bindingMaskPath,
               " and an in-memory mask); give one");
    }
    settings.bindingMask = readBindingMask(options.bindingMaskPath, db.driverMesh, db.drivenMesh);
  }
  if (!options.regionsPath.empty()) {
    if (settings.regions) {
      DS_THROW(kUsage, "the regions are given twice (the file ", options.regionsPath,
               " and an in-memory region set); give one");
    }
    settings.regions = readRegions(options.regionsPath, db.driverMesh, db.drivenMesh);
  }
  if (settings.layers.empty()) {
    LayerOptions layers = options.layers;
    layers.framesPerSecond = options.framesPerSecond;
    settings.layers = loadLayers(layers, db.drivenMesh);
  } else if (options.layers.hasMix() || options.layers.hasWind()) {
    DS_THROW(kUsage, "the layers are given twice (layer files and in-memory layers); give one");
  }
  settings.threads = options.threads;
  return settings;
}

namespace {

/// What a bake warns of before its first frame: the driver's findings (refused unless
/// forced), an untrusted driver mesh, the evaluator's warnings and bake settings left unused.
void warnBeforeBaking(const Database& db, const PointCacheReader& driver,
                      const BakeOptions& options, const Evaluator& evaluator,
                      const std::function<void(const std::string&)>& warn) {
  for (const DriverFinding& finding : checkDriver(db, driver, options.frames)) {
    if (finding.refuse && !options.force) {
      DS_THROW(kInput, finding.message);
    }
    warn(finding.refuse ? "forced: " + finding.message : finding.message);
  }
  if (!options.untrustedDriver.empty()) {
    warn(options.untrustedDriver);
  }
  for (const std::string& message : evaluator.warnings()) {
    warn(message);
  }
  for (const UnusedSetting& unused : unusedSettings({evaluator.settings(), &options})) {
    if (unused.setting->scope == SettingScope::kBake) {
      warn(unused.message);
    }
  }
}

/// The batches of the shot's plan that a bake runs, and running them: a batch runs when it
/// has a frame to write, and one whose batch before did not run (kept by a resume, or outside
/// a farm chunk) first evaluates that batch's last frame, which the audit compares the
/// batch's first frame with (its largest jump, its binding switches): every frame record is
/// then the whole bake's, however the shot was chunked or resumed.
class ShotRun {
 public:
  ShotRun(const PointCacheReader& driver, Evaluator& evaluator, const BakeOptions& options,
          BakeResult& result, int threads)
      : mDriver(driver),
        mEvaluator(evaluator),
        mResult(result),
        mThreads(threads),
        mSettings(shotPlanSettings(evaluator, options.batchFrames, options.temporalWarmup)),
        mPlan(planShot(options.shotFrames.empty() ? options.frames : options.shotFrames,
                       driver.frames(), mSettings)),
        mWork(batchWork(mPlan, result.frames)) {
    for (std::size_t b = 0; b < mPlan.size(); ++b) {
      if (!mWork[b].rows.empty()) {
        mRuns.push_back(b);
        mToBake += static_cast<int>(mWork[b].rows.size());
      }
      const auto ours = [](int index) { return index >= 0; };
      if (!mFitBatch && std::any_of(mWork[b].records.begin(), mWork[b].records.end(), ours)) {
        mFitBatch = b;
      }
    }
  }

  /// Runs the batches with a frame to write; `stopIfAsked` before each one.
  void run(BatchWriter& writer, const std::function<void()>& stopIfAsked,
           const std::function<void(const std::string&)>& warn) {
    if (mFitBatch && mWork[*mFitBatch].rows.empty()) {
      warnOfFit(*mFitBatch, warn);  // every frame of it kept
    }
    DriverReader reader(mDriver, mPlan, mRuns, mThreads);
    std::vector<FrameRecord> records;
    for (std::size_t k = 0; k < mRuns.size(); ++k) {
      const std::size_t b = mRuns[k];
      stopIfAsked();
      const auto batchStart = Clock::now();
      if (b > 0 && (k == 0 || mRuns[k - 1] != b - 1)) {
        leadIn(b);
      }
      auto start = Clock::now();
      const DriverBatch input = reader.take(k);
      mResult.times.readWait += secondsSince(start);
      mResult.times.read += input.seconds;
      const int count = static_cast<int>(mPlan[b].frames.size());
      records.assign(count, FrameRecord{});
      // Each batch starts the temporal bound afresh (after its warm-up).
      mEvaluator.resetTemporalBound();
      addSeconds(mEvaluator.evaluate(static_cast<int>(input.solveFrames.size()),
                                     input.solveFrames.data(), input.driver.data(),
                                     writer.block(count), records.data(), input.warm));
      std::vector<int> indices;
      for (int row : mWork[b].rows) {
        const int index = mWork[b].records[row];
        FrameRecord& record = mResult.frames[index];
        records[row].output = std::move(record.output);
        records[row].rebakeReason = std::move(record.rebakeReason);
        record = std::move(records[row]);
        indices.push_back(index);
      }
      warnOfFit(b, warn);
      start = Clock::now();
      writer.submit(mWork[b].rows, std::move(indices), batchStart);
      mResult.times.writeWait += secondsSince(start);
    }
  }

  /// Frames this bake writes.
  int toBake() const { return mToBake; }

 private:
  /// Evaluates what the audit of batch b's first frame compares with, as the whole bake
  /// evaluated it: batch b-1 with the temporal bound (its frames depend on one another), else
  /// its last frame alone (with its warm-up). Nothing is written, no record kept.
  void leadIn(std::size_t b) {
    const BatchPlan lead =
        mSettings.temporalBound
            ? mPlan[b - 1]
            : planShot({mPlan[b - 1].frames.back()}, mDriver.frames(), mSettings).front();
    const DriverBatch input = readDriverBatch(mDriver, lead, mThreads);
    mResult.times.read += input.seconds;
    std::vector<FrameRecord> records(lead.frames.size());
    std::vector<float> cloth(lead.frames.size() * 3 *
                             static_cast<std::size_t>(mEvaluator.database().drivenVertexCount()));
    mEvaluator.resetTemporalBound();
    addSeconds(mEvaluator.evaluate(static_cast<int>(input.solveFrames.size()),
                                   input.solveFrames.data(), input.driver.data(), cloth.data(),
                                   records.data(), input.warm));
  }

  /// The fit warning (residualWarning) from the records of the first batch of the shot that
  /// holds a frame of this bake, once they are all known.
  void warnOfFit(std::size_t b, const std::function<void(const std::string&)>& warn) const {
    if (b != mFitBatch) {
      return;
    }
    std::vector<const FrameRecord*> first;
    for (int index : mWork[b].records) {
      if (index >= 0) {
        first.push_back(&mResult.frames[index]);
      }
    }
    const std::string fit = residualWarning(first);
    if (!fit.empty()) {
      warn(fit);
    }
  }

  void addSeconds(const StageSeconds& seconds) {
    for (const auto& [stage, value] : seconds) {
      mResult.times.stages[stage] += value;
    }
  }

  const PointCacheReader& mDriver;
  Evaluator& mEvaluator;
  BakeResult& mResult;
  const int mThreads;
  const ShotPlanSettings mSettings;
  const std::vector<BatchPlan> mPlan;
  const std::vector<BatchWork> mWork;
  std::vector<std::size_t> mRuns;
  std::optional<std::size_t> mFitBatch;
  int mToBake = 0;
};

}  // namespace

BakeResult bake(const Database& db, const PointCacheReader& driver, Device& device,
                const BakeOptions& options, BakeObserver* observer) {
  const auto bakeStart = Clock::now();
  validate(db, driver, options);
  const int threads = resolveThreads(options.threads);
  const int vd = db.drivenVertexCount();
  Evaluator evaluator(db, evaluatorSettings(db, options), device);
  evaluator.checkFrames(options.frames);

  BakeResult result;
  const auto warn = [&](const std::string& message) {
    result.warnings.push_back(message);
    if (observer != nullptr) {
      observer->warning(message);
    }
  };
  warnBeforeBaking(db, driver, options, evaluator, warn);
  result.device = evaluator.deviceName();
  result.settingsHash = bakeHash(evaluator, options);
  const std::uint64_t topology = topologyHash(db.drivenMesh);
  planFrames(result, options, vd, topology,
             {result.settingsHash, evaluator.settings().audit, evaluator.coverageTolerance()},
             threads);
  ShotRun shot(driver, evaluator, options, result, threads);
  BatchWriter writer(result, exrOptions(options, evaluator, topology, result.settingsHash), vd,
                     db.shapeCount(), threads, observer);
  result.times.setup = secondsSince(bakeStart);

  // A stop request ends the bake before the next batch, and after the last one before the
  // report (a shot of one batch stops too): the frames written are whole, no report claims
  // the shot.
  const auto stopIfAsked = [&]() {
    if (observer != nullptr && observer->stopRequested()) {
      writer.finish();
      DS_THROW(kInterrupted, "stopped after ", result.baked, " of ", shot.toBake(),
               " frames; finished frames are complete, resume by baking again with existing "
               "outputs kept (--skip-existing)");
    }
  };
  shot.run(writer, stopIfAsked, warn);
  writer.finish();
  stopIfAsked();
  result.times.total = secondsSince(bakeStart);
  if (!options.reportPath.empty()) {
    writeReport(options.reportPath, db, driver, options, evaluator, result);
  }
  return result;
}

}  // namespace drivenshape
