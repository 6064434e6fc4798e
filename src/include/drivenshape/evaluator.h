// SPDX-License-Identifier: Apache-2.0
#pragma once

// The method in memory: an Evaluator is built once from a database, its settings and a device,
// then turns frames of driver positions into cloth positions, one frame or hundreds per call.
// The bake (drivenshape/bake.h), the command line, the Python module and the Blender add-on
// are all users of this one class.
//
//   drivenshape::Database db = drivenshape::loadDatabase("sleeve.dsdb");
//   std::unique_ptr<drivenshape::Device> device = drivenshape::openDevice("auto");
//   drivenshape::Evaluator evaluator(db, drivenshape::EvaluatorSettings(), *device);
//   drivenshape::Evaluation out = evaluator.evaluate({1001, 1002}, driver);  // 2 x 3Vp floats
//   // out.cloth: 2 x 3Vd floats; out.records[f]: weights, residual, audit counts

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <drivenshape/binding.h>
#include <drivenshape/database.h>
#include <drivenshape/device.h>
#include <drivenshape/layers.h>
#include <drivenshape/regions.h>

namespace drivenshape {

/// How the per-frame weights are chosen.
enum class WeightMode {
  kQp,       ///< the DrivenShape QP: min ||A w - b|| with sum w = 1, 0 <= w <= 1
  kNearest,  ///< baseline: one-hot on the closest database driver shape
  kBind,     ///< baseline: no database; the rest cloth bound to the rest driver and carried to
             ///< every frame by the correction (what Houdini's Point Deform does)
  kModel,    ///< the pose model (drivenshape/pose_model.h): the rest binding plus the learned
             ///< correction of its local offsets, fitted over the whole reference clip
  kAuto      ///< kModel when the database has a pose model, else kQp (resolved by the
             ///< Evaluator; reports name the mode it resolved to)
};

/// Whether shot frames are rigidly aligned to the database before the weights are solved.
enum class AlignMode {
  kNone,     ///< the talk: weights compare world positions
  kRigid,    ///< each shot frame (and each database shape) is fitted to the rest driver first,
             ///< weighted by how rigidly each vertex moves across the database's driver shapes
             ///< (RigidAligner::weightByRigidity): the fit follows the pelvis, not the legs
  kRigidAll  ///< the same fit weighted by area only: every selected vertex counts alike
};

/// Where the database shapes are blended.
enum class BlendMode {
  kWorld,  ///< the talk: blend world positions D~ = sum w_i D_i, then correct onto the shot
  kLocal   ///< bind each driven vertex once to the rest driver, blend every shape's offsets in
           ///< those local frames and rebuild them on the shot's driver
};

/// Which way the penetration resolution moves a vertex to the skin offset.
enum class ResolveDirection {
  kNearest,  ///< a vertex on its own side of the skin, within the offset, moves along the line
             ///< from its closest point on the driver: the shortest way to the offset, continuous
             ///< where the closest point crosses from a face onto an edge; one on the wrong side
             ///< moves along the pseudo-normal, out of a crease along its bisector
  kNormal    ///< along the driver's pseudo-normal at the closest point (0.1): jumps by up to
             ///< half the angle between two faces where the closest point crosses onto their edge
};

/// The spellings written in reports and taken by the command line and the Python module
/// ("none", "rigid", "rigid-all"; "qp", "nearest", "bind", "model", "auto"; "world", "local";
/// "nearest", "normal").
const char* alignModeName(AlignMode mode);
const char* weightModeName(WeightMode mode);
const char* blendModeName(BlendMode mode);
const char* resolveDirectionName(ResolveDirection direction);

/// Everything that decides the cloth of a frame, as in-memory objects. The defaults are the
/// command line's `bake` defaults (see docs/method.md for how they were chosen).
struct EvaluatorSettings {
  WeightMode weightMode = WeightMode::kAuto;
  /// Rigid alignment: each driver frame is fitted (Kabsch, no scale) to the database's rest
  /// driver on `alignGroup`; so is every database shape. Weights and blends are computed in
  /// that frame and the result goes back through the inverse motion.
  AlignMode align = AlignMode::kRigid;
  /// Driver vertices of the fit: comma-separated `g` group names and/or vertex indices and
  /// ranges ("0-99,250"); empty or "all" = every vertex (see selectVertices).
  std::string alignGroup;
  /// Where the shapes are blended. Local blending rebuilds the offsets on the shot's driver,
  /// which is the correction: with `correct` off or the bind baseline the evaluator blends
  /// world positions whatever this says (see blendsLocally).
  BlendMode blend = BlendMode::kLocal;
  /// Collision correction: bind every blended cloth vertex to its exact closest triangle of
  /// the blended driver and carry it to the shot's driver in that triangle's frame.
  bool correct = true;
  /// Which driver triangles each cloth vertex may bind to; empty = every triangle.
  std::optional<BindingMask> bindingMask;
  /// Penetration resolution: cloth vertices inside the shot's driver or closer than
  /// `skinOffset` (scene units) move to skinOffset from their exact closest point on the driver
  /// (every triangle, no mask), in the direction `resolveDirection` says.
  bool resolve = true;
  double skinOffset = 0.002;
  ResolveDirection resolveDirection = ResolveDirection::kNearest;
  /// The resolution's exit fade (ClosestBackend::setExitFade; 0 = off): a vertex deep on the
  /// wrong side whose two nearest exits are nearly equally far (inside a limb, or where the
  /// driver passes through itself at a bent joint) moves only part of the way, none when they
  /// tie, so it does not jump across the limb between frames. Chosen on the validation table
  /// with the strain limit on (docs/validation.md, "Strain"); without the limit 0.15 leaves
  /// less cloth inside.
  double exitFade = 0.25;
  /// Strain limit (0 = off): after the correction and before the penetration resolution, each
  /// frame's cloth edges are brought back into the band [(1 - s) L, (1 + s) L] around their rest
  /// lengths L (s = strainLimit) by `strainIterations` Chebyshev-accelerated Jacobi iterations
  /// of edge projections (docs/method.md, "Strain limit"). The garment's open borders (a hem, a
  /// cuff) and a layer under the skin stay; every other cloth vertex may move. The resolution still
  /// runs after it. 0.01, with the exit fade at 0.25: on the validation table every strain bar
  /// holds on every clip, and no clip's error, cloth inside or largest jump is worse than without
  /// it (docs/validation.md, "Strain").
  double strainLimit = 0.01;
  int strainIterations = 24;
  /// Region-local weights: one QP per region, mixed with its partition of unity; empty = one
  /// QP on every driver row.
  std::optional<RegionSet> regions;
  /// Temporal stability: |w_t - w_{t-1}| <= maxWeightChange per shape (0 = off). The bound
  /// holds between consecutive frames of the evaluator's temporal state (see
  /// Evaluator::resetTemporalBound).
  double maxWeightChange = 0.0;
  /// Per-frame audit: cloth vertices inside the driver before and after correction, binding
  /// switches, the largest frame-to-frame jump.
  bool audit = true;
  /// Coverage verdict (pose model): a frame whose predicted mean vertex error exceeds this
  /// (scene units) is flagged for simulation; 0 = 2% of the rest cloth's bounding-box diagonal.
  double coverageTolerance = 0.0;
  /// Layers after the correction and resolution (mix with another cache, wind).
  LayerSettings layers;
  /// Host threads for the weights, the alignment and the closest-point search; 0 = all cores.
  int threads = 0;
  /// The resolution and the audit search closest points only where they can matter: points
  /// proven clear of the driver are not searched (ClosestBackend::closestOrClearBlock). The
  /// cloth and every count are bitwise the same either way, so this is not in the settings
  /// hash; off only to measure or check the full search.
  bool clearanceCertificate = true;
};

/// Whether these settings blend in local frames: BlendMode::kLocal with the correction on and
/// the DrivenShape weights or the pose model (not the bind baseline).
bool blendsLocally(const EvaluatorSettings& settings);
/// The weight mode the settings run on `database` (kAuto resolved).
WeightMode resolvedWeightMode(const EvaluatorSettings& settings, const Database& database);

/// Which side of the driver's skin every driven vertex of `database` lives on: kSideInside when
/// it is inside the driver in more than half of the database's pairs (each driven shape against
/// its own driver shape, exact closest points over every driver triangle and their signs),
/// else kSideOutside. What `db build` stores (Database::drivenSides) and what an evaluator
/// learns when the database holds none; the result does not depend on the device or `threads`
/// (0 = all cores).
std::vector<std::int8_t> learnDrivenSides(const Database& database, Device& device,
                                          int threads = 0);

/// What happened to one frame.
struct FrameRecord {
  int frame = 0;
  bool skipped = false;  ///< (bake) an existing complete output was kept
  /// (bake) Why an existing output was baked again by a resume (reuseProblem), or empty.
  std::string rebakeReason;
  std::vector<double> weights;  ///< k per region, region-major (k without regions)
  std::vector<int> atZero;      ///< shapes held at weight 0 (active bounds)
  std::vector<int> atOne;
  /// ||A w - b|| / ||b|| from the QP's objective (the largest over regions); its expanded
  /// form loses the digits below about 1e-3 (see directResidual).
  double relativeResidual = 0.0;
  /// ||A w - b|| / ||b|| computed from the (aligned) shapes and the frame directly, exact to
  /// float rounding (the largest over regions; -1 for the bind baseline).
  double directResidual = -1.0;
  double kktResidual = 0.0;
  int iterations = 0;
  std::string output;  ///< (bake) the file written
  /// Rigid alignment of this frame (AlignMode::kRigid): x -> R x + t maps the shot's driver
  /// onto the rest driver. R row-major.
  std::vector<double> alignRotation;
  std::vector<double> alignTranslation;
  // Audit (-1 where not measured).
  int insideBefore = -1;     ///< blended cloth inside the (aligned) shot driver (world blend)
  int insideCorrected = -1;  ///< after the correction (or rebuild) and the strain limit, before
                             ///< resolution
  int insideAfter = -1;      ///< in the final cloth (after resolution when it runs)
  int resolved = -1;         ///< vertices moved out by the penetration resolution
  int bindingSwitches = -1;  ///< vertices bound to another triangle than the previous frame
  /// Closest-point queries of the resolution and the audit on this frame (one per cloth vertex
  /// and search), and how many of them the clearance certificate answered without a search.
  /// Work counters: they depend on the batching, the cloth does not.
  int closestQueries = 0;
  int closestCleared = 0;
  double maxJump = -1.0;  ///< largest vertex move since the previous evaluated frame
  int maxJumpVertex = -1;
  // Coverage (pose model; -1 where not measured).
  double poseDistance = -1.0;    ///< the model's posterior deviation: how new the pose is
  double predictedError = -1.0;  ///< predicted mean vertex error (scene units)
  /// The verdict's bound on the mean vertex error (scene units; PoseModel::errorBound): the
  /// true error is within it on at least the model's verdict level of frames like its
  /// held-out reference frames.
  double errorBound = -1.0;
  int flagged = -1;  ///< 1: the error bound is above the coverage tolerance (simulate)
};

/// Seconds per pipeline stage by name ("align", "project", "weights", "blend", "correct",
/// "resolve", "layers", "audit", ...), summed over the frames of a call (or a bake).
using StageSeconds = std::map<std::string, double>;

/// The result of one evaluate() call.
struct Evaluation {
  std::vector<float> cloth;          ///< F x 3Vd, frame-major, interleaved xyz
  std::vector<FrameRecord> records;  ///< F
  StageSeconds seconds;              ///< of this call
};

/// What a writer of outputs adds to Evaluator::settingsHash: the EXR width, and with the
/// temporal bound the warm-up frames and the batch size (they decide which frame bounds which).
struct OutputHashFields {
  int exrWidth = 0;
  int temporalWarmup = 0;
  int batchSize = 0;
};

/// Evaluates frames of one character's driver with one database and one set of settings.
///
/// Thread safety: an Evaluator is not thread-safe (it owns device buffers and temporal state);
/// use one per thread. Several Evaluators may share a Device and a Database, which must outlive
/// them. Construction does all the per-database work (alignment of the shapes, QP
/// factorisations, rest binding, table uploads); evaluate() does only per-frame work.
class Evaluator {
 public:
  /// Checks the settings against the database (Error(kUsage) naming the setting, Error(kInput)
  /// for masks, regions or layers that do not fit its meshes) and prepares everything.
  Evaluator(const Database& database, EvaluatorSettings settings, Device& device);
  ~Evaluator();
  Evaluator(const Evaluator&) = delete;
  Evaluator& operator=(const Evaluator&) = delete;

