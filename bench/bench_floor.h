// SPDX-License-Identifier: Apache-2.0
// drivenshape_bench --floor: what the penetration resolution's closest-point search costs at
// least on a workload, beside what the full search and the clearance certificate cost on the
// same frames (issue 31, point 2).

#pragma once

#include <filesystem>

#include <nlohmann/json.hpp>

#include <drivenshape/bake.h>
#include <drivenshape/database.h>
#include <drivenshape/device.h>
#include <drivenshape/point_cache.h>

namespace drivenshape::bench {

/// Bakes the shot once without the resolution and the audit into `folder` (the cloth the
/// resolution would receive), then times three answers to the resolution's question on those
/// frames, block by block on `device` (the bake's batches): the full exact
/// search (ClosestBackend::closestBlock), the clearance certificate with the skin offset
/// (closestOrClearBlock, the default bake's), and a run told in advance which points need a
/// search, the floor: the points whose exact signed distance is below the offset are searched,
/// every other point is handed its exact hit as answered (closestOrClearBlock with `keep`).
/// Prints one line per run and returns the seconds, the searched fractions and the frames.
nlohmann::json measureResolutionFloor(const Database& db, const PointCacheReader& shot,
                                      Device& device, const BakeOptions& options,
                                      const std::filesystem::path& folder);

}  // namespace drivenshape::bench
