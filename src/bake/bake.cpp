#include <drivenshape/bake.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <future>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <thread>

#include <drivenshape/align.h>
#include <drivenshape/atomic_file.h>
#include <drivenshape/error.h>
#include <drivenshape/frames.h>
#include <drivenshape/hash.h>
#include <drivenshape/parallel.h>
#include <drivenshape/qp.h>
#include <drivenshape/regions.h>
#include <drivenshape/version.h>

#include "json_text.h"

namespace drivenshape {
namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

/// The database driver shapes (k x 3Vp, flat) as an n x k matrix of the rows of `vertices`
/// (every vertex when empty).
Eigen::MatrixXd driverMatrix(const std::vector<float>& shapes, int k, int vertexCount,
                             const std::vector<int>& vertices) {
  const Eigen::Index n = static_cast<Eigen::Index>(vertexCount) * 3;
  if (vertices.empty()) {
    Eigen::MatrixXd a(n, k);
    for (int i = 0; i < k; ++i) {
      a.col(i) = Eigen::Map<const Eigen::VectorXf>(&shapes[i * n], n).cast<double>();
    }
    return a;
  }
  Eigen::MatrixXd a(static_cast<Eigen::Index>(vertices.size()) * 3, k);
  for (int i = 0; i < k; ++i) {
    for (std::size_t j = 0; j < vertices.size(); ++j) {
      for (int c = 0; c < 3; ++c) {
        a(static_cast<Eigen::Index>(3 * j + c), i) = shapes[i * n + 3 * vertices[j] + c];
      }
    }
  }
  return a;
}

Eigen::MatrixXd driverMatrix(const Database& db) {
  return driverMatrix(db.driverShapes, db.shapeCount(), db.driverVertexCount(), {});
}

ShapeTables tablesFrom(const Database& db, const SimplexLeastSquares& solver,
                       std::vector<float> driverShapes, std::vector<float> drivenShapes) {
  ShapeTables tables;
  tables.driverVertexCount = db.driverVertexCount();
  tables.drivenVertexCount = db.drivenVertexCount();
  tables.shapeCount = db.shapeCount();
  const Eigen::MatrixXd& basis = solver.basis();  // n x (k-1)
  const Eigen::Index n = basis.rows();
  tables.projectionRows.resize(static_cast<std::size_t>(basis.size()));
  for (Eigen::Index r = 0; r < basis.cols(); ++r) {
    for (Eigen::Index j = 0; j < n; ++j) {
      tables.projectionRows[r * n + j] = static_cast<float>(basis(j, r));
    }
  }
  tables.center.resize(static_cast<std::size_t>(n));
  for (Eigen::Index j = 0; j < n; ++j) {
    tables.center[j] = static_cast<float>(solver.center()(j));
  }
  tables.driverShapes = std::move(driverShapes);
  tables.drivenShapes = std::move(drivenShapes);
  return tables;
}

int hardwareThreads() {
  return std::max(1u, std::thread::hardware_concurrency());
}

/// One weight problem per frame: the QP on the driver rows of a region (or all rows).
/// The driver frames of one launch batch: the temporal warm-up frames (solved, not written),
/// then the batch's own frames.
struct BatchInput {
  std::vector<int> solveFrames;
  int warm = 0;
  std::vector<float> driverAll;  ///< solveFrames.size() x 3Vp
  double seconds = 0;            ///< time spent reading them
};

/// Frames per launch batch: options.chunkSize, lowered (never below 1) so that one batch's
/// frame blocks stay within kBatchMemoryBudget. The temporal bound restarts at every batch, so
/// with it on the batch is exactly options.chunkSize (results depend on it).
int batchFrames(const BakeOptions& options, int vp, int vd) {
  if (options.maxWeightChange > 0) {
    return options.chunkSize;
  }
  // Per frame: driver frames (read, aligned, blended) and the pipeline's cloth blocks (blend,
  // two output blocks) in float, plus two hit arrays.
  const std::size_t bytes = sizeof(float) * 3 * (3 * std::size_t(vp) + 3 * std::size_t(vd)) +
                            2 * sizeof(SurfaceHit) * std::size_t(vd);
  const std::size_t fit =
      std::max<std::size_t>(1, kBatchMemoryBudget / std::max<std::size_t>(1, bytes));
  return static_cast<int>(std::min<std::size_t>(options.chunkSize, fit));
}

struct WeightProblem {
  std::string name;
  std::vector<int> rows;  ///< driver vertices; empty = every row (projected by the backend)
  std::unique_ptr<SimplexLeastSquares> solver;
};

/// What a bake precomputes from the database and its settings, once.
struct Prepared {
  std::vector<float> driverShapes;  ///< k x 3Vp, rigidly aligned to the rest driver if asked
  std::vector<float> drivenShapes;  ///< k x 3Vd, the same motion per shape (world blending)
  std::unique_ptr<RigidAligner> aligner;
  std::vector<int> alignVertices;
  bool hasRegions = false;
  RegionSet regions;
  std::vector<WeightProblem> problems;  ///< 1 without regions
  std::vector<SurfaceHit> restHits;     ///< local blending: Vd hits on the rest driver
  std::vector<float> localShapes;       ///< local blending: k x 3Vd offsets
};

std::uint64_t settingsHashOf(const Database& db, const BakeOptions& options,
                             const BindingMask& mask, const Prepared& prepared) {
  Hasher hasher;
  hasher.addValue(db.contentHash());
  hasher.addValue(static_cast<int>(options.weightMode));
  hasher.addValue(options.exrWidth);
  hasher.addValue(options.correct);
  for (int c = 0; c < mask.classCount(); ++c) {
    hasher.add(mask.classTriangles(c).data(), mask.classTriangles(c).size() * sizeof(int));
  }
  hasher.add(mask.vertexClasses().data(), mask.vertexClasses().size() * sizeof(int));
  hasher.addValue(static_cast<int>(options.align));
  hasher.add(prepared.alignVertices.data(), prepared.alignVertices.size() * sizeof(int));
  if (prepared.aligner) {
    hasher.add(prepared.aligner->weights().data(),
               prepared.aligner->weights().size() * sizeof(double));
  }
  hasher.addValue(blendsLocally(options));
  hasher.addValue(options.resolve);
  hasher.addValue(options.resolve ? options.skinOffset : 0.0);
  hasher.addValue(prepared.hasRegions);
  if (prepared.hasRegions) {
    hasher.addValue(prepared.regions.falloff);
    for (const Region& region : prepared.regions.regions) {
      hasher.add(region.driverVertices.data(), region.driverVertices.size() * sizeof(int));
      hasher.add(region.drivenVertices.data(), region.drivenVertices.size() * sizeof(int));
    }
  }
  hasher.addValue(options.maxWeightChange);
  if (options.maxWeightChange > 0) {
    hasher.addValue(options.temporalWarmup);
    hasher.addValue(options.chunkSize);
  }
  hasher.addString(kVersion);
  return hasher.value();
}

void validate(const Database& db, const PointCacheReader& driver, const BakeBackends& backends,
              const BakeOptions& options) {
  if (backends.stages == nullptr ||
      ((options.correct || blendsLocally(options)) && backends.binding == nullptr) ||
      ((options.audit || options.resolve || options.layers.hasWind()) &&
       backends.audit == nullptr) ||
      ((options.layers.hasMix() || options.layers.hasWind()) && backends.layers == nullptr)) {
    DS_THROW(kInternal, "bake called without the backends its options need");
  }
  if (options.frames.empty()) {
    DS_THROW(kUsage, "the frame range is empty; pass --frames, e.g. --frames 1001-1100");
  }
  if (options.weightMode == WeightMode::kBind && !options.correct) {
    DS_THROW(kUsage,
             "the bind baseline is the correction applied to the rest shapes; it cannot "
             "run with --no-correct");
  }
  if (options.weightMode != WeightMode::kQp &&
      (!options.regionsPath.empty() || options.maxWeightChange > 0)) {
    DS_THROW(kUsage,
             "--regions and --max-weight-change apply to the QP weights only "
             "(--weights qp)");
  }
  if (!std::isfinite(options.skinOffset) || options.skinOffset < 0) {
    DS_THROW(kUsage, "--skin-offset must be a distance >= 0 in scene units (got ",
             options.skinOffset, ")");
  }
  if (!std::isfinite(options.maxWeightChange) || options.maxWeightChange < 0 ||
      options.maxWeightChange > 1) {
    DS_THROW(kUsage, "--max-weight-change must be in [0, 1] (0 = off; got ",
             options.maxWeightChange, ")");
  }
  if (options.temporalWarmup < 0) {
    DS_THROW(kUsage, "--temporal-warmup must be >= 0 (got ", options.temporalWarmup, ")");
  }
  if (options.chunkSize < 1) {
    DS_THROW(kUsage, "--batch must be at least 1 (got ", options.chunkSize, ")");
  }
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
               "); pass --frames within that range");
    }
  }
  checkOutputFolderWritable(expandFramePattern(options.outputPattern, options.frames.front()));
  if (!options.reportPath.empty()) {
    checkOutputFolderWritable(options.reportPath);
  }
}

