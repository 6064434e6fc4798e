// SPDX-License-Identifier: Apache-2.0
// The state the stages of one evaluator share, and the helpers several stages use.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <thread>

#include <drivenshape/error.h>
#include <drivenshape/settings_table.h>

#include "align.h"
#include "parallel.h"
#include "text.h"

#include "stage.h"

namespace drivenshape::pipeline {
namespace {

/// Database pairs per closest-point call while the sides are learnt: about 2^20 points, so the
/// hit and distance buffers stay small for film-scale meshes.
constexpr std::size_t kSidePointsPerCall = std::size_t(1) << 20;

/// Model::sides() from scratch: each pair's driven shape against its own driver shape, on the
/// audit backend (exact closest points over every triangle) and InsideAudit's signs. With
/// `certify`, the points the clearance certificate proves outside (clearance 0) need no search:
/// their witnesses give them a positive sign, as the search would.
std::vector<std::int8_t> learnSides(const Database& db, ClosestBackend& closest, Device& device,
                                    bool certify, int threads) {
  const int k = db.shapeCount();
  const std::size_t vd = static_cast<std::size_t>(db.drivenVertexCount());
  const std::size_t driverValues = 3 * static_cast<std::size_t>(db.driverVertexCount());
  const InsideAudit audit(db.driverMesh);
  const int perCall = static_cast<int>(
      std::clamp<std::size_t>(kSidePointsPerCall / std::max<std::size_t>(vd, 1), 1, k));
  std::vector<float> distances(static_cast<std::size_t>(perCall) * vd);
  std::vector<int> insideVotes(vd, 0);
  DeviceArray poses = device.makeArray(), points = device.makeArray(),
              hitArray = device.makeArray();
  for (int first = 0; first < k; first += perCall) {
    const int count = std::min(perCall, k - first);
    const float* driver = &db.driverShapes[static_cast<std::size_t>(first) * driverValues];
    const float* driven = &db.drivenShapes[static_cast<std::size_t>(first) * 3 * vd];
    poses.view(driver, static_cast<std::size_t>(count) * driverValues);
    points.view(driven, static_cast<std::size_t>(count) * 3 * vd);
    hitArray.resize<SurfaceHit>(static_cast<std::size_t>(count) * vd);
    if (certify) {
      closest.closestOrClearBlock(count, poses, points, 0.0f, hitArray, nullptr);
    } else {
      closest.closestBlock(count, poses, points, hitArray);
    }
    const SurfaceHit* hits = hitArray.read<SurfaceHit>();
    parallelFor(count, threads, [&](int i) {
      const std::size_t at = static_cast<std::size_t>(i) * vd;
      audit.signedDistances(driver + i * driverValues, static_cast<int>(vd), driven + 3 * at,
                            &hits[at], &distances[at]);
    });
    for (std::size_t at = 0; at < static_cast<std::size_t>(count) * vd; ++at) {
      insideVotes[at % vd] += distances[at] < 0.0f ? 1 : 0;
    }
  }
  std::vector<std::int8_t> sides(vd);
  for (std::size_t v = 0; v < vd; ++v) {
    sides[v] = 2 * insideVotes[v] > k ? kSideInside : kSideOutside;
  }
  return sides;
}

/// `settings` with the weight mode resolved (kAuto) and checked against `db`: Error(kUsage)
/// naming the setting when they cannot run on it. Values out of range, and settings these ones
/// leave unused, are the settings table's to refuse (checkSettings, unusedSettings).
EvaluatorSettings validate(const Database& db, EvaluatorSettings settings) {
  checkSettings(settings);
  settings.weightMode = resolvedWeightMode(settings, db);
  if (settings.weightMode == WeightMode::kModel) {
    if (db.poseModel.empty()) {
      DS_THROW(kUsage,
               "the database has no pose model (built with --model none or by drivenshape "
               "0.1); rebuild it with `drivenshape db build`, or choose another weight mode "
               "(qp)");
    }
    if (!settings.correct || settings.blend != BlendMode::kLocal) {
      DS_THROW(kUsage,
               "the pose model blends in the local frames of the rest binding; it needs "
               "the local blend and the correction");
    }
  }
  if (db.shapeCount() < 1) {
    DS_THROW(kInput, "the database has no shapes; build it again with `drivenshape db build`");
  }
  if (settings.weightMode == WeightMode::kBind && !settings.correct) {
    DS_THROW(kUsage,
             "the bind baseline is the correction applied to the rest shapes; it cannot run "
             "with the correction off");
  }
  if (!settings.alignGroup.empty() && settings.alignGroup != "all") {
    // Checked whichever weights run, so that a typo is never silently dropped.
    const std::string source = "align group '" + printableText(settings.alignGroup, 200) + "'";
    selectVertices(db.driverMesh, settings.alignGroup, source + " (driver mesh)");
  }
  if (settings.bindingMask && settings.bindingMask->drivenVertexCount() != db.drivenVertexCount()) {
    DS_THROW(kInput, "the binding mask covers ", settings.bindingMask->drivenVertexCount(),
             " cloth vertices but the database's cloth has ", db.drivenVertexCount());
  }
  if (settings.regions) {
    const std::size_t count = static_cast<std::size_t>(settings.regions->count());
    if (count == 0 || settings.regions->drivenMix.size() != count * db.drivenVertexCount() ||
        settings.regions->driverMix.size() != count * db.driverVertexCount()) {
      DS_THROW(kInput,
               "the regions do not fit the database's meshes (a region set needs at least one "
               "region and a mix weight per region and vertex); read them with readRegions()");
    }
  }
  return settings;
}

/// The coverage tolerance of `settings` on `db` (coverageTolerance(const Model&)).
double toleranceOf(const Database& db, const EvaluatorSettings& settings) {
  if (settings.coverageTolerance > 0) {
    return settings.coverageTolerance;
  }
  return kDefaultCoverageShare * boundsDiagonal(db.drivenMesh);
}

/// The settings' warnings (those they leave unused), and one when the pose model's coverage
/// tolerance is below the smallest error bound the database's verdict gives: every frame would
/// be flagged for simulation.
std::vector<std::string> modelWarnings(const Database& db, const EvaluatorSettings& settings) {
  std::vector<std::string> out = refuseUnusedSettings(unusedSettings({settings}));
  const PoseModel& pose = db.poseModel;
  if (settings.weightMode != WeightMode::kModel || pose.empty() || pose.verdictLevel <= 0.0) {
    return out;
  }
  const double tolerance = toleranceOf(db, settings);
  const double smallest = pose.smallestErrorBound();
  if (tolerance < smallest) {
    out.push_back(detail::concat(
        "the coverage tolerance ", tolerance, " (", percentOfDiagonal(tolerance, db.drivenMesh),
        "% of the cloth's rest diagonal) is below the smallest error bound this database's "
        "verdict gives any frame, ",
        smallest, " (", percentOfDiagonal(smallest, db.drivenMesh),
        "%): every frame will be flagged for simulation; raise the coverage tolerance to at "
        "least that, or build the database with reference clips closer to the shot's motion"));
  }
  return out;
}

}  // namespace

Model::Model(const Database& database, EvaluatorSettings evaluatorSettings, Device& target)
    : db(database),
      settings(validate(database, std::move(evaluatorSettings))),
      device(target),
      threads(resolveThreads(settings.threads)),
      k(database.shapeCount()),
      vp(database.driverVertexCount()),
      vd(database.drivenVertexCount()),
      driverValues(static_cast<std::size_t>(vp) * 3),
      drivenValues(static_cast<std::size_t>(vd) * 3),
      local(blendsLocally(settings)),
      warnings(modelWarnings(database, settings)),
      mMask(settings.bindingMask ? *settings.bindingMask : BindingMask::all(vd)) {
  driverShapes = db.driverShapes;
  if (!local) {
    // Local blending encodes the unaligned shapes (local coordinates ignore rigid motions).
    drivenShapes = db.drivenShapes;
  }
}

Model::~Model() = default;

StageBackend& Model::stages() {
  if (!mStages) {
    mStages = device.makeStages();
  }
  return *mStages;
}

ClosestBackend& Model::binding() {
  if (!mBinding) {
    mBinding = makeClosest(mMask);
  }
  return *mBinding;
}

ClosestBackend& Model::unmaskedClosest() {
  if (!mUnmaskedClosest) {
    mUnmaskedClosest = makeClosest(BindingMask::all(vd));
  }
  return *mUnmaskedClosest;
}

std::unique_ptr<ClosestBackend> Model::makeClosest(const BindingMask& mask) {
  ClosestOptions options;
  options.threads = threads;
  std::unique_ptr<ClosestBackend> backend = device.makeClosest(options);
  backend->setSurface(db.driverMesh, mask);
  return backend;
}

const std::vector<std::int8_t>& Model::sides() {
  if (!mSidesLearnt) {
    mSides =
        db.drivenSides.size() == static_cast<std::size_t>(vd)
            ? db.drivenSides
            : learnSides(db, unmaskedClosest(), device, settings.clearanceCertificate, threads);
    mInsideVertices = static_cast<int>(std::count(mSides.begin(), mSides.end(), kSideInside));
    if (mInsideVertices > 0) {
      unmaskedClosest().setSides(mSides);
    }
    mSidesLearnt = true;
  }
  return mSides;
}

int Model::insideVertices() {
  sides();
  return mInsideVertices;
}

LayerBackend& Model::layers() {
  if (!mLayers) {
    mLayers = device.makeLayers();
  }
  return *mLayers;
}

std::vector<WeightProblem>& Model::problems() {
  if (mProblems.empty()) {
    if (settings.regions) {
      for (const Region& region : settings.regions->regions) {
        mProblems.push_back({region.name, region.driverVertices, nullptr});
      }
    } else {
      mProblems.push_back({"all", {}, nullptr});
    }
    for (WeightProblem& problem : mProblems) {
      problem.solver =
          std::make_unique<SimplexLeastSquares>(driverMatrix(driverShapes, k, vp, problem.rows));
    }
  }
  return mProblems;
}

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

double coverageTolerance(const Model& model) {
  return toleranceOf(model.db, model.settings);
}

bool auditClosest(Model& model, Batch& batch, DeviceArray& poses, DeviceArray& cloth,
                  float clearance, bool keep, float reach) {
  const int count = batch.count();
  const std::size_t items = static_cast<std::size_t>(count) * model.vd;
  // The certificate proves points outside by the clearance: it is used only when every driven
  // vertex lives outside (cloth); a database with vertices under the skin searches every point.
  const bool certify = model.settings.clearanceCertificate && model.insideVertices() == 0;
  keep = keep && certify;
  DeviceArray& hits = batch.out<Array::AuditHits>();
  DeviceArray& answered = batch.out<Array::AuditAnswered>();
  std::vector<int>& counts = batch.out<Array::Counts>();
  if (!keep) {
    // (A resize forgets the values: kept hits and marks must not be resized.)
    hits.resize<SurfaceHit>(items);
    answered.resize<std::int32_t>(items);
  }
  counts.assign(static_cast<std::size_t>(count), 0);
  if (certify) {
    model.unmaskedClosest().closestOrClearBlock(count, poses, cloth, clearance, hits, counts.data(),
                                                &answered, keep, reach);
  } else {
    model.unmaskedClosest().closestBlock(count, poses, cloth, hits);
  }
  FrameRecord* records = batch.out<Array::Records>();
  for (int i = 0; i < count; ++i) {
    records[i].closestQueries += model.vd;
    records[i].closestCleared += counts[static_cast<std::size_t>(i)];
  }
  return certify;
}

DeviceArray* findSkinPlanes(Model& model, Batch& batch, DeviceArray& poses, DeviceArray& cloth,
                            float clearance, float offset, float depth, bool keep, float reach) {
  DeviceArray* marks = auditClosest(model, batch, poses, cloth, clearance, keep, reach)
                           ? &batch.out<Array::AuditAnswered>()
                           : nullptr;
  DeviceArray& planes = batch.out<Array::SkinPlanes>();
  planes.resize<float>(static_cast<std::size_t>(batch.count()) * model.vd * 4);
  model.unmaskedClosest().skinPlanesBlock(batch.count(), poses, batch.out<Array::AuditHits>(),
                                          marks, cloth, offset, depth, clearance, planes);
  return marks;
}

void countInside(Model& model, Batch& batch, DeviceArray& poses, DeviceArray& cloth,
                 int FrameRecord::*field, float clearance, bool keep) {
  auditClosest(model, batch, poses, cloth, clearance, keep);
  std::vector<int>& counts = batch.out<Array::Counts>();
  counts.assign(static_cast<std::size_t>(batch.count()), 0);
  model.unmaskedClosest().countInside(batch.count(), poses, batch.out<Array::AuditHits>(), cloth,
                                      counts.data());
  FrameRecord* records = batch.out<Array::Records>();
  for (int i = 0; i < batch.count(); ++i) {
    records[i].*field = counts[static_cast<std::size_t>(i)];
  }
}

void describeSides(Model& model, nlohmann::json& settings) {
  if (model.insideVertices() > 0) {
    settings["inside_vertices"] = model.insideVertices();
  }
}

const char* arrayName(Array array) {
  switch (array) {
    case Array::Frames:
      return "frames";
    case Array::Driver:
      return "driver";
    case Array::Shot:
      return "shot";
    case Array::Aligned:
      return "aligned";
    case Array::Records:
      return "records";
    case Array::Motions:
      return "motions";
    case Array::Projections:
      return "projections";
    case Array::Norms:
      return "norms";
    case Array::HostProjections:
      return "host_projections";
    case Array::Solutions:
      return "solutions";
    case Array::Weights:
      return "weights";
    case Array::Driven:
      return "driven";
    case Array::BlendedDriver:
      return "blended_driver";
    case Array::Hits:
      return "hits";
    case Array::AuditHits:
      return "audit_hits";
    case Array::AuditAnswered:
      return "audit_answered";
    case Array::Counts:
      return "counts";
    case Array::Moved:
      return "moved";
    case Array::SkinPlanes:
      return "skin_planes";
    case Array::Cloth:
      return "cloth";
    case Array::LayersApplied:
      return "layers_applied";
  }
  return "?";
}

std::vector<Array> Arrays::list() const {
  std::vector<Array> arrays;
  for (int i = 0; i < kArrayCount; ++i) {
    if (has(static_cast<Array>(i))) {
      arrays.push_back(static_cast<Array>(i));
    }
  }
  return arrays;
}

std::string Arrays::names() const {
  std::string text;
  for (const Array array : list()) {
    text += (text.empty() ? "" : ", ") + std::string(arrayName(array));
  }
  return text;
}

Batch::Batch(Device& device)
    : mDriverFrames(device.makeArray()),
      mShotFrames(device.makeArray()),
      mAlignedFrames(device.makeArray()),
      mAlignedShotFrames(device.makeArray()),
      mDriven(device.makeArray()),
      mBlendedDriver(device.makeArray()),
      mHits(device.makeArray()),
      mAuditHits(device.makeArray()),
      mAuditAnswered(device.makeArray()),
      mSkinPlanes(device.makeArray()),
      mCloth(device.makeArray()) {}

DeviceArray& Batch::alignedAll() {
  return in<Array::Aligned>() == mDriver ? mDriverFrames : mAlignedFrames;
}

DeviceArray& Batch::alignedShot(std::size_t driverValues) {
  if (mWarm == 0) {
    return alignedAll();
  }
  mAlignedShotFrames.view(alignedBlock(driverValues),
                          static_cast<std::size_t>(mCount) * driverValues);
  return mAlignedShotFrames;
}

const float* Batch::alignedBlock(std::size_t driverValues) {
  return in<Array::Aligned>() + static_cast<std::size_t>(mWarm) * driverValues;
}

float* Batch::writeAligned(std::size_t values) {
  const float*& aligned = out<Array::Aligned>();
  mAlignedFrames.resize<float>(values);
  float* frames = mAlignedFrames.write<float>();
  aligned = frames;
  return frames;
}

void Batch::refuse(Array array, const char* access) const {
  if (mStage == nullptr) {
    throw std::logic_error(std::string("the batch's array '") + arrayName(array) +
                           "' is reached outside of a stage");
  }
  throw std::logic_error(std::string("stage '") + mStage + "' " + access + " '" + arrayName(array) +
                         "' without declaring it");
}

}  // namespace drivenshape::pipeline

namespace drivenshape {

std::vector<std::int8_t> learnDrivenSides(const Database& database, Device& device, int threads) {
  ClosestOptions options;
  options.threads = resolveThreads(threads);
  std::unique_ptr<ClosestBackend> closest = device.makeClosest(options);
  closest->setSurface(database.driverMesh, BindingMask::all(database.drivenVertexCount()));
  return pipeline::learnSides(database, *closest, device, true, options.threads);
}

}  // namespace drivenshape
