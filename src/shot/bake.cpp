// SPDX-License-Identifier: Apache-2.0
// The bake: the shot loop around one Evaluator. Frames are read a batch ahead on an I/O task,
// evaluated a batch at a time, and written on another I/O task while the next batch runs
// (double buffering); a resume keeps complete outputs; a stop request ends the bake between
// batches with every written frame complete.

#include <drivenshape/bake.h>

#include "driver_check.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <future>
#include <memory>
#include <optional>
#include <thread>

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

/// The frame records of the bake, and which of them to bake: a resume keeps an existing
/// output only if it decodes completely and matches (reuseProblem), and removes the temporary
/// files that killed runs left for this task's frames.
std::vector<int> planFrames(BakeResult& result, const BakeOptions& options, int vd,
                            std::uint64_t topology, int threads) {
  for (int frame : options.frames) {
    FrameRecord record;
    record.frame = frame;
    record.output = expandFramePattern(options.outputPattern, frame);
    result.frames.push_back(std::move(record));
  }
  if (options.skipExisting) {
    std::vector<std::string> outputs;
    for (const FrameRecord& record : result.frames) {
      outputs.push_back(record.output);
    }
    result.staleTempFilesRemoved = removeStaleTempFiles(outputs);
    parallelFor(static_cast<int>(result.frames.size()), threads, [&](int i) {
      FrameRecord& record = result.frames[i];
      std::error_code ec;
      if (std::filesystem::exists(record.output, ec)) {
        record.rebakeReason =
            reuseProblem(record.output, vd, topology, result.settingsHash, record.frame);
        record.skipped = record.rebakeReason.empty();
      }
    });
  }
  std::vector<int> todo;
  for (std::size_t i = 0; i < result.frames.size(); ++i) {
    if (result.frames[i].skipped) {
      ++result.skipped;
    } else {
      todo.push_back(static_cast<int>(i));
    }
  }
  return todo;
}

/// The driver frames of one launch batch: the warm-up frames (solved, not written), then the
/// batch's own frames.
struct DriverBatch {
  std::vector<int> solveFrames;
  int warm = 0;
  std::vector<float> driver;  ///< solveFrames.size() x 3Vp
  double seconds = 0;         ///< time spent reading them
};

/// Reads the driver frames of the planned batches (planShot), the next batch on an I/O task
/// while the current one is evaluated.
class DriverReader {
 public:
  DriverReader(const PointCacheReader& driver, const std::vector<BatchPlan>& plan, int threads)
      : mDriver(driver), mPlan(plan), mThreads(threads) {}

  /// Batch `b` of the plan (read ahead when it was asked for), and the read-ahead of the next.
  DriverBatch take(std::size_t b) {
    DriverBatch input = mNext.valid() ? mNext.get() : read(b);
    if (b + 1 < mPlan.size()) {
      mNext = std::async(std::launch::async, [this, b] { return read(b + 1); });
    }
    return input;
  }

 private:
  DriverBatch read(std::size_t b) const {
    const auto start = Clock::now();
    DriverBatch in;
    in.solveFrames = mPlan[b].solveFrames();
    in.warm = static_cast<int>(mPlan[b].warmup.size());
    const std::size_t values = static_cast<std::size_t>(mDriver.vertexCount()) * 3;
    in.driver.resize(in.solveFrames.size() * values);
    parallelFor(static_cast<int>(in.solveFrames.size()), mThreads, [&](int i) {
      readFiniteFrame(mDriver, in.solveFrames[i], &in.driver[i * values], "driver cache");
    });
    in.seconds = secondsSince(start);
    return in;
  }

  const PointCacheReader& mDriver;
  const std::vector<BatchPlan>& mPlan;
  const int mThreads;
  std::future<DriverBatch> mNext;
};

/// Writes batch after batch of EXRs on an I/O task while the next batch is evaluated: two
/// output blocks take turns. Observer callbacks stay on the bake thread, in frame order, after
/// a batch's files are complete.
class BatchWriter {
 public:
  BatchWriter(BakeResult& result, const std::vector<int>& todo, ExrWriteOptions exr, int vd,
              int threads, BakeObserver* observer)
      : mResult(result),
        mTodo(todo),
        mExr(std::move(exr)),
        mVd(vd),
        mThreads(threads),
        mObserver(observer) {}

