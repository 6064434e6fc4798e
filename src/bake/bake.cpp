#include <drivenshape/bake.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <thread>

#include <drivenshape/atomic_file.h>
#include <drivenshape/error.h>
#include <drivenshape/frames.h>
#include <drivenshape/hash.h>
#include <drivenshape/parallel.h>
#include <drivenshape/qp.h>
#include <drivenshape/version.h>

namespace drivenshape {
namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

Eigen::MatrixXd driverMatrix(const Database& db) {
  const int k = db.shapeCount();
  const Eigen::Index n = static_cast<Eigen::Index>(db.driverVertexCount()) * 3;
  Eigen::MatrixXd a(n, k);
  for (int i = 0; i < k; ++i) {
    a.col(i) = Eigen::Map<const Eigen::VectorXf>(&db.driverShapes[i * n], n).cast<double>();
  }
  return a;
}

ShapeTables tablesFrom(const Database& db, const SimplexLeastSquares& solver) {
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
  tables.driverShapes = db.driverShapes;
  tables.drivenShapes = db.drivenShapes;
  return tables;
}

int hardwareThreads() {
  return std::max(1u, std::thread::hardware_concurrency());
}

std::uint64_t settingsHashOf(const Database& db, const BakeOptions& options,
                             const BindingMask& mask) {
  Hasher hasher;
  hasher.addValue(db.contentHash());
  hasher.addValue(static_cast<int>(options.weightMode));
  hasher.addValue(options.exrWidth);
  hasher.addValue(options.correct);
  for (int c = 0; c < mask.classCount(); ++c) {
    hasher.add(mask.classTriangles(c).data(), mask.classTriangles(c).size() * sizeof(int));
  }
  hasher.add(mask.vertexClasses().data(), mask.vertexClasses().size() * sizeof(int));
  hasher.addString(kVersion);
  return hasher.value();
}

/// True if `path` holds a complete EXR written for this database and these settings.
bool isReusableOutput(const std::string& path, std::uint64_t topology, std::uint64_t settings,
                      int frame) {
  if (!isCompleteExr(path)) {
    return false;
  }
  try {
    const ExrPointCacheInfo info = readPointCacheExrInfo(path);
    return info.topologyHash == topology && info.settingsHash == settings && info.frame == frame;
  } catch (const Error&) {
    return false;
  }
}

void validate(const Database& db, const PointCacheReader& driver, const BakeBackends& backends,
              const BakeOptions& options) {
  if (backends.stages == nullptr || (options.correct && backends.binding == nullptr) ||
      (options.audit && backends.audit == nullptr)) {
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
                 const BakeOptions& options, const BakeResult& result) {
  using nlohmann::json;
  json frames = json::array();
  for (const FrameRecord& record : result.frames) {
    json entry{{"frame", record.frame}, {"output", record.output}, {"skipped", record.skipped}};
    if (!record.skipped) {
      entry["relative_residual"] = record.relativeResidual;
      entry["kkt_residual"] = record.kktResidual;
      entry["iterations"] = record.iterations;
      entry["active_at_zero"] = record.atZero;
      entry["active_at_one"] = record.atOne;
      entry["weights"] = record.weights;
      if (record.insideAfter >= 0) {
        entry["inside_before"] = record.insideBefore;
        entry["inside_after"] = record.insideAfter;
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
        {"batch", options.chunkSize},
        {"compression", exrCompressionName(options.compression)},
        {"exr_width", options.exrWidth}}},
      {"baked", result.baked},
      {"skipped", result.skipped},
      {"seconds",
       {{"read", result.times.read},
        {"project", result.times.project},
        {"weights", result.times.weights},
        {"blend", result.times.blend},
        {"correct", result.times.correct},
        {"audit", result.times.audit},
        {"write", result.times.write},
        {"total", result.times.total}}},
      {"frames", frames},
  };
  writeFileAtomically(path, report.dump(1) + "\n");
}

}  // namespace

ShapeTables makeShapeTables(const Database& database) {
  return tablesFrom(database, SimplexLeastSquares(driverMatrix(database)));
}

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
  const std::size_t driverValues = static_cast<std::size_t>(db.driverVertexCount()) * 3;
  const std::size_t drivenValues = static_cast<std::size_t>(db.drivenVertexCount()) * 3;
  const std::uint64_t topology = topologyHash(db.drivenMesh);