  /// Evaluates `frames.size()` frames. `driver` holds them frame-major (F x 3Vp floats, the
  /// database's driver topology); frame numbers name frames in records and messages and set
  /// the wind's time. Throws Error(kInput) naming the frame and vertex of a non-finite driver
  /// position, Error(kNumerical) when a solve fails, Error(kDevice) on OpenCL failures.
  Evaluation evaluate(const std::vector<int>& frames, const std::vector<float>& driver);

  /// The same into caller-owned memory: driver F x 3Vp, cloth (F - warmup) x 3Vd, records
  /// F - warmup. The first `warmup` frames are aligned and solved, to settle the temporal
  /// bound (maxWeightChange), then dropped: cloth and records hold the other frames. Returns
  /// the seconds per stage of this call.
  StageSeconds evaluate(int frameCount, const int* frames, const float* driver, float* cloth,
                        FrameRecord* records, int warmup = 0);

  /// Throws Error(kInput) naming the first of `frames` a layer cannot provide (a mix cache
  /// without that frame). Call it before a long run to fail early.
  void checkFrames(const std::vector<int>& frames) const;

  /// Forgets the previous frame's weights: the next frame is solved without the temporal
  /// bound (a cut, a jump in the timeline, or the start of a farm batch).
  void resetTemporalBound();
  /// Forgets the previous frame altogether: the weight bound and the audit's reference for
  /// binding switches and jumps.
  void resetHistory();

