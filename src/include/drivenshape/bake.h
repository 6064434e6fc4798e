#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <drivenshape/correction.h>
#include <drivenshape/database.h>
#include <drivenshape/layers.h>
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

/// Whether shot frames are rigidly aligned to the database before the weights are solved.
enum class AlignMode {
  kNone,     ///< the talk: weights compare world positions
  kRigid,    ///< each shot frame (and each database shape) is fitted to the rest driver first,
             ///< weighted by how rigidly each vertex moves across the database's driver shapes
             ///< (RigidAligner::weightByRigidity): the fit follows the pelvis, not the legs
  kRigidAll  ///< the same fit weighted by area only: every selected vertex counts alike
};

/// The `--align` spelling of a mode, as written in the bake report.
inline const char* alignModeName(AlignMode mode) {
  switch (mode) {
    case AlignMode::kNone:
      return "none";
    case AlignMode::kRigid:
      return "rigid";
    case AlignMode::kRigidAll:
      return "rigid-all";
  }
  return "?";
}

/// Where the database shapes are blended.
enum class BlendMode {
  kWorld,  ///< the talk: blend world positions D~ = sum w_i D_i, then correct onto the shot
  kLocal   ///< bind each driven vertex once to the rest driver, blend every shape's offsets in
           ///< those local frames and rebuild them on the shot's driver
};

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

  // ---- Fidelity (issue 4); see the README's "Fidelity" section for the measured defaults. ----

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
  /// another cache of the cloth, procedural wind. Off by default; needs BakeBackends::layers
  /// when on. Recorded in the settings hash, the report and the EXR header (`dsLayers`).
  LayerOptions layers;
  /// fsync every output EXR before its atomic rename (`--sync`). Off by default: the rename
  /// alone already means readers never see a partial file, and a file cut short by a power
  /// loss is rebaked by --skip-existing; the fsync costs a disk (or NFS) round trip per frame.
  bool syncOutputs = false;
};

/// Whether a bake with these options blends in local frames: BlendMode::kLocal with the
/// correction on and the DrivenShape weights (not the bind baseline).
inline bool blendsLocally(const BakeOptions& options) {
  return options.blend == BlendMode::kLocal && options.correct &&
         options.weightMode != WeightMode::kBind;
}

/// The backends a bake runs on, all on one device (or all host): the per-frame stages, the
/// closest-triangle search used for binding (the mask is applied to it), and a second one for
/// the inside/outside audit and the penetration resolution (always against every triangle).
/// `binding` may be null when options.correct is off, `audit` when options.audit and
/// options.resolve are off.
struct BakeBackends {
  StageBackend* stages = nullptr;
  ClosestBackend* binding = nullptr;
  ClosestBackend* audit = nullptr;
  LayerBackend* layers = nullptr;  ///< needed only when options.layers has a layer
};

/// What happened to one frame.
struct FrameRecord {
  int frame = 0;
  bool skipped = false;  ///< an existing complete output was kept
  /// Why an existing output was baked again by a resume (reuseProblem), or empty.
  std::string rebakeReason;
  std::vector<double> weights;  ///< k per region, region-major (k without regions)
  std::vector<int> atZero;      ///< shapes held at weight 0 (active bounds)
  std::vector<int> atOne;
  double relativeResidual = 0.0;  ///< ||A w - b|| / ||b|| (the largest over regions)
  double kktResidual = 0.0;
  int iterations = 0;
  std::string output;
  /// Rigid alignment of this frame (AlignMode::kRigid): x -> R x + t maps the shot's driver
  /// onto the rest driver. R row-major.
  std::vector<double> alignRotation;
  std::vector<double> alignTranslation;
  // Audit (-1 where not measured).
  int insideBefore = -1;     ///< blended cloth inside the (aligned) shot driver (world blend)
  int insideCorrected = -1;  ///< after the correction (or rebuild), before resolution
  int insideAfter = -1;      ///< in the written cloth (after resolution when it runs)
  int resolved = -1;         ///< vertices moved out by the penetration resolution
  int bindingSwitches = -1;  ///< vertices bound to another triangle than the previous frame
  double maxJump = -1.0;     ///< largest vertex move since the previous baked frame
  int maxJumpVertex = -1;
};

/// Seconds spent per stage, summed over batches. Reading and writing run on I/O tasks beside
/// the other stages (the bake is pipelined), so the stages can add up to more than `total`;
/// readWait and writeWait are the time the bake thread waited for them.
struct StageTimes {
  double read = 0, align = 0, project = 0, weights = 0, blend = 0, correct = 0, resolve = 0,
         audit = 0, write = 0, total = 0;
  double layers = 0;
  double readWait = 0, writeWait = 0;
  double setup = 0;  ///< before the first batch: checks, alignment weights, tables, uploads
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
BakeResult bake(const Database& database, const PointCacheReader& driver,
                const BakeBackends& backends, const BakeOptions& options,
                BakeObserver* observer = nullptr);

/// Flat tables for the stage backends, built from a database (projection basis, shapes).
ShapeTables makeShapeTables(const Database& database);

}  // namespace drivenshape
