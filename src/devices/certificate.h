// SPDX-License-Identifier: Apache-2.0
#pragma once

// The clearance certificate of ClosestBackend::closestOrClearBlock: kernels/certificate.cl and
// its host reference src/devices/host/host_certificate.cpp. certificate.cpp says how it works
// and why a cleared point is safe.

#include <cstdint>
#include <vector>

#include "bvh.h"

namespace drivenshape::correction {

/// Whether the certificate applies to `bvh` (built for a driver of `triangleCount`
/// triangles): one search class over every triangle (no binding mask), whose root is node 0.
/// Otherwise every point is searched.
bool certifiable(const BvhTables& bvh, int triangleCount);

/// A triangle under each node of `bvh` (the first of its leftmost leaf): N triangle ids. The
/// check takes the witness from the node whose farthest point bounds the distance best.
std::vector<std::int32_t> nodeTriangles(const BvhTables& bvh);

}  // namespace drivenshape::correction