  /// A hash of everything that changes the result (database, settings, loaded masks, regions
  /// and layer weights, the library version): equal hashes, equal cloth. Its layout is that of
  /// the bake's EXR headers (docs/formats.md), which a resume compares.
  std::uint64_t settingsHash() const;
  /// The same with what a writer of outputs adds (the bake's `dsSettingsHash`).
  std::uint64_t settingsHash(const OutputHashFields& output) const;
  /// Both as a build of library version `version` (e.g. "0.1.0") computes them: the version
  /// string is part of the layout, so outputs of another version never match this build's
  /// hash; these say whether they match that version's (output: nullptr for settingsHash()).
  std::uint64_t settingsHashOfVersion(const std::string& version,
                                      const OutputHashFields* output = nullptr) const;
  /// The settings as the bake report writes them (JSON object text).
  std::string describeSettings() const;
  /// What the settings ask for that they leave unused (an exit fade without the resolution):
  /// one message each (drivenshape/settings_table.h; those the table refuses throw instead).
  const std::vector<std::string>& warnings() const;
  /// The layers as the EXR header's dsLayers attribute writes them ("{}" when none).
  std::string describeLayers() const;
  /// Earlier driver frames the settings read before each frame (the pose model's velocity and
  /// history): a caller evaluating a block should pass that many warm-up frames before it
  /// (the bake does, from the driver cache).
  int historyFrames() const;
  /// The coverage tolerance in scene units (settings.coverageTolerance or its default).
  double coverageTolerance() const;
  /// The stages this evaluator runs, in order.
  std::vector<std::string> stageNames() const;

  const Database& database() const;
  const EvaluatorSettings& settings() const;
  /// The device description (Device::description()).
  std::string deviceName() const;
  int driverVertexCount() const;
  int drivenVertexCount() const;

  /// Memory one frame takes in evaluate()'s buffers (bytes); callers batching many frames
  /// keep batch x this within their budget.
  std::size_t bytesPerFrame() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> mImpl;
};

}  // namespace drivenshape
