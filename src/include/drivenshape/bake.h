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
#include <drivenshape/stages.h>

namespace drivenshape {

struct BakeOptions {
  std::vector<int> frames;    ///< frames of the driver cache to bake
  std::string outputPattern;  ///< EXR sequence with a frame token, e.g. out/cloth.####.exr
  std::string reportPath;     ///< per-bake JSON report; empty = none
  /// Frames per kernel launch (`--batch`); lowered for large meshes so that a batch's buffers
  /// stay within kBatchMemoryBudget, except with the temporal bound (which depends on it).
  int chunkSize = 64;
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

  // ---- Fidelity (issue 4); see docs/method.md for how the defaults were chosen. ----

  /// Rigid alignment: each shot driver frame is fitted (Kabsch, no scale; weighted by
  /// rigidity (kRigid) or area (kRigidAll)) to the database's rest driver on the vertices
  /// named by `alignGroup`; so is every database shape (at bake start, driver and driven with
  /// the same motion, so databases built by earlier versions keep working). Weights and blends are
  /// computed in that frame and the result goes back through the inverse motion (the correction
  /// rebuilds directly on the shot's world-space driver).
  AlignMode align = AlignMode::kRigid;
  /// Driver vertices of the fit: comma-separated `g` group names and/or vertex indices and
  /// ranges ("0-99,250"); empty or "all" = every vertex (see selectVertices).
  std::string alignGroup;
  /// Where the shapes are blended. Local blending rebuilds the offsets on the shot's driver,
  /// which is the correction: with `correct` off (blend only) or the bind baseline the bake
  /// blends world positions whatever this says (see blendsLocally).
  BlendMode blend = BlendMode::kLocal;
  /// Penetration resolution after the correction: cloth vertices inside the shot's driver or
  /// closer than `skinOffset` (scene units) move to skinOffset along the pseudo-normal at
  /// their exact closest point on the driver (every triangle, no mask).
  bool resolve = true;
  double skinOffset = 0.002;
  /// Region file (see readRegions); empty = one QP on every driver row.
  std::string regionsPath;
  /// Temporal stability: |w_t - w_{t-1}| <= maxWeightChange per shape (0 = off). Frames are
  /// solved in order within each launch batch (`chunkSize` frames); before each batch,
  /// `temporalWarmup` driver-cache frames preceding its first frame are solved (the first of
  /// them without the bound) but not written. The output therefore depends on chunkSize and
  /// temporalWarmup, never on the thread count, and a farm chunk whose size is a multiple of
  /// chunkSize reproduces the single bake exactly.
  double maxWeightChange = 0.0;
  int temporalWarmup = 8;
  /// Layers after the correction and resolution (DESIGN.md section 3 step 7): a mix with
  /// another cache of the cloth, procedural wind. Off by default. Recorded in the settings hash,
  /// the report and the EXR header (`dsLayers`).
  LayerOptions layers;
  /// fsync every output EXR before its atomic rename (`--sync`). Off by default: the rename
  /// alone already means readers never see a partial file, and a file cut short by a power
  /// loss is rebaked by --skip-existing; the fsync costs a disk (or NFS) round trip per frame.
  bool syncOutputs = false;
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

/// Memory that one launch batch's frame blocks may take; larger meshes get smaller batches
/// (see BakeOptions::chunkSize).
inline constexpr std::size_t kBatchMemoryBudget = std::size_t(768) << 20;

struct BakeResult {
  std::vector<FrameRecord> frames;
  StageTimes times;
  std::string device;
  std::uint64_t settingsHash = 0;
  int baked = 0;
  int skipped = 0;
  int staleTempFilesRemoved = 0;  ///< by a resume (options.skipExisting), of its own frames
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
BakeResult bake(const Database& database, const PointCacheReader& driver, Device& device,
                const BakeOptions& options, BakeObserver* observer = nullptr);

/// The evaluator settings of a bake: the options' values, with the binding mask, the regions
/// and the layers loaded from the files they name (Error(kInput) naming the file).
EvaluatorSettings evaluatorSettings(const Database& database, const BakeOptions& options);

/// Flat tables for the stage backends, built from a database (projection basis, shapes).
ShapeTables makeShapeTables(const Database& database);

}  // namespace drivenshape
