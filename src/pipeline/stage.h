// SPDX-License-Identifier: Apache-2.0
#pragma once

// The evaluator's pipeline (docs/architecture.md, "The path of one driver frame"): each step of a
// frame is one Stage, in one file under src/pipeline/stages/, registered by one line in
// stage_list.h. A stage is configured once (its constructor, from the Model the stages share),
// where it also declares which arrays of the Batch (Array) it reads and which it writes; it adds
// what changes its result to the settings hash and the report, and runs on a Batch of frames. The
// Executor (executor.h) checks the wiring once (every array a stage reads is an input of the call
// or written by an earlier stage), then runs the stages in order and times each by its name; the
// Batch hands a running stage only the arrays it declared.

#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <memory>
#include <optional>
#include <string>
#include <tuple>
#include <vector>

#include <nlohmann/json.hpp>

#include <drivenshape/evaluator.h>

#include "align.h"
#include "closest.h"
#include "hash.h"
#include "qp.h"
#include "stages.h"

namespace drivenshape::pipeline {

class Stage;

/// One weight problem: the QP on the driver rows of a region (or all rows).
struct WeightProblem {
  std::string name;
  std::vector<int> rows;  ///< driver vertices; empty = every row (projected by the backend)
  std::unique_ptr<SimplexLeastSquares> solver;
};

/// What the stages of one evaluator share: the database and settings, the device's backends
/// (made on first use) and the tables stages prepare for each other while they are configured,
/// in pipeline order.
class Model {
 public:
  Model(const Database& database, EvaluatorSettings settings, Device& device);
  ~Model();

  const Database& db;
  const EvaluatorSettings settings;
  Device& device;
  const int threads;  ///< settings.threads, or every hardware thread
  const int k, vp, vd;
  const std::size_t driverValues, drivenValues;  ///< 3Vp, 3Vd
  const bool local;                              ///< blendsLocally(settings)
  /// Settings set away from their defaults that these settings leave unused (the settings
  /// table's unusedSettings on the resolved settings; those it refuses threw instead), and a
  /// coverage tolerance below the smallest error bound of the database's verdict.
  const std::vector<std::string> warnings;
  const BindingMask& mask() const { return mMask; }

  // Backends on the device, made on first use. binding() searches the triangles the mask
  // allows; unmaskedClosest() every triangle (resolution, audit, wind clearance).
  StageBackend& stages();
  ClosestBackend& binding();
  ClosestBackend& unmaskedClosest();
  LayerBackend& layers();

  /// Which side of the driver's skin each driven vertex lives on (Vd values, kSideOutside or
  /// kSideInside), learnt from the database's pairs on first use (by the resolution and the
  /// audit) and set on unmaskedClosest(): for every pair i, the sign of driven vertex v's signed
  /// distance to driver shape i (exact closest point over every triangle, InsideAudit's
  /// pseudo-normal sign); v lives inside when more than half of the pairs have it inside (ties and
  /// points on the skin count as outside). Cloth lives outside; a muscle under the skin inside.
  const std::vector<std::int8_t>& sides();
  /// How many driven vertices live inside. 0 (every cloth database): the side table is never
  /// set on the backend, nor added to the settings hash or the report, so outputs are those of
  /// a pipeline without it.
  int insideVertices();

  // Tables the stages prepare (configure order: align, project/weights, blend, ...).
  /// k x 3Vp database driver shapes, rigidly aligned to the rest driver by the align stage.
  std::vector<float> driverShapes;
  /// k x 3Vd database driven shapes moved with their driver's alignment (world blending).
  std::vector<float> drivenShapes;
  std::unique_ptr<RigidAligner> aligner;  ///< set by the align stage
  std::vector<int> alignVertices;
  /// Local blending: every driven vertex's closest point on the rest driver (mask respected),
  /// set by the blend stage, used by the correction's rebuild (restHitsBlock: the same on the
  /// device, uploaded once).
  std::vector<SurfaceHit> restHits;
  DeviceArray restHitsBlock;
  /// The layers, set by the layers stage.
  std::optional<LayerStack> layerStack;
  /// The weight problems: one per region, or one on every row. Built on first use, from the
  /// aligned driver shapes.
  std::vector<WeightProblem>& problems();
  int regionCount() { return static_cast<int>(problems().size()); }

 private:
  /// A closest-point backend on the device searching the triangles `mask` allows.
  std::unique_ptr<ClosestBackend> makeClosest(const BindingMask& mask);