  /// The block the next batch evaluates into (count x 3Vd).
  float* block(int count) {
    std::vector<float>& block = mBlocks[mTurn % 2];
    block.resize(static_cast<std::size_t>(count) * 3 * mVd);
    return block.data();
  }

  /// Waits for the batch before, then writes frames todo[begin, begin + count) from block().
  void submit(std::size_t begin, int count, Clock::time_point started) {
    finish();
    const float* positions = mBlocks[mTurn % 2].data();
    ++mTurn;
    std::vector<std::string> paths;
    std::vector<int> frames;
    for (int i = 0; i < count; ++i) {
      paths.push_back(mResult.frames[mTodo[begin + i]].output);
      frames.push_back(mResult.frames[mTodo[begin + i]].frame);
    }
    auto write = [this, paths = std::move(paths), frames = std::move(frames), positions]() {
      const auto start = Clock::now();
      const std::size_t values = static_cast<std::size_t>(mVd) * 3;
      // Frames on `workers` threads; the cores left over deflate the chunks within each frame
      // (a batch of one frame of a large mesh still uses every core).
      const int files = static_cast<int>(paths.size());
      const int workers = resolveThreads(mThreads, files);
      const int encodeThreads = std::max(1, resolveThreads(mThreads) / workers);
      parallelFor(files, workers, [&](int i) {
        ExrWriteOptions frameExr = mExr;
        frameExr.frame = frames[i];
        frameExr.encodeThreads = encodeThreads;
        writePointCacheExr(paths[i], mVd, positions + i * values, nullptr, frameExr);
      });
      return secondsSince(start);
    };
    mPending =
        Pending{std::async(std::launch::async, std::move(write)), begin, count, positions, started};
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
    for (int i = 0; i < done.count; ++i) {
      records.push_back(&mResult.frames[mTodo[done.begin + i]]);
    }
    if (mObserver != nullptr) {
      mObserver->batchBaked(records, done.positions);
    }
    const double perFrame = secondsSince(done.started) / done.count;
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
    std::size_t begin = 0;
    int count = 0;
    const float* positions = nullptr;
    Clock::time_point started;
  };

  BakeResult& mResult;
  const std::vector<int>& mTodo;
  const ExrWriteOptions mExr;
  const int mVd;
  const int mThreads;
  BakeObserver* mObserver;
  std::array<std::vector<float>, 2> mBlocks;
  std::size_t mTurn = 0;
  std::optional<Pending> mPending;
};

nlohmann::json frameJson(const FrameRecord& record, int shapeCount) {
  nlohmann::json entry{
      {"frame", record.frame}, {"output", record.output}, {"skipped", record.skipped}};
  if (!record.rebakeReason.empty()) {
    entry["rebaked_because"] = record.rebakeReason;
  }
  if (record.skipped) {
    return entry;
  }
  entry["relative_residual"] = record.relativeResidual;
  if (record.directResidual >= 0.0) {
    entry["relative_residual_direct"] = record.directResidual;
  }
  entry["kkt_residual"] = record.kktResidual;
  entry["iterations"] = record.iterations;
  entry["active_at_zero"] = record.atZero;
  entry["active_at_one"] = record.atOne;
  entry["weights"] = record.weights;
  if (record.weights.size() > static_cast<std::size_t>(shapeCount)) {
    // Regions: one weight vector per region, in the order of settings.regions.
    nlohmann::json perRegion = nlohmann::json::array();
    for (std::size_t r = 0; r < record.weights.size(); r += shapeCount) {
      perRegion.push_back(
          std::vector<double>(record.weights.begin() + r, record.weights.begin() + r + shapeCount));
    }
    entry["weights"] = perRegion;
  }
  if (!record.alignRotation.empty()) {
    entry["align_rotation"] = record.alignRotation;
    entry["align_translation"] = record.alignTranslation;
  }
  const std::pair<const char*, int> counts[] = {{"inside_before", record.insideBefore},
                                                {"inside_corrected", record.insideCorrected},
                                                {"inside_after", record.insideAfter},
                                                {"resolved", record.resolved},
                                                {"binding_switches", record.bindingSwitches}};
  for (const auto& [key, value] : counts) {
    if (value >= 0) {
      entry[key] = value;
    }
  }
  if (record.closestQueries > 0) {
    // Work counters (they depend on the batching; the cloth does not).
    entry["closest_queries"] = record.closestQueries;
    entry["closest_cleared"] = record.closestCleared;
  }
  if (record.maxJump >= 0) {
    entry["max_jump"] = record.maxJump;
    entry["max_jump_vertex"] = record.maxJumpVertex;
  }
  if (record.predictedError >= 0) {
    entry["pose_distance"] = record.poseDistance;
    entry["predicted_error"] = record.predictedError;
    entry["error_bound"] = record.errorBound;
    entry["coverage"] = {{"flagged", record.flagged == 1}, {"score", record.errorBound}};
  }
  return entry;
}