void writeReport(const std::string& path, const Database& db, const PointCacheReader& driver,
                 const BakeOptions& options, const Prepared& prepared, const std::string& layers,
                 const BakeResult& result) {
  using nlohmann::json;
  json regions = json::array();
  for (const Region& region : prepared.regions.regions) {
    regions.push_back({{"name", region.name},
                       {"driver_vertices", region.driverVertices.size()},
                       {"driven_vertices", region.drivenVertices.size()}});
  }
  json frames = json::array();
  for (const FrameRecord& record : result.frames) {
    json entry{{"frame", record.frame}, {"output", record.output}, {"skipped", record.skipped}};
    if (!record.rebakeReason.empty()) {
      entry["rebaked_because"] = record.rebakeReason;
    }
    if (!record.skipped) {
      entry["relative_residual"] = record.relativeResidual;
      entry["kkt_residual"] = record.kktResidual;
      entry["iterations"] = record.iterations;
      entry["active_at_zero"] = record.atZero;
      entry["active_at_one"] = record.atOne;
      entry["weights"] = record.weights;
      if (record.weights.size() > static_cast<std::size_t>(db.shapeCount())) {
        // Regions: one weight vector per region, in the order of settings.regions.
        json perRegion = json::array();
        for (std::size_t r = 0; r < record.weights.size(); r += db.shapeCount()) {
          perRegion.push_back(std::vector<double>(record.weights.begin() + r,
                                                  record.weights.begin() + r + db.shapeCount()));
        }
        entry["weights"] = perRegion;
      }
      if (!record.alignRotation.empty()) {
        entry["align_rotation"] = record.alignRotation;
        entry["align_translation"] = record.alignTranslation;
      }
      if (record.insideBefore >= 0) {
        entry["inside_before"] = record.insideBefore;
      }
      if (record.insideCorrected >= 0) {
        entry["inside_corrected"] = record.insideCorrected;
      }
      if (record.insideAfter >= 0) {
        entry["inside_after"] = record.insideAfter;
      }
      if (record.resolved >= 0) {
        entry["resolved"] = record.resolved;
      }
      if (record.bindingSwitches >= 0) {
        entry["binding_switches"] = record.bindingSwitches;
      }
      if (record.maxJump >= 0) {
        entry["max_jump"] = record.maxJump;
        entry["max_jump_vertex"] = record.maxJumpVertex;
      }
    }
    frames.push_back(std::move(entry));
  }
  const json report{
      {"tool", "drivenshape"},
      {"tool_version", kVersion},
      {"device", result.device},
      {"database",
       {{"content_hash", hashToHex(db.contentHash())},
        {"shape_count", db.shapeCount()},
        {"frames", db.frames}}},
      {"driver_cache", driver.path()},
      {"output", options.outputPattern},
      {"settings_hash", hashToHex(result.settingsHash)},
      {"settings",
       {{"weights", options.weightMode == WeightMode::kQp        ? "qp"
                    : options.weightMode == WeightMode::kNearest ? "nearest"
                                                                 : "bind"},
        {"correct", options.correct},
        {"binding_mask", options.bindingMaskPath},
        {"audit", options.audit},
        {"align", alignModeName(options.align)},
        {"align_group", options.alignGroup.empty() ? std::string("all") : options.alignGroup},
        {"align_vertices", prepared.alignVertices.size()},
        {"blend", blendsLocally(options) ? "local" : "world"},
        {"resolve", options.resolve},
        {"skin_offset", options.skinOffset},
        {"regions_file", options.regionsPath},
        {"regions", regions},
        {"region_falloff", prepared.hasRegions ? prepared.regions.falloff : 0},
        {"max_weight_change", options.maxWeightChange},
        {"temporal_warmup", options.maxWeightChange > 0 ? options.temporalWarmup : 0},
        {"batch", options.chunkSize},
        {"layers", parseJsonText(layers, "the layer description")},
        {"compression", exrCompressionName(options.compression)},
        {"exr_width", options.exrWidth}}},
      {"baked", result.baked},
      {"skipped", result.skipped},
      {"seconds",
       {{"read", result.times.read},
        {"align", result.times.align},
        {"project", result.times.project},
        {"weights", result.times.weights},
        {"blend", result.times.blend},
        {"correct", result.times.correct},
        {"resolve", result.times.resolve},
        {"layers", result.times.layers},
        {"setup", result.times.setup},
        {"audit", result.times.audit},
        {"write", result.times.write},
        {"read_wait", result.times.readWait},
        {"write_wait", result.times.writeWait},
        {"total", result.times.total}}},
      {"frames", frames},
  };
  writeFileAtomically(path, jsonText(report, 1) + "\n");
}

}  // namespace

