// SPDX-License-Identifier: Apache-2.0
#pragma once

#include <cstdint>
#include <iosfwd>
#include <string>
#include <vector>

#include <drivenshape/mesh.h>
#include <drivenshape/point_cache.h>
#include <drivenshape/pose_model.h>

namespace drivenshape {

/// How a database was (or is to be) built.
struct DatabaseBuildOptions {
  int count = 30;           ///< shapes wanted (fewer if the clip runs out of distinct ones)
  std::vector<int> frames;  ///< candidate frames; empty = every frame of the driver cache
  /// Always kept; they seed the greedy pick. Without them the seed is the settled rest pose:
  /// the candidate whose driver is nearest the rest driver (the latest of those within the
  /// duplicate tolerance of it, since a simulated clip drapes the cloth during its opening hold).
  std::vector<int> addFrames;
  std::vector<int> removeFrames;  ///< never kept
  /// Shapes whose RMS per-vertex distance to an already chosen shape is below this fraction
  /// of the rest driver's bounding-box diagonal are rejected as near-duplicates.
  double duplicateTolerance = 1e-3;
  /// Also fit the pose model over every candidate frame (what `--weights model`, the default
  /// bake, evaluates); off = the picked shapes only.
  bool poseModel = true;
  PoseModelOptions model;
};

/// Where a database's extra reference clip came from (provenance; not part of the content
/// hash). Its frames are numbered source frame + frameOffset in the pose model
/// (referenceClipOffsets), so that no clip's velocity or history reads another's.
struct ReferenceClipSource {
  std::string driverSource;
  std::string drivenSource;
  std::vector<int> frames;  ///< source frames fitted, ascending
  int frameOffset = 0;
};

/// Why a shape is in the database.
enum class PickReason { kSeed, kFarthest, kAdded };
const char* pickReasonName(PickReason reason);

/// A DrivenShape database: N pairs of driver and driven shapes plus the meshes they belong to.
///
///   driverShapes  N x 3Vp   shape i = source frame frames[i], interleaved xyz, float32
///   drivenShapes  N x 3Vd
///
/// Stored as one self-describing, versioned file (see saveDatabase and docs/formats.md).
struct Database {
  static constexpr int kFormatVersion = 1;

  Mesh driverMesh;                    ///< rest positions, faces, groups (from the driver OBJ)
  Mesh drivenMesh;                    ///< rest positions, faces, UVs, groups (from the driven OBJ)
  std::vector<int> frames;            ///< source frame of each shape, in pick order
  std::vector<PickReason> reasons;    ///< why each was picked
  std::vector<double> pickDistances;  ///< RMS distance to the shapes before it (0 for the first)
  std::vector<float> driverShapes;
  std::vector<float> drivenShapes;
  DatabaseBuildOptions options;
  std::string driverSource;  ///< provenance: caches and meshes it was built from
  std::string drivenSource;
  /// Provenance of the reference clips the pose model was fitted on besides the main one.
  std::vector<ReferenceClipSource> extraClips;
  std::string toolVersion;
  std::string created;  ///< UTC, ISO 8601
  /// The pose model fitted over the whole reference clip (empty for databases built with
  /// --model none or by drivenshape before 0.2): what `--weights model` evaluates.
  PoseModel poseModel;
  /// Which side of the driver's skin every driven vertex lives on (kSideOutside for cloth,
  /// kSideInside for a muscle under the skin): learnDrivenSides, stored by `db build` so that a
  /// bake need not learn it again. Empty in databases written before 2026-11-24 (and in ones
  /// made in memory): an evaluator then learns it when it starts. Derived from the shapes, so
  /// not part of the content hash.
  std::vector<std::int8_t> drivenSides;

  int shapeCount() const { return static_cast<int>(frames.size()); }
  int driverVertexCount() const { return driverMesh.vertexCount(); }
  int drivenVertexCount() const { return drivenMesh.vertexCount(); }
  /// Hash of the shapes and topologies: identifies the database in output headers.
  std::uint64_t contentHash() const;
};

/// Frames of a driver cache: a shot to improve or a candidate clip to simulate.
struct DriverClip {
  const PointCacheReader* driver = nullptr;
  std::vector<int> frames;  ///< empty = every frame of the cache
};

/// A frame of the candidate clip worth simulating and adding as a reference frame.
struct ReferenceSuggestion {
  int frame = 0;  ///< frame of the candidate clip
  /// The shots' mean predicted error (scene units) and mean posterior deviation before and
  /// after adding it (after the suggestions before it).
  double errorBefore = 0.0;
  double errorAfter = 0.0;
  double sigmaBefore = 0.0;
  double sigmaAfter = 0.0;
};

/// `db build --suggest`: the `count` frames of `candidate` that, simulated and added to the
/// pose model's reference frames, would most lower the predicted error of the shots' frames
/// (suggestFrames in pose_model.h; greedy, deterministic), in the order picked; fewer when the
/// candidate clip has fewer frames. Features read every cache's earlier frames for velocity and
/// history, as a bake does. Throws Error(kInput) when the database has no pose model or a cache
/// does not match the driver mesh or lacks a frame, Error(kUsage) when count < 1.
std::vector<ReferenceSuggestion> suggestReferenceFrames(const Database& database,
                                                        const DriverClip& candidate,
                                                        const std::vector<DriverClip>& shots,
                                                        int count, int threads = 0,
                                                        std::ostream* log = nullptr);

/// Writes the database atomically (see docs/formats.md for the layout).
void saveDatabase(const std::string& path, const Database& database);
/// Reads and verifies (magic, version, checksums); Error(kInput) with the reason otherwise.
Database loadDatabase(const std::string& path);
/// True if the file starts with the database magic (for `drivenshape info`).
bool isDatabaseFile(const std::string& path);

}  // namespace drivenshape