  BindingMask mMask;
  std::unique_ptr<StageBackend> mStages;
  std::unique_ptr<ClosestBackend> mBinding, mUnmaskedClosest;
  std::unique_ptr<LayerBackend> mLayers;
  std::vector<WeightProblem> mProblems;
  bool mSidesLearnt = false;
  std::vector<std::int8_t> mSides;
  int mInsideVertices = 0;
};

/// The arrays a Batch carries. The inputs come first: the executor sets them from the call
/// before the first stage runs; every other array is written by a stage.
enum class Array : std::uint8_t {
  // Inputs.
  Frames,   ///< n frame numbers (n = warm + count)
  Driver,   ///< n x 3Vp driver frames, world space (the caller's memory)
  Shot,     ///< count x 3Vp: the shot's frames of Driver (a DeviceArray)
  Aligned,  ///< n x 3Vp in the database's frame: Driver until the align stage writes its own
  Records,  ///< count FrameRecords, frame numbers set; the stages fill in the rest
  // Written by the stages.
  Motions,          ///< n RigidTransforms: the alignment of each frame
  Projections,      ///< n x (k-1) floats: the device projection
  Norms,            ///< n x 2 floats: the norms beside it
  HostProjections,  ///< n x regions x (k+1) doubles: region projections (empty without regions)
  Solutions,        ///< n x regions SimplexSolutions
  Weights,          ///< count x regions x k floats (the pose model's: count x (1 + rank))
  Driven,           ///< count x 3Vd blended cloth (world, or local offsets)
  BlendedDriver,    ///< count x 3Vp blended driver (world blending)
  Hits,             ///< count x Vd binding hits (world blending)
  AuditHits,        ///< count x Vd closest points over every triangle
  AuditAnswered,    ///< count x Vd ints: the audit hits answered without a search
  Counts,           ///< count per-frame counters read back from the device
  Moved,            ///< count: the vertices the resolution moved
  SkinPlanes,       ///< count x Vd x 4 floats: the strain limit's skin planes
  Cloth,            ///< count x 3Vd, the result: a view of the caller's memory
  LayersApplied,    ///< bool: the layers changed the cloth
};
inline constexpr int kArrayCount = static_cast<int>(Array::LayersApplied) + 1;

/// The array's name in messages ("blended_driver").
const char* arrayName(Array array);

/// A set of arrays: what a stage reads, or writes.
class Arrays {
 public:
  constexpr Arrays() = default;
  constexpr Arrays(std::initializer_list<Array> arrays) {
    for (const Array array : arrays) {
      mBits |= bit(array);
    }
  }
  /// This set, and `array` when `when`.
  constexpr Arrays with(Array array, bool when = true) const {
    Arrays out = *this;
    out.mBits |= when ? bit(array) : 0u;
    return out;
  }
  constexpr Arrays operator|(Arrays other) const {
    Arrays out = *this;
    out.mBits |= other.mBits;
    return out;
  }
  constexpr bool has(Array array) const { return (mBits & bit(array)) != 0; }
  /// The arrays in Array's order.
  std::vector<Array> list() const;
  /// Their names, ", "-separated.
  std::string names() const;

 private:
  static constexpr std::uint32_t bit(Array array) { return 1u << static_cast<unsigned>(array); }
  std::uint32_t mBits = 0;
};

/// The arrays the executor sets before the first stage.
inline constexpr Arrays kInputArrays{Array::Frames, Array::Driver, Array::Shot, Array::Aligned,
                                     Array::Records};
/// The arrays auditClosest() and countInside() write (with `keep`, they read them too).
inline constexpr Arrays kAuditArrays{Array::AuditHits, Array::AuditAnswered, Array::Counts,
                                     Array::Records};

/// One block of frames on its way through the pipeline. The first `warm` frames are solved
/// (align, project, weights) to settle the temporal bound, then dropped; the other `count`
/// frames go all the way. Frame blocks are frame-major. The blocks of frames the stages hand to
/// each other are DeviceArrays of the model's device: each stays where the last stage wrote it
/// (device memory on OpenCL), so that the shot's driver goes to the device once and the cloth
/// comes back once, when the audit or the caller reads it.
///
/// The arrays are the executor's: a running stage reaches one only through in() and out(),
/// which check its declaration (Stage::declare) and throw std::logic_error naming the stage and
/// the array when it lacks the array.
class Batch {
 public:
  int solveCount() const { return mSolveCount; }  ///< n = warm + count
  int warm() const { return mWarm; }
  int count() const { return mCount; }