ShapeTables makeShapeTables(const Database& database) {
  return tablesFrom(database, SimplexLeastSquares(driverMatrix(database)), database.driverShapes,
                    database.drivenShapes);
}

namespace {

Prepared prepare(const Database& db, const BakeOptions& options, const BakeBackends& backends) {
  Prepared prepared;
  const int k = db.shapeCount();
  const std::size_t driverValues = static_cast<std::size_t>(db.driverVertexCount()) * 3;
  const std::size_t drivenValues = static_cast<std::size_t>(db.drivenVertexCount()) * 3;
  const bool weighted = options.weightMode != WeightMode::kBind;
  const bool local = blendsLocally(options);
  const int threads = options.threads > 0 ? options.threads : hardwareThreads();
  prepared.driverShapes = db.driverShapes;
  if (!local) {
    // Local blending encodes the unaligned shapes (local coordinates ignore rigid motions).
    prepared.drivenShapes = db.drivenShapes;
  }
  if (weighted && options.align != AlignMode::kNone) {
    const std::string source =
        "--align-group '" + (options.alignGroup.empty() ? std::string("all") : options.alignGroup) +
        "' (driver mesh)";
    prepared.alignVertices = selectVertices(db.driverMesh, options.alignGroup, source);
    prepared.aligner = std::make_unique<RigidAligner>(db.driverMesh, db.driverMesh.positions.data(),
                                                      prepared.alignVertices, source);
    if (options.align == AlignMode::kRigid) {
      // Lock onto the part that moves rigidly across the database (the pelvis, not the legs).
      RigidityOptions rigidity;
      rigidity.threads = threads;
      prepared.aligner->weightByRigidity(db.driverShapes.data(), k, rigidity);
    }
    // The database in the same frame as the shots: each shape pair moves with the motion
    // that fits its driver shape to the rest driver.
    parallelFor(k, threads, [&](int i) {
      const RigidTransform motion = prepared.aligner->fit(&db.driverShapes[i * driverValues]);
      motion.apply(&db.driverShapes[i * driverValues], db.driverVertexCount(),
                   &prepared.driverShapes[i * driverValues]);
      if (!local) {
        motion.apply(&db.drivenShapes[i * drivenValues], db.drivenVertexCount(),
                     &prepared.drivenShapes[i * drivenValues]);
      }
    });
  }
  if (weighted && !options.regionsPath.empty()) {
    prepared.hasRegions = true;
    prepared.regions = readRegions(options.regionsPath, db.driverMesh, db.drivenMesh);
    for (const Region& region : prepared.regions.regions) {
      prepared.problems.push_back({region.name, region.driverVertices, nullptr});
    }
  } else {
    prepared.problems.push_back({"all", {}, nullptr});
  }
  for (WeightProblem& problem : prepared.problems) {
    problem.solver = std::make_unique<SimplexLeastSquares>(
        driverMatrix(prepared.driverShapes, k, db.driverVertexCount(), problem.rows));
  }
  if (local) {
    // Bind once at rest (mask respected), then store every shape as offsets in the local
    // frames of the same triangles at the same barycentric points.
    prepared.restHits.resize(static_cast<std::size_t>(db.drivenVertexCount()));
    backends.binding->closest(1, db.driverMesh.positions.data(), db.drivenMesh.positions.data(),
                              prepared.restHits.data());
    prepared.localShapes.resize(db.drivenShapes.size());
    parallelFor(k, threads, [&](int i) {
      encodeLocal(db.driverMesh, &db.driverShapes[i * driverValues], db.drivenVertexCount(),
                  &db.drivenShapes[i * drivenValues], prepared.restHits.data(),
                  &prepared.localShapes[i * drivenValues]);
    });
  }
  return prepared;
}

}  // namespace