nlohmann::json runsJson(const std::vector<SimulationRun>& runs) {
  nlohmann::json out = nlohmann::json::array();
  for (const SimulationRun& run : runs) {
    out.push_back({{"from", run.from}, {"to", run.to}, {"wanted", run.wanted}});
  }
  return out;
}

/// The shot's coverage verdict from the frames' error bounds: the fraction of frames the
/// pose model covers, the frames to simulate and the runs a simulation of them needs; null
/// without a pose model.
nlohmann::json coverageJson(const std::vector<FrameRecord>& records, double tolerance,
                            double level) {
  std::vector<int> flagged;
  int checked = 0, first = 0;
  for (const FrameRecord& record : records) {
    if (!record.skipped && record.flagged >= 0) {
      first = checked == 0 ? record.frame : std::min(first, record.frame);
      ++checked;
      if (record.flagged == 1) {
        flagged.push_back(record.frame);
      }
    }
  }
  if (checked == 0) {
    return nullptr;
  }
  std::sort(flagged.begin(), flagged.end());
  const double covered = 1.0 - static_cast<double>(flagged.size()) / checked;
  return {{"tolerance", tolerance},
          {"level", level},
          {"frames_checked", checked},
          {"covered_fraction", covered},
          {"simulate_frames", flagged.empty() ? std::string() : formatFrameRange(flagged)},
          {"simulate_runs", runsJson(simulationRuns(flagged, first))},
          {"run_up", kSimulationRunUp},
          {"verdict",
           flagged.empty() ? "DrivenShape is enough" : "simulate " + formatFrameRange(flagged)}};
}

}  // namespace

std::string bakeReportJson(const Database& db, const std::string& driverPath,
                           const BakeOptions& options, const Evaluator& evaluator,
                           const BakeResult& result) {
  using nlohmann::json;
  json settings = parseJsonText(evaluator.describeSettings(), "the evaluator settings");
  settings.update(parseJsonText(describeBakeSettings(options), "the bake settings"));
  settings["untrusted_driver"] = !options.untrustedDriver.empty();
  json seconds{{"read", result.times.read},
               {"setup", result.times.setup},
               {"write", result.times.write},
               {"read_wait", result.times.readWait},
               {"write_wait", result.times.writeWait},
               {"total", result.times.total}};
  for (const char* stage :
       {"align", "project", "weights", "blend", "correct", "resolve", "layers", "audit"}) {
    seconds[stage] = 0.0;
  }
  for (const auto& [stage, value] : result.times.stages) {
    seconds[stage] = value;
  }
  json frames = json::array();
  for (const FrameRecord& record : result.frames) {
    frames.push_back(frameJson(record, db.shapeCount()));
  }
  json report{
      {"tool", "drivenshape"},
      {"tool_version", kVersion},
      {"device", result.device},
      {"database",
       {{"content_hash", hashToHex(db.contentHash())},
        {"shape_count", db.shapeCount()},
        {"driven_vertices", db.drivenVertexCount()},
        {"frames", db.frames}}},
      {"driver_cache", driverPath},
      {"output", options.outputPattern},
      {"settings_hash", hashToHex(result.settingsHash)},
      {"settings", settings},
      {"baked", result.baked},
      {"skipped", result.skipped},
      {"seconds", seconds},
      {"frames", frames},
  };
  if (!result.warnings.empty()) {
    report["warnings"] = result.warnings;
  }
  const json coverage =
      coverageJson(result.frames, evaluator.coverageTolerance(), db.poseModel.verdictLevel);
  if (!coverage.is_null()) {
    report["coverage"] = coverage;
  }
  return jsonText(report, 1) + "\n";
}