  BakeResult result;
  result.device = stages.name();
  result.settingsHash = settingsHashOf(db, options, mask);

  const Eigen::MatrixXd shapes = driverMatrix(db);
  const SimplexLeastSquares solver(shapes);
  stages.upload(tablesFrom(db, solver));
  if (options.correct) {
    backends.binding->setSurface(db.driverMesh, mask);
  }
  std::unique_ptr<InsideAudit> inside;
  if (options.audit) {
    backends.audit->setSurface(db.driverMesh, BindingMask::all(db.drivenVertexCount()));
    inside = std::make_unique<InsideAudit>(db.driverMesh);
  }
  // The previous baked frame, for binding switches and jumps across chunk boundaries.
  std::vector<SurfaceHit> previousHits;
  std::vector<float> previousOutput;

  // Decide up front which frames to bake, so progress counts real work.
  std::vector<int> todo;
  for (int frame : options.frames) {
    FrameRecord record;
    record.frame = frame;
    record.output = expandFramePattern(options.outputPattern, frame);
    if (options.skipExisting &&
        isReusableOutput(record.output, topology, result.settingsHash, frame)) {
      record.skipped = true;
      ++result.skipped;
    } else {
      todo.push_back(static_cast<int>(result.frames.size()));
    }
    result.frames.push_back(std::move(record));
  }

  ExrWriteOptions exr;
  exr.width = options.exrWidth;
  exr.compression = options.compression;
  exr.topologyHash = topology;
  exr.settingsHash = result.settingsHash;
  exr.framesPerSecond = options.framesPerSecond;