BakeResult bake(const Database& db, const PointCacheReader& driver, const BakeBackends& backends,
                const BakeOptions& options, BakeObserver* observer) {
  const auto bakeStart = Clock::now();
  validate(db, driver, backends, options);
  StageBackend& stages = *backends.stages;
  const BindingMask mask =
      options.bindingMaskPath.empty()
          ? BindingMask::all(db.drivenVertexCount())
          : readBindingMask(options.bindingMaskPath, db.driverMesh, db.drivenMesh);
  const int threads = options.threads > 0 ? options.threads : hardwareThreads();
  const int k = db.shapeCount();
  const int vp = db.driverVertexCount();
  const int vd = db.drivenVertexCount();
  const std::size_t driverValues = static_cast<std::size_t>(vp) * 3;
  const std::size_t drivenValues = static_cast<std::size_t>(vd) * 3;
  const std::uint64_t topology = topologyHash(db.drivenMesh);
  const bool local = blendsLocally(options);
  const bool temporal = options.maxWeightChange > 0;

  BakeResult result;
  result.device = stages.name();
  if (options.correct || local) {
    backends.binding->setSurface(db.driverMesh, mask);
  }
  Prepared prepared = prepare(db, options, backends);
  result.settingsHash = settingsHashOf(db, options, mask, prepared);
  // Layers (mix, wind) after the correction; their settings join the hash and the EXR header.
  std::optional<LayerStack> layerStack;
  if (options.layers.hasMix() || options.layers.hasWind()) {
    LayerOptions layers = options.layers;
    layers.framesPerSecond = options.framesPerSecond;
    layerStack.emplace(layers, db.drivenMesh, *backends.layers);
    layerStack->checkFrames(options.frames);
    Hasher hasher;
    hasher.addValue(result.settingsHash);
    layerStack->addToHash(hasher);
    result.settingsHash = hasher.value();
  }
  const int regionCount = static_cast<int>(prepared.problems.size());
  const bool deviceProjection = !prepared.hasRegions;

  {
    // The backend's projection tables are those of the one QP on every (aligned) row.
    const SimplexLeastSquares& full =
        deviceProjection ? *prepared.problems.front().solver
                         : SimplexLeastSquares(driverMatrix(prepared.driverShapes, k, vp, {}));
    // The blended shapes are needed only on the backend from here on: hand them over.
    stages.upload(tablesFrom(db, full, prepared.driverShapes,
                             std::move(local ? prepared.localShapes : prepared.drivenShapes)));
  }
  std::unique_ptr<InsideAudit> inside;
  if (options.audit || options.resolve || options.layers.hasWind()) {
    backends.audit->setSurface(db.driverMesh, BindingMask::all(db.drivenVertexCount()));
  }
  if (options.audit) {
    inside = std::make_unique<InsideAudit>(db.driverMesh);
  }
  // The previous baked frame, for binding switches and jumps across chunk boundaries.
  std::vector<SurfaceHit> previousHits;
  std::vector<float> previousOutput;

  // Decide up front which frames to bake, so progress counts real work. A resume keeps an
  // existing output only if it decodes completely and matches (reuseProblem), and removes the
  // temporary files that killed runs left for this task's frames.
  std::vector<int> todo;
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
  for (std::size_t i = 0; i < result.frames.size(); ++i) {
    if (result.frames[i].skipped) {
      ++result.skipped;
    } else {
      todo.push_back(static_cast<int>(i));
    }
  }

  ExrWriteOptions exr;
  exr.width = options.exrWidth;
  exr.compression = options.compression;
  exr.topologyHash = topology;
  exr.settingsHash = result.settingsHash;
  exr.framesPerSecond = options.framesPerSecond;
  exr.syncToDisk = options.syncOutputs;
  if (layerStack) {
    exr.stringAttributes.emplace_back("dsLayers", layerStack->describe());
  }

  const int chunk = batchFrames(options, vp, vd);
  // The pipeline: while batch n runs its stages on the bake thread, the driver frames of batch
  // n + 1 are read on an I/O task and the EXRs of batch n - 1 are written on another (double
  // buffering: two output blocks take turns). Observer callbacks stay on the bake thread, in
  // frame order, after a batch's files are complete.
  std::vector<int> todoFrames;
  for (int index : todo) {
    todoFrames.push_back(result.frames[index].frame);
  }
  // Warm-up frames come from what the cache holds (a warm-up longer than the cache costs
  // nothing more).
  const std::vector<int> cacheFrames = temporal ? driver.frames() : std::vector<int>();
  auto readBatch = [&driver, &todoFrames, &cacheFrames, &options, temporal, chunk, threads,
                    driverValues](std::size_t begin) {
    const auto readStart = Clock::now();
    BatchInput in;
    const int count = static_cast<int>(std::min<std::size_t>(chunk, todoFrames.size() - begin));
    // Frames solved for this batch: the temporal warm-up (driver-cache frames just before the
    // batch, solved but not written), then the batch itself.
    if (temporal) {
      const int first = todoFrames[begin];
      const long long from = static_cast<long long>(first) - options.temporalWarmup;
      const auto warmBegin = std::lower_bound(
          cacheFrames.begin(), cacheFrames.end(), from,
          [](int frame, long long value) { return static_cast<long long>(frame) < value; });
      in.solveFrames.assign(warmBegin,
                            std::lower_bound(cacheFrames.begin(), cacheFrames.end(), first));
    }
    in.warm = static_cast<int>(in.solveFrames.size());
    in.solveFrames.insert(in.solveFrames.end(), todoFrames.begin() + begin,
                          todoFrames.begin() + begin + count);
    const int n = static_cast<int>(in.solveFrames.size());
    in.driverAll.resize(n * driverValues);
    parallelFor(n, threads, [&](int i) {
      const int frame = in.solveFrames[i];
      float* xyz = &in.driverAll[i * driverValues];
      driver.readFrame(frame, xyz);
      for (std::size_t j = 0; j < driverValues; ++j) {
        if (!std::isfinite(xyz[j])) {
          DS_THROW(kInput, "driver cache '", driver.path(), "' frame ", frame, " vertex ", j / 3,
                   " is not a finite number; fix the cache or leave the frame out of --frames");
        }
      }
    });
    in.seconds = secondsSince(readStart);
    return in;
  };
  std::future<BatchInput> nextInput;
  std::array<std::vector<float>, 2> outputBlocks;
  struct PendingWrite {
    std::future<double> seconds;
    std::size_t begin = 0;
    int count = 0;
    const float* positions = nullptr;
    Clock::time_point started;
  };
  std::optional<PendingWrite> pendingWrite;
  // Waits for the batch being written (rethrowing its error) and reports its frames.
  auto finishWrite = [&]() {
    if (!pendingWrite) {
      return;
    }
    PendingWrite done = std::move(*pendingWrite);
    pendingWrite.reset();
    result.times.write += done.seconds.get();
    std::vector<const FrameRecord*> records;
    for (int i = 0; i < done.count; ++i) {
      records.push_back(&result.frames[todo[done.begin + i]]);
    }
    if (observer != nullptr) {
      observer->batchBaked(records, done.positions);
    }
    const double perFrame = secondsSince(done.started) / done.count;
    for (const FrameRecord* record : records) {
      ++result.baked;
      if (observer != nullptr) {
        observer->frameDone(*record, perFrame);
      }
    }
  };

  std::vector<float> alignedAll, projections, norms, weights, blendedRegions, blendedDriverRegions,
      driven, blendedDriver;
  std::vector<SurfaceHit> hits, auditHits;
  std::vector<RigidTransform> motions;
  std::vector<SimplexSolution> solutions;
  std::vector<int> moved;
  const Eigen::MatrixXd shapes = options.weightMode == WeightMode::kNearest
                                     ? driverMatrix(prepared.driverShapes, k, vp, {})
                                     : Eigen::MatrixXd();
  result.times.setup = secondsSince(bakeStart);
  std::size_t batchIndex = 0;
  for (std::size_t begin = 0; begin < todo.size();
       begin += static_cast<std::size_t>(chunk), ++batchIndex) {
    if (observer != nullptr && observer->stopRequested()) {
      finishWrite();
      DS_THROW(kInterrupted, "stopped after ", result.baked, " of ", todo.size(),
               " frames; finished frames are complete, rerun with --skip-existing to resume");
    }
    const int count = static_cast<int>(std::min<std::size_t>(chunk, todo.size() - begin));
    auto frameRecord = [&](int i) -> FrameRecord& { return result.frames[todo[begin + i]]; };
    const auto chunkStart = Clock::now();

    // This batch's driver frames (read ahead during the previous batch), and the read-ahead
    // of the next one.
    auto start = Clock::now();
    BatchInput input = nextInput.valid() ? nextInput.get() : readBatch(begin);
    const double waited = secondsSince(start);
    if (begin + chunk < todo.size()) {
      nextInput = std::async(std::launch::async, readBatch, begin + chunk);
    }
    result.times.read += input.seconds;
    result.times.readWait += waited;
    const std::vector<int>& solveFrames = input.solveFrames;
    const std::vector<float>& driverAll = input.driverAll;
    const int warm = input.warm;
    const int n = warm + count;
    const float* driverBlock = &driverAll[warm * driverValues];

    // Rigid alignment to the rest driver (the weights and the blend live in that frame).
    start = Clock::now();
    const float* alignedFrames = driverAll.data();
    if (prepared.aligner) {
      alignedAll.resize(driverAll.size());
      motions.resize(n);
      parallelFor(n, threads, [&](int i) {
        motions[i] = prepared.aligner->fit(&driverAll[i * driverValues]);
        motions[i].apply(&driverAll[i * driverValues], vp, &alignedAll[i * driverValues]);
      });
      alignedFrames = alignedAll.data();
      for (int i = 0; i < count; ++i) {
        const RigidTransform& motion = motions[warm + i];
        FrameRecord& record = frameRecord(i);
        record.alignRotation.clear();
        for (int r = 0; r < 3; ++r) {
          for (int c = 0; c < 3; ++c) {
            record.alignRotation.push_back(motion.rotation(r, c));
          }
        }
        record.alignTranslation.assign(motion.translation.data(), motion.translation.data() + 3);
      }
    }
    const float* alignedBlock = alignedFrames + warm * driverValues;
    result.times.align += secondsSince(start);

    // Projections p = M^T (b - m) per frame and weight problem: one device launch for the
    // whole-driver QP, the host for region rows.
    start = Clock::now();
    projections.assign(static_cast<std::size_t>(n) * regionCount * (k - 1), 0.0f);
    norms.assign(static_cast<std::size_t>(n) * regionCount * 2, 0.0f);
    std::vector<double> hostProjections;
    if (options.weightMode == WeightMode::kQp) {
      if (deviceProjection) {
        stages.project(n, alignedFrames, projections.data(), norms.data());
      } else {
        hostProjections.assign(static_cast<std::size_t>(n) * regionCount * (k + 1), 0.0);
        parallelFor(n * regionCount, threads, [&](int item) {
          const int i = item / regionCount, r = item % regionCount;
          const WeightProblem& problem = prepared.problems[r];
          const float* frame = alignedFrames + i * driverValues;
          Eigen::VectorXd b(static_cast<Eigen::Index>(problem.rows.size()) * 3);
          for (std::size_t j = 0; j < problem.rows.size(); ++j) {
            for (int c = 0; c < 3; ++c) {
              b(static_cast<Eigen::Index>(3 * j + c)) = frame[3 * problem.rows[j] + c];
            }
          }
          const Eigen::VectorXd d = b - problem.solver->center();
          double* out = &hostProjections[static_cast<std::size_t>(item) * (k + 1)];
          Eigen::Map<Eigen::VectorXd>(out, k - 1) = problem.solver->basis().transpose() * d;
          out[k - 1] = d.squaredNorm();
          out[k] = b.squaredNorm();
        });
      }
    }
    result.times.project += secondsSince(start);

    start = Clock::now();
    solutions.assign(static_cast<std::size_t>(n) * regionCount, SimplexSolution{});
    auto solveOne = [&](int i, int r) {
      const int item = i * regionCount + r;
      Eigen::VectorXd p(k - 1);
      double rr = 0, bb = 0;
      if (deviceProjection) {
        p = Eigen::Map<const Eigen::VectorXf>(&projections[i * (k - 1)], k - 1).cast<double>();
        rr = norms[2 * i];
        bb = norms[2 * i + 1];
      } else {
        const double* in = &hostProjections[static_cast<std::size_t>(item) * (k + 1)];
        p = Eigen::Map<const Eigen::VectorXd>(in, k - 1);
        rr = in[k - 1];
        bb = in[k];
      }
      const SimplexLeastSquares& solver = *prepared.problems[r].solver;
      try {
        if (temporal && i > 0) {
          const Eigen::VectorXd& previous = solutions[item - regionCount].weights;
          const Eigen::VectorXd lower =
              (previous.array() - options.maxWeightChange).cwiseMax(0.0).matrix();
          const Eigen::VectorXd upper =
              (previous.array() + options.maxWeightChange).cwiseMin(1.0).matrix();
          solutions[item] = solver.solveProjected(p, rr, bb, lower, upper);
        } else {
          solutions[item] = solver.solveProjected(p, rr, bb);
        }
      } catch (const Error& error) {
        DS_THROW(kNumerical, "frame ", solveFrames[i],
                 regionCount > 1 ? " region '" + prepared.problems[r].name + "'" : std::string(),
                 ": ", error.what());
      }
    };
    if (options.weightMode == WeightMode::kQp) {
      if (temporal) {
        // Each frame's bounds come from the frame before it: in order within the batch.
        for (int i = 0; i < n; ++i) {
          parallelFor(regionCount, std::min(threads, regionCount), [&](int r) { solveOne(i, r); });
        }
      } else {
        parallelFor(n * regionCount, threads,
                    [&](int item) { solveOne(item / regionCount, item % regionCount); });
      }
    }
    weights.assign(static_cast<std::size_t>(count) * regionCount * k, 0.0f);
    parallelFor(options.weightMode == WeightMode::kBind ? 0 : count, threads, [&](int i) {
      FrameRecord& record = frameRecord(i);
      record.weights.clear();
      record.atZero.clear();
      record.atOne.clear();
      record.relativeResidual = record.kktResidual = 0.0;
      record.iterations = 0;
      if (options.weightMode == WeightMode::kQp) {
        for (int r = 0; r < regionCount; ++r) {
          const SimplexSolution& s = solutions[(warm + i) * regionCount + r];
          record.weights.insert(record.weights.end(), s.weights.data(), s.weights.data() + k);
          for (int z : s.atZero) {
            record.atZero.push_back(r * k + z);
          }
          for (int o : s.atOne) {
            record.atOne.push_back(r * k + o);
          }
          record.relativeResidual = std::max(record.relativeResidual, s.relativeResidual);
          record.kktResidual = std::max(record.kktResidual, s.kktResidual);
          record.iterations += s.iterations;
        }
      } else {
        const Eigen::VectorXd b =
            Eigen::Map<const Eigen::VectorXf>(alignedBlock + i * driverValues, driverValues)
                .cast<double>();
        Eigen::Index best = 0;
        const double distance = (shapes.colwise() - b).colwise().squaredNorm().minCoeff(&best);
        record.weights.assign(k, 0.0);
        record.weights[best] = 1.0;
        record.relativeResidual = b.norm() > 0 ? std::sqrt(distance) / b.norm() : 0.0;
      }
      for (std::size_t s = 0; s < record.weights.size(); ++s) {
        weights[i * regionCount * k + s] = static_cast<float>(record.weights[s]);
      }
    });
    result.times.weights += secondsSince(start);

    // Blend (per region), then mix the regions per vertex with their partition of unity.
    start = Clock::now();
    const bool needDriver = !local && options.correct;
    driven.resize(count * drivenValues);
    blendedDriver.resize(needDriver ? count * driverValues : 0);
    if (options.weightMode == WeightMode::kBind) {
      // The rest shapes stand in for the blend: every frame binds the rest cloth to the rest
      // driver and carries it to the shot's pose.
      for (int i = 0; i < count; ++i) {
        std::copy_n(db.drivenMesh.positions.data(), drivenValues, &driven[i * drivenValues]);
        std::copy_n(db.driverMesh.positions.data(), driverValues, &blendedDriver[i * driverValues]);
      }
    } else if (regionCount == 1) {
      stages.blend(count, weights.data(), driven.data(),
                   needDriver ? blendedDriver.data() : nullptr);
    } else {
      blendedRegions.resize(static_cast<std::size_t>(count) * regionCount * drivenValues);
      blendedDriverRegions.resize(needDriver ? blendedRegions.size() / drivenValues * driverValues
                                             : 0);
      stages.blend(count * regionCount, weights.data(), blendedRegions.data(),
                   needDriver ? blendedDriverRegions.data() : nullptr);
      auto mix = [&](const std::vector<float>& perRegion, const std::vector<float>& weightsOf,
                     int vertices, std::vector<float>& out) {
        const std::size_t values = static_cast<std::size_t>(vertices) * 3;
        parallelFor(count, threads, [&](int i) {
          for (int v = 0; v < vertices; ++v) {
            double sum[3] = {0, 0, 0};
            for (int r = 0; r < regionCount; ++r) {
              const float phi = weightsOf[static_cast<std::size_t>(r) * vertices + v];
              const float* x =
                  &perRegion[(static_cast<std::size_t>(i) * regionCount + r) * values + 3 * v];
              for (int c = 0; c < 3; ++c) {
                sum[c] += double(phi) * x[c];
              }
            }
            for (int c = 0; c < 3; ++c) {
              out[i * values + 3 * v + c] = static_cast<float>(sum[c]);
            }
          }
        });
      };
      mix(blendedRegions, prepared.regions.drivenMix, vd, driven);
      if (needDriver) {
        mix(blendedDriverRegions, prepared.regions.driverMix, vp, blendedDriver);
      }
    }
    result.times.blend += secondsSince(start);

    // Correction: bind D~ to P~ (exact closest triangles) and carry it to the shot's driver;
    // local blending rebuilds the blended offsets on the shot's driver instead.
    start = Clock::now();
    const std::size_t points = static_cast<std::size_t>(count) * vd;
    std::vector<float>& output = outputBlocks[batchIndex % 2];
    output.resize(count * drivenValues);
    if (local) {
      backends.binding->rebuild(count, prepared.restHits.data(), driverBlock, driven.data(),
                                output.data());
    } else if (options.correct) {
      hits.resize(points);
      backends.binding->closest(count, blendedDriver.data(), driven.data(), hits.data());
      // P~ is in the aligned frame, the shot's driver in world space: the transfer carries the
      // cloth through the inverse alignment too.
      backends.binding->transfer(count, hits.data(), blendedDriver.data(), driverBlock,
                                 driven.data(), output.data());
    } else if (prepared.aligner) {
      parallelFor(count, threads, [&](int i) {
        motions[warm + i].applyInverse(&driven[i * drivenValues], vd, &output[i * drivenValues]);
      });
    } else {
      std::copy(driven.begin(), driven.end(), output.begin());
    }
    const float* final = output.data();
    result.times.correct += secondsSince(start);

    // Audit of the blend (before any correction), in the frame it was blended in.
    start = Clock::now();
    auditHits.resize(points);
    auto countInside = [&](const float* poses, const float* cloth, int FrameRecord::*field) {
      backends.audit->closest(count, poses, cloth, auditHits.data());
      parallelFor(count, threads, [&](int i) {
        frameRecord(i).*field = inside->countInside(poses + i * driverValues, vd,
                                                    cloth + i * drivenValues, &auditHits[i * vd]);
      });
    };
    if (options.audit && !local) {
      countInside(alignedBlock, driven.data(), &FrameRecord::insideBefore);
    }
    result.times.audit += secondsSince(start);

    // Penetration resolution on the shot's driver (every triangle), with counts around it.
    start = Clock::now();
    if (options.resolve) {
      if (options.audit) {
        countInside(driverBlock, final, &FrameRecord::insideCorrected);
      } else {
        backends.audit->closest(count, driverBlock, final, auditHits.data());
      }
      moved.assign(count, 0);
      backends.audit->resolve(count, driverBlock, auditHits.data(),
                              static_cast<float>(options.skinOffset), output.data(), moved.data());
      for (int i = 0; i < count; ++i) {
        frameRecord(i).resolved = moved[i];
      }
    }
    result.times.resolve += secondsSince(start);

    // Layers: the mix with another cache, then wind limited by each vertex's clearance from
    // the shot's driver (exact closest points, every triangle).
    start = Clock::now();
    if (layerStack) {
      std::vector<float> clearance;
      if (options.layers.hasWind()) {
        backends.audit->closest(count, driverBlock, output.data(), auditHits.data());
        clearance.resize(points);
        for (std::size_t i = 0; i < points; ++i) {
          clearance[i] = std::sqrt(auditHits[i].distance2);
        }
      }
      layerStack->apply(count, &todoFrames[begin], output.data(),
                        clearance.empty() ? nullptr : clearance.data());
    }
    result.times.layers += secondsSince(start);

    start = Clock::now();
    if (options.audit) {
      // Recount after the resolution when it moved something or layers changed the cloth.
      const bool anyMoved = (options.resolve && std::any_of(moved.begin(), moved.end(),
                                                            [](int m) { return m > 0; })) ||
                            layerStack.has_value();
      if (!options.resolve || anyMoved) {
        countInside(driverBlock, final, &FrameRecord::insideAfter);
      }
      for (int i = 0; i < count; ++i) {
        FrameRecord& record = frameRecord(i);
        if (options.resolve && !anyMoved) {
          record.insideAfter = record.insideCorrected;
        }
        if (!options.resolve) {
          record.insideCorrected = record.insideAfter;
        }
      }
      // Switches and jumps against the previous baked frame, in bake order.
      for (int i = 0; i < count; ++i) {
        FrameRecord& record = frameRecord(i);
        const float* now = final + i * drivenValues;
        const float* before = i > 0                    ? final + (i - 1) * drivenValues
                              : previousOutput.empty() ? nullptr
                                                       : previousOutput.data();
        if (before != nullptr) {
          record.maxJump = 0.0;
          for (int v = 0; v < vd; ++v) {
            const double dx = now[3 * v] - before[3 * v], dy = now[3 * v + 1] - before[3 * v + 1],
                         dz = now[3 * v + 2] - before[3 * v + 2];
            const double jump = std::sqrt(dx * dx + dy * dy + dz * dz);
            if (jump > record.maxJump) {
              record.maxJump = jump;
              record.maxJumpVertex = v;
            }
          }
        }
        if (options.correct && !local) {
          const SurfaceHit* nowHits = &hits[i * vd];
          const SurfaceHit* beforeHits = i > 0                  ? &hits[(i - 1) * vd]
                                         : previousHits.empty() ? nullptr
                                                                : previousHits.data();
          if (beforeHits != nullptr) {
            record.bindingSwitches = 0;
            for (int v = 0; v < vd; ++v) {
              record.bindingSwitches += nowHits[v].triangle != beforeHits[v].triangle ? 1 : 0;
            }
          }
        }
      }
      previousOutput.assign(final + (count - 1) * drivenValues, final + count * drivenValues);
      if (options.correct && !local) {
        previousHits.assign(hits.end() - vd, hits.end());
      }
    }
    result.times.audit += secondsSince(start);

    // Hand the batch to the writer once the previous one is on disk; its buffer (the other
    // output block) is then free for the next batch.
    start = Clock::now();
    finishWrite();
    result.times.writeWait += secondsSince(start);
    std::vector<std::string> paths;
    std::vector<int> frameNumbers;
    for (int i = 0; i < count; ++i) {
      paths.push_back(frameRecord(i).output);
      frameNumbers.push_back(frameRecord(i).frame);
    }
    auto writeBatch = [paths = std::move(paths), frameNumbers = std::move(frameNumbers), final, exr,
                       threads, vd, drivenValues]() {
      const auto writeStart = Clock::now();
      parallelFor(static_cast<int>(paths.size()), threads, [&](int i) {
        ExrWriteOptions frameExr = exr;
        frameExr.frame = frameNumbers[i];
        writePointCacheExr(paths[i], vd, final + i * drivenValues, nullptr, frameExr);
      });
      return secondsSince(writeStart);
    };
    pendingWrite = PendingWrite{std::async(std::launch::async, std::move(writeBatch)), begin, count,
                                final, chunkStart};
  }
  finishWrite();
  result.times.total = secondsSince(bakeStart);
  if (!options.reportPath.empty()) {
    writeReport(options.reportPath, db, driver, options, prepared,
                layerStack ? layerStack->describe() : std::string("{}"), result);
  }
  return result;
}

}  // namespace drivenshape