  /// Array A, for the running stage to read: it declared that it reads or writes A. Host values
  /// come const (pointers to const); a DeviceArray as itself, since reading it may download it.
  template <Array A>
  decltype(auto) in() {
    check(A, mReadable, "reads");
    return readable(slot<A>());
  }
  /// Array A, for the running stage to write: it declared that it writes A.
  template <Array A>
  auto& out() {
    check(A, mWritable, "writes");
    return slot<A>();
  }

  /// Aligned as a DeviceArray: every frame, n x 3Vp.
  DeviceArray& alignedAll();
  /// Aligned: the shot's frames, count x 3Vp.
  DeviceArray& alignedShot(std::size_t driverValues);
  /// Aligned: the shot's frames on the host, count x 3Vp.
  const float* alignedBlock(std::size_t driverValues);
  /// Writes Aligned (the align stage): `values` floats of the batch's own, on the host.
  float* writeAligned(std::size_t values);

 private:
  friend class Executor;
  explicit Batch(Device& device);
  /// Opens the batch to `stage`'s declared arrays (the executor, before its run()); null
  /// closes it.
  void open(const Stage* stage);

  /// Throws std::logic_error unless `declared` holds `array` (see in(), out()).
  void check(Array array, Arrays declared, const char* access) const {
    if (!declared.has(array)) {
      refuse(array, access);
    }
  }
  [[noreturn]] void refuse(Array array, const char* access) const;

  /// Every array's value, in Array's order.
  auto slots() {
    return std::tie(mFrames, mDriver, shot(), mAligned, mRecords, mMotions, mProjections, mNorms,
                    mHostProjections, mSolutions, mWeights, mDriven, mBlendedDriver, mHits,
                    mAuditHits, mAuditAnswered, mCounts, mMoved, mSkinPlanes, mCloth,
                    mLayersApplied);
  }
  template <Array A>
  auto& slot() {
    static_assert(std::tuple_size_v<decltype(slots())> == kArrayCount);
    return std::get<static_cast<std::size_t>(A)>(slots());
  }
  DeviceArray& shot() { return mWarm == 0 ? mDriverFrames : mShotFrames; }

  template <typename T>
  static const T& readable(const T& value) {
    return value;
  }
  template <typename T>
  static const T* readable(T* pointer) {
    return pointer;
  }
  static DeviceArray& readable(DeviceArray& array) { return array; }

  // The running stage (set by the executor): its name and what it may read and write.
  const char* mStage = nullptr;
  Arrays mReadable, mWritable;

  int mSolveCount = 0;
  int mWarm = 0;
  int mCount = 0;
  const int* mFrames = nullptr;
  const float* mDriver = nullptr;
  DeviceArray mDriverFrames;  ///< n x 3Vp: a view of Driver (the executor's)
  DeviceArray mShotFrames;    ///< count x 3Vp: a view of its shot frames, with warm-up frames
  const float* mAligned = nullptr;
  DeviceArray mAlignedFrames;      ///< backs Aligned when the align stage runs
  DeviceArray mAlignedShotFrames;  ///< its last count frames, with warm-up frames
  FrameRecord* mRecords = nullptr;
  std::vector<RigidTransform> mMotions;
  std::vector<float> mProjections, mNorms;
  std::vector<double> mHostProjections;
  std::vector<SimplexSolution> mSolutions;
  std::vector<float> mWeights;
  DeviceArray mDriven;
  DeviceArray mBlendedDriver;
  DeviceArray mHits;
  DeviceArray mAuditHits;
  DeviceArray mAuditAnswered;
  std::vector<int> mCounts;
  std::vector<int> mMoved;
  DeviceArray mSkinPlanes;
  DeviceArray mCloth;
  bool mLayersApplied = false;
};

/// One step of a frame. Configure in the constructor (from the Model; throw Error naming the
/// setting when the settings do not fit), then run() on many batches.
class Stage {
 public:
  virtual ~Stage() = default;
  /// The timer (and report) name: stages sharing a name share a timer.
  virtual const char* name() const = 0;
  /// The arrays run() reads, each an input or written by an earlier stage (the executor checks),
  /// and those it writes; it may read what it writes.
  Arrays reads() const { return mReads; }
  Arrays writes() const { return mWrites; }
  /// Adds every setting and table that changes this stage's result.
  virtual void addToHash(Hasher& /*hasher*/) const {}
  /// Adds this stage's entries to the report's "settings" object.
  virtual void describe(nlohmann::json& /*settings*/) const {}
  /// Forgets the previous frame (temporal state); `all` also forgets audit references.
  virtual void reset(bool /*all*/) {}
  virtual void run(Batch& batch) = 0;