  const int chunk = options.chunkSize;
  std::vector<float> driverBlock, projections, norms, weights, driven, blendedDriver, output;
  std::vector<SurfaceHit> hits, auditHits;
  for (std::size_t begin = 0; begin < todo.size(); begin += static_cast<std::size_t>(chunk)) {
    if (observer != nullptr && observer->stopRequested()) {
      DS_THROW(kInterrupted, "stopped after ", result.baked, " of ", todo.size(),
               " frames; finished frames are complete, rerun with --skip-existing to resume");
    }
    const int count = static_cast<int>(std::min<std::size_t>(chunk, todo.size() - begin));
    auto frameRecord = [&](int i) -> FrameRecord& { return result.frames[todo[begin + i]]; };
    const auto chunkStart = Clock::now();

    auto start = Clock::now();
    driverBlock.resize(count * driverValues);
    parallelFor(count, threads, [&](int i) {
      const int frame = frameRecord(i).frame;
      float* xyz = &driverBlock[i * driverValues];
      driver.readFrame(frame, xyz);
      for (std::size_t j = 0; j < driverValues; ++j) {
        if (!std::isfinite(xyz[j])) {
          DS_THROW(kInput, "driver cache '", driver.path(), "' frame ", frame, " vertex ", j / 3,
                   " is not a finite number; fix the cache or leave the frame out of --frames");
        }
      }
    });
    result.times.read += secondsSince(start);

    start = Clock::now();
    projections.resize(static_cast<std::size_t>(count) * (k - 1));
    norms.resize(static_cast<std::size_t>(count) * 2);
    if (options.weightMode == WeightMode::kQp) {
      stages.project(count, driverBlock.data(), projections.data(), norms.data());
    }
    result.times.project += secondsSince(start);

    start = Clock::now();
    weights.assign(static_cast<std::size_t>(count) * k, 0.0f);
    parallelFor(options.weightMode == WeightMode::kBind ? 0 : count, threads, [&](int i) {
      FrameRecord& record = frameRecord(i);
      if (options.weightMode == WeightMode::kQp) {
        const Eigen::VectorXd p =
            Eigen::Map<const Eigen::VectorXf>(&projections[i * (k - 1)], k - 1).cast<double>();
        SimplexSolution s;
        try {
          s = solver.solveProjected(p, norms[2 * i], norms[2 * i + 1]);
        } catch (const Error& error) {
          DS_THROW(kNumerical, "frame ", record.frame, ": ", error.what());
        }
        record.weights.assign(s.weights.data(), s.weights.data() + k);
        record.atZero = s.atZero;
        record.atOne = s.atOne;
        record.relativeResidual = s.relativeResidual;
        record.kktResidual = s.kktResidual;
        record.iterations = s.iterations;
      } else {
        const Eigen::VectorXd b =
            Eigen::Map<const Eigen::VectorXf>(&driverBlock[i * driverValues], driverValues)
                .cast<double>();
        Eigen::Index best = 0;
        const double distance = (shapes.colwise() - b).colwise().squaredNorm().minCoeff(&best);
        record.weights.assign(k, 0.0);
        record.weights[best] = 1.0;
        record.relativeResidual = b.norm() > 0 ? std::sqrt(distance) / b.norm() : 0.0;
      }
      for (int s = 0; s < k; ++s) {
        weights[i * k + s] = static_cast<float>(record.weights[s]);
      }
    });
    result.times.weights += secondsSince(start);

    start = Clock::now();
    driven.resize(count * drivenValues);
    blendedDriver.resize(options.correct ? count * driverValues : 0);
    if (options.weightMode == WeightMode::kBind) {
      // The rest shapes stand in for the blend: every frame binds the rest cloth to the rest
      // driver and carries it to the shot's pose.
      for (int i = 0; i < count; ++i) {
        std::copy_n(db.drivenMesh.positions.data(), drivenValues, &driven[i * drivenValues]);
        std::copy_n(db.driverMesh.positions.data(), driverValues, &blendedDriver[i * driverValues]);
      }
    } else {
      stages.blend(count, weights.data(), driven.data(),
                   options.correct ? blendedDriver.data() : nullptr);
    }
    result.times.blend += secondsSince(start);

    // Correction: bind D~ to P~ (exact closest triangles), carry it to P_new.
    start = Clock::now();
    const std::size_t points = static_cast<std::size_t>(count) * db.drivenVertexCount();
    const float* final = driven.data();
    if (options.correct) {
      hits.resize(points);
      output.resize(count * drivenValues);
      backends.binding->closest(count, blendedDriver.data(), driven.data(), hits.data());
      backends.binding->transfer(count, hits.data(), blendedDriver.data(), driverBlock.data(),
                                 driven.data(), output.data());
      final = output.data();
    }
    result.times.correct += secondsSince(start);

    start = Clock::now();
    if (options.audit) {
      auditHits.resize(points);
      const int vd = db.drivenVertexCount();
      auto countInside = [&](const float* cloth, bool after) {
        backends.audit->closest(count, driverBlock.data(), cloth, auditHits.data());
        parallelFor(count, threads, [&](int i) {
          const int inside_count = inside->countInside(
              &driverBlock[i * driverValues], vd, cloth + i * drivenValues, &auditHits[i * vd]);
          (after ? frameRecord(i).insideAfter : frameRecord(i).insideBefore) = inside_count;
        });
      };
      countInside(driven.data(), false);
      if (options.correct) {
        countInside(final, true);
      } else {
        for (int i = 0; i < count; ++i) {
          frameRecord(i).insideAfter = frameRecord(i).insideBefore;
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
        if (options.correct) {
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
      if (options.correct) {
        previousHits.assign(hits.end() - vd, hits.end());
      }
    }
    result.times.audit += secondsSince(start);

    start = Clock::now();
    parallelFor(count, threads, [&](int i) {
      FrameRecord& record = frameRecord(i);
      ExrWriteOptions frameExr = exr;
      frameExr.frame = record.frame;
      writePointCacheExr(record.output, db.drivenVertexCount(), final + i * drivenValues, nullptr,
                         frameExr);
    });
    result.times.write += secondsSince(start);

    if (observer != nullptr) {
      std::vector<const FrameRecord*> records;
      for (int i = 0; i < count; ++i) {
        records.push_back(&frameRecord(i));
      }
      observer->batchBaked(records, final);
    }
    const double perFrame = secondsSince(chunkStart) / count;
    for (int i = 0; i < count; ++i) {
      ++result.baked;
      if (observer != nullptr) {
        observer->frameDone(frameRecord(i), perFrame);
      }
    }
  }
  result.times.total = secondsSince(bakeStart);
  if (!options.reportPath.empty()) {
    writeReport(options.reportPath, db, driver, options, result);
  }
  return result;
}

}  // namespace drivenshape
