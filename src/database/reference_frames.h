// SPDX-License-Identifier: Apache-2.0
#pragma once

// Frames of the caches the pose model reads beyond the picks (db build's reference clips,
// --suggest's candidate and shot clips): checked, with the earlier frames that velocity and
// history read (PosePredictor::blockFeatures).

#include <string>
#include <vector>

#include <drivenshape/mesh.h>
#include <drivenshape/point_cache.h>

namespace drivenshape {

/// Throws Error(kInput) naming `what` (e.g. "reference clip 2") and the cache unless the cache
/// holds as many vertices as the mesh (`role`: "driver" or "driven").
void checkClipVertexCount(const PointCacheReader& cache, const Mesh& mesh, const char* role,
                          const std::string& what);

/// Throws Error(kInput) naming `what`, the `role` cache ("" or "driven ") and the range it holds
/// unless it holds every frame of `frames`; the message ends with `advice`.
void checkFramesHeld(const PointCacheReader& cache, const std::vector<int>& frames,
                     const std::string& what, const char* role, const char* advice);

/// A clip's frames: `frames` sorted without repeats, or every frame of the cache when empty.
/// Throws Error(kInput) naming `what` and the cache when it lacks one of them or holds none.
std::vector<int> clipFrames(const PointCacheReader& cache, std::vector<int> frames,
                            const std::string& what);

/// The frames of `cache` within `need` frames before one of `frames` that are not among
/// `frames` themselves, ascending: what velocity and history read besides `frames`.
std::vector<int> earlierFrames(const PointCacheReader& cache, const std::vector<int>& frames,
                               int need);

/// readFrames, throwing Error(kInput) naming the `role` cache, the frame and the vertex when a
/// frame is missing or a value is not finite.
std::vector<float> readFiniteFrames(const PointCacheReader& cache, const std::vector<int>& frames,
                                    const char* role);

}  // namespace drivenshape