 protected:
  /// Declares what run() reads and writes (in the constructor: it may depend on the settings).
  /// A read is of values from before run(): an array run() writes first and then reads needs no
  /// read entry.
  void declare(Arrays reads, Arrays writes) {
    mReads = reads;
    mWrites = writes;
  }

 private:
  Arrays mReads, mWrites;
};

/// Makes a stage for these settings, or null when the settings leave it out.
using StageFactory = std::unique_ptr<Stage> (*)(Model& model);

/// The registered stages in pipeline order (stage_list.h).
const std::vector<StageFactory>& stageFactories();

/// The database driver shapes (k x 3Vp, flat) as an n x k matrix of the rows of `vertices`
/// (every vertex when empty).
Eigen::MatrixXd driverMatrix(const std::vector<float>& shapes, int k, int vertexCount,
                             const std::vector<int>& vertices);

/// The backend tables: the projection basis of `solver` and the shapes to blend.
ShapeTables tablesFrom(const Database& db, const SimplexLeastSquares& solver,
                       std::vector<float> driverShapes, std::vector<float> drivenShapes);

/// The coverage tolerance of the model's settings, scene units (its default: 2% of the rest
/// cloth's bounding-box diagonal).
double coverageTolerance(const Model& model);

/// Closest points over every triangle of the batch's cloth on `poses` into batch.auditHits,
/// for the resolution and the inside counts only: points proven at signed distance >=
/// `clearance` get a witness instead of a search (ClosestBackend::closestOrClearBlock, unless
/// the settings turn the certificate off or some vertex lives inside, Model::sides); the records
/// count the queries and those answered without a search. With `keep`, the points the previous call
/// answered without a search keep their hits: only for the same poses, a clearance no larger, and
/// points that did not move since (the resolution does not move them), or that moved less than
/// the `reach` of the call that answered them, whose clearance less that reach is no smaller
/// (ClosestBackend::closestOrClearBlock). Returns whether the certificate ran, i.e. whether
/// batch.auditAnswered marks the points answered without a search.
///   poses count x 3Vp, cloth count x 3Vd
bool auditClosest(Model& model, Batch& batch, DeviceArray& poses, DeviceArray& cloth,
                  float clearance, bool keep = false, float reach = 0.0f);

/// The skin planes of the batch's cloth on `poses` into batch.skinPlanes: closest points from
/// auditClosest() with `clearance` (`keep` and `reach` as there), then a plane at `offset` in front
/// of its closest point for every vertex nearer the skin than `clearance` or up to `depth` inside,
/// sinking away to none at 1.5 `depth` (ClosestBackend::skinPlanes). The planes' reach is the
/// certificate's clearance, so they are those of the full search whichever points it answered.
/// Returns batch.auditAnswered when the certificate ran (the points it answered), else null.
DeviceArray* findSkinPlanes(Model& model, Batch& batch, DeviceArray& poses, DeviceArray& cloth,
                            float clearance, float offset, float depth, bool keep = false,
                            float reach = 0.0f);

/// Counts how many cloth points of each frame of the batch are on the wrong side of the
/// driver's skin (inside, for cloth; Model::sides), from auditClosest() with `clearance` and `keep`
/// (left in batch.auditHits): poses count x 3Vp, cloth count x 3Vd, into (records[f].*field).
void countInside(Model& model, Batch& batch, DeviceArray& poses, DeviceArray& cloth,
                 int FrameRecord::*field, float clearance = 0.0f, bool keep = false);

/// Whether the strain limit runs with skin planes (a limit and the resolution on): it then
/// leaves batch.auditHits and batch.auditAnswered for the resolution to keep the clearance
/// certificate's answers of the points that moved little in it (strain_limit.cpp).
bool limitsWithSkinPlanes(const Model& model);

/// Adds "inside_vertices" (Model::insideVertices) to the report's settings when any driven
/// vertex lives inside; nothing for cloth.
void describeSides(Model& model, nlohmann::json& settings);

}  // namespace drivenshape::pipeline
