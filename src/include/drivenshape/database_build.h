// SPDX-License-Identifier: Apache-2.0
#pragma once

// Building a database from reference clips (`drivenshape db build`, the Python module's
// build_database): the farthest-point picks, the pose model over every reference frame and the
// side each cloth vertex lives on, learned on a device. The database itself and its file:
// drivenshape/database.h.

#include <iosfwd>
#include <vector>

#include <drivenshape/database.h>
#include <drivenshape/mesh.h>
#include <drivenshape/point_cache.h>

namespace drivenshape {

/// A reference clip beyond the main one (`db build --also`): the pose model is fitted over its
/// frames as well, while the shapes are still picked from the main clip. Its caches must match
/// the rest meshes. Velocity and history read its own cache's earlier frames, never another
/// clip's.
struct ReferenceClip {
  const PointCacheReader* driver = nullptr;
  const PointCacheReader* driven = nullptr;
  std::vector<int> frames;  ///< frames to fit; empty = every frame of the driver cache
};

/// Builds a database from reference caches. The greedy farthest-point pick on driver shapes:
/// the set starts from `addFrames` if given, else from the settled rest pose (the latest
/// candidate whose driver is, within the duplicate tolerance, the closest to the rest driver:
/// the end of the clip's opening hold, when the simulated cloth has draped); each step adds the
/// candidate whose smallest RMS distance to the chosen shapes is largest. Candidates closer
/// than the duplicate tolerance to a chosen shape are dropped. Progress and decisions are
/// written to `log` if not null. Throws Error(kInput/kUsage) naming the cache and frame on
/// mismatched vertex counts, missing frames or bad options.
Database buildDatabase(const Mesh& driverMesh, const Mesh& drivenMesh,
                       const PointCacheReader& driverCache, const PointCacheReader& drivenCache,
                       const DatabaseBuildOptions& options, std::ostream* log = nullptr);
/// The same with more reference clips for the pose model (`db build --also`): the model is
/// fitted over the main clip's candidate frames, then every extra clip's frames, clip after
/// clip (the cross-validation folds are contiguous blocks of that order), each clip numbered
/// apart (ReferenceClipSource). The log reports the model's cross-validated error fitted on the
/// main clip alone and on all clips (by clip). Throws Error(kInput) naming the cache when a
/// clip's caches do not match the rest meshes or lack a frame, Error(kUsage) when extra clips
/// come without the pose model.
Database buildDatabase(const Mesh& driverMesh, const Mesh& drivenMesh,
                       const PointCacheReader& driverCache, const PointCacheReader& drivenCache,
                       const std::vector<ReferenceClip>& extraClips,
                       const DatabaseBuildOptions& options, std::ostream* log = nullptr);

}  // namespace drivenshape