std::string coverageVerdictJson(const std::vector<FrameRecord>& records, double tolerance,
                                double level) {
  return jsonText(coverageJson(records, tolerance, level));
}

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
  result.device = evaluator.deviceName();
  result.settingsHash = bakeHash(evaluator, options);
  const std::uint64_t topology = topologyHash(db.drivenMesh);
  const std::vector<int> todo = planFrames(result, options, vd, topology, threads);

  const ExrWriteOptions exr = exrOptions(options, evaluator, topology, result.settingsHash);
  std::vector<int> todoFrames;
  for (int index : todo) {
    todoFrames.push_back(result.frames[index].frame);
  }
  const std::vector<BatchPlan> plan =
      planShot(todoFrames, driver.frames(),
               shotPlanSettings(evaluator, options.batchFrames, options.temporalWarmup));
  DriverReader reader(driver, plan, threads);
  BatchWriter writer(result, todo, exr, vd, threads, observer);
  std::vector<FrameRecord> records;
  result.times.setup = secondsSince(bakeStart);

  // A stop request ends the bake before the next batch, and after the last one before the
  // report (a shot of one batch stops too): the frames written are whole, no report claims
  // the shot.
  const auto stopIfAsked = [&]() {
    if (observer != nullptr && observer->stopRequested()) {
      writer.finish();
      DS_THROW(kInterrupted, "stopped after ", result.baked, " of ", todo.size(),
               " frames; finished frames are complete, resume by baking again with existing "
               "outputs kept (--skip-existing)");
    }
  };
  for (std::size_t b = 0; b < plan.size(); ++b) {
    const std::size_t begin = plan[b].first;
    stopIfAsked();
    const auto batchStart = Clock::now();
    const int count = static_cast<int>(plan[b].frames.size());
    auto start = Clock::now();
    const DriverBatch input = reader.take(b);
    result.times.readWait += secondsSince(start);
    result.times.read += input.seconds;

    // Each batch starts the temporal bound afresh (after its warm-up), so a farm chunk that
    // starts on a batch boundary reproduces the single bake; the audit's reference frame
    // carries over from the batch before.
    evaluator.resetTemporalBound();
    records.assign(count, FrameRecord{});
    for (int i = 0; i < count; ++i) {
      records[i] = result.frames[todo[begin + i]];
    }
    const StageSeconds seconds =
        evaluator.evaluate(static_cast<int>(input.solveFrames.size()), input.solveFrames.data(),
                           input.driver.data(), writer.block(count), records.data(), input.warm);
    for (const auto& [stage, value] : seconds) {
      result.times.stages[stage] += value;
    }
    if (begin == 0) {
      std::vector<const FrameRecord*> first;
      for (const FrameRecord& record : records) {
        first.push_back(&record);
      }
      const std::string fit = residualWarning(first);
      if (!fit.empty()) {
        warn(fit);
      }
    }
    for (int i = 0; i < count; ++i) {
      result.frames[todo[begin + i]] = std::move(records[i]);
    }
    start = Clock::now();
    writer.submit(begin, count, batchStart);
    result.times.writeWait += secondsSince(start);
  }
  writer.finish();
  stopIfAsked();
  result.times.total = secondsSince(bakeStart);
  if (!options.reportPath.empty()) {
    writeReport(options.reportPath, db, driver, options, evaluator, result);
  }
  return result;
}

}  // namespace drivenshape
