// SPDX-License-Identifier: Apache-2.0
#pragma once

// The "far" side of the OpenCL closest-triangle search: bounding-volume hierarchies over the
// driver triangles, built once per surface (topology and mask), refitted to every frame's pose
// on the device (kernels/bvh.cl), and the FLANN warm-start table. See bvh.cpp for the scheme
// and why it is exact.

#include <cstdint>
#include <vector>

#include <drivenshape/binding.h>
#include <drivenshape/mesh.h>

#include <correction_types.h>

namespace drivenshape::correction {

/// One tree per search class (a mask class with points, and one over every triangle for the
/// unmasked points), all in one node array sorted by depth so that a refit is one launch per
/// depth, deepest first:
///
///   nodes          N DsBvhNode    level d = nodes[levelStart[d] .. levelStart[d + 1] - 1]
///   levelStart     D + 1          D = the depth of the deepest tree + 1
///   leafTriangles  4 x L ints     leaf slot s: (vertex a, vertex b, vertex c, triangle id)
///   pointRoot      Vd             the root node of driven point i's tree
///   classes        the triangles (increasing) and points of each tree, for the seeds
struct BvhTables {
  struct SearchClass {
    std::vector<int> triangles;
    std::vector<int> points;
  };
  std::vector<DsBvhNode> nodes;
  std::vector<std::int32_t> levelStart;
  std::vector<std::int32_t> leafTriangles;
  std::vector<std::int32_t> pointRoot;
  std::vector<SearchClass> classes;
  int depth() const { return static_cast<int>(levelStart.size()) - 1; }
};

/// Builds the trees of `driver`'s triangles (checked by the caller) for `mask`, with median
/// splits of the rest pose's triangle centroids and at most `leafSize` triangles per leaf.
BvhTables buildBvh(const Mesh& driver, const BindingMask& mask, int leafSize);

/// The warm start of every point: the triangle whose centroid on `pose` is nearest to the
/// point (FLANN KD-tree, one per class), among the triangles its class allows.
///   triangles T x 3 (interleaved), pose Vp x 3, points Vd x 3, seeds Vd
void seedTriangles(const BvhTables& bvh, const std::int32_t* triangles, const float* pose,
                   const float* points, std::vector<std::int32_t>& seeds);

}  // namespace drivenshape::correction
